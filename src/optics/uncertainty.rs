//! Uncertainty of the bulk optical properties propagated from the recipe's
//! uncertain inputs (`lucent optics --uncertainty N`, docs/method.md#optics-uncertainty).
//!
//! A recipe may give weight percentages, diameters and real indices with an
//! uncertainty (`weight_percent = { value = 0.65, sd = 0.02 }`, normal;
//! `diameter_um = { min = 2.0, max = 2.4 }`, uniform; see
//! [`super::recipe`]). N samples of all uncertain inputs are drawn by Latin
//! hypercube sampling (McKay, Beckman & Conover 1979: each input's range
//! cut into N strata of equal probability, one draw per stratum, strata
//! paired across inputs by independent random permutations; normal inputs
//! through the inverse normal CDF, Acklam's rational approximation,
//! relative error < 1.2e-9), seeded; for each sample the bulk properties
//! are computed ([`super::bulk`], no phase table), and per wavelength the
//! mean, the sample standard deviation and the 95 % interval (2.5th and
//! 97.5th percentiles, linear interpolation between order statistics) of
//! μ_s, μ_a [1/m], g and n_bulk are reported.
//!
//! ```no_run
//! use lucent::optics::{recipe::{Recipe, Overrides}, uncertainty};
//! use lucent_colour::WavelengthGrid;
//! let r = Recipe::load("uncertain.toml".as_ref(), Overrides::default()).unwrap();
//! let u = uncertainty::propagate(&r, &WavelengthGrid::from_list(vec![550.0]).unwrap(), 200, 1).unwrap();
//! println!("μs = {} ± {} /m", u.mu_s_per_m.mean[0], u.mu_s_per_m.sd[0]);
//! ```

use super::bulk::{self, OpticsError};
use super::recipe::{InputDistribution, Recipe, RecipeError};
use lucent_colour::WavelengthGrid;
use lucent_render::rng::Rng;
use rayon::prelude::*;
use serde::Serialize;

/// Why the propagation could not be made.
#[derive(Debug, thiserror::Error)]
pub enum UncertaintyError {
    #[error(
        "{}: the recipe gives no input with an uncertainty (e.g. weight_percent = {{ value = 0.65, sd = 0.02 }})",
        recipe.display()
    )]
    NoUncertainInputs { recipe: std::path::PathBuf },
    #[error("--uncertainty {0}: at least 10 samples are needed")]
    TooFewSamples(usize),
    #[error("sample {sample}: {source}")]
    Recipe { sample: usize, source: RecipeError },
    #[error("sample {sample}: {source}")]
    Optics { sample: usize, source: OpticsError },
}

/// Statistics of one property per wavelength.
#[derive(Debug, Clone, Serialize)]
pub struct Band {
    pub mean: Vec<f64>,
    pub sd: Vec<f64>,
    pub p2_5: Vec<f64>,
    pub p97_5: Vec<f64>,
}

/// The files of an optics uncertainty study of one sample in its folder,
/// each name spelled here once: the bands per wavelength as a table (`csv`),
/// the [`Uncertainty`] (`json`) and their plot (`png`). Written by `lucent
/// optics --uncertainty`.
///
/// ```
/// use lucent::optics::uncertainty::UncertaintyFiles;
/// let f = UncertaintyFiles::in_dir(std::path::Path::new("out/s1"));
/// assert_eq!(f.json, std::path::Path::new("out/s1/uncertainty.json"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UncertaintyFiles {
    pub csv: std::path::PathBuf,
    pub json: std::path::PathBuf,
    pub png: std::path::PathBuf,
}

impl UncertaintyFiles {
    /// The file names.
    pub const NAMES: [&'static str; 3] = ["uncertainty.csv", "uncertainty.json", "uncertainty.png"];

    /// The files of the sample folder `dir`.
    pub fn in_dir(dir: &std::path::Path) -> Self {
        let [csv, json, png] = Self::NAMES.map(|n| dir.join(n));
        Self { csv, json, png }
    }
}

/// The result of a propagation.
#[derive(Debug, Clone, Serialize)]
pub struct Uncertainty {
    pub sample: String,
    pub samples: usize,
    pub seed: u64,
    pub method: &'static str,
    pub inputs: Vec<super::recipe::UncertainInput>,
    pub wavelength_nm: Vec<f64>,
    pub mu_s_per_m: Band,
    pub mu_a_per_m: Band,
    pub g: Band,
    pub n_bulk: Band,
    /// The input values of every sample (rows), in the order of `inputs`.
    pub draws: Vec<Vec<f64>>,
}

/// Inverse of the standard normal CDF (Acklam 2003; the coefficients as
/// published).
#[allow(clippy::excessive_precision)]
pub fn inverse_normal(p: f64) -> f64 {
    const A: [f64; 6] = [
        -3.969683028665376e1,
        2.209460984245205e2,
        -2.759285104469687e2,
        1.383577518672690e2,
        -3.066479806614716e1,
        2.506628277459239,
    ];
    const B: [f64; 5] =
        [-5.447609879822406e1, 1.615858368580409e2, -1.556989798598866e2, 6.680131188771972e1, -1.328068155288572e1];
    const C: [f64; 6] = [
        -7.784894002430293e-3,
        -3.223964580411365e-1,
        -2.400758277161838,
        -2.549732539343734,
        4.374664141464968,
        2.938163982698783,
    ];
    const D: [f64; 4] = [7.784695709041462e-3, 3.224671290700398e-1, 2.445134137142996, 3.754408661907416];
    let p_low = 0.02425;
    if p < p_low {
        let q = (-2.0 * p.ln()).sqrt();
        (((((C[0] * q + C[1]) * q + C[2]) * q + C[3]) * q + C[4]) * q + C[5])
            / ((((D[0] * q + D[1]) * q + D[2]) * q + D[3]) * q + 1.0)
    } else if p <= 1.0 - p_low {
        let q = p - 0.5;
        let r = q * q;
        (((((A[0] * r + A[1]) * r + A[2]) * r + A[3]) * r + A[4]) * r + A[5]) * q
            / (((((B[0] * r + B[1]) * r + B[2]) * r + B[3]) * r + B[4]) * r + 1.0)
    } else {
        -inverse_normal(1.0 - p)
    }
}

/// Latin hypercube: `n` points in [0, 1)^`dims`, one per stratum in every
/// dimension.
pub fn latin_hypercube(n: usize, dims: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = Rng::new(seed, 0x1a7_1f5e);
    let mut points = vec![vec![0.0; dims]; n];
    for d in 0..dims {
        let mut perm: Vec<usize> = (0..n).collect();
        for i in (1..n).rev() {
            let j = ((rng.next_f64() * (i + 1) as f64) as usize).min(i);
            perm.swap(i, j);
        }
        for (point, stratum) in points.iter_mut().zip(perm) {
            point[d] = (stratum as f64 + rng.next_f64()) / n as f64;
        }
    }
    points
}

/// The whole Latin-hypercube design of a run: the input values of draws
/// 0 … n−1 (rows, in the order of `recipe.uncertain`). It depends only on
/// the recipe's uncertain inputs, `n` and `seed`, so every shard of a run
/// makes the same design and evaluates its own rows of it.
pub fn design(recipe: &Recipe, n: usize, seed: u64) -> Result<Vec<Vec<f64>>, UncertaintyError> {
    if recipe.uncertain.is_empty() {
        return Err(UncertaintyError::NoUncertainInputs { recipe: recipe.path.clone() });
    }
    if n < 10 {
        return Err(UncertaintyError::TooFewSamples(n));
    }
    let inputs = &recipe.uncertain;
    Ok(latin_hypercube(n, inputs.len(), seed)
        .into_iter()
        .map(|u| {
            u.iter()
                .zip(inputs)
                .map(|(u, input)| match input.distribution {
                    InputDistribution::Normal { sd } => {
                        input.nominal + sd * inverse_normal(u.clamp(1e-12, 1.0 - 1e-12))
                    }
                    InputDistribution::Uniform { min, max } => min + (max - min) * u,
                })
                .collect()
        })
        .collect())
}

/// The bulk properties of some draws of a design: for each property
/// ([`Draws::PROPERTIES`]) the values of draw after draw, `wavelengths`
/// values per draw (draw-major). Each draw's values depend on its input
/// values only, so the draws of a run can be evaluated in any grouping
/// (the shards of `lucent optics --uncertainty N --shard K/N`) and put
/// together by [`Draws::append`].
#[derive(Debug, Clone, PartialEq)]
pub struct Draws {
    /// The draws' indices in the design.
    pub range: std::ops::Range<usize>,
    pub wavelengths: usize,
    /// μs [1/m], μa [1/m], g, n_bulk.
    pub values: [Vec<f64>; 4],
}

impl Draws {
    /// The names of `values`, as in [`Uncertainty`] and its CSV.
    pub const PROPERTIES: [&str; 4] = ["mu_s_per_m", "mu_a_per_m", "g", "n_bulk"];

    /// No draws, starting at draw `start`.
    pub fn empty(start: usize, wavelengths: usize) -> Self {
        Self { range: start..start, wavelengths, values: Default::default() }
    }

    /// `next` (the draws right after these) appended.
    pub fn append(&mut self, next: &Draws) -> Result<(), String> {
        if next.range.start != self.range.end || next.wavelengths != self.wavelengths {
            return Err(format!(
                "draws {:?} of {} wavelengths do not continue draws {:?} of {}",
                next.range, next.wavelengths, self.range, self.wavelengths
            ));
        }
        for (a, b) in self.values.iter_mut().zip(&next.values) {
            a.extend_from_slice(b);
        }
        self.range.end = next.range.end;
        Ok(())
    }
}

/// The bulk properties on `grid` of draws `range` of `design` ([`design`]).
pub fn evaluate(
    recipe: &Recipe,
    grid: &WavelengthGrid,
    design: &[Vec<f64>],
    range: std::ops::Range<usize>,
) -> Result<Draws, UncertaintyError> {
    let inputs = &recipe.uncertain;
    let options = bulk::Options { phase_entries: 0, ..bulk::Options::default() };
    let spectra: Vec<bulk::OpticalSpectrum> = design[range.clone()]
        .par_iter()
        .zip(range.clone())
        .map(|(values, k)| {
            let mut r = recipe.clone();
            for (input, v) in inputs.iter().zip(values) {
                r = r.with_input(input.target, *v).map_err(|source| UncertaintyError::Recipe { sample: k, source })?;
            }
            bulk::compute(&r, grid, &options).map_err(|source| UncertaintyError::Optics { sample: k, source })
        })
        .collect::<Result<_, _>>()?;
    let column = |f: &dyn Fn(&bulk::OpticalSpectrum) -> &Vec<f64>| -> Vec<f64> {
        spectra.iter().flat_map(|s| f(s).iter().copied()).collect()
    };
    Ok(Draws {
        range,
        wavelengths: grid.len(),
        values: [column(&|s| &s.mu_s_per_m), column(&|s| &s.mu_a_per_m), column(&|s| &s.g), column(&|s| &s.n_bulk)],
    })
}

/// The statistics of all draws 0 … n−1 of `design` (evaluated in
/// `draws`): the same numbers however the draws were grouped.
pub fn summarise(
    recipe: &Recipe,
    grid: &WavelengthGrid,
    seed: u64,
    design: Vec<Vec<f64>>,
    draws: &Draws,
) -> Uncertainty {
    let n = design.len();
    assert_eq!(draws.range, 0..n, "summarise needs every draw of the design");
    let w = grid.len();
    let band = |values: &[f64]| -> Band {
        let mut b = Band { mean: vec![0.0; w], sd: vec![0.0; w], p2_5: vec![0.0; w], p97_5: vec![0.0; w] };
        for i in 0..w {
            let mut v: Vec<f64> = (0..n).map(|d| values[d * w + i]).collect();
            let m = v.iter().sum::<f64>() / n as f64;
            b.mean[i] = m;
            b.sd[i] = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
            v.sort_by(f64::total_cmp);
            b.p2_5[i] = quantile(&v, 0.025);
            b.p97_5[i] = quantile(&v, 0.975);
        }
        b
    };
    let [mu_s, mu_a, g, n_bulk] = &draws.values;
    Uncertainty {
        sample: recipe.name.clone(),
        samples: n,
        seed,
        method: "Latin hypercube over the uncertain inputs (normal: inverse CDF; uniform), bulk properties per sample",
        inputs: recipe.uncertain.clone(),
        wavelength_nm: grid.wavelengths_nm().to_vec(),
        mu_s_per_m: band(mu_s),
        mu_a_per_m: band(mu_a),
        g: band(g),
        n_bulk: band(n_bulk),
        draws: design,
    }
}

/// Propagates the recipe's uncertain inputs to its bulk properties on `grid`
/// with `n` Latin-hypercube samples: [`design`], [`evaluate`] of every
/// draw, [`summarise`].
pub fn propagate(recipe: &Recipe, grid: &WavelengthGrid, n: usize, seed: u64) -> Result<Uncertainty, UncertaintyError> {
    let design = design(recipe, n, seed)?;
    let draws = evaluate(recipe, grid, &design, 0..n)?;
    Ok(summarise(recipe, grid, seed, design, &draws))
}

/// One uncertain input as a band reports it: its recipe key, nominal value
/// and standard deviation (in the key's units).
#[derive(Debug, Clone, Serialize)]
pub struct InputSd {
    pub key: String,
    pub nominal: f64,
    pub sd: f64,
}

impl InputSd {
    /// The recipe's uncertain inputs, each with [`standard_deviation`].
    pub fn of(recipe: &Recipe) -> Vec<InputSd> {
        recipe
            .uncertain
            .iter()
            .map(|i| InputSd { key: i.key.clone(), nominal: i.nominal, sd: standard_deviation(&i.distribution) })
            .collect()
    }
}

/// The standard deviation of an uncertain input, in its own units: the
/// `sd` of a normal one, (max − min)/√12 of a uniform one.
pub fn standard_deviation(d: &InputDistribution) -> f64 {
    match *d {
        InputDistribution::Normal { sd } => sd,
        InputDistribution::Uniform { min, max } => (max - min) / 12f64.sqrt(),
    }
}

/// A model output's first-order uncertainty from independent inputs
/// ([`first_order`]).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FirstOrder {
    /// Per output: the standard deviation the inputs give it,
    /// √(Σᵢ (Δᵢ/2)²) with Δᵢ = f(xᵢ + σᵢ) − f(xᵢ − σᵢ).
    pub sd: Vec<f64>,
    /// Per output: the Monte Carlo standard error of `sd`, from the
    /// standard errors of the Δᵢ (delta method).
    pub sd_std_error: Vec<f64>,
    /// Per output and input (input-major): the share of the variance,
    /// (Δᵢ/2)²/Σⱼ(Δⱼ/2)² (0 where the variance is 0).
    pub shares: Vec<Vec<f64>>,
}

/// First-order propagation of independent input uncertainties (the law of
/// propagation of uncertainty, JCGM 100:2008 "GUM", eq. 10) by central
/// differences at ±1 σ: `differences[i][k]` = f_k(x + σᵢ eᵢ) − f_k(x −
/// σᵢ eᵢ) for input i and output k, `std_errors[i][k]` its Monte Carlo
/// standard error (small when the two runs share their random numbers).
/// The sensitivity cᵢ = ∂f/∂xᵢ ≈ Δᵢ/(2σᵢ), so cᵢσᵢ = Δᵢ/2 and
/// u(f)² = Σᵢ (Δᵢ/2)². Exact for an f linear over x ± σ; the brute-force
/// sampling of [`propagate`] checks it where it is not.
///
/// ```
/// use lucent::optics::uncertainty::first_order;
/// // f = 3x + y², x ± 0.1, y = 1 ± 0.2: Δx = 0.6, Δy = (1.2² − 0.8²) = 0.8.
/// let fo = first_order(&[vec![0.6], vec![0.8]], &[vec![0.0], vec![0.0]]);
/// assert!((fo.sd[0] - (0.3f64.powi(2) + 0.4f64.powi(2)).sqrt()).abs() < 1e-12);
/// ```
pub fn first_order(differences: &[Vec<f64>], std_errors: &[Vec<f64>]) -> FirstOrder {
    let outputs = differences.first().map_or(0, Vec::len);
    let mut sd = vec![0.0; outputs];
    let mut sd_std_error = vec![0.0; outputs];
    let mut shares = vec![vec![0.0; outputs]; differences.len()];
    for k in 0..outputs {
        let var: f64 = differences.iter().map(|d| (0.5 * d[k]).powi(2)).sum();
        sd[k] = var.sqrt();
        if var > 0.0 {
            // ∂sd/∂(Δᵢ/2) = (Δᵢ/2)/sd; the Δᵢ of different inputs come from different runs.
            sd_std_error[k] = differences
                .iter()
                .zip(std_errors)
                .map(|(d, e)| (0.5 * d[k] / sd[k] * 0.5 * e[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            for (i, d) in differences.iter().enumerate() {
                shares[i][k] = (0.5 * d[k]).powi(2) / var;
            }
        }
    }
    FirstOrder { sd, sd_std_error, shares }
}

/// Quantile of sorted values, linear between order statistics (type 7).
fn quantile(sorted: &[f64], q: f64) -> f64 {
    let h = (sorted.len() - 1) as f64 * q;
    let (i, f) = (h.floor() as usize, h - h.floor());
    if i + 1 < sorted.len() {
        sorted[i] + f * (sorted[i + 1] - sorted[i])
    } else {
        sorted[i]
    }
}

/// CSV: wavelength and, per property, mean, sd, p2.5, p97.5.
pub fn to_csv(u: &Uncertainty) -> Result<String, csv::Error> {
    let mut header = vec!["wavelength_nm".to_string()];
    for p in ["mu_s_per_m", "mu_a_per_m", "g", "n_bulk"] {
        for stat in ["mean", "sd", "p2_5", "p97_5"] {
            header.push(format!("{p}_{stat}"));
        }
    }
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let rows = u.wavelength_nm.iter().enumerate().map(|(i, w)| {
        let mut row = vec![w.to_string()];
        for b in [&u.mu_s_per_m, &u.mu_a_per_m, &u.g, &u.n_bulk] {
            row.extend([b.mean[i], b.sd[i], b.p2_5[i], b.p97_5[i]].map(|v| format!("{v:.8e}")));
        }
        row
    });
    crate::io::csv_text(&header, rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_normal_matches_known_quantiles() {
        for (p, z) in [(0.5, 0.0), (0.975, 1.959963984540054), (0.01, -2.326347874040841), (0.8413447460685429, 1.0)] {
            assert!((inverse_normal(p) - z).abs() < 1e-8, "{p}: {}", inverse_normal(p));
        }
    }

    #[test]
    fn draws_evaluated_in_groups_summarise_bit_for_bit_as_all_at_once() {
        use super::super::recipe::Overrides;
        let text = include_str!("../../fixtures/samples/IOL1068-09.toml")
            .replace("weight_percent = 0.65", "weight_percent = { value = 0.65, sd = 0.02 }");
        let r = Recipe::parse(&text, std::path::Path::new("u.toml"), Overrides::default()).unwrap();
        let grid = WavelengthGrid::from_list(vec![450.0, 650.0]).unwrap();
        let whole = propagate(&r, &grid, 23, 5).unwrap();
        let design = design(&r, 23, 5).unwrap();
        let mut all = Draws::empty(0, grid.len());
        for k in 0..4 {
            let range = crate::shard::range(23, k, 4);
            let part = evaluate(&r, &grid, &design, range.start as usize..range.end as usize).unwrap();
            all.append(&part).unwrap();
        }
        // Not contiguous: refused.
        assert!(all.clone().append(&Draws::empty(3, grid.len())).is_err());
        let grouped = summarise(&r, &grid, 5, design, &all);
        let bits = |u: &Uncertainty| serde_json::to_string(u).unwrap();
        assert_eq!(bits(&whole), bits(&grouped));
    }

    #[test]
    fn latin_hypercube_has_one_point_per_stratum() {
        let pts = latin_hypercube(50, 3, 7);
        for d in 0..3 {
            let mut strata: Vec<usize> = pts.iter().map(|p| (p[d] * 50.0) as usize).collect();
            strata.sort();
            assert_eq!(strata, (0..50).collect::<Vec<_>>());
        }
    }
}
