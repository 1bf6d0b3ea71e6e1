//! Phase functions of the scattering medium: evaluation and importance
//! sampling (docs/method.md §1 and §3).
//!
//! # What is computed
//!
//! A phase function p(cos θ) is the angular distribution of singly scattered
//! light, as a density **per steradian** over the unit sphere of outgoing
//! directions: ∫₄π p dω = 2π ∫₋₁¹ p(μ) dμ = 1. θ is the angle between the
//! propagation directions before and after scattering, μ = cos θ, so μ = 1 is
//! straight on (forward) and μ = −1 is back towards the source. Every function
//! is unpolarised and rotationally symmetric about the incident direction, so
//! a direction is a cosine μ plus an azimuth φ uniform on [0, 2π).
//!
//! [`Phase`] is the closed set used by the transport code (dispatch by `match`,
//! no trait objects): for each variant,
//!
//! * [`Phase::eval`] gives p(μ) in sr⁻¹;
//! * [`Phase::sample_cos_theta`] maps u ∈ [0, 1) to μ by inverting the CDF, and
//!   the density of the result **is exactly** `eval` (up to rounding), so a
//!   sampled scattering event has weight 1;
//! * [`Phase::mean_cosine`] gives the asymmetry g = 2π ∫ μ p(μ) dμ;
//! * [`Phase::sample_direction`] turns (u₁, u₂) into a unit direction about a
//!   given propagation direction, with the tangent frame of Duff et al.,
//!   "Building an orthonormal basis, revisited", JCGT 6(1), 2017
//!   ([`orthonormal_basis`]). Everything is `f64` and allocation-free.
//!
//! # Henyey–Greenstein
//!
//! Henyey & Greenstein, "Diffuse radiation in the galaxy", ApJ 93, 70 (1941):
//!
//! p(μ) = (1 − g²) / (4π (1 + g² − 2gμ)^{3/2}),  −1 < g < 1,
//!
//! whose mean cosine is g (g > 0 forward, g < 0 backward, g = 0 isotropic).
//! The denominator is computed as (1 ∓ g)² ± 2g(1 ∓ μ) (sign of g), a sum of
//! two non-negative terms, so strongly peaked functions (g → ±1) lose no
//! digits. Sampling inverts the CDF analytically,
//!
//! μ = (1 + g² − ((1 − g²)/(1 − g + 2gu))²) / (2g),
//!
//! which is increasing in u (u = 0 → μ = −1, u = 1 → μ = 1). For |g| < 10⁻³,
//! where this divides a cancelling difference by g, the algebraically
//! identical form μ = (t + g(t²+3)/2 + g²t + g³(t²−1)/2) / (1 + gt)²,
//! t = 2u − 1, is used instead: it is exactly the isotropic μ = 2u − 1 at
//! g = 0 and keeps `pdf == eval` for tiny non-zero g (rather than switching to
//! the isotropic function, which would bias the sampled mean cosine by g).
//!
//! # Tabulated functions (Lorenz–Mie)
//!
//! [`PhaseTable`] holds N values at nodes **uniform in θ**, θᵢ = iπ/(N − 1),
//! i = 0 … N − 1 (lucent's Mie tables use N = 4096, node spacing 0.044°).
//! Uniform θ rather than uniform μ because Mie functions of µm particles have
//! forward lobes ~0.5° wide (g ≈ 0.97): uniform-μ nodes would put a handful of
//! nodes into the lobe.
//!
//! The represented function is **piecewise linear in μ**: between μᵢ₊₁ = cos θᵢ₊₁
//! and μᵢ = cos θᵢ it interpolates the node values linearly in μ. That choice
//! makes everything exact for the represented function:
//!
//! * its integral is a trapezoid sum in μ, 2π Σ (μᵢ − μᵢ₊₁)(pᵢ + pᵢ₊₁)/2, used
//!   to normalise the table to exactly 1 on construction;
//! * its CDF at the nodes is the running sum of those trapezoids; sampling
//!   picks a bin by binary search of that CDF and then inverts the within-bin
//!   CDF, a quadratic in μ, in closed form (the cancellation-free root
//!   s = u′(a + b) / (a + √(a²(1 − u′) + b²u′)), which also covers the
//!   constant case a = b and zero end values);
//! * its mean cosine is a Simpson sum per bin (exact for a quadratic
//!   integrand).
//!
//! [`PhaseTable::eval`] finds the bin in O(1) from θ = acos μ, corrects an
//! off-by-one from rounding against the exact node cosines, and interpolates
//! linearly in μ — so it returns exactly the density the sampler draws from.
//! At a node it returns the normalised node value exactly.
//!
//! ```
//! use lucent_render::phase::{Phase, PhaseTable};
//! // Isotropic scattering: 1/(4π) = 0.0795774715… per steradian.
//! let iso = Phase::henyey_greenstein(0.0).unwrap();
//! assert!((iso.eval(0.3) - 0.079_577_471_545_947_67).abs() < 1e-15);
//! // HG with g = 0.5, straight forward: (1 + g)/(4π(1 − g)²) = 6/(4π) = 0.477464829…
//! let hg = Phase::HenyeyGreenstein { g: 0.5 };
//! assert!((hg.eval(1.0) - 0.477_464_829_275_686).abs() < 1e-12);
//! // A table with any scale is normalised: constant values become 1/(4π).
//! let table = PhaseTable::from_theta_samples(&[7.0; 5]).unwrap();
//! assert!((table.eval(-0.2) - 0.079_577_471_545_947_67).abs() < 1e-15);
//! ```

use std::f64::consts::PI;

use thiserror::Error;

/// 1/(4π), the isotropic phase function, sr⁻¹.
const INV_4PI: f64 = 0.25 * std::f64::consts::FRAC_1_PI;
/// The largest double below 1 (1 − 2⁻⁵³).
const ONE_MINUS_EPSILON: f64 = 1.0 - f64::EPSILON / 2.0;
/// Below this |g| the HG sampler uses the cancellation-free rational form.
const HG_SMALL_G: f64 = 1e-3;

/// Why a phase function could not be built.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum PhaseError {
    /// A table needs at least the two end nodes θ = 0 and θ = π.
    #[error("a phase table needs at least 2 samples in θ (θ = 0 and θ = π), got {got}")]
    TooFewSamples { got: usize },
    /// A node value is NaN or infinite.
    #[error("phase table value at index {index} is not finite: {value}")]
    NotFinite { index: usize, value: f64 },
    /// A node value is negative.
    #[error("phase table value at index {index} is negative: {value}")]
    Negative { index: usize, value: f64 },
    /// All node values are zero, so the table cannot be normalised.
    #[error("phase table is zero everywhere and cannot be normalised")]
    AllZero,
    /// The Henyey–Greenstein asymmetry must be finite with |g| < 1.
    #[error("Henyey–Greenstein asymmetry g must be finite with -1 < g < 1, got {g}")]
    InvalidAsymmetry { g: f64 },
}

/// A phase function: the closed set the transport code dispatches over.
#[derive(Debug, Clone, PartialEq)]
pub enum Phase {
    /// Henyey–Greenstein (1941) with asymmetry `g`, −1 < g < 1, g > 0 forward.
    /// Build it with [`Phase::henyey_greenstein`] to have `g` checked.
    HenyeyGreenstein { g: f64 },
    /// A tabulated function, e.g. from Lorenz–Mie theory.
    Tabulated(PhaseTable),
}

impl From<PhaseTable> for Phase {
    fn from(table: PhaseTable) -> Self {
        Phase::Tabulated(table)
    }
}

impl Phase {
    /// Henyey–Greenstein with asymmetry `g`, checked to be finite with |g| < 1.
    pub fn henyey_greenstein(g: f64) -> Result<Self, PhaseError> {
        if g.is_finite() && g.abs() < 1.0 {
            Ok(Phase::HenyeyGreenstein { g })
        } else {
            Err(PhaseError::InvalidAsymmetry { g })
        }
    }

    /// p(cos θ) per steradian, θ the angle between the propagation directions
    /// before and after scattering. Integrates to 1 over the sphere.
    #[inline]
    pub fn eval(&self, cos_theta: f64) -> f64 {
        match self {
            Phase::HenyeyGreenstein { g } => hg_eval(*g, cos_theta),
            Phase::Tabulated(t) => t.eval(cos_theta),
        }
    }

    /// cos θ drawn with density 2π·[`eval`](Self::eval) in cos θ, from
    /// u ∈ [0, 1) (clamped; NaN gives NaN). Non-decreasing in u.
    #[inline]
    pub fn sample_cos_theta(&self, u: f64) -> f64 {
        match self {
            Phase::HenyeyGreenstein { g } => hg_sample_cos_theta(*g, u),
            Phase::Tabulated(t) => t.sample_cos_theta(u),
        }
    }

    /// The asymmetry parameter g = ⟨cos θ⟩.
    #[inline]
    pub fn mean_cosine(&self) -> f64 {
        match self {
            Phase::HenyeyGreenstein { g } => *g,
            Phase::Tabulated(t) => t.mean_cosine(),
        }
    }

    /// A new propagation direction after scattering a photon travelling along
    /// `incident` (a unit vector): cos θ = [`sample_cos_theta`](Self::sample_cos_theta)`(u1)`
    /// from `incident`, azimuth φ = 2π·`u2` in the frame of
    /// [`orthonormal_basis`]`(incident)`. The result is a unit vector (to
    /// rounding) whose solid-angle density is `eval(result · incident)`.
    #[inline]
    pub fn sample_direction(&self, incident: [f64; 3], u1: f64, u2: f64) -> [f64; 3] {
        self.sample_angles(u1, u2).turn(incident)
    }

    /// The scattering angles of [`sample_direction`](Self::sample_direction)
    /// alone: they depend on the random numbers only, so a simulator can draw
    /// them before it knows the incident direction (their latency then
    /// overlaps other work).
    #[inline]
    pub fn sample_angles(&self, u1: f64, u2: f64) -> ScatteringAngles {
        ScatteringAngles::at(self.sample_cos_theta(u1), u2)
    }
}

/// p_k(cos θ) per steradian of three phase functions at one angle (a
/// medium's R, G and B bands), 0 where `active[k]` is false: the same values,
/// bit for bit, as three [`Phase::eval`] calls, with one bin search when the
/// functions are tables of the same length (their nodes are then the same).
///
/// ```
/// use lucent_render::phase::{eval_each, Phase, PhaseTable};
/// let a = Phase::from(PhaseTable::from_theta_samples(&[3.0, 2.0, 1.0]).unwrap());
/// let b = Phase::from(PhaseTable::from_theta_samples(&[1.0, 1.0, 2.0]).unwrap());
/// let p = eval_each([&a, &b, &a], [true, true, false], 0.3);
/// assert_eq!(p, [a.eval(0.3), b.eval(0.3), 0.0]);
/// ```
#[inline]
pub fn eval_each(phases: [&Phase; 3], active: [bool; 3], cos_theta: f64) -> [f64; 3] {
    if let [Phase::Tabulated(t0), Phase::Tabulated(t1), Phase::Tabulated(t2)] = phases
        && t1.len() == t0.len()
        && t2.len() == t0.len()
    {
        let (i, s) = t0.position(cos_theta);
        let tables = [t0, t1, t2];
        return std::array::from_fn(|k| if active[k] { tables[k].value_at(i, s) } else { 0.0 });
    }
    std::array::from_fn(|k| if active[k] { phases[k].eval(cos_theta) } else { 0.0 })
}

/// Polar angle θ from the incident direction and azimuth φ about it, as
/// cosines and sines.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScatteringAngles {
    pub cos_theta: f64,
    pub sin_theta: f64,
    pub cos_phi: f64,
    pub sin_phi: f64,
}

impl ScatteringAngles {
    /// Polar angle θ at cos θ = `cos_theta` ∈ [−1, 1] and azimuth φ = 2π·`u`.
    #[inline]
    pub fn at(cos_theta: f64, u: f64) -> Self {
        let sin_theta = ((1.0 - cos_theta) * (1.0 + cos_theta)).max(0.0).sqrt();
        let (sin_phi, cos_phi) = sin_cos_turns(u);
        ScatteringAngles { cos_theta, sin_theta, cos_phi, sin_phi }
    }

    /// The direction at these angles from the unit vector `incident`, φ
    /// measured in the frame of [`orthonormal_basis`]`(incident)`.
    #[inline]
    pub fn turn(&self, incident: [f64; 3]) -> [f64; 3] {
        let (t, b) = orthonormal_basis(incident);
        let (x, y) = (self.sin_theta * self.cos_phi, self.sin_theta * self.sin_phi);
        let c = self.cos_theta;
        [
            x * t[0] + y * b[0] + c * incident[0],
            x * t[1] + y * b[1] + c * incident[1],
            x * t[2] + y * b[2] + c * incident[2],
        ]
    }
}

/// (sin 2πu, cos 2πu) for u ∈ [0, 1) without libm: the nearest lower entry
/// of a 1024-entry table of (sin, cos) at multiples of 2π/1024, rotated by
/// the remaining angle δ < 2π/1024 ≈ 0.0061 through its Taylor polynomials
/// to δ⁵ and δ⁶ (truncation error < 1e-19); error < 1e-15. Direction
/// sampling spent a quarter of the slab simulator's time in libm's
/// `sin_cos`, and still a third in a degree-12 polynomial; this is a load
/// and a dozen operations, with no branch.
#[inline]
pub fn sin_cos_turns(u: f64) -> (f64, f64) {
    let t = u.clamp(0.0, 1.0) * TURN_TABLE_LEN as f64;
    let k = (t as usize).min(TURN_TABLE_LEN - 1);
    let d = (t - k as f64) * (std::f64::consts::TAU / TURN_TABLE_LEN as f64);
    let d2 = d * d;
    // The constant divisions as products (as the lane form does).
    let sd = d * (1.0 - d2 * (1.0 / 6.0) * (1.0 - d2 * (1.0 / 20.0)));
    let cd = 1.0 - d2 * 0.5 * (1.0 - d2 * (1.0 / 12.0) * (1.0 - d2 * (1.0 / 30.0)));
    let [sk, ck] = TURN_TABLE[k];
    (sk * cd + ck * sd, ck * cd - sk * sd)
}

const TURN_TABLE_LEN: usize = 1024;

/// (sin, cos) of 2πk/1024, k = 0 … 1023, evaluated at compile time.
static TURN_TABLE: [[f64; 2]; TURN_TABLE_LEN] = turn_table();

/// sin and cos of a ∈ [0, π/4] by Taylor series to a²¹ (truncation error
/// < 1e-25, so the result is within an ulp or two).
const fn taylor_sin_cos(a: f64) -> [f64; 2] {
    let a2 = a * a;
    let (mut s, mut c) = (0.0, 0.0);
    let mut k = 11;
    while k > 0 {
        // Horner from the top: s = a(1 − a²/(2·3)(1 − a²/(4·5)(…))), c likewise.
        let ks = (2 * k) as f64 * (2 * k + 1) as f64;
        let kc = (2 * k - 1) as f64 * (2 * k) as f64;
        s = 1.0 - a2 / ks * s;
        c = 1.0 - a2 / kc * c;
        k -= 1;
    }
    [a * s, c]
}

const fn turn_table() -> [[f64; 2]; TURN_TABLE_LEN] {
    let mut t = [[0.0; 2]; TURN_TABLE_LEN];
    let quarter = TURN_TABLE_LEN / 4;
    let step = std::f64::consts::PI / (2 * quarter) as f64;
    let mut k = 0;
    while k < TURN_TABLE_LEN {
        let (q, j) = (k / quarter, k % quarter);
        // Angle within the quadrant, reflected into [0, π/4].
        let [s, c] = if 2 * j <= quarter {
            taylor_sin_cos(j as f64 * step)
        } else {
            let [s, c] = taylor_sin_cos((quarter - j) as f64 * step);
            [c, s]
        };
        t[k] = match q {
            0 => [s, c],
            1 => [c, -s],
            2 => [-s, -c],
            _ => [-c, s],
        };
        k += 1;
    }
    t
}

/// Two unit vectors (t, b) such that (t, b, n) is a right-handed orthonormal
/// frame, for a unit `n`. Branch-free apart from the sign of n_z and without a
/// singularity anywhere on the sphere (Duff, Burgess, Christensen, Hery,
/// Kensler, Liani, Villemin, "Building an orthonormal basis, revisited",
/// JCGT 6(1), 2017, listing 3); `copysign` makes n_z = −0 behave like −1.
#[inline]
pub fn orthonormal_basis(n: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let sign = 1.0_f64.copysign(n[2]);
    let a = -1.0 / (sign + n[2]);
    let b = n[0] * n[1] * a;
    ([1.0 + sign * n[0] * n[0] * a, sign * b, -sign * n[0]], [b, sign + n[1] * n[1] * a, -n[1]])
}

/// Henyey–Greenstein p(μ), sr⁻¹. The denominator 1 + g² − 2gμ is formed as
/// (1 − g)² + 2g(1 − μ) for g ≥ 0 and (1 + g)² − 2g(1 + μ) for g < 0: both
/// terms are non-negative, so nothing cancels near the peak.
#[inline]
fn hg_eval(g: f64, cos_theta: f64) -> f64 {
    let mu = cos_theta.clamp(-1.0, 1.0);
    let d = if g >= 0.0 {
        (1.0 - g) * (1.0 - g) + 2.0 * g * (1.0 - mu)
    } else {
        (1.0 + g) * (1.0 + g) - 2.0 * g * (1.0 + mu)
    };
    INV_4PI * (1.0 - g) * (1.0 + g) / (d * d.sqrt())
}

/// HG CDF inversion, μ non-decreasing in u (u = 0 → −1, u = 1 → 1).
#[inline]
fn hg_sample_cos_theta(g: f64, u: f64) -> f64 {
    let u = u.clamp(0.0, 1.0);
    let mu = if g.abs() < HG_SMALL_G {
        hg_sample_small_g(g, u)
    } else {
        let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
        // × 0.5/g rather than ÷ 2g: the factor is loop-invariant in the
        // simulators and hoisted, a division per sample is not.
        (1.0 + g * g - s * s) * (0.5 / g)
    };
    mu.clamp(-1.0, 1.0)
}

/// The HG inversion rewritten without the division by g: with t = 2u − 1,
/// μ = (t + g(t² + 3)/2 + g²t + g³(t² − 1)/2) / (1 + gt)². Exact algebra, not
/// a series; at g = 0 it is μ = 2u − 1.
#[inline]
fn hg_sample_small_g(g: f64, u: f64) -> f64 {
    let t = 2.0 * u - 1.0;
    let t2 = t * t;
    let d = 1.0 + g * t;
    (t + g * (0.5 * (t2 + 3.0) + g * (t + 0.5 * g * (t2 - 1.0)))) / (d * d)
}

/// Cells of a table's sampling guide (a power of two, so that u·G is exact).
const GUIDE_CELLS: usize = 4096;

/// acos μ for μ ∈ [−1, 1] within 3e-8 rad (Abramowitz & Stegun 4.4.46,
/// error ≤ 2e-8 on [0, 1], and acos(−x) = π − acos x): a bin guess for
/// [`PhaseTable::eval`], which then walks to the exact bin. libm's acos took
/// most of the time of a table evaluation.
#[inline]
fn acos_guess(mu: f64) -> f64 {
    let x = mu.abs();
    let p = ((((((-0.001_262_491_1 * x + 0.006_670_090_1) * x - 0.017_088_125_6) * x + 0.030_891_881) * x
        - 0.050_174_304_6)
        * x
        + 0.088_978_987_4)
        * x
        - 0.214_598_801_6)
        * x
        + 1.570_796_305;
    let a = (1.0 - x).sqrt() * p;
    if mu < 0.0 {
        PI - a
    } else {
        a
    }
}

/// A tabulated phase function on nodes uniform in θ, piecewise linear in
/// μ = cos θ between nodes, normalised to 1 over the sphere (see the module
/// documentation for the representation and why it is exact).
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseTable {
    /// μᵢ = cos θᵢ, θᵢ = iπ/(N − 1); μ₀ = 1, μ_{N−1} = −1, decreasing.
    mu: Vec<f64>,
    /// Normalised node values pᵢ, sr⁻¹.
    values: Vec<f64>,
    /// cdf[i] = P(μ ≤ μᵢ) = P(θ ≥ θᵢ); cdf[0] = 1, cdf[N − 1] = 0.
    cdf: Vec<f64>,
    /// (N − 1)/π, nodes per radian.
    inv_dtheta: f64,
    /// guide[j] = the first k with cdf[k] ≤ j/G, j = 0 … G (G =
    /// `GUIDE_CELLS`): sampling with u ∈ [j/G, (j+1)/G) searches only
    /// guide[j+1] ..= guide[j] (Chen & Asau's guide table).
    guide: Vec<u32>,
    /// 2π ∫ μ p(μ) dμ of the represented function.
    mean_cosine: f64,
}

impl PhaseTable {
    /// `values[i]` = phase function (any positive scale, per steradian) at
    /// θᵢ = i·π/(N − 1), i = 0 … N − 1 (N ≥ 2; lucent's default is N = 4096).
    /// Normalised on construction so that the piecewise-linear-in-μ function
    /// through the nodes integrates to exactly 1 over the sphere.
    ///
    /// Errors: fewer than 2 values, a NaN/infinite or negative value, or all
    /// values zero.
    pub fn from_theta_samples(values: &[f64]) -> Result<Self, PhaseError> {
        let n = values.len();
        if n < 2 {
            return Err(PhaseError::TooFewSamples { got: n });
        }
        let mut vmax = 0.0_f64;
        for (index, &value) in values.iter().enumerate() {
            if !value.is_finite() {
                return Err(PhaseError::NotFinite { index, value });
            }
            if value < 0.0 {
                return Err(PhaseError::Negative { index, value });
            }
            vmax = vmax.max(value);
        }
        if vmax == 0.0 {
            return Err(PhaseError::AllZero);
        }

        // Node cosines; the end nodes exactly ±1.
        let last = (n - 1) as f64;
        let mut mu: Vec<f64> = (0..n).map(|i| (i as f64 * PI / last).cos()).collect();
        mu[0] = 1.0;
        mu[n - 1] = -1.0;

        // Scale by the maximum first so that no sum can overflow, then
        // accumulate the trapezoids in μ from the back (θ = π, μ = −1).
        let mut values: Vec<f64> = values.iter().map(|v| v / vmax).collect();
        let mut cdf = vec![0.0; n];
        let mut acc = 0.0;
        for i in (0..n - 1).rev() {
            acc += (mu[i] - mu[i + 1]) * 0.5 * (values[i] + values[i + 1]);
            cdf[i] = acc;
        }
        let total = acc; // ∫ p dμ of the scaled table
        if total <= 0.0 {
            // Only reachable when every non-zero node borders zero-width bins
            // (N so large that neighbouring cosines round to the same double).
            return Err(PhaseError::AllZero);
        }
        for c in &mut cdf {
            *c /= total;
        }
        cdf[0] = 1.0;
        let norm = 1.0 / (2.0 * PI * total);
        for v in &mut values {
            *v *= norm;
        }

        // Mean cosine: Simpson per bin, exact for μ·(linear in μ).
        let mut m = 0.0;
        for i in 0..n - 1 {
            let (hi, lo) = (mu[i], mu[i + 1]);
            let (b, a) = (values[i], values[i + 1]);
            let mid = 0.5 * (hi + lo);
            m += (hi - lo) / 6.0 * (lo * a + 2.0 * mid * (a + b) + hi * b);
        }

        let guide = (0..=GUIDE_CELLS)
            .map(|j| {
                let u = j as f64 / GUIDE_CELLS as f64;
                u32::try_from(cdf.partition_point(|&c| c > u)).expect("tables longer than 2³² nodes are not made")
            })
            .collect();
        Ok(Self { mu, values, cdf, guide, inv_dtheta: last / PI, mean_cosine: 2.0 * PI * m })
    }

    /// Number of nodes N.
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// Always false: a table has at least two nodes.
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// The normalised node values pᵢ at θᵢ = iπ/(N − 1), per steradian.
    pub fn theta_samples(&self) -> &[f64] {
        &self.values
    }

    /// The node cosines μᵢ = cos θᵢ (μ₀ = 1, μ_{N−1} = −1).
    pub fn node_cos_theta(&self) -> &[f64] {
        &self.mu
    }

    /// The bin i with μ_{i+1} ≤ μ ≤ μ_i, for μ ∈ [−1, 1] (NaN: bin 0).
    #[inline]
    fn bin_of_cos(&self, mu: f64) -> usize {
        let last_bin = self.mu.len() - 2;
        // O(1) guess from θ (NaN → 0 by the saturating cast) ...
        let mut i = ((acos_guess(mu) * self.inv_dtheta) as usize).min(last_bin);
        // ... then make μ_{i+1} ≤ μ ≤ μ_i hold exactly (the guess is at most
        // a bin off).
        while i > 0 && mu > self.mu[i] {
            i -= 1;
        }
        while i < last_bin && mu < self.mu[i + 1] {
            i += 1;
        }
        i
    }

    /// The bin i with cdf[i+1] ≤ u < cdf[i], for u ∈ [0, 1): it has positive
    /// probability. (cdf is non-increasing with cdf[0] = 1 > u ≥ 0 =
    /// cdf[N−1], so the first k with cdf[k] ≤ u lies in 1..=N−1; i = k − 1.)
    #[inline]
    fn bin_of_cdf(&self, u: f64) -> usize {
        // The guide table narrows the search to the bins that u's cell can
        // reach; the result is the same as a search over all of cdf.
        let j = (u * GUIDE_CELLS as f64) as usize;
        let (lo, hi) = (self.guide[j + 1] as usize, self.guide[j] as usize);
        lo + self.cdf[lo..=hi].partition_point(|&c| c > u) - 1
    }

    /// p(cos θ) per steradian: linear interpolation in μ between the two
    /// nodes around θ = acos μ. μ is clamped to [−1, 1]; NaN gives NaN.
    #[inline]
    pub fn eval(&self, cos_theta: f64) -> f64 {
        let (i, s) = self.position(cos_theta);
        self.value_at(i, s)
    }

    /// The bin i of cos θ (clamped to [−1, 1]) and its fraction s from
    /// node i + 1 (s = 0) to node i (s = 1): the same for every table of
    /// this length.
    #[inline]
    fn position(&self, cos_theta: f64) -> (usize, f64) {
        let mu = cos_theta.clamp(-1.0, 1.0);
        let i = self.bin_of_cos(mu);
        let (hi, lo) = (self.mu[i], self.mu[i + 1]);
        let width = hi - lo;
        (i, if width > 0.0 { (mu - lo) / width } else { 0.5 })
    }

    /// The value at [`PhaseTable::position`]'s (i, s).
    #[inline]
    fn value_at(&self, i: usize, s: f64) -> f64 {
        (1.0 - s) * self.values[i + 1] + s * self.values[i]
    }

    /// cos θ with density 2π·[`eval`](Self::eval) in cos θ, from u ∈ [0, 1)
    /// (clamped; NaN gives NaN). Non-decreasing in u: u = 0 gives −1 (or the
    /// lowest μ with non-zero density).
    #[inline]
    pub fn sample_cos_theta(&self, u: f64) -> f64 {
        if u.is_nan() {
            return f64::NAN;
        }
        let u = u.clamp(0.0, ONE_MINUS_EPSILON);
        let i = self.bin_of_cdf(u);
        let (c_lo, c_hi) = (self.cdf[i + 1], self.cdf[i]);
        let up = ((u - c_lo) / (c_hi - c_lo)).clamp(0.0, 1.0);
        // Within the bin the density is a + (b − a)s, s = (μ − μ_{i+1})/Δμ.
        // Its CDF a·s + (b − a)s²/2 = u′(a + b)/2 has the stable root below.
        let (a, b) = (self.values[i + 1], self.values[i]);
        let denom = a + (a * a * (1.0 - up) + b * b * up).sqrt();
        let s = if denom > 0.0 { (up * (a + b) / denom).min(1.0) } else { 0.0 };
        let (lo, hi) = (self.mu[i + 1], self.mu[i]);
        (lo + s * (hi - lo)).min(hi)
    }

    /// The asymmetry parameter g = 2π ∫ μ p(μ) dμ of the represented function
    /// (exact, computed on construction).
    #[inline]
    pub fn mean_cosine(&self) -> f64 {
        self.mean_cosine
    }

    /// Whether every node has the same value: the isotropic function
    /// 1/(4π).
    pub fn is_constant(&self) -> bool {
        self.values.iter().all(|&v| v == self.values[0])
    }

    /// The table with its forward peak cut flat, for the similarity
    /// relation of [`crate::medium::Medium::similar`]: the node values at
    /// θ < θ_k replaced by one value c, everything at θ ≥ θ_k kept. c is
    /// chosen so that the transport moment ∫ (1 − μ) p dω of the cut part
    /// is kept. The result, normalised, has mass M = 1 − (what the cut
    /// removed) before normalisation, so a medium that scatters M times as
    /// often with it (μ_s′ = M μ_s) scatters exactly as often as before into
    /// every angle θ ≥ θ_k and has the same reduced coefficient
    /// μ_s′(1 − g′) = μ_s(1 − g): its walk replaces many small turns inside
    /// the peak by fewer turns of up to θ_k. θ_k is the smallest node angle
    /// at which the result's mean cosine g′ = 1 − (1 − g)/M is at most
    /// `g_max` (a fully flat table has g′ = 0, so any `g_max` ≥ 0 is
    /// reached). Returns a clone when g ≤ `g_max` already.
    pub fn flat_topped(&self, g_max: f64) -> PhaseTable {
        if self.mean_cosine <= g_max {
            return self.clone();
        }
        let (mu, p) = (&self.mu, &self.values);
        let n = p.len();
        // ∫ p dμ and ∫ (1 − μ) p dμ over bin i (μ_{i+1} … μ_i) of the
        // function linear from `at_lo` to `at_hi`: trapezoid and Simpson,
        // exact for these (at most quadratic) integrands.
        let bin = |i: usize, at_lo: f64, at_hi: f64| {
            let (hi, lo) = (mu[i], mu[i + 1]);
            let mid = 0.5 * (hi + lo);
            let zeroth = (hi - lo) * 0.5 * (at_lo + at_hi);
            let transport =
                (hi - lo) / 6.0 * ((1.0 - lo) * at_lo + 4.0 * (1.0 - mid) * 0.5 * (at_lo + at_hi) + (1.0 - hi) * at_hi);
            (zeroth, transport)
        };
        let total_transport: f64 = (0..n - 1).map(|i| bin(i, p[i + 1], p[i]).1).sum();
        let total_mass: f64 = (0..n - 1).map(|i| bin(i, p[i + 1], p[i]).0).sum();
        // Walk k upwards keeping: the original mass and transport of bins
        // k.., the original transport of bins < k, and the mass and
        // transport of bins < k − 1 at value 1.
        let (mut mass_below, mut transport_below) = (0.0, 0.0);
        let (mut unit_mass, mut unit_transport) = (0.0, 0.0);
        let mut chosen = None;
        for k in 1..n {
            let (m, t) = bin(k - 1, p[k], p[k - 1]);
            mass_below += m;
            transport_below += t;
            if k >= 2 {
                let (um, ut) = bin(k - 2, 1.0, 1.0);
                unit_mass += um;
                unit_transport += ut;
            }
            // Bin k − 1 runs from p_k (at μ_k) to c (at μ_{k−1}).
            let (edge_mass_pk, edge_transport_pk) = bin(k - 1, 1.0, 0.0);
            let (edge_mass_c, edge_transport_c) = bin(k - 1, 0.0, 1.0);
            let c_transport = unit_transport + edge_transport_c;
            if c_transport <= 0.0 {
                continue;
            }
            let c = (transport_below - p[k] * edge_transport_pk) / c_transport;
            if c < 0.0 {
                continue;
            }
            let mass = (total_mass - mass_below) + c * (unit_mass + edge_mass_c) + p[k] * edge_mass_pk;
            if mass > 0.0 && 1.0 - total_transport / mass <= g_max {
                chosen = Some((k, c));
                break;
            }
        }
        let mut values = p.clone();
        match chosen {
            Some((k, c)) => values[..k].fill(c),
            None => values.fill(1.0),
        }
        // Non-negative, finite and not all zero, so construction cannot
        // fail; the flat table is the fallback all the same.
        PhaseTable::from_theta_samples(&values)
            .or_else(|_| PhaseTable::from_theta_samples(&vec![1.0; n]))
            .expect("a constant table is valid")
    }
}

/// Lane forms of phase-function sampling and evaluation (HG, tables), the
/// azimuth and the turn, four directions at a time for the slab simulator's
/// lane kernel (AVX2 + FMA, see [`crate::simd`]). Same formulas and
/// constants as the scalar functions above; results agree bit for bit
/// (tables) or to a few ulp (tested below).
#[cfg(target_arch = "x86_64")]
pub(crate) mod lanes;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    // ---------------------------------------------------------------- helpers

    /// 2π ∫_{θa}^{θb} f(cos θ) sin θ dθ by composite Simpson with `m` (even)
    /// intervals: an independent quadrature over the sphere in θ, where even
    /// the 0.5° Mie-like lobes are smooth.
    fn sphere_integral(f: impl Fn(f64) -> f64, theta_a: f64, theta_b: f64, m: usize) -> f64 {
        assert_eq!(m % 2, 0);
        let h = (theta_b - theta_a) / m as f64;
        let g = |k: usize| {
            let th = theta_a + k as f64 * h;
            f(th.cos()) * th.sin()
        };
        let mut s = g(0) + g(m);
        for k in 1..m {
            s += if k % 2 == 1 { 4.0 } else { 2.0 } * g(k);
        }
        2.0 * PI * s * h / 3.0
    }

    fn hg_values(g: f64, n: usize) -> Vec<f64> {
        (0..n).map(|i| hg_eval(g, (i as f64 * PI / (n - 1) as f64).cos())).collect()
    }

    /// A Mie-like table: a Gaussian forward lobe of 0.5° width 10⁵ times the
    /// isotropic floor (≈ 80 % of the scattered power), plus a broad backward
    /// lobe. Arbitrary scale.
    fn two_lobe_values(n: usize) -> Vec<f64> {
        let sigma = 0.5_f64.to_radians();
        (0..n)
            .map(|i| {
                let th = i as f64 * PI / (n - 1) as f64;
                1e5 * (-0.5 * (th / sigma).powi(2)).exp() + 1.0 + 3.0 * (-0.5 * ((PI - th) / 0.3).powi(2)).exp()
            })
            .collect()
    }

    /// χ² goodness-of-fit of `sample` (u ↦ cos θ) against the density `pdf`
    /// (per sr), in the manner of pbrt's `Chi2Test`: `n` draws from a fixed
    /// seed, binned in cos θ on K = 256 bins whose θ edges are Chebyshev-
    /// spaced (fine near θ = 0 and θ = π, where peaked functions live),
    /// expected counts by Simpson quadrature of `pdf` over each bin (not
    /// renormalised), bins with expected count < 5 pooled
    /// ([`lucent_testkit::chi2::goodness_of_fit`]). Returns the p-value.
    fn chi2_pvalue(sample: impl Fn(f64) -> f64, pdf: impl Fn(f64) -> f64, n: usize, seed: u64) -> f64 {
        const K: usize = 256;
        // θ edges 0 … π; bin j (in ascending μ) is θ ∈ [θ_{K−j−1}, θ_{K−j}].
        let theta: Vec<f64> = (0..=K).map(|k| 0.5 * PI * (1.0 - (PI * k as f64 / K as f64).cos())).collect();
        let mut mu_edges: Vec<f64> = theta.iter().rev().map(|t| t.cos()).collect();
        mu_edges[0] = -1.0;
        mu_edges[K] = 1.0;

        let mut observed = vec![0.0_f64; K];
        let mut rng = Rng::new(seed, 0);
        for _ in 0..n {
            let mu = sample(rng.next_f64());
            assert!((-1.0..=1.0).contains(&mu), "sample out of range: {mu}");
            let j = mu_edges.partition_point(|&e| e <= mu).saturating_sub(1).min(K - 1);
            observed[j] += 1.0;
        }
        let expected: Vec<f64> =
            (0..K).map(|j| n as f64 * sphere_integral(&pdf, theta[K - j - 1], theta[K - j], 256)).collect();

        // A sample where the pdf says none can be fails outright; the rest is
        // Pearson's test with the low-expectation bins pooled (the shared
        // harness of all crates' tests).
        if observed.iter().zip(&expected).any(|(&o, &e)| e <= 0.0 && o > 0.0) {
            return 0.0;
        }
        lucent_testkit::chi2::goodness_of_fit(&observed, &expected).p_value
    }

    /// Significance per χ² test (deterministic seeds, so a pass is a pass).
    const ALPHA: f64 = 1e-3;
    const N_CHI2: usize = 1_000_000;

    const HG_GS: [f64; 5] = [-0.9, -0.3, 0.0, 0.5, 0.97];

    fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
        a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
    }

    fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    }

    fn normalize(v: [f64; 3]) -> [f64; 3] {
        let l = dot(v, v).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    }

    // ------------------------------------------------------ Henyey–Greenstein

    #[test]
    fn hg_reference_values() {
        let iso = Phase::henyey_greenstein(0.0).unwrap();
        for mu in [-1.0, -0.3, 0.0, 0.7, 1.0] {
            assert_eq!(iso.eval(mu), 1.0 / (4.0 * PI));
        }
        // Closed forms at the poles: p(±1) = (1 ± g)/(4π(1 ∓ g)²).
        for g in [0.5, 0.97, -0.9] {
            let p = Phase::HenyeyGreenstein { g };
            let fwd = (1.0 + g) / (4.0 * PI * (1.0 - g) * (1.0 - g));
            let back = (1.0 - g) / (4.0 * PI * (1.0 + g) * (1.0 + g));
            assert!((p.eval(1.0) / fwd - 1.0).abs() < 1e-14, "g={g}");
            assert!((p.eval(-1.0) / back - 1.0).abs() < 1e-14, "g={g}");
            // Textbook formula in the middle.
            let mu: f64 = 0.25;
            let text = (1.0 - g * g) / (4.0 * PI * (1.0 + g * g - 2.0 * g * mu).powf(1.5));
            assert!((p.eval(mu) / text - 1.0).abs() < 1e-13, "g={g}");
        }
        assert!((Phase::HenyeyGreenstein { g: 0.5 }.eval(1.0) - 0.477_464_829_275_686).abs() < 1e-12);
    }

    #[test]
    fn hg_normalised_with_mean_cosine_g() {
        for g in HG_GS {
            let p = Phase::henyey_greenstein(g).unwrap();
            let norm = sphere_integral(|mu| p.eval(mu), 0.0, PI, 200_000);
            let mean = sphere_integral(|mu| mu * p.eval(mu), 0.0, PI, 200_000);
            assert!((norm - 1.0).abs() < 1e-6, "g={g}: ∫p dω = {norm}");
            assert!((mean - g).abs() < 1e-6, "g={g}: ⟨μ⟩ = {mean}");
            assert_eq!(p.mean_cosine(), g);
        }
    }

    #[test]
    fn hg_constructor_rejects_bad_g() {
        for g in [1.0, -1.0, 1.5, f64::NAN, f64::INFINITY] {
            assert!(matches!(Phase::henyey_greenstein(g), Err(PhaseError::InvalidAsymmetry { .. })), "g={g}");
        }
        assert!(Phase::henyey_greenstein(-0.999).is_ok());
    }

    #[test]
    fn hg_sampling_inverts_the_analytic_cdf() {
        // F(μ) = (1 − g²)/(2g) · (1/√(1 + g² − 2gμ) − 1/(1 + g)), F(−1) = 0, F(1) = 1.
        for g in [-0.9, -0.3, 0.002, 0.5, 0.97] {
            let cdf =
                |mu: f64| (1.0 - g * g) / (2.0 * g) * (1.0 / (1.0 + g * g - 2.0 * g * mu).sqrt() - 1.0 / (1.0 + g));
            for k in 0..=100 {
                let u = k as f64 / 100.0;
                let mu = hg_sample_cos_theta(g, u);
                assert!((cdf(mu) - u).abs() < 1e-10, "g={g} u={u}: F(μ)={}", cdf(mu));
            }
            assert!((hg_sample_cos_theta(g, 0.0) + 1.0).abs() < 1e-13, "g={g}: {}", hg_sample_cos_theta(g, 0.0));
            // The standard inversion loses ~ε/|g| to cancellation.
            assert!((hg_sample_cos_theta(g, 1.0) - 1.0).abs() < 1e-13, "g={g}: {}", hg_sample_cos_theta(g, 1.0));
        }
        // g > 0 scatters forward: more than half the draws have μ > 0.
        assert!(hg_sample_cos_theta(0.5, 0.5) > 0.0);
        assert!(hg_sample_cos_theta(-0.5, 0.5) < 0.0);
    }

    #[test]
    fn hg_small_g_form_agrees_with_standard_inversion() {
        for g in [-2e-3, -1.5e-3, 1.5e-3, 2e-3, 0.3, -0.7, 0.97] {
            for k in 0..=64 {
                let u = k as f64 / 64.0;
                let s = (1.0 - g * g) / (1.0 - g + 2.0 * g * u);
                let standard = (1.0 + g * g - s * s) / (2.0 * g);
                let small = hg_sample_small_g(g, u);
                assert!((standard - small).abs() < 1e-11, "g={g} u={u}: {standard} vs {small}");
            }
        }
        for k in 0..=16 {
            let u = k as f64 / 16.0;
            assert_eq!(hg_sample_cos_theta(0.0, u), 2.0 * u - 1.0);
        }
    }

    #[test]
    fn chi2_hg_sampling() {
        for (seed, g) in HG_GS.into_iter().chain([4e-4, -0.6]).enumerate() {
            let p = Phase::HenyeyGreenstein { g };
            let pval = chi2_pvalue(|u| p.sample_cos_theta(u), |mu| p.eval(mu), N_CHI2, seed as u64);
            assert!(pval > ALPHA, "HG g={g}: χ² p-value {pval:e}");
        }
    }

    #[test]
    fn chi2_rejects_a_wrong_pdf() {
        // Power check: samples of HG g = 0.5 tested against the pdf of g = 0.55.
        let sample = Phase::HenyeyGreenstein { g: 0.5 };
        let wrong = Phase::HenyeyGreenstein { g: 0.55 };
        let pval = chi2_pvalue(|u| sample.sample_cos_theta(u), |mu| wrong.eval(mu), N_CHI2, 11);
        assert!(pval < ALPHA, "χ² failed to reject a wrong pdf: p = {pval:e}");
        // ... and a table sampler against a 1 % narrower forward lobe.
        let t = PhaseTable::from_theta_samples(&hg_values(0.97, 4096)).unwrap();
        let wrong = Phase::HenyeyGreenstein { g: 0.9703 };
        let pval = chi2_pvalue(|u| t.sample_cos_theta(u), |mu| wrong.eval(mu), N_CHI2, 12);
        assert!(pval < ALPHA, "χ² failed to reject a wrong pdf: p = {pval:e}");
    }

    // ------------------------------------------------------------- the table

    #[test]
    fn table_from_hg_is_normalised_and_exact_at_nodes() {
        let n = 4096;
        let raw: Vec<f64> = hg_values(0.9, n).iter().map(|v| 3.7 * v).collect(); // arbitrary scale
        let t = PhaseTable::from_theta_samples(&raw).unwrap();
        assert_eq!(t.len(), n);
        assert!(!t.is_empty());

        // Independent quadrature of eval over the sphere, and of μ·eval
        // (Simpson in θ, 8 intervals per bin, aligned with the nodes).
        let norm = sphere_integral(|mu| t.eval(mu), 0.0, PI, 8 * (n - 1));
        assert!((norm - 1.0).abs() < 1e-10, "∫p dω = {norm}");
        let mean = sphere_integral(|mu| mu * t.eval(mu), 0.0, PI, 8 * (n - 1));
        assert!((mean - t.mean_cosine()).abs() < 1e-10, "{mean} vs {}", t.mean_cosine());
        assert!((t.mean_cosine() - 0.9).abs() < 1e-4, "g = {}", t.mean_cosine());

        // Exact trapezoid in μ of the stored nodes.
        let (mu, p) = (t.node_cos_theta(), t.theta_samples());
        let trap: f64 = (0..n - 1).map(|i| (mu[i] - mu[i + 1]) * 0.5 * (p[i] + p[i + 1])).sum();
        assert!((2.0 * PI * trap - 1.0).abs() < 1e-13);

        // Node values are the input up to one factor; eval reproduces them.
        let scale = p[0] / raw[0];
        for i in 0..n {
            assert!((p[i] / raw[i] / scale - 1.0).abs() < 1e-13, "node {i}");
            let c = (i as f64 * PI / (n - 1) as f64).cos();
            assert!((t.eval(c) / p[i] - 1.0).abs() < 1e-12, "eval at node {i}: {} vs {}", t.eval(c), p[i]);
            assert_eq!(t.eval(mu[i]), p[i], "eval at stored node {i}");
        }
        // ... and are close to HG itself (normalisation error of the trapezoid).
        for c in [1.0, 0.999, 0.9, 0.0, -1.0] {
            assert!((t.eval(c) / hg_eval(0.9, c) - 1.0).abs() < 1e-4, "μ={c}");
        }
    }

    #[test]
    fn table_is_linear_in_mu_between_nodes() {
        let t = PhaseTable::from_theta_samples(&two_lobe_values(257)).unwrap();
        let (mu, p) = (t.node_cos_theta(), t.theta_samples());
        for i in [0, 1, 5, 100, 255] {
            for s in [0.1, 0.5, 0.9] {
                let m = mu[i + 1] + s * (mu[i] - mu[i + 1]);
                let want = (1.0 - s) * p[i + 1] + s * p[i];
                assert!((t.eval(m) / want - 1.0).abs() < 1e-9, "bin {i} s={s}");
            }
        }
        // Out of range clamps, NaN propagates.
        assert_eq!(t.eval(1.5), p[0]);
        assert_eq!(t.eval(-7.0), p[256]);
        assert!(t.eval(f64::NAN).is_nan());
        assert!(t.sample_cos_theta(f64::NAN).is_nan());
    }

    #[test]
    fn constant_table_is_isotropic() {
        for n in [2, 3, 4096] {
            let t = PhaseTable::from_theta_samples(&vec![1e300; n]).unwrap();
            for k in 0..=40 {
                let c = -1.0 + k as f64 / 20.0;
                assert!((t.eval(c) * 4.0 * PI - 1.0).abs() < 1e-13, "n={n} μ={c}");
                let u = k as f64 / 40.0;
                assert!((t.sample_cos_theta(u) - (2.0 * u - 1.0)).abs() < 1e-12, "n={n} u={u}");
            }
            assert!(t.mean_cosine().abs() < 1e-15, "n={n}: {}", t.mean_cosine());
        }
    }

    #[test]
    fn table_sampling_is_monotone_and_covers_the_range() {
        for raw in [hg_values(0.97, 4096), two_lobe_values(4096), vec![0.0, 2.0, 0.0, 0.0, 1.0, 3.0, 0.0]] {
            let t = PhaseTable::from_theta_samples(&raw).unwrap();
            let mut prev = -1.0;
            for k in 0..=100_000 {
                let u = k as f64 / 100_000.0;
                let mu = t.sample_cos_theta(u);
                assert!(mu >= prev && (-1.0..=1.0).contains(&mu), "u={u}: {mu} after {prev}");
                prev = mu;
            }
            assert!(t.sample_cos_theta(-1.0) >= -1.0);
            assert!(t.sample_cos_theta(ONE_MINUS_EPSILON) > 0.999);
        }
        // The two-lobe table has half its power within about a degree.
        let t = PhaseTable::from_theta_samples(&two_lobe_values(4096)).unwrap();
        assert!(t.sample_cos_theta(0.5) > 1.0_f64.to_radians().cos());
    }

    #[test]
    fn chi2_table_sampling() {
        let cases: Vec<(&str, Vec<f64>)> = vec![
            ("HG 0.9, N=4096", hg_values(0.9, 4096)),
            ("HG 0.97, N=4096", hg_values(0.97, 4096)),
            ("two lobes, N=4096", two_lobe_values(4096)),
            ("two lobes, N=64 (coarse)", two_lobe_values(64)),
            ("linear in μ, N=2", vec![3.0, 1.0]),
            ("zeros inside, N=7", vec![0.0, 2.0, 0.0, 0.0, 1.0, 3.0, 0.0]),
        ];
        for (seed, (name, raw)) in cases.into_iter().enumerate() {
            let t = PhaseTable::from_theta_samples(&raw).unwrap();
            let pval = chi2_pvalue(|u| t.sample_cos_theta(u), |mu| t.eval(mu), N_CHI2, 100 + seed as u64);
            assert!(pval > ALPHA, "{name}: χ² p-value {pval:e}");
        }
    }

    #[test]
    fn phase_enum_dispatches_to_the_table() {
        let t = PhaseTable::from_theta_samples(&two_lobe_values(4096)).unwrap();
        let p = Phase::from(t.clone());
        for k in 0..=20 {
            let x = -1.0 + k as f64 / 10.0;
            assert_eq!(p.eval(x), t.eval(x));
            let u = k as f64 / 20.0;
            assert_eq!(p.sample_cos_theta(u), t.sample_cos_theta(u));
        }
        assert_eq!(p.mean_cosine(), t.mean_cosine());
        // Simpson in θ with the grid aligned to the nodes (16 intervals per
        // bin) never straddles a kink, so it agrees with the exact values.
        let mean = sphere_integral(|mu| mu * t.eval(mu), 0.0, PI, 16 * 4095);
        let norm = sphere_integral(|mu| t.eval(mu), 0.0, PI, 16 * 4095);
        assert!((mean - t.mean_cosine()).abs() < 1e-10, "{mean} vs {}", t.mean_cosine());
        assert!((norm - 1.0).abs() < 1e-10, "∫p dω = {norm}");
    }

    #[test]
    fn bad_tables_are_errors() {
        use PhaseError::*;
        let e = |v: &[f64]| PhaseTable::from_theta_samples(v).unwrap_err();
        assert_eq!(e(&[]), TooFewSamples { got: 0 });
        assert_eq!(e(&[1.0]), TooFewSamples { got: 1 });
        assert!(matches!(e(&[1.0, f64::NAN, 1.0]), NotFinite { index: 1, .. }));
        assert!(matches!(e(&[1.0, 1.0, f64::INFINITY]), NotFinite { index: 2, .. }));
        assert!(matches!(e(&[f64::NEG_INFINITY, 1.0]), NotFinite { index: 0, .. }));
        assert_eq!(e(&[1.0, -1e-9, 1.0]), Negative { index: 1, value: -1e-9 });
        assert_eq!(e(&[0.0, 0.0]), AllZero);
        assert_eq!(e(&[0.0, -0.0, 0.0]), AllZero);
        assert_eq!(e(&vec![0.0; 4096]), AllZero);
        // Messages say what is wrong.
        assert!(e(&[1.0, -2.0]).to_string().contains("index 1"));
        // Tiny and huge scales are fine.
        assert!(PhaseTable::from_theta_samples(&[1e-310, 5e-311]).is_ok());
        assert!(PhaseTable::from_theta_samples(&[f64::MAX, f64::MAX, 1.0]).is_ok());
    }

    // ------------------------------------------------------------- directions

    #[test]
    fn orthonormal_basis_everywhere() {
        let mut rng = Rng::new(5, 0);
        let mut normals = vec![
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            normalize([1e-9, 2e-9, -1.0]),
            normalize([1e-9, 0.0, 1.0]),
            [0.0, 1.0, -0.0],
        ];
        for _ in 0..10_000 {
            let z = 2.0 * rng.next_f64() - 1.0;
            let phi = 2.0 * PI * rng.next_f64();
            let r = (1.0 - z * z).sqrt();
            normals.push([r * phi.cos(), r * phi.sin(), z]);
        }
        for n in normals {
            let (t, b) = orthonormal_basis(n);
            for (x, y, want) in [(t, t, 1.0), (b, b, 1.0), (t, b, 0.0), (t, n, 0.0), (b, n, 0.0)] {
                assert!((dot(x, y) - want).abs() < 1e-12, "n={n:?}");
            }
            let c = cross(t, b);
            for k in 0..3 {
                assert!((c[k] - n[k]).abs() < 1e-12, "not right-handed at n={n:?}");
            }
        }
    }

    #[test]
    fn eval_each_equals_separate_evaluations_bit_for_bit() {
        let t = |v: Vec<f64>| Phase::from(PhaseTable::from_theta_samples(&v).unwrap());
        let (a, b) = (t(hg_values(0.97, 4096)), t(two_lobe_values(4096)));
        let c = t(hg_values(0.5, 257)); // another length: evaluated on its own
        let hg = Phase::henyey_greenstein(0.8).unwrap();
        let mut rng = Rng::new(5, 0);
        for n in 0..20_000 {
            let mu = if n < 4 { [-1.0, 1.0, 0.0, 1.5][n] } else { 2.0 * rng.next_f64() - 1.0 };
            let active = [n % 3 != 0, true, n % 5 != 0];
            for phases in [[&a, &b, &a], [&a, &b, &c], [&hg, &a, &b]] {
                let got = eval_each(phases, active, mu);
                for k in 0..3 {
                    let want = if active[k] { phases[k].eval(mu) } else { 0.0 };
                    assert_eq!(got[k].to_bits(), want.to_bits(), "μ {mu}, band {k}");
                }
            }
        }
    }

    #[test]
    fn sin_cos_turns_matches_libm() {
        for k in 0..=100_000 {
            let u = k as f64 / 100_000.0 * 0.999_999_999;
            let (s, c) = sin_cos_turns(u);
            let (es, ec) = (2.0 * PI * u).sin_cos();
            assert!((s - es).abs() < 1e-15 && (c - ec).abs() < 1e-15, "u={u}: {s} {c} vs {es} {ec}");
            assert!((s * s + c * c - 1.0).abs() < 1e-15, "u={u}: not on the unit circle");
        }
    }

    #[test]
    fn sample_direction_at_the_poles() {
        let p = Phase::HenyeyGreenstein { g: 0.6 };
        for zsign in [1.0, -1.0] {
            let inc = [0.0, 0.0, zsign];
            for u1 in [0.0, 0.1, 0.5, 0.93, 0.999_999] {
                let mu = p.sample_cos_theta(u1);
                let sin_theta = ((1.0 - mu) * (1.0 + mu)).max(0.0).sqrt();
                let d0 = p.sample_direction(inc, u1, 0.0);
                let d1 = p.sample_direction(inc, u1, 0.25);
                for d in [d0, d1] {
                    assert!((dot(d, d) - 1.0).abs() < 1e-14);
                    assert!((d[2] - zsign * mu).abs() < 1e-15, "z={} μ={mu}", d[2]);
                    assert!((d[0].hypot(d[1]) - sin_theta).abs() < 1e-14);
                }
                // A quarter of u2 is a quarter turn about the axis.
                if sin_theta > 1e-6 {
                    let (a, b) = ([d0[0], d0[1], 0.0], [d1[0], d1[1], 0.0]);
                    assert!(dot(a, b).abs() < 1e-12 * sin_theta * sin_theta);
                    assert!((cross(a, b)[2] - zsign * sin_theta * sin_theta).abs() < 1e-12);
                }
            }
        }
    }

    #[test]
    fn sample_direction_statistics() {
        let phases = [
            Phase::HenyeyGreenstein { g: 0.7 },
            Phase::HenyeyGreenstein { g: -0.4 },
            Phase::from(PhaseTable::from_theta_samples(&two_lobe_values(4096)).unwrap()),
        ];
        let n = 200_000;
        for (seed, p) in phases.iter().enumerate() {
            let mut rng = Rng::new(77, seed as u64);
            let g = p.mean_cosine();
            let inc = normalize([0.3, -0.5, 0.8]);
            let (mut sum, mut sum2, mut vsum) = (0.0, 0.0, [0.0; 3]);
            for _ in 0..n {
                let (u1, u2) = (rng.next_f64(), rng.next_f64());
                let d = p.sample_direction(inc, u1, u2);
                assert!((dot(d, d) - 1.0).abs() < 1e-12, "not unit: {d:?}");
                let c = dot(d, inc);
                assert!((c - p.sample_cos_theta(u1)).abs() < 1e-12);
                sum += c;
                sum2 += c * c;
                for k in 0..3 {
                    vsum[k] += d[k];
                }
            }
            let nf = n as f64;
            let mean = sum / nf;
            let se = ((sum2 / nf - mean * mean) / nf).sqrt();
            assert!((mean - g).abs() < 5.0 * se, "⟨d·incident⟩ = {mean}, g = {g}, se = {se}");
            // Azimuth uniform: the mean vector is g · incident (each
            // component's sd ≤ 1/√n).
            for k in 0..3 {
                assert!((vsum[k] / nf - g * inc[k]).abs() < 5.0 / nf.sqrt(), "component {k}");
            }
        }
    }

    /// The guide table and the acos guess are shortcuts to the same bins:
    /// sampling and evaluation agree bit for bit with a search over the
    /// whole CDF and a walk from libm's acos, on a peaked table, one with
    /// zero-probability stretches at both ends, and a two-node one.
    #[test]
    fn shortcuts_find_the_same_bins() {
        let nearly = |u: f64| u.clamp(0.0, ONE_MINUS_EPSILON);
        let peaked: Vec<f64> = (0..4096).map(|k| (-(k as f64) / 30.0).exp()).collect();
        let holes: Vec<f64> =
            (0..500).map(|k| if (100..300).contains(&k) { 1.0 + (k as f64 * 0.1).sin() } else { 0.0 }).collect();
        for values in [peaked, holes, vec![1.0, 3.0]] {
            let t = PhaseTable::from_theta_samples(&values).expect("valid table");
            let reference_sample = |u: f64| {
                let u = nearly(u);
                let i = t.cdf.partition_point(|&c| c > u) - 1;
                let (c_lo, c_hi) = (t.cdf[i + 1], t.cdf[i]);
                let up = ((u - c_lo) / (c_hi - c_lo)).clamp(0.0, 1.0);
                let (a, b) = (t.values[i + 1], t.values[i]);
                let denom = a + (a * a * (1.0 - up) + b * b * up).sqrt();
                let s = if denom > 0.0 { (up * (a + b) / denom).min(1.0) } else { 0.0 };
                let (lo, hi) = (t.mu[i + 1], t.mu[i]);
                (lo + s * (hi - lo)).min(hi)
            };
            let reference_eval = |mu: f64| {
                let mu = mu.clamp(-1.0, 1.0);
                let last_bin = t.mu.len() - 2;
                let mut i = ((mu.acos() * t.inv_dtheta) as usize).min(last_bin);
                while i > 0 && mu > t.mu[i] {
                    i -= 1;
                }
                while i < last_bin && mu < t.mu[i + 1] {
                    i += 1;
                }
                let (hi, lo) = (t.mu[i], t.mu[i + 1]);
                let s = if hi > lo { (mu - lo) / (hi - lo) } else { 0.5 };
                (1.0 - s) * t.values[i + 1] + s * t.values[i]
            };
            let mut rng = crate::rng::Rng::new(21, values.len() as u64);
            let cells = (0..=GUIDE_CELLS).map(|j| j as f64 / GUIDE_CELLS as f64);
            let us: Vec<f64> = (0..200_000)
                .map(|_| rng.next_f64())
                .chain(cells.clone())
                .chain(cells.map(|u| u - 1e-17))
                .chain(t.cdf.iter().copied())
                .collect();
            for u in us {
                assert_eq!(t.sample_cos_theta(u).to_bits(), reference_sample(u).to_bits(), "u = {u}");
            }
            let mus: Vec<f64> = (0..200_000)
                .map(|_| 2.0 * rng.next_f64() - 1.0)
                .chain(t.mu.iter().copied())
                .chain([1.0, -1.0, 0.0, -0.0, 0.999_999_999])
                .collect();
            for mu in mus {
                assert_eq!(t.eval(mu).to_bits(), reference_eval(mu).to_bits(), "μ = {mu}");
            }
        }
        for k in 0..=20_000 {
            let mu = -1.0 + k as f64 / 10_000.0;
            assert!((acos_guess(mu) - mu.acos()).abs() < 3e-8, "acos_guess({mu})");
        }
    }

    /// The lane forms of table sampling and evaluation, and of HG, give the
    /// scalar results: bit for bit for the table (same bins, same
    /// operations), to a few ulp for HG (products for constant divisions).
    #[cfg(target_arch = "x86_64")]
    #[test]
    fn lane_forms_match_the_scalar_ones() {
        use crate::simd::{Lanes, F4};
        if crate::simd::lanes_unavailable() {
            return;
        }
        #[target_feature(enable = "avx2,fma")]
        fn check() {
            let values: Vec<f64> = (0..4096).map(|k| (-(k as f64) / 30.0).exp() + 1e-3).collect();
            let t = PhaseTable::from_theta_samples(&values).expect("valid table");
            let hg = lanes::Hg::new(0.9).expect("|g| ≥ 1e-3");
            let mut rng = crate::rng::Rng::new(8, 8);
            for _ in 0..50_000 {
                let u = Lanes(std::array::from_fn(|_| rng.next_f64()));
                let mu = Lanes(std::array::from_fn(|_| 2.0 * rng.next_f64() - 1.0));
                let sampled = t.sample_cos_theta_lanes(F4::load(&u)).lanes();
                let evaluated = t.eval_lanes(F4::load(&mu)).lanes();
                let (hg_sampled, hg_evaluated) =
                    (hg.sample_cos_theta(F4::load(&u)).lanes(), hg.eval(F4::load(&mu)).lanes());
                let (sin, cos) = lanes::sin_cos_turns(F4::load(&u));
                let (sin, cos) = (sin.lanes(), cos.lanes());
                for l in 0..4 {
                    assert_eq!(sampled.0[l].to_bits(), t.sample_cos_theta(u.0[l]).to_bits());
                    assert_eq!(evaluated.0[l].to_bits(), t.eval(mu.0[l]).to_bits());
                    assert!((hg_sampled.0[l] - hg_sample_cos_theta(0.9, u.0[l])).abs() < 1e-15);
                    let p = hg_eval(0.9, mu.0[l]);
                    assert!((hg_evaluated.0[l] - p).abs() < 1e-14 * p);
                    let (s, c) = sin_cos_turns(u.0[l]);
                    assert!((sin.0[l] - s).abs() < 1e-16 && (cos.0[l] - c).abs() < 1e-16);
                }
            }
        }
        unsafe { check() }
    }

    // ------------------------------------------------------ flat top (similarity)

    /// A Mie-like table: HG(0.97) on 4096 nodes plus a small backward lobe.
    fn peaked_table() -> PhaseTable {
        let n = 4096;
        let values: Vec<f64> = (0..n)
            .map(|i| {
                let mu = (i as f64 * PI / (n - 1) as f64).cos();
                hg_eval(0.97, mu) + 0.002 * (1.0 - mu).powi(2)
            })
            .collect();
        PhaseTable::from_theta_samples(&values).expect("valid table")
    }

    #[test]
    fn flat_top_keeps_large_angle_scattering_and_the_transport_moment() {
        let table = peaked_table();
        let g = table.mean_cosine();
        assert!(g > 0.9, "g = {g}");
        // The transport moment ∫ (1 − μ) p dω and the mass by an
        // independent quadrature in θ (Simpson, 20 000 intervals) of `eval`.
        let transport = |t: &PhaseTable| sphere_integral(|mu| (1.0 - mu) * t.eval(mu), 0.0, PI, 20_000);
        for g_max in [0.9, 0.8, 0.5, 0.2, 0.0] {
            let cut = table.flat_topped(g_max);
            let g_cut = cut.mean_cosine();
            assert!(g_cut <= g_max && g_cut > g_max - 0.02, "g_max {g_max}: g′ = {g_cut}");
            // μs′ = M μs with M = (1 − g)/(1 − g′) keeps μs (1 − g) ...
            let m = (1.0 - g) / (1.0 - g_cut);
            let (t, t_cut) = (transport(&table), transport(&cut));
            assert!(((m * t_cut) / t - 1.0).abs() < 1e-4, "g_max {g_max}: M t′ = {} against t = {t}", m * t_cut);
            // ... and μs p(θ) at every node outside the cut.
            let k =
                cut.theta_samples().iter().zip(table.theta_samples()).position(|(a, b)| (m * a / b - 1.0).abs() < 1e-6);
            let k = k.expect("a node where the cut ends");
            for (i, (a, b)) in cut.theta_samples().iter().zip(table.theta_samples()).enumerate().skip(k) {
                assert!((m * a / b - 1.0).abs() < 1e-6, "g_max {g_max}, node {i}: {} against {b}", m * a);
            }
            // The cut is flat up to node k − 1 and reaches further for smaller g_max.
            let top = cut.theta_samples()[0];
            assert!(cut.theta_samples()[..k - 1].iter().all(|&v| v == top), "g_max {g_max}");
        }
        // Nothing to cut: unchanged.
        assert_eq!(table.flat_topped(0.99), table);
    }
}
