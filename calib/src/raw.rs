//! RAW photographs (DNG, CR2, NEF, ARW, … — whatever `rawloader` 0.37
//! decodes) to linear camera RGB, with the metadata a lab needs.
//!
//! Steps, in order ([`read_raw`] does 1–4, [`develop`] 5–7):
//! 1. Decode the sensor values: **uncompressed DNGs** (Bayer or phones'
//!    three-channel `LinearRaw`, PhotometricInterpretation 34892; 8- or
//!    16-bit; strips or tiles; either byte order; `Linearization` table)
//!    with this module's own reader (`dng`, added because `rawloader` 0.37
//!    refuses uncompressed tiles, reads strips as one contiguous block and
//!    16-bit samples as little-endian, and keeps one black/white level for
//!    the three channels of a linear DNG: `calib/tests/raw_dng_phone.rs`
//!    shows each); everything else (CR2, NEF, …, lossless-JPEG DNGs,
//!    compression 7, predictor 1) with `rawloader`, a linear DNG's
//!    per-channel levels then re-read from its tags; DNGs with other
//!    compressions (Deflate, lossy JPEG, JPEG XL) are refused by name. DNG opcode lists (`OpcodeList1–3`: phones' gain maps, lens
//!    warps) and `DefaultCrop` are not applied; the metadata's warnings say
//!    so. TIFF directories (IFD chain, SubIFDs, tag values) are read with the
//!    `tiff` crate. Before decoding, a TIFF-based
//!    file whose declared image data runs past its end is refused as
//!    truncated ([`tiff_data_end`]; `rawloader` would make the missing part
//!    up), and after it a buffer whose length is not width × height ×
//!    samples is refused, never padded.
//! 2. Black level **per CFA position** (2 × 2): for non-DNG files with
//!    optically masked pixels, the integer mean (rounded down) of the masked
//!    pixels of that position — LibRaw's rule, so the levels agree with
//!    rawpy; for DNG, the file's `BlackLevel` values in CFA-position order
//!    (`BlackLevelDeltaH/V` are not applied); otherwise `rawloader`'s
//!    per-colour levels.
//! 3. Scale: `v' = (v − black) / (white − black)` in f32, so 1.0 is the white
//!    (saturation) level and 0.0 the black level. Nothing is clipped: noise
//!    below black stays negative, so means of dark patches are unbiased. The
//!    white level is `rawloader`'s (its camera database or the DNG tag) unless
//!    [`read_raw`] is given one (LibRaw uses 4095 for the EOS 30D where
//!    rawloader's database says 4071).
//! 4. Crop to the active area (the sensor without its masked borders).
//! 5. White balance only on request ([`WhiteBalance::Camera`]: the camera's
//!    as-shot multipliers normalised to green = 1); no tone curve ever.
//! 6. Demosaic ([`crate::demosaic`], Malvar–He–Cutler by default).
//! 7. Orientation from the file (EXIF values 1–8), applied last.
//!
//! [`raw_output_size`] gives the size of [`read_raw`]'s output (the active
//! area) from step 1 without the pixel data: the tags and, for other
//! formats, `rawloader`'s "dummy" decode (for `lucent run`'s planning).
//!
//! The result is camera RGB (the sensor's own primaries), not sRGB; the
//! camera's XYZ → camera matrix goes into the metadata for the colour stage.
//! Checked against LibRaw through rawpy on a real Canon EOS 30D file
//! (`calib/tests/raw_real.rs`), with a DNG written from a known mosaic
//! (`calib/tests/raw_dng.rs`) and with phone-style DNGs written byte by
//! byte (`calib/tests/raw_dng_phone.rs`: linear tiled, big-endian strips).
//!
//! ```
//! use lucent_calib::raw::{orient, Orientation};
//! use lucent_calib::RgbBuffer;
//! // 2 × 1 image, pixels 0 and 1; EXIF 6 means "rotate 90° clockwise to view".
//! let img = RgbBuffer::new(2, 1, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0]).unwrap();
//! let up = orient(&img, Orientation::from_exif(6));
//! assert_eq!((up.width, up.height), (1, 2));
//! assert_eq!(up.pixel(0, 1), [1.0, 1.0, 1.0]);
//! ```

use crate::buffer::RgbBuffer;
use crate::demosaic::{self, Bayer, Demosaic, DemosaicError, Mosaic};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

/// What went wrong with a RAW file; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum RawError {
    #[error("{}: cannot read: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{}: cannot decode as a RAW photo: {reason}", path.display())]
    Decode { path: PathBuf, reason: String },
    #[error("{}: decoded {got} sensor values where {width} × {height} × {samples} were expected (truncated or corrupt file)", path.display())]
    Size { path: PathBuf, width: usize, height: usize, samples: usize, got: usize },
    #[error("{}: unsupported RAW layout: {reason}", path.display())]
    Unsupported { path: PathBuf, reason: String },
    #[error("{}: the file records no camera white balance (use --white-balance none)", path.display())]
    NoCameraWhiteBalance { path: PathBuf },
    #[error("{}: {source}", path.display())]
    Demosaic { path: PathBuf, source: DemosaicError },
}

/// White balance applied before demosaicing.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
#[derive(EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage)]
#[strum(serialize_all = "lowercase", ascii_case_insensitive)]
pub enum WhiteBalance {
    /// Camera RGB as recorded (linear, as the sensor saw it).
    #[default]
    None,
    /// The as-shot multipliers, green = 1.
    #[strum(to_string = "camera", serialize = "as-shot")]
    Camera,
}

impl WhiteBalance {
    /// Any spelling of a choice (case ignored).
    pub fn from_name(name: &str) -> Result<Self, UnknownWhiteBalance> {
        name.trim().parse().map_err(|_| UnknownWhiteBalance { name: name.to_string() })
    }
}

/// A white-balance name that [`WhiteBalance::from_name`] does not know.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("unknown white balance {name:?}; valid: {}", <WhiteBalance as strum::VariantNames>::VARIANTS.join(", "))]
pub struct UnknownWhiteBalance {
    pub name: String,
}

/// A TIFF directory structure that cannot be read ([`tiff_data_end`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TiffStructureError {
    /// An IFD or one of the values read (strip, tile and SubIFD lists) lies past the end of the file.
    #[error("its TIFF directory structure runs past the end of the file ({file_len} bytes)")]
    Truncated { file_len: usize },
    /// What the `tiff` crate found wrong otherwise (e.g. a value list over its 1 MiB limit).
    #[error("its TIFF directory structure cannot be read: {reason}")]
    Corrupt { reason: String },
}

/// Options of [`develop`] and [`decode_raw`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RawOptions {
    pub demosaic: Demosaic,
    pub white_balance: WhiteBalance,
    /// Overrides the white (saturation) level, in raw digital numbers.
    pub white_level: Option<f32>,
}

impl Default for RawOptions {
    fn default() -> Self {
        Self { demosaic: Demosaic::MalvarHeCutler2004, white_balance: WhiteBalance::None, white_level: None }
    }
}

/// Image orientation as in EXIF/TIFF tag 0x0112 (1 = as stored).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Orientation(pub u16);

impl Orientation {
    /// From the EXIF value; anything outside 1–8 means "as stored".
    pub fn from_exif(v: u16) -> Self {
        Self(if (1..=8).contains(&v) { v } else { 1 })
    }

    /// Width and height swap when the image is shown upright (EXIF 5–8).
    pub fn transposes(self) -> bool {
        matches!(self.0, 5..=8)
    }

    /// A readable name of the transformation that shows the image upright.
    pub fn describe(self) -> &'static str {
        match self.0 {
            2 => "mirror horizontally",
            3 => "rotate 180°",
            4 => "mirror vertically",
            5 => "transpose (mirror horizontally, rotate 90° counter-clockwise)",
            6 => "rotate 90° clockwise",
            7 => "transverse (mirror horizontally, rotate 90° clockwise)",
            8 => "rotate 90° counter-clockwise",
            _ => "none",
        }
    }
}

/// The active area within the sensor, in sensor pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ActiveArea {
    pub top: usize,
    pub left: usize,
    pub width: usize,
    pub height: usize,
}

/// Everything known about a decoded RAW file; written as the sidecar JSON.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RawMetadata {
    /// File name of the source.
    pub source: String,
    pub make: String,
    pub model: String,
    pub exposure_time_s: Option<f64>,
    pub f_number: Option<f64>,
    pub iso: Option<u32>,
    pub focal_length_mm: Option<f64>,
    pub datetime_original: Option<String>,
    pub lens: Option<String>,
    /// `true` for a DNG.
    pub dng: bool,
    pub sensor_width: usize,
    pub sensor_height: usize,
    pub active_area: ActiveArea,
    /// Samples per pixel: 1 for a CFA mosaic, 3 for linear (demosaiced) DNG.
    pub samples_per_pixel: usize,
    /// CFA pattern of the active area before orientation, e.g. "RGGB" (empty for 3 samples).
    pub cfa_pattern: String,
    /// Black level per CFA position of the active area, row-major
    /// [(0,0), (0,1), (1,0), (1,1)], raw digital numbers (per channel R, G, B, - for 3 samples).
    pub black_levels: [f32; 4],
    /// Where the black levels come from.
    pub black_level_source: String,
    /// White level per CFA position (or channel), raw digital numbers; 1.0 in the output.
    pub white_levels: [f32; 4],
    /// XYZ → camera RGB, rows R, G, B, as the file or rawloader's camera table
    /// gives it (Adobe DNG `ColorMatrix` convention; for built-in tables and
    /// `ColorMatrix2`, the D65 calibration).
    pub xyz_to_camera: [[f64; 3]; 3],
    /// The camera's as-shot white-balance multipliers, green = 1, if recorded.
    pub camera_wb_multipliers: Option<[f64; 3]>,
    /// Multipliers applied to the output (None: no white balance).
    pub white_balance_applied: Option<[f64; 3]>,
    /// Orientation recorded in the file (EXIF value) and applied to the output.
    pub orientation: Orientation,
    pub orientation_applied: String,
    /// Demosaicing method of the output ("none" before [`develop`]).
    pub demosaic: String,
    /// Output width and height after crop and orientation.
    pub output_width: usize,
    pub output_height: usize,
    /// What the numbers mean.
    pub units: String,
    /// Metadata that could not be read (e.g. no EXIF), for the user to know.
    pub warnings: Vec<String>,
    /// The DNG's NoiseProfile (tag 51041) as stored: (S, O) pairs, one for
    /// all planes or one per plane; variance = S·x + O in this output's units
    /// before white balance ([`crate::noise::NoiseModel::from_noise_profile`]).
    #[serde(default)]
    pub noise_profile: Option<Vec<f64>>,
}

/// Black/white-scaled sensor data of the active area, before white balance,
/// demosaicing and orientation.
#[derive(Debug, Clone, PartialEq)]
pub enum RawData {
    /// A Bayer mosaic (one sample per pixel).
    Bayer(Mosaic),
    /// Three samples per pixel (linear DNG).
    Rgb(RgbBuffer),
}

/// A decoded RAW file ([`read_raw`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RawFrame {
    pub data: RawData,
    pub meta: RawMetadata,
    path: PathBuf,
}

/// EXIF fields read with `kamadak-exif` (TIFF-based raw files carry EXIF in
/// their own TIFF structure).
#[derive(Default)]
struct ExifInfo {
    exposure_time_s: Option<f64>,
    f_number: Option<f64>,
    iso: Option<u32>,
    focal_length_mm: Option<f64>,
    datetime_original: Option<String>,
    lens: Option<String>,
    orientation: Option<u16>,
    dng: bool,
}

fn read_exif(bytes: &[u8]) -> Result<ExifInfo, exif::Error> {
    use exif::{Context, In, Tag, Value};
    let e = exif::Reader::new().read_from_container(&mut std::io::Cursor::new(bytes))?;
    let rational = |t: Tag| {
        e.get_field(t, In::PRIMARY).and_then(|f| match &f.value {
            Value::Rational(v) => v.first().map(|r| r.to_f64()).filter(|x| x.is_finite()),
            _ => None,
        })
    };
    let text = |t: Tag| {
        e.get_field(t, In::PRIMARY).and_then(|f| match &f.value {
            Value::Ascii(v) => v
                .first()
                .map(|s| String::from_utf8_lossy(s).trim_end_matches('\0').trim().to_string())
                .filter(|s| !s.is_empty()),
            _ => None,
        })
    };
    let uint = |t: Tag| e.get_field(t, In::PRIMARY).and_then(|f| f.value.get_uint(0));
    Ok(ExifInfo {
        exposure_time_s: rational(Tag::ExposureTime),
        f_number: rational(Tag::FNumber),
        iso: uint(Tag::PhotographicSensitivity),
        focal_length_mm: rational(Tag::FocalLength),
        datetime_original: text(Tag::DateTimeOriginal),
        lens: text(Tag::LensModel),
        orientation: uint(Tag::Orientation).and_then(|v| u16::try_from(v).ok()),
        dng: e.get_field(Tag(Context::Tiff, 50706), In::PRIMARY).is_some(),
    })
}

/// Per-CFA-position (sensor parity) integer means, rounded down, of the
/// masked pixels in `areas` (rawloader tuples top, right, bottom, left).
fn masked_black(data: &[u16], width: usize, height: usize, areas: &[(u64, u64, u64, u64)]) -> Option<[u64; 4]> {
    let mut sum = [0u64; 4];
    let mut count = [0u64; 4];
    for &(top, right, bottom, left) in areas {
        let (top, right, bottom, left) = (top as usize, right as usize, bottom as usize, left as usize);
        if top >= bottom || left >= right || bottom > height || right > width {
            return None;
        }
        for y in top..bottom {
            for x in left..right {
                let k = 2 * (y & 1) + (x & 1);
                sum[k] += u64::from(data[y * width + x]);
                count[k] += 1;
            }
        }
    }
    if count.contains(&0) {
        return None;
    }
    Some([sum[0] / count[0], sum[1] / count[1], sum[2] / count[2], sum[3] / count[3]])
}

/// End (in bytes) of the image data that a TIFF-based raw file (DNG, CR2,
/// NEF, ARW, PEF, …) declares: the largest offset + length over the strips,
/// tiles and JPEG streams of every IFD reachable from the header (chain and
/// SubIFDs). `Ok(None)` for files that are not plain little/big-endian
/// TIFF; an error when an IFD lies outside the file. Used to refuse
/// truncated files, which `rawloader` would decode with the missing data
/// made up. The directories are read by the `tiff` crate (module `tiff_dir`
/// below); the byte range is this function's (the crate checks an offset only
/// when it reads the data there).
pub fn tiff_data_end(bytes: &[u8]) -> Result<Option<u64>, TiffStructureError> {
    let error = |e: tiff::TiffError| match e {
        tiff::TiffError::IoError(ref io) if io.kind() == std::io::ErrorKind::UnexpectedEof => {
            TiffStructureError::Truncated { file_len: bytes.len() }
        }
        other => TiffStructureError::Corrupt { reason: other.to_string() },
    };
    let Some(t) = tiff_dir::TiffFile::open(bytes).map_err(error)? else {
        return Ok(None);
    };
    let mut end = 0u64;
    t.find(|t, dir| {
        // StripOffsets/StripByteCounts, TileOffsets/TileByteCounts, JPEGInterchangeFormat(Length).
        for (offsets, lengths) in [(273u16, 279u16), (324, 325), (513, 514)] {
            if tiff_dir::TiffFile::has(dir, offsets) && tiff_dir::TiffFile::has(dir, lengths) {
                let (o, l) = (t.numbers(dir, offsets)?, t.numbers(dir, lengths)?);
                for (a, b) in o.iter().zip(&l) {
                    end = end.max((*a as u64).saturating_add(*b as u64));
                }
            }
        }
        Ok(false)
    })
    .map_err(error)?;
    Ok(Some(end))
}

/// TIFF structure of raw files through the `tiff` crate (0.11): the IFDs
/// reachable from the header (the IFD0 chain and SubIFDs) and their tag values.
///
/// Hand-written here, and only this: the 8-byte header and a stub directory.
/// `tiff::decoder::Decoder::new` opens a file only when its first IFD is an
/// image the crate decodes (ImageWidth, a photometric interpretation it
/// knows, strips or tiles), so a DNG whose IFD0 is the raw image itself (CFA,
/// 32803, or LinearRaw, 34892: what Android phones and `calib/tests/raw_dng*.rs`
/// write) is refused with "unknown interpretation". The decoder therefore
/// reads the file through [`Stubbed`], whose header points at a 1 × 1 stub IFD
/// just past the file's end; the file's own IFDs are then read with
/// `Decoder::read_directory` (0.11's reader of a directory at any offset) and
/// their values with `Decoder::read_directory_tags`: entry types, byte order,
/// inline or offset values and reads past the end of the file (an error) are
/// the crate's. Also left here, as the crate does neither for directories read
/// this way: which IFDs to visit (cycle and count guard) and, in
/// [`super::tiff_data_end`], the byte range of the image data.
mod tiff_dir {
    use std::cell::RefCell;
    use std::collections::HashSet;
    use std::io::{Read, Seek, SeekFrom};
    use tiff::decoder::{ifd::Value, Decoder};
    use tiff::tags::{IfdPointer, Tag};
    use tiff::{Directory, TiffResult};

    /// Most IFDs visited (real raw files have fewer than 10).
    const MAX_IFDS: usize = 64;

    /// Bytes of the stub IFD: 5 entries of 12 bytes, their count and the next-IFD offset.
    const STUB_LEN: usize = 2 + 5 * 12 + 4;

    /// The file as `tiff` reads it. While `Decoder::new` reads it, the
    /// header's first-IFD offset is replaced by that of a stub IFD (a 1 × 1
    /// grey image) appended after the file's last byte; then the stub is
    /// removed ([`Stubbed::unstub`]), so that reads past the end of the file
    /// fail as they would on the file itself.
    struct Stubbed<'a> {
        head: [u8; 8],
        file: &'a [u8],
        stub: Option<[u8; STUB_LEN]>,
        pos: u64,
    }

    impl<'a> Stubbed<'a> {
        fn new(file: &'a [u8], le: bool) -> Option<Self> {
            let stub_at = u32::try_from(file.len()).ok().filter(|&n| n <= u32::MAX - STUB_LEN as u32)?;
            let u16b = |v: u16| if le { v.to_le_bytes() } else { v.to_be_bytes() };
            let u32b = |v: u32| if le { v.to_le_bytes() } else { v.to_be_bytes() };
            let mut head = [0u8; 8];
            head[..4].copy_from_slice(&file[..4]);
            head[4..].copy_from_slice(&u32b(stub_at));
            let mut stub = [0u8; STUB_LEN];
            stub[..2].copy_from_slice(&u16b(5));
            // ImageWidth = ImageLength = 1, BlackIsZero, one strip of 1 byte at offset 0 (SHORT = 3, LONG = 4).
            for (k, (tag, typ, value)) in
                [(256u16, 3u16, 1u32), (257, 3, 1), (262, 3, 1), (273, 4, 0), (279, 4, 1)].into_iter().enumerate()
            {
                let e = &mut stub[2 + 12 * k..14 + 12 * k];
                e[..2].copy_from_slice(&u16b(tag));
                e[2..4].copy_from_slice(&u16b(typ));
                e[4..8].copy_from_slice(&u32b(1));
                if typ == 3 {
                    e[8..10].copy_from_slice(&u16b(value as u16));
                } else {
                    e[8..12].copy_from_slice(&u32b(value));
                }
            }
            Some(Self { head, file, stub: Some(stub), pos: 0 })
        }

        /// The file alone from now on.
        fn unstub(&mut self) {
            self.stub = None;
        }

        /// The bytes from `pos` to the end of the part that holds it.
        fn rest(&self) -> &[u8] {
            let (p, n) = (self.pos, self.file.len() as u64);
            match &self.stub {
                Some(_) if p < 8 => &self.head[p as usize..],
                _ if p < n => &self.file[p as usize..],
                Some(stub) if p < n + STUB_LEN as u64 => &stub[(p - n) as usize..],
                _ => &[],
            }
        }
    }

    impl Read for Stubbed<'_> {
        fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
            let rest = self.rest();
            let k = rest.len().min(buf.len());
            buf[..k].copy_from_slice(&rest[..k]);
            self.pos += k as u64;
            Ok(k)
        }
    }

    impl Seek for Stubbed<'_> {
        fn seek(&mut self, to: SeekFrom) -> std::io::Result<u64> {
            let end = (self.file.len() + if self.stub.is_some() { STUB_LEN } else { 0 }) as u64;
            let pos = match to {
                SeekFrom::Start(p) => Some(p),
                SeekFrom::End(d) => end.checked_add_signed(d),
                SeekFrom::Current(d) => self.pos.checked_add_signed(d),
            };
            self.pos = pos.ok_or_else(|| std::io::Error::new(std::io::ErrorKind::InvalidInput, "seek before 0"))?;
            Ok(self.pos)
        }
    }

    /// A classic (not Big-) TIFF file and its decoder.
    pub(super) struct TiffFile<'a> {
        /// The whole file (image data is read from it directly).
        pub(super) bytes: &'a [u8],
        /// Little-endian ("II") rather than big-endian ("MM").
        pub(super) le: bool,
        first: IfdPointer,
        decoder: RefCell<Decoder<Stubbed<'a>>>,
    }

    impl<'a> TiffFile<'a> {
        /// `Ok(None)` unless `bytes` start with a little- or big-endian TIFF
        /// header (or are 4 GiB or more, beyond classic TIFF).
        pub(super) fn open(bytes: &'a [u8]) -> TiffResult<Option<Self>> {
            let le = match bytes.get(..4) {
                Some([b'I', b'I', 42, 0]) => true,
                Some([b'M', b'M', 0, 42]) => false,
                _ => return Ok(None),
            };
            let Some(&[a, b, c, d]) = bytes.get(4..8) else {
                return Err(std::io::Error::from(std::io::ErrorKind::UnexpectedEof).into());
            };
            let first = IfdPointer(u64::from(if le {
                u32::from_le_bytes([a, b, c, d])
            } else {
                u32::from_be_bytes([a, b, c, d])
            }));
            let Some(reader) = Stubbed::new(bytes, le) else { return Ok(None) };
            let mut decoder = Decoder::new(reader)?;
            decoder.inner().unstub();
            Ok(Some(Self { bytes, le, first, decoder: RefCell::new(decoder) }))
        }

        /// IFD0.
        pub(super) fn first(&self) -> TiffResult<Directory> {
            self.decoder.borrow_mut().read_directory(self.first)
        }

        /// The first IFD for which `pick` is true, visiting IFD0, its chain
        /// and the SubIFDs depth first (of one IFD, the next in its chain
        /// before its SubIFDs); `Ok(None)` when none is. Errors when an IFD or
        /// a SubIFD list cannot be read (it lies past the end of the file).
        pub(super) fn find(
            &self,
            mut pick: impl FnMut(&Self, &Directory) -> TiffResult<bool>,
        ) -> TiffResult<Option<Directory>> {
            let mut queue = vec![self.first];
            let mut seen = HashSet::new();
            while let Some(at) = queue.pop() {
                if at.0 == 0 || !seen.insert(at.0) || seen.len() > MAX_IFDS {
                    continue;
                }
                let dir = self.decoder.borrow_mut().read_directory(at)?;
                if pick(self, &dir)? {
                    return Ok(Some(dir));
                }
                queue.extend(self.numbers(&dir, 330)?.into_iter().map(|v| IfdPointer(v as u64)));
                queue.extend(dir.next());
            }
            Ok(None)
        }

        /// Whether `dir` has `tag`.
        pub(super) fn has(dir: &Directory, tag: u16) -> bool {
            dir.contains(Tag::from_u16_exhaustive(tag))
        }

        /// The number of values of `tag` in `dir` (0 when absent).
        pub(super) fn count(dir: &Directory, tag: u16) -> u64 {
            dir.get(Tag::from_u16_exhaustive(tag)).map_or(0, |e| e.count())
        }

        /// The values of `tag` in `dir` as numbers (rationals divided out;
        /// text gives none); empty when the tag is absent.
        pub(super) fn numbers(&self, dir: &Directory, tag: u16) -> TiffResult<Vec<f64>> {
            fn push(v: Value, out: &mut Vec<f64>) {
                match v {
                    Value::List(vs) => vs.into_iter().for_each(|v| push(v, out)),
                    Value::Byte(x) => out.push(f64::from(x)),
                    Value::SignedByte(x) => out.push(f64::from(x)),
                    Value::Short(x) => out.push(f64::from(x)),
                    Value::SignedShort(x) => out.push(f64::from(x)),
                    Value::Unsigned(x) | Value::Ifd(x) => out.push(f64::from(x)),
                    Value::Signed(x) => out.push(f64::from(x)),
                    Value::UnsignedBig(x) | Value::IfdBig(x) => out.push(x as f64),
                    Value::SignedBig(x) => out.push(x as f64),
                    Value::Float(x) => out.push(f64::from(x)),
                    Value::Double(x) => out.push(x),
                    Value::Rational(n, d) => out.push(f64::from(n) / f64::from(d)),
                    Value::SRational(n, d) => out.push(f64::from(n) / f64::from(d)),
                    _ => {}
                }
            }
            let mut out = Vec::new();
            let mut decoder = self.decoder.borrow_mut();
            if let Some(v) = decoder.read_directory_tags(dir).find_tag(Tag::from_u16_exhaustive(tag))? {
                push(v, &mut out);
            }
            Ok(out)
        }

        /// The bytes of `tag` in `dir` as text (invalid UTF-8 replaced,
        /// trailing NULs and spaces removed); empty when the tag is absent.
        pub(super) fn text(&self, dir: &Directory, tag: u16) -> TiffResult<String> {
            let tag = Tag::from_u16_exhaustive(tag);
            let Some(e) = dir.get(tag) else { return Ok(String::new()) };
            // One byte per value for ASCII / BYTE / UNDEFINED; never more than the file holds.
            let mut buf = vec![0u8; usize::try_from(e.count()).unwrap_or(usize::MAX).min(self.bytes.len())];
            let n = self.decoder.borrow_mut().read_directory_tags(dir).find_tag_bytes(tag, &mut buf, 0)?.unwrap_or(0);
            buf.truncate(n);
            Ok(String::from_utf8_lossy(&buf).trim_end_matches('\0').trim().to_string())
        }

        /// The 16-bit value at byte `o` of the file, in its byte order (image data).
        pub(super) fn u16_at(&self, o: usize) -> Option<u16> {
            let s = self.bytes.get(o..o.checked_add(2)?)?;
            Some(if self.le { u16::from_le_bytes([s[0], s[1]]) } else { u16::from_be_bytes([s[0], s[1]]) })
        }
    }
}

/// `rawloader` turns its internal panics on malformed files into errors, but
/// the default panic hook still prints them; this hook (installed once,
/// delegating everything else to the previous hook) keeps those quiet.
fn quiet_rawloader_panics() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if info.location().is_some_and(|l| l.file().contains("rawloader")) {
                return;
            }
            previous(info);
        }));
    });
}

/// The size of the image [`read_raw`] would give for `path` —
/// `(meta.output_width, meta.output_height)`: the active area, before
/// orientation — from the file's directories alone, without decoding its
/// pixel data (what planning needs). The same checks as [`read_raw`] run
/// before decoding (unreadable, empty or truncated file; unsupported DNG
/// compression or layout; crop outside the sensor; not a 1-sample Bayer or
/// 3-sample image), so a file refused for those reasons is refused here
/// too, with the same error. Not checked here, as they need the pixel
/// values: the number of samples the data holds and the levels measured on
/// masked pixels, so a file whose image data is corrupt (but present) gives
/// its size here and an error from [`read_raw`].
pub fn raw_output_size(path: &Path) -> Result<(usize, usize), RawError> {
    Ok(header_sizes(path)?.0)
}

/// The size of the image [`decode_raw`] gives for `path`: [`raw_output_size`]
/// turned by the file's orientation (width and height swapped for EXIF
/// orientations 5–8), from the file's directories alone — what a photo
/// developed from this file measures.
pub fn developed_size(path: &Path) -> Result<(usize, usize), RawError> {
    let ((w, h), orientation) = header_sizes(path)?;
    Ok(if orientation.transposes() { (h, w) } else { (w, h) })
}

/// [`raw_output_size`] and the orientation [`read_raw`] would report.
fn header_sizes(path: &Path) -> Result<((usize, usize), Orientation), RawError> {
    let (bytes, img) = load(path, true)?;
    let area = active_area(path, &img)?;
    sensor_pattern(path, &img)?;
    let exif = read_exif(&bytes).unwrap_or_default();
    Ok(((area.width, area.height), file_orientation(&img, &exif)))
}

/// The orientation of a decoded file: rawloader's where it knows one, else the EXIF tag's.
fn file_orientation(img: &rawloader::RawImage, exif: &ExifInfo) -> Orientation {
    match img.orientation {
        rawloader::Orientation::Unknown => Orientation::from_exif(exif.orientation.unwrap_or(1)),
        o => Orientation::from_exif(o.to_u16()),
    }
}

/// `rawloader`'s decoder and camera table (parsed once).
static RAWLOADER: std::sync::LazyLock<rawloader::RawLoader> = std::sync::LazyLock::new(rawloader::RawLoader::new);

/// The file's bytes and its sensor image (step 1 of the module docs), after
/// the checks on the file before decoding. `header_only`: the image's
/// size, crops, levels and tags without its pixel data (`img.data` then
/// holds no samples: `rawloader`'s "dummy" decode and [`dng::decode_uncompressed`]
/// without its sample loop), for [`raw_output_size`].
fn load(path: &Path, header_only: bool) -> Result<(Vec<u8>, rawloader::RawImage), RawError> {
    let p = || path.to_path_buf();
    let bytes = std::fs::read(path).map_err(|source| RawError::Io { path: p(), source })?;
    if bytes.is_empty() {
        return Err(RawError::Decode { path: p(), reason: "the file is empty".into() });
    }
    match tiff_data_end(&bytes) {
        Ok(Some(end)) if end > bytes.len() as u64 => {
            return Err(RawError::Decode {
                path: p(),
                reason: format!("truncated: its image data ends at byte {end} but the file has {} bytes", bytes.len()),
            });
        }
        Err(why) => return Err(RawError::Decode { path: p(), reason: format!("truncated or corrupt: {why}") }),
        _ => {}
    }
    quiet_rawloader_panics();
    let own = dng::decode_uncompressed(&bytes, header_only).map_err(|reason| RawError::Decode { path: p(), reason })?;
    let decoded = match own {
        Some(img) => Ok(img),
        None => RAWLOADER.decode(&mut std::io::Cursor::new(&bytes), header_only),
    };
    let img = decoded.map_err(|msg| {
        let msg = if msg.starts_with("Caught a panic") {
            "the decoder failed on malformed data (corrupt or truncated file)".to_string()
        } else {
            msg
        };
        RawError::Decode { path: p(), reason: msg }
    })?;
    Ok((bytes, img))
}

/// The active area of `img`: the sensor without its crops (masked borders).
/// This is the size of [`read_raw`]'s output ([`raw_output_size`]).
fn active_area(path: &Path, img: &rawloader::RawImage) -> Result<ActiveArea, RawError> {
    let (w, h) = (img.width, img.height);
    let [top, right, bottom, left] = img.crops;
    if left.saturating_add(right) >= w || top.saturating_add(bottom) >= h {
        return Err(RawError::Unsupported {
            path: path.to_path_buf(),
            reason: format!("crop {:?} leaves no active area in {w} × {h}", img.crops),
        });
    }
    Ok(ActiveArea { top, left, width: w - left - right, height: h - top - bottom })
}

/// The Bayer pattern of `img` as `rawloader` names it (from the sensor's
/// origin; a DNG's from the active area's) for one sample per pixel, `None`
/// for three; an error for other layouts.
fn sensor_pattern(path: &Path, img: &rawloader::RawImage) -> Result<Option<Bayer>, RawError> {
    let p = || path.to_path_buf();
    match img.cpp {
        1 => {
            if !img.cfa.is_valid() {
                return Err(RawError::Unsupported { path: p(), reason: "monochrome sensor (no CFA)".into() });
            }
            Bayer::from_name(&img.cfa.name).map(Some).map_err(|_| RawError::Unsupported {
                path: p(),
                reason: format!("CFA pattern {:?} is not a 2 × 2 RGB Bayer pattern (X-Trans and four-colour sensors are not supported)", img.cfa.name),
            })
        }
        3 => Ok(None),
        n => Err(RawError::Unsupported { path: p(), reason: format!("{n} samples per pixel") }),
    }
}

/// Decodes `path`: steps 1–4 of the module docs (black/white scaling and
/// crop; no white balance, demosaicing or orientation). `white_level`
/// overrides the file's white level (raw digital numbers).
pub fn read_raw(path: &Path, white_level: Option<f32>) -> Result<RawFrame, RawError> {
    let p = || path.to_path_buf();
    let (bytes, mut img) = load(path, false)?;
    if img.cpp == 3
        && let Some((black, white)) = dng::levels(&bytes)
    {
        (img.blacklevels, img.whitelevels) = (black, white);
    }
    let mut warnings = dng::notes(&bytes);
    let exif = read_exif(&bytes).unwrap_or_else(|e| {
        warnings.push(format!("no EXIF metadata ({e}): exposure, ISO and lens unknown"));
        ExifInfo::default()
    });

    let (w, h, cpp) = (img.width, img.height, img.cpp);
    let got = match &img.data {
        rawloader::RawImageData::Integer(v) => v.len(),
        rawloader::RawImageData::Float(v) => v.len(),
    };
    if w == 0 || h == 0 || w.checked_mul(h).and_then(|n| n.checked_mul(cpp)) != Some(got) {
        return Err(RawError::Size { path: p(), width: w, height: h, samples: cpp, got });
    }
    let area = active_area(path, &img)?;
    let (top, left) = (area.top, area.left);

    // DNG gives the CFA pattern and black levels from the active area's
    // origin; other formats (and rawloader's tables) from the sensor's. This
    // permutation maps between the two orders of the 2 × 2 positions (it is
    // its own inverse).
    let swap = |k: usize| 2 * (((k / 2) + top) & 1) + (((k % 2) + left) & 1);

    // Colour (rawloader index 0 R, 1 G, 2 B) per sensor parity, for a Bayer CFA.
    let pattern = sensor_pattern(path, &img)?.map(|named| if exif.dng { named.shifted(top, left) } else { named });

    // Black and white levels per sensor parity (k = 2·(y&1) + (x&1)) or per channel.
    let colour_of = |k: usize| pattern.map_or(k.min(2), |b| b.colour_at(k / 2, k % 2));
    let masked = match (&img.data, exif.dng, pattern.is_some()) {
        (rawloader::RawImageData::Integer(v), false, true) if !img.blackareas.is_empty() => {
            masked_black(v, w, h, &img.blackareas)
        }
        _ => None,
    };
    let (black, black_source): ([f32; 4], String) = if let Some(m) = masked {
        (m.map(|b| b as f32), "integer mean of the masked sensor pixels per CFA position (LibRaw's rule)".into())
    } else if exif.dng && pattern.is_some() {
        (std::array::from_fn(|k| f32::from(img.blacklevels[swap(k)])), "DNG BlackLevel tag, CFA-position order".into())
    } else {
        (std::array::from_fn(|k| f32::from(img.blacklevels[colour_of(k)])), "rawloader per-colour black level".into())
    };
    let white: [f32; 4] = match white_level {
        Some(v) => [v; 4],
        None => std::array::from_fn(|k| f32::from(img.whitelevels[colour_of(k)])),
    };
    for k in 0..4 {
        if white[k].partial_cmp(&black[k]) != Some(std::cmp::Ordering::Greater) {
            return Err(RawError::Decode {
                path: p(),
                reason: match white_level {
                    Some(v) => format!(
                        "the white level {v} given (--white-level) is not above the black level {} ({black_source})",
                        black[k]
                    ),
                    None => format!(
                        "implausible levels: white {} is not above black {} ({black_source}); the file is probably corrupt",
                        white[k], black[k]
                    ),
                },
            });
        }
    }

    // Scale and crop in one pass. For cpp = 3, index k is the channel.
    let sample = |i: usize| -> f32 {
        match &img.data {
            rawloader::RawImageData::Integer(v) => f32::from(v[i]),
            rawloader::RawImageData::Float(v) => v[i],
        }
    };
    let mut out = Vec::with_capacity(area.width * area.height * cpp);
    for y in area.top..area.top + area.height {
        for x in area.left..area.left + area.width {
            for c in 0..cpp {
                let k = if cpp == 1 { 2 * (y & 1) + (x & 1) } else { c };
                out.push((sample((y * w + x) * cpp + c) - black[k]) / (white[k] - black[k]));
            }
        }
    }

    // Levels from sensor parity to active-area CFA position.
    let to_active = |v: [f32; 4]| -> [f32; 4] {
        if cpp == 1 {
            std::array::from_fn(|k| v[swap(k)])
        } else {
            v
        }
    };
    let wb = img.wb_coeffs;
    let camera_wb = (wb[..3].iter().all(|v| v.is_finite() && *v > 0.0))
        .then(|| [f64::from(wb[0] / wb[1]), 1.0, f64::from(wb[2] / wb[1])]);
    let orientation = file_orientation(&img, &exif);
    // rawloader keeps its camera table's matrices as integers ×10000 (dcraw's
    // adobe_coeff convention) and DNG matrices as they are.
    let matrix_scale = if exif.dng { 1.0 } else { 1e-4 };
    let xyz_to_camera =
        std::array::from_fn(|r| std::array::from_fn(|c| f64::from(img.xyz_to_cam[r][c]) * matrix_scale));
    let cropped_pattern = pattern.map(|b| b.shifted(area.top, area.left));
    let meta = RawMetadata {
        source: path.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default(),
        make: img.clean_make.clone(),
        model: img.clean_model.clone(),
        exposure_time_s: exif.exposure_time_s,
        f_number: exif.f_number,
        iso: exif.iso,
        focal_length_mm: exif.focal_length_mm,
        datetime_original: exif.datetime_original,
        lens: exif.lens,
        dng: exif.dng,
        sensor_width: w,
        sensor_height: h,
        active_area: area,
        samples_per_pixel: cpp,
        cfa_pattern: cropped_pattern.map(|b| b.name()).unwrap_or_default(),
        black_levels: to_active(black),
        black_level_source: black_source,
        white_levels: to_active(white),
        xyz_to_camera,
        camera_wb_multipliers: camera_wb,
        white_balance_applied: None,
        orientation,
        orientation_applied: "none".into(),
        demosaic: "none".into(),
        output_width: area.width,
        output_height: area.height,
        units: "linear camera RGB; 0 = black level, 1 = white (saturation) level; not clipped; no tone curve".into(),
        warnings,
        noise_profile: dng::noise_profile(&bytes),
    };
    let data = match cropped_pattern {
        Some(b) => RawData::Bayer(Mosaic { width: area.width, height: area.height, pattern: b, data: out }),
        None => RawData::Rgb(RgbBuffer { width: area.width, height: area.height, data: out }),
    };
    Ok(RawFrame { data, meta, path: path.to_path_buf() })
}

impl RawFrame {
    /// The same frame (metadata, file) with other sensor values of the same
    /// layout, e.g. a realisation of its noise ([`crate::noise::developed_noise`]).
    pub(crate) fn with_data(&self, data: RawData) -> RawFrame {
        RawFrame { data, meta: self.meta.clone(), path: self.path.clone() }
    }
}

/// Steps 5–7: white balance (if asked), demosaicing, orientation. Returns the
/// image and its metadata (updated with what was applied).
pub fn develop(frame: &RawFrame, opts: &RawOptions) -> Result<(RgbBuffer, RawMetadata), RawError> {
    let mut meta = frame.meta.clone();
    let gains = match opts.white_balance {
        WhiteBalance::None => None,
        WhiteBalance::Camera => Some(
            meta.camera_wb_multipliers.ok_or_else(|| RawError::NoCameraWhiteBalance { path: frame.path.clone() })?,
        ),
    };
    meta.white_balance_applied = gains;
    let rgb = match &frame.data {
        RawData::Bayer(m) => {
            let balanced;
            let m = match gains {
                Some(g) => {
                    let mut b = m.clone();
                    for (i, v) in b.data.iter_mut().enumerate() {
                        *v *= g[m.pattern.colour_at(i / m.width, i % m.width)] as f32;
                    }
                    balanced = b;
                    &balanced
                }
                None => m,
            };
            meta.demosaic = opts.demosaic.name().into();
            demosaic::demosaic(m, opts.demosaic)
                .map_err(|source| RawError::Demosaic { path: frame.path.clone(), source })?
        }
        RawData::Rgb(img) => {
            let mut img = img.clone();
            if let Some(g) = gains {
                for px in img.data.chunks_exact_mut(3) {
                    for c in 0..3 {
                        px[c] *= g[c] as f32;
                    }
                }
            }
            meta.demosaic = "none (linear DNG)".into();
            img
        }
    };
    let rgb = orient(&rgb, meta.orientation);
    meta.orientation_applied = meta.orientation.describe().into();
    meta.output_width = rgb.width;
    meta.output_height = rgb.height;
    Ok((rgb, meta))
}

/// [`read_raw`] then [`develop`].
pub fn decode_raw(path: &Path, opts: &RawOptions) -> Result<(RgbBuffer, RawMetadata), RawError> {
    let frame = read_raw(path, opts.white_level)?;
    develop(&frame, opts)
}

/// The image as it should be viewed, given its EXIF orientation.
pub fn orient(img: &RgbBuffer, o: Orientation) -> RgbBuffer {
    let (w, h) = (img.width, img.height);
    let (ow, oh) = if o.transposes() { (h, w) } else { (w, h) };
    let mut data = vec![0.0f32; img.data.len()];
    for yo in 0..oh {
        for xo in 0..ow {
            // Source pixel for output pixel (xo, yo).
            let (xs, ys) = match o.0 {
                2 => (w - 1 - xo, yo),
                3 => (w - 1 - xo, h - 1 - yo),
                4 => (xo, h - 1 - yo),
                5 => (yo, xo),
                6 => (yo, h - 1 - xo),
                7 => (w - 1 - yo, h - 1 - xo),
                8 => (w - 1 - yo, xo),
                _ => (xo, yo),
            };
            let (s, d) = (3 * (ys * w + xs), 3 * (yo * ow + xo));
            data[d..d + 3].copy_from_slice(&img.data[s..s + 3]);
        }
    }
    RgbBuffer { width: ow, height: oh, data }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn numbered(w: usize, h: usize) -> RgbBuffer {
        RgbBuffer::new(w, h, (0..w * h).flat_map(|i| [i as f32; 3]).collect()).unwrap()
    }

    fn ids(img: &RgbBuffer) -> Vec<u32> {
        img.data.chunks(3).map(|p| p[0] as u32).collect()
    }

    #[test]
    fn orientations_follow_exif() {
        // Stored 3 × 2:   0 1 2
        //                 3 4 5
        let img = numbered(3, 2);
        let o = |v| orient(&img, Orientation::from_exif(v));
        assert_eq!(ids(&o(1)), [0, 1, 2, 3, 4, 5]);
        assert_eq!(ids(&o(2)), [2, 1, 0, 5, 4, 3]);
        assert_eq!(ids(&o(3)), [5, 4, 3, 2, 1, 0]);
        assert_eq!(ids(&o(4)), [3, 4, 5, 0, 1, 2]);
        // 90° clockwise: the left column (0, 3), read bottom-up, becomes the top row.
        assert_eq!(ids(&o(6)), [3, 0, 4, 1, 5, 2]);
        assert_eq!(ids(&o(8)), [2, 5, 1, 4, 0, 3]);
        assert_eq!(ids(&o(5)), [0, 3, 1, 4, 2, 5]);
        assert_eq!(ids(&o(7)), [5, 2, 4, 1, 3, 0]);
        assert_eq!((o(6).width, o(6).height), (2, 3));
        // 6 then 8 is the identity; 0 and 9 mean "as stored".
        assert_eq!(orient(&o(6), Orientation(8)), img);
        assert_eq!(o(0), img);
        assert_eq!(o(9), img);
    }

    #[test]
    fn masked_black_is_the_floored_mean_per_position() {
        // 4 × 2 sensor, masked columns 0..2 (rawloader tuple: top, right, bottom, left).
        let data = [10, 20, 0, 0, 31, 40, 0, 0];
        assert_eq!(masked_black(&data, 4, 2, &[(0, 2, 2, 0)]), Some([10, 20, 31, 40]));
        let data = [10, 20, 11, 23, 30, 40, 0, 0];
        assert_eq!(masked_black(&data, 4, 2, &[(0, 4, 1, 0)]), None, "no odd rows masked");
        assert_eq!(masked_black(&data, 4, 2, &[(0, 4, 2, 0)]), Some([10, 21, 15, 20]));
        assert_eq!(masked_black(&data, 4, 2, &[(0, 9, 2, 0)]), None, "area outside the sensor");
    }

    #[test]
    fn missing_empty_and_garbage_files_are_errors_naming_them() {
        let dir = std::env::temp_dir().join(format!("lucent-raw-test-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("nope.cr2");
        let e = read_raw(&missing, None).unwrap_err();
        assert!(matches!(e, RawError::Io { .. }) && e.to_string().contains("nope.cr2"), "{e}");
        let empty = dir.join("empty.dng");
        std::fs::write(&empty, b"").unwrap();
        let e = read_raw(&empty, None).unwrap_err();
        assert!(e.to_string().contains("empty.dng") && e.to_string().contains("empty"), "{e}");
        let junk = dir.join("junk.nef");
        std::fs::write(&junk, b"this is not a raw file at all, just some text bytes").unwrap();
        let e = read_raw(&junk, None).unwrap_err();
        assert!(matches!(e, RawError::Decode { .. }) && e.to_string().contains("junk.nef"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn tiff_data_end_reads_strips_and_sub_ifds() {
        // Little-endian TIFF: IFD0 at 8 with StripOffsets = 100, StripByteCounts = 50
        // and a SubIFD at 60 with TileOffsets = 200, TileByteCounts = 1000.
        let mut b = vec![0u8; 300];
        b[..8].copy_from_slice(&[b'I', b'I', 42, 0, 8, 0, 0, 0]);
        let entry = |b: &mut Vec<u8>, at: usize, tag: u16, typ: u16, value: u32| {
            b[at..at + 2].copy_from_slice(&tag.to_le_bytes());
            b[at + 2..at + 4].copy_from_slice(&typ.to_le_bytes());
            b[at + 4..at + 8].copy_from_slice(&1u32.to_le_bytes());
            b[at + 8..at + 12].copy_from_slice(&value.to_le_bytes());
        };
        b[8..10].copy_from_slice(&3u16.to_le_bytes());
        entry(&mut b, 10, 273, 4, 100);
        entry(&mut b, 22, 279, 3, 50);
        entry(&mut b, 34, 330, 13, 60);
        b[60..62].copy_from_slice(&2u16.to_le_bytes());
        entry(&mut b, 62, 324, 4, 200);
        entry(&mut b, 74, 325, 4, 1000);
        assert_eq!(tiff_data_end(&b), Ok(Some(1200)));
        assert_eq!(tiff_data_end(b"not a tiff"), Ok(None));
        assert!(tiff_data_end(&b[..12]).unwrap_err().to_string().contains("past the end"), "IFD cut off");
        // IFD0 is no image `tiff` decodes (no ImageWidth): read all the same (the stub IFD).
        // Cut inside the SubIFD's entries, after its list in IFD0 was read.
        assert_eq!(tiff_data_end(&b[..70]), Err(TiffStructureError::Truncated { file_len: 70 }));
        // The header alone, and a header without its IFD0 offset.
        assert_eq!(tiff_data_end(b"II*\0"), Err(TiffStructureError::Truncated { file_len: 4 }));
        assert_eq!(tiff_data_end(&b[..8]), Err(TiffStructureError::Truncated { file_len: 8 }));
        // Big-endian: the same structure with every field swapped.
        let mut m = vec![0u8; 300];
        m[..8].copy_from_slice(&[b'M', b'M', 0, 42, 0, 0, 0, 8]);
        let entry_be = |m: &mut Vec<u8>, at: usize, tag: u16, typ: u16, value: u32| {
            m[at..at + 2].copy_from_slice(&tag.to_be_bytes());
            m[at + 2..at + 4].copy_from_slice(&typ.to_be_bytes());
            m[at + 4..at + 8].copy_from_slice(&1u32.to_be_bytes());
            // A SHORT sits in the first two bytes of the value field.
            if typ == 3 {
                m[at + 8..at + 10].copy_from_slice(&(value as u16).to_be_bytes());
            } else {
                m[at + 8..at + 12].copy_from_slice(&value.to_be_bytes());
            }
        };
        m[8..10].copy_from_slice(&3u16.to_be_bytes());
        entry_be(&mut m, 10, 273, 4, 100);
        entry_be(&mut m, 22, 279, 3, 50);
        entry_be(&mut m, 34, 330, 13, 60);
        m[60..62].copy_from_slice(&2u16.to_be_bytes());
        entry_be(&mut m, 62, 324, 4, 200);
        entry_be(&mut m, 74, 325, 4, 1000);
        assert_eq!(tiff_data_end(&m), Ok(Some(1200)));
    }

    #[test]
    fn white_balance_names() {
        assert_eq!(WhiteBalance::from_name("Camera").unwrap(), WhiteBalance::Camera);
        assert!(WhiteBalance::from_name("auto").unwrap_err().to_string().contains("none, camera"));
    }
}

/// Uncompressed DNG raw data read here rather than by `rawloader` 0.37,
/// which reads only the first strip of an uncompressed DNG as if all strips
/// were contiguous, cannot read uncompressed tiles (phones' linear DNGs are
/// tiled), reads 16-bit samples as little-endian whatever the file's byte
/// order, and keeps one black and white level for all three channels of a
/// `LinearRaw` file. For LJPEG-compressed DNGs (compression 7, as phones'
/// "pro RAW" modes write them: tiled LinearRaw; T.81 process 14) `rawloader`
/// decodes the data — predictor 1 only, which is checked here first — and
/// [`dng::levels`] corrects the per-channel levels
/// (`calib/tests/raw_dng_phone.rs` encodes such tiles and reads them back).
/// Other compressions (Deflate, lossy JPEG, JPEG XL) are refused by name.
/// Opcode lists (`OpcodeList1–3`: gain maps, lens warps, bad-pixel fixes
/// written by phones) are not applied; [`dng::notes`] reports them.
mod dng {
    use super::tiff_dir::TiffFile;
    use tiff::Directory;

    /// IFD0's tags and the raw image's IFD (NewSubfileType 0 with CFA or
    /// LinearRaw photometric interpretation, in IFD0, its chain or SubIFDs).
    struct Parsed<'a> {
        t: TiffFile<'a>,
        ifd0: Directory,
        raw: Directory,
    }

    fn parse(bytes: &[u8]) -> Option<Parsed<'_>> {
        let t = TiffFile::open(bytes).ok()??;
        let ifd0 = t.first().ok()?;
        if !TiffFile::has(&ifd0, 50706) {
            return None; // no DNGVersion: not a DNG
        }
        let raw = t
            .find(|t, dir| {
                let first = |tag: u16| t.numbers(dir, tag).map(|v| v.first().copied().unwrap_or(0.0) as u32);
                let photometric = first(262)?;
                Ok(first(254)? == 0 && (photometric == 32803 || photometric == 34892))
            })
            .ok()??;
        Some(Parsed { t, ifd0, raw })
    }

    /// The predictor (T.81 Table H.1) in the start-of-scan header of the
    /// raw IFD's first lossless-JPEG tile or strip; `None` when it cannot
    /// be found (`rawloader` then reports what is wrong).
    fn ljpeg_predictor(p: &Parsed) -> Option<u8> {
        let first = |tag: u16| p.t.numbers(&p.raw, tag).ok().and_then(|v| v.first().copied());
        let at = first(324).or_else(|| first(273))? as usize;
        let b = p.t.bytes.get(at..)?;
        if b.get(..2)? != [0xFF, 0xD8] {
            return None;
        }
        // The marker segments after SOI, up to the start of scan.
        let mut segments = &b[2..];
        loop {
            match crate::jpeg::next_segment(&mut segments).ok()? {
                // SOS: Ns, Ns × (Cs, Td/Ta), then Ss = the predictor.
                (0xDA, body) => return body.get(1 + 2 * usize::from(*body.first()?)).copied(),
                (0xD9, _) => return None,
                _ => {}
            }
        }
    }

    /// The raw IFD's levels for three samples per pixel: per-channel black
    /// and white ([r, g, b, b]), if the file is a linear DNG.
    pub(super) fn levels(bytes: &[u8]) -> Option<([u16; 4], [u16; 4])> {
        let p = parse(bytes)?;
        // An unreadable tag leaves `rawloader`'s levels in place (`None`), never defaults.
        let get = |tag: u16| p.t.numbers(&p.raw, tag).ok();
        if get(277)?.first().copied().unwrap_or(1.0) as usize != 3 {
            return None;
        }
        Some(per_sample(&get(50714)?, &get(50717)?, 3))
    }

    fn per_sample(black: &[f64], white: &[f64], cpp: usize) -> ([u16; 4], [u16; 4]) {
        let pick = |v: &[f64], k: usize, default: f64| {
            let x = if v.len() >= cpp && cpp > 1 { v[k.min(cpp - 1)] } else { v.first().copied().unwrap_or(default) };
            x.round().clamp(0.0, 65535.0) as u16
        };
        let black = if cpp == 1 && black.len() >= 4 {
            std::array::from_fn(|k| black[k].round().clamp(0.0, 65535.0) as u16)
        } else {
            std::array::from_fn(|k| pick(black, k, 0.0))
        };
        (black, std::array::from_fn(|k| pick(white, k, 65535.0)))
    }

    /// The raw IFD's (else IFD0's) NoiseProfile values, if any.
    pub(super) fn noise_profile(bytes: &[u8]) -> Option<Vec<f64>> {
        let p = parse(bytes)?;
        [&p.raw, &p.ifd0]
            .into_iter()
            .filter(|d| TiffFile::has(d, 51041))
            .find_map(|d| p.t.numbers(d, 51041).ok().filter(|v| !v.is_empty()))
    }

    /// What is in the file but not applied, for the metadata's warnings.
    pub(super) fn notes(bytes: &[u8]) -> Vec<String> {
        let Some(p) = parse(bytes) else { return Vec::new() };
        let mut out = Vec::new();
        for (tag, name) in [(51008u16, "OpcodeList1"), (51009, "OpcodeList2"), (51022, "OpcodeList3")] {
            let count = TiffFile::count(&p.raw, tag).max(TiffFile::count(&p.ifd0, tag));
            if count > 0 {
                out.push(format!(
                    "{name} ({count} bytes) ignored: its corrections (gain maps / lens shading, lens warp, bad pixels) are not applied"
                ));
            }
        }
        if TiffFile::has(&p.raw, 50719) || TiffFile::has(&p.raw, 50720) {
            out.push("DefaultCrop ignored: the output is the whole active area".into());
        }
        out
    }

    /// The raw image of an uncompressed DNG (strips or tiles, 8 or 16 bits,
    /// either byte order, CFA or LinearRaw); `Ok(None)` for other files
    /// (not a DNG, or compressed: `rawloader`'s). `header_only`: everything
    /// but the samples (the data is left empty; the tags and the strip or
    /// tile layout are still read and checked), for [`super::raw_output_size`].
    pub(super) fn decode_uncompressed(bytes: &[u8], header_only: bool) -> Result<Option<rawloader::RawImage>, String> {
        let Some(p) = parse(bytes) else { return Ok(None) };
        if rawloaders_compression(&p)? {
            return Ok(None);
        }
        let need =
            |tag: u16, name: &str| first(&p, &p.raw, tag)?.ok_or_else(|| format!("DNG raw image without {name}"));
        let (w, h) = (need(256, "ImageWidth")? as usize, need(257, "ImageLength")? as usize);
        let layout = sample_layout(&p)?;
        if w == 0 || h == 0 || w > 1 << 16 || h > 1 << 16 {
            return Err(format!("DNG raw image size {w} × {h}"));
        }
        let table = values(&p, &p.raw, 50712)?; // Linearization
        let blocks = data_blocks(&p, w, h)?;
        // The samples (none for `header_only`).
        let data = if header_only { Vec::new() } else { read_samples(&p, &blocks, &table, w, h, layout)? };
        let (make, model, wb_coeffs, xyz_to_cam) = colour_tags(&p)?;
        let cfa = if layout.linear { rawloader::CFA::new("") } else { bayer_pattern(&p)? };
        let (black, white) = per_sample(&values(&p, &p.raw, 50714)?, &values(&p, &p.raw, 50717)?, layout.cpp);
        let crops = active_area_crops(&values(&p, &p.raw, 50829)?, w, h)?;
        let orientation = values(&p, &p.ifd0, 274)?
            .first()
            .map_or(rawloader::Orientation::Unknown, |v| rawloader::Orientation::from_u16(*v as u16));
        Ok(Some(rawloader::RawImage {
            make: make.clone(),
            model: model.clone(),
            clean_make: make,
            clean_model: model,
            width: w,
            height: h,
            cpp: layout.cpp,
            wb_coeffs,
            whitelevels: white,
            blacklevels: black,
            xyz_to_cam,
            cfa,
            crops,
            blackareas: Vec::new(),
            orientation,
            data: rawloader::RawImageData::Integer(data),
        }))
    }

    /// A tag's numbers in directory `d`, its read error said with the tag.
    fn values(p: &Parsed, d: &Directory, tag: u16) -> Result<Vec<f64>, String> {
        p.t.numbers(d, tag).map_err(|e| format!("DNG tag {tag} cannot be read: {e}"))
    }

    /// A tag's first number in directory `d`, if it has one.
    fn first(p: &Parsed, d: &Directory, tag: u16) -> Result<Option<f64>, String> {
        values(p, d, tag).map(|v| v.first().copied())
    }

    /// Whether the raw image is lossless JPEG that `rawloader` decodes
    /// (compression 7, predictor 1); `false` for uncompressed data, an
    /// error naming any other compression.
    fn rawloaders_compression(p: &Parsed) -> Result<bool, String> {
        match first(p, &p.raw, 259)?.unwrap_or(1.0) as u32 {
            1 => Ok(false),
            // Lossless JPEG (ITU-T T.81 process 14): `rawloader` decodes it, predictor 1 only.
            7 => match ljpeg_predictor(p) {
                Some(1) | None => Ok(true),
                Some(k) => Err(format!(
                    "lossless-JPEG DNG (compression 7) with predictor {k}: only predictor 1 (the sample to \
                     the left, what phones and Adobe's DNG SDK write) is decoded; convert it with Adobe DNG \
                     Converter (uncompressed) first"
                )),
            },
            c => {
                let name = match c {
                    8 | 32946 => "Deflate",
                    34892 => "lossy JPEG",
                    52546 => "JPEG XL",
                    _ => "unknown",
                };
                Err(format!(
                    "DNG raw image with compression {c} ({name}): lucent reads uncompressed (1) and lossless-JPEG \
                     (7) DNGs; convert it with Adobe DNG Converter (compatibility DNG 1.4, uncompressed) first"
                ))
            }
        }
    }

    /// How the samples are stored: per pixel, in bytes, LinearRaw or CFA.
    #[derive(Clone, Copy)]
    struct SampleLayout {
        cpp: usize,
        bytes_per: usize,
        linear: bool,
    }

    fn sample_layout(p: &Parsed) -> Result<SampleLayout, String> {
        let cpp = first(p, &p.raw, 277)?.unwrap_or(1.0) as usize;
        let bps = first(p, &p.raw, 258)?.unwrap_or(1.0) as usize;
        let photometric = first(p, &p.raw, 262)?;
        let linear = photometric == Some(34892.0);
        if !(cpp == 1 && !linear || cpp == 3 && linear) {
            return Err(format!(
                "DNG raw image with {cpp} samples per pixel and photometric interpretation {} (expected 1 for CFA, 3 for LinearRaw)",
                photometric.unwrap_or(0.0)
            ));
        }
        if first(p, &p.raw, 284)?.unwrap_or(1.0) as u32 != 1 {
            return Err("DNG raw image with planar (not interleaved) samples".into());
        }
        if bps != 8 && bps != 16 {
            return Err(format!("uncompressed DNG with {bps} bits per sample (8 and 16 are read)"));
        }
        Ok(SampleLayout { cpp, bytes_per: bps / 8, linear })
    }

    /// A block of stored samples: (offset, x0, y0, block width, block
    /// height, stored row length in pixels).
    type Block = (usize, usize, usize, usize, usize, usize);

    /// The tiles or strips of a `w` × `h` image, checked against its size.
    fn data_blocks(p: &Parsed, w: usize, h: usize) -> Result<Vec<Block>, String> {
        let mut blocks = Vec::new();
        if let (true, Some(tw), Some(tl)) = (TiffFile::has(&p.raw, 324), first(p, &p.raw, 322)?, first(p, &p.raw, 323)?)
        {
            let (tw, tl) = (tw as usize, tl as usize);
            if tw == 0 || tl == 0 {
                return Err("DNG tile size 0".into());
            }
            let (across, down) = (w.div_ceil(tw), h.div_ceil(tl));
            let offs = values(p, &p.raw, 324)?;
            if offs.len() != across * down {
                return Err(format!("DNG with {} tile offsets for {across} × {down} tiles", offs.len()));
            }
            for (k, o) in offs.iter().enumerate() {
                let (x0, y0) = ((k % across) * tw, (k / across) * tl);
                blocks.push((*o as usize, x0, y0, tw.min(w - x0), tl.min(h - y0), tw));
            }
        } else if TiffFile::has(&p.raw, 273) {
            let rows = first(p, &p.raw, 278)?.map_or(h, |r| (r as usize).clamp(1, h));
            let offs = values(p, &p.raw, 273)?;
            if offs.len() != h.div_ceil(rows) {
                return Err(format!("DNG with {} strip offsets for {} strips", offs.len(), h.div_ceil(rows)));
            }
            for (k, o) in offs.iter().enumerate() {
                blocks.push((*o as usize, 0, k * rows, w, rows.min(h - k * rows), w));
            }
        } else {
            return Err("DNG raw image without strip or tile offsets".into());
        }
        Ok(blocks)
    }

    /// The samples of every block, through the Linearization table if there is one.
    fn read_samples(
        p: &Parsed,
        blocks: &[Block],
        table: &[f64],
        w: usize,
        h: usize,
        l: SampleLayout,
    ) -> Result<Vec<u16>, String> {
        let t = &p.t;
        let sample = |o: usize| -> Option<u16> {
            let v = if l.bytes_per == 2 { t.u16_at(o)? } else { u16::from(*t.bytes.get(o)?) };
            Some(if table.is_empty() {
                v
            } else {
                table[usize::from(v).min(table.len() - 1)].clamp(0.0, 65535.0) as u16
            })
        };
        let short = || "image data runs past the end of the file (truncated)".to_string();
        let cpp = l.cpp;
        let mut data = vec![0u16; w * h * cpp];
        for &(o, x0, y0, bw, bh, stride) in blocks {
            for y in 0..bh {
                for x in 0..bw {
                    for c in 0..cpp {
                        let at = o + ((y * stride + x) * cpp + c) * l.bytes_per;
                        data[((y0 + y) * w + x0 + x) * cpp + c] = sample(at).ok_or_else(short)?;
                    }
                }
            }
        }
        Ok(data)
    }

    /// Make, model, white-balance coefficients (1 / AsShotNeutral) and the
    /// XYZ → camera matrix: ColorMatrix2 if present, else ColorMatrix1,
    /// else sRGB's XYZ matrix (as `rawloader`).
    #[allow(clippy::type_complexity)]
    fn colour_tags(p: &Parsed) -> Result<(String, String, [f32; 4], [[f32; 3]; 4]), String> {
        let text0 = |tag: u16| p.t.text(&p.ifd0, tag).map_err(|e| format!("DNG tag {tag} cannot be read: {e}"));
        let (make, model) = (text0(271)?, text0(272)?);
        let neutral = values(p, &p.ifd0, 50728)?;
        let wb_coeffs = if neutral.len() >= 3 && neutral[..3].iter().all(|v| *v > 0.0) {
            [(1.0 / neutral[0]) as f32, (1.0 / neutral[1]) as f32, (1.0 / neutral[2]) as f32, f32::NAN]
        } else {
            [f32::NAN; 4]
        };
        let cm =
            if values(p, &p.ifd0, 50722)?.len() >= 9 { values(p, &p.ifd0, 50722)? } else { values(p, &p.ifd0, 50721)? };
        let mut xyz_to_cam = [[0.0f32; 3]; 4];
        if cm.len() >= 9 {
            for k in 0..9 {
                xyz_to_cam[k / 3][k % 3] = cm[k] as f32;
            }
        } else {
            xyz_to_cam[..3].copy_from_slice(&[
                [0.412453, 0.357580, 0.180423],
                [0.212671, 0.715160, 0.072169],
                [0.019334, 0.119193, 0.950227],
            ]);
        }
        Ok((make, model, wb_coeffs, xyz_to_cam))
    }

    /// The 2 × 2 Bayer pattern of CFARepeatPatternDim / CFAPattern.
    fn bayer_pattern(p: &Parsed) -> Result<rawloader::CFA, String> {
        let dim = values(p, &p.raw, 33421)?;
        let pat = values(p, &p.raw, 33422)?;
        if dim.len() != 2 || dim[0] != 2.0 || dim[1] != 2.0 || pat.len() != 4 {
            return Err(format!("DNG CFA pattern {pat:?} of repeat {dim:?} (a 2 × 2 Bayer pattern is read)"));
        }
        let name: String = pat
            .iter()
            .map(|c| match *c as u8 {
                0 => Ok('R'),
                1 => Ok('G'),
                2 => Ok('B'),
                other => Err(format!("DNG CFA colour {other} (R, G, B = 0, 1, 2 are read)")),
            })
            .collect::<Result<_, _>>()?;
        Ok(rawloader::CFA::new(&name))
    }

    /// `rawloader`'s crops (top, right, bottom, left) of ActiveArea (top,
    /// left, bottom, right) in a `w` × `h` image; none without the tag.
    fn active_area_crops(area: &[f64], w: usize, h: usize) -> Result<[usize; 4], String> {
        if area.len() != 4 {
            return Ok([0; 4]);
        }
        let [top, left, bottom, right] = [area[0], area[1], area[2], area[3]].map(|v| v as usize);
        if !(top < bottom && left < right && bottom <= h && right <= w) {
            return Err(format!("DNG ActiveArea {area:?} outside the {w} × {h} image"));
        }
        Ok([top, w - right, h - bottom, left])
    }
}
