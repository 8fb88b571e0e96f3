//! Helpers for the named outputs of generated modules: a joint angle and its rates from the
//! two dot products the generated code computes, the unwrapping of a principal angle into a
//! continuous one, the lookup of a name in a generated table, and a one-value status of a
//! solver call.

use crate::{NewtonError, NewtonReport, Real};

/// θ, θ̇, θ̈ of θ = atan2(y, x) from `x = [x, ẋ, ẍ]` and `y = [y, ẏ, ÿ]`: θ in (−π, π],
/// θ̇ = (x ẏ − y ẋ)/ρ and θ̈ = ((x ÿ − y ẍ) ρ − (x ẏ − y ẋ) ρ̇)/ρ² with ρ = x² + y² (so the
/// lengths of the reference vectors need not be 1). Straight-line; a zero ρ gives NaN, never a
/// panic.
#[inline]
#[must_use]
pub fn angle<R: Real>(x: [R; 3], y: [R; 3]) -> [R; 3] {
    let rho = x[0] * x[0] + y[0] * y[0];
    let cross = x[0] * y[1] - y[0] * x[1];
    let rho_dot = (x[0] * x[1] + y[0] * y[1]) * R::from_f64(2.0);
    let cross_dot = x[0] * y[2] - y[0] * x[2];
    [y[0].atan2(x[0]), cross / rho, (cross_dot * rho - cross * rho_dot) / (rho * rho)]
}

/// The angle congruent to `principal` (mod 2π) nearest to `previous`: call it with each new
/// principal value in (−π, π] and the last continuous value to follow an angle across turns
/// (valid while the angle moves by less than π between calls).
#[inline]
#[must_use]
pub fn unwrap_angle<R: Real>(previous: R, principal: R) -> R {
    let tau = R::from_f64(core::f64::consts::TAU);
    let half = R::from_f64(core::f64::consts::PI);
    let mut d = principal - previous;
    // At most a few turns per call in practice; the loops end for any finite input.
    if !d.is_finite() {
        return principal;
    }
    while d > half {
        d -= tau;
    }
    while d <= -half {
        d += tau;
    }
    previous + d
}

/// The position of `name` in `names`, usable in const context (the generated lookups
/// `body("crank")`, … call it and fail at compile time on a misspelt name).
#[must_use]
pub const fn find(names: &[&str], name: &str) -> Option<usize> {
    let mut k = 0;
    while k < names.len() {
        let (a, b) = (names[k].as_bytes(), name.as_bytes());
        if a.len() == b.len() {
            let mut i = 0;
            while i < a.len() && a[i] == b[i] {
                i += 1;
            }
            if i == a.len() {
                return Some(k);
            }
        }
        k += 1;
    }
    None
}

/// How one solver call ended, in one value for a control loop's log: the Newton iterations,
/// the final max |Φ_i| (NaN when it is unknown) and the outcome.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Status<R = f64> {
    /// Newton steps taken.
    pub iterations: u32,
    /// max |Φ_i| at the returned q (NaN when the call failed before evaluating it).
    pub residual: R,
    /// The outcome.
    pub outcome: Outcome,
}

/// The outcome of a solver call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    /// Converged within the tolerance.
    Converged,
    /// Φ_q was singular.
    Singular,
    /// Newton did not reach the tolerance.
    NotConverged,
    /// A NaN or an infinity was met (a non-finite t or input, or an overflowing step).
    NonFinite,
}

impl<R: Real> Status<R> {
    /// The status of a call to [`Solver::position`](crate::Solver::position).
    #[must_use]
    pub fn of(result: &Result<NewtonReport<R>, NewtonError<R>>) -> Self {
        match *result {
            Ok(r) => Status {
                iterations: r.iterations,
                residual: r.residual,
                outcome: Outcome::Converged,
            },
            Err(NewtonError::Singular { iteration, .. }) => {
                Status { iterations: iteration, residual: R::NAN, outcome: Outcome::Singular }
            }
            Err(NewtonError::NotConverged { iterations, residual }) => {
                Status { iterations, residual, outcome: Outcome::NotConverged }
            }
            Err(NewtonError::NonFinite { iteration }) => {
                Status { iterations: iteration, residual: R::NAN, outcome: Outcome::NonFinite }
            }
        }
    }

    /// Whether the call succeeded.
    #[must_use]
    pub fn is_ok(&self) -> bool {
        self.outcome == Outcome::Converged
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn angle_and_rates_match_a_rotating_scaled_vector() {
        // x = 2 cos ωt, y = 2 sin ωt (length 2): θ = ωt, θ̇ = ω, θ̈ = 0.
        let (w, t) = (1.3_f64, 2.0_f64);
        let (c, s) = (libm::cos(w * t), libm::sin(w * t));
        let x = [2.0 * c, -2.0 * w * s, -2.0 * w * w * c];
        let y = [2.0 * s, 2.0 * w * c, -2.0 * w * w * s];
        let [th, thd, thdd] = angle(x, y);
        // A few ulps of 2.6 rad, of the rate 1.3 and of ω² = 1.69 (the terms cancelling in θ̈).
        assert!((th - w * t).abs() < 1e-14, "{th}");
        assert!((thd - w).abs() < 1e-14, "{thd}");
        assert!(thdd.abs() < 1e-14, "{thdd}");
    }

    #[test]
    fn unwrap_follows_turns() {
        let mut cont = 0.0_f64;
        for k in 1..=100 {
            let exact = 0.3 * f64::from(k);
            let principal = libm::atan2(libm::sin(exact), libm::cos(exact));
            cont = unwrap_angle(cont, principal);
            // Rounding of the principal value and of the sum of 100 steps.
            assert!((cont - exact).abs() < 1e-12, "{k}: {cont} vs {exact}");
        }
    }

    #[test]
    fn find_is_exact() {
        const NAMES: [&str; 3] = ["crank", "crank2", "é"];
        assert_eq!(find(&NAMES, "crank2"), Some(1));
        assert_eq!(find(&NAMES, "é"), Some(2));
        assert_eq!(find(&NAMES, "cran"), None);
        const K: Option<usize> = find(&NAMES, "crank");
        assert_eq!(K, Some(0));
    }

    #[test]
    fn status_of_failure_keeps_its_iterations() {
        let s: Status =
            Status::of(&Err(NewtonError::NotConverged { iterations: 7, residual: 0.5 }));
        assert_eq!((s.iterations, s.outcome, s.is_ok()), (7, Outcome::NotConverged, false));
        let pivots = crate::lu::PivotInfo { smallest: 0.5, largest: 2.0 };
        let s: Status = Status::of(&Ok(NewtonReport { iterations: 2, residual: 1e-13, pivots }));
        assert!(s.is_ok());
    }
}
