//! `lucent env orient` end to end: a panorama of a level chessboard, made
//! here with its map turned by a known yaw, is oriented from the board found
//! in a view cut from it and from the given yaw; the orientation file gives
//! a scene's `[environment]` its yaw; bad inputs are refused clearly.

use crate::common;
use common::{lucent, stderr, stdout};

use lucent::imageio::{read_rgb, write_exr, RgbImage};
use serde_json::Value;
use std::path::Path;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

/// A 360° camera 0.28 m above a point beside a level 9 × 6 board (30 mm
/// squares; world x along the board's i axis, y = −j, z up, corner (0, 0)
/// at the origin), its map turned so world = R_z(yaw) · map. Square (c, r)
/// spans i ∈ [c − 1, c), j ∈ [r − 1, r); (c + r) even light (the outer
/// square at corner (0, 0): `pose`'s and `env orient`'s numbering), odd dark;
/// one square of white margin, grey floor, bright sky. 2 × 2 samples per pixel.
fn panorama(w: usize, yaw_deg: f64) -> RgbImage {
    let h = w / 2;
    let cam = [0.10, -0.06, 0.28];
    let (sy, cy) = yaw_deg.to_radians().sin_cos();
    let mut data = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for k in 0..4 {
                let u = (x as f64 + 0.25 + 0.5 * (k % 2) as f64) / w as f64;
                let v = (y as f64 + 0.25 + 0.5 * (k / 2) as f64) / h as f64;
                let (theta, phi) = (std::f64::consts::PI * v, -std::f64::consts::TAU * u);
                let m = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
                let d = [cy * m[0] - sy * m[1], sy * m[0] + cy * m[1], m[2]];
                acc += if d[2] >= 0.0 {
                    1.0
                } else {
                    let t = -cam[2] / d[2];
                    let (bi, bj) = ((cam[0] + t * d[0]) / 0.03, -(cam[1] + t * d[1]) / 0.03);
                    let (c, r) = ((bi.floor() + 1.0) as i64, (bj.floor() + 1.0) as i64);
                    if (0..=9).contains(&c) && (0..=6).contains(&r) {
                        if (c + r) % 2 == 0 {
                            0.8
                        } else {
                            0.05
                        }
                    } else if (-1..=10).contains(&c) && (-1..=7).contains(&r) {
                        0.8
                    } else {
                        0.3
                    }
                };
            }
            data.extend([acc as f32 / 4.0; 3]);
        }
    }
    RgbImage { width: w, height: h, data }
}

fn mean_abs_diff(a: &RgbImage, b: &RgbImage) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height));
    a.data.iter().zip(&b.data).map(|(x, y)| f64::from((x - y).abs())).sum::<f64>() / a.data.len() as f64
}

/// `lucent env orient PANO --board-view VIEW --board 9x6 --square-mm 30
/// --view-size SIZE --out OUT`.
fn orient_from_board(pano: &Path, view: &str, view_size: &str, out: &Path) -> std::process::Output {
    lucent(&[
        "env",
        "orient",
        s(pano),
        "--board-view",
        view,
        "--board",
        "9x6",
        "--square-mm",
        "30",
        "--view-size",
        view_size,
        "--out",
        s(out),
    ])
}

#[test]
fn a_turned_panorama_is_oriented_from_its_board_and_from_a_given_yaw() {
    let dir = tempfile::tempdir().unwrap();
    let yaw = 37.5;
    let pano = dir.path().join("pano.exr");
    write_exr(&pano, &panorama(2048, yaw)).unwrap();
    let level = panorama(2048, 0.0);

    // From the board, seen straight down.
    let out = dir.path().join("pano_oriented.exr");
    let o = orient_from_board(&pano, "20,-90,100", "1200x1200", &out);
    assert!(o.status.success(), "{}{}", stdout(&o), stderr(&o));
    let j = json(&dir.path().join("pano_oriented.json"));
    let got = j["source_yaw_deg"].as_f64().unwrap();
    eprintln!("{}recovered yaw {got:.4}° (true {yaw}°)", stdout(&o));
    assert!((got - yaw).abs() < 0.1, "{j}");
    assert_eq!(
        (j["method"].as_str(), j["source"].as_str(), j["output"].as_str()),
        (Some("board"), Some("pano.exr"), Some("pano_oriented.exr"))
    );
    assert!(j["board"]["in_map"]["tilt_deg"].as_f64().unwrap() < 0.5, "{j}");
    assert!(j["board"]["pnp_rms_px"].as_f64().unwrap() < 0.5, "{j}");
    assert!(dir.path().join("pano_oriented_board.png").is_file());
    // The turned map is the panorama made with yaw 0 (linear interpolation along rows aside).
    let turned = read_rgb(&out).unwrap();
    let err = mean_abs_diff(&turned, &level);
    assert!(err < 0.01, "mean |turned − level| = {err}");

    // From the given yaw: the same turn.
    let out2 = dir.path().join("given.exr");
    let o = lucent(&["env", "orient", s(&pano), "--yaw", "37.5", "--out", s(&out2)]);
    assert!(o.status.success(), "{}", stderr(&o));
    let err2 = mean_abs_diff(&read_rgb(&out2).unwrap(), &level);
    // A different turn is clearly different (the check can fail).
    let out3 = dir.path().join("wrong.exr");
    assert!(lucent(&["env", "orient", s(&pano), "--yaw", "33.5", "--out", s(&out3)]).status.success());
    let err3 = mean_abs_diff(&read_rgb(&out3).unwrap(), &level);
    eprintln!("mean |turned − level|: board {err:.2e}, given yaw {err2:.2e}, 4° off {err3:.2e}");
    assert!(err2 < 0.01 && err3 > 5.0 * err2, "{err2} {err3}");
    assert_eq!(json(&dir.path().join("given.json"))["source_yaw_deg"].as_f64(), Some(37.5));

    // A scene takes its yaw from the orientation file: the source map's, the turned map's (0), no other.
    let scene = |map: &str, extra: &str| {
        let path = dir.path().join("scene.toml");
        std::fs::write(
            &path,
            format!(
                "[camera]\nwidth = 8\nheight = 6\nposition_m = [0.0, -0.1, 0.1]\nlook_at_m = [0.0, 0.0, 0.0]\n\
                 vertical_fov_deg = 30.0\n\n[environment]\nmap = {map:?}\nprojection = \"infinite\"\n{extra}\n"
            ),
        )
        .unwrap();
        lucent::scene::load(&path)
    };
    let env_of = |map: &str, extra: &str| scene(map, extra).map(|l| l.summary.environment).map_err(|e| e.to_string());
    let src = env_of("pano.exr", "orientation = \"pano_oriented.json\"").unwrap();
    assert!(src.contains(&format!("yaw {got}°")), "{src}");
    let turned_desc = env_of("pano_oriented.exr", "orientation = \"pano_oriented.json\"").unwrap();
    assert!(turned_desc.contains("yaw 0°"), "{turned_desc}");
    let e = env_of("given.exr", "orientation = \"pano_oriented.json\"").unwrap_err();
    assert!(e.contains("orientation") && e.contains("given.exr"), "{e}");
    let e = env_of("pano.exr", "orientation = \"pano_oriented.json\"\nyaw_deg = 3.0").unwrap_err();
    assert!(e.contains("not both"), "{e}");
    let e = env_of("pano.exr", "orientation = \"pano.exr\"").unwrap_err();
    assert!(e.contains("pano.exr") && e.contains("orientation file"), "{e}");
    std::fs::write(dir.path().join("other.json"), "{\"yaw_deg\": 3}").unwrap();
    let e = env_of("pano.exr", "orientation = \"other.json\"").unwrap_err();
    assert!(e.contains("other.json: not an orientation file"), "{e}");
}

/// One board numbering for `lucent pose` and `lucent env orient`: the
/// panorama's board is cut out by views whose own yaw turns it to six
/// directions in the image, and each view goes to both commands. `pose`
/// (with the view's pinhole camera) must put the camera where the 360°
/// camera is by construction, (0.10, −0.06, 0.28) m in the board's world —
/// the opposite numbering would put it 0.34 m away, at (0.14, −0.09, 0.28) —
/// and the camera's right axis must be the view's right (map frame) turned
/// by the yaw `env orient` finds, itself the panorama's 37.5°.
#[test]
fn pose_and_orient_number_the_board_alike() {
    let dir = tempfile::tempdir().unwrap();
    let yaw = 37.5;
    let pano = dir.path().join("pano.exr");
    write_exr(&pano, &panorama(2048, yaw)).unwrap();
    let truth = [0.10, -0.06, 0.28];
    for view_yaw in [0.0, 60.0, 120.0, 180.0, 240.0, 300.0] {
        let view = dir.path().join(format!("view{view_yaw}.png"));
        let o = lucent(&[
            "env",
            "view",
            s(&pano),
            "--yaw",
            &view_yaw.to_string(),
            "--pitch",
            "-90",
            "--fov",
            "100",
            "--size",
            "1000x1000",
            "--out",
            s(&view),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let vcam = json(&dir.path().join(format!("view{view_yaw}.json")))["camera"].clone();
        let f = vcam["f_px"].as_f64().unwrap();
        // The view as a calibrated camera: OpenCV pixel centres at integers, no distortion.
        let camera = serde_json::json!({
            "camera": {
                "model": "pinhole-k3", "image_width": 1000, "image_height": 1000,
                "intrinsics": { "fx": f, "fy": f, "cx": 499.5, "cy": 499.5 },
                "distortion": { "k1": 0.0, "k2": 0.0, "p1": 0.0, "p2": 0.0, "k3": 0.0, "k4": 0.0, "k5": 0.0, "k6": 0.0 }
            },
            "rms_px": 0.0, "board": { "cols": 9, "rows": 6, "square_m": 0.03 }, "views": [], "not_found": [],
            "method": "a view cut from the panorama (test)", "opencv_version": ""
        });
        let cam_json = dir.path().join("camera.json");
        std::fs::write(&cam_json, camera.to_string()).unwrap();
        let scene = dir.path().join(format!("scene{view_yaw}.json"));
        let o = lucent(&[
            "pose",
            "--camera",
            s(&cam_json),
            "--image",
            s(&view),
            "--board",
            "9x6",
            "--square-mm",
            "30",
            "--out",
            s(&scene),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let sc = json(&scene);
        let pos: Vec<f64> = (0..3).map(|k| sc["camera_position_m"][k].as_f64().unwrap()).collect();
        let err = (0..3).map(|k| (pos[k] - truth[k]).powi(2)).sum::<f64>().sqrt();
        let out = dir.path().join(format!("o{view_yaw}.exr"));
        let o = orient_from_board(&pano, &format!("{view_yaw},-90,100"), "1000x1000", &out);
        assert!(o.status.success(), "{}", stderr(&o));
        let got = json(&dir.path().join(format!("o{view_yaw}.json")))["source_yaw_deg"].as_f64().unwrap();
        // The camera's right axis (camera_to_world's first column) against R_z(yaw) · the view's right.
        let right: Vec<f64> = (0..3).map(|k| vcam["right"][k].as_f64().unwrap()).collect();
        let (sy, cy) = got.to_radians().sin_cos();
        let turned = [cy * right[0] - sy * right[1], sy * right[0] + cy * right[1], right[2]];
        let c2w = &sc["camera_to_world"];
        let dot: f64 = (0..3).map(|k| turned[k] * c2w[k][0].as_f64().unwrap()).sum();
        let angle = dot.clamp(-1.0, 1.0).acos().to_degrees();
        eprintln!(
            "view yaw {view_yaw}°: pose camera at {pos:.4?} m ({:.2} mm off), orient yaw {got:.3}°, axes {angle:.3}° apart",
            err * 1e3
        );
        assert!(err < 3e-3, "view yaw {view_yaw}: pose put the camera at {pos:?}, not {truth:?}");
        assert!((got - yaw).abs() < 0.1, "view yaw {view_yaw}: orient yaw {got}");
        assert!(angle < 0.5, "view yaw {view_yaw}: pose and orient frames {angle}° apart");
    }
}

#[test]
fn bad_orient_inputs_are_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let flat = dir.path().join("flat.exr");
    write_exr(&flat, &RgbImage { width: 64, height: 32, data: vec![0.5; 64 * 32 * 3] }).unwrap();
    let out = dir.path().join("o.exr");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        // Neither --yaw nor --board-view.
        (vec!["env", "orient", s(&flat), "--out", s(&out)], "--yaw"),
        // Both.
        (
            vec![
                "env",
                "orient",
                s(&flat),
                "--yaw",
                "3",
                "--board-view",
                "0,-90,90",
                "--board",
                "9x6",
                "--square-mm",
                "30",
                "--out",
                s(&out),
            ],
            "cannot be used with",
        ),
        // --board-view without the board.
        (vec!["env", "orient", s(&flat), "--board-view", "0,-90,90", "--out", s(&out)], "--board"),
        (
            vec![
                "env",
                "orient",
                s(&flat),
                "--board-view",
                "0,-90",
                "--board",
                "9x6",
                "--square-mm",
                "30",
                "--out",
                s(&out),
            ],
            "YAW,PITCH,FOV",
        ),
        (
            vec![
                "env",
                "orient",
                s(&flat),
                "--board-view",
                "0,-95,90",
                "--board",
                "9x6",
                "--square-mm",
                "30",
                "--out",
                s(&out),
            ],
            "pitch",
        ),
        // No board in the view.
        (
            vec![
                "env",
                "orient",
                s(&flat),
                "--board-view",
                "0,-90,90",
                "--board",
                "9x6",
                "--square-mm",
                "30",
                "--view-size",
                "200x200",
                "--out",
                s(&out),
            ],
            "no chessboard",
        ),
        (vec!["env", "orient", s(&flat), "--yaw", "nan", "--out", s(&out)], "finite"),
        (vec!["env", "orient", s(&flat), "--yaw", "10", "--out", "o.png"], ".exr"),
        (vec!["env", "orient", "tests/bad/env/no_such.exr", "--yaw", "10", "--out", s(&out)], "no_such.exr"),
    ];
    for (args, want) in cases {
        let o = lucent(&args);
        assert!(!o.status.success(), "{args:?} succeeded");
        let e = stderr(&o);
        assert!(e.contains(want), "{args:?}: {e}");
        assert!(!e.contains("panicked"), "{e}");
    }
    assert!(!out.exists(), "no output after a refusal");
    // Not 2:1.
    let square = dir.path().join("square.exr");
    write_exr(&square, &RgbImage { width: 32, height: 32, data: vec![0.5; 32 * 32 * 3] }).unwrap();
    let o = lucent(&["env", "orient", s(&square), "--yaw", "10", "--out", s(&out)]);
    assert!(!o.status.success() && stderr(&o).contains("2:1"), "{}", stderr(&o));
}

#[test]
fn paste_and_brackets_make_a_synthetic_panorama_that_orients_and_merges() {
    let dir = tempfile::tempdir().unwrap();
    let grey = dir.path().join("grey.exr");
    write_exr(&grey, &RgbImage { width: 512, height: 256, data: vec![0.3; 512 * 256 * 3] }).unwrap();
    // A level board seen straight down. Numbered from the light outer square at the picture's
    // bottom right, its i axis runs along the picture's −x, the view's left (−sin 27°, cos 27°, 0):
    // azimuth 117°, so the orienting yaw is −117°.
    let pano = dir.path().join("pano.exr");
    let o = lucent(&[
        "env",
        "paste",
        s(&grey),
        "--chessboard",
        "9x6",
        "--yaw",
        "27",
        "--pitch",
        "-90",
        "--fov",
        "70",
        "--width",
        "2048",
        "--out",
        s(&pano),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let out = dir.path().join("oriented.exr");
    let o = orient_from_board(&pano, "0,-90,100", "1000x1000", &out);
    assert!(o.status.success(), "{}", stderr(&o));
    let yaw = json(&dir.path().join("oriented.json"))["source_yaw_deg"].as_f64().unwrap();
    assert!((yaw + 117.0).abs() < 0.05, "yaw {yaw}");

    // Brackets: code = round(255 · sRGB(min(v · t, 1))), written out here (IEC 61966-2-1).
    let small = dir.path().join("small.exr");
    let values = [0.001f32, 0.02, 0.2, 0.7, 3.0, 40.0, 0.0, 0.5];
    let data: Vec<f32> = values.iter().flat_map(|v| [*v, v * 0.5, v * 2.0]).collect();
    write_exr(&small, &RgbImage { width: 4, height: 2, data: data.clone() }).unwrap();
    let bdir = dir.path().join("brackets");
    let o = lucent(&["env", "brackets", s(&small), "--exposures", "1/16,1,16", "--out-dir", s(&bdir)]);
    assert!(o.status.success(), "{}", stderr(&o));
    for (k, t) in [1.0f64 / 16.0, 1.0, 16.0].iter().enumerate() {
        let png = image::open(bdir.join(format!("bracket_{}.png", k + 1))).unwrap().to_rgb8();
        for (code, v) in png.as_raw().iter().zip(&data) {
            let x = (f64::from(*v) * t).min(1.0);
            let enc = if x <= 0.0031308 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
            assert_eq!(*code, (enc * 255.0).round() as u8, "value {v} exposure {t}");
        }
    }
    let o = lucent(&["env", "brackets", s(&small), "--exposures", "1,-2", "--out-dir", s(&bdir)]);
    assert!(!o.status.success() && stderr(&o).contains("-2"), "{}", stderr(&o));
    let o = lucent(&["env", "paste", s(&grey), "--fov", "40", "--out", s(&pano)]);
    assert!(!o.status.success() && stderr(&o).contains("--image"), "{}", stderr(&o));
}
