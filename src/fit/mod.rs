//! Inverse fit of recipe parameters to measured BSSRDF slices (docs/method.md#fit):
//! the recipe values (weight percentage, particle diameter, particle real
//! index) whose simulated slices (docs/method.md#slab) best match measured ones over
//! several configurations (θ_i, θ_o), with a standard error, or the
//! statement that the data cannot pin a parameter down.
//!
//! # Objective
//!
//! For configurations c = 1 … K with measured slice m_c and simulated slice
//! s_c(θ) (same pixel grid, 1/(m² sr)):
//!
//! * `sum`: J = (1/K) Σ_c (Σ s_c / Σ m_c − 1)², the relative error of the
//!   slice sums (the lab's own comparison);
//! * `msre`: J = (1/K) Σ_c MSRE_c, the mean squared relative error over the
//!   measured pixels above `threshold` × max m_c (as [`crate::bssrdf::compare`]).
//!
//! # Method
//!
//! The objective is a Monte Carlo estimate. Every evaluation uses **common
//! random numbers**: the same seed and the same number of light paths per
//! configuration, so path k draws the same random numbers at every
//! parameter value and the objective is a smooth function of the parameter
//! plus a small noise that hardly changes from one evaluation to the next.
//! The path count of each configuration comes from a pilot run at the
//! start values to the target relative error of the slice sum
//! (`rel_error`); the search far from the optimum uses a quarter of it
//! (twice the error), the final points the full count.
//!
//! * **One parameter**: bracketing by golden-ratio expansion and golden-
//!   section search ([`search::golden_bracket_search`]) in x = ln p (the
//!   parameters are positive and act multiplicatively), to a bracket of
//!   width `x_tol`; then five points x̂ + kδ, k = −2 … 2, at the full path
//!   count and a least-squares parabola through them ([`search::quadratic_fit`]);
//!   its vertex is the estimate. A derivative-free bracketed search was
//!   chosen over gradient methods because finite differences of a Monte
//!   Carlo objective are unreliable at small steps, and over a surrogate
//!   because in one dimension golden section needs only ~10 evaluations.
//! * **Several parameters**: Nelder–Mead ([`search::nelder_mead`]) in the
//!   same log coordinates at the full path count; standard errors from a
//!   quadratic surface fitted to the evaluated points nearest the best
//!   (SE_i² = 2σ_m²/K · (H⁻¹)_ii with H the Hessian of J), and
//!   "unidentifiable" when that surface is not positive definite.
//!
//! **Speed.** For a weight-percentage fit the optics are not recomputed:
//! μ_s, μ_a (every absorption model, including the host term
//! (1 − Σφ)·4πκ_h/λ), n_bulk, μ_s·g and μ_s·p(θ) are all affine in the
//! volume fraction φ, and φ is linear in w ([`crate::optics::bulk`]), so two
//! Lorenz–Mie computations (at w₀ and 2w₀) give them exactly at any w
//! ([`WeightScaling`], tested against direct computation). The slab
//! simulation dominates the cost. The top surface is smooth.
//!
//! # Standard error
//!
//! The measured slices carry a relative uncertainty σ_m (`measured_rel_sd`,
//! the lab states 5 %) that acts as a scale error of each slice, and the
//! simulated ones a Monte Carlo error σ_MC,c (the relative standard error of
//! their sums). The standard error is a parametric bootstrap through the
//! local parabola: 400 times, each measured slice is scaled by
//! 1 + √(σ_m² + σ_MC,c²)·z_c (z_c standard normal), the objective is
//! recomputed at the five final points from the stored slices (no new
//! simulation) and the parabola's vertex taken; the standard deviation of
//! the vertices is the standard error of x = ln p, and the error of p is
//! p·SE_x. For `sum` this is the least-squares curvature error
//! SE² = σ²/Σ_c (∂ ln s_c/∂x)², computed the same way for either objective.
//! With K ≥ 3 configurations a bootstrap over the configurations
//! (resampled with replacement) is reported as well, and the larger of the
//! two is the `std_error`. The 95 % interval is exp(x̂ ± 1.96 SE_x).
//!
//! # Unidentifiable parameters
//!
//! In units of the data's uncertainty the objective is χ² ≈ K·J/σ_m². The
//! fit reports that the data cannot pin a parameter down — `identifiable =
//! false`, no value — when χ² changes by less than 1 over the whole search
//! range (tested at both bounds when the objective is flat around the
//! start), when the final parabola is not convex or the bootstrap's
//! vertices are not, when the 95 % interval is wider than the search range,
//! or when the minimum lies at a bound.
//!
//! ```no_run
//! use lucent::fit::{self, FreeParameter, Measurement, Problem};
//! use lucent::optics::recipe::{Overrides, Recipe};
//! let recipe = Recipe::load("fixtures/samples/IOL1068-09.toml".as_ref(), Overrides::default()).unwrap();
//! let m = Measurement::load("measured_45_0.exr".as_ref(), Some(0.1029), (45.0, 0.0, 0.0, 180.0)).unwrap();
//! let problem = Problem::new(recipe, 550.0, vec![FreeParameter::weight_percent(0)], vec![m]).unwrap();
//! let r = fit::fit(&problem, |e| eprintln!("{e}")).unwrap();
//! println!("{:?} ± {:?}", r.parameters[0].value, r.parameters[0].std_error);
//! ```

pub mod report;
pub mod search;

use crate::bssrdf::{self, Grid, SliceIoError};
use crate::optics::bulk::{self, OpticsError};
use crate::optics::recipe::{MediumRef, Recipe, RecipeError};
use lucent_render::phase::{Phase, PhaseError, PhaseTable};
use lucent_render::rng::Rng;
use lucent_render::slab::{
    self, Beam, Directions, Estimator, Medium, RunOptions, Sensor, Setup, Slab, SlabError, Stop,
};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Why a fit could not be made.
#[derive(Debug, thiserror::Error)]
pub enum FitError {
    #[error(transparent)]
    Recipe(#[from] RecipeError),
    #[error(transparent)]
    Optics(#[from] OpticsError),
    #[error(transparent)]
    Slice(#[from] SliceIoError),
    #[error("slab simulation: {0}")]
    Slab(#[from] SlabError),
    #[error("medium: {0}")]
    Medium(#[from] lucent_render::medium::MediumError),
    #[error("phase table: {0}")]
    Phase(#[from] PhaseError),
    /// `--free NAME` without `@K` for a recipe of several particle types.
    #[error("{}: the recipe has {count} particle types; say which, e.g. {name}@1 … {name}@{count}", recipe.display())]
    WhichParticle { recipe: PathBuf, name: String, count: usize },
    /// `--free NAME@K` with K not a particle type of the recipe.
    #[error("{text:?}: the particle type must be 1 … {count} (the recipe's [[particles]] in order)")]
    ParticleNumber { text: String, count: usize },
    /// A particle type (0-based `particle`) the recipe does not have.
    #[error("particle type {} does not exist in the recipe", particle + 1)]
    NoParticle { particle: usize },
    /// The refractive index of a particle type at the fit wavelength.
    #[error("particle {particle} index: {source}")]
    Index { particle: String, source: Box<crate::optics::index::IndexError> },
    /// A measured slice's configuration that is not a valid direction pair.
    #[error("{}: configuration {theta_i}/{theta_o}: {source}", path.display())]
    Configuration { path: PathBuf, theta_i: f64, theta_o: f64, source: Box<SlabError> },
    /// A measured slice without light.
    #[error("{}: the measured slice has no positive sum ({sum})", path.display())]
    EmptySlice { path: PathBuf, sum: f64 },
    /// A setting outside its range: "`what` `value``unit` must `rule`".
    #[error("{what} {value}{unit} must {rule}")]
    Setting { what: &'static str, value: f64, unit: &'static str, rule: &'static str },
    #[error("no free parameter (--free weight_percent, diameter_um or real_part_n)")]
    NoFreeParameter,
    #[error("free parameter {label} given twice")]
    RepeatedParameter { label: String },
    #[error("no measured slice (--measured FILE[:THETA_I/THETA_O])")]
    NoMeasurement,
    #[error("{bounds} bounds entries for {free} free parameters: one per free parameter")]
    BoundsCount { bounds: usize, free: usize },
    #[error("bounds [{lo}, {hi}] of {name} must be positive, increasing and contain the start value {start}")]
    Bounds { name: &'static str, lo: f64, hi: f64, start: f64 },
    /// [`fit_cancellable`]'s flag was raised (Ctrl-C): no result.
    #[error("interrupted: the fit stopped after {evaluations} evaluation(s), without a result")]
    Interrupted { evaluations: usize },
}

/// Why the final model of a one-parameter fit gives no value: the data
/// cannot pin the parameter down ([`FitResult::reason`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Undetermined {
    #[error("the slice sums do not change significantly over {lo:.5} … {hi:.5} (slope / standard error = {t:.2})")]
    FlatSums { lo: f64, hi: f64, t: f64 },
    #[error(
        "the objective has no minimum near {near:.5} (flat within the Monte Carlo noise, or falling towards a bound)"
    )]
    NoMinimum { near: f64 },
    #[error("in {failed} of {draws} bootstrap draws of the data's uncertainty the objective had no minimum within the search range")]
    Bootstrap { failed: usize, draws: usize },
    #[error("the minimum moved by more than the final points' span twice")]
    Moved,
}

/// The kind of a free parameter: the closed set of recipe values a fit can
/// free, named as `--free` and `[fit] free` spell them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
#[derive(strum::EnumString, strum::IntoStaticStr, strum::VariantNames, strum::VariantArray)]
#[strum(serialize_all = "snake_case")]
pub enum ParameterKind {
    /// A particle type's weight percentage.
    WeightPercent,
    /// A particle type's nominal diameter in µm ([`Recipe::diameter_um`]).
    DiameterUm,
    /// A particle type's real refractive index at the fit wavelength
    /// (the index data shifted, dispersion and κ kept).
    RealPartN,
}

impl ParameterKind {
    /// The name `--free` takes.
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// All kinds, for messages listing the valid names.
    pub const ALL: [ParameterKind; 3] =
        [ParameterKind::WeightPercent, ParameterKind::DiameterUm, ParameterKind::RealPartN];
}

/// A free parameter as `--free` and `[fit] free` name it: its kind and,
/// for a recipe of several particle types, which one (1-based K of
/// `NAME@K`; checked against the recipe by [`FreeParameter::of`]).
///
/// As text "NAME" or "NAME@K", e.g. "weight_percent" or "diameter_um@2".
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FreeSpec {
    pub kind: ParameterKind,
    /// K of `NAME@K` (1 = the recipe's first `[[particles]]`); None: the
    /// recipe's only particle type.
    pub particle: Option<usize>,
}

/// A free parameter written as text that is not one ([`FreeSpec`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FreeSpecError {
    #[error(
        "unknown free parameter {text:?} (valid: {}; NAME@K for particle type K)",
        ParameterKind::ALL.map(|k| k.name()).join(", ")
    )]
    Name { text: String },
    #[error("{text:?}: the particle type K of NAME@K must be a whole number from 1")]
    Particle { text: String },
}

impl std::str::FromStr for FreeSpec {
    type Err = FreeSpecError;

    fn from_str(text: &str) -> Result<Self, FreeSpecError> {
        let (name, which) = match text.split_once('@') {
            Some((n, k)) => (n.trim(), Some(k.trim())),
            None => (text.trim(), None),
        };
        let kind = name.parse().map_err(|_| FreeSpecError::Name { text: text.to_string() })?;
        let particle = match which {
            None => None,
            Some(k) => match k.parse::<usize>() {
                Ok(k) if k >= 1 => Some(k),
                _ => return Err(FreeSpecError::Particle { text: text.to_string() }),
            },
        };
        Ok(FreeSpec { kind, particle })
    }
}

impl std::fmt::Display for FreeSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.particle {
            Some(k) => write!(f, "{}@{k}", self.kind.name()),
            None => f.write_str(self.kind.name()),
        }
    }
}

crate::text::serde_as_text!(FreeSpec);

/// The search range of one free parameter, in its natural unit (wt-%, µm,
/// or the index): `lo` … `hi`, both finite. Whether it is positive,
/// increasing and holds the start value is the fit's check
/// ([`Problem::validate`]), which knows the start value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SearchRange {
    pub lo: f64,
    pub hi: f64,
}

/// Search ranges, one per free parameter in `--free`'s order.
///
/// As text "LO:HI,LO:HI,…", e.g. "0.1:2,0.5:5".
#[derive(Debug, Clone, PartialEq)]
pub struct SearchBounds(pub Vec<SearchRange>);

/// Search bounds written as text that are not ([`SearchBounds`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SearchBoundsError {
    #[error("{text:?}: expected LO:HI, got {part:?}")]
    Syntax { text: String, part: String },
    #[error("{text:?}: {number:?} is not a finite number")]
    Number { text: String, number: String },
}

impl std::str::FromStr for SearchBounds {
    type Err = SearchBoundsError;

    fn from_str(text: &str) -> Result<Self, SearchBoundsError> {
        let range = |part: &str| {
            let (a, b) = part
                .split_once(':')
                .ok_or_else(|| SearchBoundsError::Syntax { text: text.to_string(), part: part.to_string() })?;
            let num = |s: &str| {
                s.trim()
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite())
                    .ok_or_else(|| SearchBoundsError::Number { text: text.to_string(), number: s.to_string() })
            };
            Ok(SearchRange { lo: num(a)?, hi: num(b)? })
        };
        text.split(',').map(range).collect::<Result<_, _>>().map(SearchBounds)
    }
}

impl std::fmt::Display for SearchBounds {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let words: Vec<String> = self.0.iter().map(|r| format!("{}:{}", r.lo, r.hi)).collect();
        f.write_str(&words.join(","))
    }
}

crate::text::serde_as_text!(SearchBounds);

/// A free parameter: its kind and the particle type (0-based) it belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
pub struct FreeParameter {
    pub kind: ParameterKind,
    pub particle: usize,
}

impl FreeParameter {
    pub fn weight_percent(particle: usize) -> Self {
        Self { kind: ParameterKind::WeightPercent, particle }
    }

    /// The parameter `spec` names in `recipe` (its `@K` required when the
    /// recipe has several particle types, and one of them).
    pub fn of(spec: FreeSpec, recipe: &Recipe) -> Result<Self, FitError> {
        let count = recipe.particles.len();
        let particle = match spec.particle {
            None if count == 1 => 0,
            None => {
                return Err(FitError::WhichParticle {
                    recipe: recipe.path.clone(),
                    name: spec.kind.name().to_string(),
                    count,
                });
            }
            Some(k) if (1..=count).contains(&k) => k - 1,
            Some(_) => return Err(FitError::ParticleNumber { text: spec.to_string(), count }),
        };
        Ok(Self { kind: spec.kind, particle })
    }

    /// `NAME` or `NAME@K` for a recipe with `particles` types.
    pub fn label(&self, particles: usize) -> String {
        if particles > 1 {
            format!("{}@{}", self.kind.name(), self.particle + 1)
        } else {
            self.kind.name().to_string()
        }
    }

    /// The parameter's value in `recipe` at `wavelength_nm`.
    pub fn value_in(&self, recipe: &Recipe, wavelength_nm: f64) -> Result<f64, FitError> {
        let p = recipe.particles.get(self.particle).ok_or(FitError::NoParticle { particle: self.particle })?;
        Ok(match self.kind {
            ParameterKind::WeightPercent => p.weight_percent,
            ParameterKind::DiameterUm => recipe.diameter_um(self.particle).unwrap_or(f64::NAN),
            ParameterKind::RealPartN => {
                p.medium
                    .index
                    .at(wavelength_nm, p.medium.extrapolation)
                    .map_err(|e| FitError::Index { particle: p.medium.name.clone(), source: Box::new(e) })?
                    .index
                    .re
            }
        })
    }

    /// `recipe` with this parameter set to `value`.
    pub fn apply(&self, recipe: &Recipe, value: f64, wavelength_nm: f64) -> Result<Recipe, FitError> {
        Ok(match self.kind {
            ParameterKind::WeightPercent => recipe.with_weight_percent(self.particle, value)?,
            ParameterKind::DiameterUm => recipe.with_diameter_um(self.particle, value)?,
            ParameterKind::RealPartN => {
                recipe.with_real_part(MediumRef::Particle(self.particle), wavelength_nm, value)?
            }
        })
    }

    /// Default search bounds around the start value.
    fn default_bounds(&self, start: f64, recipe: &Recipe) -> (f64, f64) {
        match self.kind {
            ParameterKind::WeightPercent => {
                // Keep the volume fraction of all types below 0.5.
                let p = &recipe.particles[self.particle];
                let others = recipe.particle_volume_fraction() - p.volume_fraction;
                let w_max = ((0.5 - others).max(0.0) * p.weight_percent / p.volume_fraction).min(99.0);
                (start / 10.0, (start * 10.0).min(w_max))
            }
            ParameterKind::DiameterUm => (start / 10.0, start * 10.0),
            ParameterKind::RealPartN => (start / 1.2, start * 1.2),
        }
    }

    /// Initial step in ln p.
    fn step(&self) -> f64 {
        match self.kind {
            ParameterKind::WeightPercent | ParameterKind::DiameterUm => 0.15,
            ParameterKind::RealPartN => 0.005,
        }
    }
}

/// A measured slice and its configuration.
#[derive(Debug, Clone)]
pub struct Measurement {
    pub path: PathBuf,
    pub grid: Grid,
    pub directions: Directions,
}

impl Measurement {
    /// Reads a measured slice (EXR, float TIFF or CSV; see
    /// [`bssrdf::read_grid`]) taken at (θ_i, φ_i, θ_o, φ_o) in degrees.
    pub fn load(path: &Path, pixel_mm: Option<f64>, angles: (f64, f64, f64, f64)) -> Result<Self, FitError> {
        Self::load_at(path, pixel_mm, angles, None)
    }

    /// [`Measurement::load`] for a fit at `wavelength_nm`: a slice with a
    /// negative pixel, or whose sidecar says it was taken at another
    /// wavelength or other angles, is refused ([`bssrdf::check_measured`]).
    pub fn load_at(
        path: &Path,
        pixel_mm: Option<f64>,
        angles: (f64, f64, f64, f64),
        wavelength_nm: Option<f64>,
    ) -> Result<Self, FitError> {
        let grid = bssrdf::read_grid(path, pixel_mm)?;
        bssrdf::check_measured(path, &grid, wavelength_nm, Some(angles))?;
        Self::new(path, grid, angles)
    }

    /// A measurement from a grid already in memory; `path` names it.
    pub fn new(path: &Path, grid: Grid, (ti, pi, to, po): (f64, f64, f64, f64)) -> Result<Self, FitError> {
        let directions = Directions::from_degrees(ti, pi, to, po).map_err(|e| FitError::Configuration {
            path: path.to_path_buf(),
            theta_i: ti,
            theta_o: to,
            source: Box::new(e),
        })?;
        if grid.sum().is_nan() || grid.sum() <= 0.0 {
            return Err(FitError::EmptySlice { path: path.to_path_buf(), sum: grid.sum() });
        }
        Ok(Self { path: path.to_path_buf(), grid, directions })
    }
}

/// The objective (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(strum::EnumString, strum::IntoStaticStr, strum::VariantNames, strum::VariantArray, strum::EnumMessage)]
#[strum(serialize_all = "kebab-case", ascii_case_insensitive)]
pub enum Objective {
    /// Relative error of the slice sums, squared, mean over configurations.
    Sum,
    /// Mean squared relative error over the measured pixels above the threshold.
    Msre,
}

impl Objective {
    /// The name files and flags use.
    pub fn name(self) -> &'static str {
        self.into()
    }
}

/// How many paths the simulations get.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    /// Target relative standard error of each slice sum at the final points
    /// (the pilot run sets the path count from it).
    pub rel_error: f64,
    /// Cap on the pilot run per configuration, seconds.
    pub pilot_time_s: f64,
    /// Path count per configuration instead of a pilot run.
    pub paths: Option<u64>,
    /// Fraction of the path count used while searching far from the optimum.
    pub explore_fraction: f64,
}

impl Default for Budget {
    fn default() -> Self {
        Self { rel_error: 0.005, pilot_time_s: 60.0, paths: None, explore_fraction: 0.25 }
    }
}

/// Everything a fit needs.
#[derive(Debug, Clone)]
pub struct Problem {
    pub recipe: Recipe,
    pub wavelength_nm: f64,
    pub free: Vec<FreeParameter>,
    pub measurements: Vec<Measurement>,
    pub beam: Beam,
    pub objective: Objective,
    /// Mask threshold of the `msre` objective (fraction of the measured maximum).
    pub threshold: f64,
    /// Relative uncertainty of each measured slice (a scale error), e.g. 0.05.
    pub measured_rel_sd: f64,
    pub seed: u64,
    pub budget: Budget,
    /// Search bounds per free parameter (natural units); default: start/10 …
    /// start·10 (real index: start/1.2 … start·1.2).
    pub bounds: Vec<Option<(f64, f64)>>,
    /// Slab thickness \[m\] (default: the recipe's).
    pub thickness_m: f64,
    /// Width of the final golden-section bracket in ln p.
    pub x_tol: f64,
}

impl Problem {
    /// A problem with the defaults: 200 µm Gaussian beam, `sum` objective,
    /// threshold 0.01, σ_m = 0.05, seed 1, the default budget.
    pub fn new(
        recipe: Recipe,
        wavelength_nm: f64,
        free: Vec<FreeParameter>,
        measurements: Vec<Measurement>,
    ) -> Result<Self, FitError> {
        let thickness_m = recipe.thickness_m;
        let p = Self {
            bounds: vec![None; free.len()],
            recipe,
            wavelength_nm,
            free,
            measurements,
            beam: Beam::gaussian(200e-6)?,
            objective: Objective::Sum,
            threshold: 0.01,
            measured_rel_sd: 0.05,
            seed: 1,
            budget: Budget::default(),
            thickness_m,
            x_tol: 0.05,
        };
        p.validate()?;
        Ok(p)
    }

    /// Checks every input before any work is done.
    pub fn validate(&self) -> Result<(), FitError> {
        let setting = |what, value, unit, rule| Err(FitError::Setting { what, value, unit, rule });
        if self.free.is_empty() {
            return Err(FitError::NoFreeParameter);
        }
        if !(self.wavelength_nm.is_finite() && self.wavelength_nm > 0.0) {
            return setting("wavelength", self.wavelength_nm, " nm", "be positive");
        }
        for (i, a) in self.free.iter().enumerate() {
            if self.free[..i].contains(a) {
                return Err(FitError::RepeatedParameter { label: a.label(self.recipe.particles.len()) });
            }
            a.value_in(&self.recipe, self.wavelength_nm)?;
        }
        if self.measurements.is_empty() {
            return Err(FitError::NoMeasurement);
        }
        if !(self.measured_rel_sd.is_finite() && self.measured_rel_sd > 0.0 && self.measured_rel_sd < 1.0) {
            return setting("measured relative uncertainty", self.measured_rel_sd, "", "lie in (0, 1)");
        }
        if !(self.threshold.is_finite() && (0.0..1.0).contains(&self.threshold)) {
            return setting("threshold", self.threshold, "", "lie in [0, 1)");
        }
        let b = &self.budget;
        if !(b.rel_error.is_finite() && b.rel_error > 0.0 && b.rel_error < 0.5) {
            return setting("target relative error", b.rel_error, "", "lie in (0, 0.5)");
        }
        if !(b.pilot_time_s.is_finite() && b.pilot_time_s > 0.0) {
            return setting("pilot time", b.pilot_time_s, " s", "be positive");
        }
        if b.paths == Some(0) {
            return setting("paths per evaluation", 0.0, "", "be positive");
        }
        if let Some(n) = b.paths
            && n > crate::bssrdf::MAX_PATHS
        {
            return setting(
                "paths per evaluation",
                n as f64,
                "",
                "be at most 10^12 (the most light paths any command takes)",
            );
        }
        if !(b.explore_fraction > 0.0 && b.explore_fraction <= 1.0) {
            return setting("explore fraction", b.explore_fraction, "", "lie in (0, 1]");
        }
        if !(self.thickness_m.is_finite() && self.thickness_m > 0.0) {
            return setting("thickness", self.thickness_m, " m", "be positive");
        }
        if !(self.x_tol.is_finite() && self.x_tol > 0.0) {
            return setting("x_tol", self.x_tol, "", "be positive");
        }
        if self.bounds.len() != self.free.len() {
            return Err(FitError::BoundsCount { bounds: self.bounds.len(), free: self.free.len() });
        }
        for (a, b) in self.free.iter().zip(&self.bounds) {
            let start = a.value_in(&self.recipe, self.wavelength_nm)?;
            if let Some((lo, hi)) = b
                && !(lo.is_finite() && hi.is_finite() && *lo > 0.0 && lo < hi && (*lo..=*hi).contains(&start))
            {
                return Err(FitError::Bounds { name: a.kind.name(), lo: *lo, hi: *hi, start });
            }
        }
        Ok(())
    }
}

/// The optics of the recipe at one wavelength as a function of the free
/// parameters: affine for a lone weight percentage, else Lorenz–Mie anew.
enum OpticsModel {
    Linear(Box<WeightScaling>),
    Direct,
}

/// The bulk properties μ_s, μ_a, n_bulk, μ_s·g and μ_s·p(θ) of a recipe are
/// affine in one particle type's weight percentage w (see the module doc):
/// from two computations at w_a and w_b every w follows exactly.
#[derive(Debug, Clone)]
pub struct WeightScaling {
    w_a: f64,
    a: bulk::Sample,
    w_b: f64,
    b: bulk::Sample,
}

/// Bulk properties at one wavelength, as the simulator takes them.
#[derive(Debug, Clone)]
pub struct Optics {
    pub mu_s_per_m: f64,
    pub mu_a_per_m: f64,
    pub g: f64,
    pub n_bulk: f64,
    /// Phase function at θ_i = iπ/(N − 1) (any scale).
    pub phase: Vec<f64>,
}

impl WeightScaling {
    /// The two computations at `w_a` = the recipe's w and `w_b` = 2 w_a of
    /// particle type `particle`; `None` when the `mie` absorption model
    /// clamped μ_a to 0 at either (not affine there).
    pub fn new(recipe: &Recipe, particle: usize, wavelength_nm: f64) -> Result<Option<Self>, FitError> {
        let options = bulk::Options::default();
        let w_a = recipe.particles.get(particle).ok_or(FitError::NoParticle { particle })?.weight_percent;
        let a = bulk::at_wavelength(recipe, wavelength_nm, &options)?;
        let w_b = if recipe.with_weight_percent(particle, 2.0 * w_a).is_ok() { 2.0 * w_a } else { 0.5 * w_a };
        let b = bulk::at_wavelength(&recipe.with_weight_percent(particle, w_b)?, wavelength_nm, &options)?;
        let clamped = |s: &bulk::Sample| s.warnings.iter().any(|w| w.contains("negative"));
        if clamped(&a) || clamped(&b) || a.mu_s_per_m <= 0.0 {
            return Ok(None);
        }
        Ok(Some(Self { w_a, a, w_b, b }))
    }

    /// The properties at weight percentage `w`.
    pub fn at(&self, w: f64) -> Optics {
        let t = (w - self.w_a) / (self.w_b - self.w_a);
        let lerp = |x: f64, y: f64| x + t * (y - x);
        let mu_s = lerp(self.a.mu_s_per_m, self.b.mu_s_per_m);
        let g_mu_s = lerp(self.a.g * self.a.mu_s_per_m, self.b.g * self.b.mu_s_per_m);
        let phase = self
            .a
            .phase
            .iter()
            .zip(&self.b.phase)
            .map(|(pa, pb)| lerp(pa * self.a.mu_s_per_m, pb * self.b.mu_s_per_m).max(0.0) / mu_s)
            .collect();
        Optics {
            mu_s_per_m: mu_s,
            mu_a_per_m: lerp(self.a.mu_a_per_m, self.b.mu_a_per_m).max(0.0),
            g: g_mu_s / mu_s,
            n_bulk: lerp(self.a.n_bulk, self.b.n_bulk),
            phase,
        }
    }
}

impl OpticsModel {
    fn at(&self, problem: &Problem, values: &[f64]) -> Result<Optics, FitError> {
        match self {
            OpticsModel::Linear(s) => Ok(s.at(values[0])),
            OpticsModel::Direct => {
                let mut r = problem.recipe.clone();
                for (a, v) in problem.free.iter().zip(values) {
                    r = a.apply(&r, *v, problem.wavelength_nm)?;
                }
                let s = bulk::at_wavelength(&r, problem.wavelength_nm, &bulk::Options::default())?;
                Ok(Optics {
                    mu_s_per_m: s.mu_s_per_m,
                    mu_a_per_m: s.mu_a_per_m,
                    g: s.g,
                    n_bulk: s.n_bulk,
                    phase: s.phase,
                })
            }
        }
    }
}

/// One evaluation of the objective.
#[derive(Debug, Clone, Serialize)]
pub struct Evaluation {
    /// Parameter values (natural units), in the order of `free`.
    pub values: Vec<f64>,
    pub objective: f64,
    /// "pilot", "search" or "final".
    pub stage: &'static str,
    /// Per configuration: simulated sum / measured sum.
    pub sum_ratio: Vec<f64>,
    /// Per configuration: relative standard error of the simulated sum.
    pub sum_rel_error: Vec<f64>,
    /// Per configuration: mean squared relative error over the mask.
    pub msre: Vec<f64>,
    pub mu_s_per_m: f64,
    pub mu_a_per_m: f64,
    pub g: f64,
    pub n_bulk: f64,
    pub wall_s: f64,
    /// The simulated slices (kept for the final points only).
    #[serde(skip)]
    pub slices: Option<Vec<Vec<f64>>>,
}

/// The result for one free parameter.
#[derive(Debug, Clone, Serialize)]
pub struct ParameterResult {
    pub name: String,
    pub particle: String,
    pub start: f64,
    /// The fitted value; `None` when the data cannot pin the parameter down.
    pub value: Option<f64>,
    /// The standard error used (the larger of the two below when both exist).
    pub std_error: Option<f64>,
    /// From the measurement and Monte Carlo uncertainty through the local
    /// parabola (parametric bootstrap; see the module doc).
    pub std_error_measurement: Option<f64>,
    /// Bootstrap over the configurations (K ≥ 3).
    pub std_error_bootstrap_configurations: Option<f64>,
    /// 95 % interval exp(x̂ ± 1.96 SE_x).
    pub interval_95: Option<[f64; 2]>,
    pub bounds: [f64; 2],
}

/// Per-configuration summary at the start and at the fitted values.
#[derive(Debug, Clone, Serialize)]
pub struct ConfigResult {
    pub file: String,
    pub theta_i_deg: f64,
    pub phi_i_deg: f64,
    pub theta_o_deg: f64,
    pub phi_o_deg: f64,
    pub pixels: usize,
    pub pixel_mm: f64,
    pub estimator: &'static str,
    pub paths_per_evaluation: u64,
    pub measured_sum: f64,
    pub sum_ratio_start: f64,
    pub sum_ratio_end: Option<f64>,
    pub msre_start: f64,
    pub msre_end: Option<f64>,
}

/// What a fit found.
#[derive(Debug, Clone, Serialize)]
pub struct FitResult {
    pub recipe: String,
    pub wavelength_nm: f64,
    pub objective: Objective,
    pub method: String,
    pub parameters: Vec<ParameterResult>,
    /// Whether the data pin the parameters down; if not, `reason` says why
    /// and no values are given.
    pub identifiable: bool,
    pub reason: Option<String>,
    pub objective_start: f64,
    /// Objective at the fitted values (the parabola at its vertex for one
    /// parameter, the best point for several).
    pub objective_end: Option<f64>,
    /// χ² span max − min of K·J/σ_m² over the evaluated points.
    pub chi2_span: f64,
    pub measured_rel_sd: f64,
    pub evaluations: usize,
    pub paths_total: u64,
    pub wall_s: f64,
    pub seed: u64,
    pub optics: &'static str,
    /// The local model of the objective through the final points, as
    /// [parameter value, J] pairs (one parameter; for the plot).
    pub model_curve: Vec<[f64; 2]>,
    pub configurations: Vec<ConfigResult>,
    pub history: Vec<Evaluation>,
    /// The simulated slices per configuration at the recipe (the pilot) and
    /// at the fitted values (identifiable fits), f_ssr in 1/(m² sr) on the
    /// measured slices' pixels, for the profile plots.
    #[serde(skip)]
    pub slices_start: Vec<Vec<f64>>,
    #[serde(skip)]
    pub slices_end: Option<Vec<Vec<f64>>>,
}

/// Progress messages of a fit (one line each).
pub type Event = String;

struct Evaluator<'a> {
    problem: &'a Problem,
    model: OpticsModel,
    setups: Vec<Setup>,
    estimators: Vec<Estimator>,
    paths: Vec<u64>,
    history: Vec<Evaluation>,
    paths_total: u64,
    /// Raised to stop: the simulation under way ends at its next round and
    /// the evaluation fails with [`FitError::Interrupted`].
    cancel: &'a AtomicBool,
}

/// Objective of simulated slices `sims` against the measurements of
/// `configs`, measured slice c scaled by `scale[c]`.
fn objective_of(problem: &Problem, sims: &[&[f64]], scale: &[f64], configs: &[usize]) -> f64 {
    let mut acc = 0.0;
    for &c in configs {
        let m = &problem.measurements[c].grid;
        let s = sims[c];
        acc += match problem.objective {
            Objective::Sum => {
                let r = s.iter().sum::<f64>() / (m.sum() * scale[c]) - 1.0;
                r * r
            }
            Objective::Msre => msre(&m.values, s, problem.threshold, scale[c]),
        };
    }
    acc / configs.len() as f64
}

fn msre(measured: &[f64], sim: &[f64], threshold: f64, scale: f64) -> f64 {
    let max = measured.iter().copied().fold(0.0, f64::max);
    let cut = threshold * max;
    let (mut acc, mut n) = (0.0, 0usize);
    for (m, s) in measured.iter().zip(sim) {
        if *m > cut && *m > 0.0 {
            let r = s / (m * scale) - 1.0;
            acc += r * r;
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        acc / n as f64
    }
}

impl<'a> Evaluator<'a> {
    fn new(problem: &'a Problem, cancel: &'a AtomicBool) -> Result<Self, FitError> {
        let model = match problem.free.as_slice() {
            [a] if a.kind == ParameterKind::WeightPercent => {
                match WeightScaling::new(&problem.recipe, a.particle, problem.wavelength_nm)? {
                    Some(s) => OpticsModel::Linear(Box::new(s)),
                    None => OpticsModel::Direct,
                }
            }
            _ => OpticsModel::Direct,
        };
        // Placeholder medium; replaced at each evaluation.
        let placeholder = Medium::new(1.0, 0.0, Phase::henyey_greenstein(0.0)?, 1.5)?;
        let mut setups = Vec::new();
        for m in &problem.measurements {
            let sensor = Sensor::new(m.grid.size, m.grid.pixel_m)?;
            setups.push(Setup::new(
                Slab::new(problem.thickness_m, placeholder.clone())?,
                problem.beam.clone(),
                sensor,
                m.directions,
            ));
        }
        Ok(Self {
            problem,
            model,
            estimators: Vec::new(),
            paths: vec![0; setups.len()],
            setups,
            history: Vec::new(),
            paths_total: 0,
            cancel,
        })
    }

    /// Simulates every configuration at `values`; `stops` per configuration.
    fn evaluate(
        &mut self,
        values: &[f64],
        stage: &'static str,
        stops: &[Stop],
        keep: bool,
    ) -> Result<Evaluation, FitError> {
        let start = Instant::now();
        let o = self.model.at(self.problem, values)?;
        let phase = Phase::Tabulated(PhaseTable::from_theta_samples(&o.phase)?);
        let medium = Medium::new(o.mu_s_per_m, o.mu_a_per_m, phase, o.n_bulk.max(1.0))?;
        let mut sims = Vec::new();
        let mut rel = Vec::new();
        for (c, setup) in self.setups.iter_mut().enumerate() {
            setup.slab.medium = medium.clone();
            // The estimator is chosen once (at the pilot) so every
            // evaluation consumes the random numbers the same way — unless
            // the search moved to a medium it does not apply to (a thin
            // slab for the ring or lobe connection, e.g. a free diameter):
            // there the best one that applies is used (same expectation,
            // other noise).
            if self.estimators.len() <= c {
                self.estimators.push(Estimator::best_for(setup));
            }
            let estimator = match self.estimators[c] {
                e if e.applies(setup) => e,
                _ => Estimator::best_for(setup),
            };
            let options =
                RunOptions { stop: stops[c], seed: self.problem.seed, estimator, fold: true, ..RunOptions::default() };
            let slice = slab::simulate_cancellable(setup, &options, |_| {}, self.cancel)?;
            if self.cancel.load(Ordering::Relaxed) {
                return Err(FitError::Interrupted { evaluations: self.history.len() });
            }
            if stage == "pilot" {
                self.paths[c] = slice.paths;
            }
            self.paths_total += slice.paths;
            rel.push(if slice.sum > 0.0 { slice.sum_std_error / slice.sum } else { f64::INFINITY });
            sims.push(slice.values);
        }
        let refs: Vec<&[f64]> = sims.iter().map(|s| s.as_slice()).collect();
        let k = self.problem.measurements.len();
        let all: Vec<usize> = (0..k).collect();
        let objective = objective_of(self.problem, &refs, &vec![1.0; k], &all);
        let ms = &self.problem.measurements;
        let e = Evaluation {
            values: values.to_vec(),
            objective,
            stage,
            sum_ratio: (0..k).map(|c| refs[c].iter().sum::<f64>() / ms[c].grid.sum()).collect(),
            sum_rel_error: rel,
            msre: (0..k).map(|c| msre(&ms[c].grid.values, refs[c], self.problem.threshold, 1.0)).collect(),
            mu_s_per_m: o.mu_s_per_m,
            mu_a_per_m: o.mu_a_per_m,
            g: o.g,
            n_bulk: o.n_bulk,
            wall_s: start.elapsed().as_secs_f64(),
            slices: if keep { Some(sims) } else { None },
        };
        let mut stored = e.clone();
        stored.slices = None;
        self.history.push(stored);
        Ok(e)
    }

    fn stops(&self, fraction: f64) -> Vec<Stop> {
        self.paths.iter().map(|&n| Stop::samples(((n as f64 * fraction).ceil() as u64).max(256))).collect()
    }
}

/// Runs the fit; `progress` receives one line per evaluation.
pub fn fit(problem: &Problem, progress: impl FnMut(&Event)) -> Result<FitResult, FitError> {
    fit_cancellable(problem, progress, &AtomicBool::new(false))
}

/// [`fit`] that stops with [`FitError::Interrupted`] soon after `cancel`
/// becomes true (at the end of the simulation round under way).
pub fn fit_cancellable(
    problem: &Problem,
    mut progress: impl FnMut(&Event),
    cancel: &AtomicBool,
) -> Result<FitResult, FitError> {
    problem.validate()?;
    let start = Instant::now();
    let mut ev = Evaluator::new(problem, cancel)?;
    let starts: Vec<f64> =
        problem.free.iter().map(|a| a.value_in(&problem.recipe, problem.wavelength_nm)).collect::<Result<_, _>>()?;
    let bounds: Vec<(f64, f64)> = problem
        .free
        .iter()
        .zip(&problem.bounds)
        .zip(&starts)
        .map(|((a, b), s)| b.unwrap_or_else(|| a.default_bounds(*s, &problem.recipe)))
        .collect();
    let k = problem.measurements.len();

    // Pilot: the path count per configuration for the target error.
    let pilot_stops: Vec<Stop> = match problem.budget.paths {
        Some(n) => vec![Stop::samples(n); k],
        None => vec![
            Stop {
                rel_error: Some(problem.budget.rel_error),
                time_s: Some(problem.budget.pilot_time_s),
                ..Stop::default()
            };
            k
        ],
    };
    let mut pilot = ev.evaluate(&starts, "pilot", &pilot_stops, true)?;
    let slices_start = pilot.slices.take().unwrap_or_default();
    progress(&format!(
        "pilot at {}: objective {:.4e}, sum ratios {}, paths per configuration {:?}",
        fmt_values(&starts),
        pilot.objective,
        fmt_list(&pilot.sum_ratio),
        ev.paths
    ));
    let stops = Stops { explore: ev.stops(problem.budget.explore_fraction), full: ev.stops(1.0) };

    let mut params = initial_parameters(problem, &starts, &bounds);
    let searched = if problem.free.len() == 1 {
        search_one(problem, &mut ev, &mut params[0], starts[0], bounds[0], &stops, &mut progress)?
    } else {
        search_many(problem, &mut ev, &mut params, &starts, &bounds, &stops.full, &mut progress)?
    };
    let Searched { identifiable, reason, model_curve, objective_end, end_values } = searched;
    if !identifiable {
        for p in &mut params {
            p.value = None;
            p.std_error = None;
            p.interval_95 = None;
        }
    }
    // Per-configuration figures at the fitted values, at the full budget.
    let end_eval = match &end_values {
        Some(v) if identifiable => Some(ev.evaluate(v, "final", &stops.full, true)?),
        _ => None,
    };
    let configurations = configurations(problem, &ev, &pilot, end_eval.as_ref());
    let objs: Vec<f64> = ev.history.iter().map(|e| e.objective).filter(|v| v.is_finite()).collect();
    let chi2_span = chi2(problem, objs.iter().copied().fold(f64::NEG_INFINITY, f64::max))
        - chi2(problem, objs.iter().copied().fold(f64::INFINITY, f64::min));
    let optics = match ev.model {
        OpticsModel::Linear(_) => "affine in the weight percentage (two Lorenz–Mie computations)",
        OpticsModel::Direct => "Lorenz–Mie at every evaluation",
    };
    Ok(FitResult {
        recipe: problem.recipe.path.display().to_string(),
        wavelength_nm: problem.wavelength_nm,
        objective: problem.objective,
        method: if problem.free.len() == 1 {
            "golden-ratio bracketing and golden-section search in ln p (common random numbers, a quarter of the paths), then a least-squares parabola through 5 points at the full path count; SE by parametric bootstrap through the parabola".into()
        } else {
            "Nelder–Mead in ln p (common random numbers, full path count); SE from a quadratic surface fitted to the points nearest the best".into()
        },
        parameters: params,
        identifiable,
        reason,
        objective_start: pilot.objective,
        objective_end,
        chi2_span,
        measured_rel_sd: problem.measured_rel_sd,
        evaluations: ev.history.len(),
        paths_total: ev.paths_total,
        wall_s: start.elapsed().as_secs_f64(),
        seed: problem.seed,
        optics,
        model_curve,
        configurations,
        history: ev.history,
        slices_start,
        slices_end: end_eval.and_then(|e| e.slices),
    })
}

/// The objective `j` as χ² in units of the measurement uncertainty.
fn chi2(problem: &Problem, j: f64) -> f64 {
    let k = problem.measurements.len();
    k as f64 * j / (problem.measured_rel_sd * problem.measured_rel_sd)
}

/// The path counts per configuration of the search (`explore`, one
/// parameter) and of the final evaluations (`full`).
struct Stops {
    explore: Vec<Stop>,
    full: Vec<Stop>,
}

/// What a search found ([`search_one`], [`search_many`]); its parameters'
/// values are set in place.
struct Searched {
    identifiable: bool,
    /// Why the data do not pin the parameters down.
    reason: Option<String>,
    model_curve: Vec<[f64; 2]>,
    objective_end: Option<f64>,
    /// The fitted values, for the final evaluation.
    end_values: Option<Vec<f64>>,
}

/// The free parameters at their `starts` within their `bounds`, not fitted yet.
fn initial_parameters(problem: &Problem, starts: &[f64], bounds: &[(f64, f64)]) -> Vec<ParameterResult> {
    let n_particles = problem.recipe.particles.len();
    problem
        .free
        .iter()
        .zip(starts)
        .zip(bounds)
        .map(|((a, s), b)| ParameterResult {
            name: a.label(n_particles),
            particle: problem.recipe.particles[a.particle].medium.name.clone(),
            start: *s,
            value: None,
            std_error: None,
            std_error_measurement: None,
            std_error_bootstrap_configurations: None,
            interval_95: None,
            bounds: [b.0, b.1],
        })
        .collect()
}

/// One free parameter `param` from `start` within `bounds`: golden-ratio
/// bracketing and golden-section search in ln p (unless the objective is
/// flat over the range), then the final model through points at the full
/// path count for its value and standard errors.
fn search_one(
    problem: &Problem,
    ev: &mut Evaluator,
    param: &mut ParameterResult,
    start: f64,
    bounds: (f64, f64),
    stops: &Stops,
    progress: &mut impl FnMut(&Event),
) -> Result<Searched, FitError> {
    let mut identifiable = true;
    let mut reason: Option<String> = None;
    let mut model_curve = Vec::new();
    let mut objective_end = None;
    let mut end_values: Option<Vec<f64>> = None;
    let (lo, hi) = (bounds.0.ln(), bounds.1.ln());
    let step = problem.free[0].step();
    let name = param.name.clone();
    let x0 = start.ln();
    let explore = &stops.explore;
    let search_result = {
        let mut seen: Vec<(f64, f64)> = Vec::new();
        let progress = &mut *progress;
        let ev = &mut *ev;
        let mut f = |x: f64| -> Result<f64, FitError> {
            if let Some(&(_, v)) = seen.iter().find(|(p, _)| (p - x).abs() < 1e-12) {
                return Ok(v);
            }
            let e = ev.evaluate(&[x.exp()], "search", explore, false)?;
            progress(&format!("{name} = {:.5}: objective {:.4e}", x.exp(), e.objective));
            seen.push((x, e.objective));
            Ok(e.objective)
        };
        // Flat around the start? Then look at both bounds at once.
        let f0 = f(x0)?;
        let fp = f((x0 + step).min(hi))?;
        let fm = f((x0 - step).max(lo))?;
        let span = |v: &[f64]| {
            chi2(problem, v.iter().copied().fold(f64::NEG_INFINITY, f64::max))
                - chi2(problem, v.iter().copied().fold(f64::INFINITY, f64::min))
        };
        let mut flat = None;
        if span(&[f0, fp, fm]) < 0.1 {
            let all = [f0, fp, fm, f(lo)?, f(hi)?];
            if span(&all) < 1.0 {
                flat = Some(span(&all));
            }
        }
        match flat {
            Some(s) => Err(s),
            None => Ok(search::golden_bracket_search(&mut f, x0, step, (lo, hi), problem.x_tol)?),
        }
    };
    match search_result {
        Err(span) => {
            identifiable = false;
            reason = Some(format!(
                "the data cannot pin down {name}: the objective changes by only Δχ² = {span:.3} (in units of the measurement uncertainty σ = {}) over the whole search range {:.4} … {:.4}",
                problem.measured_rel_sd, bounds.0, bounds.1
            ));
        }
        Ok(r) if r.at_bound.is_some() => {
            identifiable = false;
            reason = Some(format!(
                "the data cannot pin down {name} within the search range: the objective still falls at the bound {:.5} (widen --bounds if that is physical)",
                r.at_bound.unwrap_or(f64::NAN).exp()
            ));
        }
        Ok(r) => match final_model(problem, ev, &stops.full, r.best_x, (lo, hi), progress)? {
            Ok(fin) => {
                let p = param;
                let se = fin.se_meas.max(fin.se_boot.unwrap_or(0.0));
                let v = fin.x.exp();
                p.value = Some(v);
                p.std_error = Some(v * se);
                p.std_error_measurement = Some(v * fin.se_meas);
                p.std_error_bootstrap_configurations = fin.se_boot.map(|s| v * s);
                p.interval_95 = Some([(fin.x - 1.96 * se).exp(), (fin.x + 1.96 * se).exp()]);
                model_curve = fin.curve;
                objective_end = Some(fin.j_end);
                end_values = Some(vec![v]);
                if 1.96 * se > 0.5 * (hi - lo) {
                    identifiable = false;
                    reason = Some(format!(
                        "the data cannot pin down {name}: its 95 % interval {:.4} … {:.4} is wider than the search range {:.4} … {:.4}",
                        (fin.x - 1.96 * se).exp(),
                        (fin.x + 1.96 * se).exp(),
                        bounds.0,
                        bounds.1
                    ));
                }
            }
            Err(why) => {
                identifiable = false;
                reason = Some(format!("the data cannot pin down {name}: {why}"));
            }
        },
    }
    Ok(Searched { identifiable, reason, model_curve, objective_end, end_values })
}

/// Several free parameters (`params`, from `starts` within `bounds`):
/// Nelder–Mead in ln p at the full path count (`full`), standard errors
/// from a quadratic surface through the points nearest the best.
fn search_many(
    problem: &Problem,
    ev: &mut Evaluator,
    params: &mut [ParameterResult],
    starts: &[f64],
    bounds: &[(f64, f64)],
    full: &[Stop],
    progress: &mut impl FnMut(&Event),
) -> Result<Searched, FitError> {
    let k = problem.measurements.len();
    let mut identifiable = true;
    let mut reason: Option<String> = None;
    let x0: Vec<f64> = starts.iter().map(|s| s.ln()).collect();
    let steps: Vec<f64> = problem.free.iter().map(|a| 2.0 * a.step()).collect();
    let names: Vec<String> = params.iter().map(|p| p.name.clone()).collect();
    let (xb, fb, hist) = {
        let ev = &mut *ev;
        let progress = &mut *progress;
        let mut f = |x: &[f64]| -> Result<f64, FitError> {
            let v: Vec<f64> = x.iter().zip(bounds).map(|(x, b)| x.exp().clamp(b.0, b.1)).collect();
            let e = ev.evaluate(&v, "search", full, false)?;
            progress(&format!("{}: objective {:.4e}", fmt_named(&names, &v), e.objective));
            Ok(e.objective)
        };
        let f_tol = 0.01 * problem.measured_rel_sd * problem.measured_rel_sd / k as f64;
        search::nelder_mead(&mut f, &x0, &steps, f_tol, 0.05, 40 * problem.free.len())?
    };
    let objective_end = Some(fb);
    let vb: Vec<f64> = xb.iter().zip(bounds).map(|(x, b)| x.exp().clamp(b.0, b.1)).collect();
    let end_values = Some(vb.clone());
    match local_errors(&hist, &xb, problem) {
        Some(se) => {
            for (i, p) in params.iter_mut().enumerate() {
                p.value = Some(vb[i]);
                p.std_error = Some(vb[i] * se[i]);
                p.std_error_measurement = Some(vb[i] * se[i]);
                p.interval_95 = Some([(xb[i] - 1.96 * se[i]).exp(), (xb[i] + 1.96 * se[i]).exp()]);
            }
        }
        None => {
            identifiable = false;
            reason = Some(format!(
                "the data cannot pin down {} together: the objective is flat along some combination of them near the best point {}",
                names.join(", "),
                fmt_named(&names, &vb)
            ));
        }
    }
    Ok(Searched { identifiable, reason, model_curve: Vec::new(), objective_end, end_values })
}

/// Per-configuration figures: the measured slice, the path count, and the
/// sum ratio and MSRE at the start (`pilot`) and at the fitted values
/// (`end_eval`).
fn configurations(
    problem: &Problem,
    ev: &Evaluator,
    pilot: &Evaluation,
    end_eval: Option<&Evaluation>,
) -> Vec<ConfigResult> {
    problem
        .measurements
        .iter()
        .enumerate()
        .map(|(c, m)| ConfigResult {
            file: m.path.display().to_string(),
            theta_i_deg: m.directions.theta_i_deg,
            phi_i_deg: m.directions.phi_i_deg,
            theta_o_deg: m.directions.theta_o_deg,
            phi_o_deg: m.directions.phi_o_deg,
            pixels: m.grid.size,
            pixel_mm: m.grid.pixel_m * 1e3,
            estimator: ev.estimators.get(c).map(|e| e.name()).unwrap_or(""),
            paths_per_evaluation: ev.paths[c],
            measured_sum: m.grid.sum(),
            sum_ratio_start: pilot.sum_ratio[c],
            sum_ratio_end: end_eval.map(|e| e.sum_ratio[c]),
            msre_start: pilot.msre[c],
            msre_end: end_eval.map(|e| e.msre[c]),
        })
        .collect()
}

struct Final {
    x: f64,
    /// The model objective J(ln p) near the minimum, for the plot.
    curve: Vec<[f64; 2]>,
    j_end: f64,
    se_meas: f64,
    se_boot: Option<f64>,
}

/// The local model of the objective through the final points, at
/// perturbed data: `scale[j][c]` multiplies measured slice c at point j.
fn local_model_min(
    problem: &Problem,
    xs: &[f64],
    sims: &[Vec<&[f64]>],
    scale: &[Vec<f64>],
    configs: &[usize],
    (lo, hi): (f64, f64),
) -> Option<f64> {
    let k = problem.measurements.len();
    match problem.objective {
        Objective::Sum => {
            // ln Σs_c(x) is smooth and nearly linear over the final span:
            // a least-squares line per configuration, then the minimum of
            // the model objective (robust to the points' independent noise).
            let lines: Vec<(f64, f64)> = (0..k)
                .map(|c| {
                    let ys: Vec<f64> = sims
                        .iter()
                        .zip(scale)
                        .map(|(s, sc)| (s[c].iter().sum::<f64>() / sc[c]).max(1e-300).ln())
                        .collect();
                    line_fit(xs, &ys)
                })
                .collect();
            let j = |x: f64| -> f64 {
                configs
                    .iter()
                    .map(|&c| {
                        let r = (lines[c].0 + lines[c].1 * x).exp() / problem.measurements[c].grid.sum() - 1.0;
                        r * r
                    })
                    .sum::<f64>()
                    / configs.len() as f64
            };
            let mut f = |x: f64| -> Result<f64, std::convert::Infallible> { Ok(j(x)) };
            let centre = xs[xs.len() / 2];
            let r = search::golden_bracket_search(&mut f, centre, 0.05, (lo, hi), 1e-7).ok()?;
            if r.at_bound.is_some() {
                return None;
            }
            Some(r.best_x)
        }
        Objective::Msre => {
            let f: Vec<f64> = sims
                .iter()
                .zip(scale)
                .map(|(s, sc)| {
                    configs
                        .iter()
                        .map(|&c| msre(&problem.measurements[c].grid.values, s[c], problem.threshold, sc[c]))
                        .sum::<f64>()
                        / configs.len() as f64
                })
                .collect();
            search::quadratic_fit(xs, &f).filter(|q| q.c2 > 0.0).map(|q| q.vertex())
        }
    }
}

/// Least-squares line y = a + b x.
fn line_fit(xs: &[f64], ys: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let sxy: f64 = xs.iter().zip(ys).map(|(x, y)| (x - mx) * (y - my)).sum();
    let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    (my - b * mx, b)
}

/// Five points around `x_best` at the full budget, the local model of the
/// objective through them (lines in ln Σs for `sum`, a parabola for
/// `msre`), and the bootstrap errors. `Err(reason)` when the model has no
/// minimum (flat within the noise).
fn final_model(
    problem: &Problem,
    ev: &mut Evaluator,
    full: &[Stop],
    x_best: f64,
    (lo, hi): (f64, f64),
    progress: &mut impl FnMut(&Event),
) -> Result<Result<Final, Undetermined>, FitError> {
    let k = problem.measurements.len();
    let mut centre = x_best;
    let delta = problem.x_tol.max(0.05);
    let all: Vec<usize> = (0..k).collect();
    for attempt in 0..2 {
        let xs: Vec<f64> = (-2..=2).map(|j| (centre + j as f64 * delta).clamp(lo, hi)).collect();
        let mut evals = Vec::new();
        for &x in &xs {
            let e = ev.evaluate(&[x.exp()], "final", full, true)?;
            progress(&format!("final {:.5}: objective {:.4e}", x.exp(), e.objective));
            evals.push(e);
        }
        let sims: Vec<Vec<&[f64]>> = evals
            .iter()
            .map(|e| e.slices.as_ref().map(|s| s.iter().map(|v| v.as_slice()).collect()).unwrap_or_default())
            .collect();
        if problem.objective == Objective::Sum {
            // Do the sums change significantly over the final span? t² of
            // the slopes of ln Σs against x (error from the residuals or the
            // Monte Carlo errors, whichever is larger).
            let mx = xs.iter().sum::<f64>() / xs.len() as f64;
            let sxx: f64 = xs.iter().map(|x| (x - mx).powi(2)).sum();
            let mut t2 = 0.0;
            for c in 0..k {
                let ys: Vec<f64> = sims.iter().map(|s| s[c].iter().sum::<f64>().max(1e-300).ln()).collect();
                let (a, b) = line_fit(&xs, &ys);
                let res: f64 =
                    xs.iter().zip(&ys).map(|(x, y)| (y - a - b * x).powi(2)).sum::<f64>() / (xs.len() as f64 - 2.0);
                let mc: f64 = evals.iter().map(|e| e.sum_rel_error[c].powi(2)).sum::<f64>() / evals.len() as f64;
                t2 += b * b * sxx / res.max(mc).max(1e-300);
            }
            if t2 < 9.0 {
                return Ok(Err(Undetermined::FlatSums { lo: xs[0].exp(), hi: xs[xs.len() - 1].exp(), t: t2.sqrt() }));
            }
        }
        let ones = vec![vec![1.0; k]; xs.len()];
        let Some(x) = local_model_min(problem, &xs, &sims, &ones, &all, (lo, hi)) else {
            return Ok(Err(Undetermined::NoMinimum { near: centre.exp() }));
        };
        if (x - centre).abs() > 2.0 * delta && attempt == 0 {
            centre = x.clamp(lo, hi);
            continue;
        }
        // Parametric bootstrap: the measurement's scale error (common to
        // the points) and the Monte Carlo error of each point (independent).
        let mut rng = Rng::new(problem.seed ^ 0x05ee_df17, 0);
        const DRAWS: usize = 400;
        let mut vs = Vec::with_capacity(DRAWS);
        for _ in 0..DRAWS {
            let common: Vec<f64> = (0..k).map(|_| 1.0 + problem.measured_rel_sd * normal(&mut rng)).collect();
            let scale: Vec<Vec<f64>> = evals
                .iter()
                .map(|e| (0..k).map(|c| common[c] / (1.0 + e.sum_rel_error[c] * normal(&mut rng))).collect())
                .collect();
            vs.push(local_model_min(problem, &xs, &sims, &scale, &all, (lo, hi)).unwrap_or(f64::NAN));
        }
        let failed = vs.iter().filter(|v| !v.is_finite()).count();
        if failed > DRAWS / 20 {
            return Ok(Err(Undetermined::Bootstrap { failed, draws: DRAWS }));
        }
        let se_meas = std_dev(vs.iter().copied().filter(|v| v.is_finite()));
        let se_boot = if k >= 3 {
            let vb: Vec<f64> = (0..DRAWS)
                .map(|_| {
                    let configs: Vec<usize> =
                        (0..k).map(|_| ((rng.next_f64() * k as f64) as usize).min(k - 1)).collect();
                    local_model_min(problem, &xs, &sims, &ones, &configs, (lo, hi)).unwrap_or(f64::NAN)
                })
                .collect();
            Some(std_dev(vb.into_iter().filter(|v| v.is_finite())))
        } else {
            None
        };
        // The model curve for the plot, and J at the minimum.
        let model_j = |t: f64| -> f64 {
            match problem.objective {
                Objective::Sum => {
                    let mut acc = 0.0;
                    for c in 0..k {
                        let ys: Vec<f64> = sims.iter().map(|s| s[c].iter().sum::<f64>().max(1e-300).ln()).collect();
                        let (a, b) = line_fit(&xs, &ys);
                        let r = (a + b * t).exp() / problem.measurements[c].grid.sum() - 1.0;
                        acc += r * r;
                    }
                    acc / k as f64
                }
                Objective::Msre => {
                    let f: Vec<f64> = evals.iter().map(|e| e.objective).collect();
                    search::quadratic_fit(&xs, &f).map(|q| q.at(t)).unwrap_or(f64::NAN)
                }
            }
        };
        let (a, b) = (xs[0].min(x) - delta, xs[xs.len() - 1].max(x) + delta);
        let curve = (0..=60).map(|i| a + (b - a) * i as f64 / 60.0).map(|t| [t.exp(), model_j(t)]).collect();
        return Ok(Ok(Final { x, curve, j_end: model_j(x), se_meas, se_boot }));
    }
    Ok(Err(Undetermined::Moved))
}

/// Standard errors in ln p from a quadratic surface through the Nelder–Mead
/// points nearest the best; `None` if there are too few points or the
/// surface's Hessian H is not positive definite. SE_i² = 2σ_m²/K · (H⁻¹)_ii.
fn local_errors(hist: &[search::Point], best: &[f64], problem: &Problem) -> Option<Vec<f64>> {
    let n = best.len();
    let terms = (n + 1) * (n + 2) / 2;
    let mut pts: Vec<&search::Point> = hist.iter().collect();
    let dist = |x: &[f64]| x.iter().zip(best).map(|(a, b)| (a - b).powi(2)).sum::<f64>();
    pts.sort_by(|a, b| dist(&a.0).total_cmp(&dist(&b.0)));
    pts.truncate((2 * terms).min(pts.len()));
    if pts.len() < terms + 1 {
        return None;
    }
    // Rows: 1, d_i, d_i d_j (i ≤ j).
    let row = |x: &[f64]| {
        let d: Vec<f64> = x.iter().zip(best).map(|(a, b)| a - b).collect();
        let mut r = vec![1.0];
        r.extend(d.iter().copied());
        for i in 0..n {
            for j in i..n {
                r.push(d[i] * d[j]);
            }
        }
        r
    };
    let mut ata = vec![vec![0.0; terms]; terms];
    let mut atb = vec![0.0; terms];
    for (x, f) in &pts {
        let r = row(x);
        for (i, ri) in r.iter().enumerate() {
            for (j, rj) in r.iter().enumerate() {
                ata[i][j] += ri * rj;
            }
            atb[i] += ri * f;
        }
    }
    let c = solve(ata, atb)?;
    // The quadratic coefficients in the order of `row`: (i, j), i ≤ j.
    let pairs: Vec<(usize, usize)> = (0..n).flat_map(|i| (i..n).map(move |j| (i, j))).collect();
    let mut h = vec![vec![0.0; n]; n];
    for (&(i, j), &cij) in pairs.iter().zip(&c[1 + n..]) {
        let v = if i == j { 2.0 * cij } else { cij };
        h[i][j] = v;
        h[j][i] = v;
    }
    if !positive_definite(&h) {
        return None;
    }
    let k = problem.measurements.len() as f64;
    let s2 = problem.measured_rel_sd.powi(2);
    let mut se = Vec::new();
    for i in 0..n {
        let mut e = vec![0.0; n];
        e[i] = 1.0;
        let col = solve(h.clone(), e)?;
        se.push((2.0 * s2 / k * col[i]).sqrt());
    }
    Some(se)
}

/// Gaussian elimination with partial pivoting; `None` if singular.
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let n = b.len();
    for col in 0..n {
        let piv = (col..n).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        b.swap(col, piv);
        for r in col + 1..n {
            let f = a[r][col] / a[col][col];
            let pivot_row = a[col].clone();
            for (x, p) in a[r].iter_mut().zip(&pivot_row).skip(col) {
                *x -= f * p;
            }
            b[r] -= f * b[col];
        }
    }
    let mut x = vec![0.0; n];
    for r in (0..n).rev() {
        let s: f64 = (r + 1..n).map(|c| a[r][c] * x[c]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Whether a symmetric matrix is positive definite (Cholesky succeeds).
fn positive_definite(h: &[Vec<f64>]) -> bool {
    let n = h.len();
    let mut l = vec![vec![0.0; n]; n];
    for i in 0..n {
        for j in 0..=i {
            let s: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                let d = h[i][i] - s;
                if d <= 0.0 {
                    return false;
                }
                l[i][i] = d.sqrt();
            } else {
                l[i][j] = (h[i][j] - s) / l[j][j];
            }
        }
    }
    true
}

/// Synthetic "measured" slices of `recipe` (at its own values) for fits
/// with a known truth: a simulation of `paths` light paths with seed `seed`
/// (use one the fit does not) for each (θ_i, φ_i, θ_o, φ_o) on a sensor of
/// `(pixels, pixel_mm)`, 200 µm Gaussian beam, times a per-slice scale
/// error 1 + σz and per-pixel noise 1 + σz_p with σ = `noise` (the lab's
/// 5 % uncertainty: 0.05).
pub fn synthetic_slices(
    recipe: &Recipe,
    wavelength_nm: f64,
    configs: &[(f64, f64, f64, f64)],
    (pixels, pixel_mm): (usize, f64),
    paths: u64,
    seed: u64,
    noise: f64,
) -> Result<Vec<Grid>, FitError> {
    let s = bulk::at_wavelength(recipe, wavelength_nm, &bulk::Options::default())?;
    let medium = Medium::new(
        s.mu_s_per_m,
        s.mu_a_per_m,
        Phase::Tabulated(PhaseTable::from_theta_samples(&s.phase)?),
        s.n_bulk.max(1.0),
    )?;
    let mut rng = Rng::new(seed ^ 0x0a15e, 7);
    let mut out = Vec::new();
    for &(ti, pi, to, po) in configs {
        let setup = Setup::new(
            Slab::new(recipe.thickness_m, medium.clone())?,
            Beam::gaussian(200e-6)?,
            Sensor::new(pixels, pixel_mm * 1e-3)?,
            Directions::from_degrees(ti, pi, to, po)?,
        );
        let options = RunOptions {
            stop: Stop::samples(paths),
            seed,
            estimator: Estimator::best_for(&setup),
            fold: true,
            ..RunOptions::default()
        };
        let slice = slab::simulate(&setup, &options, |_| {})?;
        let scale = 1.0 + noise * normal(&mut rng);
        let values = slice.values.iter().map(|v| (v * scale * (1.0 + noise * normal(&mut rng))).max(0.0)).collect();
        out.push(Grid { size: pixels, pixel_m: pixel_mm * 1e-3, values });
    }
    Ok(out)
}

/// A standard normal variate (Box–Muller).
fn normal(rng: &mut Rng) -> f64 {
    let u1 = rng.next_f64().max(1e-300);
    let u2 = rng.next_f64();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

fn std_dev(values: impl Iterator<Item = f64>) -> f64 {
    let v: Vec<f64> = values.collect();
    if v.len() < 2 {
        return f64::NAN;
    }
    let n = v.len() as f64;
    let mean = v.iter().sum::<f64>() / n;
    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt()
}

fn fmt_values(v: &[f64]) -> String {
    v.iter().map(|x| format!("{x:.5}")).collect::<Vec<_>>().join(", ")
}

fn fmt_list(v: &[f64]) -> String {
    format!("[{}]", v.iter().map(|x| format!("{x:.4}")).collect::<Vec<_>>().join(", "))
}

fn fmt_named(names: &[String], v: &[f64]) -> String {
    names.iter().zip(v).map(|(n, x)| format!("{n} = {x:.5}")).collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::optics::recipe::{AbsorptionModel, Overrides};

    fn pdms() -> Recipe {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/samples/IOL1068-09.toml");
        Recipe::load(&path, Overrides::default()).unwrap()
    }

    /// The affine weight scaling equals a direct Lorenz–Mie computation.
    #[test]
    fn weight_scaling_is_exact() {
        for model in [AbsorptionModel::VolumeWeightedFullHost, AbsorptionModel::Mie, AbsorptionModel::VolumeWeighted] {
            let mut r = pdms();
            r.absorption = model;
            let s = WeightScaling::new(&r, 0, 550.0).unwrap().expect("affine");
            for w in [0.1, 0.425, 3.0] {
                let o = s.at(w);
                let d = bulk::at_wavelength(&r.with_weight_percent(0, w).unwrap(), 550.0, &bulk::Options::default())
                    .unwrap();
                let rel = |a: f64, b: f64| ((a - b) / b).abs();
                assert!(rel(o.mu_s_per_m, d.mu_s_per_m) < 1e-12, "{model:?} μs {} {}", o.mu_s_per_m, d.mu_s_per_m);
                assert!(rel(o.mu_a_per_m, d.mu_a_per_m) < 1e-9, "{model:?} μa {} {}", o.mu_a_per_m, d.mu_a_per_m);
                assert!(rel(o.g, d.g) < 1e-12, "{model:?} g");
                assert!((o.n_bulk - d.n_bulk).abs() < 1e-12, "{model:?} n");
                let (pmax, dmax) = (o.phase[0], d.phase[0]);
                for (a, b) in o.phase.iter().zip(&d.phase).step_by(97) {
                    assert!((a / pmax - b / dmax).abs() < 1e-9, "{model:?} phase");
                }
            }
        }
    }

    #[test]
    fn free_parameter_names() {
        let r = pdms();
        let of = |t: &str| FreeParameter::of(t.parse().unwrap(), &r);
        assert_eq!(of("weight_percent").unwrap(), FreeParameter::weight_percent(0));
        assert_eq!(of("diameter_um@1").unwrap().kind, ParameterKind::DiameterUm);
        let e = "weight".parse::<FreeSpec>().unwrap_err().to_string();
        assert!(e.contains("\"weight\"") && e.contains("weight_percent, diameter_um, real_part_n"), "{e}");
        assert!(of("weight_percent@2").is_err());
        let spec: FreeSpec = " diameter_um@2 ".parse().unwrap();
        assert_eq!(
            (spec.kind, spec.particle, spec.to_string()),
            (ParameterKind::DiameterUm, Some(2), "diameter_um@2".into())
        );
        assert!("weight_percent@0".parse::<FreeSpec>().is_err());
        let n = FreeParameter { kind: ParameterKind::RealPartN, particle: 0 };
        let v = n.value_in(&r, 550.0).unwrap();
        let r2 = n.apply(&r, v + 0.01, 550.0).unwrap();
        assert!((n.value_in(&r2, 550.0).unwrap() - v - 0.01).abs() < 1e-12);
        let d = FreeParameter { kind: ParameterKind::DiameterUm, particle: 0 };
        assert!((d.value_in(&d.apply(&r, 3.0, 550.0).unwrap(), 550.0).unwrap() - 3.0).abs() < 1e-12);
    }

    #[test]
    fn typed_errors_name_the_file_and_the_problem() {
        let r = pdms();
        let e = FreeParameter::of("weight_percent@2".parse().unwrap(), &r).unwrap_err();
        assert!(matches!(e, FitError::ParticleNumber { count: 1, .. }), "{e:?}");
        assert!(e.to_string().contains("\"weight_percent@2\": the particle type must be 1 … 1"), "{e}");
        let path = Path::new("slices/dark.exr");
        let zero = Grid { size: 3, pixel_m: 1e-4, values: vec![0.0; 9] };
        let e = Measurement::new(path, zero.clone(), (45.0, 0.0, 0.0, 0.0)).unwrap_err();
        assert!(matches!(e, FitError::EmptySlice { .. }), "{e:?}");
        assert_eq!(e.to_string(), "slices/dark.exr: the measured slice has no positive sum (0)");
        let one = Grid { size: 3, pixel_m: 1e-4, values: vec![1.0; 9] };
        let e = Measurement::new(path, one, (95.0, 0.0, 0.0, 0.0)).unwrap_err();
        assert!(matches!(e, FitError::Configuration { theta_i, .. } if theta_i == 95.0), "{e:?}");
        assert!(e.to_string().starts_with("slices/dark.exr: configuration 95/0: "), "{e}");
        let s = FitError::Setting { what: "thickness", value: -1.0, unit: " m", rule: "be positive" };
        assert_eq!(s.to_string(), "thickness -1 m must be positive");
        let u = Undetermined::Bootstrap { failed: 30, draws: 400 };
        assert!(u.to_string().starts_with("in 30 of 400 bootstrap draws"), "{u}");
    }
}
