//! The structured values of jobs that the command line and the project
//! file write as text: each type reads its text in one place (its
//! `FromStr`, refusing a wrong text with a message naming it), writes it
//! back with `Display`, and is serialised as that text, so a job's JSON
//! holds the same words its command line does.
//!
//! Defined here: [`ImageSize`], [`MeasuredSlice`], [`SampleCorner`],
//! [`SampleSizeMm`], [`ClipLevel`]. Elsewhere, with their quantity:
//! [`lucent_colour::WavelengthGrid`], [`crate::bssrdf::Configuration`],
//! [`crate::bssrdf::Configurations`], [`lucent_calib::board::BoardSize`],
//! [`crate::fit::FreeSpec`] and [`crate::fit::SearchBounds`].

use std::path::PathBuf;
use thiserror::Error;

use crate::text::serde_as_text;

/// An image size in pixels that a render can hold (at least 1 × 1, within
/// [`lucent_render::camera::check_image_size`]'s limits).
///
/// As text "WIDTHxHEIGHT", e.g. "640x480" ("640X480" is read too and
/// written "640x480").
///
/// ```
/// use lucent::job::ImageSize;
/// let s: ImageSize = "640x480".parse().unwrap();
/// assert_eq!((s.width, s.height), (640, 480));
/// assert_eq!(s.to_string(), "640x480");
/// assert!("0x12".parse::<ImageSize>().unwrap_err().to_string().contains("\"0x12\""));
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ImageSize {
    /// Pixels per row.
    pub width: usize,
    /// Rows of pixels.
    pub height: usize,
}

/// An image size written as text that is not one ([`ImageSize`]).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ImageSizeError {
    #[error("{text:?}: expected WIDTHxHEIGHT, e.g. 640x480")]
    Syntax { text: String },
    #[error("{text:?}: bad {side}: {reason}")]
    Number { text: String, side: &'static str, reason: String },
    #[error("{text:?}: width and height must be at least 1")]
    Empty { text: String },
    #[error("{text:?}: {source}")]
    Limit { text: String, source: lucent_render::camera::CameraError },
}

impl std::str::FromStr for ImageSize {
    type Err = ImageSizeError;

    fn from_str(text: &str) -> Result<Self, ImageSizeError> {
        let (w, h) = text.split_once(['x', 'X']).ok_or_else(|| ImageSizeError::Syntax { text: text.into() })?;
        let side = |t: &str, side: &'static str| {
            t.trim().parse::<usize>().map_err(|e| ImageSizeError::Number {
                text: text.into(),
                side,
                reason: e.to_string(),
            })
        };
        let (width, height) = (side(w, "width")?, side(h, "height")?);
        if width == 0 || height == 0 {
            return Err(ImageSizeError::Empty { text: text.into() });
        }
        lucent_render::camera::check_image_size(width, height)
            .map_err(|source| ImageSizeError::Limit { text: text.into(), source })?;
        Ok(ImageSize { width, height })
    }
}

impl std::fmt::Display for ImageSize {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}x{}", self.width, self.height)
    }
}

serde_as_text!(ImageSize);

/// (θi, φi, θo, φo) of a measured slice, in degrees.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum MeasuredAngles {
    /// θi/θo in the plane of incidence (φi = 0°, φo = 180°).
    Plane(crate::bssrdf::Configuration),
    /// θi/φi/θo/φo, every angle in degrees.
    Full { theta_i_deg: f64, phi_i_deg: f64, theta_o_deg: f64, phi_o_deg: f64 },
}

impl MeasuredAngles {
    /// (θi, φi, θo, φo) in degrees.
    pub fn degrees(self) -> (f64, f64, f64, f64) {
        match self {
            MeasuredAngles::Plane(c) => (c.theta_i_deg, 0.0, c.theta_o_deg, 180.0),
            MeasuredAngles::Full { theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg } => {
                (theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg)
            }
        }
    }
}

/// A measured slice of a fit: its file and the configuration it was
/// measured at (none: from the file's sidecar).
///
/// As text "FILE", "FILE:θi/θo" or "FILE:θi/φi/θo/φo" (degrees; θ in
/// [0°, 90°), φ finite), e.g. "slice.exr:45/0".
///
/// ```
/// use lucent::job::MeasuredSlice;
/// let m: MeasuredSlice = "m.exr:45/0".parse().unwrap();
/// assert_eq!(m.angles.map(|a| a.degrees()), Some((45.0, 0.0, 0.0, 180.0)));
/// assert_eq!(m.to_string(), "m.exr:45/0");
/// assert!("m.exr:45/x".parse::<MeasuredSlice>().is_err());
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct MeasuredSlice {
    pub path: PathBuf,
    pub angles: Option<MeasuredAngles>,
}

/// A measured slice written as text that is not one ([`MeasuredSlice`]).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum MeasuredSliceError {
    #[error("{text:?}: {angles:?} is not THETA_I/THETA_O or THETA_I/PHI_I/THETA_O/PHI_O")]
    Syntax { text: String, angles: String },
    #[error("{text:?}: give 2 angles (θi/θo) or 4 (θi/φi/θo/φo)")]
    Count { text: String },
    #[error("{text:?}: θi and θo must lie in [0°, 90°), φi and φo be finite")]
    Angle { text: String },
    #[error("{text:?}: {source}")]
    Configuration { text: String, source: crate::bssrdf::ConfigError },
}

impl std::str::FromStr for MeasuredSlice {
    type Err = MeasuredSliceError;

    /// The angles are the part after the last ':' when it holds a '/'.
    fn from_str(text: &str) -> Result<Self, MeasuredSliceError> {
        let Some((file, angles)) = text.rsplit_once(':').filter(|(_, a)| a.contains('/')) else {
            return Ok(MeasuredSlice { path: PathBuf::from(text), angles: None });
        };
        let syntax = || MeasuredSliceError::Syntax { text: text.into(), angles: angles.into() };
        let nums: Vec<f64> =
            angles.split('/').map(|s| s.trim().parse::<f64>()).collect::<Result<_, _>>().map_err(|_| syntax())?;
        let angles = match nums.as_slice() {
            [_, _] => MeasuredAngles::Plane(
                angles.parse().map_err(|source| MeasuredSliceError::Configuration { text: text.into(), source })?,
            ),
            &[ti, pi, to, po] => {
                let theta = |t: f64| (0.0..90.0).contains(&t);
                if !(theta(ti) && theta(to) && pi.is_finite() && po.is_finite()) {
                    return Err(MeasuredSliceError::Angle { text: text.into() });
                }
                MeasuredAngles::Full { theta_i_deg: ti, phi_i_deg: pi, theta_o_deg: to, phi_o_deg: po }
            }
            _ => return Err(MeasuredSliceError::Count { text: text.into() }),
        };
        Ok(MeasuredSlice { path: PathBuf::from(file), angles: Some(angles) })
    }
}

impl std::fmt::Display for MeasuredSlice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.path.display())?;
        match self.angles {
            None => Ok(()),
            Some(MeasuredAngles::Plane(c)) => write!(f, ":{c}"),
            Some(MeasuredAngles::Full { theta_i_deg, phi_i_deg, theta_o_deg, phi_o_deg }) => {
                write!(f, ":{theta_i_deg}/{phi_i_deg}/{theta_o_deg}/{phi_o_deg}")
            }
        }
    }
}

serde_as_text!(MeasuredSlice);

/// The board's inner corner under a sample's top-left corner: indices
/// (i along a row, j along a column) as `lucent pose` draws them.
///
/// As text "I,J", e.g. "2,1". Whether the corner lies on the board is
/// the pose's check (it needs the board).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleCorner {
    pub i: usize,
    pub j: usize,
}

/// Comma-separated numbers of `text`, `N` of them, or `None`.
fn numbers<const N: usize>(text: &str) -> Option<[f64; N]> {
    let v: Vec<f64> = text.split(',').map(|s| s.trim().parse::<f64>()).collect::<Result<_, _>>().ok()?;
    <[f64; N]>::try_from(v).ok()
}

/// A sample's corner or size written as text that is not one
/// ([`SampleCorner`], [`SampleSizeMm`]).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum SampleError {
    #[error("{text:?}: expected inner-corner indices I,J (whole numbers ≥ 0), e.g. 2,1")]
    Corner { text: String },
    #[error("{text:?}: expected the width, height and thickness in mm, e.g. 149.1,104.5,6.35")]
    Size { text: String },
    #[error("{text:?}: width, height and thickness must be positive")]
    NotPositive { text: String },
}

impl std::str::FromStr for SampleCorner {
    type Err = SampleError;

    fn from_str(text: &str) -> Result<Self, SampleError> {
        let index = |v: f64| (v >= 0.0 && v.fract() == 0.0 && v < 1e9).then_some(v as usize);
        match numbers::<2>(text).map(|[i, j]| (index(i), index(j))) {
            Some((Some(i), Some(j))) => Ok(SampleCorner { i, j }),
            _ => Err(SampleError::Corner { text: text.into() }),
        }
    }
}

impl std::fmt::Display for SampleCorner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{}", self.i, self.j)
    }
}

serde_as_text!(SampleCorner);

/// A sample's width (along the board's i), height (along j) and thickness
/// in millimetres, each finite and > 0.
///
/// As text "W,H,T", e.g. "149.1,104.5,6.35".
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SampleSizeMm {
    pub width: f64,
    pub height: f64,
    pub thickness: f64,
}

impl SampleSizeMm {
    /// [width, height, thickness] in mm.
    pub fn mm(self) -> [f64; 3] {
        [self.width, self.height, self.thickness]
    }
}

impl std::str::FromStr for SampleSizeMm {
    type Err = SampleError;

    fn from_str(text: &str) -> Result<Self, SampleError> {
        let [width, height, thickness] = numbers::<3>(text).ok_or_else(|| SampleError::Size { text: text.into() })?;
        if [width, height, thickness].iter().any(|v| !(v.is_finite() && *v > 0.0)) {
            return Err(SampleError::NotPositive { text: text.into() });
        }
        Ok(SampleSizeMm { width, height, thickness })
    }
}

impl std::fmt::Display for SampleSizeMm {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{}", self.width, self.height, self.thickness)
    }
}

serde_as_text!(SampleSizeMm);

/// The outer corners of a ColorChecker's 4 × 6 patch grid in pixels (x
/// right, y down, the image's edge at 0): the dark-skin, bluish-green,
/// black and white patches' corners, clockwise in the image; each finite.
///
/// As text "x1,y1,x2,y2,x3,y3,x4,y4".
///
/// ```
/// use lucent::job::ChartCorners;
/// let c: ChartCorners = "10,20, 300,20,300,200,10,200".parse().unwrap();
/// assert_eq!(c.0[1], [300.0, 20.0]);
/// assert_eq!(c.to_string(), "10,20,300,20,300,200,10,200");
/// assert!("1,2,3".parse::<ChartCorners>().unwrap_err().to_string().contains("got 3"));
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChartCorners(pub [[f64; 2]; 4]);

/// Chart corners written as text that is not 8 finite numbers.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ChartCornersError {
    #[error("{text:?}: {value:?} is not a number")]
    NotNumber { text: String, value: String },
    #[error("{text:?}: expected 8 numbers x1,y1,x2,y2,x3,y3,x4,y4, got {count}")]
    Count { text: String, count: usize },
    #[error("{text:?}: {value} is not a finite number")]
    NotFinite { text: String, value: f64 },
}

impl std::str::FromStr for ChartCorners {
    type Err = ChartCornersError;

    fn from_str(text: &str) -> Result<Self, ChartCornersError> {
        let values = text
            .split(',')
            .map(|s| {
                s.trim()
                    .parse::<f64>()
                    .map_err(|_| ChartCornersError::NotNumber { text: text.into(), value: s.trim().into() })
            })
            .collect::<Result<Vec<f64>, _>>()?;
        let Ok(v) = <[f64; 8]>::try_from(values.as_slice()) else {
            return Err(ChartCornersError::Count { text: text.into(), count: values.len() });
        };
        if let Some(value) = v.iter().copied().find(|v| !v.is_finite()) {
            return Err(ChartCornersError::NotFinite { text: text.into(), value });
        }
        Ok(ChartCorners([[v[0], v[1]], [v[2], v[3]], [v[4], v[5]], [v[6], v[7]]]))
    }
}

impl std::fmt::Display for ChartCorners {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let words: Vec<String> = self.0.iter().flatten().map(f64::to_string).collect();
        f.write_str(&words.join(","))
    }
}

serde_as_text!(ChartCorners);

/// `--clip-level`: a pixel with a channel at or above this level (in the
/// image as stored) is clipped, or no check. A job file spells it as the
/// command line does: a positive number, or "none".
///
/// ```
/// use lucent::job::ClipLevel;
/// assert_eq!("none".parse::<ClipLevel>().unwrap().level(), None);
/// assert_eq!("0.95".parse::<ClipLevel>().unwrap().level(), Some(0.95));
/// assert!("-1".parse::<ClipLevel>().is_err());
/// ```
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ClipLevel {
    /// No check.
    None,
    /// The level, > 0.
    At(f64),
}

/// A `--clip-level` that is neither a positive number nor "none".
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("--clip-level {0:?}: expected a positive number or \"none\"")]
pub struct BadClipLevel(pub String);

impl ClipLevel {
    /// The level, `None` for no check.
    pub fn level(self) -> Option<f64> {
        match self {
            ClipLevel::None => None,
            ClipLevel::At(v) => Some(v),
        }
    }
}

impl Default for ClipLevel {
    /// [`DEFAULT_CLIP_LEVEL`](crate::job::DEFAULT_CLIP_LEVEL).
    fn default() -> Self {
        ClipLevel::At(0.99)
    }
}

impl std::str::FromStr for ClipLevel {
    type Err = BadClipLevel;
    fn from_str(text: &str) -> Result<Self, BadClipLevel> {
        if text.trim().eq_ignore_ascii_case("none") {
            return Ok(ClipLevel::None);
        }
        match text.trim().parse::<f64>() {
            Ok(v) if v.is_finite() && v > 0.0 => Ok(ClipLevel::At(v)),
            _ => Err(BadClipLevel(text.to_string())),
        }
    }
}

serde_as_text!(ClipLevel);

impl std::fmt::Display for ClipLevel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ClipLevel::None => f.write_str("none"),
            ClipLevel::At(v) => write!(f, "{v}"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clip_levels() {
        assert_eq!("none".parse::<ClipLevel>().unwrap(), ClipLevel::None);
        assert_eq!("0.95".parse::<ClipLevel>().unwrap(), ClipLevel::At(0.95));
        assert!("-1".parse::<ClipLevel>().is_err());
        assert!("x".parse::<ClipLevel>().is_err());
        // A job file spells it as the command line does.
        assert_eq!(
            serde_json::to_string(&ClipLevel::default()).unwrap(),
            format!("\"{}\"", crate::job::DEFAULT_CLIP_LEVEL)
        );
        assert!(serde_json::from_str::<ClipLevel>("\"0\"").is_err());
    }
}
