//! Surface topography → microfacet normal distribution (docs/method.md#surface).
//!
//! From a profilometer height map to a fitted Trowbridge–Reitz or Beckmann
//! distribution of microfacet normals:
//!
//! 1. **Reading** ([`read_height_map`]): ISO 25178-72 X3P ([`x3p`]: zip with
//!    `main.xml`, binary point data of any of the four point types I, L, F,
//!    D or an XML `DataList`, validity bit masks, MD5 checksums), text/CSV
//!    grids with the pitch in a header or from the command line, and 32-bit
//!    float TIFF and single-channel EXR with the pitch from the command line
//!    ([`grid`]). Heights and pitches are in metres from here on. Invalid
//!    points (NaN, ±inf, masked in an X3P validity file, empty fields) are
//!    excluded from everything; they are never read as zero.
//! 2. **Levelling** ([`normals::fit_plane`]): one least-squares plane
//!    z = z̄ + s_x (x − x̄) + s_y (y − ȳ) over all valid points is removed; its
//!    tilt atan(√(s_x² + s_y²)) and the azimuth of its normal are reported.
//! 3. **Normals** ([`normals::plane_fit_normals`]): at every pixel a
//!    Gaussian-weighted least-squares plane over a k × k window (default
//!    15 × 15, σ = 1 px) gives the microfacet normal
//!    m = (−∂h/∂x, −∂h/∂y, 1)/‖·‖. Roughness parameters S_q and S_dq
//!    (ISO 25178-2) are computed on the levelled map ([`normals::roughness`]).
//! 4. **Distribution** ([`distribution::measure`]): a histogram of θ_m
//!    normalised so that ∫ D(m)(m·n) dω_m = 1 (each pixel stands for the same
//!    projected area, so the histogram of pixel normals estimates D(m)(m·n)),
//!    bin width by the Freedman–Diaconis rule on θ_m, and a 2-D (θ, φ)
//!    histogram with a slope-anisotropy measure.
//! 5. **Fits** ([`fit::fit_model`]): least squares of the binned D against
//!    s · D_α (Trowbridge–Reitz or Beckmann, scale s, optionally a tilt τ of
//!    the distribution's axis); α, s, τ, MSE and the better model.
//!
//! Coordinates: column i ↦ x = i·Δx, row j ↦ y = j·Δy for every format (the
//! X3P storage order, x fastest), z up, right-handed. Images written for
//! people (`heightmap.png`, `normals.exr`) show y increasing upwards, so
//! they are the surface seen from above.
//!
//! ```
//! use lucent::surface::{fit_surface, FitOptions};
//! use lucent::surface::synth::{synthesize, SynthSpec};
//! use lucent::surface::model::RoughnessModel;
//! // A Beckmann-like Gaussian random surface with α = 0.05, 256 × 256 at 0.871 µm.
//! let spec = SynthSpec { nx: 256, ny: 256, alpha: 0.05, model: RoughnessModel::Beckmann, ..SynthSpec::default() };
//! let map = synthesize(&spec).unwrap().map;
//! let fit = fit_surface(&map, &FitOptions::default()).unwrap();
//! assert_eq!(fit.report.better_model, RoughnessModel::Beckmann);
//! assert!((fit.report.fits.beckmann.alpha / 0.05 - 1.0).abs() < 0.05);
//! ```

pub mod distribution;
mod error;
pub mod fit;
pub mod grid;
mod map;
pub mod model;
pub mod normals;
mod options;
pub mod plot;
mod report;
pub mod synth;
pub mod x3p;

use crate::surface::model::RoughnessModel;
use serde::Deserialize;
use std::path::{Path, PathBuf};

pub use error::SurfaceError;
pub use grid::{read_height_map, LengthUnit, ReadOptions};
pub use map::{HeightMap, MAX_HEIGHT_M};
pub use options::FitOptions;
pub use report::{FitReport, Fits, InputSummary, TiltReport};

/// The result of [`fit_surface`]: the report, the levelled map and the normals.
#[derive(Debug, Clone)]
pub struct SurfaceFit {
    pub report: FitReport,
    pub levelled: HeightMap,
    pub normals: normals::NormalField,
}

/// Schema name written into `fit.json`.
pub const FIT_SCHEMA: &str = "lucent.surface.fit/1";

/// The whole pipeline of this module on one height map: levelling, normals,
/// S_q/S_dq, distribution and both fits.
pub fn fit_surface(map: &HeightMap, options: &FitOptions) -> Result<SurfaceFit, SurfaceError> {
    options.validate()?;
    let start = std::time::Instant::now();
    let plane = normals::fit_plane(map)?;
    let levelled = if options.remove_tilt { normals::remove_plane(map, &plane) } else { map.clone() };
    let roughness = normals::roughness(&levelled);
    let field = normals::plane_fit_normals(&levelled, options)?;
    let mut roughness = roughness;
    roughness.sdq_plane_fit = field.rms_slope();
    let dist = distribution::measure(&field, &map.origin)?;
    let tr = fit::fit_model(&dist, RoughnessModel::TrowbridgeReitz, options.fit_tilt)?;
    let beckmann = fit::fit_model(&dist, RoughnessModel::Beckmann, options.fit_tilt)?;
    let better_model =
        if tr.mse_per_sr2 <= beckmann.mse_per_sr2 { RoughnessModel::TrowbridgeReitz } else { RoughnessModel::Beckmann };
    let valid = map.valid_count();
    let report = FitReport {
        schema: FIT_SCHEMA.into(),
        input: InputSummary {
            origin: map.origin.clone(),
            nx: map.nx,
            ny: map.ny,
            pitch_x_m: map.pitch_x_m,
            pitch_y_m: map.pitch_y_m,
            valid_points: valid,
            invalid_points: map.nx * map.ny - valid,
            notes: map.notes.clone(),
        },
        options: *options,
        global_plane: TiltReport {
            slope_x: plane.slope_x,
            slope_y: plane.slope_y,
            tilt_deg: plane.tilt_rad().to_degrees(),
            normal_azimuth_deg: plane.normal_azimuth_rad().to_degrees(),
            removed: options.remove_tilt,
        },
        roughness,
        distribution: dist,
        fits: Fits { trowbridge_reitz: tr, beckmann },
        better_model,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok(SurfaceFit { report, levelled, normals: field })
}

/// The part of a `fit.json` a recipe needs.
#[derive(Debug, Deserialize)]
struct FitFileHead {
    schema: String,
    better_model: RoughnessModel,
    fits: FitFileFits,
}

#[derive(Debug, Deserialize)]
struct FitFileFits {
    #[serde(rename = "trowbridge-reitz")]
    trowbridge_reitz: FitFileModel,
    beckmann: FitFileModel,
}

#[derive(Debug, Deserialize)]
struct FitFileModel {
    alpha: f64,
    scale: f64,
}

/// Reads a `fit.json` written by `lucent surface fit` and returns
/// (model, α, scale) of `model`, or of the better model when `None`.
pub fn load_fit_choice(path: &Path, model: Option<RoughnessModel>) -> Result<(RoughnessModel, f64, f64), SurfaceError> {
    let text = crate::io::read_text(path).map_err(|source| SurfaceError::Io { path: path.into(), source })?;
    let head: FitFileHead = serde_json::from_str(&text).map_err(|e| SurfaceError::Format {
        path: path.into(),
        reason: format!("not a fit.json of `lucent surface fit`: {e}"),
    })?;
    if head.schema != FIT_SCHEMA {
        return Err(SurfaceError::Format {
            path: path.into(),
            reason: format!("schema {:?}, expected {FIT_SCHEMA:?}", head.schema),
        });
    }
    let model = model.unwrap_or(head.better_model);
    let m = match model {
        RoughnessModel::TrowbridgeReitz => &head.fits.trowbridge_reitz,
        RoughnessModel::Beckmann => &head.fits.beckmann,
    };
    if !(m.alpha.is_finite() && m.alpha > 0.0 && m.scale.is_finite() && m.scale > 0.0) {
        return Err(SurfaceError::Format {
            path: path.into(),
            reason: format!("fit of {model:?} has α = {}, scale = {}: not positive", m.alpha, m.scale),
        });
    }
    // The range every microfacet α has (a fitted one as a typed one).
    model::check_alpha(m.alpha)
        .map_err(|e| SurfaceError::Format { path: path.into(), reason: format!("fit of {model:?}: {e}") })?;
    Ok((model, m.alpha, m.scale))
}

/// Files [`write_fit_outputs`] writes into the output folder.
pub const OUTPUT_FILES: [&str; 4] = SurfaceFitFiles::NAMES;

/// The files of a surface fit ([`write_fit_outputs`]), each name spelled
/// here once: the [`FitReport`] (`json`), the levelled height map
/// (`heightmap_png`), the distribution and its fits (`distribution_png`)
/// and the normals (`normals_exr`).
///
/// ```
/// use lucent::surface::SurfaceFitFiles;
/// let f = SurfaceFitFiles::in_dir(std::path::Path::new("out/surface"));
/// assert_eq!(f.json, std::path::Path::new("out/surface/fit.json"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SurfaceFitFiles {
    pub json: PathBuf,
    pub heightmap_png: PathBuf,
    pub distribution_png: PathBuf,
    pub normals_exr: PathBuf,
}

impl SurfaceFitFiles {
    /// The file names, in the order they are listed.
    pub const NAMES: [&'static str; 4] = ["fit.json", "heightmap.png", "distribution.png", "normals.exr"];

    /// The files of the fit whose output folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [json, heightmap_png, distribution_png, normals_exr] = Self::NAMES.map(|n| dir.join(n));
        Self { json, heightmap_png, distribution_png, normals_exr }
    }

    /// Every file, in the order of [`SurfaceFitFiles::NAMES`].
    pub fn all(&self) -> [&Path; 4] {
        [&self.json, &self.heightmap_png, &self.distribution_png, &self.normals_exr]
    }
}

/// Writes `fit.json`, `heightmap.png`, `distribution.png` and `normals.exr`
/// into `out`, all or nothing: the files are written into a temporary
/// sibling folder and moved into place only when all four exist.
///
/// `normals.exr`: 32-bit float, R, G, B = the unit normal's x, y, z, A = 1
/// where the pixel has a normal and 0 (with R = G = B = 0) where it has
/// none; the top row is the largest y, as in `heightmap.png`.
pub fn write_fit_outputs(out: &Path, fit: &SurfaceFit) -> Result<SurfaceFitFiles, SurfaceError> {
    use crate::io::{write_atomic, write_json};
    let io_err = |p: &Path| {
        let p = p.to_path_buf();
        move |source| SurfaceError::Io { path: p, source }
    };
    let title = format!(
        "levelled height map, {} × {} at {:.4} × {:.4} µm",
        fit.levelled.nx,
        fit.levelled.ny,
        fit.levelled.pitch_x_m * 1e6,
        fit.levelled.pitch_y_m * 1e6
    );
    let heightmap = plot::heightmap_png(&fit.levelled, &title)
        .map_err(|source| SurfaceError::Plot { path: out.join(OUTPUT_FILES[1]), source })?;
    let distribution = plot::distribution_png(&fit.report)
        .map_err(|source| SurfaceError::Plot { path: out.join(OUTPUT_FILES[2]), source })?;
    let (nx, ny) = (fit.normals.nx, fit.normals.ny);
    let mut planes = vec![vec![0f32; nx * ny]; 4];
    for j in 0..ny {
        for i in 0..nx {
            if let Some(n) = fit.normals.normal(i, j) {
                let k = (ny - 1 - j) * nx + i;
                planes[0][k] = n[0] as f32;
                planes[1][k] = n[1] as f32;
                planes[2][k] = n[2] as f32;
                planes[3][k] = 1.0;
            }
        }
    }
    let parent = out.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    std::fs::create_dir_all(parent).map_err(io_err(parent))?;
    if out.exists() && !out.is_dir() {
        return Err(SurfaceError::Io { path: out.into(), source: std::io::Error::other("exists and is not a folder") });
    }
    let name = out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_else(|| "surface".into());
    let tmp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(io_err(&tmp))?;
    }
    let result = (|| -> Result<(), SurfaceError> {
        std::fs::create_dir_all(&tmp).map_err(io_err(&tmp))?;
        write_json(&tmp.join(OUTPUT_FILES[0]), &fit.report)?;
        write_atomic(&tmp.join(OUTPUT_FILES[1]), &heightmap)?;
        write_atomic(&tmp.join(OUTPUT_FILES[2]), &distribution)?;
        crate::exr::write_channels(
            &tmp.join(OUTPUT_FILES[3]),
            nx,
            ny,
            &[("R", &planes[0]), ("G", &planes[1]), ("B", &planes[2]), ("A", &planes[3])],
        )?;
        if out.is_dir() {
            for f in OUTPUT_FILES {
                std::fs::rename(tmp.join(f), out.join(f)).map_err(io_err(&out.join(f)))?;
            }
            std::fs::remove_dir(&tmp).map_err(io_err(&tmp))?;
        } else {
            std::fs::rename(&tmp, out).map_err(io_err(out))?;
        }
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_dir_all(&tmp);
    }
    result?;
    Ok(SurfaceFitFiles::in_dir(out))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fit.json's α is held to the range of every microfacet α ([0, 4]),
    /// as `tr:ALPHA` is: an edited α = 7 is refused naming the file.
    #[test]
    fn a_fitted_alpha_has_the_range_of_every_alpha() {
        let dir = tempfile::tempdir().expect("a temporary folder");
        let path = dir.path().join("fit.json");
        let fit = |alpha: f64| {
            format!(
                r#"{{"schema": "{FIT_SCHEMA}", "better_model": "trowbridge-reitz",
                    "fits": {{"trowbridge-reitz": {{"alpha": {alpha}, "scale": 1.0}}, "beckmann": {{"alpha": 0.01, "scale": 1.0}}}}}}"#
            )
        };
        std::fs::write(&path, fit(0.0084)).expect("write");
        let (model, alpha, _) = load_fit_choice(&path, None).expect("a valid fit");
        assert_eq!((model, alpha), (RoughnessModel::TrowbridgeReitz, 0.0084));
        std::fs::write(&path, fit(7.0)).expect("write");
        let e = load_fit_choice(&path, None).expect_err("α = 7 is out of range").to_string();
        assert!(e.contains("fit.json") && e.contains("α = 7 must be a number in [0, 4]"), "{e}");
    }
}
