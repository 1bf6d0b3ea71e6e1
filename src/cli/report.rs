//! `lucent report PROJECT.toml`: the report of a run's folder
//! ([`ReportJob`]), as `lucent run`'s report stage writes it — for a folder
//! whose stages ran elsewhere (shards merged on a cluster, a stage rerun by
//! its own command). The command parses its flags into the job; the job
//! does the work.

use crate::pipeline::project::Project;
use crate::pipeline::report::ReportJob;
use anyhow::Result;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct ReportArgs {
    /// Project file (TOML) whose run it is.
    pub project: PathBuf,
    /// The run's folder (default: the project's [project] out, else lucent-out/NAME, as `lucent run`).
    #[arg(long)]
    pub run: Option<PathBuf>,
    /// The report's folder (default: RUN/report).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// The job of `lucent report`: its folders from the flags, else as
/// `lucent run` chooses them (the project read for its defaults).
pub fn job(a: &ReportArgs) -> Result<ReportJob> {
    let project = Project::load(&a.project)?;
    let run = project.run_folder(a.run.as_deref());
    let out = a.out.clone().unwrap_or_else(|| run.join(crate::pipeline::Stage::Report.name()));
    Ok(ReportJob { project: a.project.clone(), run, out, stages: Default::default() })
}

/// Runs `lucent report`.
pub fn run(a: ReportArgs) -> Result<()> {
    let job = job(&a)?;
    job.validate()?;
    if !job.run.is_dir() {
        anyhow::bail!("--run {}: no such folder (run `lucent run {}` first)", job.run.display(), a.project.display());
    }
    super::job_run::run_report(&job)
}
