//! Bulk optical properties of a recipe: μ_s, μ_a, μ_t [1/m], g, the
//! effective refractive index and a tabulated phase function per wavelength
//! (docs/method.md#optics).
//!
//! # Model
//!
//! For each particle type with volume fraction φ and size distribution N(r)
//! normalised so that (4π/3)∫ r³ N(r) dr = φ, with the cross sections of
//! [`super::mie::Coefficients::cross_sections`] (Frisvad et al. 2007, C_s
//! including the attenuation factor F(α), α = 4π r κ_h/λ, of an absorbing
//! host):
//!
//! * μ_s = Σ_types ∫ C_s(r) N(r) dr;
//! * absorption, by the recipe's [`AbsorptionModel`] (κ after the recipe's
//!   overrides of the imaginary part):
//!
//!   | model | μ_a |
//!   |---|---|
//!   | `mie` | Σ ∫ C_t N dr + (1 − Σφ) 4πκ_h/λ − μ_s |
//!   | `volume-weighted` | (1 − Σφ) 4πκ_h/λ + Σ φ_i 4πκ_i/λ |
//!   | `volume-weighted-full-host` (the lab's formula) | 4πκ_h/λ + Σ φ_i 4πκ_i/λ |
//!
//!   and μ_t = μ_s + μ_a. A negative `mie` μ_a (possible only when
//!   non-absorbing particles displace an absorbing host: C_t already counts
//!   the displaced host absorption, see [`super::mie`]) is set to 0 with a
//!   warning, so μ_a is never negative;
//! * g = Σ ∫ g(r) C_s N dr / μ_s (μ_s-weighted mean);
//! * phase function p(θ) = λ²/(8π²|n_h|² μ_s) Σ ∫ N F(α(r)) (|S₁|² + |S₂|²) dr,
//!   which is the μ_s-weighted mean of the per-sphere p = (|S₁|²+|S₂|²) /
//!   (4π Σ(2n+1)(|a_n|²+|b_n|²)); tabulated at N angles uniform in θ from 0
//!   to π (default 4096), per steradian; divided by its own integral (linear
//!   in cos θ between nodes, the form the renderer samples) so that it
//!   integrates to exactly 1 — the correction is below 1e-3 for the shipped
//!   samples at 4096 entries, and is reported;
//! * effective index (van de Hulst 1957, §4.3, with the forward amplitude
//!   S(0) = ½ Σ(2n+1)(a_n+b_n) and k₀ = 2π/λ):
//!   n_eff = n_h + i (2π/k₀³) Σ ∫ N S(0)/n_h² dr, and n_bulk = Re n_eff.
//!   Its imaginary part is consistent with extinction: 2k₀ Im n_eff equals the
//!   particles' μ_t. For a real host this is van de Hulst's
//!   m = 1 + i 2π N S(0)/k³ relative to the host.
//!
//! Distributions are integrated by composite 8-point Gauss–Legendre
//! quadrature (in r for a uniform range, in ln r over median·e^{±(6σ + 3σ²)}
//! for a log-normal), doubling the panel count until μ_s changes by less than
//! 1e-6 relative. The phase function uses the same nodes.
//!
//! Wavelengths are in nanometres, lengths in metres.
//!
//! ```no_run
//! use lucent::optics::{bulk, recipe::{Recipe, Overrides}};
//! use lucent_colour::WavelengthGrid;
//! let r = Recipe::load("fixtures/samples/IOL1068-09.toml".as_ref(), Overrides::default()).unwrap();
//! let s = bulk::compute(&r, &WavelengthGrid::visible(), &bulk::Options::default()).unwrap();
//! println!("μ_s(550 nm) = {} /m", s.mu_s_per_m[17]);
//! ```

use super::index::{Extrapolation, IndexError};
use super::mie::{Coefficients, MieError};
use super::recipe::{AbsorptionModel, Medium, Recipe, SizeDistribution};
use lucent_colour::WavelengthGrid;
use num_complex::Complex64;
use rayon::prelude::*;
use std::f64::consts::PI;

/// Why bulk properties could not be computed.
#[derive(Debug, thiserror::Error)]
pub enum OpticsError {
    #[error("{recipe}: {medium} index at {wavelength_nm} nm: {source}")]
    /// The sources are boxed (here and in `Mie`): an [`IndexError`] is
    /// large, and this error travels through every `Result` of the
    /// computation and into callers' error types.
    Index { recipe: String, medium: String, wavelength_nm: f64, source: Box<IndexError> },
    #[error("{recipe}: {medium} at {wavelength_nm} nm: {source}")]
    Mie { recipe: String, medium: String, wavelength_nm: f64, source: Box<MieError> },
    #[error("{recipe}: size integral for {medium} at {wavelength_nm} nm did not converge to {tolerance} (last change {change:e})")]
    NotConverged { recipe: String, medium: String, wavelength_nm: f64, tolerance: f64, change: f64 },
    #[error("phase table needs at least 2 entries, got {0}")]
    PhaseEntries(usize),
}

/// Computation options.
#[derive(Debug, Clone)]
pub struct Options {
    /// Entries of the phase table (uniform in θ over [0, π]); 0 = no table.
    pub phase_entries: usize,
    /// Relative convergence tolerance of μ_s for size distributions.
    pub size_tolerance: f64,
}

impl Default for Options {
    fn default() -> Self {
        Self { phase_entries: 4096, size_tolerance: 1e-6 }
    }
}

/// Bulk properties at one wavelength.
#[derive(Debug, Clone)]
pub struct Sample {
    pub wavelength_nm: f64,
    pub mu_s_per_m: f64,
    pub mu_a_per_m: f64,
    pub mu_t_per_m: f64,
    pub g: f64,
    pub n_bulk: f64,
    /// Phase function per steradian at θ_i = iπ/(N−1); empty when no table
    /// was requested. Normalised so that, linear in cos θ between nodes (the
    /// representation the renderer samples), it integrates to exactly 1.
    pub phase: Vec<f64>,
    /// ∫ p dΩ of the table as computed from the Lorenz–Mie normalisation,
    /// before the exact normalisation (1 up to the table's resolution).
    pub phase_integral_before_normalisation: f64,
    pub warnings: Vec<String>,
}

/// Bulk properties of one recipe over a wavelength grid; arrays over
/// wavelength (serialised with exactly these field names).
#[derive(Debug, Clone, serde::Serialize)]
pub struct OpticalSpectrum {
    pub sample: String,
    /// The absorption model μ_a was computed with (its recipe name).
    #[serde(serialize_with = "model_name")]
    pub absorption: AbsorptionModel,
    /// The recipe's corrections of the index data ([`Recipe::corrections`]).
    pub corrections: Vec<String>,
    pub wavelength_nm: Vec<f64>,
    pub mu_s_per_m: Vec<f64>,
    pub mu_a_per_m: Vec<f64>,
    pub mu_t_per_m: Vec<f64>,
    pub g: Vec<f64>,
    pub n_bulk: Vec<f64>,
    /// Phase tables per wavelength (not serialised with the spectrum; they
    /// are written to their own CSV).
    #[serde(skip)]
    pub phase: Vec<Vec<f64>>,
    /// Per wavelength, the table's integral before exact normalisation.
    #[serde(skip)]
    pub phase_integral_before_normalisation: Vec<f64>,
    pub warnings: Vec<String>,
}

fn model_name<S: serde::Serializer>(model: &AbsorptionModel, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(model.name())
}

/// Computes the bulk properties of `recipe` on `grid`, wavelengths in
/// parallel.
pub fn compute(recipe: &Recipe, grid: &WavelengthGrid, options: &Options) -> Result<OpticalSpectrum, OpticsError> {
    let samples: Vec<Sample> =
        grid.wavelengths_nm().par_iter().map(|&w| at_wavelength(recipe, w, options)).collect::<Result<_, _>>()?;
    let mut warnings: Vec<String> = Vec::new();
    summarise_warnings(&samples, &mut warnings);
    let col = |f: fn(&Sample) -> f64| samples.iter().map(f).collect::<Vec<f64>>();
    Ok(OpticalSpectrum {
        sample: recipe.name.clone(),
        absorption: recipe.absorption,
        corrections: recipe.corrections(),
        wavelength_nm: col(|s| s.wavelength_nm),
        mu_s_per_m: col(|s| s.mu_s_per_m),
        mu_a_per_m: col(|s| s.mu_a_per_m),
        mu_t_per_m: col(|s| s.mu_t_per_m),
        g: col(|s| s.g),
        n_bulk: col(|s| s.n_bulk),
        phase_integral_before_normalisation: col(|s| s.phase_integral_before_normalisation),
        phase: samples.into_iter().map(|s| s.phase).collect(),
        warnings,
    })
}

/// Groups per-wavelength warnings ("… at 380 nm") into one line per cause.
fn summarise_warnings(samples: &[Sample], out: &mut Vec<String>) {
    let mut groups: Vec<(String, Vec<f64>)> = Vec::new();
    for s in samples {
        for w in &s.warnings {
            match groups.iter_mut().find(|(k, _)| k == w) {
                Some((_, v)) => v.push(s.wavelength_nm),
                None => groups.push((w.clone(), vec![s.wavelength_nm])),
            }
        }
    }
    for (w, at) in groups {
        let list: Vec<String> = at.iter().map(|x| format!("{x}")).collect();
        out.push(format!("{w} (at {} nm)", list.join(", ")));
    }
}

/// A quadrature node of a size distribution: radius and number density
/// weight [1/m³].
#[derive(Debug, Clone, Copy)]
struct Node {
    radius_m: f64,
    number_per_m3: f64,
}

const GL8: [(f64, f64); 8] = [
    (-0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
    (-0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
    (-0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (-0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.183_434_642_495_649_8, 0.362_683_783_378_362),
    (0.525_532_409_916_329, 0.313_706_645_877_887_3),
    (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
    (0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
];

/// Quadrature nodes for `size` with `panels` Gauss–Legendre panels,
/// normalised to volume fraction `phi`.
fn size_nodes(size: SizeDistribution, phi: f64, panels: usize, out: &mut Vec<Node>) {
    out.clear();
    match size {
        SizeDistribution::Mono { radius_m } => out.push(Node { radius_m, number_per_m3: 1.0 }),
        SizeDistribution::Uniform { min_radius_m, max_radius_m } => {
            gauss_legendre(min_radius_m, max_radius_m, panels, |r, w| out.push(Node { radius_m: r, number_per_m3: w }));
        }
        SizeDistribution::LogNormal { median_radius_m, sigma } => {
            let mu = median_radius_m.ln();
            let lo = mu - 6.0 * sigma;
            let hi = mu + 6.0 * sigma + 3.0 * sigma * sigma;
            gauss_legendre(lo, hi, panels, |t, w| {
                let z = (t - mu) / sigma;
                out.push(Node { radius_m: t.exp(), number_per_m3: w * (-0.5 * z * z).exp() })
            });
        }
    }
    let volume: f64 = out.iter().map(|n| 4.0 / 3.0 * PI * n.radius_m.powi(3) * n.number_per_m3).sum();
    for n in out.iter_mut() {
        n.number_per_m3 *= phi / volume;
    }
}

fn gauss_legendre(a: f64, b: f64, panels: usize, mut f: impl FnMut(f64, f64)) {
    let h = (b - a) / panels as f64;
    for p in 0..panels {
        let c = a + (p as f64 + 0.5) * h;
        for (t, w) in GL8 {
            f(c + 0.5 * h * t, 0.5 * h * w);
        }
    }
}

/// Sums over the nodes of one particle type.
#[derive(Debug, Clone, Copy, Default)]
struct Sums {
    mu_s: f64,
    mu_t: f64,
    g_mu_s: f64,
    forward: Complex64,
    alpha_max: f64,
}

struct Context<'a> {
    recipe: &'a Recipe,
    wavelength_nm: f64,
    warnings: Vec<String>,
}

impl Context<'_> {
    fn index(&mut self, medium: &Medium, role: &str) -> Result<Complex64, OpticsError> {
        let sample =
            medium.index.at(self.wavelength_nm, medium.extrapolation).map_err(|source| OpticsError::Index {
                recipe: self.recipe.name.clone(),
                medium: format!("{role} {}", medium.name),
                wavelength_nm: self.wavelength_nm,
                source: Box::new(source),
            })?;
        if sample.extrapolated {
            let (lo, hi) = medium.index.range_nm();
            let how = match medium.extrapolation {
                Extrapolation::Clamp => "clamped",
                Extrapolation::Linear => "linearly extrapolated",
                Extrapolation::None => "extrapolated",
            };
            self.warnings.push(format!(
                "{role} {} index ({}) {how} outside its data range {lo}–{hi} nm",
                medium.name, medium.index_source
            ));
        }
        Ok(sample.index)
    }
}

/// Bulk properties of `recipe` at one wavelength.
pub fn at_wavelength(recipe: &Recipe, wavelength_nm: f64, options: &Options) -> Result<Sample, OpticsError> {
    if options.phase_entries == 1 {
        return Err(OpticsError::PhaseEntries(1));
    }
    let mut ctx = Context { recipe, wavelength_nm, warnings: Vec::new() };
    let lambda = wavelength_nm * 1e-9;
    let k0 = 2.0 * PI / lambda;
    let n_host = ctx.index(&recipe.host, "host")?;
    let mus: Vec<f64> =
        (0..options.phase_entries).map(|i| (PI * i as f64 / (options.phase_entries - 1) as f64).cos()).collect();
    let mut phase = vec![0.0; options.phase_entries];
    let mut coeffs = Coefficients::new();
    let mut nodes = Vec::new();
    let mut total = Sums::default();
    let mut phi_total = 0.0;
    let mut volume_weighted_absorption = 0.0;
    // The largest α = 4π r κ_h/λ met, for the warning below.
    let mut alpha_max: f64 = 0.0;

    for particle in &recipe.particles {
        let role = "particle";
        let n_particle = ctx.index(&particle.medium, role)?;
        let phi = particle.volume_fraction;
        phi_total += phi;
        volume_weighted_absorption += phi * 4.0 * PI * n_particle.im / lambda;
        let mie_err = |source| OpticsError::Mie {
            recipe: recipe.name.clone(),
            medium: particle.medium.name.clone(),
            wavelength_nm,
            source: Box::new(source),
        };
        let integrate = |nodes: &[Node], coeffs: &mut Coefficients, phase: Option<&mut [f64]>| {
            let mut s = Sums::default();
            let mut phase = phase;
            for node in nodes {
                let x = n_host * (k0 * node.radius_m);
                coeffs.recompute(n_particle / n_host, x).map_err(mie_err)?;
                let cs = coeffs.cross_sections(lambda, n_host, node.radius_m);
                let n = node.number_per_m3;
                s.mu_s += n * cs.scattering_m2;
                s.mu_t += n * cs.extinction_m2;
                s.g_mu_s += n * cs.scattering_m2 * cs.g;
                s.forward += coeffs.extinction_sum() * (0.5 * n);
                s.alpha_max = s.alpha_max.max(4.0 * PI * node.radius_m * n_host.im / lambda);
                if let Some(p) = phase.as_deref_mut() {
                    // F(α) weights each size as its C_s does, so that the
                    // table stays the μ_s-weighted mean.
                    let w = n * cs.attenuation * lambda * lambda / (8.0 * PI * PI * n_host.norm_sqr());
                    coeffs.accumulate_intensity(&mus, w, p);
                }
            }
            Ok::<Sums, OpticsError>(s)
        };
        let sums = if let SizeDistribution::Mono { .. } = particle.size {
            size_nodes(particle.size, phi, 1, &mut nodes);
            integrate(&nodes, &mut coeffs, Some(&mut phase))?
        } else {
            let mut panels = 4;
            size_nodes(particle.size, phi, panels, &mut nodes);
            let mut previous = integrate(&nodes, &mut coeffs, None)?;
            loop {
                panels *= 2;
                size_nodes(particle.size, phi, panels, &mut nodes);
                let current = integrate(&nodes, &mut coeffs, None)?;
                let change = ((current.mu_s - previous.mu_s) / current.mu_s).abs();
                if change < options.size_tolerance {
                    break;
                }
                if panels >= 4096 {
                    return Err(OpticsError::NotConverged {
                        recipe: recipe.name.clone(),
                        medium: particle.medium.name.clone(),
                        wavelength_nm,
                        tolerance: options.size_tolerance,
                        change,
                    });
                }
                previous = current;
            }
            if options.phase_entries > 0 {
                integrate(&nodes, &mut coeffs, Some(&mut phase))?
            } else {
                previous
            }
        };
        total.mu_s += sums.mu_s;
        total.mu_t += sums.mu_t;
        total.g_mu_s += sums.g_mu_s;
        total.forward += sums.forward / (n_host * n_host);
        alpha_max = alpha_max.max(sums.alpha_max);
    }

    if alpha_max >= 1.0 {
        ctx.warnings.push(
            "the host absorbs strongly over one particle (α = 4πrκh/λ ≥ 1): Frisvad et al.'s far-field cross sections are unreliable there"
                .to_string(),
        );
    }
    let host_absorption_full = 4.0 * PI * n_host.im / lambda;
    let host_absorption = (1.0 - phi_total) * host_absorption_full;
    let mu_s = total.mu_s;
    let mut mu_a = match recipe.absorption {
        AbsorptionModel::Mie => total.mu_t + host_absorption - mu_s,
        AbsorptionModel::VolumeWeighted => host_absorption + volume_weighted_absorption,
        AbsorptionModel::VolumeWeightedFullHost => host_absorption_full + volume_weighted_absorption,
    };
    if mu_a < 0.0 {
        ctx.warnings.push(format!("Lorenz–Mie absorption came out negative ({mu_a:.3e} /m) and was set to 0"));
        mu_a = 0.0;
    }
    let n_bulk = (n_host + Complex64::new(0.0, 2.0 * PI / k0.powi(3)) * total.forward).re;
    let mut raw_integral = f64::NAN;
    if mu_s > 0.0 && !phase.is_empty() {
        for p in &mut phase {
            *p /= mu_s;
        }
        raw_integral = table_integral(&mus, &phase);
        for p in &mut phase {
            *p /= raw_integral;
        }
    }
    Ok(Sample {
        wavelength_nm,
        mu_s_per_m: mu_s,
        mu_a_per_m: mu_a,
        mu_t_per_m: mu_s + mu_a,
        g: if mu_s > 0.0 { total.g_mu_s / mu_s } else { 0.0 },
        n_bulk,
        phase,
        phase_integral_before_normalisation: raw_integral,
        warnings: ctx.warnings,
    })
}

/// ∫ p dΩ = 2π Σ (μᵢ − μᵢ₊₁)(pᵢ + pᵢ₊₁)/2: exact for p linear in μ between
/// the nodes.
fn table_integral(mus: &[f64], p: &[f64]) -> f64 {
    let mut s = 0.0;
    for i in 0..mus.len() - 1 {
        s += (mus[i] - mus[i + 1]) * (p[i] + p[i + 1]);
    }
    PI * s
}
