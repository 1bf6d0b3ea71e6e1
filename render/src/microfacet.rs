//! Microsurfaces of rough dielectric interfaces: the microfacet normal
//! distribution D(m) in 1/sr (analytic, or a kernel density estimate of
//! measured normals), Smith's masking G1 and the sampling of normals, as used
//! by the interface BSDF of Walter, Marschner, Li & Torrance (EGSR 2007) in
//! [`crate::interface`].
//!
//! # Distributions
//!
//! [`Distribution`], α the roughness:
//!
//! * Trowbridge–Reitz (GGX): D = α² / (π cos⁴θ_m (α² + tan²θ_m)²),
//!   Λ(ω) = (√(1 + α² tan²θ) − 1)/2.
//! * Beckmann: D = exp(−tan²θ_m/α²) / (π α² cos⁴θ_m),
//!   Λ(ω) = (e^{−a²}/(a√π) − erfc a)/2 with a = 1/(α tan θ) (Walter 2007 eq. 25, exact erfc).
//!
//! G1(ω, m) = χ⁺((ω·m)(ω·n)) / (1 + Λ(ω)). Both satisfy ∫ D(m)(m·n) dω_m = 1
//! and ∫ G1(ω, m) (ω·m)⁺ D(m) dω_m = cos θ (tested).
//!
//! # Sampling normals
//!
//! [`Microsurface::sample_normal`] draws a normal from the distribution of
//! *visible* normals D_ω(m) = G1(ω_o, m) |ω_o·m| D(m) / |cos θ_o| — Heitz,
//! "Sampling the GGX distribution of visible normals" (JCGT 2018) for GGX, and
//! Heitz & d'Eon, "Importance sampling microfacet-based BSDFs using the
//! distribution of visible normals" (EGSR 2014) with W. Jakob's inversion of
//! the Beckmann slope CDF (solved here to machine precision by safeguarded
//! Newton iteration) for Beckmann.
//!
//! # Measured normals
//!
//! [`MeasuredNormals`] takes the microfacet normals fitted from a height map.
//! One normal per pixel of equal projected area makes their slopes
//! s = −(m_x, m_y)/m_z samples of the slope density P22(s), and
//! D(m) = P22(s(m)) / cos⁴θ_m (Walter 2007 §5; Heitz 2014 eq. 6). P22 is a
//! kernel density estimate in the slope plane:
//! P22(s) = (1/N) Σ_k K(‖s − s_k‖), K(r) = 3/(π h²) (1 − r²/h²)² for r < h
//! (a biweight-type kernel with ∫ K d²s = 1 exactly), so ∫ D (m·n) dω = 1
//! exactly and D, like the analytic models, vanishes towards the horizon
//! (a kernel on the sphere would leave D ∝ 1/m_z there and make the Smith
//! projected area diverge). The support radius h (slope units) comes from the
//! data unless given: Silverman's rule h = √8 σ N^(−1/6), σ a robust per-axis
//! slope spread (1.4826 × median absolute deviation), since the kernel has
//! variance h²/8 per axis. The density sums the kernel over the neighbours a
//! `kiddo` k-d tree returns within h of s.
//!
//! Sampling picks a normal uniformly and draws a slope from its kernel
//! exactly, so the sampled m has the solid-angle density D(m)(m·n) =
//! P22/cos³θ_m — the classical sampling of Walter 2007, not visible normals —
//! and the BSDF pdf uses that density (back-facing draws are rejected). The
//! Smith term uses the projected area A(ω) = ∫ (ω·m)⁺ D(m) dω_m
//! = cos θ − sin θ E[min(s_φ, cot θ)], s_φ the slope along ω's azimuth; the
//! expectation over each kernel is evaluated in closed form (the kernel's
//! marginal along a line is ∝ (1 − t²)^{5/2}), summed over all normals (over
//! 16384 of them, evenly strided, for larger sets), tabulated on 65 θ × 64 φ
//! nodes (anisotropy kept) and interpolated bilinearly: G1 = |cos θ| / A.
//!
//! ```
//! use glam::DVec3;
//! use lucent_render::microfacet::Distribution;
//! // D(n) = 1/(π α²) for Trowbridge–Reitz at the macro-normal.
//! let d = Distribution::TrowbridgeReitz { alpha: 0.1 };
//! assert!((d.d(DVec3::Z) - 1.0 / (std::f64::consts::PI * 0.01)).abs() < 1e-9);
//! ```

use glam::DVec3;
use kiddo::immutable::float::kdtree::ImmutableKdTree;
use kiddo::SquaredEuclidean;
use std::f64::consts::{FRAC_2_SQRT_PI, PI};
use std::sync::Arc;

/// Roughness below which a boundary is treated as smooth (delta lobes).
pub const SMOOTH_ALPHA: f64 = 1e-4;

/// Largest roughness accepted (α = 2 already spreads normals to grazing).
pub const MAX_ALPHA: f64 = 4.0;

/// 1/√π.
const FRAC_1_SQRT_PI: f64 = 0.5 * FRAC_2_SQRT_PI;

/// Invalid BSDF parameters or measured normal sets.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
pub enum MicrofacetError {
    /// Roughness not finite, negative or above [`MAX_ALPHA`].
    #[error("microfacet roughness alpha = {0} is invalid (need a finite value in [0, {MAX_ALPHA}])")]
    Alpha(f64),
    /// An empty normal set.
    #[error("the measured normal set is empty")]
    NoNormals,
    /// Too many normals for the 32-bit k-d tree index.
    #[error("{0} measured normals are more than the k-d tree holds (2^32 - 1)")]
    TooManyNormals(usize),
    /// A normal that is not finite, not of unit length or not facing +z.
    #[error("measured normal #{index} = {normal:?} is invalid: {reason}")]
    Normal { index: usize, normal: [f64; 3], reason: &'static str },
    /// Kernel bandwidth not finite or outside (0, [`MAX_BANDWIDTH`]].
    #[error("kernel bandwidth h = {0} (slope units) is invalid (need 0 < h <= {MAX_BANDWIDTH})")]
    Bandwidth(f64),
}

/// Analytic isotropic microfacet normal distributions (closed set).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Distribution {
    /// Trowbridge–Reitz (1975) / GGX (Walter 2007 eq. 33), roughness α.
    TrowbridgeReitz { alpha: f64 },
    /// Beckmann–Spizzichino (Walter 2007 eq. 28), RMS slope α/√2 per axis.
    Beckmann { alpha: f64 },
}

impl Distribution {
    /// The roughness α.
    pub fn alpha(&self) -> f64 {
        match *self {
            Distribution::TrowbridgeReitz { alpha } | Distribution::Beckmann { alpha } => alpha,
        }
    }

    /// Checks α (finite, 0 ≤ α ≤ [`MAX_ALPHA`]).
    pub fn validate(&self) -> Result<(), MicrofacetError> {
        let a = self.alpha();
        if a.is_finite() && (0.0..=MAX_ALPHA).contains(&a) {
            Ok(())
        } else {
            Err(MicrofacetError::Alpha(a))
        }
    }

    /// True when α < [`SMOOTH_ALPHA`]: the surface is treated as smooth.
    pub fn is_smooth(&self) -> bool {
        self.alpha() < SMOOTH_ALPHA
    }

    /// D(m) in 1/sr for a unit normal m (0 for m.z ≤ 0 and for α = 0, whose
    /// distribution is a delta without density).
    pub fn d(&self, m: DVec3) -> f64 {
        let a = self.alpha();
        if m.z <= 0.0 || a <= 0.0 {
            return 0.0;
        }
        let cos2 = m.z * m.z;
        let tan2 = (m.x * m.x + m.y * m.y) / cos2;
        let a2 = a * a;
        match self {
            Distribution::TrowbridgeReitz { .. } => {
                let e = 1.0 + tan2 / a2;
                1.0 / (PI * a2 * cos2 * cos2 * e * e)
            }
            Distribution::Beckmann { .. } => (-tan2 / a2).exp() / (PI * a2 * cos2 * cos2),
        }
    }

    /// Smith's Λ(ω) (the same for ω and −ω); +∞ for grazing ω.
    pub fn lambda(&self, w: DVec3) -> f64 {
        if w.z == 0.0 {
            return f64::INFINITY;
        }
        let a = self.alpha();
        let tan2 = (w.x * w.x + w.y * w.y) / (w.z * w.z);
        if tan2 == 0.0 || a == 0.0 {
            return 0.0;
        }
        match self {
            Distribution::TrowbridgeReitz { .. } => 0.5 * ((1.0 + a * a * tan2).sqrt() - 1.0),
            Distribution::Beckmann { .. } => {
                let b = 1.0 / (a * tan2.sqrt());
                // (erf b − 1)/2 + e^{−b²}/(2 b √π), with erf − 1 = −erfc kept exact.
                0.5 * ((-b * b).exp() * FRAC_1_SQRT_PI / b - libm::erfc(b))
            }
        }
    }

    /// Smith G1(ω, m) (0 for a back-facing microfacet).
    pub fn g1(&self, w: DVec3, m: DVec3) -> f64 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        1.0 / (1.0 + self.lambda(w))
    }

    /// Draws a normal from the visible-normal distribution D_ω(m) of a
    /// direction `w` on either side (`u` uniform in [0, 1)²); m faces +z.
    /// `None` for grazing `w`, α = 0 or a degenerate draw.
    pub fn sample_visible(&self, w: DVec3, u: [f64; 2]) -> Option<DVec3> {
        let a = self.alpha();
        if w.z == 0.0 || a <= 0.0 {
            return None;
        }
        let w = if w.z < 0.0 { -w } else { w };
        let wh = DVec3::new(a * w.x, a * w.y, w.z).normalize();
        let m = match self {
            Distribution::TrowbridgeReitz { .. } => {
                // Heitz 2018, listing 1 (isotropic α).
                let lensq = wh.x * wh.x + wh.y * wh.y;
                let t1 = if lensq > 0.0 { DVec3::new(-wh.y, wh.x, 0.0) / lensq.sqrt() } else { DVec3::X };
                let t2 = wh.cross(t1);
                let r = u[0].sqrt();
                let phi = 2.0 * PI * u[1];
                let p1 = r * phi.cos();
                let s = 0.5 * (1.0 + wh.z);
                let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
                let nh = p1 * t1 + p2 * t2 + (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt() * wh;
                DVec3::new(a * nh.x, a * nh.y, nh.z.max(0.0))
            }
            Distribution::Beckmann { .. } => {
                // Heitz & d'Eon 2014: stretch, sample the α = 1 visible
                // slopes for (θ, φ = 0), rotate by φ, unstretch.
                let sin_t = (wh.x * wh.x + wh.y * wh.y).sqrt();
                let cos_t = wh.z;
                let (cos_p, sin_p) = if sin_t > 0.0 { (wh.x / sin_t, wh.y / sin_t) } else { (1.0, 0.0) };
                let (sx, sy) = beckmann_visible_slopes(cos_t, sin_t, u);
                let (rx, ry) = (cos_p * sx - sin_p * sy, sin_p * sx + cos_p * sy);
                DVec3::new(-a * rx, -a * ry, 1.0)
            }
        };
        let len = m.length();
        if m.z > 0.0 && len.is_finite() {
            Some(m / len)
        } else {
            None
        }
    }

    /// Density in 1/sr of [`Distribution::sample_visible`] at m:
    /// D_ω(m) = G1(ω, m) |ω·m| D(m) / |cos θ|.
    pub fn pdf_visible(&self, w: DVec3, m: DVec3) -> f64 {
        if w.z == 0.0 {
            return 0.0;
        }
        self.g1(w, m) * w.dot(m).abs() * self.d(m) / w.z.abs()
    }
}

/// Bound of the slope domain: e^{−9²} ≈ 7e-36, beyond double resolution of a CDF.
const SLOPE_BOUND: f64 = 9.0;

/// Visible slopes of the α = 1 Beckmann surface seen from θ (φ = 0), slopes
/// defined by m ∝ (−x, −y, 1). x has CDF ∝ cos θ erfc(−x) + sin θ e^{−x²}/√π
/// on (−∞, cot θ]; y is Gaussian with variance 1/2 (Heitz & d'Eon 2014 §4).
fn beckmann_visible_slopes(cos_t: f64, sin_t: f64, u: [f64; 2]) -> (f64, f64) {
    let hi = if sin_t > 0.0 { (cos_t / sin_t).min(SLOPE_BOUND) } else { SLOPE_BOUND };
    // Starting point: W. Jakob's fitted approximation of the inverse CDF in
    // b = erf(x) (Mitsuba, microfacet.h), then Newton to machine precision.
    let theta = sin_t.atan2(cos_t);
    let fit = 1.0 + theta * (-0.876 + theta * (0.4265 - 0.0594 * theta));
    let c = libm::erf(hi);
    let b0 = c - (1.0 + c) * (1.0 - u[0]).powf(fit);
    let x = solve_slope_cdf(cos_t, sin_t, u[0], hi, erfinv_approx(b0));
    let y = solve_slope_cdf(1.0, 0.0, u[1], SLOPE_BOUND, erfinv_approx(2.0 * u[1] - 1.0));
    (x, y)
}

/// The x in [−9, hi] with F(x) = u F(hi), F(x) = c erfc(−x) + s e^{−x²}/√π
/// (increasing for x ≤ c/s), by Newton steps from `x0` kept inside a
/// shrinking bracket (bisection when a step would leave it).
fn solve_slope_cdf(c: f64, s: f64, u: f64, hi: f64, x0: f64) -> f64 {
    let cdf = |x: f64| c * libm::erfc(-x) + s * (-x * x).exp() * FRAC_1_SQRT_PI;
    let target = u * cdf(hi);
    let (mut lo, mut hi) = (-SLOPE_BOUND, hi);
    let mut x = if x0.is_finite() { x0.clamp(lo, hi) } else { 0.0f64.clamp(lo, hi) };
    let (lo0, hi0) = (lo, hi);
    for _ in 0..200 {
        let fx = cdf(x) - target;
        if fx == 0.0 {
            return x;
        }
        if fx > 0.0 {
            hi = x;
        } else {
            lo = x;
        }
        let dfx = FRAC_2_SQRT_PI * (-x * x).exp() * (c - s * x);
        let newton = x - fx / dfx;
        if dfx > 0.0 && (newton - x).abs() <= 1e-14 * (1.0 + x.abs()) {
            // Converged; the last step brings x to rounding level.
            return newton.clamp(lo0, hi0);
        }
        let next = if dfx > 0.0 && newton > lo && newton < hi { newton } else { 0.5 * (lo + hi) };
        if hi - lo <= 1e-15 * (1.0 + x.abs()) {
            return next;
        }
        x = next;
    }
    x
}

/// erf⁻¹ to about 10⁻⁷ relative (M. Giles, "Approximating the erfinv
/// function", GPU Computing Gems 2011, single-precision branch); a starting
/// point only. ±∞ at ±1.
fn erfinv_approx(x: f64) -> f64 {
    let w = -((1.0 - x) * (1.0 + x)).ln();
    let p = if w < 5.0 {
        let w = w - 2.5;
        [
            3.43273939e-07,
            -3.5233877e-06,
            -4.39150654e-06,
            0.00021858087,
            -0.00125372503,
            -0.00417768164,
            0.246640727,
            1.50140941,
        ]
        .iter()
        .fold(2.81022636e-08, |p, &k| k + p * w)
    } else {
        let w = w.sqrt() - 3.0;
        [
            0.000100950558,
            0.00134934322,
            -0.00367342844,
            0.00573950773,
            -0.0076224613,
            0.00943887047,
            1.00167406,
            2.83297682,
        ]
        .iter()
        .fold(-0.000200214257, |p, &k| k + p * w)
    };
    p * x
}

/// Normals used (at most) to tabulate the projected area of a measured
/// surface.
const AREA_NORMALS: usize = 16384;
/// Table nodes in θ ∈ [0, π/2] (inclusive) and φ ∈ [0, 2π) (periodic).
const AREA_NTHETA: usize = 65;
const AREA_NPHI: usize = 64;
/// Largest kernel radius accepted, in slope units (tan 84°).
pub const MAX_BANDWIDTH: f64 = 10.0;

/// A microfacet normal distribution defined by a measured set of normals
/// (kernel density estimate of the slopes; see the module docs for the
/// definition, the sampling and the Smith term).
///
/// Cost: a density query sums the kernel over the neighbours within h,
/// about N^(2/3) of them with the default bandwidth (10⁴ for 10⁶ normals);
/// subsample large sets if the BSDF is evaluated per path vertex.
pub struct MeasuredNormals {
    /// Slopes s_k = −(m_x, m_y)/m_z.
    slopes: Vec<[f64; 2]>,
    tree: ImmutableKdTree<f64, u32, 2, 32>,
    h: f64,
    /// 3 / (π h² N).
    kernel_norm: f64,
    /// B(θ_j, φ_k) = −E[min(s_φ, cot θ_j)], A(ω) = cos θ + sin θ · B(θ, φ).
    area_b: Vec<f64>,
}

impl std::fmt::Debug for MeasuredNormals {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("MeasuredNormals").field("count", &self.slopes.len()).field("bandwidth", &self.h).finish()
    }
}

impl MeasuredNormals {
    /// Builds the estimate from unit normals facing +z (|‖m‖ − 1| ≤ 10⁻⁶,
    /// m.z > 0). `bandwidth` is the kernel's support radius h in slope units
    /// (0 < h ≤ [`MAX_BANDWIDTH`]); `None` chooses it from the data
    /// (module docs), clamped to [10⁻⁶, 1].
    pub fn new(normals: &[[f64; 3]], bandwidth: Option<f64>) -> Result<Self, MicrofacetError> {
        if normals.is_empty() {
            return Err(MicrofacetError::NoNormals);
        }
        if normals.len() >= u32::MAX as usize {
            return Err(MicrofacetError::TooManyNormals(normals.len()));
        }
        let mut slopes = Vec::with_capacity(normals.len());
        for (index, n) in normals.iter().enumerate() {
            let v = DVec3::from_array(*n);
            let bad = |reason| MicrofacetError::Normal { index, normal: *n, reason };
            if !v.is_finite() {
                return Err(bad("not finite"));
            }
            if (v.length() - 1.0).abs() > 1e-6 {
                return Err(bad("not of unit length"));
            }
            if v.z <= 0.0 {
                return Err(bad("does not face +z"));
            }
            slopes.push([-v.x / v.z, -v.y / v.z]);
        }
        let h = match bandwidth {
            Some(h) if h.is_finite() && h > 0.0 && h <= MAX_BANDWIDTH => h,
            Some(h) => return Err(MicrofacetError::Bandwidth(h)),
            None => silverman_bandwidth(&slopes),
        };
        let tree = ImmutableKdTree::new_from_slice(&slopes);
        let kernel_norm = 3.0 / (PI * h * h * slopes.len() as f64);
        let mut out = MeasuredNormals { kernel_norm, slopes, tree, h, area_b: Vec::new() };
        out.tabulate_projected_area();
        Ok(out)
    }

    /// Number of normals.
    pub fn len(&self) -> usize {
        self.slopes.len()
    }

    /// Whether the set equals its mirror image about the xz-plane (every
    /// slope (s_x, s_y) has its partner (s_x, −s_y), counted as often):
    /// only then is D(m) symmetric about a plane of incidence at φ = 0°/180°.
    pub fn mirror_symmetric(&self) -> bool {
        let key = |s: &[f64; 2]| (s[0].to_bits(), s[1].to_bits());
        let mut a: Vec<_> = self.slopes.iter().map(key).collect();
        let mut b: Vec<_> = self.slopes.iter().map(|s| key(&[s[0], -s[1]])).collect();
        a.sort_unstable();
        b.sort_unstable();
        a == b
    }

    /// Always false (an empty set is rejected by [`MeasuredNormals::new`]).
    pub fn is_empty(&self) -> bool {
        self.slopes.is_empty()
    }

    /// The kernel's support radius h (slope units).
    pub fn bandwidth(&self) -> f64 {
        self.h
    }

    /// The estimated slope density P22(s) (per unit slope area).
    pub fn slope_density(&self, s: [f64; 2]) -> f64 {
        if !(s[0].is_finite() && s[1].is_finite()) {
            return 0.0;
        }
        let h2 = self.h * self.h;
        let near = self.tree.within_unsorted::<SquaredEuclidean>(&s, h2);
        let sum: f64 = near
            .iter()
            .map(|nb| {
                let t = 1.0 - nb.distance / h2;
                if t > 0.0 {
                    t * t
                } else {
                    0.0
                }
            })
            .sum();
        self.kernel_norm * sum
    }

    /// D(m) = P22(s(m)) / cos⁴θ_m in 1/sr (0 for m.z ≤ 0).
    pub fn d(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        let c2 = m.z * m.z;
        self.slope_density([-m.x / m.z, -m.y / m.z]) / (c2 * c2)
    }

    /// Solid-angle density of [`MeasuredNormals::sample_projected`]:
    /// D(m)(m·n) = P22 / cos³θ_m.
    pub fn pdf_projected(&self, m: DVec3) -> f64 {
        if m.z <= 0.0 {
            return 0.0;
        }
        self.slope_density([-m.x / m.z, -m.y / m.z]) / (m.z * m.z * m.z)
    }

    /// Draws m (m.z > 0) with density D(m)(m·n). `u[0]` picks the normal, its
    /// fractional remainder and `u[1]` place the slope in the kernel.
    pub fn sample_projected(&self, u: [f64; 2]) -> DVec3 {
        let n = self.slopes.len();
        let scaled = u[0] * n as f64;
        let k = (scaled as usize).min(n - 1);
        let v = (scaled - k as f64).clamp(0.0, 1.0);
        // Radius² = h²(1 − (1 − v)^{1/3}) inverts the kernel's radial CDF.
        let r = self.h * (1.0 - (1.0 - v).cbrt()).max(0.0).sqrt();
        let (sp, cp) = (2.0 * PI * u[1]).sin_cos();
        let s = [self.slopes[k][0] + r * cp, self.slopes[k][1] + r * sp];
        DVec3::new(-s[0], -s[1], 1.0).normalize()
    }

    /// Projected area of the microsurface seen from ω (either side):
    /// A(ω) = ∫ (ω′·m)⁺ D(m) dω_m with ω′ = ω turned to +z.
    pub fn projected_area(&self, w: DVec3) -> f64 {
        let w = if w.z < 0.0 { -w } else { w };
        let cos_t = w.z.clamp(0.0, 1.0);
        let sin_t = (w.x * w.x + w.y * w.y).sqrt();
        let theta = sin_t.atan2(cos_t);
        let phi = w.y.atan2(w.x).rem_euclid(2.0 * PI);
        let ft = (theta / (0.5 * PI) * (AREA_NTHETA - 1) as f64).clamp(0.0, (AREA_NTHETA - 1) as f64);
        let j0 = (ft as usize).min(AREA_NTHETA - 2);
        let tj = ft - j0 as f64;
        let fp = phi / (2.0 * PI) * AREA_NPHI as f64;
        let k0 = (fp as usize) % AREA_NPHI;
        let tk = fp - fp.floor();
        let k1 = (k0 + 1) % AREA_NPHI;
        let b = |j: usize, k: usize| self.area_b[j * AREA_NPHI + k];
        let bj0 = b(j0, k0) * (1.0 - tk) + b(j0, k1) * tk;
        let bj1 = b(j0 + 1, k0) * (1.0 - tk) + b(j0 + 1, k1) * tk;
        cos_t + sin_t * (bj0 * (1.0 - tj) + bj1 * tj)
    }

    /// Smith G1(ω, m) = |cos θ| / A(ω) (0 for a back-facing microfacet).
    pub fn g1(&self, w: DVec3, m: DVec3) -> f64 {
        if w.dot(m) * w.z <= 0.0 {
            return 0.0;
        }
        let a = self.projected_area(w);
        if a > 0.0 {
            (w.z.abs() / a).min(1.0)
        } else {
            0.0
        }
    }

    /// Tabulates B(θ, φ) = −E[min(s_φ, cot θ)] over P22, each kernel's
    /// expectation in closed form ([`kernel_min_mean`]).
    fn tabulate_projected_area(&mut self) {
        let n = self.slopes.len();
        let stride = n.div_ceil(AREA_NORMALS).max(1);
        let used: Vec<[f64; 2]> = self.slopes.iter().step_by(stride).copied().collect();
        let inv = 1.0 / used.len() as f64;
        self.area_b = vec![0.0; AREA_NTHETA * AREA_NPHI];
        for k in 0..AREA_NPHI {
            let phi = 2.0 * PI * k as f64 / AREA_NPHI as f64;
            let (sp, cp) = phi.sin_cos();
            let proj: Vec<f64> = used.iter().map(|s| cp * s[0] + sp * s[1]).collect();
            for j in 0..AREA_NTHETA {
                let b = if j == 0 {
                    // cot θ = ∞: min(s_φ, ∞) = s_φ, and each kernel's mean is its centre.
                    -proj.iter().sum::<f64>() * inv
                } else {
                    let theta = 0.5 * PI * j as f64 / (AREA_NTHETA - 1) as f64;
                    let cot = if j == AREA_NTHETA - 1 { 0.0 } else { 1.0 / theta.tan() };
                    -proj.iter().map(|&mu| kernel_min_mean(mu, self.h, cot)).sum::<f64>() * inv
                };
                self.area_b[j * AREA_NPHI + k] = b;
            }
        }
    }
}

/// E[min(x, c)] for x = μ + h t, t distributed as the one-axis marginal of
/// the kernel, q(t) = 16/(5π) (1 − t²)^{5/2} on [−1, 1]:
/// μ + h (∫_{−1}^{τ} t q dt + τ (1 − Q(τ))), τ = (c − μ)/h, with
/// ∫_{−1}^{τ} t q dt = −16/(35π) (1 − τ²)^{7/2} and
/// Q(τ) = 16/(5π) (F(asin τ) + 5π/32), F(u) = 5u/16 + 15 sin 2u/64 + 3 sin 4u/64 + sin 6u/192.
fn kernel_min_mean(mu: f64, h: f64, c: f64) -> f64 {
    let tau = (c - mu) / h;
    if tau >= 1.0 {
        return mu;
    }
    if tau <= -1.0 {
        return c;
    }
    let u = tau.asin();
    let f = 5.0 * u / 16.0 + 15.0 * (2.0 * u).sin() / 64.0 + 3.0 * (4.0 * u).sin() / 64.0 + (6.0 * u).sin() / 192.0;
    let q = 16.0 / (5.0 * PI) * (f + 5.0 * PI / 32.0);
    let first = -16.0 / (35.0 * PI) * (1.0 - tau * tau).powf(3.5);
    mu + h * (first + tau * (1.0 - q))
}

/// Silverman's rule for 2-D slopes with a robust spread (1.4826 × median
/// absolute deviation, pooled over both axes), converted to the support
/// radius of the kernel (variance h²/8 per axis).
fn silverman_bandwidth(slopes: &[[f64; 2]]) -> f64 {
    let median = |v: &mut Vec<f64>| {
        v.sort_by(|a, b| a.total_cmp(b));
        let n = v.len();
        if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        }
    };
    let mut dev = Vec::with_capacity(2 * slopes.len());
    for axis in 0..2 {
        let mut c: Vec<f64> = slopes.iter().map(|s| s[axis]).collect();
        let med = median(&mut c);
        dev.extend(slopes.iter().map(|s| (s[axis] - med).abs()));
    }
    let sigma = 1.4826 * median(&mut dev);
    (8.0f64.sqrt() * sigma * (slopes.len() as f64).powf(-1.0 / 6.0)).clamp(1e-6, 1.0)
}

/// The microsurface of a rough boundary: an analytic distribution or a
/// measured normal set (closed set; the measured data are shared).
#[derive(Clone, Debug)]
pub enum Microsurface {
    /// Trowbridge–Reitz or Beckmann; visible-normal sampling.
    Analytic(Distribution),
    /// Kernel density estimate of measured normals; sampling of D(m)(m·n).
    Measured(Arc<MeasuredNormals>),
}

impl Microsurface {
    /// True for an analytic distribution with α < [`SMOOTH_ALPHA`].
    pub fn is_smooth(&self) -> bool {
        match self {
            Microsurface::Analytic(d) => d.is_smooth(),
            Microsurface::Measured(_) => false,
        }
    }

    /// D(m) in 1/sr.
    pub fn d(&self, m: DVec3) -> f64 {
        match self {
            Microsurface::Analytic(d) => d.d(m),
            Microsurface::Measured(s) => s.d(m),
        }
    }

    /// Smith G1(ω, m).
    pub fn g1(&self, w: DVec3, m: DVec3) -> f64 {
        match self {
            Microsurface::Analytic(d) => d.g1(w, m),
            Microsurface::Measured(s) => s.g1(w, m),
        }
    }

    /// Draws a microfacet normal (facing +z) for light leaving along `wo`.
    pub fn sample_normal(&self, wo: DVec3, u: [f64; 2]) -> Option<DVec3> {
        match self {
            Microsurface::Analytic(d) => d.sample_visible(wo, u),
            Microsurface::Measured(s) => Some(s.sample_projected(u)).filter(|m| m.z > 0.0 && m.is_finite()),
        }
    }

    /// Density in 1/sr of [`Microsurface::sample_normal`] at m.
    pub fn pdf_normal(&self, wo: DVec3, m: DVec3) -> f64 {
        match self {
            Microsurface::Analytic(d) => d.pdf_visible(wo, m),
            Microsurface::Measured(s) => s.pdf_projected(m),
        }
    }

    /// Draws a normal as [`Microsurface::sample_normal`] and returns it with
    /// the factor G1(ω_o, m) |ω_o·m| D(m) / (|cos θ_o| p(m)), p the density it
    /// was drawn with: then a BSDF sample through m has the weight
    /// f |cos θ_i| / pdf = factor · G1(ω_i, m) (times the Fresnel lobe's
    /// factor when the lobe is not chosen by F). The factor is 1 for
    /// visible-normal sampling and G1(ω_o, m) |ω_o·m| / (|cos θ_o| m_z) for a
    /// measured set (p = D(m) m_z), so no density is evaluated (the measured
    /// set's kernel sum is the costly part). `None` as `sample_normal`, for a
    /// grazing `wo` and for a normal facing away from `wo` (factor 0).
    pub fn sample_normal_weighted(&self, wo: DVec3, u: [f64; 2]) -> Option<(DVec3, f64)> {
        if wo.z == 0.0 || !wo.is_finite() {
            return None;
        }
        match self {
            Microsurface::Analytic(d) => d.sample_visible(wo, u).map(|m| (m, 1.0)),
            Microsurface::Measured(s) => {
                let m = s.sample_projected(u);
                let g = s.g1(wo, m);
                if !(m.z > 0.0 && m.is_finite()) || g == 0.0 {
                    return None;
                }
                Some((m, g * wo.dot(m).abs() / (wo.z.abs() * m.z)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slope_cdf_inversion_is_exact() {
        // Round trip through the CDF for several incidence angles.
        for &(c, s) in &[(1.0, 0.0), (0.8, 0.6), (0.1, (1.0f64 - 0.01).sqrt())] {
            let hi = if s > 0.0 { (c / s).min(SLOPE_BOUND) } else { SLOPE_BOUND };
            let cdf = |x: f64| c * libm::erfc(-x) + s * (-x * x).exp() * FRAC_1_SQRT_PI;
            for &u in &[1e-9, 0.01, 0.3, 0.5, 0.77, 0.999, 1.0 - 1e-12] {
                let x = solve_slope_cdf(c, s, u, hi, 0.0);
                assert!(x <= hi && x >= -SLOPE_BOUND);
                assert!((cdf(x) / cdf(hi) - u).abs() < 1e-13, "c {c} u {u} x {x}");
            }
        }
    }

    #[test]
    fn erfinv_approx_inverts_erf() {
        for x in [-0.999999, -0.9, -0.3, 0.0, 0.1, 0.5, 0.99, 0.999999] {
            let y = erfinv_approx(x);
            assert!((libm::erf(y) - x).abs() < 1e-6, "{x}: {y}");
        }
    }

    #[test]
    fn kernel_min_mean_matches_quadrature() {
        // E[min(μ + h t, c)] by brute-force quadrature of the marginal.
        let (mu, h) = (0.1, 0.3);
        for c in [-0.5, -0.1, 0.0, 0.05, 0.2, 0.39, 0.5] {
            let n = 200_000;
            let (mut s, mut z) = (0.0, 0.0);
            for i in 0..n {
                let t = -1.0 + 2.0 * (i as f64 + 0.5) / n as f64;
                let q = (1.0 - t * t).powf(2.5);
                s += q * (mu + h * t).min(c);
                z += q;
            }
            let exact = kernel_min_mean(mu, h, c);
            assert!((exact - s / z).abs() < 1e-9, "c {c}: {exact} vs {}", s / z);
        }
    }
}
