//! Everything that calls OpenCV (4.6 on Debian, through the `opencv` crate),
//! and the only module that does: chessboard corners, Zhang calibration,
//! PnP, drawing, and ColorChecker detection with the contrib module `mcc`
//! ([`detect_mcc24`], used by the root crate's `chart_detect`). Every function
//! takes and returns plain Rust values; `Mat`, `Vector` and OpenCV errors
//! stop here.
//!
//! Corner detection ([`Detector::Auto`], the default): OpenCV's sector-based
//! detector (`findChessboardCornersSB`, Duda & Frese 2018, flag
//! `CALIB_CB_ACCURACY`), which localises corners more accurately; where it
//! finds nothing, the classic detector (`findChessboardCorners` with adaptive
//! threshold and normalisation) refined by `cornerSubPix` (11 × 11 window,
//! 30 iterations or 0.001 px). On OpenCV's sample photos the sector-based
//! corners give an RMS reprojection error of 0.24 px against 0.41 px for the
//! classic ones, and a focal length 0.7 % smaller. Every detection must
//! also pass [`looks_like_chessboard`] (X-junctions with alternating
//! quadrants): OpenCV's detectors otherwise accept, e.g., a 10 × 6 pattern on
//! a 9 × 6 board by taking the board's outer edge for a row of corners.
//!
//! Calibration: `calibrateCamera` (Zhang 2000 initialisation, then
//! Levenberg–Marquardt over intrinsics, distortion and all poses), flags 0
//! for `pinhole-k3` and `CALIB_RATIONAL_MODEL` for `rational`; for `fisheye`,
//! `fisheye::calibrate` (Kannala–Brandt k1–k4, flags
//! `CALIB_RECOMPUTE_EXTRINSIC | CALIB_FIX_SKEW`, 100 iterations). PnP with a
//! fisheye camera runs on the corners undistorted by our own inverse
//! ([`crate::model::CameraModel::pixel_to_ray`]) with K = I. The overall
//! RMS is OpenCV's, sqrt(Σ‖residual‖² / number of corners); per-view RMS and
//! the residuals come from [`crate::model::CameraModel::project`], which the
//! tests check against `projectPoints`.
//!
//! Camera response of 8-bit exposure brackets ([`recover_response`]):
//! `photo::CalibrateDebevec` / `CalibrateRobertson` (see [`crate::hdr`]).
//!
//! ```
//! // OpenCV is linked and reports its version.
//! assert!(lucent_calib::cv::version().starts_with("4."));
//! ```

use crate::board::BoardSpec;
use crate::bracket::{HdrError, Response, ResponseMethod, Rgb8Buffer};
use crate::buffer::{BufferSizeError, GrayImage, RgbBuffer};
use crate::model::{CameraModel, Distortion, DistortionModel, Intrinsics};
use crate::pose::Pose;
use opencv::core::{self, Mat, Point, Point2f, Point3f, Scalar, Size, TermCriteria, Vector};
use opencv::mcc::{
    MCC_CCheckerDetector, MCC_CCheckerDetectorTrait, MCC_CCheckerTrait, MCC_DetectorParameters, MCC_TYPECHART,
};
use opencv::prelude::*;
use opencv::{calib3d, imgcodecs, imgproc};
use std::path::Path;
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

// Kept at this path for the root crate and the tests (`lucent_calib::cv::CalibError`).
pub use crate::error::CalibError;

fn cv_err(context: &'static str) -> impl Fn(opencv::Error) -> CalibError {
    move |e| CalibError::OpenCv { context, message: e.message }
}

/// Version of the linked OpenCV, e.g. "4.6.0".
pub fn version() -> String {
    core::get_version_string().unwrap_or_else(|e| format!("unknown ({})", e.message))
}

/// Corner detector policy.
#[derive(Debug, Clone, Copy, PartialEq, Eq, EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage)]
#[strum(serialize_all = "kebab-case", ascii_case_insensitive)]
pub enum Detector {
    /// Sector-based first, classic + cornerSubPix where it fails.
    Auto,
    /// `findChessboardCornersSB` only.
    #[strum(to_string = "sector-based", serialize = "sb")]
    SectorBased,
    /// `findChessboardCorners` + `cornerSubPix` only.
    Classic,
}

/// Detected inner corners, OpenCV's order (i fastest), pixels.
#[derive(Debug, Clone, PartialEq)]
pub struct Corners {
    pub points: Vec<[f64; 2]>,
    /// "sector-based" or "classic".
    pub detector: &'static str,
}

/// `imread` with the file's problems as errors naming it.
fn imread(path: &Path, flags: i32) -> Result<Mat, CalibError> {
    let err = |reason: String| CalibError::Image { path: path.to_path_buf(), reason };
    if !path.is_file() {
        return Err(err("no such file".into()));
    }
    // OpenCV decodes a cut-off JPEG or PNG with a warning and grey rows; refuse it.
    let bytes = std::fs::read(path).map_err(|e| err(e.to_string()))?;
    if let Some(problem) = truncation(&bytes) {
        return Err(err(problem.into()));
    }
    let m = imgcodecs::imdecode(&core::Vector::<u8>::from_slice(&bytes), flags).map_err(|e| err(e.message))?;
    if m.empty() {
        return Err(err("not an image format OpenCV can decode, or a corrupt file".into()));
    }
    Ok(m)
}

/// Why a JPEG or PNG file is cut short, if it is: a JPEG without the
/// end-of-image marker (FF D9) after its last scan (FF DA), a PNG without its
/// IEND chunk at the end. Other formats are left to the decoder.
fn truncation(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(&[0xFF, 0xD8]) {
        let Some(last_scan) = bytes.windows(2).rposition(|w| w == [0xFF, 0xDA]) else {
            return Some("truncated JPEG (no image data)");
        };
        if !bytes[last_scan..].windows(2).any(|w| w == [0xFF, 0xD9]) {
            return Some("truncated JPEG (no end-of-image marker after the last scan)");
        }
    } else if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        let tail = &bytes[bytes.len().saturating_sub(16)..];
        if !tail.windows(4).any(|w| w == b"IEND") {
            return Some("truncated PNG (no IEND chunk at the end)");
        }
    }
    None
}

/// The pixel bytes of an 8-bit Mat, row-major without padding.
fn bytes_of(m: &Mat) -> Result<Vec<u8>, CalibError> {
    let copy;
    let m = if m.is_continuous() {
        m
    } else {
        copy = m.try_clone().map_err(cv_err("copy"))?;
        &copy
    };
    Ok(m.data_bytes().map_err(cv_err("read pixels"))?.to_vec())
}

/// Reads an image file as 8-bit grey with OpenCV's codecs (JPEG, PNG, TIFF, …).
pub fn read_gray(path: &Path) -> Result<GrayImage, CalibError> {
    let m = imread(path, imgcodecs::IMREAD_GRAYSCALE)?;
    Ok(GrayImage::new(m.cols() as usize, m.rows() as usize, bytes_of(&m)?)?)
}

/// Reads an 8-bit image file (JPEG, PNG, TIFF, …) as RGB with values /255,
/// as stored (no transfer function removed).
pub fn read_rgb8(path: &Path) -> Result<RgbBuffer, CalibError> {
    let bgr = imread(path, imgcodecs::IMREAD_COLOR)?;
    let mut rgb = Mat::default();
    imgproc::cvt_color(&bgr, &mut rgb, imgproc::COLOR_BGR2RGB, 0).map_err(cv_err("cvtColor"))?;
    let data = bytes_of(&rgb)?.iter().map(|&b| f32::from(b) / 255.0).collect();
    Ok(RgbBuffer::new(rgb.cols() as usize, rgb.rows() as usize, data)?)
}

fn gray_mat(img: &GrayImage) -> Result<Mat, CalibError> {
    if img.data.len() != img.width * img.height {
        let (width, height, len) = (img.width, img.height, img.data.len());
        return Err(BufferSizeError { width, height, channels: 1, len }.into());
    }
    let m = Mat::new_rows_cols_with_data(img.height as i32, img.width as i32, &img.data).map_err(cv_err("image"))?;
    m.try_clone().map_err(cv_err("image"))
}

fn pattern(board: &BoardSpec) -> Size {
    Size::new(board.cols as i32, board.rows as i32)
}

fn to_points(v: &Vector<Point2f>) -> Vec<[f64; 2]> {
    v.iter().map(|p| [f64::from(p.x), f64::from(p.y)]).collect()
}

/// Grey value at (x, y), bilinear; `None` outside the image.
fn grey_at(img: &GrayImage, x: f64, y: f64) -> Option<f64> {
    if !(x >= 0.0 && y >= 0.0 && x <= (img.width - 1) as f64 && y <= (img.height - 1) as f64) {
        return None;
    }
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(img.width - 1), (y0 + 1).min(img.height - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let g = |x: usize, y: usize| f64::from(img.data[y * img.width + x]);
    Some((1.0 - fy) * ((1.0 - fx) * g(x0, y0) + fx * g(x1, y0)) + fy * ((1.0 - fx) * g(x0, y1) + fx * g(x1, y1)))
}

/// Checks that detected corners are the X-junctions of a chessboard: around
/// each corner, the two diagonal quadrant pairs (sampled 0.35 of a square
/// along both grid directions) must each be uniform and contrast with the
/// other, with the dark pair alternating over the grid. Rejects patterns
/// that the detectors extend onto the board's outer edge (a row of
/// T-junctions against the white margin), which would shift every index.
pub fn looks_like_chessboard(img: &GrayImage, board: &BoardSpec, corners: &[[f64; 2]]) -> bool {
    let (cols, rows) = (board.cols, board.rows);
    if corners.len() != cols * rows || img.width < 2 || img.height < 2 {
        return false;
    }
    let at = |i: usize, j: usize| corners[j * cols + i];
    let step = |i: usize, j: usize, di: bool| {
        let (a, b) = if di {
            if i + 1 < cols {
                (at(i, j), at(i + 1, j))
            } else {
                (at(i - 1, j), at(i, j))
            }
        } else if j + 1 < rows {
            (at(i, j), at(i, j + 1))
        } else {
            (at(i, j - 1), at(i, j))
        };
        [b[0] - a[0], b[1] - a[1]]
    };
    // Per corner: Some(sign of the diagonal contrast) if it is an X-junction.
    let mut ok = vec![None; cols * rows];
    for j in 0..rows {
        for i in 0..cols {
            let (c, u, v) = (at(i, j), step(i, j, true), step(i, j, false));
            let q =
                |a: f64, b: f64| grey_at(img, c[0] + 0.35 * (a * u[0] + b * v[0]), c[1] + 0.35 * (a * u[1] + b * v[1]));
            let (Some(pp), Some(mm), Some(pm), Some(mp)) = (q(1.0, 1.0), q(-1.0, -1.0), q(1.0, -1.0), q(-1.0, 1.0))
            else {
                continue;
            };
            let contrast = ((pp + mm) - (pm + mp)) / 2.0;
            if contrast.abs() > 15.0 && (pp - mm).abs() < 0.5 * contrast.abs() && (pm - mp).abs() < 0.5 * contrast.abs()
            {
                let parity = if (i + j) % 2 == 0 { 1.0 } else { -1.0 };
                ok[j * cols + i] = Some(contrast.signum() * parity > 0.0);
            }
        }
    }
    let passing = ok.iter().flatten().count();
    let (pos, neg) = (ok.iter().flatten().filter(|&&s| s).count(), ok.iter().flatten().filter(|&&s| !s).count());
    let consistent = pos.max(neg);
    // Each outer grid line mostly X-junctions, and the whole grid.
    let line_ok = |idx: Vec<usize>| 2 * idx.iter().filter(|&&k| ok[k].is_some()).count() >= idx.len();
    let first_row = (0..cols).collect();
    let last_row = (0..cols).map(|i| (rows - 1) * cols + i).collect();
    let first_col = (0..rows).map(|j| j * cols).collect();
    let last_col = (0..rows).map(|j| j * cols + cols - 1).collect();
    5 * passing >= 4 * corners.len()
        && 10 * consistent >= 9 * passing
        && line_ok(first_row)
        && line_ok(last_row)
        && line_ok(first_col)
        && line_ok(last_col)
}

/// Longest image side (pixels) up to which the detectors run on the photo
/// itself. Larger photos (phone cameras: 4000 px and more, where the
/// sector-based detector takes ~15 s) are searched on a copy downscaled by an
/// integer factor to at most 1600 px, and the corners are then refined on the
/// full photo with `cornerSubPix` (window ¼ of a square).
pub const DETECT_MAX_SIDE: usize = 2000;

/// Finds the board's inner corners; `Ok(None)` if the detector(s) find no
/// board of that size (detections that fail [`looks_like_chessboard`] do
/// not count).
pub fn find_corners(img: &GrayImage, board: &BoardSpec, detector: Detector) -> Result<Option<Corners>, CalibError> {
    let side = img.width.max(img.height);
    if side <= DETECT_MAX_SIDE {
        return detect(img, board, detector);
    }
    let f = side.div_ceil(1600);
    let full = gray_mat(img)?;
    let mut small = Mat::default();
    let size = Size::new(img.width.div_ceil(f) as i32, img.height.div_ceil(f) as i32);
    imgproc::resize(&full, &mut small, size, 0.0, 0.0, imgproc::INTER_AREA).map_err(cv_err("resize"))?;
    let small = GrayImage::new(small.cols() as usize, small.rows() as usize, bytes_of(&small)?)?;
    let Some(found) = detect(&small, board, detector)? else {
        return Ok(None);
    };
    // Pixel centres: small (x, y) covers full f·x … f·x + f − 1.
    let (sx, sy) = (img.width as f64 / small.width as f64, img.height as f64 / small.height as f64);
    let mut c: Vector<Point2f> = found
        .points
        .iter()
        .map(|p| Point2f::new(((p[0] + 0.5) * sx - 0.5) as f32, ((p[1] + 0.5) * sy - 0.5) as f32))
        .collect();
    let mut spacing: Vec<f64> = (0..board.rows)
        .flat_map(|j| (0..board.cols - 1).map(move |i| (i, j)))
        .filter_map(|(i, j)| {
            let (a, b) = (c.get(j * board.cols + i).ok()?, c.get(j * board.cols + i + 1).ok()?);
            Some(f64::from((a.x - b.x).hypot(a.y - b.y)))
        })
        .collect();
    spacing.sort_by(f64::total_cmp);
    let half = (0.25 * spacing.get(spacing.len() / 2).copied().unwrap_or(20.0)).clamp(3.0, 30.0) as i32;
    let criteria =
        TermCriteria { typ: core::TermCriteria_EPS + core::TermCriteria_COUNT, max_count: 40, epsilon: 0.01 };
    imgproc::corner_sub_pix(&full, &mut c, Size::new(half, half), Size::new(-1, -1), criteria)
        .map_err(cv_err("cornerSubPix"))?;
    let points = to_points(&c);
    if !looks_like_chessboard(img, board, &points) {
        return Ok(None);
    }
    let detector = if found.detector == "classic" {
        "classic (downscaled, refined)"
    } else {
        "sector-based (downscaled, refined)"
    };
    Ok(Some(Corners { points, detector }))
}

/// The detectors on the image as it is.
fn detect(img: &GrayImage, board: &BoardSpec, detector: Detector) -> Result<Option<Corners>, CalibError> {
    let m = gray_mat(img)?;
    let n = board.cols * board.rows;
    if matches!(detector, Detector::Auto | Detector::SectorBased) {
        let mut c = Vector::<Point2f>::new();
        let ok = calib3d::find_chessboard_corners_sb(&m, pattern(board), &mut c, calib3d::CALIB_CB_ACCURACY)
            .map_err(cv_err("findChessboardCornersSB"))?;
        if ok && c.len() == n && looks_like_chessboard(img, board, &to_points(&c)) {
            return Ok(Some(Corners { points: to_points(&c), detector: "sector-based" }));
        }
        if detector == Detector::SectorBased {
            return Ok(None);
        }
    }
    let mut c = Vector::<Point2f>::new();
    let flags = calib3d::CALIB_CB_ADAPTIVE_THRESH | calib3d::CALIB_CB_NORMALIZE_IMAGE;
    let ok =
        calib3d::find_chessboard_corners(&m, pattern(board), &mut c, flags).map_err(cv_err("findChessboardCorners"))?;
    if !ok || c.len() != n {
        return Ok(None);
    }
    let criteria =
        TermCriteria { typ: core::TermCriteria_EPS + core::TermCriteria_COUNT, max_count: 30, epsilon: 0.001 };
    imgproc::corner_sub_pix(&m, &mut c, Size::new(11, 11), Size::new(-1, -1), criteria)
        .map_err(cv_err("cornerSubPix"))?;
    let points = to_points(&c);
    if !looks_like_chessboard(img, board, &points) {
        return Ok(None);
    }
    Ok(Some(Corners { points, detector: "classic" }))
}

/// For an image where `board` was not found: the largest other inner-corner
/// count (within ±2 per direction) that the fast classic check does find, as
/// a hint for a mistyped `--board`. (A pattern smaller than the printed
/// board is found inside it, so a too-small `--board` is not an error: it
/// calibrates on a sub-board, and corner (0, 0) moves.)
pub fn suggest_board(img: &GrayImage, board: &BoardSpec) -> Result<Option<(usize, usize)>, CalibError> {
    let m = gray_mat(img)?;
    let (c, r) = (board.cols as i64, board.rows as i64);
    // Every count within ±2 of each side (7x5 typed for a 9x6 board is +2, +1).
    let mut candidates = vec![];
    for (dc, dr) in (-2..=2i64).flat_map(|dc| (-2..=2i64).map(move |dr| (dc, dr))).filter(|&d| d != (0, 0)) {
        let (a, b) = (c + dc, r + dr);
        if a >= 3 && b >= 3 {
            candidates.push((a as usize, b as usize));
        }
    }
    // Largest first: a smaller pattern is also found inside a larger board.
    candidates.sort_by_key(|&(a, b)| std::cmp::Reverse(a * b));
    for (a, b) in candidates {
        let mut out = Vector::<Point2f>::new();
        let flags =
            calib3d::CALIB_CB_ADAPTIVE_THRESH | calib3d::CALIB_CB_NORMALIZE_IMAGE | calib3d::CALIB_CB_FAST_CHECK;
        if calib3d::find_chessboard_corners(&m, Size::new(a as i32, b as i32), &mut out, flags)
            .map_err(cv_err("findChessboardCorners"))?
        {
            return Ok(Some((a, b)));
        }
    }
    Ok(None)
}

fn object_points(board: &BoardSpec) -> Vector<Point3f> {
    board.corners().iter().map(|p| Point3f::new(p[0] as f32, p[1] as f32, p[2] as f32)).collect()
}

fn image_points(points: &[[f64; 2]]) -> Vector<Point2f> {
    points.iter().map(|p| Point2f::new(p[0] as f32, p[1] as f32)).collect()
}

fn camera_mat(k: &Intrinsics) -> Result<Mat, CalibError> {
    Mat::from_slice_2d(&k.matrix()).map_err(cv_err("camera matrix"))
}

fn dist_mat(cam: &CameraModel) -> Result<Mat, CalibError> {
    let d = cam.distortion.to_opencv(cam.model);
    Mat::from_slice(&d).and_then(|m| m.try_clone()).map_err(cv_err("distortion"))
}

fn mat_values(m: &Mat, context: &'static str) -> Result<Vec<f64>, CalibError> {
    let mut m64 = Mat::default();
    m.convert_to(&mut m64, core::CV_64F, 1.0, 0.0).map_err(cv_err(context))?;
    let m64 = if m64.is_continuous() { m64 } else { m64.try_clone().map_err(cv_err(context))? };
    Ok(m64.data_typed::<f64>().map_err(cv_err(context))?.to_vec())
}

fn vec3(v: &[f64]) -> Result<[f64; 3], CalibError> {
    <[f64; 3]>::try_from(v).map_err(|_| CalibError::OpenCvShape { context: "vector", got: v.len(), expected: "3" })
}

/// Result of [`calibrate`]: the camera, OpenCV's overall RMS and one pose per view.
#[derive(Debug, Clone, PartialEq)]
pub struct Solved {
    pub camera: CameraModel,
    pub rms_px: f64,
    pub poses: Vec<Pose>,
}

/// Zhang calibration from detected corners, one `Vec` of
/// `board.cols × board.rows` pixel positions per view (OpenCV's order).
pub fn calibrate(
    views: &[Vec<[f64; 2]>],
    board: &BoardSpec,
    image_size: (usize, usize),
    model: DistortionModel,
) -> Result<Solved, CalibError> {
    let n = board.cols * board.rows;
    if let Some(bad) = views.iter().position(|v| v.len() != n) {
        return Err(CalibError::ViewCorners { view: bad, got: views[bad].len(), board: n });
    }
    if views.is_empty() {
        return Err(CalibError::NoViews);
    }
    let obj: Vector<Vector<Point3f>> = views.iter().map(|_| object_points(board)).collect();
    let img: Vector<Vector<Point2f>> = views.iter().map(|v| image_points(v)).collect();
    let mut k = Mat::default();
    let mut d = Mat::default();
    let mut rvecs = Vector::<Mat>::new();
    let mut tvecs = Vector::<Mat>::new();
    let flags = match model {
        DistortionModel::PinholeK3 => 0,
        DistortionModel::Rational => calib3d::CALIB_RATIONAL_MODEL,
        DistortionModel::Fisheye => return calibrate_fisheye(&obj, &img, image_size),
    };
    let criteria =
        TermCriteria { typ: core::TermCriteria_COUNT + core::TermCriteria_EPS, max_count: 30, epsilon: f64::EPSILON };
    let size = Size::new(image_size.0 as i32, image_size.1 as i32);
    let rms = calib3d::calibrate_camera(&obj, &img, size, &mut k, &mut d, &mut rvecs, &mut tvecs, flags, criteria)
        .map_err(cv_err("calibrateCamera"))?;
    let kv = mat_values(&k, "camera matrix")?;
    if kv.len() != 9 {
        return Err(CalibError::OpenCvShape { context: "calibrateCamera camera matrix", got: kv.len(), expected: "9" });
    }
    let camera = CameraModel {
        model,
        image_width: image_size.0,
        image_height: image_size.1,
        intrinsics: Intrinsics { fx: kv[0], fy: kv[4], cx: kv[2], cy: kv[5] },
        distortion: Distortion::from_opencv(&mat_values(&d, "distortion")?),
    };
    let mut poses = Vec::with_capacity(views.len());
    for (r, t) in rvecs.iter().zip(tvecs.iter()) {
        poses.push(Pose::from_rvec_tvec(vec3(&mat_values(&r, "rvec")?)?, vec3(&mat_values(&t, "tvec")?)?));
    }
    Ok(Solved { camera, rms_px: rms, poses })
}

/// `fisheye::calibrate` (Kannala–Brandt), see the module doc.
fn calibrate_fisheye(
    obj: &Vector<Vector<Point3f>>,
    img: &Vector<Vector<Point2f>>,
    image_size: (usize, usize),
) -> Result<Solved, CalibError> {
    let mut k = Mat::default();
    let mut d = Mat::default();
    // N × 1 three-channel matrices (OpenCV writes the fisheye poses as one Mat each).
    let mut rvecs = Mat::default();
    let mut tvecs = Mat::default();
    let flags = calib3d::Fisheye_CALIB_RECOMPUTE_EXTRINSIC | calib3d::Fisheye_CALIB_FIX_SKEW;
    let criteria =
        TermCriteria { typ: core::TermCriteria_COUNT + core::TermCriteria_EPS, max_count: 100, epsilon: f64::EPSILON };
    let size = Size::new(image_size.0 as i32, image_size.1 as i32);
    let rms = calib3d::calibrate(obj, img, size, &mut k, &mut d, &mut rvecs, &mut tvecs, flags, criteria)
        .map_err(cv_err("fisheye::calibrate"))?;
    let kv = mat_values(&k, "fisheye camera matrix")?;
    if kv.len() != 9 {
        return Err(CalibError::OpenCvShape {
            context: "fisheye::calibrate camera matrix",
            got: kv.len(),
            expected: "9",
        });
    }
    let camera = CameraModel {
        model: DistortionModel::Fisheye,
        image_width: image_size.0,
        image_height: image_size.1,
        intrinsics: Intrinsics { fx: kv[0], fy: kv[4], cx: kv[2], cy: kv[5] },
        distortion: Distortion::from_opencv_fisheye(&mat_values(&d, "fisheye distortion")?),
    };
    let single = |m: &Mat, what: &'static str| -> Result<Vec<f64>, CalibError> {
        let flat = m.reshape(1, 0).map_err(cv_err(what))?.try_clone().map_err(cv_err(what))?;
        mat_values(&flat, what)
    };
    let (r, t) = (single(&rvecs, "fisheye rvecs")?, single(&tvecs, "fisheye tvecs")?);
    if r.len() != 3 * obj.len() || t.len() != 3 * obj.len() {
        return Err(CalibError::PoseCount { rotations: r.len(), translations: t.len(), views: obj.len() });
    }
    let poses = r
        .chunks_exact(3)
        .zip(t.chunks_exact(3))
        .map(|(r, t)| Pose::from_rvec_tvec([r[0], r[1], r[2]], [t[0], t[1], t[2]]))
        .collect();
    Ok(Solved { camera, rms_px: rms, poses })
}

/// Board pose in one photo from its corners and a calibrated camera
/// (`solvePnP`, iterative Levenberg–Marquardt from an IPPE start).
pub fn solve_pnp(corners: &[[f64; 2]], board: &BoardSpec, cam: &CameraModel) -> Result<Pose, CalibError> {
    let n = board.cols * board.rows;
    if corners.len() != n {
        return Err(CalibError::Corners { got: corners.len(), board: n });
    }
    let obj = object_points(board);
    let (img, k, d) = if cam.model == DistortionModel::Fisheye {
        let mut norm = Vec::with_capacity(n);
        for (i, c) in corners.iter().enumerate() {
            let r = cam.pixel_to_ray(c[0], c[1]).ok_or(CalibError::BeyondFisheyeAxis { index: i, x: c[0], y: c[1] })?;
            norm.push([r[0], r[1]]);
        }
        let identity = Intrinsics { fx: 1.0, fy: 1.0, cx: 0.0, cy: 0.0 };
        let no_distortion = Mat::from_slice(&[0.0f64; 4]).and_then(|m| m.try_clone()).map_err(cv_err("distortion"))?;
        (image_points(&norm), camera_mat(&identity)?, no_distortion)
    } else {
        (image_points(corners), camera_mat(&cam.intrinsics)?, dist_mat(cam)?)
    };
    let mut r = Mat::default();
    let mut t = Mat::default();
    let ok = calib3d::solve_pnp(&obj, &img, &k, &d, &mut r, &mut t, false, calib3d::SOLVEPNP_IPPE)
        .map_err(cv_err("solvePnP (IPPE)"))?;
    if !ok {
        return Err(CalibError::NoPose);
    }
    calib3d::solve_pnp(&obj, &img, &k, &d, &mut r, &mut t, true, calib3d::SOLVEPNP_ITERATIVE)
        .map_err(cv_err("solvePnP (iterative)"))?;
    Ok(Pose::from_rvec_tvec(vec3(&mat_values(&r, "rvec")?)?, vec3(&mat_values(&t, "tvec")?)?))
}

/// OpenCV's own projection (`projectPoints`), for checking
/// [`CameraModel::project`].
pub fn project_points(points: &[[f64; 3]], pose: &Pose, cam: &CameraModel) -> Result<Vec<[f64; 2]>, CalibError> {
    let obj: Vector<core::Point3d> = points.iter().map(|p| core::Point3d::new(p[0], p[1], p[2])).collect();
    let rvec = Mat::from_slice(&pose.rvec()).and_then(|m| m.try_clone()).map_err(cv_err("rvec"))?;
    let tvec = Mat::from_slice(&pose.translation_m).and_then(|m| m.try_clone()).map_err(cv_err("tvec"))?;
    let mut out = Vector::<core::Point2d>::new();
    let mut jac = Mat::default();
    if cam.model == DistortionModel::Fisheye {
        calib3d::fisheye_project_points_vec(
            &obj,
            &mut out,
            &rvec,
            &tvec,
            &camera_mat(&cam.intrinsics)?,
            &dist_mat(cam)?,
            0.0,
            &mut jac,
        )
        .map_err(cv_err("fisheye::projectPoints"))?;
        return Ok(out.iter().map(|p| [p.x, p.y]).collect());
    }
    calib3d::project_points(
        &obj,
        &rvec,
        &tvec,
        &camera_mat(&cam.intrinsics)?,
        &dist_mat(cam)?,
        &mut out,
        &mut jac,
        0.0,
    )
    .map_err(cv_err("projectPoints"))?;
    Ok(out.iter().map(|p| [p.x, p.y]).collect())
}

/// OpenCV's undistortion map (`initUndistortRectifyMap`, float maps): for
/// every output pixel the source position, for checking
/// [`crate::camera::undistort_map`].
pub fn undistort_map(cam: &CameraModel, new_k: &Intrinsics) -> Result<Vec<[f32; 2]>, CalibError> {
    let mut m1 = Mat::default();
    let mut m2 = Mat::default();
    let eye = Mat::eye(3, 3, core::CV_64F).and_then(|e| e.to_mat()).map_err(cv_err("identity"))?;
    let size = Size::new(cam.image_width as i32, cam.image_height as i32);
    if cam.model == DistortionModel::Fisheye {
        calib3d::fisheye_init_undistort_rectify_map(
            &camera_mat(&cam.intrinsics)?,
            &dist_mat(cam)?,
            &eye,
            &camera_mat(new_k)?,
            size,
            core::CV_32FC1,
            &mut m1,
            &mut m2,
        )
        .map_err(cv_err("fisheye::initUndistortRectifyMap"))?;
        let (u, v) = (m1.data_typed::<f32>().map_err(cv_err("map"))?, m2.data_typed::<f32>().map_err(cv_err("map"))?);
        return Ok(u.iter().zip(v).map(|(a, b)| [*a, *b]).collect());
    }
    calib3d::init_undistort_rectify_map(
        &camera_mat(&cam.intrinsics)?,
        &dist_mat(cam)?,
        &eye,
        &camera_mat(new_k)?,
        size,
        core::CV_32FC1,
        &mut m1,
        &mut m2,
    )
    .map_err(cv_err("initUndistortRectifyMap"))?;
    let (u, v) = (m1.data_typed::<f32>().map_err(cv_err("map"))?, m2.data_typed::<f32>().map_err(cv_err("map"))?);
    Ok(u.iter().zip(v).map(|(a, b)| [*a, *b]).collect())
}

/// A PNG of the photo with the detected corners (OpenCV's coloured pattern),
/// the reprojected corners (red crosses), the (0, 0) corner and the i, j
/// axes marked and labelled ("i (cols)", "j (rows)"), `segments` (pixel end
/// points, e.g. a sample's outline) in cyan labelled "sample", `label`
/// written at the top and a key of the marks in a strip under the photo.
pub fn draw_view_png(
    img: &GrayImage,
    board: &BoardSpec,
    detected: &[[f64; 2]],
    reprojected: &[[f64; 2]],
    segments: &[([f64; 2], [f64; 2])],
    label: &str,
) -> Result<Vec<u8>, CalibError> {
    let gray = gray_mat(img)?;
    let mut bgr = Mat::default();
    imgproc::cvt_color(&gray, &mut bgr, imgproc::COLOR_GRAY2BGR, 0).map_err(cv_err("cvtColor"))?;
    let scale = (img.width.max(img.height) as f64 / 640.0).max(1.0);
    let thick = scale.round().max(1.0) as i32;
    if detected.len() == board.cols * board.rows {
        calib3d::draw_chessboard_corners(&mut bgr, pattern(board), &image_points(detected), true)
            .map_err(cv_err("drawChessboardCorners"))?;
    }
    let pt = |p: [f64; 2]| Point::new(p[0].round() as i32, p[1].round() as i32);
    let red = Scalar::new(0.0, 0.0, 255.0, 0.0);
    let arm = (4.0 * scale).round() as i32;
    for &p in reprojected {
        let c = pt(p);
        for (a, b) in [((-arm, -arm), (arm, arm)), ((-arm, arm), (arm, -arm))] {
            imgproc::line(
                &mut bgr,
                Point::new(c.x + a.0, c.y + a.1),
                Point::new(c.x + b.0, c.y + b.1),
                red,
                thick,
                imgproc::LINE_AA,
                0,
            )
            .map_err(cv_err("line"))?;
        }
    }
    let cyan = Scalar::new(255.0, 255.0, 0.0, 0.0);
    let shown = |p: &[f64; 2]| p.iter().all(|v| v.is_finite() && v.abs() < 1e6);
    let mut outline_top: Option<[f64; 2]> = None;
    for (a, b) in segments {
        if shown(a) && shown(b) {
            imgproc::line(&mut bgr, pt(*a), pt(*b), cyan, thick, imgproc::LINE_AA, 0).map_err(cv_err("line"))?;
            for p in [a, b] {
                if outline_top.is_none_or(|t| p[1] < t[1]) {
                    outline_top = Some(*p);
                }
            }
        }
    }
    let font = imgproc::FONT_HERSHEY_SIMPLEX;
    let text = |m: &mut Mat, s: &str, at: Point, colour: Scalar| {
        imgproc::put_text(m, s, at, font, 0.5 * scale, colour, thick, imgproc::LINE_AA, false)
            .map_err(cv_err("putText"))
    };
    // Labels on the photo: drawn over a black outline, legible on white and black squares.
    let label_on_photo = |m: &mut Mat, s: &str, at: Point, colour: Scalar| {
        let black = Scalar::new(0.0, 0.0, 0.0, 0.0);
        imgproc::put_text(m, s, at, font, 0.5 * scale, black, thick + 3, imgproc::LINE_AA, false)
            .map_err(cv_err("putText"))?;
        text(m, s, at, colour)
    };
    if let Some(t) = outline_top {
        label_on_photo(&mut bgr, "sample", pt([t[0] - 20.0 * scale, t[1] - 6.0 * scale]), cyan)?;
    }
    if detected.len() == board.cols * board.rows {
        let (o, i1, j1) = (detected[0], detected[1], detected[board.cols]);
        let yellow = Scalar::new(0.0, 255.0, 255.0, 0.0);
        for (end, name) in [(i1, "i (cols)"), (j1, "j (rows)")] {
            let tip = [o[0] + 2.0 * (end[0] - o[0]), o[1] + 2.0 * (end[1] - o[1])];
            imgproc::arrowed_line(&mut bgr, pt(o), pt(tip), yellow, thick + 1, imgproc::LINE_AA, 0, 0.2)
                .map_err(cv_err("arrowedLine"))?;
            let label_at =
                [tip[0] + 0.35 * (tip[0] - o[0]) - 5.0 * scale, tip[1] + 0.35 * (tip[1] - o[1]) + 5.0 * scale];
            label_on_photo(&mut bgr, name, pt(label_at), yellow)?;
        }
        label_on_photo(&mut bgr, "(0,0)", pt([o[0] + 6.0, o[1] - 6.0]), yellow)?;
    }
    let (h_text, margin) = ((18.0 * scale) as i32, (6.0 * scale) as i32);
    imgproc::rectangle(
        &mut bgr,
        core::Rect::new(0, 0, img.width as i32, h_text + 2 * margin),
        Scalar::new(0.0, 0.0, 0.0, 0.0),
        -1,
        imgproc::LINE_8,
        0,
    )
    .map_err(cv_err("rectangle"))?;
    text(&mut bgr, label, Point::new(margin, h_text + margin / 2), Scalar::new(255.0, 255.0, 255.0, 0.0))?;

    // The key, in a black strip added under the photo (no mark covered),
    // wrapped onto as many lines as the photo's width needs.
    let white = Scalar::new(255.0, 255.0, 255.0, 0.0);
    let green = Scalar::new(0.0, 200.0, 0.0, 0.0);
    let yellow = Scalar::new(0.0, 255.0, 255.0, 0.0);
    let mut keys: Vec<(u8, Scalar, &str)> =
        vec![(0, green, "detected"), (1, red, "reprojected"), (2, yellow, "i, j: board axes from (0,0)")];
    if outline_top.is_some() {
        keys.push((3, cyan, "sample box"));
    }
    let mut placed = Vec::new();
    let (mut x, mut line) = (margin, 0);
    for (mark, colour, name) in keys {
        let mut base = 0;
        let size = imgproc::get_text_size(name, font, 0.5 * scale, thick, &mut base).map_err(cv_err("getTextSize"))?;
        let width = 3 * arm + margin + size.width;
        if x > margin && x + width > img.width as i32 - margin {
            (x, line) = (margin, line + 1);
        }
        placed.push((mark, colour, name, x, line));
        x += width + 3 * margin;
    }
    let line_h = h_text + margin;
    let strip = (line + 1) * line_h + margin;
    let mut keyed = Mat::default();
    core::copy_make_border(&bgr, &mut keyed, 0, strip, 0, 0, core::BORDER_CONSTANT, Scalar::all(0.0))
        .map_err(cv_err("copyMakeBorder"))?;
    for (mark, colour, name, x, line) in placed {
        let y = img.height as i32 + margin + h_text / 2 + line * line_h;
        let c = Point::new(x + arm, y);
        let (from, to) = (Point::new(x, y), Point::new(x + 3 * arm, y));
        match mark {
            0 => imgproc::circle(&mut keyed, c, arm, colour, thick, imgproc::LINE_AA, 0).map_err(cv_err("circle"))?,
            1 => {
                for (a, b) in [((-arm, -arm), (arm, arm)), ((-arm, arm), (arm, -arm))] {
                    let (p, q) = (Point::new(c.x + a.0, c.y + a.1), Point::new(c.x + b.0, c.y + b.1));
                    imgproc::line(&mut keyed, p, q, colour, thick, imgproc::LINE_AA, 0).map_err(cv_err("line"))?;
                }
            }
            2 => imgproc::arrowed_line(&mut keyed, from, to, colour, thick, imgproc::LINE_AA, 0, 0.4)
                .map_err(cv_err("arrowedLine"))?,
            _ => imgproc::line(&mut keyed, from, to, colour, thick + 1, imgproc::LINE_8, 0).map_err(cv_err("line"))?,
        }
        text(&mut keyed, name, Point::new(x + 3 * arm + margin, y + h_text / 3), white)?;
    }
    let mut buf = Vector::<u8>::new();
    imgcodecs::imencode(".png", &keyed, &mut buf, &Vector::new()).map_err(cv_err("imencode PNG"))?;
    Ok(buf.to_vec())
}

/// A ColorChecker Classic 24 found by OpenCV's `mcc` detector (contrib
/// module, Debian's `libopencv-contrib-dev`).
#[derive(Debug, Clone, PartialEq)]
pub struct MccChart {
    /// The four corners of mcc's chart box, pixels, in the order of its model
    /// box (0, 0), (16.75, 0), (16.75, 11.25), (0, 11.25): the patch grid
    /// plus a margin of 0.25 (a tenth of a patch side) on every side.
    pub corners: [[f64; 2]; 4],
    /// mcc's cost of the fit (lower is better).
    pub cost: f64,
}

/// Runs `CCheckerDetector::process` (chart type `MCC24`, one chart, no
/// neural net, default parameters) on an 8-bit RGB image (`width × height`
/// interleaved R, G, B bytes); `Ok(None)` when it finds no chart.
pub fn detect_mcc24(width: usize, height: usize, rgb8: &[u8]) -> Result<Option<MccChart>, CalibError> {
    if width.checked_mul(height).and_then(|n| n.checked_mul(3)) != Some(rgb8.len()) || width == 0 || height == 0 {
        return Err(BufferSizeError { width, height, channels: 3, len: rgb8.len() }.into());
    }
    let pixels: Vec<core::Vec3b> = rgb8.chunks_exact(3).map(|p| core::Vec3b::from([p[2], p[1], p[0]])).collect();
    let bgr = Mat::new_rows_cols_with_data(height as i32, width as i32, &pixels)
        .and_then(|m| m.try_clone())
        .map_err(cv_err("image"))?;
    let mut detector = MCC_CCheckerDetector::create().map_err(cv_err("mcc CCheckerDetector::create"))?;
    let params = MCC_DetectorParameters::create().map_err(cv_err("mcc DetectorParameters::create"))?;
    let found = detector
        .process(&bgr, MCC_TYPECHART::MCC24, 1, false, &params)
        .map_err(cv_err("mcc CCheckerDetector::process"))?;
    if !found {
        return Ok(None);
    }
    let mut checker = detector.get_best_color_checker().map_err(cv_err("mcc getBestColorChecker"))?;
    let b = checker.get_box().map_err(cv_err("mcc CChecker::getBox"))?;
    if b.len() != 4 {
        return Ok(None);
    }
    let cost = f64::from(checker.get_cost().map_err(cv_err("mcc CChecker::getCost"))?);
    let p = |k: usize| b.get(k).map(|q| [f64::from(q.x), f64::from(q.y)]).map_err(cv_err("mcc box"));
    Ok(Some(MccChart { corners: [p(0)?, p(1)?, p(2)?, p(3)?], cost }))
}

/// Recovers the inverse camera response of 8-bit brackets (OpenCV `photo`:
/// `CalibrateDebevec` with 70 grid samples and λ = 10, or
/// `CalibrateRobertson` with 30 iterations and threshold 0.01), returned per
/// channel R, G, B as 256 relative exposures. The brackets must have been
/// checked ([`crate::hdr::check_8bit`]).
pub fn recover_response(
    brackets: &[Rgb8Buffer],
    exposures: &[f64],
    method: ResponseMethod,
) -> Result<Response, HdrError> {
    use opencv::photo;
    fn err(what: &'static str) -> impl Fn(opencv::Error) -> HdrError {
        move |e| HdrError::OpenCv { context: what, message: e.message }
    }
    let mut images: Vector<Mat> = Vector::new();
    for b in brackets {
        if b.data.len() != b.width * b.height * 3 {
            let (width, height, len) = (b.width, b.height, b.data.len());
            return Err(BufferSizeError { width, height, channels: 3, len }.into());
        }
        // Channel order is carried through unchanged (R, G, B in, R, G, B out).
        let pixels: Vec<core::Vec3b> = b.data.chunks_exact(3).map(|p| core::Vec3b::from([p[0], p[1], p[2]])).collect();
        let m = Mat::new_rows_cols_with_data(b.height as i32, b.width as i32, &pixels)
            .and_then(|m| m.try_clone())
            .map_err(err("image"))?;
        images.push(m);
    }
    let times: Vec<f32> = exposures.iter().map(|&t| t as f32).collect();
    let times = Mat::from_slice(&times).and_then(|m| m.try_clone()).map_err(err("times"))?;
    let mut dst = Mat::default();
    match method {
        ResponseMethod::Debevec => {
            let mut c = photo::create_calibrate_debevec(70, 10.0, false).map_err(err("createCalibrateDebevec"))?;
            c.process(&images, &mut dst, &times).map_err(err("CalibrateDebevec::process"))?;
        }
        ResponseMethod::Robertson => {
            let mut c = photo::create_calibrate_robertson(30, 0.01).map_err(err("createCalibrateRobertson"))?;
            c.process(&images, &mut dst, &times).map_err(err("CalibrateRobertson::process"))?;
        }
    }
    if dst.rows() != 256 || dst.cols() != 1 || dst.typ() != core::CV_32FC3 {
        return Err(HdrError::ResponseShape { rows: dst.rows(), cols: dst.cols(), typ: dst.typ() });
    }
    let mut curve = [vec![0f32; 256], vec![0f32; 256], vec![0f32; 256]];
    for z in 0..256 {
        let v = dst.at_2d::<core::Vec3f>(z as i32, 0).map_err(err("read response"))?;
        for (channel, value) in curve.iter_mut().zip(v.iter()) {
            channel[z] = *value;
        }
    }
    if curve.iter().flatten().any(|v| !(v.is_finite() && *v > 0.0)) {
        return Err(HdrError::ResponseNotPositive);
    }
    Ok(Response { method, curve })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// scene::rodrigues (nalgebra) and scene::rotation_vector agree with OpenCV's cv::Rodrigues, the
    /// independent reference, in both directions, including small angles and angles near π.
    #[test]
    fn rodrigues_matches_opencv() {
        let cases = [[0.1, -0.2, 0.3], [2.0, 1.0, -0.5], [0.0, std::f64::consts::PI - 1e-3, 0.0], [1e-7, 0.0, 0.0]];
        for r in cases {
            let src = Mat::from_slice(&r).unwrap().try_clone().unwrap();
            let mut dst = Mat::default();
            calib3d::rodrigues(&src, &mut dst, &mut core::no_array()).unwrap();
            let want = mat_values(&dst, "test").unwrap();
            let got = crate::pose::rodrigues(r);
            for k in 0..9 {
                assert!(
                    (got[k / 3][k % 3] - want[k]).abs() < 1e-12,
                    "{r:?}: [{k}] {} vs {}",
                    got[k / 3][k % 3],
                    want[k]
                );
            }
            let m = Mat::from_slice_2d(&got).unwrap();
            let mut back = Mat::default();
            calib3d::rodrigues(&m, &mut back, &mut core::no_array()).unwrap();
            let want = mat_values(&back, "test").unwrap();
            let ours = crate::pose::rotation_vector(&got);
            for k in 0..3 {
                assert!((ours[k] - want[k]).abs() < 1e-6, "{r:?}: vector {ours:?} vs OpenCV {want:?}");
            }
        }
    }

    /// The view picture gains a key strip under the photo, which shows the
    /// sample box only when there is one, and the outline is labelled.
    #[test]
    fn view_png_keys_its_marks_and_labels_the_sample() {
        let board = BoardSpec::parse("4x3", 25.0).unwrap();
        let img = GrayImage::new(320, 240, vec![128; 320 * 240]).unwrap();
        let corners: Vec<[f64; 2]> =
            (0..3).flat_map(|r| (0..4).map(move |c| [100.0 + 30.0 * c as f64, 80.0 + 30.0 * r as f64])).collect();
        let decode = |png: Vec<u8>| imgcodecs::imdecode(&Vector::from_slice(&png), imgcodecs::IMREAD_COLOR).unwrap();
        let cyan = |m: &Mat, y0: i32, y1: i32| {
            let mut n = 0;
            for y in y0..y1 {
                for x in 0..m.cols() {
                    let p = m.at_2d::<core::Vec3b>(y, x).unwrap();
                    n += usize::from(p[0] > 200 && p[1] > 200 && p[2] < 80);
                }
            }
            n
        };
        let outline = [([40.0, 220.0], [280.0, 220.0]), ([40.0, 220.0], [40.0, 230.0])];
        let with = decode(draw_view_png(&img, &board, &corners, &corners, &outline, "v").unwrap());
        let without = decode(draw_view_png(&img, &board, &corners, &corners, &[], "v").unwrap());
        // The key wraps onto more lines (of 24 px, + 6 px margin) on a narrow photo.
        assert_eq!((with.cols(), without.cols()), (320, 320));
        assert!(with.rows() >= 240 + 54 && without.rows() >= 240 + 54, "{} {}", with.rows(), without.rows());
        assert!(cyan(&with, 240, with.rows()) > 12, "the key shows the sample box");
        assert_eq!(cyan(&without, 240, without.rows()), 0, "no sample, no sample key");
        assert!(cyan(&with, 195, 216) > 20, "the outline is labelled above its top");
        assert_eq!(cyan(&without, 195, 216), 0);
    }

    #[test]
    fn unreadable_images_are_errors_naming_the_file() {
        let dir = std::env::temp_dir().join(format!("lucent-cv-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let junk = dir.join("junk.jpg");
        std::fs::write(&junk, b"not a jpeg").unwrap();
        let e = read_gray(&junk).unwrap_err().to_string();
        assert!(e.contains("junk.jpg") && e.contains("cannot read image"), "{e}");
        let e = read_gray(&dir.join("missing.png")).unwrap_err().to_string();
        assert!(e.contains("missing.png") && e.contains("no such file"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn a_blank_image_has_no_board() {
        let img = GrayImage::new(64, 48, vec![128; 64 * 48]).unwrap();
        let board = BoardSpec { cols: 4, rows: 3, square_m: 0.01 };
        assert_eq!(find_corners(&img, &board, Detector::Auto).unwrap(), None);
        assert_eq!(suggest_board(&img, &board).unwrap(), None);
    }
}
