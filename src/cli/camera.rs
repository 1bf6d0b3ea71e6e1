//! `lucent raw …`, `lucent calibrate`, `lucent undistort`, `lucent pose` and
//! `lucent env …` (`merge` and `view` in env_hdr.rs): the photo side of the twin (docs/method.md#camera). Orchestration and
//! file handling only; the work is done by `lucent-calib`.

use super::choices::{named, ProjectionChoice};
use crate::imageio::{self, extension, RAW_EXTENSIONS};
use crate::io::json_bytes;
use anyhow::{anyhow, bail, Context, Result};
use clap::{Args, Subcommand};
use lucent_calib::camera::{self, Calibration, DistortionModel, NewCamera, Photo};
use lucent_calib::cv::{self, Detector};
use lucent_calib::demosaic::Demosaic;
use lucent_calib::env;
use lucent_calib::raw::WhiteBalance;
use lucent_calib::raw::{self, RawOptions};
use lucent_calib::RgbBuffer;
use std::path::{Path, PathBuf};

#[path = "env_hdr.rs"]
pub mod env_hdr;

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
    #[arg(long, value_parser = super::common::count_in::<2, 32_768>)]
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

use crate::job::camera::{file_name, read_camera, to_buffer, to_image};

pub(super) use lucent_calib::scene::sibling;

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

/// The photos of `--images` as 8-bit grey ([`crate::job::camera::read_photos`]).
pub fn read_photos(images: &[String]) -> Result<Vec<Photo>> {
    Ok(crate::job::camera::read_photos(images)?)
}

/// `lucent calibrate`: the job of the flags ([`crate::job::CalibrateJob::run`]),
/// then its summary on stdout.
pub fn calibrate(a: CalibrateArgs) -> Result<()> {
    let done = crate::job::CalibrateJob::from(&a).run(&crate::job::Context::default())?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(())
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

/// `lucent pose`: the job of the flags ([`crate::job::PoseJob::run`]), then
/// its summary on stdout.
pub fn pose(a: PoseArgs) -> Result<()> {
    let done = crate::job::PoseJob::from(&a).run(&crate::job::Context::default())?;
    for line in done.summary() {
        println!("{line}");
    }
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

/// An equirectangular HDR map, checked ([`crate::job::read_env_map`]).
fn read_env(path: &Path) -> Result<RgbBuffer> {
    Ok(crate::job::read_env_map(path)?)
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
