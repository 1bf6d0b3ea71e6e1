//! Rigid poses in OpenCV's convention: the board (or any object) frame to the
//! camera frame, `x_cam = R · x_board + t` (metres; camera axes x right,
//! y down, z forward), and rotation vectors (axis × angle, radians;
//! Rodrigues' formula) by nalgebra's exponential map. A leaf module, used by
//! [`crate::cv`] (PnP), [`crate::calibrate`] and [`crate::scene`] (the
//! renderer's convention).
//!
//! ```
//! use lucent_calib::pose::Pose;
//! // A quarter turn about the camera's z, then 0.5 m forward.
//! let pose = Pose::from_rvec_tvec([0.0, 0.0, std::f64::consts::FRAC_PI_2], [0.0, 0.0, 0.5]);
//! let p = pose.to_camera([0.1, 0.0, 0.0]);
//! assert!(p[0].abs() < 1e-15 && (p[1] - 0.1).abs() < 1e-15 && p[2] == 0.5);
//! assert!((pose.camera_centre_in_board()[2] + 0.5).abs() < 1e-15);
//! ```

use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

pub type Mat3 = [[f64; 3]; 3];
pub type Mat4 = [[f64; 4]; 4];

pub(crate) fn to_na(a: &Mat3) -> Matrix3<f64> {
    Matrix3::from_fn(|r, c| a[r][c])
}

pub(crate) fn from_na(a: &Matrix3<f64>) -> Mat3 {
    std::array::from_fn(|r| std::array::from_fn(|c| a[(r, c)]))
}

pub(crate) fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    from_na(&(to_na(a) * to_na(b)))
}

pub(crate) fn mat_vec(a: &Mat3, v: [f64; 3]) -> [f64; 3] {
    (to_na(a) * Vector3::from(v)).into()
}

pub(crate) fn transpose(a: &Mat3) -> Mat3 {
    from_na(&to_na(a).transpose())
}

/// Rotation matrix of a rotation vector (axis × angle in radians; Rodrigues),
/// by nalgebra's exponential map.
pub fn rodrigues(r: [f64; 3]) -> Mat3 {
    from_na(Rotation3::new(Vector3::from(r)).matrix())
}

/// Rotation vector of a rotation matrix (inverse of [`rodrigues`]): through
/// nalgebra's unit quaternion (Shepperd's method, stable near π), then
/// angle = 2 atan2(|v|, w) with w ≥ 0, which keeps small angles exact.
pub fn rotation_vector(m: &Mat3) -> [f64; 3] {
    let q = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(to_na(m)));
    let (w, v) = (q.w, q.imag());
    let (w, v) = if w < 0.0 { (-w, -v) } else { (w, v) };
    let s = v.norm();
    if s == 0.0 {
        return [0.0; 3];
    }
    (v * (2.0 * s.atan2(w) / s)).into()
}

/// OpenCV pose of the board: `x_cam = rotation · x_board + translation_m`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Pose {
    pub rotation: Mat3,
    pub translation_m: [f64; 3],
}

impl Pose {
    /// From OpenCV's rvec (radians) and tvec (metres).
    pub fn from_rvec_tvec(rvec: [f64; 3], tvec: [f64; 3]) -> Self {
        Self { rotation: rodrigues(rvec), translation_m: tvec }
    }

    /// OpenCV's rvec.
    pub fn rvec(&self) -> [f64; 3] {
        rotation_vector(&self.rotation)
    }

    /// Board point → camera frame (OpenCV axes).
    pub fn to_camera(&self, p_board: [f64; 3]) -> [f64; 3] {
        let r = mat_vec(&self.rotation, p_board);
        std::array::from_fn(|k| r[k] + self.translation_m[k])
    }

    /// The camera's centre in board coordinates, −Rᵀ t.
    pub fn camera_centre_in_board(&self) -> [f64; 3] {
        mat_vec(&transpose(&self.rotation), self.translation_m).map(|v| -v)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rodrigues_round_trips_including_near_pi() {
        for r in [
            [0.1, -0.2, 0.3],
            [0.0, 0.0, 0.0],
            [2.0, 1.0, -0.5],
            [0.0, std::f64::consts::PI - 1e-9, 0.0],
            [1e-8, 0.0, 0.0],
        ] {
            let back = rotation_vector(&rodrigues(r));
            for k in 0..3 {
                assert!((back[k] - r[k]).abs() < 1e-7, "{r:?} → {back:?}");
            }
            let m = rodrigues(r);
            let mtm = mat_mul(&transpose(&m), &m);
            for (a, row) in mtm.iter().enumerate() {
                for (b, v) in row.iter().enumerate() {
                    assert!((v - if a == b { 1.0 } else { 0.0 }).abs() < 1e-12);
                }
            }
        }
    }
}
