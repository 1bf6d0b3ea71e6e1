//! `lucent merge SHARD… --out DIR` (the merge itself is the library's,
//! [`crate::job::shard::merge`]: the run's job read out of the shards'
//! `shard.json`, checked, merged by the job; the format and the checks of
//! the shard folders are in [`crate::shard`]), and `lucent bench shard`.

use anyhow::{bail, Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct MergeArgs {
    /// The shard folders of one run (each written with --shard K/N), all N of them.
    #[arg(required = true, num_args = 1..)]
    pub shards: Vec<PathBuf>,
    /// Output folder: what the unsharded command writes.
    #[arg(long)]
    pub out: PathBuf,
}

/// Merges the shard folders `shards` of one run into `out`
/// ([`crate::job::shard::merge`]) and prints what the unsharded command
/// prints; a merge stopped by Ctrl-C fails as interrupted.
pub fn merge(shards: &[PathBuf], out: &Path) -> Result<()> {
    use crate::job::{MergeError, Merged};
    let ctx = crate::job::Context::default();
    let merged =
        crate::job::merge(&ctx, shards, out, &mut super::render::Terminal::new(true)).map_err(|e| match e {
            MergeError::Bssrdf(e) => super::bssrdf::job_error(e),
            MergeError::Optics(e) => super::common::optics_error(e),
            e => e.into(),
        })?;
    if let Merged::Render(done) = merged {
        return super::render::finish(done);
    }
    for line in merged.summary() {
        println!("{line}");
    }
    match merged {
        Merged::Bssrdf(done) => Ok(done.finished()?),
        _ => Ok(()),
    }
}

/// The large run `lucent bench shard` projects.
#[derive(Debug, Clone, Copy)]
pub struct Projection {
    pub megapixels: f64,
    pub nodes: u32,
    pub spp: u32,
}

/// User and system CPU seconds of this process's finished children so far.
#[cfg(unix)]
fn children_cpu_s() -> f64 {
    let mut u = std::mem::MaybeUninit::<libc::rusage>::zeroed();
    // SAFETY: getrusage fills the rusage it is given and only reads `who`.
    if unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, u.as_mut_ptr()) } != 0 {
        return f64::NAN;
    }
    // SAFETY: initialised by the successful call above (and zeroed before).
    let u = unsafe { u.assume_init() };
    let s = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    s(u.ru_utime) + s(u.ru_stime)
}

#[cfg(not(unix))]
fn children_cpu_s() -> f64 {
    f64::NAN
}

/// Wall and CPU (user + system) seconds of runs.
#[derive(Debug, Clone, Copy, Default)]
struct Time {
    wall_s: f64,
    cpu_s: f64,
}

impl std::ops::Add for Time {
    type Output = Time;
    fn add(self, o: Time) -> Time {
        Time { wall_s: self.wall_s + o.wall_s, cpu_s: self.cpu_s + o.cpu_s }
    }
}

/// Runs `lucent ARGS` (this binary) quietly; its wall and CPU time.
fn timed(exe: &Path, args: &[String]) -> Result<Time> {
    let (start, cpu) = (std::time::Instant::now(), children_cpu_s());
    let o = std::process::Command::new(exe)
        .args(args)
        .output()
        .with_context(|| format!("cannot start {}", exe.display()))?;
    if !o.status.success() {
        bail!("`lucent {}` failed: {}", args.join(" "), String::from_utf8_lossy(&o.stderr).trim());
    }
    Ok(Time { wall_s: start.elapsed().as_secs_f64(), cpu_s: children_cpu_s() - cpu })
}

fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// The commands `lucent bench shard` times: `exe` rendering `scene` at
/// `size` and `spp` into folders under `tmp`, as one process or `shards`.
struct BenchRun<'a> {
    exe: &'a Path,
    scene: &'a Path,
    tmp: &'a Path,
    size: &'a str,
    spp: u32,
    shards: u32,
}

/// The times of [`BenchRun::rounds`].
struct Rounds {
    /// Median of three: `lucent --version`.
    startup: Time,
    /// Median of three: a render of 8 × 6 pixels at 1 spp.
    fixed: Time,
    /// Per round: the render as one process.
    one: Vec<Time>,
    /// Per round: the shards and their merge.
    sharded: Vec<Time>,
    /// Per round: each shard.
    shard_t: Vec<Vec<Time>>,
    /// Per round: the merge.
    merge_t: Vec<Time>,
}

impl BenchRun<'_> {
    /// The render's arguments into `out` at `spp` and `size`.
    fn base(&self, out: &Path, spp: u32, size: &str) -> Vec<String> {
        let mut v: Vec<String> = vec!["render".into(), self.scene.display().to_string(), "--quiet".into()];
        v.extend(["--size".into(), size.into(), "--spp".into(), spp.to_string(), "--seed".into(), "1".into()]);
        v.extend(["--out".into(), out.display().to_string()]);
        v
    }

    /// The median of three runs of a short command.
    fn median3(&self, args: &[String]) -> Result<Time> {
        let t = [timed(self.exe, args)?, timed(self.exe, args)?, timed(self.exe, args)?];
        Ok(Time { wall_s: median(&t.map(|t| t.wall_s)), cpu_s: median(&t.map(|t| t.cpu_s)) })
    }

    /// The shards one after the other, then their merge: each shard's time
    /// and the merge's.
    fn run_sharded(&self) -> Result<(Vec<Time>, Time)> {
        let (spp, size, shards) = (self.spp, self.size, self.shards);
        let mut times = Vec::new();
        let mut dirs = Vec::new();
        for k in 0..shards {
            let d = self.tmp.join(format!("shard-{k}"));
            let mut a = self.base(&d, spp, size);
            a.extend(["--shard".into(), format!("{k}/{shards}")]);
            times.push(timed(self.exe, &a)?);
            dirs.push(d.display().to_string());
        }
        let mut m = vec!["merge".to_string()];
        m.extend(dirs);
        let merged = self.tmp.join("merged");
        let _ = std::fs::remove_dir_all(&merged);
        m.extend(["--out".into(), merged.display().to_string()]);
        Ok((times, timed(self.exe, &m)?))
    }

    /// The fixed costs, then `repeats` rounds of one process and the
    /// shards with their merge, alternating which comes first.
    fn rounds(&self, repeats: u32) -> Result<Rounds> {
        // Fixed cost per process: start-up (the dynamic loader, 150 shared
        // libraries through OpenCV), then scene loading (Lorenz–Mie phase
        // tables, the environment map) and writing.
        let startup = self.median3(&["--version".to_string()])?;
        let fixed = self.median3(&self.base(&self.tmp.join("fixed"), 1, "8x6"))?;
        let mut one = Vec::new();
        let mut sharded = Vec::new();
        let mut shard_t: Vec<Vec<Time>> = Vec::new();
        let mut merge_t = Vec::new();
        for round in 0..repeats {
            let run_one = || timed(self.exe, &self.base(&self.tmp.join("one"), self.spp, self.size));
            let (o, (s, m)) = if round % 2 == 0 {
                let o = run_one()?;
                (o, self.run_sharded()?)
            } else {
                let s = self.run_sharded()?;
                (run_one()?, s)
            };
            one.push(o);
            sharded.push(s.iter().fold(m, |a, b| a + *b));
            shard_t.push(s);
            merge_t.push(m);
        }
        Ok(Rounds { startup, fixed, one, sharded, shard_t, merge_t })
    }
}

/// `lucent bench shard`: the scene rendered as one process and as
/// `shards` shard processes run one after the other (each on all cores)
/// plus their merge, each as a child process of this binary (start-up,
/// scene loading and output included), in `repeats` rounds that alternate
/// which comes first (on a shared machine the load drifts; the overhead is
/// taken over the sums of all rounds, in wall and in CPU time); the fixed
/// cost per process and its start-up part; and a projection from the
/// measured rates for a render of `p.megapixels` at `p.spp` on `p.nodes`
/// nodes like this machine (one shard per node).
pub fn bench(
    scene: &Path,
    size: &str,
    spp: u32,
    shards: u32,
    repeats: u32,
    lucent: Option<PathBuf>,
    p: Projection,
) -> Result<()> {
    let exe = match lucent {
        Some(e) if e.is_file() => e,
        Some(e) => bail!("--lucent {}: no such binary", e.display()),
        None => std::env::current_exe().context("cannot find the lucent binary")?,
    };
    let (w, h) = super::common::parse_size(size)?;
    if shards < 2 || shards > spp {
        bail!("--shards {shards}: must lie in 2 … --spp ({spp})");
    }
    if !(1..=20).contains(&repeats) {
        bail!("--repeats {repeats}: must lie in 1 … 20");
    }
    let tmp = std::env::temp_dir().join(format!("lucent-bench-shard-{}", std::process::id()));
    let result = (|| -> Result<serde_json::Value> {
        let run = BenchRun { exe: &exe, scene, tmp: &tmp, size, spp, shards };
        let Rounds { startup, fixed, one, sharded, shard_t, merge_t } = run.rounds(repeats)?;
        let total = |v: &[Time]| v.iter().fold(Time::default(), |a, b| a + *b);
        let (one_sum, sharded_sum) = (total(&one), total(&sharded));
        let overhead = sharded_sum.wall_s / one_sum.wall_s - 1.0;
        let overhead_cpu = sharded_sum.cpu_s / one_sum.cpu_s - 1.0;
        let per_round: Vec<f64> = one.iter().zip(&sharded).map(|(o, s)| s.wall_s / o.wall_s - 1.0).collect();
        let one_s = median(&one.iter().map(|t| t.wall_s).collect::<Vec<_>>());
        let merge_s = median(&merge_t.iter().map(|t| t.wall_s).collect::<Vec<_>>());
        let shard_s: Vec<f64> =
            (0..shards as usize).map(|k| median(&shard_t.iter().map(|r| r[k].wall_s).collect::<Vec<_>>())).collect();
        let fixed_s = fixed.wall_s;
        // Rates: pixel-samples per second of the work itself; merge seconds per pixel and shard.
        let pixels = (w * h) as f64;
        let rate = pixels * f64::from(spp) / (one_s - fixed_s).max(1e-9);
        let merge_per_px_shard = (merge_s - fixed_s).max(0.0) / (pixels * f64::from(shards));
        let big_px = p.megapixels * 1e6;
        let per_node_s = fixed_s + big_px * f64::from(p.spp) / f64::from(p.nodes) / rate;
        let merge_big_s = fixed_s + merge_per_px_shard * big_px * f64::from(p.nodes);
        let one_node_s = fixed_s + big_px * f64::from(p.spp) / rate;
        eprintln!(
            "{w}×{h}, {spp} spp, {repeats} round(s): one process {:.2} s wall, {:.2} s CPU; {shards} shards one after the other + merge {:.2} s wall, {:.2} s CPU (shards {:.2} s each, merge {merge_s:.2} s, medians): overhead {:+.1} % wall (per round {}), {:+.1} % CPU",
            one_sum.wall_s / f64::from(repeats),
            one_sum.cpu_s / f64::from(repeats),
            sharded_sum.wall_s / f64::from(repeats),
            sharded_sum.cpu_s / f64::from(repeats),
            shard_s.iter().sum::<f64>() / f64::from(shards),
            100.0 * overhead,
            per_round.iter().map(|o| format!("{:+.1} %", 100.0 * o)).collect::<Vec<_>>().join(", "),
            100.0 * overhead_cpu,
        );
        eprintln!(
            "fixed cost per process {fixed_s:.2} s wall, {:.3} s CPU: start-up {:.2} s wall, {:.3} s CPU; loading and writing the rest",
            fixed.cpu_s, startup.wall_s, startup.cpu_s
        );
        eprintln!(
            "projection: {:.0} MP at {} spp on {} nodes like this one: {:.0} s per shard + {:.0} s merge = {:.0} s (one node: {:.0} s, {:.1}× faster)",
            p.megapixels,
            p.spp,
            p.nodes,
            per_node_s,
            merge_big_s,
            per_node_s + merge_big_s,
            one_node_s,
            one_node_s / (per_node_s + merge_big_s)
        );
        Ok(serde_json::json!({
            "scene": scene.display().to_string(),
            "lucent": exe.display().to_string(),
            "size": [w, h],
            "spp": spp,
            "threads": rayon::current_num_threads(),
            "repeats": repeats,
            "one_process_s": one_s,
            "shards": shards,
            "shard_s": shard_s,
            "merge_s": merge_s,
            "sharded_total_s": sharded_sum.wall_s / f64::from(repeats),
            "overhead": overhead,
            "overhead_per_round": per_round,
            "cpu": {
                "one_process_s": one_sum.cpu_s / f64::from(repeats),
                "sharded_total_s": sharded_sum.cpu_s / f64::from(repeats),
                "overhead": overhead_cpu,
                "fixed_per_process_s": fixed.cpu_s,
                "startup_s": startup.cpu_s,
            },
            "fixed_per_process_s": fixed_s,
            "startup_s": startup.wall_s,
            "pixel_samples_per_s": rate,
            "projection": {
                "megapixels": p.megapixels,
                "spp": p.spp,
                "nodes": p.nodes,
                "per_shard_s": per_node_s,
                "merge_s": merge_big_s,
                "total_s": per_node_s + merge_big_s,
                "one_node_s": one_node_s,
                "assumes": "one shard per node, each node as fast as this machine, the merge's time per pixel and shard as measured here, file transfer not counted",
            },
        }))
    })();
    let _ = std::fs::remove_dir_all(&tmp);
    println!("{}", serde_json::to_string_pretty(&result?)?);
    Ok(())
}
