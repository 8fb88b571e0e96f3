//! The structured LU of Φ_q: static pivot orders chosen at generation time, emitted as
//! straight-line `factor` and `solve` functions that touch only the entries of L and U.
//!
//! An order is a sequence of pivots (row, column) of Φ_q. It is chosen by Markowitz's rule
//! with threshold pivoting (as in Harwell's MA28 and MA48) on the numeric Jacobian at one
//! configuration: at every step of the elimination the pivot is, among the entries whose
//! magnitude is at least [`CHOICE_THRESHOLD`] of the largest in their column of the active
//! submatrix, one with the smallest (r − 1)(c − 1), r and c being the structurally non-zero
//! entries in its row and column, which bounds the fill-in the step creates. The fill-in
//! is tracked structurally, so the emitted code is valid for every value of q.
//!
//! A static order is only safe where its pivots stay large, and over a motion an entry that is
//! a fine pivot at one crank angle passes through zero at another. The generator therefore
//! walks the description's motion over its time grid (at most [`MAX_SAMPLES`] configurations
//! of it, evenly spaced, so that memory and planning time do not grow with the grid), and
//! whenever no order chosen so far passes the run-time guard with a margin there
//! ([`COVER_THRESHOLD`]), it chooses a new one at that configuration, up to [`MAX_ORDERS`].
//! At run time the guard decides (see `runtime::lu::MAX_MULTIPLIER`), and a factorisation
//! that no order passes falls back to dense LU with partial pivoting.

use syn::{Expr, Ident, parse_quote};

use super::{Prec, binary, ident, literal_signed, neg, paren};
use crate::model::Mechanism;
use crate::symbolic::Symbolic;

/// A candidate pivot qualifies when its magnitude is at least this fraction of the largest in
/// its column of the active submatrix at the configuration the order is chosen at.
///
/// The run-time guard accepts multipliers up to 10 (a fraction of 0.1); choosing with 0.5
/// leaves a factor of 5 for the entries to change along the motion before the guard refuses
/// the order, while still leaving Markowitz's rule several candidates to pick the sparsest.
pub const CHOICE_THRESHOLD: f64 = 0.5;

/// A configuration is covered by an order whose multipliers there are at most 1 / this
/// fraction (|l| ≤ 4): a margin of 2.5 below the run-time bound of 10, so that the Newton
/// iterates near a sampled configuration pass the guard too.
pub const COVER_THRESHOLD: f64 = 0.25;

/// At most this many orders are emitted. Each costs one factor and one solve function; a
/// configuration none of them covers is factored by the dense fallback.
pub const MAX_ORDERS: usize = 4;

/// The bound on |l| that the run-time guard applies (`runtime::lu::MAX_MULTIPLIER`), used here
/// to count the configurations the emitted orders leave to the fallback.
pub const RUNTIME_MAX_MULTIPLIER: f64 = 10.0;

/// A static pivot order for Φ_q and the structure of its L and U factors.
///
/// Step coordinates: step k pivots on row `rows[k]` and column `cols[k]` of Φ_q, so the
/// permuted matrix B = P Φ_q Q has `B[k][l] = Φ_q[rows[k]][cols[l]]`, and B = L U.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Order {
    /// The row of Φ_q pivoted at each step.
    pub rows: Vec<usize>,
    /// The column of Φ_q pivoted at each step.
    pub cols: Vec<usize>,
    /// For each step k, the steps l (ascending) where `B[k][l]` is a structural non-zero of L
    /// (l < k) or of U (l ≥ k).
    pub pattern: Vec<Vec<usize>>,
}

impl Order {
    /// The number of entries of L and U (the unit diagonal of L not counted).
    #[must_use]
    pub fn entries(&self) -> usize {
        self.pattern.iter().map(Vec::len).sum()
    }
}

/// The structure of Φ_q: `structure[i][j]` when entry (i, j) is not identically zero.
#[must_use]
pub fn structure(sys: &Symbolic) -> Vec<Vec<bool>> {
    let n = sys.unknowns.len();
    let mut s = vec![vec![false; n]; n];
    for (i, row) in sys.jac.iter().enumerate() {
        for &(j, _) in row {
            s[i][j] = true;
        }
    }
    s
}

/// The entries of Φ_q that depend on neither q nor t, with their values.
#[must_use]
pub fn constants(sys: &Symbolic) -> Vec<Vec<Option<f64>>> {
    let n = sys.unknowns.len();
    let mut c = vec![vec![None; n]; n];
    for (i, row) in sys.jac.iter().enumerate() {
        for &(j, e) in row {
            c[i][j] = sys.pool.as_const(e);
        }
    }
    c
}

/// Φ_q at (q, t) as a dense matrix.
#[must_use]
pub fn numeric(sys: &Symbolic, q: &[f64], t: f64) -> Vec<Vec<f64>> {
    let n = sys.unknowns.len();
    let roots: Vec<_> = sys.jac.iter().flatten().map(|&(_, e)| e).collect();
    let mut vals = sys.pool.eval(&roots, q, &[], t).into_iter();
    let mut m = vec![vec![0.0; n]; n];
    for (i, row) in sys.jac.iter().enumerate() {
        for &(j, _) in row {
            m[i][j] = vals.next().expect("one value per entry");
        }
    }
    m
}

/// The order Markowitz's rule with threshold pivoting picks for `a` (structure `s`), or `None`
/// when some step finds no non-zero candidate (`a` is singular).
///
/// The active submatrix is kept as row and column lists of its structural non-zeros, so a
/// step costs in proportion to them and not to n²: generation stays fast for hundreds of
/// unknowns. The values are those dense elimination would compute, in the same operations.
#[must_use]
pub fn choose(s: &[Vec<bool>], a: &[Vec<f64>]) -> Option<Order> {
    use std::collections::BTreeSet;
    let n = a.len();
    let mut s = s.to_vec();
    let mut v = a.to_vec();
    // The structural non-zeros of the active submatrix, by row and by column.
    let mut row_cols: Vec<BTreeSet<usize>> =
        (0..n).map(|i| (0..n).filter(|&j| s[i][j]).collect()).collect();
    let mut col_rows: Vec<BTreeSet<usize>> =
        (0..n).map(|j| (0..n).filter(|&i| s[i][j]).collect()).collect();
    let mut col_done = vec![false; n];
    let (mut rows, mut cols) = (Vec::with_capacity(n), Vec::with_capacity(n));
    for _ in 0..n {
        let mut best: Option<(usize, f64, usize, usize)> = None;
        for j in (0..n).filter(|&j| !col_done[j]) {
            let in_col = &col_rows[j];
            let big = in_col.iter().map(|&i| v[i][j].abs()).fold(0.0, f64::max);
            if big == 0.0 || !big.is_finite() {
                continue;
            }
            for &i in in_col {
                let m = v[i][j].abs();
                if m < CHOICE_THRESHOLD * big {
                    continue;
                }
                let cost = (row_cols[i].len() - 1) * (in_col.len() - 1);
                let ratio = m / big;
                // Fewest fill-in first, then the largest entry relative to its column (the most
                // margin along the motion), then the lowest column and row.
                let better = best.is_none_or(|(bc, br, bj, bi)| {
                    cost.cmp(&bc).then(br.total_cmp(&ratio)).then(j.cmp(&bj)).then(i.cmp(&bi))
                        == std::cmp::Ordering::Less
                });
                if better {
                    best = Some((cost, ratio, j, i));
                }
            }
        }
        let (_, _, pc, pr) = best?;
        let pivot_row: Vec<usize> = row_cols[pr].iter().copied().filter(|&j| j != pc).collect();
        let below: Vec<usize> = col_rows[pc].iter().copied().filter(|&i| i != pr).collect();
        for &i in &below {
            let l = v[i][pc] / v[pr][pc];
            for &j in &pivot_row {
                if !s[i][j] {
                    s[i][j] = true;
                    row_cols[i].insert(j);
                    col_rows[j].insert(i);
                }
                v[i][j] -= l * v[pr][j];
            }
            v[i][pc] = l;
        }
        for &j in &row_cols[pr] {
            col_rows[j].remove(&pr);
        }
        for &i in &col_rows[pc] {
            row_cols[i].remove(&pc);
        }
        col_done[pc] = true;
        rows.push(pr);
        cols.push(pc);
    }
    let mut step_of_col = vec![0; n];
    for (l, &c) in cols.iter().enumerate() {
        step_of_col[c] = l;
    }
    let pattern = rows
        .iter()
        .map(|&r| {
            let mut p: Vec<usize> = (0..n).filter(|&c| s[r][c]).map(|c| step_of_col[c]).collect();
            p.sort_unstable();
            p
        })
        .collect();
    Some(Order { rows, cols, pattern })
}

/// `a` factored with `order` in step coordinates (B = P a Q = L U, L below the diagonal with
/// a unit diagonal, U on and above it), each row of B aligned with its pattern, and the largest
/// |multiplier|; `None` when a pivot is zero or not finite.
fn factor_in_order(order: &Order, a: &[Vec<f64>]) -> Option<(Vec<Vec<f64>>, f64)> {
    let n = a.len();
    let pattern = &order.pattern;
    let mut b: Vec<Vec<f64>> = (0..n)
        .map(|k| pattern[k].iter().map(|&l| a[order.rows[k]][order.cols[l]]).collect())
        .collect();
    let at = |k: usize, l: usize| pattern[k].binary_search(&l).expect("in the pattern");
    // The steps i > k whose row has an entry in column k.
    let mut below: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, p) in pattern.iter().enumerate() {
        for &k in p.iter().filter(|&&k| k < i) {
            below[k].push(i);
        }
    }
    let mut worst = 0.0_f64;
    for k in 0..n {
        let dk = at(k, k);
        let p = b[k][dk];
        if p == 0.0 || !p.is_finite() {
            return None;
        }
        for &i in &below[k] {
            let ik = at(i, k);
            let l = b[i][ik] / p;
            worst = worst.max(l.abs());
            for (pos, &j) in pattern[k].iter().enumerate().skip(dk + 1) {
                let ij = at(i, j);
                b[i][ij] -= l * b[k][pos];
            }
            b[i][ik] = l;
        }
    }
    worst.is_finite().then_some((b, worst))
}

/// The largest |multiplier| when `a` is factored with `order`, or `None` when a pivot is zero
/// or not finite.
#[must_use]
pub fn largest_multiplier(order: &Order, a: &[Vec<f64>]) -> Option<f64> {
    factor_in_order(order, a).map(|(_, worst)| worst)
}

/// Solves a x = b with the factors of `a` by `order` (see [`factor_in_order`]).
fn solve_in_order(order: &Order, lu: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
    let n = b.len();
    let mut y = vec![0.0; n];
    for k in 0..n {
        let mut v = b[order.rows[k]];
        for (pos, &l) in order.pattern[k].iter().enumerate().take_while(|&(_, &l)| l < k) {
            v -= lu[k][pos] * y[l];
        }
        y[k] = v;
    }
    let mut x = vec![0.0; n];
    for k in (0..n).rev() {
        let mut v = y[k];
        let mut diagonal = 0.0;
        for (pos, &l) in order.pattern[k].iter().enumerate().filter(|&(_, &l)| l >= k) {
            if l == k {
                diagonal = lu[k][pos];
            } else {
                v -= lu[k][pos] * y[l];
            }
        }
        y[k] = v / diagonal;
        x[order.cols[k]] = y[k];
    }
    x
}

/// Solves a x = b (structure `s`) with the order [`choose`] picks, or `None` when `a` is
/// singular.
#[must_use]
pub fn solve(s: &[Vec<bool>], a: &[Vec<f64>], b: &[f64]) -> Option<Vec<f64>> {
    let order = choose(s, a)?;
    let (lu, _) = factor_in_order(&order, a)?;
    Some(solve_in_order(&order, &lu, b))
}

/// Φ_q of the reduced system factored at one configuration, by the last order that passes
/// the run-time guard there, or a new one chosen there.
struct Sampler<'s> {
    sys: &'s Symbolic,
    structure: Vec<Vec<bool>>,
    /// The orders chosen so far, the one last used first.
    orders: Vec<Order>,
}

/// The generation-time solves accept a known order whose multipliers stay below this bound
/// before choosing a new one (which costs far more): a growth of 1e4 costs at most four of the
/// sixteen digits of a Newton correction, and Newton's next iteration corrects them.
const SAMPLER_MAX_MULTIPLIER: f64 = 1e4;

impl Sampler<'_> {
    /// The factors of Φ_q(q, t), or `None` when it is singular.
    fn factor(&mut self, q: &[f64], t: f64) -> Option<Vec<Vec<f64>>> {
        let a = numeric(self.sys, q, t);
        for k in 0..self.orders.len() {
            if let Some((lu, worst)) = factor_in_order(&self.orders[k], &a)
                && worst <= SAMPLER_MAX_MULTIPLIER
            {
                let o = self.orders.remove(k);
                self.orders.insert(0, o);
                return Some(lu);
            }
        }
        let o = choose(&self.structure, &a)?;
        let (lu, _) = factor_in_order(&o, &a)?;
        self.orders.insert(0, o);
        Some(lu)
    }

    fn solve(&self, lu: &[Vec<f64>], b: &[f64]) -> Vec<f64> {
        solve_in_order(&self.orders[0], lu, b)
    }

    /// Newton–Raphson on the reduced system from `q` at `t`, then q̇ and q̈; `None` when it
    /// does not converge.
    fn step(
        &mut self,
        mut q: Vec<f64>,
        t: f64,
        tolerance: f64,
        max_iterations: u32,
    ) -> Option<[Vec<f64>; 3]> {
        let pool = &self.sys.pool;
        let mut normalised = false;
        let mut iterations = 0;
        loop {
            let phi = pool.eval(&self.sys.phi, &q, &[], t);
            let res = phi.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
            if !res.is_finite() {
                return None;
            }
            if res <= tolerance {
                if normalised {
                    break;
                }
                self.sys.normalise(&mut q);
                normalised = true;
                continue;
            }
            if iterations >= max_iterations {
                return None;
            }
            let lu = self.factor(&q, t)?;
            let dq = self.solve(&lu, &phi);
            for (x, d) in q.iter_mut().zip(&dq) {
                *x -= d;
            }
            normalised = false;
            iterations += 1;
        }
        let lu = self.factor(&q, t)?;
        let qd = self.solve(&lu, &pool.eval(&self.sys.nu, &q, &[], t));
        let qdd = self.solve(&lu, &pool.eval(&self.sys.gamma, &q, &qd, t));
        [&q, &qd, &qdd].iter().all(|v| v.iter().all(|x| x.is_finite())).then_some([q, qd, qdd])
    }
}

/// The most configurations of the motion that pivot planning looks at: evenly spaced grid
/// points, the first and the last always among them (see [`TimeGrid::sampled`]). Every shipped
/// example and benchmark has fewer points, so all of theirs are looked at; a grid of 10⁷ points
/// is planned from one point in about 2,400, which is still about a thousand samples per
/// revolution of a crank turning a few times, and keeps planning's memory and time independent
/// of the grid's length.
///
/// [`TimeGrid::sampled`]: crate::model::TimeGrid::sampled
pub const MAX_SAMPLES: usize = 4096;

/// Walks the description's motion, solved on the reduced system at every point of the time
/// grid (Newton–Raphson from a Taylor predictor, sparse LU with the static orders' own rules,
/// so that it stays on the assembly branch the grid's spacing resolves), and calls
/// `visit(t, q)` with the reduced q at the grid points [`MAX_SAMPLES`] selects, up to the first
/// point where Newton fails; then with the last configuration solved if it was not visited, or
/// with the initial estimates when Newton fails at once. Stops early when `visit` returns false.
///
/// Only the last configuration is kept, so memory does not grow with the grid.
pub fn motion(mech: &Mechanism, sys: &Symbolic, mut visit: impl FnMut(f64, &[f64]) -> bool) {
    let q0 = sys.initial_estimate(mech);
    let mut sampler = Sampler { sys, structure: structure(sys), orders: Vec::new() };
    // The last configuration solved, and whether it has been visited.
    let mut prev: Option<(f64, [Vec<f64>; 3], bool)> = None;
    let (tolerance, max_iterations) = (mech.solver.tolerance, mech.solver.max_iterations);
    for k in 0..mech.time.count {
        let t = mech.time.at(k);
        let guess = match &prev {
            // Taylor predictor q + h q̇ + h²/2 q̈ from the previous time point.
            Some((t0, [q, qd, qdd], _)) => {
                let h = t - t0;
                (0..q.len()).map(|i| q[i] + qd[i] * h + qdd[i] * (0.5 * h * h)).collect()
            }
            None => q0.clone(),
        };
        let Some(state) = sampler.step(guess, t, tolerance, max_iterations) else { break };
        let sampled = mech.time.sampled(k, MAX_SAMPLES);
        if sampled && !visit(t, &state[0]) {
            return;
        }
        prev = Some((t, state, sampled));
    }
    match prev {
        Some((t, [q, ..], false)) => {
            visit(t, &q);
        }
        Some(_) => {}
        None => {
            visit(mech.time.start, &q0);
        }
    }
}

/// Static orders chosen along a sequence of configurations: the first at the first one, each
/// further one at the first configuration the orders so far do not cover.
struct Planner<'s> {
    sys: &'s Symbolic,
    structure: Vec<Vec<bool>>,
    orders: Vec<Order>,
}

impl<'s> Planner<'s> {
    fn new(sys: &'s Symbolic) -> Self {
        Planner { sys, structure: structure(sys), orders: Vec::new() }
    }

    /// Looks at configuration (t, q); false once [`MAX_ORDERS`] orders are chosen.
    fn visit(&mut self, t: f64, q: &[f64]) -> bool {
        if self.orders.len() == MAX_ORDERS {
            return false;
        }
        let a = numeric(self.sys, q, t);
        let covered = self
            .orders
            .iter()
            .any(|o| largest_multiplier(o, &a).is_some_and(|m| m <= 1.0 / COVER_THRESHOLD));
        if !covered && let Some(o) = choose(&self.structure, &a) {
            self.orders.push(o);
        }
        self.orders.len() < MAX_ORDERS
    }
}

/// The static orders for the configurations `samples` (see [`Planner`]).
#[must_use]
pub fn plan(sys: &Symbolic, samples: &[(f64, Vec<f64>)]) -> Vec<Order> {
    let mut planner = Planner::new(sys);
    for (t, q) in samples {
        if !planner.visit(*t, q) {
            break;
        }
    }
    planner.orders
}

/// The static orders for the description's motion: [`plan`] over the configurations
/// [`motion`] visits, without keeping them.
#[must_use]
pub fn plan_motion(mech: &Mechanism, sys: &Symbolic) -> Vec<Order> {
    let mut planner = Planner::new(sys);
    motion(mech, sys, |t, q| planner.visit(t, q));
    planner.orders
}

/// `jac[r][c]` (or `lu[r][c]`).
fn entry(array: &str, r: usize, c: usize) -> Expr {
    super::element(array, &[r, c])
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
    fn finish(mut self) -> Vec<syn::Stmt> {
        if let Some((at, e)) = &self.first_run {
            let mutable = if self.run_pivots > 1 { quote::quote!(mut) } else { quote::quote!() };
            let (lo, hi) = match self.known_pivots {
                Some((lo, hi)) => {
                    let (lo, hi) = (literal_signed(lo), literal_signed(hi));
                    (quote::quote!(#e.abs().min(#lo)), quote::quote!(#e.abs().max(#hi)))
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
        self.stmts.push(syn::Stmt::Expr(parse_quote!(Some(#extremes)), None));
        self.stmts
    }
}

/// Emits `factor_{which}` and `solve_{which}` for `order` (of at least one step) of the
/// Jacobian with structure `s`, where `constant[i][j]` is the value of entry (i, j) when it does
/// not depend on q or t. A factor or solve longer than [`super::CHUNK_OPS`] operations is split
/// at step boundaries into `#[inline(never)]` helpers `factor_{which}_{part}` and
/// `solve_{which}_{part}`, the values crossing a boundary read back from where they are stored.
///
/// # Panics
///
/// When a constant pivot is zero or a constant multiplier exceeds the run-time bound: an order
/// chosen by [`choose`] at any configuration never has one.
#[must_use]
pub fn emit(
    order: &Order,
    s: &[Vec<bool>],
    constant: &[Vec<Option<f64>>],
    which: usize,
) -> Vec<syn::Item> {
    let n = order.rows.len();
    let original = |k: usize, l: usize| -> Option<Val> {
        let (r, c) = (order.rows[k], order.cols[l]);
        s[r][c].then(|| match constant[r][c] {
            Some(v) => Val::Const(v),
            None => Val::Run(entry("jac", r, c), Prec::Atom),
        })
    };
    // The steps i > k whose row has an entry in column k.
    let mut below: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (i, p) in order.pattern.iter().enumerate() {
        for &k in p.iter().filter(|&&k| k < i) {
            below[k].push(i);
        }
    }
    let mut f =
        Factored { order, vals: order.pattern.iter().map(|p| vec![None; p.len()]).collect() };
    let mut fill = 0usize;
    // a_kl − Σ_m l_km u_ml over the m < min(k, l) where both are non-zero, in ascending m (the
    // order in which right-looking elimination applies the updates), and whether the value is
    // that of Φ_q at the same place (`jac` holds it already).
    let mut eliminated = |f: &Factored<'_>, k: usize, l: usize| -> (Val, bool) {
        let mut acc = original(k, l);
        fill += usize::from(acc.is_none());
        let mut kept = true;
        for &m in order.pattern[k].iter().take_while(|&&m| m < k.min(l)) {
            let (Some(lkm), Some(uml)) = (f.get(k, m), f.get(m, l)) else { continue };
            let term = lkm.mul(uml);
            kept = false;
            acc = Some(match acc {
                // A fill-in entry starts at 0, and 0 − x = −x exactly.
                None => term.negated(),
                Some(a) => a.minus(&term),
            });
        }
        (acc.expect("an entry of the pattern is original or filled"), kept)
    };
    let bind = |stmts: &mut Vec<syn::Stmt>, name: Ident, v: Val| -> Val {
        match v {
            Val::Const(_) => v,
            Val::Run(..) => {
                let e = v.expr(Prec::Sum);
                stmts.push(super::let_stmt(name.clone(), e));
                Val::Run(super::path(name), Prec::Atom)
            }
        }
    };
    // Each value computed at run time is stored as soon as it is known, so that it need not
    // stay in a register (or be spilled) until the end; no entry is read after its own place
    // has been written.
    let mut stored = 0usize;
    let mut store = |stmts: &mut Vec<syn::Stmt>, k: usize, l: usize, v: &Val| {
        if let Val::Run(e, _) = v {
            let target = entry("jac", order.rows[k], order.cols[l]);
            stmts.push(super::assign(target, e.clone()));
            stored += 1;
        }
    };
    let mut parts: Vec<Vec<syn::Stmt>> = Vec::new();
    let mut part = Part::default();
    let mut part_ops = 0usize;
    let mut total_ops = 0usize;
    // The entries computed at run time so far, read back from `jac` after a boundary.
    let mut run_entries: Vec<(usize, usize)> = Vec::new();
    for (k, below_k) in below.iter().enumerate() {
        let first = part.stmts.len();
        // Row k of U (right of the pivot), then the pivot, then column k of L: every entry
        // read has been computed at an earlier step.
        for &l in order.pattern[k].iter().filter(|&&l| l > k) {
            let (v, kept) = eliminated(&f, k, l);
            // An entry read unchanged is read where it is used (and not stored).
            let v = if kept {
                v
            } else {
                let v = bind(&mut part.stmts, local(k, l), v);
                store(&mut part.stmts, k, l, &v);
                v
            };
            if matches!(v, Val::Run(..)) {
                run_entries.push((k, l));
            }
            f.set(k, l, v);
        }
        let (p, _) = eliminated(&f, k, k);
        let mut checks: Vec<Expr> = Vec::new();
        let d = match &p {
            Val::Const(c) => {
                assert!(c.is_finite() && *c != 0.0, "constant pivot {c} in order {which}");
                Val::Const(1.0 / c)
            }
            Val::Run(..) => {
                let pn = ident(&format!("p{k}"));
                let pivot = bind(&mut part.stmts, pn.clone(), p.clone());
                checks.push(parse_quote!(#pn.is_finite()));
                // The diagonal holds the reciprocal of the pivot.
                let d = bind(&mut part.stmts, local(k, k), Val::Const(1.0).div(&pivot));
                store(&mut part.stmts, k, k, &d);
                run_entries.push((k, k));
                d
            }
        };
        f.set(k, k, d.clone());
        for &i in below_k {
            let (v, kept) = eliminated(&f, i, k);
            let kept = kept && matches!(d, Val::Const(c) if c == 1.0);
            let v = v.mul(&d);
            let v = if kept {
                v
            } else {
                let v = bind(&mut part.stmts, local(i, k), v);
                store(&mut part.stmts, i, k, &v);
                v
            };
            match &v {
                Val::Const(c) => assert!(
                    c.abs() <= RUNTIME_MAX_MULTIPLIER,
                    "constant multiplier {c} in order {which}"
                ),
                Val::Run(e, _) => {
                    checks.push(parse_quote!(#e.abs() <= runtime::lu::MAX_MULTIPLIER));
                    run_entries.push((i, k));
                }
            }
            f.set(i, k, v);
        }
        if let Some(ok) =
            checks.into_iter().reduce(|a, b| binary(a, syn::BinOp::And(Default::default()), b))
        {
            let ok = if matches!(ok, Expr::Binary(_)) { paren(ok) } else { ok };
            part.stmts.push(parse_quote! {
                if !#ok {
                    return None;
                }
            });
        }
        match &p {
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
                    part.stmts.push(parse_quote!(smallest = smallest.min(#pn.abs());));
                    part.stmts.push(parse_quote!(largest = largest.max(#pn.abs());));
                }
            }
        }
        let ops = operations(&part.stmts[first..]);
        part_ops += ops;
        total_ops += ops;
        if part_ops > super::CHUNK_OPS && k + 1 < n {
            // A new part reads the values of this one where they are stored.
            parts.push(std::mem::take(&mut part).finish());
            part_ops = 0;
            for &(a, b) in &run_entries {
                let p = f.slot(a, b);
                f.vals[a][p] =
                    Some(Val::Run(entry("jac", order.rows[a], order.cols[b]), Prec::Atom));
            }
        }
    }
    parts.push(part.finish());
    let name = ident(&format!("factor_{which}"));
    let nnz = order.entries();
    let run_time = f.vals.iter().flatten().filter(|v| matches!(v, Some(Val::Run(..)))).count();
    let stored = stored;
    let known = nnz - run_time;
    let rows = list(&order.rows);
    let cols = list(&order.cols);
    let mut doc = format!(
        " Factors Φ_q in place with static pivot order {which}: step k pivots on row `[{rows}][k]` and column `[{cols}][k]`.\n\n L and U have {nnz} entries ({fill} of them fill-in, {known} known when generated); {total_ops} operations. The others are in `jac`: {stored} stored there, with the reciprocals of the pivots on the diagonal, and {} left as Φ_q had them.\n\n Returns the smallest and largest |pivot|, or `None` when a pivot is not finite or a multiplier exceeds [`runtime::lu::MAX_MULTIPLIER`] in magnitude; `jac` is then partly factored and must be evaluated again.",
        run_time - stored
    );
    let mut items = Vec::new();
    if parts.len() == 1 {
        let item: syn::ItemFn = parse_quote! {
            #[doc = #doc]
            #[must_use]
            pub fn #name(jac: &mut [[f64; N]; N]) -> Option<runtime::lu::PivotInfo> {}
        };
        items.push(super::item_fn(item, parts.pop().expect("one part")));
    } else {
        doc.push_str(&format!(
            "\n\n Split into {} functions of at most about {} operations each.",
            parts.len(),
            super::CHUNK_OPS
        ));
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
            items.push(super::item_fn(item, stmts));
            let p = &names[c];
            calls.push(parse_quote!(let #p = #helper(jac)?;));
        }
        let (first, rest) = names.split_first().expect("several parts");
        let smallest = rest
            .iter()
            .fold(quote::quote!(#first.smallest), |a, p| quote::quote!(#a.min(#p.smallest)));
        let largest = rest
            .iter()
            .fold(quote::quote!(#first.largest), |a, p| quote::quote!(#a.max(#p.largest)));
        calls.push(syn::Stmt::Expr(
            parse_quote!(Some(runtime::lu::PivotInfo { smallest: #smallest, largest: #largest })),
            None,
        ));
        let item: syn::ItemFn = parse_quote! {
            #[doc = #doc]
            #[must_use]
            pub fn #name(jac: &mut [[f64; N]; N]) -> Option<runtime::lu::PivotInfo> {}
        };
        items.insert(0, super::item_fn(item, calls));
    }
    items.extend(emit_solve(&f, which));
    items
}

/// `solve_{which}` for the factors `f`: y = L⁻¹ P b, then x = Q U⁻¹ y, with the factors known
/// when generated as literals; split into helpers sharing a scratch array when long.
fn emit_solve(f: &Factored<'_>, which: usize) -> Vec<syn::Item> {
    let order = f.order;
    let n = order.rows.len();
    let stored_val = |k: usize, l: usize| -> Val {
        match f.get(k, l).expect("in the pattern") {
            Val::Const(c) => Val::Const(*c),
            Val::Run(..) => Val::Run(entry("lu", order.rows[k], order.cols[l]), Prec::Atom),
        }
    };
    // The statements of each step (forward, backward, then the writes) and whether they use
    // `b`, with y_k and x_k in locals, or in `y[k]` when `split`.
    let steps = |split: bool| -> Vec<(Vec<syn::Stmt>, bool)> {
        let named = |prefix: &str, k: usize| -> Val {
            if split {
                Val::Run(super::element("y", &[k]), Prec::Atom)
            } else {
                Val::Run(super::path(ident(&format!("{prefix}{k}"))), Prec::Atom)
            }
        };
        // In the split form, x_k = y_k (a unit diagonal without off-diagonal terms) leaves
        // `y[k]` as it is: no statement.
        let define = |prefix: &str, k: usize, e: Expr| -> Vec<syn::Stmt> {
            if split {
                use quote::ToTokens;
                let target = super::element("y", &[k]);
                if e.to_token_stream().to_string() == target.to_token_stream().to_string() {
                    return Vec::new();
                }
                vec![super::assign(target, e)]
            } else {
                vec![super::let_stmt(ident(&format!("{prefix}{k}")), e)]
            }
        };
        let mut out = Vec::with_capacity(2 * n + 1);
        for k in 0..n {
            let mut v = Val::Run(super::element("b", &[order.rows[k]]), Prec::Atom);
            for &l in order.pattern[k].iter().filter(|&&l| l < k) {
                v = v.minus(&stored_val(k, l).mul(&named("y", l)));
            }
            out.push((define("y", k, v.into_expr(Prec::Sum)), true));
        }
        for k in (0..n).rev() {
            let mut v = named("y", k);
            for &l in order.pattern[k].iter().filter(|&&l| l > k) {
                v = v.minus(&stored_val(k, l).mul(&named("x", l)));
            }
            let v = v.mul(&stored_val(k, k));
            out.push((define("x", k, v.into_expr(Prec::Sum)), false));
        }
        out.push((
            (0..n)
                .map(|k| {
                    let x = named("x", k).expr(Prec::Atom);
                    super::assign(super::element("b", &[order.cols[k]]), x)
                })
                .collect(),
            true,
        ));
        out
    };
    let name = ident(&format!("solve_{which}"));
    let split = steps(true);
    let counts: Vec<usize> =
        split.iter().map(|(s, _)| s.iter().map(assigned_operations).sum()).collect();
    let ops: usize = counts.iter().sum();
    let doc = format!(
        " Solves Φ_q x = b in place with the factors [`factor_{which}`] left in `lu`.\n\n {ops} operations."
    );
    if ops <= super::CHUNK_OPS {
        let item: syn::ItemFn = parse_quote! {
            #[doc = #doc]
            pub fn #name(lu: &[[f64; N]; N], b: &mut [f64; N]) {}
        };
        let unsplit = steps(false).into_iter().flat_map(|(s, _)| s).collect();
        return vec![super::item_fn(item, unsplit)];
    }
    let mut parts: Vec<(Vec<syn::Stmt>, bool)> = vec![(Vec::new(), false)];
    let mut part_ops = 0;
    for ((step, uses_b), ops) in split.into_iter().zip(counts) {
        if part_ops + ops > super::CHUNK_OPS && !parts.last().expect("one").0.is_empty() {
            parts.push((Vec::new(), false));
            part_ops = 0;
        }
        part_ops += ops;
        let last = parts.last_mut().expect("one");
        last.0.extend(step);
        last.1 |= uses_b;
    }
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
        items.push(super::item_fn(item, stmts));
        calls.push(parse_quote!(#helper(lu, b, &mut y);));
    }
    let doc = format!(
        "{doc}\n\n Split into {count} functions of at most about {} operations each.",
        super::CHUNK_OPS
    );
    let item: syn::ItemFn = parse_quote! {
        #[doc = #doc]
        pub fn #name(lu: &[[f64; N]; N], b: &mut [f64; N]) {}
    };
    items.insert(0, super::item_fn(item, calls));
    items
}

/// The arithmetic operations of an assignment `target = value;`.
fn assigned_operations(s: &syn::Stmt) -> usize {
    match s {
        syn::Stmt::Expr(Expr::Assign(a), _) => {
            let l = super::let_stmt(ident("v"), (*a.right).clone());
            operations(std::slice::from_ref(&l))
        }
        // A compound assignment `t op= e`: its operation and those of e.
        syn::Stmt::Expr(e @ Expr::Binary(_), _) => {
            operations(std::slice::from_ref(&super::let_stmt(ident("v"), e.clone())))
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
