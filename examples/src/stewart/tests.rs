//! The closed forms against finite differences, and the baseline forward kinematics against
//! the closed-form trajectory.

use nalgebra::{Matrix3, Vector3};

use super::baseline::{Error, ForwardKinematics};
use super::{LEGS, Trajectory, leg_lengths};

/// The times checked: 2 s of the shipped trajectory, at a step that no frequency divides.
fn times() -> impl Iterator<Item = f64> {
    (0..=200).map(|k| f64::from(k) * 0.0101)
}

/// The largest absolute entry of a difference.
fn largest(m: impl IntoIterator<Item = f64>) -> f64 {
    m.into_iter().fold(0.0, |a, b| a.max(b.abs()))
}

#[test]
fn the_trajectory_s_derivatives_are_its_finite_differences() {
    let tr = Trajectory::SHIPPED;
    // Central differences over ±h: truncation h²/6 |x'''| ≤ 1e-10 · 0.06 · 27 / 6 ≈ 3e-11
    // (amplitudes ≤ 0.06 m or rad, frequencies ≤ 3 rad/s), round-off about 1e-16 / h = 1e-11.
    let h = 1e-5;
    for t in times() {
        let (m, before, after) = (tr.at(t), tr.at(t - h), tr.at(t + h));
        let fd = |a: Vector3<f64>, b: Vector3<f64>| (b - a) / (2.0 * h);
        assert!(largest((fd(before.position, after.position) - m.velocity).iter().copied()) < 1e-9);
        assert!(
            largest((fd(before.velocity, after.velocity) - m.acceleration).iter().copied()) < 1e-9
        );
        // Ṙ Rᵀ = ω̃.
        let w = (after.rotation - before.rotation) / (2.0 * h) * m.rotation.transpose();
        let omega = Vector3::new(w[(2, 1)], w[(0, 2)], w[(1, 0)]);
        assert!(
            largest((omega - m.angular_velocity).iter().copied()) < 1e-9,
            "t = {t}: {omega:?} {:?}",
            m.angular_velocity
        );
        assert!((w + w.transpose()).abs().max() < 1e-9, "Ṙ Rᵀ is skew at t = {t}");
        let alpha = fd(before.angular_velocity, after.angular_velocity);
        assert!(largest((alpha - m.angular_acceleration).iter().copied()) < 1e-9, "t = {t}");
        // R is a rotation to round-off.
        assert!((m.rotation * m.rotation.transpose() - Matrix3::identity()).abs().max() < 1e-15);
        assert!((m.rotation.determinant() - 1.0).abs() < 1e-15);
    }
}

#[test]
fn leg_rates_and_accelerations_are_the_finite_differences_of_the_lengths() {
    let tr = Trajectory::SHIPPED;
    // First differences over ±1e-5 s: truncation 1e-10 · |l'''| / 6 < 2e-11 (|l'''| ≲ 1 m/s³
    // here), round-off 2e-16 / 1e-5 = 2e-11. Second differences over ±1e-3 s: truncation
    // 1e-6 · |l''''| / 12 < 1e-7, round-off 4e-16 / 1e-6 = 4e-10.
    let (h1, h2) = (1e-5, 1e-3);
    for t in times() {
        let l = leg_lengths(&tr.at(t));
        let (b1, a1) = (leg_lengths(&tr.at(t - h1)), leg_lengths(&tr.at(t + h1)));
        let (b2, a2) = (leg_lengths(&tr.at(t - h2)), leg_lengths(&tr.at(t + h2)));
        for k in 0..LEGS {
            let rate = (a1[k][0] - b1[k][0]) / (2.0 * h1);
            let acceleration = (a2[k][0] - 2.0 * l[k][0] + b2[k][0]) / (h2 * h2);
            assert!((rate - l[k][1]).abs() < 1e-9, "leg {k} at t = {t}: {rate} against {l:?}");
            assert!((acceleration - l[k][2]).abs() < 1e-6, "leg {k} at t = {t}: {acceleration}");
        }
    }
}

#[test]
fn the_home_pose_has_six_equal_legs() {
    // The geometry is symmetric under turns of 120° and under reflection in the xz plane, which
    // maps each leg of a pair onto the other: all six lengths are equal at home.
    let legs = leg_lengths(&Trajectory { amplitude: [0.0; 6], frequency: [1.0; 6] }.at(0.0));
    // Leg from (cos 15°, −sin 15°, 0) to (0.5 cos 45°, −0.5 sin 45°, 1).
    let (a, b) = (15f64.to_radians(), 45f64.to_radians());
    let expected =
        ((0.5 * b.cos() - a.cos()).powi(2) + (a.sin() - 0.5 * b.sin()).powi(2) + 1.0).sqrt();
    for leg in legs {
        assert!((leg[0] - expected).abs() < 1e-15, "{legs:?} against {expected}");
        assert_eq!((leg[1], leg[2]), (0.0, 0.0));
    }
}

#[test]
fn the_baseline_follows_the_trajectory_at_1_khz() {
    let tr = Trajectory::SHIPPED;
    let start = tr.parameters(0.0);
    let mut fk = ForwardKinematics::new(
        0.0,
        Vector3::new(start[0][0], start[1][0], start[2][0]),
        Vector3::new(start[3][0], start[4][0], start[5][0]),
    );
    let mut iterations = 0;
    for k in 0..=2000 {
        let t = f64::from(k) * 1e-3;
        let m = tr.at(t);
        let legs = leg_lengths(&m);
        let report = fk.position(t, &legs.map(|l| l[0])).expect("the baseline converges");
        iterations += report.iterations;
        let twist = *fk.velocity(&legs.map(|l| l[1])).expect("after a position");
        let twist_dot = *fk.acceleration(&legs.map(|l| l[2])).expect("after a velocity");
        // Newton stops at max |Δl| ≤ 1e-12 m and J's condition number (σ_max / σ_min) stays
        // below 4.3 along this trajectory, so the pose is within about 1e-11 of the truth.
        let position = (fk.platform_position() - m.position).abs().max();
        let rotation = (fk.rotation() - m.rotation).abs().max();
        assert!(position < 1e-10 && rotation < 1e-10, "t = {t}: {position:e} m, {rotation:e}");
        // The twist is J⁻¹ l̇ at that pose: J errs by the pose error (about 1e-11) times its
        // derivatives (≲ 2 per m), |J⁻¹| ≲ 5 and |twist| ≲ 0.2, so the twist errs by about
        // 1e-11 · 2 · 5 · 0.2 = 2e-11; (a, α) likewise, their extra terms being as small.
        let v = twist.fixed_rows::<3>(0) - m.velocity;
        let w = twist.fixed_rows::<3>(3) - m.angular_velocity;
        assert!(v.abs().max() < 1e-10 && w.abs().max() < 1e-10, "t = {t}: {v:?} {w:?}");
        let a = twist_dot.fixed_rows::<3>(0) - m.acceleration;
        let alpha = twist_dot.fixed_rows::<3>(3) - m.angular_acceleration;
        assert!(a.abs().max() < 1e-10 && alpha.abs().max() < 1e-10, "t = {t}: {a:?} {alpha:?}");
    }
    // With the Taylor predictor the start is within h³/6 |x'''| ≈ 1e-10 of the pose, which one
    // Newton iteration brings to round-off: one iteration a period after the first.
    assert!(iterations <= 2001, "{iterations} iterations in 2001 periods");
}

#[test]
fn the_baseline_refuses_bad_input_and_keeps_its_pose() {
    let mut fk = ForwardKinematics::new(0.0, super::home_position(), Vector3::zeros());
    assert_eq!(fk.velocity(&[0.0; LEGS]), Err(Error::Order));
    let home = leg_lengths(&Trajectory::SHIPPED.at(0.0)).map(|l| l[0]);
    assert_eq!(fk.position(0.0, &home).map(|r| r.iterations), Ok(0));
    assert_eq!(fk.acceleration(&[0.0; LEGS]), Err(Error::Order));
    let mut nan = home;
    nan[3] = f64::NAN;
    assert_eq!(fk.position(1e-3, &nan), Err(Error::NotFinite));
    assert_eq!(fk.platform_position(), super::home_position());
    // No pose has these lengths: a platform attachment on its base attachment (a zero leg) is
    // within 1 + 2 = 3 m of every base attachment (platform diameter 1 m, base diameter 2 m),
    // so no leg can be 10 m long. Newton fails without a panic and the pose stays.
    let impossible = [10.0, 0.0, 10.0, 0.0, 10.0, 0.0];
    assert!(fk.position(2e-3, &impossible).is_err());
    assert_eq!(fk.platform_position(), super::home_position());
}
