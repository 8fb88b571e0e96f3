//! The single-precision generated solver (`mechgen generate --float f32`) against the
//! double-precision generic engine, over one crank revolution of the R-S-S-R.

use codegen::emit::Scalar;
use codegen::engine::{Settings, build_in, run_with};
use codegen::generic::{Analysis, Equations, Frame};
use codegen::testing::load;

/// Largest |a − b| over all frames for one quantity, relative to the largest |a|.
fn relative(reference: &[Frame], run: &[Frame], get: fn(&Frame) -> &nalgebra::DVector<f64>) -> f64 {
    let scale = reference.iter().map(|f| get(f).amax()).fold(f64::MIN_POSITIVE, f64::max);
    let diff = reference.iter().zip(run).map(|(a, b)| (get(a) - get(b)).amax()).fold(0.0, f64::max);
    diff / scale
}

#[test]
fn single_precision_rssr_follows_the_double_precision_generic_engine() {
    let root = codegen::sync::workspace_root();
    let loaded = load(&root.join("benches/rssr_revolution.toml"));
    let mech = &loaded.mechanism;
    let eq = Equations::new(mech);
    let prep = eq.prepare();
    let mut reference = Vec::new();
    let report = Analysis::new(&eq, &prep)
        .with_tolerance(1e-12)
        .run(|f| {
            reference.push(f.clone());
            Ok::<(), ()>(())
        })
        .expect("no sink errors");
    assert!(report.failure.is_none(), "{:?}", report.failure);

    let built = build_in(mech, Scalar::F32).unwrap_or_else(|e| panic!("{e}"));
    let mut frames = Vec::new();
    // 1e-4 is the f32 default Newton tolerance (runtime::Real::DEFAULT_TOLERANCE): residuals
    // of unit size cannot be pushed much below f32's rounding error of 6e-8.
    let namer = Analysis::new(&eq, &prep);
    let report = run_with(&built, &namer, Some(1e-4), Settings::default(), |f| {
        frames.push(f.clone());
        Ok(())
    })
    .unwrap_or_else(|e| panic!("{e}"));
    assert!(report.failure.is_none(), "{:?}", report.failure);
    assert_eq!(frames.len(), reference.len());
    for (a, b) in reference.iter().zip(&frames) {
        // The f32 grid times are the f64 ones rounded to f32: within 1 ulp of t ≤ 3.6 s.
        assert!((a.t - b.t).abs() <= 4.0 * f64::from(f32::EPSILON), "t {} vs {}", a.t, b.t);
    }
    let [q, qd, qdd] = [
        relative(&reference, &frames, |f| &f.q),
        relative(&reference, &frames, |f| &f.qd),
        relative(&reference, &frames, |f| &f.qdd),
    ];
    println!("f32 R-S-S-R vs generic f64: q {q:e}, qd {qd:e}, qdd {qdd:e}");
    // Newton stops at max |Φ| ≤ 1e-4 (lengths in m, links of 0.04–0.2 m), which alone bounds
    // the position error only by 1e-4 over Φ_q's smallest singular value; but the predictor's
    // chord correction and Newton's quadratic last step leave the positions near f32
    // round-off (observed 4.4e-7 relative, rates 7e-7 and 1.5e-6). The bounds are about 20×
    // those, so a loss of precision in the f32 rewrite (a literal or constant left in f64 and
    // rounded twice, a wrong pivot guard) shows.
    assert!(q < 1e-5, "positions off by {q:e}");
    assert!(qd < 2e-5 && qdd < 3e-5, "rates off by {qd:e}, {qdd:e}");
}
