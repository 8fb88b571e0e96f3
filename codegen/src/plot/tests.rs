//! Sampling of long runs.

use super::{MAX_SAMPLES, Quantity, Target, Trace};
use crate::report::{PointResult, StepResult};

fn step(t: f64) -> StepResult {
    StepResult {
        t,
        iterations: 1,
        residual: 0.0,
        condition: 1.0,
        suspect: crate::report::Suspect::default(),
        bodies: Vec::new(),
        points: vec![PointResult { name: "P".into(), r: [t, 0.0, 0.0], v: [1.0; 3], a: [0.0; 3] }],
        joints: Vec::new(),
        redundant: None,
    }
}

#[test]
fn a_long_run_is_sampled_evenly_and_keeps_its_last_point() {
    let steps = 10 * MAX_SAMPLES + 7;
    let mut trace = Trace::new(steps);
    let target = Target::Point("P".into());
    for k in 0..steps {
        trace.push(&step(k as f64), &target, Quantity::R).expect("the point exists");
    }
    trace.close();
    assert!(trace.t.len() <= MAX_SAMPLES, "{} samples", trace.t.len());
    assert!(trace.t.len() > MAX_SAMPLES / 2, "{} samples", trace.t.len());
    assert_eq!(trace.t[0], 0.0);
    assert_eq!(*trace.t.last().unwrap(), (steps - 1) as f64);
    let gaps: Vec<f64> = trace.t.windows(2).map(|w| w[1] - w[0]).collect();
    let stride = gaps[0];
    assert!(gaps[..gaps.len() - 1].iter().all(|&g| g == stride), "even sampling");
    assert_eq!(trace.path.len(), trace.t.len());
    assert_eq!(trace.path[1], [stride, 0.0, 0.0]);
}

#[test]
fn a_short_run_keeps_every_point() {
    let mut trace = Trace::new(5);
    for k in 0..5 {
        trace.push(&step(k as f64), &Target::Point("P".into()), Quantity::V).expect("exists");
    }
    trace.close();
    assert_eq!(trace.t, [0.0, 1.0, 2.0, 3.0, 4.0]);
    assert_eq!(trace.values[2], [1.0, 1.0, 1.0]);
}

#[test]
fn a_missing_target_is_an_error() {
    let mut trace = Trace::new(1);
    let e = trace.push(&step(0.0), &Target::Body("crank".into()), Quantity::R).unwrap_err();
    assert_eq!(e, super::TraceError::NoBody("crank".into()));
    assert!(e.to_string().contains("crank"), "{e}");
}
