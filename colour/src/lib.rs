//! Colour science for lucent: spectra, colour-matching functions, colour
//! spaces and ColorChecker calibration (SPEC §4, §5).
//!
//! This crate starts with the wavelength grid type that every spectral stage
//! shares; the colour-matching data and conversions land with the colour
//! issue.

/// An inclusive, evenly spaced wavelength grid in nanometres.
///
/// ```
/// let grid = lucent_colour::WavelengthGrid::new(380.0, 780.0, 10.0).unwrap();
/// assert_eq!(grid.len(), 41);
/// assert_eq!(grid.wavelengths_nm()[4], 420.0);
/// ```
#[derive(Debug, Clone, PartialEq)]
pub struct WavelengthGrid {
    wavelengths_nm: Vec<f64>,
}

/// A wavelength grid that cannot be built.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GridError {
    #[error("wavelength grid {start_nm}:{end_nm}:{step_nm} is invalid: {reason}")]
    Invalid { start_nm: f64, end_nm: f64, step_nm: f64, reason: &'static str },
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
        Ok(Self { wavelengths_nm: (0..n).map(|i| start_nm + step_nm * i as f64).collect() })
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
        Ok(Self { wavelengths_nm })
    }

    /// The default visible grid of SPEC §1: 380–780 nm in 10 nm steps.
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
