//! The committed generated solvers against the generic engine, and against the generator
//! itself (freshness).

use codegen::testing::{load_example, run_generic};
use nalgebra::DVector;
use runtime::{Mechanism, NewtonOptions, Solver};

/// One analysed time point of a generated solver, expanded to the generic layout.
struct Step {
    t: f64,
    q: DVector<f64>,
    qd: DVector<f64>,
    qdd: DVector<f64>,
}

/// A generated module's `expand`: full body coordinates, rates and accelerations.
type Expand<const N: usize, const B: usize> =
    fn(&[f64; N], &[f64; N], &[f64; N], f64, &mut [[[f64; 7]; 3]; B]);

/// Runs a generated module over its own time grid with the description's Newton settings.
fn run<M: Mechanism<N>, const N: usize, const B: usize>(
    mechanism: M,
    q0: [f64; N],
    grid: (f64, f64, usize),
    options: (f64, u32),
    expand: Expand<N, B>,
) -> Vec<Step> {
    let mut solver = Solver::with_storage(mechanism, q0, Box::new([[0.0; N]; N]));
    solver.set_options(NewtonOptions {
        tolerance: options.0,
        max_iterations: options.1,
        ..NewtonOptions::DEFAULT
    });
    solver.set_predictor(true);
    let mut steps = Vec::new();
    let mut out = [[[0.0; 7]; 3]; B];
    for k in 0..grid.2 {
        let t = grid.0 + k as f64 * grid.1;
        solver.position(t).unwrap_or_else(|e| panic!("t = {t}: {e}"));
        solver.velocity().unwrap();
        solver.acceleration().unwrap();
        expand(solver.q(), solver.qd(), solver.qdd(), t, &mut out);
        let flat = |d: usize| DVector::from_iterator(7 * B, out.iter().flat_map(|b| b[d]));
        steps.push(Step { t, q: flat(0), qd: flat(1), qdd: flat(2) });
    }
    steps
}

macro_rules! generated {
    ($module:ident, $ty:ident) => {{
        use generated::$module as g;
        (
            stringify!($module),
            run(
                g::$ty,
                g::Q0,
                (g::T_START, g::T_STEP, g::T_COUNT),
                (g::TOLERANCE, g::MAX_ITERATIONS),
                g::expand,
            ),
        )
    }};
}

/// Every shipped example's generated solver and its results.
fn all_generated() -> Vec<(&'static str, Vec<Step>)> {
    vec![
        generated!(cylindrical_joint, CylindricalJoint),
        generated!(four_bar, FourBar),
        generated!(prismatic_joint, PrismaticJoint),
        generated!(revolute_joint, RevoluteJoint),
        generated!(rotation_about_x, RotationAboutX),
        generated!(rotation_about_y, RotationAboutY),
        generated!(rotation_about_y_short, RotationAboutYShort),
        generated!(rssr, Rssr),
        generated!(screw_joint, ScrewJoint),
        generated!(slider_crank_5body, SliderCrank5body),
        generated!(spherical_joint, SphericalJoint),
        generated!(static_body, StaticBody),
        generated!(static_body_offset, StaticBodyOffset),
        generated!(translation_x, TranslationX),
        generated!(translation_xy, TranslationXy),
        generated!(translation_xyz, TranslationXyz),
        generated!(translation_y, TranslationY),
        generated!(universal_joint, UniversalJoint),
    ]
}

#[test]
fn generated_and_generic_agree_on_every_shipped_example() {
    let runs = all_generated();
    assert_eq!(runs.len(), 18);
    for (name, steps) in runs {
        let mech = load_example(&format!("{name}.toml"));
        let run = run_generic(&mech);
        assert!(run.failure.is_none(), "{name}");
        let frames = run.frames;
        assert_eq!(frames.len(), steps.len(), "{name}: same grid");
        // Scale of each quantity over the run, for the relative comparison.
        let scale = |f: fn(&codegen::generic::Frame) -> &DVector<f64>| {
            frames.iter().map(|fr| f(fr).amax()).fold(1e-300, f64::max)
        };
        let scales = [scale(|f| &f.q), scale(|f| &f.qd), scale(|f| &f.qdd)];
        for (s, f) in steps.iter().zip(&frames) {
            assert_eq!(s.t, f.t, "{name}: same time points");
            for (k, (label, ours, theirs)) in
                [("q", &s.q, &f.q), ("qd", &s.qd, &f.qd), ("qdd", &s.qdd, &f.qdd)]
                    .into_iter()
                    .enumerate()
            {
                // Euler parameters may converge to either sign only if the engines started
                // apart; both start from the same estimates, so no sign freedom is allowed.
                let diff = (ours - theirs).amax();
                // Both engines stop Newton at max |Φ| ≤ 1e-10 (the descriptions' tolerance),
                // from different iterates; 1e-10 of each quantity's scale over the run is
                // the bound, and the two derivations (symbolic vs hand-written
                // product rules) meet it.
                assert!(
                    diff <= 1e-10 * scales[k].max(1.0),
                    "{name}: t = {}: {label} differs by {diff:e} (scale {:e})",
                    s.t,
                    scales[k]
                );
            }
        }
    }
}

#[test]
fn generated_code_is_fresh() {
    let mode = if std::env::var_os("UPDATE_EXPECT").is_some() {
        codegen::sync::Mode::Write
    } else {
        codegen::sync::Mode::Check
    };
    let stale =
        codegen::sync::sync(&codegen::sync::workspace_root(), mode).expect("descriptions generate");
    assert!(
        mode == codegen::sync::Mode::Write || stale.is_empty(),
        "generated/ is out of date: {stale:#?}\nrun `cargo codegen` and commit generated/"
    );
}

#[test]
fn generated_code_names_no_machine_path_or_time() {
    // Generated modules must be byte-identical on every machine: no absolute path, no user,
    // no date. The workspace's own absolute path is the likeliest leak.
    let root = codegen::sync::workspace_root();
    let root_text = root.display().to_string();
    let dir = root.join("generated/src");
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        let text = std::fs::read_to_string(&path).unwrap();
        let name = path.display();
        assert!(!text.contains(&root_text), "{name} holds the workspace path {root_text}");
        for leak in ["/home/", "/tmp/", "/root/", "/Users/", "C:\\"] {
            assert!(!text.contains(leak), "{name} holds {leak}");
        }
        // A date like 2026-11-21 in any line (timestamps).
        let dated = text.lines().find(|l| {
            l.as_bytes().windows(10).any(|w| {
                w.iter().enumerate().all(|(k, b)| match k {
                    4 | 7 => *b == b'-',
                    _ => b.is_ascii_digit(),
                })
            })
        });
        assert!(dated.is_none(), "{name} holds a date: {dated:?}");
    }
}
