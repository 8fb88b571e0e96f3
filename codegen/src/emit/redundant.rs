//! The rows of the reduced system left out as dependent on the kept ones, for the run-time
//! check that every equation of the description holds: `DROPPED`, `DROPPED_EQUATIONS`, the
//! balanced-unit factors of every row (`ROW_FACTORS`, `DROPPED_ROW_FACTORS`) and
//! `dropped_residuals`. A module without left-out rows has none of them.

use syn::parse_quote;

use super::Rows;
use super::function::{Output, Signature};
use super::syntax::{element, ident, index, literal};
use crate::symbolic::Symbolic;

/// The items of the left-out rows, or nothing when there are none.
pub(super) fn items(sys: &Symbolic, rows: &Rows<'_>) -> Vec<syn::Item> {
    if sys.dropped.is_empty() {
        return Vec::new();
    }
    let count = index(sys.dropped.len());
    let names: Vec<String> = sys.dropped.iter().map(|d| d.label.equation()).collect();
    let factors = sys.row_factors.iter().map(|&x| literal(x));
    let dropped_factors = sys.dropped.iter().map(|d| literal(d.factor));
    let mut items: Vec<syn::Item> = vec![
        parse_quote! {
            /// Number of equations of the description left out of the reduced system as
            /// dependent on the kept ones at the initial configuration (`dropped_residuals`).
            pub const DROPPED: usize = #count;
        },
        parse_quote! {
            /// The equations left out, as `check` and the generic engine name rows.
            pub const DROPPED_EQUATIONS: [&str; DROPPED] = [#(#names),*];
        },
        parse_quote! {
            /// For every row of `residual`, the factor that puts it in balanced units at the
            /// initial configuration: the reciprocal of the power of two nearest its largest
            /// entry of Φ_q, with the translational columns times the characteristic length.
            pub const ROW_FACTORS: [f64; N] = [#(#factors),*];
        },
        parse_quote! {
            /// [`ROW_FACTORS`] of the equations left out, in [`DROPPED_EQUATIONS`] order.
            pub const DROPPED_ROW_FACTORS: [f64; DROPPED] = [#(#dropped_factors),*];
        },
    ];
    let outputs: Vec<Output> = sys
        .dropped
        .iter()
        .enumerate()
        .flat_map(|(k, d)| {
            d.residuals.into_iter().enumerate().map(move |(c, value)| Output {
                target: element("out", &[k, c]),
                array: 0,
                value,
                key: k,
                row: None,
            })
        })
        .collect();
    let ty = ident("DROPPED");
    let targets = [("out", quote::quote!(&mut [[f64; 3]; #ty]))];
    let sig = Signature {
        name: "dropped_residuals",
        qd: true,
        qdd: true,
        public: true,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let what = "For every equation left out ([`DROPPED_EQUATIONS`]): `[Φ_i, Φ_q,i q̇ − ν_i, Φ_q,i q̈ − γ_i]`, the residuals of its position, velocity and acceleration equations, which vanish when it holds with the kept ones.";
    items.extend(rows.emit(&sig, what, Vec::new(), &outputs));
    items
}
