//! The dielectric interface between two non-absorbing media — smooth, or
//! rough with an analytic or measured microsurface — as one BSDF with
//! sample, eval and pdf: the single-scattering microfacet model of Walter,
//! Marschner, Li & Torrance, "Microfacet models for refraction through rough
//! surfaces" (EGSR 2007), with reflection and transmission, unpolarised
//! Fresnel ([`crate::fresnel`]), separable Smith masking–shadowing
//! G = G1(ω_o, m) G1(ω_i, m) (Walter 2007 eq. 23) and importance sampling of
//! the microfacet normals ([`crate::microfacet`]). The slab simulator's top
//! ([`crate::slab::Slab::top`]) and the path tracer's object
//! ([`crate::tracer::Object::interface`]) are both an [`Interface`]; the next
//! boundary model is added here once.
//!
//! # Conventions
//!
//! * **Local shading frame**, macroscopic normal n = +z. All directions are
//!   unit [`DVec3`]s pointing *away* from the surface, as in pbrt-v4: `wo` is
//!   the direction the transported quantity leaves along (towards the camera
//!   for radiance), `wi` the other one.
//! * **Index:** `eta` = n_below / n_above, the index of the z < 0 side over the
//!   index of the z > 0 side (1.41 for air above a polymer, 1/1.41 for the
//!   polymer above air). Light may arrive from either side.
//! * **Units:** [`Interface::eval`] returns the BSDF f(ω_o, ω_i) in 1/sr
//!   *without* the cosine; [`Interface::pdf`] is a density in 1/sr over the
//!   solid angle of `wi`. Multiply `f` by |cos θ_i| = |wi.z| yourself.
//! * **Microfacet normals** m always face +z (m.z > 0); seen from below the
//!   surface shows its other side, −m.
//! * **Transport mode** ([`Transport`]): with radiance (camera paths) the
//!   transmitted BSDF carries the factor (n_o/n_i)² of radiance compression
//!   (Walter 2007 eq. 21; Veach 1997 §5.2); with importance (light paths, the
//!   slab simulator's photons) it does not, and f_importance(ω_o, ω_i) =
//!   f_radiance(ω_i, ω_o). Both satisfy the generalised reciprocity
//!   f_rad(ω_o, ω_i)/n_o² = f_rad(ω_i, ω_o)/n_i².
//!
//! # Model
//!
//! Half-vectors m_r = ±(ω_i + ω_o)/‖·‖ and m_t = ±(n_i ω_i + n_o ω_o)/‖·‖,
//! turned to face +z; F = unpolarised Fresnel reflectance at m.
//!
//! * f_r = F G D / (4 |cos θ_i| |cos θ_o|)
//! * f_t = |ω_i·m| |ω_o·m| (1 − F) G D / (|cos θ_i| |cos θ_o| (ω_i·m + ω_o·m / η′)²),
//!   divided by η′² in radiance mode, η′ = n_i / n_o.
//!
//! Pairs with a back-facing microfacet (sign(ω·m) ≠ sign(ω·n) for either
//! direction) have f = 0.
//!
//! # Sampling
//!
//! A microfacet normal is drawn by [`Microsurface::sample_normal_weighted`]
//! (visible normals for the analytic distributions, D(m)(m·n) for a measured
//! set). With [`Lobe::Fresnel`] reflection is chosen with probability
//! F(ω_o·m), refraction otherwise; the pdf of ω_i is then
//! D_ω(m) F / (4 |ω_o·m|) for reflection and
//! D_ω(m) (1 − F) |ω_i·m| / (ω_i·m + ω_o·m/η′)² for transmission (Walter 2007
//! eqs. 14, 17), D_ω the density the normal was drawn with. The sample's
//! weight f |cos θ_i| / pdf is then the normal's factor times G1(ω_i, m), no
//! density evaluated. [`Lobe::Reflect`] and [`Lobe::Transmit`] take one lobe
//! and put F or 1 − F into the weight. A sample whose direction ends on the
//! wrong side of the macro-surface is rejected (`None`): that is the energy
//! single scattering loses, and [`Interface::pdf`] integrates to the
//! probability of success.
//!
//! # Energy and validation
//!
//! Single scattering conserves energy only approximately. Measured
//! directional albedos (R + T, importance transport): within 1 % of one for
//! Beckmann α ≤ 0.2 and GGX α ≤ 0.1 from the rarer side up to 60°, and from
//! the denser side below the critical angle for Beckmann α ≤ 0.2 and GGX
//! α ≤ 0.05. GGX's long tail loses more: 0.959 at α = 0.2 from the denser
//! side at normal incidence, 0.973 from air at 60°; 0.60 at α = 0.7, 80°.
//! Mitsuba 3's `roughdielectric` gives the same albedos, and the same BSDF
//! values and pdfs to 7e-4 (its single precision), see
//! `tools/reference/microfacet_mitsuba.py` and `render/tests/microfacet.rs`.
//!
//! # Smooth interface and delta lobes
//!
//! [`Interface::Smooth`] (built by [`Interface::new`] for α <
//! [`crate::microfacet::SMOOTH_ALPHA`] = 10⁻⁴, including α = 0), and any
//! interface with η = 1, is a pair of Dirac deltas: mirror reflection with
//! weight F, Snell refraction with weight 1 − F. Then [`Interface::eval`] and
//! [`Interface::pdf`] return 0 (a delta has no density and can never be hit
//! by a direction chosen elsewhere), [`Interface::is_delta`] is true, and
//! [`Interface::sample`] returns the specular direction, chosen with
//! probability F (reflection) and 1 − F (refraction), with `weight` = 1 for
//! reflection and 1 (importance) or (n_o/n_i)² (radiance) for refraction.
//! Callers must not combine a delta sample by MIS with a light sample. Above
//! the threshold the rough formulas stay finite (no NaN) down to α = 10⁻⁴;
//! measured plaques have α ≈ 0.004–0.009.
//!
//! ```
//! use glam::DVec3;
//! use lucent_render::interface::{Interface, Lobe, Transport};
//! use lucent_render::microfacet::{Distribution, Microsurface};
//! let top = Interface::new(Microsurface::Analytic(Distribution::TrowbridgeReitz { alpha: 0.1 })).unwrap();
//! let wo = DVec3::new(0.0, 0.0, 1.0);
//! // At normal incidence the mirror direction is m = n: f = F G D / 4 with
//! // F = 0.04, D(n) = 1/(π α²), G = 1.
//! let f = top.eval(wo, wo, 1.5, Transport::Radiance);
//! assert!((f - 0.04 / (std::f64::consts::PI * 0.01) / 4.0).abs() < 1e-12);
//! let s = top.sample(wo, 1.5, Lobe::Fresnel, [0.5, 0.3, 0.7], Transport::Radiance).unwrap();
//! let pdf = top.pdf(wo, s.wi, 1.5);
//! let expected = top.eval(wo, s.wi, 1.5, Transport::Radiance) * s.wi.z.abs() / pdf;
//! assert!((s.weight - expected).abs() <= 1e-12 * expected);
//! ```

use crate::fresnel;
use crate::microfacet::{MicrofacetError, Microsurface};
use crate::rng::Rng;
use glam::DVec3;

/// Which quantity a path carries (pbrt-v4's TransportMode).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// Camera paths: transmitted radiance is scaled by (n_o/n_i)².
    Radiance,
    /// Light paths (importance / photon power): no η² factor.
    Importance,
}

/// The lobe a sample takes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Lobe {
    /// Reflection with probability F, else transmission (weight without F).
    Fresnel,
    /// Reflection only, weight times F.
    Reflect,
    /// Transmission only, weight times 1 − F.
    Transmit,
}

/// A direction drawn by [`Interface::sample`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sample {
    /// Unit direction away from the surface (see the module docs).
    pub wi: DVec3,
    /// f |cos θ_i| / pdf: the factor of the path's weight.
    pub weight: f64,
    /// `wi` is on the other side of the surface from `wo`.
    pub transmitted: bool,
}

/// A crossing of the interface drawn by [`Interface::cross`], in the
/// caller's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Crossing {
    /// The new unit direction of travel.
    pub dir: DVec3,
    /// `dir` leads through to the other side.
    pub transmitted: bool,
    /// The factor of the path's weight: f |cos θ_i| / pdf of a microfacet
    /// sample (radiance transport); 1 at a smooth interface, whose choice
    /// with the caller's probability cancels the Fresnel factor.
    pub weight: f64,
    /// `weight` is a sampled factor (every crossing of a rough interface),
    /// so the caller's Russian roulette applies after it; a smooth
    /// interface's crossing leaves the path's estimate as it was.
    pub weighted: bool,
}

/// A dielectric interface (closed set): the index ratio is given per call,
/// so one interface serves every wavelength band.
#[derive(Debug, Clone)]
pub enum Interface {
    /// Smooth: mirror reflection and Snell refraction with unpolarised
    /// Fresnel ([`crate::fresnel`]).
    Smooth,
    /// Rough (Walter et al. 2007): each crossing draws a microfacet normal
    /// and reflects or refracts about it. Build it with [`Interface::new`].
    Rough(Microsurface),
}

impl Interface {
    /// The interface of a microsurface: [`Interface::Smooth`] when it is
    /// smooth (analytic α < [`crate::microfacet::SMOOTH_ALPHA`] = 10⁻⁴), else
    /// [`Interface::Rough`]. α is checked.
    pub fn new(surface: Microsurface) -> Result<Self, MicrofacetError> {
        if let Microsurface::Analytic(d) = &surface {
            d.validate()?;
        }
        Ok(if surface.is_smooth() { Interface::Smooth } else { Interface::Rough(surface) })
    }

    /// Whether the interface is rough (sampled microfacets).
    pub fn is_rough(&self) -> bool {
        matches!(self, Interface::Rough(_))
    }

    /// Whether every crossing is a mirror reflection or a Snell refraction,
    /// whatever the index (smooth): a direction on one side then fixes the
    /// one on the other, so a path tracer can connect through the
    /// interface backwards, share one refraction direction between bands
    /// and split a crossing into its two lobes.
    pub fn is_specular(&self) -> bool {
        matches!(self, Interface::Smooth)
    }

    /// True when the BSDF at index ratio `eta` consists of delta lobes only
    /// (smooth, or η = 1): [`eval`](Self::eval) and [`pdf`](Self::pdf) are 0.
    pub fn is_delta(&self, eta: f64) -> bool {
        !self.is_rough() || eta == 1.0
    }

    /// Whether the interface is symmetric about the xz-plane: smooth, an
    /// (isotropic) analytic distribution, or a measured normal set equal to
    /// its mirror image ([`crate::microfacet::MeasuredNormals::mirror_symmetric`]).
    pub fn mirror_symmetric(&self) -> bool {
        match self {
            Interface::Smooth | Interface::Rough(Microsurface::Analytic(_)) => true,
            Interface::Rough(Microsurface::Measured(m)) => m.mirror_symmetric(),
        }
    }

    /// A short description for summaries.
    pub fn describe(&self) -> String {
        use crate::microfacet::Distribution;
        match self {
            Interface::Smooth => "smooth".into(),
            Interface::Rough(Microsurface::Analytic(Distribution::TrowbridgeReitz { alpha })) => {
                format!("rough, Trowbridge–Reitz α = {alpha}")
            }
            Interface::Rough(Microsurface::Analytic(Distribution::Beckmann { alpha })) => {
                format!("rough, Beckmann α = {alpha}")
            }
            Interface::Rough(Microsurface::Measured(m)) => {
                format!("rough, {} measured normals (kernel radius {:.3e} in slope)", m.len(), m.bandwidth())
            }
        }
    }

    /// How many uniform numbers [`sample`](Self::sample) uses with
    /// [`Lobe::Fresnel`]: 1 for the smooth interface, 3 for a rough one.
    pub fn numbers(&self) -> usize {
        match self {
            Interface::Smooth => 1,
            Interface::Rough(_) => 3,
        }
    }

    /// Samples the interface for `wo` at index ratio `eta` = n_below/n_above:
    /// `u[0]` chooses the lobe ([`Lobe::Fresnel`]), `u[1]`, `u[2]` the
    /// microfacet (rough only). Transmitted radiance ([`Transport::Radiance`])
    /// carries (n_wo/n_wi)², importance does not. `None` when the light is
    /// lost: total internal reflection with [`Lobe::Transmit`], F = 0 with
    /// [`Lobe::Reflect`] through a rough surface, a rough sample sent to the
    /// wrong side, a grazing or non-finite `wo`.
    #[inline]
    pub fn sample(&self, wo: DVec3, eta: f64, lobe: Lobe, u: [f64; 3], mode: Transport) -> Option<Sample> {
        if wo.z == 0.0 || !wo.is_finite() {
            return None;
        }
        let eta_o = eta_from(wo, eta);
        let radiance = |t: f64| if mode == Transport::Radiance { t / (eta_o * eta_o) } else { t };
        let choose = |f: f64| match lobe {
            Lobe::Fresnel => u[0] < f,
            Lobe::Reflect => true,
            Lobe::Transmit => false,
        };
        let surface = match self {
            Interface::Rough(surface) if eta != 1.0 => surface,
            _ => {
                let f = fresnel::reflectance(wo.z.abs(), eta_o);
                if choose(f) {
                    let weight = if lobe == Lobe::Reflect { f } else { 1.0 };
                    return Some(Sample { wi: DVec3::new(-wo.x, -wo.y, wo.z), weight, transmitted: false });
                }
                let wi = fresnel::refract(-wo, DVec3::Z, eta_o)?;
                let weight = if lobe == Lobe::Transmit { 1.0 - f } else { 1.0 };
                return Some(Sample { wi, weight: radiance(weight), transmitted: true });
            }
        };
        let (m, factor) = surface.sample_normal_weighted(wo, [u[1], u[2]])?;
        let om = wo.dot(m);
        if om * wo.z <= 0.0 {
            return None;
        }
        let f = fresnel::reflectance(om.abs(), eta_o);
        let reflect = choose(f);
        let (wi, lobe_factor) = if reflect {
            (2.0 * om * m - wo, if lobe == Lobe::Reflect { f } else { 1.0 })
        } else {
            (fresnel::refract(-wo, m, eta_o)?, if lobe == Lobe::Transmit { 1.0 - f } else { 1.0 })
        };
        // The new direction must be on the side the lobe sends it to.
        if wi.z == 0.0 || (wi.z * wo.z > 0.0) != reflect {
            return None;
        }
        let weight = factor * surface.g1(wi, m) * lobe_factor;
        if !(weight > 0.0 && weight.is_finite()) {
            return None;
        }
        let weight = if reflect { weight } else { radiance(weight) };
        Some(Sample { wi, weight, transmitted: !reflect })
    }

    /// Crosses the interface in the caller's frame, for smooth and rough
    /// alike: a ray travelling along the unit direction `d` meets it where
    /// its unit outward normal is `outward` (the local +z: outside above,
    /// the medium of index ratio `eta` = n_inside/n_outside below), coming
    /// from the inside (`from_inside`) or from outside. Smooth: the mirror
    /// direction d − 2(d·n)n with probability `reflect` (one number from
    /// `rng`; the caller's Fresnel reflectance, which may be one band's while
    /// `eta` is the bands' mean), else Snell's refraction
    /// ([`fresnel::refract`], relative index 1/η from inside, η from
    /// outside; the mirror direction should it find total internal
    /// reflection); `reflect` = `None` takes the refraction (no number
    /// drawn; its factor 1 − F is the caller's). Rough: [`Interface::sample`]
    /// with [`Lobe::Fresnel`] and radiance transport in the frame of
    /// `outward` (three numbers; `reflect` is not used). `None` when a rough
    /// sample is lost.
    pub fn cross(
        &self,
        d: DVec3,
        outward: DVec3,
        eta: f64,
        from_inside: bool,
        reflect: Option<f64>,
        rng: &mut Rng,
    ) -> Option<Crossing> {
        match self {
            Interface::Smooth => {
                let reflects = reflect.is_some_and(|f| rng.next_f64() < f);
                let dir = if reflects {
                    d - 2.0 * d.dot(outward) * outward
                } else {
                    let (n, eta) = if from_inside { (outward, 1.0 / eta) } else { (-outward, eta) };
                    fresnel::refract(d, n, eta).unwrap_or_else(|| d - 2.0 * d.dot(n) * n)
                };
                Some(Crossing { dir, transmitted: !reflects, weight: 1.0, weighted: false })
            }
            Interface::Rough(_) => {
                let (t, b) = crate::phase::orthonormal_basis(outward.to_array());
                let (t, b) = (DVec3::from_array(t), DVec3::from_array(b));
                let wo = DVec3::new(-d.dot(t), -d.dot(b), -d.dot(outward));
                let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
                let s = self.sample(wo, eta, Lobe::Fresnel, u, Transport::Radiance)?;
                let dir = (s.wi.x * t + s.wi.y * b + s.wi.z * outward).normalize();
                Some(Crossing { dir, transmitted: s.transmitted, weight: s.weight, weighted: true })
            }
        }
    }

    /// The BSDF f(ω_o, ω_i) in 1/sr without the cosine at index ratio `eta`
    /// = n_below/n_above; 0 for a delta BSDF ([`is_delta`](Self::is_delta)).
    pub fn eval(&self, wo: DVec3, wi: DVec3, eta: f64, mode: Transport) -> f64 {
        let Interface::Rough(surface) = self else { return 0.0 };
        if eta == 1.0 {
            return 0.0;
        }
        let Some((wm, etap, reflect)) = half_vector(wo, wi, eta) else {
            return 0.0;
        };
        let (co, ci) = (wo.z.abs(), wi.z.abs());
        let f = fresnel::reflectance(wo.dot(wm).abs(), eta_from(wo, eta));
        let g = surface.g1(wo, wm) * surface.g1(wi, wm);
        let d = surface.d(wm);
        if reflect {
            d * g * f / (4.0 * ci * co)
        } else {
            let (im, om) = (wi.dot(wm), wo.dot(wm));
            let denom = im + om / etap;
            let ft = d * g * (1.0 - f) * (im * om).abs() / (ci * co * denom * denom);
            match mode {
                Transport::Radiance => ft / (etap * etap),
                Transport::Importance => ft,
            }
        }
    }

    /// Solid-angle density (1/sr) with which [`sample`](Self::sample) with
    /// [`Lobe::Fresnel`] returns `wi` (0 for a delta BSDF).
    pub fn pdf(&self, wo: DVec3, wi: DVec3, eta: f64) -> f64 {
        let Interface::Rough(surface) = self else { return 0.0 };
        if eta == 1.0 {
            return 0.0;
        }
        let Some((wm, etap, reflect)) = half_vector(wo, wi, eta) else {
            return 0.0;
        };
        let om = wo.dot(wm);
        let f = fresnel::reflectance(om.abs(), eta_from(wo, eta));
        let pm = surface.pdf_normal(wo, wm);
        if reflect {
            pm * f / (4.0 * om.abs())
        } else {
            let im = wi.dot(wm);
            let denom = im + om / etap;
            pm * (1.0 - f) * im.abs() / (denom * denom)
        }
    }
}

/// n_other / n_wo: the relative index for light crossing from the side of
/// `wo`, `eta` = n_below/n_above.
#[inline]
fn eta_from(wo: DVec3, eta: f64) -> f64 {
    if wo.z > 0.0 {
        eta
    } else {
        1.0 / eta
    }
}

/// The generalised half-vector (facing +z), η′ = n_wi/n_wo, and whether the
/// pair is a reflection; `None` if degenerate or back-facing.
fn half_vector(wo: DVec3, wi: DVec3, eta: f64) -> Option<(DVec3, f64, bool)> {
    let (co, ci) = (wo.z, wi.z);
    if co == 0.0 || ci == 0.0 {
        return None;
    }
    let reflect = co * ci > 0.0;
    let etap = if reflect { 1.0 } else { eta_from(wo, eta) };
    let wm = wi * etap + wo;
    let len2 = wm.length_squared();
    if len2 == 0.0 || !len2.is_finite() {
        return None;
    }
    let mut wm = wm / len2.sqrt();
    if wm.z < 0.0 {
        wm = -wm;
    }
    if wm.z == 0.0 || wm.dot(wi) * ci <= 0.0 || wm.dot(wo) * co <= 0.0 {
        return None;
    }
    Some((wm, etap, reflect))
}
