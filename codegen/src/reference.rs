//! The reference solution: the description solved in double-double arithmetic (about 32
//! significant digits), independent of both engines' double-precision arithmetic.
//!
//! It solves the reduced system of [`crate::symbolic`], the expressions the generated engine
//! prints, evaluated over [`Dd`] by [`ExprPool::eval_in`]: Newton–Raphson on Φ(q, t) = 0 with a
//! dense LU with partial pivoting of Φ_q over all its rows (a tall Φ_q is allowed: the pivoting
//! picks the rows), started from a double-precision solution (any engine's, on the branch to
//! follow) and iterated until the correction no longer shrinks; then Φ_q q̇ = ν and
//! Φ_q q̈ = γ(q, q̇) with the same factors. Quadratic convergence takes an error of 1e-8 to the
//! arithmetic's ε ≈ 5e-32 in three iterations, so the result does not depend on the start:
//! its error is the round-off of evaluating Φ in double-double, κ·1e-31, far below the
//! 1e-16 that double precision can reach.
//!
//! What it solves is the description with its numbers as the doubles the file gives and the
//! constants the expression pool folds (products of lengths, sin and cos of constant angles)
//! rounded once to double: the problem every engine is handed, to within one rounding of
//! each folded constant.

use twofloat::TwoFloat;

use crate::expr::{ExprId, ExprPool, Scalar};
use crate::generic::{Analysis, Equations, Frame};
use crate::model::BodyId;
use crate::symbolic::{Source, Symbolic};

/// A double-double number: [`TwoFloat`] with sin and cos accurate to the type's precision.
#[derive(Clone, Copy, Debug, Default, PartialEq, PartialOrd)]
pub struct Dd(pub TwoFloat);

impl From<f64> for Dd {
    fn from(x: f64) -> Self {
        Dd(TwoFloat::from(x))
    }
}

impl std::ops::Neg for Dd {
    type Output = Dd;
    fn neg(self) -> Dd {
        Dd(-self.0)
    }
}

impl std::ops::Add for Dd {
    type Output = Dd;
    fn add(self, b: Dd) -> Dd {
        Dd(self.0 + b.0)
    }
}

impl std::ops::Sub for Dd {
    type Output = Dd;
    fn sub(self, b: Dd) -> Dd {
        Dd(self.0 - b.0)
    }
}

impl std::ops::Mul for Dd {
    type Output = Dd;
    fn mul(self, b: Dd) -> Dd {
        Dd(self.0 * b.0)
    }
}

impl std::ops::Div for Dd {
    type Output = Dd;
    /// a / b by long division in three double digits, as the QD library's accurate
    /// division: twofloat's `TwoFloat / TwoFloat` computes 1 − b_hi·(1/b_hi) without a fused
    /// multiply-add, so its quotient is only about 1e-17 accurate.
    fn div(self, b: Dd) -> Dd {
        let q1 = self.0.hi() / b.0.hi();
        let r = self.0 - b.0 * q1;
        let q2 = r.hi() / b.0.hi();
        let r = r - b.0 * q2;
        let q3 = r.hi() / b.0.hi();
        Dd(TwoFloat::new_add(q1, q2) + q3)
    }
}

impl Dd {
    /// The nearest double.
    #[must_use]
    pub fn to_f64(self) -> f64 {
        self.0.hi() + self.0.lo()
    }

    /// |x|.
    #[must_use]
    pub fn abs(self) -> Dd {
        Dd(self.0.abs())
    }

    /// x − y for a double y, rounded once to double: the difference between this value and a
    /// double close to it without the rounding of either (hi − y is exact when y is within a
    /// factor of two of hi, by Sterbenz's lemma).
    #[must_use]
    pub fn minus(self, y: f64) -> f64 {
        (self.0.hi() - y) + self.0.lo()
    }

    /// sin x and cos x: x is reduced by the nearest multiple k of π/2 (π/2 in double-double,
    /// so the reduction loses nothing for |k| up to about 1e6), then the Taylor series on
    /// |r| ≤ π/4 are summed until a term falls below 1e-36 of the sum (at most 16 terms each).
    #[must_use]
    pub fn sin_cos(self) -> (Dd, Dd) {
        let half_pi = twofloat::consts::FRAC_PI_2;
        let k = (self.0.hi() / half_pi.hi()).round();
        let r = self.0 - half_pi * k;
        let r2 = r * r;
        let series = |mut term: TwoFloat, first: f64| {
            let mut sum = term;
            let mut n = first;
            while term.hi().abs() > 1e-36 * sum.hi().abs().max(1e-300) {
                term = -(term * r2) / ((n + 1.0) * (n + 2.0));
                sum += term;
                n += 2.0;
            }
            sum
        };
        let (s, c) = (series(r, 1.0), series(TwoFloat::from(1.0), 0.0));
        // `rem_euclid` of a whole number below 2⁵³ is exact.
        match k.rem_euclid(4.0) as u8 {
            0 => (Dd(s), Dd(c)),
            1 => (Dd(c), Dd(-s)),
            2 => (Dd(-s), Dd(-c)),
            _ => (Dd(-c), Dd(s)),
        }
    }
}

impl Scalar for Dd {
    fn sin(self) -> Self {
        self.sin_cos().0
    }
    fn cos(self) -> Self {
        self.sin_cos().1
    }
}

/// Why the reference could not be computed at a time point.
#[derive(Debug, thiserror::Error)]
pub enum ReferenceError {
    /// The description could not be reduced to the symbolic system.
    #[error("the reference cannot build the symbolic system: {0}")]
    Symbolic(String),
    /// The double-precision run the reference starts from stopped.
    #[error("the run the reference starts from stopped: {0}")]
    Start(String),
    /// Φ_q is singular in double-double at the time point.
    #[error("the reference's Φ_q is singular at t = {0}")]
    Singular(f64),
    /// Newton in double-double did not bring the residual near its precision.
    #[error("the reference's Newton did not converge at t = {t} (max |Φ| = {residual:e})")]
    NoConvergence {
        /// The time point.
        t: f64,
        /// max |Φ_i| in balanced units at the last iterate.
        residual: f64,
    },
}

/// The reference solution at one time point, in the generic engine's full layout.
#[derive(Clone, Debug)]
pub struct ReferenceFrame {
    /// The grid index.
    pub index: usize,
    /// Time.
    pub t: f64,
    /// q, q̇ and q̈ of every moving body (7 each).
    pub parts: [Vec<Dd>; 3],
    /// max |Φ_i| at the solution, each row in balanced units ([`Symbolic::row_factors`]).
    pub residual: f64,
    /// max |Φ_q,i q̇ − ν_i| and max |Φ_q,i q̈ − γ_i| at the solution, in balanced units.
    pub rate_residuals: [f64; 2],
}

/// The most Newton iterations in double-double: from a double-precision start three suffice.
const MAX_ITERATIONS: usize = 12;

/// A residual in balanced units (rows of order one) the solution must reach: 1e4 times the
/// double-double ε, room for the round-off of evaluating Φ (sums of products of coordinates
/// of order one) and far below double precision's 1.1e-16.
const RESIDUAL: f64 = 1e-27;

/// The reference solver of one mechanism.
pub struct Reference<'e> {
    sym: Symbolic,
    eq: &'e Equations<'e>,
    /// Every Φ_q entry's expression, row by row, and its (row, column).
    jac_roots: Vec<ExprId>,
    jac_places: Vec<(usize, usize)>,
}

impl<'e> Reference<'e> {
    /// The reference solver of `eq`'s mechanism.
    ///
    /// # Errors
    /// When the symbolic system cannot be built.
    pub fn new(eq: &'e Equations<'e>) -> Result<Self, ReferenceError> {
        let sym =
            // Every equation solved in double-double: no closed form substituted with
            // constants rounded to double precision.
            Symbolic::build_full(eq.mechanism())
                .map_err(|e| ReferenceError::Symbolic(e.message))?;
        let mut jac_roots = Vec::new();
        let mut jac_places = Vec::new();
        for (i, row) in sym.jac.iter().enumerate() {
            for &(j, e) in row {
                jac_roots.push(e);
                jac_places.push((i, j));
            }
        }
        Ok(Reference { sym, eq, jac_roots, jac_places })
    }

    /// The solution at grid index `index`, time `t`, from `start`: q of every moving body in
    /// the generic engine's full layout (any engine's solution there, in double precision).
    ///
    /// # Errors
    /// When Φ_q is singular or Newton does not reach [`RESIDUAL`].
    pub fn solve(
        &self,
        index: usize,
        t: f64,
        start: &nalgebra::DVector<f64>,
    ) -> Result<ReferenceFrame, ReferenceError> {
        let sym = &self.sym;
        let pool: &ExprPool = &sym.pool;
        let n = sym.unknowns.len();
        let time = Dd::from(t);
        let inputs: Vec<[Dd; 3]> = sym
            .inputs
            .iter()
            .map(|d| {
                let (s, sd, sdd) = self.eq.driver_value(d.driver, t);
                [s.into(), sd.into(), sdd.into()]
            })
            .collect();
        let mut q: Vec<Dd> = sym.reduce(self.eq, start).iter().map(|&x| Dd::from(x)).collect();
        let balanced = |v: &[Dd]| {
            v.iter().zip(&sym.row_factors).map(|(x, f)| x.to_f64().abs() * f).fold(0.0, f64::max)
        };
        let mut last_step = f64::INFINITY;
        let mut lu;
        let mut iterations = 0;
        loop {
            lu = self.factor(&q, time, &inputs).ok_or(ReferenceError::Singular(t))?;
            let phi = pool.eval_in(&sym.phi, [&q, &[], &[]], time, &inputs);
            let residual = balanced(&phi);
            let dq = lu.solve(&phi);
            let step = dq.iter().map(|x| x.to_f64().abs()).fold(0.0, f64::max);
            // Stop once the correction no longer shrinks (round-off reached) or is below the
            // precision of the coordinates.
            let scale = q.iter().map(|x| x.to_f64().abs()).fold(1.0, f64::max);
            if residual <= RESIDUAL && (step >= last_step || step <= 1e-31 * scale) {
                break;
            }
            iterations += 1;
            if iterations > MAX_ITERATIONS {
                return Err(ReferenceError::NoConvergence { t, residual });
            }
            for (x, d) in q.iter_mut().zip(&dq) {
                *x = *x - *d;
            }
            last_step = step;
        }
        let phi = pool.eval_in(&sym.phi, [&q, &[], &[]], time, &inputs);
        let residual = balanced(&phi);
        let nu = pool.eval_in(&sym.nu, [&q, &[], &[]], time, &inputs);
        let qd = lu.solve(&nu);
        let gamma = pool.eval_in(&sym.gamma, [&q, &qd, &[]], time, &inputs);
        let qdd = lu.solve(&gamma);
        let rate_residuals = [self.rate_residual(&q, &qd, &nu, time, &inputs), {
            self.rate_residual(&q, &qdd, &gamma, time, &inputs)
        }];
        debug_assert_eq!(q.len(), n);
        let parts = self.expand([&q, &qd, &qdd], time, &inputs);
        Ok(ReferenceFrame { index, t, parts, residual, rate_residuals })
    }

    /// max |Φ_q,i x − b_i| in balanced units.
    fn rate_residual(&self, q: &[Dd], x: &[Dd], b: &[Dd], t: Dd, inputs: &[[Dd; 3]]) -> f64 {
        let values = self.sym.pool.eval_in(&self.jac_roots, [q, &[], &[]], t, inputs);
        let mut r: Vec<Dd> = b.iter().map(|&v| -v).collect();
        for (&(i, j), &v) in self.jac_places.iter().zip(&values) {
            r[i] = r[i] + v * x[j];
        }
        r.iter().zip(&self.sym.row_factors).map(|(x, f)| x.to_f64().abs() * f).fold(0.0, f64::max)
    }

    /// The LU factors of Φ_q at `q`, `None` when a pivot is zero or not finite.
    fn factor(&self, q: &[Dd], t: Dd, inputs: &[[Dd; 3]]) -> Option<Lu> {
        let (m, n) = (self.sym.rows.len(), self.sym.unknowns.len());
        let values = self.sym.pool.eval_in(&self.jac_roots, [q, &[], &[]], t, inputs);
        let mut a = vec![vec![Dd::default(); n]; m];
        for (&(i, j), &v) in self.jac_places.iter().zip(&values) {
            a[i][j] = v;
        }
        Lu::new(a)
    }

    /// Full coordinates, rates and accelerations in the generic engine's layout from reduced
    /// ones (as [`Symbolic::expand`], in double-double).
    fn expand(&self, reduced: [&[Dd]; 3], t: Dd, inputs: &[[Dd; 3]]) -> [Vec<Dd>; 3] {
        let sym = &self.sym;
        let n = self.eq.unknowns();
        let mut out = [vec![Dd::default(); n], vec![Dd::default(); n], vec![Dd::default(); n]];
        let roots: Vec<ExprId> = sym.laws.iter().flatten().copied().collect();
        let laws = sym.pool.eval_in(&roots, [&[], &[], &[]], t, inputs);
        let roots: Vec<ExprId> = sym.derived.iter().flat_map(|d| d.value).collect();
        let derived = sym.pool.eval_in(&roots, reduced, t, inputs);
        for (b, c) in sym.coords.iter().enumerate() {
            let Some(o) = self.eq.offset(BodyId(b)) else { continue };
            for (i, s) in c.iter().enumerate() {
                let v = match *s {
                    Source::Unknown(k) => [reduced[0][k], reduced[1][k], reduced[2][k]],
                    Source::Fixed(v) => [v.into(), Dd::default(), Dd::default()],
                    Source::Driven(l) => [laws[3 * l], laws[3 * l + 1], laws[3 * l + 2]],
                    Source::Derived(k) => [derived[3 * k], derived[3 * k + 1], derived[3 * k + 2]],
                };
                for (d, x) in out.iter_mut().zip(v) {
                    d[o + i] = x;
                }
            }
        }
        out
    }
}

/// The LU factors, with partial pivoting over all rows, of an m × n matrix with m ≥ n.
struct Lu {
    /// L below the diagonal (unit diagonal), U on and above it, rows in pivot order.
    a: Vec<Vec<Dd>>,
    /// Row k of the factors is row `perm[k]` of the matrix.
    perm: Vec<usize>,
}

impl Lu {
    /// Factors `a`; `None` when a pivot is zero or not finite (Φ_q singular).
    fn new(mut a: Vec<Vec<Dd>>) -> Option<Lu> {
        let m = a.len();
        let n = a.first().map_or(0, Vec::len);
        let mut perm: Vec<usize> = (0..m).collect();
        for k in 0..n {
            let p =
                (k..m).max_by(|&i, &j| a[i][k].abs().0.hi().total_cmp(&a[j][k].abs().0.hi()))?;
            a.swap(k, p);
            perm.swap(k, p);
            let pivot = a[k][k];
            if pivot.0.hi() == 0.0 || !pivot.0.hi().is_finite() {
                return None;
            }
            let (top, below) = a.split_at_mut(k + 1);
            let row_k = &top[k];
            for row in below {
                let l = row[k] / pivot;
                row[k] = l;
                for (x, &u) in row[k + 1..].iter_mut().zip(&row_k[k + 1..]) {
                    *x = *x - l * u;
                }
            }
        }
        Some(Lu { a, perm })
    }

    /// The solution x of A x = b on the rows the pivoting chose (all of them when square).
    fn solve(&self, b: &[Dd]) -> Vec<Dd> {
        let n = self.a.first().map_or(0, Vec::len);
        let mut y: Vec<Dd> = self.perm[..n].iter().map(|&i| b[i]).collect();
        for i in 0..n {
            for j in 0..i {
                y[i] = y[i] - self.a[i][j] * y[j];
            }
        }
        for i in (0..n).rev() {
            for j in i + 1..n {
                y[i] = y[i] - self.a[i][j] * y[j];
            }
            y[i] = y[i] / self.a[i][i];
        }
        y
    }
}

/// The most time points [`frames`] is asked for by `chart` and `compare --reference`: every
/// shipped example and benchmark has fewer.
pub const SAMPLES: usize = 4096;

/// q, q̇ and q̈ of a frame.
const PARTS: [fn(&Frame) -> &nalgebra::DVector<f64>; 3] = [|f| &f.q, |f| &f.qd, |f| &f.qdd];

/// A run's difference from the reference, accumulated frame by frame (see the module docs).
pub struct Error<'r> {
    /// The reference's frames at the compared time points, by grid index.
    reference: &'r [ReferenceFrame],
    /// The largest difference so far in q, q̇ and q̈.
    diff: [f64; 3],
    /// Frames seen.
    frames: usize,
}

impl<'r> Error<'r> {
    /// No difference yet, against `reference`.
    #[must_use]
    pub fn new(reference: &'r [ReferenceFrame]) -> Self {
        Error { reference, diff: [0.0; 3], frames: 0 }
    }

    /// Takes in one frame of the run.
    pub fn add(&mut self, f: &Frame) {
        self.frames += 1;
        if let Ok(k) = self.reference.binary_search_by_key(&f.index, |r| r.index) {
            for ((d, get), want) in self.diff.iter_mut().zip(PARTS).zip(&self.reference[k].parts) {
                for (x, w) in get(f).iter().zip(want) {
                    *d = d.max(w.minus(*x).abs());
                }
            }
        }
    }

    /// The largest difference relative to each quantity's scale, for q, q̇ and q̈.
    #[must_use]
    pub fn levels(&self) -> [f64; 3] {
        let mut out = [0.0; 3];
        for (k, o) in out.iter_mut().enumerate() {
            let scale = self
                .reference
                .iter()
                .flat_map(|f| f.parts[k].iter().map(|x| x.to_f64().abs()))
                .fold(f64::MIN_POSITIVE, f64::max);
            *o = self.diff[k] / scale;
        }
        out
    }

    /// The largest relative difference, `None` unless the run gave every time point.
    #[must_use]
    pub fn finish(&self, count: usize) -> Option<f64> {
        (self.frames == count).then(|| self.levels().into_iter().fold(0.0, f64::max))
    }
}

/// The reference at `samples` time points of the grid of `analysis` (every point of a shorter
/// grid, else evenly spaced ones with the first and last: `TimeGrid::sampled`), each started
/// from the frame of `analysis` there.
///
/// # Errors
/// When the run stops or the reference fails at a time point.
pub fn frames(
    eq: &Equations<'_>,
    analysis: &Analysis<'_, '_>,
    samples: usize,
) -> Result<Vec<ReferenceFrame>, ReferenceError> {
    let reference = Reference::new(eq)?;
    let grid = &eq.mechanism().time;
    let mut frames = Vec::new();
    let mut count = 0;
    let r = analysis.run(|f| {
        count += 1;
        if grid.sampled(f.index, samples) {
            frames.push(reference.solve(f.index, f.t, &f.q)?);
        }
        Ok::<(), ReferenceError>(())
    })?;
    if let Some(f) = r.failure {
        return Err(ReferenceError::Start(crate::report::failure_text(&f)));
    }
    if count != grid.count {
        return Err(ReferenceError::Start("the run ended early".to_owned()));
    }
    Ok(frames)
}

#[cfg(test)]
mod tests;
