//! The files of a shard: the accumulator format ([`write_accumulator`],
//! [`read_accumulator`]: named f64 arrays, little-endian, with a SHA-256 of
//! the content; a shard's carries its [`AccMeta`]), `shard.json`
//! ([`ShardFile`]: the run's [`Identity`], the shard's index and range)
//! and the checks that shard folders belong together ([`load_shards`]);
//! how a run is split ([`ShardSpec`], [`range`]) is [`super::split`]'s.
//! The overview is the parent module's.
pub use super::split::{range, ShardError, ShardSpec, FORMAT};
use crate::job::spec::Job;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};

/// The first bytes of an accumulator file without a shard's identity inside.
pub const MAGIC: &[u8; 8] = b"LUCACC01";
/// The first bytes of a shard's accumulator file: after them the shard's
/// [`AccMeta`] (u32 length, JSON), then the arrays as in [`MAGIC`]'s format.
pub const MAGIC_SHARD: &[u8; 8] = b"LUCACC02";
/// The file in a shard folder that says which shard it is.
pub const SHARD_JSON: &str = "shard.json";

/// Refuses a shard's `--out` that already holds another shard (another K
/// or N): two shards written into one folder would leave only the last.
/// Shard K of N again (a retry, or the same shard after its inputs
/// changed) may replace its own files. Checked before the shard runs and
/// again just before it writes.
pub fn check_shard_out(out: &Path, identity: &Identity, k: u32) -> Result<(), ShardError> {
    let json = out.join(SHARD_JSON);
    if std::fs::symlink_metadata(&json).is_err() {
        return Ok(());
    }
    // Which shard it is, in any format (an older shard's identity is not this version's).
    let value: Option<serde_json::Value> = crate::io::read_text(&json).ok().and_then(|t| serde_json::from_str(&t).ok());
    let there =
        value.as_ref().and_then(|v| Some((v.get("shard")?.as_u64()?, v.get("identity")?.get("shards")?.as_u64()?)));
    match there {
        // Shard K of N again (a retry, or a rerun after its inputs changed)
        // replaces its own files.
        Some((t, tn)) if t == u64::from(k) && tn == u64::from(identity.shards) => Ok(()),
        Some((t, tn)) => {
            let same_run = value
                .and_then(|v| serde_json::from_value::<ShardFile>(v).ok())
                .is_some_and(|f| f.identity == *identity);
            Err(ShardError::OutHoldsShard {
                out: out.to_path_buf(),
                json,
                there: u32::try_from(t).unwrap_or(u32::MAX),
                there_of: u32::try_from(tn).unwrap_or(u32::MAX),
                same_run,
                k,
                n: identity.shards,
            })
        }
        None => Err(ShardError::OutNotShard { out: out.to_path_buf(), json }),
    }
}

/// What a shard's accumulator records about itself, inside the checksummed
/// file: the run (SHA-256 of its [`Identity`]), the shard, its range and
/// counters. The merge checks it against the folder's `shard.json`, so an
/// accumulator copied (or linked) from another shard or run, or counters
/// edited in `shard.json`, are refused.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct AccMeta {
    pub run_sha256: String,
    pub shard: u32,
    pub shards: u32,
    pub range: [u64; 2],
    pub counters: std::collections::BTreeMap<String, u64>,
}

impl AccMeta {
    pub fn new(
        identity: &Identity,
        shard: u32,
        range: &std::ops::Range<u64>,
        counters: &std::collections::BTreeMap<String, u64>,
    ) -> Self {
        AccMeta {
            run_sha256: identity.sha256(),
            shard,
            shards: identity.shards,
            range: [range.start, range.end],
            counters: counters.clone(),
        }
    }
}

impl Identity {
    /// The identity of a run of `job` split into `shards`, with its `seed`
    /// and `budget` ("64 spp") and the SHA-256 of its input files' content
    /// (`inputs_sha256`): the job [`normalised`](Job::normalised) (its
    /// output folder, shard and settings that do not change the result left
    /// out, paths absolute), so the shards of one run have one identity
    /// however each was spelled or wherever it ran.
    pub fn new(job: &Job, inputs_sha256: String, seed: u64, budget: String, shards: u32) -> Self {
        let job = job.normalised();
        Identity {
            format: FORMAT,
            command: job.command_name().to_string(),
            job_sha256: job.identity_sha256(),
            job,
            inputs_sha256,
            lucent_version: env!("CARGO_PKG_VERSION").into(),
            seed,
            budget,
            shards,
        }
    }

    /// SHA-256 of the identity as JSON: the run an accumulator belongs to.
    pub fn sha256(&self) -> String {
        crate::job::spec::json_sha256(self)
    }
}

/// Where two jobs differ, as `key is A here, B there` for the first key (in
/// the JSON's order, nested keys joined by `.`) whose values differ.
fn job_difference(a: &Job, b: &Job) -> String {
    fn first(path: &str, a: &serde_json::Value, b: &serde_json::Value) -> Option<String> {
        use serde_json::Value::Object;
        match (a, b) {
            (Object(x), Object(y)) => {
                let keys = x.keys().chain(y.keys().filter(|k| !x.contains_key(*k)));
                for k in keys {
                    let null = serde_json::Value::Null;
                    let (va, vb) = (x.get(k).unwrap_or(&null), y.get(k).unwrap_or(&null));
                    let p = if path.is_empty() { k.clone() } else { format!("{path}.{k}") };
                    if let Some(d) = first(&p, va, vb) {
                        return Some(d);
                    }
                }
                None
            }
            _ if a != b => Some(format!("{path} is {a} here, {b} there")),
            _ => None,
        }
    }
    let (a, b) = (serde_json::to_value(a).unwrap_or_default(), serde_json::to_value(b).unwrap_or_default());
    first("", &a, &b).unwrap_or_else(|| "the jobs' JSON".into())
}

/// What makes shards parts of one run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Identity {
    /// [`FORMAT`].
    pub format: u32,
    /// `render`, `bssrdf` or `optics`.
    pub command: String,
    /// The run's job, [`normalised`](Job::normalised): without its output
    /// folder, its shard and the settings that do not change the result
    /// (`quiet`, `threads`), its paths absolute. `lucent merge` runs its
    /// merge with the output folder it is given.
    pub job: Job,
    /// SHA-256 of `job` as JSON.
    pub job_sha256: String,
    /// SHA-256 of every input file's path and content (the scene or recipe
    /// and the files it names, [`Job::inputs_sha256`]).
    pub inputs_sha256: String,
    pub lucent_version: String,
    pub seed: u64,
    /// The run's budget, e.g. "64 spp", "100000 paths" or "1000 draws".
    pub budget: String,
    /// N.
    pub shards: u32,
}

/// `shard.json`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ShardFile {
    pub identity: Identity,
    /// K.
    pub shard: u32,
    /// The sample (render), batch (bssrdf) or draw (optics) indices of this shard.
    pub range: [u64; 2],
    /// The accumulator files in the folder.
    pub accumulators: Vec<String>,
    /// Counters of the shard (integers, added by the merge).
    pub counters: std::collections::BTreeMap<String, u64>,
    pub wall_s: f64,
}

/// Named arrays of an accumulator file.
pub type Arrays = Vec<(String, Vec<f64>)>;

/// Writes named f64 arrays: [`MAGIC`], the count, per array its name
/// (u32 length, UTF-8) and values (u64 count, f64 little-endian), then the
/// SHA-256 of all the bytes before it.
pub fn write_accumulator(path: &Path, arrays: &[(&str, &[f64])]) -> Result<(), crate::io::WriteError> {
    write_accumulator_with(path, None, arrays)
}

/// [`write_accumulator`] for a shard: its [`AccMeta`] goes inside the file
/// (format [`MAGIC_SHARD`]), under the checksum.
pub fn write_shard_accumulator(
    path: &Path,
    meta: &AccMeta,
    arrays: &[(&str, &[f64])],
) -> Result<(), crate::io::WriteError> {
    write_accumulator_with(path, Some(meta), arrays)
}

fn write_accumulator_with(
    path: &Path,
    meta: Option<&AccMeta>,
    arrays: &[(&str, &[f64])],
) -> Result<(), crate::io::WriteError> {
    let size: usize = arrays.iter().map(|(n, v)| 12 + n.len() + 8 * v.len()).sum();
    let mut bytes = Vec::with_capacity(16 + size + 32);
    match meta {
        Some(m) => {
            let json = serde_json::to_string(m).unwrap_or_default();
            bytes.extend_from_slice(MAGIC_SHARD);
            bytes.extend_from_slice(&(json.len() as u32).to_le_bytes());
            bytes.extend_from_slice(json.as_bytes());
        }
        None => bytes.extend_from_slice(MAGIC),
    }
    bytes.extend_from_slice(&(arrays.len() as u32).to_le_bytes());
    for (name, values) in arrays {
        bytes.extend_from_slice(&(name.len() as u32).to_le_bytes());
        bytes.extend_from_slice(name.as_bytes());
        bytes.extend_from_slice(&(values.len() as u64).to_le_bytes());
        for v in *values {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    let digest = Sha256::digest(&bytes);
    bytes.extend_from_slice(&digest);
    crate::io::write_atomic(path, &bytes)
}

/// Reads a file of [`write_accumulator`]; a truncated, altered or foreign
/// file is a [`ShardError::Corrupt`] naming it.
pub fn read_accumulator(path: &Path) -> Result<Arrays, ShardError> {
    let bytes = std::fs::read(path).map_err(|source| ShardError::Read { path: path.to_path_buf(), source })?;
    let corrupt = |why: &str| ShardError::Corrupt { path: path.to_path_buf(), why: why.to_string() };
    if bytes.len() < MAGIC.len() + 4 + 32 || (&bytes[..MAGIC.len()] != MAGIC && &bytes[..MAGIC.len()] != MAGIC_SHARD) {
        return Err(corrupt("not a lucent accumulator (wrong header or too short)"));
    }
    let (body, digest) = bytes.split_at(bytes.len() - 32);
    if Sha256::digest(body).as_slice() != digest {
        return Err(corrupt("checksum mismatch (truncated or altered)"));
    }
    let mut at = MAGIC.len();
    if &bytes[..MAGIC.len()] == MAGIC_SHARD {
        let len = body.get(at..at + 4).map(|b| u32::from_le_bytes(b.try_into().unwrap_or([0; 4])) as usize);
        at += 4 + len.ok_or_else(|| corrupt("ends inside its shard record"))?;
    }
    let mut take = |n: usize| -> Result<&[u8], ShardError> {
        let s = body.get(at..at + n).ok_or_else(|| corrupt("ends inside an array"))?;
        at += n;
        Ok(s)
    };
    let u32_of = |b: &[u8]| u32::from_le_bytes(b.try_into().unwrap_or([0; 4]));
    let count = u32_of(take(4)?);
    let mut arrays = Vec::new();
    for _ in 0..count {
        let len = u32_of(take(4)?) as usize;
        let name = String::from_utf8(take(len)?.to_vec()).map_err(|_| corrupt("array name is not UTF-8"))?;
        let n = u64::from_le_bytes(take(8)?.try_into().unwrap_or([0; 8]));
        let n = usize::try_from(n).ok().filter(|n| n.checked_mul(8).is_some()).ok_or_else(|| corrupt("bad length"))?;
        let raw = take(8 * n)?;
        let values = raw.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect();
        arrays.push((name, values));
    }
    if at != body.len() {
        return Err(corrupt("trailing bytes after the last array"));
    }
    Ok(arrays)
}

/// The [`AccMeta`] at the start of a shard's accumulator (only the first
/// bytes are read; the checksum over the whole file is checked when its
/// arrays are read): `None` for a file of the older format without one.
pub fn read_accumulator_meta(path: &Path) -> Result<Option<AccMeta>, ShardError> {
    use std::io::Read;
    let corrupt = |why: String| ShardError::Corrupt { path: path.to_path_buf(), why };
    let read = |source| ShardError::Read { path: path.to_path_buf(), source };
    let mut f = std::fs::File::open(path).map_err(read)?;
    let mut head = [0u8; 12];
    f.read_exact(&mut head).map_err(|_| corrupt("not a lucent accumulator (too short)".into()))?;
    if &head[..8] == MAGIC {
        return Ok(None);
    }
    if &head[..8] != MAGIC_SHARD {
        return Err(corrupt("not a lucent accumulator (wrong header)".into()));
    }
    let len = u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as usize;
    if len > 1 << 20 {
        return Err(corrupt(format!("a shard record of {len} bytes")));
    }
    let mut json = vec![0u8; len];
    f.read_exact(&mut json).map_err(|_| corrupt("ends inside its shard record".into()))?;
    serde_json::from_slice(&json).map(Some).map_err(|e| corrupt(format!("unreadable shard record: {e}")))
}

/// Checks the accumulators a shard folder's `shard.json` lists against the
/// record inside each ([`AccMeta`]): each must be a file of the folder (not
/// a symbolic link), of this run and this shard, with the same range and
/// counters as `shard.json`.
fn check_accumulators(dir: &Path, file: &ShardFile) -> Result<(), ShardError> {
    let json = dir.join(SHARD_JSON);
    let run = file.identity.sha256();
    for name in &file.accumulators {
        let path = dir.join(name);
        let inside = Path::new(name).components().all(|c| matches!(c, std::path::Component::Normal(_)));
        if name.is_empty() || !inside {
            return Err(ShardError::NotShard { path: json.clone(), why: format!("accumulator name {name:?}") });
        }
        if let Ok(target) = std::fs::read_link(&path) {
            return Err(ShardError::Linked { path, target });
        }
        let meta = read_accumulator_meta(&path)?.ok_or_else(|| ShardError::NoRecord { path: path.clone() })?;
        let mismatch = |holds: String, says: String, why| ShardError::Mismatch {
            path: path.clone(),
            json: json.clone(),
            holds,
            says,
            why,
        };
        if meta.run_sha256 != run {
            return Err(mismatch(
                format!("the sums of run {}…", &meta.run_sha256[..meta.run_sha256.len().min(12)]),
                format!("run {}…", &run[..12]),
                "an accumulator of another run (copied into this folder?) is not merged",
            ));
        }
        if meta.shard != file.shard || meta.shards != file.identity.shards {
            return Err(mismatch(
                format!("shard {} of {}", meta.shard, meta.shards),
                format!("shard {} of {}", file.shard, file.identity.shards),
                "a copy of another shard's accumulator is not a shard of its own",
            ));
        }
        if meta.range != file.range {
            return Err(mismatch(
                format!("range {:?}", meta.range),
                format!("range {:?}", file.range),
                "shard.json was edited; rerun the shard",
            ));
        }
        if meta.counters != file.counters {
            let show = |c: &std::collections::BTreeMap<String, u64>| {
                c.iter().map(|(k, v)| format!("{k} {v}")).collect::<Vec<_>>().join(", ")
            };
            return Err(mismatch(
                format!("counters {{{}}}", show(&meta.counters)),
                format!("counters {{{}}}", show(&file.counters)),
                "the counters do not match the sums (shard.json was edited); rerun the shard",
            ));
        }
    }
    Ok(())
}

/// The array `name` of `arrays` with `len` values.
pub fn array<'a>(arrays: &'a Arrays, name: &str, len: usize, path: &Path) -> Result<&'a [f64], ShardError> {
    let (_, v) = arrays
        .iter()
        .find(|(n, _)| n == name)
        .ok_or_else(|| ShardError::Corrupt { path: path.to_path_buf(), why: format!("no array {name:?}") })?;
    if v.len() != len {
        return Err(ShardError::Corrupt {
            path: path.to_path_buf(),
            why: format!("array {name:?} has {} values, expected {len}", v.len()),
        });
    }
    Ok(v)
}

/// A `shard.json` of this version's [`FORMAT`]; an older or newer one, or
/// one that is no shard's, refused naming `path`.
pub fn parse_shard_file(path: &Path, text: &str) -> Result<ShardFile, ShardError> {
    let not = |why: String| ShardError::NotShard { path: path.to_path_buf(), why };
    let value: serde_json::Value = serde_json::from_str(text).map_err(|e| not(e.to_string()))?;
    let identity = value.get("identity");
    let version =
        identity.and_then(|i| i.get("lucent_version")).and_then(|v| v.as_str()).unwrap_or("(unknown)").to_string();
    match identity.map(|i| i.get("format").and_then(|f| f.as_u64())) {
        Some(None) if identity.is_some_and(|i| i.get("args").is_some()) => {
            return Err(ShardError::OldFormat { path: path.to_path_buf(), version });
        }
        Some(Some(f)) if f > u64::from(FORMAT) => {
            return Err(ShardError::NewerFormat { path: path.to_path_buf(), format: f, version });
        }
        _ => {}
    }
    serde_json::from_value(value).map_err(|e| not(e.to_string()))
}

/// One shard folder as read by [`load_shards`].
#[derive(Debug, Clone)]
pub struct Shard {
    pub dir: PathBuf,
    pub file: ShardFile,
}

/// Reads the `shard.json` of every folder and checks that they are the N
/// shards of one run, each once; returns them in shard order.
pub fn load_shards(dirs: &[PathBuf]) -> Result<Vec<Shard>, ShardError> {
    let mut shards: Vec<Shard> = Vec::new();
    for dir in dirs {
        let path = dir.join(SHARD_JSON);
        let text =
            crate::io::read_text(&path).map_err(|e| ShardError::NotShard { path: dir.clone(), why: e.to_string() })?;
        let file = parse_shard_file(&path, &text)?;
        if let Some(first) = shards.first() {
            let (a, b) = (&first.file.identity, &file.identity);
            let differs: Option<(&'static str, String, String)> = if a.command != b.command {
                Some(("command", b.command.clone(), a.command.clone()))
            } else if a.shards != b.shards {
                Some(("number of shards", b.shards.to_string(), a.shards.to_string()))
            } else if a.seed != b.seed {
                Some(("seed", b.seed.to_string(), a.seed.to_string()))
            } else if a.budget != b.budget {
                Some(("budget", b.budget.clone(), a.budget.clone()))
            } else if a.lucent_version != b.lucent_version {
                Some(("lucent version", b.lucent_version.clone(), a.lucent_version.clone()))
            } else if a.job != b.job || a.job_sha256 != b.job_sha256 {
                return Err(ShardError::OtherJob {
                    path: path.clone(),
                    first: first.dir.join(SHARD_JSON),
                    difference: job_difference(&b.job, &a.job),
                });
            } else if a.inputs_sha256 != b.inputs_sha256 {
                Some(("input files' content", b.inputs_sha256.clone(), a.inputs_sha256.clone()))
            } else {
                None
            };
            if let Some((what, this, that)) = differs {
                return Err(ShardError::OtherRun {
                    path: path.clone(),
                    first: first.dir.join(SHARD_JSON),
                    what,
                    this,
                    that,
                });
            }
        }
        if file.shard >= file.identity.shards {
            return Err(ShardError::NotShard {
                path: path.clone(),
                why: format!("shard {} of {}", file.shard, file.identity.shards),
            });
        }
        if let Some(other) = shards.iter().find(|s| s.file.shard == file.shard) {
            return Err(ShardError::Repeated {
                path: dir.clone(),
                other: other.dir.clone(),
                k: file.shard,
                n: file.identity.shards,
            });
        }
        check_accumulators(dir, &file)?;
        shards.push(Shard { dir: dir.clone(), file });
    }
    let first = shards.first().ok_or(ShardError::NoShards)?;
    let n = first.file.identity.shards;
    let missing: Vec<u32> = (0..n).filter(|k| !shards.iter().any(|s| s.file.shard == *k)).collect();
    if !missing.is_empty() {
        let given = shards.iter().map(|s| format!("{} ({})", s.file.shard, s.dir.display())).collect::<Vec<_>>();
        return Err(ShardError::Missing { missing, n, given: given.join(", ") });
    }
    shards.sort_by_key(|s| s.file.shard);
    Ok(shards)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_partition_the_indices() {
        for total in [0u64, 1, 7, 64, 1000] {
            for n in 1..9u32 {
                let mut next = 0;
                for k in 0..n {
                    let r = range(total, k, n);
                    assert_eq!(r.start, next);
                    next = r.end;
                }
                assert_eq!(next, total);
            }
        }
    }

    #[test]
    fn accumulator_round_trips_and_detects_damage() {
        let dir = std::env::temp_dir().join(format!("lucent-shard-acc-{}", std::process::id()));
        let path = dir.join("a.acc");
        let a = [1.0, -0.0, f64::MIN_POSITIVE, 1e300];
        write_accumulator(&path, &[("a", &a), ("b", &[])]).expect("write");
        let back = read_accumulator(&path).expect("read");
        assert_eq!(back.len(), 2);
        assert_eq!(back[0].1.iter().map(|v| v.to_bits()).collect::<Vec<_>>(), a.map(f64::to_bits).to_vec());
        let mut bytes = std::fs::read(&path).expect("bytes");
        bytes[20] ^= 1;
        std::fs::write(&path, &bytes).expect("write");
        assert!(read_accumulator(&path).unwrap_err().to_string().contains("checksum"));
        std::fs::write(&path, &bytes[..10]).expect("write");
        assert!(read_accumulator(&path).unwrap_err().to_string().contains("not a lucent accumulator"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
