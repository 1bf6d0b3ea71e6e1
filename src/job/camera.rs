//! The calibrate and pose stages: [`CalibrateJob::run`] finds a chessboard
//! in each photo and fits the camera's intrinsics and lens distortion to
//! the views (`lucent_calib`), writing the camera file, its residual plot
//! and a picture of every view (detected and reprojected corners;
//! [`CalibrationFiles`]); [`PoseJob::run`] finds the board in one photo of
//! the calibrated camera, solves its pose (PnP) and writes the scene file
//! the renderer reads (board, camera and the sample's box on the board)
//! with a view picture ([`PoseFiles`]). `lucent calibrate` / `pose` and the
//! pipeline's stages run them; the commands parse their flags into the jobs
//! and print the summaries.
//!
//! Also here, for these and the other photo commands (`undistort`, `env
//! orient`, the Python module): reading photos of any supported format as
//! 8-bit grey ([`read_photos`]), the camera file ([`read_camera`]).

mod section;
pub use section::{CalibrateSection, PoseSection};

pub use super::images::{ambiguous_board_warning, file_name, to_buffer, to_image};

use super::context::Context;
use super::spec::{CalibrateJob, PoseJob};
use crate::imageio::{self, extension, ImageIoError, RAW_EXTENSIONS};
use crate::io::{write_atomic, write_json, GlobError, OutputFolderError, WriteError};
use crate::text::duration;
use indicatif::{ProgressBar, ProgressStyle};
use lucent_calib::calibrate::CalibrationFiles;
use lucent_calib::camera::{self, Calibration, DistortionModel, Photo};
use lucent_calib::cv;
use lucent_calib::demosaic::Demosaic;
use lucent_calib::env;
use lucent_calib::error::CalibError;
use lucent_calib::raw::{self, RawError, RawOptions};
use lucent_calib::scene::{self, BoardSpec, PoseFiles, SampleSpec};
use lucent_calib::GrayImage;
use std::path::{Path, PathBuf};

/// Why a calibrate or pose job (or reading its photos) fails.
#[derive(Debug, thiserror::Error)]
pub enum CameraJobError {
    #[error("{spec}: cannot list folder: {source}")]
    ListFolder { spec: String, source: std::io::Error },
    #[error("{spec}: no images in this folder (looked for {}, and RAW files)", IMAGE_EXTENSIONS.join(", "))]
    NoImages { spec: String },
    #[error("{0}: no such file or folder")]
    NoSuchPath(String),
    #[error("--images: {0}")]
    Glob(GlobError),
    #[error("--images {0}: no files match")]
    NoMatch(String),
    #[error("{} of {} image(s) cannot be read:\n  {}", .unreadable.len(), .of, .unreadable.join("\n  "))]
    Unreadable { unreadable: Vec<String>, of: usize },
    #[error(transparent)]
    Raw(#[from] RawError),
    #[error(transparent)]
    Image(#[from] ImageIoError),
    #[error(transparent)]
    Calib(#[from] CalibError),
    #[error("{}: cannot read camera file: {source}", path.display())]
    ReadCamera { path: PathBuf, source: std::io::Error },
    #[error("{}: not a camera.json written by `lucent calibrate`: {source}", path.display())]
    CameraJson { path: PathBuf, source: serde_json::Error },
    #[error("--out {}: is a folder; give the camera file to write, e.g. {}", .0.display(), .0.join(CalibrationFiles::CAMERA).display())]
    OutIsFolder(PathBuf),
    #[error("--square-mm: {0}")]
    Board(String),
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error(transparent)]
    Output(#[from] OutputFolderError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    #[error("internal: view {0} has no photo")]
    ViewWithoutPhoto(String),
    #[error(
        "--board {}x{}: {} was calibrated on a board of {}x{} inner corners — the same board with its columns and \
         rows swapped? --board counts the inner corners along a row first; give --board {}x{}",
        board.0, board.1, camera.display(), calibrated.0, calibrated.1, calibrated.0, calibrated.1
    )]
    SwappedBoard { board: (usize, usize), camera: PathBuf, calibrated: (usize, usize) },
    #[error("--sample-corner {corner}: must be inner-corner indices I,J with 0 ≤ I < {cols} and 0 ≤ J < {rows}")]
    SampleCorner { corner: String, cols: usize, rows: usize },
    #[error("--sample-size-mm {size}: {reason}")]
    SampleSize { size: String, reason: String },
    #[error(
        "{}: {} × {} pixels, but {} was calibrated at {} × {}",
        image.display(), size.0, size.1, camera.display(), calibrated.0, calibrated.1
    )]
    PhotoSize { image: PathBuf, size: (usize, usize), camera: PathBuf, calibrated: (usize, usize) },
    #[error("{}: no chessboard of {cols}x{rows} inner corners found", image.display())]
    NoBoard { image: PathBuf, cols: usize, rows: usize },
}

/// The file extensions of the photos a folder of `--images` is searched for (besides RAW files).
pub const IMAGE_EXTENSIONS: [&str; 8] = ["jpg", "jpeg", "png", "tif", "tiff", "bmp", "exr", "hdr"];

/// Files named by a folder, a file, or a glob pattern in the file-name
/// part (`DIR/*.jpg`, `DIR/left??.{jpg,png}`, `DIR/left0[1-5].jpg`; see
/// [`crate::io::glob_files`]), sorted.
pub fn expand_images(spec: &str) -> Result<Vec<PathBuf>, CameraJobError> {
    let path = Path::new(spec);
    if path.is_dir() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(path)
            .map_err(|source| CameraJobError::ListFolder { spec: spec.to_string(), source })?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                let e = extension(p);
                IMAGE_EXTENSIONS.contains(&e.as_str()) || RAW_EXTENSIONS.contains(&e.as_str())
            })
            .collect();
        files.sort();
        if files.is_empty() {
            return Err(CameraJobError::NoImages { spec: spec.to_string() });
        }
        return Ok(files);
    }
    if path.is_file() {
        return Ok(vec![path.to_path_buf()]);
    }
    if !crate::io::is_glob(spec) {
        return Err(CameraJobError::NoSuchPath(spec.to_string()));
    }
    let files = crate::io::glob_files(spec).map_err(CameraJobError::Glob)?;
    if files.is_empty() {
        return Err(CameraJobError::NoMatch(spec.to_string()));
    }
    Ok(files)
}

/// Loads any supported photo as 8-bit grey for corner detection.
pub fn load_gray(path: &Path) -> Result<GrayImage, CameraJobError> {
    let e = extension(path);
    if RAW_EXTENSIONS.contains(&e.as_str()) {
        let opts = RawOptions { demosaic: Demosaic::Bilinear, ..Default::default() };
        let (img, _) = raw::decode_raw(path, &opts)?;
        return Ok(GrayImage::from_linear_rgb(&img));
    }
    if e == "exr" || e == "hdr" {
        let img = imageio::read_rgb(path)?;
        return Ok(GrayImage::from_linear_rgb(&to_buffer(img)));
    }
    Ok(cv::read_gray(path)?)
}

/// The photos of `--images` (folders, files or patterns; see
/// [`expand_images`]), sorted by path without repeats, as 8-bit grey;
/// one error listing every file that cannot be read.
pub fn read_photos(images: &[String]) -> Result<Vec<Photo>, CameraJobError> {
    read_photo_files(&photo_files(images)?, &mut |_, _| {})
}

/// The files of `--images` (see [`read_photos`]), sorted, without repeats.
pub fn photo_files(images: &[String]) -> Result<Vec<PathBuf>, CameraJobError> {
    let mut files = Vec::new();
    for spec in images {
        files.extend(expand_images(spec)?);
    }
    files.sort();
    files.dedup();
    Ok(files)
}

/// An error and its causes, "a: b: c".
fn chain(e: &dyn std::error::Error) -> String {
    let mut text = e.to_string();
    let mut cause = e.source();
    while let Some(c) = cause {
        text.push_str(&format!(": {c}"));
        cause = c.source();
    }
    text
}

/// [`read_photos`] of the files given, telling `before` of each file it is
/// about to read (with how many were read before it).
pub fn read_photo_files(files: &[PathBuf], before: &mut dyn FnMut(usize, &Path)) -> Result<Vec<Photo>, CameraJobError> {
    let mut photos = Vec::new();
    let mut unreadable = Vec::new();
    for (k, f) in files.iter().enumerate() {
        before(k, f);
        match load_gray(f) {
            Ok(image) => photos.push(Photo { name: file_name(f), image }),
            Err(e) => unreadable.push(chain(&e)),
        }
    }
    if !unreadable.is_empty() {
        return Err(CameraJobError::Unreadable { unreadable, of: files.len() });
    }
    Ok(photos)
}

/// A camera.json written by `lucent calibrate`.
pub fn read_camera(path: &Path) -> Result<Calibration, CameraJobError> {
    let text =
        crate::io::read_text(path).map_err(|source| CameraJobError::ReadCamera { path: path.to_path_buf(), source })?;
    serde_json::from_str(&text).map_err(|source| CameraJobError::CameraJson { path: path.to_path_buf(), source })
}

/// The chessboard of a job's `board` and `square_mm`.
fn board_spec(board: lucent_calib::board::BoardSize, square_mm: f64) -> Result<BoardSpec, CameraJobError> {
    BoardSpec::new(board, square_mm).map_err(|e| CameraJobError::Board(e.to_string()))
}

/// What a calibration fitted and wrote.
pub struct CalibrateRun {
    pub calibration: Calibration,
    /// The files written ([`CalibrationFiles::of`] the job's `out`).
    pub files: CalibrationFiles,
    out: PathBuf,
}

impl CalibrateJob {
    /// Reads the photos, finds the board in each, fits the model and writes
    /// the views, the residual plot and the camera file (in that order; the
    /// views replace the views folder whole). Progress lines go to `ctx`
    /// (none when the job or `ctx` is quiet).
    pub fn run(&self, ctx: &Context) -> Result<CalibrateRun, CameraJobError> {
        if self.out.is_dir() {
            return Err(CameraJobError::OutIsFolder(self.out.clone()));
        }
        let quiet = self.quiet || ctx.quiet;
        let board = board_spec(self.board, self.square_mm)?;
        let files = photo_files(&self.images)?;
        // Reading (RAW files are demosaiced) and the board search take seconds a
        // photo on large images: a bar while reading, a line per photo searched.
        let bar = if quiet || files.is_empty() { ProgressBar::hidden() } else { ProgressBar::new(files.len() as u64) };
        bar.set_style(
            ProgressStyle::with_template("{bar:40} {pos}/{len} photos read  {msg}  ETA {eta}")
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        if !quiet && !files.is_empty() {
            ctx.say(&format!("reading {} photo(s), then finding the board in each and fitting the model", files.len()));
        }
        let photos = read_photo_files(&files, &mut |k, f| {
            bar.set_position(k as u64);
            bar.set_message(file_name(f));
        })?;
        bar.finish_and_clear();
        let start = std::time::Instant::now();
        let threads = rayon::current_num_threads().max(1);
        let calibration = camera::calibrate_photos_reporting(&photos, &board, self.model, self.detector, &|step| {
            if !quiet {
                ctx.say(&calibration_step_line(step, start.elapsed().as_secs_f64(), threads));
            }
        })?;
        let files = CalibrationFiles::of(&self.out);
        write_calibration(&calibration, &photos, &board, &files, &self.out)?;
        Ok(CalibrateRun { calibration, files, out: self.out.clone() })
    }
}

/// Writes a calibration: the view pictures (into a staging folder that
/// replaces the views folder whole, so no view of an earlier run stays
/// beside the new camera file), the residual plot, then the camera file.
fn write_calibration(
    cal: &Calibration,
    photos: &[Photo],
    board: &BoardSpec,
    files: &CalibrationFiles,
    out: &Path,
) -> Result<(), CameraJobError> {
    let views: Vec<(String, Vec<[f64; 2]>)> =
        cal.views.iter().map(|v| (v.image.clone(), v.residuals_px.clone())).collect();
    let residuals_png = crate::plot::residuals_png(&views, cal.rms_px)?;
    let (plot_path, view_dir) = (&files.residuals_png, &files.views);
    // Ctrl-C from here on removes the staging folder (and the views folder,
    // plot and camera file if this run created them) and ends the run.
    let _interrupt = crate::interrupt::Interrupt::abort_on_first();
    let created: Vec<&Path> =
        [view_dir.as_path(), plot_path.as_path(), out].into_iter().filter(|p| !p.exists()).collect();
    // Registered before the staging folder exists: a Ctrl-C the moment it
    // appears still removes it.
    let staging = crate::io::StagedDir::staging_path(view_dir);
    let _remove_on_abort: Vec<_> =
        std::iter::once(staging.as_path()).chain(created).map(crate::interrupt::remove_on_abort).collect();
    let stage = crate::io::StagedDir::new(view_dir)?;
    for v in &cal.views {
        let photo = photos
            .iter()
            .find(|p| p.name == v.image)
            .ok_or_else(|| CameraJobError::ViewWithoutPhoto(v.image.clone()))?;
        let reprojected: Vec<[f64; 2]> =
            v.corners_px.iter().zip(&v.residuals_px).map(|(c, r)| [c[0] - r[0], c[1] - r[1]]).collect();
        let label = format!("{}  RMS {:.3} px  ({})", v.image, v.rms_px, v.detector);
        let png = cv::draw_view_png(&photo.image, board, &v.corners_px, &reprojected, &[], &label)?;
        let stem = Path::new(&v.image).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        write_atomic(&stage.path().join(format!("{stem}.png")), &png)?;
    }
    write_atomic(plot_path, &residuals_png)?;
    stage.commit(|name| name.ends_with(".png"))?;
    write_json(out, cal)?;
    Ok(())
}

/// The progress line of one step of `lucent calibrate`: "view k/n: FILE: …",
/// after the first search with the time the search of all photos expects
/// (the threads search side by side), then the fit.
fn calibration_step_line(step: camera::CalibrationStep<'_>, elapsed_s: f64, threads: usize) -> String {
    match step {
        camera::CalibrationStep::Searched { done, of, photo, found } => {
            let what = match found {
                Some(detector) => format!("board found ({detector})"),
                None => "no board found".into(),
            };
            let expect = if done == 1 && of > 1 {
                let rounds = of.div_ceil(threads) as f64;
                format!("; expect ≈ {} for all {of} photos ({threads} at a time)", duration(elapsed_s * rounds))
            } else {
                String::new()
            };
            format!("view {done}/{of}: {photo}: {what}{expect}")
        }
        camera::CalibrationStep::Fitting { views } => format!("fitting the model to {views} views …"),
    }
}

impl CalibrateRun {
    /// What `lucent calibrate` prints: the intrinsics, the distortion, the
    /// RMS reprojection error of every view, the photos not used, and what
    /// was written.
    pub fn summary(&self) -> Vec<String> {
        let cal = &self.calibration;
        let k = &cal.camera.intrinsics;
        let d = &cal.camera.distortion;
        let mut lines = vec![format!(
            "camera {} × {} px, model {}: fx {:.3}  fy {:.3}  cx {:.3}  cy {:.3} px",
            cal.camera.image_width,
            cal.camera.image_height,
            match cal.camera.model {
                DistortionModel::PinholeK3 => "pinhole-k3",
                DistortionModel::Rational => "rational",
                DistortionModel::Fisheye => "fisheye",
            },
            k.fx,
            k.fy,
            k.cx,
            k.cy
        )];
        let mut distortion = if cal.camera.model == DistortionModel::Fisheye {
            format!("distortion (Kannala–Brandt) k1 {:.5}  k2 {:.5}  k3 {:.5}  k4 {:.5}", d.k1, d.k2, d.k3, d.k4)
        } else {
            format!("distortion k1 {:.5}  k2 {:.5}  p1 {:.6}  p2 {:.6}  k3 {:.5}", d.k1, d.k2, d.p1, d.p2, d.k3)
        };
        if cal.camera.model == DistortionModel::Rational {
            distortion.push_str(&format!("  k4 {:.5}  k5 {:.5}  k6 {:.5}", d.k4, d.k5, d.k6));
        }
        lines.push(distortion);
        lines.push(format!("RMS reprojection error {:.4} px over {} views", cal.rms_px, cal.views.len()));
        for v in &cal.views {
            lines.push(format!("  {:<24} {:>7.4} px  ({})", v.image, v.rms_px, v.detector));
        }
        for n in &cal.not_found {
            lines.push(format!("  {:<24} not used: {}", n.image, n.reason));
        }
        lines.push(format!(
            "written: {} (camera), {} (residuals), {}/ (detected ● and reprojected × corners per view)",
            self.out.display(),
            self.files.residuals_png.display(),
            self.files.views.display()
        ));
        lines
    }
}

/// What a pose job found and wrote.
pub struct PoseRun {
    pub scene: scene::SceneDescription,
    /// The corner order found and the detector that found the corners.
    pub order: env::CornerOrder,
    pub detector: &'static str,
    /// The PnP RMS reprojection error in pixels.
    pub rms_px: f64,
    /// The files written ([`PoseFiles::of`] the job's `out`).
    pub files: PoseFiles,
    out: PathBuf,
}

impl PoseJob {
    /// The sample on the board, checked against the board (its corner one
    /// of the board's, its size one that lies on it).
    fn sample_spec(&self, board: &BoardSpec) -> Result<Option<SampleSpec>, CameraJobError> {
        let Some((c, s)) = &self.sample else { return Ok(None) };
        if c.i >= board.cols || c.j >= board.rows {
            return Err(CameraJobError::SampleCorner { corner: c.to_string(), cols: board.cols, rows: board.rows });
        }
        let size = s.mm();
        // A sample lies on the board (the range of the project's [pose] sample_size_mm).
        if let Some(reason) = super::spec::sample_size_problem(size, board.cols, board.rows, board.square_m * 1e3) {
            return Err(CameraJobError::SampleSize { size: s.to_string(), reason });
        }
        Ok(Some(SampleSpec { corner: [c.i, c.j], size_m: size.map(|v| v / 1000.0) }))
    }

    /// Finds the board in the photo, solves its pose and writes the scene
    /// file with its view picture (both or neither). Warnings go to `ctx`.
    pub fn run(&self, ctx: &Context) -> Result<PoseRun, CameraJobError> {
        let cal = read_camera(&self.camera)?;
        let board = board_spec(self.board, self.square_mm)?;
        // The calibration's board with its columns and rows swapped: the corners
        // would be numbered along the other axis (the sample corner and the
        // world's x and y turned).
        let c = &cal.board;
        if board.cols != board.rows && (board.cols, board.rows) == (c.rows, c.cols) {
            return Err(CameraJobError::SwappedBoard {
                board: (board.cols, board.rows),
                camera: self.camera.clone(),
                calibrated: (c.cols, c.rows),
            });
        }
        let sample = self.sample_spec(&board)?;
        let gray = load_gray(&self.image)?;
        if (gray.width, gray.height) != (cal.camera.image_width, cal.camera.image_height) {
            return Err(CameraJobError::PhotoSize {
                image: self.image.clone(),
                size: (gray.width, gray.height),
                camera: self.camera.clone(),
                calibrated: (cal.camera.image_width, cal.camera.image_height),
            });
        }
        // Numbered as `lucent env orient` numbers them (lucent_calib::scene: the light outer square at corner (0, 0)).
        let (corners, order) = scene::find_board_corners(&gray, &board)?.ok_or_else(|| CameraJobError::NoBoard {
            image: self.image.clone(),
            cols: board.cols,
            rows: board.rows,
        })?;
        if order == env::CornerOrder::Ambiguous {
            ctx.warn(&ambiguous_board_warning(&board, "the pose"));
        }
        let pose = cv::solve_pnp(&corners.points, &board, &cal.camera)?;
        let reprojected: Vec<[f64; 2]> =
            board.corners().iter().map(|p| cal.camera.project(pose.to_camera(*p)).unwrap_or([f64::NAN; 2])).collect();
        let ss: f64 =
            corners.points.iter().zip(&reprojected).map(|(d, r)| (d[0] - r[0]).powi(2) + (d[1] - r[1]).powi(2)).sum();
        let rms = (ss / corners.points.len() as f64).sqrt();
        let k = if self.keep_all { cal.camera.keep_all_intrinsics() } else { cal.camera.intrinsics };
        let scene = scene::describe_scene(&k, (gray.width, gray.height), &pose, &board, sample.as_ref(), rms);
        let segments = sample_box_segments(&scene, &pose, &cal);
        let label = format!("{}  PnP RMS {:.3} px", file_name(&self.image), rms);
        let png = cv::draw_view_png(&gray, &board, &corners.points, &reprojected, &segments, &label)?;
        let files = PoseFiles::of(&self.out);
        // The scene and its view image are one output: both or neither.
        let json = crate::io::json_bytes(&self.out, &scene)?;
        crate::io::write_files_atomic(&[(self.out.as_path(), json.as_slice()), (files.view_png.as_path(), &png)])?;
        Ok(PoseRun { scene, order, detector: corners.detector, rms_px: rms, files, out: self.out.clone() })
    }
}

/// The edges of the sample's box drawn through the calibrated (distorting)
/// camera, in pixels (none without a sample).
fn sample_box_segments(
    scene: &scene::SceneDescription,
    pose: &scene::Pose,
    cal: &Calibration,
) -> Vec<([f64; 2], [f64; 2])> {
    let mut segments = Vec::new();
    if let Some(sp) = &scene.sample {
        let frame = scene::opencv_to_renderer(pose);
        let px: Vec<[f64; 2]> = sp
            .box_corners_world_m
            .iter()
            .map(|w| {
                // world_from_board is diagonal ±1, its own inverse.
                let b = frame.board_to_world(*w);
                cal.camera.project(pose.to_camera(b)).unwrap_or([f64::NAN; 2])
            })
            .collect();
        for k in 0..4 {
            segments.push((px[k], px[(k + 1) % 4]));
            segments.push((px[4 + k], px[4 + (k + 1) % 4]));
            segments.push((px[k], px[4 + k]));
        }
    }
    segments
}

impl PoseRun {
    /// What `lucent pose` prints: where the camera is in the board's world,
    /// the PnP error, the sample's centre and what was written.
    pub fn summary(&self) -> Vec<String> {
        let c = self.scene.camera_position_m;
        let mut lines = vec![format!(
            "board pose: camera at ({:.4}, {:.4}, {:.4}) m in the board's world (z up), {:.3} m from corner (0,0); PnP RMS {:.3} px; \
             corner order {:?} ({} detector)",
            c[0],
            c[1],
            c[2],
            (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt(),
            self.rms_px,
            self.order,
            self.detector
        )];
        if let Some(s) = &self.scene.sample {
            let o = s.object_to_world;
            lines.push(format!("sample centre (bottom face) at ({:.4}, {:.4}, {:.4}) m", o[0][3], o[1][3], o[2][3]));
        }
        lines.push(format!(
            "written: {} (scene), {} (corners and axes)",
            self.out.display(),
            self.files.view_png.display()
        ));
        lines
    }
}
