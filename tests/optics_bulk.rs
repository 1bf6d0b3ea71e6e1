//! Bulk optical properties of recipes (SPEC §1): physical bounds on the
//! shipped samples, phase-table normalisation and mean cosine, size
//! integration convergence, volume-fraction scaling, the absorbing-host
//! limits, the volume-weighted absorption formula and the effective index
//! against Maxwell Garnett in the Rayleigh limit.

use lucent::optics::bulk::{self, Options};
use lucent::optics::mie::Coefficients;
use lucent::optics::recipe::{Overrides, Recipe};
use lucent_colour::WavelengthGrid;
use num_complex::Complex64;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};

fn samples_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/samples")
}

fn shipped() -> Vec<Recipe> {
    let mut v = Vec::new();
    for nn in 5..=16 {
        let p = samples_dir().join(format!("IOL1068-{nn:02}.toml"));
        let r = Recipe::load(&p, Overrides { weight_percent: (nn == 15).then_some(1.0) });
        v.push(r.unwrap_or_else(|e| panic!("{e}")));
    }
    v
}

/// Trapezoid in μ over θ-uniform nodes: (∫p dΩ, ∫p μ dΩ).
fn table_moments(p: &[f64]) -> (f64, f64) {
    let n = p.len();
    let (mut norm, mut mean) = (0.0, 0.0);
    for i in 0..n - 1 {
        let t0 = PI * i as f64 / (n - 1) as f64;
        let t1 = PI * (i + 1) as f64 / (n - 1) as f64;
        let (m0, m1) = (t0.cos(), t1.cos());
        let dm = m0 - m1;
        norm += 2.0 * PI * 0.5 * (p[i] + p[i + 1]) * dm;
        // ∫ μ p dμ with p linear in μ over the bin.
        let (a, b) = (p[i], p[i + 1]);
        mean += 2.0 * PI * dm * (a * (2.0 * m0 + m1) + b * (m0 + 2.0 * m1)) / 6.0;
    }
    (norm, mean)
}

#[test]
fn shipped_samples_are_physical() {
    let grid = WavelengthGrid::visible();
    for r in shipped() {
        let s = bulk::compute(&r, &grid, &Options::default()).unwrap();
        assert_eq!(s.wavelength_nm.len(), 41);
        let n_host = r.host.index.at(550.0, r.host.extrapolation).unwrap().index.re;
        for i in 0..41 {
            let w = s.wavelength_nm[i];
            assert!(s.mu_s_per_m[i] > 0.0 && s.mu_s_per_m[i].is_finite(), "{} μs at {w}", r.name);
            assert!(s.mu_a_per_m[i] >= 0.0, "{} μa at {w} = {}", r.name, s.mu_a_per_m[i]);
            assert!((s.mu_t_per_m[i] - s.mu_s_per_m[i] - s.mu_a_per_m[i]).abs() <= 1e-9 * s.mu_t_per_m[i]);
            assert!(s.g[i] > 0.0 && s.g[i] < 1.0, "{} g at {w} = {}", r.name, s.g[i]);
            assert!((s.n_bulk[i] - n_host).abs() < 0.1, "{} n_bulk at {w} = {}", r.name, s.n_bulk[i]);
            // The table integrates to 1 in its own representation (linear in
            // cos θ between nodes uniform in θ, as the renderer samples it)...
            let (norm, mean) = table_moments(&s.phase[i]);
            assert!((norm - 1.0).abs() < 1e-12, "{} phase integral at {w}: {norm}", r.name);
            // ...its Lorenz–Mie normalisation was right before that to the
            // table's resolution, and its mean cosine is the coefficients' g.
            let raw = s.phase_integral_before_normalisation[i];
            assert!((raw - 1.0).abs() < 1e-3, "{} raw phase integral at {w}: {raw}", r.name);
            assert!((mean - s.g[i]).abs() < 1e-3, "{} table mean cosine {mean} vs g {} at {w}", r.name, s.g[i]);
        }
        // The Zhang-based media start at 400 nm: clamping must be reported.
        assert!(s.warnings.iter().any(|w| w.contains("clamped") && w.contains("380")), "{}: {:?}", r.name, s.warnings);
    }
}

/// A recipe over index files written on the fly.
fn custom_recipe(dir: &Path, host: (f64, f64), particle: (f64, f64), size: &str, wt: f64, absorption: &str) -> Recipe {
    let yml = |n: f64, k: f64| format!("DATA:\n  - type: tabulated nk\n    data: |\n        0.30 {n} {k}\n        1.00 {n} {k}\n");
    std::fs::write(dir.join("host.yml"), yml(host.0, host.1)).unwrap();
    std::fs::write(dir.join("particle.yml"), yml(particle.0, particle.1)).unwrap();
    let text = format!(
        r#"
thickness_mm = 1
absorption = "{absorption}"
[host]
name = "host"
index = "host.yml"
density_g_per_ml = 1.2
[[particles]]
name = "p"
index = "particle.yml"
density_g_per_ml = 1.2
weight_percent = {wt}
size = {size}
"#
    );
    let path = dir.join("r.toml");
    std::fs::write(&path, text).unwrap();
    Recipe::load(&path, Overrides::default()).unwrap()
}

fn at(r: &Recipe, w: f64, opts: &Options) -> bulk::Sample {
    bulk::at_wavelength(r, w, opts).unwrap()
}

#[test]
fn monodisperse_bookkeeping_matches_efficiency() {
    // Real host: μs = φ · Qsca · πr² / (4/3 π r³) = 3φ Qsca / (4r).
    let dir = tempfile::tempdir().unwrap();
    let r = custom_recipe(dir.path(), (1.5, 0.0), (1.4, 0.0), r#"{ kind = "diameter", diameter_um = 2.0 }"#, 1.0, "mie");
    let s = at(&r, 500.0, &Options { phase_entries: 0, ..Default::default() });
    let phi = 0.01; // equal densities
    let x = 2.0 * PI * 1e-6 * 1.5 / 500e-9;
    let q = Coefficients::compute(Complex64::new(1.4 / 1.5, 0.0), Complex64::new(x, 0.0)).unwrap().efficiencies(x);
    let expected = 3.0 * phi * q.qsca / (4.0 * 1e-6);
    assert!((s.mu_s_per_m / expected - 1.0).abs() < 1e-12, "{} vs {expected}", s.mu_s_per_m);
    assert!(s.mu_a_per_m.abs() < 1e-9 * s.mu_s_per_m);
    assert!((s.g - q.g).abs() < 1e-12);
}

#[test]
fn scattering_scales_with_weight_percent() {
    let dir = tempfile::tempdir().unwrap();
    let size = r#"{ kind = "diameter", diameter_um = 0.9 }"#;
    let opts = Options { phase_entries: 0, ..Default::default() };
    let a = at(&custom_recipe(dir.path(), (1.59, 1e-6), (1.49, 1e-6), size, 0.5, "mie"), 550.0, &opts);
    let b = at(&custom_recipe(dir.path(), (1.59, 1e-6), (1.49, 1e-6), size, 1.0, "mie"), 550.0, &opts);
    assert!((b.mu_s_per_m / a.mu_s_per_m - 2.0).abs() < 1e-12);
}

#[test]
fn size_distributions_converge() {
    let dir = tempfile::tempdir().unwrap();
    for size in [
        r#"{ kind = "range", min_um = 8, max_um = 10, distribution = "uniform" }"#,
        r#"{ kind = "range", min_um = 0.8, max_um = 1.0, distribution = "uniform" }"#,
        r#"{ kind = "log-normal", median_diameter_um = 2.2, sigma = 0.15 }"#,
    ] {
        let r = custom_recipe(dir.path(), (1.5889, 4e-7), (1.53, 2e-3), size, 3.5, "mie");
        let coarse = at(&r, 450.0, &Options { phase_entries: 0, size_tolerance: 1e-6 });
        let fine = at(&r, 450.0, &Options { phase_entries: 4096, size_tolerance: 1e-10 });
        let change = (coarse.mu_s_per_m / fine.mu_s_per_m - 1.0).abs();
        assert!(change < 1e-4, "{size}: μs changes by {change:e} when refined");
        assert!((coarse.g - fine.g).abs() < 1e-4, "{size}: g {} vs {}", coarse.g, fine.g);
        let (norm, mean) = table_moments(&fine.phase);
        assert!((norm - 1.0).abs() < 1e-12, "{size}: phase integral {norm}");
        assert!((fine.phase_integral_before_normalisation - 1.0).abs() < 2e-3, "{size}: {}", fine.phase_integral_before_normalisation);
        assert!((mean - fine.g).abs() < 1e-3, "{size}: mean cosine {mean} vs g {}", fine.g);
    }
    // A vanishingly narrow uniform range is the monodisperse result.
    let narrow = custom_recipe(dir.path(), (1.5, 0.0), (1.4, 0.0), r#"{ kind = "range", min_um = 1.9999, max_um = 2.0001, distribution = "uniform" }"#, 1.0, "mie");
    let mono = custom_recipe(dir.path(), (1.5, 0.0), (1.4, 0.0), r#"{ kind = "diameter", diameter_um = 2.0 }"#, 1.0, "mie");
    let opts = Options { phase_entries: 0, ..Default::default() };
    let (a, b) = (at(&narrow, 500.0, &opts), at(&mono, 500.0, &opts));
    assert!((a.mu_s_per_m / b.mu_s_per_m - 1.0).abs() < 1e-6);
}

#[test]
fn absorption_is_never_negative() {
    // Clear particles displacing a strongly absorbing host, at high loading.
    let dir = tempfile::tempdir().unwrap();
    let grid = WavelengthGrid::new(380.0, 780.0, 40.0).unwrap();
    for (size, wt) in [(r#"{ kind = "diameter", diameter_um = 5.0 }"#, 30.0), (r#"{ kind = "diameter", diameter_um = 0.05 }"#, 30.0)] {
        for kh in [1e-3, 1e-5, 0.0] {
            let r = custom_recipe(dir.path(), (1.59, kh), (1.3, 0.0), size, wt, "mie");
            let s = bulk::compute(&r, &grid, &Options { phase_entries: 0, ..Default::default() }).unwrap();
            for (w, a) in s.wavelength_nm.iter().zip(&s.mu_a_per_m) {
                assert!(*a >= 0.0, "{size} κh={kh}: μa({w}) = {a}");
            }
        }
    }
}

#[test]
fn volume_weighted_absorption_formula() {
    let dir = tempfile::tempdir().unwrap();
    let (kh, kp) = (4e-7, 2e-3);
    let r = custom_recipe(dir.path(), (1.5889, kh), (1.53, kp), r#"{ kind = "diameter", diameter_um = 9.0 }"#, 3.5, "volume-weighted");
    let s = at(&r, 600.0, &Options { phase_entries: 0, ..Default::default() });
    let phi = 0.035;
    let lam = 600e-9;
    let expected = (1.0 - phi) * 4.0 * PI * kh / lam + phi * 4.0 * PI * kp / lam;
    assert!((s.mu_a_per_m / expected - 1.0).abs() < 1e-12, "{} vs {expected}", s.mu_a_per_m);
    assert!((s.mu_t_per_m - s.mu_s_per_m - s.mu_a_per_m).abs() < 1e-9 * s.mu_t_per_m);
}

#[test]
fn effective_index_matches_maxwell_garnett_for_small_spheres() {
    // Rayleigh limit: van de Hulst's n_eff → n_h (1 + 3/2 φ (m²−1)/(m²+2)) to first order in φ.
    let dir = tempfile::tempdir().unwrap();
    let (nh, np) = (1.5, 2.5);
    let wt = 1.0; // φ = 0.01 with equal densities
    let r = custom_recipe(dir.path(), (nh, 0.0), (np, 0.0), r#"{ kind = "diameter", diameter_um = 0.004 }"#, wt, "mie");
    let s = at(&r, 550.0, &Options { phase_entries: 0, ..Default::default() });
    let m2 = (np / nh) * (np / nh);
    let expected = nh * (1.0 + 1.5 * 0.01 * (m2 - 1.0) / (m2 + 2.0));
    let shift = expected - nh;
    assert!(((s.n_bulk - nh) / shift - 1.0).abs() < 1e-3, "n_bulk {} vs Maxwell Garnett {expected}", s.n_bulk);
}

#[test]
fn absorbing_host_tends_to_real_host() {
    let dir = tempfile::tempdir().unwrap();
    let size = r#"{ kind = "diameter", diameter_um = 2.2 }"#;
    let opts = Options { phase_entries: 0, ..Default::default() };
    let real = at(&custom_recipe(dir.path(), (1.5889, 0.0), (1.41, 1e-6), size, 0.65, "mie"), 550.0, &opts);
    let nearly = at(&custom_recipe(dir.path(), (1.5889, 1e-12), (1.41, 1e-6), size, 0.65, "mie"), 550.0, &opts);
    assert!((nearly.mu_s_per_m / real.mu_s_per_m - 1.0).abs() < 1e-8);
    assert!((nearly.g - real.g).abs() < 1e-8);
    // μa differs by the host's own absorption (1 − φ)·4πκ/λ, up to the
    // absorption of the host volume the particles displace (order φ·4πκ/λ).
    let phi = (0.65 / 0.965) / (100.0 / 1.2);
    let alpha = 4.0 * PI * 1e-12 / 550e-9;
    let diff = nearly.mu_a_per_m - real.mu_a_per_m;
    assert!(
        (diff - (1.0 - phi) * alpha).abs() < 2.0 * phi * alpha,
        "μa {} vs {} (host term {:e})",
        nearly.mu_a_per_m,
        real.mu_a_per_m,
        (1.0 - phi) * alpha
    );
}
