//! Bodies alike share one `expand` function (`emit::expand_shared`): independent arms whose
//! coordinates are the same expressions up to their constants run one function per shape,
//! called in a loop, for driven laws and for inputs. Checked against the generic engine.

use codegen::emit::module;
use codegen::symbolic::Symbolic;
use codegen::testing::{
    build_generated, load_toml, relative_differences, run_generated, run_generic,
};

use crate::harness::mechgen;

/// Three arms of four links (`codegen::scale::arms`): the first stands at y = 0, so its
/// expressions fold a zero the others add; arms 2 and 3 are alike.
fn arms() -> String {
    codegen::scale::arms(3, 4, 20)
}

#[test]
fn alike_arms_share_one_expand_function_and_match_the_generic_engine() {
    let mech = load_toml(&format!("{}\n[solver]\ntolerance = 1e-12\n", arms()));
    let sys = Symbolic::build(&mech).expect("generates");
    assert!(sys.unknowns.is_empty(), "driven arms are explicit");
    let code = module(&mech, &sys, "a test");
    assert!(code.contains("fn expand_shared_0("), "one shared function");
    assert!(code.contains("for m in 0..2"), "called for arms 2 and 3");
    assert!(code.contains("fn expand_rest("), "arm 1 apart");
    let generic = run_generic(&mech);
    let generated = run_generated(&mech, &build_generated(&mech));
    assert!(generic.failure.is_none() && generated.failure.is_none());
    // Nothing is left for Newton: no step is taken or reported.
    assert!(generated.frames.iter().all(|f| f.iterations == 0), "an explicit module iterates");
    assert_eq!(generic.frames.len(), generated.frames.len());
    for (diff, at) in relative_differences(&generic.frames, &generated.frames) {
        // Both engines evaluate closed forms of the same geometry (the generic one by Newton to
        // 1e-12 on unit-sized links): they agree to round-off, 1e-10 flags any wrong slot,
        // constant or window of the shared function (off by the arms' spacing, 1).
        assert!(diff <= 1e-10, "{at}");
    }
}

#[test]
fn alike_arms_driven_by_inputs_share_expand_and_both_engines_agree_on_a_recorded_series() {
    // Every motor an input; the series is s = 0.3 sin(ω t) with its exact rate and
    // acceleration, a different ω per motor.
    let text = arms();
    let mut described = String::new();
    let mut motors = Vec::new();
    for line in text.lines() {
        if let Some(name) = line.strip_prefix("name = \"").and_then(|n| n.strip_suffix('"'))
            && name.contains("_motor")
        {
            motors.push(name.to_owned());
        }
        if line.starts_with("law = {") {
            described.push_str("law = \"input\"\n");
        } else {
            described.push_str(line);
            described.push('\n');
        }
    }
    assert_eq!(motors.len(), 12);
    let dir = std::env::temp_dir().join(format!("mechgen-shared-expand-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let file = dir.join("arms.toml");
    std::fs::write(&file, &described).expect("writable");
    let mech = load_toml(&described);
    let code = module(&mech, &Symbolic::build(&mech).expect("generates"), "a test");
    assert!(code.contains("fn expand_shared_0(") && code.contains("u: &[[f64; 3]; INPUTS]"));
    let mut csv = String::from("t");
    for m in &motors {
        csv.push_str(&format!(",{m},{m}.dot,{m}.ddot"));
    }
    csv.push('\n');
    for k in 0..40 {
        let t = f64::from(k) * 0.01;
        csv.push_str(&format!("{t}"));
        for (j, _) in motors.iter().enumerate() {
            let w = 3.0 + j as f64;
            let (s, c) = (w * t).sin_cos();
            csv.push_str(&format!(",{},{},{}", 0.3 * s, 0.3 * w * c, -0.3 * w * w * s));
        }
        csv.push('\n');
    }
    let series = dir.join("series.csv");
    std::fs::write(&series, csv).expect("writable");
    let (file, series) = (file.display().to_string(), series.display().to_string());
    let (status, out, err) = mechgen(&["compare", &file, "--inputs", &series, "--format", "json"]);
    assert_eq!(status, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(v["steps"].as_u64(), Some(40));
    assert_eq!(v["disagree"], serde_json::json!([]), "{v}");
    for (quantity, d) in v["max_abs_diff"].as_object().expect("max_abs_diff") {
        // Closed forms on both sides (unit-sized links, rates up to 0.3 × 14 and accelerations
        // up to 0.3 × 14² ≈ 60): round-off of a few 1e-14 relative; 1e-10 absolute flags any
        // misplaced input slot, which is off by the difference of two motors' series.
        let d = d.as_f64().expect("a number");
        assert!(d < 1e-10, "{quantity}: {d:e}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}
