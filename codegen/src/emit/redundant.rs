//! The rows of the reduced system left out as dependent on the kept ones, for the run-time
//! check that every equation of the description holds: `DROPPED`, `DROPPED_EQUATIONS`, the
//! balanced-unit factors of every row (`ROW_FACTORS`, `DROPPED_ROW_FACTORS`) and
//! `dropped_residuals`; and, for the run-time solver's re-selection of rows
//! (`runtime::rows`), their Φ, Φ_q, ν and γ (`left_out_residual_jacobian`,
//! `left_out_velocity_rhs`, `left_out_acceleration_rhs`) with the `runtime::Mechanism` items
//! that call them ([`impl_items`]). A module without left-out rows has none of them.

use syn::parse_quote;

use super::Rows;
use super::function::{Output, Signature};
use super::syntax::{element, ident, index, literal};
use crate::expr::ExprId;
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
    items.extend(rows_of(sys, rows));
    items
}

/// `name[k] = values[k]` for every left-out row k, written to the function's array `array`.
fn vector(array: usize, name: &str, values: impl Iterator<Item = ExprId>) -> Vec<Output> {
    values
        .enumerate()
        .map(|(k, value)| Output { target: element(name, &[k]), array, value, key: k, row: None })
        .collect()
}

/// `left_out_residual_jacobian`, `left_out_velocity_rhs` and `left_out_acceleration_rhs`:
/// the left-out rows as the run-time solver substitutes them for kept ones.
fn rows_of(sys: &Symbolic, rows: &Rows<'_>) -> Vec<syn::Item> {
    let ty = ident("DROPPED");
    let vec_ty = quote::quote!(&mut [f64; #ty]);
    let mat_ty = quote::quote!(&mut [[f64; N]; #ty]);
    let mut outputs = vector(0, "phi", sys.dropped.iter().map(|d| d.residuals[0]));
    for (k, d) in sys.dropped.iter().enumerate() {
        outputs.extend(d.jac.iter().map(|&(c, value)| Output {
            target: element("jac", &[k, c]),
            array: 1,
            value,
            key: k,
            row: None,
        }));
    }
    let targets = [("phi", vec_ty.clone()), ("jac", mat_ty)];
    let sig = Signature {
        name: "left_out_residual_jacobian",
        qd: false,
        qdd: false,
        public: true,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let zero: syn::Stmt = parse_quote!(*jac = [[0.0; N]; DROPPED];);
    let what = "Φ and the rows of Φ_q of the equations left out ([`DROPPED_EQUATIONS`]), the structurally zero entries set to 0.";
    let mut items = rows.emit(&sig, what, vec![zero], &outputs);
    let targets = [("nu", vec_ty.clone())];
    let sig = Signature { name: "left_out_velocity_rhs", targets: &targets, ..sig };
    let what = "ν = −Φ_t of the equations left out ([`DROPPED_EQUATIONS`]).";
    let nu = vector(0, "nu", sys.dropped.iter().map(|d| d.rates[0]));
    items.extend(rows.emit(&sig, what, Vec::new(), &nu));
    let targets = [("gamma", vec_ty)];
    let sig = Signature { name: "left_out_acceleration_rhs", qd: true, targets: &targets, ..sig };
    let what = "γ of the equations left out ([`DROPPED_EQUATIONS`]).";
    let gamma = vector(0, "gamma", sys.dropped.iter().map(|d| d.rates[1]));
    items.extend(rows.emit(&sig, what, Vec::new(), &gamma));
    items
}

/// The `runtime::Mechanism` items of the left-out rows (none without them), for a mechanism
/// whose functions take its inputs at t when `inputs`: the runtime passes slices of at most
/// `DROPPED` rows, filled from the module's arrays.
pub(super) fn impl_items(sys: &Symbolic, inputs: bool) -> Vec<syn::ImplItem> {
    if sys.dropped.is_empty() {
        return Vec::new();
    }
    let u = if inputs { quote::quote!(&self.inputs(t),) } else { quote::quote!() };
    vec![
        parse_quote!(
            const LEFT_OUT: usize = DROPPED;
        ),
        parse_quote! {
            fn left_out_residual_jacobian(&self, q: &[f64; N], t: f64, phi: &mut [f64], jac: &mut [[f64; N]]) {
                let (mut p, mut j) = ([0.0; DROPPED], [[0.0; N]; DROPPED]);
                left_out_residual_jacobian(q, t, #u &mut p, &mut j);
                for ((a, b), (x, y)) in phi.iter_mut().zip(jac.iter_mut()).zip(p.iter().zip(&j)) {
                    *a = *x;
                    *b = *y;
                }
            }
        },
        parse_quote! {
            fn left_out_velocity_rhs(&self, q: &[f64; N], t: f64, nu: &mut [f64]) {
                let mut x = [0.0; DROPPED];
                left_out_velocity_rhs(q, t, #u &mut x);
                for (a, b) in nu.iter_mut().zip(&x) {
                    *a = *b;
                }
            }
        },
        parse_quote! {
            fn left_out_acceleration_rhs(&self, q: &[f64; N], qd: &[f64; N], t: f64, gamma: &mut [f64]) {
                let mut x = [0.0; DROPPED];
                left_out_acceleration_rhs(q, qd, t, #u &mut x);
                for (a, b) in gamma.iter_mut().zip(&x) {
                    *a = *b;
                }
            }
        },
    ]
}
