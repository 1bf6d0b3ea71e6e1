//! What is rendered ([`Scene`]): the translucent [`Object`] (a closed
//! mesh, its [`Interface`] and a homogeneous [`Medium`] per band R, G, B:
//! μ_s, μ_a [1/m], phase function, index n), the [`Board`] (a Lambertian
//! checkerboard, metres), the environment and the camera; the checks that
//! build them ([`SceneError`]); the similar media a render may walk instead
//! ([`Object::similar`]: μ_s(1 − g) kept, with depth floors measured in
//! docs/method.md) and the coefficient derivative between two objects
//! ([`Object::coefficient_derivative`]).

use super::settings::CoefficientDerivative;
use crate::accel::Accel;
use crate::camera::Camera;
use crate::env::Environment;
use crate::interface::Interface;
use crate::medium::{Medium, MediumError};
use crate::microfacet::MicrofacetError;
use crate::phase::Phase;
use crate::sphere::SphereExits;
use glam::DVec3;
use std::sync::OnceLock;
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
    pub(super) bands: BandConstants,
    /// The bands' mean index, for refraction directions under
    /// [`Dispersion::SharedDirections`].
    pub(super) eta_mean: f64,
    /// The sphere-jump tables ([`Settings::sphere_jumps`]), made on first
    /// use; `None` where jumps do not apply.
    spheres: OnceLock<Option<SphereExits>>,
    /// The scattering event from which a path walks the second object's
    /// medium instead ([`Object::similar_floored_for`]).
    later: Option<(u64, Box<Object>)>,
}

/// What the estimator needs to know about the bands, derived once.
#[derive(Debug, Clone, Copy)]
pub(super) struct BandConstants {
    /// μ_t = μ_s + μ_a per band, 1/m.
    pub(super) sigma_t: [f64; 3],
    /// The smallest μ_t, 1/m.
    pub(super) sigma_t_min: f64,
    /// All bands share μ_t: the free-flight ratios are 1.
    pub(super) same_sigma_t: bool,
    /// All bands share the phase function: the phase ratios are 1.
    pub(super) same_phase: bool,
    /// All bands share the boundary's index, so one path can carry all
    /// three bands (spectral MIS); otherwise a path keeps one band.
    pub(super) achromatic: bool,
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
    pub(super) fn walked_after(&self, events: u64) -> &Object {
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
    pub(super) fn phases(&self) -> [&Phase; 3] {
        [&self.medium[0].phase, &self.medium[1].phase, &self.medium[2].phase]
    }

    /// The tables of [`Settings::sphere_jumps`], made on the first call:
    /// `None` unless the object is convex and scatters isotropically in
    /// every band. Radii up to half the bounding box's shortest side.
    ///
    /// [`Settings::sphere_jumps`]: super::Settings::sphere_jumps
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
    pub(super) fn eta(&self, band: usize) -> f64 {
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

    pub(super) fn normal(&self) -> DVec3 {
        self.u.cross(self.v)
    }

    /// Distance to the board along the ray, and the reflectance there.
    #[inline]
    pub(super) fn intersect(&self, o: DVec3, d: DVec3) -> Option<(f64, [f64; 3])> {
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
