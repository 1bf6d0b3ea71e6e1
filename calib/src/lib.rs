//! Camera side of lucent (docs/method.md#camera): RAW files to linear camera RGB,
//! checkerboard calibration, board and sample poses, undistortion, and the
//! equirectangular HDR environment. The only crate that links OpenCV, and
//! only [`cv`] and [`ecc`] touch it: everything else here, and everything this crate
//! returns, is plain Rust (buffers, `[f64; N]` arrays, its own structs).
//!
//! | module | computes | units |
//! |---|---|---|
//! | [`buffer`] | the plain image buffers (linear RGB, 8-bit grey), bilinear sampling | as stored |
//! | [`raw`] | RAW → black/white-scaled mosaic → linear camera RGB, metadata | 1.0 = the white level |
//! | [`demosaic`] | Bayer demosaicing: Malvar–He–Cutler (2004), bilinear | as the mosaic |
//! | [`noise`] | a RAW photo's shot + read noise (var = a·x + b): DNG NoiseProfile or estimated from the image; developed noise realisations | 1.0 = the white level |
//! | [`model`] | the camera model: pinhole + the lens distortion of `lucent-lens` (Brown–Conrady / rational, Kannala–Brandt fisheye; re-exported), projection, validation | pixels, metres |
//! | [`board`] | the chessboard: inner corners, square size, corner positions | metres |
//! | [`pose`] | rigid poses in OpenCV's convention, rotation vectors (Rodrigues) | metres, radians |
//! | [`camera`] | undistortion of photos; re-exports [`model`] and the [`calibrate`] driver at their old paths | pixels |
//! | [`scene`] | sample placement, the OpenCV → renderer convention (the only place) | metres |
//! | [`error`] | [`error::CalibError`], the error of [`cv`], [`ecc`] and [`calibrate`] | — |
//! | [`cv`] | OpenCV: chessboard corners, Zhang calibration, PnP, drawing, `mcc` chart detection, camera response | pixels |
//! | [`calibrate`] | the calibration driver: detection over photos, calibration, per-view report (camera.json) | pixels, metres |
//! | [`env`](mod@env) | equirectangular HDR checks, colour matrices, perspective views | linear RGB |
//! | [`hdr`] | HDR merge of exposure brackets (linear; 8-bit via the recovered response) | relative radiance |
//! | [`ecc`] | OpenCV `findTransformECC` alignment (photo ↔ render), coarse to fine | pixels |
//!
//! Module graph (`use crate::…`, re-exports included), acyclic but for `cv` ↔ `hdr`
//! ([`hdr::merge_8bit_recovered`] calls [`cv::recover_response`], which takes and returns `hdr` types):
//! the leaves [`buffer`], [`model`], [`board`], [`pose`] import nothing from this crate;
//! [`error`] → board, buffer; [`cv`] → leaves, error, hdr; [`ecc`] → error;
//! [`noise`] → buffer, demosaic, raw; [`env`](mod@env) → model, buffer; [`calibrate`] → leaves, error, cv, env;
//! [`camera`] → buffer, model, calibrate; [`scene`] → model, board, pose, calibrate.
//!
//! ```
//! // A linear RGB buffer, row-major, interleaved.
//! let img = lucent_calib::RgbBuffer::new(2, 1, vec![0.0, 0.5, 1.0, 1.0, 0.5, 0.0]).unwrap();
//! assert_eq!(img.pixel(1, 0), [1.0, 0.5, 0.0]);
//! ```

pub mod board;
pub mod bracket;
pub mod buffer;
pub mod calibrate;
pub mod camera;
pub mod cv;
pub mod demosaic;
pub mod ecc;
pub mod env;
pub mod error;
pub mod hdr;
pub mod jpeg;
pub mod model;
pub mod noise;
pub mod pose;
pub mod raw;
pub mod scene;

pub use buffer::{BufferSizeError, GrayImage, RgbBuffer};

/// Version of the OpenCV library this crate links, e.g. `"4.6.0"`.
///
/// ```
/// assert!(lucent_calib::opencv_version().starts_with('4'));
/// ```
pub fn opencv_version() -> String {
    cv::version()
}
