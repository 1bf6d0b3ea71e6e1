//! [`Job::run`]: any stage's job run in this process, as `lucent run` runs
//! a stage and `lucent job run JOB.json` a job file. It keeps the rules of
//! [`super::guard`] (an output never over an input, an output folder that
//! is lucent's or new, marked when the work is done), checks the job
//! ([`Job::validate`]), then runs the stage's own `run` and returns its
//! typed outputs ([`JobRun`]).

use super::guard::{FileRoleError, OutputFolder};
use super::{Context, Job, JobError};
use crate::io::{OutputFolderError, WriteError};

/// What a job produced: the run of its stage (files written, figures), boxed (the runs differ in size).
pub enum JobRun {
    Optics(Box<super::OpticsRun>),
    ColourCalibrate(Box<super::ColourCalibrateRun>),
    ColourApply(Box<super::ColourApplyRun>),
    RawClipped(Box<super::RawClippedRun>),
    Calibrate(Box<super::CalibrateRun>),
    Pose(Box<super::PoseRun>),
    Compare(Box<super::CompareRun>),
}

impl JobRun {
    /// The lines the job's command prints when it is done.
    pub fn summary(&self) -> Vec<String> {
        match self {
            JobRun::Optics(r) => r.summary(),
            JobRun::ColourCalibrate(r) => r.summary(),
            JobRun::ColourApply(r) => r.summary(),
            JobRun::RawClipped(r) => r.summary(),
            JobRun::Calibrate(r) => r.summary(),
            JobRun::Pose(r) => r.summary(),
            JobRun::Compare(r) => r.summary(),
        }
    }
}

/// Why a job did not run, or how its stage failed: each variant holds the
/// stage's own error (so its fault class, [`crate::fault::Fault::of`],
/// is read from it: match on the variant rather than classing the wrapper,
/// whose transparent variants forward to the inner error's causes).
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
    Optics(#[from] super::OpticsJobError),
    #[error(transparent)]
    Colour(#[from] super::ColourJobError),
    #[error(transparent)]
    RawClipped(#[from] super::RawClippedError),
    #[error(transparent)]
    Camera(#[from] super::CameraJobError),
    #[error(transparent)]
    Compare(#[from] crate::compare::CompareError),
    /// A stage whose work is still its command's ([`Job::runs_in_library`]).
    #[error("`lucent {0}` runs as its command, not yet as a library job")]
    NotInLibrary(&'static str),
}

impl Job {
    /// Whether [`Job::run`] runs this job (else its command does).
    pub fn runs_in_library(&self) -> bool {
        matches!(
            self,
            Job::Optics(_)
                | Job::ColourCalibrate(_)
                | Job::ColourApply(_)
                | Job::RawClipped(_)
                | Job::Calibrate(_)
                | Job::Pose(_)
                | Job::Compare(_)
        )
    }

    /// Runs the job: its files checked ([`Job::check_files`]), its output
    /// folder opened ([`OutputFolder::open`]), the job checked
    /// ([`Job::validate`]) and run, the folder closed (marked, or removed
    /// when the run failed and left it empty).
    pub fn run(&self, ctx: &Context) -> Result<JobRun, JobRunError> {
        if !self.runs_in_library() {
            return Err(JobRunError::NotInLibrary(self.command_name()));
        }
        self.check_files()?;
        let folder = OutputFolder::open(self.output_folder())?;
        let result = self.validate().map_err(JobRunError::from).and_then(|()| self.run_stage(ctx));
        let interrupted =
            result.as_ref().is_err_and(|e| crate::fault::Fault::of(e) == crate::fault::Fault::Interrupted);
        folder.close(result.is_ok(), interrupted)?;
        result
    }

    fn run_stage(&self, ctx: &Context) -> Result<JobRun, JobRunError> {
        Ok(match self {
            Job::Optics(j) => JobRun::Optics(Box::new(j.run(ctx)?)),
            Job::ColourCalibrate(j) => JobRun::ColourCalibrate(Box::new(j.run(ctx)?)),
            Job::ColourApply(j) => JobRun::ColourApply(Box::new(j.run(ctx)?)),
            Job::RawClipped(j) => JobRun::RawClipped(Box::new(j.run(ctx)?)),
            Job::Calibrate(j) => JobRun::Calibrate(Box::new(j.run(ctx)?)),
            Job::Pose(j) => JobRun::Pose(Box::new(j.run(ctx)?)),
            Job::Compare(j) => JobRun::Compare(Box::new(j.run(ctx)?)),
            other => return Err(JobRunError::NotInLibrary(other.command_name())),
        })
    }
}
