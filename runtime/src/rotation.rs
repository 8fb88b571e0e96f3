//! The Euler parameters of a body turned about a joint axis by a rotation driver, in closed
//! form: what a generated solver's [`Mechanism::closed_form_block`] runs for a block of one
//! body's four Euler parameters (see `codegen::blocks::Rotation`).
//!
//! A revolute (or cylindrical) joint between a known body i and body j holds j's axis parallel
//! to i's; with j's normalisation this leaves the one-parameter family
//!
//! e_j(φ) = c u + s′ w,  (c, s′) = (cos φ/2, sin φ/2),
//! u = e_i ⊗ f_i ⊗ f_j*,  w = e_i ⊗ f_i ⊗ (0, 0, 0, 1) ⊗ f_j*,
//!
//! f_i and f_j the constant quaternions of joint frames whose third axis is the joint axis, so
//! that u and w are orthonormal when e_i is a unit quaternion. On that family the driver's row
//! f(e_j) is
//!
//! - for a joint angle driver, x sin s − y cos s with x and y quadratic forms in e_j: the
//!   quadratic a c² + b c s′ + d s′² on the unit circle, a = f(u), d = f(w),
//!   b = 2 f((u + w)/√2) − a − d (a unit point: where the row involves j's axis too, as when j
//!   is the joint's body i, it is a quartic form equal to (c² + s′²) times that quadratic);
//! - for an absolute rx, ry or rz driver on j, e_k cos(s/2) − e0 sin(s/2), linear in e_j:
//!   A c + B s′, A = f(u), B = f(w).
//!
//! Its zeros on the unit circle are the directions (c, s′) ∝ ±(B, −A), or for the quadratic the
//! roots τ = c/s′ of a τ² + b τ + d = 0 without cancellation: with
//! k = −(b + sgn(b) √(b² − 4ad))/2, (c, s′) ∝ ±(k, a) and ±(d, k). Of these (four quaternions,
//! or two) the one with the largest |e · e_prev| against the prediction e_prev is kept, signed
//! so that e · e_prev ≥ 0: the continuation the generic engine's Newton follows, through the
//! sign flip of e over every full turn.
//!
//! [`Mechanism::closed_form_block`]: crate::Mechanism::closed_form_block

use crate::Real;

/// The number of coefficients [`about_axis`] reads: u, w, f(u), f(w), f((u + w)/√2).
pub const COEFFICIENTS: usize = 11;

/// The unit quaternion c u + s′ w of the family (see the module docs) that zeroes the driver's
/// row and lies nearest `previous`, from `k` = [u₀ … u₃, w₀ … w₃, f(u), f(w), f((u + w)/√2)]
/// (the last unused when `linear`).
///
/// Returns `None` when the row has no zero on the family (b² − 4ad < 0 beyond round-off: a
/// driver angle out of reach when the joint's references are not perpendicular to its axis),
/// or when a coefficient is not finite.
#[must_use]
pub fn about_axis<R: Real>(
    k: &[R; COEFFICIENTS],
    linear: bool,
    previous: &[R; 4],
) -> Option<[R; 4]> {
    let dot = |a: &[R], b: &[R]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2] + a[3] * b[3];
    let (u, w) = (&k[0..4], &k[4..8]);
    let (pu, pw) = (dot(u, previous), dot(w, previous));
    // The best direction so far: (its squared projection on the prediction over its squared
    // length, c, s′).
    let mut best: Option<(R, R, R)> = None;
    let mut consider = |c: R, s: R| {
        let length = c * c + s * s;
        if !(length > R::ZERO && length.is_finite()) {
            return;
        }
        let p = c * pu + s * pw;
        let closeness = p * p / length;
        if best.is_none_or(|(m, _, _)| closeness > m) {
            best = Some((closeness, c, s));
        }
    };
    let (fu, fw) = (k[8], k[9]);
    if linear {
        consider(fw, -fu);
    } else {
        let (a, d) = (fu, fw);
        let b = R::from_f64(2.0) * k[10] - a - d;
        let four_ad = R::from_f64(4.0) * a * d;
        let discriminant = b * b - four_ad;
        // A double root (a driver at the edge of its reach) may come out slightly negative.
        let reach = R::from_f64(16.0) * R::EPSILON * (b * b + four_ad.abs());
        if discriminant.is_nan() || discriminant < -reach {
            return None;
        }
        let root = discriminant.max(R::ZERO).sqrt();
        let k = -(b + if b >= R::ZERO { root } else { -root }) * R::from_f64(0.5);
        consider(k, a);
        consider(d, k);
    }
    let (_, c, s) = best?;
    let sign = if c * pu + s * pw < R::ZERO { -R::ONE } else { R::ONE };
    let e: [R; 4] = core::array::from_fn(|i| sign * (c * u[i] + s * w[i]));
    let length = dot(&e, &e).sqrt();
    if !(length > R::ZERO && length.is_finite()) {
        return None;
    }
    Some(e.map(|v| v / length))
}

#[cfg(test)]
mod tests;
