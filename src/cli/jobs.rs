//! Parsed command lines → the library's jobs ([`crate::job`]): the flags a
//! job models, copied into it; the command then validates the job (the
//! ranges the pipeline checks too).

use super::{bssrdf, camera, colour, compare, env_fit, fit, raw_clip, render, Cli, Command};
use crate::job::{
    BssrdfCompareJob, BssrdfJob, CalibrateJob, ColourApplyJob, ColourCalibrateJob, CompareJob, EnvScaleJob, FitJob,
    Job, JobError, OpticsJob, PoseJob, RawClippedJob, RenderJob,
};
use clap::{Parser, ValueEnum};

/// The name a choice is spelled with on the command line.
fn name<T: ValueEnum>(v: &T) -> String {
    v.to_possible_value().map(|p| p.get_name().to_string()).unwrap_or_default()
}

/// The job of a parsed command, when it is one a pipeline stage runs (a
/// `bssrdf` run needs a `--recipe` to be one).
pub fn job_of(command: &Command) -> Option<Job> {
    Some(match command {
        Command::Optics(a) => Job::Optics(optics(a)),
        Command::Bssrdf(a) => match &a.command {
            Some(bssrdf::BssrdfCommand::Compare(c)) => Job::BssrdfCompare(bssrdf_compare(c)),
            None => Job::Bssrdf(bssrdf_run(&a.run)?),
        },
        Command::Fit(a) => Job::Fit(fit(a)),
        Command::Calibrate(a) => Job::Calibrate(calibrate(a)),
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
        }),
        Command::Raw(camera::RawCommand::Clipped(a)) => Job::RawClipped(raw_clipped(a)),
        Command::Pose(a) => Job::Pose(pose(a)),
        Command::Env(camera::EnvCommand::FitScale(a)) => Job::EnvScale(env_scale(a)),
        Command::Render(a) => Job::Render(render(a)),
        Command::Compare(a) => Job::Compare(compare(a)),
        _ => return None,
    })
}

/// Parses a `lucent` command line (without the program name) into its job.
pub fn parse_job(args: &[String]) -> anyhow::Result<Job> {
    let cli = Cli::try_parse_from(std::iter::once("lucent".to_string()).chain(args.iter().cloned()))?;
    job_of(&cli.command).ok_or_else(|| anyhow::anyhow!("`lucent {}` is not a job of a pipeline stage", args.join(" ")))
}

/// Checks the job of a parsed command, if it has one (the flag is named).
pub fn validate(command: &Command) -> Result<(), JobError> {
    job_of(command).map_or(Ok(()), |j| j.validate())
}

fn optics(a: &super::OpticsArgs) -> OpticsJob {
    OpticsJob {
        recipes: a.recipes.clone(),
        wavelengths: a.wavelengths.clone(),
        out: a.out.clone().unwrap_or_else(|| "lucent-out/optics".into()),
        weight_percent: a.weight_percent,
    }
}

fn bssrdf_run(a: &bssrdf::RunArgs) -> Option<BssrdfJob> {
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
        phase: a.phase.as_ref().map(name),
    })
}

fn bssrdf_compare(c: &bssrdf::CompareArgs) -> BssrdfCompareJob {
    BssrdfCompareJob {
        measured: c.measured.clone(),
        simulated: c.simulated.clone(),
        out: c.out.clone(),
        measured_pixel_mm: c.measured_pixel_mm,
        threshold: c.threshold,
    }
}

fn fit(a: &fit::FitArgs) -> FitJob {
    FitJob {
        recipe: a.recipe.clone(),
        measured: a.measured.clone(),
        measured_pixel_mm: a.measured_pixel_mm,
        weight_percent: a.weight_percent,
        free: a.free.split(',').map(|f| f.trim().to_string()).filter(|f| !f.is_empty()).collect(),
        wavelength_nm: a.wavelength,
        seed: a.seed,
        quiet: a.quiet,
        objective: name(&a.objective),
        rel_error: a.rel_error,
        paths: a.paths,
        measured_rel_sd: a.measured_rel_sd,
        bounds: a.bounds.clone(),
        threshold: a.threshold,
        out: a.out.clone(),
    }
}

fn calibrate(a: &camera::CalibrateArgs) -> CalibrateJob {
    CalibrateJob {
        images: a.images.clone(),
        board: a.board.clone(),
        square_mm: a.square_mm,
        out: a.out.clone(),
        model: a.model,
    }
}

fn raw_clipped(a: &raw_clip::ClippedArgs) -> RawClippedJob {
    RawClippedJob { input: a.input.clone(), out: a.out.clone() }
}

fn pose(a: &camera::PoseArgs) -> PoseJob {
    PoseJob {
        camera: a.camera.clone(),
        image: a.image.clone(),
        board: a.board.clone(),
        square_mm: a.square_mm,
        out: a.out.clone(),
        sample: a.sample_corner.clone().zip(a.sample_size_mm.clone()),
    }
}

fn env_scale(a: &env_fit::FitScaleArgs) -> EnvScaleJob {
    EnvScaleJob {
        scene: a.scene.clone(),
        photo: a.photo.clone(),
        spp: a.spp,
        per_channel: a.per_channel,
        mask: a.mask.clone(),
        size: a.size.clone(),
        seed: a.seed,
        out: a.out.clone(),
    }
}

fn render(a: &render::RenderArgs) -> RenderJob {
    RenderJob {
        scene: a.scene.clone(),
        spp: a.spp,
        quiet: a.quiet,
        time_s: a.time_s,
        size: a.size.clone(),
        seed: a.seed,
        out: a.out.clone(),
    }
}

fn compare(a: &compare::CompareArgs) -> CompareJob {
    CompareJob {
        photo: a.photo.clone(),
        render: a.render.clone(),
        out: a.out.clone(),
        mask: a.mask.clone(),
        data_range: a.data_range,
    }
}
