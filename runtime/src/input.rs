//! Run-time inputs: a driver whose value s(t) is supplied by the caller as samples
//! (t_k, s_k, ṡ_k, s̈_k) instead of a law of time.
//!
//! Between two samples, s(t) is the quintic Hermite interpolant that matches s, ṡ and s̈ at
//! both ends, so the values at every sample time are the caller's exactly, s is twice
//! continuously differentiable across samples, and a step control that sub-steps in t between
//! two samples sees a smooth driver (the command line's replay of a recorded series and, later,
//! generated solvers use this same code).

use crate::Real;

/// (s, ṡ, s̈) at `t` of the quintic Hermite interpolant between the samples `(t0, a)` and
/// `(t1, b)`, each `[s, ṡ, s̈]`, with t0 < t1. At t0 and t1 it returns `a` and `b` exactly;
/// outside [t0, t1] it extrapolates the same polynomial.
#[must_use]
pub fn hermite<R: Real>(t0: R, a: [R; 3], t1: R, b: [R; 3], t: R) -> [R; 3] {
    if t == t0 {
        return a;
    }
    if t == t1 {
        return b;
    }
    let h = t1 - t0;
    let two = R::from_f64(2.0);
    let half = R::from_f64(0.5);
    // s(u) = c0 + c1 u + … + c5 u⁵ with u = (t − t0)/h; c0, c1, c2 match the start, c3, c4, c5
    // the end (S, V, A: what the end still needs of s, h ṡ and h² s̈).
    let (c0, c1, c2) = (a[0], h * a[1], h * h * a[2] * half);
    let big_s = b[0] - c0 - c1 - c2;
    let big_v = h * b[1] - c1 - two * c2;
    let big_a = h * h * b[2] - two * c2;
    let c3 = R::from_f64(10.0) * big_s - R::from_f64(4.0) * big_v + half * big_a;
    let c4 = R::from_f64(-15.0) * big_s + R::from_f64(7.0) * big_v - big_a;
    let c5 = R::from_f64(6.0) * big_s - R::from_f64(3.0) * big_v + half * big_a;
    let u = (t - t0) / h;
    let s = c0 + u * (c1 + u * (c2 + u * (c3 + u * (c4 + u * c5))));
    let du = c1
        + u * (two * c2
            + u * (R::from_f64(3.0) * c3
                + u * (R::from_f64(4.0) * c4 + u * R::from_f64(5.0) * c5)));
    let ddu = two * c2
        + u * (R::from_f64(6.0) * c3 + u * (R::from_f64(12.0) * c4 + u * R::from_f64(20.0) * c5));
    [s, du / h, ddu / (h * h)]
}

/// (s, ṡ, s̈) at `t` of a series of samples: `times` strictly increasing, `values[k]` the
/// `[s, ṡ, s̈]` at `times[k]`, both of the same non-zero length. Between samples it is
/// [`hermite`]; before the first sample and after the last it holds the end sample's
/// values (a caller steps only within the series). An empty series gives NaN, which every
/// solver reports as a non-finite value.
#[must_use]
pub fn sample<R: Real>(times: &[R], values: &[[R; 3]], t: R) -> [R; 3] {
    let n = times.len().min(values.len());
    if n == 0 || t.is_nan() {
        return [R::NAN; 3];
    }
    if t <= times[0] {
        return values[0];
    }
    if t >= times[n - 1] {
        return values[n - 1];
    }
    // The last sample at or before t: times[lo] ≤ t < times[hi].
    let (mut lo, mut hi) = (0, n - 1);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if times[mid] <= t {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    hermite(times[lo], values[lo], times[hi], values[hi], t)
}

/// One input driver's value s and its first and second time derivatives ṡ, s̈ at one instant,
/// as a generated module's `Inputs` holds them, one field per input driver.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Input<R = f64> {
    /// s.
    pub value: R,
    /// ṡ.
    pub rate: R,
    /// s̈.
    pub acceleration: R,
}

impl<R: Copy> Input<R> {
    /// `[s, ṡ, s̈]`.
    #[must_use]
    pub const fn to_array(self) -> [R; 3] {
        [self.value, self.rate, self.acceleration]
    }

    /// The input of `[s, ṡ, s̈]`.
    #[must_use]
    pub const fn from_array(a: [R; 3]) -> Self {
        Input { value: a[0], rate: a[1], acceleration: a[2] }
    }
}

/// The values of `K` inputs between two instants: `(t0, u0)`, where the solver last stood, and
/// `(t1, u1)`, where it is asked to go. [`Segment::at`] gives the inputs at any t between them
/// by the quintic [`hermite`] interpolant of each input, exactly `u0` at t0 and `u1` at t1, so a
/// step control that sub-steps between the two instants sees inputs that move smoothly, as
/// they did between the caller's two samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment<R, const K: usize> {
    t0: R,
    u0: [[R; 3]; K],
    t1: R,
    u1: [[R; 3]; K],
}

impl<R: Real, const K: usize> Segment<R, K> {
    /// A segment that stands at `(t, u)`: both ends equal.
    #[must_use]
    pub const fn new(t: R, u: [[R; 3]; K]) -> Self {
        Segment { t0: t, u0: u, t1: t, u1: u }
    }

    /// The inputs `[s, ṡ, s̈]` of every input driver at `t`: the end's when t is t1 (the usual
    /// call, one comparison), the start's when t is t0 or both ends are at one instant, and
    /// the Hermite interpolant between them otherwise.
    #[inline]
    #[must_use]
    pub fn at(&self, t: R) -> [[R; 3]; K] {
        if t == self.t1 || self.t0 == self.t1 {
            return self.u1;
        }
        if t == self.t0 {
            return self.u0;
        }
        let mut u = self.u1;
        for (k, x) in u.iter_mut().enumerate() {
            *x = hermite(self.t0, self.u0[k], self.t1, self.u1[k], t);
        }
        u
    }

    /// The start `(t0, u0)`.
    #[must_use]
    pub const fn start(&self) -> (R, &[[R; 3]; K]) {
        (self.t0, &self.u0)
    }

    /// The end `(t1, u1)`.
    #[must_use]
    pub const fn end(&self) -> (R, &[[R; 3]; K]) {
        (self.t1, &self.u1)
    }

    /// Sets both ends: inputs `u0` at `t0` and `u1` at `t1` (t0 < t1, or t0 = t1 with the same
    /// inputs).
    pub const fn set(&mut self, t0: R, u0: [[R; 3]; K], t1: R, u1: [[R; 3]; K]) {
        *self = Segment { t0, u0, t1, u1 };
    }

    /// Moves the end to `(t, u)`, keeping the start.
    pub const fn aim(&mut self, t: R, u: [[R; 3]; K]) {
        self.t1 = t;
        self.u1 = u;
    }

    /// Moves the start to `t` with the inputs the segment gives there (the point a solver
    /// reached), keeping the end.
    pub fn settle(&mut self, t: R) {
        let u = self.at(t);
        self.t0 = t;
        self.u0 = u;
    }
}

/// A mechanism whose `K` input drivers take their values from a [`Segment`] it holds: what a
/// generated module with input drivers implements, so that
/// [`Solver::advance_with`](crate::Solver::advance_with) can move its inputs.
pub trait Driven<const K: usize, R: Real = f64> {
    /// The inputs' segment.
    fn segment(&self) -> &Segment<R, K>;
    /// The inputs' segment, to move.
    fn segment_mut(&mut self) -> &mut Segment<R, K>;
}

/// The first entry of `u` that is not finite, as (input, derivative: 0 for s, 1 for ṡ, 2 for s̈).
#[must_use]
pub fn first_non_finite<R: Real, const K: usize>(u: &[[R; 3]; K]) -> Option<(usize, usize)> {
    u.iter().enumerate().find_map(|(k, x)| x.iter().position(|v| !v.is_finite()).map(|d| (k, d)))
}

#[cfg(test)]
mod tests {
    use super::{hermite, sample};

    /// A quintic with its two derivatives.
    fn quintic(t: f64) -> [f64; 3] {
        let c = [0.3, -1.2, 0.7, 2.1, -0.9, 0.4];
        let s = c.iter().rev().fold(0.0, |acc, x| acc * t + x);
        let d = (1..6).rev().fold(0.0, |acc, k| acc * t + k as f64 * c[k]);
        let dd = (2..6).rev().fold(0.0, |acc, k| acc * t + (k * (k - 1)) as f64 * c[k]);
        [s, d, dd]
    }

    #[test]
    fn reproduces_a_quintic_and_the_samples_exactly() {
        let (t0, t1) = (0.25, 1.75);
        let (a, b) = (quintic(t0), quintic(t1));
        assert_eq!(hermite(t0, a, t1, b, t0), a);
        assert_eq!(hermite(t0, a, t1, b, t1), b);
        for k in 1..20 {
            let t = t0 + (t1 - t0) * f64::from(k) / 20.0;
            let (got, want) = (hermite(t0, a, t1, b, t), quintic(t));
            for i in 0..3 {
                // The interpolant is the quintic itself: only rounding of terms of size ~10 differs.
                assert!((got[i] - want[i]).abs() < 1e-12, "t {t} derivative {i}: {got:?} {want:?}");
            }
        }
    }

    #[test]
    fn a_series_is_exact_at_samples_and_clamped_outside() {
        let times = [0.0, 0.1, 0.3, 0.35];
        let values = times.map(quintic);
        for (t, v) in times.iter().zip(&values) {
            assert_eq!(sample(&times, &values, *t), *v);
        }
        assert_eq!(sample(&times, &values, -1.0), values[0]);
        assert_eq!(sample(&times, &values, 9.0), values[3]);
        let mid = sample(&times, &values, 0.2);
        // Within one interval the interpolant is the quintic (see above).
        assert!((mid[0] - quintic(0.2)[0]).abs() < 1e-12);
        assert!(sample::<f64>(&[], &[], 0.0)[0].is_nan());
        assert!(sample(&times, &values, f64::NAN)[0].is_nan());
    }
}
