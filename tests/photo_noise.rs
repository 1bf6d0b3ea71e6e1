//! The photo's noise from its RAW capture (lucent::compare::photo_noise):
//! the per-pixel variance predicted from the DNG's NoiseProfile, or from the
//! noise model estimated on the photo, through demosaicing and the colour
//! matrix, against the variance measured between two captures of the same
//! scene (independent noise: mean (P₁ − P₂)² / 2 = mean var P); and the whole
//! path on the command line, `colour apply --variance-out` into
//! `compare --photo-variance`, stated in metrics.json.

use crate::common::{lucent, stderr, stdout};
use lucent::compare::photo_noise::photo_variance;
use lucent::exr::write_channels;
use lucent::imageio::{write_exr, RgbImage};
use lucent::synth::{self, dng, InputSpace, Sensor};
use lucent_calib::noise::NoiseSource;
use lucent_colour::adaptation::Cat;
use lucent_colour::data::ICC_D50_XYZ;
use lucent_colour::spaces::{mat3_inverse, mat3_mul, mat3_vec, RgbSpace};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// The XYZ → camera ColorMatrix of a Canon body (as in tests/synth.rs).
const CAM: [[f64; 3]; 3] = [[0.6722, -0.0635, -0.0963], [-0.4287, 1.246, 0.2028], [-0.0908, 0.2162, 0.5668]];

/// A smooth linear CIE RGB scene, 0.04 … 0.75, the channels in different ramps.
fn scene(w: usize, h: usize) -> RgbImage {
    let mut data = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
            data.extend([0.04 + 0.6 * u, 0.05 + 0.35 * (u + v), 0.04 + 0.7 * v]);
        }
    }
    RgbImage::new(w, h, data).unwrap()
}

/// Captures `img` on the default sensor (20 000 e⁻, 2 DN read noise) at exposure 0.8 into `dir/name`.
fn capture(dir: &Path, name: &str, img: &RgbImage, seed: u64, profile: bool) -> PathBuf {
    let sensor = Sensor::default();
    let to_cam = synth::to_camera_matrix(InputSpace::CieRgb, &CAM).unwrap();
    let cap = synth::capture_mosaic(img, &to_cam, 0.8, &sensor, seed).unwrap();
    assert_eq!(cap.clipped, 0);
    let mut file = dng::CfaDng::of_capture(&cap, &sensor, CAM, "noise test");
    if !profile {
        file.noise_profile = None;
    }
    let path = dir.join(name);
    dng::write_cfa_dng(&path, &file).unwrap();
    path
}

/// Camera RGB → CIE RGB with the true colour matrix (what `colour apply --to cie-rgb` does with a perfect ccm.json).
fn develop_matrix() -> [[f64; 3]; 3] {
    let back = RgbSpace::CieRgb.from_xyz_adapted_matrix(ICC_D50_XYZ, Some(Cat::Bradford)).unwrap();
    mat3_mul(&back, &mat3_inverse(&CAM).unwrap())
}

fn developed(path: &Path) -> Vec<f64> {
    let m = develop_matrix();
    let cam = lucent::imageio::read_rgb(path).unwrap();
    cam.data.chunks_exact(3).flat_map(|p| mat3_vec(&m, [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])])).collect()
}

/// Per channel, over pixels at least 3 px from the border: (mean predicted variance, mean (P₁ − P₂)²/2).
fn predicted_and_measured(w: usize, h: usize, var: &[f32], p1: &[f64], p2: &[f64]) -> [(f64, f64); 3] {
    std::array::from_fn(|c| {
        let (mut pv, mut mv, mut n) = (0.0, 0.0, 0.0);
        for y in 3..h - 3 {
            for x in 3..w - 3 {
                let i = 3 * (y * w + x) + c;
                pv += f64::from(var[i]);
                mv += 0.5 * (p1[i] - p2[i]).powi(2);
                n += 1.0;
            }
        }
        (pv / n, mv / n)
    })
}

#[test]
fn the_predicted_photo_variance_is_the_variance_between_two_captures() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (160, 120);
    let img = scene(w, h);
    let m = develop_matrix();
    let colour = move |rgb: [f64; 3]| mat3_vec(&m, rgb);
    for profile in [true, false] {
        let a = capture(dir.path(), &format!("a_{profile}.dng"), &img, 11, profile);
        let b = capture(dir.path(), &format!("b_{profile}.dng"), &img, 12, profile);
        let (var, file) = photo_variance(&a, &colour, 16, 1, 1).unwrap();
        let want = if profile { NoiseSource::DngNoiseProfile } else { NoiseSource::EstimatedFromImage };
        assert_eq!(file.noise_model.source, want);
        assert_eq!(var.len(), w * h * 3);
        // The sensor's shot term is 1 / full well = 5·10⁻⁵ (the read term, ≈ 1.7·10⁻⁸, is too small
        // next to it at these signals to be estimated).
        let truth_a = Sensor::default().noise_profile()[0];
        let model = if profile { file.estimated_from_image.as_ref().unwrap() } else { &file.noise_model };
        for c in 0..3 {
            assert!((model.a[c] / truth_a - 1.0).abs() < 0.10, "{profile}: estimated a {:?} vs {truth_a}", model.a);
        }
        let (p1, p2) = (developed(&a), developed(&b));
        for (c, (predicted, measured)) in predicted_and_measured(w, h, &var, &p1, &p2).into_iter().enumerate() {
            eprintln!("profile {profile}, channel {c}: predicted {predicted:.4e}, measured {measured:.4e}");
            let tolerance = if profile { 0.08 } else { 0.12 };
            assert!(
                (predicted / measured - 1.0).abs() < tolerance,
                "profile {profile}, channel {c}: predicted {predicted:.4e} vs measured {measured:.4e}"
            );
        }
    }
    // Without the demosaicing (the model at the photosites alone) the prediction would be off:
    // the test can tell. Malvar–He–Cutler interpolation lowers the variance of interpolated
    // values, so a per-photosite variance (a·x + b through the matrix's squares) is too high.
    let a = capture(dir.path(), "c.dng", &img, 21, true);
    let b = capture(dir.path(), "d.dng", &img, 22, true);
    let (p1, p2) = (developed(&a), developed(&b));
    let [np_a, np_b] = Sensor::default().noise_profile();
    let cam = lucent::imageio::read_rgb(&a).unwrap();
    let naive: Vec<f32> = cam
        .data
        .chunks_exact(3)
        .flat_map(|p| {
            let v = [0, 1, 2].map(|k| np_a * f64::from(p[k]) + np_b);
            (0..3).map(move |i| (0..3).map(|k| m[i][k] * m[i][k] * v[k]).sum::<f64>() as f32).collect::<Vec<_>>()
        })
        .collect();
    let off =
        predicted_and_measured(w, h, &naive, &p1, &p2).iter().map(|(p, me)| (p / me - 1.0).abs()).fold(0.0, f64::max);
    assert!(off > 0.15, "a per-photosite variance is within {off} of the measured one: the test cannot tell");
}

/// `bin` × `bin` means of interleaved RGB values.
fn binned(w: usize, h: usize, v: &[f64], bin: usize) -> Vec<f64> {
    let v32: Vec<f32> = v.iter().map(|&x| x as f32).collect();
    lucent::imageio::bin_interleaved(&v32, w, h, 3, bin).unwrap().into_iter().map(f64::from).collect()
}

#[test]
fn a_binned_photo_has_the_variance_of_its_binned_noise() {
    // A photo binned 4 × 4 to a render's size: its pixels average 16
    // developed pixels whose noise demosaicing has correlated, so their
    // variance is not the mean variance / 16. The prediction (noise
    // realisations binned before squaring) against two binned captures.
    let dir = tempfile::tempdir().unwrap();
    let (w, h, k) = (320, 240, 4);
    let img = scene(w, h);
    let m = develop_matrix();
    let colour = move |rgb: [f64; 3]| mat3_vec(&m, rgb);
    let a = capture(dir.path(), "a.dng", &img, 31, true);
    let b = capture(dir.path(), "b.dng", &img, 32, true);
    let (var, file) = photo_variance(&a, &colour, 16, 1, k).unwrap();
    assert_eq!((var.len(), file.bin), ((w / k) * (h / k) * 3, k));
    let (p1, p2) = (binned(w, h, &developed(&a), k), binned(w, h, &developed(&b), k));
    let (wb, hb) = (w / k, h / k);
    let (unbinned, _) = photo_variance(&a, &colour, 16, 1, 1).unwrap();
    let unbinned: Vec<f64> = unbinned.iter().map(|&v| f64::from(v) / (k * k) as f64).collect();
    let naive: Vec<f32> = binned(w, h, &unbinned, k).into_iter().map(|v| v as f32).collect();
    for (c, ((predicted, measured), (independent, _))) in predicted_and_measured(wb, hb, &var, &p1, &p2)
        .into_iter()
        .zip(predicted_and_measured(wb, hb, &naive, &p1, &p2))
        .enumerate()
    {
        eprintln!("binned, channel {c}: predicted {predicted:.4e}, measured {measured:.4e}, independent pixels {independent:.4e}");
        // 60 × 40 binned pixels, two captures: the measured mean is within ±4 % (1 SD ≈ 1.6 %... 2 %).
        assert!((predicted / measured - 1.0).abs() < 0.08, "channel {c}: predicted {predicted:.4e} vs {measured:.4e}");
        assert!(
            (independent / measured - 1.0).abs() > 0.15,
            "channel {c}: treating the pixels as independent gives {independent:.4e} against {measured:.4e}: the \
             test cannot tell"
        );
    }
    // A size that is not a multiple of the bin is refused with the photo's name.
    let e = photo_variance(&a, &colour, 16, 1, 7).unwrap_err().to_string();
    assert!(e.contains("a.dng") && e.contains("multiples of 7"), "{e}");
}

/// Runs lucent, asserting success; its standard output.
fn run_ok(args: &[&str]) -> String {
    let o = lucent(args);
    assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    stdout(&o)
}

/// The synthetic phone of [`CAM`] in `dir`: its truth_colour.json, a
/// ColorChecker captured as a DNG and calibrated; (truth, ccm.json) paths.
fn calibrated_phone(dir: &Path) -> (String, String) {
    let d = |n: &str| dir.join(n).to_str().unwrap().to_string();
    let t = synth::ColourTruth { camera: "phone".into(), xyz_d50_to_camera: CAM, note: String::new() };
    std::fs::write(dir.join("truth_colour.json"), serde_json::to_string(&t).unwrap()).unwrap();
    let tr = d("truth_colour.json");
    run_ok(&["synth", "chart", "--out", &d("chart.exr")]);
    run_ok(&[
        "synth",
        "raw",
        &d("chart.exr"),
        &d("chart.dng"),
        "--truth",
        &tr,
        "--space",
        "xyz-d50",
        "--exposure",
        "0.8",
    ]);
    let corners = "48,38.4,432,32,427.2,281.6,52.8,288";
    run_ok(&["colour", "calibrate", "--image", &d("chart.dng"), "--corners", corners, "--out", &d("colour")]);
    (tr, d("colour/ccm.json"))
}

#[test]
fn colour_apply_writes_the_variance_and_compare_states_the_model() {
    let dir = tempfile::tempdir().unwrap();
    let d = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let (truth, ccm) = calibrated_phone(dir.path());
    let (tr, run) = (truth.as_str(), run_ok);
    let (w, h) = (96, 72);
    let img = scene(w, h);
    write_exr(&dir.path().join("scene.exr"), &img).unwrap();
    let text =
        run(&["synth", "raw", &d("scene.exr"), &d("photo.dng"), "--truth", tr, "--exposure", "0.8", "--seed", "3"]);
    assert!(text.contains("NoiseProfile"), "{text}");
    let text = run(&[
        "colour",
        "apply",
        "--ccm",
        &ccm,
        &d("photo.dng"),
        &d("photo.exr"),
        "--variance-out",
        &d("photo_variance.exr"),
    ]);
    assert!(text.contains("from the DNG NoiseProfile"), "{text}");
    let side: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("photo_variance.noise.json")).unwrap()).unwrap();
    assert_eq!(side["noise_model"]["source"], "dng-noise-profile");
    assert_eq!(side["realisations"], 16);
    // A render 0.02 too bright everywhere, with a small known variance of its own.
    let photo = lucent::imageio::read_rgb(&dir.path().join("photo.exr")).unwrap();
    let render: Vec<f32> = img.data.iter().map(|v| v + 0.02).collect();
    let plane = |v: &[f32], c: usize| v.iter().skip(c).step_by(3).copied().collect::<Vec<f32>>();
    let rvar = vec![1e-6f32; w * h];
    let (r, g, b) = (plane(&render, 0), plane(&render, 1), plane(&render, 2));
    write_channels(
        &dir.path().join("render.exr"),
        w,
        h,
        &[("R", &r), ("G", &g), ("B", &b), ("variance.R", &rvar), ("variance.G", &rvar), ("variance.B", &rvar)],
    )
    .unwrap();
    assert_eq!((photo.width, photo.height), (w, h));
    let compare = |with_variance: bool, out: &str| -> Value {
        let (p, rr, o) = (d("photo.exr"), d("render.exr"), d(out));
        let pv = d("photo_variance.exr");
        let mut args: Vec<&str> = vec!["compare", "--photo", &p, "--render", &rr, "--out", &o];
        if with_variance {
            args.extend(["--photo-variance", pv.as_str()]);
        }
        run(&args);
        serde_json::from_str(&std::fs::read_to_string(dir.path().join(out).join("metrics.json")).unwrap()).unwrap()
    };
    let with = compare(true, "with");
    let n = &with["noise"];
    assert_eq!(n["photo_noise"]["noise_model"]["source"], "dng-noise-profile", "{n}");
    assert!(n["photo_variance"].as_str().unwrap().contains("NoiseProfile"), "{n}");
    // The photo's noise removed, the model RMSE is the 0.02 offset (the colour matrix
    // is recovered to ≈ 1 %, so the photo is within ≈ 0.005 of the scene).
    let without = compare(false, "without");
    let (m_with, m_without) =
        (n["total"]["model_rmse"].as_f64().unwrap(), without["noise"]["total"]["model_rmse"].as_f64().unwrap());
    assert!(m_with < m_without, "with the photo's variance {m_with}, without {m_without}");
    assert!((m_with - 0.02).abs() < 0.006, "model RMSE {m_with} for an offset of 0.02");
    // EXR input has no RAW noise model: refused with the way out.
    let o = lucent(&["colour", "apply", "--ccm", &ccm, &d("scene.exr"), &d("x.exr"), "--variance-out", &d("v.exr")]);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("needs a RAW photo") && stderr(&o).contains("--photo-variance"), "{}", stderr(&o));
}

#[test]
fn colour_apply_and_raw_clipped_bin_a_photo_to_a_smaller_render() {
    let dir = tempfile::tempdir().unwrap();
    let d = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    let (truth, ccm) = calibrated_phone(dir.path());
    let (tr, run) = (truth.as_str(), run_ok);
    // A scene with a bright corner that clips: 96 × 72 px binned 4 × 4 to 24 × 18.
    let (w, h) = (96, 72);
    let mut img = scene(w, h);
    for y in 0..3 {
        for x in 0..3 {
            let i = 3 * (y * w + x);
            img.data[i..i + 3].fill(5.0);
        }
    }
    write_exr(&dir.path().join("scene.exr"), &img).unwrap();
    run(&["synth", "raw", &d("scene.exr"), &d("photo.dng"), "--truth", tr, "--exposure", "0.8", "--seed", "3"]);
    run(&["colour", "apply", "--ccm", &ccm, &d("photo.dng"), &d("full.exr")]);
    let text = run(&[
        "colour",
        "apply",
        "--ccm",
        &ccm,
        &d("photo.dng"),
        &d("binned.exr"),
        "--bin",
        "4",
        "--variance-out",
        &d("binned_variance.exr"),
    ]);
    assert!(text.contains("binned 4 × 4 from 96 × 72"), "{text}");
    let full = lucent::imageio::read_rgb(&dir.path().join("full.exr")).unwrap();
    let binned = lucent::imageio::read_rgb(&dir.path().join("binned.exr")).unwrap();
    assert_eq!((binned.width, binned.height), (24, 18));
    // Each pixel the mean of its 4 × 4 developed pixels.
    for (y, x, c) in [(0, 0, 0), (5, 7, 1), (17, 23, 2)] {
        let mean: f64 = (0..16).map(|k| f64::from(full.pixel(4 * x + k % 4, 4 * y + k / 4)[c])).sum::<f64>() / 16.0;
        let got = f64::from(binned.pixel(x, y)[c]);
        assert!((got - mean).abs() < 1e-5 * mean.abs().max(1.0), "({x}, {y}) channel {c}: {got} vs {mean}");
    }
    let (vw, vh, var) = lucent::exr::read_channels(&dir.path().join("binned_variance.exr"), &["variance.G"]).unwrap();
    assert_eq!((vw, vh), (24, 18));
    assert!(var[0].iter().all(|v| v.is_finite() && *v > 0.0));
    let side: Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("binned_variance.noise.json")).unwrap()).unwrap();
    assert_eq!(side["bin"], 4);
    // The clipping mask binned alike: the corner's binned pixel is out, the rest in.
    run(&["raw", "clipped", &d("photo.dng"), "--out", &d("valid.png"), "--bin", "4"]);
    let mask = lucent::imageio::read_rgb(&dir.path().join("valid.png")).unwrap();
    assert_eq!((mask.width, mask.height), (24, 18));
    assert_eq!(mask.pixel(0, 0)[0], 0.0);
    assert_eq!(mask.pixel(2, 2)[0], 1.0);
    // A bin that does not divide the photo is refused, naming it; nothing is written.
    for args in [
        vec!["colour", "apply", "--ccm", &ccm, &d("photo.dng"), &d("bad.exr"), "--bin", "5"],
        vec!["raw", "clipped", &d("photo.dng"), "--out", &d("bad.png"), "--bin", "5"],
    ] {
        let o = lucent(&args);
        assert!(!o.status.success(), "{args:?} accepted");
        let e = stderr(&o);
        assert!(e.contains("photo.dng") && e.contains('5'), "{args:?}: {e}");
        assert!(!dir.path().join("bad.exr").exists() && !dir.path().join("bad.png").exists());
    }
}
