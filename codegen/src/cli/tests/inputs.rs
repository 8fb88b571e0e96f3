//! `--inputs`, input drivers and point drivers on the command line.

use super::{example, mechgen, rssr_with, temp_file};
use crate::cli::{EXIT_BUILD, EXIT_INVALID, EXIT_OK};

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
    // `check` and `generate` take the description; generate cannot emit inputs yet (status 3).
    assert_eq!(mechgen(&["check", &four_bar()]).0, EXIT_OK);
    let (code, _, err) = mechgen(&["generate", &four_bar()]);
    assert_eq!(code, EXIT_BUILD, "{err}");
    assert!(err.contains("not supported by the generated engine yet"), "{err}");
}

#[test]
fn the_recorded_encoder_replays_on_the_generic_engine_and_the_default_falls_back() {
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

    let (code, _, err) =
        mechgen(&["solve", &four_bar(), "--inputs", &encoder(), "--engine", "generated"]);
    assert_eq!(code, EXIT_BUILD, "{err}");
    assert!(
        err.contains("the generated solver could not be built: input drivers are not supported"),
        "{err}"
    );
    let (code, out, err) =
        mechgen(&["solve", &four_bar(), "--inputs", &encoder(), "--format", "csv"]);
    assert_eq!(code, EXIT_OK, "{err}");
    assert!(err.contains("warning: using the generic engine"), "{err}");
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
