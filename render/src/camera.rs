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
//! (x_d, y_d, 1). With a [`Lens`] (the distortion model and coefficients of
//! camera.json, from `lucent-lens`: Brown–Conrady `pinhole-k3`, OpenCV's
//! `rational`), (x_d, y_d) is the *distorted* point and the ray goes through
//! the undistorted (x_u, y_u) that distorts onto it, found by OpenCV's
//! fixed-point iteration (`cv::undistortPoints`,
//! [`Distortion::undistort_fixed_point`]), run to convergence (< 10⁻¹⁴) — so
//! the render matches the raw photo's geometry without resampling the photo.
//! The Kannala–Brandt `fisheye` model is not drawn: [`Camera::new`] refuses it.
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

/// The lens distortion the camera takes: one type with the calibration's
/// camera.json, re-exported from `lucent-lens`.
pub use lucent_lens::{Distortion, DistortionModel, Lens};

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
    #[error("distortion coefficient {name} = {value} is not a finite number")]
    BadDistortion { name: &'static str, value: f64 },
    /// A lens model the ray generation does not follow.
    #[error(
        "the renderer draws the pinhole-k3 and rational distortion models, not {}",
        model.name()
    )]
    UnsupportedLens { model: DistortionModel },
    /// The rule of a calibrated camera's principal point, for every camera.
    #[error(
        "principal point ({cx}, {cy}) px is far outside the {width} × {height} image (allowed: within half an \
         image size of its edges)"
    )]
    PrincipalPoint { cx: f64, cy: f64, width: usize, height: usize },
}

/// A pinhole camera with optional lens distortion.
#[derive(Debug, Clone, PartialEq)]
pub struct Camera {
    pub width: usize,
    pub height: usize,
    /// fx, fy, cx, cy in OpenCV pixels.
    pub intrinsics: [f64; 4],
    /// The lens distortion (`pinhole-k3` or `rational`); None for an ideal pinhole.
    pub distortion: Option<Lens>,
    position: DVec3,
    rotation: DMat3,
}

impl Camera {
    /// A camera from intrinsics `[fx, fy, cx, cy]` (OpenCV pixels), the
    /// renderer's 4 × 4 row-major `camera_to_world` and an optional lens
    /// (`pinhole-k3` or `rational`, finite coefficients).
    pub fn new(
        width: usize,
        height: usize,
        intrinsics: [f64; 4],
        camera_to_world: [[f64; 4]; 4],
        distortion: Option<Lens>,
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
        if let Some(lens) = &distortion {
            if let Some((name, value)) = lens.non_finite() {
                return Err(CameraError::BadDistortion { name, value });
            }
            if lens.model == DistortionModel::Fisheye {
                return Err(CameraError::UnsupportedLens { model: lens.model });
            }
        }
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
        if let Some(lens) = &self.distortion {
            (xn, yn) = lens.distortion.undistort_fixed_point(xn, yn);
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
        if let Some(lens) = &self.distortion {
            [xn, yn] = lens.distort(xn, yn);
        }
        let [fx, fy, cx, cy] = self.intrinsics;
        Some([fx * xn + cx, fy * yn + cy])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_projects_back_to_its_pixel_point() {
        let cam =
            Camera::look_at(64, 48, DVec3::new(0.0, -0.14, 0.16), DVec3::new(0.0, 0.0, 0.004), DVec3::Z, 36.0).unwrap();
        let (p, r) = (cam.position, cam.rotation);
        let mut m: [[f64; 4]; 4] =
            std::array::from_fn(|i| if i < 3 { [r.col(0)[i], r.col(1)[i], r.col(2)[i], p[i]] } else { [0.0; 4] });
        m[3][3] = 1.0;
        let k3 = Distortion { k1: -0.2, k2: 0.05, p1: 1e-3, p2: 5e-4, ..Default::default() };
        let lenses = [
            Lens { model: DistortionModel::PinholeK3, distortion: k3 },
            // A wide lens: OpenCV's rational model, its denominator k4–k6 too.
            Lens {
                model: DistortionModel::Rational,
                distortion: Distortion { k1: 0.3, k4: 0.6, k5: -0.02, k6: 0.005, ..k3 },
            },
        ];
        for lens in lenses {
            let cam = Camera::new(64, 48, cam.intrinsics, m, Some(lens)).unwrap();
            for &(i, j, u) in &[(0, 0, [0.0, 0.0]), (63, 47, [0.999, 0.5]), (20, 30, [0.25, 0.75])] {
                let (o, d) = cam.ray(i, j, u);
                let px = cam.project(o + 0.3 * d).unwrap();
                assert!(
                    (px[0] - (i as f64 - 0.5 + u[0])).abs() < 1e-9 && (px[1] - (j as f64 - 0.5 + u[1])).abs() < 1e-9,
                    "{lens:?}: {px:?}"
                );
            }
        }
        let cam = Camera::new(64, 48, cam.intrinsics, m, Some(lenses[0])).unwrap();
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
        let lens = |model, k1| Some(Lens { model, distortion: Distortion { k1, ..Default::default() } });
        assert!(matches!(
            Camera::new(4, 4, [1.0, 1.0, 0.0, 0.0], id, lens(DistortionModel::PinholeK3, f64::NAN)),
            Err(CameraError::BadDistortion { name: "k1", .. })
        ));
        let e = Camera::new(4, 4, [1.0, 1.0, 0.0, 0.0], id, lens(DistortionModel::Fisheye, 0.01)).unwrap_err();
        assert_eq!(e, CameraError::UnsupportedLens { model: DistortionModel::Fisheye });
        assert!(e.to_string().contains("not fisheye"), "{e}");
        assert!(Camera::look_at(4, 4, DVec3::Z, DVec3::Z, DVec3::Z, 40.0).is_err());
    }
}
