//! A run split into shards, from its job: a shard's identity
//! ([`Job::shard_identity`]: the typed job normalised, with the SHA-256 of
//! its input files' content, [`Job::inputs_sha256`]) and the merge of a
//! run's shard folders into the run's outputs ([`merge`]: the job read out
//! of the shards' `shard.json`, checked, and merged by its own
//! [`RenderJob::merge`](super::RenderJob::merge), [`BssrdfJob::merge`] or
//! [`OpticsJob::merge_uncertainty`]). `lucent merge` and the pipeline's
//! merge of a cluster's shards both call [`merge`].

use super::{BssrdfJob, BssrdfJobError, BssrdfRun, Context, Job, OpticsJob, RenderError, RenderHooks, RenderRun};
use crate::job::optics::{OpticsJobError, UncertaintyRun};
use crate::job::shard::{self, Identity, Shard, ShardError};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// The files a scene file reads: itself, its environment map, camera and
/// scene JSON, mesh, board texture and spectra (those that exist).
pub fn scene_inputs(path: &Path) -> Vec<PathBuf> {
    use crate::envfit;
    let mut v = vec![path.to_path_buf()];
    if let Ok(text) = crate::io::read_text(path)
        && let Ok(f) = crate::scene::parse(&text, path)
    {
        let f = envfit::with_paths_from(&f, &envfit::scene_dir(path));
        v.extend(f.environment.map);
        v.extend(f.camera.scene_json);
        v.extend(f.camera.camera_json);
        if let Some(o) = f.object {
            v.extend(o.mesh);
        }
        if let Some(b) = f.board {
            v.extend(b.texture);
            v.extend(b.even_spectrum);
            v.extend(b.odd_spectrum);
        }
    }
    v.retain(|p| p.is_file());
    v
}

/// A recipe and the files it names (index tables, a surface fit.json): every
/// string value of the TOML that is the path of an existing file relative to
/// the recipe's folder (or absolute), so editing an index file reruns the
/// stages that read it.
pub fn recipe_inputs(recipe: &Path) -> Vec<PathBuf> {
    fn walk(v: &toml::Value, dir: &Path, out: &mut Vec<PathBuf>) {
        match v {
            toml::Value::String(t) if (!t.is_empty() && !t.contains(':')) || t.starts_with('/') => {
                let p = dir.join(t);
                if p.is_file() && !out.contains(&p) {
                    out.push(p);
                }
            }
            toml::Value::Array(a) => a.iter().for_each(|x| walk(x, dir, out)),
            toml::Value::Table(t) => t.values().for_each(|x| walk(x, dir, out)),
            _ => {}
        }
    }
    let mut v = vec![recipe.to_path_buf()];
    let dir = recipe.parent().unwrap_or(Path::new("."));
    if let Some(table) = crate::io::read_text(recipe).ok().and_then(|t| toml::from_str::<toml::Table>(&t).ok()) {
        walk(&toml::Value::Table(table), dir, &mut v);
    }
    v
}

/// The recipe files of a list of recipes and folders of recipes (a
/// folder's `*.toml`, sorted).
fn recipe_files(recipes: &[PathBuf]) -> Vec<PathBuf> {
    let mut out = Vec::new();
    for r in recipes {
        if r.is_dir() {
            let found = crate::job::optics::toml_files_in(r).unwrap_or_default();
            out.extend(found.into_iter().filter(|f| f.is_file()));
        } else {
            out.push(r.clone());
        }
    }
    out
}

impl Job {
    /// The files whose content makes a run's result, besides the job: a
    /// render's scene and every file it names (and the files its recipe
    /// names), a slab job's recipe (and its files) and beam map, an optics
    /// job's recipes (a folder's `*.toml`) and their files; for the other
    /// jobs the inputs of [`Job::file_roles`]. Each once, in a fixed order.
    pub fn input_files(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = Vec::new();
        let with_recipes = |named: Vec<PathBuf>, files: &mut Vec<PathBuf>| {
            for f in named {
                let more = if f.extension().is_some_and(|e| e == "toml") { recipe_inputs(&f) } else { vec![] };
                for g in std::iter::once(f).chain(more) {
                    if !files.contains(&g) {
                        files.push(g);
                    }
                }
            }
        };
        match self {
            Job::Render(r) => {
                let mut named = scene_inputs(&r.scene);
                named.extend(recipe_inputs(&r.scene));
                with_recipes(named, &mut files);
            }
            Job::Bssrdf(b) => {
                with_recipes(b.recipe.iter().cloned().collect(), &mut files);
                with_recipes(b.beam_map.iter().cloned().collect(), &mut files);
            }
            Job::Optics(o) => with_recipes(recipe_files(&o.recipes), &mut files),
            other => with_recipes(other.file_roles().inputs, &mut files),
        }
        files
    }

    /// SHA-256 of every [input file](Job::input_files)'s real path and
    /// content: what tells a merge that the inputs changed since the shards
    /// ran. A file that cannot be read is refused, named.
    pub fn inputs_sha256(&self) -> Result<String, ShardError> {
        let mut h = Sha256::new();
        for f in self.normalised().input_files() {
            let bytes = std::fs::read(&f).map_err(|source| ShardError::Input { path: f.clone(), source })?;
            let real = std::fs::canonicalize(&f).unwrap_or(f);
            h.update(real.to_string_lossy().as_bytes());
            h.update([0u8]);
            h.update(Sha256::digest(&bytes));
        }
        Ok(format!("{:x}", h.finalize()))
    }

    /// The identity of the run this job is a shard of, split into `shards`
    /// with `seed` and `budget` ("64 spp"): the job normalised (the same
    /// for every shard however its flags were spelled, its paths relative
    /// or absolute) and its inputs' SHA-256 ([`Identity::new`]).
    pub fn shard_identity(&self, seed: u64, budget: String, shards: u32) -> Result<Identity, ShardError> {
        Ok(Identity::new(self, self.inputs_sha256()?, seed, budget, shards))
    }
}

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
    Invalid { json: PathBuf, source: super::JobError },
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
        Job::Render(r) => Job::Render(super::RenderJob { out, quiet: true, shard: None, ..r }),
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
