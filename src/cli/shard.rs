//! `--shard K/N` of `lucent render`, `lucent bssrdf` and `lucent optics
//! --uncertainty N`, and `lucent merge SHARD… --out DIR` (the format and
//! the checks are in [`crate::shard`]).
//!
//! A shard's identity is the command line it was given (without `--shard`,
//! `--out`, `--threads` and `--quiet`), the folder it ran in, and a SHA-256
//! of that command line and of every input file it names (a scene or
//! recipe and the files *they* name; for a folder, the recipes in it). The
//! merge parses the same command line again in the same folder, checks the
//! input files still hash to the same value, adds the shards' sums (for an
//! uncertainty run: puts their draws together) in shard order and writes
//! what the unsharded command writes.

use crate::shard::{self, Identity};
use anyhow::{bail, Context, Result};
use clap::{Args, Parser};
use sha2::{Digest, Sha256};
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

/// Arguments that do not change a result (and `--shard`, `--out`, which differ per shard).
const NOT_IDENTITY: [(&str, bool); 4] = [("--shard", true), ("--out", true), ("--threads", true), ("--quiet", false)];

/// This process's command line after the binary's name, without the arguments of [`NOT_IDENTITY`].
fn identity_args() -> Vec<String> {
    let mut out = Vec::new();
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let flag = NOT_IDENTITY.iter().find(|(f, _)| a == *f || a.starts_with(&format!("{f}=")));
        match flag {
            Some((f, true)) if a == *f => {
                args.next();
            }
            Some(_) => {}
            None => out.push(a),
        }
    }
    out
}

/// SHA-256 of the arguments and of every existing file an argument names
/// (also after a `kind:` prefix, as in `measured:fit.json`), a TOML file
/// with the files it names.
pub fn inputs_sha256(args: &[String]) -> Result<String> {
    let mut h = Sha256::new();
    let mut files: Vec<PathBuf> = Vec::new();
    for a in args {
        h.update(a.as_bytes());
        h.update([0u8]);
        for candidate in [Some(a.as_str()), a.split_once(':').map(|(_, p)| p)].into_iter().flatten() {
            let p = Path::new(candidate);
            // A folder of recipes (`lucent optics FOLDER`): the recipes in it.
            let listed: Vec<PathBuf> = if p.is_dir() {
                let mut v: Vec<PathBuf> = std::fs::read_dir(p)
                    .with_context(|| format!("{}: cannot list folder", p.display()))?
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|f| f.is_file() && f.extension().is_some_and(|e| e == "toml"))
                    .collect();
                v.sort();
                v
            } else if p.is_file() {
                vec![p.to_path_buf()]
            } else {
                continue;
            };
            for p in listed {
                let p = p.as_path();
                let mut named = vec![p.to_path_buf()];
                if p.extension().is_some_and(|e| e == "toml") {
                    named.extend(crate::pipeline::scene_inputs(p));
                    named.extend(crate::pipeline::recipe_inputs(p));
                }
                for f in named {
                    if !files.contains(&f) {
                        files.push(f);
                    }
                }
            }
        }
    }
    for f in &files {
        let bytes = std::fs::read(f).with_context(|| format!("{}: cannot read", f.display()))?;
        h.update(f.to_string_lossy().as_bytes());
        h.update([0u8]);
        h.update(Sha256::digest(&bytes));
    }
    Ok(format!("{:x}", h.finalize()))
}

/// The identity of the run this process is a shard of.
pub fn identity(seed: u64, budget: String, shards: u32) -> Result<Identity> {
    let args = identity_args();
    Ok(Identity {
        command: args.first().cloned().unwrap_or_default(),
        inputs_sha256: inputs_sha256(&args)?,
        args,
        cwd: std::env::current_dir().context("cannot read the current folder")?,
        lucent_version: env!("CARGO_PKG_VERSION").into(),
        seed,
        budget,
        shards,
    })
}

/// Runs `lucent merge`.
pub fn merge(a: MergeArgs) -> Result<()> {
    let dirs: Vec<PathBuf> = a
        .shards
        .iter()
        .map(|d| std::path::absolute(d).with_context(|| format!("{}: cannot resolve", d.display())))
        .collect::<Result<_>>()?;
    let shards = shard::load_shards(&dirs)?;
    let id = shards[0].file.identity.clone();
    if id.lucent_version != env!("CARGO_PKG_VERSION") {
        bail!(
            "{}: made by lucent {}, this is {}: merge with the version that made the shards",
            shards[0].dir.display(),
            id.lucent_version,
            env!("CARGO_PKG_VERSION")
        );
    }
    let out = std::path::absolute(&a.out).with_context(|| format!("{}: cannot resolve", a.out.display()))?;
    if let Some(s) = shards.iter().find(|s| out.starts_with(&s.dir) || s.dir.starts_with(&out)) {
        bail!("--out {}: must not be or contain a shard folder ({})", out.display(), s.dir.display());
    }
    std::env::set_current_dir(&id.cwd)
        .with_context(|| format!("{}: cannot enter the folder the shards ran in", id.cwd.display()))?;
    if inputs_sha256(&id.args)? != id.inputs_sha256 {
        bail!(
            "{}: the input files of `lucent {}` changed since the shards were made (run in {}); rerun the shards",
            shards[0].dir.join(shard::SHARD_JSON).display(),
            id.args.join(" "),
            id.cwd.display()
        );
    }
    let mut argv = vec!["lucent".to_string()];
    argv.extend(id.args.iter().cloned());
    argv.extend(["--out".to_string(), out.display().to_string()]);
    if id.command != "optics" {
        argv.push("--quiet".to_string());
    }
    let cli = super::Cli::try_parse_from(&argv).with_context(|| {
        format!("{}: cannot parse its command line", shards[0].dir.join(shard::SHARD_JSON).display())
    })?;
    match cli.command {
        super::Command::Render(r) => super::render::run_from(r, Some(&shards)),
        super::Command::Bssrdf(b) if b.command.is_none() => super::bssrdf::simulate_from(b.run, Some(&shards)),
        super::Command::Optics(o) if o.uncertainty.is_some() => super::optics_from(o, Some(&shards)),
        _ => bail!("{}: `lucent {}` is not a command with shards", shards[0].dir.display(), id.command),
    }
}

/// The large run `lucent bench shard` projects.
#[derive(Debug, Clone, Copy)]
pub struct Projection {
    pub megapixels: f64,
    pub nodes: u32,
    pub spp: u32,
}

/// Runs `lucent ARGS` (this binary) quietly; its wall time in seconds.
fn timed(exe: &Path, args: &[String]) -> Result<f64> {
    let start = std::time::Instant::now();
    let o = std::process::Command::new(exe)
        .args(args)
        .output()
        .with_context(|| format!("cannot start {}", exe.display()))?;
    if !o.status.success() {
        bail!("`lucent {}` failed: {}", args.join(" "), String::from_utf8_lossy(&o.stderr).trim());
    }
    Ok(start.elapsed().as_secs_f64())
}

/// `lucent bench shard`: the scene rendered as one process and as
/// `shards` shard processes run one after the other (each on all cores)
/// plus their merge, each as a child process of this binary (start-up,
/// scene loading and output included); the overhead of sharding, and a
/// projection from the measured rates for a render of `p.megapixels` at
/// `p.spp` on `p.nodes` nodes like this machine (one shard per node).
pub fn bench(scene: &Path, size: &str, spp: u32, shards: u32, p: Projection) -> Result<()> {
    let exe = std::env::current_exe().context("cannot find the lucent binary")?;
    let (w, h) = super::render::parse_size(size)?;
    if shards < 2 || shards > spp {
        bail!("--shards {shards}: must lie in 2 … --spp ({spp})");
    }
    let tmp = std::env::temp_dir().join(format!("lucent-bench-shard-{}", std::process::id()));
    let base = |out: &Path, spp: u32, size: &str| -> Vec<String> {
        let mut v: Vec<String> = vec!["render".into(), scene.display().to_string(), "--quiet".into()];
        v.extend(["--size".into(), size.into(), "--spp".into(), spp.to_string(), "--seed".into(), "1".into()]);
        v.extend(["--out".into(), out.display().to_string()]);
        v
    };
    // The median of three runs of a short command (the machine may be shared).
    let median3 = |args: &[String]| -> Result<f64> {
        let mut t = [timed(&exe, args)?, timed(&exe, args)?, timed(&exe, args)?];
        t.sort_by(f64::total_cmp);
        Ok(t[1])
    };
    let result = (|| -> Result<serde_json::Value> {
        // Fixed cost per process: start-up (the dynamic loader, 150 shared
        // libraries through OpenCV), then scene loading (Lorenz–Mie phase
        // tables, the environment map) and writing.
        let startup_s = median3(&["--version".to_string()])?;
        let fixed_s = median3(&base(&tmp.join("fixed"), 1, "8x6"))?;
        let one_s = timed(&exe, &base(&tmp.join("one"), spp, size))?;
        let mut shard_s = Vec::new();
        let mut dirs = Vec::new();
        for k in 0..shards {
            let d = tmp.join(format!("shard-{k}"));
            let mut a = base(&d, spp, size);
            a.extend(["--shard".into(), format!("{k}/{shards}")]);
            shard_s.push(timed(&exe, &a)?);
            dirs.push(d.display().to_string());
        }
        let mut m = vec!["merge".to_string()];
        m.extend(dirs);
        m.extend(["--out".into(), tmp.join("merged").display().to_string()]);
        let merge_s = timed(&exe, &m)?;
        let sharded_s: f64 = shard_s.iter().sum::<f64>() + merge_s;
        let overhead = sharded_s / one_s - 1.0;
        // Rates: pixel-samples per second of the work itself; merge seconds per pixel and shard.
        let pixels = (w * h) as f64;
        let rate = pixels * f64::from(spp) / (one_s - fixed_s).max(1e-9);
        let merge_per_px_shard = (merge_s - fixed_s).max(0.0) / (pixels * f64::from(shards));
        let big_px = p.megapixels * 1e6;
        let per_node_s = fixed_s + big_px * f64::from(p.spp) / f64::from(p.nodes) / rate;
        let merge_big_s = fixed_s + merge_per_px_shard * big_px * f64::from(p.nodes);
        let one_node_s = fixed_s + big_px * f64::from(p.spp) / rate;
        eprintln!(
            "{w}×{h}, {spp} spp: one process {one_s:.2} s; {shards} shards one after the other {:.2} s ({:.2} s each) + merge {merge_s:.2} s = {sharded_s:.2} s: overhead {:+.1} % ({fixed_s:.2} s fixed per process: {startup_s:.2} s start-up, {:.2} s loading and writing)",
            shard_s.iter().sum::<f64>(),
            shard_s.iter().sum::<f64>() / f64::from(shards),
            100.0 * overhead,
            (fixed_s - startup_s).max(0.0)
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
            "size": [w, h],
            "spp": spp,
            "threads": rayon::current_num_threads(),
            "one_process_s": one_s,
            "shards": shards,
            "shard_s": shard_s,
            "merge_s": merge_s,
            "sharded_total_s": sharded_s,
            "overhead": overhead,
            "fixed_per_process_s": fixed_s,
            "startup_s": startup_s,
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
