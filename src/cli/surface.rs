//! `lucent surface`: height maps → microfacet normal distribution (docs/method.md#surface).
//! Argument handling and printing only: `surface fit`'s flags become a
//! [`SurfaceFitJob`], whose `run` reads, fits and writes
//! ([`crate::surface::SurfaceFitFiles`]); `surface synth` writes with
//! [`crate::surface::synth`].

use super::choices::named;
use crate::job::surface_fit::defaults;
use crate::job::{Context, SurfaceFitJob};
use crate::surface::model::RoughnessModel;
use crate::surface::synth::{synthesize, SynthSpec};
use crate::surface::x3p::{write_x3p, PointType, WriteOptions};
use crate::surface::LengthUnit;
use anyhow::{bail, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum SurfaceCommand {
    /// Fit Trowbridge–Reitz and Beckmann distributions to a height map: fit.json, heightmap.png, distribution.png, normals.exr.
    Fit(FitArgs),
    /// Write a synthetic Gaussian random surface with known slope statistics as X3P.
    Synth(SynthArgs),
}

#[derive(Debug, Args)]
pub struct FitArgs {
    /// Height map: .x3p (ISO 25178-72), .csv/.txt/.asc/.dat grid, 32-bit float .tif/.tiff or .exr.
    pub heightmap: PathBuf,
    /// Point spacing in µm (required for TIFF/EXR and header-less text; overrides the file's).
    #[arg(long, allow_hyphen_values = true)]
    pub pitch_um: Option<f64>,
    /// Row spacing in µm, if it differs from --pitch-um.
    #[arg(long, requires = "pitch_um", allow_hyphen_values = true)]
    pub pitch_y_um: Option<f64>,
    /// Unit of the stored heights: m, mm, um, nm (required for TIFF/EXR and text grids without one).
    #[arg(long, value_parser = named::<LengthUnit>())]
    pub height_unit: Option<LengthUnit>,
    /// Side k of the k × k window of the per-pixel plane fits (odd, 3 … 201).
    #[arg(long, default_value_t = defaults::WINDOW)]
    pub window: usize,
    /// σ of the Gaussian weights of the plane fits, in pixels.
    #[arg(long, default_value_t = defaults::SIGMA_PX, allow_hyphen_values = true)]
    pub sigma_px: f64,
    /// Minimum fraction of the window's weight on valid points for a pixel to get a normal.
    #[arg(long, default_value_t = defaults::MIN_WEIGHT, allow_hyphen_values = true)]
    pub min_weight: f64,
    /// Keep the global tilt (do not subtract the least-squares plane first).
    #[arg(long)]
    pub keep_tilt: bool,
    /// Fit a tilt of the distribution's axis as a third parameter.
    #[arg(long)]
    pub fit_tilt: bool,
    /// Output folder (created; fit.json, heightmap.png, distribution.png, normals.exr in it are replaced).
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct SynthArgs {
    /// Distribution the slopes follow: tr (Trowbridge–Reitz/GGX) or beckmann.
    #[arg(long, value_parser = named::<RoughnessModel>())]
    pub model: RoughnessModel,
    /// Roughness α of the slope distribution.
    #[arg(long, allow_hyphen_values = true)]
    pub alpha: f64,
    /// Grid size NX or NXxNY.
    #[arg(long, default_value = "256")]
    pub size: String,
    /// Point spacing in µm.
    #[arg(long, default_value_t = 0.871, allow_hyphen_values = true)]
    pub pitch_um: f64,
    /// Correlation length of the heights in pixels.
    #[arg(long, default_value_t = 8.0, allow_hyphen_values = true)]
    pub correlation_px: f64,
    /// Correlation length of the local amplitude (tr only) in pixels; default 8 × --correlation-px.
    #[arg(long, allow_hyphen_values = true)]
    pub amplitude_correlation_px: Option<f64>,
    /// Random seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Tilt of an added plane in degrees.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub tilt_deg: f64,
    /// Azimuth of the added plane's normal in degrees.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub tilt_azimuth_deg: f64,
    /// Fraction of points marked invalid at random.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub invalid_fraction: f64,
    /// X3P point type: I (int16), L (int32), F (float32), D (float64).
    #[arg(long, value_parser = named::<PointType>(), default_value = "D")]
    pub point_type: PointType,
    /// Output .x3p file.
    #[arg(long)]
    pub out: PathBuf,
}

pub fn run(c: SurfaceCommand) -> Result<()> {
    match c {
        SurfaceCommand::Fit(a) => fit(a),
        SurfaceCommand::Synth(a) => synth(a),
    }
}

/// Runs `lucent surface fit`: the job of the flags ([`SurfaceFitJob::run`]),
/// then its summary on stdout.
fn fit(a: FitArgs) -> Result<()> {
    let done = SurfaceFitJob::from(&a).run(&Context::default())?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(())
}

fn synth(a: SynthArgs) -> Result<()> {
    if !a.out.extension().is_some_and(|e| e.eq_ignore_ascii_case("x3p")) {
        bail!("--out {}: the output is an X3P file (NAME.x3p)", a.out.display());
    }
    let model = a.model;
    let (nx, ny) = match a.size.split_once(['x', 'X']) {
        Some((x, y)) => (x.trim().parse::<usize>(), y.trim().parse::<usize>()),
        None => (a.size.trim().parse::<usize>(), a.size.trim().parse::<usize>()),
    };
    let (Ok(nx), Ok(ny)) = (nx, ny) else { bail!("--size {:?}: expected N or NXxNY, e.g. 256 or 512x256", a.size) };
    if !(a.pitch_um.is_finite() && a.pitch_um > 0.0) {
        bail!("--pitch-um {}: must be a positive finite number", a.pitch_um);
    }
    let point_type = a.point_type;
    let spec = SynthSpec {
        nx,
        ny,
        pitch_m: a.pitch_um * 1e-6,
        alpha: a.alpha,
        model,
        correlation_px: a.correlation_px,
        amplitude_correlation_px: a.amplitude_correlation_px.unwrap_or(8.0 * a.correlation_px),
        seed: a.seed,
        tilt_rad: a.tilt_deg.to_radians(),
        tilt_azimuth_rad: a.tilt_azimuth_deg.to_radians(),
        invalid_fraction: a.invalid_fraction,
    };
    let s = synthesize(&spec)?;
    let comment = format!(
        "lucent surface synth --model {} --alpha {} --size {}x{} --pitch-um {} --correlation-px {} --seed {} --tilt-deg {} --tilt-azimuth-deg {} --invalid-fraction {} --point-type {:?}",
        <&str>::from(a.model), a.alpha, nx, ny, a.pitch_um, a.correlation_px, a.seed, a.tilt_deg, a.tilt_azimuth_deg, a.invalid_fraction, point_type
    );
    write_x3p(&a.out, &s.map, &WriteOptions { point_type, comment: Some(comment), ..WriteOptions::default() })?;
    println!(
        "{}: {} × {} {}-like surface, α {}, {} valid points, point type {:?}",
        a.out.display(),
        nx,
        ny,
        RoughnessModel::label(model),
        a.alpha,
        s.map.valid_count(),
        point_type
    );
    Ok(())
}
