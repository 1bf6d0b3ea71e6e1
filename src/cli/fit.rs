//! `lucent fit`: recipe parameters fitted to measured BSSRDF slices
//! ([`crate::fit`]). Argument handling and printing only: the flags become
//! a [`FitJob`], which does the work. Also `lucent bench fit`.

use crate::fit::{self, FreeParameter, FreeSpec, Measurement, Objective, Problem, SearchBounds};
use crate::job::{FitJob, FitJobError, MeasuredSlice};
use crate::optics::recipe::{Overrides, Recipe};
use anyhow::{Context, Result};
use clap::Args;
use std::path::{Path, PathBuf};

#[derive(Debug, Args)]
pub struct FitArgs {
    /// Recipe (TOML) with the start values.
    #[arg(long)]
    pub recipe: PathBuf,
    /// Weight percentage for a recipe that leaves it unknown (the start value).
    #[arg(long)]
    pub weight_percent: Option<f64>,
    /// Measured slices FILE[:THETA_I/THETA_O] or FILE:THETA_I/PHI_I/THETA_O/PHI_O (degrees; φi 0°, φo 180° by default;
    /// without angles, from the file's sidecar FILE.json or summary.json "config").
    #[arg(long, required = true, num_args = 1..)]
    pub measured: Vec<MeasuredSlice>,
    /// Pixel size of the measured slices in mm (else from their sidecar JSON).
    #[arg(long)]
    pub measured_pixel_mm: Option<f64>,
    /// Free parameters, comma-separated: weight_percent, diameter_um, real_part_n (NAME@K for particle type K).
    #[arg(long, required = true, value_delimiter = ',')]
    pub free: Vec<FreeSpec>,
    /// What the fit minimises.
    #[arg(long, value_parser = super::choices::named::<Objective>(), default_value = "sum")]
    pub objective: Objective,
    /// Wavelength of the measurements in nm (`--wavelength` is the older spelling).
    #[arg(long = "wavelength-nm", alias = "wavelength", default_value_t = 550.0)]
    pub wavelength: f64,
    #[command(flatten)]
    pub beam: super::groups::BeamArgs,
    /// Relative uncertainty of each measured slice (a scale error; the lab states 5 %).
    #[arg(long, default_value_t = crate::job::DEFAULT_MEASURED_REL_SD)]
    pub measured_rel_sd: f64,
    /// Mask of the msre objective: measured pixels above this fraction of the maximum.
    #[arg(long, default_value_t = crate::job::DEFAULT_THRESHOLD)]
    pub threshold: f64,
    /// Target relative error of each simulated slice sum at the final points (sets the path count by a pilot run).
    #[arg(long, default_value_t = crate::job::DEFAULT_FIT_REL_ERROR)]
    pub rel_error: f64,
    /// Light paths per configuration and evaluation instead of the pilot run.
    #[arg(long)]
    pub paths: Option<u64>,
    /// Time cap of the pilot run per configuration, seconds.
    #[arg(long, default_value_t = 60.0)]
    pub pilot_time_s: f64,
    /// Search bounds LO:HI per free parameter, comma-separated (default start/10 … start·10; n: ÷/× 1.2).
    #[arg(long)]
    pub bounds: Option<SearchBounds>,
    /// Slab thickness in mm (default: the recipe's).
    #[arg(long)]
    pub thickness_mm: Option<f64>,
    /// Seed of the common random numbers.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    #[arg(long, default_value = "lucent-out/fit")]
    pub out: PathBuf,
    /// No progress lines.
    #[arg(long)]
    pub quiet: bool,
}

/// `lucent fit`: the job of the flags ([`FitJob::run`]), then its summary
/// on stdout; a fit the data cannot pin down fails after it is written.
pub fn run(a: FitArgs) -> Result<()> {
    let done = FitJob::from(&a).run(&crate::job::Context::default()).map_err(job_error)?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(done.finished()?)
}

/// A fit job's error for the command: a fit stopped by Ctrl-C as the
/// [`crate::fault::Interrupted`] it is (its exit code), others as they are.
pub fn job_error(e: FitJobError) -> anyhow::Error {
    match e.into_parts() {
        Ok(e) => e.into(),
        Err(interrupted) => interrupted.into(),
    }
}

/// `lucent bench fit`: a one-parameter weight-percentage fit of IOL1068-09
/// (PDMS) over three configurations (45/0, 0/45, 45/15; the lab's sensor,
/// 117 pixels of 0.1029 mm) to synthetic measurements made at 0.425 wt-%
/// with 5 % noise, starting from the recipe's 0.65. Reports the wall time
/// of the fit (the measurements' simulation is not timed) and the result.
pub fn bench(rel_error: f64, out: Option<PathBuf>) -> Result<()> {
    let path = PathBuf::from("fixtures/samples/IOL1068-09.toml");
    let recipe = Recipe::load(&path, Overrides::default()).context("run the bench from the repository root")?;
    let truth = recipe.with_weight_percent(0, 0.425)?;
    let configs = [(45.0, 0.0, 0.0, 180.0), (0.0, 0.0, 45.0, 180.0), (45.0, 0.0, 15.0, 180.0)];
    eprintln!("simulating the synthetic measurements (0.425 wt-%, 5 % noise; not timed) …");
    let grids = fit::synthetic_slices(&truth, 550.0, &configs, (117, 0.1029), 150_000, 77, 0.05)?;
    let measurements = grids
        .into_iter()
        .zip(configs)
        .map(|(g, c)| Measurement::new(Path::new(&format!("synthetic {}/{}", c.0, c.2)), g, c))
        .collect::<Result<Vec<_>, _>>()?;
    let mut problem = Problem::new(recipe, 550.0, vec![FreeParameter::weight_percent(0)], measurements)?;
    problem.budget.rel_error = rel_error;
    let result = fit::fit(&problem, |e| eprintln!("{e}"))?;
    if let Some(dir) = out {
        crate::job::write_fit_outputs(&dir, &problem, &result)?;
    }
    let p = &result.parameters[0];
    let json = serde_json::json!({
        "benchmark": "lucent fit: weight_percent of IOL1068-09 (PDMS) over 3 configurations (45/0, 0/45, 45/15), 117 × 117 px of 0.1029 mm, 550 nm, sum objective",
        "truth": 0.425,
        "start": p.start,
        "value": p.value,
        "std_error": p.std_error,
        "interval_95": p.interval_95,
        "identifiable": result.identifiable,
        "evaluations": result.evaluations,
        "paths_total": result.paths_total,
        "paths_per_evaluation": result.configurations.iter().map(|c| c.paths_per_evaluation).collect::<Vec<_>>(),
        "target_rel_error": rel_error,
        "threads": rayon::current_num_threads(),
        "wall_s": result.wall_s,
        "target_wall_s": 300.0,
    });
    println!("{}", serde_json::to_string_pretty(&json)?);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measured_specs() {
        let m = |t: &str| t.parse::<MeasuredSlice>();
        let a = m("m.exr:45/0").unwrap();
        assert_eq!((a.path, a.angles.map(|a| a.degrees())), (PathBuf::from("m.exr"), Some((45.0, 0.0, 0.0, 180.0))));
        let a = m("dir:x/m.exr:45/10/0/190").unwrap();
        assert_eq!(
            (a.path, a.angles.map(|a| a.degrees())),
            (PathBuf::from("dir:x/m.exr"), Some((45.0, 10.0, 0.0, 190.0)))
        );
        assert_eq!(m("m.exr").unwrap().angles, None);
        assert!(m("m.exr:45/x").is_err());
        assert!(m("m.exr:45/0/1").is_err());
        let b: SearchBounds = "0.1:1".parse().unwrap();
        assert_eq!(b.0, vec![fit::SearchRange { lo: 0.1, hi: 1.0 }]);
        assert!("0.1-1".parse::<SearchBounds>().is_err());
    }
}
