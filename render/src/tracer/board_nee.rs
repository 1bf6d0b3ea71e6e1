//! The board's next-event estimation (module doc of [`tracer`](super),
//! "On the board" and "Specular chains"): at a board point (Lambertian,
//! reflectance ρ) a direction ω_o drawn from the environment's sampler
//! (pdf in solid angle at the board point), weighed against the
//! cosine-sampled bounce by the power heuristic (Veach & Guibas 1995); by
//! the object's faces, a reflection at one and, where the object blocks
//! the shadow ray, a chain through it (in at one face, one unscattered
//! flight, out at another), weighed by the balance heuristic; then the
//! cosine-weighted bounce (pdf cos θ/π, weight ρ).

use super::accumulate::Estimate;
use super::boundary::{reflectances, unrefract};
use super::connections::mean_weighted;
use super::image::Stats;
use super::scene::{Object, Scene};
use super::throughput::{roulette, Throughput};
use super::walk::{power_heuristic, Path, Walk};
use crate::rng::Rng;
use glam::DVec3;
use std::f64::consts::{FRAC_1_PI, TAU};
use std::ops::ControlFlow;

/// The board point `y` (normal `n` on the path's side) a path left by its diffuse bounce, while the path
/// can still be a chain that [`connect_by_faces`] makes (in through a
/// face, one unscattered flight, out through another, or reflected at a
/// face from outside: `mirror`);
/// `out`: it has left the object and must now escape:
/// r at `y` and the driving band's density of the chain so far, in the
/// final outside solid angle.
#[derive(Debug, Clone, Copy)]
pub(super) struct BoardVertex {
    pub(super) y: DVec3,
    pub(super) n: DVec3,
    pub(super) r: [f64; 3],
    pub(super) pdf: f64,
    pub(super) out: bool,
    pub(super) mirror: bool,
}

/// A board point `y` with the normal `n` on the side the path is on, its
/// reflectance `rho` and whether the path splits where it meets the object
/// (then the refraction in is taken as a weight, not sampled).
pub(super) struct BoardPoint {
    pub(super) y: DVec3,
    pub(super) n: DVec3,
    pub(super) rho: [f64; 3],
    pub(super) split: bool,
}

/// The board's connections to the environment by the object's faces, for
/// the direction ω_o drawn by the board's next-event estimation (`sample`)
/// and each face k that ω_o leaves (n_k·ω_o > 0), from the board point y.
///
/// By a reflection at k from outside (unless the path splits there: its
/// reflected branch then escapes unweighted): the mirror direction
/// ω_b = ω_o − 2(n_k·ω_o)n_k, if the ray y + tω_b meets face k first and the
/// board does not hide ω_o from there. The contribution per band c is
///
///   β_c ρ_c (cos θ_b / π) F_c L_c(q, ω_o) / D,
///
/// D = p_env(y, ω_o) mean r + (cos θ_b / π) mean_k r_k F_k (a mirror keeps
/// solid angle): the balance heuristic against the board's cosine-sampled
/// bounce that reflects there and escapes along ω_o. Without it such light
/// (a lamp near the horizon seen in the plaque's sides from the board beside
/// them) reaches the board only by chance, as bright single pixels.
///
/// Through the object, where it blocks the straight shadow ray (`through`):
/// for every face j ≠ k, the chain from y along ω_b,
/// refracted in at face j into ω_i, one unscattered flight of length ℓ,
/// refracted out at face k into ω_o (ω_i from ω_o by Snell's law at k, ω_b
/// from ω_i at j; between parallel faces ω_b = ω_o). The contribution per
/// band c is
///
///   β_c ρ_c (cos θ_b / π) J (1 − F_j,c) e^{−μ_t,c ℓ} (1 − F_k,c) L_c(q, ω_o) / D,
///
/// J = dω_b/dω_o = cos θ_i,j cos θ_o / (cos θ_b cos θ_i,k), and
/// D = p_env(y, ω_o) mean r + (cos θ_b / π) J mean_k r_k s_k, s_k the
/// chain's probability when band k drives the path (the same factors; the
/// first one 1 when the path splits there): the balance heuristic against
/// the board's cosine-sampled bounce that follows the same chain. Without
/// it, a shadow ray that meets the object carries nothing, and light under
/// the object reaches the board only by chance.
#[allow(clippy::too_many_arguments)]
pub(super) fn connect_by_faces(
    scene: &Scene,
    obj: &Object,
    planes: &[(DVec3, f64)],
    tp: &Throughput,
    at: &BoardPoint,
    sample: &crate::env::EnvSample,
    shared: bool,
    through: bool,
    est: &mut Estimate,
) {
    let wo = sample.dir;
    let eta = if shared { obj.eta_mean } else { obj.eta(0) };
    let eps = scene.epsilon_m;
    let hidden = |q: DVec3| scene.board.as_ref().is_some_and(|b| b.intersect(q, wo).is_some());
    for (k, _) in planes {
        let cos_o = k.dot(wo);
        if cos_o <= 0.0 {
            continue;
        }
        let wb = wo - 2.0 * cos_o * *k;
        let cos_board = wb.dot(at.n);
        if !at.split && cos_board > 0.0 {
            let hit = obj.accel.intersect(at.y, wb, f64::INFINITY).filter(|hit| hit.normal == *k);
            if let Some(q) = hit.map(|hit| at.y + hit.t * wb + eps * *k).filter(|&q| !hidden(q)) {
                let (_, f) = reflectances(obj, cos_o, eta, shared, false);
                let bounce = cos_board * FRAC_1_PI;
                let denom = sample.pdf * tp.mean_r() + bounce * mean_weighted(&tp.r, &f);
                if denom > 0.0 {
                    let l = scene.environment.radiance(q, wo);
                    for c in 0..3 {
                        est.add(c, tp.beta[c] * at.rho[c] * bounce * f[c] * l[c] / denom);
                    }
                }
            }
        }
        if !through {
            continue;
        }
        let Some((wi, cos_ik)) = unrefract(wo, *k, eta) else { continue };
        for (j, _) in planes {
            let cos_ij = -j.dot(wi);
            if j == k || cos_ij <= 0.0 {
                continue;
            }
            // The outside direction that refracts into ω_i (none beyond the critical angle).
            let Some((wb, cos_b)) = unrefract(wi, -*j, 1.0 / eta) else { continue };
            let cos_board = wb.dot(at.n);
            if cos_board <= 0.0 {
                continue;
            }
            let Some(h1) = obj.accel.intersect(at.y, wb, f64::INFINITY).filter(|hit| hit.normal == *j) else {
                continue;
            };
            let p = at.y + h1.t * wb - eps * *j;
            let Some(h2) = obj.accel.exit(p, wi).filter(|hit| hit.normal == *k) else { continue };
            let q = p + h2.t * wi + eps * *k;
            if hidden(q) {
                continue;
            }
            let (_, f_in) = reflectances(obj, cos_b, eta, shared, false);
            let (_, f_out) = reflectances(obj, cos_ik, eta, shared, true);
            // The flight and the way out, then with the way in; the path
            // samples the way in unless it splits there.
            let crossing: [f64; 3] = std::array::from_fn(|c| (-obj.bands.sigma_t[c] * h2.t).exp() * (1.0 - f_out[c]));
            let through: [f64; 3] = std::array::from_fn(|c| (1.0 - f_in[c]) * crossing[c]);
            let chance = if at.split { crossing } else { through };
            let jacobian = cos_ij * cos_o / (cos_b * cos_ik);
            let bounce = cos_board * FRAC_1_PI * jacobian;
            let denom = sample.pdf * tp.mean_r() + bounce * mean_weighted(&tp.r, &chance);
            if denom.is_nan() || denom <= 0.0 {
                continue;
            }
            let l = scene.environment.radiance(q, wo);
            for c in 0..3 {
                est.add_through(c, tp.beta[c] * at.rho[c] * bounce * through[c] * l[c] / denom, obj, h2.t);
            }
        }
    }
}

/// Cosine-weighted direction about the unit normal `n` (Malley's method).
#[inline]
pub(super) fn cosine_direction(n: DVec3, u1: f64, u2: f64) -> (DVec3, f64) {
    let r = u1.sqrt();
    let phi = TAU * u2;
    let (s, c) = phi.sin_cos();
    let z = (1.0 - u1).max(0.0).sqrt();
    let (t, b) = crate::phase::orthonormal_basis(n.to_array());
    let (t, b) = (DVec3::from_array(t), DVec3::from_array(b));
    ((r * c) * t + (r * s) * b + z * n, z * FRAC_1_PI)
}

impl Walk<'_> {
    /// The board at distance `t_board` along the path (reflectance `rho`
    /// there): next-event estimation of the environment, straight (power
    /// heuristic against the bounce) and by the object's faces
    /// (`connect_by_faces`), then the cosine-weighted bounce and the
    /// roulette.
    pub(super) fn board_bounce(
        &self,
        t_board: f64,
        rho: [f64; 3],
        path: &mut Path,
        est: &mut Estimate,
        rng: &mut Rng,
        st: &mut Stats,
    ) -> ControlFlow<()> {
        let scene = self.scene;
        let eps = scene.epsilon_m;
        st.surface_hits += 1;
        path.vertex = None;
        let board = scene.board.as_ref().expect("board hit without a board");
        let p = path.o + t_board * path.d;
        let n = board.normal();
        let n = if n.dot(path.d) < 0.0 { n } else { -n };
        let origin = p + eps * n;
        // Next-event estimation of the environment.
        if let Some(sample) = scene.environment.sample(origin, [rng.next_f64(), rng.next_f64()])
            && sample.pdf > 0.0
        {
            let cos = sample.dir.dot(n);
            // The object hides ω_o (asked only where ω_o leaves the board's side).
            let blocked = cos > 0.0
                && scene.object.as_ref().is_some_and(|obj| obj.accel.occluded(origin, sample.dir, f64::INFINITY));
            if cos > 0.0 && !blocked {
                let w = power_heuristic(sample.pdf, cos * FRAC_1_PI);
                let beta = path.tp.effective();
                for c in 0..3 {
                    est.add(c, beta[c] * rho[c] * FRAC_1_PI * cos * sample.radiance[c] * w / sample.pdf);
                }
            }
            // By the object's faces: a reflection at one, and
            // through it where it blocks ω_o.
            if let (Some(obj), Some(planes)) = (&scene.object, self.board_planes) {
                let at = BoardPoint { y: origin, n, rho, split: self.split };
                let obj = obj.walked_after(path.events);
                connect_by_faces(scene, obj, planes, &path.tp, &at, &sample, self.shared, blocked, est);
            }
        }
        let (u1, u2) = rng.next_f64_pair();
        let (nd, pdf) = cosine_direction(n, u1, u2);
        path.chain =
            self.board_planes.map(|_| BoardVertex { y: origin, n, r: path.tp.r, pdf, out: false, mirror: false });
        for (b, r) in path.tp.beta.iter_mut().zip(rho) {
            *b *= r;
        }
        path.d = nd;
        path.o = origin;
        path.last_diffuse_pdf = Some(pdf);
        if !roulette(&mut path.tp, self.settings, rng) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }
}
