//! Lorenz–Mie scattering by a homogeneous sphere, for a complex particle
//! index in a possibly absorbing (complex-index) host.
//!
//! # What is computed
//!
//! For a sphere of radius r in a host of index n_h = n + iκ (κ ≥ 0 absorbs;
//! time dependence e^{−iωt} as in Bohren & Huffman 1983), vacuum wavelength λ:
//!
//! * size parameter x = 2π r n_h / λ (complex when the host absorbs), relative
//!   index m = n_p / n_h, y = m x;
//! * the coefficients a_n, b_n (Bohren & Huffman eq. 4.88 in the logarithmic
//!   derivative form of Wiscombe 1979):
//!   a_n = [(D_n(y)/m + n/x) ψ_n(x) − ψ_{n−1}(x)] / [(D_n(y)/m + n/x) ξ_n(x) − ξ_{n−1}(x)],
//!   b_n the same with m D_n(y) in place of D_n(y)/m;
//! * efficiencies for a real host ([`Coefficients::efficiencies`]), the
//!   amplitudes S₁, S₂ ([`Coefficients::amplitudes`]), the asymmetry g, and the
//!   cross sections for an absorbing host in the formulation of Frisvad,
//!   Christensen & Jensen 2007 ([`Coefficients::cross_sections`], docs/method.md#optics):
//!   C_s = λ²/(2π|n_h|²) Σ(2n+1)(|a_n|²+|b_n|²) · F(α),
//!   C_t = λ²/(2π) Σ(2n+1) Re((a_n+b_n)/n_h²),
//!   F(α) = e^{−α} α² / (2(1 + (α − 1) e^{α})), α = 4π r Im(n_h)/λ
//!   ([`attenuation`]; F = 1 for α < 1e-6). F accounts for the attenuation
//!   of the far-field scattering over the sphere; without it C_s exceeds C_t
//!   once the host absorbs noticeably. g (and qback) come from the
//!   unattenuated sums. For a real host F = 1 and C_s, C_t are the usual
//!   cross sections;
//! * the power absorbed inside the sphere ([`absorption_inside`]), which is
//!   what [`efficiencies_in_host`] (and `lucent mie`) report as qabs in an
//!   absorbing host. There C_t − C_s is not the sphere's absorption: C_t is
//!   the apparent (far-field) extinction, which also counts the host
//!   absorption the sphere displaces — in the Rayleigh limit
//!   C_t = (8π² r³/λ) Im(n_h (m²−1)/(m²+2)), which tends to −(4πκ_h/λ)·(4/3)πr³
//!   as m → 1, so a small clear sphere has C_t < 0 (Bohren & Gilra 1979).
//!   For α ≳ 1 (a host that absorbs strongly over one sphere) the far-field
//!   quantities lose their meaning (C_t grows like e^{α}); [`super::bulk`]
//!   warns there.
//!
//! # Small spheres
//!
//! The upward recurrence for ψ_n(x) loses relative precision as the growing
//! solution χ_n contaminates it (ψ_1 = sin x/x − cos x cancels to x²/3): at
//! x = 1e-6, m = 0.9 the recurrence alone gives g = 3e-3 instead of 1.6e-13,
//! and at x = 1e-8 a qsca 72 times too large. Below |x| = 1
//! ([`SERIES_BELOW`]) ψ_n comes from its power series instead (full
//! precision for every order; χ_n, the growing solution, still recurs
//! upward), so x → 0 is exact down to [`MIN_SIZE_PARAMETER`] = 1e-20:
//! checked against miepython (audited with 50-digit mpmath) from x = 1e-8
//! to 3 for real and absorbing m, qext and qsca to 2.3e-13 relative and g to
//! 3.5e-15 absolute (`tests/mie_reference.rs`); across x = 1 ± 1e-10 the
//! efficiencies change by at most 7e-10, as their slope predicts. The b_n
//! numerator still cancels (its leading terms are O(x) and b_1 = O(x⁵)), but
//! its error is O(ε|a_1|), which changes g by O(ε) and, for a real m, qext
//! not at all (Re b_n = |b_n|² there).
//!
//! # Numerics
//!
//! * Series length N by Wiscombe's criterion on |x| (x + 4x^{1/3} + 1 up to 8,
//!   x + 4.05x^{1/3} + 2 up to 4200, x + 4x^{1/3} + 2 beyond), at least 3,
//!   plus two guard terms (see [`wiscombe_terms`]).
//! * D_n(y) = ψ'_n(y)/ψ_n(y) by downward recurrence, started with Lentz's
//!   (1976) continued fraction at max(N, ⌈|y|⌉ + 2), at or just above the
//!   turning point; downward recurrence is stable for every complex y, and
//!   the exact start matters when |y| > N (a crude start is not damped
//!   below the turning point). The recurrence runs in projective form
//!   D_n = p_n/q_n, which is linear and division-free (see
//!   `downward_step`), in real arithmetic when m and x are real.
//! * a_n and b_n are computed side by side in two SIMD lanes, and the
//!   series sums in a pass of their own (see `PairSums`).
//! * ψ_n and ξ_n by upward recurrence up to N (Wiscombe 1979 shows this is
//!   accurate up to the Wiscombe length) for |x| ≥ 1, ψ_n by its series
//!   below (see "Small spheres"), so no Bessel function is evaluated.
//! * Checked against miepython 3.3 on 320 random cases (x from 0.01 to 1000,
//!   real and complex m) to 1e-6 relative, and against Wiscombe's published
//!   MIEV0 test values (`tests/mie_reference.rs`). Stable without NaN or
//!   overflow up to |x| = 20 000 for a real host.
//! * Absorbing hosts: checked against an independent evaluation from
//!   spherical Bessel functions of complex argument (scipy; 60 spheres,
//!   κ_h = 1e-6 … 5e-2, r = 0.05 … 6 µm, clear and absorbing particles):
//!   qext, qsca, qabs to 2e-11 relative, g to 1e-14.
//!
//! Sign convention: an absorbing particle or host has a **positive**
//! imaginary index (miepython writes m = n − ik; convert by conjugating).
//!
//! ```
//! use lucent::optics::mie::Coefficients;
//! use num_complex::Complex64;
//! // Bohren & Huffman's appendix example: m = 1.55, r = 0.525 µm, λ = 0.6328 µm
//! let x = 2.0 * std::f64::consts::PI * 0.525 / 0.6328;
//! let c = Coefficients::compute(Complex64::new(1.55, 0.0), Complex64::new(x, 0.0)).unwrap();
//! let q = c.efficiencies(x);
//! assert!((q.qsca - 3.10543).abs() < 5e-6);
//! ```

use num_complex::Complex64;
use std::f64::consts::PI;

/// Why a Mie computation was refused.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MieError {
    #[error("size parameter x = {0} is not usable (must be finite with |x| > 0)")]
    SizeParameter(Complex64),
    #[error("relative refractive index m = {0} is not usable (must be finite and non-zero)")]
    RelativeIndex(Complex64),
    #[error("size parameter |x| = {0} exceeds the supported maximum of 1e5")]
    TooLarge(f64),
    #[error(
        "|m·x| = {0:e} (relative index × size parameter) exceeds the supported maximum of 1e7: the series \
         inside the sphere would need that many terms"
    )]
    TooLargeInside(f64),
    #[error("size parameter |x| = {0:e} is below the supported minimum of 1e-20")]
    TooSmall(f64),
    #[error("radius {radius_m} m and vacuum wavelength {wavelength_m} m must be positive and finite")]
    Geometry { radius_m: f64, wavelength_m: f64 },
    #[error(
        "the Mie series overflowed for m = {m}, x = {x} (host absorption too strong for this size: |Im x| = {imx})"
    )]
    Overflow { m: Complex64, x: Complex64, imx: f64 },
}

/// Efficiencies of a sphere in a non-absorbing host (dimensionless, relative
/// to the geometric cross section π r²), and the asymmetry parameter g.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Efficiencies {
    pub qext: f64,
    pub qsca: f64,
    pub qabs: f64,
    pub qback: f64,
    pub g: f64,
}

/// Cross sections in m² and the asymmetry parameter of one sphere in a
/// (possibly absorbing) host, per Frisvad et al. 2007 (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossSections {
    /// C_s, including the attenuation factor F(α).
    pub scattering_m2: f64,
    /// C_t (the apparent, far-field extinction; negative for a small clear
    /// sphere in an absorbing host).
    pub extinction_m2: f64,
    /// g from the unattenuated sums.
    pub g: f64,
    /// F(α) of [`attenuation`] (1 for a non-absorbing host).
    pub attenuation: f64,
}

/// The attenuation factor of the far-field scattering of a sphere in an
/// absorbing host (Frisvad, Christensen & Jensen 2007; docs/method.md#optics):
/// F(α) = e^{−α} α² / (2(1 + (α − 1) e^{α})), α = 4π r Im(n_h)/λ, and
/// F = 1 for α < 1e-6 by convention (at α = 1e-6 the exact F is
/// 1 − 1.7e-6, so that cut-off is a step of 1.7e-6).
///
/// Evaluated without cancellation: for α < 1 as e^{−α} / (2 Σ_j α^j (j+1)/(j+2)!)
/// (the series of (1 + (α − 1)e^α)/α²), for α ≥ 1 as
/// α² e^{−2α} / (2(α − 1 + e^{−α})), which does not overflow. F falls
/// monotonically from 1 (F ≈ 1 − 5α/3 for small α). Non-finite or negative
/// α gives NaN.
///
/// ```
/// use lucent::optics::mie::attenuation;
/// assert_eq!(attenuation(0.0), 1.0);
/// // F(1) = e^{−1}/(2 (1 + 0)) = 1/(2e).
/// assert!((attenuation(1.0) - 0.5 / std::f64::consts::E).abs() < 1e-15);
/// // A 1 µm sphere at 550 nm in a host with κ = 1e-2: α = 0.228, F = 0.682.
/// let alpha = 4.0 * std::f64::consts::PI * 1e-6 * 1e-2 / 550e-9;
/// assert!((attenuation(alpha) - 0.68234).abs() < 1e-5);
/// ```
pub fn attenuation(alpha: f64) -> f64 {
    if !(alpha.is_finite() && alpha >= 0.0) {
        return f64::NAN;
    }
    if alpha < 1e-6 {
        return 1.0;
    }
    if alpha < 1.0 {
        // Σ_{j≥0} α^j (j+1)/(j+2)!: 24 terms reach 1e-17 relative at α = 1.
        let mut sum = 0.0;
        let mut power = 1.0;
        let mut factorial = 2.0;
        for j in 0..24 {
            sum += power * (j + 1) as f64 / factorial;
            power *= alpha;
            factorial *= (j + 3) as f64;
        }
        (-alpha).exp() / (2.0 * sum)
    } else {
        let e = (-alpha).exp();
        alpha * alpha * e * e / (2.0 * (alpha - 1.0 + e))
    }
}

/// Checks (m, x) for [`Coefficients::recompute`]; returns |x|.
fn check_arguments(m: Complex64, x: Complex64) -> Result<f64, MieError> {
    let xabs = x.norm_sqr().sqrt();
    if !(x.re.is_finite() && x.im.is_finite()) || xabs == 0.0 || x.re <= 0.0 {
        return Err(MieError::SizeParameter(x));
    }
    if !(m.re.is_finite() && m.im.is_finite()) || m.norm_sqr() == 0.0 {
        return Err(MieError::RelativeIndex(m));
    }
    if xabs > 1e5 {
        return Err(MieError::TooLarge(xabs));
    }
    let mx = (m * x).norm();
    if mx > 1e7 {
        return Err(MieError::TooLargeInside(mx));
    }
    if xabs < MIN_SIZE_PARAMETER {
        return Err(MieError::TooSmall(xabs));
    }
    Ok(xabs)
}

/// Σ(2n+1)(|a|²+|b|²), Σ(2n+1)(a+b), Σ(2n+1)(−1)^n(a−b) and the numerator
/// of g (Bohren & Huffman eqs. 4.61, 4.62, 4.74 at 0° and 180°).
#[derive(Debug, Clone, Copy, Default)]
struct SeriesSums {
    scattering: f64,
    extinction: Complex64,
    backscatter: Complex64,
    asymmetry: f64,
}

impl SeriesSums {
    fn finite(&self) -> bool {
        [
            self.scattering,
            self.extinction.re,
            self.extinction.im,
            self.backscatter.re,
            self.backscatter.im,
            self.asymmetry,
        ]
        .iter()
        .all(|v| v.is_finite())
    }

    fn g(&self) -> f64 {
        if self.scattering > 0.0 {
            2.0 * self.asymmetry / self.scattering
        } else {
            0.0
        }
    }
}

/// Lorenz–Mie coefficients a_n, b_n (n = 1 …) of one sphere, with reusable
/// buffers: [`Coefficients::recompute`] allocates nothing once the buffers
/// have grown to the largest series length used.
#[derive(Debug, Clone, Default)]
pub struct Coefficients {
    /// a_n (lane 0) and b_n (lane 1), n = 1 … N.
    ab: Vec<C2>,
    /// [ψ_n, χ_n] of a real size parameter, n = 0 … N.
    riccati_real: Vec<[f64; 2]>,
    /// [ψ_n, ξ_n] of a complex size parameter, n = 0 … N.
    riccati: Vec<[Complex64; 2]>,
    sums: SeriesSums,
}

/// Series length for size parameter magnitude `x`: Wiscombe's (1979)
/// criterion, at least 3, plus [`GUARD_TERMS`]. Wiscombe's length is set for
/// the efficiencies; in the Rayleigh regime g and the polarisation null of S₂
/// at 90° come from quadrupole terms it drops (g would be wrong by ~50 % at
/// x = 0.01), and at large x the backscatter sum converges to ~1e-6 only
/// with a few more terms. The extra terms cost ≲ 2 % at x ≥ 100.
pub fn wiscombe_terms(x: f64) -> usize {
    let x3 = x.cbrt();
    let n = if x <= 8.0 {
        x + 4.0 * x3 + 1.0
    } else if x < 4200.0 {
        x + 4.05 * x3 + 2.0
    } else {
        x + 4.0 * x3 + 2.0
    };
    (n.floor() as usize).max(3) + GUARD_TERMS
}

/// Terms added to Wiscombe's length (see [`wiscombe_terms`]).
pub const GUARD_TERMS: usize = 2;

/// 1 / b with one real division.
#[inline(always)]
fn cinv(b: Complex64) -> Complex64 {
    let r = 1.0 / (b.re * b.re + b.im * b.im);
    Complex64::new(b.re * r, -b.im * r)
}

/// The scalar of D_n(y): `f64` when m and x are real, else `Complex64`.
trait Scalar:
    Copy
    + std::ops::Add<Output = Self>
    + std::ops::Sub<Output = Self>
    + std::ops::Mul<Output = Self>
    + std::ops::Mul<f64, Output = Self>
{
    /// Whether [`DownwardOrders`] pairs the steps of its serial chain where
    /// work is done on every order (measured: faster for real, slower for
    /// complex arithmetic, whose extra flops then outweigh the shorter chain).
    const PAIRED_STEPS: bool;
    fn one() -> Self;
    /// |Re| + |Im|.
    fn l1(self) -> f64;
    /// 1/self (one real division).
    fn recip(self) -> Self;
}

impl Scalar for f64 {
    const PAIRED_STEPS: bool = true;
    fn one() -> Self {
        1.0
    }
    fn l1(self) -> f64 {
        self.abs()
    }
    #[inline(always)]
    fn recip(self) -> Self {
        1.0 / self
    }
}

impl Scalar for Complex64 {
    const PAIRED_STEPS: bool = false;
    fn one() -> Self {
        Complex64::new(1.0, 0.0)
    }
    fn l1(self) -> f64 {
        self.re.abs() + self.im.abs()
    }
    #[inline(always)]
    fn recip(self) -> Self {
        cinv(self)
    }
}

/// Two lanes, (a_n-part, b_n-part): a_n and b_n follow the same formula with
/// 1/m and m, so they are computed side by side (the compiler packs the
/// lanes into one SIMD register, and one packed division serves both).
#[derive(Debug, Clone, Copy, Default)]
struct F2([f64; 2]);

impl F2 {
    #[inline(always)]
    fn splat(v: f64) -> Self {
        F2([v, v])
    }
    #[inline(always)]
    fn sum(self) -> f64 {
        self.0[0] + self.0[1]
    }
}

macro_rules! lanewise {
    ($tr:ident, $f:ident, $op:tt) => {
        impl std::ops::$tr for F2 {
            type Output = F2;
            #[inline(always)]
            fn $f(self, o: F2) -> F2 {
                F2([self.0[0] $op o.0[0], self.0[1] $op o.0[1]])
            }
        }
    };
}
lanewise!(Add, add, +);
lanewise!(Sub, sub, -);
lanewise!(Mul, mul, *);
lanewise!(Div, div, /);

impl std::ops::Mul<f64> for F2 {
    type Output = F2;
    #[inline(always)]
    fn mul(self, k: f64) -> F2 {
        F2([self.0[0] * k, self.0[1] * k])
    }
}

/// Two complex lanes (real parts, imaginary parts).
#[derive(Debug, Clone, Copy)]
struct C2 {
    re: F2,
    im: F2,
}

impl C2 {
    #[inline(always)]
    fn splat(z: Complex64) -> Self {
        C2 { re: F2::splat(z.re), im: F2::splat(z.im) }
    }
    #[inline(always)]
    fn lanes(a: Complex64, b: Complex64) -> Self {
        C2 { re: F2([a.re, b.re]), im: F2([a.im, b.im]) }
    }
    #[inline(always)]
    fn add(self, o: C2) -> C2 {
        C2 { re: self.re + o.re, im: self.im + o.im }
    }
    #[inline(always)]
    fn sub(self, o: C2) -> C2 {
        C2 { re: self.re - o.re, im: self.im - o.im }
    }
    #[inline(always)]
    fn mul(self, o: C2) -> C2 {
        C2 { re: self.re * o.re - self.im * o.im, im: self.re * o.im + self.im * o.re }
    }
    #[inline(always)]
    fn scale(self, k: f64) -> C2 {
        C2 { re: self.re * k, im: self.im * k }
    }
    /// self / o with one (packed) real division.
    #[inline(always)]
    fn div(self, o: C2) -> C2 {
        let r = F2::splat(1.0) / (o.re * o.re + o.im * o.im);
        C2 { re: (self.re * o.re + self.im * o.im) * r, im: (self.im * o.re - self.re * o.im) * r }
    }
}

/// Riccati–Bessel functions of the size parameter at one order n:
/// `[ψ_n, χ_n]` for a real x (ξ_n = ψ_n − iχ_n), `[ψ_n, ξ_n]` for a complex x.
trait Riccati: Copy {
    /// (a_n, b_n) = (u ψ_n − q ψ_{n−1}) / (u ξ_n − q ξ_{n−1}) lane by lane,
    /// for complex lanes `u`; `self` is order n, `prev` order n − 1.
    fn coefficients(self, prev: Self, u: C2, q: Complex64) -> C2;
}

impl Riccati for [f64; 2] {
    #[inline(always)]
    fn coefficients(self, prev: Self, u: C2, q: Complex64) -> C2 {
        let num = u.scale(self[0]).sub(C2::splat(q * prev[0]));
        let c = u.scale(self[1]).sub(C2::splat(q * prev[1]));
        // ξ = ψ − iχ: the denominator is num − i c.
        num.div(C2 { re: num.re + c.im, im: num.im - c.re })
    }
}

impl Riccati for [Complex64; 2] {
    #[inline(always)]
    fn coefficients(self, prev: Self, u: C2, q: Complex64) -> C2 {
        let num = u.mul(C2::splat(self[0])).sub(C2::splat(q * prev[0]));
        let den = u.mul(C2::splat(self[1])).sub(C2::splat(q * prev[1]));
        num.div(den)
    }
}

/// Below this |x|, ψ_n(x) comes from its power series (`psi_series`)
/// instead of the upward recurrence (see the module doc, "Small spheres").
pub const SERIES_BELOW: f64 = 1.0;

/// Smallest |x| accepted: below it χ_n(x)² (n ≤ 5) would approach the
/// overflow threshold. (x = 1e-20 is a sphere of radius 1e-21 λ.)
pub const MIN_SIZE_PARAMETER: f64 = 1e-20;

/// ψ_n(x) = x j_n(x) for n = 0 … `nstop` from the power series
/// ψ_n(x) = x^{n+1}/(2n+1)!! Σ_k (−x²/2)^k / (k! (2n+3)(2n+5)…(2n+2k+1)),
/// summed until a term falls below 1e-17 of the sum; for |x| < 1 that is at
/// most ~10 terms, and the sum lies in (0.8, 1.2), so every ψ_n has full
/// relative precision (the upward recurrence loses it as the growing χ_n
/// contaminates the decaying ψ_n, catastrophically for x ≲ 1e-4).
fn psi_series<T: Scalar>(x: T, nstop: usize, mut out: impl FnMut(usize, T)) {
    let x2 = x * x;
    let mut lead = x;
    for n in 0..=nstop {
        if n > 0 {
            lead = lead * x * (1.0 / (2 * n + 1) as f64);
        }
        let mut term = T::one();
        let mut sum = T::one();
        for k in 1..40 {
            term = term * x2 * (-0.5 / (k * (2 * n + 2 * k + 1)) as f64);
            sum = sum + term;
            if term.l1() < 1e-17 * sum.l1() {
                break;
            }
        }
        out(n, lead * sum);
    }
}

/// ψ_n, χ_n of a real x for n = 0 … `nstop`: upward recurrence (accurate up
/// to Wiscombe's length, Wiscombe 1979) for x ≥ [`SERIES_BELOW`]; below, ψ_n
/// from [`psi_series`] and χ_n (the growing solution) still upward.
fn riccati_real(x: f64, nstop: usize, out: &mut Vec<[f64; 2]>) {
    if x < SERIES_BELOW {
        let (sx, cx) = x.sin_cos();
        let (mut chi_prev, mut chi) = (-sx, cx);
        out.clear();
        out.reserve(nstop + 1);
        psi_series(x, nstop, |n, psi| {
            if n > 0 {
                (chi_prev, chi) = (chi, (2.0 * n as f64 - 1.0) / x * chi - chi_prev);
            }
            out.push([psi, chi]);
        });
        return;
    }
    let inv_x = 1.0 / x;
    let (sx, cx) = x.sin_cos();
    // ψ_{−1} = cos x, ψ_0 = sin x; χ_{−1} = −sin x, χ_0 = cos x.
    let (mut psi_prev, mut psi) = (cx, sx);
    let (mut chi_prev, mut chi) = (-sx, cx);
    out.clear();
    out.reserve(nstop + 1);
    out.push([psi, chi]);
    for n in 1..=nstop {
        let f = (2.0 * n as f64 - 1.0) * inv_x;
        (psi_prev, psi) = (psi, f * psi - psi_prev);
        (chi_prev, chi) = (chi, f * chi - chi_prev);
        out.push([psi, chi]);
    }
}

/// ψ_n, ξ_n of a complex x for n = 0 … `nstop`: upward recurrence for
/// |x| ≥ [`SERIES_BELOW`]; below, ψ_n from [`psi_series`], χ_n upward and
/// ξ_n = ψ_n − iχ_n (so that ξ_n carries the accurate ψ_n).
fn riccati_complex(x: Complex64, nstop: usize, out: &mut Vec<[Complex64; 2]>) {
    let inv_x = x.inv();
    let (sx, cx) = (x.sin(), x.cos());
    let i = Complex64::new(0.0, 1.0);
    if x.norm() < SERIES_BELOW {
        let (mut chi_prev, mut chi) = (-sx, cx);
        out.clear();
        out.reserve(nstop + 1);
        psi_series(x, nstop, |n, psi| {
            if n > 0 {
                (chi_prev, chi) = (chi, inv_x * (2.0 * n as f64 - 1.0) * chi - chi_prev);
            }
            out.push([psi, psi - i * chi]);
        });
        return;
    }
    // ψ_{−1} = cos x, ψ_0 = sin x; ξ_{−1} = cos x + i sin x, ξ_0 = sin x − i cos x.
    let (mut psi_prev, mut psi) = (cx, sx);
    let (mut xi_prev, mut xi) = (cx + i * sx, sx - i * cx);
    out.clear();
    out.reserve(nstop + 1);
    out.push([psi, xi]);
    for n in 1..=nstop {
        let f = inv_x * (2.0 * n as f64 - 1.0);
        (psi_prev, psi) = (psi, f * psi - psi_prev);
        (xi_prev, xi) = (xi, f * xi - xi_prev);
        out.push([psi, xi]);
    }
}

/// One step of the downward recurrence D_{n−1} = n/y − 1/(D_n + n/y) for
/// D_n = p/q in projective form, `ny` = n/y:
/// q ← p + (n/y) q, p ← (n/y) q_new − q_old. The map has determinant 1
/// (p and q never vanish together) and is division-free, so the serial
/// chain is two multiply–adds per step instead of a complex division; the
/// pair is rescaled when it leaves [1e−100, 1e100].
#[inline(always)]
fn downward_step<T: Scalar>(p: &mut T, q: &mut T, ny: T) {
    (*p, *q) = step_pair(*p, *q, ny);
    rescale(p, q);
}

/// The projective step of [`downward_step`] without the rescaling:
/// (p, q) ↦ ((n/y) q′ − q, q′) with q′ = p + (n/y) q.
#[inline(always)]
fn step_pair<T: Scalar>(p: T, q: T, ny: T) -> (T, T) {
    let q1 = p + ny * q;
    (ny * q1 - q, q1)
}

/// Two downward steps at once, D_n → D_{n−2}, with `a` = n/y and
/// `b` = (n−1)/y: the product of the two step matrices
/// M_k = [[k/y, (k/y)² − 1], [1, k/y]] is formed off the serial chain, so the
/// chain is one matrix–vector product per two orders.
#[inline(always)]
fn downward_two<T: Scalar>(p: &mut T, q: &mut T, a: T, b: T) {
    let one = T::one();
    let (a2, b2, ab) = (a * a - one, b * b - one, a * b);
    let (m00, m01, m10, m11) = (ab + b2, b * a2 + b2 * a, a + b, a2 + ab);
    let p2 = m00 * *p + m01 * *q;
    *q = m10 * *p + m11 * *q;
    *p = p2;
    rescale(p, q);
}

/// Keeps the projective pair within [1e−100, 1e100].
#[inline(always)]
fn rescale<T: Scalar>(p: &mut T, q: &mut T) {
    let s = p.l1() + q.l1();
    if !(1e-100..=1e100).contains(&s) {
        let k = 1.0 / s;
        *p = *p * k;
        *q = *q * k;
    }
}

/// D_n(y) = p_n/q_n for n = `nstop` … 1, in that order, from
/// D_{n_start} = `d_start` by the downward recurrence: two orders per step
/// of the serial chain ([`downward_two`]) down to `nstop`, where nothing
/// else runs beside the chain; below, the caller's work on each order fills
/// the chain's latency, and the chain keeps paired steps (the order between
/// computed off the chain) only where `T::PAIRED_STEPS`.
struct DownwardOrders<T> {
    p: T,
    q: T,
    inv_y: T,
    /// The order of (p, q).
    n: usize,
    pending: Option<(T, T)>,
}

impl<T: Scalar> DownwardOrders<T> {
    #[inline(always)]
    fn new(inv_y: T, d_start: T, n_start: usize, nstop: usize) -> Self {
        let (mut p, mut q) = (d_start, T::one());
        let mut n = n_start;
        while n >= nstop + 2 {
            downward_two(&mut p, &mut q, inv_y * n as f64, inv_y * (n - 1) as f64);
            n -= 2;
        }
        if n > nstop {
            downward_step(&mut p, &mut q, inv_y * n as f64);
            n -= 1;
        }
        Self { p, q, inv_y, n, pending: None }
    }
}

impl<T: Scalar> Iterator for DownwardOrders<T> {
    type Item = (T, T);
    #[inline(always)]
    fn next(&mut self) -> Option<(T, T)> {
        if let Some(x) = self.pending.take() {
            return Some(x);
        }
        if self.n == 0 {
            return None;
        }
        let out = (self.p, self.q);
        if T::PAIRED_STEPS && self.n >= 2 {
            let a = self.inv_y * self.n as f64;
            self.pending = Some(step_pair(self.p, self.q, a));
            downward_two(&mut self.p, &mut self.q, a, self.inv_y * (self.n - 1) as f64);
            self.n -= 2;
        } else {
            downward_step(&mut self.p, &mut self.q, self.inv_y * self.n as f64);
            self.n -= 1;
        }
        Some(out)
    }
}

/// Sizes `ab` to `nstop` orders.
fn reset(ab: &mut Vec<C2>, nstop: usize) {
    ab.clear();
    ab.resize(nstop, C2::splat(Complex64::new(0.0, 0.0)));
}

/// a_n, b_n for n = 1 … N into `ab` (lanes 0 and 1), and their series sums, for a real
/// m and a real x (D_n(y) real): D_n(y) by downward recurrence from
/// D_{n_start} = `d_start`, ψ_n, χ_n of x from `riccati` (orders 0 … N).
///
/// With D_n = p/q: a_n = [(p/m + nq/x) ψ_n − q ψ_{n−1}] / [(p/m + nq/x) ξ_n − q ξ_{n−1}],
/// b_n the same with p m in place of p/m; here numerator ν and the χ-part
/// c are real and a_n = ν/(ν − ic). Each a_n, b_n is formed in the step that
/// produces D_n, so that work fills the latency of the serial recurrence,
/// and the sums run from n = N down.
fn coefficients_real(
    y: f64,
    d_start: f64,
    n_start: usize,
    m: f64,
    x: f64,
    riccati: &[[f64; 2]],
    ab: &mut Vec<C2>,
) -> SeriesSums {
    let nstop = riccati.len() - 1;
    let (inv_y, inv_x) = (1.0 / y, 1.0 / x);
    reset(ab, nstop);
    let lanes_m = F2([1.0 / m, m]);
    let orders = DownwardOrders::new(inv_y, d_start, n_start, nstop);
    let slots = riccati.windows(2).rev().zip(ab.iter_mut().rev());
    for (n, ((p, q), (r, z))) in (1..=nstop).rev().zip(orders.zip(slots)) {
        let u = F2::splat(p) * lanes_m + F2::splat(q * (inv_x * n as f64));
        let num = u * r[1][0] - F2::splat(q * r[0][0]);
        let c = u * r[1][1] - F2::splat(q * r[0][1]);
        let k = num / (num * num + c * c);
        *z = C2 { re: num * k, im: c * k };
    }
    PairSums::over(ab)
}

/// As [`coefficients_real`] for a complex m and/or x: `inv_x` is 1/x and
/// `riccati` holds [ψ_n, χ_n] (real x) or [ψ_n, ξ_n] (complex x).
#[allow(clippy::too_many_arguments)]
fn coefficients_complex<R, X>(
    y: Complex64,
    d_start: Complex64,
    n_start: usize,
    m: Complex64,
    inv_x: X,
    riccati: &[R],
    ab: &mut Vec<C2>,
) -> SeriesSums
where
    R: Riccati,
    X: Copy + std::ops::Mul<f64, Output = X>,
    Complex64: std::ops::Mul<X, Output = Complex64>,
{
    let nstop = riccati.len() - 1;
    reset(ab, nstop);
    let lanes_m = C2::lanes(m.inv(), m);
    let orders = DownwardOrders::new(y.inv(), d_start, n_start, nstop);
    let slots = riccati.windows(2).rev().zip(ab.iter_mut().rev());
    for (n, ((p, q), (r, z))) in (1..=nstop).rev().zip(orders.zip(slots)) {
        let u = C2::splat(p).mul(lanes_m).add(C2::splat(q * (inv_x * n as f64)));
        *z = r[1].coefficients(r[0], u, q);
    }
    PairSums::over(ab)
}

/// Accumulates [`SeriesSums`] term by term, n = N, N − 1, … 1, with a_n in
/// lane 0 and b_n in lane 1.
#[derive(Debug)]
struct PairSums {
    scattering: F2,
    /// Σ (2n+1) a_n and Σ (2n+1) b_n over even n, and over odd n: their sum
    /// is the extinction sum, their difference the backscatter sum.
    even: C2,
    odd: C2,
    /// Σ n(n+2)/(n+1) Re(a_n a_{n+1}*), the same for b.
    neighbours: F2,
    /// Σ (2n+1)/(n(n+1)) Re(a_n b_n*).
    cross: f64,
    /// a_{n+1}, b_{n+1} (zero above N).
    next: C2,
    /// 1/(n+1).
    inv_n1: f64,
}

impl PairSums {
    /// The sums of a_n, b_n (lanes of `ab`, n = 1 … N), from n = N down,
    /// two orders (even, then odd) per iteration. A pass of its own: fused
    /// into the coefficient loop, the accumulators pushed that loop's
    /// registers onto the stack.
    fn over(ab: &[C2]) -> SeriesSums {
        let zero = C2::splat(Complex64::new(0.0, 0.0));
        let n = ab.len();
        let mut s = PairSums {
            scattering: F2::default(),
            even: zero,
            odd: zero,
            neighbours: F2::default(),
            cross: 0.0,
            next: zero,
            inv_n1: 1.0 / (n as f64 + 1.0),
        };
        let mut nf = n as f64;
        let paired = if n % 2 == 1 {
            s.add::<true>(nf, ab[n - 1]);
            nf -= 1.0;
            &ab[..n - 1]
        } else {
            ab
        };
        for pair in paired.rchunks_exact(2) {
            s.add::<false>(nf, pair[1]);
            s.add::<true>(nf - 1.0, pair[0]);
            nf -= 2.0;
        }
        let (e, o) = (s.even, s.odd);
        SeriesSums {
            scattering: s.scattering.sum(),
            extinction: Complex64::new((e.re + o.re).sum(), (e.im + o.im).sum()),
            // Σ (2n+1)(−1)^n (a_n − b_n): lane 0 minus lane 1 of even − odd.
            backscatter: Complex64::new(
                (e.re.0[0] - o.re.0[0]) - (e.re.0[1] - o.re.0[1]),
                (e.im.0[0] - o.im.0[0]) - (e.im.0[1] - o.im.0[1]),
            ),
            asymmetry: s.neighbours.sum() + s.cross,
        }
    }

    /// Adds order n = `nf` (odd when `ODD`).
    #[inline(always)]
    fn add<const ODD: bool>(&mut self, nf: f64, z: C2) {
        let w = 2.0 * nf + 1.0;
        self.scattering = self.scattering + (z.re * z.re + z.im * z.im) * w;
        if ODD {
            self.odd = self.odd.add(z.scale(w));
        } else {
            self.even = self.even.add(z.scale(w));
        }
        // Weights n(n+2)/(n+1) = (n+1) − 1/(n+1) and (2n+1)/(n(n+1)) =
        // 1/n + 1/(n+1): one division per term, 1/(n+1) carried over.
        let inv_n = 1.0 / nf;
        let inv_n1 = self.inv_n1;
        self.inv_n1 = inv_n;
        self.neighbours = self.neighbours + (z.re * self.next.re + z.im * self.next.im) * (nf + 1.0 - inv_n1);
        self.cross += (inv_n + inv_n1) * (z.re.0[0] * z.re.0[1] + z.im.0[0] * z.im.0[1]);
        self.next = z;
    }
}

/// Power absorbed inside a sphere, as a cross section \[m²\]: sphere radius
/// `radius_m`, particle index `n_particle`, host index `n_host` (either may
/// absorb), vacuum wavelength `wavelength_m`; relative to the intensity of
/// the incident wave at the sphere's centre, I₀ = ½ Re(n_h) c ε₀ |E₀|².
/// It is [`absorption_efficiency`] times πr², with y = k₀ r n_p formed
/// directly (exactly real for a real n_p: then the result is exactly 0).
pub fn absorption_inside(
    n_particle: Complex64,
    n_host: Complex64,
    wavelength_m: f64,
    radius_m: f64,
) -> Result<f64, MieError> {
    let k0r = check_geometry(wavelength_m, radius_m)?;
    if n_particle.im == 0.0 {
        check_arguments(n_particle / n_host, n_host * k0r)?;
        return Ok(0.0);
    }
    let q = absorption_core(n_particle / n_host, n_host * k0r, n_particle * k0r)?;
    Ok(q * PI * radius_m * radius_m)
}

/// The efficiency of the power absorbed inside a sphere of relative index
/// `m` = n_p/n_h and size parameter `x` = k₀ r n_h (over I₀ πr², I₀ the
/// incident intensity at the centre).
///
/// From the internal field E₁ = Σ E_n (c_n M_o1n − i d_n N_e1n) (Bohren &
/// Huffman eq. 4.40) and the inward Poynting flux through the surface:
/// Q_abs = (2/Re x) Re[(i/y) Σ (2n+1)(|d_n|² ψ'_n(y) ψ_n(y)* − |c_n|² ψ_n(y) ψ'_n(y)*)],
/// y = m x, with c_n ψ_n(y) = i m / (ξ'_n(x) − m ξ_n(x) D_n(y)) and
/// d_n ψ_n(y) = i m / (m ξ'_n(x) − ξ_n(x) D_n(y)) (Wronskian ψξ' − ξψ' = i),
/// so only the stable ξ_n(x) (upward) and D_n(y) (downward) are needed. It
/// equals ½ω Im(ε_p) ∫|E₁|² dV / I₀ (checked against that volume integral
/// in `tools/reference/mie_absorbing_host.py`), so it is ≥ 0; for a real m
/// and x it is exactly 0. In a real host it equals qext − qsca (energy
/// conservation; tested) but keeps its relative precision for a weakly
/// absorbing sphere, where the difference cancels. In an absorbing host it
/// is not qext − qsca (see the module doc).
pub fn absorption_efficiency(m: Complex64, x: Complex64) -> Result<f64, MieError> {
    check_arguments(m, x)?;
    if m.im == 0.0 && x.im == 0.0 {
        return Ok(0.0);
    }
    absorption_core(m, x, m * x)
}

fn absorption_core(m: Complex64, x: Complex64, y: Complex64) -> Result<f64, MieError> {
    let nstop = wiscombe_terms(check_arguments(m, x)?);
    // ξ_n(x), n = 0 … N, upward (the growing solution: stable).
    let i = Complex64::new(0.0, 1.0);
    let inv_x = x.inv();
    let (sx, cx) = (x.sin(), x.cos());
    let mut xi = Vec::with_capacity(nstop + 1);
    let (mut prev, mut cur) = (cx + i * sx, sx - i * cx);
    xi.push(cur);
    for n in 1..=nstop {
        (prev, cur) = (cur, inv_x * (2.0 * n as f64 - 1.0) * cur - prev);
        xi.push(cur);
    }
    let n_start = nstop.max(y.norm().ceil() as usize + 2);
    let orders = DownwardOrders::new(y.inv(), lentz(y, n_start), n_start, nstop);
    let mut sum = Complex64::new(0.0, 0.0);
    for (n, (p, q)) in (1..=nstop).rev().zip(orders) {
        let d = p / q;
        let xi_n = xi[n];
        let dxi = xi[n - 1] - inv_x * (n as f64) * xi_n;
        let te = (dxi - m * xi_n * d).norm_sqr();
        let tm = (m * dxi - xi_n * d).norm_sqr();
        sum += (d / tm - d.conj() / te) * (2.0 * n as f64 + 1.0);
    }
    let q = 2.0 / x.re * (i / y * sum * m.norm_sqr()).re;
    if !q.is_finite() {
        return Err(MieError::Overflow { m, x, imx: x.im.abs() });
    }
    Ok(q + 0.0)
}

/// Efficiencies of a sphere of relative index `m` (m_im ≥ 0 absorbs) and
/// real size parameter `x` = 2π r n_h/λ in a non-absorbing host
/// ([`Coefficients::efficiencies`]), with qabs from [`absorption_efficiency`]
/// (exactly 0 for a real m, never negative by rounding). What `lucent mie
/// --size-parameter X --relative-index M` prints.
///
/// ```
/// use lucent::optics::mie::efficiencies;
/// use num_complex::Complex64;
/// let q = efficiencies(Complex64::new(1.5, 0.0), 1.0).unwrap();
/// assert!(q.qabs == 0.0 && (q.qext - q.qsca).abs() < 1e-14);
/// ```
pub fn efficiencies(m: Complex64, x: f64) -> Result<Efficiencies, MieError> {
    let x = Complex64::new(x, 0.0);
    let c = Coefficients::compute(m, x)?;
    let qabs = absorption_efficiency(m, x)?;
    Ok(Efficiencies { qabs, ..c.efficiencies(x.re) })
}

/// k₀ r = 2π r/λ after checking r and λ.
fn check_geometry(wavelength_m: f64, radius_m: f64) -> Result<f64, MieError> {
    if !(wavelength_m.is_finite() && wavelength_m > 0.0 && radius_m.is_finite() && radius_m > 0.0) {
        return Err(MieError::Geometry { radius_m, wavelength_m });
    }
    Ok(2.0 * PI * radius_m / wavelength_m)
}

/// Efficiencies (cross sections over πr²) of one sphere of radius
/// `radius_m` and index `n_particle` in a host of index `n_host` at vacuum
/// wavelength `wavelength_m`.
///
/// * Real host: the usual Lorenz–Mie efficiencies ([`Coefficients::efficiencies`]),
///   with qabs from [`absorption_efficiency`] (= qext − qsca, but exactly 0
///   for a clear sphere and never negative by rounding).
/// * Absorbing host: qext and qsca from [`Coefficients::cross_sections`]
///   (Frisvad et al. 2007, qsca with F(α)); qabs from [`absorption_inside`],
///   the power absorbed inside the sphere, so qabs ≥ 0 and qabs = 0 for a
///   non-absorbing sphere. Here qext − qsca ≠ qabs: the apparent extinction
///   also counts the host absorption the sphere displaces (for a small clear
///   sphere qext itself is negative, −(4/3)α in the limit m → 1). qback and g
///   come from the unattenuated sums, qback = |Σ(2n+1)(−1)ⁿ(a_n − b_n)|²/|x|².
///
/// ```
/// use lucent::optics::mie::efficiencies_in_host;
/// use num_complex::Complex64;
/// // A clear 1 µm sphere in a host with κ = 1e-2 at 550 nm.
/// let q = efficiencies_in_host(Complex64::new(1.2, 0.0), Complex64::new(1.5, 1e-2), 550e-9, 1e-6).unwrap();
/// assert!(q.qsca < q.qext && q.qabs == 0.0);
/// assert!((q.qsca - 1.19736).abs() < 1e-5);
/// ```
pub fn efficiencies_in_host(
    n_particle: Complex64,
    n_host: Complex64,
    wavelength_m: f64,
    radius_m: f64,
) -> Result<Efficiencies, MieError> {
    let k0r = check_geometry(wavelength_m, radius_m)?;
    let x = n_host * k0r;
    let c = Coefficients::compute(n_particle / n_host, x)?;
    let geometric = PI * radius_m * radius_m;
    if n_host.im == 0.0 {
        let qabs = absorption_inside(n_particle, n_host, wavelength_m, radius_m)? / geometric;
        return Ok(Efficiencies { qabs, ..c.efficiencies(x.re) });
    }
    let cs = c.cross_sections(wavelength_m, n_host, radius_m);
    let qabs = absorption_inside(n_particle, n_host, wavelength_m, radius_m)? / geometric;
    let t = c.sums();
    Ok(Efficiencies {
        qext: cs.extinction_m2 / geometric,
        qsca: cs.scattering_m2 / geometric,
        qabs,
        qback: t.backscatter.norm_sqr() / x.norm_sqr(),
        g: cs.g,
    })
}

/// D_n(z) = ψ'_n(z)/ψ_n(z) by Lentz's (1976) continued fraction for the
/// Bessel ratio J_{ν−1}(z)/J_ν(z), ν = n + ½:
/// D_n = −n/z + a₁ + 1/(a₂ + 1/(a₃ + …)), a_k = (−1)^{k+1} 2(ν + k − 1)/z,
/// evaluated with the modified Lentz algorithm to 1e-15.
pub fn log_derivative_lentz(z: Complex64, n: usize) -> Complex64 {
    lentz(z, n)
}

/// [`log_derivative_lentz`] for a real or complex argument (real
/// arithmetic throughout for a real `z`).
fn lentz<T: Scalar>(z: T, n: usize) -> T {
    const TINY: f64 = 1e-150;
    let tiny = T::one() * TINY;
    let nu = n as f64 + 0.5;
    let inv_z = z.recip();
    let a = |k: usize| -> T {
        let sign = if k % 2 == 1 { 2.0 } else { -2.0 };
        inv_z * (sign * (nu + k as f64 - 1.0))
    };
    let mut f = a(1);
    if f.l1() < TINY {
        f = tiny;
    }
    let mut c = f;
    let mut d = T::one() * 0.0;
    for k in 2..100_000 {
        let b = a(k);
        d = b + d;
        if d.l1() < TINY {
            d = tiny;
        }
        c = b + c.recip();
        if c.l1() < TINY {
            c = tiny;
        }
        d = d.recip();
        let delta = c * d;
        f = f * delta;
        if (delta - T::one()).l1() < 1e-15 {
            break;
        }
    }
    f - inv_z * n as f64
}

impl Coefficients {
    /// Empty buffers, to be filled by [`Coefficients::recompute`].
    pub fn new() -> Self {
        Self::default()
    }

    /// Coefficients for relative index `m` = n_p/n_h and size parameter
    /// `x` = 2π r n_h/λ.
    pub fn compute(m: Complex64, x: Complex64) -> Result<Self, MieError> {
        let mut c = Self::new();
        c.recompute(m, x)?;
        Ok(c)
    }

    /// Recompute in place for a new sphere (no allocation when the buffers
    /// are already large enough).
    pub fn recompute(&mut self, m: Complex64, x: Complex64) -> Result<(), MieError> {
        let xabs = check_arguments(m, x)?;
        let nstop = wiscombe_terms(xabs);
        if m == Complex64::new(1.0, 0.0) {
            // An index-matched, non-absorbing sphere does not scatter: every
            // a_n, b_n is exactly 0 (the recurrences would leave ~1e-16
            // rounding whose g is meaningless), so q_sca = 0 and g = 0.
            self.ab.clear();
            self.ab.resize(nstop, C2::splat(Complex64::new(0.0, 0.0)));
            self.sums = SeriesSums::default();
            return Ok(());
        }
        let y = m * x;
        // D_n(y) starts from the continued fraction at or just above the
        // turning point |y| and recurs downward. (The fraction converges at
        // any order, in ~|y|^{1/3} terms near the turning point and ever
        // fewer above it; starting higher costs more recurrence steps than
        // it saves fraction terms.)
        let ya = y.norm_sqr().sqrt();
        let n_start = nstop.max(ya.ceil() as usize + 2);

        self.sums = if x.im == 0.0 && m.im == 0.0 {
            // Real host and real particle: D_n(y) is real.
            riccati_real(x.re, nstop, &mut self.riccati_real);
            let d_start = lentz(y.re, n_start);
            coefficients_real(y.re, d_start, n_start, m.re, x.re, &self.riccati_real, &mut self.ab)
        } else if x.im == 0.0 {
            riccati_real(x.re, nstop, &mut self.riccati_real);
            let d_start = lentz(y, n_start);
            coefficients_complex(y, d_start, n_start, m, 1.0 / x.re, &self.riccati_real, &mut self.ab)
        } else {
            riccati_complex(x, nstop, &mut self.riccati);
            let d_start = lentz(y, n_start);
            coefficients_complex(y, d_start, n_start, m, x.inv(), &self.riccati, &mut self.ab)
        };
        // A non-finite a_n or b_n makes the scattering sum (Σ|a|²+|b|²) or,
        // through NaN, every sum non-finite.
        if !self.sums.finite() {
            self.ab.clear();
            self.sums = SeriesSums::default();
            return Err(MieError::Overflow { m, x, imx: x.im.abs() });
        }
        Ok(())
    }

    /// a_n for n = 1 … N (the first item is a_1).
    pub fn a(&self) -> impl ExactSizeIterator<Item = Complex64> + '_ {
        self.ab.iter().map(|z| Complex64::new(z.re.0[0], z.im.0[0]))
    }

    /// b_n for n = 1 … N (the first item is b_1).
    pub fn b(&self) -> impl ExactSizeIterator<Item = Complex64> + '_ {
        self.ab.iter().map(|z| Complex64::new(z.re.0[1], z.im.0[1]))
    }

    /// Number of series terms N.
    pub fn terms(&self) -> usize {
        self.ab.len()
    }

    /// The series sums of one sphere (accumulated while the coefficients
    /// were computed).
    fn sums(&self) -> SeriesSums {
        self.sums
    }

    /// Σ (2n+1)(|a_n|² + |b_n|²).
    pub fn scattering_sum(&self) -> f64 {
        self.sums().scattering
    }

    /// Σ (2n+1)(a_n + b_n) = 2 S₁(0°) = 2 S₂(0°).
    pub fn extinction_sum(&self) -> Complex64 {
        self.sums().extinction
    }

    /// Asymmetry parameter g (mean cosine of the scattering angle), from the
    /// coefficients (Bohren & Huffman eq. 4.62).
    pub fn asymmetry(&self) -> f64 {
        self.sums().g()
    }

    /// Efficiencies in a non-absorbing host, for the real size parameter
    /// `x` the coefficients were computed with.
    pub fn efficiencies(&self, x: f64) -> Efficiencies {
        let t = self.sums();
        let x2 = x * x;
        let qsca = 2.0 / x2 * t.scattering;
        let qext = 2.0 / x2 * t.extinction.re;
        Efficiencies { qext, qsca, qabs: qext - qsca, qback: t.backscatter.norm_sqr() / x2, g: t.g() }
    }

    /// Scattering and extinction cross sections \[m²\] and g of a sphere of
    /// radius `radius_m` in a host of index `n_host` at vacuum wavelength
    /// `wavelength_m` (Frisvad et al. 2007; the coefficients must have been
    /// computed for these): C_s with the attenuation factor F(α), g from the
    /// unattenuated sums.
    pub fn cross_sections(&self, wavelength_m: f64, n_host: Complex64, radius_m: f64) -> CrossSections {
        let t = self.sums();
        let l2 = wavelength_m * wavelength_m / (2.0 * PI);
        let nh2 = n_host * n_host;
        let f = if n_host.im > 0.0 { attenuation(4.0 * PI * radius_m * n_host.im / wavelength_m) } else { 1.0 };
        CrossSections {
            scattering_m2: l2 / n_host.norm_sqr() * t.scattering * f,
            extinction_m2: l2 * (t.extinction / nh2).re,
            g: t.g(),
            attenuation: f,
        }
    }

    /// Amplitude functions (S₁, S₂) at scattering angle cos θ = `mu`
    /// (Bohren & Huffman eq. 4.74, unnormalised).
    pub fn amplitudes(&self, mu: f64) -> (Complex64, Complex64) {
        let mut s1 = Complex64::new(0.0, 0.0);
        let mut s2 = Complex64::new(0.0, 0.0);
        let mut pi_prev = 0.0;
        let mut pi = 1.0;
        for (k, (a, b)) in self.a().zip(self.b()).enumerate() {
            let n = (k + 1) as f64;
            let tau = n * mu * pi - (n + 1.0) * pi_prev;
            let c = (2.0 * n + 1.0) / (n * (n + 1.0));
            s1 += (a * pi + b * tau) * c;
            s2 += (a * tau + b * pi) * c;
            let pi_next = ((2.0 * n + 1.0) * mu * pi - (n + 1.0) * pi_prev) / n;
            pi_prev = pi;
            pi = pi_next;
        }
        (s1, s2)
    }

    /// Adds |S₁(θ_j)|² + |S₂(θ_j)|² · `weight` to `out[j]` for the angles
    /// whose cosines are `mus` (used to build phase tables; no allocation).
    pub fn accumulate_intensity(&self, mus: &[f64], weight: f64, out: &mut [f64]) {
        debug_assert_eq!(mus.len(), out.len());
        for (mu, o) in mus.iter().zip(out.iter_mut()) {
            let (s1, s2) = self.amplitudes(*mu);
            *o += weight * (s1.norm_sqr() + s2.norm_sqr());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(re: f64, im: f64) -> Complex64 {
        Complex64::new(re, im)
    }

    #[test]
    fn index_matched_sphere_does_not_scatter() {
        // m = 1: no scattering and g = 0 (not the g of rounding noise); just
        // off m = 1 the Rayleigh–Gans limit takes over with a real g.
        for x in [0.1, 5.0, 300.0] {
            let q = Coefficients::compute(c(1.0, 0.0), c(x, 0.0)).unwrap().efficiencies(x);
            assert_eq!((q.qext, q.qsca, q.qabs, q.qback, q.g), (0.0, 0.0, 0.0, 0.0, 0.0), "x = {x}");
        }
        let q = Coefficients::compute(c(1.001, 0.0), c(5.0, 0.0)).unwrap().efficiencies(5.0);
        assert!(q.qsca > 0.0 && q.g > 0.5, "{q:?}");
    }

    #[test]
    fn forward_amplitude_obeys_optical_theorem() {
        let x = 12.3;
        let k = Coefficients::compute(c(1.45, 0.01), c(x, 0.0)).unwrap();
        let q = k.efficiencies(x);
        let (s1, s2) = k.amplitudes(1.0);
        assert!((s1 - s2).norm() < 1e-9 * s1.norm());
        assert!((4.0 / (x * x) * s1.re - q.qext).abs() < 1e-10 * q.qext);
    }

    #[test]
    fn rayleigh_limit() {
        // Small sphere: Qsca → 8/3 x⁴ |(m²−1)/(m²+2)|², g → 0.
        let x = 1e-3;
        let m = c(1.5, 0.0);
        let k = Coefficients::compute(m, c(x, 0.0)).unwrap();
        let q = k.efficiencies(x);
        let l = ((m * m - 1.0) / (m * m + 2.0)).norm_sqr();
        let expected = 8.0 / 3.0 * x.powi(4) * l;
        assert!((q.qsca / expected - 1.0).abs() < 1e-5, "{} vs {}", q.qsca, expected);
        assert!(q.g.abs() < 1e-5);
    }

    #[test]
    fn huge_spheres_stay_finite() {
        for &x in &[2000.0, 5000.0, 20000.0] {
            for &m in &[c(1.33, 0.0), c(1.5, 1e-4), c(1.5, 1.0), c(0.75, 0.0), c(10.0, 10.0)] {
                let k = Coefficients::compute(m, c(x, 0.0)).unwrap();
                let q = k.efficiencies(x);
                assert!(q.qext.is_finite() && q.qsca.is_finite() && q.g.is_finite(), "m={m} x={x}");
                // Extinction paradox: Qext → 2 for large spheres.
                assert!((q.qext - 2.0).abs() < 0.05, "m={m} x={x} qext={}", q.qext);
                assert!(q.qsca <= q.qext * (1.0 + 1e-9));
            }
        }
    }

    #[test]
    fn absorbing_host_is_stable_and_tends_to_real_host() {
        let lam = 550e-9;
        let r = 1.1e-6;
        let np = c(1.41, 1e-6);
        let reference = {
            let nh = c(1.5889, 0.0);
            let x = 2.0 * PI * r * nh / lam;
            Coefficients::compute(np / nh, x).unwrap().cross_sections(lam, nh, r)
        };
        for &kh in &[1e-6, 1e-8, 1e-10] {
            let nh = c(1.5889, kh);
            let x = 2.0 * PI * r * nh / lam;
            let cs = Coefficients::compute(np / nh, x).unwrap().cross_sections(lam, nh, r);
            let tol = kh * 1e4;
            assert!((cs.scattering_m2 / reference.scattering_m2 - 1.0).abs() < tol);
            assert!((cs.extinction_m2 / reference.extinction_m2 - 1.0).abs() < tol);
            assert!((cs.g - reference.g).abs() < tol);
        }
        // |x| = 2000 with an absorbing host: no NaN.
        let nh = c(1.5, 1e-3);
        let k = Coefficients::compute(c(1.2, 0.0) / nh, c(2000.0, 2000.0 * 1e-3 / 1.5)).unwrap();
        let cs = k.cross_sections(lam, nh, 2000.0 * lam / (2.0 * PI * 1.5));
        assert!(cs.scattering_m2.is_finite() && cs.extinction_m2.is_finite() && cs.g.is_finite());
    }

    #[test]
    fn attenuation_factor_limits_and_branches() {
        // Closed form where its cancellation is mild (α ≥ 0.3: 1 + (α−1)e^α ≥ 0.05).
        let closed = |a: f64| (-a).exp() * a * a / (2.0 * (1.0 + (a - 1.0) * a.exp()));
        for a in [0.3, 0.5, 0.9, 0.999, 1.0, 1.001, 2.0, 10.0, 50.0] {
            assert!((attenuation(a) / closed(a) - 1.0).abs() < 1e-13, "α = {a}: {} vs {}", attenuation(a), closed(a));
        }
        // Series below α = 1, the overflow-free form above: they meet.
        let (below, above) = (attenuation(1.0 - 1e-12), attenuation(1.0 + 1e-12));
        assert!((below - above).abs() < 1e-12);
        // Small α: F = 1 − 5α/3 + 49α²/36 − …; F = 1 below 1e-6 (docs/method.md#optics).
        for a in [1e-6, 1e-5, 1e-3] {
            let taylor = 1.0 - 5.0 * a / 3.0 + 49.0 / 36.0 * a * a - 391.0 / 540.0 * a * a * a;
            assert!((attenuation(a) - taylor).abs() < a.powi(4) + 2e-16, "α = {a}");
        }
        assert_eq!(attenuation(9.9e-7), 1.0);
        assert_eq!(attenuation(0.0), 1.0);
        // Decreasing, positive, no overflow; nonsense input is NaN.
        let mut last = 1.0;
        for k in 0..400 {
            let a = 1e-6 * 1.1f64.powi(k);
            let f = attenuation(a);
            assert!(f <= last && f >= 0.0, "α = {a}");
            last = f;
        }
        assert_eq!(attenuation(800.0), 0.0);
        assert!(attenuation(-1.0).is_nan() && attenuation(f64::NAN).is_nan());
    }

    #[test]
    fn psi_series_agrees_with_closed_forms() {
        // ψ_0 = sin x, ψ_1 = sin x/x − cos x, ψ_2 = (3/x² − 1) sin x − 3 cos x/x,
        // at x where these closed forms lose little to cancellation.
        for x in [0.5f64, 0.8, 0.999] {
            let mut psi = Vec::new();
            psi_series(x, 2, |_, p| psi.push(p));
            let (s, c) = x.sin_cos();
            let exact = [s, s / x - c, (3.0 / (x * x) - 1.0) * s - 3.0 * c / x];
            let tolerance = [1e-15, 1e-14, 1e-12];
            for n in 0..3 {
                assert!((psi[n] / exact[n] - 1.0).abs() < tolerance[n], "x = {x}, n = {n}: {} vs {}", psi[n], exact[n]);
            }
        }
        // Complex argument: ψ_1(z) against its closed form at |z| = 0.9.
        let z = Complex64::from_polar(0.9, 0.4);
        let mut psi = Vec::new();
        psi_series(z, 1, |_, p| psi.push(p));
        let exact = z.sin() / z - z.cos();
        assert!((psi[1] - exact).norm() < 1e-14 * exact.norm());
    }

    #[test]
    fn tiny_spheres_are_rayleigh_scatterers_down_to_the_minimum() {
        for x in [1e-20, 1e-12, 1e-8] {
            for m in [c(1.5, 0.0), c(0.9, 0.1)] {
                let k = Coefficients::compute(m, c(x, 0.0)).unwrap();
                let q = k.efficiencies(x);
                let l = (m * m - 1.0) / (m * m + 2.0);
                let rayleigh_sca = 8.0 / 3.0 * x.powi(4) * l.norm_sqr();
                assert!((q.qsca / rayleigh_sca - 1.0).abs() < 1e-12, "x={x} m={m}: {} vs {rayleigh_sca}", q.qsca);
                if m.im > 0.0 {
                    // Absorption dominates: qext → 4x Im((m²−1)/(m²+2)).
                    assert!((q.qext / (4.0 * x * l.im) - 1.0).abs() < 1e-12, "x={x} m={m}");
                }
                assert!(q.g.abs() < 1e-12 && q.g.is_finite());
            }
        }
        assert!(matches!(Coefficients::compute(c(1.5, 0.0), c(1e-21, 0.0)), Err(MieError::TooSmall(_))));
    }

    #[test]
    fn small_clear_sphere_in_an_absorbing_host_has_negative_apparent_extinction() {
        // Rayleigh limit of C_t = λ²/(2π) Re Σ(2n+1)(a_n+b_n)/n_h²:
        // C_t = (8π² r³/λ) Im(n_h (m²−1)/(m²+2)), which tends to the host
        // absorption of the sphere's volume with a minus sign as m → 1.
        let (lam, r) = (500e-9, 1e-11);
        let nh = c(1.5, 1e-3);
        for np in [c(1.5, 0.0), c(1.3, 0.0), c(1.5, 1e-4)] {
            let m = np / nh;
            let x = nh * (2.0 * PI * r / lam);
            let cs = Coefficients::compute(m, x).unwrap().cross_sections(lam, nh, r);
            let l = (m * m - 1.0) / (m * m + 2.0);
            let rayleigh = 8.0 * PI * PI * r.powi(3) / lam * (nh * l).im;
            assert!((cs.extinction_m2 / rayleigh - 1.0).abs() < 1e-6, "np={np}: {} vs {rayleigh}", cs.extinction_m2);
        }
        let m = c(1.5, 0.0) / nh;
        let x = nh * (2.0 * PI * r / lam);
        let cs = Coefficients::compute(m, x).unwrap().cross_sections(lam, nh, r);
        let displaced = 4.0 * PI * nh.im / lam * (4.0 / 3.0 * PI * r.powi(3));
        assert!(
            cs.extinction_m2 < 0.0 && (cs.extinction_m2 / -displaced - 1.0).abs() < 5e-3,
            "{} vs {}",
            cs.extinction_m2,
            -displaced
        );
        // ...while the power absorbed inside the clear sphere is zero.
        assert_eq!(absorption_inside(c(1.5, 0.0), nh, lam, r).unwrap(), 0.0);
    }

    #[test]
    fn absorption_inside_is_extinction_minus_scattering_in_a_real_host() {
        for (m, x) in [(c(1.5, 0.1), 3.0), (c(2.5, 1.0), 40.0), (c(1.33, 1e-6), 0.7), (c(0.9, 0.05), 150.0)] {
            let q = Coefficients::compute(m, c(x, 0.0)).unwrap().efficiencies(x);
            let inside = absorption_efficiency(m, c(x, 0.0)).unwrap();
            assert!((inside - q.qabs).abs() < 1e-12 * q.qext, "m={m} x={x}: {inside} vs {}", q.qabs);
        }
        assert_eq!(absorption_efficiency(c(1.5, 0.0), c(3.0, 0.0)).unwrap(), 0.0);
        // A very weakly absorbing sphere: qext − qsca has cancelled away,
        // the internal form keeps Q_abs ∝ κ.
        let a = absorption_efficiency(c(1.5, 1e-12), c(3.0, 0.0)).unwrap();
        let b = absorption_efficiency(c(1.5, 2e-12), c(3.0, 0.0)).unwrap();
        assert!(a > 0.0 && (b / a - 2.0).abs() < 1e-6, "{a} {b}");
    }

    #[test]
    fn bad_input_is_an_error() {
        assert!(Coefficients::compute(c(1.5, 0.0), c(0.0, 0.0)).is_err());
        assert!(Coefficients::compute(c(1.5, 0.0), c(f64::NAN, 0.0)).is_err());
        assert!(Coefficients::compute(c(f64::INFINITY, 0.0), c(1.0, 0.0)).is_err());
        assert!(Coefficients::compute(c(1.5, 0.0), c(-1.0, 0.0)).is_err());
        assert!(Coefficients::compute(c(1.5, 0.0), c(1e6, 0.0)).is_err());
    }

    #[test]
    fn continued_fraction_matches_long_downward_recurrence() {
        // Downward recurrence from far above n (error damped away) versus Lentz.
        for &z in &[c(1.0, 0.0), c(150.0, 0.0), c(1370.0, 0.0), c(30.0, 20.0), c(100.0, 1e-4), c(0.05, 0.0)] {
            for &n in &[1usize, 10, 120, 588] {
                let start = n + 20_000;
                let mut d = Complex64::new(0.0, 0.0);
                for k in (n + 1..=start).rev() {
                    let kz = z.inv() * k as f64;
                    d = kz - (d + kz).inv();
                }
                let lentz = log_derivative_lentz(z, n);
                assert!((lentz - d).norm() <= 1e-11 * d.norm().max(1.0), "z={z} n={n}: {lentz} vs {d}");
            }
        }
    }

    #[test]
    fn recompute_reuses_buffers() {
        let mut k = Coefficients::compute(c(1.5, 0.0), c(100.0, 0.0)).unwrap();
        let cap = k.ab.capacity();
        k.recompute(c(1.5, 0.0), c(10.0, 0.0)).unwrap();
        assert_eq!(k.ab.capacity(), cap);
        let fresh = Coefficients::compute(c(1.5, 0.0), c(10.0, 0.0)).unwrap();
        assert!(fresh.a().eq(k.a()) && fresh.b().eq(k.b()));
    }
}
