//! Parsed command lines → the library's jobs ([`crate::job`]), as ripgrep
//! turns its low-level arguments into its validated `HiArgs`: each
//! command's arguments convert (`From`) into the job the pipeline builds
//! directly from a project, and [`validate`] checks that job before the
//! command does any work, with the same ranges and words for a flag as for
//! the project key. The Python module converts its arguments the same way.
//! [`run_in_process`] (in [`super::job_run`]) runs a job as its command does
//! (`lucent job run JOB.json`, each stage of `lucent run`).

use super::args::{Cli, Command, OpticsArgs};
use super::camera::env_hdr;
use super::{bssrdf, camera, colour, compare, env_fit, fit, raw_clip, render, surface};
use crate::job::{
    BssrdfCompareJob, BssrdfJob, CalibrateJob, ColourApplyJob, ColourCalibrateJob, CompareJob, EnvMergeJob,
    EnvOrientJob, EnvScaleJob, FitJob, Job, JobError, OpticsJob, PoseJob, RawClippedJob, RenderJob, SurfaceFitJob,
};

// `lucent job …` and the in-process runner live in `job_run` (the command
// line names `JobCommand`, and `lucent run` runs its stages with them); their
// paths here stay.
pub use super::job_run::{
    in_stage, job_error, read_job, run_command, run_in_process, InStage, JobCommand, JobFileError, JobRunArgs,
};

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

impl From<&OpticsArgs> for OpticsJob {
    fn from(a: &OpticsArgs) -> Self {
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
