//! The structured LU of Φ_q printed as code: for each static pivot order that
//! [`crate::pivot`] plans, straight-line `factor_k` and `solve_k` functions that touch only the
//! entries of L and U, with the entries known at generation time folded in; and, for the
//! diagonal blocks of Newton block by block (`block`), the same arithmetic as statements
//! at places `emit::blocks` chooses, its stores deferred until every guard passed.

use syn::{Expr, Ident, parse_quote};

use super::CHUNK_OPS;
use super::syntax::{
    Prec, assign, binary, element, ident, item_fn, let_stmt, literal_signed, neg, paren, path,
};
use crate::pivot::{Order, RUNTIME_MAX_MULTIPLIER};

/// `jac[r][c]` (or `lu[r][c]`).
fn entry(array: &str, r: usize, c: usize) -> Expr {
    element(array, &[r, c])
}

/// The local holding entry (k, l) of L or U in step coordinates (the reciprocal of the pivot on
/// the diagonal).
fn local(k: usize, l: usize) -> Ident {
    if k == l {
        ident(&format!("d{k}"))
    } else if k > l {
        ident(&format!("l{k}_{l}"))
    } else {
        ident(&format!("u{k}_{l}"))
    }
}

/// A value in the factorisation: known when the code is generated (the constant entries of
/// Φ_q, and what is computed from constants only), or computed at run time.
///
/// Folding follows IEEE arithmetic exactly: constants are combined with the same operations
/// in the same order as the run time would, and only multiplications by ±1, negations of
/// negations and subtractions of negations (all exact) are rewritten.
#[derive(Clone)]
enum Val {
    Const(f64),
    Run(Expr, Prec),
}

impl Val {
    fn expr(&self, at_least: Prec) -> Expr {
        let (e, p) = match self {
            Val::Const(c) if *c < 0.0 => (literal_signed(*c), Prec::Unary),
            Val::Const(c) => (literal_signed(*c), Prec::Atom),
            Val::Run(e, p) => (e.clone(), *p),
        };
        if p >= at_least { e } else { paren(e) }
    }

    fn negated(&self) -> Val {
        match self {
            Val::Const(c) => Val::Const(-c),
            Val::Run(Expr::Unary(u), _) if matches!(u.op, syn::UnOp::Neg(_)) => {
                let inner = (*u.expr).clone();
                // The operand was printed at unary strength at least.
                let p = if matches!(inner, Expr::Binary(_) | Expr::Paren(_)) {
                    Prec::Atom
                } else {
                    Prec::Unary
                };
                Val::Run(inner, p)
            }
            Val::Run(..) => Val::Run(neg(self.expr(Prec::Unary)), Prec::Unary),
        }
    }

    fn is_negation(&self) -> bool {
        matches!(self, Val::Run(Expr::Unary(u), _) if matches!(u.op, syn::UnOp::Neg(_)))
    }

    fn mul(&self, other: &Val) -> Val {
        match (self, other) {
            (Val::Const(a), Val::Const(b)) => Val::Const(a * b),
            (Val::Const(c), v) | (v, Val::Const(c)) if *c == 1.0 => v.clone(),
            (Val::Const(c), v) | (v, Val::Const(c)) if *c == -1.0 => v.negated(),
            (a, b) => Val::Run(
                binary(
                    a.expr(Prec::Product),
                    syn::BinOp::Mul(Default::default()),
                    b.expr(Prec::Unary),
                ),
                Prec::Product,
            ),
        }
    }

    fn div(&self, other: &Val) -> Val {
        match (self, other) {
            (Val::Const(a), Val::Const(b)) => Val::Const(a / b),
            (a, b) => Val::Run(
                binary(
                    a.expr(Prec::Product),
                    syn::BinOp::Div(Default::default()),
                    b.expr(Prec::Unary),
                ),
                Prec::Product,
            ),
        }
    }

    #[cfg(test)]
    fn sub(&self, other: &Val) -> Val {
        self.clone().minus(other)
    }

    /// `self − other`, taking `self`: an accumulated sum is extended, not copied.
    fn minus(self, other: &Val) -> Val {
        match (self, other) {
            (Val::Const(a), Val::Const(b)) => Val::Const(a - *b),
            (a, b) if b.is_negation() => {
                let b = b.negated();
                Val::Run(
                    binary(
                        a.into_expr(Prec::Sum),
                        syn::BinOp::Add(Default::default()),
                        b.expr(Prec::Product),
                    ),
                    Prec::Sum,
                )
            }
            (a, b) => Val::Run(
                binary(
                    a.into_expr(Prec::Sum),
                    syn::BinOp::Sub(Default::default()),
                    b.expr(Prec::Product),
                ),
                Prec::Sum,
            ),
        }
    }

    /// The expression a `let` binds: [`Val::expr`] without enclosing parentheses. The negation
    /// of a negated product keeps the parentheses the product had as the operand of `-`, which
    /// a binding does not need (rustc's `unused_parens`).
    fn binding(&self) -> Expr {
        match self.expr(Prec::Sum) {
            Expr::Paren(p) => *p.expr,
            e => e,
        }
    }

    /// [`Val::expr`], taking `self`.
    fn into_expr(self, at_least: Prec) -> Expr {
        match self {
            Val::Run(e, p) if p >= at_least => e,
            Val::Run(e, _) => paren(e),
            c @ Val::Const(_) => c.expr(at_least),
        }
    }
}

/// The values of L and U by step coordinates, each row aligned with its pattern.
struct Factored<'o> {
    order: &'o Order,
    vals: Vec<Vec<Option<Val>>>,
}

impl Factored<'_> {
    fn slot(&self, k: usize, l: usize) -> usize {
        self.order.pattern[k].binary_search(&l).expect("in the pattern")
    }

    fn get(&self, k: usize, l: usize) -> Option<&Val> {
        self.order.pattern[k].binary_search(&l).ok().and_then(|p| self.vals[k][p].as_ref())
    }

    fn set(&mut self, k: usize, l: usize, v: Val) {
        let p = self.slot(k, l);
        self.vals[k][p] = Some(v);
    }
}

/// The statements of one part of a factor function and the extremes of its pivots.
#[derive(Default)]
struct Part {
    stmts: Vec<syn::Stmt>,
    /// The extremes of the constant pivots.
    known_pivots: Option<(f64, f64)>,
    /// Where the first pivot computed at run time is, and its name.
    first_run: Option<(usize, Expr)>,
    run_pivots: usize,
}

impl Part {
    /// The statements, ending with `Some(PivotInfo { … })`.
    fn finish(self) -> Vec<syn::Stmt> {
        let (mut stmts, extremes) = self.extremes();
        stmts.push(syn::Stmt::Expr(parse_quote!(Some(#extremes)), None));
        stmts
    }

    /// The statements, with `smallest` and `largest` bound when a pivot is computed at run
    /// time, and the `PivotInfo { … }` of the part's pivots.
    fn extremes(mut self) -> (Vec<syn::Stmt>, Expr) {
        if let Some((at, e)) = &self.first_run {
            let mutable = if self.run_pivots > 1 { quote::quote!(mut) } else { quote::quote!() };
            // Plain comparisons, as in `track_pivot`: the pivot passed its finiteness guard.
            let (lo, hi) = match self.known_pivots {
                Some((lo, hi)) => {
                    let (lo, hi) = (literal_signed(lo), literal_signed(hi));
                    (
                        quote::quote!(if #e.abs() < #lo { #e.abs() } else { #lo }),
                        quote::quote!(if #e.abs() > #hi { #e.abs() } else { #hi }),
                    )
                }
                None => (quote::quote!(#e.abs()), quote::quote!(#e.abs())),
            };
            self.stmts.insert(*at, parse_quote!(let #mutable largest = #hi;));
            self.stmts.insert(*at, parse_quote!(let #mutable smallest = #lo;));
        }
        let extremes: Expr = match (self.run_pivots, self.known_pivots) {
            (0, Some((lo, hi))) => {
                let (lo, hi) = (literal_signed(lo), literal_signed(hi));
                parse_quote!(runtime::lu::PivotInfo { smallest: #lo, largest: #hi })
            }
            _ => parse_quote!(runtime::lu::PivotInfo { smallest, largest }),
        };
        (self.stmts, extremes)
    }
}

/// Emits `factor_{which}` and `solve_{which}` for `order` (of at least one step) of the
/// Jacobian with structure `s`, where `constant[i][j]` is the value of entry (i, j) when it does
/// not depend on q or t. A factor or solve longer than [`CHUNK_OPS`] operations is split
/// at step boundaries into `#[inline(never)]` helpers `factor_{which}_{part}` and
/// `solve_{which}_{part}`, the values crossing a boundary read back from where they are stored.
///
/// # Panics
///
/// When a constant pivot is zero or a constant multiplier exceeds the run-time bound: an order
/// chosen by [`crate::pivot::choose`] at any configuration never has one.
#[must_use]
pub fn emit(
    order: &Order,
    s: &[Vec<bool>],
    constant: &[Vec<Option<f64>>],
    which: usize,
) -> Vec<syn::Item> {
    let mut jac = |r: usize, c: usize| entry("jac", r, c);
    let mut z = Factorizer::new(order, s, constant, which, &mut jac, parse_quote!(return None;));
    z.steps(true);
    let mut items = z.functions();
    items.extend(emit_solve(&z.f, which));
    items
}

/// The places a block's static order reads and writes ([`block`]), by row and column of
/// Φ_q (those of the order), and the statement that leaves its factorisation.
pub(super) struct BlockPlaces<'p> {
    /// Entry (r, c) of Φ_q where the factorisation reads it and stores its factors.
    pub(super) jac: &'p mut dyn FnMut(usize, usize) -> Expr,
    /// Entry (r, c) of the factors where the solve reads them.
    pub(super) lu: &'p mut dyn FnMut(usize, usize) -> Expr,
    /// The right-hand side of row r.
    pub(super) input: &'p mut dyn FnMut(usize) -> Expr,
    /// The statement that writes `value`, the solution's unknown c.
    pub(super) output: &'p mut dyn FnMut(usize, Expr) -> syn::Stmt,
    /// What a refused guard runs (`break 'label;`).
    pub(super) fail: syn::Stmt,
}

/// A static order of one diagonal block as statements to place in a function of
/// `emit::blocks`.
pub(super) struct BlockOrder {
    /// The factorisation into locals, its guards running [`BlockPlaces::fail`], `smallest`
    /// and `largest` bound when a pivot is computed at run time.
    pub(super) factor: Vec<syn::Stmt>,
    /// The stores of the factors into their places, which the guards leave untouched: after
    /// a refusal the block still holds Φ_q for the dense fallback.
    pub(super) stores: Vec<syn::Stmt>,
    /// The `runtime::lu::PivotInfo` of the pivots.
    pub(super) extremes: Expr,
    /// The solve: y = L⁻¹ P b, then x = Q U⁻¹ y, with the factors known when generated as
    /// literals.
    pub(super) solve: Vec<syn::Stmt>,
}

/// `order` of a diagonal block (rows and columns of Φ_q with structure `s` and constant
/// entries `constant`, of at least one step) at the places `places`: the same arithmetic as
/// [`emit`]'s, in one part, with its stores deferred until every guard passed.
///
/// # Panics
///
/// As [`emit`].
pub(super) fn block(
    order: &Order,
    s: &[Vec<bool>],
    constant: &[Vec<Option<f64>>],
    places: BlockPlaces<'_>,
) -> BlockOrder {
    let BlockPlaces { jac, lu, input, output, fail } = places;
    let mut z = Factorizer::new(order, s, constant, 0, jac, fail);
    z.deferred = Some(Vec::new());
    z.steps(false);
    let stores = z.deferred.take().unwrap_or_default();
    let (factor, extremes) = std::mem::take(&mut z.part).extremes();
    let solve = solve_steps(&z.f, false, lu, input, output).into_iter().flat_map(|(s, _)| s);
    BlockOrder { factor, stores, extremes, solve: solve.collect() }
}

/// The state of one order's factorisation while its statements are written: the values of L
/// and U so far, the parts (functions) written and the counts their docs report.
struct Factorizer<'a> {
    order: &'a Order,
    s: &'a [Vec<bool>],
    constant: &'a [Vec<Option<f64>>],
    which: usize,
    /// Entry (r, c) of Φ_q, read and stored.
    jac: &'a mut dyn FnMut(usize, usize) -> Expr,
    /// What a refused guard runs.
    fail: syn::Stmt,
    /// When set, the stores wait here instead of following their values.
    deferred: Option<Vec<syn::Stmt>>,
    f: Factored<'a>,
    /// Fill-in entries met.
    fill: usize,
    /// Values stored into `jac`.
    stored: usize,
    /// Entries of U stored scaled by their pivot's reciprocal ([`Factorizer::scale_rows_of_u`]).
    scaled: usize,
    parts: Vec<Vec<syn::Stmt>>,
    part: Part,
    part_ops: usize,
    total_ops: usize,
    /// The entries computed at run time so far, read back from `jac` after a boundary.
    run_entries: Vec<(usize, usize)>,
}

impl<'a> Factorizer<'a> {
    fn new(
        order: &'a Order,
        s: &'a [Vec<bool>],
        constant: &'a [Vec<Option<f64>>],
        which: usize,
        jac: &'a mut dyn FnMut(usize, usize) -> Expr,
        fail: syn::Stmt,
    ) -> Self {
        Factorizer {
            order,
            s,
            constant,
            which,
            jac,
            fail,
            deferred: None,
            f: Factored {
                order,
                vals: order.pattern.iter().map(|p| vec![None; p.len()]).collect(),
            },
            fill: 0,
            stored: 0,
            scaled: 0,
            parts: Vec::new(),
            part: Part::default(),
            part_ops: 0,
            total_ops: 0,
            run_entries: Vec::new(),
        }
    }

    /// Every step of the elimination, in parts when `split` (see [`emit`]).
    fn steps(&mut self, split: bool) {
        let n = self.order.rows.len();
        // The steps i > k whose row has an entry in column k.
        let mut below: Vec<Vec<usize>> = vec![Vec::new(); n];
        for (i, p) in self.order.pattern.iter().enumerate() {
            for &k in p.iter().filter(|&&k| k < i) {
                below[k].push(i);
            }
        }
        for (k, below_k) in below.iter().enumerate() {
            let first = self.part.stmts.len();
            self.row_of_u(k);
            let (p, d) = self.pivot(k);
            let mut checks = Vec::new();
            if matches!(p, Val::Run(..)) {
                let pn = ident(&format!("p{k}"));
                checks.push(parse_quote!(#pn.is_finite()));
            }
            self.column_of_l(k, below_k, &d, &mut checks);
            self.guard(checks);
            self.track_pivot(k, &p);
            if split {
                self.close_step(k, n, first);
            }
        }
        self.scale_rows_of_u();
    }

    /// Stores each row of U scaled by the reciprocal of its pivot, û_kl = d_k u_kl, over u_kl
    /// once every step is done (the elimination reads u_kl unscaled), so that the back
    /// substitution reads x_k = d_k y_k − Σ_l û_kl x_l: one operation less on the chain of
    /// dependent operations from x_(k+1) to x_k than (y_k − Σ_l u_kl x_l) d_k, in each of a
    /// time step's three solves (chord, velocity, acceleration). An entry whose û is known
    /// when generated is folded into the solve, and one whose pivot is 1 is already in place.
    fn scale_rows_of_u(&mut self) {
        for k in 0..self.order.rows.len() {
            let d = self.f.get(k, k).expect("the pivot").clone();
            if matches!(d, Val::Const(c) if c == 1.0) {
                continue;
            }
            for &l in self.order.pattern[k].iter().filter(|&&l| l > k) {
                let scaled = self.f.get(k, l).expect("in the pattern").mul(&d);
                if let Val::Run(..) = scaled {
                    self.total_ops += 1;
                    self.scaled += 1;
                    self.store(k, l, &scaled);
                    // Counted in `scaled`, apart from the elimination's stores.
                    self.stored -= 1;
                }
            }
        }
    }

    /// Entry (k, l) of the permuted Φ_q: a constant, a read of `jac`, or absent.
    fn original(&mut self, k: usize, l: usize) -> Option<Val> {
        let (r, c) = (self.order.rows[k], self.order.cols[l]);
        if !self.s[r][c] {
            return None;
        }
        Some(match self.constant[r][c] {
            Some(v) => Val::Const(v),
            None => Val::Run((self.jac)(r, c), Prec::Atom),
        })
    }

    /// a_kl − Σ_m l_km u_ml over the m < min(k, l) where both are non-zero, in ascending m (the
    /// order in which right-looking elimination applies the updates), and whether the value is
    /// that of Φ_q at the same place (`jac` holds it already).
    fn eliminated(&mut self, k: usize, l: usize) -> (Val, bool) {
        let mut acc = self.original(k, l);
        self.fill += usize::from(acc.is_none());
        let mut kept = true;
        for &m in self.order.pattern[k].iter().take_while(|&&m| m < k.min(l)) {
            let (Some(lkm), Some(uml)) = (self.f.get(k, m), self.f.get(m, l)) else { continue };
            let term = lkm.mul(uml);
            kept = false;
            acc = Some(match acc {
                // A fill-in entry starts at 0, and 0 − x = −x exactly.
                None => term.negated(),
                Some(a) => a.minus(&term),
            });
        }
        (acc.expect("an entry of the pattern is original or filled"), kept)
    }

    /// `v` bound to `name` when it is computed at run time.
    fn bind(&mut self, name: Ident, v: Val) -> Val {
        match v {
            Val::Const(_) => v,
            Val::Run(..) => {
                self.part.stmts.push(let_stmt(name.clone(), v.binding()));
                Val::Run(path(name), Prec::Atom)
            }
        }
    }

    /// Stores a run-time value into its place (k, l) of `jac` as soon as it is known, so that
    /// it need not stay in a register (or be spilled) until the end; no entry is read after
    /// its own place has been written.
    fn store(&mut self, k: usize, l: usize, v: &Val) {
        if let Val::Run(e, _) = v {
            let target = (self.jac)(self.order.rows[k], self.order.cols[l]);
            let stmt = assign(target, e.clone());
            match &mut self.deferred {
                Some(stores) => stores.push(stmt),
                None => self.part.stmts.push(stmt),
            }
            self.stored += 1;
        }
    }

    /// `v` bound and stored at (k, l) unless `kept` (an entry read unchanged is read where it
    /// is used and not stored); a run-time result is remembered for part boundaries.
    fn settle(&mut self, k: usize, l: usize, v: Val, kept: bool) -> Val {
        let v = if kept {
            v
        } else {
            let v = self.bind(local(k, l), v);
            self.store(k, l, &v);
            v
        };
        if matches!(v, Val::Run(..)) {
            self.run_entries.push((k, l));
        }
        v
    }

    /// Row k of U, right of the pivot: every entry read has been computed at an earlier step.
    fn row_of_u(&mut self, k: usize) {
        for &l in self.order.pattern[k].iter().filter(|&&l| l > k) {
            let (v, kept) = self.eliminated(k, l);
            let v = self.settle(k, l, v, kept);
            self.f.set(k, l, v);
        }
    }

    /// The pivot p of step k and the reciprocal d = 1/p the diagonal holds.
    fn pivot(&mut self, k: usize) -> (Val, Val) {
        let (p, _) = self.eliminated(k, k);
        let d = match &p {
            Val::Const(c) => {
                assert!(c.is_finite() && *c != 0.0, "constant pivot {c} in order {}", self.which);
                Val::Const(1.0 / c)
            }
            Val::Run(..) => {
                let pivot = self.bind(ident(&format!("p{k}")), p.clone());
                let d = self.bind(local(k, k), Val::Const(1.0).div(&pivot));
                self.store(k, k, &d);
                self.run_entries.push((k, k));
                d
            }
        };
        self.f.set(k, k, d.clone());
        (p, d)
    }

    /// Column k of L below the pivot (times the reciprocal `d`), with the multiplier guards
    /// of the run-time entries added to `checks`.
    fn column_of_l(&mut self, k: usize, below_k: &[usize], d: &Val, checks: &mut Vec<Expr>) {
        for &i in below_k {
            let (v, kept) = self.eliminated(i, k);
            let kept = kept && matches!(d, Val::Const(c) if *c == 1.0);
            let v = v.mul(d);
            let v = if kept {
                v
            } else {
                let v = self.bind(local(i, k), v);
                self.store(i, k, &v);
                v
            };
            match &v {
                Val::Const(c) => assert!(
                    c.abs() <= RUNTIME_MAX_MULTIPLIER,
                    "constant multiplier {c} in order {}",
                    self.which
                ),
                Val::Run(e, _) => {
                    checks.push(parse_quote!(#e.abs() <= runtime::lu::MAX_MULTIPLIER));
                    self.run_entries.push((i, k));
                }
            }
            self.f.set(i, k, v);
        }
    }

    /// `if !(checks…) { return None; }` when there is anything to check (a lone comparison
    /// `a <= b` as `if a > b || a.is_nan()`), with [`Factorizer::fail`] for `return None`.
    fn guard(&mut self, checks: Vec<Expr>) {
        let fail = &self.fail;
        if let Some(ok) =
            checks.into_iter().reduce(|a, b| binary(a, syn::BinOp::And(Default::default()), b))
        {
            let stmt = match ok {
                // A lone multiplier check: clippy refuses `!(a <= b)` on floats
                // (`neg_cmp_op_on_partial_ord`); with b finite, `a > b || a.is_nan()` is the
                // same test.
                Expr::Binary(b) if matches!(b.op, syn::BinOp::Le(_)) => {
                    let (a, b) = (&b.left, &b.right);
                    parse_quote! {
                        if #a > #b || #a.is_nan() {
                            #fail
                        }
                    }
                }
                ok => {
                    let ok = if matches!(ok, Expr::Binary(_)) { paren(ok) } else { ok };
                    parse_quote! {
                        if !#ok {
                            #fail
                        }
                    }
                }
            };
            self.part.stmts.push(stmt);
        }
    }

    /// Folds pivot p of step k into the part's extremes (known ones now, run-time ones in code).
    fn track_pivot(&mut self, k: usize, p: &Val) {
        let part = &mut self.part;
        match p {
            Val::Const(c) => {
                let c = c.abs();
                part.known_pivots =
                    Some(part.known_pivots.map_or((c, c), |(lo, hi)| (lo.min(c), hi.max(c))));
            }
            Val::Run(..) => {
                let pn = ident(&format!("p{k}"));
                part.run_pivots += 1;
                if part.first_run.is_none() {
                    part.first_run = Some((part.stmts.len(), parse_quote!(#pn)));
                } else {
                    // Plain comparisons rather than `f64::min`/`max`, which also test for NaN
                    // (three more instructions each on x86-64): the guard just before returned
                    // unless the pivot is finite, and `smallest` and `largest` are |pivot|s
                    // that passed it, so no operand is NaN and the two agree (no −0.0 either,
                    // after `abs`).
                    part.stmts.push(parse_quote! {
                        smallest = if #pn.abs() < smallest { #pn.abs() } else { smallest };
                    });
                    part.stmts.push(parse_quote! {
                        largest = if #pn.abs() > largest { #pn.abs() } else { largest };
                    });
                }
            }
        }
    }

    /// Counts step k's operations (from statement `first` of the part) and starts a new part
    /// when this one is long: the new part reads the values of this one where they are stored.
    fn close_step(&mut self, k: usize, n: usize, first: usize) {
        let ops = operations(&self.part.stmts[first..]);
        self.part_ops += ops;
        self.total_ops += ops;
        if self.part_ops > CHUNK_OPS && k + 1 < n {
            self.parts.push(std::mem::take(&mut self.part).finish());
            self.part_ops = 0;
            for &(a, b) in &self.run_entries {
                let p = self.f.slot(a, b);
                let place = (self.jac)(self.order.rows[a], self.order.cols[b]);
                self.f.vals[a][p] = Some(Val::Run(place, Prec::Atom));
            }
        }
    }

    /// `factor_{which}` (and its helpers when split), with its doc.
    fn functions(&mut self) -> Vec<syn::Item> {
        self.parts.push(std::mem::take(&mut self.part).finish());
        let which = self.which;
        let name = ident(&format!("factor_{which}"));
        let nnz = self.order.entries();
        let run_time =
            self.f.vals.iter().flatten().filter(|v| matches!(v, Some(Val::Run(..)))).count();
        let (fill, stored, scaled, total_ops) =
            (self.fill, self.stored, self.scaled, self.total_ops);
        let known = nnz - run_time;
        let rows = list(&self.order.rows);
        let cols = list(&self.order.cols);
        let mut doc = format!(
            " Factors Φ_q in place with static pivot order {which}: step k pivots on row `[{rows}][k]` and column `[{cols}][k]`.\n\n L and U have {nnz} entries ({fill} of them fill-in, {known} known when generated); {total_ops} operations. The others are in `jac`: {stored} stored there, with the reciprocals of the pivots on the diagonal, and {} left as Φ_q had them. Entries of U then stored times their row's reciprocal pivot, for [`solve_{which}`]: {scaled}.\n\n Returns the smallest and largest |pivot|, or `None` when a pivot is not finite or a multiplier exceeds [`runtime::lu::MAX_MULTIPLIER`] in magnitude; `jac` is then partly factored and must be evaluated again.",
            run_time - stored
        );
        let mut parts = std::mem::take(&mut self.parts);
        if parts.len() == 1 {
            let item: syn::ItemFn = parse_quote! {
                #[doc = #doc]
                #[must_use]
                fn #name(jac: &mut [[f64; N]; N]) -> Option<runtime::lu::PivotInfo> {}
            };
            return vec![item_fn(item, parts.pop().expect("one part"))];
        }
        doc.push_str(&format!(
            "\n\n Split into {} functions of at most about {} operations each.",
            parts.len(),
            CHUNK_OPS
        ));
        let mut items = Vec::new();
        let mut calls: Vec<syn::Stmt> = Vec::new();
        let names: Vec<Ident> = (0..parts.len()).map(|c| ident(&format!("p{c}"))).collect();
        for (c, stmts) in parts.into_iter().enumerate() {
            let helper = ident(&format!("factor_{which}_{c}"));
            let doc = format!(" Steps of part {c} of [`factor_{which}`].");
            let item: syn::ItemFn = parse_quote! {
                #[doc = #doc]
                #[inline(never)]
                fn #helper(jac: &mut [[f64; N]; N]) -> Option<runtime::lu::PivotInfo> {}
            };
            items.push(item_fn(item, stmts));
            let p = &names[c];
            calls.push(parse_quote!(let #p = #helper(jac)?;));
        }
        calls.push(syn::Stmt::Expr(extremes(&names), None));
        let item: syn::ItemFn = parse_quote! {
            #[doc = #doc]
            #[must_use]
            fn #name(jac: &mut [[f64; N]; N]) -> Option<runtime::lu::PivotInfo> {}
        };
        items.insert(0, item_fn(item, calls));
        items
    }
}

/// `Some(PivotInfo { smallest, largest })` over the parts' results `names`.
fn extremes(names: &[Ident]) -> Expr {
    let (first, rest) = names.split_first().expect("several parts");
    let smallest =
        rest.iter().fold(quote::quote!(#first.smallest), |a, p| quote::quote!(#a.min(#p.smallest)));
    let largest =
        rest.iter().fold(quote::quote!(#first.largest), |a, p| quote::quote!(#a.max(#p.largest)));
    parse_quote!(Some(runtime::lu::PivotInfo { smallest: #smallest, largest: #largest }))
}

/// `solve_{which}` for the factors `f`: y = L⁻¹ P b, then x = Q U⁻¹ y, with the factors known
/// when generated as literals; split into helpers sharing a scratch array when long.
fn emit_solve(f: &Factored<'_>, which: usize) -> Vec<syn::Item> {
    let name = ident(&format!("solve_{which}"));
    let mut lu = |r: usize, c: usize| entry("lu", r, c);
    let mut input = |r: usize| element("b", &[r]);
    let mut output = |c: usize, v: Expr| assign(element("b", &[c]), v);
    let split = solve_steps(f, true, &mut lu, &mut input, &mut output);
    let counts: Vec<usize> =
        split.iter().map(|(s, _)| s.iter().map(assigned_operations).sum()).collect();
    let ops: usize = counts.iter().sum();
    let doc = format!(
        " Solves Φ_q x = b in place with the factors [`factor_{which}`] left in `lu`.\n\n {ops} operations."
    );
    if ops <= CHUNK_OPS {
        let item: syn::ItemFn = parse_quote! {
            #[doc = #doc]
            fn #name(lu: &[[f64; N]; N], b: &mut [f64; N]) {}
        };
        let unsplit = solve_steps(f, false, &mut lu, &mut input, &mut output);
        let unsplit = unsplit.into_iter().flat_map(|(s, _)| s).collect();
        return vec![item_fn(item, unsplit)];
    }
    let mut parts: Vec<(Vec<syn::Stmt>, bool)> = vec![(Vec::new(), false)];
    let mut part_ops = 0;
    for ((step, uses_b), ops) in split.into_iter().zip(counts) {
        if part_ops + ops > CHUNK_OPS && !parts.last().expect("one").0.is_empty() {
            parts.push((Vec::new(), false));
            part_ops = 0;
        }
        part_ops += ops;
        let last = parts.last_mut().expect("one");
        last.0.extend(step);
        last.1 |= uses_b;
    }
    split_solve(&name, &doc, which, parts)
}

/// The statements of each step of the solve with the factors `f` (forward, backward, then
/// the writes) and whether they use `b`, with y_k and x_k in locals, or in `y[k]` when `split`:
/// the factors read at `lu(r, c)`, the right-hand side of row r at `input(r)`, unknown c
/// written by `output(c, value)`.
fn solve_steps(
    f: &Factored<'_>,
    split: bool,
    lu: &mut dyn FnMut(usize, usize) -> Expr,
    input: &mut dyn FnMut(usize) -> Expr,
    output: &mut dyn FnMut(usize, Expr) -> syn::Stmt,
) -> Vec<(Vec<syn::Stmt>, bool)> {
    let order = f.order;
    let n = order.rows.len();
    // The value `v` of entry (k, l): a constant, or read where the factorisation stored it.
    let mut stored = |k: usize, l: usize, v: &Val| -> Val {
        match v {
            Val::Const(c) => Val::Const(*c),
            Val::Run(..) => Val::Run(lu(order.rows[k], order.cols[l]), Prec::Atom),
        }
    };
    let entry = |k: usize, l: usize| f.get(k, l).expect("in the pattern");
    let named = |prefix: &str, k: usize| -> Val {
        if split {
            Val::Run(element("y", &[k]), Prec::Atom)
        } else {
            Val::Run(path(ident(&format!("{prefix}{k}"))), Prec::Atom)
        }
    };
    // In the split form, x_k = y_k (a unit diagonal without off-diagonal terms) leaves `y[k]`
    // as it is: no statement.
    let define = |prefix: &str, k: usize, e: Expr| -> Vec<syn::Stmt> {
        if split {
            use quote::ToTokens;
            let target = element("y", &[k]);
            if e.to_token_stream().to_string() == target.to_token_stream().to_string() {
                return Vec::new();
            }
            vec![assign(target, e)]
        } else {
            vec![let_stmt(ident(&format!("{prefix}{k}")), e)]
        }
    };
    let mut out = Vec::with_capacity(2 * n + 1);
    for k in 0..n {
        let mut v = Val::Run(input(order.rows[k]), Prec::Sum);
        for &l in order.pattern[k].iter().filter(|&&l| l < k) {
            v = v.minus(&stored(k, l, entry(k, l)).mul(&named("y", l)));
        }
        out.push((define("y", k, v.into_expr(Prec::Sum)), true));
    }
    // x_k = d_k y_k − Σ_l û_kl x_l with U's rows stored scaled (`Factorizer::scale_rows_of_u`),
    // the x_l subtracted in the order they were computed, so that x_(k+1), the last one
    // known, enters last.
    for k in (0..n).rev() {
        let d = entry(k, k);
        let mut v = named("y", k).mul(&stored(k, k, d));
        for &l in order.pattern[k].iter().filter(|&&l| l > k).rev() {
            // û_kl: folded when known, else where `scale_rows_of_u` stored it (u_kl itself,
            // in its place already, when d_k = 1).
            let scaled = stored(k, l, &entry(k, l).mul(d));
            v = v.minus(&scaled.mul(&named("x", l)));
        }
        out.push((define("x", k, v.into_expr(Prec::Sum)), false));
    }
    let writes = (0..n).map(|k| output(order.cols[k], named("x", k).expr(Prec::Atom))).collect();
    out.push((writes, true));
    out
}

/// `solve_{which}` (`name`, with `doc`) calling one helper per part of `parts` (statements,
/// and whether they use `b`), which share a scratch array `y`.
fn split_solve(
    name: &Ident,
    doc: &str,
    which: usize,
    parts: Vec<(Vec<syn::Stmt>, bool)>,
) -> Vec<syn::Item> {
    let mut items = Vec::new();
    let mut calls: Vec<syn::Stmt> = vec![parse_quote!(let mut y = [0.0; N];)];
    let count = parts.len();
    for (c, (stmts, uses_b)) in parts.into_iter().enumerate() {
        let helper = ident(&format!("solve_{which}_{c}"));
        let doc = format!(" Part {c} of [`solve_{which}`], with y_k and then x_k in `y[k]`.");
        let b = if uses_b { ident("b") } else { ident("_b") };
        // A part whose factors are all constants does not read `lu`.
        let uses_lu = stmts.iter().any(|s| {
            use quote::ToTokens;
            s.to_token_stream()
                .into_iter()
                .any(|t| matches!(&t, proc_macro2::TokenTree::Ident(i) if i == "lu"))
        });
        let lu = if uses_lu { ident("lu") } else { ident("_lu") };
        let item: syn::ItemFn = parse_quote! {
            #[doc = #doc]
            #[inline(never)]
            fn #helper(#lu: &[[f64; N]; N], #b: &mut [f64; N], y: &mut [f64; N]) {}
        };
        items.push(item_fn(item, stmts));
        calls.push(parse_quote!(#helper(lu, b, &mut y);));
    }
    let doc = format!(
        "{doc}\n\n Split into {count} functions of at most about {} operations each.",
        CHUNK_OPS
    );
    let item: syn::ItemFn = parse_quote! {
        #[doc = #doc]
        fn #name(lu: &[[f64; N]; N], b: &mut [f64; N]) {}
    };
    items.insert(0, item_fn(item, calls));
    items
}

/// The arithmetic operations of an assignment `target = value;`.
fn assigned_operations(s: &syn::Stmt) -> usize {
    match s {
        syn::Stmt::Expr(Expr::Assign(a), _) => {
            let l = let_stmt(ident("v"), (*a.right).clone());
            operations(std::slice::from_ref(&l))
        }
        // A compound assignment `t op= e`: its operation and those of e.
        syn::Stmt::Expr(e @ Expr::Binary(_), _) => {
            operations(std::slice::from_ref(&let_stmt(ident("v"), e.clone())))
        }
        _ => operations(std::slice::from_ref(s)),
    }
}

/// The arithmetic operations (+, −, ×, ÷ and negation) in the `let` statements of `stmts`.
fn operations(stmts: &[syn::Stmt]) -> usize {
    fn count(e: &Expr) -> usize {
        match e {
            Expr::Binary(b) => {
                let arithmetic = matches!(
                    b.op,
                    syn::BinOp::Add(_)
                        | syn::BinOp::Sub(_)
                        | syn::BinOp::Mul(_)
                        | syn::BinOp::Div(_)
                        | syn::BinOp::AddAssign(_)
                        | syn::BinOp::SubAssign(_)
                        | syn::BinOp::MulAssign(_)
                        | syn::BinOp::DivAssign(_)
                );
                usize::from(arithmetic) + count(&b.left) + count(&b.right)
            }
            Expr::Unary(u) => usize::from(matches!(u.op, syn::UnOp::Neg(_))) + count(&u.expr),
            Expr::Paren(p) => count(&p.expr),
            _ => 0,
        }
    }
    stmts
        .iter()
        .filter_map(|s| match s {
            syn::Stmt::Local(l) => l.init.as_ref().map(|i| count(&i.expr)),
            _ => None,
        })
        .sum()
}

fn list(v: &[usize]) -> String {
    v.iter().map(ToString::to_string).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests;
