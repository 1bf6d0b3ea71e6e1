//! The env-scale stage: [`EnvScaleJob::run`] fits the scale of a scene's
//! environment to a photo of the empty board (docs/method.md#env-scale).
//!
//! It renders the scene without its object and material (the empty board,
//! lit by the environment alone; the environment's finite sphere stays
//! centred where the whole scene puts it), then fits k, the ratio of the
//! photo's sums to the render's over the board pixels and channels
//! ([`crate::envfit::fit_scale`]; k is dimensionless: photo values per
//! render value, both linear RGB). The board pixels are those whose four
//! corners see the board's squares, intersected with the job's `mask`.
//! It writes, in the job's `out` ([`EnvScaleFiles`]):
//! * `env_scale.json` — the fit ([`FitReport`]: k, k per channel, the
//!   residual RMS in the photo's units and relative to the photo, the part
//!   of it the render's noise explains, the number of pixels), the scale
//!   before and after, the render's samples per pixel, seed and wall time
//!   in seconds;
//! * `scene.toml` — a copy of the scene with `[environment] scale` = old · k
//!   (with `per_channel` and a `constant` environment: the constant scaled
//!   per channel), its paths made absolute so it loads from anywhere;
//! * `board_render.exr` — the empty-board render at the fitted scale.
//!
//! `lucent env fit-scale` and the pipeline's env-scale stage run it; the
//! command draws the render's progress bar ([`RenderHooks`]) and prints
//! [`EnvScaleRun::summary`].

mod section;

use super::context::Context;
use super::render::{resize, RenderHooks};
use super::spec::EnvScaleJob;
use super::threads::{check_threads, worker_pool, ThreadsError};
use crate::envfit::{self, EnvScaleFiles, FitReport};
use crate::imageio::{self, ImageIoError, RgbImage};
use crate::scene::{self, SceneFileError};
use lucent_render::tracer;
use std::path::PathBuf;
use thiserror::Error;

/// Why an env-scale job failed; every variant names the file or flag.
#[derive(Debug, Error)]
pub enum EnvScaleJobError {
    #[error(transparent)]
    Threads(#[from] ThreadsError),
    #[error("--spp 0: at least one sample per pixel")]
    ZeroSpp,
    #[error("{}: cannot read scene file", path.display())]
    ReadScene { path: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Scene(#[from] SceneFileError),
    /// The scene has no board to fit over (the message names the scene file).
    #[error("{}", scene.display())]
    EmptyBoard { scene: PathBuf, source: envfit::FitError },
    #[error("the scene has no board")]
    NoBoard,
    #[error("--photo: the empty-board photo")]
    ReadPhoto { source: ImageIoError },
    /// The photo does not fit the render (size, a value that is not finite).
    #[error("{}", photo.display())]
    Photo { photo: PathBuf, source: envfit::FitError },
    /// The mask image could not be read or has another size.
    #[error(transparent)]
    Mask(#[from] crate::compare::CompareError),
    #[error(transparent)]
    Render(#[from] tracer::StopError),
    /// No scale fits (a black render or photo, no board pixels).
    #[error("{} against {}", scene.display(), photo.display())]
    Fit { scene: PathBuf, photo: PathBuf, source: envfit::FitError },
    #[error("cannot serialise the scaled scene")]
    SceneText(#[source] toml::ser::Error),
    #[error(transparent)]
    Image(#[from] ImageIoError),
    #[error(transparent)]
    Write(#[from] crate::io::WriteError),
}

/// What an env-scale job found and wrote.
pub struct EnvScaleRun {
    /// The output folder (the job's `out`).
    pub out: PathBuf,
    /// The fit and what it was made from (`env_scale.json`).
    pub report: FitReport,
    /// The files written.
    pub files: EnvScaleFiles,
}

impl EnvScaleRun {
    /// What `lucent env fit-scale` prints on its standard output.
    pub fn summary(&self) -> Vec<String> {
        let f = &self.report.fit;
        let [exr, toml, json] = EnvScaleFiles::NAMES;
        let out = self.out.display();
        vec![
            format!(
                "environment scale k = {:.5} (per channel {:.5} {:.5} {:.5}) over {} board pixels; residual RMS \
                 {:.4e} ({:.2} % of the photo, render noise {:.4e}); scale {} → {}",
                f.scale,
                f.scale_per_channel[0],
                f.scale_per_channel[1],
                f.scale_per_channel[2],
                f.pixels,
                f.residual_rms,
                100.0 * f.relative_residual,
                f.render_noise_rms,
                self.report.previous_scale,
                self.report.new_scale
            ),
            format!("wrote {out}/{json}, {toml}, {exr}"),
        ]
    }
}

type E = EnvScaleJobError;

impl EnvScaleJob {
    /// Renders the empty board, fits the scale and writes the outputs,
    /// nobody watching the render's passes.
    pub fn run(&self, ctx: &Context) -> Result<EnvScaleRun, E> {
        self.run_with(ctx, &mut ())
    }

    /// [`EnvScaleJob::run`], `hooks` told of the render's passes. Warnings
    /// and notes go to `ctx` (`quiet` or the job's `quiet` silences what it
    /// says of its progress).
    pub fn run_with(&self, ctx: &Context, hooks: &mut dyn RenderHooks) -> Result<EnvScaleRun, E> {
        let ctx = &Context { quiet: ctx.quiet || self.quiet };
        check_threads(self.threads)?;
        if self.spp == Some(0) {
            return Err(E::ZeroSpp);
        }
        let text =
            crate::io::read_text(&self.scene).map_err(|source| E::ReadScene { path: self.scene.clone(), source })?;
        let file = scene::parse(&text, &self.scene)?;
        let mut empty =
            envfit::empty_board(&file).map_err(|source| E::EmptyBoard { scene: self.scene.clone(), source })?;
        // The finite sphere stays centred where the full scene puts it (the top
        // of the sample by default), so the board is lit as in the twin's render.
        if file.object.is_some() && empty.environment.centre_m.is_none() {
            let full = scene::build(&file, &self.scene)?;
            empty.environment.centre_m = full.summary.environment_centre_m;
        }
        let mut loaded = scene::build(&empty, &self.scene)?;
        if let Some(size) = self.size {
            resize(size, &mut loaded);
        }
        for w in &loaded.warnings {
            ctx.warn(w);
        }
        let board = loaded.scene.board.as_ref().ok_or(E::NoBoard)?;
        let cam = &loaded.scene.camera;
        let (w, h) = (cam.width, cam.height);
        let photo_img = imageio::read_rgb(&self.photo).map_err(|source| E::ReadPhoto { source })?;
        let photo = envfit::photo_pixels(&photo_img.data, photo_img.width, photo_img.height, w, h)
            .map_err(|source| E::Photo { photo: self.photo.clone(), source })?;
        let mut mask = envfit::board_mask(cam, board);
        if let Some(m) = &self.mask {
            let extra = crate::compare::mask::Mask::from_image(m, w, h)?;
            mask.iter_mut().zip(&extra.include).for_each(|(a, b)| *a &= *b);
        }
        let mut settings = loaded.settings.clone();
        if let Some(s) = self.spp {
            settings.stop.samples = Some(s.into());
        }
        if let Some(s) = self.seed {
            settings.seed = s;
        }
        let pool = worker_pool(self.threads)?;
        ctx.say(&format!(
            "rendering the empty board of {} at {w}×{h}, {}, {} threads",
            self.scene.display(),
            settings.stop.describe("spp"),
            pool.current_num_threads()
        ));
        hooks.start(&settings);
        let (image, stats) = pool.install(|| tracer::render(&loaded.scene, &settings, &mut |p| hooks.pass(p)))?;
        hooks.finish();
        let fit = envfit::fit_scale(&image.mean, &image.variance_of_mean, &photo, &mask).map_err(|source| E::Fit {
            scene: self.scene.clone(),
            photo: self.photo.clone(),
            source,
        })?;

        let previous = file.environment.scale.unwrap_or(1.0);
        let mut copy = envfit::with_paths_from(&file, &envfit::scene_dir(&self.scene));
        let mut new_constant = None;
        let k_img: [f64; 3] = match (self.per_channel, file.environment.constant) {
            (true, Some(c)) => {
                let k = fit.scale_per_channel;
                let nc = [c[0] * k[0], c[1] * k[1], c[2] * k[2]];
                copy.environment.constant = Some(nc);
                new_constant = Some(nc);
                k
            }
            (true, None) => {
                ctx.note(&format!(
                    "the scene's environment is a map with one scale; scene.toml gets the scalar k = {:.6}, the \
                     per-channel scales {:?} are in env_scale.json",
                    fit.scale, fit.scale_per_channel
                ));
                copy.environment.scale = Some(previous * fit.scale);
                [fit.scale; 3]
            }
            (false, _) => {
                copy.environment.scale = Some(previous * fit.scale);
                [fit.scale; 3]
            }
        };
        let new_scale = copy.environment.scale.unwrap_or(1.0);
        let scene_text = toml::to_string_pretty(&copy).map_err(E::SceneText)?;
        let header = format!(
            "# {} with the environment scale fitted to the empty board {} by `lucent env fit-scale` (k = {:.6}).\n",
            self.scene.display(),
            self.photo.display(),
            fit.scale
        );
        let data: Vec<f32> = image.mean.iter().flat_map(|m| [0, 1, 2].map(|c| (m[c] * k_img[c]) as f32)).collect();
        let scaled = RgbImage::new(w, h, data)?;
        let report = FitReport {
            lucent_version: env!("CARGO_PKG_VERSION").into(),
            scene: self.scene.display().to_string(),
            photo: self.photo.display().to_string(),
            mask: self.mask.as_ref().map(|m| m.display().to_string()),
            per_channel: self.per_channel,
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
        // One output: the scaled scene never appears without its fit and render.
        let files = EnvScaleFiles::in_dir(&self.out);
        crate::io::write_files_atomic(&[
            (&files.exr, &imageio::encode_exr(&files.exr, &scaled)?),
            (&files.toml, format!("{header}{scene_text}").as_bytes()),
            (&files.json, &crate::io::json_bytes(&files.json, &report)?),
        ])?;
        Ok(EnvScaleRun { out: self.out.clone(), report, files })
    }
}
