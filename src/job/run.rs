//! [`Job::run`] and [`Job::run_with`]: any stage's job run in this process,
//! as `lucent run` runs a stage and `lucent job run JOB.json` a job file.
//! It keeps the rules of [`super::guard`] (an output never over an input,
//! an output folder that is lucent's or new, marked when the work is done),
//! checks the job ([`Job::validate`]), then runs the stage's own `run` and
//! returns its typed outputs ([`JobRun`]). The caller watches a render or a
//! slab simulation through [`Hooks`] (a progress bar).

use super::bssrdf::{NoHooks, SliceHooks};
use super::context::Context;
use super::fields::JobError;
use super::guard::{FileRoleError, OutputFolder};
use super::render::RenderHooks;
use super::spec::Job;
use crate::fault::{Fault, Interrupted};
use crate::io::{OutputFolderError, WriteError};

/// What a job was given to watch it run: the hooks of a render (also the
/// empty-board render of env-scale) and of a slab simulation. `None` (as
/// in [`Hooks::none`]): nobody watches.
#[derive(Default)]
pub struct Hooks<'a> {
    pub render: Option<&'a mut dyn RenderHooks>,
    pub slices: Option<&'a mut dyn SliceHooks>,
}

impl<'a> Hooks<'a> {
    /// Both hooks.
    pub fn new(render: &'a mut dyn RenderHooks, slices: &'a mut dyn SliceHooks) -> Self {
        Hooks { render: Some(render), slices: Some(slices) }
    }

    /// No hooks: what [`Job::run`] runs with.
    pub fn none() -> Self {
        Hooks::default()
    }
}

/// What a job produced: the run of its stage (files written, figures), boxed (the runs differ in size).
pub enum JobRun {
    Optics(Box<super::optics::OpticsRun>),
    Bssrdf(Box<super::bssrdf::BssrdfRun>),
    BssrdfCompare(Box<super::bssrdf::BssrdfCompareRun>),
    Fit(Box<super::fit::FitRun>),
    ColourCalibrate(Box<super::colour::ColourCalibrateRun>),
    ColourApply(Box<super::colour::ColourApplyRun>),
    RawClipped(Box<super::raw::RawClippedRun>),
    Calibrate(Box<super::camera::CalibrateRun>),
    Pose(Box<super::camera::PoseRun>),
    EnvScale(Box<super::env_scale::EnvScaleRun>),
    Render(Box<super::render::RenderRun>),
    Compare(Box<super::compare::CompareRun>),
    SurfaceFit(Box<super::surface_fit::SurfaceFitRun>),
    EnvMerge(Box<super::env_merge::EnvMergeRun>),
    EnvOrient(Box<super::env_orient::EnvOrientRun>),
}

impl JobRun {
    /// The lines the job's command prints when it is done.
    pub fn summary(&self) -> Vec<String> {
        match self {
            JobRun::Optics(r) => r.summary(),
            JobRun::Bssrdf(r) => r.summary(),
            JobRun::BssrdfCompare(r) => r.summary(),
            JobRun::Fit(r) => r.summary(),
            JobRun::ColourCalibrate(r) => r.summary(),
            JobRun::ColourApply(r) => r.summary(),
            JobRun::RawClipped(r) => r.summary(),
            JobRun::Calibrate(r) => r.summary(),
            JobRun::Pose(r) => r.summary(),
            JobRun::EnvScale(r) => r.summary(),
            JobRun::Render(r) => r.summary(),
            JobRun::Compare(r) => r.summary(),
            JobRun::SurfaceFit(r) => r.summary(),
            JobRun::EnvMerge(r) => r.summary(),
            JobRun::EnvOrient(r) => r.summary(),
        }
    }

    /// `Err` when the run wrote its outputs but failed all the same: Ctrl-C
    /// or SIGTERM stopped a render or a slab simulation (its files hold what
    /// was finished, labelled), or the data cannot pin a fit's free
    /// parameters down. Its command prints the [`JobRun::summary`], then
    /// fails with this error.
    pub fn finished(&self) -> Result<(), JobRunError> {
        match self {
            JobRun::Render(r) => match &r.interrupted {
                Some(Interrupted(what)) => Err(JobRunError::Interrupted(Interrupted(what.clone()))),
                None => Ok(()),
            },
            JobRun::Bssrdf(r) => r.finished().map_err(JobRunError::Interrupted),
            JobRun::Fit(r) => r.finished().map_err(JobRunError::from),
            _ => Ok(()),
        }
    }
}

/// Why a job did not run, or how its stage failed: each variant holds the
/// stage's own error, so its fault class is read from it
/// ([`JobRunError::fault`]; match on the variant rather than classing the
/// wrapper, whose transparent variants forward to the inner error's causes
/// and hide its type). A stage stopped by Ctrl-C or SIGTERM is
/// [`JobRunError::Interrupted`].
#[derive(Debug, thiserror::Error)]
pub enum JobRunError {
    #[error(transparent)]
    Invalid(#[from] JobError),
    #[error(transparent)]
    Files(#[from] FileRoleError),
    #[error(transparent)]
    Folder(#[from] OutputFolderError),
    #[error(transparent)]
    Mark(#[from] WriteError),
    #[error(transparent)]
    Optics(#[from] super::optics::OpticsJobError),
    /// A slab simulation or a comparison of slices (an interrupted one is [`JobRunError::Interrupted`]).
    #[error(transparent)]
    Bssrdf(super::bssrdf::BssrdfJobError),
    /// A fit (an interrupted one is [`JobRunError::Interrupted`]).
    #[error(transparent)]
    Fit(super::fit::FitJobError),
    #[error(transparent)]
    Colour(#[from] super::colour::ColourJobError),
    #[error(transparent)]
    RawClipped(#[from] super::raw::RawClippedError),
    #[error(transparent)]
    Camera(#[from] super::camera::CameraJobError),
    /// (Boxed, as is a render's: the largest errors.)
    #[error(transparent)]
    EnvScale(Box<super::env_scale::EnvScaleJobError>),
    #[error(transparent)]
    Render(Box<super::render::RenderError>),
    #[error(transparent)]
    Compare(#[from] crate::compare::CompareError),
    #[error(transparent)]
    SurfaceFit(#[from] super::surface_fit::SurfaceFitError),
    #[error(transparent)]
    EnvMerge(#[from] super::env_merge::EnvMergeError),
    #[error(transparent)]
    EnvOrient(#[from] super::env_orient::EnvOrientError),
    /// Ctrl-C or SIGTERM stopped the stage.
    #[error(transparent)]
    Interrupted(#[from] Interrupted),
}

impl From<super::bssrdf::BssrdfJobError> for JobRunError {
    /// An interrupted simulation as the [`Interrupted`] it is.
    fn from(e: super::bssrdf::BssrdfJobError) -> Self {
        match e.into_parts() {
            Ok(e) => JobRunError::Bssrdf(e),
            Err(i) => JobRunError::Interrupted(i),
        }
    }
}

impl From<super::fit::FitJobError> for JobRunError {
    /// An interrupted fit as the [`Interrupted`] it is.
    fn from(e: super::fit::FitJobError) -> Self {
        match e.into_parts() {
            Ok(e) => JobRunError::Fit(e),
            Err(i) => JobRunError::Interrupted(i),
        }
    }
}

impl From<super::env_scale::EnvScaleJobError> for JobRunError {
    fn from(e: super::env_scale::EnvScaleJobError) -> Self {
        JobRunError::EnvScale(Box::new(e))
    }
}

impl From<super::render::RenderError> for JobRunError {
    fn from(e: super::render::RenderError) -> Self {
        JobRunError::Render(Box::new(e))
    }
}

impl JobRunError {
    /// The stage's own error inside the variant.
    pub fn inner(&self) -> &(dyn std::error::Error + Send + Sync + 'static) {
        match self {
            JobRunError::Invalid(e) => e,
            JobRunError::Files(e) => e,
            JobRunError::Folder(e) => e,
            JobRunError::Mark(e) => e,
            JobRunError::Optics(e) => e,
            JobRunError::Bssrdf(e) => e,
            JobRunError::Fit(e) => e,
            JobRunError::Colour(e) => e,
            JobRunError::RawClipped(e) => e,
            JobRunError::Camera(e) => e,
            JobRunError::EnvScale(e) => e.as_ref(),
            JobRunError::Render(e) => e.as_ref(),
            JobRunError::Compare(e) => e,
            JobRunError::SurfaceFit(e) => e,
            JobRunError::EnvMerge(e) => e,
            JobRunError::EnvOrient(e) => e,
            JobRunError::Interrupted(e) => e,
        }
    }

    /// Who is at fault ([`Fault::of`] the stage's own error).
    pub fn fault(&self) -> Fault {
        Fault::of(self.inner())
    }
}

impl Job {
    /// Runs the job with nobody watching ([`Job::run_with`] with [`Hooks::none`]).
    pub fn run(&self, ctx: &Context) -> Result<JobRun, JobRunError> {
        self.run_with(ctx, Hooks::none())
    }

    /// Runs the job: its files checked ([`Job::check_files`]), its output
    /// folder opened ([`OutputFolder::open`]), the job checked
    /// ([`Job::validate`]) and run, `hooks` told of a render's passes and a
    /// slab simulation's progress, the folder closed: marked when the run
    /// succeeded or was interrupted and kept what it finished, removed when
    /// it failed and left the folder empty. A run that wrote its outputs but
    /// failed ([`JobRun::finished`]) counts as failed here and is returned
    /// as `Ok`, for its summary.
    pub fn run_with(&self, ctx: &Context, hooks: Hooks<'_>) -> Result<JobRun, JobRunError> {
        self.check_files()?;
        let folder = OutputFolder::open(self.output_folder())?;
        let result = self.validate().map_err(JobRunError::from).and_then(|()| self.run_stage(ctx, hooks));
        let failure = match &result {
            Ok(run) => run.finished().err().map(|e| e.fault()),
            Err(e) => Some(e.fault()),
        };
        folder.close(failure.is_none(), failure == Some(Fault::Interrupted))?;
        result
    }

    fn run_stage(&self, ctx: &Context, hooks: Hooks<'_>) -> Result<JobRun, JobRunError> {
        let (mut no_render, mut no_slices) = ((), NoHooks);
        let render: &mut dyn RenderHooks = match hooks.render {
            Some(h) => h,
            None => &mut no_render,
        };
        let slices: &mut dyn SliceHooks = match hooks.slices {
            Some(h) => h,
            None => &mut no_slices,
        };
        Ok(match self {
            Job::Optics(j) => JobRun::Optics(Box::new(j.run(ctx)?)),
            Job::Bssrdf(j) => JobRun::Bssrdf(Box::new(j.run(ctx, slices)?)),
            Job::BssrdfCompare(j) => JobRun::BssrdfCompare(Box::new(j.run(ctx)?)),
            Job::Fit(j) => JobRun::Fit(Box::new(j.run(ctx)?)),
            Job::ColourCalibrate(j) => JobRun::ColourCalibrate(Box::new(j.run(ctx)?)),
            Job::ColourApply(j) => JobRun::ColourApply(Box::new(j.run(ctx)?)),
            Job::RawClipped(j) => JobRun::RawClipped(Box::new(j.run(ctx)?)),
            Job::Calibrate(j) => JobRun::Calibrate(Box::new(j.run(ctx)?)),
            Job::Pose(j) => JobRun::Pose(Box::new(j.run(ctx)?)),
            Job::EnvScale(j) => JobRun::EnvScale(Box::new(j.run_with(ctx, render)?)),
            Job::Render(j) => JobRun::Render(Box::new(j.run_with(ctx, render)?)),
            Job::Compare(j) => JobRun::Compare(Box::new(j.run(ctx)?)),
            Job::SurfaceFit(j) => JobRun::SurfaceFit(Box::new(j.run(ctx)?)),
            Job::EnvMerge(j) => JobRun::EnvMerge(Box::new(j.run(ctx)?)),
            Job::EnvOrient(j) => JobRun::EnvOrient(Box::new(j.run(ctx)?)),
        })
    }
}
