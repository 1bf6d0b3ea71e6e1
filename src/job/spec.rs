//! The jobs: one struct per command that runs as a job ([`OpticsJob`],
//! [`RenderJob`], …) with its `validate()` and `to_args()`, and [`Job`],
//! any of them, with its JSON and identity. What a job does when it runs is
//! its stage's module's (`impl RenderJob { fn run … }` in `render.rs`); the
//! overview is the parent module's.

use super::env_merge::EnvMergeJob;
use super::env_orient::EnvOrientJob;
use super::fields::{
    at_least_one, bad, board, by_name, by_name_opt, paths, positive, positive_opt, s, threshold, weight_percent,
    JobError, Line, MAX_SLICE_PIXELS,
};
use super::shard::split::ShardSpec;
use super::surface_fit::SurfaceFitJob;
use super::values::{ChartCorners, ClipLevel, ImageSize, MeasuredSlice, SampleCorner, SampleSizeMm};
use crate::bssrdf::Configurations;
use crate::fit::{FreeSpec, SearchBounds};
use lucent_calib::board::BoardSize;
use lucent_colour::WavelengthGrid;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// `lucent optics RECIPE… --wavelengths GRID --out DIR`: the recipes'
/// bulk optical properties ([`OpticsJob::run`]). The keys at their
/// defaults are not written into a stage's job.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OpticsJob {
    pub recipes: Vec<PathBuf>,
    /// The wavelengths in nm ("START:END:STEP" or one "W" as text).
    pub wavelengths: WavelengthGrid,
    /// The output folder; `None` (with `json`): nothing is written, the
    /// properties are printed as JSON only.
    pub out: Option<PathBuf>,
    pub weight_percent: Option<f64>,
    /// `--wavelength-nm`: one wavelength, instead of `wavelengths`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wavelength_nm: Option<f64>,
    /// `--json`: the properties printed as JSON instead of tables.
    #[serde(default, skip_serializing_if = "is_false")]
    pub json: bool,
    /// `--phase-entries`: entries of the tabulated phase function (0: none).
    #[serde(default = "default_phase_entries", skip_serializing_if = "is_default_phase_entries")]
    pub phase_entries: usize,
    /// `--skip-invalid`: in a folder, recipes that fail validation are
    /// reported and left out.
    #[serde(default, skip_serializing_if = "is_false")]
    pub skip_invalid: bool,
    /// `--uncertainty N`: instead of the properties, the propagation of
    /// the recipes' uncertain inputs with N Latin-hypercube draws
    /// ([`OpticsJob::run_uncertainty`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty: Option<usize>,
    /// `--uncertainty-seed`: the seed of the draws.
    #[serde(default = "default_uncertainty_seed", skip_serializing_if = "is_default_uncertainty_seed")]
    pub uncertainty_seed: u64,
    /// `--shard K/N` (with `uncertainty`): only the K-th of N ranges of the draws, as a shard.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<ShardSpec>,
}

fn default_uncertainty_seed() -> u64 {
    1
}

fn is_default_uncertainty_seed(s: &u64) -> bool {
    *s == 1
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// The default of `lucent optics --phase-entries`.
pub const DEFAULT_PHASE_ENTRIES: usize = 4096;

fn default_phase_entries() -> usize {
    DEFAULT_PHASE_ENTRIES
}

fn is_default_phase_entries(n: &usize) -> bool {
    *n == DEFAULT_PHASE_ENTRIES
}

/// The most draws of `lucent optics --uncertainty`.
pub const MAX_UNCERTAINTY_DRAWS: usize = 100_000;

/// The output folder of `lucent optics` without `--out`.
pub const DEFAULT_OPTICS_OUT: &str = "lucent-out/optics";

impl OpticsJob {
    /// The recipes at `wavelengths` into `out`, every other flag at its default.
    pub fn new(recipes: Vec<PathBuf>, wavelengths: WavelengthGrid, out: PathBuf) -> Self {
        OpticsJob {
            recipes,
            wavelengths,
            out: Some(out),
            weight_percent: None,
            wavelength_nm: None,
            json: false,
            phase_entries: DEFAULT_PHASE_ENTRIES,
            skip_invalid: false,
            uncertainty: None,
            uncertainty_seed: default_uncertainty_seed(),
            shard: None,
        }
    }
    pub fn validate(&self) -> Result<(), JobError> {
        if let Some(n) = self.uncertainty
            && !(2..=MAX_UNCERTAINTY_DRAWS).contains(&n)
        {
            return Err(bad("uncertainty", n, format!("must lie in 2 … {MAX_UNCERTAINTY_DRAWS}")));
        }
        if self.shard.is_some() && self.uncertainty.is_none() {
            return Err(bad(
                "shard",
                self.shard.map(|s| s.to_string()).unwrap_or_default(),
                "only an --uncertainty study of optics is split into shards",
            ));
        }
        if self.out.is_none() && !self.json {
            return Err(bad(
                "out",
                "",
                "give the output folder (without one the properties are only printed, as JSON)",
            ));
        }
        weight_percent(self.weight_percent)
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["optics"]);
        l.words(self.recipes.iter().map(|r| s(r)));
        match self.wavelength_nm {
            Some(w) => l.flag("--wavelength-nm", w),
            None => l.flag("--wavelengths", &self.wavelengths),
        };
        l.opt("--out", &self.out.as_deref().map(s)).opt("--weight-percent", &self.weight_percent);
        l.switch("--json", self.json).switch("--skip-invalid", self.skip_invalid);
        if !is_default_phase_entries(&self.phase_entries) {
            l.flag("--phase-entries", self.phase_entries);
        }
        l.opt("--uncertainty", &self.uncertainty);
        if !is_default_uncertainty_seed(&self.uncertainty_seed) {
            l.flag("--uncertainty-seed", self.uncertainty_seed);
        }
        l.opt("--shard", &self.shard);
        l.0
    }
}

/// The estimator of a slab job's slices (`--estimator`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(strum::EnumString, strum::IntoStaticStr, strum::VariantNames, strum::VariantArray, strum::EnumMessage)]
#[strum(serialize_all = "kebab-case", ascii_case_insensitive)]
pub enum EstimatorChoice {
    /// The ring connection where it applies (θi = 0 or θo = 0, thick slab, smooth top), else the lobe connection
    /// (thick slab, smooth or rough top), else the fixed-direction one.
    #[default]
    Auto,
    /// The ring connection (azimuthal symmetry; an error where it does not apply).
    Ring,
    /// The lobe connection (MIS with chains drawn through the phase lobe around the exit direction; thick slab,
    /// smooth or rough top).
    Lobe,
    /// The explicit connection along the one fixed exit direction (the previous estimator).
    Connection,
}

impl EstimatorChoice {
    /// The name flags and job files use.
    pub fn name(self) -> &'static str {
        self.into()
    }
}

/// `lucent bssrdf`: slab BSSRDF slices of a recipe (or of explicit
/// optical coefficients: no pipeline stage's job) ([`BssrdfJob::run`]).
/// The flags a stage of `lucent run` leaves at their defaults are not
/// written into its job.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BssrdfJob {
    pub recipe: Option<PathBuf>,
    pub wavelength_nm: f64,
    /// θi/θo pairs in degrees, "45/0,0/45" as text (else the job's
    /// single configuration `theta_i` … `phi_o`).
    pub configs: Option<Configurations>,
    pub pixels: usize,
    pub pixel_mm: f64,
    pub seed: u64,
    pub quiet: bool,
    pub out: PathBuf,
    pub weight_percent: Option<f64>,
    pub crop: Option<usize>,
    pub paths: Option<u64>,
    pub rel_error: Option<f64>,
    pub time_s: Option<f64>,
    pub phase: Option<crate::optics::PhaseModel>,
    /// `--mu-s`, `--mu-a`, `--g`, `--n`: the medium without a recipe.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mu_s: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mu_a: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub g: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub n: Option<f64>,
    /// `--thickness-mm` (default: the recipe's, else 6.35).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness_mm: Option<f64>,
    /// The one configuration without `configs` (degrees).
    #[serde(default = "slab_defaults::theta_i", skip_serializing_if = "slab_defaults::is_theta_i")]
    pub theta_i: f64,
    #[serde(default, skip_serializing_if = "slab_defaults::is_zero")]
    pub phi_i: f64,
    #[serde(default, skip_serializing_if = "slab_defaults::is_zero")]
    pub theta_o: f64,
    #[serde(default = "slab_defaults::phi_o", skip_serializing_if = "slab_defaults::is_phi_o")]
    pub phi_o: f64,
    /// `--similarity-g`: walk the similar medium of asymmetry at most this.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub similarity_g: Option<f64>,
    /// `--beam-fwhm-um`: the Gaussian beam's FWHM (without a beam map).
    #[serde(default = "slab_defaults::beam_fwhm_um", skip_serializing_if = "slab_defaults::is_beam_fwhm_um")]
    pub beam_fwhm_um: f64,
    /// `--beam-map`, `--beam-map-pixel-mm`: a measured irradiance map.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beam_map: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beam_map_pixel_mm: Option<f64>,
    /// `--pixel-rel-error`: stop at this median per-pixel relative error.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixel_rel_error: Option<f64>,
    #[serde(default, skip_serializing_if = "slab_defaults::is_auto")]
    pub estimator: EstimatorChoice,
    /// `--lobe-vertices`: camera-side vertices of the lobe connection's chains.
    #[serde(default = "slab_defaults::lobe_vertices", skip_serializing_if = "slab_defaults::is_lobe_vertices")]
    pub lobe_vertices: u8,
    /// `--roughness`: the top boundary (default: the recipe's surface, else
    /// smooth), written as the flag's text.
    #[serde(default, skip_serializing_if = "Option::is_none", deserialize_with = "roughness_field")]
    pub roughness: Option<crate::bssrdf::RoughnessSpec>,
    /// `--no-fold`: do not fold the slice about the plane of incidence.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub no_fold: bool,
    /// `--uncertainty`: the band of the recipe's uncertain inputs.
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub uncertainty: bool,
    /// `--shard K/N`: only the K-th of N ranges of the path batches, as a shard.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<ShardSpec>,
}

/// The defaults of a slab job's fields that a job.json leaves out.
mod slab_defaults {
    pub fn theta_i() -> f64 {
        45.0
    }
    pub fn is_theta_i(v: &f64) -> bool {
        *v == theta_i()
    }
    pub fn is_zero(v: &f64) -> bool {
        *v == 0.0
    }
    pub fn phi_o() -> f64 {
        180.0
    }
    pub fn is_phi_o(v: &f64) -> bool {
        *v == phi_o()
    }
    pub fn beam_fwhm_um() -> f64 {
        200.0
    }
    pub fn is_beam_fwhm_um(v: &f64) -> bool {
        *v == beam_fwhm_um()
    }
    pub fn is_auto(e: &super::EstimatorChoice) -> bool {
        *e == super::EstimatorChoice::Auto
    }
    pub fn lobe_vertices() -> u8 {
        lucent_render::slab::LOBE_VERTICES as u8
    }
    pub fn is_lobe_vertices(v: &u8) -> bool {
        *v == lobe_vertices()
    }
}

impl Default for BssrdfJob {
    /// The job of `lucent bssrdf` with no flag given (it names no medium).
    fn default() -> Self {
        BssrdfJob {
            recipe: None,
            wavelength_nm: 550.0,
            configs: None,
            pixels: 259,
            pixel_mm: 0.1029,
            seed: 1,
            quiet: false,
            out: "lucent-out/bssrdf".into(),
            weight_percent: None,
            crop: None,
            paths: None,
            rel_error: None,
            time_s: None,
            phase: None,
            mu_s: None,
            mu_a: None,
            g: None,
            n: None,
            thickness_mm: None,
            theta_i: slab_defaults::theta_i(),
            phi_i: 0.0,
            theta_o: 0.0,
            phi_o: slab_defaults::phi_o(),
            similarity_g: None,
            beam_fwhm_um: slab_defaults::beam_fwhm_um(),
            beam_map: None,
            beam_map_pixel_mm: None,
            pixel_rel_error: None,
            estimator: EstimatorChoice::Auto,
            lobe_vertices: slab_defaults::lobe_vertices(),
            roughness: None,
            no_fold: false,
            uncertainty: false,
            shard: None,
        }
    }
}

impl BssrdfJob {
    pub fn validate(&self) -> Result<(), JobError> {
        positive("wavelength_nm", self.wavelength_nm)?;
        positive("pixel_mm", self.pixel_mm)?;
        positive_opt("time_s", self.time_s)?;
        positive_opt("rel_error", self.rel_error)?;
        weight_percent(self.weight_percent)?;
        if !(1..=MAX_SLICE_PIXELS).contains(&self.pixels) {
            return Err(bad("pixels", self.pixels, format!("must lie in 1 … {MAX_SLICE_PIXELS}")));
        }
        if self.pixel_mm * self.crop.unwrap_or(self.pixels) as f64 > 1000.0 {
            return Err(bad(
                "pixel_mm",
                self.pixel_mm,
                format!(
                    "the slice ({} pixels × {} mm) must be at most 1000 mm (1 m) wide",
                    self.crop.unwrap_or(self.pixels),
                    self.pixel_mm
                ),
            ));
        }
        if let Some(c) = self.crop
            && !(1..=self.pixels).contains(&c)
        {
            return Err(bad("crop", c, format!("must lie in 1 … pixels ({})", self.pixels)));
        }
        paths(self.paths)
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["bssrdf"]);
        l.opt("--recipe", &self.recipe.as_deref().map(s))
            .flag("--wavelength-nm", self.wavelength_nm)
            .opt("--configs", &self.configs)
            .flag("--pixels", self.pixels)
            .flag("--pixel-mm", self.pixel_mm)
            .flag("--seed", self.seed)
            .switch("--quiet", self.quiet)
            .flag("--out", s(&self.out))
            .opt("--weight-percent", &self.weight_percent);
        if let Some(c) = self.crop {
            l.word(format!("--crop={c}"));
        }
        l.opt("--paths", &self.paths)
            .opt("--rel-error", &self.rel_error)
            .opt("--time-s", &self.time_s)
            .opt("--phase", &self.phase.map(|p| p.name()));
        self.other_args(&mut l);
        l.0
    }

    /// The flags a stage leaves at their defaults, when set.
    fn other_args(&self, l: &mut Line) {
        let d = BssrdfJob::default();
        let eq = |v: f64| format!("={v}");
        l.opt("--mu-s", &self.mu_s).opt("--mu-a", &self.mu_a);
        // Values that may be negative are written `--flag=V`.
        if let Some(g) = self.g {
            l.word(format!("--g{}", eq(g)));
        }
        l.opt("--n", &self.n);
        if let Some(t) = self.thickness_mm {
            l.word(format!("--thickness-mm{}", eq(t)));
        }
        for (flag, v, default) in [
            ("--theta-i", self.theta_i, d.theta_i),
            ("--phi-i", self.phi_i, d.phi_i),
            ("--theta-o", self.theta_o, d.theta_o),
            ("--phi-o", self.phi_o, d.phi_o),
        ] {
            if v != default {
                l.word(format!("{flag}{}", eq(v)));
            }
        }
        if let Some(g) = self.similarity_g {
            l.word(format!("--similarity-g{}", eq(g)));
        }
        if self.beam_fwhm_um != d.beam_fwhm_um {
            l.word(format!("--beam-fwhm-um{}", eq(self.beam_fwhm_um)));
        }
        l.opt("--beam-map", &self.beam_map.as_deref().map(s))
            .opt("--beam-map-pixel-mm", &self.beam_map_pixel_mm)
            .opt("--pixel-rel-error", &self.pixel_rel_error);
        if self.estimator != d.estimator {
            l.flag("--estimator", self.estimator.name());
        }
        if self.lobe_vertices != d.lobe_vertices {
            l.flag("--lobe-vertices", self.lobe_vertices);
        }
        l.opt("--roughness", &self.roughness)
            .switch("--no-fold", self.no_fold)
            .switch("--uncertainty", self.uncertainty)
            .opt("--shard", &self.shard);
    }
}

/// `lucent bssrdf compare`: a simulated slice against a measured one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BssrdfCompareJob {
    pub measured: PathBuf,
    pub simulated: PathBuf,
    pub out: PathBuf,
    pub measured_pixel_mm: Option<f64>,
    pub threshold: f64,
}

/// The default of `--threshold` (bssrdf compare, fit).
pub const DEFAULT_THRESHOLD: f64 = 0.01;

impl BssrdfCompareJob {
    pub fn validate(&self) -> Result<(), JobError> {
        positive_opt("measured_pixel_mm", self.measured_pixel_mm)?;
        threshold(self.threshold)
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["bssrdf", "compare"]);
        l.flag("--measured", s(&self.measured))
            .flag("--simulated", s(&self.simulated))
            .flag("--out", s(&self.out))
            .opt("--measured-pixel-mm", &self.measured_pixel_mm)
            .flag("--threshold", self.threshold);
        l.0
    }
}

/// `lucent fit`: recipe parameters fitted to measured slices.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FitJob {
    pub recipe: PathBuf,
    /// The measured slices, "FILE:θi/θo" each as text.
    pub measured: Vec<MeasuredSlice>,
    pub measured_pixel_mm: Option<f64>,
    pub weight_percent: Option<f64>,
    /// The free parameters, "NAME" or "NAME@K" each as text.
    pub free: Vec<FreeSpec>,
    pub wavelength_nm: f64,
    pub seed: u64,
    pub quiet: bool,
    pub objective: crate::fit::Objective,
    pub rel_error: f64,
    pub paths: Option<u64>,
    pub measured_rel_sd: f64,
    /// Search ranges, one per free parameter, "LO:HI,…" as text.
    pub bounds: Option<SearchBounds>,
    pub threshold: f64,
    pub out: PathBuf,
    /// `--beam-fwhm-um`: the Gaussian beam's FWHM (without a beam map).
    #[serde(default = "slab_defaults::beam_fwhm_um", skip_serializing_if = "slab_defaults::is_beam_fwhm_um")]
    pub beam_fwhm_um: f64,
    /// `--beam-map`, `--beam-map-pixel-mm`: a measured irradiance map.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beam_map: Option<PathBuf>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beam_map_pixel_mm: Option<f64>,
    /// `--pilot-time-s`: the pilot run's time cap per configuration.
    #[serde(default = "fit_defaults::pilot_time_s", skip_serializing_if = "fit_defaults::is_pilot_time_s")]
    pub pilot_time_s: f64,
    /// `--thickness-mm` (default: the recipe's).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thickness_mm: Option<f64>,
}

impl Default for FitJob {
    /// The flags' defaults of `lucent fit` (the recipe, measured slices and
    /// free parameters, which it requires, empty).
    fn default() -> Self {
        FitJob {
            recipe: PathBuf::new(),
            measured: Vec::new(),
            measured_pixel_mm: None,
            weight_percent: None,
            free: Vec::new(),
            wavelength_nm: 550.0,
            seed: 1,
            quiet: false,
            objective: crate::fit::Objective::Sum,
            rel_error: DEFAULT_FIT_REL_ERROR,
            paths: None,
            measured_rel_sd: DEFAULT_MEASURED_REL_SD,
            bounds: None,
            threshold: DEFAULT_THRESHOLD,
            out: "lucent-out/fit".into(),
            beam_fwhm_um: slab_defaults::beam_fwhm_um(),
            beam_map: None,
            beam_map_pixel_mm: None,
            pilot_time_s: fit_defaults::pilot_time_s(),
            thickness_mm: None,
        }
    }
}

/// The defaults of a fit job's fields that a job.json leaves out.
mod fit_defaults {
    /// `--pilot-time-s`.
    pub fn pilot_time_s() -> f64 {
        60.0
    }
    pub fn is_pilot_time_s(v: &f64) -> bool {
        *v == pilot_time_s()
    }
}

/// Defaults of `lucent fit`'s flags.
pub const DEFAULT_FIT_REL_ERROR: f64 = 0.005;
pub const DEFAULT_MEASURED_REL_SD: f64 = 0.05;

impl FitJob {
    pub fn validate(&self) -> Result<(), JobError> {
        positive("wavelength_nm", self.wavelength_nm)?;
        positive_opt("measured_pixel_mm", self.measured_pixel_mm)?;
        weight_percent(self.weight_percent)?;
        if self.free.is_empty() {
            return Err(bad("free", "", "name at least one parameter, e.g. weight_percent"));
        }
        if let Some(b) = &self.bounds
            && b.0.len() != self.free.len()
        {
            return Err(bad(
                "bounds",
                b,
                format!("{} entries for {} free parameter(s): one per free parameter", b.0.len(), self.free.len()),
            ));
        }
        if !(self.rel_error > 0.0 && self.rel_error < 1.0) {
            return Err(bad("rel_error", self.rel_error, "must lie in (0, 1)"));
        }
        paths(self.paths)?;
        if !(self.measured_rel_sd > 0.0 && self.measured_rel_sd <= 1.0) {
            return Err(bad(
                "measured_rel_sd",
                self.measured_rel_sd,
                "must lie in (0, 1] (the relative uncertainty of each measured slice)",
            ));
        }
        threshold(self.threshold)
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["fit"]);
        l.flag("--recipe", s(&self.recipe)).word("--measured").words(&self.measured);
        l.opt("--measured-pixel-mm", &self.measured_pixel_mm)
            .opt("--weight-percent", &self.weight_percent)
            .flag("--free", self.free.iter().map(FreeSpec::to_string).collect::<Vec<_>>().join(","))
            .flag("--wavelength-nm", self.wavelength_nm)
            .flag("--seed", self.seed)
            .switch("--quiet", self.quiet)
            .flag("--objective", self.objective.name())
            .flag("--rel-error", self.rel_error)
            .opt("--paths", &self.paths)
            .flag("--measured-rel-sd", self.measured_rel_sd);
        if let Some(b) = &self.bounds {
            l.word(format!("--bounds={b}"));
        }
        l.flag("--threshold", self.threshold).flag("--out", s(&self.out));
        if self.beam_fwhm_um != slab_defaults::beam_fwhm_um() {
            l.word(format!("--beam-fwhm-um={}", self.beam_fwhm_um));
        }
        l.opt("--beam-map", &self.beam_map.as_deref().map(s)).opt("--beam-map-pixel-mm", &self.beam_map_pixel_mm);
        if self.pilot_time_s != fit_defaults::pilot_time_s() {
            l.word(format!("--pilot-time-s={}", self.pilot_time_s));
        }
        if let Some(t) = self.thickness_mm {
            l.word(format!("--thickness-mm={t}"));
        }
        l.0
    }
}

/// `lucent calibrate`: camera intrinsics from chessboard photos
/// ([`CalibrateJob::run`]). The keys at their defaults are not written into
/// a stage's job.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CalibrateJob {
    /// Files, folders or glob patterns (free text: a pattern is matched
    /// against the disk when the command runs).
    pub images: Vec<String>,
    /// Inner corners ("COLSxROWS" as text).
    pub board: BoardSize,
    pub square_mm: f64,
    pub out: PathBuf,
    pub model: lucent_calib::model::DistortionModel,
    /// `--detector`: the corner detector (auto, sector-based or classic).
    #[serde(default = "default_detector", with = "by_name", skip_serializing_if = "is_default_detector")]
    pub detector: lucent_calib::cv::Detector,
    /// `--quiet`: no progress lines.
    #[serde(default, skip_serializing_if = "is_false")]
    pub quiet: bool,
}

fn default_detector() -> lucent_calib::cv::Detector {
    lucent_calib::cv::Detector::Auto
}
fn is_default_detector(d: &lucent_calib::cv::Detector) -> bool {
    *d == default_detector()
}

impl CalibrateJob {
    /// The photos `images` of `board` into the camera file `out`, the
    /// detector and progress lines at their defaults.
    pub fn new(
        images: Vec<String>,
        board: BoardSize,
        square_mm: f64,
        out: PathBuf,
        model: lucent_calib::model::DistortionModel,
    ) -> Self {
        CalibrateJob { images, board, square_mm, out, model, detector: default_detector(), quiet: false }
    }
    pub fn validate(&self) -> Result<(), JobError> {
        board(self.board, self.square_mm).map(drop)
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["calibrate"]);
        l.word("--images").words(&self.images);
        l.flag("--board", self.board)
            .flag("--square-mm", self.square_mm)
            .flag("--out", s(&self.out))
            .flag("--model", self.model.name());
        if !is_default_detector(&self.detector) {
            l.flag("--detector", <&str>::from(self.detector));
        }
        l.switch("--quiet", self.quiet);
        l.0
    }
}

/// `lucent colour calibrate`: a camera's colour correction from a chart
/// photo ([`ColourCalibrateJob::run`]). The keys at their defaults are not
/// written into a stage's job.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColourCalibrateJob {
    pub image: PathBuf,
    /// The camera's name (free text, written into the ccm.json).
    pub camera: Option<String>,
    pub out: PathBuf,
    /// The chart's four corners in pixels ("x1,y1,…,x4,y4" as text), else
    /// found by OpenCV's mcc.
    pub corners: Option<ChartCorners>,
    #[serde(with = "by_name")]
    pub method: lucent_colour::ccm::CcmMethod,
    pub decode_srgb: bool,
    /// `--clip-level`: a pixel with a channel at or above it (as stored) is
    /// clipped, a number or "none" (the text the command reads when it runs).
    #[serde(default = "default_clip_level", skip_serializing_if = "is_default_clip_level")]
    pub clip_level: ClipLevel,
    /// `--gap-ratio`: the gap between patches as a fraction of the patch side.
    #[serde(default = "default_gap_ratio", skip_serializing_if = "is_default_gap_ratio")]
    pub gap_ratio: f64,
    /// `--inner-fraction`: the sampled square's side as a fraction of the patch side.
    #[serde(default = "default_inner_fraction", skip_serializing_if = "is_default_inner_fraction")]
    pub inner_fraction: f64,
}

/// The defaults of `lucent colour calibrate --clip-level`, `--gap-ratio` and `--inner-fraction`.
pub const DEFAULT_CLIP_LEVEL: &str = "0.99";
pub const DEFAULT_GAP_RATIO: f64 = 0.14;
pub const DEFAULT_INNER_FRACTION: f64 = 0.5;

fn default_clip_level() -> ClipLevel {
    ClipLevel::default()
}
fn is_default_clip_level(c: &ClipLevel) -> bool {
    *c == ClipLevel::default()
}
fn default_gap_ratio() -> f64 {
    DEFAULT_GAP_RATIO
}
fn is_default_gap_ratio(v: &f64) -> bool {
    *v == DEFAULT_GAP_RATIO
}
fn default_inner_fraction() -> f64 {
    DEFAULT_INNER_FRACTION
}
fn is_default_inner_fraction(v: &f64) -> bool {
    *v == DEFAULT_INNER_FRACTION
}

impl ColourCalibrateJob {
    /// The chart in `image` into `out`, every other flag at its default.
    pub fn new(image: PathBuf, out: PathBuf, method: lucent_colour::ccm::CcmMethod) -> Self {
        ColourCalibrateJob {
            image,
            camera: None,
            out,
            corners: None,
            method,
            decode_srgb: false,
            clip_level: default_clip_level(),
            gap_ratio: DEFAULT_GAP_RATIO,
            inner_fraction: DEFAULT_INNER_FRACTION,
        }
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["colour", "calibrate"]);
        l.flag("--image", s(&self.image))
            .opt("--camera", &self.camera)
            .flag("--out", s(&self.out))
            .opt("--corners", &self.corners)
            .flag("--method", self.method.name())
            .switch("--decode-srgb", self.decode_srgb);
        if !is_default_clip_level(&self.clip_level) {
            l.word(format!("--clip-level={}", self.clip_level));
        }
        if !is_default_gap_ratio(&self.gap_ratio) {
            l.word(format!("--gap-ratio={}", self.gap_ratio));
        }
        if !is_default_inner_fraction(&self.inner_fraction) {
            l.word(format!("--inner-fraction={}", self.inner_fraction));
        }
        l.0
    }
}

/// `lucent colour apply`: an image in a camera's RGB → a standard space
/// ([`ColourApplyJob::run`]). The keys at their defaults are not written
/// into a stage's job.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ColourApplyJob {
    pub ccm: PathBuf,
    pub input: PathBuf,
    pub output: PathBuf,
    #[serde(with = "by_name")]
    pub to: crate::ccm_file::ApplyTarget,
    /// `--variance-out` and `--seed`: the developed RAW photo's per-pixel
    /// variance from its noise model, and the seed of its realisations.
    pub variance_out: Option<(PathBuf, u64)>,
    /// `--bin`: the output binned K × K (1: not binned).
    pub bin: usize,
    /// `--adaptation`: the chromatic adaptation from the fitted D50 to the
    /// target's white (`null`: none).
    #[serde(default = "default_adaptation", skip_serializing_if = "is_default_adaptation")]
    pub adaptation: Option<lucent_colour::adaptation::Cat>,
    /// `--variance-realisations`: noise realisations averaged per pixel of `variance_out`.
    #[serde(default = "default_variance_realisations", skip_serializing_if = "is_default_variance_realisations")]
    pub variance_realisations: usize,
}

/// The defaults of `lucent colour apply --adaptation` and `--variance-realisations`.
pub const DEFAULT_ADAPTATION: Option<lucent_colour::adaptation::Cat> = Some(lucent_colour::adaptation::Cat::Bradford);
pub const DEFAULT_VARIANCE_REALISATIONS: usize = 16;

fn default_adaptation() -> Option<lucent_colour::adaptation::Cat> {
    DEFAULT_ADAPTATION
}
fn is_default_adaptation(c: &Option<lucent_colour::adaptation::Cat>) -> bool {
    *c == DEFAULT_ADAPTATION
}
fn default_variance_realisations() -> usize {
    DEFAULT_VARIANCE_REALISATIONS
}
fn is_default_variance_realisations(n: &usize) -> bool {
    *n == DEFAULT_VARIANCE_REALISATIONS
}

/// The word of `--adaptation` for a transform (`None`: "none").
pub fn adaptation_word(c: Option<lucent_colour::adaptation::Cat>) -> &'static str {
    use lucent_colour::adaptation::Cat;
    match c {
        Some(Cat::Bradford) => "bradford",
        Some(Cat::VonKries) => "von-kries",
        Some(Cat::Cat02) => "cat02",
        None => "none",
    }
}

impl ColourApplyJob {
    /// `ccm` applied to `input` into `output` in `to`, every other flag at its default.
    pub fn new(ccm: PathBuf, input: PathBuf, output: PathBuf, to: crate::ccm_file::ApplyTarget) -> Self {
        ColourApplyJob {
            ccm,
            input,
            output,
            to,
            variance_out: None,
            bin: 1,
            adaptation: DEFAULT_ADAPTATION,
            variance_realisations: DEFAULT_VARIANCE_REALISATIONS,
        }
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["colour", "apply"]);
        l.flag("--ccm", s(&self.ccm)).word(s(&self.input)).word(s(&self.output)).flag("--to", <&str>::from(self.to));
        if let Some((path, seed)) = &self.variance_out {
            l.flag("--variance-out", s(path)).flag("--seed", seed);
            if !is_default_variance_realisations(&self.variance_realisations) {
                l.flag("--variance-realisations", self.variance_realisations);
            }
        }
        if self.bin > 1 {
            l.flag("--bin", self.bin);
        }
        if !is_default_adaptation(&self.adaptation) {
            l.flag("--adaptation", adaptation_word(self.adaptation));
        }
        l.0
    }
}

/// `lucent raw clipped`: the mask of validly recorded pixels of a RAW
/// photo ([`RawClippedJob::run`]). The keys at their defaults are not
/// written into a stage's job.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawClippedJob {
    pub input: PathBuf,
    pub out: PathBuf,
    /// `--bin`: the mask of the photo binned K × K (1: not binned).
    pub bin: usize,
    /// `--level`: clipped at or above this fraction of the white level.
    #[serde(default = "default_clip_fraction", skip_serializing_if = "is_default_clip_fraction")]
    pub level: f32,
    /// `--dilate`: pixels within this many pixels of a clipped photosite are invalid too.
    #[serde(default = "default_dilate", skip_serializing_if = "is_default_dilate")]
    pub dilate: usize,
}

/// The defaults of `lucent raw clipped --level` and `--dilate`.
pub const DEFAULT_CLIPPED_LEVEL: f32 = 0.999;
pub const DEFAULT_DILATE: usize = 2;

fn default_clip_fraction() -> f32 {
    DEFAULT_CLIPPED_LEVEL
}
fn is_default_clip_fraction(v: &f32) -> bool {
    *v == DEFAULT_CLIPPED_LEVEL
}
fn default_dilate() -> usize {
    DEFAULT_DILATE
}
fn is_default_dilate(n: &usize) -> bool {
    *n == DEFAULT_DILATE
}

impl RawClippedJob {
    /// The mask of `input` into `out`, binned `bin` × `bin`, the level and
    /// dilation at their defaults.
    pub fn new(input: PathBuf, out: PathBuf, bin: usize) -> Self {
        RawClippedJob { input, out, bin, level: DEFAULT_CLIPPED_LEVEL, dilate: DEFAULT_DILATE }
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["raw", "clipped"]);
        l.word(s(&self.input)).flag("--out", s(&self.out));
        if self.bin > 1 {
            l.flag("--bin", self.bin);
        }
        if !is_default_clip_fraction(&self.level) {
            l.word(format!("--level={}", self.level));
        }
        if !is_default_dilate(&self.dilate) {
            l.flag("--dilate", self.dilate);
        }
        l.0
    }
}

/// `lucent pose`: the board's (and sample's) pose in one photo
/// ([`PoseJob::run`]). The keys at their defaults are not written into a
/// stage's job.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PoseJob {
    pub camera: PathBuf,
    pub image: PathBuf,
    /// Inner corners ("COLSxROWS" as text).
    pub board: BoardSize,
    pub square_mm: f64,
    pub out: PathBuf,
    /// `--sample-corner` and `--sample-size-mm`: the board corner under the
    /// sample's corner and the sample's size ("I,J" and "W,H,T" in mm as text).
    pub sample: Option<(SampleCorner, SampleSizeMm)>,
    /// `--keep-all`: the photo will be undistorted keeping every pixel (the
    /// scene's intrinsics are those).
    #[serde(default, skip_serializing_if = "is_false")]
    pub keep_all: bool,
}

/// The largest sample side `lucent pose` takes, in units of the board's
/// larger side (a sample lies on the board).
pub const SAMPLE_PER_BOARD_MAX: f64 = 10.0;

/// Why a sample of `size_mm` (width, height, thickness) cannot lie on a
/// board of `cols` × `rows` inner corners and `square_mm` squares (a side
/// more than [`SAMPLE_PER_BOARD_MAX`] × the board's larger side: a size in
/// the wrong unit), if it cannot.
pub fn sample_size_problem(size_mm: [f64; 3], cols: usize, rows: usize, square_mm: f64) -> Option<String> {
    let extent_mm = (cols.max(rows) + 1) as f64 * square_mm;
    let big = size_mm.iter().find(|v| **v > SAMPLE_PER_BOARD_MAX * extent_mm)?;
    Some(format!(
        "{big} mm is more than {SAMPLE_PER_BOARD_MAX}× the {cols}x{rows} board's {extent_mm} mm (squares of \
         {square_mm} mm); give the sample's size in millimetres"
    ))
}

impl PoseJob {
    pub fn validate(&self) -> Result<(), JobError> {
        let b = board(self.board, self.square_mm)?;
        if let Some((_, size)) = &self.sample
            && let Some(reason) = sample_size_problem(size.mm(), b.cols, b.rows, self.square_mm)
        {
            return Err(bad("sample_size_mm", size, reason));
        }
        Ok(())
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["pose"]);
        l.flag("--camera", s(&self.camera))
            .flag("--image", s(&self.image))
            .flag("--board", self.board)
            .flag("--square-mm", self.square_mm)
            .flag("--out", s(&self.out));
        if let Some((c, z)) = &self.sample {
            l.flag("--sample-corner", c).flag("--sample-size-mm", z);
        }
        l.switch("--keep-all", self.keep_all);
        l.0
    }
}

/// `lucent env fit-scale`: the environment's scale from an empty-board photo.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvScaleJob {
    pub scene: PathBuf,
    pub photo: PathBuf,
    pub spp: Option<u32>,
    pub per_channel: bool,
    pub mask: Option<PathBuf>,
    /// The render's size ("WIDTHxHEIGHT" as text; else the scene camera's).
    pub size: Option<ImageSize>,
    pub seed: Option<u64>,
    pub out: PathBuf,
    /// `--quiet`: no progress bar or progress lines.
    #[serde(default, skip_serializing_if = "is_false")]
    pub quiet: bool,
    /// `--threads`: worker threads of the render (default: the allocation, else all cores).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threads: Option<usize>,
}

impl EnvScaleJob {
    pub fn validate(&self) -> Result<(), JobError> {
        at_least_one("spp", self.spp)
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["env", "fit-scale"]);
        l.word(s(&self.scene))
            .flag("--photo", s(&self.photo))
            .opt("--spp", &self.spp)
            .switch("--per-channel", self.per_channel);
        l.opt("--mask", &self.mask.as_deref().map(s))
            .opt("--size", &self.size)
            .opt("--seed", &self.seed)
            .flag("--out", s(&self.out))
            .switch("--quiet", self.quiet)
            .opt("--threads", &self.threads);
        l.0
    }
}

/// `dispersion`: refraction where the bands' indices differ.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, strum::IntoStaticStr)]
#[serde(rename_all = "kebab-case")]
#[strum(serialize_all = "kebab-case")]
pub enum DispersionKey {
    /// Exact: one band per path.
    PerBand,
    /// The bands' mean index for directions, Fresnel per band (approximate).
    SharedDirections,
}

impl From<DispersionKey> for lucent_render::tracer::Dispersion {
    fn from(d: DispersionKey) -> Self {
        match d {
            DispersionKey::PerBand => Self::PerBand,
            DispersionKey::SharedDirections => Self::SharedDirections,
        }
    }
}

/// `--sampling`'s word for a `[render] sampling` value.
pub fn sampling_name(k: crate::scene::SamplingKey) -> &'static str {
    match k {
        crate::scene::SamplingKey::Uniform => "uniform",
        crate::scene::SamplingKey::ObjectWeighted => "object-weighted",
    }
}

/// `lucent render SCENE`: the digital twin ([`RenderJob::run`]). The
/// flags a stage of `lucent run` leaves at their defaults are not written
/// into its job.json.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RenderJob {
    pub scene: PathBuf,
    pub spp: Option<u32>,
    pub quiet: bool,
    pub time_s: Option<f64>,
    /// The image size ("WIDTHxHEIGHT" as text; else the scene camera's).
    pub size: Option<ImageSize>,
    pub seed: Option<u64>,
    /// `--uncertainty`: the band from the recipe's uncertain inputs (uncertainty.json, band.exr).
    pub uncertainty: bool,
    pub out: PathBuf,
    /// `--exposure`: of the PNG preview, in stops.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub exposure: f64,
    /// `--target-rel-error`: stop at this median relative error over the object's pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_rel_error: Option<f64>,
    /// `--sampling`: how samples are spread over the pixels.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sampling: Option<crate::scene::SamplingKey>,
    /// `--dispersion`: refraction where the bands' indices differ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dispersion: Option<DispersionKey>,
    /// `--similarity-g`: walk the object's similar medium of this asymmetry.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub similarity_g: Option<f64>,
    /// `--split-entry`: follow reflection and refraction where a path enters the object.
    #[serde(default, skip_serializing_if = "is_false")]
    pub split_entry: bool,
    /// `--shard K/N`: only the K-th of N ranges of sample indices.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shard: Option<ShardSpec>,
    /// `--uncertainty-spp`: samples per pixel of each render at ±1 σ.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub uncertainty_spp: Option<u32>,
    /// `--uncertainty-renders`: every uncertain input by renders at ±1 σ.
    #[serde(default, skip_serializing_if = "is_false")]
    pub uncertainty_renders: bool,
    /// `--threads`: worker threads (default: the allocation, else all cores).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub threads: Option<usize>,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

impl RenderJob {
    pub fn validate(&self) -> Result<(), JobError> {
        at_least_one("spp", self.spp)?;
        positive_opt("time_s", self.time_s)
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["render"]);
        l.word(s(&self.scene)).opt("--spp", &self.spp).switch("--quiet", self.quiet).opt("--time-s", &self.time_s);
        l.opt("--size", &self.size).opt("--seed", &self.seed).switch("--uncertainty", self.uncertainty);
        l.flag("--out", s(&self.out));
        if !is_zero(&self.exposure) {
            l.flag("--exposure", self.exposure);
        }
        l.opt("--target-rel-error", &self.target_rel_error)
            .opt("--sampling", &self.sampling.map(sampling_name))
            .opt("--dispersion", &self.dispersion.map(<&str>::from))
            .opt("--similarity-g", &self.similarity_g)
            .switch("--split-entry", self.split_entry)
            .opt("--shard", &self.shard)
            .opt("--uncertainty-spp", &self.uncertainty_spp)
            .switch("--uncertainty-renders", self.uncertainty_renders)
            .opt("--threads", &self.threads);
        l.0
    }
}

/// `lucent compare`: photo against one or two renders ([`CompareJob::run`]).
/// The keys a stage of `lucent run` leaves at their defaults are not
/// written into its job.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CompareJob {
    pub photo: PathBuf,
    pub render: Vec<PathBuf>,
    pub out: PathBuf,
    pub mask: Option<PathBuf>,
    /// `--mask-object`: only the object's pixels (a scene JSON or a render
    /// EXR with an `object` layer), intersected with `mask`.
    pub mask_object: Option<PathBuf>,
    /// `--mask-board`: only the board's pixels (a scene JSON or a render
    /// EXR with a `board` layer), intersected with `mask`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mask_board: Option<PathBuf>,
    /// `--photo-variance`: the photo's per-pixel variance (EXR).
    pub photo_variance: Option<PathBuf>,
    /// `--photo-repeat`: a second photo of the same view, for the photo's variance.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub photo_repeat: Option<PathBuf>,
    /// `--scene`: the scene JSON whose board region ECC aligns on.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene: Option<PathBuf>,
    pub data_range: f64,
    /// `--luminance`: the weights of SSIM's Y, the difference picture and ECC.
    #[serde(default, with = "by_name", skip_serializing_if = "is_default_luminance")]
    pub luminance: crate::compare::Luminance,
    /// `--exposure`: triplet.png's display exposure (default: from the photo).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposure: Option<f64>,
    /// `--refine ecc --refine-motion M`: also align the render to the photo with this motion.
    #[serde(default, with = "by_name_opt", skip_serializing_if = "Option::is_none")]
    pub refine: Option<lucent_calib::ecc::Motion>,
    /// `--twin-names A,B`: what the two renders are (e.g. "recipe,fitted"),
    /// for the rows of the twins' triplet.png.
    pub twin_names: Option<[String; 2]>,
    /// `--band`: each render's uncertainty.json, in the renders' order.
    pub band: Vec<PathBuf>,
}

fn is_default_luminance(l: &crate::compare::Luminance) -> bool {
    *l == crate::compare::Luminance::default()
}

/// The default of `lucent compare --data-range`.
pub const DEFAULT_DATA_RANGE: f64 = 1.0;

impl CompareJob {
    /// The photo against `render` (one or two twins) into `out`, every
    /// other flag at its default.
    pub fn new(photo: PathBuf, render: Vec<PathBuf>, out: PathBuf) -> Self {
        CompareJob {
            photo,
            render,
            out,
            mask: None,
            mask_object: None,
            mask_board: None,
            photo_variance: None,
            photo_repeat: None,
            scene: None,
            data_range: DEFAULT_DATA_RANGE,
            luminance: Default::default(),
            exposure: None,
            refine: None,
            twin_names: None,
            band: Vec::new(),
        }
    }

    pub fn validate(&self) -> Result<(), JobError> {
        if let (Some(_), Some(p)) = (&self.photo_variance, &self.photo_repeat) {
            return Err(bad("photo_repeat", s(p), "give the photo's variance or a repeat photo, not both"));
        }
        if let (Some(_), Some(p)) = (&self.mask_object, &self.mask_board) {
            return Err(bad("mask_board", s(p), "compare the object's pixels or the board's, not both"));
        }
        crate::compare::ssim::SsimParams::new(self.data_range)
            .map(drop)
            .map_err(|e| bad("data_range", self.data_range, e.to_string()))
    }
    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["compare"]);
        l.flag("--photo", s(&self.photo));
        l.words(self.render.iter().flat_map(|r| ["--render".to_string(), s(r)]));
        l.flag("--out", s(&self.out)).opt("--mask", &self.mask.as_deref().map(s));
        l.opt("--mask-object", &self.mask_object.as_deref().map(s));
        l.opt("--mask-board", &self.mask_board.as_deref().map(s));
        l.opt("--photo-variance", &self.photo_variance.as_deref().map(s)).flag("--data-range", self.data_range);
        l.opt("--photo-repeat", &self.photo_repeat.as_deref().map(s));
        l.opt("--scene", &self.scene.as_deref().map(s));
        if !is_default_luminance(&self.luminance) {
            l.flag("--luminance", <&str>::from(self.luminance));
        }
        l.opt("--exposure", &self.exposure);
        if let Some(m) = self.refine {
            l.flag("--refine", "ecc").flag("--refine-motion", <&str>::from(m));
        }
        l.opt("--twin-names", &self.twin_names.as_ref().map(|[a, b]| format!("{a},{b}")));
        l.words(self.band.iter().flat_map(|b| ["--band".to_string(), s(b)]));
        l.0
    }
}

/// Any job: a pipeline stage's, or a command's that `lucent job run` runs
/// from a file as well (`surface fit`, `env merge`, `env orient`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum Job {
    Optics(OpticsJob),
    Bssrdf(BssrdfJob),
    BssrdfCompare(BssrdfCompareJob),
    Fit(FitJob),
    Calibrate(CalibrateJob),
    ColourCalibrate(ColourCalibrateJob),
    ColourApply(ColourApplyJob),
    RawClipped(RawClippedJob),
    Pose(PoseJob),
    EnvScale(EnvScaleJob),
    Render(RenderJob),
    Compare(CompareJob),
    SurfaceFit(SurfaceFitJob),
    EnvMerge(EnvMergeJob),
    EnvOrient(EnvOrientJob),
}

impl Job {
    /// Checks every field against the range its flag accepts.
    pub fn validate(&self) -> Result<(), JobError> {
        match self {
            Job::Optics(j) => j.validate(),
            Job::Bssrdf(j) => j.validate(),
            Job::BssrdfCompare(j) => j.validate(),
            Job::Fit(j) => j.validate(),
            Job::Calibrate(j) => j.validate(),
            Job::Pose(j) => j.validate(),
            Job::EnvScale(j) => j.validate(),
            Job::Render(j) => j.validate(),
            Job::Compare(j) => j.validate(),
            Job::SurfaceFit(j) => j.validate(),
            Job::EnvMerge(j) => j.validate(),
            Job::EnvOrient(j) => j.validate(),
            Job::ColourCalibrate(_) | Job::ColourApply(_) | Job::RawClipped(_) => Ok(()),
        }
    }

    /// The command's name as `lucent` spells it ("render", "bssrdf compare", …).
    pub fn command_name(&self) -> &'static str {
        match self {
            Job::Optics(_) => "optics",
            Job::Bssrdf(_) => "bssrdf",
            Job::BssrdfCompare(_) => "bssrdf compare",
            Job::Fit(_) => "fit",
            Job::Calibrate(_) => "calibrate",
            Job::ColourCalibrate(_) => "colour calibrate",
            Job::ColourApply(_) => "colour apply",
            Job::RawClipped(_) => "raw clipped",
            Job::Pose(_) => "pose",
            Job::EnvScale(_) => "env fit-scale",
            Job::Render(_) => "render",
            Job::Compare(_) => "compare",
            Job::SurfaceFit(_) => "surface fit",
            Job::EnvMerge(_) => "env merge",
            Job::EnvOrient(_) => "env orient",
        }
    }

    /// The job with the placeholder `{out}` in every path and word replaced
    /// by `dir` (the stage folder).
    pub fn with_out(&self, dir: &Path) -> Result<Job, serde_json::Error> {
        fn replace(v: &mut serde_json::Value, dir: &str) {
            match v {
                serde_json::Value::String(t) if t.contains("{out}") => *t = t.replace("{out}", dir),
                serde_json::Value::Array(a) => a.iter_mut().for_each(|v| replace(v, dir)),
                serde_json::Value::Object(o) => o.values_mut().for_each(|v| replace(v, dir)),
                _ => {}
            }
        }
        let mut v = serde_json::to_value(self)?;
        replace(&mut v, &s(dir));
        serde_json::from_value(v)
    }

    /// The job as one run's identity: what does not change the result left
    /// out (`out`, `quiet`) and the input paths canonical (an existing file's
    /// real path, else the absolute path), so the same run spelled with a
    /// relative or an absolute path, or written to another folder, is one job.
    pub fn normalised(&self) -> Job {
        let canon = |p: &Path| std::fs::canonicalize(p).or_else(|_| std::path::absolute(p)).unwrap_or(p.to_path_buf());
        let mut j = self.clone();
        match &mut j {
            Job::Optics(o) => {
                o.recipes = o.recipes.iter().map(|r| canon(r)).collect();
                o.out = o.out.as_ref().map(|_| PathBuf::new());
                o.shard = None;
            }
            Job::Bssrdf(b) => {
                b.recipe = b.recipe.as_deref().map(canon);
                b.beam_map = b.beam_map.as_deref().map(canon);
                b.out = PathBuf::new();
                b.quiet = false;
                b.shard = None;
            }
            Job::Render(r) => {
                r.scene = canon(&r.scene);
                r.out = PathBuf::new();
                r.quiet = false;
                r.threads = None;
                r.shard = None;
            }
            Job::EnvScale(e) => {
                e.scene = canon(&e.scene);
                e.photo = canon(&e.photo);
                e.mask = e.mask.as_deref().map(canon);
                e.out = PathBuf::new();
                e.quiet = false;
                e.threads = None;
            }
            Job::Fit(f) => {
                f.recipe = canon(&f.recipe);
                f.beam_map = f.beam_map.as_deref().map(canon);
                f.out = PathBuf::new();
                f.quiet = false;
            }
            Job::BssrdfCompare(c) => {
                c.measured = canon(&c.measured);
                c.simulated = canon(&c.simulated);
                c.out = PathBuf::new();
            }
            Job::Calibrate(c) => {
                c.out = PathBuf::new();
                c.quiet = false;
            }
            Job::ColourCalibrate(c) => {
                c.image = canon(&c.image);
                c.out = PathBuf::new();
            }
            Job::ColourApply(_) | Job::RawClipped(_) => {}
            Job::Pose(p) => {
                p.camera = canon(&p.camera);
                p.image = canon(&p.image);
                p.out = PathBuf::new();
            }
            Job::Compare(c) => {
                c.photo = canon(&c.photo);
                c.render = c.render.iter().map(|r| canon(r)).collect();
                c.out = PathBuf::new();
            }
            Job::SurfaceFit(f) => {
                f.heightmap = canon(&f.heightmap);
                f.out = PathBuf::new();
            }
            Job::EnvMerge(m) => {
                m.brackets = m.brackets.iter().map(|b| canon(b)).collect();
                m.out = PathBuf::new();
            }
            Job::EnvOrient(o) => {
                o.input = canon(&o.input);
                o.out = PathBuf::new();
            }
        }
        j
    }

    /// SHA-256 (hex) of the [`normalised`](Job::normalised) job as JSON:
    /// the run a job's shards belong to, however its command line was spelled.
    pub fn identity_sha256(&self) -> String {
        json_sha256(&self.normalised())
    }

    /// The canonical `lucent` command line (without the program name).
    pub fn to_args(&self) -> Vec<String> {
        match self {
            Job::Optics(j) => j.to_args(),
            Job::Bssrdf(j) => j.to_args(),
            Job::BssrdfCompare(j) => j.to_args(),
            Job::Fit(j) => j.to_args(),
            Job::Calibrate(j) => j.to_args(),
            Job::ColourCalibrate(j) => j.to_args(),
            Job::ColourApply(j) => j.to_args(),
            Job::RawClipped(j) => j.to_args(),
            Job::Pose(j) => j.to_args(),
            Job::EnvScale(j) => j.to_args(),
            Job::Render(j) => j.to_args(),
            Job::Compare(j) => j.to_args(),
            Job::SurfaceFit(j) => j.to_args(),
            Job::EnvMerge(j) => j.to_args(),
            Job::EnvOrient(j) => j.to_args(),
        }
    }
}

/// The stop rule of a render job ([`lucent_render::stop::Stop`]), which
/// the shard planner asks.
impl RenderJob {
    /// The stop rule the job's flags give: samples per pixel (`spp`) and a
    /// time budget in seconds (`time_s`). The scene file may add its own
    /// ([`crate::scene::RenderSection::stop`]), and `lucent render` a
    /// default error target where neither gives a sample count.
    pub fn stop(&self) -> lucent_render::stop::Stop {
        lucent_render::stop::Stop {
            samples: self.spp.map(u64::from),
            time_s: self.time_s,
            ..lucent_render::stop::Stop::default()
        }
    }
}

/// SHA-256 of `bytes`, lower-case hex: the one spelling of a hash the
/// jobs and the pipeline write (a stage's key, a job's and a shard run's
/// identity).
///
/// ```
/// assert_eq!(&lucent::job::sha256_hex(b"abc")[..16], "ba7816bf8f01cfea");
/// ```
pub fn sha256_hex(bytes: &[u8]) -> String {
    format!("{:x}", Sha256::digest(bytes))
}

/// SHA-256 (hex) of a value as JSON: a job's and a shard run's identity.
pub(crate) fn json_sha256(v: &impl Serialize) -> String {
    sha256_hex(serde_json::to_string(v).unwrap_or_default().as_bytes())
}

/// A job file's `roughness`, read as `--roughness` reads it; a bad text's
/// message names the field and the valid words.
fn roughness_field<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<crate::bssrdf::RoughnessSpec>, D::Error> {
    let text = String::deserialize(d)?;
    text.parse().map(Some).map_err(|e| serde::de::Error::custom(format!("roughness {e}")))
}
