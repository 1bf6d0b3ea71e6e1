//! A path's throughput in the three bands as the spectral-MIS pair (β, r)
//! (`Throughput`; the one-sample balance heuristic over the band that
//! drives the sampling, Wilkie et al. 2014, Miller et al. 2019; module doc
//! of [`tracer`](super), "Bands"), and the Russian roulette on its
//! estimate β / mean r (`roulette`: unbiased, never on the depth).

use super::settings::Settings;
use crate::rng::Rng;

/// Throughput of a path in the three bands, as the spectral-MIS pair
/// (β, r): β_c = f_c / p̂ and r_k = p_k / p̂ for one common scale p̂, where
/// f_c is the path's measurement contribution in band c and p_k the density
/// with which the path would have been sampled had band k driven the
/// sampling. The estimate in band c is β_c / mean_k r_k (balance heuristic
/// over the three bands, each chosen with probability 1/3). Before the path
/// meets the object all r_k are equal; a path that keeps one band b (docs/method.md
/// §5's estimator) has r = 3·e_b and β = 3·β_b·e_b, the same formula.
#[derive(Debug, Clone, Copy)]
pub(super) struct Throughput {
    pub(super) beta: [f64; 3],
    pub(super) r: [f64; 3],
}

impl Throughput {
    /// At most one band takes part: every ratio between bands is 1 (or 0/0 for
    /// the inactive ones, which stay 0), so the per-band scalings can be skipped.
    #[inline]
    pub(super) fn single_band(&self) -> bool {
        u8::from(self.active(0)) + u8::from(self.active(1)) + u8::from(self.active(2)) <= 1
    }

    /// Band c still takes part in the estimate (a path that keeps one band has β = r = 0 in the others).
    #[inline]
    pub(super) fn active(&self, c: usize) -> bool {
        self.beta[c] != 0.0 || self.r[c] != 0.0
    }

    #[inline]
    pub(super) fn mean_r(&self) -> f64 {
        (self.r[0] + self.r[1] + self.r[2]) / 3.0
    }

    /// The estimate's weight in band c: β_c / mean r.
    #[inline]
    pub(super) fn effective(&self) -> [f64; 3] {
        let m = self.mean_r();
        if m > 0.0 {
            self.beta.map(|b| b / m)
        } else {
            [0.0; 3]
        }
    }

    /// Multiplies band c's contribution by `f[c]` and its density by `p[c]`
    /// relative to the driving band `h` (whose p[h] is the density used).
    #[inline]
    pub(super) fn scale(&mut self, f: [f64; 3], p: [f64; 3], h: usize) {
        let ph = p[h];
        for c in 0..3 {
            self.beta[c] *= f[c] / ph;
            self.r[c] *= p[c] / ph;
        }
    }

    /// The throughput of a path that carries band b alone from here,
    /// weighing `weight` in it (3 for a band drawn with probability 1/3, 1
    /// for one branch of three): β_b × weight, the other bands 0, mean r kept.
    #[inline]
    pub(super) fn keep_band(&self, b: usize, weight: f64) -> Throughput {
        let mut kept = Throughput { beta: [0.0; 3], r: [0.0; 3] };
        kept.beta[b] = weight * self.beta[b];
        kept.r[b] = 3.0 * self.mean_r();
        kept
    }

    /// Rescales (β, r) so that mean r = 1 (the estimate is unchanged).
    #[inline]
    pub(super) fn normalise(&mut self) {
        let m = self.mean_r();
        if m > 0.0 && m.is_finite() {
            for c in 0..3 {
                self.beta[c] /= m;
                self.r[c] /= m;
            }
        }
    }
}

/// Russian roulette on the estimate's weight β / mean r; false = the path ends.
#[inline]
pub(super) fn roulette(tp: &mut Throughput, settings: &Settings, rng: &mut Rng) -> bool {
    let Some(threshold) = settings.roulette_threshold else {
        return true;
    };
    let e = tp.effective();
    let m = e[0].max(e[1]).max(e[2]);
    if m >= threshold {
        return true;
    }
    let q = m / threshold;
    if rng.next_f64() >= q {
        return false;
    }
    for x in tp.beta.iter_mut() {
        *x /= q;
    }
    true
}
