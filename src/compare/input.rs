//! Reading a photo or render for comparison, with the checks a comparison
//! needs and `imageio::read_rgb` does not report: how many colour channels
//! the file holds (so a grey image is not silently compared with an RGB
//! one), and where the first NaN or infinite value is.
//!
//! * OpenEXR: every channel is read (16/32-bit float, 32-bit uint). Colour
//!   channels are `R`, `G`, `B` (RGB) or `Y` alone (grey, copied into R, G
//!   and B); a layer prefix (`beauty.R`) is allowed; alpha and other
//!   channels are ignored.
//! * PNG, TIFF, Radiance HDR: decoded by `image`; grey (with or without
//!   alpha) counts as 1 channel, colour as 3. 8/16-bit values are scaled to
//!   [0, 1] as stored — no transfer function is removed, so compare linear
//!   images (EXR) for meaningful numbers.
//!
//! ```
//! use lucent::compare::input::read_image;
//! use lucent::imageio::{write_exr, RgbImage};
//! let dir = std::env::temp_dir().join("lucent-doc-compare-input");
//! let mut img = RgbImage::new(3, 2, vec![0.5; 18]).unwrap();
//! img.data[3 * 4 + 1] = f32::NAN; // pixel (1, 1), channel G
//! write_exr(&dir.join("nan.exr"), &img).unwrap();
//! let e = read_image(&dir.join("nan.exr"), "render").unwrap_err().to_string();
//! assert!(e.contains("render") && e.contains("(1, 1)") && e.contains("G"), "{e}");
//! ```

use super::error::{CompareError, ReadProblem};
use crate::imageio::{extension, RgbImage};
use std::path::Path;

/// An image and the colour channels it was read from.
#[derive(Debug, Clone, PartialEq)]
pub struct Loaded {
    pub image: RgbImage,
    /// `["R", "G", "B"]` or `["Y"]` (EXR), `["R", "G", "B"]` or `["L"]` (others).
    pub channels: Vec<String>,
}

/// Reads `path` as the `role` image ("photo", "render"); errors name both.
pub fn read_image(path: &Path, role: &'static str) -> Result<Loaded, CompareError> {
    let err = |reason: ReadProblem| CompareError::Read { role, path: path.to_path_buf(), reason };
    if !path.exists() {
        return Err(err(ReadProblem::Missing));
    }
    if path.is_dir() {
        return Err(err(ReadProblem::Folder));
    }
    let loaded = match extension(path).as_str() {
        "exr" => read_exr(path).map_err(err)?,
        "png" | "tif" | "tiff" | "hdr" => read_other(path).map_err(err)?,
        other => return Err(err(ReadProblem::Format(other.to_string()))),
    };
    check_finite(&loaded, path, role)?;
    // A linear image of a lit scene has light in it: a black image, or one
    // negative on the whole (a sign flipped, a wrong offset), has no
    // meaningful RMSE or SSIM against another (a few small negative values
    // of a colour-corrected photo are kept).
    let sum: f64 = loaded.image.data.iter().map(|&v| f64::from(v)).sum();
    if sum.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return Err(CompareError::NoLight { role, path: path.to_path_buf(), sum });
    }
    Ok(loaded)
}

fn read_exr(path: &Path) -> Result<Loaded, ReadProblem> {
    let layer = crate::exr::read_layer(path).map_err(|e| ReadProblem::Exr(Box::new(e.problem)))?;
    let (w, h) = (layer.width, layer.height);
    let find = |want: &str| {
        layer.channels.iter().position(|c| {
            let n = &c.name;
            n == want || n.rsplit_once('.').is_some_and(|(_, last)| last == want)
        })
    };
    let planes: Vec<(&str, usize)> = match (find("R"), find("G"), find("B"), find("Y")) {
        (Some(r), Some(g), Some(b), _) => vec![("R", r), ("G", g), ("B", b)],
        (None, None, None, Some(y)) => vec![("Y", y)],
        _ => return Err(ReadProblem::NoColourChannels(layer.names())),
    };
    let mut data = vec![0f32; w * h * 3];
    for (k, (name, index)) in planes.iter().enumerate() {
        let values = &layer.channels[*index].values;
        if values.len() != w * h {
            return Err(ReadProblem::Subsampled { name, got: values.len(), width: w, height: h });
        }
        let targets: &[usize] = if planes.len() == 1 { &[0, 1, 2] } else { std::slice::from_ref(&k) };
        for &t in targets {
            for (px, v) in data.chunks_exact_mut(3).zip(values) {
                px[t] = *v;
            }
        }
    }
    let image = RgbImage::new(w, h, data)?;
    Ok(Loaded { image, channels: planes.iter().map(|(n, _)| n.to_string()).collect() })
}

fn read_other(path: &Path) -> Result<Loaded, ReadProblem> {
    let img = image::ImageReader::open(path)?.with_guessed_format()?.decode()?;
    let grey = !img.color().has_color();
    let rgb = img.into_rgb32f();
    let (w, h) = rgb.dimensions();
    let image = RgbImage::new(w as usize, h as usize, rgb.into_raw())?;
    let channels = if grey { vec!["L".to_string()] } else { ["R", "G", "B"].map(String::from).to_vec() };
    Ok(Loaded { image, channels })
}

fn check_finite(loaded: &Loaded, path: &Path, role: &'static str) -> Result<(), CompareError> {
    let data = &loaded.image.data;
    let Some(first) = data.iter().position(|v| !v.is_finite()) else {
        return Ok(());
    };
    let count = data.iter().filter(|v| !v.is_finite()).count();
    let pixel = first / 3;
    let channel =
        if loaded.channels.len() == 1 { loaded.channels[0].clone() } else { ["R", "G", "B"][first % 3].to_string() };
    let v = data[first];
    let value = if v.is_nan() {
        "NaN"
    } else if v > 0.0 {
        "+inf"
    } else {
        "-inf"
    };
    // A grey image repeats each value three times.
    let count = if loaded.channels.len() == 1 { count / 3 } else { count };
    Err(CompareError::NonFinite {
        role,
        path: path.to_path_buf(),
        x: pixel % loaded.image.width,
        y: pixel / loaded.image.width,
        channel,
        value,
        count,
    })
}
