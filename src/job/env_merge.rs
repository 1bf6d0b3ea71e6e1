//! The env-merge job: [`EnvMergeJob::run`] merges exposure brackets of one
//! view into one HDR radiance map (`lucent env merge`; the merge is
//! [`lucent_calib::hdr`], docs/method.md#camera).
//!
//! The brackets are all of one kind. Linear ones (RAW files decoded to
//! linear camera RGB, their relative exposure t · ISO/100 / N² read from
//! their metadata; linear .exr/.hdr; 16-bit or float .png/.tif) are merged
//! as the weighted mean of value / exposure ([`hdr::merge_linear`]); 8-bit
//! ones (.jpg, 8-bit .png/.tif) have their inverse camera response
//! recovered first (Debevec & Malik or Robertson) and are merged in the log
//! domain ([`hdr::merge_8bit_recovered`]). The job's `exposures` (relative,
//! one per bracket) override the RAW metadata; other brackets need them.
//!
//! It writes, named after the job's `out` ([`EnvMergeFiles`]), all or none:
//! * `NAME.exr` — the merged map, 32-bit float RGB: bracket value per unit
//!   exposure (RAW: 1.0 = the white level at exposure 1), or for 8-bit
//!   brackets relative radiance (one global factor unknown);
//! * `NAME.json` — [`EnvMergeReport`]: the output's and brackets' names, the
//!   [`hdr::MergeReport`] (dynamic range reached and capturable, in stops;
//!   pixels saturated or below the noise floor in every bracket), the
//!   recovered response of 8-bit brackets and the units;
//! * `NAME_saturated.png` — white where a pixel is saturated in every
//!   bracket (its value is a lower bound).

use super::context::Context;
use super::fields::{bad, by_name, s, JobError, Line};
use super::images::{file_name, to_buffer, to_image};
use crate::imageio::{self, extension, ImageIoError, RgbImage, RAW_EXTENSIONS};
use crate::io::{json_bytes, WriteError};
use crate::text::serde_as_text;
use lucent_calib::error::CalibError;
use lucent_calib::hdr::{
    self, CodeWeights, HdrError, LinearWeights, MergeReport, Response, ResponseMethod, Rgb8Buffer,
};
use lucent_calib::raw::{self, RawError, RawOptions};
use lucent_calib::scene::sibling;
use lucent_calib::{cv, BufferSizeError, RgbBuffer};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// `lucent env merge`: exposure brackets → one HDR map
/// ([`EnvMergeJob::run`]). The keys at their defaults may be left out of a
/// job file and are not written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EnvMergeJob {
    /// The brackets (at least two), all the same size and aligned.
    pub brackets: Vec<PathBuf>,
    /// `--exposures`: the relative exposure of each bracket, in order
    /// ("1/1000,1/250,1/60" as text); else from the RAW files' metadata.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exposures: Option<Exposures>,
    /// The merged map (.exr); its report and saturation mask go beside it.
    pub out: PathBuf,
    /// `--method`: camera-response recovery of 8-bit brackets.
    #[serde(default = "defaults::method", with = "by_name", skip_serializing_if = "defaults::is_method")]
    pub method: ResponseMethod,
    /// `--saturation`: linear brackets: saturated where the largest channel reaches this.
    #[serde(default = "defaults::saturation", skip_serializing_if = "defaults::is_saturation")]
    pub saturation: f32,
    /// `--noise-floor`: linear brackets: noise below this (weights rise to twice it).
    #[serde(default = "defaults::noise_floor", skip_serializing_if = "defaults::is_noise_floor")]
    pub noise_floor: f32,
    /// `--saturation-code`: 8-bit brackets: saturated at or above this code.
    #[serde(default = "defaults::saturation_code", skip_serializing_if = "defaults::is_saturation_code")]
    pub saturation_code: u8,
    /// `--floor-code`: 8-bit brackets: noise at or below this code.
    #[serde(default = "defaults::floor_code", skip_serializing_if = "defaults::is_floor_code")]
    pub floor_code: u8,
}

/// The defaults of `lucent env merge`'s weights (those of
/// [`LinearWeights`] and [`CodeWeights`]) and response method.
pub mod defaults {
    use lucent_calib::hdr::ResponseMethod;

    pub const METHOD: ResponseMethod = ResponseMethod::Debevec;
    pub const SATURATION: f32 = 0.98;
    pub const NOISE_FLOOR: f32 = 0.002;
    pub const SATURATION_CODE: u8 = 250;
    pub const FLOOR_CODE: u8 = 5;

    pub(super) fn method() -> ResponseMethod {
        METHOD
    }
    pub(super) fn is_method(m: &ResponseMethod) -> bool {
        *m == METHOD
    }
    pub(super) fn saturation() -> f32 {
        SATURATION
    }
    pub(super) fn is_saturation(v: &f32) -> bool {
        *v == SATURATION
    }
    pub(super) fn noise_floor() -> f32 {
        NOISE_FLOOR
    }
    pub(super) fn is_noise_floor(v: &f32) -> bool {
        *v == NOISE_FLOOR
    }
    pub(super) fn saturation_code() -> u8 {
        SATURATION_CODE
    }
    pub(super) fn is_saturation_code(v: &u8) -> bool {
        *v == SATURATION_CODE
    }
    pub(super) fn floor_code() -> u8 {
        FLOOR_CODE
    }
    pub(super) fn is_floor_code(v: &u8) -> bool {
        *v == FLOOR_CODE
    }

    #[cfg(test)]
    mod tests {
        use super::*;
        use lucent_calib::hdr::{CodeWeights, LinearWeights};

        #[test]
        fn the_defaults_are_the_librarys() {
            assert_eq!(LinearWeights::default(), LinearWeights { saturation: SATURATION, noise_floor: NOISE_FLOOR });
            assert_eq!(CodeWeights::default(), CodeWeights { saturation: SATURATION_CODE, floor: FLOOR_CODE });
        }
    }
}

impl EnvMergeJob {
    /// The brackets into `out`, their exposures from their metadata and
    /// every other flag at its default.
    pub fn new(brackets: Vec<PathBuf>, out: PathBuf) -> Self {
        EnvMergeJob {
            brackets,
            exposures: None,
            out,
            method: defaults::METHOD,
            saturation: defaults::SATURATION,
            noise_floor: defaults::NOISE_FLOOR,
            saturation_code: defaults::SATURATION_CODE,
            floor_code: defaults::FLOOR_CODE,
        }
    }

    /// At least two brackets, and one exposure per bracket when they are
    /// given. (The weights are checked by the merge of the brackets' kind,
    /// which uses only its own.)
    pub fn validate(&self) -> Result<(), JobError> {
        if self.brackets.len() < 2 {
            return Err(bad("brackets", self.brackets.len(), "give at least two brackets to merge"));
        }
        if let Some(e) = &self.exposures
            && e.len() != self.brackets.len()
        {
            return Err(bad(
                "exposures",
                e,
                format!(
                    "{} values for {} brackets; give one exposure per bracket, in order",
                    e.len(),
                    self.brackets.len()
                ),
            ));
        }
        Ok(())
    }

    pub fn to_args(&self) -> Vec<String> {
        let mut l = Line::new(&["env", "merge"]);
        l.words(self.brackets.iter().map(|b| s(b)));
        if let Some(e) = &self.exposures {
            l.word(format!("--exposures={e}"));
        }
        l.flag("--out", s(&self.out));
        if !defaults::is_method(&self.method) {
            l.flag("--method", self.method.name());
        }
        if !defaults::is_saturation(&self.saturation) {
            l.word(format!("--saturation={}", self.saturation));
        }
        if !defaults::is_noise_floor(&self.noise_floor) {
            l.word(format!("--noise-floor={}", self.noise_floor));
        }
        if !defaults::is_saturation_code(&self.saturation_code) {
            l.flag("--saturation-code", self.saturation_code);
        }
        if !defaults::is_floor_code(&self.floor_code) {
            l.flag("--floor-code", self.floor_code);
        }
        l.0
    }
}

/// The relative exposures of brackets, one per bracket in order: positive
/// numbers or fractions.
///
/// As text "1/1000,1/250,1/60" (each written back in its shortest form, a
/// fraction kept as one: " 1 / 250" is written "1/250").
///
/// ```
/// use lucent::job::Exposures;
/// let e: Exposures = "1/1000, 1/250,0.5".parse().unwrap();
/// assert_eq!(e.values(), vec![0.001, 0.004, 0.5]);
/// assert_eq!(e.to_string(), "1/1000,1/250,0.5");
/// assert!("1,-4".parse::<Exposures>().unwrap_err().to_string().contains("\"-4\" is not a positive number"));
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct Exposures(Vec<(String, f64)>);

/// Exposures written as text that are not ([`Exposures`]).
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("{text:?}: {part:?} is not a positive number or fraction (e.g. 1/250)")]
pub struct ExposuresError {
    pub text: String,
    pub part: String,
}

impl Exposures {
    /// The exposures, in order.
    pub fn values(&self) -> Vec<f64> {
        self.0.iter().map(|(_, v)| *v).collect()
    }

    /// How many exposures.
    pub fn len(&self) -> usize {
        self.0.len()
    }

    /// Whether there are none (never, once read).
    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// One exposure "1/250", "0.004" or "2" (any relative unit): its text in
/// its shortest form and its value; `None` unless a positive finite number.
pub fn parse_exposure(text: &str) -> Option<(String, f64)> {
    let t = text.trim();
    let (canonical, v) = match t.split_once('/') {
        Some((a, b)) => {
            let (a, b) = (a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?);
            (format!("{a}/{b}"), a / b)
        }
        None => {
            let v = t.parse::<f64>().ok()?;
            (format!("{v}"), v)
        }
    };
    (v.is_finite() && v > 0.0).then_some((canonical, v))
}

impl std::str::FromStr for Exposures {
    type Err = ExposuresError;

    fn from_str(text: &str) -> Result<Self, ExposuresError> {
        text.split(',')
            .map(|part| parse_exposure(part).ok_or_else(|| ExposuresError { text: text.into(), part: part.into() }))
            .collect::<Result<Vec<_>, _>>()
            .map(Exposures)
    }
}

impl std::fmt::Display for Exposures {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let texts: Vec<&str> = self.0.iter().map(|(t, _)| t.as_str()).collect();
        f.write_str(&texts.join(","))
    }
}

serde_as_text!(Exposures);

/// The files of a merge, each name spelled here once: the map (`exr`, the
/// job's `out`), beside it its report (`json`, `NAME.json`) and the mask of
/// pixels saturated in every bracket (`saturated_png`, `NAME_saturated.png`).
///
/// ```
/// use lucent::job::EnvMergeFiles;
/// let f = EnvMergeFiles::of(std::path::Path::new("env/hdr.exr"));
/// assert_eq!(f.json, std::path::Path::new("env/hdr.json"));
/// assert_eq!(f.saturated_png, std::path::Path::new("env/hdr_saturated.png"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EnvMergeFiles {
    pub exr: PathBuf,
    pub json: PathBuf,
    pub saturated_png: PathBuf,
}

impl EnvMergeFiles {
    /// The files of the merge whose map is `exr`.
    pub fn of(exr: &Path) -> Self {
        Self { exr: exr.to_path_buf(), json: sibling(exr, ".json"), saturated_png: sibling(exr, "_saturated.png") }
    }
}

/// `NAME.json` of a merge: what was merged and what the merge reached.
/// Written as a JSON value ([`EnvMergeReport::to_json`]: its keys and
/// those of the report sorted, its numbers as `f64`), as it always was.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvMergeReport {
    /// The file name of the merged map.
    pub output: String,
    /// The file names of the brackets, in order.
    pub brackets: Vec<String>,
    pub report: MergeReport,
    /// The recovered inverse response (8-bit brackets; `null` for linear ones).
    pub response: Option<Response>,
    /// The file name of the mask of pixels saturated in every bracket.
    pub saturated_mask: String,
    /// What a value of the map is.
    pub units: String,
}

impl EnvMergeReport {
    /// The text of `NAME.json` (`path`), through a [`serde_json::Value`].
    pub fn to_json(&self, path: &Path) -> Result<Vec<u8>, WriteError> {
        let value = serde_json::to_value(self)
            .map_err(|e| WriteError { path: path.to_path_buf(), source: std::io::Error::other(e) })?;
        json_bytes(path, &value)
    }
}

/// Why a merge failed; every variant names the bracket, flag or file.
#[derive(Debug, Error)]
pub enum EnvMergeError {
    #[error("bracket {}: the same file as {} (each bracket is one exposure)", path.display(), first.display())]
    SameFile { path: PathBuf, first: PathBuf },
    /// A bracket that cannot be read (the source says why; boxed, the largest error).
    #[error("bracket {}", path.display())]
    Bracket { path: PathBuf, source: Box<BracketError> },
    #[error(
        "bracket {}: value {value} at pixel ({x}, {y}) is negative; linear brackets hold light (≥ 0)",
        path.display()
    )]
    Negative { path: PathBuf, value: f32, x: usize, y: usize },
    #[error("the brackets mix linear ({linear}) and 8-bit ({eight}) files; merge one kind at a time")]
    MixedKinds { linear: String, eight: String },
    #[error("no exposure recorded for {files}: give --exposures (one per bracket, e.g. 1/1000,1/250,1/60)")]
    NoExposure { files: String },
    /// A bracket of another size than the first (the message names it).
    #[error("{}", path.display())]
    Size { path: PathBuf, source: HdrError },
    #[error(transparent)]
    Merge(#[from] HdrError),
    #[error(transparent)]
    Image(#[from] ImageIoError),
    #[error(transparent)]
    Write(#[from] WriteError),
}

/// Why one bracket cannot be read.
#[derive(Debug, Error)]
pub enum BracketError {
    #[error("{}: no such file", .0.display())]
    NoSuchFile(PathBuf),
    #[error(transparent)]
    Raw(#[from] RawError),
    #[error(transparent)]
    Image(#[from] ImageIoError),
    #[error(transparent)]
    Jpeg(#[from] CalibError),
    #[error("{}: cannot open", path.display())]
    Open { path: PathBuf, source: std::io::Error },
    #[error("{}: cannot read", path.display())]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{}: cannot read image: {error}", path.display())]
    Decode { path: PathBuf, error: image::ImageError },
    #[error(transparent)]
    Buffer(#[from] BufferSizeError),
    #[error("{}: unsupported bracket format (RAW, .exr, .hdr, .png, .tif, .tiff, .jpg or .jpeg)", .0.display())]
    Format(PathBuf),
}

/// What a merge wrote and reached.
pub struct EnvMergeRun {
    /// The files written.
    pub files: EnvMergeFiles,
    /// `NAME.json`.
    pub report: EnvMergeReport,
}

impl EnvMergeRun {
    /// What `lucent env merge` prints on its standard output.
    pub fn summary(&self) -> Vec<String> {
        let rep = &self.report.report;
        vec![format!(
            "{} {} brackets ({} × {}) → {}: dynamic range {:.1} stops (the bracket set can capture {:.1}); \
             {} pixels saturated in every bracket{}, {} below the noise floor in every bracket; report {}",
            self.report.brackets.len(),
            rep.mode,
            rep.width,
            rep.height,
            self.files.exr.display(),
            rep.dynamic_range_stops,
            rep.capturable_range_stops,
            rep.saturated_in_every_bracket,
            if rep.saturated_in_every_bracket > 0 {
                format!(" (mask {})", self.files.saturated_png.display())
            } else {
                String::new()
            },
            rep.below_floor_in_every_bracket,
            self.files.json.display()
        )]
    }
}

type E = EnvMergeError;

/// A bracket as read: linear (with its exposure from metadata, if any) or 8-bit codes.
enum Bracket {
    Linear(RgbBuffer, Option<f64>),
    Codes(Rgb8Buffer),
}

impl EnvMergeJob {
    /// Reads the brackets, merges them and writes the map, its report and
    /// its saturation mask ([`EnvMergeFiles`]); a map that is not 2:1 is
    /// noted (the `lucent env` commands that need an equirectangular map
    /// refuse it).
    pub fn run(&self, ctx: &Context) -> Result<EnvMergeRun, E> {
        // One file given twice (under two spellings) would weigh one exposure twice.
        let mut seen: Vec<(PathBuf, &Path)> = Vec::new();
        for p in &self.brackets {
            let key = std::fs::canonicalize(p).unwrap_or_else(|_| p.clone());
            if let Some((_, first)) = seen.iter().find(|(k, _)| *k == key) {
                return Err(E::SameFile { path: p.clone(), first: first.to_path_buf() });
            }
            seen.push((key, p));
        }
        let (mut linear, mut eight, mut meta_exposures) = (Vec::new(), Vec::new(), Vec::new());
        for p in &self.brackets {
            match read_bracket(p).map_err(|e| E::Bracket { path: p.clone(), source: Box::new(e) })? {
                Bracket::Linear(img, t) => {
                    // Linear values are light: a negative one is no exposure of a scene.
                    if let Some(i) = img.data.iter().position(|v| *v < 0.0) {
                        let px = i / 3;
                        return Err(E::Negative {
                            path: p.clone(),
                            value: img.data[i],
                            x: px % img.width,
                            y: px / img.width,
                        });
                    }
                    linear.push((p, img));
                    meta_exposures.push(t);
                }
                Bracket::Codes(img) => eight.push((p, img)),
            }
        }
        if let (Some((l, _)), Some((e, _))) = (linear.first(), eight.first()) {
            return Err(E::MixedKinds { linear: file_name(l), eight: file_name(e) });
        }
        let exposures = match &self.exposures {
            Some(e) => e.values(),
            None => {
                let missing: Vec<String> = self
                    .brackets
                    .iter()
                    .zip(meta_exposures.iter().chain(std::iter::repeat(&None)))
                    .filter(|(_, t)| t.is_none())
                    .map(|(p, _)| file_name(p))
                    .collect();
                if !missing.is_empty() {
                    return Err(E::NoExposure { files: missing.join(", ") });
                }
                meta_exposures.iter().map(|t| t.unwrap_or(1.0)).collect()
            }
        };
        let size_err = |e: HdrError| match e {
            HdrError::SizeMismatch { index, .. } => E::Size { path: self.brackets[index].clone(), source: e },
            other => other.into(),
        };
        let (merged, response) = if eight.is_empty() {
            let w = LinearWeights { saturation: self.saturation, noise_floor: self.noise_floor };
            let imgs: Vec<RgbBuffer> = linear.into_iter().map(|(_, i)| i).collect();
            (hdr::merge_linear(&imgs, &exposures, &w).map_err(size_err)?, None)
        } else {
            let w = CodeWeights { saturation: self.saturation_code, floor: self.floor_code };
            let imgs: Vec<Rgb8Buffer> = eight.into_iter().map(|(_, i)| i).collect();
            let (m, r) = hdr::merge_8bit_recovered(&imgs, &exposures, self.method, &w).map_err(size_err)?;
            (m, Some(r))
        };
        let files = EnvMergeFiles::of(&self.out);
        let units = if response.is_some() {
            "relative radiance (8-bit: the response is known up to one global factor)"
        } else {
            "bracket values / relative exposure (RAW: 1.0 = white level at exposure 1)"
        };
        let report = EnvMergeReport {
            brackets: self.brackets.iter().map(|p| file_name(p)).collect(),
            output: file_name(&files.exr),
            report: merged.report,
            response,
            saturated_mask: file_name(&files.saturated_png),
            units: units.into(),
        };
        let (width, height) = (report.report.width, report.report.height);
        let mask = RgbImage {
            width,
            height,
            data: merged.saturated_mask.iter().flat_map(|&s| [if s { 1.0f32 } else { 0.0 }; 3]).collect(),
        };
        // The map, its JSON and its saturation mask are one output: all or none.
        crate::io::write_files_atomic(&[
            (&files.saturated_png, &imageio::encode_png(&files.saturated_png, &mask)?),
            (&files.json, &report.to_json(&files.json)?),
            (&files.exr, &imageio::encode_exr(&files.exr, &to_image(merged.image))?),
        ])?;
        if width != 2 * height {
            ctx.note(&format!(
                "{width} × {height} is not 2:1; `lucent env` commands that need an equirectangular map will refuse it"
            ));
        }
        Ok(EnvMergeRun { files, report })
    }
}

fn read_bracket(path: &Path) -> Result<Bracket, BracketError> {
    let e = extension(path);
    if !path.is_file() {
        return Err(BracketError::NoSuchFile(path.to_path_buf()));
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
        "jpg" | "jpeg" => Ok(Bracket::Codes(codes(cv::read_rgb8(path)?))),
        "png" | "tif" | "tiff" => {
            let img = image::ImageReader::open(path)
                .map_err(|source| BracketError::Open { path: path.to_path_buf(), source })?
                .with_guessed_format()
                .map_err(|source| BracketError::Read { path: path.to_path_buf(), source })?
                .decode()
                .map_err(|error| BracketError::Decode { path: path.to_path_buf(), error })?;
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
        _ => Err(BracketError::Format(path.to_path_buf())),
    }
}

/// 8-bit values read as v/255 back to codes (exact).
fn codes(img: RgbBuffer) -> Rgb8Buffer {
    let data = img.data.iter().map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8).collect();
    Rgb8Buffer { width: img.width, height: img.height, data }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exposures_read_fractions_and_name_a_bad_one() {
        let e: Exposures = "1/16, 1 / 4,1,4.0,1e1".parse().unwrap();
        assert_eq!(e.values(), vec![1.0 / 16.0, 0.25, 1.0, 4.0, 10.0]);
        assert_eq!(e.to_string(), "1/16,1/4,1,4,10");
        assert_eq!(e.to_string().parse::<Exposures>().unwrap(), e);
        for (text, part) in [("1,-4", "-4"), ("1,,2", ""), ("1/0,2", "1/0"), ("x", "x"), ("1,nan", "nan")] {
            let err = text.parse::<Exposures>().unwrap_err();
            assert_eq!(err, ExposuresError { text: text.into(), part: part.into() }, "{text}");
        }
    }

    #[test]
    fn a_merge_job_refuses_a_count_of_exposures_that_is_not_the_brackets() {
        let mut job = EnvMergeJob::new(vec!["a.png".into(), "b.png".into()], "m.exr".into());
        assert!(job.validate().is_ok());
        job.exposures = Some("1,4,16".parse().unwrap());
        let e = job.validate().unwrap_err();
        assert_eq!(
            e.to_string(),
            "--exposures 1,4,16: 3 values for 2 brackets; give one exposure per bracket, in order"
        );
        job.brackets.pop();
        assert_eq!(job.validate().unwrap_err().field, "brackets");
    }
}
