//! Emission of the reduced symbolic system as a Rust module: syn nodes printed by
//! prettyplease, one top-level item at a time.
//!
//! Three layers: [`syntax`] builds syn nodes (names, literals, operators, statements),
//! [`function`] turns outputs into one emitted function (temporaries, chunking), and this
//! module assembles the module: its constants, the equation functions, the structured LU of
//! [`lu`] for the orders [`crate::pivot`] plans, the `runtime::Mechanism` impl and the
//! documentation ([`docs`]), with a `//` note before each row's assignments ([`notes`]).

use proc_macro2::Literal;
use syn::{Expr, parse_quote};

use crate::expr::ExprId;
use crate::model::Mechanism;
use crate::symbolic::{Source, Symbolic};

mod blocks;
mod docs;
mod from_blocks;
mod function;
mod inputs;
pub mod lu;
mod names;
mod notes;
mod outputs;
mod redundant;
pub mod scalar;
mod shared;
mod syntax;
mod time;

pub use function::CHUNK_OPS;
pub use scalar::Scalar;

use docs::{doc_attributes, fenced, markdown_escaped, one_line_docs};
use function::{Output, Signature, emit_function, function};
use syntax::{binary, element, ident, index, literal_signed, param};

pub use crate::model::type_name;

/// The generated module for one mechanism, as text.
#[must_use]
pub fn module(mech: &Mechanism, sys: &Symbolic, source: &str) -> String {
    module_in(mech, sys, source, Scalar::F64)
}

/// [`module`] in the floating-point type `scalar` (see [`scalar`]).
#[must_use]
pub fn module_in(mech: &Mechanism, sys: &Symbolic, source: &str, scalar: Scalar) -> String {
    assemble(mech, sys, source, scalar, Factoring::Planned)
}

/// [`module_in`] solved by Newton block by block wherever Φ_q falls apart into blocks (more
/// than one block, none larger than 32, and no row left out as redundant), below 64 unknowns
/// too, where the plan keeps the static orders: for tests and comparisons.
#[must_use]
pub fn module_with_block_newton(
    mech: &Mechanism,
    sys: &Symbolic,
    source: &str,
    scalar: Scalar,
) -> String {
    assemble(mech, sys, source, scalar, Factoring::BlockNewton)
}

/// [`module_in`] with Φ_q factored block by block where the plan does so (64 unknowns or more)
/// but one Newton iteration over the whole system, as for rows left out as redundant: for
/// tests and comparisons of the two Newton iterations.
#[must_use]
pub fn module_with_whole_newton(
    mech: &Mechanism,
    sys: &Symbolic,
    source: &str,
    scalar: Scalar,
) -> String {
    assemble(mech, sys, source, scalar, Factoring::WholeNewton)
}

/// How the emitted solver factors Φ_q and runs Newton.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Factoring {
    /// As [`blocks::plan`] decides.
    Planned,
    /// Static pivot orders only.
    StaticOrders,
    /// Newton block by block wherever Φ_q falls apart into blocks.
    BlockNewton,
    /// Block LU as planned, one Newton iteration over the whole system.
    WholeNewton,
}

/// [`module_in`] with the static pivot orders even where Φ_q would be factored block by block
/// (a system of 64 unknowns or more with more than one block, none larger than 32): for tests
/// and comparisons of the two factorisations.
#[must_use]
pub fn module_with_static_orders(
    mech: &Mechanism,
    sys: &Symbolic,
    source: &str,
    scalar: Scalar,
) -> String {
    assemble(mech, sys, source, scalar, Factoring::StaticOrders)
}

/// The module, factored block by block when `factoring` allows it and [`blocks::plan`] finds
/// it worthwhile.
fn assemble(
    mech: &Mechanism,
    sys: &Symbolic,
    source: &str,
    scalar: Scalar,
    factoring: Factoring,
) -> String {
    // The outputs' expressions join Φ's arena (after its nodes, so Φ's code is unchanged).
    let mut sys = sys.clone();
    let named = sys.outputs(mech);
    // The structured LU: block by block when Φ_q falls apart into blocks (`blocks`), else
    // static pivot orders over the description's motion. The closed forms' expressions join
    // the arena after the outputs'.
    let layout = match factoring {
        Factoring::Planned => blocks::plan(&mut sys, mech, None),
        Factoring::StaticOrders => None,
        Factoring::BlockNewton => blocks::plan(&mut sys, mech, Some(true)),
        Factoring::WholeNewton => blocks::plan(&mut sys, mech, Some(false)),
    };
    let sys = &sys;
    let n = sys.unknowns.len();
    let moving: Vec<usize> =
        mech.bodies.iter().enumerate().filter(|(_, b)| !b.ground).map(|(k, _)| k).collect();
    let mut items = constants(mech, sys, moving.len());
    items.extend(outputs::names(mech, sys, &named));
    items.extend(inputs::items(mech, sys));
    let after_constants = items.len();
    let rows = Rows::new(sys);
    // Newton block by block emits every row's Jacobian entries in its `block_b` functions:
    // the whole Jacobian is then their calls (`from_blocks`), not two more copies of them.
    let by_blocks = layout.as_ref().filter(|plan| plan.newton);
    // Φ, ν and γ block by block too when copies of one structure can share their code.
    let by_vectors = by_blocks.filter(|plan| plan.shared.vectors);
    if let Some(plan) = by_vectors {
        items.extend(blocks::vectors(&rows, plan));
    } else {
        items.extend(residual_and_jacobian(&rows, layout.is_none(), by_blocks.is_none()));
    }
    if let Some(plan) = by_blocks {
        let nnz = sys.jac.iter().map(Vec::len).sum::<usize>();
        items.extend(from_blocks::items(plan, nnz, !sys.inputs.is_empty()));
    }
    if let Some(plan) = &layout {
        items.extend(blocks::items(&rows, plan));
    }
    let orders =
        if n == 0 || layout.is_some() { Vec::new() } else { crate::pivot::plan_motion(mech, sys) };
    let structure = crate::pivot::structure(sys);
    let constant = crate::pivot::constants(sys);
    for (k, order) in orders.iter().enumerate() {
        items.extend(lu::emit(order, &structure, &constant, k));
    }
    if by_vectors.is_none() {
        items.extend(right_hand_sides(&rows));
    }
    // The time terms, for static orders over the whole system (`time`).
    let timed = if orders.is_empty() { None } else { time::items(&rows, &moving) };
    if let Some((functions, _)) = &timed {
        time::delegate(&mut items, functions);
        items.extend(functions.iter().cloned());
    }
    items.push(normalize(sys));
    items.push(normalize_moved(sys));
    items.extend(expand(sys, &moving));
    items.extend(outputs::accessors(&rows, &named));
    items.extend(redundant::items(sys, &rows));
    let mut structured = if let Some(plan) = &layout {
        blocks::impl_items(plan, !sys.inputs.is_empty())
    } else {
        structured_items(orders.len(), !sys.inputs.is_empty())
    };
    structured.extend(timed.into_iter().flat_map(|(_, impls)| impls));
    structured.push(parse_quote! {
        fn normalize_moved(&self, q: &mut [f64; N]) -> bool {
            normalize_moved(q)
        }
    });
    structured.extend(redundant::impl_items(sys, !sys.inputs.is_empty()));
    if sys.inputs.is_empty() {
        items.extend(mechanism_type(mech, structured));
    } else {
        items.extend(inputs::mechanism_type(mech, structured));
    }
    // The law coefficients the functions read, named after the other constants.
    let mut laws = names::LawNames::new(mech);
    for item in &mut items {
        laws.apply(item);
    }
    items.splice(after_constants..after_constants, laws.items());
    let docs = module_docs(mech, sys, source, scalar);
    if scalar == Scalar::F32 {
        items.iter_mut().for_each(scalar::to_f32);
    }
    let legs: Vec<usize> = sys.legs.iter().map(|l| l.driver).collect();
    print(&docs, items, &notes::row_notes(mech, &sys.rows, &legs))
}

/// The module as text: the inner docs, then each item printed on its own (one at a time keeps
/// prettyplease's memory bounded), with every doc line a `///` line and the row notes in.
fn print(docs: &[String], items: Vec<syn::Item>, notes: &[String]) -> String {
    let mut attrs = vec![parse_quote!(#![cfg_attr(rustfmt, rustfmt::skip)])];
    attrs.extend(doc_attributes(docs, true));
    let mut text = String::from("// @generated by mechgen. Do not edit.\n\n");
    text.push_str(&prettyplease::unparse(&syn::File { shebang: None, attrs, items: Vec::new() }));
    for mut item in items {
        one_line_docs(&mut item);
        text.push('\n');
        let printed = prettyplease::unparse(&syn::File {
            shebang: None,
            attrs: Vec::new(),
            items: vec![item],
        });
        text.push_str(&notes::insert(&printed, notes));
    }
    text
}

/// `pub const NAME: ty = value;` with a one-line doc.
fn constant(doc: &str, name: &str, ty: syn::Type, value: &Expr) -> syn::Item {
    let doc = format!(" {doc}");
    let name = ident(name);
    parse_quote! {
        #[doc = #doc]
        pub const #name: #ty = #value;
    }
}

/// `body.coordinate` for every unknown.
fn unknown_names(mech: &Mechanism, sys: &Symbolic) -> Vec<String> {
    const COORDINATE: [&str; 7] = ["x", "y", "z", "e0", "e1", "e2", "e3"];
    sys.unknowns
        .iter()
        .map(|&(b, c)| format!("{}.{}", mech.bodies[b.0].name, COORDINATE[c]))
        .collect()
}

/// The module's constants: sizes, names, the time grid, the solver options and Q0.
fn constants(mech: &Mechanism, sys: &Symbolic, bodies: usize) -> Vec<syn::Item> {
    let n = index(sys.unknowns.len());
    let nb = index(bodies);
    let body_names = mech.bodies.iter().filter(|b| !b.ground).map(|b| b.name.as_str());
    let unknowns = unknown_names(mech, sys);
    let rows = sys.rows.iter().map(crate::model::RowLabel::equation);
    let grid = &mech.time;
    let max_it = Literal::u32_unsuffixed(mech.solver.max_iterations);
    let q0 = sys.unknowns.iter().map(|&(b, c)| {
        let body = &mech.bodies[b.0];
        literal_signed(if c < 3 { body.r[c] } else { body.p[c - 3] })
    });
    vec![
        parse_quote! {
            /// Number of unknowns (and of equations) of the reduced system.
            pub const N: usize = #n;
        },
        parse_quote! {
            /// Number of moving bodies reported by [`expand`].
            pub const BODIES: usize = #nb;
        },
        parse_quote! {
            /// Names of the moving bodies, in the order of [`expand`].
            pub const BODY_NAMES: [&str; BODIES] = [#(#body_names),*];
        },
        parse_quote! {
            /// The body coordinate each unknown stands for.
            pub const UNKNOWNS: [&str; N] = [#(#unknowns),*];
        },
        parse_quote! {
            /// The equation of each row.
            pub const EQUATIONS: [&str; N] = [#(#rows),*];
        },
        constant(
            "First time point of the description's grid.",
            "T_START",
            parse_quote!(f64),
            &literal_signed(grid.start),
        ),
        constant("Spacing of the grid.", "T_STEP", parse_quote!(f64), &literal_signed(grid.step)),
        {
            let count = index(grid.count);
            parse_quote! {
                /// Number of time points of the grid.
                pub const T_COUNT: usize = #count;
            }
        },
        constant(
            "Newton tolerance on max |Φ_i| from the description.",
            "TOLERANCE",
            parse_quote!(f64),
            &literal_signed(mech.solver.tolerance),
        ),
        parse_quote! {
            /// Newton iteration bound from the description.
            pub const MAX_ITERATIONS: u32 = #max_it;
        },
        parse_quote! {
            /// Initial estimates of the unknowns.
            pub const Q0: [f64; N] = [#(#q0),*];
        },
    ]
}

/// The rows of the reduced system as the outputs of emitted functions.
struct Rows<'s> {
    sys: &'s Symbolic,
    /// Locality of each row when a function is split: its last unknown.
    key: Vec<usize>,
}

impl<'s> Rows<'s> {
    fn new(sys: &'s Symbolic) -> Self {
        let key =
            sys.jac.iter().map(|row| row.iter().map(|&(c, _)| c).max().unwrap_or(0)).collect();
        Rows { sys, key }
    }

    /// Whether the module has input drivers (its functions then take the inputs).
    fn inputs(&self) -> bool {
        !self.sys.inputs.is_empty()
    }

    /// `name[i] = values[i]` for every row i, written to the function's array `array`.
    fn vector(&self, array: usize, name: &str, values: &[ExprId]) -> Vec<Output> {
        values
            .iter()
            .enumerate()
            .map(|(i, &value)| Output {
                target: element(name, &[i]),
                array,
                value,
                key: self.key[i],
                row: Some(i),
            })
            .collect()
    }

    /// `jac[i][j] = ∂Φ_i/∂q_j` for the structural non-zeros (only those that depend on q or t
    /// when `only_varying`), written to the function's array `array`.
    fn jacobian(&self, array: usize, only_varying: bool) -> Vec<Output> {
        let pool = &self.sys.pool;
        let mut out = Vec::new();
        for (i, row) in self.sys.jac.iter().enumerate() {
            for &(c, value) in row {
                if !only_varying || pool.as_const(value).is_none() {
                    let target = element("jac", &[i, c]);
                    out.push(Output { target, array, value, key: self.key[i], row: Some(i) });
                }
            }
        }
        out
    }

    /// The function `name` (see [`emit_function`]), its doc `what` followed by its counts.
    fn emit(
        &self,
        sig: &Signature<'_>,
        what: &str,
        prefix: Vec<syn::Stmt>,
        outputs: &[Output],
    ) -> Vec<syn::Item> {
        let doc =
            |ops, shared| format!(" {what}\n\n {ops} operations, {shared} shared subexpressions.");
        let kept = self.sys.derived_nodes();
        emit_function(&self.sys.pool, self.sys.unknowns.len(), sig, &doc, prefix, outputs, &kept)
    }
}

/// `residual`, then (when `whole`) `jacobian` and `residual_jacobian` and, for the static
/// orders' factorisations (`structural`), `residual_jacobian_structural`.
fn residual_and_jacobian(rows: &Rows<'_>, structural: bool, whole: bool) -> Vec<syn::Item> {
    let sys = rows.sys;
    let n = sys.unknowns.len();
    let vec_ty = quote::quote!(&mut [f64; N]);
    let mat_ty = quote::quote!(&mut [[f64; N]; N]);
    let zero_jac: syn::Stmt = parse_quote!(*jac = [[0.0; N]; N];);
    let mut items = Vec::new();
    let targets = [("phi", vec_ty.clone())];
    let sig = Signature {
        name: "residual",
        qd: false,
        qdd: false,
        public: true,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let what = format!("Constraint residuals Φ(q, t), {n} rows.");
    items.extend(rows.emit(&sig, &what, Vec::new(), &rows.vector(0, "phi", &sys.phi)));
    if !whole {
        return items;
    }

    let nnz = sys.jac.iter().map(Vec::len).sum::<usize>();
    let targets = [("jac", mat_ty.clone())];
    let sig = Signature {
        name: "jacobian",
        qd: false,
        qdd: false,
        public: true,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let what = format!(
        "Jacobian Φ_q, row-major: `jac[i][j] = ∂Φ_i/∂q_j`; the {nnz} structurally non-zero entries are written, the others set to 0."
    );
    items.extend(rows.emit(&sig, &what, vec![zero_jac.clone()], &rows.jacobian(0, false)));

    // Φ and Φ_q together, sharing subexpressions.
    let targets = [("phi", vec_ty), ("jac", mat_ty)];
    let mut both = rows.vector(0, "phi", &sys.phi);
    both.extend(rows.jacobian(1, false));
    let sig = Signature {
        name: "residual_jacobian",
        qd: false,
        qdd: false,
        public: true,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let what = "Φ and Φ_q at once (see [`residual`] and [`jacobian`]).";
    if !structural {
        items.extend(rows.emit(&sig, what, vec![zero_jac], &both));
        return items;
    }
    // With static orders, the constant entries of Φ_q and then `residual_jacobian_structural`,
    // so that the arithmetic of Φ and Φ_q is emitted once.
    let constants = rows.jacobian(1, false).into_iter().filter_map(|o| {
        let (target, value) = (o.target, literal_signed(sys.pool.as_const(o.value)?));
        Some::<syn::Stmt>(parse_quote!(#target = #value;))
    });
    let constants: Vec<syn::Stmt> = constants.collect();
    let inputs = rows.inputs().then(|| quote::quote!(inputs,));
    let doc = format!(
        " {what}\n\n The {} constant entries of Φ_q, then `residual_jacobian_structural` for Φ and the others.",
        constants.len()
    );
    let input_param = rows.inputs().then(|| quote::quote!(inputs: &Inputs,));
    items.push(parse_quote! {
        #[doc = #doc]
        pub fn residual_jacobian(q: &[f64; N], t: f64, #input_param phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
            #zero_jac
            #(#constants)*
            residual_jacobian_structural(q, t, #inputs phi, jac);
        }
    });

    // Φ and the entries of Φ_q that vary: the constant ones are literals in `factor_k`.
    let mut varying = rows.vector(0, "phi", &sys.phi);
    varying.extend(rows.jacobian(1, true));
    let count = varying.len() - n;
    let what = format!(
        "Φ and the {count} entries of Φ_q that depend on q or t, the others of `jac` left as they were: what the `factor_k` functions read ({} of the {nnz} structurally non-zero entries are constants, which they know).",
        nnz - count
    );
    let sig = Signature {
        name: "residual_jacobian_structural",
        qd: false,
        qdd: false,
        public: false,
        targets: &targets,
        inputs: rows.inputs(),
    };
    items.extend(rows.emit(&sig, &what, Vec::new(), &varying));
    items
}

/// `velocity_rhs` (ν) and `acceleration_rhs` (γ).
fn right_hand_sides(rows: &Rows<'_>) -> Vec<syn::Item> {
    let sys = rows.sys;
    let vec_ty = quote::quote!(&mut [f64; N]);
    let targets = [("nu", vec_ty.clone())];
    let sig = Signature {
        name: "velocity_rhs",
        qd: false,
        qdd: false,
        public: true,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let mut items = rows.emit(
        &sig,
        "Velocity right-hand side ν = −Φ_t.",
        Vec::new(),
        &rows.vector(0, "nu", &sys.nu),
    );
    let targets = [("gamma", vec_ty)];
    let sig = Signature {
        name: "acceleration_rhs",
        qd: true,
        qdd: false,
        public: true,
        targets: &targets,
        inputs: rows.inputs(),
    };
    items.extend(rows.emit(
        &sig,
        "Acceleration right-hand side γ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt.",
        Vec::new(),
        &rows.vector(0, "gamma", &sys.gamma),
    ));
    items
}

/// The bodies' unknown Euler parameters, as `normalize` and `normalize_moved` rescale them:
/// for each body with some, their indices, the target 1 − Σ (fixed parameters)² of their
/// squares, and the sum of their squares from the first one (0 + x = x exactly for x = q² ≥ 0).
fn euler_groups(sys: &Symbolic) -> Vec<(Vec<Literal>, Expr, Expr)> {
    let mut groups = Vec::new();
    for c in &sys.coords {
        let free: Vec<Literal> = c[3..]
            .iter()
            .filter_map(|s| if let Source::Unknown(k) = *s { Some(index(k)) } else { None })
            .collect();
        if free.is_empty() {
            continue;
        }
        let fixed: f64 =
            c[3..].iter().map(|s| if let Source::Fixed(v) = *s { v * v } else { 0.0 }).sum();
        let squares = free
            .iter()
            .map(|k| -> Expr { parse_quote!(q[#k] * q[#k]) })
            .reduce(|a, b| binary(a, syn::BinOp::Add(Default::default()), b))
            .expect("at least one free parameter");
        groups.push((free, literal_signed(1.0 - fixed), squares));
    }
    groups
}

/// `normalize_moved`: `normalize`, telling whether it moved a coordinate by more than
/// `runtime::newton::ROUND_OFF_MOVE` ulps of itself (`runtime::Mechanism::normalize_moved`),
/// by the test of `runtime::newton::moved_by_round_off` on each coordinate it rescales, as it
/// rescales it: no copy of q, no pass over the coordinates it does not touch.
fn normalize_moved(sys: &Symbolic) -> syn::Item {
    let stmts: Vec<syn::Stmt> = euler_groups(sys)
        .into_iter()
        .map(|(free, target, squares)| {
            parse_quote! {
                {
                    let free = #squares;
                    if free > 0.0 {
                        let scale = runtime::math::sqrt(#target / free);
                        #(
                            let before = q[#free];
                            q[#free] *= scale;
                            within &= (q[#free] - before).abs() <= bound * before.abs();
                        )*
                    }
                }
            }
        })
        .collect();
    if stmts.is_empty() {
        return parse_quote! {
            /// [`normalize`], which moves nothing here: returns false.
            pub fn normalize_moved(_q: &mut [f64; N]) -> bool {
                false
            }
        };
    }
    parse_quote! {
        /// [`normalize`], returning whether it moved a coordinate by more than
        /// `runtime::newton::ROUND_OFF_MOVE` ulps of itself.
        pub fn normalize_moved(q: &mut [f64; N]) -> bool {
            let bound = runtime::newton::round_off_move_bound::<f64>();
            let mut within = true;
            #(#stmts)*
            !within
        }
    }
}

/// `normalize`: each body's unknown Euler parameters rescaled so that |p| = 1.
fn normalize(sys: &Symbolic) -> syn::Item {
    let stmts: Vec<syn::Stmt> = euler_groups(sys)
        .into_iter()
        .map(|(free, target, squares)| {
            parse_quote! {
                {
                    let free = #squares;
                    if free > 0.0 {
                        let scale = runtime::math::sqrt(#target / free);
                        #(q[#free] *= scale;)*
                    }
                }
            }
        })
        .collect();
    let qn = param("q", !stmts.is_empty());
    parse_quote! {
        /// Rescales the unknown Euler parameters of each body so that |p| = 1 (the fixed
        /// ones keep their values).
        pub fn normalize(#qn: &mut [f64; N]) {
            #(#stmts)*
        }
    }
}

/// What `expand` writes: the statements that copy unknowns and fixed values, and the outputs
/// computed from driver laws and substituted coordinates with their places in `out` flattened
/// (also `time::items`' `expand_at`).
fn expand_outputs(sys: &Symbolic, moving: &[usize]) -> (Vec<syn::Stmt>, Vec<Output>, Vec<usize>) {
    let mut outputs: Vec<Output> = Vec::new();
    // Each output's place in `out` flattened: 21 b + 7 d + i.
    let mut places: Vec<usize> = Vec::new();
    let mut direct: Vec<syn::Stmt> = Vec::new();
    for (slot, &b) in moving.iter().enumerate() {
        for (i, s) in sys.coords[b].iter().enumerate() {
            let (sl, il) = (index(slot), index(i));
            match *s {
                Source::Unknown(k) => {
                    let k = index(k);
                    direct.push(parse_quote!(out[#sl][0][#il] = q[#k];));
                    direct.push(parse_quote!(out[#sl][1][#il] = qd[#k];));
                    direct.push(parse_quote!(out[#sl][2][#il] = qdd[#k];));
                }
                Source::Fixed(v) => {
                    let v = literal_signed(v);
                    direct.push(parse_quote!(out[#sl][0][#il] = #v;));
                    direct.push(parse_quote!(out[#sl][1][#il] = 0.0;));
                    direct.push(parse_quote!(out[#sl][2][#il] = 0.0;));
                }
                Source::Driven(l) => {
                    for (d, e) in sys.laws[l].iter().enumerate() {
                        places.push(21 * slot + 7 * d + i);
                        let d = index(d);
                        let target = parse_quote!(out[#sl][#d][#il]);
                        outputs.push(Output { target, array: 0, value: *e, key: slot, row: None });
                    }
                }
                Source::Derived(k) => {
                    for (d, e) in sys.derived[k].value.iter().enumerate() {
                        places.push(21 * slot + 7 * d + i);
                        let d = index(d);
                        let target = parse_quote!(out[#sl][#d][#il]);
                        outputs.push(Output { target, array: 0, value: *e, key: slot, row: None });
                    }
                }
            }
        }
    }
    (direct, outputs, places)
}

/// `expand`: the full coordinates of the moving bodies, with their rates and accelerations;
/// split into helpers as [`emit_function`] splits when longer than [`CHUNK_OPS`] operations
/// (the substituted coordinates of a long explicit chain), or shared between groups of bodies
/// alike ([`expand_shared`]).
fn expand(sys: &Symbolic, moving: &[usize]) -> Vec<syn::Item> {
    let n = sys.unknowns.len();
    let (direct, outputs, places) = expand_outputs(sys, moving);
    if let Some(items) = expand_shared(sys, moving.len(), &outputs, &places, &direct) {
        return items;
    }
    let whole: Vec<(Expr, ExprId, Option<usize>)> =
        outputs.iter().map(|o| (o.target.clone(), o.value, o.row)).collect();
    let f = function(&sys.pool, n, &whole);
    if f.ops > CHUNK_OPS {
        let targets = [("out", quote::quote!(&mut [[[f64; 7]; 3]; BODIES]))];
        let sig = Signature {
            name: "expand",
            qd: true,
            qdd: true,
            public: true,
            targets: &targets,
            inputs: !sys.inputs.is_empty(),
        };
        let doc = |ops: usize, shared: usize| {
            format!(
                " Full coordinates of every moving body (in [`BODY_NAMES`] order): `out[b][0]` \
                 is `[x, y, z, e0, e1, e2, e3]`, `out[b][1]` its rates and `out[b][2]` its \
                 accelerations, with fixed, driven and substituted coordinates filled in \
                 ({ops} operations, {shared} shared subexpressions)."
            )
        };
        return emit_function(&sys.pool, n, &sig, &doc, direct, &outputs, &sys.derived_nodes());
    }
    let any = n > 0;
    let (qn, qdn, qddn) = (param("q", any), param("qd", any), param("qdd", any));
    let tn = param("t", f.uses_t);
    let stmts = &f.stmts;
    if !sys.inputs.is_empty() {
        let un = param("inputs", f.uses_u);
        let read: Option<syn::Stmt> = f.uses_u.then(|| parse_quote!(let u = inputs.to_array();));
        return vec![parse_quote! {
            /// Full coordinates of every moving body (in [`BODY_NAMES`] order) at the inputs
            /// `inputs`: `out[b][0]` is `[x, y, z, e0, e1, e2, e3]`, `out[b][1]` its rates and
            /// `out[b][2]` its accelerations, with fixed, driven and substituted coordinates
            /// filled in.
            pub fn expand(#qn: &[f64; N], #qdn: &[f64; N], #qddn: &[f64; N], #tn: f64, #un: &Inputs, out: &mut [[[f64; 7]; 3]; BODIES]) {
                #(#direct)*
                #read
                #(#stmts)*
            }
        }];
    }
    vec![parse_quote! {
        /// Full coordinates of every moving body (in [`BODY_NAMES`] order): `out[b][0]` is
        /// `[x, y, z, e0, e1, e2, e3]`, `out[b][1]` its rates and `out[b][2]` its
        /// accelerations, with fixed, driven and substituted coordinates filled in.
        pub fn expand(#qn: &[f64; N], #qdn: &[f64; N], #qddn: &[f64; N], #tn: f64, out: &mut [[[f64; 7]; 3]; BODIES]) {
            #(#direct)*
            #(#stmts)*
        }
    }]
}

/// `expand` when groups of bodies alike run one shared function (`emit::shared`): the bodies
/// whose coordinates are expressions of each other's form a group (ten independent arms, ten
/// groups); groups whose expressions are the same up to their constants and places share one
/// function `expand_shared_s(m, …)`, called for each of them in a loop, so that every copy
/// runs the same machine code and stays in the instruction cache. The other outputs go to
/// `expand_rest`. `None` when no two groups are alike.
fn expand_shared(
    sys: &Symbolic,
    bodies: usize,
    outputs: &[Output],
    places: &[usize],
    direct: &[syn::Stmt],
) -> Option<Vec<syn::Item>> {
    use std::collections::HashMap;
    // The groups: union of the bodies an output's expression reaches through another body's
    // output (which it then reads rather than repeats).
    let owner: HashMap<usize, usize> = outputs
        .iter()
        .filter(|o| !sys.pool.is_leaf(o.value))
        .map(|o| (o.value.index(), o.key))
        .collect();
    let mut parent: Vec<usize> = (0..bodies).collect();
    fn root(parent: &mut [usize], mut x: usize) -> usize {
        while parent[x] != x {
            parent[x] = parent[parent[x]];
            x = parent[x];
        }
        x
    }
    for body in 0..bodies {
        let mut stack: Vec<ExprId> = outputs
            .iter()
            .filter(|o| o.key == body)
            .flat_map(|o| sys.pool[o.value].children())
            .collect();
        let mut seen = std::collections::HashSet::new();
        while let Some(x) = stack.pop() {
            if !seen.insert(x.index()) {
                continue;
            }
            match owner.get(&x.index()) {
                Some(&other) if other != body => {
                    let (a, b) = (root(&mut parent, body), root(&mut parent, other));
                    parent[a.max(b)] = a.min(b);
                }
                _ => stack.extend(sys.pool[x].children()),
            }
        }
    }
    let mut group_of: HashMap<usize, usize> = HashMap::new();
    let mut functions: Vec<Option<Vec<shared::Output>>> = Vec::new();
    let mut member: Vec<usize> = Vec::with_capacity(outputs.len());
    for (o, &place) in outputs.iter().zip(places) {
        let r = root(&mut parent, o.key);
        let next = functions.len();
        let g = *group_of.entry(r).or_insert(next);
        if g == functions.len() {
            functions.push(Some(Vec::new()));
        }
        functions[g].as_mut().expect("a group").push((shared::Array::Out, place, Some(o.value)));
        member.push(g);
    }
    let sharing = shared::Sharing::of(&sys.pool, &functions);
    if !sharing.any() {
        return None;
    }
    let inputs = !sys.inputs.is_empty();
    let ty = quote::quote!(&mut [[[f64; 7]; 3]; BODIES]);
    let targets = [("out", ty)];
    let mut items = sharing.items(
        "expand",
        &Signature {
            name: "expand",
            qd: true,
            qdd: true,
            public: false,
            targets: &targets,
            inputs,
        },
        "Full coordinates",
    );
    let args = if inputs {
        quote::quote!(q, qd, qdd, t, &u, out)
    } else {
        quote::quote!(q, qd, qdd, t, out)
    };
    let loops = sharing.calls_shared("expand", &args);
    let rest: Vec<Output> = outputs
        .iter()
        .zip(&member)
        .filter(|(_, g)| sharing.shared(**g).is_none())
        .map(|(o, _)| Output {
            target: o.target.clone(),
            array: 0,
            value: o.value,
            key: o.key,
            row: None,
        })
        .collect();
    let mut calls: Vec<syn::Stmt> = direct.to_vec();
    if inputs {
        calls.push(parse_quote!(let u = inputs.to_array();));
    }
    calls.extend(loops.into_iter().map(|l| -> syn::Stmt { parse_quote!(#l) }));
    if !rest.is_empty() {
        let sig = Signature {
            name: "expand_rest",
            qd: true,
            qdd: true,
            public: false,
            targets: &targets,
            inputs,
        };
        let doc = |ops: usize, shared: usize| {
            format!(
                " The full coordinates of the bodies [`expand`] does not compute in a shared \
                 function ({ops} operations, {shared} shared subexpressions)."
            )
        };
        items.extend(emit_function(
            &sys.pool,
            sys.unknowns.len(),
            &sig,
            &doc,
            Vec::new(),
            &rest,
            &sys.derived_nodes(),
        ));
        calls.push(if inputs {
            parse_quote!(expand_rest(q, qd, qdd, t, inputs, out);)
        } else {
            parse_quote!(expand_rest(q, qd, qdd, t, out);)
        });
    }
    let what = " Full coordinates of every moving body (in [`BODY_NAMES`] order): `out[b][0]` is \
                `[x, y, z, e0, e1, e2, e3]`, `out[b][1]` its rates and `out[b][2]` its \
                accelerations, with fixed, driven and substituted coordinates filled in; groups \
                of bodies alike share one function.";
    let item: syn::Item = if inputs {
        parse_quote! {
            #[doc = #what]
            pub fn expand(q: &[f64; N], qd: &[f64; N], qdd: &[f64; N], t: f64, inputs: &Inputs, out: &mut [[[f64; 7]; 3]; BODIES]) {
                #(#calls)*
            }
        }
    } else {
        parse_quote! {
            #[doc = #what]
            pub fn expand(q: &[f64; N], qd: &[f64; N], qdd: &[f64; N], t: f64, out: &mut [[[f64; 7]; 3]; BODIES]) {
                #(#calls)*
            }
        }
    };
    items.insert(0, item);
    Some(items)
}

/// The unit struct and its `runtime::Mechanism` impl, with the structured LU's items.
fn mechanism_type(mech: &Mechanism, structured: Vec<syn::ImplItem>) -> Vec<syn::Item> {
    let ty = ident(&type_name(&mech.name));
    let doc = format!(" The mechanism `{}` as a [`runtime::Mechanism`].", mech.name);
    vec![
        parse_quote! {
            #[doc = #doc]
            #[derive(Clone, Copy, Debug, Default)]
            pub struct #ty;
        },
        parse_quote! {
            impl runtime::Mechanism<N> for #ty {
                fn residual(&self, q: &[f64; N], t: f64, phi: &mut [f64; N]) {
                    residual(q, t, phi);
                }
                fn jacobian(&self, q: &[f64; N], t: f64, jac: &mut [[f64; N]; N]) {
                    jacobian(q, t, jac);
                }
                fn residual_jacobian(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                    residual_jacobian(q, t, phi, jac);
                }
                fn velocity_rhs(&self, q: &[f64; N], t: f64, nu: &mut [f64; N]) {
                    velocity_rhs(q, t, nu);
                }
                fn acceleration_rhs(&self, q: &[f64; N], qd: &[f64; N], t: f64, gamma: &mut [f64; N]) {
                    acceleration_rhs(q, qd, t, gamma);
                }
                fn normalize(&self, q: &mut [f64; N]) {
                    normalize(q);
                }
                #(#structured)*
            }
        },
    ]
}

/// The impl items of the structured LU for `orders` static orders (none without orders), for
/// a mechanism whose functions take its inputs at t when `inputs`.
fn structured_items(orders: usize, inputs: bool) -> Vec<syn::ImplItem> {
    if orders == 0 {
        return Vec::new();
    }
    let count = index(orders);
    let factor_arms = (0..orders).map(|k| {
        let (lit, f) = (index(k), ident(&format!("factor_{k}")));
        quote::quote!(#lit => #f(jac),)
    });
    let solve_arms = (0..orders).map(|k| {
        let (lit, f) = (index(k), ident(&format!("solve_{k}")));
        quote::quote!(#lit => #f(lu, b),)
    });
    let solve: syn::ImplItem = if orders == 1 {
        parse_quote! {
            fn solve_structured(&self, order: usize, lu: &[[f64; N]; N], b: &mut [f64; N]) {
                if order == 0 {
                    solve_0(lu, b);
                }
            }
        }
    } else {
        parse_quote! {
            fn solve_structured(&self, order: usize, lu: &[[f64; N]; N], b: &mut [f64; N]) {
                match order {
                    #(#solve_arms)*
                    _ => {}
                }
            }
        }
    };
    vec![
        parse_quote!(const PIVOT_ORDERS: usize = #count;),
        if inputs {
            parse_quote! {
                fn residual_jacobian_structural(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                    residual_jacobian_structural(q, t, &self.inputs(t), phi, jac);
                }
            }
        } else {
            parse_quote! {
                fn residual_jacobian_structural(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                    residual_jacobian_structural(q, t, phi, jac);
                }
            }
        },
        parse_quote! {
            fn factor_structured(&self, order: usize, jac: &mut [[f64; N]; N]) -> Option<runtime::lu::PivotInfo> {
                match order {
                    #(#factor_arms)*
                    _ => None,
                }
            }
        },
        solve,
    ]
}

/// The module's inner documentation: what was eliminated and left out, the source, the
/// description (fenced) and an example.
fn module_docs(mech: &Mechanism, sys: &Symbolic, source: &str, scalar: Scalar) -> Vec<String> {
    let n = sys.unknowns.len();
    let float = if scalar == Scalar::F32 { "f32" } else { "f64" };
    let labels = |rows: &[crate::model::RowLabel]| {
        rows.iter().map(|r| markdown_escaped(&r.equation())).collect::<Vec<_>>().join(", ")
    };
    let mut docs = vec![format!(
        " The mechanism `{name}`: {n} unknowns and {n} equations after eliminating {} (ground bodies carry none).",
        if sys.eliminated.is_empty() { "nothing".to_owned() } else { labels(&sys.eliminated) },
        name = mech.name,
    )];
    if !sys.redundant.is_empty() {
        docs.push(format!(" Redundant equations left out: {}.", labels(&sys.redundant)));
    }
    docs.push(String::new());
    docs.push(format!(" Generated by mechgen from {}.", markdown_escaped(source)));
    if let Some(description) = &mech.description {
        docs.push(" Its description:".to_owned());
        docs.push(String::new());
        docs.extend(fenced(description));
    }
    docs.extend(
        format!(
            "
 # Example

 Every time point of the description's grid: positions by Newton's method, then
 velocities and accelerations with the same factors of Φ_q (the module's path depends
 on where it is included, so the example is not compiled as a test here).

 ```text
 let mut solver = runtime::Solver::new({m}::{ty}, {m}::Q0);
 for k in 0..{m}::T_COUNT {{
     let t = {m}::T_START + k as {float} * {m}::T_STEP;
     solver.position(t)?; // Φ(q, t) = 0
     solver.velocity()?; // Φ_q q̇ = ν
     solver.acceleration()?; // Φ_q q̈ = γ
     let (q, qd, qdd) = (solver.q(), solver.qd(), solver.qdd());
 }}
 ```

 # Named outputs

 Names are strings in tables (`BODY_NAMES`, `POINT_NAMES`, `JOINT_NAMES`,
 `JOINT_COORDINATE_NAMES`, `UNKNOWNS`) with `const fn` lookups (`body`, `point`, `joint`,
 `joint_coordinate`, `unknown`): in a `const`, a misspelt name does not compile. Names that
 are plain identifiers also have index constants in the submodules of the same names
 (`body::CRANK`), which hold nothing else. The accessors read the solver's state:
 `point_positions`, `point_velocities`, `point_accelerations` (global r, v, a),
 `poses` (r and p), `angular_velocities`, `angular_accelerations` (ω = 2 G ṗ, α = 2 G p̈,
 global) and `joint_coordinates` (angle in (−π, π] or translation, with rate and
 acceleration); none allocates or panics.

 ```text
 let mut points = [[0.0; 3]; {m}::POINTS];
 {m}::point_positions(solver.q(), t, &mut points);
 let mut joints = [[0.0; 3]; {m}::JOINT_COORDINATES];
 {m}::joint_coordinates(solver.q(), solver.qd(), solver.qdd(), t, &mut joints);
 // A continuous angle across turns, from the previous period's value:
 // angle = runtime::outputs::unwrap_angle(angle, joints[k][0]);
 let status = runtime::Status::of(&solver.position(t)); // iterations, residual, outcome
 ```",
            m = mech.name,
            ty = type_name(&mech.name),
        )
        .lines()
        .map(str::to_owned),
    );
    if scalar == Scalar::F32 {
        docs.extend(
            ["", " Single precision: every value, literal and operation is `f32`."]
                .map(String::from),
        );
    }
    docs
}

#[cfg(test)]
mod tests;
