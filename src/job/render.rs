//! The render stage: [`RenderJob::run`] renders a scene file's digital
//! twin from its calibrated camera (docs/method.md#render; the scene is
//! validated by [`crate::scene`], light transport is
//! `lucent_render::tracer`) and writes into the job's `out`
//! ([`RenderFiles`](scene::RenderFiles)):
//! * `render.exr` — linear CIE RGB (`R`, `G`, `B`), the variance of each
//!   pixel's mean (`variance.R`, …), the sample count (`spp`) and the
//!   fraction of the pixel's camera rays that hit the object first
//!   (`object`) and the board first (`board`), and the means of two
//!   independent half renders (`half_a.R`, …: the samples with even index;
//!   `half_b.R`, …: odd), from which `lucent compare` extrapolates SSIM to
//!   zero render noise;
//! * `render.png` — sRGB preview (`exposure` in stops);
//! * `render.json` — the scene as resolved, settings, seed, timings, counters;
//! * with `uncertainty`, the band of the recipe's uncertain inputs
//!   ([`RenderJob::band_of`], [`write_band`]: uncertainty.json, band.exr,
//!   band.png);
//! * with `shard` K/N, only shard K's sums ([`SHARD_ACC`], shard.json),
//!   which [`RenderJob::merge`] adds into the run's outputs.
//!
//! `lucent render`, `lucent merge` and the pipeline's render stage run it;
//! the command draws the progress bar ([`RenderHooks`]) and prints
//! [`RenderRun::summary`].

mod band;
mod error;
mod outcome;
mod outputs;
mod section;
mod shard;

pub use band::Uncertain;
pub use error::{BandError, RenderError};
pub use outcome::{BandRun, RenderRun, Rendered};
pub use outputs::{describe_errors, errors_report, report, spp_by_region, write_band, write_outputs};
pub use shard::SHARD_ACC;
// Where the render job's own words were defined before the jobs had a module.
pub use super::spec::{sampling_name, DispersionKey};

use super::context::Context;
use super::spec::RenderJob;
use super::values::ImageSize;
use crate::fault::Interrupted;
use crate::interrupt::Interrupt;
use crate::scene::{self, RenderReport, SceneSummary};
use lucent_render::tracer::{self, Settings, Stats};

/// The error target of a render that names neither a sample budget nor a
/// target: the median relative standard error per pixel over the
/// object's pixels.
pub const DEFAULT_TARGET_REL_ERROR: f64 = 0.05;

/// The sample cap of such a render (per object pixel): high enough that
/// the target or a time budget ends it.
pub const DEFAULT_SPP_CAP: u32 = 1 << 20;

/// What the caller of a render sees of it as it runs. Every method has a
/// default that does nothing, so `()` is the hooks of a render nobody
/// watches.
pub trait RenderHooks: Send {
    /// Before the first pass, with the settings the render runs with.
    fn start(&mut self, _settings: &Settings) {}
    /// After each pass.
    fn pass(&mut self, _progress: &tracer::Progress) {}
    /// After the last pass, before the outputs are written.
    fn finish(&mut self) {}
}

impl RenderHooks for () {}

impl RenderRun {
    /// What `lucent render` prints on its standard output.
    pub fn summary(&self) -> Vec<String> {
        let out = self.out.display();
        match &self.rendered {
            None => Vec::new(),
            Some(Rendered::Shard { k, n, range, wall_s }) => vec![format!(
                "shard {k}/{n}: samples {}..{} of every pixel in {wall_s:.1} s → {out}/{SHARD_ACC}, {}",
                range.start,
                range.end,
                crate::job::shard::format::SHARD_JSON
            )],
            Some(Rendered::Image { report, errors, band }) => {
                let mut lines = vec![
                    format!(
                        "{} spp in {:.1} s ({:.3} M samples/s, {:.1} M scattering events/s)",
                        report.spp,
                        report.wall_s,
                        report.samples_per_s / 1e6,
                        report.scattering_events as f64 / report.wall_s.max(1e-9) / 1e6,
                    ),
                    format!(
                        "relative standard error per pixel, median (90th, 99th percentile): {}",
                        describe_errors(errors)
                    ),
                    format!("wrote {out}/{}", scene::RenderFiles::NAMES.join(", ")),
                ];
                if let Some(b) = band {
                    lines.extend(b.band.lines());
                    let names = scene::band::RenderBandFiles::NAMES.join(", ");
                    lines.push(format!("wrote {out}/{names} ({} renders, {:.1} s)", b.renders, b.wall_s));
                }
                lines
            }
        }
    }
}

/// Checks a relative-error target: a fraction strictly between 0 and 1
/// (the range `[render] target_rel_error` has too).
pub fn check_rel_error(flag: &'static str, e: f64) -> Result<f64, RenderError> {
    if !(e > 0.0 && e < 1.0) {
        return Err(RenderError::Flag {
            flag,
            value: e,
            reason: "must lie strictly between 0 and 1 (a fraction, e.g. 0.05 for 5 %)".into(),
        });
    }
    Ok(e)
}

/// The camera's image size set to `size`, its intrinsics scaled to match
/// (about the image edge, pixel centres at integers).
pub fn resize(size: ImageSize, loaded: &mut scene::LoadedScene) {
    let (w, h) = (size.width, size.height);
    let cam = &mut loaded.scene.camera;
    let (sx, sy) = (w as f64 / cam.width as f64, h as f64 / cam.height as f64);
    let [fx, fy, cx, cy] = cam.intrinsics;
    // Pixel centres at integers: the image edge is at −½, so scale about it.
    cam.intrinsics = [fx * sx, fy * sy, (cx + 0.5) * sx - 0.5, (cy + 0.5) * sy - 0.5];
    cam.width = w;
    cam.height = h;
    loaded.summary.image_width = w;
    loaded.summary.image_height = h;
    loaded.summary.intrinsics = cam.intrinsics;
}

pub use crate::text::duration;

/// Seconds to reach the object's `target` median error from `now` after
/// `elapsed_s` (the error falls as 1/√samples, so the time grows as its
/// square): the estimate `lucent render` prints after its first pass.
pub fn time_to_target_s(elapsed_s: f64, now: f64, target: f64) -> Option<f64> {
    (now > 0.0 && target > 0.0 && elapsed_s > 0.0).then(|| elapsed_s * (now / target).powi(2))
}

/// What a render that stopped short of its error target could do instead:
/// the time it would need, or a smaller image, or the similar medium.
pub fn advice_short_of_target(elapsed_s: f64, now: f64, target: f64, width: usize, height: usize) -> String {
    let need = time_to_target_s(elapsed_s, now, target).unwrap_or(f64::INFINITY);
    // The time per pixel stays: a k × k smaller image reaches the target k² times sooner.
    let side = (need / elapsed_s.max(1e-9)).sqrt().ceil().max(2.0) as usize;
    let smaller = if side <= 4 {
        format!(", or ≈ {:.0} s at {}×{} (--size)", elapsed_s, (width / side).max(1), (height / side).max(1))
    } else {
        String::new()
    };
    format!(
        "the object reached {:.1} % in {:.0} s, short of the {:.1} % target: it needs ≈ {} at this size \
         (--time-s {:.0}){smaller}; the similar medium ([render] similarity_g = 0) is far faster on a \
         forward-scattering object but an approximation with a bias (docs/method.md#render-similarity)",
        100.0 * now,
        elapsed_s,
        100.0 * target,
        duration(need),
        need.ceil(),
    )
}

impl RenderJob {
    /// Renders and writes the outputs, nobody watching its passes.
    pub fn run(&self, ctx: &Context) -> Result<RenderRun, RenderError> {
        self.run_with(ctx, &mut ())
    }

    /// Renders and writes the outputs (with `shard` K/N, shard K's sums:
    /// its run named by the job, [`Job::shard_identity`](super::Job::shard_identity)), `hooks` told of its passes. Warnings and notes go to `ctx`
    /// (`quiet` or the job's `quiet` silences what it says of its progress).
    pub fn run_with(&self, ctx: &Context, hooks: &mut dyn RenderHooks) -> Result<RenderRun, RenderError> {
        self.run_from(ctx, hooks, None)
    }

    /// Writes the outputs of the run whose shards these are (`lucent merge`).
    pub fn merge(
        &self,
        ctx: &Context,
        shards: &[crate::job::shard::format::Shard],
        hooks: &mut dyn RenderHooks,
    ) -> Result<RenderRun, RenderError> {
        self.run_from(ctx, hooks, Some(shards))
    }

    /// The scene loaded and checked, with the job's overrides applied
    /// (image size with the intrinsics scaled to match, spp, time budget,
    /// seed, estimator choices): what the job renders. The scene's warnings
    /// are in the returned [`scene::LoadedScene`].
    pub fn prepare(&self) -> Result<(scene::LoadedScene, Settings), RenderError> {
        self.prepare_as(false, None, None)
    }

    /// [`RenderJob::prepare`]; for a merge (`for_merge`) without decoding
    /// the environment map ([`scene::load_for_merge`]), with one of the
    /// recipe's uncertain inputs set to a value (`input`) and the similar
    /// medium's g′ fixed at what another render of the scene walked
    /// (`walked`, see `scene::apply_similarity`).
    fn prepare_as(
        &self,
        for_merge: bool,
        input: Option<(crate::optics::recipe::InputTarget, f64)>,
        walked: Option<(f64, Option<(u64, f64)>)>,
    ) -> Result<(scene::LoadedScene, Settings), RenderError> {
        super::threads::check_threads(self.threads)?;
        if self.spp == Some(0) {
            return Err(RenderError::ZeroSpp);
        }
        if let Some(t) = self.time_s
            && !(t > 0.0 && t.is_finite())
        {
            return Err(RenderError::Flag {
                flag: "--time-s",
                value: t,
                reason: "must be a positive number of seconds".into(),
            });
        }
        if !self.exposure.is_finite() {
            return Err(RenderError::ExposureNotFinite);
        }
        let mut file_sampling = None;
        let mut file_spp = false;
        let mut loaded = scene::load_edited(&self.scene, for_merge, |file| {
            file_sampling = file.render.sampling;
            file_spp = file.render.spp.is_some();
            if self.similarity_g.is_some() {
                file.render.similarity_g = self.similarity_g;
            }
            if let Some(m) = file.material.as_mut() {
                m.recipe_input = input;
            }
            file.render.similarity_walked = walked;
        })
        .map_err(|e| match (e, self.similarity_g) {
            // The flag's value, not the file's: name the flag.
            (scene::SceneFileError::Key { section: "render", key: "similarity_g", problem, .. }, Some(g)) => {
                RenderError::Flag { flag: "--similarity-g", value: g, reason: problem.to_string() }
            }
            (e, _) => e.into(),
        })?;
        if let Some(size) = self.size {
            resize(size, &mut loaded);
        }
        let mut settings = loaded.settings.clone();
        self.apply(&mut settings, file_sampling, file_spp || for_merge)?;
        Ok((loaded, settings))
    }

    /// The job's flags over the scene's settings; `file_sampling` and
    /// `file_spp` say what the scene file gives (a merge counts as giving
    /// its samples).
    fn apply(
        &self,
        settings: &mut Settings,
        file_sampling: Option<scene::SamplingKey>,
        file_spp: bool,
    ) -> Result<(), RenderError> {
        if let Some(s) = self.spp {
            settings.stop.samples = Some(s.into());
        }
        if let Some(s) = self.seed {
            settings.seed = s;
        }
        if self.time_s.is_some() {
            settings.stop.time_s = self.time_s;
        }
        if let Some(d) = self.dispersion {
            settings.dispersion = d.into();
        }
        settings.split_entry |= self.split_entry;
        if let Some(e) = self.target_rel_error {
            settings.stop.pixel_rel_error = Some(check_rel_error("--target-rel-error", e)?);
        }
        // A render that names no sample budget and no error target (a
        // newcomer's first) stops at the default error target on the object,
        // with a sample cap so high that the target or the time budget ends it.
        // An error target without a sample budget is likewise not capped.
        if !file_spp && self.spp.is_none() && self.shard.is_none() {
            settings.stop.pixel_rel_error.get_or_insert(DEFAULT_TARGET_REL_ERROR);
            settings.stop.samples = Some(DEFAULT_SPP_CAP.into());
        }
        if let Some(s) = self.sampling {
            settings.sampling = s.into();
        } else if file_sampling.is_none() && settings.stop.pixel_rel_error.is_some() {
            // The error target is the object's: unless told otherwise, the samples go there.
            settings.sampling = tracer::Sampling::ObjectWeighted;
        }
        Ok(())
    }

    /// "rendering SCENE at W×H, BUDGET, N threads".
    fn rendering_line(&self, settings: &Settings, (w, h): (usize, usize), threads: usize) -> String {
        let budget = match settings.stop.pixel_rel_error {
            Some(e) if settings.spp() == DEFAULT_SPP_CAP => {
                format!("until the object's median error per pixel is {:.1} % (no spp given)", 100.0 * e)
            }
            Some(e) => format!("up to {} spp, until the object's median error is {:.1} %", settings.spp(), 100.0 * e),
            None => format!("{} spp", settings.spp()),
        };
        format!(
            "rendering {} at {w}×{h}, {budget}{}, {threads} threads",
            self.scene.display(),
            settings.stop.time_s.map(|t| format!(" (at most {t} s)")).unwrap_or_default()
        )
    }

    /// Renders (or, with `merged_from`, adds the shards' sums), writes the
    /// outputs and, with `uncertainty`, the band.
    fn run_from(
        &self,
        ctx: &Context,
        hooks: &mut dyn RenderHooks,
        merged_from: Option<&[crate::job::shard::format::Shard]>,
    ) -> Result<RenderRun, RenderError> {
        let ctx = &Context { quiet: ctx.quiet || self.quiet };
        let (loaded, mut settings) = self.prepare_as(merged_from.is_some(), None, None)?;
        for w in &loaded.warnings {
            ctx.warn(w);
        }
        let shard = self.shard.map(crate::job::shard::format::ShardSpec::pair);
        if shard.is_some() || merged_from.is_some() {
            shard::check_shardable(&settings)?;
        }
        if self.uncertainty && (shard.is_some() || merged_from.is_some()) {
            return Err(RenderError::UncertaintyShard);
        }
        // The uncertain inputs, checked before any work.
        let uncertain = self.uncertain_inputs(ctx, &loaded, &mut settings)?;
        if let Some((k, n)) = shard
            && n > settings.spp()
        {
            let units = settings.spp().into();
            return Err(crate::job::shard::format::ShardError::TooManyShards {
                k,
                n,
                units,
                what: "samples per pixel",
            }
            .into());
        }
        let (w, h) = (loaded.scene.camera.width, loaded.scene.camera.height);
        // A merge reads every shard before it writes anything.
        let merged_result = match merged_from {
            Some(shards) => Some(shard::merged(shards, &settings, w, h)?),
            None => None,
        };
        std::fs::create_dir_all(&self.out)
            .map_err(|source| RenderError::CreateDir { path: self.out.clone(), source })?;
        let pool = super::threads::worker_pool(self.threads)?;
        let threads = pool.current_num_threads();
        for line in scene::approximations(&loaded.summary, &settings) {
            ctx.note(&format!("approximation: {line}"));
        }
        ctx.say(&self.rendering_line(&settings, (w, h), threads));
        if let Some((k, n)) = shard {
            return self.render_shard(&loaded, &settings, &pool, (k, n));
        }
        hooks.start(&settings);
        let interrupt = Interrupt::install();
        let (image, stats) = match merged_result {
            Some(m) => m,
            None => pool.install(|| {
                tracer::render_cancellable(&loaded.scene, &settings, &mut |p| hooks.pass(p), Some(interrupt.flag()))
            })?,
        };
        let interrupted = interrupt.requested();
        drop(interrupt);
        hooks.finish();
        let files = write_outputs(&self.out, &image, self.exposure)?;
        let mut report = report(&loaded.summary, &settings, &image, &stats, threads, self.exposure, &files);
        report.interrupted = interrupted;
        let json = scene::RenderFiles::in_dir(&self.out).json;
        crate::io::write_json(&json, &report)
            .map_err(|e| RenderError::Write { path: json.clone(), source: e.into() })?;
        warn_lost_paths(ctx, &loaded.summary, &settings, &stats);
        let errors = image.region_errors();
        if let Some(t) = settings.stop.pixel_rel_error
            && errors.object.pixels > 0
            && errors.object.median > t
            && !interrupted
        {
            warn_short_of_target(ctx, &report, &settings, errors.object.median, t, (w, h));
        }
        let band = match (&uncertain, interrupted) {
            (Some(u), false) => Some(self.render_band(ctx, &loaded, &settings, &pool, &image, u)?),
            _ => None,
        };
        let interrupted = interrupted.then(|| {
            Interrupted(format!(
                "{}/render.* hold the {} spp finished before Ctrl-C (render.json says \"interrupted\": true)",
                self.out.display(),
                report.spp
            ))
        });
        let rendered = Some(Rendered::Image { report: Box::new(report), errors, band: band.map(Box::new) });
        Ok(RenderRun { out: self.out.clone(), rendered, interrupted })
    }

    /// With `uncertainty`: the band of the nominal render `image` ([`RenderJob::band_of`]),
    /// written to uncertainty.json, band.exr and band.png beside it.
    fn render_band(
        &self,
        ctx: &Context,
        loaded: &scene::LoadedScene,
        settings: &Settings,
        pool: &rayon::ThreadPool,
        image: &tracer::Image,
        u: &Uncertain,
    ) -> Result<BandRun, RenderError> {
        let interrupt = Interrupt::install();
        let started = std::time::Instant::now();
        let (band, renders) = self
            .band_of(ctx, loaded, settings, pool, image, &u.recipe, &u.path_derivatives, interrupt.flag())
            .map_err(|source| RenderError::Band { out: self.out.clone(), source })?;
        drop(interrupt);
        let wall_s = started.elapsed().as_secs_f64();
        write_band(&self.out, image, &band)?;
        Ok(BandRun { band, renders, wall_s })
    }
}

/// Warns of paths lost inside the object (a hole, or a mesh in the wrong
/// unit) and of paths ended at the event limit.
fn warn_lost_paths(ctx: &Context, summary: &SceneSummary, settings: &Settings, stats: &Stats) {
    if stats.leaked_paths > 0 {
        // A hole, or a mesh in the wrong unit (larger than the scene around it): say which is likelier.
        let size = summary.object_bounds_m.and_then(|[lo, hi]| scene::mesh::size_warning(lo, hi));
        ctx.warn(&format!(
            "{} paths found no boundary while inside the object (a hole in the mesh{}); their light is lost",
            stats.leaked_paths,
            size.map_or(String::new(), |s| format!(", or {s}"))
        ));
    }
    if stats.truncated_paths > 0 {
        ctx.warn(&format!(
            "{} paths were ended after {} scattering events (biased low there)",
            stats.truncated_paths, settings.max_events_per_path
        ));
    }
}

/// Warns that the object's median error `median` stayed above the target
/// `t`: at the sample budget, or with advice on the time a `w` × `h` image
/// would take.
fn warn_short_of_target(
    ctx: &Context,
    report: &RenderReport,
    settings: &Settings,
    median: f64,
    t: f64,
    (w, h): (usize, usize),
) {
    if report.spp >= settings.spp() {
        ctx.warn(&format!(
            "the object reached {:.1} % at the sample budget of {} spp (--spp or [render] spp), short of the {:.1} % target",
            100.0 * median,
            settings.spp(),
            100.0 * t
        ));
    } else {
        ctx.warn(&advice_short_of_target(report.wall_s, median, t, w, h));
    }
}
