//! One emitted function from its outputs: the shared subexpressions as `let` temporaries,
//! then one assignment per output, split into `#[inline(never)]` helpers when it would exceed
//! [`CHUNK_OPS`] operations.
//!
//! Each function evaluates its outputs in one forward pass over the expression arena: nodes
//! used more than once become `let tK` temporaries (numbered in topological order), all others
//! are inlined. Operator trees are built with parentheses exactly where Rust's precedence and
//! left associativity would otherwise change the tree, so the emitted code performs the same
//! floating-point operations as `ExprPool::eval`.

use syn::{Expr, Ident, parse_quote};

use super::syntax::{
    Prec, assign, binary, call, element, ident, item_fn, let_stmt, literal, neg, param, paren, path,
};
use crate::expr::{ExprId, ExprPool, Node, Var};

/// One function body under construction: the `let` temporaries and the variables used.
struct Body<'p> {
    pool: &'p ExprPool,
    /// Temporary name of each shared node, by node index.
    temp: std::collections::HashMap<usize, Ident>,
    /// Nodes computed elsewhere and read as these expressions (the time terms, see
    /// [`function_reading`]): leaves of this body.
    given: &'p Given,
    stmts: Vec<syn::Stmt>,
    ops: usize,
}

/// Nodes a function reads instead of computing them, by node index (see [`function_reading`]).
pub(super) type Given = std::collections::HashMap<usize, Expr>;

impl<'p> Body<'p> {
    /// Plans the temporaries for `roots`: every operation node reachable more than once, and
    /// every node of `store`, which is also assigned to the place given for it (for a later
    /// part of a split function to read, see [`emit_function`]).
    ///
    /// Works on the reachable nodes alone (maps, not arrays over the arena), so that the many
    /// small functions of a large system each cost what they use.
    fn new(pool: &'p ExprPool, roots: &[ExprId], given: &'p Given, store: &'p Given) -> Self {
        use std::collections::{BTreeMap, HashMap};
        let mut uses: HashMap<usize, usize> = HashMap::new();
        let mut stack: Vec<ExprId> = roots.to_vec();
        for r in roots {
            *uses.entry(r.index()).or_insert(0) += 1;
        }
        let mut live: Vec<usize> = Vec::new();
        let mut seen = std::collections::HashSet::new();
        while let Some(x) = stack.pop() {
            if !seen.insert(x.index()) || given.contains_key(&x.index()) {
                continue;
            }
            live.push(x.index());
            for c in pool[x].children() {
                *uses.entry(c.index()).or_insert(0) += 1;
                stack.push(c);
            }
        }
        live.sort_unstable();
        // sin a and cos a both needed: one `runtime::math::sin_cos(a)` gives both, with one
        // argument reduction (and the same bits as `sin` and `cos`).
        let mut trig: BTreeMap<ExprId, [Option<usize>; 2]> = BTreeMap::new();
        for &k in &live {
            match pool.nodes()[k] {
                Node::Sin(a) => trig.entry(a).or_default()[0] = Some(k),
                Node::Cos(a) => trig.entry(a).or_default()[1] = Some(k),
                _ => {}
            }
        }
        let mut pair: HashMap<usize, (ExprId, usize, usize)> = HashMap::new();
        for (&a, &[s, c]) in &trig {
            if let (Some(s), Some(c)) = (s, c) {
                pair.insert(s, (a, s, c));
                pair.insert(c, (a, s, c));
            }
        }
        let mut body = Self { pool, temp: HashMap::new(), given, stmts: Vec::new(), ops: 0 };
        let mut count = 0;
        for &k in &live {
            let leaf = matches!(pool.nodes()[k], Node::Const(_) | Node::Var(_));
            if !leaf {
                body.ops += 1;
            }
            if let Some(&(a, s, c)) = pair.get(&k) {
                if !body.temp.contains_key(&k) {
                    let (arg, _) = body.render(a);
                    let (sin, cos) =
                        (ident(&format!("t{count}")), ident(&format!("t{}", count + 1)));
                    count += 2;
                    body.stmts.push(parse_quote!(let (#sin, #cos) = runtime::math::sin_cos(#arg);));
                    body.temp.insert(s, sin);
                    body.temp.insert(c, cos);
                }
            } else if !leaf && (uses.get(&k).copied().unwrap_or(0) >= 2 || store.contains_key(&k)) {
                let (e, _) = body.render(ExprId::from_index(k));
                let name = ident(&format!("t{count}"));
                count += 1;
                body.stmts.push(let_stmt(name.clone(), e));
                body.temp.insert(k, name);
            }
            if let (Some(place), Some(name)) = (store.get(&k), body.temp.get(&k)) {
                body.stmts.push(assign(place.clone(), path(name.clone())));
            }
        }
        body
    }

    /// The number of shared temporaries.
    fn shared(&self) -> usize {
        self.temp.len()
    }

    /// An expression for `id` with its binding strength.
    fn render(&self, id: ExprId) -> (Expr, Prec) {
        if let Some(name) = self.temp.get(&id.index()) {
            return (path(name.clone()), Prec::Atom);
        }
        if let Some(e) = self.given.get(&id.index()) {
            return (e.clone(), Prec::Atom);
        }
        let at_least = |e: (Expr, Prec), p: Prec| if e.1 >= p { e.0 } else { paren(e.0) };
        match self.pool[id] {
            Node::Const(bits) => {
                let v = f64::from_bits(bits);
                if v < 0.0 { (neg(literal(-v)), Prec::Unary) } else { (literal(v), Prec::Atom) }
            }
            Node::Var(Var::Q(k)) => (path(ident(&format!("q{k}"))), Prec::Atom),
            Node::Var(Var::Qd(k)) => (path(ident(&format!("qd{k}"))), Prec::Atom),
            Node::Var(Var::Qdd(k)) => (path(ident(&format!("qdd{k}"))), Prec::Atom),
            Node::Var(Var::T) => (path(ident("t")), Prec::Atom),
            Node::Var(Var::S(k)) => (path(ident(&format!("s{k}"))), Prec::Atom),
            Node::Var(Var::Sd(k)) => (path(ident(&format!("sd{k}"))), Prec::Atom),
            Node::Var(Var::Sdd(k)) => (path(ident(&format!("sdd{k}"))), Prec::Atom),
            Node::Var(Var::Param(k)) => (path(ident(&format!("c{k}"))), Prec::Atom),
            Node::Neg(a) => (neg(at_least(self.render(a), Prec::Unary)), Prec::Unary),
            Node::Add(a, b) => {
                // x + (−y) and (−y) + x are written x − y: the same IEEE operation, since
                // addition commutes exactly and negation is exact.
                let negated = |e: ExprId| -> Option<Expr> {
                    if self.temp.contains_key(&e.index()) || self.given.contains_key(&e.index()) {
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

/// `let [q0, _q1, …] = *q;` naming the unused entries with a leading underscore.
fn destructure(prefix: &str, n: usize, used: &[bool]) -> syn::Stmt {
    let names = (0..n).map(|k| {
        let name = if used[k] { format!("{prefix}{k}") } else { format!("_{prefix}{k}") };
        ident(&name)
    });
    let src = ident(prefix);
    parse_quote!(let [#(#names),*] = *#src;)
}

/// Which inputs an expression uses: for input k, whether it reads s_k, ṡ_k and s̈_k.
type InputUse = std::collections::BTreeMap<u32, [bool; 3]>;

/// `let [s0, sd0, _sdd0] = u[0];` for every input used, naming unused derivatives with a
/// leading underscore.
fn destructure_inputs(used: &InputUse) -> Vec<syn::Stmt> {
    used.iter()
        .map(|(&k, d)| {
            let names = ["s", "sd", "sdd"]
                .iter()
                .zip(d)
                .map(|(p, &u)| ident(&if u { format!("{p}{k}") } else { format!("_{p}{k}") }));
            let k = super::syntax::index(k as usize);
            parse_quote!(let [#(#names),*] = u[#k];)
        })
        .collect()
}

/// Which symbols the expressions reachable from `roots` use: (q, q̇, q̈, t, inputs).
fn symbols(
    pool: &ExprPool,
    roots: &[ExprId],
    n: usize,
    given: &Given,
) -> ([Vec<bool>; 3], bool, InputUse) {
    let (mut q, mut qd, mut qdd, mut t) = (vec![false; n], vec![false; n], vec![false; n], false);
    let mut inputs = InputUse::new();
    let mut seen = std::collections::BTreeSet::new();
    let mut stack = roots.to_vec();
    while let Some(x) = stack.pop() {
        if !seen.insert(x) || given.contains_key(&x.index()) {
            continue;
        }
        match pool[x] {
            Node::Var(Var::Q(k)) => q[k as usize] = true,
            Node::Var(Var::Qd(k)) => qd[k as usize] = true,
            Node::Var(Var::Qdd(k)) => qdd[k as usize] = true,
            Node::Var(Var::T) => t = true,
            Node::Var(Var::S(k)) => inputs.entry(k).or_default()[0] = true,
            Node::Var(Var::Sd(k)) => inputs.entry(k).or_default()[1] = true,
            Node::Var(Var::Sdd(k)) => inputs.entry(k).or_default()[2] = true,
            node => stack.extend(node.children()),
        }
    }
    ([q, qd, qdd], t, inputs)
}

/// The parameters (`Var::Param`) the expressions reachable from `roots` use, in order.
fn parameters(pool: &ExprPool, roots: &[ExprId]) -> std::collections::BTreeSet<u32> {
    let mut used = std::collections::BTreeSet::new();
    let mut seen = std::collections::BTreeSet::new();
    let mut stack = roots.to_vec();
    while let Some(x) = stack.pop() {
        if seen.insert(x) {
            if let Node::Var(Var::Param(k)) = pool[x] {
                used.insert(k);
            }
            stack.extend(pool[x].children());
        }
    }
    used
}

/// A function body: destructuring, temporaries, then `target = value;` per output.
pub(super) struct Function {
    pub(super) stmts: Vec<syn::Stmt>,
    pub(super) uses_t: bool,
    pub(super) uses_q: bool,
    pub(super) uses_qd: bool,
    pub(super) uses_qdd: bool,
    /// Whether it reads the inputs `u` (a local `[[s, ṡ, s̈]; INPUTS]`).
    pub(super) uses_u: bool,
    pub(super) ops: usize,
    pub(super) shared: usize,
}

/// [`function`]'s outputs: where each value goes, and the row of the system it belongs to,
/// whose note precedes the first of consecutive outputs of the same row.
pub(super) type Targets = [(Expr, ExprId, Option<usize>)];

pub(super) fn function(pool: &ExprPool, n: usize, outputs: &Targets) -> Function {
    function_with(pool, n, outputs, false)
}

/// [`function`], reading the used entries of q and q̇ one by one (`let q5 = q[5];`) when
/// `part`: a part of a split function uses few of them.
pub(super) fn function_with(pool: &ExprPool, n: usize, outputs: &Targets, part: bool) -> Function {
    let reads = if part { Reads::OneByOne } else { Reads::Destructured };
    function_reading(pool, n, outputs, &reads, &Given::new(), &Given::new())
}

/// How a function reads the entries of q, q̇ and q̈ it uses, the inputs and the parameters
/// (`Var::Param`) of a template.
pub(super) enum Reads<'a> {
    /// `let [q0, _q1, …] = *q;`.
    Destructured,
    /// `let q5 = q[5];`.
    OneByOne,
    /// `let q5 = read("q", 5);` (also "qd", "qdd"), `let [s2, sd2, sdd2] = read("u", 2);` and
    /// `let c3 = read("c", 3);`: a shared block function's entries at its block's places.
    With(&'a dyn Fn(&str, usize) -> Expr),
}

/// [`function_with`], reading the symbols as `reads` says and the nodes of `given` as the
/// expressions given for them (such as `terms[0]`) instead of computing them: what they alone
/// need is neither computed nor read. The nodes of `store` it computes are also assigned to
/// the places given for them.
pub(super) fn function_reading(
    pool: &ExprPool,
    n: usize,
    outputs: &Targets,
    reads: &Reads<'_>,
    given: &Given,
    store: &Given,
) -> Function {
    let roots: Vec<ExprId> = outputs.iter().map(|(_, e, _)| *e).collect();
    let ([q, qd, qdd], t, inputs) = symbols(pool, &roots, n, given);
    let body = Body::new(pool, &roots, given, store);
    let mut stmts = Vec::new();
    let any = |v: &[bool]| v.iter().any(|&u| u);
    let (uses_q, uses_qd, uses_qdd) = (any(&q), any(&qd), any(&qdd));
    for (prefix, used) in [("q", &q), ("qd", &qd), ("qdd", &qdd)] {
        if !used.iter().any(|&u| u) {
            continue;
        }
        match reads {
            Reads::Destructured => stmts.push(destructure(prefix, n, used)),
            Reads::OneByOne => {
                for k in (0..n).filter(|&k| used[k]) {
                    stmts.push(let_stmt(ident(&format!("{prefix}{k}")), element(prefix, &[k])));
                }
            }
            Reads::With(read) => {
                for k in (0..n).filter(|&k| used[k]) {
                    stmts.push(let_stmt(ident(&format!("{prefix}{k}")), read(prefix, k)));
                }
            }
        }
    }
    if let Reads::With(read) = reads {
        for (&k, d) in &inputs {
            let names = ["s", "sd", "sdd"]
                .iter()
                .zip(d)
                .map(|(p, &u)| ident(&if u { format!("{p}{k}") } else { format!("_{p}{k}") }));
            let at = read("u", k as usize);
            stmts.push(parse_quote!(let [#(#names),*] = #at;));
        }
        for k in parameters(pool, &roots) {
            stmts.push(let_stmt(ident(&format!("c{k}")), read("c", k as usize)));
        }
    } else {
        stmts.extend(destructure_inputs(&inputs));
    }
    stmts.extend(body.stmts.iter().cloned());
    let mut last_row = None;
    for (target, e, row) in outputs {
        if let Some(r) = *row
            && last_row != Some(r)
        {
            stmts.push(super::notes::marker(r));
        }
        last_row = *row;
        let (value, _) = body.render(*e);
        stmts.push(assign(target.clone(), value));
    }
    Function {
        stmts,
        uses_t: t,
        uses_q,
        uses_qd,
        uses_qdd,
        uses_u: !inputs.is_empty(),
        ops: body.ops,
        shared: body.shared(),
    }
}

/// Functions whose outputs take more operations than this are split into helpers of about
/// this many operations each, so that rustc and LLVM never see one giant function (their time
/// grows faster than linearly with a function's size). The largest function of the examples
/// has under 800 operations and is not split.
pub const CHUNK_OPS: usize = 1500;

/// One value a function writes: `target = value`, to the array `targets[array]`; `key` orders
/// the outputs when the function is split (outputs with near keys share subexpressions).
pub(super) struct Output {
    pub(super) target: Expr,
    pub(super) array: usize,
    pub(super) value: ExprId,
    pub(super) key: usize,
    /// The row of the system it belongs to, if any (for its note).
    pub(super) row: Option<usize>,
}

/// The outputs in groups of at most about [`CHUNK_OPS`] operations: one group in the given
/// order when they fit, else ordered by key and cut greedily. A node of `kept` that an earlier
/// group computes costs a later one nothing (it is read back, see [`emit_function`]).
fn chunks(pool: &ExprPool, outputs: &[Output], kept: &[ExprId]) -> Vec<Vec<usize>> {
    let mut marks = vec![0u32; pool.len()];
    let total: usize = outputs.iter().map(|o| pool.new_operations(o.value, &mut marks, 1)).sum();
    if total <= CHUNK_OPS {
        return vec![(0..outputs.len()).collect()];
    }
    let mut order: Vec<usize> = (0..outputs.len()).collect();
    order.sort_by_key(|&k| outputs[k].key);
    let mut available = std::collections::HashSet::new();
    let (mut groups, mut current, mut ops, mut stamp) = (Vec::new(), Vec::new(), 0, 2);
    for k in order {
        let mut more = operations(pool, outputs[k].value, &mut marks, stamp, &available);
        if !current.is_empty() && ops + more > CHUNK_OPS {
            groups.push(std::mem::take(&mut current));
            available.extend(kept.iter().map(|e| e.index()).filter(|&e| marks[e] == stamp));
            stamp += 1;
            ops = 0;
            more = operations(pool, outputs[k].value, &mut marks, stamp, &available);
        }
        current.push(k);
        ops += more;
    }
    groups.push(current);
    groups
}

/// The operations reachable from `root` and not yet marked with `stamp`, short of the nodes of
/// `available`; marks them.
fn operations(
    pool: &ExprPool,
    root: ExprId,
    marks: &mut [u32],
    stamp: u32,
    available: &std::collections::HashSet<usize>,
) -> usize {
    let mut stack = vec![root];
    let mut count = 0;
    while let Some(x) = stack.pop() {
        if available.contains(&x.index())
            || std::mem::replace(&mut marks[x.index()], stamp) == stamp
        {
            continue;
        }
        if !pool.is_leaf(x) {
            count += 1;
        }
        stack.extend(pool[x].children());
    }
    count
}

/// What an emitted function reads and writes.
pub(super) struct Signature<'a> {
    pub(super) name: &'a str,
    /// Whether q̇ is a parameter (after q).
    pub(super) qd: bool,
    /// Whether q̈ is a parameter (after q̇, which it implies).
    pub(super) qdd: bool,
    /// Whether the function is part of the module's public surface (else only the
    /// `runtime::Mechanism` impl calls it).
    pub(super) public: bool,
    /// Whether the module has input drivers: the function then takes `inputs: &Inputs`
    /// after `t` (its split parts the array `u: &[[f64; 3]; INPUTS]`).
    pub(super) inputs: bool,
    /// The arrays written, with their types, after `t`.
    pub(super) targets: &'a [(&'a str, proc_macro2::TokenStream)],
}

/// Which parameters of a [`Signature`] a function body reads or writes.
pub(super) struct Used<'a> {
    pub(super) q: bool,
    pub(super) qd: bool,
    pub(super) qdd: bool,
    pub(super) t: bool,
    pub(super) u: bool,
    /// Per target array.
    pub(super) arrays: &'a [bool],
}

impl Used<'_> {
    /// What `f` reads, with `arrays` the targets it writes.
    pub(super) fn of<'a>(f: &Function, arrays: &'a [bool]) -> Used<'a> {
        Used { q: f.uses_q, qd: f.uses_qd, qdd: f.uses_qdd, t: f.uses_t, u: f.uses_u, arrays }
    }
}

impl Signature<'_> {
    /// `fn name(q: &[f64; N], [qd: &[f64; N], [qdd: &[f64; N],]] t: f64, targets…)`, each
    /// parameter named with a leading underscore when it is not used.
    pub(super) fn item(
        &self,
        name: &Ident,
        doc: &str,
        used: &Used<'_>,
        helper: bool,
    ) -> syn::ItemFn {
        let Used { q, qd, qdd, t, u, arrays } = *used;
        let mut params: Vec<syn::FnArg> = vec![{
            let q = param("q", q);
            parse_quote!(#q: &[f64; N])
        }];
        if self.qd {
            let qd = param("qd", qd);
            params.push(parse_quote!(#qd: &[f64; N]));
        }
        if self.qdd {
            let qdd = param("qdd", qdd);
            params.push(parse_quote!(#qdd: &[f64; N]));
        }
        let t = param("t", t);
        params.push(parse_quote!(#t: f64));
        if self.inputs && helper {
            let u = param("u", u);
            params.push(parse_quote!(#u: &[[f64; 3]; INPUTS]));
        } else if self.inputs {
            let u = param("inputs", u);
            params.push(parse_quote!(#u: &Inputs));
        }
        for ((a, ty), &w) in self.targets.iter().zip(arrays) {
            let a = param(a, w);
            params.push(parse_quote!(#a: #ty));
        }
        if helper {
            parse_quote! {
                #[doc = #doc]
                #[inline(never)]
                fn #name(#(#params),*) {}
            }
        } else if self.public {
            parse_quote! {
                #[doc = #doc]
                pub fn #name(#(#params),*) {}
            }
        } else {
            parse_quote! {
                #[doc = #doc]
                fn #name(#(#params),*) {}
            }
        }
    }
}

/// The function `sig.name` writing `outputs` after `prefix`, split into `#[inline(never)]`
/// helpers `name_0`, `name_1`, … when it would exceed [`CHUNK_OPS`] operations. `doc` gets
/// the operations and shared subexpressions in total.
///
/// The nodes of `kept` (a module's substituted coordinates, with their rates and
/// accelerations) are what the outputs of a long explicit chain share: body k's coordinates
/// are expressions of body k − 1's. A part that computes one also stores it in the array
/// `kept: &mut [f64; K]` of the split function, and later parts read it there instead of
/// computing it again, so that the parts together cost what one function would.
pub(super) fn emit_function(
    pool: &ExprPool,
    n: usize,
    sig: &Signature<'_>,
    doc: &dyn Fn(usize, usize) -> String,
    prefix: Vec<syn::Stmt>,
    outputs: &[Output],
    kept: &[ExprId],
) -> Vec<syn::Item> {
    let groups = chunks(pool, outputs, kept);
    let written = |group: &[usize]| -> Vec<bool> {
        let mut written = vec![false; sig.targets.len()];
        for &k in group {
            written[outputs[k].array] = true;
        }
        written
    };
    let targets = |group: &[usize]| -> Vec<(Expr, ExprId, Option<usize>)> {
        group
            .iter()
            .map(|&k| (outputs[k].target.clone(), outputs[k].value, outputs[k].row))
            .collect()
    };
    let name = ident(sig.name);
    if groups.len() == 1 {
        let f = function_with(pool, n, &targets(&groups[0]), false);
        let mut written = written(&groups[0]);
        // The prefix (zeroing an array) writes every target it names; assume all.
        if !prefix.is_empty() {
            written.fill(true);
        }
        let item = sig.item(&name, &doc(f.ops, f.shared), &Used::of(&f, &written), false);
        let mut stmts = prefix;
        if f.uses_u {
            stmts.insert(0, parse_quote!(let u = inputs.to_array();));
        }
        stmts.extend(f.stmts);
        return vec![item_fn(item, stmts)];
    }
    // Which kept nodes each part computes first, and which of them a later part reads: only
    // those are stored, in the order the parts compute them.
    let kept: std::collections::HashSet<usize> =
        kept.iter().filter(|e| !pool.is_leaf(**e)).map(|e| e.index()).collect();
    let roots =
        |group: &[usize]| -> Vec<ExprId> { group.iter().map(|&k| outputs[k].value).collect() };
    let mut available = std::collections::HashSet::new();
    let mut first: Vec<Vec<usize>> = Vec::new();
    let mut read = std::collections::HashSet::new();
    for group in &groups {
        let (computed, reads) = reach(pool, &roots(group), &available);
        read.extend(reads);
        let new: Vec<usize> = computed.into_iter().filter(|e| kept.contains(e)).collect();
        available.extend(new.iter().copied());
        first.push(new);
    }
    let mut slot: std::collections::HashMap<usize, Expr> = std::collections::HashMap::new();
    for &node in first.iter().flatten().filter(|e| read.contains(*e)) {
        let place = element("kept", &[slot.len()]);
        slot.insert(node, place);
    }
    let mut items = Vec::new();
    let mut calls = prefix;
    if sig.inputs {
        calls.insert(0, parse_quote!(let u = inputs.to_array();));
    }
    let size = super::syntax::index(slot.len());
    if !slot.is_empty() {
        calls.push(parse_quote!(let mut kept = [0.0; #size];));
    }
    let (mut ops, mut shared) = (0, 0);
    let args: Vec<Expr> = ["q"]
        .into_iter()
        .chain(sig.qd.then_some("qd"))
        .chain(sig.qdd.then_some("qdd"))
        .chain(["t"])
        .map(|a| path(ident(a)))
        .chain(sig.inputs.then(|| parse_quote!(&u)))
        .chain(sig.targets.iter().map(|(a, _)| path(ident(a))))
        .chain((!slot.is_empty()).then(|| parse_quote!(&mut kept)))
        .collect();
    // The stored nodes computed by the parts so far, read back by the next ones.
    let mut given = Given::new();
    for (c, group) in groups.iter().enumerate() {
        let out = targets(group);
        let reads_kept = reads_given(pool, &roots(group), &given);
        let store: Given =
            first[c].iter().filter_map(|e| Some((*e, slot.get(e)?.clone()))).collect();
        let f = function_reading(pool, n, &out, &Reads::OneByOne, &given, &store);
        ops += f.ops;
        shared += f.shared;
        let helper = ident(&format!("{}_{c}", sig.name));
        let doc = format!(" Part {c} of [`{}`]: {} operations.", sig.name, f.ops);
        let mut item = sig.item(&helper, &doc, &Used::of(&f, &written(group)), true);
        if !slot.is_empty() {
            let k = param("kept", reads_kept || !store.is_empty());
            item.sig.inputs.push(parse_quote!(#k: &mut [f64; #size]));
        }
        // A part takes its function's parameters and `kept`: 8 with q̇, q̈, the inputs and two
        // arrays (the Stewart platform's joint terms), one over clippy's `too_many_arguments`.
        if item.sig.inputs.len() > 7 {
            item.attrs.push(parse_quote!(#[allow(clippy::too_many_arguments)]));
        }
        items.push(item_fn(item, f.stmts));
        calls.push(parse_quote!(#helper(#(#args),*);));
        given.extend(store);
    }
    let doc = format!(
        "{}\n\n Split into {} functions of at most about {CHUNK_OPS} operations each.",
        doc(ops, shared),
        groups.len()
    );
    let all = vec![true; sig.targets.len()];
    let used = Used { q: true, qd: true, qdd: true, t: true, u: true, arrays: &all };
    let main = sig.item(&name, &doc, &used, false);
    items.insert(0, item_fn(main, calls));
    items
}

/// The operation nodes reachable from `roots` short of the nodes of `available`, and the
/// nodes of `available` reached: what a function writing `roots` computes and what it reads.
fn reach(
    pool: &ExprPool,
    roots: &[ExprId],
    available: &std::collections::HashSet<usize>,
) -> (Vec<usize>, Vec<usize>) {
    let mut seen = std::collections::HashSet::new();
    let mut stack = roots.to_vec();
    let (mut computed, mut read) = (Vec::new(), Vec::new());
    while let Some(x) = stack.pop() {
        if !seen.insert(x.index()) {
            continue;
        }
        if available.contains(&x.index()) {
            read.push(x.index());
        } else if !pool.is_leaf(x) {
            computed.push(x.index());
            stack.extend(pool[x].children());
        }
    }
    (computed, read)
}

/// Whether the expressions reachable from `roots` read a node of `given`.
fn reads_given(pool: &ExprPool, roots: &[ExprId], given: &Given) -> bool {
    let mut seen = std::collections::HashSet::new();
    let mut stack = roots.to_vec();
    while let Some(x) = stack.pop() {
        if given.contains_key(&x.index()) {
            return true;
        }
        if seen.insert(x.index()) {
            stack.extend(pool[x].children());
        }
    }
    false
}

/// The function `sig.name` writing `outputs` after `prefix` as [`emit_function`] does, reading
/// the nodes of `given` from a parameter `terms: &[f64; TIME_TERMS]` after `t` (the time
/// terms, see `emit::time`); `None` when it would be split into helpers, or for a module with
/// inputs, which this does not cover.
pub(super) fn emit_function_given(
    pool: &ExprPool,
    n: usize,
    sig: &Signature<'_>,
    doc: &dyn Fn(usize, usize) -> String,
    prefix: Vec<syn::Stmt>,
    outputs: &[Output],
    given: &Given,
) -> Option<syn::Item> {
    if sig.inputs || chunks(pool, outputs, &[]).len() > 1 {
        return None;
    }
    let out: Vec<(Expr, ExprId, Option<usize>)> =
        outputs.iter().map(|o| (o.target.clone(), o.value, o.row)).collect();
    let f = function_reading(pool, n, &out, &Reads::Destructured, given, &Given::new());
    let mut written = vec![false; sig.targets.len()];
    for o in outputs {
        written[o.array] = true;
    }
    // The prefix (zeroing an array) writes every target it names; assume all.
    if !prefix.is_empty() {
        written.fill(true);
    }
    let mut item =
        sig.item(&ident(sig.name), &doc(f.ops, f.shared), &Used::of(&f, &written), false);
    let roots: Vec<ExprId> = outputs.iter().map(|o| o.value).collect();
    let terms = param("terms", reads_given(pool, &roots, given));
    // After q, q̇ and q̈ as the signature has them, and t.
    let at = 2 + usize::from(sig.qd) + usize::from(sig.qdd);
    item.sig.inputs.insert(at, parse_quote!(#terms: &[f64; TIME_TERMS]));
    let mut stmts = prefix;
    stmts.extend(f.stmts);
    Some(item_fn(item, stmts))
}
