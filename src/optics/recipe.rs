//! Sample recipes: the material description (docs/method.md#optics) as a TOML file.
//!
//! A recipe names a host medium and one or more particle inclusions, each
//! with a refractive-index source (a refractiveindex.info YAML file, or an
//! embedded one as `builtin:NAME`), a density in g/mL, for particles a
//! weight percentage and a size, plus the slab thickness and outer size and
//! an optional measured surface roughness. Loading is two-stage (raw TOML
//! with unknown keys rejected, then a validated [`Recipe`]); every error
//! names the file and the key.
//!
//! ```toml
//! name = "IOL1068-09"
//! thickness_mm = 6.35
//! size_mm = [149.1, 104.5]
//! absorption = "volume-weighted-full-host"   # or "mie" (default), "volume-weighted"
//!
//! [host]
//! name = "polycarbonate"
//! index = "builtin:PC_Zhang2020"        # or a path relative to this file
//! density_g_per_ml = 1.2
//! extrapolate = "clamp"                 # none (default) | clamp | linear
//! real_part = { wavelength_nm = 550, n = 1.5889, mode = "shift" }
//!
//! [[particles]]
//! name = "PDMS"
//! index = "builtin:PDMS_Zhang2020_20-1"
//! density_g_per_ml = 0.965
//! weight_percent = 0.65
//! size = { kind = "diameter", diameter_um = 2.2 }
//! # imaginary_part = { mode = "replace", kappa = 0 }    # or { mode = "scale", factor = 0.5 }
//! # size = { kind = "range", min_um = 8, max_um = 10, distribution = "uniform" }   # or "midpoint"
//! # size = { kind = "log-normal", median_diameter_um = 2.2, sigma = 0.1 }
//!
//! [surface]
//! model = "trowbridge-reitz"            # or "beckmann"
//! alpha = 0.00836
//! scale = 1.095
//! # or: fit = "surface/fit.json"         # `lucent surface fit` output: its better model
//! #     (model = "beckmann" next to fit picks that model's fit instead)
//! ```
//!
//! Volume fraction of a particle type (docs/method.md#optics): φ = (w/ρ_p) / (100/ρ_h).
//!
//! Corrections of the index data, for the host or any particle:
//! `real_part` imposes n at one wavelength (shift, or replace by a constant;
//! κ kept), `imaginary_part` replaces κ by a constant or scales it (n kept).
//! Both are listed by [`Recipe::corrections`] and reported with the
//! optical properties.
//!
//! Absorption models (`absorption`, see [`AbsorptionModel`]): `mie`
//! (the default when the key is absent), `volume-weighted`, and
//! `volume-weighted-full-host`, the lab's formula, which the shipped
//! recipes use.

use super::index::{Extrapolation, ImaginaryPartCorrection, IndexError, IndexSpectrum, RealPartCorrection};
use crate::surface::model::RoughnessModel;
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A recipe that cannot be used; the message names the file and key.
#[derive(Debug, thiserror::Error)]
pub enum RecipeError {
    #[error("{path}: cannot read recipe: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{path}: {message}")]
    Parse { path: PathBuf, message: String },
    #[error("{path}: {key}: {message}")]
    Invalid { path: PathBuf, key: String, message: String },
    /// A particle type whose weight percentage the recipe leaves unknown
    /// (no `weight_percent`, no override): a folder of recipes skips it.
    #[error(
        "{path}: {key}: the weight percentage of {particle} is not given (unknown); set it in the recipe or pass --weight-percent"
    )]
    WeightPercentUnknown { path: PathBuf, key: String, particle: String },
    #[error("{path}: {key}: {source}")]
    /// Boxed: an [`IndexError`] is large and this error travels through
    /// every `Result` of the recipe loader.
    Index { path: PathBuf, key: String, source: Box<IndexError> },
}

/// How the bulk absorption coefficient is computed (docs/method.md#optics; formulas in
/// [`super::bulk`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize, Default)]
#[serde(rename_all = "kebab-case")]
pub enum AbsorptionModel {
    /// `mie`: μ_a = μ_t − μ_s from the Lorenz–Mie cross sections plus the
    /// host's 4πκ_h/λ over the volume it occupies, (1 − Σφ).
    #[default]
    Mie,
    /// `volume-weighted`: (1 − Σφ) 4πκ_h/λ + Σ φ_i 4πκ_i/λ.
    VolumeWeighted,
    /// `volume-weighted-full-host`: 4πκ_h/λ + Σ φ_i 4πκ_i/λ, the host term
    /// not scaled by 1 − Σφ. The lab's formula: its published coefficients
    /// follow it exactly.
    VolumeWeightedFullHost,
}

impl AbsorptionModel {
    /// The name a recipe uses for this model.
    pub fn name(self) -> &'static str {
        match self {
            AbsorptionModel::Mie => "mie",
            AbsorptionModel::VolumeWeighted => "volume-weighted",
            AbsorptionModel::VolumeWeightedFullHost => "volume-weighted-full-host",
        }
    }

    /// What the model computes, in one line.
    pub fn formula(self) -> &'static str {
        match self {
            AbsorptionModel::Mie => "μa = μt − μs (Lorenz–Mie) + (1 − Σφ)·4πκh/λ",
            AbsorptionModel::VolumeWeighted => "μa = (1 − Σφ)·4πκh/λ + Σ φi·4πκi/λ",
            AbsorptionModel::VolumeWeightedFullHost => "μa = 4πκh/λ + Σ φi·4πκi/λ (the lab's formula)",
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRecipe {
    name: Option<String>,
    description: Option<String>,
    thickness_mm: RawValue,
    size_mm: Option<Vec<f64>>,
    #[serde(default)]
    absorption: AbsorptionModel,
    host: RawHost,
    particles: Vec<RawParticle>,
    surface: Option<RawSurface>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawHost {
    name: String,
    index: String,
    density_g_per_ml: f64,
    #[serde(default = "no_extrapolation")]
    extrapolate: Extrapolation,
    real_part: Option<RawRealPart>,
    imaginary_part: Option<RawImaginaryPart>,
}

/// `imaginary_part = { mode = "replace", kappa = 0 }` or
/// `{ mode = "scale", factor = 0.5 }`.
#[derive(Debug, Deserialize)]
#[serde(tag = "mode", rename_all = "kebab-case", deny_unknown_fields)]
enum RawImaginaryPart {
    Replace { kappa: f64 },
    Scale { factor: f64 },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRealPart {
    wavelength_nm: f64,
    n: RawValue,
    #[serde(default = "shift")]
    mode: RealPartCorrection,
}

fn shift() -> RealPartCorrection {
    RealPartCorrection::Shift
}

fn no_extrapolation() -> Extrapolation {
    Extrapolation::None
}

/// A number, or a number with its uncertainty:
/// `{ value = 0.65, sd = 0.02 }` (normal) or `{ min = 2.0, max = 2.4 }`
/// (uniform; `value` defaults to the midpoint).
#[derive(Debug, Clone, Deserialize)]
#[serde(untagged)]
enum RawValue {
    Plain(f64),
    Uncertain(RawUncertain),
}

#[derive(Debug, Clone, Deserialize)]
struct RawUncertain {
    value: Option<f64>,
    sd: Option<f64>,
    min: Option<f64>,
    max: Option<f64>,
    /// Unknown keys, reported by name (an untagged enum cannot say which).
    #[serde(flatten)]
    other: std::collections::BTreeMap<String, toml::Value>,
}

/// The distribution of an uncertain recipe input.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum InputDistribution {
    Normal { sd: f64 },
    Uniform { min: f64, max: f64 },
}

/// What an uncertain input sets.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "input", rename_all = "kebab-case")]
pub enum InputTarget {
    WeightPercent {
        particle: usize,
    },
    DiameterUm {
        particle: usize,
    },
    RealPartN {
        medium: MediumRef,
        wavelength_nm: f64,
    },
    /// The σ of a log-normal size distribution (of ln d).
    SizeSigma {
        particle: usize,
    },
    /// The slab's (plaque's) thickness, mm: the slice's slab and the
    /// render's box, not the optical properties.
    ThicknessMm,
}

/// An input the recipe gives with an uncertainty (`lucent optics --uncertainty`).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct UncertainInput {
    /// The recipe key, e.g. `particles[0].weight_percent`.
    pub key: String,
    pub target: InputTarget,
    pub nominal: f64,
    pub distribution: InputDistribution,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawParticle {
    name: String,
    index: String,
    density_g_per_ml: f64,
    weight_percent: Option<RawValue>,
    size: RawSize,
    #[serde(default = "no_extrapolation")]
    extrapolate: Extrapolation,
    real_part: Option<RawRealPart>,
    imaginary_part: Option<RawImaginaryPart>,
}

#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "kebab-case", deny_unknown_fields)]
enum RawSize {
    Diameter { diameter_um: RawValue },
    Range { min_um: f64, max_um: f64, distribution: RangeDistribution },
    LogNormal { median_diameter_um: RawValue, sigma: RawValue },
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(rename_all = "kebab-case")]
enum RangeDistribution {
    /// The midpoint diameter as a single size (how the lab computed its tables).
    Midpoint,
    /// Number density uniform in radius over the range.
    Uniform,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSurface {
    model: Option<RoughnessModel>,
    alpha: Option<f64>,
    scale: Option<f64>,
    /// A `fit.json` of `lucent surface fit` (relative to the recipe): its
    /// better model, or `model`'s fit when given.
    fit: Option<String>,
}

/// Measured surface roughness of the sample.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Surface {
    pub model: RoughnessModel,
    pub alpha: f64,
    pub scale: f64,
}

/// Particle size distribution, radii in metres.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum SizeDistribution {
    /// All particles have one radius.
    Mono { radius_m: f64 },
    /// Number density uniform in radius over [min, max].
    Uniform { min_radius_m: f64, max_radius_m: f64 },
    /// Log-normal number distribution in radius: ln r ~ N(ln median, σ²).
    LogNormal { median_radius_m: f64, sigma: f64 },
}

/// A medium with its refractive-index spectrum.
#[derive(Debug, Clone)]
pub struct Medium {
    pub name: String,
    /// Where the index came from, as written in the recipe.
    pub index_source: String,
    pub index: IndexSpectrum,
    pub extrapolation: Extrapolation,
    pub density_kg_per_m3: f64,
    /// The recipe's corrections of the index data, one readable line each
    /// (e.g. "n shifted to 1.5889 at 550 nm, κ kept"); empty if none.
    pub corrections: Vec<String>,
}

/// One particle type of a recipe.
#[derive(Debug, Clone)]
pub struct Particle {
    pub medium: Medium,
    pub weight_percent: f64,
    pub size: SizeDistribution,
    /// Volume fraction φ = (w/ρ_p)/(100/ρ_h).
    pub volume_fraction: f64,
}

/// A validated recipe.
#[derive(Debug, Clone)]
pub struct Recipe {
    pub name: String,
    pub description: Option<String>,
    pub path: PathBuf,
    pub thickness_m: f64,
    pub size_m: Option<[f64; 2]>,
    pub absorption: AbsorptionModel,
    pub host: Medium,
    pub particles: Vec<Particle>,
    pub surface: Option<Surface>,
    /// Inputs given with an uncertainty, at their nominal values above.
    pub uncertain: Vec<UncertainInput>,
}

/// Values the user supplies on the command line where a recipe leaves
/// them open.
#[derive(Debug, Clone, Copy, Default)]
pub struct Overrides {
    /// Weight percentage for particle types whose recipe gives none.
    pub weight_percent: Option<f64>,
}

impl Recipe {
    /// Loads and validates a recipe file.
    pub fn load(path: &Path, overrides: Overrides) -> Result<Self, RecipeError> {
        let text =
            crate::io::read_text(path).map_err(|source| RecipeError::Read { path: path.to_path_buf(), source })?;
        Self::parse(&text, path, overrides)
    }

    /// Parses recipe text; `path` names it in errors and anchors relative
    /// index-file paths.
    pub fn parse(text: &str, path: &Path, overrides: Overrides) -> Result<Self, RecipeError> {
        let raw: RawRecipe = toml::from_str(text)
            .map_err(|e| RecipeError::Parse { path: path.to_path_buf(), message: one_line(&e.to_string()) })?;
        Validator { path, uncertain: Default::default() }.recipe(raw, overrides)
    }

    /// Total volume fraction of all particle types.
    pub fn particle_volume_fraction(&self) -> f64 {
        self.particles.iter().map(|p| p.volume_fraction).sum()
    }

    /// Every correction of the index data, as "host NAME: …" and
    /// "particle NAME: …" lines, in recipe order.
    pub fn corrections(&self) -> Vec<String> {
        let host = self.host.corrections.iter().map(|c| format!("host {}: {c}", self.host.name));
        let particles = self
            .particles
            .iter()
            .flat_map(|p| p.medium.corrections.iter().map(move |c| format!("particle {}: {c}", p.medium.name)));
        host.chain(particles).collect()
    }
}

/// Which medium of a recipe a parameter refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "kebab-case", tag = "medium", content = "index")]
pub enum MediumRef {
    Host,
    /// `particles[i]`, 0-based.
    Particle(usize),
}

impl Recipe {
    fn particle_mut(&mut self, i: usize) -> Result<&mut Particle, RecipeError> {
        let count = self.particles.len();
        let path = self.path.clone();
        self.particles.get_mut(i).ok_or(RecipeError::Invalid {
            path,
            key: format!("particles[{i}]"),
            message: format!("the recipe has {count} particle type(s)"),
        })
    }

    fn invalid<T>(&self, key: String, message: String) -> Result<T, RecipeError> {
        Err(RecipeError::Invalid { path: self.path.clone(), key, message })
    }

    /// The recipe with particle `i`'s weight percentage set to `w` (its
    /// volume fraction follows; the total must stay below 1).
    pub fn with_weight_percent(&self, i: usize, w: f64) -> Result<Recipe, RecipeError> {
        let mut r = self.clone();
        let host_density = r.host.density_kg_per_m3;
        let p = r.particle_mut(i)?;
        if !(w.is_finite() && w > 0.0 && w < 100.0) {
            return self.invalid(format!("particles[{i}].weight_percent"), format!("must lie in (0, 100), got {w}"));
        }
        p.weight_percent = w;
        p.volume_fraction = (w / p.medium.density_kg_per_m3) / (100.0 / host_density);
        let total = r.particle_volume_fraction();
        if total >= 1.0 {
            return self
                .invalid("particles".into(), format!("the particles' volume fractions add up to {total:.3} ≥ 1"));
        }
        Ok(r)
    }

    /// Particle `i`'s nominal diameter in µm: the single diameter, the
    /// midpoint of a uniform range, or the median of a log-normal.
    pub fn diameter_um(&self, i: usize) -> Option<f64> {
        self.particles.get(i).map(|p| match p.size {
            SizeDistribution::Mono { radius_m } => 2e6 * radius_m,
            SizeDistribution::Uniform { min_radius_m, max_radius_m } => 1e6 * (min_radius_m + max_radius_m),
            SizeDistribution::LogNormal { median_radius_m, .. } => 2e6 * median_radius_m,
        })
    }

    /// The recipe with particle `i`'s nominal diameter ([`Recipe::diameter_um`])
    /// set to `d` µm: a uniform range is scaled about zero (its relative
    /// width kept), a log-normal keeps its σ.
    pub fn with_diameter_um(&self, i: usize, d: f64) -> Result<Recipe, RecipeError> {
        if !(d.is_finite() && d > 0.0) {
            return self.invalid(format!("particles[{i}].size"), format!("diameter {d} µm must be positive"));
        }
        let old = self.diameter_um(i);
        let mut r = self.clone();
        let p = r.particle_mut(i)?;
        let scale = d / old.unwrap_or(d);
        p.size = match p.size {
            SizeDistribution::Mono { .. } => SizeDistribution::Mono { radius_m: 0.5e-6 * d },
            SizeDistribution::Uniform { min_radius_m, max_radius_m } => {
                SizeDistribution::Uniform { min_radius_m: min_radius_m * scale, max_radius_m: max_radius_m * scale }
            }
            SizeDistribution::LogNormal { sigma, .. } => {
                SizeDistribution::LogNormal { median_radius_m: 0.5e-6 * d, sigma }
            }
        };
        Ok(r)
    }

    fn medium_mut(&mut self, m: MediumRef) -> Result<&mut Medium, RecipeError> {
        match m {
            MediumRef::Host => Ok(&mut self.host),
            MediumRef::Particle(i) => Ok(&mut self.particle_mut(i)?.medium),
        }
    }

    fn medium_key(m: MediumRef) -> String {
        match m {
            MediumRef::Host => "host".into(),
            MediumRef::Particle(i) => format!("particles[{i}]"),
        }
    }

    /// The medium `m` refers to, if it exists.
    pub fn medium(&self, m: MediumRef) -> Option<&Medium> {
        match m {
            MediumRef::Host => Some(&self.host),
            MediumRef::Particle(i) => self.particles.get(i).map(|p| &p.medium),
        }
    }

    /// The recipe with medium `m`'s real index shifted so that n = `n` at
    /// `wavelength_nm` (dispersion and κ kept; replaces an earlier shift of
    /// that medium, keeps a constant real part constant).
    pub fn with_real_part(&self, m: MediumRef, wavelength_nm: f64, n: f64) -> Result<Recipe, RecipeError> {
        let mut r = self.clone();
        let path = r.path.clone();
        let medium = r.medium_mut(m)?;
        let key = format!("{}.real_part", Self::medium_key(m));
        medium.index = medium
            .index
            .clone()
            .with_real_part_at(wavelength_nm, n, RealPartCorrection::Shift)
            .map_err(|source| RecipeError::Index { path, key, source: Box::new(source) })?;
        Ok(r)
    }

    /// The recipe with the uncertain input `target` set to `value`.
    pub fn with_input(&self, target: InputTarget, value: f64) -> Result<Recipe, RecipeError> {
        match target {
            InputTarget::WeightPercent { particle } => self.with_weight_percent(particle, value),
            InputTarget::DiameterUm { particle } => self.with_diameter_um(particle, value),
            InputTarget::RealPartN { medium, wavelength_nm } => self.with_real_part(medium, wavelength_nm, value),
            InputTarget::SizeSigma { particle } => self.with_size_sigma(particle, value),
            InputTarget::ThicknessMm => self.with_thickness_mm(value),
        }
    }

    /// The recipe with particle `i`'s log-normal σ set to `sigma` (0 < σ ≤ 2).
    pub fn with_size_sigma(&self, i: usize, sigma: f64) -> Result<Recipe, RecipeError> {
        let key = format!("particles[{i}].size.sigma");
        if !(sigma.is_finite() && sigma > 0.0 && sigma <= 2.0) {
            return self.invalid(key, format!("must lie in (0, 2], got {sigma}"));
        }
        let mut r = self.clone();
        let p = r.particle_mut(i)?;
        match p.size {
            SizeDistribution::LogNormal { median_radius_m, .. } => {
                p.size = SizeDistribution::LogNormal { median_radius_m, sigma };
                Ok(r)
            }
            _ => self.invalid(key, "the particle's size is not log-normal".into()),
        }
    }

    /// The recipe with its thickness set to `mm` (> 0).
    pub fn with_thickness_mm(&self, mm: f64) -> Result<Recipe, RecipeError> {
        if !(mm.is_finite() && mm > 0.0) {
            return self.invalid("thickness_mm".into(), format!("must be a positive number of millimetres, got {mm}"));
        }
        let mut r = self.clone();
        r.thickness_m = mm * 1e-3;
        Ok(r)
    }

    /// The recipe with medium `m`'s κ(λ) replaced by the constant `kappa`.
    pub fn with_kappa(&self, m: MediumRef, kappa: f64) -> Result<Recipe, RecipeError> {
        self.with_imaginary(m, ImaginaryPartCorrection::Replace { kappa })
    }

    /// The recipe with medium `m`'s κ(λ) = `factor` × the data's κ(λ).
    pub fn with_kappa_factor(&self, m: MediumRef, factor: f64) -> Result<Recipe, RecipeError> {
        self.with_imaginary(m, ImaginaryPartCorrection::Scale { factor })
    }

    fn with_imaginary(&self, m: MediumRef, c: ImaginaryPartCorrection) -> Result<Recipe, RecipeError> {
        let mut r = self.clone();
        let path = r.path.clone();
        let medium = r.medium_mut(m)?;
        let key = format!("{}.imaginary_part", Self::medium_key(m));
        medium.index = medium.index.clone().with_imaginary_part(c).map_err(|source| RecipeError::Index {
            path,
            key,
            source: Box::new(source),
        })?;
        Ok(r)
    }
}

/// toml's messages span several lines (source excerpt with a caret); keep
/// the location and the message.
fn one_line(message: &str) -> String {
    let lines: Vec<&str> = message.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
    let location = lines.first().copied().unwrap_or("");
    let last = lines.last().copied().unwrap_or("");
    if lines.len() > 1 {
        format!("{location}: {last}").replace("TOML parse error at ", "")
    } else {
        location.to_string()
    }
}

struct Validator<'a> {
    path: &'a Path,
    uncertain: std::cell::RefCell<Vec<UncertainInput>>,
}

impl Validator<'_> {
    /// The nominal value of `raw`; an uncertain one is recorded.
    fn value(&self, key: &str, raw: RawValue, target: InputTarget) -> Result<f64, RecipeError> {
        let u = match raw {
            RawValue::Plain(v) => return Ok(v),
            RawValue::Uncertain(u) => u,
        };
        if let Some(k) = u.other.keys().next() {
            return self.invalid(&format!("{key}.{k}"), "unknown key (valid: value, sd, min, max)");
        }
        let (nominal, distribution) =
            match (u.value, u.sd, u.min, u.max) {
                (Some(v), Some(sd), None, None) => {
                    if !(sd.is_finite() && sd > 0.0) {
                        return self.invalid(&format!("{key}.sd"), format!("must be a positive number, got {sd}"));
                    }
                    (v, InputDistribution::Normal { sd })
                }
                (value, None, Some(min), Some(max)) => {
                    if !(min.is_finite() && max.is_finite() && min < max) {
                        return self.invalid(key, format!("min {min} must be below max {max}"));
                    }
                    let v = value.unwrap_or(0.5 * (min + max));
                    if !(min..=max).contains(&v) {
                        return self.invalid(&format!("{key}.value"), format!("{v} lies outside [{min}, {max}]"));
                    }
                    (v, InputDistribution::Uniform { min, max })
                }
                _ => return self.invalid(
                    key,
                    "give a number, { value = V, sd = S } (normal) or { min = A, max = B } (uniform, value optional)",
                ),
            };
        self.uncertain.borrow_mut().push(UncertainInput { key: key.to_string(), target, nominal, distribution });
        Ok(nominal)
    }

    fn medium_ref(key: &str) -> MediumRef {
        key.strip_prefix("particles[")
            .and_then(|r| r.strip_suffix(']'))
            .and_then(|i| i.parse().ok())
            .map(MediumRef::Particle)
            .unwrap_or(MediumRef::Host)
    }

    fn invalid<T>(&self, key: &str, message: impl Into<String>) -> Result<T, RecipeError> {
        Err(RecipeError::Invalid { path: self.path.to_path_buf(), key: key.to_string(), message: message.into() })
    }

    fn positive(&self, key: &str, value: f64, unit: &str) -> Result<f64, RecipeError> {
        if value.is_finite() && value > 0.0 {
            Ok(value)
        } else {
            self.invalid(key, format!("must be a positive number of {unit}, got {value}"))
        }
    }

    fn recipe(&self, raw: RawRecipe, overrides: Overrides) -> Result<Recipe, RecipeError> {
        let name = match raw.name {
            Some(n) if !n.trim().is_empty() => n,
            Some(_) => return self.invalid("name", "must not be empty"),
            None => self.path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default(),
        };
        let thickness_mm = self.value("thickness_mm", raw.thickness_mm, InputTarget::ThicknessMm)?;
        let thickness_m = self.positive("thickness_mm", thickness_mm, "millimetres")? * 1e-3;
        let size_m = match raw.size_mm {
            None => None,
            Some(v) if v.len() == 2 => Some([
                self.positive("size_mm[0]", v[0], "millimetres")? * 1e-3,
                self.positive("size_mm[1]", v[1], "millimetres")? * 1e-3,
            ]),
            Some(v) => return self.invalid("size_mm", format!("must be [width, height], got {} values", v.len())),
        };
        let host_density = self.positive("host.density_g_per_ml", raw.host.density_g_per_ml, "g/mL")?;
        let host = self.medium(
            "host",
            &raw.host.name,
            &raw.host.index,
            host_density,
            raw.host.extrapolate,
            (raw.host.real_part.as_ref(), raw.host.imaginary_part.as_ref()),
        )?;
        if raw.particles.is_empty() {
            return self.invalid("particles", "at least one [[particles]] entry is required");
        }
        let mut particles = Vec::with_capacity(raw.particles.len());
        for (i, p) in raw.particles.iter().enumerate() {
            let key = format!("particles[{i}]");
            let density = self.positive(&format!("{key}.density_g_per_ml"), p.density_g_per_ml, "g/mL")?;
            let medium = self.medium(
                &key,
                &p.name,
                &p.index,
                density,
                p.extrapolate,
                (p.real_part.as_ref(), p.imaginary_part.as_ref()),
            )?;
            let wkey = format!("{key}.weight_percent");
            let raw_w = match &p.weight_percent {
                Some(w) => Some(self.value(&wkey, w.clone(), InputTarget::WeightPercent { particle: i })?),
                None => overrides.weight_percent,
            };
            let w = match raw_w {
                Some(w) => w,
                None => {
                    return Err(RecipeError::WeightPercentUnknown {
                        path: self.path.to_path_buf(),
                        key: wkey,
                        particle: p.name.clone(),
                    })
                }
            };
            if !(w.is_finite() && w > 0.0 && w < 100.0) {
                return self.invalid(&wkey, format!("must lie in (0, 100), got {w}"));
            }
            let size = self.size(&format!("{key}.size"), &p.size, i)?;
            let volume_fraction = (w / density) / (100.0 / host_density);
            particles.push(Particle { medium, weight_percent: w, size, volume_fraction });
        }
        let total: f64 = particles.iter().map(|p| p.volume_fraction).sum();
        if total >= 1.0 {
            return self.invalid("particles", format!("the particles' volume fractions add up to {total:.3} ≥ 1"));
        }
        let surface = match raw.surface {
            None => None,
            Some(RawSurface { fit: Some(file), alpha, scale, model }) => {
                if alpha.is_some() || scale.is_some() {
                    return self.invalid("surface", "give either fit = \"fit.json\" or alpha (and scale), not both");
                }
                let p = self.path.parent().unwrap_or(Path::new(".")).join(&file);
                let (model, alpha, scale) = crate::surface::load_fit_choice(&p, model)
                    .or_else(|e| self.invalid("surface.fit", e.to_string()))?;
                Some(Surface { model, alpha, scale })
            }
            Some(RawSurface { fit: None, alpha, scale, model }) => {
                let Some(model) = model else {
                    return self.invalid(
                        "surface.model",
                        "missing (trowbridge-reitz or beckmann), or give fit = \"fit.json\"",
                    );
                };
                let Some(alpha) = alpha else { return self.invalid("surface.alpha", "missing") };
                Some(Surface {
                    model,
                    alpha: crate::surface::model::check_alpha(alpha)
                        .or_else(|p| self.invalid("surface.alpha", format!("{p} (dimensionless roughness)")))?,
                    scale: self.positive("surface.scale", scale.unwrap_or(1.0), "(dimensionless scale)")?,
                })
            }
        };
        Ok(Recipe {
            name,
            description: raw.description,
            path: self.path.to_path_buf(),
            thickness_m,
            size_m,
            absorption: raw.absorption,
            host,
            particles,
            surface,
            uncertain: self.uncertain.take(),
        })
    }

    fn medium(
        &self,
        key: &str,
        name: &str,
        index: &str,
        density_g_per_ml: f64,
        extrapolation: Extrapolation,
        (real_part, imaginary_part): (Option<&RawRealPart>, Option<&RawImaginaryPart>),
    ) -> Result<Medium, RecipeError> {
        let index_key = format!("{key}.index");
        let index_error = |source| RecipeError::Index {
            path: self.path.to_path_buf(),
            key: index_key.clone(),
            source: Box::new(source),
        };
        let mut spectrum = if let Some(builtin) = index.strip_prefix("builtin:") {
            IndexSpectrum::builtin(builtin).map_err(index_error)?
        } else {
            let file = Path::new(index);
            let resolved = if file.is_absolute() {
                file.to_path_buf()
            } else {
                self.path.parent().unwrap_or(Path::new(".")).join(file)
            };
            IndexSpectrum::load(&resolved).map_err(index_error)?
        };
        let mut corrections = Vec::new();
        if let Some(rp) = real_part {
            let rkey = format!("{key}.real_part");
            self.positive(&format!("{rkey}.wavelength_nm"), rp.wavelength_nm, "nanometres")?;
            let target = InputTarget::RealPartN { medium: Self::medium_ref(key), wavelength_nm: rp.wavelength_nm };
            let n = self.value(&format!("{rkey}.n"), rp.n.clone(), target)?;
            self.positive(&format!("{rkey}.n"), n, "(refractive index)")?;
            spectrum = spectrum.with_real_part_at(rp.wavelength_nm, n, rp.mode).map_err(|source| {
                RecipeError::Index { path: self.path.to_path_buf(), key: rkey.clone(), source: Box::new(source) }
            })?;
            corrections.push(match rp.mode {
                RealPartCorrection::Shift => {
                    format!("n shifted to {n} at {} nm (dispersion and κ kept)", rp.wavelength_nm)
                }
                RealPartCorrection::Replace => format!("n replaced by the constant {n} (κ kept)"),
            });
        }
        if let Some(ip) = imaginary_part {
            let ikey = format!("{key}.imaginary_part");
            let (correction, text, field) = match *ip {
                RawImaginaryPart::Replace { kappa } => {
                    (ImaginaryPartCorrection::Replace { kappa }, format!("κ replaced by {kappa} (n kept)"), "kappa")
                }
                RawImaginaryPart::Scale { factor } => {
                    (ImaginaryPartCorrection::Scale { factor }, format!("κ scaled by {factor} (n kept)"), "factor")
                }
            };
            spectrum = spectrum.with_imaginary_part(correction).map_err(|source| RecipeError::Index {
                path: self.path.to_path_buf(),
                key: format!("{ikey}.{field}"),
                source: Box::new(source),
            })?;
            corrections.push(text);
        }
        Ok(Medium {
            name: name.to_string(),
            index_source: index.to_string(),
            index: spectrum,
            extrapolation,
            density_kg_per_m3: density_g_per_ml * 1000.0,
            corrections,
        })
    }

    /// A particle diameter in µm: positive, and between an atom (0.1 nm) and
    /// a centimetre, so a diameter typed in metres or millimetres is caught.
    fn diameter(&self, key: &str, value: f64) -> Result<f64, RecipeError> {
        let d = self.positive(key, value, "micrometres")?;
        if !(1e-4..=1e4).contains(&d) {
            return self
                .invalid(key, format!("{d} µm is outside 1e-4 … 1e4 µm (0.1 nm to 1 cm): the unit is micrometres"));
        }
        Ok(d)
    }

    fn size(&self, key: &str, raw: &RawSize, particle: usize) -> Result<SizeDistribution, RecipeError> {
        Ok(match *raw {
            RawSize::Diameter { ref diameter_um } => {
                let dkey = format!("{key}.diameter_um");
                let d = self.value(&dkey, diameter_um.clone(), InputTarget::DiameterUm { particle })?;
                SizeDistribution::Mono { radius_m: self.diameter(&dkey, d)? * 0.5e-6 }
            }
            RawSize::Range { min_um, max_um, distribution } => {
                let lo = self.diameter(&format!("{key}.min_um"), min_um)?;
                let hi = self.diameter(&format!("{key}.max_um"), max_um)?;
                if hi <= lo {
                    return self
                        .invalid(key, format!("empty diameter range [{lo}, {hi}] µm: max_um must exceed min_um"));
                }
                match distribution {
                    RangeDistribution::Midpoint => SizeDistribution::Mono { radius_m: 0.25e-6 * (lo + hi) },
                    RangeDistribution::Uniform => {
                        SizeDistribution::Uniform { min_radius_m: lo * 0.5e-6, max_radius_m: hi * 0.5e-6 }
                    }
                }
            }
            RawSize::LogNormal { ref median_diameter_um, ref sigma } => {
                let (dkey, skey) = (format!("{key}.median_diameter_um"), format!("{key}.sigma"));
                let d = self.value(&dkey, median_diameter_um.clone(), InputTarget::DiameterUm { particle })?;
                let d = self.diameter(&dkey, d)?;
                let s = self.value(&skey, sigma.clone(), InputTarget::SizeSigma { particle })?;
                let s = self.positive(&skey, s, "(geometric standard deviation of ln d)")?;
                if s > 2.0 {
                    return self.invalid(&format!("{key}.sigma"), format!("{s} is implausibly wide (must be ≤ 2)"));
                }
                SizeDistribution::LogNormal { median_radius_m: d * 0.5e-6, sigma: s }
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"
name = "test"
thickness_mm = 6.35
[host]
name = "polycarbonate"
index = "builtin:PC_Zhang2020"
density_g_per_ml = 1.2
extrapolate = "clamp"
real_part = { wavelength_nm = 550, n = 1.5889 }
[[particles]]
name = "PDMS"
index = "builtin:PDMS_Zhang2020_20-1"
density_g_per_ml = 0.965
weight_percent = 0.65
size = { kind = "diameter", diameter_um = 2.2 }
"#;

    fn parse(text: &str) -> Result<Recipe, RecipeError> {
        Recipe::parse(text, Path::new("sample.toml"), Overrides::default())
    }

    fn error(text: &str) -> String {
        parse(text).expect_err("recipe should be rejected").to_string()
    }

    #[test]
    fn good_recipe_loads() {
        let r = parse(GOOD).unwrap();
        assert_eq!(r.name, "test");
        assert!((r.thickness_m - 6.35e-3).abs() < 1e-15);
        let p = &r.particles[0];
        assert_eq!(p.size, SizeDistribution::Mono { radius_m: 1.1e-6 });
        assert!((p.volume_fraction - (0.65 / 0.965) / (100.0 / 1.2)).abs() < 1e-15);
        let n550 = r.host.index.at(550.0, Extrapolation::None).unwrap().index.re;
        assert!((n550 - 1.5889).abs() < 1e-12);
    }

    #[test]
    fn unknown_key_is_named() {
        let e = error(&GOOD.replace("thickness_mm", "thicknes_mm"));
        assert!(e.contains("sample.toml") && e.contains("thicknes_mm"), "{e}");
        let e = error(&GOOD.replace("weight_percent = 0.65", "weight_percent = 0.65\ncolour = 1"));
        assert!(e.contains("colour"), "{e}");
        let e = error(&GOOD.replace("diameter_um = 2.2", "diameter_um = 2.2, radius = 1"));
        assert!(e.contains("radius"), "{e}");
    }

    #[test]
    fn bad_values_are_named() {
        let cases = [
            ("density_g_per_ml = 0.965", "density_g_per_ml = -0.965", "particles[0].density_g_per_ml"),
            ("density_g_per_ml = 1.2", "density_g_per_ml = 0", "host.density_g_per_ml"),
            ("weight_percent = 0.65", "weight_percent = 100", "particles[0].weight_percent"),
            ("weight_percent = 0.65", "weight_percent = 0", "particles[0].weight_percent"),
            ("weight_percent = 0.65", "weight_percent = nan", "particles[0].weight_percent"),
            ("thickness_mm = 6.35", "thickness_mm = -1", "thickness_mm"),
            (
                "{ kind = \"diameter\", diameter_um = 2.2 }",
                "{ kind = \"range\", min_um = 10, max_um = 8, distribution = \"uniform\" }",
                "particles[0].size",
            ),
            ("builtin:PDMS_Zhang2020_20-1", "builtin:PDMS_nope", "particles[0].index"),
            ("builtin:PDMS_Zhang2020_20-1", "no/such/file.yml", "particles[0].index"),
        ];
        for (from, to, key) in cases {
            let text = GOOD.replace(from, to);
            assert_ne!(text, GOOD, "replacement {from} did not apply");
            let e = error(&text);
            assert!(e.contains("sample.toml") && e.contains(key), "{to}: {e}");
            assert!(!e.contains('\n'), "one-line error expected: {e}");
        }
    }

    #[test]
    fn missing_weight_percent_needs_override() {
        let text = GOOD.replace("weight_percent = 0.65\n", "");
        let e = error(&text);
        assert!(e.contains("weight_percent") && e.contains("unknown"), "{e}");
        let r = Recipe::parse(&text, Path::new("x.toml"), Overrides { weight_percent: Some(1.0) }).unwrap();
        assert_eq!(r.particles[0].weight_percent, 1.0);
    }

    #[test]
    fn absorption_models_and_overrides_parse() {
        for (name, model) in [
            ("mie", AbsorptionModel::Mie),
            ("volume-weighted", AbsorptionModel::VolumeWeighted),
            ("volume-weighted-full-host", AbsorptionModel::VolumeWeightedFullHost),
        ] {
            let r = parse(&format!("absorption = \"{name}\"\n{GOOD}")).unwrap();
            assert_eq!(r.absorption, model);
            assert_eq!(model.name(), name);
        }
        assert_eq!(parse(GOOD).unwrap().absorption, AbsorptionModel::Mie, "default when absent");
        let e = error(&format!("absorption = \"lab\"\n{GOOD}"));
        assert!(e.contains("volume-weighted-full-host"), "the valid names are listed: {e}");

        let with = |line: &str| GOOD.replace("size = { kind", &format!("{line}\nsize = {{ kind"));
        let r = parse(&with(r#"imaginary_part = { mode = "replace", kappa = 0 }"#)).unwrap();
        assert_eq!(r.particles[0].medium.index.at(550.0, Extrapolation::None).unwrap().index.im, 0.0);
        assert_eq!(
            r.corrections(),
            [
                "host polycarbonate: n shifted to 1.5889 at 550 nm (dispersion and κ kept)",
                "particle PDMS: κ replaced by 0 (n kept)"
            ]
        );
        let r = parse(&with(r#"imaginary_part = { mode = "scale", factor = 2 }"#)).unwrap();
        assert_eq!(r.particles[0].medium.corrections, ["κ scaled by 2 (n kept)"]);
        for (line, key) in [
            (r#"imaginary_part = { mode = "replace", kappa = -1 }"#, "particles[0].imaginary_part.kappa"),
            (r#"imaginary_part = { mode = "scale", factor = nan }"#, "particles[0].imaginary_part.factor"),
        ] {
            let e = error(&with(line));
            assert!(e.contains(key) && e.contains("sample.toml"), "{e}");
        }
        for line in [r#"imaginary_part = { mode = "replace", factor = 0 }"#, r#"imaginary_part = { mode = "double" }"#]
        {
            let e = error(&with(line));
            assert!(e.contains("sample.toml"), "{e}");
        }
    }

    #[test]
    fn uncertain_inputs_parse_and_bad_ones_are_named() {
        let r = parse(
            &GOOD
                .replace("weight_percent = 0.65", "weight_percent = { value = 0.65, sd = 0.02 }")
                .replace("diameter_um = 2.2", "diameter_um = { min = 2.0, max = 2.4 }"),
        )
        .unwrap();
        assert_eq!(r.particles[0].weight_percent, 0.65);
        assert_eq!(r.particles[0].size, SizeDistribution::Mono { radius_m: 1.1e-6 });
        assert_eq!(r.uncertain.len(), 2);
        assert_eq!(r.uncertain[0].key, "particles[0].weight_percent");
        assert_eq!(r.uncertain[0].distribution, InputDistribution::Normal { sd: 0.02 });
        assert_eq!(r.uncertain[1].distribution, InputDistribution::Uniform { min: 2.0, max: 2.4 });
        let r = parse(&GOOD.replace("n = 1.5889", "n = { value = 1.5889, sd = 0.001 }")).unwrap();
        assert_eq!(r.uncertain[0].target, InputTarget::RealPartN { medium: MediumRef::Host, wavelength_nm: 550.0 });
        assert!(parse(GOOD).unwrap().uncertain.is_empty());
        // A log-normal distribution's median and σ.
        let text = GOOD.replace(
            "size = { kind = \"diameter\", diameter_um = 2.2 }",
            "size = { kind = \"log-normal\", median_diameter_um = { value = 2.2, sd = 0.1 }, sigma = { min = 0.1, max = 0.3 } }",
        );
        assert_ne!(text, GOOD);
        let r = parse(&text).unwrap();
        assert_eq!(r.particles[0].size, SizeDistribution::LogNormal { median_radius_m: 1.1e-6, sigma: 0.2 });
        let targets: Vec<InputTarget> = r.uncertain.iter().map(|u| u.target).collect();
        assert_eq!(targets, [InputTarget::DiameterUm { particle: 0 }, InputTarget::SizeSigma { particle: 0 }]);
        let wider = r.with_input(InputTarget::SizeSigma { particle: 0 }, 0.25).unwrap();
        assert_eq!(wider.particles[0].size, SizeDistribution::LogNormal { median_radius_m: 1.1e-6, sigma: 0.25 });
        assert!(r.with_input(InputTarget::SizeSigma { particle: 0 }, 3.0).is_err());
        assert!(parse(GOOD).unwrap().with_size_sigma(0, 0.2).unwrap_err().to_string().contains("not log-normal"));
        // The thickness: recorded, and set by with_input; the properties do not depend on it.
        let r = parse(&GOOD.replace("thickness_mm = 6.35", "thickness_mm = { value = 6.35, sd = 0.05 }")).unwrap();
        assert_eq!((r.thickness_m, r.uncertain[0].target), (6.35e-3, InputTarget::ThicknessMm));
        assert_eq!(r.uncertain[0].key, "thickness_mm");
        assert!((r.with_input(InputTarget::ThicknessMm, 6.4).unwrap().thickness_m - 6.4e-3).abs() < 1e-15);
        assert!(r.with_input(InputTarget::ThicknessMm, -1.0).unwrap_err().to_string().contains("thickness_mm"));
        let e = error(&GOOD.replace("thickness_mm = 6.35", "thickness_mm = { value = -6.35, sd = 0.05 }"));
        assert!(e.contains("thickness_mm"), "{e}");
        for (from, to, key) in [
            ("weight_percent = 0.65", "weight_percent = { value = 0.65 }", "particles[0].weight_percent"),
            ("weight_percent = 0.65", "weight_percent = { value = 0.65, sd = -1 }", "particles[0].weight_percent.sd"),
            ("diameter_um = 2.2", "diameter_um = { min = 3, max = 2 }", "particles[0].size.diameter_um"),
            (
                "diameter_um = 2.2",
                "diameter_um = { value = 5, min = 2, max = 3 }",
                "particles[0].size.diameter_um.value",
            ),
        ] {
            let e = error(&GOOD.replace(from, to));
            assert!(e.contains("sample.toml") && e.contains(key), "{to}: {e}");
        }
        let e = error(&GOOD.replace("weight_percent = 0.65", "weight_percent = { value = 0.65, sdd = 1 }"));
        assert!(e.contains("sample.toml") && e.contains("particles[0].weight_percent.sdd"), "{e}");
    }

    #[test]
    fn size_kinds() {
        let r = parse(&GOOD.replace(
            "{ kind = \"diameter\", diameter_um = 2.2 }",
            "{ kind = \"range\", min_um = 8, max_um = 10, distribution = \"midpoint\" }",
        ))
        .unwrap();
        assert_eq!(r.particles[0].size, SizeDistribution::Mono { radius_m: 4.5e-6 });
        let r = parse(&GOOD.replace(
            "{ kind = \"diameter\", diameter_um = 2.2 }",
            "{ kind = \"log-normal\", median_diameter_um = 2.0, sigma = 0.2 }",
        ))
        .unwrap();
        assert_eq!(r.particles[0].size, SizeDistribution::LogNormal { median_radius_m: 1e-6, sigma: 0.2 });
    }
}
