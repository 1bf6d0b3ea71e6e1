//! The camera model of a calibration: a pinhole with OpenCV's lens
//! distortion, projection of 3-D points, the inverse (pixel → ray), and the
//! checks a camera file must pass on load ([`CameraModel::validate`]). A leaf
//! module: it imports nothing from this crate, so [`crate::camera`] (undistortion),
//! [`crate::cv`] (OpenCV), [`crate::scene`] (the renderer's convention) and
//! [`crate::calibrate`] (the calibration driver) all build on it.
//!
//! Model: a point (X, Y, Z) in the camera frame (x right, y down, z
//! forward, metres) goes to normalised coordinates x = X/Z, y = Y/Z, the
//! lens distorts them to (x_d, y_d) by its [`DistortionModel`] — Brown–Conrady
//! `pinhole-k3` (k1, k2, p1, p2, k3), OpenCV's `rational` (k1–k6, p1, p2) or
//! Kannala–Brandt `fisheye` (k1–k4), whose equations and inverses are in
//! `lucent-lens` ([`Lens`]; re-exported here) — then
//!
//! ```text
//! u = fx x_d + cx,   v = fy y_d + cy        (pixels)
//! ```
//!
//! with pixel centres at integer coordinates (the centre of the top-left
//! pixel is (0, 0)). Pixels go back to rays by Newton's method
//! ([`Lens::undistort`]); fisheye pixels more than 90° off axis have no
//! pinhole ray (`None`). This projection is tested against OpenCV's
//! `projectPoints` and the undistortion map against `initUndistortRectifyMap`
//! (`calib/tests/calibration.rs`, `calib/tests/fisheye.rs`).
//!
//! ```
//! use lucent_calib::model::{CameraModel, Distortion, DistortionModel, Intrinsics};
//! let cam = CameraModel {
//!     model: DistortionModel::PinholeK3,
//!     image_width: 640, image_height: 480,
//!     intrinsics: Intrinsics { fx: 500.0, fy: 500.0, cx: 320.0, cy: 240.0 },
//!     distortion: Distortion { k1: -0.2, ..Default::default() },
//! };
//! // x = 0.2, y = 0: r² = 0.04, radial = 1 − 0.2·0.04 = 0.992, u = 320 + 500·0.1984.
//! let [u, v] = cam.project([0.2, 0.0, 1.0]).unwrap();
//! assert!((u - 419.2).abs() < 1e-9 && (v - 240.0).abs() < 1e-12);
//! let ray = cam.pixel_to_ray(u, v).unwrap();
//! assert!((ray[0] / ray[2] - 0.2).abs() < 1e-12);
//! ```

use serde::{Deserialize, Serialize};

/// The distortion model and its coefficients, with their maths: one type
/// for the calibration and the renderer, re-exported from `lucent-lens`.
pub use lucent_lens::{Distortion, DistortionModel, Lens, UnknownModel};

/// Pinhole intrinsics in pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
}

impl Intrinsics {
    /// The 3 × 3 camera matrix K, row-major.
    pub fn matrix(&self) -> [[f64; 3]; 3] {
        [[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]]
    }
}

/// A calibrated camera. Reading one from JSON validates it
/// ([`CameraModel::validate`]): a camera file with a non-positive focal
/// length or a distortion that folds the image is refused on load.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "CameraModelFields")]
pub struct CameraModel {
    pub model: DistortionModel,
    pub image_width: usize,
    pub image_height: usize,
    pub intrinsics: Intrinsics,
    pub distortion: Distortion,
}

/// The fields of a [`CameraModel`] as stored, before validation.
#[derive(Deserialize)]
struct CameraModelFields {
    model: DistortionModel,
    image_width: usize,
    image_height: usize,
    intrinsics: Intrinsics,
    distortion: Distortion,
}

impl TryFrom<CameraModelFields> for CameraModel {
    type Error = CameraError;
    fn try_from(f: CameraModelFields) -> Result<Self, CameraError> {
        let cam = CameraModel {
            model: f.model,
            image_width: f.image_width,
            image_height: f.image_height,
            intrinsics: f.intrinsics,
            distortion: f.distortion,
        };
        cam.validate()?;
        Ok(cam)
    }
}

/// Largest image side accepted, pixels (a typo guard, 4× a 100 MP sensor side).
pub const MAX_IMAGE_SIDE: usize = 50_000;

/// Range of the radial scale r_d / r (distorted over undistorted radius)
/// accepted inside the image for the Brown–Conrady models. Real lenses stay
/// well inside [0.5, 2] over their image; beyond [0.1, 10] the coefficients
/// are a typo (k1 = 1e6 squeezes the whole image into a degree).
pub const RADIAL_SCALE_RANGE: (f64, f64) = (0.1, 10.0);

/// Why a camera model cannot be used (see [`CameraModel::validate`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CameraError {
    /// A photo whose size is not the one the camera was calibrated at.
    #[error("image is {width} × {height} pixels but the camera was calibrated at {camera_width} × {camera_height}")]
    PhotoSize { width: usize, height: usize, camera_width: usize, camera_height: usize },
    #[error("image size {width} × {height} pixels: each side must be 2 to {MAX_IMAGE_SIDE} pixels")]
    ImageSize { width: usize, height: usize },
    #[error("focal length {name} = {value} px: must be a positive finite number")]
    FocalLength { name: &'static str, value: f64 },
    #[error(
        "principal point ({cx}, {cy}) px is far outside the {width} × {height} image (allowed: within half an image size of its edges)"
    )]
    PrincipalPoint { cx: f64, cy: f64, width: usize, height: usize },
    #[error("distortion coefficient {name} = {value} is not a finite number")]
    Coefficient { name: &'static str, value: f64 },
    #[error(
        "the distortion does not map the image one-to-one: the distorted radius stops growing at {radius:.4} (normalised) before reaching the image corner at {corner:.4}; the coefficients are not a lens"
    )]
    NotMonotonic { radius: f64, corner: f64 },
    #[error(
        "the distortion scales radii by {scale:.3} inside the image (at normalised radius {radius:.4}); accepted is {}–{}: the coefficients are not a lens",
        RADIAL_SCALE_RANGE.0,
        RADIAL_SCALE_RANGE.1
    )]
    RadialScale { scale: f64, radius: f64 },
    #[error("pixel ({u}, {v}) of the image has no ray: the distortion cannot be inverted there")]
    NoRay { u: f64, v: f64 },
}

impl CameraModel {
    /// Checks that the model can describe a real camera: image sides of 2 to
    /// [`MAX_IMAGE_SIDE`] pixels; fx, fy positive and finite; the principal
    /// point inside the image grown by half its size on every side; finite
    /// coefficients; a radial map r → r_d that increases from the centre to
    /// the farthest image corner (so every pixel has one ray) with r_d / r
    /// within [`RADIAL_SCALE_RANGE`] there (Brown–Conrady; for the fisheye
    /// model θ → θ_d increasing up to the corner or 180°); and a ray for
    /// every pixel of a 9 × 9 grid over the image (corners included).
    pub fn validate(&self) -> Result<(), CameraError> {
        let (w, h) = (self.image_width, self.image_height);
        if !((2..=MAX_IMAGE_SIDE).contains(&w) && (2..=MAX_IMAGE_SIDE).contains(&h)) {
            return Err(CameraError::ImageSize { width: w, height: h });
        }
        let k = &self.intrinsics;
        for (name, value) in [("fx", k.fx), ("fy", k.fy)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(CameraError::FocalLength { name, value });
            }
        }
        let (wf, hf) = (w as f64, h as f64);
        let inside = |c: f64, side: f64| c.is_finite() && c >= -0.5 * side && c <= 1.5 * side;
        if !(inside(k.cx, wf) && inside(k.cy, hf)) {
            return Err(CameraError::PrincipalPoint { cx: k.cx, cy: k.cy, width: w, height: h });
        }
        if let Some((name, value)) = self.lens().non_finite() {
            return Err(CameraError::Coefficient { name, value });
        }
        // Distorted normalised radius of the farthest image corner.
        let corner = [(0.0, 0.0), (wf - 1.0, 0.0), (0.0, hf - 1.0), (wf - 1.0, hf - 1.0)]
            .iter()
            .map(|&(u, v)| ((u - k.cx) / k.fx).hypot((v - k.cy) / k.fy))
            .fold(0.0, f64::max);
        self.check_radial_map(corner)?;
        for j in 0..9 {
            for i in 0..9 {
                let (u, v) = (i as f64 / 8.0 * (wf - 1.0), j as f64 / 8.0 * (hf - 1.0));
                let ray = self.pixel_to_ray(u, v);
                if self.model != DistortionModel::Fisheye && !ray.is_some_and(|r| r.iter().all(|c| c.is_finite())) {
                    return Err(CameraError::NoRay { u, v });
                }
            }
        }
        Ok(())
    }

    /// The radial part of [`CameraModel::validate`]: walks outwards from the
    /// axis until the distorted radius reaches `corner`.
    fn check_radial_map(&self, corner: f64) -> Result<(), CameraError> {
        let d = &self.distortion;
        if self.model == DistortionModel::Fisheye {
            // θ_d(θ) increasing on [0, min(θ at the corner, π)].
            let steps = 20_000;
            let mut prev = 0.0;
            for s in 1..=steps {
                let t = std::f64::consts::PI * s as f64 / steps as f64;
                let t2 = t * t;
                let td = t * (1.0 + t2 * (d.k1 + t2 * (d.k2 + t2 * (d.k3 + t2 * d.k4))));
                if !(td.is_finite() && td > prev) {
                    return Err(CameraError::NotMonotonic { radius: prev, corner });
                }
                if td >= corner {
                    break;
                }
                prev = td;
            }
            return Ok(());
        }
        // r_d(r) = r · radial(r²): steps of corner/2000 up to 100 × corner.
        let radial = |r: f64| {
            let r2 = r * r;
            (1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3))) / (1.0 + r2 * (d.k4 + r2 * (d.k5 + r2 * d.k6)))
        };
        let step = corner / 2000.0;
        let mut prev = 0.0;
        for s in 1..=200_000 {
            let r = step * s as f64;
            let scale = radial(r);
            let rd = r * scale;
            if !(rd.is_finite() && rd > prev) {
                return Err(CameraError::NotMonotonic { radius: prev, corner });
            }
            if !(RADIAL_SCALE_RANGE.0..=RADIAL_SCALE_RANGE.1).contains(&scale) {
                return Err(CameraError::RadialScale { scale, radius: r });
            }
            if rd >= corner {
                return Ok(());
            }
            prev = rd;
        }
        Err(CameraError::NotMonotonic { radius: prev, corner })
    }
}

impl CameraModel {
    /// The camera's lens: its distortion model and coefficients.
    pub fn lens(&self) -> Lens {
        Lens { model: self.model, distortion: self.distortion }
    }

    /// Normalised undistorted → distorted coordinates for this camera's model ([`Lens::distort`]).
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> [f64; 2] {
        self.lens().distort(x, y)
    }

    /// Distorted → undistorted normalised coordinates for this camera's model
    /// ([`Lens::undistort`], Newton's method).
    pub fn undistort_normalised(&self, xd: f64, yd: f64) -> Option<[f64; 2]> {
        self.lens().undistort(xd, yd)
    }

    /// Pixel of a point in the camera frame (OpenCV axes); `None` behind the camera.
    pub fn project(&self, p: [f64; 3]) -> Option<[f64; 2]> {
        if p[2].partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let [xd, yd] = self.distort(p[0] / p[2], p[1] / p[2]);
        let k = &self.intrinsics;
        Some([k.fx * xd + k.cx, k.fy * yd + k.cy])
    }

    /// Ray (x, y, 1) in the camera frame through pixel (u, v).
    pub fn pixel_to_ray(&self, u: f64, v: f64) -> Option<[f64; 3]> {
        let k = &self.intrinsics;
        let [x, y] = self.undistort_normalised((u - k.cx) / k.fx, (v - k.cy) / k.fy)?;
        Some([x, y, 1.0])
    }

    /// Intrinsics of a distortion-free camera of the same image size that
    /// sees every pixel of this one (the undistorted border, sampled every
    /// pixel, fits inside the image with the pixel centres at the edges).
    pub fn keep_all_intrinsics(&self) -> Intrinsics {
        let (w, h) = (self.image_width as f64, self.image_height as f64);
        let (mut xmin, mut xmax, mut ymin, mut ymax) =
            (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
        let mut visit = |u: f64, v: f64| {
            if let Some([x, y, _]) = self.pixel_to_ray(u, v) {
                xmin = xmin.min(x);
                xmax = xmax.max(x);
                ymin = ymin.min(y);
                ymax = ymax.max(y);
            }
        };
        for i in 0..self.image_width {
            visit(i as f64, 0.0);
            visit(i as f64, h - 1.0);
        }
        for j in 0..self.image_height {
            visit(0.0, j as f64);
            visit(w - 1.0, j as f64);
        }
        if !(xmax > xmin && ymax > ymin) {
            return self.intrinsics;
        }
        // One focal-length scale for both axes keeps the pixel aspect.
        let s = ((w - 1.0) / (xmax - xmin) / self.intrinsics.fx).min((h - 1.0) / (ymax - ymin) / self.intrinsics.fy);
        let (fx, fy) = (self.intrinsics.fx * s, self.intrinsics.fy * s);
        let cx = (w - 1.0) / 2.0 - fx * (xmin + xmax) / 2.0;
        let cy = (h - 1.0) / 2.0 - fy * (ymin + ymax) / 2.0;
        Intrinsics { fx, fy, cx, cy }
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    pub(crate) fn camera() -> CameraModel {
        CameraModel {
            model: DistortionModel::PinholeK3,
            image_width: 64,
            image_height: 48,
            intrinsics: Intrinsics { fx: 60.0, fy: 61.0, cx: 31.2, cy: 24.3 },
            distortion: Distortion { k1: -0.28, k2: 0.09, p1: 0.001, p2: -0.0015, k3: -0.01, ..Default::default() },
        }
    }

    #[test]
    fn keep_all_intrinsics_keep_every_source_pixel() {
        let cam = camera();
        let k = cam.keep_all_intrinsics();
        assert!(k.fx < cam.intrinsics.fx, "barrel distortion: the kept image zooms out");
        // Every source border pixel maps inside the output (with rounding slack).
        for (u, v) in [(0.0, 0.0), (63.0, 0.0), (0.0, 47.0), (63.0, 47.0), (31.0, 0.0), (0.0, 24.0)] {
            let [x, y, _] = cam.pixel_to_ray(u, v).unwrap();
            let (uo, vo) = (k.fx * x + k.cx, k.fy * y + k.cy);
            assert!(
                (-1e-6..=63.0 + 1e-6).contains(&uo) && (-1e-6..=47.0 + 1e-6).contains(&vo),
                "({u},{v}) → ({uo},{vo})"
            );
        }
    }

    #[test]
    fn validation_refuses_cameras_that_are_not_lenses() {
        let good = camera();
        assert_eq!(good.validate(), Ok(()));
        let with = |f: &dyn Fn(&mut CameraModel)| {
            let mut c = camera();
            f(&mut c);
            c.validate().unwrap_err()
        };
        assert!(matches!(with(&|c| c.intrinsics.fx = 0.0), CameraError::FocalLength { name: "fx", .. }));
        assert!(matches!(with(&|c| c.intrinsics.fy = -60.0), CameraError::FocalLength { name: "fy", .. }));
        assert!(matches!(with(&|c| c.intrinsics.fx = f64::NAN), CameraError::FocalLength { .. }));
        assert!(matches!(with(&|c| c.intrinsics.cx = 200.0), CameraError::PrincipalPoint { .. }));
        assert!(matches!(with(&|c| c.intrinsics.cy = -30.0), CameraError::PrincipalPoint { .. }));
        assert!(matches!(with(&|c| c.image_width = 0), CameraError::ImageSize { .. }));
        assert!(matches!(with(&|c| c.distortion.p2 = f64::INFINITY), CameraError::Coefficient { name: "p2", .. }));
        // k1 = 1e6: r_d = r (1 + 1e6 r²) is monotonic but squeezes the image 80-fold.
        assert!(matches!(with(&|c| c.distortion.k1 = 1e6), CameraError::RadialScale { .. }));
        // k1 = −1: r_d = r − r³ peaks at r = 1/√3 (r_d = 0.385) before the corner (0.53).
        let e = with(&|c| c.distortion = Distortion { k1: -1.0, ..Default::default() });
        assert!(matches!(e, CameraError::NotMonotonic { .. }), "{e}");
        // Fisheye: θ_d = θ (1 − 0.5 θ²) turns back at θ = 0.816 (θ_d = 0.54) before the corner.
        let e = with(&|c| {
            c.model = DistortionModel::Fisheye;
            c.intrinsics.fx = 30.0;
            c.intrinsics.fy = 30.0;
            c.distortion = Distortion { k1: -0.5, ..Default::default() }
        });
        assert!(matches!(e, CameraError::NotMonotonic { .. }), "{e}");
    }

    #[test]
    fn opencv_calibrations_of_the_shipped_photos_validate() {
        // Real lenses must pass: OpenCV's calibrations of fixtures/camera/chessboard
        // (tools/reference/opencv_calibration.py) and the demo's synthetic camera.
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
        let text = std::fs::read_to_string(root.join("fixtures/reference/opencv_left_calibration.json")).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        for key in ["auto", "classic_only"] {
            let c = &v[key];
            let f = |k: &str| c[k].as_f64().unwrap();
            let d: Vec<f64> =
                c["distortion_k1_k2_p1_p2_k3"].as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
            let cam = CameraModel {
                model: DistortionModel::PinholeK3,
                image_width: 640,
                image_height: 480,
                intrinsics: Intrinsics { fx: f("fx"), fy: f("fy"), cx: f("cx"), cy: f("cy") },
                distortion: Distortion::from_opencv(&d),
            };
            assert_eq!(cam.validate(), Ok(()), "{key}");
        }
        let text = std::fs::read_to_string(root.join("fixtures/demo/truth_camera.json")).unwrap();
        // The `camera` of a camera.json; reading it validates, and so does the check.
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let cam: CameraModel = serde_json::from_value(v["camera"].clone()).unwrap();
        assert_eq!(cam.validate(), Ok(()));
    }

    #[test]
    fn reading_json_validates() {
        let text = serde_json::to_string(&camera()).unwrap();
        let back: CameraModel = serde_json::from_str(&text).unwrap();
        assert_eq!(back, camera());
        let bad = text.replace("\"fx\":60.0", "\"fx\":-60.0");
        assert_ne!(bad, text);
        let e = serde_json::from_str::<CameraModel>(&bad).unwrap_err().to_string();
        assert!(e.contains("focal length fx = -60"), "{e}");
    }
}
