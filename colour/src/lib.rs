//! Colour science for lucent: spectra, colour-matching functions, colour
//! spaces, chromatic adaptation, colour differences, spectral → RGB band
//! averages and ColorChecker calibration of cameras (docs/method.md#render, #camera). Pure Rust,
//! `f64`, no OpenCV.
//!
//! | module | computes |
//! |---|---|
//! | [`data`] | embedded tables: CIE 1931 and CIE 2012 2° XYZ CMFs, CIE 1931 RGB CMFs, illuminants D50/D65/A/E, ColorChecker Classic references |
//! | [`spectrum`] | reflectance spectrum → XYZ (Y of the perfect white = 1) |
//! | [`spaces`] | XYZ ↔ xyY ↔ CIELAB, linear CIE RGB and sRGB ↔ XYZ, the sRGB transfer function |
//! | [`chromaticity`] | XYZ ↔ xyY, XYZ of a chromaticity (leaf module) |
//! | [`matrix`] | 3 × 3 matrix product, matrix–vector product and inverse over nalgebra (leaf module) |
//! | [`names`] | the canonical form of names typed by users (leaf module) |
//! | [`adaptation`] | Bradford, von Kries and CAT02 chromatic adaptation |
//! | [`difference`] | ΔE*ab (CIE 1976) and ΔE00 (CIEDE2000, Sharma et al. 2005) |
//! | [`bands`] | spectral values (μs, μa, g, …) → three band values R, G, B |
//! | [`ccm`] | colour-correction matrices camera RGB → XYZ (D50): Cheung 2004, Finlayson 2015, Finlayson 1997 |
//! | [`chart`] | ColorChecker patch sampling from an image given the chart's four corners |
//!
//! Conventions: wavelengths in nm; XYZ relative with Y = 1 for the perfect
//! white (multiply by 100 for the CIE 15 convention); every table and formula
//! names its source where it is defined, and the values are tested against
//! colour-science (`tools/reference/colour_reference.py`).
//!
//! ```
//! use lucent_colour::{data::Illuminant, spaces, difference};
//! // The ICC D50 white is L* = 100, a* = b* = 0.
//! let lab = spaces::xyz_to_lab([0.9642, 1.0, 0.8249], lucent_colour::data::ICC_D50_XYZ);
//! assert!((lab[0] - 100.0).abs() < 1e-12 && lab[1].abs() < 1e-12);
//! // Sharma et al. (2005), pair 1: ΔE00 = 2.0425.
//! let de = difference::delta_e_2000([50.0, 2.6772, -79.7751], [50.0, 0.0, -82.7485]);
//! assert!((de - 2.0425).abs() < 5e-5);
//! # let _ = Illuminant::D65;
//! ```

pub mod adaptation;
pub mod bands;
pub mod ccm;
pub mod chart;
pub mod chromaticity;
pub mod data;
pub mod difference;
pub mod matrix;
pub mod names;
pub mod spaces;
pub mod spectrum;

pub use bands::{band_averages, band_weights, BandWeights};
pub use ccm::{CcmMethod, ColourCorrection, FitReport};
pub use chart::{sample_patches, ImageRef, PatchSample, SampleOptions};
pub use data::{Illuminant, Observer};

/// A 3 × 3 matrix, row-major: `y = M x` is `y[i] = Σ_j M[i][j] x[j]`.
pub type Mat3 = [[f64; 3]; 3];

/// Everything that can go wrong in this crate; each message names the input
/// at fault.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum ColourError {
    #[error(transparent)]
    Grid(#[from] GridError),
    #[error("{what}: {index_desc} is not a finite number ({value})")]
    NonFinite { what: String, index_desc: String, value: f64 },
    #[error("{what}: expected {expected} values, got {got}")]
    Length { what: String, expected: usize, got: usize },
    #[error("{what}: {reason}")]
    Invalid { what: String, reason: String },
    #[error("unknown {kind} {name:?}; valid names: {valid}")]
    UnknownName { kind: &'static str, name: String, valid: String },
    #[error("{what} is singular or rank-deficient ({reason})")]
    Singular { what: String, reason: String },
    #[error("corner {corner} ({x}, {y}) is outside the {width} × {height} image; corners are pixel coordinates, x to the right and y down, origin at the top-left edge of the image")]
    CornerOutside { corner: usize, x: f64, y: f64, width: usize, height: usize },
    #[error("{}", clipped_message(.patches, *.level))]
    ClippedPatches { patches: Vec<ClippedPatch>, level: f64 },
}

/// A chart patch refused because too many of its pixels are clipped.
#[derive(Debug, Clone, PartialEq)]
pub struct ClippedPatch {
    /// 1-based patch number in chart order.
    pub patch: usize,
    pub name: &'static str,
    /// Fraction of the sampled pixels with a channel at or above the clip level.
    pub fraction: f64,
}

fn clipped_message(patches: &[ClippedPatch], level: f64) -> String {
    let list: Vec<String> =
        patches.iter().map(|p| format!("{} ({}) {:.0} %", p.patch, p.name, 100.0 * p.fraction)).collect();
    format!(
        "clipped patch{} (pixels with a channel ≥ {level}): {}; the photo is overexposed there: expose for the white patch, or give the true clip level if the image is not normalised to 1",
        if patches.len() == 1 { "" } else { "es" },
        list.join(", ")
    )
}

/// Checks that every value is finite; the error names `what` and the index.
pub(crate) fn check_finite(what: &str, values: &[f64]) -> Result<(), ColourError> {
    match values.iter().position(|v| !v.is_finite()) {
        None => Ok(()),
        Some(i) => {
            Err(ColourError::NonFinite { what: what.to_string(), index_desc: format!("value {i}"), value: values[i] })
        }
    }
}

/// An inclusive, evenly spaced wavelength grid in nanometres (or a list of
/// wavelengths, [`WavelengthGrid::from_list`]).
///
/// As text (its [`FromStr`](std::str::FromStr), [`Display`](std::fmt::Display)
/// and serde form) a grid is "START:END:STEP" in nm, or one wavelength "W";
/// it is written as it was given, each number in its shortest form
/// ("400.0:700:10" is written "400:700:10").
///
/// ```
/// let grid = lucent_colour::WavelengthGrid::new(380.0, 780.0, 10.0).unwrap();
/// assert_eq!(grid.len(), 41);
/// assert_eq!(grid.wavelengths_nm()[4], 420.0);
/// assert_eq!(grid.to_string(), "380:780:10");
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct WavelengthGrid {
    wavelengths_nm: Vec<f64>,
    spelling: GridSpelling,
}

/// How a grid was given, for its text form.
#[derive(Debug, Clone, Copy, PartialEq)]
enum GridSpelling {
    /// START:END:STEP in nm.
    Range { start_nm: f64, end_nm: f64, step_nm: f64 },
    /// One wavelength "W" in nm.
    One,
    /// An explicit list ([`WavelengthGrid::from_list`]): written as its
    /// wavelengths separated by commas, which no parser reads back.
    List,
}

/// A wavelength grid that cannot be built.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum GridError {
    #[error("wavelength grid {start_nm}:{end_nm}:{step_nm} is invalid: {reason}")]
    Invalid { start_nm: f64, end_nm: f64, step_nm: f64, reason: &'static str },
}

/// A wavelength grid written as text that cannot be read or built.
#[derive(Debug, thiserror::Error, Clone, PartialEq)]
pub enum GridTextError {
    #[error("{text:?}: expected START:END:STEP in nm, e.g. 380:780:10, or one wavelength, e.g. 550")]
    Syntax { text: String },
    #[error("{text:?}: {part:?} is not a number")]
    NotANumber { text: String, part: String },
    #[error("{text:?}: {source}")]
    Grid { text: String, source: GridError },
}

impl std::str::FromStr for WavelengthGrid {
    type Err = GridTextError;

    /// "START:END:STEP" in nm (spaces around the numbers ignored), built by
    /// [`WavelengthGrid::new`], or one wavelength "W" (the grid W:W:1).
    ///
    /// ```
    /// let grid: lucent_colour::WavelengthGrid = "400:700:10".parse().unwrap();
    /// assert_eq!(grid.len(), 31);
    /// let one: lucent_colour::WavelengthGrid = "550".parse().unwrap();
    /// assert_eq!(one.wavelengths_nm(), &[550.0]);
    /// ```
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let parts: Vec<&str> = text.split(':').collect();
        let num = |s: &str| {
            s.trim()
                .parse::<f64>()
                .map_err(|_| GridTextError::NotANumber { text: text.to_string(), part: s.to_string() })
        };
        let grid = |source| GridTextError::Grid { text: text.to_string(), source };
        match parts.as_slice() {
            [a, b, c] => WavelengthGrid::new(num(a)?, num(b)?, num(c)?).map_err(grid),
            [w] if !w.trim().is_empty() => {
                let w = num(w)?;
                Ok(WavelengthGrid { spelling: GridSpelling::One, ..WavelengthGrid::new(w, w, 1.0).map_err(grid)? })
            }
            _ => Err(GridTextError::Syntax { text: text.to_string() }),
        }
    }
}

impl std::fmt::Display for WavelengthGrid {
    /// The text [`FromStr`](std::str::FromStr) reads: "START:END:STEP" or "W" in nm.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.spelling {
            GridSpelling::Range { start_nm, end_nm, step_nm } => write!(f, "{start_nm}:{end_nm}:{step_nm}"),
            GridSpelling::One | GridSpelling::List => {
                let words: Vec<String> = self.wavelengths_nm.iter().map(f64::to_string).collect();
                f.write_str(&words.join(","))
            }
        }
    }
}

impl serde::Serialize for WavelengthGrid {
    /// The grid's text ([`Display`](std::fmt::Display)).
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> serde::Deserialize<'de> for WavelengthGrid {
    /// The grid's text, read by its [`FromStr`](std::str::FromStr); a wrong
    /// text is refused with the text and the reason.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

impl WavelengthGrid {
    /// Grid from `start_nm` to `end_nm` inclusive in steps of `step_nm`.
    pub fn new(start_nm: f64, end_nm: f64, step_nm: f64) -> Result<Self, GridError> {
        let bad = |reason| Err(GridError::Invalid { start_nm, end_nm, step_nm, reason });
        if !(start_nm.is_finite() && end_nm.is_finite() && step_nm.is_finite()) {
            return bad("values must be finite");
        }
        if start_nm <= 0.0 {
            return bad("wavelengths must be positive");
        }
        if end_nm < start_nm {
            return bad("end is below start");
        }
        if step_nm <= 0.0 {
            return bad("step must be positive");
        }
        let n = ((end_nm - start_nm) / step_nm + 1e-9).floor() as usize + 1;
        if n > 100_000 {
            return bad("more than 100000 wavelengths");
        }
        Ok(Self {
            wavelengths_nm: (0..n).map(|i| start_nm + step_nm * i as f64).collect(),
            spelling: GridSpelling::Range { start_nm, end_nm, step_nm },
        })
    }

    /// A grid of explicitly listed wavelengths (each positive and finite).
    pub fn from_list(wavelengths_nm: Vec<f64>) -> Result<Self, GridError> {
        if wavelengths_nm.is_empty() || wavelengths_nm.iter().any(|w| !(w.is_finite() && *w > 0.0)) {
            return Err(GridError::Invalid {
                start_nm: wavelengths_nm.first().copied().unwrap_or(f64::NAN),
                end_nm: wavelengths_nm.last().copied().unwrap_or(f64::NAN),
                step_nm: f64::NAN,
                reason: "wavelengths must be a non-empty list of positive numbers",
            });
        }
        Ok(Self { wavelengths_nm, spelling: GridSpelling::List })
    }

    /// The default visible grid: 380–780 nm in 10 nm steps.
    pub fn visible() -> Self {
        Self::new(380.0, 780.0, 10.0).expect("the default grid is valid")
    }

    pub fn wavelengths_nm(&self) -> &[f64] {
        &self.wavelengths_nm
    }

    pub fn len(&self) -> usize {
        self.wavelengths_nm.len()
    }

    pub fn is_empty(&self) -> bool {
        self.wavelengths_nm.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_wavelength_is_a_grid() {
        let g: WavelengthGrid = "550".parse().unwrap();
        assert_eq!(g.wavelengths_nm(), &[550.0]);
        let g: WavelengthGrid = " 632.8 ".parse().unwrap();
        assert_eq!(g.wavelengths_nm(), &[632.8]);
        assert!(matches!("-5".parse::<WavelengthGrid>(), Err(GridTextError::Grid { .. })));
        assert!(matches!("".parse::<WavelengthGrid>(), Err(GridTextError::Syntax { .. })));
        assert!(matches!("400:700".parse::<WavelengthGrid>(), Err(GridTextError::Syntax { .. })));
        assert!(matches!("nm".parse::<WavelengthGrid>(), Err(GridTextError::NotANumber { .. })));
        let e = "400:700".parse::<WavelengthGrid>().unwrap_err().to_string();
        assert!(e.starts_with("\"400:700\": expected START:END:STEP"), "{e}");
    }

    #[test]
    fn a_grid_is_written_as_it_was_given() {
        for (text, written) in [("400:700:10", "400:700:10"), (" 380.0 : 780 : 2.5", "380:780:2.5"), ("550", "550")] {
            let g: WavelengthGrid = text.parse().unwrap();
            assert_eq!(g.to_string(), written, "{text}");
            assert_eq!(written.parse::<WavelengthGrid>().unwrap(), g, "{text}");
            assert_eq!(serde_json::to_string(&g).unwrap(), format!("\"{written}\""));
            assert_eq!(serde_json::from_str::<WavelengthGrid>(&format!("\"{written}\"")).unwrap(), g);
        }
        let e = serde_json::from_str::<WavelengthGrid>("\"780:380:10\"").unwrap_err().to_string();
        assert!(e.contains("\"780:380:10\"") && e.contains("end is below start"), "{e}");
    }

    #[test]
    fn rejects_bad_grids() {
        assert!(WavelengthGrid::new(380.0, 780.0, 0.0).is_err());
        assert!(WavelengthGrid::new(780.0, 380.0, 10.0).is_err());
        assert!(WavelengthGrid::new(f64::NAN, 780.0, 10.0).is_err());
        assert!(WavelengthGrid::from_list(vec![]).is_err());
        assert!(WavelengthGrid::from_list(vec![550.0, -1.0]).is_err());
    }

    #[test]
    fn single_wavelength() {
        let g = WavelengthGrid::new(550.0, 550.0, 10.0).unwrap();
        assert_eq!(g.wavelengths_nm(), &[550.0]);
    }
}
