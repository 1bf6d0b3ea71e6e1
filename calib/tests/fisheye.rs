//! Fisheye (Kannala–Brandt) calibration: chessboard corners projected here
//! through a known fisheye lens (the model written out independently below)
//! are calibrated back with `--model fisheye`; the pinhole models on the same
//! views fit visibly worse; our fisheye projection, undistortion map and PnP
//! agree with OpenCV's `fisheye` functions.

use lucent_calib::camera::{undistort_map, CameraModel, Distortion, DistortionModel, Intrinsics};
use lucent_calib::cv;
use lucent_calib::scene::{BoardSpec, Pose};

const BOARD: BoardSpec = BoardSpec { cols: 9, rows: 6, square_m: 0.03 };
const K: [f64; 4] = [0.03, -0.012, 0.004, -0.0008];

fn truth() -> CameraModel {
    CameraModel {
        model: DistortionModel::Fisheye,
        image_width: 1200,
        image_height: 1200,
        intrinsics: Intrinsics { fx: 380.0, fy: 381.5, cx: 600.4, cy: 598.7 },
        distortion: Distortion { k1: K[0], k2: K[1], k3: K[2], k4: K[3], ..Default::default() },
    }
}

/// Kannala–Brandt as OpenCV documents it (`cv::fisheye`): a = X/Z, b = Y/Z,
/// r = √(a² + b²), θ = atan r, θ_d = θ(1 + k1θ² + k2θ⁴ + k3θ⁶ + k4θ⁸),
/// u = fx (θ_d/r) a + cx, v = fy (θ_d/r) b + cy.
fn kannala_brandt(p: [f64; 3]) -> [f64; 2] {
    let c = truth().intrinsics;
    let (a, b) = (p[0] / p[2], p[1] / p[2]);
    let r = (a * a + b * b).sqrt();
    let t = r.atan();
    let td = t * (1.0 + K[0] * t.powi(2) + K[1] * t.powi(4) + K[2] * t.powi(6) + K[3] * t.powi(8));
    [c.fx * td / r * a + c.cx, c.fy * td / r * b + c.cy]
}

/// Board poses from the centre out to ≈ 87° off axis, tilted different ways.
fn poses() -> Vec<Pose> {
    [
        ([0.2, -0.1, 0.05], [-0.12, -0.08, 0.30]),
        ([-0.3, 0.25, 0.0], [-0.10, -0.07, 0.25]),
        ([0.1, 0.5, -0.1], [0.15, -0.05, 0.20]),
        ([0.0, -0.5, 0.1], [-0.45, -0.05, 0.22]),
        ([0.4, 0.0, 0.2], [-0.10, 0.20, 0.18]),
        ([-0.4, 0.1, -0.1], [-0.15, -0.40, 0.20]),
        ([0.3, 0.4, 0.3], [0.25, 0.15, 0.15]),
        ([-0.2, -0.3, -0.2], [-0.50, 0.15, 0.16]),
        ([0.15, 0.15, 0.5], [-0.05, -0.10, 0.45]),
        ([-0.1, 0.6, 0.0], [0.30, -0.35, 0.18]),
    ]
    .iter()
    .map(|&(r, t)| Pose::from_rvec_tvec(r, t))
    .collect()
}

fn views() -> Vec<Vec<[f64; 2]>> {
    poses()
        .iter()
        .map(|p| {
            BOARD
                .corners()
                .iter()
                .map(|&c| {
                    let q = p.to_camera(c);
                    assert!(q[2] > 0.0, "corner behind the camera");
                    kannala_brandt(q)
                })
                .collect()
        })
        .collect()
}

#[test]
fn fisheye_views_calibrate_back_and_pinhole_models_fit_worse() {
    let views = views();
    // The views reach far off axis (what a pinhole cannot model).
    let c = truth().intrinsics;
    let widest = views.iter().flatten().map(|p| ((p[0] - c.cx) / c.fx).hypot((p[1] - c.cy) / c.fy)).fold(0.0, f64::max);
    assert!(widest > 1.1, "widest θ_d {widest} rad");
    let fish = cv::calibrate(&views, &BOARD, (1200, 1200), DistortionModel::Fisheye).unwrap();
    let k = fish.camera.intrinsics;
    let d = fish.camera.distortion;
    let k3 = cv::calibrate(&views, &BOARD, (1200, 1200), DistortionModel::PinholeK3).unwrap();
    let rational = cv::calibrate(&views, &BOARD, (1200, 1200), DistortionModel::Rational).unwrap();
    eprintln!(
        "fisheye: rms {:.2e} px, f {:.4} {:.4}, c {:.4} {:.4}, k {:.5} {:.5} {:.5} {:.5}; pinhole-k3 rms {:.3} px; rational rms {:.3} px; widest θ_d {widest:.2} rad",
        fish.rms_px, k.fx, k.fy, k.cx, k.cy, d.k1, d.k2, d.k3, d.k4, k3.rms_px, rational.rms_px
    );
    // Exact corners pass through f32 inside OpenCV (≈ 3e-5 px at 1000 px).
    assert!(fish.rms_px < 1e-3, "fisheye rms {}", fish.rms_px);
    assert!((k.fx - c.fx).abs() < 0.05 && (k.fy - c.fy).abs() < 0.05, "{k:?}");
    assert!((k.cx - c.cx).abs() < 0.05 && (k.cy - c.cy).abs() < 0.05, "{k:?}");
    for (got, want) in [d.k1, d.k2, d.k3, d.k4].iter().zip(K) {
        assert!((got - want).abs() < 1e-3, "{d:?}");
    }
    for (got, want) in fish.poses.iter().zip(poses()) {
        for a in 0..3 {
            assert!((got.translation_m[a] - want.translation_m[a]).abs() < 1e-5, "{got:?} vs {want:?}");
        }
    }
    // The RMS gap: the pinhole models cannot bend rays up to 87° off axis onto the image.
    assert!(k3.rms_px > 1.0 && k3.rms_px > 1000.0 * fish.rms_px, "pinhole-k3 rms {}", k3.rms_px);
    assert!(rational.rms_px > 100.0 * fish.rms_px, "rational rms {}", rational.rms_px);
}

#[test]
fn our_fisheye_projection_undistortion_and_pnp_agree_with_opencv() {
    let cam = truth();
    let pose = poses()[3];
    let pts = BOARD.corners();
    let theirs = cv::project_points(&pts, &pose, &cam).unwrap();
    for (p, t) in pts.iter().zip(&theirs) {
        let q = pose.to_camera(*p);
        let mine = cam.project(q).unwrap();
        let indep = kannala_brandt(q);
        assert!((mine[0] - t[0]).abs() < 1e-9 && (mine[1] - t[1]).abs() < 1e-9, "{mine:?} vs OpenCV {t:?}");
        assert!((mine[0] - indep[0]).abs() < 1e-9 && (mine[1] - indep[1]).abs() < 1e-9);
        // And back: the pixel's ray is the point's direction.
        let r = cam.pixel_to_ray(mine[0], mine[1]).unwrap();
        assert!((r[0] - q[0] / q[2]).abs() < 1e-9 && (r[1] - q[1] / q[2]).abs() < 1e-9, "{r:?} vs {q:?}");
    }
    // A pinhole view of half the focal length (about ±58° across the image).
    let new_k = Intrinsics { fx: 190.0, fy: 190.0, cx: 600.0, cy: 600.0 };
    let theirs = cv::undistort_map(&cam, &new_k).unwrap();
    let mine = undistort_map(&cam, &new_k);
    let worst = mine
        .iter()
        .zip(&theirs)
        .map(|(a, b)| (a[0] - f64::from(b[0])).abs().max((a[1] - f64::from(b[1])).abs()))
        .fold(0.0, f64::max);
    assert!(worst < 2e-4, "undistortion map differs from fisheye::initUndistortRectifyMap by {worst} px");
    // PnP through the fisheye model.
    let corners: Vec<[f64; 2]> = pts.iter().map(|&p| kannala_brandt(pose.to_camera(p))).collect();
    let got = cv::solve_pnp(&corners, &BOARD, &cam).unwrap();
    for a in 0..3 {
        assert!((got.translation_m[a] - pose.translation_m[a]).abs() < 1e-5, "{got:?} vs {pose:?}");
    }
    // Beyond 90° off axis there is no pinhole ray.
    let far = cam.pixel_to_ray(cam.intrinsics.cx + 1.7 * cam.intrinsics.fx, cam.intrinsics.cy);
    assert!(far.is_none(), "{far:?}");
}
