//! Why an optics job cannot run ([`OpticsJobError`]), with the limit on
//! the phase tables it names ([`MAX_PHASE_VALUES`]).

use crate::optics::bulk;
use crate::optics::output::OutputError;
use std::path::PathBuf;

/// The most phase-table values `lucent optics` writes (wavelengths × entries:
/// about 250 MB of CSV).
pub const MAX_PHASE_VALUES: usize = 10_000_000;

/// Why an optics job cannot run.
#[derive(Debug, thiserror::Error)]
pub enum OpticsJobError {
    #[error("--wavelength {0}: must be a positive number of nanometres")]
    Wavelength(f64),
    #[error("--wavelength: {0}")]
    Grid(lucent_colour::GridError),
    #[error("--phase-entries must be 0 (no table) or at least 2")]
    PhaseEntriesOne,
    #[error(
        "{wavelengths} wavelengths × --phase-entries {entries} = {} phase-table values, more than {MAX_PHASE_VALUES}: \
         use a coarser --wavelengths step or fewer --phase-entries (0 for none)",
        wavelengths * entries
    )]
    TooManyPhaseValues { wavelengths: usize, entries: usize },
    #[error("{}: cannot list folder: {source}", path.display())]
    ListFolder { path: PathBuf, source: std::io::Error },
    #[error("{}: no recipe files (*.toml) in this folder", path.display())]
    NoRecipes { path: PathBuf },
    #[error("{}: no such recipe file or folder", path.display())]
    NoSuchRecipe { path: PathBuf },
    /// One recipe or more is invalid (each line one recipe's error).
    #[error("{}", invalid_text(.0))]
    Invalid(Vec<String>),
    #[error("{} and {} both name the sample {name:?}; sample names must differ", first.display(), second.display())]
    SameName { first: PathBuf, second: PathBuf, name: String },
    #[error("{} (its particles' size and index): {source}", path.display())]
    Compute { path: PathBuf, source: bulk::OpticsError },
    #[error(transparent)]
    Output(#[from] OutputError),
    #[error("cannot write the properties as JSON: {0}")]
    Json(serde_json::Error),
    /// The uncertainty study's functions called on a job without `uncertainty`.
    #[error("the job has no --uncertainty study")]
    NoStudy,
    #[error(transparent)]
    Study(#[from] crate::optics::uncertainty::UncertaintyError),
    #[error(transparent)]
    Shard(#[from] crate::job::shard::split::ShardError),
    #[error("{}: shard {k} holds draws {held:?}, the run's shard {k} is {expected:?}", dir.display())]
    ShardRange { dir: PathBuf, k: u32, held: [u64; 2], expected: std::ops::Range<u64> },
    #[error("{}: {why}", path.display())]
    Draws { path: PathBuf, why: String },
    #[error("the shards hold draws {held:?} of the run's 0..{n}")]
    DrawsMissing { held: std::ops::Range<usize>, n: usize },
    #[error("cannot write uncertainty.csv: {0}")]
    Csv(csv::Error),
    #[error(transparent)]
    Write(#[from] crate::io::WriteError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    /// Stopped by Ctrl-C or SIGTERM ([`OpticsJobError::into_parts`] hands
    /// the [`Interrupted`](crate::fault::Interrupted) itself to a caller
    /// that classes errors).
    #[error(transparent)]
    Interrupted(#[from] crate::fault::Interrupted),
}

impl OpticsJobError {
    /// The error as the [`Interrupted`](crate::fault::Interrupted) it is,
    /// if it is one, else itself.
    pub fn into_parts(self) -> Result<Self, crate::fault::Interrupted> {
        match self {
            OpticsJobError::Interrupted(i) => Err(i),
            e => Ok(e),
        }
    }
}

fn invalid_text(failures: &[String]) -> String {
    match failures {
        [one] => one.clone(),
        many => format!("{} recipes are invalid:\n  {}", many.len(), many.join("\n  ")),
    }
}
