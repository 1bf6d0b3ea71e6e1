//! ColorChecker Classic 24 detection with OpenCV's mcc on the real chart
//! photo in fixtures/colour/ (and turned round), and the "not found" error
//! on images without a chart.

use lucent::chart_detect::{detect_colorchecker, ChartError, DetectedChart};
use lucent_calib::cv::read_rgb8;
use lucent_calib::RgbBuffer;
use lucent_colour::ccm::{fit_colorchecker, CcmMethod};
use lucent_colour::chart::{sample_patches, ImageRef, SampleOptions};
use std::path::{Path, PathBuf};

fn fixture(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(rel)
}

/// The photo's patch-grid corners found by eye (fixtures/colour/README.md).
const GIVEN: [[f64; 2]; 4] = [[5.0, 6.5], [196.0, 6.0], [195.5, 133.5], [3.5, 133.0]];

fn photo() -> RgbBuffer {
    read_rgb8(&fixture("fixtures/colour/colorchecker.png")).unwrap()
}

fn mean_de2000(img: &RgbBuffer, corners: [[f64; 2]; 4]) -> f64 {
    let view = ImageRef::new(img.width, img.height, &img.data).unwrap();
    let samples = sample_patches(&view, corners, &SampleOptions::default()).unwrap();
    let rgb: Vec<[f64; 3]> = samples.iter().map(|s| s.mean).collect();
    fit_colorchecker(CcmMethod::Cheung2004, &rgb).unwrap().1.de2000_mean
}

fn max_corner_error(found: &DetectedChart, expected: [[f64; 2]; 4]) -> f64 {
    found.corners.iter().zip(&expected).map(|(a, b)| (a[0] - b[0]).hypot(a[1] - b[1])).fold(0.0, f64::max)
}

/// Mean R+G+B of the 1-based patch `n` sampled at the detected corners.
fn patch_sum(img: &RgbBuffer, corners: [[f64; 2]; 4], n: usize) -> f64 {
    let view = ImageRef::new(img.width, img.height, &img.data).unwrap();
    sample_patches(&view, corners, &SampleOptions::default()).unwrap()[n - 1].mean.iter().sum()
}

#[test]
fn finds_the_real_chart_with_its_patches_in_reference_order() {
    let img = photo();
    let found = detect_colorchecker(&img, &SampleOptions::default()).unwrap();
    let err = max_corner_error(&found, GIVEN);
    assert!(err < 3.0, "corners {:?} vs {GIVEN:?}: {err:.2} px", found.corners);
    // Reference order: dark skin top left, white (19) the brightest and
    // black (24) the darkest of the neutral row.
    assert!(found.patch_centres[0][0] < 40.0 && found.patch_centres[0][1] < 40.0, "{:?}", found.patch_centres[0]);
    let neutrals: Vec<f64> = (19..=24).map(|n| patch_sum(&img, found.corners, n)).collect();
    assert!(neutrals.windows(2).all(|w| w[0] > w[1]), "{neutrals:?}");
    // The colour calibration from detected corners is as good as from the given ones.
    let (detected, given) = (mean_de2000(&img, found.corners), mean_de2000(&img, GIVEN));
    assert!((detected - given).abs() < 0.5, "mean ΔE00 {detected:.3} detected vs {given:.3} given");
    assert!((found.mean_de2000 - detected).abs() < 1e-9);
    // The other orientation is far worse: the choice is not a coin toss.
    assert!(found.other_orientation_de2000 > 3.0 * found.mean_de2000, "{found:?}");
    assert_eq!(found.patch_centres.len(), 24);
}

#[test]
fn a_chart_upside_down_still_gives_the_reference_order() {
    let img = photo();
    let (w, h) = (img.width, img.height);
    let mut data = Vec::with_capacity(img.data.len());
    for y in (0..h).rev() {
        for x in (0..w).rev() {
            data.extend_from_slice(&img.pixel(x, y));
        }
    }
    let turned = RgbBuffer::new(w, h, data).unwrap();
    let found = detect_colorchecker(&turned, &SampleOptions::default()).unwrap();
    // Dark skin is now bottom right: every corner turns by 180° about the centre.
    let expected = GIVEN.map(|p| [w as f64 - p[0], h as f64 - p[1]]);
    let err = max_corner_error(&found, expected);
    assert!(err < 3.0, "corners {:?} vs {expected:?}: {err:.2} px", found.corners);
    let (detected, given) = (mean_de2000(&turned, found.corners), mean_de2000(&img, GIVEN));
    assert!((detected - given).abs() < 0.5, "mean ΔE00 {detected:.3} vs {given:.3}");
}

#[test]
fn images_without_a_chart_are_a_clear_error() {
    let grey = RgbBuffer::new(320, 240, vec![0.18; 320 * 240 * 3]).unwrap();
    let chessboard = read_rgb8(&fixture("fixtures/camera/chessboard/left01.jpg")).unwrap();
    for img in [grey, chessboard] {
        match detect_colorchecker(&img, &SampleOptions::default()) {
            Err(e @ (ChartError::NotFound | ChartError::NoMatch { .. })) => {
                assert!(e.to_string().starts_with("no ColorChecker Classic 24 found"), "{e}");
            }
            other => panic!("expected ChartNotFound, got {other:?}"),
        }
    }
}
