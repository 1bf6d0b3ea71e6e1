//! The path walk (module doc of [`slab`](super), "Estimator"): a run's
//! precomputed constants and estimator (`Kernel`, `Strategy`), the launch
//! of a path through the top, its free flights (pdf μ_t e^{−μ_t s}, s in
//! metres), the weight factor μ_s/μ_t and the connection at every
//! scattering event, the boundary crossings (module `boundary`) and the
//! Russian roulette of the weight; batches of paths one at a time here,
//! four at a time in module `lanes`. The connections are in `connection`
//! (the fixed direction), `ring` and `lobe`. Path k of a run draws from the
//! random streams (seed, k) and `aux_stream`, so a result does not depend
//! on the thread count.

use super::beam::Footprint;
use super::boundary::{refract_z, rough_specular, Crossing, Exit};
use super::error::{check, SlabError};
use super::lobe::{lobe_applies, Chain, Junctions, LOBE_REUSE, MAX_LOBE_VERTICES};
use super::options::Estimator;
use super::ring::Ring;
use super::setup::{direction, Setup};
use super::tally::Batch;
use crate::fresnel;
use crate::interface::{Lobe, Transport};
use crate::rng::Rng;
use glam::DVec3;
use std::f64::consts::PI;

/// Each estimator's own state, the payload of its variant.
pub(super) enum Strategy {
    /// [`Estimator::Connection`].
    Connection,
    /// [`Estimator::Ring`]: the sampler of exit azimuths.
    Ring(Ring),
    /// [`Estimator::Lobe`]: the chain length m and the events of a path
    /// that share one chain ([`LOBE_REUSE`]).
    Lobe { vertices: usize, reuse: usize },
    /// [`Estimator::BruteForce`]: the cone's half-angle, cos δ and
    /// 1/(A_o Ω_δ).
    BruteForce { cone_deg: f64, cone_cos: f64, cone_norm: f64 },
}

impl Strategy {
    /// The public name of the estimator.
    pub(super) fn estimator(&self) -> Estimator {
        match self {
            Strategy::Connection => Estimator::Connection,
            Strategy::Ring(_) => Estimator::Ring,
            Strategy::Lobe { vertices, .. } => Estimator::Lobe { vertices: *vertices },
            Strategy::BruteForce { cone_deg, .. } => Estimator::BruteForce { cone_deg: *cone_deg },
        }
    }
}

/// Precomputed constants of a run.
pub(super) struct Kernel<'a> {
    pub(super) setup: &'a Setup,
    pub(super) mu_t: f64,
    /// 1/μ_t, the mean free path [m].
    pub(super) inv_mu_t: f64,
    pub(super) albedo: f64,
    pub(super) n: f64,
    pub(super) d: f64,
    /// Direction of the light entering the slab (refracted −ω_i).
    pub(super) entry_dir: [f64; 3],
    pub(super) entry_weight: f64,
    pub(super) footprint: Footprint<'a>,
    /// The estimator, with its own state.
    pub(super) strategy: Strategy,
    /// ω₂₁, the in-medium direction refracting into ω_o.
    pub(super) w21: [f64; 3],
    /// T(θ_t) / (n² A_o cos θ_t).
    pub(super) splat: f64,
    pub(super) inv_cos_t: f64,
    /// The smooth top's exit (ω₂₁, T/n², 1/cos θ_t, `splat`).
    pub(super) smooth_exit: Exit,
    /// Internal Fresnel reflectance F(θ_t) at either boundary.
    pub(super) fresnel_t: f64,
    /// Whether paths via internal reflections can matter (μ_t d / cos θ_t < 40).
    pub(super) image_terms: bool,
    /// Optical depth below which connections are Russian-rouletted, and
    /// e^{−depth}.
    pub(super) roulette_depth: f64,
    pub(super) roulette_transmittance: f64,
    pub(super) omega_o: [f64; 3],
    /// Fresnel reflectance of the top surface at θ_i (the specular part,
    /// whichever side the photons are launched from).
    pub(super) specular: f64,
    /// Whether the top is rough: sampled entry, crossings and connections
    /// (`launch`, `cross`, `connect_rough`).
    pub(super) rough: bool,
    /// The launch direction (ω_i, or ω_o for the reciprocal ring).
    pub(super) launch: [f64; 3],
    /// Pixel area A_o [m²].
    pub(super) area: f64,
    /// Whether batches run in the vector lanes of [`lanes`](super::lanes).
    #[cfg(target_arch = "x86_64")]
    pub(super) lanes: bool,
}

impl<'a> Kernel<'a> {
    pub(super) fn new(setup: &'a Setup, estimator: Estimator) -> Result<Self, SlabError> {
        let m = &setup.slab.medium;
        let n = m.n;
        let dirs = setup.directions;
        let omega_i = direction(dirs.theta_i_deg, dirs.phi_i_deg);
        let omega_o = direction(dirs.theta_o_deg, dirs.phi_o_deg);
        // The ring launches its photons at normal incidence: from the light
        // when θ_i = 0, else (θ_o = 0) from the camera, by reciprocity.
        let reciprocal = estimator == Estimator::Ring && dirs.theta_i_deg != 0.0;
        if estimator == Estimator::Ring && !Ring::applies(setup) {
            return Err(SlabError::RingNotApplicable);
        }
        let (launch, exit) = if reciprocal { (omega_o, omega_i) } else { (omega_i, omega_o) };
        let incoming = [-launch[0], -launch[1], -launch[2]];
        let entry_dir = refract_z(incoming, n);
        let top = &setup.slab.top;
        let rough = top.is_rough();
        let entry_weight = 1.0 - fresnel::reflectance(launch[2], n);
        let exit_up = [-exit[0], -exit[1], -exit[2]];
        // ω₂₁: refract the exit direction back into the medium and reverse (upward).
        let down = refract_z(exit_up, n);
        let w21 = [-down[0], -down[1], -down[2]];
        let cos_t = w21[2];
        let t_out = 1.0 - fresnel::reflectance(cos_t, 1.0 / n);
        let area = setup.sensor.pixel_m * setup.sensor.pixel_m;
        // The smooth top's one exit; the connections' constants are its.
        let smooth_exit =
            Exit { up: w21, weight: t_out / (n * n), inv_cos: 1.0 / cos_t, splat: t_out / (n * n * area * cos_t) };
        let strategy = match estimator {
            Estimator::Connection => Strategy::Connection,
            Estimator::BruteForce { cone_deg } => {
                check("cone_deg", cone_deg, cone_deg > 0.0 && cone_deg < 90.0, "must lie in (0°, 90°)")?;
                let c = cone_deg.to_radians().cos();
                Strategy::BruteForce { cone_deg, cone_cos: c, cone_norm: 1.0 / (area * 2.0 * PI * (1.0 - c)) }
            }
            Estimator::Lobe { vertices } => {
                check("lobe_vertices", vertices as f64, vertices <= MAX_LOBE_VERTICES, "must lie in 0 … 32")?;
                if !lobe_applies(setup) {
                    return Err(SlabError::LobeNotApplicable);
                }
                Strategy::Lobe { vertices, reuse: LOBE_REUSE }
            }
            Estimator::Ring => {
                let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                let target = if sin_t > 0.0 { (w21[0] / sin_t, w21[1] / sin_t) } else { (1.0, 0.0) };
                Strategy::Ring(Ring::new(&m.phase, cos_t, if reciprocal { -1.0 } else { 1.0 }, target))
            }
        };
        Ok(Self {
            setup,
            mu_t: m.mu_t_per_m(),
            inv_mu_t: 1.0 / m.mu_t_per_m(),
            albedo: m.albedo(),
            n,
            d: setup.slab.thickness_m,
            entry_dir,
            entry_weight,
            footprint: setup.beam.footprint(dirs.theta_i_deg, dirs.phi_i_deg),
            strategy,
            w21,
            splat: smooth_exit.splat,
            inv_cos_t: smooth_exit.inv_cos,
            smooth_exit,
            fresnel_t: 1.0 - t_out,
            // Through a rough top the image terms' directions vary, but every
            // one of them crosses the slab at least once (τ ≥ μ_t d).
            image_terms: m.mu_t_per_m() * setup.slab.thickness_m / if rough { 1.0 } else { cos_t } < 40.0,
            roulette_depth: ROULETTE_DEPTH,
            roulette_transmittance: (-ROULETTE_DEPTH).exp(),
            omega_o,
            specular: if rough { rough_specular(top, omega_i, n) } else { fresnel::reflectance(omega_i[2], n) },
            rough,
            launch,
            area,
            #[cfg(target_arch = "x86_64")]
            lanes: matches!(estimator, Estimator::Connection | Estimator::Ring | Estimator::Lobe { .. })
                && crate::simd::available(),
        })
    }

    /// Entry point on the surface.
    #[inline]
    fn entry_point(&self, rng: &mut Rng) -> (f64, f64) {
        self.footprint.sample(rng)
    }

    /// A path's start: position on the surface, direction into the slab,
    /// weight (1 − F for the smooth top; through a rough top the direction
    /// is sampled, two more random numbers) and the path's exit direction
    /// for the connections (rough top: sampled, two more numbers). `None`
    /// when a rough entry sample is lost (the path then contributes
    /// nothing).
    #[inline]
    pub(super) fn launch(&self, rng: &mut Rng) -> Option<([f64; 3], [f64; 3], f64, Exit)> {
        // The ring launches at the origin and lays the beam's footprint on
        // each splat instead.
        let (x0, y0) = if let Strategy::Ring(_) = self.strategy { (0.0, 0.0) } else { self.entry_point(rng) };
        if !self.rough {
            return Some(([x0, y0, 0.0], self.entry_dir, self.entry_weight, self.smooth_exit));
        }
        let top = &self.setup.slab.top;
        let u = [0.0, rng.next_f64(), rng.next_f64()];
        let s = top.sample(DVec3::from_array(self.launch), self.n, Lobe::Transmit, u, Transport::Importance)?;
        // The radiance leaving along ω_o comes from −ω_i of this sample: the
        // light leaves the slab travelling along `up` = −ω_i.
        let u = [0.0, rng.next_f64(), rng.next_f64()];
        let exit = match top.sample(DVec3::from_array(self.omega_o), self.n, Lobe::Transmit, u, Transport::Radiance) {
            Some(e) => Exit::new((-e.wi).to_array(), e.weight, self.area),
            None => Exit::LOST,
        };
        Some(([x0, y0, 0.0], s.wi.to_array(), s.weight, exit))
    }

    /// Traces one path, adding to `image`; returns (path total, events,
    /// reflected weight, transmitted weight).
    /// `rng` drives the walk (launch, flights, scattering angles, boundary
    /// choices), `aux` everything else (connections, their roulette, the
    /// weight roulette): see [`aux_stream`].
    fn trace(&self, rng: &mut Rng, aux: &mut Rng, image: &mut [f64], chain: &mut Chain) -> (f64, u64, f64, f64) {
        let phase = &self.setup.slab.medium.phase;
        let sensor = &self.setup.sensor;
        let Some((mut p, mut dir, mut w, exit)) = self.launch(rng) else {
            return (0.0, 0, 0.0, 0.0);
        };
        let mut total = 0.0;
        let mut events = 0u64;
        // The lobe connection's MIS history of this walk.
        let mut junctions = Junctions::new();
        chain.restart();
        loop {
            let s = -(1.0 - rng.next_f64()).ln() * self.inv_mu_t;
            // The angles of this event's scattering, drawn first: they need
            // only random numbers, and their latency overlaps the flight and
            // the connection. (On a boundary hit they are discarded.)
            let (u1, u2) = rng.next_f64_pair();
            let angles = phase.sample_angles(u1, u2);
            // The boundary ahead is hit when s ≥ gap/|d_z|, tested as
            // s·|d_z| ≥ gap: the division is needed only on a hit (rare).
            let dz = dir[2];
            let gap = if dz < 0.0 { p[2] + self.d } else { -p[2] };
            if dz != 0.0 && s * dz.abs() >= gap {
                if self.rough
                    && events == 0
                    && dz > 0.0
                    && matches!(self.strategy, Strategy::Connection | Strategy::Lobe { .. })
                {
                    total += self.connect_unscattered(p, dir, gap, w, image);
                }
                match self.cross(&mut p, &mut dir, &mut w, gap, rng) {
                    Crossing::Reflected => {
                        junctions.from_scatter = false;
                        continue;
                    }
                    Crossing::Lost => return (total, events, 0.0, 0.0),
                    Crossing::LeftTop(out) => {
                        if let Strategy::BruteForce { cone_cos, cone_norm, .. } = self.strategy {
                            let c = out[0] * self.omega_o[0] + out[1] * self.omega_o[1] + out[2] * self.omega_o[2];
                            if c >= cone_cos
                                && let Some(i) = sensor.index(p[0], p[1])
                            {
                                let v = w * cone_norm / out[2];
                                image[i] += v;
                                total += v;
                            }
                        }
                        return (total, events, w, 0.0);
                    }
                    Crossing::LeftBottom => return (total, events, 0.0, w),
                }
            }
            p = [p[0] + s * dir[0], p[1] + s * dir[1], p[2] + s * dir[2]];
            events += 1;
            w *= self.albedo;
            match &self.strategy {
                Strategy::Ring(ring) => total += self.connect_ring(ring, p, dir, w, image, aux),
                Strategy::Connection => total += self.connect(p, dir, w, exit, image, aux),
                &Strategy::Lobe { vertices, reuse } => {
                    junctions.arrive();
                    total += self.connect_lobe((vertices, reuse), p, dir, w, &exit, &junctions, chain, image, aux);
                    junctions.scatter(phase.eval(angles.cos_theta));
                }
                Strategy::BruteForce { .. } => {}
            }
            dir = angles.turn(dir);
            if w < 0.1 && !survives_roulette(&mut w, aux) {
                return (total, events, 0.0, 0.0);
            }
        }
    }

    /// Traces paths `first_path` … `first_path + paths − 1` of `seed`: four
    /// at a time in vector lanes where the CPU allows and the estimator is
    /// the connection ([`lanes`](super::lanes)), otherwise one at a time. The two agree to
    /// rounding.
    /// `image` is a buffer to reuse (its contents are discarded).
    pub(super) fn batch(&self, seed: u64, first_path: u64, paths: u64, image: Vec<f64>) -> Batch {
        #[cfg(target_arch = "x86_64")]
        if self.lanes {
            // SAFETY: `lanes` is set only when the CPU has AVX2 and FMA.
            return unsafe { self.batch_lanes(seed, first_path, paths, image) };
        }
        self.batch_scalar(seed, first_path, paths, image)
    }

    /// The name of the kernel [`batch`](Self::batch) uses (see [`Slice::kernel`](super::Slice::kernel)).
    pub(super) fn name(&self) -> &'static str {
        #[cfg(target_arch = "x86_64")]
        if self.lanes {
            return "avx2-fma lanes";
        }
        "scalar"
    }

    /// [`batch`](Self::batch) one path at a time.
    pub(super) fn batch_scalar(&self, seed: u64, first_path: u64, paths: u64, image: Vec<f64>) -> Batch {
        let mut b = Batch::new(image, self.setup.sensor.pixels);
        let mut chain = Chain::new();
        for k in 0..paths {
            let mut rng = Rng::new(seed, first_path + k);
            let mut aux = aux_stream(seed, first_path + k);
            let (t, e, r, tr) = self.trace(&mut rng, &mut aux, &mut b.image, &mut chain);
            b.path_sum += t;
            b.path_sq += t * t;
            b.events += e;
            b.reflected += r;
            b.transmitted += tr;
        }
        b
    }
}

/// The second random stream of path `path`: connections, their roulette
/// and the weight roulette draw from it, the walk itself (launch, flights,
/// scattering angles, boundary choices) from `Rng::new(seed, path)`. How
/// many numbers those draw depends on μ_t and the weight, so in one stream
/// they would shift the walk's numbers whenever a coefficient changes; kept
/// apart, the walks of slightly different slabs traced with one seed stay
/// alike ([`simulate_coupled`](super::simulate_coupled)).
#[inline]
pub(super) fn aux_stream(seed: u64, path: u64) -> Rng {
    Rng::new(seed ^ 0x5eed_a0c5_11ce_5a17, path)
}

/// Russian roulette on a path's weight `w` < 0.1: survives with probability
/// w/0.1 and then carries weight 0.1 (unbiased).
#[inline]
pub(super) fn survives_roulette(w: &mut f64, rng: &mut Rng) -> bool {
    if rng.next_f64() >= *w / 0.1 {
        return false;
    }
    *w = 0.1;
    true
}

/// Optical depth (along ω₂₁) below which connections are Russian-rouletted
/// (see `Kernel::connect`): a surviving term weighs e^{−8} ≈ 3.4e-4 of an
/// unattenuated one, so the added variance is negligible.
const ROULETTE_DEPTH: f64 = 8.0;
