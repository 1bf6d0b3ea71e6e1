//! The 3D digital twin: unidirectional volumetric path tracing of a
//! translucent object on a checkerboard under an HDR environment (SPEC §4).
//!
//! # What is computed
//!
//! Each pixel's value is the mean radiance L [W m⁻² sr⁻¹, in the units of
//! the environment map] arriving at the camera through that pixel's square
//! (box filter, [`crate::camera`]), in three bands R, G, B of CIE RGB. Every
//! pixel also gets the variance of that mean, estimated from its samples, so
//! a render can be compared with another by a per-pixel z-test.
//!
//! # Scene
//!
//! * One **object**: a closed triangle mesh ([`Accel`]) whose boundary is a
//!   [`Boundary`] (smooth dielectric now: unpolarised Fresnel and Snell,
//!   [`crate::fresnel`]; the rough and measured-normal microfacet boundaries
//!   of SPEC §2 join this enum) around a homogeneous [`Medium`]: scattering
//!   and absorption coefficients μ_s, μ_a [1/m], a phase function and the
//!   index n per band.
//! * A **checkerboard** ([`Board`]): a finite plane, Lambertian (two-sided),
//!   reflectance per square from two RGB values or an image texture.
//! * The **environment** ([`Environment`]): equirectangular radiance at
//!   infinity or on the finite sphere of SPEC §4.
//!
//! # Estimator
//!
//! Paths start at the camera. At the object's boundary the path chooses
//! reflection with probability F (the Fresnel reflectance of the path's
//! band) and refraction otherwise, so the Fresnel factors cancel. **Bands:**
//! at its first contact with the object a path picks one band b uniformly
//! (probability 1/3) and carries 3·β_b in that band and 0 in the others
//! from then on (SPEC §4; one-sample estimator of the three bands, unbiased
//! because each band is picked with probability 1/3 and weighted by 3).
//! Inside, free flights are drawn with density μ_t e^{−μ_t s} (band b);
//! a flight that reaches the boundary first crosses it (probability of that
//! = e^{−μ_t t}, which is exactly the transmittance), otherwise the path
//! scatters: β_b ← β_b μ_s/μ_t and a new direction is drawn from the phase
//! function (weight 1). There is no depth limit.
//!
//! **Russian roulette** acts on the path throughput only, never on the
//! depth: when max β < 1/4 the path survives with probability 4·max β and
//! its β is divided by that probability (unbiased; the test renders the
//! same scene with and without roulette). A slab of optical depth ≈ 90 with
//! albedo 0.9993 keeps β ≈ 3 · 0.9993ⁿ for thousands of events, so its long
//! subsurface paths are not cut early (a depth-based roulette such as
//! Mitsuba's default starts at depth 5 and loses most of them).
//!
//! **On the board** (diffuse, reflectance ρ) the environment is sampled by
//! next-event estimation ([`Environment::sample`], pdf in solid angle *at
//! the board point*, which on the finite sphere differs from the pdf at the
//! sphere's centre), shadow rays blocked by the object (a smooth dielectric
//! cannot be connected through), and the next direction is drawn
//! cosine-weighted (pdf cos θ/π, weight ρ). The two strategies for light
//! that arrives straight from the environment are combined by multiple
//! importance sampling with the power heuristic (Veach & Guibas 1995):
//! NEE weight p_env²/(p_env² + p_bsdf²), and the same with the roles swapped
//! when a BSDF-sampled ray escapes directly. A ray that escapes after passing
//! through the object could not have been found by NEE and has weight 1.
//!
//! **Self-intersection:** a ray leaving a surface starts ε = 10⁻⁷ × (the
//! scene's extent) off the surface along the geometric normal (20 nm for a
//! 0.2 m scene), on the side it travels into.
//!
//! **Determinism:** sample k of pixel p draws from
//! [`Rng::new`]`(seed, k·2³² + p)`, so an image depends on the seed and the
//! sample count only, never on the thread count or the tile order.
//!
//! ```
//! use glam::DVec3;
//! use lucent_render::{camera::Camera, env::{Environment, Projection}, tracer::*};
//! // An empty scene under a constant sky: every pixel sees the sky exactly.
//! let camera = Camera::look_at(8, 6, DVec3::new(0.0, -1.0, 1.0), DVec3::ZERO, DVec3::Z, 40.0).unwrap();
//! let env = Environment::constant([0.5, 1.0, 2.0], Projection::Infinite);
//! let scene = Scene::new(None, None, env, camera).unwrap();
//! let (img, _) = render(&scene, &Settings { spp: 4, ..Settings::default() }, &mut |_| {});
//! assert_eq!(img.mean[0], [0.5, 1.0, 2.0]);
//! ```

use crate::accel::Accel;
use crate::camera::Camera;
use crate::env::Environment;
use crate::fresnel;
use crate::phase::Phase;
use crate::rng::Rng;
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::{FRAC_1_PI, TAU};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use thiserror::Error;

/// Why a scene could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SceneError {
    #[error("medium band {band}: μ_s = {sigma_s} and μ_a = {sigma_a} /m must be finite and ≥ 0 with μ_s + μ_a > 0")]
    BadCoefficients { band: usize, sigma_s: f64, sigma_a: f64 },
    #[error("boundary band {band}: the relative index n = {eta} must be finite and > 0")]
    BadIndex { band: usize, eta: f64 },
    #[error("board: {0}")]
    BadBoard(String),
    #[error("the object has no triangles")]
    EmptyObject,
}

/// The object's boundary: the closed set of interface models.
#[derive(Debug, Clone, PartialEq)]
pub enum Boundary {
    /// A smooth dielectric with index `eta` per band inside (air, n = 1, outside).
    Smooth { eta: [f64; 3] },
}

impl Boundary {
    fn eta(&self, band: usize) -> f64 {
        match self {
            Boundary::Smooth { eta } => eta[band],
        }
    }
}

/// A homogeneous medium, per band R, G, B.
#[derive(Debug, Clone, PartialEq)]
pub struct Medium {
    /// Scattering coefficient μ_s per band, 1/m.
    pub sigma_s: [f64; 3],
    /// Absorption coefficient μ_a per band, 1/m.
    pub sigma_a: [f64; 3],
    /// Phase function per band.
    pub phase: [Phase; 3],
}

/// The object: a closed mesh, its boundary and its interior medium.
#[derive(Debug, Clone)]
pub struct Object {
    pub accel: Accel,
    pub boundary: Boundary,
    pub medium: Medium,
}

impl Object {
    /// Checks the coefficients and indices.
    pub fn new(accel: Accel, boundary: Boundary, medium: Medium) -> Result<Self, SceneError> {
        if accel.is_empty() {
            return Err(SceneError::EmptyObject);
        }
        for b in 0..3 {
            let (s, a) = (medium.sigma_s[b], medium.sigma_a[b]);
            if !(s.is_finite() && a.is_finite() && s >= 0.0 && a >= 0.0 && s + a > 0.0) {
                return Err(SceneError::BadCoefficients { band: b, sigma_s: s, sigma_a: a });
            }
            let eta = boundary.eta(b);
            if !(eta.is_finite() && eta > 0.0) {
                return Err(SceneError::BadIndex { band: b, eta });
            }
        }
        Ok(Self { accel, boundary, medium })
    }
}

/// Reflectance of the board's squares.
#[derive(Debug, Clone, PartialEq)]
pub enum BoardReflectance {
    /// Square (a, b) has `even` when a + b is even, `odd` otherwise.
    Checker { even: [f64; 3], odd: [f64; 3] },
    /// An RGB image (row-major, row 0 at the board's v = 0 edge) stretched
    /// over the squares' area; nearest pixel.
    Texture { width: usize, height: usize, rgb: Vec<[f64; 3]> },
}

/// A rectangular checkerboard: corner `origin`, unit edge directions `u`
/// (along columns) and `v` (along rows), `columns × rows` squares of side
/// `square_m`, surrounded by a margin of `margin_m` with reflectance
/// `margin` (paper). Lambertian on both sides.
#[derive(Debug, Clone, PartialEq)]
pub struct Board {
    pub origin: DVec3,
    pub u: DVec3,
    pub v: DVec3,
    pub square_m: f64,
    pub columns: usize,
    pub rows: usize,
    pub margin_m: f64,
    pub margin: [f64; 3],
    pub reflectance: BoardReflectance,
}

impl Board {
    fn check(&self) -> Result<(), SceneError> {
        let bad = |s: &str| Err(SceneError::BadBoard(s.to_string()));
        if !(self.square_m > 0.0 && self.square_m.is_finite()) {
            return bad("square size must be finite and > 0");
        }
        if self.columns == 0 || self.rows == 0 {
            return bad("the board needs at least one row and one column");
        }
        if !(self.margin_m >= 0.0 && self.margin_m.is_finite()) {
            return bad("margin must be finite and ≥ 0");
        }
        if (self.u.length() - 1.0).abs() > 1e-9
            || (self.v.length() - 1.0).abs() > 1e-9
            || self.u.dot(self.v).abs() > 1e-9
        {
            return bad("edge directions u and v must be orthonormal");
        }
        let rho_ok = |r: &[f64; 3]| r.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x));
        let ok = match &self.reflectance {
            BoardReflectance::Checker { even, odd } => rho_ok(even) && rho_ok(odd),
            BoardReflectance::Texture { width, height, rgb } => {
                *width > 0 && *height > 0 && rgb.len() == width * height && rgb.iter().all(rho_ok)
            }
        };
        if !ok || !rho_ok(&self.margin) {
            return bad("reflectances must lie in [0, 1] (a texture must have width × height pixels)");
        }
        Ok(())
    }

    fn normal(&self) -> DVec3 {
        self.u.cross(self.v)
    }

    /// Distance to the board along the ray, and the reflectance there.
    #[inline]
    fn intersect(&self, o: DVec3, d: DVec3) -> Option<(f64, [f64; 3])> {
        let n = self.normal();
        let dn = d.dot(n);
        if dn == 0.0 {
            return None;
        }
        let t = (self.origin - o).dot(n) / dn;
        if !(t > 0.0 && t.is_finite()) {
            return None;
        }
        let p = o + t * d - self.origin;
        let (x, y) = (p.dot(self.u), p.dot(self.v));
        let (w, h) = (self.columns as f64 * self.square_m, self.rows as f64 * self.square_m);
        let m = self.margin_m;
        if x < -m || y < -m || x > w + m || y > h + m {
            return None;
        }
        if x < 0.0 || y < 0.0 || x >= w || y >= h {
            return Some((t, self.margin));
        }
        let rho = match &self.reflectance {
            BoardReflectance::Checker { even, odd } => {
                let (a, b) = ((x / self.square_m) as usize, (y / self.square_m) as usize);
                if (a + b) % 2 == 0 {
                    *even
                } else {
                    *odd
                }
            }
            BoardReflectance::Texture { width, height, rgb } => {
                let i = ((x / w * *width as f64) as usize).min(width - 1);
                let j = ((y / h * *height as f64) as usize).min(height - 1);
                rgb[j * width + i]
            }
        };
        Some((t, rho))
    }
}

/// Everything a render needs.
#[derive(Debug, Clone)]
pub struct Scene {
    pub object: Option<Object>,
    pub board: Option<Board>,
    pub environment: Environment,
    pub camera: Camera,
    /// Offset of rays leaving a surface, metres.
    pub epsilon_m: f64,
}

impl Scene {
    /// Assembles a scene; ε is 10⁻⁷ of the extent of the object, board and camera.
    pub fn new(
        object: Option<Object>,
        board: Option<Board>,
        environment: Environment,
        camera: Camera,
    ) -> Result<Self, SceneError> {
        if let Some(b) = &board {
            b.check()?;
        }
        let mut extent = camera.position().abs().max_element();
        if let Some(o) = &object {
            let (lo, hi) = o.accel.bounds();
            extent = extent.max(lo.abs().max_element()).max(hi.abs().max_element());
        }
        if let Some(b) = &board {
            extent =
                extent.max(b.origin.abs().max_element() + (b.columns.max(b.rows) as f64) * b.square_m + b.margin_m);
        }
        Ok(Self { object, board, environment, camera, epsilon_m: 1e-7 * extent.max(1e-3) })
    }
}

/// How long to render and with what.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// Samples per pixel in all (the render stops earlier if `time_budget_s` runs out).
    pub spp: u32,
    /// Stop after the pass that exceeds this wall time, seconds.
    pub time_budget_s: Option<f64>,
    /// Samples per pixel per progressive pass.
    pub spp_per_pass: u32,
    pub seed: u64,
    /// Throughput below which Russian roulette starts; `None` disables it.
    pub roulette_threshold: Option<f64>,
    /// Safety stop: a path with more scattering events is ended and counted
    /// in [`Stats::truncated_paths`] (reported, never silent).
    pub max_events_per_path: u64,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            spp: 64,
            time_budget_s: None,
            spp_per_pass: 4,
            seed: 1,
            roulette_threshold: Some(0.25),
            max_events_per_path: 10_000_000,
        }
    }
}

/// The rendered image: per pixel the mean, the variance of the mean and
/// the number of samples, row-major from the top-left pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub mean: Vec<[f64; 3]>,
    pub variance_of_mean: Vec<[f64; 3]>,
    pub samples: Vec<u32>,
}

/// Counters of a render.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stats {
    pub samples: u64,
    /// Scattering events inside the medium.
    pub events: u64,
    /// Ray–surface interactions (object boundary and board).
    pub surface_hits: u64,
    /// Paths that found no boundary while inside the object (a hole in the mesh).
    pub leaked_paths: u64,
    /// Paths ended by `max_events_per_path`.
    pub truncated_paths: u64,
    pub passes: u32,
    pub wall_s: f64,
}

impl Stats {
    fn add(&mut self, o: &Stats) {
        self.samples += o.samples;
        self.events += o.events;
        self.surface_hits += o.surface_hits;
        self.leaked_paths += o.leaked_paths;
        self.truncated_paths += o.truncated_paths;
    }
}

/// Progress after each pass.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    pub spp_done: u32,
    pub spp_target: u32,
    pub elapsed_s: f64,
    pub stats: Stats,
}

/// Renders `scene` progressively; `on_pass` is called after every pass.
/// Stops at `settings.spp` samples per pixel, after the pass that exceeds the
/// time budget, or when `cancel` (if given) is set.
pub fn render(scene: &Scene, settings: &Settings, on_pass: &mut dyn FnMut(&Progress)) -> (Image, Stats) {
    render_cancellable(scene, settings, on_pass, None)
}

/// [`render`] with a cancellation flag checked between passes.
pub fn render_cancellable(
    scene: &Scene,
    settings: &Settings,
    on_pass: &mut dyn FnMut(&Progress),
    cancel: Option<&AtomicBool>,
) -> (Image, Stats) {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let n = w * h;
    let mut sum = vec![[0.0f64; 3]; n];
    let mut sum_sq = vec![[0.0f64; 3]; n];
    let mut stats = Stats::default();
    let start = Instant::now();
    let per_pass = settings.spp_per_pass.max(1);
    let mut done = 0u32;
    while done < settings.spp {
        let k0 = done;
        let k1 = (done + per_pass).min(settings.spp);
        let pass_stats = sum
            .par_chunks_mut(w)
            .zip(sum_sq.par_chunks_mut(w))
            .enumerate()
            .map(|(j, (row, row_sq))| {
                let mut st = Stats::default();
                for i in 0..w {
                    let pixel = (j * w + i) as u64;
                    for k in k0..k1 {
                        let mut rng = Rng::new(settings.seed, (u64::from(k) << 32) | pixel);
                        let u = [rng.next_f64(), rng.next_f64()];
                        let (o, d) = scene.camera.ray(i, j, u);
                        let l = trace(scene, settings, o, d, &mut rng, &mut st);
                        for c in 0..3 {
                            row[i][c] += l[c];
                            row_sq[i][c] += l[c] * l[c];
                        }
                    }
                }
                st.samples = (w as u64) * u64::from(k1 - k0);
                st
            })
            .reduce(Stats::default, |mut a, b| {
                a.add(&b);
                a
            });
        stats.add(&pass_stats);
        stats.passes += 1;
        done = k1;
        let elapsed = start.elapsed().as_secs_f64();
        stats.wall_s = elapsed;
        on_pass(&Progress { spp_done: done, spp_target: settings.spp, elapsed_s: elapsed, stats });
        if settings.time_budget_s.is_some_and(|b| elapsed >= b) || cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            break;
        }
    }
    let m = f64::from(done.max(1));
    let mean: Vec<[f64; 3]> = sum.iter().map(|s| s.map(|v| v / m)).collect();
    let variance_of_mean = sum
        .iter()
        .zip(&sum_sq)
        .map(|(s, q)| {
            std::array::from_fn(|c| {
                if done > 1 {
                    ((q[c] - s[c] * s[c] / m) / (m - 1.0)).max(0.0) / m
                } else {
                    f64::INFINITY
                }
            })
        })
        .collect();
    stats.wall_s = start.elapsed().as_secs_f64();
    (Image { width: w, height: h, mean, variance_of_mean, samples: vec![done; n] }, stats)
}

/// Power heuristic weight of a strategy with pdf `a` against one with pdf `b`.
#[inline]
fn power_heuristic(a: f64, b: f64) -> f64 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// Cosine-weighted direction about the unit normal `n` (Malley's method).
#[inline]
fn cosine_direction(n: DVec3, u1: f64, u2: f64) -> (DVec3, f64) {
    let r = u1.sqrt();
    let phi = TAU * u2;
    let (s, c) = phi.sin_cos();
    let z = (1.0 - u1).max(0.0).sqrt();
    let (t, b) = crate::phase::orthonormal_basis(n.to_array());
    let (t, b) = (DVec3::from_array(t), DVec3::from_array(b));
    ((r * c) * t + (r * s) * b + z * n, z * FRAC_1_PI)
}

/// One camera path: the radiance estimate it carries back, per band.
fn trace(scene: &Scene, settings: &Settings, mut o: DVec3, mut d: DVec3, rng: &mut Rng, st: &mut Stats) -> [f64; 3] {
    let eps = scene.epsilon_m;
    let mut beta = [1.0f64; 3];
    let mut radiance = [0.0f64; 3];
    let mut band: Option<usize> = None;
    let mut inside = false;
    // pdf of the last diffuse bounce's direction (for MIS when the ray escapes straight to the sky).
    let mut last_diffuse_pdf: Option<f64> = None;
    let mut events = 0u64;
    loop {
        if inside {
            // In the medium: `band` is set, the object exists.
            let (Some(obj), Some(b)) = (&scene.object, band) else {
                break;
            };
            let Some(hit) = obj.accel.exit(o, d) else {
                st.leaked_paths += 1;
                break;
            };
            let sigma_t = obj.medium.sigma_s[b] + obj.medium.sigma_a[b];
            let s = -(1.0 - rng.next_f64()).ln() / sigma_t;
            if s < hit.t {
                o += s * d;
                beta[b] *= obj.medium.sigma_s[b] / sigma_t;
                let (u1, u2) = rng.next_f64_pair();
                d = DVec3::from_array(obj.medium.phase[b].sample_direction(d.to_array(), u1, u2));
                events += 1;
                if events >= settings.max_events_per_path {
                    st.truncated_paths += 1;
                    break;
                }
                if !roulette(&mut beta, settings, rng) {
                    break;
                }
                continue;
            }
            // Leaving: the normal facing along the ray.
            st.surface_hits += 1;
            let p = o + hit.t * d;
            let n_out = if hit.normal.dot(d) >= 0.0 { hit.normal } else { -hit.normal };
            let eta = obj.boundary.eta(b);
            let cos_i = d.dot(n_out);
            let f = fresnel::reflectance(cos_i, 1.0 / eta);
            if rng.next_f64() < f {
                d -= 2.0 * d.dot(n_out) * n_out;
                o = p - eps * n_out;
            } else {
                d = refract(d, n_out, 1.0 / eta);
                o = p + eps * n_out;
                inside = false;
            }
            last_diffuse_pdf = None;
            continue;
        }

        // Outside: the closest of object and board, else the sky.
        let obj_hit = scene.object.as_ref().and_then(|obj| obj.accel.intersect(o, d, f64::INFINITY));
        let board_hit = scene.board.as_ref().and_then(|bd| bd.intersect(o, d));
        let t_obj = obj_hit.map_or(f64::INFINITY, |h| h.t);
        match board_hit {
            Some((t_board, rho)) if t_board < t_obj => {
                st.surface_hits += 1;
                let board = scene.board.as_ref().expect("board hit without a board");
                let p = o + t_board * d;
                let n = board.normal();
                let n = if n.dot(d) < 0.0 { n } else { -n };
                let origin = p + eps * n;
                // Next-event estimation of the environment.
                if let Some(sample) = scene.environment.sample(origin, [rng.next_f64(), rng.next_f64()]) {
                    let cos = sample.dir.dot(n);
                    if cos > 0.0 && sample.pdf > 0.0 {
                        let blocked = scene
                            .object
                            .as_ref()
                            .is_some_and(|obj| obj.accel.occluded(origin, sample.dir, f64::INFINITY));
                        if !blocked {
                            let w = power_heuristic(sample.pdf, cos * FRAC_1_PI);
                            for c in 0..3 {
                                radiance[c] += beta[c] * rho[c] * FRAC_1_PI * cos * sample.radiance[c] * w / sample.pdf;
                            }
                        }
                    }
                }
                let (u1, u2) = rng.next_f64_pair();
                let (nd, pdf) = cosine_direction(n, u1, u2);
                for c in 0..3 {
                    beta[c] *= rho[c];
                }
                d = nd;
                o = origin;
                last_diffuse_pdf = Some(pdf);
                if !roulette(&mut beta, settings, rng) {
                    break;
                }
            }
            _ => {
                let Some(hit) = obj_hit else {
                    // Escaped to the environment.
                    let l = scene.environment.radiance(o, d);
                    let w = match last_diffuse_pdf {
                        Some(pdf_bsdf) => power_heuristic(pdf_bsdf, scene.environment.pdf(o, d)),
                        None => 1.0,
                    };
                    for c in 0..3 {
                        radiance[c] += beta[c] * l[c] * w;
                    }
                    break;
                };
                // The object's boundary from outside.
                st.surface_hits += 1;
                let obj = scene.object.as_ref().expect("object hit without an object");
                let b = *band.get_or_insert_with(|| {
                    let b = ((rng.next_f64() * 3.0) as usize).min(2);
                    let keep = 3.0 * beta[b];
                    beta = [0.0; 3];
                    beta[b] = keep;
                    b
                });
                let p = o + hit.t * d;
                let n_in = if hit.normal.dot(d) < 0.0 { hit.normal } else { -hit.normal };
                let eta = obj.boundary.eta(b);
                let f = fresnel::reflectance(-d.dot(n_in), eta);
                if rng.next_f64() < f {
                    d -= 2.0 * d.dot(n_in) * n_in;
                    o = p + eps * n_in;
                } else {
                    d = refract(d, -n_in, eta);
                    o = p - eps * n_in;
                    inside = true;
                }
                last_diffuse_pdf = None;
            }
        }
    }
    st.events += events;
    radiance
}

/// Russian roulette on the throughput; false = the path ends.
#[inline]
fn roulette(beta: &mut [f64; 3], settings: &Settings, rng: &mut Rng) -> bool {
    let Some(threshold) = settings.roulette_threshold else {
        return true;
    };
    let m = beta[0].max(beta[1]).max(beta[2]);
    if m >= threshold {
        return true;
    }
    let q = m / threshold;
    if rng.next_f64() >= q {
        return false;
    }
    for x in beta.iter_mut() {
        *x /= q;
    }
    true
}

/// Refraction of unit `d` through an interface with unit normal `n` on the
/// transmitted side (d·n > 0), relative index `eta` = n_t/n_i. The caller
/// has already chosen refraction, so total internal reflection cannot
/// occur (F = 1 there); it falls back to the mirror direction defensively.
#[inline]
fn refract(d: DVec3, n: DVec3, eta: f64) -> DVec3 {
    let cos_i = d.dot(n);
    let sin_t2 = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin_t2 >= 1.0 {
        return d - 2.0 * cos_i * n;
    }
    let cos_t = (1.0 - sin_t2).sqrt();
    ((d - cos_i * n) / eta + cos_t * n).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refraction_obeys_snell() {
        let n = DVec3::Z;
        let d = DVec3::new(0.6, 0.0, 0.8);
        let t = refract(d, n, 1.5);
        assert!((t.length() - 1.0).abs() < 1e-12);
        assert!((0.6 - 1.5 * t.x).abs() < 1e-12 && t.z > 0.0);
        let back = refract(t, n, 1.0 / 1.5);
        assert!((back - d).length() < 1e-12);
    }
}
