//! The rules for joints: bodies, the fields each type needs (`model::JOINT_TYPES`), vectors,
//! the screw's lead and origin, the distance's length.

use nalgebra::Vector3;

use super::{At, MAX_MAGNITUDE, PERPENDICULAR, Rules, ZERO_LENGTH};
use crate::desc::{JointDesc, JointType};
use crate::model::frame::{self, rotation};
use crate::model::{self, BodyId, JointKind, JointSpec, Need};

/// What a missing joint field is, for the message that asks for it.
fn joint_field_meaning(field: &str) -> &'static str {
    match field {
        "point_i" => "the joint point on body i, local; it has no default",
        "point_j" => "the joint point on body j, local; it has no default",
        "axis_i" => "the joint axis, local to body i",
        "axis_j" => "the joint axis, local to body j",
        "ref_i" => "a reference direction ⟂ axis_i, local to body i",
        "ref_j" => "a reference direction ⟂ axis_j, local to body j",
        "lead" => "the axial advance of j relative to i per full turn",
        _ => "",
    }
}

/// Which of a joint's vector fields are given and used.
struct Used {
    point_i: bool,
    point_j: bool,
    axis_i: bool,
    axis_j: bool,
    ref_i: bool,
    ref_j: bool,
}

/// A joint's vector fields as read (`None` when absent, unused or invalid).
struct Vectors {
    point_i: Option<Vector3<f64>>,
    point_j: Option<Vector3<f64>>,
    axis_i: Option<Vector3<f64>>,
    axis_j: Option<Vector3<f64>>,
    ref_i: Option<Vector3<f64>>,
    ref_j: Option<Vector3<f64>>,
    /// Both references given and used.
    refs_given: bool,
}

impl Rules<'_> {
    /// Rules for a joint: known, distinct bodies not both ground; the fields its type needs,
    /// and no others; finite points, non-zero axes, refs ⟂ axes; the screw's lead and the
    /// distance's length.
    pub(super) fn joint(
        &mut self,
        k: usize,
        j: &JointDesc,
        bodies: &[Option<model::Body>],
    ) -> Option<model::Joint> {
        let at = At::item("joint", &j.name, "joints", k);
        let body_i = self.body_ref(&at, "body_i", &j.body_i);
        let body_j = self.body_ref(&at, "body_j", &j.body_j);
        if let (Some(bi), Some(bj)) = (body_i, body_j) {
            self.joint_bodies(&at, bi, bj);
        }
        let needs = j.kind.spec();
        let Vectors { point_i, point_j, axis_i, axis_j, ref_i, ref_j, refs_given } =
            self.joint_vectors(&at, j, needs);
        let lead = j.lead.filter(|_| needs.lead != Need::Unused).and_then(|l| self.lead(&at, l));
        let length = j.distance.filter(|_| needs.distance != Need::Unused);
        let length_ok = length.is_none_or(|d| self.length(&at, d));

        // Everything below needs the joint to be complete and valid.
        let (bi, bj) = (body_i?, body_j?);
        let (point_i, point_j) = (point_i?, point_j?);
        let axis = match needs.axes {
            Need::Unused => None,
            _ => Some((axis_i?, axis_j?)),
        };
        let reference = match (needs.refs, refs_given) {
            (Need::Unused, _) | (Need::Optional, false) => None,
            _ => Some((ref_i?, ref_j?)),
        };
        let kind = match j.kind {
            JointType::Spherical => JointKind::Spherical,
            JointType::Universal => JointKind::Universal,
            JointType::Revolute => JointKind::Revolute,
            JointType::Cylindrical => JointKind::Cylindrical,
            JointType::Prismatic => JointKind::Prismatic,
            JointType::Screw => {
                let (place_i, place_j) = (bodies[bi.0].as_ref()?, bodies[bj.0].as_ref()?);
                let (axis, reference) = (axis?, reference?);
                let (d0, theta0) =
                    screw_origin(place_i, place_j, point_i, point_j, axis, reference);
                JointKind::Screw { lead: lead?, d0, theta0 }
            }
            JointType::Distance => {
                if !length_ok {
                    return None;
                }
                let length = match length {
                    Some(d) => d,
                    None => {
                        let (place_i, place_j) = (bodies[bi.0].as_ref()?, bodies[bj.0].as_ref()?);
                        self.initial_length(&at, place_i, place_j, &point_i, &point_j)?
                    }
                };
                JointKind::Distance { length }
            }
        };
        Some(model::Joint {
            name: j.name.clone(),
            body_i: bi,
            body_j: bj,
            point_i,
            point_j,
            axis,
            reference,
            kind,
        })
    }

    /// Rules: the joint gives the fields its type requires, not those it does not use, and
    /// optional references in pairs (the table [`crate::model::JOINT_TYPES`]).
    fn joint_usage(&mut self, at: &At, j: &JointDesc, needs: &JointSpec) -> Used {
        let ty = j.kind.as_str();
        let mut usage =
            |field: &str, given: bool, need: Need| self.usage(at, ty, field, given, need);
        let used = Used {
            point_i: usage("point_i", j.point_i.is_some(), Need::Required),
            point_j: usage("point_j", j.point_j.is_some(), Need::Required),
            axis_i: usage("axis_i", j.axis_i.is_some(), needs.axes),
            axis_j: usage("axis_j", j.axis_j.is_some(), needs.axes),
            ref_i: usage("ref_i", j.ref_i.is_some(), needs.refs),
            ref_j: usage("ref_j", j.ref_j.is_some(), needs.refs),
        };
        usage("lead", j.lead.is_some(), needs.lead);
        usage("distance", j.distance.is_some(), needs.distance);
        if needs.refs == Need::Optional && used.ref_i != used.ref_j {
            let (given, missing) = if used.ref_i { ("ref_i", "ref_j") } else { ("ref_j", "ref_i") };
            let message = format!("`{given}` is given without `{missing}`: give both or neither");
            self.error(at, missing, message);
        }
        used
    }

    /// Rules: the vector fields are finite, directions non-zero, references ⟂ their axes;
    /// returns those given and used (unit directions), after [`Rules::joint_usage`].
    fn joint_vectors(&mut self, at: &At, j: &JointDesc, needs: &JointSpec) -> Vectors {
        let used = self.joint_usage(at, j, needs);
        let point_i =
            j.point_i.filter(|_| used.point_i).and_then(|v| self.point3(at, "point_i", v));
        let point_j =
            j.point_j.filter(|_| used.point_j).and_then(|v| self.point3(at, "point_j", v));
        let axis_i = j.axis_i.filter(|_| used.axis_i).and_then(|v| self.direction(at, "axis_i", v));
        let axis_j = j.axis_j.filter(|_| used.axis_j).and_then(|v| self.direction(at, "axis_j", v));
        let ref_i = j.ref_i.filter(|_| used.ref_i).and_then(|v| self.direction(at, "ref_i", v));
        let ref_j = j.ref_j.filter(|_| used.ref_j).and_then(|v| self.direction(at, "ref_j", v));
        for (r, a, rf, af) in
            [(ref_i, axis_i, "ref_i", "axis_i"), (ref_j, axis_j, "ref_j", "axis_j")]
        {
            if let (Some(r), Some(a)) = (r, a) {
                self.perpendicular(at, rf, af, &r, &a);
            }
        }
        let refs_given = used.ref_i && used.ref_j;
        Vectors { point_i, point_j, axis_i, axis_j, ref_i, ref_j, refs_given }
    }

    /// Rules: a joint connects two different bodies, not both ground.
    fn joint_bodies(&mut self, at: &At, bi: BodyId, bj: BodyId) {
        let desc = self.desc;
        if bi == bj {
            let message = format!(
                "body_i and body_j are both \"{}\": a joint connects two different bodies",
                desc.bodies[bi.0].name
            );
            self.error(at, "body_j", message);
        } else if desc.bodies[bi.0].ground && desc.bodies[bj.0].ground {
            let message = format!(
                "\"{}\" and \"{}\" are both ground: the joint would constrain nothing that moves",
                desc.bodies[bi.0].name, desc.bodies[bj.0].name
            );
            self.error(at, "body_j", message);
        }
    }

    /// Rules: a field the type requires is given; a field it does not use is not.
    /// Returns whether the field is given and used.
    fn usage(&mut self, at: &At, ty: &str, field: &str, given: bool, need: Need) -> bool {
        match (need, given) {
            (Need::Unused, true) => {
                self.error(at, field, format!("field `{field}` is not used by a {ty} joint"));
                false
            }
            (Need::Required, false) => {
                let meaning = joint_field_meaning(field);
                let message = format!("missing `{field}`: a {ty} joint needs it ({meaning})");
                self.error(at, field, message);
                false
            }
            _ => given,
        }
    }

    /// Rule: a reference direction is ⟂ its axis within 1e-6.
    fn perpendicular(&mut self, at: &At, rf: &str, af: &str, r: &Vector3<f64>, a: &Vector3<f64>) {
        let dot = r.dot(a);
        if dot.abs() > PERPENDICULAR {
            let message = format!(
                "`{rf}` is not perpendicular to `{af}`: the dot product of the unit vectors is \
                 {dot:.3e}, more than {PERPENDICULAR:e} in magnitude"
            );
            self.error(at, rf, message);
        }
    }

    /// Rule: a screw's lead is finite and at least 1/[`MAX_MAGNITUDE`] in magnitude.
    fn lead(&mut self, at: &At, lead: f64) -> Option<f64> {
        if !self.finite_number(at, "lead", lead) {
            return None;
        }
        if lead == 0.0 {
            let message = "`lead` = 0 locks the slide, which makes this a revolute joint: \
                           use type = \"revolute\"";
            self.error(at, "lead", message);
            return None;
        }
        if lead.abs() < 1.0 / MAX_MAGNITUDE {
            let message = format!(
                "`lead` = {lead:e} is below {:e} in magnitude: the screw's 2π/lead overflows",
                1.0 / MAX_MAGNITUDE
            );
            self.error(at, "lead", message);
            return None;
        }
        Some(lead)
    }

    /// Rule: a given rod length is finite and at least 1/[`MAX_MAGNITUDE`].
    fn length(&mut self, at: &At, length: f64) -> bool {
        if !self.finite_number(at, "distance", length) {
            return false;
        }
        if length <= 0.0 {
            self.error(at, "distance", format!("`distance` = {length} must be > 0"));
            return false;
        }
        if length < 1.0 / MAX_MAGNITUDE {
            let message = format!(
                "`distance` = {length:e} is below {:e}: the rod's 1/distance overflows",
                1.0 / MAX_MAGNITUDE
            );
            self.error(at, "distance", message);
            return false;
        }
        true
    }

    /// Rule: without `distance`, the rod length is |P_j − P_i| at the initial estimates, and
    /// it must not be zero.
    fn initial_length(
        &mut self,
        at: &At,
        place_i: &model::Body,
        place_j: &model::Body,
        point_i: &Vector3<f64>,
        point_j: &Vector3<f64>,
    ) -> Option<f64> {
        let length = (global_point(place_j, point_j) - global_point(place_i, point_i)).norm();
        if length.is_finite() && length > ZERO_LENGTH {
            return Some(length);
        }
        let message = "the points coincide at the initial estimates, so the length cannot be \
                       taken from them: give `distance`";
        self.error(at, "distance", message);
        None
    }
}

/// P = r + A(p)·s', global.
fn global_point(body: &model::Body, local: &Vector3<f64>) -> Vector3<f64> {
    frame::global_point(&body.r, &body.p, local)
}

/// The screw's d0 = (P_j − P_i)·a and θ0 = atan2((g_i × g_j)·a, g_i·g_j) in (−π, π], with
/// a = A_i·axis_i and g = A·ref, all at the initial estimates.
fn screw_origin(
    place_i: &model::Body,
    place_j: &model::Body,
    point_i: Vector3<f64>,
    point_j: Vector3<f64>,
    (axis_i, _): (Vector3<f64>, Vector3<f64>),
    (ref_i, ref_j): (Vector3<f64>, Vector3<f64>),
) -> (f64, f64) {
    let a_i = rotation(&place_i.p);
    let a_j = rotation(&place_j.p);
    let axis = a_i * axis_i;
    let d0 = (global_point(place_j, &point_j) - global_point(place_i, &point_i)).dot(&axis);
    let (g_i, g_j) = (a_i * ref_i, a_j * ref_j);
    let theta0 = g_i.cross(&g_j).dot(&axis).atan2(g_i.dot(&g_j));
    // atan2 gives −π for a negative zero sine; the contract's interval is (−π, π].
    let theta0 = if theta0 <= -std::f64::consts::PI { std::f64::consts::PI } else { theta0 };
    (d0, theta0)
}
