//! `lucent bssrdf` end to end: a run's files and summary fields, the sweep
//! table, comparison against a measured slice, and clear errors for bad
//! input (negative thickness, θ ≥ 90°, NaN in a map, non-square grids,
//! size mismatches, a ring where it does not apply), the per-pixel stop
//! rule and the ring estimator's summary.

use crate::common;
use common::{lucent, stderr};

use std::path::Path;
use std::process::Output;

const THIN: [&str; 8] = ["--mu-s", "3000", "--mu-a", "30", "--g", "0.8", "--n", "1.5"];

fn run_thin(out: &Path, extra: &[&str]) -> Output {
    let mut args = vec!["bssrdf", "--quiet", "--thickness-mm", "2", "--pixels", "41", "--pixel-mm", "0.1"];
    args.extend_from_slice(&THIN);
    if !extra.contains(&"--paths") {
        args.extend_from_slice(&["--paths", "20000"]);
    }
    args.extend_from_slice(&["--out", out.to_str().unwrap()]);
    args.extend_from_slice(extra);
    lucent(&args)
}

#[test]
fn run_writes_slice_profile_and_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let o = run_thin(&out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    for k in [
        "sum",
        "sum_std_error",
        "pixel_rel_error_median",
        "pixel_rel_error_p90",
        "paths",
        "events",
        "events_per_s",
        "wall_s",
    ] {
        assert!(s[k].is_number(), "summary lacks {k}: {s}");
    }
    // A 2 mm slab (μt d = 6) has image terms: the fixed-direction
    // connection, folded (φi = 0°, φo = 180°, Gaussian beam).
    assert_eq!(s["estimator"], "connection (fixed direction)");
    assert_eq!(s["folded"], true);
    assert_eq!(s["paths"].as_u64(), Some(20000));
    let sum = s["sum"].as_f64().unwrap();
    // The EXR holds the per-pixel values whose sum is `sum`.
    let (_, _, planes) = lucent_testkit::exr::read_channels(&out.join("bssrdf.exr"), &["Y", "std_error"]).unwrap();
    let total: f64 = planes[0].iter().copied().map(f64::from).sum();
    assert!((total / sum - 1.0).abs() < 1e-5, "{total} vs {sum}");
    let profile = std::fs::read_to_string(out.join("profile.csv")).unwrap();
    assert_eq!(profile.lines().count(), 42);
    assert!(profile.starts_with("x_mm,f_per_m2_sr,std_error_per_m2_sr,beam_relative"));
    for png in ["bssrdf.png", "profile.png"] {
        assert!(std::fs::read(out.join(png)).unwrap().starts_with(b"\x89PNG"), "{png}");
    }
    // Same seed, same result.
    let again = dir.path().join("again");
    assert!(run_thin(&again, &[]).status.success());
    let s2: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(again.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s2["sum"], s["sum"]);
}

#[test]
fn sweep_writes_one_folder_per_configuration_and_a_table() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("sweep");
    let o = run_thin(&out, &["--configs", "45/0,0/45,45/15", "--paths", "3000"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let table = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    assert_eq!(table.lines().count(), 4, "{table}");
    for f in ["ti45_to0", "ti0_to45", "ti45_to15"] {
        assert!(out.join(f).join("summary.json").exists(), "{f}");
    }
}

#[test]
fn compare_scores_against_a_measured_slice() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    assert!(run_thin(&out, &[]).status.success());
    // A "measurement": the simulated slice scaled by 1.1, as a CSV grid.
    let (_, _, mut planes) = lucent_testkit::exr::read_channels(&out.join("bssrdf.exr"), &["Y"]).unwrap();
    let y = planes.remove(0);
    let mut csv = String::new();
    for r in 0..41 {
        let row: Vec<String> = (0..41).map(|c| format!("{}", 1.1 * y[r * 41 + c] as f64)).collect();
        csv.push_str(&row.join(","));
        csv.push('\n');
    }
    let measured = dir.path().join("measured.csv");
    std::fs::write(&measured, &csv).unwrap();
    let cmp = dir.path().join("cmp");
    let o = lucent(&[
        "bssrdf",
        "compare",
        "--measured",
        measured.to_str().unwrap(),
        "--measured-pixel-mm",
        "0.1",
        "--simulated",
        out.to_str().unwrap(),
        "--out",
        cmp.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let c: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cmp.join("comparison.json")).unwrap()).unwrap();
    assert!((c["sum_ratio"].as_f64().unwrap() - 1.0 / 1.1).abs() < 1e-5, "{c}");
    let expected = (1.0f64 / 1.1 - 1.0).powi(2);
    assert!((c["mean_squared_relative_error"].as_f64().unwrap() - expected).abs() < 1e-5, "{c}");
    for png in ["profiles.png", "panel.png"] {
        assert!(cmp.join(png).exists(), "{png}");
    }
    // Wrong pixel size, non-square grid, NaN: clear errors naming the file.
    let o = lucent(&[
        "bssrdf",
        "compare",
        "--measured",
        measured.to_str().unwrap(),
        "--measured-pixel-mm",
        "0.2",
        "--simulated",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success() && stderr(&o).contains("pixel size"), "{}", stderr(&o));
    let bad = dir.path().join("nonsquare.csv");
    std::fs::write(&bad, "1,2,3\n4,5,6\n").unwrap();
    let o = lucent(&[
        "bssrdf",
        "compare",
        "--measured",
        bad.to_str().unwrap(),
        "--measured-pixel-mm",
        "0.1",
        "--simulated",
        out.to_str().unwrap(),
    ]);
    assert!(
        !o.status.success() && stderr(&o).contains("nonsquare.csv") && stderr(&o).contains("square"),
        "{}",
        stderr(&o)
    );
    let nan = dir.path().join("nan.csv");
    std::fs::write(&nan, "1,nan\n3,4\n").unwrap();
    let o = lucent(&[
        "bssrdf",
        "compare",
        "--measured",
        nan.to_str().unwrap(),
        "--measured-pixel-mm",
        "0.1",
        "--simulated",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success() && stderr(&o).contains("nan.csv") && stderr(&o).contains("finite"), "{}", stderr(&o));
}

#[test]
fn bad_input_gives_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("x");
    let cases: [(&[&str], &str); 7] = [
        (&["--thickness-mm", "-1"], "thickness"),
        (&["--theta-i", "90"], "theta_i"),
        (&["--theta-o", "120"], "theta_o"),
        (&["--crop", "500"], "crop"),
        (&["--rel-error", "2"], "rel_error"),
        (&["--pixel-rel-error", "0"], "pixel_rel_error"),
        // The ring needs θi or θo = 0 (and a thick slab).
        (&["--estimator", "ring", "--theta-i", "45", "--theta-o", "15"], "ring connection needs"),
    ];
    for (extra, key) in cases {
        let o = run_thin(&out, extra);
        assert!(!o.status.success(), "{extra:?} accepted");
        assert!(stderr(&o).contains(key), "{extra:?}: {}", stderr(&o));
        assert!(!stderr(&o).contains("panicked"));
    }
    let map = dir.path().join("beam.csv");
    std::fs::write(&map, "0,1\nnan,0\n").unwrap();
    let o = run_thin(&out, &["--beam-map", map.to_str().unwrap(), "--beam-map-pixel-mm", "0.01"]);
    assert!(!o.status.success() && stderr(&o).contains("beam.csv") && stderr(&o).contains("finite"), "{}", stderr(&o));
    let o = lucent(&["bssrdf", "--quiet", "--paths", "10", "--out", out.to_str().unwrap()]);
    assert!(!o.status.success() && stderr(&o).contains("--recipe"), "{}", stderr(&o));
}

#[test]
fn recipe_runs_use_the_lorenz_mie_properties() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("r");
    let o = lucent(&[
        "bssrdf",
        "--quiet",
        "--recipe",
        "fixtures/samples/IOL1068-09.toml",
        "--wavelength",
        "550",
        "--paths",
        "2000",
        "--pixels",
        "21",
        "--pixel-mm",
        "0.5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    let op = &s["optical_properties"];
    // The PDMS-09 sample: μs ≈ 1.47e4 /m, g ≈ 0.974, n ≈ 1.589 at 550 nm.
    assert!((op["mu_s_per_m"].as_f64().unwrap() / 1.47e4 - 1.0).abs() < 0.02, "{op}");
    assert!((op["g"].as_f64().unwrap() - 0.974).abs() < 0.002, "{op}");
    assert!((op["n"].as_f64().unwrap() - 1.589).abs() < 0.001, "{op}");
    assert_eq!(s["config"]["thickness_mm"].as_f64(), Some(6.35));
}

#[test]
fn ring_runs_stop_on_the_per_pixel_error() {
    // A thick slab (μt d = 45) at 45°/0°: the ring, launched from the
    // camera's side, until the median per-pixel error reaches 20 %.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("ring");
    let o = lucent(&[
        "bssrdf",
        "--quiet",
        "--mu-s",
        "3000",
        "--mu-a",
        "30",
        "--g",
        "0.8",
        "--n",
        "1.5",
        "--thickness-mm",
        "15",
        "--pixels",
        "16",
        "--pixel-mm",
        "0.5",
        "--pixel-rel-error",
        "0.2",
        "--time-s",
        "60",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["estimator"], "ring connection (azimuthal symmetry)");
    assert_eq!(s["reciprocal"], true);
    let median = s["pixel_rel_error_median"].as_f64().unwrap();
    assert!(median <= 0.2 && s["wall_s"].as_f64().unwrap() < 60.0, "{s}");
    assert!(s["pixel_rel_error_p90"].as_f64().unwrap() >= median);
}

/// The bad `--roughness` values of tests/bad/bssrdf/README.md: a clear
/// error naming the flag, the value and the problem, non-zero exit (2, the
/// usage error, for a text that is not a roughness: refused as the flags are
/// read), nothing written.
#[test]
fn bad_roughness_gives_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("rough");
    let words = "recipe, smooth, tr:ALPHA (ggx:ALPHA), beckmann:ALPHA or measured:FIT.json";
    let cases = [
        ("tr:abc", "\"abc\" is not a number", Some(2)),
        ("beckmann:-1", "α = -1", Some(2)),
        ("tr:nan", "[0, 4]", Some(2)),
        ("ggx:4.5", "[0, 4]", Some(2)),
        ("glossy:0.1", "unknown model \"glossy\"", Some(2)),
        ("0.01", "MODEL:VALUE", Some(2)),
        ("measured:", "names no file", Some(2)),
        ("measured:tests/bad/bssrdf/wrong_schema_fit.json", "schema", None),
        ("measured:tests/bad/bssrdf/missing/fit.json", "cannot read", None),
    ];
    for (value, key, code) in cases {
        let o = run_thin(&out, &["--roughness", value, "--paths", "100"]);
        let e = stderr(&o);
        assert!(!o.status.success(), "{value} accepted");
        assert!(e.contains(key) && e.contains("--roughness"), "{value}: {e}");
        if let Some(code) = code {
            assert_eq!(o.status.code(), Some(code), "{value}: {e}");
            assert!(e.contains(words), "{value}: the valid words: {e}");
        }
        assert!(!e.contains("panicked"), "{value}: {e}");
        assert!(!out.exists(), "{value}: output written");
    }
}

/// A rough-top run: the boundary in summary.json (from --roughness, from a
/// measured normal set of `lucent surface fit`), the fixed-direction
/// connection, and a slice close to the smooth one for the lab's α.
#[test]
fn rough_runs_record_their_boundary() {
    let dir = tempfile::tempdir().unwrap();
    let surface = dir.path().join("surface");
    let o = lucent(&["surface", "fit", "fixtures/surface/tr_0p0084.x3p", "--out", surface.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let fit = surface.join("fit.json");
    let summary = |name: &str, roughness: &str| -> serde_json::Value {
        let out = dir.path().join(name);
        let o = run_thin(&out, &["--roughness", roughness]);
        assert!(o.status.success(), "{roughness}: {}", stderr(&o));
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap()
    };
    let smooth = summary("smooth", "smooth");
    let tr = summary("tr", "tr:0.0084");
    let measured = summary("measured", &format!("measured:{}", fit.display()));
    assert_eq!(smooth["config"]["roughness"], "smooth (--roughness)");
    assert!(tr["config"]["roughness"].as_str().unwrap().contains("Trowbridge–Reitz α = 0.0084"), "{tr}");
    let m = measured["config"]["roughness"].as_str().unwrap();
    assert!(m.contains("measured normals") && m.contains("normals.exr"), "{m}");
    for s in [&tr, &measured] {
        assert_eq!(s["estimator"], "connection (fixed direction)");
        // α ≈ 0.008 barely changes a diffuse slice: within 4σ + 3 % of smooth.
        let (a, sa) = (s["sum"].as_f64().unwrap(), s["sum_std_error"].as_f64().unwrap());
        let (b, sb) = (smooth["sum"].as_f64().unwrap(), smooth["sum_std_error"].as_f64().unwrap());
        assert!((a - b).abs() < 4.0 * (sa * sa + sb * sb).sqrt() + 0.03 * b, "{a} ± {sa} vs {b} ± {sb}");
    }
}

#[test]
fn ctrl_c_keeps_a_labelled_partial_slice() {
    // SIGINT during a long run: the slice from the finished rounds is written
    // with "interrupted": true, the later configuration is not run, the exit
    // is non-zero and no staging folder is left.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    let mut args = vec!["bssrdf", "--thickness-mm", "2", "--pixels", "41", "--pixel-mm", "0.1", "--time-s", "120"];
    args.extend_from_slice(&THIN);
    args.extend_from_slice(&["--configs", "45/0,0/45", "--out", out.to_str().unwrap()]);
    let started = std::time::Instant::now();
    let (status, text) = common::interrupt_after(&args, "Ctrl-C stops");
    assert_eq!(status.code(), Some(130), "an interrupted run exits 130: {text}");
    assert!(started.elapsed().as_secs_f64() < 60.0, "the run did not stop at Ctrl-C");
    assert!(text.contains("interrupted"), "{text}");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("ti45_to0/summary.json")).unwrap()).unwrap();
    assert_eq!(summary["interrupted"], true);
    assert!(summary["paths"].as_u64().unwrap() > 0 && summary["sum"].as_f64().unwrap() > 0.0);
    assert!(out.join("ti45_to0/bssrdf.exr").exists());
    assert!(!out.join("ti0_to45").exists(), "the configuration after Ctrl-C must not run");
    let leftovers: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("staging"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn a_second_ctrl_c_aborts_and_removes_the_staging_folder() {
    // Two SIGINTs: the second ends the run at once (exit status 130) and
    // takes the staging folder, and the --out folder this run created, with
    // it; a file already beside them stays.
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("run");
    std::fs::write(dir.path().join("notes.txt"), "the user's").unwrap();
    let mut args = vec!["bssrdf", "--thickness-mm", "2", "--pixels", "41", "--pixel-mm", "0.1", "--time-s", "120"];
    args.extend_from_slice(&THIN);
    args.extend_from_slice(&["--configs", "45/0,0/45", "--out", out.to_str().unwrap()]);
    let started = std::time::Instant::now();
    let (status, text) = common::interrupt_n_after(&args, "Ctrl-C stops", 2);
    assert_eq!(status.code(), Some(130), "the second Ctrl-C must end the run at once: {text}");
    assert!(started.elapsed().as_secs_f64() < 60.0, "the run did not stop at Ctrl-C");
    assert!(text.contains("interrupted twice"), "{text}");
    let left: Vec<_> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert_eq!(left, vec!["notes.txt".to_string()], "the staging folder and the new --out must be gone");
}

/// `--roughness` errors as variants: the syntax problem (as the text is
/// read), and a measured normal set that cannot be used, named once with
/// its file.
#[test]
fn roughness_errors_are_typed() {
    use lucent::bssrdf::{roughness, NormalsError, RoughnessError, RoughnessSpec, RoughnessSyntax};
    let syntax = |text: &str| text.parse::<RoughnessSpec>().unwrap_err().problem;
    assert_eq!(syntax("tr:abc"), RoughnessSyntax::NotANumber("abc".into()));
    assert_eq!(syntax("beckmann:-1"), RoughnessSyntax::Alpha(-1.0));
    assert_eq!(syntax("glossy:0.1"), RoughnessSyntax::UnknownModel("glossy".into()));
    assert_eq!(syntax("0.01"), RoughnessSyntax::NoModel);

    let dir = tempfile::tempdir().unwrap();
    let exr = dir.path().join("normals.exr");
    let measured = |path: &Path| RoughnessSpec::Measured(path.to_path_buf());
    let normals = |path: &Path| match roughness(Some(&measured(path)), None) {
        Err(RoughnessError::Normals { source, .. }) => source,
        other => panic!("{}: {other:?}", path.display()),
    };
    // No pixel holds a normal (alpha 0 everywhere).
    let zero = vec![0.0f32; 4];
    let up = vec![1.0f32; 4];
    lucent::exr::write_channels(&exr, 2, 2, &[("R", &zero), ("G", &zero), ("B", &up), ("A", &zero)]).unwrap();
    let e = normals(&exr);
    assert!(matches!(&e, NormalsError::Empty { path } if path == &exr), "{e:?}");
    // Pixel (1, 0) is not of unit length.
    let z = vec![1.0f32, 2.0, 1.0, 1.0];
    lucent::exr::write_channels(&exr, 2, 2, &[("R", &zero), ("G", &zero), ("B", &z), ("A", &up)]).unwrap();
    let e = normals(&exr);
    assert!(matches!(e, NormalsError::NotUnit { column: 1, row: 0, value: [0.0, 0.0, 2.0], .. }), "{e:?}");
    // A missing file: its name once, in the image reader's message.
    let missing = dir.path().join("nope.exr");
    let e = roughness(Some(&measured(&missing)), None).unwrap_err();
    assert!(matches!(&e, RoughnessError::Normals { source: NormalsError::Read(_), .. }), "{e:?}");
    assert_eq!(e.to_string().matches("nope.exr").count(), 2, "the value and the file: {e}");
}

#[test]
fn a_path_budget_says_how_long_it_expects_unless_quiet() {
    let dir = tempfile::tempdir().unwrap();
    // 20000 paths are three rounds: the first tells the rate.
    let args = |out: &Path, quiet: bool| {
        let mut a = vec!["bssrdf", "--thickness-mm", "2", "--pixels", "41", "--pixel-mm", "0.1", "--paths", "20000"];
        a.extend_from_slice(&THIN);
        if quiet {
            a.push("--quiet");
        }
        a.extend_from_slice(&["--out", out.to_str().unwrap()]);
        a.into_iter().map(String::from).collect::<Vec<_>>()
    };
    let run = |out: &Path, quiet: bool| {
        let a = args(out, quiet);
        lucent(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let o = run(&dir.path().join("loud"), false);
    assert!(o.status.success(), "{}", stderr(&o));
    let err = stderr(&o);
    let line = err.lines().find(|l| l.contains("expect ≈")).unwrap_or_else(|| panic!("no expect line: {err}"));
    assert!(line.starts_with("θi 45° → θo 0°: expect ≈ ") && line.contains(" for 20000 paths ("), "{line}");
    let o = run(&dir.path().join("quiet"), true);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("expect"), "{}", stderr(&o));
}
