//! Lens distortion of a calibrated camera: the one model shared by the
//! calibration (`lucent-calib`, which writes and reads it in camera.json) and
//! the renderer (`lucent-render`, whose camera rays follow it). A leaf crate:
//! it depends on neither, so both can.
//!
//! Everything here maps **normalised image coordinates** (dimensionless):
//! a point (X, Y, Z) in OpenCV's camera frame (x right, y down, z forward)
//! is at x = X/Z, y = Y/Z; the pixel is (fx x_d + cx, fy y_d + cy) of the
//! distorted (x_d, y_d). Angles are in radians.
//!
//! # Models ([`DistortionModel`])
//!
//! `pinhole-k3` and `rational` are Brown–Conrady (Brown 1966; Conrady 1919)
//! as OpenCV's calib3d writes it, with its rational extension: r² = x² + y²,
//!
//! ```text
//! radial = (1 + k1 r² + k2 r⁴ + k3 r⁶) / (1 + k4 r² + k5 r⁴ + k6 r⁶)
//! x_d = x·radial + 2 p1 x y + p2 (r² + 2x²)
//! y_d = y·radial + p1 (r² + 2y²) + 2 p2 x y
//! ```
//!
//! `pinhole-k3` estimates k1, k2, p1, p2, k3 (k4–k6 = 0), `rational` all eight.
//!
//! `fisheye` is Kannala–Brandt (Kannala & Brandt, IEEE PAMI 28(8), 2006;
//! OpenCV's `cv::fisheye`): r = √(x² + y²), θ = atan r (the angle off the
//! axis), θ_d = θ (1 + k1 θ² + k2 θ⁴ + k3 θ⁶ + k4 θ⁸),
//! (x_d, y_d) = (θ_d / r)(x, y); its k1–k4 are stored in the fields
//! `k1`–`k4` (p1 = p2 = 0).
//!
//! # Inverses
//!
//! Two inverses of Brown–Conrady are here, for two users:
//! - [`Distortion::invert`]: Newton's method with the analytic Jacobian, to a
//!   residual below 10⁻¹³, `None` where it does not converge — the
//!   calibration's (undistortion maps, rays of pixels, validation).
//! - [`Distortion::undistort_fixed_point`]: OpenCV's fixed-point iteration of
//!   `cv::undistortPoints` (x ← (x_d − Δx) / radial), at most 100 steps,
//!   stopping at a step below 10⁻¹⁴ — the renderer's camera rays, kept as
//!   they were so renders stay the same bit for bit.
//!
//! The fisheye inverse ([`Distortion::invert_fisheye`]) solves θ_d(θ) = r_d
//! by Newton's method; points more than 90° off the axis have no pinhole
//! ray (`None`).
//!
//! ```
//! use lucent_lens::{Distortion, DistortionModel, Lens};
//! let lens = Lens { model: DistortionModel::PinholeK3, distortion: Distortion { k1: -0.2, ..Default::default() } };
//! // x = 0.2, y = 0: r² = 0.04, radial = 1 − 0.2·0.04 = 0.992, x_d = 0.1984.
//! let [xd, yd] = lens.distort(0.2, 0.0);
//! assert!((xd - 0.1984).abs() < 1e-15 && yd == 0.0);
//! let [x, y] = lens.undistort(xd, yd).unwrap();
//! assert!((x - 0.2).abs() < 1e-12 && y.abs() < 1e-15);
//! let (x, _) = lens.distortion.undistort_fixed_point(xd, yd);
//! assert!((x - 0.2).abs() < 1e-12);
//! ```

use serde::{Deserialize, Serialize};
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

/// Which distortion coefficients a calibration estimates (the `model` of camera.json).
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

/// A distortion model name that [`DistortionModel::from_name`] does not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown camera model {name:?}; valid: {}", <DistortionModel as VariantNames>::VARIANTS.join(", "))]
pub struct UnknownModel {
    /// The name as given.
    pub name: String,
}

impl DistortionModel {
    /// Any spelling of a model (case ignored).
    pub fn from_name(name: &str) -> Result<Self, UnknownModel> {
        name.trim().parse().map_err(|_| UnknownModel { name: name.to_string() })
    }

    /// The name, as written in camera.json ("pinhole-k3", …).
    pub fn name(self) -> &'static str {
        self.into()
    }
}

/// OpenCV distortion coefficients (dimensionless), as in camera.json; which
/// of them mean what depends on the [`DistortionModel`] (module doc).
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
    /// The eight coefficients with their names, in the order of the struct.
    pub fn named(&self) -> [(&'static str, f64); 8] {
        [
            ("k1", self.k1),
            ("k2", self.k2),
            ("p1", self.p1),
            ("p2", self.p2),
            ("k3", self.k3),
            ("k4", self.k4),
            ("k5", self.k5),
            ("k6", self.k6),
        ]
    }

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

    /// Brown–Conrady (rational): normalised undistorted (x, y) → distorted (x_d, y_d).
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

    /// Brown–Conrady distorted → undistorted normalised coordinates by
    /// Newton's method; `None` where it does not converge (outside the
    /// lens's invertible field).
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

    /// The Brown–Conrady undistorted point that [`apply`](Self::apply)
    /// maps onto (xd, yd), by OpenCV's fixed-point iteration
    /// (`cv::undistortPoints`): x ← (x_d − Δx(x, y)) / radial(r²), at most 100
    /// steps, stopping at a step below 10⁻¹⁴ (or a non-finite one). Always
    /// returns the last iterate: where the iteration does not converge it is
    /// not an inverse.
    ///
    /// Without k4–k6 (`pinhole-k3`) the radial factor is the numerator
    /// 1 + k1 r² + k2 r⁴ + k3 r⁶ alone, computed as the renderer always has.
    pub fn undistort_fixed_point(&self, xd: f64, yd: f64) -> (f64, f64) {
        let rational = self.k4 != 0.0 || self.k5 != 0.0 || self.k6 != 0.0;
        let (mut x, mut y) = (xd, yd);
        for _ in 0..100 {
            let r2 = x * x + y * y;
            let mut radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
            if rational {
                radial /= 1.0 + r2 * (self.k4 + r2 * (self.k5 + r2 * self.k6));
            }
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

/// A lens: its distortion model and coefficients — the one distortion type
/// of the calibration and the renderer.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lens {
    pub model: DistortionModel,
    pub distortion: Distortion,
}

impl Lens {
    /// Normalised undistorted (x, y) → distorted (x_d, y_d) for this model.
    #[inline]
    pub fn distort(&self, x: f64, y: f64) -> [f64; 2] {
        match self.model {
            DistortionModel::Fisheye => self.distortion.apply_fisheye(x, y),
            DistortionModel::PinholeK3 | DistortionModel::Rational => self.distortion.apply(x, y),
        }
    }

    /// Distorted → undistorted normalised coordinates for this model, by
    /// Newton's method ([`Distortion::invert`], [`Distortion::invert_fisheye`]);
    /// `None` where the point has no pinhole ray.
    pub fn undistort(&self, xd: f64, yd: f64) -> Option<[f64; 2]> {
        match self.model {
            DistortionModel::Fisheye => self.distortion.invert_fisheye(xd, yd),
            DistortionModel::PinholeK3 | DistortionModel::Rational => self.distortion.invert(xd, yd),
        }
    }

    /// The first coefficient that is not a finite number, with its name.
    pub fn non_finite(&self) -> Option<(&'static str, f64)> {
        self.distortion.named().into_iter().find(|(_, v)| !v.is_finite())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k3() -> Distortion {
        Distortion { k1: -0.28, k2: 0.09, p1: 0.001, p2: -0.0015, k3: -0.01, ..Default::default() }
    }

    #[test]
    fn inverse_distortion_round_trips() {
        let mut d = k3();
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
    fn fixed_point_inverts_brown_conrady_and_rational() {
        let pinhole = Distortion { k1: -0.28, k2: 0.07, p1: 1e-3, p2: -2e-4, k3: 0.01, ..Default::default() };
        let rational = Distortion { k4: 0.3, k5: 0.01, k6: 0.002, ..pinhole };
        for d in [pinhole, rational] {
            for &(x, y) in &[(0.0, 0.0), (0.3, -0.2), (-0.5, 0.4), (0.1, 0.6)] {
                let [xd, yd] = d.apply(x, y);
                let (xu, yu) = d.undistort_fixed_point(xd, yd);
                assert!((xu - x).abs() < 1e-12 && (yu - y).abs() < 1e-12, "{d:?}: ({x}, {y}) → ({xu}, {yu})");
            }
        }
    }

    #[test]
    fn fixed_point_without_k4_to_k6_is_the_renderers_arithmetic() {
        // The iteration as lucent-render wrote it before this crate, operation for operation.
        let d = k3();
        let before = |xd: f64, yd: f64| {
            let (mut x, mut y) = (xd, yd);
            for _ in 0..100 {
                let r2 = x * x + y * y;
                let radial = 1.0 + r2 * (d.k1 + r2 * (d.k2 + r2 * d.k3));
                let dx = 2.0 * d.p1 * x * y + d.p2 * (r2 + 2.0 * x * x);
                let dy = d.p1 * (r2 + 2.0 * y * y) + 2.0 * d.p2 * x * y;
                let (nx, ny) = ((xd - dx) / radial, (yd - dy) / radial);
                let step = (nx - x).abs().max((ny - y).abs());
                (x, y) = (nx, ny);
                if step < 1e-14 || !step.is_finite() {
                    break;
                }
            }
            (x, y)
        };
        for i in 0..50 {
            let (xd, yd) = (-0.7 + 0.029 * i as f64, 0.55 - 0.021 * i as f64);
            let (a, b) = (d.undistort_fixed_point(xd, yd), before(xd, yd));
            assert!(a.0.to_bits() == b.0.to_bits() && a.1.to_bits() == b.1.to_bits(), "{a:?} {b:?}");
        }
    }

    #[test]
    fn fisheye_round_trips_and_refuses_beyond_90_degrees() {
        let lens = Lens {
            model: DistortionModel::Fisheye,
            distortion: Distortion { k1: -0.02, k2: 0.003, k3: -0.0004, k4: 0.00002, ..Default::default() },
        };
        for (x, y) in [(0.0, 0.0), (0.4, -0.3), (-1.5, 2.0), (8.0, 1.0)] {
            let [xd, yd] = lens.distort(x, y);
            let [xu, yu] = lens.undistort(xd, yd).unwrap();
            assert!((xu - x).abs() < 1e-9 * (1.0 + x.abs()) && (yu - y).abs() < 1e-9 * (1.0 + y.abs()));
        }
        // θ_d ≈ 1.8 rad is past 90° off the axis.
        assert_eq!(lens.undistort(1.8, 0.0), None);
    }

    #[test]
    fn names_and_opencv_order() {
        assert_eq!(DistortionModel::from_name("rational").unwrap(), DistortionModel::Rational);
        assert!(DistortionModel::from_name("fish").unwrap_err().to_string().contains("pinhole-k3, rational, fisheye"));
        assert_eq!(DistortionModel::from_name("Fisheye").unwrap(), DistortionModel::Fisheye);
        assert_eq!(DistortionModel::from_name(" brown-conrady ").unwrap().name(), "pinhole-k3");
        let f = Distortion::from_opencv_fisheye(&[0.1, 0.2, 0.3, 0.4]);
        assert_eq!(f.to_opencv(DistortionModel::Fisheye), [0.1, 0.2, 0.3, 0.4]);
        let d = Distortion::from_opencv(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(d.to_opencv(DistortionModel::PinholeK3), [1.0, 2.0, 3.0, 4.0, 0.0]);
        let lens = Lens { model: DistortionModel::Rational, distortion: Distortion { k5: f64::NAN, ..d } };
        assert_eq!(lens.non_finite().map(|(n, _)| n), Some("k5"));
    }
}
