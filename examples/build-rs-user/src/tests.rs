//! The build-time generated solver against the closed form of the planar four-bar.

use core::f64::consts::PI;

use super::{Sample, control_loop};

/// Crank, coupler, rocker and ground lengths (m), as in `planar_four_bar.toml`.
const A: f64 = 0.2;
const B: f64 = 0.5;
const C: f64 = 0.4;
const D: f64 = 0.6;

/// The rocker angle ψ(θ) by intersecting the circle of radius B about the crank pin
/// (A cos θ, A sin θ) with the circle of radius C about the pivot (D, 0), on the branch with
/// the joint B above the line from the crank pin to the pivot (the assembly of the
/// description at θ = 0).
fn rocker_angle(theta: f64) -> f64 {
    let (sin, cos) = theta.sin_cos();
    let pin = [A * cos, A * sin];
    let to_pivot = [D - pin[0], -pin[1]];
    let l = to_pivot[0].hypot(to_pivot[1]);
    let u = [to_pivot[0] / l, to_pivot[1] / l];
    let along = (B * B - C * C + l * l) / (2.0 * l);
    let across = (B * B - along * along).sqrt();
    // Left of the direction from the pin to the pivot: the side B lies on at θ = 0.
    let joint = [pin[0] + along * u[0] - across * u[1], pin[1] + along * u[1] + across * u[0]];
    (joint[1]).atan2(joint[0] - D)
}

/// The difference of two angles in (−π, π].
fn angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(2.0 * PI);
    if d > PI { d - 2.0 * PI } else { d }
}

#[test]
fn the_generated_solver_follows_the_closed_form_over_one_crank_turn() {
    let mut samples: Vec<Sample> = Vec::new();
    control_loop(101, 0.01, |s| samples.push(s)).expect("a crank-rocker turns fully");
    assert_eq!(samples.len(), 101);
    let omega = 2.0 * PI; // The description's crank speed (rad/s).
    for s in &samples {
        let theta = omega * s.t;
        let psi = rocker_angle(theta);
        // Newton stops at max |Φ_i| ≤ 1e-12 over O(1) coordinates; the angle inherits that
        // error scaled by the conditioning of the loop (well away from toggle), so 1e-9.
        assert!(
            angle_diff(s.rocker_angle, psi).abs() < 1e-9,
            "t = {}: rocker {} rad, closed form {psi}",
            s.t,
            s.rocker_angle
        );
        // ψ̇ = ψ'(θ) ω by a central difference of the closed form: h = 1e-6 leaves a
        // truncation error ~h² |ψ'''| ~ 1e-11 and round-off ~1e-16/h ~ 1e-10 (times ω ≈ 6).
        let h = 1e-6;
        let rate = angle_diff(rocker_angle(theta + h), rocker_angle(theta - h)) / (2.0 * h) * omega;
        assert!(
            (s.rocker_rate - rate).abs() < 1e-7 * (1.0 + rate.abs()),
            "t = {}: rocker rate {}, closed form {rate}",
            s.t,
            s.rocker_rate
        );
    }
    // The rocker swings: its angle range is that of a crank-rocker, not a constant.
    let (lo, hi) = samples
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), s| (lo.min(s.rocker_angle), hi.max(s.rocker_angle)));
    assert!(hi - lo > 0.5, "swing {lo}..{hi}");
}
