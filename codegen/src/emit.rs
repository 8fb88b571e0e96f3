//! Emission of the reduced symbolic system as a Rust module: syn nodes printed by
//! prettyplease, one top-level item at a time.
//!
//! Each function evaluates its outputs in one forward pass over the expression arena:
//! nodes used more than once become `let tK` temporaries (numbered in topological order),
//! all others are inlined. Operator trees are built as syn nodes with parentheses exactly
//! where Rust's precedence and left associativity would otherwise change the tree, so the
//! emitted code performs the same floating-point operations as `ExprPool::eval`.

use proc_macro2::{Literal, Span};
use syn::{Expr, Ident, parse_quote};

use crate::expr::{ExprId, ExprPool, Node, Var};
use crate::model::Mechanism;
use crate::symbolic::{Source, Symbolic};

pub mod lu;
pub mod scalar;

pub use scalar::Scalar;

/// Binding strength of an emitted expression.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum Prec {
    Sum = 1,
    Product = 2,
    Unary = 3,
    Atom = 4,
}

fn ident(name: &str) -> Ident {
    Ident::new(name, Span::call_site())
}

fn paren(e: Expr) -> Expr {
    Expr::Paren(syn::ExprParen {
        attrs: Vec::new(),
        paren_token: Default::default(),
        expr: Box::new(e),
    })
}

fn binary(l: Expr, op: syn::BinOp, r: Expr) -> Expr {
    Expr::Binary(syn::ExprBinary { attrs: Vec::new(), left: Box::new(l), op, right: Box::new(r) })
}

fn neg(e: Expr) -> Expr {
    Expr::Unary(syn::ExprUnary {
        attrs: Vec::new(),
        op: syn::UnOp::Neg(Default::default()),
        expr: Box::new(e),
    })
}

/// `runtime::math::name(arg)`: `core` has no sin, cos or sqrt under no_std.
fn call(name: &str, arg: Expr) -> Expr {
    let name = ident(name);
    parse_quote!(runtime::math::#name(#arg))
}

/// The constants clippy's `approx_constant` (a deny lint) knows, with the number of
/// characters a literal needs before it is compared (clippy's `min_digits`).
const KNOWN: [(f64, &str, usize); 19] = [
    (std::f64::consts::E, "E", 4),
    (std::f64::consts::FRAC_1_PI, "FRAC_1_PI", 4),
    (std::f64::consts::FRAC_1_SQRT_2, "FRAC_1_SQRT_2", 5),
    (std::f64::consts::FRAC_2_PI, "FRAC_2_PI", 5),
    (std::f64::consts::FRAC_2_SQRT_PI, "FRAC_2_SQRT_PI", 5),
    (std::f64::consts::FRAC_PI_2, "FRAC_PI_2", 5),
    (std::f64::consts::FRAC_PI_3, "FRAC_PI_3", 5),
    (std::f64::consts::FRAC_PI_4, "FRAC_PI_4", 5),
    (std::f64::consts::FRAC_PI_6, "FRAC_PI_6", 5),
    (std::f64::consts::FRAC_PI_8, "FRAC_PI_8", 5),
    (std::f64::consts::LN_10, "LN_10", 5),
    (std::f64::consts::LN_2, "LN_2", 5),
    (std::f64::consts::LOG10_E, "LOG10_E", 5),
    (std::f64::consts::LOG2_E, "LOG2_E", 5),
    (std::f64::consts::LOG2_10, "LOG2_10", 5),
    (std::f64::consts::LOG10_2, "LOG10_2", 5),
    (std::f64::consts::PI, "PI", 3),
    (std::f64::consts::SQRT_2, "SQRT_2", 5),
    (std::f64::consts::TAU, "TAU", 3),
];

/// Whether clippy would read the literal `text` as an approximation of `c`: it is longer
/// than `min_digits` and is a prefix of `c`'s digits or `c` rounded to as many decimals.
fn looks_like(text: &str, c: f64, min_digits: usize) -> bool {
    if text.len() <= min_digits {
        return false;
    }
    if c.to_string().starts_with(text) {
        return true;
    }
    text.find('.').is_some_and(|dot| format!("{c:.*}", text.len() - dot - 1) == text)
}

/// A non-negative float literal: `{:?}` (shortest round trip), the named constant when it is
/// one exactly, and `f64::from_bits` for values that merely look like one.
fn literal(v: f64) -> Expr {
    debug_assert!(v >= 0.0 && v.is_finite());
    let text = format!("{v:?}");
    for &(c, name, min_digits) in &KNOWN {
        if v == c {
            let name = ident(name);
            return parse_quote!(core::f64::consts::#name);
        }
        if looks_like(&text, c, min_digits) {
            let bits = Literal::u64_unsuffixed(v.to_bits());
            return parse_quote!(f64::from_bits(#bits));
        }
    }
    Expr::Lit(syn::ExprLit {
        attrs: Vec::new(),
        lit: syn::Lit::Float(syn::LitFloat::new(&text, Span::call_site())),
    })
}

/// One function body under construction: the `let` temporaries and the variables used.
struct Body<'p> {
    pool: &'p ExprPool,
    /// Temporary name of each shared node (indexed by node).
    temp: Vec<Option<Ident>>,
    stmts: Vec<syn::Stmt>,
    ops: usize,
}

impl<'p> Body<'p> {
    /// Plans the temporaries for `roots`: every operation node reachable more than once.
    fn new(pool: &'p ExprPool, roots: &[ExprId]) -> Self {
        let last = roots.iter().map(|r| r.index() + 1).max().unwrap_or(0);
        let mut uses = vec![0usize; last];
        let mut live = vec![false; last];
        let mut stack: Vec<ExprId> = roots.to_vec();
        for r in roots {
            uses[r.index()] += 1;
        }
        while let Some(x) = stack.pop() {
            if std::mem::replace(&mut live[x.index()], true) {
                continue;
            }
            for c in pool[x].children() {
                uses[c.index()] += 1;
                stack.push(c);
            }
        }
        // sin a and cos a both needed: one `runtime::math::sin_cos(a)` gives both, with one
        // argument reduction (and the same bits as `sin` and `cos`).
        let mut trig: std::collections::BTreeMap<ExprId, [Option<usize>; 2]> =
            std::collections::BTreeMap::new();
        for k in (0..last).filter(|&k| live[k]) {
            match pool.nodes()[k] {
                Node::Sin(a) => trig.entry(a).or_default()[0] = Some(k),
                Node::Cos(a) => trig.entry(a).or_default()[1] = Some(k),
                _ => {}
            }
        }
        let mut pair: Vec<Option<(ExprId, usize, usize)>> = vec![None; last];
        for (&a, &[s, c]) in &trig {
            if let (Some(s), Some(c)) = (s, c) {
                pair[s] = Some((a, s, c));
                pair[c] = Some((a, s, c));
            }
        }
        let mut body = Self { pool, temp: vec![None; last], stmts: Vec::new(), ops: 0 };
        let mut count = 0;
        for k in 0..last {
            if !live[k] {
                continue;
            }
            let leaf = matches!(pool.nodes()[k], Node::Const(_) | Node::Var(_));
            if !leaf {
                body.ops += 1;
            }
            if let Some((a, s, c)) = pair[k] {
                if body.temp[k].is_none() {
                    let (arg, _) = body.render(a);
                    let (sin, cos) =
                        (ident(&format!("t{count}")), ident(&format!("t{}", count + 1)));
                    count += 2;
                    body.stmts.push(parse_quote!(let (#sin, #cos) = runtime::math::sin_cos(#arg);));
                    body.temp[s] = Some(sin);
                    body.temp[c] = Some(cos);
                }
            } else if !leaf && uses[k] >= 2 {
                let (e, _) = body.render(ExprId::from_index(k));
                let name = ident(&format!("t{count}"));
                count += 1;
                body.stmts.push(parse_quote!(let #name = #e;));
                body.temp[k] = Some(name);
            }
        }
        body
    }

    /// The number of shared temporaries.
    fn shared(&self) -> usize {
        self.temp.iter().flatten().count()
    }

    /// An expression for `id` with its binding strength.
    fn render(&self, id: ExprId) -> (Expr, Prec) {
        if let Some(name) = &self.temp[id.index()] {
            return (parse_quote!(#name), Prec::Atom);
        }
        let at_least = |e: (Expr, Prec), p: Prec| if e.1 >= p { e.0 } else { paren(e.0) };
        match self.pool[id] {
            Node::Const(bits) => {
                let v = f64::from_bits(bits);
                if v < 0.0 { (neg(literal(-v)), Prec::Unary) } else { (literal(v), Prec::Atom) }
            }
            Node::Var(Var::Q(k)) => {
                let name = ident(&format!("q{k}"));
                (parse_quote!(#name), Prec::Atom)
            }
            Node::Var(Var::Qd(k)) => {
                let name = ident(&format!("qd{k}"));
                (parse_quote!(#name), Prec::Atom)
            }
            Node::Var(Var::T) => (parse_quote!(t), Prec::Atom),
            Node::Neg(a) => (neg(at_least(self.render(a), Prec::Unary)), Prec::Unary),
            Node::Add(a, b) => {
                // x + (−y) and (−y) + x are written x − y: the same IEEE operation, since
                // addition commutes exactly and negation is exact.
                let negated = |e: ExprId| -> Option<Expr> {
                    if self.temp[e.index()].is_some() {
                        return None;
                    }
                    match (self.pool[e], self.pool.as_const(e)) {
                        (_, Some(c)) if c < 0.0 => Some(literal(-c)),
                        (Node::Neg(x), _) => Some(at_least(self.render(x), Prec::Product)),
                        _ => None,
                    }
                };
                let sub = syn::BinOp::Sub(Default::default());
                if let Some(r) = negated(b) {
                    (binary(at_least(self.render(a), Prec::Sum), sub, r), Prec::Sum)
                } else if let Some(r) = negated(a) {
                    (binary(at_least(self.render(b), Prec::Sum), sub, r), Prec::Sum)
                } else {
                    let left = at_least(self.render(a), Prec::Sum);
                    let right = at_least(self.render(b), Prec::Product);
                    (binary(left, syn::BinOp::Add(Default::default()), right), Prec::Sum)
                }
            }
            Node::Mul(a, b) => {
                let left = at_least(self.render(a), Prec::Product);
                let right = at_least(self.render(b), Prec::Unary);
                (binary(left, syn::BinOp::Mul(Default::default()), right), Prec::Product)
            }
            Node::Sin(a) => (call("sin", self.render(a).0), Prec::Atom),
            Node::Cos(a) => (call("cos", self.render(a).0), Prec::Atom),
        }
    }
}

/// `rssr` → `Rssr`, `four_bar` → `FourBar`, `ex_2_6_1` → `Ex261`.
#[must_use]
pub fn type_name(name: &str) -> String {
    name.split('_')
        .map(|w| {
            let mut c = w.chars();
            c.next().map_or_else(String::new, |f| f.to_ascii_uppercase().to_string() + c.as_str())
        })
        .collect()
}

/// `let [q0, _q1, …] = *q;` naming the unused entries with a leading underscore.
fn destructure(prefix: &str, n: usize, used: &[bool]) -> syn::Stmt {
    let names = (0..n).map(|k| {
        let name = if used[k] { format!("{prefix}{k}") } else { format!("_{prefix}{k}") };
        ident(&name)
    });
    let src = ident(prefix);
    parse_quote!(let [#(#names),*] = *#src;)
}

/// Which symbols the expressions reachable from `roots` use: (q, q̇, t).
fn symbols(pool: &ExprPool, roots: &[ExprId], n: usize) -> (Vec<bool>, Vec<bool>, bool) {
    let (mut q, mut qd, mut t) = (vec![false; n], vec![false; n], false);
    let mut seen = std::collections::BTreeSet::new();
    let mut stack = roots.to_vec();
    while let Some(x) = stack.pop() {
        if !seen.insert(x) {
            continue;
        }
        match pool[x] {
            Node::Var(Var::Q(k)) => q[k as usize] = true,
            Node::Var(Var::Qd(k)) => qd[k as usize] = true,
            Node::Var(Var::T) => t = true,
            node => stack.extend(node.children()),
        }
    }
    (q, qd, t)
}

/// A function body: destructuring, temporaries, then `target = value;` per output.
struct Function {
    stmts: Vec<syn::Stmt>,
    uses_t: bool,
    uses_q: bool,
    uses_qd: bool,
    ops: usize,
    shared: usize,
}

fn function(pool: &ExprPool, n: usize, outputs: &[(syn::Expr, ExprId)]) -> Function {
    let roots: Vec<ExprId> = outputs.iter().map(|(_, e)| *e).collect();
    let (q, qd, t) = symbols(pool, &roots, n);
    let body = Body::new(pool, &roots);
    let mut stmts = Vec::new();
    let (uses_q, uses_qd) = (q.iter().any(|&u| u), qd.iter().any(|&u| u));
    if uses_q {
        stmts.push(destructure("q", n, &q));
    }
    if uses_qd {
        stmts.push(destructure("qd", n, &qd));
    }
    stmts.extend(body.stmts.iter().cloned());
    for (target, e) in outputs {
        let (value, _) = body.render(*e);
        stmts.push(parse_quote!(#target = #value;));
    }
    Function { stmts, uses_t: t, uses_q, uses_qd, ops: body.ops, shared: body.shared() }
}

fn param(name: &str, used: bool) -> Ident {
    ident(&if used { name.to_owned() } else { format!("_{name}") })
}

fn index(k: usize) -> Literal {
    Literal::usize_unsuffixed(k)
}

/// The generated module for one mechanism, as text.
#[must_use]
pub fn module(mech: &Mechanism, sys: &Symbolic, source: &str) -> String {
    module_in(mech, sys, source, Scalar::F64)
}

/// [`module`] in the floating-point type `scalar` (see [`scalar`]).
#[must_use]
pub fn module_in(mech: &Mechanism, sys: &Symbolic, source: &str, scalar: Scalar) -> String {
    let n = sys.unknowns.len();
    let pool = &sys.pool;
    let ty = ident(&type_name(&mech.name));
    let mut items: Vec<syn::Item> = Vec::new();
    let moving: Vec<usize> =
        mech.bodies.iter().enumerate().filter(|(_, b)| !b.ground).map(|(k, _)| k).collect();
    let nb = moving.len();
    let coordinate = ["x", "y", "z", "e0", "e1", "e2", "e3"];

    let n_lit = index(n);
    items.push(parse_quote! {
        /// Number of unknowns (and of equations) of the reduced system.
        pub const N: usize = #n_lit;
    });
    let nb_lit = index(nb);
    items.push(parse_quote! {
        /// Number of moving bodies reported by [`expand`].
        pub const BODIES: usize = #nb_lit;
    });
    let body_names = moving.iter().map(|&b| mech.bodies[b].name.as_str());
    items.push(parse_quote! {
        /// Names of the moving bodies, in the order of [`expand`].
        pub const BODY_NAMES: [&str; BODIES] = [#(#body_names),*];
    });
    let unknowns =
        sys.unknowns.iter().map(|&(b, c)| format!("{}.{}", mech.bodies[b.0].name, coordinate[c]));
    items.push(parse_quote! {
        /// The body coordinate each unknown stands for.
        pub const UNKNOWNS: [&str; N] = [#(#unknowns),*];
    });
    let rows = sys.rows.iter().map(crate::generic::RowLabel::equation);
    items.push(parse_quote! {
        /// The equation of each row.
        pub const EQUATIONS: [&str; N] = [#(#rows),*];
    });
    let grid = mech.time;
    let (start, step, count) =
        (literal_signed(grid.start), literal_signed(grid.step), index(grid.count));
    items.push(parse_quote! {
        /// First time point of the description's grid.
        pub const T_START: f64 = #start;
    });
    items.push(parse_quote! {
        /// Spacing of the grid.
        pub const T_STEP: f64 = #step;
    });
    items.push(parse_quote! {
        /// Number of time points of the grid.
        pub const T_COUNT: usize = #count;
    });
    let tol = literal_signed(mech.solver.tolerance);
    let max_it = Literal::u32_unsuffixed(mech.solver.max_iterations);
    items.push(parse_quote! {
        /// Newton tolerance on max |Φ_i| from the description.
        pub const TOLERANCE: f64 = #tol;
    });
    items.push(parse_quote! {
        /// Newton iteration bound from the description.
        pub const MAX_ITERATIONS: u32 = #max_it;
    });
    let q0 = sys.unknowns.iter().map(|&(b, c)| {
        let body = &mech.bodies[b.0];
        literal_signed(if c < 3 { body.r[c] } else { body.p[c - 3] })
    });
    items.push(parse_quote! {
        /// Initial estimates of the unknowns.
        pub const Q0: [f64; N] = [#(#q0),*];
    });

    // Φ.
    let outputs: Vec<(Expr, ExprId)> = sys
        .phi
        .iter()
        .enumerate()
        .map(|(i, &e)| {
            let i = index(i);
            (parse_quote!(phi[#i]), e)
        })
        .collect();
    let f = function(pool, n, &outputs);
    let (qn, tn, stmts) = (param("q", f.uses_q), param("t", f.uses_t), &f.stmts);
    let doc = format!(
        " Constraint residuals Φ(q, t), {n} rows.\n\n {} operations, {} shared subexpressions.",
        f.ops, f.shared
    );
    items.push(parse_quote! {
        #[doc = #doc]
        pub fn residual(#qn: &[f64; N], #tn: f64, phi: &mut [f64; N]) {
            #(#stmts)*
        }
    });

    // Φ_q.
    let jac_outputs: Vec<(Expr, ExprId)> = sys
        .jac
        .iter()
        .enumerate()
        .flat_map(|(i, row)| {
            row.iter().map(move |&(c, e)| {
                let (i, c) = (index(i), index(c));
                (parse_quote!(jac[#i][#c]), e)
            })
        })
        .collect();
    let nnz = jac_outputs.len();
    let f = function(pool, n, &jac_outputs);
    let (qn, tn, stmts) = (param("q", f.uses_q), param("t", f.uses_t), &f.stmts);
    let doc = format!(
        " Jacobian Φ_q, row-major: `jac[i][j] = ∂Φ_i/∂q_j`; the {nnz} structurally non-zero entries are written, the others set to 0.\n\n {} operations, {} shared subexpressions.",
        f.ops, f.shared
    );
    items.push(parse_quote! {
        #[doc = #doc]
        pub fn jacobian(#qn: &[f64; N], #tn: f64, jac: &mut [[f64; N]; N]) {
            *jac = [[0.0; N]; N];
            #(#stmts)*
        }
    });

    // Φ and Φ_q together, sharing subexpressions.
    let mut both = outputs.clone();
    both.extend(jac_outputs.iter().cloned());
    let f = function(pool, n, &both);
    let (qn, tn, stmts) = (param("q", f.uses_q), param("t", f.uses_t), &f.stmts);
    let doc = format!(
        " Φ and Φ_q at once (see [`residual`] and [`jacobian`]).\n\n {} operations, {} shared subexpressions.",
        f.ops, f.shared
    );
    items.push(parse_quote! {
        #[doc = #doc]
        pub fn residual_jacobian(#qn: &[f64; N], #tn: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
            *jac = [[0.0; N]; N];
            #(#stmts)*
        }
    });
    // Φ and the entries of Φ_q that vary: the constant ones are literals in `factor_k`.
    let mut varying = outputs.clone();
    varying.extend(jac_outputs.iter().filter(|(_, e)| pool.as_const(*e).is_none()).cloned());
    let count = varying.len() - outputs.len();
    let f = function(pool, n, &varying);
    let (qn, tn, stmts) = (param("q", f.uses_q), param("t", f.uses_t), &f.stmts);
    let doc = format!(
        " Φ and the {count} entries of Φ_q that depend on q or t, the others of `jac` left as they were: what the `factor_k` functions read ({} of the {nnz} structurally non-zero entries are constants, which they know).\n\n {} operations, {} shared subexpressions.",
        nnz - count,
        f.ops,
        f.shared
    );
    items.push(parse_quote! {
        #[doc = #doc]
        pub fn residual_jacobian_structural(#qn: &[f64; N], #tn: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
            #(#stmts)*
        }
    });

    // The structured LU: static pivot orders over the description's motion.
    let orders = if n == 0 { Vec::new() } else { lu::plan(sys, &lu::motion(mech, sys)) };
    let structure = lu::structure(sys);
    let constant = lu::constants(sys);
    for (k, order) in orders.iter().enumerate() {
        let e = lu::emit(order, &structure, &constant, k);
        items.push(e.factor);
        items.push(e.solve);
    }

    // ν.
    let outputs: Vec<(Expr, ExprId)> = sys
        .nu
        .iter()
        .enumerate()
        .map(|(i, &e)| {
            let i = index(i);
            (parse_quote!(nu[#i]), e)
        })
        .collect();
    let f = function(pool, n, &outputs);
    let (qn, tn, stmts) = (param("q", f.uses_q), param("t", f.uses_t), &f.stmts);
    let doc = format!(
        " Velocity right-hand side ν = −Φ_t.\n\n {} operations, {} shared subexpressions.",
        f.ops, f.shared
    );
    items.push(parse_quote! {
        #[doc = #doc]
        pub fn velocity_rhs(#qn: &[f64; N], #tn: f64, nu: &mut [f64; N]) {
            #(#stmts)*
        }
    });

    // γ.
    let outputs: Vec<(Expr, ExprId)> = sys
        .gamma
        .iter()
        .enumerate()
        .map(|(i, &e)| {
            let i = index(i);
            (parse_quote!(gamma[#i]), e)
        })
        .collect();
    let f = function(pool, n, &outputs);
    let (qn, qdn, tn, stmts) =
        (param("q", f.uses_q), param("qd", f.uses_qd), param("t", f.uses_t), &f.stmts);
    let doc = format!(
        " Acceleration right-hand side γ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt.\n\n {} operations, {} shared subexpressions.",
        f.ops, f.shared
    );
    items.push(parse_quote! {
        #[doc = #doc]
        pub fn acceleration_rhs(#qn: &[f64; N], #qdn: &[f64; N], #tn: f64, gamma: &mut [f64; N]) {
            #(#stmts)*
        }
    });

    // Normalisation of the Euler parameters.
    let mut stmts: Vec<syn::Stmt> = Vec::new();
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
        let target = literal_signed(1.0 - fixed);
        let squares = free.iter().map(|k| -> Expr { parse_quote!(q[#k] * q[#k]) });
        stmts.push(parse_quote! {
            {
                let free = 0.0 #(+ #squares)*;
                if free > 0.0 {
                    let scale = runtime::math::sqrt(#target / free);
                    #(q[#free] *= scale;)*
                }
            }
        });
    }
    let qn = param("q", !stmts.is_empty());
    items.push(parse_quote! {
        /// Rescales the unknown Euler parameters of each body so that |p| = 1 (the fixed
        /// ones keep their values).
        pub fn normalize(#qn: &mut [f64; N]) {
            #(#stmts)*
        }
    });

    // Full coordinates of the moving bodies.
    let mut outputs: Vec<(Expr, ExprId)> = Vec::new();
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
                        let d = index(d);
                        outputs.push((parse_quote!(out[#sl][#d][#il]), *e));
                    }
                }
            }
        }
    }
    let f = function(pool, n, &outputs);
    let any = n > 0;
    let (qn, qdn, qddn) = (param("q", any), param("qd", any), param("qdd", any));
    let tn = param("t", f.uses_t);
    let stmts = &f.stmts;
    items.push(parse_quote! {
        /// Full coordinates of every moving body (in [`BODY_NAMES`] order): `out[b][0]` is
        /// `[x, y, z, e0, e1, e2, e3]`, `out[b][1]` its rates and `out[b][2]` its
        /// accelerations, with fixed and driven coordinates filled in.
        pub fn expand(#qn: &[f64; N], #qdn: &[f64; N], #qddn: &[f64; N], #tn: f64, out: &mut [[[f64; 7]; 3]; BODIES]) {
            #(#direct)*
            #(#stmts)*
        }
    });

    let doc = format!(" The mechanism `{}` as a [`runtime::Mechanism`].", mech.name);
    items.push(parse_quote! {
        #[doc = #doc]
        #[derive(Clone, Copy, Debug, Default)]
        pub struct #ty;
    });
    let count = index(orders.len());
    let factor_arms = (0..orders.len()).map(|k| {
        let (lit, f) = (index(k), ident(&format!("factor_{k}")));
        quote::quote!(#lit => #f(jac),)
    });
    let solve_arms = (0..orders.len()).map(|k| {
        let (lit, f) = (index(k), ident(&format!("solve_{k}")));
        quote::quote!(#lit => #f(lu, b),)
    });
    let structured: Vec<syn::ImplItem> = if orders.is_empty() {
        Vec::new()
    } else {
        let solve: syn::ImplItem = if orders.len() == 1 {
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
            parse_quote! {
                fn residual_jacobian_structural(&self, q: &[f64; N], t: f64, phi: &mut [f64; N], jac: &mut [[f64; N]; N]) {
                    residual_jacobian_structural(q, t, phi, jac);
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
    };
    items.push(parse_quote! {
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
    });

    let mut text = format!(
        "// @generated by `cargo codegen` from {source}. Do not edit.\n\n#![cfg_attr(rustfmt, rustfmt::skip)]\n"
    );
    let title = mech.description.as_deref().unwrap_or(&mech.name);
    text.push_str(&format!(
        "//! {title}: {n} unknowns and {n} equations after eliminating {} (ground bodies carry none).\n",
        if sys.eliminated.is_empty() {
            "nothing".to_owned()
        } else {
            sys.eliminated.iter().map(crate::generic::RowLabel::equation).collect::<Vec<_>>().join(", ")
        }
    ));
    if !sys.redundant.is_empty() {
        text.push_str(&format!(
            "//! Redundant equations left out: {}.\n",
            sys.redundant
                .iter()
                .map(crate::generic::RowLabel::equation)
                .collect::<Vec<_>>()
                .join(", ")
        ));
    }
    if scalar == Scalar::F32 {
        text.push_str("//! Single precision: every value, literal and operation is `f32`.\n");
        items.iter_mut().for_each(scalar::to_f32);
    }
    for item in items {
        text.push('\n');
        text.push_str(&prettyplease::unparse(&syn::File {
            shebang: None,
            attrs: Vec::new(),
            items: vec![item],
        }));
    }
    text
}

/// A literal for any finite value (negative ones as unary minus).
fn literal_signed(v: f64) -> Expr {
    if v < 0.0 { neg(literal(-v)) } else { literal(v) }
}

#[cfg(test)]
mod tests;
