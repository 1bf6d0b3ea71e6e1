//! `lucent env merge` (HDR from exposure brackets), `lucent env view`
//! (a perspective view cut from an equirectangular map) and `lucent env
//! orient` (the map turned to the board's world, from a given yaw or the
//! board found in a view): file handling only; the merge is
//! `lucent_calib::hdr`, the view and orientation `lucent_calib::env`.

use super::{file_name, sibling, to_buffer, to_image, RAW_EXTENSIONS};
use crate::cli::choices::named;
use crate::imageio::{self, extension, RgbImage};
use crate::io::{json_bytes, write_json};
use anyhow::{bail, Context, Result};
use clap::{ArgGroup, Args};
use lucent_calib::camera::{CameraModel, Distortion, DistortionModel};
use lucent_calib::env::{self, BoardFound, Orientation, ViewSpec};
use lucent_calib::hdr::{self, CodeWeights, LinearWeights, Merged, ResponseMethod, Rgb8Buffer};
use lucent_calib::raw::{self, RawOptions};
use lucent_calib::scene::BoardSpec;
use lucent_calib::{cv, RgbBuffer};
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct EnvMergeArgs {
    /// The brackets, all the same size and aligned: RAW files (decoded to linear camera RGB; exposure
    /// time × ISO / f-number² read from their metadata), linear .exr/.hdr or 16-bit .png/.tif (need
    /// --exposures), or 8-bit .jpg/.png/.tif (camera response recovered, need --exposures).
    #[arg(required = true, num_args = 2..)]
    pub brackets: Vec<PathBuf>,
    /// Relative exposure of each bracket, in order, comma-separated; fractions allowed
    /// (e.g. "1/1000,1/250,1/60"). Overrides RAW metadata.
    #[arg(long)]
    pub exposures: Option<String>,
    /// Output HDR (.exr, 32-bit float); the report goes to NAME.json and the mask of pixels saturated
    /// in every bracket to NAME_saturated.png.
    #[arg(long)]
    pub out: PathBuf,
    /// Camera-response recovery for 8-bit brackets: debevec (Debevec & Malik 1997) or robertson
    /// (Robertson et al. 2003).
    #[arg(long, value_parser = named::<ResponseMethod>(), default_value = "debevec")]
    pub method: ResponseMethod,
    /// Linear brackets: a pixel whose largest channel reaches this is saturated (RAW white = 1).
    #[arg(long, default_value_t = 0.98)]
    pub saturation: f32,
    /// Linear brackets: values below this are noise (weights rise from here to twice it).
    #[arg(long, default_value_t = 0.002)]
    pub noise_floor: f32,
    /// 8-bit brackets: codes at or above this are saturated.
    #[arg(long, default_value_t = 250)]
    pub saturation_code: u8,
    /// 8-bit brackets: codes at or below this are noise.
    #[arg(long, default_value_t = 5)]
    pub floor_code: u8,
}

#[derive(Debug, Args)]
pub struct EnvViewArgs {
    /// Equirectangular map (.exr or .hdr, 2:1), the renderer's convention (u = 0 along +x, z up).
    pub input: PathBuf,
    /// Azimuth of the view axis, degrees counter-clockwise from the map's +x seen from above
    /// (0 = the map's left edge column, 90 = three quarters across).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub yaw: f64,
    /// Elevation of the view axis, degrees (+90 = straight up).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub pitch: f64,
    /// Horizontal field of view, degrees (0 < fov < 180).
    #[arg(long, default_value_t = 90.0)]
    pub fov: f64,
    /// Output size WIDTHxHEIGHT in pixels, e.g. 1024x768 (or one number for a square).
    #[arg(long, default_value = "1024x768")]
    pub size: String,
    /// Output view: .exr (linear, 32-bit float) or .png (8-bit sRGB for looking at); the camera
    /// (focal length in pixels, axes in the map frame) goes to NAME.json.
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
#[command(group(ArgGroup::new("how").required(true).args(["yaw", "board_view"])))]
pub struct EnvOrientArgs {
    /// Equirectangular map (.exr or .hdr, 2:1) as the 360° camera made it.
    pub input: PathBuf,
    /// The turn, degrees counter-clockwise seen from above, if known: world = R_z(yaw) · map (the
    /// renderer's [environment] yaw_deg).
    #[arg(long, allow_hyphen_values = true)]
    pub yaw: Option<f64>,
    /// Find the board instead: the view of the map that shows it, YAW,PITCH,FOV in degrees as for
    /// `lucent env view` (e.g. "0,-90,100" looks straight down). Needs --board and --square-mm.
    #[arg(long, requires_all = ["board", "square_mm"], allow_hyphen_values = true)]
    pub board_view: Option<String>,
    /// Inner corners COLSxROWS of the board (its i axis becomes the world's +x). Corner (0, 0) is numbered
    /// as `lucent pose` numbers it: the one diagonally beyond the light outer corner square (OpenCV's
    /// numbering); only a board with one odd and one even count (e.g. 9x6) fixes it.
    #[arg(long)]
    pub board: Option<String>,
    /// Side of one square in millimetres.
    #[arg(long)]
    pub square_mm: Option<f64>,
    /// Size of the board view, WIDTHxHEIGHT pixels.
    #[arg(long, default_value = "1600x1200")]
    pub view_size: String,
    /// Refuse a board whose normal is further than this from the map's zenith (degrees): a yaw cannot
    /// level a tilted map.
    #[arg(long, default_value_t = 10.0)]
    pub max_tilt_deg: f64,
    /// Output map (.exr), turned so world = map (render it with yaw 0); the orientation goes to
    /// NAME.json (a scene's [environment] orientation = "NAME.json" takes its yaw from it) and, with
    /// --board-view, the view with the corners to NAME_board.png.
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
#[command(group(ArgGroup::new("what").required(true).args(["image", "chessboard"])))]
pub struct EnvPasteArgs {
    /// Equirectangular map (.exr or .hdr, 2:1) to paste into.
    pub input: PathBuf,
    /// The picture (.exr linear, or .png/.tif scaled to [0, 1]), pasted as the view --yaw/--pitch/--fov
    /// of its own size would see it (the inverse of `lucent env view`).
    #[arg(long)]
    pub image: Option<PathBuf>,
    /// Or a flat chessboard of COLSxROWS inner corners (dark outer square at the picture's top left, one
    /// square of white margin; for e.g. 9x6 `pose`/`env orient` put corner (0, 0) at the light bottom-right
    /// outer square, i pointing left, j up), as a level board seen straight down when --pitch is -90.
    #[arg(long)]
    pub chessboard: Option<String>,
    /// Chessboard: values of the dark and light squares (linear).
    #[arg(long, default_value = "0.03,0.6")]
    pub chessboard_values: String,
    /// Azimuth of the view axis, degrees (as for `lucent env view`).
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub yaw: f64,
    /// Elevation of the view axis, degrees.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub pitch: f64,
    /// Horizontal field of view the picture spans, degrees.
    #[arg(long)]
    pub fov: f64,
    /// Resample the map to this width first (bilinear; height = width/2, at most 32768), so a small picture keeps
    /// its detail.
    #[arg(long, value_parser = crate::cli::count_in::<2, 32_768>)]
    pub width: Option<usize>,
    /// Output map (.exr).
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct EnvBracketsArgs {
    /// HDR map or image (.exr or .hdr) to "photograph".
    pub input: PathBuf,
    /// Relative exposures, comma-separated (e.g. "1,4,16,64"); value × exposure is clipped at 1 and
    /// encoded with the sRGB transfer curve (IEC 61966-2-1), 8 bits per channel.
    #[arg(long)]
    pub exposures: String,
    /// Output folder: bracket_1.png … bracket_N.png (in the order given) and brackets.json
    /// (`--out-dir` and `--output` are older spellings).
    #[arg(long = "out", alias = "out-dir", alias = "output")]
    pub out_dir: PathBuf,
}

/// "1/250", "0.004", "2" → seconds (or any relative unit).
fn parse_exposure(s: &str) -> Option<f64> {
    let s = s.trim();
    let v = match s.split_once('/') {
        Some((a, b)) => a.trim().parse::<f64>().ok()? / b.trim().parse::<f64>().ok()?,
        None => s.parse::<f64>().ok()?,
    };
    (v.is_finite() && v > 0.0).then_some(v)
}

fn parse_exposures(text: &str, n: usize) -> Result<Vec<f64>> {
    let parts: Vec<&str> = text.split(',').collect();
    let mut out = Vec::with_capacity(parts.len());
    for p in &parts {
        match parse_exposure(p) {
            Some(v) => out.push(v),
            None => bail!("--exposures {text}: {p:?} is not a positive number or fraction (e.g. 1/250)"),
        }
    }
    if out.len() != n {
        bail!("--exposures {text}: {} values for {n} brackets; give one exposure per bracket, in order", out.len());
    }
    Ok(out)
}

/// A bracket as read: linear (with its exposure from metadata, if any) or 8-bit codes.
enum Bracket {
    Linear(RgbBuffer, Option<f64>),
    Codes(Rgb8Buffer),
}

fn read_bracket(path: &Path) -> Result<Bracket> {
    let e = extension(path);
    if !path.is_file() {
        bail!("{}: no such file", path.display());
    }
    if RAW_EXTENSIONS.contains(&e.as_str()) {
        let (img, meta) = raw::decode_raw(path, &RawOptions::default())?;
        // Relative exposure ∝ t · ISO / N² (only the factors the file records).
        let exposure = meta.exposure_time_s.filter(|t| *t > 0.0).map(|t| {
            let iso = meta.iso.map_or(1.0, |i| f64::from(i.max(1)) / 100.0);
            let n = meta.f_number.filter(|n| *n > 0.0).map_or(1.0, |n| 1.0 / (n * n));
            t * iso * n
        });
        return Ok(Bracket::Linear(img, exposure));
    }
    match e.as_str() {
        "exr" | "hdr" => Ok(Bracket::Linear(to_buffer(imageio::read_rgb(path)?), None)),
        "jpg" | "jpeg" => {
            let img = cv::read_rgb8(path)?;
            Ok(Bracket::Codes(codes(img)))
        }
        "png" | "tif" | "tiff" => {
            let read_err = |e: image::ImageError| anyhow::anyhow!("{}: cannot read image: {e}", path.display());
            let img = image::ImageReader::open(path)
                .with_context(|| format!("{}: cannot open", path.display()))?
                .with_guessed_format()
                .with_context(|| format!("{}: cannot read", path.display()))?
                .decode()
                .map_err(read_err)?;
            let eight = matches!(
                img.color(),
                image::ColorType::L8 | image::ColorType::La8 | image::ColorType::Rgb8 | image::ColorType::Rgba8
            );
            if eight {
                let rgb = img.to_rgb8();
                let (w, h) = rgb.dimensions();
                Ok(Bracket::Codes(Rgb8Buffer::new(w as usize, h as usize, rgb.into_raw())?))
            } else {
                let rgb = img.into_rgb32f();
                let (w, h) = rgb.dimensions();
                Ok(Bracket::Linear(RgbBuffer::new(w as usize, h as usize, rgb.into_raw())?, None))
            }
        }
        _ => {
            bail!("{}: unsupported bracket format (RAW, .exr, .hdr, .png, .tif, .tiff, .jpg or .jpeg)", path.display())
        }
    }
}

/// 8-bit values read as v/255 back to codes (exact).
fn codes(img: RgbBuffer) -> Rgb8Buffer {
    let data = img.data.iter().map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8).collect();
    Rgb8Buffer { width: img.width, height: img.height, data }
}

pub fn merge(a: EnvMergeArgs) -> Result<()> {
    if extension(&a.out) != "exr" {
        bail!("{}: the output must be an .exr file (32-bit float)", a.out.display());
    }
    let method = a.method;
    let mut linear = Vec::new();
    let mut eight = Vec::new();
    let mut meta_exposures = Vec::new();
    // One file given twice (under two spellings) would weigh one exposure twice.
    let mut seen: Vec<(PathBuf, &Path)> = Vec::new();
    for p in &a.brackets {
        let key = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
        if let Some((_, first)) = seen.iter().find(|(k, _)| *k == key) {
            bail!("bracket {}: the same file as {} (each bracket is one exposure)", p.display(), first.display());
        }
        seen.push((key, p));
    }
    for p in &a.brackets {
        match read_bracket(p).with_context(|| format!("bracket {}", p.display()))? {
            Bracket::Linear(img, t) => {
                // Linear values are light: a negative one is no exposure of a scene.
                if let Some(i) = img.data.iter().position(|v| *v < 0.0) {
                    let px = i / 3;
                    bail!(
                        "bracket {}: value {} at pixel ({}, {}) is negative; linear brackets hold light (≥ 0)",
                        p.display(),
                        img.data[i],
                        px % img.width,
                        px / img.width
                    );
                }
                linear.push((p, img));
                meta_exposures.push(t);
            }
            Bracket::Codes(img) => eight.push((p, img)),
        }
    }
    if !linear.is_empty() && !eight.is_empty() {
        bail!(
            "the brackets mix linear ({}) and 8-bit ({}) files; merge one kind at a time",
            file_name(linear[0].0),
            file_name(eight[0].0)
        );
    }
    let n = a.brackets.len();
    let exposures = match &a.exposures {
        Some(text) => parse_exposures(text, n)?,
        None => {
            let missing: Vec<String> = a
                .brackets
                .iter()
                .zip(meta_exposures.iter().chain(std::iter::repeat(&None)))
                .filter(|(_, t)| t.is_none())
                .map(|(p, _)| file_name(p))
                .collect();
            if !missing.is_empty() {
                bail!(
                    "no exposure recorded for {}: give --exposures (one per bracket, e.g. 1/1000,1/250,1/60)",
                    missing.join(", ")
                );
            }
            meta_exposures.iter().map(|t| t.unwrap_or(1.0)).collect()
        }
    };
    let size_err = |e: hdr::HdrError| -> anyhow::Error {
        match e {
            hdr::HdrError::SizeMismatch { index, .. } => {
                anyhow::anyhow!("{}: {e}", a.brackets[index].display())
            }
            other => other.into(),
        }
    };
    let (merged, response): (Merged, Option<hdr::Response>) = if eight.is_empty() {
        let w = LinearWeights { saturation: a.saturation, noise_floor: a.noise_floor };
        let imgs: Vec<RgbBuffer> = linear.into_iter().map(|(_, i)| i).collect();
        (hdr::merge_linear(&imgs, &exposures, &w).map_err(size_err)?, None)
    } else {
        let w = CodeWeights { saturation: a.saturation_code, floor: a.floor_code };
        let imgs: Vec<Rgb8Buffer> = eight.into_iter().map(|(_, i)| i).collect();
        let (m, r) = hdr::merge_8bit_recovered(&imgs, &exposures, method, &w).map_err(size_err)?;
        (m, Some(r))
    };
    let rep = &merged.report;
    let json_path = sibling(&a.out, ".json");
    let mask_path = sibling(&a.out, "_saturated.png");
    let json = serde_json::json!({
        "output": file_name(&a.out),
        "brackets": a.brackets.iter().map(|p| file_name(p)).collect::<Vec<_>>(),
        "report": rep,
        "response": response,
        "saturated_mask": file_name(&mask_path),
        "units": if response.is_some() {
            "relative radiance (8-bit: the response is known up to one global factor)"
        } else {
            "bracket values / relative exposure (RAW: 1.0 = white level at exposure 1)"
        },
    });
    let mask = RgbImage {
        width: rep.width,
        height: rep.height,
        data: merged.saturated_mask.iter().flat_map(|&s| [if s { 1.0f32 } else { 0.0 }; 3]).collect(),
    };
    // The map, its JSON and its saturation mask are one output: all or none.
    crate::io::write_files_atomic(&[
        (&mask_path, &imageio::encode_png(&mask_path, &mask)?),
        (&json_path, &json_bytes(&json_path, &json)?),
        (&a.out, &imageio::encode_exr(&a.out, &to_image(merged.image))?),
    ])?;
    println!(
        "{} {} brackets ({} × {}) → {}: dynamic range {:.1} stops (the bracket set can capture {:.1}); \
         {} pixels saturated in every bracket{}, {} below the noise floor in every bracket; report {}",
        n,
        rep.mode,
        rep.width,
        rep.height,
        a.out.display(),
        rep.dynamic_range_stops,
        rep.capturable_range_stops,
        rep.saturated_in_every_bracket,
        if rep.saturated_in_every_bracket > 0 { format!(" (mask {})", mask_path.display()) } else { String::new() },
        rep.below_floor_in_every_bracket,
        json_path.display()
    );
    if rep.width != 2 * rep.height {
        eprintln!(
            "note: {} × {} is not 2:1; `lucent env` commands that need an equirectangular map will refuse it",
            rep.width, rep.height
        );
    }
    Ok(())
}

fn parse_size(s: &str) -> Result<(usize, usize)> {
    let bad = || anyhow::anyhow!("--size {s}: give WIDTHxHEIGHT in pixels, e.g. 1024x768, or one number");
    let (w, h) = match s.split_once(['x', 'X', '×']) {
        Some((w, h)) => (w.trim().parse().map_err(|_| bad())?, h.trim().parse().map_err(|_| bad())?),
        None => {
            let n = s.trim().parse().map_err(|_| bad())?;
            (n, n)
        }
    };
    Ok((w, h))
}

pub fn view(a: EnvViewArgs) -> Result<()> {
    let ext = extension(&a.out);
    if ext != "exr" && ext != "png" {
        bail!("{}: the output must be .exr (linear) or .png (sRGB preview)", a.out.display());
    }
    let (width, height) = parse_size(&a.size)?;
    let spec = ViewSpec { yaw_deg: a.yaw, pitch_deg: a.pitch, fov_deg: a.fov, width, height };
    spec.camera()?; // parameters checked before the map is read
    let map = super::read_env(&a.input)?;
    let (img, cam) = env::perspective_view(&map, &spec)?;
    let img = to_image(img);
    let json_path = sibling(&a.out, ".json");
    let json = json_bytes(&json_path, &serde_json::json!({ "source": file_name(&a.input), "camera": cam }))?;
    let view = if ext == "exr" { imageio::encode_exr(&a.out, &img)? } else { imageio::encode_png(&a.out, &img)? };
    crate::io::write_files_atomic(&[(&json_path, &json), (&a.out, &view)])?;
    println!(
        "{width} × {height} view (yaw {}°, pitch {}°, horizontal fov {}°, f = {:.2} px) of {} → {}; camera {}",
        a.yaw,
        a.pitch,
        a.fov,
        cam.f_px,
        a.input.display(),
        a.out.display(),
        json_path.display()
    );
    Ok(())
}

pub fn orient(a: EnvOrientArgs) -> Result<()> {
    if extension(&a.out) != "exr" {
        bail!("{}: the output must be an .exr file (32-bit float)", a.out.display());
    }
    if let Some(y) = a.yaw
        && !(y.is_finite() && y.abs() <= lucent_render::env::MAX_YAW_DEG)
    {
        bail!("--yaw {y}: must be a finite number of degrees within ±{}°", lucent_render::env::MAX_YAW_DEG);
    }
    if !(a.max_tilt_deg.is_finite() && a.max_tilt_deg > 0.0) {
        bail!("--max-tilt-deg {}: must be a positive number of degrees", a.max_tilt_deg);
    }
    // Parameters are checked before the map is read.
    let board_setup = match &a.board_view {
        None => None,
        Some(text) => {
            let v: Vec<f64> =
                text.split(',').map(|s| s.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| {
                    anyhow::anyhow!("--board-view {text:?}: expected YAW,PITCH,FOV in degrees, e.g. 0,-90,100")
                })?;
            let [yaw, pitch, fov] = <[f64; 3]>::try_from(v).map_err(|_| {
                anyhow::anyhow!("--board-view {text:?}: expected YAW,PITCH,FOV in degrees, e.g. 0,-90,100")
            })?;
            let (width, height) = parse_size(&a.view_size).context("--view-size")?;
            let spec = ViewSpec { yaw_deg: yaw, pitch_deg: pitch, fov_deg: fov, width, height };
            spec.camera().context("--board-view")?;
            let square_mm = a.square_mm.unwrap_or(f64::NAN);
            let board = BoardSpec::parse(a.board.as_deref().unwrap_or(""), square_mm)
                .map_err(|e| anyhow::anyhow!("--board/--square-mm: {e}"))?;
            Some((spec, board, square_mm))
        }
    };
    let map = super::read_env(&a.input)?;
    let (yaw, found, png) = match board_setup {
        None => (a.yaw.unwrap_or(0.0), None, None),
        Some((spec, board, square_mm)) => {
            let (view, cam) = env::perspective_view(&map, &spec)?;
            let gray = lucent_calib::GrayImage::from_linear_rgb(&view);
            let (corners, order) = lucent_calib::scene::find_board_corners(&gray, &board)?.ok_or_else(|| {
                anyhow::anyhow!(
                    "{}: no chessboard of {}x{} inner corners in the view --board-view {} (yaw {}°, pitch {}°, fov {}°); \
                     cut it with `lucent env view` to look, and aim the view at the board",
                    a.input.display(),
                    board.cols,
                    board.rows,
                    a.board_view.as_deref().unwrap_or(""),
                    spec.yaw_deg,
                    spec.pitch_deg,
                    spec.fov_deg
                )
            })?;
            let points = corners.points.clone();
            let pinhole = CameraModel {
                model: DistortionModel::PinholeK3,
                image_width: spec.width,
                image_height: spec.height,
                intrinsics: env::view_intrinsics(&cam),
                distortion: Distortion::default(),
            };
            let pose = cv::solve_pnp(&points, &board, &pinhole)?;
            let reprojected: Vec<[f64; 2]> =
                board.corners().iter().map(|p| pinhole.project(pose.to_camera(*p)).unwrap_or([f64::NAN; 2])).collect();
            let ss: f64 =
                points.iter().zip(&reprojected).map(|(d, r)| (d[0] - r[0]).powi(2) + (d[1] - r[1]).powi(2)).sum();
            let rms = (ss / points.len() as f64).sqrt();
            let in_map = env::board_in_map(&cam, &pose.rotation, pose.translation_m);
            if in_map.tilt_deg.is_nan() || in_map.tilt_deg > a.max_tilt_deg {
                bail!(
                    "{}: the board's normal is {:.1}° from the map's zenith (more than --max-tilt-deg {}): either the \
                     board is not the level one the scene stands on or the 360° camera was not level; a yaw cannot \
                     align them",
                    a.input.display(),
                    in_map.tilt_deg,
                    a.max_tilt_deg
                );
            }
            if order == env::CornerOrder::Ambiguous {
                eprintln!("warning: {}", crate::job::camera::ambiguous_board_warning(&board, "the yaw"));
            }
            let label = format!("board in view: PnP RMS {rms:.3} px, yaw {:.2} deg", in_map.yaw_deg);
            let png = cv::draw_view_png(&gray, &board, &points, &reprojected, &[], &label)?;
            let yaw = in_map.yaw_deg;
            let found = BoardFound {
                view: spec,
                board: format!("{}x{}", board.cols, board.rows),
                square_mm,
                detector: corners.detector.to_string(),
                corner_order: order,
                pnp_rms_px: rms,
                in_map,
            };
            (yaw, Some(found), Some(png))
        }
    };
    let turned = env::rotate_yaw(&map, yaw)?;
    let orientation = Orientation {
        convention: env::ORIENTATION_CONVENTION.into(),
        source: file_name(&a.input),
        source_yaw_deg: yaw,
        output: file_name(&a.out),
        output_yaw_deg: 0.0,
        method: if found.is_some() { "board" } else { "given" }.into(),
        board: found,
    };
    let json_path = sibling(&a.out, ".json");
    let png_path = sibling(&a.out, "_board.png");
    let json = json_bytes(&json_path, &orientation)?;
    let map = imageio::encode_exr(&a.out, &to_image(turned))?;
    let mut files: Vec<(&std::path::Path, &[u8])> = vec![(&json_path, &json), (&a.out, &map)];
    if let Some(png) = &png {
        files.insert(0, (&png_path, png));
    }
    crate::io::write_files_atomic(&files)?;
    match &orientation.board {
        Some(b) => println!(
            "board {} found in the view (yaw {}°, pitch {}°, fov {}°; {} detector, PnP RMS {:.3} px, corner order {:?}): \
             its i axis points {:.2}° from the map's +x, tilt {:.2}° from level, corner (0, 0) {:.3} m away; yaw {:.3}°",
            b.board,
            b.view.yaw_deg,
            b.view.pitch_deg,
            b.view.fov_deg,
            b.detector,
            b.pnp_rms_px,
            b.corner_order,
            -yaw,
            b.in_map.tilt_deg,
            b.in_map.corner00_distance_m,
            yaw
        ),
        None => println!("given yaw {yaw}°"),
    }
    println!(
        "{} turned by {yaw:.3}° → {} (render with yaw 0; or render {} with yaw_deg = {yaw:.3}); orientation {}{}",
        a.input.display(),
        a.out.display(),
        file_name(&a.input),
        json_path.display(),
        if png.is_some() { format!(", board view {}", png_path.display()) } else { String::new() }
    );
    Ok(())
}

/// `lucent env paste`: a picture or a chessboard put into a map as a view sees it (synthetic panoramas).
pub fn paste(a: EnvPasteArgs) -> Result<()> {
    if extension(&a.out) != "exr" {
        bail!("{}: the output must be an .exr file (32-bit float)", a.out.display());
    }
    let picture = match (&a.image, &a.chessboard) {
        (Some(p), _) => to_buffer(imageio::read_rgb(p)?),
        (None, Some(text)) => {
            let board = BoardSpec::parse(text, 1.0).map_err(|e| anyhow::anyhow!("--chessboard: {e}"))?;
            let v: Vec<f32> = text_numbers(&a.chessboard_values)
                .filter(|v: &Vec<f32>| v.len() == 2 && v.iter().all(|x| x.is_finite() && *x >= 0.0))
                .ok_or_else(|| anyhow::anyhow!("--chessboard-values {}: give DARK,LIGHT ≥ 0", a.chessboard_values))?;
            env::chessboard_picture(board.cols, board.rows, 40, v[0], v[1])
        }
        (None, None) => bail!("give --image or --chessboard"),
    };
    let spec =
        ViewSpec { yaw_deg: a.yaw, pitch_deg: a.pitch, fov_deg: a.fov, width: picture.width, height: picture.height };
    spec.camera()?;
    let mut map = super::read_env(&a.input)?;
    if let Some(w) = a.width {
        if w < 2 || !w.is_multiple_of(2) || w > 32768 {
            bail!("--width {w}: an even number of pixels, 2 to 32768");
        }
        let h = w / 2;
        let mut big = RgbBuffer::zeros(w, h);
        for y in 0..h {
            for x in 0..w {
                let p = env::sample_bilinear(&map, (x as f64 + 0.5) / w as f64, (y as f64 + 0.5) / h as f64);
                big.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&p);
            }
        }
        map = big;
    }
    let n = env::paste_view(&mut map, &picture, &spec)?;
    let (w, h) = (map.width, map.height);
    imageio::write_exr(&a.out, &to_image(map))?;
    println!(
        "pasted a {} × {} picture at yaw {}°, pitch {}°, fov {}° into {} ({w} × {h}, {n} map pixels) → {}",
        spec.width,
        spec.height,
        a.yaw,
        a.pitch,
        a.fov,
        a.input.display(),
        a.out.display()
    );
    Ok(())
}

fn text_numbers(text: &str) -> Option<Vec<f32>> {
    text.split(',').map(|s| s.trim().parse::<f32>().ok()).collect()
}

/// sRGB encoding (IEC 61966-2-1) of a linear value in [0, 1].
fn srgb_encode(v: f32) -> f32 {
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// The most brackets `lucent env brackets` writes (and `env merge` reads).
pub const MAX_BRACKETS: usize = 64;

/// `lucent env brackets`: 8-bit exposure brackets of an HDR image through the sRGB curve.
pub fn brackets(a: EnvBracketsArgs) -> Result<()> {
    let e = extension(&a.input);
    if e != "exr" && e != "hdr" {
        bail!("{}: the input must be .exr or .hdr", a.input.display());
    }
    let exposures: Vec<f64> = a
        .exposures
        .split(',')
        .map(|p| {
            parse_exposure(p).ok_or_else(|| {
                anyhow::anyhow!("--exposures {}: {p:?} is not a positive number or fraction", a.exposures)
            })
        })
        .collect::<Result<_>>()?;
    if exposures.len() > MAX_BRACKETS {
        bail!("--exposures: {} brackets, at most {MAX_BRACKETS}", exposures.len());
    }
    let img = imageio::read_rgb(&a.input)?;
    // All brackets or none: written into a staging folder moved in whole;
    // Ctrl-C or SIGTERM removes it (and the folder, if this run made it).
    let _interrupt = crate::interrupt::Interrupt::abort_on_first();
    let _remove_on_abort = crate::interrupt::remove_staged_on_abort(&a.out_dir);
    let stage = crate::io::StagedDir::new(&a.out_dir)?;
    let mut names = Vec::new();
    for (k, t) in exposures.iter().enumerate() {
        let bytes: Vec<u8> =
            img.data.iter().map(|v| (srgb_encode((v.max(0.0) * *t as f32).min(1.0)) * 255.0).round() as u8).collect();
        let buf = image::RgbImage::from_raw(img.width as u32, img.height as u32, bytes)
            .ok_or_else(|| anyhow::anyhow!("{}: image size", a.input.display()))?;
        let mut out = std::io::Cursor::new(Vec::new());
        buf.write_to(&mut out, image::ImageFormat::Png).context("encode PNG")?;
        let name = format!("bracket_{}.png", k + 1);
        crate::io::write_atomic(&stage.path().join(&name), &out.into_inner())?;
        names.push(name);
    }
    write_json(
        &stage.path().join("brackets.json"),
        &serde_json::json!({
            "source": file_name(&a.input),
            "brackets": names,
            "exposures": exposures,
            "response": "8-bit sRGB transfer curve (IEC 61966-2-1) of min(value × exposure, 1), rounded",
        }),
    )?;
    stage.commit(|n| n == "brackets.json" || (n.starts_with("bracket_") && n.ends_with(".png")))?;
    println!(
        "{} brackets of {} (exposures {}) → {}/bracket_1.png … ; merge with: lucent env merge {}/bracket_*.png --exposures {}",
        exposures.len(),
        a.input.display(),
        a.exposures,
        a.out_dir.display(),
        a.out_dir.display(),
        a.exposures
    );
    Ok(())
}
