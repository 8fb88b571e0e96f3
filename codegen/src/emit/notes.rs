//! The `//` comments of the emitted code: before each group of assignments, the equation row
//! it computes and the row's form (`// joint O2 row 4: b_i · a_j = 0`).
//!
//! prettyplease prints no ordinary comments, so the functions carry a marker statement
//! `__mechgen_note!(i);` where a note for row i belongs, and [`insert`] replaces every line
//! that is exactly such a marker by the comment, after printing. Only the emitter writes
//! statements: every name of the description reaches the code inside a string literal or a
//! doc line (`"…"`, `///`), never as a line of its own, so no text of the description can
//! pose as a marker. The notes themselves are single lines of our own text, with the names
//! they quote made safe by [`doc_safe`] (controls, line separators and other invisible
//! characters as visible escapes), so a comment can neither end early nor start a new line.

use syn::parse_quote;

use super::docs::doc_safe;
use crate::desc::{DriverCoordinate, Motion};
use crate::model::RowLabel;
use crate::model::{ConstraintKind, DriverTarget, JointKind, Law, Mechanism};

/// The row of a U-P-S leg reduced to a distance (`symbolic::legs`): U and S its end points on
/// the bodies it joins, v0 and a its constant offset and axis, L its assembled length.
const LEG_FORM: &str = "(|S − U|² − s² − 2 s v0·a − |v0|²) / (2 L)";

/// The name of the marker macro; nothing else in an emitted module is called this.
const MARKER: &str = "__mechgen_note";

/// The marker statement for the note of row `row`.
pub(super) fn marker(row: usize) -> syn::Stmt {
    let name = super::syntax::ident(MARKER);
    let row = super::syntax::index(row);
    parse_quote!(#name!(#row);)
}

/// The note of every row of the reduced system: `joint O2 row 4: b_i · a_j = 0`; the driver
/// rows of the reduced legs (`legs`, driver indices) are their distance rows.
pub(super) fn row_notes(mech: &Mechanism, rows: &[RowLabel], legs: &[usize]) -> Vec<String> {
    let reduced = |label: &RowLabel| {
        label.kind == RowLabel::DRIVER
            && legs.iter().any(|&k| mech.drivers.get(k).is_some_and(|d| d.name == label.name))
    };
    rows.iter()
        .map(|label| {
            let form = if reduced(label) {
                let d = mech.drivers.iter().find(|d| d.name == label.name).expect("a driver");
                format!("{LEG_FORM} = 0 (leg reduced), s = {}", law(&d.law))
            } else {
                form(mech, label)
            };
            let text = format!("{}: {form}", label.equation());
            let line = doc_safe(&text);
            assert!(!line.contains(['\n', '\r']), "a note is one line");
            line
        })
        .collect()
}

/// `text` with each marker line replaced by its note, indented as the marker was.
///
/// # Panics
///
/// When a marker names a row without a note (an emitter bug).
pub(super) fn insert(text: &str, notes: &[String]) -> String {
    let mut out = String::with_capacity(text.len());
    for line in text.split_inclusive('\n') {
        let body = line.trim_end_matches('\n');
        let code = body.trim_start();
        let row = code
            .strip_prefix(MARKER)
            .and_then(|r| r.strip_prefix("!("))
            .and_then(|r| r.strip_suffix(");"))
            .filter(|r| !r.is_empty() && r.bytes().all(|b| b.is_ascii_digit()));
        match row {
            Some(row) => {
                let row: usize = row.parse().expect("a row index");
                out.push_str(&body[..body.len() - code.len()]);
                out.push_str("// ");
                out.push_str(&notes[row]);
                out.push('\n');
            }
            None => out.push_str(line),
        }
    }
    assert!(!out.contains(MARKER), "every marker is a line of its own");
    out
}

/// The equation a row states, in the symbols of the thesis: P the joint points, a the axes,
/// b and c the normals of axis_i, r the references, all as vectors of the global frame.
fn form(mech: &Mechanism, label: &RowLabel) -> String {
    let row = label.row;
    match label.kind {
        "joint" => mech
            .joints
            .iter()
            .find(|j| j.name == label.name)
            .map_or_else(String::new, |j| joint_form(j.kind, row).to_owned()),
        "constraint" => {
            let Some(c) = mech.constraints.iter().find(|c| c.name == label.name) else {
                return String::new();
            };
            match c.kind {
                ConstraintKind::Fix { coordinate, value, .. } => {
                    format!("{} − {value:?} = 0", coordinate.as_str())
                }
                ConstraintKind::CoordinateDifference { coordinate, value, .. } => {
                    let c = coordinate.as_str();
                    format!("{c}_i − {c}_j − {value:?} = 0")
                }
            }
        }
        "driver" => {
            let Some(d) = mech.drivers.iter().find(|d| d.name == label.name) else {
                return String::new();
            };
            let lhs = match d.target {
                DriverTarget::Joint { motion: Motion::Rotation, .. } => {
                    "r_i · r_j sin s − (r_i × r_j) · a_i cos s"
                }
                DriverTarget::Joint { motion: Motion::Translation, .. } => "(P_j − P_i) · a_i − s",
                DriverTarget::Absolute { coordinate, .. } => match coordinate {
                    DriverCoordinate::X => "x − s",
                    DriverCoordinate::Y => "y − s",
                    DriverCoordinate::Z => "z − s",
                    DriverCoordinate::Rx => "e1 cos(s/2) − e0 sin(s/2)",
                    DriverCoordinate::Ry => "e2 cos(s/2) − e0 sin(s/2)",
                    DriverCoordinate::Rz => "e3 cos(s/2) − e0 sin(s/2)",
                    DriverCoordinate::E1 => "e1 − s",
                    DriverCoordinate::E2 => "e2 − s",
                    DriverCoordinate::E3 => "e3 − s",
                },
                DriverTarget::Point { axis, .. } => ["r_P.x − s", "r_P.y − s", "r_P.z − s"][axis],
                DriverTarget::Leg(_) => LEG_FORM,
            };
            format!("{lhs} = 0, s = {}", law(&d.law))
        }
        "body" => "e0² + e1² + e2² + e3² − 1 = 0".to_owned(),
        _ => String::new(),
    }
}

/// s(t) as the description gives it, without its zero terms.
fn law(law: &Law) -> String {
    let terms: Vec<(f64, String)> = match *law {
        Law::Polynomial { start, velocity, acceleration } => vec![
            (start, String::new()),
            (velocity, " t".to_owned()),
            (acceleration, " t²/2".to_owned()),
        ],
        Law::Harmonic { offset, amplitude, frequency, phase } => {
            let argument = if phase == 0.0 {
                format!("{frequency:?} t")
            } else {
                format!("{frequency:?} t + {phase:?}")
            };
            vec![(offset, String::new()), (amplitude, format!(" sin({argument})"))]
        }
        Law::Input => return "the input".to_owned(),
    };
    let mut text = String::new();
    for (c, unit) in terms.into_iter().filter(|(c, _)| *c != 0.0) {
        match (text.is_empty(), c < 0.0) {
            (true, _) => text.push_str(&format!("{c:?}{unit}")),
            (false, true) => text.push_str(&format!(" − {:?}{unit}", -c)),
            (false, false) => text.push_str(&format!(" + {c:?}{unit}")),
        }
    }
    if text.is_empty() { "0".to_owned() } else { text }
}

/// Row `row` (from 1) of a joint of kind `kind`, in the order `symbolic` writes them.
fn joint_form(kind: JointKind, row: usize) -> &'static str {
    const POINTS: [&str; 3] = ["(P_j − P_i)_x = 0", "(P_j − P_i)_y = 0", "(P_j − P_i)_z = 0"];
    const PARALLEL: [&str; 4] =
        ["b_i · a_j = 0", "c_i · a_j = 0", "b_i · (P_j − P_i) = 0", "c_i · (P_j − P_i) = 0"];
    let k = row - 1;
    match kind {
        JointKind::Spherical => POINTS[k],
        JointKind::Universal if k < 3 => POINTS[k],
        JointKind::Universal => "a_i · a_j = 0",
        JointKind::Revolute if k < 3 => POINTS[k],
        JointKind::Revolute => PARALLEL[k - 3],
        JointKind::Cylindrical => PARALLEL[k],
        JointKind::Prismatic if k < 4 => PARALLEL[k],
        JointKind::Prismatic => "r_i · r_j = 0",
        JointKind::Screw { .. } if k < 4 => PARALLEL[k],
        JointKind::Screw { .. } => {
            "r_i · r_j sin θ − (r_i × r_j) · a_i cos θ = 0, θ = θ0 + 2π ((P_j − P_i) · a_i − d0) / lead"
        }
        JointKind::Distance { .. } => "(|P_j − P_i|² − L²) / (2 L) = 0",
    }
}
