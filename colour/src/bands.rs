//! Spectral values → three band values R, G, B (docs/method.md#render): every spectral
//! optical property (μs(λ), μa(λ), g(λ), n(λ), a reflectance …) becomes the
//! weighted average v_b = Σᵢ w_b(λᵢ) v(λᵢ) with non-negative weights that sum
//! to 1 in each band, so a constant spectrum keeps its value and the bands
//! have the units of the input.
//!
//! Weight set "CIE 1931 RGB, negative lobes clipped" (the only one, named
//! [`BAND_WEIGHT_SET`]): w_b(λᵢ) ∝ max(0, c̄_b(λᵢ)) Δλᵢ with c̄ = r̄, ḡ, b̄ the
//! CIE 1931 RGB colour-matching functions (Wright & Guild; primaries 700,
//! 546.1, 435.8 nm, white E — the space the photos and the environment are
//! converted to, see [`crate::spaces::RgbSpace::CieRgb`]), linearly
//! interpolated at the grid's wavelengths (0 outside their 380–780 nm table),
//! times the quadrature widths Δλᵢ of [`crate::spectrum::quadrature_widths`],
//! normalised per band. The illuminant is E (the space's white), so no
//! illuminant weighting enters.
//!
//! Negative lobes: r̄ is negative from 440 to 545 nm (down to −0.27 of its
//! peak; the negative area is 22 % of the positive one), ḡ from 380 to
//! 435 nm (−0.7 % of its peak) and b̄ from 550 to 655 nm (−0.4 %). These parts
//! are set to 0 (clipped), not folded into another band. 90 % of each band's
//! weight then lies in R 565–655 nm, G 485–600 nm, B 420–495 nm.
//!
//! A grid of a single wavelength is a monochromatic computation: all three
//! bands equal the value there.
//!
//! The asymmetry g is averaged like any other value here; a scattering-
//! weighted g_b = Σ w μs g / Σ w μs is the alternative some renderers use.
//!
//! ```
//! use lucent_colour::{bands::band_averages, WavelengthGrid};
//! let grid = WavelengthGrid::visible();
//! // A constant spectrum keeps its value in every band.
//! let b = band_averages(&grid, &vec![120.0; grid.len()]).unwrap();
//! assert!(b.iter().all(|v| (v - 120.0).abs() < 1e-9));
//! // μs ∝ λ⁻⁴ scatters blue most.
//! let mu_s: Vec<f64> = grid.wavelengths_nm().iter().map(|l| (550.0 / l).powi(4)).collect();
//! let b = band_averages(&grid, &mu_s).unwrap();
//! assert!(b[2] > b[1] && b[1] > b[0]);
//! ```

use crate::{check_finite, ColourError, WavelengthGrid};
use serde::Serialize;

/// Name of the weight set used by [`band_weights`].
pub const BAND_WEIGHT_SET: &str = "CIE 1931 RGB colour-matching functions (Wright & Guild), negative lobes clipped to 0, each band normalised to sum 1";

/// Band names in order.
pub const BANDS: [&str; 3] = ["R", "G", "B"];

/// The weights of the three bands on one grid: `weights[b][i]` ≥ 0 for band
/// b (R, G, B) at wavelength i, each band summing to 1.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BandWeights {
    /// [`BAND_WEIGHT_SET`].
    pub set: &'static str,
    pub wavelength_nm: Vec<f64>,
    pub weights: [Vec<f64>; 3],
    /// Fraction of each band's colour-matching mass (360–830 nm) that lies
    /// inside the grid's span (its first and last wavelengths widened by
    /// their quadrature half-cells); 1 for a single-wavelength grid, which
    /// stands for itself. Below [`MIN_BAND_COVERAGE`] the grid is refused;
    /// callers should warn below 0.99.
    pub coverage: [f64; 3],
}

/// The smallest fraction of a band's colour-matching mass a grid must span
/// (see [`BandWeights::coverage`]): a grid that misses more would silently
/// renormalise the band to what little it covers.
pub const MIN_BAND_COVERAGE: f64 = 0.9;

/// Fraction of each band's positive CMF mass between `lo` and `hi` nm
/// (1 nm midpoint sums over 360–830 nm).
fn band_coverage(lo: f64, hi: f64) -> [f64; 3] {
    let (mut inside, mut total) = ([0.0f64; 3], [0.0f64; 3]);
    for i in 0..470 {
        let nm = 360.5 + i as f64;
        let c = crate::data::cie1931_rgb_cmf(nm);
        for b in 0..3 {
            let v = c[b].max(0.0);
            total[b] += v;
            if (lo..=hi).contains(&nm) {
                inside[b] += v;
            }
        }
    }
    std::array::from_fn(|b| if total[b] > 0.0 { inside[b] / total[b] } else { 0.0 })
}

/// The band weights on `grid`; an error if a band has no positive weight
/// there (e.g. a grid entirely below 440 nm has no R weight).
pub fn band_weights(grid: &WavelengthGrid) -> Result<BandWeights, ColourError> {
    let widths = crate::spectrum::quadrature_widths(grid)?;
    let wl = grid.wavelengths_nm();
    if wl.len() == 1 {
        return Ok(BandWeights {
            set: BAND_WEIGHT_SET,
            wavelength_nm: wl.to_vec(),
            weights: [vec![1.0], vec![1.0], vec![1.0]],
            coverage: [1.0; 3],
        });
    }
    let (lo, hi) = (wl[0] - 0.5 * widths[0], wl[wl.len() - 1] + 0.5 * widths[widths.len() - 1]);
    let coverage = band_coverage(lo, hi);
    for (b, &f) in coverage.iter().enumerate() {
        if f < MIN_BAND_COVERAGE {
            return Err(ColourError::Invalid {
                what: format!("wavelength grid {lo}…{hi} nm"),
                reason: format!(
                    "it spans only {:.1} % of band {}'s colour-matching mass ({BAND_WEIGHT_SET}); at least {:.0} % is needed (e.g. 380:780:10)",
                    100.0 * f,
                    BANDS[b],
                    100.0 * MIN_BAND_COVERAGE
                ),
            });
        }
    }
    let mut weights: [Vec<f64>; 3] = Default::default();
    for (&nm, &dw) in wl.iter().zip(&widths) {
        let c = crate::data::cie1931_rgb_cmf(nm);
        for b in 0..3 {
            weights[b].push(c[b].max(0.0) * dw);
        }
    }
    for (b, w) in weights.iter_mut().enumerate() {
        let sum: f64 = w.iter().sum();
        if sum.is_nan() || sum <= 0.0 {
            return Err(ColourError::Invalid {
                what: format!("wavelength grid {:?}…{:?} nm", wl.first(), wl.last()),
                reason: format!(
                    "band {} has no positive colour-matching weight on it ({BAND_WEIGHT_SET}); the grid must reach into that band",
                    BANDS[b]
                ),
            });
        }
        w.iter_mut().for_each(|v| *v /= sum);
    }
    Ok(BandWeights { set: BAND_WEIGHT_SET, wavelength_nm: wl.to_vec(), weights, coverage })
}

impl BandWeights {
    /// The three band averages of `values` (one per grid wavelength); an
    /// error for a wrong length or a non-finite value (named by wavelength).
    pub fn average(&self, values: &[f64]) -> Result<[f64; 3], ColourError> {
        let n = self.wavelength_nm.len();
        if values.len() != n {
            return Err(ColourError::Length { what: "spectral values".into(), expected: n, got: values.len() });
        }
        if let Err(e) = check_finite("spectral values", values) {
            let i = values.iter().position(|v| !v.is_finite()).unwrap_or(0);
            return Err(ColourError::NonFinite {
                what: "spectral values".into(),
                index_desc: format!("the value at {} nm", self.wavelength_nm[i]),
                value: match e {
                    ColourError::NonFinite { value, .. } => value,
                    _ => f64::NAN,
                },
            });
        }
        let mut out = [0.0; 3];
        for (b, w) in self.weights.iter().enumerate() {
            out[b] = w.iter().zip(values).map(|(w, v)| w * v).sum();
        }
        Ok(out)
    }
}

/// Band values R, G, B of `values` sampled on `grid` (see the module docs);
/// the function the renderer calls for every coefficient.
pub fn band_averages(grid: &WavelengthGrid, values: &[f64]) -> Result<[f64; 3], ColourError> {
    band_weights(grid)?.average(values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_grid_missing_a_band_is_refused_and_partial_coverage_reported() {
        let grid = |a, b, s| WavelengthGrid::new(a, b, s).unwrap();
        // 500–600 nm leaves half of R (and most of B) out: refused, naming the band.
        let e = band_weights(&grid(500.0, 600.0, 10.0)).unwrap_err().to_string();
        assert!(e.contains("band R") && e.contains("48.4 %"), "{e}");
        // The full grid covers everything; 400–700 nm most but not all.
        let full = band_weights(&grid(380.0, 780.0, 10.0)).unwrap();
        assert!(full.coverage.iter().all(|f| *f > 0.999), "{:?}", full.coverage);
        let part = band_weights(&grid(400.0, 700.0, 10.0)).unwrap();
        assert!(part.coverage.iter().all(|f| (0.9..=1.0).contains(f)), "{:?}", part.coverage);
        assert!(part.coverage[0] < 0.999 && part.coverage[2] < 0.999, "{:?}", part.coverage);
    }

    #[test]
    fn weights_are_non_negative_and_normalised() {
        let w = band_weights(&WavelengthGrid::new(360.0, 830.0, 1.0).unwrap()).unwrap();
        for band in &w.weights {
            assert!(band.iter().all(|v| *v >= 0.0));
            assert!((band.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        }
        // Outside 380–780 nm there is no weight.
        assert_eq!(w.weights[0][0], 0.0);
        assert_eq!(*w.weights[2].last().unwrap(), 0.0);
    }

    #[test]
    fn a_band_without_weight_and_bad_values_are_errors() {
        let blue_only = WavelengthGrid::new(450.0, 470.0, 10.0).unwrap();
        let e = band_averages(&blue_only, &[1.0; 3]).unwrap_err().to_string();
        assert!(e.contains("band R"), "{e}");
        let grid = WavelengthGrid::visible();
        let mut v = vec![1.0; grid.len()];
        v[17] = f64::INFINITY;
        let e = band_averages(&grid, &v).unwrap_err().to_string();
        assert!(e.contains("550 nm"), "{e}");
        assert!(matches!(band_averages(&grid, &[1.0; 3]), Err(ColourError::Length { .. })));
    }

    #[test]
    fn single_wavelength_grid_returns_the_value() {
        let g = WavelengthGrid::from_list(vec![600.0]).unwrap();
        assert_eq!(band_averages(&g, &[42.0]).unwrap(), [42.0; 3]);
    }
}
