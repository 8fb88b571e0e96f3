//! Grids far from t = 0 driven into a singular position: every command stops with status 2
//! at the grid time past it (issue: sub-steps below the spacing of floating-point time made
//! the step control cycle forever, so these commands hung with nothing written).

use std::path::PathBuf;
use std::sync::mpsc;
use std::time::Duration;

use super::{EXIT_STOPPED, mechgen, temp_file};

/// How long one command may take before the test calls it a hang: the generic analyses take
/// well under a second; a generated solver's first build takes up to a minute on a loaded
/// machine.
const HANG: Duration = Duration::from_secs(600);

/// Runs mechgen on its own thread and fails the test, instead of hanging it, when the
/// command does not return within [`HANG`].
fn mechgen_bounded(args: &[&str]) -> (i32, String, String) {
    let args: Vec<String> = args.iter().map(|&a| a.to_owned()).collect();
    let (send, receive) = mpsc::channel();
    let shown = args.join(" ");
    std::thread::spawn(move || {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let _ = send.send(mechgen(&args));
    });
    receive.recv_timeout(HANG).unwrap_or_else(|_| panic!("`mechgen {shown}` does not return"))
}

/// The slider-crank of the stability suite (crank 1, rod 3, driven by its slider from x = 3.5
/// towards the outer dead centre at x = 4, where Φ_q is singular and beyond which there is no
/// assembly), on the grid `origin + k·step` with the slider at `velocity`. Returns the file
/// and the first grid time past the dead centre.
fn dead_centre_far_from_zero(origin: f64, step: f64, velocity: f64) -> (PathBuf, f64) {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../tests/stability/slider_crank_dead_centre.toml");
    let text = std::fs::read_to_string(path).expect("the stability case");
    // The dead centre is 0.5 of slider travel away; the grid passes it by 3 steps.
    let past = (0.5 / velocity / step).ceil();
    let end = origin + (past + 3.0) * step;
    let text = text
        .replace(
            "start = 0.0\nend = 0.9\nstep = 0.03",
            &format!("start = {origin:?}\nend = {end:?}\nstep = {step:?}"),
        )
        .replace(
            "law = { start = 3.5, velocity = 1.0, acceleration = 0.0 }",
            // x = 3.5 at t = origin: both terms are exact in f64 for the origins tested.
            &format!("law = {{ start = {:?}, velocity = {velocity:?} }}", 3.5 - velocity * origin),
        );
    assert!(text.contains(&format!("start = {origin:?}")), "the grid was replaced");
    let name = format!("dead_centre_{origin:e}.toml");
    // The grid time is computed as the model does: start + k·step.
    (temp_file(&name, &text), origin + past * step)
}

/// The cases: at 1e12 the spacing of f64 is 1.2e-4, so sub-steps of 0.03/2⁹ no longer move
/// t; at 1e17 it is 16, so a grid step of 48 leaves only two halvings.
fn cases() -> [(PathBuf, f64); 2] {
    [
        dead_centre_far_from_zero(1e12, 0.03, 1.0),
        dead_centre_far_from_zero(1e17, 48.0, 1.0 / 1024.0),
    ]
}

/// Checks a stopped `solve --format json`: the failure's kind and grid time, and that every
/// step before it was written.
fn assert_stopped_json(out: &str, t_fail: f64, what: &str) -> serde_json::Value {
    let v: serde_json::Value = serde_json::from_str(out).expect("valid JSON");
    let kind = v["error"]["kind"].as_str().unwrap_or_else(|| panic!("{what}: {v}"));
    assert!(["singular", "no_convergence"].contains(&kind), "{what}: {}", v["error"]);
    assert_eq!(v["error"]["t"].as_f64(), Some(t_fail), "{what}: {}", v["error"]);
    let steps = v["steps"].as_array().expect("steps");
    assert!(!steps.is_empty(), "{what}: the steps before the dead centre are written");
    assert!(steps.iter().all(|s| s["t"].as_f64().unwrap() < t_fail), "{what}");
    v
}

#[test]
fn solve_stops_on_both_engines_when_sub_steps_no_longer_change_t() {
    for (file, t_fail) in cases() {
        let file = file.to_str().unwrap();
        let (code, out, err) =
            mechgen_bounded(&["solve", file, "--engine", "generic", "--format", "json"]);
        assert_eq!(code, EXIT_STOPPED, "{err}");
        let generic = assert_stopped_json(&out, t_fail, file);
        let (code, out, err) =
            mechgen_bounded(&["solve", file, "--engine", "generated", "--format", "json"]);
        assert_eq!(code, EXIT_STOPPED, "{err}");
        let generated = assert_stopped_json(&out, t_fail, file);
        assert_eq!(generic["error"]["kind"], generated["error"]["kind"], "{file}");
        assert_eq!(
            generic["steps"].as_array().map(Vec::len),
            generated["steps"].as_array().map(Vec::len)
        );
    }
}

#[test]
fn plot_compare_and_chart_stop_when_sub_steps_no_longer_change_t() {
    for (file, t_fail) in cases() {
        let file = file.to_str().unwrap();
        let svg = format!("{file}.svg");
        let (code, out, err) = mechgen_bounded(&["plot", file, "--body", "slider", "-o", &svg]);
        assert_eq!(code, EXIT_STOPPED, "{out}{err}");
        assert!(err.contains(&format!("at t = {t_fail}")), "{err}");
        let drawn = std::fs::read_to_string(&svg).expect("the steps before the stop are drawn");
        assert!(drawn.starts_with("<svg"), "{file}");
        let (code, _, err) = mechgen_bounded(&["compare", file]);
        assert_eq!(code, EXIT_STOPPED, "{err}");
        assert!(err.contains(&format!("at t = {t_fail}")), "{err}");
        let (code, _, err) = mechgen_bounded(&["chart", file, "-o", &svg, "--repeats", "1"]);
        assert_eq!(code, EXIT_STOPPED, "{err}");
        assert!(err.contains("the run the reference starts from stopped"), "{err}");
    }
}
