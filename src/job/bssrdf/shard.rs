//! The shards of a slab job (`--shard K/N`): each traces its range of the
//! path batches of every configuration and keeps the tallies
//! (`slice-I.acc` per configuration, shard.json); the merge reads them back
//! and adds them in shard order.

use super::error::BssrdfJobError as E;
use super::outcome::BssrdfRun;
use super::plan::PlannedRun;
use crate::fault::Interrupted;
use crate::interrupt::Interrupt;
use crate::job::spec::BssrdfJob;
use lucent_render::slab;
use std::path::Path;

/// The scalar tallies of a slice shard, in this order.
const SHARD_SCALARS: [&str; 8] =
    ["path_sum", "path_sq", "reflected", "transmitted", "events", "batches", "paths", "wall_s"];

/// The accumulator file of configuration `i` in a shard folder.
fn shard_acc(i: usize) -> String {
    format!("slice-{i}.acc")
}

/// A shard's tallies of one configuration as written by [`write_slice_shard`].
fn read_slice_shard(path: &Path, npix: usize) -> Result<crate::job::shard::format::Arrays, E> {
    let arrays = crate::job::shard::format::read_accumulator(path)?;
    for name in ["sum_b", "sq_b", "raw"] {
        crate::job::shard::format::array(&arrays, name, npix, path)?;
    }
    crate::job::shard::format::array(&arrays, "scalars", SHARD_SCALARS.len(), path)?;
    Ok(arrays)
}

fn write_slice_shard(path: &Path, meta: &crate::job::shard::format::AccMeta, t: &slab::SliceSums) -> Result<(), E> {
    let scalars = [
        t.path_sum,
        t.path_sq,
        t.reflected,
        t.transmitted,
        t.events as f64,
        t.batches as f64,
        t.paths as f64,
        t.wall_s,
    ];
    crate::job::shard::format::write_shard_accumulator(
        path,
        meta,
        &[("sum_b", &t.sum_b), ("sq_b", &t.sq_b), ("raw", &t.raw), ("scalars", &scalars)],
    )?;
    Ok(())
}

/// `empty` with the tallies of a shard's arrays (read by [`read_slice_shard`]).
pub(super) fn slice_sums_of(empty: &slab::SliceSums, arrays: &crate::job::shard::format::Arrays) -> slab::SliceSums {
    let get = |name: &str| arrays.iter().find(|(n, _)| n == name).map(|(_, v)| v.clone()).unwrap_or_default();
    let sc = get("scalars");
    let at = |k: usize| sc.get(k).copied().unwrap_or(0.0);
    slab::SliceSums {
        sum_b: get("sum_b"),
        sq_b: get("sq_b"),
        raw: get("raw"),
        path_sum: at(0),
        path_sq: at(1),
        reflected: at(2),
        transmitted: at(3),
        events: at(4) as u64,
        batches: at(5) as u64,
        paths: at(6) as u64,
        wall_s: at(7),
        ..empty.clone()
    }
}

/// The tallies of every shard (in shard order), one per configuration (of
/// `configs`, slices of `out_pixels` per side), each shard checked to hold
/// its range of the `total_batches`.
pub(super) fn read_merged_tallies(
    shards: &[crate::job::shard::format::Shard],
    configs: usize,
    out_pixels: usize,
    total_batches: u64,
) -> Result<Vec<Vec<crate::job::shard::format::Arrays>>, E> {
    shards
        .iter()
        .map(|s| {
            let k = s.file.shard;
            let expected = crate::job::shard::format::range(total_batches, k, s.file.identity.shards);
            if s.file.range != [expected.start, expected.end] {
                return Err(E::Refused(format!(
                    "{}: shard {k} holds batches {:?}, the run's shard {k} is {expected:?}",
                    s.dir.display(),
                    s.file.range
                )));
            }
            (0..configs)
                .map(|i| read_slice_shard(&s.dir.join(shard_acc(i)), out_pixels * out_pixels))
                .collect::<Result<Vec<_>, E>>()
        })
        .collect()
}

impl BssrdfJob {
    /// Shard k of n: its range of the `total_batches` of every
    /// configuration, tallied into `out` with shard.json (the run named by
    /// the job, [`Job::shard_identity`](crate::job::Job::shard_identity)).
    pub(super) fn run_shard(
        &self,
        configs: &[PlannedRun],
        (k, n): (u32, u32),
        total_batches: u64,
    ) -> Result<BssrdfRun, E> {
        let range = crate::job::shard::format::range(total_batches, k, n);
        let paths = self.paths.unwrap_or(0);
        let identity =
            crate::job::spec::Job::Bssrdf(self.clone()).shard_identity(self.seed, format!("{paths} paths"), n)?;
        crate::job::shard::format::check_shard_out(&self.out, &identity, k)?;
        // A second Ctrl-C or SIGTERM ends the process: the staging folder goes with it.
        let _remove_on_abort = crate::interrupt::remove_on_abort(&crate::io::StagedDir::staging_path(&self.out));
        let stage = crate::io::StagedDir::new(&self.out)?;
        let interrupt = Interrupt::install();
        let mut wall_s = 0.0;
        let mut accumulators = Vec::new();
        for (i, run) in configs.iter().enumerate() {
            let t = slab::simulate_batches(&run.setup, &run.options, range.clone(), paths, interrupt.flag())?;
            if interrupt.requested() {
                return Err(
                    Interrupted(format!("shard {k}/{n} not written (a shard is merged whole or not at all)")).into()
                );
            }
            wall_s += t.wall_s;
            let meta = crate::job::shard::format::AccMeta::new(&identity, k, &range, &Default::default());
            write_slice_shard(&stage.path().join(shard_acc(i)), &meta, &t)?;
            accumulators.push(shard_acc(i));
        }
        drop(interrupt);
        let file = crate::job::shard::format::ShardFile {
            identity,
            shard: k,
            range: [range.start, range.end],
            accumulators,
            counters: Default::default(),
            wall_s,
        };
        crate::io::write_json(&stage.path().join(crate::job::shard::format::SHARD_JSON), &file)?;
        // Another shard may have finished into the same folder meanwhile.
        crate::job::shard::format::check_shard_out(&self.out, &file.identity, k)?;
        stage.commit(|n| {
            n == crate::job::shard::format::SHARD_JSON || (n.starts_with("slice-") && n.ends_with(".acc"))
        })?;
        let line = format!(
            "shard {k}/{n}: path batches {}..{} of {total_batches} in {wall_s:.1} s → {}",
            range.start,
            range.end,
            self.out.display()
        );
        Ok(BssrdfRun { lines: vec![line], interrupted_at: None })
    }
}
