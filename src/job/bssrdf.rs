//! The slab stages: [`BssrdfJob::run`] simulates a slab's BSSRDF slices
//! (docs/method.md#slab) per configuration — bssrdf.exr, profile.csv,
//! summary.json … ([`SliceFiles`](crate::bssrdf::SliceFiles)), with
//! `uncertainty` the band of the recipe's uncertain inputs
//! ([`SliceBandFiles`](crate::bssrdf::SliceBandFiles)), with `shard` one
//! shard's tallies (`slice-I.acc`, shard.json), and [`BssrdfJob::merge`]
//! the outputs of a run from its shards; [`BssrdfCompareJob::run`] scores a
//! simulated slice against a measured one
//! ([`ComparisonFiles`](crate::bssrdf::ComparisonFiles)). `lucent bssrdf`
//! and the pipeline's slab stages run them; the command parses its flags
//! into the job, draws the progress bar ([`SliceHooks`]) and prints the
//! run's summary.

mod error;
mod outcome;
mod plan;
mod section;
mod shard;

pub use error::BssrdfJobError;
pub use outcome::BssrdfRun;
pub use plan::{beam, MediumChoice, Perturbation, Plan, PlannedRun};
pub use section::{BssrdfConfigFiles, BssrdfSection};

use super::context::Context;
use super::spec::{BssrdfCompareJob, BssrdfJob};
use crate::bssrdf::{self, RunConfig, Summary};
use crate::interrupt::Interrupt;
use lucent_render::slab::{self, RunOptions, Stop};
use lucent_render::stop::{Condition, Standing};
use std::path::{Path, PathBuf};

type E = BssrdfJobError;

/// What a slab job tells its caller while it runs, besides `ctx`'s lines:
/// each configuration's progress (`lucent bssrdf` draws a bar). Every
/// method has a default: no progress shown, lines to `ctx`.
pub trait SliceHooks {
    /// A configuration's simulation starts: its label ("θi 45° → θo 0°")
    /// and the stop rule it runs under.
    fn start(&mut self, _label: &str, _stop: &Stop) {}
    /// After each round of the configuration's simulation.
    fn progress(&mut self, _stop: &Stop, _p: &slab::Progress) {}
    /// A line about the run while a configuration is simulated (the time it
    /// expects).
    fn say(&mut self, ctx: &Context, line: &str) {
        ctx.say(line);
    }
    /// The configuration's simulation ended.
    fn finish(&mut self) {}
}

/// [`SliceHooks`] at their defaults.
pub struct NoHooks;

impl SliceHooks for NoHooks {}

impl BssrdfJob {
    /// Simulates the job's slices into `out` (staged: moved into `out` when
    /// every configuration is done), or with `shard` one shard's tallies.
    /// Ctrl-C stops after the round under way and keeps the slice so far
    /// ([`BssrdfRun::finished`] says so). Progress goes to `hooks`, lines
    /// and warnings to `ctx`.
    pub fn run(&self, ctx: &Context, hooks: &mut dyn SliceHooks) -> Result<BssrdfRun, E> {
        self.simulate(ctx, hooks, None)
    }

    /// Writes the outputs of the run whose shards these are (`lucent
    /// merge`): the shards' tallies added in shard order, what the
    /// unsharded run writes.
    pub fn merge(&self, ctx: &Context, shards: &[crate::job::shard::format::Shard]) -> Result<BssrdfRun, E> {
        self.simulate(ctx, &mut NoHooks, Some(shards))
    }

    fn simulate(
        &self,
        ctx: &Context,
        hooks: &mut dyn SliceHooks,
        merged_from: Option<&[crate::job::shard::format::Shard]>,
    ) -> Result<BssrdfRun, E> {
        let plan = self.plan(ctx)?;
        let shard = self.shard.map(crate::job::shard::format::ShardSpec::pair);
        let batch_paths = RunOptions::default().batch_paths;
        let total_batches = self.stop().samples.unwrap_or(0).div_ceil(batch_paths);
        self.check_stop_for_split(shard, merged_from.is_some(), total_batches)?;
        // A merge reads and checks every shard before it writes anything.
        let merged_tallies = match merged_from {
            Some(shards) => Some(shard::read_merged_tallies(shards, plan.runs.len(), plan.out_pixels, total_batches)?),
            None => None,
        };
        if let Some((k, n)) = shard {
            return self.run_shard(&plan.runs, (k, n), total_batches);
        }
        // Written into a staging folder, moved into `out` when every configuration is done.
        // A second Ctrl-C ends the process at once: the staging folder goes with
        // it (registered before it exists), and so does `out` if this run
        // created it (it is still empty then).
        let _remove_on_abort = crate::interrupt::remove_staged_on_abort(&self.out);
        let stage = crate::io::StagedDir::new(&self.out)?;
        let mut table = String::from(
            "folder,theta_i_deg,phi_i_deg,theta_o_deg,phi_o_deg,sum_per_m2_sr,sum_std_error,paths,wall_s\n",
        );
        let interrupt = Interrupt::install();
        let mut done = BssrdfRun { lines: Vec::new(), interrupted_at: None };
        if !self.quiet {
            ctx.say(&format!(
                "simulating {} configuration(s); Ctrl-C stops after the round under way and keeps the slice so far",
                plan.runs.len()
            ));
        }
        for (i, run) in plan.runs.iter().enumerate() {
            let (ti, _, to, _) = run.angles;
            let sub = bssrdf::SliceFiles::run_subdir(plan.runs.len(), ti, to);
            let (dir, shown) = (stage.path().join(&sub), self.out.join(&sub));
            let tallies = merged_tallies.as_ref().map(|t| t.iter().map(|shard| &shard[i]).collect::<Vec<_>>());
            let (slice, band) = self.slice(ctx, hooks, &plan, i, tallies.as_deref(), &interrupt)?;
            let interrupted = interrupt.requested();
            self.write_configuration(ctx, &plan, run, &dir, &shown, &slice, band.as_deref(), interrupted, &mut done)?;
            let (_, pi, _, po) = run.angles;
            table.push_str(&format!(
                "{},{ti},{pi},{to},{po},{:.8e},{:.3e},{},{:.3}\n",
                shown.display(),
                slice.sum,
                slice.sum_std_error,
                slice.paths,
                slice.wall_s
            ));
            if interrupted {
                done.interrupted_at = Some(shown);
                break;
            }
        }
        drop(interrupt);
        if plan.runs.len() > 1 {
            let sweep = bssrdf::SliceFiles::SWEEP_CSV;
            crate::io::write_atomic(&stage.path().join(sweep), table.as_bytes())?;
            done.lines.push(format!("combined table: {}", self.out.join(sweep).display()));
        }
        let owned: Vec<&str> = bssrdf::SliceFiles::NAMES
            .into_iter()
            .chain([bssrdf::SliceFiles::SWEEP_CSV])
            .chain(bssrdf::SliceBandFiles::NAMES)
            .collect();
        stage.commit(|n| owned.contains(&n) || bssrdf::SliceFiles::is_run_subdir(n))?;
        Ok(done)
    }

    /// Configuration `i`'s slice: the shards' `tallies` of it added (a
    /// merge), else simulated (with `uncertainty`, coupled with its runs at
    /// ±1 σ: their differences returned too).
    #[allow(clippy::type_complexity)]
    fn slice(
        &self,
        ctx: &Context,
        hooks: &mut dyn SliceHooks,
        plan: &Plan,
        i: usize,
        tallies: Option<&[&crate::job::shard::format::Arrays]>,
        interrupt: &Interrupt,
    ) -> Result<(slab::Slice, Option<Vec<slab::SliceDifference>>), E> {
        let run = &plan.runs[i];
        let (setup, options, stop) = (&run.setup, &run.options, &plan.stop);
        if let Some(tallies) = tallies {
            // The shards' tallies added in shard order to an empty run's (its constants).
            let mut sums = slab::simulate_batches(setup, options, 0..0, self.paths.unwrap_or(0), interrupt.flag())?;
            for arrays in tallies {
                let t = shard::slice_sums_of(&sums, arrays);
                sums.add(&t);
            }
            return Ok((sums.slice(), None));
        }
        let (ti, _, to, _) = run.angles;
        let label = format!("θi {ti}° → θo {to}°");
        let configs = plan.runs.len();
        hooks.start(&label, stop);
        let mut estimated = false;
        let result = {
            let mut on_progress = |p: &slab::Progress| {
                hooks.progress(stop, p);
                // Once the first round tells, the time this configuration expects.
                if !estimated {
                    estimated = true;
                    if let Some(line) = expectation(stop, p)
                        && !self.quiet
                    {
                        let all = if i == 0 && configs > 1 {
                            format!(
                                "; ≈ {} for all {configs} configurations",
                                crate::text::duration(line.0 * configs as f64)
                            )
                        } else {
                            String::new()
                        };
                        // Said whether or not a bar is drawn (a log file gets it too).
                        hooks.say(ctx, &format!("{label}: {}{all}", line.1));
                    }
                }
            };
            if self.uncertainty {
                slab::simulate_coupled(setup, &run.pairs, options, &mut on_progress, interrupt.flag())
                    .map(|(slice, differences)| (slice, Some(differences)))
            } else {
                slab::simulate_cancellable(setup, options, &mut on_progress, interrupt.flag()).map(|s| (s, None))
            }
        };
        hooks.finish();
        Ok(result?)
    }

    /// Writes a configuration's `slice` (of `run`) into `dir` (`shown` to
    /// the user), with its band when there is one; its lines into `done`.
    #[allow(clippy::too_many_arguments)]
    fn write_configuration(
        &self,
        ctx: &Context,
        plan: &Plan,
        run: &PlannedRun,
        dir: &Path,
        shown: &Path,
        slice: &slab::Slice,
        band: Option<&[slab::SliceDifference]>,
        interrupted: bool,
        done: &mut BssrdfRun,
    ) -> Result<(), E> {
        let (ti, pi, to, po) = run.angles;
        if let Some(target) = plan.stop.rel_error {
            let reached = slice.sum_std_error / slice.sum;
            if reached > target {
                ctx.warn(&format!(
                    "θi {ti}° → θo {to}°: stopped at {:.2} % relative error, before the target {:.2} % (time or path budget)",
                    100.0 * reached,
                    100.0 * target
                ));
            }
        }
        let summary = self.slice_summary(plan, run, slice, interrupted);
        let beam_row = plan.beam_profile(run, self.pixel_mm);
        bssrdf::write_run(dir, slice, &summary, &beam_row)?;
        if let Some(differences) = band {
            done.lines
                .push(format!("θi {ti}° → θo {to}°: {}", write_slice_band(plan, dir, slice, differences, &beam_row)?));
        }
        done.lines.push(format!(
            "θi {ti}° φi {pi}° → θo {to}° φo {po}°: sum = {:.5e} ± {:.2e} 1/(m² sr) ({:.2} %), per pixel {:.1} % median, {:.1} % p90, {} paths, {:.1} M events/s, {:.1} s → {}",
            slice.sum,
            slice.sum_std_error,
            100.0 * summary.relative_std_error,
            100.0 * summary.pixel_rel_error_median,
            100.0 * summary.pixel_rel_error_p90,
            slice.paths,
            summary.events_per_s / 1e6,
            slice.wall_s,
            shown.display()
        ));
        Ok(())
    }

    /// Checks the stop rules against the run's mode: `uncertainty` (not
    /// sharded, a path count or time budget), a `shard` (k, n) or a merge
    /// (`merged`: a path budget alone, at most `total_batches` shards).
    fn check_stop_for_split(&self, shard: Option<(u32, u32)>, merged: bool, total_batches: u64) -> Result<(), E> {
        let stop = self.stop();
        let refuse = |m: &str| Err(E::Refused(m.to_string()));
        if self.uncertainty {
            if shard.is_some() || merged {
                return refuse(
                    "--uncertainty: the coupled runs of the uncertain inputs are not sharded; run without --shard",
                );
            }
            if !stop.has(Condition::Samples) && !stop.has(Condition::Time) {
                return refuse("--uncertainty: give --paths or --time-s (the runs at ±1 σ stop with the nominal one, on a path count or a time budget)");
            }
            if stop.has_error_target() {
                return refuse(
                    "--uncertainty: --rel-error and --pixel-rel-error do not apply; give --paths or --time-s",
                );
            }
        }
        if shard.is_some() || merged {
            if stop.shard_samples().is_err() {
                return refuse("--shard: needs a path budget (--paths) and no other stop rule (--time-s, --rel-error and --pixel-rel-error depend on the whole run and cannot be split exactly)");
            }
            if let Some((k, n)) = shard
                && u64::from(n) > total_batches
            {
                return Err(crate::job::shard::format::ShardError::TooManyShards {
                    k,
                    n,
                    units: total_batches,
                    what: "batches of paths",
                }
                .into());
            }
        }
        Ok(())
    }

    /// summary.json of one configuration's `slice` (of `run` in `plan`).
    fn slice_summary(&self, plan: &Plan, run: &PlannedRun, slice: &slab::Slice, interrupted: bool) -> Summary {
        let m = &plan.medium;
        let (ti, pi, to, po) = run.angles;
        let pixel_errors = slice.pixel_errors();
        Summary {
            config: RunConfig {
                recipe: self.recipe.as_ref().map(|p| p.display().to_string()),
                wavelength_nm: self.recipe.as_ref().map(|_| self.wavelength_nm),
                theta_i_deg: ti,
                phi_i_deg: pi,
                theta_o_deg: to,
                phi_o_deg: po,
                phase: m.phase_name.clone(),
                beam: plan.beam_name.clone(),
                pixels: plan.out_pixels,
                pixel_mm: self.pixel_mm,
                crop_of: self.crop.map(|_| self.pixels),
                seed: self.seed,
                thickness_mm: m.thickness_m * 1e3,
                roughness: plan.roughness.clone(),
            },
            optical_properties: m.used,
            sum: slice.sum,
            sum_std_error: slice.sum_std_error,
            relative_std_error: slice.sum_std_error / slice.sum,
            pixel_rel_error_median: pixel_errors.median,
            pixel_rel_error_p90: pixel_errors.p90,
            pixel_mask_pixels: pixel_errors.pixels,
            paths: slice.paths,
            events: slice.events,
            events_per_s: slice.events_per_s(),
            kernel: slice.kernel.into(),
            estimator: slice.estimator.name().into(),
            folded: slice.folded,
            reciprocal: slice.reciprocal,
            wall_s: slice.wall_s,
            specular_reflectance: slice.specular_reflectance,
            diffuse_reflectance: slice.diffuse_reflectance,
            transmittance: slice.transmittance,
            pixel_mm: self.pixel_mm,
            interrupted,
        }
    }
}

/// The band of a configuration's `slice` from its runs at ±1 σ of the
/// plan's uncertain inputs (`differences`), written into `dir`; its sentence.
fn write_slice_band(
    plan: &Plan,
    dir: &Path,
    slice: &slab::Slice,
    differences: &[slab::SliceDifference],
    beam_row: &[f64],
) -> Result<String, E> {
    let inputs: Vec<crate::optics::uncertainty::InputSd> = plan
        .perturbations
        .iter()
        .map(|p| crate::optics::uncertainty::InputSd { key: p.key.clone(), nominal: p.nominal, sd: p.sd })
        .collect();
    let u = bssrdf::SliceBand::new(slice, &inputs, differences);
    bssrdf::write_band(dir, slice, &u, beam_row)?;
    Ok(u.sentence())
}

/// After a configuration's first round: roughly how long it takes in all
/// (seconds) and the line that says so. The first stop rule expected to end
/// it decides: a path budget at the rate so far, an error target by
/// error² ∝ 1/time, a time budget as given. `None` when the round already
/// ended it (or nothing can tell).
pub fn expectation(stop: &Stop, p: &slab::Progress) -> Option<(f64, String)> {
    use crate::text::duration;
    let elapsed = p.elapsed_s;
    if p.paths == 0 || elapsed.is_nan() || elapsed <= 0.0 {
        return None;
    }
    let standing = Standing { samples: Some(p.paths), elapsed_s: elapsed, ..Standing::default() };
    if stop.met(&standing).is_some() {
        return None;
    }
    let target = |name: &str, now: f64, e: f64| -> Option<(f64, String)> {
        (now.is_finite() && now > e).then(|| {
            (
                elapsed * (now / e).powi(2),
                format!(
                    "to {:.2} % {name} ({:.2} % after {} paths in {:.2} s)",
                    100.0 * e,
                    100.0 * now,
                    p.paths,
                    elapsed
                ),
            )
        })
    };
    let mut rules: Vec<(f64, String)> = Vec::new();
    if let Some(n) = stop.samples {
        rules.push((
            elapsed * n as f64 / p.paths as f64,
            format!("for {n} paths ({} done in {:.2} s)", p.paths, elapsed),
        ));
    }
    // A target reached already ends the run within a round or two.
    if let Some(e) = stop.rel_error {
        if p.rel_error <= e {
            return None;
        }
        rules.extend(target("on the slice sum", p.rel_error, e));
    }
    if let Some(e) = stop.pixel_rel_error {
        if p.pixels.median <= e {
            return None;
        }
        rules.extend(target("per pixel (median)", p.pixels.median, e));
    }
    let first = rules.iter().min_by(|a, b| a.0.total_cmp(&b.0)).cloned();
    let line = |t: f64, what: &str| format!("expect ≈ {} {what}", duration(t));
    match (first, stop.time_s) {
        (Some((t, what)), Some(budget)) if t > budget => Some((
            budget,
            format!("expect ≈ {} (the time budget; {} would take ≈ {})", duration(budget), what, duration(t)),
        )),
        (Some((t, what)), _) => Some((t, line(t, &what))),
        (None, Some(budget)) => Some((budget, format!("expect ≈ {} (the time budget)", duration(budget)))),
        (None, None) => None,
    }
}

/// The slice file of `simulated`: a run folder's bssrdf.exr, or the file itself.
fn simulated_path(p: &Path) -> PathBuf {
    if p.is_dir() {
        bssrdf::SliceFiles::in_dir(p).exr
    } else {
        p.to_path_buf()
    }
}

/// What a slice comparison found, and where it wrote it.
pub struct BssrdfCompareRun {
    pub comparison: bssrdf::Comparison,
    pub out: PathBuf,
}

impl BssrdfCompareJob {
    /// Compares the simulated slice with the measured one (the measured
    /// slice checked to be of the simulation's wavelength and configuration,
    /// and not negative) and writes comparison.json, the profiles and the
    /// panel into `out` (staged: all three or none).
    pub fn run(&self, _ctx: &Context) -> Result<BssrdfCompareRun, E> {
        let measured = bssrdf::read_grid(&self.measured, self.measured_pixel_mm)?;
        // A negative pixel is the measured file's fault, said before the simulated slice is read.
        bssrdf::check_measured(&self.measured, &measured, None, None)?;
        let sim_path = simulated_path(&self.simulated);
        let simulated = bssrdf::read_grid(&sim_path, None)?;
        // The measured slice must be of the simulated one's wavelength and
        // configuration (as the simulation's summary.json says), and not negative.
        let sim = bssrdf::sidecar_of(&sim_path)?;
        let sim_angles = sim.as_ref().and_then(|s| match (s.theta_i_deg, s.phi_i_deg, s.theta_o_deg, s.phi_o_deg) {
            (Some(ti), Some(pi), Some(to), Some(po)) => Some((ti, pi, to, po)),
            _ => None,
        });
        bssrdf::check_measured(&self.measured, &measured, sim.as_ref().and_then(|s| s.wavelength_nm), sim_angles)?;
        let (c, rel) = bssrdf::compare(&measured, &simulated, self.threshold).map_err(|error| E::Comparison {
            measured: self.measured.clone(),
            simulated: sim_path.clone(),
            error,
        })?;
        // Written into a staging folder and moved into `out` only when all three
        // files are made; Ctrl-C or SIGTERM removes the staging folder and ends.
        let _interrupt = Interrupt::abort_on_first();
        let _remove_on_abort = crate::interrupt::remove_on_abort(&crate::io::StagedDir::staging_path(&self.out));
        let stage = crate::io::StagedDir::new(&self.out)?;
        let files = bssrdf::ComparisonFiles::in_dir(stage.path());
        crate::io::write_json(&files.json, &c)?;
        let x = measured.x_mm();
        let png = bssrdf::profile_png(
            &x,
            &[("measured", measured.middle_row(), None), ("simulated", simulated.middle_row(), None)],
            None,
        )?;
        crate::io::write_atomic(&files.profiles, &png)?;
        let panel = bssrdf::heatmap_png(
            &[("measured", &measured), ("simulated", &simulated)],
            Some(("relative difference (masked)", &rel)),
        )?;
        crate::io::write_atomic(&files.panel, &panel)?;
        stage.commit(|n| bssrdf::ComparisonFiles::NAMES.contains(&n))?;
        Ok(BssrdfCompareRun { comparison: c, out: self.out.clone() })
    }
}

impl BssrdfCompareRun {
    /// comparison.json as text, then the files written.
    pub fn summary(&self) -> Vec<String> {
        vec![
            serde_json::to_string_pretty(&self.comparison).unwrap_or_default(),
            format!("written: {}/{{{}}}", self.out.display(), bssrdf::ComparisonFiles::NAMES.join(", ")),
        ]
    }
}
