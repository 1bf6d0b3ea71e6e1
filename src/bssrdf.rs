//! The BSSRDF stage (docs/method.md#slab): builds a slab simulation from a recipe (or
//! explicit coefficients), writes the slice and its plots, and compares a
//! simulated slice with a measured one.
//!
//! Files of a run (`lucent bssrdf … --out DIR`):
//!
//! | file | content |
//! |---|---|
//! | `bssrdf.exr` | channel `Y`: f_ssr [1/(m² sr)] per pixel, `std_error`: its standard error |
//! | `bssrdf.png` | log₁₀(f/f_max) in false colour, colour bar, scale in mm |
//! | `profile.csv` | x_mm, f_per_m2_sr, std_error, beam (relative) along the plane of incidence |
//! | `profile.png` | the same, log scale, beam on a second axis |
//! | `summary.json` | configuration (including the top boundary, `config.roughness`), optical properties used, sum, errors (of the sum; per pixel: median and 90th percentile of the relative standard error over the pixels above 1 % of the maximum), paths, events, speed |
//!
//! With `--uncertainty` ([`SliceBand`]), beside them:
//!
//! | file | content |
//! |---|---|
//! | `uncertainty.json` | per uncertain recipe input: nominal, σ, the slice sum's difference between +1 σ and −1 σ with its Monte Carlo standard error, its share of the variance; the sum's standard deviation from all inputs (first order) with its own Monte Carlo error, beside the sum's Monte Carlo standard error |
//! | `band.exr` | channels `Y` (f_ssr), `std_error` (Monte Carlo), `inputs_sd` (first-order standard deviation from the inputs), `inputs_sd_std_error` (its Monte Carlo error), per pixel [1/(m² sr)] |
//! | `profile-band.csv` | x_mm, f_per_m2_sr, std_error_per_m2_sr, inputs_sd_per_m2_sr, inputs_sd_std_error_per_m2_sr along the plane of incidence |
//! | `profile-band.png` | the profile with its ±1 σ band from the inputs (shaded) and its Monte Carlo error bars |
//!
//! Comparison (`lucent bssrdf compare`): the mean squared relative error
//! MSRE = mean over the mask of ((f_sim − f_meas)/f_meas)², where the mask
//! holds the measured pixels above `threshold` × max(f_meas) (default 0.01,
//! so near-zero, noise-dominated pixels do not dominate the mean); the sums
//! of both slices over all pixels and their ratio; the two profiles; a
//! side-by-side panel on a shared scale and a relative-difference map.

use crate::imageio::{self, ImageIoError};
use crate::io::{write_atomic, write_json, WriteError};
use crate::optics::uncertainty::InputSd;
use crate::plot::{perr, render_png, viridis, PlotError, MASKED};
use lucent_render::interface::Interface;
use lucent_render::slab::{Beam, Directions, Slice, SliceDifference};
use plotters::prelude::*;
use serde::{Deserialize, Deserializer, Serialize};
use std::path::{Path, PathBuf};

/// What is wrong with a θi/θo goniometer configuration or a list of them
/// ([`Configuration`], [`Configurations`]).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    #[error("{part:?}: expected θi/θo in degrees, e.g. 45/0")]
    Syntax { part: String },
    #[error("{part:?}: {text:?} is not a number")]
    Number { part: String, text: String },
    #[error("{part:?}: angles must lie in [0°, 90°)")]
    Angle { part: String },
    #[error("{part:?} is given twice")]
    Repeated { part: String },
    #[error("{text:?}: one θi/θo pair per measured slice")]
    NotOne { text: String },
}

/// One goniometer configuration: the polar angles of incidence θi and of
/// observation θo in degrees, each in [0°, 90°) (φi = 0°, φo = 180°: the
/// plane of incidence).
///
/// As text (its `FromStr`, `Display` and serde form) "θi/θo", e.g. "45/0",
/// each number written in its shortest form ("45.0/0" is written "45/0").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Configuration {
    pub theta_i_deg: f64,
    pub theta_o_deg: f64,
}

impl Configuration {
    /// (θi, θo) in degrees.
    pub fn pair(self) -> (f64, f64) {
        (self.theta_i_deg, self.theta_o_deg)
    }
}

impl std::str::FromStr for Configuration {
    type Err = ConfigError;

    fn from_str(text: &str) -> Result<Self, ConfigError> {
        if text.contains(',') {
            return Err(ConfigError::NotOne { text: text.to_string() });
        }
        let (a, b) = text.split_once('/').ok_or_else(|| ConfigError::Syntax { part: text.to_string() })?;
        let num = |s: &str| {
            s.trim().parse::<f64>().map_err(|_| ConfigError::Number { part: text.to_string(), text: s.to_string() })
        };
        let (ti, to) = (num(a)?, num(b)?);
        if !(0.0..90.0).contains(&ti) || !(0.0..90.0).contains(&to) {
            return Err(ConfigError::Angle { part: text.to_string() });
        }
        Ok(Self { theta_i_deg: ti, theta_o_deg: to })
    }
}

impl std::fmt::Display for Configuration {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.theta_i_deg, self.theta_o_deg)
    }
}

crate::text::serde_as_text!(Configuration);

/// Goniometer configurations ([`Configuration`]), at least one, none twice.
///
/// As text "θi/θo,θi/θo,…", e.g. "45/0,0/45".
#[derive(Debug, Clone, PartialEq)]
pub struct Configurations(Vec<Configuration>);

impl Configurations {
    /// The configurations in the order given.
    pub fn list(&self) -> &[Configuration] {
        &self.0
    }

    /// (θi, θo) pairs in degrees, in the order given.
    pub fn pairs(&self) -> Vec<(f64, f64)> {
        self.0.iter().map(|c| c.pair()).collect()
    }
}

impl From<Configuration> for Configurations {
    fn from(c: Configuration) -> Self {
        Configurations(vec![c])
    }
}

impl std::str::FromStr for Configurations {
    type Err = ConfigError;

    /// "45/0,0/45": each part a [`Configuration`], none given twice.
    fn from_str(text: &str) -> Result<Self, ConfigError> {
        let mut out: Vec<Configuration> = Vec::new();
        for part in text.split(',') {
            let c: Configuration = part.parse()?;
            if out.contains(&c) {
                return Err(ConfigError::Repeated { part: part.trim().to_string() });
            }
            out.push(c);
        }
        Ok(Configurations(out))
    }
}

impl std::fmt::Display for Configurations {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let words: Vec<String> = self.0.iter().map(Configuration::to_string).collect();
        f.write_str(&words.join(","))
    }
}

crate::text::serde_as_text!(Configurations);

/// A slice file that cannot be read or written.
#[derive(Debug, thiserror::Error)]
pub enum SliceIoError {
    #[error(transparent)]
    Image(#[from] ImageIoError),
    /// An EXR that cannot be written (the message names the file).
    #[error(transparent)]
    ExrWrite(#[from] crate::exr::ExrWriteError),
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error("{path}: {problem}")]
    Invalid { path: PathBuf, problem: SliceProblem },
    #[error("{path}: {source}")]
    Plot { path: PathBuf, source: PlotError },
    /// A measured slice's sidecar says it was taken otherwise than it is used.
    #[error(transparent)]
    Metadata(Box<MetadataMismatch>),
}

/// A measured slice's sidecar says it was taken at another wavelength or
/// other angles than it is used for ([`check_measured`]).
#[derive(Debug, thiserror::Error)]
#[error("{sidecar} says {slice} was measured at {what} {there}, but it is used as the slice at {here}: {hint}")]
pub struct MetadataMismatch {
    pub sidecar: PathBuf,
    pub slice: PathBuf,
    pub what: &'static str,
    pub there: String,
    pub here: String,
    pub hint: &'static str,
}

/// What is wrong with a slice file ([`SliceIoError::Invalid`]).
#[derive(Debug, thiserror::Error)]
pub enum SliceProblem {
    #[error("no such file")]
    Missing,
    #[error("not a file")]
    NotAFile,
    #[error("unsupported slice format (expected .exr, .tif/.tiff or .csv)")]
    Format,
    #[error("the grid is {width} × {height}; slices must be square")]
    NotSquare { width: usize, height: usize },
    #[error("pixel (column {column}, row {row}) is not a finite number")]
    NotFinite { column: usize, row: usize },
    #[error(
        "pixel size unknown: pass it (--measured-pixel-mm for --measured, --beam-map-pixel-mm for --beam-map) or put {{\"pixel_mm\": …}} in FILE.json"
    )]
    PixelSizeUnknown,
    #[error(
        "pixel (column {column}, row {row}) is {value}: a measured slice is a ratio of radiances and cannot be \
         negative (subtract the dark frame so that no pixel goes below 0, or set such pixels to 0)"
    )]
    Negative { column: usize, row: usize, value: f64 },
    #[error("pixel size {pixel_mm} mm must be positive")]
    PixelSize { pixel_mm: f64 },
    #[error("not a JSON file with a number `pixel_mm` (or `config.pixel_mm`): {0}")]
    Sidecar(#[source] serde_json::Error),
    #[error("cannot read: {0}")]
    Read(#[source] std::io::Error),
    /// A value that is not a number: the token, the line's text and a hint.
    #[error("line {line}: {detail}")]
    Number { line: usize, detail: Box<str> },
    #[error("line {line} has {values} values, the first row {first}: {text}")]
    RowLength { line: usize, values: usize, first: usize, text: Box<str> },
    #[error("no data rows")]
    Empty,
    #[error("cannot read EXR: {0}")]
    Exr(#[source] crate::exr::ExrProblem),
    #[error("EXR has no channels")]
    NoChannels,
    #[error(
        "EXR has channels {names:?} but no Y: a slice has one value per pixel (channel Y, or a single channel); \
         an RGB image is not read as one of its channels"
    )]
    Channels { names: Vec<String> },
}

/// A square grid of values with its pixel size (a slice, measured or
/// simulated), row-major from the top row.
#[derive(Debug, Clone, PartialEq)]
pub struct Grid {
    pub size: usize,
    pub pixel_m: f64,
    pub values: Vec<f64>,
}

impl Grid {
    /// Middle row (the plane of incidence for φ = 0°/180°).
    pub fn middle_row(&self) -> &[f64] {
        let r = self.size / 2;
        &self.values[r * self.size..(r + 1) * self.size]
    }

    /// x \[mm\] of each column centre.
    pub fn x_mm(&self) -> Vec<f64> {
        (0..self.size).map(|c| (c as f64 + 0.5 - 0.5 * self.size as f64) * self.pixel_m * 1e3).collect()
    }

    pub fn sum(&self) -> f64 {
        self.values.iter().sum()
    }
}

fn invalid(path: &Path, problem: SliceProblem) -> SliceIoError {
    SliceIoError::Invalid { path: path.to_path_buf(), problem }
}

/// Reads a square grid of finite values from EXR (channel `Y`, else the
/// only channel besides `A` and `std_error`), float TIFF or CSV (rows of numbers separated by commas
/// or whitespace; `#` comments). The pixel size comes from `pixel_mm` or,
/// failing that, from a sidecar JSON (`FILE.json` or `summary.json` in the
/// same folder) with `pixel_mm`.
pub fn read_grid(path: &Path, pixel_mm: Option<f64>) -> Result<Grid, SliceIoError> {
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if !path.is_file() {
        return Err(invalid(path, if path.exists() { SliceProblem::NotAFile } else { SliceProblem::Missing }));
    }
    let (w, h, values) = match ext.as_str() {
        "csv" | "txt" => read_csv_grid(path)?,
        "exr" => read_exr_scalar(path)?,
        // Float samples only: integer counts have no physical scale.
        "tif" | "tiff" => imageio::read_float_tiff(path)?,
        _ => return Err(invalid(path, SliceProblem::Format)),
    };
    if w != h {
        return Err(invalid(path, SliceProblem::NotSquare { width: w, height: h }));
    }
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(invalid(path, SliceProblem::NotFinite { column: i % w, row: i / w }));
    }
    let pixel_mm = match pixel_mm {
        Some(p) => p,
        None => sidecar_pixel_mm(path)?.ok_or_else(|| invalid(path, SliceProblem::PixelSizeUnknown))?,
    };
    if !(pixel_mm.is_finite() && pixel_mm > 0.0) {
        return Err(invalid(path, SliceProblem::PixelSize { pixel_mm }));
    }
    Ok(Grid { size: w, pixel_m: pixel_mm * 1e-3, values })
}

/// How a slice was taken, as its sidecar says (`FILE.json`, else
/// `summary.json` in its folder; keys at the top or under `config`):
/// wavelength and angles, each when given.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct SliceSidecar {
    /// The file these come from.
    pub file: PathBuf,
    pub wavelength_nm: Option<f64>,
    pub theta_i_deg: Option<f64>,
    pub phi_i_deg: Option<f64>,
    pub theta_o_deg: Option<f64>,
    pub phi_o_deg: Option<f64>,
}

/// The sidecar of a slice file ([`SliceSidecar`]); `None` without one.
pub fn sidecar_of(path: &Path) -> Result<Option<SliceSidecar>, SliceIoError> {
    let mut candidates = vec![PathBuf::from(format!("{}.json", path.display()))];
    if let Some(dir) = path.parent() {
        candidates.push(dir.join(SliceFiles::SUMMARY));
    }
    for c in candidates {
        let Ok(text) = crate::io::read_text(&c) else { continue };
        let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| invalid(&c, SliceProblem::Sidecar(e)))?;
        let get = |k: &str| v.get(k).or_else(|| v.pointer(&format!("/config/{k}"))).and_then(|x| x.as_f64());
        return Ok(Some(SliceSidecar {
            file: c.clone(),
            wavelength_nm: get("wavelength_nm"),
            theta_i_deg: get("theta_i_deg"),
            phi_i_deg: get("phi_i_deg"),
            theta_o_deg: get("theta_o_deg"),
            phi_o_deg: get("phi_o_deg"),
        }));
    }
    Ok(None)
}

/// Checks a measured slice before it is scored or fitted: no pixel is
/// negative, and what its sidecar says ([`sidecar_of`]) matches the
/// wavelength and the angles (θi, φi, θo, φo in degrees) it is used for.
/// A wavelength within 0.5 nm and angles within 0.01° match; an azimuth
/// is compared only off the normal (θ > 0) and modulo 360°.
pub fn check_measured(
    path: &Path,
    grid: &Grid,
    wavelength_nm: Option<f64>,
    angles: Option<(f64, f64, f64, f64)>,
) -> Result<(), SliceIoError> {
    if let Some(i) = grid.values.iter().position(|v| *v < 0.0) {
        let n = grid.size.max(1);
        return Err(invalid(path, SliceProblem::Negative { column: i % n, row: i / n, value: grid.values[i] }));
    }
    let Some(side) = sidecar_of(path)? else { return Ok(()) };
    let mismatch = |what, there: String, here: String, hint| {
        SliceIoError::Metadata(Box::new(MetadataMismatch {
            sidecar: side.file.clone(),
            slice: path.to_path_buf(),
            what,
            there,
            here,
            hint,
        }))
    };
    if let (Some(there), Some(here)) = (side.wavelength_nm, wavelength_nm)
        && (there - here).abs() > 0.5
    {
        return Err(mismatch(
            "wavelength",
            format!("{there} nm"),
            format!("{here} nm"),
            "fit or score it at the wavelength it was measured at, or correct the sidecar",
        ));
    }
    if let Some((ti, pi, to, po)) = angles {
        let az = |a: f64, b: f64| ((a - b).rem_euclid(360.0)).min((b - a).rem_euclid(360.0)) > 0.01;
        let differs = side.theta_i_deg.is_some_and(|t| (t - ti).abs() > 0.01)
            || side.theta_o_deg.is_some_and(|t| (t - to).abs() > 0.01)
            || (ti > 0.0 && side.phi_i_deg.is_some_and(|p| az(p, pi)))
            || (to > 0.0 && side.phi_o_deg.is_some_and(|p| az(p, po)));
        if differs {
            let show = |v: Option<f64>| v.map_or("?".to_string(), |x| format!("{x}"));
            return Err(mismatch(
                "θi/φi/θo/φo",
                format!(
                    "{}/{}/{}/{}°",
                    show(side.theta_i_deg),
                    show(side.phi_i_deg),
                    show(side.theta_o_deg),
                    show(side.phi_o_deg)
                ),
                format!("{ti}/{pi}/{to}/{po}°"),
                "give the slice with the configuration it was measured at, or correct the sidecar",
            ));
        }
    }
    Ok(())
}

/// The pixel size a slice's sidecar gives (`pixel_mm` in `FILE.json`, or
/// `config.pixel_mm` in `summary.json` beside it); `None` without one.
pub fn sidecar_pixel_mm(path: &Path) -> Result<Option<f64>, SliceIoError> {
    let mut candidates = vec![PathBuf::from(format!("{}.json", path.display()))];
    if let Some(dir) = path.parent() {
        candidates.push(dir.join(SliceFiles::SUMMARY));
    }
    // `FILE.json` holds `pixel_mm`; a simulated slice's `summary.json` holds
    // it in `config` (other fields of either are not read here).
    #[derive(Deserialize)]
    struct Sidecar {
        pixel_mm: Option<f64>,
        config: Option<SidecarConfig>,
    }
    #[derive(Deserialize)]
    struct SidecarConfig {
        pixel_mm: Option<f64>,
    }
    for c in candidates {
        if let Ok(text) = crate::io::read_text(&c) {
            let v: Sidecar = serde_json::from_str(&text).map_err(|e| invalid(&c, SliceProblem::Sidecar(e)))?;
            if let Some(p) = v.pixel_mm.or(v.config.and_then(|c| c.pixel_mm)) {
                return Ok(Some(p));
            }
        }
    }
    Ok(None)
}

fn read_csv_grid(path: &Path) -> Result<(usize, usize, Vec<f64>), SliceIoError> {
    let text = crate::io::read_text(path).map_err(|e| invalid(path, SliceProblem::Read(e)))?;
    // A UTF-8 byte-order mark (spreadsheet exports) is not part of the first number.
    let text = text.strip_prefix('\u{feff}').unwrap_or(&text);
    let mut rows: Vec<Vec<f64>> = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let mut row = Vec::new();
        for token in line.split(|c: char| c == ',' || c.is_whitespace()).filter(|s| !s.is_empty()) {
            let v = token.parse::<f64>().map_err(|source| {
                let shown: String = line.chars().take(80).collect();
                let hint = if line.contains(';') {
                    ": values are separated by commas or spaces, not semicolons (a spreadsheet's export setting)"
                } else {
                    ""
                };
                let token: String = token.chars().take(40).collect();
                let text = if line.chars().count() > 80 { format!("{shown}…") } else { shown };
                let detail = format!("{token:?} is not a number ({source}) in {text:?}{hint}");
                invalid(path, SliceProblem::Number { line: k + 1, detail: detail.into() })
            })?;
            row.push(v);
        }
        if let Some(first) = rows.first()
            && row.len() != first.len()
        {
            return Err(invalid(
                path,
                SliceProblem::RowLength {
                    line: k + 1,
                    values: row.len(),
                    first: first.len(),
                    text: crate::io::quoted_line(line).into(),
                },
            ));
        }
        rows.push(row);
    }
    if rows.is_empty() {
        return Err(invalid(path, SliceProblem::Empty));
    }
    let (w, h) = (rows[0].len(), rows.len());
    Ok((w, h, rows.into_iter().flatten().collect()))
}

fn read_exr_scalar(path: &Path) -> Result<(usize, usize, Vec<f64>), SliceIoError> {
    let exr_err = |e: crate::exr::ExrReadError| invalid(path, SliceProblem::Exr(e.problem));
    let layer = crate::exr::read_layer(path).map_err(exr_err)?;
    // A slice has one value per pixel: channel Y, or the only channel
    // besides an alpha or a standard error. An RGB image is refused rather
    // than read as its R channel.
    let names = layer.names();
    let data: Vec<usize> = (0..names.len()).filter(|&i| !["A", "std_error"].contains(&names[i].as_str())).collect();
    let pick = match (names.iter().position(|n| n == "Y"), data.as_slice()) {
        (Some(y), _) => y,
        (None, [only]) => *only,
        (None, []) => return Err(invalid(path, SliceProblem::NoChannels)),
        (None, _) => return Err(invalid(path, SliceProblem::Channels { names })),
    };
    let values: Vec<f64> = layer.plane_at(pick).map_err(exr_err)?.iter().copied().map(f64::from).collect();
    Ok((layer.width, layer.height, values))
}

/// Two slices that [`compare`] cannot compare.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ComparisonError {
    #[error("size mismatch: measured {measured} × {measured}, simulated {simulated} × {simulated} pixels")]
    Size { measured: usize, simulated: usize },
    #[error("pixel size mismatch: measured {measured_mm} mm, simulated {simulated_mm} mm")]
    PixelSize { measured_mm: f64, simulated_mm: f64 },
    #[error("threshold {0} must lie in [0, 1)")]
    Threshold(f64),
    #[error("the measured slice has no positive values")]
    NoPositiveMeasured,
}

/// A top boundary (`--roughness`, a job's `roughness`) that cannot be used;
/// its text is parsed with the flag ([`RoughnessSpec`]), so what is left is
/// what only reading its files or building the boundary finds.
#[derive(Debug, thiserror::Error)]
pub enum RoughnessError {
    /// The boundary cannot be built from the distribution (the recipe's `[surface]` or `--roughness`).
    #[error("--roughness {text:?}: {problem} (expected {})", crate::surface::model::ROUGHNESS_WORDS)]
    Syntax { text: String, problem: RoughnessSyntax },
    #[error("--roughness {text:?}: {source}")]
    Surface { text: String, source: Box<crate::surface::SurfaceError> },
    /// The measured normals (`normals.exr`) cannot be used; the source names the file.
    #[error("--roughness {text:?}: {source}")]
    Normals { text: String, source: NormalsError },
}

/// The most light paths a BSSRDF slice or a fit evaluation may be given
/// (`--paths`, `[bssrdf] paths`, `[fit] paths`, `bench surface --paths`):
/// 10¹² paths, about 12 core-days at the slab's 1 M paths/s per core (a
/// month on a 100-core cluster at the slower rates of dense media), and far
/// below 2⁵³, where the tallies' path counts stop being exact. A study that
/// needs more is several runs with different seeds.
pub const MAX_PATHS: u64 = 1_000_000_000_000;

/// Why a path count is refused (the reason half of a message naming the flag or key).
pub fn paths_problem(n: u64) -> Option<String> {
    if n == 0 {
        Some("must be at least 1".into())
    } else if n > MAX_PATHS {
        Some(format!(
            "must be at most {MAX_PATHS} (10^12, about 12 core-days of simulation; run a larger study as several \
             runs with different seeds)"
        ))
    } else {
        None
    }
}

pub use crate::surface::model::{RoughnessSpec, RoughnessSyntax};

/// A `normals.exr` (of `lucent surface fit`) that cannot be used as a
/// measured normal set; every variant names the file.
#[derive(Debug, thiserror::Error)]
pub enum NormalsError {
    /// Not readable as an EXR with channels R, G, B, A (the message names the file).
    #[error(transparent)]
    Read(#[from] crate::exr::ExrReadError),
    #[error("{path}: pixel ({column}, {row}) = {value:?} is not a unit normal facing +z")]
    NotUnit { path: PathBuf, column: usize, row: usize, value: [f64; 3] },
    #[error("{path}: no pixel holds a normal (alpha is 0 everywhere)")]
    Empty { path: PathBuf },
    #[error("{path}: {source}")]
    Set { path: PathBuf, source: lucent_render::microfacet::MicrofacetError },
}

/// The top boundary of `--roughness` (`spec`; without it, of the recipe's
/// `[surface]`, else smooth) and a description for the summary:
///
/// * `smooth`;
/// * `tr:ALPHA` (also `ggx:`, `trowbridge-reitz:`) or `beckmann:ALPHA`:
///   the analytic distribution with roughness α (0 ≤ α ≤ 4, checked when
///   the text is read; below 10⁻⁴ the boundary is smooth);
/// * `measured:FIT.json`: the measured normal set of a `lucent surface fit`
///   run — `normals.exr` beside its `fit.json` (the fit's schema is
///   checked) — as a kernel density estimate of the slopes
///   ([`lucent_render::microfacet::MeasuredNormals`], bandwidth from the
///   data); a `normals.exr` may be named directly too.
///
/// The recipe's `[surface]` gives its model and α; its fitted scale factor
/// is not used (the distributions are normalised).
pub fn roughness(
    spec: Option<&RoughnessSpec>,
    recipe_surface: Option<&crate::optics::recipe::Surface>,
) -> Result<(Interface, String), RoughnessError> {
    use lucent_render::microfacet::{Distribution, MeasuredNormals, Microsurface};
    let analytic = |d: Distribution, origin: &str, text: &str| -> Result<(Interface, String), RoughnessError> {
        let boundary = Interface::new(Microsurface::Analytic(d))
            .map_err(|_| RoughnessError::Syntax { text: text.into(), problem: RoughnessSyntax::Alpha(d.alpha()) })?;
        let name = format!("{} ({origin})", boundary.describe());
        Ok((boundary, name))
    };
    let from_recipe = || match recipe_surface {
        Some(s) => analytic(s.model.distribution(s.alpha), "the recipe's [surface]", "recipe"),
        None => Ok((Interface::Smooth, "smooth".into())),
    };
    let Some(spec) = spec else {
        return from_recipe();
    };
    let text = spec.to_string();
    match spec {
        RoughnessSpec::Recipe => from_recipe(),
        RoughnessSpec::Smooth => Ok((Interface::Smooth, "smooth (--roughness)".into())),
        RoughnessSpec::Analytic { model, alpha } => analytic(model.distribution(*alpha), "--roughness", &text),
        RoughnessSpec::Measured(path) => {
            let is_exr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
            let normals_path = if is_exr {
                path.clone()
            } else {
                crate::surface::load_fit_choice(path, None)
                    .map_err(|e| RoughnessError::Surface { text: text.clone(), source: Box::new(e) })?;
                path.parent().unwrap_or(Path::new(".")).join(crate::surface::OUTPUT_FILES[3])
            };
            let normals_err = |source| RoughnessError::Normals { text: text.clone(), source };
            let normals = read_normals(&normals_path).map_err(normals_err)?;
            let set = MeasuredNormals::new(&normals, None)
                .map_err(|source| normals_err(NormalsError::Set { path: normals_path.clone(), source }))?;
            let boundary = Interface::Rough(Microsurface::Measured(std::sync::Arc::new(set)));
            let name = format!("{} from {}", boundary.describe(), normals_path.display());
            Ok((boundary, name))
        }
    }
}

/// The unit normals of a `normals.exr` of `lucent surface fit` (R, G, B =
/// x, y, z, A = 1 where the pixel has a normal), renormalised from 32-bit
/// floats; pixels with A = 0 are skipped.
fn read_normals(path: &Path) -> Result<Vec<[f64; 3]>, NormalsError> {
    let (w, h, planes) = crate::exr::read_channels(path, &["R", "G", "B", "A"])?;
    let mut out = Vec::with_capacity(w * h);
    let pixels = planes[0].iter().zip(&planes[1]).zip(&planes[2]).zip(&planes[3]);
    for (k, (((x, y), z), a)) in pixels.enumerate() {
        if *a == 0.0 {
            continue;
        }
        let v = [*x as f64, *y as f64, *z as f64];
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if !(l.is_finite() && (l - 1.0).abs() < 1e-3 && v[2] > 0.0) {
            return Err(NormalsError::NotUnit { path: path.to_path_buf(), column: k % w, row: k / w, value: v });
        }
        out.push([v[0] / l, v[1] / l, v[2] / l]);
    }
    if out.is_empty() {
        return Err(NormalsError::Empty { path: path.to_path_buf() });
    }
    Ok(out)
}

/// Configuration and results of a run, as written to `summary.json` and
/// read back by the report (`lucent run`). Fields added after the first
/// version default on reading files written before them: the per-pixel
/// errors to NaN (unknown) and their mask to 0, `kernel` and `estimator` to
/// "" (unknown), `folded`, `reciprocal` and `interrupted` to false (those
/// runs had neither). Non-finite numbers are written as `null` and read back
/// as NaN.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Summary {
    pub config: RunConfig,
    pub optical_properties: OpticalUsed,
    /// Σ over output pixels of f_ssr [1/(m² sr)].
    pub sum: f64,
    pub sum_std_error: f64,
    #[serde(deserialize_with = "f64_or_nan")]
    pub relative_std_error: f64,
    /// Median per-pixel relative standard error over the pixels above 1 % of
    /// the maximum (the figure that says whether the image has converged).
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub pixel_rel_error_median: f64,
    /// Its 90th percentile.
    #[serde(default = "nan", deserialize_with = "f64_or_nan")]
    pub pixel_rel_error_p90: f64,
    /// Pixels in that 1 % mask.
    #[serde(default)]
    pub pixel_mask_pixels: usize,
    pub paths: u64,
    pub events: u64,
    #[serde(deserialize_with = "f64_or_nan")]
    pub events_per_s: f64,
    /// The simulator's kernel ("avx2-fma lanes" or "scalar"; they agree to
    /// rounding).
    #[serde(default)]
    pub kernel: String,
    /// The estimator: the ring connection (azimuthal symmetry) where it
    /// applies, else the lobe connection (thick slab, smooth or rough top),
    /// else the connection along the fixed exit direction.
    #[serde(default)]
    pub estimator: String,
    /// Whether the slice was folded about the plane of incidence (exact when
    /// both azimuths are 0°/180° and the beam is mirror-symmetric).
    #[serde(default)]
    pub folded: bool,
    /// Whether the photons were launched from the camera's side (ring with
    /// θo = 0, by reciprocity); `diffuse_reflectance` and `transmittance`
    /// then describe light arriving along ωo.
    #[serde(default)]
    pub reciprocal: bool,
    pub wall_s: f64,
    pub specular_reflectance: f64,
    pub diffuse_reflectance: f64,
    pub transmittance: f64,
    pub pixel_mm: f64,
    /// True when Ctrl-C stopped the run before its stop rule: the slice is the
    /// estimate from the paths finished until then (valid, with its errors).
    #[serde(default)]
    pub interrupted: bool,
}

fn nan() -> f64 {
    f64::NAN
}

/// A number as serde_json writes it: non-finite values become `null`, read back as NaN.
pub(crate) fn f64_or_nan<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NAN))
}

fn smooth() -> String {
    "smooth".into()
}

/// The configuration part of a summary.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunConfig {
    pub recipe: Option<String>,
    pub wavelength_nm: Option<f64>,
    pub theta_i_deg: f64,
    pub phi_i_deg: f64,
    pub theta_o_deg: f64,
    pub phi_o_deg: f64,
    pub phase: String,
    pub beam: String,
    pub pixels: usize,
    pub pixel_mm: f64,
    pub crop_of: Option<usize>,
    pub seed: u64,
    pub thickness_mm: f64,
    /// The top boundary: "smooth" or the rough surface used and where it
    /// came from (`--roughness`, the recipe's `[surface]`); "smooth" in
    /// files written before rough tops existed.
    #[serde(default = "smooth")]
    pub roughness: String,
}

/// The optical properties a run used.
#[derive(Debug, Clone, Copy, Serialize, Deserialize)]
pub struct OpticalUsed {
    pub mu_s_per_m: f64,
    pub mu_a_per_m: f64,
    pub g: f64,
    pub n: f64,
}

/// Relative beam irradiance along the middle row of the sensor (for the
/// profile plot): the footprint the simulator samples
/// ([`Beam::footprint`]) evaluated at (x, 0), over its maximum on that row.
pub fn beam_profile(beam: &Beam, dirs: &Directions, x_mm: &[f64]) -> Vec<f64> {
    let footprint = beam.footprint(dirs.theta_i_deg, dirs.phi_i_deg);
    let values: Vec<f64> = x_mm.iter().map(|x| footprint.irradiance(x * 1e-3, 0.0)).collect();
    let max = values.iter().copied().fold(0.0, f64::max);
    if max > 0.0 {
        values.iter().map(|v| v / max).collect()
    } else {
        values
    }
}

/// The files of one slice run in its folder, each name spelled here once:
/// the slice (`exr`), its picture (`png`), the profile along the plane of
/// incidence (`profile_csv`, `profile_png`) and the run's [`Summary`]
/// (`summary`). Written by [`write_run`], read by `lucent bssrdf compare`,
/// `lucent fit` and `lucent run`'s report.
///
/// ```
/// use lucent::bssrdf::SliceFiles;
/// let f = SliceFiles::in_dir(std::path::Path::new("out/bssrdf/s1"));
/// assert_eq!(f.summary, std::path::Path::new("out/bssrdf/s1/summary.json"));
/// assert_eq!(SliceFiles::run_subdir(2, 45.0, 0.0), "ti45_to0");
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SliceFiles {
    pub exr: PathBuf,
    pub png: PathBuf,
    pub profile_csv: PathBuf,
    pub profile_png: PathBuf,
    pub summary: PathBuf,
}

impl SliceFiles {
    /// The file names.
    pub const NAMES: [&'static str; 5] = ["bssrdf.exr", "bssrdf.png", "profile.csv", "profile.png", "summary.json"];
    /// The summary's name ([`SliceFiles::summary`]'s), beside any slice it describes.
    pub const SUMMARY: &'static str = Self::NAMES[4];
    /// The table of a run over several configurations, in the folder above their runs.
    pub const SWEEP_CSV: &'static str = "sweep.csv";

    /// The files of the run whose folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [exr, png, profile_csv, profile_png, summary] = Self::NAMES.map(|n| dir.join(n));
        Self { exr, png, profile_csv, profile_png, summary }
    }

    /// The subfolder of configuration θi/θo in a run over `count`
    /// configurations: empty for one (it runs in the folder itself).
    pub fn run_subdir(count: usize, theta_i_deg: f64, theta_o_deg: f64) -> String {
        if count > 1 {
            format!("ti{theta_i_deg}_to{theta_o_deg}")
        } else {
            String::new()
        }
    }

    /// Whether `name` is of a [`SliceFiles::run_subdir`].
    pub fn is_run_subdir(name: &str) -> bool {
        name.starts_with("ti") && name.contains("_to")
    }
}

/// The files of a slice's band (`--uncertainty`, [`SliceBand`]) beside the
/// run's [`SliceFiles`]: `uncertainty.json` (`json`), `band.exr` (`exr`) and
/// the profile with its band (`profile_csv`, `profile_png`). Written by
/// [`write_band`].
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SliceBandFiles {
    pub json: PathBuf,
    pub exr: PathBuf,
    pub profile_csv: PathBuf,
    pub profile_png: PathBuf,
}

impl SliceBandFiles {
    /// The file names.
    pub const NAMES: [&'static str; 4] = ["uncertainty.json", "band.exr", "profile-band.csv", "profile-band.png"];

    /// The band files of the run whose folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [json, exr, profile_csv, profile_png] = Self::NAMES.map(|n| dir.join(n));
        Self { json, exr, profile_csv, profile_png }
    }
}

/// The files of `lucent bssrdf compare` in its output folder: the
/// [`Comparison`] (`json`), the two profiles (`profiles`) and the
/// side-by-side panel with the relative difference (`panel`). Read by
/// `lucent run`'s report.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ComparisonFiles {
    pub json: PathBuf,
    pub profiles: PathBuf,
    pub panel: PathBuf,
}

impl ComparisonFiles {
    /// The file names.
    pub const NAMES: [&'static str; 3] = ["comparison.json", "profiles.png", "panel.png"];

    /// The files of the comparison whose folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [json, profiles, panel] = Self::NAMES.map(|n| dir.join(n));
        Self { json, profiles, panel }
    }
}

/// Writes the files of one run into `dir`; returns their paths.
pub fn write_run(dir: &Path, slice: &Slice, summary: &Summary, beam: &[f64]) -> Result<Vec<PathBuf>, SliceIoError> {
    let n = slice.pixels;
    let mut written = Vec::new();
    let files = SliceFiles::in_dir(dir);
    let exr = files.exr;
    let f32v = |v: &[f64]| v.iter().map(|x| *x as f32).collect::<Vec<f32>>();
    crate::exr::write_channels(&exr, n, n, &[("Y", &f32v(&slice.values)), ("std_error", &f32v(&slice.std_error))])?;
    written.push(exr);
    let grid = Grid { size: n, pixel_m: slice.pixel_m, values: slice.values.clone() };
    let png = files.png;
    let title = format!(
        "f_ssr, θi {}° φi {}° → θo {}° φo {}°",
        summary.config.theta_i_deg, summary.config.phi_i_deg, summary.config.theta_o_deg, summary.config.phi_o_deg
    );
    let bytes =
        heatmap_png(&[(&title, &grid)], None).map_err(|source| SliceIoError::Plot { path: png.clone(), source })?;
    write_atomic(&png, &bytes)?;
    written.push(png);

    let x = grid.x_mm();
    let row = n / 2;
    let mut csv = String::from("x_mm,f_per_m2_sr,std_error_per_m2_sr,beam_relative\n");
    for (c, xc) in x.iter().enumerate().take(n) {
        csv.push_str(&format!(
            "{:.6},{:.8e},{:.8e},{:.6e}\n",
            xc,
            slice.values[row * n + c],
            slice.std_error[row * n + c],
            beam.get(c).copied().unwrap_or(0.0)
        ));
    }
    let p = files.profile_csv;
    write_atomic(&p, csv.as_bytes())?;
    written.push(p);
    let p = files.profile_png;
    let err: Vec<f64> = (0..n).map(|c| slice.std_error[row * n + c]).collect();
    let bytes = profile_png(&x, &[("simulated", grid.middle_row(), Some(&err[..]))], Some(beam))
        .map_err(|source| SliceIoError::Plot { path: p.clone(), source })?;
    write_atomic(&p, &bytes)?;
    written.push(p);
    let p = files.summary;
    write_json(&p, summary)?;
    written.push(p);
    Ok(written)
}

/// What one input does to the slice sum.
#[derive(Debug, Clone, Serialize)]
pub struct InputEffect {
    #[serde(flatten)]
    pub input: InputSd,
    /// Slice sum at +1 σ minus at −1 σ [1/(m² sr)], and its Monte Carlo standard error.
    pub sum_difference: f64,
    pub sum_difference_std_error: f64,
    /// d(sum)/d(input) ≈ difference/(2σ) [1/(m² sr) per unit of the input].
    pub sum_sensitivity: f64,
    /// Its share of the sum's variance from the inputs (0 … 1).
    pub share_of_variance: f64,
}

/// A slice's uncertainty from the recipe's uncertain inputs, first order
/// ([`crate::optics::uncertainty::first_order`]), written as
/// `uncertainty.json` (the per-pixel arrays go to `band.exr`).
#[derive(Debug, Clone, Serialize)]
pub struct SliceBand {
    pub method: &'static str,
    pub inputs: Vec<InputEffect>,
    /// The nominal slice sum [1/(m² sr)] and its Monte Carlo standard error.
    pub sum: f64,
    pub sum_std_error: f64,
    /// The sum's standard deviation from the inputs, its Monte Carlo
    /// standard error, and relative to the sum.
    pub sum_inputs_sd: f64,
    pub sum_inputs_sd_std_error: f64,
    pub sum_inputs_relative_sd: f64,
    /// Median over the bright pixels (above 1 % of the maximum) of the
    /// per-pixel standard deviation from the inputs relative to the pixel.
    pub pixel_inputs_relative_sd_median: f64,
    pub paths: u64,
    #[serde(skip)]
    pub pixel_sd: Vec<f64>,
    #[serde(skip)]
    pub pixel_sd_std_error: Vec<f64>,
}

impl SliceBand {
    /// The band of `slice` from the coupled differences at ±1 σ of `inputs` (same order).
    pub fn new(slice: &Slice, inputs: &[InputSd], differences: &[SliceDifference]) -> Self {
        use crate::optics::uncertainty::first_order;
        let sums = first_order(
            &differences.iter().map(|d| vec![d.sum]).collect::<Vec<_>>(),
            &differences.iter().map(|d| vec![d.sum_std_error]).collect::<Vec<_>>(),
        );
        let pixels = first_order(
            &differences.iter().map(|d| d.values.clone()).collect::<Vec<_>>(),
            &differences.iter().map(|d| d.std_error.clone()).collect::<Vec<_>>(),
        );
        let max = slice.values.iter().copied().fold(0.0, f64::max);
        let mut rel: Vec<f64> = slice
            .values
            .iter()
            .zip(&pixels.sd)
            .filter(|(v, _)| **v > lucent_render::slab::PIXEL_MASK_FRACTION * max && **v > 0.0)
            .map(|(v, s)| s / v)
            .collect();
        rel.sort_by(f64::total_cmp);
        let median = rel.get(rel.len() / 2).copied().unwrap_or(f64::NAN);
        let effects = inputs
            .iter()
            .zip(differences)
            .zip(&sums.shares)
            .map(|((input, d), share)| InputEffect {
                input: input.clone(),
                sum_difference: d.sum,
                sum_difference_std_error: d.sum_std_error,
                sum_sensitivity: d.sum / (2.0 * input.sd),
                share_of_variance: share[0],
            })
            .collect();
        SliceBand {
            method: "first order (GUM): per input, the slices at +1 σ and −1 σ traced with the nominal slice's random numbers; u² = Σ (Δ/2)²",
            inputs: effects,
            sum: slice.sum,
            sum_std_error: slice.sum_std_error,
            sum_inputs_sd: sums.sd[0],
            sum_inputs_sd_std_error: sums.sd_std_error[0],
            sum_inputs_relative_sd: sums.sd[0] / slice.sum,
            pixel_inputs_relative_sd_median: median,
            paths: slice.paths,
            pixel_sd: pixels.sd,
            pixel_sd_std_error: pixels.sd_std_error,
        }
    }

    /// One line for the terminal: the sum's band beside its Monte Carlo error, and each input's share.
    pub fn sentence(&self) -> String {
        let shares: Vec<String> =
            self.inputs.iter().map(|e| format!("{} {:.0} %", e.input.key, 100.0 * e.share_of_variance)).collect();
        format!(
            "slice sum {:.5e} 1/(m² sr): ±{:.2} % from the inputs (±{:.2} % Monte Carlo error of that band; shares: {}), ±{:.2} % Monte Carlo; per pixel ±{:.1} % (median)",
            self.sum,
            100.0 * self.sum_inputs_relative_sd,
            100.0 * self.sum_inputs_sd_std_error / self.sum,
            shares.join(", "),
            100.0 * self.sum_std_error / self.sum,
            100.0 * self.pixel_inputs_relative_sd_median,
        )
    }
}

/// Writes `uncertainty.json`, `band.exr`, `profile-band.csv` and
/// `profile-band.png` of `band` (the band of `slice`) into `dir`.
pub fn write_band(dir: &Path, slice: &Slice, band: &SliceBand, beam: &[f64]) -> Result<Vec<PathBuf>, SliceIoError> {
    let n = slice.pixels;
    let mut written = Vec::new();
    let files = SliceBandFiles::in_dir(dir);
    let p = files.json;
    write_json(&p, band)?;
    written.push(p);
    let f32v = |v: &[f64]| v.iter().map(|x| *x as f32).collect::<Vec<f32>>();
    let exr = files.exr;
    crate::exr::write_channels(
        &exr,
        n,
        n,
        &[
            ("Y", &f32v(&slice.values)),
            ("std_error", &f32v(&slice.std_error)),
            ("inputs_sd", &f32v(&band.pixel_sd)),
            ("inputs_sd_std_error", &f32v(&band.pixel_sd_std_error)),
        ],
    )?;
    written.push(exr);
    let row = n / 2;
    let x: Vec<f64> = (0..n).map(|c| (c as f64 + 0.5 - 0.5 * n as f64) * slice.pixel_m * 1e3).collect();
    let at = |v: &[f64]| -> Vec<f64> { (0..n).map(|c| v[row * n + c]).collect() };
    let (f, se, sd, sd_se) =
        (at(&slice.values), at(&slice.std_error), at(&band.pixel_sd), at(&band.pixel_sd_std_error));
    let mut csv =
        String::from("x_mm,f_per_m2_sr,std_error_per_m2_sr,inputs_sd_per_m2_sr,inputs_sd_std_error_per_m2_sr\n");
    for c in 0..n {
        csv.push_str(&format!("{:.6},{:.8e},{:.8e},{:.8e},{:.8e}\n", x[c], f[c], se[c], sd[c], sd_se[c]));
    }
    let p = files.profile_csv;
    write_atomic(&p, csv.as_bytes())?;
    written.push(p);
    let p = files.profile_png;
    let bytes = profile_band_png(&x, &f, &se, &sd, band, Some(beam))
        .map_err(|source| SliceIoError::Plot { path: p.clone(), source })?;
    write_atomic(&p, &bytes)?;
    written.push(p);
    Ok(written)
}

/// The profile along the plane of incidence (log scale) with its ±1 σ band
/// from the recipe's inputs shaded and its Monte Carlo errors as bars.
fn profile_band_png(
    x_mm: &[f64],
    values: &[f64],
    mc: &[f64],
    sd: &[f64],
    band: &SliceBand,
    beam: Option<&[f64]>,
) -> Result<Vec<u8>, PlotError> {
    let positive: Vec<f64> = values.iter().copied().filter(|v| *v > 0.0).collect();
    let hi = positive.iter().copied().fold(0.0, f64::max) * 2.0;
    let lo = (hi * 1e-5).max(positive.iter().copied().fold(f64::INFINITY, f64::min) / 2.0);
    if !(hi > 0.0 && lo.is_finite()) {
        return Err(perr("profile has no positive values"));
    }
    let (x0, x1) = (x_mm.first().copied().unwrap_or(-1.0), x_mm.last().copied().unwrap_or(1.0));
    let caption = format!(
        "profile with ±1 σ from the recipe's inputs (sum ±{:.2} %; Monte Carlo ±{:.2} %)",
        100.0 * band.sum_inputs_relative_sd,
        100.0 * band.sum_std_error / band.sum
    );
    render_png(1220, 600, |root| {
        let (root, legend) = root.split_horizontally(1000);
        let blue = crate::plot::palette(0);
        let grey = RGBColor(120, 120, 120);
        // The band's colour: the curve's at 30 % over white (what `mix(0.3)` shows).
        let over_white = |c: u8| (0.3 * f64::from(c) + 0.7 * 255.0).round() as u8;
        let pale = RGBColor(over_white(blue.0), over_white(blue.1), over_white(blue.2));
        let mut items = vec![
            ("simulated, Monte Carlo ±1 s.e.".to_string(), crate::plot::Mark::Line(blue, 2)),
            ("±1 σ from the inputs".to_string(), crate::plot::Mark::Box(pale)),
        ];
        if beam.is_some() {
            items.push(("beam (right axis)".into(), crate::plot::Mark::Line(grey, 1)));
        }
        crate::plot::legend_column(&legend, 60, &items)?;
        let mut chart = ChartBuilder::on(&root)
            .margin(15)
            .caption(caption, ("sans-serif", 18))
            .x_label_area_size(40)
            .y_label_area_size(80)
            .right_y_label_area_size(60)
            .build_cartesian_2d(x0..x1, crate::plot::log_axis(lo, hi))
            .map_err(perr)?
            .set_secondary_coord(x0..x1, 0.0..1.05);
        chart
            .configure_mesh()
            .x_desc("x [mm]")
            .y_desc("f_ssr [1/(m² sr)]")
            .y_label_formatter(&|v| crate::plot::short_number(*v))
            .draw()
            .map_err(perr)?;
        // The band as one polygon: upper edge left to right, lower edge back.
        let upper: Vec<(f64, f64)> =
            x_mm.iter().zip(values.iter().zip(sd)).map(|(x, (v, s))| (*x, (v + s).max(lo))).collect();
        let lower: Vec<(f64, f64)> =
            x_mm.iter().zip(values.iter().zip(sd)).rev().map(|(x, (v, s))| (*x, (v - s).max(lo))).collect();
        let outline: Vec<(f64, f64)> = upper.into_iter().chain(lower).collect();
        chart.draw_series(std::iter::once(Polygon::new(outline, pale.filled()))).map_err(perr)?;
        let pts: Vec<(f64, f64)> =
            x_mm.iter().zip(values.iter()).filter(|(_, v)| **v > 0.0).map(|(x, v)| (*x, *v)).collect();
        chart.draw_series(LineSeries::new(pts, blue.stroke_width(2))).map_err(perr)?;
        chart
            .draw_series(
                x_mm.iter()
                    .zip(values.iter().zip(mc))
                    .filter(|(_, (v, s))| **v - **s > 0.0)
                    .map(|(x, (v, s))| PathElement::new(vec![(*x, v - s), (*x, v + s)], BLACK.mix(0.6))),
            )
            .map_err(perr)?;
        if let Some(b) = beam {
            chart.configure_secondary_axes().y_desc("beam (relative)").draw().map_err(perr)?;
            chart
                .draw_secondary_series(LineSeries::new(x_mm.iter().zip(b).map(|(x, v)| (*x, *v)), grey.stroke_width(1)))
                .map_err(perr)?;
        }
        Ok(())
    })
}

/// Log-scale false-colour panels side by side on one shared scale
/// (log₁₀(f/f_max) from −`decades` to 0), with a colour bar and axes in mm.
/// With `diverging`, the last panel is a relative-difference map in
/// [−1, 1] instead (blue negative, white 0, red positive), NaN (outside the
/// mask) in [`MASKED`] grey, values beyond ±1 clipped and marked in the
/// darker [`OVER`] / [`UNDER`], each keyed under its colour bar.
/// Colours of the difference map outside its range: above +1, below −1
/// (masked pixels, NaN, in [`MASKED`]).
pub const OVER: RGBColor = RGBColor(110, 0, 0);
pub const UNDER: RGBColor = RGBColor(0, 0, 110);

pub fn heatmap_png(panels: &[(&str, &Grid)], diverging: Option<(&str, &Grid)>) -> Result<Vec<u8>, PlotError> {
    let decades = 4.0;
    let fmax = panels.iter().flat_map(|(_, g)| g.values.iter().copied()).fold(0.0, f64::max);
    let count = panels.len() + usize::from(diverging.is_some());
    let (pw, ph) = (620u32, 600u32);
    render_png(pw * count as u32, ph + 80 + 30 * u32::from(diverging.is_some()), |root| {
        let (top, bar) = root.split_vertically(ph);
        let areas = top.split_evenly((1, count));
        let draw = |area: &DrawingArea<BitMapBackend, plotters::coord::Shift>,
                    title: &str,
                    g: &Grid,
                    colour: &dyn Fn(f64) -> RGBColor|
         -> Result<(), PlotError> {
            let half = 0.5 * g.size as f64 * g.pixel_m * 1e3;
            let mut chart = ChartBuilder::on(area)
                .margin(10)
                .caption(title, ("sans-serif", 18))
                .x_label_area_size(35)
                .y_label_area_size(45)
                .build_cartesian_2d(-half..half, -half..half)
                .map_err(perr)?;
            chart.configure_mesh().disable_mesh().x_desc("x [mm]").y_desc("y [mm]").draw().map_err(perr)?;
            let p = g.pixel_m * 1e3;
            chart
                .draw_series(g.values.iter().enumerate().map(|(i, v)| {
                    let (c, r) = ((i % g.size) as f64, (i / g.size) as f64);
                    let x0 = -half + c * p;
                    let y0 = half - r * p;
                    Rectangle::new([(x0, y0), (x0 + p, y0 - p)], colour(*v).filled())
                }))
                .map_err(perr)?;
            Ok(())
        };
        let log_colour = |v: f64| {
            if v <= 0.0 || fmax <= 0.0 {
                viridis(0.0)
            } else {
                viridis(((v / fmax).log10() + decades) / decades)
            }
        };
        for (area, (title, g)) in areas.iter().zip(panels) {
            draw(area, title, g, &log_colour)?;
        }
        let diverge = |v: f64| {
            if v.is_nan() {
                return MASKED;
            } else if v > 1.0 {
                return OVER;
            } else if v < -1.0 {
                return UNDER;
            }
            let t = v;
            if t < 0.0 {
                let a = 1.0 + t;
                RGBColor((255.0 * a) as u8, (255.0 * a) as u8, 255)
            } else {
                let a = 1.0 - t;
                RGBColor(255, (255.0 * a) as u8, (255.0 * a) as u8)
            }
        };
        if let Some((title, g)) = diverging {
            draw(&areas[count - 1], title, g, &diverge)?;
        }
        // Colour bars.
        let bars = bar.split_evenly((1, count));
        let fmax_label = format!("log10(f / f_max), f_max = {fmax:.3e} 1/(m² sr)");
        for b in bars.iter().take(panels.len()) {
            let colour = |v: f64| viridis((v + decades) / decades);
            crate::plot::colour_bar(&b.split_vertically(80).0, (-decades, 0.0), &fmax_label, 9, &colour)?;
        }
        if diverging.is_some() {
            let (b, keys) = bars[count - 1].split_vertically(80);
            crate::plot::colour_bar(&b, (-1.0, 1.0), "(simulated − measured) / measured", 9, &diverge)?;
            let font = ("sans-serif", 14).into_font();
            for (k, (c, label)) in
                [(MASKED, "masked"), (UNDER, "< −1 (clipped)"), (OVER, "> +1 (clipped)")].iter().enumerate()
            {
                let x = 55 + 170 * k as i32;
                keys.draw(&Rectangle::new([(x, 6), (x + 22, 22)], c.filled())).map_err(perr)?;
                keys.draw(&Text::new(*label, (x + 28, 6), font.clone())).map_err(perr)?;
            }
        }
        Ok(())
    })
}

/// One profile: its label, values and optional standard errors.
pub type ProfileCurve<'a> = (&'a str, &'a [f64], Option<&'a [f64]>);

/// Profiles along x (log scale) with optional error bars, and the beam
/// profile on a secondary axis.
pub fn profile_png(x_mm: &[f64], curves: &[ProfileCurve], beam: Option<&[f64]>) -> Result<Vec<u8>, PlotError> {
    let positive: Vec<f64> = curves.iter().flat_map(|(_, v, _)| v.iter().copied()).filter(|v| *v > 0.0).collect();
    let hi = positive.iter().copied().fold(0.0, f64::max) * 2.0;
    let lo = (hi * 1e-5).max(positive.iter().copied().fold(f64::INFINITY, f64::min) / 2.0);
    if !(hi > 0.0 && lo.is_finite()) {
        return Err(perr("profile has no positive values"));
    }
    let (x0, x1) = (x_mm.first().copied().unwrap_or(-1.0), x_mm.last().copied().unwrap_or(1.0));
    render_png(1220, 600, |root| {
        // The legend in a column of its own, so it never covers a curve.
        let (root, legend) = root.split_horizontally(1000);
        let mut items: Vec<(String, crate::plot::Mark)> = curves
            .iter()
            .enumerate()
            .map(|(k, c)| (c.0.to_string(), crate::plot::Mark::Line(crate::plot::palette(k), 2)))
            .collect();
        if beam.is_some() {
            items.push(("beam (right axis)".into(), crate::plot::Mark::Line(RGBColor(120, 120, 120), 1)));
        }
        crate::plot::legend_column(&legend, 60, &items)?;
        let mut chart = ChartBuilder::on(&root)
            .margin(15)
            .caption("profile along the plane of incidence", ("sans-serif", 20))
            .x_label_area_size(40)
            .y_label_area_size(80)
            .right_y_label_area_size(60)
            .build_cartesian_2d(x0..x1, crate::plot::log_axis(lo, hi))
            .map_err(perr)?
            .set_secondary_coord(x0..x1, 0.0..1.05);
        chart
            .configure_mesh()
            .x_desc("x [mm]")
            .y_desc("f_ssr [1/(m² sr)]")
            .y_label_formatter(&|v| crate::plot::short_number(*v))
            .draw()
            .map_err(perr)?;
        for (k, (name, values, err)) in curves.iter().enumerate() {
            let colour = crate::plot::palette(k);
            let pts: Vec<(f64, f64)> =
                x_mm.iter().zip(values.iter()).filter(|(_, v)| **v > 0.0).map(|(x, v)| (*x, *v)).collect();
            chart
                .draw_series(LineSeries::new(pts, colour.stroke_width(2)))
                .map_err(perr)?
                .label(*name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(2)));
            if let Some(e) = err {
                chart
                    .draw_series(
                        x_mm.iter()
                            .zip(values.iter())
                            .zip(e.iter())
                            .filter(|((_, v), s)| **v - **s > 0.0)
                            .map(|((x, v), s)| PathElement::new(vec![(*x, v - s), (*x, v + s)], colour.mix(0.5))),
                    )
                    .map_err(perr)?;
            }
        }
        if let Some(b) = beam {
            chart.configure_secondary_axes().y_desc("beam (relative)").draw().map_err(perr)?;
            let grey = RGBColor(120, 120, 120);
            chart
                .draw_secondary_series(LineSeries::new(x_mm.iter().zip(b).map(|(x, v)| (*x, *v)), grey.stroke_width(1)))
                .map_err(perr)?
                .label("beam")
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey));
        }
        Ok(())
    })
}

/// Metrics of a simulated slice against a measured one, as written to
/// `comparison.json` (`lucent bssrdf compare`) and read back by the report.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Comparison {
    /// Mean over the mask of ((sim − meas)/meas)².
    #[serde(deserialize_with = "f64_or_nan")]
    pub mean_squared_relative_error: f64,
    /// Measured pixels above threshold × max(measured) form the mask.
    pub threshold: f64,
    pub mask_pixels: usize,
    pub measured_sum: f64,
    pub simulated_sum: f64,
    /// simulated_sum / measured_sum.
    #[serde(deserialize_with = "f64_or_nan")]
    pub sum_ratio: f64,
    pub pixels: usize,
    pub pixel_mm: f64,
}

/// Compares two grids of the same size and pixel pitch (a mismatch is an
/// error, never a silent resample). The returned grid holds (s − m)/m over
/// the mask and NaN outside it.
pub fn compare(measured: &Grid, simulated: &Grid, threshold: f64) -> Result<(Comparison, Grid), ComparisonError> {
    if measured.size != simulated.size {
        return Err(ComparisonError::Size { measured: measured.size, simulated: simulated.size });
    }
    if (measured.pixel_m / simulated.pixel_m - 1.0).abs() > 1e-6 {
        return Err(ComparisonError::PixelSize {
            measured_mm: measured.pixel_m * 1e3,
            simulated_mm: simulated.pixel_m * 1e3,
        });
    }
    if !(threshold.is_finite() && (0.0..1.0).contains(&threshold)) {
        return Err(ComparisonError::Threshold(threshold));
    }
    let mmax = measured.values.iter().copied().fold(0.0, f64::max);
    if mmax <= 0.0 {
        return Err(ComparisonError::NoPositiveMeasured);
    }
    let cut = threshold * mmax;
    let mut acc = 0.0;
    let mut count = 0usize;
    let rel: Vec<f64> = measured
        .values
        .iter()
        .zip(&simulated.values)
        .map(|(m, s)| {
            if *m > cut && *m > 0.0 {
                let r = (s - m) / m;
                acc += r * r;
                count += 1;
                r
            } else {
                f64::NAN
            }
        })
        .collect();
    let (ms, ss) = (measured.sum(), simulated.sum());
    Ok((
        Comparison {
            mean_squared_relative_error: if count > 0 { acc / count as f64 } else { f64::NAN },
            threshold,
            mask_pixels: count,
            measured_sum: ms,
            simulated_sum: ss,
            sum_ratio: ss / ms,
            pixels: measured.size,
            pixel_mm: measured.pixel_m * 1e3,
        },
        Grid { size: measured.size, pixel_m: measured.pixel_m, values: rel },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(values: Vec<f64>) -> Grid {
        let size = (values.len() as f64).sqrt() as usize;
        Grid { size, pixel_m: 1e-4, values }
    }

    #[test]
    fn beam_profile_uses_the_footprint_geometry() {
        // θ = φ = 45°: along x the footprint's variance is σ²(cos²φ/cos²θ +
        // sin²φ) = 1.5 σ², a stretch of √1.5 ≈ 1.22 of σ along y = 0 … but
        // the row y = 0 cuts the tilted ellipse: its width along x is set by
        // the inverse covariance, 1/(C⁻¹)ₓₓ = σ²/(cos²φ cos²θ + sin²φ)
        // = σ²/0.75, a stretch of 1/√0.75 ≈ 1.1547.
        let beam = Beam::gaussian(200e-6).unwrap();
        let dirs = Directions::from_degrees(45.0, 45.0, 0.0, 180.0).unwrap();
        let sigma_mm = lucent_render::slab::fwhm_to_sigma(0.2);
        let x = [0.0, sigma_mm];
        let b = beam_profile(&beam, &dirs, &x);
        let stretch = (-0.5 / b[1].ln()).sqrt();
        assert!((stretch - 1.0 / 0.75f64.sqrt()).abs() < 1e-9, "stretch {stretch}");
        // In the plane of incidence (φ = 0) the stretch is 1/cos θ.
        let dirs = Directions::from_degrees(45.0, 0.0, 0.0, 180.0).unwrap();
        let b = beam_profile(&beam, &dirs, &x);
        let stretch = (-0.5 / b[1].ln()).sqrt();
        assert!((stretch - 2f64.sqrt()).abs() < 1e-9, "stretch {stretch}");
    }

    #[test]
    fn comparison_metrics() {
        let m = grid(vec![1.0, 2.0, 0.001, 4.0]);
        let s = grid(vec![1.1, 2.0, 5.0, 2.0]);
        let (c, rel) = compare(&m, &s, 0.01).unwrap();
        assert_eq!(c.mask_pixels, 3);
        let expected = (0.1f64.powi(2) + 0.0 + 0.5f64.powi(2)) / 3.0;
        assert!((c.mean_squared_relative_error - expected).abs() < 1e-12);
        assert!((c.sum_ratio - 10.1 / 7.001).abs() < 1e-12);
        assert!(rel.values[2].is_nan());
        assert!(compare(&m, &grid(vec![1.0; 9]), 0.01).unwrap_err().to_string().contains("size"));
        let mut other = s.clone();
        other.pixel_m = 2e-4;
        assert!(compare(&m, &other, 0.01).unwrap_err().to_string().contains("pixel size"));
    }

    #[test]
    fn csv_grids_are_checked() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.csv");
        std::fs::write(&p, "# measured\n1, 2\n3 4\n").unwrap();
        let g = read_grid(&p, Some(0.1)).unwrap();
        assert_eq!(g.values, vec![1.0, 2.0, 3.0, 4.0]);
        std::fs::write(&p, "1,2,3\n4,5,6\n").unwrap();
        assert!(read_grid(&p, Some(0.1)).unwrap_err().to_string().contains("square"));
        std::fs::write(&p, "1,nan\n3,4\n").unwrap();
        assert!(read_grid(&p, Some(0.1)).unwrap_err().to_string().contains("finite"));
        std::fs::write(&p, "1,2\n3\n").unwrap();
        assert!(read_grid(&p, Some(0.1)).is_err());
        std::fs::write(&p, "1,2\n3,4\n").unwrap();
        assert!(read_grid(&p, None).unwrap_err().to_string().contains("pixel size"));
        std::fs::write(dir.path().join("m.csv.json"), r#"{"pixel_mm": 0.1029}"#).unwrap();
        assert!((read_grid(&p, None).unwrap().pixel_m - 0.1029e-3).abs() < 1e-15);
    }
}
