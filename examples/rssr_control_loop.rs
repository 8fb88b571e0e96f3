//! A control loop on the generated R-S-S-R solver: 10,000 periods of 10 µs, position and
//! velocity each period, no allocation. Run with
//! `cargo run --release -p examples --example rssr_control_loop`.

fn main() {
    let periods = 10_000;
    let start = std::time::Instant::now();
    match examples::rssr_control_loop(periods, 1e-5) {
        Ok(s) => {
            let ns = start.elapsed().as_nanos() as f64 / s.periods as f64;
            println!(
                "{} periods, {:.2} Newton iterations per period, {ns:.0} ns per period, \
                 max |Φ| {:.1e}, max rocker |ė1| {:.3}",
                s.periods,
                s.iterations as f64 / s.periods as f64,
                s.max_residual,
                s.max_rocker_rate
            );
        }
        Err(e) => {
            eprintln!("the solver stopped: {e}");
            std::process::exit(2);
        }
    }
}
