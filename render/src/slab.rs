//! BSSRDF slices of a plane-parallel slab by light tracing with explicit
//! connection to a fixed observation direction (docs/method.md §3).
//!
//! # Geometry and units
//!
//! The surface is the plane z = 0 with air (n = 1) above; the medium fills
//! −d ≤ z ≤ 0 with index n, scattering and absorption coefficients μ_s, μ_a
//! [1/m] and a phase function ([`Phase`](crate::phase::Phase)); below is air again. Lengths are in
//! metres, angles in degrees at the interface and radians inside. A direction
//! given by (θ, φ) is (sin θ cos φ, sin θ sin φ, cos θ): ω_i points from the
//! surface towards the light, ω_o towards the camera. The camera is
//! orthographic along −ω_o; its N × N pixels of side p form a grid *on the
//! surface*, centred at the origin, columns along +x, rows from +y (top) to
//! −y, so the plane of incidence for φ = 0° or 180° is the middle row.
//!
//! # Estimator
//!
//! Photons leave the beam with total flux Φ_i (weight 1 per path; Φ_i
//! cancels), are refracted into the slab with weight (1 − F(θ_i)) (the
//! specular part F is a delta in direction and is not part of the slice; it
//! is reported as `specular_reflectance`), fly distances with pdf μ_t e^{−μ_t s},
//! are reflected or transmitted at the boundaries with probability F and
//! 1 − F, and at every scattering event keep the weight factor μ_s/μ_t
//! (absorption as weight) before sampling the phase function. Russian
//! roulette below weight 0.1 survives with probability w/0.1 and resets the
//! weight to 0.1, which keeps the estimator unbiased. Connections (below)
//! from deeper than 8 optical depths along ω₂₁ are Russian-rouletted too:
//! made with probability e^{−(τ−8)} and weighted by its inverse.
//!
//! **Explicit connection.** For a smooth top surface the in-medium direction
//! that refracts into ω_o is fixed: ω₂₁ with sin θ_t = sin θ_o / n and the
//! azimuth of ω_o. From a scattering event at x_s (depth |z_s|) it meets the
//! surface after ℓ = |z_s| / cos θ_t at x_o = x_s + ℓ ω₂₁. The radiance that
//! leaves towards ω_o at x_o is L_o = T(θ_t)/n² · L_in, with L_in the
//! radiance arriving along ω₂₁ below the surface (radiance/n² is invariant
//! across a refraction) and T = 1 − F. Writing L_in as the integral of the
//! in-scattered source μ_s ∫p L along the line through x_o, and averaging
//! over the pixel area A_o = p², the volume element of the slanted column is
//! dV = cos θ_t dA dℓ, so
//!
//! ⟨L_o⟩_pixel = T / (n² A_o cos θ_t) · E[ Σ_events w (μ_s/μ_t) p(ω_s·ω₂₁) e^{−μ_t ℓ} 1{x_o ∈ pixel} ],
//!
//! because the power-weighted density of collisions is μ_t L. Each event
//! therefore splats w · p · e^{−μ_t ℓ} · T / (n² A_o cos θ_t) (w already
//! multiplied by μ_s/μ_t), and the slice is f_ssr = ⟨L_o⟩/Φ_i = I_p/(A_⊥ Φ_i)
//! with A_⊥ = A_o cos θ_o, in 1/(m² sr). The connection direction is never
//! sampled, so the split of the transport integral is exact.
//!
//! **Internal reflections.** Light scattered at x_s can also reach ω_o after
//! specular reflections at the smooth boundaries: down along the mirror of
//! ω₂₁, reflected at the bottom (factor F(θ_t)), up through the slab; or up,
//! reflected at the top, down, reflected at the bottom, up; and so on. These
//! are the same straight column folded at the boundaries, so each adds an
//! image term with path length (2d − |z_s| + 2kd)/cos θ_t (factor F^{2k+1},
//! phase function at the mirrored direction) or (|z_s| + 2(k+1)d)/cos θ_t
//! (F^{2k+2}), splatted at its own exit point. Without them a thin slab's
//! slice is several percent low; in a thick slab (μ_t d / cos θ_t ≥ 40) they
//! are skipped.
//!
//! **Rough top** ([`Interface::Rough`], docs/method.md §2–§3). The top is then the
//! microfacet dielectric of [`crate::microfacet`] (Walter et al. 2007) and
//! every crossing samples it ([`Interface::sample`]): the entry direction
//! is −ω_i refracted through a microfacet normal drawn from the visible
//! normals of ω_i (weight (1 − F(ω_i·m)) G1(ω_t, m), the exact f|cos|/pdf
//! with the transmission lobe forced); a photon reaching the top from
//! below reflects or leaves through a normal drawn for it, by the Fresnel
//! choice (weight G1 of the new direction); samples sent to the wrong side
//! of the macro-surface are lost (single scattering). The connection can no
//! longer use one ω₂₁: the radiance leaving towards ω_o is
//! L_o(x_o) = ∫ f_t(ω_o, ω′) L_in(x_o, ω′) |cos θ′| dω′, estimated by
//! drawing ω′ (refracting ω_o into the slab through a normal drawn from
//! ω_o's visible normals, forced transmission) independently of the path:
//! L_o ≈ W · L_in(x_o, ω′), W = (1 − F) G1(ω′, m)/n² (radiance transport).
//! For a fixed ω′ the smooth derivation above holds with T/n² replaced by
//! W and θ_t by the angle of ω₂₁ = −ω′, so every event of a path splats
//! w p(ω_s·ω₂₁) e^{−μ_t ℓ} W / (A_o cos θ₂₁) with ℓ = |z_s|/cos θ₂₁ for the
//! ω′ the path drew at its launch. (One ω′ per path, not per event: the
//! sum over events stays unbiased, paths stay independent so the errors
//! from path and batch statistics stay right, and the sampling — a visible
//! normal, a refraction — is done once instead of at every event: 6× the
//! events/s for TR α 0.0084, 12× for Beckmann, measured with `lucent bench
//! surface`; a rough top then runs at about 0.65× the smooth one's speed.)
//! The direction is drawn from the surface alone, never from the photon, so
//! the split stays exact; as α → 0 it becomes the smooth connection. In a
//! thin slab (μ_t d < 40; every image term crosses the slab at least once)
//! the image terms follow a chain of segments traced backwards from the
//! exit — up along ω₂₁, before it the bottom's mirror (F), before that a
//! reflection at the rough top drawn for radiance leaving downwards
//! (weight F G1), and so on — and an event connecting into a segment of
//! direction v splats w p(ω_s·v) e^{−μ_t L} c / (A_o |v_z|), L its length
//! to the exit along the chain and c the chain's weight so far (|v_z| is
//! the Jacobian of the slanted segment, as cos θ_t above; the chain is
//! independent of the event, so the change of variables holds per chain).
//! Light that reaches the rough top from below *without having scattered*
//! (entered, crossed the slab, reflected at the bottom; the paths that have
//! no event to connect from, and through a smooth top leave in one
//! specular direction only) is connected at the top itself: a photon of
//! weight w arriving along d adds w f_t(ω_o, −d)/A_o (radiance transport)
//! to the pixel of its hit point; in an optically thin slab near the
//! mirror direction that is most of the slice. The surface's own
//! reflection lobe at the entry is not part of the slice (reported as
//! `specular_reflectance`, its directional albedo, as the smooth F).
//! The ring needs a fixed exit polar angle and is not used with a rough
//! top; in a thick slab (μ_t d ≥ 40) the lobe connection (below, "Through
//! a rough top") takes the path's ω′ as its ω₂₁ and is the default.
//! Tested (`render/tests/slab_rough.rs`): α = 10⁻⁴ against the smooth
//! slice pixel by pixel, against brute-force exit binning at α = 0.05 and
//! 0.3 (thick and thin), reciprocity, and the lane kernel against the
//! scalar one.
//!
//! **Ring connection** ([`Estimator::Ring`], the default where it
//! applies: θ_i or θ_o is 0 and the slab is thick). Under normal incidence
//! on the launch side the slab is symmetric about the normal, so every
//! direction on the ring of the exit polar angle is a valid connection; the
//! derivation is with its code, `slab/ring.rs`.
//!
//! **Lobe connection** ([`Estimator::Lobe`], the default where the ring
//! does not apply and the slab is thick): the fixed-direction connection
//! combined by multiple importance sampling with chains drawn backwards
//! from ω₂₁ through the phase function's lobe; derivation in `slab/lobe.rs`.
//!
//! **Fold** ([`RunOptions::fold`]). With both azimuths 0° or 180°, a
//! mirror-symmetric beam and a top surface symmetric about the plane of
//! incidence (smooth, an isotropic distribution, or a measured normal set
//! equal to its mirror image — a measured surface generally is not) the
//! slice is symmetric about the plane of incidence; each batch's image is averaged with its mirror image before
//! the batch statistics, so the reported errors include the correlation of
//! the two halves.
//!
//! **Per-pixel errors** ([`PixelErrors`]): the median and 90th percentile of
//! σ_i/f_i over the pixels above 1 % of the maximum, after every round and
//! as a stop rule ([`Stop::pixel_rel_error`]).
//!
//! **Brute force** ([`Estimator::BruteForce`], for testing): photons that
//! leave through the top within a cone of half-angle δ around ω_o add
//! w / (A_o cos θ_e Ω_δ) to the pixel of their exit point, Ω_δ = 2π(1 − cos δ).
//! It converges to the same slice as δ → 0 and shares no code with the
//! connection except the random walk itself.
//!
//! # Errors and determinism
//!
//! Paths are traced in batches of [`RunOptions::batch_paths`]; a round of
//! 32 batches runs in parallel (rayon) and is reduced in batch order, and
//! path k draws from the random stream (seed, k), so a result depends on the
//! seed and the stop rule, not on the thread count. The standard error of
//! the slice sum comes from the per-path totals; per-pixel errors from batch
//! means.
//!
//! # Speed
//!
//! On a CPU with AVX2 and FMA the connection estimators trace four paths at
//! a time, one per vector lane (module `lanes`, reported as
//! [`Slice::kernel`]): the flight, the scattering angles, the turn and the
//! fixed-direction connection's geometry, phase function and transmittance
//! of four events are one set of vector instructions; the ring's and the
//! lobe's connections run per lane on that vector walk (each lane with its
//! own path's ω₂₁ and C through a rough top), the lobe's chain links four
//! at a time. Each lane draws the same random
//! numbers for its path as the scalar kernel, so both give the same slice to
//! rounding (tested), whichever the CPU.
//!
//! ```
//! use lucent_render::slab::*;
//! use lucent_render::phase::Phase;
//! let slab = Slab::new(1e-3, Medium::new(2000.0, 10.0, Phase::henyey_greenstein(0.5).unwrap(), 1.4).unwrap()).unwrap();
//! let setup = Setup::new(slab, Beam::gaussian(200e-6).unwrap(), Sensor::new(31, 0.1e-3).unwrap(),
//!     Directions::from_degrees(45.0, 0.0, 0.0, 180.0).unwrap());
//! let slice = simulate(&setup, &RunOptions { stop: Stop::paths(20_000), ..RunOptions::default() }, |_| {}).unwrap();
//! assert!(slice.sum > 0.0 && slice.sum_std_error < 0.1 * slice.sum);
//! ```

use crate::fresnel;
use crate::interface::{Interface, Lobe, Transport};
pub use crate::medium::{valid_coefficients, Medium, MediumError, MU_T_MAX_PER_M};
use crate::rng::Rng;
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Invalid simulator input.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum SlabError {
    #[error("{name} = {value} is invalid: {reason}")]
    Parameter { name: &'static str, value: f64, reason: &'static str },
    #[error("beam map: {values} values do not fill {width} × {height} pixels")]
    BeamMapSize { values: usize, width: usize, height: usize },
    #[error("beam map: pixel ({column}, {row}) is not a finite number")]
    BeamMapNotFinite { column: usize, row: usize },
    #[error("beam map: pixel ({column}, {row}) is negative")]
    BeamMapNegative { column: usize, row: usize },
    #[error("beam map: all pixels are zero")]
    BeamMapAllZero,
    #[error("the stop rule needs a path count, a time budget or a target relative error")]
    NoStopRule,
    #[error("the ring connection needs exactly one of θ_i, θ_o to be 0°, a slab at least 40 optical depths thick along the exit direction and a smooth top")]
    RingNotApplicable,
    #[error(
        "the lobe connection needs a slab at least 40 optical depths thick along the exit direction (through a rough top: 40 optical depths thick)"
    )]
    LobeNotApplicable,
}

fn check(name: &'static str, value: f64, ok: bool, reason: &'static str) -> Result<f64, SlabError> {
    if ok && value.is_finite() {
        Ok(value)
    } else {
        Err(SlabError::Parameter { name, value, reason })
    }
}

impl From<MediumError> for SlabError {
    fn from(e: MediumError) -> Self {
        SlabError::Parameter { name: e.name, value: e.value, reason: e.reason }
    }
}

/// The slab: thickness, medium, top interface (the bottom one is always
/// [`Interface::Smooth`]).
#[derive(Debug, Clone)]
pub struct Slab {
    pub thickness_m: f64,
    pub medium: Medium,
    pub top: Interface,
}

impl Slab {
    pub fn new(thickness_m: f64, medium: Medium) -> Result<Self, SlabError> {
        check("thickness_m", thickness_m, thickness_m > 0.0, "must be > 0")?;
        Ok(Self { thickness_m, medium, top: Interface::Smooth })
    }

    /// The slab with `top` as its top interface.
    pub fn with_top(self, top: Interface) -> Self {
        Self { top, ..self }
    }
}

/// Incident irradiance on the surface, normalised to unit flux: the closed
/// set of beams. Where a beam lands depends on the incidence direction, so
/// its sampling and evaluation go through [`Beam::footprint`].
#[derive(Debug, Clone)]
pub enum Beam {
    /// Gaussian beam; `fwhm_m` is the full width at half maximum of its cross
    /// section perpendicular to the beam (the footprint on the surface is
    /// longer by 1/cos θ_i in the plane of incidence).
    Gaussian { fwhm_m: f64 },
    /// A measured map of irradiance on the surface.
    Map(BeamMap),
}

/// σ of a Gaussian of full width at half maximum `fwhm`: FWHM = 2√(2 ln 2) σ
/// ≈ 2.3548 σ. The one place this conversion is written.
pub fn fwhm_to_sigma(fwhm: f64) -> f64 {
    fwhm / (2.0 * (2.0 * std::f64::consts::LN_2).sqrt())
}

impl Beam {
    pub fn gaussian(fwhm_m: f64) -> Result<Self, SlabError> {
        check("beam_fwhm_m", fwhm_m, fwhm_m > 0.0, "must be > 0")?;
        Ok(Beam::Gaussian { fwhm_m })
    }

    /// The irradiance this beam lays on the surface when it arrives from
    /// (θ_i, φ_i) (degrees): the sampler and the density the simulator and
    /// the plots share.
    pub fn footprint(&self, theta_i_deg: f64, phi_i_deg: f64) -> Footprint<'_> {
        match self {
            Beam::Gaussian { fwhm_m } => {
                let (sin_phi, cos_phi) = phi_i_deg.to_radians().sin_cos();
                Footprint::Gaussian {
                    sigma_m: fwhm_to_sigma(*fwhm_m),
                    cos_theta_i: theta_i_deg.to_radians().cos(),
                    cos_phi,
                    sin_phi,
                }
            }
            Beam::Map(map) => Footprint::Map(map),
        }
    }

    /// Whether the irradiance is unchanged by the mirror y → −y for light
    /// arriving from azimuth `phi_i_deg` (a Gaussian arriving in the x–z
    /// plane; a map whose rows read the same from both ends).
    pub fn mirror_symmetric(&self, phi_i_deg: f64) -> bool {
        match self {
            Beam::Gaussian { .. } => (phi_i_deg.to_radians().sin()).abs() < 1e-12,
            Beam::Map(map) => (0..map.height / 2).all(|r| {
                let a = &map.values[r * map.width..(r + 1) * map.width];
                let b = &map.values[(map.height - 1 - r) * map.width..(map.height - r) * map.width];
                a == b
            }),
        }
    }
}

/// A beam's irradiance on the surface z = 0 for one incidence direction,
/// normalised to unit flux ([`Beam::footprint`]).
#[derive(Debug, Clone, Copy)]
pub enum Footprint<'a> {
    /// A Gaussian of standard deviation σ across the beam; on the surface
    /// σ/cos θ_i along the plane of incidence (azimuth φ_i), σ across it.
    Gaussian {
        sigma_m: f64,
        cos_theta_i: f64,
        cos_phi: f64,
        sin_phi: f64,
    },
    Map(&'a BeamMap),
}

impl Footprint<'_> {
    /// A point (x, y) \[m\] drawn with density [`irradiance`](Self::irradiance)
    /// from two uniform numbers (Gaussian: Box–Muller in the beam's cross
    /// section, stretched onto the surface) or three (map: a pixel by its
    /// CDF, then uniform inside it).
    #[inline]
    pub fn sample(&self, rng: &mut Rng) -> (f64, f64) {
        match self {
            Footprint::Gaussian { sigma_m, cos_theta_i, cos_phi, sin_phi } => {
                let r = sigma_m * (-2.0 * (1.0 - rng.next_f64()).ln()).sqrt();
                let (sin_a, cos_a) = crate::phase::sin_cos_turns(rng.next_f64());
                let (u, v) = (r * cos_a / cos_theta_i, r * sin_a);
                (u * cos_phi - v * sin_phi, u * sin_phi + v * cos_phi)
            }
            Footprint::Map(map) => map.sample(rng.next_f64(), rng.next_f64(), rng.next_f64()),
        }
    }

    /// Irradiance per unit incident flux at (x, y) [1/m²]; integrates to 1
    /// over the plane.
    pub fn irradiance(&self, x: f64, y: f64) -> f64 {
        match self {
            Footprint::Gaussian { sigma_m, cos_theta_i, cos_phi, sin_phi } => {
                // Coordinates along and across the plane of incidence.
                let u = x * cos_phi + y * sin_phi;
                let v = -x * sin_phi + y * cos_phi;
                let su = sigma_m / cos_theta_i;
                (-0.5 * ((u / su).powi(2) + (v / sigma_m).powi(2))).exp() / (2.0 * PI * su * sigma_m)
            }
            Footprint::Map(map) => {
                let c = (x / map.pixel_m + 0.5 * map.width as f64).floor();
                let r = (0.5 * map.height as f64 - y / map.pixel_m).floor();
                if c >= 0.0 && r >= 0.0 && (c as usize) < map.width && (r as usize) < map.height {
                    let total: f64 = map.values.iter().sum();
                    map.values[r as usize * map.width + c as usize] / (total * map.pixel_m * map.pixel_m)
                } else {
                    0.0
                }
            }
        }
    }
}

/// Irradiance map on the surface: `width` × `height` pixels of side
/// `pixel_m`, row-major from +y (top) down, centred at the origin.
#[derive(Debug, Clone)]
pub struct BeamMap {
    pub width: usize,
    pub height: usize,
    pub pixel_m: f64,
    pub values: Vec<f64>,
    cdf: Vec<f64>,
}

impl BeamMap {
    /// Validates the map: finite, non-negative, not all zero.
    pub fn new(width: usize, height: usize, pixel_m: f64, values: Vec<f64>) -> Result<Self, SlabError> {
        check("beam_map_pixel_m", pixel_m, pixel_m > 0.0, "must be > 0")?;
        if width == 0 || height == 0 || values.len() != width * height {
            return Err(SlabError::BeamMapSize { values: values.len(), width, height });
        }
        if let Some(i) = values.iter().position(|v| !v.is_finite()) {
            return Err(SlabError::BeamMapNotFinite { column: i % width, row: i / width });
        }
        if let Some(i) = values.iter().position(|v| *v < 0.0) {
            return Err(SlabError::BeamMapNegative { column: i % width, row: i / width });
        }
        let mut cdf = Vec::with_capacity(values.len());
        let mut acc = 0.0;
        for v in &values {
            acc += v;
            cdf.push(acc);
        }
        if acc <= 0.0 {
            return Err(SlabError::BeamMapAllZero);
        }
        for c in &mut cdf {
            *c /= acc;
        }
        Ok(Self { width, height, pixel_m, values, cdf })
    }

    fn sample(&self, u: f64, v: f64, w: f64) -> (f64, f64) {
        let i = self.cdf.partition_point(|c| *c <= u).min(self.cdf.len() - 1);
        let (col, row) = (i % self.width, i / self.width);
        let x = (col as f64 + v - 0.5 * self.width as f64) * self.pixel_m;
        let y = (0.5 * self.height as f64 - row as f64 - w) * self.pixel_m;
        (x, y)
    }
}

/// The camera's pixel grid on the surface.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sensor {
    pub pixels: usize,
    pub pixel_m: f64,
}

impl Sensor {
    pub fn new(pixels: usize, pixel_m: f64) -> Result<Self, SlabError> {
        check("pixels", pixels as f64, (1..=8192).contains(&pixels), "must lie in 1 … 8192")?;
        check("pixel_m", pixel_m, pixel_m > 0.0, "must be > 0")?;
        // A slice wider than a metre is no measurement of a sample (and a
        // pixel of 1e305 m made the coordinates overflow, and paths loop).
        check(
            "pixel_m",
            pixel_m,
            pixel_m * pixels as f64 <= 1.0,
            "the slice (pixels × pixel size) must be at most 1 m wide",
        )?;
        Ok(Self { pixels, pixel_m })
    }

    /// Pixel index of surface point (x, y), if on the sensor.
    #[inline]
    fn index(&self, x: f64, y: f64) -> Option<usize> {
        let half = 0.5 * self.pixels as f64;
        // 1/pixel_m is loop-invariant in the simulator's loops (hoisted).
        let inv = 1.0 / self.pixel_m;
        let c = x * inv + half;
        let r = half - y * inv;
        if c >= 0.0 && r >= 0.0 && c < self.pixels as f64 && r < self.pixels as f64 {
            Some(r as usize * self.pixels + c as usize)
        } else {
            None
        }
    }
}

/// Incidence and observation directions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Directions {
    pub theta_i_deg: f64,
    pub phi_i_deg: f64,
    pub theta_o_deg: f64,
    pub phi_o_deg: f64,
}

impl Directions {
    pub fn from_degrees(theta_i_deg: f64, phi_i_deg: f64, theta_o_deg: f64, phi_o_deg: f64) -> Result<Self, SlabError> {
        let polar = |v: f64| (0.0..90.0).contains(&v);
        check("theta_i_deg", theta_i_deg, polar(theta_i_deg), "must lie in [0°, 90°)")?;
        check("theta_o_deg", theta_o_deg, polar(theta_o_deg), "must lie in [0°, 90°)")?;
        check("phi_i_deg", phi_i_deg, true, "must be finite")?;
        check("phi_o_deg", phi_o_deg, true, "must be finite")?;
        Ok(Self { theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg })
    }

    /// The configuration with ω_i and ω_o exchanged.
    pub fn swapped(&self) -> Self {
        Self {
            theta_i_deg: self.theta_o_deg,
            phi_i_deg: self.phi_o_deg,
            theta_o_deg: self.theta_i_deg,
            phi_o_deg: self.phi_i_deg,
        }
    }
}

/// Unit vector of polar angle θ and azimuth φ (degrees).
pub fn direction(theta_deg: f64, phi_deg: f64) -> [f64; 3] {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()]
}

/// Everything a simulation needs.
#[derive(Debug, Clone)]
pub struct Setup {
    pub slab: Slab,
    pub beam: Beam,
    pub sensor: Sensor,
    pub directions: Directions,
}

impl Setup {
    pub fn new(slab: Slab, beam: Beam, sensor: Sensor, directions: Directions) -> Self {
        Self { slab, beam, sensor, directions }
    }

    /// Whether the slice is symmetric under y → −y: ω_i and ω_o in the
    /// x–z plane (φ a multiple of 180°) and the beam's footprint symmetric.
    /// The phase function depends on the scattering angle only, so the
    /// transport is mirror-symmetric then.
    pub fn mirror_symmetric(&self) -> bool {
        let in_plane = |phi_deg: f64| phi_deg.to_radians().sin().abs() < 1e-12;
        let d = &self.directions;
        in_plane(d.phi_i_deg)
            && in_plane(d.phi_o_deg)
            && self.beam.mirror_symmetric(d.phi_i_deg)
            && self.slab.top.mirror_symmetric()
    }
}

/// When to stop; the first condition met ends the run (checked after each
/// round of 32 batches).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stop {
    pub paths: Option<u64>,
    pub time_s: Option<f64>,
    /// Target relative standard error of the slice sum.
    pub rel_error: Option<f64>,
    /// Target median per-pixel relative standard error over the pixels above
    /// [`PIXEL_MASK_FRACTION`] of the maximum (see [`PixelErrors`]).
    pub pixel_rel_error: Option<f64>,
}

impl Stop {
    pub fn paths(n: u64) -> Self {
        Self { paths: Some(n), ..Self::default() }
    }
}

/// Which estimator fills the slice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Estimator {
    /// Explicit connection at every scattering event along the one fixed
    /// direction ω₂₁ (the estimator before the ring; any configuration).
    Connection,
    /// Explicit connection over the ring of directions at the exit polar
    /// angle, using the slab's symmetry about the normal (see the module
    /// doc, "Ring connection"). Needs θ_i = 0 or θ_o = 0 and a thick slab
    /// (μ_t d / cos θ_t ≥ 40, no image terms); [`Estimator::best_for`]
    /// picks it where it applies.
    Ring,
    /// The fixed-direction connection combined by multiple importance
    /// sampling with chains of `vertices` events drawn backwards from ω₂₁
    /// through the phase function's lobe (see the module doc, "Lobe
    /// connection"; `vertices` = 1 is the two-vertex connection). Any exit
    /// direction, smooth or rough top; needs a thick slab (μ_t d / cos θ_t
    /// ≥ 40; through a rough top μ_t d ≥ 40). [`Estimator::best_for`] uses
    /// [`LOBE_VERTICES`].
    Lobe { vertices: usize },
    /// Escaping photons binned by exit pixel within a cone of half-angle
    /// `cone_deg` around ω_o (a slow, independent check).
    BruteForce { cone_deg: f64 },
}

impl Estimator {
    /// [`Estimator::Ring`] where it applies (one of θ_i, θ_o is 0 and the
    /// other is not, thick slab, smooth top), else [`Estimator::Lobe`] where
    /// it applies (thick slab, smooth or rough top), else
    /// [`Estimator::Connection`].
    pub fn best_for(setup: &Setup) -> Self {
        if Ring::applies(setup) {
            Estimator::Ring
        } else if lobe_applies(setup) {
            Estimator::Lobe { vertices: LOBE_VERTICES }
        } else {
            Estimator::Connection
        }
    }

    /// Whether the estimator is exact for `setup`: the ring needs θ_i or
    /// θ_o = 0, a thick slab and a smooth top; the lobe connection a thick
    /// slab ([`SlabError::RingNotApplicable`], [`SlabError::LobeNotApplicable`]
    /// otherwise); the others apply to every setup.
    pub fn applies(&self, setup: &Setup) -> bool {
        match self {
            Estimator::Ring => Ring::applies(setup),
            Estimator::Lobe { .. } => lobe_applies(setup),
            Estimator::Connection | Estimator::BruteForce { .. } => true,
        }
    }

    /// A short name for summaries.
    pub fn name(&self) -> &'static str {
        match self {
            Estimator::Connection => "connection (fixed direction)",
            Estimator::Ring => "ring connection (azimuthal symmetry)",
            Estimator::Lobe { .. } => {
                "lobe connection (MIS with chains drawn through the phase lobe around the exit direction)"
            }
            Estimator::BruteForce { .. } => "brute force (exit binning)",
        }
    }
}

/// Run options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunOptions {
    pub stop: Stop,
    pub seed: u64,
    pub batch_paths: u64,
    pub estimator: Estimator,
    /// Fold the slice about the plane of incidence (average of pixel (r, c)
    /// and its mirror (N−1−r, c), in every batch) where that is exact: both
    /// azimuths 0° or 180°, a mirror-symmetric beam and top surface ([`Setup::mirror_symmetric`]).
    pub fold: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self { stop: Stop::paths(100_000), seed: 1, batch_paths: 256, estimator: Estimator::Connection, fold: false }
    }
}

/// Progress after a round.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    pub paths: u64,
    pub events: u64,
    pub elapsed_s: f64,
    /// Relative standard error of the slice sum.
    pub rel_error: f64,
    /// Per-pixel relative standard errors over the bright pixels.
    pub pixels: PixelErrors,
}

/// Fraction of the brightest pixel's value above which pixels enter the
/// per-pixel error figures ([`PixelErrors`]): 1 %, the mask the lab's
/// comparison uses (`lucent bssrdf compare --threshold`).
pub const PIXEL_MASK_FRACTION: f64 = 0.01;

/// The per-pixel relative standard error σ_i / f_i over the pixels with
/// f_i > [`PIXEL_MASK_FRACTION`] · max f: its median and 90th percentile
/// (nearest rank). This is the figure that says whether a slice *image*
/// has converged (the sum converges much sooner); a mean squared relative
/// error against a measurement gains about median² from it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PixelErrors {
    pub median: f64,
    pub p90: f64,
    /// Pixels in the mask.
    pub pixels: usize,
}

impl PixelErrors {
    /// The figures of a slice's `values` and `std_error` (same length);
    /// infinite errors when no pixel is positive.
    pub fn of(values: &[f64], std_error: &[f64]) -> Self {
        let max = values.iter().copied().fold(0.0, f64::max);
        let cut = PIXEL_MASK_FRACTION * max;
        let mut rel: Vec<f64> =
            values.iter().zip(std_error).filter(|(v, _)| **v > cut && **v > 0.0).map(|(v, s)| s / v).collect();
        if rel.is_empty() {
            return Self { median: f64::INFINITY, p90: f64::INFINITY, pixels: 0 };
        }
        rel.sort_by(f64::total_cmp);
        let rank = |q: f64| rel[((q * rel.len() as f64).ceil() as usize).clamp(1, rel.len()) - 1];
        Self { median: rank(0.5), p90: rank(0.9), pixels: rel.len() }
    }
}

/// A simulated slice: per-pixel f_ssr [1/(m² sr)] and its standard error,
/// row-major from the top row.
#[derive(Debug, Clone)]
pub struct Slice {
    pub pixels: usize,
    pub pixel_m: f64,
    pub values: Vec<f64>,
    pub std_error: Vec<f64>,
    /// Σ over pixels of f_ssr [1/(m² sr)].
    pub sum: f64,
    pub sum_std_error: f64,
    pub paths: u64,
    pub events: u64,
    pub wall_s: f64,
    /// Fresnel reflectance of the top surface at θ_i (not in the slice).
    pub specular_reflectance: f64,
    /// Fraction of Φ_i leaving through the top after entering (all directions).
    pub diffuse_reflectance: f64,
    /// Fraction of Φ_i leaving through the bottom.
    pub transmittance: f64,
    /// Which kernel traced the paths: "avx2-fma lanes" (four paths per
    /// vector, see the `lanes` module) or "scalar". They agree to rounding.
    pub kernel: &'static str,
    pub estimator: Estimator,
    /// Whether the slice was folded about the plane of incidence
    /// ([`RunOptions::fold`]).
    pub folded: bool,
    /// Whether the photons were launched from the camera's side (the ring
    /// with θ_o = 0, by reciprocity); `diffuse_reflectance` and
    /// `transmittance` then describe light arriving along ω_o.
    pub reciprocal: bool,
}

impl Slice {
    pub fn events_per_s(&self) -> f64 {
        self.events as f64 / self.wall_s.max(1e-12)
    }

    /// Median and 90th percentile of the per-pixel relative standard error
    /// over the bright pixels ([`PixelErrors`]).
    pub fn pixel_errors(&self) -> PixelErrors {
        PixelErrors::of(&self.values, &self.std_error)
    }
}

/// Per-batch tallies.
struct Batch {
    image: Vec<f64>,
    path_sum: f64,
    path_sq: f64,
    events: u64,
    reflected: f64,
    transmitted: f64,
}

impl Batch {
    /// Empty tallies with `image` (a buffer to reuse) zeroed for `pixels`².
    fn new(mut image: Vec<f64>, pixels: usize) -> Self {
        image.clear();
        image.resize(pixels * pixels, 0.0);
        Batch { image, path_sum: 0.0, path_sq: 0.0, events: 0, reflected: 0.0, transmitted: 0.0 }
    }
}

/// Each estimator's own state, the payload of its variant.
enum Strategy {
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
    fn estimator(&self) -> Estimator {
        match self {
            Strategy::Connection => Estimator::Connection,
            Strategy::Ring(_) => Estimator::Ring,
            Strategy::Lobe { vertices, .. } => Estimator::Lobe { vertices: *vertices },
            Strategy::BruteForce { cone_deg, .. } => Estimator::BruteForce { cone_deg: *cone_deg },
        }
    }
}

/// Precomputed constants of a run.
struct Kernel<'a> {
    setup: &'a Setup,
    mu_t: f64,
    /// 1/μ_t, the mean free path [m].
    inv_mu_t: f64,
    albedo: f64,
    n: f64,
    d: f64,
    /// Direction of the light entering the slab (refracted −ω_i).
    entry_dir: [f64; 3],
    entry_weight: f64,
    footprint: Footprint<'a>,
    /// The estimator, with its own state.
    strategy: Strategy,
    /// ω₂₁, the in-medium direction refracting into ω_o.
    w21: [f64; 3],
    /// T(θ_t) / (n² A_o cos θ_t).
    splat: f64,
    inv_cos_t: f64,
    /// The smooth top's exit (ω₂₁, T/n², 1/cos θ_t, `splat`).
    smooth_exit: Exit,
    /// Internal Fresnel reflectance F(θ_t) at either boundary.
    fresnel_t: f64,
    /// Whether paths via internal reflections can matter (μ_t d / cos θ_t < 40).
    image_terms: bool,
    /// Optical depth below which connections are Russian-rouletted, and
    /// e^{−depth}.
    roulette_depth: f64,
    roulette_transmittance: f64,
    omega_o: [f64; 3],
    /// Fresnel reflectance of the top surface at θ_i (the specular part,
    /// whichever side the photons are launched from).
    specular: f64,
    /// Whether the top is rough: sampled entry, crossings and connections
    /// (`launch`, `cross`, `connect_rough`).
    rough: bool,
    /// The launch direction (ω_i, or ω_o for the reciprocal ring).
    launch: [f64; 3],
    /// Pixel area A_o [m²].
    area: f64,
    /// Whether batches run in the vector lanes of [`lanes`].
    #[cfg(target_arch = "x86_64")]
    lanes: bool,
}

impl<'a> Kernel<'a> {
    fn new(setup: &'a Setup, estimator: Estimator) -> Result<Self, SlabError> {
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
    fn launch(&self, rng: &mut Rng) -> Option<([f64; 3], [f64; 3], f64, Exit)> {
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

    /// Moves a photon at `p` travelling along `dir` with weight `w` to the
    /// boundary `gap` ahead (vertically) and samples it there
    /// ([`Interface::sample`], the Fresnel choice): reflected (new direction
    /// and weight), transmitted out of the top (with the direction in air)
    /// or bottom, or lost at a rough top.
    #[inline]
    fn cross(&self, p: &mut [f64; 3], dir: &mut [f64; 3], w: &mut f64, gap: f64, rng: &mut Rng) -> Crossing {
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
    fn connection_transmittance(&self, tau: f64, e: f64, rng: &mut Rng) -> f64 {
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
    fn connect(&self, p: [f64; 3], dir: [f64; 3], w: f64, exit: Exit, image: &mut [f64], rng: &mut Rng) -> f64 {
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
    fn connect_unscattered(&self, p: [f64; 3], dir: [f64; 3], gap: f64, w: f64, image: &mut [f64]) -> f64 {
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

    /// Traces paths `first_path` … `first_path + paths − 1` of `seed`: four
    /// at a time in vector lanes where the CPU allows and the estimator is
    /// the connection ([`lanes`]), otherwise one at a time. The two agree to
    /// rounding.
    /// `image` is a buffer to reuse (its contents are discarded).
    fn batch(&self, seed: u64, first_path: u64, paths: u64, image: Vec<f64>) -> Batch {
        #[cfg(target_arch = "x86_64")]
        if self.lanes {
            // SAFETY: `lanes` is set only when the CPU has AVX2 and FMA.
            return unsafe { self.batch_lanes(seed, first_path, paths, image) };
        }
        self.batch_scalar(seed, first_path, paths, image)
    }

    /// The name of the kernel [`batch`](Self::batch) uses (see [`Slice::kernel`]).
    fn name(&self) -> &'static str {
        #[cfg(target_arch = "x86_64")]
        if self.lanes {
            return "avx2-fma lanes";
        }
        "scalar"
    }

    /// [`batch`](Self::batch) one path at a time.
    fn batch_scalar(&self, seed: u64, first_path: u64, paths: u64, image: Vec<f64>) -> Batch {
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

#[cfg(target_arch = "x86_64")]
mod lanes;
mod lobe;
mod ring;

use lobe::{Chain, Junctions};
#[cfg(target_arch = "x86_64")]
use lobe::{Links, LobeEvent};
use ring::Ring;

/// A path's exit direction: the light leaves the slab travelling along
/// `up` = ω₂₁ with the radiance weight W of the exit, (1 − F) G1 / n² for a
/// sample through a rough top (0: lost, no connections) and T(θ_t)/n² for
/// the smooth top's fixed ω₂₁. Drawn once per path through a rough top
/// (`Kernel::launch`), fixed for the smooth one.
#[derive(Debug, Clone, Copy)]
struct Exit {
    up: [f64; 3],
    weight: f64,
    /// 1/cos θ₂₁ (cos θ₂₁ = `up`'s z component).
    inv_cos: f64,
    /// The splat constant C = W/(A_o cos θ₂₁) of the thick-slab
    /// connections along `up` (0 when the sample is lost).
    splat: f64,
}

impl Exit {
    /// No exit: a rough exit sample that was lost.
    const LOST: Exit = Exit { up: [0.0, 0.0, 1.0], weight: 0.0, inv_cos: 1.0, splat: 0.0 };

    /// The exit along `up` (z > 0) with radiance weight `weight`, for
    /// pixels of area `area`.
    fn new(up: [f64; 3], weight: f64, area: f64) -> Self {
        let inv_cos = 1.0 / up[2];
        Exit { up, weight, inv_cos, splat: weight * inv_cos / area }
    }
}

/// Where a photon that reached a boundary goes.
enum Crossing {
    Reflected,
    /// Out through the top, along this direction in air.
    LeftTop([f64; 3]),
    LeftBottom,
    /// Lost at a rough top (a microfacet sample sent to the wrong side).
    Lost,
}

/// The reflectance of a rough top for light arriving from ω_i (the
/// directional albedo of its reflection lobe, not part of the slice): the
/// mean of the reflection weight F G1 over 64 × 64 stratified visible
/// normals (deterministic).
fn rough_specular(top: &Interface, omega_i: [f64; 3], n: f64) -> f64 {
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
fn refract_z(d: [f64; 3], n: f64) -> [f64; 3] {
    fresnel::refract(DVec3::from_array(d), DVec3::Z, n).expect("air → denser medium always refracts").to_array()
}

/// The second random stream of path `path`: connections, their roulette
/// and the weight roulette draw from it, the walk itself (launch, flights,
/// scattering angles, boundary choices) from `Rng::new(seed, path)`. How
/// many numbers those draw depends on μ_t and the weight, so in one stream
/// they would shift the walk's numbers whenever a coefficient changes; kept
/// apart, the walks of slightly different slabs traced with one seed stay
/// alike ([`simulate_coupled`]).
#[inline]
fn aux_stream(seed: u64, path: u64) -> Rng {
    Rng::new(seed ^ 0x5eed_a0c5_11ce_5a17, path)
}

/// Russian roulette on a path's weight `w` < 0.1: survives with probability
/// w/0.1 and then carries weight 0.1 (unbiased).
#[inline]
fn survives_roulette(w: &mut f64, rng: &mut Rng) -> bool {
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

/// Azimuths per ring connection (see the module doc): stratified in the
/// sampler's CDF, sharing one footprint point. Measured on IOL1068-09
/// (45°/0°, 10⁵ paths), median relative error of the pixels 0.5–3 mm from
/// the beam: 38 % with 1 azimuth, 22 % with 4, 13 % with 16, 11 % with 32;
/// 16 costs about 4× the CPU time of the fixed-direction connection per
/// path (1 azimuth: 1.6×) and gave the smallest error² × time; one footprint
/// point per connection instead of one per azimuth cost 25 % less time for
/// 3 % more error.
pub const RING_SPLATS: usize = 16;

/// Camera-side vertices of the lobe connection by default (see the module
/// doc, "Lobe connection"; [`Estimator::Lobe`]). Measured on IOL1068-09
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

/// The most camera-side vertices [`Estimator::Lobe`] accepts.
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
fn lobe_applies(setup: &Setup) -> bool {
    let m = &setup.slab.medium;
    let tau_d = m.mu_t_per_m() * setup.slab.thickness_m;
    if setup.slab.top.is_rough() {
        return tau_d >= 40.0;
    }
    let sin_t = setup.directions.theta_o_deg.to_radians().sin() / m.n;
    let cos_t = (1.0 - sin_t * sin_t).sqrt();
    tau_d / cos_t >= 40.0
}

/// Longest chain of internal reflections a rough-top connection follows
/// (it stops earlier at 40 optical depths or a weight below 10⁻⁹).
const MAX_CHAIN: usize = 64;

/// Batches per round (fixed, so results do not depend on the thread count).
const ROUND_BATCHES: u64 = 32;

/// Simulates the slice of `setup`, calling `progress` after every round.
pub fn simulate(setup: &Setup, options: &RunOptions, progress: impl FnMut(&Progress)) -> Result<Slice, SlabError> {
    simulate_cancellable(setup, options, progress, &AtomicBool::new(false))
}

/// [`simulate`] that also stops at the end of the round under way when
/// `cancel` becomes true (a Ctrl-C handler sets it): the slice returned is
/// then a valid estimate from the paths finished so far, with its errors.
pub fn simulate_cancellable(
    setup: &Setup,
    options: &RunOptions,
    mut progress: impl FnMut(&Progress),
    cancel: &AtomicBool,
) -> Result<Slice, SlabError> {
    let stop = options.stop;
    if stop.paths.is_none() && stop.time_s.is_none() && stop.rel_error.is_none() && stop.pixel_rel_error.is_none() {
        return Err(SlabError::NoStopRule);
    }
    if let Some(e) = stop.rel_error {
        check("rel_error", e, e > 0.0 && e < 1.0, "must lie in (0, 1)")?;
    }
    if let Some(e) = stop.pixel_rel_error {
        check("pixel_rel_error", e, e > 0.0 && e < 1.0, "must lie in (0, 1)")?;
    }
    if let Some(t) = stop.time_s {
        check("time_s", t, t > 0.0, "must be > 0")?;
    }
    let batch_paths = options.batch_paths.max(1);
    let kernel = Kernel::new(setup, options.estimator)?;
    let fold = options.fold && setup.mirror_symmetric();
    let mut sums = SliceSums::empty(&kernel, setup, fold);
    let mut batches = 0u64;
    let mut pool: Vec<Vec<f64>> = Vec::new();
    let start = Instant::now();
    let rel_err = |paths: u64, s: f64, sq: f64| {
        let n = paths as f64;
        let mean = s / n;
        let var = (sq / n - mean * mean).max(0.0) / (n - 1.0).max(1.0);
        if mean > 0.0 {
            var.sqrt() / mean
        } else {
            f64::INFINITY
        }
    };
    loop {
        let mut round = ROUND_BATCHES;
        if let Some(max) = stop.paths {
            let left = max.saturating_sub(batches * batch_paths).div_ceil(batch_paths);
            round = round.min(left);
        }
        if round == 0 {
            break;
        }
        let firsts: Vec<(u64, u64)> = (0..round)
            .map(|k| {
                let first = (batches + k) * batch_paths;
                let count = match stop.paths {
                    Some(max) => batch_paths.min(max - first),
                    None => batch_paths,
                };
                (first, count)
            })
            .collect();
        sums.add_round(&kernel, options.seed, &firsts, &mut pool);
        let (path_sum, path_sq, events) = (sums.path_sum, sums.path_sq, sums.events);
        batches += round;
        let paths = stop.paths.map_or(batches * batch_paths, |m| m.min(batches * batch_paths));
        let elapsed = start.elapsed().as_secs_f64();
        let e = rel_err(paths, path_sum, path_sq);
        let (v, se) = pixel_estimates(&sums.raw, &sums.sum_b, &sums.sq_b, paths, batches);
        let pixels = PixelErrors::of(&v, &se);
        progress(&Progress { paths, events, elapsed_s: elapsed, rel_error: e, pixels });
        let enough = batches >= 2 * ROUND_BATCHES;
        if stop.paths.is_some_and(|m| paths >= m)
            || stop.time_s.is_some_and(|t| elapsed >= t)
            || stop.rel_error.is_some_and(|t| e <= t && enough)
            || stop.pixel_rel_error.is_some_and(|t| pixels.median <= t && enough)
            || cancel.load(Ordering::Relaxed)
        {
            break;
        }
    }
    sums.batches = batches;
    sums.paths = stop.paths.map_or(batches * batch_paths, |m| m.min(batches * batch_paths));
    sums.wall_s = start.elapsed().as_secs_f64();
    Ok(sums.slice())
}

/// The tallies of a run, or of one shard of it ([`simulate_batches`]):
/// per pixel the sums over batches of the batch means and of their squares
/// and the raw sum of the splats, and the sums over paths of the per-path
/// totals. Shards of one run add up ([`SliceSums::add`]) to the run's
/// tallies, to rounding (the sums are taken in another order).
#[derive(Debug, Clone)]
pub struct SliceSums {
    pub pixels: usize,
    pub pixel_m: f64,
    pub sum_b: Vec<f64>,
    pub sq_b: Vec<f64>,
    pub raw: Vec<f64>,
    pub path_sum: f64,
    pub path_sq: f64,
    pub events: u64,
    pub reflected: f64,
    pub transmitted: f64,
    /// Batches and paths traced.
    pub batches: u64,
    pub paths: u64,
    pub wall_s: f64,
    pub specular_reflectance: f64,
    pub kernel: &'static str,
    pub estimator: Estimator,
    pub folded: bool,
    pub reciprocal: bool,
}

impl SliceSums {
    fn empty(kernel: &Kernel, setup: &Setup, fold: bool) -> Self {
        let npix = setup.sensor.pixels * setup.sensor.pixels;
        Self {
            pixels: setup.sensor.pixels,
            pixel_m: setup.sensor.pixel_m,
            sum_b: vec![0.0; npix],
            sq_b: vec![0.0; npix],
            raw: vec![0.0; npix],
            path_sum: 0.0,
            path_sq: 0.0,
            events: 0,
            reflected: 0.0,
            transmitted: 0.0,
            batches: 0,
            paths: 0,
            wall_s: 0.0,
            specular_reflectance: kernel.specular,
            kernel: kernel.name(),
            estimator: kernel.strategy.estimator(),
            folded: fold,
            reciprocal: matches!(&kernel.strategy, Strategy::Ring(r) if r.sign < 0.0),
        }
    }

    /// Traces the batches `(first path, paths)` in parallel and adds them
    /// in their order. Batch images are reused from round to round (no
    /// allocation and no page faults), and merged in parallel over pixel
    /// chunks, each pixel taking the batches in order (so the sums do not
    /// depend on the thread count).
    fn add_round(&mut self, kernel: &Kernel, seed: u64, batches: &[(u64, u64)], pool: &mut Vec<Vec<f64>>) {
        let buffers: Vec<Vec<f64>> = batches.iter().map(|_| pool.pop().unwrap_or_default()).collect();
        let results: Vec<(u64, Batch)> = buffers
            .into_par_iter()
            .zip(batches.par_iter())
            .map(|(image, &(first, count))| (count, kernel.batch(seed, first, count, image)))
            .collect();
        let images: Vec<(u64, &[f64])> = results.iter().map(|(count, b)| (*count, b.image.as_slice())).collect();
        tally_images(&mut self.sum_b, &mut self.sq_b, &mut self.raw, &images, self.folded, self.pixels);
        for (_, b) in results {
            self.path_sum += b.path_sum;
            self.path_sq += b.path_sq;
            self.events += b.events;
            self.reflected += b.reflected;
            self.transmitted += b.transmitted;
            pool.push(b.image);
        }
    }

    /// Adds another shard's tallies (same setup, same pixels) after these.
    pub fn add(&mut self, o: &SliceSums) {
        for (a, b) in [(&mut self.sum_b, &o.sum_b), (&mut self.sq_b, &o.sq_b), (&mut self.raw, &o.raw)] {
            for (x, y) in a.iter_mut().zip(b.iter()) {
                *x += y;
            }
        }
        self.path_sum += o.path_sum;
        self.path_sq += o.path_sq;
        self.events += o.events;
        self.reflected += o.reflected;
        self.transmitted += o.transmitted;
        self.batches += o.batches;
        self.paths += o.paths;
        self.wall_s += o.wall_s;
    }

    /// The slice these tallies give.
    pub fn slice(&self) -> Slice {
        let paths = self.paths.max(1);
        let (values, std_error) = pixel_estimates(&self.raw, &self.sum_b, &self.sq_b, paths, self.batches);
        let n = paths as f64;
        let mean = self.path_sum / n;
        let sum_std_error = ((self.path_sq / n - mean * mean).max(0.0) / (n - 1.0).max(1.0)).sqrt();
        Slice {
            pixels: self.pixels,
            pixel_m: self.pixel_m,
            values,
            std_error,
            sum: mean,
            sum_std_error,
            paths,
            events: self.events,
            wall_s: self.wall_s,
            specular_reflectance: self.specular_reflectance,
            diffuse_reflectance: self.reflected / n,
            transmittance: self.transmitted / n,
            kernel: self.kernel,
            estimator: self.estimator,
            folded: self.folded,
            reciprocal: self.reciprocal,
        }
    }
}

/// Batches `batches` of the run [`simulate`] makes with
/// `options.stop = Stop::paths(total_paths)` (batch b holds paths
/// b·batch_paths … up to `total_paths`, each path drawing from its own
/// stream), as tallies: one shard of that run. The shards of a partition of
/// its batches add up to its tallies ([`SliceSums::add`], in batch order).
/// Stops at the end of the round under way when `cancel` becomes true.
pub fn simulate_batches(
    setup: &Setup,
    options: &RunOptions,
    batches: std::ops::Range<u64>,
    total_paths: u64,
    cancel: &AtomicBool,
) -> Result<SliceSums, SlabError> {
    let batch_paths = options.batch_paths.max(1);
    let kernel = Kernel::new(setup, options.estimator)?;
    let fold = options.fold && setup.mirror_symmetric();
    let mut sums = SliceSums::empty(&kernel, setup, fold);
    let mut pool: Vec<Vec<f64>> = Vec::new();
    let start = Instant::now();
    let mut b = batches.start;
    let end = batches.end.min(total_paths.div_ceil(batch_paths));
    while b < end && !cancel.load(Ordering::Relaxed) {
        let round: Vec<(u64, u64)> = (b..end.min(b + ROUND_BATCHES))
            .map(|k| (k * batch_paths, batch_paths.min(total_paths - k * batch_paths)))
            .collect();
        sums.add_round(&kernel, options.seed, &round, &mut pool);
        sums.batches += round.len() as u64;
        sums.paths += round.iter().map(|r| r.1).sum::<u64>();
        b += round.len() as u64;
    }
    sums.wall_s = start.elapsed().as_secs_f64();
    Ok(sums)
}

/// Per-pixel values (mean over `paths` of the raw sums) and standard
/// errors (from the spread of the `batches` batch means, which are
/// equal-sized except possibly the last).
fn pixel_estimates(raw: &[f64], sum_b: &[f64], sq_b: &[f64], paths: u64, batches: u64) -> (Vec<f64>, Vec<f64>) {
    let nb = batches.max(1) as f64;
    let values = raw.iter().map(|r| r / paths.max(1) as f64).collect();
    let std_error = sum_b
        .iter()
        .zip(sq_b)
        .map(|(s, q)| {
            let mean = s / nb;
            ((q / nb - mean * mean).max(0.0) / (nb - 1.0).max(1.0)).sqrt()
        })
        .collect();
    (values, std_error)
}

/// Adds batch images `(paths, image)`, in their order, to the per-pixel
/// sums of batch means (`sum_b`), of their squares (`sq_b`) and of the raw
/// splats (`raw`); with `fold`, pixel (r, c) and its mirror (N−1−r, c) of
/// the `side` × `side` image averaged first. Parallel over pixel chunks,
/// each pixel taking the batches in order (so the sums do not depend on
/// the thread count).
fn tally_images(
    sum_b: &mut [f64],
    sq_b: &mut [f64],
    raw: &mut [f64],
    images: &[(u64, &[f64])],
    fold: bool,
    side: usize,
) {
    const CHUNK: usize = 4096;
    sum_b.par_chunks_mut(CHUNK).zip(sq_b.par_chunks_mut(CHUNK)).zip(raw.par_chunks_mut(CHUNK)).enumerate().for_each(
        |(c, ((sum_b, sq_b), raw))| {
            let at = c * CHUNK;
            for (count, image) in images {
                let scale = 1.0 / *count as f64;
                for (k, ((s, q), r)) in sum_b.iter_mut().zip(sq_b.iter_mut()).zip(raw.iter_mut()).enumerate() {
                    let i = at + k;
                    let v = if fold {
                        let mirror = (side - 1 - i / side) * side + i % side;
                        0.5 * (image[i] + image[mirror])
                    } else {
                        image[i]
                    };
                    let m = v * scale;
                    *s += m;
                    *q += m * m;
                    *r += v;
                }
            }
        },
    );
}

/// The difference f_a − f_b of two slices traced with common random
/// numbers ([`simulate_coupled`]): per pixel [1/(m² sr)], row-major from
/// the top row, with its standard error from the spread of the batches'
/// differences (so the two slices' shared noise, which cancels in the
/// difference, does not count).
#[derive(Debug, Clone)]
pub struct SliceDifference {
    pub pixels: usize,
    pub pixel_m: f64,
    pub values: Vec<f64>,
    pub std_error: Vec<f64>,
    /// Σ over pixels of f_a − f_b [1/(m² sr)] and its standard error.
    pub sum: f64,
    pub sum_std_error: f64,
    pub paths: u64,
}

/// The slice of `nominal` and, for each pair (a, b) of `pairs`, the
/// difference of the slices of a and b, all traced with **common random
/// numbers**: path k of every setup draws from the same stream
/// ([`Rng::new`]`(seed, k)`), so where the setups differ a little (a
/// perturbed μ_s, μ_a or phase function), their paths stay alike and the
/// difference carries far less noise than either slice (the correlated
/// sampling of Rubinstein & Kroese, *Simulation and the Monte Carlo
/// Method*, 2017, §5.2; the central differences of a sensitivity). Every
/// setup must have the nominal one's sensor; the estimator is the nominal
/// run's and must apply to each setup. Stops by `options.stop.paths` or
/// `time_s` (required: one of them), or at the end of the round under way
/// when `cancel` becomes true; `progress` is called after every round with
/// the nominal slice's figures.
pub fn simulate_coupled(
    nominal: &Setup,
    pairs: &[(Setup, Setup)],
    options: &RunOptions,
    mut progress: impl FnMut(&Progress),
    cancel: &AtomicBool,
) -> Result<(Slice, Vec<SliceDifference>), SlabError> {
    let stop = options.stop;
    if stop.paths.is_none() && stop.time_s.is_none() {
        return Err(SlabError::NoStopRule);
    }
    if let Some(t) = stop.time_s {
        check("time_s", t, t > 0.0, "must be > 0")?;
    }
    let batch_paths = options.batch_paths.max(1);
    let kernel = Kernel::new(nominal, options.estimator)?;
    let kernels: Vec<(Kernel, Kernel)> = pairs
        .iter()
        .map(|(a, b)| {
            for s in [a, b] {
                if s.sensor != nominal.sensor {
                    return Err(SlabError::Parameter {
                        name: "pixels",
                        value: s.sensor.pixels as f64,
                        reason: "a coupled setup must have the nominal setup's sensor",
                    });
                }
            }
            Ok((Kernel::new(a, options.estimator)?, Kernel::new(b, options.estimator)?))
        })
        .collect::<Result<_, SlabError>>()?;
    let fold = options.fold
        && nominal.mirror_symmetric()
        && pairs.iter().all(|(a, b)| a.mirror_symmetric() && b.mirror_symmetric());
    let mut sums = SliceSums::empty(&kernel, nominal, fold);
    let npix = nominal.sensor.pixels * nominal.sensor.pixels;
    // Per pair: sums over batches of the batch mean differences, their squares, the raw differences; and of the batch sum differences.
    let mut diffs: Vec<([Vec<f64>; 3], f64, f64, f64)> =
        pairs.iter().map(|_| ([vec![0.0; npix], vec![0.0; npix], vec![0.0; npix]], 0.0, 0.0, 0.0)).collect();
    let mut pool: Vec<Vec<f64>> = Vec::new();
    let start = Instant::now();
    let mut batches = 0u64;
    loop {
        let mut round = ROUND_BATCHES;
        if let Some(max) = stop.paths {
            round = round.min(max.saturating_sub(batches * batch_paths).div_ceil(batch_paths));
        }
        if round == 0 {
            break;
        }
        let firsts: Vec<(u64, u64)> = (0..round)
            .map(|k| {
                let first = (batches + k) * batch_paths;
                (first, stop.paths.map_or(batch_paths, |max| batch_paths.min(max - first)))
            })
            .collect();
        sums.add_round(&kernel, options.seed, &firsts, &mut pool);
        for ((ka, kb), (d, s, sq, raw_sum)) in kernels.iter().zip(diffs.iter_mut()) {
            let traced: Vec<(u64, Vec<f64>, f64)> = firsts
                .par_iter()
                .map(|&(first, count)| {
                    let a = ka.batch(options.seed, first, count, Vec::new());
                    let b = kb.batch(options.seed, first, count, Vec::new());
                    let image: Vec<f64> = a.image.iter().zip(&b.image).map(|(x, y)| x - y).collect();
                    (count, image, a.path_sum - b.path_sum)
                })
                .collect();
            let images: Vec<(u64, &[f64])> = traced.iter().map(|(c, im, _)| (*c, im.as_slice())).collect();
            let [sum_b, sq_b, raw] = d;
            tally_images(sum_b, sq_b, raw, &images, fold, nominal.sensor.pixels);
            for (count, _, path_diff) in &traced {
                let m = path_diff / *count as f64;
                *s += m;
                *sq += m * m;
                *raw_sum += path_diff;
            }
        }
        batches += round;
        let elapsed = start.elapsed().as_secs_f64();
        let paths = stop.paths.map_or(batches * batch_paths, |m| m.min(batches * batch_paths));
        let n = paths as f64;
        let mean = sums.path_sum / n;
        let var = (sums.path_sq / n - mean * mean).max(0.0) / (n - 1.0).max(1.0);
        let (v, se) = pixel_estimates(&sums.raw, &sums.sum_b, &sums.sq_b, paths, batches);
        progress(&Progress {
            paths,
            events: sums.events,
            elapsed_s: elapsed,
            rel_error: if mean > 0.0 { var.sqrt() / mean } else { f64::INFINITY },
            pixels: PixelErrors::of(&v, &se),
        });
        if stop.paths.is_some_and(|m| paths >= m)
            || stop.time_s.is_some_and(|t| elapsed >= t)
            || cancel.load(Ordering::Relaxed)
        {
            break;
        }
    }
    sums.batches = batches;
    sums.paths = stop.paths.map_or(batches * batch_paths, |m| m.min(batches * batch_paths));
    sums.wall_s = start.elapsed().as_secs_f64();
    let paths = sums.paths;
    let nb = batches.max(1) as f64;
    let differences = diffs
        .into_iter()
        .map(|([sum_b, sq_b, raw], s, sq, raw_sum)| {
            let (values, std_error) = pixel_estimates(&raw, &sum_b, &sq_b, paths, batches);
            let mean_b = s / nb;
            SliceDifference {
                pixels: nominal.sensor.pixels,
                pixel_m: nominal.sensor.pixel_m,
                values,
                std_error,
                sum: raw_sum / paths.max(1) as f64,
                sum_std_error: ((sq / nb - mean_b * mean_b).max(0.0) / (nb - 1.0).max(1.0)).sqrt(),
                paths,
            }
        })
        .collect();
    Ok((sums.slice(), differences))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::microfacet::{Distribution, Microsurface};
    use crate::phase::Phase;

    /// Mean and standard error of the per-path totals of `paths` paths.
    fn slice_sum(kernel: &Kernel, seed: u64, paths: u64) -> (f64, f64) {
        let b = kernel.batch(seed, 0, paths, Vec::new());
        let n = paths as f64;
        let mean = b.path_sum / n;
        (mean, ((b.path_sq / n - mean * mean) / (n - 1.0)).sqrt())
    }

    /// Common random numbers: the coupled difference of two slabs whose μ_s
    /// differ by 4 % agrees with the difference of two independent long
    /// runs; its stated standard error matches the spread over seeds; and
    /// it is several times smaller than the independent runs' at the same
    /// paths (what the coupling is for).
    #[test]
    fn coupled_differences_are_unbiased_with_honest_errors() {
        let setup = |mu_s: f64| {
            let medium =
                Medium::new(mu_s, 30.0, Phase::henyey_greenstein(0.8).expect("valid g"), 1.5).expect("valid medium");
            Setup::new(
                Slab::new(2.0e-3, medium).expect("valid slab"),
                Beam::gaussian(300e-6).expect("valid beam"),
                Sensor::new(21, 0.2e-3).expect("valid sensor"),
                Directions::from_degrees(45.0, 0.0, 0.0, 180.0).expect("valid directions"),
            )
        };
        let (nominal, a, b) = (setup(5.0e3), setup(5.1e3), setup(4.9e3));
        let paths = 20_000;
        let options = |seed: u64, paths: u64| RunOptions {
            stop: Stop::paths(paths),
            seed,
            batch_paths: 250,
            estimator: Estimator::Connection,
            fold: true,
        };
        let never = AtomicBool::new(false);
        let pairs = [(a.clone(), b.clone())];
        let runs: Vec<SliceDifference> = (0..8)
            .map(|seed| {
                let (slice, mut d) =
                    simulate_coupled(&nominal, &pairs, &options(10 + seed, paths), |_| {}, &never).unwrap();
                assert_eq!(slice.paths, paths);
                d.remove(0)
            })
            .collect();
        let sums: Vec<f64> = runs.iter().map(|d| d.sum).collect();
        let mean = sums.iter().sum::<f64>() / 8.0;
        let spread = (sums.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 7.0).sqrt();
        let stated = (runs.iter().map(|d| d.sum_std_error.powi(2)).sum::<f64>() / 8.0).sqrt();
        // 8 seeds: the sample sd lies within 0.45 … 1.6 of the true one with probability > 0.99.
        assert!(spread > 0.45 * stated && spread < 1.6 * stated, "spread over seeds {spread} vs stated {stated}");
        // The same per pixel, pooled over the bright pixels.
        let bright: Vec<usize> = (0..runs[0].values.len()).filter(|&i| runs[0].std_error[i] > 0.0).collect();
        let mut ratio = 0.0;
        for &i in &bright {
            let m = runs.iter().map(|d| d.values[i]).sum::<f64>() / 8.0;
            let var = runs.iter().map(|d| (d.values[i] - m).powi(2)).sum::<f64>() / 7.0;
            let stated = runs.iter().map(|d| d.std_error[i].powi(2)).sum::<f64>() / 8.0;
            ratio += var / stated;
        }
        ratio /= bright.len() as f64;
        assert!(ratio > 0.7 && ratio < 1.4, "per-pixel variance over seeds / stated variance: {ratio}");
        // Independent long runs of a and b (their own seeds).
        let long = 8 * paths;
        let sa = simulate(&a, &options(101, long), |_| {}).unwrap();
        let sb = simulate(&b, &options(202, long), |_| {}).unwrap();
        let independent = sa.sum - sb.sum;
        let se_independent = (sa.sum_std_error.powi(2) + sb.sum_std_error.powi(2)).sqrt();
        let se_coupled = stated / 8f64.sqrt();
        let z = (mean - independent) / (se_coupled.powi(2) + se_independent.powi(2)).sqrt();
        assert!(z.abs() < 3.5, "coupled {mean} ± {se_coupled} vs independent {independent} ± {se_independent} (z {z})");
        // At equal paths the independent difference's error is ×√8 larger than the long runs'.
        let se_independent_equal = se_independent * 8f64.sqrt();
        assert!(
            stated < 0.5 * se_independent_equal,
            "coupled s.e. {stated} vs independent {se_independent_equal} at {paths} paths"
        );
    }

    #[test]
    fn connection_roulette_is_unbiased() {
        // Thick, forward-scattering slab (μ_t d ≈ 60): most events lie
        // deeper than the roulette depth. Each run has its own seed, so the
        // three estimates are independent.
        let medium =
            Medium::new(1.0e4, 20.0, Phase::henyey_greenstein(0.9).expect("valid g"), 1.5).expect("valid medium");
        let setup = Setup::new(
            Slab::new(6.0e-3, medium).expect("valid slab"),
            Beam::gaussian(200e-6).expect("valid beam"),
            Sensor::new(65, 0.2e-3).expect("valid sensor"),
            Directions::from_degrees(45.0, 0.0, 0.0, 180.0).expect("valid directions"),
        );
        let mut kernel = Kernel::new(&setup, Estimator::Connection).expect("valid kernel");
        assert!(!kernel.image_terms);
        let (default, se_default) = slice_sum(&kernel, 3, 20_000);
        kernel.roulette_depth = f64::INFINITY;
        let (without, se_without) = slice_sum(&kernel, 4, 20_000);
        // Roulette from one optical depth on: most of the slice goes through
        // it, so a wrong weight would show.
        kernel.roulette_depth = 1.0;
        kernel.roulette_transmittance = (-1.0f64).exp();
        let (shallow, se_shallow) = slice_sum(&kernel, 5, 20_000);
        for (name, with, se_with) in [("default", default, se_default), ("τ_r = 1", shallow, se_shallow)] {
            let z = (with - without) / (se_with * se_with + se_without * se_without).sqrt();
            assert!(
                z.abs() < 4.0,
                "{name}: with roulette {with} ± {se_with}, without {without} ± {se_without} (z = {z})"
            );
        }
        let se_with = se_default;
        assert!(se_with < 1.2 * se_without, "standard error {se_with} vs {se_without}");
    }

    /// The lane kernel against the scalar one on the same paths: the same
    /// random numbers and decisions, so every pixel, the path tallies and
    /// the event count agree to rounding. Covers the thick slab (vector
    /// connection, roulette) and the thin one (image terms), HG with g ≥ 10⁻³
    /// (vector sampling) and g = 0 and a table (per-lane sampling), and a
    /// measured beam map.
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn lanes_trace_the_scalar_paths() {
        if crate::simd::lanes_unavailable() {
            return;
        }
        let table = table_phase();
        let hg = |g| Phase::henyey_greenstein(g).expect("valid g");
        let map = Beam::Map(BeamMap::new(3, 2, 0.1e-3, vec![0.0, 1.0, 2.0, 4.0, 0.5, 0.0]).expect("valid map"));
        let cases = [
            ("thick PDMS-like, HG", Medium::new(1.47e4, 9.6, hg(0.974), 1.589), 6.35e-3, 45.0, Beam::gaussian(200e-6)),
            ("thin, HG, image terms", Medium::new(2000.0, 10.0, hg(0.5), 1.4), 1e-3, 30.0, Beam::gaussian(300e-6)),
            ("thin, g = 0, beam map", Medium::new(3000.0, 50.0, hg(0.0), 1.3), 0.5e-3, 0.0, Ok(map)),
            ("thick, table", Medium::new(1.0e4, 30.0, table, 1.5), 5e-3, 60.0, Beam::gaussian(100e-6)),
            ("thick, g < 0", Medium::new(8000.0, 5.0, hg(-0.3), 1.45), 4e-3, 20.0, Beam::gaussian(100e-6)),
        ];
        for (name, medium, d, theta_i, beam) in cases {
            let setup = Setup::new(
                Slab::new(d, medium.expect("valid medium")).expect("valid slab"),
                beam.expect("valid beam"),
                Sensor::new(63, 0.1e-3).expect("valid sensor"),
                Directions::from_degrees(theta_i, 0.0, 15.0, 180.0).expect("valid directions"),
            );
            let kernel = Kernel::new(&setup, Estimator::Connection).expect("valid kernel");
            assert!(kernel.lanes, "{name}");
            compare_kernels(name, &kernel);
        }
        // A rough top: sampled entry, crossings and connections, thick
        // (straight-up term) and thin (the chain of image terms), analytic
        // distributions and a measured normal set.
        let measured: Vec<[f64; 3]> = (0..400)
            .map(|k| {
                let (a, b) = ((k % 20) as f64 / 20.0 - 0.5, (k / 20) as f64 / 20.0 - 0.5);
                let v = [0.3 * a, 0.2 * b + 0.05 * a, 1.0];
                let l = (v[0] * v[0] + v[1] * v[1] + 1.0f64).sqrt();
                [v[0] / l, v[1] / l, v[2] / l]
            })
            .collect();
        let rough_cases = [
            ("rough thick, TR 0.3", Microsurface::Analytic(Distribution::TrowbridgeReitz { alpha: 0.3 }), 6e-3),
            ("rough thin, Beckmann 0.1", Microsurface::Analytic(Distribution::Beckmann { alpha: 0.1 }), 1e-3),
            (
                "rough thin, measured",
                Microsurface::Measured(std::sync::Arc::new(
                    crate::microfacet::MeasuredNormals::new(&measured, None).expect("valid normals"),
                )),
                1e-3,
            ),
        ];
        for (name, surface, d) in rough_cases {
            let medium = Medium::new(4000.0, 10.0, hg(0.7), 1.5).expect("valid medium");
            let setup = Setup::new(
                Slab::new(d, medium).expect("valid slab").with_top(Interface::new(surface).expect("valid α")),
                Beam::gaussian(200e-6).expect("valid beam"),
                Sensor::new(63, 0.1e-3).expect("valid sensor"),
                Directions::from_degrees(45.0, 0.0, 0.0, 180.0).expect("valid directions"),
            );
            let kernel = Kernel::new(&setup, Estimator::Connection).expect("valid kernel");
            assert!(kernel.lanes && kernel.rough, "{name}");
            compare_kernels(name, &kernel);
        }
        // The ring connection: launched from the light (θ_i = 0) and from
        // the camera (θ_o = 0), HG and a table.
        let ring_cases = [
            ("ring, reciprocal, HG", Phase::henyey_greenstein(0.9).expect("valid g"), 45.0, 0.0),
            ("ring, direct, table", table_phase(), 0.0, 30.0),
        ];
        for (name, phase, theta_i, theta_o) in ring_cases {
            let setup = Setup::new(
                Slab::new(6e-3, Medium::new(1.2e4, 10.0, phase, 1.5).expect("valid medium")).expect("valid slab"),
                Beam::gaussian(200e-6).expect("valid beam"),
                Sensor::new(63, 0.1e-3).expect("valid sensor"),
                Directions::from_degrees(theta_i, 0.0, theta_o, 180.0).expect("valid directions"),
            );
            let kernel = Kernel::new(&setup, Estimator::Ring).expect("valid kernel");
            assert!(kernel.lanes && matches!(kernel.strategy, Strategy::Ring(_)), "{name}");
            compare_kernels(name, &kernel);
        }
        // The lobe connection (45°/15° and out of plane): HG and a table,
        // chains of 4 and 16, drawn at every event, reused for 3 events and
        // for the whole path; a thick slab whose walk reflects at the
        // bottom (the MIS history restarts there).
        let lobe_cases = [
            ("lobe, HG, m 4", Phase::henyey_greenstein(0.9).expect("valid g"), 15.0, 180.0, 4, 1, 6e-3),
            ("lobe, table, m 16, reuse 3", table_phase(), 15.0, 180.0, 16, 3, 6e-3),
            (
                "lobe, HG, m 16, one chain a path",
                Phase::henyey_greenstein(0.8).expect("valid g"),
                40.0,
                100.0,
                16,
                usize::MAX,
                6e-3,
            ),
            ("lobe, table, m 2, reflecting bottom", table_phase(), 15.0, 180.0, 2, 2, 3.5e-3),
        ];
        for (name, phase, theta_o, phi_o, m, reuse, d) in lobe_cases {
            let setup = Setup::new(
                Slab::new(d, Medium::new(1.2e4, 10.0, phase, 1.5).expect("valid medium")).expect("valid slab"),
                Beam::gaussian(200e-6).expect("valid beam"),
                Sensor::new(63, 0.1e-3).expect("valid sensor"),
                Directions::from_degrees(45.0, 0.0, theta_o, phi_o).expect("valid directions"),
            );
            let mut kernel = Kernel::new(&setup, Estimator::Lobe { vertices: m }).expect("valid kernel");
            kernel.strategy = Strategy::Lobe { vertices: m, reuse };
            assert!(kernel.lanes, "{name}");
            compare_kernels(name, &kernel);
        }
        // The lobe connection through a rough top (thick): per-lane ω₂₁ and
        // C from each path's sampled exit, lost exits; an analytic
        // distribution at large α (many lost and grazing exits) and a
        // measured normal set, HG and a table.
        let rough_lobe_cases = [
            (
                "rough lobe, TR 0.8, HG, m 4",
                Microsurface::Analytic(Distribution::TrowbridgeReitz { alpha: 0.8 }),
                hg(0.9),
                4,
            ),
            (
                "rough lobe, measured, table, m 16",
                Microsurface::Measured(std::sync::Arc::new(
                    crate::microfacet::MeasuredNormals::new(&measured, None).expect("valid normals"),
                )),
                table_phase(),
                16,
            ),
        ];
        for (name, surface, phase, m) in rough_lobe_cases {
            let setup = Setup::new(
                Slab::new(6e-3, Medium::new(1.2e4, 10.0, phase, 1.5).expect("valid medium"))
                    .expect("valid slab")
                    .with_top(Interface::new(surface).expect("valid α")),
                Beam::gaussian(200e-6).expect("valid beam"),
                Sensor::new(63, 0.1e-3).expect("valid sensor"),
                Directions::from_degrees(45.0, 0.0, 15.0, 180.0).expect("valid directions"),
            );
            let kernel = Kernel::new(&setup, Estimator::Lobe { vertices: m }).expect("valid kernel");
            assert!(
                kernel.lanes && kernel.rough && kernel.strategy.estimator() == Estimator::Lobe { vertices: m },
                "{name}"
            );
            compare_kernels(name, &kernel);
        }
    }

    /// A forward-peaked tabulated phase function.
    #[cfg(target_arch = "x86_64")]
    fn table_phase() -> Phase {
        Phase::Tabulated(
            crate::phase::PhaseTable::from_theta_samples(
                &(0..400).map(|k| (-(k as f64) / 40.0).exp() + 0.05).collect::<Vec<_>>(),
            )
            .expect("valid table"),
        )
    }

    /// Asserts that the lane and scalar kernels trace the same paths.
    #[cfg(target_arch = "x86_64")]
    fn compare_kernels(name: &str, kernel: &Kernel) {
        {
            let paths = 3001; // not a multiple of four: lanes retire at the end
            let scalar = kernel.batch_scalar(9, 100, paths, Vec::new());
            // SAFETY: `kernel.lanes` is set, so the CPU has AVX2 and FMA.
            assert!(kernel.lanes);
            let lanes = unsafe { kernel.batch_lanes(9, 100, paths, Vec::new()) };
            assert_eq!(lanes.events, scalar.events, "{name}: events");
            let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-9 * scale;
            assert!(scalar.path_sum > 0.0, "{name}: empty slice");
            assert!(
                close(lanes.path_sum, scalar.path_sum, scalar.path_sum),
                "{name}: {} vs {}",
                lanes.path_sum,
                scalar.path_sum
            );
            assert!(close(lanes.path_sq, scalar.path_sq, scalar.path_sq), "{name}: squares");
            assert!(
                close(lanes.reflected, scalar.reflected, paths as f64),
                "{name}: {} vs {}",
                lanes.reflected,
                scalar.reflected
            );
            assert!(close(lanes.transmitted, scalar.transmitted, paths as f64), "{name}: transmitted");
            let peak = scalar.image.iter().fold(0.0f64, |m, v| m.max(*v));
            for (k, (a, b)) in lanes.image.iter().zip(&scalar.image).enumerate() {
                assert!(close(*a, *b, peak), "{name}: pixel {k}: {a} vs {b}");
            }
        }
    }

    /// χ² p-value of `observed` counts against `expected` (the shared
    /// harness: bins expecting fewer than 5 pooled).
    fn chi2_p(observed: &[f64], expected: &[f64]) -> f64 {
        lucent_testkit::chi2::goodness_of_fit(observed, expected).p_value
    }

    /// The ring's azimuth sampler draws ψ with the density it reports (χ²
    /// over 64 bins, for photons along, across and against the ring).
    #[test]
    fn ring_azimuth_sampler_matches_its_density() {
        let ring = Ring::new(&Phase::henyey_greenstein(0.95).expect("valid g"), 0.9, 1.0, (1.0, 0.0));
        let n = 200_000;
        for c_s in [0.9, 0.3, -0.7] {
            let mut rng = Rng::new(5, (c_s * 100.0) as u64);
            let bins = 64;
            let mut observed = vec![0.0; bins];
            for _ in 0..n {
                let (psi, density) = ring.sample_psi(c_s, rng.next_f64());
                assert!((density - ring.density_at(c_s, psi)).abs() <= 1e-12 * density, "c_s {c_s}: ψ {psi}");
                observed[((psi / PI * bins as f64) as usize).min(bins - 1)] += 1.0;
            }
            // Expected: ∫ density over each bin (midpoint rule on 32 points).
            let expected: Vec<f64> = (0..bins)
                .map(|b| {
                    let w = PI / bins as f64;
                    (0..32).map(|k| ring.density_at(c_s, (b as f64 + (k as f64 + 0.5) / 32.0) * w)).sum::<f64>() * w
                        / 32.0
                        * n as f64
                })
                .collect();
            let p = chi2_p(&observed, &expected);
            assert!(p > 1e-3, "c_s {c_s}: χ² p = {p}");
        }
    }

    /// The Fresnel choice at a boundary reflects with probability F: χ²
    /// (one degree of freedom) at five angles, inside the medium (n = 1.5,
    /// so the last two angles are beyond the critical angle and always
    /// reflect).
    #[test]
    fn fresnel_choice_reflects_with_probability_f() {
        let setup = Setup::new(
            Slab::new(1e-3, Medium::new(1000.0, 0.0, Phase::henyey_greenstein(0.0).expect("g = 0"), 1.5).expect("ok"))
                .expect("valid slab"),
            Beam::gaussian(100e-6).expect("valid beam"),
            Sensor::new(8, 1e-4).expect("valid sensor"),
            Directions::from_degrees(0.0, 0.0, 0.0, 0.0).expect("valid directions"),
        );
        let kernel = Kernel::new(&setup, Estimator::Connection).expect("valid kernel");
        let n = 100_000;
        for (k, theta_deg) in [0.0f64, 20.0, 40.0, 45.0, 70.0].into_iter().enumerate() {
            let (st, ct) = theta_deg.to_radians().sin_cos();
            let f = crate::fresnel::reflectance(ct, 1.0 / 1.5);
            let mut rng = Rng::new(17, k as u64);
            let mut reflected = 0.0;
            for _ in 0..n {
                let (mut p, mut dir) = ([0.0, 0.0, -0.5e-3], [st, 0.0, ct]);
                let mut w = 1.0;
                if let Crossing::Reflected = kernel.cross(&mut p, &mut dir, &mut w, 0.5e-3, &mut rng) {
                    assert!(dir[2] < 0.0 && p[2] == 0.0);
                    reflected += 1.0;
                }
            }
            if f >= 1.0 {
                assert_eq!(reflected, n as f64, "θ {theta_deg}°: total internal reflection");
                continue;
            }
            let p = chi2_p(&[reflected, n as f64 - reflected], &[f * n as f64, (1.0 - f) * n as f64]);
            assert!(p > 1e-3, "θ {theta_deg}°: reflected {reflected} of {n}, F = {f} (χ² p = {p})");
        }
    }
}
