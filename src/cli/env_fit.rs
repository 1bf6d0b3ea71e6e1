//! `lucent env fit-scale`: the environment's radiance scale from the
//! photographed empty board. The flags become an [`EnvScaleJob`], whose
//! `run` (`lucent::job`'s env-scale stage) renders the empty board, fits
//! the scale and writes its files ([`crate::envfit::EnvScaleFiles`]) in
//! `--out`; this module parses the flags and prints the job's summary.

use crate::job::{Context, EnvScaleJob};
use anyhow::Result;
use clap::Args;
use std::path::PathBuf;

#[derive(Debug, Args)]
pub struct FitScaleArgs {
    /// Scene file of the twin (its object and material are left out: the empty board is rendered).
    pub scene: PathBuf,
    /// The photographed empty board (linear EXR, the scene camera's image size).
    #[arg(long)]
    pub photo: PathBuf,
    /// Restrict the fit to the nonzero pixels of this mask image (intersected with the board).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Scale each channel on its own (written to the scene when the environment is a constant).
    #[arg(long)]
    pub per_channel: bool,
    /// The empty-board render, as `lucent render` takes it.
    #[command(flatten)]
    pub render: super::groups::TwinRenderArgs,
    /// Output folder.
    #[arg(long, default_value = "lucent-out/env-scale")]
    pub out: PathBuf,
    /// No progress bar or progress lines.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs `lucent env fit-scale`: the job of the flags
/// ([`EnvScaleJob::run_with`], the render's progress bar on the terminal),
/// then its summary on stdout.
pub fn run(a: FitScaleArgs) -> Result<()> {
    let job = EnvScaleJob::from(&a);
    let done = job.run_with(&Context::default(), &mut super::render::Terminal::new(job.quiet))?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(())
}
