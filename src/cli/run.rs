//! `lucent run PROJECT.toml`: the stages of [`crate::pipeline`] in order,
//! each stage's `lucent` commands run as child processes of this binary with
//! their output in `STAGE/log.txt`; one status line per stage with its time.

use super::choices::{ForceChoice, StageChoice};
use super::interrupt::Interrupt;
use crate::pipeline::{self, project::Project, Options, Stage, Status};
use anyhow::{anyhow, bail, Context, Result};
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
}

/// The last `n` lines of a log file.
fn tail(log: &Path, n: usize) -> String {
    let text = std::fs::read_to_string(log).unwrap_or_default();
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
        bail!("interrupted (Ctrl-C or SIGTERM) before `lucent {}`", args.join(" "));
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
        bail!("interrupted (Ctrl-C or SIGTERM) during `lucent {}`", args.join(" "));
    }
    if status.success() {
        Ok(())
    } else {
        Err(anyhow!(
            "`lucent {}` exited with {status}; the end of {}:\n    {}",
            args.join(" "),
            log.display(),
            tail(log, 12)
        ))
    }
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
    println!("lucent run {} → {}", a.project.display(), out.display());
    let total = std::time::Instant::now();
    let n = Stage::ALL.len();
    // The whole chain of causes goes into the stage's error message.
    // Ctrl-C or SIGTERM: the stage under way fails (its output is kept as
    // STAGE.failed/, the previous result is put back) and no later one starts.
    let interrupt = Interrupt::install();
    let mut exec =
        |args: &[String], log: &Path| run_lucent(&exe, args, log, &interrupt).map_err(|e| format!("{e:#}").into());
    let mut status_line = |stage: Stage, st: &Status, notes: &[String]| {
        let k = Stage::ALL.iter().position(|s| *s == stage).unwrap_or(0) + 1;
        let what = match st {
            Status::Ran { wall_s, tasks } => {
                format!("ran {tasks} task{} in {wall_s:.1} s", if *tasks == 1 { "" } else { "s" })
            }
            Status::UpToDate => "up to date (inputs and parameters unchanged)".into(),
            Status::Skipped { reason } => format!("skipped: {reason}"),
        };
        let notes = if notes.is_empty() { String::new() } else { format!(" [{}]", notes.join("; ")) };
        println!("[{k}/{n}] {:<10} {what}{notes}", stage.name());
    };
    let result = pipeline::run(&project, &out, &Options { force, until }, &mut exec, &mut status_line);
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
