//! The module's named outputs: name tables with const lookups and index submodules, and the
//! accessors of points, bodies and joint coordinates.
//!
//! Names from the description reach the code only as string literals: the tables
//! (`BODY_NAMES`, `POINT_NAMES`, `JOINT_NAMES`, `JOINT_COORDINATE_NAMES`, `UNKNOWNS`) and the
//! `const fn` lookups over them (`body("crank")`, a compile error in const context when the
//! name is misspelt). A name that is a plain identifier (`[A-Za-z][A-Za-z0-9_]*`) whose
//! uppercase form is unique in its table also gets an index constant in a submodule that holds
//! nothing else (`body::CRANK`, `joint::O4`), so no user name can shadow a generated item.

use syn::parse_quote;

use super::Rows;
use super::function::{Output, Signature};
use super::syntax::{element, ident, index};
use crate::model::Mechanism;
use crate::symbolic::{JointCoordinate, Outputs, Symbolic};

/// One name table: what it names, its length and name constants, the lookup and submodule.
struct Table {
    /// "moving body", "point of interest", … for docs, and its plural.
    what: &'static str,
    plural: &'static str,
    /// The length constant (`BODIES`) and the table (`BODY_NAMES`).
    len: &'static str,
    names: &'static str,
    /// The lookup function and the submodule.
    lookup: &'static str,
    entries: Vec<String>,
}

/// The name tables, lookups and index submodules (`BODY_NAMES` and `UNKNOWNS` themselves are
/// among the module's constants).
pub(super) fn names(mech: &Mechanism, sys: &Symbolic, outputs: &Outputs) -> Vec<syn::Item> {
    let tables = [
        Table {
            what: "moving body",
            plural: "moving bodies",
            len: "BODIES",
            names: "BODY_NAMES",
            lookup: "body",
            entries: mech.bodies.iter().filter(|b| !b.ground).map(|b| b.name.clone()).collect(),
        },
        Table {
            what: "point of interest",
            plural: "points of interest",
            len: "POINTS",
            names: "POINT_NAMES",
            lookup: "point",
            entries: mech.points.iter().map(|p| p.name.clone()).collect(),
        },
        Table {
            what: "joint",
            plural: "joints",
            len: "JOINTS",
            names: "JOINT_NAMES",
            lookup: "joint",
            entries: mech.joints.iter().map(|j| j.name.clone()).collect(),
        },
        Table {
            what: "joint coordinate",
            plural: "joint coordinates",
            len: "JOINT_COORDINATES",
            names: "JOINT_COORDINATE_NAMES",
            lookup: "joint_coordinate",
            entries: outputs
                .joints
                .iter()
                .map(|(j, what, _)| format!("{}.{what}", mech.joints[*j].name))
                .collect(),
        },
        Table {
            what: "input driver",
            plural: "input drivers",
            len: "INPUTS",
            names: "INPUT_NAMES",
            lookup: "input",
            entries: sys.inputs.iter().map(|d| mech.drivers[d.driver].name.clone()).collect(),
        },
        Table {
            what: "unknown",
            plural: "unknowns",
            len: "N",
            names: "UNKNOWNS",
            lookup: "unknown",
            entries: super::unknown_names(mech, sys),
        },
    ];
    let mut items = Vec::new();
    for t in &tables {
        // A module without input drivers has no input table.
        if t.lookup == "input" && t.entries.is_empty() {
            continue;
        }
        // BODY_NAMES, UNKNOWNS, BODIES and N are among the module's constants already.
        if !matches!(t.lookup, "body" | "unknown") {
            let (len, names, count) = (ident(t.len), ident(t.names), index(t.entries.len()));
            let entries = &t.entries;
            let doc_len = format!(" Number of {}.", t.plural);
            let doc_names = format!(" Name of each {}.", t.what);
            items.push(parse_quote! {
                #[doc = #doc_len]
                pub const #len: usize = #count;
            });
            items.push(parse_quote! {
                #[doc = #doc_names]
                pub const #names: [&str; #len] = [#(#entries),*];
            });
        }
        items.push(lookup(t));
        items.push(submodule(t));
    }
    items
}

/// `pub const fn body(name: &str) -> usize`: the index of `name` in the table, or a panic,
/// which in const context is a compile error.
fn lookup(t: &Table) -> syn::Item {
    let (f, names) = (ident(t.lookup), ident(t.names));
    let doc = format!(
        " The index of the {what} `name` in [`{names}`], for const context: \
         `const K: usize = {f}(\"…\");` does not compile when no {what} has that name.\n\n \
         # Panics\n\n When no {what} is named `name` (at compile time when used in a const).",
        what = t.what,
        names = t.names,
        f = t.lookup,
    );
    let message = format!("no {} of that name", t.what);
    parse_quote! {
        #[doc = #doc]
        #[must_use]
        pub const fn #f(name: &str) -> usize {
            match runtime::outputs::find(&#names, name) {
                Some(k) => k,
                None => panic!(#message),
            }
        }
    }
}

/// The constant name of a table entry when it is a plain identifier (`[A-Za-z][A-Za-z0-9_]*`;
/// `a.b` for unknowns and joint coordinates reads as `a_b`), uppercased: never a keyword, and
/// made of the entry's checked characters only, so user text cannot become other code.
fn constant_name(entry: &str) -> Option<String> {
    let flat = entry.replacen('.', "_", 1);
    let mut chars = flat.chars();
    let first = chars.next()?;
    let plain = first.is_ascii_alphabetic() && chars.all(|c| c.is_ascii_alphanumeric() || c == '_');
    plain.then(|| flat.to_ascii_uppercase())
}

/// `pub mod body { pub const CRANK: usize = 0; … }` for the entries with a constant name that
/// no other entry of the table shares.
fn submodule(t: &Table) -> syn::Item {
    let named: Vec<Option<String>> = t.entries.iter().map(|e| constant_name(e)).collect();
    let consts = named.iter().enumerate().filter_map(|(k, c)| {
        let c = c.as_ref()?;
        let unique = named.iter().filter(|o| o.as_ref() == Some(c)).count() == 1;
        unique.then(|| {
            let doc =
                format!(" Index of the {} `{}` in [`super::{}`].", t.what, t.entries[k], t.names);
            let (name, k) = (ident(c), index(k));
            quote::quote! {
                #[doc = #doc]
                pub const #name: usize = #k;
            }
        })
    });
    let module = ident(t.lookup);
    let doc = format!(
        " Index constants of the {} whose names are plain identifiers (ASCII letters, digits and \
         `_`, from a letter; uppercased, `.` read as `_`); every other name is reached through \
         [`super::{}`].",
        t.plural, t.lookup
    );
    parse_quote! {
        #[doc = #doc]
        pub mod #module {
            #(#consts)*
        }
    }
}

/// The accessors of points and bodies: (function, count, derivative order, needs q̇, needs q̈,
/// doc).
const KINDS: [(&str, &str, usize, bool, bool, &str); 5] = [
    (
        "point_positions",
        "POINTS",
        0,
        false,
        false,
        "Position r of every point of interest (global), in [`POINT_NAMES`] order.",
    ),
    (
        "point_velocities",
        "POINTS",
        1,
        true,
        false,
        "Velocity v = ṙ of every point of interest (global).",
    ),
    (
        "point_accelerations",
        "POINTS",
        2,
        true,
        true,
        "Acceleration a = r̈ of every point of interest (global).",
    ),
    (
        "angular_velocities",
        "BODIES",
        0,
        true,
        false,
        "Angular velocity ω = 2 G(p) ṗ of every moving body (global components), in [`BODY_NAMES`] order.",
    ),
    (
        "angular_accelerations",
        "BODIES",
        1,
        true,
        true,
        "Angular acceleration α = 2 G(p) p̈ of every moving body (global components).",
    ),
];

/// The accessor functions.
pub(super) fn accessors(rows: &Rows<'_>, outputs: &Outputs) -> Vec<syn::Item> {
    let v3 = |count: &str| {
        let count = ident(count);
        quote::quote!(&mut [[f64; 3]; #count])
    };
    let triple = |array: &str, values: &mut dyn Iterator<Item = [crate::expr::ExprId; 3]>| {
        values
            .enumerate()
            .flat_map(|(k, v)| {
                v.into_iter().enumerate().map(move |(c, value)| Output {
                    target: element(array, &[k, c]),
                    array: 0,
                    value,
                    key: k,
                    row: None,
                })
            })
            .collect::<Vec<_>>()
    };
    let mut items = Vec::new();
    for (name, count, order, qd, qdd, what) in KINDS {
        let targets = [("out", v3(count))];
        let sig =
            Signature { name, qd, qdd, public: true, targets: &targets, inputs: rows.inputs() };
        let values: Vec<_> = if count == "POINTS" {
            triple("out", &mut outputs.points.iter().map(|p| p[order]))
        } else {
            triple("out", &mut outputs.bodies.iter().map(|b| b[order]))
        };
        items.extend(rows.emit(&sig, what, Vec::new(), &values));
    }
    items.extend(poses(rows, outputs));
    items.extend(joint_coordinates(rows, outputs));
    items
}

/// `poses`: r and p of every moving body, fixed, driven and substituted ones included.
fn poses(rows: &Rows<'_>, outputs: &Outputs) -> Vec<syn::Item> {
    let poses: Vec<Output> = outputs
        .poses
        .iter()
        .enumerate()
        .flat_map(|(k, p)| {
            p.iter().enumerate().map(move |(c, &value)| Output {
                target: element("out", &[k, c]),
                array: 0,
                value,
                key: k,
                row: None,
            })
        })
        .collect();
    let targets = [("out", quote::quote!(&mut [[f64; 7]; BODIES]))];
    let sig = Signature {
        name: "poses",
        qd: false,
        qdd: false,
        public: true,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let what = "Coordinates `[x, y, z, e0, e1, e2, e3]` (r and p) of every moving body, fixed, driven and substituted ones included.";
    rows.emit(&sig, what, Vec::new(), &poses)
}

/// `joint_coordinates` (public) over `joint_terms` (the polynomial parts).
fn joint_coordinates(rows: &Rows<'_>, outputs: &Outputs) -> Vec<syn::Item> {
    let mut values = Vec::new();
    let mut angles = Vec::new();
    for (k, (_, _, c)) in outputs.joints.iter().enumerate() {
        let mut push = |array, target, value| {
            values.push(Output { target, array, value, key: k, row: None });
        };
        match *c {
            JointCoordinate::Translation(d) => {
                for (i, e) in d.into_iter().enumerate() {
                    push(0, element("out", &[k, i]), e);
                }
            }
            JointCoordinate::Angle { x, y } => {
                let a = angles.len();
                for (i, e) in x.into_iter().chain(y).enumerate() {
                    push(1, element("terms", &[a, i]), e);
                }
                angles.push(k);
            }
        }
    }
    let count = index(angles.len());
    let targets = [
        ("out", quote::quote!(&mut [[f64; 3]; JOINT_COORDINATES])),
        ("terms", quote::quote!(&mut [[f64; 6]; #count])),
    ];
    let sig = Signature {
        name: "joint_terms",
        qd: true,
        qdd: true,
        public: false,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let what = "The translations of [`joint_coordinates`] and, for each angle, x = ref_i·ref_j and y = (ref_i × ref_j)·axis_i with their rates: `[x, ẋ, ẍ, y, ẏ, ÿ]`.";
    let mut items = rows.emit(&sig, what, Vec::new(), &values);
    let finish = angles.iter().enumerate().map(|(a, &k)| -> syn::Stmt {
        let (a, k) = (index(a), index(k));
        parse_quote! {
            out[#k] = runtime::outputs::angle(
                [terms[#a][0], terms[#a][1], terms[#a][2]],
                [terms[#a][3], terms[#a][4], terms[#a][5]],
            );
        }
    });
    if rows.inputs() {
        items.push(parse_quote! {
            /// Every joint coordinate (in [`JOINT_COORDINATE_NAMES`] order) with its rate and
            /// acceleration at the inputs `inputs`: `out[k] = [value, rate, acceleration]`. An
            /// angle θ is measured from ref_i to ref_j, right-handed about axis_i, in (−π, π]
            /// (follow it across turns with `runtime::outputs::unwrap_angle`); a translation is
            /// d = (P_j − P_i)·axis_i.
            pub fn joint_coordinates(q: &[f64; N], qd: &[f64; N], qdd: &[f64; N], t: f64, inputs: &Inputs, out: &mut [[f64; 3]; JOINT_COORDINATES]) {
                let mut terms = [[0.0; 6]; #count];
                joint_terms(q, qd, qdd, t, inputs, out, &mut terms);
                #(#finish)*
            }
        });
        return items;
    }
    items.push(parse_quote! {
        /// Every joint coordinate (in [`JOINT_COORDINATE_NAMES`] order) with its rate and
        /// acceleration: `out[k] = [value, rate, acceleration]`. An angle θ is measured from
        /// ref_i to ref_j, right-handed about axis_i, in (−π, π] (follow it across turns with
        /// `runtime::outputs::unwrap_angle`); a translation is d = (P_j − P_i)·axis_i.
        pub fn joint_coordinates(q: &[f64; N], qd: &[f64; N], qdd: &[f64; N], t: f64, out: &mut [[f64; 3]; JOINT_COORDINATES]) {
            let mut terms = [[0.0; 6]; #count];
            joint_terms(q, qd, qdd, t, out, &mut terms);
            #(#finish)*
        }
    });
    items
}
