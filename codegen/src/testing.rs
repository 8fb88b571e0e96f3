//! What the tests share, in one place: the shipped examples and other description files,
//! loaded and validated; the generic engine run to the end; the generated engine built and
//! run; and the comparison of two runs. Compiled for codegen's own unit tests and, with the
//! feature `test-support`, for the workspace's `tests` crate; never part of a user's build.
//!
//! Every helper panics with the description's name and the reason, since a test that cannot
//! load or build its input has failed.

use std::path::{Path, PathBuf};

use nalgebra::DVector;

use crate::engine::{self, Built};
use crate::generic::{Analysis, Equations, Failure, Frame};
use crate::model::Mechanism;
use crate::validate::{Format, Loaded, load_file, load_str};

/// The path of a shipped example, `examples/{file}` in the workspace.
#[must_use]
pub fn example(file: &str) -> PathBuf {
    crate::sync::workspace_root().join("examples").join(file)
}

/// Every shipped example description (`examples/*.toml`), sorted by path.
#[must_use]
pub fn examples() -> Vec<PathBuf> {
    let dir = crate::sync::workspace_root().join("examples");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml") && !p.ends_with("Cargo.toml"))
        .collect();
    files.sort();
    files
}

/// The path of a shipped example as a command-line argument.
#[must_use]
pub fn example_arg(file: &str) -> String {
    example(file).to_str().expect("the workspace path is UTF-8").to_owned()
}

/// The description file at `path`, loaded and validated.
#[must_use]
pub fn load(path: &Path) -> Loaded {
    load_file(path).unwrap_or_else(|diags| panic!("{}: {diags:?}", path.display()))
}

/// The validated mechanism of the shipped example `examples/{file}`.
#[must_use]
pub fn load_example(file: &str) -> Mechanism {
    load(&example(file)).mechanism
}

/// The validated mechanism of a TOML description's text.
#[must_use]
pub fn load_toml(text: &str) -> Mechanism {
    load_str(text, Format::Toml, None).unwrap_or_else(|diags| panic!("{diags:?}")).mechanism
}

/// A whole run of one engine: its frames, and why it stopped early if it did.
#[derive(Clone, Debug, Default)]
pub struct Run {
    /// One frame per time point solved.
    pub frames: Vec<Frame>,
    /// The failure that ended the run early.
    pub failure: Option<Failure>,
}

/// The generic engine's run of `mech` over its whole grid.
#[must_use]
pub fn run_generic(mech: &Mechanism) -> Run {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let mut run = Run::default();
    let report = Analysis::new(&eq, &prep)
        .run(|f| {
            run.frames.push(f.clone());
            Ok::<(), ()>(())
        })
        .expect("the sink does not fail");
    run.failure = report.failure;
    run
}

/// The generated solver of `mech`, generated and built (or taken from the cache).
#[must_use]
pub fn build_generated(mech: &Mechanism) -> Built {
    engine::build(mech)
        .unwrap_or_else(|e| panic!("{}: the generated solver does not build: {e}", mech.name))
}

/// The generated engine's run of `mech` over its whole grid with the solver `built`.
#[must_use]
pub fn run_generated(mech: &Mechanism, built: &Built) -> Run {
    run_generated_with(mech, built, None, engine::Settings::default())
}

/// [`run_generated`] with a Newton tolerance (`None`: the description's) and the solver's
/// [`engine::Settings`] (predictor, dense LU).
///
/// # Panics
///
/// When the solver cannot be run.
#[must_use]
pub fn run_generated_with(
    mech: &Mechanism,
    built: &Built,
    tolerance: Option<f64>,
    settings: engine::Settings,
) -> Run {
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let analysis = Analysis::new(&eq, &prep);
    let mut run = Run::default();
    let report = engine::run_with(built, &analysis, tolerance, settings, |f| {
        run.frames.push(f.clone());
        Ok(())
    })
    .unwrap_or_else(|e| panic!("{}: {e}", mech.name));
    run.failure = report.failure;
    run
}

/// A quantity of a frame: q, q̇ or q̈.
type Quantity = fn(&Frame) -> &DVector<f64>;

/// The largest differences of q, q̇ and q̈ between two runs of the same grid, each relative
/// to that quantity's scale over the reference run (max |·|, at least 1), with where the
/// largest occurred. Panics when the runs' time points differ.
#[must_use]
pub fn relative_differences(reference: &[Frame], other: &[Frame]) -> [(f64, String); 3] {
    let quantities: [(&str, Quantity); 3] =
        [("q", |f| &f.q), ("qd", |f| &f.qd), ("qdd", |f| &f.qdd)];
    quantities.map(|(label, get)| {
        let scale = reference.iter().map(|f| get(f).amax()).fold(1.0, f64::max);
        let mut worst = (0.0, String::new());
        for (a, b) in reference.iter().zip(other) {
            assert_eq!(a.t, b.t, "same time points");
            let diff = get(a) - get(b);
            let k = diff.iamax();
            let rel = diff[k].abs() / scale;
            if rel > worst.0 || worst.1.is_empty() {
                worst = (
                    rel,
                    format!(
                        "{label}[{k}] at t = {}: {:e} against {:e} (scale {scale:e})",
                        a.t,
                        get(a)[k],
                        get(b)[k]
                    ),
                );
            }
        }
        worst
    })
}
