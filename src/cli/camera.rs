//! `lucent raw …`, `lucent calibrate`, `lucent undistort`, `lucent pose` and
//! `lucent env …` (`merge` and `view` in env_hdr.rs): the photo side of the twin (docs/method.md#camera). Orchestration and
//! file handling only; the work is done by `lucent-calib`.

use super::choices::{named, ProjectionChoice};
use crate::imageio::{self, extension, RgbImage, RAW_EXTENSIONS};
use crate::io::{json_bytes, write_atomic, write_json};
use crate::plot;
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use lucent_calib::camera::{self, Calibration, DistortionModel, NewCamera, Photo};
use lucent_calib::cv::{self, Detector};
use lucent_calib::demosaic::Demosaic;
use lucent_calib::env;
use lucent_calib::raw::WhiteBalance;
use lucent_calib::raw::{self, RawOptions};
use lucent_calib::scene::{self, BoardSpec, SampleSpec};
use lucent_calib::{GrayImage, RgbBuffer};
use std::path::{Path, PathBuf};

#[path = "env_hdr.rs"]
mod env_hdr;

#[derive(Debug, Subcommand)]
pub enum RawCommand {
    /// RAW photo (DNG, CR2, NEF, ARW, …) → linear camera RGB as 32-bit float EXR, with a sidecar JSON
    /// of metadata (make, model, exposure, ISO, black/white levels, colour matrix).
    Decode(RawDecodeArgs),
    /// A mask of the pixels a RAW photo records validly (white) and those at or near a clipped photosite (black).
    Clipped(super::raw_clip::ClippedArgs),
    /// Print the metadata of a RAW photo as JSON (no demosaicing, nothing written).
    Info {
        /// The RAW file.
        input: PathBuf,
    },
}

#[derive(Debug, Args)]
pub struct RawDecodeArgs {
    /// The RAW file.
    pub input: PathBuf,
    /// Output image (.exr); the metadata goes to the same path with .json.
    pub output: PathBuf,
    /// Demosaicing: malvar (Malvar–He–Cutler 2004) or bilinear.
    #[arg(long, value_parser = named::<Demosaic>(), default_value = "malvar")]
    pub demosaic: Demosaic,
    /// White balance: none (camera RGB as recorded) or camera (as-shot multipliers, green = 1).
    #[arg(long, value_parser = named::<WhiteBalance>(), default_value = "none")]
    pub white_balance: WhiteBalance,
    /// Override the white (saturation) level in raw digital numbers.
    #[arg(long)]
    pub white_level: Option<f32>,
    /// Also write an 8-bit sRGB PNG preview here (values clipped to [0, 1]).
    #[arg(long)]
    pub preview: Option<PathBuf>,
}

#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Photos of the chessboard: a folder, a file, or a pattern in the file name such as
    /// 'DIR/*.jpg', 'DIR/*.{jpg,png,exr}' or 'DIR/left0[1-5].jpg' (quote it). JPEG/PNG/TIFF,
    /// EXR/HDR and RAW files are read.
    #[arg(long, required = true, num_args = 1..)]
    pub images: Vec<String>,
    #[command(flatten)]
    pub board: super::groups::BoardArgs,
    /// Distortion model: pinhole-k3 (k1 k2 p1 p2 k3), rational (k1..k6 p1 p2) or fisheye
    /// (Kannala–Brandt k1..k4, OpenCV's fisheye module; one lens of a 360° rig at a time).
    #[arg(long, value_parser = named::<DistortionModel>(), default_value = "pinhole-k3")]
    pub model: DistortionModel,
    /// Corner detector: auto (sector-based, else classic + cornerSubPix), sector-based or classic.
    #[arg(long, value_parser = named::<Detector>(), default_value = "auto")]
    pub detector: Detector,
    /// Output camera JSON; the residual plot and per-view images go beside it
    /// (NAME_residuals.png, NAME_views/).
    #[arg(long)]
    pub out: PathBuf,
    /// No progress lines (the photos read, the board found in each).
    #[arg(long)]
    pub quiet: bool,
}

#[derive(Debug, Args)]
pub struct UndistortArgs {
    /// camera.json written by `lucent calibrate`.
    #[arg(long)]
    pub camera: PathBuf,
    /// Input photo of the calibration's size: .exr/.hdr (linear), RAW (decoded, linear),
    /// .png/.tif/.jpg (values as stored).
    pub input: PathBuf,
    /// Output: .exr (32-bit float) or .png (8-bit; linear input is sRGB-encoded for viewing).
    pub output: PathBuf,
    /// Choose new intrinsics that keep every pixel of the photo (default: keep the calibrated ones,
    /// cropping the borders). The intrinsics used are printed and written to OUTPUT.json.
    #[arg(long)]
    pub keep_all: bool,
    /// Output geometry: pinhole (the photo's size, a distortion-free camera) or equirect (a 2:1
    /// latitude–longitude map of the sphere around the lens, its axis at the map's centre; for
    /// fisheye lenses, also beyond 90° off axis).
    #[arg(long, value_enum, default_value = "pinhole")]
    pub to: ProjectionChoice,
    /// Pinhole output: horizontal field of view in degrees (sets fx = fy = (width/2)/tan(fov/2),
    /// principal point at the centre); overrides --keep-all.
    #[arg(long)]
    pub fov: Option<f64>,
    /// Equirect output: map width in pixels (even, at most 32768; height = width/2). Default: twice the photo's height.
    #[arg(long, value_parser = super::count_in::<2, 32_768>)]
    pub width: Option<usize>,
}

#[derive(Debug, Args)]
pub struct PoseArgs {
    /// camera.json written by `lucent calibrate`.
    #[arg(long)]
    pub camera: PathBuf,
    /// Photo of the board and sample (distorted, as taken; the calibration's size).
    #[arg(long)]
    pub image: PathBuf,
    #[command(flatten)]
    pub board: super::groups::BoardArgs,
    /// Board inner corner I,J under the sample's top-left corner (indices as drawn in the view image).
    #[arg(long, requires = "sample_size_mm")]
    pub sample_corner: Option<crate::job::SampleCorner>,
    /// Sample width (along i), height (along j) and thickness in mm, e.g. 149.1,104.5,6.35.
    #[arg(long, requires = "sample_corner")]
    pub sample_size_mm: Option<crate::job::SampleSizeMm>,
    /// The photo will be undistorted with --keep-all (use those intrinsics in the scene).
    #[arg(long)]
    pub keep_all: bool,
    /// Output scene JSON (renderer convention: see the "convention" field); a view image with the
    /// corners, axes and sample outline goes beside it as NAME_view.png.
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Debug, Subcommand)]
pub enum EnvCommand {
    /// Equirectangular HDR (.exr, .hdr) → checked (2:1, finite), optionally colour-converted, 32-bit EXR (or a PNG preview).
    Convert(EnvConvertArgs),
    /// Size and radiance statistics of an equirectangular HDR map, as JSON.
    Info {
        /// The map (.exr or .hdr).
        input: PathBuf,
    },
    /// Fit the environment's radiance scale so the rendered empty board matches its photo (ratio of sums over the board).
    FitScale(super::env_fit::FitScaleArgs),
    /// HDR from exposure brackets (RAW/linear: weighted mean of value/exposure; 8-bit: camera response
    /// recovered by Debevec–Malik or Robertson), with the dynamic range and saturated pixels as JSON.
    Merge(env_hdr::EnvMergeArgs),
    /// A perspective view cut from an equirectangular map (bilinear), e.g. to find a chart in a panorama.
    View(env_hdr::EnvViewArgs),
    /// Turn the map so its axes match the board's world (x along the board's i axis, z up), from a given
    /// yaw or the board found in a view of the map; the orientation goes beside it as JSON.
    Orient(env_hdr::EnvOrientArgs),
    /// Put a picture (or a flat chessboard) into a map as a view would see it: synthetic panoramas.
    Paste(env_hdr::EnvPasteArgs),
    /// 8-bit exposure brackets of an HDR image through the sRGB curve: synthetic input for `env merge`.
    Brackets(env_hdr::EnvBracketsArgs),
}

#[derive(Debug, Args)]
pub struct EnvConvertArgs {
    /// Input map (.exr or .hdr), equirectangular, 2:1.
    pub input: PathBuf,
    /// Output map (.exr, 32-bit float), or .png: an 8-bit sRGB preview for looking at (clipped at 1).
    pub output: PathBuf,
    /// 3 × 3 matrix applied to every pixel (out = M·rgb): nine numbers row-major ("a,b,c;d,e,f;g,h,i"),
    /// or a JSON file with a 3 × 3 array or a "matrix" key. (For a ColorChecker ccm.json with
    /// chromatic adaptation use `lucent colour apply`.)
    #[arg(long)]
    pub matrix: Option<String>,
}

fn to_buffer(img: RgbImage) -> RgbBuffer {
    RgbBuffer { width: img.width, height: img.height, data: img.data }
}

fn to_image(buf: RgbBuffer) -> RgbImage {
    RgbImage { width: buf.width, height: buf.height, data: buf.data }
}

pub(super) use lucent_calib::scene::sibling;

fn file_name(path: &Path) -> String {
    path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| path.display().to_string())
}

const IMAGE_EXTENSIONS: [&str; 8] = ["jpg", "jpeg", "png", "tif", "tiff", "bmp", "exr", "hdr"];

// ---------------------------------------------------------------- raw

pub fn run_raw(cmd: RawCommand) -> Result<()> {
    match cmd {
        RawCommand::Decode(a) => raw_decode(a),
        RawCommand::Clipped(a) => super::raw_clip::run(a),
        RawCommand::Info { input } => {
            let frame = raw::read_raw(&input, None)?;
            println!("{}", serde_json::to_string_pretty(&frame.meta)?);
            Ok(())
        }
    }
}

fn raw_decode(a: RawDecodeArgs) -> Result<()> {
    if extension(&a.output) != "exr" {
        bail!("{}: the output must be an .exr file (32-bit float linear RGB)", a.output.display());
    }
    let opts = RawOptions { demosaic: a.demosaic, white_balance: a.white_balance, white_level: a.white_level };
    if let Some(w) = a.white_level
        && !(w.is_finite() && w > 0.0)
    {
        bail!("--white-level {w}: must be a positive number of raw digital numbers");
    }
    let (img, meta) = raw::decode_raw(&a.input, &opts)?;
    let img = to_image(img);
    // The image, its metadata and the preview are one output: all or none.
    let sidecar = a.output.with_extension("json");
    let mut files = vec![
        (a.output.clone(), imageio::encode_exr(&a.output, &img)?),
        (sidecar.clone(), json_bytes(&sidecar, &meta)?),
    ];
    if let Some(p) = &a.preview {
        files.push((p.clone(), imageio::encode_png(p, &img)?));
    }
    write_all(&files)?;
    for w in &meta.warnings {
        eprintln!("warning: {}: {w}", a.input.display());
    }
    let exposure = match (meta.exposure_time_s, meta.iso, meta.f_number) {
        (Some(t), iso, f) => format!(
            ", {} s{}{}",
            if t < 1.0 { format!("1/{:.0}", 1.0 / t) } else { format!("{t}") },
            f.map(|f| format!(" f/{f}")).unwrap_or_default(),
            iso.map(|i| format!(" ISO {i}")).unwrap_or_default()
        ),
        _ => String::new(),
    };
    println!(
        "{} {}{exposure}: {} × {} camera RGB ({} demosaic, white balance {}, orientation {}) → {} and {}",
        meta.make,
        meta.model,
        img.width,
        img.height,
        meta.demosaic,
        meta.white_balance_applied.map_or("none".to_string(), |g| format!("{:.3}/{:.3}/{:.3}", g[0], g[1], g[2])),
        meta.orientation_applied,
        a.output.display(),
        sidecar.display()
    );
    Ok(())
}

// ---------------------------------------------------------------- calibrate

/// Files named by a folder, a file, or a glob pattern in the file-name
/// part (`DIR/*.jpg`, `DIR/left??.{jpg,png}`, `DIR/left0[1-5].jpg`; see
/// [`crate::io::glob_files`]), sorted.
pub fn expand_images(spec: &str) -> Result<Vec<PathBuf>> {
    let path = Path::new(spec);
    if path.is_dir() {
        let mut files: Vec<PathBuf> = std::fs::read_dir(path)
            .with_context(|| format!("{spec}: cannot list folder"))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| {
                let e = extension(p);
                IMAGE_EXTENSIONS.contains(&e.as_str()) || RAW_EXTENSIONS.contains(&e.as_str())
            })
            .collect();
        files.sort();
        if files.is_empty() {
            bail!("{spec}: no images in this folder (looked for {}, and RAW files)", IMAGE_EXTENSIONS.join(", "));
        }
        return Ok(files);
    }
    if path.is_file() {
        return Ok(vec![path.to_path_buf()]);
    }
    if !crate::io::is_glob(spec) {
        bail!("{spec}: no such file or folder");
    }
    let files = crate::io::glob_files(spec).context("--images")?;
    if files.is_empty() {
        bail!("--images {spec}: no files match");
    }
    Ok(files)
}

/// Loads any supported photo as 8-bit grey for corner detection.
fn load_gray(path: &Path) -> Result<GrayImage> {
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
pub fn read_photos(images: &[String]) -> Result<Vec<Photo>> {
    read_photo_files(&photo_files(images)?, &mut |_, _| {})
}

/// The files of `--images` (see [`read_photos`]), sorted, without repeats.
fn photo_files(images: &[String]) -> Result<Vec<PathBuf>> {
    let mut files = Vec::new();
    for spec in images {
        files.extend(expand_images(spec)?);
    }
    files.sort();
    files.dedup();
    Ok(files)
}

/// [`read_photos`] of the files given, telling `before` of each file it is
/// about to read (with how many were read before it).
fn read_photo_files(files: &[PathBuf], before: &mut dyn FnMut(usize, &Path)) -> Result<Vec<Photo>> {
    let mut photos = Vec::new();
    let mut unreadable = Vec::new();
    for (k, f) in files.iter().enumerate() {
        before(k, f);
        match load_gray(f) {
            Ok(image) => photos.push(Photo { name: file_name(f), image }),
            Err(e) => unreadable.push(format!("{e:#}")),
        }
    }
    if !unreadable.is_empty() {
        bail!("{} of {} image(s) cannot be read:\n  {}", unreadable.len(), files.len(), unreadable.join("\n  "));
    }
    Ok(photos)
}

pub fn calibrate(a: CalibrateArgs) -> Result<()> {
    if a.out.is_dir() {
        bail!(
            "--out {}: is a folder; give the camera file to write, e.g. {}",
            a.out.display(),
            a.out.join(lucent_calib::calibrate::CalibrationFiles::CAMERA).display()
        );
    }
    let board = a.board.spec()?;
    let files = photo_files(&a.images)?;
    // Reading (RAW files are demosaiced) and the board search take seconds a
    // photo on large images: a bar while reading, a line per photo searched.
    let bar = if a.quiet || files.is_empty() { ProgressBar::hidden() } else { ProgressBar::new(files.len() as u64) };
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} photos read  {msg}  ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    if !a.quiet && !files.is_empty() {
        eprintln!("reading {} photo(s), then finding the board in each and fitting the model", files.len());
    }
    let photos = read_photo_files(&files, &mut |k, f| {
        bar.set_position(k as u64);
        bar.set_message(file_name(f));
    })?;
    bar.finish_and_clear();
    let start = std::time::Instant::now();
    let threads = rayon::current_num_threads().max(1);
    let quiet = a.quiet;
    let cal = camera::calibrate_photos_reporting(&photos, &board, a.model, a.detector, &|step| {
        if !quiet {
            eprintln!("{}", calibration_step_line(step, start.elapsed().as_secs_f64(), threads));
        }
    })?;

    // Plots first, camera.json last; the views go to a staging folder that
    // replaces NAME_views/ whole, so no view of an earlier run stays beside
    // the new camera.json.
    let views: Vec<(String, Vec<[f64; 2]>)> =
        cal.views.iter().map(|v| (v.image.clone(), v.residuals_px.clone())).collect();
    let files = lucent_calib::calibrate::CalibrationFiles::of(&a.out);
    let plot_path = files.residuals_png;
    let residuals_png = plot::residuals_png(&views, cal.rms_px)?;
    let view_dir = files.views;
    // Ctrl-C from here on removes the staging folder (and the views folder,
    // plot and camera file if this run created them) and ends the run.
    let _interrupt = super::interrupt::Interrupt::abort_on_first();
    let created: Vec<_> = [&view_dir, &plot_path, &a.out].into_iter().filter(|p| !p.exists()).collect();
    // Registered before the staging folder exists: a Ctrl-C the moment it
    // appears still removes it.
    let staging = crate::io::StagedDir::staging_path(&view_dir);
    let _remove_on_abort: Vec<_> = std::iter::once(staging.as_path())
        .chain(created.into_iter().map(|p| p.as_path()))
        .map(super::interrupt::remove_on_abort)
        .collect();
    let stage = crate::io::StagedDir::new(&view_dir)?;
    for v in &cal.views {
        let photo = photos
            .iter()
            .find(|p| p.name == v.image)
            .ok_or_else(|| anyhow!("internal: view {} has no photo", v.image))?;
        let reprojected: Vec<[f64; 2]> =
            v.corners_px.iter().zip(&v.residuals_px).map(|(c, r)| [c[0] - r[0], c[1] - r[1]]).collect();
        let label = format!("{}  RMS {:.3} px  ({})", v.image, v.rms_px, v.detector);
        let png = cv::draw_view_png(&photo.image, &board, &v.corners_px, &reprojected, &[], &label)?;
        let stem = Path::new(&v.image).file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        write_atomic(&stage.path().join(format!("{stem}.png")), &png)?;
    }
    write_atomic(&plot_path, &residuals_png)?;
    stage.commit(|name| name.ends_with(".png"))?;
    write_json(&a.out, &cal)?;
    print_calibration(&cal);
    println!(
        "written: {} (camera), {} (residuals), {}/ (detected ● and reprojected × corners per view)",
        a.out.display(),
        plot_path.display(),
        view_dir.display()
    );
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
                format!(
                    "; expect ≈ {} for all {of} photos ({threads} at a time)",
                    super::common::duration(elapsed_s * rounds)
                )
            } else {
                String::new()
            };
            format!("view {done}/{of}: {photo}: {what}{expect}")
        }
        camera::CalibrationStep::Fitting { views } => format!("fitting the model to {views} views …"),
    }
}

fn print_calibration(cal: &Calibration) {
    let k = &cal.camera.intrinsics;
    let d = &cal.camera.distortion;
    println!(
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
    );
    if cal.camera.model == DistortionModel::Fisheye {
        print!("distortion (Kannala–Brandt) k1 {:.5}  k2 {:.5}  k3 {:.5}  k4 {:.5}", d.k1, d.k2, d.k3, d.k4);
    } else {
        print!("distortion k1 {:.5}  k2 {:.5}  p1 {:.6}  p2 {:.6}  k3 {:.5}", d.k1, d.k2, d.p1, d.p2, d.k3);
    }
    if cal.camera.model == DistortionModel::Rational {
        print!("  k4 {:.5}  k5 {:.5}  k6 {:.5}", d.k4, d.k5, d.k6);
    }
    println!();
    println!("RMS reprojection error {:.4} px over {} views", cal.rms_px, cal.views.len());
    for v in &cal.views {
        println!("  {:<24} {:>7.4} px  ({})", v.image, v.rms_px, v.detector);
    }
    for n in &cal.not_found {
        println!("  {:<24} not used: {}", n.image, n.reason);
    }
}

fn read_camera(path: &Path) -> Result<Calibration> {
    let text = crate::io::read_text(path).with_context(|| format!("{}: cannot read camera file", path.display()))?;
    serde_json::from_str(&text)
        .with_context(|| format!("{}: not a camera.json written by `lucent calibrate`", path.display()))
}

// ---------------------------------------------------------------- undistort

/// Any supported photo as RGB; `true` if the values are linear (EXR, HDR,
/// RAW), `false` if they are as an 8/16-bit file stores them (usually
/// sRGB-encoded), scaled to [0, 1].
fn load_rgb(path: &Path) -> Result<(RgbBuffer, bool)> {
    let e = extension(path);
    if RAW_EXTENSIONS.contains(&e.as_str()) {
        return Ok((raw::decode_raw(path, &RawOptions::default())?.0, true));
    }
    match e.as_str() {
        "exr" | "hdr" => Ok((to_buffer(imageio::read_rgb(path)?), true)),
        "png" | "tif" | "tiff" => Ok((to_buffer(imageio::read_rgb(path)?), false)),
        _ => Ok((cv::read_rgb8(path)?, false)),
    }
}

/// An undistorted image as the bytes of `path`'s format: EXR (float), PNG
/// sRGB-encoded from linear values, or PNG of values already display-encoded.
fn encode_output(path: &Path, img: RgbBuffer, linear: bool) -> Result<Vec<u8>> {
    Ok(if extension(path) == "exr" {
        imageio::encode_exr(path, &to_image(img))?
    } else if linear {
        imageio::encode_png(path, &to_image(img))?
    } else {
        png_as_stored(path, &img)?
    })
}

/// Writes a set of files as one output ([`crate::io::write_files_atomic`]).
fn write_all(files: &[(PathBuf, Vec<u8>)]) -> Result<()> {
    let refs: Vec<(&Path, &[u8])> = files.iter().map(|(p, b)| (p.as_path(), b.as_slice())).collect();
    Ok(crate::io::write_files_atomic(&refs)?)
}

/// Values that are already display-encoded as an 8-bit PNG, unchanged.
fn png_as_stored(path: &Path, img: &RgbBuffer) -> Result<Vec<u8>> {
    let bytes: Vec<u8> = img.data.iter().map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8).collect();
    let buf = image::RgbImage::from_raw(img.width as u32, img.height as u32, bytes)
        .ok_or_else(|| anyhow!("{}: image buffer size", path.display()))?;
    let mut out = std::io::Cursor::new(Vec::new());
    buf.write_to(&mut out, image::ImageFormat::Png)
        .with_context(|| format!("{}: cannot encode PNG", path.display()))?;
    Ok(out.into_inner())
}

pub fn undistort(a: UndistortArgs) -> Result<()> {
    let cal = read_camera(&a.camera)?;
    let out_ext = extension(&a.output);
    if out_ext != "exr" && out_ext != "png" {
        bail!("{}: the output must be .exr (float) or .png (8-bit view)", a.output.display());
    }
    let equirect = a.to == ProjectionChoice::Equirect;
    if equirect && a.fov.is_some() {
        bail!("--fov belongs to --to pinhole (an equirectangular map always covers the whole sphere)");
    }
    if !equirect && a.width.is_some() {
        bail!("--width belongs to --to equirect (a pinhole output has the photo's size)");
    }
    if let Some(f) = a.fov
        && !(f > 0.0 && f < 180.0)
    {
        bail!("--fov {f}: a pinhole field of view must be within (0°, 180°)");
    }
    let (img, linear) = load_rgb(&a.input)?;
    if equirect {
        return undistort_equirect(&a, &cal, &img, linear);
    }
    let mode = match a.fov {
        Some(f) => {
            let fx = 0.5 * cal.camera.image_width as f64 / (0.5 * f.to_radians()).tan();
            let (cx, cy) = ((cal.camera.image_width as f64 - 1.0) / 2.0, (cal.camera.image_height as f64 - 1.0) / 2.0);
            NewCamera::Given(camera::Intrinsics { fx, fy: fx, cx, cy })
        }
        None if a.keep_all => NewCamera::KeepAll,
        None => NewCamera::Same,
    };
    let (out, k) = camera::undistort(&img, &cal.camera, mode).map_err(|e| anyhow!("{}: {e}", a.input.display()))?;
    // Values pass through unchanged: linear input stays linear; an 8-bit
    // photo's encoded values are resampled as they are.
    let (width, height) = (out.width, out.height);
    let image = encode_output(&a.output, out, linear)?;
    let info = serde_json::json!({
        "source": file_name(&a.input),
        "camera": file_name(&a.camera),
        "keep_all": a.keep_all,
        "intrinsics": k,
        "resampling": "bilinear; pixels outside the photo are 0",
        "values": if linear { "linear, as read" } else { "as stored in the 8/16-bit input (not linearised), scaled to [0, 1]" },
    });
    let sidecar = a.output.with_extension("json");
    write_all(&[(a.output.clone(), image), (sidecar.clone(), json_bytes(&sidecar, &info)?)])?;
    println!(
        "undistorted {} × {} → {} (pinhole fx {:.3} fy {:.3} cx {:.3} cy {:.3}; written to {})",
        width,
        height,
        a.output.display(),
        k.fx,
        k.fy,
        k.cx,
        k.cy,
        sidecar.display()
    );
    Ok(())
}

/// `lucent undistort --to equirect`: the lens's view as a 2:1 map (`lucent_calib::env::lens_to_equirect`).
fn undistort_equirect(a: &UndistortArgs, cal: &Calibration, img: &RgbBuffer, linear: bool) -> Result<()> {
    let width = a.width.unwrap_or(2 * cal.camera.image_height);
    let out = env::lens_to_equirect(img, &cal.camera, width).map_err(|e| anyhow!("{}: {e}", a.input.display()))?;
    let (w, h) = (out.width, out.height);
    let image = encode_output(&a.output, out, linear)?;
    let info = serde_json::json!({
        "source": file_name(&a.input),
        "camera": file_name(&a.camera),
        "to": "equirect",
        "width": w,
        "height": h,
        "convention": "renderer's map convention (u = 0 along +x, z up); the lens axis at the map's centre (map −x), the camera's up at +z, its right at +y",
        "resampling": "bilinear; directions outside the photo or the lens's field are 0",
        "values": if linear { "linear, as read" } else { "as stored in the 8/16-bit input (not linearised), scaled to [0, 1]" },
    });
    let sidecar = a.output.with_extension("json");
    write_all(&[(a.output.clone(), image), (sidecar.clone(), json_bytes(&sidecar, &info)?)])?;
    println!(
        "{} ({} model) → {w} × {h} equirectangular map {} (lens axis at the centre); written to {}",
        a.input.display(),
        match cal.camera.model {
            DistortionModel::Fisheye => "fisheye",
            DistortionModel::PinholeK3 => "pinhole-k3",
            DistortionModel::Rational => "rational",
        },
        a.output.display(),
        sidecar.display()
    );
    Ok(())
}

// ---------------------------------------------------------------- pose

/// The warning of `pose` and `env orient` when corner (0, 0) cannot be told from the opposite one.
fn ambiguous_board_warning(board: &BoardSpec, what: &str) -> String {
    format!(
        "warning: corner (0, 0) of the {}x{} board cannot be told from the opposite corner (a board with two even \
         or two odd counts looks the same turned 180°, or its outer corner squares are not both visible): {what} \
         may be off by 180°; use a board with one odd and one even count, e.g. 9x6, seen whole",
        board.cols, board.rows
    )
}

pub fn pose(a: PoseArgs) -> Result<()> {
    let cal = read_camera(&a.camera)?;
    let board = a.board.spec()?;
    // The calibration's board with its columns and rows swapped: the corners
    // would be numbered along the other axis (the sample corner and the
    // world's x and y turned).
    let c = &cal.board;
    if board.cols != board.rows && (board.cols, board.rows) == (c.rows, c.cols) {
        bail!(
            "--board {}x{}: {} was calibrated on a board of {}x{} inner corners — the same board with its columns and \
             rows swapped? --board counts the inner corners along a row first; give --board {}x{}",
            board.cols,
            board.rows,
            a.camera.display(),
            c.cols,
            c.rows,
            c.cols,
            c.rows
        );
    }
    let sample = match (&a.sample_corner, &a.sample_size_mm) {
        (Some(c), Some(s)) => {
            if c.i >= board.cols || c.j >= board.rows {
                bail!(
                    "--sample-corner {c}: must be inner-corner indices I,J with 0 ≤ I < {} and 0 ≤ J < {}",
                    board.cols,
                    board.rows
                );
            }
            let size = s.mm();
            // A sample lies on the board (the range of the project's [pose] sample_size_mm).
            if let Some(reason) = crate::job::sample_size_problem(size, board.cols, board.rows, board.square_m * 1e3) {
                bail!("--sample-size-mm {s}: {reason}");
            }
            Some(SampleSpec { corner: [c.i, c.j], size_m: size.map(|v| v / 1000.0) })
        }
        _ => None,
    };
    let gray = load_gray(&a.image)?;
    if (gray.width, gray.height) != (cal.camera.image_width, cal.camera.image_height) {
        bail!(
            "{}: {} × {} pixels, but {} was calibrated at {} × {}",
            a.image.display(),
            gray.width,
            gray.height,
            a.camera.display(),
            cal.camera.image_width,
            cal.camera.image_height
        );
    }
    // Numbered as `lucent env orient` numbers them (lucent_calib::scene: the light outer square at corner (0, 0)).
    let (corners, order) = scene::find_board_corners(&gray, &board)?.ok_or_else(|| {
        anyhow!("{}: no chessboard of {}x{} inner corners found", a.image.display(), board.cols, board.rows)
    })?;
    if order == env::CornerOrder::Ambiguous {
        eprintln!("{}", ambiguous_board_warning(&board, "the pose"));
    }
    let pose = cv::solve_pnp(&corners.points, &board, &cal.camera)?;
    let reprojected: Vec<[f64; 2]> =
        board.corners().iter().map(|p| cal.camera.project(pose.to_camera(*p)).unwrap_or([f64::NAN; 2])).collect();
    let ss: f64 =
        corners.points.iter().zip(&reprojected).map(|(d, r)| (d[0] - r[0]).powi(2) + (d[1] - r[1]).powi(2)).sum();
    let rms = (ss / corners.points.len() as f64).sqrt();
    let k = if a.keep_all { cal.camera.keep_all_intrinsics() } else { cal.camera.intrinsics };
    let scene = scene::describe_scene(&k, (gray.width, gray.height), &pose, &board, sample.as_ref(), rms);
    // The sample's box drawn through the calibrated (distorting) camera.
    let mut segments = Vec::new();
    if let Some(sp) = &scene.sample {
        let frame = scene::opencv_to_renderer(&pose);
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
    let label = format!("{}  PnP RMS {:.3} px", file_name(&a.image), rms);
    let png = cv::draw_view_png(&gray, &board, &corners.points, &reprojected, &segments, &label)?;
    let view = lucent_calib::scene::PoseFiles::of(&a.out).view_png;
    // The scene and its view image are one output: both or neither.
    write_all(&[(a.out.clone(), json_bytes(&a.out, &scene)?), (view.clone(), png)])?;
    let c = scene.camera_position_m;
    println!(
        "board pose: camera at ({:.4}, {:.4}, {:.4}) m in the board's world (z up), {:.3} m from corner (0,0); PnP RMS {:.3} px; \
         corner order {:?} ({} detector)",
        c[0],
        c[1],
        c[2],
        (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt(),
        rms,
        order,
        corners.detector
    );
    if let Some(s) = &scene.sample {
        let o = s.object_to_world;
        println!("sample centre (bottom face) at ({:.4}, {:.4}, {:.4}) m", o[0][3], o[1][3], o[2][3]);
    }
    println!("written: {} (scene), {} (corners and axes)", a.out.display(), view.display());
    Ok(())
}

// ---------------------------------------------------------------- env

pub fn run_env(cmd: EnvCommand) -> Result<()> {
    match cmd {
        EnvCommand::Convert(a) => env_convert(a),
        EnvCommand::Info { input } => {
            let img = read_env(&input)?;
            println!("{}", serde_json::to_string_pretty(&env::summarize(&img))?);
            Ok(())
        }
        EnvCommand::FitScale(a) => super::env_fit::run(a),
        EnvCommand::Merge(a) => env_hdr::merge(a),
        EnvCommand::View(a) => env_hdr::view(a),
        EnvCommand::Orient(a) => env_hdr::orient(a),
        EnvCommand::Paste(a) => env_hdr::paste(a),
        EnvCommand::Brackets(a) => env_hdr::brackets(a),
    }
}

fn read_env(path: &Path) -> Result<RgbBuffer> {
    let e = extension(path);
    if e != "exr" && e != "hdr" {
        bail!("{}: an HDR environment must be .exr or .hdr", path.display());
    }
    let img = to_buffer(imageio::read_rgb(path)?);
    env::check_equirectangular(img.width, img.height).with_context(|| format!("{}", path.display()))?;
    env::check_finite(&img).with_context(|| format!("{}", path.display()))?;
    Ok(img)
}

fn env_convert(a: EnvConvertArgs) -> Result<()> {
    let png = extension(&a.output) == "png";
    if extension(&a.output) != "exr" && !png {
        bail!("{}: the output must be an .exr file (or a .png preview)", a.output.display());
    }
    let matrix = match &a.matrix {
        None => None,
        Some(m) => {
            let p = Path::new(m);
            let text = if p.is_file() {
                crate::io::read_text(p).with_context(|| format!("{m}: cannot read matrix file"))?
            } else if m.ends_with(".json") || m.contains('/') {
                bail!("--matrix {m}: no such file (give a JSON file or nine numbers \"a,b,c;d,e,f;g,h,i\")");
            } else {
                m.clone()
            };
            let matrix = env::parse_matrix(&text).with_context(|| format!("--matrix {m}"))?;
            if matrix.iter().flatten().all(|v| *v == 0.0) {
                bail!("--matrix {m}: every coefficient is 0, the map would be black");
            }
            Some(matrix)
        }
    };
    let mut img = read_env(&a.input)?;
    if let Some(m) = &matrix {
        env::apply_matrix(&mut img, m);
    }
    let summary = env::summarize(&img);
    if png {
        imageio::write_png(&a.output, &to_image(img))?;
    } else {
        imageio::write_exr(&a.output, &to_image(img))?;
    }
    println!(
        "{} × {} equirectangular{} → {}; mean radiance over the sphere R {:.4} G {:.4} B {:.4}, max {:.1}{}",
        summary.width,
        summary.height,
        if matrix.is_some() { ", colour matrix applied" } else { "" },
        a.output.display(),
        summary.mean_over_sphere[0],
        summary.mean_over_sphere[1],
        summary.mean_over_sphere[2],
        summary.max.iter().copied().fold(f32::NEG_INFINITY, f32::max),
        if summary.negative_values > 0 {
            format!(", {} negative values (outside the target gamut)", summary.negative_values)
        } else {
            String::new()
        }
    );
    Ok(())
}
