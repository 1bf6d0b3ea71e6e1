//! The internal representation of an index file's spectrum: tables of n or
//! κ against wavelength (µm, linear interpolation), the refractiveindex.info
//! dispersion formulas 1–9 (n(λ) from their coefficients, λ in µm), the real
//! part with its correction, and the range helpers. See the parent module
//! for the formulas' definitions and the file format.

/// How far beyond its valid range a part of the data may be extrapolated,
/// as a fraction of the nearer range end's wavelength (the parent module's
/// doc).
pub const MAX_EXTRAPOLATION: f64 = 0.25;

/// Relative tolerance on range ends (absorbs nm ↔ µm rounding).
pub(super) const RANGE_TOLERANCE: f64 = 1e-9;

/// A tabulated quantity: strictly increasing wavelengths (µm), ≥ 2 rows.
#[derive(Debug, Clone)]
pub(super) struct Table {
    pub(super) wavelength_um: Vec<f64>,
    pub(super) value: Vec<f64>,
}

impl Table {
    pub(super) fn range_um(&self) -> (f64, f64) {
        // Non-empty by construction (≥ 2 rows).
        (self.wavelength_um[0], self.wavelength_um[self.wavelength_um.len() - 1])
    }

    /// Linear interpolation; outside the nodes the end segment is extended.
    /// Exact at the nodes.
    pub(super) fn interpolate(&self, x: f64) -> f64 {
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
    pub(super) fn clamped(&self, x: f64) -> f64 {
        let (lo, hi) = self.range_um();
        self.interpolate(x.clamp(lo, hi))
    }
}

/// One of the nine database dispersion formulas.
#[derive(Debug, Clone)]
pub(super) struct Formula {
    /// 1 … 9.
    pub(super) kind: u8,
    /// C0 … C16, missing ones zero.
    pub(super) c: [f64; 17],
    pub(super) range_um: (f64, f64),
}

/// Largest number of coefficients each formula type takes (database document).
pub(super) const MAX_COEFFICIENTS: [usize; 9] = [17, 17, 17, 17, 11, 11, 6, 4, 6];

impl Formula {
    /// n at λ = `l` µm; NaN where the formula gives no real index.
    pub(super) fn eval(&self, l: f64) -> f64 {
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

pub(super) fn sqrt_or_nan(n2: f64) -> f64 {
    if n2 >= 0.0 {
        n2.sqrt()
    } else {
        f64::NAN
    }
}

#[derive(Debug, Clone)]
pub(super) enum RealSource {
    Table(Table),
    Formula(Formula),
}

#[derive(Debug, Clone, Copy)]
pub(super) enum Correction {
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
pub(super) struct RealPart {
    pub(super) source: RealSource,
    pub(super) correction: Correction,
}

impl RealPart {
    pub(super) fn range_um(&self) -> (f64, f64) {
        match &self.source {
            RealSource::Table(t) => t.range_um(),
            RealSource::Formula(f) => f.range_um,
        }
    }

    /// Uncorrected n at `x` µm (tables: interpolated, end segments extended).
    pub(super) fn raw_at(&self, x: f64) -> f64 {
        match &self.source {
            RealSource::Table(t) => t.interpolate(x),
            RealSource::Formula(f) => f.eval(x),
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Position {
    Below,
    Inside,
    Above,
}

pub(super) fn position(x: f64, (lo, hi): (f64, f64)) -> Position {
    if x < lo * (1.0 - RANGE_TOLERANCE) {
        Position::Below
    } else if x > hi * (1.0 + RANGE_TOLERANCE) {
        Position::Above
    } else {
        Position::Inside
    }
}

/// `x` µm lies further outside `(lo, hi)` µm than [`MAX_EXTRAPOLATION`] reaches.
pub(super) fn beyond_reach(x: f64, (lo, hi): (f64, f64)) -> bool {
    x < lo * (1.0 - MAX_EXTRAPOLATION) || x > hi * (1.0 + MAX_EXTRAPOLATION)
}

/// µm → nm, rounded to 1e-6 nm so that ranges print cleanly (0.4368 µm →
/// 436.8 nm, not 436.79999999999995).
pub(super) fn um_to_nm(um: f64) -> f64 {
    (um * 1e9).round() / 1e6
}

pub(super) fn fmt_nm(nm: f64) -> String {
    if nm.is_finite() {
        format!("{}", (nm * 1e6).round() / 1e6)
    } else {
        format!("{nm}")
    }
}
