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

use super::bulk::OpticalSpectrum;
use crate::io::{csv_text, write_atomic, write_json, WriteError};
use crate::plot::{self, PlotError};
use std::path::{Path, PathBuf};

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

fn png(path: &Path, bytes: Result<Vec<u8>, PlotError>) -> Result<(), OutputError> {
    let bytes = bytes.map_err(|source| OutputError::Plot { path: path.to_path_buf(), source })?;
    Ok(write_atomic(path, &bytes)?)
}

/// Writes the phase table and the plots of one sample into `dir`; returns
/// the files written.
pub fn write_sample_files(dir: &Path, spectrum: &OpticalSpectrum) -> Result<Vec<PathBuf>, OutputError> {
    let mut written = Vec::new();
    if let Some(csv) = phase_csv(spectrum) {
        let p = dir.join("phase_function.csv");
        let csv = csv.map_err(|source| OutputError::Csv { path: p.clone(), source })?;
        write_atomic(&p, csv.as_bytes())?;
        written.push(p);
        if let Some(i) = closest_wavelength(spectrum, 550.0) {
            let w = spectrum.wavelength_nm[i];
            let p = dir.join(format!("phase_{w}nm.png"));
            let title = format!("{}: phase function at {w} nm (log radial axis)", spectrum.sample);
            png(&p, plot::phase_polar_png(&title, &spectrum.phase[i], spectrum.g[i]))?;
            written.push(p);
        }
    }
    let p = dir.join("optical_properties.png");
    png(&p, plot::spectra_png(&[series(spectrum)]))?;
    written.push(p);
    Ok(written)
}

/// Writes the full output of the optics stage for `spectra` into `dir`.
pub fn write_all(dir: &Path, spectra: &[OpticalSpectrum]) -> Result<Vec<PathBuf>, OutputError> {
    let refs: Vec<&OpticalSpectrum> = spectra.iter().collect();
    let mut written = Vec::new();
    let csv = dir.join("optical_properties.csv");
    let table = table_csv(&refs).map_err(|source| OutputError::Csv { path: csv.clone(), source })?;
    write_atomic(&csv, table.as_bytes())?;
    written.push(csv);
    let json = dir.join("optical_properties.json");
    if let [single] = spectra {
        write_json(&json, single)?;
        written.push(json);
        written.extend(write_sample_files(dir, single)?);
    } else {
        write_json(&json, &spectra)?;
        written.push(json);
        let p = dir.join("optical_properties.png");
        let all: Vec<plot::SpectrumSeries> = spectra.iter().map(series).collect();
        png(&p, plot::spectra_png(&all))?;
        written.push(p);
        for s in spectra {
            written.extend(write_sample_files(&dir.join(sanitise(&s.sample)), s)?);
        }
    }
    Ok(written)
}

/// A sample name made safe as a folder name.
fn sanitise(name: &str) -> String {
    name.chars().map(|c| if c.is_alphanumeric() || "-_.".contains(c) { c } else { '_' }).collect()
}
