//! Is the photo within the twin's predictive band? (`lucent compare --band`)
//!
//! Over the compared pixels (the object's or the board's), per band R, G, B,
//! the photo's mean P̄ is set against the twin's mean R̄ with everything that
//! makes them differ when the twin is right:
//!
//! * the recipe's uncertainty: the twin's relative band u_in/R̄ of that
//!   region (`lucent render --uncertainty`, its `uncertainty.json`), times
//!   R̄ over the compared pixels (the band is the same recipe's effect on
//!   the same object, so the relative figure carries over when the compared
//!   pixels are a subset of the render's, e.g. without clipped pixels);
//! * the render's Monte Carlo error of R̄: √(Σ var(pixel mean))/n;
//! * the photo's noise in P̄: √(Σ var(pixel))/n from the photo's variance
//!   (`--photo-variance` or `--photo-repeat`), 0 when none is given (said so).
//!
//! The predictive standard deviation is u = √(u_in² + u_MC² + u_photo²),
//! z = (P̄ − R̄)/u, and the photo lies within the band when |z| ≤ k = 2 in
//! every band (coverage ≈ 95 % per band for normal errors; JCGM 100:2008
//! "GUM", 6.2–6.3).
//!
//! ```
//! use lucent::compare::band::{check, TwinBand};
//! let band = TwinBand { region: "object".into(), inputs_relative_sd: [0.02; 3], pixels: 100 };
//! // The photo is 3 % above the twin, the band 2 %: within (z = 1.5).
//! let c = check(&band, [1.03; 3], None, [1.0; 3], Some([0.0; 3]), 100);
//! assert!(c.within && (c.z[0] - 1.5).abs() < 1e-9);
//! ```

use serde::{Deserialize, Serialize};
use std::path::Path;

/// The coverage factor k of the check: within when |z| ≤ k.
pub const COVERAGE_FACTOR: f64 = 2.0;

/// A twin's band over one region, read from its `uncertainty.json`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct TwinBand {
    /// "object" or "board".
    pub region: String,
    /// The region's standard deviation from the recipe's inputs relative to its mean, per band.
    pub inputs_relative_sd: [f64; 3],
    /// Pixels of the region in the render.
    pub pixels: usize,
}

/// A twin's bands by region: the regions of an `uncertainty.json`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
pub struct TwinBands {
    /// Where they come from (the file, or "band" for a value given in Python).
    #[serde(skip)]
    pub source: String,
    pub regions: Vec<TwinBand>,
}

/// Why a band cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum BandError {
    #[error("{source_name}: cannot read: {reason}")]
    Read { source_name: String, reason: String },
    #[error("{source_name}: has no {region} region (it has {have}); the band is of the region compared (--mask-object or --mask-board)")]
    NoRegion { source_name: String, region: String, have: String },
}

impl TwinBands {
    /// The bands in the text of an `uncertainty.json`, checked: finite,
    /// non-negative relative sds. `source` names it in errors.
    pub fn from_json(text: &str, source: &str) -> Result<Self, BandError> {
        let bad = |reason: String| BandError::Read { source_name: source.to_string(), reason };
        let mut parsed: TwinBands = serde_json::from_str(text)
            .map_err(|e| bad(format!("not a render's uncertainty.json (lucent render --uncertainty): {e}")))?;
        for r in &parsed.regions {
            if let Some(v) = r.inputs_relative_sd.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
                return Err(bad(format!("{}'s inputs_relative_sd holds {v}, not a finite number ≥ 0", r.region)));
            }
        }
        parsed.source = source.to_string();
        Ok(parsed)
    }

    /// The `uncertainty.json` at `path` (or in the folder `path`).
    pub fn read(path: &Path) -> Result<Self, BandError> {
        let file =
            if path.is_dir() { crate::scene::band::RenderBandFiles::in_dir(path).json } else { path.to_path_buf() };
        let name = file.display().to_string();
        let text = std::fs::read_to_string(&file).map_err(|e| BandError::Read {
            source_name: name.clone(),
            reason: if e.kind() == std::io::ErrorKind::InvalidData {
                "not a render's uncertainty.json (lucent render --uncertainty): not text".into()
            } else {
                e.to_string()
            },
        })?;
        Self::from_json(&text, &name)
    }

    /// The band of `region` ("object" or "board").
    pub fn region(&self, region: &str) -> Result<&TwinBand, BandError> {
        self.regions.iter().find(|r| r.region == region).ok_or_else(|| BandError::NoRegion {
            source_name: self.source.clone(),
            region: region.to_string(),
            have: self.regions.iter().map(|r| r.region.clone()).collect::<Vec<_>>().join(", "),
        })
    }
}

/// `band` in metrics.json: the photo against one twin's predictive band.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BandCheck {
    /// The twin's render and its uncertainty.json.
    pub render: String,
    pub band: String,
    /// "object" or "board", and the compared pixels.
    pub region: String,
    pub pixels: usize,
    /// Means over the compared pixels per band R, G, B.
    pub photo_mean: [f64; 3],
    pub render_mean: [f64; 3],
    /// Standard deviations of P̄ − R̄ per band: from the recipe's inputs, the
    /// render's Monte Carlo error, the photo's noise (0 when unknown), and all three.
    pub inputs_sd: [f64; 3],
    pub monte_carlo_sd: [f64; 3],
    pub photo_noise_sd: [f64; 3],
    pub photo_noise_known: bool,
    pub predictive_sd: [f64; 3],
    /// (P̄ − R̄) / predictive_sd per band.
    pub z: [f64; 3],
    pub coverage_factor: f64,
    /// |z| ≤ k in every band.
    pub within: bool,
    /// The answer in one sentence.
    pub statement: String,
}

/// The check of a photo's mean against a twin's: `photo_mean_var` and
/// `render_mean_var` are the variances of the two means (`None`: unknown).
pub fn check(
    band: &TwinBand,
    photo_mean: [f64; 3],
    photo_mean_var: Option<[f64; 3]>,
    render_mean: [f64; 3],
    render_mean_var: Option<[f64; 3]>,
    pixels: usize,
) -> BandCheck {
    let inputs_sd: [f64; 3] = std::array::from_fn(|c| band.inputs_relative_sd[c] * render_mean[c].abs());
    let monte_carlo_sd = render_mean_var.unwrap_or([0.0; 3]).map(f64::sqrt);
    let photo_noise_sd = photo_mean_var.unwrap_or([0.0; 3]).map(f64::sqrt);
    let predictive_sd: [f64; 3] =
        std::array::from_fn(|c| (inputs_sd[c].powi(2) + monte_carlo_sd[c].powi(2) + photo_noise_sd[c].powi(2)).sqrt());
    let z: [f64; 3] = std::array::from_fn(|c| {
        let d = photo_mean[c] - render_mean[c];
        if predictive_sd[c] > 0.0 {
            d / predictive_sd[c]
        } else if d == 0.0 {
            0.0
        } else {
            d.signum() * f64::INFINITY
        }
    });
    let within = z.iter().all(|v| v.abs() <= COVERAGE_FACTOR);
    let pct = |v: [f64; 3]| {
        std::array::from_fn::<String, 3, _>(|c| {
            // One decimal, two below 1 % (a render's Monte Carlo error of
            // the object's mean is often a few hundredths of a percent).
            let p = 100.0 * v[c] / render_mean[c].abs().max(f64::MIN_POSITIVE);
            if p.abs() < 1.0 {
                format!("{p:+.2}")
            } else {
                format!("{p:+.1}")
            }
        })
        .join("/")
    };
    let off: [f64; 3] = std::array::from_fn(|c| photo_mean[c] - render_mean[c]);
    let statement = format!(
        "The photo's mean over the {} ({pixels} px) is {} % (R/G/B) from the twin's, {} its predictive band (±{} %, k = {COVERAGE_FACTOR}: the recipe's inputs ±{} %, Monte Carlo ±{} %, photo noise {}); z = {}.",
        band.region,
        pct(off),
        if within { "within" } else { "outside" },
        pct(predictive_sd.map(|v| COVERAGE_FACTOR * v)).replace('+', ""),
        pct(inputs_sd).replace('+', ""),
        pct(monte_carlo_sd).replace('+', ""),
        if photo_mean_var.is_some() {
            format!("±{} %", pct(photo_noise_sd).replace('+', ""))
        } else {
            "not given (taken as 0)".to_string()
        },
        z.map(|v| format!("{v:+.2}")).join("/"),
    );
    BandCheck {
        render: String::new(),
        band: String::new(),
        region: band.region.clone(),
        pixels,
        photo_mean,
        render_mean,
        inputs_sd,
        monte_carlo_sd,
        photo_noise_sd,
        photo_noise_known: photo_mean_var.is_some(),
        predictive_sd,
        z,
        coverage_factor: COVERAGE_FACTOR,
        within,
        statement,
    }
}

/// Mean per band of interleaved RGB `data` over the `include`d pixels
/// (all when `None`), and the variance of that mean from per-pixel
/// variances `var` (interleaved RGB) when given.
pub fn region_mean(data: &[f32], var: Option<&[f32]>, include: Option<&[bool]>) -> ([f64; 3], Option<[f64; 3]>, usize) {
    let (mut sum, mut vsum, mut n) = ([0.0f64; 3], [0.0f64; 3], 0usize);
    for (p, px) in data.chunks_exact(3).enumerate() {
        if include.is_some_and(|m| !m[p]) {
            continue;
        }
        n += 1;
        for c in 0..3 {
            sum[c] += f64::from(px[c]);
            if let Some(v) = var {
                vsum[c] += f64::from(v[3 * p + c]);
            }
        }
    }
    let nf = n.max(1) as f64;
    (sum.map(|s| s / nf), var.map(|_| vsum.map(|s| s / (nf * nf))), n)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn band(rel: f64) -> TwinBand {
        TwinBand { region: "object".into(), inputs_relative_sd: [rel; 3], pixels: 10 }
    }

    #[test]
    fn every_source_of_spread_widens_the_band() {
        // 5 % off; the recipe alone (2 %) leaves it outside, with the
        // render's (3 %) and photo's (3 %) errors it is within (u = 4.69 %).
        let alone = check(&band(0.02), [1.05; 3], None, [1.0; 3], Some([0.0; 3]), 10);
        assert!(!alone.within && (alone.z[1] - 2.5).abs() < 1e-9, "{alone:?}");
        assert!(alone.statement.contains("outside") && alone.statement.contains("not given"));
        let all = check(&band(0.02), [1.05; 3], Some([0.03f64.powi(2); 3]), [1.0; 3], Some([0.03f64.powi(2); 3]), 10);
        let u = (0.02f64.powi(2) + 2.0 * 0.03f64.powi(2)).sqrt();
        assert!(all.within && (all.predictive_sd[2] - u).abs() < 1e-12 && (all.z[0] - 0.05 / u).abs() < 1e-9);
        // One band outside is outside.
        let one = check(&band(0.02), [1.0, 1.0, 0.9], None, [1.0; 3], None, 10);
        assert!(!one.within && one.z[2] < -2.0);
    }

    #[test]
    fn a_region_mean_and_its_variance_over_a_mask() {
        let data = [1.0, 2.0, 3.0, 3.0, 4.0, 5.0, 100.0, 100.0, 100.0];
        let var = [0.1, 0.2, 0.3, 0.3, 0.2, 0.1, 9.0, 9.0, 9.0];
        let (m, v, n) = region_mean(&data, Some(&var), Some(&[true, true, false]));
        assert_eq!((m, n), ([2.0, 3.0, 4.0], 2));
        let v = v.unwrap();
        assert!((v[0] - 0.4 / 4.0).abs() < 1e-7 && (v[2] - 0.4 / 4.0).abs() < 1e-7);
    }

    #[test]
    fn a_band_file_without_the_region_or_with_a_bad_figure_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("uncertainty.json");
        std::fs::write(&p, r#"{"regions":[{"region":"board","pixels":4,"inputs_relative_sd":[0.01,0.01,0.01]}]}"#)
            .unwrap();
        let bands = TwinBands::read(dir.path()).unwrap();
        let e = bands.region("object").unwrap_err().to_string();
        assert!(e.contains("no object region") && e.contains("board") && e.contains("uncertainty.json"), "{e}");
        assert!(bands.region("board").is_ok());
        std::fs::write(&p, r#"{"regions":[{"region":"object","pixels":4,"inputs_relative_sd":[0.01,-1,0.01]}]}"#)
            .unwrap();
        assert!(TwinBands::read(&p).unwrap_err().to_string().contains("-1"));
        std::fs::write(&p, "{}").unwrap();
        assert!(TwinBands::read(&p).unwrap_err().to_string().contains("uncertainty.json"));
    }
}
