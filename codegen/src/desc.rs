//! The description file as written: serde types that mirror the TOML/JSON format 1:1.
//!
//! Nothing here is checked beyond what serde checks (field names, types, enum spellings):
//! `validate` turns a [`MechanismDesc`] into a `model::Mechanism` and reports every semantic
//! problem with the entity, the field and the place in the file. The format is specified in
//! `docs/contract.md` §1.

use serde::{Deserialize, Serialize};

/// A whole description file.
///
/// ```toml
/// name = "rssr"
/// [time]
/// start = 0.0
/// end = 0.04
/// step = 0.001
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MechanismDesc {
    /// `[a-z][a-z0-9_]*`, also the generated module's name.
    pub name: String,
    /// Free text.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// The analysis grid.
    pub time: TimeDesc,
    /// Newton controls; defaults apply when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solver: Option<SolverDesc>,
    /// `[[bodies]]`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub bodies: Vec<BodyDesc>,
    /// `[[joints]]`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub joints: Vec<JointDesc>,
    /// `[[constraints]]`: constraints that are not joints.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constraints: Vec<ConstraintDesc>,
    /// `[[drivers]]`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub drivers: Vec<DriverDesc>,
    /// `[[points]]`: points of interest reported every step.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub points: Vec<PointDesc>,
}

/// `[time]`: `start`, `end` and either `step` or `steps` (the number of intervals).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TimeDesc {
    /// First time point.
    pub start: f64,
    /// Last time point (inclusive, within step/1000).
    pub end: f64,
    /// Spacing of the grid.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub step: Option<f64>,
    /// Number of intervals; replaces `step`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub steps: Option<u64>,
}

/// `[solver]`: `tolerance = 1e-10`, `max_iterations = 25` by default.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolverDesc {
    /// Newton converges when max |Φ_i| ≤ tolerance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tolerance: Option<f64>,
    /// Upper bound on Newton iterations per time point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_iterations: Option<u32>,
}

/// `[[bodies]]`: a rigid body with 7 coordinates, or a ground body with none.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyDesc {
    /// Unique body name.
    pub name: String,
    /// A ground body has all 7 coordinates fixed at `r`, `p`.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub ground: bool,
    /// Initial estimate of the body frame origin, global (default origin).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub r: Option<[f64; 3]>,
    /// Initial estimate of the Euler parameters `[e0, e1, e2, e3]` (default identity).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub p: Option<[f64; 4]>,
}

/// The joint types of the contract's table (fields and rows: `model::JOINT_TYPES`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointType {
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
    /// Cylindrical plus the helix d − d0 = lead·(θ − θ0)/(2π).
    Screw,
    /// |P_j − P_i| = distance.
    Distance,
}

impl JointType {
    /// The spelling used in description files.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::Spherical => "spherical",
            Self::Universal => "universal",
            Self::Revolute => "revolute",
            Self::Cylindrical => "cylindrical",
            Self::Prismatic => "prismatic",
            Self::Screw => "screw",
            Self::Distance => "distance",
        }
    }
}

/// `[[joints]]`: one flat record; which fields a type needs is checked by `validate`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointDesc {
    /// Unique among joints, constraints and drivers.
    pub name: String,
    /// The joint type.
    #[serde(rename = "type")]
    pub kind: JointType,
    /// First body.
    pub body_i: String,
    /// Second body.
    pub body_j: String,
    /// Joint point, local to body i.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point_i: Option<[f64; 3]>,
    /// Joint point, local to body j.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point_j: Option<[f64; 3]>,
    /// Joint axis, local to body i.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_i: Option<[f64; 3]>,
    /// Joint axis, local to body j.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis_j: Option<[f64; 3]>,
    /// Reference direction ⟂ axis_i, local to body i.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ref_i: Option<[f64; 3]>,
    /// Reference direction ⟂ axis_j, local to body j.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ref_j: Option<[f64; 3]>,
    /// Screw: axial advance of j relative to i per full turn (length).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lead: Option<f64>,
    /// Distance joint: the rod length (taken from the initial estimates when absent).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distance: Option<f64>,
}

/// The constraint types that are not joints.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ConstraintType {
    /// `q_body[coordinate] = value`.
    Fix,
    /// `q_i[c] − q_j[c] = value` (the thesis' "distance constraint", NSIMP2).
    CoordinateDifference,
}

/// A coordinate that `fix` and `coordinate_difference` may name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CoordinateName {
    /// Body origin, global x.
    X,
    /// Body origin, global y.
    Y,
    /// Body origin, global z.
    Z,
    /// Euler parameter e1.
    E1,
    /// Euler parameter e2.
    E2,
    /// Euler parameter e3.
    E3,
}

impl CoordinateName {
    /// The spelling used in description files.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::X => "x",
            Self::Y => "y",
            Self::Z => "z",
            Self::E1 => "e1",
            Self::E2 => "e2",
            Self::E3 => "e3",
        }
    }

    /// Index of the coordinate in a body's `[x, y, z, e0, e1, e2, e3]`.
    #[must_use]
    pub fn index(self) -> usize {
        match self {
            Self::X => 0,
            Self::Y => 1,
            Self::Z => 2,
            Self::E1 => 4,
            Self::E2 => 5,
            Self::E3 => 6,
        }
    }
}

/// `[[constraints]]`: one flat record; `fix` uses `body`, `coordinate_difference` uses
/// `body_i` and `body_j`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConstraintDesc {
    /// Unique among joints, constraints and drivers.
    pub name: String,
    /// The constraint type.
    #[serde(rename = "type")]
    pub kind: ConstraintType,
    /// `fix`: the body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body: Option<String>,
    /// `coordinate_difference`: the first body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_i: Option<String>,
    /// `coordinate_difference`: the second body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body_j: Option<String>,
    /// The coordinate constrained.
    pub coordinate: CoordinateName,
    /// The value it is held at (or the difference).
    pub value: f64,
}

/// What a joint driver moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Motion {
    /// The joint angle from ref_i to ref_j, right-handed about axis_i.
    Rotation,
    /// `(P_j − P_i)·axis_i` in global components.
    Translation,
}

/// The coordinate an absolute driver moves.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum DriverCoordinate {
    /// Body origin, global x.
    X,
    /// Body origin, global y.
    Y,
    /// Body origin, global z.
    Z,
    /// Rotation about the global x axis from the identity orientation.
    Rx,
    /// Rotation about the global y axis.
    Ry,
    /// Rotation about the global z axis.
    Rz,
    /// Euler parameter e1 (q_body[e1] = s).
    E1,
    /// Euler parameter e2.
    E2,
    /// Euler parameter e3.
    E3,
}

impl DriverCoordinate {
    /// The spelling used in description files.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        match self {
            Self::X => "x",
            Self::Y => "y",
            Self::Z => "z",
            Self::Rx => "rx",
            Self::Ry => "ry",
            Self::Rz => "rz",
            Self::E1 => "e1",
            Self::E2 => "e2",
            Self::E3 => "e3",
        }
    }
}

/// `law`: either the polynomial `{ start, velocity, acceleration }` or the harmonic
/// `{ offset, amplitude, frequency, phase }`; missing members of the chosen form are 0.
/// The string `"input"` instead of a table makes the driver a run-time input (`input` set,
/// every member `None`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LawDesc {
    /// s0 in s(t) = s0 + v0·t + a·t²/2.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start: Option<f64>,
    /// v0.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<f64>,
    /// a.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub acceleration: Option<f64>,
    /// c in s(t) = c + A·sin(w·t + φ).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset: Option<f64>,
    /// A.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amplitude: Option<f64>,
    /// w (rad/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frequency: Option<f64>,
    /// φ (rad).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub phase: Option<f64>,
    /// `law = "input"`: s, ṡ and s̈ are supplied at run time.
    #[serde(skip)]
    pub input: bool,
}

/// The `law` key: the string `"input"` or a law table, with the table's own diagnostics
/// (unknown members keep their place in the file).
mod law_or_input {
    use std::fmt;

    use serde::de::{self, MapAccess, Visitor};
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    use super::LawDesc;

    pub(super) fn serialize<S: Serializer>(law: &LawDesc, ser: S) -> Result<S::Ok, S::Error> {
        if law.input { ser.serialize_str("input") } else { law.serialize(ser) }
    }

    pub(super) fn deserialize<'de, D: Deserializer<'de>>(de: D) -> Result<LawDesc, D::Error> {
        de.deserialize_any(LawVisitor)
    }

    struct LawVisitor;

    impl<'de> Visitor<'de> for LawVisitor {
        type Value = LawDesc;

        fn expecting(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            f.write_str("a law table ({ start, velocity, acceleration } or { offset, amplitude, frequency, phase }) or the string \"input\"")
        }

        fn visit_str<E: de::Error>(self, v: &str) -> Result<LawDesc, E> {
            if v == "input" {
                Ok(LawDesc { input: true, ..LawDesc::default() })
            } else {
                Err(E::unknown_variant(v, &["input"]))
            }
        }

        fn visit_map<A: MapAccess<'de>>(self, map: A) -> Result<LawDesc, A::Error> {
            LawDesc::deserialize(de::value::MapAccessDeserializer::new(map))
        }
    }
}

/// `[[drivers]]`: a joint driver (`joint`, `motion`), an absolute one (`body`, `coordinate`)
/// or a point driver (`point`, `coordinate` x, y or z).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DriverDesc {
    /// Unique among joints, constraints and drivers.
    pub name: String,
    /// Joint driver: the joint.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub joint: Option<String>,
    /// Joint driver: rotation or translation.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub motion: Option<Motion>,
    /// Absolute driver: the body.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub body: Option<String>,
    /// Point driver: the point of interest whose global coordinate is driven.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<String>,
    /// Absolute or point driver: the coordinate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub coordinate: Option<DriverCoordinate>,
    /// The motion law s(t), or `"input"`.
    #[serde(with = "law_or_input")]
    pub law: LawDesc,
}

/// `[[points]]`: a point of interest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PointDesc {
    /// Unique point name.
    pub name: String,
    /// The body it is fixed to.
    pub body: String,
    /// Its coordinates in the body frame.
    pub local: [f64; 3],
}
