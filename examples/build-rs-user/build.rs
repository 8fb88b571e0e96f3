//! Generates the solver of `planar_four_bar.toml` into `OUT_DIR` on every change of the
//! description (see `codegen::build`).

fn main() {
    if let Err(e) = codegen::build::Builder::new().file("planar_four_bar.toml").compile() {
        // The message holds each diagnostic with its excerpt; cargo shows it under the error.
        eprintln!("{e}");
        std::process::exit(1);
    }
}
