//! Descriptions → readable TOML, in the layout of the contract's example.

use crate::desc::{
    BodyDesc, ConstraintDesc, ConstraintType, DriverDesc, JointDesc, LawDesc, MechanismDesc,
    Motion, PointDesc, SolverDesc, TimeDesc,
};

/// Writes a description as readable TOML, in the layout of the contract's example: top-level
/// keys, `[time]`, `[solver]`, then `[[bodies]]`, `[[joints]]`, `[[constraints]]`,
/// `[[drivers]]` and `[[points]]` in order, vectors and laws inline.
///
/// `comment` is written first, each line prefixed with `# ` (nothing when it is empty).
/// Floats are written in Rust's shortest round-trip form, so
/// `toml::from_str::<MechanismDesc>(&to_toml(&d, c)) == d` for every description whose numbers
/// are finite (non-finite ones are written as TOML's `nan` and `inf`).
#[must_use]
pub fn to_toml(desc: &MechanismDesc, comment: &str) -> String {
    let mut w = TomlWriter::default();
    w.comment(comment);
    w.string("name", &desc.name);
    if let Some(description) = &desc.description {
        w.string("description", description);
    }
    w.time(&desc.time);
    if let Some(solver) = &desc.solver {
        w.solver(solver);
    }
    desc.bodies.iter().for_each(|b| w.body(b));
    desc.joints.iter().for_each(|j| w.joint(j));
    desc.constraints.iter().for_each(|c| w.constraint(c));
    desc.drivers.iter().for_each(|d| w.driver(d));
    desc.points.iter().for_each(|p| w.point(p));
    w.out
}

/// The sections of a description, one method each.
impl TomlWriter {
    /// `comment`, each line prefixed with `# `, then a blank line.
    fn comment(&mut self, comment: &str) {
        for line in comment.lines() {
            self.out.push('#');
            if !line.is_empty() {
                self.out.push(' ');
                self.out.push_str(line);
            }
            self.out.push('\n');
        }
        if !comment.is_empty() {
            self.out.push('\n');
        }
    }

    fn time(&mut self, time: &TimeDesc) {
        self.header("[time]");
        self.float("start", time.start);
        self.float("end", time.end);
        if let Some(step) = time.step {
            self.float("step", step);
        }
        if let Some(steps) = time.steps {
            self.raw("steps", &steps.to_string());
        }
    }

    fn solver(&mut self, solver: &SolverDesc) {
        self.header("[solver]");
        if let Some(tolerance) = solver.tolerance {
            self.float("tolerance", tolerance);
        }
        if let Some(max_iterations) = solver.max_iterations {
            self.raw("max_iterations", &max_iterations.to_string());
        }
    }

    fn body(&mut self, body: &BodyDesc) {
        self.header("[[bodies]]");
        self.string("name", &body.name);
        if body.ground {
            self.raw("ground", "true");
        }
        self.opt_vec("r", body.r.as_ref().map(|v| &v[..]));
        self.opt_vec("p", body.p.as_ref().map(|v| &v[..]));
    }

    fn joint(&mut self, joint: &JointDesc) {
        self.header("[[joints]]");
        self.string("name", &joint.name);
        self.string("type", joint.kind.as_str());
        self.string("body_i", &joint.body_i);
        self.string("body_j", &joint.body_j);
        let vectors = [
            ("point_i", &joint.point_i),
            ("point_j", &joint.point_j),
            ("axis_i", &joint.axis_i),
            ("axis_j", &joint.axis_j),
            ("ref_i", &joint.ref_i),
            ("ref_j", &joint.ref_j),
        ];
        for (key, value) in vectors {
            self.opt_vec(key, value.as_ref().map(|v| &v[..]));
        }
        if let Some(lead) = joint.lead {
            self.float("lead", lead);
        }
        if let Some(distance) = joint.distance {
            self.float("distance", distance);
        }
    }

    fn constraint(&mut self, constraint: &ConstraintDesc) {
        self.header("[[constraints]]");
        self.string("name", &constraint.name);
        let kind = match constraint.kind {
            ConstraintType::Fix => "fix",
            ConstraintType::CoordinateDifference => "coordinate_difference",
        };
        self.string("type", kind);
        for (key, value) in [
            ("body", &constraint.body),
            ("body_i", &constraint.body_i),
            ("body_j", &constraint.body_j),
        ] {
            if let Some(value) = value {
                self.string(key, value);
            }
        }
        self.string("coordinate", constraint.coordinate.as_str());
        self.float("value", constraint.value);
    }

    fn driver(&mut self, driver: &DriverDesc) {
        self.header("[[drivers]]");
        self.string("name", &driver.name);
        if let Some(joint) = &driver.joint {
            self.string("joint", joint);
        }
        if let Some(motion) = driver.motion {
            let motion = match motion {
                Motion::Rotation => "rotation",
                Motion::Translation => "translation",
            };
            self.string("motion", motion);
        }
        if let Some(body) = &driver.body {
            self.string("body", body);
        }
        if let Some(point) = &driver.point {
            self.string("point", point);
        }
        if let Some(coordinate) = driver.coordinate {
            self.string("coordinate", coordinate.as_str());
        }
        if driver.law.input {
            self.string("law", "input");
        } else {
            self.raw("law", &inline_law(&driver.law));
        }
    }

    fn point(&mut self, point: &PointDesc) {
        self.header("[[points]]");
        self.string("name", &point.name);
        self.string("body", &point.body);
        self.opt_vec("local", Some(&point.local[..]));
    }
}

/// A law as an inline table of the members it has.
fn inline_law(law: &LawDesc) -> String {
    let members = [
        ("start", law.start),
        ("velocity", law.velocity),
        ("acceleration", law.acceleration),
        ("offset", law.offset),
        ("amplitude", law.amplitude),
        ("frequency", law.frequency),
        ("phase", law.phase),
    ];
    let inline: Vec<String> = members
        .iter()
        .filter_map(|(key, value)| value.map(|v| format!("{key} = {}", toml_float(v))))
        .collect();
    if inline.is_empty() { "{}".to_owned() } else { format!("{{ {} }}", inline.join(", ")) }
}

/// Accumulates the TOML text; writing to a `String` cannot fail, so no method returns a
/// `Result`.
#[derive(Default)]
struct TomlWriter {
    out: String,
}

impl TomlWriter {
    /// A blank line, then a table header.
    fn header(&mut self, header: &str) {
        self.out.push('\n');
        self.out.push_str(header);
        self.out.push('\n');
    }

    /// `key = value` with the value written as given.
    fn raw(&mut self, key: &str, value: &str) {
        self.out.push_str(key);
        self.out.push_str(" = ");
        self.out.push_str(value);
        self.out.push('\n');
    }

    fn string(&mut self, key: &str, value: &str) {
        self.raw(key, &toml_string(value));
    }

    fn float(&mut self, key: &str, value: f64) {
        self.raw(key, &toml_float(value));
    }

    /// `key = [a, b, c]` when the vector is present.
    fn opt_vec(&mut self, key: &str, value: Option<&[f64]>) {
        if let Some(value) = value {
            let items: Vec<String> = value.iter().map(|&x| toml_float(x)).collect();
            self.raw(key, &format!("[{}]", items.join(", ")));
        }
    }
}

/// A float in TOML syntax that parses back to the same `f64`: Rust's `{:?}` gives the
/// shortest round-trip form and always a `.` or an exponent (`0.0`, `1.19e-7`), which TOML
/// reads as a float.
fn toml_float(x: f64) -> String {
    if x.is_nan() {
        "nan".to_owned()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.to_owned()
    } else {
        format!("{x:?}")
    }
}

/// A TOML basic string: quotes, backslashes and control characters escaped.
fn toml_string(s: &str) -> String {
    let mut out = String::with_capacity(s.len() + 2);
    out.push('"');
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            '\n' => out.push_str("\\n"),
            '\t' => out.push_str("\\t"),
            '\r' => out.push_str("\\r"),
            c if c.is_control() => out.push_str(&format!("\\u{:04X}", u32::from(c))),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}
