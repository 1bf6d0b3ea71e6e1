//! The merge of a run's shard folders into the run's outputs ([`merge`]:
//! the job read out of the shards' `shard.json`, checked
//! ([`load_for_merge`]), and merged by its own
//! [`RenderJob::merge`](crate::job::RenderJob::merge),
//! [`BssrdfJob::merge`] or [`OpticsJob::merge_uncertainty`]). `lucent
//! merge` and the pipeline's merge of a cluster's shards both call
//! [`merge`].

use super::format::{self as shard, Shard, ShardError};
use crate::job::bssrdf::{BssrdfJobError, BssrdfRun};
use crate::job::context::Context;
use crate::job::optics::{OpticsJobError, UncertaintyRun};
use crate::job::render::{RenderError, RenderHooks, RenderRun};
use crate::job::spec::{BssrdfJob, Job, OpticsJob, RenderJob};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why shards were not merged.
#[derive(Debug, Error)]
pub enum MergeError {
    #[error(transparent)]
    Shard(#[from] ShardError),
    #[error("{}: made by lucent {made_by}, this is {}: merge with the version that made the shards", dir.display(), env!("CARGO_PKG_VERSION"))]
    Version { dir: PathBuf, made_by: String },
    #[error("{}: cannot resolve: {source}", path.display())]
    Resolve { path: PathBuf, source: std::io::Error },
    #[error("--out {}{}: must not be or contain a shard folder ({})", out.display(), via.as_ref().map(|v| format!(" (it leads to {})", v.display())).unwrap_or_default(), shard.display())]
    OutIsShard { out: PathBuf, via: Option<PathBuf>, shard: PathBuf },
    #[error("{}: the input files of its `lucent {command}` job changed since the shards were made; rerun the shards", json.display())]
    InputsChanged { json: PathBuf, command: String },
    #[error("{}: {source}", json.display())]
    Invalid { json: PathBuf, source: crate::job::fields::JobError },
    #[error("{}: `lucent {command}` is not a job with shards", dir.display())]
    NotSharded { dir: PathBuf, command: String },
    #[error(transparent)]
    Render(Box<RenderError>),
    #[error(transparent)]
    Bssrdf(#[from] BssrdfJobError),
    #[error(transparent)]
    Optics(#[from] OpticsJobError),
}

impl From<RenderError> for MergeError {
    fn from(e: RenderError) -> Self {
        MergeError::Render(Box::new(e))
    }
}

/// What a merge wrote: what the unsharded job writes, and its summary.
pub enum Merged {
    Render(RenderRun),
    Bssrdf(BssrdfRun),
    Optics(UncertaintyRun),
}

impl Merged {
    /// The lines the unsharded command prints.
    pub fn summary(&self) -> Vec<String> {
        match self {
            Merged::Render(r) => r.summary(),
            Merged::Bssrdf(b) => b.summary(),
            Merged::Optics(o) => o.summary(),
        }
    }
}

/// The shard folders `dirs` of one run, loaded and checked for a merge into
/// `out`: all N shards of one run ([`shard::load_shards`]), made by this
/// version, `out` none of them (nor inside one, nor holding one, also
/// through symbolic links), their input files unchanged. Returns the run's
/// job writing into `out` (quietly, but for an optics study) and the shards
/// in shard order.
pub fn load_for_merge(dirs: &[PathBuf], out: &Path) -> Result<(Job, Vec<Shard>), MergeError> {
    let resolve = |p: &Path| std::path::absolute(p).map_err(|source| MergeError::Resolve { path: p.into(), source });
    let dirs: Vec<PathBuf> = dirs.iter().map(|d| resolve(d)).collect::<Result<_, _>>()?;
    let shards = shard::load_shards(&dirs)?;
    let id = &shards[0].file.identity;
    if id.lucent_version != env!("CARGO_PKG_VERSION") {
        return Err(MergeError::Version { dir: shards[0].dir.clone(), made_by: id.lucent_version.clone() });
    }
    let out = resolve(out)?;
    // Compared where the paths lead (through symbolic links), not as spelled.
    let real_out = crate::io::resolved(&out);
    if let Some(s) = shards.iter().find(|s| {
        let d = crate::io::resolved(&s.dir);
        out.starts_with(&s.dir) || s.dir.starts_with(&out) || real_out.starts_with(&d) || d.starts_with(&real_out)
    }) {
        let via = (real_out != out).then(|| real_out.clone());
        return Err(MergeError::OutIsShard { out, via, shard: s.dir.clone() });
    }
    if id.job.inputs_sha256()? != id.inputs_sha256 {
        let json = shards[0].dir.join(shard::SHARD_JSON);
        return Err(MergeError::InputsChanged { json, command: id.command.clone() });
    }
    let job = match id.job.clone() {
        Job::Render(r) => Job::Render(RenderJob { out, quiet: true, shard: None, ..r }),
        Job::Bssrdf(b) => Job::Bssrdf(BssrdfJob { out, quiet: true, shard: None, ..b }),
        Job::Optics(o) if o.uncertainty.is_some() => Job::Optics(OpticsJob { out: Some(out), shard: None, ..o }),
        other => {
            return Err(MergeError::NotSharded { dir: shards[0].dir.clone(), command: other.command_name().into() });
        }
    };
    job.validate().map_err(|source| MergeError::Invalid { json: shards[0].dir.join(shard::SHARD_JSON), source })?;
    Ok((job, shards))
}

/// Merges the shard folders `dirs` of one run into `out` ([`load_for_merge`]
/// checks them, every shard is read before anything is written): the
/// render, slices or uncertainty study the unsharded job writes. A render's
/// progress goes to `hooks`, lines and warnings to `ctx`.
pub fn merge(ctx: &Context, dirs: &[PathBuf], out: &Path, hooks: &mut dyn RenderHooks) -> Result<Merged, MergeError> {
    let (job, shards) = load_for_merge(dirs, out)?;
    Ok(match &job {
        Job::Render(r) => Merged::Render(r.merge(ctx, &shards, hooks)?),
        Job::Bssrdf(b) => Merged::Bssrdf(b.merge(ctx, &shards)?),
        Job::Optics(o) => Merged::Optics(o.merge_uncertainty(ctx, &shards)?),
        other => {
            return Err(MergeError::NotSharded { dir: shards[0].dir.clone(), command: other.command_name().into() });
        }
    })
}
