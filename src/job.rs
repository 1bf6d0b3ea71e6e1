//! Jobs: one validated value per command that `lucent run` hands to a
//! stage, built by the pipeline from the project file and by the command
//! line from its flags (the pattern of ripgrep's `HiArgs`, which its
//! low-level argument struct converts into). `surface fit`, `env merge`
//! and `env orient`, which no stage runs, are jobs too: their commands and
//! `lucent job run` run them the same way.
//!
//! Every job has
//! * `validate()`: the ranges its flags accept (the same limits the
//!   commands check), so a project value out of range is refused with the
//!   project key before any stage runs, never as a command's
//!   "unexpected argument";
//! * `to_args()`: its canonical `lucent` command line (every field with a
//!   default is written, optional ones only when set). The pipeline records
//!   this line in a stage's manifest.json and its logs; parsing it back
//!   gives the same job.
//!
//! A job is also a JSON value (serde; `{"render": {"scene": …}}`, the
//! format `lucent job run JOB.json` reads, and the one the cluster scripts
//! run each shard from): the stage key hashes it, and
//! [`Job::identity_sha256`] (the job without its output folder, paths
//! canonical) names the folder of a long job's shards; a shard's run is
//! named by the same normalised job with its input files' SHA-256
//! ([`Job::shard_identity`], [`shard`]). A stage runs its
//! jobs in the `lucent run` process through [`Job::run_with`] (the stage's
//! own `run`, e.g. [`RenderJob::run_with`], inside the checks its command
//! makes), as `lucent job run JOB.json` runs a job file.
//!
//! Paths may hold the placeholder `{out}` (the stage folder), replaced when
//! the command runs.
//!
//! A field with structure (an image size, a wavelength grid, goniometer
//! configurations, a board, free parameters and their bounds, a sample's
//! corner and size) is a type that reads its text in one place, its
//! `FromStr` (the flags' parser, the project file's and the job file's):
//! a job never holds a value its command would refuse to read, and its
//! JSON holds the text its command line does ([`values`]). Strings left
//! are free text: names, file patterns.
//!
//! This module declares the parts and re-exports what they make public:
//! the jobs' structs and [`Job`] are in `spec`, the checks and command
//! lines every job's fields share in `fields`, and what a job does when it
//! runs in its stage's module (`render`, `bssrdf`, …). The parts import
//! from one another, never from here.

mod bssrdf;
pub mod camera;
mod colour;
mod compare;
mod context;
pub mod env_merge;
pub mod env_orient;
mod env_scale;
mod fields;
mod fit;
pub mod guard;
mod images;
pub mod optics;
mod raw;
pub mod render;
pub mod report;
pub mod run;
pub mod shard;
mod spec;
pub mod surface_fit;
mod threads;

pub use crate::text::duration;
pub use bssrdf::{
    beam, expectation, BssrdfCompareRun, BssrdfJobError, BssrdfRun, MediumChoice, NoHooks, Perturbation, Plan,
    PlannedRun, SliceHooks,
};
pub use camera::{CalibrateRun, CameraJobError, PoseRun};
pub use colour::{ColourApplyRun, ColourCalibrateRun, ColourJobError};
pub use compare::CompareRun;
pub use context::Context;
pub use env_merge::{
    BracketError, EnvMergeError, EnvMergeFiles, EnvMergeJob, EnvMergeReport, EnvMergeRun, Exposures, ExposuresError,
};
pub use env_orient::{
    read_env_map, EnvMapError, EnvOrientError, EnvOrientFiles, EnvOrientJob, EnvOrientRun, ViewAngles, ViewAnglesError,
};
pub use env_scale::{EnvScaleJobError, EnvScaleRun};
pub use fields::{flag_name, positive, threshold, weight_percent, JobError, MAX_SLICE_PIXELS};
pub use fit::{write_fit_outputs, write_fit_outputs_with_recipe_text, FitJobError, FitRun};
pub use optics::{OpticsJobError, OpticsRun};
pub use raw::{RawClippedError, RawClippedRun};
pub use render::{RenderError, RenderHooks, RenderRun};
pub use shard::{merge, MergeError, Merged};
pub use spec::{
    adaptation_word, sample_size_problem, sha256_hex, BssrdfCompareJob, BssrdfJob, CalibrateJob, ColourApplyJob,
    ColourCalibrateJob, CompareJob, EnvScaleJob, EstimatorChoice, FitJob, Job, OpticsJob, PoseJob, RawClippedJob,
    RenderJob, DEFAULT_ADAPTATION, DEFAULT_CLIPPED_LEVEL, DEFAULT_CLIP_LEVEL, DEFAULT_DATA_RANGE, DEFAULT_DILATE,
    DEFAULT_FIT_REL_ERROR, DEFAULT_GAP_RATIO, DEFAULT_INNER_FRACTION, DEFAULT_MEASURED_REL_SD, DEFAULT_OPTICS_OUT,
    DEFAULT_PHASE_ENTRIES, DEFAULT_THRESHOLD, DEFAULT_VARIANCE_REALISATIONS, MAX_UNCERTAINTY_DRAWS,
    SAMPLE_PER_BOARD_MAX,
};
pub use surface_fit::{SurfaceFitError, SurfaceFitJob, SurfaceFitRun};
pub use threads::{allocated_threads, check_threads, worker_pool, ThreadsError, MAX_THREADS};

// Each stage's section of the run's report, beside its outputs ([`report`]).
pub use bssrdf::{BssrdfConfigFiles, BssrdfSection};
pub use camera::{CalibrateSection, PoseSection};
pub use colour::{ColourCamera, ColourSection};
pub use compare::{verdict_sentence, CompareSection};
pub use fit::FitSection;
pub use optics::{read_spectra, OpticsSection};

pub mod values;
pub use values::{
    BadClipLevel, ChartCorners, ClipLevel, ImageSize, MeasuredAngles, MeasuredSlice, SampleCorner, SampleSizeMm,
};
