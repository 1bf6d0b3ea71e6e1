//! The plain types of bracket merging that both [`crate::hdr`] (the merge)
//! and [`crate::cv`] (OpenCV's camera-response recovery) use: 8-bit
//! brackets, the response-recovery method and the recovered inverse
//! response, and the merge's error. A leaf module (it imports only
//! [`crate::buffer`]), so `hdr` and `cv` do not import each other for them;
//! [`crate::hdr`] re-exports them.

use serde::{Deserialize, Serialize};
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

/// What is wrong with a set of brackets.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HdrError {
    #[error("need at least 2 brackets to merge, got {0}")]
    TooFewBrackets(usize),
    #[error("bracket {index} is {width} × {height} pixels but bracket 0 is {width0} × {height0}: brackets must be the same size (and aligned)")]
    SizeMismatch { index: usize, width: usize, height: usize, width0: usize, height0: usize },
    #[error("{brackets} brackets but {exposures} exposures: give one exposure per bracket")]
    ExposureCount { brackets: usize, exposures: usize },
    #[error("exposure {value} of bracket {index} must be a positive finite number")]
    BadExposure { index: usize, value: f64 },
    #[error("brackets {a} and {b} have the same exposure {value}: bracketing needs different exposures")]
    SameExposure { a: usize, b: usize, value: f64 },
    #[error("bracket {index} has a NaN or infinite value at x = {x}, y = {y}")]
    NonFinite { index: usize, x: usize, y: usize },
    #[error("response method {name:?}: use {}", <ResponseMethod as strum::VariantNames>::VARIANTS.join(" or "))]
    UnknownResponseMethod { name: String },
    #[error("saturation {saturation} and noise floor {noise_floor} must be finite with 0 ≤ 2 × floor < saturation")]
    LinearWeights { saturation: f32, noise_floor: f32 },
    #[error("floor code {floor} must be below the saturation code {saturation}")]
    CodeWeights { floor: u8, saturation: u8 },
    #[error(
        "camera response recovery failed: channel {channel}: the inverse response must hold 256 positive finite values"
    )]
    BadResponse { channel: usize },
    #[error("camera response recovery failed: OpenCV {context}: {message}")]
    OpenCv { context: &'static str, message: String },
    #[error("camera response recovery failed: {0}")]
    Buffer(#[from] crate::buffer::BufferSizeError),
    #[error("camera response recovery failed: unexpected response of {rows} × {cols} (type {typ})")]
    ResponseShape { rows: i32, cols: i32, typ: i32 },
    #[error("camera response recovery failed: the recovered response has non-positive or non-finite values (too few brackets, or brackets without overlap)")]
    ResponseNotPositive,
}

/// An 8-bit RGB image: `width × height` interleaved R, G, B bytes, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Rgb8Buffer {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
}

impl Rgb8Buffer {
    /// Checks that `data` holds exactly `width × height` RGB triples.
    pub fn new(width: usize, height: usize, data: Vec<u8>) -> Result<Self, crate::buffer::BufferSizeError> {
        if width.checked_mul(height).and_then(|n| n.checked_mul(3)) != Some(data.len()) {
            return Err(crate::buffer::BufferSizeError { width, height, channels: 3, len: data.len() });
        }
        Ok(Self { width, height, data })
    }
}

/// Camera-response recovery method for 8-bit brackets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage)]
#[strum(serialize_all = "lowercase", ascii_case_insensitive)]
#[derive(Serialize, Deserialize)]
pub enum ResponseMethod {
    /// Debevec & Malik 1997.
    #[strum(to_string = "debevec", serialize = "debevec-malik")]
    Debevec,
    /// Robertson, Borman & Stevenson 2003.
    Robertson,
}

impl ResponseMethod {
    /// Any spelling of a method (case ignored); a bad name lists the valid ones.
    pub fn from_name(name: &str) -> Result<Self, HdrError> {
        name.trim().parse().map_err(|_| HdrError::UnknownResponseMethod { name: name.to_string() })
    }

    /// The name ("debevec", "robertson").
    pub fn name(self) -> &'static str {
        self.into()
    }
}

/// The inverse camera response: `curve[c][Z]` is the relative exposure
/// (radiance × exposure, one global factor unknown) that gives code `Z` in
/// channel `c` (R, G, B).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Response {
    pub method: ResponseMethod,
    pub curve: [Vec<f32>; 3],
}
