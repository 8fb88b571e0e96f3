//! `mechgen plot` run in process: the SVG it writes, and its errors.

use std::path::PathBuf;

use crate::cli::tests::mechgen;
use crate::cli::{EXIT_INVALID, EXIT_OK};

use crate::testing::example_arg as example;

/// A fresh output path in the temporary directory.
fn output(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("mechgen-plot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temporary directory");
    dir.join(name)
}

#[test]
fn a_point_plot_has_labelled_axes_and_the_path() {
    let svg = output("four_bar_b.svg");
    let (code, out, err) =
        mechgen(&["plot", &example("four_bar.toml"), "--point", "B", "-o", svg.to_str().unwrap()]);
    assert_eq!(code, EXIT_OK, "{err}");
    // The four-bar's grid has 26 time points (0 to 2.5 s by 0.1 s).
    assert!(out.contains("26 time points"), "{out}");
    let text = std::fs::read_to_string(&svg).expect("the SVG was written");
    for label in ["t (s)", "r_P (m)", "r_P.x", "r_P.z", "path (m)", "\nx ", "\ny ", "\nz "] {
        assert!(text.contains(label), "missing label {label}");
    }
    assert!(text.contains("four_bar: point B"));
}

#[test]
fn a_body_plot_of_omega_is_in_radians_per_second_without_a_path() {
    let svg = output("rssr_crank_omega.svg");
    let (code, _, err) = mechgen(&[
        "plot",
        &example("rssr.toml"),
        "--body",
        "crank",
        "--quantity",
        "omega",
        "-o",
        svg.to_str().unwrap(),
    ]);
    assert_eq!(code, EXIT_OK, "{err}");
    let text = std::fs::read_to_string(&svg).expect("the SVG was written");
    assert!(text.contains("ω (rad/s)"));
    assert!(!text.contains("path (m)"), "ω has no path panel");
}

#[test]
fn an_unknown_point_is_invalid_input_with_a_suggestion() {
    let svg = output("never.svg");
    let (code, _, err) =
        mechgen(&["plot", &example("rssr.toml"), "--point", "BB", "-o", svg.to_str().unwrap()]);
    assert_eq!(code, EXIT_INVALID);
    assert!(err.contains("no point \"BB\": did you mean \"B\"?"), "{err}");
    assert!(!svg.exists());
}

#[test]
fn a_point_has_no_angular_velocity() {
    let svg = output("never2.svg");
    let (code, _, err) = mechgen(&[
        "plot",
        &example("rssr.toml"),
        "--point",
        "B",
        "--quantity",
        "omega",
        "-o",
        svg.to_str().unwrap(),
    ]);
    assert_eq!(code, EXIT_INVALID);
    assert!(err.contains("--quantity"), "{err}");
}
