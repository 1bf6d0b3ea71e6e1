//! 3 × 3 matrices as row-major arrays ([`Mat3`]), with the arithmetic done by
//! nalgebra: `M x`, `A B` and `M⁻¹` (with a singularity check relative to the
//! matrix's scale). A leaf module: the colour spaces, chromatic adaptation
//! and chart code all use it, it uses none of them.
//!
//! ```
//! use lucent_colour::matrix::{mat3_inverse, mat3_mul};
//! let m = [[2.0, 0.0, 0.0], [0.0, 4.0, 0.0], [1.0, 0.0, 1.0]];
//! let inv = mat3_inverse(&m).unwrap();
//! assert_eq!(inv, [[0.5, 0.0, 0.0], [0.0, 0.25, 0.0], [-0.5, 0.0, 1.0]]);
//! assert_eq!(mat3_mul(&m, &inv), [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]);
//! ```

use crate::{ColourError, Mat3};
use nalgebra::{Matrix3, Vector3};

/// The nalgebra matrix of a row-major [`Mat3`].
pub fn to_matrix3(m: &Mat3) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| m[i][j])
}

/// The row-major [`Mat3`] of an nalgebra matrix.
pub fn from_matrix3(m: &Matrix3<f64>) -> Mat3 {
    std::array::from_fn(|i| std::array::from_fn(|j| m[(i, j)]))
}

/// `M x`.
pub fn mat3_vec(m: &Mat3, x: [f64; 3]) -> [f64; 3] {
    (to_matrix3(m) * Vector3::from(x)).into()
}

/// `A B`.
pub fn mat3_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    from_matrix3(&(to_matrix3(a) * to_matrix3(b)))
}

/// `M⁻¹`; an error if `M` is not finite or singular (|det M| at most 10⁻¹⁴
/// times the cube of its largest entry).
pub fn mat3_inverse(m: &Mat3) -> Result<Mat3, ColourError> {
    let a = to_matrix3(m);
    let det = a.determinant();
    let scale = a.amax();
    let singular = || ColourError::Singular { what: "3 × 3 matrix".into(), reason: format!("determinant {det:e}") };
    if !det.is_finite() || scale == 0.0 || det.abs() <= 1e-14 * scale.powi(3) {
        return Err(singular());
    }
    a.try_inverse().map(|inv| from_matrix3(&inv)).ok_or_else(singular)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The inverse of the sRGB → XYZ matrix of IEC 61966-2-1:1999 (4 digits) is the standard's own XYZ → sRGB
    /// matrix to its 4 digits (an independent reference: the standard prints both).
    #[test]
    fn inverse_of_the_srgb_matrix_is_the_standards_other_matrix() {
        let to_xyz = [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]];
        let from_xyz = [[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.2040, 1.0570]];
        let inv = mat3_inverse(&to_xyz).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                assert!((inv[i][j] - from_xyz[i][j]).abs() < 6e-4, "[{i}][{j}]: {} vs {}", inv[i][j], from_xyz[i][j]);
            }
        }
    }

    /// M x and A B by the definition, written out for one case; singular and non-finite matrices are refused.
    #[test]
    fn products_follow_the_definition_and_singular_matrices_are_refused() {
        let a = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 10.0]];
        let b = [[0.5, -1.0, 0.0], [2.0, 0.25, 1.0], [-3.0, 0.0, 4.0]];
        assert_eq!(mat3_vec(&a, [1.0, -1.0, 2.0]), [5.0, 11.0, 19.0]);
        let ab = mat3_mul(&a, &b);
        assert_eq!(ab[0], [0.5 + 4.0 - 9.0, -1.0 + 0.5, 2.0 + 12.0]);
        assert_eq!(ab[2], [3.5 + 16.0 - 30.0, -7.0 + 2.0, 8.0 + 40.0]);
        let inv = mat3_inverse(&a).unwrap();
        let id = mat3_mul(&a, &inv);
        for (i, row) in id.iter().enumerate() {
            for (j, v) in row.iter().enumerate() {
                assert!((v - f64::from(u8::from(i == j))).abs() < 1e-12, "A A⁻¹ [{i}][{j}] = {v}");
            }
        }
        let singular = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]];
        assert!(matches!(mat3_inverse(&singular), Err(ColourError::Singular { .. })));
        assert!(mat3_inverse(&[[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]).is_err());
        assert!(mat3_inverse(&[[0.0; 3]; 3]).is_err());
    }
}
