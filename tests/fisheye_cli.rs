//! Fisheye cameras at the command line: chessboard photos rendered here
//! through a known Kannala–Brandt lens (its inverse solved by bisection in
//! this file, not by the library) are calibrated back by `lucent calibrate
//! --model fisheye`, while `--model pinhole-k3` on the same photos fits
//! clearly worse; a fisheye image whose colours are the ray directions is
//! undistorted by `lucent undistort` to a pinhole view (`--fov`) and to an
//! equirectangular map (`--to equirect`), and each output pixel is checked
//! to show its own direction.

use crate::common;
use common::{lucent, stderr, stdout};

use lucent::imageio::{read_rgb, write_exr, RgbImage};
use rayon::prelude::*;
use serde_json::Value;
use std::path::Path;

const SIZE: usize = 640;
const F: [f64; 2] = [202.4, 203.2];
const C: [f64; 2] = [320.3, 319.1];
/// θ_d increasing up to π, so the validation of camera files accepts the lens over its whole image.
const K: [f64; 4] = [0.01, -0.001, 0.0001, -0.000005];
const SQUARE_M: f64 = 0.03;

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

fn theta_d(t: f64) -> f64 {
    let t2 = t * t;
    t * (1.0 + K[0] * t2 + K[1] * t2 * t2 + K[2] * t2.powi(3) + K[3] * t2.powi(4))
}

/// Unit ray (OpenCV camera frame) through pixel (u, v), centres at integers:
/// θ from θ_d(θ) = r_d by bisection on [0, π].
fn ray(u: f64, v: f64) -> [f64; 3] {
    let (x, y) = ((u - C[0]) / F[0], (v - C[1]) / F[1]);
    let rd = x.hypot(y);
    let (mut lo, mut hi) = (0.0, std::f64::consts::PI);
    for _ in 0..52 {
        let mid = 0.5 * (lo + hi);
        if theta_d(mid) < rd {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let t = 0.5 * (lo + hi);
    if rd < 1e-12 {
        return [0.0, 0.0, 1.0];
    }
    [t.sin() * x / rd, t.sin() * y / rd, t.cos()]
}

/// Rotation of a rotation vector (Rodrigues), written out here.
fn rot(r: [f64; 3]) -> [[f64; 3]; 3] {
    let th = (r[0] * r[0] + r[1] * r[1] + r[2] * r[2]).sqrt();
    let [x, y, z] = r.map(|v| v / th);
    let (s, c) = th.sin_cos();
    let t = 1.0 - c;
    [
        [c + x * x * t, x * y * t - z * s, x * z * t + y * s],
        [y * x * t + z * s, c + y * y * t, y * z * t - x * s],
        [z * x * t - y * s, z * y * t + x * s, c + z * z * t],
    ]
}

/// The rays of 2 × 2 samples per pixel (row-major pixels, 4 each).
fn sample_rays() -> Vec<[f64; 3]> {
    (0..SIZE * SIZE * 4)
        .into_par_iter()
        .map(|i| {
            let (p, k) = (i / 4, i % 4);
            ray((p % SIZE) as f64 - 0.25 + 0.5 * (k % 2) as f64, (p / SIZE) as f64 - 0.25 + 0.5 * (k / 2) as f64)
        })
        .collect()
}

/// An 8-bit photo of a 9 × 6 board (10 × 7 squares of 30 mm, white margin
/// of one square, grey beyond; black outside the lens's 100° circle), pose
/// x_cam = R x_board + t, from the rays of [`sample_rays`].
fn board_photo(rays: &[[f64; 3]], rvec: [f64; 3], t: [f64; 3]) -> image::GrayImage {
    let r = rot(rvec);
    let rt_t: f64 = (0..3).map(|k| r[k][2] * t[k]).sum();
    let data: Vec<u8> = rays
        .par_chunks(4)
        .map(|sub| {
            let mut acc = 0.0f64;
            for &d in sub {
                if d[2] < (100f64).to_radians().cos() {
                    continue;
                }
                // Board plane z_board = 0: (Rᵀ(λd − t))_z = 0.
                let den: f64 = (0..3).map(|k| r[k][2] * d[k]).sum();
                let lambda = rt_t / den;
                acc += if lambda <= 0.0 || !lambda.is_finite() {
                    0.5
                } else {
                    let q: [f64; 3] = std::array::from_fn(|k| lambda * d[k] - t[k]);
                    let xb: f64 = (0..3).map(|k| r[k][0] * q[k]).sum();
                    let yb: f64 = (0..3).map(|k| r[k][1] * q[k]).sum();
                    let (i, j) = ((xb / SQUARE_M).floor() as i64, (yb / SQUARE_M).floor() as i64);
                    if (-1..=8).contains(&i) && (-1..=5).contains(&j) {
                        if (i + j).rem_euclid(2) == 0 {
                            0.08
                        } else {
                            0.92
                        }
                    } else if (-2..=9).contains(&i) && (-2..=6).contains(&j) {
                        0.92
                    } else {
                        0.45
                    }
                };
            }
            (acc / 4.0 * 255.0).round() as u8
        })
        .collect();
    image::GrayImage::from_raw(SIZE as u32, SIZE as u32, data).unwrap()
}

#[test]
fn fisheye_photos_calibrate_back_and_undistort_to_pinhole_and_equirect() {
    let dir = tempfile::tempdir().unwrap();
    let photos = dir.path().join("photos");
    std::fs::create_dir(&photos).unwrap();
    // Board poses (rvec, tvec of corner (0, 0)): the board's centre from the axis out to ≈ 70° off it.
    let poses: [([f64; 3], [f64; 3]); 9] = [
        ([0.2, -0.1, 0.05], [-0.12, -0.08, 0.30]),
        ([-0.3, 0.25, 0.02], [-0.10, -0.07, 0.25]),
        ([0.1, 0.5, -0.1], [0.10, -0.05, 0.22]),
        ([0.0, -0.5, 0.1], [-0.40, -0.05, 0.24]),
        ([0.4, 0.0, 0.2], [-0.10, 0.12, 0.20]),
        ([-0.4, 0.1, -0.1], [-0.15, -0.32, 0.22]),
        ([0.3, 0.4, 0.3], [0.15, 0.08, 0.20]),
        ([-0.2, -0.3, -0.2], [-0.42, 0.10, 0.20]),
        ([0.15, 0.15, 0.5], [-0.05, -0.10, 0.40]),
    ];
    let rays = sample_rays();
    for (n, (r, t)) in poses.iter().enumerate() {
        board_photo(&rays, *r, *t).save(photos.join(format!("view{n}.png"))).unwrap();
    }
    let pattern = format!("{}/*.png", photos.display());
    let calibrate = |model: &str| {
        let out = dir.path().join(format!("{model}.json"));
        let o = lucent(&[
            "calibrate",
            "--images",
            &pattern,
            "--board",
            "9x6",
            "--square-mm",
            "30",
            "--model",
            model,
            "--out",
            s(&out),
        ]);
        assert!(o.status.success(), "{model}: {}{}", stdout(&o), stderr(&o));
        json(&out)
    };
    let fish = calibrate("fisheye");
    let views = fish["views"].as_array().unwrap().len();
    let rms_fish = fish["rms_px"].as_f64().unwrap();
    let k = &fish["camera"]["intrinsics"];
    let got = ["fx", "fy", "cx", "cy"].map(|n| k[n].as_f64().unwrap());
    eprintln!(
        "{views} views: fisheye rms {rms_fish:.4} px, f {:.3} {:.3}, c {:.3} {:.3} (truth {F:?} {C:?})",
        got[0], got[1], got[2], got[3]
    );
    assert!(views >= 6, "{views} views found");
    // Anti-aliased rendering and corner refinement: a few hundredths of a pixel.
    assert!(rms_fish < 0.1, "fisheye rms {rms_fish}");
    for (g, w) in got[..2].iter().zip(F) {
        assert!((g / w - 1.0).abs() < 0.005, "focal lengths {got:?}");
    }
    for (g, w) in got[2..].iter().zip(C) {
        assert!((g - w).abs() < 1.0, "principal point {got:?}");
    }
    // The pinhole model cannot bend rays 70° off axis onto the image: its fit
    // folds the image, and calibrate refuses to write it (undistort would).
    let o = lucent(&[
        "calibrate",
        "--images",
        &pattern,
        "--board",
        "9x6",
        "--square-mm",
        "30",
        "--model",
        "pinhole-k3",
        "--out",
        s(&dir.path().join("pinhole-k3.json")),
    ]);
    assert!(!o.status.success() && stderr(&o).contains("not usable"), "pinhole-k3: {}", stderr(&o));
    assert!(!dir.path().join("pinhole-k3.json").exists());

    // Undistortion of the true lens: a fisheye image whose colour is the ray direction.
    let mut truth = fish.clone();
    truth["camera"]["intrinsics"] = serde_json::json!({"fx": F[0], "fy": F[1], "cx": C[0], "cy": C[1]});
    for (n, v) in ["k1", "k2", "k3", "k4"].iter().zip(K) {
        truth["camera"]["distortion"][n] = serde_json::json!(v);
    }
    let cam = dir.path().join("truth.json");
    std::fs::write(&cam, serde_json::to_string_pretty(&truth).unwrap()).unwrap();
    let data: Vec<f32> = (0..SIZE * SIZE)
        .into_par_iter()
        .flat_map_iter(|p| {
            let d = ray((p % SIZE) as f64, (p / SIZE) as f64);
            let inside = d[2] >= (100f64).to_radians().cos();
            d.map(|v| if inside { v as f32 } else { 0.0 })
        })
        .collect();
    let fisheye = dir.path().join("fisheye.exr");
    write_exr(&fisheye, &RgbImage { width: SIZE, height: SIZE, data }).unwrap();
    let unit = |p: [f32; 3]| {
        let v = p.map(f64::from);
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        (n, v.map(|x| x / n))
    };
    let worst_of = |pairs: Vec<([f32; 3], [f64; 3])>| {
        pairs
            .iter()
            .map(|(p, want)| (0..3).map(|k| (unit(*p).1[k] - want[k]).abs()).fold(0.0, f64::max))
            .fold(0.0, f64::max)
    };

    // Pinhole view, 120° across: pixel (u, v) looks along ((u − cx)/f, (v − cy)/f, 1).
    let pinhole = dir.path().join("pinhole.exr");
    let o = lucent(&["undistort", "--camera", s(&cam), s(&fisheye), s(&pinhole), "--fov", "120"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = read_rgb(&pinhole).unwrap();
    let f = 0.5 * SIZE as f64 / (60f64).to_radians().tan();
    let c = (SIZE as f64 - 1.0) / 2.0;
    let pairs: Vec<_> = (0..SIZE * SIZE)
        .step_by(97)
        .map(|p| {
            let (u, v) = ((p % SIZE) as f64, (p / SIZE) as f64);
            let i = 3 * p;
            let n = ((u - c) / f).hypot((v - c) / f).hypot(1.0);
            ([img.data[i], img.data[i + 1], img.data[i + 2]], [(u - c) / f / n, (v - c) / f / n, 1.0 / n])
        })
        .collect();
    let worst_pin = worst_of(pairs);

    // The lens's own projection (written out here): pixel of a camera-frame ray.
    let project = |r: [f64; 3]| {
        let rho = r[0].hypot(r[1]);
        let td = theta_d(rho.atan2(r[2]));
        if rho < 1e-12 {
            return C;
        }
        [F[0] * td * r[0] / rho + C[0], F[1] * td * r[1] / rho + C[1]]
    };
    // Equirectangular map, 720 × 360: the lens axis at the centre, up at the top, the camera's right at u = ¾.
    let equi = dir.path().join("equirect.exr");
    let o = lucent(&["undistort", "--camera", s(&cam), s(&fisheye), s(&equi), "--to", "equirect", "--width", "720"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let img = read_rgb(&equi).unwrap();
    assert_eq!((img.width, img.height), (720, 360));
    let at = |x: usize, y: usize| {
        let i = 3 * (y * 720 + x);
        [img.data[i], img.data[i + 1], img.data[i + 2]]
    };
    // Landmarks: centre = axis (0, 0, 1); u = ¾ on the horizon = right (1, 0, 0); u = ¼ = left;
    // 80° up from the centre (row 20: 10° from the zenith) = (0, −sin 80°, cos 80°).
    let up80 = [0.0, -(80f64).to_radians().sin(), (80f64).to_radians().cos()];
    for ((x, y), want) in [
        ((360, 180), [0.0, 0.0, 1.0]),
        ((540, 180), [1.0, 0.0, 0.0]),
        ((180, 180), [-1.0, 0.0, 0.0]),
        ((360, 20), up80),
    ] {
        let (_, got) = unit(at(x, y));
        let err = (0..3).map(|k| (got[k] - want[k]).abs()).fold(0.0, f64::max);
        assert!(err < 0.02, "pixel ({x}, {y}) sees {got:?}, want {want:?}");
    }
    // Every pixel within 95° of the axis whose direction falls inside the photo (one pixel in from
    // its edges) shows its direction; beyond 100° nothing (0).
    let mut pairs = Vec::new();
    let mut outside_lit = 0;
    for y in 0..360 {
        for x in 0..720 {
            let theta = std::f64::consts::PI * (y as f64 + 0.5) / 360.0;
            let phi = -std::f64::consts::TAU * (x as f64 + 0.5) / 720.0;
            let d = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
            // Camera frame of the map direction, as documented: axis = map −x, up = map +z, right = map +y.
            let r = [d[1], -d[2], -d[0]];
            let off_axis = r[2].clamp(-1.0, 1.0).acos().to_degrees();
            let [pu, pv] = project(r);
            let in_photo = pu >= 1.0 && pv >= 1.0 && pu <= SIZE as f64 - 2.0 && pv <= SIZE as f64 - 2.0;
            if off_axis < 95.0 && in_photo {
                assert!((unit(at(x, y)).0 - 1.0).abs() < 1e-3, "pixel ({x}, {y}) {:?}", at(x, y));
                pairs.push((at(x, y), r));
            } else if off_axis > 101.0 && unit(at(x, y)).0 > 0.0 {
                outside_lit += 1;
            }
        }
    }
    let worst_eq = worst_of(pairs);
    eprintln!("undistorted fisheye: pinhole worst direction error {worst_pin:.2e}, equirect {worst_eq:.2e}");
    assert!(worst_pin < 2e-3, "pinhole view: worst {worst_pin}");
    assert!(worst_eq < 2e-3, "equirect view: worst {worst_eq}");
    assert_eq!(outside_lit, 0);
    assert!(json(&dir.path().join("equirect.json"))["convention"].as_str().unwrap().contains("axis"));

    // Bad combinations.
    for (args, want) in [
        (
            vec!["undistort", "--camera", s(&cam), s(&fisheye), s(&equi), "--to", "cube"],
            "[possible values: pinhole, equirect]",
        ),
        (vec!["undistort", "--camera", s(&cam), s(&fisheye), s(&equi), "--to", "equirect", "--fov", "90"], "--fov"),
        (vec!["undistort", "--camera", s(&cam), s(&fisheye), s(&equi), "--to", "equirect", "--width", "721"], "even"),
        (vec!["undistort", "--camera", s(&cam), s(&fisheye), s(&pinhole), "--fov", "180"], "--fov"),
    ] {
        let o = lucent(&args);
        assert!(!o.status.success() && stderr(&o).contains(want), "{args:?}: {}", stderr(&o));
    }
}
