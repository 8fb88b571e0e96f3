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

/// The expression `name`.
fn path(name: Ident) -> Expr {
    Expr::Path(syn::ExprPath { attrs: Vec::new(), qself: None, path: name.into() })
}

/// `let name = e;`, built directly (parsing it from tokens costs more than the rest of the
/// emission for large mechanisms).
fn let_stmt(name: Ident, e: Expr) -> syn::Stmt {
    syn::Stmt::Local(syn::Local {
        attrs: Vec::new(),
        let_token: Default::default(),
        pat: syn::Pat::Ident(syn::PatIdent {
            attrs: Vec::new(),
            by_ref: None,
            mutability: None,
            ident: name,
            subpat: None,
        }),
        init: Some(syn::LocalInit {
            eq_token: Default::default(),
            expr: Box::new(e),
            diverge: None,
        }),
        semi_token: Default::default(),
    })
}

/// `target = value;`, or `target op= rhs;` when value is `target op rhs` (clippy's
/// `assign_op_pattern`); the same floating-point operation either way.
fn assign(target: Expr, value: Expr) -> syn::Stmt {
    use quote::ToTokens;
    let same = |e: &Expr| e.to_token_stream().to_string() == target.to_token_stream().to_string();
    if let Expr::Binary(b) = &value
        && same(&b.left)
    {
        let op = match b.op {
            syn::BinOp::Add(_) => Some(syn::BinOp::AddAssign(Default::default())),
            syn::BinOp::Sub(_) => Some(syn::BinOp::SubAssign(Default::default())),
            syn::BinOp::Mul(_) => Some(syn::BinOp::MulAssign(Default::default())),
            syn::BinOp::Div(_) => Some(syn::BinOp::DivAssign(Default::default())),
            _ => None,
        };
        if let Some(op) = op {
            return syn::Stmt::Expr(
                binary(target, op, (*b.right).clone()),
                Some(Default::default()),
            );
        }
    }
    syn::Stmt::Expr(
        Expr::Assign(syn::ExprAssign {
            attrs: Vec::new(),
            left: Box::new(target),
            eq_token: Default::default(),
            right: Box::new(value),
        }),
        Some(Default::default()),
    )
}

/// `array[i]`, `array[i][j]`, … .
fn element(array: &str, indices: &[usize]) -> Expr {
    indices.iter().fold(path(ident(array)), |e, &k| {
        Expr::Index(syn::ExprIndex {
            attrs: Vec::new(),
            expr: Box::new(e),
            bracket_token: Default::default(),
            index: Box::new(Expr::Lit(syn::ExprLit {
                attrs: Vec::new(),
                lit: syn::Lit::Int(syn::LitInt::from(index(k))),
            })),
        })
    })
}

/// A function item with `stmts` as its body, the signature parsed from `signature` (the
/// statements are not turned into tokens and parsed again).
fn item_fn(mut signature: syn::ItemFn, stmts: Vec<syn::Stmt>) -> syn::Item {
    signature.block.stmts = stmts;
    syn::Item::Fn(signature)
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
                body.stmts.push(let_stmt(name.clone(), e));
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
            return (path(name.clone()), Prec::Atom);
        }
        let at_least = |e: (Expr, Prec), p: Prec| if e.1 >= p { e.0 } else { paren(e.0) };
        match self.pool[id] {
            Node::Const(bits) => {
                let v = f64::from_bits(bits);
                if v < 0.0 { (neg(literal(-v)), Prec::Unary) } else { (literal(v), Prec::Atom) }
            }
            Node::Var(Var::Q(k)) => (path(ident(&format!("q{k}"))), Prec::Atom),
            Node::Var(Var::Qd(k)) => (path(ident(&format!("qd{k}"))), Prec::Atom),
            Node::Var(Var::T) => (path(ident("t")), Prec::Atom),
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

pub use crate::model::type_name;

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
    function_with(pool, n, outputs, false)
}

/// [`function`], reading the used entries of q and q̇ one by one (`let q5 = q[5];`) when
/// `part`: a part of a split function uses few of them.
fn function_with(
    pool: &ExprPool,
    n: usize,
    outputs: &[(syn::Expr, ExprId)],
    part: bool,
) -> Function {
    let roots: Vec<ExprId> = outputs.iter().map(|(_, e)| *e).collect();
    let (q, qd, t) = symbols(pool, &roots, n);
    let body = Body::new(pool, &roots);
    let mut stmts = Vec::new();
    let (uses_q, uses_qd) = (q.iter().any(|&u| u), qd.iter().any(|&u| u));
    for (prefix, used) in [("q", &q), ("qd", &qd)] {
        if !used.iter().any(|&u| u) {
            continue;
        }
        if part {
            for k in (0..n).filter(|&k| used[k]) {
                stmts.push(let_stmt(ident(&format!("{prefix}{k}")), element(prefix, &[k])));
            }
        } else {
            stmts.push(destructure(prefix, n, used));
        }
    }
    stmts.extend(body.stmts.iter().cloned());
    for (target, e) in outputs {
        let (value, _) = body.render(*e);
        stmts.push(assign(target.clone(), value));
    }
    Function { stmts, uses_t: t, uses_q, uses_qd, ops: body.ops, shared: body.shared() }
}

/// Functions whose outputs take more operations than this are split into helpers of about
/// this many operations each, so that rustc and LLVM never see one giant function (their time
/// grows faster than linearly with a function's size). The largest function of the examples
/// has under 800 operations and is not split.
pub const CHUNK_OPS: usize = 1500;

/// One value a function writes: `target = value`, to the array `targets[array]`; `key` orders
/// the outputs when the function is split (outputs with near keys share subexpressions).
struct Output {
    target: Expr,
    array: usize,
    value: ExprId,
    key: usize,
}

/// Marks the nodes reachable from `root` with `stamp` and returns how many of them are
/// operations not marked before.
fn new_operations(pool: &ExprPool, root: ExprId, marks: &mut [u32], stamp: u32) -> usize {
    let mut stack = vec![root];
    let mut count = 0;
    while let Some(x) = stack.pop() {
        if std::mem::replace(&mut marks[x.index()], stamp) == stamp {
            continue;
        }
        if !matches!(pool[x], Node::Const(_) | Node::Var(_)) {
            count += 1;
        }
        stack.extend(pool[x].children());
    }
    count
}

/// The outputs in groups of at most about [`CHUNK_OPS`] operations: one group in the given
/// order when they fit, else ordered by key and cut greedily.
fn chunks(pool: &ExprPool, outputs: &[Output]) -> Vec<Vec<usize>> {
    let mut marks = vec![0u32; pool.len()];
    let total: usize = outputs.iter().map(|o| new_operations(pool, o.value, &mut marks, 1)).sum();
    if total <= CHUNK_OPS {
        return vec![(0..outputs.len()).collect()];
    }
    let mut order: Vec<usize> = (0..outputs.len()).collect();
    order.sort_by_key(|&k| outputs[k].key);
    let (mut groups, mut current, mut ops, mut stamp) = (Vec::new(), Vec::new(), 0, 2);
    for k in order {
        let mut more = new_operations(pool, outputs[k].value, &mut marks, stamp);
        if !current.is_empty() && ops + more > CHUNK_OPS {
            groups.push(std::mem::take(&mut current));
            stamp += 1;
            ops = 0;
            more = new_operations(pool, outputs[k].value, &mut marks, stamp);
        }
        current.push(k);
        ops += more;
    }
    groups.push(current);
    groups
}

/// What an emitted function reads and writes.
struct Signature<'a> {
    name: &'a str,
    /// Whether q̇ is a parameter (after q).
    qd: bool,
    /// The arrays written, with their types, after `t`.
    targets: &'a [(&'a str, proc_macro2::TokenStream)],
}

impl Signature<'_> {
    /// `fn name(q: &[f64; N], [qd: &[f64; N],] t: f64, targets…)`, each parameter named with a
    /// leading underscore when it is not used.
    fn item(
        &self,
        name: &Ident,
        doc: &str,
        used: (bool, bool, bool, &[bool]),
        helper: bool,
    ) -> syn::ItemFn {
        let (q, qd, t, arrays) = used;
        let mut params: Vec<syn::FnArg> = vec![{
            let q = param("q", q);
            parse_quote!(#q: &[f64; N])
        }];
        if self.qd {
            let qd = param("qd", qd);
            params.push(parse_quote!(#qd: &[f64; N]));
        }
        let t = param("t", t);
        params.push(parse_quote!(#t: f64));
        for ((a, ty), &u) in self.targets.iter().zip(arrays) {
            let a = param(a, u);
            params.push(parse_quote!(#a: #ty));
        }
        if helper {
            parse_quote! {
                #[doc = #doc]
                #[inline(never)]
                fn #name(#(#params),*) {}
            }
        } else {
            parse_quote! {
                #[doc = #doc]
                pub fn #name(#(#params),*) {}
            }
        }
    }
}

/// The function `sig.name` writing `outputs` after `prefix`, split into `#[inline(never)]`
/// helpers `name_0`, `name_1`, … when it would exceed [`CHUNK_OPS`] operations. `doc` gets
/// the operations and shared subexpressions in total.
fn emit_function(
    pool: &ExprPool,
    n: usize,
    sig: &Signature<'_>,
    doc: &dyn Fn(usize, usize) -> String,
    prefix: Vec<syn::Stmt>,
    outputs: &[Output],
) -> Vec<syn::Item> {
    let groups = chunks(pool, outputs);
    let body = |group: &[usize]| -> (Function, Vec<bool>) {
        let out: Vec<(Expr, ExprId)> =
            group.iter().map(|&k| (outputs[k].target.clone(), outputs[k].value)).collect();
        let mut written = vec![false; sig.targets.len()];
        for &k in group {
            written[outputs[k].array] = true;
        }
        (function_with(pool, n, &out, groups.len() > 1), written)
    };
    let name = ident(sig.name);
    if groups.len() == 1 {
        let (f, _) = body(&groups[0]);
        let written = vec![true; sig.targets.len()];
        let mut stmts = prefix;
        stmts.extend(f.stmts);
        let item = sig.item(
            &name,
            &doc(f.ops, f.shared),
            (f.uses_q, f.uses_qd, f.uses_t, &written),
            false,
        );
        return vec![item_fn(item, stmts)];
    }
    let mut items = Vec::new();
    let mut calls = prefix;
    let (mut ops, mut shared) = (0, 0);
    let args: Vec<Ident> = ["q"]
        .into_iter()
        .chain(sig.qd.then_some("qd"))
        .chain(["t"])
        .chain(sig.targets.iter().map(|(a, _)| *a))
        .map(ident)
        .collect();
    for (c, group) in groups.iter().enumerate() {
        let (f, written) = body(group);
        ops += f.ops;
        shared += f.shared;
        let helper = ident(&format!("{}_{c}", sig.name));
        let doc = format!(" Part {c} of [`{}`]: {} operations.", sig.name, f.ops);
        let item = sig.item(&helper, &doc, (f.uses_q, f.uses_qd, f.uses_t, &written), true);
        items.push(item_fn(item, f.stmts));
        calls.push(parse_quote!(#helper(#(#args),*);));
    }
    let doc = format!(
        "{}\n\n Split into {} functions of at most about {CHUNK_OPS} operations each.",
        doc(ops, shared),
        groups.len()
    );
    let all = vec![true; sig.targets.len()];
    let main = sig.item(&name, &doc, (true, true, true, &all), false);
    items.insert(0, item_fn(main, calls));
    items
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
    let rows = sys.rows.iter().map(crate::model::RowLabel::equation);
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

    // Locality of each row when a function is split: its last unknown.
    let key: &Vec<usize> =
        &sys.jac.iter().map(|row| row.iter().map(|&(c, _)| c).max().unwrap_or(0)).collect();
    let vector = |array: usize, name: &str, values: &[ExprId]| -> Vec<Output> {
        values
            .iter()
            .enumerate()
            .map(|(i, &value)| Output { target: element(name, &[i]), array, value, key: key[i] })
            .collect()
    };
    let vec_ty = quote::quote!(&mut [f64; N]);
    let mat_ty = quote::quote!(&mut [[f64; N]; N]);
    let zero_jac: syn::Stmt = parse_quote!(*jac = [[0.0; N]; N];);

    // Φ.
    let phi_outputs = vector(0, "phi", &sys.phi);
    let doc = |ops, shared| {
        format!(
            " Constraint residuals Φ(q, t), {n} rows.\n\n {ops} operations, {shared} shared subexpressions."
        )
    };
    let targets = [("phi", vec_ty.clone())];
    let sig = Signature { name: "residual", qd: false, targets: &targets };
    items.extend(emit_function(pool, n, &sig, &doc, Vec::new(), &phi_outputs));

    // Φ_q.
    let jac_outputs = |array: usize, only_varying: bool| -> Vec<Output> {
        sys.jac
            .iter()
            .enumerate()
            .flat_map(|(i, row)| {
                row.iter().filter(move |&&(_, e)| !only_varying || pool.as_const(e).is_none()).map(
                    move |&(c, value)| Output {
                        target: element("jac", &[i, c]),
                        array,
                        value,
                        key: key[i],
                    },
                )
            })
            .collect()
    };
    let nnz = sys.jac.iter().map(Vec::len).sum::<usize>();
    let doc = |ops, shared| {
        format!(
            " Jacobian Φ_q, row-major: `jac[i][j] = ∂Φ_i/∂q_j`; the {nnz} structurally non-zero entries are written, the others set to 0.\n\n {ops} operations, {shared} shared subexpressions."
        )
    };
    let targets = [("jac", mat_ty.clone())];
    let sig = Signature { name: "jacobian", qd: false, targets: &targets };
    items.extend(emit_function(
        pool,
        n,
        &sig,
        &doc,
        vec![zero_jac.clone()],
        &jac_outputs(0, false),
    ));

    // Φ and Φ_q together, sharing subexpressions.
    let targets = [("phi", vec_ty.clone()), ("jac", mat_ty.clone())];
    let mut both = vector(0, "phi", &sys.phi);
    both.extend(jac_outputs(1, false));
    let doc = |ops, shared| {
        format!(
            " Φ and Φ_q at once (see [`residual`] and [`jacobian`]).\n\n {ops} operations, {shared} shared subexpressions."
        )
    };
    let sig = Signature { name: "residual_jacobian", qd: false, targets: &targets };
    items.extend(emit_function(pool, n, &sig, &doc, vec![zero_jac], &both));

    // Φ and the entries of Φ_q that vary: the constant ones are literals in `factor_k`.
    let mut varying = phi_outputs;
    varying.extend(jac_outputs(1, true));
    let count = varying.len() - n;
    let doc = |ops, shared| {
        format!(
            " Φ and the {count} entries of Φ_q that depend on q or t, the others of `jac` left as they were: what the `factor_k` functions read ({} of the {nnz} structurally non-zero entries are constants, which they know).\n\n {ops} operations, {shared} shared subexpressions.",
            nnz - count
        )
    };
    let sig = Signature { name: "residual_jacobian_structural", qd: false, targets: &targets };
    items.extend(emit_function(pool, n, &sig, &doc, Vec::new(), &varying));

    // The structured LU: static pivot orders over the description's motion.
    let orders = if n == 0 { Vec::new() } else { lu::plan_motion(mech, sys) };
    let structure = lu::structure(sys);
    let constant = lu::constants(sys);
    for (k, order) in orders.iter().enumerate() {
        items.extend(lu::emit(order, &structure, &constant, k));
    }

    // ν.
    let doc = |ops, shared| {
        format!(
            " Velocity right-hand side ν = −Φ_t.\n\n {ops} operations, {shared} shared subexpressions."
        )
    };
    let targets = [("nu", vec_ty.clone())];
    let sig = Signature { name: "velocity_rhs", qd: false, targets: &targets };
    items.extend(emit_function(pool, n, &sig, &doc, Vec::new(), &vector(0, "nu", &sys.nu)));

    // γ.
    let doc = |ops, shared| {
        format!(
            " Acceleration right-hand side γ = −(Φ_q q̇)_q q̇ − 2Φ_qt q̇ − Φ_tt.\n\n {ops} operations, {shared} shared subexpressions."
        )
    };
    let targets = [("gamma", vec_ty)];
    let sig = Signature { name: "acceleration_rhs", qd: true, targets: &targets };
    items.extend(emit_function(pool, n, &sig, &doc, Vec::new(), &vector(0, "gamma", &sys.gamma)));

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
        items.iter_mut().for_each(scalar::to_f32);
    }
    let mut attrs = vec![parse_quote!(#![cfg_attr(rustfmt, rustfmt::skip)])];
    attrs.extend(doc_attributes(&docs, true));
    let mut text = String::from("// @generated by mechgen. Do not edit.\n\n");
    text.push_str(&prettyplease::unparse(&syn::File { shebang: None, attrs, items: Vec::new() }));
    for mut item in items {
        one_line_docs(&mut item);
        text.push('\n');
        text.push_str(&prettyplease::unparse(&syn::File {
            shebang: None,
            attrs: Vec::new(),
            items: vec![item],
        }));
    }
    text
}

/// `text` as documentation shows it safely: every character a comment cannot hold as it is
/// (controls, bidi and other invisible format characters, line separators) as a visible
/// `\u{…}` escape, and tabs as four spaces (clippy's `tabs_in_doc_comments`). Validation
/// refuses most of these; this holds for any text.
fn doc_safe(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if c == '\t' {
            out.push_str("    ");
        } else if crate::validate::names::hidden(c) {
            out.push_str(&format!("\\u{{{:04x}}}", u32::from(c)));
        } else {
            out.push(c);
        }
    }
    out
}

/// `text` with a backslash before each character Markdown reads as markup inside a line
/// (code spans, links, images, HTML, emphasis), so rustdoc shows names as the plain text
/// they are.
fn markdown_escaped(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        if matches!(c, '\\' | '`' | '*' | '<' | '>' | '[' | ']' | '&' | '~' | '|') {
            out.push('\\');
        }
        out.push(c);
    }
    out
}

/// A description as documentation lines: a fenced `text` block whose fence is longer than
/// any run of backticks in it, so nothing in it is Markdown (no code block rustdoc would run
/// as a doctest, no HTML, no link) and no line of it can close the block.
fn fenced(description: &str) -> Vec<String> {
    let longest = description.split(|c| c != '`').map(str::len).max().unwrap_or(0);
    let fence = "`".repeat(longest.max(2) + 1);
    let mut lines = vec![format!(" {fence}text")];
    lines.extend(description.split("\r\n").flat_map(|l| l.split(['\n', '\r'])).map(|l| {
        let l = doc_safe(l);
        if l.is_empty() { l } else { format!(" {l}") }
    }));
    lines.push(format!(" {fence}"));
    lines
}

/// One `#[doc = "…"]` attribute per line, each line a string literal (made safe by
/// [`doc_safe`]); inner (`//!`) or outer (`///`) as prettyplease prints them.
fn doc_attributes(lines: &[String], inner: bool) -> Vec<syn::Attribute> {
    lines
        .iter()
        .map(|line| {
            let lit = syn::LitStr::new(&doc_safe(line), Span::call_site());
            if inner { parse_quote!(#![doc = #lit]) } else { parse_quote!(#[doc = #lit]) }
        })
        .collect()
}

/// Rewrites every `#[doc]` attribute of a top-level item (and of an impl's items) as one
/// attribute per line made safe by [`doc_safe`], so prettyplease prints `///` lines and never
/// a `/** … */` block, which a `*/` in the text would end.
fn one_line_docs(item: &mut syn::Item) {
    fn split(attrs: &mut Vec<syn::Attribute>) {
        if !attrs.iter().any(|a| doc_of(a).is_some()) {
            return;
        }
        let mut out = Vec::with_capacity(attrs.len());
        for attr in attrs.drain(..) {
            match doc_of(&attr) {
                Some(doc) => {
                    let lines: Vec<String> = doc.lines().map(str::to_owned).collect();
                    out.extend(doc_attributes(&lines, false));
                }
                None => out.push(attr),
            }
        }
        *attrs = out;
    }
    match item {
        syn::Item::Fn(f) => split(&mut f.attrs),
        syn::Item::Const(c) => split(&mut c.attrs),
        syn::Item::Static(s) => split(&mut s.attrs),
        syn::Item::Struct(s) => split(&mut s.attrs),
        syn::Item::Impl(i) => {
            split(&mut i.attrs);
            for item in &mut i.items {
                if let syn::ImplItem::Fn(f) = item {
                    split(&mut f.attrs);
                }
            }
        }
        _ => {}
    }
}

/// The text of a `#[doc = "…"]` attribute.
fn doc_of(attr: &syn::Attribute) -> Option<String> {
    match &attr.meta {
        syn::Meta::NameValue(m) if m.path.is_ident("doc") => match &m.value {
            Expr::Lit(syn::ExprLit { lit: syn::Lit::Str(s), .. }) => Some(s.value()),
            _ => None,
        },
        _ => None,
    }
}

/// A literal for any finite value (negative ones as unary minus).
fn literal_signed(v: f64) -> Expr {
    if v < 0.0 { neg(literal(-v)) } else { literal(v) }
}

#[cfg(test)]
mod tests;
