//! `ccm.json`: the colour correction `lucent colour calibrate` fits from a
//! ColorChecker photo, and `lucent colour apply` (and the pipeline's
//! develop and report stages) read back. The one definition of the file's
//! fields: [`CcmFile`] serialises to exactly the JSON earlier versions wrote
//! (field names and order), and [`CcmFile::read`] checks the matrix against
//! the method ([`ColourCorrection::new`]: shape, finite entries), so a
//! hand-edited or truncated file is refused naming the file.
//!
//! The matrix maps t(camera RGB) to CIE XYZ (1931 2°) as under D50, Y of the
//! perfect white = 1 (the `maps` field says so in the file).

use crate::io::{write_json, WriteError};
use lucent_colour::ccm::{CcmMethod, ColourCorrection, PatchResult};
use lucent_colour::chart::SampleOptions;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// The files of `lucent colour calibrate` in its output folder, each name
/// spelled here once: the [`CcmFile`] (`ccm`), the chart measured |
/// corrected | reference (`chart`), the ΔE per patch (`delta_e`) and the
/// sampled areas (`patches`). Written by the command, read by `lucent run`'s
/// planning and report.
///
/// ```
/// use lucent::ccm_file::ColourFiles;
/// let f = ColourFiles::in_dir(std::path::Path::new("out/colour/phone"));
/// assert_eq!(f.ccm, std::path::Path::new("out/colour/phone/ccm.json"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ColourFiles {
    pub ccm: PathBuf,
    pub chart: PathBuf,
    pub delta_e: PathBuf,
    pub patches: PathBuf,
}

impl ColourFiles {
    /// The file names.
    pub const NAMES: [&'static str; 4] = ["ccm.json", "chart.png", "delta_e.png", "patches.png"];

    /// The files of the calibration whose output folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [ccm, chart, delta_e, patches] = Self::NAMES.map(|n| dir.join(n));
        Self { ccm, chart, delta_e, patches }
    }
}

/// A ccm.json that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum CcmFileError {
    #[error("{}: cannot read: {source}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{}: not a ccm.json written by `lucent colour calibrate`: {source}", path.display())]
    Format { path: PathBuf, source: serde_json::Error },
    #[error("{}: {source}", path.display())]
    Matrix { path: PathBuf, source: lucent_colour::ColourError },
}

/// How the image values were encoded before calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum InputEncoding {
    /// Linear values used as read.
    Linear,
    /// sRGB-encoded values, linearised with the inverse sRGB transfer function.
    Srgb,
}

/// One patch in ccm.json.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CcmPatch {
    /// Patch number, name, camera RGB, fitted and reference XYZ and L*a*b*, ΔE00, ΔE*ab.
    #[serde(flatten)]
    pub fit: PatchResult,
    /// Standard deviation of the sampled pixels per channel (after the trim).
    pub camera_rgb_std_dev: [f64; 3],
    /// Pixels sampled.
    pub pixels: usize,
}

/// The content of ccm.json.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CcmFile {
    pub camera: String,
    pub image: String,
    /// TL, TR, BR, BL outer corners of the patch grid, pixels.
    pub corners: [[f64; 2]; 4],
    /// The corners were found by OpenCV's mcc detector, not given with --corners.
    #[serde(default)]
    pub corners_detected: bool,
    pub method: CcmMethod,
    pub method_description: String,
    /// Terms t(RGB) the matrix columns multiply.
    pub terms: Vec<String>,
    /// XYZ = matrix · t(camera RGB): 3 rows (X, Y, Z).
    pub matrix: Vec<Vec<f64>>,
    pub maps: String,
    pub input_encoding: InputEncoding,
    pub reference_set: String,
    pub illuminant: String,
    pub white_xyz: [f64; 3],
    pub observer: String,
    pub sampling: SampleOptions,
    pub de2000_mean: f64,
    pub de2000_max: f64,
    pub de76_mean: f64,
    pub de76_max: f64,
    pub patches: Vec<CcmPatch>,
}

impl CcmFile {
    /// Reads and checks `path`; also returns the correction it describes.
    pub fn read(path: &Path) -> Result<(CcmFile, ColourCorrection), CcmFileError> {
        let text =
            crate::io::read_text(path).map_err(|source| CcmFileError::Read { path: path.to_path_buf(), source })?;
        let file: CcmFile =
            serde_json::from_str(&text).map_err(|source| CcmFileError::Format { path: path.to_path_buf(), source })?;
        let ccm = ColourCorrection::new(file.method, file.matrix.clone())
            .map_err(|source| CcmFileError::Matrix { path: path.to_path_buf(), source })?;
        Ok((file, ccm))
    }

    /// Writes the file (pretty JSON, atomically).
    pub fn write(&self, path: &Path) -> Result<(), WriteError> {
        write_json(path, self)
    }
}

/// The space `colour apply` writes a camera image into.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    strum::EnumString,
    strum::IntoStaticStr,
    strum::VariantNames,
    strum::VariantArray,
    strum::EnumMessage,
)]
#[strum(ascii_case_insensitive)]
pub enum ApplyTarget {
    /// CIE 1931 RGB, white E.
    #[strum(to_string = "cie-rgb", serialize = "ciergb", serialize = "cie1931rgb", serialize = "cie-1931-rgb")]
    CieRgb,
    /// CIE XYZ, D50-adapted as fitted.
    #[strum(to_string = "xyz")]
    Xyz,
    /// Linear sRGB, D65.
    #[strum(to_string = "srgb", serialize = "rec709", serialize = "linear-srgb")]
    Srgb,
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIXTURE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/formats/ccm.json");

    /// A ccm.json written by `lucent colour calibrate` before this module
    /// existed reads back, and writes back byte for byte.
    #[test]
    fn fixture_reads_and_writes_back_unchanged() {
        let (file, ccm) = CcmFile::read(Path::new(FIXTURE)).unwrap();
        assert_eq!(file.method, CcmMethod::Cheung2004);
        assert_eq!(file.patches.len(), 24);
        assert_eq!(ccm.matrix().len(), 3);
        // Same content written back (compared as parsed JSON: serde_json's
        // float parsing may change a last digit), in the same field order.
        let dir = tempfile::tempdir().unwrap();
        let again = dir.path().join("ccm.json");
        file.write(&again).unwrap();
        let (a, b) = (std::fs::read_to_string(&again).unwrap(), std::fs::read_to_string(FIXTURE).unwrap());
        let (va, vb): (serde_json::Value, serde_json::Value) =
            (serde_json::from_str(&a).unwrap(), serde_json::from_str(&b).unwrap());
        assert_eq!(va, vb);
        let keys = |t: &str| {
            t.lines()
                .filter(|l| l.starts_with("  \""))
                .map(|l| l.split(':').next().unwrap().to_string())
                .collect::<Vec<_>>()
        };
        assert_eq!(keys(&a), keys(&b));
    }

    #[test]
    fn a_bad_file_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ccm.json");
        std::fs::write(&p, "{\"camera\": \"x\"}").unwrap();
        let e = CcmFile::read(&p).unwrap_err().to_string();
        assert!(e.contains("ccm.json: not a ccm.json written by `lucent colour calibrate`"), "{e}");
        // The fixture with one matrix row dropped: the shape check names the file.
        let mut v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(FIXTURE).unwrap()).unwrap();
        v["matrix"].as_array_mut().unwrap().pop();
        std::fs::write(&p, v.to_string()).unwrap();
        let e = CcmFile::read(&p).unwrap_err();
        assert!(matches!(e, CcmFileError::Matrix { .. }), "{e:?}");
        assert!(e.to_string().starts_with(&format!("{}: ", p.display())), "{e}");
    }
}
