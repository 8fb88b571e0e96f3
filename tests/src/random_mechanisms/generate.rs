//! Random valid, assembled, exactly driven mechanisms, written as description text.
//!
//! A case is a ground body (sometimes placed and turned off the global frame) and a chain of
//! 1–4 moving bodies in random poses, each joined to the previous one by a revolute,
//! prismatic, cylindrical or screw joint. Every joint is laid out once in global terms (a
//! point, an axis, a reference direction, the joint's initial angle and axial offset), and
//! its local points, axes and references are derived from that layout and the two bodies'
//! poses, so the initial estimates satisfy it exactly. Every joint degree of freedom starts
//! out driven by a joint driver whose law starts at the assembled value.
//!
//! Then, at random:
//! - the chain is closed back to ground or to an earlier body by a spherical, universal or
//!   distance joint, and as many drivers of the loop are dropped as the closure adds
//!   equations;
//! - a driver is traded for a `fix` constraint, a `coordinate_difference` (against ground or
//!   an upstream body) or an absolute x/y/z driver of a downstream body, holding the value
//!   the assembled pose has;
//! - when the first joint turns body 1 about a global coordinate axis (body 1 then starts as
//!   a pure rotation about that axis), its rotation driver becomes an absolute rx/ry/rz
//!   driver, the one case where the contract says those drivers are meaningful;
//! - the estimates of bodies without a screw joint are perturbed by up to 1e-3 (a screw's d0
//!   and θ0 are measured at the estimates, so its bodies keep exact ones).
//!
//! Rates are bounded per second (2 rad/s, 0.5 length/s; lengths are of order 1) and the
//! grids have 10–30 steps of at most 0.07 s, so that no step moves more than about
//! 0.14 rad or 0.035 in length and Newton, started from the Taylor predictor, follows.

use std::collections::BTreeSet;
use std::f64::consts::PI;
use std::fmt::Write as _;

use nalgebra::{Unit, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};

/// The time grid of the generated cases: a step in `step` and `steps` intervals.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Grid {
    /// Smallest and largest number of intervals.
    pub(crate) steps: (usize, usize),
    /// Range of the step, seconds.
    pub(crate) step: (f64, f64),
}

impl Grid {
    /// The analysis grids: 10–30 steps of 0.02–0.07 s.
    pub(crate) const ANALYSIS: Grid = Grid { steps: (10, 30), step: (0.02, 0.07) };
    /// Fine grids for finite differences: 16 steps of 1 ms.
    pub(crate) const FINE: Grid = Grid { steps: (16, 16), step: (1e-3, 1e-3) };
}

/// One generated mechanism.
#[derive(Clone, Debug)]
pub(crate) struct Case {
    /// The seed it was generated from.
    pub(crate) seed: u64,
    /// The description, TOML.
    pub(crate) toml: String,
    /// What it contains (`joint screw`, `driver rz`, `closure universal`, …), for coverage.
    pub(crate) features: BTreeSet<&'static str>,
}

/// Largest rate of a driven joint angle or body rotation, rad/s.
const ROTATION_RATE: f64 = 2.0;
/// Largest rate of a driven translation, length/s.
const TRANSLATION_RATE: f64 = 0.5;
/// Largest rate of a driven body coordinate, length/s.
const COORDINATE_RATE: f64 = 0.4;
/// Newton tolerance of every generated description: at the default 1e-10, two engines may
/// stop one iteration apart and differ by the tolerance times the conditioning.
pub(crate) const TOLERANCE: f64 = 1e-12;
/// Largest perturbation of an initial estimate component.
const PERTURBATION: f64 = 1e-3;

/// A body placement: origin and orientation, global.
#[derive(Clone, Copy, Debug)]
struct Pose {
    r: Vector3<f64>,
    q: UnitQuaternion<f64>,
}

impl Pose {
    fn identity() -> Pose {
        Pose { r: Vector3::zeros(), q: UnitQuaternion::identity() }
    }

    /// Body components of a global point.
    fn local_point(&self, global: &Vector3<f64>) -> Vector3<f64> {
        self.q.inverse_transform_vector(&(global - self.r))
    }

    /// Body components of a global direction.
    fn local_vector(&self, global: &Vector3<f64>) -> Vector3<f64> {
        self.q.inverse_transform_vector(global)
    }

    /// `[x, y, z, e0, e1, e2, e3]`.
    fn coordinates(&self) -> [f64; 7] {
        let (r, q) = (self.r, self.q.quaternion());
        [r.x, r.y, r.z, q.w, q.i, q.j, q.k]
    }
}

/// Joint types of the generated cases.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Kind {
    Revolute,
    Prismatic,
    Cylindrical,
    Screw,
    Spherical,
    Universal,
    Distance,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Revolute => "revolute",
            Kind::Prismatic => "prismatic",
            Kind::Cylindrical => "cylindrical",
            Kind::Screw => "screw",
            Kind::Spherical => "spherical",
            Kind::Universal => "universal",
            Kind::Distance => "distance",
        }
    }
}

/// One joint, in local terms, ready to print.
#[derive(Clone, Debug)]
struct JointSpec {
    name: String,
    kind: Kind,
    body_i: usize,
    body_j: usize,
    point_i: Vector3<f64>,
    point_j: Vector3<f64>,
    axis: Option<(Vector3<f64>, Vector3<f64>)>,
    reference: Option<(Vector3<f64>, Vector3<f64>)>,
    lead: Option<f64>,
    distance: Option<f64>,
}

/// A joint degree of freedom of the chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Motion {
    Rotation,
    Translation,
}

/// What holds a degree of freedom.
#[derive(Clone, Debug)]
enum Holder {
    /// A joint driver (the start).
    JointDriver,
    /// Nothing: a closure determines it.
    Free,
    /// A `fix` constraint on a body coordinate.
    Fix { body: usize, coordinate: usize },
    /// `q_i[c] − q_j[c] = value`.
    Difference { body_i: usize, body_j: usize, coordinate: usize },
    /// An absolute x/y/z driver.
    Coordinate { body: usize, coordinate: usize },
    /// An absolute rx/ry/rz driver about global axis `axis` (body 1 only).
    Rotation { body: usize, axis: usize },
}

#[derive(Clone, Debug)]
struct Dof {
    /// Index of the chain joint (1-based: joint k joins bodies k − 1 and k).
    joint: usize,
    motion: Motion,
    /// The joint value at assembly: angle or axial offset.
    value: f64,
    holder: Holder,
}

const COORDINATES: [&str; 7] = ["x", "y", "z", "e0", "e1", "e2", "e3"];

fn uniform(rng: &mut StdRng, lo: f64, hi: f64) -> f64 {
    rng.random_range(lo..hi)
}

fn vec3(rng: &mut StdRng, half: f64) -> Vector3<f64> {
    Vector3::from_fn(|_, _| uniform(rng, -half, half))
}

fn unit(rng: &mut StdRng) -> Vector3<f64> {
    loop {
        let v = vec3(rng, 1.0);
        if v.norm() > 0.3 {
            return v.normalize();
        }
    }
}

/// A unit vector ⟂ `a`, well away from parallel.
fn perpendicular(rng: &mut StdRng, a: &Vector3<f64>) -> Vector3<f64> {
    loop {
        let v = unit(rng);
        let w = v - a * a.dot(&v);
        if w.norm() > 0.3 {
            return w.normalize();
        }
    }
}

/// A random orientation, at least 0.3 rad away from the identity.
fn orientation(rng: &mut StdRng) -> UnitQuaternion<f64> {
    loop {
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            uniform(rng, -1.0, 1.0),
            uniform(rng, -1.0, 1.0),
            uniform(rng, -1.0, 1.0),
            uniform(rng, -1.0, 1.0),
        ));
        if q.angle() > 0.3 {
            return q;
        }
    }
}

fn about(axis: &Vector3<f64>, angle: f64) -> UnitQuaternion<f64> {
    UnitQuaternion::from_axis_angle(&Unit::new_normalize(*axis), angle)
}

fn num(x: f64) -> String {
    format!("{x:?}")
}

fn v3(v: &Vector3<f64>) -> String {
    format!("[{:?}, {:?}, {:?}]", v.x, v.y, v.z)
}

/// A law s(t) with s(t0) = `value` and |ṡ| ≤ `rate` on [t0, t0 + span].
fn law(
    rng: &mut StdRng,
    features: &mut BTreeSet<&'static str>,
    value: f64,
    (t0, span): (f64, f64),
    rate: f64,
) -> String {
    let pick = uniform(rng, 0.0, 1.0);
    if pick < 0.5 {
        features.insert("law polynomial");
        let (v, a) = if pick < 0.05 {
            features.insert("law constant");
            (0.0, 0.0)
        } else {
            // |v| ≤ 0.6 rate and |a·t| ≤ 0.4 rate for |t| ≤ |t0| + span.
            (uniform(rng, -0.6, 0.6) * rate, uniform(rng, -0.4, 0.4) * rate / (t0.abs() + span))
        };
        let start = value - v * t0 - 0.5 * a * t0 * t0;
        format!("{{ start = {}, velocity = {}, acceleration = {} }}", num(start), num(v), num(a))
    } else {
        features.insert("law harmonic");
        let w = uniform(rng, 0.5, 4.0);
        let amplitude = uniform(rng, 0.1, 0.9) * rate / w;
        let phase = uniform(rng, -PI, PI);
        let offset = value - amplitude * (w * t0 + phase).sin();
        format!(
            "{{ offset = {}, amplitude = {}, frequency = {}, phase = {} }}",
            num(offset),
            num(amplitude),
            num(w),
            num(phase)
        )
    }
}

/// The mechanism of `seed` on a grid drawn from `grid`.
pub(crate) fn mechanism(seed: u64, grid: Grid) -> Case {
    let mut rng = StdRng::seed_from_u64(seed);
    let rng = &mut rng;
    let mut draft = Draft::chain(rng);
    if rng.random_bool(0.45) {
        draft.close(rng);
    }
    draft.trade_drivers(rng);
    draft.into_case(seed, grid, rng)
}

/// A mechanism being drawn.
struct Draft {
    /// Assembled poses; index 0 is ground, body k is `b{k}`.
    poses: Vec<Pose>,
    joints: Vec<JointSpec>,
    /// The chain's degrees of freedom and what holds each.
    dofs: Vec<Dof>,
    /// The global coordinate axis joint 1 turns about, when body 1 starts as a pure rotation
    /// about it: the case for absolute rx/ry/rz drivers.
    aligned: Option<usize>,
    features: BTreeSet<&'static str>,
}

impl Draft {
    /// Number of moving bodies.
    fn moving(&self) -> usize {
        self.poses.len() - 1
    }

    /// Ground, 1–4 moving bodies and the chain joints, every degree of freedom driven.
    fn chain(rng: &mut StdRng) -> Draft {
        let n = rng.random_range(1..=4_usize);
        let mut features = BTreeSet::new();
        let mut poses = vec![Pose::identity(); n + 1];
        if rng.random_bool(0.5) {
            features.insert("ground placed");
            poses[0] = Pose { r: vec3(rng, 1.0), q: orientation(rng) };
        }
        let kinds = [Kind::Revolute, Kind::Prismatic, Kind::Cylindrical, Kind::Screw];
        let chain: Vec<Kind> = (0..n).map(|_| kinds[rng.random_range(0..4)]).collect();
        let aligned = (chain[0] != Kind::Prismatic && rng.random_bool(0.3))
            .then(|| rng.random_range(0..3_usize));
        for k in 1..=n {
            let q = match (k, aligned) {
                (1, Some(c)) => about(&Vector3::ith(c, 1.0), uniform(rng, -3.0, 3.0)),
                _ => orientation(rng),
            };
            poses[k] = Pose { r: poses[k - 1].r * 0.3 + vec3(rng, 1.0), q };
        }
        let mut draft = Draft { poses, joints: Vec::new(), dofs: Vec::new(), aligned, features };
        for (k, kind) in (1..=n).zip(chain) {
            draft.chain_joint(rng, k, kind);
        }
        draft
    }

    /// Chain joint k between bodies k − 1 and k, laid out globally (point, axis, reference,
    /// initial angle and axial offset) and then expressed in the two bodies' frames.
    fn chain_joint(&mut self, rng: &mut StdRng, k: usize, kind: Kind) {
        self.features.insert(match kind {
            Kind::Revolute => "joint revolute",
            Kind::Prismatic => "joint prismatic",
            Kind::Cylindrical => "joint cylindrical",
            _ => "joint screw",
        });
        let (a, b) = (self.poses[k - 1], self.poses[k]);
        let point = (a.r + b.r) * 0.5 + vec3(rng, 0.3);
        let axis = match (k, self.aligned) {
            (1, Some(c)) => Vector3::ith(c, if rng.random_bool(0.5) { 1.0 } else { -1.0 }),
            _ => unit(rng),
        };
        let reference = perpendicular(rng, &axis);
        // A prismatic joint holds ref_i ⟂ ref_j.
        let angle = match kind {
            Kind::Prismatic if rng.random_bool(0.5) => PI / 2.0,
            Kind::Prismatic => -PI / 2.0,
            _ => uniform(rng, -3.0, 3.0),
        };
        let offset = if kind == Kind::Revolute { 0.0 } else { uniform(rng, -0.3, 0.3) };
        let axis_j = if rng.random_bool(0.25) {
            self.features.insert("antiparallel axes");
            -axis
        } else {
            axis
        };
        let lead = (kind == Kind::Screw).then(|| {
            let l = uniform(rng, 0.2, 1.5);
            if rng.random_bool(0.3) { -l } else { l }
        });
        self.joints.push(JointSpec {
            name: format!("j{k}"),
            kind,
            body_i: k - 1,
            body_j: k,
            point_i: a.local_point(&point),
            point_j: b.local_point(&(point + axis * offset)),
            axis: Some((a.local_vector(&axis), b.local_vector(&axis_j))),
            reference: Some((
                a.local_vector(&reference),
                b.local_vector(&(about(&axis, angle) * reference)),
            )),
            lead,
            distance: None,
        });
        let mut dof = |motion, value| {
            self.dofs.push(Dof { joint: k, motion, value, holder: Holder::JointDriver });
        };
        match kind {
            Kind::Prismatic => dof(Motion::Translation, offset),
            Kind::Cylindrical => {
                dof(Motion::Rotation, angle);
                dof(Motion::Translation, offset);
            }
            _ => dof(Motion::Rotation, angle),
        }
    }

    /// Closes the chain with a spherical (3 equations), universal (4) or distance (1) joint
    /// between the last body and ground or an earlier body, and frees as many degrees of
    /// freedom of the loop; at least one stays driven.
    fn close(&mut self, rng: &mut StdRng) {
        let n = self.moving();
        let mut options = Vec::new();
        for partner in 0..n {
            let in_loop = self.dofs.iter().filter(|d| d.joint > partner).count();
            for (kind, rows) in [(Kind::Spherical, 3), (Kind::Universal, 4), (Kind::Distance, 1)] {
                if in_loop >= rows && self.dofs.len() > rows {
                    options.push((partner, kind, rows));
                }
            }
        }
        if options.is_empty() {
            return;
        }
        let (partner, kind, rows) = options[rng.random_range(0..options.len())];
        self.features.insert(match kind {
            Kind::Spherical => "closure spherical",
            Kind::Universal => "closure universal",
            _ => "closure distance",
        });
        self.features.insert(if partner == 0 { "closure to ground" } else { "closure to body" });
        let (a, b) = (self.poses[partner], self.poses[n]);
        let mut spec = JointSpec {
            name: "closure".to_owned(),
            kind,
            body_i: partner,
            body_j: n,
            point_i: Vector3::zeros(),
            point_j: Vector3::zeros(),
            axis: None,
            reference: None,
            lead: None,
            distance: None,
        };
        if kind == Kind::Distance {
            let (pa, pb) = loop {
                let (pa, pb) = (a.r + vec3(rng, 0.5), b.r + vec3(rng, 0.5));
                if (pb - pa).norm() > 0.3 {
                    break (pa, pb);
                }
            };
            (spec.point_i, spec.point_j) = (a.local_point(&pa), b.local_point(&pb));
            if rng.random_bool(0.5) {
                self.features.insert("distance given");
                spec.distance = Some((pb - pa).norm());
            }
        } else {
            let point = (a.r + b.r) * 0.5 + vec3(rng, 0.4);
            (spec.point_i, spec.point_j) = (a.local_point(&point), b.local_point(&point));
            if kind == Kind::Universal {
                // The cross-pin axes, ⟂ at assembly.
                let ua = unit(rng);
                let ub = perpendicular(rng, &ua);
                spec.axis = Some((a.local_vector(&ua), b.local_vector(&ub)));
            }
        }
        self.joints.push(spec);
        // A universal needs a rotation among the freed degrees of freedom to keep its axes
        // perpendicular.
        let in_loop: Vec<usize> =
            (0..self.dofs.len()).filter(|&d| self.dofs[d].joint > partner).collect();
        for tries in 1.. {
            let mut pool = in_loop.clone();
            let freed: Vec<usize> =
                (0..rows).map(|_| pool.swap_remove(rng.random_range(0..pool.len()))).collect();
            let rotation = freed.iter().any(|&d| self.dofs[d].motion == Motion::Rotation);
            if kind != Kind::Universal || rotation || tries > 10 {
                for d in freed {
                    self.dofs[d].holder = Holder::Free;
                }
                break;
            }
        }
    }

    /// Trades some joint drivers for a `fix`, a `coordinate_difference` or an absolute
    /// driver of a body the joint moves, and (mostly) the rotation driver of an aligned
    /// joint 1 for an absolute rx/ry/rz driver. One driver stays.
    fn trade_drivers(&mut self, rng: &mut StdRng) {
        let n = self.moving();
        let mut held: BTreeSet<(usize, usize)> = BTreeSet::new();
        let driven: Vec<usize> = (0..self.dofs.len())
            .filter(|&d| matches!(self.dofs[d].holder, Holder::JointDriver))
            .collect();
        let keep = driven[rng.random_range(0..driven.len())];
        for d in driven {
            let Dof { joint, motion, .. } = self.dofs[d];
            let turns_body_1 = joint == 1 && motion == Motion::Rotation;
            if let Some(c) = self.aligned
                && turns_body_1
                && rng.random_bool(0.6)
            {
                held.insert((1, 4 + c));
                self.dofs[d].holder = Holder::Rotation { body: 1, axis: c };
                continue;
            }
            if d == keep || !rng.random_bool(0.3) {
                continue;
            }
            // A body downstream of the joint, and one of its coordinates that the joint moves.
            let body = rng.random_range(joint..=n);
            let choices: &[usize] = match motion {
                Motion::Translation => &[0, 1, 2],
                Motion::Rotation => &[0, 1, 2, 4, 5, 6],
            };
            let coordinate = choices[rng.random_range(0..choices.len())];
            if let Some(c) = self.aligned
                && turns_body_1
                && body == 1
                && (coordinate == c || (coordinate >= 4 && coordinate != 4 + c))
            {
                // Body 1 turns about global axis c: this coordinate stays put.
                continue;
            }
            if !held.insert((body, coordinate)) {
                continue;
            }
            let pick = uniform(rng, 0.0, 1.0);
            self.dofs[d].holder = if pick < 0.3 {
                Holder::Fix { body, coordinate }
            } else if pick < 0.6 || (coordinate > 2 && pick < 0.8) {
                // Against ground, or against an upstream body that the joint does not move.
                let other =
                    if joint > 1 && rng.random_bool(0.3) { rng.random_range(1..joint) } else { 0 };
                if rng.random_bool(0.5) {
                    Holder::Difference { body_i: body, body_j: other, coordinate }
                } else {
                    Holder::Difference { body_i: other, body_j: body, coordinate }
                }
            } else if coordinate <= 2 {
                Holder::Coordinate { body, coordinate }
            } else {
                Holder::Fix { body, coordinate }
            };
        }
    }

    /// The initial estimates: the assembled poses, perturbed at random except for the
    /// bodies of a screw joint.
    fn estimates(&mut self, rng: &mut StdRng) -> Vec<[f64; 7]> {
        let mut estimates: Vec<[f64; 7]> = self.poses.iter().map(Pose::coordinates).collect();
        if rng.random_bool(0.35) {
            self.features.insert("estimates perturbed");
            for (k, e) in estimates.iter_mut().enumerate().skip(1) {
                let screw = self
                    .joints
                    .iter()
                    .any(|j| j.kind == Kind::Screw && (j.body_i == k || j.body_j == k));
                if !screw {
                    for x in e.iter_mut() {
                        *x += uniform(rng, -PERTURBATION, PERTURBATION);
                    }
                }
            }
        }
        estimates
    }

    /// The description: grid, solver, bodies, joints, constraints and drivers (laws drawn
    /// here), a point of interest.
    fn into_case(mut self, seed: u64, grid: Grid, rng: &mut StdRng) -> Case {
        let estimates = self.estimates(rng);
        let t0 = if rng.random_bool(0.6) { 0.0 } else { uniform(rng, -1.0, 1.0) };
        let steps = rng.random_range(grid.steps.0..=grid.steps.1);
        let h = if grid.step.0 < grid.step.1 {
            uniform(rng, grid.step.0, grid.step.1)
        } else {
            grid.step.0
        };
        let span = steps as f64 * h;
        let n = self.moving();
        let mut toml = String::new();
        let w = &mut toml;
        let _ = writeln!(w, "name = \"random_{seed}\"");
        let _ = writeln!(w, "description = \"random mechanism {seed}: {n} moving bodies\"\n");
        let _ = writeln!(w, "[time]\nstart = {}\nend = {}", num(t0), num(t0 + span));
        if rng.random_bool(0.3) {
            self.features.insert("grid by step");
            let _ = writeln!(w, "step = {}\n", num(h));
        } else {
            let _ = writeln!(w, "steps = {steps}\n");
        }
        // Newton well below the engines' agreement bound, so that comparisons see the
        // equations rather than where each Newton happened to stop.
        let _ = writeln!(w, "[solver]\ntolerance = {}\n", num(TOLERANCE));
        for (k, e) in estimates.iter().enumerate() {
            let _ = writeln!(w, "[[bodies]]\nname = \"{}\"", body_name(k));
            if k == 0 {
                let _ = writeln!(w, "ground = true");
            }
            let _ = writeln!(w, "r = [{}, {}, {}]", num(e[0]), num(e[1]), num(e[2]));
            let _ =
                writeln!(w, "p = [{}, {}, {}, {}]\n", num(e[3]), num(e[4]), num(e[5]), num(e[6]));
        }
        for j in &self.joints {
            j.write(w);
        }
        self.write_holders(w, rng, (t0, span));
        let _ = writeln!(
            w,
            "[[points]]\nname = \"tip\"\nbody = \"b{n}\"\nlocal = {}",
            v3(&vec3(rng, 0.5))
        );
        Case { seed, toml, features: self.features }
    }

    /// The constraints and drivers that hold the degrees of freedom, with the values of the
    /// assembled pose and laws that start there at t0.
    fn write_holders(&mut self, w: &mut String, rng: &mut StdRng, (t0, span): (f64, f64)) {
        let assembled: Vec<[f64; 7]> = self.poses.iter().map(Pose::coordinates).collect();
        let features = &mut self.features;
        let (mut constraints, mut drivers) = (String::new(), String::new());
        for (k, dof) in self.dofs.iter().enumerate() {
            let name = format!("h{k}");
            match dof.holder {
                Holder::Free => {}
                Holder::JointDriver => {
                    let (motion, rate) = match dof.motion {
                        Motion::Rotation => ("rotation", ROTATION_RATE),
                        Motion::Translation => ("translation", TRANSLATION_RATE),
                    };
                    features.insert(if dof.motion == Motion::Rotation {
                        "driver rotation"
                    } else {
                        "driver translation"
                    });
                    let law = law(rng, features, dof.value, (t0, span), rate);
                    let _ = writeln!(
                        drivers,
                        "[[drivers]]\nname = \"{name}\"\njoint = \"j{}\"",
                        dof.joint
                    );
                    let _ = writeln!(drivers, "motion = \"{motion}\"\nlaw = {law}\n");
                }
                Holder::Fix { body, coordinate } => {
                    features.insert("constraint fix");
                    let _ =
                        writeln!(constraints, "[[constraints]]\nname = \"{name}\"\ntype = \"fix\"");
                    let _ = writeln!(
                        constraints,
                        "body = \"b{body}\"\ncoordinate = \"{}\"",
                        COORDINATES[coordinate]
                    );
                    let _ = writeln!(constraints, "value = {}\n", num(assembled[body][coordinate]));
                }
                Holder::Difference { body_i, body_j, coordinate } => {
                    features.insert(if body_i == 0 || body_j == 0 {
                        "constraint coordinate_difference to ground"
                    } else {
                        "constraint coordinate_difference between bodies"
                    });
                    let value = assembled[body_i][coordinate] - assembled[body_j][coordinate];
                    let _ = writeln!(
                        constraints,
                        "[[constraints]]\nname = \"{name}\"\ntype = \"coordinate_difference\""
                    );
                    let _ = writeln!(
                        constraints,
                        "body_i = \"{}\"\nbody_j = \"{}\"",
                        body_name(body_i),
                        body_name(body_j)
                    );
                    let _ = writeln!(
                        constraints,
                        "coordinate = \"{}\"\nvalue = {}\n",
                        COORDINATES[coordinate],
                        num(value)
                    );
                }
                Holder::Coordinate { body, coordinate } => {
                    features.insert(["driver x", "driver y", "driver z"][coordinate]);
                    let start = assembled[body][coordinate];
                    let law = law(rng, features, start, (t0, span), COORDINATE_RATE);
                    let _ = writeln!(drivers, "[[drivers]]\nname = \"{name}\"\nbody = \"b{body}\"");
                    let _ = writeln!(
                        drivers,
                        "coordinate = \"{}\"\nlaw = {law}\n",
                        COORDINATES[coordinate]
                    );
                }
                Holder::Rotation { body, axis } => {
                    features.insert(["driver rx", "driver ry", "driver rz"][axis]);
                    // Body 1 is a pure rotation about e_axis: the driver's angle s has
                    // e_k cos(s/2) = e0 sin(s/2).
                    let start = 2.0 * assembled[body][4 + axis].atan2(assembled[body][3]);
                    let law = law(rng, features, start, (t0, span), ROTATION_RATE);
                    let _ = writeln!(drivers, "[[drivers]]\nname = \"{name}\"\nbody = \"b{body}\"");
                    let _ = writeln!(
                        drivers,
                        "coordinate = \"{}\"\nlaw = {law}\n",
                        ["rx", "ry", "rz"][axis]
                    );
                }
            }
        }
        w.push_str(&constraints);
        w.push_str(&drivers);
    }
}

/// `ground` or `b{k}`.
fn body_name(k: usize) -> String {
    if k == 0 { "ground".to_owned() } else { format!("b{k}") }
}

impl JointSpec {
    /// The `[[joints]]` entry.
    fn write(&self, w: &mut String) {
        let _ =
            writeln!(w, "[[joints]]\nname = \"{}\"\ntype = \"{}\"", self.name, self.kind.name());
        let _ = writeln!(
            w,
            "body_i = \"{}\"\nbody_j = \"{}\"",
            body_name(self.body_i),
            body_name(self.body_j)
        );
        let _ = writeln!(w, "point_i = {}\npoint_j = {}", v3(&self.point_i), v3(&self.point_j));
        if let Some((ai, aj)) = &self.axis {
            let _ = writeln!(w, "axis_i = {}\naxis_j = {}", v3(ai), v3(aj));
        }
        if let Some((ri, rj)) = &self.reference {
            let _ = writeln!(w, "ref_i = {}\nref_j = {}", v3(ri), v3(rj));
        }
        if let Some(lead) = self.lead {
            let _ = writeln!(w, "lead = {}", num(lead));
        }
        if let Some(d) = self.distance {
            let _ = writeln!(w, "distance = {}", num(d));
        }
        let _ = writeln!(w);
    }
}
