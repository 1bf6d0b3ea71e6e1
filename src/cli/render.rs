//! `lucent render SCENE.toml`: the digital twin rendered from the calibrated
//! camera (docs/method.md#render). Argument handling, the progress bar and
//! printing only: the flags become a [`RenderJob`], which renders and
//! writes render.exr, render.png and render.json
//! ([`crate::job::render`] says what each holds); `lucent merge` of a
//! render's shards runs the same job with their sums ([`RenderJob::merge`]).

use super::common::duration;
use crate::fault::Interrupted;
use crate::job::render::{describe_errors, spp_by_region, time_to_target_s};
use crate::job::{Context, RenderHooks, RenderJob, RenderRun};
use crate::scene;
use anyhow::{bail, Context as _, Result};
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lucent_render::tracer::{self, Settings, Stop};
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
    pub shard: Option<crate::job::shard::ShardSpec>,
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

/// `--dispersion`.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum DispersionArg {
    PerBand,
    SharedDirections,
}

impl From<DispersionArg> for crate::job::render::DispersionKey {
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

impl From<SamplingArg> for scene::SamplingKey {
    fn from(a: SamplingArg) -> Self {
        match a {
            SamplingArg::Uniform => Self::Uniform,
            SamplingArg::ObjectWeighted => Self::ObjectWeighted,
        }
    }
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

/// The terminal's view of a render ([`RenderHooks`]): the progress bar
/// and its "expect ≈ …" line (neither when `quiet`).
pub struct Terminal {
    quiet: bool,
    shown: Option<(ProgressBar, Settings, bool)>,
}

impl Terminal {
    pub fn new(quiet: bool) -> Self {
        Terminal { quiet, shown: None }
    }
}

impl RenderHooks for Terminal {
    fn start(&mut self, settings: &Settings) {
        self.shown = Some((progress_bar(self.quiet, settings), settings.clone(), false));
    }

    fn pass(&mut self, p: &tracer::Progress) {
        if let Some((bar, settings, estimated)) = &mut self.shown {
            show_progress(bar, settings, self.quiet, estimated, p);
        }
    }

    fn finish(&mut self) {
        if let Some((bar, _, _)) = self.shown.take() {
            bar.finish_and_clear();
        }
    }
}

/// Runs `lucent render`.
pub fn run(a: RenderArgs) -> Result<()> {
    let job = RenderJob::from(&a);
    finish(job.run_with(&Context::default(), &mut Terminal::new(job.quiet))?)
}

/// Prints a render's summary; fails as interrupted when Ctrl-C or SIGTERM
/// stopped it (its files then hold what was finished).
pub fn finish(done: RenderRun) -> Result<()> {
    for line in done.summary() {
        println!("{line}");
    }
    match done.interrupted {
        Some(Interrupted(what)) => Err(Interrupted(what).into()),
        None => Ok(()),
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
