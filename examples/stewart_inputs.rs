//! Writes the leg lengths of the Stewart platform (examples/inputs/stewart.toml) along its
//! shipped trajectory as an inputs file for `mechgen solve --inputs`: each leg's length, rate
//! and acceleration by closed-form inverse kinematics, every STEP seconds (default 0.02) from 0
//! to SECONDS (default 2). The shipped file is
//! `cargo run -p examples --example stewart_inputs -- examples/inputs/stewart_legs.csv`;
//! BENCHMARKS.md uses `… -- /tmp/stewart_1khz.csv 0.001 2`. Without a path (or with `-`) the
//! file goes to standard output.

use examples::stewart::{self, Trajectory};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let number = |i: usize, default: f64| match args.get(i) {
        None => Some(default),
        Some(s) => s.parse::<f64>().ok().filter(|x| x.is_finite() && *x > 0.0),
    };
    let (Some(step), Some(seconds)) = (number(1, 0.02), number(2, 2.0)) else {
        eprintln!("usage: stewart_inputs [PATH|- [STEP [SECONDS]]], STEP and SECONDS > 0");
        std::process::exit(1);
    };
    let steps = (seconds / step).round();
    if steps > 1e7 {
        eprintln!("{steps} rows are more than an inputs file may have (10,000,000)");
        std::process::exit(1);
    }
    let comment = format!(
        "Leg lengths (m, m/s, m/s²) of examples/inputs/stewart.toml along \
         examples::stewart::Trajectory::SHIPPED,\nby closed-form inverse kinematics \
         (examples/src/stewart.rs), written by\n`cargo run -p examples --example stewart_inputs \
         -- {} {step} {seconds}`.",
        args.first().map_or("-", String::as_str)
    );
    let text = stewart::inputs_csv(&Trajectory::SHIPPED, step, steps as usize, &comment);
    match args.first().filter(|p| *p != "-") {
        Some(path) => {
            if let Err(e) = std::fs::write(path, text) {
                eprintln!("cannot write {path}: {e}");
                std::process::exit(1);
            }
        }
        None => print!("{text}"),
    }
}
