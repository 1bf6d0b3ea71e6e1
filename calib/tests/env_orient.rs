//! Orientation of an equirectangular map to the board's world: a panorama
//! is made here of a level chessboard seen from above by a 360° camera whose
//! map is turned by a known yaw (the scene written out independently below:
//! ray from the camera, plane z = 0, square parity); the board is found in a
//! view cut from it and the yaw recovered; `rotate_yaw` is checked against
//! the renderer's stated convention on a map whose colours are directions.

use lucent_calib::camera::{CameraModel, Distortion, DistortionModel};
use lucent_calib::cv::{self, Detector};
use lucent_calib::env::{self, CornerOrder, ViewSpec};
use lucent_calib::scene::BoardSpec;
use lucent_calib::{GrayImage, RgbBuffer};

const BOARD: BoardSpec = BoardSpec { cols: 9, rows: 6, square_m: 0.03 };

/// The map of a 360° camera at `camera_m` (world: x along the board's i
/// axis, y = −j, z up, corner (0, 0) at the origin) whose map frame is turned
/// so that world = R_z(yaw) · map. Square (c, r) of the 10 × 7 board spans
/// i ∈ [c − 1, c), j ∈ [r − 1, r) squares; (c + r) even is light (0.8: the
/// outer square at corner (0, 0) is light, the numbering of `lucent pose`
/// and `lucent env orient`), odd dark (0.05); a white margin (0.8) of one
/// square; grey floor (0.3); sky 1.0. 3 × 3 samples per pixel.
fn panorama(w: usize, yaw_deg: f64, camera_m: [f64; 3]) -> RgbBuffer {
    let h = w / 2;
    let (sy, cy) = yaw_deg.to_radians().sin_cos();
    let s = BOARD.square_m;
    let mut img = RgbBuffer::zeros(w, h);
    for y in 0..h {
        for x in 0..w {
            let mut acc = 0.0;
            for k in 0..9 {
                let u = (x as f64 + (k % 3) as f64 / 3.0 + 1.0 / 6.0) / w as f64;
                let v = (y as f64 + (k / 3) as f64 / 3.0 + 1.0 / 6.0) / h as f64;
                let (theta, phi) = (std::f64::consts::PI * v, -std::f64::consts::TAU * u);
                let m = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
                let d = [cy * m[0] - sy * m[1], sy * m[0] + cy * m[1], m[2]];
                acc += if d[2] >= -1e-9 {
                    1.0
                } else {
                    let t = -camera_m[2] / d[2];
                    let (px, py) = (camera_m[0] + t * d[0], camera_m[1] + t * d[1]);
                    let (bi, bj) = (px / s, -py / s);
                    let (c, r) = ((bi.floor() + 1.0) as i64, (bj.floor() + 1.0) as i64);
                    if (0..=BOARD.cols as i64).contains(&c) && (0..=BOARD.rows as i64).contains(&r) {
                        if (c + r) % 2 == 0 {
                            0.8
                        } else {
                            0.05
                        }
                    } else if (-1..=BOARD.cols as i64 + 1).contains(&c) && (-1..=BOARD.rows as i64 + 1).contains(&r) {
                        0.8
                    } else {
                        0.3
                    }
                };
            }
            let o = 3 * (y * w + x);
            img.data[o..o + 3].copy_from_slice(&[(acc / 9.0) as f32; 3]);
        }
    }
    img
}

/// Finds the board in a view and returns the recovered yaw, order and tilt.
fn recover(map: &RgbBuffer, spec: &ViewSpec) -> (f64, CornerOrder, env::BoardInMap) {
    let (view, cam) = env::perspective_view(map, spec).unwrap();
    let gray = GrayImage::from_linear_rgb(&view);
    let corners = cv::find_corners(&gray, &BOARD, Detector::Auto).unwrap().expect("board found in the view");
    let (pts, order) = env::canonical_corner_order(&gray, BOARD.cols, BOARD.rows, &corners.points);
    let pinhole = CameraModel {
        model: DistortionModel::PinholeK3,
        image_width: spec.width,
        image_height: spec.height,
        intrinsics: env::view_intrinsics(&cam),
        distortion: Distortion::default(),
    };
    let pose = cv::solve_pnp(&pts, &BOARD, &pinhole).unwrap();
    let found = env::board_in_map(&cam, &pose.rotation, pose.translation_m);
    (found.yaw_deg, order, found)
}

fn angle_diff(a: f64, b: f64) -> f64 {
    (a - b + 180.0).rem_euclid(360.0) - 180.0
}

#[test]
fn the_yaw_of_a_turned_panorama_is_recovered_from_the_board() {
    // Camera 0.28 m above a point beside the board's middle.
    let camera = [0.10, -0.06, 0.28];
    for (yaw, view_yaw) in [(37.5, -20.0), (-123.0, 75.0)] {
        let map = panorama(2048, yaw, camera);
        // Looking straight down; the view's own yaw is arbitrary.
        let spec = ViewSpec { yaw_deg: view_yaw, pitch_deg: -90.0, fov_deg: 100.0, width: 1200, height: 1200 };
        let (got, order, found) = recover(&map, &spec);
        eprintln!(
            "yaw {yaw}: recovered {got:.4}° (order {order:?}, tilt {:.3}°, corner (0,0) at {:.4} m)",
            found.tilt_deg, found.corner00_distance_m
        );
        assert_ne!(order, CornerOrder::Ambiguous);
        assert!(angle_diff(got, yaw).abs() < 0.1, "yaw {yaw}: recovered {got}");
        assert!(found.tilt_deg < 0.2, "tilt {}", found.tilt_deg);
        // Corner (0, 0) is at the world origin: √(0.10² + 0.06² + 0.28²) away.
        let want = (0.10f64 * 0.10 + 0.06 * 0.06 + 0.28 * 0.28).sqrt();
        assert!((found.corner00_distance_m - want).abs() < 2e-3, "{}", found.corner00_distance_m);
        // Turning the map by the recovered yaw puts the board's i axis on +x:
        // the turned map equals the panorama made with yaw 0 (up to interpolation).
        let turned = env::rotate_yaw(&map, got).unwrap();
        let (v0, _, _) = recover(&turned, &spec);
        assert!(angle_diff(v0, 0.0).abs() < 0.1, "turned map: yaw {v0}");
    }
}

/// A map whose colours are the unit direction of the pixel centre (the
/// renderer's formula, not [`env::direction_to_uv`]).
fn direction_map(w: usize, h: usize) -> RgbBuffer {
    let mut m = RgbBuffer::zeros(w, h);
    for y in 0..h {
        for x in 0..w {
            let theta = std::f64::consts::PI * (y as f64 + 0.5) / h as f64;
            let phi = -std::f64::consts::TAU * (x as f64 + 0.5) / w as f64;
            let d = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
            for (o, v) in m.data[3 * (y * w + x)..3 * (y * w + x) + 3].iter_mut().zip(d) {
                *o = v as f32;
            }
        }
    }
    m
}

#[test]
fn rotate_yaw_follows_the_renderer_convention() {
    let (w, h) = (720, 360);
    let map = direction_map(w, h);
    for yaw in [90.0, -30.0, 12.25] {
        let turned = env::rotate_yaw(&map, yaw).unwrap();
        let (s, c) = f64::to_radians(yaw).sin_cos();
        let mut worst = 0.0f64;
        for y in (10..h - 10).step_by(7) {
            for x in (0..w).step_by(5) {
                // The turned map's pixel at world direction d holds the original map at
                // R_z(−yaw)·d, whose colour is that map direction m: R_z(yaw)·m must be d.
                let p = turned.pixel(x, y);
                let m = [f64::from(p[0]), f64::from(p[1]), f64::from(p[2])];
                let world = [c * m[0] - s * m[1], s * m[0] + c * m[1], m[2]];
                let theta = std::f64::consts::PI * (y as f64 + 0.5) / h as f64;
                let phi = -std::f64::consts::TAU * (x as f64 + 0.5) / w as f64;
                let d = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
                let n = m.iter().map(|v| v * v).sum::<f64>().sqrt();
                worst = worst.max((0..3).map(|k| (world[k] / n - d[k]).abs()).fold(0.0, f64::max));
            }
        }
        // Linear interpolation between pixel centres 0.5° apart: chord error ≤ (0.5° in rad)²/8.
        assert!(worst < 1e-4, "yaw {yaw}: worst {worst}");
    }
    // A whole-pixel turn is an exact shift; 360° is the identity.
    let t = env::rotate_yaw(&map, 360.0 / w as f64 * 3.0).unwrap();
    assert_eq!(t.pixel(0, 100), map.pixel(3, 100));
    assert_eq!(env::rotate_yaw(&map, 360.0).unwrap(), map);
    assert!(env::rotate_yaw(&RgbBuffer::zeros(10, 10), 5.0).is_err());
    assert!(env::rotate_yaw(&map, f64::NAN).is_err());
}

#[test]
fn orientation_gives_the_yaw_of_its_own_maps_only() {
    let o = env::Orientation {
        convention: env::ORIENTATION_CONVENTION.into(),
        source: "env.exr".into(),
        source_yaw_deg: 37.5,
        output: "env_oriented.exr".into(),
        output_yaw_deg: 0.0,
        method: "given".into(),
        board: None,
    };
    assert_eq!(o.yaw_for_map("env.exr").unwrap(), 37.5);
    assert_eq!(o.yaw_for_map("env_oriented.exr").unwrap(), 0.0);
    let e = o.yaw_for_map("studio.exr").unwrap_err().to_string();
    assert!(e.contains("env.exr") && e.contains("studio.exr"), "{e}");
}

#[test]
fn a_pasted_picture_is_seen_again_by_the_same_view() {
    // A smooth picture pasted into a grey map and cut out again by the same view: the
    // two bilinear resamplings (map pixels 0.09° apart, picture pixels ≈ 0.07°) leave a small error.
    let (w, h) = (200, 150);
    let mut pic = RgbBuffer::zeros(w, h);
    for y in 0..h {
        for x in 0..w {
            let (u, v) = (x as f32 / w as f32, y as f32 / h as f32);
            pic.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[u, v, 0.5 + 0.5 * (u * 6.0).sin() * v]);
        }
    }
    let mut map = RgbBuffer::new(4096, 2048, vec![0.25; 4096 * 2048 * 3]).unwrap();
    let spec = ViewSpec { yaw_deg: 130.0, pitch_deg: -30.0, fov_deg: 14.0, width: w, height: h };
    let n = env::paste_view(&mut map, &pic, &spec).unwrap();
    assert!(n > 10_000, "{n} map pixels");
    let (back, _) = env::perspective_view(&map, &spec).unwrap();
    let mut worst = 0.0f32;
    for y in 2..h - 2 {
        for x in 2..w - 2 {
            for c in 0..3 {
                worst = worst.max((back.pixel(x, y)[c] - pic.pixel(x, y)[c]).abs());
            }
        }
    }
    assert!(worst < 0.01, "worst {worst}");
    // Outside the view the map is untouched; a picture of the wrong size is refused.
    assert_eq!(map.pixel(0, 1024), [0.25; 3]);
    assert!(env::paste_view(&mut map, &RgbBuffer::zeros(3, 3), &spec).is_err());
    // The board picture: dark outer corner square at the top left, 10 × 7 squares inside a margin.
    let b = env::chessboard_picture(9, 6, 10, 0.05, 0.8);
    assert_eq!((b.width, b.height), (120, 90));
    assert_eq!((b.pixel(15, 15), b.pixel(25, 15), b.pixel(5, 5)), ([0.05; 3], [0.8; 3], [0.8; 3]));
    assert_eq!(b.pixel(105, 75), [0.8; 3], "the bottom-right outer square (at corner (0, 0) for 9 × 6) is light");
}
