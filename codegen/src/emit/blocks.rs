//! The block-by-block LU: the layout of Φ_q's block-lower-triangular form
//! ([`crate::blocks`]) as a `static` the runtime's `blocks::factor` and `blocks::solve` read,
//! the function that evaluates what they read, and the `runtime::Mechanism` items that select
//! them instead of static pivot orders.

use syn::parse_quote;

use super::Rows;
use super::function::Signature;
use super::syntax::{element, index};
use crate::blocks::Blocks;
use crate::symbolic::Symbolic;

/// A system of at least this many unknowns is factored block by block when it has more than one
/// block: below it the static pivot orders' straight-line code is faster than the runtime's
/// loops over index tables (the R-S-S-R, 20 unknowns: see BENCHMARKS.md).
pub(super) const MIN_UNKNOWNS: usize = 64;

/// The blocks of `sys` when its solver factors Φ_q block by block.
pub(super) fn plan(sys: &Symbolic) -> Option<Blocks> {
    let n = sys.unknowns.len();
    if n < MIN_UNKNOWNS {
        return None;
    }
    let blocks = Blocks::of(sys);
    (blocks.blocks.len() > 1).then_some(blocks)
}

/// `static BLOCKS: runtime::blocks::Layout` and `residual_jacobian_blocks`.
pub(super) fn items(rows: &Rows<'_>, blocks: &Blocks) -> Vec<syn::Item> {
    let sys = rows.sys;
    let n = sys.unknowns.len();
    let mut block_of_column = vec![0; n];
    let (mut order_rows, mut order_columns, mut starts) = (Vec::new(), Vec::new(), vec![0]);
    for (b, block) in blocks.blocks.iter().enumerate() {
        order_rows.extend(&block.rows);
        order_columns.extend(&block.unknowns);
        starts.push(order_rows.len());
        for &c in &block.unknowns {
            block_of_column[c] = b;
        }
    }
    let mut block_of_row = vec![0; n];
    for (b, block) in blocks.blocks.iter().enumerate() {
        for &r in &block.rows {
            block_of_row[r] = b;
        }
    }
    let (mut lower, mut lower_starts) = (Vec::new(), vec![0]);
    for (r, row) in sys.jac.iter().enumerate() {
        lower.extend(row.iter().map(|&(c, _)| c).filter(|&c| block_of_column[c] < block_of_row[r]));
        lower_starts.push(lower.len());
    }
    let list = |v: &[usize]| {
        let v = v.iter().map(|&k| index(k));
        quote::quote!(&[#(#v),*])
    };
    let (r, c, s, l, ls) = (
        list(&order_rows),
        list(&order_columns),
        list(&starts),
        list(&lower),
        list(&lower_starts),
    );
    let doc = format!(
        " The block-lower-triangular form of Φ_q: {} blocks (the largest of {}), {} entries below them.",
        blocks.blocks.len(),
        blocks.blocks.iter().map(|b| b.rows.len()).max().unwrap_or(0),
        lower.len()
    );
    let mut items: Vec<syn::Item> = vec![parse_quote! {
        #[doc = #doc]
        static BLOCKS: runtime::blocks::Layout = runtime::blocks::Layout {
            rows: #r,
            columns: #c,
            starts: #s,
            lower: #l,
            lower_starts: #ls,
        };
    }];
    // The diagonal blocks' structural zeros, which `blocks::factor` reads as entries.
    let mut zeros: Vec<syn::Stmt> = Vec::new();
    for block in &blocks.blocks {
        for &i in &block.rows {
            for &j in &block.unknowns {
                if !sys.jac[i].iter().any(|&(c, _)| c == j) {
                    let target = element("jac", &[i, j]);
                    zeros.push(parse_quote!(#target = 0.0;));
                }
            }
        }
    }
    let vec_ty = quote::quote!(&mut [f64; N]);
    let mat_ty = quote::quote!(&mut [[f64; N]; N]);
    let targets = [("phi", vec_ty), ("jac", mat_ty)];
    let mut outputs = rows.vector(0, "phi", &sys.phi);
    outputs.extend(rows.jacobian(1, false));
    let sig = Signature {
        name: "residual_jacobian_blocks",
        qd: false,
        qdd: false,
        public: false,
        targets: &targets,
        inputs: rows.inputs(),
    };
    let what = format!(
        "Φ and every entry of Φ_q's diagonal blocks and below them ({} of them 0), the others of `jac` left as they were: what `runtime::blocks::factor` reads.",
        zeros.len()
    );
    items.extend(rows.emit(&sig, &what, zeros, &outputs));
    items
}

/// The `runtime::Mechanism` items that select the block-by-block LU, for a mechanism whose
/// functions take its inputs at t when `inputs`.
pub(super) fn impl_items(inputs: bool) -> Vec<syn::ImplItem> {
    vec![
        parse_quote!(const BLOCKS: Option<&'static runtime::blocks::Layout> = Some(&BLOCKS);),
        if inputs {
            parse_quote! {
                fn residual_jacobian_blocks(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                    residual_jacobian_blocks(q, t, &self.inputs(t), phi, jac);
                }
            }
        } else {
            parse_quote! {
                fn residual_jacobian_blocks(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                    residual_jacobian_blocks(q, t, phi, jac);
                }
            }
        },
    ]
}
