//! Spectrum → CIE XYZ: tristimulus values of a reflectance (or transmittance)
//! spectrum under an illuminant for a standard observer,
//!
//! X = k Σᵢ S(λᵢ) R(λᵢ) x̄(λᵢ) Δλᵢ,  k = 1 / Σᵢ S(λᵢ) ȳ(λᵢ) Δλᵢ,
//!
//! so the perfect white (R ≡ 1) has Y = 1 (multiply by 100 for the CIE 15
//! convention). This is CIE 15:2004 §7.1 by summation, colour-science's
//! `sd_to_XYZ(method="Integration")` divided by 100. The illuminant and the
//! CMFs are sampled at the grid's wavelengths (linear interpolation between
//! table nodes, see [`crate::data`]); no interpolation of the spectrum is
//! done. Quadrature widths Δλᵢ: half the distance between the neighbours,
//! and the neighbour spacing at the two ends — on an even grid every Δλᵢ is
//! the step, as in CIE 15 (no end correction; ASTM E308 weighting tables are
//! not used).
//!
//! ```
//! use lucent_colour::{spectrum::reflectance_to_xyz, Illuminant, Observer, WavelengthGrid};
//! let grid = WavelengthGrid::new(380.0, 780.0, 5.0).unwrap();
//! let grey = vec![0.18; grid.len()];
//! let xyz = reflectance_to_xyz(&grid, &grey, Observer::Cie1931_2, Illuminant::D65).unwrap();
//! assert!((xyz[1] - 0.18).abs() < 1e-12);
//! ```

use crate::{check_finite, ColourError, Illuminant, Observer, WavelengthGrid};

/// Quadrature widths Δλᵢ in nm of the grid's nodes (see the module docs);
/// a single wavelength gets width 1.
pub fn quadrature_widths(grid: &WavelengthGrid) -> Result<Vec<f64>, ColourError> {
    let wl = grid.wavelengths_nm();
    if wl.windows(2).any(|w| w[1] <= w[0]) {
        return Err(ColourError::Invalid {
            what: "wavelength grid".into(),
            reason: "wavelengths must be strictly increasing".into(),
        });
    }
    let n = wl.len();
    if n == 1 {
        return Ok(vec![1.0]);
    }
    Ok((0..n)
        .map(|i| match i {
            0 => wl[1] - wl[0],
            _ if i == n - 1 => wl[n - 1] - wl[n - 2],
            _ => (wl[i + 1] - wl[i - 1]) / 2.0,
        })
        .collect())
}

/// Precomputed weights k S(λᵢ) c̄(λᵢ) Δλᵢ for one grid, observer and
/// illuminant; [`SpectralIntegrator::xyz`] is then a dot product.
#[derive(Debug, Clone)]
pub struct SpectralIntegrator {
    weights: Vec<[f64; 3]>,
    pub observer: Observer,
    pub illuminant: Illuminant,
}

impl SpectralIntegrator {
    /// An error if the grid is not increasing or does not overlap the
    /// observer's ȳ (no light to normalise by).
    pub fn new(grid: &WavelengthGrid, observer: Observer, illuminant: Illuminant) -> Result<Self, ColourError> {
        let widths = quadrature_widths(grid)?;
        let mut weights: Vec<[f64; 3]> = grid
            .wavelengths_nm()
            .iter()
            .zip(&widths)
            .map(|(&nm, &dw)| {
                let s = illuminant.spd(nm) * dw;
                let c = observer.cmf(nm);
                [s * c[0], s * c[1], s * c[2]]
            })
            .collect();
        let norm: f64 = weights.iter().map(|w| w[1]).sum();
        if !(norm.is_finite() && norm > 0.0) {
            let (lo, hi) = observer.range_nm();
            return Err(ColourError::Invalid {
                what: "wavelength grid".into(),
                reason: format!(
                    "it does not overlap the {} colour-matching functions ({lo}–{hi} nm) under illuminant {}",
                    observer.name(),
                    illuminant.name()
                ),
            });
        }
        for w in &mut weights {
            for v in w.iter_mut() {
                *v /= norm;
            }
        }
        Ok(Self { weights, observer, illuminant })
    }

    /// XYZ (white Y = 1) of a reflectance spectrum on the integrator's grid.
    pub fn xyz(&self, reflectance: &[f64]) -> Result<[f64; 3], ColourError> {
        if reflectance.len() != self.weights.len() {
            return Err(ColourError::Length {
                what: "reflectance spectrum".into(),
                expected: self.weights.len(),
                got: reflectance.len(),
            });
        }
        check_finite("reflectance spectrum", reflectance)?;
        let mut xyz = [0.0; 3];
        for (w, r) in self.weights.iter().zip(reflectance) {
            for k in 0..3 {
                xyz[k] += w[k] * r;
            }
        }
        Ok(xyz)
    }

    /// XYZ of the perfect white (R ≡ 1): the white point of this integration, Y = 1.
    pub fn white_xyz(&self) -> [f64; 3] {
        let mut xyz = [0.0; 3];
        for w in &self.weights {
            for k in 0..3 {
                xyz[k] += w[k];
            }
        }
        xyz
    }
}

/// XYZ (Y of the perfect white = 1) of `reflectance` sampled on `grid`.
pub fn reflectance_to_xyz(
    grid: &WavelengthGrid,
    reflectance: &[f64],
    observer: Observer,
    illuminant: Illuminant,
) -> Result<[f64; 3], ColourError> {
    SpectralIntegrator::new(grid, observer, illuminant)?.xyz(reflectance)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_input_is_an_error() {
        let grid = WavelengthGrid::visible();
        let obs = Observer::Cie1931_2;
        assert!(matches!(reflectance_to_xyz(&grid, &[0.5; 3], obs, Illuminant::D65), Err(ColourError::Length { .. })));
        let mut r = vec![0.5; grid.len()];
        r[7] = f64::NAN;
        let e = reflectance_to_xyz(&grid, &r, obs, Illuminant::D65).unwrap_err();
        assert!(e.to_string().contains("value 7"), "{e}");
        let ir = WavelengthGrid::new(1000.0, 1100.0, 10.0).unwrap();
        assert!(reflectance_to_xyz(&ir, &vec![0.5; ir.len()], obs, Illuminant::D65).is_err());
        let unsorted = WavelengthGrid::from_list(vec![550.0, 500.0]).unwrap();
        assert!(quadrature_widths(&unsorted).is_err());
    }

    #[test]
    fn white_has_unit_luminance_and_equal_energy_is_nearly_neutral() {
        let grid = WavelengthGrid::new(360.0, 830.0, 1.0).unwrap();
        let integ = SpectralIntegrator::new(&grid, Observer::Cie1931_2, Illuminant::E).unwrap();
        let w = integ.white_xyz();
        assert!((w[1] - 1.0).abs() < 1e-12);
        // The CIE 1931 CMF areas at 1 nm agree to 3.3e-4 (E: x = y = 1/3 to 1e-4).
        assert!((w[0] - 1.0).abs() < 4e-4 && (w[2] - 1.0).abs() < 4e-4, "{w:?}");
    }
}
