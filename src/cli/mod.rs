//! The `lucent` command line: argument parsing and orchestration only; the
//! work is done by the library modules. The definitions of the command line
//! are in [`args`] (each command's own arguments in its module); this module
//! runs a parsed [`Cli`] ([`run()`]) and the commands that have no module of
//! their own (`optics`, `mie`, `bench`).

// The doc comments of the argument structs are clap's `--help` text, which
// prints them verbatim: `[render]` there names a scene file's TOML table
// and `<scene>` a placeholder, not an intra-doc link or an HTML tag.
#![allow(rustdoc::broken_intra_doc_links, rustdoc::invalid_html_tags)]

pub mod args;
pub use args::{BenchCommand, Cli, Command, MieArgs, OpticsArgs};
pub mod bssrdf;
pub mod camera;
pub mod choices;
pub mod colour;
pub mod common;
pub use common::{count_in, optics_error, parse_grid};
pub mod compare;
pub mod env_fit;
pub mod fit;
pub mod groups;
/// Ctrl-C handling lives below the commands (library stages install it too).
pub use crate::interrupt;
pub mod job_run;
pub mod jobs;
pub mod raw_clip;
pub mod render;
pub mod report;
pub mod run;
pub mod shard;
pub mod surface;
pub mod synth;

use crate::job::guard::FileRoles;
use crate::optics::bulk::{self, OpticalSpectrum};
use crate::optics::mie::{self, Coefficients, Efficiencies};
use crate::optics::recipe::Overrides;
use anyhow::{anyhow, bail, Context, Result};
use lucent_colour::WavelengthGrid;
use num_complex::Complex64;
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The CPUs a batch system gave this process, with the variable that says
/// so: `LUCENT_THREADS` (set by the Kubernetes Job `lucent run --emit k8s`
/// writes, from the pod's CPU request), else Slurm's `SLURM_CPUS_PER_TASK`
/// (set when the job asks for `--cpus-per-task`). A value that is not a
/// whole number in 1 … [`common::MAX_THREADS`] is ignored.
pub fn allocated_threads(var: impl Fn(&str) -> Option<String>) -> Option<(usize, &'static str)> {
    crate::job::allocated_threads(var)
}

/// Runs the parsed command.
pub fn run(cli: Cli) -> Result<()> {
    check_outputs_are_not_inputs(&cli.command)?;
    let folder = output_folder(&cli.command);
    common::writing_into(folder, || {
        jobs::validate(&cli.command)?;
        dispatch(cli)
    })
}

/// The files a command that is not a job's reads, writes and writes
/// beside them under derived names (sidecars); a job's are
/// [`Job::file_roles`](crate::job::Job::file_roles).
fn file_roles(command: &Command) -> FileRoles {
    let json = |p: &Path| p.with_extension("json");
    let sibling = camera::sibling;
    match command {
        Command::Raw(camera::RawCommand::Decode(a)) => FileRoles::new(
            vec![a.input.clone()],
            std::iter::once(a.output.clone()).chain(a.preview.clone()).collect(),
            vec![json(&a.output)],
        ),
        Command::Undistort(a) => {
            FileRoles::new(vec![a.camera.clone(), a.input.clone()], vec![a.output.clone()], vec![json(&a.output)])
        }
        Command::Env(camera::EnvCommand::Convert(a)) => {
            FileRoles::new(vec![a.input.clone()], vec![a.output.clone()], vec![])
        }
        Command::Env(camera::EnvCommand::View(a)) => {
            FileRoles::new(vec![a.input.clone()], vec![a.out.clone()], vec![sibling(&a.out, ".json")])
        }
        _ => FileRoles::default(),
    }
}

/// A command must not write over a file it reads (`env view map.exr --out
/// map.exr`, a sidecar `camera.json` beside `--camera camera.json`), nor
/// write two of its outputs to one path, nor replace a file under a
/// sidecar's name that is not from an earlier run (its main output is not
/// there: `photo.json` of the user's beside `raw decode … photo.exr`):
/// refused before any work ([`FileRoles::check`]; a job's by [`Job::check_files`](crate::job::Job::check_files)).
fn check_outputs_are_not_inputs(command: &Command) -> Result<()> {
    match jobs::job_of(command) {
        Some(job) => job.check_files()?,
        None => file_roles(command).check()?,
    }
    Ok(())
}

/// The output folder (not file) a command writes into, if it has one.
fn output_folder(command: &Command) -> Option<PathBuf> {
    Some(match command {
        Command::Optics(a) => return crate::job::optics::output_folder(a.out.as_deref(), a.json),
        Command::Bssrdf(a) => match &a.command {
            Some(bssrdf::BssrdfCommand::Compare(c)) => c.out.clone(),
            None => a.run.out.clone(),
        },
        Command::Render(a) => a.out.clone(),
        Command::Surface(surface::SurfaceCommand::Fit(a)) => a.out.clone(),
        Command::Colour(colour::ColourCommand::Calibrate(a)) => a.out.clone(),
        Command::Env(camera::EnvCommand::FitScale(a)) => a.out.clone(),
        Command::Env(camera::EnvCommand::Brackets(a)) => a.out_dir.clone(),
        Command::Compare(a) => a.out.clone(),
        Command::Fit(a) => a.out.clone(),
        Command::Bench(BenchCommand::Fit { out: Some(out), .. }) => out.clone(),
        Command::Merge(a) => a.out.clone(),
        _ => return None,
    })
}

fn dispatch(cli: Cli) -> Result<()> {
    match cli.command {
        Command::Optics(a) => optics(a),
        Command::Mie(a) => mie(a),
        Command::Bssrdf(a) => bssrdf::run(a),
        Command::Render(a) => render::run(a),
        Command::Surface(c) => surface::run(c),
        Command::Bench(b) => bench(b),
        Command::Colour(c) => colour::run(c),
        Command::Raw(c) => camera::run_raw(c),
        Command::Calibrate(a) => camera::calibrate(a),
        Command::Undistort(a) => camera::undistort(a),
        Command::Pose(a) => camera::pose(a),
        Command::Env(c) => camera::run_env(c),
        Command::Compare(a) => compare::run(a),
        Command::Run(a) => run::run(a),
        Command::Report(a) => report::run(a),
        Command::Fit(a) => fit::run(a),
        Command::Synth(c) => synth::run(c),
        Command::Merge(a) => merge(a),
        Command::Job(c) => job_run::run_command(c),
    }
}

/// Runs `lucent merge` ([`shard::merge`]).
fn merge(a: shard::MergeArgs) -> Result<()> {
    shard::merge(&a.shards, &a.out)
}

/// Parses a refractive index "1.5", "1.5+0.01i" or "1.5+1e-3j" (spaces
/// ignored) with num-complex's `FromStr`.
pub fn parse_index(flag: &str, text: &str) -> Result<Complex64> {
    let t = text.trim().replace(' ', "");
    let value: Complex64 =
        t.parse().map_err(|_| anyhow!("{flag} {text:?}: expected N or N+Ki, e.g. 1.5 or 1.5+0.01i"))?;
    if !(value.re.is_finite() && value.im.is_finite()) || value.re <= 0.0 {
        bail!("{flag} {text:?}: the real part must be a positive finite number");
    }
    if value.im < 0.0 {
        bail!(
            "{flag} {text:?}: the imaginary part must be ≥ 0 (lucent writes an absorbing index as n+κi; miepython's n−ki means the same as n+ki here)"
        );
    }
    Ok(value)
}

/// `lucent optics` ([`crate::job::OpticsJob::run`]: the properties, or
/// with `--uncertainty` the propagation of the recipes' uncertain inputs),
/// its summary on stdout.
fn optics(a: OpticsArgs) -> Result<()> {
    let job = crate::job::OpticsJob::from(&a);
    let done = job.run(&crate::job::Context::default()).map_err(optics_error)?;
    for line in done.summary() {
        println!("{line}");
    }
    Ok(())
}

/// Efficiencies of one sphere, for either form of the `mie` arguments.
pub fn mie_efficiencies(a: &MieArgs) -> Result<Efficiencies> {
    if let Some(x) = a.size_parameter {
        let m_text = a.relative_index.as_deref().ok_or_else(|| anyhow!("--size-parameter needs --relative-index"))?;
        let m = parse_index("--relative-index", m_text)?;
        if !(x.is_finite() && x > 0.0) {
            bail!("--size-parameter {x}: must be a positive finite number");
        }
        return Ok(mie::efficiencies(m, x)?);
    }
    let (Some(r_um), Some(w_nm), Some(np_text)) = (a.radius_um, a.wavelength_nm, a.particle_index.as_deref()) else {
        bail!("give either --size-parameter X --relative-index M, or --radius-um R --wavelength-nm L --particle-index N [--host-index N]");
    };
    if !(r_um.is_finite() && r_um > 0.0) {
        bail!("--radius-um {r_um}: must be a positive finite number");
    }
    if !(w_nm.is_finite() && w_nm > 0.0) {
        bail!("--wavelength-nm {w_nm}: must be a positive finite number");
    }
    let np = parse_index("--particle-index", np_text)?;
    let nh = match a.host_index.as_deref() {
        Some(t) => parse_index("--host-index", t)?,
        None => Complex64::new(1.0, 0.0),
    };
    // Absorbing host: Frisvad et al.'s qext, qsca (with F(α)) and the power
    // absorbed inside the sphere as qabs (see mie::efficiencies_in_host).
    Ok(mie::efficiencies_in_host(np, nh, w_nm * 1e-9, r_um * 1e-6)?)
}

fn mie(a: MieArgs) -> Result<()> {
    let q = mie_efficiencies(&a)?;
    if let Some(nh) = a.host_index.as_deref().map(|t| parse_index("--host-index", t)).transpose()?
        && nh.im > 0.0
    {
        eprintln!(
                "note: absorbing host: qext and qsca are the apparent (far-field) efficiencies of Frisvad et al. 2007, qsca with the attenuation factor F(α); qabs is the power absorbed inside the sphere, so qext − qsca ≠ qabs (qext − qsca also counts the host absorption the sphere displaces)"
            );
    }
    println!("{}", serde_json::to_string_pretty(&q)?);
    Ok(())
}

/// Reads (m, x) cases from a reference CSV with columns m_re, m_im, x
/// (others ignored; `#` lines are comments).
pub fn read_mie_cases(path: &Path) -> Result<Vec<(Complex64, f64)>> {
    #[derive(serde::Deserialize)]
    struct Case {
        m_re: f64,
        m_im: f64,
        x: f64,
    }
    let mut reader = csv::ReaderBuilder::new()
        .comment(Some(b'#'))
        .trim(csv::Trim::All)
        .from_path(path)
        .with_context(|| format!("{}: cannot read cases", path.display()))?;
    let header = reader.headers().with_context(|| format!("{}: cannot read cases", path.display()))?;
    if header.is_empty() {
        bail!("{}: empty file", path.display());
    }
    for name in ["m_re", "m_im", "x"] {
        if !header.iter().any(|h| h == name) {
            bail!("{}: no column {name:?}", path.display());
        }
    }
    let mut cases = Vec::new();
    for (k, row) in reader.deserialize::<Case>().enumerate() {
        let c = row.with_context(|| format!("{}: data row {}", path.display(), k + 1))?;
        cases.push((Complex64::new(c.m_re, c.m_im), c.x));
    }
    if cases.is_empty() {
        bail!("{}: no cases (a header only): nothing to time", path.display());
    }
    Ok(cases)
}

/// A default input of `bench` (a path relative to the repository): as given
/// if it exists, else under the repository this binary was built from, so
/// that `lucent bench …` works from any folder.
fn repository_file(p: &Path) -> PathBuf {
    let in_repo = Path::new(env!("CARGO_MANIFEST_DIR")).join(p);
    if p.exists() || p.is_absolute() || !in_repo.exists() {
        p.to_path_buf()
    } else {
        in_repo
    }
}

fn bench(b: BenchCommand) -> Result<()> {
    match b {
        BenchCommand::Mie { cases, repeats } => {
            let cases = read_mie_cases(&repository_file(&cases))?;
            let repeats = repeats.max(1);
            let run = |cases: &[(Complex64, f64)], c: &mut Coefficients| -> Result<f64> {
                let mut checksum = 0.0;
                for &(m, x) in cases {
                    c.recompute(m, Complex64::new(x, 0.0))?;
                    checksum += c.efficiencies(x).qsca;
                }
                Ok(checksum)
            };
            // Each repeat is timed on its own and the best is reported, as
            // tools/bench_miepython.py does for miepython (this machine's speed
            // drifts; the minimum is the least disturbed run). A repeat makes
            // PASSES passes over the cases, so the all-cores timing is not
            // dominated by waking rayon's threads (one pass takes ~1 ms).
            const PASSES: usize = 8;
            let mut c = Coefficients::new();
            run(&cases, &mut c)?; // warm-up
            let mut one = f64::INFINITY;
            let mut all = f64::INFINITY;
            let mut checksum = 0.0;
            let chunks: Vec<&[(Complex64, f64)]> = cases.chunks(8).collect();
            for _ in 0..repeats {
                let start = Instant::now();
                for _ in 0..PASSES {
                    checksum += run(&cases, &mut c)?;
                }
                one = one.min(start.elapsed().as_secs_f64());
                // All cores: chunks of 8 cases spread over rayon's threads, one buffer each.
                let start = Instant::now();
                let parts: Vec<f64> = (0..PASSES * chunks.len())
                    .into_par_iter()
                    .map_init(Coefficients::new, |c, i| run(chunks[i % chunks.len()], c))
                    .collect::<Result<_>>()?;
                all = all.min(start.elapsed().as_secs_f64());
                std::hint::black_box(parts);
            }
            let n = (cases.len() * PASSES) as f64;
            let json = serde_json::json!({
                "benchmark": "mie efficiencies (qext, qsca, qback, g)",
                "cases": cases.len(),
                "repeats": repeats,
                "statistic": format!("best of the repeats, each {PASSES} passes over the cases"),
                "seconds_per_sphere": one / n,
                "spheres_per_second": n / one,
                "threads": rayon::current_num_threads(),
                "seconds_per_sphere_all_cores": all / n,
                "spheres_per_second_all_cores": n / all,
                "checksum": checksum,
            });
            println!("{}", serde_json::to_string_pretty(&json)?);
        }
        BenchCommand::Bssrdf { rel_error, time_s } => bssrdf::bench(rel_error, time_s)?,
        BenchCommand::Surface { paths } => bssrdf::bench_surface(paths)?,
        BenchCommand::Compare { megapixels, repeats } => compare::bench(megapixels, repeats)?,
        BenchCommand::Fit { rel_error, out } => fit::bench(rel_error, out)?,
        BenchCommand::Shard { scene, size, spp, shards, repeats, lucent, megapixels, nodes, projected_spp } => {
            shard::bench(
                &repository_file(&scene),
                &size,
                spp,
                shards,
                repeats,
                lucent,
                shard::Projection { megapixels, nodes, spp: projected_spp },
            )?
        }
        BenchCommand::Render { scene, time_s: Some(t), .. } => {
            common::check_time_s(t)?;
            render::bench_estimators(&repository_file(&scene), t)?
        }
        BenchCommand::Render { scene, reference, spp, time_s: None } => {
            let spps: Vec<u32> = spp
                .split(',')
                .map(|s| s.trim().parse::<u32>().with_context(|| format!("--spp {spp:?}: {s:?} is not a count")))
                .collect::<Result<_>>()?;
            render::bench(&repository_file(&scene), &repository_file(&reference), &spps)?
        }
        BenchCommand::Optics { samples, repeats, weight_percent } => {
            let ctx = crate::job::Context::default();
            let paths = crate::job::optics::collect_recipe_paths(&[repository_file(&samples)], &ctx)?;
            let recipes = crate::job::optics::load_recipes(
                &paths,
                Overrides { weight_percent: Some(weight_percent) },
                false,
                &ctx,
            )?;
            let grid = WavelengthGrid::visible();
            let options = bulk::Options::default();
            let mut times = Vec::new();
            for _ in 0..repeats.max(1) {
                let start = Instant::now();
                let spectra: Vec<OpticalSpectrum> =
                    recipes.par_iter().map(|r| bulk::compute(r, &grid, &options)).collect::<Result<_, _>>()?;
                times.push(start.elapsed().as_secs_f64());
                std::hint::black_box(spectra);
            }
            times.sort_by(f64::total_cmp);
            let json = serde_json::json!({
                "benchmark": "full optical-property table with 4096-entry phase tables",
                "recipes": recipes.len(),
                "wavelengths": grid.len(),
                "threads": rayon::current_num_threads(),
                "median_seconds": times[times.len() / 2],
                "min_seconds": times[0],
            });
            println!("{}", serde_json::to_string_pretty(&json)?);
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_parsing() {
        assert_eq!(parse_index("f", "1.5").unwrap(), Complex64::new(1.5, 0.0));
        assert_eq!(parse_index("f", "1.5+0.01i").unwrap(), Complex64::new(1.5, 0.01));
        assert_eq!(parse_index("f", "1.5+1e-3j").unwrap(), Complex64::new(1.5, 1e-3));
        assert_eq!(parse_index("f", "1.5e0+1E-3i").unwrap(), Complex64::new(1.5, 1e-3));
        assert!(parse_index("f", "1.5-0.01i").unwrap_err().to_string().contains("≥ 0"));
        assert!(parse_index("f", "abc").is_err());
        assert!(parse_index("f", "-1.5").is_err());
        assert!(parse_index("f", "nan").is_err());
    }

    #[test]
    fn grid_parsing() {
        assert_eq!(parse_grid("380:780:10").unwrap().len(), 41);
        assert!(parse_grid("380:780").is_err());
        assert!(parse_grid("380:x:10").is_err());
        assert!(parse_grid("780:380:10").is_err());
    }
}
