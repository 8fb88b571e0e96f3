//! Property tests over random mechanisms (see [`generate`]): the generic engine against the
//! interpreted symbolic system and against the compiled generated solver, rates against
//! finite differences of positions, the committed generated Jacobians and γ against finite
//! differences, and deterministic output.
//!
//! Randomness is seeded: every case is `generate::mechanism(seed, grid)`, and a failure
//! prints the seed and the description.

mod generate;

use std::collections::{BTreeMap, BTreeSet};

use codegen::generic::{Analysis, Equations, Frame};
use codegen::model::Mechanism;
use codegen::stepping::{self, Point, Rejection, Trouble};
use codegen::symbolic::Symbolic;
use codegen::testing::{build_generated, relative_differences, run_generated};
use codegen::validate::{Format, load_str};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::{RngExt, SeedableRng};
use runtime::dynamic::{DynMechanism, Fixed};

use generate::{Case, Grid};

/// The bound on the disagreement of two engines, relative to each quantity's scale over the
/// run. The generated descriptions ask Newton for max |Φ| ≤ 1e-12 (see
/// [`generate::TOLERANCE`]), so where each engine stops accounts for at most 1e-12 times the
/// conditioning; the rest is round-off in two independent derivations of the same equations
/// (product rules by hand against symbolic differentiation). 1e-10 leaves a factor of 100.
const AGREEMENT: f64 = 1e-10;

/// How far the Euler parameters may be from unit norm: both engines renormalise p at
/// convergence, which leaves | |p| − 1 | at a few ulps.
const UNIT_NORM: f64 = 1e-14;

/// One of a frame's q, q̇, q̈.
type Quantity = fn(&Frame) -> &DVector<f64>;

/// Why a generated case is not used.
#[derive(Clone, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Reject {
    /// Φ_q has lower column rank than the unknowns at the initial configuration.
    RankDeficient,
    /// The generator refuses the description.
    NotGenerated,
    /// The generic analysis stopped (a random loop reached a singular position, …).
    AnalysisFailed(&'static str),
}

/// A usable case: its mechanism, reduced system and generic run.
struct Usable {
    mech: Mechanism,
    sys: Symbolic,
    frames: Vec<Frame>,
}

/// Loads a generated description; an invalid one is a generator bug.
fn load(case: &Case) -> Mechanism {
    match load_str(&case.toml, Format::Toml, None) {
        Ok(loaded) => loaded.mechanism,
        Err(diags) => panic!(
            "seed {}: the generated description is invalid: {diags:#?}\n{}",
            case.seed, case.toml
        ),
    }
}

/// Filters a case (full rank at the initial configuration, a reduced system, a complete
/// generic analysis with the description's tolerance or `tolerance`) and runs it.
fn usable(case: &Case, tolerance: Option<f64>) -> Result<Usable, Reject> {
    let mech = load(case);
    let eq = Equations::new(&mech);
    let prep = eq.prepare();
    if prep.rank < eq.unknowns() {
        return Err(Reject::RankDeficient);
    }
    let sys = Symbolic::build(&mech).map_err(|_| Reject::NotGenerated)?;
    let mut analysis = Analysis::new(&eq, &prep);
    if let Some(t) = tolerance {
        analysis = analysis.with_tolerance(t);
    }
    let mut frames = Vec::new();
    let report = analysis
        .run(|f| {
            frames.push(f.clone());
            Ok::<(), ()>(())
        })
        .expect("the sink does not fail");
    if let Some(failure) = report.failure {
        return Err(Reject::AnalysisFailed(failure.kind.as_str()));
    }
    assert_eq!(frames.len(), mech.time.count, "seed {}: a frame per time point", case.seed);
    Ok(Usable { mech, sys, frames })
}

/// Tally of usable and rejected cases.
#[derive(Default)]
struct Tally {
    generated: usize,
    rejects: BTreeMap<Reject, usize>,
    features: BTreeSet<&'static str>,
}

impl Tally {
    /// Generates case `seed`, keeps it if usable.
    fn next(&mut self, seed: u64, grid: Grid, tolerance: Option<f64>) -> Option<(Case, Usable)> {
        let case = generate::mechanism(seed, grid);
        self.generated += 1;
        match usable(&case, tolerance) {
            Ok(u) => {
                self.features.extend(case.features.iter().copied());
                Some((case, u))
            }
            Err(r) => {
                *self.rejects.entry(r).or_default() += 1;
                None
            }
        }
    }

    fn used(&self) -> usize {
        self.generated - self.rejects.values().sum::<usize>()
    }

    /// At least `fraction` of the generated cases must be usable, so that the test cannot
    /// silently test nothing.
    fn assert_mostly_usable(&self, fraction: f64) {
        let used = self.used();
        assert!(
            used as f64 >= fraction * self.generated as f64,
            "only {used} of {} generated cases are usable; rejected: {:?}",
            self.generated,
            self.rejects
        );
    }
}

/// Reduced Φ_q as a dense matrix.
fn reduced_jacobian(sys: &Symbolic, q: &[f64], t: f64) -> DMatrix<f64> {
    let n = sys.unknowns.len();
    let roots: Vec<_> = sys.jac.iter().flatten().map(|&(_, e)| e).collect();
    let vals = sys.pool.eval(&roots, q, &[], t);
    let mut m = DMatrix::zeros(n, n);
    let mut it = vals.into_iter();
    for (r, row) in sys.jac.iter().enumerate() {
        for &(c, _) in row {
            m[(r, c)] = it.next().expect("one value per entry");
        }
    }
    m
}

fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0_f64, |m, x| m.max(x.abs()))
}

/// (t, q, q̇, q̈) in reduced unknowns.
type Reduced = (f64, Vec<f64>, DVector<f64>, DVector<f64>);

/// The reduced symbolic system interpreted, as the generated solver runs it: from the initial
/// estimates, a Taylor predictor from the last accepted point, Newton to the description's
/// tolerance with the closed-form normalisation at convergence, then q̇ and q̈ with the
/// factorisation at the converged configuration; under the same step control as both
/// engines ([`stepping`]).
struct Interpreted<'a> {
    mech: &'a Mechanism,
    sys: &'a Symbolic,
    eq: Equations<'a>,
    /// The last accepted (t, q, q̇, q̈) in reduced unknowns, `None` before the first.
    accepted: Option<Reduced>,
    /// The last successful attempt, in reduced unknowns.
    attempted: Option<Reduced>,
}

impl stepping::Engine for Interpreted<'_> {
    fn attempt(&mut self, t: f64) -> Result<Point, Rejection> {
        let (sys, n) = (self.sys, self.sys.unknowns.len());
        let reject =
            |trouble, message: String| Rejection { trouble, message, point: None, body: None };
        let mut q = match &self.accepted {
            None => sys.reduce(&self.eq, &self.eq.initial_estimate()).as_slice().to_vec(),
            Some((t_prev, q, qd, qdd)) => {
                let h = t - t_prev;
                (0..n).map(|k| q[k] + h * qd[k] + 0.5 * h * h * qdd[k]).collect()
            }
        };
        let mut iterations = 0;
        let mut normalised = false;
        loop {
            let phi = sys.pool.eval(&sys.phi, &q, &[], t);
            let res = max_abs(&phi);
            if !res.is_finite() {
                return Err(reject(
                    Trouble::NoConvergence,
                    format!("t = {t}: non-finite residual"),
                ));
            }
            if res <= self.mech.solver.tolerance {
                if normalised {
                    break;
                }
                let before = q.clone();
                sys.normalise(&mut q);
                normalised = true;
                if q != before {
                    continue;
                }
                break;
            }
            if iterations >= self.mech.solver.max_iterations {
                return Err(reject(
                    Trouble::NoConvergence,
                    format!("t = {t}: no convergence (max |Φ| = {res:e})"),
                ));
            }
            let dq = reduced_jacobian(sys, &q, t)
                .lu()
                .solve(&DVector::from_vec(phi))
                .ok_or_else(|| reject(Trouble::Singular, format!("t = {t}: singular Jacobian")))?;
            for k in 0..n {
                q[k] -= dq[k];
            }
            normalised = false;
            iterations += 1;
        }
        // A system whose every block was substituted (`symbolic::substitute`) has no unknowns:
        // its bodies' coordinates and rates are all explicit.
        let (qd, qdd, pivot_ratio) = if n == 0 {
            (DVector::zeros(0), DVector::zeros(0), 1.0)
        } else {
            let lu = reduced_jacobian(sys, &q, t).lu();
            let singular = || reject(Trouble::Singular, format!("t = {t}: singular Jacobian"));
            let nu = DVector::from_vec(sys.pool.eval(&sys.nu, &q, &[], t));
            let qd = lu.solve(&nu).ok_or_else(singular)?;
            let gamma = DVector::from_vec(sys.pool.eval(&sys.gamma, &q, qd.as_slice(), t));
            let qdd = lu.solve(&gamma).ok_or_else(singular)?;
            let diag = lu.u().diagonal().abs();
            (qd, qdd, diag.min() / diag.max())
        };
        let [fq, fqd, fqdd] = sys.expand(&self.eq, &q, qd.as_slice(), qdd.as_slice(), t);
        let residual = self.eq.evaluate(&fq, &fqd, t).phi.amax();
        self.attempted = Some((t, q, qd, qdd));
        Ok(Point {
            t,
            q: fq.as_slice().to_vec(),
            qd: fqd.as_slice().to_vec(),
            qdd: fqdd.as_slice().to_vec(),
            iterations,
            residual,
            pivot_ratio,
        })
    }

    fn accept(&mut self, p: &Point) {
        if let Some(a) = self.attempted.take()
            && a.0 == p.t
        {
            self.accepted = Some(a);
        }
    }
}

/// Runs the reduced symbolic system interpreted (see [`Interpreted`]). Frames come in the
/// generic layout; their residual is that of the full generic system at the expanded
/// coordinates.
fn interpreted(mech: &Mechanism, sys: &Symbolic) -> Result<Vec<Frame>, String> {
    let mut engine =
        Interpreted { mech, sys, eq: Equations::new(mech), accepted: None, attempted: None };
    let mut frames = Vec::new();
    let mut last: Option<Point> = None;
    for index in 0..mech.time.count {
        let t = mech.time.at(index);
        let outcome = match &last {
            None => stepping::first(&mut engine, t).map(|p| {
                let n = p.iterations;
                (p, n)
            }),
            Some(a) => stepping::advance(&mut engine, a, t),
        };
        let (p, iterations) = outcome.map_err(|s| format!("t = {t}: {}", s.message))?;
        frames.push(Frame {
            index,
            t,
            iterations,
            residual: p.residual,
            condition: 1.0 / p.pivot_ratio,
            q: DVector::from_column_slice(&p.q),
            qd: DVector::from_column_slice(&p.qd),
            qdd: DVector::from_column_slice(&p.qdd),
            redundant: None,
        });
        last = Some(p);
    }
    Ok(frames)
}

/// Every frame's residual is within the tolerance and every body's p has unit norm.
fn assert_consistent(case: &Case, engine: &str, frames: &[Frame], tolerance: f64) {
    for f in frames {
        assert!(
            f.residual <= tolerance,
            "seed {}: {engine}: t = {}: residual {:e} above the tolerance {tolerance:e}\n{}",
            case.seed,
            f.t,
            f.residual,
            case.toml
        );
        for body in f.q.as_slice().chunks(7) {
            let norm = (body[3..].iter().map(|e| e * e).sum::<f64>()).sqrt();
            assert!(
                (norm - 1.0).abs() <= UNIT_NORM,
                "seed {}: {engine}: t = {}: |p| − 1 = {:e}\n{}",
                case.seed,
                f.t,
                norm - 1.0,
                case.toml
            );
        }
    }
}

/// Asserts two runs agree to [`AGREEMENT`]; returns the largest relative differences.
fn assert_agree(case: &Case, engine: &str, generic: &[Frame], other: &[Frame]) -> [f64; 3] {
    assert_eq!(generic.len(), other.len(), "seed {}: {engine}: same number of frames", case.seed);
    let diffs = relative_differences(generic, other);
    for (rel, place) in &diffs {
        assert!(
            *rel <= AGREEMENT,
            "seed {}: {engine} and the generic engine differ by {rel:e} of the scale in \
             {place}\n{}",
            case.seed,
            case.toml
        );
    }
    diffs.map(|(rel, _)| rel)
}

/// Features every batch of random cases must cover: all joint types, all driver and
/// constraint kinds, closures to ground and to a body, placed ground, perturbed estimates.
const COVERAGE: [&str; 27] = [
    "joint revolute",
    "joint prismatic",
    "joint cylindrical",
    "joint screw",
    "closure spherical",
    "closure universal",
    "closure distance",
    "closure to ground",
    "closure to body",
    "driver rotation",
    "driver translation",
    "driver x",
    "driver y",
    "driver z",
    "driver rx",
    "driver ry",
    "driver rz",
    "constraint fix",
    "constraint coordinate_difference to ground",
    "constraint coordinate_difference between bodies",
    "ground placed",
    "estimates perturbed",
    "antiparallel axes",
    "distance given",
    "law polynomial",
    "law harmonic",
    "grid by step",
];

#[test]
fn generic_engine_and_interpreted_symbolic_system_agree_on_random_mechanisms() {
    let mut tally = Tally::default();
    let mut worst = [0.0_f64; 3];
    let mut iterations = 0u64;
    let mut steps = 0usize;
    for seed in 0..250 {
        let Some((case, run)) = tally.next(seed, Grid::ANALYSIS, None) else { continue };
        let tolerance = run.mech.solver.tolerance;
        assert_consistent(&case, "generic", &run.frames, tolerance);
        let frames = interpreted(&run.mech, &run.sys).unwrap_or_else(|e| {
            panic!("seed {seed}: the interpreted symbolic system fails: {e}\n{}", case.toml)
        });
        // The interpreted run converges the reduced rows to the tolerance; the full system
        // at the expanded coordinates adds the eliminated rows, which hold exactly.
        assert_consistent(&case, "interpreted", &frames, tolerance);
        let diffs = assert_agree(&case, "the interpreted symbolic system", &run.frames, &frames);
        for (w, d) in worst.iter_mut().zip(diffs) {
            *w = w.max(d);
        }
        iterations += frames.iter().map(|f| u64::from(f.iterations)).sum::<u64>();
        steps += frames.len();
    }
    println!(
        "{} of {} cases usable (rejected: {:?}); {steps} steps, {:.2} Newton iterations per \
         step; largest relative differences q {:e}, qd {:e}, qdd {:e}",
        tally.used(),
        tally.generated,
        tally.rejects,
        iterations as f64 / steps as f64,
        worst[0],
        worst[1],
        worst[2]
    );
    assert!(tally.used() >= 200, "{} usable cases, 200 wanted", tally.used());
    tally.assert_mostly_usable(0.8);
    for feature in COVERAGE {
        assert!(tally.features.contains(feature), "no usable case has {feature}");
    }
}

#[test]
fn generic_rates_match_central_differences_of_its_positions() {
    let mut tally = Tally::default();
    let mut worst = [0.0_f64; 2];
    for seed in 10_000..10_040 {
        // Newton to 1e-13 leaves position errors of about 1e-13 times the conditioning,
        // small enough to difference over 1 ms steps.
        let Some((case, run)) = tally.next(seed, Grid::FINE, Some(1e-13)) else { continue };
        let h = run.mech.time.step;
        let f = &run.frames;
        let interior = 1..f.len() - 1;
        let central = |get: Quantity, k: usize| (get(&f[k + 1]) - get(&f[k - 1])) / (2.0 * h);
        // Per component, the largest q''' and q'''' over the run, from the run's own q̈.
        let nq = f[0].q.len();
        let (mut d3, mut d4) = (DVector::<f64>::zeros(nq), DVector::<f64>::zeros(nq));
        for k in interior.clone() {
            let third = central(|fr| &fr.qdd, k);
            let fourth = (&f[k + 1].qdd - &f[k].qdd * 2.0 + &f[k - 1].qdd) / (h * h);
            d3 = d3.zip_map(&third, |a, b| a.max(b.abs()));
            d4 = d4.zip_map(&fourth, |a, b| a.max(b.abs()));
        }
        let scale = |get: Quantity| f.iter().map(|fr| get(fr).amax()).fold(1.0, f64::max);
        let (scale_v, scale_a) = (scale(|fr| &fr.qd), scale(|fr| &fr.qdd));
        for k in interior {
            for (m, (label, fd, exact, bound, s)) in [
                ("qd", central(|fr| &fr.q, k), &f[k].qd, &d3, scale_v),
                ("qdd", central(|fr| &fr.qd, k), &f[k].qdd, &d4, scale_a),
            ]
            .into_iter()
            .enumerate()
            {
                for i in 0..nq {
                    // A central difference errs by h²/6 times the next derivative (plus
                    // O(h⁴)); allow twice that, with the derivative's largest value over the
                    // run. Positions and rates converged to 1e-13 add about 1e-13·κ/h; 1e-8
                    // of the scale covers a conditioning κ up to 100.
                    let tolerance = 2.0 * h * h / 6.0 * bound[i] + 1e-8 * s;
                    let err = (fd[i] - exact[i]).abs();
                    worst[m] = worst[m].max(err / tolerance);
                    assert!(
                        err <= tolerance,
                        "seed {}: t = {}: {label}[{i}] = {:e} but the central difference \
                         gives {:e} (difference {err:e}, tolerance {tolerance:e})\n{}",
                        case.seed,
                        f[k].t,
                        exact[i],
                        fd[i],
                        case.toml
                    );
                }
            }
        }
    }
    println!(
        "{} of {} cases usable (rejected: {:?}); largest error / tolerance: qd {:.3}, qdd {:.3}",
        tally.used(),
        tally.generated,
        tally.rejects,
        worst[0],
        worst[1]
    );
    tally.assert_mostly_usable(0.8);
}

#[test]
fn compiled_generated_solvers_agree_with_the_generic_engine_on_random_mechanisms() {
    let mut tally = Tally::default();
    let mut chosen = Vec::new();
    let mut covered = BTreeSet::new();
    // Six usable cases picked greedily from 60 for the features they add, so that the few
    // builds see as many kinds of joint, driver and constraint as possible.
    let mut candidates: Vec<Case> =
        (20_000..20_060).map(|seed| generate::mechanism(seed, Grid::ANALYSIS)).collect();
    while chosen.len() < 6 && !candidates.is_empty() {
        let best = (0..candidates.len())
            .max_by_key(|&k| (candidates[k].features.difference(&covered).count(), usize::MAX - k))
            .expect("candidates left");
        let case = candidates.swap_remove(best);
        if let Some((case, run)) = tally.next(case.seed, Grid::ANALYSIS, None) {
            covered.extend(case.features.iter().copied());
            chosen.push((case, run));
        }
    }
    assert_eq!(chosen.len(), 6, "rejected: {:?}", tally.rejects);
    let mut worst = [0.0_f64; 3];
    for (case, run) in &chosen {
        // The mechanism is named `random_{seed}`, so the helpers' panics name the seed.
        let generated = run_generated(&run.mech, &build_generated(&run.mech));
        assert!(
            generated.failure.is_none(),
            "seed {}: the generated solver stops: {:?}\n{}",
            case.seed,
            generated.failure,
            case.toml
        );
        let frames = generated.frames;
        assert_consistent(case, "generated", &frames, run.mech.solver.tolerance);
        let diffs = assert_agree(case, "the generated solver", &run.frames, &frames);
        for (w, d) in worst.iter_mut().zip(diffs) {
            *w = w.max(d);
        }
    }
    println!(
        "seeds {:?}; features {covered:?}; largest relative differences q {:e}, qd {:e}, qdd {:e}",
        chosen.iter().map(|(c, _)| c.seed).collect::<Vec<_>>(),
        worst[0],
        worst[1],
        worst[2]
    );
}

/// A committed generated module behind [`DynMechanism`], with its initial estimates and
/// time span.
struct Module {
    name: &'static str,
    mechanism: Box<dyn DynMechanism>,
    q0: Vec<f64>,
    span: (f64, f64),
}

macro_rules! module {
    ($module:ident, $ty:ident) => {{
        use generated::$module as g;
        Module {
            name: stringify!($module),
            mechanism: Box::new(Fixed::<_, { g::N }>(g::$ty)),
            q0: g::Q0.to_vec(),
            span: (g::T_START, g::T_START + (g::T_COUNT - 1) as f64 * g::T_STEP),
        }
    }};
}

/// Every committed generated module.
fn modules() -> Vec<Module> {
    vec![
        module!(cylindrical_joint, CylindricalJoint),
        module!(four_bar, FourBar),
        module!(prismatic_joint, PrismaticJoint),
        module!(revolute_joint, RevoluteJoint),
        module!(rotation_about_x, RotationAboutX),
        module!(rotation_about_y, RotationAboutY),
        module!(rotation_about_y_short, RotationAboutYShort),
        module!(rssr, Rssr),
        module!(screw_joint, ScrewJoint),
        module!(slider_crank_5body, SliderCrank5body),
        module!(spherical_joint, SphericalJoint),
        module!(static_body, StaticBody),
        module!(static_body_offset, StaticBodyOffset),
        module!(translation_x, TranslationX),
        module!(translation_xy, TranslationXy),
        module!(translation_xyz, TranslationXyz),
        module!(translation_y, TranslationY),
        module!(universal_joint, UniversalJoint),
    ]
}

/// Random configurations near a module's Q0 (each unknown moved by up to 0.1) at random
/// times of its grid, with random rates of up to 1.
fn configurations(m: &Module, rng: &mut StdRng) -> Vec<(Vec<f64>, Vec<f64>, f64)> {
    (0..5)
        .map(|_| {
            let q = m.q0.iter().map(|x| x + rng.random_range(-0.1..0.1)).collect();
            let qd = m.q0.iter().map(|_| rng.random_range(-1.0..1.0)).collect();
            let t =
                if m.span.1 > m.span.0 { rng.random_range(m.span.0..m.span.1) } else { m.span.0 };
            (q, qd, t)
        })
        .collect()
}

#[test]
fn generated_jacobians_match_central_differences_of_the_residuals() {
    let mut rng = StdRng::seed_from_u64(5);
    let mut worst = 0.0_f64;
    let all = modules();
    assert_eq!(all.len(), 18);
    for m in &all {
        let n = m.mechanism.n();
        for (q, _, t) in configurations(m, &mut rng) {
            let mut jac = vec![0.0; n * n];
            m.mechanism.jacobian_into(&q, t, &mut jac);
            let scale = max_abs(&jac).max(1.0);
            let h = 1e-6;
            for j in 0..n {
                let (mut qp, mut qm) = (q.clone(), q.clone());
                qp[j] += h;
                qm[j] -= h;
                let (mut fp, mut fm) = (vec![0.0; n], vec![0.0; n]);
                m.mechanism.residual_into(&qp, t, &mut fp);
                m.mechanism.residual_into(&qm, t, &mut fm);
                for i in 0..n {
                    let fd = (fp[i] - fm[i]) / (2.0 * h);
                    let err = (fd - jac[i * n + j]).abs() / scale;
                    worst = worst.max(err);
                    // Central differences with h = 1e-6 err by h²/6·Φ''' ≈ 1e-13 and by
                    // round-off ε·|Φ|/h ≈ 1e-9 for residual terms of order 10; 1e-7 of the
                    // Jacobian's scale leaves a margin of 100 over both.
                    assert!(
                        err <= 1e-7,
                        "{}: t = {t}: ∂Φ{i}/∂q{j} = {:e} but the central difference gives {fd:e}",
                        m.name,
                        jac[i * n + j]
                    );
                }
            }
        }
    }
    println!("largest Jacobian error relative to its scale: {worst:e}");
}

#[test]
fn generated_gamma_matches_central_differences_of_the_constraint_rates() {
    // γ = −d/dτ Φ̇(q + τq̇, t + τ) at τ = 0, with Φ̇ = Φ_q q̇ − ν: the generated γ against a
    // central difference of the generated Φ_q and ν along a straight path.
    let mut rng = StdRng::seed_from_u64(6);
    let mut worst = 0.0_f64;
    for m in &modules() {
        let n = m.mechanism.n();
        for (q, qd, t) in configurations(m, &mut rng) {
            let rate = |tau: f64| {
                let qt: Vec<f64> = q.iter().zip(&qd).map(|(a, b)| a + tau * b).collect();
                let (mut jac, mut nu) = (vec![0.0; n * n], vec![0.0; n]);
                m.mechanism.jacobian_into(&qt, t + tau, &mut jac);
                m.mechanism.velocity_rhs_into(&qt, t + tau, &mut nu);
                (0..n)
                    .map(|i| (0..n).map(|j| jac[i * n + j] * qd[j]).sum::<f64>() - nu[i])
                    .collect::<Vec<f64>>()
            };
            let mut gamma = vec![0.0; n];
            m.mechanism.acceleration_rhs_into(&q, &qd, t, &mut gamma);
            let h = 1e-6;
            let (rp, rm) = (rate(h), rate(-h));
            let fd: Vec<f64> = (0..n).map(|i| -(rp[i] - rm[i]) / (2.0 * h)).collect();
            let scale = max_abs(&gamma).max(max_abs(&rp)).max(1.0);
            for i in 0..n {
                let err = (fd[i] - gamma[i]).abs() / scale;
                worst = worst.max(err);
                // As for the Jacobian: truncation h²/6 ≈ 2e-13 times a third derivative,
                // round-off ε·|Φ̇|/h ≈ 1e-9 of the scale; 1e-7 leaves a margin of 100.
                assert!(
                    err <= 1e-7,
                    "{}: t = {t}: γ{i} = {:e} but the central difference gives {:e}",
                    m.name,
                    gamma[i],
                    fd[i]
                );
            }
        }
    }
    println!("largest γ error relative to its scale: {worst:e}");
}

#[test]
fn emission_and_json_solutions_are_byte_identical_when_repeated() {
    let dir = codegen::sync::workspace_root().join("target/random-mechanisms");
    std::fs::create_dir_all(&dir).expect("target/ is writable");
    let mut tally = Tally::default();
    let mut checked = 0;
    // Four cases: emitting a module takes 0.1–0.4 s.
    for seed in 30_000..30_010 {
        if checked == 4 {
            break;
        }
        let Some((case, run)) = tally.next(seed, Grid::ANALYSIS, None) else { continue };
        checked += 1;
        let emit = || {
            let mech = load(&case);
            let sys = Symbolic::build(&mech).expect("usable cases generate");
            codegen::emit::module(&mech, &sys, "a random description")
        };
        let first = emit();
        assert!(first == emit(), "seed {seed}: two emissions differ");
        assert!(first.contains(&format!("pub const N: usize = {};", run.sys.unknowns.len())));
        let file = dir.join(format!("random_{seed}.toml"));
        std::fs::write(&file, &case.toml).expect("target/ is writable");
        let solve = || {
            let args = ["mechgen", "solve", "--engine", "generic", "--format", "json"]
                .into_iter()
                .map(Into::into)
                .chain([file.clone().into_os_string()])
                .collect();
            let (mut out, mut err) = (Vec::new(), Vec::new());
            let status = codegen::cli::run(args, &mut out, &mut err);
            assert_eq!(status, 0, "seed {seed}: {}", String::from_utf8_lossy(&err));
            out
        };
        let first = solve();
        let json: serde_json::Value = serde_json::from_slice(&first).expect("JSON output");
        assert_eq!(json["steps"].as_array().map(Vec::len), Some(run.frames.len()));
        assert!(first == solve(), "seed {seed}: two JSON solutions differ");
    }
    assert_eq!(checked, 4, "rejected: {:?}", tally.rejects);
}
