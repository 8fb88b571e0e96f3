//! A control loop on the generated R-S-S-R solver under the runtime's step control
//! (`Solver::advance_to`), reading named outputs and deciding what to do on each error; the
//! listing of docs/embedding.md. One sample is a NaN, as from a failed sensor read, to show the
//! loop holding its last good output. Run with
//! `cargo run --release -p examples --example embedded_loop`.

use std::time::Instant;

use generated::rssr;
use runtime::{NewtonOptions, Solver};

/// What the controller reads every period.
#[derive(Clone, Copy, Debug, Default)]
struct Output {
    /// Position and velocity of point B (m, m/s, global).
    b: [[f64; 3]; 2],
    /// Angular velocity of the rocker (rad/s, global).
    rocker_omega: [f64; 3],
}

/// What a run of the loop ended with.
#[derive(Clone, Copy, Debug)]
struct Run {
    /// Periods whose call succeeded.
    steps: u32,
    /// Periods that held the last good output.
    held: u32,
    /// The time of the solver's last point.
    t: f64,
    /// The last good output.
    last: Output,
}

fn main() {
    // 10 µs periods over 1,000 periods: the crank (146.6 rad/s) turns by 1.47 rad.
    let (periods, dt): (u32, f64) = (1_000, 1e-5);
    let start = Instant::now();
    let run = match control_loop(periods, dt, Some(500)) {
        Ok(run) => run,
        Err(message) => {
            eprintln!("{message}");
            std::process::exit(2);
        }
    };
    let ns = start.elapsed().as_nanos() as f64 / f64::from(periods);
    println!(
        "advance_to: {} steps, {} held, {ns:.0} ns per period; plain position, velocity and \
         acceleration: {:.0} ns per period",
        run.steps,
        run.held,
        plain(periods, dt).1
    );
    println!(
        "at t = {:.5} s: B = {:.6?} m, v_B = {:.6?} m/s, rocker ω = {:.6?} rad/s",
        run.t, run.last.b[0], run.last.b[1], run.last.rocker_omega
    );
}

/// The control loop: `periods` periods of `dt` under `advance_to`, a NaN sample in period
/// `nan_at`. A stop is returned as the message the machine's log would get.
fn control_loop(periods: u32, dt: f64, nan_at: Option<u32>) -> Result<Run, String> {
    let mut solver = Solver::new(rssr::Rssr, rssr::Q0);
    solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    let mut last = Output::default();
    let (mut held, mut steps) = (0, 0);
    for k in 0..periods {
        // The time (here: the sampled command); period `nan_at` reads a NaN.
        let t = if Some(k) == nan_at { f64::NAN } else { f64::from(k) * dt };
        match solver.advance_to(t) {
            Ok(_) => {
                // Named outputs: index constants and accessors of the generated module.
                let mut points = [[0.0; 3]; rssr::POINTS];
                rssr::point_positions(solver.q(), t, &mut points);
                last.b[0] = points[rssr::point::B];
                rssr::point_velocities(solver.q(), solver.qd(), t, &mut points);
                last.b[1] = points[rssr::point::B];
                let mut omega = [[0.0; 3]; rssr::BODIES];
                rssr::angular_velocities(solver.q(), solver.qd(), t, &mut omega);
                last.rocker_omega = omega[rssr::body::ROCKER];
                steps += 1;
            }
            // A NaN or infinite t never converges: the solver keeps its last accepted point,
            // and the loop holds its last good output for this period.
            Err(stop) if !stop.t.is_finite() => held += 1,
            // The sub-steps could not reach t (branch_jump, singular or no_convergence): the
            // mechanism cannot follow its command, so the machine must stop safely.
            Err(stop) => {
                let (at, kind) = (solver.t(), stop.trouble);
                return Err(format!("stopping the machine at t = {at}: {kind}: {stop}"));
            }
        }
    }
    Ok(Run { steps, held, t: solver.t(), last })
}

/// Point B at the last period and ns per period of the same loop with plain `position`,
/// `velocity` and `acceleration` calls, which trust the caller's step.
fn plain(periods: u32, dt: f64) -> ([f64; 3], f64) {
    let mut solver = Solver::new(rssr::Rssr, rssr::Q0);
    solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    let start = Instant::now();
    for k in 0..periods {
        let status = runtime::Status::of(&solver.position(f64::from(k) * dt));
        if !status.is_ok() || solver.velocity().is_err() || solver.acceleration().is_err() {
            eprintln!("the plain loop stopped at period {k}: {status:?}");
            break;
        }
    }
    let ns = start.elapsed().as_nanos() as f64 / f64::from(periods);
    let mut points = [[0.0; 3]; rssr::POINTS];
    rssr::point_positions(solver.q(), solver.t(), &mut points);
    (points[rssr::point::B], ns)
}

#[cfg(test)]
mod tests {
    use super::{control_loop, plain};

    #[test]
    fn a_nan_sample_is_held_and_the_loop_ends_where_the_plain_one_does() {
        let with_nan = control_loop(1_000, 1e-5, Some(500)).expect("the R-S-S-R follows its crank");
        let clean = control_loop(1_000, 1e-5, None).expect("the R-S-S-R follows its crank");
        assert_eq!((with_nan.steps, with_nan.held), (999, 1));
        assert_eq!((clean.steps, clean.held), (1_000, 0));
        let (b, _) = plain(1_000, 1e-5);
        // Both loops converge to max |Φ| ≤ 1e-12 at the same t; Φ_q of the R-S-S-R is well
        // conditioned along this arc, so their positions agree far below 1e-9 m.
        for (name, run) in [("with a NaN", with_nan), ("clean", clean)] {
            assert!((run.t - 999e-5).abs() < 1e-15, "{name}: t = {}", run.t);
            for (x, y) in run.last.b[0].iter().zip(&b) {
                assert!((x - y).abs() < 1e-9, "{name}: B = {:?} against {b:?}", run.last.b[0]);
            }
        }
    }
}
