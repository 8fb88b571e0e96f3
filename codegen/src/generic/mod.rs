//! The generic engine: Φ, Φ_q, ν and γ assembled at run time for any mechanism.
//!
//! Unknowns are the 7 coordinates `[x, y, z, e0, e1, e2, e3]` of every non-ground body, in
//! body order. Equations come in a fixed order: joint rows (joints in file order), then
//! constraint rows, then driver rows, then one Euler-parameter normalisation per non-ground
//! body (thesis eq. 3.13: pᵀp − 1 = 0). Each row is written once, as a function of vector
//! primitives (`kin`), which carry its Jacobian and its ν and γ terms along.
//!
//! Row forms (all free of singularities at every relative angle):
//! - spherical (eq. 4.11): P_j − P_i = 0, 3 rows;
//! - universal (eq. 4.14–4.19): spherical + a_i·a_j = 0;
//! - parallel axes (the thesis' n1/p1 conditions, eq. 4.20–4.25): b_i·a_j = 0 and
//!   c_i·a_j = 0, where b_i, c_i are body-i unit vectors ⟂ axis_i (Haug's form, instead of
//!   two rows of a_i × a_j, whose choice degenerates for some axis directions);
//! - revolute: spherical + parallel axes;
//! - cylindrical (eq. 4.26–4.31): parallel axes + b_i·d = 0, c_i·d = 0 with d = P_j − P_i;
//! - prismatic (eq. 4.32–4.38): cylindrical + ref_i·ref_j = 0;
//! - screw (eq. 4.40–4.56, reformulated): cylindrical + x sin φ − y cos φ = 0, where
//!   x = ref_i·ref_j, y = (ref_i × ref_j)·a_i (so θ = atan2(y, x) is the joint angle) and
//!   φ = θ0 + 2π (d·a_i − d0)/lead is the angle the helix demands for the current axial
//!   position. It states θ ≡ φ (mod π) with no arccos and no stored turn count, so it holds
//!   through any number of turns;
//! - distance: (d·d − L²)/(2L) = 0 (≈ |d| − L near the solution, in length units);
//! - fix (eq. 4.57): `q_b[c] − value`; coordinate difference: `q_i[c] − q_j[c] − value`;
//! - joint rotation driver: x sin s(t) − y cos s(t) = sin(s − θ) = 0; joint translation
//!   driver: d·a_i − s(t) = 0; absolute drivers: `q_b[c] − s(t) = 0` or, for rotations about a
//!   global axis (eq. 4.62), e_k cos(s/2) − e0 sin(s/2) = 0.

pub(crate) mod kin;
pub mod redundancy;
pub mod scaling;
mod solve;
mod sparse;
#[cfg(test)]
mod tests;

use nalgebra::{DMatrix, DVector, Vector3};

use crate::model::{
    BodyId, Constraint, ConstraintKind, Driver, DriverCoordinate, DriverTarget, Joint, JointKind,
    Leg, Mechanism, Motion,
};
use kin::{BodyState, Sk, Vk};

pub use solve::{Analysis, Failure, FailureKind, Frame, Preparation, StepReport, TimedStop};
pub use sparse::SPARSE_FROM_UNKNOWNS;

/// Re-exported from the model, where the row layout lives, for the tool's existing paths.
pub use crate::model::RowLabel;

/// The assembled system at one evaluation.
#[derive(Clone, Debug)]
pub struct System {
    /// Φ(q, t).
    pub phi: DVector<f64>,
    /// Φ_q, equations × unknowns.
    pub jac: DMatrix<f64>,
    /// ν = −Φ_t.
    pub nu: DVector<f64>,
    /// γ = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt, valid for the q̇ given.
    pub gamma: DVector<f64>,
}

/// The equations of one mechanism, ready to evaluate.
#[derive(Clone, Debug)]
pub struct Equations<'m> {
    mech: &'m Mechanism,
    /// Column of each body's first coordinate; `None` for ground bodies.
    offset: Vec<Option<usize>>,
    labels: Vec<RowLabel>,
    unknowns: usize,
    /// Local unit vectors (b_i, c_i) ⟂ axis_i for each joint with an axis.
    normals: Vec<Option<(Vector3<f64>, Vector3<f64>)>>,
    /// The bodies each row acts on.
    row_bodies: Vec<Vec<BodyId>>,
    /// Each driver's driven quantity at the initial estimates: what an input driver holds
    /// when no series is replayed (`check`, `generate`).
    held: Vec<f64>,
}

impl<'m> Equations<'m> {
    /// Lays out the unknowns and equations of `mech`.
    #[must_use]
    pub fn new(mech: &'m Mechanism) -> Self {
        let mut offset = Vec::with_capacity(mech.bodies.len());
        let mut unknowns = 0;
        for body in &mech.bodies {
            if body.ground {
                offset.push(None);
            } else {
                offset.push(Some(unknowns));
                unknowns += 7;
            }
        }
        let labels = mech.row_labels();
        let normals = mech.joints.iter().map(Joint::normals).collect();
        let mut row_bodies = Vec::with_capacity(labels.len());
        for joint in &mech.joints {
            for _ in 0..joint.kind.equations() {
                row_bodies.push(vec![joint.body_i, joint.body_j]);
            }
        }
        for c in &mech.constraints {
            row_bodies.push(match c.kind {
                ConstraintKind::Fix { body, .. } => vec![body],
                ConstraintKind::CoordinateDifference { body_i, body_j, .. } => vec![body_i, body_j],
            });
        }
        for d in &mech.drivers {
            row_bodies.push(match d.target {
                DriverTarget::Joint { joint, .. } => {
                    vec![mech.joints[joint.0].body_i, mech.joints[joint.0].body_j]
                }
                DriverTarget::Absolute { body, .. } => vec![body],
                DriverTarget::Point { point, .. } => vec![mech.points[point.0].body],
                DriverTarget::Leg(leg) => vec![leg.body_i, leg.body_j],
            });
        }
        row_bodies.extend(mech.moving_bodies().map(|b| vec![b]));
        debug_assert_eq!(row_bodies.len(), labels.len());
        let mut eq = Self { mech, offset, labels, unknowns, normals, row_bodies, held: Vec::new() };
        let q = eq.initial_estimate();
        let states = eq.states(&q, &DVector::zeros(q.len()));
        eq.held = (0..mech.drivers.len()).map(|k| eq.driven(k, &states).v).collect();
        eq
    }

    /// The value driver `k` prescribes at the initial estimates: what an input driver holds
    /// when no series is replayed.
    #[must_use]
    pub fn held(&self, k: usize) -> f64 {
        self.held[k]
    }

    /// `(s, ṡ, s̈)` of driver `k` at time `t` (see [`Mechanism::drive`]).
    #[must_use]
    pub fn driver_value(&self, k: usize, t: f64) -> (f64, f64, f64) {
        self.mech.drive(k, t, || self.held[k])
    }

    /// The quantity driver `k` prescribes, as a function of the body states: the joint angle
    /// atan2(y, x), the axial position, the body coordinate, the rotation 2 atan2(e_k, e0)
    /// about a global axis or the point's coordinate (only its value is meaningful for the
    /// angles).
    fn driven(&self, k: usize, states: &[BodyState]) -> Sk {
        match self.mech.drivers[k].target {
            DriverTarget::Joint { joint, motion } => {
                let jt = &self.mech.joints[joint.0];
                let (bi, bj) = (&states[jt.body_i.0], &states[jt.body_j.0]);
                match motion {
                    Motion::Rotation => {
                        let (x, y) = joint_angle(jt, bi, bj);
                        Sk::constant(y.v.atan2(x.v))
                    }
                    Motion::Translation => axial_position(jt, bi, bj),
                }
            }
            DriverTarget::Absolute { body, coordinate } => {
                let b = &states[body.0];
                match coordinate {
                    DriverCoordinate::Rx | DriverCoordinate::Ry | DriverCoordinate::Rz => {
                        let e = Sk::coordinate(0, b, absolute_index(coordinate));
                        Sk::constant(2.0 * e.v.atan2(b.p[0]))
                    }
                    _ => Sk::coordinate(0, b, absolute_index(coordinate)),
                }
            }
            DriverTarget::Point { point, axis } => {
                let pt = &self.mech.points[point.0];
                Vk::point(0, &states[pt.body.0], &pt.local).component(axis)
            }
            DriverTarget::Leg(leg) => {
                let d = leg_separation(&leg, states);
                Sk::constant(leg.length_of(d.v.norm()))
            }
        }
    }

    /// The bodies equation `row` acts on.
    #[must_use]
    pub fn row_bodies(&self, row: usize) -> &[BodyId] {
        &self.row_bodies[row]
    }

    /// The mechanism.
    #[must_use]
    pub fn mechanism(&self) -> &'m Mechanism {
        self.mech
    }

    /// Number of unknowns.
    #[must_use]
    pub fn unknowns(&self) -> usize {
        self.unknowns
    }

    /// Number of equations.
    #[must_use]
    pub fn equations(&self) -> usize {
        self.labels.len()
    }

    /// The label of every equation, in row order.
    #[must_use]
    pub fn labels(&self) -> &[RowLabel] {
        &self.labels
    }

    /// Column offset of a body's coordinates, `None` for ground.
    #[must_use]
    pub fn offset(&self, body: BodyId) -> Option<usize> {
        self.offset[body.0]
    }

    /// The initial estimates as a vector of unknowns.
    #[must_use]
    pub fn initial_estimate(&self) -> DVector<f64> {
        let mut q = DVector::zeros(self.unknowns);
        for (body, off) in self.mech.bodies.iter().zip(&self.offset) {
            if let Some(o) = *off {
                q.fixed_rows_mut::<3>(o).copy_from(&body.r);
                q.fixed_rows_mut::<4>(o + 3).copy_from(&body.p);
            }
        }
        q
    }

    /// The state of every body for the unknowns `q` and their rates `qd`.
    fn states(&self, q: &DVector<f64>, qd: &DVector<f64>) -> Vec<BodyState> {
        self.mech
            .bodies
            .iter()
            .zip(&self.offset)
            .map(|(body, off)| match *off {
                Some(o) => BodyState::new(&q.as_slice()[o..o + 7], &qd.as_slice()[o..o + 7]),
                None => {
                    let fixed =
                        [body.r.x, body.r.y, body.r.z, body.p[0], body.p[1], body.p[2], body.p[3]];
                    BodyState::new(&fixed, &[0.0; 7])
                }
            })
            .collect()
    }

    /// Evaluates Φ, Φ_q, ν and γ at `(q, t)` with rates `qd` (γ is only meaningful for the
    /// true q̇; the other three do not depend on `qd`).
    #[must_use]
    pub fn evaluate(&self, q: &DVector<f64>, qd: &DVector<f64>, t: f64) -> System {
        let m = self.equations();
        let mut sys = System {
            phi: DVector::zeros(m),
            jac: DMatrix::zeros(m, self.unknowns),
            nu: DVector::zeros(m),
            gamma: DVector::zeros(m),
        };
        self.visit_rows(q, qd, t, |row, bodies, sk| {
            sys.phi[row] = sk.v;
            sys.nu[row] = -sk.t;
            sys.gamma[row] = -sk.d2;
            for (slot, off) in bodies.iter().enumerate() {
                if let Some(o) = *off {
                    for c in 0..7 {
                        sys.jac[(row, o + c)] += sk.jac[slot][c];
                    }
                }
            }
        });
        sys
    }

    /// Φ_q at `(q, t)` by rows, only the entries of the (at most two) bodies each row acts
    /// on: `(column, value)` in increasing column order, zeros left out.
    #[must_use]
    pub fn jacobian_rows(&self, q: &DVector<f64>, t: f64) -> Vec<Vec<(usize, f64)>> {
        let mut rows = vec![Vec::new(); self.equations()];
        self.visit_rows(q, &DVector::zeros(q.len()), t, |row, bodies, sk| {
            let entries = &mut rows[row];
            for (slot, off) in bodies.iter().enumerate() {
                if let Some(o) = *off {
                    for c in 0..7 {
                        entries.push((o + c, sk.jac[slot][c]));
                    }
                }
            }
            entries.sort_by_key(|&(c, _)| c);
            // A row whose two slots are one body adds its blocks, as `evaluate` does.
            entries.dedup_by(|b, a| {
                let same = a.0 == b.0;
                if same {
                    a.1 += b.1;
                }
                same
            });
            entries.retain(|&(_, x)| x != 0.0);
        });
        rows
    }

    /// Calls `f(row, bodies, sk)` for every equation in row order, with the column offsets of
    /// the bodies of its two slots and its value, Jacobian blocks and time derivatives.
    fn visit_rows(
        &self,
        q: &DVector<f64>,
        qd: &DVector<f64>,
        t: f64,
        mut f: impl FnMut(usize, [Option<usize>; 2], &Sk),
    ) {
        let states = self.states(q, qd);
        let mut row = 0;
        let mut emit = |bodies: [Option<usize>; 2], sk: Sk| {
            f(row, bodies, &sk);
            row += 1;
        };
        for (k, joint) in self.mech.joints.iter().enumerate() {
            let pair = [self.offset[joint.body_i.0], self.offset[joint.body_j.0]];
            let (bi, bj) = (&states[joint.body_i.0], &states[joint.body_j.0]);
            for sk in self.joint_rows(k, joint, bi, bj) {
                emit(pair, sk);
            }
        }
        for c in &self.mech.constraints {
            let (bodies, sk) = self.constraint_row(c, &states);
            emit(bodies, sk);
        }
        for (k, d) in self.mech.drivers.iter().enumerate() {
            let (bodies, sk) = self.driver_row(k, d, &states, t);
            emit(bodies, sk);
        }
        for (b, off) in states.iter().zip(&self.offset) {
            if off.is_some() {
                // Thesis eq. 3.13: pᵀp − 1 = 0, Jacobian 2pᵀ, γ = −2ṗᵀṗ.
                let p: Vec<Sk> = (3..7).map(|i| Sk::coordinate(0, b, i)).collect();
                let sk = p.iter().fold(Sk::constant(-1.0), |acc, e| acc.add(&e.mul(e)));
                emit([*off, None], sk);
            }
        }
        debug_assert_eq!(row, self.equations());
    }

    /// A constraint's row and the column offsets of its bodies.
    fn constraint_row(&self, c: &Constraint, states: &[BodyState]) -> ([Option<usize>; 2], Sk) {
        match c.kind {
            ConstraintKind::Fix { body, coordinate, value } => {
                let sk = Sk::coordinate(0, &states[body.0], coordinate.index())
                    .sub(&Sk::constant(value));
                ([self.offset[body.0], None], sk)
            }
            ConstraintKind::CoordinateDifference { body_i, body_j, coordinate, value } => {
                let idx = coordinate.index();
                let sk = Sk::coordinate(0, &states[body_i.0], idx)
                    .sub(&Sk::coordinate(1, &states[body_j.0], idx))
                    .sub(&Sk::constant(value));
                ([self.offset[body_i.0], self.offset[body_j.0]], sk)
            }
        }
    }

    /// A driver's row at time `t` and the column offsets of its bodies.
    fn driver_row(
        &self,
        k: usize,
        d: &Driver,
        states: &[BodyState],
        t: f64,
    ) -> ([Option<usize>; 2], Sk) {
        let s = Sk::time(self.driver_value(k, t));
        match d.target {
            DriverTarget::Joint { joint, motion } => {
                let jt = &self.mech.joints[joint.0];
                let (bi, bj) = (&states[jt.body_i.0], &states[jt.body_j.0]);
                let sk = match motion {
                    Motion::Rotation => {
                        let (x, y) = joint_angle(jt, bi, bj);
                        angle_residual(&x, &y, &s)
                    }
                    Motion::Translation => axial_position(jt, bi, bj).sub(&s),
                };
                ([self.offset[jt.body_i.0], self.offset[jt.body_j.0]], sk)
            }
            DriverTarget::Absolute { body, coordinate } => {
                ([self.offset[body.0], None], absolute_row(&states[body.0], coordinate, &s))
            }
            DriverTarget::Point { point, axis } => {
                // The point's global coordinate r + A s' minus s: its Jacobian, ṙ + B ṗ and
                // the κ term 2 A(ṗ) s' come from the point primitive.
                let pt = &self.mech.points[point.0];
                let sk = Vk::point(0, &states[pt.body.0], &pt.local).component(axis).sub(&s);
                ([self.offset[pt.body.0], None], sk)
            }
            DriverTarget::Leg(leg) => {
                ([self.offset[leg.body_i.0], self.offset[leg.body_j.0]], leg_row(&leg, states, &s))
            }
        }
    }

    /// The rows of joint `k`, in the order of [`crate::model::JointSpec::rows`]; one
    /// function per type below, as in `symbolic`.
    fn joint_rows(&self, k: usize, joint: &Joint, bi: &BodyState, bj: &BodyState) -> Vec<Sk> {
        let v = JointVectors::new(joint, self.normals[k], bi, bj);
        match joint.kind {
            JointKind::Spherical => spherical(&v),
            JointKind::Universal => universal(&v),
            JointKind::Revolute => revolute(&v),
            JointKind::Cylindrical => cylindrical(&v),
            JointKind::Prismatic => prismatic(&v, joint, bi, bj),
            JointKind::Screw { lead, d0, theta0 } => screw(&v, joint, bi, bj, lead, d0, theta0),
            JointKind::Distance { length } => distance(&v, length),
        }
    }
}

/// The global vectors of one joint that its rows combine.
struct JointVectors {
    /// d = P_j − P_i.
    d: Vk,
    /// (a_i, a_j), the axes, for the types that have them.
    axes: Option<(Vk, Vk)>,
    /// (b_i, c_i), the body-i unit vectors ⟂ axis_i.
    normals: Option<(Vk, Vk)>,
}

impl JointVectors {
    fn new(
        joint: &Joint,
        normals: Option<(Vector3<f64>, Vector3<f64>)>,
        bi: &BodyState,
        bj: &BodyState,
    ) -> Self {
        let d = Vk::point(1, bj, &joint.point_j).sub(&Vk::point(0, bi, &joint.point_i));
        let axes = joint.axis.map(|(ai, aj)| (Vk::vector(0, bi, &ai), Vk::vector(1, bj, &aj)));
        let normals = normals.map(|(b, c)| (Vk::vector(0, bi, &b), Vk::vector(0, bi, &c)));
        Self { d, axes, normals }
    }

    fn axes(&self) -> &(Vk, Vk) {
        self.axes.as_ref().expect("validated: joint has axes")
    }

    fn normals(&self) -> &(Vk, Vk) {
        self.normals.as_ref().expect("validated: joint has axes")
    }
}

/// d = 0: the joint points coincide.
fn coincident(v: &JointVectors) -> Vec<Sk> {
    (0..3).map(|c| v.d.component(c)).collect()
}

/// b_i·a_j = 0, c_i·a_j = 0: the axes are parallel.
fn parallel(v: &JointVectors) -> Vec<Sk> {
    let (_, aj) = v.axes();
    let (b, c) = v.normals();
    vec![b.dot(aj), c.dot(aj)]
}

/// Spherical: d = 0.
fn spherical(v: &JointVectors) -> Vec<Sk> {
    coincident(v)
}

/// Universal: d = 0; a_i·a_j = 0.
fn universal(v: &JointVectors) -> Vec<Sk> {
    let (ai, aj) = v.axes();
    let mut rows = coincident(v);
    rows.push(ai.dot(aj));
    rows
}

/// Revolute: d = 0; axes parallel.
fn revolute(v: &JointVectors) -> Vec<Sk> {
    let mut rows = coincident(v);
    rows.extend(parallel(v));
    rows
}

/// Cylindrical: axes parallel; b_i·d = 0, c_i·d = 0.
fn cylindrical(v: &JointVectors) -> Vec<Sk> {
    let (b, c) = v.normals();
    let mut rows = parallel(v);
    rows.push(b.dot(&v.d));
    rows.push(c.dot(&v.d));
    rows
}

/// Prismatic: cylindrical; ref_i·ref_j = 0.
fn prismatic(v: &JointVectors, joint: &Joint, bi: &BodyState, bj: &BodyState) -> Vec<Sk> {
    let (ri, rj) = references(joint, bi, bj);
    let mut rows = cylindrical(v);
    rows.push(ri.dot(&rj));
    rows
}

/// Screw: cylindrical; x sin φ − y cos φ = 0 with φ = θ0 + 2π (d·a_i − d0)/lead.
fn screw(
    v: &JointVectors,
    joint: &Joint,
    bi: &BodyState,
    bj: &BodyState,
    lead: f64,
    d0: f64,
    theta0: f64,
) -> Vec<Sk> {
    let (x, y) = joint_angle(joint, bi, bj);
    let k = 2.0 * std::f64::consts::PI / lead;
    let phi =
        axial_position(joint, bi, bj).sub(&Sk::constant(d0)).scale(k).add(&Sk::constant(theta0));
    let mut rows = cylindrical(v);
    rows.push(angle_residual(&x, &y, &phi));
    rows
}

/// Distance: (d·d − L²)/(2L) = 0.
fn distance(v: &JointVectors, length: f64) -> Vec<Sk> {
    vec![v.d.dot(&v.d).sub(&Sk::constant(length * length)).scale(0.5 / length)]
}

/// d = S − U of a reduced leg, body i in slot 0 and body j in slot 1.
fn leg_separation(leg: &Leg, states: &[BodyState]) -> Vk {
    let u = Vk::point(0, &states[leg.body_i.0], &leg.point_i);
    Vk::point(1, &states[leg.body_j.0], &leg.point_j).sub(&u)
}

/// A reduced leg's row: (d·d − s² − 2 s·along − base) / (2 length).
fn leg_row(leg: &Leg, states: &[BodyState], s: &Sk) -> Sk {
    let d = leg_separation(leg, states);
    let f = s.mul(s).add(&s.scale(2.0 * leg.along)).add(&Sk::constant(leg.base));
    d.dot(&d).sub(&f).scale(0.5 / leg.length)
}

/// An absolute driver's row: `q_b[c] − s(t)`, or for a rotation about a global axis
/// e_k cos(s/2) − e0 sin(s/2).
fn absolute_row(b: &BodyState, coordinate: DriverCoordinate, s: &Sk) -> Sk {
    match coordinate {
        DriverCoordinate::X => Sk::coordinate(0, b, 0).sub(s),
        DriverCoordinate::Y => Sk::coordinate(0, b, 1).sub(s),
        DriverCoordinate::Z => Sk::coordinate(0, b, 2).sub(s),
        // q_b[e_k] − s = 0.
        DriverCoordinate::E1 => Sk::coordinate(0, b, 4).sub(s),
        DriverCoordinate::E2 => Sk::coordinate(0, b, 5).sub(s),
        DriverCoordinate::E3 => Sk::coordinate(0, b, 6).sub(s),
        DriverCoordinate::Rx | DriverCoordinate::Ry | DriverCoordinate::Rz => {
            let k = match coordinate {
                DriverCoordinate::Rx => 4,
                DriverCoordinate::Ry => 5,
                _ => 6,
            };
            // Thesis eq. 4.62 in the one-equation form of the contract:
            // e_k cos(s/2) − e0 sin(s/2) = 0.
            let (sin, cos) = s.scale(0.5).sin_cos();
            Sk::coordinate(0, b, k).mul(&cos).sub(&Sk::coordinate(0, b, 3).mul(&sin))
        }
    }
}

/// Index in `[x, y, z, e0, e1, e2, e3]` of the coordinate an absolute driver moves (for rx, ry
/// and rz, the Euler parameter e_k of its equation).
pub(crate) fn absolute_index(c: DriverCoordinate) -> usize {
    match c {
        DriverCoordinate::X => 0,
        DriverCoordinate::Y => 1,
        DriverCoordinate::Z => 2,
        DriverCoordinate::Rx | DriverCoordinate::E1 => 4,
        DriverCoordinate::Ry | DriverCoordinate::E2 => 5,
        DriverCoordinate::Rz | DriverCoordinate::E3 => 6,
    }
}

/// The global reference vectors (ref_i, ref_j) of a joint.
fn references(joint: &Joint, bi: &BodyState, bj: &BodyState) -> (Vk, Vk) {
    let (ri, rj) = joint.reference.expect("validated: joint has references");
    (Vk::vector(0, bi, &ri), Vk::vector(1, bj, &rj))
}

/// (x, y) = (ref_i·ref_j, (ref_i × ref_j)·axis_i): the joint angle is θ = atan2(y, x).
pub(crate) fn joint_angle(joint: &Joint, bi: &BodyState, bj: &BodyState) -> (Sk, Sk) {
    let (ri, rj) = references(joint, bi, bj);
    let (ai, _) = joint.axis.expect("validated: joint has axes");
    let ai = Vk::vector(0, bi, &ai);
    (ri.dot(&rj), ri.cross(&rj).dot(&ai))
}

/// The axial position (P_j − P_i)·axis_i.
pub(crate) fn axial_position(joint: &Joint, bi: &BodyState, bj: &BodyState) -> Sk {
    let d = Vk::point(1, bj, &joint.point_j).sub(&Vk::point(0, bi, &joint.point_i));
    let (ai, _) = joint.axis.expect("validated: joint has axes");
    d.dot(&Vk::vector(0, bi, &ai))
}

/// x sin s − y cos s: zero when the angle atan2(y, x) equals s (mod π).
fn angle_residual(x: &Sk, y: &Sk, s: &Sk) -> Sk {
    let (sin, cos) = s.sin_cos();
    x.mul(&sin).sub(&y.mul(&cos))
}

/// cos(θ − s) for the joint angle θ of a rotation driver: positive on the intended branch,
/// negative when Newton landed on θ = s + π.
pub(crate) fn angle_alignment(joint: &Joint, bi: &BodyState, bj: &BodyState, s: f64) -> f64 {
    let (x, y) = joint_angle(joint, bi, bj);
    let (sin, cos) = s.sin_cos();
    x.v * cos + y.v * sin
}
