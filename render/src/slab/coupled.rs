//! Differences of slices by common random numbers ([`simulate_coupled`]):
//! setups that differ a little (a perturbed μ_s, μ_a or phase function) are
//! traced with the same random streams, so their paths stay alike and the
//! difference of their slices [1/(m² sr)] carries far less noise than
//! either slice (Rubinstein & Kroese, *Simulation and the Monte Carlo
//! Method*, 2017, §5.2).

use super::error::SlabError;
use super::kernel::Kernel;
use super::options::{Progress, RunOptions};
use super::setup::Setup;
use super::tally::{pixel_estimates, tally_images, PixelErrors, Slice, SliceSums};
use super::ROUND_BATCHES;
use crate::stop::{Condition, Standing};
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// The difference f_a − f_b of two slices traced with common random
/// numbers ([`simulate_coupled`]): per pixel [1/(m² sr)], row-major from
/// the top row, with its standard error from the spread of the batches'
/// differences (so the two slices' shared noise, which cancels in the
/// difference, does not count).
#[derive(Debug, Clone)]
pub struct SliceDifference {
    pub pixels: usize,
    pub pixel_m: f64,
    pub values: Vec<f64>,
    pub std_error: Vec<f64>,
    /// Σ over pixels of f_a − f_b [1/(m² sr)] and its standard error.
    pub sum: f64,
    pub sum_std_error: f64,
    pub paths: u64,
}

/// The slice of `nominal` and, for each pair (a, b) of `pairs`, the
/// difference of the slices of a and b, all traced with **common random
/// numbers**: path k of every setup draws from the same stream
/// ([`Rng::new`](crate::rng::Rng::new)`(seed, k)`), so where the setups differ a little (a
/// perturbed μ_s, μ_a or phase function), their paths stay alike and the
/// difference carries far less noise than either slice (the correlated
/// sampling of Rubinstein & Kroese, *Simulation and the Monte Carlo
/// Method*, 2017, §5.2; the central differences of a sensitivity). Every
/// setup must have the nominal one's sensor; the estimator is the nominal
/// run's and must apply to each setup. Stops by `options.stop.samples` or
/// `time_s` (required: one of them), or at the end of the round under way
/// when `cancel` becomes true; `progress` is called after every round with
/// the nominal slice's figures.
pub fn simulate_coupled(
    nominal: &Setup,
    pairs: &[(Setup, Setup)],
    options: &RunOptions,
    mut progress: impl FnMut(&Progress),
    cancel: &AtomicBool,
) -> Result<(Slice, Vec<SliceDifference>), SlabError> {
    let stop = options.stop;
    stop.check()?;
    stop.refuse_unsupported("the coupled simulation", &[Condition::Samples, Condition::Time])?;
    let batch_paths = options.batch_paths.max(1);
    let kernel = Kernel::new(nominal, options.estimator)?;
    let kernels: Vec<(Kernel, Kernel)> = pairs
        .iter()
        .map(|(a, b)| {
            for s in [a, b] {
                if s.sensor != nominal.sensor {
                    return Err(SlabError::Parameter {
                        name: "pixels",
                        value: s.sensor.pixels as f64,
                        reason: "a coupled setup must have the nominal setup's sensor",
                    });
                }
            }
            Ok((Kernel::new(a, options.estimator)?, Kernel::new(b, options.estimator)?))
        })
        .collect::<Result<_, SlabError>>()?;
    let fold = options.fold
        && nominal.mirror_symmetric()
        && pairs.iter().all(|(a, b)| a.mirror_symmetric() && b.mirror_symmetric());
    let mut sums = SliceSums::empty(&kernel, nominal, fold);
    let npix = nominal.sensor.pixels * nominal.sensor.pixels;
    // Per pair: sums over batches of the batch mean differences, their squares, the raw differences; and of the batch sum differences.
    let mut diffs: Vec<([Vec<f64>; 3], f64, f64, f64)> =
        pairs.iter().map(|_| ([vec![0.0; npix], vec![0.0; npix], vec![0.0; npix]], 0.0, 0.0, 0.0)).collect();
    let mut pool: Vec<Vec<f64>> = Vec::new();
    let start = Instant::now();
    let mut batches = 0u64;
    loop {
        let mut round = ROUND_BATCHES;
        if let Some(max) = stop.samples {
            round = round.min(max.saturating_sub(batches * batch_paths).div_ceil(batch_paths));
        }
        if round == 0 {
            break;
        }
        let firsts: Vec<(u64, u64)> = (0..round)
            .map(|k| {
                let first = (batches + k) * batch_paths;
                (first, stop.samples.map_or(batch_paths, |max| batch_paths.min(max - first)))
            })
            .collect();
        sums.add_round(&kernel, options.seed, &firsts, &mut pool);
        for ((ka, kb), (d, s, sq, raw_sum)) in kernels.iter().zip(diffs.iter_mut()) {
            let traced: Vec<(u64, Vec<f64>, f64)> = firsts
                .par_iter()
                .map(|&(first, count)| {
                    let a = ka.batch(options.seed, first, count, Vec::new());
                    let b = kb.batch(options.seed, first, count, Vec::new());
                    let image: Vec<f64> = a.image.iter().zip(&b.image).map(|(x, y)| x - y).collect();
                    (count, image, a.path_sum - b.path_sum)
                })
                .collect();
            let images: Vec<(u64, &[f64])> = traced.iter().map(|(c, im, _)| (*c, im.as_slice())).collect();
            let [sum_b, sq_b, raw] = d;
            tally_images(sum_b, sq_b, raw, &images, fold, nominal.sensor.pixels);
            for (count, _, path_diff) in &traced {
                let m = path_diff / *count as f64;
                *s += m;
                *sq += m * m;
                *raw_sum += path_diff;
            }
        }
        batches += round;
        let elapsed = start.elapsed().as_secs_f64();
        let paths = stop.samples.map_or(batches * batch_paths, |m| m.min(batches * batch_paths));
        let n = paths as f64;
        let mean = sums.path_sum / n;
        let var = (sums.path_sq / n - mean * mean).max(0.0) / (n - 1.0).max(1.0);
        let (v, se) = pixel_estimates(&sums.raw, &sums.sum_b, &sums.sq_b, paths, batches);
        progress(&Progress {
            paths,
            events: sums.events,
            elapsed_s: elapsed,
            rel_error: if mean > 0.0 { var.sqrt() / mean } else { f64::INFINITY },
            pixels: PixelErrors::of(&v, &se),
        });
        let standing = Standing { samples: Some(paths), elapsed_s: elapsed, ..Standing::default() };
        if stop.met(&standing).is_some() || cancel.load(Ordering::Relaxed) {
            break;
        }
    }
    sums.batches = batches;
    sums.paths = stop.samples.map_or(batches * batch_paths, |m| m.min(batches * batch_paths));
    sums.wall_s = start.elapsed().as_secs_f64();
    let paths = sums.paths;
    let nb = batches.max(1) as f64;
    let differences = diffs
        .into_iter()
        .map(|([sum_b, sq_b, raw], s, sq, raw_sum)| {
            let (values, std_error) = pixel_estimates(&raw, &sum_b, &sq_b, paths, batches);
            let mean_b = s / nb;
            SliceDifference {
                pixels: nominal.sensor.pixels,
                pixel_m: nominal.sensor.pixel_m,
                values,
                std_error,
                sum: raw_sum / paths.max(1) as f64,
                sum_std_error: ((sq / nb - mean_b * mean_b).max(0.0) / (nb - 1.0).max(1.0)).sqrt(),
                paths,
            }
        })
        .collect();
    Ok((sums.slice(), differences))
}
