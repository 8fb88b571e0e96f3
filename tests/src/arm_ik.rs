//! Inverse kinematics of a spatial 3R arm as a description (issue 14, point 7):
//! `examples/inputs/arm3r_ik.toml` takes its tool point's x, y and z as inputs, and
//! `examples/inputs/arm3r_tool_path.csv` is the tool path of a known joint trajectory, made by
//! the closed-form forward kinematics below. `solve --inputs` must report that trajectory as
//! the joints' angles, rates and accelerations, and the forward kinematics of what it reports
//! must give the tool path back; so must the committed generated module `generated::arm3r_ik`
//! driven row by row through `runtime::Solver::advance_with`, as a control loop would.
//!
//! `UPDATE_EXPECT=1 cargo test -p tests arm_ik` rewrites the CSV from the closed form.

use crate::harness::mechgen;
use std::path::PathBuf;

/// Upper arm and forearm lengths, and the shoulder's height above the base (m).
const UPPER: f64 = 1.0;
const FORE: f64 = 0.8;
const SHOULDER: f64 = 1.0;

/// The known joint trajectory: θ_k(t) = c + A sin(w t + φ) as (c, A, w, φ), for J1, J2, J3.
/// J3 stays in [−0.4, 0.2], far from the stretched arm at −π/2, and the wrist's distance from
/// the base axis stays above 0.5 m (both checked by `the_path_keeps_clear_of_the_singularities`).
const TRAJECTORY: [(f64, f64, f64, f64); 3] =
    [(0.1, 0.6, 1.2, 0.0), (0.05, 0.2, 2.0, 0.3), (-0.1, -0.3, 1.7, 0.0)];

/// The path's time points: every 0.02 s from 0 to 2 s.
const ROWS: usize = 101;

fn time(k: usize) -> f64 {
    // k / 50 is correctly rounded, so the file's t reads as written.
    k as f64 / 50.0
}

/// A scalar's value, rate and acceleration.
type Motion = [f64; 3];

/// The joint angles of the known trajectory at `t`, with their rates and accelerations.
fn joints(t: f64) -> [Motion; 3] {
    TRAJECTORY.map(|(c, a, w, phase)| {
        let (s, co) = (w * t + phase).sin_cos();
        [c + a * s, a * w * co, -a * w * w * s]
    })
}

/// The tool point's position, velocity and acceleration (rows) for joint motions `j`, in closed
/// form: with φ = θ2 + θ3, the reach ρ = u cos θ2 − f sin φ and the height
/// h = 1 − u sin θ2 − f cos φ in the arm's vertical plane, the tool is (ρ cos θ1, ρ sin θ1, h);
/// its rates follow by the product and chain rules.
fn forward(j: &[Motion; 3]) -> [[f64; 3]; 3] {
    let ([t1, d1, a1], [t2, d2, a2], [t3, d3, a3]) = (j[0], j[1], j[2]);
    let (phi, dphi, aphi) = (t2 + t3, d2 + d3, a2 + a3);
    let ((s1, c1), (s2, c2), (sp, cp)) = (t1.sin_cos(), t2.sin_cos(), phi.sin_cos());
    let rho = UPPER * c2 - FORE * sp;
    let drho = -UPPER * s2 * d2 - FORE * cp * dphi;
    let arho = -UPPER * (c2 * d2 * d2 + s2 * a2) - FORE * (cp * aphi - sp * dphi * dphi);
    let h = SHOULDER - UPPER * s2 - FORE * cp;
    let dh = -UPPER * c2 * d2 + FORE * sp * dphi;
    let ah = -UPPER * (c2 * a2 - s2 * d2 * d2) + FORE * (sp * aphi + cp * dphi * dphi);
    [
        [rho * c1, rho * s1, h],
        [drho * c1 - rho * s1 * d1, drho * s1 + rho * c1 * d1, dh],
        [
            arho * c1 - 2.0 * drho * s1 * d1 - rho * (c1 * d1 * d1 + s1 * a1),
            arho * s1 + 2.0 * drho * c1 * d1 + rho * (c1 * a1 - s1 * d1 * d1),
            ah,
        ],
    ]
}

fn example(name: &str) -> PathBuf {
    codegen::sync::workspace_root().join("examples/inputs").join(name)
}

/// The CSV's text for the known trajectory.
fn tool_path_csv() -> String {
    let mut text = String::from(concat!(
        "# Tool path of examples/inputs/arm3r_ik.toml (m, m/s, m/s^2): the arm's closed-form\n",
        "# forward kinematics for the joint trajectory (rad) J1 = 0.1 + 0.6 sin(1.2 t),\n",
        "# J2 = 0.05 + 0.2 sin(2 t + 0.3), J3 = -0.1 - 0.3 sin(1.7 t), every 0.02 s for 2 s.\n",
        "# Written and checked by tests/src/arm_ik.rs (UPDATE_EXPECT=1 rewrites it).\n",
        "t,tool_x,tool_x.dot,tool_x.ddot,tool_y,tool_y.dot,tool_y.ddot,tool_z,tool_z.dot,tool_z.ddot\n",
    ));
    for k in 0..ROWS {
        let t = time(k);
        let [r, v, a] = forward(&joints(t));
        let cells: Vec<String> =
            (0..3).flat_map(|c| [r[c], v[c], a[c]]).map(|x| format!("{x:?}")).collect();
        text.push_str(&format!("{t:?},{}\n", cells.join(",")));
    }
    text
}

/// The committed CSV's rows: t, then (x, ẋ, ẍ, y, …) as in its header.
fn tool_path_rows() -> Vec<[f64; 10]> {
    let text = std::fs::read_to_string(example("arm3r_tool_path.csv")).expect("the tool path");
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header = lines.next().expect("a header");
    assert_eq!(
        header,
        "t,tool_x,tool_x.dot,tool_x.ddot,tool_y,tool_y.dot,tool_y.ddot,tool_z,tool_z.dot,tool_z.ddot"
    );
    lines
        .map(|l| {
            let cells: Vec<f64> = l.split(',').map(|c| c.parse().expect("a number")).collect();
            cells.try_into().expect("ten cells")
        })
        .collect()
}

#[test]
fn the_forward_rates_are_the_derivatives_of_the_forward_positions() {
    // Central differences of the closed form's position and velocity against its velocity and
    // acceleration, so that the reference itself is checked.
    let h = 1e-4;
    for k in 0..ROWS {
        let t = time(k);
        let [_, v, a] = forward(&joints(t));
        let (before, after) = (forward(&joints(t - h)), forward(&joints(t + h)));
        for c in 0..3 {
            let fd_v = (after[0][c] - before[0][c]) / (2.0 * h);
            let fd_a = (after[1][c] - before[1][c]) / (2.0 * h);
            // Truncation h²/6 times a third derivative of at most about 10 (rates of order 1
            // rad/s on unit links): 2e-8, and rounding ε/h: 2e-12; 1e-6 bounds both while a
            // wrong term of the product rule is off by O(0.1) or more.
            assert!((fd_v - v[c]).abs() < 1e-6, "t {t}: v[{c}] {} vs {fd_v}", v[c]);
            assert!((fd_a - a[c]).abs() < 1e-6, "t {t}: a[{c}] {} vs {fd_a}", a[c]);
        }
    }
}

#[test]
fn the_forward_kinematics_places_the_tool_as_the_description_does() {
    // At zero angles the tool is the point's local coordinates in the description (every frame
    // is the global one there); a quarter turn of J1 alone swings it to +y, and a quarter turn
    // of J2 alone (x towards −z) brings the upper arm down with the forearm along −x.
    let at = |a: [f64; 3]| forward(&a.map(|x| [x, 0.0, 0.0]))[0];
    let quarter = std::f64::consts::FRAC_PI_2;
    for (angles, want) in [
        ([0.0, 0.0, 0.0], [1.0, 0.0, 0.2]),
        ([quarter, 0.0, 0.0], [0.0, 1.0, 0.2]),
        ([0.0, quarter, 0.0], [-0.8, 0.0, 0.0]),
    ] {
        let got = at(angles);
        for c in 0..3 {
            // Closed-form values of sin and cos at 0 and π/2 are exact to a few ulps.
            assert!((got[c] - want[c]).abs() < 1e-15, "{angles:?}: {got:?}");
        }
    }
}

#[test]
fn the_path_keeps_clear_of_the_singularities() {
    for k in 0..ROWS {
        let [t1, t2, t3] = joints(time(k)).map(|m| m[0]);
        let reach = UPPER * t2.cos() - FORE * (t2 + t3).sin();
        // The tool Jacobian's determinant is ρ u f cos θ3 (ρ the reach): the arm is singular
        // stretched or folded (θ3 = ∓π/2) and with the tool over the base axis (ρ = 0).
        assert!(reach > 0.5, "t {}: reach {reach}", time(k));
        assert!(t3.cos() > 0.9, "t {}: J3 = {t3}", time(k));
        assert!(t1.abs() < 1.0, "t {}: J1 = {t1} stays in (−π, π]", time(k));
        // The smallest singular value of ∂tool/∂θ: J1's column (length ρ) is orthogonal to the
        // plane of J2's and J3's, whose 2×2 block in (ρ, h) has determinant −u f cos θ3.
        let (s2, c2, sp, cp) = (t2.sin(), t2.cos(), (t2 + t3).sin(), (t2 + t3).cos());
        let block = [[-UPPER * s2 - FORE * cp, -FORE * cp], [-UPPER * c2 + FORE * sp, FORE * sp]];
        let frobenius = block.iter().flatten().map(|x| x * x).sum::<f64>();
        let det = block[0][0] * block[1][1] - block[0][1] * block[1][0];
        let planar = ((frobenius - (frobenius * frobenius - 4.0 * det * det).sqrt()) / 2.0).sqrt();
        assert!(reach.min(planar) > 0.4, "t {}: σ_min {}", time(k), reach.min(planar));
    }
}

#[test]
fn the_tool_path_file_is_the_forward_kinematics_of_the_trajectory() {
    let path = example("arm3r_tool_path.csv");
    if std::env::var_os("UPDATE_EXPECT").is_some_and(|v| v == "1") {
        std::fs::write(&path, tool_path_csv()).expect("write the tool path");
    }
    let rows = tool_path_rows();
    assert_eq!(rows.len(), ROWS);
    for (k, row) in rows.iter().enumerate() {
        assert_eq!(row[0], time(k), "row {k}");
        let [r, v, a] = forward(&joints(row[0]));
        for c in 0..3 {
            // The file holds the closed form's values in shortest round-trip form; 1e-14 allows
            // for another platform's sin and cos being an ulp or two away.
            for (d, want) in [r[c], v[c], a[c]].into_iter().enumerate() {
                let got = row[1 + 3 * c + d];
                assert!(
                    (got - want).abs() < 1e-14,
                    "t {}: column {} {got} vs {want}",
                    row[0],
                    1 + 3 * c + d
                );
            }
        }
    }
}

/// `solve --inputs` of the arm on `engine`, as JSON.
fn solve(engine: &str) -> serde_json::Value {
    let (arm, path) = (example("arm3r_ik.toml"), example("arm3r_tool_path.csv"));
    let (arm, path) = (arm.display().to_string(), path.display().to_string());
    let (code, out, err) =
        mechgen(&["solve", &arm, "--inputs", &path, "--engine", engine, "--format", "json"]);
    assert_eq!(code, 0, "{engine}: {err}");
    serde_json::from_str(&out).unwrap_or_else(|e| panic!("{engine}: {e}: {out}"))
}

fn triple(v: &serde_json::Value) -> [f64; 3] {
    let a = v.as_array().expect("three numbers");
    [0, 1, 2].map(|c| a[c].as_f64().expect("a number"))
}

/// Checks the joints of a solve against the known trajectory and their forward kinematics
/// against the tool path; returns the largest errors (angle, rate, acceleration, tool).
fn check_against_the_trajectory(v: &serde_json::Value, engine: &str) -> [f64; 4] {
    assert!(v["error"].is_null(), "{engine}: {}", v["error"]);
    let steps = v["steps"].as_array().expect("steps");
    let rows = tool_path_rows();
    assert_eq!(steps.len(), rows.len(), "{engine}: one step per row of the path");
    let mut worst = [0.0f64; 4];
    for (step, row) in steps.iter().zip(&rows) {
        let t = step["t"].as_f64().expect("t");
        assert_eq!(t, row[0], "{engine}: the rows are the time points");
        let want = joints(t);
        let mut got = [[0.0; 3]; 3];
        for (k, name) in ["J1", "J2", "J3"].into_iter().enumerate() {
            let joint = &step["joints"][name];
            for (d, key) in ["angle", "angle_dot", "angle_ddot"].into_iter().enumerate() {
                got[k][d] = joint[key].as_f64().unwrap_or_else(|| panic!("{engine}: {name}.{key}"));
                worst[d] = worst[d].max((got[k][d] - want[k][d]).abs());
            }
        }
        // Newton stops at max |Φ_i| ≤ 1e-12 (the description's tolerance) and the tool
        // Jacobian's smallest singular value stays above 0.4 on the path (checked above), so
        // the tool rows leave the angles within √3 · 1e-12 / 0.4 ≈ 4e-12 rad, and the joint
        // rows (unit axes and lever arms) about as much. The rates and accelerations are solved
        // by LU from Φ_q at that configuration (condition about 1e2 on unit links, rates of
        // order 1), so they carry the same error plus about 1e-14. 5e-11 is ten times that,
        // while a wrong branch, a sign or a missing ν or γ term is off by 1e-3 or more.
        for (k, name) in ["J1", "J2", "J3"].into_iter().enumerate() {
            for d in 0..3 {
                let err = (got[k][d] - want[k][d]).abs();
                assert!(err < 5e-11, "{engine} t {t}: {name}[{d}] {} vs {}", got[k][d], want[k][d]);
            }
        }
        // The forward kinematics of the reported joints is the tool path that was fed in, and
        // the tool point the solve reports is that path too: the bound above through links of
        // at most 1.8 m and products with rates of order 1 (such as 2 ρ̇ θ̇1), 2e-10.
        let fk = forward(&got);
        let tool = &step["points"]["tool"];
        let reported = [triple(&tool["r"]), triple(&tool["v"]), triple(&tool["a"])];
        for c in 0..3 {
            for d in 0..3 {
                let path = row[1 + 3 * c + d];
                worst[3] = worst[3].max((fk[d][c] - path).abs());
                assert!((fk[d][c] - path).abs() < 2e-10, "{engine} t {t}: FK [{d}][{c}]");
                assert!((reported[d][c] - path).abs() < 2e-10, "{engine} t {t}: tool [{d}][{c}]");
            }
        }
    }
    worst
}

#[test]
fn both_engines_recover_the_joint_trajectory_from_the_tool_path() {
    for engine in ["generic", "generated"] {
        let v = solve(engine);
        assert_eq!(v["engine"], engine);
        let worst = check_against_the_trajectory(&v, engine);
        eprintln!("{engine}: largest errors (angle, rate, acceleration, tool) {worst:?}");
    }
}

#[test]
fn compare_replays_the_tool_path_on_both_engines_and_they_agree() {
    let (arm, path) = (example("arm3r_ik.toml"), example("arm3r_tool_path.csv"));
    let (arm, path) = (arm.display().to_string(), path.display().to_string());
    let (code, out, err) = mechgen(&["compare", &arm, "--inputs", &path, "--format", "json"]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap_or_else(|e| panic!("{e}: {out}"));
    assert_eq!(v["steps"].as_u64(), Some(ROWS as u64), "one step per row of the path");
    assert_eq!(v["disagree"], serde_json::json!([]), "{v}");
    let diffs = v["max_abs_diff"].as_object().expect("max_abs_diff");
    assert!(diffs.len() >= 11, "every quantity compared: {diffs:?}");
    for (quantity, d) in diffs {
        let d = d.as_f64().expect("a number");
        // Each engine is within the bound of the trajectory test above of the true solution
        // (a few 1e-12 on positions and Euler parameters of unit-sized bodies, the same
        // relative to rates and accelerations of order 1), so they differ by at most twice
        // that; 1e-10 leaves a margin of ten and flags any real disagreement.
        assert!(d < 1e-10, "{quantity}: {d:e}");
    }
}

#[test]
fn the_generated_module_follows_the_tool_path_through_advance_with() {
    use generated::arm3r_ik::joint_coordinate::{J1_ANGLE, J2_ANGLE, J3_ANGLE};
    use generated::arm3r_ik::{self as arm, Arm3rIk, Inputs};
    use runtime::input::Input;
    use runtime::{NewtonOptions, Solver};

    let mut solver = Solver::new(Arm3rIk::new(0.0, &arm::INITIAL_INPUTS), arm::Q0);
    solver.set_options(NewtonOptions { tolerance: arm::TOLERANCE, ..NewtonOptions::DEFAULT });
    let mut worst = 0.0f64;
    for row in tool_path_rows() {
        let t = row[0];
        let input = |c: usize| Input {
            value: row[1 + 3 * c],
            rate: row[2 + 3 * c],
            acceleration: row[3 + 3 * c],
        };
        let inputs = Inputs { tool_x: input(0), tool_y: input(1), tool_z: input(2) };
        solver.advance_with(t, &inputs.to_array()).unwrap_or_else(|e| panic!("t {t}: {e}"));
        let mut coordinates = [[0.0; 3]; arm::JOINT_COORDINATES];
        arm::joint_coordinates(solver.q(), solver.qd(), solver.qdd(), t, &inputs, &mut coordinates);
        let want = joints(t);
        let angles = [J1_ANGLE, J2_ANGLE, J3_ANGLE];
        for (k, name) in angles.into_iter().enumerate() {
            for d in 0..3 {
                let err = (coordinates[name][d] - want[k][d]).abs();
                worst = worst.max(err);
                // The bound of the command-line runs above: the same tolerance and path.
                assert!(
                    err < 5e-11,
                    "t {t}: J{} [{d}] {} vs {}",
                    k + 1,
                    coordinates[name][d],
                    want[k][d]
                );
            }
        }
    }
    eprintln!("advance_with: largest joint error {worst:e}");
}
