//! `lucent job run JOB.json`, and running a job in this process as its
//! command runs it ([`run_in_process`], also each stage of `lucent run`,
//! inside an [`InStage`]): the terminal's hooks, the summary on stdout, the
//! stage's own error.

use super::{bssrdf, render};
use crate::job::run::{Hooks, JobRunError};
use crate::job::{Context, Job, JobError};
use crate::pipeline::report::{ReportFiles, ReportJob};

/// Runs a job in this process as its command runs it, for `lucent job run`
/// and the stages of `lucent run`: [`Job::run_with`] with the terminal's
/// hooks (the progress bars of a render and of a slab simulation, hidden
/// when the job is quiet), the
/// job's summary on stdout, and a run that wrote its outputs but failed
/// ([`JobRun::finished`](crate::job::run::JobRun::finished): interrupted,
/// a fit the data cannot pin down) failing after its summary.
pub fn run_in_process(job: &Job) -> anyhow::Result<()> {
    let quiet = match job {
        Job::Render(j) => j.quiet,
        Job::Bssrdf(j) => j.quiet,
        Job::EnvScale(j) => j.quiet,
        _ => false,
    };
    let (mut terminal, mut bars) = (render::Terminal::new(quiet), bssrdf::Bar::new(quiet));
    let done = job.run_with(&Context::default(), Hooks::new(&mut terminal, &mut bars)).map_err(job_error)?;
    for line in done.summary() {
        println!("{line}");
    }
    done.finished().map_err(job_error)
}

/// A job's error as its command returns it: the stage's own error (not the
/// wrapper, whose transparent variants hide its type), so that its fault
/// class is read from it ([`crate::pipeline::fault_of`]: a run stopped by
/// Ctrl-C exits with 130, a bad input with 1).
pub fn job_error(e: JobRunError) -> anyhow::Error {
    match e {
        JobRunError::Invalid(e) => e.into(),
        JobRunError::Files(e) => e.into(),
        JobRunError::Folder(e) => e.into(),
        JobRunError::Mark(e) => e.into(),
        JobRunError::Optics(e) => e.into(),
        JobRunError::Bssrdf(e) => e.into(),
        JobRunError::Fit(e) => e.into(),
        JobRunError::Colour(e) => e.into(),
        JobRunError::RawClipped(e) => e.into(),
        JobRunError::Camera(e) => e.into(),
        JobRunError::EnvScale(e) => (*e).into(),
        JobRunError::Render(e) => (*e).into(),
        JobRunError::Compare(e) => e.into(),
        JobRunError::SurfaceFit(e) => e.into(),
        JobRunError::EnvMerge(e) => e.into(),
        JobRunError::EnvOrient(e) => e.into(),
        JobRunError::Interrupted(e) => e.into(),
    }
}

/// How many stages of `lucent run` are running a command in this process.
static IN_STAGE: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

/// While alive: a command runs in this process as a stage of `lucent run`
/// ([`in_stage`]).
pub struct InStage(());

impl InStage {
    pub fn enter() -> Self {
        IN_STAGE.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        InStage(())
    }
}

impl Drop for InStage {
    fn drop(&mut self) {
        IN_STAGE.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
    }
}

/// Whether a command runs as a stage of `lucent run` in this process: a
/// panic then unwinds to the stage (which classes it) instead of ending
/// the process.
pub fn in_stage() -> bool {
    IN_STAGE.load(std::sync::atomic::Ordering::SeqCst) > 0
}

/// `lucent job …`.
#[derive(Debug, clap::Subcommand)]
pub enum JobCommand {
    /// Run one job (JSON, as a stage of `lucent run` holds it: `{"render": {"scene": …, "out": …}}`,
    /// every key in docs/formats.md#job) exactly as its command would run.
    Run(JobRunArgs),
}

#[derive(Debug, clap::Args)]
pub struct JobRunArgs {
    /// The job file (JSON).
    pub job: std::path::PathBuf,
}

/// Why a job file cannot be run.
#[derive(Debug, thiserror::Error)]
pub enum JobFileError {
    #[error("{path}: cannot read: {source}")]
    Read { path: std::path::PathBuf, source: std::io::Error },
    #[error("{path}: not a job of lucent (JSON, e.g. {{\"render\": {{\"scene\": \"scene.toml\", …}}}}): {source}")]
    Parse { path: std::path::PathBuf, source: serde_json::Error },
    #[error("{path}: holds the placeholder {{out}} (a stage folder of `lucent run`): give the output folder itself")]
    Placeholder { path: std::path::PathBuf },
    #[error("{path}: {source}")]
    Invalid { path: std::path::PathBuf, source: JobError },
    #[error("{path}: {source}")]
    Report { path: std::path::PathBuf, source: crate::pipeline::report::ReportJobError },
}

/// What a job file holds: a stage's or a command's job, or the report's
/// (`{"report": {"project": …, "run": …, "out": …}}`, which reads the whole
/// run and so lives with the pipeline, [`ReportJob`]).
#[derive(Debug)]
pub enum JobFile {
    Job(Box<Job>),
    Report(ReportJob),
}

/// A report job as its file holds it.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ReportJobFile {
    report: ReportJob,
}

/// Reads and checks a job file.
pub fn read_job(path: &std::path::Path) -> Result<JobFile, JobFileError> {
    let text = crate::io::read_text(path).map_err(|source| JobFileError::Read { path: path.to_path_buf(), source })?;
    let parse = |source| JobFileError::Parse { path: path.to_path_buf(), source };
    let is_report = serde_json::from_str::<serde_json::Value>(&text)
        .is_ok_and(|v| v.as_object().is_some_and(|o| o.len() == 1 && o.contains_key("report")));
    let job = if is_report {
        JobFile::Report(serde_json::from_str::<ReportJobFile>(&text).map_err(parse)?.report)
    } else {
        JobFile::Job(Box::new(serde_json::from_str(&text).map_err(parse)?))
    };
    let placeholder = match &job {
        JobFile::Job(j) => serde_json::to_string(j),
        JobFile::Report(j) => serde_json::to_string(j),
    };
    if placeholder.is_ok_and(|t| t.contains("{out}")) {
        return Err(JobFileError::Placeholder { path: path.to_path_buf() });
    }
    match &job {
        JobFile::Job(j) => j.validate().map_err(|source| JobFileError::Invalid { path: path.to_path_buf(), source })?,
        JobFile::Report(j) => {
            j.validate().map_err(|source| JobFileError::Report { path: path.to_path_buf(), source })?
        }
    }
    Ok(job)
}

/// Runs a report job as `lucent report` does: the report written, its
/// files printed.
pub fn run_report(job: &ReportJob) -> anyhow::Result<()> {
    print_report(&job.run()?);
    Ok(())
}

/// The lines that name a written report (`lucent run`, `lucent report`,
/// `lucent job run`).
pub fn print_report(files: &ReportFiles) {
    println!("report: {}", files.html.display());
    println!("metrics: {}", files.metrics.display());
}

/// Runs `lucent job …`.
pub fn run_command(c: JobCommand) -> anyhow::Result<()> {
    match c {
        JobCommand::Run(a) => match read_job(&a.job)? {
            JobFile::Job(job) => run_in_process(&job),
            JobFile::Report(job) => run_report(&job),
        },
    }
}
