//! `--shard K/N` of `lucent render` and `lucent bssrdf`, and `lucent merge
//! SHARD… --out DIR` (the format and the checks are in [`crate::shard`]).
//!
//! A shard's identity is the command line it was given (without `--shard`,
//! `--out`, `--threads` and `--quiet`), the folder it ran in, and a SHA-256
//! of that command line and of every input file it names (a scene or
//! recipe and the files *they* name). The merge parses the same command
//! line again in the same folder, checks the input files still hash to the
//! same value, adds the shards' sums in shard order and writes what the
//! unsharded command writes.

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
            if !p.is_file() {
                continue;
            }
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
    argv.extend(["--out".to_string(), out.display().to_string(), "--quiet".to_string()]);
    let cli = super::Cli::try_parse_from(&argv).with_context(|| {
        format!("{}: cannot parse its command line", shards[0].dir.join(shard::SHARD_JSON).display())
    })?;
    match cli.command {
        super::Command::Render(r) => super::render::run_from(r, Some(&shards)),
        super::Command::Bssrdf(b) if b.command.is_none() => super::bssrdf::simulate_from(b.run, Some(&shards)),
        _ => bail!("{}: `lucent {}` is not a command with shards", shards[0].dir.display(), id.command),
    }
}
