//! `lucent mie` and `lucent optics`: absorbing hosts
//! never give a negative qabs, very small spheres are exact, and the folder
//! of shipped recipes prints the lab-formula table with its corrections.

use crate::common;
use common::{lucent, stderr, stdout};

fn json(o: &std::process::Output) -> serde_json::Value {
    assert!(o.status.success(), "{}", stderr(o));
    serde_json::from_str(&stdout(o)).unwrap_or_else(|e| panic!("{e}: {}", stdout(o)))
}

fn field(v: &serde_json::Value, k: &str) -> f64 {
    v[k].as_f64().unwrap_or_else(|| panic!("no {k} in {v}"))
}

#[test]
fn mie_never_prints_a_negative_qabs_in_an_absorbing_host() {
    // (The library function behind it is checked on 60 reference spheres in
    // tests/mie_reference.rs; here the command itself, on a coarser grid.)
    for host in ["1.5", "1.5+1e-6i", "1.5+1e-2i", "1.33+5e-2i"] {
        for particle in ["1.2", "1.5", "2.7+0.05i"] {
            for radius in ["0.01", "1", "6"] {
                let args = [
                    "mie",
                    "--radius-um",
                    radius,
                    "--wavelength-nm",
                    "550",
                    "--host-index",
                    host,
                    "--particle-index",
                    particle,
                ];
                let v = json(&lucent(&args));
                let qabs = field(&v, "qabs");
                assert!(qabs >= 0.0 && !v["qabs"].to_string().starts_with('-'), "{args:?}: {v}");
                if !particle.contains('i') {
                    assert_eq!(qabs, 0.0, "{args:?}: a clear sphere absorbs nothing: {v}");
                }
            }
        }
    }
    // The case: before the attenuation factor, qsca 1.755 > qext 1.387.
    let o = lucent(&[
        "mie",
        "--radius-um",
        "1",
        "--wavelength-nm",
        "550",
        "--host-index",
        "1.5+1e-2i",
        "--particle-index",
        "1.2",
    ]);
    let v = json(&o);
    assert!((field(&v, "qext") - 1.38693).abs() < 1e-5, "{v}");
    assert!((field(&v, "qsca") - 1.19736).abs() < 1e-5, "{v}");
    assert!(stderr(&o).contains("absorbed inside the sphere"), "{}", stderr(&o));
}

#[test]
fn mie_is_exact_for_very_small_spheres() {
    // The cases; miepython: g = 1.5e-13 at x = 1e-6, m = 0.9.
    let v = json(&lucent(&["mie", "--size-parameter", "1e-6", "--relative-index", "0.9"]));
    assert!(field(&v, "g").abs() < 1e-12, "{v}");
    // Rayleigh: qsca = 8/3 x⁴ |(m²−1)/(m²+2)|² to O(x²).
    for (x, m) in [(1e-6f64, 0.9f64), (1e-8, 1.5)] {
        let v = json(&lucent(&["mie", "--size-parameter", &x.to_string(), "--relative-index", &m.to_string()]));
        let l = (m * m - 1.0) / (m * m + 2.0);
        let rayleigh = 8.0 / 3.0 * x.powi(4) * l * l;
        assert!((field(&v, "qsca") / rayleigh - 1.0).abs() < 1e-9, "x={x} m={m}: {v}");
        assert!(field(&v, "g").abs() < 1e-9, "x={x} m={m}: {v}");
    }
}

#[test]
fn optics_folder_prints_the_lab_formula_table_with_its_corrections() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = lucent(&[
        "optics",
        "fixtures/samples",
        "--skip-invalid",
        "--phase-entries",
        "0",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(
        text.contains(
            "absorption volume-weighted-full-host: μa = 4πκh/λ + Σ φi·4πκi/λ (the lab's formula) [all samples]"
        ),
        "{text}"
    );
    assert!(
        text.contains(
            "particle PVP (polyvinylpyrrolidone): κ replaced by 0 (n kept) [IOL1068-11, IOL1068-12, IOL1068-13]"
        ),
        "{text}"
    );
    assert!(
        text.contains("host polycarbonate: n shifted to 1.5889 at 550 nm (dispersion and κ kept) [all samples]"),
        "{text}"
    );
    // The PVP rows at 550 nm: μa is the host's 4πκh/λ alone (κh = 4.08e-7 there).
    let host = 4.0 * std::f64::consts::PI * 4.08e-7 / 550e-9;
    let row =
        text.lines().find(|l| l.starts_with("IOL1068-12") && l.split_whitespace().nth(1) == Some("550")).expect("row");
    let mu_a: f64 = row.split_whitespace().nth(3).unwrap().parse().unwrap();
    assert!((mu_a / host - 1.0).abs() < 1e-5, "{row}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("optical_properties.json")).unwrap()).unwrap();
    assert_eq!(json[0]["absorption"], "volume-weighted-full-host");
}
