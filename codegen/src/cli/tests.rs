//! The command line run in process: exit statuses, JSON shapes and messages.

use std::path::PathBuf;

use super::{EXIT_INVALID, EXIT_OK, EXIT_STOPPED, run};

use crate::testing::example;

/// Writes `text` to a fresh file in the temporary directory.
fn temp_file(name: &str, text: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mechgen-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary directory");
    let path = dir.join(name);
    std::fs::write(&path, text).expect("temporary file");
    path
}

/// Runs mechgen and returns (status, stdout, stderr); the plot tests use it too.
pub(super) fn mechgen(args: &[&str]) -> (i32, String, String) {
    let mut argv = vec!["mechgen".into()];
    argv.extend(args.iter().map(Into::into));
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let code = run(argv, &mut out, &mut err);
    (code, String::from_utf8(out).expect("utf-8"), String::from_utf8(err).expect("utf-8"))
}

/// The RSSR with its driver replaced by `extra` (TOML appended).
fn rssr_with(extra: &str, keep_driver: bool) -> String {
    let text = std::fs::read_to_string(example("rssr.toml")).expect("rssr example");
    let text = if keep_driver {
        text
    } else {
        let start = text.find("[[drivers]]").expect("driver section");
        let end = text.find("[[points]]").expect("points section");
        format!("{}{}", &text[..start], &text[end..])
    };
    format!("{text}\n{extra}\n")
}

#[test]
fn check_json_reports_the_counts_of_the_rssr() {
    let (code, out, _) =
        mechgen(&["check", example("rssr.toml").to_str().unwrap(), "--format", "json"]);
    assert_eq!(code, EXIT_OK);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    // Three moving bodies: 21 unknowns; 2 spherical (6) + 2 revolute (10) + fix + driver +
    // 3 normalisations = 21 equations; one crank drives a one-degree-of-freedom loop.
    assert_eq!(v["bodies"], 4);
    assert_eq!(v["unknowns"], 21);
    assert_eq!(v["equations"], 21);
    assert_eq!(v["rank"], 21);
    assert_eq!(v["mobility"], 1);
    assert_eq!(v["drivers"], 1);
    // The fix constraint on e2 of the coupler is eliminated in the generated system.
    assert_eq!(v["reduced_unknowns"], 20);
    assert_eq!(v["redundant"], serde_json::json!([]));
}

#[test]
fn check_reports_the_blocks_of_the_generated_system() {
    // The R-S-S-R (see `blocks::tests`): the origins of crank, coupler and rocker sit on O2, A
    // and O4, nine coordinates each alone and affine; the crank's orientation is a block of four
    // (O2's axis rows, the motor, its normalisation), a rotation about O2's axis in closed form;
    // the coupler's e0, e1, e3 and the rocker's four Euler parameters close the loop, one
    // implicit block of seven.
    let (code, out, _) =
        mechgen(&["check", example("rssr.toml").to_str().unwrap(), "--format", "json"]);
    assert_eq!(code, EXIT_OK);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(
        v["blocks"],
        serde_json::json!({
            "count": 11,
            "closed_form": 10,
            "rotations": 1,
            "implicit": 1,
            "largest_implicit": 7,
            "sizes": [
                { "size": 1, "count": 9 },
                { "size": 4, "count": 1 },
                { "size": 7, "count": 1 },
            ],
        })
    );
    // A driven chain of five links: per link one orientation block of four, a rotation in
    // closed form, and three closed-form positions.
    let file = temp_file("chain_5.toml", &crate::scale::chain(5, 3));
    let (code, out, _) = mechgen(&["check", file.to_str().unwrap()]);
    assert_eq!(code, EXIT_OK);
    assert!(
        out.contains("blocks:            20 (20 closed form, 5 of them rotations, 0 implicit)\n"),
        "{out}"
    );
    assert!(out.contains("block sizes:       15 of 1, 5 of 4\n"), "{out}");
}

#[test]
fn an_input_driver_gives_the_blocks_a_law_driver_gives() {
    // The structure of Φ_q does not depend on the driver's law.
    let file = example("inputs/four_bar_input.toml");
    let text = std::fs::read_to_string(&file).expect("the example");
    let law = text.replace("law = \"input\"", "law = { start = 0.0, velocity = 1.0 }");
    assert_ne!(law, text, "the input driver's law is replaced");
    let law_file = temp_file("four_bar_law.toml", &law);
    let blocks = |path: &std::path::Path| {
        let (code, out, err) = mechgen(&["check", path.to_str().unwrap(), "--format", "json"]);
        assert_eq!(code, EXIT_OK, "{err}");
        let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
        v["blocks"].clone()
    };
    let with_input = blocks(&file);
    assert!(with_input["count"].as_u64().is_some_and(|n| n > 1), "{with_input}");
    assert_eq!(with_input, blocks(&law_file));
}

#[test]
fn check_names_a_redundant_equation() {
    // The crank's y is already held by revolute O2; fixing it again is redundant.
    let extra = "[[constraints]]\nname = \"again\"\ntype = \"fix\"\nbody = \"crank\"\ncoordinate = \"y\"\nvalue = -0.06567\n";
    let file = temp_file("redundant.toml", &rssr_with(extra, true));
    let (code, out, _) = mechgen(&["check", file.to_str().unwrap(), "--format", "json"]);
    assert_eq!(code, EXIT_OK);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["equations"], 22);
    assert_eq!(v["rank"], 21);
    assert_eq!(v["redundant"], serde_json::json!(["constraint again"]));
}

#[test]
fn solve_handles_a_consistent_redundant_constraint() {
    let extra = "[[constraints]]\nname = \"again\"\ntype = \"fix\"\nbody = \"crank\"\ncoordinate = \"y\"\nvalue = -0.06567\n";
    let file = temp_file("redundant_solve.toml", &rssr_with(extra, true));
    let (code, out, err) =
        mechgen(&["solve", file.to_str().unwrap(), "--engine", "generic", "--format", "json"]);
    assert_eq!(code, EXIT_OK, "{err}");
    assert!(err.contains("constraint again"), "the dropped equation is named: {err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["steps"].as_array().unwrap().len(), 12);
}

#[test]
fn an_undriven_degree_of_freedom_is_invalid_input_naming_the_bodies() {
    // Replacing the driver by a constraint the revolute already imposes keeps the counts
    // square but leaves the crank free.
    let extra = "[[constraints]]\nname = \"again\"\ntype = \"fix\"\nbody = \"crank\"\ncoordinate = \"y\"\nvalue = -0.06567\n";
    let file = temp_file("undriven.toml", &rssr_with(extra, false));
    let (code, out, _) =
        mechgen(&["solve", file.to_str().unwrap(), "--engine", "generic", "--format", "json"]);
    assert_eq!(code, EXIT_INVALID);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["error"]["kind"], "invalid_input");
    let msg = v["error"]["message"].as_str().unwrap();
    // At t = 0 the rocker sits at a limit position of its swing (its rate is 4e-6 of the
    // crank's), so to first order only the crank and the coupler move.
    for body in ["crank", "coupler"] {
        assert!(msg.contains(body), "{msg}");
    }
}

#[test]
fn solve_json_has_every_body_and_point_at_every_step() {
    let (code, out, _) =
        mechgen(&["solve", example("rssr.toml").to_str().unwrap(), "--format", "json"]);
    assert_eq!(code, EXIT_OK);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["mechanism"], "rssr");
    // The default engine is the generated one when it can be built.
    assert_eq!(v["engine"], "generated");
    assert!(v["error"].is_null());
    let steps = v["steps"].as_array().unwrap();
    // start = 1.19e-7, end = 0.04, step = 0.0035717333: 12 points (0.04 itself is not on the grid).
    assert_eq!(steps.len(), 12);
    for s in steps {
        for body in ["crank", "coupler", "rocker"] {
            for key in ["r", "p", "r_dot", "p_dot", "omega", "r_ddot", "p_ddot", "alpha"] {
                assert!(s["bodies"][body][key].is_array(), "{body}.{key}");
            }
        }
        assert!(s["bodies"].get("ground").is_none());
        for point in ["A", "B"] {
            for key in ["r", "v", "a"] {
                assert_eq!(s["points"][point][key].as_array().unwrap().len(), 3);
            }
        }
    }
}

#[test]
fn solve_csv_names_columns_body_quantity_component() {
    let (code, out, _) = mechgen(&[
        "solve",
        example("rssr.toml").to_str().unwrap(),
        "--engine",
        "generic",
        "--format",
        "csv",
    ]);
    assert_eq!(code, EXIT_OK);
    let mut lines = out.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    assert_eq!(&header[..6], ["t", "iterations", "residual", "condition", "suspect", "crank.r.x"]);
    assert!(header.contains(&"B.a.z"));
    assert!(header.contains(&"coupler.omega.y"));
    // 3 bodies × 27 scalars (r 3, p 4, ṙ 3, ṗ 4, ω 3, r̈ 3, p̈ 4, α 3) + 2 points × 9 + 5 leading
    // columns.
    assert_eq!(header.len(), 5 + 3 * 27 + 2 * 9);
    assert_eq!(lines.count(), 12);
}

#[test]
fn a_description_error_has_status_1_and_a_place() {
    let text = std::fs::read_to_string(example("rssr.toml")).unwrap().replace(
        "body_j = \"coupler\"\npoint_i = [0.0, 0.06567",
        "body_j = \"couple\"\npoint_i = [0.0, 0.06567",
    );
    let file = temp_file("typo.toml", &text);
    let (code, out, err) =
        mechgen(&["solve", file.to_str().unwrap(), "--engine", "generic", "--format", "json"]);
    assert_eq!(code, EXIT_INVALID);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    assert_eq!(v["error"]["kind"], "invalid_input");
    assert_eq!(v["error"]["entity"], "joint \"A\"");
    assert_eq!(v["error"]["field"], "body_j");
    assert!(v["error"]["line"].as_u64().unwrap() > 30);
    assert!(err.contains("couple"), "{err}");
    assert!(!err.contains("panicked"));
}

#[test]
fn an_impossible_motion_stops_with_status_2_after_the_valid_steps() {
    // A rod of length 1 hinged at the origin with its end driven along x at 1 m/s: the
    // motion exists for t < 1 and is impossible after that. The grid steps over t = 1, the
    // singular stretched position itself (a stability case of its own).
    let text = r#"
name = "overstretched"
[time]
start = 0.0
end = 2.0
step = 0.3
[[bodies]]
name = "ground"
ground = true
[[bodies]]
name = "slider"
r = [0.0, 1.0, 0.0]
[[joints]]
name = "rod"
type = "distance"
body_i = "ground"
body_j = "slider"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, 0.0, 0.0]
distance = 1.0
[[constraints]]
name = "z0"
type = "fix"
body = "slider"
coordinate = "z"
value = 0.0
[[constraints]]
name = "e1"
type = "fix"
body = "slider"
coordinate = "e1"
value = 0.0
[[constraints]]
name = "e2"
type = "fix"
body = "slider"
coordinate = "e2"
value = 0.0
[[constraints]]
name = "e3"
type = "fix"
body = "slider"
coordinate = "e3"
value = 0.0
[[drivers]]
name = "push"
body = "slider"
coordinate = "x"
law = { start = 0.0, velocity = 1.0 }
"#;
    let file = temp_file("overstretched.toml", text);
    let (code, out, _) =
        mechgen(&["solve", file.to_str().unwrap(), "--engine", "generic", "--format", "json"]);
    assert_eq!(code, EXIT_STOPPED);
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    let steps = v["steps"].as_array().unwrap();
    // t = 0, 0.3, 0.6, 0.9 are reachable; t = 1.2 is not.
    assert_eq!(steps.len(), 4, "{}", v["error"]);
    let t = v["error"]["t"].as_f64().unwrap();
    assert!((t - 1.2).abs() < 1e-12, "{t}");
    assert!(["singular", "no_convergence"].contains(&v["error"]["kind"].as_str().unwrap()));
    // y = sqrt(1 − x²) at each valid step, the closed form of the rod.
    for s in steps {
        let x = s["t"].as_f64().unwrap();
        let y = s["bodies"]["slider"]["r"][1].as_f64().unwrap();
        assert!((y - (1.0 - x * x).sqrt()).abs() < 1e-9, "t = {x}: y = {y}");
    }
}

#[test]
fn import_young_prints_a_valid_description() {
    let deck = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/reference/seed-examples/4-bar.deck");
    let (code, out, err) = mechgen(&["import-young", deck.to_str().unwrap()]);
    assert_eq!(code, EXIT_OK, "{err}");
    let loaded = crate::validate::load_str(&out, crate::validate::Format::Toml, None)
        .expect("the imported description validates");
    assert_eq!(loaded.mechanism.bodies.len(), 4);
}

#[test]
fn a_bad_command_line_is_status_1() {
    let (code, _, err) = mechgen(&["solve"]);
    assert_eq!(code, EXIT_INVALID);
    assert!(err.contains("FILE") || err.contains("file"), "{err}");
}

#[test]
fn a_misspelt_field_is_shown_with_an_excerpt_a_caret_and_the_fix() {
    let text = std::fs::read_to_string(example("rssr.toml")).unwrap();
    let at = text.find("axis_i").expect("the RSSR has an axis_i");
    let line = text[..at].matches('\n').count() + 1;
    let file = temp_file("axsi.toml", &text.replacen("axis_i", "axsi_i", 1));
    let (code, out, err) = mechgen(&["check", file.to_str().unwrap()]);
    assert_eq!(code, EXIT_INVALID);
    assert!(out.is_empty(), "{out}");
    assert!(err.contains(&format!("axsi.toml:{line}:1")), "{err}");
    assert!(err.contains("unknown field `axsi_i`: did you mean `axis_i`?"), "{err}");
    // The excerpt, the caret under the key, and the line as the fix would make it.
    let gutter = " ".repeat(line.to_string().len());
    assert!(err.contains(&format!("{line} | axsi_i = ")), "{err}");
    assert!(err.contains(&format!("{gutter} | ^^^^^^\n")), "{err}");
    assert!(err.contains(&format!("{line} + axis_i = ")), "{err}");
    assert!(!err.contains('\u{1b}'), "no colour outside a terminal: {err:?}");
}

#[test]
fn the_json_error_object_stays_as_the_contract_says_when_the_text_has_an_excerpt() {
    let text = std::fs::read_to_string(example("rssr.toml")).unwrap();
    let file = temp_file("axsi_json.toml", &text.replacen("axis_i", "axsi_i", 1));
    let (code, out, _) = mechgen(&["check", file.to_str().unwrap(), "--format", "json"]);
    assert_eq!(code, EXIT_INVALID);
    let v: serde_json::Value = serde_json::from_str(&out).expect("one JSON object on stdout");
    let keys: Vec<&str> = v["error"].as_object().unwrap().keys().map(String::as_str).collect();
    assert_eq!(keys, ["column", "entity", "field", "kind", "line", "message"]);
    assert_eq!(v["error"]["field"], "axsi_i");
}

mod far_time;
mod inputs;
mod output;

#[test]
fn select_writes_only_the_named_points_bodies_and_joints() {
    let file = example("rssr.toml");
    let file = file.to_str().unwrap();
    let args = ["solve", file, "--engine", "generic", "--format", "csv", "--select", "B,crank"];
    let (code, out, err) = mechgen(&args);
    assert_eq!(code, EXIT_OK, "{err}");
    let header: Vec<&str> = out.lines().next().expect("a header").split(',').collect();
    // Every column after t, iterations, residual, condition and suspect belongs to the crank or
    // to point B.
    assert!(header.len() > 5, "{header:?}");
    for column in &header[5..] {
        assert!(column.starts_with("crank.") || column.starts_with("B."), "{column}");
    }
    assert!(header.iter().any(|c| c.starts_with("B.")), "{header:?}");
    // The rocker and point A were left out, in JSON too.
    let json_args = ["solve", file, "--engine", "generic", "--format", "json", "--select", "B"];
    let (code, out, err) = mechgen(&json_args);
    assert_eq!(code, EXIT_OK, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    let step = &v["steps"][0];
    assert!(step["points"]["B"].is_object() && step["points"]["A"].is_null(), "{step}");
    assert!(step["bodies"]["rocker"].is_null(), "{step}");
}

#[test]
fn select_refuses_an_unknown_name_with_the_likely_one() {
    let file = example("rssr.toml");
    let args = [
        "solve",
        file.to_str().unwrap(),
        "--engine",
        "generic",
        "--format",
        "csv",
        "--select",
        "cronk",
    ];
    let (code, out, err) = mechgen(&args);
    assert_eq!(code, EXIT_INVALID, "{out}");
    assert!(err.contains("`cronk`") && err.contains("did you mean `crank`"), "{err}");
    assert!(out.is_empty(), "nothing is analysed: {out}");
}

#[test]
fn compare_reports_a_finite_speedup_and_no_disagreement_on_the_rssr() {
    let file = example("rssr.toml");
    let (code, out, err) = mechgen(&["compare", file.to_str().unwrap(), "--format", "json"]);
    assert_eq!(code, EXIT_OK, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).expect("JSON");
    // Both engines were timed, so the speedup is a positive number (never NaN or null here).
    let speedup = v["speedup"].as_f64().expect("a speedup");
    assert!(speedup.is_finite() && speedup > 0.0, "{v}");
    // The engines agree to round-off on the R-S-S-R (about 1e-15), far below the 1e-6 flag.
    assert_eq!(v["disagree"], serde_json::json!([]), "{v}");
    assert!(!err.contains("differ by more than"), "{err}");
}

#[test]
fn bench_names_the_kind_time_and_reason_of_an_analysis_that_stops() {
    // A crank-rocker driven into its toggle stops at t = 1.35 on both engines; two drivers that
    // contradict each other stop at t = 0. Plain timed steps would pass the second (they do not
    // check the rows a generated module leaves out), so bench must run solve's checked pass.
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../tests");
    let cases = [
        ("stability/crank_rocker_toggle.toml", "singular at t = 1.35", "pivot ratio"),
        ("redundancy/four_bar_conflict.toml", "inconsistent at t = 0", "driver push"),
    ];
    for (name, kind_time, reason) in cases {
        let file = dir.join(name);
        for engine in ["generic", "generated"] {
            let args = ["bench", file.to_str().unwrap(), "--engine", engine, "--repeats", "1"];
            let (code, out, err) = mechgen(&args);
            assert_eq!(code, EXIT_STOPPED, "{name}, {engine}: {err}");
            // Which engine, kind, time and reason, each named; nothing timed.
            assert!(err.contains(&format!("error: {engine} engine")), "{name}, {engine}: {err}");
            assert!(err.contains(kind_time), "{name}, {engine}: {err}");
            assert!(err.contains(reason), "{name}, {engine}: {err}");
            assert!(!out.contains("ns/step"), "{name}, {engine}: {out}");
        }
    }
}

#[test]
fn disagreeing_flags_differences_above_1e_6_relative_and_nan() {
    // Made-up differences: round-off, just below and just above the flag, and a NaN (a
    // quantity one engine did not compute).
    let diffs = [
        ("r", 1e-16, 3e-16),
        ("v", 1e-7, 9.9e-7),
        ("a", 1e-3, 1.01e-6),
        ("omega", f64::NAN, f64::NAN),
    ];
    assert_eq!(super::compare::disagreeing(&diffs), ["a", "omega"]);
    assert!(super::compare::disagreeing(&diffs[..2]).is_empty());
}

#[test]
fn generate_outputs_keeps_what_the_named_outputs_need_and_names_an_unknown_one() {
    // A chain of five driven links: link 2's pose needs links 1 and 2 only.
    let chain = temp_file("chain_5.toml", &crate::scale::chain(5, 5));
    let file = chain.to_str().expect("UTF-8");
    let (code, out, err) = mechgen(&["generate", file, "--outputs", "link2"]);
    assert_eq!(code, EXIT_OK, "{err}");
    // A driven chain is closed form throughout: every coordinate is substituted, none is left.
    assert!(out.contains("pub const N: usize = 0;"), "no unknowns left");
    assert!(out.contains("pub const BODIES: usize = 2;"), "two links");
    assert!(out.contains("pub const BODY_NAMES: [&str; BODIES] = [\"link1\", \"link2\"];"));
    let (code, whole, _) = mechgen(&["generate", file]);
    assert_eq!(code, EXIT_OK);
    assert!(whole.contains("pub const BODIES: usize = 5;"), "the whole chain without --outputs");
    let (code, _, err) = mechgen(&["generate", file, "--outputs", "link2,link9"]);
    assert_eq!(code, EXIT_INVALID);
    assert!(err.contains("\"link9\""), "{err}");
    assert!(err.contains("link1, link2, link3, link4, link5, hinge1"), "{err}");
}
