//! The semantic rules of the contract's Validation section, each a small function, building
//! the model on the way. Every diagnostic carries the entity, the field and the key path; the
//! caller turns paths into lines and columns when there is a file.

use std::collections::BTreeMap;

use nalgebra::{Vector3, Vector4};

use super::{closest, names};
use crate::desc::{
    BodyDesc, ConstraintDesc, ConstraintType, CoordinateName, DriverDesc, JointDesc, JointType,
    LawDesc, MechanismDesc, Motion, PointDesc, SolverDesc, TimeDesc,
};
use crate::diag::{Diagnostic, Severity};
use crate::model::{
    self, BodyId, ConstraintKind, DriverTarget, JointId, Law, SolverOptions, TimeGrid,
};

mod joints;

/// The largest time grid accepted (contract).
const MAX_TIME_POINTS: usize = 10_000_000;

/// The most moving bodies accepted.
///
/// The generic engine works on the dense Jacobian (7 unknowns per body): at 500 bodies that is
/// 3,500 columns, about 100 MB per matrix and tens of seconds per time step, which bounds both
/// memory and time; the generated engine's build grows with the bodies too (BENCHMARKS.md).
pub(crate) const MAX_BODIES: usize = 500;

/// The most equations accepted: twice the unknowns of [`MAX_BODIES`] bodies, room for any
/// redundancy a real mechanism has, and a bound on the Jacobian's rows.
pub(crate) const MAX_EQUATIONS: usize = 14 * MAX_BODIES;

/// The largest `max_iterations` accepted: Newton converges in a handful of iterations or not
/// at all, so more only delays the report.
const MAX_ITERATIONS: u32 = 10_000;

/// The largest magnitude of any number of a description.
///
/// Rows of Φ multiply and square coordinates (distances, Euler-parameter products, the
/// normalisation pᵀp), so values beyond 1e150 overflow to infinity at once (1e150² = 1e300 is
/// near f64's limit of 1.8e308). No mechanism needs them: 1e150 m is far beyond any physical
/// size.
pub(crate) const MAX_MAGNITUDE: f64 = 1e150;

/// A direction whose largest component is at most this (absolute) is the zero vector.
/// Directions are written in whatever units the user likes, typically O(1); a vector this
/// short is a typo or rounding residue, and normalising it would make a direction of noise.
const ZERO_DIRECTION: f64 = 1e-12;

/// A distance joint whose points are closer than this (absolute, in the file's length unit)
/// at the initial estimates cannot take its length from them; as for directions, this is
/// far below any real rod and far above rounding of O(1) coordinates only by coincidence.
const ZERO_LENGTH: f64 = 1e-12;

/// |ref · axis| allowed between unit vectors (contract: ⟂ within 1e-6 after normalisation).
const PERPENDICULAR: f64 = 1e-6;

/// ||p| − 1| above which `p` is refused (contract).
const P_NORM_ERROR: f64 = 0.1;

/// ||p| − 1| above which normalising `p` is worth a warning (contract).
const P_NORM_WARNING: f64 = 1e-6;

/// Checks `desc`; returns the model when there is no error, and every diagnostic.
pub(super) fn check(desc: &MechanismDesc) -> (Option<model::Mechanism>, Vec<Diagnostic>) {
    let mut r = Rules { desc, diags: Vec::new() };
    r.name();
    r.names();
    let time = r.time(&desc.time);
    let solver = r.solver(desc.solver.as_ref());
    let bodies: Vec<_> = desc.bodies.iter().enumerate().map(|(k, b)| r.body(k, b)).collect();
    r.unique_names();
    let joints: Vec<_> =
        desc.joints.iter().enumerate().map(|(k, j)| r.joint(k, j, &bodies)).collect();
    let constraints: Vec<_> =
        desc.constraints.iter().enumerate().map(|(k, c)| r.constraint(k, c)).collect();
    let drivers: Vec<_> = desc.drivers.iter().enumerate().map(|(k, d)| r.driver(k, d)).collect();
    if let Some(grid) = &time {
        for (k, driver) in drivers.iter().enumerate() {
            if let Some(d) = driver {
                r.law_bounds(k, d, grid);
            }
        }
    }
    let points: Vec<_> = desc.points.iter().enumerate().map(|(k, p)| r.point(k, p)).collect();
    let equations = r.counting();
    let failed = r.diags.iter().any(|d| d.severity == Severity::Error);
    let mechanism = (|| {
        if failed {
            return None;
        }
        Some(model::Mechanism {
            name: desc.name.clone(),
            description: desc.description.clone(),
            time: time?,
            solver: solver?,
            bodies: bodies.into_iter().collect::<Option<_>>()?,
            joints: joints.into_iter().collect::<Option<_>>()?,
            constraints: constraints.into_iter().collect::<Option<_>>()?,
            drivers: drivers.into_iter().collect::<Option<_>>()?,
            points: points.into_iter().collect::<Option<_>>()?,
        })
    })();
    if let Some(m) = &mechanism {
        debug_assert_eq!(Some(m.equations()), equations, "the count must match the model's");
    }
    (mechanism, r.diags)
}

/// An entity as messages name it (`joint "O2"`) and its key path (`joints[2]`).
struct At {
    entity: String,
    path: String,
}

impl At {
    /// An element of an array section.
    fn item(kind: &str, name: &str, section: &str, k: usize) -> Self {
        Self { entity: format!("{kind} \"{name}\""), path: format!("{section}[{k}]") }
    }

    /// A top-level table, or with an empty path a top-level key.
    fn section(entity: &str, path: &str) -> Self {
        Self { entity: entity.to_owned(), path: path.to_owned() }
    }

    fn field_path(&self, field: &str) -> String {
        if self.path.is_empty() { field.to_owned() } else { format!("{}.{field}", self.path) }
    }
}

struct Rules<'a> {
    desc: &'a MechanismDesc,
    diags: Vec<Diagnostic>,
}

impl Rules<'_> {
    fn error(&mut self, at: &At, field: &str, message: impl Into<String>) {
        self.push(Diagnostic::error(message), at, field, at.field_path(field));
    }

    fn warning(&mut self, at: &At, field: &str, message: impl Into<String>) {
        self.push(Diagnostic::warning(message), at, field, at.field_path(field));
    }

    fn push(&mut self, diag: Diagnostic, at: &At, field: &str, path: String) {
        self.diags.push(diag.entity(at.entity.as_str()).field(field).path(path));
    }

    /// The whole mechanism, for the rules that are about no entity in particular.
    fn mechanism(&self) -> At {
        At::section(&format!("mechanism \"{}\"", self.desc.name), "")
    }

    /// Rules: `name` matches `[a-z][a-z0-9_]*` and can name the generated module and type;
    /// the description is printable text (see [`names`]).
    fn name(&mut self) {
        let name = &self.desc.name;
        let mut chars = name.chars();
        let valid = chars.next().is_some_and(|c| c.is_ascii_lowercase())
            && chars.all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_');
        if !valid {
            let mut fixed: String = name
                .chars()
                .map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '_' })
                .collect();
            if !fixed.starts_with(|c: char| c.is_ascii_lowercase()) {
                fixed.insert_str(0, "m_");
            }
            let message = format!(
                "the name \"{name}\" must match [a-z][a-z0-9_]* (it is also the generated \
                 module's name), e.g. \"{fixed}\""
            );
            self.error(&At::section("name", ""), "name", message);
        } else if let Some(message) = names::mechanism_name_problem(name, &model::type_name(name)) {
            self.error(&At::section("name", ""), "name", message);
        }
        if let Some(message) = self.desc.description.as_deref().and_then(names::description_problem)
        {
            self.error(&At::section("description", ""), "description", message);
        }
    }

    /// Rule: every entity's name is printable text of at most [`names::MAX_NAME_CHARS`]
    /// characters (see [`names`]).
    fn names(&mut self) {
        let desc = self.desc;
        let bodies = desc.bodies.iter().enumerate().map(|(k, b)| ("body", "bodies", k, &b.name));
        let joints = desc.joints.iter().enumerate().map(|(k, j)| ("joint", "joints", k, &j.name));
        let constraints = (desc.constraints.iter().enumerate())
            .map(|(k, c)| ("constraint", "constraints", k, &c.name));
        let drivers =
            desc.drivers.iter().enumerate().map(|(k, d)| ("driver", "drivers", k, &d.name));
        let points = desc.points.iter().enumerate().map(|(k, p)| ("point", "points", k, &p.name));
        for (kind, section, k, name) in
            bodies.chain(joints).chain(constraints).chain(drivers).chain(points)
        {
            if let Some(message) = names::name_problem(name) {
                self.error(&At::item(kind, name, section, k), "name", message);
            }
        }
    }

    /// Rule: every number of a vector is finite and at most [`MAX_MAGNITUDE`] in magnitude.
    /// Reports each bad component at its place.
    fn finite(&mut self, at: &At, field: &str, v: &[f64]) -> bool {
        let mut ok = true;
        for (k, x) in v.iter().enumerate() {
            let problem = if !x.is_finite() {
                format!("`{field}[{k}]` is {x}: every number must be finite")
            } else if x.abs() > MAX_MAGNITUDE {
                format!(
                    "`{field}[{k}]` = {x:e} is beyond ±{MAX_MAGNITUDE:e}: squares and products \
                     of such values overflow"
                )
            } else {
                continue;
            };
            let path = format!("{}[{k}]", at.field_path(field));
            self.push(Diagnostic::error(problem), at, field, path);
            ok = false;
        }
        ok
    }

    /// Rule: a scalar is finite and at most [`MAX_MAGNITUDE`] in magnitude.
    fn finite_number(&mut self, at: &At, field: &str, x: f64) -> bool {
        if !x.is_finite() {
            self.error(at, field, format!("`{field}` is {x}: it must be finite"));
            false
        } else if x.abs() > MAX_MAGNITUDE {
            let message = format!(
                "`{field}` = {x:e} is beyond ±{MAX_MAGNITUDE:e}: squares and products of such \
                 values overflow"
            );
            self.error(at, field, message);
            false
        } else {
            true
        }
    }

    /// Rule: a point is finite.
    fn point3(&mut self, at: &At, field: &str, v: [f64; 3]) -> Option<Vector3<f64>> {
        self.finite(at, field, &v).then(|| Vector3::from(v))
    }

    /// Rule: a direction is finite and non-zero; it is returned normalised.
    fn direction(&mut self, at: &At, field: &str, v: [f64; 3]) -> Option<Vector3<f64>> {
        if !self.finite(at, field, &v) {
            return None;
        }
        let v = Vector3::from(v);
        // Scaling by the largest component first keeps the norm from overflowing.
        let scale = v.amax();
        if scale <= ZERO_DIRECTION {
            self.error(
                at,
                field,
                format!("`{field}` is the zero vector: a direction must be non-zero"),
            );
            return None;
        }
        let v = v / scale;
        Some(v / v.norm())
    }

    /// Rule: a body reference names an existing body; suggests the closest name.
    fn body_ref(&mut self, at: &At, field: &str, name: &str) -> Option<BodyId> {
        let bodies = &self.desc.bodies;
        if let Some(k) = bodies.iter().position(|b| b.name == name) {
            return Some(BodyId(k));
        }
        let mut message = format!("unknown body \"{name}\"");
        let near = closest(name, bodies.iter().map(|b| b.name.as_str()));
        match near {
            Some(near) => message.push_str(&format!(": did you mean \"{near}\"?")),
            None if bodies.is_empty() => message.push_str(": there are no bodies"),
            None => {}
        }
        let mut diag = Diagnostic::error(message);
        if let Some(near) = near {
            diag = diag.suggest(format!("\"{near}\""));
        }
        self.push(diag, at, field, at.field_path(field));
        None
    }

    /// Rule: a joint reference names an existing joint; suggests the closest name.
    fn joint_ref(&mut self, at: &At, field: &str, name: &str) -> Option<JointId> {
        let desc = self.desc;
        if let Some(k) = desc.joints.iter().position(|j| j.name == name) {
            return Some(JointId(k));
        }
        let diag = if desc.constraints.iter().any(|c| c.name == name) {
            Diagnostic::error(format!(
                "\"{name}\" is a constraint, not a joint: only joints can be driven"
            ))
        } else if desc.drivers.iter().any(|d| d.name == name) {
            Diagnostic::error(format!("\"{name}\" is a driver, not a joint"))
        } else {
            match closest(name, desc.joints.iter().map(|j| j.name.as_str())) {
                Some(near) => {
                    Diagnostic::error(format!("unknown joint \"{name}\": did you mean \"{near}\"?"))
                        .suggest(format!("\"{near}\""))
                }
                None => Diagnostic::error(format!("unknown joint \"{name}\"")),
            }
        };
        self.push(diag, at, field, at.field_path(field));
        None
    }

    /// Rules for `[time]`: finite bounds, end ≥ start, exactly one of step and steps, a
    /// positive step, and at most 10,000,000 time points (counted without allocating).
    fn time(&mut self, t: &TimeDesc) -> Option<TimeGrid> {
        let at = At::section("time", "time");
        let mut bounds = self.finite_number(&at, "start", t.start);
        bounds &= self.finite_number(&at, "end", t.end);
        if bounds && t.end < t.start {
            let message = format!("end = {} is before start = {}", t.end, t.start);
            self.error(&at, "end", message);
            bounds = false;
        }
        match (t.step, t.steps) {
            (Some(_), Some(_)) => {
                let message = "give either `step` (the spacing) or `steps` (the number of \
                               intervals), not both";
                self.error(&at, "steps", message);
                None
            }
            (None, None) => {
                let message = "missing `step` (the spacing) or `steps` (the number of intervals)";
                self.error(&at, "step", message);
                None
            }
            (Some(step), None) => {
                if !(step.is_finite() && step > 0.0) {
                    self.error(&at, "step", format!("`step` = {step} must be finite and > 0"));
                    return None;
                }
                if !bounds {
                    return None;
                }
                // The end is included when it lies within step/1000 of a grid point.
                let points = ((t.end - t.start) / step + 1e-3).floor() + 1.0;
                let count = self.time_points(&at, "step", points)?;
                Some(TimeGrid::uniform(t.start, step, count))
            }
            (None, Some(steps)) => {
                if steps == 0 {
                    self.error(&at, "steps", "`steps` = 0: the grid needs at least 1 interval");
                    return None;
                }
                if !bounds {
                    return None;
                }
                if t.end == t.start {
                    let message = "with `steps`, end must be after start (a grid of one time \
                                   point takes `step` instead)";
                    self.error(&at, "end", message);
                    return None;
                }
                let step = (t.end - t.start) / steps as f64;
                if step <= 0.0 {
                    let message = "(end − start)/steps underflows to 0: use fewer steps";
                    self.error(&at, "steps", message);
                    return None;
                }
                let count = self.time_points(&at, "steps", steps as f64 + 1.0)?;
                Some(TimeGrid::uniform(t.start, step, count))
            }
        }
    }

    /// Rule: at most 10,000,000 time points.
    fn time_points(&mut self, at: &At, field: &str, points: f64) -> Option<usize> {
        if points <= MAX_TIME_POINTS as f64 {
            // The caller's arithmetic gives a whole number ≥ 1 here.
            return Some(points as usize);
        }
        let shown = if points < 1e15 { format!("{points:.0}") } else { format!("{points:e}") };
        let message = format!(
            "the grid has {shown} time points, more than the {MAX_TIME_POINTS} allowed: use a \
             larger step or a shorter interval"
        );
        self.error(at, field, message);
        None
    }

    /// Rules for `[solver]`: tolerance finite and > 0, 1 ≤ max_iterations ≤ 10,000.
    fn solver(&mut self, s: Option<&SolverDesc>) -> Option<SolverOptions> {
        let defaults = SolverOptions::default();
        let Some(s) = s else { return Some(defaults) };
        let at = At::section("solver", "solver");
        let tolerance = s.tolerance.unwrap_or(defaults.tolerance);
        let max_iterations = s.max_iterations.unwrap_or(defaults.max_iterations);
        let mut ok = true;
        if !(tolerance.is_finite() && tolerance > 0.0) {
            let message = format!("`tolerance` = {tolerance} must be finite and > 0");
            self.error(&at, "tolerance", message);
            ok = false;
        }
        if !(1..=MAX_ITERATIONS).contains(&max_iterations) {
            let message = format!(
                "`max_iterations` = {max_iterations} must be between 1 and {MAX_ITERATIONS}"
            );
            self.error(&at, "max_iterations", message);
            ok = false;
        }
        ok.then_some(SolverOptions { tolerance, max_iterations })
    }

    /// Rules for a body: `r` finite; `p` finite with | |p| − 1 | ≤ 0.1 (a warning above
    /// 1e-6), normalised. Defaults: the origin and the identity.
    fn body(&mut self, k: usize, b: &BodyDesc) -> Option<model::Body> {
        let at = At::item("body", &b.name, "bodies", k);
        let r = b.r.map_or(Some(Vector3::zeros()), |r| self.point3(&at, "r", r));
        let p = b.p.map_or(Some(Vector4::new(1.0, 0.0, 0.0, 0.0)), |p| self.euler(&at, p));
        Some(model::Body { name: b.name.clone(), ground: b.ground, r: r?, p: p? })
    }

    /// Rule: Euler parameters are finite and of unit norm within 0.1; normalised.
    fn euler(&mut self, at: &At, p: [f64; 4]) -> Option<Vector4<f64>> {
        if !self.finite(at, "p", &p) {
            return None;
        }
        let p = Vector4::from(p);
        let norm = p.norm();
        let off = (norm - 1.0).abs();
        if off > P_NORM_ERROR {
            let message = format!(
                "|p| = {norm} is not 1: Euler parameters [cos(χ/2), u·sin(χ/2)] have unit norm \
                 (p is normalised on load, but only when it is within {P_NORM_ERROR} of 1)"
            );
            self.error(at, "p", message);
            return None;
        }
        if off > P_NORM_WARNING {
            let message = format!("|p| = {norm} differs from 1 by {off:.1e}; p is normalised");
            self.warning(at, "p", message);
        }
        Some(p / norm)
    }

    /// Rule: names are unique among bodies, among points, and among joints, constraints and
    /// drivers together.
    fn unique_names(&mut self) {
        let desc = self.desc;
        let bodies = desc.bodies.iter().enumerate().map(|(k, b)| ("body", "bodies", k, &b.name));
        self.unique(bodies, "body names must be unique");
        let joints = desc.joints.iter().enumerate().map(|(k, j)| ("joint", "joints", k, &j.name));
        let constraints = (desc.constraints.iter().enumerate())
            .map(|(k, c)| ("constraint", "constraints", k, &c.name));
        let drivers =
            desc.drivers.iter().enumerate().map(|(k, d)| ("driver", "drivers", k, &d.name));
        let shared = "joints, constraints and drivers share one namespace";
        self.unique(joints.chain(constraints).chain(drivers), shared);
        let points = desc.points.iter().enumerate().map(|(k, p)| ("point", "points", k, &p.name));
        self.unique(points, "point names must be unique");
    }

    fn unique<'n>(
        &mut self,
        items: impl Iterator<Item = (&'static str, &'static str, usize, &'n String)>,
        why: &str,
    ) {
        let mut seen: BTreeMap<&str, (&str, &str, usize)> = BTreeMap::new();
        for (kind, section, k, name) in items {
            if let Some(&(first_kind, first_section, first_k)) = seen.get(name.as_str()) {
                let message = format!(
                    "the name \"{name}\" is already taken by {first_kind} \"{name}\" \
                     ({first_section}[{first_k}]): {why}"
                );
                self.error(&At::item(kind, name, section, k), "name", message);
            } else {
                seen.insert(name, (kind, section, k));
            }
        }
    }

    /// Rules for a constraint: `fix` takes `body` (not ground), `coordinate_difference` takes
    /// two distinct `body_i`, `body_j`, not both ground; the value is finite.
    fn constraint(&mut self, k: usize, c: &ConstraintDesc) -> Option<model::Constraint> {
        let at = At::item("constraint", &c.name, "constraints", k);
        let value_ok = self.finite_number(&at, "value", c.value);
        let kind = match c.kind {
            ConstraintType::Fix => self.fix(&at, c, value_ok),
            ConstraintType::CoordinateDifference => self.difference(&at, c, value_ok),
        };
        Some(model::Constraint { name: c.name.clone(), kind: kind? })
    }

    fn fix(&mut self, at: &At, c: &ConstraintDesc, value_ok: bool) -> Option<ConstraintKind> {
        for (field, given) in [("body_i", c.body_i.is_some()), ("body_j", c.body_j.is_some())] {
            if given {
                let message = format!(
                    "field `{field}` is not used by a fix constraint (it names its body with \
                     `body`)"
                );
                self.error(at, field, message);
            }
        }
        let euler =
            matches!(c.coordinate, CoordinateName::E1 | CoordinateName::E2 | CoordinateName::E3);
        if value_ok && euler && c.value.abs() > 1.0 {
            let message = format!(
                "`value` = {} for {}: an Euler parameter lies in [−1, 1]",
                c.value,
                c.coordinate.as_str()
            );
            self.error(at, "value", message);
        }
        let Some(name) = &c.body else {
            self.error(at, "body", "missing `body`: a fix constraint needs the body it fixes");
            return None;
        };
        let body = self.body_ref(at, "body", name)?;
        if self.desc.bodies[body.0].ground {
            let message = format!("body \"{name}\" is ground: its coordinates are already fixed");
            self.error(at, "body", message);
            return None;
        }
        let fixed = ConstraintKind::Fix { body, coordinate: c.coordinate, value: c.value };
        value_ok.then_some(fixed)
    }

    fn difference(
        &mut self,
        at: &At,
        c: &ConstraintDesc,
        value_ok: bool,
    ) -> Option<ConstraintKind> {
        if c.body.is_some() {
            let message = "field `body` is not used by a coordinate_difference constraint (it \
                           takes `body_i` and `body_j`)";
            self.error(at, "body", message);
        }
        let mut resolve = |field: &str, name: &Option<String>| match name {
            Some(name) => self.body_ref(at, field, name),
            None => {
                let message =
                    format!("missing `{field}`: a coordinate_difference constraint needs it");
                self.error(at, field, message);
                None
            }
        };
        let body_i = resolve("body_i", &c.body_i);
        let body_j = resolve("body_j", &c.body_j);
        let (body_i, body_j) = (body_i?, body_j?);
        let bodies = &self.desc.bodies;
        if body_i == body_j {
            let message = format!(
                "body_i and body_j are both \"{}\": the difference of a coordinate with itself \
                 is always 0",
                bodies[body_i.0].name
            );
            self.error(at, "body_j", message);
            return None;
        }
        if bodies[body_i.0].ground && bodies[body_j.0].ground {
            let message = format!(
                "\"{}\" and \"{}\" are both ground: their coordinates are already fixed",
                bodies[body_i.0].name, bodies[body_j.0].name
            );
            self.error(at, "body_j", message);
            return None;
        }
        let kind = ConstraintKind::CoordinateDifference {
            body_i,
            body_j,
            coordinate: c.coordinate,
            value: c.value,
        };
        value_ok.then_some(kind)
    }

    /// Rules for a driver: exactly one of the joint form (`joint`, `motion`) and the absolute
    /// form (`body`, `coordinate`); a law of one form.
    fn driver(&mut self, k: usize, d: &DriverDesc) -> Option<model::Driver> {
        let at = At::item("driver", &d.name, "drivers", k);
        let target = match (&d.joint, &d.body, &d.point) {
            (Some(_), Some(_), _) | (Some(_), _, Some(_)) | (_, Some(_), Some(_)) => {
                let message = "a driver is either a joint driver (`joint`, `motion`) or an absolute \
                               one (`body`, `coordinate`) or a point driver (`point`, \
                               `coordinate`): give only one of joint, body and point";
                let field = if d.point.is_some() { "point" } else { "body" };
                self.error(&at, field, message);
                None
            }
            (None, None, None) => {
                let message = "missing `joint`, `body` or `point`: a driver moves a joint \
                               (`joint`, `motion`), a body coordinate (`body`, `coordinate`) or \
                               a point of interest's coordinate (`point`, `coordinate`)";
                self.error(&at, "joint", message);
                None
            }
            (Some(joint), None, None) => self.joint_driver(&at, d, joint),
            (None, Some(body), None) => self.absolute_driver(&at, d, body),
            (None, None, Some(point)) => self.point_driver(&at, d, point),
        };
        let law = self.law(&at, &d.law);
        if law == Some(Law::Input)
            && let Some(problem) = super::names::input_name_problem(&d.name)
        {
            self.error(&at, "name", problem);
        }
        Some(model::Driver { name: d.name.clone(), target: target?, law: law? })
    }

    /// Rules: a joint driver has a motion its joint allows; rotation needs the joint's refs.
    fn joint_driver(&mut self, at: &At, d: &DriverDesc, joint: &str) -> Option<DriverTarget> {
        if d.coordinate.is_some() {
            let message = "field `coordinate` is not used by a joint driver (it goes with `body`)";
            self.error(at, "coordinate", message);
        }
        let id = self.joint_ref(at, "joint", joint);
        let Some(motion) = d.motion else {
            let message = "missing `motion` (rotation or translation): a joint driver needs it";
            self.error(at, "motion", message);
            return None;
        };
        let j = &self.desc.joints[id?.0];
        let allowed = match motion {
            Motion::Rotation => {
                matches!(j.kind, JointType::Revolute | JointType::Cylindrical | JointType::Screw)
            }
            Motion::Translation => matches!(j.kind, JointType::Prismatic | JointType::Cylindrical),
        };
        if !allowed {
            let (word, takes) = match motion {
                Motion::Rotation => ("rotation", "revolute, cylindrical and screw joints"),
                Motion::Translation => ("translation", "prismatic and cylindrical joints"),
            };
            let message = format!(
                "joint \"{}\" is a {} joint, which cannot be driven in {word}: only {takes} can",
                j.name,
                j.kind.as_str()
            );
            self.error(at, "motion", message);
            return None;
        }
        if motion == Motion::Rotation && (j.ref_i.is_none() || j.ref_j.is_none()) {
            let message = format!(
                "joint \"{}\" has no `ref_i`/`ref_j`, which driver \"{}\" needs to measure the \
                 joint angle: add ref_i and ref_j (⟂ the axes) to joint \"{}\"",
                j.name, d.name, j.name
            );
            self.error(at, "joint", message);
            return None;
        }
        Some(DriverTarget::Joint { joint: id?, motion })
    }

    /// Rules: an absolute driver has a coordinate and moves a body that is not ground.
    fn absolute_driver(&mut self, at: &At, d: &DriverDesc, body: &str) -> Option<DriverTarget> {
        if d.motion.is_some() {
            let message = "field `motion` is not used by an absolute driver (it goes with `joint`)";
            self.error(at, "motion", message);
        }
        let id = self.body_ref(at, "body", body);
        let Some(coordinate) = d.coordinate else {
            let message = "missing `coordinate` (x, y, z, rx, ry, rz, e1, e2 or e3): an absolute driver \
                 needs it";
            self.error(at, "coordinate", message);
            return None;
        };
        let id = id?;
        if self.desc.bodies[id.0].ground {
            let message = format!("body \"{body}\" is ground: it cannot be driven");
            self.error(at, "body", message);
            return None;
        }
        Some(DriverTarget::Absolute { body: id, coordinate })
    }

    /// Rules: a point driver names a point of interest on a body that is not ground and a
    /// coordinate x, y or z.
    fn point_driver(&mut self, at: &At, d: &DriverDesc, point: &str) -> Option<DriverTarget> {
        if d.motion.is_some() {
            let message = "field `motion` is not used by a point driver (it goes with `joint`)";
            self.error(at, "motion", message);
        }
        let Some(k) = self.desc.points.iter().position(|p| p.name == point) else {
            let names: Vec<&str> = self.desc.points.iter().map(|p| p.name.as_str()).collect();
            let message = match super::closest(point, names.iter().copied()) {
                Some(near) => {
                    format!("unknown point \"{point}\" in `point`: did you mean \"{near}\"?")
                }
                None => format!(
                    "unknown point \"{point}\" in `point`: a point driver names one of the \
                     [[points]] ({})",
                    names.join(", ")
                ),
            };
            self.error(at, "point", message);
            return None;
        };
        let axis = match d.coordinate {
            Some(model::DriverCoordinate::X) => 0,
            Some(model::DriverCoordinate::Y) => 1,
            Some(model::DriverCoordinate::Z) => 2,
            Some(c) => {
                let message = format!(
                    "coordinate \"{}\" cannot be driven on a point: a point driver takes x, y or z",
                    c.as_str()
                );
                self.error(at, "coordinate", message);
                return None;
            }
            None => {
                let message = "missing `coordinate` (x, y or z): a point driver needs it";
                self.error(at, "coordinate", message);
                return None;
            }
        };
        let body = &self.desc.points[k].body;
        if self.desc.bodies.iter().any(|b| &b.name == body && b.ground) {
            let message =
                format!("point \"{point}\" is on ground body \"{body}\": it cannot be driven");
            self.error(at, "point", message);
            return None;
        }
        self.desc
            .bodies
            .iter()
            .any(|b| &b.name == body)
            .then_some(DriverTarget::Point { point: model::PointId(k), axis })
    }

    /// Rules for a law: `"input"`, or the polynomial members or the harmonic ones, not both,
    /// not none; the harmonic form needs amplitude and frequency; every number finite.
    fn law(&mut self, at: &At, law: &LawDesc) -> Option<Law> {
        if law.input {
            return Some(Law::Input);
        }
        let polynomial =
            [("start", law.start), ("velocity", law.velocity), ("acceleration", law.acceleration)];
        let harmonic = [
            ("offset", law.offset),
            ("amplitude", law.amplitude),
            ("frequency", law.frequency),
            ("phase", law.phase),
        ];
        let mut finite = true;
        for (member, value) in polynomial.iter().chain(&harmonic) {
            if let Some(x) = value {
                finite &= self.finite_number(at, &format!("law.{member}"), *x);
            }
        }
        let given = |members: &[(&str, Option<f64>)]| members.iter().any(|(_, v)| v.is_some());
        let law = match (given(&polynomial), given(&harmonic)) {
            (true, true) => {
                let message = "the law mixes the polynomial form (start, velocity, acceleration) \
                               with the harmonic one (offset, amplitude, frequency, phase): use one";
                self.error(at, "law", message);
                return None;
            }
            (false, false) => {
                let message = "the law is empty: give { start, velocity, acceleration } for \
                               s = start + velocity·t + acceleration·t²/2, or { offset, \
                               amplitude, frequency, phase } for s = offset + amplitude·sin(\
                               frequency·t + phase)";
                self.error(at, "law", message);
                return None;
            }
            (true, false) => Law::Polynomial {
                start: law.start.unwrap_or(0.0),
                velocity: law.velocity.unwrap_or(0.0),
                acceleration: law.acceleration.unwrap_or(0.0),
            },
            (false, true) => {
                for (member, value) in [("amplitude", law.amplitude), ("frequency", law.frequency)]
                {
                    if value.is_none() {
                        let message = format!(
                            "missing `law.{member}`: the harmonic law needs amplitude and frequency"
                        );
                        self.error(at, &format!("law.{member}"), message);
                    }
                }
                Law::Harmonic {
                    offset: law.offset.unwrap_or(0.0),
                    amplitude: law.amplitude?,
                    frequency: law.frequency?,
                    phase: law.phase.unwrap_or(0.0),
                }
            }
        };
        finite.then_some(law)
    }

    /// Rule: a law's value s and its derivatives ṡ and s̈ stay within [`MAX_MAGNITUDE`] over
    /// the time grid, by their bounds: for the polynomial law |s0| + |v|·T + |a|·T²/2,
    /// |v| + |a|·T and |a|; for the harmonic one |c| + |A|, |A|·ω and |A|·ω², where T is the
    /// largest |t| of the grid. Every member is within the bound on its own, but their
    /// products are not (A = 1e10, ω = 1e150: A·ω² = 1e310 overflows), and both engines
    /// evaluate these products.
    fn law_bounds(&mut self, k: usize, d: &model::Driver, grid: &TimeGrid) {
        let at = At::item("driver", &d.name, "drivers", k);
        let last = grid.at(grid.count.saturating_sub(1));
        let t = grid.start.abs().max(last.abs());
        let bounds = match d.law {
            Law::Input => return,
            Law::Polynomial { start, velocity, acceleration } => {
                let (v, a) = (velocity.abs(), acceleration.abs());
                [
                    (
                        "s",
                        start.abs() + v * t + 0.5 * a * t * t,
                        "|start| + |velocity|·|t| + |acceleration|·t²/2",
                    ),
                    ("ṡ", v + a * t, "|velocity| + |acceleration|·|t|"),
                    ("s̈", a, "|acceleration|"),
                ]
            }
            Law::Harmonic { offset, amplitude, frequency, .. } => {
                let (a, w) = (amplitude.abs(), frequency.abs());
                [
                    ("s", offset.abs() + a, "|offset| + |amplitude|"),
                    ("ṡ", a * w, "|amplitude|·|frequency|"),
                    ("s̈", a * w * w, "|amplitude|·frequency²"),
                ]
            }
        };
        let beyond = |v: f64| v.is_nan() || v > MAX_MAGNITUDE;
        if let Some((what, value, how)) = bounds.into_iter().find(|b| beyond(b.1)) {
            let value = if value.is_finite() {
                format!("{value:?}")
            } else {
                format!("more than {:e}", f64::MAX)
            };
            let message = format!(
                "{what} reaches {value} over the time grid ({how}, with |t| up to {t:?}), \
                 beyond ±{MAX_MAGNITUDE:e}: the equations would overflow; use smaller values"
            );
            self.error(&at, "law", message);
        }
    }

    /// Rules for a point of interest: a known body and finite local coordinates.
    fn point(&mut self, k: usize, p: &PointDesc) -> Option<model::Point> {
        let at = At::item("point", &p.name, "points", k);
        let body = self.body_ref(&at, "body", &p.body);
        let local = self.point3(&at, "local", p.local);
        Some(model::Point { name: p.name.clone(), body: body?, local: local? })
    }

    /// Rules: at least one moving body, at most [`MAX_BODIES`] and [`MAX_EQUATIONS`]; no fewer
    /// equations than unknowns. Returns the number of equations when the counts are in range.
    fn counting(&mut self) -> Option<usize> {
        let desc = self.desc;
        let moving = desc.bodies.iter().filter(|b| !b.ground).count();
        if moving == 0 {
            let message = "there is no moving body: add a body without `ground = true`";
            let diag = Diagnostic::error(message).entity(self.mechanism().entity).path("bodies");
            self.diags.push(diag);
            return None;
        }
        let unknowns = 7 * moving;
        let equations = desc.joints.iter().map(|j| j.kind.spec().rows.len()).sum::<usize>()
            + desc.constraints.len()
            + desc.drivers.len()
            + moving;
        if moving > MAX_BODIES || equations > MAX_EQUATIONS {
            let message = format!(
                "{moving} moving bodies and {equations} equations: at most {MAX_BODIES} moving \
                 bodies and {MAX_EQUATIONS} equations are accepted (the generic engine's dense \
                 Jacobian bounds memory and time)"
            );
            let diag = Diagnostic::error(message).entity(self.mechanism().entity).path("bodies");
            self.diags.push(diag);
            return None;
        }
        if equations < unknowns {
            let missing = unknowns - equations;
            let (noun, verb) = if missing == 1 {
                ("driver or constraint", "is")
            } else {
                ("drivers or constraints", "are")
            };
            let mut message = format!(
                "{unknowns} unknowns (7 per moving body) but only {equations} equations: \
                 {missing} {noun} {verb} missing"
            );
            for idle in idle_spins(desc) {
                message.push_str("; ");
                message.push_str(&idle);
            }
            let diag = Diagnostic::error(message).entity(self.mechanism().entity).path("drivers");
            self.diags.push(diag);
        }
        Some(equations)
    }
}

/// The moving bodies held only by two spherical joints, each with the reason and the fix: such
/// a body (the coupler of an R-S-S-R without its spin constraint) can turn freely about the
/// line through the two joint centres, a degree of freedom no driver is meant to fix.
fn idle_spins(desc: &MechanismDesc) -> Vec<String> {
    let mut found = Vec::new();
    for body in desc.bodies.iter().filter(|b| !b.ground) {
        let name = body.name.as_str();
        let touches = |i: &str, j: &str| i == name || j == name;
        let joints: Vec<&JointDesc> =
            desc.joints.iter().filter(|j| touches(&j.body_i, &j.body_j)).collect();
        let held =
            desc.constraints.iter().any(|c| {
                [&c.body, &c.body_i, &c.body_j].iter().any(|b| b.as_deref() == Some(name))
            }) || desc.drivers.iter().any(|d| d.body.as_deref() == Some(name));
        let spherical = joints.iter().all(|j| j.kind == JointType::Spherical);
        if held || joints.len() != 2 || !spherical {
            continue;
        }
        let other =
            |j: &JointDesc| if j.body_i == name { j.body_j.clone() } else { j.body_i.clone() };
        let (a, b) = (joints[0], joints[1]);
        found.push(format!(
            "body \"{name}\" spins idly about the line through its spherical joints \"{}\" and \
             \"{}\": replace it and those joints by one `distance` joint between \"{}\" and \
             \"{}\" (a rod with spherical ends), or fix its spin with a constraint",
            a.name,
            b.name,
            other(a),
            other(b)
        ));
    }
    found
}
