//! The slab's boundaries: where a photon that reaches one goes
//! (`Kernel::cross`: the Fresnel choice at a smooth boundary, a sampled
//! microfacet at a rough top, [`Interface::sample`]), a path's exit
//! direction and radiance weight for the connections (`Exit`; module doc
//! of [`slab`](super), "Rough top"), the directional albedo of a rough top's
//! reflection (`rough_specular`, reported as `specular_reflectance`) and
//! the refraction into the slab (`refract_z`).

use super::kernel::Kernel;
use crate::fresnel;
use crate::interface::{Interface, Lobe, Transport};
use crate::rng::Rng;
use glam::DVec3;

/// A path's exit direction: the light leaves the slab travelling along
/// `up` = ω₂₁ with the radiance weight W of the exit, (1 − F) G1 / n² for a
/// sample through a rough top (0: lost, no connections) and T(θ_t)/n² for
/// the smooth top's fixed ω₂₁. Drawn once per path through a rough top
/// (`Kernel::launch`), fixed for the smooth one.
#[derive(Debug, Clone, Copy)]
pub(super) struct Exit {
    pub(super) up: [f64; 3],
    pub(super) weight: f64,
    /// 1/cos θ₂₁ (cos θ₂₁ = `up`'s z component).
    pub(super) inv_cos: f64,
    /// The splat constant C = W/(A_o cos θ₂₁) of the thick-slab
    /// connections along `up` (0 when the sample is lost).
    pub(super) splat: f64,
}

impl Exit {
    /// No exit: a rough exit sample that was lost.
    pub(super) const LOST: Exit = Exit { up: [0.0, 0.0, 1.0], weight: 0.0, inv_cos: 1.0, splat: 0.0 };

    /// The exit along `up` (z > 0) with radiance weight `weight`, for
    /// pixels of area `area`.
    pub(super) fn new(up: [f64; 3], weight: f64, area: f64) -> Self {
        let inv_cos = 1.0 / up[2];
        Exit { up, weight, inv_cos, splat: weight * inv_cos / area }
    }
}

/// Where a photon that reached a boundary goes.
pub(super) enum Crossing {
    Reflected,
    /// Out through the top, along this direction in air.
    LeftTop([f64; 3]),
    LeftBottom,
    /// Lost at a rough top (a microfacet sample sent to the wrong side).
    Lost,
}

impl Kernel<'_> {
    /// Moves a photon at `p` travelling along `dir` with weight `w` to the
    /// boundary `gap` ahead (vertically) and samples it there
    /// ([`Interface::sample`], the Fresnel choice): reflected (new direction
    /// and weight), transmitted out of the top (with the direction in air)
    /// or bottom, or lost at a rough top.
    #[inline]
    pub(super) fn cross(&self, p: &mut [f64; 3], dir: &mut [f64; 3], w: &mut f64, gap: f64, rng: &mut Rng) -> Crossing {
        let t_boundary = gap / dir[2].abs();
        let up = dir[2] > 0.0;
        *p = [p[0] + t_boundary * dir[0], p[1] + t_boundary * dir[1], if up { 0.0 } else { -self.d }];
        // The top surface is the slab's boundary; the bottom one is smooth.
        // n_below/n_above: the medium is below the top and above the bottom.
        let (boundary, eta) = if up { (&self.setup.slab.top, self.n) } else { (&Interface::Smooth, 1.0 / self.n) };
        let mut u = [rng.next_f64(), 0.0, 0.0];
        if boundary.numbers() == 3 {
            (u[1], u[2]) = rng.next_f64_pair();
        }
        let wo = DVec3::new(-dir[0], -dir[1], -dir[2]);
        let Some(s) = boundary.sample(wo, eta, Lobe::Fresnel, u, Transport::Importance) else {
            return Crossing::Lost;
        };
        *w *= s.weight;
        if !s.transmitted {
            *dir = s.wi.to_array();
            Crossing::Reflected
        } else if up {
            Crossing::LeftTop(s.wi.to_array())
        } else {
            Crossing::LeftBottom
        }
    }
}

/// The reflectance of a rough top for light arriving from ω_i (the
/// directional albedo of its reflection lobe, not part of the slice): the
/// mean of the reflection weight F G1 over 64 × 64 stratified visible
/// normals (deterministic).
pub(super) fn rough_specular(top: &Interface, omega_i: [f64; 3], n: f64) -> f64 {
    const K: usize = 64;
    let mut sum = 0.0;
    for a in 0..K {
        for b in 0..K {
            let u = [0.0, (a as f64 + 0.5) / K as f64, (b as f64 + 0.5) / K as f64];
            if let Some(s) = top.sample(DVec3::from_array(omega_i), n, Lobe::Reflect, u, Transport::Importance) {
                sum += s.weight;
            }
        }
    }
    sum / (K * K) as f64
}

/// Refraction of the direction of travel `d` from air into the medium of
/// index `n` ≥ 1 through the plane z = 0 (never total internal reflection).
pub(super) fn refract_z(d: [f64; 3], n: f64) -> [f64; 3] {
    fresnel::refract(DVec3::from_array(d), DVec3::Z, n).expect("air → denser medium always refracts").to_array()
}
