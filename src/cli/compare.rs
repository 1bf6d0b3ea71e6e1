//! `lucent compare`: a photo and its twin's render → metrics.json,
//! triplet.png and difference.exr (docs/method.md#compare). Argument handling and
//! printing only: the flags become a [`CompareJob`], which does the work.

use super::choices::{named, RefineChoice};
use crate::compare::{self, Luminance};
use crate::job::{CompareJob, Context};
use anyhow::{Context as _, Result};
use clap::Args;
use lucent_calib::ecc::Motion;
use std::path::PathBuf;

#[derive(Debug, Args)]
#[command(group(clap::ArgGroup::new("masking").args(["mask_object", "mask_board"])))]
pub struct CompareArgs {
    /// The photo: linear RGB (.exr, .hdr; .png/.tif are taken as stored), undistorted.
    #[arg(long)]
    pub photo: PathBuf,
    /// The render of the twin, same size and channels as the photo; give it twice
    /// (`--render A.exr --render B.exr`) to ask which of two twins is closer.
    #[arg(long, required = true, num_args = 1)]
    pub render: Vec<PathBuf>,
    /// Mask image of the photo's size: nonzero = pixel included (with --mask-object or
    /// --mask-board: the pixels both include, e.g. the object minus clipped pixels).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Compare only the sample: its box projected from this scene JSON (`lucent pose`), or the
    /// pixels a render EXR's `object` layer marks (any mesh; `lucent render` writes it).
    #[arg(long, value_name = "SCENE_JSON|RENDER_EXR")]
    pub mask_object: Option<PathBuf>,
    /// Compare only the board (printed squares minus the sample), from this scene JSON or a
    /// render EXR's `board` layer.
    #[arg(long, value_name = "SCENE_JSON|RENDER_EXR")]
    pub mask_board: Option<PathBuf>,
    /// Per-pixel variance of the photo (EXR: R, G, B or variance.R/G/B), removed with the
    /// render's own variance from the model RMSE.
    #[arg(long)]
    pub photo_variance: Option<PathBuf>,
    /// A second photo of the same view (same camera, settings and light): the photo's variance
    /// is then (P − P2)² / 2 per pixel, for the model RMSE.
    #[arg(long, value_name = "PHOTO2", conflicts_with = "photo_variance")]
    pub photo_repeat: Option<PathBuf>,
    /// Scene JSON whose board region ECC aligns on (implied by --mask-object/--mask-board).
    #[arg(long, value_name = "SCENE_JSON")]
    pub scene: Option<PathBuf>,
    /// SSIM data range L (C1 = (0.01 L)², C2 = (0.03 L)²), in the images' units.
    #[arg(long, default_value_t = crate::job::DEFAULT_DATA_RANGE, allow_hyphen_values = true)]
    pub data_range: f64,
    /// Luminance weights for SSIM Y, the difference picture and ECC: cie-rgb (0.1769, 0.8124,
    /// 0.0107) or rec709 (0.2126, 0.7152, 0.0722).
    #[arg(long, value_parser = named::<Luminance>(), default_value = "cie-rgb")]
    pub luminance: Luminance,
    /// Display exposure k for triplet.png (shown = sRGB(k × linear)); default: 1 / the 99th
    /// percentile of the photo's max(R, G, B).
    #[arg(long, allow_hyphen_values = true)]
    pub exposure: Option<f64>,
    /// With two --render: what they are, e.g. "recipe,fitted" (the rows of triplet.png say
    /// "A: recipe" and "B: fitted"; default "A,B").
    #[arg(long, value_name = "NAME_A,NAME_B", value_parser = twin_names, requires = "render")]
    pub twin_names: Option<[String; 2]>,
    /// Also align the render to the photo and report the metrics after it: ecc (OpenCV findTransformECC).
    #[arg(long, value_enum, ignore_case = true, value_name = "METHOD")]
    pub refine: Option<RefineChoice>,
    /// Motion model of the refinement: translation, euclidean, affine or homography.
    #[arg(long, value_parser = named::<Motion>(), default_value = "translation", requires = "refine")]
    pub refine_motion: Motion,
    /// A twin's band: its render's uncertainty.json (or the folder holding it) from `lucent
    /// render --uncertainty`; once per --render, in the same order. With --mask-object or
    /// --mask-board: is the photo's mean over those pixels within the twin's predictive band?
    #[arg(long, value_name = "UNCERTAINTY_JSON")]
    pub band: Vec<PathBuf>,
    /// Output folder (created; existing metrics.json, triplet.png, difference.exr in it are replaced).
    #[arg(long)]
    pub out: PathBuf,
}

/// `--twin-names A,B`: two non-empty names.
fn twin_names(text: &str) -> Result<[String; 2], String> {
    match text.split(',').map(str::trim).collect::<Vec<_>>().as_slice() {
        [a, b] if !a.is_empty() && !b.is_empty() => Ok([a.to_string(), b.to_string()]),
        _ => Err(format!("{text:?}: expected two names separated by a comma, e.g. recipe,fitted")),
    }
}

/// `lucent compare`: the job of the flags ([`CompareJob::run`]), then its summary on stdout.
pub fn run(a: CompareArgs) -> Result<()> {
    let job = CompareJob::from(&a);
    let done = job.run(&Context::default())?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(())
}

/// `lucent bench compare`: SSIM (R, G, B, Y) and the error metrics of a
/// synthetic `megapixels` pair (4:3, a textured image and a darker, noisier
/// copy), best of `repeats`, on all cores.
pub fn bench(megapixels: f64, repeats: usize) -> Result<()> {
    use crate::compare::ssim::SsimParams;
    use crate::imageio::RgbImage;
    if !(megapixels.is_finite() && (0.001..=100.0).contains(&megapixels)) {
        anyhow::bail!("--megapixels {megapixels}: must lie in 0.001 … 100");
    }
    let h = ((megapixels * 1e6 * 0.75).sqrt().round() as usize).max(16);
    let w = h * 4 / 3;
    // A deterministic texture with fine detail and noise (a 64-bit LCG).
    let mut state = 0x9e37_79b9_7f4a_7c15_u64;
    let mut noise = move || {
        state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (state >> 11) as f64 / (1u64 << 53) as f64 - 0.5
    };
    let x: Vec<f32> = (0..w * h * 3)
        .map(|i| {
            let (px, py, c) = ((i / 3 % w) as f64, (i / 3 / w) as f64, (i % 3) as f64);
            (0.5 + 0.3 * (0.13 * px + c).sin() * (0.07 * py).cos() + 0.05 * noise()) as f32
        })
        .collect();
    let y: Vec<f32> = x.iter().map(|v| 0.9 * v + (0.02 * noise()) as f32).collect();
    let (x, y) = (RgbImage::new(w, h, x)?, RgbImage::new(w, h, y)?);
    let settings = compare::Settings { ssim: SsimParams::new(1.0)?, luminance: Luminance::CieRgb };
    eprintln!(
        "{w} × {h} pair ({:.1} Mpixel), best of {repeats}, {} threads …",
        (w * h) as f64 / 1e6,
        rayon::current_num_threads()
    );
    let mut best = f64::INFINITY;
    let mut last = None;
    for _ in 0..repeats {
        let t = std::time::Instant::now();
        let m = compare::metrics(&x, &y, None, &settings)?;
        best = best.min(t.elapsed().as_secs_f64());
        last = Some(m);
    }
    let m = last.context("no repeat ran")?;
    println!(
        "compare {w} × {h}: all metrics (SSIM R, G, B, Y and the errors) {best:.2} s (best of {repeats}); SSIM Y {:.4}, RMSE {:.4e}",
        m.ssim.y, m.rmse
    );
    Ok(())
}
