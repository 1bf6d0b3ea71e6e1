//! `lucent env fit-scale`: the environment's radiance scale from the
//! photographed empty board (docs/method.md#env-scale). Renders the scene without its object
//! (the empty board), fits k as the ratio of sums over the board pixels
//! ([`crate::envfit`]) and writes, in `--out`:
//! * `env_scale.json` — the fit (k, k per channel, residuals, pixels), the
//!   scale before and after, render settings;
//! * `scene.toml` — a copy of the scene with `[environment] scale` = old · k
//!   (with `--per-channel` and a `constant` environment: the constant scaled
//!   per channel), its paths made absolute so it loads from anywhere;
//! * `board_render.exr` — the empty-board render at the fitted scale.

use crate::envfit::{self, FitReport};
use crate::imageio::{self, RgbImage};
use crate::scene;
use anyhow::{Context, Result};
use clap::Args;
use lucent_render::tracer;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct FitScaleArgs {
    /// Scene file of the twin (its object and material are left out: the empty board is rendered).
    pub scene: PathBuf,
    /// The photographed empty board (linear EXR, the scene camera's image size).
    #[arg(long)]
    pub photo: PathBuf,
    /// Restrict the fit to the nonzero pixels of this mask image (intersected with the board).
    #[arg(long)]
    pub mask: Option<PathBuf>,
    /// Scale each channel on its own (written to the scene when the environment is a constant).
    #[arg(long)]
    pub per_channel: bool,
    /// The empty-board render, as `lucent render` takes it.
    #[command(flatten)]
    pub render: super::groups::TwinRenderArgs,
    /// Output folder.
    #[arg(long, default_value = "lucent-out/env-scale")]
    pub out: PathBuf,
    /// No progress bar or progress lines.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs `lucent env fit-scale`.
pub fn run(a: FitScaleArgs) -> Result<()> {
    a.render.check()?;
    let text =
        crate::io::read_text(&a.scene).with_context(|| format!("{}: cannot read scene file", a.scene.display()))?;
    let file = scene::parse(&text, &a.scene)?;
    let mut empty = envfit::empty_board(&file).with_context(|| a.scene.display().to_string())?;
    // The finite sphere stays centred where the full scene puts it (the top
    // of the sample by default), so the board is lit as in the twin's render.
    if file.object.is_some() && empty.environment.centre_m.is_none() {
        let full = scene::build(&file, &a.scene)?;
        empty.environment.centre_m = full.summary.environment_centre_m;
    }
    let mut loaded = scene::build(&empty, &a.scene)?;
    a.render.resize(&mut loaded)?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    let board = loaded.scene.board.as_ref().context("the scene has no board")?;
    let cam = &loaded.scene.camera;
    let (w, h) = (cam.width, cam.height);
    let photo_img = imageio::read_rgb(&a.photo).with_context(|| "--photo: the empty-board photo".to_string())?;
    let photo = envfit::photo_pixels(&photo_img.data, photo_img.width, photo_img.height, w, h)
        .with_context(|| format!("{}", a.photo.display()))?;
    let mut mask = envfit::board_mask(cam, board);
    if let Some(m) = &a.mask {
        let extra = crate::compare::mask::Mask::from_image(m, w, h)?;
        mask.iter_mut().zip(&extra.include).for_each(|(a, b)| *a &= *b);
    }
    let mut settings = loaded.settings.clone();
    a.render.apply(&mut settings);
    let pool = a.render.pool()?;
    if !a.quiet {
        let budget = settings.stop.describe("spp");
        eprintln!(
            "rendering the empty board of {} at {w}×{h}, {budget}, {} threads",
            a.scene.display(),
            pool.current_num_threads()
        );
    }
    let bar = super::render::progress_bar(a.quiet, &settings);
    let mut estimated = false;
    let (image, stats) = pool.install(|| {
        tracer::render(&loaded.scene, &settings, &mut |p| {
            super::render::show_progress(&bar, &settings, a.quiet, &mut estimated, p)
        })
    })?;
    bar.finish_and_clear();
    let fit = envfit::fit_scale(&image.mean, &image.variance_of_mean, &photo, &mask)
        .with_context(|| format!("{} against {}", a.scene.display(), a.photo.display()))?;

    let previous = file.environment.scale.unwrap_or(1.0);
    let mut copy = envfit::with_paths_from(&file, &envfit::scene_dir(&a.scene));
    let mut new_constant = None;
    let k_img: [f64; 3];
    match (a.per_channel, file.environment.constant) {
        (true, Some(c)) => {
            let k = fit.scale_per_channel;
            let nc = [c[0] * k[0], c[1] * k[1], c[2] * k[2]];
            copy.environment.constant = Some(nc);
            new_constant = Some(nc);
            k_img = k;
        }
        (true, None) => {
            eprintln!(
                "note: the scene's environment is a map with one scale; scene.toml gets the scalar k = {:.6}, the per-channel scales {:?} are in env_scale.json",
                fit.scale, fit.scale_per_channel
            );
            copy.environment.scale = Some(previous * fit.scale);
            k_img = [fit.scale; 3];
        }
        (false, _) => {
            copy.environment.scale = Some(previous * fit.scale);
            k_img = [fit.scale; 3];
        }
    }
    let new_scale = copy.environment.scale.unwrap_or(1.0);
    let scene_text = toml::to_string_pretty(&copy).context("cannot serialise the scaled scene")?;
    let header = format!(
        "# {} with the environment scale fitted to the empty board {} by `lucent env fit-scale` (k = {:.6}).\n",
        a.scene.display(),
        a.photo.display(),
        fit.scale
    );
    let data: Vec<f32> = image.mean.iter().flat_map(|m| [0, 1, 2].map(|c| (m[c] * k_img[c]) as f32)).collect();
    let scaled = RgbImage::new(w, h, data)?;
    let report = FitReport {
        lucent_version: env!("CARGO_PKG_VERSION").into(),
        scene: a.scene.display().to_string(),
        photo: a.photo.display().to_string(),
        mask: a.mask.as_ref().map(|m| m.display().to_string()),
        per_channel: a.per_channel,
        spp: image.samples.first().copied().unwrap_or(0),
        seed: settings.seed,
        render_wall_s: stats.wall_s,
        previous_scale: previous,
        new_scale,
        new_constant,
        fit,
        method: "k = Σ P / Σ R over the board pixels and channels (ratio of sums; blur- and demosaicing-invariant)"
            .into(),
    };
    write(&a.out, &report, &header, &scene_text, &scaled)?;
    let f = &report.fit;
    println!(
        "environment scale k = {:.5} (per channel {:.5} {:.5} {:.5}) over {} board pixels; residual RMS {:.4e} ({:.2} % of the photo, render noise {:.4e}); scale {} → {}",
        f.scale,
        f.scale_per_channel[0],
        f.scale_per_channel[1],
        f.scale_per_channel[2],
        f.pixels,
        f.residual_rms,
        100.0 * f.relative_residual,
        f.render_noise_rms,
        previous,
        new_scale
    );
    let [exr, toml, json] = crate::envfit::EnvScaleFiles::NAMES;
    println!("wrote {}/{json}, {toml}, {exr}", a.out.display());
    Ok(())
}

fn write(out: &Path, report: &FitReport, header: &str, scene_text: &str, img: &RgbImage) -> Result<()> {
    // One output: the scaled scene never appears without its fit and render.
    let crate::envfit::EnvScaleFiles { exr, toml, json } = crate::envfit::EnvScaleFiles::in_dir(out);
    crate::io::write_files_atomic(&[
        (&exr, &imageio::encode_exr(&exr, img)?),
        (&toml, format!("{header}{scene_text}").as_bytes()),
        (&json, &crate::io::json_bytes(&json, report)?),
    ])?;
    Ok(())
}
