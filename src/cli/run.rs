//! `lucent run PROJECT.toml`: the stages of [`crate::pipeline`] in order,
//! each stage's jobs run in this process (the library's job, as `lucent job
//! run` runs it) with their output (descriptors 1 and 2)
//! in `STAGE/log.txt`; one status line per stage with its time on the
//! standard output and error `lucent run` was started with. Only the
//! cluster executors start processes (Slurm jobs, Kubernetes manifests).

use super::choices::{ForceChoice, StageChoice};
use crate::fault::{Fault, Faulted, Interrupted};
use crate::interrupt::Interrupt;
use crate::job::Job;
use crate::pipeline::executor::{self, Kind};
use crate::pipeline::{self, project::Project, Options, Stage, Status};
use anyhow::{Context, Result};
use clap::Args;
use std::io::Write;
use std::path::{Path, PathBuf};

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

/// Standard output and error of this process as they were when `lucent
/// run` started (the terminal, a pipe, a file): the status lines keep going
/// there while a stage's output goes to its log.
struct Console {
    #[cfg(unix)]
    saved: [libc::c_int; 2],
}

impl Console {
    /// Duplicates descriptors 1 and 2 (and tells the Ctrl-C helper to say its
    /// messages on the duplicate of 2).
    fn save() -> Result<Self> {
        #[cfg(unix)]
        {
            // SAFETY: duplicates the standard descriptors (closed on exec: the
            // cluster tools lucent starts do not inherit them); the copies are ours until drop.
            let saved = unsafe { [1, 2].map(|fd| libc::fcntl(fd, libc::F_DUPFD_CLOEXEC, 3)) };
            if saved.iter().any(|fd| *fd < 0) {
                let e = std::io::Error::last_os_error();
                for fd in saved.into_iter().filter(|fd| *fd >= 0) {
                    // SAFETY: closes a copy made above.
                    unsafe { libc::close(fd) };
                }
                return Err(anyhow::Error::from(e).context("cannot duplicate standard output and error"));
            }
            crate::interrupt::set_console(saved[1]);
            Ok(Console { saved })
        }
        #[cfg(not(unix))]
        Ok(Console {})
    }

    /// Runs `f` with descriptors 1 and 2 appended to `log` (what a command
    /// prints with println! and eprintln! goes there), then puts them back.
    fn redirected<T>(&self, log: &std::fs::File, f: impl FnOnce() -> T) -> Result<T> {
        #[cfg(unix)]
        {
            use std::os::fd::AsRawFd;
            let _ = std::io::stdout().flush();
            // SAFETY: dup2(2) onto the standard descriptors of a file we hold open.
            if unsafe { libc::dup2(log.as_raw_fd(), 1) } < 0 || unsafe { libc::dup2(log.as_raw_fd(), 2) } < 0 {
                let e = std::io::Error::last_os_error();
                self.restore();
                return Err(anyhow::Error::from(e).context("cannot send a stage's output to its log"));
            }
            let out = f();
            self.restore();
            Ok(out)
        }
        #[cfg(not(unix))]
        {
            let _ = log;
            Ok(f())
        }
    }

    #[cfg(unix)]
    fn restore(&self) {
        let _ = std::io::stdout().flush();
        // SAFETY: dup2(2) of the saved copies back onto 1 and 2.
        unsafe {
            libc::dup2(self.saved[0], 1);
            libc::dup2(self.saved[1], 2);
        }
    }
}

impl Drop for Console {
    fn drop(&mut self) {
        #[cfg(unix)]
        {
            crate::interrupt::set_console(-1);
            // SAFETY: closes the copies made by `save`.
            unsafe {
                libc::close(self.saved[0]);
                libc::close(self.saved[1]);
            }
        }
    }
}

/// What a caught panic says (its message, when it is text).
fn panic_message(payload: &(dyn std::any::Any + Send)) -> &str {
    payload
        .downcast_ref::<String>()
        .map(String::as_str)
        .or_else(|| payload.downcast_ref::<&str>().copied())
        .unwrap_or("")
}

/// Runs `work` (a command, whose command line is `args`) in this process,
/// as a child `lucent` would have run it: its output appended to `log` after a
/// line `$ lucent ARGS`, its error written there as the binary prints it,
/// a panic caught and classed as a bug (or, when the log could not be
/// written, as the machine's), the current folder put back afterwards. A
/// stop request (Ctrl-C, SIGTERM) before or during it fails it as interrupted.
fn run_here(
    work: impl FnOnce() -> Result<()>,
    args: &[String],
    log: &Path,
    interrupt: &Interrupt,
    console: &Console,
) -> Result<()> {
    let mut f = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(log)
        .with_context(|| format!("{}: cannot open log", log.display()))?;
    let _ = writeln!(f, "$ lucent {}", args.join(" "));
    if interrupt.requested() {
        return Err(Interrupted(format!("before `lucent {}`", args.join(" "))).into());
    }
    let cwd = std::env::current_dir().context("cannot read the current folder")?;
    let outcome = console.redirected(&f, || {
        let _stage = super::job_run::InStage::enter();
        let caught = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work));
        if let Ok(Err(e)) = &caught {
            // As the binary says it (into the log, standard error meanwhile).
            // One write: the line stays whole where other threads write too.
            let line = match crate::pipeline::fault_of(e.as_ref()) {
                Fault::Input | Fault::Interrupted => format!("error: {e:#}\n"),
                fault => format!("error ({fault}): {e:#}\n"),
            };
            let _ = std::io::stderr().write_all(line.as_bytes());
        }
        caught
    });
    // A command may enter another folder: the run's relative paths stay
    // those of its own.
    std::env::set_current_dir(&cwd).with_context(|| format!("{}: cannot go back to", cwd.display()))?;
    if interrupt.requested() {
        return Err(Interrupted(format!("during `lucent {}`", args.join(" "))).into());
    }
    match outcome? {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(e.context(format!("`lucent {}` (its log: {})", args.join(" "), log.display()))),
        Err(payload) => {
            let message = panic_message(payload.as_ref());
            let fault =
                if message.starts_with("failed printing to std") { Fault::Environment } else { Fault::Internal };
            Err(anyhow::Error::from(Faulted {
                fault,
                message: format!(
                    "`lucent {}` panicked ({fault}{}): {message}; the end of {}:\n    {}",
                    args.join(" "),
                    if fault == Fault::Internal { ", a bug; please report it" } else { "" },
                    log.display(),
                    tail(log, 12)
                ),
            }))
        }
    }
}

/// Runs a stage's job in this process ([`run_here`]) as `lucent job run`
/// runs a job file ([`super::job_run::run_in_process`]: the library's
/// [`Job::run_with`] with the terminal's hooks, the job's files and output
/// folder checked as its command checks them, its summary printed as its
/// command prints it).
fn run_job_here(job: &Job, log: &Path, interrupt: &Interrupt, console: &Console) -> Result<()> {
    run_here(|| super::job_run::run_in_process(job), &job.to_args(), log, interrupt, console)
}

/// Merges the finished shards of `t` into its output, in this process, as
/// `lucent merge` does ([`super::shard::merge`], the library's merge), its
/// output folder checked and marked as the command's.
fn merge_here(t: &executor::Sharded, log: &Path, interrupt: &Interrupt, console: &Console) -> Result<()> {
    let work = || super::common::writing_into(Some(t.out.clone()), || super::shard::merge(&t.shard_dirs(), &t.out));
    run_here(work, &t.merge_command(), log, interrupt, console)
}

/// A command's error for the pipeline: its whole chain as one message, and its class.
fn classified(e: anyhow::Error) -> Box<dyn std::error::Error + Send + Sync> {
    Box::new(Faulted { fault: crate::pipeline::fault_of(e.as_ref()), message: format!("{e:#}") })
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
        Some(s) if s.is_finite() && s >= 0.0 => format!(" (≈ {}, as last time)", super::common::duration(s)),
        _ => String::new(),
    };
    format!("[{k}/{n}] {} …{last}", stage.name())
}

/// Runs `lucent run`.
pub fn run(a: RunArgs) -> Result<()> {
    let project = Project::load(&a.project)?;
    let force: Vec<Stage> = a.force.iter().flat_map(|f| f.stages()).collect();
    let until: Option<Stage> = a.until.map(|u| u.0);
    let out = project.run_folder(a.out.as_deref());
    // Stages write paths into files they hand to later stages (scene files
    // resolve paths relative to themselves), so the folder must be absolute.
    let out =
        std::path::absolute(&out).with_context(|| format!("{}: cannot resolve the output folder", out.display()))?;
    // The binary the cluster's scripts run (the stages here run in this process).
    let exe = || std::env::current_exe().context("cannot find the lucent binary for the cluster's scripts");
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
    let emit = emit_target(&a.emit)?;
    if emit.is_some() && exec_cfg.shards < 2 {
        anyhow::bail!(
            "--emit: [executor] shards is {}: set it to the number of shards per long command (≥ 2)",
            exec_cfg.shards
        );
    }
    if emit.is_none() && exec_cfg.kind == Kind::Slurm {
        for line in crate::pipeline::project::plan_lines(&project.file, &exec_cfg) {
            println!("{line}");
        }
    }
    let cwd = std::env::current_dir().context("cannot read the current folder")?;
    // Ctrl-C or SIGTERM: the stage under way fails (its output is kept as
    // STAGE.failed/, the previous result is put back) and no later one starts.
    let interrupt = Interrupt::install();
    // The stages' output goes to their logs; the status lines to these.
    let console = Console::save()?;
    let mut submit = String::new();
    let mut emitted = 0usize;
    let mut exec = |job: &Job, log: &Path| -> Result<(), Box<dyn std::error::Error + Send + Sync>> {
        // Shards an earlier run's jobs finished are merged, not run again.
        if let Some(t) = executor::finished_shards(job, &out) {
            merge_here(&t, log, &interrupt, &console).map_err(classified)?;
            std::fs::remove_dir_all(&t.dir).map_err(|e| format!("{}: {e}", t.dir.display()))?;
            return Ok(());
        }
        let sharded = executor::shard_plan(job, exec_cfg.shards, &out);
        match (sharded, &emit) {
            (Some(t), Some(Emit::Slurm(dir))) => {
                emitted += 1;
                let name = format!("lucent-{emitted:02}-{}", t.command_name());
                submit.push_str(&executor::emit_slurm(&exec_cfg, &t, &exe()?, &cwd, dir, &name)?);
                Err(Box::new(executor::Deferred))
            }
            (Some(t), Some(Emit::K8s(dir))) => {
                emitted += 1;
                let name = format!("lucent-{emitted:02}-{}", t.command_name());
                executor::emit_k8s(&exec_cfg, &t, &cwd, dir, &name)?;
                Err(Box::new(executor::Deferred))
            }
            (None, None) if exec_cfg.kind == Kind::Slurm && matches!(job, Job::Render(_) | Job::Bssrdf(_)) => {
                // A long-looking command the cluster does not get: say so, and why.
                if let Some(why) = executor::not_shardable(job) {
                    let args = job.to_args();
                    println!("    here, not on the cluster: `lucent {}` ({why})", args[..2.min(args.len())].join(" "));
                }
                run_job_here(job, log, &interrupt, &console).map_err(classified)
            }
            (Some(t), None) if exec_cfg.kind == Kind::Slurm => {
                let label = t.label();
                executor::run_on_slurm(&exec_cfg, &t, &exe()?, log, &mut |line| println!("    {line}"))
                    .map_err(|e| classified(anyhow::Error::from(e).context(format!("`lucent {label}` on Slurm"))))
            }
            _ => run_job_here(job, log, &interrupt, &console).map_err(classified),
        }
    };
    let mut status_line = |stage: Stage, st: &Status, notes: &[String]| print_status(n, stage, st, notes);
    let result = pipeline::run(&project, &out, &Options { force, until }, &mut exec, &mut status_line);
    if let Some(e) = &emit
        && emitted > 0
    {
        write_emitted(e, emitted, &submit, &a.project)?;
    }
    match result {
        Ok(_) => {
            println!("done in {:.1} s", total.elapsed().as_secs_f64());
            let report = crate::pipeline::report::ReportFiles::in_dir(&out.join(Stage::Report.name()));
            if report.html.is_file() {
                super::job_run::print_report(&report);
            }
            Ok(())
        }
        Err(e) => Err(e.into()),
    }
}

/// The `--emit KIND DIR` target (`args`, none or two), its folder absolute
/// and new or lucent's.
fn emit_target(args: &[String]) -> Result<Option<Emit>> {
    Ok(match args {
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
    })
}

/// The status line of `stage` (of `n`): its start on stderr, how it ended
/// on stdout with its notes (their warnings on stderr).
fn print_status(n: usize, stage: Stage, st: &Status, notes: &[String]) {
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
}

/// After `emitted` jobs were written to `e`'s folder: marks it as lucent's,
/// writes submit.sh (Slurm, its `submit` lines) and says how to go on with
/// the project file `project`.
fn write_emitted(e: &Emit, emitted: usize, submit: &str, project: &Path) -> Result<()> {
    let (Emit::Slurm(dir) | Emit::K8s(dir)) = e;
    crate::io::mark_output_folder(dir)?;
    match e {
        Emit::Slurm(dir) => {
            let path = dir.join("submit.sh");
            let text = format!("#!/bin/bash\n# Submits the shards of {emitted} long command(s) of `lucent run {}` and their merges.\nset -eu\n{submit}", project.display());
            crate::io::write_atomic(&path, text.as_bytes())?;
            println!("wrote {emitted} job array(s) and merge job(s); submit them with: bash {}", path.display());
        }
        Emit::K8s(dir) => {
            println!("wrote {emitted} Indexed Job manifest(s) to {}; apply them with kubectl apply -f", dir.display())
        }
    }
    println!(
        "when the jobs have finished, run `lucent run {}` again: it merges the shards and goes on",
        project.display()
    );
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stage's work runs here with its output in the log: a panic is caught
    /// and classed as a bug (internal), and an error keeps its type for the
    /// class. (While it runs, descriptors 1 and 2 of the test process go to
    /// the log: the harness's lines of other tests then may go there too.)
    #[test]
    fn a_stage_that_panics_fails_as_a_bug_and_errors_keep_their_class() {
        let dir = tempfile::tempdir().expect("temporary folder");
        let log = dir.path().join("log.txt");
        let interrupt = Interrupt::install();
        let console = Console::save().expect("standard descriptors");
        let args = ["render".to_string(), "scene.toml".to_string()];
        let work = || -> Result<()> {
            // Written to descriptor 1 itself (println! is the test harness's here).
            let _ = writeln!(std::io::stdout(), "a line of the command");
            panic!("tile index out of range")
        };
        let e = run_here(work, &args, &log, &interrupt, &console).expect_err("a panic fails the stage");
        assert_eq!(crate::pipeline::fault_of(e.as_ref()), Fault::Internal, "{e:#}");
        let text = format!("{e:#}");
        assert!(
            text.contains("`lucent render scene.toml` panicked") && text.contains("tile index out of range"),
            "{text}"
        );
        let written = std::fs::read_to_string(&log).expect("log");
        assert!(written.starts_with("$ lucent render scene.toml\n"), "{written}");
        assert!(written.contains("a line of the command"), "the command's output goes to the log: {written}");
        let disk = || -> Result<()> {
            Err(anyhow::Error::from(std::io::Error::from(std::io::ErrorKind::StorageFull)).context("render.exr"))
        };
        let e = run_here(disk, &args, &log, &interrupt, &console).expect_err("an error fails the stage");
        assert_eq!(crate::pipeline::fault_of(e.as_ref()), Fault::Environment, "{e:#}");
        let written = std::fs::read_to_string(&log).expect("log");
        assert!(
            written.contains("error (environment): render.exr"),
            "the error is in the log as the binary says it: {written}"
        );
        assert!(run_here(|| Ok(()), &args, &log, &interrupt, &console).is_ok());
    }
}
