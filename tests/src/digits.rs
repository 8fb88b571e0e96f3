//! Digits accounted for (issue 15.3): every step carries κ̂, an estimate of the condition of
//! Φ_q, and the velocities and accelerations it cannot vouch for to six significant digits are
//! flagged (`runtime::step::suspect`: κ̂² ε and κ̂³ ε against 1e-6).
//!
//! - The parallelogram four-bar of `tests/digits/` lands 1e-5 and 1e-7 rad past its flat
//!   configuration (a bifurcation, κ ≈ 8.6/δ): against its closed form the accelerations there
//!   have lost digits, and both engines flag them, with exit status 0.
//! - The regular four-bar and the R-S-S-R are flagged nowhere.
//! - κ̂ is checked against κ₂ from a singular value decomposition, for both engines.

use crate::harness::mechgen;
use std::path::{Path, PathBuf};

use codegen::generic::scaling::balanced;
use codegen::generic::{Analysis, Equations};
use nalgebra::{DMatrix, DVector};
use runtime::{Mechanism, Solver};
use serde_json::Value;

fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `solve --format json` of `file` on `engine`: status, output and standard error.
fn solve(file: &Path, engine: &str) -> (i32, Value, String) {
    let (status, out, err) =
        mechgen(&["solve", file.to_str().unwrap(), "--engine", engine, "--format", "json"]);
    let json =
        serde_json::from_str(&out).unwrap_or_else(|e| panic!("{}: {e}: {out}", file.display()));
    (status, json, err)
}

fn number(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn suspects(step: &Value) -> Vec<&str> {
    step["suspect"].as_array().expect("a suspect list").iter().filter_map(Value::as_str).collect()
}

/// The bounds of the rule at condition κ̂: (κ̂² ε, κ̂³ ε), the relative errors it allows
/// velocities and accelerations.
fn bounds(condition: f64) -> (f64, f64) {
    let e = f64::EPSILON;
    (condition * condition * e, condition.powi(3) * e)
}

#[test]
fn the_parallelogram_past_its_flat_configuration_flags_its_accelerations() {
    for delta in ["1e-5", "1e-7"] {
        let file = root().join(format!("tests/digits/parallelogram_past_flat_{delta}.toml"));
        for engine in ["generic", "generated"] {
            let context = format!("δ = {delta}, {engine}");
            let (status, json, err) = solve(&file, engine);
            // A flag is a warning: the analysis itself succeeded.
            assert_eq!(status, 0, "{context}: {err}");
            assert!(json["error"].is_null(), "{context}: {}", json["error"]);
            let steps = json["steps"].as_array().expect("steps");
            assert_eq!(steps.len(), 11, "{context}");
            for step in steps {
                let t = number(&step["t"]);
                let theta = std::f64::consts::PI - 1.0 + delta.parse::<f64>().unwrap() + t;
                let rocker = &step["bodies"]["rocker"];
                let coupler = &step["bodies"]["coupler"];
                // The closed form of the parallelogram branch: the rocker turns with the crank
                // (ω = 1 rad/s, α = 0) and the coupler translates (ω = α = 0) with its origin
                // on the crank pin, at (cos θ, sin θ), accelerating by −(cos θ, sin θ). Its
                // scale is ω² times the crank's length: 1.
                let errors = [
                    (number(&rocker["omega"][2]) - 1.0).abs(),
                    number(&coupler["omega"][2]).abs(),
                    number(&rocker["alpha"][2]).abs(),
                    number(&coupler["alpha"][2]).abs(),
                    (number(&coupler["r_ddot"][0]) + theta.cos()).abs(),
                    (number(&coupler["r_ddot"][1]) + theta.sin()).abs(),
                ];
                let (velocity, acceleration) = (
                    errors[..2].iter().fold(0.0_f64, |a, &b| a.max(b)),
                    errors[2..].iter().fold(0.0_f64, |a, &b| a.max(b)),
                );
                let condition = number(&step["condition"]);
                let (v_bound, a_bound) = bounds(condition);
                let context = format!("{context}, t = {t}: κ̂ {condition:e}, errors {errors:?}");
                if t < 0.95 {
                    // Regular steps (κ̂ ≤ 30): nothing flagged, and the closed form holds to
                    // far better than six digits.
                    assert!(suspects(step).is_empty(), "{context}");
                    assert!(acceleration < 1e-9, "{context}");
                } else {
                    // κ̂ ≈ 3/δ (generic) or 4/δ (generated): 3e5 and more, above both bounds.
                    assert_eq!(suspects(step), ["velocity", "acceleration"], "{context}");
                    // The estimate vouches for no more than the step has: the true errors stay
                    // within the rule's bounds.
                    assert!(velocity <= v_bound && acceleration <= a_bound, "{context}");
                    // The digits are lost indeed: the accelerations are off by more than 1e-6
                    // (3e-4 to 1e2 when this test was written).
                    assert!(acceleration > 1e-6, "{context}");
                }
            }
            assert!(
                err.contains("warning: the acceleration at 1 step (t = 1) is suspect"),
                "{context}: {err}"
            );
        }
    }
}

#[test]
fn regular_mechanisms_are_flagged_nowhere() {
    for example in ["four_bar.toml", "rssr.toml", "slider_crank_5body.toml"] {
        let file = codegen::testing::example(example);
        for engine in ["generic", "generated"] {
            let (status, json, err) = solve(&file, engine);
            assert_eq!(status, 0, "{example}, {engine}: {err}");
            for step in json["steps"].as_array().expect("steps") {
                assert!(suspects(step).is_empty(), "{example}, {engine}: {step}");
                // κ̂ stays far below the acceleration bound (1651) on these.
                assert!(number(&step["condition"]) < 1e3, "{example}, {engine}: {step}");
            }
            assert!(!err.contains("suspect"), "{example}, {engine}: {err}");
        }
    }
}

/// κ₂ = σ_max / σ_min.
fn kappa(m: &DMatrix<f64>) -> f64 {
    let s = m.clone().singular_values();
    s.max() / s.min()
}

/// The range of κ₂ / κ̂ seen: κ̂ from the generic engine's frames, κ₂ of the whole Φ_q (it
/// solves every row, redundant ones included) in the balanced units its LU sees.
fn generic_ratios(file: &Path) -> (f64, f64) {
    let mech = codegen::testing::load(file).mechanism;
    let eq = Equations::new(&mech);
    let prep = eq.prepare();
    let columns = eq.column_scales();
    let mut range = (f64::INFINITY, 0.0_f64);
    Analysis::new(&eq, &prep)
        .run(|f| {
            let jac = eq.evaluate(&f.q, &DVector::zeros(f.q.len()), f.t).jac;
            let r = kappa(&balanced(jac, &columns).0) / f.condition;
            range = (range.0.min(r), range.1.max(r));
            Ok::<(), ()>(())
        })
        .expect("the sink never fails");
    range
}

/// The range of κ₂ / κ̂ along `T_COUNT` steps of a generated module under `advance_to`: κ̂
/// from `Solver::condition`, κ₂ of the reduced Φ_q equilibrated as the runtime does (each
/// column, then each row, divided by the power of two nearest its largest entry).
fn generated_ratios<M: Mechanism<N> + Copy, const N: usize>(
    m: M,
    q0: [f64; N],
    times: impl Iterator<Item = f64>,
) -> (f64, f64) {
    let mut solver = Solver::new(m, q0);
    solver.set_predictor(true);
    let mut range = (f64::INFINITY, 0.0_f64);
    let pow2 = |x: f64| 2f64.powi(x.log2().round() as i32);
    for t in times {
        let report = solver.advance_to(t).unwrap_or_else(|e| panic!("t = {t}: {e}"));
        let mut jac = [[0.0; N]; N];
        m.jacobian(solver.q(), t, &mut jac);
        let mut a = DMatrix::from_fn(N, N, |r, c| jac[r][c]);
        for mut col in a.column_iter_mut() {
            let big = col.amax();
            col /= pow2(big);
        }
        for mut row in a.row_iter_mut() {
            let big = row.amax();
            row /= pow2(big);
        }
        let r = kappa(&a) / report.condition;
        range = (range.0.min(r), range.1.max(r));
    }
    range
}

#[test]
fn the_condition_estimate_tracks_the_singular_values() {
    // κ̂ = 1/ρ estimates κ₂ from the LU's pivots alone. It is no bound in general, but on
    // mechanism Jacobians it stays within a small factor of κ₂: when this test was written,
    // κ₂ / κ̂ lay between 2.0 and 34 for the generic engine (the Bricard linkage the most;
    // the parallelogram past its flat configuration 2.9 to 4.2, κ₂ ≈ 8.6/δ against κ̂ = 3/δ)
    // and between 0.16 and 8.5 for the generated modules, whose cheap estimate comes from
    // unbalanced static orders and may overestimate (the safe side: more flags, never fewer);
    // hence the ranges [0.25, 100] and [0.1, 100] asserted here.
    let files = [
        codegen::testing::example("four_bar.toml"),
        codegen::testing::example("rssr.toml"),
        codegen::testing::example("slider_crank_5body.toml"),
        codegen::testing::example("universal_joint.toml"),
        root().join("tests/stability/bennett.toml"),
        root().join("tests/stability/bricard.toml"),
        root().join("tests/stability/four_bar_near_toggle.toml"),
        root().join("tests/digits/parallelogram_past_flat_1e-5.toml"),
    ];
    for file in &files {
        let (lo, hi) = generic_ratios(file);
        assert!(0.25 <= lo && hi <= 100.0, "{}: κ₂/κ̂ in [{lo}, {hi}]", file.display());
    }
    // The generated modules: the cheap estimate of the static orders' pivots (κ̂ < 103 here,
    // so never replaced by the equilibrated one) against κ₂ of the equilibrated Φ_q.
    use generated::{four_bar, rssr, slider_crank_5body as slider};
    let grid =
        |start: f64, step: f64, count: usize| (0..count).map(move |k| start + k as f64 * step);
    let ranges = [
        (
            "four_bar",
            generated_ratios(
                four_bar::FourBar,
                four_bar::Q0,
                grid(four_bar::T_START, four_bar::T_STEP, four_bar::T_COUNT),
            ),
        ),
        (
            "rssr",
            generated_ratios(
                rssr::Rssr,
                rssr::Q0,
                grid(rssr::T_START, rssr::T_STEP, rssr::T_COUNT),
            ),
        ),
        (
            "slider_crank_5body",
            generated_ratios(
                slider::SliderCrank5body,
                slider::Q0,
                grid(slider::T_START, slider::T_STEP, slider::T_COUNT),
            ),
        ),
    ];
    for (name, (lo, hi)) in ranges {
        assert!(0.1 <= lo && hi <= 100.0, "{name}: κ₂/κ̂ in [{lo}, {hi}]");
    }
}
