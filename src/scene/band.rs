//! The render's uncertainty from the recipe's uncertain inputs (`lucent
//! render --uncertainty`): per input Δᵢ, the change of the image between
//! the input at +1 σ and at −1 σ, and the first-order band
//! u² = Σᵢ (Δᵢ/2)² (JCGM 100:2008 "GUM", eq. 10;
//! [`crate::optics::uncertainty::first_order`]). Δᵢ comes from one of
//! two estimators ([`EffectEstimate`]):
//!
//! * **path derivative**, for an input that changes only the object's μs
//!   and μa (a weight percentage): Δᵢ = 2 σ ∂L/∂θ, estimated by the nominal
//!   render from its own paths ([`lucent_render::tracer::CoefficientDerivative`],
//!   perturbation Monte Carlo), at no extra render, with each pixel's Monte
//!   Carlo error from the spread of its samples;
//! * **renders at ±1 σ**, for any other input (a diameter, an index, which
//!   change the phase functions): the scene rendered twice with the
//!   nominal's seed and samples (common random numbers), Δ's error from the
//!   renders' two independent halves (per pixel (Δ_even − Δ_odd)²/4, the
//!   shared noise cancelling as it does in Δ) for a region, conservatively
//!   from the two renders' variances added for a pixel.
//!
//! The band is given for each region's mean radiance per band R, G, B (the
//! object's pixels, the board's: [`Image::region`]), beside the nominal
//! mean's own Monte Carlo standard error, and for every pixel, in the units
//! of the environment map.
//!
//! ```
//! use lucent::optics::uncertainty::InputSd;
//! use lucent::scene::band::{render_band, EffectEstimate};
//! use lucent_render::tracer::Image;
//! // A one-pixel "object" whose mean rises from 0.9 to 1.1 between −1 σ and +1 σ.
//! let image = |v: f64| Image {
//!     width: 1, height: 1, mean: vec![[v; 3]], variance_of_mean: vec![[1e-6; 3]],
//!     samples: vec![4], object_samples: vec![4], board_samples: vec![0],
//!     halves: [vec![[v; 3]], vec![[v; 3]]], derivatives: Vec::new(),
//! };
//! let input = InputSd { key: "particles[0].weight_percent".into(), nominal: 0.65, sd: 0.0325 };
//! let (plus, minus) = (image(1.1), image(0.9));
//! let band = render_band(&image(1.0), &[input], &[EffectEstimate::Renders { plus: &plus, minus: &minus, spp: 4 }]);
//! assert!((band.regions[0].inputs_sd[1] - 0.1).abs() < 1e-12);
//! ```

use crate::optics::uncertainty::{first_order, InputSd};
use lucent_render::tracer::{Image, Region};
use serde::Serialize;
use std::path::{Path, PathBuf};

/// How an input's effect Δ (+1 σ minus −1 σ) on the image is estimated.
#[derive(Debug, Clone, Copy)]
pub enum EffectEstimate<'a> {
    /// 2 σ ∂L/∂θ from the nominal render's own paths: its
    /// [`Image::derivatives`] entry `index`, made per 1 σ; `left_out`: the
    /// largest relative change of the phase functions and indices between
    /// ±1 σ, which the derivative does not carry
    /// ([`lucent_render::tracer::Object::coefficient_derivative`]).
    PathDerivative { index: usize, left_out: f64 },
    /// The renders at +1 σ and −1 σ, of `spp` samples per pixel with the nominal's seed.
    Renders { plus: &'a Image, minus: &'a Image, spp: u32 },
}

impl EffectEstimate<'_> {
    /// The name written to uncertainty.json.
    pub fn method(&self) -> &'static str {
        match self {
            EffectEstimate::PathDerivative { .. } => "path derivative",
            EffectEstimate::Renders { .. } => "renders at ±1 σ",
        }
    }

    /// Δ at pixel p per band, its variance for a region's mean (whose
    /// terms add over pixels) and a conservative variance for the pixel alone.
    fn at(&self, nominal: &Image, p: usize) -> ([f64; 3], [f64; 3], [f64; 3]) {
        match *self {
            EffectEstimate::PathDerivative { index, .. } => {
                let d = &nominal.derivatives[index];
                let var = d.variance_of_mean[p].map(|v| 4.0 * v);
                (d.mean[p].map(|v| 2.0 * v), var, var)
            }
            EffectEstimate::Renders { plus, minus, .. } => (
                std::array::from_fn(|c| plus.mean[p][c] - minus.mean[p][c]),
                std::array::from_fn(|c| {
                    let even = plus.halves[0][p][c] - minus.halves[0][p][c];
                    let odd = plus.halves[1][p][c] - minus.halves[1][p][c];
                    0.25 * (even - odd).powi(2)
                }),
                std::array::from_fn(|c| plus.variance_of_mean[p][c] + minus.variance_of_mean[p][c]),
            ),
        }
    }
}

/// How one input's effect was estimated.
#[derive(Debug, Clone, Serialize)]
pub struct InputMethod {
    pub key: String,
    /// [`EffectEstimate::method`].
    pub method: &'static str,
    /// For a path derivative, the largest relative change of the phase
    /// functions and indices between ±1 σ that it leaves out.
    pub left_out_relative_change: Option<f64>,
}

/// What one input does to a region's mean.
#[derive(Debug, Clone, Serialize)]
pub struct RegionEffect {
    pub key: String,
    /// [`EffectEstimate::method`].
    pub method: &'static str,
    /// Mean at +1 σ minus at −1 σ per band R, G, B, and its Monte Carlo standard error.
    pub difference: [f64; 3],
    pub difference_std_error: [f64; 3],
    /// Its share of the region's variance from the inputs, per band (0 … 1).
    pub share_of_variance: [f64; 3],
}

/// A region's mean and its bands.
#[derive(Debug, Clone, Serialize)]
pub struct RegionBand {
    /// "object" or "board" ([`Image::region`] of the nominal render).
    pub region: &'static str,
    pub pixels: usize,
    /// The nominal render's mean over the region per band R, G, B, and its Monte Carlo standard error.
    pub mean: [f64; 3],
    pub mean_std_error: [f64; 3],
    /// The mean's standard deviation from the inputs (first order), its
    /// Monte Carlo standard error, and relative to the mean.
    pub inputs_sd: [f64; 3],
    pub inputs_sd_std_error: [f64; 3],
    pub inputs_relative_sd: [f64; 3],
    pub inputs: Vec<RegionEffect>,
}

/// The files of a render's band (`lucent render --uncertainty`) beside its
/// [`super::RenderFiles`], each name spelled here once: the [`RenderBand`]
/// (`json`), the per-pixel band (`exr`) and its picture over the object
/// (`png`). Written by `lucent render`, read by `lucent compare --band` and
/// `lucent run`'s planning.
///
/// ```
/// use lucent::scene::band::RenderBandFiles;
/// let f = RenderBandFiles::in_dir(std::path::Path::new("out/render/s1"));
/// assert_eq!(f.json, std::path::Path::new("out/render/s1/uncertainty.json"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RenderBandFiles {
    pub json: PathBuf,
    pub exr: PathBuf,
    pub png: PathBuf,
}

impl RenderBandFiles {
    /// The file names.
    pub const NAMES: [&'static str; 3] = ["uncertainty.json", "band.exr", "band.png"];

    /// The band files of the render whose output folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [json, exr, png] = Self::NAMES.map(|n| dir.join(n));
        Self { json, exr, png }
    }
}

/// The render's band, written as `uncertainty.json` (the per-pixel arrays go to `band.exr`).
#[derive(Debug, Clone, Serialize)]
pub struct RenderBand {
    pub method: &'static str,
    pub inputs: Vec<InputSd>,
    /// Per input, how its effect was estimated.
    pub input_methods: Vec<InputMethod>,
    /// Samples per pixel of each render at ±1 σ (the nominal render's are
    /// in render.json); `None` where every input's effect came from the
    /// nominal render's paths.
    pub spp_per_input_render: Option<u32>,
    pub regions: Vec<RegionBand>,
    /// Per pixel and band, the standard deviation from the inputs and its (conservative) Monte Carlo error.
    #[serde(skip)]
    pub pixel_sd: Vec<[f64; 3]>,
    #[serde(skip)]
    pub pixel_sd_std_error: Vec<[f64; 3]>,
}

/// The band of `nominal` from each input's effect, `effects[i]` for `inputs[i]`.
pub fn render_band(nominal: &Image, inputs: &[InputSd], effects: &[EffectEstimate]) -> RenderBand {
    let n = nominal.mean.len();
    let mut regions = Vec::new();
    for (name, which) in [("object", Region::Object), ("board", Region::Board)] {
        let pixels: Vec<usize> = (0..n).filter(|&p| nominal.region(p) == which).collect();
        if pixels.is_empty() {
            continue;
        }
        let count = pixels.len() as f64;
        let mut mean = [0.0; 3];
        let mut mean_var = [0.0; 3];
        for &p in &pixels {
            for c in 0..3 {
                mean[c] += nominal.mean[p][c] / count;
                mean_var[c] += nominal.variance_of_mean[p][c] / (count * count);
            }
        }
        let per_input: Vec<([f64; 3], [f64; 3])> = effects
            .iter()
            .map(|e| {
                let (mut d, mut var) = ([0.0; 3], [0.0; 3]);
                for &p in &pixels {
                    let (dp, vp, _) = e.at(nominal, p);
                    for c in 0..3 {
                        d[c] += dp[c] / count;
                        var[c] += vp[c] / (count * count);
                    }
                }
                (d, var.map(f64::sqrt))
            })
            .collect();
        let mut band = RegionBand {
            region: name,
            pixels: pixels.len(),
            mean,
            mean_std_error: mean_var.map(f64::sqrt),
            inputs_sd: [0.0; 3],
            inputs_sd_std_error: [0.0; 3],
            inputs_relative_sd: [0.0; 3],
            inputs: inputs
                .iter()
                .zip(&per_input)
                .zip(effects)
                .map(|((i, (d, se)), e)| RegionEffect {
                    key: i.key.clone(),
                    method: e.method(),
                    difference: *d,
                    difference_std_error: *se,
                    share_of_variance: [0.0; 3],
                })
                .collect(),
        };
        for c in 0..3 {
            let fo = first_order(
                &per_input.iter().map(|(d, _)| vec![d[c]]).collect::<Vec<_>>(),
                &per_input.iter().map(|(_, se)| vec![se[c]]).collect::<Vec<_>>(),
            );
            band.inputs_sd[c] = fo.sd[0];
            band.inputs_sd_std_error[c] = fo.sd_std_error[0];
            band.inputs_relative_sd[c] = if mean[c] > 0.0 { fo.sd[0] / mean[c] } else { f64::NAN };
            for (e, share) in band.inputs.iter_mut().zip(&fo.shares) {
                e.share_of_variance[c] = share[0];
            }
        }
        regions.push(band);
    }
    // Per pixel: the outputs are the 3n values, pixel-major.
    let flat = |f: &dyn Fn(usize, usize) -> f64| -> Vec<f64> { (0..3 * n).map(|k| f(k / 3, k % 3)).collect() };
    let differences: Vec<Vec<f64>> = effects.iter().map(|e| flat(&|p, c| e.at(nominal, p).0[c])).collect();
    let errors: Vec<Vec<f64>> = effects.iter().map(|e| flat(&|p, c| e.at(nominal, p).2[c].sqrt())).collect();
    let fo = first_order(&differences, &errors);
    let triples = |v: &[f64]| -> Vec<[f64; 3]> { v.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect() };
    RenderBand {
        method: "first order (GUM): u² = Σ (Δ/2)², per input Δ (+1 σ minus −1 σ) from the nominal render's own paths (path derivative, 2σ ∂L/∂θ) or from the scene rendered at +1 σ and −1 σ with the same seed and samples",
        inputs: inputs.to_vec(),
        input_methods: inputs
            .iter()
            .zip(effects)
            .map(|(i, e)| InputMethod {
                key: i.key.clone(),
                method: e.method(),
                left_out_relative_change: match e {
                    EffectEstimate::PathDerivative { left_out, .. } => Some(*left_out),
                    EffectEstimate::Renders { .. } => None,
                },
            })
            .collect(),
        spp_per_input_render: effects.iter().find_map(|e| match e {
            EffectEstimate::Renders { spp, .. } => Some(*spp),
            EffectEstimate::PathDerivative { .. } => None,
        }),
        regions,
        pixel_sd: triples(&fo.sd),
        pixel_sd_std_error: triples(&fo.sd_std_error),
    }
}

impl RenderBand {
    /// One line per region for the terminal.
    pub fn lines(&self) -> Vec<String> {
        self.regions
            .iter()
            .map(|r| {
                let pct = |v: [f64; 3]| v.map(|x| format!("{:.2}", 100.0 * x)).join("/");
                let rel = |v: [f64; 3]| std::array::from_fn::<f64, 3, _>(|c| v[c] / r.mean[c]);
                format!(
                    "{} mean ({} px), R/G/B: ±{} % from the inputs (Monte Carlo error of that band ±{} %), ±{} % Monte Carlo",
                    r.region,
                    r.pixels,
                    pct(r.inputs_relative_sd),
                    pct(rel(r.inputs_sd_std_error)),
                    pct(rel(r.mean_std_error)),
                )
            })
            .collect()
    }
}
