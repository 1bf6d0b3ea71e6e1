//! The noise of a RAW photo: shot + read noise, per colour channel
//!
//!   var(x) = a · x + b,
//!
//! with x the decoded value ([`crate::raw::read_raw`]'s units: 0 = black
//! level, 1 = white level) and var in the same units squared. `a` is the
//! shot (Poisson) term, 1 / (electrons at the white level) for a sensor with
//! unit gain per electron; `b` the read noise (and quantisation) floor. This
//! is the DNG `NoiseProfile` model (tag 51041, Adobe DNG 1.4 specification,
//! "NoiseProfile": N(x) = √(S·x + O) per colour plane, x normalised to [0, 1]),
//! so a DNG that carries the tag gives `a = S`, `b = O` directly
//! ([`NoiseModel::from_noise_profile`]).
//!
//! **From the image itself** ([`estimate`]), when the file has no profile:
//! per CFA position, the photosites of that position form a sub-image z. At
//! each photosite whose 5 × 5 window of z is inside the image and below
//! clipping, a least-squares plane through the window leaves a residual sum
//! of squares with 22 degrees of freedom: RSS / 22 estimates the noise
//! variance where the scene is linear across the window (a ramp costs
//! nothing), its signal is the window's mean. The windows are sorted by
//! signal into up to 32 bins of at least 200; each bin's variance is the
//! median of its windows' estimates divided by 0.970 (the median of
//! χ²₂₂ / 22), so texture in a minority of windows does not inflate it; a, b
//! come from a weighted least-squares line through the bins (weights n /
//! var², var from the previous line — iteratively reweighted —, standard
//! errors from the bins' scatter about the line). Windows
//! holding an edge are then left out — those whose estimate exceeds 2.5 ×
//! the line's variance at their signal (pure noise: a share of ≈ 2·10⁻⁴) —
//! and the line refitted, three times. Foi et al. 2008 ("Practical
//! Poissonian-Gaussian noise modeling and fitting for single-image raw-data",
//! IEEE TIP 17(10)) fit the same model from level sets of smooth regions;
//! this is a simpler variant of that idea. An image whose signals span too
//! little to separate the two terms (all bins within 2 % of the white level
//! of each other) gets b = 0 and a from the mean variance/signal (stated in
//! [`NoiseModel::note`]).
//!
//! Trust: the estimate counts everything that varies from photosite to
//! photosite within 5 × 5 same-colour windows as noise — a scene with fine
//! texture at that scale (fabric, print dots, a checkerboard of a few pixels
//! per square) reads noisier than the sensor is. On synthetic 512 × 384
//! mosaics (a = 1.5–3·10⁻⁴, b = 4–6·10⁻⁶, gradients and 48-px patches) a is
//! recovered within 5 % (standard error ≈ 1.5 %) and b, which only the
//! darkest bins constrain, within 55 % (standard error ≈ 15 %; edges that
//! survive the screen pull it ≈ 10 % low) (`calib/tests/noise.rs`).
//!
//! [`developed_noise`] draws one realisation of this noise (Gaussian, the
//! model's variance at each photosite's recorded value) through the same
//! white balance, demosaicing and orientation as [`crate::raw::develop`],
//! which are linear: the spread of such realisations is the noise of the
//! developed photo, spatial and channel correlations included.
//!
//! ```
//! use lucent_calib::noise::NoiseModel;
//! // A DNG NoiseProfile with one (S, O) pair for all planes.
//! let m = NoiseModel::from_noise_profile(&[2e-4, 4e-6]).unwrap();
//! assert!((m.variance(1, 0.5) - (2e-4 * 0.5 + 4e-6)).abs() < 1e-15);
//! ```

use crate::buffer::RgbBuffer;
use crate::demosaic::Mosaic;
use crate::raw::{RawData, RawError, RawFrame, RawOptions};
use serde::{Deserialize, Serialize};

/// Fewest photosites per signal bin of [`estimate`].
pub const MIN_PER_BIN: usize = 200;
/// Most signal bins of [`estimate`].
pub const MAX_BINS: usize = 32;
/// Photosites whose neighbourhood reaches this fraction of the white level are left out.
pub const CLIP_LEVEL: f32 = 0.95;

/// Where a [`NoiseModel`] comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum NoiseSource {
    /// The DNG's NoiseProfile tag (51041).
    DngNoiseProfile,
    /// [`estimate`] on the photo itself.
    EstimatedFromImage,
}

/// One bin of [`estimate`]: its mean signal and robust variance.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct NoiseBin {
    pub channel: usize,
    pub signal: f64,
    pub variance: f64,
    pub photosites: usize,
}

/// var = a·x + b per channel (R, G, B), x and var in decoded units (1 = white level).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoiseModel {
    pub definition: String,
    pub source: NoiseSource,
    /// Shot-noise coefficient per channel R, G, B.
    pub a: [f64; 3],
    /// Read-noise variance per channel R, G, B.
    pub b: [f64; 3],
    /// Approximate standard errors of a and b (estimates only; residuals
    /// taken as independent, which neighbouring ones are not quite).
    #[serde(default)]
    pub a_std_error: Option<[f64; 3]>,
    #[serde(default)]
    pub b_std_error: Option<[f64; 3]>,
    /// Photosites the estimate used, per channel.
    #[serde(default)]
    pub photosites: Option<[usize; 3]>,
    /// The bins the line was fitted to (estimates only).
    #[serde(default)]
    pub bins: Vec<NoiseBin>,
    /// What the user should know (a fallback taken).
    #[serde(default)]
    pub note: String,
}

/// Why the noise cannot be estimated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NoiseError {
    #[error("too few usable photosites of channel {channel} to estimate its noise ({got}, need {need}; the image is small, clipped or all edges)")]
    TooFew { channel: &'static str, got: usize, need: usize },
    #[error("NoiseProfile: {0}")]
    Profile(String),
}

const DEFINITION: &str = "variance = a * x + b per channel (R, G, B), x the decoded raw value \
                          (0 = black level, 1 = white level), variance in the same units squared";

const CHANNELS: [&str; 3] = ["R", "G", "B"];

impl NoiseModel {
    /// From a DNG NoiseProfile's values: one (S, O) pair for all planes or
    /// one per plane R, G, B (CFAPlaneColor's default order).
    pub fn from_noise_profile(values: &[f64]) -> Result<Self, NoiseError> {
        let pairs: [[f64; 2]; 3] = match values.len() {
            2 => [[values[0], values[1]]; 3],
            6 => std::array::from_fn(|c| [values[2 * c], values[2 * c + 1]]),
            n => return Err(NoiseError::Profile(format!("{n} values; expected 2 or 6 (S, O per plane)"))),
        };
        if pairs.iter().flatten().any(|v| !v.is_finite()) || pairs.iter().any(|p| p[0] < 0.0) {
            return Err(NoiseError::Profile(format!("{values:?}: S must be finite and ≥ 0, O finite")));
        }
        Ok(Self {
            definition: DEFINITION.into(),
            source: NoiseSource::DngNoiseProfile,
            a: pairs.map(|p| p[0]),
            b: pairs.map(|p| p[1]),
            a_std_error: None,
            b_std_error: None,
            photosites: None,
            bins: Vec::new(),
            note: String::new(),
        })
    }

    /// The variance of a value `x` of channel `c` (0 R, 1 G, 2 B), never below 0.
    pub fn variance(&self, c: usize, x: f64) -> f64 {
        (self.a[c] * x + self.b[c]).max(0.0)
    }
}

/// The photosites of each CFA position (or each channel of a linear image)
/// as sub-images: (channel, width, height, values).
fn planes(data: &RawData) -> Vec<(usize, usize, usize, Vec<f32>)> {
    match data {
        RawData::Bayer(m) => {
            let mut out = Vec::new();
            for py in 0..2 {
                for px in 0..2 {
                    let (w, h) = ((m.width - px).div_ceil(2), (m.height - py).div_ceil(2));
                    let v = (0..h)
                        .flat_map(|i| (0..w).map(move |j| (i, j)))
                        .map(|(i, j)| m.data[(2 * i + py) * m.width + 2 * j + px]);
                    out.push((m.pattern.colour_at(py, px), w, h, v.collect()));
                }
            }
            out
        }
        RawData::Rgb(b) => {
            (0..3).map(|c| (c, b.width, b.height, b.data.iter().skip(c).step_by(3).copied().collect())).collect()
        }
    }
}

/// Per photosite of a plane whose 5 × 5 window of same-colour photosites
/// lies inside the plane and below the clip level: (signal, variance
/// estimate). The window's least-squares plane (mean and two slopes, the
/// offsets −2…2 being orthogonal) leaves a residual sum of squares RSS with
/// 22 degrees of freedom: RSS / 22 estimates the noise variance where the
/// scene is linear across the window (a ramp costs nothing, an edge a lot).
fn windows(w: usize, h: usize, z: &[f32]) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for i in 2..h.saturating_sub(2) {
        'px: for j in 2..w.saturating_sub(2) {
            let (mut s, mut sx, mut sy, mut ss) = (0.0, 0.0, 0.0, 0.0);
            for di in -2isize..=2 {
                for dj in -2isize..=2 {
                    let v = z[(i as isize + di) as usize * w + (j as isize + dj) as usize];
                    if v >= CLIP_LEVEL {
                        continue 'px;
                    }
                    let v = f64::from(v);
                    s += v;
                    sx += dj as f64 * v;
                    sy += di as f64 * v;
                    ss += v * v;
                }
            }
            // Σ offsets² over the window = 5 · (4 + 1 + 0 + 1 + 4) = 50 per axis.
            let rss = ss - s * s / 25.0 - sx * sx / 50.0 - sy * sy / 50.0;
            out.push((s / 25.0, rss.max(0.0) / WINDOW_DOF));
        }
    }
    out
}

/// Residual degrees of freedom of a 5 × 5 window's plane fit.
const WINDOW_DOF: f64 = 22.0;
/// Median of χ²₂₂ / 22 (Wilson–Hilferty: (1 − 2/(9·22))³).
const MEDIAN_CHI2_22_RATIO: f64 = 0.970_0;
/// A window whose variance estimate exceeds this multiple of the model's
/// holds an edge or texture (χ²₂₂ / 22 exceeds 2.5 with probability ≈ 2·10⁻⁴).
const EDGE_RATIO: f64 = 2.5;

/// Sorted by signal and split into bins: (mean signal, robust variance, count)
/// per bin, the variance from the median of the windows' estimates.
fn bins(px: &mut [(f64, f64)]) -> Vec<(f64, f64, usize)> {
    px.sort_by(|a, b| a.0.total_cmp(&b.0));
    let k = (px.len() / MIN_PER_BIN).clamp(1, MAX_BINS);
    let mut out = Vec::with_capacity(k);
    for b in 0..k {
        let part = &px[b * px.len() / k..(b + 1) * px.len() / k];
        let mut v: Vec<f64> = part.iter().map(|p| p.1).collect();
        let m = v.len() / 2;
        let (_, med, _) = v.select_nth_unstable_by(m, f64::total_cmp);
        let signal = part.iter().map(|p| p.0).sum::<f64>() / part.len() as f64;
        out.push((signal, *med / MEDIAN_CHI2_22_RATIO, part.len()));
    }
    out
}

/// Weighted least squares var = a·x + b through `bins`, weights n / var²
/// with var from `prior` (a previous line; else the bins' own, whose noise
/// would pull the line towards the bins that came out low): (a, b, se a,
/// se b), the standard errors from the scatter of the bins about the line;
/// `None` when the signals span too little.
fn fit_line(bins: &[(f64, f64, usize)], prior: Option<(f64, f64)>) -> Option<(f64, f64, f64, f64)> {
    let (lo, hi) = bins.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), b| (l.min(b.0), h.max(b.0)));
    if bins.len() < 3 || hi - lo < 0.02 {
        return None;
    }
    let weight = |x: f64, v: f64, n: usize| {
        let v = match prior {
            Some((a, b)) if a * x + b > 0.0 => a * x + b,
            _ => v,
        };
        n as f64 / v.max(1e-30).powi(2)
    };
    let (mut sw, mut sx, mut sy, mut sxx, mut sxy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for &(x, v, n) in bins {
        let w = weight(x, v, n);
        sw += w;
        sx += w * x;
        sy += w * v;
        sxx += w * x * x;
        sxy += w * x * v;
    }
    let det = sw * sxx - sx * sx;
    if det <= 0.0 {
        return None;
    }
    let a = (sw * sxy - sx * sy) / det;
    let b = (sxx * sy - sx * sxy) / det;
    let chi2: f64 = bins.iter().map(|&(x, v, n)| weight(x, v, n) * (v - a * x - b).powi(2)).sum();
    let scale = chi2 / (bins.len() - 2) as f64;
    Some((a, b, (scale * sw / det).sqrt(), (scale * sxx / det).sqrt()))
}

/// Estimates the noise model from the photo itself (see the module docs).
pub fn estimate(data: &RawData) -> Result<NoiseModel, NoiseError> {
    // Per channel: every plane's windows.
    let mut per: [Vec<(f64, f64)>; 3] = Default::default();
    for (c, w, h, z) in planes(data) {
        per[c].extend(windows(w, h, &z));
    }
    let mut a = [0.0; 3];
    let mut b = [0.0; 3];
    let (mut sa, mut sb) = ([0.0; 3], [0.0; 3]);
    let mut used = [0usize; 3];
    let mut all_bins = Vec::new();
    let mut notes = Vec::new();
    for c in 0..3 {
        let all = &per[c];
        let too_few = |got: usize| NoiseError::TooFew { channel: CHANNELS[c], got, need: 2 * MIN_PER_BIN };
        if all.len() < 2 * MIN_PER_BIN {
            return Err(too_few(all.len()));
        }
        // Pass 1 over every window (edges inflate it); then, three times, only
        // the windows whose variance is within EDGE_RATIO of the last model's.
        let mut kept = all.clone();
        let mut line: Option<(f64, f64, f64, f64)> = None;
        let mut fine = Vec::new();
        for pass in 0..4 {
            if pass > 0 {
                let (pa, pb) = match line {
                    Some((pa, pb, _, _)) => (pa, pb),
                    None => (
                        fine.iter().map(|b: &(f64, f64, usize)| b.1).sum::<f64>()
                            / fine.iter().map(|b| b.0).sum::<f64>().max(1e-12),
                        0.0,
                    ),
                };
                kept = all.iter().copied().filter(|p| p.1 <= EDGE_RATIO * (pa * p.0 + pb).max(1e-30)).collect();
                if kept.len() < 2 * MIN_PER_BIN {
                    return Err(too_few(kept.len()));
                }
            }
            fine = bins(&mut kept);
            // Weights from the last line; twice on the last pass (reweighted).
            line = fit_line(&fine, line.map(|l| (l.0, l.1)));
            if pass == 3 {
                line = fit_line(&fine, line.map(|l| (l.0, l.1)));
            }
        }
        used[c] = kept.len();
        match line {
            Some((fa, fb, ea, eb)) => {
                (a[c], b[c], sa[c], sb[c]) = (fa, fb, ea, eb);
            }
            None => {
                let (sv, sx): (f64, f64) = fine.iter().fold((0.0, 0.0), |(v, x), b| (v + b.1, x + b.0));
                a[c] = sv / sx.max(1e-12);
                notes.push(format!(
                    "channel {}: its signals span less than 2 % of the white level, too little to separate shot from \
                     read noise: b = 0, a = mean variance / mean signal",
                    CHANNELS[c]
                ));
            }
        }
        all_bins.extend(fine.iter().map(|&(signal, variance, n)| NoiseBin {
            channel: c,
            signal,
            variance,
            photosites: n,
        }));
    }
    Ok(NoiseModel {
        definition: DEFINITION.into(),
        source: NoiseSource::EstimatedFromImage,
        a,
        b,
        a_std_error: Some(sa),
        b_std_error: Some(sb),
        photosites: Some(used),
        bins: all_bins,
        note: notes.join("; "),
    })
}

/// The photo's noise model: the DNG's NoiseProfile where it has a valid one,
/// else [`estimate`] on the photo (a profile that cannot be used is said in
/// the model's note).
pub fn model_of(frame: &RawFrame) -> Result<NoiseModel, NoiseError> {
    let why = match frame.meta.noise_profile.as_deref().map(NoiseModel::from_noise_profile) {
        Some(Ok(m)) => return Ok(m),
        Some(Err(e)) => format!("the file's {e}: not used; "),
        None => String::new(),
    };
    let mut m = estimate(&frame.data)?;
    if !why.is_empty() {
        m.note = format!("{why}{}", m.note);
    }
    Ok(m)
}

/// SplitMix64: the noise realisations' random stream (seeded, so the same
/// photo and seed give the same variance image).
struct SplitMix(u64);

impl SplitMix {
    fn next_f64(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A standard normal variate (Box–Muller).
    fn normal(&mut self) -> f64 {
        let (u, v) = (self.next_f64(), self.next_f64());
        (-2.0 * (1.0 - u).ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// One realisation of the photo's noise, developed like the photo
/// ([`crate::raw::develop`] with `opts`): Gaussian, zero mean, the model's
/// variance at each photosite's recorded value. `seed` picks the realisation.
pub fn developed_noise(
    frame: &RawFrame,
    model: &NoiseModel,
    opts: &RawOptions,
    seed: u64,
) -> Result<RgbBuffer, RawError> {
    let mut rng = SplitMix(seed ^ 0x6E01_5E00_D15E_A5E5);
    let data = match &frame.data {
        RawData::Bayer(m) => {
            let data = m
                .data
                .iter()
                .enumerate()
                .map(|(i, &x)| {
                    let c = m.pattern.colour_at((i / m.width) % 2, (i % m.width) % 2);
                    (model.variance(c, f64::from(x)).sqrt() * rng.normal()) as f32
                })
                .collect();
            RawData::Bayer(Mosaic { width: m.width, height: m.height, pattern: m.pattern, data })
        }
        RawData::Rgb(b) => {
            let data = b
                .data
                .iter()
                .enumerate()
                .map(|(i, &x)| (model.variance(i % 3, f64::from(x)).sqrt() * rng.normal()) as f32)
                .collect();
            RawData::Rgb(RgbBuffer { width: b.width, height: b.height, data })
        }
    };
    let noise = frame.with_data(data);
    Ok(crate::raw::develop(&noise, opts)?.0)
}
