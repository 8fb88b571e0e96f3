//! Draws the condition of Φ_q and the Newton iterations of both engines against time for one
//! description (the chart `docs/four-bar-near-toggle-conditioning.svg` comes from
//! `cargo run --release -p examples --example conditioning_chart --
//! tests/stability/four_bar_near_toggle.toml docs/four-bar-near-toggle-conditioning.svg`).

use std::path::Path;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let [_, file, svg] = args.as_slice() else {
        return Err("usage: conditioning_chart DESCRIPTION.toml OUTPUT.svg".into());
    };
    let loaded = codegen::validate::load_file(Path::new(file))
        .map_err(|d| d.iter().map(ToString::to_string).collect::<Vec<_>>().join("\n"))?;
    let mech = &loaded.mechanism;
    let points = codegen::chart::conditioning(mech)?;
    println!("{:>8} {:>12} {:>12} {:>8} {:>10}", "t", "kappa_2", "1/rho", "generic", "generated");
    for p in &points {
        let g = p.generated_iterations.map_or_else(|| "-".to_owned(), |n| n.to_string());
        println!(
            "{:>8.3} {:>12.4e} {:>12.4e} {:>8} {:>10}",
            p.t, p.condition, p.pivot_estimate, p.generic_iterations, g
        );
    }
    let title = format!("{}: condition of Φ_q and Newton iterations", mech.name);
    codegen::chart::draw_conditioning(&points, &title, Path::new(svg))?;
    println!("wrote {svg}");
    Ok(())
}
