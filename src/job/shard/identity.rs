//! A shard's identity from its job: the files whose content makes a run's
//! result ([`Job::input_files`]: a scene and every file it names, recipes
//! and theirs), their SHA-256 ([`Job::inputs_sha256`]) and the identity of
//! the run a job is a shard of ([`Job::shard_identity`], the
//! [`Identity`] its `shard.json` holds).

use super::format::{Identity, ShardError};
use crate::job::spec::Job;
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

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
