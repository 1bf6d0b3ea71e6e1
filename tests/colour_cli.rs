//! `lucent colour calibrate | apply | bands` end to end: output files, agreement with colour-science on a synthetic chart, the real chart photo in fixtures/colour/, and one-line errors for clipped patches, corners outside the image, bad method names and bad inputs.

use crate::common;
use common::{lucent, stderr, stdout};

use lucent::imageio::{read_rgb, write_exr, RgbImage};
use lucent_colour::chart::{draw_chart, Homography, SampleOptions};
use serde_json::Value;
use std::path::Path;
use std::process::Output;

/// `lucent colour calibrate --image IMAGE --corners CORNERS --out OUT EXTRA…`
fn calibrate(image: &str, corners: &str, out: &Path, extra: &[&str]) -> Output {
    let out = out.to_str().expect("UTF-8 path");
    let mut args = vec!["colour", "calibrate", "--image", image, "--corners", corners, "--out", out];
    args.extend_from_slice(extra);
    lucent(&args)
}

fn reference() -> Value {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/reference/colour_reference.json");
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn rows3(v: &Value) -> Vec<[f64; 3]> {
    v.as_array().unwrap().iter().map(|r| [0, 1, 2].map(|k| r[k].as_f64().unwrap())).collect()
}

fn matrix(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().flat_map(|r| r.as_array().unwrap().iter().map(|x| x.as_f64().unwrap())).collect()
}

/// The real chart photo (Argyll CMS documentation) and its patch-grid corners, found by eye.
const PHOTO: &str = "fixtures/colour/colorchecker.png";
const PHOTO_CORNERS: &str = "5,6.5,196,6,195.5,133.5,3.5,133";

/// A synthetic linear chart image in perspective (the library's test chart).
fn synthetic_chart(width: usize, height: usize, corners: [[f64; 2]; 4], patches: &[[f64; 3]]) -> RgbImage {
    let data = draw_chart(width, height, corners, patches, &SampleOptions::default(), [0.01; 3]).unwrap();
    RgbImage::new(width, height, data).unwrap()
}

const SYN_CORNERS: [[f64; 2]; 4] = [[40.0, 30.0], [560.0, 55.0], [540.0, 390.0], [25.0, 360.0]];

fn corners_arg(c: &[[f64; 2]; 4]) -> String {
    c.iter().flatten().map(|v| v.to_string()).collect::<Vec<_>>().join(",")
}

fn write_synthetic(dir: &Path, name: &str, patches: &[[f64; 3]]) -> String {
    let path = dir.join(name);
    write_exr(&path, &synthetic_chart(600, 420, SYN_CORNERS, patches)).unwrap();
    path.to_string_lossy().into_owned()
}

fn max_rel(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs() / y.abs().max(1e-3)).fold(0.0, f64::max)
}

#[test]
fn calibrate_on_a_synthetic_chart_matches_colour_science_and_apply_reproduces_it() {
    let dir = tempfile::tempdir().unwrap();
    let r = reference();
    let camera = rows3(&r["ccm"]["camera_rgb"]);
    let image = write_synthetic(dir.path(), "chart.exr", &camera);
    let corners = corners_arg(&SYN_CORNERS);
    for fit in r["ccm"]["fits"].as_array().unwrap() {
        let method = fit["method"].as_str().unwrap();
        if method.contains("degree 1") {
            continue;
        }
        let out = dir.path().join(method.replace(' ', "_"));
        let o = calibrate(&image, &corners, &out, &["--method", method, "--camera", "synthetic D5100"]);
        assert!(o.status.success(), "{method}: {}", stderr(&o));
        assert!(stdout(&o).contains("mean"), "{}", stdout(&o));
        let ccm: Value = serde_json::from_str(&std::fs::read_to_string(out.join("ccm.json")).unwrap()).unwrap();
        assert_eq!(ccm["method"], method);
        assert_eq!(ccm["camera"], "synthetic D5100");
        let e = max_rel(&matrix(&ccm["matrix"]), &matrix(&fit["matrix"]));
        // Patch means pass through f32 pixels (relative rounding 6e-8, amplified by the fit's
        // conditioning to ~1e-6; the library tests compare the same f64 data to 1e-9).
        assert!(e < 1e-5, "{method}: matrix differs from colour-science by {e:e}");
        let de: Vec<f64> = ccm["patches"].as_array().unwrap().iter().map(|p| p["de2000"].as_f64().unwrap()).collect();
        let de_ref: Vec<f64> = fit["de2000"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
        assert!(de.iter().zip(&de_ref).all(|(a, b)| (a - b).abs() < 1e-4), "{method}: {de:?} vs {de_ref:?}");
        for f in ["chart.png", "delta_e.png", "patches.png"] {
            let bytes = std::fs::read(out.join(f)).unwrap();
            assert!(bytes.starts_with(b"\x89PNG"), "{f}");
        }
    }

    // apply --to xyz: a patch centre becomes the fitted XYZ of that patch.
    let ccm_path = dir.path().join("Cheung_2004/ccm.json");
    let fitted = rows3(&r["ccm"]["fits"][0]["predicted_xyz"]);
    let out_xyz = dir.path().join("xyz.exr");
    let o = lucent(&[
        "colour",
        "apply",
        "--ccm",
        ccm_path.to_str().unwrap(),
        &image,
        out_xyz.to_str().unwrap(),
        "--to",
        "xyz",
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = read_rgb(&out_xyz).unwrap();
    let hom = Homography::from_corners(SYN_CORNERS).unwrap();
    let opts = SampleOptions::default();
    for k in [0usize, 7, 18, 23] {
        let [u0, v0, u1, v1] = opts.sample_square(k);
        let [x, y] = hom.map((u0 + u1) / 2.0, (v0 + v1) / 2.0);
        let p = img.pixel(x as usize, y as usize);
        for c in 0..3 {
            assert!(
                (f64::from(p[c]) - fitted[k][c]).abs() < 1e-5 * fitted[k][c].abs().max(0.01),
                "patch {}: {p:?} vs {:?}",
                k + 1,
                fitted[k]
            );
        }
    }
    // apply --to cie-rgb (default, Bradford D50 → E): the Finlayson 1997 matrix maps the white
    // patch exactly onto its reference XYZ, so the pixel is colour-science's CIE RGB of that XYZ.
    let out_rgb = dir.path().join("cie.exr");
    let wp = dir.path().join("Finlayson_1997/ccm.json");
    let o = lucent(&["colour", "apply", "--ccm", wp.to_str().unwrap(), &image, out_rgb.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("Bradford"), "{}", stdout(&o));
    let img = read_rgb(&out_rgb).unwrap();
    let [u0, v0, u1, v1] = opts.sample_square(18);
    let [x, y] = hom.map((u0 + u1) / 2.0, (v0 + v1) / 2.0);
    let w = img.pixel(x as usize, y as usize);
    let expect = rows3(&r["rgb"]["checker_cie_rgb_bradford"])[18];
    for c in 0..3 {
        assert!(
            (f64::from(w[c]) - expect[c]).abs() < 1e-5,
            "white patch in CIE RGB: {w:?} vs colour-science {expect:?}"
        );
    }
}

#[test]
fn calibrate_the_real_chart_photo() {
    let dir = tempfile::tempdir().unwrap();
    let o = calibrate(PHOTO, PHOTO_CORNERS, dir.path(), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(!stderr(&o).contains("warning"), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("white 9.5 (.05 D)") && text.contains("mean"), "{text}");
    let ccm: Value = serde_json::from_str(&std::fs::read_to_string(dir.path().join("ccm.json")).unwrap()).unwrap();
    assert_eq!(ccm["patches"].as_array().unwrap().len(), 24);
    assert_eq!(ccm["input_encoding"], "linear");
    for key in ["reference_set", "illuminant", "observer", "maps"] {
        assert!(ccm[key].is_string(), "{key}");
    }
    let mean = ccm["de2000_mean"].as_f64().unwrap();
    let max = ccm["de2000_max"].as_f64().unwrap();
    // A small web JPEG of a chart: a 3 × 3 matrix gets it to a few ΔE00 (4.69 when written).
    assert!(mean > 1.0 && mean < 6.0, "mean ΔE00 {mean}");
    assert!(max < 15.0, "max ΔE00 {max}");
    // Every patch was sampled from inside its square: the white patch is the brightest, black the darkest.
    let g: Vec<f64> = ccm["patches"].as_array().unwrap().iter().map(|p| p["camera_rgb"][1].as_f64().unwrap()).collect();
    let (imax, imin) = (
        (0..24).max_by(|a, b| g[*a].total_cmp(&g[*b])).unwrap(),
        (0..24).min_by(|a, b| g[*a].total_cmp(&g[*b])).unwrap(),
    );
    assert_eq!((imax, imin), (18, 23));
}

#[test]
fn clipped_patches_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let mut patches = rows3(&reference()["ccm"]["camera_rgb"]);
    patches[18] = [1.0, 1.0, 1.0];
    patches[11] = [1.0, 0.6, 0.1];
    let image = write_synthetic(dir.path(), "clipped.exr", &patches);
    let out = dir.path().join("out");
    let o = calibrate(&image, &corners_arg(&SYN_CORNERS), &out, &[]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("clipped") && e.contains("12 (orange yellow)") && e.contains("19 (white 9.5 (.05 D))"), "{e}");
    assert!(e.contains("clipped.exr"), "the error names the image: {e}");
    assert_eq!(e.trim().lines().count(), 1, "one line: {e}");
    assert!(!out.join("ccm.json").exists());
    // --clip-level none accepts them.
    let o = calibrate(&image, &corners_arg(&SYN_CORNERS), &out, &["--clip-level", "none"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn corners_outside_the_image_and_bad_corner_text_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path();
    let o = calibrate(PHOTO, "5,6.5,196,6,195.5,150,3.5,133", out, &[]);
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("corner 3 (195.5, 150)") && e.contains("200 × 141"), "{e}");
    let o = calibrate(PHOTO, "5,6.5,196,6", out, &[]);
    assert!(stderr(&o).contains("expected 8 numbers"), "{}", stderr(&o));
    // Given anticlockwise (white corner first, going up): refused with the expected order.
    let o = calibrate(PHOTO, "3.5,133,195.5,133.5,196,6,5,6.5", out, &[]);
    assert!(stderr(&o).contains("anticlockwise"), "{}", stderr(&o));
    let o = calibrate("fixtures/colour/missing.exr", PHOTO_CORNERS, out, &[]);
    assert!(stderr(&o).contains("missing.exr"), "{}", stderr(&o));
}

#[test]
fn bad_method_names_list_the_valid_ones() {
    let dir = tempfile::tempdir().unwrap();
    let o = calibrate(PHOTO, PHOTO_CORNERS, dir.path(), &["--method", "Vandermonde"]);
    // clap refuses it (exit 2) and lists the methods.
    assert_eq!(o.status.code(), Some(2));
    let e = stderr(&o);
    assert!(
        e.contains("invalid value 'Vandermonde' for '--method")
            && e.contains("[possible values: \"Cheung 2004\", \"Finlayson 2015\", \"Finlayson 1997\"]"),
        "{e}"
    );
    // Spelling variants of a valid name are accepted.
    let o = calibrate(PHOTO, PHOTO_CORNERS, dir.path(), &["--method", "finlayson-2015"]);
    assert!(o.status.success(), "{}", stderr(&o));
}

#[test]
fn apply_rejects_bad_inputs() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("cal");
    let o = calibrate(PHOTO, PHOTO_CORNERS, &out, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let ccm = out.join("ccm.json");
    let ccm = ccm.to_str().unwrap();
    let o = lucent(&["colour", "apply", "--ccm", ccm, PHOTO, dir.path().join("x.png").to_str().unwrap()]);
    assert!(stderr(&o).contains("must be an .exr"), "{}", stderr(&o));
    let o =
        lucent(&["colour", "apply", "--ccm", ccm, PHOTO, dir.path().join("x.exr").to_str().unwrap(), "--to", "lab"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("[possible values: cie-rgb, xyz, srgb]"), "{}", stderr(&o));
    let bad = dir.path().join("bad.json");
    std::fs::write(&bad, r#"{"method": "Cheung 2004"}"#).unwrap();
    let o =
        lucent(&["colour", "apply", "--ccm", bad.to_str().unwrap(), PHOTO, dir.path().join("x.exr").to_str().unwrap()]);
    assert!(!o.status.success() && stderr(&o).contains("bad.json"), "{}", stderr(&o));
    // The happy path: sRGB output of the photo.
    let o =
        lucent(&["colour", "apply", "--ccm", ccm, PHOTO, dir.path().join("x.exr").to_str().unwrap(), "--to", "srgb"]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(read_rgb(&dir.path().join("x.exr")).unwrap().width, 200);
}

#[test]
fn bands_of_optical_properties_json_and_of_a_recipe() {
    let dir = tempfile::tempdir().unwrap();
    let wl: Vec<f64> = (0..41).map(|i| 380.0 + 10.0 * i as f64).collect();
    let sample = |name: &str, mu_s: f64| {
        serde_json::json!({
            "sample": name,
            "wavelength_nm": wl,
            "mu_s_per_m": vec![mu_s; 41],
            "mu_a_per_m": wl.iter().map(|l| l / 100.0).collect::<Vec<f64>>(),
            "g": vec![0.9; 41],
        })
    };
    let path = dir.path().join("optical_properties.json");
    std::fs::write(&path, serde_json::to_string(&vec![sample("a", 100.0), sample("b", 250.0)]).unwrap()).unwrap();
    let o = lucent(&["colour", "bands", path.to_str().unwrap(), "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert!(v["weight_set"].as_str().unwrap().contains("clipped"));
    assert_eq!(v["weights"][0]["weights"][0].as_array().unwrap().len(), 41);
    let b = &v["samples"][1];
    assert_eq!(b["sample"], "b");
    for k in 0..3 {
        assert!((b["mu_s_per_m"][k].as_f64().unwrap() - 250.0).abs() < 1e-9);
        assert!((b["g"][k].as_f64().unwrap() - 0.9).abs() < 1e-12);
    }
    // μa rises with λ: R > G > B.
    let mu_a: Vec<f64> = (0..3).map(|k| b["mu_a_per_m"][k].as_f64().unwrap()).collect();
    assert!(mu_a[0] > mu_a[1] && mu_a[1] > mu_a[2], "{mu_a:?}");

    // A single object works too, and the text table names the weights.
    let single = dir.path().join("one.json");
    std::fs::write(&single, serde_json::to_string(&sample("one", 5.0)).unwrap()).unwrap();
    let o = lucent(&["colour", "bands", single.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("weights: CIE 1931 RGB"), "{}", stdout(&o));

    // A recipe is computed first (μs, μa, g from Lorenz–Mie).
    let o = lucent(&["colour", "bands", "fixtures/samples/IOL1068-09.toml", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let v: Value = serde_json::from_str(&stdout(&o)).unwrap();
    assert_eq!(v["samples"][0]["sample"], "IOL1068-09");
    assert!(v["samples"][0]["mu_s_per_m"][1].as_f64().unwrap() > 0.0);

    // Bad inputs: mismatched lengths, NaN, wrong extension.
    let mut broken = sample("x", 1.0);
    broken["g"] = serde_json::json!([0.9, 0.9]);
    std::fs::write(&single, serde_json::to_string(&broken).unwrap()).unwrap();
    let o = lucent(&["colour", "bands", single.to_str().unwrap()]);
    assert!(stderr(&o).contains("g has 2 values"), "{}", stderr(&o));
    let text = serde_json::to_string(&sample("n", 1.0)).unwrap().replacen("1.0", "NaN", 1);
    std::fs::write(&single, text).unwrap();
    let o = lucent(&["colour", "bands", single.to_str().unwrap()]);
    assert!(!o.status.success() && stderr(&o).contains("one.json"), "{}", stderr(&o));
    let o = lucent(&["colour", "bands", "README.md"]);
    assert!(stderr(&o).contains("expected a recipe"), "{}", stderr(&o));
}

/// `lucent colour calibrate --image IMAGE --out OUT` without --corners: the chart is detected.
fn calibrate_detected(image: &str, out: &Path) -> Output {
    lucent(&["colour", "calibrate", "--image", image, "--out", out.to_str().expect("UTF-8 path")])
}

fn ccm_json(dir: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(dir.join("ccm.json")).unwrap()).unwrap()
}

#[test]
fn calibrate_without_corners_detects_the_real_chart() {
    let dir = tempfile::tempdir().unwrap();
    let (auto, given) = (dir.path().join("auto"), dir.path().join("given"));
    let o = calibrate_detected(PHOTO, &auto);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(stdout(&o).contains("chart found by OpenCV mcc: --corners "), "{}", stdout(&o));
    let o = calibrate(PHOTO, PHOTO_CORNERS, &given, &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    let (a, g) = (ccm_json(&auto), ccm_json(&given));
    assert_eq!(a["corners_detected"], true);
    assert_eq!(g["corners_detected"], false);
    for k in 0..4 {
        let (p, q) = (&a["corners"][k], &g["corners"][k]);
        let d =
            (p[0].as_f64().unwrap() - q[0].as_f64().unwrap()).hypot(p[1].as_f64().unwrap() - q[1].as_f64().unwrap());
        assert!(d < 3.0, "corner {}: {p} detected vs {q} given", k + 1);
    }
    let (da, dg) = (a["de2000_mean"].as_f64().unwrap(), g["de2000_mean"].as_f64().unwrap());
    assert!((da - dg).abs() < 0.5, "mean ΔE00 {da} detected vs {dg} given");
    // Patches in reference order: every patch's own ΔE stays close to the given-corner one.
    for k in 0..24 {
        assert_eq!(a["patches"][k]["name"], g["patches"][k]["name"]);
        let (x, y) = (a["patches"][k]["de2000"].as_f64().unwrap(), g["patches"][k]["de2000"].as_f64().unwrap());
        assert!((x - y).abs() < 1.5, "patch {}: ΔE00 {x} detected vs {y} given", k + 1);
    }
}

#[test]
fn calibrate_without_corners_on_an_image_without_a_chart_asks_for_them() {
    let dir = tempfile::tempdir().unwrap();
    let grey = dir.path().join("grey.exr");
    write_exr(&grey, &RgbImage::new(160, 120, vec![0.18; 160 * 120 * 3]).unwrap()).unwrap();
    let o = calibrate_detected(grey.to_str().unwrap(), &dir.path().join("out"));
    assert!(!o.status.success());
    let e = stderr(&o);
    assert!(e.contains("grey.exr") && e.contains("no ColorChecker Classic 24 found") && e.contains("--corners"), "{e}");
    assert_eq!(e.trim().lines().count(), 1, "{e}");
    assert!(!dir.path().join("out/ccm.json").exists());
}
