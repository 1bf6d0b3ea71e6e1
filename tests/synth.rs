//! Synthetic captures (a known truth): the DNG written by
//! `lucent::synth` decodes to the mosaic it was made from; a chart captured
//! through a known camera matrix is calibrated back to that matrix (up to the
//! exposure); a CIE RGB image captured and developed with the truth comes
//! back; and a wrong matrix is detected.

use lucent::imageio::RgbImage;
use lucent::synth::{self, dng, ColourTruth, InputSpace, Sensor};
use lucent_calib::raw::{read_raw, RawData};
use lucent_colour::adaptation::Cat;
use lucent_colour::ccm::{fit_colorchecker, CcmMethod};
use lucent_colour::chart::{sample_patches, ImageRef, SampleOptions};
use lucent_colour::data::ICC_D50_XYZ;
use lucent_colour::spaces::{mat3_vec, RgbSpace};

/// The XYZ → camera ColorMatrix of a Canon body (as DNG files carry it).
const CAM: [[f64; 3]; 3] = [[0.6722, -0.0635, -0.0963], [-0.4287, 1.246, 0.2028], [-0.0908, 0.2162, 0.5668]];

fn truth() -> ColourTruth {
    ColourTruth { camera: "phone".into(), xyz_d50_to_camera: CAM, note: String::new() }
}

fn write(dir: &std::path::Path, name: &str, cap: &synth::Capture, sensor: &Sensor) -> std::path::PathBuf {
    let path = dir.join(name);
    dng::write_cfa_dng(&path, &dng::CfaDng::of_capture(cap, sensor, CAM, "test")).unwrap();
    path
}

#[test]
fn dng_decodes_to_the_mosaic_it_was_made_from() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (37, 22);
    let data: Vec<f32> = (0..w * h * 3).map(|i| ((i * 7919) % 1000) as f32 / 1000.0).collect();
    let img = RgbImage::new(w, h, data).unwrap();
    let sensor = Sensor::default();
    let ident = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    let cap = synth::capture_mosaic(&img, &ident, 0.7, &sensor, 3).unwrap();
    let path = write(dir.path(), "m.dng", &cap, &sensor);
    let frame = read_raw(&path, None).unwrap();
    assert_eq!(frame.meta.cfa_pattern, "RGGB");
    assert_eq!(frame.meta.black_levels, [1024.0; 4]);
    assert_eq!(frame.meta.white_levels, [16383.0; 4]);
    let wb = frame.meta.camera_wb_multipliers.unwrap();
    let n = synth::as_shot_neutral(&CAM);
    assert!((wb[0] - 1.0 / n[0]).abs() < 1e-4 && (wb[2] - 1.0 / n[2]).abs() < 1e-4, "{wb:?} vs 1/{n:?}");
    let RawData::Bayer(m) = &frame.data else { panic!("a Bayer DNG") };
    assert_eq!((m.width, m.height), (w, h));
    for (k, (&got, &dn)) in m.data.iter().zip(&cap.data).enumerate() {
        let want = (f32::from(dn) - 1024.0) / (16383.0 - 1024.0);
        assert_eq!(got, want, "photosite {k}");
    }
    // The noise is there, has the modelled size, and is seeded.
    let flat = RgbImage::new(64, 64, vec![0.5; 64 * 64 * 3]).unwrap();
    let a = synth::capture_mosaic(&flat, &ident, 1.0, &sensor, 1).unwrap();
    let b = synth::capture_mosaic(&flat, &ident, 1.0, &sensor, 1).unwrap();
    assert_eq!(a, b);
    let mean = a.data.iter().map(|&v| f64::from(v)).sum::<f64>() / a.data.len() as f64;
    let var = a.data.iter().map(|&v| (f64::from(v) - mean).powi(2)).sum::<f64>() / (a.data.len() - 1) as f64;
    let gain = (16383.0 - 1024.0) / 20000.0; // DN per electron
    let want = gain * gain * 10000.0 + 4.0 + 1.0 / 12.0; // shot + read + rounding
    assert!((mean - (1024.0 + 0.5 * 15359.0)).abs() < 3.0, "mean {mean}");
    assert!((var / want - 1.0).abs() < 0.1, "variance {var} vs {want}");
}

#[test]
fn a_captured_chart_is_calibrated_back_to_the_truth() {
    let dir = tempfile::tempdir().unwrap();
    let (w, h) = (360, 240);
    let corners = [[36.0, 30.0], [324.0, 24.0], [320.0, 214.0], [40.0, 216.0]];
    let chart = synth::chart_image(w, h, corners, 0.2).unwrap();
    let sensor = Sensor::default();
    let to_cam = synth::to_camera_matrix(InputSpace::XyzD50, &CAM).unwrap();
    let cap = synth::capture_mosaic(&chart, &to_cam, 0.8, &sensor, 7).unwrap();
    assert_eq!(cap.clipped, 0);
    let path = write(dir.path(), "chart.dng", &cap, &sensor);
    let img = lucent::imageio::read_rgb(&path).unwrap();
    let view = ImageRef::new(img.width, img.height, &img.data).unwrap();
    let samples = sample_patches(&view, corners, &SampleOptions::default()).unwrap();
    let rgb: Vec<[f64; 3]> = samples.iter().map(|s| s.mean).collect();
    let (ccm, report) = fit_colorchecker(CcmMethod::Cheung2004, &rgb).unwrap();
    let m: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| ccm.matrix()[r][c]));
    let rec = synth::colour_recovery(&truth(), &m).unwrap();
    assert!((rec.gain - 1.0 / 0.8).abs() < 0.005, "gain {} vs 1/0.8", rec.gain);
    assert!(rec.max_rel_matrix_error < 0.01, "{rec:?}");
    assert!(rec.de2000_max < 0.3, "{rec:?}");
    assert!(report.de2000_mean < 0.3, "fit ΔE {}", report.de2000_mean);
    // A camera matrix 5 % off in one entry is caught.
    let mut wrong = m;
    wrong[0][1] += 0.05 * m[0][0];
    let bad = synth::colour_recovery(&truth(), &wrong).unwrap();
    assert!(bad.max_rel_matrix_error > 0.02 && bad.de2000_max > 1.0, "{bad:?}");
}

#[test]
fn a_cie_rgb_image_developed_with_the_truth_comes_back() {
    let dir = tempfile::tempdir().unwrap();
    // Flat colours (no demosaicing error) on an 8 × 8 grid of 16-pixel tiles.
    let (w, h) = (128, 128);
    let colour = |tile: usize| -> [f32; 3] {
        let t = tile as f32;
        [0.05 + 0.4 * ((t * 0.37) % 1.0), 0.05 + 0.4 * ((t * 0.61) % 1.0), 0.05 + 0.4 * ((t * 0.83) % 1.0)]
    };
    let mut data = Vec::with_capacity(w * h * 3);
    for y in 0..h {
        for x in 0..w {
            data.extend(colour((y / 16) * 8 + x / 16));
        }
    }
    let img = RgbImage::new(w, h, data).unwrap();
    let sensor = Sensor { full_well_e: f64::INFINITY, read_noise_dn: 0.0, ..Sensor::default() };
    let to_cam = synth::to_camera_matrix(InputSpace::CieRgb, &CAM).unwrap();
    let cap = synth::capture_mosaic(&img, &to_cam, 1.0, &sensor, 1).unwrap();
    let path = write(dir.path(), "photo.dng", &cap, &sensor);
    let cam = lucent::imageio::read_rgb(&path).unwrap();
    // Develop as `colour apply --to cie-rgb` does: camera → XYZ D50 → Bradford → CIE RGB (E).
    let back = RgbSpace::CieRgb.from_xyz_adapted_matrix(ICC_D50_XYZ, Some(Cat::Bradford)).unwrap();
    let ccm = truth().camera_to_xyz_d50().unwrap();
    let mut worst = 0.0f64;
    for ty in 0..8 {
        for tx in 0..8 {
            let (x, y) = (16 * tx + 8, 16 * ty + 8);
            let c = cam.pixel(x, y).map(f64::from);
            let out = mat3_vec(&back, mat3_vec(&ccm, c));
            let want = img.pixel(x, y);
            for k in 0..3 {
                worst = worst.max((out[k] - f64::from(want[k])).abs());
            }
        }
    }
    // 14-bit quantisation through a matrix with entries up to ≈ 2.
    assert!(worst < 5e-4, "largest error {worst}");
}
