//! Where a stage's long commands run: on this machine, on a Slurm cluster
//! as job arrays, or written out as batch scripts (Slurm) or manifests
//! (Kubernetes Indexed Jobs) for someone to submit.
//!
//! A **long command** is a render job with a sample budget and uniform
//! sampling, or a BSSRDF slice job with a path budget and no other stop
//! rule: the commands that `--shard K/N` can split exactly
//! ([`crate::shard`]), told from the job's type and its stop rule
//! ([`not_shardable`] asks [`Stop::shard_samples`]), never from how a
//! command line spells them. With
//! `[executor] shards = N` (N > 1) such a job becomes N shards: shard K is
//! the typed job with `shard` K/N writing into `OUT/.lucent-shards/ID/K`
//! (ID from the typed job, [`Job::identity_sha256`], outside every stage
//! folder), written as the job file `OUT/.lucent-shards/ID/job-K.json`
//! beside the shard folders, which the Slurm array task or Kubernetes pod
//! of index K runs (`lucent job run`); `lucent merge` then writes the job's
//! own output folder. The stage folders, manifests
//! and keys are those of the local executor: the same jobs are recorded,
//! and the shard folders are removed after the merge. Every other job runs
//! on this machine, in the `lucent run` process.
//!
//! ```toml
//! [executor]
//! kind = "slurm"          # or "local" (default)
//! shards = 8              # per long command
//! partition = "compute"
//! account = "optics-lab"
//! time_limit = "02:00:00" # per shard, Slurm's formats (MM, HH:MM:SS, D-HH:MM, …)
//! cpus_per_task = 16
//! sbatch = ["--mem=8G"]   # more sbatch options, one per line of the script
//! setup = ["module load rust"]  # shell lines before lucent runs
//! retries = 2             # resubmissions of a failed shard
//! image = "registry.example.org/lucent:0.1"  # container image of --emit k8s
//! ```

use crate::job::Job;
use lucent_render::stop::{Condition, NotSplittable, Stop};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};
use thiserror::Error;

/// `[executor]` as typed.
#[derive(Debug, Clone, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ExecutorSection {
    pub kind: Option<String>,
    pub shards: Option<u32>,
    pub partition: Option<String>,
    pub account: Option<String>,
    pub time_limit: Option<String>,
    pub cpus_per_task: Option<u32>,
    pub sbatch: Option<Vec<String>>,
    pub setup: Option<Vec<String>>,
    pub retries: Option<u32>,
    pub image: Option<String>,
}

/// Where long commands run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Kind {
    Local,
    Slurm,
}

/// The validated `[executor]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Executor {
    pub kind: Kind,
    pub shards: u32,
    pub partition: Option<String>,
    pub account: Option<String>,
    pub time_limit: Option<String>,
    pub cpus_per_task: Option<u32>,
    pub sbatch: Vec<String>,
    pub setup: Vec<String>,
    pub retries: u32,
    pub image: String,
}

impl Default for Executor {
    fn default() -> Self {
        Self {
            kind: Kind::Local,
            shards: 1,
            partition: None,
            account: None,
            time_limit: None,
            cpus_per_task: None,
            sbatch: Vec::new(),
            setup: Vec::new(),
            retries: 2,
            image: "lucent:latest".into(),
        }
    }
}

/// The most shards per command.
pub const MAX_SHARDS: u32 = 10_000;
/// The most resubmissions of a failed shard.
pub const MAX_RETRIES: u32 = 10;

/// A bad `[executor]` key: which and why.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("[executor] {key}: {reason}")]
pub struct ExecutorKeyError {
    pub key: &'static str,
    pub reason: String,
}

/// A Slurm time limit: minutes, MM:SS, HH:MM:SS, D-HH, D-HH:MM or D-HH:MM:SS.
fn valid_time_limit(t: &str) -> bool {
    let digits = |s: &str| !s.is_empty() && s.len() <= 6 && s.bytes().all(|b| b.is_ascii_digit());
    let (days, rest) = match t.split_once('-') {
        Some((d, r)) => (Some(d), r),
        None => (None, t),
    };
    if days.is_some_and(|d| !digits(d)) {
        return false;
    }
    let parts: Vec<&str> = rest.split(':').collect();
    parts.len() <= 3 && parts.iter().all(|p| digits(p))
}

/// A value that goes into a script as one word: no whitespace, quotes or shell characters.
fn plain_word(s: &str) -> bool {
    !s.is_empty() && s.chars().all(|c| c.is_ascii_alphanumeric() || "-_.,:/@+=".contains(c))
}

impl Executor {
    /// Checks `[executor]`.
    pub fn from_section(s: &ExecutorSection) -> Result<Self, ExecutorKeyError> {
        let bad = |key: &'static str, reason: String| ExecutorKeyError { key, reason };
        let mut e = Executor::default();
        if let Some(k) = &s.kind {
            e.kind = match k.as_str() {
                "local" => Kind::Local,
                "slurm" => Kind::Slurm,
                other => return Err(bad("kind", format!("{other:?}: expected \"local\" or \"slurm\""))),
            };
        }
        if let Some(n) = s.shards {
            if !(1..=MAX_SHARDS).contains(&n) {
                return Err(bad("shards", format!("{n}: must lie in 1 … {MAX_SHARDS}")));
            }
            e.shards = n;
        }
        for (key, v, slot) in [
            ("partition", &s.partition, &mut e.partition),
            ("account", &s.account, &mut e.account),
            ("image", &s.image, &mut None),
        ] {
            if let Some(v) = v {
                if !plain_word(v) {
                    return Err(bad(key, format!("{v:?}: one word of letters, digits and -_.,:/@+= expected")));
                }
                *slot = Some(v.clone());
            }
        }
        if let Some(i) = &s.image {
            e.image = i.clone();
        }
        if let Some(t) = &s.time_limit {
            if !valid_time_limit(t) {
                return Err(bad(
                    "time_limit",
                    format!("{t:?}: Slurm's formats are MM, MM:SS, HH:MM:SS, D-HH, D-HH:MM, D-HH:MM:SS"),
                ));
            }
            e.time_limit = Some(t.clone());
        }
        if let Some(c) = s.cpus_per_task {
            if !(1..=1024).contains(&c) {
                return Err(bad("cpus_per_task", format!("{c}: must lie in 1 … 1024")));
            }
            e.cpus_per_task = Some(c);
        }
        for line in s.sbatch.iter().flatten() {
            if !line.starts_with("--") || line.contains(['\n', '\r']) || line.len() > 500 {
                return Err(bad(
                    "sbatch",
                    format!("{line:?}: one sbatch option per entry, starting with --, e.g. \"--mem=8G\""),
                ));
            }
            if ["--array", "--output", "--error", "--dependency", "--parsable"].iter().any(|o| line.starts_with(o)) {
                return Err(bad("sbatch", format!("{line:?}: lucent sets this option itself")));
            }
        }
        e.sbatch = s.sbatch.clone().unwrap_or_default();
        for line in s.setup.iter().flatten() {
            if line.contains(['\n', '\r']) {
                return Err(bad("setup", format!("{line:?}: one shell line per entry")));
            }
        }
        e.setup = s.setup.clone().unwrap_or_default();
        if let Some(r) = s.retries {
            if r > MAX_RETRIES {
                return Err(bad("retries", format!("{r}: at most {MAX_RETRIES}")));
            }
            e.retries = r;
        }
        Ok(e)
    }
}

/// A long command split into shards.
#[derive(Debug, Clone, PartialEq)]
pub struct Sharded {
    /// The job, writing into `out` (not quiet, no shard).
    pub job: Job,
    /// The job's output folder: what the merge writes.
    pub out: PathBuf,
    pub shards: u32,
    /// Where the shard folders go: `K` under it for shard K, beside it
    /// shard K's job file `job-K.json` ([`Sharded::job_file`]).
    pub dir: PathBuf,
}

impl Sharded {
    /// The shard folders in order.
    pub fn shard_dirs(&self) -> Vec<PathBuf> {
        (0..self.shards).map(|k| self.dir.join(k.to_string())).collect()
    }

    /// `render` or `bssrdf`: the command the job stands for.
    pub fn command_name(&self) -> &'static str {
        self.job.command_name()
    }

    /// The job's command line without `--out` (for log lines and messages;
    /// the shards run their job files).
    pub fn label(&self) -> String {
        let mut kept = Vec::new();
        let mut it = self.job.to_args().into_iter();
        while let Some(a) = it.next() {
            if a == "--out" {
                it.next();
            } else {
                kept.push(a);
            }
        }
        kept.join(" ")
    }

    /// Shard K's job: the job with `shard` K/N, writing quietly into `DIR/K`.
    pub fn shard_job(&self, k: u32) -> Job {
        let (spec, out) = (Some(crate::job::shard::ShardSpec { k, n: self.shards }), self.dir.join(k.to_string()));
        match &self.job {
            Job::Render(r) => Job::Render(crate::job::RenderJob { shard: spec, out, quiet: true, ..r.clone() }),
            Job::Bssrdf(b) => Job::Bssrdf(crate::job::BssrdfJob { shard: spec, out, quiet: true, ..b.clone() }),
            other => other.clone(),
        }
    }

    /// `DIR/job-K.json`, shard K's job file (`K` a number or a shell word,
    /// e.g. "$SLURM_ARRAY_TASK_ID"), beside the shard folders, never inside one.
    pub fn job_file(&self, k: &str) -> PathBuf {
        self.dir.join(format!("job-{k}.json"))
    }

    /// Writes every shard's job file ([`Sharded::shard_job`] as JSON, the
    /// format `lucent job run` reads), creating `DIR`.
    pub fn write_job_files(&self) -> Result<(), crate::io::WriteError> {
        for k in 0..self.shards {
            crate::io::write_json(&self.job_file(&k.to_string()), &self.shard_job(k))?;
        }
        Ok(())
    }

    /// `lucent job run DIR/job-K.json` with `K` given as a shell word (e.g. "$SLURM_ARRAY_TASK_ID").
    pub fn shard_command(&self, k: &str) -> Vec<String> {
        vec!["job".into(), "run".into(), self.job_file(k).display().to_string()]
    }

    /// `lucent merge DIR/0 … --out OUT`.
    pub fn merge_command(&self) -> Vec<String> {
        let mut v = vec!["merge".to_string()];
        v.extend(self.shard_dirs().iter().map(|d| d.display().to_string()));
        v.extend(["--out".into(), self.out.display().to_string()]);
        v
    }

    /// Whether every shard folder holds a finished shard.
    pub fn done(&self) -> Vec<bool> {
        self.shard_dirs().iter().map(|d| d.join(crate::shard::SHARD_JSON).is_file()).collect()
    }
}

/// Why a scene file's render cannot be split into shards (a time budget,
/// an error target, object-weighted sampling), `None` when it can.
pub(crate) fn scene_unshardable(scene: &Path) -> Option<String> {
    let name = scene.display();
    let Ok(text) = crate::io::read_text(scene) else { return Some(format!("{name} cannot be read")) };
    let Ok(f) = crate::scene::parse(&text, scene) else { return Some(format!("{name} is not a scene file")) };
    let r = &f.render;
    // A scene without a sample count leaves it to the job (or the default).
    match r.stop().shard_samples() {
        Err(NotSplittable::Beside(Condition::Time)) => {
            return Some(format!("{name} sets [render] time_s (a time budget cannot be split exactly)"));
        }
        Err(NotSplittable::Beside(_)) => {
            return Some(format!("{name} sets [render] target_rel_error (an error target cannot be split exactly)"));
        }
        Ok(_) | Err(NotSplittable::NoSamples) => {}
    }
    if r.sampling.is_some_and(|s| s != crate::scene::SamplingKey::Uniform) {
        Some(format!("{name} sets [render] sampling other than uniform (shards sample uniformly)"))
    } else {
        None
    }
}

/// Why a job's stop rule `stop` does not split exactly into shards
/// ([`Stop::shard_samples`]), said with the job's flags: its sample count
/// `flag` of `unit`s. `None` when it splits.
fn stop_unshardable(stop: &Stop, budget: &str, flag: &str, unit: &str) -> Option<String> {
    match stop.shard_samples() {
        Ok(_) => None,
        Err(NotSplittable::NoSamples) => {
            Some(format!("no {budget} budget ({flag}): only a fixed number of {unit} splits exactly"))
        }
        Err(NotSplittable::Beside(Condition::Time)) => Some("a time budget (--time-s) cannot be split exactly".into()),
        Err(NotSplittable::Beside(c)) => {
            Some(format!("an error target (--{}) cannot be split exactly", c.key().replace('_', "-")))
        }
    }
}

/// Why `job` is not a long command that shards split exactly (see the
/// module doc), `None` when it is one: decided from the job's type and
/// its stop rule ([`RenderJob::stop`](crate::job::RenderJob::stop),
/// [`BssrdfJob::stop`](crate::job::BssrdfJob::stop)), never from how a
/// command line spells them.
pub fn not_shardable(job: &Job) -> Option<String> {
    match job {
        Job::Render(r) => {
            stop_unshardable(&r.stop(), "sample", "--spp", "samples").or_else(|| scene_unshardable(&r.scene))
        }
        Job::BssrdfCompare(_) => Some("a comparison of slices, seconds of work".into()),
        Job::Bssrdf(b) => stop_unshardable(&b.stop(), "path", "--paths", "paths"),
        other => Some(format!(
            "`lucent {}` is not split into shards (only renders and BSSRDF slices are)",
            other.command_name()
        )),
    }
}

/// How many shards an sbatch `--array` spec holds: "0-3" → 4, "1,3" → 2.
pub fn array_count(indices: &str) -> usize {
    indices
        .split(',')
        .map(|part| match part.split_once('-') {
            Some((a, b)) => match (a.trim().parse::<usize>(), b.trim().parse::<usize>()) {
                (Ok(a), Ok(b)) if b >= a => b - a + 1,
                _ => 1,
            },
            None => 1,
        })
        .sum()
}

/// `job` as shards when it is a long command (see the module doc) and
/// `shards` > 1; `run_out` is the run's output folder. The shard folder is
/// named by the job's identity ([`Job::identity_sha256`]: the typed job
/// without its output folder, paths canonical).
pub fn shard_plan(job: &Job, shards: u32, run_out: &Path) -> Option<Sharded> {
    if shards < 2 || not_shardable(job).is_some() {
        return None;
    }
    let (out, plain) = match job {
        Job::Render(r) => {
            (r.out.clone(), Job::Render(crate::job::RenderJob { quiet: false, shard: None, ..r.clone() }))
        }
        Job::Bssrdf(b) => {
            (b.out.clone(), Job::Bssrdf(crate::job::BssrdfJob { quiet: false, shard: None, ..b.clone() }))
        }
        _ => return None,
    };
    let id: String = job.identity_sha256().chars().take(16).collect();
    Some(Sharded { job: plain, out, shards, dir: run_out.join(".lucent-shards").join(id) })
}

/// The finished shards of `job` that an earlier run left in `run_out`
/// (written by the jobs of `--emit`, or by an interrupted Slurm run): all
/// N shard folders hold a `shard.json`. The command is then merged from
/// them instead of run again.
pub fn finished_shards(job: &Job, run_out: &Path) -> Option<Sharded> {
    let t = shard_plan(job, 2, run_out)?;
    let text = crate::io::read_text(t.dir.join("0").join(crate::shard::SHARD_JSON)).ok()?;
    let first: crate::shard::ShardFile = serde_json::from_str(&text).ok()?;
    let t = Sharded { shards: first.identity.shards, ..t };
    t.done().iter().all(|d| *d).then_some(t)
}

/// A shell word: the text as is when it is plain, else in single quotes.
pub fn shell_word(s: &str) -> String {
    if plain_word(s) {
        s.to_string()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

fn shell_line(exe: &Path, args: &[String]) -> String {
    let mut v = vec![shell_word(&exe.display().to_string())];
    v.extend(args.iter().map(|a| {
        if a.contains("$SLURM_ARRAY_TASK_ID") || a.contains("$JOB_COMPLETION_INDEX") {
            format!("\"{a}\"")
        } else {
            shell_word(a)
        }
    }));
    v.join(" ")
}

/// The sbatch script of a job array over the shards of `t` (`indices`
/// "0-3" or "1,3"), each task `lucent job run DIR/job-$SLURM_ARRAY_TASK_ID.json`
/// (shard K's job file, [`Sharded::write_job_files`]).
pub fn array_script(e: &Executor, t: &Sharded, exe: &Path, cwd: &Path, indices: &str, name: &str) -> String {
    let mut s = String::from("#!/bin/bash\n");
    s.push_str(&format!("#SBATCH --job-name={}\n", shell_word(name)));
    s.push_str(&format!("#SBATCH --array={indices}\n"));
    s.push_str(&format!("#SBATCH --output={}/shard-%a.log\n", t.dir.display()));
    s.push_str("#SBATCH --open-mode=append\n");
    s.push_str(&header_lines(e));
    s.push_str("set -eu\n");
    s.push_str(&format!("cd {}\n", shell_word(&cwd.display().to_string())));
    for l in &e.setup {
        s.push_str(l);
        s.push('\n');
    }
    s.push_str(&format!("# shard $SLURM_ARRAY_TASK_ID of {} of `lucent {}`\n", t.shards, t.label()));
    // lucent takes its threads from SLURM_CPUS_PER_TASK itself (set when
    // the job asks for --cpus-per-task, here or in [executor] sbatch).
    s.push_str("# threads: lucent uses $SLURM_CPUS_PER_TASK when Slurm sets it, else every core it sees\n");
    s.push_str(&format!("exec {}\n", shell_line(exe, &t.shard_command("$SLURM_ARRAY_TASK_ID"))));
    s
}

fn header_lines(e: &Executor) -> String {
    let mut s = String::new();
    if let Some(p) = &e.partition {
        s.push_str(&format!("#SBATCH --partition={p}\n"));
    }
    if let Some(a) = &e.account {
        s.push_str(&format!("#SBATCH --account={a}\n"));
    }
    if let Some(t) = &e.time_limit {
        s.push_str(&format!("#SBATCH --time={t}\n"));
    }
    if let Some(c) = e.cpus_per_task {
        s.push_str(&format!("#SBATCH --cpus-per-task={c}\n"));
    }
    for l in &e.sbatch {
        s.push_str(&format!("#SBATCH {l}\n"));
    }
    s
}

/// The sbatch script of the merge of `t`'s shards (submitted with `--dependency=afterok:ARRAY`).
pub fn merge_script(e: &Executor, t: &Sharded, exe: &Path, cwd: &Path, name: &str) -> String {
    let mut s = String::from("#!/bin/bash\n");
    s.push_str(&format!("#SBATCH --job-name={}\n", shell_word(&format!("{name}-merge"))));
    s.push_str(&format!("#SBATCH --output={}/merge.log\n", t.dir.display()));
    let plain = Executor { cpus_per_task: Some(1), ..e.clone() };
    s.push_str(&header_lines(&plain));
    s.push_str("set -eu\n");
    s.push_str(&format!("cd {}\n", shell_word(&cwd.display().to_string())));
    for l in &e.setup {
        s.push_str(l);
        s.push('\n');
    }
    s.push_str(&format!("exec {}\n", shell_line(exe, &t.merge_command())));
    s
}

/// A Kubernetes Indexed Job running the shards of `t` (`lucent job run
/// DIR/job-$(JOB_COMPLETION_INDEX).json`, shard K's job file), in YAML; the
/// job files and output folders must be on a volume shared with the merge
/// (`lucent merge`, printed in a comment).
pub fn k8s_job(e: &Executor, t: &Sharded, cwd: &Path, name: &str) -> String {
    let cmd = t.shard_command("$(JOB_COMPLETION_INDEX)");
    let args: Vec<String> = cmd.iter().map(|a| format!("        - {}", serde_json::Value::String(a.clone()))).collect();
    // The pod's CPU request, handed to lucent's threads through LUCENT_THREADS
    // (the downward API; a container sees every core of its node otherwise).
    let cpus = e
        .cpus_per_task
        .map(|c| {
            format!(
                "        resources:\n          requests:\n            cpu: \"{c}\"\n        env:\n        - name: LUCENT_THREADS\n          valueFrom:\n            resourceFieldRef:\n              resource: requests.cpu\n              divisor: \"1\"\n"
            )
        })
        .unwrap_or_default();
    let merge: Vec<String> = t.merge_command().iter().map(|a| shell_word(a)).collect();
    format!(
        "# The shards of `lucent {}`, each running its job file {}; when all {} have completed, merge them with:\n#   lucent {}\n\
         apiVersion: batch/v1\nkind: Job\nmetadata:\n  name: {name}\nspec:\n  completionMode: Indexed\n  completions: {n}\n  parallelism: {n}\n  backoffLimitPerIndex: {retries}\n  template:\n    spec:\n      restartPolicy: Never\n      containers:\n      - name: shard\n        image: {image}\n        workingDir: {cwd}\n        command: [\"lucent\"]\n        args:\n{args}\n{cpus}",
        t.label(),
        t.job_file("K").display(),
        t.shards,
        merge.join(" "),
        n = t.shards,
        retries = e.retries,
        image = serde_json::Value::String(e.image.clone()),
        cwd = serde_json::Value::String(cwd.display().to_string()),
        args = args.join("\n"),
    )
}

/// Writes the Indexed Job of `t` ([`k8s_job`]) as `dir/NAME.yaml` and the
/// shards' job files into `t.dir`.
pub fn emit_k8s(e: &Executor, t: &Sharded, cwd: &Path, dir: &Path, name: &str) -> Result<(), SlurmError> {
    t.write_job_files().map_err(|e| SlurmError::Io { path: e.path, source: e.source })?;
    write_script(&dir.join(format!("{name}.yaml")), &k8s_job(e, t, cwd, name))
}

/// The error an executor returns for a command it wrote out as batch jobs
/// instead of running (`lucent run --emit`): the pipeline then stops after
/// the stage, without a manifest ([`super::Status::Deferred`]).
#[derive(Debug, Clone, Copy, Error)]
#[error("written as batch jobs, not run")]
pub struct Deferred;

/// Why a sharded command failed on Slurm.
#[derive(Debug, Error)]
pub enum SlurmError {
    #[error("cannot run {program}: {source} (is Slurm installed and on PATH?)")]
    Spawn { program: String, source: std::io::Error },
    #[error("{program} failed ({status}): {stderr}")]
    Failed { program: String, status: String, stderr: String },
    #[error("sbatch printed no job id: {0:?}")]
    NoJobId(String),
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("shard{} {} of `lucent {command}` still failed after {retries} resubmission(s); logs in {dir}", if shards.len() > 1 { "s" } else { "" }, shards.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(", "))]
    ShardsFailed { shards: Vec<u32>, retries: u32, command: String, dir: PathBuf },
    #[error("the merge job of `lucent {command}` failed; its log {log}:\n    {tail}")]
    MergeFailed { command: String, log: PathBuf, tail: String },
}

fn run_tool(program: &str, args: &[&str]) -> Result<String, SlurmError> {
    let o = Command::new(program)
        .args(args)
        .output()
        .map_err(|source| SlurmError::Spawn { program: program.into(), source })?;
    if !o.status.success() {
        return Err(SlurmError::Failed {
            program: format!("{program} {}", args.join(" ")),
            status: o.status.to_string(),
            stderr: String::from_utf8_lossy(&o.stderr).trim().to_string(),
        });
    }
    Ok(String::from_utf8_lossy(&o.stdout).into_owned())
}

/// Submits a script with sbatch; returns the job id.
fn sbatch(script: &Path, extra: &[&str]) -> Result<String, SlurmError> {
    let mut args = vec!["--parsable"];
    args.extend_from_slice(extra);
    let p = script.display().to_string();
    args.push(&p);
    let out = run_tool("sbatch", &args)?;
    let id = out.trim().split(';').next().unwrap_or("").trim().to_string();
    if id.is_empty() || !id.bytes().all(|b| b.is_ascii_digit()) {
        return Err(SlurmError::NoJobId(out));
    }
    Ok(id)
}

/// Waits until job `id` (all its array tasks) has left the queue; calls
/// `progress` with squeue's count of pending and running tasks.
fn wait(id: &str, poll: Duration, progress: &mut dyn FnMut(usize, usize)) -> Result<(), SlurmError> {
    let mut failures = 0;
    loop {
        // An unknown (long finished) job makes squeue fail: then it is done
        // too; a busy controller can make it fail once, so three in a row.
        let out = match run_tool("squeue", &["-h", "-j", id, "-o", "%T"]) {
            Ok(out) => {
                failures = 0;
                out
            }
            Err(_) if failures >= 2 => return Ok(()),
            Err(_) => {
                failures += 1;
                std::thread::sleep(poll);
                continue;
            }
        };
        let states: Vec<&str> = out.lines().map(str::trim).filter(|l| !l.is_empty()).collect();
        if states.is_empty() {
            return Ok(());
        }
        let pending = states.iter().filter(|s| **s == "PENDING").count();
        progress(pending, states.len() - pending);
        std::thread::sleep(poll);
    }
}

fn write_script(path: &Path, text: &str) -> Result<(), SlurmError> {
    crate::io::write_atomic(path, text.as_bytes())
        .map_err(|e| SlurmError::Io { path: path.to_path_buf(), source: e.source })
}

/// The last lines of a file.
fn tail(path: &Path, n: usize) -> String {
    let text = crate::io::read_text(path).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n    ")
}

/// Runs the shards of `t` on Slurm: a job array, resubmitting the shards
/// that did not finish up to `e.retries` times, then the merge job; the
/// jobs' logs are appended to `log`, and the shard folders removed.
/// `report` hears progress lines.
pub fn run_on_slurm(
    e: &Executor,
    t: &Sharded,
    exe: &Path,
    log: &Path,
    report: &mut dyn FnMut(&str),
) -> Result<(), SlurmError> {
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| SlurmError::Io { path, source }
    };
    let cwd = std::env::current_dir().map_err(io(Path::new(".")))?;
    if t.dir.exists() {
        std::fs::remove_dir_all(&t.dir).map_err(io(&t.dir))?;
    }
    std::fs::create_dir_all(&t.dir).map_err(io(&t.dir))?;
    t.write_job_files().map_err(|e| SlurmError::Io { path: e.path, source: e.source })?;
    let name = format!("lucent-{}", t.command_name());
    let poll = Duration::from_millis(500);
    let start = Instant::now();
    let mut indices = format!("0-{}", t.shards - 1);
    let mut jobs = Vec::new();
    for attempt in 0..=e.retries {
        let script = t.dir.join(format!("array-{attempt}.sbatch"));
        write_script(&script, &array_script(e, t, exe, &cwd, &indices, &name))?;
        let id = sbatch(&script, &[])?;
        let n = array_count(&indices);
        report(&format!(
            "submitted job array {id}: {n} shard{} of `lucent {}` (array indices {indices})",
            if n == 1 { "" } else { "s" },
            t.command_name()
        ));
        jobs.push(id.clone());
        let mut last = (usize::MAX, usize::MAX);
        wait(&id, poll, &mut |pending, running| {
            let done = t.done().iter().filter(|d| **d).count();
            if (pending, running) != last {
                report(&format!(
                    "job {id}: {done}/{} shards done, {running} running, {pending} pending ({:.0} s)",
                    t.shards,
                    start.elapsed().as_secs_f64()
                ));
                last = (pending, running);
            }
        })?;
        let missing: Vec<u32> = t.done().iter().enumerate().filter(|(_, d)| !**d).map(|(k, _)| k as u32).collect();
        if missing.is_empty() {
            break;
        }
        if attempt == e.retries {
            append_logs(t, log);
            return Err(SlurmError::ShardsFailed {
                shards: missing,
                retries: e.retries,
                command: t.label(),
                dir: t.dir.clone(),
            });
        }
        report(&format!("shard(s) {missing:?} did not finish; resubmitting"));
        indices = missing.iter().map(|k| k.to_string()).collect::<Vec<_>>().join(",");
    }
    let script = t.dir.join("merge.sbatch");
    write_script(&script, &merge_script(e, t, exe, &cwd, &name))?;
    let dep = format!("--dependency=afterany:{}", jobs.join(":"));
    let id = sbatch(&script, &[&dep])?;
    report(&format!("submitted merge job {id}"));
    wait(&id, poll, &mut |_, _| {})?;
    append_logs(t, log);
    let merged = t.out.is_dir()
        && std::fs::read_dir(&t.out).map(|mut d| d.next().is_some()).unwrap_or(false)
        && !tail(&t.dir.join("merge.log"), 50).contains("error:");
    if !merged {
        return Err(SlurmError::MergeFailed {
            command: t.label(),
            log: t.dir.join("merge.log"),
            tail: tail(&t.dir.join("merge.log"), 12),
        });
    }
    std::fs::remove_dir_all(&t.dir).map_err(io(&t.dir))?;
    Ok(())
}

/// Appends the shards' and the merge's Slurm logs to the stage log.
fn append_logs(t: &Sharded, log: &Path) {
    use std::io::Write;
    let Ok(mut f) = std::fs::OpenOptions::new().create(true).append(true).open(log) else { return };
    let _ =
        writeln!(f, "$ lucent {} (as {} shards on Slurm, each `lucent job run` of its job file)", t.label(), t.shards);
    let mut logs: Vec<PathBuf> = std::fs::read_dir(&t.dir)
        .map(|d| d.flatten().map(|e| e.path()).filter(|p| p.extension().is_some_and(|x| x == "log")).collect())
        .unwrap_or_default();
    logs.sort();
    for p in logs {
        let _ = writeln!(f, "--- {}", p.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default());
        let _ = f.write_all(&std::fs::read(&p).unwrap_or_default());
    }
}

/// Writes the scripts of `t` into `dir` (`NAME.array.sbatch`,
/// `NAME.merge.sbatch`) and the shards' job files into `t.dir`, and returns
/// the lines of `submit.sh` that submit them, the merge after the array
/// (`--dependency=afterok`).
pub fn emit_slurm(
    e: &Executor,
    t: &Sharded,
    exe: &Path,
    cwd: &Path,
    dir: &Path,
    name: &str,
) -> Result<String, SlurmError> {
    t.write_job_files().map_err(|e| SlurmError::Io { path: e.path, source: e.source })?;
    let array = dir.join(format!("{name}.array.sbatch"));
    let merge = dir.join(format!("{name}.merge.sbatch"));
    write_script(&array, &array_script(e, t, exe, cwd, &format!("0-{}", t.shards - 1), name))?;
    write_script(&merge, &merge_script(e, t, exe, cwd, name))?;
    let var = name.replace(|c: char| !c.is_ascii_alphanumeric(), "_");
    Ok(format!(
        "mkdir -p {dir}\n{var}=$(sbatch --parsable {a})\nsbatch --parsable --dependency=afterok:${{{var}%%;*}} --kill-on-invalid-dep=yes {m}\n",
        dir = shell_word(&t.dir.display().to_string()),
        a = shell_word(&array.display().to_string()),
        m = shell_word(&merge.display().to_string()),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn section(text: &str) -> ExecutorSection {
        toml::from_str(text).expect("toml")
    }

    #[test]
    fn executor_keys_are_checked() {
        let e = Executor::from_section(&section(
            "kind = \"slurm\"\nshards = 4\npartition = \"debug\"\ntime_limit = \"1-02:00:00\"\ncpus_per_task = 2\nsbatch = [\"--mem=1G\"]",
        ))
        .expect("valid");
        assert_eq!((e.kind, e.shards, e.cpus_per_task), (Kind::Slurm, 4, Some(2)));
        for (text, key) in [
            ("kind = \"pbs\"", "kind"),
            ("shards = 0", "shards"),
            ("partition = \"a b\"", "partition"),
            ("time_limit = \"2h\"", "time_limit"),
            ("cpus_per_task = 0", "cpus_per_task"),
            ("sbatch = [\"mem=1G\"]", "sbatch"),
            ("sbatch = [\"--array=0-3\"]", "sbatch"),
            ("retries = 99", "retries"),
        ] {
            let err = Executor::from_section(&section(text)).unwrap_err();
            assert_eq!(err.key, key, "{text}: {err}");
        }
        for t in ["30", "30:00", "02:00:00", "1-0", "1-02:00", "1-02:00:00"] {
            assert!(valid_time_limit(t), "{t}");
        }
        for t in ["", "1:2:3:4", "a", "1-", "-1"] {
            assert!(!valid_time_limit(t), "{t}");
        }
    }

    fn slice(paths: Option<u64>, time_s: Option<f64>, out: &str) -> Job {
        Job::Bssrdf(crate::job::BssrdfJob {
            recipe: Some("/r/recipe.toml".into()),
            wavelength_nm: 550.0,
            configs: None,
            pixels: 65,
            pixel_mm: 0.1,
            seed: 1,
            quiet: true,
            out: out.into(),
            weight_percent: None,
            crop: None,
            paths,
            rel_error: None,
            time_s,
            phase: None,
            ..crate::job::BssrdfJob::default()
        })
    }

    #[test]
    fn long_commands_become_shards_and_scripts() {
        let job = slice(Some(9000), None, "/r/bssrdf/s1");
        let t = shard_plan(&job, 4, Path::new("/r")).expect("a long command");
        assert_eq!(t.out, PathBuf::from("/r/bssrdf/s1"));
        assert!(t.dir.starts_with("/r/.lucent-shards"));
        // The job itself, not quiet; shard K's job is it with its shard and folder.
        let Job::Bssrdf(b) = &t.job else { panic!("{:?}", t.job) };
        assert!(!b.quiet && b.shard.is_none() && b.out == t.out, "{b:?}");
        let Job::Bssrdf(s2) = t.shard_job(2) else { panic!() };
        assert_eq!(
            (s2.shard.map(|s| s.to_string()), s2.out.clone(), s2.quiet),
            (Some("2/4".to_string()), t.dir.join("2"), true)
        );
        assert_eq!(Job::Bssrdf(crate::job::BssrdfJob { shard: None, out: t.out.clone(), quiet: false, ..s2 }), t.job);
        // Job files sit beside the shard folders, never inside one.
        assert_eq!(t.job_file("3"), t.dir.join("job-3.json"));
        assert!(!t.shard_dirs().iter().any(|d| t.job_file("3").starts_with(d)));
        assert!(!t.label().contains("--out") && t.label().starts_with("bssrdf "), "{}", t.label());
        assert!(shard_plan(&job, 1, Path::new("/r")).is_none());
        // The shard folder is the job's, wherever its output goes.
        let elsewhere = shard_plan(&slice(Some(9000), None, "/r/bssrdf/s2"), 4, Path::new("/r")).unwrap();
        assert_eq!(elsewhere.dir, t.dir);
        assert_ne!(shard_plan(&slice(Some(9001), None, "/r/bssrdf/s1"), 4, Path::new("/r")).unwrap().dir, t.dir);
        assert!(shard_plan(&slice(Some(9), Some(9.0), "x"), 4, Path::new("/r")).is_none());
        let e = Executor { partition: Some("debug".into()), cpus_per_task: Some(2), ..Executor::default() };
        let s = array_script(&e, &t, Path::new("/usr/bin/lucent"), Path::new("/work"), "0-3", "lucent-bssrdf");
        assert!(s.contains("#SBATCH --array=0-3\n"), "{s}");
        assert!(s.contains("#SBATCH --partition=debug\n"), "{s}");
        let file = format!("job run \"{}/job-$SLURM_ARRAY_TASK_ID.json\"\n", t.dir.display());
        assert!(s.contains(&file) && !s.contains("--shard"), "each task runs its job file: {s}");
        // Threads come from SLURM_CPUS_PER_TASK inside lucent (bssrdf has no --threads).
        assert!(s.contains("#SBATCH --cpus-per-task=2\n") && !s.contains("--threads"), "{s}");
        let k = k8s_job(&e, &t, Path::new("/work"), "lucent-bssrdf");
        assert!(k.contains("completionMode: Indexed") && k.contains("/job-$(JOB_COMPLETION_INDEX).json"), "{k}");
        assert!(k.contains("cpu: \"2\"") && k.contains("name: LUCENT_THREADS") && k.contains("resource: requests.cpu"));
        // The file is the Job it says: parsed as YAML, the CPU request and
        // the thread count sit on the shard's container.
        let job: serde_yaml_ng::Value = serde_yaml_ng::from_str(&k).expect("the emitted Job is valid YAML");
        let container = &job["spec"]["template"]["spec"]["containers"][0];
        assert_eq!(container["name"].as_str(), Some("shard"), "{k}");
        assert_eq!(container["resources"]["requests"]["cpu"].as_str(), Some("2"), "{k}");
        assert_eq!(container["env"][0]["name"].as_str(), Some("LUCENT_THREADS"), "{k}");
        assert_eq!(
            container["env"][0]["valueFrom"]["resourceFieldRef"]["resource"].as_str(),
            Some("requests.cpu"),
            "{k}"
        );
        assert_eq!(container["args"].as_sequence().map(Vec::len), Some(t.shard_command("0").len()), "{k}");
        assert_eq!(job["spec"]["completions"].as_u64(), Some(4), "{k}");
        // Without a CPU request, no thread count is passed.
        let k = k8s_job(&Executor::default(), &t, Path::new("/work"), "lucent-bssrdf");
        assert!(!k.contains("LUCENT_THREADS"), "{k}");
        let job: serde_yaml_ng::Value = serde_yaml_ng::from_str(&k).expect("the emitted Job is valid YAML");
        assert!(job["spec"]["template"]["spec"]["containers"][0]["resources"].is_null(), "{k}");
    }

    #[test]
    fn each_shard_has_its_job_file_beside_its_folder() {
        let tmp = tempfile::tempdir().expect("temporary folder");
        let t = shard_plan(&slice(Some(9000), None, "/r/bssrdf/s1"), 3, tmp.path()).expect("a long command");
        t.write_job_files().expect("job files");
        for k in 0..3u32 {
            let text = std::fs::read_to_string(t.job_file(&k.to_string())).expect("job file");
            let job: Job = serde_json::from_str(&text).expect("a job");
            assert_eq!(job, t.shard_job(k));
            assert_eq!(t.shard_command(&k.to_string())[..2], ["job".to_string(), "run".to_string()]);
        }
        // The shard folders are not made: a folder holds a shard only once it ran.
        assert!(t.done().iter().all(|d| !d) && !t.dir.join("0").exists());
    }

    #[test]
    fn array_specs_count_their_shards() {
        assert_eq!(array_count("0-3"), 4);
        assert_eq!(array_count("1,3"), 2);
        assert_eq!(array_count("2"), 1);
        assert_eq!(array_count("0-1,5,7-9"), 6);
    }

    #[test]
    fn commands_say_why_they_are_not_sharded() {
        assert!(not_shardable(&slice(Some(9), None, "x")).is_none());
        let why = not_shardable(&slice(None, Some(9.0), "x")).unwrap();
        assert!(why.contains("path budget"), "{why}");
        let Job::Bssrdf(mut targeted) = slice(Some(9), None, "x") else { unreachable!() };
        targeted.rel_error = Some(0.01);
        assert_eq!(targeted.stop().shard_samples(), Err(NotSplittable::Beside(Condition::RelError)));
        let why = not_shardable(&Job::Bssrdf(targeted)).unwrap();
        assert!(why.contains("error target (--rel-error)"), "{why}");
        let render = crate::job::RenderJob {
            scene: "s.toml".into(),
            spp: Some(8),
            quiet: false,
            time_s: Some(3.0),
            size: None,
            seed: None,
            uncertainty: false,
            out: "x".into(),
            ..Default::default()
        };
        assert_eq!(render.stop(), Stop { time_s: Some(3.0), ..Stop::samples(8) });
        let why = not_shardable(&Job::Render(render)).unwrap();
        assert!(why.contains("time budget"), "{why}");
        let optics = crate::job::OpticsJob::new(vec!["r.toml".into()], "550".parse().expect("a grid"), "x".into());
        let why = not_shardable(&Job::Optics(optics)).unwrap();
        assert!(why.contains("not split"), "{why}");
    }

    #[test]
    fn the_plan_names_what_goes_to_the_cluster_and_what_stays_here() {
        let file: crate::pipeline::project::ProjectFile = toml::from_str(
            "[bssrdf]\nconfigs = \"45/0\"\npaths = 3000\n\n[render]\nscene = \"/nonexistent.toml\"\nspp = 8\n",
        )
        .expect("toml");
        let e = Executor { kind: Kind::Slurm, shards: 4, cpus_per_task: Some(2), ..Executor::default() };
        let text = crate::pipeline::project::plan_lines(&file, &e).join("\n");
        assert!(text.contains("4 shards per long command") && text.contains("2 CPU(s) per shard"), "{text}");
        assert!(text.contains("bssrdf      on the cluster: each slice ([bssrdf] paths = 3000) as 4 shards"), "{text}");
        // The scene cannot be read here: the render stays here, and the line says why.
        assert!(text.contains("render      here: /nonexistent.toml cannot be read"), "{text}");
        assert!(text.contains("optics, ") && text.contains("report  here: "), "{text}");
        let timed: crate::pipeline::project::ProjectFile =
            toml::from_str("[bssrdf]\nconfigs = \"45/0\"\npaths = 3000\ntime_s = 9\n").expect("toml");
        let text = crate::pipeline::project::plan_lines(&timed, &e).join("\n");
        assert!(text.contains("bssrdf      here: [bssrdf] sets time_s or rel_error"), "{text}");
        assert!(text.contains("(render not in this project)"), "{text}");
    }
}
