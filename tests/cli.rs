//! The `lucent` command line end to end: output files and field names,
//! folder mode, and one-line errors for bad input.

use crate::common;
use common::{lucent, stderr, stdout};

use std::path::{Path, PathBuf};

fn sample(nn: &str) -> String {
    format!("fixtures/samples/IOL1068-{nn}.toml")
}

#[test]
fn mie_prints_efficiencies_as_json() {
    // Bohren & Huffman (1983), appendix A: r = 0.525 µm, λ = 0.6328 µm, m = 1.55.
    let x = 2.0 * std::f64::consts::PI * 0.525 / 0.6328;
    let o = lucent(&["mie", "--size-parameter", &x.to_string(), "--relative-index", "1.55"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    for k in ["qext", "qsca", "qabs", "qback", "g"] {
        assert!(v[k].is_f64(), "missing {k}: {v}");
    }
    // Published: Qsca = 3.10543, Qback = 2.92534.
    assert!((v["qsca"].as_f64().unwrap() - 3.10543).abs() < 6e-6);
    assert!((v["qback"].as_f64().unwrap() - 2.92534).abs() < 6e-6);

    // The physical form gives the same numbers: x = 2π r n_h / λ.
    let o2 = lucent(&["mie", "--radius-um", "0.525", "--wavelength-nm", "632.8", "--particle-index", "1.55"]);
    assert!(o2.status.success(), "{}", stderr(&o2));
    let v2: serde_json::Value = serde_json::from_str(&stdout(&o2)).unwrap();
    assert!((v2["qsca"].as_f64().unwrap() - v["qsca"].as_f64().unwrap()).abs() < 1e-9);

    let bad = lucent(&["mie", "--size-parameter", "5", "--relative-index", "1.5-0.1i"]);
    assert!(!bad.status.success());
    assert!(stderr(&bad).contains("imaginary part"), "{}", stderr(&bad));

    // The two forms do not mix: a relative index beside a particle index
    // was silently ignored (m = 1 then printed the efficiencies of m = 1.5).
    let mixed = lucent(&[
        "mie",
        "--relative-index",
        "1",
        "--particle-index",
        "1.5",
        "--radius-um",
        "1",
        "--wavelength-nm",
        "550",
    ]);
    assert_eq!(mixed.status.code(), Some(2), "{}", stderr(&mixed));
    assert!(stderr(&mixed).contains("cannot be used with"), "{}", stderr(&mixed));
    let alone = lucent(&["mie", "--relative-index", "1.2"]);
    assert_eq!(alone.status.code(), Some(2), "{}", stderr(&alone));
    assert!(stderr(&alone).contains("--size-parameter"), "{}", stderr(&alone));
}

#[test]
fn optics_json_to_stdout_has_the_documented_fields() {
    let o = lucent(&["optics", &sample("09"), "--json", "--phase-entries", "0"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    for k in ["wavelength_nm", "mu_s_per_m", "mu_a_per_m", "mu_t_per_m", "g", "n_bulk"] {
        assert_eq!(v[k].as_array().map(Vec::len), Some(41), "{k}");
    }
    assert_eq!(v["wavelength_nm"][0].as_f64(), Some(380.0));
    assert!(stderr(&o).contains("clamped"), "extrapolation warning expected: {}", stderr(&o));

    let one = lucent(&["optics", &sample("09"), "--json", "--wavelength", "550"]);
    let v: serde_json::Value = serde_json::from_str(&stdout(&one)).unwrap();
    assert_eq!(v["g"].as_array().map(Vec::len), Some(1));
}

#[test]
fn optics_writes_tables_phase_and_plots() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("o");
    let o = lucent(&["optics", &sample("12"), "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("optical_properties.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(lines.next(), Some("sample,wavelength_nm,mu_s_per_m,mu_a_per_m,mu_t_per_m,g,n_bulk"));
    assert_eq!(lines.count(), 41);
    let phase = std::fs::read_to_string(out.join("phase_function.csv")).unwrap();
    assert_eq!(phase.lines().count(), 4097);
    assert_eq!(phase.lines().next().unwrap().split(',').count(), 2 + 41);
    for png in ["optical_properties.png", "phase_550nm.png"] {
        let bytes = std::fs::read(out.join(png)).unwrap_or_else(|e| panic!("{png}: {e}"));
        assert!(bytes.starts_with(b"\x89PNG"), "{png}");
    }
    let leftovers: Vec<PathBuf> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.to_string_lossy().ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn folder_mode_reports_the_unknown_weight_percent() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("all");
    let o = lucent(&["optics", "fixtures/samples", "--phase-entries", "64", "--out", out.to_str().unwrap()]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("IOL1068-15.toml") && e.contains("weight_percent"), "{e}");

    let o = lucent(&[
        "optics",
        "fixtures/samples",
        "--phase-entries",
        "64",
        "--skip-invalid",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("note: skipped") && stderr(&o).contains("IOL1068-15"), "{}", stderr(&o));
    // The shipped recipes give no warning: IOL1068-15's unknown weight
    // percentage and the 380–399 nm index clamps they ask for are notes.
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    let csv = std::fs::read_to_string(out.join("optical_properties.csv")).unwrap();
    let samples: std::collections::BTreeSet<&str> = csv.lines().skip(1).map(|l| l.split(',').next().unwrap()).collect();
    assert_eq!(samples.len(), 11, "{samples:?}");
    assert!(out.join("IOL1068-05/phase_function.csv").exists());

    let o = lucent(&["optics", "fixtures/samples", "--phase-entries", "0", "--weight-percent", "1.0", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: serde_json::Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v.as_array().map(Vec::len), Some(12));
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.to_string_lossy().into_owned()
}

#[test]
fn bad_recipes_give_one_line_errors_naming_file_and_key() {
    let dir = tempfile::tempdir().unwrap();
    let good = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join(sample("09"))).unwrap();
    let half = (0..=good.len() / 2).rev().find(|&i| good.is_char_boundary(i)).unwrap();
    let cases = [
        ("typo.toml", good.replace("thickness_mm", "thickness"), "thickness"),
        ("neg.toml", good.replace("thickness_mm = 6.35", "thickness_mm = -6.35"), "thickness_mm"),
        ("nan.toml", good.replace("weight_percent = 0.65", "weight_percent = nan"), "weight_percent"),
        ("dens.toml", good.replace("density_g_per_ml = 0.965", "density_g_per_ml = 0"), "density_g_per_ml"),
        ("file.toml", good.replace("builtin:PDMS_Zhang2020_20-1", "missing.yml"), "missing.yml"),
        ("trunc.toml", good[..half].to_string(), "trunc.toml"),
    ];
    for (name, text, key) in cases {
        let path = write(dir.path(), name, &text);
        let o = lucent(&["optics", &path, "--json"]);
        assert!(!o.status.success(), "{name} accepted");
        let e = stderr(&o);
        assert!(e.contains(name) && e.contains(key), "{name}: {e}");
        assert_eq!(e.trim().lines().count(), 1, "{name}: not one line: {e}");
        assert!(!e.contains("panicked"), "{e}");
    }
    let o = lucent(&["optics", "no/such/recipe.toml"]);
    assert!(!o.status.success() && stderr(&o).contains("no/such/recipe.toml"));
    // Without extrapolation the Zhang table does not reach 380 nm: a clear error.
    let strict = write(dir.path(), "strict.toml", &good.replace("extrapolate = \"clamp\"", "extrapolate = \"none\""));
    let o = lucent(&["optics", &strict, "--json"]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("380"), "{}", stderr(&o));
}

/// A negative number after a space is the flag's value (`--time-s -1`, as
/// people type it), not an unknown flag: the flag's own check names it and
/// its range, and a negative value that is valid (`--exposure -2`) works.
#[test]
fn negative_numbers_after_a_space_reach_the_flags_check() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("out");
    let out = out.to_str().unwrap();
    let scene = "fixtures/render/demo.toml";
    for (flag, value, needles) in [
        ("--time-s", "-1", &["--time-s -1", "> 0"][..]),
        ("--target-rel-error", "-0.5", &["--target-rel-error -0.5", "between 0 and 1"][..]),
        ("--similarity-g", "-0.5", &["--similarity-g -0.5", "[0, 1)"][..]),
        ("--spp", "-4", &["--spp", "-4"][..]),
    ] {
        let o = lucent(&["render", scene, flag, value, "--size", "8x6", "--quiet", "--out", out]);
        let err = stderr(&o);
        assert!(!o.status.success(), "{flag} {value} was accepted");
        assert!(!err.contains("unexpected argument"), "{flag} {value}: {err}");
        for n in needles {
            assert!(err.contains(n), "{flag} {value}: {err:?} lacks {n:?}");
        }
    }
    let o = lucent(&["render", scene, "--exposure", "-2", "--size", "8x6", "--spp", "1", "--quiet", "--out", out]);
    assert!(o.status.success(), "--exposure -2: {}", stderr(&o));
    let o = lucent(&[
        "mie",
        "--radius-um",
        "-1",
        "--wavelength-nm",
        "550",
        "--host-index",
        "1.5",
        "--particle-index",
        "1.4",
    ]);
    assert!(!o.status.success() && stderr(&o).contains("--radius-um"), "mie: {}", stderr(&o));
}
