//! What the reference tests share: reading the thesis' reference data, solving a description
//! with the generic engine, and comparing numbers while collecting every failure with its
//! place, so that one run shows all the disagreements of an example, not just the first.

use std::collections::BTreeMap;
use std::convert::Infallible;
use std::fmt::Write as _;

use codegen::desc::MechanismDesc;
use codegen::generic::{Analysis, Equations, Failure, Frame};
use codegen::model;
use codegen::report::{self, BodyResult, StepResult};
use serde_json::Value;

/// The thesis' decks and their reference outputs (`tests/reference/seed-examples`, see its README).
pub(crate) const SEED_EXAMPLES: &str =
    concat!(env!("CARGO_MANIFEST_DIR"), "/reference/seed-examples");

/// Two times are the same grid point when they differ by less than this (s). The grids are
/// `start + k·step` in binary; the references print the same decimal times, which differ from
/// ours by round-off (≈1e-16 s), while the finest step of any reference is 3.6e-3 s.
const SAME_TIME: f64 = 1e-9;

/// Reads `file` of the seed examples as JSON.
pub(crate) fn read_json(file: &str) -> Value {
    let path = format!("{SEED_EXAMPLES}/{file}");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("{path} is not JSON: {e}"))
}

/// Imports the deck `{example}.deck` as the command line would.
pub(crate) fn import_deck(example: &str) -> MechanismDesc {
    let path = format!("{SEED_EXAMPLES}/{example}.deck");
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    let name = codegen::young::name_from_path(std::path::Path::new(&path));
    codegen::young::import(&text, &name)
        .unwrap_or_else(|d| panic!("{example}: the deck does not import: {d}"))
}

/// One analysis over a description's whole time grid.
pub(crate) struct Run {
    /// Which example, for messages.
    pub(crate) example: String,
    /// The validated model.
    pub(crate) mechanism: model::Mechanism,
    /// The raw frames, one per time point analysed.
    pub(crate) frames: Vec<Frame>,
    /// The same frames in the contract's terms.
    pub(crate) steps: Vec<StepResult>,
    /// Why the analysis stopped early, if it did.
    pub(crate) failure: Option<Failure>,
}

/// Validates `desc` and runs the generic engine over its grid.
pub(crate) fn solve(example: &str, desc: &MechanismDesc) -> Run {
    let loaded = codegen::validate::validate(desc).unwrap_or_else(|diags| {
        let text: Vec<String> = diags.iter().map(ToString::to_string).collect();
        panic!("{example}: the description does not validate:\n{}", text.join("\n"))
    });
    let mechanism = loaded.mechanism;
    let eq = Equations::new(&mechanism);
    let prep = eq.prepare();
    let analysis = Analysis::new(&eq, &prep);
    let layout = report::layout(&mechanism);
    let mut frames = Vec::new();
    let mut steps = Vec::new();
    let outcome = analysis.run(|frame| -> Result<(), Infallible> {
        steps.push(report::step_result(&mechanism, &layout, frame));
        frames.push(frame.clone());
        Ok(())
    });
    let Ok(report) = outcome;
    Run { example: example.to_owned(), mechanism, frames, steps, failure: report.failure }
}

/// Validates `desc` and runs its generated solver over its grid (generated and built, or taken
/// from mechgen's cache).
pub(crate) fn solve_generated(example: &str, desc: &MechanismDesc) -> Run {
    let loaded = codegen::validate::validate(desc).unwrap_or_else(|diags| {
        let text: Vec<String> = diags.iter().map(ToString::to_string).collect();
        panic!("{example}: the description does not validate:\n{}", text.join("\n"))
    });
    let mechanism = loaded.mechanism;
    let built = codegen::testing::build_generated(&mechanism);
    let run = codegen::testing::run_generated(&mechanism, &built);
    let layout = report::layout(&mechanism);
    let steps = run.frames.iter().map(|f| report::step_result(&mechanism, &layout, f)).collect();
    Run { example: example.to_owned(), mechanism, frames: run.frames, steps, failure: run.failure }
}

impl Run {
    /// Requires an analysis without failure that reached every time in `times`.
    pub(crate) fn assert_covers(&self, times: impl IntoIterator<Item = f64>) {
        if let Some(f) = &self.failure {
            panic!("{}: the analysis failed: {}", self.example, report::failure_text(f));
        }
        for t in times {
            assert!(
                self.step_at(t).is_some(),
                "{}: no analysed time point at t = {t} (grid {:?})",
                self.example,
                self.mechanism.time
            );
        }
    }

    /// The step at time `t`, if the grid has it.
    pub(crate) fn step_at(&self, t: f64) -> Option<&StepResult> {
        self.steps.iter().find(|s| (s.t - t).abs() <= SAME_TIME)
    }

    /// `desc` (the description this run solved) with the initial estimates of every moving
    /// body set to the configuration of `frame`.
    pub(crate) fn estimates_from(&self, desc: &MechanismDesc, frame: &Frame) -> MechanismDesc {
        let mut desc = desc.clone();
        let layout = report::layout(&self.mechanism);
        for (body, offset) in desc.bodies.iter_mut().zip(layout) {
            let Some(o) = offset else { continue };
            let q = &frame.q;
            body.r = Some([q[o], q[o + 1], q[o + 2]]);
            body.p = Some([q[o + 3], q[o + 4], q[o + 5], q[o + 6]]);
        }
        desc
    }

    /// The results of deck body `k` (1-based) at `step`: the moving body's results, or, for
    /// a ground body, its fixed placement with zero rates.
    pub(crate) fn deck_body(&self, step: &StepResult, k: usize) -> BodyResult {
        let body = &self.mechanism.bodies[k - 1];
        if body.ground {
            let zero3 = [0.0; 3];
            let zero4 = [0.0; 4];
            return BodyResult {
                name: body.name.clone(),
                r: [body.r.x, body.r.y, body.r.z],
                p: [body.p[0], body.p[1], body.p[2], body.p[3]],
                r_dot: zero3,
                p_dot: zero4,
                omega: zero3,
                r_ddot: zero3,
                p_ddot: zero4,
                alpha: zero3,
            };
        }
        step.bodies
            .iter()
            .find(|b| b.name == body.name)
            .unwrap_or_else(|| panic!("{}: body {} has no results", self.example, body.name))
            .clone()
    }
}

/// A reference value's quantity, in the references' names (`q`, `qd`, `omega`, `qdd`,
/// `omegad` of bodies; `r`, `rd`, `rdd` of points).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Quantity {
    /// x y z e0 e1 e2 e3.
    Q,
    /// Their first derivatives.
    Qd,
    /// Global angular velocity.
    Omega,
    /// Second derivatives of x y z e0 e1 e2 e3.
    Qdd,
    /// Global angular acceleration.
    Omegad,
    /// Point position.
    R,
    /// Point velocity.
    Rd,
    /// Point acceleration.
    Rdd,
}

impl Quantity {
    /// Body quantities in reference order.
    pub(crate) const BODY: [Self; 5] = [Self::Q, Self::Qd, Self::Omega, Self::Qdd, Self::Omegad];
    /// Point quantities in reference order.
    pub(crate) const POINT: [Self; 3] = [Self::R, Self::Rd, Self::Rdd];

    /// The key in the reference JSON.
    pub(crate) fn key(self) -> &'static str {
        match self {
            Self::Q => "q",
            Self::Qd => "qd",
            Self::Omega => "omega",
            Self::Qdd => "qdd",
            Self::Omegad => "omegad",
            Self::R => "r",
            Self::Rd => "rd",
            Self::Rdd => "rdd",
        }
    }

    /// The derivative order: 0 for positions, 1 for velocities, 2 for accelerations.
    pub(crate) fn order(self) -> usize {
        match self {
            Self::Q | Self::R => 0,
            Self::Qd | Self::Omega | Self::Rd => 1,
            Self::Qdd | Self::Omegad | Self::Rdd => 2,
        }
    }

    /// Whether components 3..7 are Euler parameters (or their derivatives), which are
    /// defined only up to one sign per body and step.
    pub(crate) fn has_euler_parameters(self) -> bool {
        matches!(self, Self::Q | Self::Qd | Self::Qdd)
    }

    /// Our values of this body quantity, in reference order.
    pub(crate) fn of_body(self, b: &BodyResult) -> Vec<f64> {
        let cat = |a: &[f64], b: &[f64]| a.iter().chain(b).copied().collect();
        match self {
            Self::Q => cat(&b.r, &b.p),
            Self::Qd => cat(&b.r_dot, &b.p_dot),
            Self::Omega => b.omega.to_vec(),
            Self::Qdd => cat(&b.r_ddot, &b.p_ddot),
            Self::Omegad => b.alpha.to_vec(),
            Self::R | Self::Rd | Self::Rdd => unreachable!("{self:?} is a point quantity"),
        }
    }
}

/// Where a compared value sits.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Place {
    /// Time.
    pub(crate) t: f64,
    /// `true` for a point of interest, `false` for a body.
    pub(crate) point: bool,
    /// 1-based deck body or point number.
    pub(crate) number: usize,
    /// The quantity.
    pub(crate) quantity: Quantity,
    /// 0-based component.
    pub(crate) component: usize,
}

impl Place {
    fn item(&self) -> String {
        format!("{} {}", if self.point { "point" } else { "body" }, self.number)
    }
}

/// The largest deviation seen for one quantity.
#[derive(Clone, Debug)]
struct Worst {
    diff: f64,
    ratio: f64,
    at: String,
}

/// Compares values against one reference, collecting every failure and the largest
/// deviation of each quantity.
pub(crate) struct Comparison {
    title: String,
    compared: usize,
    failures: Vec<String>,
    worst: BTreeMap<(Quantity, bool), Worst>,
}

impl Comparison {
    /// A comparison of `example` against `reference` (for messages).
    pub(crate) fn new(example: &str, reference: &str) -> Self {
        Self {
            title: format!("{example} against {reference}"),
            compared: 0,
            failures: Vec::new(),
            worst: BTreeMap::new(),
        }
    }

    /// Requires |ours − expected| ≤ tolerance.
    pub(crate) fn value(&mut self, place: Place, ours: f64, expected: f64, tolerance: f64) {
        self.compared += 1;
        let diff = (ours - expected).abs();
        let ratio = diff / tolerance;
        let at = format!(
            "t = {}, {}, {}[{}]",
            place.t,
            place.item(),
            place.quantity.key(),
            place.component
        );
        let worst = self.worst.entry((place.quantity, place.point)).or_insert_with(|| Worst {
            diff: 0.0,
            ratio: f64::NEG_INFINITY,
            at: String::new(),
        });
        // A NaN on either side is a failure.
        if diff.is_nan() || diff > tolerance {
            self.failures.push(format!(
                "{at}: ours {ours:.10}, expected {expected}, |diff| {diff:.3e} > tolerance \
                 {tolerance:.3e}"
            ));
        }
        if ratio.is_nan() || ratio > worst.ratio {
            *worst = Worst { diff, ratio, at };
        }
    }

    /// Compares our `values` with the reference `expected` (a JSON array, nulls skipped),
    /// component by component; `tolerance` gives the tolerance at a place for an expected
    /// value, or `None` to skip it. With `sign` = −1 our Euler-parameter components are
    /// negated first.
    pub(crate) fn values(
        &mut self,
        place: Place,
        ours: &[f64],
        expected: &Value,
        sign: f64,
        tolerance: impl Fn(&Place, f64) -> Option<f64>,
    ) {
        let Some(expected) = expected.as_array() else { return };
        assert_eq!(ours.len(), expected.len(), "{}: {place:?} has the wrong length", self.title);
        for (c, (o, e)) in ours.iter().zip(expected).enumerate() {
            let place = Place { component: c, ..place };
            let Some(e) = e.as_f64() else { continue };
            let Some(tol) = tolerance(&place, e) else { continue };
            let euler = place.quantity.has_euler_parameters() && c >= 3;
            let o = if euler { sign * o } else { *o };
            self.value(place, o, e, tol);
        }
    }

    /// Prints the largest deviations (seen with `--nocapture`) and fails with every failure.
    pub(crate) fn finish(self) {
        let mut text = format!("{}: {} values compared\n", self.title, self.compared);
        for ((q, _), w) in &self.worst {
            let _ = writeln!(
                text,
                "  {:<6} max |diff| {:.3e} ({:.2e} of its tolerance) at {}",
                q.key(),
                w.diff,
                w.ratio,
                w.at
            );
        }
        println!("{text}");
        assert!(self.compared > 0, "{}: nothing was compared", self.title);
        assert!(
            self.failures.is_empty(),
            "{}: {} of {} values outside tolerance:\n{}",
            self.title,
            self.failures.len(),
            self.compared,
            self.failures.join("\n")
        );
    }
}

/// The sign that best aligns our Euler parameters with a reference's: YOUNG (and the
/// independent solution, which follows YOUNG's printed sign) may describe an orientation by
/// −p, so e, ė and ë are compared up to one sign per body and step. The sign is taken from
/// the positions when the reference prints them, else from whichever derivative it prints.
pub(crate) fn euler_sign(ours: &BodyResult, reference: &Value) -> f64 {
    let pairs = [(&ours.p, "q"), (&ours.p_dot, "qd"), (&ours.p_ddot, "qdd")];
    for (mine, key) in pairs {
        let Some(theirs) = reference[key].as_array() else { continue };
        let theirs: Option<Vec<f64>> = theirs[3..7].iter().map(Value::as_f64).collect();
        let Some(theirs) = theirs else { continue };
        let dot: f64 = mine.iter().zip(&theirs).map(|(a, b)| a * b).sum();
        if dot != 0.0 {
            return dot.signum();
        }
    }
    1.0
}

/// A reference number as f64 (the references write every number as a JSON number).
pub(crate) fn num(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("expected a number, found {v}"))
}

/// Runs `mechgen` in process with `args`: (exit status, standard output, standard error).
pub(crate) fn mechgen(args: &[&str]) -> (i32, String, String) {
    let mut argv: Vec<std::ffi::OsString> = vec!["mechgen".into()];
    argv.extend(args.iter().map(std::ffi::OsString::from));
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let status = codegen::cli::run(argv, &mut out, &mut err);
    (status, String::from_utf8_lossy(&out).into_owned(), String::from_utf8_lossy(&err).into_owned())
}
