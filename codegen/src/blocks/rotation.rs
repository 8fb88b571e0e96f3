//! A body's orientation set by a driven rotation about a joint axis to a known body: a block of
//! four Euler parameters with a closed form (`runtime::rotation`).
//!
//! The block's rows are body j's normalisation, the two parallel-axis rows of a revolute or
//! cylindrical joint between j and a body k whose Euler parameters are known (earlier blocks or
//! constants), and a rotation driver: the joint's angle, or an absolute rx, ry or rz of j. The
//! parallel rows and the normalisation leave the family
//!
//! e_j(φ) = cos(φ/2) u + sin(φ/2) w,  u = e_k ⊗ g,  w = e_k ⊗ h,
//! g = f_k ⊗ f_j*,  h = f_k ⊗ (0, 0, 0, 1) ⊗ f_j*,
//!
//! where f_k turns the z axis onto k's joint axis and f_j onto σ times j's, σ = ±1 the sign of
//! a_j · a_k at the initial estimates (the parallel rows hold for either). The driver's row is a
//! homogeneous quadratic in (cos φ/2, sin φ/2) for a joint angle (x and y are quadratic forms
//! in e_j; where j is the joint's body i the row involves j's axis too and is (c² + s′²) times
//! that quadratic) and linear for an absolute rotation, so its three (or two) values at the
//! unit points u, w and (u + w)/√2, emitted from the row itself with e_j replaced, determine it
//! on the unit circle; the runtime solves it. Evaluating the row rather than deriving formulas
//! per driver keeps one path for both drivers, any law or input, and whatever the joint's
//! references, and it cannot disagree with the equations the rest of the solver uses.
//! The recognition is checked numerically against the block's own rows at the initial
//! estimates before a block is called closed form: on the family the other three rows vanish
//! and the driver's row is the quadratic (or linear) form its values predict.

use std::collections::BTreeMap;

use nalgebra::{Quaternion, UnitQuaternion, Vector3, Vector4};

use crate::expr::{ExprId, ExprPool, Var};
use crate::model::frame::rotation;
use crate::model::{
    BodyId, DriverCoordinate, DriverTarget, JointKind, Mechanism, Motion, RowLabel,
};
use crate::symbolic::{Source, Symbolic};

/// A block of four Euler parameters with a closed form (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rotation {
    /// The body whose Euler parameters the block solves.
    pub body: BodyId,
    /// The body across the joint, known when the block is solved.
    pub known: BodyId,
    /// The joint: an index into the mechanism's joints.
    pub joint: usize,
    /// The driver's row: an index into [`Symbolic::rows`].
    pub driver_row: usize,
    /// Whether the driver is an absolute rotation (its row linear in e_j) rather than the
    /// joint's angle (quadratic).
    pub linear: bool,
    /// Whether j's axis points against k's at the initial estimates (σ = −1).
    pub flipped: bool,
}

/// The Hamilton product a ⊗ b of Euler parameters [e0, e1, e2, e3].
fn product(a: Vector4<f64>, b: Vector4<f64>) -> Vector4<f64> {
    parameters(quaternion(a) * quaternion(b))
}

/// e ⊗ (0, a): Euler parameters times a pure vector.
#[must_use]
pub(crate) fn product_with_vector(e: Vector4<f64>, a: &Vector3<f64>) -> Vector4<f64> {
    product(e, Vector4::new(0.0, a.x, a.y, a.z))
}

fn quaternion(p: Vector4<f64>) -> Quaternion<f64> {
    Quaternion::new(p[0], p[1], p[2], p[3])
}

fn parameters(q: Quaternion<f64>) -> Vector4<f64> {
    Vector4::new(q.w, q.i, q.j, q.k)
}

/// A unit quaternion turning the z axis onto the unit vector `a` (the shortest rotation), or a
/// half turn about x when `a` is −z.
fn onto(a: &Vector3<f64>) -> Quaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::z(), a)
        .unwrap_or_else(|| {
            UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
        })
        .into_inner()
}

impl Rotation {
    /// (g, h) of the module docs.
    fn frames(&self, mech: &Mechanism) -> (Vector4<f64>, Vector4<f64>) {
        let j = &mech.joints[self.joint];
        let (ai, aj) = j.axis.expect("a revolute or cylindrical joint has axes");
        let (a_known, mut a_body) = if j.body_i == self.known { (ai, aj) } else { (aj, ai) };
        if self.flipped {
            a_body = -a_body;
        }
        let (fk, fj) = (onto(&a_known), onto(&a_body));
        let g = fk * fj.conjugate();
        let h = fk * Quaternion::new(0.0, 0.0, 0.0, 1.0) * fj.conjugate();
        (parameters(g), parameters(h))
    }

    /// The first of the body's four consecutive unknowns e0 … e3.
    #[must_use]
    pub fn first_unknown(&self, sys: &Symbolic) -> usize {
        match sys.coords[self.body.0][3] {
            Source::Unknown(k) => k,
            _ => unreachable!("a rotation block's body has unknown Euler parameters"),
        }
    }

    /// The expressions of what `runtime::rotation::about_axis` reads, written into the pool:
    /// u, w, f(u), f(w) and, for a joint angle, f((u + w)/√2) (0 for an absolute rotation).
    pub fn coefficients(&self, sys: &mut Symbolic, mech: &Mechanism) -> [ExprId; 11] {
        let (g, h) = self.frames(mech);
        let known: [ExprId; 4] = std::array::from_fn(|c| match sys.coords[self.known.0][3 + c] {
            Source::Unknown(k) => sys.pool.var(Var::Q(u32::try_from(k).expect("small"))),
            Source::Fixed(v) => sys.pool.constant(v),
            Source::Driven(l) => sys.laws[l][0],
            Source::Derived(i) => sys.derived[i].value[0],
        });
        let pool = &mut sys.pool;
        let u = times(pool, &known, &g);
        let w = times(pool, &known, &h);
        let first = self.first_unknown(sys);
        let row = sys.phi[self.driver_row];
        let pool = &mut sys.pool;
        let at = |pool: &mut ExprPool, e: [ExprId; 4]| {
            let map: BTreeMap<Var, ExprId> =
                (0..4).map(|c| (Var::Q(u32::try_from(first + c).expect("small")), e[c])).collect();
            substitute(pool, row, &map)
        };
        let fu = at(pool, u);
        let fw = at(pool, w);
        let fuw = if self.linear {
            pool.constant(0.0)
        } else {
            let half = pool.constant(std::f64::consts::FRAC_1_SQRT_2);
            let mid: [ExprId; 4] = std::array::from_fn(|c| {
                let sum = pool.add(u[c], w[c]);
                pool.mul(half, sum)
            });
            at(pool, mid)
        };
        [u[0], u[1], u[2], u[3], w[0], w[1], w[2], w[3], fu, fw, fuw]
    }
}

/// e ⊗ c for a quaternion of expressions e and a constant one c.
fn times(pool: &mut ExprPool, e: &[ExprId; 4], c: &Vector4<f64>) -> [ExprId; 4] {
    // e ⊗ c = M(c) e with the right-multiplication matrix of c.
    let m = [
        [c[0], -c[1], -c[2], -c[3]],
        [c[1], c[0], c[3], -c[2]],
        [c[2], -c[3], c[0], c[1]],
        [c[3], c[2], -c[1], c[0]],
    ];
    // Entries within a few ulps of −1, 0 or 1 are those values up to the round-off of the
    // quaternion products that made c: exact, they fold (a single-precision module would
    // otherwise round −0.9999999999999998 to −1 and print a product by −1).
    let exact = |v: f64| if (v - v.round()).abs() <= 4.0 * f64::EPSILON { v.round() } else { v };
    std::array::from_fn(|r| {
        let terms: Vec<ExprId> = (0..4)
            .filter(|&k| exact(m[r][k]) != 0.0)
            .map(|k| {
                let v = pool.constant(exact(m[r][k]));
                pool.mul(v, e[k])
            })
            .collect();
        pool.sum(terms)
    })
}

/// `e` with the variables of `map` replaced by their expressions ([`ExprPool::substitute`]).
fn substitute(pool: &mut ExprPool, e: ExprId, map: &BTreeMap<Var, ExprId>) -> ExprId {
    pool.substitute(e, map)
}

/// The rotation block `rows` × `unknowns` is, if it is one (see the module docs).
#[must_use]
pub fn recognise(
    sys: &Symbolic,
    mech: &Mechanism,
    rows: &[usize],
    unknowns: &[usize],
) -> Option<Rotation> {
    let (body, first) = match unknowns {
        &[k, ..] if unknowns.len() == 4 => (sys.unknowns[k].0, k),
        _ => return None,
    };
    let consecutive = unknowns.iter().enumerate().all(|(c, &k)| sys.unknowns[k] == (body, 3 + c));
    if !consecutive || rows.len() != 4 || first + 3 != unknowns[3] {
        return None;
    }
    let labels: Vec<&RowLabel> = rows.iter().map(|&r| &sys.rows[r]).collect();
    let name = &mech.bodies[body.0].name;
    let normalisation = labels.iter().filter(|l| l.kind == RowLabel::BODY && &l.name == name);
    let parallel: Vec<usize> = labels
        .iter()
        .filter(|l| l.kind == RowLabel::JOINT)
        .map(|l| {
            let j = mech.joints.iter().position(|j| j.name == l.name)?;
            let first = match mech.joints[j].kind {
                JointKind::Revolute => 4,
                JointKind::Cylindrical => 1,
                _ => return None,
            };
            (l.row == first || l.row == first + 1).then_some(j)
        })
        .collect::<Option<_>>()?;
    let drivers: Vec<(usize, usize)> = rows
        .iter()
        .filter(|&&r| sys.rows[r].kind == RowLabel::DRIVER)
        .map(|&r| Some((r, mech.drivers.iter().position(|d| d.name == sys.rows[r].name)?)))
        .collect::<Option<_>>()?;
    let (&[joint, other], &[(driver_row, driver)]) = (parallel.as_slice(), drivers.as_slice())
    else {
        return None;
    };
    if normalisation.count() != 1 || joint != other {
        return None;
    }
    let j = &mech.joints[joint];
    let known = match (j.body_i, j.body_j) {
        (i, k) if k == body => i,
        (i, k) if i == body => k,
        _ => return None,
    };
    // A known body's substituted Euler parameters are expressions of the unknowns and t that
    // `holds` would have to evaluate along the motion: left to Newton.
    let moved = |s: &Source| matches!(s, Source::Driven(_) | Source::Derived(_));
    if known == body || sys.coords[known.0][3..].iter().any(moved) {
        return None;
    }
    let linear = match mech.drivers[driver].target {
        DriverTarget::Joint { joint: d, motion: Motion::Rotation } if d.0 == joint => false,
        DriverTarget::Absolute {
            body: b,
            coordinate: DriverCoordinate::Rx | DriverCoordinate::Ry | DriverCoordinate::Rz,
        } if b == body => true,
        _ => return None,
    };
    // The sign of j's axis against k's, from the initial estimates; refused when they are
    // too far from parallel to tell.
    let (ai, aj) = j.axis?;
    let (a_known, a_body) = if j.body_i == known { (ai, aj) } else { (aj, ai) };
    let pk = mech.bodies[known.0].p.normalize();
    let pj = mech.bodies[body.0].p.normalize();
    let alignment = (rotation(&pk) * a_known).dot(&(rotation(&pj) * a_body));
    if alignment.abs() < 0.5 {
        return None;
    }
    let rotation = Rotation { body, known, joint, driver_row, linear, flipped: alignment < 0.0 };
    rotation.holds(sys, mech, rows).then_some(rotation)
}

impl Rotation {
    /// Whether the block's own rows, evaluated at the initial estimates with e_j on the family,
    /// agree with the closed form: the normalisation and parallel rows vanish and the driver's
    /// row is the form its values at u, w (and (u + w)/√2) predict, at four angles.
    fn holds(&self, sys: &Symbolic, mech: &Mechanism, rows: &[usize]) -> bool {
        let mut q = sys.initial_estimate(mech);
        let known: Vector4<f64> = Vector4::from_fn(|c, _| match sys.coords[self.known.0][3 + c] {
            Source::Unknown(k) => q[k],
            Source::Fixed(v) => v,
            Source::Driven(_) | Source::Derived(_) => f64::NAN,
        })
        .normalize();
        for (c, s) in sys.coords[self.known.0][3..].iter().enumerate() {
            if let Source::Unknown(k) = *s {
                q[k] = known[c];
            }
        }
        let (g, h) = self.frames(mech);
        let (u, w) = (product(known, g), product(known, h));
        let first = self.first_unknown(sys);
        let t = mech.time.start;
        let inputs = sys.planning_inputs(t);
        let exprs: Vec<ExprId> = rows.iter().map(|&r| sys.phi[r]).collect();
        let driver = rows.iter().position(|&r| r == self.driver_row).expect("the driver's row");
        let mut at = |e: Vector4<f64>| {
            q[first..first + 4].copy_from_slice(e.as_slice());
            sys.pool.eval_inputs(&exprs, [&q, &[], &[]], t, &inputs)
        };
        let mid = (u + w) * std::f64::consts::FRAC_1_SQRT_2;
        let (fu, fw, fm) = (at(u)[driver], at(w)[driver], at(mid)[driver]);
        let scale = 1.0 + fu.abs() + fw.abs() + fm.abs();
        [0.3_f64, 1.7, 2.9, -2.2].iter().all(|&phi| {
            let (s, c) = (0.5 * phi).sin_cos();
            let values = at(c * u + s * w);
            let predicted = if self.linear {
                fu * c + fw * s
            } else {
                fu * c * c + (2.0 * fm - fu - fw) * c * s + fw * s * s
            };
            // Round-off of rows of unit quantities: far below any modelling difference.
            values.iter().enumerate().all(|(r, v)| {
                let expected = if r == driver { predicted } else { 0.0 };
                (v - expected).abs() <= 1e-12 * scale
            })
        })
    }
}
