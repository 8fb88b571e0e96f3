//! `jacobian` and `residual_jacobian` of a module solved by Newton block by block, written as
//! calls of the blocks' own `block_b` functions rather than as a second and third copy of every
//! Jacobian entry's code.
//!
//! The `block_b` functions ([`super::blocks`]) already write Φ and the structural non-zeros of
//! Φ_q of every row, block by block, packed at the front of the storage, and the blocks'
//! rows are all the rows, so the whole Jacobian is theirs, moved to its row-major places by
//! `unpack` with the other entries 0: the same expressions, the same values, and
//! a third of the code rustc compiles for the chain of 100 links (BENCHMARKS.md, "Explicit
//! velocities of closed-form blocks").

use syn::parse_quote;

use super::blocks::Plan;

/// `jacobian` and `residual_jacobian` as calls of `block_0` … `block_{m−1}` (or of the
/// functions they share, [`super::shared`]) (the public
/// signatures of [`super::residual_and_jacobian`]'s, with `inputs: &Inputs` when `inputs`).
pub(super) fn items(plan: &Plan, nnz: usize, inputs: bool) -> Vec<syn::Item> {
    let u = inputs.then(|| quote::quote!(&u,));
    let calls = plan.shared.both.calls_all("block", &quote::quote!(q, t, #u phi, jac));
    let doc = " Φ and Φ_q at once (see [`residual`] and [`jacobian`]), block by block.";
    let jacobian_doc = format!(
        " Jacobian Φ_q, row-major: `jac[i][j] = ∂Φ_i/∂q_j`; the {nnz} structurally non-zero entries are written, the others set to 0."
    );
    let (param, arg, gather) = if inputs {
        (
            Some(quote::quote!(inputs: &Inputs,)),
            Some(quote::quote!(inputs,)),
            Some(quote::quote!(let u = inputs.to_array();)),
        )
    } else {
        (None, None, None)
    };
    vec![
        parse_quote! {
            #[doc = #jacobian_doc]
            pub fn jacobian(q: &[f64; N], t: f64, #param jac: &mut [[f64; N]; N]) {
                let mut phi = [0.0; N];
                residual_jacobian(q, t, #arg &mut phi, jac);
            }
        },
        parse_quote! {
            #[doc = #doc]
            pub fn residual_jacobian(q: &[f64; N], t: f64, #param phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                #gather
                *jac = [[0.0; N]; N];
                #(#calls)*
                unpack(jac);
            }
        },
    ]
}
