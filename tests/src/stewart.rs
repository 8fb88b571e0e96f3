//! The Gough–Stewart platform of examples/inputs/stewart.toml: the description is the geometry
//! of `examples::stewart`, the shipped inputs file holds that module's closed-form leg lengths,
//! and `solve --inputs` on either engine recovers the platform's trajectory from them.

use crate::harness::mechgen;

use examples::stewart::{self, LEGS, Trajectory};
use nalgebra::{Matrix3, Vector3};
use serde_json::Value;

fn description() -> String {
    codegen::testing::example_arg("inputs/stewart.toml")
}

fn legs_file() -> String {
    codegen::testing::example_arg("inputs/stewart_legs.csv")
}

/// The entry of `array` (`[[bodies]]`, `[[joints]]`, …) called `name`.
fn entry<'a>(doc: &'a toml::Table, array: &str, name: &str) -> &'a toml::Table {
    doc[array]
        .as_array()
        .and_then(|a| {
            a.iter().filter_map(toml::Value::as_table).find(|e| e["name"].as_str() == Some(name))
        })
        .unwrap_or_else(|| panic!("no {array} entry {name}"))
}

/// The 3-vector `key` of a table.
fn vector(table: &toml::Table, key: &str) -> Vector3<f64> {
    let a = table[key].as_array().unwrap_or_else(|| panic!("{key} is not an array"));
    Vector3::from_iterator(a.iter().map(|x| x.as_float().expect("a number")))
}

/// A(p) of Euler parameters p (thesis eq. 3.17), written out independently of codegen.
fn rotation(p: [f64; 4]) -> Matrix3<f64> {
    let [e0, e1, e2, e3] = p;
    2.0 * Matrix3::new(
        e0 * e0 + e1 * e1 - 0.5,
        e1 * e2 - e0 * e3,
        e1 * e3 + e0 * e2,
        e1 * e2 + e0 * e3,
        e0 * e0 + e2 * e2 - 0.5,
        e2 * e3 - e0 * e1,
        e1 * e3 - e0 * e2,
        e2 * e3 + e0 * e1,
        e0 * e0 + e3 * e3 - 0.5,
    )
}

#[test]
fn the_description_is_the_closed_form_geometry_and_has_six_degrees_of_freedom() {
    let text = std::fs::read_to_string(description()).expect("the description");
    let doc: toml::Table = text.parse().expect("TOML");
    let home = stewart::home_position();
    assert_eq!(vector(entry(&doc, "bodies", "platform"), "r"), home);
    for k in 0..LEGS {
        let n = k + 1;
        let (a, b) = (stewart::base_point(k), stewart::platform_point(k));
        let u = (home + b - a).normalize();
        // The numbers were printed from the closed form with round-trip precision.
        let close = |x: Vector3<f64>, y: Vector3<f64>| (x - y).abs().max() < 1e-15;
        assert!(close(vector(entry(&doc, "joints", &format!("U{n}")), "point_i"), a), "U{n}");
        assert!(close(vector(entry(&doc, "joints", &format!("S{n}")), "point_j"), b), "S{n}");
        assert!(close(vector(entry(&doc, "bodies", &format!("cylinder{n}")), "r"), a));
        assert!(close(vector(entry(&doc, "bodies", &format!("rod{n}")), "r"), home + b));
        let prismatic = entry(&doc, "joints", &format!("P{n}"));
        assert!(close(vector(prismatic, "axis_i"), u), "P{n} is along leg {n}");
        let driver = entry(&doc, "drivers", &format!("leg{n}"));
        assert_eq!(driver["joint"].as_str(), Some(format!("P{n}").as_str()));
        assert_eq!(driver["law"].as_str(), Some("input"));
    }
    // Gruebler: 13 moving bodies × 6 − 6 × (4 + 5 + 3) = 6, and no joint row is redundant.
    let (code, out, err) = mechgen(&["check", &description()]);
    assert_eq!(code, 0, "{err}");
    for line in ["rank of Φ_q:       91", "mobility:          6", "redundant:         none"] {
        assert!(out.contains(line), "{out}");
    }
}

#[test]
fn the_shipped_inputs_are_the_closed_form_leg_lengths() {
    let text = std::fs::read_to_string(legs_file()).expect("the inputs file");
    let mut rows = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = rows.next().expect("a header").split(',').collect();
    assert_eq!(header.len(), 1 + 3 * LEGS);
    let mut count = 0;
    for row in rows {
        let cells: Vec<f64> = row.split(',').map(|c| c.parse().expect("a number")).collect();
        let legs = stewart::leg_lengths(&Trajectory::SHIPPED.at(cells[0]));
        for (k, leg) in legs.iter().enumerate() {
            for (j, (suffix, value)) in ["", ".dot", ".ddot"].iter().zip(leg).enumerate() {
                assert_eq!(header[1 + 3 * k + j], format!("leg{}{suffix}", k + 1));
                // Written with round-trip precision; sin and cos of another libm may differ
                // in the last bit or two.
                let cell = cells[1 + 3 * k + j];
                assert!((cell - value).abs() <= 1e-15 * (1.0 + value.abs()), "t = {}", cells[0]);
            }
        }
        count += 1;
    }
    assert_eq!(count, 101, "2 s every 20 ms");
}

#[test]
fn solve_with_the_leg_lengths_recovers_the_platform_trajectory_on_both_engines() {
    for engine in ["generic", "generated"] {
        recovers_the_platform_trajectory(engine);
    }
}

fn recovers_the_platform_trajectory(engine: &str) {
    let (code, out, err) = mechgen(&[
        "solve",
        &description(),
        "--inputs",
        &legs_file(),
        "--engine",
        engine,
        "--format",
        "json",
    ]);
    assert_eq!(code, 0, "{engine}: {err}");
    let v: Value = serde_json::from_str(&out).expect("JSON");
    let steps = v["steps"].as_array().expect("steps");
    assert_eq!(steps.len(), 101);
    let three =
        |x: &Value| Vector3::from_iterator((0..3).map(|i| x[i].as_f64().expect("a number")));
    let mut worst = [0.0f64; 6];
    for step in steps {
        let t = step["t"].as_f64().expect("t");
        let m = Trajectory::SHIPPED.at(t);
        let body = &step["bodies"]["platform"];
        let p = [0, 1, 2, 3].map(|i| body["p"][i].as_f64().expect("e_i"));
        let errors = [
            (three(&body["r"]) - m.position).abs().max(),
            (rotation(p) - m.rotation).abs().max(),
            (three(&body["r_dot"]) - m.velocity).abs().max(),
            (three(&body["omega"]) - m.angular_velocity).abs().max(),
            (three(&body["r_ddot"]) - m.acceleration).abs().max(),
            (three(&body["alpha"]) - m.angular_acceleration).abs().max(),
        ];
        for (w, e) in worst.iter_mut().zip(errors) {
            *w = w.max(e);
        }
    }
    // Newton stops at max |Φ_i| ≤ 1e-12 (the description's tolerance), and the Jacobian of the
    // leg lengths has a condition number below 4.3 along this trajectory, so the pose is within
    // about 1e-11 (measured on both engines: 8e-13 m, 1.2e-12): the issue's 1e-10 holds with
    // margin.
    assert!(worst[0] < 1e-10 && worst[1] < 1e-10, "{engine}: pose errors {worst:?}");
    // Velocities and accelerations come from Φ_q q̇ = ν and Φ_q q̈ = γ at that pose with the
    // exact l̇ and l̈ of the file: they err by the pose error times the rates over the lever
    // arms (|v|, |ω| ≲ 0.2, lever arms ≥ 0.5 m: a factor below 1) plus round-off, so 1e-10
    // holds as for the pose (measured: 4e-14 to 2e-13).
    for (what, error) in ["v", "ω", "a", "α"].iter().zip(&worst[2..]) {
        assert!(*error < 1e-10, "{engine}: {what}: {error:e} (all: {worst:?})");
    }
}
