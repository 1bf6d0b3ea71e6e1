//! Parsed command lines → the library's jobs ([`crate::job`]), as ripgrep
//! turns its low-level arguments into its validated `HiArgs`: each
//! command's arguments convert (`From`) into the job the pipeline builds
//! directly from a project, and [`validate`] checks that job before the
//! command does any work, with the same ranges and words for a flag as for
//! the project key. The Python module converts its arguments the same way.

use super::choices::name;
use super::{bssrdf, camera, colour, compare, env_fit, fit, raw_clip, render, Cli, Command};
use crate::job::{
    BssrdfCompareJob, BssrdfJob, CalibrateJob, ColourApplyJob, ColourCalibrateJob, CompareJob, EnvScaleJob, FitJob,
    Job, JobError, OpticsJob, PoseJob, RawClippedJob, RenderJob,
};

/// The job of a parsed command, when it is one a pipeline stage runs (a
/// `bssrdf` run needs a `--recipe` to be one).
pub fn job_of(command: &Command) -> Option<Job> {
    Some(match command {
        Command::Optics(a) => Job::Optics(a.into()),
        Command::Bssrdf(a) => match &a.command {
            Some(bssrdf::BssrdfCommand::Compare(c)) => Job::BssrdfCompare(c.into()),
            None => Job::Bssrdf(bssrdf_run(&a.run)?),
        },
        Command::Fit(a) => Job::Fit(a.into()),
        Command::Calibrate(a) => Job::Calibrate(a.into()),
        Command::Colour(colour::ColourCommand::Calibrate(a)) => Job::ColourCalibrate(ColourCalibrateJob {
            image: a.image.clone(),
            camera: a.camera.clone(),
            out: a.out.clone(),
            corners: a.corners.clone(),
            method: a.method,
            decode_srgb: a.decode_srgb,
        }),
        Command::Colour(colour::ColourCommand::Apply(a)) => Job::ColourApply(ColourApplyJob {
            ccm: a.ccm.clone(),
            input: a.input.clone(),
            output: a.output.clone(),
            to: name(&a.to),
            variance_out: a.variance_out.clone().map(|v| (v, a.seed)),
            bin: a.bin,
        }),
        Command::Raw(camera::RawCommand::Clipped(a)) => Job::RawClipped(a.into()),
        Command::Pose(a) => Job::Pose(a.into()),
        Command::Env(camera::EnvCommand::FitScale(a)) => Job::EnvScale(a.into()),
        Command::Render(a) => Job::Render(a.into()),
        Command::Compare(a) => Job::Compare(a.into()),
        _ => return None,
    })
}

/// Parses a `lucent` command line (without the program name) into its job.
pub fn parse_job(args: &[String]) -> anyhow::Result<Job> {
    let cli = Cli::try_parse_args(std::iter::once("lucent".to_string()).chain(args.iter().cloned()))?;
    job_of(&cli.command).ok_or_else(|| anyhow::anyhow!("`lucent {}` is not a job of a pipeline stage", args.join(" ")))
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
            out: a.out.clone().unwrap_or_else(|| "lucent-out/optics".into()),
            weight_percent: a.weight_percent,
        }
    }
}

/// The job of a `bssrdf` run; `None` without `--recipe` (optical
/// coefficients given directly are no pipeline stage's job).
pub fn bssrdf_run(a: &bssrdf::RunArgs) -> Option<BssrdfJob> {
    Some(BssrdfJob {
        recipe: a.recipe.clone()?,
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
    })
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
            free: a.free.split(',').map(|f| f.trim().to_string()).filter(|f| !f.is_empty()).collect(),
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
        }
    }
}

impl From<&camera::CalibrateArgs> for CalibrateJob {
    fn from(a: &camera::CalibrateArgs) -> Self {
        CalibrateJob {
            images: a.images.clone(),
            board: a.board.board.clone(),
            square_mm: a.board.square_mm,
            out: a.out.clone(),
            model: a.model,
        }
    }
}

impl From<&raw_clip::ClippedArgs> for RawClippedJob {
    fn from(a: &raw_clip::ClippedArgs) -> Self {
        RawClippedJob { input: a.input.clone(), out: a.out.clone(), bin: a.bin }
    }
}

impl From<&camera::PoseArgs> for PoseJob {
    fn from(a: &camera::PoseArgs) -> Self {
        PoseJob {
            camera: a.camera.clone(),
            image: a.image.clone(),
            board: a.board.board.clone(),
            square_mm: a.board.square_mm,
            out: a.out.clone(),
            sample: a.sample_corner.clone().zip(a.sample_size_mm.clone()),
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
            size: a.render.size.clone(),
            seed: a.render.seed,
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
            size: a.render.size.clone(),
            seed: a.render.seed,
            uncertainty: a.uncertainty,
            out: a.out.clone(),
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
            photo_variance: a.photo_variance.clone(),
            data_range: a.data_range,
            twin_names: a.twin_names.clone(),
            band: a.band.clone(),
        }
    }
}
