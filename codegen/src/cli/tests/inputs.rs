//! `--inputs`, input drivers and point drivers on the command line.

use super::{example, mechgen, rssr_with, temp_file};
use crate::cli::{EXIT_INVALID, EXIT_OK};

fn four_bar() -> String {
    example("inputs/four_bar_input.toml").display().to_string()
}

fn encoder() -> String {
    example("inputs/four_bar_encoder.csv").display().to_string()
}

#[test]
fn input_drivers_without_inputs_are_invalid_input_naming_them_and_the_option() {
    for command in ["solve", "compare", "bench"] {
        let (code, out, err) = mechgen(&[command, &four_bar(), "--format", "json"]);
        assert_eq!(code, EXIT_INVALID, "{command}: {err}");
        assert!(err.contains("driver crank") && err.contains("--inputs"), "{command}: {err}");
        let v: serde_json::Value = serde_json::from_str(&out).expect("JSON error object");
        assert_eq!(v["error"]["kind"], "invalid_input", "{command}");
    }
    // `check` and `generate` take the description: the module has a field per input driver.
    assert_eq!(mechgen(&["check", &four_bar()]).0, EXIT_OK);
    let (code, out, err) = mechgen(&["generate", &four_bar()]);
    assert_eq!(code, EXIT_OK, "{err}");
    assert!(
        out.contains("pub struct Inputs {")
            && out.contains("pub crank: runtime::input::Input<f64>,")
    );
    assert!(out.contains("impl runtime::input::Driven<INPUTS, f64> for FourBarInput"));
}

/// B of the four-bar at crank angle θ, closed form: A = (cos θ, sin θ) on the unit crank, B
/// at 3 from A and 2.5 from O4 = (3, 0), on the side of AO4 the assembly starts on (left of
/// the line from A to O4, y > 0 at θ = 0).
fn four_bar_b(theta: f64) -> [f64; 2] {
    let a = [theta.cos(), theta.sin()];
    let (o4, l3, l4) = ([3.0, 0.0], 3.0, 2.5);
    let d = [o4[0] - a[0], o4[1] - a[1]];
    let dist = d[0].hypot(d[1]);
    // Distance from A along AO4 to the foot of B, and B's height above the line.
    let along = (l3 * l3 - l4 * l4 + dist * dist) / (2.0 * dist);
    let height = (l3 * l3 - along * along).sqrt();
    let (ux, uy) = (d[0] / dist, d[1] / dist);
    [a[0] + along * ux - height * uy, a[1] + along * uy + height * ux]
}

#[test]
fn both_engines_replay_the_encoder_onto_the_closed_form_and_agree() {
    let rows = std::fs::read_to_string(encoder()).expect("encoder");
    let theta: Vec<(f64, f64)> = rows
        .lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with('t'))
        .map(|l| {
            let mut c = l.split(',').map(|x| x.parse::<f64>().expect("number"));
            (c.next().expect("t"), c.next().expect("crank"))
        })
        .collect();
    let mut runs = Vec::new();
    for engine in ["generic", "generated"] {
        let args =
            ["solve", &four_bar(), "--inputs", &encoder(), "--engine", engine, "--format", "json"];
        let (code, out, err) = mechgen(&args);
        assert_eq!(code, EXIT_OK, "{engine}: {err}");
        let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
        assert_eq!(v["engine"], engine);
        let steps = v["steps"].as_array().expect("steps").clone();
        assert_eq!(steps.len(), theta.len(), "{engine}: one step per recorded row");
        for (step, &(t, th)) in steps.iter().zip(&theta) {
            assert_eq!(step["t"].as_f64(), Some(t));
            let r = &step["points"]["B"]["r"];
            let b = four_bar_b(th);
            for (i, want) in b.iter().enumerate() {
                let got = r[i].as_f64().expect("r");
                // Newton stops at max |Φ| ≤ 1e-10 on links of about 3: the position error is of
                // that order times the conditioning (≈ 10 here), so 1e-8 is a safe bound.
                assert!((got - want).abs() < 1e-8, "{engine} t {t}: B[{i}] {got} vs {want}");
            }
        }
        runs.push(steps);
    }
    // Velocities and accelerations use the estimated rates in both engines alike: they agree
    // to the Newton tolerance's effect (1e-10 relative on positions, amplified by the
    // conditioning and the finite-difference rates' size, ≈ 30 rad/s²), so 1e-7.
    for (a, b) in runs[0].iter().zip(&runs[1]) {
        for key in ["v", "a"] {
            for i in 0..3 {
                let (x, y) = (a["points"]["B"][key][i].as_f64(), b["points"]["B"][key][i].as_f64());
                let (x, y) = (x.expect("value"), y.expect("value"));
                assert!(
                    (x - y).abs() <= 1e-7 * (1.0 + x.abs()),
                    "t {}: B.{key}[{i}] {x} vs {y}",
                    a["t"]
                );
            }
        }
    }
}

#[test]
fn the_recorded_encoder_replays_with_rates_estimated_and_joint_columns() {
    let (code, out, err) = mechgen(&[
        "solve",
        &four_bar(),
        "--inputs",
        &encoder(),
        "--engine",
        "generic",
        "--format",
        "json",
    ]);
    assert_eq!(code, EXIT_OK, "{err}");
    assert!(err.contains("crank.dot") && err.contains("finite differences"), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    let steps = v["steps"].as_array().expect("steps");
    let rows = std::fs::read_to_string(encoder()).expect("encoder");
    let rows = rows.lines().filter(|l| !l.starts_with('#')).count() - 1;
    assert_eq!(steps.len(), rows, "one step per recorded row");
    assert!(v["error"].is_null());
    let last = &steps[rows - 1];
    assert_eq!(last["t"].as_f64(), Some(2.0));
    assert!(last["joints"]["O4"]["angle_ddot"].is_f64() && last["joints"]["O2"]["angle"].is_f64());

    // The default engine is the generated one, with inputs too: no fall-back warning.
    let (code, out, err) =
        mechgen(&["solve", &four_bar(), "--inputs", &encoder(), "--format", "csv"]);
    assert_eq!(code, EXIT_OK, "{err}");
    assert!(!err.contains("using the generic engine"), "{err}");
    let header = out.lines().next().expect("header");
    assert!(
        header.ends_with("O2.angle,O2.angle_dot,O2.angle_ddot,O4.angle,O4.angle_dot,O4.angle_ddot")
    );
}

#[test]
fn a_bad_inputs_file_is_invalid_input_naming_file_line_column_and_header() {
    let bad = temp_file("bad_encoder.csv", "t,crank\n0,0\n0.1,zero\n");
    let (code, out, err) = mechgen(&[
        "solve",
        &four_bar(),
        "--inputs",
        &bad.display().to_string(),
        "--engine",
        "generic",
        "--format",
        "json",
    ]);
    assert_eq!(code, EXIT_INVALID, "{err}");
    assert!(err.contains("bad_encoder.csv:3:5") && err.contains("\"crank\""), "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("only the error object");
    assert_eq!(v["error"]["line"], 3);
    assert!(v.get("steps").is_none(), "no partial run");
}

#[test]
fn law_spellings_and_point_driver_mistakes_are_named() {
    let cases = [
        ("law = \"inptu\"", "unknown value \"inptu\""),
        ("law = { velocty = 1.0 }", "did you mean `velocity`"),
        ("law = 3.0", "expected a law table"),
    ];
    for (law, want) in cases {
        let text = rssr_with(
            &format!("[[drivers]]\nname = \"m\"\njoint = \"O2\"\nmotion = \"rotation\"\n{law}\n"),
            false,
        );
        let path = temp_file("law.toml", &text);
        let (code, _, err) = mechgen(&["check", &path.display().to_string()]);
        assert_eq!(code, EXIT_INVALID, "{law}: {err}");
        assert!(err.contains(want), "{law}: {err}");
    }
    let point = |coordinate: &str, name: &str| {
        rssr_with(
            &format!(
                "[[drivers]]\nname = \"m\"\npoint = \"{name}\"\ncoordinate = \"{coordinate}\"\nlaw = \"input\"\n"
            ),
            false,
        )
    };
    for (text, want) in [
        (point("rx", "B"), "a point driver takes x, y or z"),
        (point("x", "nowhere"), "unknown point \"nowhere\""),
    ] {
        let path = temp_file("point.toml", &text);
        let (code, _, err) = mechgen(&["check", &path.display().to_string()]);
        assert_eq!(code, EXIT_INVALID, "{err}");
        assert!(err.contains(want), "{err}");
    }
}
