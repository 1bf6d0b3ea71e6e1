//! Image alignment by OpenCV's `findTransformECC` (Evangelidis & Psarakis
//! 2008, "Parametric image alignment using enhanced correlation coefficient
//! maximization", IEEE TPAMI 30(10)): the warp `W` that maximises the
//! zero-mean normalised correlation between a template `T(x)` and the
//! warped input `I(W·x)` — insensitive to gain and offset, so a render and
//! a photo that differ in exposure still align. Used by `lucent compare
//! --refine ecc` to separate geometry error (calibration) from appearance
//! error. Plain slices in, a `[[f64; 3]; 3]` out: OpenCV types stay here
//! (the second module of this crate that calls OpenCV, beside [`crate::cv`]).
//!
//! * Coordinates are pixels with the centre of the top-left pixel at (0, 0)
//!   (OpenCV's). `warp` maps a template pixel to where the same content lies
//!   in the input: `(x', y', w)ᵀ = W (x, y, 1)ᵀ`, input at `(x'/w, y'/w)`.
//!   For a translation, `W = [[1, 0, dx], [0, 1, dy], [0, 0, 1]]` means
//!   `input(x + dx, y + dy) ≈ template(x, y)`.
//! * Coarse to fine: the images (and the mask) are halved with `pyrDown`
//!   until the longer side is at most [`PYRAMID_MAX_SIDE`] pixels; ECC runs
//!   on the smallest level from the identity and each result starts the next
//!   finer level (translations ×2 per level; a pyrDown pixel i is centred on
//!   pixel 2i of the level below). Shifts of tens of pixels on a 12-Mpixel
//!   photo are found this way, and the full-resolution pass needs only a few
//!   iterations.
//! * The mask marks the input pixels to use (OpenCV's `inputMask`: nonzero =
//!   valid; OpenCV warps it into the template's frame along with the image).
//!
//! ```
//! use lucent_calib::ecc::{find_transform_ecc, EccOptions, Motion};
//! // A smooth pattern and a copy whose content sits 1.5 px right, 0.5 px up.
//! let (w, h) = (96, 80);
//! let f = |x: f64, y: f64| ((0.21 * x).sin() * (0.17 * y).cos() + 0.3 * (0.05 * (x + y)).sin()) as f32;
//! let template: Vec<f32> = (0..w * h).map(|i| f((i % w) as f64, (i / w) as f64)).collect();
//! let input: Vec<f32> = (0..w * h).map(|i| f((i % w) as f64 - 1.5, (i / w) as f64 + 0.5)).collect();
//! let r = find_transform_ecc(&template, &input, w, h, None, &EccOptions::new(Motion::Translation)).unwrap();
//! assert!((r.warp[0][2] - 1.5).abs() < 0.02 && (r.warp[1][2] + 0.5).abs() < 0.02, "{:?}", r.warp);
//! assert!(r.correlation > 0.99);
//! ```

use crate::error::CalibError;
use opencv::core::{self, Mat, Size, TermCriteria};
use opencv::prelude::*;
use opencv::{imgproc, video};
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

/// Longest side of the coarsest pyramid level (see the module docs).
pub const PYRAMID_MAX_SIDE: usize = 512;

/// The warp's degrees of freedom (OpenCV's `MOTION_*`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage)]
#[strum(serialize_all = "lowercase", ascii_case_insensitive)]
pub enum Motion {
    /// dx, dy (2 parameters).
    Translation,
    /// Rotation and translation (3).
    Euclidean,
    /// 2 × 3 affine matrix (6).
    Affine,
    /// 3 × 3 homography with h₂₂ = 1 (8).
    Homography,
}

impl Motion {
    /// Any spelling of a model (case ignored).
    pub fn from_name(name: &str) -> Result<Self, CalibError> {
        let name = name.trim();
        name.parse().map_err(|_| CalibError::UnknownMotion {
            name: name.to_ascii_lowercase(),
            expected: <Self as strum::VariantNames>::VARIANTS,
        })
    }

    /// The name ("translation", …).
    pub fn name(self) -> &'static str {
        self.into()
    }

    fn opencv(self) -> i32 {
        match self {
            Self::Translation => video::MOTION_TRANSLATION,
            Self::Euclidean => video::MOTION_EUCLIDEAN,
            Self::Affine => video::MOTION_AFFINE,
            Self::Homography => video::MOTION_HOMOGRAPHY,
        }
    }
}

/// Parameters of [`find_transform_ecc`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EccOptions {
    pub motion: Motion,
    /// Iterations per pyramid level at most.
    pub max_iterations: i32,
    /// Stop a level when the correlation changes by less than this.
    pub epsilon: f64,
    /// OpenCV's `gaussFiltSize` (odd; smoothing before the gradients).
    pub gauss_filter_size: i32,
}

impl EccOptions {
    /// 200 iterations, ε = 1e-7, Gaussian 5 × 5.
    pub fn new(motion: Motion) -> Self {
        Self { motion, max_iterations: 200, epsilon: 1e-7, gauss_filter_size: 5 }
    }
}

/// The warp found and how well it aligns.
#[derive(Debug, Clone, PartialEq)]
pub struct EccResult {
    pub motion: Motion,
    /// Template pixel → input pixel (homogeneous; see the module docs).
    /// The last row is (0, 0, 1) except for a homography.
    pub warp: [[f64; 3]; 3],
    /// OpenCV's final enhanced correlation coefficient (1 = perfect).
    pub correlation: f64,
    /// Pyramid levels used (1 = full resolution only).
    pub levels: usize,
}

fn cv_err(context: &'static str) -> impl Fn(opencv::Error) -> CalibError {
    move |e| CalibError::OpenCv { context, message: e.message }
}

fn f32_mat(data: &[f32], width: usize, height: usize) -> Result<Mat, CalibError> {
    let m = Mat::new_rows_cols_with_data(height as i32, width as i32, data).map_err(cv_err("ECC image"))?;
    m.try_clone().map_err(cv_err("ECC image"))
}

fn u8_mat(data: &[u8], width: usize, height: usize) -> Result<Mat, CalibError> {
    let m = Mat::new_rows_cols_with_data(height as i32, width as i32, data).map_err(cv_err("ECC mask"))?;
    m.try_clone().map_err(cv_err("ECC mask"))
}

/// Warp of level `l` → warp of the level below (pixel i ↦ 2i).
fn upscale(w: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    [[w[0][0], w[0][1], 2.0 * w[0][2]], [w[1][0], w[1][1], 2.0 * w[1][2]], [w[2][0] / 2.0, w[2][1] / 2.0, w[2][2]]]
}

/// Finds the warp from `template` to `input` (both `width × height`,
/// single channel, row-major, finite). `mask`: nonzero = input pixel used.
/// Errors if a buffer has the wrong length, the images are smaller than
/// 16 × 16, the mask leaves fewer than 64 pixels, or ECC does not converge
/// (OpenCV: "images may be uncorrelated or non-overlapped").
pub fn find_transform_ecc(
    template: &[f32],
    input: &[f32],
    width: usize,
    height: usize,
    mask: Option<&[u8]>,
    options: &EccOptions,
) -> Result<EccResult, CalibError> {
    let n = width.checked_mul(height);
    if n.is_none_or(|n| template.len() != n || input.len() != n || mask.is_some_and(|m| m.len() != n)) {
        return Err(CalibError::EccBuffers {
            template: template.len(),
            input: input.len(),
            mask: mask.map(<[u8]>::len),
            width,
            height,
        });
    }
    if width < 16 || height < 16 {
        return Err(CalibError::EccTooSmall { width, height });
    }
    if let Some(m) = mask {
        let used = m.iter().filter(|&&v| v != 0).count();
        if used < 64 {
            return Err(CalibError::EccRegion { used });
        }
    }
    if template.iter().chain(input).any(|v| !v.is_finite()) {
        return Err(CalibError::EccNonFinite);
    }
    // Pyramid, finest first.
    let mut levels = vec![(
        f32_mat(template, width, height)?,
        f32_mat(input, width, height)?,
        mask.map(|m| u8_mat(m, width, height)).transpose()?,
    )];
    loop {
        // `levels` starts with one level and only grows.
        let (t, i, m) = &levels[levels.len() - 1];
        let (w, h) = (t.cols() as usize, t.rows() as usize);
        if w.max(h) <= PYRAMID_MAX_SIDE || w.min(h) < 64 {
            break;
        }
        let size = Size::new(w.div_ceil(2) as i32, h.div_ceil(2) as i32);
        let (mut t2, mut i2) = (Mat::default(), Mat::default());
        imgproc::pyr_down(t, &mut t2, size, core::BORDER_REFLECT_101).map_err(cv_err("pyrDown"))?;
        imgproc::pyr_down(i, &mut i2, size, core::BORDER_REFLECT_101).map_err(cv_err("pyrDown"))?;
        let m2 = match m {
            Some(m) => {
                let mut out = Mat::default();
                imgproc::resize(m, &mut out, size, 0.0, 0.0, imgproc::INTER_NEAREST).map_err(cv_err("resize mask"))?;
                Some(out)
            }
            None => None,
        };
        levels.push((t2, i2, m2));
    }
    let count = levels.len();
    let mut warp = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let mut correlation = f64::NAN;
    for (k, (t, i, m)) in levels.iter().enumerate().rev() {
        if k + 1 < count {
            warp = upscale(warp);
        }
        let mut w = if options.motion == Motion::Homography {
            let rows: [[f32; 3]; 3] = warp.map(|r| r.map(|v| v as f32));
            Mat::from_slice_2d(&rows).map_err(cv_err("warp matrix"))?
        } else {
            let rows: [[f32; 3]; 2] = [warp[0].map(|v| v as f32), warp[1].map(|v| v as f32)];
            Mat::from_slice_2d(&rows).map_err(cv_err("warp matrix"))?
        };
        let criteria = TermCriteria {
            typ: core::TermCriteria_COUNT + core::TermCriteria_EPS,
            max_count: options.max_iterations,
            epsilon: options.epsilon,
        };
        let no_mask = Mat::default();
        let mask_mat = m.as_ref().unwrap_or(&no_mask);
        correlation = video::find_transform_ecc(
            t,
            i,
            &mut w,
            options.motion.opencv(),
            criteria,
            mask_mat,
            options.gauss_filter_size,
        )
        .map_err(cv_err("findTransformECC"))?;
        let v: Vec<f32> = if w.is_continuous() {
            w.data_typed::<f32>().map_err(cv_err("warp matrix"))?.to_vec()
        } else {
            w.try_clone().map_err(cv_err("warp matrix"))?.data_typed::<f32>().map_err(cv_err("warp matrix"))?.to_vec()
        };
        let v: Vec<f64> = v.into_iter().map(f64::from).collect();
        warp = match v.len() {
            6 => [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [0.0, 0.0, 1.0]],
            9 => [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]],
            len => {
                return Err(CalibError::OpenCvShape { context: "findTransformECC warp", got: len, expected: "6 or 9" })
            }
        };
    }
    Ok(EccResult { motion: options.motion, warp, correlation, levels: count })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(x: f64, y: f64) -> f32 {
        // Smooth blobs and stripes: informative in both directions.
        let blob = (-((x - 60.0).powi(2) + (y - 45.0).powi(2)) / 300.0).exp();
        (0.4 + 0.25 * (0.19 * x).sin() * (0.13 * y + 0.4).cos() + 0.3 * blob + 0.1 * (0.07 * (x - 2.0 * y)).sin())
            as f32
    }

    fn shifted(w: usize, h: usize, dx: f64, dy: f64, gain: f32) -> Vec<f32> {
        (0..w * h).map(|i| gain * pattern((i % w) as f64 - dx, (i / w) as f64 - dy) + 0.05).collect()
    }

    #[test]
    fn recovers_a_known_subpixel_translation_despite_gain_and_offset() {
        let (w, h) = (160, 120);
        let template = shifted(w, h, 0.0, 0.0, 1.0);
        let input = shifted(w, h, 2.5, -1.25, 0.7);
        let r = find_transform_ecc(&template, &input, w, h, None, &EccOptions::new(Motion::Translation)).unwrap();
        assert!((r.warp[0][2] - 2.5).abs() < 0.05 && (r.warp[1][2] + 1.25).abs() < 0.05, "{:?}", r.warp);
        assert_eq!(r.warp[0][0], 1.0);
        assert!(r.correlation > 0.99);
    }

    #[test]
    fn pyramid_finds_a_large_shift_and_the_mask_is_respected() {
        let (w, h) = (1200, 700);
        let big = |x: f64, y: f64| pattern(x / 6.0, y / 6.0);
        let template: Vec<f32> = (0..w * h).map(|i| big((i % w) as f64, (i / w) as f64)).collect();
        let input: Vec<f32> = (0..w * h).map(|i| big((i % w) as f64 - 14.0, (i / w) as f64 - 9.5)).collect();
        // Mask out nothing useful: only a central rectangle is used.
        let mask: Vec<u8> =
            (0..w * h).map(|i| u8::from((200..1000).contains(&(i % w)) && (100..600).contains(&(i / w)))).collect();
        let r =
            find_transform_ecc(&template, &input, w, h, Some(&mask), &EccOptions::new(Motion::Translation)).unwrap();
        assert!(r.levels >= 2);
        assert!((r.warp[0][2] - 14.0).abs() < 0.05 && (r.warp[1][2] - 9.5).abs() < 0.05, "{:?}", r.warp);
    }

    #[test]
    fn affine_and_homography_start_from_identity() {
        let (w, h) = (160, 120);
        let template = shifted(w, h, 0.0, 0.0, 1.0);
        let input = shifted(w, h, -1.0, 0.5, 1.0);
        for motion in [Motion::Affine, Motion::Homography, Motion::Euclidean] {
            let r = find_transform_ecc(&template, &input, w, h, None, &EccOptions::new(motion)).unwrap();
            assert!((r.warp[0][2] + 1.0).abs() < 0.1 && (r.warp[1][2] - 0.5).abs() < 0.1, "{motion:?} {:?}", r.warp);
            assert!((r.warp[0][0] - 1.0).abs() < 0.01 && (r.warp[2][2] - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let e =
            find_transform_ecc(&[0.0; 10], &[0.0; 10], 5, 2, None, &EccOptions::new(Motion::Translation)).unwrap_err();
        assert!(e.to_string().contains("16 × 16"), "{e}");
        assert!(find_transform_ecc(&[0.0; 10], &[0.0; 9], 5, 2, None, &EccOptions::new(Motion::Translation)).is_err());
        let mut t = vec![0.5f32; 400];
        t[3] = f32::NAN;
        assert!(find_transform_ecc(&t, &[0.5; 400], 20, 20, None, &EccOptions::new(Motion::Affine)).is_err());
        // Flat images: OpenCV reports non-convergence as an error, not a panic.
        assert!(
            find_transform_ecc(&[0.5; 400], &[0.5; 400], 20, 20, None, &EccOptions::new(Motion::Translation)).is_err()
        );
        assert!(Motion::from_name("shear").unwrap_err().to_string().contains("translation, euclidean"));
        assert_eq!(Motion::from_name("Homography").unwrap(), Motion::Homography);
    }
}
