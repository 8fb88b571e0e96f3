//! Writes the leg lengths of the Stewart platform (examples/inputs/stewart.toml) along its
//! shipped trajectory as an inputs file for `mechgen solve --inputs`: 2 s every 20 ms, each
//! leg's length, rate and acceleration by closed-form inverse kinematics. Run with
//! `cargo run -p examples --example stewart_inputs -- examples/inputs/stewart_legs.csv`
//! (standard output without a path).

use examples::stewart::{self, Trajectory};

/// The sampling step (s) and the number of steps: 2 s.
const STEP: f64 = 0.02;
/// Steps of [`STEP`] after t = 0.
const STEPS: usize = 100;

fn main() {
    let comment = "Leg lengths (m, m/s, m/s²) of examples/inputs/stewart.toml along \
                   examples::stewart::Trajectory::SHIPPED,\nby closed-form inverse kinematics \
                   (examples/src/stewart.rs), written by\n`cargo run -p examples --example \
                   stewart_inputs -- examples/inputs/stewart_legs.csv`.";
    let text = stewart::inputs_csv(&Trajectory::SHIPPED, STEP, STEPS, comment);
    match std::env::args_os().nth(1) {
        Some(path) => {
            if let Err(e) = std::fs::write(&path, text) {
                eprintln!("cannot write {}: {e}", path.to_string_lossy());
                std::process::exit(1);
            }
        }
        None => print!("{text}"),
    }
}
