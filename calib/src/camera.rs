//! Undistortion of linear RGB photos with a calibrated camera
//! ([`crate::model`]), and the camera API at its long-standing paths
//! (`lucent_calib::camera::CameraModel`, `…::calibrate_photos`, …): the
//! model is the leaf module [`crate::model`], the calibration driver
//! [`crate::calibrate`]; both are re-exported here.
//!
//! Undistortion resamples a photo to the pinhole image of the same camera:
//! output pixel → ray with the new intrinsics → distorted source position →
//! bilinear interpolation (pixels outside the photo are 0). The new
//! intrinsics are the old ones, or ([`NewCamera::KeepAll`]) a focal length
//! and principal point chosen so that every source pixel lands inside the
//! output (the whole photo is kept; corners of the output may be black).
//!
//! ```
//! use lucent_calib::camera::{undistort, CameraModel, Distortion, DistortionModel, Intrinsics, NewCamera};
//! use lucent_calib::RgbBuffer;
//! let cam = CameraModel {
//!     model: DistortionModel::PinholeK3,
//!     image_width: 64, image_height: 48,
//!     intrinsics: Intrinsics { fx: 60.0, fy: 60.0, cx: 31.5, cy: 23.5 },
//!     distortion: Distortion::default(),
//! };
//! // Without distortion and with the same intrinsics, undistortion is the identity.
//! let photo = RgbBuffer::new(64, 48, (0..64 * 48 * 3).map(|i| (i % 7) as f32).collect()).unwrap();
//! let (out, k) = undistort(&photo, &cam, NewCamera::Same).unwrap();
//! let worst = out.data.iter().zip(&photo.data).map(|(a, b)| (a - b).abs()).fold(0.0f32, f32::max);
//! assert!(worst < 1e-4 && k == cam.intrinsics, "{worst}");
//! ```

use crate::buffer::RgbBuffer;
use rayon::prelude::*;

// The camera model, bilinear sampling and the calibration driver at this module's paths
// (the root crate, the fuzz target and the tests use them).
pub use crate::buffer::sample_bilinear;
pub use crate::calibrate::{
    calibrate_photos, calibrate_photos_reporting, Calibration, CalibrationStep, CalibrationView, NotFound, Photo,
    MIN_VIEWS,
};
pub use crate::model::{
    CameraError, CameraModel, Distortion, DistortionModel, Intrinsics, Lens, MAX_IMAGE_SIDE, RADIAL_SCALE_RANGE,
};

/// Intrinsics of an undistorted image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NewCamera {
    /// The calibrated ones (the centre keeps its scale; borders are cropped).
    Same,
    /// Every source pixel kept ([`CameraModel::keep_all_intrinsics`]).
    KeepAll,
    /// Given ones.
    Given(Intrinsics),
}

/// For every output pixel (row-major), the source position (u, v) in the
/// distorted photo, for an output of the camera's image size with
/// intrinsics `new_k`.
pub fn undistort_map(cam: &CameraModel, new_k: &Intrinsics) -> Vec<[f64; 2]> {
    let (w, h) = (cam.image_width, cam.image_height);
    let k = cam.intrinsics;
    (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (u, v) = ((i % w) as f64, (i / w) as f64);
            let [xd, yd] = cam.distort((u - new_k.cx) / new_k.fx, (v - new_k.cy) / new_k.fy);
            [k.fx * xd + k.cx, k.fy * yd + k.cy]
        })
        .collect()
}

/// Undistorts a linear RGB photo taken by `cam` (its size must be the
/// calibration's). Returns the image and the intrinsics it has.
pub fn undistort(
    img: &RgbBuffer,
    cam: &CameraModel,
    new_camera: NewCamera,
) -> Result<(RgbBuffer, Intrinsics), CameraError> {
    if (img.width, img.height) != (cam.image_width, cam.image_height) {
        return Err(CameraError::PhotoSize {
            width: img.width,
            height: img.height,
            camera_width: cam.image_width,
            camera_height: cam.image_height,
        });
    }
    let new_k = match new_camera {
        NewCamera::Same => cam.intrinsics,
        NewCamera::KeepAll => cam.keep_all_intrinsics(),
        NewCamera::Given(k) => k,
    };
    let map = undistort_map(cam, &new_k);
    let data: Vec<f32> = map.par_iter().flat_map_iter(|&[u, v]| sample_bilinear(img, u, v)).collect();
    Ok((RgbBuffer { width: img.width, height: img.height, data }, new_k))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::tests::camera;

    #[test]
    fn undistorting_an_image_rendered_through_the_lens_gives_the_pinhole_image() {
        // A smooth scene seen by the pinhole camera: f(x, y) of normalised coordinates.
        let cam = camera();
        let scene = |x: f64, y: f64| (0.5 + 0.3 * (4.0 * x).sin() * (3.0 * y).cos()) as f32;
        let k = cam.intrinsics;
        // Photo through the lens: each pixel sees the scene at its undistorted ray.
        let mut photo = RgbBuffer::zeros(64, 48);
        for v in 0..48 {
            for u in 0..64 {
                let [x, y, _] = cam.pixel_to_ray(u as f64, v as f64).unwrap();
                let s = scene(x, y);
                photo.data[3 * (v * 64 + u)..3 * (v * 64 + u) + 3].copy_from_slice(&[s, 0.5 * s, 0.25]);
            }
        }
        let (out, nk) = undistort(&photo, &cam, NewCamera::Same).unwrap();
        assert_eq!(nk, k);
        let mut worst = 0.0f32;
        for v in 8..40 {
            for u in 8..56 {
                let s = scene((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy);
                let p = out.pixel(u, v);
                worst = worst.max((p[0] - s).abs()).max((p[1] - 0.5 * s).abs()).max((p[2] - 0.25).abs());
            }
        }
        assert!(worst < 5e-3, "bilinear resampling error {worst}");
        let wrong = RgbBuffer::zeros(10, 10);
        assert!(undistort(&wrong, &cam, NewCamera::Same).unwrap_err().to_string().contains("64 × 48"));
    }
}
