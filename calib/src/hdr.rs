//! HDR radiance maps from exposure brackets (docs/method.md#camera, `lucent env merge`).
//!
//! # Linear brackets (RAW decoded, or linear EXR)
//!
//! Each bracket `i` holds values `v_i = E · t_i` (plus noise, clipped at the
//! white level), with `t_i` the bracket's relative exposure (exposure time ×
//! gain). The merged radiance is the weighted mean of the per-bracket
//! estimates `v_i / t_i`:
//!
//! E = Σ_i w_i v_i / t_i / Σ_i w_i,   w_i = t_i · s(m_i),
//!
//! where `m_i` is the pixel's largest channel in bracket `i`. The factor `t_i`
//! is the inverse variance of `v_i / t_i` under photon noise (var(v_i) ∝ E t_i,
//! so var(v_i/t_i) ∝ E / t_i; Granados et al., CVPR 2010, "Optimal HDR
//! reconstruction with linear digital cameras", §3), and `s` removes
//! unreliable samples: s = 0 at or above the saturation level, s = 0 below
//! the noise floor, rising linearly to 1 between the floor and twice the
//! floor. One weight per pixel (all channels together), so a pixel with one
//! clipped channel does not change hue.
//!
//! # 8-bit brackets (JPEG, 8-bit PNG/TIFF)
//!
//! The code values `Z` are a non-linear function of exposure, Z = f(E t).
//! The inverse response `g = f⁻¹` (256 values per channel, relative scale)
//! is recovered from the brackets by Debevec & Malik (SIGGRAPH 1997,
//! "Recovering high dynamic range radiance maps from photographs", eq. 3,
//! smoothness λ = 10, 70 grid samples) or Robertson et al. (JEI 2003,
//! "Estimation-theoretic approach to dynamic range enhancement", 30
//! iterations) through OpenCV's `photo` module ([`crate::cv::recover_response`]),
//! then the brackets are merged in the log domain as in Debevec & Malik eq. 6:
//!
//! ln E = Σ_i w(Z_i) (ln g(Z_i) − ln t_i) / Σ_i w(Z_i),
//!
//! with the hat weight w(Z) = min(Z, 255 − Z) of the pixel's largest code,
//! and w = 0 at or above the saturation code (default 250) or at or below
//! the floor code (default 5). The response is only known up to one global
//! factor, so an 8-bit merge is radiance up to scale (fixed later by
//! `lucent env fit-scale`).
//!
//! # Pixels no bracket measures
//!
//! A pixel saturated in every bracket takes the shortest exposure's value
//! over its exposure (a lower bound); a pixel below the floor in every
//! bracket takes the longest exposure's. Both are counted in the
//! [`MergeReport`] with the saturated pixels listed.
//!
//! ```
//! use lucent_calib::hdr::{merge_linear, LinearWeights};
//! use lucent_calib::RgbBuffer;
//! // One pixel of radiance 3.0 seen at exposures 0.1 and 1.0 (white level 1):
//! // the long exposure clips, the short one measures 0.3.
//! let short = RgbBuffer::new(1, 1, vec![0.3; 3]).unwrap();
//! let long = RgbBuffer::new(1, 1, vec![1.0; 3]).unwrap();
//! let m = merge_linear(&[short, long], &[0.1, 1.0], &LinearWeights::default()).unwrap();
//! assert!((m.image.pixel(0, 0)[0] - 3.0).abs() < 1e-6);
//! assert_eq!(m.report.saturated_in_every_bracket, 0);
//! ```

pub use crate::bracket::{HdrError, Response, ResponseMethod, Rgb8Buffer};
use crate::buffer::RgbBuffer;
use serde::{Deserialize, Serialize};

/// Saturation and noise-floor levels of linear brackets (same units as
/// their values; RAW decoded by [`crate::raw`] has white = 1.0).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LinearWeights {
    /// A pixel whose largest channel is at or above this is saturated.
    pub saturation: f32,
    /// Below this the pixel is noise; weights rise linearly from here to twice it.
    pub noise_floor: f32,
}

impl Default for LinearWeights {
    /// Saturation 0.98 (2 % below the white level 1.0), noise floor 0.002.
    fn default() -> Self {
        Self { saturation: 0.98, noise_floor: 0.002 }
    }
}

/// Saturation and floor codes of 8-bit brackets.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CodeWeights {
    /// A pixel whose largest code is at or above this is saturated (default 250).
    pub saturation: u8,
    /// A pixel whose largest code is at or below this is noise (default 5).
    pub floor: u8,
}

impl Default for CodeWeights {
    fn default() -> Self {
        Self { saturation: 250, floor: 5 }
    }
}

/// What a merge reached and what it could not measure.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MergeReport {
    pub width: usize,
    pub height: usize,
    pub brackets: usize,
    /// Relative exposure of each bracket, as used.
    pub exposures: Vec<f64>,
    /// `"linear"` or `"8-bit <method>"`.
    pub mode: String,
    /// log2(largest / smallest positive merged luminance) over the pixels
    /// measured by at least one bracket, stops.
    pub dynamic_range_stops: f64,
    /// What the bracket set can measure: log2((saturation / shortest
    /// exposure) / (noise floor / longest exposure)), stops.
    pub capturable_range_stops: f64,
    /// Pixels saturated in every bracket (their value is a lower bound).
    pub saturated_in_every_bracket: usize,
    /// Pixels below the noise floor in every bracket.
    pub below_floor_in_every_bracket: usize,
    /// Up to 1000 of the pixels saturated in every bracket, [x, y].
    pub saturated_pixels: Vec<[usize; 2]>,
    /// Pixels saturated per bracket.
    pub saturated_per_bracket: Vec<usize>,
}

/// A merged HDR image, its report, and the mask of pixels saturated in
/// every bracket (row-major, `true` = saturated everywhere).
#[derive(Debug, Clone, PartialEq)]
pub struct Merged {
    pub image: RgbBuffer,
    pub report: MergeReport,
    pub saturated_mask: Vec<bool>,
}

fn check_exposures(n: usize, exposures: &[f64]) -> Result<(), HdrError> {
    if n < 2 {
        return Err(HdrError::TooFewBrackets(n));
    }
    if exposures.len() != n {
        return Err(HdrError::ExposureCount { brackets: n, exposures: exposures.len() });
    }
    for (index, &value) in exposures.iter().enumerate() {
        if !(value.is_finite() && value > 0.0) {
            return Err(HdrError::BadExposure { index, value });
        }
    }
    for a in 0..n {
        for b in a + 1..n {
            if exposures[a] == exposures[b] {
                return Err(HdrError::SameExposure { a, b, value: exposures[a] });
            }
        }
    }
    Ok(())
}

fn check_sizes(sizes: &[(usize, usize)]) -> Result<(), HdrError> {
    let (width0, height0) = sizes[0];
    for (index, &(width, height)) in sizes.iter().enumerate() {
        if (width, height) != (width0, height0) || width == 0 || height == 0 {
            return Err(HdrError::SizeMismatch { index, width, height, width0, height0 });
        }
    }
    Ok(())
}

/// Per-bracket sample of one pixel: linear estimate E·t (RGB), weight, flags.
struct Sample {
    value: [f64; 3],
    weight: f64,
    saturated: bool,
    below_floor: bool,
}

/// The shared merge: `sample(i, p)` gives bracket i's sample of pixel p;
/// `log_domain` averages ln(value/t) (Debevec–Malik eq. 6) instead of value/t.
fn merge_core(
    width: usize,
    height: usize,
    exposures: &[f64],
    log_domain: bool,
    sample: impl Fn(usize, usize) -> Sample,
) -> Core {
    let n = exposures.len();
    let shortest = (0..n).min_by(|&a, &b| exposures[a].total_cmp(&exposures[b])).unwrap_or(0);
    let longest = (0..n).max_by(|&a, &b| exposures[a].total_cmp(&exposures[b])).unwrap_or(0);
    let mut out = RgbBuffer::zeros(width, height);
    let mut sat_all = vec![false; width * height];
    let mut floor_all = 0;
    let mut sat_per = vec![0usize; n];
    let (mut lum_min, mut lum_max) = (f64::INFINITY, 0.0f64);
    for (p, sat_p) in sat_all.iter_mut().enumerate() {
        let mut acc = [0.0f64; 3];
        let mut wsum = 0.0;
        let (mut all_sat, mut all_floor) = (true, true);
        for (i, &t) in exposures.iter().enumerate() {
            let s = sample(i, p);
            sat_per[i] += usize::from(s.saturated);
            all_sat &= s.saturated;
            all_floor &= s.below_floor;
            if s.weight > 0.0 {
                for (a, v) in acc.iter_mut().zip(s.value) {
                    *a += s.weight * if log_domain { (v.max(1e-30) / t).ln() } else { v / t };
                }
                wsum += s.weight;
            }
        }
        let e: [f64; 3] = if wsum > 0.0 {
            let mean = acc.map(|a| a / wsum);
            if log_domain {
                mean.map(f64::exp)
            } else {
                mean
            }
        } else {
            // Nothing measured it: a bound from the nearest bracket.
            let i = if all_sat || !all_floor { shortest } else { longest };
            sample(i, p).value.map(|v| v / exposures[i])
        };
        *sat_p = all_sat;
        floor_all += usize::from(all_floor && !all_sat);
        if wsum > 0.0 {
            let y = 0.2126 * e[0] + 0.7152 * e[1] + 0.0722 * e[2];
            if y > 0.0 {
                lum_min = lum_min.min(y);
                lum_max = lum_max.max(y);
            }
        }
        for (o, v) in out.data[3 * p..3 * p + 3].iter_mut().zip(e) {
            *o = v as f32;
        }
    }
    let dr = if lum_max > 0.0 && lum_min.is_finite() { (lum_max / lum_min).log2() } else { 0.0 };
    Core { image: out, sat_all, floor_all, sat_per, dr }
}

/// What [`merge_core`] returns.
struct Core {
    image: RgbBuffer,
    sat_all: Vec<bool>,
    floor_all: usize,
    sat_per: Vec<usize>,
    dr: f64,
}

#[allow(clippy::too_many_arguments)]
fn report(
    width: usize,
    height: usize,
    exposures: &[f64],
    mode: String,
    dr: f64,
    capturable: f64,
    sat_all: &[bool],
    floor_all: usize,
    sat_per: Vec<usize>,
) -> MergeReport {
    let saturated_pixels: Vec<[usize; 2]> =
        sat_all.iter().enumerate().filter(|&(_, &s)| s).take(1000).map(|(p, _)| [p % width, p / width]).collect();
    MergeReport {
        width,
        height,
        brackets: exposures.len(),
        exposures: exposures.to_vec(),
        mode,
        dynamic_range_stops: dr,
        capturable_range_stops: capturable,
        saturated_in_every_bracket: sat_all.iter().filter(|&&s| s).count(),
        below_floor_in_every_bracket: floor_all,
        saturated_pixels,
        saturated_per_bracket: sat_per,
    }
}

fn exposure_span(exposures: &[f64]) -> f64 {
    let max = exposures.iter().copied().fold(0.0, f64::max);
    let min = exposures.iter().copied().fold(f64::INFINITY, f64::min);
    max / min
}

/// Merges linear brackets (values ∝ radiance × exposure) taken at relative
/// `exposures` (one per bracket, all different). See the module doc for the
/// weights.
pub fn merge_linear(brackets: &[RgbBuffer], exposures: &[f64], w: &LinearWeights) -> Result<Merged, HdrError> {
    check_exposures(brackets.len(), exposures)?;
    check_sizes(&brackets.iter().map(|b| (b.width, b.height)).collect::<Vec<_>>())?;
    if !(w.saturation.is_finite()
        && w.noise_floor.is_finite()
        && w.noise_floor >= 0.0
        && w.saturation > 2.0 * w.noise_floor)
    {
        return Err(HdrError::LinearWeights { saturation: w.saturation, noise_floor: w.noise_floor });
    }
    for (index, b) in brackets.iter().enumerate() {
        if let Some(k) = b.data.iter().position(|v| !v.is_finite()) {
            return Err(HdrError::NonFinite { index, x: (k / 3) % b.width, y: (k / 3) / b.width });
        }
    }
    let (width, height) = (brackets[0].width, brackets[0].height);
    let (sat, floor) = (f64::from(w.saturation), f64::from(w.noise_floor));
    let Core { image: img, sat_all, floor_all, sat_per, dr } = merge_core(width, height, exposures, false, |i, p| {
        let d = &brackets[i].data[3 * p..3 * p + 3];
        let value = [f64::from(d[0]), f64::from(d[1]), f64::from(d[2])];
        let m = value[0].max(value[1]).max(value[2]);
        let saturated = m >= sat;
        let below_floor = m < floor;
        let ramp = if floor > 0.0 { ((m - floor) / floor).clamp(0.0, 1.0) } else { 1.0 };
        let weight = if saturated || below_floor { 0.0 } else { exposures[i] * ramp };
        Sample { value, weight, saturated, below_floor }
    });
    let capturable = (exposure_span(exposures) * sat / floor.max(f64::MIN_POSITIVE)).log2();
    let rep = report(width, height, exposures, "linear".into(), dr, capturable, &sat_all, floor_all, sat_per);
    Ok(Merged { image: img, report: rep, saturated_mask: sat_all })
}

/// Checks 8-bit brackets and their exposures (sizes, counts, values).
pub fn check_8bit(brackets: &[Rgb8Buffer], exposures: &[f64]) -> Result<(), HdrError> {
    check_exposures(brackets.len(), exposures)?;
    check_sizes(&brackets.iter().map(|b| (b.width, b.height)).collect::<Vec<_>>())
}

/// Merges 8-bit brackets through a recovered inverse response (Debevec &
/// Malik eq. 6, module doc). The result is relative radiance (one global
/// factor unknown).
pub fn merge_8bit(
    brackets: &[Rgb8Buffer],
    exposures: &[f64],
    response: &Response,
    w: &CodeWeights,
) -> Result<Merged, HdrError> {
    check_8bit(brackets, exposures)?;
    if w.floor >= w.saturation {
        return Err(HdrError::CodeWeights { floor: w.floor, saturation: w.saturation });
    }
    for (c, curve) in response.curve.iter().enumerate() {
        if curve.len() != 256 || curve.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(HdrError::BadResponse { channel: c });
        }
    }
    let (width, height) = (brackets[0].width, brackets[0].height);
    let Core { image: img, sat_all, floor_all, sat_per, dr } = merge_core(width, height, exposures, true, |i, p| {
        let d = &brackets[i].data[3 * p..3 * p + 3];
        let value = std::array::from_fn(|c| f64::from(response.curve[c][usize::from(d[c])]));
        let m = d[0].max(d[1]).max(d[2]);
        let saturated = m >= w.saturation;
        let below_floor = m <= w.floor;
        let hat = f64::from(m.min(255 - m));
        let weight = if saturated || below_floor { 0.0 } else { hat };
        Sample { value, weight, saturated, below_floor }
    });
    // Capturable range in the response's own units (green channel).
    let g = &response.curve[1];
    let capturable = (exposure_span(exposures) * f64::from(g[usize::from(w.saturation) - 1])
        / f64::from(g[usize::from(w.floor) + 1]))
    .log2();
    let mode = format!("8-bit {}", response.method.name());
    let rep = report(width, height, exposures, mode, dr, capturable, &sat_all, floor_all, sat_per);
    Ok(Merged { image: img, report: rep, saturated_mask: sat_all })
}

/// Recovers the inverse response from the brackets (OpenCV `photo`), then
/// merges them ([`merge_8bit`]).
pub fn merge_8bit_recovered(
    brackets: &[Rgb8Buffer],
    exposures: &[f64],
    method: ResponseMethod,
    w: &CodeWeights,
) -> Result<(Merged, Response), HdrError> {
    check_8bit(brackets, exposures)?;
    let response = crate::cv::recover_response(brackets, exposures, method)?;
    let merged = merge_8bit(brackets, exposures, &response, w)?;
    Ok((merged, response))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A smooth synthetic radiance field spanning ~12 stops.
    fn scene(w: usize, h: usize) -> RgbBuffer {
        let mut img = RgbBuffer::zeros(w, h);
        for y in 0..h {
            for x in 0..w {
                let a = x as f32 / (w - 1) as f32;
                let b = y as f32 / (h - 1) as f32;
                let e = 2f32.powf(-6.0 + 12.0 * a);
                let i = 3 * (y * w + x);
                img.data[i] = e * (0.6 + 0.4 * b);
                img.data[i + 1] = e * 0.8;
                img.data[i + 2] = e * (1.0 - 0.5 * b);
            }
        }
        img
    }

    #[test]
    fn linear_brackets_merge_back_exactly_where_measured() {
        let truth = scene(64, 8);
        let exposures = [1.0 / 128.0, 1.0 / 8.0, 1.0, 8.0];
        let brackets: Vec<RgbBuffer> = exposures
            .iter()
            .map(|&t| RgbBuffer {
                data: truth.data.iter().map(|&e| (e * t as f32).min(1.0)).collect(),
                ..truth.clone()
            })
            .collect();
        let m = merge_linear(&brackets, &exposures, &LinearWeights::default()).unwrap();
        for (a, b) in m.image.data.iter().zip(&truth.data) {
            assert!((a - b).abs() <= 1e-5 * b, "{a} vs {b}");
        }
        assert_eq!(m.report.saturated_in_every_bracket, 0);
        // 12 stops of luminance (times the colour variation).
        assert!((m.report.dynamic_range_stops - 12.0).abs() < 0.5, "{}", m.report.dynamic_range_stops);
        // A pixel brighter than the shortest exposure can hold is flagged and bounded.
        let mut b2 = brackets.clone();
        for b in &mut b2 {
            b.data[..3].copy_from_slice(&[1.0; 3]);
        }
        let m = merge_linear(&b2, &exposures, &LinearWeights::default()).unwrap();
        assert_eq!(m.report.saturated_in_every_bracket, 1);
        assert_eq!(m.report.saturated_pixels, [[0, 0]]);
        assert_eq!(m.image.pixel(0, 0), [128.0; 3]);
    }

    #[test]
    fn bad_brackets_are_rejected() {
        let a = RgbBuffer::zeros(4, 2);
        let b = RgbBuffer::zeros(4, 3);
        let w = LinearWeights::default();
        let e = merge_linear(&[a.clone(), b], &[1.0, 2.0], &w).unwrap_err();
        assert_eq!(e, HdrError::SizeMismatch { index: 1, width: 4, height: 3, width0: 4, height0: 2 });
        assert!(e.to_string().contains("4 × 3") && e.to_string().contains("same size"));
        assert_eq!(merge_linear(std::slice::from_ref(&a), &[1.0], &w).unwrap_err(), HdrError::TooFewBrackets(1));
        assert!(matches!(merge_linear(&[a.clone(), a.clone()], &[1.0], &w), Err(HdrError::ExposureCount { .. })));
        assert!(matches!(merge_linear(&[a.clone(), a.clone()], &[1.0, -1.0], &w), Err(HdrError::BadExposure { .. })));
        assert!(matches!(merge_linear(&[a.clone(), a.clone()], &[1.0, 1.0], &w), Err(HdrError::SameExposure { .. })));
        let mut nan = a.clone();
        nan.data[4] = f32::NAN;
        assert_eq!(
            merge_linear(&[a.clone(), nan], &[1.0, 2.0], &w).unwrap_err(),
            HdrError::NonFinite { index: 1, x: 1, y: 0 }
        );
        let bad = LinearWeights { saturation: 0.001, noise_floor: 0.002 };
        assert!(matches!(merge_linear(&[a.clone(), a], &[1.0, 2.0], &bad), Err(HdrError::LinearWeights { .. })));
        assert!(ResponseMethod::from_name("mitsunaga").unwrap_err().to_string().contains("debevec or robertson"));
    }

    #[test]
    fn eight_bit_merge_with_the_true_response_recovers_the_radiance() {
        // Known response: Z = round(255 (E t)^(1/2.2)); its inverse at code centres.
        let truth = scene(64, 8);
        let exposures = [1.0 / 64.0, 1.0 / 16.0, 1.0 / 4.0, 1.0, 4.0, 16.0];
        let brackets: Vec<Rgb8Buffer> = exposures
            .iter()
            .map(|&t| Rgb8Buffer {
                width: 64,
                height: 8,
                data: truth
                    .data
                    .iter()
                    .map(|&e| (255.0 * (f64::from(e) * t).min(1.0).powf(1.0 / 2.2)).round() as u8)
                    .collect(),
            })
            .collect();
        let curve: Vec<f32> = (0..256).map(|z| (f64::from(z.max(1)) / 255.0).powf(2.2) as f32).collect();
        let response = Response { method: ResponseMethod::Debevec, curve: [curve.clone(), curve.clone(), curve] };
        let m = merge_8bit(&brackets, &exposures, &response, &CodeWeights::default()).unwrap();
        let mut worst = 0.0f32;
        for (a, b) in m.image.data.iter().zip(&truth.data) {
            worst = worst.max((a / b - 1.0).abs());
        }
        // 8-bit quantisation: ≤ half a code at Z ≥ 64 of the best bracket → ≤ 2.2 × 0.5/64 ≈ 1.7 %.
        assert!(worst < 0.03, "worst relative error {worst}");
    }
}
