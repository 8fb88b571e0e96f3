//! Criterion benchmarks of one full time step (position to 1e-12, velocity, acceleration)
//! of the R-S-S-R over one crank revolution, generic and generated side by side, and the
//! generated one under the runtime's step control (`Solver::advance_to`).
//! Run with `cargo bench -p examples --bench step`.

use std::hint::black_box;

use codegen::generic::{Analysis, Equations};
use criterion::{Criterion, criterion_group, criterion_main};
use generated::rssr;
use runtime::{NewtonOptions, Solver};

/// One revolution (2π/146.6 s) in 1000 steps.
const STEPS: usize = 1000;

fn revolution_generated(controlled: bool) -> f64 {
    let dt = 2.0 * std::f64::consts::PI / 146.6 / STEPS as f64;
    let mut solver = Solver::new(rssr::Rssr, rssr::Q0);
    solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    let mut sum = 0.0;
    for k in 0..=STEPS {
        let t = k as f64 * dt;
        if controlled {
            solver.advance_to(t).expect("the R-S-S-R turns smoothly");
        } else {
            solver.position(t).expect("converges");
            solver.velocity().expect("factorised");
            solver.acceleration().expect("factorised");
        }
        sum += solver.qdd()[0];
    }
    sum
}

fn benches(c: &mut Criterion) {
    let path = examples::dir().join("../benches/rssr_revolution.toml");
    let mech = codegen::validate::load_file(&path).expect("benchmark input").mechanism;
    let eq = Equations::new(&mech);
    let prep = eq.prepare();
    let analysis = Analysis::new(&eq, &prep).with_tolerance(1e-12);
    let mut group = c.benchmark_group("rssr revolution, 1001 steps");
    group.sample_size(20);
    group.bench_function("generated", |b| b.iter(|| black_box(revolution_generated(false))));
    group.bench_function("generated advance_to", |b| {
        b.iter(|| black_box(revolution_generated(true)));
    });
    group.bench_function("generic", |b| {
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

criterion_group!(step, benches);
criterion_main!(step);
