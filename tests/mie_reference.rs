//! Lorenz–Mie core against independent references: 320+ random cases from
//! miepython 3.3 (efficiencies, g, |S₁|², |S₂|² at seven angles), the
//! published Wiscombe (1979) / Bohren & Huffman (1983) test values, very
//! small spheres (x = 1e-8 … 3) from miepython audited with mpmath, and
//! spheres in absorbing hosts from spherical Bessel functions of complex
//! argument (scipy). The fixtures are made by the scripts in
//! `tools/reference/`; see `tools/reference/README.md`.

use lucent::optics::mie::{attenuation, efficiencies_in_host, Coefficients, SERIES_BELOW};
use num_complex::Complex64;
use std::collections::HashMap;

struct Table {
    header: Vec<String>,
    rows: Vec<Vec<String>>,
}

impl Table {
    fn read(path: &str) -> Table {
        let full = format!("{}/{path}", env!("CARGO_MANIFEST_DIR"));
        let text = std::fs::read_to_string(&full).unwrap_or_else(|e| panic!("{full}: {e}"));
        let mut lines = text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty());
        let header = lines.next().expect("header").split(',').map(|s| s.trim().to_string()).collect();
        let rows = lines.map(|l| l.split(',').map(|s| s.trim().to_string()).collect()).collect();
        Table { header, rows }
    }

    fn maps(&self) -> Vec<HashMap<&str, &str>> {
        self.rows
            .iter()
            .map(|r| self.header.iter().map(String::as_str).zip(r.iter().map(String::as_str)).collect())
            .collect()
    }
}

fn num(row: &HashMap<&str, &str>, key: &str) -> Option<f64> {
    row.get(key).filter(|s| !s.is_empty()).map(|s| s.parse().unwrap_or_else(|_| panic!("{key}: {s:?}")))
}

fn rel(a: f64, b: f64) -> f64 {
    if a == b {
        0.0
    } else {
        (a - b).abs() / b.abs().max(1e-300)
    }
}

#[test]
fn miepython_random_cases() {
    let table = Table::read("fixtures/reference/mie_miepython.csv");
    let rows = table.maps();
    assert!(rows.len() >= 300, "only {} cases", rows.len());
    let angles: Vec<(f64, String, String)> = table
        .header
        .iter()
        .filter_map(|h| h.strip_prefix("s1sq_"))
        .map(|deg| (deg.parse::<f64>().expect("angle"), format!("s1sq_{deg}"), format!("s2sq_{deg}")))
        .collect();
    assert!(angles.len() >= 5, "S1/S2 at too few angles");
    let mut errors: Vec<(f64, String)> = Vec::new();
    let mut c = Coefficients::new();
    for row in &rows {
        let m = Complex64::new(num(row, "m_re").unwrap(), num(row, "m_im").unwrap());
        let x = num(row, "x").unwrap();
        c.recompute(m, Complex64::new(x, 0.0)).unwrap();
        let q = c.efficiencies(x);
        let mut check = |name: &str, ours: f64, theirs: f64, floor: f64| {
            // Relative 1e-6, with an absolute floor for quantities that are
            // tiny next to their scale (g of a Rayleigh sphere, S at a minimum).
            let e = (ours - theirs).abs() / theirs.abs().max(floor);
            errors.push((e, format!("{name} m={m} x={x}: ours {ours} miepython {theirs}")));
        };
        check("qext", q.qext, num(row, "qext").unwrap(), 0.0);
        check("qsca", q.qsca, num(row, "qsca").unwrap(), 0.0);
        check("qback", q.qback, num(row, "qback").unwrap(), 1e-12 * q.qext);
        check("g", q.g, num(row, "g").unwrap(), 1e-6);
        let forward = c.amplitudes(1.0).0.norm_sqr();
        for (deg, k1, k2) in &angles {
            let (s1, s2) = c.amplitudes(deg.to_radians().cos());
            check(k1, s1.norm_sqr(), num(row, k1).unwrap(), 1e-9 * forward);
            check(k2, s2.norm_sqr(), num(row, k2).unwrap(), 1e-9 * forward);
        }
    }
    errors.sort_by(|a, b| b.0.total_cmp(&a.0));
    let report: Vec<String> = errors.iter().take(8).map(|(e, s)| format!("{e:.2e} {s}")).collect();
    assert!(errors[0].0 < 1e-6, "worst relative differences:\n{}", report.join("\n"));
}

#[test]
fn published_wiscombe_and_bohren_huffman_cases() {
    let table = Table::read("fixtures/reference/mie_published.csv");
    let rows = table.maps();
    assert!(rows.len() >= 10, "only {} published cases", rows.len());
    for row in &rows {
        let m = Complex64::new(num(row, "m_re").unwrap(), num(row, "m_im").unwrap());
        let x = num(row, "x").unwrap();
        let digits = num(row, "digits").unwrap_or(5.0);
        // A value published with d significant digits is good to half a unit in the last one.
        let tol = 0.5 * 10f64.powf(1.0 - digits) * 1.0001;
        let q = Coefficients::compute(m, Complex64::new(x, 0.0)).unwrap().efficiencies(x);
        for (key, ours) in [("qext", q.qext), ("qsca", q.qsca), ("qback", q.qback), ("g", q.g)] {
            if let Some(published) = num(row, key) {
                let e = rel(ours, published);
                assert!(
                    e <= tol,
                    "{}: {key} for m={m}, x={x}: ours {ours}, published {published} (rel {e:.2e} > {tol:.1e})",
                    row.get("source").copied().unwrap_or("?")
                );
            }
        }
    }
}

#[test]
fn small_spheres_match_miepython_down_to_x_1e8() {
    let table = Table::read("fixtures/reference/mie_small_x.csv");
    let rows = table.maps();
    assert!(rows.len() >= 200, "only {} cases", rows.len());
    let xs: Vec<f64> = rows.iter().map(|r| num(r, "x").unwrap()).collect();
    assert!(
        xs.iter().any(|&x| x <= 1e-8) && xs.iter().any(|&x| x < SERIES_BELOW) && xs.iter().any(|&x| x > SERIES_BELOW)
    );
    assert!(rows.iter().any(|r| num(r, "m_im").unwrap() > 0.0) && rows.iter().any(|r| num(r, "m_im").unwrap() == 0.0));
    // Worst (qext or qsca relative, g absolute) for the real-x path and for
    // the complex-x path (an absorbing m in an absorbing host of
    // Im x = 1e-16 Re x, which changes nothing visible here; for a real m
    // the host's absorption would dominate qext).
    let mut worst =
        [((0.0f64, String::new()), (0.0f64, String::new())), ((0.0f64, String::new()), (0.0f64, String::new()))];
    let mut c = Coefficients::new();
    for row in &rows {
        let m = Complex64::new(num(row, "m_re").unwrap(), num(row, "m_im").unwrap());
        let x = num(row, "x").unwrap();
        let mut paths = vec![(0, Complex64::new(x, 0.0))];
        if m.im > 0.0 {
            paths.push((1, Complex64::new(x, 1e-16 * x)));
        }
        for (path, xc) in paths {
            c.recompute(m, xc).unwrap();
            let q = c.efficiencies(xc.norm());
            let (worst_q, worst_g) = &mut worst[path];
            for (name, ours, theirs) in
                [("qext", q.qext, num(row, "qext").unwrap()), ("qsca", q.qsca, num(row, "qsca").unwrap())]
            {
                let e = rel(ours, theirs);
                if e > worst_q.0 {
                    *worst_q = (e, format!("{name} m={m} x={xc}: ours {ours:e}, miepython {theirs:e}"));
                }
            }
            let e = (q.g - num(row, "g").unwrap()).abs();
            if e > worst_g.0 {
                *worst_g = (e, format!("g m={m} x={xc}: ours {:e}, miepython {:e}", q.g, num(row, "g").unwrap()));
            }
        }
    }
    for (label, (q, g)) in ["real x", "complex x"].iter().zip(&worst) {
        println!("{label}: worst {:.1e} ({}); {:.1e} ({})", q.0, q.1, g.0, g.1);
        assert!(q.0 < 1e-6, "qext/qsca: {}", q.1);
        assert!(g.0 < 1e-9, "g: {}", g.1);
    }
}

#[test]
fn small_sphere_results_are_continuous_across_the_series_switch() {
    // Just below SERIES_BELOW the power series gives ψ_n, just above the
    // upward recurrence: the efficiencies must change only as the functions
    // do (relative slope of qsca ≈ 4/x, so the step of 2e-10 in x changes it
    // by ~8e-10; measured largest change 7.1e-10).
    let mut worst: f64 = 0.0;
    for m in [Complex64::new(1.5, 0.0), Complex64::new(0.9, 0.1), Complex64::new(2.5, 1.0)] {
        for host_im in [0.0, 1e-3] {
            let at = |x: f64| {
                // |xc| = x, so that the switch (on |x|) falls between the two.
                let u = Complex64::new(1.0, host_im);
                let xc = u / u.norm() * x;
                let c = Coefficients::compute(m, xc).unwrap();
                c.efficiencies(xc.norm())
            };
            let h = 1e-10;
            let (below, above) = (at(SERIES_BELOW * (1.0 - h)), at(SERIES_BELOW * (1.0 + h)));
            for (name, a, b) in
                [("qext", below.qext, above.qext), ("qsca", below.qsca, above.qsca), ("g", below.g, above.g)]
            {
                assert!(rel(a, b) < 2e-9, "{name} m={m} host_im={host_im}: {a:e} below, {b:e} above");
                worst = worst.max(rel(a, b));
            }
        }
    }
    println!("largest relative change across |x| = {SERIES_BELOW} ± 1e-10: {worst:.1e}");
}

#[test]
fn absorbing_host_matches_the_bessel_reference() {
    let table = Table::read("fixtures/reference/mie_absorbing_host.csv");
    let rows = table.maps();
    assert!(rows.len() >= 40, "only {} cases", rows.len());
    let col = |k: &str| rows.iter().map(|r| num(r, k).unwrap()).collect::<Vec<f64>>();
    let (kh, radii, kp) = (col("nh_im"), col("radius_um"), col("np_im"));
    let span = |v: &[f64]| v.iter().fold((f64::INFINITY, 0.0f64), |(a, b), &x| (a.min(x), b.max(x)));
    assert_eq!(span(&kh), (1e-6, 5e-2), "κh range");
    assert_eq!(span(&radii), (0.05, 6.0), "radius range");
    assert!(kp.contains(&0.0) && kp.iter().any(|&k| k > 0.0), "absorbing and clear particles");

    let mut worst = (0.0f64, String::new());
    let mut worst_g = (0.0f64, String::new());
    for row in &rows {
        let nh = Complex64::new(num(row, "nh_re").unwrap(), num(row, "nh_im").unwrap());
        let np = Complex64::new(num(row, "np_re").unwrap(), num(row, "np_im").unwrap());
        let (lam, r) = (num(row, "wavelength_nm").unwrap() * 1e-9, num(row, "radius_um").unwrap() * 1e-6);
        let case = format!("λ={lam:e} r={r:e} nh={nh} np={np}");
        let q = efficiencies_in_host(np, nh, lam, r).unwrap_or_else(|e| panic!("{case}: {e}"));
        // The reference evaluates F from its closed form in 50 digits.
        let alpha = 4.0 * std::f64::consts::PI * r * nh.im / lam;
        assert!(rel(alpha, num(row, "alpha").unwrap()) < 1e-14, "{case}: α");
        assert!(rel(attenuation(alpha), num(row, "attenuation").unwrap()) < 1e-13, "{case}: F({alpha})");
        for (name, ours, theirs) in [
            ("qext", q.qext, num(row, "qext").unwrap()),
            ("qsca", q.qsca, num(row, "qsca").unwrap()),
            ("qabs", q.qabs, num(row, "qabs").unwrap()),
        ] {
            let e = rel(ours, theirs);
            if e > worst.0 {
                worst = (e, format!("{name} {case}: ours {ours:e}, reference {theirs:e}"));
            }
        }
        // qabs is the power absorbed inside the sphere: never negative, and
        // zero exactly when the sphere does not absorb.
        assert!(q.qabs >= 0.0, "qabs = {} < 0 for {case}", q.qabs);
        assert_eq!(q.qabs == 0.0, np.im == 0.0, "{case}: qabs = {}", q.qabs);
        let e = (q.g - num(row, "g").unwrap()).abs();
        if e > worst_g.0 {
            worst_g = (e, format!("g {case}: ours {}, reference {}", q.g, num(row, "g").unwrap()));
        }
    }
    println!("worst: {:.1e} ({}); g {:.1e} ({})", worst.0, worst.1, worst_g.0, worst_g.1);
    assert!(worst.0 < 1e-6, "{}", worst.1);
    assert!(worst_g.0 < 1e-6, "{}", worst_g.1);
}
