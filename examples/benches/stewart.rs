//! Criterion benchmarks of the Stewart platform's forward kinematics at 1 kHz: one call is
//! position (to max |Φ| or max |Δl| ≤ 1e-12), velocity and acceleration from the six leg
//! lengths, rates and accelerations of the shipped trajectory, over 201 periods (0.2 s). Side by
//! side: the generated solver under its step control (`advance_with`) and with plain calls,
//! the whole system without its closed forms substituted (`generated::stewart_whole`, 91
//! unknowns against 55) with plain calls,
//! the generated solver of the platform alone (`generated::stewart_platform`, the legs reduced
//! to distance rows) with plain calls, the generic engine straight from point to point (as
//! `mechgen bench` times it) and under its step control (as `solve` runs), and the
//! motion-control baseline (Newton on the six pose parameters). Run with `cargo bench -p examples --bench stewart`.

use std::hint::black_box;
use std::sync::Arc;

use codegen::generic::{Analysis, Equations};
use codegen::inputs::Replay;
use codegen::model::TimeGrid;
use criterion::{Criterion, criterion_group, criterion_main};
use examples::stewart::baseline::ForwardKinematics;
use examples::stewart::{LEGS, Trajectory, control, leg_lengths, pose};

/// Control periods per pass (0.2 s at 1 kHz).
const PERIODS: usize = 201;
/// The control period (s).
const PERIOD: f64 = 1e-3;

/// The leg inputs of every period, computed before timing.
fn samples() -> Vec<(f64, [[f64; 3]; LEGS])> {
    (0..PERIODS)
        .map(|k| {
            let t = k as f64 * PERIOD;
            (t, leg_lengths(&Trajectory::SHIPPED.at(t)))
        })
        .collect()
}

fn benches(c: &mut Criterion) {
    let samples = samples();
    let mut group = c.benchmark_group("stewart at 1 kHz, 201 periods");
    group.sample_size(10);
    group.bench_function("generated, advance_with", |b| {
        let mut solver = Box::new(control::solver(&Trajectory::SHIPPED, 0.0));
        b.iter(|| {
            solver.set_q(generated::stewart::Q0);
            for (t, u) in &samples {
                solver.advance_with(*t, u).expect("the platform follows");
            }
            black_box(solver.qdd()[0])
        });
    });
    group.bench_function("generated, plain calls", |b| {
        let mut solver = Box::new(control::solver(&Trajectory::SHIPPED, 0.0));
        b.iter(|| {
            solver.set_q(generated::stewart::Q0);
            for (t, u) in &samples {
                control::plain_step(&mut solver, *t, u).expect("the platform follows");
            }
            black_box(solver.qdd()[0])
        });
    });
    group.bench_function("generated whole (no substitution), plain calls", |b| {
        use generated::stewart_whole::{self as sw, Inputs, StewartWhole};
        let start = Inputs::from_array(leg_lengths(&Trajectory::SHIPPED.at(0.0)));
        let mut solver = Box::new(runtime::Solver::new(StewartWhole::new(0.0, &start), sw::Q0));
        solver.set_options(runtime::NewtonOptions {
            tolerance: sw::TOLERANCE,
            ..runtime::NewtonOptions::DEFAULT
        });
        solver.set_predictor(true);
        b.iter(|| {
            solver.set_q(sw::Q0);
            for (t, u) in &samples {
                control::plain_step(&mut solver, *t, u).expect("the platform follows");
            }
            black_box(solver.qdd()[0])
        });
    });
    group.bench_function("generated platform only, plain calls", |b| {
        let mut solver = Box::new(pose::solver(&Trajectory::SHIPPED, 0.0));
        b.iter(|| {
            solver.set_q(generated::stewart_platform::Q0);
            for (t, u) in &samples {
                pose::plain_step(&mut solver, *t, u).expect("the platform follows");
            }
            black_box(solver.qdd()[0])
        });
    });
    group.bench_function("baseline (Newton on the pose)", |b| {
        b.iter(|| {
            let home = examples::stewart::home_position();
            let mut fk = ForwardKinematics::new(0.0, home, nalgebra::Vector3::zeros());
            for (t, u) in &samples {
                fk.position(*t, &u.map(|l| l[0])).expect("converges");
                fk.velocity(&u.map(|l| l[1])).expect("after a position");
                fk.acceleration(&u.map(|l| l[2])).expect("after a velocity");
            }
            black_box(fk.twist_dot()[0])
        });
    });
    let path = examples::dir().join("inputs/stewart.toml");
    let mut mech = codegen::validate::load_file(&path).expect("the description").mechanism;
    let replay = Replay {
        file: "closed form".into(),
        t: samples.iter().map(|s| s.0).collect(),
        series: (0..LEGS).map(|k| Some(samples.iter().map(|s| s.1[k]).collect())).collect(),
        declared: (mech.time.start, mech.time.step, mech.time.count),
    };
    mech.time = TimeGrid::replaying(Arc::new(replay));
    let eq = Equations::new(&mech);
    let prep = eq.prepare();
    let analysis = Analysis::new(&eq, &prep).with_tolerance(1e-12);
    group.bench_function("generic, straight", |b| {
        b.iter(|| analysis.time(1).expect("the platform follows"));
    });
    group.bench_function("generic, step control", |b| {
        b.iter(|| {
            analysis
                .run(|f| {
                    black_box(&f.qdd);
                    Ok::<(), ()>(())
                })
                .expect("the sink never fails")
        });
    });
    group.finish();
}

criterion_group!(stewart, benches);
criterion_main!(stewart);
