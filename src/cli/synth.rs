//! `lucent synth …`: synthetic inputs with a known truth (the demo's capture,
//! tests): a ColorChecker chart image and RAW captures (DNG) of linear images
//! through a known camera colour matrix and Bayer sensor. See
//! [`crate::synth`].

use super::choices::named;
use crate::imageio::{self, RgbImage};
use crate::synth::{self, dng, ColourTruth, InputSpace, Sensor};
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum SynthCommand {
    /// A ColorChecker Classic image in CIE XYZ (D50) with its patch corners, for `synth raw --space xyz-d50`.
    Chart(ChartArgs),
    /// A Bayer RAW capture (DNG) of a linear image through a known camera colour matrix, with shot and read noise.
    Raw(RawArgs),
}

#[derive(Debug, Args)]
pub struct ChartArgs {
    /// Image size WIDTHxHEIGHT in pixels.
    #[arg(long, default_value = "480x320")]
    pub size: String,
    /// Background luminance as a fraction of the D50 white.
    #[arg(long, default_value_t = 0.2)]
    pub background: f64,
    /// Output image (.exr, linear XYZ D50).
    #[arg(long)]
    pub out: PathBuf,
}

#[derive(Debug, Args)]
pub struct RawArgs {
    /// Linear input image (.exr).
    pub input: PathBuf,
    /// Output DNG.
    pub output: PathBuf,
    /// The camera's colour response: a truth_colour.json (xyz_d50_to_camera).
    #[arg(long)]
    pub truth: PathBuf,
    /// Colour space of the input: cie-rgb (a render) or xyz-d50 (`synth chart`).
    #[arg(long, value_parser = named::<InputSpace>(), default_value = "cie-rgb")]
    pub space: InputSpace,
    /// Camera RGB × exposure = fraction of the white level.
    #[arg(long, default_value_t = 0.5)]
    pub exposure: f64,
    /// Electrons at the white level (shot noise); 0 = no shot noise.
    #[arg(long, default_value_t = 20000.0)]
    pub full_well: f64,
    /// Read noise in digital numbers.
    #[arg(long, default_value_t = 2.0)]
    pub read_noise: f64,
    /// Seed of the noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Leave the DNG without its NoiseProfile tag (readers then estimate the noise from the image).
    #[arg(long)]
    pub no_noise_profile: bool,
}

/// Runs a `lucent synth` subcommand.
pub fn run(cmd: SynthCommand) -> Result<()> {
    match cmd {
        SynthCommand::Chart(a) => chart(a),
        SynthCommand::Raw(a) => raw(a),
    }
}

fn chart(a: ChartArgs) -> Result<()> {
    let (w, h) = super::common::parse_size(&a.size).with_context(|| format!("--size {:?}", a.size))?;
    if w < 60 || h < 40 {
        bail!("--size {}: the chart needs at least 60x40 pixels", a.size);
    }
    if !(a.background >= 0.0 && a.background.is_finite()) {
        bail!("--background {}: must be a finite fraction ≥ 0 of the white", a.background);
    }
    let (fw, fh) = (w as f64, h as f64);
    // The 4 × 6 grid (gap 0.14) with a tenth of the image as margin, slightly keystoned.
    let corners = [[0.10 * fw, 0.12 * fh], [0.90 * fw, 0.10 * fh], [0.89 * fw, 0.88 * fh], [0.11 * fw, 0.90 * fh]];
    let img = synth::chart_image(w, h, corners, a.background)?;
    check_exr(&a.out)?;
    imageio::write_exr(&a.out, &img)?;
    let list = corners.iter().flatten().map(|v| format!("{v:.2}")).collect::<Vec<_>>().join(",");
    println!("{}: ColorChecker in XYZ (D50), {w} × {h} px; --corners {list}", a.out.display());
    Ok(())
}

fn check_exr(path: &std::path::Path) -> Result<()> {
    if imageio::extension(path) != "exr" {
        bail!("{}: the output must be an .exr file (linear 32-bit float)", path.display());
    }
    Ok(())
}

fn raw(a: RawArgs) -> Result<()> {
    if imageio::extension(&a.output) != "dng" {
        bail!("{}: the output must be a .dng file", a.output.display());
    }
    let space = a.space;
    let truth = ColourTruth::load(&a.truth)?;
    if !(a.full_well >= 0.0 && a.full_well.is_finite()) {
        bail!("--full-well {}: must be a finite number of electrons ≥ 0 (0 = no shot noise)", a.full_well);
    }
    let sensor = Sensor {
        full_well_e: if a.full_well == 0.0 { f64::INFINITY } else { a.full_well },
        read_noise_dn: a.read_noise,
        ..Sensor::default()
    };
    let img: RgbImage = imageio::read_rgb(&a.input)?;
    let to_camera = synth::to_camera_matrix(space, &truth.xyz_d50_to_camera)?;
    let cap = synth::capture_mosaic(&img, &to_camera, a.exposure, &sensor, a.seed)?;
    let model = format!("lucent synthetic {}", truth.camera);
    let mut file = dng::CfaDng::of_capture(&cap, &sensor, truth.xyz_d50_to_camera, &model);
    if a.no_noise_profile {
        file.noise_profile = None;
    }
    dng::write_cfa_dng(&a.output, &file).with_context(|| format!("{}", a.output.display()))?;
    let share = cap.clipped as f64 / cap.data.len() as f64;
    println!(
        "{} → {}: {} × {} RGGB, exposure {}, {} photosites clipped ({:.3} %); noise: variance = {:.4e} x + {:.4e}{}",
        a.input.display(),
        a.output.display(),
        cap.width,
        cap.height,
        a.exposure,
        cap.clipped,
        100.0 * share,
        sensor.noise_profile()[0],
        sensor.noise_profile()[1],
        if a.no_noise_profile { " (not written)" } else { " (NoiseProfile)" }
    );
    if share > 0.05 {
        eprintln!(
            "warning: {}: {:.2} % of the photosites are clipped; lower --exposure (`lucent raw clipped` masks them)",
            a.output.display(),
            100.0 * share
        );
    }
    Ok(())
}
