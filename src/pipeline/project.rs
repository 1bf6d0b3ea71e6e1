//! Project files for `lucent run`: one TOML file naming a digitisation's
//! inputs, validated in two stages — the file as typed ([`ProjectFile`],
//! unknown keys rejected), then [`Project`] with every path resolved
//! relative to the project file and checked to exist.
//!
//! ```toml
//! [project]
//! name = "demo"                  # default: the file's stem
//! seed = 1                       # every stochastic stage's seed
//! # out = "out"                  # output folder, relative to this file (default lucent-out/NAME; --out wins)
//!
//! [optics]                       # stage optics: every sample's recipe
//! wavelengths = "380:780:10"
//!
//! # [surface]                    # stage surface: `lucent surface fit` of each sample's `surface` height map
//! # window = 15                  # the flags of `surface fit`, same names, ranges and defaults
//!
//! [bssrdf]                       # stage bssrdf: slab slices per sample (and comparison with measurements)
//! wavelength_nm = 550.0
//! configs = "45/0"               # θi/θo pairs, φi = 0°, φo = 180°
//! pixels = 259                   # camera pixels per side
//! pixel_mm = 0.1029
//! # crop = 117
//! paths = 200000                 # stop rule: paths, rel_error and/or time_s
//! # roughness = "smooth"         # top boundary, as `lucent bssrdf --roughness` (default: the sample's fitted
//!                                # surface from stage surface, else the recipe's [surface], else smooth)
//!
//! [calibration]                  # stage calibrate: Zhang's method
//! images = "photos/board_*.jpg"  # wildcards in the file name
//! board = "9x6"                  # inner corners
//! square_mm = 25.0
//! # truth = "camera.json"        # a known camera (calibrate's format): the report tabulates recovered − truth
//!
//! [[colour]]                     # stage colour: one ColorChecker per camera
//! camera = "phone"
//! image = "chart.exr"
//! # corners = "x1,y1,x2,y2,x3,y3,x4,y4"   # else found by OpenCV's mcc
//! # truth = "truth_colour.json"  # a known camera response (`lucent synth`): the report tabulates recovered vs truth
//!
//! [pose]                         # stage pose: the board's pose in the sample photo (needs calibrate)
//! image = "photos/sample.jpg"
//! sample_corner = "2,1"
//! sample_size_mm = "100,60,6.35"
//! # truth = "views/view1.toml"   # a scene whose [camera] camera_to_world is the known pose: the report compares
//!
//! [render]                       # stages env-scale, render: the scene template (a scene file)
//! scene = "scene.toml"           # its [material] recipe is replaced by each sample's
//! # spp = 1024                  # default: the scene's stop rule, else 5 % per pixel on the object
//! # size = "320x240"
//! # camera = "template"           # keep the template's camera; default with a [pose]: the pose stage's
//! # uncertainty = true            # each twin with its band from its recipe's uncertain inputs (the fitted
//! #                               # twin's: the fit's standard errors); compare: is the photo within it?
//!
//! [compare]
//! data_range = 1.0
//!
//! [fit]                          # stage fit: each sample's recipe fitted to its measured slices
//! free = ["weight_percent"]      # weight_percent, diameter_um, real_part_n (NAME@K for particle type K)
//! # objective = "sum"            # or "msre"
//! # rel_error = 0.01             # target relative error of the simulated sums at the final points
//! # measured_rel_sd = 0.05       # relative uncertainty of each measured slice
//! # render and compare then make and score both twins: the recipe's and the fitted one
//!
//! [[sample]]
//! name = "IOL1068-09"
//! recipe = "samples/IOL1068-09.toml"
//! # photo = "photo.exr"              # stage compare: the photograph (render's size, linear; with a
//!                                    # camera also K times the render's size, which develop bins K × K)
//! # camera = "phone"                 # photo and empty_board are that [[colour]] camera's RGB (RAW or EXR):
//!                                    # stage develop turns them into CIE RGB with its ccm.json
//! # empty_board = "empty.exr"        # stage env-scale: the board photographed without the sample
//! # truth_recipe = "truth.toml"      # synthetic data: the known recipe, tabulated beside the fit (report only)
//! # surface = "heights.x3p"          # stage surface: a measured height map of the top; its fitted normals
//!                                    # are the top boundary of the sample's BSSRDF slices
//! # [[sample.measured]]              # stage bssrdf: measured slices to score; stage fit: to fit
//! # config = "45/0"
//! # file = "slice.exr"
//! ```

pub use crate::bssrdf::{ConfigError, Configuration, Configurations};
use crate::fit::{FreeSpec, SearchBounds};
use crate::job::{
    BssrdfCompareJob, BssrdfJob, CalibrateJob, CompareJob, EnvScaleJob, FitJob, ImageSize, JobError, MeasuredAngles,
    MeasuredSlice, PoseJob, RenderJob, SampleCorner, SampleSizeMm, SurfaceFitJob,
};
use crate::surface::model::RoughnessSpec;
use lucent_calib::board::BoardSize;
use lucent_calib::model::DistortionModel;
use lucent_colour::{CcmMethod, WavelengthGrid};
use lucent_render::stop::{NotSplittable, Stop};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// A project file that cannot be used; every variant names the file.
#[derive(Debug, Error)]
pub enum ProjectError {
    #[error("{path}: cannot read project file: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    /// Not valid TOML, or a key the format does not have: the parser's
    /// message led by the key it concerns, with the 1-based line and column
    /// it points at.
    #[error("{path}:{}{message}", crate::scene::location(*line, *column))]
    Toml { path: PathBuf, line: Option<usize>, column: Option<usize>, message: String },
    #[error("{path}: {key}: {reason}")]
    Key { path: PathBuf, key: String, reason: String },
    /// Several keys with values out of range, each with its reason.
    #[error("{path}: {} values out of range:{}", problems.len(), problems.iter().map(|(k, r)| format!("\n  {k}: {r}")).collect::<String>())]
    Keys { path: PathBuf, problems: Vec<(String, String)> },
}

/// The project file as typed.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectFile {
    #[serde(default)]
    pub project: ProjectSection,
    pub optics: Option<OpticsSection>,
    /// The `surface fit` settings of stage surface (its defaults without it).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface: Option<SurfaceSection>,
    pub bssrdf: Option<BssrdfSection>,
    pub calibration: Option<CalibrationSection>,
    #[serde(default)]
    pub colour: Vec<ColourSection>,
    pub pose: Option<PoseSection>,
    pub render: Option<RenderSection>,
    pub compare: Option<CompareSection>,
    pub fit: Option<FitSection>,
    #[serde(default)]
    pub sample: Vec<SampleSection>,
    /// Where long commands run ([`super::executor`]).
    pub executor: Option<super::executor::ExecutorSection>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ProjectSection {
    pub name: Option<String>,
    pub seed: Option<u64>,
    pub out: Option<PathBuf>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct OpticsSection {
    /// "START:END:STEP" in nm (default 380:780:10).
    pub wavelengths: Option<WavelengthGrid>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct BssrdfSection {
    pub wavelength_nm: Option<f64>,
    /// θi/θo pairs in degrees, "45/0,0/45" (default 45/0).
    pub configs: Option<Configurations>,
    pub pixels: Option<usize>,
    pub pixel_mm: Option<f64>,
    pub crop: Option<usize>,
    pub paths: Option<u64>,
    pub rel_error: Option<f64>,
    pub time_s: Option<f64>,
    /// Any spelling `lucent bssrdf --phase` reads.
    #[serde(default, deserialize_with = "phase_model")]
    pub phase: Option<crate::optics::PhaseModel>,
    pub threshold: Option<f64>,
    /// The top boundary, as `lucent bssrdf --roughness` reads it (a
    /// `measured:` path relative to the project file). Default: the
    /// sample's fitted surface (stage surface), else the recipe's
    /// `[surface]`, else smooth.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub roughness: Option<RoughnessSpec>,
}

/// `[surface]`: the flags of `lucent surface fit` that a project sets for
/// every sample's height map (`[[sample]] surface`), with the flags' names,
/// ranges and defaults ([`SurfaceFitJob`]).
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SurfaceSection {
    /// Point spacing in µm (overrides the file's; required for TIFF, EXR and header-less text).
    pub pitch_um: Option<f64>,
    /// Row spacing in µm, if it differs (with `pitch_um`).
    pub pitch_y_um: Option<f64>,
    /// The unit of the stored heights: any spelling `surface fit --height-unit` reads.
    #[serde(default, deserialize_with = "height_unit", serialize_with = "height_unit_name")]
    pub height_unit: Option<crate::surface::LengthUnit>,
    /// Side of the plane fits' window in pixels (odd, 3 … 201; default 15).
    pub window: Option<usize>,
    /// σ of the plane fits' Gaussian weights in pixels (default 1).
    pub sigma_px: Option<f64>,
    /// The least fraction of the window's weight on valid points for a normal (default 0.9).
    pub min_weight: Option<f64>,
    /// Do not subtract the least-squares plane first.
    pub keep_tilt: Option<bool>,
    /// Fit a tilt of the distribution's axis too.
    pub fit_tilt: Option<bool>,
}

fn height_unit<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<crate::surface::LengthUnit>, D::Error> {
    crate::io::named(d, "height_unit")
}

fn height_unit_name<S: serde::Serializer>(v: &Option<crate::surface::LengthUnit>, s: S) -> Result<S::Ok, S::Error> {
    match v {
        Some(u) => s.serialize_str(<&str>::from(*u)),
        None => s.serialize_none(),
    }
}

impl BssrdfSection {
    /// `configs`, or the one configuration 45/0 without it.
    pub fn configurations(&self) -> Configurations {
        self.configs.clone().unwrap_or_else(|| Configuration { theta_i_deg: 45.0, theta_o_deg: 0.0 }.into())
    }

    /// The stop rule of each slice: `paths`, `time_s`, `rel_error` (as
    /// [`crate::job::BssrdfJob::stop`] of the stage's jobs).
    pub fn stop(&self) -> Stop {
        Stop { samples: self.paths, time_s: self.time_s, rel_error: self.rel_error, pixel_rel_error: None }
    }
}

#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CalibrationSection {
    /// A file pattern (free text, wildcards in the file name).
    pub images: String,
    /// Inner corners "COLSxROWS".
    pub board: BoardSize,
    pub square_mm: f64,
    /// Any spelling `lucent calibrate --model` reads.
    #[serde(default, deserialize_with = "distortion_model")]
    pub model: Option<DistortionModel>,
    /// The known camera of synthetic views (a `lucent calibrate` camera.json).
    pub truth: Option<PathBuf>,
}

fn phase_model<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<crate::optics::PhaseModel>, D::Error> {
    crate::io::named(d, "phase")
}

fn objective<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<crate::fit::Objective>, D::Error> {
    crate::io::named(d, "objective")
}

/// `[calibration] model`, read as `lucent calibrate --model` reads it (its
/// own serde form knows only the canonical names).
fn distortion_model<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<DistortionModel>, D::Error> {
    let name = String::deserialize(d)?;
    DistortionModel::from_name(&name).map(Some).map_err(serde::de::Error::custom)
}

#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ColourSection {
    /// The camera's name (it names a folder).
    pub camera: String,
    pub image: PathBuf,
    /// The chart's corners in pixels ("x1,y1,…,x4,y4" as text).
    pub corners: Option<crate::job::ChartCorners>,
    /// Any spelling `lucent colour calibrate --method` reads.
    pub method: Option<CcmMethod>,
    pub decode_srgb: Option<bool>,
    /// A `truth_colour.json` ([`crate::synth::ColourTruth`]): the camera's known response.
    pub truth: Option<PathBuf>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PoseSection {
    pub image: PathBuf,
    /// Inner corners "COLSxROWS" (default: `[calibration]`'s).
    pub board: Option<BoardSize>,
    pub square_mm: Option<f64>,
    /// "I,J": the board corner under the sample's corner.
    pub sample_corner: Option<SampleCorner>,
    /// "W,H,T": the sample's size in mm.
    pub sample_size_mm: Option<SampleSizeMm>,
    /// A scene file whose `[camera] camera_to_world` is the known pose (synthetic photos): the report compares.
    pub truth: Option<PathBuf>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RenderSection {
    pub scene: PathBuf,
    pub spp: Option<u32>,
    /// "WIDTHxHEIGHT" in pixels (default: the scene camera's).
    pub size: Option<ImageSize>,
    pub time_s: Option<f64>,
    pub env_spp: Option<u32>,
    pub per_channel_scale: Option<bool>,
    /// "pose" (the default with a `[pose]`) or "template".
    pub camera: Option<String>,
    /// Each twin rendered with its band from the recipe's uncertain inputs
    /// (`lucent render --uncertainty`; the fitted twin's from the fit's
    /// standard errors), and the compare stage says whether the photo lies
    /// within it.
    pub uncertainty: Option<bool>,
}

impl RenderSection {
    /// The stop rule of each render: `spp`, `time_s` (as
    /// [`crate::job::RenderJob::stop`] of the stage's jobs; the scene may add its own).
    pub fn stop(&self) -> Stop {
        Stop { samples: self.spp.map(u64::from), time_s: self.time_s, ..Stop::default() }
    }
}

#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CompareSection {
    pub data_range: Option<f64>,
}

/// `[fit]`: `lucent fit` on each sample's measured slices (`[[sample.measured]]`).
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct FitSection {
    /// Free parameters: `weight_percent`, `diameter_um`, `real_part_n`, each optionally `@K`.
    pub free: Vec<FreeSpec>,
    /// What the fit minimises (default: the slice sums); any spelling
    /// `lucent fit --objective` reads.
    #[serde(default, deserialize_with = "objective")]
    pub objective: Option<crate::fit::Objective>,
    /// Target relative error of each simulated slice sum at the final points.
    pub rel_error: Option<f64>,
    /// Light paths per configuration and evaluation instead of the pilot run.
    pub paths: Option<u64>,
    /// Relative uncertainty of each measured slice (default 0.05).
    pub measured_rel_sd: Option<f64>,
    /// Search bounds "LO:HI,…", one per free parameter.
    pub bounds: Option<SearchBounds>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SampleSection {
    pub name: String,
    pub recipe: PathBuf,
    pub weight_percent: Option<f64>,
    pub photo: Option<PathBuf>,
    pub empty_board: Option<PathBuf>,
    /// The `[[colour]]` camera whose RGB `photo` and `empty_board` are in (developed by stage develop).
    pub camera: Option<String>,
    #[serde(default)]
    pub measured: Vec<MeasuredSection>,
    /// A recipe with the sample's known values (synthetic data): the report
    /// tabulates them beside what stage fit recovered. Never read by a stage.
    pub truth_recipe: Option<PathBuf>,
    /// A measured height map of the sample's top (.x3p, text grid, TIFF,
    /// EXR): stage surface fits it, and its normals are the top boundary of
    /// the sample's BSSRDF slices unless `[bssrdf] roughness` is set.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub surface: Option<PathBuf>,
}

#[derive(Debug, Clone, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MeasuredSection {
    /// "θi/θo" in degrees.
    pub config: Configuration,
    pub file: PathBuf,
    pub pixel_mm: Option<f64>,
}

/// A validated project: paths absolute (or relative to the current folder
/// when the project file's path was), names unique, numbers in range.
#[derive(Debug, Clone)]
pub struct Project {
    pub path: PathBuf,
    pub name: String,
    pub seed: u64,
    /// The output folder the file asks for (None: the caller's default).
    pub out: Option<PathBuf>,
    pub file: ProjectFile,
    /// θi/θo pairs of `[bssrdf]` configs.
    pub bssrdf_configs: Vec<(f64, f64)>,
    /// The validated `[executor]` (local, one shard, without one).
    pub executor: super::executor::Executor,
}

/// Checks that a name from the project file (the project's, a sample's, a
/// camera's) can become a folder name under the output folder: 1 to 100
/// letters, digits, '-', '_' and '.', not starting with '.' (so never "."
/// or "..", a hidden name, a path or a control character).
///
/// ```
/// use lucent::pipeline::project::folder_name;
/// assert!(folder_name("IOL1068-09").is_ok());
/// for bad in ["", ".", "..", "a/b", "/", ".hidden", "a\0b", "tab\t"] {
///     assert!(folder_name(bad).is_err(), "{bad:?}");
/// }
/// ```
pub fn folder_name(name: &str) -> Result<(), &'static str> {
    if name.is_empty() || name.len() > 100 {
        return Err("must be 1 to 100 characters (it names a folder)");
    }
    if name.starts_with('.') {
        return Err("must not start with '.' (it names a folder; \".\" and \"..\" would leave the output folder)");
    }
    if !name.chars().all(|c| c.is_ascii_alphanumeric() || "-_.".contains(c)) {
        return Err("use letters, digits, '-', '_' and '.' only (a folder name)");
    }
    Ok(())
}

/// Sample `smp`'s slice job of `[bssrdf]` (outputs under `{out}/NAME`).
pub fn bssrdf_job(b: &BssrdfSection, smp: &SampleSection, seed: u64) -> BssrdfJob {
    BssrdfJob {
        recipe: Some(smp.recipe.clone()),
        wavelength_nm: b.wavelength_nm.unwrap_or(550.0),
        configs: Some(b.configurations()),
        pixels: b.pixels.unwrap_or(259),
        pixel_mm: b.pixel_mm.unwrap_or(0.1029),
        seed,
        quiet: true,
        out: PathBuf::from(format!("{{out}}/{}", smp.name)),
        weight_percent: smp.weight_percent,
        crop: b.crop,
        paths: b.paths,
        rel_error: b.rel_error,
        time_s: b.time_s,
        phase: b.phase,
        roughness: b.roughness.clone(),
        ..BssrdfJob::default()
    }
}

/// Sample `smp`'s surface-fit job of `[surface]` (its defaults without
/// one; outputs under `{out}/NAME`); None when the sample has no `surface`.
pub fn surface_job(sec: Option<&SurfaceSection>, smp: &SampleSection) -> Option<SurfaceFitJob> {
    let heightmap = smp.surface.clone()?;
    Some(surface_job_of(sec.cloned().unwrap_or_default(), heightmap, PathBuf::from(format!("{{out}}/{}", smp.name))))
}

fn surface_job_of(sec: SurfaceSection, heightmap: PathBuf, out: PathBuf) -> SurfaceFitJob {
    let d = SurfaceFitJob::new(heightmap, out);
    SurfaceFitJob {
        pitch_um: sec.pitch_um,
        pitch_y_um: sec.pitch_y_um,
        height_unit: sec.height_unit,
        window: sec.window.unwrap_or(d.window),
        sigma_px: sec.sigma_px.unwrap_or(d.sigma_px),
        min_weight: sec.min_weight.unwrap_or(d.min_weight),
        keep_tilt: sec.keep_tilt.unwrap_or(d.keep_tilt),
        fit_tilt: sec.fit_tilt.unwrap_or(d.fit_tilt),
        ..d
    }
}

/// Sample `smp`'s fit job of `[fit]` (the wavelength and threshold of `[bssrdf]`).
pub fn fit_job(fit: &FitSection, bssrdf: Option<&BssrdfSection>, smp: &SampleSection, seed: u64) -> FitJob {
    FitJob {
        recipe: smp.recipe.clone(),
        measured: smp
            .measured
            .iter()
            .map(|m| MeasuredSlice { path: m.file.clone(), angles: Some(MeasuredAngles::Plane(m.config)) })
            .collect(),
        measured_pixel_mm: smp.measured.first().and_then(|m| m.pixel_mm),
        weight_percent: smp.weight_percent,
        free: fit.free.clone(),
        wavelength_nm: bssrdf.and_then(|b| b.wavelength_nm).unwrap_or(550.0),
        seed,
        quiet: true,
        objective: fit.objective.unwrap_or(crate::fit::Objective::Sum),
        rel_error: fit.rel_error.unwrap_or(crate::job::DEFAULT_FIT_REL_ERROR),
        paths: fit.paths,
        measured_rel_sd: fit.measured_rel_sd.unwrap_or(crate::job::DEFAULT_MEASURED_REL_SD),
        bounds: fit.bounds.clone(),
        threshold: bssrdf.and_then(|b| b.threshold).unwrap_or(crate::job::DEFAULT_THRESHOLD),
        out: PathBuf::from(format!("{{out}}/{}", smp.name)),
        ..FitJob::default()
    }
}

/// The calibrate job of `[calibration]`.
pub fn calibrate_job(c: &CalibrationSection, out: PathBuf) -> CalibrateJob {
    CalibrateJob::new(vec![c.images.clone()], c.board, c.square_mm, out, c.model.unwrap_or(DistortionModel::PinholeK3))
}

/// The pose job of `[pose]` (board and square size from `[calibration]`
/// unless given); None without a board in either.
pub fn pose_job(
    p: &PoseSection,
    calibration: Option<&CalibrationSection>,
    camera: PathBuf,
    out: PathBuf,
) -> Option<PoseJob> {
    Some(PoseJob {
        camera,
        image: p.image.clone(),
        board: p.board.or(calibration.map(|c| c.board))?,
        square_mm: p.square_mm.or(calibration.map(|c| c.square_mm)).unwrap_or(20.0),
        out,
        sample: p.sample_corner.zip(p.sample_size_mm),
        keep_all: false,
    })
}

/// The values of the project that become job fields, checked by the jobs
/// ([`crate::job`]) with the ranges of the commands' flags: every problem,
/// as (project key, reason).
fn job_problems(file: &ProjectFile) -> Vec<(String, String)> {
    let mut problems = Vec::new();
    let mut check = |section: &str, prefix: &str, r: Result<(), JobError>| {
        if let Err(e) = r {
            let got = if e.value.is_empty() { String::new() } else { format!(", got {}", e.value) };
            problems.push((format!("{section} {prefix}{}", e.field), format!("{}{got}", e.reason)));
        }
    };
    let nobody = SampleSection::default();
    // ([optics] holds only its grid, whose type is its check.)
    if let Some(sf) = &file.surface {
        check("[surface]", "", surface_job_of(sf.clone(), PathBuf::new(), PathBuf::new()).validate());
    }
    if let Some(b) = &file.bssrdf {
        check("[bssrdf]", "", bssrdf_job(b, &nobody, 1).validate());
        let compare = BssrdfCompareJob {
            measured: PathBuf::new(),
            simulated: PathBuf::new(),
            out: PathBuf::new(),
            measured_pixel_mm: None,
            threshold: b.threshold.unwrap_or(crate::job::DEFAULT_THRESHOLD),
        };
        check("[bssrdf]", "", compare.validate());
    }
    if let Some(f) = &file.fit {
        check("[fit]", "", fit_job(f, None, &nobody, 1).validate());
    }
    if let Some(c) = &file.calibration {
        check("[calibration]", "", calibrate_job(c, PathBuf::new()).validate());
    }
    if let Some(p) = &file.pose
        && p.square_mm.is_some()
        && let Some(job) = pose_job(p, None, PathBuf::new(), PathBuf::new())
    {
        check("[pose]", "", job.validate());
    }
    if let Some(r) = &file.render {
        let job = RenderJob {
            scene: PathBuf::new(),
            spp: r.spp,
            quiet: true,
            time_s: r.time_s,
            size: r.size,
            seed: None,
            uncertainty: r.uncertainty == Some(true),
            out: PathBuf::new(),
            ..RenderJob::default()
        };
        check("[render]", "", job.validate());
        let env = EnvScaleJob {
            scene: PathBuf::new(),
            photo: PathBuf::new(),
            spp: r.env_spp,
            per_channel: false,
            mask: None,
            size: None,
            seed: None,
            out: PathBuf::new(),
            quiet: false,
            threads: None,
        };
        check("[render]", "env_", env.validate());
    }
    if let Some(c) = &file.compare {
        let job = CompareJob {
            data_range: c.data_range.unwrap_or(crate::job::DEFAULT_DATA_RANGE),
            ..CompareJob::new(PathBuf::new(), vec![], PathBuf::new())
        };
        check("[compare]", "", job.validate());
    }
    problems
}

impl Project {
    /// The run's output folder: `given` (`--out`, `--run`), else the file's
    /// `[project] out`, else lucent-out/NAME.
    pub fn run_folder(&self, given: Option<&Path>) -> PathBuf {
        given
            .map(Path::to_path_buf)
            .or_else(|| self.out.clone())
            .unwrap_or_else(|| PathBuf::from("lucent-out").join(&self.name))
    }

    /// Reads and validates a project file.
    pub fn load(path: &Path) -> Result<Project, ProjectError> {
        let text =
            crate::io::read_text(path).map_err(|source| ProjectError::Read { path: path.to_path_buf(), source })?;
        let file: ProjectFile = toml::from_str(&text).map_err(|error: toml::de::Error| {
            let (line, column) = crate::scene::line_column(&text, error.span());
            ProjectError::Toml {
                path: path.to_path_buf(),
                line,
                column,
                message: crate::scene::toml_message(&text, &error),
            }
        })?;
        Self::build(file, path)
    }

    /// Stage two: resolves and checks every path and number.
    pub fn build(mut file: ProjectFile, path: &Path) -> Result<Project, ProjectError> {
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let dir =
            std::path::absolute(if dir.as_os_str().is_empty() { Path::new(".") } else { &dir }).unwrap_or(dir.clone());
        let c = Checker { path, dir };
        let name = match &file.project.name {
            Some(n) => n.clone(),
            None => path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "project".into()),
        };
        if let Err(reason) = folder_name(&name) {
            return Err(c.key("[project] name", format!("{name:?}: {reason}")));
        }
        let out = file.project.out.as_ref().map(|p| c.resolve(p));
        let mut seen = std::collections::HashSet::new();
        for (k, s) in file.sample.iter_mut().enumerate() {
            check_sample(&c, k, s, &mut seen)?;
        }
        let configs = check_bssrdf(&c, &file)?;
        if let Some(RoughnessSpec::Measured(p)) = file.bssrdf.as_mut().and_then(|b| b.roughness.as_mut()) {
            c.existing("[bssrdf] roughness", p)?;
        }
        let bssrdf_configs = configs.as_ref().map(Configurations::pairs).unwrap_or_default();
        // The values that become flags of the stages' commands, checked by
        // their jobs with the flags' ranges: all named here, before any stage runs.
        match job_problems(&file).as_slice() {
            [] => {}
            [(k, reason)] => return Err(c.key(k, reason.clone())),
            many => return Err(ProjectError::Keys { path: path.to_path_buf(), problems: many.to_vec() }),
        }
        if let Some(cal) = &mut file.calibration {
            check_calibration(&c, cal)?;
        }
        check_colour(&c, &mut file)?;
        if let Some(p) = &mut file.pose {
            c.existing("[pose] image", &mut p.image)?;
            if let Some(t) = &mut p.truth {
                c.existing("[pose] truth", t)?;
            }
            if p.board.is_none() && file.calibration.is_none() {
                return Err(c.key("[pose] board", "required without [calibration]".into()));
            }
        }
        if let Some(r) = &mut file.render {
            c.existing("[render] scene", &mut r.scene)?;
            if let Some(cam) = &r.camera {
                if cam != "pose" && cam != "template" {
                    return Err(c.key("[render] camera", format!("expected \"pose\" or \"template\", got {cam:?}")));
                }
                if cam == "pose" && file.pose.is_none() {
                    return Err(c.key("[render] camera", "\"pose\" needs a [pose] section".into()));
                }
            }
        }
        if let Some(f) = &file.fit {
            check_fit(&c, f, &file.sample)?;
        }
        let seed = file.project.seed.unwrap_or(1);
        let executor = match &file.executor {
            Some(e) => super::executor::Executor::from_section(e)
                .map_err(|e| c.key(&format!("[executor] {}", e.key), e.reason))?,
            None => super::executor::Executor::default(),
        };
        Ok(Project { path: path.to_path_buf(), name, seed, out, file, bssrdf_configs, executor })
    }
}

/// The project file at `path` being checked: its keys named in errors, its
/// relative paths resolved against its folder `dir`.
struct Checker<'a> {
    path: &'a Path,
    dir: PathBuf,
}

impl Checker<'_> {
    /// The error of key `k`.
    fn key(&self, k: &str, reason: String) -> ProjectError {
        ProjectError::Key { path: self.path.to_path_buf(), key: k.to_string(), reason }
    }

    /// `p` resolved against the project file's folder.
    fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.dir.join(p)
        }
    }

    /// Resolves `p` (of key `k`) in place; an error when it does not exist.
    fn existing(&self, k: &str, p: &mut PathBuf) -> Result<(), ProjectError> {
        *p = self.resolve(p);
        if p.exists() {
            Ok(())
        } else {
            Err(self.key(k, format!("{}: no such file", p.display())))
        }
    }
}

/// Checks `[[sample]]` number `k` (from 0) and resolves its paths: its
/// numbers, its name (a folder name, not in `seen`), its files and its
/// measured slices.
fn check_sample(
    c: &Checker,
    k: usize,
    s: &mut SampleSection,
    seen: &mut std::collections::HashSet<String>,
) -> Result<(), ProjectError> {
    let at = format!("[[sample]] #{} ({})", k + 1, s.name);
    if let Some(w) = s.weight_percent
        && !(w > 0.0 && w < 100.0)
    {
        return Err(c.key(&format!("{at} weight_percent"), format!("must lie in (0, 100), got {w}")));
    }
    for m in &s.measured {
        if let Some(px) = m.pixel_mm
            && !(px > 0.0 && px.is_finite())
        {
            return Err(c.key(&format!("{at} measured pixel_mm"), format!("must be finite and > 0, got {px}")));
        }
    }
    if let Err(reason) = folder_name(&s.name) {
        return Err(c.key(&format!("{at} name"), reason.into()));
    }
    if !seen.insert(s.name.clone()) {
        return Err(c.key(&format!("{at} name"), "two samples have this name".into()));
    }
    c.existing(&format!("{at} recipe"), &mut s.recipe)?;
    if let Some(p) = &mut s.photo {
        c.existing(&format!("{at} photo"), p)?;
    }
    if let Some(p) = &mut s.empty_board {
        c.existing(&format!("{at} empty_board"), p)?;
    }
    if let Some(p) = &mut s.surface {
        c.existing(&format!("{at} surface"), p)?;
    }
    if let Some(t) = &mut s.truth_recipe {
        c.existing(&format!("{at} truth_recipe"), t)?;
        crate::optics::recipe::Recipe::load(t, crate::optics::recipe::Overrides::default())
            .map_err(|e| c.key(&format!("{at} truth_recipe"), e.to_string()))?;
    }
    check_measured(c, &at, &mut s.measured)
}

/// Checks a sample's measured slices (named `at` in errors) and resolves
/// their files: one configuration each, no file twice, a pixel size here
/// or in the slice's sidecar.
fn check_measured(c: &Checker, at: &str, measured: &mut [MeasuredSection]) -> Result<(), ProjectError> {
    let mut slices: Vec<(Configuration, PathBuf)> = Vec::new();
    for m in measured.iter_mut() {
        c.existing(&format!("{at} measured file"), &mut m.file)?;
        // One slice given twice would count as two configurations in the fit.
        let file = crate::io::file_key(&m.file);
        if let Some((cfg, _)) = slices.iter().find(|(_, f)| *f == file) {
            return Err(c.key(
                &format!("{at} measured"),
                format!("{} is given twice (at {cfg} and {})", m.file.display(), m.config),
            ));
        }
        slices.push((m.config, file));
    }
    for m in measured.iter() {
        // Without pixel_mm here the slice's sidecar must give it; the
        // message names this key, not the stage's --measured-pixel-mm.
        if m.pixel_mm.is_none() {
            match crate::bssrdf::sidecar_pixel_mm(&m.file) {
                Ok(Some(_)) => {}
                Ok(None) => {
                    return Err(c.key(
                        &format!("{at} measured pixel_mm"),
                        format!(
                            "{}: pixel size unknown; set pixel_mm = … (mm) in this [[sample.measured]] \
                             entry, or put {{\"pixel_mm\": …}} in {}.json",
                            m.file.display(),
                            m.file.display()
                        ),
                    ));
                }
                Err(e) => return Err(c.key(&format!("{at} measured pixel_mm"), e.to_string())),
            }
        }
    }
    Ok(())
}

/// The `[bssrdf]` configurations (none without the section), checked: a
/// stop rule, and every measured slice's configuration among them.
fn check_bssrdf(c: &Checker, file: &ProjectFile) -> Result<Option<Configurations>, ProjectError> {
    let Some(b) = &file.bssrdf else { return Ok(None) };
    let configs = b.configurations();
    if b.paths.is_none() && b.rel_error.is_none() && b.time_s.is_none() {
        return Err(c.key("[bssrdf]", "give a stop rule: paths, rel_error or time_s".into()));
    }
    for s in &file.sample {
        for m in &s.measured {
            if !configs.list().contains(&m.config) {
                return Err(c.key(
                    &format!("[[sample]] {} measured config", s.name),
                    format!("\"{}\" is not among [bssrdf] configs", m.config),
                ));
            }
        }
    }
    Ok(Some(configs))
}

/// Resolves `[calibration]`'s images pattern and checks its truth, a
/// camera.json in `lucent calibrate`'s format.
fn check_calibration(c: &Checker, cal: &mut CalibrationSection) -> Result<(), ProjectError> {
    let p = c.resolve(Path::new(&cal.images));
    cal.images = p.to_string_lossy().into_owned();
    if let Some(t) = &mut cal.truth {
        c.existing("[calibration] truth", t)?;
        let text =
            crate::io::read_text(&*t).map_err(|e| c.key("[calibration] truth", format!("{}: {e}", t.display())))?;
        if serde_json::from_str::<lucent_calib::camera::Calibration>(&text).is_err() {
            return Err(c.key(
                "[calibration] truth",
                format!("{}: not a camera.json in `lucent calibrate`'s format", t.display()),
            ));
        }
    }
    Ok(())
}

/// Checks the `[[colour]]` sections (one per camera, their chart photos and
/// truths) and each sample's camera (a `[[colour]]` camera, with a photo to
/// develop).
fn check_colour(c: &Checker, file: &mut ProjectFile) -> Result<(), ProjectError> {
    let mut cameras = std::collections::HashSet::new();
    for col in &mut file.colour {
        if let Err(reason) = folder_name(&col.camera) {
            return Err(c.key("[[colour]] camera", format!("{:?}: {reason}", col.camera)));
        }
        if !cameras.insert(col.camera.clone()) {
            return Err(c.key("[[colour]] camera", format!("{:?}: two [[colour]] sections name it", col.camera)));
        }
        c.existing(&format!("[[colour]] {} image", col.camera), &mut col.image)?;
        if let Some(t) = &mut col.truth {
            let k = format!("[[colour]] {} truth", col.camera);
            c.existing(&k, t)?;
            crate::synth::ColourTruth::load(t).map_err(|e| c.key(&k, e.to_string()))?;
        }
    }
    for s in &file.sample {
        if let Some(cam) = &s.camera {
            if !cameras.contains(cam) {
                return Err(c.key(
                    &format!("[[sample]] {} camera", s.name),
                    format!("{cam:?} is not a [[colour]] camera (its ccm.json develops the photos)"),
                ));
            }
            if s.photo.is_none() && s.empty_board.is_none() {
                return Err(c.key(&format!("[[sample]] {} camera", s.name), "there is no photo to develop".into()));
            }
        }
    }
    Ok(())
}

/// Checks `[fit]` (at least one free parameter) against the `samples` (one
/// valid pixel size per sample's measured slices).
fn check_fit(c: &Checker, f: &FitSection, samples: &[SampleSection]) -> Result<(), ProjectError> {
    if f.free.is_empty() {
        return Err(c.key("[fit] free", "name at least one parameter, e.g. [\"weight_percent\"]".into()));
    }
    for smp in samples {
        let px: Vec<Option<f64>> = smp.measured.iter().map(|m| m.pixel_mm).collect();
        if px.windows(2).any(|w| w[0] != w[1]) {
            return Err(c.key(
                &format!("[[sample]] {} measured pixel_mm", smp.name),
                "the fit takes one pixel size for all of a sample's measured slices".into(),
            ));
        }
        if let Some(Some(p)) = px.first()
            && !(*p > 0.0 && p.is_finite())
        {
            return Err(c.key(
                &format!("[[sample]] {} measured pixel_mm", smp.name),
                format!("must be finite and > 0, got {p}"),
            ));
        }
    }
    Ok(())
}

/// Where each stage of `file`'s project runs under executor `e` (kind
/// Slurm): one line per stage or group of stages, printed by `lucent run
/// --executor slurm` before anything is submitted.
pub fn plan_lines(file: &ProjectFile, e: &super::executor::Executor) -> Vec<String> {
    let shards = e.shards;
    let mut lines = vec![format!(
        "plan: Slurm job arrays of {shards} shards per long command{}{}{}{}, each shard resubmitted up to {} time(s), \
         then a merge job",
        e.partition.as_ref().map(|p| format!(", partition {p}")).unwrap_or_default(),
        e.account.as_ref().map(|a| format!(", account {a}")).unwrap_or_default(),
        e.time_limit.as_ref().map(|t| format!(", time limit {t}")).unwrap_or_default(),
        e.cpus_per_task.map(|c| format!(", {c} CPU(s) per shard (its threads)")).unwrap_or_default(),
        e.retries
    )];
    let mut here: Vec<&str> = Vec::new();
    // bssrdf: each slice with a path budget and no other stop rule.
    match file.bssrdf.as_ref().map(|b| b.stop().shard_samples()) {
        Some(Ok(paths)) => lines.push(format!(
            "  bssrdf      on the cluster: each slice ([bssrdf] paths = {paths}) as {shards} shards of {} paths or so",
            paths.div_ceil(u64::from(shards))
        )),
        Some(Err(why)) => lines.push(format!(
            "  bssrdf      here: [bssrdf] {} (only a fixed path budget, `paths` alone, splits exactly)",
            if why == NotSplittable::NoSamples { "has no paths" } else { "sets time_s or rel_error beside paths" }
        )),
        None => here.push("bssrdf"),
    }
    // render: each render with a sample budget and a scene that allows it.
    match &file.render {
        Some(r) => {
            let stop = r.stop();
            let why = match stop.shard_samples() {
                Err(NotSplittable::NoSamples) => {
                    Some("[render] has no spp (only a fixed sample budget splits exactly)".to_string())
                }
                Err(_) => Some("[render] time_s is set (a time budget cannot be split exactly)".to_string()),
                Ok(_) => super::executor::scene_unshardable(&r.scene),
            };
            lines.push(match why {
                None => format!(
                    "  render      on the cluster: each render ([render] spp = {}) as {shards} shards, merged \
                     byte-identical to one unsharded render",
                    stop.samples.unwrap_or(0)
                ),
                Some(why) => format!("  render      here: {why}"),
            });
        }
        None => here.push("render"),
    }
    let short: Vec<&str> =
        super::stage::Stage::ALL.iter().map(|s| s.name()).filter(|n| !["bssrdf", "render"].contains(n)).collect();
    lines.push(format!(
        "  {}  here: short commands, or not splittable into shards (only renders with a sample budget and \
         BSSRDF slices with a path budget are)",
        short.join(", ")
    ));
    if !here.is_empty() {
        lines.push(format!("  ({} not in this project)", here.join(", ")));
    }
    lines
}
