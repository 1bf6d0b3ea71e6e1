//! The fixed-direction connection (module doc of [`slab`](super),
//! "Explicit connection", "Internal reflections" and "Rough top"): from
//! every scattering event a splat w p(ω_s·ω₂₁) e^{−μ_t ℓ} T/(n² A_o cos θ_t)
//! [1/(m² sr)] at the exit point of ω₂₁, the image terms of a thin slab
//! (the same column folded at the boundaries), their chains of sampled
//! reflections through a rough top, the connection of unscattered light
//! at a rough top, and the Russian roulette of deep connections
//! (`connection_transmittance`, which the ring and lobe connections of
//! modules `ring` and `lobe` share).

use super::boundary::Exit;
use super::kernel::Kernel;
use super::setup::Sensor;
use crate::fresnel;
use crate::interface::{Lobe, Transport};
use crate::rng::Rng;
use glam::DVec3;

/// Longest chain of internal reflections a rough-top connection follows
/// (it stops earlier at 40 optical depths or a weight below 10⁻⁹).
const MAX_CHAIN: usize = 64;

impl Kernel<'_> {
    /// The transmittance of a thick-slab connection at optical depth `tau`
    /// (≤ 40) along ω₂₁, given `e` = e^{τ_r − τ} if τ > τ_r = ROULETTE_DEPTH
    /// and e^{−τ} otherwise; 0 when the connection is rouletted away.
    ///
    /// Russian roulette below τ_r: the connection is made with probability
    /// q = e^{−(τ − τ_r)} and then weighted 1/q, so its transmittance becomes
    /// e^{−τ}/q = e^{−τ_r}. Unbiased; it spares most deep events the phase
    /// evaluation and splat, and the surviving terms are no larger than one
    /// at depth τ_r.
    #[inline]
    pub(super) fn connection_transmittance(&self, tau: f64, e: f64, rng: &mut Rng) -> f64 {
        if tau > self.roulette_depth {
            if rng.next_f64() >= e {
                return 0.0;
            }
            self.roulette_transmittance
        } else {
            e
        }
    }

    /// Splats the connections of a scattering event at `p` (incoming
    /// direction `dir`, weight `w` after albedo) into `image`; returns the
    /// total added. Term 0 goes straight up along ω₂₁; the image terms first
    /// go down along the mirrored direction and/or bounce between the
    /// boundaries (Fresnel factor F per reflection), until their weight is
    /// below 1e-9 of the first term's.
    #[inline]
    pub(super) fn connect(
        &self,
        p: [f64; 3],
        dir: [f64; 3],
        w: f64,
        exit: Exit,
        image: &mut [f64],
        rng: &mut Rng,
    ) -> f64 {
        if self.rough {
            return self.connect_rough(p, dir, w, exit, image, rng);
        }
        let phase = &self.setup.slab.medium.phase;
        let sensor = &self.setup.sensor;
        let depth = -p[2];
        let cos_up = dir[0] * self.w21[0] + dir[1] * self.w21[1] + dir[2] * self.w21[2];
        if !self.image_terms {
            // Thick slab: only the straight-up term, path length |z|/cos θ_t.
            let l = depth * self.inv_cos_t;
            let tau = self.mu_t * l;
            // Below 40 optical depths the term is < e^{-40} ≈ 4e-18 of an
            // event at the surface: skipped.
            if tau > 40.0 {
                return 0.0;
            }
            let Some(i) = sensor.index(p[0] + l * self.w21[0], p[1] + l * self.w21[1]) else {
                return 0.0;
            };
            let e = if tau > self.roulette_depth { (self.roulette_depth - tau).exp() } else { (-tau).exp() };
            let transmittance = self.connection_transmittance(tau, e, rng);
            if transmittance == 0.0 {
                return 0.0;
            }
            let v = w * phase.eval(cos_up) * transmittance * self.splat;
            image[i] += v;
            return v;
        }
        let p_up = phase.eval(cos_up);
        // Straight up: path length |z|/cos θ_t.
        let mut total = self.splat_at(p, depth * self.inv_cos_t, w * p_up, image, sensor);
        let cos_down = cos_up - 2.0 * dir[2] * self.w21[2];
        let p_down = phase.eval(cos_down);
        let mut factor = self.fresnel_t;
        let mut k = 0.0;
        loop {
            // Down first: (2d − |z| + 2kd)/cos θ_t with F^(2k+1).
            let l_down = (2.0 * self.d - depth + 2.0 * k * self.d) * self.inv_cos_t;
            // Up first, after k top-and-bottom round trips: (|z| + 2(k+1)d)/cos θ_t, F^(2k+2).
            let l_up = (depth + 2.0 * (k + 1.0) * self.d) * self.inv_cos_t;
            if self.mu_t * l_down > 40.0 || factor < 1e-9 {
                break;
            }
            total += self.splat_at(p, l_down, w * factor * p_down, image, sensor);
            factor *= self.fresnel_t;
            total += self.splat_at(p, l_up, w * factor * p_up, image, sensor);
            factor *= self.fresnel_t;
            k += 1.0;
        }
        total
    }

    /// [`connect`](Self::connect) through a rough top (module doc, "Rough
    /// top"): ω₂₁ sampled by refracting ω_o into the slab through a sampled
    /// microfacet (radiance weight (1 − F) G1 / n²); in a thin slab the
    /// image terms follow a chain of directions traced backwards from the
    /// exit: the bottom's mirror (F), a sampled internal reflection at the
    /// top (F G1), the bottom's mirror, … Each term splats
    /// w p(ω_s·v) e^{−μ_t L} · c / (A_o |v_z|), v the direction of the
    /// segment the event connects into, L the length to the exit along the
    /// chain, c the product of the chain's weights up to that segment.
    fn connect_rough(&self, p: [f64; 3], dir: [f64; 3], w: f64, exit: Exit, image: &mut [f64], rng: &mut Rng) -> f64 {
        let top = &self.setup.slab.top;
        let phase = &self.setup.slab.medium.phase;
        let sensor = &self.setup.sensor;
        if exit.weight == 0.0 {
            return 0.0;
        }
        let mut up = exit.up;
        let depth = -p[2];
        let dot = |a: [f64; 3]| a[0] * dir[0] + a[1] * dir[1] + a[2] * dir[2];
        if !self.image_terms {
            let l = depth / up[2];
            let tau = self.mu_t * l;
            if tau > 40.0 {
                return 0.0;
            }
            let Some(i) = sensor.index(p[0] + l * up[0], p[1] + l * up[1]) else {
                return 0.0;
            };
            let e = if tau > self.roulette_depth { (self.roulette_depth - tau).exp() } else { (-tau).exp() };
            let transmittance = self.connection_transmittance(tau, e, rng);
            if transmittance == 0.0 {
                return 0.0;
            }
            let v = w * phase.eval(dot(up)) * transmittance * exit.weight / (self.area * up[2]);
            image[i] += v;
            return v;
        }
        // Thin slab. (sx, sy, len): the horizontal displacement and length
        // from the far end of the current segment to the exit point; c the
        // chain's weight up to the current segment.
        let (mut sx, mut sy, mut len, mut c) = (0.0, 0.0, 0.0, exit.weight);
        let mut total = 0.0;
        let splat = |l: f64, v: [f64; 3], sx: f64, sy: f64, len: f64, weight: f64, image: &mut [f64]| -> f64 {
            let Some(i) = sensor.index(p[0] + l * v[0] + sx, p[1] + l * v[1] + sy) else {
                return 0.0;
            };
            let value = weight * (-self.mu_t * (l + len)).exp();
            image[i] += value;
            value
        };
        for _ in 0..MAX_CHAIN {
            if self.mu_t * len > 40.0 || c < 1e-9 * exit.weight {
                break;
            }
            let inv_cz = 1.0 / up[2];
            // Straight up along `up` to the top.
            total += splat(depth * inv_cz, up, sx, sy, len, w * c * phase.eval(dot(up)) * inv_cz / self.area, image);
            // Before `up`: the bottom's mirror reflection of `down`.
            let full = self.d * inv_cz;
            let down = [up[0], up[1], -up[2]];
            (sx, sy, len) = (sx + full * up[0], sy + full * up[1], len + full);
            c *= fresnel::reflectance(up[2], 1.0 / self.n);
            if self.mu_t * len > 40.0 {
                break;
            }
            total += splat(
                (self.d - depth) * inv_cz,
                down,
                sx,
                sy,
                len,
                w * c * phase.eval(dot(down)) * inv_cz / self.area,
                image,
            );
            // Before `down`: a reflection at the rough top, sampled backwards
            // (radiance leaving along `down`).
            let (u1, u2) = rng.next_f64_pair();
            let Some(r) =
                top.sample(DVec3::from_array(down), self.n, Lobe::Reflect, [0.0, u1, u2], Transport::Radiance)
            else {
                break;
            };
            (sx, sy, len) = (sx + full * up[0], sy + full * up[1], len + full);
            c *= r.weight;
            up = (-r.wi).to_array();
        }
        total
    }

    /// The connection of a photon that reaches a rough top from below
    /// without having scattered (module doc, "Rough top"): at the hit point
    /// x (`gap` above `p` along `dir`) it adds
    /// w f_t(ω_o, −dir) / A_o, the outgoing radiance of a flux w arriving
    /// at x, averaged over the pixel (f_t in radiance transport). These
    /// paths have no scattering event to connect from; with a smooth top
    /// they leave in one specular direction only.
    pub(super) fn connect_unscattered(&self, p: [f64; 3], dir: [f64; 3], gap: f64, w: f64, image: &mut [f64]) -> f64 {
        let t = gap / dir[2];
        let Some(i) = self.setup.sensor.index(p[0] + t * dir[0], p[1] + t * dir[1]) else {
            return 0.0;
        };
        let (wo, wi) = (DVec3::from_array(self.omega_o), DVec3::new(-dir[0], -dir[1], -dir[2]));
        let f = self.setup.slab.top.eval(wo, wi, self.n, Transport::Radiance);
        let v = w * f / self.area;
        image[i] += v;
        v
    }

    #[inline]
    fn splat_at(&self, p: [f64; 3], l: f64, weight: f64, image: &mut [f64], sensor: &Sensor) -> f64 {
        let Some(i) = sensor.index(p[0] + l * self.w21[0], p[1] + l * self.w21[1]) else {
            return 0.0;
        };
        let tau = self.mu_t * l;
        if tau > 700.0 {
            return 0.0;
        }
        let v = weight * (-tau).exp() * self.splat;
        image[i] += v;
        v
    }
}
