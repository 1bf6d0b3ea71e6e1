//! `lucent render SCENE.toml`: the digital twin rendered from the calibrated
//! camera (docs/method.md#render). Orchestration only: the scene file is validated by
//! [`crate::scene`], light transport is `lucent_render::tracer`.
//!
//! Outputs in `--out` (default `lucent-out/render`):
//! * `render.exr` — linear CIE RGB (`R`, `G`, `B`), the variance of each
//!   pixel's mean (`variance.R`, …), the sample count (`spp`) and the
//!   fraction of the pixel's camera rays that hit the object first
//!   (`object`) and the board first (`board`), and the means of two
//!   independent half renders (`half_a.R`, …: the samples with even index;
//!   `half_b.R`, …: odd), from which `lucent compare` extrapolates SSIM to
//!   zero render noise;
//! * `render.png` — sRGB preview (`--exposure` in stops);
//! * `render.json` — the scene as resolved, settings, seed, timings, counters.

use super::common::{check_time_s, duration};
use super::interrupt::Interrupt;
use crate::fault::Interrupted;
use crate::imageio::{self, RgbImage};
use crate::scene::{self, RenderReport, SceneSummary};
use anyhow::{bail, Context, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lucent_render::tracer::{self, Condition, Image, NotSplittable, Settings, Stats, Stop};
use serde::Serialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct RenderArgs {
    /// Scene file (TOML; format in the README and `src/scene/mod.rs`).
    pub scene: PathBuf,
    /// Output folder for render.exr, render.png and render.json.
    #[arg(long, default_value = "lucent-out/render")]
    pub out: PathBuf,
    #[command(flatten)]
    pub render: super::groups::TwinRenderArgs,
    /// Wall-time budget in seconds: stop after the pass that exceeds it (overrides [render] time_s).
    #[arg(long)]
    pub time_s: Option<f64>,
    /// Exposure of the PNG preview in stops (the EXR is never scaled).
    #[arg(long, default_value_t = 0.0)]
    pub exposure: f64,
    /// Stop when the median relative standard error over the object's
    /// pixels reaches this fraction (e.g. 0.05; overrides [render] target_rel_error).
    #[arg(long)]
    pub target_rel_error: Option<f64>,
    /// How samples are spread over the pixels (overrides [render] sampling):
    /// object-weighted (the object's pixels get what their error needs) or
    /// uniform. Default: object-weighted with an error target, else uniform.
    #[arg(long, value_enum)]
    pub sampling: Option<SamplingArg>,
    /// Refraction where the bands' indices differ: per-band (exact, default:
    /// one band per path) or shared-directions (the bands' mean index for
    /// directions, Fresnel per band, all bands on every path; approximate).
    #[arg(long, value_enum)]
    pub dispersion: Option<DispersionArg>,
    /// Walk the object's similar medium of asymmetry G, raised (the same in
    /// every band) where it would be under 3 mean free paths deep (μs(1 − g),
    /// μa and n kept; 0 ≤ G < 1; overrides [render] similarity_g): far
    /// fewer events and less noise for a strongly forward-scattering medium,
    /// an approximation whose bias is measured in docs/method.md.
    #[arg(long, value_name = "G", allow_hyphen_values = true)]
    pub similarity_g: Option<f64>,
    /// Follow both the reflection and the refraction where a path meets the object from outside.
    #[arg(long)]
    pub split_entry: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Render only the K-th of N disjoint ranges of sample indices of this
    /// run (0 ≤ K < N) into --out as a shard (render.acc, shard.json);
    /// `lucent merge` adds the N shards into the run's render.exr, png and
    /// json. Needs a sample budget (--spp or [render] spp; no time budget or
    /// error target) and uniform sampling.
    #[arg(long, value_name = "K/N")]
    pub shard: Option<String>,
    /// Carry the recipe's uncertain inputs (e.g. `weight_percent = { value =
    /// 0.65, sd = 0.03 }`) to the render: an input that changes only μs and
    /// μa (a weight percentage) by the render's own paths (path
    /// derivative, no extra render), any other by the scene rendered at
    /// +1 σ and −1 σ with the same seed and samples; writes
    /// uncertainty.json (each region's mean with its band), band.exr
    /// (per pixel) and band.png (the relative band over the object).
    /// Needs a scene whose [material] has a recipe.
    #[arg(long)]
    pub uncertainty: bool,
    /// Samples per pixel of each render at ±1 σ (--uncertainty; even;
    /// default: half the nominal render's median over the object's pixels).
    #[arg(long, requires = "uncertainty")]
    pub uncertainty_spp: Option<u32>,
    /// With --uncertainty: every input by renders at ±1 σ, also those the
    /// path derivative would take (a check of one estimator by the other).
    #[arg(long, requires = "uncertainty")]
    pub uncertainty_renders: bool,
}

/// The accumulator file of a render shard.
pub const SHARD_ACC: &str = "render.acc";

/// Refuses what a shard of a render cannot do exactly: a stop rule other
/// than a sample count ([`Stop::shard_samples`]), object-weighted sampling.
fn check_shardable(settings: &Settings) -> Result<()> {
    match settings.stop.shard_samples() {
        Ok(_) => {}
        Err(NotSplittable::NoSamples) => bail!("--shard: needs a sample budget (--spp or [render] spp)"),
        Err(NotSplittable::Beside(Condition::Time)) => {
            bail!("--shard: a time budget (--time-s or [render] time_s) cannot be split into shards exactly; give a sample budget (--spp) instead")
        }
        Err(NotSplittable::Beside(_)) => {
            bail!("--shard: an error target (--target-rel-error or [render] target_rel_error) depends on the whole image; give a sample budget (--spp) instead")
        }
    }
    if settings.sampling != tracer::Sampling::Uniform {
        bail!("--shard: object-weighted sampling plans every pass from the image so far and cannot be split; use --sampling uniform");
    }
    Ok(())
}

/// The merged sums of a render's shards (added in shard order) and their counters.
fn merged(shards: &[crate::shard::Shard], settings: &Settings, w: usize, h: usize) -> Result<(Image, Stats)> {
    let n = w * h;
    let mut acc = tracer::Accumulator::new(w, h);
    let mut stats = Stats::default();
    for s in shards {
        let k = s.file.shard;
        let expected = crate::shard::range(u64::from(settings.spp()), k, s.file.identity.shards);
        if s.file.range != [expected.start, expected.end] {
            bail!(
                "{}: shard {k} holds samples {:?}, the run's shard {k} is {expected:?}",
                s.dir.display(),
                s.file.range
            );
        }
        let path = s.dir.join(SHARD_ACC);
        let arrays = crate::shard::read_accumulator(&path)?;
        let get = |name: &str, len: usize| crate::shard::array(&arrays, name, len, &path);
        let (sum, sq, even) = (get("sum", 3 * n)?, get("sum_sq", 3 * n)?, get("sum_even", 3 * n)?);
        let (samples, object, board) = (get("samples", n)?, get("object_samples", n)?, get("board_samples", n)?);
        let count = (expected.end - expected.start) as f64;
        if let Some(p) = samples.iter().position(|&c| c != count) {
            bail!("{}: pixel {p} has {} samples, the shard should have {count}", path.display(), samples[p]);
        }
        for p in 0..n {
            for c in 0..3 {
                acc.sum[p][c] += sum[3 * p + c];
                acc.sum_sq[p][c] += sq[3 * p + c];
                acc.sum_even[p][c] += even[3 * p + c];
            }
            acc.samples[p] += samples[p] as u32;
            acc.object_samples[p] += object[p] as u32;
            acc.board_samples[p] += board[p] as u32;
        }
        let c = |name: &str| s.file.counters.get(name).copied().unwrap_or(0);
        stats.samples += c("samples");
        stats.events += c("events");
        stats.surface_hits += c("surface_hits");
        stats.leaked_paths += c("leaked_paths");
        stats.truncated_paths += c("truncated_paths");
        stats.passes += c("passes") as u32;
        stats.wall_s += s.file.wall_s;
    }
    Ok((acc.image(), stats))
}

/// Writes a render shard's accumulator and shard.json (last: a folder with
/// a shard.json holds a complete shard).
fn write_shard(
    out: &Path,
    acc: &tracer::Accumulator,
    stats: &Stats,
    identity: crate::shard::Identity,
    k: u32,
    range: std::ops::Range<u64>,
) -> Result<()> {
    let flat = |v: &[[f64; 3]]| v.iter().flatten().copied().collect::<Vec<f64>>();
    let counts = |v: &[u32]| v.iter().map(|&c| f64::from(c)).collect::<Vec<f64>>();
    let (sum, sq, even) = (flat(&acc.sum), flat(&acc.sum_sq), flat(&acc.sum_even));
    let (samples, object, board) = (counts(&acc.samples), counts(&acc.object_samples), counts(&acc.board_samples));
    let counters: std::collections::BTreeMap<String, u64> = [
        ("samples", stats.samples),
        ("events", stats.events),
        ("surface_hits", stats.surface_hits),
        ("leaked_paths", stats.leaked_paths),
        ("truncated_paths", stats.truncated_paths),
        ("passes", u64::from(stats.passes)),
    ]
    .into_iter()
    .map(|(k, v)| (k.to_string(), v))
    .collect();
    crate::shard::write_shard_accumulator(
        &out.join(SHARD_ACC),
        &crate::shard::AccMeta::new(&identity, k, &range, &counters),
        &[
            ("sum", &sum),
            ("sum_sq", &sq),
            ("sum_even", &even),
            ("samples", &samples),
            ("object_samples", &object),
            ("board_samples", &board),
        ],
    )?;
    let file = crate::shard::ShardFile {
        identity,
        shard: k,
        range: [range.start, range.end],
        accumulators: vec![SHARD_ACC.into()],
        counters,
        wall_s: stats.wall_s,
    };
    crate::io::write_json(&out.join(crate::shard::SHARD_JSON), &file)?;
    Ok(())
}

/// `--dispersion`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum DispersionArg {
    PerBand,
    SharedDirections,
}

impl From<DispersionArg> for tracer::Dispersion {
    fn from(a: DispersionArg) -> Self {
        match a {
            DispersionArg::PerBand => Self::PerBand,
            DispersionArg::SharedDirections => Self::SharedDirections,
        }
    }
}

/// `--sampling`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum SamplingArg {
    Uniform,
    ObjectWeighted,
}

impl From<SamplingArg> for tracer::Sampling {
    fn from(a: SamplingArg) -> Self {
        match a {
            SamplingArg::Uniform => Self::Uniform,
            SamplingArg::ObjectWeighted => Self::ObjectWeighted,
        }
    }
}

/// Checks a relative-error target: a fraction strictly between 0 and 1
/// (the range `[render] target_rel_error` has too).
pub fn check_rel_error(flag: &str, e: f64) -> Result<f64> {
    if !(e > 0.0 && e < 1.0) {
        bail!("{flag} {e}: must lie strictly between 0 and 1 (a fraction, e.g. 0.05 for 5 %)");
    }
    Ok(e)
}

/// The scene of `a` loaded and checked, with the arguments' overrides
/// applied (image size with the intrinsics scaled to match, spp, time
/// budget, seed, estimator choices): what `lucent render` renders. The
/// scene's warnings are in the returned [`scene::LoadedScene`].
pub fn prepare(a: &RenderArgs) -> Result<(scene::LoadedScene, Settings)> {
    prepare_with(a, false)
}

/// [`prepare`]; for a merge (`for_merge`) without decoding the environment
/// map ([`scene::load_for_merge`]).
fn prepare_with(a: &RenderArgs, for_merge: bool) -> Result<(scene::LoadedScene, Settings)> {
    prepare_input(a, for_merge, None)
}

/// [`prepare_with`] with one of the recipe's uncertain inputs set to a value.
fn prepare_input(
    a: &RenderArgs,
    for_merge: bool,
    input: Option<(crate::optics::recipe::InputTarget, f64)>,
) -> Result<(scene::LoadedScene, Settings)> {
    prepare_as(a, for_merge, input, None)
}

/// [`prepare_input`] with the similar medium's g′ fixed at what another
/// render of the scene walked (`walked`, see `scene::apply_similarity`).
fn prepare_as(
    a: &RenderArgs,
    for_merge: bool,
    input: Option<(crate::optics::recipe::InputTarget, f64)>,
    walked: Option<(f64, Option<(u64, f64)>)>,
) -> Result<(scene::LoadedScene, Settings)> {
    a.render.check()?;
    if let Some(t) = a.time_s {
        check_time_s(t)?;
    }
    if !a.exposure.is_finite() {
        bail!("--exposure must be finite");
    }
    let mut file_sampling = None;
    let mut file_spp = false;
    let mut loaded = scene::load_edited(&a.scene, for_merge, |file| {
        file_sampling = file.render.sampling;
        file_spp = file.render.spp.is_some();
        if a.similarity_g.is_some() {
            file.render.similarity_g = a.similarity_g;
        }
        if let Some(m) = file.material.as_mut() {
            m.recipe_input = input;
        }
        file.render.similarity_walked = walked;
    })
    .map_err(|e| match (e, a.similarity_g) {
        // The flag's value, not the file's: name the flag.
        (scene::SceneFileError::Key { section: "render", key: "similarity_g", problem, .. }, Some(g)) => {
            anyhow::anyhow!("--similarity-g {g}: {problem}")
        }
        (e, _) => e.into(),
    })?;
    a.render.resize(&mut loaded)?;
    let mut settings = loaded.settings.clone();
    a.render.apply(&mut settings);
    if a.time_s.is_some() {
        settings.stop.time_s = a.time_s;
    }
    if let Some(d) = a.dispersion {
        settings.dispersion = d.into();
    }
    settings.split_entry |= a.split_entry;
    if let Some(e) = a.target_rel_error {
        settings.stop.pixel_rel_error = Some(check_rel_error("--target-rel-error", e)?);
    }
    // A render that names no sample budget and no error target (a
    // newcomer's first) stops at the default error target on the object,
    // with a sample cap so high that the target or the time budget ends it.
    // An error target without a sample budget is likewise not capped.
    if !file_spp && a.render.spp.is_none() && a.shard.is_none() && !for_merge {
        settings.stop.pixel_rel_error.get_or_insert(DEFAULT_TARGET_REL_ERROR);
        settings.stop.samples = Some(DEFAULT_SPP_CAP.into());
    }
    if let Some(s) = a.sampling {
        settings.sampling = s.into();
    } else if file_sampling.is_none() && settings.stop.pixel_rel_error.is_some() {
        // The error target is the object's: unless told otherwise, the samples go there.
        settings.sampling = tracer::Sampling::ObjectWeighted;
    }
    Ok((loaded, settings))
}

/// The error target of a render that names neither a sample budget nor a
/// target: the median relative standard error per pixel over the
/// object's pixels.
pub const DEFAULT_TARGET_REL_ERROR: f64 = 0.05;

/// The sample cap of such a render (per object pixel): high enough that
/// the target or a time budget ends it.
pub const DEFAULT_SPP_CAP: u32 = 1 << 20;

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

/// The bar of a render: an error target's counts towards the target, in
/// 0.1 % of error² reduction; a sample budget's counts samples (with the
/// time left). Hidden when `quiet`.
pub(super) fn progress_bar(quiet: bool, settings: &tracer::Settings) -> ProgressBar {
    let target = settings.stop.pixel_rel_error;
    let bar = if quiet {
        ProgressBar::hidden()
    } else if target.is_some() {
        ProgressBar::new(1000)
    } else {
        ProgressBar::new(u64::from(settings.spp()))
    };
    bar.set_style(
        ProgressStyle::with_template(if target.is_some() {
            "{bar:40} {elapsed_precise}  {msg}"
        } else {
            "{bar:40} {pos}/{len} spp  {msg}  ETA {eta}"
        })
        .unwrap_or_else(|_| ProgressStyle::default_bar()),
    );
    bar
}

/// A render's pass on [`progress_bar`]'s bar; after the first pass that
/// tells (`estimated` not yet set), the line "expect ≈ …" on stderr unless `quiet`.
pub(super) fn show_progress(
    bar: &ProgressBar,
    settings: &tracer::Settings,
    quiet: bool,
    estimated: &mut bool,
    p: &tracer::Progress,
) {
    let line = match settings.stop.pixel_rel_error {
        Some(e) if p.errors.object.pixels > 0 && p.errors.object.median > 0.0 => {
            // Fraction of the way in error² (∝ time), and once the first pass tells, the expected time.
            let now = p.errors.object.median;
            let frac = (e / now).powi(2).min(1.0);
            bar.set_position((1000.0 * frac) as u64);
            // (A median still infinite, some object pixel without light in
            // a channel, tells nothing yet: the next pass will.)
            if !*estimated && now.is_finite() && now > e {
                *estimated = true;
                time_to_target_s(p.elapsed_s, now, e).map(|t| {
                    let over = settings.stop.time_s.is_some_and(|b| t > b);
                    format!(
                        "expect ≈ {} to {:.1} % on the object ({:.1} % after {} spp in {:.1} s){}",
                        duration(t),
                        100.0 * e,
                        100.0 * now,
                        p.spp_done,
                        p.elapsed_s,
                        if over { "; beyond the time budget" } else { "" }
                    )
                })
            } else {
                None
            }
        }
        Some(_) => {
            bar.set_position(u64::from(p.spp_done));
            None
        }
        None => {
            bar.set_position(u64::from(p.spp_done));
            // A sample budget: the rate of the first pass.
            let spp = settings.spp();
            let first = !*estimated && p.spp_done > 0 && p.spp_done < spp && p.elapsed_s > 0.0;
            *estimated = true;
            first.then(|| {
                let t = p.elapsed_s * f64::from(spp) / f64::from(p.spp_done);
                let over = settings.stop.time_s.is_some_and(|b| t > b);
                format!(
                    "expect ≈ {} for {} spp ({} spp in {:.1} s){}",
                    duration(t),
                    spp,
                    p.spp_done,
                    p.elapsed_s,
                    if over { "; beyond the time budget" } else { "" }
                )
            })
        }
    };
    // Printed whether or not the bar is drawn (a log file gets it too).
    if let Some(line) = line
        && !quiet
    {
        bar.suspend(|| eprintln!("{line}"));
    }
    bar.set_message(format!(
        "object {:.1} % (p90 {:.1} %), board {:.1} %, {:.1} M events/s",
        100.0 * p.errors.object.median,
        100.0 * p.errors.object.p90,
        100.0 * p.errors.board.median,
        p.stats.events as f64 / p.elapsed_s / 1e6
    ));
}

/// Runs `lucent render`.
pub fn run(a: RenderArgs) -> Result<()> {
    run_from(a, None)
}

/// Runs `lucent render`, or with `merged` writes the outputs of the run
/// whose shards these are (`lucent merge`).
pub fn run_from(a: RenderArgs, merged_from: Option<&[crate::shard::Shard]>) -> Result<()> {
    let (loaded, mut settings) = prepare_with(&a, merged_from.is_some())?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    let shard = a.shard.as_deref().map(crate::shard::parse_spec).transpose()?;
    if shard.is_some() || merged_from.is_some() {
        check_shardable(&settings)?;
    }
    if a.uncertainty && (shard.is_some() || merged_from.is_some()) {
        bail!("--uncertainty: the renders at ±1 σ are not sharded; run without --shard");
    }
    // The uncertain inputs, checked before any work.
    let (uncertain, path_derivatives) = match uncertain_inputs(&a, &loaded, &mut settings)? {
        Some(u) => (Some(u.recipe), u.path_derivatives),
        None => (None, Vec::new()),
    };
    if let Some((k, n)) = shard
        && n > settings.spp()
    {
        return Err(crate::shard::ShardError::TooManyShards {
            k,
            n,
            units: settings.spp().into(),
            what: "samples per pixel",
        }
        .into());
    }
    // A merge reads every shard before it writes anything.
    let merged_result = match merged_from {
        Some(shards) => Some(merged(shards, &settings, loaded.scene.camera.width, loaded.scene.camera.height)?),
        None => None,
    };
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}: cannot create output folder", a.out.display()))?;
    let pool = a.render.pool()?;
    let threads = pool.current_num_threads();
    let (w, h) = (loaded.scene.camera.width, loaded.scene.camera.height);
    let target = settings.stop.pixel_rel_error;
    for line in scene::approximations(&loaded.summary, &settings) {
        eprintln!("note: approximation: {line}");
    }
    if !a.quiet {
        let budget = match target {
            Some(e) if settings.spp() == DEFAULT_SPP_CAP => {
                format!("until the object's median error per pixel is {:.1} % (no spp given)", 100.0 * e)
            }
            Some(e) => format!("up to {} spp, until the object's median error is {:.1} %", settings.spp(), 100.0 * e),
            None => format!("{} spp", settings.spp()),
        };
        eprintln!(
            "rendering {} at {w}×{h}, {budget}{}, {threads} threads",
            a.scene.display(),
            settings.stop.time_s.map(|t| format!(" (at most {t} s)")).unwrap_or_default()
        );
    }
    let bar = progress_bar(a.quiet, &settings);
    let mut estimated = false;
    if let Some((k, n)) = shard {
        return render_shard(&a, &loaded, &settings, &pool, (k, n));
    }
    let interrupt = Interrupt::install();
    let (image, stats) = if let Some(m) = merged_result {
        m
    } else {
        pool.install(|| {
            tracer::render_cancellable(
                &loaded.scene,
                &settings,
                &mut |p| show_progress(&bar, &settings, a.quiet, &mut estimated, p),
                Some(interrupt.flag()),
            )
        })?
    };
    let interrupted = interrupt.requested();
    drop(interrupt);
    bar.finish_and_clear();
    let files = write_outputs(&a.out, &image, a.exposure)?;
    let mut report = report(&loaded.summary, &settings, &image, &stats, threads, a.exposure, &files);
    report.interrupted = interrupted;
    let json = scene::RenderFiles::in_dir(&a.out).json;
    crate::io::write_json(&json, &report).with_context(|| format!("{}: cannot write", json.display()))?;
    warn_lost_paths(&loaded.summary, &settings, &stats);
    let e = image.region_errors();
    println!(
        "{} spp in {:.1} s ({:.3} M samples/s, {:.1} M scattering events/s)",
        report.spp,
        report.wall_s,
        report.samples_per_s / 1e6,
        stats.events as f64 / stats.wall_s.max(1e-9) / 1e6,
    );
    println!("relative standard error per pixel, median (90th, 99th percentile): {}", describe_errors(&e));
    if let Some(t) = settings.stop.pixel_rel_error
        && e.object.pixels > 0
        && e.object.median > t
        && !interrupted
    {
        warn_short_of_target(&report, &settings, e.object.median, t, (w, h));
    }
    println!("wrote {}/render.exr, render.png, render.json", a.out.display());
    if let (Some(recipe), false) = (&uncertain, interrupted) {
        render_band(&a, &loaded, &settings, &pool, &image, recipe, &path_derivatives)?;
    }
    if interrupted {
        return Err(Interrupted(format!(
            "{}/render.* hold the {} spp finished before Ctrl-C (render.json says \"interrupted\": true)",
            a.out.display(),
            report.spp
        ))
        .into());
    }
    Ok(())
}

/// Renders shard k of n (`--shard K/N`): its range of the samples of every
/// pixel, tallied into --out with shard.json.
fn render_shard(
    a: &RenderArgs,
    loaded: &scene::LoadedScene,
    settings: &Settings,
    pool: &rayon::ThreadPool,
    (k, n): (u32, u32),
) -> Result<()> {
    let range = crate::shard::range(u64::from(settings.spp()), k, n);
    let identity = super::shard::identity(settings.seed, format!("{} spp", settings.spp()), n)?;
    super::shard::check_shard_out(&a.out, &identity, k)?;
    let interrupt = Interrupt::install();
    let (acc, stats) = pool.install(|| {
        tracer::render_samples(&loaded.scene, settings, range.start as u32..range.end as u32, Some(interrupt.flag()))
    });
    if interrupt.requested() {
        return Err(Interrupted(format!("shard {k}/{n} not written (a shard is merged whole or not at all)")).into());
    }
    drop(interrupt);
    // Another shard may have finished into the same folder meanwhile.
    super::shard::check_shard_out(&a.out, &identity, k)?;
    write_shard(&a.out, &acc, &stats, identity, k, range.clone())?;
    println!(
        "shard {k}/{n}: samples {}..{} of every pixel in {:.1} s → {}/{SHARD_ACC}, {}",
        range.start,
        range.end,
        stats.wall_s,
        a.out.display(),
        crate::shard::SHARD_JSON
    );
    Ok(())
}

/// Warns of paths lost inside the object (a hole, or a mesh in the wrong
/// unit) and of paths ended at the event limit.
fn warn_lost_paths(summary: &SceneSummary, settings: &Settings, stats: &Stats) {
    if stats.leaked_paths > 0 {
        // A hole, or a mesh in the wrong unit (larger than the scene around it): say which is likelier.
        let size = summary.object_bounds_m.and_then(|[lo, hi]| scene::mesh::size_warning(lo, hi));
        eprintln!(
            "warning: {} paths found no boundary while inside the object (a hole in the mesh{}); their light is lost",
            stats.leaked_paths,
            size.map_or(String::new(), |s| format!(", or {s}"))
        );
    }
    if stats.truncated_paths > 0 {
        eprintln!(
            "warning: {} paths were ended after {} scattering events (biased low there)",
            stats.truncated_paths, settings.max_events_per_path
        );
    }
}

/// Warns that the object's median error `median` stayed above the target
/// `t`: at the sample budget, or with advice on the time a `w` × `h` image
/// would take.
fn warn_short_of_target(report: &RenderReport, settings: &Settings, median: f64, t: f64, (w, h): (usize, usize)) {
    if report.spp >= settings.spp() {
        eprintln!(
            "warning: the object reached {:.1} % at the sample budget of {} spp (--spp or [render] spp), short of the {:.1} % target",
            100.0 * median,
            settings.spp(),
            100.0 * t
        );
    } else {
        eprintln!("warning: {}", advice_short_of_target(report.wall_s, median, t, w, h));
    }
}

/// With `--uncertainty`: the scene's recipe (refused without one or
/// without an uncertain input) and, per uncertain input, its index in
/// `settings.derivatives` (pushed here) where the nominal render's own
/// paths carry its effect (with what that leaves out), `None` where it is
/// rendered at ±1 σ. `None` without `--uncertainty`.
pub fn uncertain_inputs(
    a: &RenderArgs,
    loaded: &scene::LoadedScene,
    settings: &mut Settings,
) -> Result<Option<Uncertain>> {
    if !a.uncertainty {
        return Ok(None);
    }
    if let Some(n) = a.uncertainty_spp
        && (n == 0 || n % 2 == 1)
    {
        bail!("--uncertainty-spp {n}: must be a positive even number (the band's error comes from the two halves of the samples)");
    }
    let recipe = scene::material_recipe(&a.scene)?.ok_or_else(|| {
        anyhow::anyhow!("--uncertainty: {} has no [material] recipe to take uncertain inputs from", a.scene.display())
    })?;
    if recipe.uncertain.is_empty() {
        bail!(
            "--uncertainty: the recipe {} gives no input with an uncertainty (write e.g. weight_percent = {{ value = 0.65, sd = 0.03 }})",
            recipe.path.display()
        );
    }
    let found = if a.uncertainty_renders {
        vec![None; recipe.uncertain.len()]
    } else {
        coefficient_derivatives(a, loaded, &recipe)?
    };
    let mut index = Vec::new();
    for d in found {
        index.push(match d {
            Some((d, left_out)) if settings.derivatives.len() < tracer::MAX_DERIVATIVES => {
                settings.derivatives.push(d);
                Some((settings.derivatives.len() - 1, left_out))
            }
            _ => None,
        });
    }
    if settings.sphere_jumps && !settings.derivatives.is_empty() && !a.quiet {
        eprintln!("note: sphere jumps are off in this render: the path derivatives of --uncertainty need every scattering event");
    }
    Ok(Some(Uncertain { recipe, path_derivatives: index }))
}

/// The recipe's uncertain inputs of a render ([`uncertain_inputs`]).
pub struct Uncertain {
    pub recipe: crate::optics::recipe::Recipe,
    /// Per input, its index in the settings' derivatives and what that
    /// leaves out (relative), or `None`: rendered at ±1 σ.
    pub path_derivatives: Vec<Option<(usize, f64)>>,
}

/// The similar medium's g′ (and the later one's) that the nominal render
/// walks, for the renders at ±1 σ: the depth floor would otherwise move g′
/// with the input, and the phase functions with it, and the renders would
/// no longer share their paths.
fn walked_similarity(loaded: &scene::LoadedScene) -> Option<(f64, Option<(u64, f64)>)> {
    loaded.summary.material.as_ref().and_then(|m| m.similar.as_ref()).map(|s| {
        // (+1e-9: the walked g′ is the table's mean cosine, which the cut's own test may round just above.)
        (s.g[0] + 1e-9, s.later.as_ref().map(|l| (l.from_event, l.g[0] + 1e-9)))
    })
}

/// The largest relative change of the phase functions and indices between
/// an input's ±1 σ that its path derivative may leave out (a weight
/// percentage of IOL1068-09 changes them by ≤ 4·10⁻⁴ through the bands'
/// spectral weights and 2·10⁻⁶ through the mixture's index; the test
/// against renders at ±1 σ bounds the effect).
const PATH_DERIVATIVE_LEFT_OUT: f64 = 1e-3;

/// Per uncertain input of `recipe`, the derivative of the object's
/// coefficients per 1 σ where the input changes only μs and μa
/// ([`tracer::Object::coefficient_derivative`] of the scenes at ±1 σ): the
/// nominal render then estimates its effect from its own paths. `None`
/// for an input that changes more (it is rendered at ±1 σ).
fn coefficient_derivatives(
    a: &RenderArgs,
    loaded: &scene::LoadedScene,
    recipe: &crate::optics::recipe::Recipe,
) -> Result<Vec<Option<(tracer::CoefficientDerivative, f64)>>> {
    let walked = walked_similarity(loaded);
    let inputs = crate::optics::uncertainty::InputSd::of(recipe);
    let mut out = Vec::new();
    for (input, sd) in recipe.uncertain.iter().zip(&inputs) {
        let mut at = Vec::new();
        for (sign, value) in [("+", input.nominal + sd.sd), ("−", input.nominal - sd.sd)] {
            let (scene, _) = prepare_as(a, false, Some((input.target, value)), walked)
                .with_context(|| format!("--uncertainty: {} = {value} (nominal {sign} 1 σ)", input.key))?;
            at.push(scene.scene.object);
        }
        out.push(match (&loaded.scene.object, &at[0], &at[1]) {
            (Some(o), Some(plus), Some(minus)) => o.coefficient_derivative(plus, minus, PATH_DERIVATIVE_LEFT_OUT),
            _ => None,
        });
    }
    Ok(out)
}

/// `lucent render --uncertainty`: each of `recipe`'s uncertain inputs'
/// effect, from the nominal render's own paths where `path_derivatives`
/// gives its index in [`Image::derivatives`], else from renders at ±1 σ,
/// and their band ([`scene::band`]), written to uncertainty.json and
/// band.exr beside the nominal render `image`.
fn render_band(
    a: &RenderArgs,
    loaded: &scene::LoadedScene,
    settings: &Settings,
    pool: &rayon::ThreadPool,
    image: &Image,
    recipe: &crate::optics::recipe::Recipe,
    path_derivatives: &[Option<(usize, f64)>],
) -> Result<()> {
    let interrupt = Interrupt::install();
    let started = std::time::Instant::now();
    let (band, renders) = band_of(a, loaded, settings, pool, image, recipe, path_derivatives, interrupt.flag())
        .with_context(|| format!("the band was not written (the render itself is in {}/render.*)", a.out.display()))?;
    drop(interrupt);
    let wall_s = started.elapsed().as_secs_f64();
    write_band(&a.out, image, &band)?;
    for line in band.lines() {
        println!("{line}");
    }
    let names = scene::band::RenderBandFiles::NAMES.join(", ");
    println!("wrote {}/{names} ({renders} renders, {wall_s:.1} s)", a.out.display());
    Ok(())
}

/// uncertainty.json, band.exr (per pixel and band, the standard
/// deviation from the inputs and its Monte Carlo error) and band.png (the
/// relative band over the object's pixels, to look at) in `out`.
pub fn write_band(out: &Path, image: &Image, band: &scene::band::RenderBand) -> Result<()> {
    let files = scene::band::RenderBandFiles::in_dir(out);
    crate::io::write_json(&files.json, band)
        .with_context(|| format!("{}: cannot write {}", out.display(), scene::band::RenderBandFiles::NAMES[0]))?;
    let channel = |v: &[[f64; 3]], c: usize| -> Vec<f32> { v.iter().map(|t| t[c] as f32).collect() };
    let (sd, se) = (&band.pixel_sd, &band.pixel_sd_std_error);
    let (r, g, b) = (channel(sd, 0), channel(sd, 1), channel(sd, 2));
    let (er, eg, eb) = (channel(se, 0), channel(se, 1), channel(se, 2));
    crate::exr::write_channels(
        &files.exr,
        image.width,
        image.height,
        &[
            ("inputs_sd.R", &r),
            ("inputs_sd.G", &g),
            ("inputs_sd.B", &b),
            ("inputs_sd_std_error.R", &er),
            ("inputs_sd_std_error.G", &eg),
            ("inputs_sd_std_error.B", &eb),
        ],
    )?;
    // band.png: the relative band over the object, to look at.
    let relative: Vec<f64> = (0..image.width * image.height)
        .map(|p| {
            let m = image.mean[p];
            let lum: f64 = m.iter().sum();
            if image.region(p) != tracer::Region::Object || lum <= 0.0 {
                return f64::NAN;
            }
            // The bands' sds added as a sum's (fully correlated: one input moves all bands alike).
            sd[p].iter().sum::<f64>() / lum
        })
        .collect();
    // Cropped to the object's pixels and a margin of a tenth of their extent.
    let (w, h) = (image.width, image.height);
    let on: Vec<usize> = (0..w * h).filter(|&p| relative[p].is_finite()).collect();
    let (x0, x1, y0, y1) = on.iter().fold((w, 0, h, 0), |(a, b, c, d), &p| {
        let (x, y) = (p % w, p / w);
        (a.min(x), b.max(x), c.min(y), d.max(y))
    });
    let (x0, x1, y0, y1) = if on.is_empty() {
        (0, w - 1, 0, h - 1)
    } else {
        let (mx, my) = ((x1 - x0) / 10 + 1, (y1 - y0) / 10 + 1);
        (x0.saturating_sub(mx), (x1 + mx).min(w - 1), y0.saturating_sub(my), (y1 + my).min(h - 1))
    };
    // A pixel's band is resolved where it is at least twice its own Monte Carlo error in every band.
    let resolved = |p: usize| (0..3).all(|c| sd[p][c] >= 2.0 * se[p][c]);
    let pixels = || (y0..=y1).flat_map(|y| (x0..=x1).map(move |x| y * w + x));
    let crop: Vec<f64> = pixels().map(|p| relative[p]).collect();
    let crop_resolved: Vec<bool> = pixels().map(resolved).collect();
    let shown = on.iter().filter(|&&p| resolved(p)).count();
    let png = crate::plot::relative_band_png(
        x1 - x0 + 1,
        y1 - y0 + 1,
        &crop,
        &crop_resolved,
        &format!(
            "the twin's band per pixel (R + G + B) from the recipe's inputs;\nlight grey: under 2× its own Monte \
             Carlo error ({:.0} % of {} object px):\nmore samples resolve it; uncertainty.json has the region means",
            100.0 * (on.len() - shown) as f64 / on.len().max(1) as f64,
            on.len()
        ),
    )?;
    crate::io::write_atomic(&files.png, &png)
        .with_context(|| format!("{}: cannot write {}", out.display(), scene::band::RenderBandFiles::NAMES[2]))?;
    Ok(())
}

/// The band of the nominal render `image` ([`scene::band::render_band`]):
/// each of `recipe`'s uncertain inputs' effect from the nominal render's own
/// paths where `path_derivatives` ([`uncertain_inputs`]) gives its index in
/// [`Image::derivatives`], else from renders at ±1 σ with the nominal's
/// seed (`--uncertainty-spp` samples, default half the nominal's median on
/// the object), which `cancel` stops (an error) as does the time budget.
/// Also the number of those renders.
#[allow(clippy::too_many_arguments)]
pub fn band_of(
    a: &RenderArgs,
    loaded: &scene::LoadedScene,
    settings: &Settings,
    pool: &rayon::ThreadPool,
    image: &Image,
    recipe: &crate::optics::recipe::Recipe,
    path_derivatives: &[Option<(usize, f64)>],
    cancel: &std::sync::atomic::AtomicBool,
) -> Result<(scene::band::RenderBand, usize)> {
    use crate::optics::uncertainty::InputSd;
    use scene::band::EffectEstimate;
    // The renders at ±1 σ carry no derivatives.
    let settings = &Settings { derivatives: Vec::new(), ..settings.clone() };
    let spp = match a.uncertainty_spp {
        Some(n) => n,
        None => {
            // Half the nominal's median over the object's pixels (all pixels without an object), even, ≥ 2.
            let mut counts: Vec<u32> = (0..image.samples.len())
                .filter(|&p| image.region(p) == tracer::Region::Object)
                .map(|p| image.samples[p])
                .collect();
            if counts.is_empty() {
                counts = image.samples.clone();
            }
            counts.sort_unstable();
            let median = counts.get(counts.len() / 2).copied().unwrap_or(2);
            ((median / 2).max(2) + 1) & !1
        }
    };
    let inputs = InputSd::of(recipe);
    let rendered = path_derivatives.iter().filter(|d| d.is_none()).count();
    let renders = 2 * rendered;
    if !a.quiet {
        for (input, d) in inputs.iter().zip(path_derivatives) {
            if let Some((_, left_out)) = d {
                eprintln!(
                    "uncertainty: {} changes μs and μa (its phase functions and index by ≤ {left_out:.1e}, left out): its effect from the render's own paths (path derivative)",
                    input.key
                );
            }
        }
        if renders > 0 {
            eprintln!(
                "uncertainty: {renders} renders of {spp} spp (each other input of {} at ±1 σ, with the same seed)",
                recipe.path.display()
            );
        }
    }
    let walked = walked_similarity(loaded);
    // --time-s (or [render] time_s) bounds the ±1 σ renders too, together:
    // past it, or when `cancel` is set, a watcher stops them.
    use std::sync::atomic::{AtomicBool, Ordering};
    let deadline = settings.stop.time_s.map(|t| std::time::Instant::now() + std::time::Duration::from_secs_f64(t));
    let (stop, finished, timed_out) = (AtomicBool::new(false), AtomicBool::new(false), AtomicBool::new(false));
    let pairs = std::thread::scope(|scope| {
        scope.spawn(|| {
            while !finished.load(Ordering::Relaxed) {
                if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
                    timed_out.store(true, Ordering::Relaxed);
                    stop.store(true, Ordering::Relaxed);
                }
                if cancel.load(Ordering::Relaxed) {
                    stop.store(true, Ordering::Relaxed);
                }
                std::thread::sleep(std::time::Duration::from_millis(20));
            }
        });
        let rendered = (|| -> Result<Vec<(Image, Image)>> {
            let mut pairs = Vec::new();
            let each = recipe.uncertain.iter().zip(&inputs).zip(path_derivatives).filter(|(_, d)| d.is_none());
            for ((input, sd), _) in each {
                let mut pair = Vec::new();
                for (sign, value) in [("+", input.nominal + sd.sd), ("−", input.nominal - sd.sd)] {
                    let (loaded, _) = prepare_as(a, false, Some((input.target, value)), walked)
                        .with_context(|| format!("--uncertainty: {} = {value} (nominal {sign} 1 σ)", input.key))?;
                    let (acc, stats) =
                        pool.install(|| tracer::render_samples(&loaded.scene, settings, 0..spp, Some(&stop)));
                    if timed_out.load(Ordering::Relaxed) {
                        bail!(
                            "--uncertainty: the renders at ±1 σ did not finish within the time budget ({} s); give a smaller --uncertainty-spp or more time",
                            settings.stop.time_s.unwrap_or(0.0),
                        );
                    }
                    if stop.load(Ordering::Relaxed) {
                        return Err(Interrupted("the renders at ±1 σ were stopped".into()).into());
                    }
                    if !a.quiet {
                        eprintln!("  {} {sign} 1 σ = {value:.6}: {spp} spp in {:.1} s", input.key, stats.wall_s);
                    }
                    pair.push(acc.image());
                }
                let minus = pair.pop().context("two renders per input")?;
                let plus = pair.pop().context("two renders per input")?;
                pairs.push((plus, minus));
            }
            Ok(pairs)
        })();
        finished.store(true, Ordering::Relaxed);
        rendered
    })?;
    let mut rendered = pairs.iter();
    let mut effects = Vec::new();
    for d in path_derivatives {
        effects.push(match d {
            Some((index, left_out)) => EffectEstimate::PathDerivative { index: *index, left_out: *left_out },
            None => {
                let (plus, minus) = rendered.next().context("one pair of renders per rendered input")?;
                EffectEstimate::Renders { plus, minus, spp }
            }
        });
    }
    Ok((scene::band::render_band(image, &inputs, &effects), renders))
}

/// "object 4.1 % (6.0 %, 9.2 %) over 51234 px, board …, all …": per region
/// the median, 90th and 99th percentile of the per-pixel relative standard error.
pub fn describe_errors(e: &tracer::RegionErrors) -> String {
    let one = |name: &str, q: &tracer::Quantiles| {
        if q.pixels == 0 {
            format!("{name}: no pixels")
        } else {
            format!(
                "{name} {:.1} % ({:.1} %, {:.1} %) over {} px",
                100.0 * q.median,
                100.0 * q.p90,
                100.0 * q.p99,
                q.pixels
            )
        }
    };
    format!("{}; {}; {}", one("object", &e.object), one("board", &e.board), one("all", &e.all))
}

/// The region figures as written into render.json.
pub fn errors_report(e: &tracer::RegionErrors) -> scene::RegionErrorsReport {
    let q = |q: &tracer::Quantiles| scene::QuantilesReport {
        pixels: q.pixels,
        median: q.median,
        p90: q.p90,
        p99: Some(q.p99),
    };
    scene::RegionErrorsReport {
        definition:
            "relative standard error of the pixel's mean, RMS over R, G, B, over the pixels that are not black \
                     (a pixel with a channel still without light counts as infinite); object: pixels where at least \
                     half the camera rays hit the object first; board: likewise the board; null: no pixels, or a \
                     quantile that is infinite"
                .into(),
        object: q(&e.object),
        board: q(&e.board),
        all: q(&e.all),
    }
}

/// Mean samples per pixel over the object's pixels and over the others.
pub fn spp_by_region(image: &Image) -> scene::SppByRegion {
    let (mut s, mut n) = ([0.0f64; 2], [0usize; 2]);
    for p in 0..image.samples.len() {
        let k = usize::from(image.region(p) != tracer::Region::Object);
        s[k] += f64::from(image.samples[p]);
        n[k] += 1;
    }
    let mean = |k: usize| if n[k] > 0 { s[k] / n[k] as f64 } else { 0.0 };
    scene::SppByRegion { object: mean(0), other: mean(1) }
}

/// Writes render.exr and render.png; returns their names.
pub fn write_outputs(out: &Path, image: &Image, exposure_stops: f64) -> Result<Vec<String>> {
    let (w, h) = (image.width, image.height);
    let plane = |f: &dyn Fn(usize) -> f64| (0..w * h).map(|i| f(i) as f32).collect::<Vec<f32>>();
    let (r, g, b) = (plane(&|i| image.mean[i][0]), plane(&|i| image.mean[i][1]), plane(&|i| image.mean[i][2]));
    let (vr, vg, vb) = (
        plane(&|i| image.variance_of_mean[i][0]),
        plane(&|i| image.variance_of_mean[i][1]),
        plane(&|i| image.variance_of_mean[i][2]),
    );
    let spp = plane(&|i| f64::from(image.samples[i]));
    let object = plane(&|i| image.object_fraction(i));
    let board = plane(&|i| f64::from(image.board_samples[i]) / f64::from(image.samples[i].max(1)));
    let half = |k: usize, c: usize| plane(&|i| image.halves[k][i][c]);
    let (ar, ag, ab, br, bg, bb) = (half(0, 0), half(0, 1), half(0, 2), half(1, 0), half(1, 1), half(1, 2));
    let files = scene::RenderFiles::in_dir(out);
    crate::exr::write_channels(
        &files.exr,
        w,
        h,
        &[
            ("R", &r),
            ("G", &g),
            ("B", &b),
            ("variance.R", &vr),
            ("variance.G", &vg),
            ("variance.B", &vb),
            ("spp", &spp),
            ("object", &object),
            ("board", &board),
            ("half_a.R", &ar),
            ("half_a.G", &ag),
            ("half_a.B", &ab),
            ("half_b.R", &br),
            ("half_b.G", &bg),
            ("half_b.B", &bb),
        ],
    )
    .with_context(|| format!("{}: cannot write", files.exr.display()))?;
    let k = 2f64.powf(exposure_stops);
    let data: Vec<f32> = image.mean.iter().flat_map(|m| m.map(|v| (v * k) as f32)).collect();
    imageio::write_png(&files.png, &RgbImage::new(w, h, data)?)
        .with_context(|| format!("{}: cannot write", files.png.display()))?;
    Ok(scene::RenderFiles::NAMES.map(String::from).to_vec())
}

fn report(
    summary: &SceneSummary,
    settings: &Settings,
    image: &Image,
    stats: &Stats,
    threads: usize,
    exposure: f64,
    files: &[String],
) -> RenderReport {
    let n = image.mean.len().max(1) as f64;
    let mean_rgb = std::array::from_fn(|c| image.mean.iter().map(|m| m[c]).sum::<f64>() / n);
    let errors = image.region_errors();
    RenderReport {
        lucent_version: env!("CARGO_PKG_VERSION").into(),
        scene: summary.clone(),
        spp: image.samples.iter().copied().max().unwrap_or(0),
        spp_requested: settings.spp(),
        time_budget_s: settings.stop.time_s,
        seed: settings.seed,
        threads,
        roulette_threshold: settings.roulette_threshold,
        wall_s: stats.wall_s,
        samples: stats.samples,
        samples_per_s: stats.samples as f64 / stats.wall_s.max(1e-9),
        scattering_events: stats.events,
        surface_hits: stats.surface_hits,
        leaked_paths: stats.leaked_paths,
        truncated_paths: stats.truncated_paths,
        mean_rgb,
        // The all-pixels median of the one per-pixel figure the regions use
        // (once a grey mean of the channels that read √3 too low where the
        // bands ride on one path).
        median_relative_std_error: errors.all.median,
        relative_std_error: Some(errors_report(&errors)),
        sampling: Some(match settings.sampling {
            tracer::Sampling::Uniform => scene::SamplingKey::Uniform,
            tracer::Sampling::ObjectWeighted => scene::SamplingKey::ObjectWeighted,
        }),
        spp_by_region: Some(spp_by_region(image)),
        target_rel_error: settings.stop.pixel_rel_error,
        estimator: Some(settings.into()),
        exposure_stops_png: exposure,
        files: files.to_vec(),
        interrupted: false,
        approximations: scene::approximations(summary, settings),
    }
}

/// CPU seconds used by this process so far (user + system, all threads).
#[cfg(unix)]
fn process_cpu_s() -> f64 {
    // SAFETY: getrusage only writes into the struct we pass.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return f64::NAN;
    }
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    tv(u.ru_utime) + tv(u.ru_stime)
}

#[cfg(not(unix))]
fn process_cpu_s() -> f64 {
    f64::NAN
}

/// One row of `lucent bench render`.
#[derive(Debug, Serialize)]
pub struct BenchRow {
    pub spp: u32,
    pub wall_s: f64,
    pub cpu_s: f64,
    pub samples_per_cpu_s: f64,
    pub events_per_cpu_s: f64,
    /// RMSE against the Mitsuba reference mean over all pixels and channels.
    pub rmse_vs_reference: f64,
    /// The same with the reference's own noise removed: sqrt(RMSE² − mean reference variance).
    pub rmse_corrected: f64,
    /// RMSE over the plaque's pixels (`object_pixels` of mitsuba_bench_<scene>.json) and channels.
    pub rmse_object: Option<f64>,
    /// The same with the reference's own noise there removed.
    pub rmse_object_corrected: Option<f64>,
}

/// `lucent bench render`: a Mitsuba reference scene (plaque_dense: constant
/// sky; plaque_envmap: a sky map with a small sun) at increasing sample
/// counts on all cores; samples per CPU-second and RMSE against the
/// reference, and the CPU time lucent needs to reach the RMSE Mitsuba
/// reached in its own side-by-side runs (`fixtures/reference/render/mitsuba_bench_<scene>.json`,
/// from `tools/reference/bench_render_mitsuba.py`).
pub fn bench(scene_path: &Path, reference_dir: &Path, spps: &[u32]) -> Result<()> {
    let loaded = scene::load(scene_path)?;
    // The reference of the same name as the scene file: plaque_dense.toml
    // against plaque_dense_mean.exr, _var.exr and mitsuba_bench_plaque_dense.json.
    let name = scene_path.file_stem().and_then(|s| s.to_str()).unwrap_or_default();
    let mean_file = reference_dir.join(format!("{name}_mean.exr"));
    if !mean_file.is_file() {
        bail!(
            "{}: no Mitsuba reference for scene {} (the scenes with one: plaque_dense.toml, plaque_envmap.toml in fixtures/render)",
            mean_file.display(),
            scene_path.display()
        );
    }
    let (w, h, mean) = crate::exr::read_channels(&mean_file, &["R", "G", "B"])?;
    let (_, _, var) = crate::exr::read_channels(&reference_dir.join(format!("{name}_var.exr")), &["R", "G", "B"])?;
    if (w, h) != (loaded.scene.camera.width, loaded.scene.camera.height) {
        bail!(
            "{}: reference is {w}×{h}, the scene renders {}×{}",
            reference_dir.display(),
            loaded.scene.camera.width,
            loaded.scene.camera.height
        );
    }
    // Per region (a list of pixels): the mean over its pixels and channels of
    // the reference's variance, and of an image's squared error against it.
    let all: Vec<usize> = (0..w * h).collect();
    let (var, mean) = (&var, &mean);
    let ref_variance = |pixels: &[usize]| {
        pixels.iter().flat_map(|&p| var.iter().map(move |v| f64::from(v[p]))).sum::<f64>()
            / (3 * pixels.len().max(1)) as f64
    };
    let mean_sq_error = |img: &tracer::Image, pixels: &[usize]| {
        pixels.iter().flat_map(|&p| (0..3).map(move |c| (img.mean[p][c] - f64::from(mean[c][p])).powi(2))).sum::<f64>()
            / (3 * pixels.len()) as f64
    };
    let ref_var = ref_variance(&all);
    // Mitsuba's side-by-side figures, if present, and the plaque's pixels they name.
    let bench_file = reference_dir.join(format!("mitsuba_bench_{name}.json"));
    // Missing: no side-by-side figures; present but unreadable: an error.
    let mitsuba: Option<serde_json::Value> = if bench_file.exists() {
        let text = crate::io::read_text(&bench_file)?;
        Some(serde_json::from_str(&text).with_context(|| format!("{}: not valid JSON", bench_file.display()))?)
    } else {
        None
    };
    let object: Vec<usize> = match mitsuba.as_ref().and_then(|m| m.get("object_pixels")) {
        None => Vec::new(),
        Some(list) => {
            let ids: Option<Vec<usize>> = list
                .as_array()
                .map(|a| a.iter().map(|v| v.as_u64().and_then(|i| usize::try_from(i).ok())).collect())
                .unwrap_or(None);
            match ids {
                Some(ids) if ids.iter().all(|&i| i < w * h) => ids,
                _ => bail!("{}: object_pixels is not a list of pixel indices below {}", bench_file.display(), w * h),
            }
        }
    };
    let ref_var_object = ref_variance(&object);
    let mut rows = Vec::new();
    for &spp in spps {
        let stop = Stop { samples: Some(spp.into()), ..loaded.settings.stop };
        let settings = Settings { stop, seed: 77 + u64::from(spp), ..loaded.settings.clone() };
        let cpu0 = process_cpu_s();
        let (img, stats) = tracer::render(&loaded.scene, &settings, &mut |_| {})?;
        let cpu = process_cpu_s() - cpu0;
        let mse = mean_sq_error(&img, &all);
        let mse_object = (!object.is_empty()).then(|| mean_sq_error(&img, &object));
        let row = BenchRow {
            spp,
            wall_s: stats.wall_s,
            cpu_s: cpu,
            samples_per_cpu_s: stats.samples as f64 / cpu,
            events_per_cpu_s: stats.events as f64 / cpu,
            rmse_vs_reference: mse.sqrt(),
            rmse_corrected: (mse - ref_var).max(0.0).sqrt(),
            rmse_object: mse_object.map(f64::sqrt),
            rmse_object_corrected: mse_object.map(|m| (m - ref_var_object).max(0.0).sqrt()),
        };
        let on_object = row.rmse_object.map_or(String::new(), |r| format!("; on the plaque {r:.5}"));
        eprintln!(
            "lucent {:>5} spp: {:>7.2} s wall, {:>7.2} CPU-s, {:.3} M samples/CPU-s, {:.1} M events/CPU-s, RMSE {:.5} (corrected {:.5}){on_object}",
            row.spp, row.wall_s, row.cpu_s, row.samples_per_cpu_s / 1e6, row.events_per_cpu_s / 1e6, row.rmse_vs_reference, row.rmse_corrected
        );
        rows.push(row);
    }
    // Mitsuba's RMSE `m_rmse` over a region whose reference variance is `rv`,
    // corrected for the reference's noise, and the CPU time lucent (whose
    // corrected RMSE at `best` is `l_corr`) needs to reach it (RMSE² ∝ 1/time).
    let to_equal = |best: &BenchRow, m_rmse: f64, l_corr: f64, rv: f64| {
        let m_corr = (m_rmse * m_rmse - rv).max(1e-300).sqrt();
        (m_corr, best.cpu_s * (l_corr / m_corr).powi(2))
    };
    let mut ratios = Vec::new();
    if let (Some(m), Some(best)) = (&mitsuba, rows.last()) {
        for r in m.get("runs").and_then(|r| r.as_array()).into_iter().flatten() {
            let (Some(m_cpu), Some(m_rmse)) =
                (r.get("cpu_seconds").and_then(|v| v.as_f64()), r.get("rmse_vs_reference").and_then(|v| v.as_f64()))
            else {
                continue;
            };
            // Both errors include the reference's noise; compare the corrected ones.
            let (m_corr, lucent_cpu) = to_equal(best, m_rmse, best.rmse_corrected, ref_var);
            let ratio = m_cpu / lucent_cpu;
            eprintln!("Mitsuba {:>5} spp: {m_cpu:.1} CPU-s for RMSE {m_rmse:.5} (corrected {m_corr:.5}); lucent reaches it in {lucent_cpu:.2} CPU-s: {ratio:.1}× faster", r.get("spp").and_then(|v| v.as_u64()).unwrap_or(0));
            // The same on the plaque's pixels alone.
            let on_object = match (r.get("rmse_object").and_then(|v| v.as_f64()), best.rmse_object_corrected) {
                (Some(m_obj), Some(l_obj)) => {
                    let (m_corr, lucent_cpu) = to_equal(best, m_obj, l_obj, ref_var_object);
                    let ratio = m_cpu / lucent_cpu;
                    eprintln!("    on the plaque: RMSE {m_obj:.5} (corrected {m_corr:.5}); lucent reaches it in {lucent_cpu:.2} CPU-s: {ratio:.1}× faster");
                    serde_json::json!({"mitsuba_rmse_corrected": m_corr, "lucent_cpu_s_to_equal_rmse": lucent_cpu, "speed_ratio": ratio})
                }
                _ => serde_json::Value::Null,
            };
            ratios.push(serde_json::json!({"mitsuba": r, "mitsuba_rmse_corrected": m_corr, "lucent_cpu_s_to_equal_rmse": lucent_cpu, "speed_ratio": ratio, "on_the_plaque": on_object}));
        }
    } else {
        eprintln!(
            "no {}: run tools/reference/bench_render_mitsuba.py for the side-by-side figures",
            bench_file.display()
        );
    }
    println!(
        "{}",
        serde_json::to_string_pretty(
            &serde_json::json!({"scene": scene_path.display().to_string(), "threads": rayon::current_num_threads(), "reference_mean_variance": ref_var, "lucent": rows, "versus_mitsuba": ratios})
        )?
    );
    Ok(())
}

/// One estimator's row of `lucent bench render --time-s`.
#[derive(Debug, Serialize)]
pub struct EstimatorRow {
    pub estimator: &'static str,
    pub wall_s: f64,
    pub cpu_s: f64,
    pub spp_object: f64,
    pub spp_other: f64,
    pub events_per_s: f64,
    pub object_median: f64,
    pub object_p90: f64,
    /// 99th percentile over the object's pixels: its sparse bright outliers.
    pub object_p99: f64,
    pub board_median: f64,
    pub board_p90: f64,
    pub all_median: f64,
    /// 1 / (object median² × wall s).
    pub object_efficiency: f64,
    /// Wall seconds to an object median of 5 % at this efficiency.
    pub projected_s_to_5_percent: f64,
}

/// `lucent bench render --time-s T`: the previous estimator (one band at
/// random where a path keeps one band) for `time_s` of wall time on all cores, then today's default
/// and each selectable device on top of it at the samples per pixel the
/// first reached, on one scene, per region. Efficiency on the object is
/// 1/(median² × CPU seconds of this process): on a machine shared with
/// other work the CPU time is what the estimator cost, the wall time is
/// not. The projected time to 5 % is that CPU time spread over the
/// threads. (The median of per-pixel errors estimated from a dozen
/// heavy-tailed samples reads low, and lower with fewer samples — hence
/// equal counts; measured on the demo at 32 spp against 30 s runs, an
/// option that looked 1.4–1.7× better at unequal counts was 0.94×.)
pub fn bench_estimators(scene_path: &Path, time_s: f64) -> Result<()> {
    // The exact medium and dispersion whatever the file says; the
    // approximations are rows of their own.
    let exact = |f: &mut scene::SceneFile| {
        f.render.similarity_g = None;
        f.render.similarity_floor_events = None;
        if let Some(m) = f.material.as_mut() {
            m.dispersion = None;
        }
    };
    let exact_scene = scene::load_edited(scene_path, false, exact)?;
    // The bands' mean index (`[material] dispersion = false`), so that every
    // path carries R, G and B.
    let mean_index_scene = scene::load_edited(scene_path, false, |f| {
        exact(f);
        if let Some(m) = f.material.as_mut() {
            m.dispersion = Some(false);
        }
    })?;
    let mut rows = Vec::new();
    type Configure = fn(&mut Settings);
    let shared = |s: &mut Settings| s.dispersion = tracer::Dispersion::SharedDirections;
    let object_weighted = |s: &mut Settings| s.sampling = tracer::Sampling::ObjectWeighted;
    // (name, settings, mean index, similarity g_max and the events its
    // depth floor holds for, environment sampled by luminance alone rather
    // than weighted towards the board's normal)
    let chains = |s: &mut Settings| s.specular_chains = true;
    let jumps = |s: &mut Settings| {
        s.specular_chains = true;
        s.sphere_jumps = true;
    };
    type Similar = Option<(f64, Option<u64>)>;
    let similar = Some((0.0, None));
    let configurations: [(&'static str, Configure, bool, Similar, bool); 12] = [
        ("previous (phase connections through any mesh)", |s| s.phase_connection = true, false, None, false),
        ("default", |_| {}, false, None, false),
        ("default + splitting at entry", |s| s.split_entry = true, false, None, false),
        ("default + shared dispersion", shared, false, None, false),
        ("default + object-weighted", object_weighted, false, None, false),
        ("mean index", |_| {}, true, None, false),
        ("similar g′ ≤ 0.5, mean index", |_| {}, true, Some((0.5, None)), false),
        ("similar g′ ≤ 0, mean index", |_| {}, true, similar, false),
        ("similar g′ ≤ 0, mean index, + specular chains", chains, true, similar, false),
        ("similar g′ ≤ 0, mean index, + chains + sphere jumps", jumps, true, similar, false),
        (
            "similar g′ ≤ 0, mean index, + chains + jumps, luminance-only environment sampling",
            jumps,
            true,
            similar,
            true,
        ),
        (
            "similar g′ ≤ 0, mean index, + chains + jumps, depth floor for 16 events",
            jumps,
            true,
            Some((0.0, Some(16))),
            false,
        ),
    ];
    // The first estimator runs for `time_s`; the others render the samples
    // per pixel it reached, so that every median is read at the same count.
    let mut same_spp: Option<u32> = None;
    for (name, configure, mean_index, similarity_g, plain_env) in configurations {
        let mut loaded = if mean_index { mean_index_scene.clone() } else { exact_scene.clone() };
        if plain_env {
            loaded.scene.environment.set_sampling_normal(None);
        }
        let mut settings = match same_spp {
            None => Settings {
                stop: Stop { samples: Some((u32::MAX / 2).into()), time_s: Some(time_s), ..loaded.settings.stop },
                ..loaded.settings.clone()
            },
            Some(spp) => Settings {
                stop: Stop { samples: Some(spp.into()), time_s: None, ..loaded.settings.stop },
                ..loaded.settings.clone()
            },
        };
        configure(&mut settings);
        if let Some((g, floor_events)) = similarity_g {
            if loaded.scene.object.is_none() {
                continue;
            }
            scene::apply_similarity(&mut loaded, g, floor_events, None)?;
        }
        let cpu0 = process_cpu_s();
        let (img, stats) = tracer::render(&loaded.scene, &settings, &mut |_| {})?;
        let cpu = process_cpu_s() - cpu0;
        let e = img.region_errors();
        same_spp.get_or_insert_with(|| img.samples.iter().copied().max().unwrap_or(1).max(1));
        let by = spp_by_region(&img);
        // CPU seconds; where they cannot be read, wall time on all threads.
        let cost = if cpu.is_finite() && cpu > 0.0 { cpu } else { stats.wall_s * rayon::current_num_threads() as f64 };
        let eff = 1.0 / (e.object.median * e.object.median * cost);
        let row = EstimatorRow {
            estimator: name,
            wall_s: stats.wall_s,
            cpu_s: cpu,
            spp_object: by.object,
            spp_other: by.other,
            events_per_s: stats.events as f64 / stats.wall_s,
            object_median: e.object.median,
            object_p90: e.object.p90,
            object_p99: e.object.p99,
            board_median: e.board.median,
            board_p90: e.board.p90,
            all_median: e.all.median,
            object_efficiency: eff,
            projected_s_to_5_percent: 1.0 / (eff * 0.05 * 0.05) / rayon::current_num_threads() as f64,
        };
        eprintln!(
            "{name:>32}: {:.1} s wall, {:.1} CPU s, {:.1} spp on the object ({:.1} elsewhere), {:.1} M events/s; {}; time to 5 % on the object ≈ {:.0} s",
            row.wall_s,
            row.cpu_s,
            row.spp_object,
            row.spp_other,
            row.events_per_s / 1e6,
            describe_errors(&e),
            row.projected_s_to_5_percent
        );
        rows.push(row);
    }
    let base = rows[0].object_efficiency;
    for r in &rows[1..] {
        eprintln!(
            "{}: efficiency on the object {:.2}× the previous estimator's",
            r.estimator,
            r.object_efficiency / base
        );
    }
    let gains: Vec<f64> = rows.iter().map(|r| r.object_efficiency / base).collect();
    println!(
        "{}",
        serde_json::to_string_pretty(&serde_json::json!({
            "scene": scene_path.display().to_string(),
            "threads": rayon::current_num_threads(),
            "time_s_each": time_s,
            "figure": "relative standard error of the pixel's mean (RMS over R, G, B), median and 90th percentile per region",
            "estimators": rows,
            "object_efficiency_relative_to_previous": gains,
        }))?
    );
    Ok(())
}
