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

/// What the loop does after a call.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Action {
    /// Use the new output.
    Run,
    /// Keep the last good output for this period and try again at the next one.
    Hold,
    /// Bring the machine to a safe stop: the mechanism cannot follow its command.
    Stop,
}

fn main() {
    // 10 µs periods over 1,000 periods: the crank (146.6 rad/s) turns by 1.47 rad.
    let (periods, dt): (u32, f64) = (1_000, 1e-5);
    let mut solver = Solver::new(rssr::Rssr, rssr::Q0);
    solver.set_options(NewtonOptions { tolerance: 1e-12, ..NewtonOptions::DEFAULT });
    solver.set_predictor(true);
    let mut last = Output::default();
    let (mut held, mut steps) = (0, 0);
    let start = Instant::now();
    for k in 0..periods {
        // The time (here: the sampled command); period 500 reads a NaN.
        let t = if k == 500 { f64::NAN } else { f64::from(k) * dt };
        let action = match solver.advance_to(t) {
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
                Action::Run
            }
            // A NaN or infinite t never converges: the solver keeps its last accepted point.
            Err(stop) if !stop.t.is_finite() => Action::Hold,
            // The sub-steps could not reach t: branch_jump, singular or no_convergence.
            Err(stop) => {
                eprintln!("stopping the machine at t = {}: {}: {stop}", solver.t(), stop.trouble);
                Action::Stop
            }
        };
        match action {
            Action::Run => {}
            Action::Hold => held += 1,
            Action::Stop => std::process::exit(2),
        }
    }
    let ns = start.elapsed().as_nanos() as f64 / f64::from(periods);
    println!(
        "advance_to: {steps} steps, {held} held, {ns:.0} ns per period; plain position, \
         velocity and acceleration: {:.0} ns per period",
        plain(periods, dt)
    );
    println!(
        "at t = {:.5} s: B = {:.6?} m, \
         v_B = {:.6?} m/s, rocker ω = {:.6?} rad/s",
        solver.t(),
        last.b[0],
        last.b[1],
        last.rocker_omega
    );
}

/// ns per period of the same loop with plain `position`, `velocity` and `acceleration` calls,
/// which trust the caller's step.
fn plain(periods: u32, dt: f64) -> f64 {
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
    start.elapsed().as_nanos() as f64 / f64::from(periods)
}
