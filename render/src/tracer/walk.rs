//! The path walk (module doc of [`tracer`](super), "Estimator"): one
//! camera path (`trace`) and its branches (`trace_path`), step by step:
//! in the medium a free flight of density μ_t,h e^{−μ_t,h s} [1/m] in the
//! driving band h, then a scattering event (weight μ_s,c e^{−μ_t,c s} per
//! band, the medium connections, a sphere jump or a turn by the phase
//! function, the roulette) or the boundary (module `boundary`); outside,
//! the board (module `board_nee`), the object's boundary from outside, or
//! the escape to the environment with its multiple-importance weight
//! against the connections that make the same path (balance heuristic) or
//! against the board's next-event estimation (power heuristic, Veach &
//! Guibas 1995).

use super::accumulate::Estimate;
use super::board_nee::BoardVertex;
use super::boundary::mesh_exit_through;
use super::connections::{
    attempt_probability, band_phases, connect_vertex, distance_to_lit_planes, distance_to_planes, mean_weighted,
    Connection, Faces, MediumVertex,
};
use super::image::Stats;
use super::scene::{Object, Scene};
use super::settings::{Dispersion, Settings, MAX_DERIVATIVES};
use super::throughput::{roulette, Throughput};
use crate::phase::eval_each;
use crate::rng::Rng;
use crate::sphere::{self, SphereExits};
use glam::DVec3;
use std::ops::ControlFlow;

/// The first surface a camera ray meets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum FirstHit {
    Object,
    Board,
    Environment,
}

/// One camera path: the radiance estimate it carries back, per band, and
/// the first surface the camera ray meets.
pub(super) fn trace(
    scene: &Scene,
    settings: &Settings,
    o: DVec3,
    d: DVec3,
    rng: &mut Rng,
    st: &mut Stats,
) -> ([f64; 3], [[f64; 3]; MAX_DERIVATIVES], FirstHit) {
    let tp = Throughput { beta: [1.0; 3], r: [1.0; 3] };
    let mut est = Estimate::new(settings);
    let first = trace_path(scene, settings, o, d, tp, None, 0, settings.split_entry, &mut est, rng, st);
    (est.l, est.dl, first)
}

/// A path from `o` along `d` (outside the object) with throughput `tp` and
/// driving band `hero` (if already chosen), after `events_before`
/// scattering events; `split`: split at the object's boundary from outside
/// ([`Settings::split_entry`]). Adds its contributions to `est`.
#[allow(clippy::too_many_arguments)]
pub(super) fn trace_path(
    scene: &Scene,
    settings: &Settings,
    o: DVec3,
    d: DVec3,
    tp: Throughput,
    hero: Option<usize>,
    events_before: u64,
    split: bool,
    est: &mut Estimate,
    rng: &mut Rng,
    st: &mut Stats,
) -> FirstHit {
    let walk = Walk::new(scene, settings, split);
    let mut path = Path {
        o,
        d,
        tp,
        hero,
        inside: false,
        last_diffuse_pdf: None,
        vertex: None,
        stretch: Stretch { pdf: 1.0, mu: 1.0, jacobian: 0.0, t: 0.0, refl: None, triangle: u32::MAX },
        events: events_before,
        first_hit: None,
        safe: 0.0,
        chain: None,
    };
    loop {
        let step = if path.inside {
            walk.medium_step(&mut path, est, rng, st)
        } else {
            walk.outside_step(&mut path, est, rng, st)
        };
        if step.is_break() {
            break;
        }
    }
    st.events += path.events - events_before;
    path.first_hit.unwrap_or(FirstHit::Environment)
}

/// What stays the same along one path (one call of `trace_path`): the
/// scene, the settings and the strategies they allow.
pub(super) struct Walk<'a> {
    pub(super) scene: &'a Scene,
    pub(super) settings: &'a Settings,
    /// Split at the object's boundary from outside ([`Settings::split_entry`]).
    pub(super) split: bool,
    /// All bands ride on one path whose refractions use the bands' mean index.
    pub(super) shared: bool,
    /// A convex object's face planes (a flight's safe distance).
    pub(super) convex: Option<&'a [(DVec3, f64)]>,
    /// The face planes the medium connections go through (a convex object
    /// with a smooth boundary under an environment that is not uniform).
    pub(super) planes: Option<&'a [(DVec3, f64)]>,
    /// The boundary the medium connections cross (`None`: no connections).
    pub(super) faces: Option<Faces<'a>>,
    /// [`Settings::specular_chains`].
    pub(super) chains: bool,
    /// The hemisphere the environment's sampling favours (`attempt_probability`).
    pub(super) facing: Option<DVec3>,
    /// The face planes of the board's chains through the object.
    pub(super) board_planes: Option<&'a [(DVec3, f64)]>,
}

/// A path on its way: where it is and where it goes, its throughput and
/// driving band, and what its multiple-importance weights still need to
/// know about the stretch since its last medium vertex or board point.
pub(super) struct Path {
    pub(super) o: DVec3,
    pub(super) d: DVec3,
    pub(super) tp: Throughput,
    pub(super) hero: Option<usize>,
    pub(super) inside: bool,
    /// pdf of the last diffuse bounce's direction (for MIS when the ray escapes straight to the sky).
    pub(super) last_diffuse_pdf: Option<f64>,
    /// The last scattering point, while the path since then can still be
    /// one that a medium connection makes (one flight, one refraction out).
    pub(super) vertex: Option<MediumVertex>,
    /// The stretch since `vertex`.
    pub(super) stretch: Stretch,
    pub(super) events: u64,
    /// Whether the camera ray's first hit is the object (set at the first outside segment).
    pub(super) first_hit: Option<FirstHit>,
    /// A lower bound of the distance from `o` to the surface while inside: a
    /// flight shorter than it cannot leave (exact for a convex object's planes).
    pub(super) safe: f64,
    /// The board point the path left by its diffuse bounce while it can
    /// still be a chain that the board's connection through the object
    /// makes, and the driving band's density of the chain so far.
    pub(super) chain: Option<BoardVertex>,
}

/// The stretch of a path since its medium vertex.
#[derive(Debug, Clone, Copy)]
pub(super) struct Stretch {
    /// The driving band's density of the stretch in outside solid angle.
    pub(super) pdf: f64,
    /// The cosine of the turn at the vertex.
    pub(super) mu: f64,
    /// dω_i/dω_o of the stretch's refraction out.
    pub(super) jacobian: f64,
    /// Medium length since the medium vertex.
    pub(super) t: f64,
    /// The driving band's probability of the one reflection on the way
    /// (`None` before it).
    pub(super) refl: Option<f64>,
    /// The triangle the stretch left the object through (a mesh's connections
    /// make it only through the one `mesh_exit` finds).
    pub(super) triangle: u32,
}

impl<'a> Walk<'a> {
    fn new(scene: &'a Scene, settings: &'a Settings, split: bool) -> Self {
        // All bands ride on one path whose refractions use the bands' mean index.
        let shared = scene.object.as_ref().is_some_and(|obj| {
            settings.spectral_mis
                && !obj.bands.achromatic
                && obj.interface.is_specular()
                && settings.dispersion == Dispersion::SharedDirections
        });
        let convex = scene.object.as_ref().and_then(|obj| obj.accel.convex_planes());
        let planes = match &scene.object {
            Some(obj) if settings.medium_nee && obj.interface.is_specular() && !scene.environment.is_uniform() => {
                obj.accel.convex_planes()
            }
            _ => None,
        };
        // Any other closed mesh with smooth faces connects through the face
        // that `mesh_exit` finds.
        let faces = match &scene.object {
            Some(obj) if settings.medium_nee && obj.interface.is_specular() && !scene.environment.is_uniform() => {
                Some(planes.map_or(Faces::Mesh, Faces::Planes))
            }
            _ => None,
        };
        let chains = settings.specular_chains;
        // The hemisphere the environment's sampling favours (`attempt_probability`).
        let facing = scene.environment.sampling_normal();
        // Chains from the board through the object need every band on the path
        // (a band picked at the object would not be known at the board).
        let board_planes = match &scene.object {
            Some(obj) if chains && settings.spectral_mis && (obj.bands.achromatic || shared) => planes,
            _ => None,
        };
        Self { scene, settings, split, shared, convex, planes, faces, chains, facing, board_planes }
    }

    /// One step in the medium: a free flight in the driving band, then a
    /// scattering event (`scatter`) or the boundary (`leave_medium`).
    fn medium_step(&self, path: &mut Path, est: &mut Estimate, rng: &mut Rng, st: &mut Stats) -> ControlFlow<()> {
        // In the medium: `hero` is set, the object exists.
        let (Some(obj0), Some(h)) = (&self.scene.object, path.hero) else {
            return ControlFlow::Break(());
        };
        let obj = obj0.walked_after(path.events);
        let sigma_t = obj.bands.sigma_t[h];
        let s = -(1.0 - rng.next_f64()).ln() / sigma_t;
        // A flight shorter than the distance to the nearest face plane,
        // or within a convex mesh's inscribed ball, cannot leave: no
        // boundary search needed.
        let hit = if s < path.safe || obj.accel.stays_inside(path.o, path.d, s) {
            None
        } else {
            let Some(hit) = obj.accel.exit(path.o, path.d) else {
                st.leaked_paths += 1;
                return ControlFlow::Break(());
            };
            Some(hit)
        };
        match hit.filter(|hit| s >= hit.t) {
            Some(hit) => self.leave_medium(obj, h, &hit, path, est, rng, st),
            None => self.scatter(obj0, h, s, path, est, rng, st),
        }
    }

    /// A scattering event at distance `s` along the path in the medium of
    /// `obj0` (as walked after the path's events so far), in driving band
    /// `h`: the weights of the flight and the event, the medium connections
    /// from there, then a sphere jump or a turn by the phase function, the
    /// event limit and the roulette.
    #[allow(clippy::too_many_arguments)]
    fn scatter(
        &self,
        obj0: &Object,
        h: usize,
        s: f64,
        path: &mut Path,
        est: &mut Estimate,
        rng: &mut Rng,
        st: &mut Stats,
    ) -> ControlFlow<()> {
        let settings = self.settings;
        let obj = obj0.walked_after(path.events);
        let bc = &obj.bands;
        let sigma_t = bc.sigma_t[h];
        // Scattering at x: density μ_t,h e^{−μ_t,h s}, contribution μ_s,c e^{−μ_t,c s}.
        path.o += s * path.d;
        est.flight(obj, s);
        est.scatter();
        let tp = &mut path.tp;
        if bc.same_sigma_t || tp.single_band() {
            // (One band: its ratios f/p reduce to μ_s/μ_t.)
            for c in 0..3 {
                tp.beta[c] *= obj.medium[c].mu_s_per_m / sigma_t;
            }
        } else {
            let decay: [f64; 3] =
                std::array::from_fn(|c| if tp.active(c) { (-(bc.sigma_t[c] - sigma_t) * s).exp() } else { 0.0 });
            tp.scale(
                std::array::from_fn(|c| obj.medium[c].mu_s_per_m * decay[c]),
                std::array::from_fn(|c| bc.sigma_t[c] * decay[c]),
                h,
            );
        }
        tp.normalise();
        path.events += 1;
        let obj = obj0.walked_after(path.events);
        let spheres = sphere_tables(obj, settings);
        let bc = &obj.bands;
        path.chain = None;
        path.safe = match self.convex {
            Some(planes) => distance_to_planes(planes, path.o),
            None => obj.accel.distance_lower_bound(path.o),
        };
        if let Some(faces) = self.faces {
            let reach = match faces {
                Faces::Planes(planes) => distance_to_lit_planes(planes, path.o, self.facing),
                Faces::Mesh => obj.accel.distance_estimate(path.o),
            };
            let p_attempt = attempt_probability(reach, bc.sigma_t_min);
            let p_phase = if settings.phase_connection { p_attempt } else { 0.0 };
            let chains = self.chains && self.planes.is_some();
            let conn =
                Connection { h, x: path.o, d_in: path.d, p_attempt, p_phase, shared: self.shared, chains, exit: None };
            path.vertex = Some(connect_vertex(self.scene, obj, faces, &path.tp, &conn, rng, est));
            path.stretch.t = 0.0;
            path.stretch.refl = None;
        }
        // Deep inside: jump through the largest sphere that fits;
        // else turn by the phase function.
        let room = path.safe - settings.sphere_margin_mfp / bc.sigma_t_min;
        if let Some((t, j)) = spheres.and_then(|t| t.largest_within(room).map(|j| (t, j))) {
            self.sphere_jump(obj, h, t, j, path, est, rng);
        } else {
            let d_in = path.d;
            let (u1, u2) = rng.next_f64_pair();
            path.d = DVec3::from_array(obj.medium[h].phase.sample_direction(d_in.to_array(), u1, u2));
            path.stretch.mu = d_in.dot(path.d);
            if !bc.same_phase && !path.tp.single_band() {
                let active = std::array::from_fn(|c| c == h || path.tp.active(c));
                let p = eval_each(obj.phases(), active, path.stretch.mu);
                path.tp.scale(p, p, h);
            }
        }
        if path.events >= settings.max_events_per_path {
            st.truncated_paths += 1;
            return ControlFlow::Break(());
        }
        if !roulette(&mut path.tp, settings, rng) {
            return ControlFlow::Break(());
        }
        ControlFlow::Continue(())
    }

    /// A sphere jump ([`Settings::sphere_jumps`]) from the scattering point:
    /// the walk inside sphere `j` of the tables `t` is replaced by one draw
    /// from its exit distribution in band `h` ([`crate::sphere`]).
    #[allow(clippy::too_many_arguments)]
    fn sphere_jump(
        &self,
        obj: &Object,
        h: usize,
        t: &SphereExits,
        j: usize,
        path: &mut Path,
        est: &mut Estimate,
        rng: &mut Rng,
    ) {
        let omega = sphere::isotropic(rng);
        let (u, v) = rng.next_f64_pair();
        let exit = t.sample(h, j, u, v);
        let (f, p) = t.factors(j, exit);
        let arriving = path.tp;
        path.tp.scale(f, p, h);
        let r = t.radius_m(j);
        path.o += r * omega;
        match exit.bin {
            // Unscattered: the flight from x along ω, longer
            // than r. Its escape is one that x's connections
            // also make, so it keeps x as its vertex.
            None => {
                path.stretch.mu = path.d.dot(omega);
                path.stretch.t += r;
                path.d = omega;
            }
            // Scattered inside: the exit point is a vertex of its
            // own, connected with the exit distribution about ω
            // as its phase function, and its escapes are weighed
            // against that (without connections: weight 1).
            Some(_) => {
                path.d = sphere::leave(omega, exit.cos_theta, rng.next_f64());
                path.vertex = None;
                if let Some(planes) = self.planes {
                    // The branch's own probability per band,
                    // 1 − e^{−R_c}, goes into the densities
                    // (the tail is given_scattered's).
                    let mut branch = arriving;
                    branch.scale([1.0; 3], t.scattered_probability(j), h);
                    // No phase connection at a sphere's exit.
                    let reach = distance_to_lit_planes(planes, path.o, self.facing);
                    let p_attempt = attempt_probability(reach, obj.bands.sigma_t_min);
                    let conn = Connection {
                        h,
                        x: path.o,
                        d_in: omega,
                        p_attempt,
                        p_phase: 0.0,
                        shared: self.shared,
                        chains: self.chains,
                        exit: Some((t, j)),
                    };
                    // (No normalisation until the next event: the
                    // vertex's r and the path's share one scale.)
                    path.vertex =
                        Some(connect_vertex(self.scene, obj, Faces::Planes(planes), &branch, &conn, rng, est));
                    path.stretch.mu = exit.cos_theta;
                    path.stretch.t = 0.0;
                    path.stretch.refl = None;
                } else {
                    path.tp.normalise();
                }
            }
        }
        path.safe = self.convex.map_or(0.0, |planes| distance_to_planes(planes, path.o));
    }

    /// One step outside the object: the closest of object and board
    /// (`enter_object`, `board_bounce`), else the escape to the sky.
    fn outside_step(&self, path: &mut Path, est: &mut Estimate, rng: &mut Rng, st: &mut Stats) -> ControlFlow<()> {
        let scene = self.scene;
        let (o, d) = (path.o, path.d);
        let obj_hit = scene.object.as_ref().and_then(|obj| obj.accel.intersect(o, d, f64::INFINITY));
        let board_hit = scene.board.as_ref().and_then(|bd| bd.intersect(o, d));
        let t_obj = obj_hit.map_or(f64::INFINITY, |h| h.t);
        path.first_hit.get_or_insert(match board_hit {
            Some((t_board, _)) if t_board < t_obj => FirstHit::Board,
            _ if t_obj < f64::INFINITY => FirstHit::Object,
            _ => FirstHit::Environment,
        });
        match board_hit {
            Some((t_board, rho)) if t_board < t_obj => self.board_bounce(t_board, rho, path, est, rng, st),
            _ => match obj_hit {
                Some(hit) => self.enter_object(&hit, path, est, rng, st),
                None => {
                    self.escape(path, est);
                    ControlFlow::Break(())
                }
            },
        }
    }

    /// The path escapes to the environment: its radiance, weighed against
    /// the medium connections from the path's vertex (balance heuristic),
    /// against the board's connection through the object, or against the
    /// board's next-event estimation (power heuristic).
    fn escape(&self, path: &Path, est: &mut Estimate) {
        let scene = self.scene;
        let (o, d, tp) = (path.o, path.d, &path.tp);
        let l = scene.environment.radiance(o, d);
        let beta = tp.effective();
        if let Some(v) = path.vertex {
            // Weighed against the medium connections from v.x (balance heuristic).
            let obj = scene.object.as_ref().expect("a medium vertex without an object").walked_after(path.events);
            // A mesh's connection makes this path only if it
            // finds the face the path left through.
            let made = self.planes.is_some()
                || v.p_attempt > 0.0 && {
                    let eta = if self.shared { obj.eta_mean } else { obj.eta(path.hero.unwrap_or(0)) };
                    mesh_exit_through(&obj.accel, v.x, d, eta, path.stretch.triangle)
                };
            let p_conn = if made { v.p_attempt * scene.environment.pdf(v.x, d) } else { 0.0 };
            let p_phase = if v.p_phase > 0.0 {
                let ph = band_phases(obj, |k| v.r[k] > 0.0, path.hero.unwrap_or(0), path.stretch.mu);
                v.p_phase * path.stretch.jacobian * mean_weighted(&v.r, &ph)
            } else {
                0.0
            };
            let stretch_pdf = path.stretch.pdf;
            let denom = p_conn * v.mean_r + stretch_pdf * tp.mean_r() + p_phase;
            if denom > 0.0 {
                for (c, lc) in l.iter().enumerate() {
                    est.add(c, tp.beta[c] * stretch_pdf * lc / denom);
                }
            }
        } else if let Some(c) = path.chain.filter(|c| c.out) {
            // Weighed against the board's connection through the object (balance heuristic).
            // (The connection is made where the object blocks the
            // board's straight view along ω_o.)
            let made = c.mirror
                || d.dot(c.n) > 0.0
                    && scene.object.as_ref().is_some_and(|obj| obj.accel.occluded(c.y, d, f64::INFINITY));
            let p_nee = if made { scene.environment.pdf(c.y, d) } else { 0.0 };
            let denom = p_nee * mean_weighted(&c.r, &[1.0; 3]) + c.pdf * tp.mean_r();
            if denom > 0.0 {
                for (k, lk) in l.iter().enumerate() {
                    est.add(k, tp.beta[k] * c.pdf * lk / denom);
                }
            }
        } else {
            let w = match path.last_diffuse_pdf {
                Some(pdf_bsdf) => power_heuristic(pdf_bsdf, scene.environment.pdf(o, d)),
                None => 1.0,
            };
            for c in 0..3 {
                est.add(c, beta[c] * l[c] * w);
            }
        }
    }
}

/// The sphere-jump tables a path in `obj`'s medium uses ([`Settings::sphere_jumps`]).
#[inline]
pub(super) fn sphere_tables<'a>(obj: &'a Object, settings: &Settings) -> Option<&'a SphereExits> {
    if settings.sphere_jumps && settings.derivatives.is_empty() {
        obj.sphere_exits()
    } else {
        None
    }
}

/// Power heuristic weight of a strategy with pdf `a` against one with pdf `b`.
#[inline]
pub(super) fn power_heuristic(a: f64, b: f64) -> f64 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}
