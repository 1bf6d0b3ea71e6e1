//! `lucent colour …`: ColorChecker calibration of a camera and applying
//! the fitted matrix to linear images (argument handling and printing: the
//! flags become a [`ColourCalibrateJob`] or [`ColourApplyJob`], which does
//! the work), and the RGB band values of spectral optical properties. The
//! colour science is in `lucent-colour`.

use super::choices::{named, AdaptationChoice};
use crate::ccm_file::ApplyTarget;
use crate::job::{ColourApplyJob, ColourCalibrateJob};
use crate::optics::bulk::{self, OpticalSpectrum};
use crate::optics::recipe::{Overrides, Recipe};
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use lucent_colour::bands::{band_weights, BandWeights, BANDS};
use lucent_colour::ccm::CcmMethod;
use lucent_colour::WavelengthGrid;
use serde::Serialize;
use std::path::PathBuf;

#[derive(Debug, Subcommand)]
pub enum ColourCommand {
    /// Fit a colour-correction matrix camera RGB → XYZ (D50) from a photo of a ColorChecker Classic 24.
    Calibrate(CalibrateArgs),
    /// Apply a fitted ccm.json to a linear image (photo or equirectangular HDR): camera RGB → CIE RGB, XYZ or linear sRGB.
    Apply(ApplyArgs),
    /// RGB band values of μs, μa and g of a recipe or an optical_properties.json, and the weights used.
    Bands(BandsArgs),
}

#[derive(Debug, Args)]
pub struct CalibrateArgs {
    /// Linear image of the chart (.exr, .hdr, .png, .tif; PNG/TIFF values are divided by their maximum).
    #[arg(long)]
    pub image: PathBuf,
    /// Outer corners of the 4 × 6 patch grid in pixels (x right, y down, image edge at 0):
    /// x1,y1,…,x4,y4 for the dark-skin, bluish-green, black and white corners (clockwise in the image).
    /// Without it the chart is found automatically (OpenCV's mcc detector).
    #[arg(long, allow_hyphen_values = true)]
    pub corners: Option<crate::job::ChartCorners>,
    /// Name of the camera, stored in ccm.json (default: the image's file name).
    #[arg(long)]
    pub camera: Option<String>,
    /// Fitting method: "Cheung 2004" (3 × 3 least squares), "Finlayson 2015" (root-polynomial,
    /// exposure invariant) or "Finlayson 1997" (white-point preserving).
    #[arg(long, value_parser = named::<CcmMethod>(), default_value = "Cheung 2004")]
    pub method: CcmMethod,
    /// Output folder for ccm.json, chart.png, delta_e.png and patches.png.
    #[arg(long)]
    pub out: PathBuf,
    /// The image is sRGB-encoded (an 8-bit photo as cameras and JPEGs deliver it): remove the
    /// sRGB transfer function before sampling. Not for RAW-derived linear images.
    #[arg(long)]
    pub decode_srgb: bool,
    /// A pixel with a channel ≥ this value (in the image as stored) is clipped; a patch with more
    /// than 1 % clipped pixels is refused. "none" disables the check.
    #[arg(long, default_value = crate::job::DEFAULT_CLIP_LEVEL)]
    pub clip_level: crate::job::ClipLevel,
    /// Gap between patches as a fraction of the patch side.
    #[arg(long, default_value_t = crate::job::DEFAULT_GAP_RATIO)]
    pub gap_ratio: f64,
    /// Side of the sampled square as a fraction of the patch side.
    #[arg(long, default_value_t = crate::job::DEFAULT_INNER_FRACTION)]
    pub inner_fraction: f64,
}

#[derive(Debug, Args)]
pub struct ApplyArgs {
    /// ccm.json written by `lucent colour calibrate`.
    #[arg(long)]
    pub ccm: PathBuf,
    /// Input image in the calibrated camera's RGB (.exr, .hdr, .png, .tif).
    pub input: PathBuf,
    /// Output image (.exr, 32-bit float, linear).
    pub output: PathBuf,
    /// Target space: cie-rgb (CIE 1931 RGB, white E), xyz (CIE XYZ, D50-adapted as fitted) or srgb (linear, D65).
    #[arg(long, value_parser = named::<ApplyTarget>(), default_value = "cie-rgb")]
    pub to: ApplyTarget,
    /// Chromatic adaptation from the fitted D50 to the target's white (cie-rgb: E, srgb: D65):
    /// bradford, cat02, von-kries or none.
    #[arg(long, value_enum, ignore_case = true, default_value = "bradford")]
    pub adaptation: AdaptationChoice,
    /// Also write the output's per-pixel variance (.exr, variance.R/G/B) from the RAW input's noise
    /// model (its DNG NoiseProfile, else estimated from the photo), with the model in a .json beside
    /// it: `lucent compare --photo-variance` (RAW input only).
    #[arg(long, value_name = "VARIANCE_EXR")]
    pub variance_out: Option<PathBuf>,
    /// Noise realisations averaged per pixel for --variance-out (per-pixel precision √(2/K)).
    #[arg(long, default_value_t = crate::job::DEFAULT_VARIANCE_REALISATIONS, value_parser = super::common::count_in::<2, 1000>, requires = "variance_out")]
    pub variance_realisations: usize,
    /// Seed of the noise realisations of --variance-out.
    #[arg(long, default_value_t = 1, requires = "variance_out")]
    pub seed: u64,
    /// Bin the output K × K (each pixel the mean of K × K developed pixels; both sides must be
    /// multiples of K): a photo at the resolution of a smaller render, with --variance-out binned alike.
    #[arg(long, value_name = "K", default_value_t = 1, value_parser = super::common::count_in::<1, 64>)]
    pub bin: usize,
}

#[derive(Debug, Args)]
pub struct BandsArgs {
    /// A recipe (.toml) or an optical_properties.json written by `lucent optics`.
    pub input: PathBuf,
    /// Wavelength grid START:END:STEP in nm, or one wavelength (recipes only).
    #[arg(long, default_value = "380:780:10")]
    pub wavelengths: String,
    /// Weight percentage for particle types whose recipe leaves it unknown.
    #[arg(long)]
    pub weight_percent: Option<f64>,
    /// Print JSON (band values and weights) instead of tables.
    #[arg(long)]
    pub json: bool,
}

/// Runs a `lucent colour` subcommand.
pub fn run(cmd: ColourCommand) -> Result<()> {
    match cmd {
        ColourCommand::Calibrate(a) => calibrate(a),
        ColourCommand::Apply(a) => apply(a),
        ColourCommand::Bands(a) => bands(a),
    }
}

/// `lucent colour calibrate`: the job of the flags
/// ([`ColourCalibrateJob::run`]), then its summary (the ΔE table) on stdout.
fn calibrate(a: CalibrateArgs) -> Result<()> {
    let done = ColourCalibrateJob::from(&a).run(&crate::job::Context::default())?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(())
}

/// `lucent colour apply`: the job of the flags ([`ColourApplyJob::run`]),
/// then its summary on stdout.
fn apply(a: ApplyArgs) -> Result<()> {
    let done = ColourApplyJob::from(&a).run(&crate::job::Context::default())?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(())
}

/// (sample, grid, μs, μa, g) of one sample.
type NamedSpectra = (String, WavelengthGrid, Vec<f64>, Vec<f64>, Vec<f64>);

/// Band values of one sample.
#[derive(Debug, Serialize)]
struct SampleBands {
    sample: String,
    mu_s_per_m: [f64; 3],
    mu_a_per_m: [f64; 3],
    g: [f64; 3],
}

fn bands(a: BandsArgs) -> Result<()> {
    let ext = a.input.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    let spectra: Vec<NamedSpectra> = match ext.as_str() {
        "toml" => {
            let grid = super::common::parse_grid(&a.wavelengths)?;
            let recipe = Recipe::load(&a.input, Overrides { weight_percent: a.weight_percent })?;
            let options = bulk::Options { phase_entries: 0, ..Default::default() };
            let s: OpticalSpectrum = bulk::compute(&recipe, &grid, &options)?;
            for w in &s.warnings {
                eprintln!("warning: {}: {w}", s.sample);
            }
            vec![(s.sample, grid, s.mu_s_per_m, s.mu_a_per_m, s.g)]
        }
        "json" => crate::optics::output::read_optical_properties(&a.input)?
            .into_iter()
            .enumerate()
            .map(|(i, s)| {
                let name = s.name(i);
                let grid = WavelengthGrid::from_list(s.wavelength_nm)
                    .with_context(|| format!("{}: {name}: wavelength_nm", a.input.display()))?;
                Ok((name, grid, s.mu_s_per_m, s.mu_a_per_m, s.g))
            })
            .collect::<Result<_>>()?,
        _ => bail!("{}: expected a recipe (.toml) or an optical_properties.json", a.input.display()),
    };

    let mut results = Vec::new();
    let mut weights: Vec<BandWeights> = Vec::new();
    for (name, grid, mu_s, mu_a, g) in &spectra {
        let w = band_weights(grid).with_context(|| format!("{}: {name}", a.input.display()))?;
        warn_partial_coverage(&format!("{}: {name}", a.input.display()), &w);
        let avg =
            |what: &str, v: &[f64]| w.average(v).with_context(|| format!("{}: {name}: {what}", a.input.display()));
        results.push(SampleBands {
            sample: name.clone(),
            mu_s_per_m: avg("mu_s_per_m", mu_s)?,
            mu_a_per_m: avg("mu_a_per_m", mu_a)?,
            g: avg("g", g)?,
        });
        if !weights.iter().any(|x| x.wavelength_nm == w.wavelength_nm) {
            weights.push(w);
        }
    }

    if a.json {
        let json = serde_json::json!({
            "weight_set": lucent_colour::bands::BAND_WEIGHT_SET,
            "bands": BANDS,
            "samples": results,
            "weights": weights,
        });
        println!("{}", serde_json::to_string_pretty(&json)?);
        return Ok(());
    }
    println!("{:<14} {:<5} {:>13} {:>13} {:>9}", "sample", "band", "μs [1/m]", "μa [1/m]", "g");
    for r in &results {
        for (b, band) in BANDS.iter().enumerate() {
            println!(
                "{:<14} {:<5} {:>13.5e} {:>13.5e} {:>9.5}",
                r.sample, band, r.mu_s_per_m[b], r.mu_a_per_m[b], r.g[b]
            );
        }
    }
    println!("\nweights: {}", lucent_colour::bands::BAND_WEIGHT_SET);
    for w in &weights {
        println!("{:>8} {:>9} {:>9} {:>9}", "λ [nm]", "w_R", "w_G", "w_B");
        for (i, nm) in w.wavelength_nm.iter().enumerate() {
            println!("{:>8} {:>9.5} {:>9.5} {:>9.5}", nm, w.weights[0][i], w.weights[1][i], w.weights[2][i]);
        }
    }
    Ok(())
}

/// Warns when a grid spans less than 99 % of a band's colour-matching mass
/// (below 90 % `band_weights` refuses it).
pub fn warn_partial_coverage(what: &str, w: &BandWeights) {
    for (b, f) in w.coverage.iter().enumerate() {
        if *f < 0.99 {
            eprintln!(
                "warning: {what}: the wavelength grid spans {:.1} % of band {}'s colour-matching mass; \
                 the band average leaves the rest out (use e.g. 380:780:10)",
                100.0 * f,
                BANDS[b]
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::ValueEnum;
    use lucent_colour::adaptation::Cat;

    #[test]
    fn corner_and_option_parsing() {
        let corners = |t: &str| t.parse::<crate::job::ChartCorners>();
        assert_eq!(corners("1,2,3,4,5,6,7,8").unwrap().0[2], [5.0, 6.0]);
        assert!(corners("1,2,3").unwrap_err().to_string().contains("expected 8 numbers"));
        assert!(corners("1,2,3,4,5,6,7,x").unwrap_err().to_string().contains("\"x\""));
        assert!(corners("1,2,3,4,5,6,7,nan").is_err());
        // The spellings of --adaptation, through clap as the command line parses them.
        let parse = |s: &str| AdaptationChoice::from_str(s, true).map(AdaptationChoice::cat);
        assert_eq!(parse("CAT02").unwrap(), Some(Cat::Cat02));
        assert_eq!(parse("von Kries").unwrap(), Some(Cat::VonKries));
        assert_eq!(parse("none").unwrap(), None);
        assert!(parse("cat16").is_err());
    }
}
