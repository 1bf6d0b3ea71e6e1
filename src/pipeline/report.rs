//! The run's report: `report/index.html`, one self-contained page (inline
//! style, no script, no network; its images copied into `report/img/` and
//! referenced relatively), and `report/metrics.json` with every number the
//! stages wrote. Both are built from the stage folders as they are on disk
//! (a stage that did not run this time contributes its earlier result, with
//! its manifest).
//!
//! Per sample: the optical-property table (μs, μa, μt in 1/m, g, n_bulk at
//! every 50 nm of the grid) with the spectra and phase-function plots; the
//! fitted surface (each microfacet model's α, scale, tilt, MSE and NRMSE,
//! with the distribution plot); the
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
//! [`crate::surface::FitReport`],
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
//! writes its own section from them beside its job (a
//! [`ReportSection`], e.g. [`crate::job::CompareSection`]; the formatting
//! they share is [`crate::job::report`]). [`write()`] assembles the page:
//! the heading, each sample's answer, the stages' table, each sample's
//! sections, the calibration's and the manifests (the heading, the stages'
//! table and the manifests are the pipeline's own, from the project and
//! its [`Manifest`]s).

use super::layout::{bssrdf_comparison_dir, bssrdf_run_dir, CompareDirs, Manifest, StageFiles};
use super::project::{Project, SampleSection};
use super::stage::{Stage, Status};
use crate::bssrdf::{ComparisonFiles, SliceFiles};
use crate::compare::CompareFiles;
use crate::envfit::EnvScaleFiles;
use crate::fit::report::FitFiles;
use crate::job::guard::OutputFolder;
use crate::job::report::{slug, table, to_value, Metrics, Page, ReportSection, SectionContext};
use crate::job::{
    read_spectra, BssrdfConfigFiles, BssrdfSection, CalibrateSection, ColourCamera, ColourSection, CompareSection,
    FitSection, OpticsSection, PoseSection,
};
use crate::optics::output::{OpticalProperties, OpticsFiles};
use crate::scene::RenderFiles;
use crate::surface::SurfaceFitFiles;
use lucent_calib::calibrate::CalibrationFiles;
use lucent_calib::scene::PoseFiles;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

pub use crate::job::report::{esc, read_json, ReportError};
pub use crate::job::verdict_sentence;

/// The folder of `stage` under `out` when it is in this run's plan (ran or
/// up to date); else a path that does not exist, so a folder left by an
/// earlier project, or an earlier version of this one, is not reported.
/// Without outcomes (`stages` empty: a report of a folder, not of a run)
/// every stage's folder.
fn stage_folder(out: &Path, stages: &StageOutcomes, stage: Stage) -> PathBuf {
    if stages.is_empty() {
        return out.join(stage.name());
    }
    match stages.get(&stage) {
        Some(StageOutcome::Ran | StageOutcome::UpToDate) => out.join(stage.name()),
        _ => out.join(format!(".{}.not-in-this-plan", stage.name())),
    }
}

/// How a stage ended in the run whose report it is, as the report's table
/// of stages says it ([`Status`] without its times: the report stage's key
/// does not hash it, so a rerun where every stage is up to date keeps the
/// report of the run that made it).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", deny_unknown_fields)]
pub enum StageOutcome {
    Ran,
    UpToDate,
    /// Skipped, and why.
    Skipped(String),
    /// Its tasks were written as batch jobs and have not run yet.
    Deferred {
        tasks: usize,
    },
    Running,
}

impl StageOutcome {
    /// The outcome of a stage that ended with `status`.
    pub fn of(status: &Status) -> Self {
        match status {
            Status::Ran { .. } => StageOutcome::Ran,
            Status::UpToDate => StageOutcome::UpToDate,
            Status::Skipped { reason } => StageOutcome::Skipped(reason.to_string()),
            Status::Deferred { tasks } => StageOutcome::Deferred { tasks: *tasks },
            Status::Started { .. } => StageOutcome::Running,
        }
    }

    /// The words of the report's table of stages.
    fn text(&self) -> String {
        match self {
            StageOutcome::Ran => "ran".into(),
            StageOutcome::UpToDate => "up to date (inputs unchanged)".into(),
            StageOutcome::Skipped(reason) => format!("skipped: {reason}"),
            StageOutcome::Deferred { tasks } => format!("{tasks} task(s) written as batch jobs, not yet run"),
            StageOutcome::Running => "running".into(),
        }
    }
}

/// Every stage's outcome in the run whose report it is (in the stages' order).
pub type StageOutcomes = BTreeMap<Stage, StageOutcome>;

/// The outcomes of a run's stages as [`crate::pipeline::run`] returns them.
pub fn outcomes(done: &[(Stage, Status)]) -> StageOutcomes {
    done.iter().map(|(s, st)| (*s, StageOutcome::of(st))).collect()
}

/// The report stage's job: the report of the run in `run` (the stage
/// folders' parent) for `project`, written into `out` (`run/report` in
/// `lucent run`). `stages` says how each stage ended in that run; without
/// it (`lucent report`, a job file that leaves it out) every stage folder
/// in `run` is reported as it is. [`ReportJob::run`] writes
/// [`ReportFiles`]; the pipeline's report stage runs the same job
/// ([`ReportJob::run_on`] with the project it has loaded).
///
/// ```
/// use lucent::pipeline::report::ReportJob;
/// let job: ReportJob = serde_json::from_str(
///     r#"{"project": "demo/project.toml", "run": "lucent-out/demo", "out": "lucent-out/demo/report"}"#,
/// ).unwrap();
/// assert!(job.stages.is_empty());
/// assert_eq!(job.to_args(), ["report", "demo/project.toml", "--run", "lucent-out/demo", "--out", "lucent-out/demo/report"]);
/// ```
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ReportJob {
    /// The project file.
    pub project: PathBuf,
    /// The run's output folder (the parent of its stage folders).
    pub run: PathBuf,
    /// The report's folder.
    pub out: PathBuf,
    /// How each stage ended in the run; empty: every stage folder as it is.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub stages: StageOutcomes,
}

/// Why a report job did not write its report.
#[derive(Debug, thiserror::Error)]
pub enum ReportJobError {
    #[error(transparent)]
    Project(#[from] super::project::ProjectError),
    #[error("{}: the report would be written into the {stage} stage's folder {}: give the report its own folder (nothing was written)", out.display(), folder.display())]
    IntoStage { out: PathBuf, stage: &'static str, folder: PathBuf },
    #[error(transparent)]
    Folder(#[from] crate::io::OutputFolderError),
    #[error(transparent)]
    Mark(#[from] crate::io::WriteError),
    #[error(transparent)]
    Report(#[from] ReportError),
}

impl ReportJob {
    /// The job's command line (`lucent report …`), as a stage's manifest records it.
    pub fn to_args(&self) -> Vec<String> {
        let s = |p: &Path| p.display().to_string();
        vec!["report".into(), s(&self.project), "--run".into(), s(&self.run), "--out".into(), s(&self.out)]
    }

    /// The report folder is neither the run's folder nor a stage's (it
    /// would mix its files with theirs).
    pub fn validate(&self) -> Result<(), ReportJobError> {
        let key = crate::io::file_key;
        let out = key(&self.out);
        let stages = Stage::ALL.iter().filter(|s| **s != Stage::Report);
        for (name, folder) in
            std::iter::once(("run", self.run.clone())).chain(stages.map(|s| (s.name(), self.run.join(s.name()))))
        {
            if out == key(&folder) {
                return Err(ReportJobError::IntoStage { out: self.out.clone(), stage: name, folder });
            }
        }
        Ok(())
    }

    /// Reads the project and writes the report ([`ReportJob::run_on`],
    /// which checks the job first).
    pub fn run(&self) -> Result<ReportFiles, ReportJobError> {
        let project = Project::load(&self.project)?;
        self.run_on(&project)
    }

    /// Writes the report of `project` (the job's project, as loaded) into
    /// the job's folder: refused before any work when the folder is the
    /// user's, marked as lucent's when written.
    pub fn run_on(&self, project: &Project) -> Result<ReportFiles, ReportJobError> {
        self.validate()?;
        let folder = OutputFolder::open(Some(&self.out))?;
        let written = write(project, &self.run, &self.out, &self.stages);
        folder.close(written.is_ok(), false)?;
        Ok(written?)
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
pub fn write(project: &Project, out: &Path, dir: &Path, stages: &StageOutcomes) -> Result<ReportFiles, ReportError> {
    let mut page = Page::new(dir.join("img"));
    let folder = |s: Stage| stage_folder(out, stages, s);
    let mut manifests: Vec<(Stage, Manifest)> = Vec::new();
    // The stages the report is of (its own folder's manifest is written after it).
    for s in Stage::ALL.into_iter().filter(|s| *s != Stage::Report) {
        if let Some(m) = read_json(&StageFiles::in_dir(&folder(s)).manifest, "a stage manifest")? {
            manifests.push((s, m));
        }
    }
    let mut metrics = Metrics::new();
    let mut html = project_heading(project, &mut metrics);
    let stage_table = stages_section(stages, &manifests, &mut metrics);
    // The answer, per sample, before any detail.
    for smp in &project.file.sample {
        let render = RenderFiles::in_dir(&folder(Stage::Render).join(&smp.name));
        html.push_str(&compare_section(smp, &folder, &render).answer(&mut page)?);
    }
    html.push_str(&stage_table);
    let all_spectra = read_spectra(&OpticsFiles::in_dir(&folder(Stage::Optics)))?;
    let mut samples = Metrics::new();
    for smp in &project.file.sample {
        let (h, sj) = sample_sections(&mut page, project, smp, &all_spectra, &folder)?;
        html.push_str(&h);
        samples.insert(smp.name.clone(), Value::Object(sj));
    }
    metrics.insert("samples".into(), Value::Object(samples));
    html.push_str(&calibration_sections(&mut page, project, &folder, &mut metrics)?);
    html.push_str(&manifest_section(&manifests, &mut metrics));
    let html = format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{} — lucent report</title>\n<style>{STYLE}</style></head>\n<body>{}</body></html>\n",
        esc(&project.name),
        html
    );
    let files = ReportFiles::in_dir(dir);
    crate::io::write_json(&files.metrics, &Value::Object(metrics))?;
    crate::io::write_atomic(&files.html, html.as_bytes())?;
    Ok(files)
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

/// A sample's comparison (stage compare's folders under `folder`), its
/// section showing the picture of `render` when there is none.
fn compare_section<'a>(
    smp: &'a SampleSection,
    folder: &impl Fn(Stage) -> PathBuf,
    render: &'a RenderFiles,
) -> CompareSection<'a> {
    let dirs = CompareDirs::in_dir(&folder(Stage::Compare).join(&smp.name));
    CompareSection {
        sample: &smp.name,
        image: CompareFiles::in_dir(&dirs.image),
        object: CompareFiles::in_dir(&dirs.object),
        truth_recipe: smp.truth_recipe.as_deref(),
        render,
    }
}

/// A sample's details, one section per stage from that stage's files under
/// `folder(stage)` (optics, surface, bssrdf, fit, env-scale, render, compare; without
/// a comparison the render's picture), with their numbers for metrics.json.
fn sample_sections(
    page: &mut Page,
    project: &Project,
    smp: &SampleSection,
    all_spectra: &[OpticalProperties],
    folder: &impl Fn(Stage) -> PathBuf,
) -> Result<(String, Metrics), ReportError> {
    let sample_dir = |s: Stage| folder(s).join(&smp.name);
    let (optics_dir, bssrdf_dir) = (folder(Stage::Optics), sample_dir(Stage::Bssrdf));
    let configs = project.bssrdf_configs.iter().map(|&c| BssrdfConfigFiles {
        config: c,
        slice: SliceFiles::in_dir(Path::new(&bssrdf_run_dir(
            &bssrdf_dir.display().to_string(),
            &project.bssrdf_configs,
            c,
        ))),
        comparison: ComparisonFiles::in_dir(&bssrdf_comparison_dir(&bssrdf_dir, c)),
    });
    let render = RenderFiles::in_dir(&sample_dir(Stage::Render));
    let sections: [&dyn ReportSection; 7] = [
        &OpticsSection {
            sample: &smp.name,
            recipe: &smp.recipe,
            weight_percent: smp.weight_percent,
            spectra: all_spectra,
            dir: &optics_dir,
        },
        &SurfaceFitFiles::in_dir(&sample_dir(Stage::Surface)),
        &BssrdfSection { sample: &smp.name, dir: &bssrdf_dir, configs: configs.collect() },
        &FitSection {
            sample: &smp.name,
            files: FitFiles::in_dir(&sample_dir(Stage::Fit)),
            truth_recipe: smp.truth_recipe.as_deref(),
        },
        &EnvScaleFiles::in_dir(&sample_dir(Stage::EnvScale)),
        &render,
        &compare_section(smp, folder, &render),
    ];
    let (mut ctx, mut sj) = (SectionContext::new(page), Metrics::new());
    let mut h =
        format!("<section id=\"sample-{}\"><h2>Sample {}: details per stage</h2>", slug(&smp.name), esc(&smp.name));
    for s in sections {
        h.push_str(&s.section(&mut ctx, &mut sj)?);
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
    let file = &project.file;
    let colour_dir = folder(Stage::Colour);
    let sections: [&dyn ReportSection; 3] = [
        &CalibrateSection {
            files: CalibrationFiles::in_dir(&folder(Stage::Calibrate)),
            truth: file.calibration.as_ref().and_then(|c| c.truth.as_deref()),
        },
        &ColourSection {
            dir: &colour_dir,
            cameras: file
                .colour
                .iter()
                .map(|c| ColourCamera { camera: &c.camera, truth: c.truth.as_deref() })
                .collect(),
        },
        &PoseSection {
            files: PoseFiles::in_dir(&folder(Stage::Pose)),
            truth: file.pose.as_ref().and_then(|p| p.truth.as_deref()),
        },
    ];
    let mut ctx = SectionContext::new(page);
    let mut h = String::from("<section><h2>Calibration</h2>");
    let before = h.len();
    for s in sections {
        h.push_str(&s.section(&mut ctx, metrics)?);
    }
    if h.len() == before {
        h.push_str("<p class=\"note\">No calibration in this project.</p>");
    }
    h.push_str("</section>");
    Ok(h)
}

/// The stages' table: each stage's outcome in the run that made the report
/// (`stages`) and its wall time from its manifest.
fn stages_section(stages: &StageOutcomes, manifests: &[(Stage, Manifest)], metrics: &mut Metrics) -> String {
    let mut rows = Vec::new();
    let mut stage_json = serde_json::Map::new();
    for s in Stage::ALL.iter().filter(|s| **s != Stage::Report) {
        let m = manifests.iter().find(|(d, _)| d == s).map(|(_, m)| m);
        let text = match (stages.get(s), m) {
            (Some(outcome), _) => outcome.text(),
            (None, Some(_)) if stages.is_empty() => "as in the run's folder (its manifest)".to_string(),
            (None, _) => "not run".to_string(),
        };
        let wall = m.map(|m| format!("{:.2} s", m.wall_s)).unwrap_or_else(|| "—".into());
        rows.push(vec![s.name().to_string(), text.clone(), wall]);
        stage_json.insert(s.name().into(), json!({"status": text, "wall_s": m.map(|m| m.wall_s)}));
    }
    metrics.insert("stages".into(), Value::Object(stage_json));
    format!("<h2>Stages</h2>{}", table(&["stage", "in the run that made this report", "wall time (last run)"], &rows))
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
