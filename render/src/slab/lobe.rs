//! **Lobe connection** ([`Estimator::Lobe`], the default where the ring
//! does not apply and the slab is thick). When neither θ_i nor θ_o is 0
//! (the lab's 45°/15°) there is no symmetry to use. Instead the connection
//! is combined, by multiple importance sampling over the last few events of
//! the path, with chains of events drawn *backwards from the camera*
//! through the phase function's lobe around ω₂₁.
//!
//! *Two vertices (m = 1).* Let x_k be a scattering event, ω_k the
//! photon's direction arriving there, w_k its weight after the factor
//! μ_s/μ_t. By a straight flight the walk reaches its next event
//! x′ = x_k + t ω′ with density p_A(ω′) μ_t e^{−μ_t t} per steradian and
//! metre, p_A = p(ω_k·ω′), if x′ lies inside the slab (else it meets a
//! boundary first), with weight w_k μ_s/μ_t in expectation over the
//! roulette at x_k; its connection is worth p_B(ω′) e^{−μ_t ℓ′} C 1{x_o′ ∈
//! pixel}, p_B = p(ω′·ω₂₁), ℓ′ = |z′|/cos θ_t, x_o′ = x′ + ℓ′ ω₂₁,
//! C = T/(n² A_o cos θ_t) as above. The expected connection of the next
//! event, given x_k, is therefore
//!
//! I_k = w_k (μ_s/μ_t) ∫_{S²} ∫_{x′ ∈ slab} p_A(ω′) p_B(ω′) μ_t e^{−μ_t t} e^{−μ_t ℓ′} C 1{x_o′ ∈ pixel} dt dω′.
//!
//! Strategy A is the walk itself, (ω′, t) from p_A μ_t e^{−μ_t t};
//! strategy B draws ω′ from p_B — the phase function's sampler with ω₂₁ as
//! the incident direction, density p(ω′·ω₂₁), whose forward lobe
//! ω′ ≈ ω₂₁ holds the photons the connection needs — and t from
//! μ_t e^{−μ_t t}. The distance density is common, so the balance
//! heuristic (Veach & Guibas 1995) weighs a sample by p_A/(p_A + p_B) or
//! p_B/(p_A + p_B), and either sample is worth
//! w_k (μ_s/μ_t) e^{−μ_t ℓ′} C / (1/p_A + 1/p_B) at the pixel of x_o′: at
//! most min(p_A, p_B) times the rest, where the fixed-direction connection
//! had p_B alone. In effect the estimator sees the phase function convolved
//! with itself (for Henyey–Greenstein g exactly HG with g², by the
//! Funk–Hecke theorem), a lower and wider lobe.
//!
//! *m vertices.* The same holds for longer chains. Number the path's
//! scattering events v_1 … v_n and its directions ω_1 (the refracted beam)
//! … ω_n, ω_{n+1} = ω₂₁; the path's phase factors are φ_a = p(ω_a·ω_{a+1})
//! at its junctions a = 1 … n. Strategy j (0 ≤ j ≤ m) lets the walk draw
//! the directions up to ω_{n−j} and draws ω_n, ω_{n−1}, …, ω_{n−j+1}
//! backwards from ω₂₁ (each from p(·ω_{a+1}), density φ_a) with
//! exponential distances; the one factor no strategy samples is φ_{n−j},
//! the connection at v_{n−j}. Its pdf is Π_a φ_a / φ_{n−j}, so the balance
//! heuristic weighs strategy j by (1/φ_{n−j}) / S with S = Σ_i 1/φ_{n−i}
//! over the strategies that can produce the path, and every sample, of
//! whichever strategy, is worth
//!
//! w (μ_s/μ_t)^j e^{−μ_t ℓ} C / S at the pixel where the path leaves,
//!
//! w the walk's weight at v_{n−j} and (μ_s/μ_t)^j the drawn events'
//! albedo: at most the smallest phase value over the path's last m + 1
//! junctions, the lobe (m + 1)-fold convolved (HG: g^{m+1}). A strategy
//! can produce the path when the j drawn flights stay inside the slab and
//! the walk's flights it takes over went straight from event to event:
//! strategy i is counted for i ≤ min(m, r) with r the number of trailing
//! straight flights of the path (the first flight, from the entry, and a
//! flight after a reflection at a boundary are not straight — only the
//! walk reaches those; weights need to add up to 1 only where the
//! strategies have density). In the kernel every event v_k of the walk
//! connects (strategy 0, S over its own last min(m, r_k) + 1 junctions,
//! the walk keeping 1/φ of its last scattering angles), and uses one
//! chain (drawn for it or, see "Chain reuse", shared with earlier events
//! of the path) of m directions and distances from ω₂₁ whose first j links make
//! strategy j's path v_k → … → exit, j = 1 … m (its S: the chain's j
//! sampled junctions, the connection p(ω_k·ω^c_j) at v_k, and the walk's
//! last min(m − j, r_k) junctions). A chain that leaves the slab adds
//! nothing for that j (the walk meets the boundary there). The chains use
//! the weight w_k before the roulette at v_k (whose expectation it is).
//! The depth roulette and the 40-optical-depth cut apply to each exit point
//! as to the connection; the chain decides its roulette before drawing any
//! direction, from the lower bound τ_lb = μ_t (|z_k| − Σ t)/cos θ_t of
//! every one of its exit depths (|ω_z| ≤ 1): kept with probability
//! q = e^{−(τ_lb − τ_r)} and weighted 1/q, so no term exceeds e^{−τ_r} of an
//! unattenuated one. Splat geometry: the exit point is the chain's end
//! v_k + Σ_{i ≤ j} t_i ω^c_i moved by ℓ ω₂₁, ℓ its depth / cos θ_t, with
//! the connection's constant C. Needs a thick slab (μ_t d / cos θ_t ≥ 40:
//! no image terms, which the chains' straight flights would miss);
//! [`Estimator::best_for`] falls back to the fixed direction otherwise.
//! Tested pixel by pixel against the fixed-direction connection, against
//! brute force, its standard errors against the spread over seeds, and in
//! a white furnace.
//!
//! *Through a rough top.* There the radiance leaving towards ω_o is
//! L_o(x_o) = E_{ω′}[W(ω′) L_in(x_o, ω′)] over the ω′ a path draws at its
//! launch from the surface alone ("Rough top" above; W = (1 − F) G1/n²).
//! Given ω′, ω₂₁ = −ω′ is fixed for the whole path, and L_in(x_o, ω′) is
//! the smooth case's transport integral with that ω₂₁: the walk's density
//! is unchanged, each chain is drawn from ω₂₁ and random numbers alone (and
//! one chain serves one path, so a chain never outlives its ω′), hence every
//! strategy's density and the balance weights above hold as they stand, with
//! T/n² replaced by W and cos θ_t by cos θ₂₁ = ω₂₁·z. The path's splats are
//! then an unbiased estimate of W L_in(x_o, ω′) given ω′, and their
//! expectation over ω′ is L_o. So per path: ℓ = |z|/cos θ₂₁, the chain's
//! skip and roulette bound τ_u and its transmittance factors s_j take
//! μ_t/cos θ₂₁, and C = W/(A_o cos θ₂₁) (`Exit`); a lost ω′ (W = 0) adds
//! nothing. Thick here means μ_t d ≥ 40, which bounds μ_t d/cos θ₂₁ for
//! every ω′ (the rough connection's own test for image terms). Light that
//! reaches the rough top from below unscattered keeps its connection at the
//! top (f_t, "Rough top"). Tested (`render/tests/slab_rough.rs`): pixel by
//! pixel against the rough fixed-direction connection (α = 0.3 and 0.8,
//! where W and cos θ₂₁ are far from the smooth T/n² and cos θ_t), against
//! brute force at α = 0.05 and 0.3, its standard errors against the spread
//! over 30 seeds, and the lane kernel against the scalar one.
//!
//! *Chain reuse* ([`LOBE_REUSE`]). A chain is drawn from ω₂₁ and random
//! numbers alone, never from the photon, so one chain may serve K
//! consecutive events of a path: the chain is redrawn at the path's events
//! 1, K + 1, 2K + 1, … (a schedule that looks at the event count only,
//! never at the chain) and drawn lazily, when the first event of its turn
//! that needs it arrives (its distances first, its directions once the
//! roulette has kept it). At event k the chain in use was made from
//! uniforms that no decision of the walk up to k has seen, and the walk's
//! later flights, scatterings and roulettes take later numbers of the
//! stream and never look at the chain (the chain's own roulette takes its
//! own number and changes only its splats); so given the walk up to k the
//! chain is distributed exactly as a fresh one, the expected sum of event
//! k's terms is the I_k above, and the path's total stays unbiased by
//! linearity. Terms of different events of one path are correlated through
//! their shared chain, but paths stay independent, so the per-path totals
//! (the sum's error) and the batch means (the per-pixel errors) are still
//! i.i.d. and the reported errors stay right (tested against the spread
//! over seeds). What a chain costs per draw — m logarithms, m phase samples
//! and values, m turns and the transmittance factors — is then paid once
//! per K events; per event and link remain the inside test, the pixel, the
//! phase value at the junction with the event, p(ω_k·ω^c_j), and a
//! division. The transmittance factors: the exit of link j lies
//! τ_j = τ_u + s_j optical depths deep, τ_u = μ_t (|z_k| − Σ t)/cos θ_t
//! the event's part (the roulette's lower bound) and
//! s_j = μ_t (Σ t − D_{j,z})/cos θ_t ≥ 0 the chain's (D_j = Σ_{i ≤ j} t_i ω^c_i),
//! so e^{−τ_j} = e^{−τ_u} e^{−s_j} takes one exponential per event (after the
//! roulette e^{−τ_u}/q = e^{−τ_r}), e^{−s_j} stored with the chain.
//!

use super::boundary::Exit;
use super::kernel::Kernel;
use super::setup::Setup;
use crate::phase::Phase;
use crate::rng::Rng;

/// Camera-side vertices of the lobe connection by default (see the module
/// doc, "Lobe connection"; [`Estimator::Lobe`](super::Estimator::Lobe)). Measured on IOL1068-09
/// (Lorenz–Mie, 45°/15°, 117 px of 0.1029 mm, 20 s runs on a loaded
/// machine), the median per-pixel variance × paths fell from 70 k (the
/// fixed-direction connection) to 35 k, 24 k, 12.7 k, 5.4 k and 1.9 k for
/// m = 1, 2, 4, 8, 16 while the time per path grew 1.9×, 2.3×, 3.9×, 7.0×
/// and 15× (the lane kernel of the connection against the scalar one):
/// median² × time 2.4× lower than the connection's at m = 16, 1.8× at 8,
/// 1.0× at 1. Longer chains still gain a little (30 s runs: variance ×
/// paths 2.4 k, 1.1 k, 0.77 k and median² × time 2.7, 2.3, 2.2 s for
/// m = 16, 24, 32), but a round of 32 batches then takes tens of seconds
/// on a loaded machine, which a time-limited run overshoots: 16 is kept.
/// (Those figures are for a chain drawn at every event. With one chain a
/// path, [`LOBE_REUSE`], and the lane kernel, 20 s runs on 1 Dec 2026 gave
/// median² × time 2.7, 1.4, 1.7 and 1.6 s for m = 8, 16, 24, 32: 16 is
/// still the best.)
pub const LOBE_VERTICES: usize = 16;

/// The most camera-side vertices [`Estimator::Lobe`](super::Estimator::Lobe) accepts.
pub const MAX_LOBE_VERTICES: usize = 32;

/// Events of a path that share one chain of the lobe connection (module
/// doc, "Chain reuse"); `usize::MAX`: one chain for the whole path.
/// Measured side by side on IOL1068-09 (Lorenz–Mie, 45°/15°, m = 16, 117 px
/// of 0.1029 mm, lane kernel, 20 s each on a loaded machine, 1 Dec 2026):
/// redrawn every K = 1, 2, 4, 8 events and once a path, the paths/s were
/// 667, 1113, 1728, 2205, 2865, the median per-pixel variance × paths
/// 1.9 k, 2.6 k, 3.6 k, 4.3 k, 5.0 k (the shared chain correlates a
/// path's events) and median² × time 2.89, 2.37, 2.09, 1.94, 1.73 s: the
/// time a chain saves outweighs the correlation all the way to one chain a
/// path.
pub const LOBE_REUSE: usize = usize::MAX;

/// Whether the lobe connection is exact for `setup`: a slab at least 40
/// optical depths thick along the exit direction (no image terms; the
/// chains do not reflect). Through a rough top the exit direction ω₂₁ is
/// drawn per path and μ_t d / cos θ₂₁ ≥ μ_t d, so μ_t d ≥ 40 is asked (the
/// rough connection's own test for image terms).
pub(super) fn lobe_applies(setup: &Setup) -> bool {
    let m = &setup.slab.medium;
    let tau_d = m.mu_t_per_m() * setup.slab.thickness_m;
    if setup.slab.top.is_rough() {
        return tau_d >= 40.0;
    }
    let sin_t = setup.directions.theta_o_deg.to_radians().sin() / m.n;
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    tau_d / cos_t >= 40.0
}

impl Kernel<'_> {
    /// The lobe connection of a scattering event at `p` (incoming direction
    /// `dir`, weight `w` after albedo; `junctions` the walk's MIS history)
    /// with m = `lobe_vertices` camera-side vertices (module doc, "Lobe
    /// connection"): strategy 0, the connection along ω₂₁ from `p`, and
    /// strategies j = 1 … m from `chain`, directions drawn backwards from ω₂₁
    /// by the phase function (ω^c_j from p(·ω^c_{j−1}), ω^c_0 = ω₂₁) and
    /// distances from μ_t e^{−μ_t t}: the path `p` → p + t_j ω^c_j → … →
    /// p + Σ_{i ≤ j} t_i ω^c_i, connected along ω₂₁. The chain is redrawn
    /// every `lobe_reuse` events of the path ([`Chain`]). Every sample is
    /// worth w (μ_s/μ_t)^j e^{−μ_t ℓ} C / S with S the sum of 1/p over the
    /// junctions of the full path that the strategies can produce (the
    /// balance heuristic). ω₂₁, 1/cos θ₂₁ and C are the path's `exit`
    /// (fixed for a smooth top, drawn at launch through a rough one; a lost
    /// exit adds nothing). Thick slabs only. Returns the value added.
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(super) fn connect_lobe(
        &self,
        shape: (usize, usize),
        p: [f64; 3],
        dir: [f64; 3],
        w: f64,
        exit: &Exit,
        junctions: &Junctions,
        chain: &mut Chain,
        image: &mut [f64],
        rng: &mut Rng,
    ) -> f64 {
        match self.lobe_event(shape, p, dir, w, exit, junctions, chain, image, rng) {
            Ok(ev) => ev.total + self.lobe_links(&ev, p, dir, chain, image),
            Err(total) => total,
        }
    }

    /// [`connect_lobe`](Self::connect_lobe) up to the chain's links:
    /// strategy 0 (added to `image`), the chain's turn, its distances, the
    /// skip and the roulette, its directions. `Err(total)` when no link can
    /// contribute (total: strategy 0's value).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub(super) fn lobe_event(
        &self,
        (m, reuse): (usize, usize),
        p: [f64; 3],
        dir: [f64; 3],
        w: f64,
        exit: &Exit,
        junctions: &Junctions,
        chain: &mut Chain,
        image: &mut [f64],
        rng: &mut Rng,
    ) -> Result<LobeEvent, f64> {
        // A lost exit sample (rough top, W = 0): no connection of the path.
        if exit.splat == 0.0 {
            return Err(0.0);
        }
        let phase = &self.setup.slab.medium.phase;
        let sensor = &self.setup.sensor;
        let (w21, inv_cos) = (exit.up, exit.inv_cos);
        let mut total = 0.0;
        let depth = -p[2];
        chain.tick(reuse);
        // Σ 1/p over the walk's last l junctions, l = 0 … min(m, run)
        // (filled only for an event that can contribute).
        let light = junctions.run.min(m);
        let mut prefix = [0.0; MAX_LOBE_VERTICES + 1];
        let fill = |prefix: &mut [f64; MAX_LOBE_VERTICES + 1]| {
            for l in 0..light {
                prefix[l + 1] = prefix[l] + junctions.inv[l];
            }
        };
        // Strategy 0: the connection from this event.
        let l = depth * inv_cos;
        let tau = self.mu_t * l;
        let filled = tau <= 40.0;
        if filled {
            fill(&mut prefix);
            if let Some(i) = sensor.index(p[0] + l * w21[0], p[1] + l * w21[1]) {
                let e = if tau > self.roulette_depth { (self.roulette_depth - tau).exp() } else { (-tau).exp() };
                let transmittance = self.connection_transmittance(tau, e, rng);
                if transmittance > 0.0 {
                    let c = dir[0] * w21[0] + dir[1] * w21[1] + dir[2] * w21[2];
                    let v = w * transmittance * exit.splat / (1.0 / phase.eval(c) + prefix[light]);
                    image[i] += v;
                    total += v;
                }
            }
        }
        if m == 0 {
            return Err(total);
        }
        // Strategies 1 … m. The distances first: the chain's end lies at
        // least |z| − Σ t deep (|ω_z| ≤ 1), a lower bound of its optical
        // depth along ω₂₁ that decides the skip and the roulette before any
        // direction is drawn.
        if !chain.has_distances {
            chain.draw_distances(m, self.inv_mu_t, rng);
        }
        // τ_u = μ_t (|z| − Σ t)/cos θ_t; every exit depth's optical depth is
        // τ_u + s_j, s_j ≥ 0 the chain's own part.
        let tau_u = self.mu_t * (depth - chain.rise) * inv_cos;
        if tau_u > 40.0 {
            return Err(total);
        }
        // e^{−τ_u} (after the roulette: e^{−τ_r}); far above the lower bound
        // (τ_u < −600, a chain rising far above the event) e^{−τ_u} could
        // overflow and each term takes its own exponential instead.
        let direct = tau_u < -600.0;
        let e = if tau_u > self.roulette_depth {
            if rng.next_f64() >= (self.roulette_depth - tau_u).exp() {
                return Err(total);
            }
            self.roulette_transmittance
        } else if direct {
            0.0
        } else {
            (-tau_u).exp()
        };
        if !chain.has_directions {
            chain.draw_directions(m, phase, w21, self.albedo, self.mu_t * inv_cos, rng);
        }
        if !filled {
            fill(&mut prefix);
        }
        Ok(LobeEvent { m, w21, inv_cos, tau_u, direct, e, weight: w * exit.splat, prefix, light, total })
    }

    /// The terms of strategies 1 … m of one event from its chain
    /// ([`lobe_event`](Self::lobe_event)), one link at a time; returns the
    /// value added. (The lane kernel runs the same arithmetic four links at
    /// a time.)
    #[inline]
    pub(super) fn lobe_links(
        &self,
        ev: &LobeEvent,
        p: [f64; 3],
        dir: [f64; 3],
        chain: &Chain,
        image: &mut [f64],
    ) -> f64 {
        let m = ev.m;
        let phase = &self.setup.slab.medium.phase;
        let sensor = &self.setup.sensor;
        let w21 = ev.w21;
        let depth = -p[2];
        let floor = depth - self.d;
        let mut total = 0.0;
        for j in 0..m {
            // Every vertex of strategy j + 1 inside the slab.
            if !(chain.hi.0[j] < depth && chain.lo.0[j] > floor) {
                continue;
            }
            let tau = ev.tau_u + chain.s_tau.0[j];
            if tau > 40.0 {
                continue;
            }
            let l = (depth - chain.dz.0[j]) * ev.inv_cos;
            let Some(i) = sensor.index(p[0] + chain.x.0[j] + l * w21[0], p[1] + chain.y.0[j] + l * w21[1]) else {
                continue;
            };
            let c = dir[0] * chain.cx.0[j] + dir[1] * chain.cy.0[j] + dir[2] * chain.cz.0[j];
            let s = chain.q.0[j] + 1.0 / phase.eval(c) + ev.prefix[ev.light.min(m - j - 1)];
            let attenuation = if ev.direct { chain.albedo.0[j] * (-tau).exp() } else { ev.e * chain.atten.0[j] };
            let v = ev.weight * attenuation / s;
            image[i] += v;
            total += v;
        }
        total
    }
}

/// The light walk's side of the lobe connection's MIS weights: the
/// reciprocals 1/p(cos θ_s) of the phase function at its last scattering
/// angles (newest first) and the number of trailing flights that went
/// straight from one scattering event to the next (no boundary between).
#[derive(Debug, Clone, Copy)]
pub(super) struct Junctions {
    pub(super) inv: [f64; MAX_LOBE_VERTICES],
    pub(super) run: usize,
    /// Whether the current flight started at a scattering event.
    pub(super) from_scatter: bool,
}

impl Junctions {
    pub(super) fn new() -> Self {
        Self { inv: [0.0; MAX_LOBE_VERTICES], run: 0, from_scatter: false }
    }

    /// The photon reached a scattering event.
    #[inline]
    pub(super) fn arrive(&mut self) {
        self.run = if self.from_scatter { self.run + 1 } else { 0 };
    }

    /// The photon scattered with phase function value `p`.
    #[inline]
    pub(super) fn scatter(&mut self, p: f64) {
        self.inv.copy_within(0..MAX_LOBE_VERTICES - 1, 1);
        self.inv[0] = 1.0 / p;
        self.from_scatter = true;
    }
}

/// Per-link figures of a [`Chain`], aligned for the lane kernel's
/// four-link loads.
#[derive(Debug, Clone, Copy)]
#[repr(C, align(32))]
pub(super) struct Links(pub(super) [f64; MAX_LOBE_VERTICES]);

/// What the links of one event's lobe connection share
/// (`Kernel::lobe_event`).
pub(super) struct LobeEvent {
    /// The chain's length m (camera-side vertices, `Strategy::Lobe`).
    pub(super) m: usize,
    /// The path's ω₂₁ and 1/cos θ₂₁ ([`Exit`]).
    pub(super) w21: [f64; 3],
    pub(super) inv_cos: f64,
    /// τ_u = μ_t (|z| − Σ t)/cos θ₂₁.
    pub(super) tau_u: f64,
    /// Whether every term takes its own exponential (τ_u < −600).
    pub(super) direct: bool,
    /// e^{−τ_u}, or e^{−τ_r} after the roulette (unused when `direct`).
    pub(super) e: f64,
    /// w C, C the path's splat constant ([`Exit::splat`]).
    pub(super) weight: f64,
    /// Σ 1/p over the walk's last l junctions, l = 0 … `light`.
    pub(super) prefix: [f64; MAX_LOBE_VERTICES + 1],
    pub(super) light: usize,
    /// Strategy 0's value (already in the image).
    pub(super) total: f64,
}

/// One chain of the lobe connection (module doc, "Lobe connection" and
/// "Chain reuse"): m distances t_j and directions ω^c_j drawn backwards
/// from ω₂₁, and per link j (strategy j + 1) what its terms need from the
/// chain alone. Drawn in two steps (the distances decide the roulette) and
/// only when an event uses it; redrawn on a schedule of the path's events
/// that does not look at the chain.
#[derive(Debug, Clone)]
pub(super) struct Chain {
    /// Events of the path left in the current chain's turn.
    pub(super) left: usize,
    pub(super) has_distances: bool,
    pub(super) has_directions: bool,
    pub(super) t: [f64; MAX_LOBE_VERTICES],
    /// Σ t_j.
    pub(super) rise: f64,
    /// ω^c_{j+1}.
    pub(super) cx: Links,
    pub(super) cy: Links,
    pub(super) cz: Links,
    /// D_{j+1} = Σ_{i ≤ j+1} t_i ω^c_i: its x, y and z.
    pub(super) x: Links,
    pub(super) y: Links,
    pub(super) dz: Links,
    /// The vertices of strategy j + 1 lie at depths |z| − (D_{j+1} − D_l)_z,
    /// l = 0 … j: inside the slab iff `hi` < |z| and `lo` > |z| − d.
    pub(super) hi: Links,
    pub(super) lo: Links,
    /// μ_t (Σ t − D_{j+1,z}) / cos θ_t ≥ 0: the exit's optical depth less τ_u.
    pub(super) s_tau: Links,
    /// (μ_s/μ_t)^{j+1}, and times e^{−s_tau}.
    pub(super) albedo: Links,
    pub(super) atten: Links,
    /// Σ_{i ≤ j+1} 1/p at the chain's sampled junctions.
    pub(super) q: Links,
}

impl Chain {
    pub(super) fn new() -> Self {
        let z = Links([0.0; MAX_LOBE_VERTICES]);
        Self {
            left: 0,
            has_distances: false,
            has_directions: false,
            t: [0.0; MAX_LOBE_VERTICES],
            rise: 0.0,
            cx: z,
            cy: z,
            cz: z,
            x: z,
            y: z,
            dz: z,
            hi: z,
            lo: z,
            s_tau: z,
            albedo: z,
            atten: z,
            q: z,
        }
    }

    /// A new path: the next event draws a new chain.
    #[inline]
    pub(super) fn restart(&mut self) {
        self.left = 0;
    }

    /// An event of the path: every `reuse` events (the first one included)
    /// the chain is due to be redrawn (drawn when first used).
    #[inline]
    pub(super) fn tick(&mut self, reuse: usize) {
        if self.left == 0 {
            self.has_distances = false;
            self.has_directions = false;
            self.left = reuse;
        }
        self.left -= 1;
    }

    /// The m distances from μ_t e^{−μ_t t}, one number each.
    #[inline]
    pub(super) fn draw_distances(&mut self, m: usize, inv_mu_t: f64, rng: &mut Rng) {
        let mut rise = 0.0;
        for ti in self.t.iter_mut().take(m) {
            *ti = -(1.0 - rng.next_f64()).ln() * inv_mu_t;
            rise += *ti;
        }
        self.rise = rise;
        self.has_distances = true;
    }

    /// The m directions (two numbers each) and the per-link figures;
    /// `tau_per_m` = μ_t / cos θ_t.
    #[inline]
    pub(super) fn draw_directions(
        &mut self,
        m: usize,
        phase: &Phase,
        w21: [f64; 3],
        albedo: f64,
        tau_per_m: f64,
        rng: &mut Rng,
    ) {
        let mut c = w21;
        let (mut x, mut y, mut dz) = (0.0, 0.0, 0.0);
        let (mut d_min, mut d_max) = (0.0f64, 0.0f64);
        let (mut q, mut a) = (0.0, 1.0);
        for j in 0..m {
            let (u1, u2) = rng.next_f64_pair();
            let angles = phase.sample_angles(u1, u2);
            q += 1.0 / phase.eval(angles.cos_theta);
            c = angles.turn(c);
            let t = self.t[j];
            x += t * c[0];
            y += t * c[1];
            dz += t * c[2];
            a *= albedo;
            let s_tau = tau_per_m * (self.rise - dz);
            (self.cx.0[j], self.cy.0[j], self.cz.0[j]) = (c[0], c[1], c[2]);
            (self.x.0[j], self.y.0[j], self.dz.0[j]) = (x, y, dz);
            (self.hi.0[j], self.lo.0[j]) = (dz - d_min, dz - d_max);
            d_min = d_min.min(dz);
            d_max = d_max.max(dz);
            self.s_tau.0[j] = s_tau;
            self.albedo.0[j] = a;
            self.atten.0[j] = a * (-s_tau).exp();
            self.q.0[j] = q;
        }
        self.has_directions = true;
    }
}
