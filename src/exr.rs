//! OpenEXR files: the one module that reads and writes them, through the
//! `exr` crate (`imageio` reads and writes RGB images as EXR through it).
//!
//! * Writing: named 32-bit float channels of one layer, zip-compressed
//!   (`SMALL_LOSSLESS`), channels sorted by name as the format requires;
//!   [`write_channels`] writes atomically, [`encode_channels`] gives the
//!   bytes for a caller that writes several files together. Channel names
//!   are what lucent's outputs hold: `R`, `G`, `B` (linear RGB), the
//!   render's per-pixel variance `variance.R/G/B`, its half renders
//!   `half_a.*`/`half_b.*`, `spp`, `object`, a slice's `Y` and `std_error`.
//! * Reading: [`read_layer`] reads every channel of the first layer
//!   (16/32-bit float or 32-bit unsigned integer samples, as `f32`);
//!   [`read_channels`] the named ones; [`read_rgb`] the R, G, B of the
//!   first layer that has them (alpha ignored, interleaved).
//! * Header only: [`image_size`] (of the layer [`read_rgb`] reads) and
//!   [`channel_names`], without decoding pixels.
//!
//! Every read first checks the header: a layer claiming more than
//! [`MAX_PIXELS`] pixels is refused before any pixel buffer is allocated.
//! Values are returned as stored (no unit conversion, no clamping); pixel
//! planes are row-major from the top row. Every error names the file.
//!
//! ```
//! let dir = std::env::temp_dir().join("lucent-doc-exr");
//! let path = dir.join("y.exr");
//! lucent::exr::write_channels(&path, 2, 1, &[("Y", &[0.5, 2.0])]).unwrap();
//! let (w, h, planes) = lucent::exr::read_channels(&path, &["Y"]).unwrap();
//! assert_eq!((w, h, planes), (2, 1, vec![vec![0.5, 2.0]]));
//! let e = lucent::exr::read_channels(&path, &["R"]).unwrap_err().to_string();
//! assert!(e.contains("y.exr") && e.contains("no channel \"R\""), "{e}");
//! ```

use crate::io::{write_atomic, WriteError};
use std::path::{Path, PathBuf};

/// Largest EXR layer read, in pixels: 2²⁷ (a 16384 × 8192 panorama). A
/// header is checked against it before any pixel buffer is allocated, so a
/// small damaged or hostile file that claims a huge size (a 5 kB file asking
/// for 34 GB, found by `fuzz/`) is an error naming it, not an abort.
pub const MAX_PIXELS: usize = 1 << 27;

/// What is wrong with an EXR file (without its path: [`ExrReadError`]
/// names it, or a caller that names the file itself wraps this).
#[derive(Debug, thiserror::Error)]
pub enum ExrProblem {
    /// The `exr` crate could not decode the header or the pixels.
    #[error("{}", reason(.0))]
    Decode(::exr::error::Error),
    #[error(
        "the header claims a {width} × {height} image, more than the {MAX_PIXELS} pixels lucent reads (damaged file?)"
    )]
    TooLarge { width: usize, height: usize },
    #[error("no layer")]
    NoLayer,
    #[error("no channel {name:?} (channels: {})", present.join(", "))]
    MissingChannel { name: String, present: Vec<String> },
    /// A channel with fewer samples than pixels (subsampled).
    #[error("channel {name:?} has {got} samples, expected {expected}")]
    Subsampled { name: String, got: usize, expected: usize },
}

/// An EXR file that could not be read.
#[derive(Debug, thiserror::Error)]
#[error("{}: cannot read EXR: {problem}", path.display())]
pub struct ExrReadError {
    pub path: PathBuf,
    pub problem: ExrProblem,
}

/// An EXR file that could not be written; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum ExrWriteError {
    #[error("{}: channel {name:?} has {got} values, expected {expected} for {width} × {height} pixels", path.display())]
    ChannelLength { path: PathBuf, name: String, got: usize, expected: usize, width: usize, height: usize },
    #[error("{}: cannot encode image: {reason}", path.display())]
    Encode { path: PathBuf, reason: String },
    #[error(transparent)]
    Write(#[from] WriteError),
}

/// The exr crate's error in words a user can act on ("invalid: reference to
/// missing bytes" is what an empty or cut-off file gives).
fn reason(e: &::exr::error::Error) -> String {
    let text = e.to_string();
    if text.contains("missing bytes")
        || matches!(e, ::exr::error::Error::Io(io) if io.kind() == std::io::ErrorKind::UnexpectedEof)
    {
        format!("the EXR file is empty or cut short ({text})")
    } else {
        text
    }
}

fn read_error(path: &Path) -> impl Fn(ExrProblem) -> ExrReadError + '_ {
    move |problem| ExrReadError { path: path.to_path_buf(), problem }
}

/// The headers of `path`, every layer checked against [`MAX_PIXELS`].
fn headers(path: &Path) -> Result<::exr::meta::MetaData, ExrReadError> {
    let err = read_error(path);
    let meta = ::exr::meta::MetaData::read_from_file(path, false).map_err(|e| err(ExrProblem::Decode(e)))?;
    for header in meta.headers.iter() {
        let (width, height) = (header.layer_size.width(), header.layer_size.height());
        if width.checked_mul(height).is_none_or(|n| n > MAX_PIXELS) {
            return Err(err(ExrProblem::TooLarge { width, height }));
        }
    }
    Ok(meta)
}

/// Whether a header's layer has R, G and B channels (any case), as
/// [`read_rgb`] requires.
fn has_rgb(header: &::exr::meta::header::Header) -> bool {
    ["R", "G", "B"].iter().all(|c| header.channels.list.iter().any(|ch| ch.name.eq_case_insensitive(c)))
}

/// Width and height of the layer [`read_rgb`] reads (the first with R, G
/// and B channels, else the first), from the header only.
pub fn image_size(path: &Path) -> Result<(usize, usize), ExrReadError> {
    let meta = headers(path)?;
    let h = meta.headers.iter().find(|h| has_rgb(h)).or(meta.headers.first());
    let h = h.ok_or_else(|| read_error(path)(ExrProblem::NoLayer))?;
    Ok((h.layer_size.width(), h.layer_size.height()))
}

/// The channel names of every layer, from the header only (in file order:
/// sorted by name within a layer).
pub fn channel_names(path: &Path) -> Result<Vec<String>, ExrReadError> {
    let meta = headers(path)?;
    Ok(meta.headers.iter().flat_map(|h| h.channels.list.iter().map(|c| c.name.to_string())).collect())
}

/// One channel of a layer: its name and one sample per pixel (a
/// subsampled channel has fewer; [`Layer::plane`] refuses it).
#[derive(Debug, Clone, PartialEq)]
pub struct Channel {
    pub name: String,
    pub values: Vec<f32>,
}

/// The first layer of an EXR file, every channel as `f32`.
#[derive(Debug, Clone, PartialEq)]
pub struct Layer {
    /// The file it was read from (named in errors).
    pub path: PathBuf,
    pub width: usize,
    pub height: usize,
    /// In file order (sorted by name).
    pub channels: Vec<Channel>,
}

impl Layer {
    /// The channel names, in file order.
    pub fn names(&self) -> Vec<String> {
        self.channels.iter().map(|c| c.name.clone()).collect()
    }

    /// The full-resolution plane of the channel at `index`.
    pub fn plane_at(&self, index: usize) -> Result<&[f32], ExrReadError> {
        let err = read_error(&self.path);
        let ch = self.channels.get(index).ok_or_else(|| err(ExrProblem::NoLayer))?;
        let expected = self.width * self.height;
        if ch.values.len() != expected {
            return Err(err(ExrProblem::Subsampled { name: ch.name.clone(), got: ch.values.len(), expected }));
        }
        Ok(&ch.values)
    }

    /// The full-resolution plane of the channel named `name` (exactly).
    pub fn plane(&self, name: &str) -> Result<&[f32], ExrReadError> {
        let index = self.channels.iter().position(|c| c.name == name).ok_or_else(|| {
            read_error(&self.path)(ExrProblem::MissingChannel { name: name.into(), present: self.names() })
        })?;
        self.plane_at(index)
    }
}

/// Reads every channel of the first layer of `path` (its largest
/// resolution level; deep data refused).
pub fn read_layer(path: &Path) -> Result<Layer, ExrReadError> {
    use ::exr::prelude::{FlatSamples, ReadChannels, ReadLayers};
    let err = read_error(path);
    headers(path)?;
    let image = ::exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .pedantic()
        .from_file(path)
        .map_err(|e| err(ExrProblem::Decode(e)))?;
    let layer = image.layer_data;
    let channels = layer
        .channel_data
        .list
        .into_iter()
        .map(|c| Channel {
            name: c.name.to_string(),
            values: match c.sample_data {
                FlatSamples::F32(v) => v,
                other => other.values_as_f32().collect(),
            },
        })
        .collect();
    Ok(Layer { path: path.to_path_buf(), width: layer.size.width(), height: layer.size.height(), channels })
}

/// Reads the named channels (e.g. `variance.R`, `spp`) of the first layer:
/// (width, height, one row-major plane per name). A missing channel is an
/// error naming the file and listing the channels present.
pub fn read_channels(path: &Path, names: &[&str]) -> Result<(usize, usize, Vec<Vec<f32>>), ExrReadError> {
    let layer = read_layer(path)?;
    let planes = names.iter().map(|n| layer.plane(n).map(<[f32]>::to_vec)).collect::<Result<_, _>>()?;
    Ok((layer.width, layer.height, planes))
}

/// Reads R, G and B of the first layer that has them (any case; alpha and
/// other channels ignored): (width, height, interleaved RGB).
pub fn read_rgb(path: &Path) -> Result<(usize, usize, Vec<f32>), ExrReadError> {
    use ::exr::prelude::*;
    headers(path)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |res, _| (res.width(), res.height(), vec![0f32; res.width() * res.height() * 3]),
            |(w, _, px): &mut (usize, usize, Vec<f32>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                let i = 3 * (pos.y() * *w + pos.x());
                px[i] = r;
                px[i + 1] = g;
                px[i + 2] = b;
            },
        )
        .first_valid_layer()
        .all_attributes()
        .pedantic()
        .from_file(path)
        .map_err(|e| read_error(path)(ExrProblem::Decode(e)))?;
    Ok(image.layer_data.channel_data.pixels)
}

/// Writes named float channels (each `width × height`, row-major) as one
/// 32-bit float EXR layer, atomically.
pub fn write_channels(
    path: &Path,
    width: usize,
    height: usize,
    channels: &[(&str, &[f32])],
) -> Result<(), ExrWriteError> {
    Ok(write_atomic(path, &encode_channels(path, width, height, channels)?)?)
}

/// The bytes [`write_channels`] writes (`path` only names the file in an error).
pub fn encode_channels(
    path: &Path,
    width: usize,
    height: usize,
    channels: &[(&str, &[f32])],
) -> Result<Vec<u8>, ExrWriteError> {
    use ::exr::prelude::*;
    for (name, c) in channels {
        if c.len() != width * height {
            return Err(ExrWriteError::ChannelLength {
                path: path.to_path_buf(),
                name: name.to_string(),
                got: c.len(),
                expected: width * height,
                width,
                height,
            });
        }
    }
    let list: SmallVec<[AnyChannel<FlatSamples>; 4]> =
        channels.iter().map(|(name, c)| AnyChannel::new(*name, FlatSamples::F32(c.to_vec()))).collect();
    let layer = ::exr::prelude::Layer::new(
        (width, height),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(list),
    );
    let image = Image::from_layer(layer);
    let mut bytes = std::io::Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut bytes)
        .map_err(|e| ExrWriteError::Encode { path: path.to_path_buf(), reason: e.to_string() })?;
    Ok(bytes.into_inner())
}

/// Writes interleaved RGB (`width × height × 3`) as channels R, G, B.
pub fn encode_rgb(path: &Path, width: usize, height: usize, rgb: &[f32]) -> Result<Vec<u8>, ExrWriteError> {
    let plane = |c: usize| rgb.iter().skip(c).step_by(3).copied().collect::<Vec<f32>>();
    let (r, g, b) = (plane(0), plane(1), plane(2));
    encode_channels(path, width, height, &[("R", &r), ("G", &g), ("B", &b)])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn channels_round_trip_and_names_are_read_from_the_header() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("c.exr");
        write_channels(&path, 2, 1, &[("spp", &[4.0, 8.0]), ("R", &[1.0, 2.0])]).unwrap();
        assert_eq!(channel_names(&path).unwrap(), ["R", "spp"]);
        assert_eq!(image_size(&path).unwrap(), (2, 1));
        let layer = read_layer(&path).unwrap();
        assert_eq!(layer.plane("spp").unwrap(), [4.0, 8.0]);
        let e = layer.plane("G").unwrap_err().to_string();
        assert!(e.contains("c.exr") && e.contains("no channel \"G\" (channels: R, spp)"), "{e}");
    }

    #[test]
    fn a_short_channel_is_refused_before_writing() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("short.exr");
        let e = write_channels(&path, 2, 2, &[("Y", &[1.0])]).unwrap_err().to_string();
        assert!(e.contains("short.exr") && e.contains("1 values, expected 4"), "{e}");
        assert!(!path.exists());
    }

    #[test]
    fn an_empty_file_is_an_error_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("empty.exr");
        std::fs::write(&path, b"").unwrap();
        for e in [
            read_layer(&path).unwrap_err(),
            read_rgb(&path).unwrap_err(),
            image_size(&path).unwrap_err(),
            channel_names(&path).unwrap_err(),
        ] {
            let text = e.to_string();
            assert!(text.contains("empty.exr") && text.contains("cannot read EXR"), "{text}");
        }
    }
}
