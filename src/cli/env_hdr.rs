//! `lucent env merge` (HDR from exposure brackets) and `lucent env view`
//! (a perspective view cut from an equirectangular map): file handling
//! only; the merge is `lucent_calib::hdr`, the view `lucent_calib::env`.

use super::{file_name, sibling, to_buffer, to_image, RAW_EXTENSIONS};
use crate::imageio::{self, RgbImage};
use crate::io::write_json;
use anyhow::{bail, Context, Result};
use clap::Args;
use lucent_calib::env::{self, ViewSpec};
use lucent_calib::hdr::{self, CodeWeights, LinearWeights, Merged, ResponseMethod, Rgb8Buffer};
use lucent_calib::raw::{self, RawOptions};
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
    #[arg(long, default_value = "debevec")]
    pub method: String,
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

fn extension(path: &Path) -> String {
    path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default()
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
    let method = ResponseMethod::from_name(&a.method).context("--method")?;
    let mut linear = Vec::new();
    let mut eight = Vec::new();
    let mut meta_exposures = Vec::new();
    for p in &a.brackets {
        match read_bracket(p).with_context(|| format!("bracket {}", p.display()))? {
            Bracket::Linear(img, t) => {
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
    imageio::write_png(&mask_path, &mask)?;
    write_json(&json_path, &json)?;
    imageio::write_exr(&a.out, &to_image(merged.image))?;
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
    write_json(&json_path, &serde_json::json!({ "source": file_name(&a.input), "camera": cam }))?;
    if ext == "exr" {
        imageio::write_exr(&a.out, &img)?;
    } else {
        imageio::write_png(&a.out, &img)?;
    }
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
