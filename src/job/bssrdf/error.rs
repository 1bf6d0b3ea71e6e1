//! Why a slab job or a slice comparison failed ([`BssrdfJobError`]).

use crate::bssrdf;
use crate::fault::Interrupted;
use lucent_render::slab;
use std::path::PathBuf;
use thiserror::Error;

/// Why a slab job or a slice comparison failed.
#[derive(Debug, Error)]
pub enum BssrdfJobError {
    /// A value the job cannot use (the message names its flag).
    #[error("{0}")]
    Refused(String),
    #[error(transparent)]
    Recipe(#[from] crate::optics::recipe::RecipeError),
    #[error(transparent)]
    Optics(#[from] crate::optics::bulk::OpticsError),
    #[error(transparent)]
    Phase(#[from] lucent_render::phase::PhaseError),
    #[error(transparent)]
    Medium(#[from] lucent_render::medium::MediumError),
    #[error(transparent)]
    Slab(#[from] slab::SlabError),
    #[error(transparent)]
    Roughness(#[from] bssrdf::RoughnessError),
    #[error(transparent)]
    Slice(#[from] bssrdf::SliceIoError),
    #[error(transparent)]
    Output(#[from] crate::io::OutputFolderError),
    #[error(transparent)]
    Write(#[from] crate::io::WriteError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    #[error(transparent)]
    Shard(#[from] crate::job::shard::format::ShardError),
    /// The beam map cannot be read.
    #[error("--beam-map")]
    BeamMap(#[source] bssrdf::SliceIoError),
    /// A configuration's directions cannot be used.
    #[error("configuration θi {ti}° → θo {to}°")]
    Configuration { ti: f64, to: f64, source: slab::SlabError },
    /// The recipe at ±1 σ of an uncertain input is not valid.
    #[error("{what}")]
    Perturbed { what: String, source: crate::optics::recipe::RecipeError },
    /// The slices cannot be compared.
    #[error("{measured} vs {simulated}: {error}")]
    Comparison { measured: PathBuf, simulated: PathBuf, error: bssrdf::ComparisonError },
    /// Stopped by Ctrl-C or SIGTERM ([`BssrdfJobError::into_parts`] hands
    /// the [`Interrupted`] itself to a caller that classes errors).
    #[error(transparent)]
    Interrupted(#[from] Interrupted),
}

impl BssrdfJobError {
    /// The error as the [`Interrupted`] it is, if it is one (a caller that
    /// classes errors by their type sees it then), else itself.
    pub fn into_parts(self) -> Result<Self, Interrupted> {
        match self {
            BssrdfJobError::Interrupted(i) => Err(i),
            e => Ok(e),
        }
    }
}
