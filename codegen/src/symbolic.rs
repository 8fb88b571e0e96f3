//! The mechanism as symbolic expressions: the reduced system the generator emits.
//!
//! "Model no more than the scene needs": ground bodies, `fix` constraints, coordinate
//! differences against a ground body and absolute x/y/z drivers are eliminated here: the
//! coordinate they hold becomes a constant or a function of time, and their equation
//! disappears. What remains are the true unknowns and their equations, in the generic
//! engine's row order.
//!
//! Φ is written once per row kind, with the same row forms as the generic engine (see
//! `generic`); Φ_q, ν and γ are then obtained by symbolic differentiation (`expr::diff`):
//! Φ_q = ∂Φ/∂q, ν = −∂Φ/∂t, and with Φ̇ = Φ_q q̇ + Φ_t (q̇ symbolic),
//! γ = −(∂Φ̇/∂q q̇ + ∂Φ̇/∂t) = −(Φ_q q̇)_q q̇ − 2 Φ_qt q̇ − Φ_tt. The generic engine derives
//! the same quantities by hand-written product rules, so the two are independent
//! derivations and their agreement is a test of both.

use std::collections::BTreeSet;

use nalgebra::{DVector, Vector3};

use crate::expr::{ExprId, ExprPool, Node, Var};
use crate::generic::Equations;
use crate::generic::redundancy::independent;
use crate::model::{
    BodyId, Constraint, ConstraintKind, Driver, DriverCoordinate, DriverTarget, Joint, JointKind,
    Law, Mechanism, Motion, RowLabel,
};

/// Where a body coordinate comes from in the reduced system.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Source {
    /// Reduced unknown number k.
    Unknown(usize),
    /// A constant (ground bodies, `fix` constraints).
    Fixed(f64),
    /// A driven coordinate: index into [`Symbolic::laws`].
    Driven(usize),
    /// A coordinate of a closed-form block substituted at generation time, an explicit
    /// expression of the remaining unknowns and t: index into [`Symbolic::derived`].
    Derived(usize),
}

/// The reduced symbolic system of one mechanism.
#[derive(Clone, Debug)]
pub struct Symbolic {
    /// The expression arena.
    pub pool: ExprPool,
    /// For every body, the source of its 7 coordinates `[x, y, z, e0, e1, e2, e3]`.
    pub coords: Vec<[Source; 7]>,
    /// Reduced unknown k ↔ (body, coordinate index).
    pub unknowns: Vec<(BodyId, usize)>,
    /// The equations kept, in row order.
    pub rows: Vec<RowLabel>,
    /// The equations eliminated with their coordinate.
    pub eliminated: Vec<RowLabel>,
    /// The equations named redundant by the rule of `generic::redundancy` on the whole Φ_q
    /// at the assembled initial configuration, as `check` and the generic engine name them.
    /// The reduced system leaves them out, except one whose coordinate was eliminated (a
    /// redundant `fix`): it leaves out the row that this one makes dependent instead.
    pub redundant: Vec<RowLabel>,
    /// The rows of the reduced system left out as dependent on the kept ones (the eliminated
    /// rows hold exactly and are not among them), checked at run time: a step on which one of
    /// them does not hold is refused.
    pub dropped: Vec<Dropped>,
    /// For every kept row, the factor that puts it in balanced units at the assembled initial
    /// configuration (the reciprocal of the power of two nearest its largest entry with the
    /// translational columns times the characteristic length, `generic::scaling::balanced`).
    pub row_factors: Vec<f64>,
    /// Φ, one expression per kept row.
    pub phi: Vec<ExprId>,
    /// Φ_q by rows: the structurally non-zero entries `(column, expression)`.
    pub jac: Vec<Vec<(usize, ExprId)>>,
    /// ν = −Φ_t.
    pub nu: Vec<ExprId>,
    /// γ, in terms of q, q̇ and t.
    pub gamma: Vec<ExprId>,
    /// For driven coordinates: (s, ṡ, s̈) as expressions in t (and in the inputs).
    pub laws: Vec<[ExprId; 3]>,
    /// The input drivers (`law = "input"`), in file order: input k is the symbol
    /// `Var::S(k)` with its rates `Var::Sd(k)` and `Var::Sdd(k)`.
    pub inputs: Vec<InputDriver>,
    /// The U-P-S legs whose driver row was replaced by the distance row of the bodies they
    /// join (`legs`), in driver order.
    pub legs: Vec<ReducedLeg>,
    /// The coordinates substituted by the closed forms of their blocks (`substitute`), in
    /// solve order: each an expression of the earlier ones, the remaining unknowns and t.
    pub derived: Vec<Derived>,
}

/// A row of the reduced system left out as dependent on the kept ones.
#[derive(Clone, Debug)]
pub struct Dropped {
    /// Its equation.
    pub label: RowLabel,
    /// Φ_i, its rate Φ̇_i = Φ_q,i q̇ − ν_i and its acceleration Φ̈_i = Φ_q,i q̈ − γ_i, in q, q̇,
    /// q̈ and t: the residuals of its position, velocity and acceleration equations.
    pub residuals: [ExprId; 3],
    /// The factor that puts it in balanced units, as [`Symbolic::row_factors`].
    pub factor: f64,
    /// Its row of Φ_q: the structurally non-zero entries `(column, expression)`.
    pub jac: Vec<(usize, ExprId)>,
    /// Its ν = −Φ_t and γ (in q, q̇ and t), as [`Symbolic::nu`] and [`Symbolic::gamma`]: the
    /// run-time solver substitutes the row for a kept one where the kept rows degenerate.
    pub rates: [ExprId; 2],
}

/// One input driver of the reduced system.
#[derive(Clone, Debug, PartialEq)]
pub struct InputDriver {
    /// Its index among the mechanism's drivers.
    pub driver: usize,
    /// The value it prescribes at the initial estimates (what the generic engine holds
    /// without a replayed series), the input the generated module starts from.
    pub initial: f64,
    /// The rate at which the generator's own walks (assembly, pivot planning) move it over
    /// the description's `[time]` grid: one turn over the grid for a rotation (a joint's, or a
    /// body's about a global axis), none otherwise (a translation's or a target's range is not
    /// known at generation time).
    pub sweep: f64,
    /// The first time point of that grid, where the sweep starts from `initial`.
    pub start: f64,
}

/// A sparse matrix by rows: `(column, value)`.
type SparseRows = Vec<Vec<(usize, f64)>>;

/// A 3-vector of expressions.
type V3 = [ExprId; 3];

/// Builds the rows of a mechanism into a pool.
struct Builder {
    pool: ExprPool,
    coords: Vec<[Source; 7]>,
    laws: Vec<[ExprId; 3]>,
    /// For every driver, its input index when it is an input driver.
    input_of: Vec<Option<u32>>,
    /// The value of every substituted coordinate ([`Source::Derived`]).
    derived: Vec<ExprId>,
}

impl Builder {
    fn coordinate(&mut self, body: BodyId, c: usize) -> ExprId {
        match self.coords[body.0][c] {
            Source::Unknown(k) => self.pool.var(Var::Q(u32::try_from(k).expect("small"))),
            Source::Fixed(v) => self.pool.constant(v),
            Source::Driven(l) => self.laws[l][0],
            Source::Derived(i) => self.derived[i],
        }
    }

    /// s of driver `k`: its law as an expression in t, or the symbol of its input.
    fn law(&mut self, k: usize, law: &Law) -> ExprId {
        if let Some(i) = self.input_of[k] {
            return self.pool.var(Var::S(i));
        }
        let t = self.pool.var(Var::T);
        let p = &mut self.pool;
        match *law {
            Law::Polynomial { start, velocity, acceleration } => {
                let (s0, v0, a) =
                    (p.constant(start), p.constant(velocity), p.constant(0.5 * acceleration));
                let vt = p.mul(v0, t);
                let tt = p.mul(t, t);
                let att = p.mul(a, tt);
                let s = p.add(s0, vt);
                p.add(s, att)
            }
            // Input drivers returned their symbol above.
            Law::Input => unreachable!("an input driver has an input index"),
            Law::Harmonic { offset, amplitude, frequency, phase } => {
                let (c, amp, w, ph) = (
                    p.constant(offset),
                    p.constant(amplitude),
                    p.constant(frequency),
                    p.constant(phase),
                );
                let wt = p.mul(w, t);
                let arg = p.add(wt, ph);
                let sin = p.sin(arg);
                let term = p.mul(amp, sin);
                p.add(c, term)
            }
        }
    }

    /// A(p) for a body (thesis eq. 3.18), row-major.
    fn rotation(&mut self, body: BodyId) -> [[ExprId; 3]; 3] {
        let e: [ExprId; 4] = std::array::from_fn(|k| self.coordinate(body, 3 + k));
        let p = &mut self.pool;
        let two = p.constant(2.0);
        let sq: [ExprId; 4] = std::array::from_fn(|k| p.mul(e[k], e[k]));
        // Diagonal: e0² + ek² − ej² − el²; off-diagonal: 2(ei ej ∓ e0 ek).
        let diag = |p: &mut ExprPool, k: usize| {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let a = p.add(sq[0], sq[1 + k]);
            let b = p.add(sq[1 + i], sq[1 + j]);
            p.sub(a, b)
        };
        let off = |p: &mut ExprPool, i: usize, j: usize, k: usize, plus: bool| {
            let a = p.mul(e[1 + i], e[1 + j]);
            let b = p.mul(e[0], e[1 + k]);
            let s = if plus { p.add(a, b) } else { p.sub(a, b) };
            p.mul(two, s)
        };
        let d0 = diag(p, 0);
        let d1 = diag(p, 1);
        let d2 = diag(p, 2);
        let a01 = off(p, 0, 1, 2, false);
        let a02 = off(p, 0, 2, 1, true);
        let a10 = off(p, 0, 1, 2, true);
        let a12 = off(p, 1, 2, 0, false);
        let a20 = off(p, 0, 2, 1, false);
        let a21 = off(p, 1, 2, 0, true);
        [[d0, a01, a02], [a10, d1, a12], [a20, a21, d2]]
    }

    /// A s' for a body-fixed vector.
    fn vector(&mut self, body: BodyId, local: &Vector3<f64>) -> V3 {
        let a = self.rotation(body);
        let s: [ExprId; 3] = std::array::from_fn(|k| self.pool.constant(local[k]));
        std::array::from_fn(|r| {
            let terms: Vec<ExprId> = (0..3).map(|c| self.pool.mul(a[r][c], s[c])).collect();
            self.pool.sum(terms)
        })
    }

    /// r + A s' for a body-fixed point.
    fn point(&mut self, body: BodyId, local: &Vector3<f64>) -> V3 {
        let v = self.vector(body, local);
        std::array::from_fn(|k| {
            let r = self.coordinate(body, k);
            self.pool.add(r, v[k])
        })
    }

    fn sub(&mut self, a: &V3, b: &V3) -> V3 {
        std::array::from_fn(|k| self.pool.sub(a[k], b[k]))
    }

    fn dot(&mut self, a: &V3, b: &V3) -> ExprId {
        let terms: Vec<ExprId> = (0..3).map(|k| self.pool.mul(a[k], b[k])).collect();
        self.pool.sum(terms)
    }

    fn cross(&mut self, a: &V3, b: &V3) -> V3 {
        std::array::from_fn(|k| {
            let (i, j) = ((k + 1) % 3, (k + 2) % 3);
            let x = self.pool.mul(a[i], b[j]);
            let y = self.pool.mul(a[j], b[i]);
            self.pool.sub(x, y)
        })
    }

    /// x sin s − y cos s.
    fn angle_residual(&mut self, x: ExprId, y: ExprId, s: ExprId) -> ExprId {
        let (sin, cos) = (self.pool.sin(s), self.pool.cos(s));
        let a = self.pool.mul(x, sin);
        let b = self.pool.mul(y, cos);
        self.pool.sub(a, b)
    }

    /// (x, y) = (ref_i·ref_j, (ref_i × ref_j)·axis_i).
    fn joint_angle(&mut self, j: &Joint) -> (ExprId, ExprId) {
        let (ri, rj) = j.reference.expect("validated: joint has references");
        let (ai, _) = j.axis.expect("validated: joint has axes");
        let (ri, rj) = (self.vector(j.body_i, &ri), self.vector(j.body_j, &rj));
        let ai = self.vector(j.body_i, &ai);
        let x = self.dot(&ri, &rj);
        let c = self.cross(&ri, &rj);
        (x, self.dot(&c, &ai))
    }

    /// (P_j − P_i)·axis_i.
    fn axial_position(&mut self, j: &Joint) -> ExprId {
        let d = self.separation(j);
        let (ai, _) = j.axis.expect("validated: joint has axes");
        let ai = self.vector(j.body_i, &ai);
        self.dot(&d, &ai)
    }

    /// d = P_j − P_i.
    fn separation(&mut self, j: &Joint) -> V3 {
        let pi = self.point(j.body_i, &j.point_i);
        let pj = self.point(j.body_j, &j.point_j);
        self.sub(&pj, &pi)
    }

    /// The coordinates ground bodies, `fix` constraints, coordinate differences against
    /// ground and absolute x/y/z drivers hold (the others left [`PLACEHOLDER`]), and the rows
    /// (indices into the row labels) eliminated with them.
    fn eliminate(&mut self, mech: &Mechanism) -> (Vec<[Source; 7]>, BTreeSet<usize>) {
        let mut coords: Vec<[Source; 7]> = mech
            .bodies
            .iter()
            .map(|b| {
                if b.ground {
                    let q = [b.r.x, b.r.y, b.r.z, b.p[0], b.p[1], b.p[2], b.p[3]];
                    q.map(Source::Fixed)
                } else {
                    [PLACEHOLDER; 7]
                }
            })
            .collect();
        // Row indices (into `labels`) of the eliminated equations.
        let mut eliminated = BTreeSet::new();
        let (first_constraint, first_driver) =
            (mech.first_constraint_row(), mech.first_driver_row());
        for (k, c) in mech.constraints.iter().enumerate() {
            let target = match c.kind {
                ConstraintKind::Fix { body, coordinate, value } => {
                    Some((body, coordinate.index(), value))
                }
                ConstraintKind::CoordinateDifference { body_i, body_j, coordinate, value } => {
                    let c = coordinate.index();
                    match (&coords[body_i.0][c], &coords[body_j.0][c]) {
                        (Source::Fixed(g), _) if mech.bodies[body_i.0].ground => {
                            Some((body_j, c, g - value))
                        }
                        (_, Source::Fixed(g)) if mech.bodies[body_j.0].ground => {
                            Some((body_i, c, g + value))
                        }
                        _ => None,
                    }
                }
            };
            if let Some((body, idx, value)) = target
                && coords[body.0][idx] == PLACEHOLDER
            {
                coords[body.0][idx] = Source::Fixed(value);
                eliminated.insert(first_constraint + k);
            }
        }
        for (k, d) in mech.drivers.iter().enumerate() {
            if let DriverTarget::Absolute { body, coordinate } = d.target {
                let idx = match coordinate {
                    DriverCoordinate::X => 0,
                    DriverCoordinate::Y => 1,
                    DriverCoordinate::Z => 2,
                    _ => continue,
                };
                if coords[body.0][idx] == PLACEHOLDER {
                    let s = self.law(k, &d.law);
                    let (sd, sdd) = match self.input_of[k] {
                        Some(i) => (self.pool.var(Var::Sd(i)), self.pool.var(Var::Sdd(i))),
                        None => {
                            let sd = self.pool.diff(s, Var::T);
                            (sd, self.pool.diff(sd, Var::T))
                        }
                    };
                    coords[body.0][idx] = Source::Driven(self.laws.len());
                    self.laws.push([s, sd, sdd]);
                    eliminated.insert(first_driver + k);
                }
            }
        }
        (coords, eliminated)
    }

    /// Φ of every row in the generic engine's order: joints, constraints, drivers,
    /// normalisations.
    fn phi(&mut self, mech: &Mechanism) -> Vec<ExprId> {
        let mut phi_all = Vec::with_capacity(mech.equations());
        for j in &mech.joints {
            phi_all.extend(self.joint_rows(j));
        }
        for c in &mech.constraints {
            let e = self.constraint_row(c);
            phi_all.push(e);
        }
        for (k, d) in mech.drivers.iter().enumerate() {
            let e = self.driver_row(k, d, mech);
            phi_all.push(e);
        }
        for b in mech.moving_bodies() {
            let terms: Vec<ExprId> = (3..7)
                .map(|c| {
                    let e = self.coordinate(b, c);
                    self.pool.mul(e, e)
                })
                .collect();
            let s = self.pool.sum(terms);
            let one = self.pool.constant(1.0);
            phi_all.push(self.pool.sub(s, one));
        }
        phi_all
    }

    /// A constraint's row: `q_b[c] − value` or `q_i[c] − q_j[c] − value`.
    fn constraint_row(&mut self, c: &Constraint) -> ExprId {
        match c.kind {
            ConstraintKind::Fix { body, coordinate, value } => {
                let q = self.coordinate(body, coordinate.index());
                let v = self.pool.constant(value);
                self.pool.sub(q, v)
            }
            ConstraintKind::CoordinateDifference { body_i, body_j, coordinate, value } => {
                let qi = self.coordinate(body_i, coordinate.index());
                let qj = self.coordinate(body_j, coordinate.index());
                let v = self.pool.constant(value);
                let d = self.pool.sub(qi, qj);
                self.pool.sub(d, v)
            }
        }
    }

    /// A driver's row: the joint angle's x sin s − y cos s, the axial position − s, or an
    /// absolute coordinate's row.
    fn driver_row(&mut self, k: usize, d: &Driver, mech: &Mechanism) -> ExprId {
        let s = self.law(k, &d.law);
        match d.target {
            DriverTarget::Point { point, axis } => {
                let pt = &mech.points[point.0];
                let r = self.point(pt.body, &pt.local);
                self.pool.sub(r[axis], s)
            }
            DriverTarget::Joint { joint, motion } => {
                let j = &mech.joints[joint.0];
                match motion {
                    Motion::Rotation => {
                        let (x, y) = self.joint_angle(j);
                        self.angle_residual(x, y, s)
                    }
                    Motion::Translation => {
                        let ax = self.axial_position(j);
                        self.pool.sub(ax, s)
                    }
                }
            }
            DriverTarget::Leg(leg) => self.leg_row(&leg, s),
            DriverTarget::Absolute { body, coordinate } => {
                let k = crate::generic::absolute_index(coordinate);
                let q = self.coordinate(body, k);
                let rotation = matches!(
                    coordinate,
                    DriverCoordinate::Rx | DriverCoordinate::Ry | DriverCoordinate::Rz
                );
                if !rotation {
                    // x, y, z, e1, e2, e3: q_b[c] − s.
                    self.pool.sub(q, s)
                } else {
                    // e_k cos(s/2) − e0 sin(s/2) (thesis eq. 4.62, one-equation form).
                    let half = self.pool.constant(0.5);
                    let hs = self.pool.mul(half, s);
                    let (sin, cos) = (self.pool.sin(hs), self.pool.cos(hs));
                    let e0 = self.coordinate(body, 3);
                    let a = self.pool.mul(q, cos);
                    let b = self.pool.mul(e0, sin);
                    self.pool.sub(a, b)
                }
            }
        }
    }

    /// The rows of one joint, in the order of [`crate::model::JointSpec::rows`]; one
    /// method per type below, as in `generic`.
    fn joint_rows(&mut self, j: &Joint) -> Vec<ExprId> {
        let v = self.joint_vectors(j);
        let rows = match j.kind {
            JointKind::Spherical => self.spherical(&v),
            JointKind::Universal => self.universal(&v),
            JointKind::Revolute => self.revolute(&v),
            JointKind::Cylindrical => self.cylindrical(&v),
            JointKind::Prismatic => self.prismatic(&v, j),
            JointKind::Screw { lead, d0, theta0 } => self.screw(&v, j, lead, d0, theta0),
            JointKind::Distance { length } => self.distance(&v, length),
        };
        debug_assert_eq!(rows.len(), j.kind.equations());
        rows
    }

    /// d, the axes and the normals of a joint, written into the pool in that order.
    fn joint_vectors(&mut self, j: &Joint) -> JointVectors {
        let d = self.separation(j);
        let axes = j.axis.map(|(ai, aj)| (self.vector(j.body_i, &ai), self.vector(j.body_j, &aj)));
        let normals =
            j.normals().map(|(b, c)| (self.vector(j.body_i, &b), self.vector(j.body_i, &c)));
        JointVectors { d, axes, normals }
    }

    /// d = 0: the joint points coincide.
    fn coincident(v: &JointVectors) -> Vec<ExprId> {
        v.d.to_vec()
    }

    /// b_i·a_j = 0, c_i·a_j = 0: the axes are parallel.
    fn parallel(&mut self, v: &JointVectors) -> Vec<ExprId> {
        let (_, aj) = v.axes();
        let (b, c) = v.normals();
        vec![self.dot(b, aj), self.dot(c, aj)]
    }

    /// Spherical: d = 0.
    fn spherical(&mut self, v: &JointVectors) -> Vec<ExprId> {
        Self::coincident(v)
    }

    /// Universal: d = 0; a_i·a_j = 0.
    fn universal(&mut self, v: &JointVectors) -> Vec<ExprId> {
        let (ai, aj) = v.axes();
        let mut rows = Self::coincident(v);
        rows.push(self.dot(ai, aj));
        rows
    }

    /// Revolute: d = 0; axes parallel.
    fn revolute(&mut self, v: &JointVectors) -> Vec<ExprId> {
        let mut rows = Self::coincident(v);
        rows.extend(self.parallel(v));
        rows
    }

    /// Cylindrical: axes parallel; b_i·d = 0, c_i·d = 0.
    fn cylindrical(&mut self, v: &JointVectors) -> Vec<ExprId> {
        let (b, c) = v.normals();
        let mut rows = self.parallel(v);
        rows.push(self.dot(b, &v.d));
        rows.push(self.dot(c, &v.d));
        rows
    }

    /// Prismatic: cylindrical; ref_i·ref_j = 0.
    fn prismatic(&mut self, v: &JointVectors, j: &Joint) -> Vec<ExprId> {
        let mut rows = self.cylindrical(v);
        let (ri, rj) = j.reference.expect("validated: prismatic has references");
        let (ri, rj) = (self.vector(j.body_i, &ri), self.vector(j.body_j, &rj));
        rows.push(self.dot(&ri, &rj));
        rows
    }

    /// Screw: cylindrical; x sin φ − y cos φ = 0 with φ = θ0 + 2π (d·a_i − d0)/lead.
    fn screw(
        &mut self,
        v: &JointVectors,
        j: &Joint,
        lead: f64,
        d0: f64,
        theta0: f64,
    ) -> Vec<ExprId> {
        let mut rows = self.cylindrical(v);
        let (x, y) = self.joint_angle(j);
        let ax = self.axial_position(j);
        let d0 = self.pool.constant(d0);
        let k = self.pool.constant(2.0 * std::f64::consts::PI / lead);
        let th0 = self.pool.constant(theta0);
        let dd = self.pool.sub(ax, d0);
        let kd = self.pool.mul(k, dd);
        let phi = self.pool.add(kd, th0);
        rows.push(self.angle_residual(x, y, phi));
        rows
    }

    /// Distance: (d·d − L²)/(2L) = 0.
    fn distance(&mut self, v: &JointVectors, length: f64) -> Vec<ExprId> {
        let dd = self.dot(&v.d, &v.d);
        let l2 = self.pool.constant(length * length);
        let diff = self.pool.sub(dd, l2);
        let half = self.pool.constant(0.5 / length);
        vec![self.pool.mul(half, diff)]
    }
}

/// A coordinate not yet assigned a source while the system is laid out.
const PLACEHOLDER: Source = Source::Unknown(usize::MAX);

/// Numbers the coordinates still [`PLACEHOLDER`] as the reduced unknowns, body by body.
fn number_unknowns(coords: &mut [[Source; 7]]) -> Vec<(BodyId, usize)> {
    let mut unknowns = Vec::new();
    for (b, c) in coords.iter_mut().enumerate() {
        for (i, s) in c.iter_mut().enumerate() {
            if *s == PLACEHOLDER {
                *s = Source::Unknown(unknowns.len());
                unknowns.push((BodyId(b), i));
            }
        }
    }
    unknowns
}

/// The global vectors of one joint that its rows combine, as expressions.
struct JointVectors {
    /// d = P_j − P_i.
    d: V3,
    /// (a_i, a_j), the axes, for the types that have them.
    axes: Option<(V3, V3)>,
    /// (b_i, c_i), the body-i unit vectors ⟂ axis_i.
    normals: Option<(V3, V3)>,
}

impl JointVectors {
    fn axes(&self) -> &(V3, V3) {
        self.axes.as_ref().expect("validated: joint has axes")
    }

    fn normals(&self) -> &(V3, V3) {
        self.normals.as_ref().expect("validated: joint has axes")
    }
}

/// What the generator refuses.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GenerateError {
    /// A sentence naming the entities involved.
    pub message: String,
}

impl std::fmt::Display for GenerateError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for GenerateError {}

impl Symbolic {
    /// The substituted coordinates' values, rates and accelerations ([`Source::Derived`]), in
    /// order: what the outputs of an explicit chain share (see `emit::function`).
    #[must_use]
    pub fn derived_nodes(&self) -> Vec<ExprId> {
        self.derived.iter().flat_map(|d| d.value).collect()
    }

    /// Builds the reduced system of `mech`: [`Symbolic::build_full`], then, unless rows are
    /// dropped as dependent, with the closed-form blocks substituted (`substitute`): Newton
    /// runs on the remaining unknowns only, whole or block by block.
    ///
    /// # Errors
    /// When the reduced system is not square with full rank at the initial configuration
    /// (an undriven degree of freedom, or a coordinate fixed twice).
    pub fn build(mech: &Mechanism) -> Result<Self, GenerateError> {
        let (full, q) = Self::build_with(mech, ExprPool::new(), &[])?;
        // Rows left out as dependent are checked and re-selected at run time against the whole
        // system's (`Symbolic::dropped`): such a system is left whole. Systems with U-P-S legs
        // reduced to distance rows (`legs`) are substituted too: the rebuilt system reduces its
        // legs again, on the substituted coordinates (see `substitute`).
        if !full.dropped.is_empty() {
            return Ok(full);
        }
        Ok(full.substituted(mech, &q))
    }

    /// Builds the reduced system of `mech` with every closed-form block left to Newton (the
    /// block structure `check` reports, and the system a block-by-block solver runs).
    ///
    /// # Errors
    /// As [`Symbolic::build`].
    pub fn build_full(mech: &Mechanism) -> Result<Self, GenerateError> {
        Self::build_with(mech, ExprPool::new(), &[]).map(|(sys, _)| sys)
    }

    /// Builds the reduced system of `mech` in `pool` with the coordinates of `derived`
    /// substituted (their values in the numbering of the unknowns that remain, their rows
    /// eliminated); returns it with the assembled initial configuration.
    fn build_with(
        mech: &Mechanism,
        pool: ExprPool,
        derived: &[Substitution],
    ) -> Result<(Self, Vec<f64>), GenerateError> {
        let labels = mech.row_labels();
        let inputs = input_drivers(mech);
        let mut input_of = vec![None; mech.drivers.len()];
        for (i, d) in inputs.iter().enumerate() {
            input_of[d.driver] = Some(u32::try_from(i).expect("fewer than 2³² drivers"));
        }
        let mut builder = Builder {
            pool,
            coords: Vec::new(),
            laws: Vec::new(),
            input_of,
            derived: derived.iter().map(|d| d.value).collect(),
        };
        let (mut coords, mut eliminated) = builder.eliminate(mech);
        for (i, d) in derived.iter().enumerate() {
            coords[d.body.0][d.coordinate] = Source::Derived(i);
            for label in &d.rows {
                eliminated.insert(labels.iter().position(|l| l == label).expect("a row of mech"));
            }
        }
        let unknowns = number_unknowns(&mut coords);
        builder.coords = coords;
        // Φ for every row, eliminated ones included, in the generic engine's order.
        let phi_all = builder.phi(mech);
        debug_assert_eq!(phi_all.len(), labels.len());
        let kept: Vec<usize> = (0..labels.len()).filter(|k| !eliminated.contains(k)).collect();
        let derived = derived
            .iter()
            .map(|d| {
                let rate = builder.pool.rate(d.value);
                let acceleration = outputs::acceleration(&mut builder.pool, rate);
                Derived {
                    body: d.body,
                    coordinate: d.coordinate,
                    value: [d.value, rate, acceleration],
                    torn: d.torn,
                }
            })
            .collect();
        let mut sys = Self {
            pool: builder.pool,
            coords: builder.coords,
            unknowns,
            rows: Vec::new(),
            eliminated: eliminated.iter().map(|&k| labels[k].clone()).collect(),
            redundant: Vec::new(),
            dropped: Vec::new(),
            row_factors: Vec::new(),
            phi: Vec::new(),
            jac: Vec::new(),
            nu: Vec::new(),
            gamma: Vec::new(),
            laws: builder.laws,
            inputs,
            legs: Vec::new(),
            derived,
        };
        let q = sys.keep_independent(mech, &labels, &kept, &phi_all);
        let n = sys.unknowns.len();
        if sys.rows.len() != n {
            return Err(GenerateError {
                message: format!(
                    "the reduced system has {} independent equations for {n} unknowns at the \
                     initial configuration: a degree of freedom is not driven or a coordinate \
                     is held twice",
                    sys.rows.len()
                ),
            });
        }
        sys.reduce_legs(mech, &q, builder.input_of);
        sys.derive_rates();
        Ok((sys, q))
    }

    /// Keeps the rows `kept` (indices into `labels` and `phi_all`) that do not depend on the
    /// others, with their Jacobian rows; the others become `redundant`. Returns the assembled
    /// initial configuration (reduced unknowns) the choice was made at.
    fn keep_independent(
        &mut self,
        mech: &Mechanism,
        labels: &[RowLabel],
        kept: &[usize],
        phi_all: &[ExprId],
    ) -> Vec<f64> {
        let mut jac_rows = Vec::with_capacity(kept.len());
        for &k in kept {
            jac_rows.push(self.jacobian_row(phi_all[k]));
        }
        let kept_phi: Vec<ExprId> = kept.iter().map(|&k| phi_all[k]).collect();
        let normalisation: Vec<bool> = kept.iter().map(|&k| labels[k].is_normalisation()).collect();
        let (independent, q) = self.independent_rows(mech, &kept_phi, &jac_rows, &normalisation);
        let factors = self.row_factors_at(mech, &jac_rows, &q);
        for (pos, &k) in kept.iter().enumerate() {
            if independent.contains(&pos) {
                self.rows.push(labels[k].clone());
                self.phi.push(phi_all[k]);
                self.jac.push(std::mem::take(&mut jac_rows[pos]));
                self.row_factors.push(factors[pos]);
            } else {
                let phi = phi_all[k];
                let rate = self.pool.rate(phi);
                let acceleration = outputs::acceleration(&mut self.pool, rate);
                let residuals = [phi, rate, acceleration];
                // Its rates are derived with the kept rows' (`derive_rates`).
                self.dropped.push(Dropped {
                    label: labels[k].clone(),
                    residuals,
                    factor: factors[pos],
                    jac: std::mem::take(&mut jac_rows[pos]),
                    rates: [phi, phi],
                });
            }
        }
        // The names: the shared rule on the whole Φ_q at the same configuration.
        let eq = Equations::new(mech);
        let n = q.len();
        let zero = vec![0.0; n];
        let [full, _, _] = self.expand(&eq, &q, &zero, &zero, mech.time.start);
        self.redundant = eq
            .redundant_rows(&full, mech.time.start)
            .into_iter()
            .map(|k| labels[k].clone())
            .collect();
        q
    }

    /// The balanced-unit factor of every row of `jac_rows` at the reduced configuration `q`
    /// (see [`Symbolic::row_factors`]).
    fn row_factors_at(
        &self,
        mech: &Mechanism,
        jac_rows: &[Vec<(usize, ExprId)>],
        q: &[f64],
    ) -> Vec<f64> {
        let t = mech.time.start;
        let u = self.planning_inputs(t);
        let roots: Vec<ExprId> = jac_rows.iter().flatten().map(|&(_, e)| e).collect();
        let mut it = self.pool.eval_inputs(&roots, [q, &[], &[]], t, &u).into_iter();
        let rows: SparseRows = jac_rows
            .iter()
            .map(|row| row.iter().map(|&(c, _)| (c, it.next().expect("one value"))).collect())
            .collect();
        self.balanced(rows, mech)
            .iter()
            .map(|row| {
                let big = row.iter().fold(0.0_f64, |m, &(_, x)| m.max(x.abs()));
                if big > 0.0 && big.is_finite() {
                    1.0 / crate::generic::scaling::power_of_two(big)
                } else {
                    1.0
                }
            })
            .collect()
    }

    /// The structurally non-zero entries of ∂e/∂q.
    fn jacobian_row(&mut self, e: ExprId) -> Vec<(usize, ExprId)> {
        let vars = q_vars(&self.pool, e);
        let mut row = Vec::new();
        for k in vars {
            let d = self.pool.diff(e, Var::Q(k));
            if self.pool.as_const(d) != Some(0.0) {
                row.push((k as usize, d));
            }
        }
        row
    }

    /// Rows (positions in `jac_rows`) kept after dropping those that depend on the others
    /// at the assembled initial configuration (greedy, normalisations first, the rule of
    /// `generic::redundancy`), and that configuration (reduced unknowns).
    ///
    /// The reduced system is assembled first by Newton–Raphson on its independent rows
    /// (sparse, see [`independent`]); when that does not converge, the generic engine's
    /// Gauss–Newton assembly (`Equations::prepare`, dense, with the SVD) decides instead.
    fn independent_rows(
        &self,
        mech: &Mechanism,
        phi: &[ExprId],
        jac_rows: &[Vec<(usize, ExprId)>],
        normalisation: &[bool],
    ) -> (BTreeSet<usize>, Vec<f64>) {
        let t = mech.time.start;
        let u = self.planning_inputs(t);
        let at = |q: &[f64]| -> SparseRows {
            let roots: Vec<ExprId> = jac_rows.iter().flatten().map(|&(_, e)| e).collect();
            let mut it = self.pool.eval_inputs(&roots, [q, &[], &[]], t, &u).into_iter();
            jac_rows
                .iter()
                .map(|row| row.iter().map(|&(c, _)| (c, it.next().expect("one value"))).collect())
                .collect()
        };
        let q = self.assemble(mech, phi, jac_rows, &at).unwrap_or_else(|| {
            // The generic engine's dense assembly as a fall-back.
            let eq = Equations::new(mech);
            let prep = eq.prepare();
            self.reduce(&eq, &prep.q).as_slice().to_vec()
        });
        (independent(&self.balanced(at(&q), mech), self.unknowns.len(), normalisation), q)
    }

    /// Sparse rows of Φ_q with the translational columns times the mechanism's characteristic
    /// length, so that the redundancy test, relative to each row, does not depend on the unit
    /// of length (`generic::scaling`).
    fn balanced(&self, mut rows: SparseRows, mech: &Mechanism) -> SparseRows {
        let l = crate::generic::scaling::length_scale(mech);
        for row in &mut rows {
            for (c, x) in row.iter_mut() {
                if self.unknowns[*c].1 < 3 {
                    *x *= l;
                }
            }
        }
        rows
    }

    /// Newton–Raphson at the first time point on the rows independent at the current
    /// configuration, from the initial estimates; `None` when those rows are not square or
    /// Newton does not reach the description's tolerance.
    fn assemble(
        &self,
        mech: &Mechanism,
        phi: &[ExprId],
        jac_rows: &[Vec<(usize, ExprId)>],
        at: &dyn Fn(&[f64]) -> SparseRows,
    ) -> Option<Vec<f64>> {
        let n = self.unknowns.len();
        let t = mech.time.start;
        let mut q = self.initial_estimate(mech);
        let u = self.planning_inputs(t);
        for _ in 0..mech.solver.max_iterations.max(50) {
            let res = self.pool.eval_inputs(phi, [&q, &[], &[]], t, &u);
            if !res.iter().all(|x| x.is_finite()) {
                return None;
            }
            if res.iter().all(|x| x.abs() <= mech.solver.tolerance) {
                return Some(q);
            }
            let jac = at(&q);
            let rows: Vec<usize> =
                independent(&self.balanced(jac.clone(), mech), n, &[]).into_iter().collect();
            if rows.len() != n || jac_rows.len() < n {
                return None;
            }
            let s: Vec<Vec<bool>> = rows
                .iter()
                .map(|&r| {
                    let mut v = vec![false; n];
                    jac[r].iter().for_each(|&(c, _)| v[c] = true);
                    v
                })
                .collect();
            let a: Vec<Vec<f64>> = rows
                .iter()
                .map(|&r| {
                    let mut v = vec![0.0; n];
                    jac[r].iter().for_each(|&(c, x)| v[c] = x);
                    v
                })
                .collect();
            let b: Vec<f64> = rows.iter().map(|&r| res[r]).collect();
            let dq = crate::pivot::solve(&s, &a, &b)?;
            for (x, d) in q.iter_mut().zip(&dq) {
                *x -= d;
            }
        }
        None
    }

    /// The initial estimates of the reduced unknowns.
    #[must_use]
    pub fn initial_estimate(&self, mech: &Mechanism) -> Vec<f64> {
        self.unknowns
            .iter()
            .map(|&(b, c)| {
                let body = &mech.bodies[b.0];
                if c < 3 { body.r[c] } else { body.p[c - 3] }
            })
            .collect()
    }

    /// The reduced unknowns taken from a full coordinate vector of the generic engine.
    #[must_use]
    pub fn reduce(&self, eq: &Equations<'_>, full: &DVector<f64>) -> DVector<f64> {
        DVector::from_iterator(
            self.unknowns.len(),
            self.unknowns.iter().map(|&(b, c)| full[eq.offset(b).expect("moving body") + c]),
        )
    }

    /// Rescales the unknown Euler parameters of every body so that |p| = 1 given its fixed
    /// ones (what the generated `normalize` does).
    pub fn normalise(&self, q: &mut [f64]) {
        for c in &self.coords {
            let (mut fixed, mut free) = (0.0, 0.0);
            for s in &c[3..] {
                match *s {
                    Source::Unknown(k) => free += q[k] * q[k],
                    Source::Fixed(v) => fixed += v * v,
                    // A body's substituted Euler parameters are all four of them, or two that
                    // vanish beside unknown ones (`substitute`): either way they add nothing.
                    Source::Driven(_) | Source::Derived(_) => {}
                }
            }
            if free > 0.0 && fixed < 1.0 && c[3..].iter().any(|s| matches!(s, Source::Unknown(_))) {
                let scale = ((1.0 - fixed) / free).sqrt();
                for s in &c[3..] {
                    if let Source::Unknown(k) = *s {
                        q[k] *= scale;
                    }
                }
            }
        }
    }

    /// Full coordinates, rates and accelerations of the moving bodies in the generic
    /// engine's layout, from reduced ones.
    #[must_use]
    pub fn expand(
        &self,
        eq: &Equations<'_>,
        q: &[f64],
        qd: &[f64],
        qdd: &[f64],
        t: f64,
    ) -> [DVector<f64>; 3] {
        let n = eq.unknowns();
        let mut out = [DVector::zeros(n), DVector::zeros(n), DVector::zeros(n)];
        let roots: Vec<ExprId> = self.laws.iter().flatten().copied().collect();
        let inputs: Vec<[f64; 3]> = self
            .inputs
            .iter()
            .map(|d| {
                let (s, sd, sdd) = eq.driver_value(d.driver, t);
                [s, sd, sdd]
            })
            .collect();
        let laws = self.pool.eval_inputs(&roots, [&[], &[], &[]], t, &inputs);
        let roots: Vec<ExprId> = self.derived.iter().flat_map(|d| d.value).collect();
        let derived = self.pool.eval_inputs(&roots, [q, qd, qdd], t, &inputs);
        for (b, c) in self.coords.iter().enumerate() {
            let Some(o) = eq.offset(BodyId(b)) else { continue };
            for (i, s) in c.iter().enumerate() {
                let v = match *s {
                    Source::Unknown(k) => [q[k], qd[k], qdd[k]],
                    Source::Fixed(v) => [v, 0.0, 0.0],
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

    /// The inputs `[s, ṡ, s̈]` at `t` of the generator's own walks over the `[time]` grid
    /// (see [`InputDriver::sweep`]).
    #[must_use]
    pub fn planning_inputs(&self, t: f64) -> Vec<[f64; 3]> {
        self.inputs.iter().map(|d| [d.initial + d.sweep * (t - d.start), d.sweep, 0.0]).collect()
    }

    /// ν and γ from Φ.
    fn derive_rates(&mut self) {
        let phi: Vec<ExprId> = self.phi.clone();
        for phi in phi {
            let [nu, gamma] = self.rates_of(phi);
            self.nu.push(nu);
            self.gamma.push(gamma);
        }
        for k in 0..self.dropped.len() {
            self.dropped[k].rates = self.rates_of(self.dropped[k].residuals[0]);
        }
    }

    /// ν = −Φ_t and γ of the row Φ_i = `phi`.
    fn rates_of(&mut self, phi: ExprId) -> [ExprId; 2] {
        let t = Var::T;
        let inputs = u32::try_from(self.inputs.len()).expect("fewer than 2³² inputs");
        // Φ_t = ∂Φ/∂t + Σ_k ∂Φ/∂s_k ṡ_k: the inputs move with time too.
        let mut phi_t = self.pool.diff(phi, t);
        for k in 0..inputs {
            let d = self.pool.diff(phi, Var::S(k));
            if self.pool.as_const(d) != Some(0.0) {
                let sd = self.pool.var(Var::Sd(k));
                let term = self.pool.mul(d, sd);
                phi_t = self.pool.add(phi_t, term);
            }
        }
        let nu = self.pool.neg(phi_t);
        // Φ̇ = Φ_q q̇ + Φ_t and Φ̈* = (Φ_q q̇)_q q̇ + 2 Φ_qt q̇ + Φ_tt (q̈ = 0), both by
        // forward-mode differentiation along the motion; γ = −Φ̈*.
        let phi_dot = self.pool.rate(phi);
        let s = self.pool.rate(phi_dot);
        [nu, self.pool.neg(s)]
    }
}

/// The input drivers of `mech`, with the value each prescribes at the initial estimates.
fn input_drivers(mech: &Mechanism) -> Vec<InputDriver> {
    if mech.drivers.iter().all(|d| d.law != Law::Input) {
        return Vec::new();
    }
    let eq = Equations::new(mech);
    let grid = mech.time.declared();
    let span = grid.step * grid.count.saturating_sub(1) as f64;
    mech.drivers
        .iter()
        .enumerate()
        .filter(|(_, d)| d.law == Law::Input)
        .map(|(k, d)| {
            let rotation = matches!(
                d.target,
                DriverTarget::Joint { motion: Motion::Rotation, .. }
                    | DriverTarget::Absolute {
                        coordinate: DriverCoordinate::Rx
                            | DriverCoordinate::Ry
                            | DriverCoordinate::Rz,
                        ..
                    }
            );
            let sweep = if rotation && span > 0.0 { std::f64::consts::TAU / span } else { 0.0 };
            InputDriver { driver: k, initial: eq.held(k), sweep, start: grid.start }
        })
        .collect()
}

/// The unknowns q_k an expression depends on, in increasing k.
fn q_vars(pool: &ExprPool, e: ExprId) -> BTreeSet<u32> {
    vars_of(pool, e, |v| match v {
        Var::Q(k) => Some(k),
        _ => None,
    })
}

/// The indices `pick` returns for the variables an expression depends on, in increasing order.
fn vars_of(pool: &ExprPool, e: ExprId, pick: impl Fn(Var) -> Option<u32>) -> BTreeSet<u32> {
    let mut seen = vec![false; e.index() + 1];
    let mut stack = vec![e];
    let mut vars = BTreeSet::new();
    while let Some(x) = stack.pop() {
        if std::mem::replace(&mut seen[x.index()], true) {
            continue;
        }
        match pool[x] {
            Node::Var(v) => vars.extend(pick(v)),
            node => stack.extend(node.children()),
        }
    }
    vars
}

mod legs;
mod outputs;
mod substitute;
pub use legs::ReducedLeg;
pub use outputs::{JointCoordinate, Outputs, Rates};
pub use substitute::Derived;
use substitute::Substitution;

#[cfg(test)]
mod tests;
