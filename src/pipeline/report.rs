//! The run's report: `report/index.html`, one self-contained page (inline
//! style, no script, no network; its images copied into `report/img/` and
//! referenced relatively), and `report/metrics.json` with every number the
//! stages wrote. Both are built from the stage folders as they are on disk
//! (a stage that did not run this time contributes its earlier result, with
//! its manifest).
//!
//! Per sample: the optical-property table (μs, μa, μt in 1/m, g, n_bulk at
//! every 50 nm of the grid) with the spectra and phase-function plots; the
//! BSSRDF slices (sum ± standard error in 1/(m² sr)) and, where measured,
//! the mean squared relative error and the sums measured vs simulated with
//! their panels; the photo | render | difference triplet with RMSE and SSIM;
//! the environment scale. Then the calibration summary (intrinsics,
//! distortion, RMS reprojection error), the ΔE2000 table of every colour
//! calibration, and the manifest (inputs with SHA-256, commands, versions,
//! seed, wall times).
//!
//! Every stage file is read into the type its writer serialises, so each
//! format is defined once: [`crate::optics::output::OpticalProperties`],
//! [`crate::bssrdf::Summary`] and [`crate::bssrdf::Comparison`],
//! [`crate::envfit::FitReport`], [`crate::scene::RenderReport`],
//! [`crate::compare::Report`], `lucent_calib`'s `Calibration` (camera.json)
//! and `SceneDescription` (scene.json), [`crate::ccm_file::CcmFile`] and
//! [`Manifest`]. A file that is absent contributes nothing (its stage has not
//! run); one that is there but not in its format stops the report with
//! [`ReportError`] naming the file and the field. Fields added to a format
//! later default when older files are read (see each type).
//!
//! Each stage's files are found through the struct that names them beside
//! their writer (e.g. [`crate::bssrdf::SliceFiles`],
//! [`crate::compare::CompareFiles`], [`super::StageFiles`]), and each stage
//! contributes its own section from them; [`write()`] assembles the sections.

use super::project::{Project, SampleSection};
use super::{CompareDirs, Manifest, Stage, StageFiles, Status};
use crate::bssrdf::{ComparisonFiles, SliceFiles};
use crate::ccm_file::ColourFiles;
use crate::compare::CompareFiles;
use crate::envfit::EnvScaleFiles;
use crate::fit::report::FitFiles;
use crate::optics::output::{OpticalProperties, OpticsFiles, SampleFiles};
use crate::scene::RenderFiles;
use lucent_calib::calibrate::CalibrationFiles;
use lucent_calib::scene::PoseFiles;
use serde::de::DeserializeOwned;
use serde::Serialize;
use serde_json::{json, Value};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use thiserror::Error;

/// The report could not be written, or a stage's file it reads is not in
/// the format lucent writes (every variant names the file; a format error
/// names the field, e.g. "missing field `sum` at line 4 column 1").
#[derive(Debug, Error)]
pub enum ReportError {
    #[error("{to}: cannot copy {from}: {source}")]
    Copy { from: PathBuf, to: PathBuf, source: std::io::Error },
    #[error(transparent)]
    Write(#[from] crate::io::WriteError),
    #[error("{path}: cannot read {what}: {source}")]
    Read { path: PathBuf, what: &'static str, source: std::io::Error },
    #[error("{path}: not {what} as lucent writes it: {source}")]
    Format { path: PathBuf, what: &'static str, source: serde_json::Error },
    #[error(transparent)]
    Optics(#[from] crate::optics::output::OpticalPropertiesError),
    #[error(transparent)]
    Ccm(#[from] crate::ccm_file::CcmFileError),
    /// `[[colour]] truth` (the message names the file).
    #[error(transparent)]
    ColourTruth(#[from] crate::synth::SynthError),
    /// `[pose] truth` is not a scene file (the message names the file and key).
    #[error(transparent)]
    PoseTruth(Box<crate::scene::SceneFileError>),
}

/// HTML-escapes text.
pub fn esc(t: &str) -> String {
    t.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Distance between two camera-to-world poses' centres (mm, the matrices in
/// metres) and the angle of the rotation between them (degrees).
fn pose_error(truth: &[[f64; 4]; 4], rec: &[[f64; 4]; 4]) -> (f64, f64) {
    let d: f64 = (0..3).map(|r| (truth[r][3] - rec[r][3]).powi(2)).sum::<f64>().sqrt();
    // trace(Rtᵀ Rr) = 1 + 2 cos θ
    let trace: f64 = (0..3).map(|i| (0..3).map(|k| truth[k][i] * rec[k][i]).sum::<f64>()).sum();
    let angle = ((trace - 1.0) / 2.0).clamp(-1.0, 1.0).acos().to_degrees();
    (1000.0 * d, angle)
}

/// A stage's JSON file `p` read into the type its writer serialises
/// (`what` names the file kind in messages): `None` when the file does not
/// exist (the stage has not run), an error naming the file and the field
/// when it exists but does not hold that type.
pub fn read_json<T: DeserializeOwned>(p: &Path, what: &'static str) -> Result<Option<T>, ReportError> {
    let text = match crate::io::read_text(p) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(source) => return Err(ReportError::Read { path: p.to_path_buf(), what, source }),
    };
    serde_json::from_str(&text).map(Some).map_err(|source| ReportError::Format { path: p.to_path_buf(), what, source })
}

/// A typed value as JSON for metrics.json.
fn to_value<T: Serialize>(v: &T) -> Value {
    serde_json::to_value(v).unwrap_or(Value::Null)
}

/// Drops arrays of more than `max` numbers (phase tables, corner lists)
/// so metrics.json stays readable; everything else is kept.
fn trim(v: &Value, max: usize) -> Value {
    match v {
        Value::Array(a) if a.len() > max && a.iter().all(|x| x.is_number()) => {
            json!(format!("({} numbers, see the stage folder)", a.len()))
        }
        Value::Array(a) => Value::Array(a.iter().map(|x| trim(x, max)).collect()),
        Value::Object(o) => Value::Object(o.iter().map(|(k, x)| (k.clone(), trim(x, max))).collect()),
        x => x.clone(),
    }
}

/// A number of a stage's file for a table cell; non-finite (written as
/// `null`, read back as NaN) shows as "—".
fn num(v: f64, fmt: fn(f64) -> String) -> String {
    if v.is_finite() {
        fmt(v)
    } else {
        "—".into()
    }
}

fn e4(x: f64) -> String {
    format!("{x:.4e}")
}
fn e3(x: f64) -> String {
    format!("{x:.3e}")
}
fn f3(x: f64) -> String {
    format!("{x:.3}")
}
fn f4(x: f64) -> String {
    format!("{x:.4}")
}

struct Page {
    html: String,
    img_dir: PathBuf,
    copied: usize,
}

impl Page {
    /// Copies `src` into img/ and returns an <img> tag, or a note when absent.
    fn img(&mut self, src: &Path, alt: &str) -> Result<String, ReportError> {
        if !src.is_file() {
            return Ok(String::new());
        }
        self.copied += 1;
        let ext = src.extension().map(|e| e.to_string_lossy().into_owned()).unwrap_or_else(|| "png".into());
        let name = format!("{:03}-{}.{ext}", self.copied, slug(alt));
        let dst = self.img_dir.join(&name);
        std::fs::create_dir_all(&self.img_dir)
            .and_then(|_| std::fs::copy(src, &dst))
            .map_err(|source| ReportError::Copy { from: src.to_path_buf(), to: dst.clone(), source })?;
        Ok(format!(
            "<figure><img src=\"img/{name}\" alt=\"{}\"><figcaption>{}</figcaption></figure>",
            esc(alt),
            esc(alt)
        ))
    }
}

/// A section's numbers for metrics.json.
type Metrics = serde_json::Map<String, Value>;

/// A fitted parameter beside its known truth: (name, fitted, 95 % interval, truth).
type FittedVsTruth = (String, Option<f64>, Option<[f64; 2]>, f64);

fn slug(t: &str) -> String {
    let s: String = t.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect();
    s.split('-').filter(|p| !p.is_empty()).collect::<Vec<_>>().join("-").chars().take(48).collect()
}

fn table(head: &[&str], rows: &[Vec<String>]) -> String {
    let mut t = String::from("<table><thead><tr>");
    for h in head {
        let _ = write!(t, "<th>{}</th>", esc(h));
    }
    t.push_str("</tr></thead><tbody>");
    for r in rows {
        t.push_str("<tr>");
        for c in r {
            let _ = write!(t, "<td>{}</td>", esc(c));
        }
        t.push_str("</tr>");
    }
    t.push_str("</tbody></table>");
    t
}

/// The optics stage's spectra (one sample writes an object, several an
/// array), none when the stage has not run.
fn spectra(files: &OpticsFiles) -> Result<Vec<OpticalProperties>, ReportError> {
    if !files.json.exists() {
        return Ok(vec![]);
    }
    Ok(crate::optics::output::read_optical_properties(&files.json)?)
}

/// The folder of `stage` under `out` when it is in this run's plan (ran or
/// up to date); else a path that does not exist, so a folder left by an
/// earlier project, or an earlier version of this one, is not reported.
/// Without statuses (`done` empty: a report of a folder, not of a run) every
/// stage's folder.
fn stage_folder(out: &Path, done: &[(Stage, Status)], stage: Stage) -> PathBuf {
    if done.is_empty() {
        return out.join(stage.name());
    }
    match done.iter().find(|(s, _)| *s == stage).map(|(_, st)| st) {
        Some(Status::Ran { .. } | Status::UpToDate) => out.join(stage.name()),
        _ => out.join(format!(".{}.not-in-this-plan", stage.name())),
    }
}

/// The files of the report stage in its folder, each name spelled here
/// once: the page (`html`) and every number the stages wrote (`metrics`).
/// Written by [`write()`], read by `lucent run` (the project a folder holds).
///
/// ```
/// use lucent::pipeline::report::ReportFiles;
/// let f = ReportFiles::in_dir(std::path::Path::new("out/report"));
/// assert_eq!(f.html, std::path::Path::new("out/report/index.html"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReportFiles {
    pub html: PathBuf,
    pub metrics: PathBuf,
}

impl ReportFiles {
    /// The file names.
    pub const NAMES: [&'static str; 2] = ["index.html", "metrics.json"];

    /// The files of the report folder `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [html, metrics] = Self::NAMES.map(|n| dir.join(n));
        Self { html, metrics }
    }
}

/// Writes index.html and metrics.json into `dir` (the report stage's
/// folder): the answer per sample, the stages, each sample's sections, the
/// calibration sections and the manifests, each from its stage's files.
pub fn write(project: &Project, out: &Path, dir: &Path, done: &[(Stage, Status)]) -> Result<(), ReportError> {
    let mut page = Page { html: String::new(), img_dir: dir.join("img"), copied: 0 };
    let folder = |s: Stage| stage_folder(out, done, s);
    let mut manifests: Vec<(Stage, Manifest)> = Vec::new();
    for s in Stage::ALL {
        if let Some(m) = read_json(&StageFiles::in_dir(&folder(s)).manifest, "a stage manifest")? {
            manifests.push((s, m));
        }
    }
    let mut metrics = Metrics::new();
    page.html = project_heading(project, &mut metrics);
    let stages = stages_section(done, &manifests, &mut metrics);
    // The answer, per sample, before any detail.
    for smp in &project.file.sample {
        let a = answer(&mut page, &CompareDirs::in_dir(&folder(Stage::Compare).join(&smp.name)), smp)?;
        page.html.push_str(&a);
    }
    page.html.push_str(&stages);
    let all_spectra = spectra(&OpticsFiles::in_dir(&folder(Stage::Optics)))?;
    let mut samples = Metrics::new();
    for smp in &project.file.sample {
        let (h, sj) = sample_sections(&mut page, project, smp, &all_spectra, &folder)?;
        page.html.push_str(&h);
        samples.insert(smp.name.clone(), Value::Object(sj));
    }
    metrics.insert("samples".into(), Value::Object(samples));
    let calibration = calibration_sections(&mut page, project, &folder, &mut metrics)?;
    page.html.push_str(&calibration);
    page.html.push_str(&manifest_section(&manifests, &mut metrics));
    let html = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{} — lucent report</title>\n<style>{STYLE}</style></head>\n<body>{}</body></html>\n",
        esc(&project.name),
        page.html
    );
    let files = ReportFiles::in_dir(dir);
    crate::io::write_json(&files.metrics, &Value::Object(metrics))?;
    crate::io::write_atomic(&files.html, html.as_bytes())?;
    Ok(())
}

/// The page's heading (project, version, project file, seed), the same in
/// metrics.json.
fn project_heading(project: &Project, metrics: &mut Metrics) -> String {
    metrics.insert("project".into(), json!(project.name));
    metrics.insert("project_file".into(), json!(project.path.display().to_string()));
    metrics.insert("lucent_version".into(), json!(env!("CARGO_PKG_VERSION")));
    metrics.insert("seed".into(), json!(project.seed));
    format!(
        "<h1>{}</h1><p class=\"meta\">lucent {} · project file <code>{}</code> · seed {}</p>",
        esc(&project.name),
        env!("CARGO_PKG_VERSION"),
        esc(&project.path.display().to_string()),
        project.seed
    )
}

/// A sample's details, one section per stage from that stage's files under
/// `folder(stage)` (optics, bssrdf, fit, env-scale, render, compare; without
/// a comparison the render's picture), with their numbers for metrics.json.
fn sample_sections(
    page: &mut Page,
    project: &Project,
    smp: &SampleSection,
    all_spectra: &[OpticalProperties],
    folder: &impl Fn(Stage) -> PathBuf,
) -> Result<(String, Metrics), ReportError> {
    let mut sj = Metrics::new();
    let sample_dir = |s: Stage| folder(s).join(&smp.name);
    let mut h =
        format!("<section id=\"sample-{}\"><h2>Sample {}: details per stage</h2>", slug(&smp.name), esc(&smp.name));
    h.push_str(&optics_section(page, smp, all_spectra, &folder(Stage::Optics), &mut sj)?);
    h.push_str(&bssrdf_section(page, smp, &project.bssrdf_configs, &sample_dir(Stage::Bssrdf), &mut sj)?);
    let (fit, fitted_vs_truth) = fit_section(page, smp, &FitFiles::in_dir(&sample_dir(Stage::Fit)), &mut sj)?;
    h.push_str(&fit);
    h.push_str(&env_scale_section(&EnvScaleFiles::in_dir(&sample_dir(Stage::EnvScale)), &mut sj)?);
    let rdir = sample_dir(Stage::Render);
    h.push_str(&render_section(&RenderFiles::in_dir(&rdir), &mut sj)?);
    let dirs = CompareDirs::in_dir(&sample_dir(Stage::Compare));
    match compare_section(smp, &dirs, &fitted_vs_truth, &mut sj)? {
        Some(c) => h.push_str(&c),
        None if rdir.is_dir() => {
            h.push_str(&page.img(&RenderFiles::in_dir(&rdir).png, &format!("{} render", smp.name))?)
        }
        None => {}
    }
    h.push_str("</section>");
    Ok((h, sj))
}

/// The calibration section: the camera, the colour calibrations and the
/// board's pose, each from its stage's files under `folder(stage)`.
fn calibration_sections(
    page: &mut Page,
    project: &Project,
    folder: &impl Fn(Stage) -> PathBuf,
    metrics: &mut Metrics,
) -> Result<String, ReportError> {
    let camera = calibrate_section(page, project, &CalibrationFiles::in_dir(&folder(Stage::Calibrate)), metrics)?;
    let (colour, any_colour) = colour_section(page, project, &folder(Stage::Colour), metrics)?;
    let pose = pose_section(page, project, &PoseFiles::in_dir(&folder(Stage::Pose)), metrics)?;
    let none = camera.is_none() && !any_colour && pose.is_none();
    Ok(format!(
        "<section><h2>Calibration</h2>{}{colour}{}{}</section>",
        camera.unwrap_or_default(),
        pose.unwrap_or_default(),
        if none { "<p class=\"note\">No calibration in this project.</p>" } else { "" }
    ))
}

/// The stages' table: each stage's status in the run that made the report
/// (`done`) and its wall time from its manifest.
fn stages_section(done: &[(Stage, Status)], manifests: &[(Stage, Manifest)], metrics: &mut Metrics) -> String {
    let mut rows = Vec::new();
    let mut stage_json = serde_json::Map::new();
    for s in Stage::ALL.iter().filter(|s| **s != Stage::Report) {
        let status = done.iter().find(|(d, _)| d == s).map(|(_, st)| st.clone());
        let m = manifests.iter().find(|(d, _)| d == s).map(|(_, m)| m);
        let text = match &status {
            Some(Status::Ran { .. }) => "ran".to_string(),
            Some(Status::UpToDate) => "up to date (inputs unchanged)".to_string(),
            Some(Status::Skipped { reason }) => format!("skipped: {reason}"),
            Some(Status::Deferred { tasks }) => format!("{tasks} task(s) written as batch jobs, not yet run"),
            Some(Status::Started { .. }) => "running".to_string(),
            None => "not run".to_string(),
        };
        let wall = m.map(|m| format!("{:.2} s", m.wall_s)).unwrap_or_else(|| "—".into());
        rows.push(vec![s.name().to_string(), text.clone(), wall]);
        stage_json.insert(s.name().into(), json!({"status": text, "wall_s": m.map(|m| m.wall_s)}));
    }
    metrics.insert("stages".into(), Value::Object(stage_json));
    format!("<h2>Stages</h2>{}", table(&["stage", "in the run that made this report", "wall time (last run)"], &rows))
}

/// A sample's optical properties (its entry of the optics stage's
/// `all_spectra`, matched by its recipe's name) with their plots in
/// `optics_dir`; empty when the stage has not computed the sample.
fn optics_section(
    page: &mut Page,
    smp: &SampleSection,
    all_spectra: &[OpticalProperties],
    optics_dir: &Path,
    sj: &mut Metrics,
) -> Result<String, ReportError> {
    let mut h = String::new();
    // Optics: match by recipe name (the "sample" field is the recipe's sample name).
    let recipe_name = crate::optics::recipe::Recipe::load(
        &smp.recipe,
        crate::optics::recipe::Overrides { weight_percent: smp.weight_percent },
    )
    .map(|r| r.name)
    .unwrap_or_else(|_| smp.name.clone());
    if let Some(sp) = all_spectra.iter().find(|s| s.sample.as_deref() == Some(recipe_name.as_str())) {
        h.push_str("<h3>Optical properties (Lorenz–Mie)</h3>");
        let wl = &sp.wavelength_nm;
        let mut rows = Vec::new();
        for (i, w) in wl.iter().enumerate() {
            if wl.len() > 12 && (w.round() as i64) % 50 != 0 {
                continue;
            }
            // μt and n_bulk may be left out of a hand-made file (read_optical_properties
            // checks every array given has one value per wavelength); μt = μs + μa then.
            let (mu_s, mu_a) = (sp.mu_s_per_m[i], sp.mu_a_per_m[i]);
            let mu_t = sp.mu_t_per_m.get(i).copied().unwrap_or(mu_s + mu_a);
            rows.push(vec![
                format!("{w}"),
                num(mu_s, e4),
                num(mu_a, e4),
                num(mu_t, e4),
                num(sp.g[i], f4),
                sp.n_bulk.get(i).map_or_else(|| "not in the file".into(), |n| num(*n, f4)),
            ]);
        }
        h.push_str(&table(&["λ [nm]", "μs [1/m]", "μa [1/m]", "μt [1/m]", "g", "n_bulk"], &rows));
        if let Some(a) = &sp.absorption {
            let _ = write!(h, "<p class=\"note\">absorption model: {}</p>", esc(a));
        }
        let clamps: Vec<&String> = sp.warnings.iter().filter(|w| w.contains(" clamped outside")).collect();
        if !clamps.is_empty() {
            let _ = write!(
                h,
                "<p class=\"why\">Clamped index: {}. The recipe's extrapolate = \"clamp\" holds n and κ at the \
                     data's end value there; at 380–399 nm the CIE colour-matching functions are below 1.2 % of their \
                     peaks, so a render's colour barely depends on it.</p>",
                esc(&clamps.iter().map(|s| s.as_str()).collect::<Vec<_>>().join("; "))
            );
        }
        let files = SampleFiles::in_dir(&OpticsFiles::sample_dir(optics_dir, all_spectra.len(), &recipe_name));
        h.push_str("<div class=\"row\">");
        h.push_str(&page.img(&files.png, &format!("{} μs, μa, g against wavelength", smp.name))?);
        for p in files.phase_pngs() {
            h.push_str(&page.img(&p, &format!("{} phase function (Lorenz–Mie vs HG)", smp.name))?);
        }
        h.push_str("</div>");
        sj.insert("optics".into(), trim(&to_value(sp), 64));
    }
    Ok(h)
}

/// A sample's BSSRDF slices (its folder `bdir` of the bssrdf stage, one
/// run per configuration of `configs`) and, where measured, their
/// comparisons; empty when the stage has not run for the sample.
fn bssrdf_section(
    page: &mut Page,
    smp: &SampleSection,
    configs: &[(f64, f64)],
    bdir: &Path,
    sj: &mut Metrics,
) -> Result<String, ReportError> {
    let mut h = String::new();
    if bdir.is_dir() {
        h.push_str("<h3>BSSRDF slices (slab simulator)</h3>");
        let mut rows = Vec::new();
        let mut bj = Vec::new();
        let mut imgs = String::new();
        // The largest median per-pixel error of a slice drawn with the ring estimator.
        let mut ring_noise: Option<f64> = None;
        for &c in configs {
            let run = SliceFiles::in_dir(Path::new(&super::bssrdf_run_dir(&bdir.display().to_string(), configs, c)));
            let compared = ComparisonFiles::in_dir(&super::bssrdf_comparison_dir(bdir, c));
            let summary: Option<crate::bssrdf::Summary> = read_json(&run.summary, "a BSSRDF summary.json")?;
            let cmp: Option<crate::bssrdf::Comparison> = read_json(&compared.json, "a BSSRDF comparison.json")?;
            if let Some(sm) = &summary
                && sm.estimator.contains("ring")
            {
                let e = sm.pixel_rel_error_median;
                ring_noise = Some(ring_noise.map_or(e, |r: f64| if e.is_finite() { r.max(e) } else { r }));
            }
            if let Some(sm) = &summary {
                rows.push(vec![
                    format!("{}° / {}°", c.0, c.1),
                    format!("{} ± {}", num(sm.sum, e4), num(sm.sum_std_error, e4)),
                    cmp.as_ref().map_or_else(|| "not measured".into(), |x| num(x.measured_sum, e4)),
                    cmp.as_ref().map_or_else(|| "—".into(), |x| num(x.sum_ratio, f4)),
                    cmp.as_ref().map_or_else(|| "—".into(), |x| num(x.mean_squared_relative_error, f4)),
                    format!("{}{}", sm.paths, if sm.interrupted { " (interrupted)" } else { "" }),
                ]);
            }
            imgs.push_str(&page.img(&run.png, &format!("{} slice θi {}° θo {}°", smp.name, c.0, c.1))?);
            imgs.push_str(&page.img(&run.profile_png, &format!("{} profile θi {}° θo {}°", smp.name, c.0, c.1))?);
            imgs.push_str(
                &page.img(&compared.panel, &format!("{} measured vs simulated θi {}° θo {}°", smp.name, c.0, c.1))?,
            );
            imgs.push_str(&page.img(
                &compared.profiles,
                &format!("{} measured vs simulated profiles θi {}° θo {}°", smp.name, c.0, c.1),
            )?);
            bj.push(json!({"theta_i_deg": c.0, "theta_o_deg": c.1, "summary": summary, "comparison": cmp}));
        }
        h.push_str(&table(
            &["θi / θo", "simulated sum [1/(m² sr)]", "measured sum", "sim/meas", "MSRE", "paths"],
            &rows,
        ));
        let _ = write!(h, "<div class=\"row\">{imgs}</div>");
        if let Some(e) = ring_noise {
            let _ = write!(
                h,
                "<p class=\"why\">Rings in a slice: Monte Carlo noise of the ring estimator, not structure of \
                     the material. With θi or θo = 0° each scattering event is spread over a whole ring of azimuths, \
                     so its noise lies on circles instead of in single pixels; the rings move with the seed, shrink \
                     with more paths, bias neither the sum nor the profile, and their size is the per-pixel error \
                     (median up to {} % here). They matter only for a pixel-by-pixel reading closer than that.</p>",
                num(e, |x| format!("{:.1}", 100.0 * x))
            );
        }
        sj.insert("bssrdf".into(), trim(&json!(bj), 64));
    }
    Ok(h)
}

/// A sample's fitted recipe (stage fit's `files`) beside the truth when
/// known, and the parameters with their truth for the loop's summary
/// ([`compare_section`]); empty when the stage has not fitted the sample.
fn fit_section(
    page: &mut Page,
    smp: &SampleSection,
    files: &FitFiles,
    sj: &mut Metrics,
) -> Result<(String, Vec<FittedVsTruth>), ReportError> {
    let mut h = String::new();
    // (parameter, fitted, 95 % interval, truth) of the fit, for the loop's summary below.
    let mut fitted_vs_truth: Vec<FittedVsTruth> = Vec::new();
    if let Some(fj) = read_json::<Value>(&files.json, "a fit.json")? {
        h.push_str("<h3>Recipe fitted to the measured slices (lucent fit)</h3>");
        let truth = match &smp.truth_recipe {
            Some(t) => crate::optics::recipe::Recipe::load(t, crate::optics::recipe::Overrides::default()).ok(),
            None => None,
        };
        let mut rows = Vec::new();
        let mut pj = Vec::new();
        for p in fj["parameters"].as_array().into_iter().flatten() {
            let name = p["name"].as_str().unwrap_or_default();
            let value = p["value"].as_f64();
            let ci = p["interval_95"].as_array().and_then(|a| Some([a.first()?.as_f64()?, a.get(1)?.as_f64()?]));
            let particle = name.split_once('@').and_then(|(_, k)| k.parse::<usize>().ok()).unwrap_or(0);
            let known = truth.as_ref().and_then(|t| match name.split('@').next() {
                Some("weight_percent") => t.particles.get(particle).map(|q| q.weight_percent),
                _ => None,
            });
            let covered = match (known, ci) {
                (Some(k), Some([lo, hi])) => {
                    if lo <= k && k <= hi {
                        "yes"
                    } else {
                        "no"
                    }
                }
                _ => "—",
            };
            rows.push(vec![
                esc(name),
                num(p["start"].as_f64().unwrap_or(f64::NAN), f4),
                value.map_or_else(|| "not identifiable".into(), |v| num(v, f4)),
                ci.map_or_else(|| "—".into(), |[lo, hi]| format!("{} – {}", num(lo, f4), num(hi, f4))),
                known.map_or_else(|| "—".into(), |k| num(k, f4)),
                covered.into(),
            ]);
            pj.push(json!({"name": name, "start": p["start"], "value": value, "interval_95": ci, "truth": known}));
            if let Some(k) = known {
                fitted_vs_truth.push((name.to_string(), value, ci, k));
            }
        }
        h.push_str(&table(
            &["parameter", "start (recipe)", "fitted", "95 % interval", "truth", "truth in interval"],
            &rows,
        ));
        if fj["identifiable"] == json!(false) {
            let _ = write!(
                h,
                "<p>The data do not pin the parameters down: {}.</p>",
                esc(fj["reason"].as_str().unwrap_or(""))
            );
        }
        // The measured slices against the simulation at the recipe (start) and at the fit (end).
        let cfgs: Vec<Vec<String>> = fj["configurations"]
            .as_array()
            .into_iter()
            .flatten()
            .map(|c| {
                let v = |k: &str, f: fn(f64) -> String| c[k].as_f64().map_or_else(|| "—".into(), |x| num(x, f));
                vec![
                    format!(
                        "{} / {}",
                        v("theta_i_deg", |x| format!("{x:.0}")),
                        v("theta_o_deg", |x| format!("{x:.0}"))
                    ),
                    v("measured_sum", e4),
                    v("sum_ratio_start", f4),
                    v("sum_ratio_end", f4),
                    v("msre_start", f4),
                    v("msre_end", f4),
                ]
            })
            .collect();
        if !cfgs.is_empty() {
            h.push_str(&table(
                &[
                    "θi / θo",
                    "measured sum [1/(m² sr)]",
                    "simulated/measured sum: recipe",
                    "fitted",
                    "MSRE: recipe",
                    "fitted",
                ],
                &cfgs,
            ));
        }
        let mut imgs = page.img(&files.objective_png, &format!("{} fit objective", smp.name))?;
        for c in fj["configurations"].as_array().into_iter().flatten() {
            let (Some(ti), Some(to)) = (c["theta_i_deg"].as_f64(), c["theta_o_deg"].as_f64()) else { continue };
            imgs.push_str(&page.img(
                &files.profiles_png(ti, to),
                &format!("{} measured profile vs simulated at the recipe and at the fit, θi {ti}° θo {to}°", smp.name),
            )?);
        }
        let _ = write!(h, "<div class=\"row\">{imgs}</div>");
        sj.insert(
            "fit".into(),
            json!({"parameters": pj, "identifiable": fj["identifiable"], "evaluations": fj["evaluations"]}),
        );
    }
    Ok((h, fitted_vs_truth))
}

/// A sample's environment scale (stage env-scale's `files`); empty when the
/// stage has not fitted one for the sample.
fn env_scale_section(files: &EnvScaleFiles, sj: &mut Metrics) -> Result<String, ReportError> {
    let mut h = String::new();
    if let Some(e) = read_json::<crate::envfit::FitReport>(&files.json, "an env_scale.json")? {
        let f = &e.fit;
        let _ = write!(
                h,
                "<h3>Environment scale</h3><p>k = {} (per channel {}, {}, {}) over {} board pixels; residual RMS {} ({} % of the photo; render noise {}).</p>",
                num(f.scale, f4),
                num(f.scale_per_channel[0], f4),
                num(f.scale_per_channel[1], f4),
                num(f.scale_per_channel[2], f4),
                f.pixels,
                num(f.residual_rms, e4),
                num(f.relative_residual, |x| format!("{:.2}", 100.0 * x)),
                num(f.render_noise_rms, e4),
            );
        let _ = write!(h, "<p class=\"why\">{}</p>", esc(&env_residual_note(f)));
        sj.insert("env_scale".into(), to_value(&e));
    }
    Ok(h)
}

/// A sample's render (stage render's `files`): samples, size, seed, time,
/// noise and approximations; empty when the stage has not rendered it.
fn render_section(files: &RenderFiles, sj: &mut Metrics) -> Result<String, ReportError> {
    let mut h = String::new();
    if let Some(r) = read_json::<crate::scene::RenderReport>(&files.json, "a render.json")? {
        let _ = write!(
            h,
            "<h3>Render</h3><p>{} spp{}, {} × {} px, seed {}, {} s; {}.</p>",
            r.spp,
            if r.interrupted { " (interrupted)" } else { "" },
            r.scene.image_width,
            r.scene.image_height,
            r.seed,
            num(r.wall_s, |x| format!("{x:.1}")),
            match &r.relative_std_error {
                Some(e) => {
                    let pct = |x: f64| num(x, |x| format!("{:.1}", 100.0 * x));
                    format!(
                        "relative standard error per pixel, median (90th percentile): the object's {} px {} % ({} %), \
                             the board's {} px {} % ({} %), all {} %",
                        e.object.pixels,
                        pct(e.object.median),
                        pct(e.object.p90),
                        e.board.pixels,
                        pct(e.board.median),
                        pct(e.board.p90),
                        pct(e.all.median)
                    )
                }
                None => format!(
                    "median relative standard error over all pixels {} %",
                    num(r.median_relative_std_error, |x| format!("{:.1}", 100.0 * x))
                ),
            },
        );
        for a in &r.approximations {
            let _ = write!(h, "<p class=\"why approximation\">Approximation: {}.</p>", esc(a));
        }
        sj.insert("render".into(), trim(&to_value(&r), 64));
    }
    Ok(h)
}

/// A sample's comparison with its photo (stage compare's folders `dirs`):
/// the metrics, the noise, the object's pixels, which twin is closer and
/// the loop against its known truth (`fitted_vs_truth`, from
/// [`fit_section`]); `None` when the stage has not compared the sample.
fn compare_section(
    smp: &SampleSection,
    dirs: &CompareDirs,
    fitted_vs_truth: &[FittedVsTruth],
    sj: &mut Metrics,
) -> Result<Option<String>, ReportError> {
    let Some(m) =
        read_json::<crate::compare::Report>(&CompareFiles::in_dir(&dirs.image).metrics, "a compare metrics.json")?
    else {
        return Ok(None);
    };
    let mut h = String::from("<h3>Photo | render | difference</h3>");
    h.push_str(&compare_metrics_table(&m));
    if let Some(n) = &m.noise {
        h.push_str(&noise_paragraphs(n));
    }
    // The object's pixels alone (compare/NAME/object/, the render's object layer).
    let object =
        read_json::<crate::compare::Report>(&CompareFiles::in_dir(&dirs.object).metrics, "a compare metrics.json")?;
    if let Some(o) = &object
        && let Some(n) = &o.noise
    {
        h.push_str(&object_paragraph(o, n));
    }
    // Which twin is closer, over the whole image and over the object; the
    // loop's verdict is the object's (where the twins differ), else the image's.
    let regions: Vec<(&str, &crate::compare::Report)> =
        std::iter::once(("the whole image", &m)).chain(object.as_ref().map(|o| ("the object's pixels", o))).collect();
    let mut verdict: Option<(&str, &crate::compare::noise::PairedReport)> = None;
    for (region, r) in &regions {
        let Some(t) = &r.twins else { continue };
        h.push_str(&twins_table(region, r, t));
        h.push_str(&paired_test_paragraph(&t.paired));
        verdict = Some((region, &t.paired));
    }
    // The loop against its known truth (truth_recipe, read by the report only).
    if let (Some(t_path), false, Some((region, paired))) = (&smp.truth_recipe, fitted_vs_truth.is_empty(), verdict) {
        h.push_str(&loop_against_truth(t_path, fitted_vs_truth, region, paired, sj));
    }
    if let Some(o) = &object {
        sj.insert("compare_object".into(), trim(&to_value(o), 64));
    }
    // The triplet (with two twins: both, under one scale) is in the answer at the top.
    let _ = write!(
        h,
        "<p class=\"note\">The photo | render | difference picture{} is at the top of the page.</p>",
        if m.twins.is_some() { " of both twins" } else { "" }
    );
    sj.insert("compare".into(), trim(&to_value(&m), 64));
    Ok(Some(h))
}

/// The comparison's metrics table (as calibrated and, when refined, after
/// ECC refinement) and the pixels it is over.
fn compare_metrics_table(m: &crate::compare::Report) -> String {
    let row = |label: &str, x: &crate::compare::Metrics| {
        vec![
            label.to_string(),
            num(x.rmse, e4),
            num(x.rmse_channels.r, e4),
            num(x.rmse_channels.g, e4),
            num(x.rmse_channels.b, e4),
            num(x.ssim.y, f4),
            num(x.ssim.mean_rgb, f4),
        ]
    };
    let mut rows = vec![row("as calibrated", &m.as_calibrated)];
    if let Some(r) = &m.refined {
        rows.push(row("after ECC refinement", &r.metrics));
    }
    let mut h = table(&["", "RMSE", "RMSE R", "RMSE G", "RMSE B", "SSIM (Y)", "SSIM (mean RGB)"], &rows);
    let _ = write!(
        h,
        "<p>Over {} pixels ({}: {}).</p>",
        m.mask.included_pixels,
        esc(&m.mask.source),
        esc(m.mask.path.as_deref().unwrap_or("the whole image"))
    );
    h
}

/// The model RMSE with the noise removed over the image, and the photo's
/// noise model when the comparison has one.
fn noise_paragraphs(n: &crate::compare::noise::NoiseReport) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<p>Model RMSE with the render's and the photo's noise removed: {} (95 % interval {} – {}); noise \
                 floor {} (the RMSE a perfect twin would show at this noise); photo variance: {}.</p>",
        num(n.total.model_rmse, e4),
        num(n.total.ci95[0], e4),
        num(n.total.ci95[1], e4),
        num(n.total.noise_floor, e4),
        esc(&n.photo_variance)
    );
    if let Some(pn) = &n.photo_noise {
        h.push_str(&photo_noise_paragraph(pn));
    }
    h
}

/// The photo's noise model (variance = a·x + b), and the one estimated from
/// the photo itself when there is one.
fn photo_noise_paragraph(pn: &crate::compare::photo_noise::PhotoVarianceFile) -> String {
    let model = |m: &lucent_calib::noise::NoiseModel| {
        format!(
            "a = {} / {} / {}, b = {} / {} / {} (R / G / B)",
            num(m.a[0], e4),
            num(m.a[1], e4),
            num(m.a[2], e4),
            num(m.b[0], e4),
            num(m.b[1], e4),
            num(m.b[2], e4)
        )
    };
    format!(
        "<p>The photo's noise model, variance = a·x + b of a raw value x (1 = white level): {}{}.</p>",
        model(&pn.noise_model),
        match &pn.estimated_from_image {
            Some(e) => format!(
                "; estimated from the photo itself, as a check: {} (larger where the photo has \
                         texture or noise of its own at the photosite scale)",
                model(e)
            ),
            None => String::new(),
        }
    )
}

/// The metrics over the object's pixels alone (`o`, with its noise `n`),
/// with a warning when the interval rests on too few blocks.
fn object_paragraph(o: &crate::compare::Report, n: &crate::compare::noise::NoiseReport) -> String {
    format!(
        "<p>Over the object's {} pixels alone ({}): RMSE {}, model RMSE {} (95 % interval {} – {}), noise \
                 floor {}, SSIM (Y) {}{}.</p>",
        o.mask.included_pixels,
        esc(&o.mask.source),
        num(o.as_calibrated.rmse, e4),
        num(n.total.model_rmse, e4),
        num(n.total.ci95[0], e4),
        num(n.total.ci95[1], e4),
        num(n.total.noise_floor, e4),
        num(o.as_calibrated.ssim.y, f4),
        if n.blocks < crate::compare::noise::MIN_BLOCKS {
            format!(
                "; the interval rests on {} blocks of {} px, fewer than {}: too few to trust",
                n.blocks,
                n.block_px,
                crate::compare::noise::MIN_BLOCKS
            )
        } else {
            String::new()
        }
    )
}

/// The heading and table of the two twins over `region` (`r` the recipe's
/// twin A, `t` the fitted twin B): model RMSE with the noise removed, SSIM
/// and SSIM at zero render noise.
fn twins_table(region: &str, r: &crate::compare::Report, t: &crate::compare::TwinsReport) -> String {
    let zero = |z: &Option<crate::compare::noise::SsimAtZeroNoise>| {
        z.as_ref().map_or_else(
            || "—".to_string(),
            |z| format!("{} ({} – {})", num(z.at_zero_noise, f4), num(z.ci95[0], f4), num(z.ci95[1], f4)),
        )
    };
    let twin = |label: &str, n: Option<&crate::compare::noise::NoiseReport>, ssim: f64, z: String| {
        vec![
            label.to_string(),
            n.map_or_else(
                || "—".into(),
                |n| {
                    format!(
                        "{} ({} – {})",
                        num(n.total.model_rmse, e4),
                        num(n.total.ci95[0], e4),
                        num(n.total.ci95[1], e4)
                    )
                },
            ),
            num(ssim, f4),
            z,
        ]
    };
    let mut h = format!("<h3>Which twin is closer over {region}: the recipe's (A) or the fitted one (B)</h3>");
    h.push_str(&table(
        &["twin", "model RMSE, noise removed (95 %)", "SSIM (Y)", "SSIM (Y) at zero render noise (95 %)"],
        &[
            twin("A: recipe", r.noise.as_ref(), r.as_calibrated.ssim.y, zero(&r.ssim_at_zero_noise)),
            twin("B: fitted", Some(&t.noise_b), t.metrics_b.ssim.y, zero(&t.ssim_at_zero_noise_b)),
        ],
    ));
    h
}

/// The paired test of the two twins' means and its verdict, in bold.
fn paired_test_paragraph(p: &crate::compare::noise::PairedReport) -> String {
    format!(
        "<p>Paired test of the means over {c} × {c} px cells, {} blocks{}: mean squared-error difference A − B {} ± {} \
         (t {}, p {}): <b>{}</b>.</p>",
        p.blocks,
        if p.blocks < crate::compare::noise::MIN_BLOCKS {
            format!(" (fewer than {}: its standard error is itself uncertain)", crate::compare::noise::MIN_BLOCKS)
        } else {
            String::new()
        },
        num(p.squared_difference, e4),
        num(p.standard_error, e4),
        num(p.z, |x| format!("{x:.2}")),
        num(p.p_value, |x| format!("{x:.2e}")),
        esc(&p.verdict.replace('A', "A (recipe)").replace('B', "B (fitted)")),
        c = p.cell_px
    )
}

/// The loop against its known truth (`truth_recipe` at `t_path`): each
/// fitted parameter beside its truth, and whether the compare stage names
/// the fitted twin closer over `region` at p < 0.01 (also into `sj`).
fn loop_against_truth(
    t_path: &Path,
    fitted_vs_truth: &[FittedVsTruth],
    region: &str,
    paired: &crate::compare::noise::PairedReport,
    sj: &mut Metrics,
) -> String {
    let fits: Vec<String> = fitted_vs_truth
        .iter()
        .map(|(name, v, ci, k)| {
            format!(
                "{} truth {}, recovered {}{}",
                esc(name),
                num(*k, f4),
                v.map_or_else(|| "—".into(), |v| num(v, f4)),
                match ci {
                    Some([lo, hi]) => format!(
                        " (95 % {} – {}: the truth {} it)",
                        num(*lo, f4),
                        num(*hi, f4),
                        if *lo <= *k && *k <= *hi { "is in" } else { "is outside" }
                    ),
                    None => String::new(),
                }
            )
        })
        .collect();
    let named_fitted = paired.verdict == "B is closer";
    let met = named_fitted && paired.p_value < 0.01;
    let h = format!(
        "<p><b>The loop against its known truth</b> ({}, which no stage reads): {}; over {region} the \
                 compare stage {} (p = {}; the demo's bar: the fitted twin named closer with p &lt; 0.01, {}).</p>",
        esc(&t_path.display().to_string()),
        fits.join("; "),
        if named_fitted {
            "names the fitted twin closer".to_string()
        } else {
            format!("does not name the fitted twin closer ({})", esc(&paired.verdict))
        },
        num(paired.p_value, |x| format!("{x:.2e}")),
        if met { "met" } else { "not met" }
    );
    sj.insert(
        "loop".into(),
        json!({
            "truth_recipe": t_path,
            "parameters": fitted_vs_truth.iter().map(|(n, v, ci, k)| json!({"name": n, "truth": k, "recovered": v, "interval_95": ci})).collect::<Vec<_>>(),
            "region": region,
            "verdict": paired.verdict,
            "p_value": paired.p_value,
            "fitted_named_closer_at_p_below_0_01": met,
        }),
    );
    h
}

/// The camera calibration (stage calibrate's `files`), beside the known
/// camera when `[calibration] truth` gives one; `None` when the stage has
/// not run.
fn calibrate_section(
    page: &mut Page,
    project: &Project,
    files: &CalibrationFiles,
    metrics: &mut Metrics,
) -> Result<Option<String>, ReportError> {
    let mut h = String::new();
    type Calibration = lucent_calib::camera::Calibration;
    let Some(c) = read_json::<Calibration>(&files.camera, "a camera.json")? else {
        return Ok(None);
    };
    let (k, d) = (&c.camera.intrinsics, &c.camera.distortion);
    h.push_str("<h3>Camera (Zhang)</h3>");
    h.push_str(&table(
        &["fx [px]", "fy [px]", "cx [px]", "cy [px]", "k1", "k2", "p1", "p2", "k3", "RMS [px]", "views"],
        &[vec![
            num(k.fx, f3),
            num(k.fy, f3),
            num(k.cx, f3),
            num(k.cy, f3),
            num(d.k1, f4),
            num(d.k2, f4),
            num(d.p1, e4),
            num(d.p2, e4),
            num(d.k3, f4),
            num(c.rms_px, f4),
            c.views.len().to_string(),
        ]],
    ));
    let truth = match project.file.calibration.as_ref().and_then(|c| c.truth.as_ref()) {
        Some(p) => read_json::<Calibration>(p, "a camera.json ([calibration] truth)")?,
        None => None,
    };
    let mut truth_json = None;
    if let Some(t) = &truth {
        // Synthetic views from a known camera: truth, recovered and their difference.
        let values = |c: &Calibration| {
            let (k, d) = (&c.camera.intrinsics, &c.camera.distortion);
            [
                ("fx", k.fx),
                ("fy", k.fy),
                ("cx", k.cx),
                ("cy", k.cy),
                ("k1", d.k1),
                ("k2", d.k2),
                ("p1", d.p1),
                ("p2", d.p2),
                ("k3", d.k3),
            ]
        };
        let mut rows = Vec::new();
        let mut tj = serde_json::Map::new();
        for ((name, tv), (_, rv)) in values(t).into_iter().zip(values(&c)) {
            let fmt = |x: f64| format!("{x:.5}");
            rows.push(vec![name.to_string(), fmt(tv), fmt(rv), fmt(rv - tv)]);
            tj.insert(name.into(), json!({"truth": tv, "recovered": rv, "error": rv - tv}));
        }
        h.push_str("<h3>Recovered vs known camera (synthetic views)</h3>");
        h.push_str(&table(&["parameter", "truth", "recovered", "recovered − truth"], &rows));
        truth_json = Some(Value::Object(tj));
    }
    h.push_str(&page.img(&files.residuals_png, "reprojection residuals per view")?);
    let mut cj = trim(&to_value(&c), 16);
    if let Some(t) = truth_json {
        cj["truth_vs_recovered"] = t;
    }
    cj["views"] = json!(c.views.iter().map(|v| json!({"image": v.image, "rms_px": v.rms_px})).collect::<Vec<_>>());
    metrics.insert("calibration".into(), cj);
    Ok(Some(h))
}

/// Every colour calibration of the project (stage colour's folder
/// `colour_dir`, one [`ColourFiles`] per camera) with its ΔE2000 table,
/// beside the known camera response where `[[colour]] truth` gives one; and
/// whether there was any.
fn colour_section(
    page: &mut Page,
    project: &Project,
    colour_dir: &Path,
    metrics: &mut Metrics,
) -> Result<(String, bool), ReportError> {
    let (mut h, mut any) = (String::new(), false);
    let mut colour_json = serde_json::Map::new();
    for c in &project.file.colour {
        let files = ColourFiles::in_dir(&colour_dir.join(&c.camera));
        if !files.ccm.exists() {
            continue;
        }
        let (ccm, _) = crate::ccm_file::CcmFile::read(&files.ccm)?;
        any = true;
        let _ = write!(
            h,
            "<h3>Colour: {}</h3><p>{} · ΔE2000 mean {} max {}</p>",
            esc(&c.camera),
            esc(&ccm.method.to_string()),
            num(ccm.de2000_mean, f3),
            num(ccm.de2000_max, f3)
        );
        let rows: Vec<Vec<String>> = ccm
            .patches
            .iter()
            .map(|p| vec![p.fit.patch.to_string(), p.fit.name.clone(), num(p.fit.de2000, f3), num(p.fit.de76, f3)])
            .collect();
        h.push_str(&table(&["patch", "name", "ΔE2000", "ΔE76"], &rows));
        let mut cj = trim(&to_value(&ccm), 16);
        if let Some(t) = &c.truth {
            let truth = crate::synth::ColourTruth::load(t)?;
            let recovered: Option<lucent_colour::Mat3> = match ccm.matrix.as_slice() {
                [a, b, c] if [a, b, c].iter().all(|r| r.len() == 3) => {
                    Some([[a[0], a[1], a[2]], [b[0], b[1], b[2]], [c[0], c[1], c[2]]])
                }
                _ => None,
            };
            match recovered {
                Some(m) => {
                    let r = crate::synth::colour_recovery(&truth, &m)?;
                    let _ = write!(
                        h,
                        "<p>Known camera response ({}): the recovered matrix is {:.4} × the truth (the chart's \
                         1 / exposure) within {:.2} % (largest entry error); truth vs recovered on the 24 \
                         patches ΔE2000 mean {:.3}, max {:.3}.</p>",
                        esc(&t.display().to_string()),
                        r.gain,
                        100.0 * r.max_rel_matrix_error,
                        r.de2000_mean,
                        r.de2000_max
                    );
                    cj["truth_vs_recovered"] = json!(r);
                }
                None => h.push_str("<p class=\"note\">The colour truth applies to 3 × 3 matrices only.</p>"),
            }
        }
        h.push_str("<div class=\"row\">");
        h.push_str(&page.img(&files.chart, &format!("{} chart: measured | corrected | reference", c.camera))?);
        h.push_str(&page.img(&files.delta_e, &format!("{} ΔE per patch", c.camera))?);
        h.push_str("</div>");
        colour_json.insert(c.camera.clone(), cj);
    }
    metrics.insert("colour".into(), Value::Object(colour_json));
    Ok((h, any))
}

/// The board's pose (stage pose's `files`), beside the known pose when
/// `[pose] truth` gives one; `None` when the stage has not run.
fn pose_section(
    page: &mut Page,
    project: &Project,
    files: &PoseFiles,
    metrics: &mut Metrics,
) -> Result<Option<String>, ReportError> {
    let mut h = String::new();
    type Pose = lucent_calib::scene::SceneDescription;
    let Some(p) = read_json::<Pose>(&files.json, "a scene.json of `lucent pose`")? else {
        return Ok(None);
    };
    h.push_str("<h3>Board pose</h3>");
    let mut pj = trim(&to_value(&p), 16);
    if let Some(t) = project.file.pose.as_ref().and_then(|s| s.truth.as_ref()) {
        let text = crate::io::read_text(t).map_err(|source| ReportError::Read {
            path: t.clone(),
            what: "a scene file ([pose] truth)",
            source,
        })?;
        match crate::scene::parse(&text, t).map_err(|e| ReportError::PoseTruth(Box::new(e)))?.camera.camera_to_world {
            Some(k) => {
                let (mm, deg) = pose_error(&k, &p.camera_to_world);
                let _ = write!(
                    h,
                    "<p>Known camera pose ({}): recovered camera position {mm:.2} mm from the truth, \
                         orientation {deg:.3}° off.</p>",
                    esc(&t.display().to_string())
                );
                pj["truth_vs_recovered"] = json!({"position_error_mm": mm, "rotation_error_deg": deg});
            }
            None => h.push_str("<p class=\"note\">[pose] truth has no [camera] camera_to_world.</p>"),
        }
    }
    h.push_str(&page.img(&files.view_png, "board pose and sample outline")?);
    metrics.insert("pose".into(), pj);
    Ok(Some(h))
}

/// The manifest of every stage that has one: key, version, seed, wall
/// time, inputs with their SHA-256 and the commands.
fn manifest_section(manifests: &[(Stage, Manifest)], metrics: &mut Metrics) -> String {
    let mut h = String::from("<section><h2>Manifest</h2>");
    let mut mj = serde_json::Map::new();
    for (s, m) in manifests {
        let _ = write!(
            h,
            "<h3>{}</h3><p class=\"meta\">key <code>{}</code> · lucent {} · seed {} · {:.2} s · outputs <code>{}</code></p>",
            s.name(),
            &m.key[..16.min(m.key.len())],
            esc(&m.lucent_version),
            m.seed,
            m.wall_s,
            &m.outputs_sha256[..16.min(m.outputs_sha256.len())]
        );
        let rows: Vec<Vec<String>> = m
            .inputs
            .iter()
            .map(|i| vec![i.path.clone(), i.bytes.to_string(), i.sha256[..16.min(i.sha256.len())].to_string()])
            .collect();
        if !rows.is_empty() {
            h.push_str(&table(&["input", "bytes", "SHA-256 (first 16)"], &rows));
        }
        h.push_str("<details><summary>commands</summary><pre>");
        for c in &m.commands {
            let _ = writeln!(h, "lucent {}", esc(&c.join(" ")));
        }
        h.push_str("</pre></details>");
        mj.insert(s.name().into(), to_value(m));
    }
    h.push_str("</section>");
    metrics.insert("manifests".into(), Value::Object(mj));
    h
}

/// The significance of a paired test's p-value, in words.
fn significance(p: f64) -> &'static str {
    if !p.is_finite() {
        "its significance could not be computed"
    } else if p < 0.01 {
        "significant at the 1 % level"
    } else if p < 0.05 {
        "significant at 5 % but not at 1 %"
    } else {
        "not significant (p ≥ 0.05)"
    }
}

/// The one-sentence verdict of two twins over `region`: which is closer,
/// by how much (their model RMSE with the noise removed) and how sure (the
/// paired test).
pub fn verdict_sentence(region: &str, a: &crate::compare::Report) -> Option<String> {
    let t = a.twins.as_ref()?;
    let (ra, rb) = (a.noise.as_ref()?.total.model_rmse, t.noise_b.total.model_rmse);
    let p = &t.paired;
    let numbers = format!(
        "model RMSE with the noise removed {} for the recipe's twin (A) and {} for the fitted twin (B)",
        num(ra, e3),
        num(rb, e3)
    );
    let by = |closer: f64, other: f64| {
        if other > 0.0 && closer.is_finite() && other.is_finite() {
            format!(", {:.0} % lower", 100.0 * (other - closer) / other)
        } else {
            String::new()
        }
    };
    Some(match p.verdict.as_str() {
        "B is closer" => format!(
            "Over {region}, the fitted twin (B) is closer to the photo than the recipe's twin (A): {numbers}{}; \
             paired test p = {}, {}.",
            by(rb, ra),
            num(p.p_value, |x| format!("{x:.1e}")),
            significance(p.p_value)
        ),
        "A is closer" => format!(
            "Over {region}, the recipe's twin (A) is closer to the photo than the fitted twin (B): {numbers}{}; \
             paired test p = {}, {}.",
            by(ra, rb),
            num(p.p_value, |x| format!("{x:.1e}")),
            significance(p.p_value)
        ),
        _ => format!(
            "Over {region}, the photo cannot tell the recipe's twin (A) from the fitted twin (B) at this noise: \
             {numbers}; paired test p = {}, {}.",
            num(p.p_value, |x| format!("{x:.2}")),
            significance(p.p_value)
        ),
    })
}

/// One twin against the photo, in one sentence (no fitted twin to compare with).
fn single_twin_sentence(region: &str, r: &crate::compare::Report) -> String {
    match &r.noise {
        Some(n) => format!(
            "Over {region}, the twin differs from the photo by a model RMSE with the noise removed of {} (95 % {} – \
             {}); a perfect twin would show an RMSE of {} at this noise (the noise floor), this one shows {}.",
            num(n.total.model_rmse, e3),
            num(n.total.ci95[0], e3),
            num(n.total.ci95[1], e3),
            num(n.total.noise_floor, e3),
            num(r.as_calibrated.rmse, e3)
        ),
        None => format!(
            "Over {region}, the twin differs from the photo by an RMSE of {} and SSIM (Y) {} (the render has no \
             variance, so the noise cannot be removed).",
            num(r.as_calibrated.rmse, e3),
            num(r.as_calibrated.ssim.y, f4)
        ),
    }
}

/// The first thing on the page for one sample: the verdict in one sentence,
/// then the photo | render | difference picture (with two twins: side by side
/// under one difference scale, each headed by its twin). Empty when the
/// compare stage has not run for the sample.
fn answer(page: &mut Page, dirs: &CompareDirs, smp: &SampleSection) -> Result<String, ReportError> {
    let (image_files, object_files) = (CompareFiles::in_dir(&dirs.image), CompareFiles::in_dir(&dirs.object));
    let Some(image) = read_json::<crate::compare::Report>(&image_files.metrics, "a compare metrics.json")? else {
        return Ok(String::new());
    };
    let object = read_json::<crate::compare::Report>(&object_files.metrics, "a compare metrics.json")?;
    // The object's pixels, where the twins differ, when the render marks them.
    let (region, r) = match &object {
        Some(o) if o.twins.is_some() || image.twins.is_none() => ("the object's pixels", o),
        _ => ("the whole image", &image),
    };
    let sentence = verdict_sentence(region, r).unwrap_or_else(|| single_twin_sentence(region, r));
    let mut h = format!(
        "<section class=\"answer\" id=\"answer-{}\"><h2>{}: the answer</h2><p class=\"verdict\">{}</p>",
        slug(&smp.name),
        esc(&smp.name),
        esc(&sentence)
    );
    let twins = image.twins.is_some();
    h.push_str(&difference_note(&image.display, twins, region));
    let alt = if twins {
        format!(
            "{}: photo | A (recipe) render, difference | B (fitted) render, difference, one difference scale",
            smp.name
        )
    } else {
        format!("{}: photo | render | difference", smp.name)
    };
    h.push_str(&page.img(&image_files.triplet, &alt)?);
    // The approximations the renders made, with their measured bias, beside the comparison that uses them.
    h.push_str(&approximation_note(r, twins));
    // Is the photo within each twin's predictive band (`[render] uncertainty`)?
    if let Some(o) = object.as_ref().filter(|o| !o.bands.is_empty()) {
        h.push_str(&band_section(page, o, &object_files, smp)?);
    }
    let _ = write!(
        h,
        "<p class=\"note\"><a href=\"#sample-{}\">The details per stage ↓</a></p></section>",
        slug(&smp.name)
    );
    Ok(h)
}

/// How to read the answer's picture (`d`, its display scale): the columns
/// with two twins, the difference column's colour scale and what it clips,
/// and where the verdict's numbers are from when not the whole image.
fn difference_note(d: &crate::compare::DisplayReport, twins: bool, region: &str) -> String {
    format!(
        "<p class=\"why\">{}Difference column: luminance of the render minus the photo, blue = render darker, red = \
         render brighter, one colour scale ±{} for {}; {:.1} % of the pixels lie beyond it and show at full colour \
         (they are not lost: the metrics use every value).{}{}</p>",
        if twins {
            "Left to right: the photo, the recipe's twin A (render, difference), the fitted twin B (render, \
             difference). "
        } else {
            ""
        },
        num(d.difference_range, e3),
        if twins { "both twins" } else { "the picture" },
        100.0 * d.clipped_fraction_difference,
        if d.clipped_fraction_photo > 0.0 || d.clipped_fraction_render > 0.0 {
            format!(
                " Striped pixels ({:.2} % of the photo's, {:.2} % of the render's) are brighter than the display \
                 range at this exposure: a display clip only, the metrics use the unclipped values.",
                100.0 * d.clipped_fraction_photo,
                100.0 * d.clipped_fraction_render
            )
        } else {
            String::new()
        },
        if region == "the whole image" {
            String::new()
        } else {
            format!(
                " The picture shows the whole image; the verdict's numbers are over {region}, where the twins differ."
            )
        }
    )
}

/// The approximations the renders compared in `r` made (once when both
/// twins share them, else per twin or render file); empty when none.
fn approximation_note(r: &crate::compare::Report, twins: bool) -> String {
    let approximate = &r.approximations;
    if approximate.is_empty() {
        return String::new();
    }
    let shared = twins && approximate.len() == 2 && approximate[0].approximations == approximate[1].approximations;
    let mut h = String::from("<p class=\"why approximation\"><b>The renders approximate</b>: ");
    let lists: Vec<String> = if shared {
        vec![approximate[0].approximations.join("; ")]
    } else {
        approximate
            .iter()
            .map(|a| {
                // The twin's name where the render is one of the compared twins, else its file.
                let name = if twins && a.render == r.render {
                    "A (recipe)".to_string()
                } else if r.twins.as_ref().is_some_and(|t| t.render_b == a.render) {
                    "B (fitted)".to_string()
                } else {
                    a.render.clone()
                };
                format!("{name}: {}", a.approximations.join("; "))
            })
            .collect()
    };
    let _ = write!(
        h,
        "{}. A difference to the photo on the object includes that bias{}.</p>",
        esc(&lists.join(" — ")),
        if shared { "; both twins share it, so which is closer is not moved by it as much" } else { "" }
    );
    h
}

/// Whether the photo is within each twin's predictive band over the object
/// (`o`, whose bands are not empty), with the band picture.
fn band_section(
    page: &mut Page,
    o: &crate::compare::Report,
    object_files: &CompareFiles,
    smp: &SampleSection,
) -> Result<String, ReportError> {
    let names = ["A (recipe)", "B (fitted)"];
    let mut h = String::from("<h3>Within the twin's predictive band?</h3><ul>");
    for (k, b) in o.bands.iter().enumerate() {
        let name = if o.twins.is_some() { names[k] } else { "the twin" };
        let _ = write!(
            h,
            "<li><b>{}: {}</b>. {}</li>",
            esc(name),
            if b.within { "within" } else { "outside" },
            esc(&b.statement)
        );
    }
    h.push_str(
        "</ul><p class=\"why\">The band is what the twin predicts for the object's mean given the recipe's \
         uncertain inputs (the fitted twin's: the fit's standard errors), the render's Monte Carlo error and \
         the photo's noise; outside it, the difference is more than those uncertainties explain.</p>",
    );
    h.push_str(&page.img(&object_files.band_png, &format!("{}: photo against the twins' bands", smp.name))?);
    Ok(h)
}

/// What the environment scale's residual is, and whether it matters: it is
/// the pixel-by-pixel scatter of the photo about k × the render over the
/// board, not an error of k (a ratio of sums over many pixels).
fn env_residual_note(f: &crate::envfit::ScaleFit) -> String {
    // Were the scatter independent from pixel to pixel, it would move the
    // ratio of sums by about relative_residual / √(3 N).
    let moves = f.relative_residual / (3.0 * f.pixels.max(1) as f64).sqrt();
    format!(
        "What the {} % means: the residual is the pixel-by-pixel scatter of the photo about k × the render over the \
         board (the photo's noise, the render's noise, demosaicing and the squares' edges), not an error of k. k is \
         a ratio of sums over {} pixels, which scatter of this size moves by only about ±{:.2} % (were it \
         independent from pixel to pixel); it matters only if the per-channel k disagree or the residual is far \
         above the noise.",
        num(f.relative_residual, |x| format!("{:.2}", 100.0 * x)),
        f.pixels,
        100.0 * moves
    )
}

const STYLE: &str =
    "body{font:15px/1.45 system-ui,sans-serif;margin:2em auto;max-width:1200px;padding:0 1em;color:#222}\
h1{margin-bottom:.2em}h2{border-bottom:2px solid #ccc;padding-bottom:.2em;margin-top:2em}\
table{border-collapse:collapse;margin:.6em 0}td,th{border:1px solid #ccc;padding:.25em .6em;text-align:right}\
th{background:#f2f2f2}td:first-child,th:first-child{text-align:left}\
figure{display:inline-block;margin:.4em;vertical-align:top}figure img{max-width:100%;border:1px solid #ddd}\
.row figure{max-width:48%}figcaption{font-size:85%;color:#555}.meta,.note{color:#666;font-size:90%}\
pre{background:#f7f7f7;padding:.6em;overflow-x:auto;font-size:80%}code{font-size:90%}\
.answer h2{margin-top:.6em}.verdict{font-size:118%;font-weight:600;background:#eef5ff;border-left:4px solid #3b73c4;\
padding:.5em .8em}.answer figure{display:block;margin:.4em 0}.why{color:#444;font-size:90%;border-left:3px solid #ddd;\
padding-left:.6em}";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_error_measures_distance_and_angle() {
        let t = [[1.0, 0.0, 0.0, 0.1], [0.0, 1.0, 0.0, 0.2], [0.0, 0.0, 1.0, 0.3], [0.0, 0.0, 0.0, 1.0]];
        let (c, s) = (2f64.to_radians().cos(), 2f64.to_radians().sin());
        let r = [[c, -s, 0.0, 0.103], [s, c, 0.0, 0.196], [0.0, 0.0, 1.0, 0.3], [0.0, 0.0, 0.0, 1.0]];
        let (mm, deg) = pose_error(&t, &r);
        assert!((mm - 5.0).abs() < 1e-9 && (deg - 2.0).abs() < 1e-9, "{mm} {deg}");
        assert_eq!(pose_error(&t, &t), (0.0, 0.0));
    }
}
