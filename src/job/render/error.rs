//! Why a render job failed ([`RenderError`]) and why its band was not
//! computed ([`BandError`]).

use crate::job::threads::ThreadsError;
use crate::scene;
use lucent_render::tracer;
use std::error::Error as StdError;
use std::path::PathBuf;
use thiserror::Error;

/// Why a render job failed.
#[derive(Debug, Error)]
pub enum RenderError {
    /// A flag's value is out of range (the message names the flag).
    #[error("{flag} {value}: {reason}")]
    Flag { flag: &'static str, value: f64, reason: String },
    #[error("--spp 0: at least one sample per pixel")]
    ZeroSpp,
    #[error("--exposure must be finite")]
    ExposureNotFinite,
    #[error(transparent)]
    Threads(#[from] ThreadsError),
    #[error(transparent)]
    Scene(#[from] scene::SceneFileError),
    #[error(transparent)]
    Stop(#[from] tracer::StopError),
    #[error("{path}: cannot create output folder")]
    CreateDir { path: PathBuf, source: std::io::Error },
    /// An output file could not be written.
    #[error("{path}: cannot write")]
    Write { path: PathBuf, source: Box<dyn StdError + Send + Sync> },
    #[error(transparent)]
    WriteFile(#[from] crate::io::WriteError),
    #[error(transparent)]
    Image(#[from] crate::imageio::ImageIoError),
    #[error(transparent)]
    Exr(#[from] crate::exr::ExrWriteError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    /// `--shard` with what a shard cannot split.
    #[error("--shard: {0}")]
    NotShardable(&'static str),
    #[error("--uncertainty: the renders at ±1 σ are not sharded; run without --shard")]
    UncertaintyShard,
    #[error(transparent)]
    Shard(#[from] crate::job::shard::format::ShardError),
    #[error("{dir}: shard {k} holds samples {held:?}, the run's shard {k} is {expected:?}")]
    ShardRange { dir: PathBuf, k: u32, held: [u64; 2], expected: std::ops::Range<u64> },
    #[error("{path}: pixel {pixel} has {samples} samples, the shard should have {count}")]
    ShardSamples { path: PathBuf, pixel: usize, samples: f64, count: f64 },
    #[error(
        "--uncertainty-spp {0}: must be a positive even number (the band's error comes from the two halves of the samples)"
    )]
    UncertaintySpp(u32),
    #[error("--uncertainty: {scene} has no [material] recipe to take uncertain inputs from")]
    NoRecipe { scene: PathBuf },
    #[error(
        "--uncertainty: the recipe {recipe} gives no input with an uncertainty (write e.g. weight_percent = {{ value = 0.65, sd = 0.03 }})"
    )]
    NoUncertainInput { recipe: PathBuf },
    #[error("--uncertainty: {key} = {value} (nominal {sign} 1 σ)")]
    AtOneSigma { key: String, value: f64, sign: &'static str, source: Box<RenderError> },
    #[error(
        "--uncertainty: the renders at ±1 σ did not finish within the time budget ({0} s); give a smaller --uncertainty-spp or more time"
    )]
    BandTimeBudget(f64),
    #[error("the band was not written (the render itself is in {}/render.*)", out.display())]
    Band { out: PathBuf, source: BandError },
    #[error("{}: cannot write {name}", out.display())]
    BandFile { out: PathBuf, name: &'static str, source: crate::io::WriteError },
    #[error("{0}")]
    Internal(&'static str),
}

/// Why the band of a render was not computed: a [`RenderError`] (the scene
/// at ±1 σ), or the renders at ±1 σ stopped by Ctrl-C or SIGTERM
/// ([`Interrupted`](crate::fault::Interrupted), kept as itself so that the run is classed as
/// interrupted).
pub type BandError = Box<dyn std::error::Error + Send + Sync>;
