//! Linear images on disk: OpenEXR (32-bit float, read 16/32-bit, through
//! [`crate::exr`], which owns the EXR format), Radiance
//! `.hdr`, 16/8-bit PNG and TIFF (values scaled to [0, 1], no transfer
//! function removed), and 8-bit sRGB PNG for looking at. Every write is
//! atomic (temporary file, then rename); every read checks what it got: a
//! truncated or corrupt file is an error naming it, never a padded image.
//!
//! ```
//! use lucent::imageio::{RgbImage, write_exr, read_rgb};
//! let dir = std::env::temp_dir().join("lucent-doc-imageio");
//! let img = RgbImage::new(4, 2, vec![0.25; 24]).unwrap();
//! write_exr(&dir.join("a.exr"), &img).unwrap();
//! assert_eq!(read_rgb(&dir.join("a.exr")).unwrap(), img);
//! ```

use crate::io::{write_atomic, WriteError};
use std::path::{Path, PathBuf};

/// An image that could not be read or written.
#[derive(Debug, thiserror::Error)]
pub enum ImageIoError {
    #[error("{path}: cannot read image: {reason}")]
    Read { path: PathBuf, reason: String },
    #[error("{path}: unsupported image format (expected .exr, .hdr, .png, .tif, .tiff or a camera RAW such as .dng, .cr2, .nef)")]
    Format { path: PathBuf },
    #[error(transparent)]
    Write(#[from] WriteError),
    /// A camera RAW file that could not be decoded (the message names the file).
    #[error(transparent)]
    Raw(#[from] lucent_calib::raw::RawError),
    #[error("{path}: cannot encode image: {reason}")]
    Encode { path: PathBuf, reason: String },
    /// An EXR that could not be read (the message names the file; boxed,
    /// as every variant here stays small).
    #[error(transparent)]
    ExrRead(Box<crate::exr::ExrReadError>),
    /// An EXR that could not be written (the message names the file).
    #[error(transparent)]
    ExrWrite(Box<crate::exr::ExrWriteError>),
    #[error("image data has {got} values, expected {expected} for {width} × {height} × {channels}")]
    Size { got: usize, expected: usize, width: usize, height: usize, channels: usize },
    /// Binning by `factor` needs both sides divisible by it.
    #[error(
        "a {width} × {height} image cannot be binned {factor} × {factor}: both sides must be multiples of {factor}"
    )]
    Bin { width: usize, height: usize, factor: usize },
}

impl From<crate::exr::ExrReadError> for ImageIoError {
    fn from(e: crate::exr::ExrReadError) -> Self {
        ImageIoError::ExrRead(Box::new(e))
    }
}

impl From<crate::exr::ExrWriteError> for ImageIoError {
    fn from(e: crate::exr::ExrWriteError) -> Self {
        ImageIoError::ExrWrite(Box::new(e))
    }
}

/// A linear RGB image, interleaved, row-major, top row first.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

impl RgbImage {
    /// An image of `width` × `height` RGB pixels from interleaved data.
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Result<Self, ImageIoError> {
        let expected = width * height * 3;
        if data.len() != expected || width == 0 || height == 0 {
            return Err(ImageIoError::Size { got: data.len(), expected, width, height, channels: 3 });
        }
        Ok(Self { width, height, data })
    }

    /// The image binned `factor` × `factor`: each output pixel the mean of
    /// a square of input pixels (a box filter, as a camera pixel `factor`
    /// times larger would record, and as the renderer's pixels integrate).
    ///
    /// ```
    /// use lucent::imageio::RgbImage;
    /// let img = RgbImage::new(2, 2, vec![1.0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0]).unwrap();
    /// assert_eq!(img.binned(2).unwrap().data, vec![1.0, 0.0, 1.0]);
    /// ```
    pub fn binned(&self, factor: usize) -> Result<RgbImage, ImageIoError> {
        let data = bin_interleaved(&self.data, self.width, self.height, 3, factor)?;
        RgbImage::new(self.width / factor, self.height / factor, data)
    }

    /// The RGB value at column `x`, row `y`.
    pub fn pixel(&self, x: usize, y: usize) -> [f32; 3] {
        let i = 3 * (y * self.width + x);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
}

/// Whether a `width` × `height` image can be binned `factor` × `factor`
/// (both sides multiples of a factor ≥ 1).
pub fn check_bin(width: usize, height: usize, factor: usize) -> Result<(), ImageIoError> {
    if factor == 0 || !width.is_multiple_of(factor) || !height.is_multiple_of(factor) {
        return Err(ImageIoError::Bin { width, height, factor });
    }
    Ok(())
}

/// `data` (`channels` interleaved values per pixel, `width` × `height`,
/// row-major) binned `factor` × `factor` by the mean (in f64).
pub fn bin_interleaved(
    data: &[f32],
    width: usize,
    height: usize,
    channels: usize,
    factor: usize,
) -> Result<Vec<f32>, ImageIoError> {
    check_bin(width, height, factor)?;
    let expected = width * height * channels;
    if data.len() != expected {
        return Err(ImageIoError::Size { got: data.len(), expected, width, height, channels });
    }
    let (w, h) = (width / factor, height / factor);
    let mut sum = vec![0f64; w * h * channels];
    for y in 0..height {
        let row = &mut sum[(y / factor) * w * channels..(y / factor + 1) * w * channels];
        for x in 0..width {
            let (o, i) = ((x / factor) * channels, (y * width + x) * channels);
            for c in 0..channels {
                row[o + c] += f64::from(data[i + c]);
            }
        }
    }
    let n = (factor * factor) as f64;
    Ok(sum.iter().map(|s| (s / n) as f32).collect())
}

/// The file extension in lower case ("" without one).
pub fn extension(path: &Path) -> String {
    path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default()
}

/// Reads a linear RGB image; the format follows the file extension.
pub fn read_rgb(path: &Path) -> Result<RgbImage, ImageIoError> {
    let read_err = |reason: String| ImageIoError::Read { path: path.to_path_buf(), reason };
    if !path.exists() {
        return Err(read_err("no such file".into()));
    }
    match extension(path).as_str() {
        "exr" => read_exr(path),
        "hdr" | "png" | "tif" | "tiff" => {
            let img = image::ImageReader::open(path)
                .map_err(|e| read_err(e.to_string()))?
                .with_guessed_format()
                .map_err(|e| read_err(e.to_string()))?
                .decode()
                .map_err(|e| read_err(e.to_string()))?;
            let rgb = img.into_rgb32f();
            let (w, h) = rgb.dimensions();
            let out = RgbImage::new(w as usize, h as usize, rgb.into_raw()).map_err(|e| read_err(e.to_string()))?;
            if out.data.iter().any(|v| !v.is_finite()) {
                return Err(read_err("contains NaN or infinite values".into()));
            }
            Ok(out)
        }
        "jpg" | "jpeg" => {
            // 8-bit values as stored, /255 (as PNG); OpenCV's decoder, which
            // refuses a truncated file instead of filling it with grey.
            let rgb = lucent_calib::cv::read_rgb8(path).map_err(|e| match e {
                lucent_calib::cv::CalibError::Image { reason, .. } => read_err(reason),
                other => read_err(other.to_string()),
            })?;
            RgbImage::new(rgb.width, rgb.height, rgb.data).map_err(|e| read_err(e.to_string()))
        }
        e if RAW_EXTENSIONS.contains(&e) => {
            // Linear camera RGB relative to the white level (no white balance,
            // Malvar–He–Cutler demosaicing, orientation applied), as `lucent raw decode`.
            let (rgb, _) = lucent_calib::raw::decode_raw(path, &lucent_calib::raw::RawOptions::default())?;
            RgbImage::new(rgb.width, rgb.height, rgb.data).map_err(|e| read_err(e.to_string()))
        }
        _ => Err(ImageIoError::Format { path: path.to_path_buf() }),
    }
}

/// The width and height of an image [`read_rgb`] reads, from its header
/// only: EXR, HDR, PNG, TIFF; JPEG with its EXIF orientation applied
/// ([`lucent_calib::jpeg`]); RAW as developed ([`lucent_calib::raw::developed_size`]).
pub fn image_size(path: &Path) -> Result<(usize, usize), ImageIoError> {
    let read_err = |reason: String| ImageIoError::Read { path: path.to_path_buf(), reason };
    match extension(path).as_str() {
        "exr" => Ok(crate::exr::image_size(path)?),
        "hdr" | "png" | "tif" | "tiff" => {
            let (w, h) = image::ImageReader::open(path)
                .map_err(|e| read_err(e.to_string()))?
                .with_guessed_format()
                .map_err(|e| read_err(e.to_string()))?
                .into_dimensions()
                .map_err(|e| read_err(e.to_string()))?;
            Ok((w as usize, h as usize))
        }
        "jpg" | "jpeg" => lucent_calib::jpeg::jpeg_size(path).map_err(|e| read_err(e.reason)),
        e if RAW_EXTENSIONS.contains(&e) => Ok(lucent_calib::raw::developed_size(path)?),
        _ => Err(ImageIoError::Format { path: path.to_path_buf() }),
    }
}

/// File extensions read as camera RAW (decoded by `lucent_calib::raw`).
pub const RAW_EXTENSIONS: [&str; 14] =
    ["dng", "cr2", "nef", "nrw", "arw", "srf", "sr2", "orf", "rw2", "raf", "pef", "srw", "erf", "3fr"];

fn read_exr(path: &Path) -> Result<RgbImage, ImageIoError> {
    let (w, h, data) = crate::exr::read_rgb(path)?;
    let read_err = |reason: String| ImageIoError::Read { path: path.to_path_buf(), reason };
    let out = RgbImage::new(w, h, data).map_err(|e| read_err(e.to_string()))?;
    if out.data.iter().any(|v| !v.is_finite()) {
        return Err(read_err("contains NaN or infinite values".into()));
    }
    Ok(out)
}

/// Writes a linear RGB image as a 32-bit float EXR, atomically.
pub fn write_exr(path: &Path, img: &RgbImage) -> Result<(), ImageIoError> {
    Ok(write_atomic(path, &encode_exr(path, img)?)?)
}

/// The bytes [`write_exr`] writes (`path` only names the file in an error).
pub fn encode_exr(path: &Path, img: &RgbImage) -> Result<Vec<u8>, ImageIoError> {
    Ok(crate::exr::encode_rgb(path, img.width, img.height, &img.data)?)
}

/// The sRGB transfer function (IEC 61966-2-1) of a linear value in [0, 1].
pub fn srgb_encode(linear: f32) -> f32 {
    let v = linear.clamp(0.0, 1.0);
    if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    }
}

/// Writes a linear RGB image as an 8-bit sRGB PNG for display (values
/// clipped to [0, 1]), atomically.
pub fn write_png(path: &Path, img: &RgbImage) -> Result<(), ImageIoError> {
    Ok(write_atomic(path, &encode_png(path, img)?)?)
}

/// The bytes [`write_png`] writes (`path` only names the file in an error).
pub fn encode_png(path: &Path, img: &RgbImage) -> Result<Vec<u8>, ImageIoError> {
    let bytes: Vec<u8> = img.data.iter().map(|v| (srgb_encode(*v) * 255.0 + 0.5) as u8).collect();
    let buf = image::RgbImage::from_raw(img.width as u32, img.height as u32, bytes).ok_or(ImageIoError::Size {
        got: img.data.len(),
        expected: img.width * img.height * 3,
        width: img.width,
        height: img.height,
        channels: 3,
    })?;
    let mut out = std::io::Cursor::new(Vec::new());
    buf.write_to(&mut out, image::ImageFormat::Png)
        .map_err(|e| ImageIoError::Encode { path: path.to_path_buf(), reason: e.to_string() })?;
    Ok(out.into_inner())
}

/// One channel of a floating-point TIFF (32- or 64-bit samples; of several
/// channels the first) as f64, row-major: a measured slice or map. Integer
/// TIFFs are refused: 8- or 16-bit counts carry no physical scale, and
/// scaling them to [0, 1] would silently change the result by the camera's
/// gain.
pub fn read_float_tiff(path: &Path) -> Result<(usize, usize, Vec<f64>), ImageIoError> {
    use tiff::decoder::{Decoder, DecodingResult};
    let read_err = |reason: String| ImageIoError::Read { path: path.to_path_buf(), reason };
    let file = std::fs::File::open(path).map_err(|e| read_err(e.to_string()))?;
    let mut dec = Decoder::new(std::io::BufReader::new(file)).map_err(|e| read_err(format!("not a TIFF: {e}")))?;
    let (w, h) = dec.dimensions().map_err(|e| read_err(e.to_string()))?;
    let colour = dec.colortype().map_err(|e| read_err(e.to_string()))?;
    let channels = match colour {
        tiff::ColorType::Gray(_) => 1,
        tiff::ColorType::GrayA(_) => 2,
        tiff::ColorType::RGB(_) => 3,
        tiff::ColorType::RGBA(_) => 4,
        other => return Err(read_err(format!("unsupported TIFF colour type {other:?}"))),
    };
    let integer = |bits: u32| {
        read_err(format!(
            "{bits}-bit integer samples have no physical scale; save the slice as 32-bit float TIFF, EXR or CSV"
        ))
    };
    let values: Vec<f64> = match dec.read_image().map_err(|e| read_err(e.to_string()))? {
        DecodingResult::F32(v) => v.into_iter().step_by(channels).map(f64::from).collect(),
        DecodingResult::F64(v) => v.into_iter().step_by(channels).collect(),
        DecodingResult::F16(v) => v.into_iter().step_by(channels).map(|x| f64::from(f32::from(x))).collect(),
        DecodingResult::U8(_) | DecodingResult::I8(_) => return Err(integer(8)),
        DecodingResult::U16(_) | DecodingResult::I16(_) => return Err(integer(16)),
        DecodingResult::U32(_) | DecodingResult::I32(_) => return Err(integer(32)),
        _ => return Err(integer(64)),
    };
    let (w, h) = (w as usize, h as usize);
    if values.len() != w * h {
        return Err(read_err(format!("{} samples for {w} × {h} pixels", values.len())));
    }
    Ok((w, h, values))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp(w: usize, h: usize) -> RgbImage {
        RgbImage::new(w, h, (0..w * h * 3).map(|i| i as f32 * 0.37 - 3.0).collect()).unwrap()
    }

    #[test]
    fn exr_round_trip_is_exact() {
        let dir = tempfile::tempdir().unwrap();
        let img = ramp(7, 5);
        let p = dir.path().join("x.exr");
        write_exr(&p, &img).unwrap();
        assert_eq!(read_rgb(&p).unwrap(), img);
    }

    #[test]
    fn truncated_exr_is_an_error() {
        let dir = tempfile::tempdir().unwrap();
        let img = ramp(64, 64);
        let p = dir.path().join("x.exr");
        write_exr(&p, &img).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let cut = dir.path().join("cut.exr");
        std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
        let e = read_rgb(&cut).unwrap_err().to_string();
        assert!(e.contains("cut.exr"), "{e}");
    }

    #[test]
    fn nan_and_unknown_formats_are_errors() {
        let dir = tempfile::tempdir().unwrap();
        let mut img = ramp(3, 3);
        img.data[4] = f32::NAN;
        let p = dir.path().join("nan.exr");
        write_exr(&p, &img).unwrap();
        assert!(read_rgb(&p).unwrap_err().to_string().contains("NaN"));
        assert!(matches!(read_rgb(&dir.path().join("x.bmp")), Err(ImageIoError::Read { .. })));
        std::fs::write(dir.path().join("x.bmp"), b"BM").unwrap();
        assert!(matches!(read_rgb(&dir.path().join("x.bmp")), Err(ImageIoError::Format { .. })));
        assert!(RgbImage::new(2, 2, vec![0.0; 11]).is_err());
    }

    #[test]
    fn png_is_srgb_encoded() {
        let dir = tempfile::tempdir().unwrap();
        let img = RgbImage::new(2, 1, vec![0.0, 0.5, 1.0, 0.2140411, 2.0, -1.0]).unwrap();
        let p = dir.path().join("x.png");
        write_png(&p, &img).unwrap();
        let back = read_rgb(&p).unwrap();
        let expect = [0.0, 188.0, 255.0, 128.0, 255.0, 0.0];
        for (b, e) in back.data.iter().zip(expect) {
            assert!((b * 255.0 - e).abs() <= 1.0, "{b} vs {e}");
        }
    }
}
