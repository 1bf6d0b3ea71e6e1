//! The command line's definitions: [`Cli`] and its [`Command`]s, the
//! arguments of the commands that have no module of their own (`optics`,
//! `mie`, `bench`), and [`Cli::try_parse_args`], which parses them (a
//! negative number is a value). Each command's own arguments live in its
//! module; [`super::run()`] dispatches the parsed command.

use super::common::count_in;
use super::{bssrdf, camera, colour, compare, fit, job_run, render, report, run, shard, surface, synth};
use clap::{Args, Parser, Subcommand};
use lucent_colour::WavelengthGrid;
use std::path::PathBuf;

/// Every option that takes a value, in `cmd` and its subcommands, also
/// takes a negative number after a space (`--time-s -1`): the command's own
/// check then names the flag and its valid range, where clap would read
/// `-1` as an unknown flag ("unexpected argument '-1'").
fn negative_numbers(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(|a| if a.get_action().takes_values() { a.allow_negative_numbers(true) } else { a })
        .mut_subcommands(negative_numbers)
}

impl Cli {
    /// Parses a command line (program name first), negative numbers
    /// included: every option that takes a value takes one too.
    pub fn try_parse_args<I, T>(args: I) -> Result<Self, clap::Error>
    where
        I: IntoIterator<Item = T>,
        T: Into<std::ffi::OsString> + Clone,
    {
        use clap::{CommandFactory, FromArgMatches};
        let matches = negative_numbers(Self::command()).try_get_matches_from(args)?;
        Self::from_arg_matches(&matches)
    }

    /// [`Cli::try_parse_args`] of the process's arguments; on an error,
    /// clap's message and exit code 2 (help and version exit 0).
    pub fn parse_args() -> Self {
        Self::try_parse_args(std::env::args_os()).unwrap_or_else(|e| e.exit())
    }
}

#[derive(Debug, Parser)]
#[command(name = "lucent", version, about = "Digital twins of translucent objects", after_help = crate::fault::EXIT_CODES)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

// The arguments are parsed once per process: boxing the largest variant would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Spectral optical properties of recipes (Lorenz–Mie): μs, μa, μt, g, n_bulk, phase tables, plots.
    Optics(OpticsArgs),
    /// Lorenz–Mie efficiencies of one sphere, printed as JSON.
    Mie(MieArgs),
    /// BSSRDF slices of a slab (light tracing with explicit connection), and their comparison with measurements.
    Bssrdf(bssrdf::BssrdfArgs),
    /// Render the digital twin (object on the checkerboard under the HDR environment) from a scene file.
    Render(render::RenderArgs),
    /// Surface topography: height map (X3P, CSV, TIFF, EXR) → microfacet normals, fitted Trowbridge–Reitz/Beckmann α.
    #[command(subcommand)]
    Surface(surface::SurfaceCommand),
    /// Benchmarks (see README, performance section).
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Colour: ColorChecker calibration of cameras, applying it to images, RGB bands of spectra.
    #[command(subcommand)]
    Colour(colour::ColourCommand),
    /// RAW photos → linear camera RGB (EXR) with metadata.
    #[command(subcommand)]
    Raw(camera::RawCommand),
    /// Camera calibration from chessboard photos (intrinsics, distortion, poses, RMS, plots).
    Calibrate(camera::CalibrateArgs),
    /// Undistort a photo with a calibrated camera (bilinear resampling).
    Undistort(camera::UndistortArgs),
    /// Board pose in one photo (PnP) and the sample's pose, as a renderer-ready scene JSON.
    Pose(camera::PoseArgs),
    /// Equirectangular HDR environments: check, colour-convert, summarise.
    #[command(subcommand)]
    Env(camera::EnvCommand),
    /// Photo vs render: RMSE, SSIM, triplet.png (photo | render | difference), difference.exr; optional ECC alignment.
    Compare(compare::CompareArgs),
    /// Fit recipe parameters (weight-%, diameter, particle index) to measured BSSRDF slices; fit.json, fitted recipe, plot.
    Fit(fit::FitArgs),
    /// The whole digitisation from one project file: stages in order, unchanged ones skipped, report/index.html.
    Run(run::RunArgs),
    /// The report of a run's folder (report/index.html, metrics.json), as `lucent run`'s last stage writes it.
    Report(report::ReportArgs),
    /// Merge the shards of a render, bssrdf or optics --uncertainty run (each made with --shard K/N) into the run's outputs.
    Merge(shard::MergeArgs),
    /// Jobs of pipeline stages as JSON files: `lucent job run JOB.json` runs one as its command would.
    #[command(subcommand)]
    Job(job_run::JobCommand),
    /// Synthetic inputs with a known truth: a ColorChecker chart, RAW (DNG) captures through a known camera.
    #[command(subcommand)]
    Synth(synth::SynthCommand),
}

#[derive(Debug, Args)]
pub struct OpticsArgs {
    /// Recipe files (TOML) or folders of recipes.
    #[arg(required = true)]
    pub recipes: Vec<PathBuf>,
    /// Wavelength grid START:END:STEP in nm, or one wavelength (e.g. 550).
    #[arg(long, default_value = "380:780:10", conflicts_with = "wavelength")]
    pub wavelengths: WavelengthGrid,
    /// A single wavelength in nm (`--wavelength` is the older spelling).
    #[arg(long = "wavelength-nm", alias = "wavelength", allow_hyphen_values = true)]
    pub wavelength: Option<f64>,
    /// Output folder (default: lucent-out/optics; with --json and no --out, nothing is written).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print the properties as JSON on stdout.
    #[arg(long)]
    pub json: bool,
    /// Entries of the tabulated phase function (uniform in θ; 0 disables; at most 100000).
    #[arg(long, default_value_t = 4096, value_parser = count_in::<0, 100_000>)]
    pub phase_entries: usize,
    /// Weight percentage for particle types whose recipe leaves it unknown.
    #[arg(long)]
    pub weight_percent: Option<f64>,
    /// In a folder, skip recipes that fail validation (reported on stderr) instead of stopping.
    #[arg(long)]
    pub skip_invalid: bool,
    /// Propagate the recipe's uncertain inputs ({ value, sd } or { min, max }) with N Latin-hypercube samples:
    /// mean, sd and 95 % interval of μs, μa, g, n_bulk per wavelength (uncertainty.csv/.json/.png per sample;
    /// 2 … 100000 samples).
    #[arg(long, value_parser = count_in::<2, 100_000>)]
    pub uncertainty: Option<usize>,
    /// Seed of the --uncertainty samples.
    #[arg(long, default_value_t = 1)]
    pub uncertainty_seed: u64,
    /// With --uncertainty: evaluate only the K-th of N disjoint ranges of the
    /// draws (0 ≤ K < N) into --out as a shard (SAMPLE/uncertainty.acc,
    /// shard.json); `lucent merge` writes the run's uncertainty files.
    #[arg(long, value_name = "K/N", requires = "uncertainty")]
    pub shard: Option<crate::job::shard::ShardSpec>,
}

#[derive(Debug, Args)]
pub struct MieArgs {
    /// Size parameter x = 2π r n_host / λ (real host).
    #[arg(long, requires = "relative_index", conflicts_with_all = ["radius_um", "wavelength_nm", "host_index", "particle_index"])]
    pub size_parameter: Option<f64>,
    /// Relative index m = n_particle/n_host as N or N+Ki (K ≥ 0 absorbs); with --size-parameter only.
    #[arg(long, allow_hyphen_values = true, requires = "size_parameter", conflicts_with_all = ["radius_um", "wavelength_nm", "host_index", "particle_index"])]
    pub relative_index: Option<String>,
    /// Sphere radius in µm.
    #[arg(long, requires_all = ["wavelength_nm", "particle_index"])]
    pub radius_um: Option<f64>,
    /// Vacuum wavelength in nm.
    #[arg(long)]
    pub wavelength_nm: Option<f64>,
    /// Host index N or N+Ki (default 1).
    #[arg(long, allow_hyphen_values = true)]
    pub host_index: Option<String>,
    /// Particle index N or N+Ki.
    #[arg(long, allow_hyphen_values = true)]
    pub particle_index: Option<String>,
}

#[derive(Debug, Subcommand)]
pub enum BenchCommand {
    /// Mie efficiencies over the cases of a reference CSV (m_re,m_im,x,… columns).
    Mie {
        #[arg(long, default_value = "fixtures/reference/mie_miepython.csv")]
        cases: PathBuf,
        /// Timed repeats (1 … 1000).
        #[arg(long, default_value_t = 20, value_parser = count_in::<1, 1000>)]
        repeats: usize,
    },
    /// The full optical-property table with phase tables for every recipe in a folder.
    Optics {
        #[arg(long, default_value = "fixtures/samples")]
        samples: PathBuf,
        /// Timed repeats (1 … 1000).
        #[arg(long, default_value_t = 5, value_parser = count_in::<1, 1000>)]
        repeats: usize,
        /// Weight percentage for recipes that leave it unknown (IOL1068-15).
        #[arg(long, default_value_t = 1.0)]
        weight_percent: f64,
    },
    /// The renderer on a Mitsuba reference scene: samples per CPU-second, RMSE against the reference, speed ratio to Mitsuba.
    Render {
        /// The scene: plaque_dense.toml (constant sky) or plaque_envmap.toml
        /// (a sky map with a small sun); its reference is the file of the
        /// same name in --reference.
        #[arg(long, default_value = "fixtures/render/plaque_dense.toml")]
        scene: PathBuf,
        /// Folder of the references (<scene>_mean.exr, <scene>_var.exr) and
        /// of Mitsuba's own timings (mitsuba_bench_<scene>.json).
        #[arg(long, default_value = "fixtures/reference/render")]
        reference: PathBuf,
        /// Sample counts per pixel to run, comma-separated.
        #[arg(long, default_value = "16,64,256,1024")]
        spp: String,
        /// Instead of the Mitsuba comparison: render the scene for this many
        /// seconds with the previous estimator, then with the current one and
        /// each option at the same samples per pixel, one after the other on
        /// all cores, and print the relative standard error per region
        /// (object, board, all) side by side, with the efficiency
        /// 1/(median² × CPU time) on the object and the projected time to 5 %.
        #[arg(long)]
        time_s: Option<f64>,
    },
    /// Sharding overhead: a render as one process against N shard processes
    /// one after the other on this machine plus their merge; and from the
    /// measured times a projection for a large render on many nodes. The
    /// default is the demo camera's 640 × 480 at 32 spp in 4 shards (≈ 25 s
    /// each on 2 loaded cores; a cluster's shards run minutes to hours).
    Shard {
        #[arg(long, default_value = "fixtures/render/demo.toml")]
        scene: PathBuf,
        #[arg(long, default_value = "640x480")]
        size: String,
        #[arg(long, default_value_t = 32)]
        spp: u32,
        #[arg(long, default_value_t = 4)]
        shards: u32,
        /// Rounds of one process against the shards, alternating which runs first (1 … 20).
        #[arg(long, default_value_t = 3)]
        repeats: u32,
        /// The lucent binary to measure (default: this one), e.g. an earlier build to compare with.
        #[arg(long)]
        lucent: Option<PathBuf>,
        /// The projection: megapixels, nodes (each like this machine) and samples per pixel.
        #[arg(long, default_value_t = 12.0)]
        megapixels: f64,
        #[arg(long, default_value_t = 32)]
        nodes: u32,
        #[arg(long, default_value_t = 1024)]
        projected_spp: u32,
    },
    /// A one-parameter weight-% fit of IOL1068-09 over three configurations (synthetic measurements at 0.425 wt-%); wall time.
    Fit {
        /// Target relative error of each slice sum at the final points.
        #[arg(long, default_value_t = 0.01)]
        rel_error: f64,
        /// Also write fit.json, objective.png and the fitted recipe here.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Rough top: slab events/s with a smooth vs rough (TR, Beckmann, measured) top, and rough dielectric BSDF sample/eval throughput.
    Surface {
        /// Light paths per slab run (best of three runs on one core).
        #[arg(long, default_value_t = 20_000)]
        paths: u64,
    },
    /// Photo vs render metrics: SSIM (R, G, B, Y) and the error metrics of a synthetic pair of this size, best of the repeats, wall time.
    Compare {
        /// Image size in megapixels (4:3; 0.001 … 100).
        #[arg(long, default_value_t = 12.0)]
        megapixels: f64,
        /// Timed repeats (1 … 100).
        #[arg(long, default_value_t = 3, value_parser = count_in::<1, 100>)]
        repeats: usize,
    },
    /// The slab simulator: events/s and wall time to 1 % (PDMS-like medium), and the per-pixel error of the previous and current estimators side by side.
    Bssrdf {
        /// Target relative standard error of the slice sum.
        #[arg(long, default_value_t = 0.01)]
        rel_error: f64,
        /// Seconds per run of the per-pixel comparison (previous vs current estimator, IOL1068-09 and -13 at 45°/0°,
        /// IOL1068-09 at 45°/15°).
        #[arg(long, default_value_t = 60.0)]
        time_s: f64,
    },
}
