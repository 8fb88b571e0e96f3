//! The Gough–Stewart platform of `examples/inputs/stewart.toml` in closed form: its geometry, a
//! smooth platform trajectory with exact derivatives, and the inverse kinematics of its six
//! U-P-S legs; [`baseline`] holds its forward kinematics written the way a motion-control
//! engineer writes them, for tests and benchmarks to compare the solvers against.
//!
//! Leg k joins the base attachment a_k (global, in the plane z = 0) to the platform attachment
//! b_k (platform frame, origin at the platform's centre). With the platform at position p and
//! orientation R (platform to global), velocity v, angular velocity ω, acceleration a and
//! angular acceleration α (all global), r_k = R b_k and
//!
//! - s_k = p + r_k − a_k, the leg length l_k = |s_k| and its direction n_k = s_k / l_k;
//! - ṡ_k = v + ω × r_k and l̇_k = n_k·ṡ_k = [n_kᵀ, (r_k × n_k)ᵀ] [v; ω];
//! - s̈_k = a + α × r_k + ω × (ω × r_k) and l̈_k = n_k·s̈_k + (|ṡ_k|² − l̇_k²) / l_k.
//!
//! The rows [n_kᵀ, (r_k × n_k)ᵀ] form the 6 × 6 Jacobian J of the leg lengths with respect to
//! the platform's twist (v, ω).

pub mod baseline;
pub mod control;
pub mod pose;
#[cfg(test)]
mod tests;

use std::fmt::Write as _;

use nalgebra::{Matrix3, Vector3};

/// Number of legs, and of input drivers (one per leg).
pub const LEGS: usize = 6;
/// Radius of the circle of base attachments (m).
pub const BASE_RADIUS: f64 = 1.0;
/// Radius of the circle of platform attachments (m).
pub const PLATFORM_RADIUS: f64 = 0.5;
/// Height of the platform's centre above the base in the home pose (m).
pub const HOME_HEIGHT: f64 = 1.0;
/// Half the angle between the two attachments of a pair, on the base and on the platform (°).
const HALF_SPREAD_DEGREES: f64 = 15.0;

/// The base attachment a_k of leg k (global, m): pairs at 0°, 120° and 240°, ±15° apart.
#[must_use]
pub fn base_point(k: usize) -> Vector3<f64> {
    let centre = 120.0 * (k / 2) as f64;
    let side = if k.is_multiple_of(2) { -HALF_SPREAD_DEGREES } else { HALF_SPREAD_DEGREES };
    on_circle(BASE_RADIUS, centre + side)
}

/// The platform attachment b_k of leg k (platform frame, m): pairs at 60°, 180° and 300°, ±15°
/// apart, so each base pair's legs lean towards the two neighbouring platform pairs.
#[must_use]
pub fn platform_point(k: usize) -> Vector3<f64> {
    let centre = 120.0 * (k / 2) as f64;
    let side =
        if k.is_multiple_of(2) { -60.0 + HALF_SPREAD_DEGREES } else { 60.0 - HALF_SPREAD_DEGREES };
    on_circle(PLATFORM_RADIUS, centre + side)
}

/// The point of the circle of `radius` about the z axis at `degrees` from the x axis.
fn on_circle(radius: f64, degrees: f64) -> Vector3<f64> {
    let (sin, cos) = degrees.to_radians().sin_cos();
    Vector3::new(radius * cos, radius * sin, 0.0)
}

/// The platform's centre in the home pose (global, m); its orientation there is the identity.
#[must_use]
pub fn home_position() -> Vector3<f64> {
    Vector3::new(0.0, 0.0, HOME_HEIGHT)
}

/// A platform pose with its first and second time derivatives, all in global components.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// Position p of the platform's centre (m).
    pub position: Vector3<f64>,
    /// Orientation R: platform components to global ones.
    pub rotation: Matrix3<f64>,
    /// Velocity v = ṗ (m/s).
    pub velocity: Vector3<f64>,
    /// Angular velocity ω, Ṙ = ω̃ R (rad/s).
    pub angular_velocity: Vector3<f64>,
    /// Acceleration a = p̈ (m/s²).
    pub acceleration: Vector3<f64>,
    /// Angular acceleration α = ω̇ (rad/s²).
    pub angular_acceleration: Vector3<f64>,
}

/// The orientation R = R_z(ψ) R_y(θ) R_x(φ) of the ZYX angles `[φ, θ, ψ]` (roll, pitch, yaw)
/// and the matrix E whose columns are the axes of the three rotations in global components,
/// so that ω = E [φ̇, θ̇, ψ̇] (columns R_z R_y x̂, R_z ŷ, ẑ).
#[must_use]
pub fn zyx(angles: &Vector3<f64>) -> (Matrix3<f64>, Matrix3<f64>) {
    let (sx, cx) = angles.x.sin_cos();
    let (sy, cy) = angles.y.sin_cos();
    let (sz, cz) = angles.z.sin_cos();
    let rotation = Matrix3::new(
        cz * cy,
        cz * sy * sx - sz * cx,
        cz * sy * cx + sz * sx,
        sz * cy,
        sz * sy * sx + cz * cx,
        sz * sy * cx - cz * sx,
        -sy,
        cy * sx,
        cy * cx,
    );
    let axes = Matrix3::new(cz * cy, -sz, 0.0, sz * cy, cz, 0.0, -sy, 0.0, 1.0);
    (rotation, axes)
}

/// A platform trajectory about the home pose: each pose parameter (x, y, z in m; roll, pitch,
/// yaw in rad, as the ZYX angles of [`zyx`]) is its home value plus A_j sin(w_j t).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Trajectory {
    /// A_j for x, y, z (m) and roll, pitch, yaw (rad).
    pub amplitude: [f64; 6],
    /// w_j (rad/s).
    pub frequency: [f64; 6],
}

impl Trajectory {
    /// The shipped trajectory: a few centimetres and a few degrees, at 1.5 to 3 rad/s, so that
    /// no two parameters share a period and every leg moves differently.
    pub const SHIPPED: Self = Self {
        amplitude: [0.03, 0.02, 0.04, 0.05, 0.04, 0.06],
        frequency: [2.0, 2.5, 1.5, 3.0, 2.2, 1.8],
    };

    /// The pose parameters x, y, z, φ, θ, ψ at time t with their first and second derivatives.
    #[must_use]
    pub fn parameters(&self, t: f64) -> [[f64; 3]; 6] {
        let home = [0.0, 0.0, HOME_HEIGHT, 0.0, 0.0, 0.0];
        std::array::from_fn(|j| {
            let (a, w) = (self.amplitude[j], self.frequency[j]);
            let (sin, cos) = (w * t).sin_cos();
            [home[j] + a * sin, a * w * cos, -a * w * w * sin]
        })
    }

    /// The platform's motion at time t.
    ///
    /// With ZYX angles, ω = ψ̇ u_z + θ̇ u_y + φ̇ u_x for the axes u_z = ẑ, u_y = R_z ŷ and
    /// u_x = R_z R_y x̂; u̇_y = ψ̇ ẑ × u_y and u̇_x = (ψ̇ ẑ + θ̇ u_y) × u_x, so
    /// α = ψ̈ u_z + θ̈ u_y + θ̇ u̇_y + φ̈ u_x + φ̇ u̇_x.
    #[must_use]
    pub fn at(&self, t: f64) -> Motion {
        let q = self.parameters(t);
        let [x, y, z, roll, pitch, yaw] = q;
        let (rotation, axes) = zyx(&Vector3::new(roll[0], pitch[0], yaw[0]));
        let (ux, uy, uz) = (axes.column(0).into_owned(), axes.column(1).into_owned(), Vector3::z());
        let angular_velocity = ux * roll[1] + uy * pitch[1] + uz * yaw[1];
        let uy_dot = (uz * yaw[1]).cross(&uy);
        let ux_dot = (uz * yaw[1] + uy * pitch[1]).cross(&ux);
        let angular_acceleration =
            uz * yaw[2] + uy * pitch[2] + uy_dot * pitch[1] + ux * roll[2] + ux_dot * roll[1];
        Motion {
            position: Vector3::new(x[0], y[0], z[0]),
            rotation,
            velocity: Vector3::new(x[1], y[1], z[1]),
            angular_velocity,
            acceleration: Vector3::new(x[2], y[2], z[2]),
            angular_acceleration,
        }
    }
}

/// The six leg lengths of a platform motion with their rates and accelerations,
/// `[[l_k, l̇_k, l̈_k]; 6]` (m, m/s, m/s²), by the closed forms of the module docs.
#[must_use]
pub fn leg_lengths(motion: &Motion) -> [[f64; 3]; LEGS] {
    let (w, alpha) = (motion.angular_velocity, motion.angular_acceleration);
    std::array::from_fn(|k| {
        let r = motion.rotation * platform_point(k);
        let s = motion.position + r - base_point(k);
        let l = s.norm();
        let n = s / l;
        let s_dot = motion.velocity + w.cross(&r);
        let s_ddot = motion.acceleration + alpha.cross(&r) + w.cross(&w.cross(&r));
        let l_dot = n.dot(&s_dot);
        [l, l_dot, n.dot(&s_ddot) + (s_dot.norm_squared() - l_dot * l_dot) / l]
    })
}

/// An inputs file for `mechgen solve examples/inputs/stewart.toml --inputs FILE` (the format
/// of docs/format.md): a comment saying how it was made, the header
/// `t,leg1,leg1.dot,leg1.ddot,…,leg6.ddot`, and one row per time `k · step` for k = 0 to
/// `steps`, the leg lengths of `trajectory` written so that they read back exactly.
#[must_use]
pub fn inputs_csv(trajectory: &Trajectory, step: f64, steps: usize, comment: &str) -> String {
    let mut text = String::new();
    for line in comment.lines() {
        let _ = writeln!(text, "# {line}");
    }
    text.push('t');
    for k in 1..=LEGS {
        let _ = write!(text, ",leg{k},leg{k}.dot,leg{k}.ddot");
    }
    text.push('\n');
    for i in 0..=steps {
        let t = i as f64 * step;
        let _ = write!(text, "{t:?}");
        for leg in leg_lengths(&trajectory.at(t)) {
            let _ = write!(text, ",{:?},{:?},{:?}", leg[0], leg[1], leg[2]);
        }
        text.push('\n');
    }
    text
}
