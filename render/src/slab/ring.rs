//! **Ring connection** ([`Estimator::Ring`], the default where it applies).
//! The fixed-direction connection converges in its sum but not pixel by
//! pixel: its value at an event is p(ω_s·ω₂₁), and for a forward-peaked
//! medium only the rare photons already travelling within the phase
//! function's lobe around ω₂₁ (a few degrees) contribute. With the
//! Lorenz–Mie table of IOL1068-09 at 550 nm, 4π∫p² dω = 105 (p(0°) =
//! 21 /sr, half the scattering within 5°): replacing p by 1/(4π) in the
//! connection (a biased diagnostic) cut the per-pixel error 0.5–3 mm from
//! the beam from 60 % to 19 % at 10⁵ paths. (A detector cone of ≤ 1°
//! averages p over 0.63° in the medium and leaves 4π∫p̄² at 105; 933 → 868
//! for the PVP of IOL1068-13 — so the cone and its MIS with phase-sampled
//! exits were measured not to pay and are not implemented.)
//! The ring uses the one symmetry left: when light enters at normal
//! incidence the slab is symmetric about the normal through the entry
//! point, so the response at exit azimuth φ equals the response at the
//! wanted azimuth φ_t with the exit point rotated by φ_t − φ about the entry
//! point. Every direction on the ring of the exit polar angle θ_t is
//! therefore a valid connection direction; the photon's lobe meets a ring
//! far more often than a point. Per event the ring connection draws exit
//! azimuths from a table shaped like p along the ring (see `Ring`), splats
//! w p e^{−μ_t ℓ} T/(n² A_o cos θ_t) / (2π pdf_φ) — the same factors as
//! the fixed direction, ℓ = |z|/cos θ_t being the same for every azimuth —
//! at the rotated exit point, and averages [`RING_SPLATS`] such azimuths
//! (stratified). The beam is not rotation-symmetric, so photons start at
//! the origin and the beam's footprint is laid on by convolution: the splat
//! goes to the pixel of b + Δ with b drawn from the footprint (E over b of
//! the pixel indicator is the footprint integrated over the pixel, which is
//! exactly the convolution the slice is). Normal incidence is needed on the
//! launch side only: for θ_o = 0 (the lab's 45°/0°) the photons are
//! launched from the camera's side by reciprocity, f(x_i, ω_i; x_o, ω_o) =
//! f(x_o, ω_o; x_i, ω_i), the connection aims at ω_i, and the splat goes to
//! b − Δ (h(Δ) = f(0, ω_o; Δ, ω_i), so the slice at x is E_b h(b − x)). It
//! needs a thick slab (no image terms, μ_t d / cos θ_t ≥ 40) and one of
//! θ_i, θ_o equal to 0; [`Estimator::best_for`] falls back to the lobe
//! connection (below) or the fixed direction otherwise. Tested pixel by pixel against the fixed-direction
//! connection, against brute force, and in a white furnace.
//!

use super::kernel::Kernel;
use super::setup::Setup;
use crate::phase::Phase;
use crate::rng::Rng;
use std::f64::consts::PI;

/// Azimuths per ring connection (see the module doc): stratified in the
/// sampler's CDF, sharing one footprint point. Measured on IOL1068-09
/// (45°/0°, 10⁵ paths), median relative error of the pixels 0.5–3 mm from
/// the beam: 38 % with 1 azimuth, 22 % with 4, 13 % with 16, 11 % with 32;
/// 16 costs about 4× the CPU time of the fixed-direction connection per
/// path (1 azimuth: 1.6×) and gave the smallest error² × time; one footprint
/// point per connection instead of one per azimuth cost 25 % less time for
/// 3 % more error.
pub const RING_SPLATS: usize = 16;

impl Kernel<'_> {
    /// The ring connection of a scattering event at `p` (photon launched at
    /// the origin; incoming direction `dir`, weight `w` after albedo): an
    /// exit azimuth drawn by the ring's sampler, the splat rotated to the
    /// wanted azimuth and shifted by a point of the beam's footprint (see
    /// the module doc). Thick slabs only (no image terms). Returns the value
    /// added.
    #[inline]
    pub(super) fn connect_ring(
        &self,
        ring: &Ring,
        p: [f64; 3],
        dir: [f64; 3],
        w: f64,
        image: &mut [f64],
        rng: &mut Rng,
    ) -> f64 {
        let l = -p[2] * self.inv_cos_t;
        let tau = self.mu_t * l;
        if tau > 40.0 {
            return 0.0;
        }
        let e = if tau > self.roulette_depth { (self.roulette_depth - tau).exp() } else { (-tau).exp() };
        let transmittance = self.connection_transmittance(tau, e, rng);
        if transmittance == 0.0 {
            return 0.0;
        }
        let c_s = dir[2];
        let h = (dir[0] * dir[0] + dir[1] * dir[1]).sqrt();
        let (hx, hy) = if h > 1e-300 { (dir[0] / h, dir[1] / h) } else { (1.0, 0.0) };
        let (tx, ty) = ring.target;
        let base = w * transmittance * self.splat / (PI * RING_SPLATS as f64);
        let u0 = rng.next_f64();
        // One random bit per splat for the sign of ψ.
        let mut signs = rng.next_u64();
        let mut total = 0.0;
        let (bx, by) = self.footprint.sample(rng);
        for k in 0..RING_SPLATS {
            // Stratified in the sampler's CDF: u_k = (k + u0)/K.
            let (psi, density) = ring.sample_psi(c_s, (k as f64 + u0) * (1.0 / RING_SPLATS as f64));
            let (mut sin_psi, cos_psi) = crate::phase::sin_cos_turns(psi * (0.5 / PI));
            if signs & 1 == 1 {
                sin_psi = -sin_psi;
            }
            signs >>= 1;
            // Exit azimuth: the photon's own azimuth turned by ±ψ.
            let (ex, ey) = (hx * cos_psi - hy * sin_psi, hx * sin_psi + hy * cos_psi);
            let cos_gamma = c_s * ring.cos_t + h * ring.sin_t * cos_psi;
            // f/(2π pdf_φ) with pdf_φ = density/2 over the full turn.
            let v = base * self.setup.slab.medium.phase.eval(cos_gamma) / density;
            // The exit point, rotated about the launch point from the drawn
            // azimuth to the wanted one, then moved by a footprint point.
            let (dx, dy) = (p[0] + l * ring.sin_t * ex, p[1] + l * ring.sin_t * ey);
            let (c, s) = (tx * ex + ty * ey, ex * ty - ey * tx);
            let (rx, ry) = (c * dx - s * dy, s * dx + c * dy);
            if let Some(i) = self.setup.sensor.index(bx + ring.sign * rx, by + ring.sign * ry) {
                image[i] += v;
                total += v;
            }
        }
        total
    }
}

/// The ring connection's geometry and its sampler of exit azimuths.
///
/// For a photon travelling along ω_s (z component c_s) the connection
/// directions of polar angle θ_t form a ring; ψ is the azimuth of a ring
/// direction relative to the photon's own, and the phase function there is
/// p(c_s cos θ_t + √(1 − c_s²) sin θ_t cos ψ). The sampler is a table over
/// c_s (256 rows) of piecewise-constant densities in ψ ∈ [0, π] (128 bins),
/// each bin's value the largest of p at 3 × 3 points of the (c_s, ψ) cell,
/// floored at 10⁻³ of the row mean so no bin is empty. Any such density
/// keeps the estimator unbiased (the splat divides by the density actually
/// used); its closeness to p only sets the variance.
pub(super) struct Ring {
    /// +1: photons launched from the light (θ_i = 0); −1: from the camera
    /// (θ_o = 0), the splat point reflected through the origin.
    pub(super) sign: f64,
    /// Horizontal unit vector of the wanted exit direction (the ω₂₁ of the
    /// launch's exit side).
    pub(super) target: (f64, f64),
    pub(super) cos_t: f64,
    pub(super) sin_t: f64,
    /// Per row, the density per radian of each bin, and the CDF at the bin
    /// ends (`BINS + 1` values from 0 to 1).
    pub(super) density: Vec<f64>,
    pub(super) cdf: Vec<f64>,
}

impl Ring {
    const ROWS: usize = 256;
    const BINS: usize = 128;

    /// Whether the ring connection is exact for `setup`: exactly one of
    /// θ_i, θ_o is 0 (the launch at normal incidence is symmetric about the
    /// normal; when both are 0 the ring is a point and brings nothing) and
    /// the slab is thick along the other (no image terms).
    pub(super) fn applies(setup: &Setup) -> bool {
        // A rough top's exit directions have no fixed polar angle.
        if setup.slab.top.is_rough() {
            return false;
        }
        let d = &setup.directions;
        let other = if d.theta_i_deg == 0.0 {
            d.theta_o_deg
        } else if d.theta_o_deg == 0.0 {
            d.theta_i_deg
        } else {
            return false;
        };
        if other == 0.0 {
            return false;
        }
        let m = &setup.slab.medium;
        let sin_t = other.to_radians().sin() / m.n;
        let cos_t = (1.0 - sin_t * sin_t).sqrt();
        m.mu_t_per_m() * setup.slab.thickness_m / cos_t >= 40.0
    }

    pub(super) fn new(phase: &Phase, cos_t: f64, sign: f64, target: (f64, f64)) -> Self {
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let (rows, bins) = (Self::ROWS, Self::BINS);
        let d_psi = PI / bins as f64;
        let mut density = Vec::with_capacity(rows * bins);
        let mut cdf = Vec::with_capacity(rows * (bins + 1));
        for r in 0..rows {
            let c_lo = -1.0 + 2.0 * r as f64 / rows as f64;
            let c_hi = -1.0 + 2.0 * (r + 1) as f64 / rows as f64;
            let row: Vec<f64> = (0..bins)
                .map(|b| {
                    let mut best: f64 = 0.0;
                    for c in [c_lo, 0.5 * (c_lo + c_hi), c_hi] {
                        let sc = (1.0 - c * c).max(0.0).sqrt();
                        for k in 0..3 {
                            let psi = (b as f64 + 0.5 * k as f64) * d_psi;
                            best = best.max(phase.eval(c * cos_t + sc * sin_t * psi.cos()));
                        }
                    }
                    best
                })
                .collect();
            let floor = 1e-3 * row.iter().sum::<f64>() / bins as f64;
            let row: Vec<f64> = row.into_iter().map(|v| v.max(floor).max(1e-300)).collect();
            let total: f64 = row.iter().sum::<f64>() * d_psi;
            let mut acc = 0.0;
            cdf.push(0.0);
            for v in row {
                density.push(v / total);
                acc += v / total * d_psi;
                cdf.push(acc);
            }
            *cdf.last_mut().expect("a row has bins") = 1.0;
        }
        Self { sign, target, cos_t, sin_t, density, cdf }
    }

    /// ψ ∈ [0, π] drawn from the row of `c_s` with `u` ∈ [0, 1), and its
    /// density per radian.
    #[inline]
    pub(super) fn sample_psi(&self, c_s: f64, u: f64) -> (f64, f64) {
        let (rows, bins) = (Self::ROWS, Self::BINS);
        let r = (((c_s + 1.0) * 0.5 * rows as f64) as usize).min(rows - 1);
        let cdf = &self.cdf[r * (bins + 1)..(r + 1) * (bins + 1)];
        let b = (cdf.partition_point(|c| *c <= u).max(1) - 1).min(bins - 1);
        let width = cdf[b + 1] - cdf[b];
        let f = if width > 0.0 { ((u - cdf[b]) / width).clamp(0.0, 1.0) } else { 0.5 };
        ((b as f64 + f) * PI / bins as f64, self.density[r * bins + b])
    }

    /// The density of [`sample_psi`](Self::sample_psi) at ψ for `c_s` (for
    /// tests).
    #[cfg(test)]
    pub(super) fn density_at(&self, c_s: f64, psi: f64) -> f64 {
        let (rows, bins) = (Self::ROWS, Self::BINS);
        let r = (((c_s + 1.0) * 0.5 * rows as f64) as usize).min(rows - 1);
        let b = ((psi / PI * bins as f64) as usize).min(bins - 1);
        self.density[r * bins + b]
    }
}
