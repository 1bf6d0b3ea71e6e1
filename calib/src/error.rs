//! The error of the OpenCV side of this crate ([`crate::cv`], [`crate::ecc`],
//! [`crate::calibrate`]): unreadable images, OpenCV failures, boards not
//! found, too few views, bad ECC inputs. A leaf module (it imports only the
//! plain [`crate::board`] and [`crate::buffer`] types), so the modules that
//! return it do not import each other for it.
//!
//! ```
//! use lucent_calib::error::CalibError;
//! let e = CalibError::Corners { got: 53, board: 54 };
//! assert_eq!(e.to_string(), "53 corners for a board of 54");
//! ```

use crate::board::BoardSpec;
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// What went wrong in detection, calibration or drawing.
#[derive(Debug, thiserror::Error)]
pub enum CalibError {
    #[error("{}: cannot read image: {reason}", path.display())]
    Image { path: PathBuf, reason: String },
    #[error("OpenCV {context}: {message}")]
    OpenCv { context: &'static str, message: String },
    /// A pixel buffer whose length does not match its stated size.
    #[error(transparent)]
    Buffer(#[from] crate::buffer::BufferSizeError),
    /// OpenCV returned a result of an unexpected size.
    #[error("OpenCV {context} returned {got} values, expected {expected}")]
    OpenCvShape { context: &'static str, got: usize, expected: &'static str },
    /// `fisheye::calibrate` returned poses for a different number of views.
    #[error(
        "fisheye::calibrate returned {rotations} rotation and {translations} translation values for {views} views"
    )]
    PoseCount { rotations: usize, translations: usize, views: usize },
    #[error("no views to calibrate from")]
    NoViews,
    #[error("view {view} has {got} corners, the board has {board}")]
    ViewCorners { view: usize, got: usize, board: usize },
    #[error("{got} corners for a board of {board}")]
    Corners { got: usize, board: usize },
    #[error("corner {index} at ({x:.1}, {y:.1}) px is 90° or more off the fisheye's axis: no pinhole ray for PnP")]
    BeyondFisheyeAxis { index: usize, x: f64, y: f64 },
    #[error("solvePnP found no pose for these corners")]
    NoPose,
    /// [`crate::calibrate::calibrate_photos`] was given no photos.
    #[error("no photos given")]
    NoPhotos,
    /// The photos of one calibration differ in size.
    #[error("photos differ in size: {first} is {width} × {height}, but {}", .others.join(", "))]
    PhotoSizes { first: String, width: usize, height: usize, others: Vec<String> },
    /// Fewer than `needed` ([`crate::calibrate::MIN_VIEWS`]) photos show the board.
    #[error(
        "{}:\n{}{}\n(--board counts inner corners: a board of 10 × 7 squares has 9x6)",
        too_few_views_head(.board, .found, .needed),
        .not_found.iter().map(|n| format!("  {}: {}", n.image, n.reason)).collect::<Vec<_>>().join("\n"),
        .suggestion.as_ref().map_or(String::new(), |(name, c, r)| format!("\n{name} does show a board of {c}x{r} inner corners: is --board {c}x{r} meant?"))
    )]
    TooFewViews {
        board: BoardSpec,
        /// Names of the photos that show the board.
        found: Vec<String>,
        not_found: Vec<NotFound>,
        /// A photo without the board and the board size it does show.
        suggestion: Option<(String, usize, usize)>,
        /// Fewest views a calibration accepts.
        needed: usize,
    },
    /// Too few views for the coefficients of the chosen model.
    #[error(
        "--model {}: {views} views for {coefficients} camera coefficients (and 6 per view) is too few: the fit \
         follows the noise; this model needs at least {needed} views, or use --model pinhole-k3",
        <&'static str>::from(*model)
    )]
    TooFewViewsForModel { model: crate::model::DistortionModel, views: usize, needed: usize, coefficients: usize },
    /// The fitted camera fails [`crate::model::CameraModel::validate`].
    #[error(
        "the camera fitted to {views} views is not usable: {source}; photograph the board in more views, tilted \
         differently and reaching the image corners (or use a model with fewer coefficients)"
    )]
    Unusable { views: usize, source: crate::model::CameraError },
    /// An ECC motion model name not in `expected` (the names of [`crate::ecc::Motion`]).
    #[error("motion {name:?}: expected one of {}", .expected.join(", "))]
    UnknownMotion { name: String, expected: &'static [&'static str] },
    #[error("ECC buffers of {template}, {input} and {mask:?} values for {width} × {height}")]
    EccBuffers { template: usize, input: usize, mask: Option<usize>, width: usize, height: usize },
    #[error("ECC needs at least 16 × 16 pixels, got {width} × {height}")]
    EccTooSmall { width: usize, height: usize },
    #[error("the ECC region has {used} pixels; at least 64 are needed")]
    EccRegion { used: usize },
    #[error("ECC images contain NaN or infinite values")]
    EccNonFinite,
}

fn too_few_views_head(board: &BoardSpec, found: &[String], needed: &usize) -> String {
    if found.is_empty() {
        format!("no photo shows a chessboard of {}x{} inner corners", board.cols, board.rows)
    } else {
        format!(
            "only {} photo(s) show the {}x{} board ({}); calibration needs at least {} views at different angles",
            found.len(),
            board.cols,
            board.rows,
            found.join(", "),
            needed
        )
    }
}

/// A photo in which the board was not found (listed in camera.json and in
/// [`CalibError::TooFewViews`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NotFound {
    pub image: String,
    pub reason: String,
}
