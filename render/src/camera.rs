//! The renderer's camera: a pinhole with calibrated intrinsics, optionally
//! with the calibrated lens distortion (docs/method.md §5, §6).
//!
//! # Conventions
//!
//! Intrinsics are OpenCV's: focal lengths `fx`, `fy` and principal point
//! `cx`, `cy` in pixels, **the centre of the top-left pixel at (0, 0)**, v
//! down. A pixel (i, j) covers the image points [i − ½, i + ½) × [j − ½, j + ½),
//! and a camera sample (u₁, u₂) ∈ [0, 1)² lands at (i − ½ + u₁, j − ½ + u₂):
//! the pixel value is the mean radiance over its square (a box filter).
//!
//! The image point (x, y) becomes the normalised point
//! ((x − cx)/fx, (y − cy)/fy) = (x_d, y_d). Without distortion this is the
//! ray's direction in OpenCV camera axes (x right, y down, z forward),
//! (x_d, y_d, 1). With [`Distortion`] (Brown–Conrady, OpenCV's k1, k2, p1,
//! p2, k3), (x_d, y_d) is the *distorted* point and the ray goes through the
//! undistorted (x_u, y_u) that distorts onto it, found by OpenCV's fixed-point
//! iteration (`cv::undistortPoints`), run to convergence (< 10⁻¹⁴) — so the
//! render matches the raw photo's geometry without resampling the photo.
//!
//! The camera-to-world matrix is the renderer's (see `lucent_calib::scene`):
//! camera x right, **y up, looking along −z**; the OpenCV direction
//! (x, y, z) is (x, −y, −z) in those axes. Metres, world z up.
//!
//! ```
//! use glam::DVec3;
//! use lucent_render::camera::Camera;
//! // 0.5 m above the origin looking straight down (camera −z = world −z).
//! let id = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.5], [0.0, 0.0, 0.0, 1.0]];
//! let cam = Camera::new(64, 48, [100.0, 100.0, 31.5, 23.5], id, None).unwrap();
//! // The centre of the image (between the four middle pixels) looks along −z.
//! let (o, d) = cam.ray(31, 23, [1.0, 1.0]);
//! assert_eq!(o, DVec3::new(0.0, 0.0, 0.5));
//! assert!((d - DVec3::new(0.0, 0.0, -1.0)).length() < 1e-12);
//! ```

use glam::{DMat3, DVec3};
use thiserror::Error;

/// The largest image side a render makes, pixels.
pub const MAX_IMAGE_SIDE: usize = 32_768;
/// The most pixels a render makes (≈ 100 bytes per pixel in memory while it
/// runs: 50 M pixels take ≈ 5 GB).
pub const MAX_IMAGE_PIXELS: usize = 50_000_000;

/// Checks an image size against [`MAX_IMAGE_SIDE`] and [`MAX_IMAGE_PIXELS`] (and ≥ 1 × 1).
pub fn check_image_size(width: usize, height: usize) -> Result<(), CameraError> {
    if width == 0 || height == 0 {
        return Err(CameraError::EmptyImage { width, height });
    }
    if width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE || width * height > MAX_IMAGE_PIXELS {
        return Err(CameraError::TooLarge { width, height });
    }
    Ok(())
}

/// Why a camera could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum CameraError {
    #[error("image size must be at least 1 × 1 pixel, got {width} × {height}")]
    EmptyImage { width: usize, height: usize },
    #[error(
        "image size {width} × {height} is larger than a render can hold: at most {MAX_IMAGE_SIDE} pixels a \
         side and {MAX_IMAGE_PIXELS} pixels in all"
    )]
    TooLarge { width: usize, height: usize },
    #[error("intrinsics must be finite with fx, fy > 0, got fx {fx}, fy {fy}, cx {cx}, cy {cy}")]
    BadIntrinsics { fx: f64, fy: f64, cx: f64, cy: f64 },
    #[error(
        "camera_to_world must be finite with an orthonormal rotation part (columns of length 1, determinant +1); {why}"
    )]
    BadPose { why: String },
    #[error("distortion coefficients must be finite, got {0:?}")]
    BadDistortion([f64; 5]),
    /// The rule of a calibrated camera's principal point, for every camera.
    #[error(
        "principal point ({cx}, {cy}) px is far outside the {width} × {height} image (allowed: within half an \
         image size of its edges)"
    )]
    PrincipalPoint { cx: f64, cy: f64, width: usize, height: usize },
}

/// OpenCV's Brown–Conrady distortion (k1, k2, p1, p2, k3) of normalised points:
/// x_d = x(1 + k1 r² + k2 r⁴ + k3 r⁶) + 2 p1 x y + p2 (r² + 2x²),
/// y_d = y(1 + k1 r² + k2 r⁴ + k3 r⁶) + p1 (r² + 2y²) + 2 p2 x y.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

impl Distortion {
    /// The distorted normalised point of the undistorted (x, y).
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }

    /// The undistorted point that [`distort`](Self::distort)s onto (xd, yd):
    /// OpenCV's fixed-point iteration, at most 100 steps, stopping at a step
    /// below 10⁻¹⁴.
    pub fn undistort(&self, xd: f64, yd: f64) -> (f64, f64) {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..100 {
            let r2 = x * x + y * y;
            let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x);
            let dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y;
            let (nx, ny) = ((xd - dx) / radial, (yd - dy) / radial);
            let step = (nx - x).abs().max((ny - y).abs());
            (x, y) = (nx, ny);
            if step < 1e-14 || !step.is_finite() {
                break;
            }
        }
        (x, y)
    }
}

/// A pinhole camera with optional lens distortion.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    pub width: usize,
    pub height: usize,
    /// fx, fy, cx, cy in OpenCV pixels.
    pub intrinsics: [f64; 4],
    pub distortion: Option<Distortion>,
    position: DVec3,
    rotation: DMat3,
}

impl Camera {
    /// A camera from intrinsics `[fx, fy, cx, cy]` (OpenCV pixels), the
    /// renderer's 4 × 4 row-major `camera_to_world` and optional distortion
    /// coefficients `[k1, k2, p1, p2, k3]`.
    pub fn new(
        width: usize,
        height: usize,
        intrinsics: [f64; 4],
        camera_to_world: [[f64; 4]; 4],
        distortion: Option<[f64; 5]>,
    ) -> Result<Self, CameraError> {
        check_image_size(width, height)?;
        let [fx, fy, cx, cy] = intrinsics;
        if !(fx > 0.0 && fy > 0.0 && fx.is_finite() && fy.is_finite() && cx.is_finite() && cy.is_finite()) {
            return Err(CameraError::BadIntrinsics { fx, fy, cx, cy });
        }
        let inside = |c: f64, side: usize| c >= -0.5 * side as f64 && c <= 1.5 * side as f64;
        if !(inside(cx, width) && inside(cy, height)) {
            return Err(CameraError::PrincipalPoint { cx, cy, width, height });
        }
        let m = camera_to_world;
        if m.iter().flatten().any(|v| !v.is_finite()) {
            return Err(CameraError::BadPose { why: "a value is not finite".into() });
        }
        let rotation = DMat3::from_cols(
            DVec3::new(m[0][0], m[1][0], m[2][0]),
            DVec3::new(m[0][1], m[1][1], m[2][1]),
            DVec3::new(m[0][2], m[1][2], m[2][2]),
        );
        let ortho = (rotation.transpose() * rotation - DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .map(|v| v.abs())
            .fold(0.0, f64::max);
        if ortho > 1e-6 || (rotation.determinant() - 1.0).abs() > 1e-6 {
            return Err(CameraError::BadPose {
                why: format!("RᵀR − I is {ortho:.2e} off, det R = {:.6}", rotation.determinant()),
            });
        }
        let distortion = match distortion {
            Some(d) if d.iter().any(|v| !v.is_finite()) => return Err(CameraError::BadDistortion(d)),
            Some([k1, k2, p1, p2, k3]) => Some(Distortion { k1, k2, p1, p2, k3 }),
            None => None,
        };
        Ok(Self { width, height, intrinsics, distortion, position: DVec3::new(m[0][3], m[1][3], m[2][3]), rotation })
    }

    /// A camera at `position` looking at `target` with `up` roughly up,
    /// vertical field of view `vfov_deg` over the image height, principal
    /// point at the image centre, square pixels.
    pub fn look_at(
        width: usize,
        height: usize,
        position: DVec3,
        target: DVec3,
        up: DVec3,
        vfov_deg: f64,
    ) -> Result<Self, CameraError> {
        let back = (position - target).normalize();
        let right = up.cross(back).normalize();
        let true_up = back.cross(right);
        if !(back.is_finite() && right.is_finite()) {
            return Err(CameraError::BadPose {
                why: "position equals target or up is parallel to the view direction".into(),
            });
        }
        if !(vfov_deg > 0.0 && vfov_deg < 180.0) {
            return Err(CameraError::BadIntrinsics { fx: f64::NAN, fy: f64::NAN, cx: f64::NAN, cy: f64::NAN });
        }
        let f = 0.5 * height as f64 / (0.5 * vfov_deg.to_radians()).tan();
        let m = [
            [right.x, true_up.x, back.x, position.x],
            [right.y, true_up.y, back.y, position.y],
            [right.z, true_up.z, back.z, position.z],
            [0.0, 0.0, 0.0, 1.0],
        ];
        Self::new(width, height, [f, f, 0.5 * width as f64 - 0.5, 0.5 * height as f64 - 0.5], m, None)
    }

    /// Camera centre in the world, metres.
    pub fn position(&self) -> DVec3 {
        self.position
    }

    /// The ray (origin, unit direction in the world) through pixel (i, j) at
    /// the sub-pixel offset `u` ∈ [0, 1)².
    #[inline]
    pub fn ray(&self, i: usize, j: usize, u: [f64; 2]) -> (DVec3, DVec3) {
        let [fx, fy, cx, cy] = self.intrinsics;
        let x = i as f64 - 0.5 + u[0];
        let y = j as f64 - 0.5 + u[1];
        let (mut xn, mut yn) = ((x - cx) / fx, (y - cy) / fy);
        if let Some(d) = &self.distortion {
            (xn, yn) = d.undistort(xn, yn);
        }
        let local = DVec3::new(xn, -yn, -1.0);
        (self.position, (self.rotation * local).normalize())
    }

    /// The image point (OpenCV pixels) of a world point in front of the
    /// camera, distorted if the camera has distortion; None behind it.
    pub fn project(&self, p: DVec3) -> Option<[f64; 2]> {
        let local = self.rotation.transpose() * (p - self.position);
        if local.z >= 0.0 {
            return None;
        }
        let (mut xn, mut yn) = (local.x / -local.z, -local.y / -local.z);
        if let Some(d) = &self.distortion {
            (xn, yn) = d.distort(xn, yn);
        }
        let [fx, fy, cx, cy] = self.intrinsics;
        Some([fx * xn + cx, fy * yn + cy])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn undistort_inverts_distort() {
        let d = Distortion { k1: -0.28, k2: 0.07, p1: 1e-3, p2: -2e-4, k3: 0.01 };
        for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.5, 0.4), (0.1, 0.6)] {
            let (xd, yd) = d.distort(x, y);
            let (xu, yu) = d.undistort(xd, yd);
            assert!((xu - x).abs() < 1e-12 && (yu - y).abs() < 1e-12, "({x}, {y}) → ({xu}, {yu})");
        }
    }

    #[test]
    fn ray_projects_back_to_its_pixel_point() {
        let cam =
            Camera::look_at(64, 48, DVec3::new(0.0, -0.14, 0.16), DVec3::new(0.0, 0.0, 0.004), DVec3::Z, 36.0).unwrap();
        let (p, r) = (cam.position, cam.rotation);
        let mut m: [[f64; 4]; 4] =
            std::array::from_fn(|i| if i < 3 { [r.col(0)[i], r.col(1)[i], r.col(2)[i], p[i]] } else { [0.0; 4] });
        m[3][3] = 1.0;
        let cam = Camera::new(64, 48, cam.intrinsics, m, Some([-0.2, 0.05, 1e-3, 5e-4, 0.0])).unwrap();
        for &(i, j, u) in &[(0, 0, [0.0, 0.0]), (63, 47, [0.999, 0.5]), (20, 30, [0.25, 0.75])] {
            let (o, d) = cam.ray(i, j, u);
            let px = cam.project(o + 0.3 * d).unwrap();
            assert!(
                (px[0] - (i as f64 - 0.5 + u[0])).abs() < 1e-9 && (px[1] - (j as f64 - 0.5 + u[1])).abs() < 1e-9,
                "{px:?}"
            );
        }
        // Image up is world up: the top row looks higher than the bottom row.
        assert!(cam.ray(32, 0, [0.5; 2]).1.z > cam.ray(32, 47, [0.5; 2]).1.z);
        // Image right is world +x here (camera at −y looking towards +y).
        assert!(cam.ray(63, 24, [0.5; 2]).1.x > 0.0 && cam.ray(0, 24, [0.5; 2]).1.x < 0.0);
    }

    #[test]
    fn bad_cameras() {
        let id = [[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        assert!(matches!(Camera::new(0, 4, [1.0, 1.0, 0.0, 0.0], id, None), Err(CameraError::EmptyImage { .. })));
        assert!(matches!(Camera::new(4, 4, [-1.0, 1.0, 0.0, 0.0], id, None), Err(CameraError::BadIntrinsics { .. })));
        // The principal point within half an image of its edges, as for a calibrated camera.
        assert!(matches!(Camera::new(4, 4, [1.0, 1.0, 1e9, 2.0], id, None), Err(CameraError::PrincipalPoint { .. })));
        assert!(Camera::new(4, 4, [1.0, 1.0, 6.0, -2.0], id, None).is_ok());
        assert!(matches!(Camera::new(4, 4, [1.0, 1.0, 2.0, -2.1], id, None), Err(CameraError::PrincipalPoint { .. })));
        let mut skew = id;
        skew[0][1] = 0.5;
        assert!(matches!(Camera::new(4, 4, [1.0, 1.0, 0.0, 0.0], skew, None), Err(CameraError::BadPose { .. })));
        assert!(matches!(
            Camera::new(4, 4, [1.0, 1.0, 0.0, 0.0], id, Some([f64::NAN, 0.0, 0.0, 0.0, 0.0])),
            Err(CameraError::BadDistortion(_))
        ));
        assert!(Camera::look_at(4, 4, DVec3::Z, DVec3::Z, DVec3::Z, 40.0).is_err());
    }
}
