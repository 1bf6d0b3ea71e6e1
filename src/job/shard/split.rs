//! How a run is split into shards ([`ShardSpec`]: `--shard K/N`, [`range`]:
//! shard K's part of the work), the format of `shard.json` this version
//! writes ([`FORMAT`]) and what can go wrong with shards ([`ShardError`]):
//! what a job names without knowing the run's files ([`super::format`]).

use std::path::PathBuf;
use thiserror::Error;

/// Why shards could not be made or merged.
#[derive(Debug, Error)]
pub enum ShardError {
    #[error("--shard {spec:?}: expected K/N with 0 ≤ K < N (e.g. 0/4), N ≥ 1")]
    BadSpec { spec: String },
    #[error("--shard {k}/{n}: the run has only {units} {what}, fewer than the {n} shards")]
    TooManyShards { k: u32, n: u32, units: u64, what: &'static str },
    #[error("{path}: cannot read: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{path}: not a shard folder of lucent (no readable shard.json: {why})")]
    NotShard { path: PathBuf, why: String },
    #[error("{path}: corrupt accumulator: {why}")]
    Corrupt { path: PathBuf, why: String },
    #[error("{path}: belongs to another run than {first} ({what} differs: {this} vs {that})")]
    OtherRun { path: PathBuf, first: PathBuf, what: &'static str, this: String, that: String },
    #[error("{path}: belongs to another run than {first} (its job differs: {difference})")]
    OtherJob { path: PathBuf, first: PathBuf, difference: String },
    #[error("{path} and {other} are both shard {k} of {n}")]
    Repeated { path: PathBuf, other: PathBuf, k: u32, n: u32 },
    #[error("shard{} {} of {n} missing (given: {given})", if missing.len() > 1 { "s" } else { "" }, missing.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(", "))]
    Missing { missing: Vec<u32>, n: u32, given: String },
    #[error("no shard folders given")]
    NoShards,
    /// An accumulator that is a symbolic link (to another shard's, typically).
    #[error(
        "{path}: is a symbolic link (to {target}); a shard's accumulator must be the file that shard wrote, \
         not a link to another one"
    )]
    Linked { path: PathBuf, target: PathBuf },
    /// An accumulator whose own record of the shard differs from its folder's shard.json.
    #[error("{path}: holds {holds}, but {json} says {says}: {why}")]
    Mismatch { path: PathBuf, json: PathBuf, holds: String, says: String, why: &'static str },
    /// An accumulator from before the shard's identity was kept inside it.
    #[error("{path}: holds no record of its shard and run (an older accumulator format); rerun the shard")]
    NoRecord { path: PathBuf },
    /// A shard's output folder holds another shard ([`check_shard_out`](super::format::check_shard_out)).
    #[error(
        "--out {}: already holds shard {there} of {there_of} of {} run ({}); give each shard its own folder (writing shard {k} \
         of {n} here would replace it)",
        out.display(),
        if *same_run { "this" } else { "another" },
        json.display()
    )]
    OutHoldsShard { out: PathBuf, json: PathBuf, there: u32, there_of: u32, same_run: bool, k: u32, n: u32 },
    /// A shard of an earlier version, whose run was named by its command line.
    #[error(
        "{path}: a shard of lucent {version} in an older format (its run named by the command line that made it, \
         not by its job); rerun the shards with this version (lucent {this})",
        this = env!("CARGO_PKG_VERSION")
    )]
    OldFormat { path: PathBuf, version: String },
    /// A shard of a format newer than this version's.
    #[error("{path}: a shard of format {format} (lucent {version}); this version (lucent {this}) merges format {FORMAT}", this = env!("CARGO_PKG_VERSION"))]
    NewerFormat { path: PathBuf, format: u64, version: String },
    /// The input files of a shard's job cannot be read.
    #[error("{path}: cannot read an input file of the job: {source}")]
    Input { path: PathBuf, source: std::io::Error },
    /// A shard's output folder holds a shard.json that is not one.
    #[error("--out {}: holds a {} lucent cannot read as a shard's; give each shard its own folder", out.display(), json.display())]
    OutNotShard { out: PathBuf, json: PathBuf },
}

/// `K/N` of `--shard`: shard `k` (from 0) of `n` ≥ 1, k < n. A job file
/// spells it as the command line does, the text "K/N".
///
/// ```
/// use lucent::job::shard::ShardSpec;
/// let s: ShardSpec = "2/7".parse().unwrap();
/// assert_eq!((s.k, s.n, s.to_string()), (2, 7, "2/7".to_string()));
/// assert!("7/7".parse::<ShardSpec>().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct ShardSpec {
    /// This shard's index, 0 ≤ k < n.
    pub k: u32,
    /// The number of shards the run is split into.
    pub n: u32,
}

impl ShardSpec {
    /// (k, n).
    pub fn pair(self) -> (u32, u32) {
        (self.k, self.n)
    }
}

impl std::str::FromStr for ShardSpec {
    type Err = ShardError;
    fn from_str(spec: &str) -> Result<Self, ShardError> {
        let bad = || ShardError::BadSpec { spec: spec.to_string() };
        let (k, n) = spec.split_once('/').ok_or_else(bad)?;
        let (k, n): (u32, u32) = (k.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
        if n == 0 || k >= n {
            return Err(bad());
        }
        Ok(Self { k, n })
    }
}

crate::text::serde_as_text!(ShardSpec);

impl std::fmt::Display for ShardSpec {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.k, self.n)
    }
}

/// The K-th of N contiguous ranges that split 0 … total−1 as evenly as
/// possible (the first ones one longer).
///
/// ```
/// use lucent::job::shard::range;
/// assert_eq!((0..3).map(|k| range(10, k, 3)).collect::<Vec<_>>(), vec![0..4, 4..7, 7..10]);
/// ```
pub fn range(total: u64, k: u32, n: u32) -> std::ops::Range<u64> {
    let (k, n) = (u64::from(k), u64::from(n));
    let (q, r) = (total / n, total % n);
    let start = k * q + k.min(r);
    start..start + q + u64::from(k < r)
}

/// The format of `shard.json` this version writes and merges: 2, the run
/// named by its typed job (format 1, of earlier versions, named it by the
/// command line and the folder it ran in).
pub const FORMAT: u32 = 2;
