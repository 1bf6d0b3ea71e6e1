//! `lucent env merge` (HDR from exposure brackets) and `lucent env orient`
//! (the map turned to the board's world, from a given yaw or the board
//! found in a view): their flags become an [`EnvMergeJob`] and an
//! [`EnvOrientJob`], whose `run` does the work and writes the files
//! ([`crate::job::EnvMergeFiles`], [`crate::job::EnvOrientFiles`]); this
//! module parses the flags and prints the job's summary. `lucent env view`
//! (a perspective view cut from an equirectangular map, a viewer), `env
//! paste` and `env brackets` (synthetic panoramas and brackets) work here,
//! with `lucent_calib::env`.

use crate::cli::choices::named;
use crate::imageio::{self, extension};
use crate::io::{json_bytes, write_json};
use crate::job::camera::{file_name, to_buffer, to_image};
use crate::job::{read_env_map, Context as JobContext, EnvMergeJob, EnvOrientJob, Exposures, ImageSize, ViewAngles};
use anyhow::{bail, Context, Result};
use clap::{ArgGroup, Args};
use lucent_calib::board::BoardSize;
use lucent_calib::env::{self, ViewSpec};
use lucent_calib::hdr::ResponseMethod;
use lucent_calib::scene::{sibling, BoardSpec};
use lucent_calib::RgbBuffer;
use std::path::PathBuf;

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
    pub exposures: Option<Exposures>,
    /// Output HDR (.exr, 32-bit float); the report goes to NAME.json and the mask of pixels saturated
    /// in every bracket to NAME_saturated.png.
    #[arg(long)]
    pub out: PathBuf,
    /// Camera-response recovery for 8-bit brackets: debevec (Debevec & Malik 1997) or robertson
    /// (Robertson et al. 2003).
    #[arg(long, value_parser = named::<ResponseMethod>(), default_value = "debevec")]
    pub method: ResponseMethod,
    /// Linear brackets: a pixel whose largest channel reaches this is saturated (RAW white = 1).
    #[arg(long, default_value_t = crate::job::env_merge::defaults::SATURATION)]
    pub saturation: f32,
    /// Linear brackets: values below this are noise (weights rise from here to twice it).
    #[arg(long, default_value_t = crate::job::env_merge::defaults::NOISE_FLOOR)]
    pub noise_floor: f32,
    /// 8-bit brackets: codes at or above this are saturated.
    #[arg(long, default_value_t = crate::job::env_merge::defaults::SATURATION_CODE)]
    pub saturation_code: u8,
    /// 8-bit brackets: codes at or below this are noise.
    #[arg(long, default_value_t = crate::job::env_merge::defaults::FLOOR_CODE)]
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
    pub board_view: Option<ViewAngles>,
    /// Inner corners COLSxROWS of the board (its i axis becomes the world's +x). Corner (0, 0) is numbered
    /// as `lucent pose` numbers it: the one diagonally beyond the light outer corner square (OpenCV's
    /// numbering); only a board with one odd and one even count (e.g. 9x6) fixes it.
    #[arg(long)]
    pub board: Option<BoardSize>,
    /// Side of one square in millimetres.
    #[arg(long)]
    pub square_mm: Option<f64>,
    /// Size of the board view, WIDTHxHEIGHT pixels.
    #[arg(long, default_value = "1600x1200")]
    pub view_size: ImageSize,
    /// Refuse a board whose normal is further than this from the map's zenith (degrees): a yaw cannot
    /// level a tilted map.
    #[arg(long, default_value_t = crate::job::env_orient::DEFAULT_MAX_TILT_DEG)]
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
    #[arg(long, value_parser = crate::cli::common::count_in::<2, 32_768>)]
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

/// Runs `lucent env merge`: the job of the flags ([`EnvMergeJob::run`]),
/// then its summary on stdout.
pub fn merge(a: EnvMergeArgs) -> Result<()> {
    let done = EnvMergeJob::from(&a).run(&JobContext::default())?;
    for line in done.summary() {
        println!("{line}");
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
    let map = read_env_map(&a.input)?;
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

/// Runs `lucent env orient`: the job of the flags ([`EnvOrientJob::run`]),
/// then its summary on stdout.
pub fn orient(a: EnvOrientArgs) -> Result<()> {
    let done = EnvOrientJob::from(&a).run(&JobContext::default())?;
    for line in done.summary() {
        println!("{line}");
    }
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
    let mut map = read_env_map(&a.input)?;
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
            crate::job::env_merge::parse_exposure(p).map(|(_, v)| v).ok_or_else(|| {
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
