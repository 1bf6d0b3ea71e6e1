//! `lucent bssrdf`: slab BSSRDF slices (docs/method.md#slab) and their comparison with
//! measured slices.

use super::interrupt::Interrupt;
use crate::bssrdf::{self, OpticalUsed, RunConfig, Summary};
use crate::fault::Interrupted;
use crate::optics::recipe::{Overrides, Recipe};
use crate::optics::{bulk, PhaseModel};
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use indicatif::{ProgressBar, ProgressStyle};
use lucent_render::phase::{Phase, PhaseTable};
use lucent_render::slab::{self, Beam, BeamMap, Directions, Estimator, Medium, RunOptions, Sensor, Setup, Slab, Stop};
use lucent_render::stop::{Condition, Standing};
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BssrdfArgs {
    #[command(subcommand)]
    pub command: Option<BssrdfCommand>,
    #[command(flatten)]
    pub run: RunArgs,
}

#[derive(Debug, Subcommand)]
pub enum BssrdfCommand {
    /// Score a simulated slice against a measured one.
    Compare(CompareArgs),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum EstimatorChoice {
    /// The ring connection where it applies (θi = 0 or θo = 0, thick slab, smooth top), else the lobe connection
    /// (thick slab, smooth or rough top), else the fixed-direction one.
    Auto,
    /// The ring connection (azimuthal symmetry; an error where it does not apply).
    Ring,
    /// The lobe connection (MIS with chains drawn through the phase lobe around the exit direction; thick slab,
    /// smooth or rough top).
    Lobe,
    /// The explicit connection along the one fixed exit direction (the previous estimator).
    Connection,
}

#[derive(Debug, Args)]
pub struct RunArgs {
    /// Recipe (TOML); optical properties by Lorenz–Mie at --wavelength.
    #[arg(long, conflicts_with_all = ["mu_s", "mu_a", "g", "n"])]
    pub recipe: Option<PathBuf>,
    /// Weight percentage for a recipe that leaves it unknown.
    #[arg(long)]
    pub weight_percent: Option<f64>,
    /// Wavelength in nm (with --recipe; `--wavelength` is the older spelling).
    #[arg(long = "wavelength-nm", alias = "wavelength", default_value_t = 550.0)]
    pub wavelength: f64,
    /// Scattering coefficient [1/m] (instead of a recipe).
    #[arg(long, requires_all = ["mu_a", "g", "n"])]
    pub mu_s: Option<f64>,
    /// Absorption coefficient [1/m].
    #[arg(long)]
    pub mu_a: Option<f64>,
    /// Asymmetry parameter (Henyey–Greenstein) without a recipe.
    #[arg(long, allow_hyphen_values = true)]
    pub g: Option<f64>,
    /// Refractive index of the slab without a recipe.
    #[arg(long)]
    pub n: Option<f64>,
    /// Slab thickness in mm (default: the recipe's, else 6.35).
    #[arg(long, allow_hyphen_values = true)]
    pub thickness_mm: Option<f64>,
    #[arg(long, default_value_t = 45.0, allow_hyphen_values = true)]
    pub theta_i: f64,
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub phi_i: f64,
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub theta_o: f64,
    #[arg(long, default_value_t = 180.0, allow_hyphen_values = true)]
    pub phi_o: f64,
    /// Several θi/θo configurations at once, e.g. 45/0,0/45,45/15 (φi, φo as given).
    #[arg(long)]
    pub configs: Option<crate::bssrdf::Configurations>,
    /// Phase function (default: mie with a recipe, hg otherwise).
    #[arg(long, value_parser = super::choices::named::<PhaseModel>())]
    pub phase: Option<PhaseModel>,
    /// Walk the first-order similar medium whose asymmetry is at most G
    /// (μs(1 − g), μa and n kept; an approximation whose bias this command
    /// can measure against the exact medium; 0 ≤ G < 1).
    #[arg(long, value_name = "G", allow_hyphen_values = true)]
    pub similarity_g: Option<f64>,
    #[command(flatten)]
    pub beam: super::groups::BeamArgs,
    /// Pixels per side of the camera.
    #[arg(long, default_value_t = 259)]
    pub pixels: usize,
    /// Pixel size on the surface in mm.
    #[arg(long, default_value_t = 0.1029)]
    pub pixel_mm: f64,
    /// Keep only the central N × N pixels (117 when given without a value).
    #[arg(long, num_args = 0..=1, default_missing_value = "117")]
    pub crop: Option<usize>,
    /// Stop at this relative standard error of the slice sum (default without
    /// any stop rule: 0.01, capped at 600 s).
    #[arg(long)]
    pub rel_error: Option<f64>,
    /// Stop when the median per-pixel relative standard error over the pixels
    /// above 1 % of the maximum reaches this (e.g. 0.05).
    #[arg(long)]
    pub pixel_rel_error: Option<f64>,
    /// Stop after this many light paths.
    #[arg(long)]
    pub paths: Option<u64>,
    /// Stop after this many seconds.
    #[arg(long)]
    pub time_s: Option<f64>,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Estimator of the slice.
    #[arg(long, value_enum, default_value_t = EstimatorChoice::Auto)]
    pub estimator: EstimatorChoice,
    /// Camera-side vertices of the lobe connection's chains (0 … 32; 0 is the fixed-direction connection).
    #[arg(long, default_value_t = lucent_render::slab::LOBE_VERTICES as u8)]
    pub lobe_vertices: u8,
    /// Top boundary: smooth, tr:ALPHA (ggx:ALPHA), beckmann:ALPHA, or
    /// measured:FIT.json (the normals.exr beside a `lucent surface fit`
    /// fit.json). Default: the recipe's [surface], else smooth.
    #[arg(long)]
    pub roughness: Option<String>,
    /// Do not fold the slice about the plane of incidence (the fold is exact,
    /// and applied, when φi and φo are 0° or 180° and the beam is mirror-symmetric).
    #[arg(long)]
    pub no_fold: bool,
    /// Carry the recipe's uncertain inputs (e.g. `weight_percent = { value =
    /// 0.65, sd = 0.03 }`) to the slice: per input, the slices at ±1 σ
    /// traced with the nominal one's random numbers; writes uncertainty.json,
    /// band.exr, profile-band.csv and profile-band.png beside the slice.
    /// Needs --recipe and --paths or --time-s.
    #[arg(long, requires = "recipe")]
    pub uncertainty: bool,
    /// Output folder.
    #[arg(long, default_value = "lucent-out/bssrdf")]
    pub out: PathBuf,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Trace only the K-th of N disjoint ranges of path batches of this run
    /// (0 ≤ K < N) into --out as a shard (slice-I.acc per configuration,
    /// shard.json); `lucent merge` adds the N shards into the run's outputs.
    /// Needs --paths and no other stop rule.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
}

/// The scalar tallies of a slice shard, in this order.
const SHARD_SCALARS: [&str; 8] =
    ["path_sum", "path_sq", "reflected", "transmitted", "events", "batches", "paths", "wall_s"];

/// The accumulator file of configuration `i` in a shard folder.
fn shard_acc(i: usize) -> String {
    format!("slice-{i}.acc")
}

/// A shard's tallies of one configuration as written by [`write_slice_shard`].
fn read_slice_shard(path: &Path, npix: usize) -> Result<crate::shard::Arrays> {
    let arrays = crate::shard::read_accumulator(path)?;
    for name in ["sum_b", "sq_b", "raw"] {
        crate::shard::array(&arrays, name, npix, path)?;
    }
    crate::shard::array(&arrays, "scalars", SHARD_SCALARS.len(), path)?;
    Ok(arrays)
}

fn write_slice_shard(path: &Path, meta: &crate::shard::AccMeta, t: &slab::SliceSums) -> Result<()> {
    let scalars = [
        t.path_sum,
        t.path_sq,
        t.reflected,
        t.transmitted,
        t.events as f64,
        t.batches as f64,
        t.paths as f64,
        t.wall_s,
    ];
    crate::shard::write_shard_accumulator(
        path,
        meta,
        &[("sum_b", &t.sum_b), ("sq_b", &t.sq_b), ("raw", &t.raw), ("scalars", &scalars)],
    )?;
    Ok(())
}

/// `empty` with the tallies of a shard's arrays (read by [`read_slice_shard`]).
fn slice_sums_of(empty: &slab::SliceSums, arrays: &crate::shard::Arrays) -> slab::SliceSums {
    let get = |name: &str| arrays.iter().find(|(n, _)| n == name).map(|(_, v)| v.clone()).unwrap_or_default();
    let sc = get("scalars");
    let at = |k: usize| sc.get(k).copied().unwrap_or(0.0);
    slab::SliceSums {
        sum_b: get("sum_b"),
        sq_b: get("sq_b"),
        raw: get("raw"),
        path_sum: at(0),
        path_sq: at(1),
        reflected: at(2),
        transmitted: at(3),
        events: at(4) as u64,
        batches: at(5) as u64,
        paths: at(6) as u64,
        wall_s: at(7),
        ..empty.clone()
    }
}

#[derive(Debug, Args)]
pub struct CompareArgs {
    /// Measured slice (EXR, 32-bit TIFF or CSV grid).
    #[arg(long)]
    pub measured: PathBuf,
    /// Pixel size of the measured slice in mm (else from FILE.json).
    #[arg(long)]
    pub measured_pixel_mm: Option<f64>,
    /// Simulated slice: a run folder or its bssrdf.exr.
    #[arg(long)]
    pub simulated: PathBuf,
    /// Mask: measured pixels above this fraction of the measured maximum.
    #[arg(long, default_value_t = crate::job::DEFAULT_THRESHOLD)]
    pub threshold: f64,
    #[arg(long, default_value = "lucent-out/bssrdf-compare")]
    pub out: PathBuf,
}

pub fn run(a: BssrdfArgs) -> Result<()> {
    match a.command {
        Some(BssrdfCommand::Compare(c)) => compare(c),
        None => simulate_from(a.run, None),
    }
}

/// The medium, thickness and description of what was used.
struct MediumChoice {
    /// The recipe's measured surface, if any.
    surface: Option<crate::optics::recipe::Surface>,
    medium: Medium,
    thickness_m: f64,
    used: OpticalUsed,
    phase_name: String,
}

/// The medium of the arguments, the recipe read from `--recipe`.
fn medium(a: &RunArgs) -> Result<MediumChoice> {
    medium_of(a, load_recipe(a)?.as_ref())
}

/// `--recipe`'s recipe (with `--weight-percent`), if given.
fn load_recipe(a: &RunArgs) -> Result<Option<Recipe>> {
    let overrides = Overrides { weight_percent: a.weight_percent };
    Ok(a.recipe.as_ref().map(|path| Recipe::load(path, overrides)).transpose()?)
}

/// The medium of the arguments with `recipe` as the recipe (`None`: the
/// explicit coefficients).
fn medium_of(a: &RunArgs, recipe: Option<&Recipe>) -> Result<MediumChoice> {
    let choice = exact_medium(a, recipe)?;
    similar_if_asked(a, choice)
}

/// `choice` with its medium replaced by the similar one when --similarity-g asks for it.
fn similar_if_asked(a: &RunArgs, mut choice: MediumChoice) -> Result<MediumChoice> {
    if let Some(g_max) = a.similarity_g {
        let similar = choice.medium.similar(g_max).map_err(|e| anyhow::anyhow!("--similarity-g: {e}"))?;
        choice.phase_name = format!(
            "{}, similar medium (g′ = {:.4}, μs′ = {:.6} /m)",
            choice.phase_name,
            similar.phase.mean_cosine(),
            similar.mu_s_per_m
        );
        choice.medium = similar;
    }
    Ok(choice)
}

/// --thickness-mm in metres, checked.
fn explicit_thickness_m(a: &RunArgs) -> Result<Option<f64>> {
    match a.thickness_mm {
        Some(t) if !(t.is_finite() && t > 0.0) => {
            bail!("--thickness-mm {t}: the slab thickness must be a positive number of millimetres")
        }
        t => Ok(t.map(|t| t * 1e-3)),
    }
}

/// The medium of `recipe` at --wavelength-nm (Lorenz–Mie), with the phase function --phase asks for.
fn recipe_medium(a: &RunArgs, recipe: &Recipe, warn: bool) -> Result<MediumChoice> {
    let options = bulk::Options::default();
    let s = bulk::at_wavelength(recipe, a.wavelength, &options)?;
    if warn {
        for w in &s.warnings {
            eprintln!("warning: {}: {w} (at {} nm)", recipe.name, a.wavelength);
        }
    }
    let choice = a.phase.unwrap_or(PhaseModel::Mie);
    let (phase, name) = match choice {
        PhaseModel::Mie => {
            (Phase::Tabulated(PhaseTable::from_theta_samples(&s.phase)?), "mie (4096-entry table)".to_string())
        }
        PhaseModel::Hg => (Phase::henyey_greenstein(s.g)?, format!("hg (g = {:.5})", s.g)),
    };
    let medium = Medium::new(s.mu_s_per_m, s.mu_a_per_m, phase, s.n_bulk.max(1.0))?;
    Ok(MediumChoice {
        surface: recipe.surface,
        medium,
        thickness_m: explicit_thickness_m(a)?.unwrap_or(recipe.thickness_m),
        used: OpticalUsed { mu_s_per_m: s.mu_s_per_m, mu_a_per_m: s.mu_a_per_m, g: s.g, n: s.n_bulk },
        phase_name: name,
    })
}

fn exact_medium(a: &RunArgs, recipe: Option<&Recipe>) -> Result<MediumChoice> {
    let explicit_thickness = explicit_thickness_m(a)?;
    if let Some(recipe) = recipe {
        recipe_medium(a, recipe, true)
    } else {
        let (Some(mu_s), Some(mu_a), Some(g), Some(n)) = (a.mu_s, a.mu_a, a.g, a.n) else {
            bail!("give --recipe R.toml, or all of --mu-s --mu-a --g --n (and optionally --thickness-mm)");
        };
        if a.phase == Some(PhaseModel::Mie) {
            bail!("--phase mie needs --recipe (a tabulated Lorenz–Mie phase function)");
        }
        let medium = Medium::new(mu_s, mu_a, Phase::henyey_greenstein(g)?, n)?;
        Ok(MediumChoice {
            surface: None,
            medium,
            thickness_m: explicit_thickness.unwrap_or(6.35e-3),
            used: OpticalUsed { mu_s_per_m: mu_s, mu_a_per_m: mu_a, g, n },
            phase_name: format!("hg (g = {g})"),
        })
    }
}

/// One uncertain recipe input of `lucent bssrdf --uncertainty`: its key,
/// nominal value and standard deviation, and the slabs at ±1 σ.
pub struct Perturbation {
    pub key: String,
    pub nominal: f64,
    pub sd: f64,
    plus: Slab,
    minus: Slab,
}

/// The perturbed slabs of --uncertainty (empty without it) of `recipe`, their tops `top`.
fn perturbations(
    a: &RunArgs,
    recipe: Option<&Recipe>,
    top: &lucent_render::interface::Interface,
) -> Result<Vec<Perturbation>> {
    if !a.uncertainty {
        return Ok(Vec::new());
    }
    let Some(recipe) = recipe else {
        bail!("--uncertainty needs --recipe: the uncertain inputs are a recipe's (e.g. weight_percent = {{ value = 0.65, sd = 0.03 }})");
    };
    if recipe.uncertain.is_empty() {
        bail!(
            "--uncertainty: {} gives no input with an uncertainty (write e.g. weight_percent = {{ value = 0.65, sd = 0.03 }})",
            recipe.path.display()
        );
    }
    recipe
        .uncertain
        .iter()
        .map(|input| {
            let sd = crate::optics::uncertainty::standard_deviation(&input.distribution);
            let slab_at = |v: f64| -> Result<Slab> {
                let r = recipe
                    .with_input(input.target, v)
                    .with_context(|| format!("--uncertainty: {} = {v} (nominal ∓ 1 σ)", input.key))?;
                let m = similar_if_asked(a, recipe_medium(a, &r, false)?)?;
                Ok(Slab::new(m.thickness_m, m.medium)?.with_top(top.clone()))
            };
            Ok(Perturbation {
                key: input.key.clone(),
                nominal: input.nominal,
                sd,
                plus: slab_at(input.nominal + sd)?,
                minus: slab_at(input.nominal - sd)?,
            })
        })
        .collect()
}

/// The larger of the map's Gaussian-equivalent FWHMs along x and y [m]:
/// the FWHM of a Gaussian of σ² the irradiance-weighted variance of the
/// pixel centres (the conversion is `slab::fwhm_to_sigma`'s, inverted).
fn beam_map_fwhm_m(map: &BeamMap) -> f64 {
    let (mut w, mut sx, mut sy, mut sxx, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (i, v) in map.values.iter().enumerate() {
        let (x, y) = ((i % map.width) as f64 * map.pixel_m, (i / map.width) as f64 * map.pixel_m);
        w += v;
        sx += v * x;
        sy += v * y;
        sxx += v * x * x;
        syy += v * y * y;
    }
    let var = |s: f64, ss: f64| (ss / w - (s / w).powi(2)).max(0.0);
    var(sx, sxx).max(var(sy, syy)).sqrt() / slab::fwhm_to_sigma(1.0)
}

/// One configuration of a `lucent bssrdf` run, set up as the command sets it up.
pub struct PlannedRun {
    /// θi, φi, θo, φo in degrees.
    pub angles: (f64, f64, f64, f64),
    pub dirs: Directions,
    pub setup: Setup,
    pub options: RunOptions,
    /// Per [`Plan::perturbations`] entry, the setups at +1 σ and −1 σ.
    pub pairs: Vec<(Setup, Setup)>,
}

/// Everything `lucent bssrdf` simulates for the arguments, checked before
/// any work: the medium (the recipe's bulk properties at the wavelength, or
/// the explicit coefficients), the beam, the sensor (only the crop is
/// simulated), the stop rule (without one: 1 % on the slice sum, at most
/// 600 s per configuration), the top boundary, and per configuration the
/// directions, the estimator and the run options.
pub struct Plan {
    medium: MediumChoice,
    pub beam: Beam,
    pub beam_name: String,
    /// Pixels per side of the simulated (cropped) slice.
    pub out_pixels: usize,
    pub stop: Stop,
    /// The top boundary as described in summary.json.
    pub roughness: String,
    pub runs: Vec<PlannedRun>,
    /// The uncertain inputs --uncertainty carries to the slices (empty without it).
    pub perturbations: Vec<Perturbation>,
}

impl Plan {
    /// The beam's relative irradiance along the slice's middle row
    /// (`beam_relative` of profile.csv) for `run`, pixel size `pixel_mm`.
    pub fn beam_profile(&self, run: &PlannedRun, pixel_mm: f64) -> Vec<f64> {
        let n = self.out_pixels;
        let grid_x: Vec<f64> = (0..n).map(|c| (c as f64 + 0.5 - 0.5 * n as f64) * pixel_mm).collect();
        bssrdf::beam_profile(&self.beam, &run.dirs, &grid_x)
    }

    /// The medium's μs, μa [1/m], g and n as used.
    pub fn optical_properties(&self) -> &OpticalUsed {
        &self.medium.used
    }

    /// The phase function as described in summary.json.
    pub fn phase_name(&self) -> &str {
        &self.medium.phase_name
    }
}

/// The [`Plan`] of `lucent bssrdf` for the arguments `a`.
pub fn plan(a: &RunArgs) -> Result<Plan> {
    plan_with_recipe(a, load_recipe(a)?.as_ref())
}

/// The [`Plan`] of `lucent bssrdf` for the arguments `a` with `recipe` as
/// the medium's recipe in place of `--recipe` (a recipe not read from a
/// file, e.g. the Python API's dict); `None`: the explicit coefficients.
pub fn plan_with_recipe(a: &RunArgs, recipe: Option<&Recipe>) -> Result<Plan> {
    let m = medium_of(a, recipe)?;
    let (beam, beam_name) = a.beam.beam()?;
    let out_pixels = match a.crop {
        Some(c) if c == 0 || c > a.pixels => bail!("--crop {c}: must lie in 1 … --pixels ({})", a.pixels),
        Some(c) => c,
        None => a.pixels,
    };
    // Said with the flags (the simulator's own message names its pixel_m).
    // Large and small values as written (1e300, not 300 digits).
    let num = |x: f64| if x != 0.0 && !(1e-4..1e6).contains(&x.abs()) { format!("{x:e}") } else { format!("{x}") };
    if !(a.pixel_mm.is_finite() && a.pixel_mm > 0.0) {
        bail!("--pixel-mm {}: must be a positive number of millimetres", a.pixel_mm);
    }
    if a.pixel_mm * out_pixels as f64 > 1000.0 {
        bail!(
            "--pixel-mm {}: the slice ({out_pixels} pixels × {} mm = {} mm) must be at most 1000 mm (1 m) wide",
            num(a.pixel_mm),
            num(a.pixel_mm),
            num(a.pixel_mm * out_pixels as f64)
        );
    }
    // Only the crop is simulated: the pixels outside it would be discarded.
    let sensor = Sensor::new(out_pixels, a.pixel_mm * 1e-3)?;
    let stop = a.stop();
    // A stop rule and a beam that cannot give a slice are refused before any work.
    if let Some(n) = a.paths
        && let Some(reason) = crate::bssrdf::paths_problem(n)
    {
        bail!("--paths {n}: {reason}");
    }
    let field_mm = out_pixels as f64 * a.pixel_mm;
    if a.beam.beam_map.is_none() && a.beam.beam_fwhm_um * 1e-3 > field_mm {
        bail!("--beam-fwhm-um {}: the beam is wider than the slice ({out_pixels} pixels × {} mm = {} mm); widen the slice (--pixels, --pixel-mm) or narrow the beam", a.beam.beam_fwhm_um, num(a.pixel_mm), num(field_mm));
    }
    if let (Beam::Map(map), Some(path)) = (&beam, &a.beam.beam_map) {
        // The same rule for a map, by its second moments (a map may have a wide dark border).
        let fwhm_mm = beam_map_fwhm_m(map) * 1e3;
        if fwhm_mm > field_mm {
            bail!("--beam-map {}: the beam is wider than the slice (Gaussian-equivalent FWHM {fwhm_mm:.3} mm from its second moments; the slice is {out_pixels} pixels × {} mm = {} mm); widen the slice (--pixels, --pixel-mm) or check --beam-map-pixel-mm", path.display(), num(a.pixel_mm), num(field_mm));
        }
    }
    // Without a stop rule: 1 % on the slice sum, but at most 10 minutes per
    // configuration (strongly forward-peaked media converge slowly).
    let stop = if stop.is_empty() { Stop { rel_error: Some(0.01), time_s: Some(600.0), ..stop } } else { stop };
    let (top, roughness) = bssrdf::roughness(a.roughness.as_deref(), m.surface.as_ref())?;
    let perturbations = perturbations(a, recipe, &top)?;
    let slab = Slab::new(m.thickness_m, m.medium.clone())?.with_top(top);
    let configs = match &a.configs {
        Some(list) => list.pairs().into_iter().map(|(ti, to)| (ti, a.phi_i, to, a.phi_o)).collect(),
        None => vec![(a.theta_i, a.phi_i, a.theta_o, a.phi_o)],
    };
    let runs = configs
        .into_iter()
        .map(|(ti, pi, to, po)| {
            let dirs = Directions::from_degrees(ti, pi, to, po)
                .with_context(|| format!("configuration θi {ti}° → θo {to}°"))?;
            let setup = Setup::new(slab.clone(), beam.clone(), sensor, dirs);
            let options = run_options(a, &setup, stop);
            let pairs = perturbations
                .iter()
                .map(|p| {
                    (
                        Setup::new(p.plus.clone(), beam.clone(), sensor, dirs),
                        Setup::new(p.minus.clone(), beam.clone(), sensor, dirs),
                    )
                })
                .collect();
            Ok(PlannedRun { angles: (ti, pi, to, po), dirs, setup, options, pairs })
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(Plan { medium: m, beam, beam_name, out_pixels, stop, roughness, runs, perturbations })
}

/// Runs `lucent bssrdf`, or with `merged_from` writes the outputs of the
/// run whose shards these are (`lucent merge`).
pub fn simulate_from(a: RunArgs, merged_from: Option<&[crate::shard::Shard]>) -> Result<()> {
    let plan = plan(&a)?;
    let Plan { out_pixels, stop, .. } = &plan;
    let configs = &plan.runs;
    let shard = a.shard.as_deref().map(crate::shard::parse_spec).transpose()?;
    let batch_paths = RunOptions::default().batch_paths;
    let total_batches = a.stop().samples.unwrap_or(0).div_ceil(batch_paths);
    check_stop_for_split(&a, shard, merged_from.is_some(), total_batches)?;
    // A merge reads and checks every shard before it writes anything.
    let merged_tallies = match merged_from {
        Some(shards) => Some(read_merged_tallies(shards, configs.len(), *out_pixels, total_batches)?),
        None => None,
    };
    if let Some((k, n)) = shard {
        return run_shard(&a, configs, (k, n), total_batches);
    }
    // Written into a staging folder, moved into --out when every configuration is done.
    // A second Ctrl-C ends the process at once: the staging folder goes with
    // it (registered before it exists), and so does --out if this run
    // created it (it is still empty then).
    let _remove_on_abort = super::interrupt::remove_staged_on_abort(&a.out);
    let stage = crate::io::StagedDir::new(&a.out)?;
    let mut table =
        String::from("folder,theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,sum_per_m2_sr,sum_std_error,paths,wall_s\n");
    let interrupt = Interrupt::install();
    let mut interrupted_at = None;
    if !a.quiet {
        eprintln!(
            "simulating {} configuration(s); Ctrl-C stops after the round under way and keeps the slice so far",
            configs.len()
        );
    }
    for (i, run) in configs.iter().enumerate() {
        let (ti, pi, to, po) = run.angles;
        let (setup, options) = (&run.setup, &run.options);
        let sub = bssrdf::SliceFiles::run_subdir(configs.len(), ti, to);
        let (dir, shown) = (stage.path().join(&sub), a.out.join(&sub));
        let bar = progress_bar(a.quiet, stop);
        let label = format!("θi {ti}° → θo {to}°");
        bar.set_prefix(label.clone());
        let mut estimated = false;
        let mut band = None;
        let slice = if let Some(tallies) = &merged_tallies {
            // The shards' tallies added in shard order to an empty run's (its constants).
            let mut sums = slab::simulate_batches(setup, options, 0..0, a.paths.unwrap_or(0), interrupt.flag())?;
            for shard in tallies {
                let t = slice_sums_of(&sums, &shard[i]);
                sums.add(&t);
            }
            sums.slice()
        } else {
            let on_progress = |p: &slab::Progress| {
                bar.set_position(bar_position(stop, p));
                // Once the first round tells, the time this configuration expects.
                if !estimated {
                    estimated = true;
                    if let Some(line) = expectation(stop, p)
                        && !a.quiet
                    {
                        let all = if i == 0 && configs.len() > 1 {
                            format!(
                                "; ≈ {} for all {} configurations",
                                super::common::duration(line.0 * configs.len() as f64),
                                configs.len()
                            )
                        } else {
                            String::new()
                        };
                        // Printed whether or not the bar is drawn (a log file gets it too).
                        bar.suspend(|| eprintln!("{label}: {}{all}", line.1));
                    }
                }
                bar.set_message(progress_message(stop, p));
            };
            if a.uncertainty {
                let (slice, differences) =
                    slab::simulate_coupled(setup, &run.pairs, options, on_progress, interrupt.flag())?;
                band = Some(differences);
                slice
            } else {
                slab::simulate_cancellable(setup, options, on_progress, interrupt.flag())?
            }
        };
        bar.finish_and_clear();
        let interrupted = interrupt.requested();
        if let Some(target) = stop.rel_error {
            let reached = slice.sum_std_error / slice.sum;
            if reached > target {
                eprintln!(
                    "warning: θi {ti}° → θo {to}°: stopped at {:.2} % relative error, before the target {:.2} % (time or path budget)",
                    100.0 * reached,
                    100.0 * target
                );
            }
        }
        let summary = slice_summary(&a, &plan, run, &slice, interrupted);
        let beam_row = plan.beam_profile(run, a.pixel_mm);
        bssrdf::write_run(&dir, &slice, &summary, &beam_row)?;
        if let Some(differences) = &band {
            println!("θi {ti}° → θo {to}°: {}", write_slice_band(&plan, &dir, &slice, differences, &beam_row)?);
        }
        println!(
            "θi {ti}° φi {pi}° → θo {to}° φo {po}°: sum = {:.5e} ± {:.2e} 1/(m² sr) ({:.2} %), per pixel {:.1} % median, {:.1} % p90, {} paths, {:.1} M events/s, {:.1} s → {}",
            slice.sum,
            slice.sum_std_error,
            100.0 * summary.relative_std_error,
            100.0 * summary.pixel_rel_error_median,
            100.0 * summary.pixel_rel_error_p90,
            slice.paths,
            summary.events_per_s / 1e6,
            slice.wall_s,
            shown.display()
        );
        table.push_str(&format!(
            "{},{ti},{pi},{to},{po},{:.8e},{:.3e},{},{:.3}\n",
            shown.display(),
            slice.sum,
            slice.sum_std_error,
            slice.paths,
            slice.wall_s
        ));
        if interrupted {
            interrupted_at = Some(shown);
            break;
        }
    }
    drop(interrupt);
    if configs.len() > 1 {
        let sweep = bssrdf::SliceFiles::SWEEP_CSV;
        crate::io::write_atomic(&stage.path().join(sweep), table.as_bytes())?;
        println!("combined table: {}", a.out.join(sweep).display());
    }
    let owned: Vec<&str> = bssrdf::SliceFiles::NAMES
        .into_iter()
        .chain([bssrdf::SliceFiles::SWEEP_CSV])
        .chain(bssrdf::SliceBandFiles::NAMES)
        .collect();
    stage.commit(|n| owned.contains(&n) || bssrdf::SliceFiles::is_run_subdir(n))?;
    if let Some(at) = interrupted_at {
        return Err(Interrupted(format!(
            "{} holds the slice from the paths finished before Ctrl-C (summary.json says \"interrupted\": true); the configurations after it were not run",
            at.display()
        ))
        .into());
    }
    Ok(())
}

/// Checks the stop rules against the run's mode: `--uncertainty` (not
/// sharded, a path count or time budget), a `shard` (k, n) or a merge
/// (`merged`: a path budget alone, at most `total_batches` shards).
fn check_stop_for_split(a: &RunArgs, shard: Option<(u32, u32)>, merged: bool, total_batches: u64) -> Result<()> {
    let stop = a.stop();
    if a.uncertainty {
        if shard.is_some() || merged {
            bail!("--uncertainty: the coupled runs of the uncertain inputs are not sharded; run without --shard");
        }
        if !stop.has(Condition::Samples) && !stop.has(Condition::Time) {
            bail!("--uncertainty: give --paths or --time-s (the runs at ±1 σ stop with the nominal one, on a path count or a time budget)");
        }
        if stop.has_error_target() {
            bail!("--uncertainty: --rel-error and --pixel-rel-error do not apply; give --paths or --time-s");
        }
    }
    if shard.is_some() || merged {
        if stop.shard_samples().is_err() {
            bail!("--shard: needs a path budget (--paths) and no other stop rule (--time-s, --rel-error and --pixel-rel-error depend on the whole run and cannot be split exactly)");
        }
        if let Some((k, n)) = shard
            && u64::from(n) > total_batches
        {
            return Err(crate::shard::ShardError::TooManyShards {
                k,
                n,
                units: total_batches,
                what: "batches of paths",
            }
            .into());
        }
    }
    Ok(())
}

/// The tallies of every shard (in shard order), one per configuration (of
/// `configs`, slices of `out_pixels` per side), each shard checked to hold
/// its range of the `total_batches`.
fn read_merged_tallies(
    shards: &[crate::shard::Shard],
    configs: usize,
    out_pixels: usize,
    total_batches: u64,
) -> Result<Vec<Vec<crate::shard::Arrays>>> {
    shards
        .iter()
        .map(|s| {
            let k = s.file.shard;
            let expected = crate::shard::range(total_batches, k, s.file.identity.shards);
            if s.file.range != [expected.start, expected.end] {
                bail!(
                    "{}: shard {k} holds batches {:?}, the run's shard {k} is {expected:?}",
                    s.dir.display(),
                    s.file.range
                );
            }
            (0..configs)
                .map(|i| read_slice_shard(&s.dir.join(shard_acc(i)), out_pixels * out_pixels))
                .collect::<Result<Vec<_>>>()
        })
        .collect::<Result<Vec<_>>>()
}

/// Shard k of n (`--shard K/N`): its range of the `total_batches` of every
/// configuration, tallied into --out with shard.json.
fn run_shard(a: &RunArgs, configs: &[PlannedRun], (k, n): (u32, u32), total_batches: u64) -> Result<()> {
    let range = crate::shard::range(total_batches, k, n);
    let identity = super::shard::identity(a.seed, format!("{} paths", a.paths.unwrap_or(0)), n)?;
    super::shard::check_shard_out(&a.out, &identity, k)?;
    // A second Ctrl-C or SIGTERM ends the process: the staging folder goes with it.
    let _remove_on_abort = super::interrupt::remove_on_abort(&crate::io::StagedDir::staging_path(&a.out));
    let stage = crate::io::StagedDir::new(&a.out)?;
    let interrupt = Interrupt::install();
    let mut wall_s = 0.0;
    let mut accumulators = Vec::new();
    for (i, run) in configs.iter().enumerate() {
        let t =
            slab::simulate_batches(&run.setup, &run.options, range.clone(), a.paths.unwrap_or(0), interrupt.flag())?;
        if interrupt.requested() {
            return Err(
                Interrupted(format!("shard {k}/{n} not written (a shard is merged whole or not at all)")).into()
            );
        }
        wall_s += t.wall_s;
        let meta = crate::shard::AccMeta::new(&identity, k, &range, &Default::default());
        write_slice_shard(&stage.path().join(shard_acc(i)), &meta, &t)?;
        accumulators.push(shard_acc(i));
    }
    drop(interrupt);
    let file = crate::shard::ShardFile {
        identity,
        shard: k,
        range: [range.start, range.end],
        accumulators,
        counters: Default::default(),
        wall_s,
    };
    crate::io::write_json(&stage.path().join(crate::shard::SHARD_JSON), &file)?;
    // Another shard may have finished into the same folder meanwhile.
    super::shard::check_shard_out(&a.out, &file.identity, k)?;
    stage.commit(|n| n == crate::shard::SHARD_JSON || (n.starts_with("slice-") && n.ends_with(".acc")))?;
    println!(
        "shard {k}/{n}: path batches {}..{} of {total_batches} in {wall_s:.1} s → {}",
        range.start,
        range.end,
        a.out.display()
    );
    Ok(())
}

/// The progress bar's message during a run with stop rule `stop`.
fn progress_message(stop: &Stop, p: &slab::Progress) -> String {
    format!(
        "{}{:.2} M events/s, rel. error {:.2} % (sum), per pixel {:.1} % median, {:.1} % p90",
        if stop.samples.is_none() && stop.time_s.is_some() { format!("{} paths, ", p.paths) } else { String::new() },
        p.events as f64 / p.elapsed_s.max(1e-9) / 1e6,
        100.0 * p.rel_error,
        100.0 * p.pixels.median,
        100.0 * p.pixels.p90
    )
}

/// summary.json of one configuration's `slice` (of `run` in `plan`).
fn slice_summary(a: &RunArgs, plan: &Plan, run: &PlannedRun, slice: &slab::Slice, interrupted: bool) -> Summary {
    let m = &plan.medium;
    let (ti, pi, to, po) = run.angles;
    let pixel_errors = slice.pixel_errors();
    Summary {
        config: RunConfig {
            recipe: a.recipe.as_ref().map(|p| p.display().to_string()),
            wavelength_nm: a.recipe.as_ref().map(|_| a.wavelength),
            theta_i_deg: ti,
            phi_i_deg: pi,
            theta_o_deg: to,
            phi_o_deg: po,
            phase: m.phase_name.clone(),
            beam: plan.beam_name.clone(),
            pixels: plan.out_pixels,
            pixel_mm: a.pixel_mm,
            crop_of: a.crop.map(|_| a.pixels),
            seed: a.seed,
            thickness_mm: m.thickness_m * 1e3,
            roughness: plan.roughness.clone(),
        },
        optical_properties: m.used,
        sum: slice.sum,
        sum_std_error: slice.sum_std_error,
        relative_std_error: slice.sum_std_error / slice.sum,
        pixel_rel_error_median: pixel_errors.median,
        pixel_rel_error_p90: pixel_errors.p90,
        pixel_mask_pixels: pixel_errors.pixels,
        paths: slice.paths,
        events: slice.events,
        events_per_s: slice.events_per_s(),
        kernel: slice.kernel.into(),
        estimator: slice.estimator.name().into(),
        folded: slice.folded,
        reciprocal: slice.reciprocal,
        wall_s: slice.wall_s,
        specular_reflectance: slice.specular_reflectance,
        diffuse_reflectance: slice.diffuse_reflectance,
        transmittance: slice.transmittance,
        pixel_mm: a.pixel_mm,
        interrupted,
    }
}

/// The band of a configuration's `slice` from its runs at ±1 σ of the
/// plan's uncertain inputs (`differences`), written into `dir`; its sentence.
fn write_slice_band(
    plan: &Plan,
    dir: &Path,
    slice: &slab::Slice,
    differences: &[slab::SliceDifference],
    beam_row: &[f64],
) -> Result<String> {
    let inputs: Vec<crate::optics::uncertainty::InputSd> = plan
        .perturbations
        .iter()
        .map(|p| crate::optics::uncertainty::InputSd { key: p.key.clone(), nominal: p.nominal, sd: p.sd })
        .collect();
    let u = bssrdf::SliceBand::new(slice, &inputs, differences);
    bssrdf::write_band(dir, slice, &u, beam_row)?;
    Ok(u.sentence())
}

/// The run options of one configuration.
fn run_options(a: &RunArgs, setup: &Setup, stop: Stop) -> RunOptions {
    let estimator = match a.estimator {
        EstimatorChoice::Auto => match Estimator::best_for(setup) {
            Estimator::Lobe { .. } => Estimator::Lobe { vertices: a.lobe_vertices.into() },
            e => e,
        },
        EstimatorChoice::Ring => Estimator::Ring,
        EstimatorChoice::Lobe => Estimator::Lobe { vertices: a.lobe_vertices.into() },
        EstimatorChoice::Connection => Estimator::Connection,
    };
    RunOptions { stop, seed: a.seed, estimator, fold: !a.no_fold, ..RunOptions::default() }
}

/// The bar of one configuration: the paths of a path budget (with the time
/// left), else the fraction of a time budget, else a spinner counting paths
/// (an error target alone: its time shows in the "expect ≈" line).
fn progress_bar(quiet: bool, stop: &Stop) -> ProgressBar {
    if quiet {
        return ProgressBar::hidden();
    }
    let (bar, template) = match (stop.samples, stop.time_s) {
        (Some(n), _) => (ProgressBar::new(n), "{prefix} {bar:40} {pos}/{len} paths  {msg}  ETA {eta}"),
        (None, Some(_)) => {
            (ProgressBar::new(1000), "{prefix} {bar:40} {percent} % of the time budget  {msg}  ETA {eta}")
        }
        (None, None) => (ProgressBar::new_spinner(), "{prefix} {spinner} [{elapsed_precise}] {pos} paths  {msg}"),
    };
    bar.set_style(ProgressStyle::with_template(template).unwrap_or_else(|_| ProgressStyle::default_bar()));
    bar
}

/// Where [`progress_bar`]'s bar stands after a round: paths done, or
/// thousandths of the time budget.
fn bar_position(stop: &Stop, p: &slab::Progress) -> u64 {
    match (stop.samples, stop.time_s) {
        (Some(n), _) => p.paths.min(n),
        (None, Some(t)) => (1000.0 * (p.elapsed_s / t).clamp(0.0, 1.0)) as u64,
        (None, None) => p.paths,
    }
}

/// After a configuration's first round: roughly how long it takes in all
/// (seconds) and the line that says so. The first stop rule expected to end
/// it decides: a path budget at the rate so far, an error target by
/// error² ∝ 1/time, a time budget as given. `None` when the round already
/// ended it (or nothing can tell).
fn expectation(stop: &Stop, p: &slab::Progress) -> Option<(f64, String)> {
    let elapsed = p.elapsed_s;
    if p.paths == 0 || elapsed.is_nan() || elapsed <= 0.0 {
        return None;
    }
    let standing = Standing { samples: Some(p.paths), elapsed_s: elapsed, ..Standing::default() };
    if stop.met(&standing).is_some() {
        return None;
    }
    let target = |name: &str, now: f64, e: f64| -> Option<(f64, String)> {
        (now.is_finite() && now > e).then(|| {
            (
                elapsed * (now / e).powi(2),
                format!(
                    "to {:.2} % {name} ({:.2} % after {} paths in {:.2} s)",
                    100.0 * e,
                    100.0 * now,
                    p.paths,
                    elapsed
                ),
            )
        })
    };
    let mut rules: Vec<(f64, String)> = Vec::new();
    if let Some(n) = stop.samples {
        rules.push((
            elapsed * n as f64 / p.paths as f64,
            format!("for {n} paths ({} done in {:.2} s)", p.paths, elapsed),
        ));
    }
    // A target reached already ends the run within a round or two.
    if let Some(e) = stop.rel_error {
        if p.rel_error <= e {
            return None;
        }
        rules.extend(target("on the slice sum", p.rel_error, e));
    }
    if let Some(e) = stop.pixel_rel_error {
        if p.pixels.median <= e {
            return None;
        }
        rules.extend(target("per pixel (median)", p.pixels.median, e));
    }
    let first = rules.iter().min_by(|a, b| a.0.total_cmp(&b.0)).cloned();
    let line = |t: f64, what: &str| format!("expect ≈ {} {what}", super::common::duration(t));
    match (first, stop.time_s) {
        (Some((t, what)), Some(budget)) if t > budget => Some((
            budget,
            format!(
                "expect ≈ {} (the time budget; {} would take ≈ {})",
                super::common::duration(budget),
                what,
                super::common::duration(t)
            ),
        )),
        (Some((t, what)), _) => Some((t, line(t, &what))),
        (None, Some(budget)) => {
            Some((budget, format!("expect ≈ {} (the time budget)", super::common::duration(budget))))
        }
        (None, None) => None,
    }
}

fn simulated_path(p: &Path) -> PathBuf {
    if p.is_dir() {
        bssrdf::SliceFiles::in_dir(p).exr
    } else {
        p.to_path_buf()
    }
}

fn compare(a: CompareArgs) -> Result<()> {
    let measured = bssrdf::read_grid(&a.measured, a.measured_pixel_mm)?;
    // A negative pixel is the measured file's fault, said before the simulated slice is read.
    bssrdf::check_measured(&a.measured, &measured, None, None)?;
    let sim_path = simulated_path(&a.simulated);
    let simulated = bssrdf::read_grid(&sim_path, None)?;
    // The measured slice must be of the simulated one's wavelength and
    // configuration (as the simulation's summary.json says), and not negative.
    let sim = bssrdf::sidecar_of(&sim_path)?;
    let sim_angles = sim.as_ref().and_then(|s| match (s.theta_i_deg, s.phi_i_deg, s.theta_o_deg, s.phi_o_deg) {
        (Some(ti), Some(pi), Some(to), Some(po)) => Some((ti, pi, to, po)),
        _ => None,
    });
    bssrdf::check_measured(&a.measured, &measured, sim.as_ref().and_then(|s| s.wavelength_nm), sim_angles)?;
    let (c, rel) = bssrdf::compare(&measured, &simulated, a.threshold)
        .map_err(|e| anyhow!("{} vs {}: {e}", a.measured.display(), sim_path.display()))?;
    // Written into a staging folder and moved into --out only when all three
    // files are made; Ctrl-C or SIGTERM removes the staging folder and ends.
    let _interrupt = Interrupt::abort_on_first();
    let _remove_on_abort = super::interrupt::remove_on_abort(&crate::io::StagedDir::staging_path(&a.out));
    let stage = crate::io::StagedDir::new(&a.out)?;
    let files = bssrdf::ComparisonFiles::in_dir(stage.path());
    crate::io::write_json(&files.json, &c)?;
    let x = measured.x_mm();
    let png = bssrdf::profile_png(
        &x,
        &[("measured", measured.middle_row(), None), ("simulated", simulated.middle_row(), None)],
        None,
    )?;
    crate::io::write_atomic(&files.profiles, &png)?;
    let panel = bssrdf::heatmap_png(
        &[("measured", &measured), ("simulated", &simulated)],
        Some(("relative difference (masked)", &rel)),
    )?;
    crate::io::write_atomic(&files.panel, &panel)?;
    stage.commit(|n| bssrdf::ComparisonFiles::NAMES.contains(&n))?;
    println!("{}", serde_json::to_string_pretty(&c)?);
    println!("written: {}/{{{}}}", a.out.display(), bssrdf::ComparisonFiles::NAMES.join(", "));
    Ok(())
}

/// `lucent bench bssrdf`: the simulator's speed on a PDMS-like medium
/// (events/s on one core, wall time to `rel_error` on the slice sum), and
/// the per-pixel figure of the issue side by side for the previous
/// estimator (fixed-direction connection, not folded at 45°/0°) and the
/// current one (ring connection at 45°/0°, lobe connection at 45°/15°,
/// folded): IOL1068-09 and IOL1068-13 from their recipes (tabulated
/// Lorenz–Mie phase, 550 nm), 45°/0° and 45°/15°, the central 117 of 259
/// pixels of 0.1029 mm, `time_s` each.
pub fn bench(rel_error: f64, time_s: f64) -> Result<()> {
    use lucent_render::slab::{simulate, Slice};
    if !(time_s.is_finite() && time_s > 0.0) {
        bail!("--time-s {time_s}: must be a positive number of seconds");
    }
    let pdms_like = Medium::new(1.47e4, 9.6, Phase::henyey_greenstein(0.974)?, 1.589)?;
    let setup = Setup::new(
        Slab::new(6.35e-3, pdms_like)?,
        Beam::gaussian(200e-6)?,
        Sensor::new(259, 0.1029e-3)?,
        Directions::from_degrees(45.0, 0.0, 0.0, 180.0)?,
    );
    // One core: the best of five runs of 20 000 paths (the machine's speed
    // drifts by tens of percent from one second to the next).
    let one_core = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut single: Option<Slice> = None;
    for seed in 7..12 {
        let run = one_core.install(|| {
            simulate(&setup, &RunOptions { stop: Stop::samples(20_000), seed, ..RunOptions::default() }, |_| {})
        })?;
        if single.as_ref().is_none_or(|s| run.events_per_s() > s.events_per_s()) {
            single = Some(run);
        }
    }
    let single = single.expect("five runs were made");
    let all = simulate(
        &setup,
        &RunOptions { stop: Stop { rel_error: Some(rel_error), ..Stop::default() }, seed: 8, ..RunOptions::default() },
        |_| {},
    )?;
    let mut per_pixel = Vec::new();
    // (sample, θi, θo, whether the previous estimator was folded: at 45°/15°
    // the demo already folded the fixed-direction connection).
    for (sample, theta_i, theta_o, previous_fold) in [
        ("IOL1068-09", 45.0, 0.0, false),
        ("IOL1068-13", 45.0, 0.0, false),
        ("IOL1068-09", 45.0, 15.0, true),
        ("IOL1068-13", 45.0, 15.0, true),
    ] {
        let recipe = PathBuf::from(format!("fixtures/samples/{sample}.toml"));
        let args = RunArgs {
            recipe: Some(recipe.clone()),
            theta_i,
            theta_o,
            crop: Some(117),
            time_s: Some(time_s),
            out: PathBuf::new(),
            quiet: true,
            ..RunArgs::defaults()
        };
        let m =
            medium(&args).with_context(|| format!("{} (run the bench from the repository root)", recipe.display()))?;
        let setup = Setup::new(
            Slab::new(m.thickness_m, m.medium.clone())?,
            Beam::gaussian(200e-6)?,
            Sensor::new(117, 0.1029e-3)?,
            Directions::from_degrees(theta_i, 0.0, theta_o, 180.0)?,
        );
        let mut row = serde_json::Map::new();
        row.insert("sample".into(), sample.into());
        row.insert("theta_i_deg".into(), theta_i.into());
        row.insert("theta_o_deg".into(), theta_o.into());
        row.insert("g".into(), m.used.g.into());
        for (name, estimator, fold) in
            [("previous", Estimator::Connection, previous_fold), ("current", Estimator::best_for(&setup), true)]
        {
            let options = RunOptions {
                stop: Stop { time_s: Some(time_s), ..Stop::default() },
                seed: 1,
                estimator,
                fold,
                ..RunOptions::default()
            };
            let s = simulate(&setup, &options, |_| {})?;
            let e = s.pixel_errors();
            row.insert(
                name.into(),
                serde_json::json!({
                    "estimator": s.estimator.name(),
                    "folded": s.folded,
                    "paths": s.paths,
                    "wall_s": s.wall_s,
                    "sum_per_m2_sr": s.sum,
                    "sum_rel_error": s.sum_std_error / s.sum,
                    "pixel_rel_error_median": e.median,
                    "pixel_rel_error_p90": e.p90,
                    "mask_pixels": e.pixels,
                    // median² × time: the time to a given median error, up to a constant
                    "median_sq_times_wall_s": e.median * e.median * s.wall_s,
                }),
            );
        }
        per_pixel.push(serde_json::Value::Object(row));
    }
    let json = serde_json::json!({
        "benchmark": "slab BSSRDF: speed (PDMS-like HG medium, 259 × 259, fixed-direction connection) and per-pixel convergence (recipes, 45°/0° and 45°/15°, 117 of 259 px)",
        "kernel": single.kernel,
        "events_per_s_one_core": single.events_per_s(),
        "one_core_statistic": "best of 5 runs of 20 000 paths",
        "events_per_path": single.events as f64 / single.paths as f64,
        "threads": rayon::current_num_threads(),
        "target_rel_error": rel_error,
        "reached_rel_error": all.sum_std_error / all.sum,
        "paths": all.paths,
        "events_per_s_all_cores": all.events_per_s(),
        "events_per_s_per_core_all_cores": all.events_per_s() / rayon::current_num_threads() as f64,
        "wall_s_to_target": all.wall_s,
        "sum_per_m2_sr": all.sum,
        "per_pixel_time_s": time_s,
        "per_pixel_mask": "pixels above 1 % of the slice's maximum",
        "per_pixel": per_pixel,
    });
    println!("{}", serde_json::to_string_pretty(&json)?);
    Ok(())
}

/// `lucent bench surface`: what a rough top costs. (1) The slab simulator
/// on the PDMS-like medium of `bench bssrdf` (45°/0°, 259 × 259 pixels,
/// fixed-direction connection), smooth top against Trowbridge–Reitz α
/// 0.0084 (IOL1068-08), Beckmann α 0.0087, TR α 0.3 and the measured normal
/// set of the shipped height map (`fixtures/surface/tr_0p0084.x3p`): events/s
/// on one core (best of three runs of `paths` paths), the kernel, the
/// slice sum. (2) The rough dielectric BSDF alone: samples and evaluations
/// per second on one core, from air at 45° and from inside at 20°.
pub fn bench_surface(paths: u64) -> Result<()> {
    use glam::DVec3;
    use lucent_render::interface::{Interface, Lobe, Transport};
    use lucent_render::microfacet::{Distribution, MeasuredNormals, Microsurface};
    use lucent_render::slab::{simulate, Slice};
    use std::sync::Arc;
    if let Some(reason) = crate::bssrdf::paths_problem(paths) {
        bail!("--paths {paths}: {reason}");
    }
    let x3p = Path::new("fixtures/surface/tr_0p0084.x3p");
    let map = crate::surface::read_height_map(x3p, &Default::default())
        .with_context(|| "run the bench from the repository root")?;
    let fit = crate::surface::fit_surface(&map, &Default::default())?;
    let start = std::time::Instant::now();
    let measured = Arc::new(MeasuredNormals::new(&fit.normals.normals(), None)?);
    let measured_build_s = start.elapsed().as_secs_f64();
    let surfaces: Vec<(&str, Option<Microsurface>)> = vec![
        ("smooth", None),
        ("TR 0.0084", Some(Microsurface::Analytic(Distribution::TrowbridgeReitz { alpha: 0.0084 }))),
        ("Beckmann 0.0087", Some(Microsurface::Analytic(Distribution::Beckmann { alpha: 0.0087 }))),
        ("TR 0.3", Some(Microsurface::Analytic(Distribution::TrowbridgeReitz { alpha: 0.3 }))),
        ("measured (shipped X3P)", Some(Microsurface::Measured(measured.clone()))),
    ];
    let medium = Medium::new(1.47e4, 9.6, Phase::henyey_greenstein(0.974)?, 1.589)?;
    let one_core = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut slab_rows = Vec::new();
    for (name, surface) in &surfaces {
        let top = match surface {
            Some(s) => Interface::new(s.clone())?,
            None => Interface::Smooth,
        };
        let setup = Setup::new(
            Slab::new(6.35e-3, medium.clone())?.with_top(top),
            Beam::gaussian(200e-6)?,
            Sensor::new(259, 0.1029e-3)?,
            Directions::from_degrees(45.0, 0.0, 0.0, 180.0)?,
        );
        let mut best: Option<Slice> = None;
        for seed in 1..4 {
            let options = RunOptions { stop: Stop::samples(paths), seed, ..RunOptions::default() };
            let run = one_core.install(|| simulate(&setup, &options, |_| {}))?;
            if best.as_ref().is_none_or(|b| run.events_per_s() > b.events_per_s()) {
                best = Some(run);
            }
        }
        let s = best.expect("three runs were made");
        slab_rows.push(serde_json::json!({
            "top": name,
            "kernel": s.kernel,
            "events_per_s_one_core": s.events_per_s(),
            "events_per_path": s.events as f64 / s.paths as f64,
            "sum_per_m2_sr": s.sum,
            "sum_std_error": s.sum_std_error,
            "specular_reflectance": s.specular_reflectance,
        }));
    }
    let smooth_rate = slab_rows[0]["events_per_s_one_core"].as_f64().unwrap_or(f64::NAN);
    for row in &mut slab_rows {
        let r = row["events_per_s_one_core"].as_f64().unwrap_or(f64::NAN) / smooth_rate;
        row["speed_vs_smooth"] = r.into();
    }
    // The BSDF alone: 2·10⁵ calls per case, directions drawn beforehand.
    let calls = 200_000usize;
    let mut bsdf_rows = Vec::new();
    for (name, surface) in surfaces.iter().skip(1) {
        let Some(surface) = surface else { continue };
        let bsdf = Interface::new(surface.clone())?;
        let eta = 1.589;
        for (side, wo) in [
            ("from air, 45°", DVec3::new(0.5f64.sqrt(), 0.0, 0.5f64.sqrt())),
            ("from inside, 20°", DVec3::new(20f64.to_radians().sin(), 0.0, -20f64.to_radians().cos())),
        ] {
            let mut rng = lucent_render::rng::Rng::new(5, 0);
            let u: Vec<[f64; 3]> = (0..calls).map(|_| [rng.next_f64(), rng.next_f64(), rng.next_f64()]).collect();
            let t = std::time::Instant::now();
            let samples: Vec<DVec3> = u
                .iter()
                .filter_map(|u| bsdf.sample(wo, eta, Lobe::Fresnel, *u, Transport::Importance))
                .map(|s| s.wi)
                .collect();
            let sample_s = t.elapsed().as_secs_f64();
            let t = std::time::Instant::now();
            let total: f64 = samples.iter().map(|wi| bsdf.eval(wo, *wi, eta, Transport::Importance)).sum();
            let eval_s = t.elapsed().as_secs_f64();
            bsdf_rows.push(serde_json::json!({
                "surface": name,
                "wo": side,
                "samples_per_s": calls as f64 / sample_s,
                "evals_per_s": samples.len() as f64 / eval_s,
                "kept_fraction": samples.len() as f64 / calls as f64,
                "checksum": total,
            }));
        }
    }
    let json = serde_json::json!({
        "benchmark": "rough top: slab simulator events/s (PDMS-like HG medium, 6.35 mm, 45°/0°, 259 × 259, fixed-direction connection) and rough dielectric BSDF throughput",
        "paths_per_run": paths,
        "one_core_statistic": "best of 3 runs",
        "measured_normals": measured.len(),
        "measured_bandwidth_slope": measured.bandwidth(),
        "measured_build_s": measured_build_s,
        "slab": slab_rows,
        "bsdf_one_core": bsdf_rows,
    });
    println!("{}", serde_json::to_string_pretty(&json)?);
    Ok(())
}

impl RunArgs {
    /// The stop rule the flags give (--paths, --time-s, --rel-error,
    /// --pixel-rel-error), without the default a run adds when none is
    /// given.
    pub fn stop(&self) -> Stop {
        Stop {
            samples: self.paths,
            time_s: self.time_s,
            rel_error: self.rel_error,
            pixel_rel_error: self.pixel_rel_error,
        }
    }

    /// The arguments of a `bssrdf` run as clap gives them when no flag is set.
    pub(super) fn defaults() -> Self {
        RunArgs {
            recipe: None,
            weight_percent: None,
            wavelength: 550.0,
            mu_s: None,
            mu_a: None,
            g: None,
            n: None,
            thickness_mm: None,
            theta_i: 45.0,
            phi_i: 0.0,
            theta_o: 0.0,
            phi_o: 180.0,
            configs: None,
            phase: None,
            similarity_g: None,
            beam: super::groups::BeamArgs::default(),
            pixels: 259,
            pixel_mm: 0.1029,
            crop: None,
            rel_error: None,
            pixel_rel_error: None,
            paths: None,
            time_s: None,
            seed: 1,
            estimator: EstimatorChoice::Auto,
            lobe_vertices: lucent_render::slab::LOBE_VERTICES as u8,
            roughness: None,
            no_fold: false,
            uncertainty: false,
            out: "lucent-out/bssrdf".into(),
            quiet: false,
            shard: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beam_map_fwhm_is_the_gaussian_fwhm_of_a_gaussian_map() {
        // A Gaussian of σx = 0.2 mm, σy = 0.1 mm on 0.01 mm pixels, off centre:
        // FWHM = 2.3548 σ of the wider axis, 0.471 mm.
        let (n, p) = (201, 1e-5);
        let values: Vec<f64> = (0..n * n)
            .map(|i| {
                let (x, y) = (((i % n) as f64 - 120.0) * p, ((i / n) as f64 - 90.0) * p);
                (-0.5 * (x * x / 4e-8 + y * y / 1e-8)).exp()
            })
            .collect();
        let map = BeamMap::new(n, n, p, values).unwrap();
        let fwhm = beam_map_fwhm_m(&map);
        assert!((fwhm / (2.354_820 * 2e-4) - 1.0).abs() < 0.01, "{fwhm}");
    }
}
