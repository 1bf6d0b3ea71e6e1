//! The optics stage: [`OpticsJob::run`] computes the bulk optical
//! properties (μs, μa, μt, g, n_bulk and the tabulated phase function per
//! wavelength, [`crate::optics::bulk`]) of every recipe the job names (files
//! or folders of recipes) and writes them into the job's folder
//! ([`crate::optics::output::write_all`]). `lucent optics` and the
//! pipeline's optics stage both run it; the command only parses its flags
//! into the job and prints [`OpticsRun::summary`] (the table, the models and
//! corrections, or the JSON). With `uncertainty` N the job is instead the
//! propagation of the recipes' uncertain inputs
//! ([`OpticsJob::run_uncertainty`], which `shard` splits and
//! [`OpticsJob::merge_uncertainty`] merges).

mod error;
mod section;
mod uncertainty;

pub use error::{OpticsJobError, MAX_PHASE_VALUES};
pub use section::{read_spectra, OpticsSection};
pub use uncertainty::{uncertainty_acc, UncertaintyRun};

use super::context::Context;
use super::spec::{OpticsJob, DEFAULT_OPTICS_OUT};
use crate::optics::bulk::{self, OpticalSpectrum};
use crate::optics::output;
use crate::optics::recipe::{Overrides, Recipe, RecipeError};
use lucent_colour::WavelengthGrid;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What an optics job computed and wrote.
pub struct OpticsRun {
    /// Each recipe's properties, in the order the recipes were given.
    pub spectra: Vec<OpticalSpectrum>,
    /// The wavelengths computed.
    pub wavelengths: usize,
    /// Seconds the computation took.
    pub elapsed_s: f64,
    /// The output folder and the files written into it (`None`: nothing written).
    pub written: Option<(PathBuf, Vec<PathBuf>)>,
    /// With `json`: the properties as JSON text (one object for one sample
    /// and nothing written, else an array), printed instead of the tables.
    pub json: Option<String>,
    /// With `uncertainty`: the study (or its shard) instead of the properties.
    pub study: Option<UncertaintyRun>,
}

impl OpticsJob {
    /// The wavelength grid the job computes (`wavelength_nm`, else
    /// `wavelengths`), checked with the phase tables it asks for when
    /// `with_phase_tables` (a table of 1 entry, or too many values, refused).
    pub fn checked_grid(&self, with_phase_tables: bool) -> Result<WavelengthGrid, OpticsJobError> {
        let grid = match self.wavelength_nm {
            Some(w) if !(w.is_finite() && w > 0.0) => return Err(OpticsJobError::Wavelength(w)),
            Some(w) => WavelengthGrid::from_list(vec![w]).map_err(OpticsJobError::Grid)?,
            None => self.wavelengths.clone(),
        };
        if self.phase_entries == 1 {
            return Err(OpticsJobError::PhaseEntriesOne);
        }
        if with_phase_tables && grid.len() * self.phase_entries > MAX_PHASE_VALUES {
            return Err(OpticsJobError::TooManyPhaseValues { wavelengths: grid.len(), entries: self.phase_entries });
        }
        Ok(grid)
    }

    /// The job's recipes read (folders expanded, each file once), invalid
    /// ones left out with `skip_invalid`; warnings and notes go to `ctx`.
    pub fn load_recipes(&self, ctx: &Context) -> Result<Vec<Recipe>, OpticsJobError> {
        let paths = collect_recipe_paths(&self.recipes, ctx)?;
        load_recipes(&paths, Overrides { weight_percent: self.weight_percent }, self.skip_invalid, ctx)
    }

    /// Computes the properties and writes them (unless the job only prints
    /// JSON); with `uncertainty`, the study instead
    /// ([`OpticsJob::run_uncertainty`]). Warnings and notes go to `ctx`.
    pub fn run(&self, ctx: &Context) -> Result<OpticsRun, OpticsJobError> {
        if self.uncertainty.is_some() {
            let study = self.run_uncertainty(ctx)?;
            let written = Some((study.out.clone(), Vec::new()));
            let wavelengths = self.checked_grid(false)?.len();
            return Ok(OpticsRun {
                spectra: Vec::new(),
                wavelengths,
                elapsed_s: 0.0,
                written,
                json: None,
                study: Some(study),
            });
        }
        let grid = self.checked_grid(true)?;
        let recipes = self.load_recipes(ctx)?;
        let options = bulk::Options { phase_entries: self.phase_entries, ..Default::default() };
        let start = Instant::now();
        let spectra: Vec<OpticalSpectrum> = recipes
            .par_iter()
            .map(|r| {
                bulk::compute(r, &grid, &options)
                    .map_err(|source| OpticsJobError::Compute { path: r.path.clone(), source })
            })
            .collect::<Result<_, _>>()?;
        let elapsed_s = start.elapsed().as_secs_f64();
        for line in grouped_warnings(&spectra) {
            match (line.strip_prefix("warning: "), line.strip_prefix("note: ")) {
                (Some(w), _) => ctx.warn(w),
                (None, Some(n)) => ctx.note(n),
                (None, None) => ctx.say(&line),
            }
        }
        let json = |all: bool| {
            match spectra.as_slice() {
                [single] if !all => serde_json::to_string_pretty(single),
                _ => serde_json::to_string_pretty(&spectra),
            }
            .map_err(OpticsJobError::Json)
        };
        let Some(out) = &self.out else {
            let text = if self.json { Some(json(false)?) } else { None };
            return Ok(OpticsRun {
                wavelengths: grid.len(),
                elapsed_s,
                written: None,
                json: text,
                spectra,
                study: None,
            });
        };
        let written = output::write_all(out, &spectra)?;
        let text = if self.json { Some(json(true)?) } else { None };
        Ok(OpticsRun {
            wavelengths: grid.len(),
            elapsed_s,
            written: Some((out.clone(), written)),
            json: text,
            spectra,
            study: None,
        })
    }
}

impl OpticsRun {
    /// What `lucent optics` prints: the JSON, or the table (every
    /// wavelength of one sample, 450/550/650 nm of several), the absorption
    /// models and index corrections, and what was written.
    pub fn summary(&self) -> Vec<String> {
        if let Some(study) = &self.study {
            return study.summary();
        }
        if let Some(text) = &self.json {
            return vec![text.clone()];
        }
        let mut lines = table(&self.spectra);
        lines.push(String::new());
        lines.extend(models_and_corrections(&self.spectra));
        if let Some((out, written)) = &self.written {
            lines.push(String::new());
            lines.push(format!(
                "{} sample(s) × {} wavelength(s) in {:.2} s; {} files written to {}/ (full table: {})",
                self.spectra.len(),
                self.wavelengths,
                self.elapsed_s,
                written.len(),
                out.display(),
                output::OpticsFiles::in_dir(out).csv.display()
            ));
        }
        lines
    }
}

/// The output folder of `lucent optics` given `--out` or not and `--json`:
/// none when only JSON is printed.
pub fn output_folder(out: Option<&Path>, json: bool) -> Option<PathBuf> {
    match out {
        Some(o) => Some(o.to_path_buf()),
        None if json => None,
        None => Some(PathBuf::from(DEFAULT_OPTICS_OUT)),
    }
}

/// The `*.toml` entries of folder `dir`, sorted.
pub fn toml_files_in(dir: &Path) -> std::io::Result<Vec<PathBuf>> {
    let mut found: Vec<PathBuf> = std::fs::read_dir(dir)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    found.sort();
    Ok(found)
}

/// The recipe files of `inputs` (a folder gives its `*.toml`, sorted), each
/// file once (a repeat is warned of).
pub fn collect_recipe_paths(inputs: &[PathBuf], ctx: &Context) -> Result<Vec<PathBuf>, OpticsJobError> {
    let mut paths = Vec::new();
    for input in inputs {
        if input.is_dir() {
            let found =
                toml_files_in(input).map_err(|source| OpticsJobError::ListFolder { path: input.clone(), source })?;
            if found.is_empty() {
                return Err(OpticsJobError::NoRecipes { path: input.clone() });
            }
            paths.extend(found);
        } else if input.exists() {
            paths.push(input.clone());
        } else {
            return Err(OpticsJobError::NoSuchRecipe { path: input.clone() });
        }
    }
    // The same file given twice (directly, through a folder, or by another
    // spelling of its path) is computed once.
    let mut seen = Vec::new();
    paths.retain(|p| {
        let key = crate::io::file_key(p);
        if seen.contains(&key) {
            ctx.warn(&format!("{}: recipe given more than once; computed once", p.display()));
            return false;
        }
        seen.push(key);
        true
    });
    Ok(paths)
}

/// Loads recipes; with `skip_invalid`, invalid ones are reported and left out.
pub fn load_recipes(
    paths: &[PathBuf],
    overrides: Overrides,
    skip_invalid: bool,
    ctx: &Context,
) -> Result<Vec<Recipe>, OpticsJobError> {
    let mut recipes = Vec::new();
    let mut failures = Vec::new();
    // Recipes that leave a weight percentage unknown on purpose (IOL1068-15):
    // in a folder they are skipped with a note, not a warning.
    let mut unknown = Vec::new();
    for p in paths {
        match Recipe::load(p, overrides) {
            Ok(r) => recipes.push(r),
            Err(e @ RecipeError::WeightPercentUnknown { .. }) => unknown.push(e.to_string()),
            Err(e) => failures.push(e.to_string()),
        }
    }
    if skip_invalid && !recipes.is_empty() {
        for f in &unknown {
            ctx.note(&format!("skipped {f}"));
        }
    } else {
        failures.append(&mut unknown);
    }
    if !failures.is_empty() {
        if skip_invalid && !recipes.is_empty() {
            for f in &failures {
                ctx.warn(&format!("skipped {f}"));
            }
        } else {
            return Err(OpticsJobError::Invalid(failures));
        }
    }
    // Two files with one sample name would give rows nobody can tell apart.
    for (i, r) in recipes.iter().enumerate() {
        if let Some(first) = recipes[..i].iter().find(|q| q.name == r.name) {
            return Err(OpticsJobError::SameName {
                first: first.path.clone(),
                second: r.path.clone(),
                name: r.name.clone(),
            });
        }
    }
    Ok(recipes)
}

/// The samples' warnings, each text once with the samples it applies to
/// ("warning: TEXT [11 samples: A, B, …]"): a set of recipes that share a
/// host gives one line, not one per recipe. An index held at its end value
/// (`extrapolate = "clamp"`) is followed by one line saying what that means.
fn grouped_warnings(spectra: &[OpticalSpectrum]) -> Vec<String> {
    let mut groups: Vec<(&str, Vec<&str>)> = Vec::new();
    for s in spectra {
        for w in &s.warnings {
            match groups.iter_mut().find(|(t, _)| *t == w.as_str()) {
                Some((_, samples)) => samples.push(&s.sample),
                None => groups.push((w, vec![&s.sample])),
            }
        }
    }
    let mut lines: Vec<String> = groups
        .iter()
        .map(|(text, samples)| {
            let level = if expected_clamp(text) { "note" } else { "warning" };
            match samples.as_slice() {
                [one] => format!("{level}: {one}: {text}"),
                many if many.len() == spectra.len() => format!("{level}: {text} [all {} samples]", many.len()),
                many => format!("{level}: {text} [{} samples: {}]", many.len(), many.join(", ")),
            }
        })
        .collect();
    if groups.iter().any(|(t, _)| t.contains(" clamped outside its data range")) {
        lines.push(
            "   (clamped: the recipe's extrapolate = \"clamp\" holds n and κ at the data's end value at those \
             wavelengths; expected at 380–399 nm for tables that start at 400 nm, where the CIE colour-matching \
             functions are below 1.2 % of their peaks, so a render's colour barely depends on it)"
                .into(),
        );
    }
    lines
}

/// Whether a sample's warning is an index the recipe asked to clamp
/// (`extrapolate = "clamp"`) at wavelengths of 380–399 nm only: the
/// shipped tables start at 400 nm, and there the CIE colour-matching
/// functions are below 1.2 % of their peaks. Such a line is a note, not a
/// warning; a clamp anywhere else stays a warning.
fn expected_clamp(text: &str) -> bool {
    let Some(at) = text.split(" clamped outside its data range ").nth(1) else {
        return false;
    };
    let Some(list) = at.split("(at ").nth(1).and_then(|l| l.strip_suffix(" nm)")) else {
        return false;
    };
    let nm: Vec<Option<f64>> = list.split(", ").map(|x| x.parse::<f64>().ok()).collect();
    !nm.is_empty() && nm.iter().all(|x| matches!(x, Some(l) if (380.0..400.0).contains(l)))
}

/// The readable table: every wavelength for one sample, or 450/550/650 nm for several.
fn table(spectra: &[OpticalSpectrum]) -> Vec<String> {
    let mut lines = vec![format!(
        "{:<14} {:>8} {:>13} {:>13} {:>13} {:>9} {:>9}",
        "sample", "λ [nm]", "μs [1/m]", "μa [1/m]", "μt [1/m]", "g", "n_bulk"
    )];
    for s in spectra {
        let rows: Vec<usize> = if spectra.len() == 1 {
            (0..s.wavelength_nm.len()).collect()
        } else {
            let picks: Vec<usize> =
                (0..s.wavelength_nm.len()).filter(|&i| [450.0, 550.0, 650.0].contains(&s.wavelength_nm[i])).collect();
            if picks.is_empty() {
                (0..s.wavelength_nm.len()).collect()
            } else {
                picks
            }
        };
        for i in rows {
            lines.push(format!(
                "{:<14} {:>8} {:>13.5e} {:>13.5e} {:>13.5e} {:>9.5} {:>9.5}",
                s.sample, s.wavelength_nm[i], s.mu_s_per_m[i], s.mu_a_per_m[i], s.mu_t_per_m[i], s.g[i], s.n_bulk[i]
            ));
        }
    }
    lines
}

/// The absorption model and the corrections of the index data, each line
/// once with the samples it applies to.
fn models_and_corrections(spectra: &[OpticalSpectrum]) -> Vec<String> {
    let mut lines: Vec<(String, Vec<&str>)> = Vec::new();
    for s in spectra {
        let model = format!("absorption {}: {}", s.absorption.name(), s.absorption.formula());
        for text in std::iter::once(model).chain(s.corrections.iter().cloned()) {
            match lines.iter_mut().find(|(t, _)| *t == text) {
                Some((_, samples)) => samples.push(&s.sample),
                None => lines.push((text, vec![&s.sample])),
            }
        }
    }
    lines
        .into_iter()
        .map(|(text, samples)| {
            if spectra.len() > 1 && samples.len() == spectra.len() {
                format!("{text} [all samples]")
            } else if spectra.len() > 1 {
                format!("{text} [{}]", samples.join(", "))
            } else {
                text
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_clamp_below_400_nm_is_a_note_and_any_other_a_warning() {
        let clamp =
            |at: &str| format!("host PC index (builtin:PC) clamped outside its data range 400–19942 nm (at {at} nm)");
        assert!(expected_clamp(&clamp("380, 390")));
        assert!(!expected_clamp(&clamp("370, 380, 390")));
        assert!(!expected_clamp(&clamp("20000")));
        assert!(!expected_clamp(&clamp("")));
        let linear = "host PC index (x) linearly extrapolated outside its data range 400–900 nm (at 390 nm)";
        assert!(!expected_clamp(linear));
        let one = OpticalSpectrum {
            sample: "A".into(),
            absorption: crate::optics::recipe::AbsorptionModel::Mie,
            corrections: Vec::new(),
            wavelength_nm: vec![390.0],
            mu_s_per_m: vec![1.0],
            mu_a_per_m: vec![0.0],
            mu_t_per_m: vec![1.0],
            g: vec![0.0],
            n_bulk: vec![1.5],
            phase: Vec::new(),
            phase_integral_before_normalisation: Vec::new(),
            warnings: vec![clamp("380, 390"), clamp("360")],
        };
        let lines = grouped_warnings(std::slice::from_ref(&one));
        assert!(lines[0].starts_with("note: A: host PC"), "{lines:?}");
        assert!(lines[1].starts_with("warning: A: host PC"), "{lines:?}");
    }
}
