//! Colour spaces: XYZ ↔ xyY ↔ CIELAB, linear CIE RGB and linear sRGB ↔ XYZ,
//! the sRGB transfer function. The 3 × 3 matrix helpers ([`crate::matrix`])
//! and the xy/xyY conversions ([`crate::chromaticity`]) live in leaf modules
//! and are re-exported here.
//!
//! * XYZ are relative tristimulus values, Y = 1 for the white.
//! * CIELAB (CIE 15:2004 §8.2.1) with the exact constants ε = 216/24389 and
//!   κ = 24389/27, relative to a given white XYZ.
//! * CIE RGB: the CIE 1931 RGB system, primaries 700, 546.1 and 435.8 nm,
//!   white E (R = G = B = 1 ↦ X = Y = Z = 1). Matrix as colour-science has it
//!   (Fairman, Brill & Hemmendinger 1997, "How the CIE 1931 color-matching
//!   functions were derived from Wright–Guild data", Color Res. Appl. 22, 11):
//!   X = 0.49 R + 0.31 G + 0.20 B, Y = 0.1769 R + 0.8124 G + 0.0107 B,
//!   Z = 0.0099 G + 0.9901 B; the inverse is computed.
//! * sRGB (IEC 61966-2-1:1999): Rec. 709 primaries, white D65; the standard's
//!   own 4-digit matrices in both directions (as colour-science uses them, so
//!   a round trip differs from identity by up to 1·10⁻⁴), and the piecewise
//!   transfer function — for display only; all computation is linear.
//! * Conversions are plain arithmetic and never fail: NaN in gives NaN out.
//!
//! ```
//! use lucent_colour::spaces::{self, RgbSpace};
//! let xyz = RgbSpace::CieRgb.to_xyz([1.0, 1.0, 1.0]);
//! assert!(xyz.iter().all(|v| (v - 1.0).abs() < 1e-12));          // white E
//! assert!((spaces::srgb_encode(0.18) - 0.461356129).abs() < 1e-9); // 18 % grey
//! let lab = spaces::xyz_to_lab([0.18, 0.18, 0.18], [1.0, 1.0, 1.0]);
//! assert!((lab[0] - 49.4961).abs() < 1e-4);
//! ```

use crate::adaptation::{adaptation_matrix, Cat};
pub use crate::chromaticity::{xy_to_xyz, xyy_to_xyz, xyz_to_xyy};
pub use crate::matrix::{mat3_inverse, mat3_mul, mat3_vec};
use crate::{ColourError, Mat3};
use strum::{EnumIter, EnumMessage, IntoStaticStr, VariantArray, VariantNames};

/// CIELAB ε = (6/29)³.
pub const LAB_EPSILON: f64 = 216.0 / 24389.0;
/// CIELAB κ = (29/3)³.
pub const LAB_KAPPA: f64 = 24389.0 / 27.0;

fn lab_f(t: f64) -> f64 {
    if t > LAB_EPSILON {
        t.cbrt()
    } else {
        (LAB_KAPPA * t + 16.0) / 116.0
    }
}

fn lab_f_inv(f: f64) -> f64 {
    let t = f * f * f;
    if t > LAB_EPSILON {
        t
    } else {
        (116.0 * f - 16.0) / LAB_KAPPA
    }
}

/// CIE L\*a\*b\* of `xyz` relative to the white `white_xyz` (same scale).
pub fn xyz_to_lab(xyz: [f64; 3], white_xyz: [f64; 3]) -> [f64; 3] {
    let fx = lab_f(xyz[0] / white_xyz[0]);
    let fy = lab_f(xyz[1] / white_xyz[1]);
    let fz = lab_f(xyz[2] / white_xyz[2]);
    [116.0 * fy - 16.0, 500.0 * (fx - fy), 200.0 * (fy - fz)]
}

/// XYZ of CIE L\*a\*b\* relative to `white_xyz`.
pub fn lab_to_xyz(lab: [f64; 3], white_xyz: [f64; 3]) -> [f64; 3] {
    let fy = (lab[0] + 16.0) / 116.0;
    let fx = fy + lab[1] / 500.0;
    let fz = fy - lab[2] / 200.0;
    let y = if lab[0] > LAB_KAPPA * LAB_EPSILON { fy * fy * fy } else { lab[0] / LAB_KAPPA };
    [lab_f_inv(fx) * white_xyz[0], y * white_xyz[1], lab_f_inv(fz) * white_xyz[2]]
}

/// sRGB transfer function (IEC 61966-2-1): linear → encoded, for display.
/// Negative values are mirrored (sign-preserving).
pub fn srgb_encode(v: f64) -> f64 {
    let a = v.abs();
    let e = if a <= 0.0031308 { 12.92 * a } else { 1.055 * a.powf(1.0 / 2.4) - 0.055 };
    e.copysign(v)
}

/// Inverse sRGB transfer function: encoded → linear (sign-preserving).
pub fn srgb_decode(v: f64) -> f64 {
    let a = v.abs();
    let l = if a <= 0.04045 { a / 12.92 } else { ((a + 0.055) / 1.055).powf(2.4) };
    l.copysign(v)
}

/// The linear RGB spaces lucent converts to and from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, IntoStaticStr, VariantArray, VariantNames, EnumMessage, EnumIter)]
pub enum RgbSpace {
    /// CIE 1931 RGB: primaries 700 / 546.1 / 435.8 nm, white E. The space
    /// photos, environment maps and material bands share (docs/method.md#render).
    #[strum(to_string = "CIE RGB", serialize = "CIE 1931 RGB")]
    CieRgb,
    /// Linear sRGB / Rec. 709, white D65.
    #[strum(to_string = "sRGB", serialize = "Rec. 709", serialize = "linear sRGB")]
    Srgb,
}

crate::names::named!(RgbSpace, "RGB space");

const CIE_RGB_TO_XYZ: Mat3 = [[0.49, 0.31, 0.2], [0.1769, 0.8124, 0.0107], [0.0, 0.0099, 0.9901]];
const SRGB_TO_XYZ: Mat3 = [[0.4124, 0.3576, 0.1805], [0.2126, 0.7152, 0.0722], [0.0193, 0.1192, 0.9505]];
const XYZ_TO_SRGB: Mat3 = [[3.2406, -1.5372, -0.4986], [-0.9689, 1.8758, 0.0415], [0.0557, -0.204, 1.057]];

impl RgbSpace {
    /// The name, as written in files ("CIE RGB", "sRGB").
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// The white of the space: E for CIE RGB, D65 for sRGB.
    pub fn white(self) -> crate::Illuminant {
        match self {
            RgbSpace::CieRgb => crate::Illuminant::E,
            RgbSpace::Srgb => crate::Illuminant::D65,
        }
    }

    /// Linear RGB → XYZ matrix.
    pub fn to_xyz_matrix(self) -> Mat3 {
        match self {
            RgbSpace::CieRgb => CIE_RGB_TO_XYZ,
            RgbSpace::Srgb => SRGB_TO_XYZ,
        }
    }

    /// XYZ → linear RGB matrix.
    pub fn from_xyz_matrix(self) -> Mat3 {
        match self {
            RgbSpace::CieRgb => {
                // Invertible by construction (checked in the tests).
                mat3_inverse(&CIE_RGB_TO_XYZ).unwrap_or([[f64::NAN; 3]; 3])
            }
            RgbSpace::Srgb => XYZ_TO_SRGB,
        }
    }

    pub fn to_xyz(self, rgb: [f64; 3]) -> [f64; 3] {
        mat3_vec(&self.to_xyz_matrix(), rgb)
    }

    pub fn from_xyz(self, xyz: [f64; 3]) -> [f64; 3] {
        mat3_vec(&self.from_xyz_matrix(), xyz)
    }

    /// XYZ seen under `source_white_xyz` → linear RGB of this space, adapted
    /// to the space's white with `cat` (None: no adaptation, the colorimetric
    /// conversion). This is colour-science's `XYZ_to_RGB(XYZ, space,
    /// illuminant, chromatic_adaptation_transform)` as one matrix.
    pub fn from_xyz_adapted_matrix(self, source_white_xyz: [f64; 3], cat: Option<Cat>) -> Result<Mat3, ColourError> {
        let m = self.from_xyz_matrix();
        match cat {
            None => Ok(m),
            Some(cat) => Ok(mat3_mul(&m, &adaptation_matrix(source_white_xyz, self.white().white_xyz(), cat)?)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lab_round_trip_and_the_linear_segment() {
        let w = crate::Illuminant::D65.white_xyz();
        for xyz in [[0.2, 0.3, 0.4], [0.001, 0.0008, 0.0012], [0.95, 1.0, 1.09], [0.0, 0.0, 0.0]] {
            let back = lab_to_xyz(xyz_to_lab(xyz, w), w);
            for k in 0..3 {
                assert!((back[k] - xyz[k]).abs() < 1e-14, "{xyz:?} -> {back:?}");
            }
        }
        let lab = xyz_to_lab(w, w);
        assert!((lab[0] - 100.0).abs() < 1e-12 && lab[1].abs() < 1e-12 && lab[2].abs() < 1e-12);
    }

    #[test]
    fn nan_propagates_without_panic() {
        assert!(xyz_to_lab([f64::NAN, 0.2, 0.3], [1.0; 3])[1].is_nan());
        assert!(srgb_encode(f64::NAN).is_nan());
        assert!(xyz_to_xyy([f64::NAN, 0.0, 0.0])[0].is_nan());
        assert!(mat3_inverse(&[[f64::NAN; 3]; 3]).is_err());
        assert!(mat3_inverse(&[[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 0.0, 1.0]]).is_err());
    }

    #[test]
    fn srgb_transfer_function_round_trips() {
        for v in [-0.5, 0.0, 0.001, 0.0031308, 0.04, 0.18, 0.5, 1.0, 2.0] {
            assert!((srgb_decode(srgb_encode(v)) - v).abs() < 1e-12, "{v}");
        }
        // Continuous at the break point (within the standard's rounding).
        assert!((12.92 * 0.0031308 - (1.055 * 0.0031308f64.powf(1.0 / 2.4) - 0.055)).abs() < 1e-7);
    }

    #[test]
    fn rgb_space_names() {
        assert_eq!("cie-rgb".parse::<RgbSpace>().unwrap(), RgbSpace::CieRgb);
        assert_eq!("sRGB".parse::<RgbSpace>().unwrap(), RgbSpace::Srgb);
        assert!("adobe".parse::<RgbSpace>().unwrap_err().to_string().contains("CIE RGB, sRGB"));
    }
}
