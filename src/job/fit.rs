//! The fit stage: [`FitJob::run`] fits a recipe's free parameters to
//! measured BSSRDF slices ([`crate::fit`]) and writes fit.json,
//! objective.png, the profiles per configuration and (identifiable fits)
//! the fitted recipe ([`FitFiles`](crate::fit::report::FitFiles)) into the
//! job's folder. `lucent fit` and the pipeline's fit stage run it; the
//! command parses its flags into the job and prints [`FitRun::summary`].

mod section;
pub use section::FitSection;

use super::context::Context;
use super::spec::FitJob;
use super::values::MeasuredSlice;
use crate::fit::{self, report, Budget, FitResult, FreeParameter, Measurement, Problem};
use crate::optics::recipe::{Overrides, Recipe};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why a fit job failed.
#[derive(Debug, Error)]
pub enum FitJobError {
    /// A value the job cannot use (the message names its flag).
    #[error("{0}")]
    Refused(String),
    #[error(transparent)]
    Fit(#[from] fit::FitError),
    #[error(transparent)]
    Recipe(#[from] crate::optics::recipe::RecipeError),
    #[error(transparent)]
    Beam(#[from] super::bssrdf::BssrdfJobError),
    #[error(transparent)]
    Output(#[from] crate::io::OutputFolderError),
    #[error(transparent)]
    Write(#[from] crate::io::WriteError),
    #[error(transparent)]
    Plot(#[from] crate::plot::PlotError),
    #[error(transparent)]
    Slice(#[from] crate::bssrdf::SliceIoError),
    /// A sidecar that is no JSON.
    #[error("{}: not valid JSON", path.display())]
    Sidecar { path: PathBuf, source: serde_json::Error },
    /// The recipe cannot be read again for the fitted one.
    #[error("{}: cannot read the recipe again", path.display())]
    RecipeAgain { path: PathBuf, source: std::io::Error },
    /// The fitted recipe does not load as it is written.
    #[error("the fitted recipe does not validate")]
    FittedRecipe { source: crate::optics::recipe::RecipeError },
    /// The staged outputs cannot be listed.
    #[error("{}: cannot list the staged outputs", path.display())]
    List { path: PathBuf, source: std::io::Error },
    /// The data cannot pin the free parameters down (the outputs are written).
    #[error("{0}")]
    NotIdentifiable(String),
    /// Stopped by Ctrl-C or SIGTERM, nothing written.
    #[error(transparent)]
    Interrupted(#[from] crate::fault::Interrupted),
}

impl FitJobError {
    /// The error as the [`Interrupted`](crate::fault::Interrupted) it is,
    /// if it is one (a caller that classes errors by their type sees it
    /// then), else itself.
    pub fn into_parts(self) -> Result<Self, crate::fault::Interrupted> {
        match self {
            FitJobError::Interrupted(i) => Err(i),
            e => Ok(e),
        }
    }
}

type E = FitJobError;

/// (θi, φi, θo, φo) in degrees.
pub type Angles = (f64, f64, f64, f64);

/// What a fit job found and wrote.
pub struct FitRun {
    pub result: FitResult,
    /// The files written, sorted.
    pub written: Vec<PathBuf>,
}

impl FitRun {
    /// The fit in a few lines (per parameter its start, value, standard
    /// error and interval; the objective), then the files written.
    pub fn summary(&self) -> Vec<String> {
        let r = &self.result;
        let mut lines: Vec<String> = r
            .parameters
            .iter()
            .map(|p| match (p.value, p.std_error, p.interval_95) {
                (Some(v), Some(se), Some([lo, hi])) => format!(
                    "{}: {:.5} → {v:.5} ± {se:.5} (95 %: {lo:.5} … {hi:.5}; SE from the measurement uncertainty {:.5}{})",
                    p.name,
                    p.start,
                    p.std_error_measurement.unwrap_or(f64::NAN),
                    p.std_error_bootstrap_configurations
                        .map(|s| format!(", bootstrap over configurations {s:.5}"))
                        .unwrap_or_default()
                ),
                _ => format!("{}: not identifiable", p.name),
            })
            .collect();
        lines.push(format!(
            "objective ({}): {:.4e} → {}; {} evaluations, {:.2e} paths, {:.1} s",
            r.objective.name(),
            r.objective_start,
            r.objective_end.map(|v| format!("{v:.4e}")).unwrap_or("—".into()),
            r.evaluations,
            r.paths_total as f64,
            r.wall_s
        ));
        lines.push(format!(
            "written: {}",
            self.written.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", ")
        ));
        lines
    }

    /// `Err` when the data cannot pin the free parameters down (the
    /// outputs are written all the same).
    pub fn finished(&self) -> Result<(), E> {
        if self.result.identifiable {
            Ok(())
        } else {
            Err(E::NotIdentifiable(self.result.reason.clone().unwrap_or_else(|| "the fit is not identifiable".into())))
        }
    }
}

/// The configuration from a sidecar (`FILE.json`, or `summary.json` beside
/// it, as `lucent bssrdf` writes): `config.theta_i_deg` etc.
fn sidecar_angles(path: &Path) -> Result<Option<Angles>, E> {
    let mut candidates = vec![PathBuf::from(format!("{}.json", path.display()))];
    if let Some(dir) = path.parent() {
        candidates.push(dir.join(crate::bssrdf::SliceFiles::SUMMARY));
    }
    for c in candidates {
        let Ok(text) = crate::io::read_text(&c) else { continue };
        let v: serde_json::Value =
            serde_json::from_str(&text).map_err(|source| E::Sidecar { path: c.clone(), source })?;
        let get = |k: &str| v.get(k).or_else(|| v.pointer(&format!("/config/{k}"))).and_then(|x| x.as_f64());
        if let (Some(ti), Some(to)) = (get("theta_i_deg"), get("theta_o_deg")) {
            return Ok(Some((ti, get("phi_i_deg").unwrap_or(0.0), to, get("phi_o_deg").unwrap_or(180.0))));
        }
    }
    Ok(None)
}

impl FitJob {
    /// The fit problem of the job, checked before any work.
    pub fn problem(&self) -> Result<Problem, E> {
        self.problem_with(Recipe::load(&self.recipe, Overrides { weight_percent: self.weight_percent })?)
    }

    /// The fit problem of the job with `recipe` (the start values) in place
    /// of the file `recipe` names: a recipe not read from a file, e.g. the
    /// Python API's dict.
    pub fn problem_with(&self, recipe: Recipe) -> Result<Problem, E> {
        let free: Vec<FreeParameter> =
            self.free.iter().map(|spec| FreeParameter::of(*spec, &recipe)).collect::<Result<_, _>>()?;
        if let Some(p) = self.measured_pixel_mm
            && !(p.is_finite() && p > 0.0)
        {
            return Err(E::Refused(format!("--measured-pixel-mm {p}: must be a positive number of millimetres")));
        }
        if let Some(n) = self.paths
            && let Some(reason) = crate::bssrdf::paths_problem(n)
        {
            return Err(E::Refused(format!("--paths {n}: {reason}")));
        }
        let measurements = self.measurements()?;
        let (beam, _) = super::bssrdf::beam(self.beam_fwhm_um, self.beam_map.as_deref(), self.beam_map_pixel_mm)?;
        let thickness_m = match self.thickness_mm {
            Some(t) if !(t.is_finite() && t > 0.0) => {
                return Err(E::Refused(format!("--thickness-mm {t}: must be a positive number of millimetres")));
            }
            Some(t) => t * 1e-3,
            None => recipe.thickness_m,
        };
        let bounds = match &self.bounds {
            Some(b) if b.0.len() != free.len() => {
                return Err(E::Refused(format!(
                    "--bounds {b}: {} entries for {} free parameter(s)",
                    b.0.len(),
                    free.len()
                )));
            }
            Some(b) => b.0.iter().map(|r| Some((r.lo, r.hi))).collect(),
            None => vec![None; free.len()],
        };
        let mut problem = Problem::new(recipe, self.wavelength_nm, free, measurements)?;
        problem.beam = beam;
        problem.objective = self.objective;
        problem.threshold = self.threshold;
        problem.measured_rel_sd = self.measured_rel_sd;
        problem.seed = self.seed;
        problem.budget = Budget {
            rel_error: self.rel_error,
            pilot_time_s: self.pilot_time_s,
            paths: self.paths,
            ..Budget::default()
        };
        problem.bounds = bounds;
        problem.thickness_m = thickness_m;
        problem.validate()?;
        Ok(problem)
    }

    /// The measured slices, each given once, with their configurations.
    fn measurements(&self) -> Result<Vec<Measurement>, E> {
        let mut measurements = Vec::new();
        // One slice given twice (under two spellings) would count as two configurations.
        let mut seen: Vec<(PathBuf, &MeasuredSlice)> = Vec::new();
        for spec in &self.measured {
            let (path, angles) = (&spec.path, spec.angles.map(|a| a.degrees()));
            if !path.is_file() {
                return Err(E::Refused(format!("--measured {}: no such file", path.display())));
            }
            let key = crate::io::file_key(path);
            if let Some((_, first)) = seen.iter().find(|(k, _)| *k == key) {
                return Err(E::Refused(format!(
                    "--measured {spec}: the same file as --measured {first}; give each measured slice once"
                )));
            }
            seen.push((key, spec));
            let angles = match angles {
                Some(x) => x,
                None => sidecar_angles(path)?.ok_or_else(|| {
                    E::Refused(format!(
                        "--measured {}: configuration unknown; write it as {}:45/0 (θi/θo in degrees) or give a FILE.json with theta_i_deg, theta_o_deg",
                        path.display(),
                        path.display()
                    ))
                })?,
            };
            measurements.push(Measurement::load_at(path, self.measured_pixel_mm, angles, Some(self.wavelength_nm))?);
        }
        Ok(measurements)
    }

    /// Fits and writes the outputs. Ctrl-C or SIGTERM stops the fit at the
    /// end of the simulation under way and writes nothing (a second one
    /// ends it at once); the outputs are written into a staging folder and
    /// moved into `out` only when all of them are, so `out` never holds
    /// half a fit. Each evaluation and the time the fit expects go to `ctx`
    /// (unless `quiet`). A fit the data cannot pin down is written and
    /// returned ([`FitRun::finished`] says so).
    pub fn run(&self, ctx: &Context) -> Result<FitRun, E> {
        let problem = self.problem()?;
        // Registered before the staging folder exists: a second Ctrl-C the
        // moment it appears still removes it (and `out`, if this run made it).
        let _remove_on_abort = crate::interrupt::remove_staged_on_abort(&self.out);
        let stage = crate::io::StagedDir::new(&self.out)?;
        let interrupt = crate::interrupt::Interrupt::install();
        let quiet = self.quiet;
        if !quiet {
            ctx.say("fitting; Ctrl-C stops after the simulation under way and writes nothing");
        }
        let stopped = |evaluations: usize| {
            crate::fault::Interrupted(format!(
                "the fit stopped after {evaluations} evaluation(s), without a result; nothing was written to {}",
                self.out.display()
            ))
        };
        // Each evaluation numbered with the time so far; after the pilot, the
        // time a search of this many parameters roughly takes (a one-parameter
        // golden search 12–20 evaluations, Nelder–Mead up to 40 per parameter).
        let started = std::time::Instant::now();
        let mut count = 0usize;
        let free = problem.free.len();
        let progress = |e: &fit::Event| {
            if quiet {
                return;
            }
            count += 1;
            let t = started.elapsed().as_secs_f64();
            ctx.say(&format!("[{count}, {t:.0} s] {e}"));
            if count == 1 {
                let (lo, hi) = if free == 1 { (12, 20) } else { (10 * free, 40 * free) };
                ctx.say(&format!(
                    "expect ≈ {}–{} s: a search over {free} parameter(s) takes ≈ {lo}–{hi} evaluations of ≈ {:.0} s",
                    (lo as f64 * t).round(),
                    (hi as f64 * t).round(),
                    t
                ));
            }
        };
        let result = match fit::fit_cancellable(&problem, progress, interrupt.flag()) {
            Err(fit::FitError::Interrupted { evaluations }) => return Err(stopped(evaluations).into()),
            r => r?,
        };
        write_fit_outputs(stage.path(), &problem, &result)?;
        if interrupt.requested() {
            return Err(stopped(result.evaluations).into());
        }
        let mut written: Vec<PathBuf> = std::fs::read_dir(stage.path())
            .map_err(|source| E::List { path: stage.path().to_path_buf(), source })?
            .filter_map(|e| e.ok())
            .map(|e| self.out.join(e.file_name()))
            .filter(|p| p.file_name().is_some_and(|n| report::FitFiles::is_output(&n.to_string_lossy())))
            .collect();
        written.sort();
        stage.commit(report::FitFiles::is_output)?;
        drop(interrupt);
        Ok(FitRun { result, written })
    }
}

/// Writes fit.json, objective.png, the profiles per configuration and
/// (identifiable fits) the fitted recipe, `NAME_fitted.toml` after the
/// recipe file's name, into `out`.
pub fn write_fit_outputs(out: &Path, problem: &Problem, result: &FitResult) -> Result<Vec<PathBuf>, E> {
    let original = crate::io::read_text(&problem.recipe.path)
        .map_err(|source| E::RecipeAgain { path: problem.recipe.path.clone(), source })?;
    let stem = problem.recipe.path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or("recipe".into());
    write_fit_outputs_with_recipe_text(out, problem, result, &original, &stem)
}

/// [`write_fit_outputs`] with the recipe's TOML text given (`original`, its
/// relative paths anchored at the folder of `problem.recipe.path`) and the
/// fitted recipe written as `STEM_fitted.toml`: for a recipe not read from
/// a file.
pub fn write_fit_outputs_with_recipe_text(
    out: &Path,
    problem: &Problem,
    result: &FitResult,
    original: &str,
    stem: &str,
) -> Result<Vec<PathBuf>, E> {
    let mut written = Vec::new();
    let files = report::FitFiles::in_dir(out);
    let p = files.json.clone();
    crate::io::write_json(&p, result)?;
    written.push(p);
    let p = files.objective_png.clone();
    crate::io::write_atomic(&p, &report::objective_png(result)?)?;
    written.push(p);
    // Per configuration: the measured profile against the simulated ones at
    // the recipe and at the fit.
    for (c, m) in problem.measurements.iter().enumerate() {
        let row = |s: &[f64]| -> Option<Vec<f64>> {
            let n = m.grid.size;
            (s.len() == n * n).then(|| s[(n / 2) * n..(n / 2 + 1) * n].to_vec())
        };
        let start = result.slices_start.get(c).and_then(|s| row(s));
        let end = result.slices_end.as_ref().and_then(|e| e.get(c)).and_then(|s| row(s));
        let mut curves: Vec<crate::bssrdf::ProfileCurve> = vec![("measured", m.grid.middle_row(), None)];
        curves.extend(start.as_deref().map(|v| ("simulated at the recipe", v, None)));
        curves.extend(end.as_deref().map(|v| ("simulated at the fit", v, None)));
        let d = &m.directions;
        let p = files.profiles_png(d.theta_i_deg, d.theta_o_deg);
        crate::io::write_atomic(&p, &crate::bssrdf::profile_png(&m.grid.x_mm(), &curves, None)?)?;
        written.push(p);
    }
    let dir = problem.recipe.path.parent().unwrap_or(Path::new("."));
    if let Some(text) = report::fitted_recipe_text(original, dir, result) {
        let p = files.fitted_recipe(stem);
        // The fitted recipe must load as it is written.
        Recipe::parse(&text, &p, Overrides::default()).map_err(|source| E::FittedRecipe { source })?;
        crate::io::write_atomic(&p, text.as_bytes())?;
        written.push(p);
    }
    Ok(written)
}
