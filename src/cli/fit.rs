//! `lucent fit`: recipe parameters fitted to measured BSSRDF slices
//! ([`crate::fit`]). Argument handling and printing only: the flags become
//! a [`FitJob`], which does the work. Also `lucent bench fit`, and `lucent
//! optics --uncertainty N` ([`optics_uncertainty`]).

use crate::fit::{self, FreeParameter, FreeSpec, Measurement, Objective, Problem, SearchBounds};
use crate::job::{FitJob, FitJobError, MeasuredSlice};
use crate::optics::recipe::{Overrides, Recipe};
use anyhow::{anyhow, bail, Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct FitArgs {
    /// Recipe (TOML) with the start values.
    #[arg(long)]
    pub recipe: PathBuf,
    /// Weight percentage for a recipe that leaves it unknown (the start value).
    #[arg(long)]
    pub weight_percent: Option<f64>,
    /// Measured slices FILE[:THETA_I/THETA_O] or FILE:THETA_I/PHI_I/THETA_O/PHI_O (degrees; φi 0°, φo 180° by default;
    /// without angles, from the file's sidecar FILE.json or summary.json "config").
    #[arg(long, required = true, num_args = 1..)]
    pub measured: Vec<MeasuredSlice>,
    /// Pixel size of the measured slices in mm (else from their sidecar JSON).
    #[arg(long)]
    pub measured_pixel_mm: Option<f64>,
    /// Free parameters, comma-separated: weight_percent, diameter_um, real_part_n (NAME@K for particle type K).
    #[arg(long, required = true, value_delimiter = ',')]
    pub free: Vec<FreeSpec>,
    /// What the fit minimises.
    #[arg(long, value_parser = super::choices::named::<Objective>(), default_value = "sum")]
    pub objective: Objective,
    /// Wavelength of the measurements in nm (`--wavelength` is the older spelling).
    #[arg(long = "wavelength-nm", alias = "wavelength", default_value_t = 550.0)]
    pub wavelength: f64,
    #[command(flatten)]
    pub beam: super::groups::BeamArgs,
    /// Relative uncertainty of each measured slice (a scale error; the lab states 5 %).
    #[arg(long, default_value_t = crate::job::DEFAULT_MEASURED_REL_SD)]
    pub measured_rel_sd: f64,
    /// Mask of the msre objective: measured pixels above this fraction of the maximum.
    #[arg(long, default_value_t = crate::job::DEFAULT_THRESHOLD)]
    pub threshold: f64,
    /// Target relative error of each simulated slice sum at the final points (sets the path count by a pilot run).
    #[arg(long, default_value_t = crate::job::DEFAULT_FIT_REL_ERROR)]
    pub rel_error: f64,
    /// Light paths per configuration and evaluation instead of the pilot run.
    #[arg(long)]
    pub paths: Option<u64>,
    /// Time cap of the pilot run per configuration, seconds.
    #[arg(long, default_value_t = 60.0)]
    pub pilot_time_s: f64,
    /// Search bounds LO:HI per free parameter, comma-separated (default start/10 … start·10; n: ÷/× 1.2).
    #[arg(long)]
    pub bounds: Option<SearchBounds>,
    /// Slab thickness in mm (default: the recipe's).
    #[arg(long)]
    pub thickness_mm: Option<f64>,
    /// Seed of the common random numbers.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[arg(long, default_value = "lucent-out/fit")]
    pub out: PathBuf,
    /// No progress lines.
    #[arg(long)]
    pub quiet: bool,
}

/// `lucent fit`: the job of the flags ([`FitJob::run`]), then its summary
/// on stdout; a fit the data cannot pin down fails after it is written.
pub fn run(a: FitArgs) -> Result<()> {
    let done = FitJob::from(&a).run(&crate::job::Context::default()).map_err(job_error)?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(done.finished()?)
}

/// A fit job's error for the command: a fit stopped by Ctrl-C as the
/// [`crate::fault::Interrupted`] it is (its exit code), others as they are.
pub fn job_error(e: FitJobError) -> anyhow::Error {
    match e.into_parts() {
        Ok(e) => e.into(),
        Err(interrupted) => interrupted.into(),
    }
}

/// `lucent bench fit`: a one-parameter weight-percentage fit of IOL1068-09
/// (PDMS) over three configurations (45/0, 0/45, 45/15; the lab's sensor,
/// 117 pixels of 0.1029 mm) to synthetic measurements made at 0.425 wt-%
/// with 5 % noise, starting from the recipe's 0.65. Reports the wall time
/// of the fit (the measurements' simulation is not timed) and the result.
pub fn bench(rel_error: f64, out: Option<PathBuf>) -> Result<()> {
    let path = PathBuf::from("fixtures/samples/IOL1068-09.toml");
    let recipe = Recipe::load(&path, Overrides::default()).context("run the bench from the repository root")?;
    let truth = recipe.with_weight_percent(0, 0.425)?;
    let configs = [(45.0, 0.0, 0.0, 180.0), (0.0, 0.0, 45.0, 180.0), (45.0, 0.0, 15.0, 180.0)];
    eprintln!("simulating the synthetic measurements (0.425 wt-%, 5 % noise; not timed) …");
    let grids = fit::synthetic_slices(&truth, 550.0, &configs, (117, 0.1029), 150_000, 77, 0.05)?;
    let measurements = grids
        .into_iter()
        .zip(configs)
        .map(|(g, c)| Measurement::new(Path::new(&format!("synthetic {}/{}", c.0, c.2)), g, c))
        .collect::<Result<Vec<_>, _>>()?;
    let mut problem = Problem::new(recipe, 550.0, vec![FreeParameter::weight_percent(0)], measurements)?;
    problem.budget.rel_error = rel_error;
    let result = fit::fit(&problem, |e| eprintln!("{e}"))?;
    if let Some(dir) = out {
        crate::job::write_fit_outputs(&dir, &problem, &result)?;
    }
    let p = &result.parameters[0];
    let json = serde_json::json!({
        "benchmark": "lucent fit: weight_percent of IOL1068-09 (PDMS) over 3 configurations (45/0, 0/45, 45/15), 117 × 117 px of 0.1029 mm, 550 nm, sum objective",
        "truth": 0.425,
        "start": p.start,
        "value": p.value,
        "std_error": p.std_error,
        "interval_95": p.interval_95,
        "identifiable": result.identifiable,
        "evaluations": result.evaluations,
        "paths_total": result.paths_total,
        "paths_per_evaluation": result.configurations.iter().map(|c| c.paths_per_evaluation).collect::<Vec<_>>(),
        "target_rel_error": rel_error,
        "threads": rayon::current_num_threads(),
        "wall_s": result.wall_s,
        "target_wall_s": 300.0,
    });
    println!("{}", serde_json::to_string_pretty(&json)?);
    Ok(())
}

/// The accumulator file of a sample in a shard folder of `lucent optics
/// --uncertainty N --shard K/N`.
pub fn uncertainty_acc(sample: &str) -> String {
    format!("{sample}/uncertainty.acc")
}

/// The arrays of an uncertainty accumulator: the shard's rows of the design
/// (`draws`) and the bulk properties of its draws.
fn uncertainty_arrays() -> [&'static str; 5] {
    let [a, b, c, d] = crate::optics::uncertainty::Draws::PROPERTIES;
    ["draws", a, b, c, d]
}

/// The draws of `recipe` in the shards of a run, checked against the run's
/// `design` and put together in shard order (every shard read and checked
/// before anything is written).
fn merged_draws(
    recipe: &Recipe,
    wavelengths: usize,
    design: &[Vec<f64>],
    shards: &[crate::shard::Shard],
) -> Result<crate::optics::uncertainty::Draws> {
    use crate::optics::uncertainty::Draws;
    let n = design.len();
    let dims = recipe.uncertain.len();
    let mut all = Draws::empty(0, wavelengths);
    for s in shards {
        let k = s.file.shard;
        let expected = crate::shard::range(n as u64, k, s.file.identity.shards);
        if s.file.range != [expected.start, expected.end] {
            bail!("{}: shard {k} holds draws {:?}, the run's shard {k} is {expected:?}", s.dir.display(), s.file.range);
        }
        let range = expected.start as usize..expected.end as usize;
        let path = s.dir.join(uncertainty_acc(&recipe.name));
        let arrays = crate::shard::read_accumulator(&path)?;
        let rows = design[range.clone()].concat();
        let got = crate::shard::array(&arrays, "draws", rows.len(), &path)?;
        if let Some(i) = got.iter().zip(&rows).position(|(a, b)| a.to_bits() != b.to_bits()) {
            return Err(crate::shard::ShardError::Corrupt {
                path,
                why: format!(
                    "draw {} has input values {:?}, the run's Latin-hypercube design has {:?}",
                    range.start + i / dims,
                    &got[i / dims * dims..(i / dims + 1) * dims],
                    &design[range.start + i / dims]
                ),
            }
            .into());
        }
        let mut values: [Vec<f64>; 4] = Default::default();
        for (v, name) in values.iter_mut().zip(Draws::PROPERTIES) {
            *v = crate::shard::array(&arrays, name, range.len() * wavelengths, &path)?.to_vec();
        }
        all.append(&Draws { range, wavelengths, values }).map_err(|why| anyhow!("{}: {why}", path.display()))?;
    }
    if all.range != (0..n) {
        bail!("the shards hold draws {:?} of the run's 0..{n}", all.range);
    }
    Ok(all)
}

/// `lucent optics --uncertainty N`: per recipe, the propagation of its
/// uncertain inputs ([`crate::optics::uncertainty`]) written to
/// `OUT/SAMPLE/uncertainty.{csv,json,png}` and summarised on stdout.
///
/// With `shard` = (K, N) only the K-th of N ranges of the draws is
/// evaluated (the whole design is made from the seed, so every shard has
/// the same one) and written as `OUT/SAMPLE/uncertainty.acc` (the shard's
/// rows of the design and the bulk properties of its draws: the 2.5th and
/// 97.5th percentiles need every value, not only sums) with
/// `OUT/shard.json`; with `merged_from` the draws are read from the shards
/// of a run instead of computed, and the outputs are bit for bit those of
/// the unsharded run (the same values, summarised by the same code in the
/// same order).
pub fn optics_uncertainty(
    recipes: &[Recipe],
    grid: &lucent_colour::WavelengthGrid,
    n: usize,
    seed: u64,
    out: &Path,
    shard: Option<(u32, u32)>,
    merged_from: Option<&[crate::shard::Shard]>,
) -> Result<()> {
    use crate::optics::uncertainty;
    if let Some((k, shards)) = shard {
        let start = std::time::Instant::now();
        if u64::from(shards) > n as u64 {
            return Err(crate::shard::ShardError::TooManyShards { k, n: shards, units: n as u64, what: "draws" }.into());
        }
        let identity = super::shard::identity(seed, format!("{n} draws"), shards)?;
        super::shard::check_shard_out(out, &identity, k)?;
        let range = crate::shard::range(n as u64, k, shards);
        let r = range.start as usize..range.end as usize;
        let mut parts = Vec::new();
        for recipe in recipes {
            let design = uncertainty::design(recipe, n, seed)?;
            let draws = uncertainty::evaluate(recipe, grid, &design, r.clone())?;
            parts.push((recipe.name.clone(), design[r.clone()].concat(), draws));
        }
        let mut accumulators = Vec::new();
        let counters: std::collections::BTreeMap<String, u64> =
            [("draws".to_string(), range.end - range.start)].into_iter().collect();
        let meta = crate::shard::AccMeta::new(&identity, k, &range, &counters);
        for (sample, rows, draws) in &parts {
            let name = uncertainty_acc(sample);
            let values = std::iter::once(rows.as_slice()).chain(draws.values.iter().map(Vec::as_slice));
            let arrays: Vec<(&str, &[f64])> = uncertainty_arrays().into_iter().zip(values).collect();
            crate::shard::write_shard_accumulator(&out.join(&name), &meta, &arrays)?;
            accumulators.push(name);
        }
        let wall_s = start.elapsed().as_secs_f64();
        let file = crate::shard::ShardFile {
            identity,
            shard: k,
            range: [range.start, range.end],
            accumulators,
            counters,
            wall_s,
        };
        super::shard::check_shard_out(out, &file.identity, k)?;
        crate::io::write_json(&out.join(crate::shard::SHARD_JSON), &file)?;
        println!(
            "shard {k}/{shards}: draws {}..{} of {n} in {wall_s:.1} s → {}/{{{}, {}}}",
            range.start,
            range.end,
            out.display(),
            file.accumulators.join(", "),
            crate::shard::SHARD_JSON
        );
        return Ok(());
    }
    let mut results = Vec::new();
    match merged_from {
        Some(shards) => {
            // Every shard is read and checked before anything is written.
            let mut merged = Vec::new();
            for r in recipes {
                let design = uncertainty::design(r, n, seed)?;
                let draws = merged_draws(r, grid.len(), &design, shards)?;
                merged.push((design, draws));
            }
            for (r, (design, draws)) in recipes.iter().zip(merged) {
                results.push(uncertainty::summarise(r, grid, seed, design, &draws));
            }
        }
        None => {
            // In twenty groups, to say how far a long study is (the same
            // numbers as one group: `Draws::append`). Ctrl-C (or SIGTERM,
            // SIGHUP) stops after the group under way, writing nothing.
            let interrupt = super::interrupt::Interrupt::install();
            for r in recipes {
                let start = std::time::Instant::now();
                let design = uncertainty::design(r, n, seed)?;
                let mut draws = uncertainty::Draws::empty(0, grid.len());
                let group = n.div_ceil(20);
                for lo in (0..n).step_by(group) {
                    if interrupt.requested() {
                        return Err(crate::fault::Interrupted(format!(
                            "{}: the uncertainty study stopped after {lo} of {n} draws; nothing was written to {}",
                            r.name,
                            out.display()
                        ))
                        .into());
                    }
                    let part = uncertainty::evaluate(r, grid, &design, lo..(lo + group).min(n))?;
                    draws.append(&part).map_err(anyhow::Error::msg)?;
                    let elapsed = start.elapsed().as_secs_f64();
                    if elapsed > 2.0 && draws.range.end < n {
                        let left = elapsed * (n - draws.range.end) as f64 / draws.range.end as f64;
                        eprintln!("{}: {} of {n} draws in {elapsed:.0} s, ≈ {left:.0} s left", r.name, draws.range.end);
                    }
                }
                results.push(uncertainty::summarise(r, grid, seed, design, &draws));
            }
        }
    }
    for u in &results {
        let dir = out.join(&u.sample);
        let files = uncertainty::UncertaintyFiles::in_dir(&dir);
        crate::io::write_atomic(&files.csv, uncertainty::to_csv(u)?.as_bytes())?;
        crate::io::write_json(&files.json, u)?;
        crate::io::write_atomic(&files.png, &bands_png(u)?)?;
        println!(
            "{}: {} Latin-hypercube samples of {}",
            u.sample,
            u.samples,
            u.inputs.iter().map(|i| i.key.as_str()).collect::<Vec<_>>().join(", ")
        );
        println!(
            "{:>8} {:>24} {:>24} {:>20} {:>20}",
            "λ [nm]", "μs [1/m] mean ± sd", "μa [1/m] mean ± sd", "g mean ± sd", "n_bulk mean ± sd"
        );
        for (i, w) in u.wavelength_nm.iter().enumerate() {
            if u.wavelength_nm.len() > 5 && ![450.0, 550.0, 650.0].contains(w) {
                continue;
            }
            println!(
                "{w:>8} {:>13.5e} ± {:<9.2e} {:>13.5e} ± {:<9.2e} {:>9.5} ± {:<8.1e} {:>9.5} ± {:<8.1e}",
                u.mu_s_per_m.mean[i],
                u.mu_s_per_m.sd[i],
                u.mu_a_per_m.mean[i],
                u.mu_a_per_m.sd[i],
                u.g.mean[i],
                u.g.sd[i],
                u.n_bulk.mean[i],
                u.n_bulk.sd[i]
            );
        }
        println!("written: {}/uncertainty.{{csv,json,png}}", dir.display());
    }
    Ok(())
}

/// μs, μa and g against wavelength: mean and the 95 % band.
fn bands_png(u: &crate::optics::uncertainty::Uncertainty) -> Result<Vec<u8>> {
    use crate::plot::{perr, render_png};
    use plotters::prelude::*;
    let panels = [("μs [1/m]", &u.mu_s_per_m), ("μa [1/m]", &u.mu_a_per_m), ("g", &u.g)];
    let x = &u.wavelength_nm;
    let (x0, x1) = (x[0], x[x.len() - 1]);
    let (x0, x1) = if x1 > x0 { (x0, x1) } else { (x0 - 10.0, x0 + 10.0) };
    Ok(render_png(1500, 480, |root| {
        for (area, (label, b)) in root.split_evenly((1, 3)).iter().zip(panels) {
            let lo = b.p2_5.iter().copied().fold(f64::INFINITY, f64::min);
            let hi = b.p97_5.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let pad = 0.05 * (hi - lo).max(1e-12 * hi.abs().max(1e-300));
            let mut chart = ChartBuilder::on(area)
                .margin(12)
                .caption(
                    format!("{} — {label}, mean and 95 % band ({} samples)", u.sample, u.samples),
                    ("sans-serif", 15),
                )
                .x_label_area_size(35)
                .y_label_area_size(75)
                .build_cartesian_2d(x0..x1, (lo - pad)..(hi + pad))
                .map_err(perr)?;
            chart
                .configure_mesh()
                .x_desc("wavelength [nm]")
                .y_desc(label)
                .y_label_formatter(&|v| format!("{v:.3e}"))
                .draw()
                .map_err(perr)?;
            let blue = RGBColor(31, 119, 180);
            let mut poly: Vec<(f64, f64)> = x.iter().zip(&b.p97_5).map(|(a, b)| (*a, *b)).collect();
            poly.extend(x.iter().zip(&b.p2_5).rev().map(|(a, b)| (*a, *b)));
            if x.len() > 1 {
                chart.draw_series(std::iter::once(Polygon::new(poly, blue.mix(0.25).filled()))).map_err(perr)?;
                chart
                    .draw_series(LineSeries::new(x.iter().zip(&b.mean).map(|(a, b)| (*a, *b)), blue.stroke_width(2)))
                    .map_err(perr)?;
            } else {
                chart
                    .draw_series(std::iter::once(PathElement::new(
                        vec![(x[0], b.p2_5[0]), (x[0], b.p97_5[0])],
                        blue.stroke_width(3),
                    )))
                    .map_err(perr)?;
                chart.draw_series(std::iter::once(Circle::new((x[0], b.mean[0]), 5, blue.filled()))).map_err(perr)?;
            }
        }
        Ok(())
    })?)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measured_specs() {
        let m = |t: &str| t.parse::<MeasuredSlice>();
        let a = m("m.exr:45/0").unwrap();
        assert_eq!((a.path, a.angles.map(|a| a.degrees())), (PathBuf::from("m.exr"), Some((45.0, 0.0, 0.0, 180.0))));
        let a = m("dir:x/m.exr:45/10/0/190").unwrap();
        assert_eq!(
            (a.path, a.angles.map(|a| a.degrees())),
            (PathBuf::from("dir:x/m.exr"), Some((45.0, 10.0, 0.0, 190.0)))
        );
        assert_eq!(m("m.exr").unwrap().angles, None);
        assert!(m("m.exr:45/x").is_err());
        assert!(m("m.exr:45/0/1").is_err());
        let b: SearchBounds = "0.1:1".parse().unwrap();
        assert_eq!(b.0, vec![fit::SearchRange { lo: 0.1, hi: 1.0 }]);
        assert!("0.1-1".parse::<SearchBounds>().is_err());
    }
}
