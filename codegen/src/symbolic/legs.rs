//! U-P-S legs as distance rows: a leg whose length is driven is, for the bodies it joins, one
//! distance equation.
//!
//! A leg is two moving bodies joined by a prismatic joint P whose translation s is driven
//! ((P_j − P_i)·a_i − s = 0), one of them joined by a universal joint U to a body A, the other
//! by a spherical joint S to a body B, and nothing else acting on the two (no other joint,
//! constraint or driver). Write everything in the frame of P's body i: P's rows hold that body
//! j is body i turned by the constant R0 = A_iᵀ A_j (its value at the assembled configuration)
//! and shifted by s a along P's axis a (local to body i), so a point y of body j sits at
//! p_i + s a + R0 (y − p_j) in body i's frame. The joint points U (on the universal joint's leg
//! body) and S (on the spherical joint's) are therefore
//!
//! S − U = A_i (σ s a + v0),  |S − U|² = s² + 2 s σ (v0·a) + |v0|²,
//!
//! with σ = +1 when S is on body j and −1 when it is on body i, and v0 constant. Given the
//! U, P and S rows, the difference between this distance equation (in A's and B's unknowns
//! and s alone) and the driver's is (s_P − s)(s_P + s + 2 σ v0·a), s_P the translation the
//! bodies have: where s + σ v0·a ≠ 0, one holds near the assembled configuration exactly when
//! the other does, and the system with the distance row in place of the driver's is locally
//! equivalent, with the same solution. Its Jacobian has the same rank there (the distance
//! row's gradient is the driver's times 2 (s + σ v0·a) plus a combination of the U, P and S
//! rows' gradients).
//!
//! The block-lower-triangular form then sees the bodies A and B alone in the distance rows:
//! a Gough–Stewart platform's pose (six distance rows and a normalisation) becomes a block of
//! its own, and each leg's bodies later blocks given the platform, which `blocks::outputs`
//! leaves out when no requested output needs them (the driver becomes a
//! [`DriverTarget::Leg`]).
//!
//! The universal joint keeps the leg's spin about its axis determined; a spherical joint at
//! both ends leaves it free (no square system), and a universal joint at both ends makes the
//! leg two equations on the bodies it joins, so neither is reduced. Every reduction is checked
//! at generation time: the distance row must vanish at the assembled configuration and
//! s + σ v0·a must be away from zero there, else the driver row is kept. The generic engine
//! does not reduce anything: it stays the independent reference.

use nalgebra::{Matrix3, Vector3, Vector4};

use super::{Builder, ExprId, Source, Symbolic};
use crate::expr::ExprPool;
use crate::model::frame::rotation;
use crate::model::{
    BodyId, ConstraintKind, DriverTarget, JointId, JointKind, Leg, Mechanism, Motion, RowLabel,
};

/// The distance row replaces the driver row only where |s + σ v0·a| is at least this fraction
/// of the leg's length: the distance row's gradient is the driver's times 2 (s + σ v0·a)
/// (over 2 length), so a smaller factor would trade a well-conditioned row for an
/// ill-conditioned one (the leg's axis nearly perpendicular to S − U).
const BRANCH_MARGIN: f64 = 1e-2;

/// The distance row must vanish at the assembled configuration to within this multiple of
/// the description's Newton tolerance: it is a combination of the U, P, S and driver rows
/// with coefficients of order one (in units of length), each of which holds to the
/// tolerance there, while a wrong v0 would leave a residual of the order of the leg's size.
const VANISHES: f64 = 1e3;

/// A leg whose driver row the generator replaced by a distance row.
#[derive(Clone, Debug, PartialEq)]
pub struct ReducedLeg {
    /// The driver (index into the mechanism's drivers) whose row was replaced.
    pub driver: usize,
    /// The leg's two bodies: the universal joint's, then the spherical joint's.
    pub bodies: [BodyId; 2],
    /// Its universal, prismatic and spherical joints.
    pub joints: [JointId; 3],
    /// The distance equation (bodies and points of the mechanism the system was built from).
    pub leg: Leg,
}

/// A leg found in the description's structure, before the numbers are checked.
struct Candidate {
    driver: usize,
    prismatic: JointId,
    universal: JointId,
    spherical: JointId,
    /// The leg body the universal joint holds, and the one the spherical joint holds.
    u_body: BodyId,
    s_body: BodyId,
}

/// The legs of `mech`: every translation driver of a prismatic joint between two moving
/// bodies on which nothing else acts but one universal joint (on one of them) and one
/// spherical joint (on the other), each to a body outside the leg, the two ends on different
/// bodies.
fn candidates(mech: &Mechanism) -> Vec<Candidate> {
    let mut found = Vec::new();
    for (k, d) in mech.drivers.iter().enumerate() {
        let DriverTarget::Joint { joint: prismatic, motion: Motion::Translation } = d.target else {
            continue;
        };
        let p = &mech.joints[prismatic.0];
        if p.kind != JointKind::Prismatic {
            continue;
        }
        let leg = [p.body_i, p.body_j];
        if leg.iter().any(|b| mech.bodies[b.0].ground) {
            continue;
        }
        // The other joint on each leg body, which must be its only other entity.
        let others = |b: BodyId| -> Vec<JointId> {
            (0..mech.joints.len())
                .filter(|&j| j != prismatic.0)
                .filter(|&j| mech.joints[j].body_i == b || mech.joints[j].body_j == b)
                .map(JointId)
                .collect()
        };
        let (oi, oj) = (others(leg[0]), others(leg[1]));
        let ([ji], [jj]) = (oi.as_slice(), oj.as_slice()) else { continue };
        let (ji, jj) = (*ji, *jj);
        let (u, s, u_body, s_body) = match (&mech.joints[ji.0].kind, &mech.joints[jj.0].kind) {
            (JointKind::Universal, JointKind::Spherical) => (ji, jj, leg[0], leg[1]),
            (JointKind::Spherical, JointKind::Universal) => (jj, ji, leg[1], leg[0]),
            _ => continue,
        };
        let end = |j: JointId, own: BodyId| {
            let joint = &mech.joints[j.0];
            if joint.body_i == own { joint.body_j } else { joint.body_i }
        };
        let (a, b) = (end(u, u_body), end(s, s_body));
        if leg.contains(&a) || leg.contains(&b) || a == b {
            continue;
        }
        if acts_on_leg(mech, k, &leg) {
            continue;
        }
        found.push(Candidate { driver: k, prismatic, universal: u, spherical: s, u_body, s_body });
    }
    found
}

/// Whether a constraint, or a driver other than `driver`, acts on a body of `leg`.
fn acts_on_leg(mech: &Mechanism, driver: usize, leg: &[BodyId; 2]) -> bool {
    let on = |b: &BodyId| leg.contains(b);
    let constraint = mech.constraints.iter().any(|c| match c.kind {
        ConstraintKind::Fix { body, .. } => on(&body),
        ConstraintKind::CoordinateDifference { body_i, body_j, .. } => on(&body_i) || on(&body_j),
    });
    let other_driver = mech.drivers.iter().enumerate().any(|(k, d)| {
        k != driver
            && match d.target {
                DriverTarget::Joint { joint, .. } => {
                    on(&mech.joints[joint.0].body_i) || on(&mech.joints[joint.0].body_j)
                }
                DriverTarget::Absolute { body, .. } => on(&body),
                DriverTarget::Point { point, .. } => on(&mech.points[point.0].body),
                DriverTarget::Leg(l) => on(&l.body_i) || on(&l.body_j),
            }
    });
    constraint || other_driver
}

impl Builder {
    /// A reduced leg's row: (|S − U|² − s² − 2 s·along − base) / (2 length).
    pub(super) fn leg_row(&mut self, leg: &Leg, s: ExprId) -> ExprId {
        let u = self.point(leg.body_i, &leg.point_i);
        let end = self.point(leg.body_j, &leg.point_j);
        let d = self.sub(&end, &u);
        let dd = self.dot(&d, &d);
        let p = &mut self.pool;
        let ss = p.mul(s, s);
        let two_along = p.constant(2.0 * leg.along);
        let linear = p.mul(two_along, s);
        let base = p.constant(leg.base);
        let f = p.sum(vec![ss, linear, base]);
        let diff = p.sub(dd, f);
        let half = p.constant(0.5 / leg.length);
        p.mul(half, diff)
    }
}

impl Symbolic {
    /// Replaces the driver row of every leg of `mech` by its distance row where the check at
    /// the assembled configuration `q` passes (see the module docs); records them in
    /// [`Symbolic::legs`].
    pub(super) fn reduce_legs(&mut self, mech: &Mechanism, q: &[f64], input_of: Vec<Option<u32>>) {
        let found = candidates(mech);
        if found.is_empty() {
            return;
        }
        let t = mech.time.start;
        let mut builder = Builder {
            pool: std::mem::take(&mut self.pool),
            coords: self.coords.clone(),
            laws: self.laws.clone(),
            input_of,
            derived: self.derived.iter().map(|d| d.value[0]).collect(),
        };
        let mut replaced = Vec::new();
        for c in found {
            let d = &mech.drivers[c.driver];
            let Some(row) =
                self.rows.iter().position(|l| l.kind == RowLabel::DRIVER && l.name == d.name)
            else {
                continue;
            };
            // A leg row left out as dependent keeps the rows as they are.
            let leg_joints = [c.universal, c.prismatic, c.spherical];
            let dependent = self.dropped.iter().any(|x| {
                x.label.kind == RowLabel::JOINT
                    && leg_joints.iter().any(|j| mech.joints[j.0].name == x.label.name)
            });
            if dependent {
                continue;
            }
            let Some(leg) = self.leg_at(mech, &builder.pool, &c, q, t) else { continue };
            let s = builder.law(c.driver, &d.law);
            let e = builder.leg_row(&leg, s);
            let u = self.planning_inputs(t);
            let value = builder.pool.eval_inputs(&[e], [q, &[], &[]], t, &u)[0];
            let vanishes = value.abs() <= VANISHES * mech.solver.tolerance;
            if !vanishes {
                log::debug!(
                    "leg of driver {}: its distance row is {value:e} at the assembled \
                     configuration, the driver row is kept",
                    d.name
                );
                continue;
            }
            replaced.push((
                row,
                e,
                ReducedLeg {
                    driver: c.driver,
                    bodies: [c.u_body, c.s_body],
                    joints: leg_joints,
                    leg,
                },
            ));
        }
        self.pool = builder.pool;
        for (row, e, leg) in replaced {
            self.phi[row] = e;
            self.jac[row] = self.jacobian_row(e);
            let jac = std::slice::from_ref(&self.jac[row]);
            self.row_factors[row] = self.row_factors_at(mech, jac, q)[0];
            self.legs.push(leg);
        }
    }

    /// The distance equation of leg `c` at the reduced configuration `q`, or `None` where
    /// s + σ v0·a is too near zero for the reduction (see [`BRANCH_MARGIN`]).
    fn leg_at(
        &self,
        mech: &Mechanism,
        pool: &ExprPool,
        c: &Candidate,
        q: &[f64],
        t: f64,
    ) -> Option<Leg> {
        let pose = |b: BodyId| self.pose(pool, b, q, t);
        let p = &mech.joints[c.prismatic.0];
        let (axis, _) = p.axis?;
        let ((ri, pi), (rj, pj)) = (pose(p.body_i), pose(p.body_j));
        let (ai, aj) = (rotation(&pi), rotation(&pj));
        let r0: Matrix3<f64> = ai.transpose() * aj;
        // A point `y` of a leg body in body i's frame, without the translation s a.
        let in_i = |body: BodyId, y: &Vector3<f64>| -> Vector3<f64> {
            if body == p.body_i { *y } else { p.point_i + r0 * (y - p.point_j) }
        };
        let (u, s) = (&mech.joints[c.universal.0], &mech.joints[c.spherical.0]);
        let (u_leg, u_end, a) = ends(u, c.u_body);
        let (s_leg, s_end, b) = ends(s, c.s_body);
        let v0 = in_i(c.s_body, &s_leg) - in_i(c.u_body, &u_leg);
        let sigma = if c.s_body == p.body_j { 1.0 } else { -1.0 };
        let along = sigma * v0.dot(&axis);
        let base = v0.norm_squared();
        // The translation the bodies have, and the leg's length, at `q`.
        let separation = (rj + aj * p.point_j) - (ri + ai * p.point_i);
        let s0 = separation.dot(&(ai * axis));
        let ((ra, pa), (rb, pb)) = (pose(a), pose(b));
        let length = ((rb + rotation(&pb) * s_end) - (ra + rotation(&pa) * u_end)).norm();
        let factor = s0 + along;
        let away = length > 0.0 && factor.abs() >= BRANCH_MARGIN * length;
        if !away {
            return None;
        }
        Some(Leg {
            body_i: a,
            point_i: u_end,
            body_j: b,
            point_j: s_end,
            along,
            base,
            length,
            branch: factor.signum(),
        })
    }

    /// r and p of body `b` at the reduced configuration `q` and time `t`.
    fn pose(&self, pool: &ExprPool, b: BodyId, q: &[f64], t: f64) -> (Vector3<f64>, Vector4<f64>) {
        let u = self.planning_inputs(t);
        let c: [f64; 7] = std::array::from_fn(|i| match self.coords[b.0][i] {
            Source::Unknown(k) => q[k],
            Source::Fixed(v) => v,
            Source::Driven(l) => pool.eval_inputs(&[self.laws[l][0]], [q, &[], &[]], t, &u)[0],
            Source::Derived(k) => {
                pool.eval_inputs(&[self.derived[k].value[0]], [q, &[], &[]], t, &u)[0]
            }
        });
        (Vector3::new(c[0], c[1], c[2]), Vector4::new(c[3], c[4], c[5], c[6]))
    }
}

/// A joint's point on the leg body `own`, its point on the other body, and that body.
fn ends(joint: &crate::model::Joint, own: BodyId) -> (Vector3<f64>, Vector3<f64>, BodyId) {
    if joint.body_i == own {
        (joint.point_i, joint.point_j, joint.body_j)
    } else {
        (joint.point_j, joint.point_i, joint.body_i)
    }
}

#[cfg(test)]
mod tests;
