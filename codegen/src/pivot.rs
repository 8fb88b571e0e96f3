//! Pivot planning for the structured LU of Φ_q: static pivot orders chosen at generation time
//! along the description's motion. Numbers only; `emit::lu` prints the orders as code.
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
//! walks the description's motion over its time grid (at most [`MAX_WALK`] points of it, and
//! looks at [`MAX_SAMPLES`] configurations of those, evenly spaced, so that memory and planning
//! time do not grow with the grid), and
//! whenever no order chosen so far passes the run-time guard with a margin there
//! ([`COVER_THRESHOLD`]), it chooses a new one at that configuration, up to [`MAX_ORDERS`].
//! At run time the guard decides (see `runtime::lu::MAX_MULTIPLIER`), and a factorisation
//! that no order passes falls back to dense LU with partial pivoting.

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
    let mut vals =
        sys.pool.eval_inputs(&roots, [q, &[], &[]], t, &sys.planning_inputs(t)).into_iter();
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
        let u = self.sys.planning_inputs(t);
        let mut normalised = false;
        let mut iterations = 0;
        loop {
            let phi = pool.eval_inputs(&self.sys.phi, [&q, &[], &[]], t, &u);
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
        let qd = self.solve(&lu, &pool.eval_inputs(&self.sys.nu, [&q, &[], &[]], t, &u));
        let qdd = self.solve(&lu, &pool.eval_inputs(&self.sys.gamma, [&q, &qd, &[]], t, &u));
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

/// The most grid points the walk of [`motion`] solves: every point of a grid up to this size,
/// else this many evenly spaced ones. Four points walked per point looked at keeps the walk's
/// steps at a quarter of the samples' spacing (small enough for Newton from a Taylor predictor
/// to stay on its branch on any motion whose samples resolve it), while the walk's cost, a
/// Newton solve in the expression interpreter per point, no longer grows with the grid: it was
/// a quarter of a 100,000-point `solve` with the generated engine, paid on every run to find
/// the cache entry.
pub const MAX_WALK: usize = 4 * MAX_SAMPLES;

/// Walks the description's motion, solved on the reduced system at the grid points
/// [`MAX_WALK`] selects (Newton–Raphson from a Taylor predictor, sparse LU with the static
/// orders' own rules, so that it stays on the assembly branch the spacing resolves), and calls
/// `visit(t, q)` with the reduced q at [`MAX_SAMPLES`] of them evenly spaced (every point of a
/// grid of at most [`MAX_SAMPLES`]), up to the first point where Newton fails; then with the last configuration
/// solved if it was not visited, or with the initial estimates when Newton fails at once. Stops
/// early when `visit` returns false.
///
/// Only the last configuration is kept, so memory does not grow with the grid.
pub fn motion(mech: &Mechanism, sys: &Symbolic, mut visit: impl FnMut(f64, &[f64]) -> bool) {
    let q0 = sys.initial_estimate(mech);
    let mut sampler = Sampler { sys, structure: structure(sys), orders: Vec::new() };
    // The last configuration solved, and whether it has been visited.
    let mut prev: Option<(f64, [Vec<f64>; 3], bool)> = None;
    let (tolerance, max_iterations) = (mech.solver.tolerance, mech.solver.max_iterations);
    // The points walked, numbered 0, 1, …: MAX_SAMPLES of them evenly spaced are looked at.
    let walked_grid = crate::model::TimeGrid::uniform(0.0, 1.0, mech.time.count.min(MAX_WALK));
    let walk = (0..mech.time.count).filter(|&k| mech.time.sampled(k, MAX_WALK));
    for (walked, k) in walk.enumerate() {
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
        let sampled = walked_grid.sampled(walked, MAX_SAMPLES);
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

/// The structure and the constant entries of the diagonal block of Φ_q on `rows` and
/// `columns`, in block coordinates: entry (i, j) is Φ_q's (`rows[i]`, `columns[j]`).
#[must_use]
pub fn block_structure(
    sys: &Symbolic,
    rows: &[usize],
    columns: &[usize],
) -> (Vec<Vec<bool>>, Vec<Vec<Option<f64>>>) {
    let s = rows.len();
    let (mut structure, mut constant) = (vec![vec![false; s]; s], vec![vec![None; s]; s]);
    for (i, &r) in rows.iter().enumerate() {
        for &(c, e) in &sys.jac[r] {
            if let Some(j) = columns.iter().position(|&k| k == c) {
                structure[i][j] = true;
                constant[i][j] = sys.pool.as_const(e);
            }
        }
    }
    (structure, constant)
}

/// Static orders for the diagonal blocks of a block-lower-triangular Φ_q, in block
/// coordinates, one list per group of blocks (each block its rows and its columns, of one
/// structure within a group): every order of a group serves each of its blocks.
///
/// Along the description's motion ([`motion`], the earlier blocks' unknowns given by it as
/// well), a block none of whose group's orders covers it ([`COVER_THRESHOLD`]) gets a new
/// order chosen at its own values, up to [`MAX_ORDERS`] per group; a group whose blocks are
/// singular everywhere it was looked at gets none.
#[must_use]
pub fn plan_blocks(
    mech: &Mechanism,
    sys: &Symbolic,
    groups: &[Vec<(Vec<usize>, Vec<usize>)>],
) -> Vec<Vec<Order>> {
    // Per block: its group, its structure, and where its entries sit among the roots.
    let mut roots = Vec::new();
    let mut blocks = Vec::new();
    for (g, group) in groups.iter().enumerate() {
        for (rows, columns) in group {
            let (structure, _) = block_structure(sys, rows, columns);
            let mut places = Vec::new();
            for (i, &r) in rows.iter().enumerate() {
                for &(c, e) in &sys.jac[r] {
                    if let Some(j) = columns.iter().position(|&k| k == c) {
                        places.push((i, j));
                        roots.push(e);
                    }
                }
            }
            blocks.push((g, structure, places));
        }
    }
    let mut orders: Vec<Vec<Order>> = vec![Vec::new(); groups.len()];
    if blocks.is_empty() {
        return orders;
    }
    motion(mech, sys, |t, q| {
        let values = sys.pool.eval_inputs(&roots, [q, &[], &[]], t, &sys.planning_inputs(t));
        let mut values = values.into_iter();
        for (g, structure, places) in &blocks {
            let s = structure.len();
            let mut a = vec![vec![0.0; s]; s];
            for &(i, j) in places {
                a[i][j] = values.next().expect("one value per entry");
            }
            let list = &mut orders[*g];
            let covered = list
                .iter()
                .any(|o| largest_multiplier(o, &a).is_some_and(|m| m <= 1.0 / COVER_THRESHOLD));
            if !covered
                && list.len() < MAX_ORDERS
                && let Some(o) = choose(structure, &a)
            {
                list.push(o);
            }
        }
        orders.iter().any(|list| list.len() < MAX_ORDERS)
    });
    orders
}

#[cfg(test)]
mod tests;
