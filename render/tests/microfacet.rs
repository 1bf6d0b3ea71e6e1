//! Rough dielectric BSDF (render::microfacet): χ² of every sampler against
//! its pdf, reciprocity, white-furnace energy, normalisation of D and the
//! Smith identity by quadrature, the smooth limit, measured normals, bad
//! input, and values from Mitsuba 3's `roughdielectric`.

use glam::DVec3;
use lucent_render::fresnel;
use lucent_render::interface::{Interface, Lobe, Sample, Transport};
use lucent_render::microfacet::{Distribution, MeasuredNormals, MicrofacetError, Microsurface, SMOOTH_ALPHA};
use lucent_render::rng::Rng;
use std::f64::consts::PI;
use std::sync::Arc;

const ETA: f64 = 1.41;
const ALPHAS: [f64; 4] = [0.01, 0.1, 0.3, 0.7];

fn tr(alpha: f64) -> Microsurface {
    Microsurface::Analytic(Distribution::TrowbridgeReitz { alpha })
}
fn beckmann(alpha: f64) -> Microsurface {
    Microsurface::Analytic(Distribution::Beckmann { alpha })
}
/// The interface at one index ratio η = n_below/n_above, sampled with the
/// Fresnel lobe choice: the BSDF the tests examine.
struct Bsdf {
    interface: Interface,
    eta: f64,
}
impl Bsdf {
    fn eta(&self) -> f64 {
        self.eta
    }
    fn is_delta(&self) -> bool {
        self.interface.is_delta(self.eta)
    }
    fn sample(&self, wo: DVec3, u: [f64; 3], mode: Transport) -> Option<Sample> {
        self.interface.sample(wo, self.eta, Lobe::Fresnel, u, mode)
    }
    fn eval(&self, wo: DVec3, wi: DVec3, mode: Transport) -> f64 {
        self.interface.eval(wo, wi, self.eta, mode)
    }
    fn pdf(&self, wo: DVec3, wi: DVec3) -> f64 {
        self.interface.pdf(wo, wi, self.eta)
    }
}
fn bsdf(eta: f64, s: Microsurface) -> Bsdf {
    Bsdf { interface: Interface::new(s).unwrap(), eta }
}
/// Unit direction at polar angle θ (degrees, from +z) and azimuth φ (degrees).
fn dir(theta_deg: f64, phi_deg: f64) -> DVec3 {
    let (t, p) = (theta_deg.to_radians(), phi_deg.to_radians());
    DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), t.cos())
}
fn uniform_sphere(rng: &mut Rng) -> DVec3 {
    let z = 1.0 - 2.0 * rng.next_f64();
    let r = (1.0 - z * z).max(0.0).sqrt();
    let p = 2.0 * PI * rng.next_f64();
    DVec3::new(r * p.cos(), r * p.sin(), z)
}

/// Gauss–Legendre nodes and weights on [−1, 1] (Newton on P_n).
fn gauss_legendre(n: usize) -> Vec<(f64, f64)> {
    (0..n)
        .map(|i| {
            let mut x = (PI * (i as f64 + 0.75) / (n as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for k in 2..=n {
                    let p2 = ((2 * k - 1) as f64 * x * p1 - (k - 1) as f64 * p0) / k as f64;
                    p0 = p1;
                    p1 = p2;
                }
                dp = n as f64 * (x * p1 - p0) / (x * x - 1.0);
                let dx = p1 / dp;
                x -= dx;
                if dx.abs() < 1e-16 {
                    break;
                }
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

// ---------------------------------------------------------------------------
// χ² goodness of fit of sample() against pdf()
// ---------------------------------------------------------------------------

/// A warp of [lo, hi] that puts half the bins within a few `s` of `c`:
/// x = (atan((v − c)/s) − a0)/(a1 − a0).
struct Warp {
    c: f64,
    s: f64,
    a0: f64,
    a1: f64,
}
impl Warp {
    fn new(c: f64, s: f64, lo: f64, hi: f64) -> Self {
        Warp { c, s, a0: ((lo - c) / s).atan(), a1: ((hi - c) / s).atan() }
    }
    fn forward(&self, v: f64) -> f64 {
        ((((v - self.c) / self.s).atan() - self.a0) / (self.a1 - self.a0)).clamp(0.0, 1.0 - 1e-15)
    }
    fn inverse(&self, x: f64) -> f64 {
        self.c + self.s * (self.a0 + x * (self.a1 - self.a0)).tan()
    }
}

/// Bins of the sphere: per hemisphere, polar angle θ′ = acos|z| ∈ [0, π/2]
/// warped around the lobe centre, azimuth relative to φ_o + π warped around 0.
struct SphereBins {
    nt: usize,
    np: usize,
    theta: [Warp; 2],
    phi: [Warp; 2],
    phi_c: f64,
    /// θ′ on the far side where the transmission half-vector turns
    /// horizontal: D (GGX) jumps to 0 there, so cells are split at it.
    theta_break: Option<f64>,
}
impl SphereBins {
    fn for_lobes(b: &Bsdf, wo: DVec3, spread: f64) -> Self {
        let eta_o = if wo.z > 0.0 { b.eta() } else { 1.0 / b.eta() };
        let t_o = wo.z.abs().acos();
        let sin_t = t_o.sin() / eta_o;
        let t_t = if sin_t < 1.0 { sin_t.asin() } else { 0.5 * PI };
        let s = (2.5 * spread).clamp(0.01, 1.0);
        // Index 0: the hemisphere of wo (reflection), 1: the other one.
        let tw = |c: f64| Warp::new(c, s, 0.0, 0.5 * PI);
        let pw = |c: f64| {
            let sp = (s / c.sin().max(s)).min(PI);
            Warp::new(0.0, sp, -PI, PI)
        };
        let zb = wo.z.abs() / eta_o;
        SphereBins {
            nt: 24,
            np: 24,
            theta: [tw(t_o), tw(t_t)],
            phi: [pw(t_o), pw(t_t)],
            phi_c: wo.y.atan2(wo.x) + PI,
            theta_break: (zb < 1.0).then(|| zb.acos()),
        }
    }
    fn cells(&self) -> usize {
        2 * self.nt * self.np
    }
    fn wrap(&self, phi: f64) -> f64 {
        (phi - self.phi_c + PI).rem_euclid(2.0 * PI) - PI
    }
    fn index(&self, wo: DVec3, w: DVec3) -> usize {
        let h = usize::from(w.z * wo.z <= 0.0);
        let tp = w.z.abs().min(1.0).acos();
        let i = (self.theta[h].forward(tp) * self.nt as f64) as usize;
        let j = (self.phi[h].forward(self.wrap(w.y.atan2(w.x))) * self.np as f64) as usize;
        (h * self.nt + i) * self.np + j
    }
    /// ∫ pdf over every cell by 8 × 8 Gauss–Legendre per cell.
    fn integrate(&self, wo: DVec3, pdf: &dyn Fn(DVec3) -> f64) -> Vec<f64> {
        let gl = gauss_legendre(8);
        let mut out = vec![0.0; self.cells()];
        for h in 0..2 {
            let side = if h == 0 { wo.z.signum() } else { -wo.z.signum() };
            for i in 0..self.nt {
                let (t0, t1) = (
                    self.theta[h].inverse(i as f64 / self.nt as f64),
                    self.theta[h].inverse((i + 1) as f64 / self.nt as f64),
                );
                for j in 0..self.np {
                    let (p0, p1) = (
                        self.phi[h].inverse(j as f64 / self.np as f64),
                        self.phi[h].inverse((j + 1) as f64 / self.np as f64),
                    );
                    let mut pieces = vec![(t0, t1)];
                    if let Some(tb) = self.theta_break.filter(|&tb| h == 1 && tb > t0 && tb < t1) {
                        pieces = vec![(t0, tb), (tb, t1)];
                    }
                    let mut sum = 0.0;
                    for (ta, tb) in pieces {
                        for &(xa, wa) in &gl {
                            let t = 0.5 * (ta + tb) + 0.5 * (tb - ta) * xa;
                            for &(xb, wb) in &gl {
                                let p = self.phi_c + 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * xb;
                                let w = DVec3::new(t.sin() * p.cos(), t.sin() * p.sin(), side * t.cos());
                                sum += wa * wb * pdf(w) * t.sin() * (tb - ta);
                            }
                        }
                    }
                    out[(h * self.nt + i) * self.np + j] = sum * 0.25 * (p1 - p0);
                }
            }
        }
        out
    }
}

struct Chi2 {
    p_value: f64,
    /// |observed success fraction − ∫ pdf| and its binomial σ.
    mass_abs: f64,
    mass_sigma: f64,
    mass: f64,
}

/// Draws `n` samples, bins the successful ones, and compares with the
/// expected counts n_success · ∫_cell pdf / ∫ pdf (cells with fewer than 5
/// expected pooled). The lost fraction is checked against 1 − ∫ pdf.
fn chi2(
    bins: &SphereBins,
    wo: DVec3,
    n: usize,
    seed: u64,
    sample: &dyn Fn(DVec3, [f64; 3]) -> Option<Sample>,
    pdf: &dyn Fn(DVec3) -> f64,
) -> Chi2 {
    let expected = bins.integrate(wo, pdf);
    let mass: f64 = expected.iter().sum();
    let mut observed = vec![0u64; bins.cells()];
    let mut rng = Rng::new(seed, 0);
    let mut ok = 0usize;
    for _ in 0..n {
        let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
        if let Some(s) = sample(wo, u) {
            assert!(s.wi.is_finite() && s.weight.is_finite() && s.weight > 0.0, "{s:?}");
            observed[bins.index(wo, s.wi)] += 1;
            ok += 1;
        }
    }
    let expected: Vec<f64> = expected.iter().map(|e| e / mass * ok as f64).collect();
    let observed: Vec<f64> = observed.iter().map(|&o| o as f64).collect();
    let p_value = lucent_testkit::chi2::goodness_of_fit(&observed, &expected).p_value;
    let frac = ok as f64 / n as f64;
    let mass_sigma = (mass * (1.0 - mass) / n as f64).abs().sqrt().max(1.0 / n as f64);
    Chi2 { p_value, mass_abs: (frac - mass).abs(), mass_sigma, mass }
}

/// Total number of χ² tests in this file, for the Bonferroni correction.
const CHI2_TESTS: f64 = 160.0;
const SIGNIFICANCE: f64 = 0.01 / CHI2_TESTS;

fn chi2_config(b: &Bsdf, wo: DVec3, spread: f64, n: usize, seed: u64, label: &str) {
    let bins = SphereBins::for_lobes(b, wo, spread);
    let r = chi2(&bins, wo, n, seed, &|wo, u| b.sample(wo, u, Transport::Radiance), &|wi| b.pdf(wo, wi));
    assert!(r.p_value > SIGNIFICANCE, "{label}: χ² p = {:.3e}", r.p_value);
    // The lost fraction: 5σ of binomial noise plus 1e-3 for the quadrature.
    assert!(r.mass_abs < 5.0 * r.mass_sigma + 1e-3, "{label}: ∫ pdf {} vs success fraction (Δ {})", r.mass, r.mass_abs);
    assert!(r.mass <= 1.0 + 2e-3, "{label}: ∫ pdf = {}", r.mass);
}

fn chi2_distribution(make: fn(f64) -> Microsurface, name: &str, seed0: u64) {
    let mut seed = seed0;
    for &alpha in &ALPHAS {
        for &(eta, below) in &[(ETA, false), (1.0 / ETA, false), (ETA, true)] {
            let thetas: &[f64] = if below { &[40.0] } else { &[10.0, 45.0, 80.0] };
            for &t in thetas {
                let b = bsdf(eta, make(alpha));
                let mut wo = dir(t, 30.0);
                if below {
                    wo.z = -wo.z;
                }
                seed += 1;
                chi2_config(&b, wo, alpha, 60_000, seed, &format!("{name} α {alpha} η {eta:.4} θo {t}° below {below}"));
            }
        }
    }
}

#[test]
fn chi2_trowbridge_reitz() {
    chi2_distribution(tr, "TR", 1000);
}

#[test]
fn chi2_beckmann() {
    chi2_distribution(beckmann, "Beckmann", 2000);
}

#[test]
fn chi2_rejects_a_mismatched_sampler() {
    // The test has power: sampling α·1.05 against the pdf of α is caught, as is
    // Beckmann sampling against the Trowbridge–Reitz pdf of the same α.
    let wo = dir(45.0, 30.0);
    for (s, p, a) in
        [(tr(0.105), tr(0.1), 0.1), (beckmann(0.3), tr(0.3), 0.3), (beckmann(0.0105), beckmann(0.01), 0.01)]
    {
        let (bs, bp) = (bsdf(ETA, s), bsdf(ETA, p));
        let bins = SphereBins::for_lobes(&bp, wo, a);
        let r = chi2(&bins, wo, 100_000, 7, &|wo, u| bs.sample(wo, u, Transport::Radiance), &|wi| bp.pdf(wo, wi));
        assert!(r.p_value < SIGNIFICANCE, "mismatch not detected: p = {}", r.p_value);
    }
}

// ---------------------------------------------------------------------------
// Sample records agree with eval and pdf
// ---------------------------------------------------------------------------

#[test]
fn sample_weight_and_pdf_match_eval_and_pdf() {
    let mut rng = Rng::new(11, 0);
    let measured = MeasuredNormals::new(&normals_from(Distribution::Beckmann { alpha: 0.3 }, 2000, 3), None).unwrap();
    let measured = Microsurface::Measured(Arc::new(measured));
    for s in [tr(0.05), beckmann(0.3), tr(0.7), beckmann(0.002), measured] {
        for eta in [ETA, 1.0 / ETA] {
            let b = bsdf(eta, s.clone());
            assert!(!b.is_delta());
            for mode in [Transport::Radiance, Transport::Importance] {
                for _ in 0..2000 {
                    let wo = uniform_sphere(&mut rng);
                    let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
                    let Some(x) = b.sample(wo, u, mode) else { continue };
                    assert_eq!(x.transmitted, x.wi.z * wo.z < 0.0);
                    assert!((x.wi.length() - 1.0).abs() < 1e-12);
                    // The sampler's weight (the normal's factor × G1, no
                    // density evaluated) is f |cos θ_i| / pdf.
                    let pdf = b.pdf(wo, x.wi);
                    assert!(pdf > 0.0 && pdf.is_finite(), "{pdf}");
                    let w = b.eval(wo, x.wi, mode) * x.wi.z.abs() / pdf;
                    assert!((x.weight - w).abs() <= 1e-9 * w.max(1e-300), "{} vs {w}", x.weight);
                    // For visible-normal sampling the reflection weight is G1(ωi).
                    if let (false, Microsurface::Analytic(d)) = (x.transmitted, &s) {
                        let m = (wo + x.wi).normalize();
                        let m = if m.z < 0.0 { -m } else { m };
                        assert!((x.weight - d.g1(x.wi, m)).abs() < 1e-9, "{} vs {}", x.weight, d.g1(x.wi, m));
                    }
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------
// Reciprocity
// ---------------------------------------------------------------------------

#[test]
fn reflection_is_reciprocal_and_transmission_obeys_eta_squared_reciprocity() {
    let mut rng = Rng::new(12, 0);
    let (mut n_refl, mut n_trans) = (0, 0);
    for s in [tr(0.05), tr(0.4), beckmann(0.05), beckmann(0.4)] {
        let b = bsdf(ETA, s);
        for _ in 0..20_000 {
            let (wo, wi) = (uniform_sphere(&mut rng), uniform_sphere(&mut rng));
            let f = b.eval(wo, wi, Transport::Radiance);
            let r = b.eval(wi, wo, Transport::Radiance);
            assert!(f.is_finite() && f >= 0.0);
            if wo.z * wi.z > 0.0 {
                assert!((f - r).abs() <= 1e-8 * f.max(r), "{f} vs {r}");
                n_refl += usize::from(f > 0.0);
            } else {
                // n = 1 above, ETA below: f(wo, wi)/n_o² = f(wi, wo)/n_i².
                let (n_o, n_i) = if wo.z > 0.0 { (1.0, ETA) } else { (ETA, 1.0) };
                assert!((f / (n_o * n_o) - r / (n_i * n_i)).abs() <= 1e-8 * f.max(r), "{f} vs {r}");
                // Importance transport is the adjoint: f*(wo, wi) = f(wi, wo).
                let adj = b.eval(wo, wi, Transport::Importance);
                assert!((adj - r).abs() <= 1e-8 * adj.max(r), "{adj} vs {r} {wo} {wi}");
                n_trans += usize::from(f > 0.0);
                // The factor is not trivially 1: the two directions differ.
                if f > 0.0 {
                    assert!((f - r).abs() > 0.1 * f);
                }
            }
        }
    }
    assert!(n_refl > 1000 && n_trans > 1000, "{n_refl} {n_trans}");
}

// ---------------------------------------------------------------------------
// White furnace: ∫ f* cos dω_i = R + T = 1 (single scattering, α ≤ 0.2)
// ---------------------------------------------------------------------------

/// Directional albedo by sampling: mean weight (lost samples count 0) with
/// its standard error, and the reflected part with its standard error.
struct Albedo {
    total: f64,
    total_se: f64,
    refl: f64,
    refl_se: f64,
}

fn albedo(b: &Bsdf, wo: DVec3, n: usize, seed: u64, mode: Transport) -> Albedo {
    let mut rng = Rng::new(seed, 1);
    let (mut s, mut s2, mut r, mut r2) = (0.0, 0.0, 0.0, 0.0);
    for _ in 0..n {
        let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
        if let Some(x) = b.sample(wo, u, mode) {
            s += x.weight;
            s2 += x.weight * x.weight;
            if !x.transmitted {
                r += x.weight;
                r2 += x.weight * x.weight;
            }
        }
    }
    let nf = n as f64;
    let se = |s: f64, s2: f64| ((s2 / nf - (s / nf).powi(2)).max(0.0) / nf).sqrt();
    Albedo { total: s / nf, total_se: se(s, s2), refl: r / nf, refl_se: se(r, r2) }
}

#[test]
fn white_furnace_within_one_percent_for_alpha_up_to_0_2() {
    // ∫ f* |cos θ_i| dω_i = R + T (importance transport) for a dielectric.
    // Single scattering loses what leaves towards the wrong side. From the
    // dense side GGX's long tail puts a fraction ≈ α²/(1 + α²) of the
    // microfacets beyond the critical angle, whose total reflection goes
    // below the horizon: ≈ 1 % at α = 0.1, 4 % at α = 0.2 (Mitsuba 3 agrees:
    // tests `mitsuba_*` below). There the 1 % bound holds for α ≤ 0.05. From
    // the light side GGX at α = 0.2, θ = 60° loses 2.6 % (Mitsuba 3: 2.5 %),
    // so for GGX the bound is checked to α = 0.1.
    let mut seed = 50;
    for (make, is_tr) in [(tr as fn(f64) -> Microsurface, true), (beckmann, false)] {
        for alpha in [0.01, 0.05, 0.1, 0.2] {
            for (eta, below) in [(ETA, false), (1.0 / ETA, false), (ETA, true)] {
                let dense_side = eta < 1.0 || below;
                if is_tr && (alpha > 0.1 || dense_side && alpha > 0.05) {
                    continue;
                }
                // From the dense side only below the critical angle (45°):
                // beyond it rough total reflection loses several per cent.
                let thetas: &[f64] = if dense_side { &[0.0, 30.0] } else { &[0.0, 30.0, 60.0] };
                for &t in thetas {
                    let b = bsdf(eta, make(alpha));
                    let mut wo = dir(t, 10.0);
                    if below {
                        wo.z = -wo.z;
                    }
                    seed += 1;
                    let a = albedo(&b, wo, 20_000, seed, Transport::Importance);
                    assert!(a.total_se < 2e-3, "σ {}", a.total_se);
                    assert!(
                        (a.total - 1.0).abs() < 0.01,
                        "α {alpha} η {eta} θ {t} below {below}: R + T = {} ± {}",
                        a.total,
                        a.total_se
                    );
                    // The energy never exceeds one beyond noise.
                    assert!(a.total < 1.0 + 4.0 * a.total_se + 1e-9, "{} ± {}", a.total, a.total_se);
                }
            }
        }
    }
    // Radiance transport scales the transmitted part by (n_o/n_i)²: from air
    // into η at normal incidence T → (1 − F)/η².
    let b = bsdf(ETA, tr(0.01));
    let a = albedo(&b, DVec3::Z, 20_000, 3, Transport::Radiance);
    let f0 = fresnel::reflectance(1.0, ETA);
    assert!((a.refl - f0).abs() < 4.0 * a.refl_se + 1e-3, "{} vs {f0}", a.refl);
    assert!((a.total - a.refl - (1.0 - f0) / (ETA * ETA)).abs() < 4.0 * a.total_se + 1e-3, "{}", a.total);
}

#[test]
fn single_scattering_loses_energy_at_high_roughness() {
    // The furnace test can fail: at α = 0.7 and grazing incidence the single
    // scattering model loses several per cent (multiple scattering missing).
    let b = bsdf(ETA, tr(0.7));
    let a = albedo(&b, dir(80.0, 0.0), 20_000, 9, Transport::Importance);
    assert!(a.total < 0.97 && a.total_se < 0.01, "{}", a.total);
}

// ---------------------------------------------------------------------------
// ∫ D (m·n) dω = 1 and the Smith identity, by quadrature
// ---------------------------------------------------------------------------

/// ∫ g(m) dω_m over the upper hemisphere, m parametrised by t = tan θ_m =
/// scale·x/(1 − x) (x ∈ [0, 1)) and φ: composite Gauss–Legendre.
fn hemisphere_integral(scale: f64, panels_t: usize, panels_p: usize, g: &dyn Fn(DVec3) -> f64) -> f64 {
    let gl = gauss_legendre(8);
    let mut sum = 0.0;
    for a in 0..panels_t {
        let (x0, x1) = (a as f64 / panels_t as f64, (a + 1) as f64 / panels_t as f64);
        for &(xa, wa) in &gl {
            let x = 0.5 * (x0 + x1) + 0.5 * (x1 - x0) * xa;
            let t = scale * x / (1.0 - x);
            let dt = scale / ((1.0 - x) * (1.0 - x)) * 0.5 * (x1 - x0);
            let theta = t.atan();
            let dtheta = dt / (1.0 + t * t);
            for b in 0..panels_p {
                let (p0, p1) = (2.0 * PI * b as f64 / panels_p as f64, 2.0 * PI * (b + 1) as f64 / panels_p as f64);
                for &(xb, wb) in &gl {
                    let p = 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * xb;
                    let m = DVec3::new(theta.sin() * p.cos(), theta.sin() * p.sin(), theta.cos());
                    sum += wa * wb * g(m) * theta.sin() * dtheta * 0.5 * (p1 - p0);
                }
            }
        }
    }
    sum
}

#[test]
fn distributions_are_normalised_and_satisfy_the_smith_identity() {
    for alpha in ALPHAS.iter().copied().chain([0.002, 1.5]) {
        for d in [Distribution::TrowbridgeReitz { alpha }, Distribution::Beckmann { alpha }] {
            let norm = hemisphere_integral(alpha, 96, 4, &|m| d.d(m) * m.z);
            assert!((norm - 1.0).abs() < 1e-6, "{d:?}: ∫ D cos = {norm}");
            for t in [0.0, 30.0, 60.0, 85.0] {
                let w = dir(t, 20.0);
                let lhs = hemisphere_integral(alpha, 64, 32, &|m| d.g1(w, m) * w.dot(m).max(0.0) * d.d(m));
                assert!((lhs - w.z).abs() < 2e-4 * w.z + 1e-7, "{d:?} θ {t}: {lhs} vs {}", w.z);
                // Visible normals integrate to 1.
                let vis = hemisphere_integral(alpha, 64, 32, &|m| d.pdf_visible(w, m));
                assert!((vis - 1.0).abs() < 2e-4, "{d:?} θ {t}: ∫ D_ω = {vis}");
            }
        }
    }
    // Closed forms: D(n) = 1/(π α²) for both; Λ for TR at tan θ = 1/α is (√2 − 1)/2.
    let d = Distribution::TrowbridgeReitz { alpha: 0.3 };
    assert!((d.d(DVec3::Z) - 1.0 / (PI * 0.09)).abs() < 1e-12);
    let w = DVec3::new(1.0 / 0.3, 0.0, 1.0).normalize();
    assert!((d.lambda(w) - 0.5 * (2f64.sqrt() - 1.0)).abs() < 1e-12);
    // Beckmann Λ against Walter 2007's rational fit (≤ 0.35 % error in G1).
    let d = Distribution::Beckmann { alpha: 0.5 };
    for t in [20.0, 50.0, 70.0, 85.0] {
        let w = dir(t, 0.0);
        let a = 1.0 / (0.5 * t.to_radians().tan());
        let fit = if a < 1.6 { (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a) } else { 1.0 };
        let g1 = 1.0 / (1.0 + d.lambda(w));
        assert!((g1 - fit).abs() < 0.0035 * fit + 1e-4, "θ {t}: {g1} vs {fit}");
    }
}

// ---------------------------------------------------------------------------
// Smooth limit
// ---------------------------------------------------------------------------

#[test]
fn smooth_limit_gives_delta_lobes_with_fresnel_weights() {
    for alpha in [0.0, 0.5 * SMOOTH_ALPHA] {
        for make in [tr as fn(f64) -> Microsurface, beckmann] {
            for eta in [ETA, 1.0 / ETA] {
                let b = bsdf(eta, make(alpha));
                assert!(b.is_delta());
                for t in [0.0, 20.0, 44.0, 46.0, 70.0, 89.0] {
                    let wo = dir(t, 40.0);
                    let f = fresnel::reflectance(wo.z, eta);
                    assert_eq!(b.eval(wo, DVec3::new(-wo.x, -wo.y, wo.z), Transport::Radiance), 0.0);
                    assert_eq!(b.pdf(wo, DVec3::new(-wo.x, -wo.y, wo.z)), 0.0);
                    // The lobe is reflection exactly when u₀ < F.
                    let r = b.sample(wo, [0.999999 * f, 0.3, 0.3], Transport::Radiance).unwrap();
                    assert!(!r.transmitted && r.weight == 1.0);
                    assert!((r.wi - DVec3::new(-wo.x, -wo.y, wo.z)).length() < 1e-15);
                    if f < 1.0 {
                        let s = b.sample(wo, [f + 0.5 * (1.0 - f), 0.3, 0.3], Transport::Radiance).unwrap();
                        assert!(s.transmitted);
                        // Snell: sin θ_t = sin θ_o / η; radiance weight 1/η².
                        assert!((s.wi.truncate().length() - wo.truncate().length() / eta).abs() < 1e-12);
                        assert!(s.wi.z < 0.0 && (s.weight - 1.0 / (eta * eta)).abs() < 1e-12);
                        let i = b.sample(wo, [f + 0.5 * (1.0 - f), 0.3, 0.3], Transport::Importance).unwrap();
                        assert_eq!(i.weight, 1.0);
                    } else {
                        assert!(eta < 1.0 && t > 45.0, "total internal reflection only past the critical angle");
                    }
                }
            }
        }
    }
    // η = 1: an index-matched rough surface is invisible (straight through).
    let b = bsdf(1.0, tr(0.3));
    let wo = dir(30.0, 0.0);
    let s = b.sample(wo, [0.5, 0.5, 0.5], Transport::Radiance).unwrap();
    assert!(b.is_delta() && s.transmitted && (s.wi + wo).length() < 1e-12 && s.weight == 1.0);
    assert_eq!(b.eval(wo, -wo, Transport::Radiance), 0.0);
}

#[test]
fn nearly_smooth_rough_surface_matches_fresnel() {
    // Just above the threshold the rough model is finite and its directional
    // reflectance and transmittance approach Fresnel's.
    for alpha in [2.0 * SMOOTH_ALPHA, 1e-3] {
        for make in [tr as fn(f64) -> Microsurface, beckmann] {
            for eta in [ETA, 1.0 / ETA] {
                let b = bsdf(eta, make(alpha));
                assert!(!b.is_delta());
                for t in [0.0, 30.0, 60.0] {
                    let wo = dir(t, 0.0);
                    let mirror = DVec3::new(-wo.x, -wo.y, wo.z);
                    let f_spec = b.eval(wo, mirror, Transport::Radiance);
                    assert!(f_spec.is_finite() && f_spec > 0.0, "{f_spec}");
                    let a = albedo(&b, wo, 20_000, 77, Transport::Importance);
                    let f = fresnel::reflectance(wo.z, eta);
                    // Lobe selection is Bernoulli(F): allow 4σ plus 1e-3.
                    let tol = 4.0 * a.refl_se + 1e-3;
                    assert!((a.refl - f).abs() < tol, "α {alpha} η {eta} θ {t}: R {} vs F {f}", a.refl);
                    let t_est = a.total - a.refl;
                    assert!(
                        (t_est - (1.0 - f)).abs() < tol + 4.0 * a.total_se,
                        "α {alpha} η {eta} θ {t}: T {t_est} vs {}",
                        1.0 - f
                    );
                }
            }
        }
    }
    // No NaN anywhere for tiny α, grazing and exactly specular pairs.
    let mut rng = Rng::new(5, 0);
    for alpha in [SMOOTH_ALPHA, 1e-3] {
        for make in [tr as fn(f64) -> Microsurface, beckmann] {
            let b = bsdf(ETA, make(alpha));
            for _ in 0..5000 {
                let (wo, wi) = (uniform_sphere(&mut rng), uniform_sphere(&mut rng));
                for (x, y) in [(wo, wi), (wo, DVec3::new(-wo.x, -wo.y, wo.z)), (DVec3::X, wi), (wo, DVec3::X)] {
                    let f = b.eval(x, y, Transport::Radiance);
                    let p = b.pdf(x, y);
                    assert!(f.is_finite() && p.is_finite() && f >= 0.0 && p >= 0.0, "{x} {y}: {f} {p}");
                }
                let u = [rng.next_f64(), rng.next_f64(), rng.next_f64()];
                if let Some(s) = b.sample(wo, u, Transport::Radiance) {
                    assert!(s.weight.is_finite() && s.wi.is_finite() && b.pdf(wo, s.wi).is_finite());
                }
            }
            assert!(b.sample(DVec3::X, [0.5; 3], Transport::Radiance).is_none());
        }
    }
}

// ---------------------------------------------------------------------------
// Measured normals
// ---------------------------------------------------------------------------

/// `n` normals drawn from D(m)(m·n) (visible normals seen from +z are
/// exactly that distribution).
fn normals_from(d: Distribution, n: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut rng = Rng::new(seed, 0);
    (0..n).map(|_| d.sample_visible(DVec3::Z, [rng.next_f64(), rng.next_f64()]).unwrap().to_array()).collect()
}

#[test]
fn measured_normals_density_is_normalised_and_close_to_the_source() {
    // Beckmann α = 0.2 normals: slopes Gaussian with σ = α/√2 per axis.
    let alpha: f64 = 0.2;
    let normals = normals_from(Distribution::Beckmann { alpha }, 1500, 21);
    let m = MeasuredNormals::new(&normals, None).unwrap();
    // Silverman: h = √8 σ N^(−1/6) ≈ 0.118.
    let h = m.bandwidth();
    assert!((h / (8f64.sqrt() * alpha / 2f64.sqrt() * 1500f64.powf(-1.0 / 6.0)) - 1.0).abs() < 0.1, "h {h}");
    // ∫ K d²s = 1 → ∫ D (m·n) dω = 1.
    let norm = hemisphere_integral(alpha, 32, 32, &|v| m.d(v) * v.z);
    assert!((norm - 1.0).abs() < 1e-3, "∫ D cos = {norm}");
    // The slope density follows the source's P22 = exp(−s²/α²)/(π α²)
    // smoothed by the kernel (quadrature over the kernel's disk).
    let p22 = |x: f64, y: f64| (-(x * x + y * y) / (alpha * alpha)).exp() / (PI * alpha * alpha);
    let gl = gauss_legendre(16);
    let smoothed = |x: f64, y: f64| {
        let mut s = 0.0;
        for &(xa, wa) in &gl {
            let t = 0.5 * (xa + 1.0); // t = r²/h², d²s = (h²/2) dt dφ
            for &(xb, wb) in &gl {
                let p = PI * (xb + 1.0);
                let r = h * t.sqrt();
                s += wa * wb * (1.0 - t).powi(2) * p22(x + r * p.cos(), y + r * p.sin()) * 0.75;
            }
        }
        s
    };
    for (x, y) in [(0.0, 0.0), (0.1, 0.0), (0.0, -0.15), (0.15, 0.1)] {
        let est = m.slope_density([x, y]);
        let reference = smoothed(x, y);
        // Sampling noise of a kernel estimate: Var = (∫K² P22 − (∫K P22)²)/N,
        // ∫K² P22 ≈ P22 · 9/(5π h²).
        let sigma = ((reference * 9.0 / (5.0 * PI * h * h) - reference * reference) / 1500.0).sqrt();
        assert!((est - reference).abs() < 4.0 * sigma, "s ({x}, {y}): {est} vs {reference} ± {sigma}");
        // D(m) = P22 / cos⁴θ.
        let v = DVec3::new(-x, -y, 1.0).normalize();
        assert!((m.d(v) * v.z.powi(4) - est).abs() < 1e-12 * est);
    }
    // Smith identity with the tabulated projected area.
    for t in [0.0, 30.0, 60.0, 80.0] {
        let w = dir(t, 75.0);
        let lhs = hemisphere_integral(alpha, 32, 32, &|v| m.g1(w, v) * w.dot(v).max(0.0) * m.d(v));
        assert!((lhs / w.z - 1.0).abs() < 0.01, "θ {t}: {lhs} vs {}", w.z);
    }
}

#[test]
fn chi2_measured_normals() {
    // GGX normals: the heavy slope tail tests the kernel far from the peak.
    let normals = normals_from(Distribution::TrowbridgeReitz { alpha: 0.15 }, 1000, 22);
    let m = Arc::new(MeasuredNormals::new(&normals, None).unwrap());
    let mut seed = 3000;
    for (eta, below, t) in [(ETA, false, 10.0), (ETA, false, 60.0), (1.0 / ETA, false, 30.0), (ETA, true, 40.0)] {
        let b = bsdf(eta, Microsurface::Measured(m.clone()));
        let mut wo = dir(t, 30.0);
        if below {
            wo.z = -wo.z;
        }
        seed += 1;
        chi2_config(&b, wo, 0.15, 40_000, seed, &format!("measured η {eta:.4} θo {t}° below {below}"));
    }
    // The tabulated projected area against a stratified Monte Carlo estimate
    // of ∫ (ω·m)⁺ D dω = E[(ω·m)⁺/m_z] over the exact kernel sampler.
    for t in [0.0, 40.0, 70.0, 85.0] {
        let w = dir(t, 200.0);
        let k = 64 * m.len();
        let mut rng = Rng::new(23, 0);
        let mc = (0..k)
            .map(|i| {
                let v = m.sample_projected([(i as f64 + rng.next_f64()) / k as f64, rng.next_f64()]);
                w.dot(v).max(0.0) / v.z
            })
            .sum::<f64>()
            / k as f64;
        assert!((m.projected_area(w) / mc - 1.0).abs() < 2e-3, "θ {t}: A {} vs {mc}", m.projected_area(w));
    }
    // Close to the analytic BSDF it was drawn from: same albedo within 2 %.
    let a = bsdf(ETA, tr(0.15));
    let b = bsdf(ETA, Microsurface::Measured(m));
    for t in [0.0, 45.0] {
        let (x, y) = (
            albedo(&a, dir(t, 0.0), 20_000, 1, Transport::Importance),
            albedo(&b, dir(t, 0.0), 20_000, 2, Transport::Importance),
        );
        assert!(
            (x.total - y.total).abs() < 0.02 && (x.refl - y.refl).abs() < 0.01,
            "θ {t}: {} {} / {} {}",
            x.total,
            y.total,
            x.refl,
            y.refl
        );
    }
}

#[test]
fn bad_parameters_are_typed_errors() {
    assert!(matches!(Interface::new(tr(-0.1)), Err(MicrofacetError::Alpha(_))));
    assert!(matches!(Interface::new(beckmann(f64::NAN)), Err(MicrofacetError::Alpha(_))));
    assert!(matches!(Interface::new(beckmann(f64::INFINITY)), Err(MicrofacetError::Alpha(_))));
    assert!(matches!(MeasuredNormals::new(&[], None), Err(MicrofacetError::NoNormals)));
    let good = [0.0, 0.0, 1.0];
    for (bad, why) in [
        ([0.0, 0.0, 2.0], "not of unit length"),
        ([0.0, 0.0, -1.0], "does not face +z"),
        ([1.0, 0.0, 0.0], "does not face +z"),
        ([f64::NAN, 0.0, 1.0], "not finite"),
    ] {
        match MeasuredNormals::new(&[good, good, bad], None) {
            Err(MicrofacetError::Normal { index: 2, reason, .. }) => assert_eq!(reason, why),
            other => panic!("{bad:?}: {other:?}"),
        }
    }
    for h in [0.0, -0.1, 11.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(MeasuredNormals::new(&[good], Some(h)), Err(MicrofacetError::Bandwidth(_))));
    }
    let e = MeasuredNormals::new(&[good, [0.0, 0.0, -1.0]], None).unwrap_err().to_string();
    assert!(e.contains("#1") && e.contains("+z"), "{e}");
}

// ---------------------------------------------------------------------------
// Mitsuba 3 `roughdielectric` (tools/reference/microfacet_mitsuba.py)
// ---------------------------------------------------------------------------

fn fixture_rows(name: &str) -> Vec<Vec<String>> {
    let path = format!("{}/../fixtures/reference/microfacet/{name}", env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines().filter(|l| !l.starts_with('#')).skip(1).map(|l| l.split(',').map(str::to_owned).collect()).collect()
}

fn distribution(name: &str, alpha: f64) -> Distribution {
    match name {
        "ggx" => Distribution::TrowbridgeReitz { alpha },
        "beckmann" => Distribution::Beckmann { alpha },
        other => panic!("unknown distribution {other}"),
    }
}

/// lucent's generalised half-vector (as in the BSDF), facing +z.
fn half_vector(wo: DVec3, wi: DVec3, eta: f64) -> DVec3 {
    let etap = if wo.z * wi.z > 0.0 {
        1.0
    } else if wo.z > 0.0 {
        eta
    } else {
        1.0 / eta
    };
    let m = (wi * etap + wo).normalize();
    if m.z < 0.0 {
        -m
    } else {
        m
    }
}

#[test]
fn mitsuba_bsdf_values_and_pdfs_agree() {
    let rows = fixture_rows("mitsuba_roughdielectric.csv");
    assert!(rows.len() > 900, "{} rows", rows.len());
    let (mut worst_f, mut worst_p, mut worst_g_tr, mut worst_g_b) = (0.0f64, 0.0f64, 0.0f64, 0.0f64);
    let (mut n_trans, mut n_refl) = (0, 0);
    for r in &rows {
        let x: Vec<f64> = r[4..].iter().map(|v| v.parse().unwrap()).collect();
        let alpha: f64 = r[1].parse().unwrap();
        let eta: f64 = r[2].parse().unwrap();
        let mode = if r[3] == "radiance" { Transport::Radiance } else { Transport::Importance };
        let (wo, wi) = (DVec3::new(x[0], x[1], x[2]).normalize(), DVec3::new(x[3], x[4], x[5]).normalize());
        let (f_ref, pdf_ref, g_ref, g1o_ref) = (x[6], x[7], x[8], x[9]);
        let d = distribution(&r[0], alpha);
        let b = bsdf(eta, Microsurface::Analytic(d));
        let m = half_vector(wo, wi, eta);
        let (g1o, g) = (d.g1(wo, m), d.g1(wo, m) * d.g1(wi, m));
        // Smith G: exact for GGX (float32 rounding), Walter's fit for Beckmann.
        let dg = (g - g_ref).abs();
        if r[0] == "ggx" {
            worst_g_tr = worst_g_tr.max(dg);
        } else {
            worst_g_b = worst_g_b.max(dg / g_ref.max(1e-3));
        }
        // BSDF × cos and pdf, with Mitsuba's G swapped in.
        let f = b.eval(wo, wi, mode) * wi.z.abs();
        let p = b.pdf(wo, wi);
        let f_cmp = if g > 0.0 { f * g_ref / g } else { f };
        let p_cmp = if g1o > 0.0 { p * g1o_ref / g1o } else { p };
        let scale = f_ref.abs().max(1e-6);
        let ef = (f_cmp - f_ref).abs() / scale;
        let ep = (p_cmp - pdf_ref).abs() / pdf_ref.abs().max(1e-6);
        assert!(ef < 2e-3, "{r:?}: f cos {f_cmp} (unswapped {f}) vs {f_ref}");
        assert!(ep < 2e-3, "{r:?}: pdf {p_cmp} (unswapped {p}) vs {pdf_ref}");
        worst_f = worst_f.max(ef);
        worst_p = worst_p.max(ep);
        if f_ref > 1e-3 {
            if wo.z * wi.z < 0.0 {
                n_trans += 1;
            } else {
                n_refl += 1;
            }
        }
    }
    assert!(worst_g_tr < 2e-5, "GGX G {worst_g_tr}");
    assert!(worst_g_b < 8e-3, "Beckmann G {worst_g_b}");
    assert!(n_trans > 200 && n_refl > 100, "{n_trans} {n_refl}");
    println!("worst relative f {worst_f:.2e}, pdf {worst_p:.2e}, GGX G {worst_g_tr:.2e}, Beckmann G {worst_g_b:.2e}");
}

#[test]
fn mitsuba_albedo_agrees_where_single_scattering_loses_energy() {
    for r in fixture_rows("mitsuba_albedo.csv") {
        let alpha: f64 = r[1].parse().unwrap();
        let eta: f64 = r[2].parse().unwrap();
        let theta: f64 = r[3].parse().unwrap();
        let (reference, se_ref): (f64, f64) = (r[5].parse().unwrap(), r[6].parse().unwrap());
        let d = distribution(&r[0], alpha);
        let b = bsdf(eta, Microsurface::Analytic(d));
        let a = albedo(&b, dir(theta, 0.0), 40_000, 31, Transport::Importance);
        let sigma = (a.total_se.powi(2) + se_ref.powi(2)).sqrt();
        // Mitsuba's Beckmann G1 fit adds up to 0.35 % per factor.
        let model = if r[0] == "beckmann" { 0.004 } else { 0.0 };
        assert!(
            (a.total - reference).abs() < 4.0 * sigma + model,
            "{r:?}: {} ± {} vs Mitsuba {reference} ± {se_ref}",
            a.total,
            a.total_se
        );
    }
}
