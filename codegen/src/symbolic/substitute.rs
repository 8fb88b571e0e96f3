//! Closed-form blocks substituted at generation time: "model no more than the scene needs".
//!
//! The block-lower-triangular form of the reduced system (`blocks`) shows which of its
//! unknowns follow from the earlier ones without iteration. Three kinds of closed-form block
//! have an exact expression as their solution and are substituted, in solve order, so that a
//! block's expression may use the coordinates substituted before it:
//!
//! - an affine block, one equation Φ_r = a q_k + ρ(q, t) whose coefficient a = ∂Φ_r/∂q_k is a
//!   non-zero constant, for a translational coordinate: q_k = −ρ/a, with ρ = Φ_r at q_k = 0
//!   (a body's position through a joint at a known point);
//! - a rotation block (`blocks::Rotation`) driven by an absolute rx, ry or rz about a body
//!   whose Euler parameters are constants: on the family e_j = c u + s′ w of the joint the
//!   driver's row e_i cos(s/2) − e_0 sin(s/2) is A c + B s′ with A = f(u), B = f(w) (see
//!   `runtime::rotation`), zero at
//!
//!   e_j = σ (B u − A w) / κ,
//!
//!   where κ² = A² + B², a quadratic form in (cos s/2, sin s/2) with the constant u and w;
//!   the block is substituted only where that form is a constant (the joint's axis along the
//!   driver's: κ = 1 in every description that drives a revolute this way), so that e_j is
//!   a polynomial in sin(s/2) and cos(s/2), finite for every s, with no division at run time.
//!   σ = ±1 is chosen at generation time to match the assembled configuration; e_j is then a
//!   smooth function of s which changes sign over every full turn, as the continuation the
//!   generic engine's Newton follows does;
//! - a rotation block driven by its joint's angle, where that angle is ±s plus a constant
//!   (references perpendicular to the axes, checked along the family at generation time: the
//!   joint angle's x and y are κ cos(φ − ψ) and σ κ sin(φ − ψ), σ = ±1): the driver's row
//!   x sin s − y cos s = κ sin(s − σ (φ − ψ)) is zero at φ = σ s + ψ + kπ, k chosen with the
//!   assembled configuration, so e_j = cos(φ/2) u + sin(φ/2) w with u and w expressions of
//!   the known body's Euler parameters, whatever moves that body (the angle is relative).
//!
//! Beyond the blocks, a body that a revolute or cylindrical joint turns about a global axis
//! its Euler parameters' frame shares, relative to a body of constant orientation (the
//! R-S-S-R's rocker about x), has two Euler parameters that vanish on the joint's family: they
//! become the constant 0 and the joint's two parallel-axis rows, which then vanish identically,
//! join the eliminated ones (`off_axis`). The family is taken through the assembled
//! configuration, so it is the branch the generic engine follows.
//!
//! Inside an implicit block (a closed loop), a position on which one of the block's rows is
//! affine with a constant coefficient (a pin of the loop's body: x_j + (A_j s'_j)_x − … = 0,
//! coefficient ±1 whatever the orientations) is torn from it (`torn`): q_k = −ρ/a as for an
//! affine block, substituted into the block's other rows, which leaves Newton the Schur
//! complement on fewer unknowns (the four-bar's loop: 14 → 8, its Euler parameters). Only
//! constant coefficients are torn: they cannot vanish on the motion, so a torn value is as
//! finite and exact as the row it comes from.
//!
//! Other joint-angle rows, absolute rotations about a moving body (κ then varies) and affine
//! blocks with a coefficient that varies stay unknowns, as does every block when the system
//! has rows dropped as dependent (their run-time checks and re-selection belong to the whole
//! system), or a closed form that adds more than [`LARGEST_VALUE`] operations to those
//! substituted before it. U-P-S legs reduced to distance rows (`legs`) do not stand in the
//! way: the blocks are found with the distance rows, the rebuilt system writes the legs'
//! driver rows again and `legs` replaces them on it (its check reads the legs' bodies'
//! substituted coordinates through their expressions), so the Stewart platform keeps 55 of
//! its 91 unknowns: the cylinders' and rods' positions are closed forms given the platform.
//! (It was once excluded for a disagreement of 3e-2 with the generic engine; that was a test
//! reading the module's reduced q as the generic layout of all 91 coordinates, where a module
//! with substituted coordinates gives them through `expand`.) Systems of every size are
//! substituted: a module solved block by block
//! (`emit::blocks`) is planned on the unknowns that remain, so its closed-form blocks cost
//! neither a Newton block nor a place in the solver's storage. The substituted coordinates become
//! [`Source::Derived`] and their rows [`Symbolic::eliminated`] (they hold exactly by
//! construction); the system is then built again on the remaining unknowns, so Φ, Φ_q, ν, γ,
//! the dropped rows and everything emitted from them follow unchanged.

use std::collections::{BTreeMap, BTreeSet};

use nalgebra::Vector4;

use crate::blocks::{Block, Blocks, Kind, Rotation};
use crate::expr::{ExprId, Var};
use crate::model::{BodyId, DriverTarget, JointKind, Mechanism, RowLabel};

use super::{Source, Symbolic};

/// The most operations a substituted coordinate's value may add to the values substituted
/// before it; a system with a longer closed form is left whole. Down an explicit chain each
/// body's value is an expression of the body's before it (about 20 operations per link), which
/// the emitted functions compute once (`emit::function` keeps them when it splits a function),
/// so a chain costs what its links add: a driven chain of 100 links takes 14,368 operations in
/// `expand` (rates and accelerations included) and 4.8 µs per step, against 36 µs solved block
/// by block. The limit guards against one closed form of a size no link has: a value of the
/// shipped examples and benchmarks adds at most 14.
const LARGEST_VALUE: usize = 256;

/// A body coordinate substituted by the closed form of its block ([`Source::Derived`]).
#[derive(Clone, Debug, PartialEq)]
pub struct Derived {
    /// The body.
    pub body: BodyId,
    /// The coordinate: an index into `[x, y, z, e0, e1, e2, e3]`.
    pub coordinate: usize,
    /// Its value f(q, t), rate ḟ = f_q q̇ + f_t and acceleration
    /// f̈ = f_q q̈ + (f_q q̇)_q q̇ + 2 f_qt q̇ + f_tt, in q, q̇, q̈, t (and the inputs).
    pub value: [ExprId; 3],
    /// Whether it was torn from an implicit block (see the module docs) rather than solved by
    /// a closed-form block of its own.
    pub torn: bool,
}

/// A coordinate to substitute while the system is built: its value in the remaining unknowns,
/// and the rows its block eliminates (on the block's first coordinate only).
pub(super) struct Substitution {
    pub(super) body: BodyId,
    pub(super) coordinate: usize,
    pub(super) value: ExprId,
    pub(super) rows: Vec<RowLabel>,
    pub(super) torn: bool,
}

/// The largest round-off tolerated, relative to 1 or to κ, where a form must be exact (κ² =
/// A² + B² a constant; a joint angle's x and y of the form κ cos(φ − ψ), σ κ sin(φ − ψ)): sums
/// of products of unit quaternions' entries, each within a few ulps.
const CONSTANT_FORM: f64 = 1e-12;

impl Symbolic {
    /// This system with its closed-form blocks substituted (see the module docs), built again
    /// on the remaining unknowns; `q` is its assembled initial configuration. Unchanged when
    /// no block qualifies, or when the substituted system does not build.
    pub(super) fn substituted(mut self, mech: &Mechanism, q: &[f64]) -> Self {
        let blocks = Blocks::of(&self, mech);
        let mut map: BTreeMap<Var, ExprId> = BTreeMap::new();
        // (old unknown, value in the old numbering, rows eliminated with it, whether torn).
        let mut found: Vec<(usize, ExprId, Vec<RowLabel>, bool)> = Vec::new();
        // Node marks for counting the operations each value adds to those before it.
        let mut marks = Vec::new();
        for block in &blocks.blocks {
            if block.kind == Kind::Implicit {
                for (k, e, r) in self.torn(block, &map, &mut marks) {
                    map.insert(Var::Q(small(k)), e);
                    found.push((k, e, vec![self.rows[r].clone()], true));
                }
                continue;
            }
            let values = match block.kind {
                Kind::ClosedForm => self.affine(block, &map),
                Kind::Rotation(r) if r.linear => self.turned(mech, &r, q),
                Kind::Rotation(r) => self.angle(mech, &r, q, &map),
                _ => None,
            };
            let Some(values) = values else { continue };
            marks.resize(self.pool.len(), 0);
            let too_long = values
                .iter()
                .any(|&(_, e)| self.pool.new_operations(e, &mut marks, 1) > LARGEST_VALUE);
            if too_long {
                log::debug!("{}: closed forms not substituted: a value is too long", mech.name);
                return self;
            }
            for (n, (k, e)) in values.into_iter().enumerate() {
                map.insert(Var::Q(small(k)), e);
                let rows = if n == 0 {
                    block.rows.iter().map(|&r| self.rows[r].clone()).collect()
                } else {
                    Vec::new()
                };
                found.push((k, e, rows, false));
            }
        }
        for joint in 0..mech.joints.len() {
            for side in [true, false] {
                let Some((values, rows)) = self.off_axis(mech, joint, side, q, &map) else {
                    continue;
                };
                for (n, (k, e)) in values.into_iter().enumerate() {
                    map.insert(Var::Q(small(k)), e);
                    let rows = if n == 0 { rows.clone() } else { Vec::new() };
                    found.push((k, e, rows, false));
                }
            }
        }
        if found.is_empty() {
            return self;
        }
        // A block's value may use a coordinate substituted after it (the vanishing Euler
        // parameters come last): substitute until only remaining unknowns are left.
        for entry in &mut found {
            loop {
                let e = self.pool.substitute(entry.1, &map);
                if e == entry.1 {
                    break;
                }
                entry.1 = e;
            }
        }
        // The remaining unknowns keep their order: number_unknowns numbers them body by body.
        let gone: BTreeSet<usize> = found.iter().map(|&(k, ..)| k).collect();
        let mut renumber = BTreeMap::new();
        for (new, old) in (0..self.unknowns.len()).filter(|k| !gone.contains(k)).enumerate() {
            renumber.insert(Var::Q(small(old)), self.pool.var(Var::Q(small(new))));
        }
        let derived: Vec<Substitution> = found
            .into_iter()
            .map(|(k, e, rows, torn)| Substitution {
                body: self.unknowns[k].0,
                coordinate: self.unknowns[k].1,
                value: self.pool.substitute(e, &renumber),
                rows,
                torn,
            })
            .collect();
        match Self::build_with(mech, self.pool.clone(), &derived) {
            Ok((sys, _)) => {
                let remaining = self.unknowns.iter().enumerate().filter(|(k, _)| !gone.contains(k));
                debug_assert!(sys.unknowns.iter().eq(remaining.map(|(_, u)| u)), "renumbered");
                sys
            }
            Err(e) => {
                log::debug!("{}: closed forms not substituted: {}", mech.name, e.message);
                self
            }
        }
    }

    /// The closed form of an affine block, with the coordinates of `map` substituted: q_k =
    /// −ρ/a (see the module docs), for a translational coordinate with a constant coefficient.
    fn affine(&mut self, block: &Block, map: &BTreeMap<Var, ExprId>) -> Option<Values> {
        let (&[r], &[k]) = (block.rows.as_slice(), block.unknowns.as_slice()) else {
            return None;
        };
        // An Euler parameter shares its body's normalisation with the others: left to Newton.
        if self.unknowns[k].1 >= 3 {
            return None;
        }
        let qk = Var::Q(small(k));
        let phi = self.pool.substitute(self.phi[r], map);
        let d = self.pool.diff(phi, qk);
        let a = self.pool.as_const(d).filter(|a| *a != 0.0 && a.is_finite())?;
        let zero = self.pool.constant(0.0);
        let rest = self.pool.substitute(phi, &BTreeMap::from([(qk, zero)]));
        let factor = self.pool.constant(-1.0 / a);
        Some(vec![(k, self.pool.mul(factor, rest))])
    }

    /// The unknowns torn from an implicit block: while one of its rows, with the coordinates of
    /// `map` and those torn before substituted, is affine in one of its translational unknowns
    /// with a constant non-zero coefficient a, that unknown is q_k = −ρ/a (ρ the row at q_k = 0,
    /// as [`Symbolic::affine`]) and leaves the block with the row; (unknown, value, row) in the
    /// order torn. Of the candidates, the one with the largest |a| is torn first (threshold
    /// pivoting on constants: on the rows of a joint's coincident point a is ±1).
    ///
    /// This is tearing (the equation-based generators' term) restricted to where it is exact
    /// and safe: a constant coefficient cannot vanish along the motion, so the torn value is
    /// finite wherever the row is, and the block that remains is the Schur complement of the
    /// torn rows, solved by Newton on fewer unknowns. A position coupled into a loop through
    /// its body's orientation (the four-bar's coupler and rocker, whose points are pinned to
    /// the bodies around them) follows from the orientations and leaves the loop's Newton
    /// system; Euler parameters, which share their body's normalisation, stay, as do unknowns
    /// whose coefficients vary (a division by an expression that may vanish on the motion).
    /// A value that would add more than [`LARGEST_VALUE`] operations ends the tearing.
    fn torn(
        &mut self,
        block: &Block,
        map: &BTreeMap<Var, ExprId>,
        marks: &mut Vec<u32>,
    ) -> Vec<(usize, ExprId, usize)> {
        // The block's rows with the coordinates substituted so far, and the block's
        // translational unknowns each row depends on; both updated as unknowns are torn, so
        // that no row or value holds a torn unknown.
        let mut rows: Vec<(usize, ExprId, BTreeSet<usize>)> = block
            .rows
            .iter()
            .map(|&r| {
                let phi = self.pool.substitute(self.phi[r], map);
                (r, phi, BTreeSet::new())
            })
            .collect();
        let mut unknowns: BTreeSet<usize> =
            block.unknowns.iter().copied().filter(|&k| self.unknowns[k].1 < 3).collect();
        for row in &mut rows {
            row.2 = unknowns
                .iter()
                .copied()
                .filter(|&k| self.pool.depends_on(row.1, Var::Q(small(k))))
                .collect();
        }
        let mut torn: Vec<(usize, ExprId, usize)> = Vec::new();
        while !unknowns.is_empty() && !rows.is_empty() {
            // (|a|, row position, unknown, a).
            let mut best: Option<(f64, usize, usize, f64)> = None;
            for (ri, (_, phi, depends)) in rows.iter().enumerate() {
                for &k in depends {
                    let d = self.pool.diff(*phi, Var::Q(small(k)));
                    let Some(a) = self.pool.as_const(d).filter(|a| *a != 0.0 && a.is_finite())
                    else {
                        continue;
                    };
                    if best.is_none_or(|b| a.abs() > b.0) {
                        best = Some((a.abs(), ri, k, a));
                    }
                }
            }
            let Some((_, ri, k, a)) = best else { break };
            let qk = Var::Q(small(k));
            let zero = self.pool.constant(0.0);
            let rest = self.pool.substitute(rows[ri].1, &BTreeMap::from([(qk, zero)]));
            let factor = self.pool.constant(-1.0 / a);
            let value = self.pool.mul(factor, rest);
            marks.resize(self.pool.len(), 0);
            if self.pool.new_operations(value, marks, 1) > LARGEST_VALUE {
                break;
            }
            let (r, ..) = rows.remove(ri);
            unknowns.remove(&k);
            let step = BTreeMap::from([(qk, value)]);
            for entry in &mut torn {
                entry.1 = self.pool.substitute(entry.1, &step);
            }
            for row in rows.iter_mut().filter(|row| row.2.contains(&k)) {
                row.1 = self.pool.substitute(row.1, &step);
                row.2 = unknowns
                    .iter()
                    .copied()
                    .filter(|&j| self.pool.depends_on(row.1, Var::Q(small(j))))
                    .collect();
            }
            torn.push((k, value, r));
        }
        torn
    }

    /// The closed form e_j = σ (B u − A w)/κ of a rotation block driven by an absolute
    /// rotation about a body of constant Euler parameters (see the module docs), σ from the
    /// assembled configuration `q`.
    fn turned(&mut self, mech: &Mechanism, r: &Rotation, q: &[f64]) -> Option<Values> {
        let constant = |s: &Source| matches!(s, Source::Fixed(_));
        if !self.coords[r.known.0][3..].iter().all(constant) {
            return None;
        }
        let label = &self.rows[r.driver_row];
        let driver = mech.drivers.iter().find(|d| d.name == label.name)?;
        let DriverTarget::Absolute { coordinate, .. } = driver.target else { return None };
        // The driver's row is e_i cos(s/2) − e_0 sin(s/2).
        let i = crate::generic::absolute_index(coordinate).checked_sub(3)?;
        let k = r.coefficients(self, mech);
        let values: Vec<f64> =
            k[..8].iter().map(|&e| self.pool.as_const(e)).collect::<Option<_>>()?;
        let (u, w) = (&values[0..4], &values[4..8]);
        // κ² = P cos² − 2 R cos sin + Q sin² (of s/2): a constant when P = Q and R = 0.
        let p = u[i] * u[i] + w[i] * w[i];
        let q0 = u[0] * u[0] + w[0] * w[0];
        let cross = u[i] * u[0] + w[i] * w[0];
        if (p - q0).abs() > CONSTANT_FORM || cross.abs() > CONSTANT_FORM || p < 0.25 {
            return None;
        }
        let kappa = (0.5 * (p + q0)).sqrt();
        let (a, b) = (k[8], k[9]);
        let at = |pool: &mut crate::expr::ExprPool, sign: f64| -> [ExprId; 4] {
            std::array::from_fn(|c| {
                let bu = pool.constant(sign * u[c] / kappa);
                let aw = pool.constant(-sign * w[c] / kappa);
                let x = pool.mul(bu, b);
                let y = pool.mul(aw, a);
                pool.add(x, y)
            })
        };
        let first = r.first_unknown(self);
        let e = at(&mut self.pool, 1.0);
        let t = mech.time.start;
        let inputs = self.planning_inputs(t);
        let e0 = self.pool.eval_inputs(&e, [q, &[], &[]], t, &inputs);
        let dot: f64 = e0.iter().zip(&q[first..first + 4]).map(|(x, y)| x * y).sum();
        // Both are unit quaternions on the family: ±1 up to round-off, else not the same branch.
        let sign = if dot > 0.5 {
            1.0
        } else if dot < -0.5 {
            -1.0
        } else {
            return None;
        };
        let e = if sign > 0.0 { e } else { at(&mut self.pool, -1.0) };
        Some((0..4).map(|c| (first + c, e[c])).collect())
    }
}

impl Symbolic {
    /// The closed form e_j = cos(φ/2) u + sin(φ/2) w, φ = σ s + ψ + kπ, of a rotation block
    /// driven by its joint's angle where that angle is ±s plus a constant (see the module
    /// docs); σ, ψ and k from the joint's angle along the family at the assembled
    /// configuration `q`, the known body's coordinates through `map`.
    fn angle(
        &mut self,
        mech: &Mechanism,
        r: &Rotation,
        q: &[f64],
        map: &BTreeMap<Var, ExprId>,
    ) -> Option<Values> {
        let label = &self.rows[r.driver_row];
        let d = mech.drivers.iter().position(|d| d.name == label.name)?;
        let joint = &mech.joints[r.joint];
        let mut input_of = vec![None; mech.drivers.len()];
        for (i, input) in self.inputs.iter().enumerate() {
            input_of[input.driver] = Some(u32::try_from(i).expect("fewer than 2³² drivers"));
        }
        let mut builder = super::Builder {
            pool: std::mem::take(&mut self.pool),
            coords: self.coords.clone(),
            laws: self.laws.clone(),
            input_of,
            derived: self.derived.iter().map(|d| d.value[0]).collect(),
        };
        let (x, y) = builder.joint_angle(joint);
        let s = builder.law(d, &mech.drivers[d].law);
        self.pool = builder.pool;
        let k = r.coefficients(self, mech);
        let t = mech.time.start;
        let inputs = self.planning_inputs(t);
        let values = self.pool.eval_inputs(&k[..8], [q, &[], &[]], t, &inputs);
        let (u, w) =
            (Vector4::from_column_slice(&values[0..4]), Vector4::from_column_slice(&values[4..8]));
        let first = r.first_unknown(self);
        // The joint's angle (x, y) along the family, x = α + β cos φ + γ sin φ and y alike.
        let at = |phi: f64| -> [f64; 2] {
            let mut q = q.to_vec();
            let e = (0.5 * phi).cos() * u + (0.5 * phi).sin() * w;
            q[first..first + 4].copy_from_slice(e.as_slice());
            let v = self.pool.eval_inputs(&[x, y], [&q, &[], &[]], t, &inputs);
            [v[0], v[1]]
        };
        let quarter = std::f64::consts::FRAC_PI_2;
        let samples: Vec<[f64; 2]> = (0..4).map(|k| at(f64::from(k) * quarter)).collect();
        let fit = |c: usize| {
            let (a, b) = (samples[0][c], samples[2][c]);
            let (e, f) = (samples[1][c], samples[3][c]);
            [0.25 * (a + b + e + f), 0.5 * (a - b), 0.5 * (e - f)]
        };
        let ([ax, bx, cx], [ay, by, cy]) = (fit(0), fit(1));
        let kappa = bx.hypot(cx);
        // The joint's angle is φ + ψ turned by σ: y = σ (β sin φ − γ cos φ), no constant terms.
        let sigma = (bx * cy - cx * by) / (kappa * kappa);
        let tolerance = CONSTANT_FORM * kappa;
        let check = at(1.0);
        let predicted =
            [bx * 1.0_f64.cos() + cx * 1.0_f64.sin(), by * 1.0_f64.cos() + cy * 1.0_f64.sin()];
        let exact = kappa > 0.0
            && ax.abs() <= tolerance
            && ay.abs() <= tolerance
            && (sigma.abs() - 1.0).abs() <= CONSTANT_FORM
            && (by + sigma * cx).abs() <= tolerance
            && (cy - sigma * bx).abs() <= tolerance
            && (check[0] - predicted[0]).abs() <= tolerance
            && (check[1] - predicted[1]).abs() <= tolerance;
        if !exact {
            return None;
        }
        let sigma = sigma.signum();
        let psi = cx.atan2(bx);
        // x sin s − y cos s = κ sin(s − σ (φ − ψ)): zero at φ = σ s + ψ + kπ; k from the
        // assembled configuration, whose sign of e_j fixes φ modulo 4π.
        let assembled = Vector4::from_column_slice(&q[first..first + 4]);
        let phi = 2.0 * assembled.dot(&w).atan2(assembled.dot(&u));
        let s0 = self.pool.eval_inputs(&[s], [q, &[], &[]], t, &inputs)[0];
        let turns = ((phi - sigma * s0 - psi) / std::f64::consts::PI).round();
        let offset = psi + turns * std::f64::consts::PI;
        // Assembled to the description's tolerance: far closer than this to the branch.
        if (phi - sigma * s0 - offset).abs() > 1e-6 {
            return None;
        }
        let p = &mut self.pool;
        let (half, c0) = (p.constant(0.5 * sigma), p.constant(0.5 * offset));
        let hs = p.mul(half, s);
        let arg = p.add(hs, c0);
        let (cos, sin) = (p.cos(arg), p.sin(arg));
        Some(
            (0..4)
                .map(|c| {
                    let (uc, wc) = (p.substitute(k[c], map), p.substitute(k[4 + c], map));
                    let a = p.mul(uc, cos);
                    let b = p.mul(wc, sin);
                    (first + c, p.add(a, b))
                })
                .collect(),
        )
    }
}

impl Symbolic {
    /// The two Euler parameters of a body that vanish on the family its revolute or
    /// cylindrical joint `joint` to a body of constant orientation leaves it, with the joint's
    /// two parallel-axis rows, which then vanish identically: the body turning about a global
    /// axis its Euler parameters' frame shares (the R-S-S-R's rocker about x: e2 = e3 = 0).
    /// The family through the assembled e is e(θ) = cos(θ/2) e + sin(θ/2) e ⊗ (0, â) with â the
    /// joint's axis in the body's frame; `side` picks the joint's body j (else i) as the body.
    fn off_axis(
        &mut self,
        mech: &Mechanism,
        joint: usize,
        side: bool,
        q: &[f64],
        map: &BTreeMap<Var, ExprId>,
    ) -> Option<(Values, Vec<RowLabel>)> {
        let j = &mech.joints[joint];
        let first_row = match j.kind {
            JointKind::Revolute => 4,
            JointKind::Cylindrical => 1,
            _ => return None,
        };
        let (ai, aj) = j.axis?;
        let (body, known, axis) =
            if side { (j.body_j, j.body_i, aj) } else { (j.body_i, j.body_j, ai) };
        if !self.coords[known.0][3..].iter().all(|s| matches!(s, Source::Fixed(_))) {
            return None;
        }
        let unknowns: Vec<usize> = self.coords[body.0][3..]
            .iter()
            .map(|s| match *s {
                Source::Unknown(k) if !map.contains_key(&Var::Q(small(k))) => Some(k),
                _ => None,
            })
            .collect::<Option<_>>()?;
        let e = Vector4::from_fn(|c, _| q[unknowns[c]]).normalize();
        let a = axis.normalize();
        let w = super::super::blocks::rotation::product_with_vector(e, &a);
        let zero: Vec<usize> = (0..4)
            .filter(|&c| e[c].abs() <= CONSTANT_FORM && w[c].abs() <= CONSTANT_FORM)
            .collect();
        if zero.len() != 2 {
            return None;
        }
        let rows: Vec<usize> = (0..self.rows.len())
            .filter(|&r| {
                let l = &self.rows[r];
                l.kind == RowLabel::JOINT
                    && l.name == j.name
                    && (l.row == first_row || l.row == first_row + 1)
            })
            .collect();
        if rows.len() != 2 {
            return None;
        }
        let zero_value = self.pool.constant(0.0);
        let mut with_zeros = map.clone();
        for &c in &zero {
            with_zeros.insert(Var::Q(small(unknowns[c])), zero_value);
        }
        for &r in &rows {
            let phi = self.pool.substitute(self.phi[r], &with_zeros);
            if self.pool.as_const(phi) != Some(0.0) {
                return None;
            }
        }
        let labels = rows.iter().map(|&r| self.rows[r].clone()).collect();
        Some((zero.iter().map(|&c| (unknowns[c], zero_value)).collect(), labels))
    }
}

/// Substituted unknowns (indices before renumbering) with their values.
type Values = Vec<(usize, ExprId)>;

/// An unknown's index as the pool's variable index.
fn small(k: usize) -> u32 {
    u32::try_from(k).expect("fewer than 2³² unknowns")
}
