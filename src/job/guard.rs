//! The rules a job's files keep whoever runs it (`lucent CMD`, `lucent job
//! run JOB.json`, a stage of `lucent run`), checked before any work:
//! an output never replaces an input, two outputs never share a file, a
//! sidecar that is not from an earlier run is never replaced
//! ([`FileRoles::check`]), and an output folder is lucent's own or new
//! ([`OutputFolder`]: refused when it is a folder of the user's,
//! marked as lucent's when the work succeeds, removed again when the work
//! fails and leaves it empty).

use super::spec::Job;
use crate::io::{OutputFolderError, WriteError};
use lucent_calib::calibrate::CalibrationFiles;
use lucent_calib::scene::PoseFiles;
use std::path::{Path, PathBuf};

/// The files a command reads, the files the user names it to write, and
/// the files it writes beside them under derived names (sidecars).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FileRoles {
    pub inputs: Vec<PathBuf>,
    pub outputs: Vec<PathBuf>,
    pub sidecars: Vec<PathBuf>,
}

/// Why a command's files are refused before any work.
#[derive(Debug, thiserror::Error)]
pub enum FileRoleError {
    #[error("{} would be written over the input {}: give the output another name (nothing was written)", output.display(), input.display())]
    OverInput { output: PathBuf, input: PathBuf },
    #[error("{} and {} name the same file: two outputs cannot share it (nothing was written)", first.display(), second.display())]
    SharedOutput { first: PathBuf, second: PathBuf },
    #[error(
        "{} exists but {} does not, so it is not from an earlier run of this command: move it or give the output \
         another name (nothing was written)",
        sidecar.display(),
        main.display()
    )]
    StraySidecar { sidecar: PathBuf, main: PathBuf },
    #[error("--out {}: the output is a JSON file (NAME.json)", out.display())]
    NotJson { out: PathBuf },
    #[error("{}: the output must be an .exr file (32-bit float)", out.display())]
    NotExr { out: PathBuf },
}

impl FileRoles {
    pub fn new(inputs: Vec<PathBuf>, outputs: Vec<PathBuf>, sidecars: Vec<PathBuf>) -> Self {
        FileRoles { inputs, outputs, sidecars }
    }

    /// An output (or sidecar) must not be an input nor another output, and
    /// a sidecar may be replaced only where the main output exists (the
    /// earlier run's).
    pub fn check(&self) -> Result<(), FileRoleError> {
        let key = |p: &Path| crate::io::file_key(p);
        let all: Vec<&PathBuf> = self.outputs.iter().chain(&self.sidecars).collect();
        for (k, o) in all.iter().enumerate() {
            let ko = key(o);
            if let Some(i) = self.inputs.iter().find(|i| key(i) == ko) {
                return Err(FileRoleError::OverInput { output: o.to_path_buf(), input: i.clone() });
            }
            if let Some(other) = all[..k].iter().find(|p| key(p) == ko) {
                return Err(FileRoleError::SharedOutput { first: other.to_path_buf(), second: o.to_path_buf() });
            }
        }
        if let Some(main) = self.outputs.first().filter(|m| !m.exists())
            && let Some(s) = self.sidecars.iter().find(|s| s.exists())
        {
            return Err(FileRoleError::StraySidecar { sidecar: s.clone(), main: main.clone() });
        }
        Ok(())
    }
}

/// An output folder in use: opened before the work
/// ([`OutputFolder::open`]), closed after it ([`OutputFolder::close`]).
#[derive(Debug)]
pub struct OutputFolder {
    path: Option<PathBuf>,
    existed: bool,
}

impl OutputFolder {
    /// Refuses `folder` before any work when it is the user's
    /// ([`crate::io::check_output_folder`]); `None`: the work writes files, not a folder.
    pub fn open(folder: Option<&Path>) -> Result<Self, OutputFolderError> {
        let existed = folder.is_some_and(|f| std::fs::symlink_metadata(f).is_ok());
        if let Some(f) = folder {
            crate::io::check_output_folder(f)?;
            crate::io::mark_when_written(f);
        }
        Ok(OutputFolder { path: folder.map(Path::to_path_buf), existed })
    }

    /// Marks the folder as lucent's when the work `succeeded` (or was
    /// `interrupted` and kept a labelled partial result in it); removes it
    /// again when the work failed and left it empty (it did not exist before).
    pub fn close(self, succeeded: bool, interrupted: bool) -> Result<(), WriteError> {
        let Some(f) = self.path.filter(|f| f.is_dir()) else { return Ok(()) };
        let kept_partial = !succeeded
            && interrupted
            && std::fs::read_dir(&f)
                .is_ok_and(|d| d.flatten().any(|e| !e.file_name().to_string_lossy().starts_with('.')));
        if succeeded || kept_partial {
            crate::io::mark_output_folder(&f)?;
        } else if !self.existed {
            let only_mark = std::fs::read_dir(&f)
                .map(|d| d.flatten().all(|e| e.file_name() == crate::io::OUTPUT_MARK))
                .unwrap_or(false);
            if only_mark {
                let _ = std::fs::remove_file(f.join(crate::io::OUTPUT_MARK));
                let _ = std::fs::remove_dir(&f);
            }
        }
        Ok(())
    }
}

impl Job {
    /// The folder the job writes into, if it writes a folder (not files).
    pub fn output_folder(&self) -> Option<&Path> {
        Some(match self {
            Job::Optics(j) => return j.out.as_deref(),
            Job::Bssrdf(j) => &j.out,
            Job::BssrdfCompare(j) => &j.out,
            Job::Fit(j) => &j.out,
            Job::ColourCalibrate(j) => &j.out,
            Job::EnvScale(j) => &j.out,
            Job::Render(j) => &j.out,
            Job::Compare(j) => &j.out,
            Job::SurfaceFit(j) => &j.out,
            Job::Calibrate(_)
            | Job::ColourApply(_)
            | Job::RawClipped(_)
            | Job::Pose(_)
            | Job::EnvMerge(_)
            | Job::EnvOrient(_) => return None,
        })
    }

    /// The files a job that writes files (not a folder) reads and writes.
    pub fn file_roles(&self) -> FileRoles {
        match self {
            Job::Pose(j) => FileRoles::new(
                vec![j.camera.clone(), j.image.clone()],
                vec![j.out.clone()],
                vec![PoseFiles::of(&j.out).view_png],
            ),
            Job::Calibrate(j) => FileRoles::new(
                j.images.iter().flat_map(|s| crate::io::glob_files(s).unwrap_or_default()).collect(),
                vec![j.out.clone()],
                vec![CalibrationFiles::of(&j.out).residuals_png],
            ),
            Job::ColourApply(j) => FileRoles::new(
                vec![j.ccm.clone(), j.input.clone()],
                std::iter::once(j.output.clone()).chain(j.variance_out.as_ref().map(|(p, _)| p.clone())).collect(),
                vec![],
            ),
            Job::RawClipped(j) => FileRoles::new(vec![j.input.clone()], vec![j.out.clone()], vec![]),
            Job::EnvMerge(j) => {
                let files = super::env_merge::EnvMergeFiles::of(&j.out);
                FileRoles::new(j.brackets.clone(), vec![files.exr], vec![files.json, files.saturated_png])
            }
            Job::EnvOrient(j) => {
                let files = super::env_orient::EnvOrientFiles::of(&j.out);
                FileRoles::new(vec![j.input.clone()], vec![files.exr], vec![files.json, files.board_png])
            }
            _ => FileRoles::default(),
        }
    }

    /// [`FileRoles::check`] of the job's files, a camera or scene file
    /// (calibrate, pose) named `.json` and a merged or turned map (env
    /// merge, env orient) named `.exr`.
    pub fn check_files(&self) -> Result<(), FileRoleError> {
        self.file_roles().check()?;
        if let Job::Calibrate(super::spec::CalibrateJob { out, .. }) | Job::Pose(super::spec::PoseJob { out, .. }) =
            self
            && !out.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"))
        {
            return Err(FileRoleError::NotJson { out: out.clone() });
        }
        if let Job::EnvMerge(super::env_merge::EnvMergeJob { out, .. })
        | Job::EnvOrient(super::env_orient::EnvOrientJob { out, .. }) = self
            && crate::imageio::extension(out) != "exr"
        {
            return Err(FileRoleError::NotExr { out: out.clone() });
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_output_over_an_input_or_another_output_is_refused() {
        let a = PathBuf::from("/nonexistent/a.png");
        let b = PathBuf::from("/nonexistent/b.png");
        let over = FileRoles::new(vec![a.clone()], vec![a.clone()], vec![]);
        assert!(matches!(over.check(), Err(FileRoleError::OverInput { .. })));
        let shared = FileRoles::new(vec![], vec![b.clone()], vec![b.clone()]);
        assert!(matches!(shared.check(), Err(FileRoleError::SharedOutput { .. })));
        assert!(FileRoles::new(vec![a], vec![b], vec![]).check().is_ok());
    }
}
