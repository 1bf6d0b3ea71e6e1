//! The 3D digital twin: unidirectional volumetric path tracing of a
//! translucent object on a checkerboard under an HDR environment (docs/method.md §5).
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
//! * One **object**: a closed triangle mesh ([`Accel`]) whose boundary is an
//!   [`Interface`] (smooth dielectric: unpolarised Fresnel and Snell,
//!   [`crate::fresnel`]; or rough: the microfacet BSDF of Walter et al. 2007
//!   with an analytic or measured-normal microsurface, docs/method.md §2,
//!   [`crate::interface`], sampled with its weight f|cos|/pdf, radiance
//!   transport) around a homogeneous [`Medium`] per band: scattering and
//!   absorption coefficients μ_s, μ_a [1/m], a phase function and the index n.
//! * A **checkerboard** ([`Board`]): a finite plane, Lambertian (two-sided),
//!   reflectance per square from two RGB values or an image texture.
//! * The **environment** ([`Environment`]): equirectangular radiance at
//!   infinity or on the finite sphere of docs/method.md §5.
//!
//! # Estimator
//!
//! Paths start at the camera. At the object's boundary the path chooses
//! reflection with probability F (the Fresnel reflectance of the path's
//! band) and refraction otherwise, so the Fresnel factors cancel.
//!
//! **Bands.** At its first contact with the object a path picks one band h
//! uniformly (probability 1/3); h drives the sampling from then on (free
//! flights with density μ_t,h e^{−μ_t,h s}, directions from h's phase
//! function, h's index at the boundary). The plain estimator of docs/method.md §5 carries 3·β_h
//! in band h and 0 in the others ([`Settings::spectral_mis`] = false, and
//! always when the index differs between bands: a refraction direction then
//! belongs to one band only). When the index is the same in all bands the
//! path carries all three (**spectral MIS**, the one-sample balance
//! heuristic over the band that drives the sampling; Wilkie et al. 2014,
//! Miller et al. 2019): band c's estimate is f_c / ((1/3) Σ_k p_k), f_c the
//! path's contribution in band c and p_k its density had band k driven it.
//! The weight is at most 3·Π(μ_s/μ_t) per path, so it is never much worse
//! than the single band and, for bands with similar coefficients, close to
//! three independent paths for the price of one. A flight ends at a
//! scattering event (contribution μ_s,c e^{−μ_t,c s}) or at the boundary
//! (e^{−μ_t,c t}, exactly the probability of getting there). There is no
//! depth limit.
//!
//! **Connections from inside.** A smooth boundary makes the light that
//! leaves the medium a delta in direction, so no shadow ray can reach the
//! environment from a scattering point x. For a convex object (its flat
//! faces known, [`Accel::convex_planes`]) the connection is made backwards:
//! a direction ω_o is drawn from the environment's sampler at x; for each
//! face with n·ω_o > 0 Snell's law gives the inside direction ω_i that
//! refracts into ω_o, and if the ray x + tω_i leaves through that face (and
//! the board does not block ω_o) the path gets p(ω_in·ω_i) e^{−μ_t t}
//! (1 − F) L(q, ω_o) cos θ_o / (n² cos θ_i) / p_env(x, ω_o), the last
//! factor dω_i/dω_o of the refraction. Phase sampling finds the same light
//! when its path leaves straight through a face; the two are combined by the
//! balance heuristic (over bands too). A third strategy, the **phase
//! connection** ([`Settings::phase_connection`]), draws ω_i from the phase
//! function instead, follows x + tω_i to the face it leaves through,
//! refracts into ω_o and takes e^{−μ_t t} and (1 − F) as factors rather than
//! sampling them: the phase function's forward peak (g ≈ 0.97: most of its
//! mass within a few degrees), where an environment-sampled ω_o rarely
//! lands and then carries a huge p(ω_in·ω_i), is sampled by this strategy,
//! and the path's own escape, which must first fly unscattered to the
//! face, gives up most of its weight to it. All three share one balance
//! heuristic (densities in outside solid angle). A connection is attempted with
//! probability exp(−μ_t d), d the distance to the nearest face plane that
//! looks into the hemisphere the environment's sampling favours (not the
//! bottom face on a board, which hides that face's connections), a
//! bound on its transmittance (the probability is part of its density in
//! the weights). Connections are skipped under a uniform environment, where
//! they cannot help, and through a rough boundary, which this connection
//! does not model ([`Settings::medium_nee`]).
//!
//! **Specular chains** ([`Settings::specular_chains`], off by default): the
//! environment and phase connections also follow one reflection at a face
//! before the refraction out (the environment connection by the image
//! method: the ray from x's mirror image across the reflecting face), the
//! reflection made with probability max_c R_c and weighted by its inverse;
//! and the board's next-event estimation, where the object blocks its
//! shadow ray, connects through the object (in at one face, one
//! unscattered flight, out at another). The
//! path's own escape along such a chain is weighted against them (balance
//! heuristic), where it used to count in full and, meeting a lamp, made
//! the object's bright outliers.
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
//! **Options** (none on by default; each is z-tested against the default
//! in `tests/tracer.rs`, per pixel and on the object's mean):
//! [`Settings::split_entry`] follows both the reflection (weight F_c) and
//! the refraction (1 − F_c) where a path meets the object from outside;
//! [`Dispersion::SharedDirections`] refracts with the bands' mean index
//! while keeping each band's Fresnel factors, so a path carries all bands
//! (approximate: the refracted directions of the bands no longer spread);
//! [`Sampling::ObjectWeighted`] gives pixels whose camera rays hit the
//! object more samples per pass, from the two regions' median per-sample
//! relative variances (a region-level statistic over thousands of pixels).
//!
//! **Figures.** Every [`Image`] counts per pixel the camera rays whose first
//! hit is the object or the board; [`Image::region_errors`] gives the median
//! and 90th percentile of the per-pixel relative standard error over the
//! object's pixels, the board's and all, and [`Settings::target_rel_error`]
//! stops on the object's median.
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
use crate::interface::{Interface, Lobe, Transport};
use crate::medium::{Medium, MediumError};
use crate::microfacet::MicrofacetError;
use crate::phase::{eval_each, Phase};
use crate::rng::Rng;
use crate::sphere::{self, SphereExits};
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::{FRAC_1_PI, TAU};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::OnceLock;
use std::time::Instant;
use thiserror::Error;

/// Why a scene could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SceneError {
    #[error("medium band {band}: {source}")]
    Medium { band: usize, source: MediumError },
    #[error("board: square size {square_m} m must be finite and > 0")]
    BoardSquare { square_m: f64 },
    #[error("board: the board needs at least one row and one column (got {columns} × {rows})")]
    BoardEmpty { columns: usize, rows: usize },
    #[error("board: margin {margin_m} m must be finite and ≥ 0")]
    BoardMargin { margin_m: f64 },
    #[error("board: edge directions u and v must be orthonormal")]
    BoardAxes,
    #[error("board: reflectances must lie in [0, 1] (a texture must have width × height pixels)")]
    BoardReflectance,
    #[error("the object has no triangles")]
    EmptyObject,
    #[error("rough boundary: {0}")]
    BadSurface(#[from] MicrofacetError),
}

/// The least depth, in mean free paths of the similar medium, across the
/// object's thinnest side that [`Object::similar`] keeps. Measured against
/// the exact walk (5 Dec 2026): 3 keeps the PVP plaque IOL1068-13 (g′ = 0.82)
/// within 0.5 % and the demo plaque within +1.0–1.5 %; 1.5 halves the PVP
/// plaque's time to a given noise but moves its mean by −1 to −2.6 %.
pub const SIMILAR_MIN_DEPTH: f64 = 3.0;

/// The least depth, in mean free paths across the object's thinnest side,
/// of the similar medium a path walks after the first events
/// ([`Object::similar_floored_for`]). Thinner, light bounces between the
/// faces unscattered, by more reflections than the specular chains
/// connect: on the PVP plaque (5 Dec 2026) the isotropic medium of
/// 0.55–0.78 mean free paths raised the plaque's 99th percentile error from
/// 15 % to 25 % and moved its mean by +0.8 %; this floor (g′ 0.45 there)
/// kept both (−0.2 to +0.1 %).
pub const SIMILAR_LATER_MIN_DEPTH: f64 = 1.0;

/// The object: a closed mesh, its interface with the air around it and
/// its interior medium per band R, G, B (each band's index
/// [`Medium::n`] is the interface's index ratio in that band).
#[derive(Debug, Clone)]
pub struct Object {
    pub accel: Accel,
    /// The boundary, in the frame whose +z is the outward normal (air
    /// above, the medium below: η = n_c).
    pub interface: Interface,
    pub medium: [Medium; 3],
    /// Per-band constants derived once by [`Object::new`].
    bands: BandConstants,
    /// The bands' mean index, for refraction directions under
    /// [`Dispersion::SharedDirections`].
    eta_mean: f64,
    /// The sphere-jump tables ([`Settings::sphere_jumps`]), made on first
    /// use; `None` where jumps do not apply.
    spheres: OnceLock<Option<SphereExits>>,
    /// The scattering event from which a path walks the second object's
    /// medium instead ([`Object::similar_floored_for`]).
    later: Option<(u64, Box<Object>)>,
}

/// What the estimator needs to know about the bands, derived once.
#[derive(Debug, Clone, Copy)]
struct BandConstants {
    /// μ_t = μ_s + μ_a per band, 1/m.
    sigma_t: [f64; 3],
    /// The smallest μ_t, 1/m.
    sigma_t_min: f64,
    /// All bands share μ_t: the free-flight ratios are 1.
    same_sigma_t: bool,
    /// All bands share the phase function: the phase ratios are 1.
    same_phase: bool,
    /// All bands share the boundary's index, so one path can carry all
    /// three bands (spectral MIS); otherwise a path keeps one band.
    achromatic: bool,
}

impl Object {
    /// Checks the coefficients and indices.
    pub fn new(accel: Accel, interface: Interface, medium: [Medium; 3]) -> Result<Self, SceneError> {
        if accel.is_empty() {
            return Err(SceneError::EmptyObject);
        }
        for (band, m) in medium.iter().enumerate() {
            m.validate().map_err(|source| SceneError::Medium { band, source })?;
        }
        let sigma_t: [f64; 3] = std::array::from_fn(|b| medium[b].mu_t_per_m());
        let eta: [f64; 3] = std::array::from_fn(|b| medium[b].n);
        let bands = BandConstants {
            sigma_t,
            sigma_t_min: sigma_t[0].min(sigma_t[1]).min(sigma_t[2]),
            same_sigma_t: sigma_t[1] == sigma_t[0] && sigma_t[2] == sigma_t[0],
            same_phase: medium[1].phase == medium[0].phase && medium[2].phase == medium[0].phase,
            achromatic: eta[1] == eta[0] && eta[2] == eta[0],
        };
        let eta_mean = (eta[0] + eta[1] + eta[2]) / 3.0;
        Ok(Self { accel, interface, medium, bands, eta_mean, spheres: OnceLock::new(), later: None })
    }

    /// The object whose medium a path walks once it has scattered
    /// `events` times ([`Object::later`]).
    #[inline]
    fn walked_after(&self, events: u64) -> &Object {
        match &self.later {
            Some((from, later)) if events >= *from => later,
            _ => self,
        }
    }

    /// ([`Object::similar_floored_for`]) The scattering event from which a
    /// path walks the later similar medium, and that medium's
    /// object; `None` where the whole walk is in this object's medium.
    pub fn later(&self) -> Option<(u64, &Object)> {
        self.later.as_ref().map(|(from, o)| (*from, &**o))
    }

    /// The derivative of this object's coefficients along the central
    /// difference from `minus` (θ − δ) to `plus` (θ + δ), per unit of δ:
    /// ∂ln μ_s = (μ_s⁺ − μ_s⁻)/(2 μ_s), ∂μ_a = (μ_a⁺ − μ_a⁻)/2 per band, and
    /// the largest relative change of the phase functions (over 65 cosines)
    /// and indices between the three, which the derivative leaves out, if
    /// that is at most `tolerance` and the three agree in the rest (bounds
    /// and triangle count, the interface's kind (its roughness comes from
    /// the scene, not from the medium), the later medium's event and its
    /// μ_s and μ_a in the same ratio); `None` otherwise (the change needs
    /// renders of its own). A weight percentage changes the bands' phase
    /// functions (their spectral weights) and the mixture's index a little
    /// too.
    pub fn coefficient_derivative(
        &self,
        plus: &Object,
        minus: &Object,
        tolerance: f64,
    ) -> Option<(CoefficientDerivative, f64)> {
        let rel = |a: f64, b: f64| if a == b { 0.0 } else { (a - b).abs() / a.abs().max(b.abs()) };
        let left_out = |o: &Object| -> f64 {
            (0..3)
                .map(|c| {
                    let (p, q) = (&o.medium[c].phase, &self.medium[c].phase);
                    let phase = if p == q {
                        0.0
                    } else {
                        (0..=64)
                            .map(|i| {
                                let mu = -1.0 + 2.0 * f64::from(i) / 64.0;
                                rel(p.eval(mu), q.eval(mu))
                            })
                            .fold(0.0, f64::max)
                    };
                    phase.max(rel(o.medium[c].n, self.medium[c].n))
                })
                .fold(0.0, f64::max)
        };
        let alike = |o: &Object| {
            o.accel.bounds() == self.accel.bounds()
                && o.accel.len() == self.accel.len()
                && o.interface.is_rough() == self.interface.is_rough()
        };
        if !alike(plus) || !alike(minus) {
            return None;
        }
        let change = left_out(plus).max(left_out(minus));
        if change.is_nan() || change > tolerance {
            return None;
        }
        let d = CoefficientDerivative {
            d_ln_mu_s: std::array::from_fn(|c| {
                let m = self.medium[c].mu_s_per_m;
                if m > 0.0 {
                    (plus.medium[c].mu_s_per_m - minus.medium[c].mu_s_per_m) / (2.0 * m)
                } else {
                    0.0
                }
            }),
            d_mu_a_per_m: std::array::from_fn(|c| 0.5 * (plus.medium[c].mu_a_per_m - minus.medium[c].mu_a_per_m)),
        };
        if !d.d_ln_mu_s.iter().chain(&d.d_mu_a_per_m).all(|v| v.is_finite()) {
            return None;
        }
        match (self.later(), plus.later(), minus.later()) {
            (None, None, None) => Some((d, change)),
            (Some((k, l)), Some((kp, lp)), Some((km, lm))) if k == kp && k == km => {
                let (dl, later_change) = l.coefficient_derivative(lp, lm, tolerance)?;
                // The later medium's coefficients move with the input as the
                // first one's do up to its flat top's cut (≈ 4·10⁻⁴ in G on
                // IOL1068-09); the walk applies the first one's derivative
                // to both, leaving that difference out.
                let apart = (0..3)
                    .map(|c| {
                        let rel = |a: f64, b: f64| (a - b).abs() / a.abs().max(b.abs()).max(1e-300);
                        rel(dl.d_ln_mu_s[c], d.d_ln_mu_s[c]).max(rel(dl.d_mu_a_per_m[c], d.d_mu_a_per_m[c]))
                    })
                    .fold(0.0, f64::max);
                let change = change.max(later_change).max(apart);
                (change <= tolerance).then_some((d, change))
            }
            _ => None,
        }
    }

    /// The bands' phase functions.
    #[inline]
    fn phases(&self) -> [&Phase; 3] {
        [&self.medium[0].phase, &self.medium[1].phase, &self.medium[2].phase]
    }

    /// The tables of [`Settings::sphere_jumps`], made on the first call:
    /// `None` unless the object is convex and scatters isotropically in
    /// every band. Radii up to half the bounding box's shortest side.
    pub fn sphere_exits(&self) -> Option<&SphereExits> {
        self.spheres
            .get_or_init(|| {
                let isotropic =
                    self.medium.iter().all(|m| matches!(m.phase, Phase::HenyeyGreenstein { g } if g == 0.0));
                if !isotropic || self.accel.convex_planes().is_none() {
                    return None;
                }
                let (lo, hi) = self.accel.bounds();
                let albedo = std::array::from_fn(|c| self.medium[c].mu_s_per_m / self.bands.sigma_t[c]);
                Some(SphereExits::new(self.bands.sigma_t, albedo, 0.5 * (hi - lo).min_element()))
            })
            .as_ref()
    }

    /// The same object with each band's medium replaced by its similar one
    /// ([`Medium::similar`]: μ_s(1 − g), μ_a and n kept) of asymmetry at
    /// most `g_max`, raised where needed (the same g′ in every band) so
    /// that the similar medium stays at least [`SIMILAR_MIN_DEPTH`] mean
    /// free paths deep across the object's thinnest bounding-box side d in
    /// every band: g′ ≥ 1 − μ_s(1 − g) d / [`SIMILAR_MIN_DEPTH`]. (An
    /// optically thin similar medium would let the board be seen through it unscattered,
    /// where the exact walk blurs it by many small turns.) An
    /// approximation that makes the walk of a strongly forward-scattering
    /// medium far shorter (see the module documentation).
    pub fn similar(self, g_max: f64) -> Result<Self, SceneError> {
        self.similar_with(g_max, None)
    }

    /// [`Object::similar`] with the depth floor of [`SIMILAR_MIN_DEPTH`]
    /// held for the first `events` scattering events of a path only (≥ 1):
    /// that floor is for light that has scattered a few times, the
    /// unscattered view through the object above all. From its `events`-th
    /// event on a path walks the similar medium of g′ = `g_max` raised only
    /// as far as [`SIMILAR_LATER_MIN_DEPTH`] asks ([`Object::later`]; μ_s(1 −
    /// g), μ_a and n kept in both), where that is lower. A further
    /// approximation: light trapped by total internal reflection in a thin
    /// plaque leaves its trapped directions in fewer, larger turns
    /// (measured in docs/method.md#render-similarity-floor-events).
    pub fn similar_floored_for(self, g_max: f64, events: u64) -> Result<Self, SceneError> {
        self.similar_with(g_max, Some(events.max(1)))
    }

    fn similar_with(self, g_max: f64, floor_events: Option<u64>) -> Result<Self, SceneError> {
        let (lo, hi) = self.accel.bounds();
        let d = (hi - lo).min_element();
        // One g′ for all bands (the highest any band's floor asks for): the
        // bands' phase functions then differ only where their media differ,
        // and a path shared by the bands keeps weights near 1 (per-band g′
        // of 0.06–0.22 doubled the plaque's variance per sample).
        let floor_for = |depth: f64| {
            self.medium
                .iter()
                .map(|m| 1.0 - m.mu_s_per_m * (1.0 - m.phase.mean_cosine()) * d / depth)
                .fold(0.0_f64, f64::max)
                .min(0.999)
        };
        let g_first = g_max.max(floor_for(SIMILAR_MIN_DEPTH));
        let g_later = floor_events.map(|from| (from, g_max.max(floor_for(SIMILAR_LATER_MIN_DEPTH))));
        self.similar_at(g_first, g_later)
    }

    /// The same object with each band's medium replaced by its similar one
    /// of asymmetry at most `g_first` exactly (no depth floor), and, with
    /// `later` = (event, g), the medium of asymmetry at most g from that
    /// scattering event on where g < `g_first`: the media an earlier call of
    /// [`Object::similar`] or [`Object::similar_floored_for`] walked (its g′
    /// as `g_first`), for a slightly different medium. Renders that must
    /// share their random numbers (`lucent render --uncertainty`) then
    /// share the phase functions too.
    pub fn similar_at(self, g_first: f64, later: Option<(u64, f64)>) -> Result<Self, SceneError> {
        let similar_media = |g: f64| -> Result<[Medium; 3], SceneError> {
            let mut media = self.medium.clone();
            for (band, m) in media.iter_mut().enumerate() {
                *m = m.similar(g).map_err(|source| SceneError::Medium { band, source })?;
            }
            Ok(media)
        };
        let later = match later {
            Some((from, g)) if g < g_first => {
                let media = similar_media(g)?;
                Some((from, Box::new(Object::new(self.accel.clone(), self.interface.clone(), media)?)))
            }
            _ => None,
        };
        let media = similar_media(g_first)?;
        Ok(Object { later, ..Object::new(self.accel, self.interface, media)? })
    }

    /// The interface's index ratio (the medium's index) in band `band`.
    #[inline]
    fn eta(&self, band: usize) -> f64 {
        self.medium[band].n
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
        if !(self.square_m > 0.0 && self.square_m.is_finite()) {
            return Err(SceneError::BoardSquare { square_m: self.square_m });
        }
        if self.columns == 0 || self.rows == 0 {
            return Err(SceneError::BoardEmpty { columns: self.columns, rows: self.rows });
        }
        if !(self.margin_m >= 0.0 && self.margin_m.is_finite()) {
            return Err(SceneError::BoardMargin { margin_m: self.margin_m });
        }
        if (self.u.length() - 1.0).abs() > 1e-9
            || (self.v.length() - 1.0).abs() > 1e-9
            || self.u.dot(self.v).abs() > 1e-9
        {
            return Err(SceneError::BoardAxes);
        }
        let rho_ok = |r: &[f64; 3]| r.iter().all(|x| x.is_finite() && (0.0..=1.0).contains(x));
        let ok = match &self.reflectance {
            BoardReflectance::Checker { even, odd } => rho_ok(even) && rho_ok(odd),
            BoardReflectance::Texture { width, height, rgb } => {
                *width > 0 && *height > 0 && rgb.len() == width * height && rgb.iter().all(rho_ok)
            }
        };
        if !ok || !rho_ok(&self.margin) {
            return Err(SceneError::BoardReflectance);
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
    /// Assembles a scene; ε is 10⁻⁷ of the extent of the object, board and
    /// camera. With a board, the environment's sampling is weighted towards
    /// the board's normal on the camera's side
    /// ([`Environment::set_sampling_normal`]): everything lit there faces up.
    pub fn new(
        object: Option<Object>,
        board: Option<Board>,
        mut environment: Environment,
        camera: Camera,
    ) -> Result<Self, SceneError> {
        if let Some(b) = &board {
            b.check()?;
            let n = b.normal();
            let n = if n.dot(camera.position() - b.origin) >= 0.0 { n } else { -n };
            environment.set_sampling_normal(Some(n));
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
    /// Carry all three bands along one path inside the medium, combined by
    /// multiple importance sampling over the band that drives the sampling
    /// (see the module documentation). `false` gives docs/method.md §5's plain
    /// estimator (one band per path, weight 3). Applies only when the
    /// boundary's index is the same in all bands.
    pub spectral_mis: bool,
    /// Where a path meets the object and must keep one band from there on
    /// (a boundary whose index differs between bands, or
    /// [`Settings::spectral_mis`] = false), follow three branches from that
    /// point, one per band, each weighing 1 in its band, instead of one band
    /// drawn at random with weight 3 (docs/method.md §5). A sample's value
    /// is the branches' sum, so its variance stays that of independent
    /// samples. Per sample the object costs three walks instead of one, and
    /// the variance of the random band's estimator, 3 E(X²) − E(X)² per band,
    /// falls to Var X, for any X: never less efficient. `false`: one band
    /// at random.
    pub band_branches: bool,
    /// Next-event estimation of the environment from scattering events
    /// inside a convex object, through its flat faces (see the module
    /// documentation). `false`: light leaves the medium only by chance.
    pub medium_nee: bool,
    /// With [`Settings::medium_nee`]: also connect along a direction drawn
    /// from the phase function, the transmittance to the face and the
    /// Fresnel transmission taken as factors instead of sampled (a third
    /// strategy in the same balance heuristic; see the module
    /// documentation). `false`: the two strategies of before.
    pub phase_connection: bool,
    /// With [`Settings::medium_nee`]: connections also through the specular
    /// chains a path takes without scattering (see the module
    /// documentation): from a scattering point through one reflection at a
    /// face and out through another (image method), and from the board
    /// through the object (in at one face, one unscattered flight, out at
    /// another) or by a reflection at one of its faces. `false` (default):
    /// such paths are found only by chance,
    /// unweighted, and carry most of the object's sparse bright pixels
    /// (fireflies); on the demo plaque the chains cut the 99th percentile of
    /// the per-pixel error from 44 % to 12 % at the same median, for 12 %
    /// more time (fixtures/render/demo.toml turns them on).
    pub specular_chains: bool,
    /// Where a path scatters deeper than [`SPHERE_MARGIN_MFP`] + the
    /// smallest sphere inside an object that scatters isotropically in
    /// every band (a similar medium of g′ = 0, for instance), replace the
    /// walk inside the largest tabulated sphere that fits by one draw from
    /// its exit distribution ([`crate::sphere`]): a diffusive medium's
    /// deep excursions cost O(log depth) jumps instead of depth² events.
    /// The tables are Monte Carlo estimates (a fixed error of a few % per
    /// bin in the exit angle). `false` (default): the plain walk.
    pub sphere_jumps: bool,
    /// With [`Settings::sphere_jumps`]: the least depth, in mean free paths
    /// of the least extinct band, between a sphere and the nearest face
    /// plane (default [`SPHERE_MARGIN_MFP`]). Smaller: more jumps and
    /// fewer events, each exit point near a face connected to the
    /// environment as a scattering point is.
    pub sphere_margin_mfp: f64,
    /// How a smooth boundary whose index differs between bands refracts a
    /// path that carries all bands (see [`Dispersion`]).
    pub dispersion: Dispersion,
    /// Split the path where it meets the object from outside: the
    /// reflection (weight F per band) and the refraction (1 − F) are both
    /// followed instead of choosing one with probability F. The reflected
    /// branch is traced without further splitting.
    pub split_entry: bool,
    /// How the samples are spread over the pixels.
    pub sampling: Sampling,
    /// Stop after the pass in which the median relative standard error over
    /// the object's pixels ([`RegionErrors::object`]) reaches this fraction.
    pub target_rel_error: Option<f64>,
    /// Changes of the object's coefficients whose effect on every pixel the
    /// render estimates from its own paths ([`Image::derivatives`]; at most
    /// [`MAX_DERIVATIVES`], the rest are ignored). Turns
    /// [`Settings::sphere_jumps`] off (a jump's events are not seen).
    pub derivatives: Vec<CoefficientDerivative>,
}

/// The most [`CoefficientDerivative`]s one render carries.
pub const MAX_DERIVATIVES: usize = 4;

/// The derivative of the object's scattering and absorption coefficients
/// with respect to one parameter θ (a recipe's weight percentage, for
/// instance), per band R, G, B; the phase functions, indices and geometry
/// do not depend on θ. The render then estimates ∂L/∂θ per pixel from the
/// same paths as L (perturbation Monte Carlo, the likelihood-ratio or
/// "score" estimator: Hayakawa et al., Opt. Lett. 26(17), 2001; Sassaroli,
/// J. Biomed. Opt. 17(7), 2012): every contribution f/p of a path with n
/// scattering events and medium length ℓ_c in band c is weighted by
///
///   ∂ ln f_c / ∂θ = n ∂ln μ_s,c/∂θ − (∂μ_s,c/∂θ + ∂μ_a,c/∂θ) ℓ_c,
///
/// unbiased for ∂L/∂θ, whatever the sampling densities and multiple
/// importance weights (they do not depend on θ). A similar medium of fixed
/// g and g′ scales its μ_s′ with μ_s, so the relative derivative serves it
/// too.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoefficientDerivative {
    /// ∂ ln μ_s / ∂θ per band (per unit of θ).
    pub d_ln_mu_s: [f64; 3],
    /// ∂μ_a / ∂θ per band, 1/m per unit of θ.
    pub d_mu_a_per_m: [f64; 3],
}

impl CoefficientDerivative {
    /// ∂μ_t/∂θ in band c of a medium whose scattering coefficient is `mu_s_per_m`.
    #[inline]
    fn d_mu_t(&self, c: usize, mu_s_per_m: f64) -> f64 {
        self.d_ln_mu_s[c] * mu_s_per_m + self.d_mu_a_per_m[c]
    }
}

/// What one camera path carries back: the radiance per band, and per
/// [`CoefficientDerivative`] its derivative, with the path's running score
/// ∂ ln f/∂θ (flights and events so far) that each contribution is weighted by.
struct Estimate<'a> {
    derivatives: &'a [CoefficientDerivative],
    l: [f64; 3],
    dl: [[f64; 3]; MAX_DERIVATIVES],
    score: [[f64; 3]; MAX_DERIVATIVES],
}

impl<'a> Estimate<'a> {
    fn new(settings: &'a Settings) -> Self {
        let k = settings.derivatives.len().min(MAX_DERIVATIVES);
        Self {
            derivatives: &settings.derivatives[..k],
            l: [0.0; 3],
            dl: [[0.0; 3]; MAX_DERIVATIVES],
            score: [[0.0; 3]; MAX_DERIVATIVES],
        }
    }

    /// A contribution `v` to band c.
    #[inline]
    fn add(&mut self, c: usize, v: f64) {
        self.l[c] += v;
        for (k, _) in self.derivatives.iter().enumerate() {
            self.dl[k][c] += v * self.score[k][c];
        }
    }

    /// A contribution `v` to band c that crossed `length_m` more of `obj`'s
    /// medium than the path has walked (a connection).
    #[inline]
    fn add_through(&mut self, c: usize, v: f64, obj: &Object, length_m: f64) {
        self.l[c] += v;
        for (k, d) in self.derivatives.iter().enumerate() {
            self.dl[k][c] += v * (self.score[k][c] - d.d_mu_t(c, obj.medium[c].mu_s_per_m) * length_m);
        }
    }

    /// The path flew `length_m` through `obj`'s medium.
    #[inline]
    fn flight(&mut self, obj: &Object, length_m: f64) {
        for (k, d) in self.derivatives.iter().enumerate() {
            for c in 0..3 {
                self.score[k][c] -= d.d_mu_t(c, obj.medium[c].mu_s_per_m) * length_m;
            }
        }
    }

    /// The path scattered.
    #[inline]
    fn scatter(&mut self) {
        for (k, d) in self.derivatives.iter().enumerate() {
            for c in 0..3 {
                self.score[k][c] += d.d_ln_mu_s[c];
            }
        }
    }
}

/// Refraction at a smooth boundary whose index n differs between bands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dispersion {
    /// Exact: a refraction direction belongs to one band, so a path keeps
    /// one band from its first contact with the object (weight 3, docs/method.md §5).
    PerBand,
    /// Approximate: refraction directions (Snell's law and its solid-angle
    /// factor cos θ_o/(n² cos θ_i)) from the bands' mean index, while each
    /// band keeps its own Fresnel factors F_c and 1 − F_c (where the mean
    /// index reflects totally, F_c = 1 in every band). A path then carries
    /// all three bands (spectral MIS). Reflection is exact; what is lost is
    /// the spread of the refracted directions between bands (≈ 0.5° for
    /// polycarbonate's 1.582–1.608).
    SharedDirections,
}

/// How a render spreads its samples over the pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sampling {
    /// Every pixel gets `spp` samples.
    Uniform,
    /// Samples go where the error is: after each pass the per-sample
    /// relative variance of the object's pixels and of the others (medians
    /// over each region, [`RegionErrors`]) sets how many more samples a
    /// pixel whose camera rays hit the object gets per pass than one whose
    /// rays miss it (at most [`MAX_OBJECT_RATIO`]), so both regions approach
    /// the same relative error. The object's pixels get `spp` samples, the
    /// others `spp / ratio` (at least one pass). A pixel's share depends on
    /// the fraction of its camera rays that hit the object (geometry) and
    /// on the two region medians, never on its own samples alone.
    ObjectWeighted,
}

/// The largest ratio of samples per pass between an object pixel and a
/// pixel that does not see the object ([`Sampling::ObjectWeighted`]).
pub const MAX_OBJECT_RATIO: u32 = 256;

impl Default for Settings {
    fn default() -> Self {
        Self {
            spp: 64,
            time_budget_s: None,
            spp_per_pass: 4,
            seed: 1,
            roulette_threshold: Some(0.25),
            max_events_per_path: 10_000_000,
            spectral_mis: true,
            band_branches: true,
            medium_nee: true,
            phase_connection: true,
            specular_chains: false,
            sphere_jumps: false,
            sphere_margin_mfp: SPHERE_MARGIN_MFP,
            dispersion: Dispersion::PerBand,
            split_entry: false,
            sampling: Sampling::Uniform,
            target_rel_error: None,
            derivatives: Vec::new(),
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
    /// Per pixel, how many of its camera rays hit the object first.
    pub object_samples: Vec<u32>,
    /// Per pixel, how many of its camera rays hit the board first.
    pub board_samples: Vec<u32>,
    /// Two independent half renders of the same run: per pixel the mean of
    /// its samples with even index k (`halves[0]`, ⌈n/2⌉ samples) and with
    /// odd k (`halves[1]`, ⌊n/2⌋; 0 where a pixel has a single sample). Their
    /// noise is independent and twice the variance of `mean`, which is what
    /// an extrapolation of a noisy figure to zero noise needs.
    pub halves: [Vec<[f64; 3]>; 2],
    /// Per [`Settings::derivatives`] entry, ∂L/∂θ per pixel (empty without).
    pub derivatives: Vec<DerivativeImage>,
}

/// One [`CoefficientDerivative`]'s ∂L/∂θ per pixel: the mean over the
/// pixel's samples and its variance, row-major like [`Image::mean`].
#[derive(Debug, Clone, PartialEq)]
pub struct DerivativeImage {
    pub mean: Vec<[f64; 3]>,
    pub variance_of_mean: Vec<[f64; 3]>,
}

/// The first surface a camera ray meets.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum FirstHit {
    Object,
    Board,
    Environment,
}

/// Median and 90th percentile of a per-pixel figure over a set of pixels.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Quantiles {
    /// Pixels in the region that are not black (those the figure is taken over).
    pub pixels: usize,
    pub median: f64,
    pub p90: f64,
    /// The 99th percentile: the sparse bright outliers' share.
    pub p99: f64,
}

impl Quantiles {
    /// Median, 90th and 99th percentile of `values` (NaN for an empty set).
    pub fn of(mut values: Vec<f64>) -> Self {
        if values.is_empty() {
            return Self { pixels: 0, median: f64::NAN, p90: f64::NAN, p99: f64::NAN };
        }
        values.sort_by(f64::total_cmp);
        let q = |q| sorted_quantile(&values, q);
        Self { pixels: values.len(), median: q(0.5), p90: q(0.9), p99: q(0.99) }
    }
}

/// The q-quantile of non-empty ascending `sorted`: its element at ⌊q n⌋ (the last for q = 1).
fn sorted_quantile(sorted: &[f64], q: f64) -> f64 {
    sorted[((q * sorted.len() as f64) as usize).min(sorted.len() - 1)]
}

/// The relative standard error of each pixel's mean, summarised per region:
/// the pixels where at least half the camera rays hit the object first, those
/// where at least half hit the board first, and all pixels. A pixel's
/// relative standard error is [`Image::relative_std_error`] (the RMS over
/// R, G, B), taken over the pixels that are not black; one with a channel
/// still without light, or with one sample, counts as +∞.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RegionErrors {
    pub object: Quantiles,
    pub board: Quantiles,
    pub all: Quantiles,
}

/// Which region a pixel belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Region {
    Object,
    Board,
    Other,
}

impl Image {
    /// The fraction of pixel `p`'s camera rays that hit the object first.
    pub fn object_fraction(&self, p: usize) -> f64 {
        f64::from(self.object_samples[p]) / f64::from(self.samples[p].max(1))
    }

    /// The region of pixel `p` (at least half its camera rays hit the object
    /// first, else the board first, else neither).
    pub fn region(&self, p: usize) -> Region {
        let n = self.samples[p].max(1);
        if 2 * self.object_samples[p] >= n && self.object_samples[p] > 0 {
            Region::Object
        } else if 2 * self.board_samples[p] >= n && self.board_samples[p] > 0 {
            Region::Board
        } else {
            Region::Other
        }
    }

    /// The root mean square over R, G, B of the channels' relative standard
    /// errors √(var of the mean)/mean of pixel `p` (so coloured noise counts
    /// in full). `None` for a black pixel (no channel has a positive mean:
    /// no relative error is defined). A pixel that has light in one channel
    /// but none yet in another (a band no path of it has carried), or a
    /// variance that is not finite (one sample), gets +∞: its error is not
    /// known to be small, and leaving it out would make a median over few
    /// samples read low.
    pub fn relative_std_error(&self, p: usize) -> Option<f64> {
        let (m, v) = (self.mean[p], self.variance_of_mean[p]);
        if !m.iter().any(|&x| x > 0.0) {
            return None;
        }
        let mut sum = 0.0;
        for c in 0..3 {
            if !(m[c] > 0.0 && v[c].is_finite()) {
                return Some(f64::INFINITY);
            }
            sum += v[c] / (m[c] * m[c]);
        }
        Some((sum / 3.0).sqrt())
    }

    /// Median and 90th percentile of the relative standard error over the
    /// object's pixels, the board's and all.
    pub fn region_errors(&self) -> RegionErrors {
        let [o, b, a] = self.errors_by_region();
        RegionErrors { object: Quantiles::of(o), board: Quantiles::of(b), all: Quantiles::of(a) }
    }

    /// The pixels' relative standard errors (black pixels left out) over
    /// the object's pixels, the board's and all.
    fn errors_by_region(&self) -> [Vec<f64>; 3] {
        let mut by: [Vec<f64>; 3] = Default::default();
        for p in 0..self.mean.len() {
            let Some(r) = self.relative_std_error(p) else { continue };
            match self.region(p) {
                Region::Object => by[0].push(r),
                Region::Board => by[1].push(r),
                Region::Other => {}
            }
            by[2].push(r);
        }
        by
    }
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
    /// The relative standard errors per region after this pass.
    pub errors: RegionErrors,
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
    let mut acc = Accumulator::new(w, h);
    let mut stats = Stats::default();
    let start = Instant::now();
    let per_pass = settings.spp_per_pass.max(1);
    let weighted = settings.sampling == Sampling::ObjectWeighted && scene.object.is_some();
    // Samples per pass of an object pixel relative to a pixel that misses it.
    let mut ratio = 1u32;
    // This pass's samples per object pixel, in units of `per_pass`: it
    // doubles from pass to pass up to `ratio`, as long as a pass is expected
    // to end within the time budget and within MAX_PASS_S.
    let mut step = 1u32;
    let mut last_elapsed = 0.0;
    // Samples per pixel so far of a pixel whose rays all hit the object.
    let mut object_done = 0u32;
    let mut quota = vec![0u32; n];
    loop {
        // This pass's samples per pixel: the object's pixels get `step`
        // times more, pro rata of the fraction of rays that hit the object;
        // in all, the object's pixels get `spp`, the others spp / ratio.
        let object_next = object_done.saturating_add(per_pass.saturating_mul(step)).min(settings.spp);
        let mut any = false;
        for (p, q) in quota.iter_mut().enumerate() {
            let done = acc.samples[p];
            let target = if !weighted {
                object_next
            } else if done == 0 {
                per_pass.min(settings.spp)
            } else {
                // Keep pace with the object's pixels, at 1/ratio for a pixel that misses the object.
                let share = f64::from(acc.object_samples[p]) / f64::from(done);
                let t = (f64::from(object_next) * (share + (1.0 - share) / f64::from(ratio))).ceil() as u32;
                // A pixel that gets samples gets at least a pass's worth.
                if t > done {
                    t.max(done + per_pass)
                } else {
                    t
                }
            };
            *q = target.min(settings.spp).saturating_sub(done);
            any |= *q > 0;
        }
        if !any {
            break;
        }
        let pass_stats = acc.add_pass(scene, settings, &quota, cancel);
        object_done = object_next;
        stats.add(&pass_stats);
        stats.passes += 1;
        let elapsed = start.elapsed().as_secs_f64();
        stats.wall_s = elapsed;
        let image = acc.image();
        let errors = image.region_errors();
        if weighted {
            ratio = object_ratio(&image);
            let unit_s = (elapsed - last_elapsed) / f64::from(step);
            let mut next = step.saturating_mul(2).min(ratio);
            if unit_s > 0.0 {
                let remaining = settings.time_budget_s.map_or(MAX_PASS_S, |b| (b - elapsed).min(MAX_PASS_S));
                next = next.min((remaining / unit_s).floor().max(1.0) as u32);
            }
            step = next.max(1);
        }
        last_elapsed = elapsed;
        let spp_done = acc.max_samples();
        on_pass(&Progress { spp_done, spp_target: settings.spp, elapsed_s: elapsed, stats, errors });
        let target_met =
            settings.target_rel_error.is_some_and(|e| errors.object.pixels > 0 && errors.object.median <= e);
        if target_met
            || settings.time_budget_s.is_some_and(|b| elapsed >= b)
            || cancel.is_some_and(|c| c.load(Ordering::Relaxed))
        {
            break;
        }
    }
    stats.wall_s = start.elapsed().as_secs_f64();
    (acc.image(), stats)
}

/// The longest a pass of [`Sampling::ObjectWeighted`] is planned to take,
/// seconds (progress and cancellation are seen between passes).
const MAX_PASS_S: f64 = 10.0;

/// The samples-per-pass ratio between the object's pixels and the others
/// that makes their relative standard errors meet: the ratio of the medians
/// (over each region) of the per-sample relative variance n·(SE/mean)² of
/// the object's pixels and the board's (of all other pixels without a
/// board: the environment's pixels, nearly noiseless, would otherwise set
/// the ratio and starve the board), between 1 and [`MAX_OBJECT_RATIO`].
fn object_ratio(image: &Image) -> u32 {
    let mut by: [Vec<f64>; 3] = Default::default();
    for p in 0..image.mean.len() {
        let Some(r) = image.relative_std_error(p) else { continue };
        let v = f64::from(image.samples[p]) * r * r;
        by[match image.region(p) {
            Region::Object => 0,
            Region::Board => 1,
            Region::Other => 2,
        }]
        .push(v);
    }
    let [objects, mut board, other] = by;
    if board.is_empty() {
        board = other;
    }
    let [o, rest] = [objects, board].map(|v| Quantiles::of(v).median);
    let ratio = if o.is_nan() {
        1.0
    } else if rest.is_nan() || rest <= 0.0 {
        f64::from(MAX_OBJECT_RATIO)
    } else {
        o / rest
    };
    (ratio.round() as u32).clamp(1, MAX_OBJECT_RATIO)
}

/// Samples `samples.start .. samples.end` of every pixel (uniform
/// sampling, in passes of `settings.spp_per_pass`), as per-pixel sums: one
/// shard of the render [`render`] makes with `spp = samples.end` (sample k
/// of pixel p draws from the same stream, so the shards of a partition of
/// 0..spp together hold exactly that render's samples). `settings.spp`,
/// the time budget, the error target and the sampling are not used. Stops
/// early only when `cancel` is set (then the counts say so).
pub fn render_samples(
    scene: &Scene,
    settings: &Settings,
    samples: std::ops::Range<u32>,
    cancel: Option<&AtomicBool>,
) -> (Accumulator, Stats) {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mut acc = Accumulator::new(w, h);
    acc.first_sample = samples.start;
    let count = samples.end.saturating_sub(samples.start);
    let per_pass = settings.spp_per_pass.max(1);
    let mut stats = Stats::default();
    let start = Instant::now();
    let mut done = 0u32;
    while done < count && !cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
        let q = per_pass.min(count - done);
        let pass_stats = acc.add_pass(scene, settings, &vec![q; w * h], cancel);
        stats.add(&pass_stats);
        stats.passes += 1;
        done += q;
    }
    stats.wall_s = start.elapsed().as_secs_f64();
    (acc, stats)
}

/// Per-pixel sums of a progressive render (or of one shard of it,
/// [`render_samples`]): Σ L and Σ L² per band over the pixel's samples, in
/// the samples' order.
#[derive(Debug, Clone, PartialEq)]
pub struct Accumulator {
    pub width: usize,
    pub height: usize,
    pub sum: Vec<[f64; 3]>,
    pub sum_sq: Vec<[f64; 3]>,
    /// The sum over the samples with even index (counted from sample 0 of
    /// the whole render, not of the shard): the first half render.
    pub sum_even: Vec<[f64; 3]>,
    pub samples: Vec<u32>,
    pub object_samples: Vec<u32>,
    pub board_samples: Vec<u32>,
    /// The index of the first sample of every pixel (0 for a whole render).
    pub first_sample: u32,
    /// Σ ∂L/∂θ and Σ (∂L/∂θ)² per pixel and [`Settings::derivatives`]
    /// entry k, at p · K + k (K entries; empty until a pass carries them).
    pub derivative_sum: Vec<[f64; 3]>,
    pub derivative_sum_sq: Vec<[f64; 3]>,
}

impl Accumulator {
    pub fn new(width: usize, height: usize) -> Self {
        let n = width * height;
        Self {
            width,
            height,
            first_sample: 0,
            sum: vec![[0.0; 3]; n],
            sum_sq: vec![[0.0; 3]; n],
            sum_even: vec![[0.0; 3]; n],
            samples: vec![0; n],
            object_samples: vec![0; n],
            board_samples: vec![0; n],
            derivative_sum: Vec::new(),
            derivative_sum_sq: Vec::new(),
        }
    }

    /// The number of derivatives the sums hold.
    fn derivative_count(&self) -> usize {
        self.derivative_sum.len() / (self.width * self.height).max(1)
    }

    fn max_samples(&self) -> u32 {
        self.samples.iter().copied().max().unwrap_or(0)
    }

    /// Adds `quota[p]` samples to every pixel p, rows in parallel. Sample k
    /// of pixel p draws from `Rng::new(seed, k·2³² + p)`. Once `cancel` is
    /// set, the samples not yet started are left out (each pixel keeps its
    /// own sample count, so the image stays valid).
    fn add_pass(&mut self, scene: &Scene, settings: &Settings, quota: &[u32], cancel: Option<&AtomicBool>) -> Stats {
        let w = self.width;
        let first_sample = self.first_sample;
        let kd = settings.derivatives.len().min(MAX_DERIVATIVES);
        if self.derivative_count() != kd {
            // (A render's settings do not change between passes: this is the first.)
            self.derivative_sum = vec![[0.0; 3]; self.sum.len() * kd];
            self.derivative_sum_sq = vec![[0.0; 3]; self.sum.len() * kd];
        }
        // Rows of the derivative sums (empty rows without derivatives).
        fn rows(v: &mut [[f64; 3]], width: usize, height: usize) -> Vec<&mut [[f64; 3]]> {
            if v.is_empty() {
                (0..height).map(|_| <&mut [[f64; 3]]>::default()).collect()
            } else {
                v.chunks_mut(width).collect()
            }
        }
        let mut d_rows = rows(&mut self.derivative_sum, w * kd, self.height);
        let mut d_rows_sq = rows(&mut self.derivative_sum_sq, w * kd, self.height);
        self.sum
            .par_chunks_mut(w)
            .zip(self.sum_sq.par_chunks_mut(w))
            .zip(self.sum_even.par_chunks_mut(w))
            .zip(self.samples.par_chunks_mut(w))
            .zip(self.object_samples.par_chunks_mut(w).zip(self.board_samples.par_chunks_mut(w)))
            .zip(d_rows.par_iter_mut().zip(d_rows_sq.par_iter_mut()))
            .enumerate()
            .map(|(j, (((((row, row_sq), row_even), row_n), (row_obj, row_board)), (row_d, row_d_sq)))| {
                let mut st = Stats::default();
                'pixels: for i in 0..w {
                    let pixel = (j * w + i) as u64;
                    let k0 = row_n[i];
                    let k1 = k0 + quota[j * w + i];
                    for k in k0..k1 {
                        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
                            st.samples += u64::from(k - k0);
                            row_n[i] = k;
                            break 'pixels;
                        }
                        let mut rng = Rng::new(settings.seed, (u64::from(first_sample + k) << 32) | pixel);
                        let u = [rng.next_f64(), rng.next_f64()];
                        let (o, d) = scene.camera.ray(i, j, u);
                        let (l, dl, first) = trace(scene, settings, o, d, &mut rng, &mut st);
                        for c in 0..3 {
                            row[i][c] += l[c];
                            row_sq[i][c] += l[c] * l[c];
                        }
                        for (k, dk) in dl.iter().enumerate().take(kd) {
                            for c in 0..3 {
                                row_d[i * kd + k][c] += dk[c];
                                row_d_sq[i * kd + k][c] += dk[c] * dk[c];
                            }
                        }
                        if (first_sample + k).is_multiple_of(2) {
                            for c in 0..3 {
                                row_even[i][c] += l[c];
                            }
                        }
                        match first {
                            FirstHit::Object => row_obj[i] += 1,
                            FirstHit::Board => row_board[i] += 1,
                            FirstHit::Environment => {}
                        }
                    }
                    st.samples += u64::from(k1 - k0);
                    row_n[i] = k1;
                }
                st
            })
            .reduce(Stats::default, |mut a, b| {
                a.add(&b);
                a
            })
    }

    /// Mean and variance of the mean per pixel.
    pub fn image(&self) -> Image {
        let mean = self.sum.iter().zip(&self.samples).map(|(s, &k)| s.map(|v| v / f64::from(k.max(1)))).collect();
        let variance_of_mean = self
            .sum
            .iter()
            .zip(&self.sum_sq)
            .zip(&self.samples)
            .map(|((s, q), &k)| {
                let m = f64::from(k);
                std::array::from_fn(|c| {
                    if k > 1 {
                        ((q[c] - s[c] * s[c] / m) / (m - 1.0)).max(0.0) / m
                    } else {
                        f64::INFINITY
                    }
                })
            })
            .collect();
        let half = |odd: bool| {
            self.sum
                .iter()
                .zip(&self.sum_even)
                .zip(&self.samples)
                .map(|((s, e), &k)| {
                    // Even global indices in first .. first + k.
                    let f = self.first_sample;
                    let even = (f + k).div_ceil(2) - f.div_ceil(2);
                    let (n, part) = if odd { (k - even, sub(*s, *e)) } else { (even, *e) };
                    part.map(|v| if n > 0 { v / f64::from(n) } else { 0.0 })
                })
                .collect()
        };
        let halves = [half(false), half(true)];
        let kd = self.derivative_count();
        let derivatives = (0..kd)
            .map(|k| {
                let (mean, variance_of_mean) = (0..self.samples.len())
                    .map(|p| {
                        mean_and_variance(
                            self.derivative_sum[p * kd + k],
                            self.derivative_sum_sq[p * kd + k],
                            self.samples[p],
                        )
                    })
                    .unzip();
                DerivativeImage { mean, variance_of_mean }
            })
            .collect();
        Image {
            width: self.width,
            height: self.height,
            mean,
            variance_of_mean,
            halves,
            samples: self.samples.clone(),
            object_samples: self.object_samples.clone(),
            board_samples: self.board_samples.clone(),
            derivatives,
        }
    }
}

/// The mean of k samples from their sum and sum of squares, and the variance of that mean (∞ below 2 samples).
fn mean_and_variance(sum: [f64; 3], sum_sq: [f64; 3], k: u32) -> ([f64; 3], [f64; 3]) {
    let m = f64::from(k);
    let mean = sum.map(|v| v / m.max(1.0));
    let var = std::array::from_fn(|c| {
        if k > 1 {
            ((sum_sq[c] - sum[c] * sum[c] / m) / (m - 1.0)).max(0.0) / m
        } else {
            f64::INFINITY
        }
    });
    (mean, var)
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|c| a[c] - b[c])
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

/// Throughput of a path in the three bands, as the spectral-MIS pair
/// (β, r): β_c = f_c / p̂ and r_k = p_k / p̂ for one common scale p̂, where
/// f_c is the path's measurement contribution in band c and p_k the density
/// with which the path would have been sampled had band k driven the
/// sampling. The estimate in band c is β_c / mean_k r_k (balance heuristic
/// over the three bands, each chosen with probability 1/3). Before the path
/// meets the object all r_k are equal; a path that keeps one band b (docs/method.md
/// §5's estimator) has r = 3·e_b and β = 3·β_b·e_b, the same formula.
#[derive(Debug, Clone, Copy)]
struct Throughput {
    beta: [f64; 3],
    r: [f64; 3],
}

impl Throughput {
    /// At most one band takes part: every ratio between bands is 1 (or 0/0 for
    /// the inactive ones, which stay 0), so the per-band scalings can be skipped.
    #[inline]
    fn single_band(&self) -> bool {
        u8::from(self.active(0)) + u8::from(self.active(1)) + u8::from(self.active(2)) <= 1
    }

    /// Band c still takes part in the estimate (a path that keeps one band has β = r = 0 in the others).
    #[inline]
    fn active(&self, c: usize) -> bool {
        self.beta[c] != 0.0 || self.r[c] != 0.0
    }

    #[inline]
    fn mean_r(&self) -> f64 {
        (self.r[0] + self.r[1] + self.r[2]) / 3.0
    }

    /// The estimate's weight in band c: β_c / mean r.
    #[inline]
    fn effective(&self) -> [f64; 3] {
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
    fn scale(&mut self, f: [f64; 3], p: [f64; 3], h: usize) {
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
    fn keep_band(&self, b: usize, weight: f64) -> Throughput {
        let mut kept = Throughput { beta: [0.0; 3], r: [0.0; 3] };
        kept.beta[b] = weight * self.beta[b];
        kept.r[b] = 3.0 * self.mean_r();
        kept
    }

    /// Rescales (β, r) so that mean r = 1 (the estimate is unchanged).
    #[inline]
    fn normalise(&mut self) {
        let m = self.mean_r();
        if m > 0.0 && m.is_finite() {
            for c in 0..3 {
                self.beta[c] /= m;
                self.r[c] /= m;
            }
        }
    }
}

/// Makes a next-event connection from a scattering point inside a convex
/// object possible: the refraction through a flat face is a delta, so the
/// environment direction ω_o outside is sampled and refracted backwards.
/// Carries what the path needs to weight its own escape against the
/// connection (multiple importance sampling).
#[derive(Debug, Clone, Copy)]
struct MediumVertex {
    x: DVec3,
    /// mean r at x (1 after normalisation).
    mean_r: f64,
    /// r at x, for the phase connection's density in each band.
    r: [f64; 3],
    /// Probability that the connection was attempted at x.
    p_attempt: f64,
    /// Probability that the phase connection was made at x (`p_attempt`, or 0 without it).
    p_phase: f64,
    /// x is the exit point of sphere j, scattered: the direction's density
    /// is that sphere's exit distribution, not the phase function.
    sphere: Option<usize>,
}

/// The board point `y` (normal `n` on the path's side) a path left by its diffuse bounce, while the path
/// can still be a chain that [`connect_by_faces`] makes (in through a
/// face, one unscattered flight, out through another, or reflected at a
/// face from outside: `mirror`);
/// `out`: it has left the object and must now escape:
/// r at `y` and the driving band's density of the chain so far, in the
/// final outside solid angle.
#[derive(Debug, Clone, Copy)]
struct BoardVertex {
    y: DVec3,
    n: DVec3,
    r: [f64; 3],
    pdf: f64,
    out: bool,
    mirror: bool,
}

/// A board point `y` with the normal `n` on the side the path is on, its
/// reflectance `rho` and whether the path splits where it meets the object
/// (then the refraction in is taken as a weight, not sampled).
struct BoardPoint {
    y: DVec3,
    n: DVec3,
    rho: [f64; 3],
    split: bool,
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
fn connect_by_faces(
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

/// One camera path: the radiance estimate it carries back, per band, and
/// the first surface the camera ray meets.
fn trace(
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
fn trace_path(
    scene: &Scene,
    settings: &Settings,
    mut o: DVec3,
    mut d: DVec3,
    mut tp: Throughput,
    mut hero: Option<usize>,
    events_before: u64,
    split: bool,
    est: &mut Estimate,
    rng: &mut Rng,
    st: &mut Stats,
) -> FirstHit {
    let eps = scene.epsilon_m;
    // All bands ride on one path whose refractions use the bands' mean index.
    let shared = scene.object.as_ref().is_some_and(|obj| {
        settings.spectral_mis
            && !obj.bands.achromatic
            && !obj.interface.is_rough()
            && settings.dispersion == Dispersion::SharedDirections
    });
    let mut inside = false;
    // pdf of the last diffuse bounce's direction (for MIS when the ray escapes straight to the sky).
    let mut last_diffuse_pdf: Option<f64> = None;
    // The last scattering point, while the path since then can still be
    // one that a medium connection makes (one flight, one refraction out),
    // and the driving band's density of that stretch in outside solid angle.
    let mut vertex: Option<MediumVertex> = None;
    let mut stretch_pdf = 1.0f64;
    let mut stretch_mu = 1.0f64;
    // dω_i/dω_o of the stretch's refraction out.
    let mut stretch_jacobian = 0.0f64;
    let mut events = events_before;
    // Whether the camera ray's first hit is the object (set at the first outside segment).
    let mut first_hit: Option<FirstHit> = None;
    // A lower bound of the distance from `o` to the surface while inside: a
    // flight shorter than it cannot leave (exact for a convex object's planes).
    let mut safe = 0.0f64;
    let convex = scene.object.as_ref().and_then(|obj| obj.accel.convex_planes());
    let planes = match &scene.object {
        Some(obj) if settings.medium_nee && !obj.interface.is_rough() && !scene.environment.is_uniform() => {
            obj.accel.convex_planes()
        }
        _ => None,
    };
    // Any other closed mesh with smooth faces connects through the face
    // that [`mesh_exit`] finds.
    let faces = match &scene.object {
        Some(obj) if settings.medium_nee && !obj.interface.is_rough() && !scene.environment.is_uniform() => {
            Some(planes.map_or(Faces::Mesh, Faces::Planes))
        }
        _ => None,
    };
    let chains = settings.specular_chains;
    // The hemisphere the environment's sampling favours ([`attempt_probability`]).
    let facing = scene.environment.sampling_normal();
    // Chains from the board through the object need every band on the path
    // (a band picked at the object would not be known at the board).
    let board_planes = match &scene.object {
        Some(obj) if chains && settings.spectral_mis && (obj.bands.achromatic || shared) => planes,
        _ => None,
    };
    // Medium length since the medium vertex, and the driving band's
    // probability of the one reflection on the way (1 before it).
    let mut stretch_t = 0.0f64;
    let mut stretch_refl: Option<f64> = None;
    // The triangle the stretch left the object through (a mesh's connections
    // make it only through the one [`mesh_exit`] finds).
    let mut stretch_triangle = u32::MAX;
    // The board point the path left by its diffuse bounce while it can
    // still be a chain that the board's connection through the object
    // makes, and the driving band's density of the chain so far.
    let mut chain: Option<BoardVertex> = None;
    loop {
        if inside {
            // In the medium: `hero` is set, the object exists.
            let (Some(obj0), Some(h)) = (&scene.object, hero) else {
                break;
            };
            let obj = obj0.walked_after(events);
            let bc = &obj.bands;
            let sigma_t = bc.sigma_t[h];
            let s = -(1.0 - rng.next_f64()).ln() / sigma_t;
            // A flight shorter than the distance to the nearest face plane,
            // or within a convex mesh's inscribed ball, cannot leave: no
            // boundary search needed.
            let hit = if s < safe || obj.accel.stays_inside(o, d, s) {
                None
            } else {
                let Some(hit) = obj.accel.exit(o, d) else {
                    st.leaked_paths += 1;
                    break;
                };
                Some(hit)
            };
            let Some(hit) = hit.filter(|hit| s >= hit.t) else {
                // Scattering at x: density μ_t,h e^{−μ_t,h s}, contribution μ_s,c e^{−μ_t,c s}.
                o += s * d;
                est.flight(obj, s);
                est.scatter();
                if bc.same_sigma_t || tp.single_band() {
                    // (One band: its ratios f/p reduce to μ_s/μ_t.)
                    for c in 0..3 {
                        tp.beta[c] *= obj.medium[c].mu_s_per_m / sigma_t;
                    }
                } else {
                    let decay: [f64; 3] =
                        std::array::from_fn(
                            |c| if tp.active(c) { (-(bc.sigma_t[c] - sigma_t) * s).exp() } else { 0.0 },
                        );
                    tp.scale(
                        std::array::from_fn(|c| obj.medium[c].mu_s_per_m * decay[c]),
                        std::array::from_fn(|c| bc.sigma_t[c] * decay[c]),
                        h,
                    );
                }
                tp.normalise();
                events += 1;
                let obj = obj0.walked_after(events);
                let spheres = sphere_tables(obj, settings);
                let bc = &obj.bands;
                chain = None;
                safe = match convex {
                    Some(planes) => distance_to_planes(planes, o),
                    None => obj.accel.distance_lower_bound(o),
                };
                if let Some(faces) = faces {
                    let reach = match faces {
                        Faces::Planes(planes) => distance_to_lit_planes(planes, o, facing),
                        Faces::Mesh => obj.accel.distance_estimate(o),
                    };
                    let p_attempt = attempt_probability(reach, bc.sigma_t_min);
                    let p_phase = if settings.phase_connection { p_attempt } else { 0.0 };
                    let chains = chains && planes.is_some();
                    let conn = Connection { h, x: o, d_in: d, p_attempt, p_phase, shared, chains, exit: None };
                    vertex = Some(connect_vertex(scene, obj, faces, &tp, &conn, rng, est));
                    stretch_t = 0.0;
                    stretch_refl = None;
                }
                // Deep inside: jump through the largest sphere that fits;
                // else turn by the phase function.
                let room = safe - settings.sphere_margin_mfp / bc.sigma_t_min;
                if let Some((t, j)) = spheres.and_then(|t| t.largest_within(room).map(|j| (t, j))) {
                    let omega = sphere::isotropic(rng);
                    let (u, v) = rng.next_f64_pair();
                    let exit = t.sample(h, j, u, v);
                    let (f, p) = t.factors(j, exit);
                    let arriving = tp;
                    tp.scale(f, p, h);
                    let r = t.radius_m(j);
                    o += r * omega;
                    match exit.bin {
                        // Unscattered: the flight from x along ω, longer
                        // than r. Its escape is one that x's connections
                        // also make, so it keeps x as its vertex.
                        None => {
                            stretch_mu = d.dot(omega);
                            stretch_t += r;
                            d = omega;
                        }
                        // Scattered inside: the exit point is a vertex of its
                        // own, connected with the exit distribution about ω
                        // as its phase function, and its escapes are weighed
                        // against that (without connections: weight 1).
                        Some(_) => {
                            d = sphere::leave(omega, exit.cos_theta, rng.next_f64());
                            vertex = None;
                            if let Some(planes) = planes {
                                // The branch's own probability per band,
                                // 1 − e^{−R_c}, goes into the densities
                                // (the tail is given_scattered's).
                                let mut branch = arriving;
                                branch.scale([1.0; 3], t.scattered_probability(j), h);
                                // No phase connection at a sphere's exit.
                                let reach = distance_to_lit_planes(planes, o, facing);
                                let p_attempt = attempt_probability(reach, bc.sigma_t_min);
                                let conn = Connection {
                                    h,
                                    x: o,
                                    d_in: omega,
                                    p_attempt,
                                    p_phase: 0.0,
                                    shared,
                                    chains,
                                    exit: Some((t, j)),
                                };
                                // (No normalisation until the next event: the
                                // vertex's r and the path's share one scale.)
                                vertex =
                                    Some(connect_vertex(scene, obj, Faces::Planes(planes), &branch, &conn, rng, est));
                                stretch_mu = exit.cos_theta;
                                stretch_t = 0.0;
                                stretch_refl = None;
                            } else {
                                tp.normalise();
                            }
                        }
                    }
                    safe = convex.map_or(0.0, |planes| distance_to_planes(planes, o));
                } else {
                    let d_in = d;
                    let (u1, u2) = rng.next_f64_pair();
                    d = DVec3::from_array(obj.medium[h].phase.sample_direction(d.to_array(), u1, u2));
                    stretch_mu = d_in.dot(d);
                    if !bc.same_phase && !tp.single_band() {
                        let active = std::array::from_fn(|c| c == h || tp.active(c));
                        let p = eval_each(obj.phases(), active, stretch_mu);
                        tp.scale(p, p, h);
                    }
                }
                if events >= settings.max_events_per_path {
                    st.truncated_paths += 1;
                    break;
                }
                if !roulette(&mut tp, settings, rng) {
                    break;
                }
                continue;
            };
            // The flight reaches the boundary: probability e^{−μ_t,h t}.
            if !bc.same_sigma_t && !tp.single_band() {
                let decay: [f64; 3] =
                    std::array::from_fn(
                        |c| if tp.active(c) { (-(bc.sigma_t[c] - sigma_t) * hit.t).exp() } else { 0.0 },
                    );
                tp.scale(decay, decay, h);
            }
            st.surface_hits += 1;
            est.flight(obj, hit.t);
            let p = o + hit.t * d;
            let n_out = if hit.normal.dot(d) >= 0.0 { hit.normal } else { -hit.normal };
            stretch_t += hit.t;
            if let Some(c) = chain.as_mut() {
                c.pdf *= (-sigma_t * hit.t).exp();
            }
            if obj.interface.is_rough() {
                let Some((nd, no, now_inside)) = rough_scatter(obj, h, n_out, p, d, eps, &mut tp, rng) else {
                    break;
                };
                (d, o, inside, safe, last_diffuse_pdf) = (nd, no, now_inside, 0.0, None);
                if !roulette(&mut tp, settings, rng) {
                    break;
                }
                continue;
            }
            let eta = if shared { obj.eta_mean } else { obj.eta(h) };
            let cos_i = d.dot(n_out);
            let (_, fr) = reflectances(obj, cos_i, eta, shared, true);
            if rng.next_f64() < fr[h] {
                if shared {
                    tp.scale(fr, fr, h);
                }
                d -= 2.0 * d.dot(n_out) * n_out;
                o = p - eps * n_out;
                // One reflection on the way out keeps the stretch one that
                // the connections make (with the chains).
                if chains && planes.is_some() && vertex.is_some() && stretch_refl.is_none() {
                    stretch_refl = Some(fr[h]);
                } else {
                    vertex = None;
                }
                chain = None;
                safe = 0.0;
            } else {
                let f = fr[h];
                if shared {
                    let t = fr.map(|x| 1.0 - x);
                    tp.scale(t, t, h);
                }
                d = refract_or_mirror(d, n_out, 1.0 / eta);
                o = p + eps * n_out;
                inside = false;
                if vertex.is_some() {
                    stretch_triangle = hit.triangle;
                    // Phase sampling, the flights, a reflection, refraction; in outside
                    // solid angle: dω_i/dω_o = cos θ_o / (n² cos θ_i).
                    stretch_jacobian = d.dot(n_out) / (eta * eta * cos_i);
                    let density = match (vertex.and_then(|v| v.sphere), sphere_tables(obj, settings)) {
                        (Some(j), Some(t)) => t.given_scattered(j, stretch_mu).1[h] / TAU,
                        _ => obj.medium[h].phase.eval(stretch_mu),
                    };
                    stretch_pdf = density
                        * (-sigma_t * stretch_t).exp()
                        * stretch_refl.unwrap_or(1.0)
                        * (1.0 - f)
                        * stretch_jacobian;
                }
                if let Some(c) = chain.as_mut() {
                    // Out: 1 − F and the second refraction's cos θ_o / cos θ_i.
                    c.pdf *= (1.0 - f) * d.dot(n_out) / cos_i;
                    c.out = true;
                }
            }
            last_diffuse_pdf = None;
            continue;
        }

        // Outside: the closest of object and board, else the sky.
        let obj_hit = scene.object.as_ref().and_then(|obj| obj.accel.intersect(o, d, f64::INFINITY));
        let board_hit = scene.board.as_ref().and_then(|bd| bd.intersect(o, d));
        let t_obj = obj_hit.map_or(f64::INFINITY, |h| h.t);
        first_hit.get_or_insert(match board_hit {
            Some((t_board, _)) if t_board < t_obj => FirstHit::Board,
            _ if t_obj < f64::INFINITY => FirstHit::Object,
            _ => FirstHit::Environment,
        });
        match board_hit {
            Some((t_board, rho)) if t_board < t_obj => {
                st.surface_hits += 1;
                vertex = None;
                let board = scene.board.as_ref().expect("board hit without a board");
                let p = o + t_board * d;
                let n = board.normal();
                let n = if n.dot(d) < 0.0 { n } else { -n };
                let origin = p + eps * n;
                // Next-event estimation of the environment.
                if let Some(sample) = scene.environment.sample(origin, [rng.next_f64(), rng.next_f64()])
                    && sample.pdf > 0.0
                {
                    let cos = sample.dir.dot(n);
                    // The object hides ω_o (asked only where ω_o leaves the board's side).
                    let blocked = cos > 0.0
                        && scene
                            .object
                            .as_ref()
                            .is_some_and(|obj| obj.accel.occluded(origin, sample.dir, f64::INFINITY));
                    if cos > 0.0 && !blocked {
                        let w = power_heuristic(sample.pdf, cos * FRAC_1_PI);
                        let beta = tp.effective();
                        for c in 0..3 {
                            est.add(c, beta[c] * rho[c] * FRAC_1_PI * cos * sample.radiance[c] * w / sample.pdf);
                        }
                    }
                    // By the object's faces: a reflection at one, and
                    // through it where it blocks ω_o.
                    if let (Some(obj), Some(planes)) = (&scene.object, board_planes) {
                        let at = BoardPoint { y: origin, n, rho, split };
                        connect_by_faces(
                            scene,
                            obj.walked_after(events),
                            planes,
                            &tp,
                            &at,
                            &sample,
                            shared,
                            blocked,
                            est,
                        );
                    }
                }
                let (u1, u2) = rng.next_f64_pair();
                let (nd, pdf) = cosine_direction(n, u1, u2);
                chain = board_planes.map(|_| BoardVertex { y: origin, n, r: tp.r, pdf, out: false, mirror: false });
                for (b, r) in tp.beta.iter_mut().zip(rho) {
                    *b *= r;
                }
                d = nd;
                o = origin;
                last_diffuse_pdf = Some(pdf);
                if !roulette(&mut tp, settings, rng) {
                    break;
                }
            }
            _ => {
                let Some(hit) = obj_hit else {
                    // Escaped to the environment.
                    let l = scene.environment.radiance(o, d);
                    let beta = tp.effective();
                    if let Some(v) = vertex {
                        // Weighed against the medium connections from v.x (balance heuristic).
                        let obj =
                            scene.object.as_ref().expect("a medium vertex without an object").walked_after(events);
                        // A mesh's connection makes this path only if it
                        // finds the face the path left through.
                        let made = planes.is_some()
                            || v.p_attempt > 0.0 && {
                                let eta = if shared { obj.eta_mean } else { obj.eta(hero.unwrap_or(0)) };
                                mesh_exit_through(&obj.accel, v.x, d, eta, stretch_triangle)
                            };
                        let p_conn = if made { v.p_attempt * scene.environment.pdf(v.x, d) } else { 0.0 };
                        let p_phase = if v.p_phase > 0.0 {
                            let ph = band_phases(obj, |k| v.r[k] > 0.0, hero.unwrap_or(0), stretch_mu);
                            v.p_phase * stretch_jacobian * mean_weighted(&v.r, &ph)
                        } else {
                            0.0
                        };
                        let denom = p_conn * v.mean_r + stretch_pdf * tp.mean_r() + p_phase;
                        if denom > 0.0 {
                            for (c, lc) in l.iter().enumerate() {
                                est.add(c, tp.beta[c] * stretch_pdf * lc / denom);
                            }
                        }
                    } else if let Some(c) = chain.filter(|c| c.out) {
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
                        let w = match last_diffuse_pdf {
                            Some(pdf_bsdf) => power_heuristic(pdf_bsdf, scene.environment.pdf(o, d)),
                            None => 1.0,
                        };
                        for c in 0..3 {
                            est.add(c, beta[c] * l[c] * w);
                        }
                    }
                    break;
                };
                // The object's boundary from outside.
                vertex = None;
                if chain.is_some_and(|c| c.out) {
                    chain = None;
                }
                let obj = scene.object.as_ref().expect("object hit without an object");
                let p = o + hit.t * d;
                let n_in = if hit.normal.dot(d) < 0.0 { hit.normal } else { -hit.normal };
                let one_band = !(settings.spectral_mis && (obj.bands.achromatic || shared));
                if hero.is_none() && one_band && settings.band_branches {
                    // One branch per band from here, each in its band alone
                    // (each makes its own split of the entry, if any).
                    let score = est.score;
                    for b in 0..3 {
                        let branch = tp.keep_band(b, 1.0);
                        trace_path(scene, settings, o, d, branch, Some(b), events, split, est, rng, st);
                        est.score = score;
                    }
                    break;
                }
                // (Counted here, after the branches, which count their own.)
                st.surface_hits += 1;
                // Splitting: the reflection, weighted by F_c, as a branch of its own.
                let entry_f = (split && !obj.interface.is_rough()).then(|| {
                    let cos_i = -d.dot(n_in);
                    let f: [f64; 3] = std::array::from_fn(|c| fresnel::reflectance(cos_i, obj.eta(c)));
                    let mut branch = tp;
                    for (b, fc) in branch.beta.iter_mut().zip(f) {
                        *b *= fc;
                    }
                    let d_refl = d - 2.0 * d.dot(n_in) * n_in;
                    // (The branch's score goes on from the path's, and the path's from here.)
                    let score = est.score;
                    trace_path(scene, settings, p + eps * n_in, d_refl, branch, hero, events, false, est, rng, st);
                    est.score = score;
                    f
                });
                let h = *hero.get_or_insert_with(|| {
                    let b = ((rng.next_f64() * 3.0) as usize).min(2);
                    if one_band {
                        // One band per path (docs/method.md §5): weight 3 in band b.
                        tp = tp.keep_band(b, 3.0);
                    }
                    b
                });
                if obj.interface.is_rough() {
                    let Some((nd, no, now_inside)) = rough_scatter(obj, h, n_in, p, d, eps, &mut tp, rng) else {
                        break;
                    };
                    (d, o, inside, safe, last_diffuse_pdf) = (nd, no, now_inside, 0.0, None);
                    if !roulette(&mut tp, settings, rng) {
                        break;
                    }
                    continue;
                }
                let eta = if shared { obj.eta_mean } else { obj.eta(h) };
                let cos_b = -d.dot(n_in);
                // The probability of refracting in (and of reflecting, when the path does).
                let mut p_reflect = 0.0;
                let p_in = if let Some(f) = entry_f {
                    // The reflection was traced above; the refraction carries 1 − F_c.
                    for (b, fc) in tp.beta.iter_mut().zip(f) {
                        *b *= 1.0 - fc;
                    }
                    Some(1.0)
                } else {
                    let (_, fr) = reflectances(obj, cos_b, eta, shared, false);
                    let reflects = rng.next_f64() < fr[h];
                    if shared {
                        let w = if reflects { fr } else { fr.map(|x| 1.0 - x) };
                        tp.scale(w, w, h);
                    }
                    p_reflect = fr[h];
                    (!reflects).then(|| 1.0 - fr[h])
                };
                if let Some(p_in) = p_in {
                    d = refract_or_mirror(d, -n_in, eta);
                    o = p - eps * n_in;
                    inside = true;
                    safe = 0.0;
                    if let Some(c) = chain.as_mut() {
                        // In: the first refraction's cos θ_i / cos θ_o (dω_b/dω_i = n² cos θ_i / cos θ_b).
                        c.pdf *= p_in * (-d.dot(n_in)) / cos_b;
                    }
                } else {
                    d -= 2.0 * d.dot(n_in) * n_in;
                    o = p + eps * n_in;
                    // Straight from the board: a chain that the board's
                    // connection by reflection makes.
                    chain = chain.filter(|c| !c.out).map(|c| BoardVertex {
                        pdf: c.pdf * p_reflect,
                        out: true,
                        mirror: true,
                        ..c
                    });
                }
                last_diffuse_pdf = None;
            }
        }
    }
    st.events += events - events_before;
    first_hit.unwrap_or(FirstHit::Environment)
}

/// The sphere-jump tables a path in `obj`'s medium uses ([`Settings::sphere_jumps`]).
#[inline]
fn sphere_tables<'a>(obj: &'a Object, settings: &Settings) -> Option<&'a SphereExits> {
    if settings.sphere_jumps && settings.derivatives.is_empty() {
        obj.sphere_exits()
    } else {
        None
    }
}

/// The Fresnel reflectance per band at a smooth boundary under
/// [`Dispersion::SharedDirections`]: each band's own index at the angle of
/// incidence `cos_i` > 0; `from_inside`: the path is in the medium (relative
/// index 1/n_c), and `f_mean`, the mean index's reflectance there, = 1 marks
/// total internal reflection, which then holds in every band.
#[inline]
fn band_reflectance(obj: &Object, cos_i: f64, f_mean: f64, from_inside: bool) -> [f64; 3] {
    if from_inside && f_mean >= 1.0 {
        return [1.0; 3];
    }
    std::array::from_fn(|c| {
        let eta = obj.eta(c);
        fresnel::reflectance(cos_i, if from_inside { 1.0 / eta } else { eta })
    })
}

/// The Fresnel reflectance at a smooth boundary at the angle of incidence
/// cos_i > 0 with the path's index `eta` (its band's, or the bands' mean
/// under `shared`), from inside the medium (relative index 1/η) or from
/// outside: that value, and per band the same or, under `shared`, each
/// band's own ([`band_reflectance`]).
#[inline]
fn reflectances(obj: &Object, cos_i: f64, eta: f64, shared: bool, from_inside: bool) -> (f64, [f64; 3]) {
    let f = fresnel::reflectance(cos_i, if from_inside { 1.0 / eta } else { eta });
    (f, if shared { band_reflectance(obj, cos_i, f, from_inside) } else { [f; 3] })
}

/// Snell's law backwards at a flat face with unit normal `n`: the direction
/// v on the far side (relative index `eta` = n_far / n_near) that refracts
/// into the unit direction `w` leaving the face on n's side (n·w > 0), and
/// cos θ_v = n·v; `None` where no v does (w beyond the critical angle).
/// Both travel along +n: v = (w − (n·w) n)/η + cos θ_v n.
#[inline]
fn unrefract(w: DVec3, n: DVec3, eta: f64) -> Option<(DVec3, f64)> {
    let cos_w = n.dot(w);
    let cos_v = (1.0 - (1.0 - cos_w * cos_w) / (eta * eta)).max(0.0).sqrt();
    (cos_v > 0.0).then(|| (((w - cos_w * n) / eta + cos_v * n).normalize(), cos_v))
}

/// Optical depth below which a chain through a reflection is always
/// connected (beyond it, with probability e^{CHAIN_TAU − τ}).
const CHAIN_TAU: f64 = 4.6;

/// Distance from x to the nearest of the face planes (≥ 0).
#[inline]
fn distance_to_planes(planes: &[(DVec3, f64)], x: DVec3) -> f64 {
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
fn distance_to_lit_planes(planes: &[(DVec3, f64)], x: DVec3, facing: Option<DVec3>) -> f64 {
    // (A bounded convex object has a face with n·facing > 0, so some plane
    // always passes the filter.)
    planes
        .iter()
        .filter(|(n, _)| facing.is_none_or(|f| n.dot(f) > -0.5))
        .map(|(n, c)| (c - n.dot(x)).max(0.0))
        .fold(f64::INFINITY, f64::min)
}

/// The default [`Settings::sphere_margin_mfp`]: a sphere jump leaves at
/// least this many mean free paths (of the least extinct band) between the
/// sphere and the nearest face plane. A scattered exit is a vertex with
/// connections of its own, so a small margin costs no tail. Measured on
/// IOL1068-06 (320 × 240, 64 spp): margin 3, 17.8 % median, 4.51 s; 1,
/// 17.1 %, 4.08 s; 0.5, 16.9 %, 3.87 s; 0, 16.7 %, 3.65 s (99th
/// percentiles 24–25 % throughout); 0.5 keeps the exit points off the faces.
pub const SPHERE_MARGIN_MFP: f64 = 0.5;

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
fn attempt_probability(d: f64, sigma_t_min: f64) -> f64 {
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
enum Faces<'a> {
    Planes(&'a [(DVec3, f64)]),
    Mesh,
}

/// Steps of [`mesh_exit`]'s search.
const MESH_EXIT_STEPS: usize = 4;

/// Where the inside ray from `x` that refracts into the outside direction
/// `wo` leaves a mesh: the face is searched by fixed-point steps, starting
/// from the face the ray x + t·ω_o meets: the inside direction ω_i that
/// refracts into ω_o at that face's plane (Snell backwards, relative index
/// `eta`) is traced from x, and the face it meets is taken next, until a
/// face is met by its own ω_i (found) or [`MESH_EXIT_STEPS`] steps pass
/// (none). The search is deterministic in (x, ω_o), so the path's own escape
/// asks it whether a connection would have made the same path
/// (multiple-importance weights), and a face it does not find is left to the
/// path's escape and the phase connection.
fn mesh_exit(accel: &Accel, x: DVec3, wo: DVec3, eta: f64) -> Option<MeshExit> {
    let mut hit = accel.exit(x, wo)?;
    let mut dir = wo;
    for _ in 0..MESH_EXIT_STEPS {
        let n = if hit.normal.dot(dir) >= 0.0 { hit.normal } else { -hit.normal };
        if n.dot(wo) <= 0.0 {
            return None;
        }
        let (wi, cos_i) = unrefract(wo, n, eta)?;
        let next = accel.exit_from(x, wi, hit.triangle)?;
        if next.triangle == hit.triangle {
            return Some(MeshExit { hit: next, n, wi, cos_i });
        }
        (hit, dir) = (next, wi);
    }
    None
}

/// True when [`mesh_exit`] finds `triangle` for (x, ω_o): the environment
/// connection makes a path that left through it (the path's own escape and
/// the phase connection ask this for their weights).
fn mesh_exit_through(accel: &Accel, x: DVec3, wo: DVec3, eta: f64, triangle: u32) -> bool {
    mesh_exit(accel, x, wo, eta).is_some_and(|e| e.hit.triangle == triangle)
}

/// One direction drawn from the environment's sampler at `x` for a medium
/// connection, or None where its density is not positive.
fn sample_environment(scene: &Scene, x: DVec3, rng: &mut Rng) -> Option<crate::env::EnvSample> {
    let es = scene.environment.sample(x, [rng.next_f64(), rng.next_f64()])?;
    (es.pdf > 0.0).then_some(es)
}

/// True when the ray leaving the object at `q` along ω_o meets the board,
/// or, for a mesh that is not convex, the mesh itself.
fn outside_blocked(scene: &Scene, obj: &Object, q: DVec3, wo: DVec3) -> bool {
    scene.board.as_ref().is_some_and(|b| b.intersect(q, wo).is_some())
        || !obj.accel.is_convex() && obj.accel.occluded(q, wo, f64::INFINITY)
}

/// A face found by [`mesh_exit`]: the hit, the outward normal n, the inside
/// direction ω_i and cos θ_i = n·ω_i.
struct MeshExit {
    hit: crate::accel::Hit,
    n: DVec3,
    wi: DVec3,
    cos_i: f64,
}

/// The medium connection from scattering point `x` of a mesh that is not a
/// convex polyhedron of few planes: one direction ω_o drawn from the
/// environment's sampler at x, the face the inside ray refracting into it
/// leaves through ([`mesh_exit`]), and the contribution and denominator of
/// [`connect_through_faces`] through that face (no chains). Shadowed by the
/// board and, for a mesh that is not convex, by the mesh itself.
fn connect_through_mesh(
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

/// The connections from a medium vertex (`conn`: where, and with what
/// probabilities) with the path's throughput `tp` there: the environment
/// connection, made with probability `conn.p_attempt`, and with it the phase
/// connection where `conn.p_phase` > 0. Returns what the path's own escape
/// from the vertex needs for its weight.
fn connect_vertex(
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
fn connect_through_faces(
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
struct Connection<'a> {
    h: usize,
    x: DVec3,
    d_in: DVec3,
    p_attempt: f64,
    p_phase: f64,
    shared: bool,
    chains: bool,
    exit: Option<(&'a SphereExits, usize)>,
}

/// Per band, the contribution and the density per steradian of leaving
/// `conn`'s point in a direction at cosine `mu` to `conn.d_in`: the phase
/// function's value twice, or a sphere exit's (w_c, q_c)(μ)/2π.
#[inline]
fn direction_factors(obj: &Object, tp: &Throughput, conn: &Connection, mu: f64) -> ([f64; 3], [f64; 3]) {
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
fn band_phases(obj: &Object, active: impl Fn(usize) -> bool, h: usize, mu: f64) -> [f64; 3] {
    if obj.bands.same_phase {
        let ph_h = obj.medium[h].phase.eval(mu);
        std::array::from_fn(|k| if active(k) { ph_h } else { 0.0 })
    } else {
        eval_each(obj.phases(), std::array::from_fn(active), mu)
    }
}

/// (1/3) Σ_k r_k v_k.
#[inline]
fn mean_weighted(r: &[f64; 3], v: &[f64; 3]) -> f64 {
    (r[0] * v[0] + r[1] * v[1] + r[2] * v[2]) / 3.0
}

/// Where a medium connection leaves the object: after a length `t` of
/// medium (μ = ω_in·ω_1, ω_1 the direction from the scattering point),
/// reflected on the way with the Fresnel reflectance `refl` per band (1
/// when it leaves straight), refracted into `wo` at the point `q` on the
/// face, with `jacobian` = dω_i/dω_o = cos θ_o / (n² cos θ_i) and the
/// Fresnel reflectance `fr` per band there; `weight`: 1 / the probability
/// with which the connection was made (Russian roulette on the reflection).
struct Exit {
    t: f64,
    mu: f64,
    jacobian: f64,
    refl: [f64; 3],
    fr: [f64; 3],
    q: DVec3,
    wo: DVec3,
    weight: f64,
}

/// Adds a medium connection's contribution per band c,
/// β_c u_c L_c(q, ω_o) / D, u_k = p_k(μ) e^{−μ_t,k t} R_k (1 − F_k) J the path's
/// own escape along the same chain in band k per unit outside solid angle
/// (R_k the reflection on the way, 1 for none), and
/// D = p_att p_env mean r + mean_k r_k u_k + p_phase J mean_k r_k p_k(μ),
/// the balance heuristic over the three strategies and the bands
/// (`pdf_env` = p_env(x, ω_o)).
fn add_connection(
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
fn connect_along_phase(
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

/// Samples the object's rough interface in band `h` (frame: +z = the
/// outward normal `n_out` at the hit point `p`, η = n_h) for a ray arriving
/// along `d`, multiplies the throughput by the weight f|cos θ_i|/pdf
/// (radiance transport), and returns the new direction, the new origin
/// (offset by `eps` to the side it leaves into) and whether that side is the
/// inside. `None` when the sample is lost (the microfacet model's energy
/// loss).
#[inline]
#[allow(clippy::too_many_arguments)]
fn rough_scatter(
    obj: &Object,
    h: usize,
    n_out: DVec3,
    p: DVec3,
    d: DVec3,
    eps: f64,
    tp: &mut Throughput,
    rng: &mut Rng,
) -> Option<(DVec3, DVec3, bool)> {
    let (t, b) = crate::phase::orthonormal_basis(n_out.to_array());
    let (t, b) = (DVec3::from_array(t), DVec3::from_array(b));
    let wo = DVec3::new(-d.dot(t), -d.dot(b), -d.dot(n_out));
    let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
    let s = obj.interface.sample(wo, obj.eta(h), Lobe::Fresnel, u, Transport::Radiance)?;
    for beta in tp.beta.iter_mut() {
        *beta *= s.weight;
    }
    let wi = (s.wi.x * t + s.wi.y * b + s.wi.z * n_out).normalize();
    let inside = s.wi.z < 0.0;
    Some((wi, if inside { p - eps * n_out } else { p + eps * n_out }, inside))
}

/// Russian roulette on the estimate's weight β / mean r; false = the path ends.
#[inline]
fn roulette(tp: &mut Throughput, settings: &Settings, rng: &mut Rng) -> bool {
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

/// Refraction of unit `d` through an interface with unit normal `n`,
/// relative index `eta` = n_t/n_i ([`fresnel::refract`]). The caller has
/// already chosen refraction, so total internal reflection cannot occur
/// (F = 1 there); it falls back to the mirror direction defensively.
#[inline]
fn refract_or_mirror(d: DVec3, n: DVec3, eta: f64) -> DVec3 {
    fresnel::refract(d, n, eta).unwrap_or_else(|| d - 2.0 * d.dot(n) * n)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 149.1 × 104.5 × 6.35 mm plaque's outward face planes n·x ≤ c, its bottom at z = 0.
    fn plaque_planes() -> Vec<(DVec3, f64)> {
        vec![
            (DVec3::Z, 0.00635),
            (-DVec3::Z, 0.0),
            (DVec3::X, 0.07455),
            (-DVec3::X, 0.07455),
            (DVec3::Y, 0.05225),
            (-DVec3::Y, 0.05225),
        ]
    }

    #[test]
    fn lit_planes_leave_out_the_faces_that_look_down_at_the_board() {
        let planes = plaque_planes();
        let x = DVec3::new(0.01, -0.02, 0.001);
        // 1 mm above the bottom: the bottom face is nearest, the top 5.35 mm away.
        assert!((distance_to_planes(&planes, x) - 0.001).abs() < 1e-15);
        assert!((distance_to_lit_planes(&planes, x, Some(DVec3::Z)) - 0.00535).abs() < 1e-15);
        // Without a favoured hemisphere every face counts.
        assert_eq!(distance_to_lit_planes(&planes, x, None), distance_to_planes(&planes, x));
        // Near a side, the side (vertical, n·up = 0) counts.
        let y = DVec3::new(0.0745, 0.0, 0.001);
        assert!((distance_to_lit_planes(&planes, y, Some(DVec3::Z)) - 0.00005).abs() < 1e-12);
        // A board seen from below favours −z: now the top face is the hidden one.
        let z = DVec3::new(0.0, 0.0, 0.006);
        assert!((distance_to_lit_planes(&planes, z, Some(-DVec3::Z)) - 0.006).abs() < 1e-15);
    }
}
