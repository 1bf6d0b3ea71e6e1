//! Parsed command lines → the library's jobs ([`crate::job`]), as ripgrep
//! turns its low-level arguments into its validated `HiArgs`: each
//! command's arguments convert (`From`) into the job the pipeline builds
//! directly from a project, and [`validate`] checks that job before the
//! command does any work, with the same ranges and words for a flag as for
//! the project key. The Python module converts its arguments the same way.
//! [`run_in_process`] runs a job as its command does (`lucent job run
//! JOB.json`, each stage of `lucent run`).

use super::camera::env_hdr;
use super::{bssrdf, camera, colour, compare, env_fit, fit, raw_clip, render, surface, Cli, Command};
use crate::job::run::{Hooks, JobRunError};
use crate::job::{
    BssrdfCompareJob, BssrdfJob, CalibrateJob, ColourApplyJob, ColourCalibrateJob, CompareJob, Context, EnvMergeJob,
    EnvOrientJob, EnvScaleJob, FitJob, Job, JobError, OpticsJob, PoseJob, RawClippedJob, RenderJob, SurfaceFitJob,
};
use crate::pipeline::report::ReportJob;

/// The job of a parsed command, when it has one: a pipeline stage's (a
/// `bssrdf` run needs a `--recipe` to be one), or `surface fit`'s, `env
/// merge`'s or `env orient`'s.
pub fn job_of(command: &Command) -> Option<Job> {
    Some(match command {
        Command::Optics(a) => Job::Optics(a.into()),
        Command::Bssrdf(a) => match &a.command {
            Some(bssrdf::BssrdfCommand::Compare(c)) => Job::BssrdfCompare(c.into()),
            None => Job::Bssrdf(bssrdf_run(&a.run)?),
        },
        Command::Fit(a) => Job::Fit(a.into()),
        Command::Calibrate(a) => Job::Calibrate(a.into()),
        Command::Colour(colour::ColourCommand::Calibrate(a)) => Job::ColourCalibrate(a.into()),
        Command::Colour(colour::ColourCommand::Apply(a)) => Job::ColourApply(a.into()),
        Command::Raw(camera::RawCommand::Clipped(a)) => Job::RawClipped(a.into()),
        Command::Pose(a) => Job::Pose(a.into()),
        Command::Env(camera::EnvCommand::FitScale(a)) => Job::EnvScale(a.into()),
        Command::Env(camera::EnvCommand::Merge(a)) => Job::EnvMerge(a.into()),
        Command::Env(camera::EnvCommand::Orient(a)) => Job::EnvOrient(a.into()),
        Command::Surface(surface::SurfaceCommand::Fit(a)) => Job::SurfaceFit(a.into()),
        Command::Render(a) => Job::Render(a.into()),
        Command::Compare(a) => Job::Compare(a.into()),
        _ => return None,
    })
}

/// Parses a `lucent` command line (without the program name) into its job.
pub fn parse_job(args: &[String]) -> anyhow::Result<Job> {
    let cli = Cli::try_parse_args(std::iter::once("lucent".to_string()).chain(args.iter().cloned()))?;
    job_of(&cli.command).ok_or_else(|| anyhow::anyhow!("`lucent {}` is not a command that runs as a job (`lucent job run` runs the stages' commands, surface fit and env merge, orient, fit-scale)", args.join(" ")))
}

/// Checks the job of a parsed command, if it has one (the flag is named).
pub fn validate(command: &Command) -> Result<(), JobError> {
    job_of(command).map_or(Ok(()), |j| j.validate())
}

impl From<&super::OpticsArgs> for OpticsJob {
    fn from(a: &super::OpticsArgs) -> Self {
        OpticsJob {
            recipes: a.recipes.clone(),
            wavelengths: a.wavelengths.clone(),
            out: crate::job::optics::output_folder(a.out.as_deref(), a.json),
            weight_percent: a.weight_percent,
            wavelength_nm: a.wavelength,
            json: a.json,
            phase_entries: a.phase_entries,
            skip_invalid: a.skip_invalid,
            uncertainty: a.uncertainty,
            uncertainty_seed: a.uncertainty_seed,
            shard: a.shard,
        }
    }
}

impl From<&colour::CalibrateArgs> for ColourCalibrateJob {
    fn from(a: &colour::CalibrateArgs) -> Self {
        ColourCalibrateJob {
            image: a.image.clone(),
            camera: a.camera.clone(),
            out: a.out.clone(),
            corners: a.corners,
            method: a.method,
            decode_srgb: a.decode_srgb,
            clip_level: a.clip_level,
            gap_ratio: a.gap_ratio,
            inner_fraction: a.inner_fraction,
        }
    }
}

impl From<&colour::ApplyArgs> for ColourApplyJob {
    fn from(a: &colour::ApplyArgs) -> Self {
        ColourApplyJob {
            ccm: a.ccm.clone(),
            input: a.input.clone(),
            output: a.output.clone(),
            to: a.to,
            variance_out: a.variance_out.clone().map(|v| (v, a.seed)),
            bin: a.bin,
            adaptation: a.adaptation.cat(),
            variance_realisations: a.variance_realisations,
        }
    }
}

/// The job of a `bssrdf` run when it is a pipeline stage's; `None`
/// without `--recipe` (optical coefficients given directly are no stage's job).
pub fn bssrdf_run(a: &bssrdf::RunArgs) -> Option<BssrdfJob> {
    a.recipe.is_some().then(|| a.into())
}

impl From<&bssrdf::RunArgs> for BssrdfJob {
    fn from(a: &bssrdf::RunArgs) -> Self {
        BssrdfJob {
            recipe: a.recipe.clone(),
            wavelength_nm: a.wavelength,
            configs: a.configs.clone(),
            pixels: a.pixels,
            pixel_mm: a.pixel_mm,
            seed: a.seed,
            quiet: a.quiet,
            out: a.out.clone(),
            weight_percent: a.weight_percent,
            crop: a.crop,
            paths: a.paths,
            rel_error: a.rel_error,
            time_s: a.time_s,
            phase: a.phase,
            mu_s: a.mu_s,
            mu_a: a.mu_a,
            g: a.g,
            n: a.n,
            thickness_mm: a.thickness_mm,
            theta_i: a.theta_i,
            phi_i: a.phi_i,
            theta_o: a.theta_o,
            phi_o: a.phi_o,
            similarity_g: a.similarity_g,
            beam_fwhm_um: a.beam.beam_fwhm_um,
            beam_map: a.beam.beam_map.clone(),
            beam_map_pixel_mm: a.beam.beam_map_pixel_mm,
            pixel_rel_error: a.pixel_rel_error,
            estimator: a.estimator,
            lobe_vertices: a.lobe_vertices,
            roughness: a.roughness.clone(),
            no_fold: a.no_fold,
            uncertainty: a.uncertainty,
            shard: a.shard,
        }
    }
}

impl From<&bssrdf::CompareArgs> for BssrdfCompareJob {
    fn from(c: &bssrdf::CompareArgs) -> Self {
        BssrdfCompareJob {
            measured: c.measured.clone(),
            simulated: c.simulated.clone(),
            out: c.out.clone(),
            measured_pixel_mm: c.measured_pixel_mm,
            threshold: c.threshold,
        }
    }
}

impl From<&fit::FitArgs> for FitJob {
    fn from(a: &fit::FitArgs) -> Self {
        FitJob {
            recipe: a.recipe.clone(),
            measured: a.measured.clone(),
            measured_pixel_mm: a.measured_pixel_mm,
            weight_percent: a.weight_percent,
            free: a.free.clone(),
            wavelength_nm: a.wavelength,
            seed: a.seed,
            quiet: a.quiet,
            objective: a.objective,
            rel_error: a.rel_error,
            paths: a.paths,
            measured_rel_sd: a.measured_rel_sd,
            bounds: a.bounds.clone(),
            threshold: a.threshold,
            out: a.out.clone(),
            beam_fwhm_um: a.beam.beam_fwhm_um,
            beam_map: a.beam.beam_map.clone(),
            beam_map_pixel_mm: a.beam.beam_map_pixel_mm,
            pilot_time_s: a.pilot_time_s,
            thickness_mm: a.thickness_mm,
        }
    }
}

impl From<&camera::CalibrateArgs> for CalibrateJob {
    fn from(a: &camera::CalibrateArgs) -> Self {
        CalibrateJob {
            images: a.images.clone(),
            board: a.board.board,
            square_mm: a.board.square_mm,
            out: a.out.clone(),
            model: a.model,
            detector: a.detector,
            quiet: a.quiet,
        }
    }
}

impl From<&raw_clip::ClippedArgs> for RawClippedJob {
    fn from(a: &raw_clip::ClippedArgs) -> Self {
        RawClippedJob { input: a.input.clone(), out: a.out.clone(), bin: a.bin, level: a.level, dilate: a.dilate }
    }
}

impl From<&camera::PoseArgs> for PoseJob {
    fn from(a: &camera::PoseArgs) -> Self {
        PoseJob {
            camera: a.camera.clone(),
            image: a.image.clone(),
            board: a.board.board,
            square_mm: a.board.square_mm,
            out: a.out.clone(),
            sample: a.sample_corner.zip(a.sample_size_mm),
            keep_all: a.keep_all,
        }
    }
}

impl From<&env_fit::FitScaleArgs> for EnvScaleJob {
    fn from(a: &env_fit::FitScaleArgs) -> Self {
        EnvScaleJob {
            scene: a.scene.clone(),
            photo: a.photo.clone(),
            spp: a.render.spp,
            per_channel: a.per_channel,
            mask: a.mask.clone(),
            size: a.render.size,
            seed: a.render.seed,
            out: a.out.clone(),
            quiet: a.quiet,
            threads: a.render.threads,
        }
    }
}

impl From<&env_hdr::EnvMergeArgs> for EnvMergeJob {
    fn from(a: &env_hdr::EnvMergeArgs) -> Self {
        EnvMergeJob {
            brackets: a.brackets.clone(),
            exposures: a.exposures.clone(),
            out: a.out.clone(),
            method: a.method,
            saturation: a.saturation,
            noise_floor: a.noise_floor,
            saturation_code: a.saturation_code,
            floor_code: a.floor_code,
        }
    }
}

impl From<&env_hdr::EnvOrientArgs> for EnvOrientJob {
    fn from(a: &env_hdr::EnvOrientArgs) -> Self {
        EnvOrientJob {
            input: a.input.clone(),
            yaw: a.yaw,
            board_view: a.board_view,
            board: a.board,
            square_mm: a.square_mm,
            view_size: a.view_size,
            max_tilt_deg: a.max_tilt_deg,
            out: a.out.clone(),
        }
    }
}

impl From<&surface::FitArgs> for SurfaceFitJob {
    fn from(a: &surface::FitArgs) -> Self {
        SurfaceFitJob {
            heightmap: a.heightmap.clone(),
            pitch_um: a.pitch_um,
            pitch_y_um: a.pitch_y_um,
            height_unit: a.height_unit,
            window: a.window,
            sigma_px: a.sigma_px,
            min_weight: a.min_weight,
            keep_tilt: a.keep_tilt,
            fit_tilt: a.fit_tilt,
            out: a.out.clone(),
        }
    }
}

impl From<&render::RenderArgs> for RenderJob {
    fn from(a: &render::RenderArgs) -> Self {
        RenderJob {
            scene: a.scene.clone(),
            spp: a.render.spp,
            quiet: a.quiet,
            time_s: a.time_s,
            size: a.render.size,
            seed: a.render.seed,
            uncertainty: a.uncertainty,
            out: a.out.clone(),
            exposure: a.exposure,
            target_rel_error: a.target_rel_error,
            sampling: a.sampling.map(Into::into),
            dispersion: a.dispersion.map(Into::into),
            similarity_g: a.similarity_g,
            split_entry: a.split_entry,
            shard: a.shard,
            uncertainty_spp: a.uncertainty_spp,
            uncertainty_renders: a.uncertainty_renders,
            threads: a.render.threads,
        }
    }
}

impl From<&compare::CompareArgs> for CompareJob {
    fn from(a: &compare::CompareArgs) -> Self {
        CompareJob {
            photo: a.photo.clone(),
            render: a.render.clone(),
            out: a.out.clone(),
            mask: a.mask.clone(),
            mask_object: a.mask_object.clone(),
            mask_board: a.mask_board.clone(),
            photo_variance: a.photo_variance.clone(),
            photo_repeat: a.photo_repeat.clone(),
            scene: a.scene.clone(),
            data_range: a.data_range,
            luminance: a.luminance,
            exposure: a.exposure,
            refine: a.refine.map(|super::choices::RefineChoice::Ecc| a.refine_motion),
            twin_names: a.twin_names.clone(),
            band: a.band.clone(),
        }
    }
}

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
    let files = job.run()?;
    println!("report: {}", files.html.display());
    println!("metrics: {}", files.metrics.display());
    Ok(())
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
