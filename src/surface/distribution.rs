//! The measured distribution of microfacet normals D(θ_m) and D(θ_m, φ_m).
//!
//! Every pixel stands for the same projected (macroscopic) area, so the
//! fraction of pixel normals in a solid-angle bin estimates ∫_bin D(m)(m·n)
//! dω_m. For a bin θ ∈ [θ₀, θ₁), all φ:
//!
//!   D_bin = (count / N) / (π (sin²θ₁ − sin²θ₀))   [1/sr],
//!
//! the mean of D over the bin weighted by cos θ sin θ, with N all normals,
//! so Σ D_bin π (sin²θ₁ − sin²θ₀) = (normals in range)/N ≤ 1, i.e.
//! ∫ D(m)(m·n) dω_m = 1 over the hemisphere. The 2-D histogram uses
//! (count/N) / (Δφ ½ (sin²θ₁ − sin²θ₀)).
//!
//! Bins (chosen from the data, stated in the result): θ from 0 to θ_max, the
//! 99.9th percentile of θ_m (the last 0.1 % are left out, so that a few
//! outliers do not stretch the axis); width by the Freedman–Diaconis rule
//! h = 2 IQR(θ) N^(−1/3), clamped to 8–400 bins. The 2-D histogram covers
//! the core, θ up to the 90th percentile, with bins of twice the
//! Freedman–Diaconis width (4–40) and 24 φ bins of 15°.
//! Each bin carries its Poisson standard error √count / N / Ω_proj.
//!
//! Anisotropy: the eigen-decomposition of E[(n_x, n_y)(n_x, n_y)ᵀ] over the
//! normals gives the RMS of the normals' horizontal part along its major and
//! minor axes, their ratio (1 = isotropic) and the major axis's azimuth.
//!
//! ```
//! use lucent::surface::normals::NormalField;
//! use lucent::surface::distribution::measure;
//! // 400 normals with slopes on a 20 × 20 grid from −0.01 to 0.009.
//! let sx: Vec<f64> = (0..400).map(|k| 0.001 * ((k % 20) as f64 - 10.0)).collect();
//! let sy: Vec<f64> = (0..400).map(|k| 0.001 * ((k / 20) as f64 - 10.0)).collect();
//! let field = NormalField { nx: 20, ny: 20, slope_x: sx, slope_y: sy, count: 400 };
//! let d = measure(&field, "doc").unwrap();
//! assert!(d.fraction_in_range > 0.99);
//! let total: f64 = d.d_per_sr.iter().zip(d.edges_rad.windows(2))
//!     .map(|(v, e)| v * std::f64::consts::PI * (e[1].sin().powi(2) - e[0].sin().powi(2))).sum();
//! assert!((total - d.fraction_in_range).abs() < 1e-12);
//! ```

use super::error::SurfaceError;
use super::normals::NormalField;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// A 2-D (θ, φ) histogram of normals.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Histogram2d {
    pub theta_edges_rad: Vec<f64>,
    pub phi_edges_rad: Vec<f64>,
    /// Counts, row-major [θ bin][φ bin].
    pub counts: Vec<u64>,
    /// D per bin in 1/sr, row-major [θ bin][φ bin].
    pub d_per_sr: Vec<f64>,
}

/// Slope anisotropy from the normals' horizontal components.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct Anisotropy {
    /// RMS of the normals' horizontal part along the major axis.
    pub rms_major: f64,
    /// RMS along the minor axis.
    pub rms_minor: f64,
    /// rms_major / rms_minor (1 for an isotropic surface).
    pub ratio: f64,
    /// Azimuth of the major axis, degrees in (−90, 90] from +x towards +y.
    pub major_azimuth_deg: f64,
}

/// The measured distribution of normals.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Distribution {
    /// Normals used (pixels with a plane fit).
    pub normals: usize,
    /// How the bins were chosen.
    pub bin_rule: String,
    pub bin_width_rad: f64,
    pub theta_max_rad: f64,
    /// Fraction of the normals with θ < θ_max.
    pub fraction_in_range: f64,
    /// θ bin edges in radians (bins + 1 values).
    pub edges_rad: Vec<f64>,
    pub counts: Vec<u64>,
    /// Normalised D(θ) per bin, 1/sr.
    pub d_per_sr: Vec<f64>,
    /// Poisson standard error of each bin's D, 1/sr.
    pub d_std_error_per_sr: Vec<f64>,
    /// Mean unit normal (normalised mean of the unit normals).
    pub mean_normal: [f64; 3],
    /// Angle of the mean normal from z, degrees.
    pub mean_normal_tilt_deg: f64,
    /// Azimuth of the mean normal, degrees from +x towards +y.
    pub mean_normal_azimuth_deg: f64,
    /// Median of tan θ_m (a scale for starting the fits).
    pub median_tan_theta: f64,
    pub anisotropy: Anisotropy,
    pub histogram_2d: Histogram2d,
}

impl Distribution {
    /// Bin centres in radians.
    pub fn centres_rad(&self) -> Vec<f64> {
        self.edges_rad.windows(2).map(|e| 0.5 * (e[0] + e[1])).collect()
    }
}

/// The value at quantile q of a slice (sorted in place, partially).
fn quantile(v: &mut [f64], q: f64) -> f64 {
    let k = ((v.len() - 1) as f64 * q).round() as usize;
    *v.select_nth_unstable_by(k, f64::total_cmp).1
}

/// Histograms the normals of `field` (see the module doc).
pub fn measure(field: &NormalField, origin: &str) -> Result<Distribution, SurfaceError> {
    let normals = field.normals();
    let n = normals.len();
    if n < 100 {
        return Err(SurfaceError::Data {
            origin: origin.into(),
            reason: format!("only {n} normals: at least 100 are needed for a distribution (map too small or too many invalid points)"),
        });
    }
    let nf = n as f64;
    let mut theta: Vec<f64> = normals.iter().map(|m| m[2].clamp(-1.0, 1.0).acos()).collect();
    let mut scratch = theta.clone();
    let theta_max = quantile(&mut scratch, 0.999);
    let q25 = quantile(&mut scratch, 0.25);
    let q75 = quantile(&mut scratch, 0.75);
    let median = quantile(&mut scratch, 0.5);
    let theta_90 = quantile(&mut scratch, 0.9);
    if theta_max.is_nan() || theta_max <= 0.0 {
        return Err(SurfaceError::Data {
            origin: origin.into(),
            reason: "the surface is flat: 99.9 % of the normals are exactly vertical".into(),
        });
    }
    let fd = 2.0 * (q75 - q25) * nf.powf(-1.0 / 3.0);
    let bins = if fd > 0.0 { (theta_max / fd).ceil() as usize } else { 8 }.clamp(8, 400);
    let width = theta_max / bins as f64;
    let edges: Vec<f64> = (0..=bins).map(|k| k as f64 * width).collect();
    let mut counts = vec![0u64; bins];
    // The 2-D histogram covers the core (to the 90th percentile), where anisotropy shows.
    let theta2_max = if theta_90 > 0.0 { theta_90 } else { theta_max };
    let bins2 = ((theta2_max / fd.max(f64::MIN_POSITIVE)).ceil() as usize / 2).clamp(4, 40);
    let width2 = theta2_max / bins2 as f64;
    const NPHI: usize = 24;
    let mut counts2 = vec![0u64; bins2 * NPHI];
    let mut mean = [0.0f64; 3];
    let (mut mxx, mut mxy, mut myy) = (0.0, 0.0, 0.0);
    for (m, t) in normals.iter().zip(theta.iter_mut()) {
        for k in 0..3 {
            mean[k] += m[k];
        }
        mxx += m[0] * m[0];
        mxy += m[0] * m[1];
        myy += m[1] * m[1];
        if *t <= theta2_max {
            let b2 = ((*t / width2) as usize).min(bins2 - 1);
            let phi = m[1].atan2(m[0]).rem_euclid(2.0 * PI);
            let p = ((phi / (2.0 * PI / NPHI as f64)) as usize).min(NPHI - 1);
            counts2[b2 * NPHI + p] += 1;
        }
        if *t > theta_max {
            continue;
        }
        let b = ((*t / width) as usize).min(bins - 1);
        counts[b] += 1;
    }
    let proj = |t0: f64, t1: f64| PI * (t1.sin().powi(2) - t0.sin().powi(2));
    let d: Vec<f64> = counts.iter().enumerate().map(|(k, &c)| c as f64 / nf / proj(edges[k], edges[k + 1])).collect();
    let d_err: Vec<f64> =
        counts.iter().enumerate().map(|(k, &c)| (c as f64).sqrt() / nf / proj(edges[k], edges[k + 1])).collect();
    let in_range = counts.iter().sum::<u64>() as f64 / nf;
    let edges2: Vec<f64> = (0..=bins2).map(|k| k as f64 * width2).collect();
    let phi_edges: Vec<f64> = (0..=NPHI).map(|k| k as f64 * 2.0 * PI / NPHI as f64).collect();
    let dphi = 2.0 * PI / NPHI as f64;
    let d2: Vec<f64> = counts2
        .iter()
        .enumerate()
        .map(|(k, &c)| {
            let b = k / NPHI;
            c as f64 / nf / (dphi * 0.5 * (edges2[b + 1].sin().powi(2) - edges2[b].sin().powi(2)))
        })
        .collect();
    let norm = (mean[0] * mean[0] + mean[1] * mean[1] + mean[2] * mean[2]).sqrt();
    let mean_normal = [mean[0] / norm, mean[1] / norm, mean[2] / norm];
    // Eigen-decomposition of the 2 × 2 second-moment matrix of (n_x, n_y).
    let (a, b, c) = (mxx / nf, mxy / nf, myy / nf);
    let tr = a + c;
    let disc = ((a - c) * (a - c) / 4.0 + b * b).sqrt();
    let (l1, l2) = (tr / 2.0 + disc, (tr / 2.0 - disc).max(0.0));
    let mut az = 0.5 * (2.0 * b).atan2(a - c);
    if az <= -PI / 2.0 {
        az += PI;
    }
    let anisotropy = Anisotropy {
        rms_major: l1.sqrt(),
        rms_minor: l2.sqrt(),
        ratio: if l2 > 0.0 { (l1 / l2).sqrt() } else { f64::INFINITY },
        major_azimuth_deg: az.to_degrees(),
    };
    Ok(Distribution {
        normals: n,
        bin_rule: format!(
            "uniform in θ from 0 to the 99.9th percentile of θ_m ({:.4}°), Freedman–Diaconis width 2·IQR·N^(-1/3) = {:.3e} rad → {bins} bins of {:.3e} rad; 2-D: {bins2} θ bins to the 90th percentile ({:.4}°) × {NPHI} φ bins of 15°",
            theta_max.to_degrees(),
            fd,
            width,
            theta2_max.to_degrees()
        ),
        bin_width_rad: width,
        theta_max_rad: theta_max,
        fraction_in_range: in_range,
        edges_rad: edges,
        counts,
        d_per_sr: d,
        d_std_error_per_sr: d_err,
        mean_normal,
        mean_normal_tilt_deg: mean_normal[2].clamp(-1.0, 1.0).acos().to_degrees(),
        mean_normal_azimuth_deg: mean_normal[1].atan2(mean_normal[0]).to_degrees(),
        median_tan_theta: median.tan(),
        anisotropy,
        histogram_2d: Histogram2d { theta_edges_rad: edges2, phi_edges_rad: phi_edges, counts: counts2, d_per_sr: d2 },
    })
}
