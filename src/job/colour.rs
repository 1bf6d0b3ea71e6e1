//! The colour stage: [`ColourCalibrateJob::run`] fits a camera's colour
//! correction (camera RGB → CIE XYZ as under D50) to the 24 patches of a
//! ColorChecker photo (the chart's corners given, or found by OpenCV's mcc)
//! and writes ccm.json, chart.png, delta_e.png and patches.png
//! ([`ColourFiles`]); [`ColourApplyJob::run`] applies a fitted ccm.json to a
//! linear image (a developed RAW photo), into CIE RGB, XYZ or linear sRGB,
//! optionally binned and with the photo's per-pixel variance from its noise
//! model. `lucent colour calibrate` / `apply` and the pipeline's colour and
//! develop stages run them; the commands parse their flags into the jobs and
//! print the summaries ([`ColourCalibrateRun::summary`], the ΔE table;
//! [`ColourApplyRun::summary`]).

mod section;
pub use section::{ColourCamera, ColourSection};

use super::context::Context;
use super::spec::{ColourApplyJob, ColourCalibrateJob};
use crate::ccm_file::{ApplyTarget, CcmFile, CcmFileError, CcmPatch, ColourFiles, InputEncoding};
use crate::imageio::{self, ImageIoError, RgbImage};
use crate::io::WriteError;
use crate::plot::PlotError;
use lucent_colour::adaptation::Cat;
use lucent_colour::ccm::{fit_colorchecker, ColourCorrection};
use lucent_colour::chart::{neutral_ramp_warning, sample_patches, ImageRef, PatchSample, SampleOptions};
use lucent_colour::data::ICC_D50_XYZ;
use lucent_colour::spaces::{mat3_vec, srgb_decode, RgbSpace};
use lucent_colour::{ColourError, Mat3};
use std::path::{Path, PathBuf};

/// Why a colour job cannot run.
#[derive(Debug, thiserror::Error)]
pub enum ColourJobError {
    #[error(transparent)]
    Image(#[from] ImageIoError),
    #[error(transparent)]
    Colour(#[from] ColourError),
    #[error(transparent)]
    Buffer(#[from] lucent_calib::BufferSizeError),
    #[error(
        "{}: {source}; give the chart's corners with --corners x1,y1,x2,y2,x3,y3,x4,y4 (outer corners of the patch \
         grid: dark skin, bluish green, black, white)",
        path.display()
    )]
    NotDetected { path: PathBuf, source: Box<crate::chart_detect::ChartError> },
    #[error("{}: cannot sample the ColorChecker: {source}", path.display())]
    Sample { path: PathBuf, source: ColourError },
    #[error("{}: {warning}; no matrix fitted", path.display())]
    BelowBlack { path: PathBuf, warning: String },
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error(transparent)]
    Plot(#[from] PlotError),
    #[error(transparent)]
    Ccm(#[from] CcmFileError),
    #[error("{}: the output must be an .exr file (linear 32-bit float)", .0.display())]
    OutputNotExr(PathBuf),
    #[error(
        "--variance-out {}: needs a RAW photo (its noise model); for a photo in {} give                  `lucent \
         compare --photo-variance` a variance image of your own",
        variance.display(),
        input.display()
    )]
    VarianceNeedsRaw { variance: PathBuf, input: PathBuf },
    #[error("--variance-out: {} was fitted to sRGB-encoded values, not a RAW's linear ones", .0.display())]
    VarianceOfSrgb(PathBuf),
    #[error("--variance-out {}: must be an .exr file", .0.display())]
    VarianceNotExr(PathBuf),
    #[error("--bin {bin}: {}: {source}", input.display())]
    Bin { bin: usize, input: PathBuf, source: ImageIoError },
    #[error(transparent)]
    Noise(#[from] crate::compare::photo_noise::PhotoNoiseError),
    #[error(transparent)]
    ExrWrite(#[from] crate::exr::ExrWriteError),
}

/// What a colour calibration fitted and wrote.
pub struct ColourCalibrateRun {
    /// The ccm.json written.
    pub file: CcmFile,
    /// The files written ([`ColourFiles::in_dir`] of the job's `out`).
    pub files: ColourFiles,
    /// The line saying where OpenCV's mcc found the chart, when it was not given.
    pub detected: Option<String>,
    image: PathBuf,
    out: PathBuf,
}

fn decode_in_place(img: &mut RgbImage) {
    for v in &mut img.data {
        *v = srgb_decode(f64::from(*v)) as f32;
    }
}

impl ColourCalibrateJob {
    /// Samples the chart's patches, fits the correction and writes the
    /// files (plots first, ccm.json last). Warnings go to `ctx`.
    pub fn run(&self, ctx: &Context) -> Result<ColourCalibrateRun, ColourJobError> {
        let method = self.method;
        let given_corners = self.corners.map(|c| c.0);
        let clip = self.clip_level.level();
        let mut img = imageio::read_rgb(&self.image)?;
        let encoding = if self.decode_srgb { InputEncoding::Srgb } else { InputEncoding::Linear };
        // The clip level refers to the stored values; sRGB decoding is monotonic.
        let clip_linear = match encoding {
            InputEncoding::Srgb => clip.map(srgb_decode),
            InputEncoding::Linear => clip,
        };
        if encoding == InputEncoding::Srgb {
            decode_in_place(&mut img);
        }
        let options = SampleOptions {
            gap_ratio: self.gap_ratio,
            inner_fraction: self.inner_fraction,
            clip_level: clip_linear,
            ..SampleOptions::default()
        };
        let (corners, detected) = match given_corners {
            Some(c) => (c, None),
            None => detect_corners(&img, &options, &self.image).map(|(c, line)| (c, Some(line)))?,
        };
        let view = ImageRef::new(img.width, img.height, &img.data)?;
        let samples = sample_patches(&view, corners, &options)
            .map_err(|source| ColourJobError::Sample { path: self.image.clone(), source })?;
        if let Some(w) = neutral_ramp_warning(&samples) {
            // No camera records a chart below black: a matrix fitted to it is no camera's.
            if samples.iter().all(|s| s.mean.iter().sum::<f64>() < 0.0) {
                return Err(ColourJobError::BelowBlack { path: self.image.clone(), warning: w });
            }
            ctx.warn(&format!("{}: {w}", self.image.display()));
        }
        let camera_rgb: Vec<[f64; 3]> = samples.iter().map(|s| s.mean).collect();
        let (ccm, report) = fit_colorchecker(method, &camera_rgb)?;
        let camera = self.camera.clone().unwrap_or_else(|| {
            self.image.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "camera".into())
        });
        let file = CcmFile {
            camera,
            image: self.image.display().to_string(),
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
        let files = ColourFiles::in_dir(&self.out);
        write_calibration(&files, &file, &ccm, &img, &samples)?;
        Ok(ColourCalibrateRun { file, files, detected, image: self.image.clone(), out: self.out.clone() })
    }
}

/// Writes a calibration's files: ccm.json, chart.png, delta_e.png and patches.png.
fn write_calibration(
    files: &ColourFiles,
    file: &CcmFile,
    ccm: &ColourCorrection,
    img: &RgbImage,
    samples: &[PatchSample],
) -> Result<(), ColourJobError> {
    file.write(&files.ccm)?;
    crate::io::write_atomic(&files.chart, &chart_comparison(ccm, file)?)?;
    let labels: Vec<String> = file.patches.iter().map(|p| format!("{} {}", p.fit.patch, p.fit.name)).collect();
    let de2000: Vec<f64> = file.patches.iter().map(|p| p.fit.de2000).collect();
    let de76: Vec<f64> = file.patches.iter().map(|p| p.fit.de76).collect();
    let to_srgb8 = srgb_display_matrix()?;
    let colours: Vec<[u8; 3]> = file.patches.iter().map(|p| srgb8(mat3_vec(&to_srgb8, p.fit.reference_xyz))).collect();
    let title =
        format!("{} — {} — ΔE00 mean {:.2}, max {:.2}", file.camera, file.method, file.de2000_mean, file.de2000_max);
    let png = crate::plot::delta_e_bars_png(&title, &labels, &de2000, &de76, &colours)?;
    crate::io::write_atomic(&files.delta_e, &png)?;
    crate::io::write_atomic(&files.patches, &sampling_overlay(img, samples)?)?;
    Ok(())
}

impl ColourCalibrateRun {
    /// What `lucent colour calibrate` prints: where the chart was found (if
    /// it was searched), the ΔE of every patch, their mean and maximum, and
    /// what was written.
    pub fn summary(&self) -> Vec<String> {
        let file = &self.file;
        let mut lines: Vec<String> = self.detected.iter().cloned().collect();
        lines.push(format!("{:>5}  {:<22} {:>8} {:>8}", "patch", "name", "ΔE00", "ΔE*ab"));
        for CcmPatch { fit: p, .. } in &file.patches {
            lines.push(format!("{:>5}  {:<22} {:>8.2} {:>8.2}", p.patch, p.name, p.de2000, p.de76));
        }
        lines.push(format!("{:>5}  {:<22} {:>8.2} {:>8.2}", "", "mean", file.de2000_mean, file.de76_mean));
        lines.push(format!("{:>5}  {:<22} {:>8.2} {:>8.2}", "", "max", file.de2000_max, file.de76_max));
        lines.push(String::new());
        lines.push(format!(
            "{} ({}) fitted to {}; written to {}/: {}, {} (each patch: corrected photo | reference), {}, {} (sampled areas)",
            file.method,
            file.method.description(),
            self.image.display(),
            self.out.display(),
            ColourFiles::NAMES[0],
            ColourFiles::NAMES[1],
            ColourFiles::NAMES[2],
            ColourFiles::NAMES[3],
        ));
        lines
    }
}

/// The chart's patch-grid corners found by OpenCV's mcc detector, with the
/// line that says so, or an error that says so and asks for --corners.
fn detect_corners(
    img: &RgbImage,
    options: &SampleOptions,
    path: &Path,
) -> Result<([[f64; 2]; 4], String), ColourJobError> {
    let buffer = lucent_calib::RgbBuffer::new(img.width, img.height, img.data.clone())?;
    match crate::chart_detect::detect_colorchecker(&buffer, options) {
        Ok(d) => {
            let list = d.corners.iter().flatten().map(|v| format!("{v:.1}")).collect::<Vec<_>>().join(",");
            let line = format!(
                "chart found by OpenCV mcc: --corners {list} (patches in reference order: mean ΔE00 {:.2} after a 3 × 3 fit, {:.2} turned round)",
                d.mean_de2000, d.other_orientation_de2000
            );
            Ok((d.corners, line))
        }
        Err(e) => Err(ColourJobError::NotDetected { path: path.to_path_buf(), source: Box::new(e) }),
    }
}

/// XYZ (D50) → linear sRGB (D65, Bradford), for pictures people look at.
fn srgb_display_matrix() -> Result<Mat3, ColourError> {
    RgbSpace::Srgb.from_xyz_adapted_matrix(ICC_D50_XYZ, Some(Cat::Bradford))
}

fn srgb8(linear: [f64; 3]) -> [u8; 3] {
    linear.map(|v| (imageio::srgb_encode(v as f32) * 255.0 + 0.5) as u8)
}

/// chart.png: the 4 × 6 chart, each patch split into the corrected photo
/// (left half) and the reference (right half), in sRGB for display, the
/// halves named under each patch and in the header.
fn chart_comparison(ccm: &ColourCorrection, file: &CcmFile) -> Result<Vec<u8>, ColourJobError> {
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
fn sampling_overlay(img: &RgbImage, samples: &[PatchSample]) -> Result<Vec<u8>, ColourJobError> {
    let white = samples.get(18).map(|s| s.mean.iter().copied().fold(0.0, f64::max)).unwrap_or(1.0);
    let scale = if white > 0.0 { (0.9 / white) as f32 } else { 1.0 };
    let bytes: Vec<u8> = img.data.iter().map(|v| (imageio::srgb_encode(v * scale) * 255.0 + 0.5) as u8).collect();
    let outlines: Vec<[[f64; 2]; 4]> = samples.iter().map(|s| s.outline).collect();
    Ok(crate::plot::patch_overlay_png(img.width, img.height, &bytes, &outlines)?)
}

/// What applying a colour correction wrote.
pub struct ColourApplyRun {
    /// The camera and method of the ccm.json applied.
    pub camera: String,
    pub method: lucent_colour::ccm::CcmMethod,
    /// The output's size (after binning) and the size before it.
    pub size: (usize, usize),
    pub unbinned: (usize, usize),
    /// The line about the photo's noise model and its variance file, with `variance_out`.
    pub noise: Option<String>,
    input: PathBuf,
    output: PathBuf,
    to: ApplyTarget,
    bin: usize,
    adaptation: Option<Cat>,
}

impl ColourApplyJob {
    /// The matrix from camera RGB (through XYZ as fitted, under D50) into
    /// the target space, with the adaptation to its white.
    fn target_matrix(&self, file: &CcmFile) -> Result<Mat3, ColourError> {
        Ok(match self.to {
            ApplyTarget::Xyz => [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            ApplyTarget::CieRgb => RgbSpace::CieRgb.from_xyz_adapted_matrix(file.white_xyz, self.adaptation)?,
            ApplyTarget::Srgb => RgbSpace::Srgb.from_xyz_adapted_matrix(file.white_xyz, self.adaptation)?,
        })
    }

    /// Refuses outputs the job cannot write: the image must be an EXR, the
    /// variance (an EXR too) needs a RAW input and a matrix fitted to linear values.
    fn check_outputs(&self, file: &CcmFile) -> Result<(), ColourJobError> {
        if imageio::extension(&self.output) != "exr" {
            return Err(ColourJobError::OutputNotExr(self.output.clone()));
        }
        if let Some((v, _)) = &self.variance_out {
            if !imageio::RAW_EXTENSIONS.contains(&imageio::extension(&self.input).as_str()) {
                return Err(ColourJobError::VarianceNeedsRaw { variance: v.clone(), input: self.input.clone() });
            }
            if file.input_encoding == InputEncoding::Srgb {
                return Err(ColourJobError::VarianceOfSrgb(self.ccm.clone()));
            }
            if imageio::extension(v) != "exr" {
                return Err(ColourJobError::VarianceNotExr(v.clone()));
            }
        }
        Ok(())
    }

    /// Applies the correction and writes the output (the variance and its
    /// noise model first, when asked for). Notes go to `ctx`.
    pub fn run(&self, ctx: &Context) -> Result<ColourApplyRun, ColourJobError> {
        let (file, ccm) = CcmFile::read(&self.ccm)?;
        let target = self.target_matrix(&file)?;
        self.check_outputs(&file)?;
        let mut img = imageio::read_rgb(&self.input)?;
        if file.input_encoding == InputEncoding::Srgb {
            decode_in_place(&mut img);
        }
        // Checked before anything is written (the variance file comes first).
        imageio::check_bin(img.width, img.height, self.bin).map_err(|source| ColourJobError::Bin {
            bin: self.bin,
            input: self.input.clone(),
            source,
        })?;
        let binned = (img.width / self.bin, img.height / self.bin);
        let noise = match &self.variance_out {
            Some((v, seed)) => Some(self.write_variance(ctx, v, *seed, &ccm, &target, binned)?),
            None => None,
        };
        for px in img.data.chunks_exact_mut(3) {
            let xyz = ccm.apply([f64::from(px[0]), f64::from(px[1]), f64::from(px[2])]);
            let out = mat3_vec(&target, xyz);
            for k in 0..3 {
                px[k] = out[k] as f32;
            }
        }
        let unbinned = (img.width, img.height);
        if self.bin > 1 {
            img = img.binned(self.bin)?;
        }
        imageio::write_exr(&self.output, &img)?;
        Ok(ColourApplyRun {
            camera: file.camera,
            method: file.method,
            size: (img.width, img.height),
            unbinned,
            noise,
            input: self.input.clone(),
            output: self.output.clone(),
            to: self.to,
            bin: self.bin,
            adaptation: self.adaptation,
        })
    }

    /// Writes the developed photo's per-pixel variance (`variance.R/G/B`)
    /// and its noise model beside it; returns the line that says so.
    fn write_variance(
        &self,
        ctx: &Context,
        v: &Path,
        seed: u64,
        ccm: &ColourCorrection,
        target: &Mat3,
        binned: (usize, usize),
    ) -> Result<String, ColourJobError> {
        let colour = |rgb: [f64; 3]| mat3_vec(target, ccm.apply(rgb));
        let (var, sidecar) = crate::compare::photo_noise::photo_variance(
            &self.input,
            &colour,
            self.variance_realisations,
            seed,
            self.bin,
        )?;
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
        let line = format!(
            "{}: noise {} a = ({:.3e}, {:.3e}, {:.3e}), b = ({:.3e}, {:.3e}, {:.3e}); variance of the output → {} ({})",
            self.input.display(),
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
            ctx.note(&m.note);
        }
        Ok(line)
    }
}

impl ColourApplyRun {
    /// What `lucent colour apply` prints: the noise model and variance file
    /// (with `variance_out`), then the image written and its space.
    pub fn summary(&self) -> Vec<String> {
        let (w, h) = self.unbinned;
        let mut lines: Vec<String> = self.noise.iter().cloned().collect();
        lines.push(format!(
            "{} → {}: {} × {} pixels{}, camera {:?} ({}) → {}{}",
            self.input.display(),
            self.output.display(),
            self.size.0,
            self.size.1,
            if self.bin > 1 { format!(" (binned {0} × {0} from {w} × {h})", self.bin) } else { String::new() },
            self.camera,
            self.method,
            <&str>::from(self.to),
            match (self.to, self.adaptation) {
                (ApplyTarget::Xyz, _) => " (D50-adapted XYZ as fitted)".to_string(),
                (_, Some(c)) => format!(" ({} adaptation from D50)", c.name()),
                (_, None) => " (no chromatic adaptation)".to_string(),
            }
        ));
        lines
    }
}
