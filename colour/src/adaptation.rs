//! Chromatic adaptation: the von Kries-type matrix that maps XYZ seen under
//! a source white to the corresponding colour under a target white,
//! M = A⁻¹ · diag(ρ_t / ρ_s) · A, with A the transform's "cone" matrix and ρ
//! its responses to the two whites (Fairchild, *Color Appearance Models*,
//! 3rd ed. 2013, ch. 9; colour-science `matrix_chromatic_adaptation_VonKries`).
//!
//! | transform | A (rows) | source |
//! |---|---|---|
//! | Bradford | 0.8951 0.2664 −0.1614 / −0.7502 1.7135 0.0367 / 0.0389 −0.0685 1.0296 | Lam 1985; linearised as in ICC.1 Annex E |
//! | von Kries | 0.40024 0.7076 −0.08081 / −0.2263 1.16532 0.0457 / 0 0 0.91822 | Hunt–Pointer–Estévez, as colour-science |
//! | CAT02 | 0.7328 0.4296 −0.1624 / −0.7036 1.6975 0.0061 / 0.0030 0.0136 0.9834 | CIECAM02 (CIE 159:2004) |
//!
//! Whites are XYZ on any common scale (only their ratios matter).
//!
//! ```
//! use lucent_colour::{adaptation::{adaptation_matrix, Cat}, Illuminant, spaces::mat3_vec};
//! let m = adaptation_matrix(Illuminant::D65.white_xyz(), Illuminant::D50.white_xyz(), Cat::Bradford).unwrap();
//! // The source white maps onto the target white; M[0][0] as colour-science computes it:
//! let w = mat3_vec(&m, Illuminant::D65.white_xyz());
//! assert!((w[0] - Illuminant::D50.white_xyz()[0]).abs() < 1e-12);
//! assert!((m[0][0] - 1.0479297925).abs() < 1e-9);
//! ```

use crate::matrix::{mat3_inverse, mat3_mul, mat3_vec};
use crate::{ColourError, Mat3};
use strum::{EnumIter, EnumMessage, IntoStaticStr, VariantArray, VariantNames};

/// A chromatic adaptation transform.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, IntoStaticStr, VariantArray, VariantNames, EnumMessage, EnumIter)]
pub enum Cat {
    Bradford,
    #[strum(to_string = "von Kries")]
    VonKries,
    #[strum(to_string = "CAT02")]
    Cat02,
}

crate::names::named!(Cat, "chromatic adaptation transform");

impl Cat {
    /// The name, as written in files ("Bradford", "von Kries", "CAT02").
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// The transform's XYZ → "cone" response matrix A.
    pub fn cone_matrix(self) -> Mat3 {
        match self {
            Cat::Bradford => [[0.8951, 0.2664, -0.1614], [-0.7502, 1.7135, 0.0367], [0.0389, -0.0685, 1.0296]],
            Cat::VonKries => [[0.40024, 0.7076, -0.08081], [-0.2263, 1.16532, 0.0457], [0.0, 0.0, 0.91822]],
            Cat::Cat02 => [[0.7328, 0.4296, -0.1624], [-0.7036, 1.6975, 0.0061], [0.0030, 0.0136, 0.9834]],
        }
    }
}

/// The adaptation matrix from `source_white` to `target_white` (XYZ); an
/// error if a white is not finite or gives a zero cone response.
pub fn adaptation_matrix(source_white: [f64; 3], target_white: [f64; 3], cat: Cat) -> Result<Mat3, ColourError> {
    crate::check_finite("source white XYZ", &source_white)?;
    crate::check_finite("target white XYZ", &target_white)?;
    let a = cat.cone_matrix();
    let rs = mat3_vec(&a, source_white);
    let rt = mat3_vec(&a, target_white);
    if rs.iter().any(|v| v.abs() < 1e-12) {
        return Err(ColourError::Invalid {
            what: format!("source white {source_white:?}"),
            reason: format!("a {} cone response is zero", cat.name()),
        });
    }
    let d = [[rt[0] / rs[0], 0.0, 0.0], [0.0, rt[1] / rs[1], 0.0], [0.0, 0.0, rt[2] / rs[2]]];
    Ok(mat3_mul(&mat3_mul(&mat3_inverse(&a)?, &d), &a))
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)]
mod tests {
    use super::*;
    use crate::Illuminant;

    #[test]
    fn identity_for_equal_whites_and_inverse_for_swapped() {
        for cat in <Cat as strum::IntoEnumIterator>::iter() {
            let w = Illuminant::A.white_xyz();
            let m = adaptation_matrix(w, w, cat).unwrap();
            for i in 0..3 {
                for j in 0..3 {
                    assert!((m[i][j] - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
                }
            }
            let f = adaptation_matrix(Illuminant::D65.white_xyz(), Illuminant::D50.white_xyz(), cat).unwrap();
            let b = adaptation_matrix(Illuminant::D50.white_xyz(), Illuminant::D65.white_xyz(), cat).unwrap();
            let p = mat3_mul(&f, &b);
            for i in 0..3 {
                for j in 0..3 {
                    assert!((p[i][j] - if i == j { 1.0 } else { 0.0 }).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn bad_whites_are_errors() {
        assert!(adaptation_matrix([f64::NAN, 1.0, 1.0], [1.0; 3], Cat::Bradford).is_err());
        assert!(adaptation_matrix([0.0; 3], [1.0; 3], Cat::Cat02).is_err());
        assert!("CAT16".parse::<Cat>().unwrap_err().to_string().contains("Bradford, von Kries, CAT02"));
    }
}
