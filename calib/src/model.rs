//! The camera model of a calibration: a pinhole with OpenCV's lens
//! distortion, projection of 3-D points, the inverse (pixel → ray), and the
//! checks a camera file must pass on load ([`CameraModel::validate`]). A leaf
//! module: it imports nothing from this crate, so [`crate::camera`] (undistortion),
//! [`crate::cv`] (OpenCV), [`crate::scene`] (the renderer's convention) and
//! [`crate::calibrate`] (the calibration driver) all build on it.
//!
//! Model (OpenCV's, Brown–Conrady with the rational extension): a point
//! (X, Y, Z) in the camera frame (x right, y down, z forward, metres) goes to
//! normalised coordinates x = X/Z, y = Y/Z, r² = x² + y², then
//!
//! ```text
//! radial = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)
//! x_d = x·radial + 2 p1 x y + p2 (r² + 2x²)
//! y_d = y·radial + p1 (r² + 2y²) + 2 p2 x y
//! u = fx x_d + cx,   v = fy y_d + cy        (pixels)
//! ```
//!
//! with pixel centres at integer coordinates (the centre of the top-left
//! pixel is (0, 0)). `pinhole-k3` estimates k1, k2, p1, p2, k3 (k4–k6 = 0);
//! `rational` all eight.
//!
//! `fisheye` is Kannala–Brandt (Kannala & Brandt, PAMI 2006; OpenCV's
//! `cv::fisheye`): r = √(x² + y²), θ = atan r (the angle off the axis),
//! θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸), (x_d, y_d) = (θ_d / r)(x, y),
//! then the same u, v; k1–k4 are stored in the fields `k1`–`k4` (p1 = p2 = 0).
//! Its inverse solves θ_d(θ) = r_d by Newton's method; pixels more than 90°
//! off axis have no pinhole ray (`None`).
//!
//! The Brown–Conrady inverse is solved by Newton's method
//! (analytic Jacobian) to 1e-12. This projection is tested against OpenCV's
//! `projectPoints` and the undistortion map against `initUndistortRectifyMap`
//! (`calib/tests/calibration.rs`).
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
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

/// Which distortion coefficients a calibration estimates.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage)]
#[strum(serialize_all = "kebab-case", ascii_case_insensitive)]
pub enum DistortionModel {
    /// k1, k2, p1, p2, k3.
    #[strum(to_string = "pinhole-k3", serialize = "k3", serialize = "brown-conrady")]
    PinholeK3,
    /// k1–k6, p1, p2 (OpenCV's `CALIB_RATIONAL_MODEL`), for wide lenses.
    Rational,
    /// Kannala–Brandt k1–k4 on the angle off the axis (OpenCV's `fisheye`), for fisheye lenses.
    #[strum(to_string = "fisheye", serialize = "kannala-brandt")]
    Fisheye,
}

impl DistortionModel {
    /// Any spelling of a model (case ignored).
    pub fn from_name(name: &str) -> Result<Self, CameraError> {
        name.trim().parse().map_err(|_| CameraError::UnknownModel { name: name.to_string() })
    }

    /// The name, as written in camera.json ("pinhole-k3", …).
    pub fn name(self) -> &'static str {
        self.into()
    }
}

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

/// OpenCV distortion coefficients (dimensionless).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
    #[serde(default)]
    pub k4: f64,
    #[serde(default)]
    pub k5: f64,
    #[serde(default)]
    pub k6: f64,
}

impl Distortion {
    /// In OpenCV's order: k1, k2, p1, p2, k3[, k4, k5, k6]; for `Fisheye`, k1, k2, k3, k4.
    pub fn to_opencv(&self, model: DistortionModel) -> Vec<f64> {
        if model == DistortionModel::Fisheye {
            return vec![self.k1, self.k2, self.k3, self.k4];
        }
        let mut v = vec![self.k1, self.k2, self.p1, self.p2, self.k3];
        if model == DistortionModel::Rational {
            v.extend([self.k4, self.k5, self.k6]);
        }
        v
    }

    /// From OpenCV's order (4, 5, 8 or more values; missing ones are 0).
    pub fn from_opencv(v: &[f64]) -> Self {
        let g = |i: usize| v.get(i).copied().unwrap_or(0.0);
        Self { k1: g(0), k2: g(1), p1: g(2), p2: g(3), k3: g(4), k4: g(5), k5: g(6), k6: g(7) }
    }

    /// From OpenCV's fisheye order k1, k2, k3, k4 (missing ones are 0).
    pub fn from_opencv_fisheye(v: &[f64]) -> Self {
        let g = |i: usize| v.get(i).copied().unwrap_or(0.0);
        Self { k1: g(0), k2: g(1), k3: g(2), k4: g(3), ..Default::default() }
    }

    /// Kannala–Brandt: normalised undistorted (x, y) → distorted (module doc).
    #[inline]
    pub fn apply_fisheye(&self, x: f64, y: f64) -> [f64; 2] {
        let r = (x * x + y * y).sqrt();
        if r < 1e-15 {
            return [x, y]; // θ_d / r → 1 on the axis
        }
        let t = r.atan();
        let t2 = t * t;
        let s = t * (1.0 + t2 * (self.k1 + t2 * (self.k2 + t2 * (self.k3 + t2 * self.k4)))) / r;
        [x * s, y * s]
    }

    /// Kannala–Brandt inverse: θ from θ_d by Newton's method, then
    /// r = tan θ; `None` where θ would reach 90° or the polynomial does not
    /// invert.
    pub fn invert_fisheye(&self, xd: f64, yd: f64) -> Option<[f64; 2]> {
        let rd = (xd * xd + yd * yd).sqrt();
        if rd < 1e-15 {
            return Some([xd, yd]);
        }
        let poly = |t: f64| {
            let t2 = t * t;
            t * (1.0 + t2 * (self.k1 + t2 * (self.k2 + t2 * (self.k3 + t2 * self.k4))))
        };
        let mut t = rd.min(1.5);
        for _ in 0..60 {
            let t2 = t * t;
            let df = 1.0 + t2 * (3.0 * self.k1 + t2 * (5.0 * self.k2 + t2 * (7.0 * self.k3 + t2 * 9.0 * self.k4)));
            if !(df.is_finite() && df > 1e-9) {
                return None;
            }
            let step = (poly(t) - rd) / df;
            t -= step;
            if !t.is_finite() {
                return None;
            }
            if step.abs() < 1e-15 {
                break;
            }
        }
        if !(0.0..std::f64::consts::FRAC_PI_2 - 1e-9).contains(&t) || (poly(t) - rd).abs() > 1e-10 {
            return None;
        }
        let s = t.tan() / rd;
        Some([xd * s, yd * s])
    }

    /// Normalised undistorted (x, y) → distorted (x_d, y_d).
    #[inline]
    pub fn apply(&self, x: f64, y: f64) -> [f64; 2] {
        let r2 = x * x + y * y;
        let a = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        let b = 1.0 + r2 * (self.k4 + r2 * (self.k5 + r2 * self.k6));
        let radial = a / b;
        [
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        ]
    }

    /// Distorted → undistorted normalised coordinates by Newton's method;
    /// `None` where it does not converge (outside the lens's invertible
    /// field).
    pub fn invert(&self, xd: f64, yd: f64) -> Option<[f64; 2]> {
        let (mut x, mut y) = (xd, yd);
        for _ in 0..50 {
            let [fx, fy] = self.apply(x, y);
            let (ex, ey) = (fx - xd, fy - yd);
            if ex.abs() < 1e-13 && ey.abs() < 1e-13 {
                return Some([x, y]);
            }
            let r2 = x * x + y * y;
            let a = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            let b = 1.0 + r2 * (self.k4 + r2 * (self.k5 + r2 * self.k6));
            let da = self.k1 + r2 * (2.0 * self.k2 + 3.0 * self.k3 * r2);
            let db = self.k4 + r2 * (2.0 * self.k5 + 3.0 * self.k6 * r2);
            let radial = a / b;
            let dr = (da * b - a * db) / (b * b);
            let j11 = radial + 2.0 * x * x * dr + 2.0 * self.p1 * y + 6.0 * self.p2 * x;
            let j12 = 2.0 * x * y * dr + 2.0 * self.p1 * x + 2.0 * self.p2 * y;
            let j21 = j12;
            let j22 = radial + 2.0 * y * y * dr + 6.0 * self.p1 * y + 2.0 * self.p2 * x;
            let det = j11 * j22 - j12 * j21;
            if !det.is_finite() || det.abs() < 1e-12 {
                return None;
            }
            x -= (j22 * ex - j12 * ey) / det;
            y -= (j11 * ey - j21 * ex) / det;
            if !(x.is_finite() && y.is_finite()) {
                return None;
            }
        }
        let [fx, fy] = self.apply(x, y);
        ((fx - xd).abs() < 1e-9 && (fy - yd).abs() < 1e-9).then_some([x, y])
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
    #[error("unknown camera model {name:?}; valid: {}", <DistortionModel as strum::VariantNames>::VARIANTS.join(", "))]
    UnknownModel { name: String },
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
        let d = &self.distortion;
        for (name, value) in [
            ("k1", d.k1),
            ("k2", d.k2),
            ("p1", d.p1),
            ("p2", d.p2),
            ("k3", d.k3),
            ("k4", d.k4),
            ("k5", d.k5),
            ("k6", d.k6),
        ] {
            if !value.is_finite() {
                return Err(CameraError::Coefficient { name, value });
            }
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
    /// Normalised undistorted → distorted coordinates for this camera's model.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> [f64; 2] {
        match self.model {
            DistortionModel::Fisheye => self.distortion.apply_fisheye(x, y),
            DistortionModel::PinholeK3 | DistortionModel::Rational => self.distortion.apply(x, y),
        }
    }

    /// Distorted → undistorted normalised coordinates for this camera's model.
    pub fn undistort_normalised(&self, xd: f64, yd: f64) -> Option<[f64; 2]> {
        match self.model {
            DistortionModel::Fisheye => self.distortion.invert_fisheye(xd, yd),
            DistortionModel::PinholeK3 | DistortionModel::Rational => self.distortion.invert(xd, yd),
        }
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
    fn inverse_distortion_round_trips() {
        let mut d = camera().distortion;
        for (x, y) in [(0.0, 0.0), (0.3, -0.2), (-0.55, 0.4), (0.7, 0.5)] {
            let [xd, yd] = d.apply(x, y);
            let [xu, yu] = d.invert(xd, yd).unwrap();
            assert!((xu - x).abs() < 1e-11 && (yu - y).abs() < 1e-11, "({x},{y}) → ({xu},{yu})");
        }
        d = Distortion { k1: 0.1, k2: -0.02, k4: 0.3, k5: 0.01, k6: 0.002, p1: 0.0005, ..Default::default() };
        let [xd, yd] = d.apply(-0.8, 0.6);
        let [xu, yu] = d.invert(xd, yd).unwrap();
        assert!((xu + 0.8).abs() < 1e-11 && (yu - 0.6).abs() < 1e-11);
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

    #[test]
    fn model_names() {
        assert_eq!(DistortionModel::from_name("rational").unwrap(), DistortionModel::Rational);
        assert!(DistortionModel::from_name("fish").unwrap_err().to_string().contains("pinhole-k3, rational, fisheye"));
        assert_eq!(DistortionModel::from_name("Fisheye").unwrap(), DistortionModel::Fisheye);
        let f = Distortion::from_opencv_fisheye(&[0.1, 0.2, 0.3, 0.4]);
        assert_eq!(f.to_opencv(DistortionModel::Fisheye), [0.1, 0.2, 0.3, 0.4]);
        let d = Distortion::from_opencv(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(d.to_opencv(DistortionModel::PinholeK3), [1.0, 2.0, 3.0, 4.0, 0.0]);
    }
}
