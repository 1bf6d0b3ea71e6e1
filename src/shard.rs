//! Long runs split into shards and merged back: the accumulator and
//! `shard.json` formats, a shard's identity and the checks of a merge.
//! They live with the jobs that write and merge shards
//! ([`crate::job::shard`], its [`format`](crate::job::shard::format)) and
//! are re-exported here as `lucent::shard`.

pub use crate::job::shard::format::*;
