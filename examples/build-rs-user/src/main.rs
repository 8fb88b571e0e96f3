//! Runs the control loop of the build-time generated four-bar solver for one crank turn and
//! prints the rocker's angle and rate every 0.1 s.

fn main() {
    let mut period = 0;
    let result = build_rs_user::control_loop(101, 0.01, |s| {
        period += 1;
        if period % 10 == 1 {
            println!(
                "t = {:.2} s  rocker {:8.3}°  {:8.3} rad/s  ({} Newton iterations)",
                s.t,
                s.rocker_angle.to_degrees(),
                s.rocker_rate,
                s.iterations
            );
        }
    });
    if let Err(e) = result {
        eprintln!("the solver stopped: {e}");
        std::process::exit(2);
    }
}
