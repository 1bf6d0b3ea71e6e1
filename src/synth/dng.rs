//! A minimal Bayer DNG writer (Adobe DNG 1.4 specification): one
//! uncompressed 16-bit CFA image in IFD 0 with the tags a DNG reader needs to
//! develop it — CFARepeatPatternDim/CFAPattern, BlackLevel, WhiteLevel,
//! ColorMatrix1 (XYZ → camera) with CalibrationIlluminant1 D50,
//! AsShotNeutral, and, when known, NoiseProfile (the sensor's shot and read
//! noise, [`super::Sensor::noise_profile`]). Written to a temporary file and renamed, so a reader never
//! sees half a file.
//!
//! ```no_run
//! use lucent::synth::dng::{write_cfa_dng, CfaDng};
//! let identity = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
//! let dng = CfaDng {
//!     width: 2, height: 2, data: &[1024, 9000, 9000, 4000], cfa: [0, 1, 1, 2],
//!     black_dn: 1024, white_dn: 16383, xyz_to_camera: identity, as_shot_neutral: [1.0; 3],
//!     model: "Synthetic", noise_profile: Some([5e-5, 1.7e-8]),
//! };
//! write_cfa_dng(std::path::Path::new("tiny.dng"), &dng).unwrap();
//! ```

use crate::io::{write_atomic, WriteError};
use lucent_colour::Mat3;
use std::io::Cursor;
use std::path::Path;
use tiff::encoder::{colortype, Rational, SRational, TiffEncoder};
use tiff::tags::Tag;

/// What goes into the DNG.
#[derive(Debug, Clone)]
pub struct CfaDng<'a> {
    pub width: usize,
    pub height: usize,
    /// Raw values, row-major, `width × height`.
    pub data: &'a [u16],
    /// Colour (0 R, 1 G, 2 B) of the 2 × 2 pattern, row-major from the top-left photosite.
    pub cfa: [u8; 4],
    pub black_dn: u16,
    pub white_dn: u16,
    /// XYZ (D50) → camera RGB, as DNG's ColorMatrix1.
    pub xyz_to_camera: Mat3,
    /// Camera RGB of the scene's white, green = 1.
    pub as_shot_neutral: [f64; 3],
    /// Camera model written to Model and UniqueCameraModel.
    pub model: &'a str,
    /// NoiseProfile (S, O) for all planes: variance = S·x + O, x in [0, 1] of the white level.
    pub noise_profile: Option<[f64; 2]>,
}

impl<'a> CfaDng<'a> {
    /// The DNG of a [`super::Capture`] taken on `sensor` by a camera with this
    /// XYZ (D50) → camera matrix; AsShotNeutral is the camera's D50 white.
    pub fn of_capture(cap: &'a super::Capture, sensor: &super::Sensor, xyz_to_camera: Mat3, model: &'a str) -> Self {
        CfaDng {
            width: cap.width,
            height: cap.height,
            data: &cap.data,
            cfa: sensor.cfa,
            black_dn: sensor.black_dn,
            white_dn: sensor.white_dn,
            xyz_to_camera,
            as_shot_neutral: super::as_shot_neutral(&xyz_to_camera),
            model,
            noise_profile: Some(sensor.noise_profile()),
        }
    }
}

/// Why a DNG could not be written.
#[derive(Debug, thiserror::Error)]
pub enum DngWriteError {
    #[error("{what}: {reason}")]
    Invalid { what: &'static str, reason: String },
    #[error("encoding the DNG: {0}")]
    Tiff(#[from] tiff::TiffError),
    #[error(transparent)]
    Write(#[from] WriteError),
}

fn srational(v: f64) -> SRational {
    SRational { n: (v * 1e6).round() as i32, d: 1_000_000 }
}

/// Encodes `dng` and writes it to `path` atomically.
pub fn write_cfa_dng(path: &Path, dng: &CfaDng) -> Result<(), DngWriteError> {
    if dng.width == 0 || dng.height == 0 || dng.data.len() != dng.width * dng.height {
        return Err(DngWriteError::Invalid {
            what: "mosaic",
            reason: format!("{} values for {} × {} photosites", dng.data.len(), dng.width, dng.height),
        });
    }
    let mut entries = dng.xyz_to_camera.iter().flatten().chain(dng.as_shot_neutral.iter());
    if entries.any(|v| !v.is_finite() || v.abs() > 2000.0) || dng.as_shot_neutral.iter().any(|&v| v <= 0.0) {
        return Err(DngWriteError::Invalid {
            what: "colour tags",
            reason: "ColorMatrix1 entries must be finite (|v| ≤ 2000) and AsShotNeutral positive".into(),
        });
    }
    let mut bytes = Cursor::new(Vec::new());
    {
        let mut enc = TiffEncoder::new(&mut bytes)?;
        let mut img = enc.new_image::<colortype::Gray16>(dng.width as u32, dng.height as u32)?;
        img.rows_per_strip(dng.height as u32)?;
        let e = img.encoder();
        e.write_tag(Tag::NewSubfileType, 0u32)?;
        e.write_tag(Tag::PhotometricInterpretation, 32803u16)?; // CFA
        e.write_tag(Tag::Make, "Lucent")?;
        e.write_tag(Tag::Model, dng.model)?;
        e.write_tag(Tag::Orientation, 1u16)?;
        e.write_tag(Tag::Unknown(33421), &[2u16, 2][..])?; // CFARepeatPatternDim
        e.write_tag(Tag::Unknown(33422), &dng.cfa[..])?; // CFAPattern
        e.write_tag(Tag::Unknown(50706), &[1u8, 4, 0, 0][..])?; // DNGVersion
        e.write_tag(Tag::Unknown(50708), dng.model)?; // UniqueCameraModel
        e.write_tag(Tag::Unknown(50714), u32::from(dng.black_dn))?; // BlackLevel
        e.write_tag(Tag::Unknown(50717), u32::from(dng.white_dn))?; // WhiteLevel
        let cm: Vec<SRational> = dng.xyz_to_camera.iter().flatten().map(|&v| srational(v)).collect();
        e.write_tag(Tag::Unknown(50721), &cm[..])?; // ColorMatrix1
        e.write_tag(Tag::Unknown(50778), 23u16)?; // CalibrationIlluminant1 = D50
        let an: Vec<Rational> =
            dng.as_shot_neutral.iter().map(|&v| Rational { n: (v * 1e6).round() as u32, d: 1_000_000 }).collect();
        e.write_tag(Tag::Unknown(50728), &an[..])?; // AsShotNeutral
        if let Some(p) = dng.noise_profile {
            e.write_tag(Tag::Unknown(51041), &p[..])?; // NoiseProfile (DOUBLE)
        }
        img.write_data(dng.data)?;
    }
    write_atomic(path, bytes.get_ref())?;
    Ok(())
}
