//! Files of the optics stage: the property table (CSV and JSON, one row per
//! sample and wavelength), the phase tables (CSV, per steradian) and plots.
//!
//! Layout of an output folder for one recipe:
//!
//! | file | content |
//! |---|---|
//! | `optical_properties.csv` | sample, wavelength_nm, mu_s_per_m, mu_a_per_m, mu_t_per_m, g, n_bulk |
//! | `optical_properties.json` | the same as arrays over wavelength, with the sample's `absorption` model and the `corrections` of its index data |
//! | `phase_function.csv` | theta_deg, cos_theta, then p [1/sr] per wavelength |
//! | `optical_properties.png` | μ_s, μ_a, g against wavelength |
//! | `phase_<λ>nm.png` | polar plot, Lorenz–Mie against Henyey–Greenstein, near 550 nm |
//!
//! For several recipes the table files hold all samples (the JSON is an
//! array) and each sample gets a subfolder with its phase table and plots.
//!
//! `optical_properties.json` is defined once, by [`OpticalProperties`]:
//! [`write_all`] writes it and [`read_optical_properties`] reads it back
//! (`lucent colour bands`). Units: wavelength in nm, μ_s, μ_a, μ_t in 1/m,
//! g and n_bulk dimensionless.

use super::bulk::OpticalSpectrum;
use crate::io::{csv_text, json_bytes, write_files_atomic, WriteError};
use crate::plot::{self, PlotError};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// One sample's entry of `optical_properties.json` (the file holds one
/// object, or an array of them for several samples). The fields and their
/// order are those [`OpticalSpectrum`] was always serialised with, so files
/// written before this type existed read back and re-serialise unchanged.
/// Only the wavelength grid, μ_s, μ_a and g are required on reading (a
/// hand-made file may leave out the rest).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OpticalProperties {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sample: Option<String>,
    /// The absorption model's recipe name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub absorption: Option<String>,
    #[serde(default)]
    pub corrections: Vec<String>,
    pub wavelength_nm: Vec<f64>,
    pub mu_s_per_m: Vec<f64>,
    pub mu_a_per_m: Vec<f64>,
    #[serde(default)]
    pub mu_t_per_m: Vec<f64>,
    pub g: Vec<f64>,
    #[serde(default)]
    pub n_bulk: Vec<f64>,
    #[serde(default)]
    pub warnings: Vec<String>,
}

impl From<&OpticalSpectrum> for OpticalProperties {
    fn from(s: &OpticalSpectrum) -> Self {
        Self {
            sample: Some(s.sample.clone()),
            absorption: Some(s.absorption.name().to_string()),
            corrections: s.corrections.clone(),
            wavelength_nm: s.wavelength_nm.clone(),
            mu_s_per_m: s.mu_s_per_m.clone(),
            mu_a_per_m: s.mu_a_per_m.clone(),
            mu_t_per_m: s.mu_t_per_m.clone(),
            g: s.g.clone(),
            n_bulk: s.n_bulk.clone(),
            warnings: s.warnings.clone(),
        }
    }
}

/// An `optical_properties.json` that cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum OpticalPropertiesError {
    #[error("{}: cannot read: {source}", path.display())]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{}: not valid JSON: {source}", path.display())]
    Json { path: PathBuf, source: serde_json::Error },
    #[error("{}: no spectra in this file", path.display())]
    Empty { path: PathBuf },
    #[error(
        "{}: entry {entry}: expected an object with arrays wavelength_nm, mu_s_per_m, mu_a_per_m, g (as `lucent optics` writes): {source}",
        path.display()
    )]
    Entry { path: PathBuf, entry: usize, source: serde_json::Error },
    #[error("{}: {sample}: {field} has {len} values but wavelength_nm has {expected}", path.display())]
    Length { path: PathBuf, sample: String, field: &'static str, len: usize, expected: usize },
}

impl OpticalProperties {
    /// The sample's name, or `entry K` (1-based) for an unnamed one.
    pub fn name(&self, entry: usize) -> String {
        self.sample.clone().unwrap_or_else(|| format!("entry {}", entry + 1))
    }
}

/// Reads `optical_properties.json` (one object or an array); every entry's
/// arrays must have one value per wavelength.
pub fn read_optical_properties(path: &Path) -> Result<Vec<OpticalProperties>, OpticalPropertiesError> {
    let text = crate::io::read_text(path)
        .map_err(|source| OpticalPropertiesError::Read { path: path.to_path_buf(), source })?;
    let value: serde_json::Value = serde_json::from_str(&text)
        .map_err(|source| OpticalPropertiesError::Json { path: path.to_path_buf(), source })?;
    let items = match value {
        serde_json::Value::Array(items) => items,
        single => vec![single],
    };
    if items.is_empty() {
        return Err(OpticalPropertiesError::Empty { path: path.to_path_buf() });
    }
    let mut out = Vec::with_capacity(items.len());
    for (i, v) in items.into_iter().enumerate() {
        let p: OpticalProperties = serde_json::from_value(v).map_err(|source| OpticalPropertiesError::Entry {
            path: path.to_path_buf(),
            entry: i + 1,
            source,
        })?;
        let n = p.wavelength_nm.len();
        let optional = |v: &Vec<f64>| if v.is_empty() { n } else { v.len() };
        for (field, len) in [
            ("mu_s_per_m", p.mu_s_per_m.len()),
            ("mu_a_per_m", p.mu_a_per_m.len()),
            ("g", p.g.len()),
            ("mu_t_per_m", optional(&p.mu_t_per_m)),
            ("n_bulk", optional(&p.n_bulk)),
        ] {
            if len != n {
                return Err(OpticalPropertiesError::Length {
                    path: path.to_path_buf(),
                    sample: p.name(i),
                    field,
                    len,
                    expected: n,
                });
            }
        }
        out.push(p);
    }
    Ok(out)
}

/// An output that could not be produced.
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    #[error(transparent)]
    Write(#[from] WriteError),
    #[error("{path}: {source}")]
    Plot { path: PathBuf, source: PlotError },
    #[error("{path}: cannot form the CSV table: {source}")]
    Csv { path: PathBuf, source: csv::Error },
}

/// Columns of the property table.
pub const CSV_HEADER: [&str; 7] = ["sample", "wavelength_nm", "mu_s_per_m", "mu_a_per_m", "mu_t_per_m", "g", "n_bulk"];

/// The property table of all `spectra` as CSV text.
pub fn table_csv(spectra: &[&OpticalSpectrum]) -> Result<String, csv::Error> {
    let rows = spectra.iter().flat_map(|s| {
        (0..s.wavelength_nm.len()).map(move |i| {
            vec![
                s.sample.clone(),
                s.wavelength_nm[i].to_string(),
                format!("{:.10e}", s.mu_s_per_m[i]),
                format!("{:.10e}", s.mu_a_per_m[i]),
                format!("{:.10e}", s.mu_t_per_m[i]),
                format!("{:.10}", s.g[i]),
                format!("{:.10}", s.n_bulk[i]),
            ]
        })
    });
    csv_text(&CSV_HEADER, rows)
}

/// The phase tables of `spectrum` as CSV text (None without tables).
pub fn phase_csv(spectrum: &OpticalSpectrum) -> Option<Result<String, csv::Error>> {
    let n = spectrum.phase.first().map(Vec::len).filter(|&n| n >= 2)?;
    let mut header = vec!["theta_deg".to_string(), "cos_theta".to_string()];
    header.extend(spectrum.wavelength_nm.iter().map(|w| format!("p_{w}nm_per_sr")));
    let header: Vec<&str> = header.iter().map(String::as_str).collect();
    let rows = (0..n).map(|i| {
        let theta = std::f64::consts::PI * i as f64 / (n - 1) as f64;
        let mut row = vec![format!("{:.8}", theta.to_degrees()), format!("{:.12}", theta.cos())];
        row.extend(spectrum.phase.iter().map(|table| format!("{:.9e}", table[i])));
        row
    });
    Some(csv_text(&header, rows))
}

/// Index of the grid wavelength closest to `target_nm`.
pub fn closest_wavelength(spectrum: &OpticalSpectrum, target_nm: f64) -> Option<usize> {
    (0..spectrum.wavelength_nm.len()).min_by(|&a, &b| {
        (spectrum.wavelength_nm[a] - target_nm).abs().total_cmp(&(spectrum.wavelength_nm[b] - target_nm).abs())
    })
}

/// The plotted view of a spectrum: plain slices for [`plot::spectra_png`].
fn series(s: &OpticalSpectrum) -> plot::SpectrumSeries<'_> {
    plot::SpectrumSeries {
        name: &s.sample,
        absorption_model: s.absorption.name(),
        wavelength_nm: &s.wavelength_nm,
        mu_s_per_m: &s.mu_s_per_m,
        mu_a_per_m: &s.mu_a_per_m,
        g: &s.g,
    }
}

fn png(path: &Path, bytes: Result<Vec<u8>, PlotError>) -> Result<(PathBuf, Vec<u8>), OutputError> {
    let bytes = bytes.map_err(|source| OutputError::Plot { path: path.to_path_buf(), source })?;
    Ok((path.to_path_buf(), bytes))
}

/// The files of the optics stage in its output folder, each name spelled
/// here once: the property table (`csv`), its JSON ([`OpticalProperties`],
/// `json`) and the spectra plot (`png`). Written by [`write_all`], read by
/// `lucent run`'s report.
///
/// ```
/// use lucent::optics::output::OpticsFiles;
/// let f = OpticsFiles::in_dir(std::path::Path::new("out/optics"));
/// assert_eq!(f.json, std::path::Path::new("out/optics/optical_properties.json"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OpticsFiles {
    pub csv: PathBuf,
    pub json: PathBuf,
    pub png: PathBuf,
}

impl OpticsFiles {
    /// The file names.
    pub const NAMES: [&'static str; 3] =
        ["optical_properties.csv", "optical_properties.json", "optical_properties.png"];

    /// The files of the optics output folder `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [csv, json, png] = Self::NAMES.map(|n| dir.join(n));
        Self { csv, json, png }
    }

    /// The folder of one sample's phase table and plots: `dir` itself when
    /// the folder holds `count` = 1 sample, else the subfolder of its name.
    pub fn sample_dir(dir: &Path, count: usize, sample: &str) -> PathBuf {
        if count == 1 {
            dir.to_path_buf()
        } else {
            dir.join(sanitise(sample))
        }
    }
}

/// One sample's phase table (`phase_csv`), its spectra plot (`png`) and its
/// phase-function plots ([`SampleFiles::phase_png`]) in its folder
/// ([`OpticsFiles::sample_dir`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SampleFiles {
    pub phase_csv: PathBuf,
    pub png: PathBuf,
    dir: PathBuf,
}

impl SampleFiles {
    const PHASE_CSV: &'static str = "phase_function.csv";
    /// The start and end of a phase-function plot's name.
    const PHASE_PNG: (&'static str, &'static str) = ("phase_", "nm.png");

    /// The files of the sample folder `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        Self { phase_csv: dir.join(Self::PHASE_CSV), png: OpticsFiles::in_dir(dir).png, dir: dir.to_path_buf() }
    }

    /// The phase-function plot at `wavelength_nm`.
    pub fn phase_png(&self, wavelength_nm: f64) -> PathBuf {
        let (start, end) = Self::PHASE_PNG;
        self.dir.join(format!("{start}{wavelength_nm}{end}"))
    }

    /// The phase-function plots in the folder, sorted (none when it cannot be read).
    pub fn phase_pngs(&self) -> Vec<PathBuf> {
        let (start, _) = Self::PHASE_PNG;
        let Ok(rd) = std::fs::read_dir(&self.dir) else { return Vec::new() };
        let mut v: Vec<PathBuf> = rd
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.file_name().is_some_and(|n| {
                    let n = n.to_string_lossy();
                    n.starts_with(start) && n.ends_with(".png")
                })
            })
            .collect();
        v.sort();
        v
    }
}

/// The phase table and the plots of one sample in `dir`, as (path, bytes).
fn sample_files(dir: &Path, spectrum: &OpticalSpectrum) -> Result<Vec<(PathBuf, Vec<u8>)>, OutputError> {
    let names = SampleFiles::in_dir(dir);
    let mut files = Vec::new();
    if let Some(csv) = phase_csv(spectrum) {
        let p = names.phase_csv.clone();
        let csv = csv.map_err(|source| OutputError::Csv { path: p.clone(), source })?;
        files.push((p, csv.into_bytes()));
        if let Some(i) = closest_wavelength(spectrum, 550.0) {
            let w = spectrum.wavelength_nm[i];
            let p = names.phase_png(w);
            let title = format!("{}: phase function at {w} nm (log radial axis)", spectrum.sample);
            files.push(png(&p, plot::phase_polar_png(&title, &spectrum.phase[i], spectrum.g[i]))?);
        }
    }
    files.push(png(&names.png, plot::spectra_png(&[series(spectrum)]))?);
    Ok(files)
}

/// Writes the full output of the optics stage for `spectra` into `dir`, all
/// files or none ([`crate::io::write_files_atomic`]: a full disk or Ctrl-C
/// leaves no part of a table); returns the files written.
pub fn write_all(dir: &Path, spectra: &[OpticalSpectrum]) -> Result<Vec<PathBuf>, OutputError> {
    let refs: Vec<&OpticalSpectrum> = spectra.iter().collect();
    let mut files = Vec::new();
    let OpticsFiles { csv, json, png: all_png } = OpticsFiles::in_dir(dir);
    let table = table_csv(&refs).map_err(|source| OutputError::Csv { path: csv.clone(), source })?;
    files.push((csv, table.into_bytes()));
    let file: Vec<OpticalProperties> = spectra.iter().map(OpticalProperties::from).collect();
    if let ([single], [entry]) = (spectra, file.as_slice()) {
        files.push((json.clone(), json_bytes(&json, entry)?));
        files.extend(sample_files(dir, single)?);
    } else {
        files.push((json.clone(), json_bytes(&json, &file)?));
        let all: Vec<plot::SpectrumSeries> = spectra.iter().map(series).collect();
        files.push(png(&all_png, plot::spectra_png(&all))?);
        for s in spectra {
            files.extend(sample_files(&OpticsFiles::sample_dir(dir, spectra.len(), &s.sample), s)?);
        }
    }
    let refs: Vec<(&Path, &[u8])> = files.iter().map(|(p, b)| (p.as_path(), b.as_slice())).collect();
    write_files_atomic(&refs)?;
    Ok(files.into_iter().map(|(p, _)| p).collect())
}

/// A sample name made safe as a folder name.
fn sanitise(name: &str) -> String {
    name.chars().map(|c| if c.is_alphanumeric() || "-_.".contains(c) { c } else { '_' }).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIXTURES: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/fixtures/formats");

    /// Files written by `lucent optics` before this type existed (one
    /// sample: an object; two: an array) read back and write back with the
    /// same content (compared as parsed JSON: serde_json's float parsing
    /// without `float_roundtrip` may change a last digit).
    #[test]
    fn fixtures_read_and_write_back_unchanged() {
        for (name, count) in [("optical_properties_one.json", 1), ("optical_properties_two.json", 2)] {
            let path = Path::new(FIXTURES).join(name);
            let file = read_optical_properties(&path).unwrap();
            assert_eq!(file.len(), count, "{name}");
            assert_eq!(file[0].sample.as_deref(), Some("IOL1068-05"));
            assert_eq!(file[0].wavelength_nm, vec![450.0, 550.0, 650.0]);
            let again =
                if count == 1 { serde_json::to_value(&file[0]).unwrap() } else { serde_json::to_value(&file).unwrap() };
            let original: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
            assert_eq!(again, original, "{name}");
        }
    }

    /// The file type serialises a computed spectrum to exactly the bytes the
    /// spectrum itself was written as before (field names, order, numbers).
    #[test]
    fn the_file_type_writes_what_the_spectrum_wrote() {
        use crate::optics::recipe::{Overrides, Recipe};
        let recipe = Recipe::load(
            &Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/samples/IOL1068-05.toml"),
            Overrides::default(),
        )
        .unwrap();
        let grid = lucent_colour::WavelengthGrid::from_list(vec![450.0, 550.0, 650.0]).unwrap();
        let options = crate::optics::bulk::Options { phase_entries: 0, ..Default::default() };
        let spectrum = crate::optics::bulk::compute(&recipe, &grid, &options).unwrap();
        let file = OpticalProperties::from(&spectrum);
        assert_eq!(serde_json::to_string_pretty(&file).unwrap(), serde_json::to_string_pretty(&spectrum).unwrap());
    }

    #[test]
    fn bad_files_are_refused_naming_the_file_and_the_field() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("op.json");
        std::fs::write(
            &p,
            r#"{"sample": "a", "wavelength_nm": [500, 600], "mu_s_per_m": [1], "mu_a_per_m": [1, 2], "g": [0, 0]}"#,
        )
        .unwrap();
        let e = read_optical_properties(&p).unwrap_err().to_string();
        assert!(e.contains("op.json: a: mu_s_per_m has 1 values but wavelength_nm has 2"), "{e}");
        std::fs::write(&p, "[]").unwrap();
        assert!(read_optical_properties(&p).unwrap_err().to_string().ends_with("op.json: no spectra in this file"));
        std::fs::write(&p, r#"[{"wavelength_nm": [500]}]"#).unwrap();
        let e = read_optical_properties(&p).unwrap_err().to_string();
        assert!(e.contains("op.json: entry 1: expected an object") && e.contains("mu_s_per_m"), "{e}");
        // A minimal hand-made entry: only the four required arrays.
        std::fs::write(&p, r#"{"wavelength_nm": [500], "mu_s_per_m": [1], "mu_a_per_m": [2], "g": [0.5]}"#).unwrap();
        let ok = read_optical_properties(&p).unwrap();
        assert_eq!((ok[0].name(0), ok[0].g[0]), ("entry 1".to_string(), 0.5));
    }
}
