//! The connections from a scattering point inside the object (module doc
//! of [`tracer`](super), "Connections from inside" and "Specular chains"):
//! the environment connection (ω_o drawn from the environment, refracted
//! backwards through each flat face, or through the face a mesh's search
//! finds), the phase connection (ω_i drawn from the phase function,
//! refracted out), their chains through one reflection at a face, and the
//! balance heuristic over the three strategies and the bands (densities in
//! outside solid angle, dω_i/dω_o = cos θ_o / (n² cos θ_i)). A connection
//! is attempted with probability exp(−μ_t,min d), d [m] the distance to the
//! nearest lit face plane.

use super::accumulate::Estimate;
use super::boundary::{mesh_exit, mesh_exit_through, reflectances, refract_or_mirror, unrefract, MeshExit};
use super::scene::{Object, Scene};
use super::throughput::Throughput;
use crate::phase::eval_each;
use crate::rng::Rng;
use crate::sphere::SphereExits;
use glam::DVec3;
use std::f64::consts::TAU;

/// Makes a next-event connection from a scattering point inside a convex
/// object possible: the refraction through a flat face is a delta, so the
/// environment direction ω_o outside is sampled and refracted backwards.
/// Carries what the path needs to weight its own escape against the
/// connection (multiple importance sampling).
#[derive(Debug, Clone, Copy)]
pub(super) struct MediumVertex {
    pub(super) x: DVec3,
    /// mean r at x (1 after normalisation).
    pub(super) mean_r: f64,
    /// r at x, for the phase connection's density in each band.
    pub(super) r: [f64; 3],
    /// Probability that the connection was attempted at x.
    pub(super) p_attempt: f64,
    /// Probability that the phase connection was made at x (`p_attempt`, or 0 without it).
    pub(super) p_phase: f64,
    /// x is the exit point of sphere j, scattered: the direction's density
    /// is that sphere's exit distribution, not the phase function.
    pub(super) sphere: Option<usize>,
}

/// The connections from a medium vertex (`conn`: where, and with what
/// probabilities) with the path's throughput `tp` there: the environment
/// connection, made with probability `conn.p_attempt`, and with it the phase
/// connection where `conn.p_phase` > 0. Returns what the path's own escape
/// from the vertex needs for its weight.
pub(super) fn connect_vertex(
    scene: &Scene,
    obj: &Object,
    faces: Faces,
    tp: &Throughput,
    conn: &Connection,
    rng: &mut Rng,
    est: &mut Estimate,
) -> MediumVertex {
    let p_attempt = conn.p_attempt;
    if p_attempt >= 1.0 || rng.next_f64() < p_attempt {
        match faces {
            Faces::Planes(planes) => connect_through_faces(scene, obj, planes, tp, conn, rng, est),
            Faces::Mesh => connect_through_mesh(scene, obj, tp, conn, rng, est),
        }
        if conn.p_phase > 0.0 {
            connect_along_phase(scene, obj, tp, conn, rng, est);
        }
    }
    MediumVertex {
        x: conn.x,
        mean_r: tp.mean_r(),
        r: tp.r,
        p_attempt,
        p_phase: conn.p_phase,
        sphere: conn.exit.map(|(_, j)| j),
    }
}

/// Where and how a medium connection is made: the driving band `h`, the
/// scattering point `x`, the direction the path arrived along `d_in`, the
/// probabilities with which the environment connection (`p_attempt`) and
/// the phase connection (`p_phase`) are made there, whether refraction
/// uses the bands' mean index (`shared`) and whether chains through one
/// reflection at a face are connected too (`chains`,
/// [`Settings::specular_chains`]). At a sphere jump's scattered exit
/// (`exit`: the tables and the sphere j) the direction's density is the
/// exit distribution about the sphere's outward normal `d_in` instead of
/// the phase function.
#[derive(Debug, Clone, Copy)]
pub(super) struct Connection<'a> {
    pub(super) h: usize,
    pub(super) x: DVec3,
    pub(super) d_in: DVec3,
    pub(super) p_attempt: f64,
    pub(super) p_phase: f64,
    pub(super) shared: bool,
    pub(super) chains: bool,
    pub(super) exit: Option<(&'a SphereExits, usize)>,
}

/// The medium connection from scattering point `x` (the path arrived along
/// `d_in`): one direction ω_o drawn from the environment's sampler at x;
/// for every face whose outward normal n has n·ω_o > 0, the inside direction
/// ω_i that refracts into ω_o (Snell), if the ray x + tω_i leaves through that
/// face; the contribution per band c is
///
///   β_c p_c(ω_in·ω_i) e^{−μ_t,c t} (1 − F) (cos θ_o / (n² cos θ_i)) L_c(q, ω_o) / D,
///
/// D = p_att p_env(x, ω_o) mean r + mean_k r_k u_k, u_k = p_k e^{−μ_t,k t} (1 − F) cos θ_o / (n² cos θ_i)
/// the density of the same path by phase sampling in band k (balance
/// heuristic over bands and the two strategies). Shadowed by the board.
pub(super) fn connect_through_faces(
    scene: &Scene,
    obj: &Object,
    planes: &[(DVec3, f64)],
    tp: &Throughput,
    conn: &Connection,
    rng: &mut Rng,
    est: &mut Estimate,
) {
    let &Connection { h, x, shared, .. } = conn;
    let Some(es) = sample_environment(scene, x, rng) else { return };
    let wo = es.dir;
    let eta = if shared { obj.eta_mean } else { obj.eta(h) };
    let d_in = conn.d_in;
    let eps = scene.epsilon_m;
    // One draw for the far-face roulette of every chain below: a chain τ
    // deep (its whole length) is made when τ < τ_far = CHAIN_TAU − ln u,
    // i.e. with probability min(1, e^{CHAIN_TAU − τ}).
    let tau_far = if conn.chains { CHAIN_TAU - (1.0 - rng.next_f64()).ln() } else { 0.0 };
    for (n, c_n) in planes {
        let cos_o = n.dot(wo);
        if cos_o <= 0.0 {
            continue;
        }
        let Some((wi, cos_i)) = unrefract(wo, *n, eta) else { continue };
        let jacobian = cos_o / (eta * eta * cos_i);
        let (_, fr) = reflectances(obj, cos_i, eta, shared, true);
        let blocked = |q: DVec3| outside_blocked(scene, obj, q, wo);
        // Straight out through face n.
        if let Some(hit) = obj.accel.exit(x, wi).filter(|hit| hit.normal == *n) {
            let q = x + hit.t * wi + eps * *n;
            if !blocked(q) {
                let exit = Exit { t: hit.t, mu: d_in.dot(wi), jacobian, refl: [1.0; 3], fr, q, wo, weight: 1.0 };
                add_connection(scene, obj, tp, conn, &exit, es.pdf, est);
            }
        }
        if !conn.chains {
            continue;
        }
        // Through one reflection at another face m first (the ray from x's
        // mirror image across m along ω_i is the reflected path unfolded).
        for (m, c_m) in planes {
            let cos_m = -m.dot(wi);
            if m == n || cos_m <= 0.0 {
                continue;
            }
            // Made with probability max_c R_c (Russian roulette, weight
            // 1/that): a partial reflection carries little and costs as
            // much as a straight connection. The same, independently, with
            // e^{CHAIN_TAU − τ} where the chain is τ > CHAIN_TAU deep (its
            // length ℓ: from x's mirror image x′ across m, straight along
            // ω_i to n's plane): a far face (the plaque's sides seen from
            // its middle) costs two boundary searches for nothing. (Its
            // test, τ < τ_far, takes no exponential per face.)
            let x_mirror = x + 2.0 * (c_m - m.dot(x)) * *m;
            let length = (c_n - n.dot(x_mirror)) / cos_i;
            let tau = obj.bands.sigma_t_min * length;
            if length.is_nan() || length <= 0.0 || tau >= tau_far {
                continue;
            }
            let (_, refl) = reflectances(obj, cos_m, eta, shared, true);
            let r_max = refl[0].max(refl[1]).max(refl[2]).min(1.0);
            if !(r_max >= 1.0 || rng.next_f64() < r_max) {
                continue;
            }
            let keep = r_max * (CHAIN_TAU - tau).exp().min(1.0);
            let d1 = wi + 2.0 * cos_m * *m;
            let Some(h1) = obj.accel.exit(x, d1).filter(|hit| hit.normal == *m) else { continue };
            let p = x + h1.t * d1 - eps * *m;
            let Some(h2) = obj.accel.exit(p, wi).filter(|hit| hit.normal == *n) else { continue };
            let q = p + h2.t * wi + eps * *n;
            if blocked(q) {
                continue;
            }
            let exit =
                Exit { t: h1.t + h2.t, mu: d_in.dot(d1), jacobian, refl, fr, q, wo, weight: 1.0 / keep.min(1.0) };
            add_connection(scene, obj, tp, conn, &exit, es.pdf, est);
        }
    }
}

/// The medium connection from scattering point `x` of a mesh that is not a
/// convex polyhedron of few planes: one direction ω_o drawn from the
/// environment's sampler at x, the face the inside ray refracting into it
/// leaves through ([`mesh_exit`]), and the contribution and denominator of
/// [`connect_through_faces`] through that face (no chains). Shadowed by the
/// board and, for a mesh that is not convex, by the mesh itself.
pub(super) fn connect_through_mesh(
    scene: &Scene,
    obj: &Object,
    tp: &Throughput,
    conn: &Connection,
    rng: &mut Rng,
    est: &mut Estimate,
) {
    let &Connection { h, x, d_in, shared, .. } = conn;
    let Some(es) = sample_environment(scene, x, rng) else { return };
    let wo = es.dir;
    let eta = if shared { obj.eta_mean } else { obj.eta(h) };
    let Some(MeshExit { hit, n, wi, cos_i }) = mesh_exit(&obj.accel, x, wo, eta) else { return };
    let q = x + hit.t * wi + scene.epsilon_m * n;
    if outside_blocked(scene, obj, q, wo) {
        return;
    }
    let jacobian = n.dot(wo) / (eta * eta * cos_i);
    let (_, fr) = reflectances(obj, cos_i, eta, shared, true);
    let exit = Exit { t: hit.t, mu: d_in.dot(wi), jacobian, refl: [1.0; 3], fr, q, wo, weight: 1.0 };
    add_connection(scene, obj, tp, conn, &exit, es.pdf, est);
}

/// The phase connection from scattering point x: a direction ω_i drawn from
/// the driving band's phase function about `d_in`; the ray x + tω_i leaves
/// through a face with outward normal n (the first it meets), refracts into
/// ω_o (no contribution under total internal reflection or when the board
/// blocks ω_o), and the path gets, per band c,
///
///   β_c p_c(ω_in·ω_i) e^{−μ_t,c t} (1 − F_c) J L_c(q, ω_o) / D,
///
/// J = cos θ_o / (n² cos θ_i) = dω_i/dω_o, with the same denominator D as
/// the environment connection ([`connect_through_faces`]) plus this
/// strategy's own density p_phase · J · (1/3) Σ_k r_k p_k (balance heuristic
/// over the three strategies and the bands). Unlike the path's own escape,
/// which reaches the face with probability e^{−μ_t t} and passes it with
/// probability 1 − F, both factors are taken as weights, and unlike the
/// environment connection, the phase function's forward peak is sampled,
/// not met by chance.
pub(super) fn connect_along_phase(
    scene: &Scene,
    obj: &Object,
    tp: &Throughput,
    conn: &Connection,
    rng: &mut Rng,
    est: &mut Estimate,
) {
    let &Connection { h, x, d_in, shared, .. } = conn;
    let (u1, u2) = rng.next_f64_pair();
    let w1 = DVec3::from_array(obj.medium[h].phase.sample_direction(d_in.to_array(), u1, u2));
    let eta = if shared { obj.eta_mean } else { obj.eta(h) };
    let eps = scene.epsilon_m;
    let mu = d_in.dot(w1);
    // Out through the face that the ray x + t ω_1 meets, then (with the
    // chains) reflected there and out through the next.
    let Some(hit) = obj.accel.exit(x, w1) else { return };
    let mut p = x + hit.t * w1;
    let mut t = hit.t;
    let mut wi = w1;
    let mut n = if hit.normal.dot(w1) >= 0.0 { hit.normal } else { -hit.normal };
    let mut refl = [1.0; 3];
    let mut weight = 1.0;
    for bounce in 0..2 {
        let cos_i = wi.dot(n);
        if cos_i <= 0.0 {
            return;
        }
        let (f, fr) = reflectances(obj, cos_i, eta, shared, true);
        if f < 1.0 {
            let wo = refract_or_mirror(wi, n, 1.0 / eta);
            let cos_o = wo.dot(n);
            let q = p + eps * n;
            if cos_o > 0.0 && !outside_blocked(scene, obj, q, wo) {
                let exit = Exit { t, mu, jacobian: cos_o / (eta * eta * cos_i), refl, fr, q, wo, weight };
                // A mesh's environment connection makes this path only
                // through the face its search finds.
                let made =
                    obj.accel.convex_planes().is_some() || mesh_exit_through(&obj.accel, x, wo, eta, hit.triangle);
                let pdf_env = if made { scene.environment.pdf(x, wo) } else { 0.0 };
                add_connection(scene, obj, tp, conn, &exit, pdf_env, est);
            }
        }
        if bounce == 1 || !conn.chains {
            return;
        }
        // On by reflection with probability max_c F_c (weight 1/that).
        let keep = fr[0].max(fr[1]).max(fr[2]);
        if !(keep >= 1.0 || rng.next_f64() < keep) {
            return;
        }
        refl = fr;
        weight = 1.0 / keep.min(1.0);
        wi -= 2.0 * cos_i * n;
        let Some(h2) = obj.accel.exit(p - eps * n, wi) else { return };
        let n2 = if h2.normal.dot(wi) >= 0.0 { h2.normal } else { -h2.normal };
        p = p - eps * n + h2.t * wi;
        t += h2.t;
        n = n2;
    }
}

/// Where a medium connection leaves the object: after a length `t` of
/// medium (μ = ω_in·ω_1, ω_1 the direction from the scattering point),
/// reflected on the way with the Fresnel reflectance `refl` per band (1
/// when it leaves straight), refracted into `wo` at the point `q` on the
/// face, with `jacobian` = dω_i/dω_o = cos θ_o / (n² cos θ_i) and the
/// Fresnel reflectance `fr` per band there; `weight`: 1 / the probability
/// with which the connection was made (Russian roulette on the reflection).
pub(super) struct Exit {
    pub(super) t: f64,
    pub(super) mu: f64,
    pub(super) jacobian: f64,
    pub(super) refl: [f64; 3],
    pub(super) fr: [f64; 3],
    pub(super) q: DVec3,
    pub(super) wo: DVec3,
    pub(super) weight: f64,
}

/// Adds a medium connection's contribution per band c,
/// β_c u_c L_c(q, ω_o) / D, u_k = p_k(μ) e^{−μ_t,k t} R_k (1 − F_k) J the path's
/// own escape along the same chain in band k per unit outside solid angle
/// (R_k the reflection on the way, 1 for none), and
/// D = p_att p_env mean r + mean_k r_k u_k + p_phase J mean_k r_k p_k(μ),
/// the balance heuristic over the three strategies and the bands
/// (`pdf_env` = p_env(x, ω_o)).
pub(super) fn add_connection(
    scene: &Scene,
    obj: &Object,
    tp: &Throughput,
    conn: &Connection,
    exit: &Exit,
    pdf_env: f64,
    est: &mut Estimate,
) {
    let (f, ph) = direction_factors(obj, tp, conn, exit.mu);
    let through: [f64; 3] = std::array::from_fn(|k| {
        (-obj.bands.sigma_t[k] * exit.t).exp() * exit.refl[k] * (1.0 - exit.fr[k]) * exit.jacobian
    });
    let u: [f64; 3] = std::array::from_fn(|k| ph[k] * through[k]);
    let phase = if conn.p_phase > 0.0 { conn.p_phase * exit.jacobian * mean_weighted(&tp.r, &ph) } else { 0.0 };
    let denom = conn.p_attempt * pdf_env * tp.mean_r() + mean_weighted(&tp.r, &u) + phase;
    if denom.is_nan() || denom <= 0.0 {
        return;
    }
    let l = scene.environment.radiance(exit.q, exit.wo);
    for c in 0..3 {
        est.add_through(c, exit.weight * tp.beta[c] * f[c] * through[c] * l[c] / denom, obj, exit.t);
    }
}

/// Per band, the contribution and the density per steradian of leaving
/// `conn`'s point in a direction at cosine `mu` to `conn.d_in`: the phase
/// function's value twice, or a sphere exit's (w_c, q_c)(μ)/2π.
#[inline]
pub(super) fn direction_factors(obj: &Object, tp: &Throughput, conn: &Connection, mu: f64) -> ([f64; 3], [f64; 3]) {
    match conn.exit {
        None => {
            let ph = band_phases(obj, |k| tp.r[k] > 0.0 || tp.beta[k] > 0.0, conn.h, mu);
            (ph, ph)
        }
        Some((t, j)) => {
            let (w, q) = t.given_scattered(j, mu);
            (w.map(|x| x / TAU), q.map(|x| x / TAU))
        }
    }
}

/// The phase functions' values p_k(μ) of the bands taking part (`active`),
/// 0 for the others; band `h`'s value serves every band when they share one.
#[inline]
pub(super) fn band_phases(obj: &Object, active: impl Fn(usize) -> bool, h: usize, mu: f64) -> [f64; 3] {
    if obj.bands.same_phase {
        let ph_h = obj.medium[h].phase.eval(mu);
        std::array::from_fn(|k| if active(k) { ph_h } else { 0.0 })
    } else {
        eval_each(obj.phases(), std::array::from_fn(active), mu)
    }
}

/// (1/3) Σ_k r_k v_k.
#[inline]
pub(super) fn mean_weighted(r: &[f64; 3], v: &[f64; 3]) -> f64 {
    (r[0] * v[0] + r[1] * v[1] + r[2] * v[2]) / 3.0
}

/// One direction drawn from the environment's sampler at `x` for a medium
/// connection, or None where its density is not positive.
pub(super) fn sample_environment(scene: &Scene, x: DVec3, rng: &mut Rng) -> Option<crate::env::EnvSample> {
    let es = scene.environment.sample(x, [rng.next_f64(), rng.next_f64()])?;
    (es.pdf > 0.0).then_some(es)
}

/// True when the ray leaving the object at `q` along ω_o meets the board,
/// or, for a mesh that is not convex, the mesh itself.
pub(super) fn outside_blocked(scene: &Scene, obj: &Object, q: DVec3, wo: DVec3) -> bool {
    scene.board.as_ref().is_some_and(|b| b.intersect(q, wo).is_some())
        || !obj.accel.is_convex() && obj.accel.occluded(q, wo, f64::INFINITY)
}

/// Optical depth below which a chain through a reflection is always
/// connected (beyond it, with probability e^{CHAIN_TAU − τ}).
pub(super) const CHAIN_TAU: f64 = 4.6;

/// Distance from x to the nearest of the face planes (≥ 0).
#[inline]
pub(super) fn distance_to_planes(planes: &[(DVec3, f64)], x: DVec3) -> f64 {
    planes.iter().map(|(n, c)| (c - n.dot(x)).max(0.0)).fold(f64::INFINITY, f64::min)
}

/// Distance from x to the nearest face plane whose outward normal n looks
/// into the hemisphere about `facing` that the environment's sampling
/// favours (n·facing > −½; every plane without `facing`): the least medium
/// a medium connection that is not hidden crosses. With a board the
/// sampling faces up, and a face that looks down at the board has its
/// connections hidden by it, so a point just above the bottom face of a
/// plaque is as far from a useful face as from the top.
#[inline]
pub(super) fn distance_to_lit_planes(planes: &[(DVec3, f64)], x: DVec3, facing: Option<DVec3>) -> f64 {
    // (A bounded convex object has a face with n·facing > 0, so some plane
    // always passes the filter.)
    planes
        .iter()
        .filter(|(n, _)| facing.is_none_or(|f| n.dot(f) > -0.5))
        .map(|(n, c)| (c - n.dot(x)).max(0.0))
        .fold(f64::INFINITY, f64::min)
}

/// Probability of attempting the medium connection from x: the bound
/// exp(−μ_t,min d) on its transmittance, d ≥ 0 the distance to the nearest
/// face plane through which a connection the board does not hide leaves
/// ([`distance_to_lit_planes`]: any such connection crosses at least that
/// much medium); 0 beyond 40 mean free paths. Deep
/// vertices, whose connections carry almost nothing, rarely pay for one;
/// the estimator stays unbiased because the probability enters the
/// connection's density in the MIS weights. (Measured on the plaque scene
/// under a lamp: a gain of e⁴ on this probability cost more time than it
/// saved variance; a gain of 0.2 lost variance. Measured on the plaques of
/// demo.toml, 320 × 240, 256 spp: the distance to every face, the bottom
/// one on the board included, instead of the faces that look up, cost
/// 1.04× (PVP IOL1068-13) and 1.14× (IOL1068-09) in variance × time.)
#[inline]
pub(super) fn attempt_probability(d: f64, sigma_t_min: f64) -> f64 {
    let tau = sigma_t_min * d;
    if tau < 40.0 {
        (-tau).exp().min(1.0)
    } else {
        0.0
    }
}

/// The boundary a medium connection crosses: a convex mesh's face planes
/// (every face is tried, and chains through one reflection), or any other
/// closed mesh with smooth faces (the one face [`mesh_exit`] finds).
#[derive(Debug, Clone, Copy)]
pub(super) enum Faces<'a> {
    Planes(&'a [(DVec3, f64)]),
    Mesh,
}
