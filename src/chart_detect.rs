//! Automatic ColorChecker Classic 24 detection: OpenCV's `mcc` detector
//! (through `lucent_calib::cv::detect_mcc24`, which returns plain numbers)
//! finds the chart, and this module — in the root crate because it joins the
//! camera crate with the colour crate, which never depend on each other —
//! turns
//! its box into the four outer corners of the patch grid that
//! `lucent_colour::chart::sample_patches` takes, and settles the orientation
//! by the patch colours.
//!
//! Geometry. mcc fits its chart model to the photo and reports the corners
//! of the model's box, 16.75 × 11.25 units (OpenCV 4.6 `CChartModel`,
//! `MCC24`), in the photo. Here that box is taken to hold 24 patches of side
//! 2.5 with gaps of 0.25 (gap ratio 0.10), patch centres 2.75 apart, the
//! first at (1.5, 1.5), i.e. a margin of 0.25 round the grid; on
//! `fixtures/colour/colorchecker.png` the corners so derived land within
//! 2 px of those found by eye (`calib/tests/chart_detect.rs`). The model's patch
//! *centres* are what mcc matched to the photo, so the corners are placed
//! from them: half a patch side beyond the outer centres, with the patch side
//! taken from the centre pitch and the sampling's gap ratio (`gap_ratio`,
//! 0.14 by default in the colour crate): pitch / (1 + gap) / 2 = 0.4386
//! pitches. Sampling with those corners and that gap ratio then puts every
//! sample square on mcc's patch centre.
//!
//! Orientation. A 6 × 4 grid fits its box only with the six-patch side along
//! the box's long side, which leaves four assignments of the chart to the
//! box: as mcc reports it, turned by 180°, and the two mirror images (a chart
//! seen in a mirror; `sample_patches` refuses corners that run
//! anticlockwise, so those count only if the box itself is mirrored). For
//! each, the 24 patches are sampled and a 3 × 3 least-squares matrix (Cheung
//! 2004) is fitted to the references; the assignment with the smallest mean
//! ΔE2000 wins. A detection whose best mean ΔE2000 exceeds
//! [`MAX_MEAN_DE2000`] is not a ColorChecker (or not a usable one) and is
//! reported as not found.
//!
//! The detector runs on 8-bit copies of the image: the values scaled so the
//! 99.5th percentile of each pixel's largest channel is 255, once as they
//! are and once sRGB-encoded (linear RAW data look like a photo only after
//! encoding); the copy that gives the smaller mean ΔE2000 wins.

use lucent_calib::cv::{self, CalibError, MccChart};
use lucent_calib::RgbBuffer;
use lucent_colour::ccm::{fit_colorchecker, CcmMethod};
use lucent_colour::chart::{sample_patches, Homography, ImageRef, SampleOptions, COLS, ROWS};
use lucent_colour::ColourError;

/// Why no ColorChecker was found.
#[derive(Debug, thiserror::Error)]
pub enum ChartError {
    /// OpenCV failed (not: found no chart).
    #[error(transparent)]
    Calib(#[from] CalibError),
    /// The image buffer is not a valid image.
    #[error(transparent)]
    Colour(#[from] ColourError),
    #[error("empty image: {width} × {height} pixels")]
    EmptyImage { width: usize, height: usize },
    #[error("no ColorChecker Classic 24 found: OpenCV's mcc detector found no chart in the image")]
    NotFound,
    #[error(
        "no ColorChecker Classic 24 found: OpenCV's mcc detector found a chart-like region, but its patches do not match the ColorChecker references (mean ΔE00 {mean_de2000:.1} after a 3 × 3 fit, more than {MAX_MEAN_DE2000})"
    )]
    NoMatch { mean_de2000: f64 },
    #[error("no ColorChecker Classic 24 found: OpenCV's mcc detector returned a degenerate box ({0})")]
    DegenerateBox(ColourError),
}

/// mcc's MCC24 model: box size (x along the six-patch side, y along the four).
const MODEL_BOX: [f64; 2] = [16.75, 11.25];
/// mcc's MCC24 model: centre of patch 1 and the centre-to-centre pitch.
const MODEL_FIRST_CENTRE: f64 = 1.5;
const MODEL_PITCH: f64 = 2.75;

/// Largest mean ΔE2000 (3 × 3 fit) of a detection that counts as a chart.
pub const MAX_MEAN_DE2000: f64 = 15.0;

/// A detected chart.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectedChart {
    /// Outer corners of the patch grid, pixels, in the order
    /// `sample_patches` takes: dark skin, bluish green, black, white.
    pub corners: [[f64; 2]; 4],
    /// Centres of the 24 patches, pixels, in reference order (1 = dark skin … 24 = black).
    pub patch_centres: Vec<[f64; 2]>,
    /// mcc's box (grid plus margin), in mcc's order.
    pub mcc_box: [[f64; 2]; 4],
    /// mcc's cost.
    pub mcc_cost: f64,
    /// Mean ΔE2000 of a `Cheung 2004` fit to the patches in the chosen orientation.
    pub mean_de2000: f64,
    /// The same for the best other orientation (infinite if none could be sampled).
    pub other_orientation_de2000: f64,
    /// Which 8-bit copy the detector found it in: "as stored" or "sRGB-encoded".
    pub detected_in: &'static str,
}

/// Finds a ColorChecker Classic 24 in a linear RGB image. `options` gives
/// the gap ratio the corners are placed for and the sample size of the
/// orientation check (its clip level is ignored here). Errors:
/// [`ChartError::NotFound`] when mcc finds no chart, [`ChartError::NoMatch`]
/// when what it finds does not match the references.
pub fn detect_colorchecker(image: &RgbBuffer, options: &SampleOptions) -> Result<DetectedChart, ChartError> {
    if image.width == 0 || image.height == 0 {
        return Err(ChartError::EmptyImage { width: image.width, height: image.height });
    }
    let mut best: Option<DetectedChart> = None;
    let mut rejected: Option<f64> = None;
    for (encode, label) in [(false, "as stored"), (true, "sRGB-encoded")] {
        let rgb8 = to_8bit(image, encode);
        let Some(found) = cv::detect_mcc24(image.width, image.height, &rgb8)? else {
            continue;
        };
        match orient(image, &found, options, label)? {
            Some(d)
                if d.mean_de2000 <= MAX_MEAN_DE2000 && best.as_ref().is_none_or(|b| d.mean_de2000 < b.mean_de2000) =>
            {
                best = Some(d);
            }
            Some(d) if d.mean_de2000 <= MAX_MEAN_DE2000 => {}
            Some(d) => rejected = Some(rejected.map_or(d.mean_de2000, |r: f64| r.min(d.mean_de2000))),
            None => {}
        }
    }
    best.ok_or(match rejected {
        Some(mean_de2000) => ChartError::NoMatch { mean_de2000 },
        None => ChartError::NotFound,
    })
}

/// The image as 8-bit RGB for the detector (see the module docs).
fn to_8bit(image: &RgbBuffer, encode_srgb: bool) -> Vec<u8> {
    let mut peaks: Vec<f32> =
        image.data.chunks_exact(3).map(|p| p[0].max(p[1]).max(p[2])).filter(|v| v.is_finite()).collect();
    peaks.sort_by(f32::total_cmp);
    let white = peaks.get(((peaks.len().saturating_sub(1)) as f64 * 0.995).round() as usize).copied().unwrap_or(1.0);
    let white = if white > 0.0 { white } else { 1.0 };
    image
        .data
        .iter()
        .map(|&v| {
            let v = if v.is_finite() { (v / white).clamp(0.0, 1.0) } else { 0.0 };
            let e = if !encode_srgb {
                v
            } else if v <= 0.003_130_8 {
                12.92 * v
            } else {
                1.055 * v.powf(1.0 / 2.4) - 0.055
            };
            (e * 255.0).round().clamp(0.0, 255.0) as u8
        })
        .collect()
}

/// Maps mcc model coordinates to pixels through the box's homography.
fn model_to_image(found: &MccChart) -> Result<impl Fn(f64, f64) -> [f64; 2] + use<>, ChartError> {
    let b = found.corners;
    // `Homography::from_corners` wants clockwise corners; a mirrored box is
    // handled by mirroring the model's x as well.
    let (corners, mirrored) = match Homography::from_corners(b) {
        Ok(h) => (h, false),
        Err(_) => (Homography::from_corners([b[1], b[0], b[3], b[2]]).map_err(ChartError::DegenerateBox)?, true),
    };
    Ok(move |x: f64, y: f64| {
        let u = x / MODEL_BOX[0];
        corners.map(if mirrored { 1.0 - u } else { u }, y / MODEL_BOX[1])
    })
}

/// The orientation of the patch grid in `found` that best matches the
/// references; `None` if no orientation can be sampled.
fn orient(
    image: &RgbBuffer,
    found: &MccChart,
    options: &SampleOptions,
    label: &'static str,
) -> Result<Option<DetectedChart>, ChartError> {
    let map = model_to_image(found)?;
    let half_side = 0.5 * MODEL_PITCH / (1.0 + options.gap_ratio);
    let lo = MODEL_FIRST_CENTRE - half_side;
    let (hx, hy) = (
        MODEL_FIRST_CENTRE + (COLS - 1) as f64 * MODEL_PITCH + half_side,
        MODEL_FIRST_CENTRE + (ROWS - 1) as f64 * MODEL_PITCH + half_side,
    );
    let (w, h) = (image.width as f64, image.height as f64);
    let clamp = |p: [f64; 2]| [p[0].clamp(0.0, w), p[1].clamp(0.0, h)];
    let [a, b, c, d] = [map(lo, lo), map(hx, lo), map(hx, hy), map(lo, hy)].map(clamp);
    let candidates = [[a, b, c, d], [c, d, a, b], [b, a, d, c], [d, c, b, a]];
    let view = ImageRef::new(image.width, image.height, &image.data)?;
    let check = SampleOptions { clip_level: None, ..options.clone() };
    let mut scored: Vec<([[f64; 2]; 4], f64)> = Vec::new();
    for corners in candidates {
        let Ok(samples) = sample_patches(&view, corners, &check) else {
            continue;
        };
        let rgb: Vec<[f64; 3]> = samples.iter().map(|s| s.mean).collect();
        if let Ok((_, report)) = fit_colorchecker(CcmMethod::Cheung2004, &rgb)
            && report.de2000_mean.is_finite()
        {
            scored.push((corners, report.de2000_mean));
        }
    }
    scored.sort_by(|x, y| x.1.total_cmp(&y.1));
    let Some(&(corners, mean_de2000)) = scored.first() else {
        return Ok(None);
    };
    let hom = Homography::from_corners(corners)?;
    let patch_centres = (0..ROWS * COLS)
        .map(|k| {
            let [u0, v0, u1, v1] = options.sample_square(k);
            hom.map(0.5 * (u0 + u1), 0.5 * (v0 + v1))
        })
        .collect();
    Ok(Some(DetectedChart {
        corners,
        patch_centres,
        mcc_box: found.corners,
        mcc_cost: found.cost,
        mean_de2000,
        other_orientation_de2000: scored.get(1).map_or(f64::INFINITY, |s| s.1),
        detected_in: label,
    }))
}
