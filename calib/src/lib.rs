//! Camera side of lucent (SPEC §5): RAW decoding, checkerboard calibration,
//! poses and undistortion. The only crate that links OpenCV; OpenCV types
//! never leave this crate.
//!
//! For now it reports the OpenCV it was built against; calibration lands with
//! the cameras issue.

/// Version of the OpenCV library this crate links, e.g. `"4.6.0"`.
///
/// ```
/// assert!(lucent_calib::opencv_version().starts_with('4'));
/// ```
pub fn opencv_version() -> String {
    opencv::core::get_version_string().unwrap_or_else(|e| format!("unknown ({e})"))
}
