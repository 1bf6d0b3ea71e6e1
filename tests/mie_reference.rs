//! Lorenz–Mie core against independent references: 320+ random cases from
//! miepython 3.3 (efficiencies, g, |S₁|², |S₂|² at seven angles) and the
//! published Wiscombe (1979) / Bohren & Huffman (1983) test values. The
//! fixtures are made by `tools/reference/mie_miepython.py`; see
//! `tools/reference/README.md`.

use lucent::optics::mie::Coefficients;
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
