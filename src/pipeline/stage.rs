//! The stages of a run ([`Stage`]: their names, order and dependencies) and
//! how one ended ([`Status`], [`Skip`]).

use serde::{Deserialize, Serialize};
use thiserror::Error;

/// The stages, in the order they run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    Optics,
    Surface,
    Bssrdf,
    Fit,
    Calibrate,
    Colour,
    Develop,
    Pose,
    EnvScale,
    Render,
    Compare,
    Report,
}

impl Stage {
    pub const ALL: [Stage; 12] = [
        Stage::Optics,
        Stage::Surface,
        Stage::Bssrdf,
        Stage::Fit,
        Stage::Calibrate,
        Stage::Colour,
        Stage::Develop,
        Stage::Pose,
        Stage::EnvScale,
        Stage::Render,
        Stage::Compare,
        Stage::Report,
    ];

    /// Every stage before the report (which reads them all).
    const BEFORE_REPORT: &'static [Stage] = match Self::ALL.split_last() {
        Some((_, before)) => before,
        None => &[],
    };

    /// The stage's name (also its folder).
    pub fn name(self) -> &'static str {
        match self {
            Stage::Optics => "optics",
            Stage::Surface => "surface",
            Stage::Bssrdf => "bssrdf",
            Stage::Fit => "fit",
            Stage::Calibrate => "calibrate",
            Stage::Colour => "colour",
            Stage::Develop => "develop",
            Stage::Pose => "pose",
            Stage::EnvScale => "env-scale",
            Stage::Render => "render",
            Stage::Compare => "compare",
            Stage::Report => "report",
        }
    }

    /// The stage of a name; a bad name lists the valid ones.
    pub fn from_name(name: &str) -> Result<Stage, UnknownStage> {
        Stage::ALL.into_iter().find(|s| s.name() == name).ok_or_else(|| UnknownStage { name: name.to_string() })
    }

    /// The stages whose outputs this one reads.
    pub fn depends_on(self) -> &'static [Stage] {
        match self {
            Stage::Optics | Stage::Surface | Stage::Fit | Stage::Calibrate | Stage::Colour => &[],
            Stage::Bssrdf => &[Stage::Surface],
            Stage::Develop => &[Stage::Colour],
            Stage::Pose => &[Stage::Calibrate],
            Stage::EnvScale => &[Stage::Pose, Stage::Develop],
            Stage::Render => &[Stage::EnvScale, Stage::Pose, Stage::Fit],
            Stage::Compare => &[Stage::Render, Stage::Develop],
            Stage::Report => Self::BEFORE_REPORT,
        }
    }
}

impl std::fmt::Display for Stage {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// A stage name that [`Stage::from_name`] does not know.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("no stage {name:?}; the stages are {}", Stage::ALL.iter().map(|s| s.name()).collect::<Vec<_>>().join(", "))]
pub struct UnknownStage {
    pub name: String,
}

/// How a stage ended in this run; [`Status::Started`] only as the note
/// that a stage begins (never a stage's end).
#[derive(Debug, Clone, PartialEq)]
pub enum Status {
    /// The stage is about to run its tasks; `last_wall_s` is the time its
    /// previous result took (from its manifest.json), when there is one.
    Started {
        last_wall_s: Option<f64>,
    },
    Ran {
        wall_s: f64,
        tasks: usize,
    },
    UpToDate,
    Skipped {
        reason: Skip,
    },
    /// Tasks handed to someone else to run ([`executor::Deferred`](super::executor::Deferred)): the
    /// stage and the ones after it wait for a later run.
    Deferred {
        tasks: usize,
    },
}

/// Why a stage is skipped: what the project (or an earlier stage) does not
/// provide for it.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum Skip {
    /// A section the stage needs (`[bssrdf]`, `[[sample]]`, …).
    #[error("no {0} in the project")]
    Missing(&'static str),
    #[error("no sample names a camera whose RGB its photos are in")]
    NoSampleCamera,
    #[error("needs the calibrate stage's camera.json (no [calibration] or it has not run)")]
    NoCamera,
    #[error("no sample has an empty_board photo")]
    NoEmptyBoard,
    #[error("no sample has both a photo and a render")]
    NoPhotoAndRender,
    #[error("no sample has measured slices ([[sample.measured]])")]
    NoMeasured,
    #[error("no sample has a surface height map ([[sample]] surface)")]
    NoSurface,
}
