//! The time terms of a module: the sines and cosines of functions of t alone (a driver law's
//! angle) that Φ, Φ_q, ν and γ read, computed once per time by `time_terms` and read by the
//! `_at` variants of `residual`, `residual_jacobian_structural`, `velocity_rhs` and
//! `acceleration_rhs` (`runtime::Mechanism::TIME_TERMS`), which a solver calls at the time of
//! the terms. The plain functions compute the terms and call their variant ([`delegate`]), so
//! each function's arithmetic is emitted once.
//!
//! `expand_at` is `expand` reading the same terms where it has them (the driven and
//! substituted coordinates of the bodies turned by a driver law), so that a caller who has the
//! solver's terms at t ([`runtime::Solver::time_terms`]) does not compute them again
//! (`runtime::Mechanism::expand_at`).
//!
//! The terms are the very nodes the plain functions would compute, so the variants give the
//! same values bit for bit. Emitted for modules with static pivot orders and without inputs
//! (whose terms would depend on the inputs as well), when no function would be split into
//! helpers ([`super::CHUNK_OPS`]) and there are at most `runtime::MAX_TIME_TERMS` terms.

use std::collections::BTreeSet;

use syn::parse_quote;

use super::Rows;
use super::function::{Given, Output, Signature, emit_function_given, function};
use super::syntax::{element, ident, index, item_fn, param};
use crate::expr::{ExprId, ExprPool, Node, Var};

/// The most time terms a module gets: `runtime::MAX_TIME_TERMS`.
const MAX_TERMS: usize = 16;

/// Whether `id` depends on nothing but t and constants (memoised in `memo` by node index).
fn time_only(
    pool: &ExprPool,
    id: ExprId,
    memo: &mut std::collections::HashMap<usize, bool>,
) -> bool {
    if let Some(&known) = memo.get(&id.index()) {
        return known;
    }
    let only = match pool[id] {
        Node::Const(_) | Node::Var(Var::T) => true,
        Node::Var(_) => false,
        node => node.children().into_iter().all(|c| time_only(pool, c, memo)),
    };
    memo.insert(id.index(), only);
    only
}

/// The sines and cosines of functions of t alone reachable from `roots`, in arena order.
fn terms(pool: &ExprPool, roots: &[ExprId]) -> Vec<ExprId> {
    let mut memo = std::collections::HashMap::new();
    let mut found = BTreeSet::new();
    let mut seen = std::collections::HashSet::new();
    let mut stack = roots.to_vec();
    while let Some(x) = stack.pop() {
        if !seen.insert(x.index()) {
            continue;
        }
        match pool[x] {
            Node::Sin(a) | Node::Cos(a) if time_only(pool, a, &mut memo) => {
                found.insert(x);
            }
            node => stack.extend(node.children()),
        }
    }
    found.into_iter().collect()
}

/// The module's time-term items (`TIME_TERMS`, `time_terms`, the four `_at` functions and
/// `expand_at` when `expand` of the bodies `moving` reads a term and is not split) and the
/// `runtime::Mechanism` impl items that call them, or `None` when the module has no time
/// terms or is not covered (see the module docs).
pub(super) fn items(
    rows: &Rows<'_>,
    moving: &[usize],
) -> Option<(Vec<syn::Item>, Vec<syn::ImplItem>)> {
    let sys = rows.sys;
    if rows.inputs() {
        return None;
    }
    let pool = &sys.pool;
    let n = sys.unknowns.len();
    let vec_ty = quote::quote!(&mut [f64; N]);
    let mat_ty = quote::quote!(&mut [[f64; N]; N]);
    let mut structural = rows.vector(0, "phi", &sys.phi);
    structural.extend(rows.jacobian(1, true));
    let phi_targets = [("phi", vec_ty.clone())];
    let both_targets = [("phi", vec_ty.clone()), ("jac", mat_ty)];
    let nu_targets = [("nu", vec_ty.clone())];
    let gamma_targets = [("gamma", vec_ty)];
    // `residual_jacobian_structural` is not public: only the impl calls it, and its variant.
    let sig = |name, qd, targets| Signature {
        name,
        qd,
        qdd: false,
        public: name != "residual_jacobian_structural_at",
        targets,
        inputs: false,
    };
    let functions: [(Signature<'_>, &str, Vec<Output>); 4] = [
        (sig("residual_at", false, &phi_targets), "residual", rows.vector(0, "phi", &sys.phi)),
        (
            sig("residual_jacobian_structural_at", false, &both_targets),
            "residual_jacobian_structural",
            structural,
        ),
        (sig("velocity_rhs_at", false, &nu_targets), "velocity_rhs", rows.vector(0, "nu", &sys.nu)),
        (
            sig("acceleration_rhs_at", true, &gamma_targets),
            "acceleration_rhs",
            rows.vector(0, "gamma", &sys.gamma),
        ),
    ];
    let roots: Vec<ExprId> =
        functions.iter().flat_map(|(_, _, outputs)| outputs.iter().map(|o| o.value)).collect();
    let found = terms(pool, &roots);
    if found.is_empty() || found.len() > MAX_TERMS {
        return None;
    }
    let given: Given =
        found.iter().enumerate().map(|(k, id)| (id.index(), element("terms", &[k]))).collect();

    let count = index(found.len());
    let const_doc = " The number of time terms: the sines and cosines of functions of t alone that Φ, Φ_q, ν and γ read, computed by [`time_terms`].";
    let mut items: Vec<syn::Item> = vec![parse_quote! {
        #[doc = #const_doc]
        pub const TIME_TERMS: usize = #count;
    }];
    let outputs: Vec<_> =
        found.iter().enumerate().map(|(k, &id)| (element("terms", &[k]), id, None)).collect();
    let f = function(pool, n, &outputs);
    let t = param("t", f.uses_t);
    let doc = format!(
        " The time terms at t, computed once per time for the `_at` functions, which read them instead of computing them again.\n\n {} operations.",
        f.ops
    );
    let item: syn::ItemFn = parse_quote! {
        #[doc = #doc]
        pub fn time_terms(#t: f64, terms: &mut [f64; TIME_TERMS]) {}
    };
    items.push(item_fn(item, f.stmts));
    for (sig, plain, outputs) in &functions {
        let what = format!(
            " [`{plain}`] reading the time terms at t from `terms` ([`time_terms`]): the same values, bit for bit."
        );
        let doc =
            |ops, shared| format!("{what}\n\n {ops} operations, {shared} shared subexpressions.");
        items.push(emit_function_given(pool, n, sig, &doc, Vec::new(), outputs, &given)?);
    }
    let expand = expand_at(rows, moving, &found, &given);
    let timed_expand = expand.is_some();
    items.extend(expand);

    let mut impls: Vec<syn::ImplItem> = vec![
        parse_quote!(
            const TIME_TERMS: usize = TIME_TERMS;
        ),
        parse_quote! {
            fn time_terms(&self, t: f64, terms: &mut [f64]) {
                if let Some(terms) = terms.first_chunk_mut() {
                    time_terms(t, terms);
                }
            }
        },
        parse_quote! {
            fn residual_at(&self, q: &[f64; N], t: f64, terms: &[f64], phi: &mut [f64; N]) {
                match terms.first_chunk() {
                    Some(terms) => residual_at(q, t, terms, phi),
                    None => residual(q, t, phi),
                }
            }
        },
        parse_quote! {
            fn residual_jacobian_structural_at(&self, q: &[f64; N], t: f64, terms: &[f64], phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                match terms.first_chunk() {
                    Some(terms) => residual_jacobian_structural_at(q, t, terms, phi, jac),
                    None => residual_jacobian_structural(q, t, phi, jac),
                }
            }
        },
        parse_quote! {
            fn velocity_rhs_at(&self, q: &[f64; N], t: f64, terms: &[f64], nu: &mut [f64; N]) {
                match terms.first_chunk() {
                    Some(terms) => velocity_rhs_at(q, t, terms, nu),
                    None => velocity_rhs(q, t, nu),
                }
            }
        },
        parse_quote! {
            fn acceleration_rhs_at(&self, q: &[f64; N], qd: &[f64; N], t: f64, terms: &[f64], gamma: &mut [f64; N]) {
                match terms.first_chunk() {
                    Some(terms) => acceleration_rhs_at(q, qd, t, terms, gamma),
                    None => acceleration_rhs(q, qd, t, gamma),
                }
            }
        },
    ];
    if timed_expand {
        impls.push(parse_quote! {
            fn expand_at(&self, q: &[f64; N], qd: &[f64; N], qdd: &[f64; N], t: f64, terms: &[f64], out: &mut [[[f64; 7]; 3]]) -> bool {
                let Some(out) = out.first_chunk_mut() else {
                    return false;
                };
                match terms.first_chunk() {
                    Some(terms) => expand_at(q, qd, qdd, t, terms, out),
                    None => expand(q, qd, qdd, t, out),
                }
                true
            }
        });
    }
    Some((items, impls))
}

/// `expand_at`: `expand` (`super::expand`, the same outputs after the same copies) reading
/// the time terms `found` at t where `given` names them, or `None` when `expand` reads none of
/// them or would be split into helpers.
fn expand_at(
    rows: &Rows<'_>,
    moving: &[usize],
    found: &[ExprId],
    given: &Given,
) -> Option<syn::Item> {
    let sys = rows.sys;
    let (direct, outputs, _) = super::expand_outputs(sys, moving);
    let roots: Vec<ExprId> = outputs.iter().map(|o| o.value).collect();
    if !terms(&sys.pool, &roots).iter().any(|id| found.contains(id)) {
        return None;
    }
    let targets = [("out", quote::quote!(&mut [[[f64; 7]; 3]; BODIES]))];
    let sig = Signature {
        name: "expand_at",
        qd: true,
        qdd: true,
        public: true,
        targets: &targets,
        inputs: false,
    };
    let doc = |ops, shared| {
        format!(
            " [`expand`] reading the time terms at t from `terms` ([`time_terms`]): the same values, bit for bit.\n\n {ops} operations, {shared} shared subexpressions."
        )
    };
    let n = sys.unknowns.len();
    let mut item = emit_function_given(&sys.pool, n, &sig, &doc, direct, &outputs, given)?;
    // The copies of the unknowns read q, q̇ and q̈ whenever there are unknowns, as in `expand`.
    if let syn::Item::Fn(f) = &mut item
        && n > 0
    {
        for input in &mut f.sig.inputs {
            if let syn::FnArg::Typed(typed) = input
                && let syn::Pat::Ident(pat) = typed.pat.as_mut()
                && ["_q", "_qd", "_qdd"].contains(&pat.ident.to_string().as_str())
            {
                pat.ident = ident(pat.ident.to_string().trim_start_matches('_'));
            }
        }
    }
    Some(item)
}

/// The plain functions that have an `_at` variant.
const PLAIN: [&str; 4] =
    ["residual", "residual_jacobian_structural", "velocity_rhs", "acceleration_rhs"];

/// Rewrites each plain function of `items` that has an `_at` variant among `variants` into a
/// call of it after [`time_terms`] (emitted by [`items`]), so that a module carries each
/// function's arithmetic once: `residual(q, t, phi)` computes the terms at t and calls
/// `residual_at(q, t, &terms, phi)`, which gives the values the plain function computed, bit
/// for bit (the terms are the nodes it computed).
pub(super) fn delegate(items: &mut [syn::Item], variants: &[syn::Item]) {
    let names: BTreeSet<String> = variants
        .iter()
        .filter_map(|item| match item {
            syn::Item::Fn(f) => Some(f.sig.ident.to_string()),
            _ => None,
        })
        .collect();
    for item in items {
        let syn::Item::Fn(f) = item else { continue };
        let plain = f.sig.ident.to_string();
        let at = format!("{plain}_at");
        if !PLAIN.contains(&plain.as_str()) || !names.contains(&at) {
            continue;
        }
        let mut args: Vec<syn::Expr> = Vec::new();
        for input in &mut f.sig.inputs {
            let syn::FnArg::Typed(typed) = input else { continue };
            let syn::Pat::Ident(pat) = typed.pat.as_mut() else { continue };
            if pat.ident == "_t" {
                // The plain function reads t now: the time terms are computed from it.
                pat.ident = ident("t");
            }
            args.push(super::syntax::path(pat.ident.clone()));
            if pat.ident == "t" {
                args.push(parse_quote!(&terms));
            }
        }
        let callee = ident(&at);
        // The count of operations in the docs becomes the call's description.
        let link = format!(" Computes the time terms at t ([`time_terms`]) and calls [`{at}`].");
        for attr in &mut f.attrs {
            if let syn::Meta::NameValue(meta) = &mut attr.meta
                && meta.path.is_ident("doc")
                && let syn::Expr::Lit(syn::ExprLit { lit: syn::Lit::Str(text), .. }) = &meta.value
                && text.value().contains(" operations")
            {
                let doc: Vec<String> = text
                    .value()
                    .split('\n')
                    .map(
                        |line| {
                            if line.contains(" operations") { link.clone() } else { line.into() }
                        },
                    )
                    .collect();
                let doc = doc.join("\n");
                meta.value = parse_quote!(#doc);
            }
        }
        *f.block = parse_quote!({
            let mut terms = [0.0; TIME_TERMS];
            time_terms(t, &mut terms);
            #callee(#(#args),*)
        });
    }
}
