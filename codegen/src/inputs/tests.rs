//! The inputs reader on bad files, and replays checked against closed forms.

use std::sync::Arc;

use super::{derivative, parse};
use crate::generic::{Analysis, Equations};
use crate::model::{Mechanism, TimeGrid};
use crate::report::{self, StepResult, Unwrap};
use crate::validate::{Format, load_str};

/// The shipped example: a planar crank-rocker (crank 1, coupler 3, rocker 2.5, ground 3)
/// whose crank angle is the input driver "crank".
const FOUR_BAR: &str = include_str!("../../../examples/inputs/four_bar_input.toml");
const LINKS: (f64, f64, f64, f64) = (1.0, 3.0, 2.5, 3.0);

fn mechanism(text: &str) -> Mechanism {
    match load_str(text, Format::Toml, Some("test.toml")) {
        Ok(l) => l.mechanism,
        Err(d) => panic!("the test description is valid: {d:?}"),
    }
}

/// The error message of `parse` on `text`, which must be refused.
fn refused(text: &str) -> String {
    let mech = mechanism(FOUR_BAR);
    match parse(text, "rec.csv", &mech) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(d) => {
            assert_eq!(d.file.as_deref(), Some("rec.csv"), "{d}");
            assert!(d.line.is_some() && d.column.is_some(), "{d}");
            d.to_string()
        }
    }
}

#[test]
fn every_bad_file_is_refused_with_its_line_column_and_header() {
    let cases: [(&str, &str, &[&str]); 15] = [
        (
            "overflowing estimate",
            "t,crank\n0,0\n1e-200,1e150\n",
            &["line 2", "estimated crank.dot"],
        ),
        ("missing input column", "t\n0,\n", &["line 1", "missing column \"crank\""]),
        ("missing t", "crank\n0.1\n", &["line 1", "missing column \"t\""]),
        ("unknown column", "t,crank,crank.dt\n0,1,2\n", &["column 9", "\"crank.dt\"", "unknown"]),
        ("duplicate", "t,crank,crank\n0,1,2\n", &["column 9", "duplicate column \"crank\""]),
        ("non-numeric", "t,crank\n0,1\n0.1,abc\n", &["line 3", "column 5", "(\"crank\")", "abc"]),
        ("NaN", "t,crank\n0,NaN\n", &["line 2", "(\"crank\")", "not a finite"]),
        ("inf", "t,crank\n0,1\n0.1,inf\n", &["line 3", "not a finite"]),
        ("overflow", "t,crank\n0,1e400\n", &["line 2", "not a finite"]),
        ("short row", "t,crank\n0,1\n0.1\n", &["line 3", "1 cells", "2 columns"]),
        ("long row", "t,crank\n0,1,2\n", &["line 2", "3 cells"]),
        (
            "decreasing t",
            "t,crank\n0,1\n0.2,1\n0.1,1\n",
            &["line 4", "(\"t\")", "does not increase"],
        ),
        ("repeated t", "t,crank\n0,1\n0,1\n", &["line 3", "does not increase"]),
        ("empty", "# only a comment\n\n", &["line 1", "empty"]),
        ("header only", "# c\nt,crank\n", &["line 2", "no rows"]),
    ];
    for (what, text, words) in cases {
        let message = refused(text);
        for w in words {
            assert!(message.contains(w), "{what}: {message:?} lacks {w:?}");
        }
        assert!(message.contains("rec.csv"), "{what}: {message}");
    }
}

#[test]
fn a_file_over_the_size_limit_is_refused_without_reading_it() {
    // The byte limit of `read` comes first: a row has at least 4 bytes ("t,x" and a line
    // feed), so 16 MiB hold fewer rows than the time-point limit, and a file over it is
    // refused from its size alone.
    assert!(super::MAX_BYTES / 4 < super::MAX_ROWS as u64);
    let dir = std::env::temp_dir().join(format!("mechgen-inputs-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary directory");
    let path = dir.join("big.csv");
    let file = std::fs::File::create(&path).expect("create");
    file.set_len(super::MAX_BYTES + 1).expect("sparse file");
    let mech = mechanism(FOUR_BAR);
    let e = super::read(&path, &mech).expect_err("over the limit");
    assert!(e.message.contains("more than"), "{e}");
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn finite_differences_are_second_order_on_uneven_spacing() {
    // f = t³ on uneven points: the three-point formulas are exact for quadratics, so the error
    // is the cubic term, O(h²); halving every spacing must divide it by about 4.
    let error = |h: f64| {
        let t: Vec<f64> =
            (0..12).map(|k| f64::from(k) * h * (1.0 + 0.3 * f64::from(k % 3))).collect();
        let t: Vec<f64> = t
            .iter()
            .scan(0.0, |acc, dt| {
                *acc += dt;
                Some(*acc)
            })
            .collect();
        let f: Vec<f64> = t.iter().map(|x| x * x * x).collect();
        derivative(&t, &f).iter().zip(&t).map(|(d, x)| (d - 3.0 * x * x).abs()).fold(0.0, f64::max)
    };
    let (coarse, fine) = (error(0.01), error(0.005));
    assert!(coarse > 0.0 && fine < coarse / 3.0, "errors {coarse:e} → {fine:e}");
}

/// The rocker angle θ4 and its two derivatives for crank angle θ2 and rates, on the branch of
/// the example (rocker pin above the ground line), by the loop closure of a planar four-bar.
fn rocker(theta: f64, rate: f64, acc: f64) -> [f64; 3] {
    let (a, b, c, d) = LINKS;
    let angle = |th: f64| {
        let (ax, ay) = (a * th.cos(), a * th.sin());
        let (dx, dy) = (d - ax, -ay);
        let l = dx.hypot(dy);
        let x = (b * b - c * c + l * l) / (2.0 * l);
        let h = (b * b - x * x).sqrt();
        let (ux, uy) = (dx / l, dy / l);
        let (bx, by) = (ax + x * ux - h * uy, ay + x * uy + h * ux);
        by.atan2(bx - d)
    };
    // dθ4/dθ2 and d²θ4/dθ2² by central differences: h = 1e-4 gives truncation ~1e-8 and
    // round-off ~1e-12 (first) and ~1e-8 (second) on these O(1) derivatives.
    let h = 1e-4;
    let (m, z, p) = (angle(theta - h), angle(theta), angle(theta + h));
    let (g1, g2) = ((p - m) / (2.0 * h), (p - 2.0 * z + m) / (h * h));
    [z, g1 * rate, g2 * rate * rate + g1 * acc]
}

/// Runs the generic engine over `mech`'s time points and returns every step with unwrapped
/// joint angles; the run must complete.
fn run(mech: &Mechanism) -> Vec<StepResult> {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let layout = report::layout(mech);
    let mut unwrap = Unwrap::default();
    let mut steps = Vec::new();
    let r = Analysis::new(&eq, &prep)
        .run(|f| {
            let mut s = report::step_result(mech, &layout, f);
            unwrap.apply(&mut s);
            steps.push(s);
            Ok::<(), ()>(())
        })
        .expect("the sink never fails");
    assert!(r.failure.is_none(), "{:?}", r.failure);
    assert_eq!(steps.len(), mech.time.count);
    steps
}

fn joint<'a>(s: &'a StepResult, name: &str) -> &'a report::JointResult {
    s.joints.iter().find(|j| j.name == name).expect("reported joint")
}

/// A deterministic pseudo-random number in [−1, 1) (a 64-bit LCG).
fn lcg(state: &mut u64) -> f64 {
    *state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
    ((*state >> 11) as f64 / (1_u64 << 53) as f64) * 2.0 - 1.0
}

#[test]
fn a_noisy_encoder_series_replays_onto_the_closed_form() {
    // The crank angle of a known motion plus 1e-4 rad of noise, without rate columns.
    let mut state = 99_u64;
    let mut text = String::from("# recorded\nt,crank\n");
    for k in 0..301 {
        let t = f64::from(k) * 0.005;
        let theta = 1.5 * t + 0.4 * (3.0 * t).sin() + 1e-4 * lcg(&mut state);
        text.push_str(&format!("{t:?},{theta:?}\n"));
    }
    let mut mech = mechanism(FOUR_BAR);
    let read = parse(&text, "enc.csv", &mech).expect("a valid series");
    assert_eq!(read.warnings.len(), 2, "both rates are estimated: {:?}", read.warnings);
    let replay = Arc::new(read.replay);
    mech.time = TimeGrid::replaying(Arc::clone(&replay));
    let steps = run(&mech);
    let samples = replay.series(0).expect("crank is an input");
    for (k, s) in steps.iter().enumerate() {
        assert_eq!(s.t, replay.t[k]);
        let [theta, rate, acc] = samples[k];
        // The crank's reported angle is the recorded one (Newton tolerance 1e-10 on a unit
        // crank) and its rates are the estimated ones exactly as ν and γ used them.
        let crank = joint(s, "O2").angle.expect("angle");
        assert!((crank[0] - theta).abs() < 1e-9, "t {}: {crank:?} vs {theta}", s.t);
        assert!((crank[1] - rate).abs() < 1e-8 * (1.0 + rate.abs()), "t {}", s.t);
        assert!((crank[2] - acc).abs() < 1e-7 * (1.0 + acc.abs()), "t {}", s.t);
        // The rocker at the recorded (noisy) crank angle and estimated rates: positions to the
        // Newton tolerance, rates to the closed form's difference error (~1e-8, above).
        let want = rocker(theta, rate, acc);
        let got = joint(s, "O4").angle.expect("angle");
        assert!((got[0] - want[0]).abs() < 1e-8, "t {}: θ4 {} vs {}", s.t, got[0], want[0]);
        assert!((got[1] - want[1]).abs() < 1e-6 * (1.0 + want[1].abs()), "t {}: θ̇4", s.t);
        assert!((got[2] - want[2]).abs() < 1e-5 * (1.0 + want[2].abs()), "t {}: θ̈4", s.t);
    }
}

#[test]
fn the_rocker_angle_under_a_law_matches_the_closed_form_over_a_full_turn_of_the_crank() {
    // Two crank turns at 5 rad/s with 2 rad/s²: the crank angle must come out unwrapped.
    let law = "law = { start = 0.0, velocity = 5.0, acceleration = 2.0 }";
    let text = FOUR_BAR.replace("law = \"input\"", law).replace("end = 1.0", "end = 1.9");
    let steps = run(&mechanism(&text));
    for s in &steps {
        let (theta, rate, acc) = (5.0 * s.t + s.t * s.t, 5.0 + 2.0 * s.t, 2.0);
        let crank = joint(s, "O2").angle.expect("angle");
        // Unwrapped: the angle is the law's, past π and 2π (Newton tolerance on a unit crank).
        assert!((crank[0] - theta).abs() < 1e-9, "t {}: {} vs {theta}", s.t, crank[0]);
        let want = rocker(theta, rate, acc);
        let got = joint(s, "O4").angle.expect("angle");
        // As in the replay test: Newton tolerance, then the closed form's difference error.
        assert!((got[0] - want[0]).abs() < 1e-8, "t {}: θ4 {} vs {}", s.t, got[0], want[0]);
        assert!((got[1] - want[1]).abs() < 1e-6 * (1.0 + want[1].abs()), "t {}: θ̇4", s.t);
        assert!((got[2] - want[2]).abs() < 1e-5 * (1.0 + want[2].abs()), "t {}: θ̈4", s.t);
    }
    assert!(steps.last().map(|s| joint(s, "O2").angle.expect("angle")[0]) > Some(10.0));
}

/// An in-line slider-crank (crank 0.5 about z at the origin, rod 1.5, slider on the x axis):
/// crank revolute O, spherical crank–rod, universal rod–slider, prismatic slider–ground.
const SLIDER_CRANK: &str = r#"
name = "slider_crank"
[time]
start = 0.0
end = 1.5
step = 0.01
[[bodies]]
name = "ground"
ground = true
[[bodies]]
name = "crank"
[[bodies]]
name = "rod"
[[bodies]]
name = "slider"
r = [2.0, 0.0, 0.0]
[[joints]]
name = "O"
type = "revolute"
body_i = "ground"
body_j = "crank"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, 0.0, 0.0]
axis_i = [0.0, 0.0, 1.0]
axis_j = [0.0, 0.0, 1.0]
ref_i = [1.0, 0.0, 0.0]
ref_j = [1.0, 0.0, 0.0]
[[joints]]
name = "A"
type = "spherical"
body_i = "crank"
body_j = "rod"
point_i = [0.5, 0.0, 0.0]
point_j = [0.5, 0.0, 0.0]
[[joints]]
name = "B"
type = "universal"
body_i = "rod"
body_j = "slider"
point_i = [2.0, 0.0, 0.0]
point_j = [0.0, 0.0, 0.0]
axis_i = [0.0, 1.0, 0.0]
axis_j = [0.0, 0.0, 1.0]
[[joints]]
name = "P1"
type = "prismatic"
body_i = "ground"
body_j = "slider"
point_i = [0.0, 0.0, 0.0]
point_j = [0.0, 0.0, 0.0]
axis_i = [1.0, 0.0, 0.0]
axis_j = [1.0, 0.0, 0.0]
ref_i = [0.0, 1.0, 0.0]
ref_j = [0.0, 0.0, 1.0]
[[drivers]]
name = "motor"
joint = "O"
motion = "rotation"
law = { start = 0.0, velocity = 4.0, acceleration = 1.0 }
"#;

#[test]
fn the_slider_translation_matches_the_slider_crank_closed_form() {
    let (a, b) = (0.5, 1.5);
    let x = |th: f64| a * th.cos() + (b * b - (a * th.sin()).powi(2)).sqrt();
    let steps = run(&mechanism(SLIDER_CRANK));
    for s in &steps {
        let (th, rate, acc) = (4.0 * s.t + 0.5 * s.t * s.t, 4.0 + s.t, 1.0);
        // dx/dθ and d²x/dθ² by central differences (h = 1e-4: errors ~1e-8, as above).
        let h = 1e-4;
        let (m, z, p) = (x(th - h), x(th), x(th + h));
        let (g1, g2) = ((p - m) / (2.0 * h), (p - 2.0 * z + m) / (h * h));
        let want = [z, g1 * rate, g2 * rate * rate + g1 * acc];
        let got = joint(s, "P1").translation.expect("translation");
        assert!(joint(s, "P1").angle.is_none(), "a prismatic joint has no angle");
        assert!((got[0] - want[0]).abs() < 1e-9, "t {}: d {} vs {}", s.t, got[0], want[0]);
        assert!((got[1] - want[1]).abs() < 1e-6 * (1.0 + want[1].abs()), "t {}: ḋ", s.t);
        assert!((got[2] - want[2]).abs() < 1e-5 * (1.0 + want[2].abs()), "t {}: d̈", s.t);
    }
}
