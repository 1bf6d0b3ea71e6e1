//! Scene files for `lucent render` (docs/method.md#render): a TOML file naming the
//! object, its material, the checkerboard, the environment and the camera,
//! validated in two stages like recipes — the file as typed ([`SceneFile`],
//! unknown keys rejected, each error naming the file and key), then the
//! renderer's [`lucent_render::tracer::Scene`] built by [`load`].
//!
//! Units: metres unless a key says otherwise (`_mm`, `_deg`); world
//! right-handed, **z up**, as written by `lucent pose` (see
//! `lucent_calib::scene`). Relative paths are relative to the scene file.
//!
//! ```toml
//! [camera]                      # either scene_json (from `lucent pose`) or explicit
//! scene_json = "scene.json"     # intrinsics, pose and image size of the photo
//! distortion = "none"           # or "calibrated" (needs camera_json): render the raw photo's geometry
//! # camera_json = "camera.json"
//! # width = 640, height = 480, position_m = [0, -0.3, 0.35], look_at_m = [0, 0, 0], up = [0, 0, 1], vertical_fov_deg = 40
//!
//! [object]                      # without `mesh`: the plaque box of the recipe's size_mm/thickness_mm (or `size_mm`)
//! # mesh = "part.ply"           # PLY, OBJ or STL; unit_scale_m = 0.001 for a mesh in mm
//! placement = "scene"           # the sample placement in scene_json; or board_corner = [i, j]; or transform = 4×4
//! lift_m = 1e-6                 # air gap under an object placed on the board (default 1 µm)
//!
//! [material]
//! recipe = "../samples/IOL1068-09.toml"   # Lorenz–Mie → R, G, B bands
//! phase = "mie"                 # "mie" (band-averaged tabulated function) or "hg" (the band's g)
//! # or explicit bands: mu_s_per_m = [..3], mu_a_per_m = [..3], g = [..3], n = [..3]
//! # (sigma_s_per_m and sigma_a_per_m, the earlier spellings, are still read)
//! roughness = "recipe"          # the recipe's [surface] if any (else smooth); "smooth"; "ggx:0.0084"; "beckmann:0.005"
//! dispersion = true             # false: one index (the bands' mean) for all bands, so a path
//!                               # carries R, G and B together (an approximation; docs/method.md#render-dispersion)
//!
//! [board]                       # geometry from scene_json, or origin_m/u/v/columns/rows/square_mm
//! even = [0.04, 0.04, 0.04]     # squares whose (column + row) is even (the outer corner square)
//! odd = [0.80, 0.80, 0.80]      # or even_spectrum / odd_spectrum = "r.csv", or texture = "board.png"
//!
//! [environment]
//! map = "studio.exr"            # equirectangular, linear CIE RGB; or constant = [r, g, b]
//! projection = "finite-sphere"  # or "infinite"
//! radius_m = 0.60               # centred at the top of the sample unless centre_m is given
//! yaw_deg = 0                   # or orientation = "env_oriented.json" (`lucent env orient`)
//! scale = 1.0
//!
//! [render]
//! spp = 64
//! seed = 1
//! # time_s = 120, spp_per_pass = 4
//! # spectral_mis = true, medium_connections = true   (false, false: the plain one-band estimator)
//! # band_branches = true         (where a path keeps one band: one branch per band; false: one band at random, weight 3)
//! # phase_connections = true     (with medium_connections: also connect along the phase function's directions; default: only for an object of few face planes)
//! # specular_chains = false      (true: also connect through one reflection at a face, and from the board through or off the object; fewer bright outliers, ≈ 12–20 % more time)
//! # sphere_jumps = false         (true: deep inside an isotropically scattering object, jump through tabulated spheres; diffusive media)
//! # sampling = "uniform"          # every pixel gets spp; "object-weighted": the object's pixels more
//! #                               # (default: object-weighted with an error target, else uniform)
//! # target_rel_error = 0.05       # stop when the object's median relative standard error reaches 5 %
//! ```
//!
//! **Bands.** Spectral quantities (μ_s, μ_a, g, n_bulk, reflectance spectra)
//! become R, G, B with `lucent_colour::bands` (CIE 1931 RGB colour-matching
//! functions, Wright & Guild, negative lobes clipped, each band normalised):
//! the same weights as `lucent colour bands`. The tabulated phase function
//! of a band is the mixture of the wavelengths' Lorenz–Mie functions
//! weighted by w_b(λ) μ_s(λ) (the band's scattered light), renormalised.
//!
//! **Placement on the board.** "The sample's top-left corner on board
//! corner (i, j)" (`board_corner`) or `placement = "scene"` uses
//! `lucent_calib::scene::place_sample`: the object's frame has its origin at
//! the centre of the bottom face. The object is lifted by `lift_m` (default
//! 1 µm) so its bottom face and the board are not coplanar: light leaving
//! the bottom face crosses a 1 µm air gap to the board, as under a plaque
//! lying on paper.

pub mod band;
pub mod mesh;

use crate::optics::bulk::{self, OpticalSpectrum};
use crate::optics::recipe::{self, Overrides, Recipe};
use crate::optics::PhaseModel;
use glam::DVec3;
use lucent_calib::scene::{BoardSpec, SceneDescription};
use lucent_colour::bands::{band_weights, BandWeights};
use lucent_colour::WavelengthGrid;
use lucent_render::accel::Accel;
use lucent_render::camera::Camera;
use lucent_render::env::{Environment, Projection};
use lucent_render::interface::Interface;
use lucent_render::medium::Medium;
use lucent_render::microfacet::Microsurface;
use lucent_render::phase::{Phase, PhaseTable};
use lucent_render::tracer::{Board, BoardReflectance, Object, Scene, Settings, Stop};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// What went wrong with a scene file; every variant names the file.
#[derive(Debug, Error)]
pub enum SceneFileError {
    #[error("{path}: cannot read scene file: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    /// Not valid TOML, or a key the format does not have: the parser's
    /// message, with the 1-based line and column where it points.
    #[error("{path}:{}{message}", location(*line, *column))]
    Syntax { path: PathBuf, line: Option<usize>, column: Option<usize>, message: String },
    /// A key whose value cannot be used: [`KeyProblem`] says why.
    #[error("{path}: [{section}] {key}: {problem}")]
    Key {
        path: PathBuf,
        section: &'static str,
        key: &'static str,
        #[source]
        problem: Box<KeyProblem>,
    },
    /// Keys of a section that do not fit together: [`SectionProblem`] says how.
    #[error("{path}: [{section}]: {problem}")]
    Section {
        path: PathBuf,
        section: &'static str,
        #[source]
        problem: Box<SectionProblem>,
    },
    #[error("{path}: [object] mesh: {source}")]
    Mesh { path: PathBuf, source: mesh::MeshError },
    #[error("{path}: [material] recipe: {source}")]
    Recipe { path: PathBuf, source: crate::optics::recipe::RecipeError },
    /// The recipe's optical properties over the scene's wavelength grid
    /// (`[material] wavelengths`, default 380:780:10: the colour-matching
    /// functions' range) failed, e.g. an index table that starts at 400 nm.
    #[error("{path}: [material] recipe over wavelengths {wavelengths} nm: {source}")]
    Optics { path: PathBuf, wavelengths: String, source: crate::optics::bulk::OpticsError },
    #[error("{path}: [environment] map: {source}")]
    Image { path: PathBuf, source: crate::imageio::ImageIoError },
    #[error("{path}: {source}")]
    Scene { path: PathBuf, source: lucent_render::tracer::SceneError },
}

/// Why the value of one key of a scene file cannot be used (the `problem`
/// of [`SceneFileError::Key`]). Variants that concern a file the key names
/// carry that file's path (`file`); a cause is kept as the source.
#[derive(Debug, Error)]
pub enum KeyProblem {
    #[error("values must be finite, got {values:?}")]
    NotFinite { values: Vec<f64> },
    #[error("must be finite and > 0, got {value}")]
    NotPositive { value: f64 },
    #[error("must be finite and ≥ 0, got {value}")]
    Negative { value: f64 },
    #[error("must be at least 1")]
    Zero,
    #[error("must lie strictly between {low} and {high}, got {value}")]
    Between { low: f64, high: f64, value: f64 },
    #[error(
        "band {band}: σs = {s} /m, σa = {a} /m: each must be ≥ 0 and σs + σa in (0, 1e7] /m \
         (lucent_render::slab::MU_T_MAX_PER_M, a mean free path of 0.1 µm)"
    )]
    Coefficients { band: usize, s: f64, a: f64 },
    #[error(
        "must be an affine map that keeps a solid a solid: last row [0, 0, 0, 1] (got {last_row:?}) and an \
         invertible, well-conditioned 3 × 3 part (determinant {determinant}, at least 1e-9 × the cube of its largest entry \
         {largest})"
    )]
    SingularTransform { determinant: f64, last_row: [f64; 4], largest: f64 },
    #[error(
        "mirrors the object (determinant {determinant} < 0): a mirrored mesh is turned inside out (its faces' \
         outward normals point inwards); mirror the mesh file itself, or use a rotation (determinant > 0)"
    )]
    MirrorTransform { determinant: f64 },
    #[error(
        "scales the object by {scale:e} (the cube root of the determinant {determinant:e}): it would be \
         {size_m:e} m across and vanish from the render; a transform places the object in metres (put a unit \
         conversion in unit_scale_m), and must keep it at least {min_m:e} m across"
    )]
    VanishingTransform { determinant: f64, scale: f64, size_m: f64, min_m: f64 },
    #[error("must lie strictly between 0 and 1 (a fraction, e.g. 0.05 for 5 %), got {value}")]
    Fraction { value: f64 },
    #[error(
        "{radius} m: the camera at {camera:?} m is {distance:.4} m from the sphere's centre {centre:?} m, outside \
         the sphere; the environment's finite sphere must enclose the camera (a larger radius_m, or another centre_m)"
    )]
    CameraOutsideSphere { radius: f64, camera: [f64; 3], centre: [f64; 3], distance: f64 },
    #[error(
        "the object is {:.4} × {:.4} × {:.4} m ({lo:?} … {hi:?} m), around the camera at {camera:?} m: the camera \
         must be outside the object, or every path is lost{hint}",
        hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]
    )]
    CameraInsideObject { lo: [f64; 3], hi: [f64; 3], camera: [f64; 3], hint: &'static str },
    #[error("{0}")]
    Similarity(SimilarityProblem),
    #[error("reflectances must lie in [0, 1], got {values:?}")]
    Reflectance { values: [f64; 3] },
    #[error("radiance must be finite and ≥ 0, got {values:?}")]
    Radiance { values: [f64; 3] },
    #[error("{0}")]
    Constant(lucent_render::env::EnvError),
    #[error("{0}")]
    Board(lucent_calib::board::BoardError),
    #[error("must be a unit vector, got {values:?} of length {length}")]
    NotUnit { values: [f64; 3], length: f64 },
    #[error("box sides must be finite and > 0, got {sides_m:?} m")]
    BoxSize { sides_m: [f64; 3] },
    /// A choice among named values.
    #[error("expected {expected}, got {got:?}")]
    Choice { expected: &'static str, got: String },
    /// A key that is required when another one is given or missing.
    #[error("required {when}")]
    Required { when: &'static str },
    #[error("\"calibrated\" needs camera_json (the camera.json of `lucent calibrate`)")]
    CalibratedNeedsCameraJson,
    #[error("\"calibrated\" needs the calibrated intrinsics (scene_json or intrinsics)")]
    CalibratedNeedsIntrinsics,
    /// A camera.json whose lens model the renderer's rays do not follow.
    #[error(
        "the lens of camera.json {} is the {model} distortion model, which the renderer cannot draw (it \
         draws pinhole-k3 and rational); calibrate with one of those or render undistorted (distortion = \"none\")",
        file.display()
    )]
    UnsupportedLens { file: PathBuf, model: &'static str },
    #[error("\"mie\" needs a recipe; explicit bands use \"hg\"")]
    MieNeedsRecipe,
    #[error(
        "\"scene\" needs [camera] scene_json with a sample (run `lucent pose` with --sample-corner and \
         --sample-size-mm)"
    )]
    PlacementNeedsSample,
    #[error("needs [camera] scene_json (the board's pose from `lucent pose`)")]
    BoardCornerNeedsSceneJson,
    #[error("corner ({i}, {j}) is outside the board's {columns} × {rows} inner corners")]
    CornerOutside { i: usize, j: usize, columns: usize, rows: usize },
    #[error("differs from scene_json's square of {scene_json_mm} mm")]
    SquareMismatch { scene_json_mm: f64 },
    #[error("unknown model {0:?}: trowbridge-reitz (ggx) or beckmann")]
    UnknownRoughnessModel(String),
    #[error("α {0:?} is not a number")]
    AlphaNotANumber(String),
    #[error("α must be a number in [0, {max}], got {0}", max = lucent_render::microfacet::MAX_ALPHA)]
    Alpha(f64),
    #[error(transparent)]
    Microfacet(lucent_render::microfacet::MicrofacetError),
    #[error(transparent)]
    Phase(lucent_render::phase::PhaseError),
    #[error(transparent)]
    Wavelengths(lucent_colour::GridTextError),
    #[error(transparent)]
    Bands(lucent_colour::ColourError),
    /// A file the key names cannot be read.
    #[error("{file}: {source}")]
    Read { file: PathBuf, source: std::io::Error },
    #[error("{file}: not a scene.json written by `lucent pose`: {source}")]
    NotSceneJson { file: PathBuf, source: serde_json::Error },
    #[error("{file}: not a camera.json written by `lucent calibrate`: {source}")]
    NotCameraJson { file: PathBuf, source: serde_json::Error },
    #[error("{file}: {source}")]
    Csv { file: PathBuf, source: csv::Error },
    #[error("{file}: line {line}: expected wavelength_nm,reflectance, got {text}")]
    SpectrumLine { file: PathBuf, line: u64, text: String },
    #[error("{file}: reflectance values must lie in [0, 1]")]
    SpectrumRange { file: PathBuf },
    #[error("{file}: {source}")]
    SpectrumGrid { file: PathBuf, source: lucent_colour::GridError },
    #[error("{file}: {source}")]
    SpectrumBands { file: PathBuf, source: lucent_colour::ColourError },
    /// An image the key names (the message names the file).
    #[error(transparent)]
    Image(crate::imageio::ImageIoError),
    #[error("{file}: reflectances must lie in [0, 1]")]
    TextureRange { file: PathBuf },
    #[error("{file}: {source}")]
    Environment { file: PathBuf, source: lucent_render::env::EnvError },
    /// Not a 2:1 equirectangular map (the check of every `lucent env` command).
    #[error("{file}: {source}")]
    Equirectangular { file: PathBuf, source: lucent_calib::env::EnvError },
    /// An orientation file of `lucent env orient` (the message names it).
    #[error(transparent)]
    Orientation(OrientationFileError),
}

/// Why the keys of a section do not fit together (the `problem` of
/// [`SceneFileError::Section`]).
#[derive(Debug, Error)]
pub enum SectionProblem {
    /// Two ways of giving the same thing.
    #[error("give either {first} or {second}, not both")]
    Conflict { first: &'static str, second: &'static str },
    #[error("an [object] needs a [material] (recipe or explicit bands)")]
    ObjectNeedsMaterial,
    #[error("a [material] is given but no [object] to fill")]
    MaterialNeedsObject,
    #[error(
        "give scene_json, or width and height with position_m/look_at_m/vertical_fov_deg or \
         intrinsics/camera_to_world"
    )]
    NoCamera,
    #[error("give either intrinsics + camera_to_world or position_m + look_at_m (+ vertical_fov_deg)")]
    CameraKeys,
    #[error(transparent)]
    Camera(lucent_render::camera::CameraError),
    #[error("give a recipe or explicit mu_s_per_m, mu_a_per_m, g and n")]
    NoMaterial,
    #[error("{quantity}: {source}")]
    BandAverage { quantity: &'static str, source: lucent_colour::ColourError },
    #[error("band {band} phase table: {source}")]
    PhaseTable { band: usize, source: lucent_render::phase::PhaseError },
    #[error("no mesh, no size_mm and the recipe gives no size_mm/thickness_mm: the plaque box needs a size")]
    NoObjectSize,
    #[error("give only one of transform, placement and board_corner")]
    Placement,
    #[error("no board geometry: give origin_m, columns and rows, or [camera] scene_json")]
    NoBoardGeometry,
    #[error("radius_m and centre_m belong to projection = \"finite-sphere\"")]
    FiniteSphereKeys,
    #[error("orientation needs a map")]
    OrientationNeedsMap,
    #[error("give map (an equirectangular EXR/HDR) or constant = [r, g, b]")]
    NoEnvironment,
}

// ------------------------------------------------------------ raw file

/// The scene file as typed.
#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    pub camera: CameraSection,
    #[serde(default)]
    pub object: Option<ObjectSection>,
    #[serde(default)]
    pub material: Option<MaterialSection>,
    #[serde(default)]
    pub board: Option<BoardSection>,
    pub environment: EnvironmentSection,
    #[serde(default)]
    pub render: RenderSection,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct CameraSection {
    pub scene_json: Option<PathBuf>,
    pub camera_json: Option<PathBuf>,
    pub distortion: Option<String>,
    pub width: Option<usize>,
    pub height: Option<usize>,
    pub position_m: Option<[f64; 3]>,
    pub look_at_m: Option<[f64; 3]>,
    pub up: Option<[f64; 3]>,
    pub vertical_fov_deg: Option<f64>,
    pub intrinsics: Option<[f64; 4]>,
    pub camera_to_world: Option<[[f64; 4]; 4]>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectSection {
    pub mesh: Option<PathBuf>,
    pub unit_scale_m: Option<f64>,
    pub size_mm: Option<[f64; 3]>,
    pub placement: Option<String>,
    pub board_corner: Option<[usize; 2]>,
    pub transform: Option<[[f64; 4]; 4]>,
    pub lift_m: Option<f64>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSection {
    pub recipe: Option<PathBuf>,
    pub weight_percent: Option<f64>,
    #[serde(default, deserialize_with = "phase_model")]
    pub phase: Option<PhaseModel>,
    pub wavelengths: Option<String>,
    /// Scattering coefficient μs per band (R, G, B), 1/m.
    pub mu_s_per_m: Option<[f64; 3]>,
    /// Absorption coefficient μa per band (R, G, B), 1/m.
    pub mu_a_per_m: Option<[f64; 3]>,
    /// The earlier spelling of `mu_s_per_m`, still read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_s_per_m: Option<[f64; 3]>,
    /// The earlier spelling of `mu_a_per_m`, still read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma_a_per_m: Option<[f64; 3]>,
    pub g: Option<[f64; 3]>,
    pub n: Option<[f64; 3]>,
    pub dispersion: Option<bool>,
    pub roughness: Option<String>,
    /// One of the recipe's uncertain inputs set to a value (`lucent render
    /// --uncertainty` renders the scene at each input ± 1 σ); never read
    /// from a file.
    #[serde(skip)]
    pub recipe_input: Option<(recipe::InputTarget, f64)>,
}

impl MaterialSection {
    /// μs per band and the key it was given under (`mu_s_per_m` or its
    /// earlier spelling `sigma_s_per_m`); both at once is a conflict.
    fn mu_s(&self) -> Result<(Option<[f64; 3]>, &'static str), SectionProblem> {
        either_spelling((self.mu_s_per_m, "mu_s_per_m"), (self.sigma_s_per_m, "sigma_s_per_m"))
    }

    /// μa per band and the key it was given under, as [`Self::mu_s`].
    fn mu_a(&self) -> Result<(Option<[f64; 3]>, &'static str), SectionProblem> {
        either_spelling((self.mu_a_per_m, "mu_a_per_m"), (self.sigma_a_per_m, "sigma_a_per_m"))
    }
}

/// The value of a key that has a current and an earlier spelling, with the
/// spelling used (the current one when neither is given).
fn either_spelling(
    current: (Option<[f64; 3]>, &'static str),
    earlier: (Option<[f64; 3]>, &'static str),
) -> Result<(Option<[f64; 3]>, &'static str), SectionProblem> {
    match (current.0, earlier.0) {
        (Some(_), Some(_)) => Err(SectionProblem::Conflict { first: current.1, second: earlier.1 }),
        (None, Some(v)) => Ok((Some(v), earlier.1)),
        (v, None) => Ok((v, current.1)),
    }
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct BoardSection {
    pub origin_m: Option<[f64; 3]>,
    pub u: Option<[f64; 3]>,
    pub v: Option<[f64; 3]>,
    pub square_mm: Option<f64>,
    pub columns: Option<usize>,
    pub rows: Option<usize>,
    pub even: Option<[f64; 3]>,
    pub odd: Option<[f64; 3]>,
    pub even_spectrum: Option<PathBuf>,
    pub odd_spectrum: Option<PathBuf>,
    pub texture: Option<PathBuf>,
    pub margin_mm: Option<f64>,
    pub margin: Option<[f64; 3]>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct EnvironmentSection {
    pub map: Option<PathBuf>,
    pub constant: Option<[f64; 3]>,
    pub projection: Option<String>,
    pub radius_m: Option<f64>,
    pub centre_m: Option<[f64; 3]>,
    pub yaw_deg: Option<f64>,
    /// An orientation file of `lucent env orient` (instead of yaw_deg): the yaw for this map from it.
    pub orientation: Option<PathBuf>,
    pub scale: Option<f64>,
}

#[derive(Debug, Clone, Default, Deserialize, Serialize)]
#[serde(deny_unknown_fields)]
pub struct RenderSection {
    /// The similar medium's g′ (and its later medium's event and g′) as
    /// another render of this scene walked them, used without the depth
    /// floor (`lucent render --uncertainty`); never read from a file.
    #[serde(skip)]
    pub similarity_walked: Option<(f64, Option<(u64, f64)>)>,
    pub spp: Option<u32>,
    pub time_s: Option<f64>,
    pub seed: Option<u64>,
    pub spp_per_pass: Option<u32>,
    pub spectral_mis: Option<bool>,
    /// Where a path keeps one band (a dispersive boundary): three branches,
    /// one per band, instead of one band at random (default true).
    pub band_branches: Option<bool>,
    pub medium_connections: Option<bool>,
    pub phase_connections: Option<bool>,
    /// With `medium_connections`: connect through one reflection at a face
    /// and from the board through the object too (default false).
    pub specular_chains: Option<bool>,
    /// Jump through tabulated spheres deep inside an object that scatters
    /// isotropically in every band (default false).
    pub sphere_jumps: Option<bool>,
    /// "uniform" (every pixel `spp`) or "object-weighted" (the object's
    /// pixels get the samples their error needs). Default: object-weighted
    /// when the render stops on an error target (this file's or
    /// `--target-rel-error`), else uniform.
    pub sampling: Option<SamplingKey>,
    /// Stop when the median relative standard error over the object's pixels reaches this fraction.
    pub target_rel_error: Option<f64>,
    /// Walk the object's similar medium, asymmetry this, raised (the same in
    /// every band) where it would be under 3 mean free paths deep (0 ≤ g < 1;
    /// μs(1 − g), μa and n kept): an approximation, see docs/method.md.
    pub similarity_g: Option<f64>,
    /// With `similarity_g`: hold that depth floor for a path's first this
    /// many scattering events only (≥ 1) and walk the similar medium of
    /// `similarity_g` after them, raised only as far as keeps it 1 mean free
    /// path deep: a further approximation, see docs/method.md (default: the
    /// floor holds for the whole walk).
    pub similarity_floor_events: Option<u64>,
}

impl RenderSection {
    /// The stop rule this section gives (samples per pixel `spp`, `time_s`,
    /// the object's median error `target_rel_error`), with none of the
    /// defaults a render adds where it gives none.
    pub fn stop(&self) -> Stop {
        Stop {
            samples: self.spp.map(u64::from),
            time_s: self.time_s,
            rel_error: None,
            pixel_rel_error: self.target_rel_error,
        }
    }
}

/// `[render] sampling`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum SamplingKey {
    Uniform,
    ObjectWeighted,
}

impl From<SamplingKey> for lucent_render::tracer::Sampling {
    fn from(k: SamplingKey) -> Self {
        match k {
            SamplingKey::Uniform => Self::Uniform,
            SamplingKey::ObjectWeighted => Self::ObjectWeighted,
        }
    }
}

// ------------------------------------------------------------ validated

/// A loaded scene with what a report needs to say about it.
#[derive(Debug, Clone)]
pub struct LoadedScene {
    pub scene: Scene,
    pub settings: Settings,
    /// What was used, for render.json.
    pub summary: SceneSummary,
    /// Warnings (open mesh, clipped reflectance …) to print.
    pub warnings: Vec<String>,
}

/// The files of a render in its output folder, each name spelled here
/// once: the linear image with its variance, sample counts, object and
/// board fractions and half renders (`exr`), its preview (`png`) and its
/// report ([`RenderReport`], `json`). Written by `lucent render` and `lucent
/// merge`, read by `lucent run`'s planning, compare and report.
///
/// ```
/// use lucent::scene::RenderFiles;
/// let f = RenderFiles::in_dir(std::path::Path::new("out/render/s1"));
/// assert_eq!(f.exr, std::path::Path::new("out/render/s1/render.exr"));
/// assert_eq!(RenderFiles::NAMES, ["render.exr", "render.png", "render.json"]);
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RenderFiles {
    pub exr: PathBuf,
    pub png: PathBuf,
    pub json: PathBuf,
}

impl RenderFiles {
    /// The file names, as render.json's `files` lists them.
    pub const NAMES: [&'static str; 3] = ["render.exr", "render.png", "render.json"];
    /// The report's name ([`RenderFiles::json`]'s), beside any render's EXR.
    pub const JSON: &'static str = Self::NAMES[2];

    /// The files of the render whose output folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [exr, png, json] = Self::NAMES.map(|n| dir.join(n));
        Self { exr, png, json }
    }
}

/// `render.json` of `lucent render`: the scene as resolved, settings, seed,
/// timings and counters; written by the command and read back by the report
/// of `lucent run`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RenderReport {
    pub lucent_version: String,
    pub scene: SceneSummary,
    pub spp: u32,
    /// The stop rule's samples per pixel ([`Settings::stop`]).
    pub spp_requested: u32,
    /// The stop rule's time budget, seconds.
    pub time_budget_s: Option<f64>,
    pub seed: u64,
    pub threads: usize,
    pub roulette_threshold: Option<f64>,
    pub wall_s: f64,
    pub samples: u64,
    pub samples_per_s: f64,
    pub scattering_events: u64,
    pub surface_hits: u64,
    pub leaked_paths: u64,
    pub truncated_paths: u64,
    pub mean_rgb: [f64; 3],
    /// The median over all pixels of the relative standard error (RMS over
    /// R, G, B), = `relative_std_error.all.median`; NaN (written as `null`)
    /// when no pixel has a defined relative error.
    #[serde(deserialize_with = "crate::bssrdf::f64_or_nan")]
    pub median_relative_std_error: f64,
    /// The relative standard error of the pixels' means per region (the
    /// object's pixels, the board's, all), median and 90th percentile.
    /// Absent in files written before it existed.
    #[serde(default)]
    pub relative_std_error: Option<RegionErrorsReport>,
    /// "uniform" or "object-weighted".
    #[serde(default)]
    pub sampling: Option<SamplingKey>,
    /// Samples per pixel per region: the object's pixels, the others (means).
    #[serde(default)]
    pub spp_by_region: Option<SppByRegion>,
    /// The stop rule's target for the object's median per-pixel relative
    /// standard error.
    #[serde(default)]
    pub target_rel_error: Option<f64>,
    /// The estimator's switches as the render ran. Absent in files written
    /// before it existed.
    #[serde(default)]
    pub estimator: Option<EstimatorReport>,
    pub exposure_stops_png: f64,
    pub files: Vec<String>,
    /// True when Ctrl-C stopped the render early: the files hold the
    /// passes finished by then (a valid image with fewer samples). False in
    /// files written before it existed.
    #[serde(default)]
    pub interrupted: bool,
    /// The approximations the render made, each named with its measured
    /// bias ([`approximations`]); empty for the exact estimator.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub approximations: Vec<String>,
}

/// The similar medium's bias on a plaque's interior against the exact walk,
/// R, G, B, in %: fixtures/render/demo.toml's estimator keys (IOL1068-09
/// under studio.exr) and the same scene with the PVP plaque IOL1068-13 (g′
/// walked 0.82 there), 160 × 120, object fraction > 0.99 eroded by 2 pixels
/// (≈ 900 pixels); standard errors ± 0.2 % (IOL1068-09; two independent
/// long exact walks agree) and ± 0.6 % (IOL1068-13), references in
/// fixtures/reference/render/exact_*.exr (docs/method.md#render-similarity).
pub const SIMILAR_BIAS_INTERIOR_PERCENT: [(&str, [f64; 3]); 2] =
    [("IOL1068-09", [2.64, 2.29, 2.55]), ("IOL1068-13", [-0.76, -1.72, -0.88])];

/// What a render of this scene approximates, each with its measured bias
/// (render.json's `approximations`, printed before a render starts and
/// shown by the report beside the comparisons that use the render).
pub fn approximations(summary: &SceneSummary, settings: &lucent_render::tracer::Settings) -> Vec<String> {
    let mut out = Vec::new();
    if let Some(m) = &summary.material {
        if let Some(s) = &m.similar {
            let [(_, [r, g, b]), (_, [r13, g13, b13])] = SIMILAR_BIAS_INTERIOR_PERCENT;
            out.push(format!(
                "similar medium (similarity_g = {}, g′ walked {:.2}/{:.2}/{:.2}): biased; on the demo plaque's \
                 interior (IOL1068-09, studio.exr) {r:+.2} / {g:+.2} / {b:+.2} % (R / G / B) against the exact walk \
                 (± 0.2), on the PVP plaque's (IOL1068-13) {r13:+.2} / {g13:+.2} / {b13:+.2} % (± 0.6), the board \
                 +0.01 % (docs/method.md#render-similarity)",
                s.g_max, s.g[0], s.g[1], s.g[2]
            ));
        }
        if !m.dispersion {
            out.push(
                "bands' mean index (dispersion = false): on the demo plaque +1 % in B, the others within 0.3 % \
                 (docs/method.md#render-dispersion)"
                    .into(),
            );
        }
    }
    if settings.dispersion == lucent_render::tracer::Dispersion::SharedDirections {
        out.push(
            "shared refraction directions (--dispersion shared-directions): +4.0 % in R and −6.4 % in B on the \
             plaque's similar medium (docs/method.md#render-similarity)"
                .into(),
        );
    }
    out
}

/// The switches of [`lucent_render::tracer::Settings`] that choose the
/// estimator (not the image's expectation, except where a switch says it
/// approximates), as written into render.json.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct EstimatorReport {
    /// All three bands on one path, combined by MIS over the driving band.
    pub spectral_mis: bool,
    /// Where a path keeps one band: one branch per band instead of one band at random.
    #[serde(default)]
    pub band_branches: bool,
    /// Connections from scattering points to the environment through the faces.
    pub medium_connections: bool,
    /// A third connection along a direction drawn from the phase function.
    pub phase_connections: bool,
    /// Connections through one reflection at a face and from the board through the object.
    pub specular_chains: bool,
    /// Jumps through tabulated spheres deep inside an isotropically scattering object.
    #[serde(default)]
    pub sphere_jumps: bool,
    /// Both the reflection and the refraction followed where a path meets the object.
    pub split_entry: bool,
}

impl From<&Settings> for EstimatorReport {
    fn from(s: &Settings) -> Self {
        EstimatorReport {
            spectral_mis: s.spectral_mis,
            band_branches: s.band_branches,
            medium_connections: s.medium_nee,
            phase_connections: s.phase_connection,
            specular_chains: s.specular_chains,
            sphere_jumps: s.sphere_jumps,
            split_entry: s.split_entry,
        }
    }
}

/// Median and 90th percentile of a per-pixel figure over one region.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct QuantilesReport {
    /// Pixels the figure is taken over.
    pub pixels: usize,
    #[serde(deserialize_with = "crate::bssrdf::f64_or_nan")]
    pub median: f64,
    #[serde(deserialize_with = "crate::bssrdf::f64_or_nan")]
    pub p90: f64,
    /// The 99th percentile (the sparse bright outliers' share); absent in
    /// files written before it existed, `null` where it is infinite.
    #[serde(default)]
    pub p99: Option<f64>,
}

/// [`lucent_render::tracer::RegionErrors`] as written into render.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RegionErrorsReport {
    /// What the figures are (the relative standard error of the pixel's mean, RMS over R, G, B; the regions).
    pub definition: String,
    /// Pixels where at least half the camera rays hit the object first.
    pub object: QuantilesReport,
    /// Pixels where at least half the camera rays hit the board first.
    pub board: QuantilesReport,
    pub all: QuantilesReport,
}

/// Mean samples per pixel over the object's pixels and over the others.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SppByRegion {
    pub object: f64,
    pub other: f64,
}

/// The resolved inputs, written into render.json.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SceneSummary {
    pub scene_file: String,
    pub object: Option<String>,
    pub triangles: usize,
    pub mesh_report: Option<mesh::MeshReport>,
    pub object_bounds_m: Option<[[f64; 3]; 2]>,
    pub material: Option<MaterialSummary>,
    pub board: Option<String>,
    pub environment: String,
    pub projection: String,
    pub environment_centre_m: Option<[f64; 3]>,
    pub environment_radius_m: Option<f64>,
    pub camera: String,
    pub image_width: usize,
    pub image_height: usize,
    pub intrinsics: [f64; 4],
    /// The calibrated lens's coefficients in OpenCV's order for its model:
    /// k1, k2, p1, p2, k3 (`pinhole-k3`), then k4, k5, k6 (`rational`).
    pub distortion: Option<Vec<f64>>,
    pub band_weight_set: String,
}

/// The medium's band values.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct MaterialSummary {
    pub source: String,
    pub phase: String,
    pub mu_s_per_m: [f64; 3],
    pub mu_a_per_m: [f64; 3],
    pub g: [f64; 3],
    /// The boundary's index per band as rendered.
    pub n: [f64; 3],
    /// False when `dispersion = false` replaced the bands' indices by their
    /// mean (true in files written before the key existed).
    #[serde(default = "yes")]
    pub dispersion: bool,
    /// The boundary: "smooth" or the microfacet distribution with its α
    /// ("smooth" in files written before rough boundaries existed).
    #[serde(default = "smooth")]
    pub boundary: String,
    /// The similarity approximation, when the walk used it: the largest
    /// asymmetry asked for, and μs′ and g′ per band as walked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub similar: Option<SimilarSummary>,
}

/// The similar medium the object's walk used ([`apply_similarity`]).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct SimilarSummary {
    /// The largest asymmetry asked for (g′, the same in every band, is
    /// higher where a band's similar medium would otherwise be less than
    /// `lucent_render::tracer::SIMILAR_MIN_DEPTH` mean free paths deep
    /// across the object's thinnest side).
    pub g_max: f64,
    /// μs′ per band as walked, 1/m.
    pub mu_s_per_m: [f64; 3],
    /// g′ per band as walked.
    pub g: [f64; 3],
    /// With `[render] similarity_floor_events`, where the floor raised g′:
    /// the similar medium that a path walks from its `from_event`-th
    /// scattering event on (absent otherwise).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub later: Option<LaterSimilar>,
}

/// The similar medium (of the asked-for g′, raised to 1 mean free path
/// deep) that a path walks once it has scattered `from_event` times
/// (`[render] similarity_floor_events`).
#[derive(Debug, Clone, Serialize, Deserialize, PartialEq)]
pub struct LaterSimilar {
    /// `[render] similarity_floor_events`.
    pub from_event: u64,
    /// μs′ per band, 1/m.
    pub mu_s_per_m: [f64; 3],
    /// g′ per band: `g_max`, raised where the medium would be under 1 mean
    /// free path deep (`lucent_render::tracer::SIMILAR_LATER_MIN_DEPTH`).
    pub g: [f64; 3],
}

fn yes() -> bool {
    true
}

fn smooth() -> String {
    "smooth".into()
}

struct Ctx<'a> {
    path: &'a Path,
    dir: PathBuf,
    /// Only what describes the scene ([`load_for_merge`]): the environment
    /// map's size, not its pixels.
    summary_only: bool,
}

impl Ctx<'_> {
    fn key(&self, section: &'static str, key: &'static str, problem: KeyProblem) -> SceneFileError {
        SceneFileError::Key { path: self.path.to_path_buf(), section, key, problem: Box::new(problem) }
    }
    fn section(&self, section: &'static str, problem: SectionProblem) -> SceneFileError {
        SceneFileError::Section { path: self.path.to_path_buf(), section, problem: Box::new(problem) }
    }
    fn resolve(&self, p: &Path) -> PathBuf {
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            self.dir.join(p)
        }
    }
}

/// Parses a scene file's text (stage one: syntax, unknown keys).
pub fn parse(text: &str, path: &Path) -> Result<SceneFile, SceneFileError> {
    toml::from_str(text).map_err(|e: toml::de::Error| {
        let (line, column) = line_column(text, e.span());
        SceneFileError::Syntax { path: path.to_path_buf(), line, column, message: toml_message(text, &e) }
    })
}

/// A TOML parser's message for `text`, led by the key it concerns
/// ("[render] spp: …") where the error's line assigns one and the message
/// does not name it, with serde's type names in words ("expected u64" →
/// "expected a whole number ≥ 0").
pub(crate) fn toml_message(text: &str, e: &toml::de::Error) -> String {
    let mut message = e.message().trim_end().to_string();
    if let Some((rest, rust)) = message.rsplit_once("expected ") {
        let words = match rust {
            "u8" | "u16" | "u32" | "u64" | "usize" => Some("a whole number ≥ 0"),
            "i64" => Some("a whole number"),
            "f64" => Some("a number"),
            _ => None,
        };
        if let Some(words) = words {
            message = format!("{rest}expected {words}");
        }
    }
    let Some(start) = e.span().map(|s| s.start) else { return message };
    let before = text.get(..start).unwrap_or(text);
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    let line = text[line_start..].lines().next().unwrap_or("").trim_start();
    let key: String = line.chars().take_while(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.')).collect();
    if key.is_empty() || !line[key.len()..].trim_start().starts_with('=') || message.contains(key.as_str()) {
        return message;
    }
    // The last table header above the line, without a trailing comment.
    let section = before[..line_start]
        .lines()
        .rev()
        .map(|l| l.split('#').next().unwrap_or("").trim())
        .find(|l| l.starts_with('['));
    match section {
        Some(s) => format!("{s} {key}: {message}"),
        None => format!("{key}: {message}"),
    }
}

/// The 1-based line and column (in characters) where a TOML parser's error
/// span starts in `text`.
pub(crate) fn line_column(text: &str, span: Option<std::ops::Range<usize>>) -> (Option<usize>, Option<usize>) {
    match span {
        Some(span) => {
            let before = text.get(..span.start).unwrap_or(text);
            let line = before.matches('\n').count() + 1;
            let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
            (Some(line), Some(column))
        }
        None => (None, None),
    }
}

/// " line L, column C: " for a located syntax error, else " ".
pub(crate) fn location(line: Option<usize>, column: Option<usize>) -> String {
    match (line, column) {
        (Some(l), Some(c)) => format!(" line {l}, column {c}: "),
        _ => " ".into(),
    }
}

/// Loads and validates a scene file (both stages) into a renderable scene.
pub fn load(path: &Path) -> Result<LoadedScene, SceneFileError> {
    let text =
        crate::io::read_text(path).map_err(|source| SceneFileError::Read { path: path.to_path_buf(), source })?;
    let file = parse(&text, path)?;
    build(&file, path)
}

fn finite3(ctx: &Ctx, section: &'static str, key: &'static str, v: [f64; 3]) -> Result<DVec3, SceneFileError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(DVec3::from_array(v))
    } else {
        Err(ctx.key(section, key, KeyProblem::NotFinite { values: v.to_vec() }))
    }
}

fn read_scene_json(ctx: &Ctx, p: &Path) -> Result<SceneDescription, SceneFileError> {
    let full = ctx.resolve(p);
    let text = crate::io::read_text(&full)
        .map_err(|source| ctx.key("camera", "scene_json", KeyProblem::Read { file: full.clone(), source }))?;
    serde_json::from_str(&text)
        .map_err(|source| ctx.key("camera", "scene_json", KeyProblem::NotSceneJson { file: full.clone(), source }))
}

/// The recipe of the scene file's `[material]` (with its `weight_percent`
/// override), or `None` for a scene without one: what `lucent render
/// --uncertainty` reads the uncertain inputs from.
pub fn material_recipe(path: &Path) -> Result<Option<Recipe>, SceneFileError> {
    let text =
        crate::io::read_text(path).map_err(|source| SceneFileError::Read { path: path.to_path_buf(), source })?;
    let file = parse(&text, path)?;
    let Some(m) = &file.material else { return Ok(None) };
    let Some(recipe_path) = &m.recipe else { return Ok(None) };
    let ctx = Ctx { path, dir: path.parent().map(Path::to_path_buf).unwrap_or_default(), summary_only: true };
    Recipe::load(&ctx.resolve(recipe_path), Overrides { weight_percent: m.weight_percent })
        .map(Some)
        .map_err(|source| SceneFileError::Recipe { path: path.to_path_buf(), source })
}

/// [`load`] for `lucent merge`, which writes a render's outputs from its
/// shards' sums and needs the scene's settings and description, not its
/// light: the environment map is not decoded (its header gives the size the
/// description states) and the scene holds a black constant environment
/// instead. Everything else, and every check, is [`load`]'s.
pub fn load_for_merge(path: &Path) -> Result<LoadedScene, SceneFileError> {
    let text =
        crate::io::read_text(path).map_err(|source| SceneFileError::Read { path: path.to_path_buf(), source })?;
    let file = parse(&text, path)?;
    build_with(&file, path, true)
}

/// [`load`] (or [`load_for_merge`] with `summary_only`) with the file
/// edited between parsing and validation: how a command-line flag
/// overrides a key, checked like the key.
pub fn load_edited(
    path: &Path,
    summary_only: bool,
    edit: impl FnOnce(&mut SceneFile),
) -> Result<LoadedScene, SceneFileError> {
    let text =
        crate::io::read_text(path).map_err(|source| SceneFileError::Read { path: path.to_path_buf(), source })?;
    let mut file = parse(&text, path)?;
    edit(&mut file);
    build_with(&file, path, summary_only)
}

/// Every check of [`build`] on `file` (read from `path`) without decoding
/// the environment map's pixels: how `lucent run` checks the user's scene
/// template before it writes a stage's `input_scene.toml`, so an error names
/// the user's file and key.
pub fn check(file: &SceneFile, path: &Path) -> Result<(), SceneFileError> {
    build_with(file, path, true).map(|_| ())
}

/// Stage two: the validated scene.
pub fn build(file: &SceneFile, path: &Path) -> Result<LoadedScene, SceneFileError> {
    build_with(file, path, false)
}

fn build_with(file: &SceneFile, path: &Path, summary_only: bool) -> Result<LoadedScene, SceneFileError> {
    let ctx = Ctx { path, dir: path.parent().map(Path::to_path_buf).unwrap_or_default(), summary_only };
    let mut warnings = Vec::new();
    let scene_json = match &file.camera.scene_json {
        Some(p) => Some(read_scene_json(&ctx, p)?),
        None => None,
    };

    // --- camera
    let (camera, camera_desc) = build_camera(&ctx, &file.camera, scene_json.as_ref())?;

    // --- material and object
    let material = match &file.material {
        Some(m) => Some(checked_material(&ctx, m, &mut warnings)?),
        None => None,
    };
    let (object, object_desc, mesh_report, bounds, top_centre) = match (&file.object, material) {
        (Some(o), Some(material)) => placed_object(&ctx, o, material, scene_json.as_ref(), &mut warnings)?,
        (Some(_), None) => return Err(ctx.section("material", SectionProblem::ObjectNeedsMaterial)),
        (None, Some(_)) => return Err(ctx.section("object", SectionProblem::MaterialNeedsObject)),
        (None, None) => (None, None, None, None, None),
    };

    // --- board
    let board = match &file.board {
        Some(b) => Some(build_board(&ctx, b, scene_json.as_ref())?),
        None => None,
    };

    // --- environment
    let (environment, env_desc, projection_desc, centre, radius) =
        build_environment(&ctx, &file.environment, top_centre, &mut warnings)?;

    // --- where the camera is: outside the object, inside the finite sphere
    let eye = camera.position();
    check_camera_place(&ctx, file.object.as_ref(), eye, bounds, centre.zip(radius))?;

    // --- render settings
    let r = &file.render;
    let mut settings = render_settings(&ctx, r)?;

    let (object, material_summary) = match object {
        Some((o, s)) => (Some(o), Some(s)),
        None => (None, None),
    };
    let triangles = object.as_ref().map_or(0, |o| o.accel.len());
    // Phase connections by default only through a convex object's few face
    // planes: through any other mesh each needs the face search of the
    // environment connection for its weight, and on the worked example's
    // sphere they cost 1.35× the CPU time for no less variance.
    settings.phase_connection =
        r.phase_connections.unwrap_or_else(|| object.as_ref().is_none_or(|o| o.accel.convex_planes().is_some()));
    let (intr, dist) = (camera.intrinsics, camera.distortion.map(|l| l.distortion.to_opencv(l.model)));
    let (w, h) = (camera.width, camera.height);
    let scene = Scene::new(object, board.as_ref().map(|b| b.0.clone()), environment, camera)
        .map_err(|source| SceneFileError::Scene { path: path.to_path_buf(), source })?;
    if let Some(rep) = &mesh_report {
        warnings.extend(rep.warnings.iter().cloned());
    }
    let mut loaded = LoadedScene {
        scene,
        settings,
        summary: SceneSummary {
            scene_file: path.display().to_string(),
            object: object_desc,
            triangles,
            mesh_report,
            object_bounds_m: bounds,
            material: material_summary,
            board: board.map(|b| b.1),
            environment: env_desc,
            projection: projection_desc,
            environment_centre_m: centre,
            environment_radius_m: radius,
            camera: camera_desc,
            image_width: w,
            image_height: h,
            intrinsics: intr,
            distortion: dist,
            band_weight_set: lucent_colour::bands::BAND_WEIGHT_SET.into(),
        },
        warnings,
    };
    match (r.similarity_g, r.similarity_floor_events) {
        (_, Some(0)) => {
            let problem = SimilarityProblem::FloorEvents { value: 0 };
            return Err(ctx.key("render", "similarity_floor_events", KeyProblem::Similarity(problem)));
        }
        (None, Some(_)) => {
            let problem = SimilarityProblem::FloorEventsWithoutG;
            return Err(ctx.key("render", "similarity_floor_events", KeyProblem::Similarity(problem)));
        }
        (Some(g), floor_events) => apply_similarity(&mut loaded, g, floor_events, r.similarity_walked)
            .map_err(|problem| ctx.key("render", "similarity_g", KeyProblem::Similarity(problem)))?,
        (None, None) => {}
    }
    Ok(loaded)
}

/// A checked `[material]`: its bands, its index per band, its summary, the
/// object's size from the recipe and its boundary ([`checked_material`]).
type CheckedMaterial = (Bands, [f64; 3], MaterialSummary, Option<[f64; 3]>, Option<(Microsurface, String)>);

/// `[material]` `m` built and checked: valid coefficients in every band, its
/// boundary, and one index for all bands without dispersion.
fn checked_material(
    ctx: &Ctx,
    m: &MaterialSection,
    warnings: &mut Vec<String>,
) -> Result<CheckedMaterial, SceneFileError> {
    let (medium, mut eta, mut summary, size, surface) = build_material(ctx, m, warnings)?;
    for b in 0..3 {
        let (s, a) = (medium.mu_s_per_m[b], medium.mu_a_per_m[b]);
        if !lucent_render::slab::valid_coefficients(s, a) {
            let key = m.mu_s().map_or("mu_s_per_m", |(_, key)| key);
            return Err(ctx.key("material", key, KeyProblem::Coefficients { band: b, s, a }));
        }
    }
    let rough = build_roughness(ctx, m, surface)?;
    if let Some((_, desc)) = &rough {
        summary.boundary.clone_from(desc);
    }
    if m.dispersion == Some(false) {
        // One index for all bands (their mean), so that a path can
        // carry all three bands (spectral MIS in the renderer).
        eta = [(eta[0] + eta[1] + eta[2]) / 3.0; 3];
        summary.n = eta;
        summary.dispersion = false;
    }
    Ok((medium, eta, summary, size, rough))
}

/// The object placed in the scene ([`placed_object`]): the object with its
/// material's summary, its description, its mesh report, its bounds (m)
/// and the centre of its top.
type PlacedObject =
    (Option<(Object, MaterialSummary)>, Option<String>, Option<mesh::MeshReport>, Option<[[f64; 3]; 2]>, Option<DVec3>);

/// `[object]` `o` of `material`: its triangles in their BVH, its boundary
/// and its medium per band.
fn placed_object(
    ctx: &Ctx,
    o: &ObjectSection,
    (medium, eta, summary, size_from_recipe, rough): CheckedMaterial,
    scene_json: Option<&SceneDescription>,
    warnings: &mut Vec<String>,
) -> Result<PlacedObject, SceneFileError> {
    let (triangles, desc, report) = build_object_triangles(ctx, o, size_from_recipe, scene_json, warnings)?;
    let accel = Accel::new(&triangles);
    let (lo, hi) = accel.bounds();
    let scene_error = |source| SceneFileError::Scene { path: ctx.path.to_path_buf(), source };
    let interface = match rough {
        Some((surface, _)) => Interface::new(surface).map_err(|e| scene_error(e.into()))?,
        None => Interface::Smooth,
    };
    let Bands { mu_s_per_m, mu_a_per_m, phase } = medium;
    let [p0, p1, p2] = phase;
    let band = |b: usize, phase| Medium { mu_s_per_m: mu_s_per_m[b], mu_a_per_m: mu_a_per_m[b], phase, n: eta[b] };
    let object = Object::new(accel, interface, [band(0, p0), band(1, p1), band(2, p2)]).map_err(scene_error)?;
    let top = DVec3::new(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), hi.z);
    Ok((Some((object, summary)), Some(desc), report, Some([lo.to_array(), hi.to_array()]), Some(top)))
}

/// The camera at `eye` must be outside the object (`o`, within `bounds`)
/// and inside the finite environment sphere (`sphere`: centre, radius).
fn check_camera_place(
    ctx: &Ctx,
    o: Option<&ObjectSection>,
    eye: DVec3,
    bounds: Option<[[f64; 3]; 2]>,
    sphere: Option<([f64; 3], f64)>,
) -> Result<(), SceneFileError> {
    if let (Some(o), Some([lo, hi])) = (o, bounds)
        && (0..3).all(|k| lo[k] < eye[k] && eye[k] < hi[k])
    {
        let key = if o.transform.is_some() {
            "transform"
        } else if o.mesh.is_some() {
            "unit_scale_m"
        } else {
            "size_mm"
        };
        let hint = match key {
            "unit_scale_m" => "; a mesh in millimetres needs unit_scale_m = 0.001",
            "size_mm" => "; size_mm is in millimetres",
            _ => "; a transform places the object in metres",
        };
        let problem = KeyProblem::CameraInsideObject { lo, hi, camera: eye.to_array(), hint };
        return Err(ctx.key("object", key, problem));
    }
    if let Some((c, r)) = sphere {
        let distance = (eye - DVec3::from_array(c)).length();
        if distance >= r {
            let problem = KeyProblem::CameraOutsideSphere { radius: r, camera: eye.to_array(), centre: c, distance };
            return Err(ctx.key("environment", "radius_m", problem));
        }
    }
    Ok(())
}

/// The renderer's settings from `[render]` `r` (the defaults where it
/// gives none), each checked.
fn render_settings(ctx: &Ctx, r: &RenderSection) -> Result<Settings, SceneFileError> {
    let mut settings = Settings::default();
    if let Some(spp) = r.spp {
        if spp == 0 {
            return Err(ctx.key("render", "spp", KeyProblem::Zero));
        }
        settings.stop.samples = Some(spp.into());
    }
    if let Some(t) = r.time_s {
        if !(t > 0.0 && t.is_finite()) {
            return Err(ctx.key("render", "time_s", KeyProblem::NotPositive { value: t }));
        }
        settings.stop.time_s = Some(t);
    }
    if let Some(s) = r.seed {
        settings.seed = s;
    }
    if let Some(p) = r.spp_per_pass {
        if p == 0 {
            return Err(ctx.key("render", "spp_per_pass", KeyProblem::Zero));
        }
        settings.spp_per_pass = p;
    }
    if let Some(b) = r.spectral_mis {
        settings.spectral_mis = b;
    }
    if let Some(b) = r.band_branches {
        settings.band_branches = b;
    }
    if let Some(b) = r.medium_connections {
        settings.medium_nee = b;
    }
    if let Some(b) = r.specular_chains {
        settings.specular_chains = b;
    }
    if let Some(b) = r.sphere_jumps {
        settings.sphere_jumps = b;
    }
    if let Some(k) = r.sampling {
        settings.sampling = k.into();
    }
    if let Some(e) = r.target_rel_error {
        if !(e > 0.0 && e < 1.0) {
            return Err(ctx.key("render", "target_rel_error", KeyProblem::Fraction { value: e }));
        }
        settings.stop.pixel_rel_error = Some(e);
    }
    Ok(settings)
}

/// Why the similarity approximation cannot be applied.
#[derive(Debug, Clone, Error, PartialEq)]
pub enum SimilarityProblem {
    #[error("must lie in [0, 1) (an asymmetry g), got {value}")]
    Range { value: f64 },
    #[error("must be at least 1 (scattering events), got {value}")]
    FloorEvents { value: u64 },
    #[error("needs [render] similarity_g (the similar medium it applies to)")]
    FloorEventsWithoutG,
    #[error("{0}")]
    Object(#[from] lucent_render::tracer::SceneError),
}

/// Replaces the object's medium in every band by its similar medium of
/// asymmetry at most `g_max` (μs(1 − g), μa and n kept;
/// [`lucent_render::medium::Medium::similar`]) and records it in the
/// summary. An approximation that is exact in the diffusion limit; its
/// measured bias is in docs/method.md#render-similarity. A scene without
/// an object (env-scale's empty board) has nothing to make similar: only
/// `g_max` is checked. `floor_events`: hold the depth floor for a path's
/// first this many scattering events only
/// ([`lucent_render::tracer::Object::similar_floored_for`]). `walked`: the
/// g′ an earlier scene walked (and its later medium's event and g′), used
/// as they are instead ([`lucent_render::tracer::Object::similar_at`]).
pub fn apply_similarity(
    loaded: &mut LoadedScene,
    g_max: f64,
    floor_events: Option<u64>,
    walked: Option<(f64, Option<(u64, f64)>)>,
) -> Result<(), SimilarityProblem> {
    if !lucent_render::medium::valid_similarity_g(g_max) {
        return Err(SimilarityProblem::Range { value: g_max });
    }
    let Some(object) = loaded.scene.object.take() else {
        return Ok(());
    };
    let similar = match (walked, floor_events) {
        (Some((g_first, later)), _) => object.similar_at(g_first, later)?,
        (None, Some(events)) => object.similar_floored_for(g_max, events)?,
        (None, None) => object.similar(g_max)?,
    };
    // μs′ and g′ per band of an object's medium.
    let walked = |o: &lucent_render::tracer::Object| {
        let mu_s: [f64; 3] = std::array::from_fn(|b| o.medium[b].mu_s_per_m);
        let g: [f64; 3] = std::array::from_fn(|b| o.medium[b].phase.mean_cosine());
        (mu_s, g)
    };
    if let Some(m) = loaded.summary.material.as_mut() {
        let (mu_s_per_m, g) = walked(&similar);
        m.similar = Some(SimilarSummary {
            g_max,
            mu_s_per_m,
            g,
            later: similar.later().map(|(from_event, later)| {
                let (mu_s_per_m, g) = walked(later);
                LaterSimilar { from_event, mu_s_per_m, g }
            }),
        });
    }
    loaded.scene.object = Some(similar);
    Ok(())
}

fn build_camera(
    ctx: &Ctx,
    c: &CameraSection,
    scene_json: Option<&SceneDescription>,
) -> Result<(Camera, String), SceneFileError> {
    let distortion = match c.distortion.as_deref() {
        None | Some("none") => None,
        Some("calibrated") => {
            let Some(p) = &c.camera_json else {
                return Err(ctx.key("camera", "distortion", KeyProblem::CalibratedNeedsCameraJson));
            };
            let full = ctx.resolve(p);
            let text = crate::io::read_text(&full)
                .map_err(|source| ctx.key("camera", "camera_json", KeyProblem::Read { file: full.clone(), source }))?;
            let cal: lucent_calib::camera::Calibration = serde_json::from_str(&text).map_err(|source| {
                ctx.key("camera", "camera_json", KeyProblem::NotCameraJson { file: full.clone(), source })
            })?;
            let lens = cal.camera.lens();
            if lens.model == lucent_calib::model::DistortionModel::Fisheye {
                let problem = KeyProblem::UnsupportedLens { file: full, model: lens.model.name() };
                return Err(ctx.key("camera", "distortion", problem));
            }
            // The same lucent_lens::Lens type in both crates: the render's rays follow camera.json's lens.
            Some(lens)
        }
        Some(other) => {
            return Err(ctx.key(
                "camera",
                "distortion",
                KeyProblem::Choice { expected: "\"none\" or \"calibrated\"", got: other.into() },
            ))
        }
    };
    let cam_err = |e| ctx.section("camera", SectionProblem::Camera(e));
    if let Some(s) = scene_json {
        if c.position_m.is_some() || c.look_at_m.is_some() || c.intrinsics.is_some() || c.camera_to_world.is_some() {
            return Err(ctx.section(
                "camera",
                SectionProblem::Conflict {
                    first: "scene_json",
                    second: "an explicit camera (position_m/look_at_m or intrinsics/camera_to_world)",
                },
            ));
        }
        let k = &s.intrinsics;
        let (w, h) = (c.width.unwrap_or(s.image_width), c.height.unwrap_or(s.image_height));
        let cam = Camera::new(w, h, [k.fx, k.fy, k.cx, k.cy], s.camera_to_world, distortion).map_err(cam_err)?;
        return Ok((cam, format!("scene.json pose, {w}×{h}, fx {:.2} px", k.fx)));
    }
    let (Some(w), Some(h)) = (c.width, c.height) else {
        return Err(ctx.section("camera", SectionProblem::NoCamera));
    };
    match (c.intrinsics, c.camera_to_world, c.position_m, c.look_at_m) {
        (Some(k), Some(m), None, None) => {
            Ok((Camera::new(w, h, k, m, distortion).map_err(cam_err)?, "explicit intrinsics and pose".into()))
        }
        (None, None, Some(p), Some(t)) => {
            let fov = c.vertical_fov_deg.ok_or_else(|| {
                ctx.key("camera", "vertical_fov_deg", KeyProblem::Required { when: "with position_m/look_at_m" })
            })?;
            if !(fov > 0.0 && fov < 180.0) {
                return Err(ctx.key(
                    "camera",
                    "vertical_fov_deg",
                    KeyProblem::Between { low: 0.0, high: 180.0, value: fov },
                ));
            }
            let up = c.up.unwrap_or([0.0, 0.0, 1.0]);
            let cam = Camera::look_at(
                w,
                h,
                finite3(ctx, "camera", "position_m", p)?,
                finite3(ctx, "camera", "look_at_m", t)?,
                finite3(ctx, "camera", "up", up)?,
                fov,
            )
            .map_err(cam_err)?;
            let cam = match distortion {
                Some(_) => return Err(ctx.key("camera", "distortion", KeyProblem::CalibratedNeedsIntrinsics)),
                None => cam,
            };
            Ok((cam, format!("look-at from {p:?} to {t:?}, vertical FOV {fov}°")))
        }
        _ => Err(ctx.section("camera", SectionProblem::CameraKeys)),
    }
}

/// The medium's coefficients (1/m) and phase functions per band R, G, B,
/// before the index joins them.
struct Bands {
    mu_s_per_m: [f64; 3],
    mu_a_per_m: [f64; 3],
    phase: [Phase; 3],
}

type MaterialParts = (Bands, [f64; 3], MaterialSummary, Option<[f64; 3]>, Option<recipe::Surface>);

/// The boundary of `[material] roughness`: "recipe" (default: the recipe's
/// `[surface]` if it has one, else smooth), "smooth", or
/// "trowbridge-reitz:α" / "ggx:α" / "beckmann:α".
fn build_roughness(
    ctx: &Ctx,
    m: &MaterialSection,
    from_recipe: Option<recipe::Surface>,
) -> Result<Option<(Microsurface, String)>, SceneFileError> {
    use crate::surface::model::{RoughnessModel, RoughnessSpec, RoughnessSyntax};
    let analytic = |model: RoughnessModel, alpha: f64, origin: &str| {
        let d = model.distribution(alpha);
        d.validate().map_err(|e| ctx.key("material", "roughness", KeyProblem::Microfacet(e)))?;
        Ok(Some((Microsurface::Analytic(d), format!("rough: {} α = {alpha} ({origin})", model.label()))))
    };
    let text = m.roughness.as_deref().unwrap_or("recipe");
    let problem = match text.parse::<RoughnessSpec>().map_err(|e| e.problem) {
        Ok(RoughnessSpec::Recipe) => {
            return match from_recipe {
                Some(sf) => analytic(sf.model, sf.alpha, "the recipe's [surface]"),
                None => Ok(None),
            };
        }
        Ok(RoughnessSpec::Smooth) => return Ok(None),
        Ok(RoughnessSpec::Analytic { model, alpha }) => return analytic(model, alpha, "the scene file"),
        // The renderer's object takes an analytic distribution only.
        Ok(RoughnessSpec::Measured(_)) | Err(RoughnessSyntax::NoFile) => {
            KeyProblem::UnknownRoughnessModel("measured".into())
        }
        Err(RoughnessSyntax::NoModel) => KeyProblem::Choice {
            expected: "\"recipe\", \"smooth\" or MODEL:ALPHA (trowbridge-reitz, ggx, beckmann)",
            got: text.trim().into(),
        },
        Err(RoughnessSyntax::UnknownModel(m)) => KeyProblem::UnknownRoughnessModel(m),
        Err(RoughnessSyntax::NotANumber(a)) => KeyProblem::AlphaNotANumber(a),
        Err(RoughnessSyntax::Alpha(a)) => KeyProblem::Alpha(a),
    };
    Err(ctx.key("material", "roughness", problem))
}

/// `[material] phase`, any spelling `lucent bssrdf --phase` reads.
fn phase_model<'de, D: serde::Deserializer<'de>>(d: D) -> Result<Option<PhaseModel>, D::Error> {
    crate::io::named(d, "phase")
}

fn build_material(ctx: &Ctx, m: &MaterialSection, warnings: &mut Vec<String>) -> Result<MaterialParts, SceneFileError> {
    let mie = m.phase.unwrap_or(if m.recipe.is_some() { PhaseModel::Mie } else { PhaseModel::Hg }) == PhaseModel::Mie;
    let (mu_s, mu_s_key) = m.mu_s().map_err(|p| ctx.section("material", p))?;
    let (mu_a, mu_a_key) = m.mu_a().map_err(|p| ctx.section("material", p))?;
    let explicit = mu_s.is_some() || mu_a.is_some() || m.g.is_some();
    match (&m.recipe, explicit) {
        (Some(_), true) => Err(ctx.section(
            "material",
            SectionProblem::Conflict { first: "recipe", second: "explicit mu_s_per_m/mu_a_per_m/g" },
        )),
        (None, false) => Err(ctx.section("material", SectionProblem::NoMaterial)),
        (None, true) => {
            let need = |v: Option<[f64; 3]>, key: &'static str| {
                v.ok_or_else(|| ctx.key("material", key, KeyProblem::Required { when: "with explicit bands" }))
            };
            let (s, a, g, n) = (need(mu_s, mu_s_key)?, need(mu_a, mu_a_key)?, need(m.g, "g")?, need(m.n, "n")?);
            if mie {
                return Err(ctx.key("material", "phase", KeyProblem::MieNeedsRecipe));
            }
            let phase = hg_phases(ctx, g)?;
            let summary = MaterialSummary {
                source: "explicit bands".into(),
                phase: "Henyey–Greenstein".into(),
                mu_s_per_m: s,
                mu_a_per_m: a,
                g,
                n,
                dispersion: true,
                boundary: "smooth".into(),
                similar: None,
            };
            Ok((Bands { mu_s_per_m: s, mu_a_per_m: a, phase }, n, summary, None, None))
        }
        (Some(recipe_path), false) => {
            let full = ctx.resolve(recipe_path);
            let mut recipe = Recipe::load(&full, Overrides { weight_percent: m.weight_percent })
                .map_err(|source| SceneFileError::Recipe { path: ctx.path.to_path_buf(), source })?;
            if let Some((target, value)) = m.recipe_input {
                recipe = recipe
                    .with_input(target, value)
                    .map_err(|source| SceneFileError::Recipe { path: ctx.path.to_path_buf(), source })?;
            }
            let grid_text = m.wavelengths.as_deref().unwrap_or("380:780:10");
            let grid = grid_text
                .parse::<WavelengthGrid>()
                .map_err(|e| ctx.key("material", "wavelengths", KeyProblem::Wavelengths(e)))?;
            let options = bulk::Options { phase_entries: if mie { 4096 } else { 0 }, ..Default::default() };
            let spectrum = bulk::compute(&recipe, &grid, &options).map_err(|source| SceneFileError::Optics {
                path: ctx.path.to_path_buf(),
                wavelengths: grid_text.to_string(),
                source,
            })?;
            let weights = band_weights(&grid).map_err(|e| ctx.key("material", "wavelengths", KeyProblem::Bands(e)))?;
            for (b, f) in weights.coverage.iter().enumerate() {
                if *f < 0.99 {
                    warnings.push(format!(
                        "{}: [material] wavelengths {grid_text:?} span {:.1} % of band {}'s colour-matching mass",
                        ctx.path.display(),
                        100.0 * f,
                        ["R", "G", "B"][b]
                    ));
                }
            }
            let (medium, summary) = medium_from_spectrum(ctx, &spectrum, &weights, mie, &full)?;
            let size = recipe_size_m(&recipe);
            let eta = summary.n;
            Ok((medium, eta, summary, size, recipe.surface))
        }
    }
}

fn recipe_size_m(recipe: &Recipe) -> Option<[f64; 3]> {
    let [w, h] = recipe.size_m?;
    Some([w, h, recipe.thickness_m])
}

fn hg_phases(ctx: &Ctx, g: [f64; 3]) -> Result<[Phase; 3], SceneFileError> {
    let one = |b: usize| Phase::henyey_greenstein(g[b]).map_err(|e| ctx.key("material", "g", KeyProblem::Phase(e)));
    Ok([one(0)?, one(1)?, one(2)?])
}

/// The object's mesh in metres: `[object] mesh` (scaled by `unit_scale_m`,
/// with its report) or a plaque box of `size_mm`, else of the recipe's
/// size; with its description.
fn object_mesh(
    ctx: &Ctx,
    o: &ObjectSection,
    size_from_recipe: Option<[f64; 3]>,
) -> Result<(mesh::Mesh, String, Option<mesh::MeshReport>), SceneFileError> {
    Ok(match &o.mesh {
        Some(p) => {
            let scale = o.unit_scale_m.unwrap_or(1.0);
            if !(scale > 0.0 && scale.is_finite()) {
                return Err(ctx.key("object", "unit_scale_m", KeyProblem::NotPositive { value: scale }));
            }
            let full = ctx.resolve(p);
            let (m, report) = mesh::load(&full, scale)
                .map_err(|source| SceneFileError::Mesh { path: ctx.path.to_path_buf(), source })?;
            (m, format!("mesh {}", full.display()), Some(report))
        }
        None => {
            let size = match (o.size_mm, size_from_recipe) {
                (Some(s), _) => s.map(|v| v * 1e-3),
                (None, Some(s)) => s,
                (None, None) => return Err(ctx.section("object", SectionProblem::NoObjectSize)),
            };
            if size.iter().any(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(ctx.key("object", "size_mm", KeyProblem::BoxSize { sides_m: size }));
            }
            (
                mesh::plaque_box(size[0], size[1], size[2]),
                format!("plaque box {:.2} × {:.2} × {:.2} mm", size[0] * 1e3, size[1] * 1e3, size[2] * 1e3),
                None,
            )
        }
    })
}

/// `[object] transform` `t` checked for the mesh `mesh_obj`: finite, affine,
/// invertible, not a mirror, and leaving the object at least
/// [`MIN_OBJECT_SIZE_M`] across.
fn checked_transform(ctx: &Ctx, t: [[f64; 4]; 4], mesh_obj: &mesh::Mesh) -> Result<[[f64; 4]; 4], SceneFileError> {
    if t.iter().flatten().any(|v| !v.is_finite()) {
        return Err(ctx.key(
            "object",
            "transform",
            KeyProblem::NotFinite { values: t.iter().flatten().copied().collect() },
        ));
    }
    // An affine map that keeps a solid a solid: last row (0, 0, 0, 1),
    // an invertible 3 × 3 part (a zero or flattening matrix would
    // collapse the mesh to a plane, a line or a point).
    let a = |i: usize, j: usize| t[i][j];
    let det = a(0, 0) * (a(1, 1) * a(2, 2) - a(1, 2) * a(2, 1)) - a(0, 1) * (a(1, 0) * a(2, 2) - a(1, 2) * a(2, 0))
        + a(0, 2) * (a(1, 0) * a(2, 1) - a(1, 1) * a(2, 0));
    let scale = (0..3).flat_map(|i| (0..3).map(move |j| (i, j))).map(|(i, j)| a(i, j).abs()).fold(0.0, f64::max);
    if t[3] != [0.0, 0.0, 0.0, 1.0] || det.abs() <= 1e-9 * scale.powi(3) || scale == 0.0 {
        return Err(ctx.key(
            "object",
            "transform",
            KeyProblem::SingularTransform { determinant: det, last_row: t[3], largest: scale },
        ));
    }
    if det < 0.0 {
        return Err(ctx.key("object", "transform", KeyProblem::MirrorTransform { determinant: det }));
    }
    // The object after the transform: at least 1 µm across (a smaller
    // one covers no pixel of any camera lucent renders with).
    let size_before = (0..3)
        .map(|k| {
            let (lo, hi) = mesh_obj
                .positions_m
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[k]), hi.max(p[k])));
            hi - lo
        })
        .fold(0.0, f64::max);
    let linear = det.abs().cbrt();
    if size_before.is_finite() && size_before > 0.0 && size_before * linear < MIN_OBJECT_SIZE_M {
        return Err(ctx.key(
            "object",
            "transform",
            KeyProblem::VanishingTransform {
                determinant: det,
                scale: linear,
                size_m: size_before * linear,
                min_m: MIN_OBJECT_SIZE_M,
            },
        ));
    }
    Ok(t)
}

/// Band values of a computed spectrum; with `mie`, the band phase tables.
fn medium_from_spectrum(
    ctx: &Ctx,
    s: &OpticalSpectrum,
    w: &BandWeights,
    mie: bool,
    source: &Path,
) -> Result<(Bands, MaterialSummary), SceneFileError> {
    let avg = |v: &[f64], quantity: &'static str| {
        w.average(v).map_err(|source| ctx.section("material", SectionProblem::BandAverage { quantity, source }))
    };
    let (mu_s, mu_a, g, n) =
        (avg(&s.mu_s_per_m, "μs")?, avg(&s.mu_a_per_m, "μa")?, avg(&s.g, "g")?, avg(&s.n_bulk, "n_bulk")?);
    let phase = if mie {
        let tables = &s.phase;
        let entries = tables.first().map_or(0, Vec::len);
        let band = |b: usize| {
            let mut mix = vec![0.0; entries];
            for (i, table) in tables.iter().enumerate() {
                let weight = w.weights[b][i] * s.mu_s_per_m[i];
                for (m, p) in mix.iter_mut().zip(table) {
                    *m += weight * p;
                }
            }
            PhaseTable::from_theta_samples(&mix)
                .map(Phase::Tabulated)
                .map_err(|source| ctx.section("material", SectionProblem::PhaseTable { band: b, source }))
        };
        [band(0)?, band(1)?, band(2)?]
    } else {
        hg_phases(ctx, g)?
    };
    let summary = MaterialSummary {
        source: format!("{} ({})", source.display(), s.sample),
        phase: if mie {
            "Lorenz–Mie, band mixture of 4096-entry tables".into()
        } else {
            "Henyey–Greenstein with the band's g".into()
        },
        mu_s_per_m: mu_s,
        mu_a_per_m: mu_a,
        g,
        n,
        dispersion: true,
        boundary: "smooth".into(),
        similar: None,
    };
    Ok((Bands { mu_s_per_m: mu_s, mu_a_per_m: mu_a, phase }, summary))
}

type ObjectParts = (Vec<[DVec3; 3]>, String, Option<mesh::MeshReport>);

fn build_object_triangles(
    ctx: &Ctx,
    o: &ObjectSection,
    size_from_recipe: Option<[f64; 3]>,
    scene_json: Option<&SceneDescription>,
    warnings: &mut Vec<String>,
) -> Result<ObjectParts, SceneFileError> {
    let (mesh_obj, desc, report) = object_mesh(ctx, o, size_from_recipe)?;
    let lift = o.lift_m.unwrap_or(1e-6);
    if !(lift >= 0.0 && lift.is_finite()) {
        return Err(ctx.key("object", "lift_m", KeyProblem::Negative { value: lift }));
    }
    let chosen =
        [o.transform.is_some(), o.placement.is_some(), o.board_corner.is_some()].iter().filter(|x| **x).count();
    if chosen > 1 {
        return Err(ctx.section("object", SectionProblem::Placement));
    }
    // A transform places the object whole (its own z offset is the gap);
    // lift_m beside it would be ignored.
    if o.transform.is_some() && o.lift_m.is_some() {
        return Err(ctx.section("object", SectionProblem::Conflict { first: "transform", second: "lift_m" }));
    }
    let lifted = |mut m: [[f64; 4]; 4]| {
        m[2][3] += lift;
        m
    };
    let transform: [[f64; 4]; 4] = if let Some(t) = o.transform {
        checked_transform(ctx, t, &mesh_obj)?
    } else if let Some(p) = &o.placement {
        if p != "scene" {
            return Err(ctx.key(
                "object",
                "placement",
                KeyProblem::Choice { expected: "\"scene\" (the sample placement in scene_json)", got: p.clone() },
            ));
        }
        let Some(s) = scene_json.and_then(|s| s.sample.as_ref()) else {
            return Err(ctx.key("object", "placement", KeyProblem::PlacementNeedsSample));
        };
        lifted(s.object_to_world)
    } else if let Some([i, j]) = o.board_corner {
        let Some(s) = scene_json else {
            return Err(ctx.key("object", "board_corner", KeyProblem::BoardCornerNeedsSceneJson));
        };
        let (cols, rows) = (s.board.cols, s.board.rows);
        if i >= cols || j >= rows {
            return Err(ctx.key("object", "board_corner", KeyProblem::CornerOutside { i, j, columns: cols, rows }));
        }
        let size_m: [f64; 3] = std::array::from_fn(|k| {
            let (lo, hi) = mesh_obj
                .positions_m
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| (lo.min(p[k]), hi.max(p[k])));
            hi - lo
        });
        let frame = lucent_calib::scene::RendererFrame {
            camera_to_world: s.camera_to_world,
            world_from_board: s.world_from_board,
        };
        let placement = lucent_calib::scene::place_sample(
            &s.board,
            &lucent_calib::scene::SampleSpec { corner: [i, j], size_m },
            &frame,
        );
        lifted(placement.object_to_world)
    } else {
        lifted([[1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
    };
    let world = mesh_obj.transformed(&transform);
    if report.as_ref().is_some_and(|r| !r.closed) {
        warnings.push(format!(
            "{}: the mesh is not closed; paths inside the medium may leak through its holes (counted in render.json)",
            ctx.path.display()
        ));
    }
    let tris = world.triangles.iter().map(|t| t.map(|i| DVec3::from_array(world.positions_m[i as usize]))).collect();
    Ok((tris, desc, report))
}

/// The smallest object (largest side, metres) a `transform` may leave.
pub const MIN_OBJECT_SIZE_M: f64 = 1e-6;

type BoardParts = (Board, String);

/// When the board's geometry keys are required.
const NO_SCENE_JSON: &str = "(no scene_json to take the board from)";

fn read_spectrum_csv(ctx: &Ctx, key: &'static str, p: &Path) -> Result<[f64; 3], SceneFileError> {
    let full = ctx.resolve(p);
    let file = || full.clone();
    let bad = |problem| ctx.key("board", key, problem);
    let csv_err = |source| bad(KeyProblem::Csv { file: file(), source });
    let mut reader = csv::ReaderBuilder::new()
        .has_headers(false)
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .flexible(true)
        .from_path(&full)
        .map_err(csv_err)?;
    let (mut wl, mut r) = (Vec::new(), Vec::new());
    for (k, record) in reader.records().enumerate() {
        let record = record.map_err(csv_err)?;
        if record.iter().all(str::is_empty) {
            continue;
        }
        let num = |i: usize| record.get(i).and_then(|x| x.parse::<f64>().ok());
        match (record.len(), num(0), num(1)) {
            (2, Some(a), Some(b)) if a.is_finite() && b.is_finite() => {
                wl.push(a);
                r.push(b);
            }
            _ if k == 0 => continue, // header
            _ => {
                let line = record.position().map_or(k as u64 + 1, csv::Position::line);
                let text = crate::io::quoted_line(&record.iter().collect::<Vec<_>>().join(","));
                return Err(bad(KeyProblem::SpectrumLine { file: file(), line, text }));
            }
        }
    }
    if r.iter().any(|v| !(0.0..=1.0).contains(v)) {
        return Err(bad(KeyProblem::SpectrumRange { file: file() }));
    }
    let grid =
        WavelengthGrid::from_list(wl).map_err(|source| bad(KeyProblem::SpectrumGrid { file: file(), source }))?;
    let bands = |source| bad(KeyProblem::SpectrumBands { file: file(), source });
    let w = band_weights(&grid).map_err(bands)?;
    w.average(&r).map_err(bands)
}

fn build_board(
    ctx: &Ctx,
    b: &BoardSection,
    scene_json: Option<&SceneDescription>,
) -> Result<BoardParts, SceneFileError> {
    let explicit_geometry =
        b.origin_m.is_some() || b.u.is_some() || b.v.is_some() || b.columns.is_some() || b.rows.is_some();
    let (origin, u, v, square_m, columns, rows, desc) = if explicit_geometry || scene_json.is_none() {
        let need_usize = |x: Option<usize>, key: &'static str| {
            x.ok_or_else(|| ctx.key("board", key, KeyProblem::Required { when: NO_SCENE_JSON }))
        };
        let square_mm = b.square_mm.unwrap_or(20.0);
        let origin = finite3(
            ctx,
            "board",
            "origin_m",
            b.origin_m.ok_or_else(|| ctx.key("board", "origin_m", KeyProblem::Required { when: NO_SCENE_JSON }))?,
        )?;
        // Unit vectors, as documented: a u of [100, 0, 0] is a mistake, not a direction to normalise.
        let unit = |key: &'static str, v: [f64; 3]| -> Result<DVec3, SceneFileError> {
            let d = finite3(ctx, "board", key, v)?;
            if (d.length() - 1.0).abs() > 1e-6 {
                return Err(ctx.key("board", key, KeyProblem::NotUnit { values: v, length: d.length() }));
            }
            Ok(d.normalize())
        };
        let u = unit("u", b.u.unwrap_or([1.0, 0.0, 0.0]))?;
        let v = unit("v", b.v.unwrap_or([0.0, 1.0, 0.0]))?;
        let (c, r) = (need_usize(b.columns, "columns")?, need_usize(b.rows, "rows")?);
        (
            origin,
            u,
            v,
            square_mm * 1e-3,
            c,
            r,
            format!("{c} × {r} squares of {square_mm} mm at {:?}", origin.to_array()),
        )
    } else {
        let Some(s) = scene_json else {
            return Err(ctx.section("board", SectionProblem::NoBoardGeometry));
        };
        let spec: &BoardSpec = &s.board;
        if b.square_mm.is_some_and(|mm| (mm * 1e-3 - spec.square_m).abs() > 1e-9) {
            return Err(ctx.key(
                "board",
                "square_mm",
                KeyProblem::SquareMismatch { scene_json_mm: spec.square_m * 1e3 },
            ));
        }
        let wfb = s.world_from_board;
        let mul = |p: [f64; 3]| {
            DVec3::new(
                wfb[0][0] * p[0] + wfb[0][1] * p[1] + wfb[0][2] * p[2],
                wfb[1][0] * p[0] + wfb[1][1] * p[1] + wfb[1][2] * p[2],
                wfb[2][0] * p[0] + wfb[2][1] * p[1] + wfb[2][2] * p[2],
            )
        };
        let sq = spec.square_m;
        // Inner corners (0..cols, 0..rows): the squares run one square beyond them on every side.
        (
            mul([-sq, -sq, 0.0]),
            mul([1.0, 0.0, 0.0]),
            mul([0.0, 1.0, 0.0]),
            sq,
            spec.cols + 1,
            spec.rows + 1,
            format!("{} × {} squares of {} mm from scene.json", spec.cols + 1, spec.rows + 1, sq * 1e3),
        )
    };
    // The range of every command's square size (`lucent calibrate`, `pose`).
    if let Err(e) = lucent_calib::board::BoardSpec::check_square_mm(square_m * 1e3) {
        return Err(ctx.key("board", "square_mm", KeyProblem::Board(e)));
    }
    let reflectance = if let Some(t) = &b.texture {
        if b.even.is_some() || b.odd.is_some() || b.even_spectrum.is_some() || b.odd_spectrum.is_some() {
            return Err(
                ctx.section("board", SectionProblem::Conflict { first: "texture", second: "even/odd reflectances" })
            );
        }
        let full = ctx.resolve(t);
        let img = crate::imageio::read_rgb(&full).map_err(|e| ctx.key("board", "texture", KeyProblem::Image(e)))?;
        let rgb: Vec<[f64; 3]> =
            img.data.chunks(3).map(|c| [f64::from(c[0]), f64::from(c[1]), f64::from(c[2])]).collect();
        if rgb.iter().flatten().any(|v| !(0.0..=1.0).contains(v)) {
            return Err(ctx.key("board", "texture", KeyProblem::TextureRange { file: full }));
        }
        BoardReflectance::Texture { width: img.width, height: img.height, rgb }
    } else {
        let pick = |rgb: Option<[f64; 3]>,
                    spec: &Option<PathBuf>,
                    key_rgb: &'static str,
                    key_spec: &'static str,
                    default: [f64; 3]|
         -> Result<[f64; 3], SceneFileError> {
            match (rgb, spec) {
                (Some(_), Some(_)) => {
                    Err(ctx.section("board", SectionProblem::Conflict { first: key_rgb, second: key_spec }))
                }
                (Some(v), None) => {
                    if v.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x)) {
                        Ok(v)
                    } else {
                        Err(ctx.key("board", key_rgb, KeyProblem::Reflectance { values: v }))
                    }
                }
                (None, Some(p)) => read_spectrum_csv(ctx, key_spec, p),
                (None, None) => Ok(default),
            }
        };
        let even = pick(b.even, &b.even_spectrum, "even", "even_spectrum", [0.04; 3])?;
        let odd = pick(b.odd, &b.odd_spectrum, "odd", "odd_spectrum", [0.80; 3])?;
        BoardReflectance::Checker { even, odd }
    };
    let margin_m = b.margin_mm.unwrap_or(0.0) * 1e-3;
    let margin = b.margin.unwrap_or([0.80; 3]);
    let board = Board { origin, u, v, square_m, columns, rows, margin_m, margin, reflectance };
    Ok((board, desc))
}

type EnvParts = (Environment, String, String, Option<[f64; 3]>, Option<f64>);

/// An orientation file (`lucent env orient`) that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum OrientationFileError {
    #[error("{}: cannot read as an orientation file of `lucent env orient`: {source}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{}: not an orientation file of `lucent env orient`: {source}", path.display())]
    Parse { path: PathBuf, source: serde_json::Error },
    #[error("{}: {source}", path.display())]
    OtherMap { path: PathBuf, source: lucent_calib::env::EnvError },
}

/// The yaw an orientation file (`lucent env orient`) gives the map `map`.
fn orientation_yaw(path: &std::path::Path, map: &std::path::Path) -> Result<f64, OrientationFileError> {
    let p = || path.to_path_buf();
    let text = crate::io::read_text(path).map_err(|source| OrientationFileError::Read { path: p(), source })?;
    let o: lucent_calib::env::Orientation =
        serde_json::from_str(&text).map_err(|source| OrientationFileError::Parse { path: p(), source })?;
    let name = map.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    o.yaw_for_map(&name).map_err(|source| OrientationFileError::OtherMap { path: p(), source })
}

fn build_environment(
    ctx: &Ctx,
    e: &EnvironmentSection,
    top_centre: Option<DVec3>,
    warnings: &mut Vec<String>,
) -> Result<EnvParts, SceneFileError> {
    let projection_name = e.projection.as_deref().unwrap_or("finite-sphere");
    let (projection, centre, radius) = match projection_name {
        "infinite" => {
            if e.radius_m.is_some() || e.centre_m.is_some() {
                return Err(ctx.section("environment", SectionProblem::FiniteSphereKeys));
            }
            (Projection::Infinite, None, None)
        }
        "finite-sphere" => {
            let radius = e.radius_m.unwrap_or(0.60);
            if !(radius > 0.0 && radius.is_finite()) {
                return Err(ctx.key("environment", "radius_m", KeyProblem::NotPositive { value: radius }));
            }
            let centre = match e.centre_m {
                Some(c) => finite3(ctx, "environment", "centre_m", c)?,
                None => top_centre.unwrap_or(DVec3::ZERO),
            };
            (Projection::FiniteSphere { centre, radius_m: radius }, Some(centre.to_array()), Some(radius))
        }
        other => {
            return Err(ctx.key(
                "environment",
                "projection",
                KeyProblem::Choice { expected: "\"finite-sphere\" or \"infinite\"", got: other.into() },
            ))
        }
    };
    let yaw = match (&e.orientation, e.yaw_deg, &e.map) {
        (None, y, _) => y.unwrap_or(0.0),
        (Some(_), Some(_), _) => {
            return Err(ctx.section("environment", SectionProblem::Conflict { first: "yaw_deg", second: "orientation" }))
        }
        (Some(_), None, None) => return Err(ctx.section("environment", SectionProblem::OrientationNeedsMap)),
        (Some(o), None, Some(map)) => orientation_yaw(&ctx.resolve(o), map)
            .map_err(|e| ctx.key("environment", "orientation", KeyProblem::Orientation(e)))?,
    };
    let scale = e.scale.unwrap_or(1.0);
    if !yaw.is_finite() {
        return Err(ctx.key("environment", "yaw_deg", KeyProblem::NotFinite { values: vec![yaw] }));
    }
    if !(scale >= 0.0 && scale.is_finite()) {
        return Err(ctx.key("environment", "scale", KeyProblem::Negative { value: scale }));
    }
    let (env, desc) = match (&e.map, e.constant) {
        (Some(_), Some(_)) => {
            return Err(ctx.section("environment", SectionProblem::Conflict { first: "map", second: "constant" }))
        }
        (None, None) => return Err(ctx.section("environment", SectionProblem::NoEnvironment)),
        (None, Some(c)) => {
            if c.iter().any(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(ctx.key("environment", "constant", KeyProblem::Radiance { values: c }));
            }
            // As a 1 × 1 map, with the map's checks (32-bit values, the radiance bound).
            let data = c.iter().map(|&v| v as f32).collect();
            let env = Environment::new(1, 1, data, 0.0, scale, projection)
                .map_err(|source| ctx.key("environment", "constant", KeyProblem::Constant(source)))?;
            (env, format!("constant {c:?} × {scale}"))
        }
        (Some(p), None) if ctx.summary_only => {
            let full = ctx.resolve(p);
            let (width, height) = crate::imageio::image_size(&full)
                .map_err(|source| SceneFileError::Image { path: ctx.path.to_path_buf(), source })?;
            let env = Environment::constant([0.0; 3], projection);
            (env, format!("{} ({width}×{height}), yaw {yaw}°, scale {scale}", full.display()))
        }
        (Some(p), None) => {
            let full = ctx.resolve(p);
            let img = crate::imageio::read_rgb(&full)
                .map_err(|source| SceneFileError::Image { path: ctx.path.to_path_buf(), source })?;
            // Lossy EXR compression (DWAB, as in Blender's maps) leaves tiny
            // negative values; they are set to 0, never kept. Where the light
            // they remove is below NEGATIVE_LIGHT_WARN of the map's (no render
            // could see it) that is not warned about, otherwise it is. (The
            // environment's description stays the map's alone: a sharded
            // render's merge describes the scene without reading the map.)
            lucent_calib::env::check_equirectangular(img.width, img.height).map_err(|source| {
                ctx.key("environment", "map", KeyProblem::Equirectangular { file: full.clone(), source })
            })?;
            let mut data = img.data;
            let negative = data.iter().filter(|v| **v < 0.0).count();
            if negative > 0 {
                let min = data.iter().copied().fold(0.0f32, f32::min);
                let max = data.iter().copied().fold(0.0f32, f32::max);
                let removed: f64 = data.iter().filter(|v| **v < 0.0).map(|v| -f64::from(*v)).sum();
                let total: f64 = data.iter().map(|v| f64::from(v.abs())).sum();
                let fraction = if total > 0.0 { removed / total } else { 1.0 };
                let text = format!(
                    "{negative} negative values (down to {min:e}, map maximum {max:e}; {fraction:.1e} of the map's light) set to 0"
                );
                if fraction > NEGATIVE_LIGHT_WARN {
                    warnings.push(format!("{}: {text}", full.display()));
                }
                data.iter_mut().for_each(|v| *v = v.max(0.0));
            }
            let env = Environment::new(img.width, img.height, data, yaw, scale, projection).map_err(|source| {
                ctx.key("environment", "map", KeyProblem::Environment { file: full.clone(), source })
            })?;
            (env, format!("{} ({}×{}), yaw {yaw}°, scale {scale}", full.display(), img.width, img.height))
        }
    };
    Ok((env, desc, projection_name.to_string(), centre, radius))
}

/// The fraction of an environment map's light (Σ|value|) that its negative
/// values, set to 0, may take away without a warning: 10⁻⁴, far below any
/// render's Monte Carlo noise (studio.exr's three DWAB negatives are 8·10⁻¹²,
/// night.exr's 829 are 6·10⁻⁷). Above it the map is not a linear radiance map
/// and the user is warned.
pub const NEGATIVE_LIGHT_WARN: f64 = 1e-4;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn board_spectrum_csv_takes_comments_and_a_header_and_names_bad_lines() {
        let dir = tempfile::tempdir().unwrap();
        let ctx = Ctx { path: Path::new("scene.toml"), dir: dir.path().to_path_buf(), summary_only: false };
        let p = dir.path().join("r.csv");
        let mut text = String::from("# a grey card\nwavelength_nm, reflectance\n");
        for w in (380..=780).step_by(5) {
            text += &format!("{w}, 0.5\n");
        }
        std::fs::write(&p, &text).unwrap();
        // A constant spectrum is that constant in every band (band weights sum to 1).
        let rgb = read_spectrum_csv(&ctx, "even_spectrum", &p).unwrap();
        assert!(rgb.iter().all(|v| (v - 0.5).abs() < 1e-12), "{rgb:?}");
        std::fs::write(&p, "380,0.5\n385,x\n").unwrap();
        let e = read_spectrum_csv(&ctx, "even_spectrum", &p).unwrap_err().to_string();
        assert!(e.contains("r.csv") && e.contains("line 2") && e.contains("wavelength_nm,reflectance"), "{e}");
    }

    #[test]
    fn syntax_errors_give_file_line_and_column() {
        let text = "[camera]\nwidth = 64\nheight = = 3\n";
        let e = parse(text, Path::new("scenes/bad.toml")).unwrap_err();
        let SceneFileError::Syntax { line, column, .. } = &e else { panic!("{e:?}") };
        assert_eq!((*line, *column), (Some(3), Some(10)), "{e}");
        assert!(e.to_string().starts_with("scenes/bad.toml: line 3, column 10: "), "{e}");
        let e = parse("[camera]\nwidht = 64\n", Path::new("s.toml")).unwrap_err();
        assert!(e.to_string().starts_with("s.toml: line 2, column 1: unknown field `widht`"), "{e}");
    }

    /// A scene written with the earlier keys `sigma_s_per_m` and
    /// `sigma_a_per_m` loads to the same material as with `mu_s_per_m` and
    /// `mu_a_per_m`; both spellings of one key at once are refused.
    #[test]
    fn earlier_coefficient_keys_still_load() {
        let fixture = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/render/plaque_dense.toml");
        let text = std::fs::read_to_string(&fixture).unwrap();
        assert!(text.contains("\nmu_s_per_m = ") && text.contains("\nmu_a_per_m = "));
        let dir = tempfile::tempdir().unwrap();
        let old = dir.path().join("old.toml");
        std::fs::write(
            &old,
            text.replace("\nmu_s_per_m = ", "\nsigma_s_per_m = ").replace("\nmu_a_per_m = ", "\nsigma_a_per_m = "),
        )
        .unwrap();
        let (a, b) = (load(&fixture).unwrap().summary, load(&old).unwrap().summary);
        assert_eq!(serde_json::to_value(&a.material).unwrap(), serde_json::to_value(&b.material).unwrap());
        assert_eq!(b.material.map(|m| m.mu_s_per_m), Some([1200.0, 1500.0, 1800.0]));
        let both = dir.path().join("both.toml");
        std::fs::write(&both, text.replace("\nmu_s_per_m = ", "\nsigma_s_per_m = [1.0, 1.0, 1.0]\nmu_s_per_m = "))
            .unwrap();
        let e = load(&both).unwrap_err();
        let SceneFileError::Section { section, problem, .. } = &e else { panic!("{e:?}") };
        assert_eq!(*section, "material");
        assert!(
            matches!(**problem, SectionProblem::Conflict { first: "mu_s_per_m", second: "sigma_s_per_m" }),
            "{e:?}"
        );
    }

    /// Phase connections are on by default through a plaque's few face
    /// planes, off through another mesh (the worked example's sphere), and
    /// the scene key overrides both.
    #[test]
    fn phase_connections_default_by_the_objects_faces() {
        let root = Path::new(env!("CARGO_MANIFEST_DIR"));
        let plaque = load(&root.join("fixtures/render/plaque_dense.toml")).unwrap();
        assert!(plaque.settings.phase_connection);
        let dir = tempfile::tempdir().unwrap();
        for f in ["scene.toml", "part.obj", "tio2_pmma.toml"] {
            std::fs::copy(root.join("fixtures/example").join(f), dir.path().join(f)).unwrap();
        }
        std::fs::copy(root.join("fixtures/env/studio.exr"), dir.path().join("studio.exr")).unwrap();
        let sphere = dir.path().join("scene.toml");
        assert!(!load(&sphere).unwrap().settings.phase_connection);
        let text = std::fs::read_to_string(&sphere).unwrap();
        let asked = dir.path().join("asked.toml");
        std::fs::write(&asked, text.replace("[render]\n", "[render]\nphase_connections = true\n")).unwrap();
        assert!(load(&asked).unwrap().settings.phase_connection);
    }
}
