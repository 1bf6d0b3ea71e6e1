//! The optics job's uncertainty study (`uncertainty` N draws): per recipe,
//! the propagation of its uncertain inputs ([`crate::optics::uncertainty`]:
//! a Latin-hypercube design of N draws from the seed, the bulk properties
//! of each, their mean, sd and 95 % interval per wavelength) written to
//! `OUT/SAMPLE/uncertainty.{csv,json,png}`.
//!
//! With `shard` K/N only the K-th of N ranges of the draws is evaluated
//! (the whole design is made from the seed, so every shard has the same
//! one) and written as `OUT/SAMPLE/uncertainty.acc` (the shard's rows of
//! the design and the bulk properties of its draws: the 2.5th and 97.5th
//! percentiles need every value, not only sums) with `OUT/shard.json`;
//! [`OpticsJob::merge_uncertainty`] reads the draws from the shards of a
//! run instead of computing them, and its outputs are bit for bit those of
//! the unsharded run (the same values, summarised by the same code in the
//! same order).

use super::error::OpticsJobError as E;
use crate::fault::Interrupted;
use crate::job::context::Context;
use crate::job::spec::OpticsJob;
use crate::optics::recipe::Recipe;
use crate::optics::uncertainty::{self, Draws, Uncertainty};
use std::path::{Path, PathBuf};

/// The accumulator file of a sample in a shard folder of an uncertainty study.
pub fn uncertainty_acc(sample: &str) -> String {
    format!("{sample}/uncertainty.acc")
}

/// The arrays of an uncertainty accumulator: the shard's rows of the design
/// (`draws`) and the bulk properties of its draws.
fn uncertainty_arrays() -> [&'static str; 5] {
    let [a, b, c, d] = Draws::PROPERTIES;
    ["draws", a, b, c, d]
}

/// What an uncertainty study wrote: each sample's result, or a shard.
pub struct UncertaintyRun {
    pub out: PathBuf,
    /// Each recipe's propagation (empty for a shard).
    pub results: Vec<Uncertainty>,
    /// A shard's line ("shard K/N: draws … → …"), `None` for the study.
    pub shard: Option<String>,
}

impl UncertaintyRun {
    /// What `lucent optics --uncertainty` prints: per sample its inputs, a
    /// table of the means and sds (450, 550 and 650 nm of a longer grid)
    /// and the files written; for a shard its line.
    pub fn summary(&self) -> Vec<String> {
        if let Some(line) = &self.shard {
            return vec![line.clone()];
        }
        let mut lines = Vec::new();
        for u in &self.results {
            lines.push(format!(
                "{}: {} Latin-hypercube samples of {}",
                u.sample,
                u.samples,
                u.inputs.iter().map(|i| i.key.as_str()).collect::<Vec<_>>().join(", ")
            ));
            lines.push(format!(
                "{:>8} {:>24} {:>24} {:>20} {:>20}",
                "λ [nm]", "μs [1/m] mean ± sd", "μa [1/m] mean ± sd", "g mean ± sd", "n_bulk mean ± sd"
            ));
            for (i, w) in u.wavelength_nm.iter().enumerate() {
                if u.wavelength_nm.len() > 5 && ![450.0, 550.0, 650.0].contains(w) {
                    continue;
                }
                lines.push(format!(
                    "{w:>8} {:>13.5e} ± {:<9.2e} {:>13.5e} ± {:<9.2e} {:>9.5} ± {:<8.1e} {:>9.5} ± {:<8.1e}",
                    u.mu_s_per_m.mean[i],
                    u.mu_s_per_m.sd[i],
                    u.mu_a_per_m.mean[i],
                    u.mu_a_per_m.sd[i],
                    u.g.mean[i],
                    u.g.sd[i],
                    u.n_bulk.mean[i],
                    u.n_bulk.sd[i]
                ));
            }
            lines.push(format!("written: {}/uncertainty.{{csv,json,png}}", self.out.join(&u.sample).display()));
        }
        lines
    }
}

/// The draws of `recipe` in the shards of a run, checked against the run's
/// `design` and put together in shard order (every shard read and checked
/// before anything is written).
fn merged_draws(
    recipe: &Recipe,
    wavelengths: usize,
    design: &[Vec<f64>],
    shards: &[crate::job::shard::format::Shard],
) -> Result<Draws, E> {
    let n = design.len();
    let dims = recipe.uncertain.len();
    let mut all = Draws::empty(0, wavelengths);
    for s in shards {
        let k = s.file.shard;
        let expected = crate::job::shard::format::range(n as u64, k, s.file.identity.shards);
        if s.file.range != [expected.start, expected.end] {
            return Err(E::ShardRange { dir: s.dir.clone(), k, held: s.file.range, expected });
        }
        let range = expected.start as usize..expected.end as usize;
        let path = s.dir.join(uncertainty_acc(&recipe.name));
        let arrays = crate::job::shard::format::read_accumulator(&path)?;
        let rows = design[range.clone()].concat();
        let got = crate::job::shard::format::array(&arrays, "draws", rows.len(), &path)?;
        if let Some(i) = got.iter().zip(&rows).position(|(a, b)| a.to_bits() != b.to_bits()) {
            return Err(crate::job::shard::format::ShardError::Corrupt {
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
            *v = crate::job::shard::format::array(&arrays, name, range.len() * wavelengths, &path)?.to_vec();
        }
        all.append(&Draws { range, wavelengths, values }).map_err(|why| E::Draws { path, why })?;
    }
    if all.range != (0..n) {
        return Err(E::DrawsMissing { held: all.range, n });
    }
    Ok(all)
}

impl OpticsJob {
    /// The job's uncertainty study (`uncertainty` draws; with `shard` one
    /// shard of it) into `out`. Ctrl-C (or SIGTERM, SIGHUP) stops after the
    /// group of draws under way, writing nothing.
    pub fn run_uncertainty(&self, ctx: &Context) -> Result<UncertaintyRun, E> {
        self.study(ctx, None)
    }

    /// Writes the uncertainty study whose shards these are (`lucent
    /// merge`): their draws put together in draw order and summarised, bit
    /// for bit what the unsharded study writes.
    pub fn merge_uncertainty(
        &self,
        ctx: &Context,
        shards: &[crate::job::shard::format::Shard],
    ) -> Result<UncertaintyRun, E> {
        self.study(ctx, Some(shards))
    }

    fn study(
        &self,
        ctx: &Context,
        merged_from: Option<&[crate::job::shard::format::Shard]>,
    ) -> Result<UncertaintyRun, E> {
        let n = self.uncertainty.ok_or(E::NoStudy)?;
        let seed = self.uncertainty_seed;
        let grid = self.checked_grid(false)?;
        let recipes = self.load_recipes(ctx)?;
        let out = self.out.clone().unwrap_or_else(|| PathBuf::from(crate::job::spec::DEFAULT_OPTICS_OUT));
        if let Some((k, shards)) = self.shard.map(crate::job::shard::format::ShardSpec::pair) {
            let line = self.study_shard(&recipes, &grid, n, (k, shards), &out)?;
            return Ok(UncertaintyRun { out, results: Vec::new(), shard: Some(line) });
        }
        let mut results = Vec::new();
        match merged_from {
            Some(shards) => {
                // Every shard is read and checked before anything is written.
                let mut merged = Vec::new();
                for r in &recipes {
                    let design = uncertainty::design(r, n, seed)?;
                    let draws = merged_draws(r, grid.len(), &design, shards)?;
                    merged.push((design, draws));
                }
                for (r, (design, draws)) in recipes.iter().zip(merged) {
                    results.push(uncertainty::summarise(r, &grid, seed, design, &draws));
                }
            }
            None => {
                // In twenty groups, to say how far a long study is (the same
                // numbers as one group: `Draws::append`). Ctrl-C (or SIGTERM,
                // SIGHUP) stops after the group under way, writing nothing.
                let interrupt = crate::interrupt::Interrupt::install();
                for r in &recipes {
                    let start = std::time::Instant::now();
                    let design = uncertainty::design(r, n, seed)?;
                    let mut draws = Draws::empty(0, grid.len());
                    let group = n.div_ceil(20);
                    for lo in (0..n).step_by(group) {
                        if interrupt.requested() {
                            return Err(Interrupted(format!(
                                "{}: the uncertainty study stopped after {lo} of {n} draws; nothing was written to {}",
                                r.name,
                                out.display()
                            ))
                            .into());
                        }
                        let part = uncertainty::evaluate(r, &grid, &design, lo..(lo + group).min(n))?;
                        draws.append(&part).map_err(|why| E::Draws { path: r.path.clone(), why })?;
                        let elapsed = start.elapsed().as_secs_f64();
                        if elapsed > 2.0 && draws.range.end < n {
                            let left = elapsed * (n - draws.range.end) as f64 / draws.range.end as f64;
                            ctx.say(&format!(
                                "{}: {} of {n} draws in {elapsed:.0} s, ≈ {left:.0} s left",
                                r.name, draws.range.end
                            ));
                        }
                    }
                    results.push(uncertainty::summarise(r, &grid, seed, design, &draws));
                }
            }
        }
        for u in &results {
            let dir = out.join(&u.sample);
            let files = uncertainty::UncertaintyFiles::in_dir(&dir);
            crate::io::write_atomic(&files.csv, uncertainty::to_csv(u).map_err(E::Csv)?.as_bytes())?;
            crate::io::write_json(&files.json, u)?;
            crate::io::write_atomic(&files.png, &bands_png(u)?)?;
        }
        Ok(UncertaintyRun { out, results, shard: None })
    }

    /// Shard k of `shards` of the study: its range of the `n` draws of
    /// every recipe evaluated and written into `out` with shard.json (the
    /// run named by the job, [`Job::shard_identity`](crate::job::Job::shard_identity)); its line.
    fn study_shard(
        &self,
        recipes: &[Recipe],
        grid: &lucent_colour::WavelengthGrid,
        n: usize,
        (k, shards): (u32, u32),
        out: &Path,
    ) -> Result<String, E> {
        let seed = self.uncertainty_seed;
        let start = std::time::Instant::now();
        if u64::from(shards) > n as u64 {
            return Err(crate::job::shard::format::ShardError::TooManyShards {
                k,
                n: shards,
                units: n as u64,
                what: "draws",
            }
            .into());
        }
        let identity =
            crate::job::spec::Job::Optics(self.clone()).shard_identity(seed, format!("{n} draws"), shards)?;
        crate::job::shard::format::check_shard_out(out, &identity, k)?;
        let range = crate::job::shard::format::range(n as u64, k, shards);
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
        let meta = crate::job::shard::format::AccMeta::new(&identity, k, &range, &counters);
        for (sample, rows, draws) in &parts {
            let name = uncertainty_acc(sample);
            let values = std::iter::once(rows.as_slice()).chain(draws.values.iter().map(Vec::as_slice));
            let arrays: Vec<(&str, &[f64])> = uncertainty_arrays().into_iter().zip(values).collect();
            crate::job::shard::format::write_shard_accumulator(&out.join(&name), &meta, &arrays)?;
            accumulators.push(name);
        }
        let wall_s = start.elapsed().as_secs_f64();
        let file = crate::job::shard::format::ShardFile {
            identity,
            shard: k,
            range: [range.start, range.end],
            accumulators,
            counters,
            wall_s,
        };
        // Another shard may have finished into the same folder meanwhile.
        crate::job::shard::format::check_shard_out(out, &file.identity, k)?;
        crate::io::write_json(&out.join(crate::job::shard::format::SHARD_JSON), &file)?;
        Ok(format!(
            "shard {k}/{shards}: draws {}..{} of {n} in {wall_s:.1} s → {}/{{{}, {}}}",
            range.start,
            range.end,
            out.display(),
            file.accumulators.join(", "),
            crate::job::shard::format::SHARD_JSON
        ))
    }
}

/// μs, μa and g against wavelength: mean and the 95 % band.
fn bands_png(u: &Uncertainty) -> Result<Vec<u8>, crate::plot::PlotError> {
    use crate::plot::{perr, render_png};
    use plotters::prelude::*;
    let panels = [("μs [1/m]", &u.mu_s_per_m), ("μa [1/m]", &u.mu_a_per_m), ("g", &u.g)];
    let x = &u.wavelength_nm;
    let (x0, x1) = (x[0], x[x.len() - 1]);
    let (x0, x1) = if x1 > x0 { (x0, x1) } else { (x0 - 10.0, x0 + 10.0) };
    render_png(1500, 480, |root| {
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
    })
}
