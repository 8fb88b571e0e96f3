//! The generated module's named outputs as expressions in the same arena as Φ: every point of
//! interest's r, v, a, every moving body's ω and α, and every joint coordinate with its rates.
//!
//! Positions are written with the builder that writes Φ (so a point is r + A(p) s' exactly as
//! in the joint rows); rates come from `ExprPool::rate` (q ↦ q̇, t ↦ 1, the drivers' laws
//! differentiated through) and accelerations from [`Outputs`]'s rule
//! ë = (ė)˙|_{q̈=0} + Σ_k ∂ė/∂q̇_k q̈_k, so q̈ enters only through `Var::Qdd`.

use std::collections::BTreeSet;

use super::{Builder, Symbolic, V3};
use crate::expr::{ExprId, ExprPool, Var};
use crate::model::{BodyId, JointKind, Mechanism};

/// Value, rate and acceleration of one scalar output.
pub type Rates = [ExprId; 3];

/// A joint coordinate of the output list (contract §5).
#[derive(Clone, Copy, Debug)]
pub enum JointCoordinate {
    /// θ from ref_i to ref_j about axis_i, as x = ref_i·ref_j and y = (ref_i × ref_j)·axis_i
    /// with their rates: θ = atan2(y, x) is finished in the emitted code.
    Angle {
        /// x, ẋ, ẍ.
        x: Rates,
        /// y, ẏ, ÿ.
        y: Rates,
    },
    /// d = (P_j − P_i)·axis_i, ḋ, d̈.
    Translation(Rates),
}

/// The outputs of one mechanism.
#[derive(Clone, Debug)]
pub struct Outputs {
    /// For every point of interest (in the description's order): r, v and a.
    pub points: Vec<[V3; 3]>,
    /// For every moving body (in the order of `BODY_NAMES`): ω = 2 G ṗ and α = 2 G p̈, global.
    pub bodies: Vec<[V3; 2]>,
    /// For every moving body: its coordinates `[x, y, z, e0, e1, e2, e3]` (unknown, fixed or
    /// driven).
    pub poses: Vec<[ExprId; 7]>,
    /// The joint coordinates: joint index, `"angle"` or `"translation"`, the expressions.
    pub joints: Vec<(usize, &'static str, JointCoordinate)>,
}

impl Symbolic {
    /// Writes the outputs of `mech` into the pool.
    #[must_use]
    pub fn outputs(&mut self, mech: &Mechanism) -> Outputs {
        let mut b = Builder {
            pool: std::mem::take(&mut self.pool),
            coords: self.coords.clone(),
            laws: self.laws.clone(),
            // Outputs read coordinates only: no driver law is written here.
            input_of: Vec::new(),
            derived: self.derived.iter().map(|d| d.value[0]).collect(),
        };
        let points = mech
            .points
            .iter()
            .map(|pt| {
                let r = b.point(pt.body, &pt.local);
                let v = r.map(|e| b.pool.rate(e));
                let a = v.map(|e| acceleration(&mut b.pool, e));
                [r, v, a]
            })
            .collect();
        let bodies = mech.moving_bodies().map(|body| b.angular(body)).collect();
        let poses = mech
            .moving_bodies()
            .map(|body| std::array::from_fn(|k| b.coordinate(body, k)))
            .collect();
        let mut joints = Vec::new();
        for (k, j) in mech.joints.iter().enumerate() {
            let angle = j.reference.is_some()
                && matches!(
                    j.kind,
                    JointKind::Revolute | JointKind::Cylindrical | JointKind::Screw { .. }
                );
            if angle {
                let (x, y) = b.joint_angle(j);
                let (x, y) = (b.rates(x), b.rates(y));
                joints.push((k, "angle", JointCoordinate::Angle { x, y }));
            }
            let translation = j.axis.is_some()
                && matches!(
                    j.kind,
                    JointKind::Prismatic | JointKind::Cylindrical | JointKind::Screw { .. }
                );
            if translation {
                let d = b.axial_position(j);
                joints.push((k, "translation", JointCoordinate::Translation(b.rates(d))));
            }
        }
        self.pool = b.pool;
        Outputs { points, bodies, poses, joints }
    }
}

impl Builder {
    /// e, ė, ë.
    fn rates(&mut self, e: ExprId) -> Rates {
        let v = self.pool.rate(e);
        [e, v, acceleration(&mut self.pool, v)]
    }

    /// ω = 2 G(p) ṗ and α = 2 G(p) p̈ (G = [−e, e0 I + ẽ], e = (e1, e2, e3)), global.
    fn angular(&mut self, body: BodyId) -> [V3; 2] {
        let p: [ExprId; 4] = std::array::from_fn(|k| self.coordinate(body, 3 + k));
        let pd = p.map(|e| self.pool.rate(e));
        let pdd = pd.map(|e| acceleration(&mut self.pool, e));
        [self.two_g(&p, &pd), self.two_g(&p, &pdd)]
    }

    /// 2 G(p) u for a 4-vector u: 2 (−e u0 + e0 u⃗ + e × u⃗).
    fn two_g(&mut self, p: &[ExprId; 4], u: &[ExprId; 4]) -> V3 {
        let e = [p[1], p[2], p[3]];
        let w = [u[1], u[2], u[3]];
        let cross = self.cross(&e, &w);
        let two = self.pool.constant(2.0);
        std::array::from_fn(|k| {
            let a = self.pool.mul(e[k], u[0]);
            let b = self.pool.mul(p[0], w[k]);
            let s = self.pool.sub(b, a);
            let s = self.pool.add(s, cross[k]);
            self.pool.mul(two, s)
        })
    }
}

/// The time derivative of a rate expression `v` (in q, q̇ and t): its rate at q̈ = 0 plus
/// Σ_k ∂v/∂q̇_k q̈_k.
pub(super) fn acceleration(pool: &mut ExprPool, v: ExprId) -> ExprId {
    let mut a = pool.rate(v);
    for k in qd_vars(pool, v) {
        let d = pool.diff(v, Var::Qd(k));
        let qdd = pool.var(Var::Qdd(k));
        let term = pool.mul(d, qdd);
        a = pool.add(a, term);
    }
    a
}

/// The rates q̇_k an expression depends on, in increasing k.
fn qd_vars(pool: &ExprPool, e: ExprId) -> BTreeSet<u32> {
    super::vars_of(pool, e, |v| match v {
        Var::Qd(k) => Some(k),
        _ => None,
    })
}
