//! `lucent env fit-scale`: a synthetic empty-board photo rendered with a known
//! environment scale is fitted from scale 1 (scalar, and per channel with a
//! constant sky); bad inputs are refused with reasons and write nothing.

use lucent::exr::read_channels;
use lucent::imageio::{read_rgb, write_exr, RgbImage};
use std::path::{Path, PathBuf};
use std::process::Command;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn lucent(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_lucent")).args(args).output().expect("run lucent")
}

/// A 48 × 36 view of a 10 × 8 board of 20 mm squares; `object` adds a plaque
/// with explicit bands (the fit must leave it out); `env` is the [environment] body.
fn scene(object: bool, env: &str, seed: u64, spp: u32) -> String {
    let obj = if object {
        "[object]\nsize_mm = [60.0, 40.0, 6.35]\n\n[material]\nsigma_s_per_m = [2000.0, 2000.0, 2000.0]\nsigma_a_per_m = [5.0, 10.0, 20.0]\ng = [0.8, 0.8, 0.8]\nn = [1.5, 1.5, 1.5]\nphase = \"hg\"\n\n"
    } else {
        ""
    };
    format!(
        "[camera]\nwidth = 48\nheight = 36\nposition_m = [0.0, -0.25, 0.30]\nlook_at_m = [0.0, 0.0, 0.0]\nvertical_fov_deg = 34.0\n\n{obj}[board]\norigin_m = [-0.10, -0.08, 0.0]\nsquare_mm = 20.0\ncolumns = 10\nrows = 8\neven = [0.05, 0.05, 0.05]\nodd = [0.8, 0.7, 0.6]\nmargin_mm = 40.0\n\n[environment]\n{env}\n\n[render]\nspp = {spp}\nseed = {seed}\n"
    )
}

fn render_photo(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("photo_scene.toml");
    std::fs::write(&p, text).unwrap();
    let out = dir.join("photo");
    let o = lucent(&["render", p.to_str().unwrap(), "--quiet", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out.join("render.exr")
}

fn json(p: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(p).unwrap()).unwrap()
}

#[test]
fn scale_of_a_map_environment_is_recovered() {
    let tmp = tempfile::tempdir().unwrap();
    let map = root().join("fixtures/env/studio.exr");
    let env = |scale: f64| format!("map = {:?}\nprojection = \"infinite\"\nscale = {scale}", map.display().to_string());
    let truth = 2.5;
    let photo = render_photo(tmp.path(), &scene(false, &env(truth), 11, 256));
    let twin = tmp.path().join("twin.toml");
    std::fs::write(&twin, scene(true, &env(1.0), 5, 64)).unwrap();
    let out = tmp.path().join("fit");
    let o = lucent(&[
        "env",
        "fit-scale",
        twin.to_str().unwrap(),
        "--photo",
        photo.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // The render says what it does and, after its first pass, how long it expects.
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("rendering the empty board of") && err.contains("64 spp"), "{err}");
    assert!(err.contains("expect ≈") && err.contains("for 64 spp ("), "{err}");
    let j = json(&out.join("env_scale.json"));
    let k = j["fit"]["scale"].as_f64().unwrap();
    let pixels = j["fit"]["pixels"].as_u64().unwrap();
    assert!(pixels > 400, "{j}");
    // Both renders are noisy (photo 256 spp, fit 64 spp); over ~500 pixels × 3
    // channels k's standard error is a few 0.1 %. Without the variance term
    // of the estimator k comes out several per cent low.
    assert!((k - truth).abs() < 0.02 * truth, "k = {k}, truth {truth}: {j}");
    for c in 0..3 {
        let kc = j["fit"]["scale_per_channel"][c].as_f64().unwrap();
        assert!((kc - truth).abs() < 0.03 * truth, "channel {c}: {kc}");
    }
    // The residual is noise: about the two renders' noise combined, not more.
    let resid = j["fit"]["residual_rms"].as_f64().unwrap();
    let noise = j["fit"]["render_noise_rms"].as_f64().unwrap();
    assert!(resid < 2.0 * noise, "residual {resid} vs the fit render's noise {noise}");
    assert_eq!(j["new_scale"].as_f64().unwrap(), k);
    // The scaled scene loads from its new place and keeps the object.
    let copy = std::fs::read_to_string(out.join("scene.toml")).unwrap();
    assert!(copy.contains("[object]") && copy.contains(&format!("scale = {k}")), "{copy}");
    let o = lucent(&[
        "render",
        out.join("scene.toml").to_str().unwrap(),
        "--spp",
        "1",
        "--quiet",
        "--out",
        tmp.path().join("again").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let (w, h, _) = read_channels(&out.join("board_render.exr"), &["R", "G", "B"]).unwrap();
    assert_eq!((w, h), (48, 36));
}

#[test]
fn per_channel_scales_of_a_constant_sky_go_into_the_scene() {
    let tmp = tempfile::tempdir().unwrap();
    let photo = render_photo(tmp.path(), &scene(false, "constant = [0.6, 1.0, 1.8]", 3, 64));
    let twin = tmp.path().join("twin.toml");
    std::fs::write(&twin, scene(false, "constant = [1.0, 1.0, 1.0]", 9, 16)).unwrap();
    let out = tmp.path().join("fit");
    let o = lucent(&[
        "env",
        "fit-scale",
        twin.to_str().unwrap(),
        "--photo",
        photo.to_str().unwrap(),
        "--per-channel",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let j = json(&out.join("env_scale.json"));
    for (c, truth) in [0.6, 1.0, 1.8].into_iter().enumerate() {
        let got = j["new_constant"][c].as_f64().unwrap();
        assert!((got - truth).abs() < 0.02 * truth, "channel {c}: {got} vs {truth}: {j}");
    }
    // A scalar cannot match a coloured sky: its residual is far above the per-channel ones.
    let r = j["fit"]["residual_rms"].as_f64().unwrap();
    let rc = j["fit"]["residual_rms_per_channel"].as_array().unwrap();
    assert!(rc.iter().all(|v| v.as_f64().unwrap() < 0.5 * r), "{j}");
}

#[test]
fn bad_inputs_are_refused_and_write_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let twin = tmp.path().join("twin.toml");
    std::fs::write(&twin, scene(true, "constant = [1.0, 1.0, 1.0]", 1, 1)).unwrap();
    let small = tmp.path().join("small.exr");
    write_exr(&small, &RgbImage::new(8, 6, vec![0.5; 8 * 6 * 3]).unwrap()).unwrap();
    let mut nan = vec![0.5f32; 48 * 36 * 3];
    nan[3 * (48 * 2 + 5) + 1] = f32::NAN;
    let nan_photo = tmp.path().join("nan.exr");
    write_exr(&nan_photo, &RgbImage::new(48, 36, nan).unwrap()).unwrap();
    let no_board = root().join("tests/bad/env/no_board.toml");
    let cases: [(&Path, &Path, &[&str]); 4] = [
        (&twin, &small, &["8×6", "48×36"]),
        (&twin, &nan_photo, &["nan.exr", "NaN"]),
        (&twin, Path::new("/nonexistent/photo.exr"), &["photo.exr"]),
        (&no_board, &small, &["no_board.toml", "[board]"]),
    ];
    for (k, (s, p, needles)) in cases.iter().enumerate() {
        let out = tmp.path().join(format!("out{k}"));
        let o = lucent(&[
            "env",
            "fit-scale",
            s.to_str().unwrap(),
            "--photo",
            p.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "case {k} succeeded");
        for n in *needles {
            assert!(err.contains(n), "case {k}: {err:?} does not mention {n:?}");
        }
        assert!(!out.exists(), "case {k} wrote output");
    }
    // The photo reads as itself (sanity of the fixture writer).
    assert_eq!(read_rgb(&small).unwrap().width, 8);
}
