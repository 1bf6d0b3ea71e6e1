//! The shards of a render (`--shard K/N`): shard K renders the K-th of N
//! disjoint ranges of every pixel's sample indices and writes its sums
//! ([`SHARD_ACC`], shard.json); a merge adds the N shards' sums in shard
//! order into the image the unsharded run renders ([`merged`]).

use super::error::RenderError;
use super::outcome::{RenderRun, Rendered};
use crate::fault::Interrupted;
use crate::interrupt::Interrupt;
use crate::job::spec::RenderJob;
use crate::scene;
use lucent_render::tracer::{self, Condition, Image, NotSplittable, Settings, Stats};
use std::path::Path;

/// The accumulator file of a render shard.
pub const SHARD_ACC: &str = "render.acc";

/// Refuses what a shard of a render cannot do exactly: a stop rule other
/// than a sample count ([`Stop::shard_samples`](tracer::Stop::shard_samples)), object-weighted sampling.
pub(super) fn check_shardable(settings: &Settings) -> Result<(), RenderError> {
    let why = match settings.stop.shard_samples() {
        Ok(_) => None,
        Err(NotSplittable::NoSamples) => Some("needs a sample budget (--spp or [render] spp)"),
        Err(NotSplittable::Beside(Condition::Time)) => Some(
            "a time budget (--time-s or [render] time_s) cannot be split into shards exactly; give a sample budget (--spp) instead",
        ),
        Err(NotSplittable::Beside(_)) => Some(
            "an error target (--target-rel-error or [render] target_rel_error) depends on the whole image; give a sample budget (--spp) instead",
        ),
    };
    if let Some(why) = why {
        return Err(RenderError::NotShardable(why));
    }
    if settings.sampling != tracer::Sampling::Uniform {
        return Err(RenderError::NotShardable(
            "object-weighted sampling plans every pass from the image so far and cannot be split; use --sampling uniform",
        ));
    }
    Ok(())
}

/// The merged sums of a render's shards (added in shard order) and their counters.
pub(super) fn merged(
    shards: &[crate::job::shard::format::Shard],
    settings: &Settings,
    w: usize,
    h: usize,
) -> Result<(Image, Stats), RenderError> {
    let n = w * h;
    let mut acc = tracer::Accumulator::new(w, h);
    let mut stats = Stats::default();
    for s in shards {
        let k = s.file.shard;
        let expected = crate::job::shard::format::range(u64::from(settings.spp()), k, s.file.identity.shards);
        if s.file.range != [expected.start, expected.end] {
            return Err(RenderError::ShardRange { dir: s.dir.clone(), k, held: s.file.range, expected });
        }
        let path = s.dir.join(SHARD_ACC);
        let arrays = crate::job::shard::format::read_accumulator(&path)?;
        let get = |name: &str, len: usize| crate::job::shard::format::array(&arrays, name, len, &path);
        let (sum, sq, even) = (get("sum", 3 * n)?, get("sum_sq", 3 * n)?, get("sum_even", 3 * n)?);
        let (samples, object, board) = (get("samples", n)?, get("object_samples", n)?, get("board_samples", n)?);
        let count = (expected.end - expected.start) as f64;
        if let Some(p) = samples.iter().position(|&c| c != count) {
            return Err(RenderError::ShardSamples { path, pixel: p, samples: samples[p], count });
        }
        for p in 0..n {
            for c in 0..3 {
                acc.sum[p][c] += sum[3 * p + c];
                acc.sum_sq[p][c] += sq[3 * p + c];
                acc.sum_even[p][c] += even[3 * p + c];
            }
            acc.samples[p] += samples[p] as u32;
            acc.object_samples[p] += object[p] as u32;
            acc.board_samples[p] += board[p] as u32;
        }
        let c = |name: &str| s.file.counters.get(name).copied().unwrap_or(0);
        stats.samples += c("samples");
        stats.events += c("events");
        stats.surface_hits += c("surface_hits");
        stats.leaked_paths += c("leaked_paths");
        stats.truncated_paths += c("truncated_paths");
        stats.passes += c("passes") as u32;
        stats.wall_s += s.file.wall_s;
    }
    Ok((acc.image(), stats))
}

/// Writes a render shard's accumulator and shard.json (last: a folder with
/// a shard.json holds a complete shard).
fn write_shard(
    out: &Path,
    acc: &tracer::Accumulator,
    stats: &Stats,
    identity: crate::job::shard::format::Identity,
    k: u32,
    range: std::ops::Range<u64>,
) -> Result<(), RenderError> {
    let flat = |v: &[[f64; 3]]| v.iter().flatten().copied().collect::<Vec<f64>>();
    let counts = |v: &[u32]| v.iter().map(|&c| f64::from(c)).collect::<Vec<f64>>();
    let (sum, sq, even) = (flat(&acc.sum), flat(&acc.sum_sq), flat(&acc.sum_even));
    let (samples, object, board) = (counts(&acc.samples), counts(&acc.object_samples), counts(&acc.board_samples));
    let counters: std::collections::BTreeMap<String, u64> = [
        ("samples", stats.samples),
        ("events", stats.events),
        ("surface_hits", stats.surface_hits),
        ("leaked_paths", stats.leaked_paths),
        ("truncated_paths", stats.truncated_paths),
        ("passes", u64::from(stats.passes)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    crate::job::shard::format::write_shard_accumulator(
        &out.join(SHARD_ACC),
        &crate::job::shard::format::AccMeta::new(&identity, k, &range, &counters),
        &[
            ("sum", &sum),
            ("sum_sq", &sq),
            ("sum_even", &even),
            ("samples", &samples),
            ("object_samples", &object),
            ("board_samples", &board),
        ],
    )?;
    let file = crate::job::shard::format::ShardFile {
        identity,
        shard: k,
        range: [range.start, range.end],
        accumulators: vec![SHARD_ACC.into()],
        counters,
        wall_s: stats.wall_s,
    };
    crate::io::write_json(&out.join(crate::job::shard::format::SHARD_JSON), &file)?;
    Ok(())
}

impl RenderJob {
    /// Renders shard k of n (`--shard K/N`): its range of the samples of every
    /// pixel, tallied into `out` with shard.json (the run named by the job,
    /// [`Job::shard_identity`](crate::job::Job::shard_identity); `out` must
    /// not hold another shard).
    pub(super) fn render_shard(
        &self,
        loaded: &scene::LoadedScene,
        settings: &Settings,
        pool: &rayon::ThreadPool,
        (k, n): (u32, u32),
    ) -> Result<RenderRun, RenderError> {
        let range = crate::job::shard::format::range(u64::from(settings.spp()), k, n);
        let job = crate::job::spec::Job::Render(self.clone());
        let identity = job.shard_identity(settings.seed, format!("{} spp", settings.spp()), n)?;
        crate::job::shard::format::check_shard_out(&self.out, &identity, k)?;
        let interrupt = Interrupt::install();
        let (acc, stats) = pool.install(|| {
            tracer::render_samples(
                &loaded.scene,
                settings,
                range.start as u32..range.end as u32,
                Some(interrupt.flag()),
            )
        });
        if interrupt.requested() {
            return Ok(RenderRun {
                out: self.out.clone(),
                rendered: None,
                interrupted: Some(Interrupted(format!(
                    "shard {k}/{n} not written (a shard is merged whole or not at all)"
                ))),
            });
        }
        drop(interrupt);
        // Another shard may have finished into the same folder meanwhile.
        crate::job::shard::format::check_shard_out(&self.out, &identity, k)?;
        write_shard(&self.out, &acc, &stats, identity, k, range.clone())?;
        Ok(RenderRun {
            out: self.out.clone(),
            rendered: Some(Rendered::Shard { k, n, range, wall_s: stats.wall_s }),
            interrupted: None,
        })
    }
}
