//! `lucent run PROJECT.toml`: the stages of [`crate::pipeline`] in order,
//! each stage's `lucent` commands run as child processes of this binary with
//! their output in `STAGE/log.txt`; one status line per stage with its time.

use super::choices::{ForceChoice, StageChoice};
use super::interrupt::Interrupt;
use crate::fault::{Fault, Faulted, Interrupted};
use crate::pipeline::executor::{self, Kind};
use crate::pipeline::{self, project::Project, Options, Stage, Status};
use anyhow::{Context, Result};
use clap::Args;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

#[derive(Debug, Args)]
pub struct RunArgs {
    /// Project file (TOML; format in `src/pipeline/project.rs` and the README).
    pub project: PathBuf,
    /// Output folder (default: the project's [project] out, else lucent-out/NAME).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Rerun this stage even if its inputs are unchanged (repeatable; "all" for every stage).
    #[arg(long, value_enum, value_name = "STAGE")]
    pub force: Vec<ForceChoice>,
    /// Stop after this stage.
    #[arg(long, value_enum, value_name = "STAGE")]
    pub until: Option<StageChoice>,
    /// Where long commands (render, bssrdf slices) run: here, or as Slurm
    /// job arrays of [executor] shards (overrides [executor] kind).
    #[arg(long, value_enum)]
    pub executor: Option<ExecutorChoice>,
    /// Write the long commands as batch jobs into DIR instead of running
    /// them (slurm: sbatch scripts and submit.sh; k8s: Indexed Job
    /// manifests); the stages before them run here. Rerun `lucent run` when
    /// the jobs have finished: it merges their shards and goes on.
    #[arg(long, num_args = 2, value_names = ["KIND", "DIR"])]
    pub emit: Vec<String>,
}

/// `--executor`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum ExecutorChoice {
    Local,
    Slurm,
}

/// `--emit KIND DIR`.
#[derive(Debug, Clone)]
enum Emit {
    Slurm(PathBuf),
    K8s(PathBuf),
}

/// The last `n` lines of a log file.
fn tail(log: &Path, n: usize) -> String {
    let text = crate::io::read_text(log).unwrap_or_default();
    let lines: Vec<&str> = text.lines().collect();
    lines[lines.len().saturating_sub(n)..].join("\n    ")
}

/// Runs `lucent ARGS` with stdout and stderr appended to `log`.
fn run_lucent(exe: &Path, args: &[String], log: &Path, interrupt: &Interrupt) -> Result<()> {
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
        .with_context(|| format!("{}: cannot open log", log.display()))?;
    let _ = writeln!(f, "$ lucent {}", args.join(" "));
    let err = f.try_clone().with_context(|| format!("{}: cannot open log", log.display()))?;
    if interrupt.requested() {
        return Err(Interrupted(format!("before `lucent {}`", args.join(" "))).into());
    }
    let mut child = Command::new(exe)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::from(f))
        .stderr(Stdio::from(err))
        .spawn()
        .with_context(|| format!("cannot start {}", exe.display()))?;
    // A stop request reaches the command too (a Ctrl-C at the terminal does
    // by itself; a SIGTERM to this process alone is passed on), and the stage
    // then fails whatever the command did with it: an interrupted result is
    // kept as STAGE.failed/, never taken for the stage's output.
    let mut passed_on = false;
    let status = loop {
        if let Some(status) = child.try_wait().with_context(|| format!("waiting for `lucent {}`", args.join(" ")))? {
            break status;
        }
        if interrupt.requested() && !passed_on {
            passed_on = true;
            #[cfg(unix)]
            if let Ok(pid) = libc::pid_t::try_from(child.id()) {
                // SAFETY: kill(2) on the child we started and have not yet reaped.
                unsafe { libc::kill(pid, libc::SIGTERM) };
            }
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    if interrupt.requested() {
        return Err(Interrupted(format!("during `lucent {}`", args.join(" "))).into());
    }
    match status.code().map_or_else(|| Some(killed_by(&status)), Fault::from_exit_code) {
        None => Ok(()),
        Some(fault) => Err(anyhow::Error::from(Faulted {
            fault,
            message: format!(
                "`lucent {}` exited with {status} ({fault}); the end of {}:\n    {}",
                args.join(" "),
                log.display(),
                tail(log, 12)
            ),
        })),
    }
}

/// The class of a command ended by a signal: SIGINT, SIGTERM or SIGHUP stopped it
/// (interrupted), SIGKILL is the machine's (the kernel's out-of-memory
/// killer, a batch system's limit), anything else (SIGSEGV, SIGABRT) a bug.
fn killed_by(status: &std::process::ExitStatus) -> Fault {
    #[cfg(unix)]
    {
        use std::os::unix::process::ExitStatusExt;
        match status.signal() {
            Some(libc::SIGINT | libc::SIGTERM | libc::SIGHUP) => Fault::Interrupted,
            Some(libc::SIGKILL) => Fault::Environment,
            _ => Fault::Internal,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = status;
        Fault::Internal
    }
}

/// A command's error for the pipeline: its whole chain as one message, and its class.
fn classified(e: anyhow::Error) -> Box<dyn std::error::Error + Send + Sync> {
    Box::new(Faulted { fault: Fault::of(e.as_ref()), message: format!("{e:#}") })
}

/// What a Slurm run lacks in the project's `[executor]` table, naming the
/// keys; `None` when it can run (at least 2 shards per long command).
fn slurm_settings_missing(project: &Project) -> Option<String> {
    let keys = "shards = N (≥ 2, required: how many shards each long command is split into); optional: partition, \
                account, time_limit, cpus_per_task (each shard's threads), sbatch, setup, retries";
    match &project.file.executor {
        None => Some(format!(
            "--executor slurm needs an [executor] table in the project file: {keys} (see docs/formats.md#executor)"
        )),
        Some(_) if project.executor.shards < 2 => {
            Some(format!("Slurm runs need [executor] shards ≥ 2 (it is {}): {keys}", project.executor.shards))
        }
        Some(_) => None,
    }
}

/// The line `lucent run` prints (on stderr) as stage `k` of `n` starts:
/// "[k/n] STAGE … (≈ N s, as last time)", the time from the stage's
/// previous manifest.json when there is one.
fn start_line(k: usize, n: usize, stage: Stage, last_wall_s: Option<f64>) -> String {
    let last = match last_wall_s {
        Some(s) if s.is_finite() && s >= 0.0 => format!(" (≈ {}, as last time)", super::render::duration(s)),
        _ => String::new(),
    };
    format!("[{k}/{n}] {} …{last}", stage.name())
}

/// Runs `lucent run`.
pub fn run(a: RunArgs) -> Result<()> {
    let project = Project::load(&a.project)?;
    let force: Vec<Stage> = a.force.iter().flat_map(|f| f.stages()).collect();
    let until: Option<Stage> = a.until.map(|u| u.0);
    let out = a.out.clone().or(project.out.clone()).unwrap_or_else(|| PathBuf::from("lucent-out").join(&project.name));
    // Stages write paths into files they hand to later stages (scene files
    // resolve paths relative to themselves), so the folder must be absolute.
    let out =
        std::path::absolute(&out).with_context(|| format!("{}: cannot resolve the output folder", out.display()))?;
    let exe = std::env::current_exe().context("cannot find the lucent binary to run the stages")?;
    // The whole chain of causes goes into the stage's error message.
    let mut exec_cfg = project.executor.clone();
    match a.executor {
        Some(ExecutorChoice::Local) => exec_cfg.kind = Kind::Local,
        Some(ExecutorChoice::Slurm) => exec_cfg.kind = Kind::Slurm,
        None => {}
    }
    if a.emit.is_empty()
        && exec_cfg.kind == Kind::Slurm
        && let Some(problem) = slurm_settings_missing(&project)
    {
        anyhow::bail!("{}: {problem}", a.project.display());
    }
    println!("lucent run {} → {}", a.project.display(), out.display());
    let total = std::time::Instant::now();
    let n = Stage::ALL.len();
    let emit = match a.emit.as_slice() {
        [] => None,
        [kind, dir] => {
            let dir = std::path::absolute(dir).with_context(|| format!("--emit {kind} {dir}: cannot resolve"))?;
            // Like every output folder: new, or one lucent wrote (a folder of
            // the user's, e.g. holding their own submit.sh, is refused).
            crate::io::check_output_folder(&dir).with_context(|| format!("--emit {kind} {}", dir.display()))?;
            match kind.as_str() {
                "slurm" => Some(Emit::Slurm(dir)),
                "k8s" => Some(Emit::K8s(dir)),
                other => anyhow::bail!("--emit {other:?}: expected slurm or k8s"),
            }
        }
        _ => anyhow::bail!("--emit needs KIND and DIR, e.g. --emit slurm jobs/"),
    };
    if emit.is_some() && exec_cfg.shards < 2 {
        anyhow::bail!(
            "--emit: [executor] shards is {}: set it to the number of shards per long command (≥ 2)",
            exec_cfg.shards
        );
    }
    if emit.is_none() && exec_cfg.kind == Kind::Slurm {
        for line in executor::plan_lines(&project.file, &exec_cfg) {
            println!("{line}");
        }
    }
    let cwd = std::env::current_dir().context("cannot read the current folder")?;
    // Ctrl-C or SIGTERM: the stage under way fails (its output is kept as
    // STAGE.failed/, the previous result is put back) and no later one starts.
    let interrupt = Interrupt::install();
    let mut submit = String::new();
    let mut emitted = 0usize;
    let mut exec = |args: &[String], log: &Path| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        // Shards an earlier run's jobs finished are merged, not run again.
        if let Some(t) = executor::finished_shards(args, &out) {
            run_lucent(&exe, &t.merge_command(), log, &interrupt).map_err(classified)?;
            std::fs::remove_dir_all(&t.dir).map_err(|e| format!("{}: {e}", t.dir.display()))?;
            return Ok(());
        }
        let sharded = executor::shard_plan(args, exec_cfg.shards, &out);
        match (sharded, &emit) {
            (Some(t), Some(Emit::Slurm(dir))) => {
                emitted += 1;
                let name = format!("lucent-{emitted:02}-{}", t.args[0]);
                submit.push_str(&executor::emit_slurm(&exec_cfg, &t, &exe, &cwd, dir, &name)?);
                Err(Box::new(executor::Deferred))
            }
            (Some(t), Some(Emit::K8s(dir))) => {
                emitted += 1;
                let name = format!("lucent-{emitted:02}-{}", t.args[0]);
                let path = dir.join(format!("{name}.yaml"));
                crate::io::write_atomic(&path, executor::k8s_job(&exec_cfg, &t, &cwd, &name).as_bytes())?;
                Err(Box::new(executor::Deferred))
            }
            (None, None)
                if exec_cfg.kind == Kind::Slurm && args.first().is_some_and(|c| c == "render" || c == "bssrdf") =>
            {
                // A long-looking command the cluster does not get: say so, and why.
                if let Some(why) = executor::not_shardable(args) {
                    println!("    here, not on the cluster: `lucent {}` ({why})", args[..2.min(args.len())].join(" "));
                }
                run_lucent(&exe, args, log, &interrupt).map_err(classified)
            }
            (Some(t), None) if exec_cfg.kind == Kind::Slurm => {
                let label = t.args.join(" ");
                executor::run_on_slurm(&exec_cfg, &t, &exe, log, &mut |line| println!("    {line}"))
                    .map_err(|e| classified(anyhow::Error::from(e).context(format!("`lucent {label}` on Slurm"))))
            }
            _ => run_lucent(&exe, args, log, &interrupt).map_err(classified),
        }
    };
    let mut status_line = |stage: Stage, st: &Status, notes: &[String]| {
        let k = Stage::ALL.iter().position(|s| *s == stage).unwrap_or(0) + 1;
        let what = match st {
            Status::Started { last_wall_s } => {
                // Before the stage's commands: which, and how long it took last time.
                eprintln!("{}", start_line(k, n, stage, *last_wall_s));
                return;
            }
            Status::Ran { wall_s, tasks } => {
                format!("ran {tasks} task{} in {wall_s:.1} s", if *tasks == 1 { "" } else { "s" })
            }
            Status::UpToDate => "up to date (inputs and parameters unchanged)".into(),
            Status::Skipped { reason } => format!("skipped: {reason}"),
            Status::Deferred { tasks } => format!("{tasks} long task(s) written as batch jobs, not run here"),
        };
        let (warnings, notes): (Vec<&String>, Vec<&String>) = notes.iter().partition(|n| n.starts_with("warning: "));
        let notes = if notes.is_empty() {
            String::new()
        } else {
            format!(" [{}]", notes.iter().map(|n| n.as_str()).collect::<Vec<_>>().join("; "))
        };
        println!("[{k}/{n}] {:<10} {what}{notes}", stage.name());
        for w in warnings {
            eprintln!("{w}");
        }
    };
    let result = pipeline::run(&project, &out, &Options { force, until }, &mut exec, &mut status_line);
    if let Some(e) = &emit
        && emitted > 0
    {
        let (Emit::Slurm(dir) | Emit::K8s(dir)) = e;
        crate::io::mark_output_folder(dir)?;
        match e {
            Emit::Slurm(dir) => {
                let path = dir.join("submit.sh");
                let text = format!("#!/bin/bash\n# Submits the shards of {emitted} long command(s) of `lucent run {}` and their merges.\nset -eu\n{submit}", a.project.display());
                crate::io::write_atomic(&path, text.as_bytes())?;
                println!("wrote {emitted} job array(s) and merge job(s); submit them with: bash {}", path.display());
            }
            Emit::K8s(dir) => println!(
                "wrote {emitted} Indexed Job manifest(s) to {}; apply them with kubectl apply -f",
                dir.display()
            ),
        }
        println!(
            "when the jobs have finished, run `lucent run {}` again: it merges the shards and goes on",
            a.project.display()
        );
    }
    match result {
        Ok(_) => {
            println!("done in {:.1} s", total.elapsed().as_secs_f64());
            let index = out.join("report/index.html");
            if index.is_file() {
                println!("report: {}", index.display());
                println!("metrics: {}", out.join("report/metrics.json").display());
            }
            Ok(())
        }
        Err(e) => Err(e.into()),
    }
}
