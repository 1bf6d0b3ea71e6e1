//! `lucent colour …`: ColorChecker calibration of a camera, applying the
//! fitted matrix to linear images, and the RGB band values of spectral
//! optical properties. Orchestration only; the colour science is in
//! `lucent-colour`.

use super::choices::{named, AdaptationChoice};
use crate::ccm_file::ApplyTarget;
use crate::ccm_file::{CcmFile, CcmPatch, InputEncoding};
use crate::imageio::{self, RgbImage};
use crate::optics::bulk::{self, OpticalSpectrum};
use crate::optics::recipe::{Overrides, Recipe};
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use lucent_colour::adaptation::Cat;
use lucent_colour::bands::{band_weights, BandWeights, BANDS};
use lucent_colour::ccm::{fit_colorchecker, CcmMethod, ColourCorrection};
use lucent_colour::chart::{neutral_ramp_warning, sample_patches, ImageRef, PatchSample, SampleOptions};
use lucent_colour::data::ICC_D50_XYZ;
use lucent_colour::spaces::{mat3_vec, srgb_decode, RgbSpace};
use lucent_colour::{Mat3, WavelengthGrid};
use serde::Serialize;
use std::path::{Path, PathBuf};

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
    #[arg(long, default_value = "0.99")]
    pub clip_level: String,
    /// Gap between patches as a fraction of the patch side.
    #[arg(long, default_value_t = 0.14)]
    pub gap_ratio: f64,
    /// Side of the sampled square as a fraction of the patch side.
    #[arg(long, default_value_t = 0.5)]
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
    #[arg(long, default_value_t = 16, value_parser = super::count_in::<2, 1000>, requires = "variance_out")]
    pub variance_realisations: usize,
    /// Seed of the noise realisations of --variance-out.
    #[arg(long, default_value_t = 1, requires = "variance_out")]
    pub seed: u64,
    /// Bin the output K × K (each pixel the mean of K × K developed pixels; both sides must be
    /// multiples of K): a photo at the resolution of a smaller render, with --variance-out binned alike.
    #[arg(long, value_name = "K", default_value_t = 1, value_parser = super::count_in::<1, 64>)]
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

fn parse_clip_level(text: &str) -> Result<Option<f64>> {
    if text.trim().eq_ignore_ascii_case("none") {
        return Ok(None);
    }
    match text.trim().parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(Some(v)),
        _ => bail!("--clip-level {text:?}: expected a positive number or \"none\""),
    }
}

fn decode_in_place(img: &mut RgbImage) {
    for v in &mut img.data {
        *v = srgb_decode(f64::from(*v)) as f32;
    }
}

fn calibrate(a: CalibrateArgs) -> Result<()> {
    let method = a.method;
    let given_corners = a.corners.map(|c| c.0);
    let clip = parse_clip_level(&a.clip_level)?;
    let mut img = imageio::read_rgb(&a.image)?;
    let encoding = if a.decode_srgb { InputEncoding::Srgb } else { InputEncoding::Linear };
    // The clip level refers to the stored values; sRGB decoding is monotonic.
    let clip_linear = match encoding {
        InputEncoding::Srgb => clip.map(srgb_decode),
        InputEncoding::Linear => clip,
    };
    if encoding == InputEncoding::Srgb {
        decode_in_place(&mut img);
    }
    let options = SampleOptions {
        gap_ratio: a.gap_ratio,
        inner_fraction: a.inner_fraction,
        clip_level: clip_linear,
        ..SampleOptions::default()
    };
    let corners = match given_corners {
        Some(c) => c,
        None => detect_corners(&img, &options, &a.image)?,
    };
    let view = ImageRef::new(img.width, img.height, &img.data)?;
    let samples = sample_patches(&view, corners, &options)
        .with_context(|| format!("{}: cannot sample the ColorChecker", a.image.display()))?;
    if let Some(w) = neutral_ramp_warning(&samples) {
        // No camera records a chart below black: a matrix fitted to it is no camera's.
        if samples.iter().all(|s| s.mean.iter().sum::<f64>() < 0.0) {
            bail!("{}: {w}; no matrix fitted", a.image.display());
        }
        eprintln!("warning: {}: {w}", a.image.display());
    }
    let camera_rgb: Vec<[f64; 3]> = samples.iter().map(|s| s.mean).collect();
    let (ccm, report) = fit_colorchecker(method, &camera_rgb)?;

    let camera = a.camera.clone().unwrap_or_else(|| {
        a.image.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "camera".into())
    });
    let file = CcmFile {
        camera,
        image: a.image.display().to_string(),
        corners,
        corners_detected: given_corners.is_none(),
        method,
        method_description: method.description().to_string(),
        terms: method.term_names().iter().map(|s| s.to_string()).collect(),
        matrix: ccm.matrix().to_vec(),
        maps: "linear camera RGB → CIE XYZ (CIE 1931 2°) as under D50, Y of the perfect white = 1".into(),
        input_encoding: encoding,
        reference_set:
            "X-Rite ColorChecker Classic 24, post-November-2014 reference L*a*b* (X-Rite 2016, via colour-science)"
                .into(),
        illuminant: "D50 (ICC PCS white)".into(),
        white_xyz: ICC_D50_XYZ,
        observer: "CIE 1931 2°".into(),
        sampling: options.clone(),
        de2000_mean: report.de2000_mean,
        de2000_max: report.de2000_max,
        de76_mean: report.de76_mean,
        de76_max: report.de76_max,
        patches: report
            .patches
            .iter()
            .zip(&samples)
            .map(|(p, s)| CcmPatch { fit: p.clone(), camera_rgb_std_dev: s.std_dev, pixels: s.pixels })
            .collect(),
    };

    let files = crate::ccm_file::ColourFiles::in_dir(&a.out);
    file.write(&files.ccm)?;
    crate::io::write_atomic(&files.chart, &chart_comparison(&ccm, &file)?)?;
    let labels: Vec<String> = file.patches.iter().map(|p| format!("{} {}", p.fit.patch, p.fit.name)).collect();
    let de2000: Vec<f64> = file.patches.iter().map(|p| p.fit.de2000).collect();
    let de76: Vec<f64> = file.patches.iter().map(|p| p.fit.de76).collect();
    let to_srgb8 = srgb_display_matrix()?;
    let colours: Vec<[u8; 3]> = file.patches.iter().map(|p| srgb8(mat3_vec(&to_srgb8, p.fit.reference_xyz))).collect();
    let title = format!("{} — {} — ΔE00 mean {:.2}, max {:.2}", file.camera, method, file.de2000_mean, file.de2000_max);
    let png = crate::plot::delta_e_bars_png(&title, &labels, &de2000, &de76, &colours)?;
    crate::io::write_atomic(&files.delta_e, &png)?;
    crate::io::write_atomic(&files.patches, &sampling_overlay(&img, &samples)?)?;

    print_delta_e_table(&file);
    println!(
        "\n{} ({}) fitted to {}; written to {}/: ccm.json, chart.png (each patch: corrected photo | reference), delta_e.png, patches.png (sampled areas)",
        method,
        method.description(),
        a.image.display(),
        a.out.display()
    );
    Ok(())
}

/// The chart's patch-grid corners found by OpenCV's mcc detector, or an
/// error that says so and asks for --corners.
fn detect_corners(img: &RgbImage, options: &SampleOptions, path: &Path) -> Result<[[f64; 2]; 4]> {
    let buffer = lucent_calib::RgbBuffer::new(img.width, img.height, img.data.clone())?;
    match crate::chart_detect::detect_colorchecker(&buffer, options) {
        Ok(d) => {
            let list = d.corners.iter().flatten().map(|v| format!("{v:.1}")).collect::<Vec<_>>().join(",");
            println!(
                "chart found by OpenCV mcc: --corners {list} (patches in reference order: mean ΔE00 {:.2} after a 3 × 3 fit, {:.2} turned round)",
                d.mean_de2000, d.other_orientation_de2000
            );
            Ok(d.corners)
        }
        Err(e) => bail!(
            "{}: {e}; give the chart's corners with --corners x1,y1,x2,y2,x3,y3,x4,y4 (outer corners of the patch grid: dark skin, bluish green, black, white)",
            path.display()
        ),
    }
}

fn print_delta_e_table(file: &CcmFile) {
    println!("{:>5}  {:<22} {:>8} {:>8}", "patch", "name", "ΔE00", "ΔE*ab");
    for CcmPatch { fit: p, .. } in &file.patches {
        println!("{:>5}  {:<22} {:>8.2} {:>8.2}", p.patch, p.name, p.de2000, p.de76);
    }
    println!("{:>5}  {:<22} {:>8.2} {:>8.2}", "", "mean", file.de2000_mean, file.de76_mean);
    println!("{:>5}  {:<22} {:>8.2} {:>8.2}", "", "max", file.de2000_max, file.de76_max);
}

/// XYZ (D50) → linear sRGB (D65, Bradford), for pictures people look at.
fn srgb_display_matrix() -> Result<Mat3> {
    Ok(RgbSpace::Srgb.from_xyz_adapted_matrix(ICC_D50_XYZ, Some(Cat::Bradford))?)
}

fn srgb8(linear: [f64; 3]) -> [u8; 3] {
    linear.map(|v| (imageio::srgb_encode(v as f32) * 255.0 + 0.5) as u8)
}

/// chart.png: the 4 × 6 chart, each patch split into the corrected photo
/// (left half) and the reference (right half), in sRGB for display, the
/// halves named under each patch and in the header.
fn chart_comparison(ccm: &ColourCorrection, file: &CcmFile) -> Result<Vec<u8>> {
    let to_srgb = srgb_display_matrix()?;
    let labels: Vec<String> = file.patches.iter().map(|p| format!("{} {}", p.fit.patch, p.fit.name)).collect();
    let photo: Vec<[u8; 3]> =
        file.patches.iter().map(|p| srgb8(mat3_vec(&to_srgb, ccm.apply(p.fit.camera_rgb)))).collect();
    let reference: Vec<[u8; 3]> = file.patches.iter().map(|p| srgb8(mat3_vec(&to_srgb, p.fit.reference_xyz))).collect();
    let title = format!("{} — {}: photo corrected by the fitted matrix vs reference", file.camera, file.method);
    Ok(crate::plot::chart_halves_png(&title, &labels, &photo, &reference)?)
}

/// patches.png: the (linear) chart image scaled so the white patch is at
/// 0.9, sRGB-encoded, enlarged to a legible size, with the sampled squares
/// outlined in magenta and numbered.
fn sampling_overlay(img: &RgbImage, samples: &[PatchSample]) -> Result<Vec<u8>> {
    let white = samples.get(18).map(|s| s.mean.iter().copied().fold(0.0, f64::max)).unwrap_or(1.0);
    let scale = if white > 0.0 { (0.9 / white) as f32 } else { 1.0 };
    let bytes: Vec<u8> = img.data.iter().map(|v| (imageio::srgb_encode(v * scale) * 255.0 + 0.5) as u8).collect();
    let outlines: Vec<[[f64; 2]; 4]> = samples.iter().map(|s| s.outline).collect();
    Ok(crate::plot::patch_overlay_png(img.width, img.height, &bytes, &outlines)?)
}

fn apply(a: ApplyArgs) -> Result<()> {
    let (file, ccm) = CcmFile::read(&a.ccm)?;
    let cat = a.adaptation.cat();
    let target: Mat3 = match a.to {
        ApplyTarget::Xyz => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        ApplyTarget::CieRgb => RgbSpace::CieRgb.from_xyz_adapted_matrix(file.white_xyz, cat)?,
        ApplyTarget::Srgb => RgbSpace::Srgb.from_xyz_adapted_matrix(file.white_xyz, cat)?,
    };
    let ext = a.output.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if ext != "exr" {
        bail!("{}: the output must be an .exr file (linear 32-bit float)", a.output.display());
    }
    if let Some(v) = &a.variance_out {
        if !imageio::RAW_EXTENSIONS.contains(&imageio::extension(&a.input).as_str()) {
            bail!(
                "--variance-out {}: needs a RAW photo (its noise model); for a photo in {} give                  `lucent compare --photo-variance` a variance image of your own",
                v.display(),
                a.input.display()
            );
        }
        if file.input_encoding == InputEncoding::Srgb {
            bail!("--variance-out: {} was fitted to sRGB-encoded values, not a RAW's linear ones", a.ccm.display());
        }
        if imageio::extension(v) != "exr" {
            bail!("--variance-out {}: must be an .exr file", v.display());
        }
    }
    let mut img = imageio::read_rgb(&a.input)?;
    if file.input_encoding == InputEncoding::Srgb {
        decode_in_place(&mut img);
    }
    // Checked before anything is written (the variance file comes first).
    imageio::check_bin(img.width, img.height, a.bin)
        .with_context(|| format!("--bin {}: {}", a.bin, a.input.display()))?;
    let binned = (img.width / a.bin, img.height / a.bin);
    if let Some(v) = &a.variance_out {
        let colour = |rgb: [f64; 3]| mat3_vec(&target, ccm.apply(rgb));
        let (var, sidecar) =
            crate::compare::photo_noise::photo_variance(&a.input, &colour, a.variance_realisations, a.seed, a.bin)?;
        let plane = |c: usize| var.iter().skip(c).step_by(3).copied().collect::<Vec<f32>>();
        let (r, g, b) = (plane(0), plane(1), plane(2));
        crate::exr::write_channels(
            v,
            binned.0,
            binned.1,
            &[("variance.R", &r), ("variance.G", &g), ("variance.B", &b)],
        )?;
        let json = crate::compare::photo_noise::sidecar(v);
        crate::io::write_json(&json, &sidecar)?;
        let m = &sidecar.noise_model;
        println!(
            "{}: noise {} a = ({:.3e}, {:.3e}, {:.3e}), b = ({:.3e}, {:.3e}, {:.3e}); variance of the output → {} ({})",
            a.input.display(),
            match m.source {
                lucent_calib::noise::NoiseSource::DngNoiseProfile => "from the DNG NoiseProfile:",
                lucent_calib::noise::NoiseSource::EstimatedFromImage => "estimated from the photo:",
            },
            m.a[0],
            m.a[1],
            m.a[2],
            m.b[0],
            m.b[1],
            m.b[2],
            v.display(),
            json.display()
        );
        if !m.note.is_empty() {
            eprintln!("note: {}", m.note);
        }
    }
    for px in img.data.chunks_exact_mut(3) {
        let xyz = ccm.apply([f64::from(px[0]), f64::from(px[1]), f64::from(px[2])]);
        let out = mat3_vec(&target, xyz);
        for k in 0..3 {
            px[k] = out[k] as f32;
        }
    }
    let (w, h) = (img.width, img.height);
    if a.bin > 1 {
        img = img.binned(a.bin)?;
    }
    imageio::write_exr(&a.output, &img)?;
    println!(
        "{} → {}: {} × {} pixels{}, camera {:?} ({}) → {}{}",
        a.input.display(),
        a.output.display(),
        img.width,
        img.height,
        if a.bin > 1 { format!(" (binned {0} × {0} from {w} × {h})", a.bin) } else { String::new() },
        file.camera,
        file.method,
        <&str>::from(a.to),
        match (a.to, cat) {
            (ApplyTarget::Xyz, _) => " (D50-adapted XYZ as fitted)".to_string(),
            (_, Some(c)) => format!(" ({} adaptation from D50)", c.name()),
            (_, None) => " (no chromatic adaptation)".to_string(),
        }
    );
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
            let grid = super::parse_grid(&a.wavelengths)?;
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

    #[test]
    fn corner_and_option_parsing() {
        let corners = |t: &str| t.parse::<crate::job::ChartCorners>();
        assert_eq!(corners("1,2,3,4,5,6,7,8").unwrap().0[2], [5.0, 6.0]);
        assert!(corners("1,2,3").unwrap_err().to_string().contains("expected 8 numbers"));
        assert!(corners("1,2,3,4,5,6,7,x").unwrap_err().to_string().contains("\"x\""));
        assert!(corners("1,2,3,4,5,6,7,nan").is_err());
        assert_eq!(parse_clip_level("none").unwrap(), None);
        assert_eq!(parse_clip_level("0.95").unwrap(), Some(0.95));
        assert!(parse_clip_level("-1").is_err());
        // The spellings of --adaptation, through clap as the command line parses them.
        let parse = |s: &str| AdaptationChoice::from_str(s, true).map(AdaptationChoice::cat);
        assert_eq!(parse("CAT02").unwrap(), Some(Cat::Cat02));
        assert_eq!(parse("von Kries").unwrap(), Some(Cat::VonKries));
        assert_eq!(parse("none").unwrap(), None);
        assert!(parse("cat16").is_err());
    }
}
