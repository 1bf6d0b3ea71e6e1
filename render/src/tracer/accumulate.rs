//! Accumulation: the per-pixel sums Σ L, Σ L², the even samples' Σ L and
//! the derivatives' sums of a progressive render ([`Accumulator`]), one
//! pass of it (sample k of pixel p from `Rng::new(seed, k·2³² + p)`, rows in
//! parallel) and the image they give (mean and variance of the mean per
//! pixel); and what one camera path carries back (`Estimate`): the radiance
//! per band and, per coefficient derivative, the likelihood-ratio score
//! ∂ ln f/∂θ = n ∂ln μ_s/∂θ − ∂μ_t/∂θ ℓ its contributions are weighted by
//! (Hayakawa et al. 2001).

use super::image::{DerivativeImage, Image, Stats};
use super::scene::{Object, Scene};
use super::settings::{CoefficientDerivative, Settings, MAX_DERIVATIVES};
use super::walk::{trace, FirstHit};
use crate::rng::Rng;
use rayon::prelude::*;
use std::sync::atomic::{AtomicBool, Ordering};

/// Per-pixel sums of a progressive render (or of one shard of it,
/// [`render_samples`]): Σ L and Σ L² per band over the pixel's samples, in
/// the samples' order.
///
/// [`render_samples`]: super::render_samples
#[derive(Debug, Clone, PartialEq)]
pub struct Accumulator {
    pub width: usize,
    pub height: usize,
    pub sum: Vec<[f64; 3]>,
    pub sum_sq: Vec<[f64; 3]>,
    /// The sum over the samples with even index (counted from sample 0 of
    /// the whole render, not of the shard): the first half render.
    pub sum_even: Vec<[f64; 3]>,
    pub samples: Vec<u32>,
    pub object_samples: Vec<u32>,
    pub board_samples: Vec<u32>,
    /// The index of the first sample of every pixel (0 for a whole render).
    pub first_sample: u32,
    /// Σ ∂L/∂θ and Σ (∂L/∂θ)² per pixel and [`Settings::derivatives`]
    /// entry k, at p · K + k (K entries; empty until a pass carries them).
    pub derivative_sum: Vec<[f64; 3]>,
    pub derivative_sum_sq: Vec<[f64; 3]>,
}

impl Accumulator {
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            first_sample: 0,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![[0.0; 3]; n],
            sum_even: vec![[0.0; 3]; n],
            samples: vec![0; n],
            object_samples: vec![0; n],
            board_samples: vec![0; n],
            derivative_sum: Vec::new(),
            derivative_sum_sq: Vec::new(),
        }
    }

    /// The number of derivatives the sums hold.
    pub(super) fn derivative_count(&self) -> usize {
        self.derivative_sum.len() / (self.width * self.height).max(1)
    }

    pub(super) fn max_samples(&self) -> u32 {
        self.samples.iter().copied().max().unwrap_or(0)
    }

    /// Adds `quota[p]` samples to every pixel p, rows in parallel. Sample k
    /// of pixel p draws from `Rng::new(seed, k·2³² + p)`. Once `cancel` is
    /// set, the samples not yet started are left out (each pixel keeps its
    /// own sample count, so the image stays valid).
    pub(super) fn add_pass(
        &mut self,
        scene: &Scene,
        settings: &Settings,
        quota: &[u32],
        cancel: Option<&AtomicBool>,
    ) -> Stats {
        let w = self.width;
        let first_sample = self.first_sample;
        let kd = settings.derivatives.len().min(MAX_DERIVATIVES);
        if self.derivative_count() != kd {
            // (A render's settings do not change between passes: this is the first.)
            self.derivative_sum = vec![[0.0; 3]; self.sum.len() * kd];
            self.derivative_sum_sq = vec![[0.0; 3]; self.sum.len() * kd];
        }
        // Rows of the derivative sums (empty rows without derivatives).
        fn rows(v: &mut [[f64; 3]], width: usize, height: usize) -> Vec<&mut [[f64; 3]]> {
            if v.is_empty() {
                (0..height).map(|_| <&mut [[f64; 3]]>::default()).collect()
            } else {
                v.chunks_mut(width).collect()
            }
        }
        let mut d_rows = rows(&mut self.derivative_sum, w * kd, self.height);
        let mut d_rows_sq = rows(&mut self.derivative_sum_sq, w * kd, self.height);
        self.sum
            .par_chunks_mut(w)
            .zip(self.sum_sq.par_chunks_mut(w))
            .zip(self.sum_even.par_chunks_mut(w))
            .zip(self.samples.par_chunks_mut(w))
            .zip(self.object_samples.par_chunks_mut(w).zip(self.board_samples.par_chunks_mut(w)))
            .zip(d_rows.par_iter_mut().zip(d_rows_sq.par_iter_mut()))
            .enumerate()
            .map(|(j, (((((row, row_sq), row_even), row_n), (row_obj, row_board)), (row_d, row_d_sq)))| {
                let mut st = Stats::default();
                'pixels: for i in 0..w {
                    let pixel = (j * w + i) as u64;
                    let k0 = row_n[i];
                    let k1 = k0 + quota[j * w + i];
                    for k in k0..k1 {
                        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                            st.samples += u64::from(k - k0);
                            row_n[i] = k;
                            break 'pixels;
                        }
                        let mut rng = Rng::new(settings.seed, (u64::from(first_sample + k) << 32) | pixel);
                        let u = [rng.next_f64(), rng.next_f64()];
                        let (o, d) = scene.camera.ray(i, j, u);
                        let (l, dl, first) = trace(scene, settings, o, d, &mut rng, &mut st);
                        for c in 0..3 {
                            row[i][c] += l[c];
                            row_sq[i][c] += l[c] * l[c];
                        }
                        for (k, dk) in dl.iter().enumerate().take(kd) {
                            for c in 0..3 {
                                row_d[i * kd + k][c] += dk[c];
                                row_d_sq[i * kd + k][c] += dk[c] * dk[c];
                            }
                        }
                        if (first_sample + k).is_multiple_of(2) {
                            for c in 0..3 {
                                row_even[i][c] += l[c];
                            }
                        }
                        match first {
                            FirstHit::Object => row_obj[i] += 1,
                            FirstHit::Board => row_board[i] += 1,
                            FirstHit::Environment => {}
                        }
                    }
                    st.samples += u64::from(k1 - k0);
                    row_n[i] = k1;
                }
                st
            })
            .reduce(Stats::default, |mut a, b| {
                a.add(&b);
                a
            })
    }

    /// Mean and variance of the mean per pixel.
    pub fn image(&self) -> Image {
        let mean = self.sum.iter().zip(&self.samples).map(|(s, &k)| s.map(|v| v / f64::from(k.max(1)))).collect();
        let variance_of_mean = self
            .sum
            .iter()
            .zip(&self.sum_sq)
            .zip(&self.samples)
            .map(|((s, q), &k)| {
                let m = f64::from(k);
                std::array::from_fn(|c| {
                    if k > 1 {
                        ((q[c] - s[c] * s[c] / m) / (m - 1.0)).max(0.0) / m
                    } else {
                        f64::INFINITY
                    }
                })
            })
            .collect();
        let half = |odd: bool| {
            self.sum
                .iter()
                .zip(&self.sum_even)
                .zip(&self.samples)
                .map(|((s, e), &k)| {
                    // Even global indices in first .. first + k.
                    let f = self.first_sample;
                    let even = (f + k).div_ceil(2) - f.div_ceil(2);
                    let (n, part) = if odd { (k - even, sub(*s, *e)) } else { (even, *e) };
                    part.map(|v| if n > 0 { v / f64::from(n) } else { 0.0 })
                })
                .collect()
        };
        let halves = [half(false), half(true)];
        let kd = self.derivative_count();
        let derivatives = (0..kd)
            .map(|k| {
                let (mean, variance_of_mean) = (0..self.samples.len())
                    .map(|p| {
                        mean_and_variance(
                            self.derivative_sum[p * kd + k],
                            self.derivative_sum_sq[p * kd + k],
                            self.samples[p],
                        )
                    })
                    .unzip();
                DerivativeImage { mean, variance_of_mean }
            })
            .collect();
        Image {
            width: self.width,
            height: self.height,
            mean,
            variance_of_mean,
            halves,
            samples: self.samples.clone(),
            object_samples: self.object_samples.clone(),
            board_samples: self.board_samples.clone(),
            derivatives,
        }
    }
}

/// The mean of k samples from their sum and sum of squares, and the variance of that mean (∞ below 2 samples).
pub(super) fn mean_and_variance(sum: [f64; 3], sum_sq: [f64; 3], k: u32) -> ([f64; 3], [f64; 3]) {
    let m = f64::from(k);
    let mean = sum.map(|v| v / m.max(1.0));
    let var = std::array::from_fn(|c| {
        if k > 1 {
            ((sum_sq[c] - sum[c] * sum[c] / m) / (m - 1.0)).max(0.0) / m
        } else {
            f64::INFINITY
        }
    });
    (mean, var)
}

pub(super) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|c| a[c] - b[c])
}

/// What one camera path carries back: the radiance per band, and per
/// [`CoefficientDerivative`] its derivative, with the path's running score
/// ∂ ln f/∂θ (flights and events so far) that each contribution is weighted by.
pub(super) struct Estimate<'a> {
    pub(super) derivatives: &'a [CoefficientDerivative],
    pub(super) l: [f64; 3],
    pub(super) dl: [[f64; 3]; MAX_DERIVATIVES],
    pub(super) score: [[f64; 3]; MAX_DERIVATIVES],
}

impl<'a> Estimate<'a> {
    pub(super) fn new(settings: &'a Settings) -> Self {
        let k = settings.derivatives.len().min(MAX_DERIVATIVES);
        Self {
            derivatives: &settings.derivatives[..k],
            l: [0.0; 3],
            dl: [[0.0; 3]; MAX_DERIVATIVES],
            score: [[0.0; 3]; MAX_DERIVATIVES],
        }
    }

    /// A contribution `v` to band c.
    #[inline]
    pub(super) fn add(&mut self, c: usize, v: f64) {
        self.l[c] += v;
        for (k, _) in self.derivatives.iter().enumerate() {
            self.dl[k][c] += v * self.score[k][c];
        }
    }

    /// A contribution `v` to band c that crossed `length_m` more of `obj`'s
    /// medium than the path has walked (a connection).
    #[inline]
    pub(super) fn add_through(&mut self, c: usize, v: f64, obj: &Object, length_m: f64) {
        self.l[c] += v;
        for (k, d) in self.derivatives.iter().enumerate() {
            self.dl[k][c] += v * (self.score[k][c] - d.d_mu_t(c, obj.medium[c].mu_s_per_m) * length_m);
        }
    }

    /// The path flew `length_m` through `obj`'s medium.
    #[inline]
    pub(super) fn flight(&mut self, obj: &Object, length_m: f64) {
        for (k, d) in self.derivatives.iter().enumerate() {
            for c in 0..3 {
                self.score[k][c] -= d.d_mu_t(c, obj.medium[c].mu_s_per_m) * length_m;
            }
        }
    }

    /// The path scattered.
    #[inline]
    pub(super) fn scatter(&mut self) {
        for (k, d) in self.derivatives.iter().enumerate() {
            for c in 0..3 {
                self.score[k][c] += d.d_ln_mu_s[c];
            }
        }
    }
}
