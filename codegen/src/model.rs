//! The validated mechanism: resolved references, normalised vectors, derived constants.
//!
//! A `model::Mechanism` is only built by `validate`, so every engine may rely on its
//! invariants: names are unique, every id indexes its vector, every direction is a unit
//! vector, reference directions are ⟂ their axis, `p` has unit norm, the time grid is
//! non-empty and bounded.

use nalgebra::{Vector3, Vector4};

pub mod frame;
mod joints;
mod rows;

pub use crate::desc::{CoordinateName, DriverCoordinate, JointType, Motion};
pub use joints::{DeckRecord, JOINT_TYPES, JointSpec, Need, docs_row};
pub use rows::RowLabel;

/// The type a generated module declares for the mechanism `name`: `rssr` → `Rssr`,
/// `four_bar` → `FourBar`, `ex_2_6_1` → `Ex261`. Validation checks that it is a usable Rust
/// type name, the emitter and the engine's driver use it.
#[must_use]
pub fn type_name(name: &str) -> String {
    name.split('_')
        .map(|w| {
            let mut c = w.chars();
            c.next().map_or_else(String::new, |f| f.to_ascii_uppercase().to_string() + c.as_str())
        })
        .collect()
}

/// Index of a body in [`Mechanism::bodies`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct BodyId(pub usize);

/// Index of a point of interest in [`Mechanism::points`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct PointId(pub usize);

/// Index of a joint in [`Mechanism::joints`].
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct JointId(pub usize);

/// A validated mechanism.
#[derive(Clone, Debug, PartialEq)]
pub struct Mechanism {
    /// `[a-z][a-z0-9_]*`.
    pub name: String,
    /// Free text from the description.
    pub description: Option<String>,
    /// The analysis grid.
    pub time: TimeGrid,
    /// Newton controls.
    pub solver: SolverOptions,
    /// All bodies, ground ones included, in file order.
    pub bodies: Vec<Body>,
    /// All joints in file order.
    pub joints: Vec<Joint>,
    /// `fix` and `coordinate_difference` constraints in file order.
    pub constraints: Vec<Constraint>,
    /// Drivers in file order.
    pub drivers: Vec<Driver>,
    /// Points of interest in file order.
    pub points: Vec<Point>,
}

/// The time points `start + k·step`, `k = 0 … count − 1`, or those of a replayed series
/// of recorded inputs (`solve --inputs`).
#[derive(Clone, Debug, PartialEq)]
pub struct TimeGrid {
    /// First time point.
    pub start: f64,
    /// Spacing (> 0); for a replay, the mean spacing.
    pub step: f64,
    /// Number of time points (≥ 1, ≤ 10,000,000).
    pub count: usize,
    /// The recorded inputs whose rows are the time points, when replaying.
    pub replay: Option<std::sync::Arc<crate::inputs::Replay>>,
}

impl TimeGrid {
    /// The grid `start + k·step`, `k < count`.
    #[must_use]
    pub fn uniform(start: f64, step: f64, count: usize) -> Self {
        Self { start, step, count, replay: None }
    }

    /// The time points of a replayed series (non-empty, strictly increasing).
    #[must_use]
    pub fn replaying(replay: std::sync::Arc<crate::inputs::Replay>) -> Self {
        let count = replay.t.len();
        let (first, last) = (replay.t[0], replay.t[count - 1]);
        let step = if count > 1 { (last - first) / (count - 1) as f64 } else { 1.0 };
        Self { start: first, step, count, replay: Some(replay) }
    }

    /// The description's own `[time]` grid: this one, or the one a replay replaced.
    #[must_use]
    pub fn declared(&self) -> Self {
        match &self.replay {
            Some(r) => {
                let (start, step, count) = r.declared;
                Self::uniform(start, step, count)
            }
            None => self.clone(),
        }
    }

    /// The k-th time point, computed without accumulating sums.
    #[must_use]
    pub fn at(&self, k: usize) -> f64 {
        match &self.replay {
            Some(r) => r.t[k],
            None => self.start + k as f64 * self.step,
        }
    }

    /// Whether point k is among `bound` (≥ 2) evenly spaced points of the grid: every point
    /// when there are at most `bound`, else the points round(j (count − 1) / (bound − 1)) for
    /// j = 0, …, bound − 1, the first and the last among them. Lets a pass over the grid keep
    /// a bounded sample of it without allocating.
    #[must_use]
    pub fn sampled(&self, k: usize, bound: usize) -> bool {
        if self.count <= bound {
            return true;
        }
        // Integer arithmetic: count ≤ 10⁷ and bound ≤ count, so the products fit in u128
        // with room to spare, and rounding is exact.
        let (last, gaps) = ((self.count - 1) as u128, (bound.max(2) - 1) as u128);
        let point = |j: u128| (2 * j * last + gaps) / (2 * gaps);
        let j = k as u128 * gaps / last;
        (j.saturating_sub(1)..=(j + 1).min(gaps)).any(|j| point(j) == k as u128)
    }
}

/// Newton controls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolverOptions {
    /// Converged when max |Φ_i| ≤ tolerance.
    pub tolerance: f64,
    /// Upper bound on iterations per time point.
    pub max_iterations: u32,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self { tolerance: 1e-10, max_iterations: 25 }
    }
}

/// A body: its initial estimate, or for a ground body its fixed placement.
#[derive(Clone, Debug, PartialEq)]
pub struct Body {
    /// Unique name.
    pub name: String,
    /// All 7 coordinates fixed.
    pub ground: bool,
    /// Origin of the body frame, global.
    pub r: Vector3<f64>,
    /// Euler parameters `[e0, e1, e2, e3]`, normalised.
    pub p: Vector4<f64>,
}

/// A joint between two bodies. Which optional members are present depends on `kind`
/// (the table of the contract): `axis` for all but spherical and distance, `reference`
/// for prismatic and screw and for rotation-driven revolute and cylindrical joints.
#[derive(Clone, Debug, PartialEq)]
pub struct Joint {
    /// Unique name.
    pub name: String,
    /// First body.
    pub body_i: BodyId,
    /// Second body.
    pub body_j: BodyId,
    /// Joint point on body i, local.
    pub point_i: Vector3<f64>,
    /// Joint point on body j, local.
    pub point_j: Vector3<f64>,
    /// Unit axes `(axis_i, axis_j)`, local to their bodies.
    pub axis: Option<(Vector3<f64>, Vector3<f64>)>,
    /// Unit reference directions `(ref_i, ref_j)`, each ⟂ its axis, local.
    pub reference: Option<(Vector3<f64>, Vector3<f64>)>,
    /// The joint type and its type-specific data.
    pub kind: JointKind,
}

impl Joint {
    /// Body-i unit vectors (b, c) ⟂ axis_i used by the parallel-axis rows b·a_j = 0,
    /// c·a_j = 0: (ref_i, axis_i × ref_i) when the joint has references, else the
    /// completion of axis_i by the coordinate axis least aligned with it. Both engines use
    /// these, so they write the same equations.
    #[must_use]
    pub fn normals(&self) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let (a, _) = self.axis?;
        let b = match self.reference {
            Some((r, _)) => r,
            None => {
                let k = a.iamin();
                let mut e = Vector3::zeros();
                e[k] = 1.0;
                (e - a * a.dot(&e)).normalize()
            }
        };
        Some((b, a.cross(&b)))
    }
}

/// Joint types with the data only they carry; their fields and rows are described by
/// [`JOINT_TYPES`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum JointKind {
    /// Points coincide.
    Spherical,
    /// Points coincide, axis_i ⟂ axis_j.
    Universal,
    /// Points coincide, axes parallel.
    Revolute,
    /// Axes parallel, P_j − P_i parallel to the axis.
    Cylindrical,
    /// Cylindrical plus ref_i ⟂ ref_j.
    Prismatic,
    /// Cylindrical plus d − d0 = lead·(θ − θ0)/(2π).
    Screw {
        /// Axial advance per full turn (non-zero).
        lead: f64,
        /// d = (P_j − P_i)·axis_i at the initial estimates.
        d0: f64,
        /// θ, the angle from ref_i to ref_j about axis_i, at the initial estimates, in (−π, π].
        theta0: f64,
    },
    /// |P_j − P_i| = length.
    Distance {
        /// The rod length (> 0).
        length: f64,
    },
}

impl JointKind {
    /// The spelling used in description files.
    #[must_use]
    pub fn type_name(&self) -> &'static str {
        self.joint_type().as_str()
    }

    /// Number of constraint equations the joint contributes ([`JointSpec::rows`]).
    #[must_use]
    pub fn equations(&self) -> usize {
        self.spec().rows.len()
    }
}

/// A constraint that is not a joint (one equation).
#[derive(Clone, Debug, PartialEq)]
pub struct Constraint {
    /// Unique name.
    pub name: String,
    /// What it constrains.
    pub kind: ConstraintKind,
}

/// The two simplified constraints of the thesis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ConstraintKind {
    /// `q_body[coordinate] = value`; `body` is never a ground body.
    Fix {
        /// The body.
        body: BodyId,
        /// The coordinate.
        coordinate: CoordinateName,
        /// The value.
        value: f64,
    },
    /// `q_i[c] − q_j[c] = value`; at most one of the bodies is ground.
    CoordinateDifference {
        /// First body.
        body_i: BodyId,
        /// Second body.
        body_j: BodyId,
        /// The coordinate.
        coordinate: CoordinateName,
        /// The difference.
        value: f64,
    },
}

/// A driver: one equation `f(q) = s(t)` in the form the engines choose.
#[derive(Clone, Debug, PartialEq)]
pub struct Driver {
    /// Unique name.
    pub name: String,
    /// What is driven.
    pub target: DriverTarget,
    /// s(t).
    pub law: Law,
}

/// What a driver moves.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum DriverTarget {
    /// A joint's angle (revolute, cylindrical, screw; the joint has references) or
    /// translation (prismatic, cylindrical).
    Joint {
        /// The joint.
        joint: JointId,
        /// Rotation or translation.
        motion: Motion,
    },
    /// A body coordinate or a rotation about a global axis; `body` is never ground.
    Absolute {
        /// The body.
        body: BodyId,
        /// The coordinate.
        coordinate: DriverCoordinate,
    },
    /// A global coordinate of a point of interest, on a body that is not ground.
    Point {
        /// The point.
        point: PointId,
        /// 0, 1 or 2 for x, y or z.
        axis: usize,
    },
    /// The driven length of a U-P-S leg whose cylinder and rod are left out, as one distance
    /// equation between the bodies the leg joins. No description states it: only
    /// `blocks::outputs` makes one, from a driver of a prismatic joint that the generator
    /// reduced (`symbolic::legs`), when no requested output needs the leg's bodies.
    Leg(Leg),
}

/// A U-P-S (or S-P-U) leg reduced to the distance between its end points: with U the
/// universal joint's point on the body it joins, S the spherical joint's, and s the prismatic
/// joint's translation, |S − U|² = s² + 2 s·along + base, written as the row
/// (|S − U|² − s² − 2 s·along − base) / (2 length).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Leg {
    /// The body of the universal joint's end (U), never one of the leg's own bodies.
    pub body_i: BodyId,
    /// U, local to `body_i`.
    pub point_i: Vector3<f64>,
    /// The body of the spherical joint's end (S).
    pub body_j: BodyId,
    /// S, local to `body_j`.
    pub point_j: Vector3<f64>,
    /// v0·a: S − U = A_c (±s a + v0) with a the prismatic axis and v0 constant in the
    /// cylinder's frame; the sign is folded in.
    pub along: f64,
    /// |v0|².
    pub base: f64,
    /// |S − U| at the assembled configuration where the leg was reduced: the row's scale.
    pub length: f64,
    /// The sign of s + along there: which root of the quadratic the leg is on.
    pub branch: f64,
}

impl Leg {
    /// The driven length s that the distance |S − U| = `distance` means on the leg's branch:
    /// s = −along + branch·√(distance² − base + along²), the radicand clamped at 0.
    #[must_use]
    pub fn length_of(&self, distance: f64) -> f64 {
        let radicand = (distance * distance - self.base + self.along * self.along).max(0.0);
        -self.along + self.branch * radicand.sqrt()
    }
}

/// A motion law s(t).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Law {
    /// s(t) = start + velocity·t + acceleration·t²/2 (thesis eq. 4.59).
    Polynomial {
        /// s0.
        start: f64,
        /// v0.
        velocity: f64,
        /// a.
        acceleration: f64,
    },
    /// s(t) = offset + amplitude·sin(frequency·t + phase).
    Harmonic {
        /// c.
        offset: f64,
        /// A.
        amplitude: f64,
        /// w.
        frequency: f64,
        /// φ.
        phase: f64,
    },
    /// `law = "input"`: s, ṡ, s̈ are supplied at run time ([`Mechanism::drive`]).
    Input,
}

impl Law {
    /// `(s, ṡ, s̈)` at time `t`; an input has no law and gives zeros (engines ask
    /// [`Mechanism::drive`], which knows the inputs).
    #[must_use]
    pub fn eval(&self, t: f64) -> (f64, f64, f64) {
        match *self {
            Self::Input => (0.0, 0.0, 0.0),
            Self::Polynomial { start, velocity, acceleration } => (
                start + velocity * t + 0.5 * acceleration * t * t,
                velocity + acceleration * t,
                acceleration,
            ),
            Self::Harmonic { offset, amplitude, frequency, phase } => {
                let (sin, cos) = (frequency * t + phase).sin_cos();
                (
                    offset + amplitude * sin,
                    amplitude * frequency * cos,
                    -amplitude * frequency * frequency * sin,
                )
            }
        }
    }
}

/// A point of interest.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// Unique name.
    pub name: String,
    /// The body it is fixed to.
    pub body: BodyId,
    /// Its coordinates in the body frame.
    pub local: Vector3<f64>,
}

impl Mechanism {
    /// `(s, ṡ, s̈)` of driver `k` at time `t`: its law, or for an input driver the replayed
    /// series interpolated at t (`runtime::input::sample`), or, with no series, the value
    /// `held` gives (engines pass the driven quantity at the initial estimates, so that
    /// `check` and the assembly of a description with inputs see a consistent driver).
    #[must_use]
    pub fn drive(&self, k: usize, t: f64, held: impl FnOnce() -> f64) -> (f64, f64, f64) {
        let d = &self.drivers[k];
        match d.law {
            Law::Input => {
                match self.time.replay.as_ref().and_then(|r| Some((&r.t, r.series(k)?))) {
                    Some((times, values)) => {
                        let [s, sd, sdd] = runtime::input::sample(times, values, t);
                        (s, sd, sdd)
                    }
                    None => (held(), 0.0, 0.0),
                }
            }
            _ => d.law.eval(t),
        }
    }

    /// The names of the input drivers, in file order.
    #[must_use]
    pub fn input_drivers(&self) -> Vec<&str> {
        self.drivers.iter().filter(|d| d.law == Law::Input).map(|d| d.name.as_str()).collect()
    }

    /// Bodies that carry unknowns (all but ground), in file order.
    pub fn moving_bodies(&self) -> impl Iterator<Item = BodyId> + '_ {
        self.bodies.iter().enumerate().filter(|(_, b)| !b.ground).map(|(k, _)| BodyId(k))
    }

    /// Number of unknowns: 7 per non-ground body.
    #[must_use]
    pub fn unknowns(&self) -> usize {
        7 * self.moving_bodies().count()
    }

    /// Number of equations: joint rows, constraint rows, driver rows and one Euler-parameter
    /// normalisation per non-ground body.
    #[must_use]
    pub fn equations(&self) -> usize {
        self.joints.iter().map(|j| j.kind.equations()).sum::<usize>()
            + self.constraints.len()
            + self.drivers.len()
            + self.moving_bodies().count()
    }
}
