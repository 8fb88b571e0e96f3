//! The body frame in Euler parameters: the rotation matrix A(p) and the matrix G(p) of the
//! angular velocity (thesis ch. 3). Validation (global points, the screw's origin), the
//! generic engine's primitives and the reports all take them from here; the symbolic
//! builder writes A(p) again as expressions, an independent derivation.

use nalgebra::{Matrix3, SMatrix, Vector3, Vector4};

/// The skew matrix ã with ã b = a × b.
#[must_use]
pub fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// The quadratic form A(p) = (e0² − eᵀe) I + 2 e eᵀ + 2 e0 ẽ (thesis eq. 3.18 written as
/// G Lᵀ, eq. 3.31). It is the rotation matrix when |p| = 1; the generic engine also
/// evaluates it at ṗ for the κ term of γ.
#[must_use]
pub fn rotation(p: &Vector4<f64>) -> Matrix3<f64> {
    let e0 = p[0];
    let e = Vector3::new(p[1], p[2], p[3]);
    Matrix3::identity() * (e0 * e0 - e.dot(&e)) + e * e.transpose() * 2.0 + skew(&e) * (2.0 * e0)
}

/// G(p) = [−e, e0 I + ẽ], 3×4 (thesis eq. 3.26); ω = 2 G ṗ in global components.
#[must_use]
pub fn g_matrix(p: &Vector4<f64>) -> SMatrix<f64, 3, 4> {
    let e = Vector3::new(p[1], p[2], p[3]);
    let mut g = SMatrix::<f64, 3, 4>::zeros();
    g.set_column(0, &(-e));
    g.fixed_view_mut::<3, 3>(0, 1).copy_from(&(Matrix3::identity() * p[0] + skew(&e)));
    g
}

/// P = r + A(p)·s', global, for a body placed at `r` with Euler parameters `p`.
#[must_use]
pub fn global_point(r: &Vector3<f64>, p: &Vector4<f64>, local: &Vector3<f64>) -> Vector3<f64> {
    r + rotation(p) * local
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A(p) of unit Euler parameters is nalgebra's rotation matrix of the same quaternion
    /// (an independent implementation), and G(p) Gᵀ(p) = I.
    #[test]
    fn rotation_matches_nalgebra_and_g_has_orthonormal_rows() {
        let p = Vector4::new(0.3, -0.5, 0.7, 0.1).normalize();
        let q = nalgebra::UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            p[0], p[1], p[2], p[3],
        ));
        // Both are a few products of O(1) numbers: agreement to 1e-15 is rounding only.
        assert!((rotation(&p) - *q.to_rotation_matrix().matrix()).amax() < 1e-15);
        let g = g_matrix(&p);
        assert!((g * g.transpose() - Matrix3::identity()).amax() < 1e-15);
    }
}
