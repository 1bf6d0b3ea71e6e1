//! What can go wrong reading or evaluating refractive-index data
//! ([`IndexError`]); every message names the file.

use super::dispersion::{fmt_nm, MAX_EXTRAPOLATION};

/// Errors from reading or evaluating refractive-index data. Every message
/// names the file (the spectrum's [`IndexSpectrum::source`](super::IndexSpectrum::source)).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum IndexError {
    /// The file could not be read.
    #[error("cannot read refractive-index file {file}: {message}")]
    Read { file: String, message: String },
    /// Not YAML, or not a mapping with a `DATA` list of entries.
    #[error("{file}: not a valid refractiveindex.info YAML file: {message}")]
    Yaml { file: String, message: String },
    /// A `DATA` entry of a type other than `tabulated nk|n|k`, `formula 1…9`.
    #[error(
        "{file}: {location}: unknown DATA type '{kind}' (expected tabulated nk, tabulated n, tabulated k or formula 1 … formula 9)"
    )]
    UnknownType { file: String, location: String, kind: String },
    /// A token that is not a number.
    #[error("{file}: {location}: malformed number '{token}'")]
    BadNumber { file: String, location: String, token: String },
    /// A number that is NaN, infinite or negative where that is not allowed.
    #[error("{file}: {location}: {quantity} = {value} is not allowed (must be {requirement})")]
    InvalidValue { file: String, location: String, quantity: String, value: f64, requirement: String },
    /// A table with fewer than two rows.
    #[error("{file}: {location}: a table needs at least 2 rows, found {rows}")]
    TooFewRows { file: String, location: String, rows: usize },
    /// Table wavelengths that do not increase strictly.
    #[error("{file}: {location}: wavelengths must increase strictly, but {wavelength_um} µm follows {previous_um} µm")]
    NonIncreasing { file: String, location: String, previous_um: f64, wavelength_um: f64 },
    /// Any other structural problem (missing keys, wrong column count, …).
    #[error("{file}: {message}")]
    Format { file: String, message: String },
    /// No entry provides the real part n.
    #[error("{file}: no DATA entry provides the real part n (need a formula, tabulated n or tabulated nk)")]
    NoRealPart { file: String },
    /// The wavelength is outside the valid range of the n or κ data and no
    /// extrapolation was asked for.
    #[error(
        "{file}: wavelength {} nm is outside the valid range {}–{} nm of the {part} data (to go beyond it, set extrapolate = \"clamp\" or \"linear\" for this medium in the recipe: under [host] or its [[particles]] entry)",
        fmt_nm(*wavelength_nm), fmt_nm(*min_nm), fmt_nm(*max_nm)
    )]
    OutOfRange { file: String, part: String, wavelength_nm: f64, min_nm: f64, max_nm: f64 },
    /// The wavelength is further outside the valid range than any
    /// extrapolation reaches ([`MAX_EXTRAPOLATION`]).
    #[error(
        "{file}: wavelength {} nm is too far outside the valid range {}–{} nm of the {part} data: extrapolation reaches {}–{} nm (25 % of the range ends)",
        fmt_nm(*wavelength_nm), fmt_nm(*min_nm), fmt_nm(*max_nm),
        fmt_nm(*min_nm * (1.0 - MAX_EXTRAPOLATION)), fmt_nm(*max_nm * (1.0 + MAX_EXTRAPOLATION))
    )]
    TooFarOutside { file: String, part: String, wavelength_nm: f64, min_nm: f64, max_nm: f64 },
    /// The requested wavelength is NaN, infinite or not positive.
    #[error("{file}: requested wavelength {wavelength_nm} nm is not a finite positive number")]
    InvalidWavelength { file: String, wavelength_nm: f64 },
    /// The data give no physical index at this wavelength (formula with
    /// n² < 0, a pole, n ≤ 0 after extrapolation, …).
    #[error("{file}: the data give no physical refractive index at {} nm ({detail})", fmt_nm(*wavelength_nm))]
    NonPhysical { file: String, wavelength_nm: f64, detail: String },
    /// [`IndexSpectrum::with_real_part_at`](super::IndexSpectrum::with_real_part_at) with a value of n that is not
    /// finite and positive.
    #[error("{file}: cannot set the real part to n = {n} at {wavelength_nm} nm (n must be finite and positive)")]
    InvalidCorrection { file: String, wavelength_nm: f64, n: f64 },
    /// [`IndexSpectrum::with_imaginary_part`](super::IndexSpectrum::with_imaginary_part) with a value that is not
    /// finite and ≥ 0.
    #[error("{file}: cannot override the imaginary part with {what} = {value} (must be finite and ≥ 0)")]
    InvalidImaginaryCorrection { file: String, what: String, value: f64 },
    /// [`IndexSpectrum::builtin`](super::IndexSpectrum::builtin) with a name that is not built in.
    #[error("unknown built-in refractive-index data '{name}'; valid names: {valid}")]
    UnknownBuiltin { name: String, valid: String },
}
