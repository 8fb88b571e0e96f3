//! Units for rank and pivot decisions. Φ_q mixes units: its translational columns (x, y, z of
//! a body) are per length, its Euler-parameter columns dimensionless, and its rows are lengths
//! (joint points, distances, translations) or dimensionless (axes, angles, normalisations). A
//! tolerance relative to the largest singular value or pivot of such a matrix depends on the
//! unit of length: with links of length L, a length row's Euler-parameter entries are about L
//! and its translational entries about 1, and the smallest singular value of a regular Φ_q
//! falls like 1/L² relative to the largest (links of 10⁵ m looked undriven at 10⁻¹⁰).
//!
//! Every rank and pivot decision therefore looks at Φ_q in balanced units: translational
//! columns times the mechanism's characteristic length ([`length_scale`]), which makes every
//! entry of a row carry that row's unit, and then (where the decision is not already relative
//! to each row) each row divided by its largest entry. A uniform change of the unit of length
//! then leaves the balanced matrix unchanged up to the rounding of the scales to powers of two
//! (which keeps the scaling itself exact).

use nalgebra::{DMatrix, DVector};

use super::Equations;
use crate::model::Mechanism;

/// The power of two nearest `x` (> 0, finite), or 1.
#[must_use]
pub fn power_of_two(x: f64) -> f64 {
    if x > 0.0 && x.is_finite() { 2f64.powi(x.log2().round() as i32) } else { 1.0 }
}

/// The mechanism's characteristic length, a power of two: the largest lever arm of a joint
/// (|point| in the frame of a moving body, which sets the size of the Euler-parameter entries
/// of the joint's length rows), else the largest distance of a moving body from the origin,
/// else 1.
#[must_use]
pub fn length_scale(mech: &Mechanism) -> f64 {
    let moving = |b: crate::model::BodyId| !mech.bodies[b.0].ground;
    let arms = mech.joints.iter().flat_map(|j| {
        [(j.body_i, j.point_i.norm()), (j.body_j, j.point_j.norm())]
            .into_iter()
            .filter(|&(b, _)| moving(b))
            .map(|(_, x)| x)
    });
    let largest =
        |it: &mut dyn Iterator<Item = f64>| it.filter(|x| x.is_finite()).fold(0.0, f64::max);
    let arm = largest(&mut arms.into_iter());
    let l = if arm > 0.0 {
        arm
    } else {
        largest(&mut mech.bodies.iter().filter(|b| !b.ground).map(|b| b.r.norm()))
    };
    power_of_two(l)
}

/// `m` with column j multiplied by `columns[j]` and then each row divided by the power of two
/// nearest its largest entry (rows of zeros stay), and those row factors (the reciprocals of
/// the divisors): exact, every factor being a power of two.
#[must_use]
pub fn balanced(mut m: DMatrix<f64>, columns: &DVector<f64>) -> (DMatrix<f64>, DVector<f64>) {
    for (j, &c) in columns.iter().enumerate() {
        m.column_mut(j).scale_mut(c);
    }
    let mut rows = DVector::from_element(m.nrows(), 1.0);
    for (i, mut row) in m.row_iter_mut().enumerate() {
        let big = row.iter().fold(0.0_f64, |a, x| a.max(x.abs()));
        if big > 0.0 {
            rows[i] = 1.0 / power_of_two(big);
            row *= rows[i];
        }
    }
    (m, rows)
}

impl Equations<'_> {
    /// The factor of each unknown's column in balanced units: the mechanism's
    /// [`length_scale`] for x, y and z, 1 for the Euler parameters.
    #[must_use]
    pub fn column_scales(&self) -> DVector<f64> {
        let l = length_scale(self.mechanism());
        DVector::from_fn(self.unknowns(), |j, _| if j % 7 < 3 { l } else { 1.0 })
    }
}
