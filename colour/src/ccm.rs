//! Colour-correction matrices: camera RGB (linear, e.g. ColorChecker patch
//! means) → CIE XYZ under D50 (Y_white = 1), fitted by least squares over the
//! patches, and their per-patch ΔE00 / ΔE\*ab against the reference
//! L\*a\*b\* (relative to [`crate::data::ICC_D50_XYZ`]).
//!
//! XYZ = M · t(RGB), M a 3 × T matrix and t the method's terms:
//!
//! | method | terms t | fit |
//! |---|---|---|
//! | `Cheung 2004` | R, G, B (T = 3) | linear least squares, min Σ‖M t − XYZ‖² (Cheung, Westland, Connah & Ripamonti 2004, Coloration Technol. 120, 19; colour-science `matrix_colour_correction_Cheung2004`, terms = 3) |
//! | `Finlayson 2015` | R, G, B, √(RG), √(GB), √(RB) (T = 6) | root-polynomial least squares of degree 2: every term scales with exposure, so M t(k·RGB) = k·M t(RGB) — the exposure-invariant variant (Finlayson, Mackiewicz & Hurlbert 2015, IEEE TIP 24, 1460; colour-science `matrix_colour_correction_Finlayson2015`, degree = 2, root_polynomial_expansion = True) |
//! | `Finlayson 1997` | R, G, B (T = 3) | white-point preserving least squares: min Σ‖M t − XYZ‖² subject to M·RGB_white = XYZ_white exactly, so the white patch and (for a linear camera) the whole grey scale map onto the reference neutrals (Finlayson & Drew 1997, "White-point preserving color correction", Proc. IS&T/SID 5th Color Imaging Conf., 258–261) |
//!
//! Least squares is solved by SVD (the Moore–Penrose solution colour-science
//! uses); rank-deficient patch sets are an error. Square roots of negative
//! products (noise in dark patches) are sign-preserving, √x := sign(x)√|x|,
//! as colour-science's `spow`.
//!
//! ```
//! use lucent_colour::ccm::{fit, CcmMethod};
//! use lucent_colour::data::{colorchecker_2014, CHECKER_WHITE};
//! // Camera RGB made from the reference XYZ by a known invertible matrix:
//! let m_cam = [[0.9, 0.2, -0.1], [0.1, 0.8, 0.1], [0.0, 0.1, 0.7]];
//! let xyz: Vec<[f64; 3]> = colorchecker_2014().iter().map(|p| p.xyz()).collect();
//! let rgb: Vec<[f64; 3]> = xyz.iter().map(|x| lucent_colour::spaces::mat3_vec(&m_cam, *x)).collect();
//! let ccm = fit("Cheung 2004".parse().unwrap(), &rgb, &xyz, CHECKER_WHITE).unwrap();
//! let back = ccm.apply(rgb[3]);
//! assert!((back[1] - xyz[3][1]).abs() < 1e-12);
//! ```

use crate::data::{colorchecker_2014, CHECKER_WHITE, ICC_D50_XYZ};
use crate::difference::{delta_e_2000, delta_e_76};
use crate::spaces::xyz_to_lab;
use crate::ColourError;
use nalgebra::{DMatrix, Matrix3, Vector3};
use serde::{Deserialize, Serialize};
use strum::{EnumIter, EnumMessage, IntoStaticStr, VariantArray, VariantNames};

/// A colour-correction method (see the module table).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, IntoStaticStr, VariantArray, VariantNames, EnumMessage, EnumIter)]
pub enum CcmMethod {
    /// 3 × 3 linear least squares.
    #[strum(to_string = "Cheung 2004")]
    Cheung2004,
    /// Root-polynomial (degree 2), exposure invariant, 3 × 6.
    #[strum(to_string = "Finlayson 2015")]
    Finlayson2015,
    /// 3 × 3 white-point preserving least squares.
    #[strum(to_string = "Finlayson 1997")]
    Finlayson1997,
}

crate::names::named!(CcmMethod, "colour-correction method");

impl CcmMethod {
    /// The name, as written in ccm.json ("Cheung 2004", …).
    pub fn name(self) -> &'static str {
        self.into()
    }

    pub fn description(self) -> &'static str {
        match self {
            CcmMethod::Cheung2004 => "3 × 3 linear least squares",
            CcmMethod::Finlayson2015 => "root-polynomial (degree 2) least squares, exposure invariant, 3 × 6",
            CcmMethod::Finlayson1997 => "3 × 3 white-point preserving least squares",
        }
    }

    /// Names of the terms t, in matrix column order.
    pub fn term_names(self) -> &'static [&'static str] {
        match self {
            CcmMethod::Cheung2004 | CcmMethod::Finlayson1997 => &["R", "G", "B"],
            CcmMethod::Finlayson2015 => &["R", "G", "B", "√(RG)", "√(GB)", "√(RB)"],
        }
    }

    pub fn terms(self) -> usize {
        self.term_names().len()
    }

    /// The terms t(rgb); the first `self.terms()` entries are used.
    pub fn expand(self, rgb: [f64; 3]) -> [f64; 6] {
        let [r, g, b] = rgb;
        match self {
            CcmMethod::Cheung2004 | CcmMethod::Finlayson1997 => [r, g, b, 0.0, 0.0, 0.0],
            CcmMethod::Finlayson2015 => [r, g, b, signed_sqrt(r * g), signed_sqrt(g * b), signed_sqrt(r * b)],
        }
    }
}

fn signed_sqrt(x: f64) -> f64 {
    x.abs().sqrt().copysign(x)
}

/// A fitted colour correction: XYZ = M · t(RGB).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ColourCorrection {
    pub method: CcmMethod,
    /// 3 rows (X, Y, Z) × `method.terms()` columns.
    matrix: Vec<Vec<f64>>,
}

impl ColourCorrection {
    /// A correction from a stored matrix (e.g. read back from `ccm.json`);
    /// checks the shape and that every entry is finite.
    pub fn new(method: CcmMethod, matrix: Vec<Vec<f64>>) -> Result<Self, ColourError> {
        let t = method.terms();
        if matrix.len() != 3 || matrix.iter().any(|r| r.len() != t) {
            return Err(ColourError::Invalid {
                what: format!("{method} matrix"),
                reason: format!("must have 3 rows of {t} values ({})", method.term_names().join(", ")),
            });
        }
        for row in &matrix {
            crate::check_finite(&format!("{method} matrix"), row)?;
        }
        Ok(Self { method, matrix })
    }

    pub fn matrix(&self) -> &[Vec<f64>] {
        &self.matrix
    }

    /// XYZ of camera `rgb`. NaN in gives NaN out.
    pub fn apply(&self, rgb: [f64; 3]) -> [f64; 3] {
        let t = self.method.expand(rgb);
        let mut out = [0.0; 3];
        for (o, row) in out.iter_mut().zip(&self.matrix) {
            *o = row.iter().zip(&t).map(|(m, x)| m * x).sum();
        }
        out
    }

    /// Per-patch and summary errors of this correction: `reference_xyz`
    /// against the corrected `camera_rgb`, both as L\*a\*b\* relative to
    /// `white_xyz`; `names` label the patches (may be empty).
    pub fn report(
        &self,
        camera_rgb: &[[f64; 3]],
        reference_xyz: &[[f64; 3]],
        white_xyz: [f64; 3],
        names: &[&str],
    ) -> Result<FitReport, ColourError> {
        check_patches(camera_rgb, reference_xyz)?;
        let patches: Vec<PatchResult> = camera_rgb
            .iter()
            .zip(reference_xyz)
            .enumerate()
            .map(|(i, (rgb, xyz))| {
                let fitted_xyz = self.apply(*rgb);
                let fitted_lab = xyz_to_lab(fitted_xyz, white_xyz);
                let reference_lab = xyz_to_lab(*xyz, white_xyz);
                PatchResult {
                    patch: i + 1,
                    name: names.get(i).map(|s| s.to_string()).unwrap_or_default(),
                    camera_rgb: *rgb,
                    fitted_xyz,
                    reference_xyz: *xyz,
                    fitted_lab,
                    reference_lab,
                    de2000: delta_e_2000(fitted_lab, reference_lab),
                    de76: delta_e_76(fitted_lab, reference_lab),
                }
            })
            .collect();
        let n = patches.len() as f64;
        let mean = |f: fn(&PatchResult) -> f64| patches.iter().map(f).sum::<f64>() / n;
        let max = |f: fn(&PatchResult) -> f64| patches.iter().map(f).fold(f64::NEG_INFINITY, f64::max);
        Ok(FitReport {
            de2000_mean: mean(|p| p.de2000),
            de2000_max: max(|p| p.de2000),
            de76_mean: mean(|p| p.de76),
            de76_max: max(|p| p.de76),
            white_xyz,
            patches,
        })
    }
}

/// One patch of a [`FitReport`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PatchResult {
    /// 1-based patch number.
    pub patch: usize,
    pub name: String,
    pub camera_rgb: [f64; 3],
    pub fitted_xyz: [f64; 3],
    pub reference_xyz: [f64; 3],
    pub fitted_lab: [f64; 3],
    pub reference_lab: [f64; 3],
    pub de2000: f64,
    pub de76: f64,
}

/// Errors of a fitted correction over all patches.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitReport {
    pub de2000_mean: f64,
    pub de2000_max: f64,
    pub de76_mean: f64,
    pub de76_max: f64,
    /// The white of the L\*a\*b\* both sides were compared in.
    pub white_xyz: [f64; 3],
    pub patches: Vec<PatchResult>,
}

fn check_patches(camera_rgb: &[[f64; 3]], reference_xyz: &[[f64; 3]]) -> Result<(), ColourError> {
    if camera_rgb.len() != reference_xyz.len() {
        return Err(ColourError::Length {
            what: "reference XYZ (one per camera RGB patch)".into(),
            expected: camera_rgb.len(),
            got: reference_xyz.len(),
        });
    }
    for (i, (rgb, xyz)) in camera_rgb.iter().zip(reference_xyz).enumerate() {
        if let Some(v) = rgb.iter().chain(xyz).find(|v| !v.is_finite()) {
            return Err(ColourError::NonFinite {
                what: "colour-correction patches".into(),
                index_desc: format!("patch {}", i + 1),
                value: *v,
            });
        }
    }
    Ok(())
}

/// Fits `method` to patches: `camera_rgb[i]` should map to `reference_xyz[i]`.
/// `white_index` (0-based) is the white patch that `Finlayson 1997` maps
/// exactly; the other methods ignore it.
pub fn fit(
    method: CcmMethod,
    camera_rgb: &[[f64; 3]],
    reference_xyz: &[[f64; 3]],
    white_index: usize,
) -> Result<ColourCorrection, ColourError> {
    check_patches(camera_rgb, reference_xyz)?;
    let n = camera_rgb.len();
    let t = method.terms();
    if n < t {
        return Err(ColourError::Invalid {
            what: format!("{method} fit"),
            reason: format!("needs at least {t} patches, got {n}"),
        });
    }
    let a = DMatrix::from_fn(n, t, |i, j| method.expand(camera_rgb[i])[j]);
    let b = DMatrix::from_fn(n, 3, |i, j| reference_xyz[i][j]);
    let svd = a.clone().svd(true, true);
    let smax = svd.singular_values.max();
    let smin = svd.singular_values.min();
    if smax.is_nan() || smax <= 0.0 || smin <= 1e-10 * smax {
        return Err(ColourError::Singular {
            what: format!("{method} fit"),
            reason: format!(
                "the patches' camera terms are (nearly) linearly dependent, singular values {smin:e} … {smax:e}: are the patches all the same colour or all black?"
            ),
        });
    }
    let x = svd
        .solve(&b, 0.0)
        .map_err(|e| ColourError::Singular { what: format!("{method} fit"), reason: e.to_string() })?;
    // x is T × 3; M = xᵀ.
    let mut matrix: Vec<Vec<f64>> = (0..3).map(|r| (0..t).map(|c| x[(c, r)]).collect()).collect();

    if method == CcmMethod::Finlayson1997 {
        if white_index >= n {
            return Err(ColourError::Invalid {
                what: "Finlayson 1997 fit".into(),
                reason: format!("white patch {} does not exist ({n} patches)", white_index + 1),
            });
        }
        // M = M_ls + (x_w − M_ls c_w) c_wᵀ A⁻¹ / (c_wᵀ A⁻¹ c_w), A = Σ c cᵀ.
        let mut ata = Matrix3::zeros();
        for c in camera_rgb {
            let v = Vector3::from(*c);
            ata += v * v.transpose();
        }
        let ata_inv = ata.try_inverse().ok_or_else(|| ColourError::Singular {
            what: "Finlayson 1997 fit".into(),
            reason: "the patches' camera RGB span fewer than 3 dimensions".into(),
        })?;
        let m_ls = Matrix3::from_fn(|r, c| matrix[r][c]);
        let cw = Vector3::from(camera_rgb[white_index]);
        let xw = Vector3::from(reference_xyz[white_index]);
        let a_inv_cw = ata_inv * cw;
        let denom = cw.dot(&a_inv_cw);
        if denom.is_nan() || denom <= 0.0 {
            return Err(ColourError::Invalid {
                what: "Finlayson 1997 fit".into(),
                reason: format!("white patch {} has no camera signal", white_index + 1),
            });
        }
        let m = m_ls + (xw - m_ls * cw) * a_inv_cw.transpose() / denom;
        matrix = (0..3).map(|r| (0..3).map(|c| m[(r, c)]).collect()).collect();
    }
    ColourCorrection::new(method, matrix)
}

/// Fits `method` to the 24 ColorChecker Classic patch means (chart order)
/// against the post-2014 X-Rite references (ICC D50), and reports the
/// per-patch ΔE. The white patch (19) is the one `Finlayson 1997` preserves.
pub fn fit_colorchecker(
    method: CcmMethod,
    camera_rgb: &[[f64; 3]],
) -> Result<(ColourCorrection, FitReport), ColourError> {
    let chart = colorchecker_2014();
    if camera_rgb.len() != chart.len() {
        return Err(ColourError::Length {
            what: "ColorChecker patch means".into(),
            expected: chart.len(),
            got: camera_rgb.len(),
        });
    }
    let reference: Vec<[f64; 3]> = chart.iter().map(|p| p.xyz()).collect();
    let names: Vec<&str> = chart.iter().map(|p| p.name).collect();
    let ccm = fit(method, camera_rgb, &reference, CHECKER_WHITE)?;
    let report = ccm.report(camera_rgb, &reference, ICC_D50_XYZ, &names)?;
    Ok((ccm, report))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn method_registry_parses_and_lists_valid_names() {
        assert_eq!("Cheung 2004".parse::<CcmMethod>().unwrap(), CcmMethod::Cheung2004);
        assert_eq!("finlayson-2015".parse::<CcmMethod>().unwrap(), CcmMethod::Finlayson2015);
        assert_eq!("FINLAYSON_1997".parse::<CcmMethod>().unwrap(), CcmMethod::Finlayson1997);
        let e = "Vandermonde".parse::<CcmMethod>().unwrap_err().to_string();
        assert!(e.contains("Cheung 2004, Finlayson 2015, Finlayson 1997"), "{e}");
        assert!(e.contains("Vandermonde"), "{e}");
    }

    #[test]
    fn bad_input_is_an_error_not_a_panic() {
        let rgb = vec![[0.1, 0.2, 0.3]; 24];
        let xyz = vec![[0.1, 0.2, 0.3]; 24];
        // All patches equal: rank 1.
        assert!(matches!(fit(CcmMethod::Cheung2004, &rgb, &xyz, 18), Err(ColourError::Singular { .. })));
        assert!(matches!(fit(CcmMethod::Cheung2004, &rgb[..2], &xyz[..2], 0), Err(ColourError::Invalid { .. })));
        assert!(matches!(fit(CcmMethod::Cheung2004, &rgb, &xyz[..3], 0), Err(ColourError::Length { .. })));
        let mut bad = rgb.clone();
        bad[5][1] = f64::NAN;
        let e = fit(CcmMethod::Finlayson2015, &bad, &xyz, 18).unwrap_err().to_string();
        assert!(e.contains("patch 6"), "{e}");
        assert!(fit_colorchecker(CcmMethod::Cheung2004, &rgb[..20]).is_err());
        assert!(ColourCorrection::new(CcmMethod::Finlayson2015, vec![vec![1.0; 3]; 3]).is_err());
        assert!(ColourCorrection::new(CcmMethod::Cheung2004, vec![vec![1.0, f64::NAN, 0.0]; 3]).is_err());
    }

    #[test]
    fn signed_square_root() {
        assert_eq!(signed_sqrt(-4.0), -2.0);
        assert_eq!(signed_sqrt(9.0), 3.0);
        assert!(signed_sqrt(f64::NAN).is_nan());
    }
}
