//! Long runs split into shards and merged back (the formats re-exported as
//! `lucent::shard`): the shard's files ([`format`](mod@format)), a shard's identity
//! from its job ([`identity`]) and the merge ([`merge()`], module
//! [`merge`](mod@merge)).
//!
//! A run of `lucent render` (samples 0 … spp−1 of every pixel) or of
//! `lucent bssrdf` (path batches 0 … B−1) is split into N disjoint,
//! contiguous ranges of sample or batch indices ([`range`]); shard K runs
//! range K with the random streams the whole run would use for those
//! indices (every sample and every path draws from its own stream, seeded
//! by its index), and writes its sums (per pixel Σx, Σx², counts) as an
//! accumulator file ([`write_accumulator`]: named f64 arrays, little-endian,
//! with a SHA-256 of the content) beside `shard.json` ([`ShardFile`]: the
//! run's [`Identity`] and the shard's index and range). The identity is
//! the run's typed job, normalised (no output folder or shard, paths
//! absolute), with the SHA-256 of the job and of its input files' content
//! ([`Identity::new`]; [`Job::shard_identity`](crate::job::Job::shard_identity) computes it), so shards of
//! one run agree however each was spelled or started.
//!
//! [`load_shards`] reads the shard folders of one run and checks that they
//! belong together: this version's [`FORMAT`], the same identity (the
//! first field of the job that differs is named), every K in 0 … N−1
//! exactly once, accumulators intact. The merged sums are the shards' sums added in
//! shard order. Merged and unsharded results agree to rounding only: the
//! unsharded run adds each sample to a running sum, the merge adds the
//! shards' partial sums, and floating-point addition is not associative.
//! For the non-negative terms of both estimators each way's relative error
//! is at most (m − 1)·2⁻⁵³ for a sum of m terms (Higham 2002, *Accuracy and
//! Stability of Numerical Algorithms*, §4.2), so means differ by at most
//! 2m·2⁻⁵³ relatively (2.8·10⁻¹⁴ for m = 64 samples); with N = 1 they are
//! bit-for-bit equal.
//!
//! A run of `lucent optics --uncertainty N` is split the same way over its
//! Latin-hypercube draws 0 … N−1: every shard makes the whole design from
//! the seed and evaluates its range, and its accumulator holds the draws'
//! values, not sums (the percentiles need every value). The merge puts them
//! together in draw order and summarises them with the unsharded code, so
//! there the merged result is bit-for-bit the unsharded one for every N.

pub mod format;
pub mod identity;
pub mod merge;
pub mod split;

pub use format::*;
pub use identity::{recipe_inputs, scene_inputs};
pub use merge::{load_for_merge, merge, MergeError, Merged};
