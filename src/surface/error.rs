//! What can go wrong with a height map ([`SurfaceError`]): reading it
//! (X3P, text, TIFF, EXR), its values and the parameters of the fit; every
//! step of the module returns it.

use crate::imageio::ImageIoError;
use crate::io::WriteError;
use crate::plot::PlotError;
use std::path::PathBuf;

/// A height map that cannot be read, or parameters that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum SurfaceError {
    #[error("{path}: cannot read: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{path}: not a readable X3P archive (truncated, damaged or not a zip file): {reason}")]
    Archive { path: PathBuf, reason: String },
    #[error("{path}: {member}: {reason}")]
    Member { path: PathBuf, member: String, reason: String },
    #[error("{path}: main.xml: {reason}")]
    Xml { path: PathBuf, reason: String },
    #[error("{path}: {member}: MD5 checksum {actual} does not match {expected} stated in {stated_in} (damaged file)")]
    Checksum { path: PathBuf, member: String, expected: String, actual: String, stated_in: String },
    #[error("{path}: {member} holds {got} points, but {stated_in} says {expected}")]
    PointCount { path: PathBuf, member: String, got: usize, expected: usize, stated_in: String },
    #[error("{origin}: {what} {} m: the pitch must be a positive finite number", show_metres(*value))]
    Pitch { origin: String, what: String, value: f64 },
    #[error("{origin}: no valid height point (all {points} points are NaN, infinite or masked invalid)")]
    AllInvalid { origin: String, points: usize },
    #[error("{path}: line {line}: {reason}")]
    Text { path: PathBuf, line: usize, reason: String },
    #[error("{path}: {reason}")]
    Format { path: PathBuf, reason: String },
    #[error("{name} {value}: {reason}")]
    Parameter { name: String, value: String, reason: String },
    #[error("{origin}: {reason}")]
    Data { origin: String, reason: String },
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error(transparent)]
    Image(#[from] ImageIoError),
    /// An EXR height map that cannot be read (the message names the file).
    #[error(transparent)]
    ExrRead(#[from] crate::exr::ExrReadError),
    #[error(transparent)]
    ExrWrite(#[from] crate::exr::ExrWriteError),
    #[error("{path}: {source}")]
    Plot { path: PathBuf, source: PlotError },
}

/// A length in metres for a message: "0", "-5e-7", "8.71e-7".
pub(super) fn show_metres(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        format!("{v}")
    } else {
        format!("{v:e}")
    }
}

impl SurfaceError {
    pub(crate) fn parameter(name: &str, value: impl std::fmt::Display, reason: impl Into<String>) -> Self {
        SurfaceError::Parameter { name: name.into(), value: value.to_string(), reason: reason.into() }
    }
}
