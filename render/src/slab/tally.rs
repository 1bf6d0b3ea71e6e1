//! What a run adds up and reports. The kernel fills one image and the path
//! totals per batch (`Batch`); a run, or one shard of it, sums the batch
//! means per pixel and their squares ([`SliceSums`]); the slice they give
//! ([`Slice`]) is f_ssr per pixel [1/(m² sr)], the mean over paths of the
//! splats, with standard errors from the spread of the batch means, and
//! the slice sum's standard error from the per-path totals. [`PixelErrors`]
//! sums up the per-pixel relative errors over the bright pixels.

use super::kernel::{Kernel, Strategy};
use super::options::Estimator;
use super::setup::Setup;
use rayon::prelude::*;

/// Fraction of the brightest pixel's value above which pixels enter the
/// per-pixel error figures ([`PixelErrors`]): 1 %, the mask the lab's
/// comparison uses (`lucent bssrdf compare --threshold`).
pub const PIXEL_MASK_FRACTION: f64 = 0.01;

/// The per-pixel relative standard error σ_i / f_i over the pixels with
/// f_i > [`PIXEL_MASK_FRACTION`] · max f: its median and 90th percentile
/// (nearest rank). This is the figure that says whether a slice *image*
/// has converged (the sum converges much sooner); a mean squared relative
/// error against a measurement gains about median² from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelErrors {
    pub median: f64,
    pub p90: f64,
    /// Pixels in the mask.
    pub pixels: usize,
}

impl PixelErrors {
    /// The figures of a slice's `values` and `std_error` (same length);
    /// infinite errors when no pixel is positive.
    pub fn of(values: &[f64], std_error: &[f64]) -> Self {
        let max = values.iter().copied().fold(0.0, f64::max);
        let cut = PIXEL_MASK_FRACTION * max;
        let mut rel: Vec<f64> =
            values.iter().zip(std_error).filter(|(v, _)| **v > cut && **v > 0.0).map(|(v, s)| s / v).collect();
        if rel.is_empty() {
            return Self { median: f64::INFINITY, p90: f64::INFINITY, pixels: 0 };
        }
        rel.sort_by(f64::total_cmp);
        let rank = |q: f64| rel[((q * rel.len() as f64).ceil() as usize).clamp(1, rel.len()) - 1];
        Self { median: rank(0.5), p90: rank(0.9), pixels: rel.len() }
    }
}

/// A simulated slice: per-pixel f_ssr [1/(m² sr)] and its standard error,
/// row-major from the top row.
#[derive(Debug, Clone)]
pub struct Slice {
    pub pixels: usize,
    pub pixel_m: f64,
    pub values: Vec<f64>,
    pub std_error: Vec<f64>,
    /// Σ over pixels of f_ssr [1/(m² sr)].
    pub sum: f64,
    pub sum_std_error: f64,
    pub paths: u64,
    pub events: u64,
    pub wall_s: f64,
    /// Fresnel reflectance of the top surface at θ_i (not in the slice).
    pub specular_reflectance: f64,
    /// Fraction of Φ_i leaving through the top after entering (all directions).
    pub diffuse_reflectance: f64,
    /// Fraction of Φ_i leaving through the bottom.
    pub transmittance: f64,
    /// Which kernel traced the paths: "avx2-fma lanes" (four paths per
    /// vector, see the `lanes` module) or "scalar". They agree to rounding.
    pub kernel: &'static str,
    pub estimator: Estimator,
    /// Whether the slice was folded about the plane of incidence
    /// ([`RunOptions::fold`](super::RunOptions::fold)).
    pub folded: bool,
    /// Whether the photons were launched from the camera's side (the ring
    /// with θ_o = 0, by reciprocity); `diffuse_reflectance` and
    /// `transmittance` then describe light arriving along ω_o.
    pub reciprocal: bool,
}

impl Slice {
    pub fn events_per_s(&self) -> f64 {
        self.events as f64 / self.wall_s.max(1e-12)
    }

    /// Median and 90th percentile of the per-pixel relative standard error
    /// over the bright pixels ([`PixelErrors`]).
    pub fn pixel_errors(&self) -> PixelErrors {
        PixelErrors::of(&self.values, &self.std_error)
    }
}

/// Per-batch tallies.
pub(super) struct Batch {
    pub(super) image: Vec<f64>,
    pub(super) path_sum: f64,
    pub(super) path_sq: f64,
    pub(super) events: u64,
    pub(super) reflected: f64,
    pub(super) transmitted: f64,
}

impl Batch {
    /// Empty tallies with `image` (a buffer to reuse) zeroed for `pixels`².
    pub(super) fn new(mut image: Vec<f64>, pixels: usize) -> Self {
        image.clear();
        image.resize(pixels * pixels, 0.0);
        Batch { image, path_sum: 0.0, path_sq: 0.0, events: 0, reflected: 0.0, transmitted: 0.0 }
    }
}

/// The tallies of a run, or of one shard of it ([`simulate_batches`](super::simulate_batches)):
/// per pixel the sums over batches of the batch means and of their squares
/// and the raw sum of the splats, and the sums over paths of the per-path
/// totals. Shards of one run add up ([`SliceSums::add`]) to the run's
/// tallies, to rounding (the sums are taken in another order).
#[derive(Debug, Clone)]
pub struct SliceSums {
    pub pixels: usize,
    pub pixel_m: f64,
    pub sum_b: Vec<f64>,
    pub sq_b: Vec<f64>,
    pub raw: Vec<f64>,
    pub path_sum: f64,
    pub path_sq: f64,
    pub events: u64,
    pub reflected: f64,
    pub transmitted: f64,
    /// Batches and paths traced.
    pub batches: u64,
    pub paths: u64,
    pub wall_s: f64,
    pub specular_reflectance: f64,
    pub kernel: &'static str,
    pub estimator: Estimator,
    pub folded: bool,
    pub reciprocal: bool,
}

impl SliceSums {
    pub(super) fn empty(kernel: &Kernel, setup: &Setup, fold: bool) -> Self {
        let npix = setup.sensor.pixels * setup.sensor.pixels;
        Self {
            pixels: setup.sensor.pixels,
            pixel_m: setup.sensor.pixel_m,
            sum_b: vec![0.0; npix],
            sq_b: vec![0.0; npix],
            raw: vec![0.0; npix],
            path_sum: 0.0,
            path_sq: 0.0,
            events: 0,
            reflected: 0.0,
            transmitted: 0.0,
            batches: 0,
            paths: 0,
            wall_s: 0.0,
            specular_reflectance: kernel.specular,
            kernel: kernel.name(),
            estimator: kernel.strategy.estimator(),
            folded: fold,
            reciprocal: matches!(&kernel.strategy, Strategy::Ring(r) if r.sign < 0.0),
        }
    }

    /// Traces the batches `(first path, paths)` in parallel and adds them
    /// in their order. Batch images are reused from round to round (no
    /// allocation and no page faults), and merged in parallel over pixel
    /// chunks, each pixel taking the batches in order (so the sums do not
    /// depend on the thread count).
    pub(super) fn add_round(&mut self, kernel: &Kernel, seed: u64, batches: &[(u64, u64)], pool: &mut Vec<Vec<f64>>) {
        let buffers: Vec<Vec<f64>> = batches.iter().map(|_| pool.pop().unwrap_or_default()).collect();
        let results: Vec<(u64, Batch)> = buffers
            .into_par_iter()
            .zip(batches.par_iter())
            .map(|(image, &(first, count))| (count, kernel.batch(seed, first, count, image)))
            .collect();
        let images: Vec<(u64, &[f64])> = results.iter().map(|(count, b)| (*count, b.image.as_slice())).collect();
        tally_images(&mut self.sum_b, &mut self.sq_b, &mut self.raw, &images, self.folded, self.pixels);
        for (_, b) in results {
            self.path_sum += b.path_sum;
            self.path_sq += b.path_sq;
            self.events += b.events;
            self.reflected += b.reflected;
            self.transmitted += b.transmitted;
            pool.push(b.image);
        }
    }

    /// Adds another shard's tallies (same setup, same pixels) after these.
    pub fn add(&mut self, o: &SliceSums) {
        for (a, b) in [(&mut self.sum_b, &o.sum_b), (&mut self.sq_b, &o.sq_b), (&mut self.raw, &o.raw)] {
            for (x, y) in a.iter_mut().zip(b.iter()) {
                *x += y;
            }
        }
        self.path_sum += o.path_sum;
        self.path_sq += o.path_sq;
        self.events += o.events;
        self.reflected += o.reflected;
        self.transmitted += o.transmitted;
        self.batches += o.batches;
        self.paths += o.paths;
        self.wall_s += o.wall_s;
    }

    /// The slice these tallies give.
    pub fn slice(&self) -> Slice {
        let paths = self.paths.max(1);
        let (values, std_error) = pixel_estimates(&self.raw, &self.sum_b, &self.sq_b, paths, self.batches);
        let n = paths as f64;
        let mean = self.path_sum / n;
        let sum_std_error = ((self.path_sq / n - mean * mean).max(0.0) / (n - 1.0).max(1.0)).sqrt();
        Slice {
            pixels: self.pixels,
            pixel_m: self.pixel_m,
            values,
            std_error,
            sum: mean,
            sum_std_error,
            paths,
            events: self.events,
            wall_s: self.wall_s,
            specular_reflectance: self.specular_reflectance,
            diffuse_reflectance: self.reflected / n,
            transmittance: self.transmitted / n,
            kernel: self.kernel,
            estimator: self.estimator,
            folded: self.folded,
            reciprocal: self.reciprocal,
        }
    }
}

/// Per-pixel values (mean over `paths` of the raw sums) and standard
/// errors (from the spread of the `batches` batch means, which are
/// equal-sized except possibly the last).
pub(super) fn pixel_estimates(
    raw: &[f64],
    sum_b: &[f64],
    sq_b: &[f64],
    paths: u64,
    batches: u64,
) -> (Vec<f64>, Vec<f64>) {
    let nb = batches.max(1) as f64;
    let values = raw.iter().map(|r| r / paths.max(1) as f64).collect();
    let std_error = sum_b
        .iter()
        .zip(sq_b)
        .map(|(s, q)| {
            let mean = s / nb;
            ((q / nb - mean * mean).max(0.0) / (nb - 1.0).max(1.0)).sqrt()
        })
        .collect();
    (values, std_error)
}

/// Adds batch images `(paths, image)`, in their order, to the per-pixel
/// sums of batch means (`sum_b`), of their squares (`sq_b`) and of the raw
/// splats (`raw`); with `fold`, pixel (r, c) and its mirror (N−1−r, c) of
/// the `side` × `side` image averaged first. Parallel over pixel chunks,
/// each pixel taking the batches in order (so the sums do not depend on
/// the thread count).
pub(super) fn tally_images(
    sum_b: &mut [f64],
    sq_b: &mut [f64],
    raw: &mut [f64],
    images: &[(u64, &[f64])],
    fold: bool,
    side: usize,
) {
    const CHUNK: usize = 4096;
    sum_b.par_chunks_mut(CHUNK).zip(sq_b.par_chunks_mut(CHUNK)).zip(raw.par_chunks_mut(CHUNK)).enumerate().for_each(
        |(c, ((sum_b, sq_b), raw))| {
            let at = c * CHUNK;
            for (count, image) in images {
                let scale = 1.0 / *count as f64;
                for (k, ((s, q), r)) in sum_b.iter_mut().zip(sq_b.iter_mut()).zip(raw.iter_mut()).enumerate() {
                    let i = at + k;
                    let v = if fold {
                        let mirror = (side - 1 - i / side) * side + i % side;
                        0.5 * (image[i] + image[mirror])
                    } else {
                        image[i]
                    };
                    let m = v * scale;
                    *s += m;
                    *q += m * m;
                    *r += v;
                }
            }
        },
    );
}
