//! Embedded colour data: colour-matching functions, illuminants and the
//! ColorChecker Classic references, read from the CSV files in
//! `colour/data/` (compiled in with `include_str!`; their headers and
//! `colour/data/README.md` give source, units and licence of each table).
//!
//! | table | range | unit |
//! |---|---|---|
//! | CIE 1931 2° x̄ ȳ z̄ (CIE 15) | 360–830 nm, 1 nm | dimensionless, ȳ(555) = 1 |
//! | CIE 2012 2° x̄ ȳ z̄ (CIE 170-2, Stockman & Sharpe cone fundamentals) | 390–830 nm, 1 nm | dimensionless |
//! | CIE 1931 r̄ ḡ b̄ (Wright & Guild; primaries 700, 546.1, 435.8 nm) | 380–780 nm, 5 nm | equal areas |
//! | illuminants D50, D65, A (CIE 15:2004); E = 100 | 300–780 nm, 5 nm | relative, 100 at 560 nm |
//! | ColorChecker Classic, post-November-2014 X-Rite xyY and L\*a\*b\* (ICC D50) | 24 patches | Y_white = 1 |
//! | ColorChecker spectral reflectance (N. Ohta 1997 = ISO 17321-1) | 380–780 nm, 5 nm | 0–1 |
//!
//! Between table nodes values are interpolated linearly. Outside a table:
//! colour-matching functions are 0 (they vanish there to < 2·10⁻⁴ of their
//! peak); illuminants and reflectances hold their end value (colour-science's
//! default extrapolation).
//!
//! ```
//! use lucent_colour::data::{Illuminant, Observer};
//! assert_eq!(Observer::Cie1931_2.cmf(555.0)[1], 1.0);
//! assert_eq!(Illuminant::D65.spd(560.0), 100.0);
//! let d50 = Illuminant::D50.white_xyz();
//! assert!((d50[0] - 0.9642956764295677).abs() < 1e-15); // x, y = 0.3457, 0.3585
//! assert_eq!(lucent_colour::data::colorchecker_2014()[0].lab, [37.54, 14.37, 14.92]);
//! ```

use std::sync::OnceLock;
use strum::{EnumIter, EnumMessage, IntoStaticStr, VariantArray, VariantNames};

const CIE1931_XYZ: &str = include_str!("../data/cie1931_2deg_xyz.csv");
const CIE2012_XYZ: &str = include_str!("../data/cie2012_2deg_xyz.csv");
const CIE1931_RGB: &str = include_str!("../data/cie1931_rgb_wright_guild.csv");
const ILLUMINANTS: &str = include_str!("../data/illuminants_d50_d65_a.csv");
const CHECKER_2014: &str = include_str!("../data/colorchecker24_after_nov2014.csv");
const CHECKER_OHTA: &str = include_str!("../data/colorchecker_ohta_reflectance.csv");

/// The ICC profile connection space white, XYZ = (0.9642, 1, 0.8249) (ICC.1:2010,
/// D50): the white of the ColorChecker reference L\*a\*b\* and of every ΔE in
/// [`crate::ccm`].
pub const ICC_D50_XYZ: [f64; 3] = [0.9642, 1.0, 0.8249];

/// A table on an even wavelength grid, columns after the wavelength.
struct Table {
    start_nm: f64,
    step_nm: f64,
    columns: Vec<Vec<f64>>,
}

/// Parses one of the embedded CSV files. The files are part of the build and
/// checked by this crate's tests, so a malformed one is a build defect.
fn parse_table(name: &str, text: &str) -> Table {
    let mut rows = text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    let ncols = rows.next().map(|h| h.split(',').count()).unwrap_or(0);
    let mut wl = Vec::new();
    let mut columns = vec![Vec::new(); ncols.saturating_sub(1)];
    for line in rows {
        let fields: Vec<f64> = line
            .split(',')
            .map(|f| {
                f.trim().parse::<f64>().unwrap_or_else(|_| panic!("embedded table {name}: bad number in {line:?}"))
            })
            .collect();
        assert_eq!(fields.len(), ncols, "embedded table {name}: row {line:?}");
        wl.push(fields[0]);
        for (c, v) in columns.iter_mut().zip(&fields[1..]) {
            c.push(*v);
        }
    }
    assert!(wl.len() >= 2, "embedded table {name}: fewer than two rows");
    let step_nm = wl[1] - wl[0];
    for (i, w) in wl.iter().enumerate() {
        assert!((w - (wl[0] + step_nm * i as f64)).abs() < 1e-9, "embedded table {name}: uneven wavelength {w}");
    }
    Table { start_nm: wl[0], step_nm, columns }
}

impl Table {
    fn end_nm(&self) -> f64 {
        self.start_nm + self.step_nm * (self.columns[0].len() - 1) as f64
    }

    /// Linear interpolation of column `c` at `nm`; outside the table `outside`
    /// gives the value (None: hold the end value).
    fn at(&self, c: usize, nm: f64, outside: Option<f64>) -> f64 {
        let col = &self.columns[c];
        let n = col.len();
        let t = (nm - self.start_nm) / self.step_nm;
        if t.is_nan() {
            return f64::NAN;
        }
        if t < 0.0 || t > (n - 1) as f64 {
            return outside.unwrap_or(if t < 0.0 { col[0] } else { col[n - 1] });
        }
        let i = (t.floor() as usize).min(n - 2);
        let f = t - i as f64;
        if f == 0.0 {
            col[i]
        } else {
            col[i] * (1.0 - f) + col[i + 1] * f
        }
    }
}

/// All spectral tables, parsed once on first use.
struct Tables {
    cie1931_xyz: Table,
    cie2012_xyz: Table,
    cie1931_rgb: Table,
    illuminants: Table,
    checker_ohta: Table,
}

fn tables() -> &'static Tables {
    static T: OnceLock<Tables> = OnceLock::new();
    T.get_or_init(|| Tables {
        cie1931_xyz: parse_table("cie1931_2deg_xyz.csv", CIE1931_XYZ),
        cie2012_xyz: parse_table("cie2012_2deg_xyz.csv", CIE2012_XYZ),
        cie1931_rgb: parse_table("cie1931_rgb_wright_guild.csv", CIE1931_RGB),
        illuminants: parse_table("illuminants_d50_d65_a.csv", ILLUMINANTS),
        checker_ohta: parse_table("colorchecker_ohta_reflectance.csv", CHECKER_OHTA),
    })
}

pub use crate::names::canonical_name;

/// A standard colorimetric observer (XYZ colour-matching functions).
/// Also read as "cie1931", "1931", "2012", "2015" and the like: a leading
/// "CIE" and a trailing "deg"/"degree" are optional.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, IntoStaticStr, VariantArray, VariantNames, EnumMessage, EnumIter)]
pub enum Observer {
    /// CIE 1931 2° standard observer (CIE 015:2018).
    #[strum(to_string = "CIE 1931 2°", serialize = "1931 2", serialize = "1931")]
    Cie1931_2,
    /// CIE 2012 2° XYZ CMFs (CIE 170-2:2015), from the Stockman & Sharpe (2000)
    /// cone fundamentals ("CIE 2015 2 Degree" in colour-science).
    #[strum(
        to_string = "CIE 2012 2°",
        serialize = "2012 2",
        serialize = "2012",
        serialize = "2015 2",
        serialize = "2015"
    )]
    Cie2012_2,
}

crate::names::named!(Observer, "observer", observer_core);

/// The canonical form of an observer's name without a leading "cie" and a
/// trailing "deg" or "degree".
fn observer_core(s: &str) -> String {
    let c = canonical_name(s);
    let c = c.strip_prefix("cie").unwrap_or(&c);
    let c = c.strip_suffix("degree").or_else(|| c.strip_suffix("deg")).unwrap_or(c);
    c.to_string()
}

impl Observer {
    /// The name, as written in files ("CIE 1931 2°", "CIE 2012 2°").
    pub fn name(self) -> &'static str {
        self.into()
    }

    fn table(self) -> &'static Table {
        match self {
            Observer::Cie1931_2 => &tables().cie1931_xyz,
            Observer::Cie2012_2 => &tables().cie2012_xyz,
        }
    }

    /// x̄, ȳ, z̄ at `nm` (0 outside the tabulated range).
    pub fn cmf(self, nm: f64) -> [f64; 3] {
        let t = self.table();
        [t.at(0, nm, Some(0.0)), t.at(1, nm, Some(0.0)), t.at(2, nm, Some(0.0))]
    }

    /// Tabulated range in nm.
    pub fn range_nm(self) -> (f64, f64) {
        let t = self.table();
        (t.start_nm, t.end_nm())
    }
}

/// A CIE illuminant.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, IntoStaticStr, VariantArray, VariantNames, EnumMessage, EnumIter)]
pub enum Illuminant {
    D50,
    D65,
    /// CIE standard illuminant A (Planckian, 2856 K).
    A,
    /// Equal-energy illuminant E.
    E,
}

crate::names::named!(Illuminant, "illuminant");

impl Illuminant {
    /// The name, as written in files ("D50", "D65", "A", "E").
    pub fn name(self) -> &'static str {
        self.into()
    }

    /// Relative spectral power at `nm` (100 at 560 nm); D50, D65 and A are
    /// tabulated 300–780 nm and hold their end value outside; E is 100.
    pub fn spd(self, nm: f64) -> f64 {
        match self {
            Illuminant::D50 => tables().illuminants.at(0, nm, None),
            Illuminant::D65 => tables().illuminants.at(1, nm, None),
            Illuminant::A => tables().illuminants.at(2, nm, None),
            Illuminant::E => {
                if nm.is_nan() {
                    f64::NAN
                } else {
                    100.0
                }
            }
        }
    }

    /// Tabulated white-point chromaticity (CIE 1931 2°) as colour-science's
    /// `CCS_ILLUMINANTS` has it: D50 (0.3457, 0.3585), D65 (0.3127, 0.3290)
    /// (the 4-digit values of CIE 15 and IEC 61966-2-1), A (0.44758, 0.40745),
    /// E (1/3, 1/3).
    pub fn white_xy(self) -> [f64; 2] {
        match self {
            Illuminant::D50 => [0.3457, 0.3585],
            Illuminant::D65 => [0.3127, 0.3290],
            Illuminant::A => [0.44758, 0.40745],
            Illuminant::E => [1.0 / 3.0, 1.0 / 3.0],
        }
    }

    /// White point XYZ from [`Illuminant::white_xy`] with Y = 1.
    pub fn white_xyz(self) -> [f64; 3] {
        crate::chromaticity::xy_to_xyz(self.white_xy())
    }
}

/// CIE 1931 r̄, ḡ, b̄ (Wright & Guild, primaries 700, 546.1, 435.8 nm) at
/// `nm`, with their negative lobes; 0 outside 380–780 nm.
pub fn cie1931_rgb_cmf(nm: f64) -> [f64; 3] {
    let t = &tables().cie1931_rgb;
    [t.at(0, nm, Some(0.0)), t.at(1, nm, Some(0.0)), t.at(2, nm, Some(0.0))]
}

/// One patch of the ColorChecker Classic with its X-Rite reference values.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckerPatch {
    /// 1..=24, row by row from dark skin (top left) to black (bottom right).
    pub number: usize,
    pub name: &'static str,
    /// x, y, Y under ICC D50 (Y of the perfect white = 1).
    pub xyy: [f64; 3],
    /// CIE L\*a\*b\* relative to [`ICC_D50_XYZ`] (X-Rite's published values).
    pub lab: [f64; 3],
}

impl CheckerPatch {
    /// XYZ under ICC D50 (Y_white = 1).
    pub fn xyz(&self) -> [f64; 3] {
        crate::chromaticity::xyy_to_xyz(self.xyy)
    }
}

/// Index (0-based) of the white patch "white 9.5 (.05 D)" in chart order.
pub const CHECKER_WHITE: usize = 18;

/// The 24 ColorChecker Classic patches with the post-November-2014 X-Rite
/// reference values (X-Rite 2016, via colour-science).
pub fn colorchecker_2014() -> &'static [CheckerPatch] {
    static P: OnceLock<Vec<CheckerPatch>> = OnceLock::new();
    P.get_or_init(|| {
        let patches: Vec<CheckerPatch> = CHECKER_2014
            .lines()
            .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
            .skip(1)
            .map(|line| {
                let f: Vec<&'static str> = line.split(',').collect();
                assert_eq!(f.len(), 8, "embedded colorchecker24_after_nov2014.csv: row {line:?}");
                let num = |i: usize| -> f64 {
                    f[i].parse().unwrap_or_else(|_| panic!("embedded colorchecker24_after_nov2014.csv: {line:?}"))
                };
                CheckerPatch {
                    number: num(0) as usize,
                    name: f[1],
                    xyy: [num(2), num(3), num(4)],
                    lab: [num(5), num(6), num(7)],
                }
            })
            .collect();
        assert_eq!(patches.len(), 24, "embedded colorchecker24_after_nov2014.csv: 24 patches");
        patches
    })
}

/// Spectral reflectance (0–1) of ColorChecker patch `index` (0-based, chart
/// order) at `nm`, measured by N. Ohta (1997) on a pre-2014 chart; tabulated
/// 380–780 nm in 5 nm steps, end values held outside. `None` for an index
/// above 23.
pub fn colorchecker_reflectance(index: usize, nm: f64) -> Option<f64> {
    let t = &tables().checker_ohta;
    (index < t.columns.len()).then(|| t.at(index, nm, None))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tables_parse_with_their_documented_ranges() {
        assert_eq!(Observer::Cie1931_2.range_nm(), (360.0, 830.0));
        assert_eq!(Observer::Cie2012_2.range_nm(), (390.0, 830.0));
        assert_eq!((tables().cie1931_rgb.start_nm, tables().cie1931_rgb.end_nm()), (380.0, 780.0));
        assert_eq!(
            (tables().illuminants.start_nm, tables().illuminants.end_nm(), tables().illuminants.step_nm),
            (300.0, 780.0, 5.0)
        );
        assert_eq!(tables().checker_ohta.columns.len(), 24);
        assert_eq!(colorchecker_2014().len(), 24);
        assert_eq!(colorchecker_2014()[CHECKER_WHITE].name, "white 9.5 (.05 D)");
        assert_eq!(colorchecker_2014()[23].name, "black 2 (1.5 D)");
    }

    #[test]
    fn interpolation_and_outside_values() {
        // Linear between 1 nm nodes.
        let a = Observer::Cie1931_2.cmf(500.0)[1];
        let b = Observer::Cie1931_2.cmf(501.0)[1];
        assert!((Observer::Cie1931_2.cmf(500.25)[1] - (0.75 * a + 0.25 * b)).abs() < 1e-15);
        assert_eq!(Observer::Cie1931_2.cmf(200.0), [0.0; 3]);
        assert_eq!(Observer::Cie2012_2.cmf(385.0), [0.0; 3]);
        assert_eq!(Illuminant::D65.spd(900.0), Illuminant::D65.spd(780.0));
        assert!(Illuminant::D65.spd(f64::NAN).is_nan());
        assert!(Illuminant::E.spd(f64::NAN).is_nan());
        assert_eq!(colorchecker_reflectance(24, 500.0), None);
    }

    #[test]
    fn illuminant_a_table_is_planck_at_2856_k() {
        // CIE 15: S_A(λ) = 100 (560/λ)^5 (e^{c2/(2848·560e-9)} − 1)/(e^{c2/(2848 λ)} − 1), c2 = 1.435e-2 m·K.
        let c2: f64 = 1.435e-2;
        let s = |nm: f64| {
            100.0 * (560.0 / nm).powi(5) * ((c2 / (2848.0 * 560e-9)).exp() - 1.0)
                / ((c2 / (2848.0 * nm * 1e-9)).exp() - 1.0)
        };
        for nm in (300..=780).step_by(5) {
            let nm = nm as f64;
            assert!(
                (Illuminant::A.spd(nm) - s(nm)).abs() / s(nm) < 1e-5,
                "{nm}: {} vs {}",
                Illuminant::A.spd(nm),
                s(nm)
            );
        }
    }

    #[test]
    fn names_parse_and_bad_names_list_the_valid_ones() {
        assert_eq!("CIE 1931 2°".parse::<Observer>().unwrap(), Observer::Cie1931_2);
        assert_eq!("cie2012".parse::<Observer>().unwrap(), Observer::Cie2012_2);
        assert_eq!("d65".parse::<Illuminant>().unwrap(), Illuminant::D65);
        let e = "D75".parse::<Illuminant>().unwrap_err().to_string();
        assert!(e.contains("D50, D65, A, E"), "{e}");
        let e = "1964".parse::<Observer>().unwrap_err().to_string();
        assert!(e.contains("\"1964\"") && e.contains("CIE 1931 2°"), "{e}");
    }
}
