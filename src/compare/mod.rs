//! Photo ↔ render comparison (docs/method.md#compare): error metrics, SSIM, the triplet
//! picture and the difference image, optionally after aligning the render
//! to the photo with OpenCV's ECC (`lucent compare`).
//!
//! Metrics, over the included pixels (all, or a mask's), values in the
//! images' own linear units, difference = render − photo:
//!
//! | name | definition |
//! |---|---|
//! | `rmse` | √(mean over pixels and channels of (r − p)²); per channel: over pixels |
//! | `mean_abs_error` | mean \|r − p\| (total and per channel) |
//! | `relative_error` | Σ\|r − p\| / Σ\|p\| over pixels and channels (robust to dark pixels) |
//! | `ssim.R/G/B` | SSIM of each channel ([`ssim`]: Wang et al. 2004, Gaussian σ = 1.5, 11 taps, K1 = 0.01, K2 = 0.03, stated data range; = scikit-image) |
//! | `ssim.mean_rgb` | mean of the three (what skimage returns with `channel_axis=-1`) |
//! | `ssim.Y` | SSIM of the luminance Y = w·(R, G, B) ([`Luminance`]) |
//!
//! With a mask, the errors are over the mask pixels and each SSIM is the
//! mean of its SSIM map over the mask pixels at least 5 px from the image
//! border (skimage's crop; the windows themselves see all pixels, masked or
//! not). Luminance weights default to the Y row of the CIE 1931 RGB → XYZ
//! matrix (0.1769, 0.8124, 0.0107), the space photos, environment and
//! renders share (docs/method.md#render); Rec. 709 / linear sRGB (0.2126, 0.7152, 0.0722)
//! on request.
//!
//! Refinement ([`Request::refine`]): `lucent_calib::ecc::find_transform_ecc`
//! on the luminance, photo as template and render as input, over the board
//! (printed squares minus the sample) projected from the scene JSON, or the
//! whole image without a scene; the render is then resampled (bilinear) at
//! `W·(x, y, 1)` for every photo pixel, pixels whose source falls outside the
//! render are excluded, and the metrics are computed again.
//!
//! ```
//! use lucent::compare::{metrics, Luminance, Settings};
//! use lucent::compare::ssim::SsimParams;
//! use lucent::imageio::RgbImage;
//! let (w, h) = (24, 16);
//! let photo = RgbImage::new(w, h, (0..w * h * 3).map(|i| 0.3 + 0.2 * ((i % 7) as f32 / 7.0)).collect()).unwrap();
//! let render = RgbImage::new(w, h, photo.data.iter().map(|v| v + 0.1).collect()).unwrap();
//! let settings = Settings { ssim: SsimParams::new(1.0).unwrap(), luminance: Luminance::CieRgb };
//! let m = metrics(&photo, &render, None, &settings).unwrap();
//! assert!((m.rmse - 0.1).abs() < 1e-6 && (m.mean_abs_error - 0.1).abs() < 1e-6);
//! assert!(m.ssim.y < 1.0 && m.ssim.y > 0.9);
//! ```

pub mod band;
mod error;
pub mod input;
mod luminance;
pub mod mask;
pub mod noise;
pub mod photo_noise;
pub mod ssim;
pub mod triplet;

pub use error::{CompareError, ReadProblem};
pub use luminance::Luminance;

use crate::exr::write_channels;
use crate::imageio::RgbImage;
use crate::io::{write_atomic, write_json};
use lucent_calib::ecc::{self, EccOptions, Motion};
use mask::Mask;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use ssim::{Channel, SsimParams, Weighted};
use std::path::{Path, PathBuf};

// The name of a luminance (the error lists the choices) is read here, above
// both: `Luminance` lives beside its weights, `CompareError` with the other
// errors.
impl Luminance {
    /// Any spelling of a choice (case ignored).
    pub fn from_name(name: &str) -> Result<Self, CompareError> {
        name.trim().parse().map_err(|_| CompareError::UnknownLuminance { name: name.to_string() })
    }
}

/// How the metrics are computed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    pub ssim: SsimParams,
    pub luminance: Luminance,
}

/// Three values, one per channel.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Rgb {
    #[serde(rename = "R")]
    pub r: f64,
    #[serde(rename = "G")]
    pub g: f64,
    #[serde(rename = "B")]
    pub b: f64,
}

impl Rgb {
    fn from(v: [f64; 3]) -> Self {
        Self { r: v[0], g: v[1], b: v[2] }
    }
}

/// SSIM per channel, their mean, and of the luminance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SsimSet {
    #[serde(rename = "R")]
    pub r: f64,
    #[serde(rename = "G")]
    pub g: f64,
    #[serde(rename = "B")]
    pub b: f64,
    pub mean_rgb: f64,
    #[serde(rename = "Y")]
    pub y: f64,
    /// SSIM-map pixels averaged (included and ≥ 5 px from the border).
    pub pixels: usize,
}

/// The numbers of one photo/render pair (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Metrics {
    /// Pixels included in the error metrics.
    pub pixels: usize,
    pub rmse: f64,
    pub rmse_channels: Rgb,
    pub mean_abs_error: f64,
    pub mean_abs_error_channels: Rgb,
    pub relative_error: f64,
    pub mean_photo: Rgb,
    pub mean_render: Rgb,
    pub ssim: SsimSet,
}

/// Errors if the images differ in size.
pub fn check_same_size(photo: &RgbImage, render: &RgbImage) -> Result<(), CompareError> {
    if (photo.width, photo.height) != (render.width, render.height) {
        return Err(CompareError::Size {
            first: "the photo".into(),
            first_size: (photo.width, photo.height),
            second: "the render".into(),
            second_size: (render.width, render.height),
        });
    }
    Ok(())
}

#[derive(Clone, Copy, Default)]
struct Sums {
    n: usize,
    sq: [f64; 3],
    abs: [f64; 3],
    abs_photo: f64,
    photo: [f64; 3],
    render: [f64; 3],
}

/// [`metrics`] and the luminance SSIM map (`width × height`).
pub fn metrics_and_ssim_map(
    photo: &RgbImage,
    render: &RgbImage,
    mask: Option<&Mask>,
    settings: &Settings,
) -> Result<(Metrics, Vec<f32>), CompareError> {
    check_same_size(photo, render)?;
    let w = photo.width;
    if let Some(m) = mask
        && (m.width, m.height) != (photo.width, photo.height)
    {
        return Err(CompareError::Size {
            first: "the mask".into(),
            first_size: (m.width, m.height),
            second: "the images".into(),
            second_size: (photo.width, photo.height),
        });
    }
    // Per-row sums, added in row order (deterministic for any thread count).
    let rows: Vec<Sums> = (0..photo.height)
        .into_par_iter()
        .map(|y| {
            let mut s = Sums::default();
            for x in 0..w {
                if mask.is_some_and(|m| !m.get(x, y)) {
                    continue;
                }
                let (p, r) = (photo.pixel(x, y), render.pixel(x, y));
                s.n += 1;
                for c in 0..3 {
                    let (pc, rc) = (f64::from(p[c]), f64::from(r[c]));
                    let d = rc - pc;
                    s.sq[c] += d * d;
                    s.abs[c] += d.abs();
                    s.abs_photo += pc.abs();
                    s.photo[c] += pc;
                    s.render[c] += rc;
                }
            }
            s
        })
        .collect();
    let mut t = Sums::default();
    for s in rows {
        t.n += s.n;
        t.abs_photo += s.abs_photo;
        for c in 0..3 {
            t.sq[c] += s.sq[c];
            t.abs[c] += s.abs[c];
            t.photo[c] += s.photo[c];
            t.render[c] += s.render[c];
        }
    }
    if t.n == 0 {
        return Err(CompareError::EmptyMask { kind: None, path: None });
    }
    let n = t.n as f64;
    let p = &settings.ssim;
    let per: Vec<ssim::Ssim> =
        (0..3).map(|c| ssim::ssim(&Channel(photo, c), &Channel(render, c), p, mask)).collect::<Result<_, _>>()?;
    let lw = settings.luminance.weights();
    let (sy, map) = ssim::ssim_with_map(&Weighted(photo, lw), &Weighted(render, lw), p, mask)?;
    let metrics = Metrics {
        pixels: t.n,
        rmse: ((t.sq[0] + t.sq[1] + t.sq[2]) / (3.0 * n)).sqrt(),
        rmse_channels: Rgb::from(t.sq.map(|v| (v / n).sqrt())),
        mean_abs_error: (t.abs[0] + t.abs[1] + t.abs[2]) / (3.0 * n),
        mean_abs_error_channels: Rgb::from(t.abs.map(|v| v / n)),
        relative_error: (t.abs[0] + t.abs[1] + t.abs[2]) / t.abs_photo,
        mean_photo: Rgb::from(t.photo.map(|v| v / n)),
        mean_render: Rgb::from(t.render.map(|v| v / n)),
        ssim: SsimSet {
            r: per[0].mean,
            g: per[1].mean,
            b: per[2].mean,
            mean_rgb: (per[0].mean + per[1].mean + per[2].mean) / 3.0,
            y: sy.mean,
            pixels: sy.pixels,
        },
    };
    Ok((metrics, map))
}

/// Error metrics and SSIM of `render` against `photo` (same size) over
/// `mask` (None: all pixels).
pub fn metrics(
    photo: &RgbImage,
    render: &RgbImage,
    mask: Option<&Mask>,
    settings: &Settings,
) -> Result<Metrics, CompareError> {
    metrics_and_ssim_map(photo, render, mask, settings).map(|(m, _)| m)
}

/// Luminance plane `w·(R, G, B)` as f32.
pub fn luminance_plane(img: &RgbImage, weights: [f64; 3]) -> Vec<f32> {
    img.data
        .chunks_exact(3)
        .map(|p| (weights[0] * f64::from(p[0]) + weights[1] * f64::from(p[1]) + weights[2] * f64::from(p[2])) as f32)
        .collect()
}

/// Resamples `img` at `W·(x, y, 1)` for every pixel (x, y) (bilinear;
/// pixel centres at integers). Returns the image and the pixels whose
/// source lies inside `img` (others take the nearest edge value).
pub fn warp_bilinear(img: &RgbImage, warp: &[[f64; 3]; 3]) -> (RgbImage, Mask) {
    let (w, h) = (img.width, img.height);
    let mut data = vec![0f32; w * h * 3];
    let mut valid = vec![false; w * h];
    data.par_chunks_mut(3 * w).zip(valid.par_chunks_mut(w)).enumerate().for_each(|(y, (row, ok))| {
        for x in 0..w {
            let (xf, yf) = (x as f64, y as f64);
            let d = warp[2][0] * xf + warp[2][1] * yf + warp[2][2];
            let sx = (warp[0][0] * xf + warp[0][1] * yf + warp[0][2]) / d;
            let sy = (warp[1][0] * xf + warp[1][1] * yf + warp[1][2]) / d;
            let tol = 1e-9;
            ok[x] = sx >= -tol && sy >= -tol && sx <= (w - 1) as f64 + tol && sy <= (h - 1) as f64 + tol;
            let cx = if sx.is_finite() { sx.clamp(0.0, (w - 1) as f64) } else { 0.0 };
            let cy = if sy.is_finite() { sy.clamp(0.0, (h - 1) as f64) } else { 0.0 };
            let (x0, y0) = (cx.floor() as usize, cy.floor() as usize);
            let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
            let (fx, fy) = (cx - x0 as f64, cy - y0 as f64);
            let (a, b, c, e) = (img.pixel(x0, y0), img.pixel(x1, y0), img.pixel(x0, y1), img.pixel(x1, y1));
            for k in 0..3 {
                let top = (1.0 - fx) * f64::from(a[k]) + fx * f64::from(b[k]);
                let bottom = (1.0 - fx) * f64::from(c[k]) + fx * f64::from(e[k]);
                row[3 * x + k] = ((1.0 - fy) * top + fy * bottom) as f32;
            }
        }
    });
    (RgbImage { width: w, height: h, data }, Mask { width: w, height: h, include: valid })
}

/// The value below which a fraction `q` of `values` lie (nearest rank on
/// the sorted values, index round(q·(n − 1))); None if empty.
pub fn percentile(mut values: Vec<f32>, q: f64) -> Option<f32> {
    if values.is_empty() {
        return None;
    }
    let k = ((values.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
    let (_, v, _) = values.select_nth_unstable_by(k, f32::total_cmp);
    Some(*v)
}

fn included<'a>(img: &'a RgbImage, mask: Option<&'a Mask>) -> impl Iterator<Item = &'a [f32]> + 'a {
    img.data.chunks_exact(3).enumerate().filter(move |(i, _)| mask.is_none_or(|m| m.include[*i])).map(|(_, p)| p)
}

/// Automatic display exposure: 1 / (99th percentile of the photo's
/// max(R, G, B) over included pixels); 1 if that is not positive. Returns
/// (exposure, percentile).
pub fn auto_exposure(photo: &RgbImage, mask: Option<&Mask>) -> (f64, f64) {
    let values: Vec<f32> = included(photo, mask).map(|p| p[0].max(p[1]).max(p[2])).collect();
    let p99 = f64::from(percentile(values, 0.99).unwrap_or(0.0));
    (if p99 > 0.0 { 1.0 / p99 } else { 1.0 }, p99)
}

/// Fraction of included pixels with some channel above 1 after × `exposure`
/// (they clip in the picture).
pub fn clipped_fraction(img: &RgbImage, mask: Option<&Mask>, exposure: f64) -> f64 {
    let (mut n, mut clipped) = (0usize, 0usize);
    for p in included(img, mask) {
        n += 1;
        if p.iter().any(|&v| f64::from(v) * exposure > 1.0) {
            clipped += 1;
        }
    }
    clipped as f64 / n.max(1) as f64
}

/// Where the comparison's mask comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum MaskSpec {
    None,
    /// A mask image: nonzero = included.
    Image(PathBuf),
    /// The sample's silhouette from a scene JSON, or, from a render EXR
    /// with an `object` layer (`lucent render`), the pixels where at least
    /// half the camera rays hit the object first (any mesh).
    Object(PathBuf),
    /// The board minus the sample from a scene JSON, or from a render EXR's
    /// `board` layer (at least half the camera rays hit the board first).
    Board(PathBuf),
}

/// Everything `lucent compare` is asked to do.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    pub photo: PathBuf,
    pub render: PathBuf,
    pub mask: MaskSpec,
    /// Scene for the ECC region when the mask is not from a scene.
    pub scene: Option<PathBuf>,
    pub data_range: f64,
    pub luminance: Luminance,
    /// Display exposure; None = [`auto_exposure`].
    pub exposure: Option<f64>,
    /// ECC refinement with this motion model.
    pub refine: Option<Motion>,
    /// Per-pixel variance of the photo (an EXR with `R`, `G`, `B` or
    /// `variance.R/G/B`), for the model RMSE ([`noise`]).
    pub photo_variance: Option<PathBuf>,
    /// A second photo of the same view (same camera, settings and light):
    /// the photo's per-pixel variance is then (P − P₂)² / 2, unbiased for
    /// independent noise (used when `photo_variance` is not given).
    pub photo_repeat: Option<PathBuf>,
    /// A second twin's render: both twins' model RMSE and which is closer.
    pub render_b: Option<PathBuf>,
    /// A mask image (nonzero = included) intersected with an object or
    /// board mask, e.g. the photo's validly recorded pixels (`lucent raw
    /// clipped`): `--mask` given together with `--mask-object` or `--mask-board`.
    pub mask_also: Option<PathBuf>,
    /// What the two twins are (e.g. "recipe", "fitted"), for the rows of
    /// triplet.png; `None`: "A" and "B" with their files.
    pub twin_names: Option<[String; 2]>,
    /// Each twin's bands (its `uncertainty.json` from `lucent render
    /// --uncertainty`), in the order of the renders: is the photo within its
    /// predictive band over the object or board mask ([`band`])?
    pub bands: Vec<band::TwinBands>,
}

/// `twins` in metrics.json: the second render against the first.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TwinsReport {
    pub render_a: String,
    pub render_b: String,
    /// The second twin's metrics and model RMSE over the same pixels.
    pub metrics_b: Metrics,
    pub noise_b: noise::NoiseReport,
    /// The second twin's SSIM extrapolated to zero render noise.
    #[serde(default)]
    pub ssim_at_zero_noise_b: Option<noise::SsimAtZeroNoise>,
    pub paired: noise::PairedReport,
}

/// `mask` in metrics.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MaskReport {
    /// "none", "image", "object" or "board".
    pub source: String,
    pub path: Option<String>,
    pub included_pixels: usize,
    pub included_fraction: f64,
}

/// How the numbers are defined, in metrics.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Definitions {
    pub difference: String,
    pub ssim: String,
    pub ssim_parameters: SsimParams,
    pub ssim_window_taps: usize,
    pub ssim_border_px: usize,
    pub ssim_with_mask: String,
    pub luminance: String,
    pub luminance_weights: [f64; 3],
    pub relative_error: String,
}

/// `refined` in metrics.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Refinement {
    pub method: String,
    pub motion: String,
    /// Photo pixel → render pixel, homogeneous, row-major.
    pub warp: [[f64; 3]; 3],
    pub warp_convention: String,
    /// Displacement W·c − c of the image centre c, pixels (= (dx, dy) for a translation).
    pub shift_px: [f64; 2],
    pub correlation: f64,
    pub pyramid_levels: usize,
    pub region: String,
    pub region_pixels: usize,
    /// Included pixels dropped because their source lies outside the render.
    pub outside_render_pixels: usize,
    pub metrics: Metrics,
}

/// `display` in metrics.json: how triplet.png shows the images.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DisplayReport {
    pub exposure: f64,
    pub exposure_source: String,
    pub transfer: String,
    pub difference: String,
    pub difference_colour_map: String,
    /// The colour bar spans ± this (linear units).
    pub difference_range: f64,
    pub difference_range_source: String,
    pub clipped_fraction_photo: f64,
    pub clipped_fraction_render: f64,
    pub clipped_fraction_difference: f64,
    pub masked_pixels: String,
}

/// metrics.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Report {
    pub lucent_version: String,
    pub photo: String,
    pub render: String,
    pub width: usize,
    pub height: usize,
    pub channels: Vec<String>,
    pub mask: MaskReport,
    pub definitions: Definitions,
    pub as_calibrated: Metrics,
    /// The model RMSE with the expected noise removed, its 95 % interval and
    /// the noise floor (as calibrated), when the render carries its variance.
    #[serde(default)]
    pub noise: Option<noise::NoiseReport>,
    /// With a second render: both twins and which is closer.
    #[serde(default)]
    pub twins: Option<TwinsReport>,
    /// SSIM (Y) extrapolated to zero render noise from the render's two
    /// half renders, when its EXR carries them.
    #[serde(default)]
    pub ssim_at_zero_noise: Option<noise::SsimAtZeroNoise>,
    pub refined: Option<Refinement>,
    /// Per twin given a band (`--band`): is the photo within its predictive band?
    #[serde(default)]
    pub bands: Vec<band::BandCheck>,
    /// Per render that approximates (its `render.json`'s `approximations`,
    /// e.g. the similar medium with its measured bias on the object's
    /// interior): what the difference on the object includes besides the
    /// twin. Empty for exact renders and renders without a render.json.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub approximations: Vec<RenderApproximations>,
    pub display: DisplayReport,
    pub files: Vec<String>,
}

/// The result of [`compare_files`], ready to be written by [`write_outputs`].
pub struct Outcome {
    pub report: Report,
    pub triplet_png: Vec<u8>,
    pub width: usize,
    pub height: usize,
    /// Channels of difference.exr.
    pub difference: Vec<(String, Vec<f32>)>,
    /// band.png ([`BAND_PNG`]): the photo against each twin's band, with `--band`.
    pub band_png: Option<Vec<u8>>,
    /// Things the user should know (clipping, ECC region), for stderr.
    pub notes: Vec<String>,
}

/// The include mask of a render EXR's `layer` ("object" or "board"): the
/// pixels whose fraction is at least ½.
fn mask_from_render_layer(path: &Path, layer: &'static str, w: usize, h: usize) -> Result<Mask, CompareError> {
    let role = if layer == "object" { "--mask-object" } else { "--mask-board" };
    let read = |reason: ReadProblem| CompareError::Read { role, path: path.to_path_buf(), reason };
    let (mw, mh, ch) =
        crate::exr::read_channels(path, &[layer]).map_err(|e| read(ReadProblem::Exr(Box::new(e.problem))))?;
    if (mw, mh) != (w, h) {
        return Err(read(ReadProblem::Invalid(format!(
            "its {layer} layer is {mw} × {mh} pixels, the photo {w} × {h}"
        ))));
    }
    if let Some(v) = ch[0].iter().find(|v| !(v.is_finite() && (0.0..=1.0).contains(*v))) {
        return Err(read(ReadProblem::Invalid(format!("its {layer} layer holds {v}, not a fraction in [0, 1]"))));
    }
    Ok(Mask { width: w, height: h, include: ch[0].iter().map(|&f| f >= 0.5).collect() })
}

/// The variance layers of lucent render's EXR.
const VARIANCE_CHANNELS: [&str; 3] = ["variance.R", "variance.G", "variance.B"];

/// Three planes as interleaved RGB.
/// A compared render's approximations, read from the `render.json` beside
/// its EXR (`metrics.json` `approximations`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RenderApproximations {
    /// The render's EXR.
    pub render: String,
    /// Each approximation with its measured bias, as render.json states it.
    pub approximations: Vec<String>,
}

/// The approximations `render` (an EXR) was made with, from the
/// `render.json` beside it; `None` when there is none or it lists none.
/// An unreadable render.json is a note, not an error: the EXR holds the
/// image that is compared.
fn render_approximations(render: &Path, notes: &mut Vec<String>) -> Option<RenderApproximations> {
    let json = render.with_file_name(crate::scene::RenderFiles::JSON);
    let text = std::fs::read_to_string(&json).ok()?;
    #[derive(Deserialize)]
    struct Approximations {
        #[serde(default)]
        approximations: Vec<String>,
    }
    match serde_json::from_str::<Approximations>(&text) {
        Ok(a) if !a.approximations.is_empty() => {
            Some(RenderApproximations { render: render.display().to_string(), approximations: a.approximations })
        }
        Ok(_) => None,
        Err(e) => {
            notes.push(format!(
                "{}: not a render.json ({e}); the approximations of {} are unknown",
                json.display(),
                render.display()
            ));
            None
        }
    }
}

fn interleave(ch: &[Vec<f32>]) -> Vec<f32> {
    (0..ch[0].len()).flat_map(|i| [ch[0][i], ch[1][i], ch[2][i]]).collect()
}

/// Reads `variance.R/G/B` of a render EXR, interleaved; `None` if it has none.
fn render_variance(path: &Path) -> Option<Vec<f32>> {
    if crate::imageio::extension(path) != "exr" {
        return None;
    }
    let (_, _, ch) = crate::exr::read_channels(path, &VARIANCE_CHANNELS).ok()?;
    Some(interleave(&ch))
}

/// The half-render layers of lucent render's EXR.
const HALF_CHANNELS: [[&str; 3]; 2] = [["half_a.R", "half_a.G", "half_a.B"], ["half_b.R", "half_b.G", "half_b.B"]];

/// SSIM (Y) of the photo against the render at `path` without its noise,
/// from its two half renders ([`noise::ssim_at_zero_noise`]);
/// `None` with a note when its EXR has no half renders or a pixel has fewer
/// than two samples. `full_map` is SSIM(photo, render)'s map.
fn ssim_zero_noise_report(
    path: &Path,
    photo: &RgbImage,
    full_map: &[f32],
    mask: Option<&Mask>,
    settings: &Settings,
    notes: &mut Vec<String>,
) -> Result<Option<noise::SsimAtZeroNoise>, CompareError> {
    if crate::imageio::extension(path) != "exr" {
        return Ok(None);
    }
    let (w, h) = (photo.width, photo.height);
    let read = |names: &[&str]| crate::exr::read_channels(path, names).ok().filter(|g| (g.0, g.1) == (w, h));
    let (Some(a), Some(b)) = (read(&HALF_CHANNELS[0]), read(&HALF_CHANNELS[1])) else {
        notes.push(format!(
            "{} has no half renders (half_a/half_b of lucent render's EXR): no SSIM at zero render noise",
            path.display()
        ));
        return Ok(None);
    };
    let include = ssim::mean_pixels(w, h, &settings.ssim, mask);
    if let Some(spp) = read(&["spp"])
        && spp.2[0].iter().zip(&include).any(|(n, &inc)| inc && *n < 2.0)
    {
        notes.push(format!(
            "{}: some pixels have fewer than 2 samples, so a half render is empty there: no SSIM at zero render noise",
            path.display()
        ));
        return Ok(None);
    }
    let invalid =
        |e: String| CompareError::Read { role: "render", path: path.to_path_buf(), reason: ReadProblem::Invalid(e) };
    let lw = settings.luminance.weights();
    let y_of = |ch: &[Vec<f32>]| -> Vec<f64> {
        (0..w * h).map(|i| (0..3).map(|c| lw[c] * f64::from(ch[c][i])).sum()).collect()
    };
    let py: Vec<f64> = photo.data.chunks_exact(3).map(|p| (0..3).map(|c| lw[c] * f64::from(p[c])).sum()).collect();
    let free = ssim::ssim_map_noise_free(&py, &y_of(&a.2), &y_of(&b.2), w, h, &settings.ssim)?;
    let r = noise::ssim_at_zero_noise(w, h, full_map, &free, &include, NOISE_BLOCK_PX, NOISE_RESAMPLES, 1)
        .map_err(|e| invalid(e.to_string()))?;
    if r.correction > 0.05 {
        notes.push(format!(
            "{}: the render's noise lowers SSIM by {:.3}; at such noise the SSIM at zero render noise may still \
             fall short of the converged value by up to ≈ 10–20 % of that (render more samples to trust its interval)",
            path.display(),
            r.correction
        ));
    }
    Ok(Some(r))
}

/// The second twin `path_b` against the first: its metrics and model RMSE,
/// and the paired test of which is closer (both renders need their variance);
/// with the second render, for the picture.
fn twins_report(
    req: &Request,
    path_b: &Path,
    photo: &RgbImage,
    (render_a, var_a): (&RgbImage, Option<&[f32]>),
    mask: Option<&Mask>,
    settings: &Settings,
    notes: &mut Vec<String>,
) -> Result<(TwinsReport, RgbImage), CompareError> {
    let loaded = input::read_image(path_b, "render B")?;
    check_same_size(photo, &loaded.image)?;
    let b = &loaded.image;
    let no_variance = |path: &Path| CompareError::Read {
        role: "render",
        path: path.to_path_buf(),
        reason: ReadProblem::Invalid(
            "comparing two twins needs each render's variance (variance.R/G/B of lucent render's EXR)".into(),
        ),
    };
    let var_a = var_a.ok_or_else(|| no_variance(&req.render))?;
    let var_b = render_variance(path_b).ok_or_else(|| no_variance(path_b))?;
    let (metrics_b, map_b) = metrics_and_ssim_map(photo, b, mask, settings)?;
    let ssim_at_zero_noise_b = ssim_zero_noise_report(path_b, photo, &map_b, mask, settings, notes)?;
    let noise_b = noise_report(req, path_b, Some(&var_b), photo, b, mask, notes)?.ok_or_else(|| no_variance(path_b))?;
    let paired = noise::paired(
        photo.width,
        photo.height,
        &photo.data,
        (&render_a.data, var_a),
        (&b.data, &var_b),
        mask.map(|m| m.include.as_slice()),
        (PAIRED_CELL_PX, NOISE_BLOCK_PX),
        0.05,
    )
    .map_err(|e| CompareError::Read {
        role: "render B",
        path: path_b.to_path_buf(),
        reason: ReadProblem::Invalid(e.to_string()),
    })?;
    let report = TwinsReport {
        render_a: req.render.display().to_string(),
        render_b: path_b.display().to_string(),
        metrics_b,
        noise_b,
        ssim_at_zero_noise_b,
        paired,
    };
    Ok((report, loaded.image))
}

/// A photo's variance image is implausible above this multiple of the
/// squared photo value (the photo's mean value as the floor, so dark pixels
/// are not judged by a value near 0): a variance 100 × the signal squared
/// is a noise standard deviation 10 × the signal, which no exposed photo has.
pub const MAX_PHOTO_VARIANCE_RATIO: f64 = 100.0;

/// Checks a photo's variance (interleaved RGB, the photo's size): every
/// value finite and ≥ 0, and in at least half the values not above
/// [`MAX_PHOTO_VARIANCE_RATIO`] × max(photo value, the photo's mean)².
/// The reason names the pixel and channel.
pub fn check_photo_variance(v: &[f32], photo: &RgbImage) -> Result<(), String> {
    let w = photo.width.max(1);
    let at = |i: usize| format!("pixel ({}, {}) channel {}", (i / 3) % w, i / 3 / w, ["R", "G", "B"][i % 3]);
    if let Some(i) = v.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
        return Err(format!("{} is {}: a variance must be a finite number ≥ 0", at(i), v[i]));
    }
    let finite: Vec<f64> = photo.data.iter().map(|&p| f64::from(p)).filter(|p| p.is_finite()).collect();
    let mean = finite.iter().map(|p| p.abs()).sum::<f64>() / finite.len().max(1) as f64;
    if mean.is_nan() || mean <= 0.0 {
        return Ok(());
    }
    let bound = |i: usize| MAX_PHOTO_VARIANCE_RATIO * f64::from(photo.data[i]).abs().max(mean).powi(2);
    let above: Vec<usize> = (0..v.len().min(photo.data.len())).filter(|&i| f64::from(v[i]) > bound(i)).collect();
    if !v.is_empty() && 2 * above.len() > v.len() {
        let i = above[0];
        return Err(format!(
            "the variance is above {MAX_PHOTO_VARIANCE_RATIO} × the squared photo value in {:.0} % of the values \
             (e.g. {}: variance {:.4e}, photo {:.4e}; the photo's mean {mean:.4e} is the floor of the photo value): \
             a noise standard deviation of more than 10 × the signal is no photo's; is this the photo's variance \
             (e.g. from `lucent colour apply --variance-out`), not an image or another quantity?",
            100.0 * above.len() as f64 / v.len() as f64,
            at(i),
            v[i],
            photo.data[i]
        ));
    }
    Ok(())
}

/// The model RMSE of `render` against `photo` ([`noise::model_rmse`] with
/// `lucent compare`'s block size [`NOISE_BLOCK_PX`], [`NOISE_RESAMPLES`]
/// resamples and seed 1) given the variance of the render's pixel means and,
/// if known, the photo's (`variances`: both interleaved RGB of the images'
/// size), over `mask`'s pixels. Pushes to `notes` what `lucent compare`
/// says about the result: too few bootstrap blocks, and a photo variance
/// (named `photo_variance_name` in the message) larger than the mean squared
/// difference of the images. `render_variance` and `photo_variance` of the
/// report are left empty for the caller to say where they come from. The
/// photo variance is taken as given: [`check_photo_variance`] checks that it
/// is plausible.
pub fn model_error(
    photo: &RgbImage,
    render: &RgbImage,
    (render_variance, photo_variance): (&[f32], Option<&[f32]>),
    mask: Option<&Mask>,
    photo_variance_name: Option<&str>,
    notes: &mut Vec<String>,
) -> Result<noise::NoiseReport, noise::NoiseError> {
    let input = noise::NoiseInput {
        width: photo.width,
        height: photo.height,
        photo: &photo.data,
        render: &render.data,
        render_variance,
        photo_variance,
        include: mask.map(|m| m.include.as_slice()),
    };
    let report = noise::model_rmse(&input, NOISE_BLOCK_PX, NOISE_RESAMPLES, 1)?;
    if report.blocks < noise::MIN_BLOCKS {
        notes.push(format!(
            "the model RMSE's interval rests on {} blocks of {NOISE_BLOCK_PX} × {NOISE_BLOCK_PX} px (fewer than {}): \
             too few to trust; compare a larger region or image",
            report.blocks,
            noise::MIN_BLOCKS
        ));
    }
    if let (Some(name), Some(v)) = (photo_variance_name, photo_variance) {
        // The photo and render differ by at least the photo's noise: a photo
        // variance above their mean squared difference does not describe them.
        let included = |i: usize| mask.is_none_or(|m| m.include.get(i / 3).copied().unwrap_or(false));
        let (mut sum_v, mut sum_d, mut n) = (0.0f64, 0.0f64, 0usize);
        for i in (0..v.len().min(photo.data.len()).min(render.data.len())).filter(|&i| included(i)) {
            let d = f64::from(photo.data[i]) - f64::from(render.data[i]);
            if d.is_finite() {
                sum_v += f64::from(v[i]);
                sum_d += d * d;
                n += 1;
            }
        }
        if n > 0 && sum_v > sum_d {
            notes.push(format!(
                "warning: the photo variance {name} (mean {:.4e}) is larger than the mean squared difference of photo \
                 and render ({:.4e}), which holds the photo's noise and more: the model RMSE comes out 0 and means \
                 nothing; check that {name} is the photo's variance (not a radiance image)",
                sum_v / n as f64,
                sum_d / n as f64,
            ));
        }
    }
    Ok(report)
}

/// The photo's per-pixel variance (interleaved RGB): `--photo-variance`,
/// else (P − P₂)²/2 from `--photo-repeat`, else `None`.
fn photo_variance(req: &Request, photo: &RgbImage) -> Result<Option<Vec<f32>>, CompareError> {
    Ok(match &req.photo_variance {
        None => match &req.photo_repeat {
            None => None,
            Some(p2) => {
                let second = input::read_image(p2, "second photo")?;
                check_same_size(photo, &second.image)?;
                Some(
                    photo
                        .data
                        .iter()
                        .zip(&second.image.data)
                        .map(|(a, b)| (0.5 * (f64::from(*a) - f64::from(*b)).powi(2)) as f32)
                        .collect(),
                )
            }
        },
        Some(p) => {
            let read = |reason: String| CompareError::Read {
                role: "photo variance",
                path: p.clone(),
                reason: ReadProblem::Invalid(reason),
            };
            let got = crate::exr::read_channels(p, &VARIANCE_CHANNELS)
                .or_else(|_| crate::exr::read_channels(p, &["R", "G", "B"]))
                .map_err(|e| CompareError::Read {
                    role: "photo variance",
                    path: p.clone(),
                    reason: ReadProblem::Exr(Box::new(e.problem)),
                })?;
            if (got.0, got.1) != (photo.width, photo.height) {
                return Err(read(format!(
                    "{} × {} pixels, the photo {} × {}",
                    got.0, got.1, photo.width, photo.height
                )));
            }
            let v = interleave(&got.2);
            check_photo_variance(&v, photo).map_err(read)?;
            Some(v)
        }
    })
}

/// The model RMSE of the render at `render_path` given its variance
/// (`variance.R/G/B` of its EXR, read by [`render_variance`]); `None` with a
/// note when it has none.
#[allow(clippy::too_many_arguments)]
fn noise_report(
    req: &Request,
    render_path: &Path,
    render_variance: Option<&[f32]>,
    photo: &RgbImage,
    render: &RgbImage,
    mask: Option<&Mask>,
    notes: &mut Vec<String>,
) -> Result<Option<noise::NoiseReport>, CompareError> {
    // Read (and checked) even when the render gives no variance to use it
    // with: a photo variance or repeat that cannot be read is an error, not
    // silently passed over.
    let photo_variance = photo_variance(req, photo)?;
    let Some(render_variance) = render_variance else {
        notes.push(format!(
            "{} has no variance layers (variance.R/G/B of lucent render's EXR): no model RMSE",
            render_path.display()
        ));
        return Ok(None);
    };
    let photo_variance_name = req.photo_variance.as_ref().map(|p| p.display().to_string());
    let mut report = model_error(
        photo,
        render,
        (render_variance, photo_variance.as_deref()),
        mask,
        photo_variance_name.as_deref(),
        notes,
    )
    .map_err(|e| CompareError::Read {
        role: "render variance",
        path: render_path.to_path_buf(),
        reason: ReadProblem::Invalid(e.to_string()),
    })?;
    report.render_variance = format!("{}: variance.R/G/B (variance of each pixel's mean)", render_path.display());
    report.photo_variance = match (&req.photo_variance, &req.photo_repeat) {
        (Some(p), _) => format!("{}", p.display()),
        (None, Some(p2)) => {
            format!("from two photos of the same view: (P - P2)^2 / 2 per pixel and channel, P2 = {}", p2.display())
        }
        (None, None) => PHOTO_VARIANCE_NOT_GIVEN.into(),
    };
    if let Some(p) = &req.photo_variance {
        let json = photo_noise::sidecar(p);
        if json.is_file() {
            let text = crate::io::read_text(&json).map_err(|source| CompareError::Io { path: json.clone(), source })?;
            let file: photo_noise::PhotoVarianceFile = serde_json::from_str(&text).map_err(|e| CompareError::Read {
                role: "photo variance",
                path: json.clone(),
                reason: ReadProblem::Invalid(format!("not the sidecar of `lucent colour apply --variance-out`: {e}")),
            })?;
            report.photo_variance = format!(
                "{}: the RAW photo's noise model ({}) developed like the photo",
                p.display(),
                match file.noise_model.source {
                    lucent_calib::noise::NoiseSource::DngNoiseProfile => "its DNG NoiseProfile",
                    lucent_calib::noise::NoiseSource::EstimatedFromImage => "estimated from the photo itself",
                }
            );
            report.photo_noise = Some(file);
        }
    }
    Ok(Some(report))
}

/// `photo_variance` of the model RMSE's report without a photo variance.
pub const PHOTO_VARIANCE_NOT_GIVEN: &str = "not given (0): the model RMSE still contains the photo's noise";

/// Block side of the model RMSE's bootstrap, pixels.
pub const NOISE_BLOCK_PX: usize = 8;

/// Side of the cells whose means the paired test of two twins compares, in
/// pixels ([`noise::paired`]): a twin's model error is smooth over a few
/// pixels, a render's noise is not.
pub const PAIRED_CELL_PX: usize = 8;
/// Bootstrap resamples of the model RMSE's interval.
pub const NOISE_RESAMPLES: usize = 1000;

/// Output file names inside the folder ([`CompareFiles::NAMES`]).
pub const FILES: [&str; 3] = CompareFiles::NAMES;

/// The picture of `--band`'s check, beside [`FILES`] when bands are given.
pub const BAND_PNG: &str = "band.png";

/// The files of a comparison in its output folder, each name spelled here
/// once: the [`Report`] (`metrics`), the photo | render | difference picture
/// (`triplet`), the difference image (`difference`) and, with `--band`, the
/// photo against the twins' bands (`band_png`). Written by
/// [`write_outputs`], read by `lucent run`'s report.
///
/// ```
/// use lucent::compare::CompareFiles;
/// let f = CompareFiles::in_dir(std::path::Path::new("out/compare/s1"));
/// assert_eq!(f.metrics, std::path::Path::new("out/compare/s1/metrics.json"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CompareFiles {
    pub metrics: PathBuf,
    pub triplet: PathBuf,
    pub difference: PathBuf,
    pub band_png: PathBuf,
}

impl CompareFiles {
    /// The names of the files every comparison writes.
    pub const NAMES: [&'static str; 3] = ["metrics.json", "triplet.png", "difference.exr"];

    /// The files of the comparison whose output folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [metrics, triplet, difference] = Self::NAMES.map(|n| dir.join(n));
        Self { metrics, triplet, difference, band_png: dir.join(BAND_PNG) }
    }
}

/// Reads, checks and compares the images of `req`; nothing is written.
pub fn compare_files(req: &Request) -> Result<Outcome, CompareError> {
    let settings = Settings { ssim: SsimParams::new(req.data_range)?, luminance: req.luminance };
    if let Some(k) = req.exposure
        && !(k.is_finite() && k > 0.0)
    {
        return Err(CompareError::NotPositive { what: "exposure", value: k });
    }
    let photo = input::read_image(&req.photo, "photo")?;
    let render = input::read_image(&req.render, "render")?;
    if photo.channels.len() != render.channels.len() {
        return Err(CompareError::Channels { photo: photo.channels.clone(), render: render.channels.clone() });
    }
    check_same_size(&photo.image, &render.image)?;
    let (w, h) = (photo.image.width, photo.image.height);
    let (photo_img, render_img) = (&photo.image, &render.image);

    let Selection { mask, source, path: mask_path, scene } = select_pixels(req, w, h)?;
    let mask_path = mask_path.as_ref();
    let twin_bands = band_regions(req, source)?;
    let mut notes: Vec<String> = Vec::new();

    let (calibrated, ssim_map) = metrics_and_ssim_map(photo_img, render_img, mask.as_ref(), &settings)?;
    let render_var = render_variance(&req.render);
    let noise =
        noise_report(req, &req.render, render_var.as_deref(), photo_img, render_img, mask.as_ref(), &mut notes)?;
    let ssim_at_zero_noise =
        ssim_zero_noise_report(&req.render, photo_img, &ssim_map, mask.as_ref(), &settings, &mut notes)?;
    let (twins, render_b_img) = match &req.render_b {
        None => (None, None),
        Some(pb) => {
            twins_report(req, pb, photo_img, (render_img, render_var.as_deref()), mask.as_ref(), &settings, &mut notes)
                .map(|(t, b)| (Some(t), Some(b)))?
        }
    };
    let images = Images { photo: photo_img, render: render_img, render_b: render_b_img.as_ref() };

    let approximations: Vec<RenderApproximations> = std::iter::once(req.render.as_path())
        .chain(req.render_b.as_deref())
        .filter_map(|r| render_approximations(r, &mut notes))
        .collect();
    for a in &approximations {
        for line in &a.approximations {
            notes.push(format!("{} approximates: {line}; the difference on the object includes that bias", a.render));
        }
    }
    let bands = if twin_bands.is_empty() {
        Vec::new()
    } else {
        band_checks(req, &twin_bands, images, render_var.clone(), mask.as_ref(), &mut notes)?
    };

    // ECC refinement.
    let refined_parts = match req.refine {
        Some(motion) => Some(ecc_refinement(motion, scene.as_ref(), images, mask.as_ref(), &settings, &mut notes)?),
        None => None,
    };

    let display = display_scale(req, images, mask.as_ref(), &settings, &mut notes);

    let lw = settings.luminance.weights();
    let report = Report {
        lucent_version: env!("CARGO_PKG_VERSION").into(),
        photo: req.photo.display().to_string(),
        render: req.render.display().to_string(),
        width: w,
        height: h,
        channels: photo.channels.clone(),
        mask: MaskReport {
            source: source.into(),
            path: mask_path.map(|p| p.display().to_string()),
            included_pixels: mask.as_ref().map_or(w * h, Mask::count),
            included_fraction: mask.as_ref().map_or(1.0, Mask::fraction),
        },
        definitions: Definitions {
            difference: "render - photo, linear, the images' own units".into(),
            ssim: "Wang, Bovik, Sheikh & Simoncelli 2004 (IEEE TIP 13(4)); = skimage.metrics.structural_similarity(gaussian_weights=True, sigma=1.5, use_sample_covariance=False, data_range=L) per channel".into(),
            ssim_parameters: settings.ssim,
            ssim_window_taps: settings.ssim.window(),
            ssim_border_px: settings.ssim.border(),
            ssim_with_mask: "mean of the SSIM map over included pixels at least ssim_border_px from the image border".into(),
            luminance: settings.luminance.describe().into(),
            luminance_weights: lw,
            relative_error: "sum |render - photo| / sum |photo| over included pixels and channels".into(),
        },
        as_calibrated: calibrated,
        noise,
        twins,
        ssim_at_zero_noise,
        refined: refined_parts.as_ref().map(|(r, _, _)| r.clone()),
        bands,
        approximations,
        display: DisplayReport {
            exposure: display.exposure,
            exposure_source: display.exposure_source,
            transfer: "sRGB (IEC 61966-2-1) of exposure x linear value, clipped to [0, 1]".into(),
            difference: "luminance Y(render) - Y(photo), linear units (not scaled by the exposure)".into(),
            difference_colour_map: "ColorBrewer RdBu: blue = render darker, white = 0, red = render brighter".into(),
            difference_range: display.diff_range,
            difference_range_source: if render_b_img.is_some() {
                "the larger of the two twins' 99th percentiles of |dY| over included pixels (1 % of the data range \
                 if zero): one scale for both twins"
                    .into()
            } else {
                "99th percentile of |dY| over included pixels (1 % of the data range if zero)".into()
            },
            clipped_fraction_photo: display.clip_photo,
            clipped_fraction_render: display.clip_render,
            clipped_fraction_difference: display.clipped_diff,
            masked_pixels: "greyed (photo, render), hatched light grey (difference)".into(),
        },
        files: FILES.iter().map(|s| s.to_string()).collect(),
    };
    let triplet_png = picture(req, &report, images, mask.as_ref(), refined_parts.as_ref())?;
    let difference = difference_channels(images, display.dy, ssim_map, mask.as_ref(), refined_parts.as_ref());
    let band_png = band_png(req, &report)?;
    Ok(Outcome { report, triplet_png, width: w, height: h, difference, band_png, notes })
}

/// The images a comparison reads: the photo, the render (twin A) and, with
/// two twins, twin B's render.
#[derive(Clone, Copy)]
struct Images<'a> {
    photo: &'a RgbImage,
    render: &'a RgbImage,
    render_b: Option<&'a RgbImage>,
}

/// The pixels a comparison includes ([`select_pixels`]).
struct Selection {
    /// `None`: every pixel.
    mask: Option<Mask>,
    /// `mask.source` of metrics.json: "none", "image", "object", "board",
    /// "object and image" or "board and image".
    source: &'static str,
    /// The mask's file(s).
    path: Option<PathBuf>,
    /// The scene JSON (of the mask, else of `--scene`) and its path, for
    /// the ECC region.
    scene: Option<(lucent_calib::scene::SceneDescription, PathBuf)>,
}

/// The mask of `req` (an image, an object or board mask from a render EXR's
/// layer or a scene JSON, intersected with a mask image when both are
/// given) over a `w` × `h` image, and the scene; an error when it includes
/// no pixel.
fn select_pixels(req: &Request, w: usize, h: usize) -> Result<Selection, CompareError> {
    let mut scene = None;
    let (mask, source, mask_path) = match &req.mask {
        MaskSpec::None => (None, "none", None),
        MaskSpec::Image(p) => (Some(Mask::from_image(p, w, h)?), "image", Some(p)),
        MaskSpec::Object(p) if crate::imageio::extension(p) == "exr" => {
            (Some(mask_from_render_layer(p, "object", w, h)?), "object", Some(p))
        }
        MaskSpec::Board(p) if crate::imageio::extension(p) == "exr" => {
            (Some(mask_from_render_layer(p, "board", w, h)?), "board", Some(p))
        }
        MaskSpec::Object(p) => {
            let s = mask::read_scene(p)?;
            let m = mask::object_mask(&s, w, h)?;
            scene = Some((s, p.clone()));
            (Some(m), "object", Some(p))
        }
        MaskSpec::Board(p) => {
            let s = mask::read_scene(p)?;
            let m = mask::board_mask(&s, w, h)?;
            scene = Some((s, p.clone()));
            (Some(m), "board", Some(p))
        }
    };
    // An object or board mask and a mask image: the pixels both include.
    let (mask, source, mask_path) = match (&req.mask_also, mask) {
        (None, m) => (m, source, mask_path.cloned()),
        (Some(p), m) => {
            let image = Mask::from_image(p, w, h)?;
            let source = match source {
                "object" => "object and image",
                "board" => "board and image",
                _ => "image",
            };
            let path = match mask_path {
                Some(first) => PathBuf::from(format!("{} and {}", first.display(), p.display())),
                None => p.clone(),
            };
            (
                Some(match m {
                    Some(m) => m.and(&image)?,
                    None => image,
                }),
                source,
                Some(path),
            )
        }
    };
    if scene.is_none()
        && let Some(p) = &req.scene
    {
        scene = Some((mask::read_scene(p)?, p.clone()));
    }
    if let Some(m) = &mask
        && m.count() == 0
    {
        return Err(CompareError::EmptyMask { kind: Some(source), path: mask_path });
    }
    Ok(Selection { mask, source, path: mask_path, scene })
}

/// The bands of `req`, one per twin, of the region the mask `source` is
/// over (the object's or the board's pixels); an error when there are more
/// bands than renders or the mask is of neither.
fn band_regions<'a>(req: &'a Request, source: &str) -> Result<Vec<&'a band::TwinBand>, CompareError> {
    let renders = 1 + usize::from(req.render_b.is_some());
    if req.bands.len() > renders {
        return Err(CompareError::BandUse(format!(
            "{} bands for {renders} render(s): give one per --render, in the same order",
            req.bands.len()
        )));
    }
    let band_region = match source {
        "object" | "object and image" => "object",
        "board" | "board and image" => "board",
        _ => "",
    };
    if !req.bands.is_empty() && band_region.is_empty() {
        return Err(CompareError::BandUse(
            "a twin's band is of the object's or the board's mean: give --mask-object or --mask-board".into(),
        ));
    }
    Ok(req.bands.iter().map(|b| b.region(band_region)).collect::<Result<Vec<_>, _>>()?)
}

/// The photo's mean over the `mask`ed pixels against each twin's band
/// (`twin_bands`, in the order of the renders; `render_var` the first
/// render's variance).
fn band_checks(
    req: &Request,
    twin_bands: &[&band::TwinBand],
    images: Images,
    render_var: Option<Vec<f32>>,
    mask: Option<&Mask>,
    notes: &mut Vec<String>,
) -> Result<Vec<band::BandCheck>, CompareError> {
    let include = mask.map(|m| m.include.as_slice());
    let pv = photo_variance(req, images.photo)?;
    let (photo_mean, photo_var, n) = band::region_mean(&images.photo.data, pv.as_deref(), include);
    if pv.is_none() {
        notes.push("--band: no photo variance given (--photo-variance or --photo-repeat): the photo's noise is taken as 0 in the predictive band".into());
    }
    let renders: Vec<(&Path, &RgbImage, Option<Vec<f32>>)> =
        std::iter::once((req.render.as_path(), images.render, render_var))
            .chain(req.render_b.as_deref().zip(images.render_b).map(|(p, img)| (p, img, render_variance(p))))
            .collect();
    Ok(twin_bands
        .iter()
        .zip(&renders)
        .zip(&req.bands)
        .map(|((b, (path, img, var)), bands)| {
            let (render_mean, render_var_mean, _) = band::region_mean(&img.data, var.as_deref(), include);
            let mut c = band::check(b, photo_mean, photo_var, render_mean, render_var_mean, n);
            c.render = path.display().to_string();
            c.band.clone_from(&bands.source);
            c
        })
        .collect())
}

/// The render aligned to the photo by ECC (`motion`), over the board minus
/// the sample of `scene` (else the whole image): the refinement's record,
/// the warped render and the pixels still included.
fn ecc_refinement(
    motion: Motion,
    scene: Option<&(lucent_calib::scene::SceneDescription, PathBuf)>,
    images: Images,
    mask: Option<&Mask>,
    settings: &Settings,
    notes: &mut Vec<String>,
) -> Result<(Refinement, RgbImage, Mask), CompareError> {
    let (photo_img, render_img) = (images.photo, images.render);
    let (w, h) = (photo_img.width, photo_img.height);
    let (region, region_text) = match scene {
        Some((s, p)) => (Some(mask::board_mask(s, w, h)?), format!("board minus sample, from {}", p.display())),
        None => {
            notes.push(
                "ECC ran on the whole image (no scene JSON given: pass --scene to align on the board only)".into(),
            );
            (None, "whole image".to_string())
        }
    };
    let lw = settings.luminance.weights();
    let (t, i) = (luminance_plane(photo_img, lw), luminance_plane(render_img, lw));
    let region_u8 = region.as_ref().map(Mask::to_u8);
    let found = ecc::find_transform_ecc(&t, &i, w, h, region_u8.as_deref(), &EccOptions::new(motion))?;
    let (warped, valid) = warp_bilinear(render_img, &found.warp);
    let base = mask.cloned().unwrap_or_else(|| Mask::all(w, h));
    let refined_mask = base.and(&valid)?;
    let outside = base.count() - refined_mask.count();
    let (m, _) = metrics_and_ssim_map(photo_img, &warped, Some(&refined_mask), settings)?;
    let c = [(w as f64 - 1.0) / 2.0, (h as f64 - 1.0) / 2.0];
    let wp = found.warp;
    let d = wp[2][0] * c[0] + wp[2][1] * c[1] + wp[2][2];
    let shift = [
        (wp[0][0] * c[0] + wp[0][1] * c[1] + wp[0][2]) / d - c[0],
        (wp[1][0] * c[0] + wp[1][1] * c[1] + wp[1][2]) / d - c[1],
    ];
    let refinement = Refinement {
        method: "OpenCV findTransformECC (Evangelidis & Psarakis 2008) on luminance, coarse to fine".into(),
        motion: motion.name().into(),
        warp: wp,
        warp_convention: "render(W (x, y, 1)) ~ photo(x, y); pixel centres at integers".into(),
        shift_px: shift,
        correlation: found.correlation,
        pyramid_levels: found.levels,
        region: region_text,
        region_pixels: region.as_ref().map_or(w * h, Mask::count),
        outside_render_pixels: outside,
        metrics: m,
    };
    Ok((refinement, warped, refined_mask))
}

/// How triplet.png shows the images ([`display_scale`]).
struct DisplayScale {
    exposure: f64,
    exposure_source: String,
    /// The luminance difference render − photo of twin A, per pixel.
    dy: Vec<f32>,
    /// The difference colour bar spans ± this.
    diff_range: f64,
    /// The fraction of included differences beyond the bar.
    clipped_diff: f64,
    clip_photo: f64,
    clip_render: f64,
}

/// The display exposure (`--exposure`, else from the photo), the difference
/// scale (one for both twins) and what each clips over the `mask`ed pixels
/// (a note when the photo or the render clips).
fn display_scale(
    req: &Request,
    images: Images,
    mask: Option<&Mask>,
    settings: &Settings,
    notes: &mut Vec<String>,
) -> DisplayScale {
    let (photo_img, render_img) = (images.photo, images.render);
    let (exposure, exposure_source) = match req.exposure {
        Some(k) => (k, "--exposure".to_string()),
        None => {
            let (k, p99) = auto_exposure(photo_img, mask);
            (k, format!("auto: 1 / (99th percentile of the photo's max(R, G, B) over included pixels = {p99:.6e})"))
        }
    };
    let lw = settings.luminance.weights();
    let luminance_difference = |render: &RgbImage| -> Vec<f32> {
        photo_img
            .data
            .chunks_exact(3)
            .zip(render.data.chunks_exact(3))
            .map(|(p, r)| (0..3).map(|c| lw[c] * (f64::from(r[c]) - f64::from(p[c]))).sum::<f64>() as f32)
            .collect()
    };
    let included_abs = |d: &[f32]| -> Vec<f32> {
        d.iter().enumerate().filter(|(i, _)| mask.is_none_or(|m| m.include[*i])).map(|(_, v)| v.abs()).collect()
    };
    let dy = luminance_difference(render_img);
    let mut abs_included = included_abs(&dy);
    // Two twins share one scale: the larger of their 99th percentiles, so
    // their difference columns can be compared by eye.
    if let Some(b) = images.render_b {
        abs_included.extend(included_abs(&luminance_difference(b)));
    }
    let n_included = abs_included.len();
    let p99 = match images.render_b {
        None => f64::from(percentile(abs_included.clone(), 0.99).unwrap_or(0.0)),
        Some(_) => {
            let half = n_included / 2;
            let a = f64::from(percentile(abs_included[..half].to_vec(), 0.99).unwrap_or(0.0));
            let b = f64::from(percentile(abs_included[half..].to_vec(), 0.99).unwrap_or(0.0));
            a.max(b)
        }
    };
    let diff_range = if p99 > 0.0 { p99 } else { 0.01 * req.data_range };
    let clipped_diff =
        abs_included.iter().filter(|v| f64::from(**v) > diff_range).count() as f64 / n_included.max(1) as f64;
    let clip_photo = clipped_fraction(photo_img, mask, exposure);
    let clip_render = clipped_fraction(render_img, mask, exposure);
    if clip_photo > 0.0 || clip_render > 0.0 {
        notes.push(format!(
            "clipping in triplet.png at exposure ×{exposure:.4}: {:.2} % of the photo's and {:.2} % of the render's included pixels exceed 1 (the metrics use the unclipped values)",
            100.0 * clip_photo,
            100.0 * clip_render
        ));
    }
    DisplayScale { exposure, exposure_source, dy, diff_range, clipped_diff, clip_photo, clip_render }
}

/// A file's name, or its whole path when it has none.
fn file_name(p: &Path) -> String {
    p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| p.display().to_string())
}

/// A twin's file as its folder and name ("fitted/render.exr"): two renders
/// are often both render.exr.
fn short_name(p: &Path) -> String {
    match p.parent().and_then(Path::file_name) {
        Some(d) => format!("{}/{}", d.to_string_lossy(), file_name(p)),
        None => file_name(p),
    }
}

/// Twin `k`'s label in triplet.png ("A: recipe twin (recipe/render.exr)").
fn twin_label(req: &Request, k: usize, p: &Path) -> String {
    match &req.twin_names {
        Some(n) => format!("{}: {} twin ({})", ["A", "B"][k], n[k], short_name(p)),
        None => format!("{}: {}", ["A", "B"][k], short_name(p)),
    }
}

/// The lines above triplet.png: the files, the mask, the display and the
/// ECC shift.
fn picture_header(req: &Request, report: &Report, mask: Option<&Mask>) -> Vec<String> {
    let (w, h) = (report.width, report.height);
    let d = &report.display;
    let lw = report.definitions.luminance_weights;
    let mut header = vec![
        match &req.render_b {
            None => format!("photo {}  |  render {}  |  {w} × {h} px", file_name(&req.photo), file_name(&req.render)),
            Some(b) => format!(
                "photo {}  |  twin {}  |  twin {}  |  {w} × {h} px; one difference scale for both",
                file_name(&req.photo),
                twin_label(req, 0, &req.render),
                twin_label(req, 1, b)
            ),
        },
        format!(
            "mask: {}   data range {}   luminance: {} ({:.4}, {:.4}, {:.4})",
            match mask {
                Some(m) => format!("{} ({:.1} % of the pixels)", report.mask.source, 100.0 * m.fraction()),
                None => "none".into(),
            },
            req.data_range,
            req.luminance.describe(),
            lw[0],
            lw[1],
            lw[2]
        ),
        format!(
            "display: exposure ×{:.4} ({}), sRGB; clipped: photo {:.2} %, render {:.2} %; difference beyond the bar: {:.2} %",
            d.exposure,
            if req.exposure.is_some() { "--exposure" } else { "auto, photo p99" },
            100.0 * d.clipped_fraction_photo,
            100.0 * d.clipped_fraction_render,
            100.0 * d.clipped_fraction_difference
        ),
    ];
    if let Some(r) = &report.refined {
        header.push(format!(
            "ECC ({}): shift dx = {:+.3} px, dy = {:+.3} px, correlation {:.4}, region: {}",
            r.motion,
            r.shift_px[0],
            r.shift_px[1],
            r.correlation,
            r.region.split(", from").next().unwrap_or_default()
        ));
    }
    header
}

/// A row's metrics under its picture.
fn metrics_caption(m: &Metrics) -> String {
    format!(
        "RMSE {:.4e} (R {:.3e}, G {:.3e}, B {:.3e})   SSIM Y {:.4} (R {:.4}, G {:.4}, B {:.4})   rel. error {:.2} %",
        m.rmse,
        m.rmse_channels.r,
        m.rmse_channels.g,
        m.rmse_channels.b,
        m.ssim.y,
        m.ssim.r,
        m.ssim.g,
        m.ssim.b,
        100.0 * m.relative_error
    )
}

/// Two twins: a row's title names its twin, with its model RMSE (the SSIM
/// at zero noise is in metrics.json; the row title must fit the picture).
fn twin_title(label: String, n: Option<&noise::NoiseReport>) -> String {
    match n {
        Some(n) => format!(
            "{label}: model RMSE {:.3e} (95 %: {:.3e} – {:.3e}), floor {:.3e}",
            n.total.model_rmse, n.total.ci95[0], n.total.ci95[1], n.total.noise_floor
        ),
        None => label,
    }
}

/// The first row's title: as calibrated, with the model RMSE and the SSIM
/// at zero render noise when known (with two twins, twin A's title).
fn calibrated_title(req: &Request, report: &Report) -> String {
    let mut title = match &report.noise {
        Some(n) => format!(
            "as calibrated; model RMSE with the noise removed {:.3e} (95 %: {:.3e} – {:.3e}), noise floor {:.3e}",
            n.total.model_rmse, n.total.ci95[0], n.total.ci95[1], n.total.noise_floor
        ),
        None => "as calibrated".into(),
    };
    if let Some(z) = &report.ssim_at_zero_noise {
        // Shorter words so the row title fits the picture's width.
        title = title.replace("model RMSE with the noise removed", "model RMSE").replace("noise floor", "floor");
        title.push_str(&format!(
            "; SSIM Y at zero render noise {:.4} ({:.4}–{:.4})",
            z.at_zero_noise, z.ci95[0], z.ci95[1]
        ));
    }
    if req.render_b.is_some() {
        title = twin_title(twin_label(req, 0, &req.render), report.noise.as_ref());
    }
    title
}

/// triplet.png: photo | render | difference per row (as calibrated, twin B,
/// after ECC), or with two twins and no ECC row, both side by side against
/// the photo under one difference scale.
fn picture(
    req: &Request,
    report: &Report,
    images: Images,
    mask: Option<&Mask>,
    refined: Option<&(Refinement, RgbImage, Mask)>,
) -> Result<Vec<u8>, CompareError> {
    let photo_img = images.photo;
    let mut rows = vec![triplet::Row {
        title: calibrated_title(req, report),
        photo: photo_img,
        render: images.render,
        mask,
        caption: metrics_caption(&report.as_calibrated),
    }];
    if let (Some(b), Some(t), Some(pb)) = (images.render_b, &report.twins, &req.render_b) {
        let title = twin_title(twin_label(req, 1, pb), Some(&t.noise_b));
        rows.push(triplet::Row { title, photo: photo_img, render: b, mask, caption: metrics_caption(&t.metrics_b) });
    }
    if let Some((r, warped, m)) = refined {
        rows.push(triplet::Row {
            title: format!(
                "after ECC refinement ({}: dx = {:+.3} px, dy = {:+.3} px)",
                r.motion, r.shift_px[0], r.shift_px[1]
            ),
            photo: photo_img,
            render: warped,
            mask: Some(m),
            caption: metrics_caption(&r.metrics),
        });
    }
    let style = triplet::Style {
        exposure: report.display.exposure,
        luminance: report.definitions.luminance_weights,
        diff_range: report.display.difference_range,
        header: picture_header(req, report, mask),
    };
    // Two twins (and no ECC row): side by side against the photo, one scale.
    Ok(match (images.render_b, &report.twins, &req.render_b, refined) {
        (Some(b), Some(t), Some(pb), None) => {
            let short_metrics = |m: &Metrics| {
                format!("RMSE {:.3e}, SSIM Y {:.4}, rel. error {:.2} %", m.rmse, m.ssim.y, 100.0 * m.relative_error)
            };
            let noise_text = |n: Option<&noise::NoiseReport>| {
                n.map_or_else(String::new, |n| {
                    format!(
                        "model RMSE {:.3e} (95 % {:.3e} – {:.3e}), floor {:.3e}; ",
                        n.total.model_rmse, n.total.ci95[0], n.total.ci95[1], n.total.noise_floor
                    )
                })
            };
            triplet::twins_png(
                photo_img,
                mask,
                [
                    triplet::Twin {
                        render: images.render,
                        title: twin_label(req, 0, &req.render),
                        caption: format!(
                            "A: {}{}",
                            noise_text(report.noise.as_ref()),
                            short_metrics(&report.as_calibrated)
                        ),
                    },
                    triplet::Twin {
                        render: b,
                        title: twin_label(req, 1, pb),
                        caption: format!("B: {}{}", noise_text(Some(&t.noise_b)), short_metrics(&t.metrics_b)),
                    },
                ],
                &style,
            )?
        }
        _ => triplet::triplet_png(&rows, &style)?,
    })
}

/// The channels of difference.exr: render − photo per channel, the
/// luminance difference `dy`, the SSIM map, the mask and, after ECC, the
/// refined differences and mask.
fn difference_channels(
    images: Images,
    dy: Vec<f32>,
    ssim_map: Vec<f32>,
    mask: Option<&Mask>,
    refined: Option<&(Refinement, RgbImage, Mask)>,
) -> Vec<(String, Vec<f32>)> {
    let (photo_img, render_img) = (images.photo, images.render);
    let plane = |img: &RgbImage, other: &RgbImage, c: usize| -> Vec<f32> {
        img.data.iter().skip(c).step_by(3).zip(other.data.iter().skip(c).step_by(3)).map(|(r, p)| r - p).collect()
    };
    let mut difference = vec![
        ("R".to_string(), plane(render_img, photo_img, 0)),
        ("G".to_string(), plane(render_img, photo_img, 1)),
        ("B".to_string(), plane(render_img, photo_img, 2)),
        ("Y".to_string(), dy),
        ("ssim.Y".to_string(), ssim_map),
    ];
    if let Some(m) = mask {
        difference.push(("mask".to_string(), m.include.iter().map(|&v| f32::from(u8::from(v))).collect()));
    }
    if let Some((_, warped, m)) = refined {
        for (c, n) in ["R", "G", "B"].iter().enumerate() {
            difference.push((format!("refined.{n}"), plane(warped, photo_img, c)));
        }
        difference.push(("refined.mask".to_string(), m.include.iter().map(|&v| f32::from(u8::from(v))).collect()));
    }
    difference
}

/// band.png ([`BAND_PNG`]): the photo against each twin's band, relative to
/// the twin's mean; `None` without bands.
fn band_png(req: &Request, report: &Report) -> Result<Option<Vec<u8>>, CompareError> {
    if report.bands.is_empty() {
        return Ok(None);
    }
    let bars: Vec<crate::plot::BandBars> = report
        .bands
        .iter()
        .enumerate()
        .map(|(k, b)| {
            let rel = |v: [f64; 3], scale: f64| -> [f64; 3] {
                std::array::from_fn(|c| scale * v[c] / b.render_mean[c].abs().max(f64::MIN_POSITIVE))
            };
            let off: [f64; 3] = std::array::from_fn(|c| b.photo_mean[c] - b.render_mean[c]);
            crate::plot::BandBars {
                twin: match &req.twin_names {
                    Some(n) => format!("{} twin", n[k]),
                    None => short_name(Path::new(&b.render)),
                },
                photo_offset: rel(off, 1.0),
                predictive_half_width: rel(b.predictive_sd, b.coverage_factor),
                inputs_half_width: rel(b.inputs_sd, b.coverage_factor),
                within: b.within,
            }
        })
        .collect();
    Ok(Some(crate::plot::band_check_png(&bars, band::COVERAGE_FACTOR)?))
}

fn io_err(path: &Path) -> impl Fn(std::io::Error) -> CompareError + '_ {
    move |source| CompareError::Io { path: path.to_path_buf(), source }
}

/// The temporary sibling folder [`write_outputs`] fills (hidden, named with
/// the process id): known beforehand, so a Ctrl-C handler can remove it.
pub fn staging_path(out: &Path) -> PathBuf {
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    let name = out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "compare".into());
    parent.join(format!(".{name}.tmp-{}", std::process::id()))
}

/// Writes metrics.json, triplet.png and difference.exr into `out`: all
/// into a temporary sibling folder first, then moved into place (the folder
/// itself is renamed if it did not exist), so a failure leaves no partial
/// result. Returns the written paths.
pub fn write_outputs(out: &Path, outcome: &Outcome) -> Result<Vec<PathBuf>, CompareError> {
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    let tmp = staging_path(out);
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(io_err(&tmp))?;
    }
    let result = (|| -> Result<(), CompareError> {
        std::fs::create_dir_all(&tmp).map_err(io_err(&tmp))?;
        let files = CompareFiles::in_dir(&tmp);
        write_json(&files.metrics, &outcome.report)?;
        write_atomic(&files.triplet, &outcome.triplet_png)?;
        let channels: Vec<(&str, &[f32])> =
            outcome.difference.iter().map(|(n, v)| (n.as_str(), v.as_slice())).collect();
        write_channels(&files.difference, outcome.width, outcome.height, &channels)?;
        if let Some(png) = &outcome.band_png {
            write_atomic(&files.band_png, png)?;
        }
        if out.is_dir() {
            for f in FILES {
                std::fs::rename(tmp.join(f), out.join(f)).map_err(io_err(&out.join(f)))?;
            }
            // A band.png of an earlier comparison would no longer belong to metrics.json.
            let band = out.join(BAND_PNG);
            if outcome.band_png.is_some() {
                std::fs::rename(tmp.join(BAND_PNG), &band).map_err(io_err(&band))?;
            } else if band.is_file() {
                std::fs::remove_file(&band).map_err(io_err(&band))?;
            }
            std::fs::remove_dir(&tmp).map_err(io_err(&tmp))?;
        } else if out.exists() {
            return Err(CompareError::Io {
                path: out.to_path_buf(),
                source: std::io::Error::other("exists and is not a folder"),
            });
        } else {
            std::fs::rename(&tmp, out).map_err(io_err(out))?;
        }
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result?;
    Ok(FILES.iter().copied().chain(outcome.band_png.as_ref().map(|_| BAND_PNG)).map(|f| out.join(f)).collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn img(w: usize, h: usize, f: impl Fn(usize, usize, usize) -> f32) -> RgbImage {
        RgbImage::new(w, h, (0..w * h * 3).map(|i| f((i / 3) % w, (i / 3) / w, i % 3)).collect()).unwrap()
    }

    #[test]
    fn warp_by_a_translation_moves_content_and_marks_the_edge() {
        let a = img(20, 10, |x, y, c| (x + 10 * y + c) as f32);
        let (b, valid) = warp_bilinear(&a, &[[1.0, 0.0, 2.5], [0.0, 1.0, -1.0], [0.0, 0.0, 1.0]]);
        // b(x, y) = a(x + 2.5, y − 1) = x + 2.5 + 10(y − 1) + c.
        assert!((b.pixel(3, 4)[1] - (3.0 + 2.5 + 30.0 + 1.0)).abs() < 1e-5);
        assert!(!valid.get(0, 0) && !valid.get(17, 5) && valid.get(16, 5) && valid.get(0, 1));
    }

    #[test]
    fn percentile_and_exposure() {
        assert_eq!(percentile((0..101).map(|v| v as f32).collect(), 0.99), Some(99.0));
        assert_eq!(percentile(vec![], 0.5), None);
        let a = img(10, 10, |x, _, _| if x == 0 { 4.0 } else { 0.5 });
        let (k, p) = auto_exposure(&a, None);
        assert_eq!((k, p), (0.25, 4.0));
        assert!((clipped_fraction(&a, None, 1.0) - 0.1).abs() < 1e-12);
        let m = Mask { width: 10, height: 10, include: (0..100).map(|i| i % 10 != 0).collect() };
        assert_eq!(auto_exposure(&a, Some(&m)).0, 2.0);
    }

    #[test]
    fn metrics_reject_empty_masks_and_size_mismatch() {
        let s = Settings { ssim: SsimParams::new(1.0).unwrap(), luminance: Luminance::CieRgb };
        let a = img(16, 16, |x, y, _| (x * y) as f32 / 256.0);
        let b = img(16, 15, |_, _, _| 0.0);
        assert!(metrics(&a, &b, None, &s)
            .unwrap_err()
            .to_string()
            .contains("the photo is 16 × 16 pixels, the render 16 × 15"));
        let none = Mask { width: 16, height: 16, include: vec![false; 256] };
        assert!(metrics(&a, &a, Some(&none), &s).unwrap_err().to_string().contains("no pixel"));
        let m = metrics(&a, &a, None, &s).unwrap();
        assert_eq!((m.rmse, m.mean_abs_error, m.relative_error), (0.0, 0.0, 0.0));
        assert!((Luminance::CieRgb.weights().iter().sum::<f64>() - 1.0).abs() < 1e-12);
        assert!(Luminance::from_name("xyz").unwrap_err().to_string().contains("cie-rgb, rec709"));
    }

    #[test]
    fn typed_errors_say_which_file_and_what() {
        let e = CompareError::Channels { photo: vec!["Y".into()], render: vec!["R".into(), "G".into(), "B".into()] };
        assert_eq!(e.to_string(), "the photo has 1 colour channel(s) (Y) but the render has 3 (R, G, B)");
        let e = CompareError::EmptyMask { kind: Some("object"), path: Some(PathBuf::from("pose/scene.json")) };
        assert_eq!(e.to_string(), "the object mask from pose/scene.json includes no pixel");
        assert_eq!(CompareError::EmptyMask { kind: None, path: None }.to_string(), "the mask includes no pixel");
        let e = CompareError::Size {
            first: "mask m.png".into(),
            first_size: (4, 3),
            second: "the photo and render".into(),
            second_size: (8, 6),
        };
        assert_eq!(e.to_string(), "mask m.png is 4 × 3 pixels, the photo and render 8 × 6: they must be the same size");
        assert!(matches!(Luminance::from_name("xyz"), Err(CompareError::UnknownLuminance { .. })));
    }
}
