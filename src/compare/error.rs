//! What can go wrong in a comparison ([`CompareError`]) and why an input
//! file cannot be read ([`ReadProblem`]): the errors of the readers
//! ([`super::input`], [`super::mask`]), of SSIM and of the comparison itself.

use super::band;
use super::luminance::Luminance;
use crate::imageio::ImageIoError;
use crate::io::WriteError;
use crate::plot::PlotError;
use std::path::PathBuf;

/// A comparison that could not be made.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// Not one render nor two.
    #[error("--render given {count} times: one twin, or two to compare")]
    Renders { count: usize },
    /// Names for two twins with one render.
    #[error("--twin-names names two renders: give --render twice")]
    TwinNamesWithoutTwoRenders,
    /// The repeat photo is a file already given in another role.
    #[error("{} is given as {other} and as --photo-repeat: the repeat must be a second photo", path.display())]
    RepeatIsNotSecondPhoto { path: PathBuf, other: &'static str },
    /// A file that cannot be read (missing, unreadable, wrong format).
    #[error("{role} {}: cannot read: {reason}", path.display())]
    Read { role: &'static str, path: PathBuf, reason: ReadProblem },
    /// A black image, or one whose values sum to ≤ 0.
    #[error("{role} {}: black or negative on the whole (the values sum to {sum:e}); give a linear image of the lit scene", path.display())]
    NoLight { role: &'static str, path: PathBuf, sum: f64 },
    /// NaN or ±inf in an input image.
    #[error("{role} {}: {count} non-finite value(s); the first is {value} at pixel ({x}, {y}) (column, row from the top left), channel {channel}", path.display())]
    NonFinite {
        role: &'static str,
        path: PathBuf,
        x: usize,
        y: usize,
        channel: String,
        value: &'static str,
        count: usize,
    },
    /// Images, masks or scenes of different sizes (`first` and `second` say
    /// which, with the file where there is one).
    #[error(
        "{first} is {} × {} pixels, {second} {} × {}: they must be the same size",
        first_size.0, first_size.1, second_size.0, second_size.1
    )]
    Size { first: String, first_size: (usize, usize), second: String, second_size: (usize, usize) },
    /// Images smaller than the SSIM window.
    #[error("SSIM needs images of at least {window} × {window} pixels (the Gaussian window), got {width} × {height}")]
    TooSmallForSsim { window: usize, width: usize, height: usize },
    /// Different colour channels (e.g. grey vs RGB).
    #[error(
        "the photo has {} colour channel(s) ({}) but the render has {} ({})",
        photo.len(), photo.join(", "), render.len(), render.join(", ")
    )]
    Channels { photo: Vec<String>, render: Vec<String> },
    /// An option that must be a positive finite number.
    #[error("{what} {value}: must be a positive finite number")]
    NotPositive { what: &'static str, value: f64 },
    /// A mask that leaves no pixel (`kind`: image, object or board; `path`: its file).
    #[error("the {}mask{} includes no pixel", kind.map(|k| format!("{k} ")).unwrap_or_default(),
        path.as_ref().map(|p| format!(" from {}", p.display())).unwrap_or_default())]
    EmptyMask { kind: Option<&'static str>, path: Option<PathBuf> },
    /// A mask whose pixels all lie within 5 px of the border.
    #[error("no pixel for SSIM: the mask leaves none at least 5 px from the image border")]
    NoSsimPixels,
    /// A point of the scene the camera cannot see.
    #[error("the scene's {what} at {point:?} m is behind the camera")]
    BehindCamera { what: &'static str, point: [f64; 3] },
    /// An object mask from a scene without a sample.
    #[error("the scene has no sample (run `lucent pose` with --sample-corner and --sample-size-mm)")]
    NoSample,
    /// A luminance name [`Luminance::from_name`] does not know.
    #[error("luminance {name:?}: expected one of {}", <Luminance as strum::VariantNames>::VARIANTS.join(", "))]
    UnknownLuminance { name: String },
    #[error("ECC refinement failed: {0}")]
    Ecc(#[from] lucent_calib::cv::CalibError),
    #[error(transparent)]
    Plot(#[from] PlotError),
    #[error(transparent)]
    Image(#[from] ImageIoError),
    /// An EXR that cannot be written (the message names the file).
    #[error(transparent)]
    ExrWrite(#[from] crate::exr::ExrWriteError),
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error("{}: {source}", path.display())]
    Io { path: PathBuf, source: std::io::Error },
    #[error("--band: {0}")]
    Band(#[from] band::BandError),
    /// A band without an object or board mask, or more bands than renders.
    #[error("--band: {0}")]
    BandUse(String),
}

/// Why an input file of a comparison cannot be read ([`CompareError::Read`]).
#[derive(Debug, thiserror::Error)]
pub enum ReadProblem {
    #[error("no such file")]
    Missing,
    #[error("is a folder, not an image")]
    Folder,
    #[error("unsupported format {0:?} (expected .exr, .hdr, .png, .tif or .tiff)")]
    Format(String),
    #[error("{0}")]
    Io(#[from] std::io::Error),
    #[error("{0}")]
    Exr(Box<crate::exr::ExrProblem>),
    #[error("{0}")]
    Decode(#[from] image::ImageError),
    /// Readable, but not what the comparison needs (a missing layer, a value out of range).
    #[error("{0}")]
    Invalid(String),
    #[error("{0}")]
    Buffer(#[from] ImageIoError),
    #[error("no R, G, B (or single Y) channels; the file has {}", .0.join(", "))]
    NoColourChannels(Vec<String>),
    #[error("channel {name} has {got} samples for {width} × {height} pixels (subsampled?)")]
    Subsampled { name: &'static str, got: usize, width: usize, height: usize },
    #[error("not a scene JSON from `lucent pose`: {0}")]
    NotScene(#[from] serde_json::Error),
}
