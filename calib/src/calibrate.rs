//! The calibration driver (docs/method.md#camera): detects the board in every photo,
//! calibrates (Zhang 2000 through OpenCV's `calibrateCamera`, or Kannala–Brandt
//! through `fisheye::calibrate`; see [`crate::cv`]), and reports per view the
//! pose, the corners and the reprojection residuals in pixels — what
//! `lucent calibrate` writes as camera.json ([`Calibration`]). Also the
//! board detection of `lucent pose` and `lucent env orient`
//! ([`find_board_corners`]).
//!
//! The top of this crate's module graph on the camera side: it uses
//! [`crate::cv`], [`crate::env`] and the leaf modules [`crate::model`],
//! [`crate::board`], [`crate::pose`], [`crate::buffer`], [`crate::error`];
//! none of them imports it. [`crate::camera`] and [`crate::scene`] re-export
//! its items at their old paths.
//!
//! ```
//! use lucent_calib::calibrate::{calibrate_photos, MIN_VIEWS};
//! use lucent_calib::{board::BoardSpec, cv::Detector, model::DistortionModel, GrayImage};
//! // Three blank photos show no board: an error naming them, not a calibration.
//! let blank = GrayImage::new(64, 48, vec![128; 64 * 48]).unwrap();
//! let photos: Vec<_> = (0..MIN_VIEWS)
//!     .map(|i| lucent_calib::calibrate::Photo { name: format!("p{i}.png"), image: blank.clone() })
//!     .collect();
//! let board = BoardSpec::parse("9x6", 25.0).unwrap();
//! let e = calibrate_photos(&photos, &board, DistortionModel::PinholeK3, Detector::Auto).unwrap_err();
//! assert!(e.to_string().contains("p0.png: no chessboard of 9x6 inner corners found"), "{e}");
//! ```

use crate::board::BoardSpec;
use crate::buffer::GrayImage;
use crate::cv::{self, Detector};
use crate::env;
use crate::model::{CameraModel, DistortionModel};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

pub use crate::error::{CalibError, NotFound};

/// One photo for [`calibrate_photos`].
#[derive(Debug, Clone, PartialEq)]
pub struct Photo {
    /// Name used in reports (usually the file name).
    pub name: String,
    pub image: GrayImage,
}

/// A view used in the calibration.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CalibrationView {
    pub image: String,
    /// "sector-based" or "classic".
    pub detector: String,
    pub rms_px: f64,
    /// OpenCV pose of the board: rotation vector (radians), translation (metres).
    pub rvec: [f64; 3],
    pub tvec_m: [f64; 3],
    /// Detected corners (OpenCV's order, i fastest), pixels.
    pub corners_px: Vec<[f64; 2]>,
    /// Detected minus reprojected, pixels.
    pub residuals_px: Vec<[f64; 2]>,
}

/// The files of `lucent calibrate`, each name spelled here once: the
/// [`Calibration`] (`camera`, in a stage folder `camera.json`), beside it
/// the reprojection residuals per view (`residuals_png`, `NAME_residuals.png`)
/// and the folder of the detected and reprojected corners per view
/// (`views`, `NAME_views/`). Written by `lucent calibrate`, read by `lucent
/// run`'s planning and report.
///
/// ```
/// use lucent_calib::calibrate::CalibrationFiles;
/// let f = CalibrationFiles::in_dir(std::path::Path::new("out/calibrate"));
/// assert_eq!(f.residuals_png, std::path::Path::new("out/calibrate/camera_residuals.png"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CalibrationFiles {
    pub camera: PathBuf,
    pub residuals_png: PathBuf,
    pub views: PathBuf,
}

impl CalibrationFiles {
    /// The camera file's name in a folder ([`CalibrationFiles::in_dir`]).
    pub const CAMERA: &'static str = "camera.json";

    /// The files beside the camera file `camera`.
    pub fn of(camera: &Path) -> Self {
        Self {
            camera: camera.to_path_buf(),
            residuals_png: crate::scene::sibling(camera, "_residuals.png"),
            views: crate::scene::sibling(camera, "_views"),
        }
    }

    /// The files of the calibration written into the folder `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        Self::of(&dir.join(Self::CAMERA))
    }
}

/// What `lucent calibrate` writes as camera.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    pub camera: CameraModel,
    /// Overall RMS reprojection error, pixels (OpenCV's).
    pub rms_px: f64,
    pub board: BoardSpec,
    pub views: Vec<CalibrationView>,
    pub not_found: Vec<NotFound>,
    pub method: String,
    pub opencv_version: String,
}

/// Fewest views accepted for a calibration.
pub const MIN_VIEWS: usize = 3;

/// What [`calibrate_photos_reporting`] says while it works.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CalibrationStep<'a> {
    /// The board was looked for in one more photo: `done` of `of` so far (in
    /// the order the searches finish), with the detector that found it.
    Searched { done: usize, of: usize, photo: &'a str, found: Option<&'static str> },
    /// The board was found in `views` photos: the model is being fitted.
    Fitting { views: usize },
}

/// Detects the board in every photo, calibrates, and reports per view.
/// Photos must share one size. Errors (naming the photos) when fewer than
/// [`MIN_VIEWS`] photos show the board.
pub fn calibrate_photos(
    photos: &[Photo],
    board: &BoardSpec,
    model: DistortionModel,
    detector: Detector,
) -> Result<Calibration, CalibError> {
    calibrate_photos_reporting(photos, board, model, detector, &|_| {})
}

/// [`calibrate_photos`] that tells `progress` of every photo searched and of
/// the fit (from the search's threads: it must be `Sync`).
pub fn calibrate_photos_reporting(
    photos: &[Photo],
    board: &BoardSpec,
    model: DistortionModel,
    detector: Detector,
    progress: &(dyn Fn(CalibrationStep<'_>) + Sync),
) -> Result<Calibration, CalibError> {
    let first = photos.first().ok_or(CalibError::NoPhotos)?;
    let size = (first.image.width, first.image.height);
    let odd: Vec<String> = photos
        .iter()
        .filter(|p| (p.image.width, p.image.height) != size)
        .map(|p| format!("{} ({} × {})", p.name, p.image.width, p.image.height))
        .collect();
    if !odd.is_empty() {
        return Err(CalibError::PhotoSizes { first: first.name.clone(), width: size.0, height: size.1, others: odd });
    }
    let searched = AtomicUsize::new(0);
    let detections: Vec<Result<Option<cv::Corners>, CalibError>> = photos
        .par_iter()
        .map(|p| {
            let d = cv::find_corners(&p.image, board, detector);
            let done = searched.fetch_add(1, Ordering::Relaxed) + 1;
            let found = d.as_ref().ok().and_then(|c| c.as_ref()).map(|c| c.detector);
            progress(CalibrationStep::Searched { done, of: photos.len(), photo: &p.name, found });
            d
        })
        .collect();
    let mut found = Vec::new();
    let mut not_found = Vec::new();
    for (p, d) in photos.iter().zip(detections) {
        match d? {
            Some(c) => found.push((p, c)),
            None => not_found.push(NotFound { image: p.name.clone(), reason: no_board_reason(&p.image, board) }),
        }
    }
    if found.len() < MIN_VIEWS {
        let suggestion = match photos.iter().find(|p| found.iter().all(|(f, _)| f.name != p.name)) {
            Some(p) => cv::suggest_board(&p.image, board)?.map(|(c, r)| (p.name.clone(), c, r)),
            None => None,
        };
        return Err(CalibError::TooFewViews {
            board: *board,
            found: found.iter().map(|(p, _)| p.name.clone()).collect(),
            not_found,
            suggestion,
            needed: MIN_VIEWS,
        });
    }
    // Each view fits 6 pose parameters besides the camera's: a model with
    // many distortion coefficients needs the views to pin them down.
    let needed = min_views(model);
    if found.len() < needed {
        return Err(CalibError::TooFewViewsForModel {
            model,
            views: found.len(),
            needed,
            coefficients: coefficients(model),
        });
    }
    let corners: Vec<Vec<[f64; 2]>> = found.iter().map(|(_, c)| c.points.clone()).collect();
    progress(CalibrationStep::Fitting { views: found.len() });
    let solved = cv::calibrate(&corners, board, size, model)?;
    // The camera `undistort`, `pose` and the renderer would refuse is not
    // written: the same check as theirs (too few or too alike views fit
    // distortion coefficients that fold the image).
    solved.camera.validate().map_err(|source| CalibError::Unusable { views: found.len(), source })?;
    let object = board.corners();
    let views = found
        .iter()
        .zip(&solved.poses)
        .map(|((p, c), pose)| {
            let residuals: Vec<[f64; 2]> = c
                .points
                .iter()
                .zip(&object)
                .map(|(d, o)| {
                    let q = solved.camera.project(pose.to_camera(*o)).unwrap_or([f64::NAN; 2]);
                    [d[0] - q[0], d[1] - q[1]]
                })
                .collect();
            let ss: f64 = residuals.iter().map(|r| r[0] * r[0] + r[1] * r[1]).sum();
            CalibrationView {
                image: p.name.clone(),
                detector: c.detector.into(),
                rms_px: (ss / residuals.len() as f64).sqrt(),
                rvec: pose.rvec(),
                tvec_m: pose.translation_m,
                corners_px: c.points.clone(),
                residuals_px: residuals,
            }
        })
        .collect();
    let method = format!(
        "OpenCV calibrateCamera ({}), corners by {}",
        match model {
            DistortionModel::PinholeK3 => "k1 k2 p1 p2 k3",
            DistortionModel::Rational => "rational model k1..k6 p1 p2",
            DistortionModel::Fisheye => "fisheye::calibrate, Kannala–Brandt k1..k4",
        },
        match detector {
            Detector::Auto => "findChessboardCornersSB (ACCURACY), else findChessboardCorners + cornerSubPix",
            Detector::SectorBased => "findChessboardCornersSB (ACCURACY)",
            Detector::Classic => "findChessboardCorners + cornerSubPix",
        }
    );
    Ok(Calibration {
        camera: solved.camera,
        rms_px: solved.rms_px,
        board: *board,
        views,
        not_found,
        method,
        opencv_version: cv::version(),
    })
}

/// The fewest views [`calibrate_photos`] accepts for `model`: [`MIN_VIEWS`],
/// and for the rational model (8 distortion coefficients, 12 with the
/// intrinsics) [`MIN_VIEWS_RATIONAL`].
pub fn min_views(model: DistortionModel) -> usize {
    match model {
        DistortionModel::Rational => MIN_VIEWS_RATIONAL,
        DistortionModel::PinholeK3 | DistortionModel::Fisheye => MIN_VIEWS,
    }
}

/// Fewest views accepted for the rational model: each view's homography
/// leaves 2 constraints on the camera after its own 6 pose parameters
/// (Zhang 2000), and the model has 12 camera coefficients (fx, fy, cx, cy,
/// k1…k6, p1, p2). With fewer, its coefficients are not pinned down by the
/// views (with 3 views on OpenCV's left01–03 the fit still passes the
/// one-to-one check, so it was written without a word).
pub const MIN_VIEWS_RATIONAL: usize = 6;

/// The camera's coefficients `model` fits (intrinsics and distortion).
fn coefficients(model: DistortionModel) -> usize {
    match model {
        DistortionModel::PinholeK3 => 9,
        DistortionModel::Rational => 12,
        DistortionModel::Fisheye => 8,
    }
}

/// Why a board may not have been found, for the report.
fn no_board_reason(img: &GrayImage, board: &BoardSpec) -> String {
    let mut hist = [0usize; 256];
    for &v in &img.data {
        hist[v as usize] += 1;
    }
    let n = img.data.len().max(1);
    let quantile = |q: f64| {
        let target = (q * n as f64) as usize;
        let mut acc = 0;
        for (v, &c) in hist.iter().enumerate() {
            acc += c;
            if acc > target {
                return v;
            }
        }
        255
    };
    let (lo, hi) = (quantile(0.05), quantile(0.95));
    let mut reason = format!(
        "no chessboard of {}x{} inner corners found (sector-based and classic detectors)",
        board.cols, board.rows
    );
    if hi - lo < 40 {
        reason.push_str(&format!("; low contrast (5th–95th percentile grey {lo}–{hi})"));
    }
    reason
}

/// The board's inner corners in a photo or view, numbered by [`crate::scene`]'s
/// convention (its module docs): OpenCV's detectors ([`cv::find_corners`],
/// sector-based first), then [`env::canonical_corner_order`]; with
/// the order found. `Ok(None)` when no board of that size is found.
pub fn find_board_corners(
    img: &GrayImage,
    board: &BoardSpec,
) -> Result<Option<(cv::Corners, env::CornerOrder)>, CalibError> {
    let Some(found) = cv::find_corners(img, board, Detector::Auto)? else {
        return Ok(None);
    };
    let (points, order) = env::canonical_corner_order(img, board.cols, board.rows, &found.points);
    Ok(Some((cv::Corners { points, detector: found.detector }, order)))
}
