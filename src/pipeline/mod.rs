//! `lucent run PROJECT.toml`: the whole digitisation from one project file
//! (docs/method.md#pipeline). The stages are a closed set ([`Stage`]) run in dependency
//! order, each into its own folder under the output folder:
//!
//! | stage | does | needs |
//! |---|---|---|
//! | `optics` | `lucent optics` on every sample's recipe | `[[sample]]` |
//! | `surface` | `lucent surface fit` of each sample's height map (`surface/NAME/`: fit.json, normals.exr, plots) | a sample's `surface` |
//! | `bssrdf` | `lucent bssrdf` slices per sample (top boundary: `[bssrdf] roughness`, else the sample's fitted surface, `--roughness measured:surface/NAME/fit.json`, else the recipe's `[surface]`), `bssrdf compare` with measured slices | `[bssrdf]` |
//! | `fit` | `lucent fit` of each sample's recipe to its measured slices; writes the fitted recipe when the data pin it down | `[fit]`, a sample's `[[sample.measured]]` |
//! | `calibrate` | `lucent calibrate` (Zhang) | `[calibration]` |
//! | `colour` | `lucent colour calibrate` per camera | `[[colour]]` |
//! | `develop` | `lucent colour apply`: a sample's photo and empty board (RAW or EXR in its camera's RGB) → CIE RGB; of a RAW also `lucent raw clipped`, the mask env-scale and compare then use, and the photo's per-pixel variance from the RAW's noise model (`--variance-out`, var P of the model RMSE) | a sample's `camera` |
//! | `pose` | `lucent pose` on the sample photo | `[pose]` and the `calibrate` output |
//! | `env-scale` | `lucent env fit-scale` per sample | `[render]`, a sample's `empty_board` |
//! | `render` | `lucent render` per sample (the scene template with the sample's recipe, and the fitted scale); with a fitted recipe from stage fit, also the fitted twin (`render/NAME/fitted/`) | `[render]` |
//!
//! **The camera of env-scale and render.** With a `[pose]` (and unless
//! `[render] camera = "template"`), the scene template's camera, board
//! geometry and object placement are replaced by the pose stage's
//! `scene.json` ([`pose_frame`]): `[camera] scene_json` with
//! `distortion = "calibrated"` and the calibrate stage's `camera.json` (the
//! photo is rendered in its raw, distorted geometry), the board's squares from
//! `scene.json` (the template keeps its reflectances and margin), and the
//! object at `placement = "scene"` when the pose placed a sample (the finite
//! sphere then centred on its top). Without a `[pose]` the template is used
//! as it is.
//! | `compare` | `lucent compare` photo vs render per sample (minus clipped pixels, with the photo's variance from develop), and the same over the object's pixels (`NAME/object/`: the render's `object` layer, any mesh); with a fitted twin, both twins (recipe = A, fitted = B) and which is closer | a sample's `photo`, its render |
//! | `report` | `report/index.html` and `report/metrics.json` ([`report`]) | any stage's output |
//!
//! A stage's work is a list of [`Task`]s — validated jobs ([`crate::job`]),
//! run by the executor `lucent run` hands in (in this process, or as shards
//! on a cluster), with files to write first — planned just before it runs
//! ([`plan`]), so a stage reads what the stages before it wrote; its
//! manifest.json records each job as its canonical `lucent` command line.
//! Its **key** is the SHA-256 of: the stage name, the
//! lucent version, the tasks (typed jobs and file contents), the
//! content of every input file, and the output hash of the stages it
//! depends on. A stage whose key equals the one in its folder's
//! `manifest.json`, and whose outputs still hash to what the manifest says,
//! is skipped; `--force STAGE` reruns it. A stage runs into its final folder
//! after the previous result is moved aside; if it fails the partial output
//! is moved to `STAGE.failed/` (with `log.txt`), the previous result is put
//! back, and the run stops: earlier results stay intact.
//!
//! A stage a project gives nothing to do is skipped and leaves no folder,
//! so it adds nothing to the keys of the stages after it: a project without
//! surfaces keeps the keys it had before the surface stage existed.
//!
//! ```
//! use lucent::pipeline::Stage;
//! assert_eq!(Stage::from_name("env-scale").unwrap(), Stage::EnvScale);
//! assert!(Stage::from_name("rendr").unwrap_err().to_string().contains("render"));
//! assert_eq!(Stage::ALL.last(), Some(&Stage::Report));
//! ```

pub mod executor;
mod layout;
pub mod project;
pub mod report;
mod stage;

pub use layout::{
    bssrdf_comparison_dir, bssrdf_run_dir, CompareDirs, DevelopFiles, InputHash, Manifest, SampleRenderFiles,
    StageFiles,
};
pub use stage::{Skip, Stage, Status, UnknownStage};

use crate::ccm_file::ColourFiles;
use crate::envfit;
use crate::envfit::EnvScaleFiles;
use crate::fault::Fault;
use crate::fit::report::FitFiles;
use crate::job::{
    BssrdfCompareJob, ColourApplyJob, ColourCalibrateJob, CompareJob, EnvScaleJob, ImageSize, Job, OpticsJob,
    RawClippedJob, RenderJob,
};
use crate::scene::band::RenderBandFiles;
use crate::scene::RenderFiles;
use lucent_calib::calibrate::CalibrationFiles;
use lucent_calib::scene::PoseFiles;
use lucent_colour::WavelengthGrid;
use project::Project;
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::path::{Path, PathBuf};
use std::time::Instant;
use thiserror::Error;

/// One unit of a stage's work.
// A stage plans a handful of tasks: boxing the job would buy nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug, Clone, PartialEq)]
pub enum Task {
    /// Write these files (path relative to the stage folder, contents), then
    /// run the job (`{out}` in a path or word stands for the stage folder,
    /// [`Job::with_out`]); manifest.json records it as its command line
    /// ([`Job::to_args`]).
    Lucent { label: String, files: Vec<(String, String)>, job: Job },
    /// Write the report: the stage's [`report::ReportJob`], made when the
    /// stage runs (it carries how the stages before it ended).
    Report,
}

/// A task as it goes into the stage key: the typed job (its JSON form).
impl Serialize for Task {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        enum Form<'a> {
            Lucent { label: &'a str, files: &'a [(String, String)], job: &'a Job },
            Report,
        }
        match self {
            Task::Lucent { label, files, job } => Form::Lucent { label, files, job },
            Task::Report => Form::Report,
        }
        .serialize(serializer)
    }
}

/// What a stage will do.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    pub tasks: Vec<Task>,
    /// Files whose content goes into the key.
    pub inputs: Vec<PathBuf>,
    /// Notes for the status line (e.g. samples left out and why).
    pub notes: Vec<String>,
}

/// The class of a failure, the pipeline's and Slurm's errors included: a
/// stage that failed has its class, a Slurm failure is the environment's
/// ([`Fault::of_with`] with the pipeline's classifier).
pub fn fault_of(error: &(dyn std::error::Error + 'static)) -> Fault {
    Fault::of_with(error, &[classify])
}

/// The class of the pipeline's own errors that know it (`None` for others).
fn classify(e: &(dyn std::error::Error + 'static)) -> Option<Fault> {
    if let Some(PipelineError::Failed { fault, .. }) = e.downcast_ref() {
        return Some(*fault);
    }
    e.is::<executor::SlurmError>().then_some(Fault::Environment)
}

/// Why the pipeline stopped.
#[derive(Debug, Error)]
pub enum PipelineError {
    /// A stage cannot be planned: [`StageProblem`] says why.
    #[error("stage {stage}: {problem}")]
    Stage {
        stage: Stage,
        #[source]
        problem: StageProblem,
    },
    /// A task failed; `fault` says who is at fault ([`crate::fault`]).
    #[error(
        "stage {stage} failed ({fault}): {message}\n  partial output and log kept in {kept}; earlier stages' results \
         are intact"
    )]
    Failed { stage: Stage, fault: crate::fault::Fault, message: TaskError, kept: PathBuf },
    /// A file or folder of the output tree could not be created, moved or removed.
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    /// An input file (hashed for a stage's key) could not be read.
    #[error("{path}: cannot read input: {source}")]
    Input { path: PathBuf, source: std::io::Error },
    /// The `[render]` scene template (or env-scale's fitted scene) is not a
    /// valid scene file (the message names the file and key).
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneFileError),
    /// The `[render]` scene template (with a sample's recipe) is not a valid scene.
    #[error("{project}: [render] scene (for sample {sample}): {source}")]
    Template { project: PathBuf, sample: String, source: Box<crate::scene::SceneFileError> },
    /// The `[render]` scene template has no `[material]` to take the samples' recipes.
    #[error("{path}: the [render] scene has no [material]: the samples' recipes need one to replace")]
    SceneWithoutMaterial { path: PathBuf },
    #[error("{path}: cannot write the sample's scene as TOML: {source}")]
    SceneToml { path: PathBuf, source: toml::ser::Error },
    /// The pose stage's `scene.json` cannot be read.
    #[error("{path}: cannot read: {source}")]
    Read { path: PathBuf, source: std::io::Error },
    #[error("{path}: not a scene.json written by `lucent pose`: {source}")]
    PoseJson { path: PathBuf, source: serde_json::Error },
    /// A stage's manifest could not be written (the message names the file).
    #[error(transparent)]
    Write(#[from] crate::io::WriteError),
    /// The output folder is not one lucent wrote (see [`crate::io::claim_output_folder`]).
    #[error(transparent)]
    Output(#[from] crate::io::OutputFolderError),
    /// Where a stage's folder goes there is a file, or a folder lucent did not write: it is left alone.
    #[error(
        "{path}: is {what}, where stage {stage} writes its folder; lucent leaves it alone — move it away or choose \
         another output folder"
    )]
    Foreign { path: PathBuf, what: String, stage: Stage },
    /// The output folder holds the results of another project: its stages
    /// would be mixed into this one's (a stale fit rendered, a report of both).
    #[error(
        "{out}: holds the results of project {earlier:?} ({earlier_file}), not of {name:?} ({file}); a run of {name:?} \
         there would mix the two projects' stages — choose another output folder (--out), or remove {out} to start clean"
    )]
    OtherProject { out: PathBuf, earlier: String, earlier_file: String, name: String, file: String },
}

/// `OUT/.lucent-project`: the project whose results an output folder of
/// `lucent run` holds (its name and project file).
pub const PROJECT_MARK: &str = ".lucent-project";

#[derive(Serialize, Deserialize)]
struct ProjectMark {
    project: String,
    project_file: String,
}

/// The project whose results `out` holds: [`PROJECT_MARK`], else (a folder of
/// a run before the mark) the name in `report/metrics.json`.
fn earlier_project(out: &Path) -> Option<ProjectMark> {
    if let Ok(t) = std::fs::read_to_string(out.join(PROJECT_MARK)) {
        return serde_json::from_str(&t).ok();
    }
    let t = std::fs::read_to_string(report::ReportFiles::in_dir(&out.join(Stage::Report.name())).metrics).ok()?;
    let v: serde_json::Value = serde_json::from_str(&t).ok()?;
    Some(ProjectMark {
        project: v.get("project")?.as_str()?.to_string(),
        project_file: v.get("project_file").and_then(|f| f.as_str()).unwrap_or("?").to_string(),
    })
}

/// Why a stage cannot be planned (the `problem` of [`PipelineError::Stage`]).
#[derive(Debug, Error)]
pub enum StageProblem {
    #[error("no [render]")]
    NoRender,
    /// The render's camera comes from the pose stage but its output is missing.
    #[error(
        "the render's camera comes from the pose stage ([pose] is given) but {missing} is missing; run the \
         calibrate and pose stages, or set [render] camera = \"template\" to keep the scene's camera"
    )]
    PoseOutputMissing { missing: PathBuf },
    /// A sample's photo is in a camera's RGB but the develop stage has not written its CIE RGB version.
    #[error("{sample}: {photo} is in camera {camera:?}'s RGB but the develop stage has not written {expected}")]
    NotDeveloped { sample: String, photo: PathBuf, camera: String, expected: PathBuf },
    #[error("[calibration] images: {0}")]
    CalibrationImages(crate::io::GlobError),
    #[error("[calibration] images {pattern:?}: no file matches")]
    NoCalibrationImages { pattern: String },
    #[error("{sample}: camera {camera:?} has no ccm.json from the colour stage")]
    NoCcm { sample: String, camera: String },
    /// A photo larger than `[render] size` by other than one integer factor.
    #[error(
        "{sample}: {photo} is {photo_size} pixels and [render] size is {render_size}: the photo is binned to \
         the render's size, so it must be the same size or an integer multiple of it in both directions"
    )]
    PhotoSize { sample: String, photo: PathBuf, photo_size: String, render_size: String },
    #[error("{sample}: {photo}: {reason}")]
    PhotoUnreadable { sample: String, photo: PathBuf, reason: String },
    /// A sample's surface is its slices' top boundary but the surface stage has not written its fit.
    #[error("{sample}: its surface is the slices' top boundary but the surface stage has not written {expected}")]
    NoSurfaceFit { sample: String, expected: PathBuf },
}

/// Why a task of a stage failed.
#[derive(Debug, Error)]
pub enum TaskError {
    /// A file the task hands to its command could not be written.
    #[error("{label}: {source}")]
    Write { label: String, source: crate::io::WriteError },
    /// The job's `{out}` could not be replaced by the stage folder.
    #[error("{label}: cannot place the job in its stage folder: {source}")]
    Place { label: String, source: crate::fault::Internal },
    /// The command failed ([`Executor`]'s error).
    #[error("{label}: {source}")]
    Command { label: String, source: Box<dyn std::error::Error + Send + Sync> },
    #[error(transparent)]
    Report(#[from] report::ReportJobError),
}

/// Options of a run.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// Stages to rerun even when up to date.
    pub force: Vec<Stage>,
    /// Run only up to (and including) this stage.
    pub until: Option<Stage>,
}

/// Hex SHA-256 of bytes (the jobs' [`crate::job::sha256_hex`]).
pub use crate::job::sha256_hex;

/// Hash of one file, streamed.
pub fn hash_file(path: &Path) -> Result<InputHash, PipelineError> {
    use std::io::Read;
    let err = |source| PipelineError::Input { path: path.to_path_buf(), source };
    let mut f = std::fs::File::open(path).map_err(err)?;
    let mut h = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    let mut n = 0u64;
    loop {
        let k = f.read(&mut buf).map_err(err)?;
        if k == 0 {
            break;
        }
        n += k as u64;
        h.update(&buf[..k]);
    }
    Ok(InputHash { path: path.display().to_string(), bytes: n, sha256: format!("{:x}", h.finalize()) })
}

/// Files under `dir`, relative paths sorted, excluding the manifest and log.
pub fn output_files(dir: &Path) -> Vec<String> {
    fn walk(base: &Path, dir: &Path, out: &mut Vec<String>) {
        let Ok(rd) = std::fs::read_dir(dir) else { return };
        for e in rd.flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(base, &p, out);
            } else if let Ok(rel) = p.strip_prefix(base) {
                let r = rel.to_string_lossy().replace('\\', "/");
                if !StageFiles::NAMES.contains(&r.as_str()) && !r.starts_with('.') {
                    out.push(r);
                }
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

/// SHA-256 over the names and contents of a stage folder's outputs.
pub fn outputs_hash(dir: &Path) -> Result<String, PipelineError> {
    let mut h = Sha256::new();
    for f in output_files(dir) {
        h.update(f.as_bytes());
        h.update([0]);
        h.update(hash_file(&dir.join(&f))?.sha256.as_bytes());
    }
    Ok(format!("{:x}", h.finalize()))
}

/// The hash of the outputs a stage's manifest lists (files added to the
/// folder since, e.g. the user's notes, do not change it); without a
/// manifest, of every file in the folder ([`outputs_hash`]).
pub fn listed_outputs_hash(dir: &Path) -> Result<String, PipelineError> {
    match read_manifest(dir) {
        Some(m) => hash_listed(dir, &m.outputs),
        None => outputs_hash(dir),
    }
}

fn hash_listed(dir: &Path, files: &[String]) -> Result<String, PipelineError> {
    let mut h = Sha256::new();
    for f in files {
        h.update(f.as_bytes());
        h.update([0]);
        h.update(hash_file(&dir.join(f))?.sha256.as_bytes());
    }
    Ok(format!("{:x}", h.finalize()))
}

/// Every file (and symbolic link) under `dir`, relative paths sorted, hidden
/// ones included; symbolic links to folders are not followed.
fn all_files(dir: &Path) -> Vec<String> {
    fn walk(base: &Path, dir: &Path, out: &mut Vec<String>) {
        let Ok(rd) = std::fs::read_dir(dir) else { return };
        for e in rd.flatten() {
            let p = e.path();
            let Ok(meta) = std::fs::symlink_metadata(&p) else { continue };
            if meta.is_dir() {
                let before = out.len();
                walk(base, &p, out);
                if out.len() == before
                    && let Ok(rel) = p.strip_prefix(base)
                {
                    // An empty folder of the user's is kept too.
                    out.push(format!("{}/", rel.to_string_lossy().replace('\\', "/")));
                }
            } else if let Ok(rel) = p.strip_prefix(base) {
                out.push(rel.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

/// The files in a stage folder that lucent did not write: not listed in
/// the folder's manifest, or listed with a hash the file no longer has (the
/// user edited it). The manifest, the log and the mark of a stage under way
/// are lucent's. Relative paths; an empty folder ends with `/`.
pub fn users_files(dir: &Path, manifest: Option<&Manifest>) -> Vec<String> {
    let Some(m) = manifest else { return Vec::new() };
    let listed: std::collections::BTreeSet<&str> = m.outputs.iter().map(String::as_str).collect();
    let hashes: std::collections::BTreeMap<&str, &str> =
        m.files.iter().map(|f| (f.path.as_str(), f.sha256.as_str())).collect();
    all_files(dir)
        .into_iter()
        .filter(|f| {
            if StageFiles::NAMES.contains(&f.as_str()) || f == STAGE_MARK {
                return false;
            }
            if !listed.contains(f.as_str()) {
                // Empty folders lucent made are not listed; keep only ones
                // that are not a prefix of a listed output.
                return !(f.ends_with('/') && listed.iter().any(|l| l.starts_with(f.as_str())));
            }
            match hashes.get(f.as_str()) {
                Some(h) => hash_file(&dir.join(f)).map_or(true, |now| now.sha256 != *h),
                None => false,
            }
        })
        .collect()
}

/// Moves the user's files `kept` from `from` (the previous result, moved
/// aside) into the stage folder `to`. A name lucent has now written itself
/// gets the user's file as `NAME.yours` (or `NAME.yours-2`, …). Returns one
/// warning per file, naming where it is now.
fn carry_users_files(from: &Path, to: &Path, kept: &[String], stage: Stage) -> Vec<String> {
    let mut warnings = Vec::new();
    for f in kept {
        let src = from.join(f.trim_end_matches('/'));
        if std::fs::symlink_metadata(&src).is_err() {
            continue;
        }
        let mut dst = to.join(f.trim_end_matches('/'));
        if f.ends_with('/') {
            if !dst.exists() {
                let _ = std::fs::create_dir_all(&dst);
            }
            let _ = std::fs::remove_dir(&src);
            continue;
        }
        if std::fs::symlink_metadata(&dst).is_ok() {
            let mut k = 1;
            loop {
                let suffix = if k == 1 { ".yours".to_string() } else { format!(".yours-{k}") };
                let mut name = dst.as_os_str().to_owned();
                name.push(&suffix);
                let alt = PathBuf::from(name);
                if std::fs::symlink_metadata(&alt).is_err() {
                    dst = alt;
                    break;
                }
                k += 1;
            }
        }
        if let Some(parent) = dst.parent() {
            let _ = std::fs::create_dir_all(parent);
        }
        match std::fs::rename(&src, &dst) {
            Ok(()) => warnings.push(format!(
                "warning: kept {}: not a file lucent wrote (not in {}/manifest.json, or edited since); \
                 lucent leaves it alone",
                dst.display(),
                stage.name()
            )),
            Err(e) => warnings.push(format!(
                "warning: {} is not a file lucent wrote and could not be put back ({e}); it is still in {}",
                f,
                from.display()
            )),
        }
    }
    warnings
}

fn read_manifest(dir: &Path) -> Option<Manifest> {
    serde_json::from_str(&crate::io::read_text(StageFiles::in_dir(dir).manifest).ok()?).ok()
}

/// The scene file a sample renders: the project's template with the
/// sample's recipe, paths made absolute; from env-scale's scene when that
/// stage fitted one for the sample.
fn sample_scene(
    project: &Project,
    out: &Path,
    sample: &project::SampleSection,
    use_fitted: bool,
) -> Result<String, PipelineError> {
    sample_scene_with(project, out, sample, use_fitted, None)
}

/// The recipe stage fit wrote for `sample` (`fit/NAME/*_fitted.toml`), if
/// any and if the project has a `[fit]` (a fit of an earlier version of the
/// project, left in its folder, is not this project's).
pub fn fitted_recipe(project: &Project, out: &Path, sample: &project::SampleSection) -> Option<PathBuf> {
    if project.file.fit.is_none() || sample.measured.is_empty() {
        return None;
    }
    let stem = sample.recipe.file_stem()?.to_string_lossy().into_owned();
    let p = FitFiles::in_dir(&out.join(Stage::Fit.name()).join(&sample.name)).fitted_recipe(&stem);
    p.is_file().then_some(p)
}

/// Whether the recipe at `path` gives an input with an uncertainty (false
/// when it does not load: the render stage then says why).
fn recipe_has_uncertain_input(path: &Path) -> bool {
    crate::optics::recipe::Recipe::load(path, Default::default()).is_ok_and(|r| !r.uncertain.is_empty())
}

/// [`sample_scene`] with `recipe` (a fitted recipe, its weight percentage
/// inside) in place of the sample's.
fn sample_scene_with(
    project: &Project,
    out: &Path,
    sample: &project::SampleSection,
    use_fitted: bool,
    recipe: Option<&Path>,
) -> Result<String, PipelineError> {
    let Some(r) = &project.file.render else {
        return Err(PipelineError::Stage { stage: Stage::Render, problem: StageProblem::NoRender });
    };
    let fitted = EnvScaleFiles::in_dir(&out.join(Stage::EnvScale.name()).join(&sample.name)).toml;
    // env-scale's scene only where this project has that stage for the sample.
    let source = if use_fitted && sample.empty_board.is_some() && fitted.is_file() { fitted } else { r.scene.clone() };
    let text = crate::io::read_text(&source).map_err(|e| PipelineError::Read { path: source.clone(), source: e })?;
    let file = crate::scene::parse(&text, &source)?;
    let mut file = envfit::with_paths_from(&file, &envfit::scene_dir(&source));
    match &mut file.material {
        Some(m) => {
            m.recipe = Some(recipe.map_or_else(|| sample.recipe.clone(), Path::to_path_buf));
            m.weight_percent = if recipe.is_some() { None } else { sample.weight_percent };
            m.sigma_s_per_m = None;
            m.sigma_a_per_m = None;
            m.g = None;
            m.n = None;
        }
        None => {
            return Err(PipelineError::SceneWithoutMaterial { path: source });
        }
    }
    // The template as the user wrote it (with the sample's recipe): an error
    // names their file and key, not the input_scene.toml written from it.
    crate::scene::check(&file, &source).map_err(|e| PipelineError::Template {
        project: project.path.clone(),
        sample: sample.name.clone(),
        source: Box::new(e),
    })?;
    let frame = pose_frame(project, out)?;
    if let Some((scene_json, camera_json, has_sample)) = &frame {
        file.camera = crate::scene::CameraSection {
            scene_json: Some(scene_json.clone()),
            camera_json: Some(camera_json.clone()),
            distortion: Some("calibrated".into()),
            ..Default::default()
        };
        if let Some(b) = &mut file.board {
            (b.origin_m, b.u, b.v, b.columns, b.rows, b.square_mm) = (None, None, None, None, None, None);
        }
        if *has_sample {
            if let Some(o) = &mut file.object {
                (o.placement, o.transform, o.board_corner) = (Some("scene".into()), None, None);
            }
            file.environment.centre_m = None;
        }
    }
    let body =
        toml::to_string_pretty(&file).map_err(|e| PipelineError::SceneToml { path: source.clone(), source: e })?;
    let camera = if frame.is_some() { ", camera, board and placement from the pose stage" } else { "" };
    let whose = match recipe {
        Some(r) => format!("the fitted recipe {} of sample {}", r.display(), sample.name),
        None => format!("the recipe of sample {}", sample.name),
    };
    Ok(format!("# {} with {whose}{camera} (written by `lucent run`)\n{body}", source.display()))
}

/// The pose stage's frame for env-scale and render (see the module doc):
/// `(scene.json, camera.json, whether the pose placed a sample)`, or `None`
/// when the project has no `[pose]` or `[render] camera = "template"`. An
/// error when the pose stage's or calibrate stage's output is missing.
pub fn pose_frame(project: &Project, out: &Path) -> Result<Option<(PathBuf, PathBuf, bool)>, PipelineError> {
    let f = &project.file;
    let template = f.render.as_ref().and_then(|r| r.camera.as_deref()) == Some("template");
    if f.pose.is_none() || template {
        return Ok(None);
    }
    let scene_json = PoseFiles::in_dir(&out.join(Stage::Pose.name())).json;
    let camera_json = CalibrationFiles::in_dir(&out.join(Stage::Calibrate.name())).camera;
    for p in [&scene_json, &camera_json] {
        // Without a [calibration] the calibrate stage's camera is not this project's.
        if !p.is_file() || f.calibration.is_none() {
            return Err(PipelineError::Stage {
                stage: Stage::Render,
                problem: StageProblem::PoseOutputMissing { missing: p.clone() },
            });
        }
    }
    let text =
        crate::io::read_text(&scene_json).map_err(|source| PipelineError::Read { path: scene_json.clone(), source })?;
    let pose: lucent_calib::scene::SceneDescription =
        serde_json::from_str(&text).map_err(|source| PipelineError::PoseJson { path: scene_json.clone(), source })?;
    let has_sample = pose.sample.is_some();
    Ok(Some((scene_json, camera_json, has_sample)))
}

pub use crate::job::shard::{recipe_inputs, scene_inputs};

/// The photo `which` ("photo" or "empty_board") of a sample as the stages
/// after develop read it: the develop stage's CIE RGB EXR when the sample
/// names a camera, else the file as given.
fn developed(
    out: &Path,
    smp: &project::SampleSection,
    which: &str,
    given: Option<&Path>,
) -> Result<PathBuf, PipelineError> {
    let given = given.map(Path::to_path_buf).unwrap_or_default();
    if smp.camera.is_none() {
        return Ok(given);
    }
    let p = DevelopFiles::in_dir(&out.join(Stage::Develop.name()).join(&smp.name), which).exr;
    if p.is_file() {
        Ok(p)
    } else {
        Err(PipelineError::Stage {
            stage: Stage::Develop,
            problem: StageProblem::NotDeveloped {
                sample: smp.name.clone(),
                photo: given,
                camera: smp.camera.clone().unwrap_or_default(),
                expected: p,
            },
        })
    }
}

/// How many photo pixels a side make one render pixel: the photo's size
/// over `[render] size` (1 without one, or when they are equal). A photo
/// larger than the render by an integer factor is binned to it by the
/// develop stage (a box filter, as the renderer's pixels integrate).
fn photo_bin(sample: &str, photo: &Path, render_size: Option<ImageSize>) -> Result<usize, StageProblem> {
    let Some(ImageSize { width: rw, height: rh }) = render_size else { return Ok(1) };
    let unreadable =
        |reason: String| StageProblem::PhotoUnreadable { sample: sample.into(), photo: photo.to_path_buf(), reason };
    // The header only (RAW: the developed size from the file's tags): planning needs the size, not the pixels.
    let (pw, ph) = crate::imageio::image_size(photo).map_err(|e| unreadable(e.to_string()))?;
    let k = pw / rw;
    if k >= 1 && pw == k * rw && ph == k * rh {
        Ok(k)
    } else {
        Err(StageProblem::PhotoSize {
            sample: sample.into(),
            photo: photo.to_path_buf(),
            photo_size: format!("{pw} × {ph}"),
            render_size: format!("{rw} × {rh}"),
        })
    }
}

/// The develop stage's mask of validly recorded pixels (not at or near a
/// clipped photosite) of a sample's RAW photo `which`, if it wrote one.
fn valid_mask(out: &Path, smp: &project::SampleSection, which: &str) -> Option<PathBuf> {
    smp.camera.as_ref()?;
    let p = DevelopFiles::in_dir(&out.join(Stage::Develop.name()).join(&smp.name), which).valid;
    p.is_file().then_some(p)
}

/// The develop stage's variance of a sample's RAW photo
/// (`colour apply --variance-out`), if it wrote one.
fn photo_variance(out: &Path, smp: &project::SampleSection) -> Option<PathBuf> {
    smp.camera.as_ref()?;
    let p = DevelopFiles::in_dir(&out.join(Stage::Develop.name()).join(&smp.name), "photo").variance;
    p.is_file().then_some(p)
}

/// Whether the EXR at `path` has a channel `name` (its header only).
fn has_exr_channel(path: &Path, name: &str) -> bool {
    crate::exr::channel_names(path).is_ok_and(|names| names.iter().any(|c| c == name))
}

/// What `stage` will do for `project` with outputs under `out`; an inner
/// `Err` with the reason when the project gives it nothing to do.
pub fn plan(stage: Stage, project: &Project, out: &Path) -> Result<Result<Plan, Skip>, PipelineError> {
    let mut p = Plan { tasks: Vec::new(), inputs: Vec::new(), notes: Vec::new() };
    let planned = match stage {
        Stage::Optics => plan_optics(project, &mut p),
        Stage::Surface => plan_surface(project, &mut p),
        Stage::Bssrdf => plan_bssrdf(project, out, &mut p),
        Stage::Fit => plan_fit(project, &mut p),
        Stage::Calibrate => plan_calibrate(project, &mut p),
        Stage::Colour => plan_colour(project, &mut p),
        Stage::Develop => plan_develop(project, out, &mut p),
        Stage::Pose => plan_pose(project, out, &mut p),
        Stage::EnvScale | Stage::Render => plan_render(stage, project, out, &mut p),
        Stage::Compare => plan_compare(project, out, &mut p),
        Stage::Report => plan_report(project, &mut p),
    }?;
    Ok(planned.map(|()| p))
}

/// What a stage's planner adds to its [`Plan`]: `Ok(Err(skip))` when the
/// project gives the stage nothing to do.
type Planned = Result<Result<(), Skip>, PipelineError>;

/// A task running `job` as its lucent command.
fn lucent_task(label: String, job: Job) -> Task {
    Task::Lucent { label, files: vec![], job }
}

/// `rel` under the stage folder, as a job names it (`{out}` + `rel`).
fn under_out(rel: String) -> PathBuf {
    PathBuf::from(format!("{{out}}{rel}"))
}

/// The optics stage: every sample's recipe in one run.
fn plan_optics(project: &Project, p: &mut Plan) -> Planned {
    let f = &project.file;
    let Plan { inputs, tasks, .. } = p;
    if f.sample.is_empty() {
        return Ok(Err(Skip::Missing("[[sample]]")));
    }
    for smp in &f.sample {
        inputs.extend(recipe_inputs(&smp.recipe));
    }
    let job = OpticsJob {
        weight_percent: f.sample.iter().find_map(|s| s.weight_percent),
        ..OpticsJob::new(
            f.sample.iter().map(|smp| smp.recipe.clone()).collect(),
            f.optics.as_ref().and_then(|o| o.wavelengths.clone()).unwrap_or_else(WavelengthGrid::visible),
            under_out(String::new()),
        )
    };
    tasks.push(lucent_task(format!("{} recipes", f.sample.len()), Job::Optics(job)));
    Ok(Ok(()))
}

/// The surface stage: a surface fit of each sample's height map.
fn plan_surface(project: &Project, p: &mut Plan) -> Planned {
    let f = &project.file;
    let Plan { inputs, tasks, .. } = p;
    for smp in &f.sample {
        let Some(job) = project::surface_job(f.surface.as_ref(), smp) else { continue };
        inputs.push(job.heightmap.clone());
        tasks.push(lucent_task(format!("{} surface", smp.name), Job::SurfaceFit(job)));
    }
    if tasks.is_empty() {
        return Ok(Err(Skip::NoSurface));
    }
    Ok(Ok(()))
}

/// The surface stage's fit of `sample` (`surface/NAME/fit.json`), the
/// slices' top boundary, when the sample has a surface and `[bssrdf]` sets
/// no roughness; an error when the stage has not written it.
fn sample_surface_fit(
    project: &Project,
    out: &Path,
    smp: &project::SampleSection,
) -> Result<Option<PathBuf>, PipelineError> {
    let set = project.file.bssrdf.as_ref().is_some_and(|b| b.roughness.is_some());
    if smp.surface.is_none() || set {
        return Ok(None);
    }
    let fit = crate::surface::SurfaceFitFiles::in_dir(&out.join(Stage::Surface.name()).join(&smp.name)).json;
    if fit.is_file() {
        Ok(Some(fit))
    } else {
        Err(PipelineError::Stage {
            stage: Stage::Bssrdf,
            problem: StageProblem::NoSurfaceFit { sample: smp.name.clone(), expected: fit },
        })
    }
}

/// The bssrdf stage: each sample's slices (with its fitted surface as the
/// top boundary, when it has one) and their comparison with each measured
/// slice.
fn plan_bssrdf(project: &Project, out: &Path, p: &mut Plan) -> Planned {
    let f = &project.file;
    let Plan { inputs, tasks, notes } = p;
    let Some(b) = &f.bssrdf else { return Ok(Err(Skip::Missing("[bssrdf]"))) };
    if f.sample.is_empty() {
        return Ok(Err(Skip::Missing("[[sample]]")));
    }
    let configs = &project.bssrdf_configs;
    for smp in &f.sample {
        inputs.extend(recipe_inputs(&smp.recipe));
        let mut job = project::bssrdf_job(b, smp, project.seed);
        if let Some(fit) = sample_surface_fit(project, out, smp)? {
            notes.push(format!("{}: top boundary the measured surface {}", smp.name, fit.display()));
            job.roughness = Some(crate::surface::model::RoughnessSpec::Measured(fit));
        }
        tasks.push(lucent_task(format!("{} slices", smp.name), Job::Bssrdf(job)));
        for m in &smp.measured {
            inputs.push(m.file.clone());
            let c = m.config.pair();
            let job = BssrdfCompareJob {
                measured: m.file.clone(),
                simulated: PathBuf::from(bssrdf_run_dir(&format!("{{out}}/{}", smp.name), configs, c)),
                out: bssrdf_comparison_dir(&under_out(format!("/{}", smp.name)), c),
                measured_pixel_mm: m.pixel_mm,
                threshold: b.threshold.unwrap_or(crate::job::DEFAULT_THRESHOLD),
            };
            tasks.push(lucent_task(format!("{} vs measured {}", smp.name, m.config), Job::BssrdfCompare(job)));
        }
    }
    Ok(Ok(()))
}

/// The fit stage: a fit per sample with measured slices.
fn plan_fit(project: &Project, p: &mut Plan) -> Planned {
    let f = &project.file;
    let Plan { inputs, tasks, .. } = p;
    let Some(fit) = &f.fit else { return Ok(Err(Skip::Missing("[fit]"))) };
    for smp in f.sample.iter().filter(|s| !s.measured.is_empty()) {
        inputs.extend(recipe_inputs(&smp.recipe));
        inputs.extend(smp.measured.iter().map(|m| m.file.clone()));
        let job = project::fit_job(fit, f.bssrdf.as_ref(), smp, project.seed);
        tasks.push(lucent_task(format!("{} fit", smp.name), Job::Fit(job)));
    }
    if tasks.is_empty() {
        return Ok(Err(Skip::NoMeasured));
    }
    Ok(Ok(()))
}

/// The calibrate stage: the camera from the `[calibration]` photos.
fn plan_calibrate(project: &Project, p: &mut Plan) -> Planned {
    let f = &project.file;
    let stage = Stage::Calibrate;
    let Plan { inputs, tasks, .. } = p;
    let Some(c) = &f.calibration else { return Ok(Err(Skip::Missing("[calibration]"))) };
    let files = crate::io::glob_files(&c.images)
        .map_err(|e| PipelineError::Stage { stage, problem: StageProblem::CalibrationImages(e) })?;
    if files.is_empty() {
        return Err(PipelineError::Stage {
            stage,
            problem: StageProblem::NoCalibrationImages { pattern: c.images.clone() },
        });
    }
    inputs.extend(files);
    let job = project::calibrate_job(c, CalibrationFiles::in_dir(&under_out(String::new())).camera);
    tasks.push(lucent_task(format!("{} photos", inputs.len()), Job::Calibrate(job)));
    Ok(Ok(()))
}

/// The colour stage: a colour correction per `[[colour]]` chart photo.
fn plan_colour(project: &Project, p: &mut Plan) -> Planned {
    let f = &project.file;
    let Plan { inputs, tasks, .. } = p;
    if f.colour.is_empty() {
        return Ok(Err(Skip::Missing("[[colour]]")));
    }
    for c in &f.colour {
        inputs.push(c.image.clone());
        let job = ColourCalibrateJob {
            camera: Some(c.camera.clone()),
            corners: c.corners,
            decode_srgb: c.decode_srgb == Some(true),
            ..ColourCalibrateJob::new(
                c.image.clone(),
                under_out(format!("/{}", c.camera)),
                c.method.unwrap_or(lucent_colour::CcmMethod::Cheung2004),
            )
        };
        tasks.push(lucent_task(c.camera.clone(), Job::ColourCalibrate(job)));
    }
    Ok(Ok(()))
}

/// The develop stage: each sample's photos through its camera's colour
/// correction (with their noise and clipping when RAW).
fn plan_develop(project: &Project, out: &Path, p: &mut Plan) -> Planned {
    let f = &project.file;
    let stage = Stage::Develop;
    let Plan { inputs, tasks, .. } = p;
    for smp in &f.sample {
        let Some(cam) = &smp.camera else { continue };
        let ccm = ColourFiles::in_dir(&out.join(Stage::Colour.name()).join(cam)).ccm;
        if !ccm.is_file() {
            return Err(PipelineError::Stage {
                stage,
                problem: StageProblem::NoCcm { sample: smp.name.clone(), camera: cam.clone() },
            });
        }
        for (what, photo) in [("photo", &smp.photo), ("empty_board", &smp.empty_board)] {
            let Some(photo) = photo else { continue };
            inputs.push(photo.clone());
            let bin = photo_bin(&smp.name, photo, f.render.as_ref().and_then(|r| r.size))
                .map_err(|problem| PipelineError::Stage { stage, problem })?;
            let is_raw = crate::imageio::RAW_EXTENSIONS.contains(&crate::imageio::extension(photo).as_str());
            // The photo's noise (var P of the compare stage's model RMSE), from its RAW noise model.
            let files = DevelopFiles::in_dir(&under_out(format!("/{}", smp.name)), what);
            let variance_out = (is_raw && what == "photo").then_some((files.variance, project.seed));
            let job = ColourApplyJob {
                variance_out,
                bin,
                ..ColourApplyJob::new(ccm.clone(), photo.clone(), files.exr, crate::ccm_file::ApplyTarget::CieRgb)
            };
            tasks.push(lucent_task(format!("{} {what}", smp.name), Job::ColourApply(job)));
            if is_raw {
                let job = RawClippedJob::new(photo.clone(), files.valid, bin);
                tasks.push(lucent_task(format!("{} {what} clipping", smp.name), Job::RawClipped(job)));
            }
        }
    }
    if tasks.is_empty() {
        return Ok(Err(Skip::NoSampleCamera));
    }
    Ok(Ok(()))
}

/// The pose stage: the board's pose with the calibrated camera.
fn plan_pose(project: &Project, out: &Path, p: &mut Plan) -> Planned {
    let f = &project.file;
    let Plan { inputs, tasks, .. } = p;
    let Some(pose) = &f.pose else { return Ok(Err(Skip::Missing("[pose]"))) };
    let camera = CalibrationFiles::in_dir(&out.join(Stage::Calibrate.name())).camera;
    if f.calibration.is_none() || !camera.is_file() {
        return Ok(Err(Skip::NoCamera));
    }
    inputs.push(pose.image.clone());
    let Some(job) =
        project::pose_job(pose, f.calibration.as_ref(), camera, PoseFiles::in_dir(&under_out(String::new())).json)
    else {
        return Ok(Err(Skip::NoCamera));
    };
    tasks.push(lucent_task("board pose".into(), Job::Pose(job)));
    Ok(Ok(()))
}

/// The env-scale stage (`stage` [`Stage::EnvScale`]: each sample's empty board)
/// or the render stage (each sample's twin and, after a fit, its fitted twin).
fn plan_render(stage: Stage, project: &Project, out: &Path, p: &mut Plan) -> Planned {
    let f = &project.file;
    let Plan { inputs, notes, tasks } = p;
    let Some(r) = &f.render else { return Ok(Err(Skip::Missing("[render]"))) };
    for smp in &f.sample {
        if stage == Stage::EnvScale && smp.empty_board.is_none() {
            notes.push(format!("{}: no empty_board photo", smp.name));
            continue;
        }
        let scene_text = sample_scene(project, out, smp, stage == Stage::Render)?;
        inputs.extend(scene_inputs(&r.scene));
        inputs.extend(recipe_inputs(&smp.recipe));
        let sample_out = under_out(format!("/{}", smp.name));
        // The scenes' paths in the stage folder, as the task's files name them.
        let rel = SampleRenderFiles::in_dir(Path::new(&smp.name));
        let scene_rel = rel.scene.display().to_string();
        let scene = SampleRenderFiles::in_dir(&sample_out).scene;
        if stage == Stage::EnvScale {
            let photo = developed(out, smp, "empty_board", smp.empty_board.as_deref())?;
            inputs.push(photo.clone());
            let job = EnvScaleJob {
                scene,
                photo,
                spp: Some(r.env_spp.or(r.spp).unwrap_or(16)),
                per_channel: r.per_channel_scale == Some(true),
                mask: valid_mask(out, smp, "empty_board"),
                size: r.size,
                seed: Some(project.seed),
                out: sample_out,
                quiet: false,
                threads: None,
            };
            let job = Job::EnvScale(job);
            tasks.push(Task::Lucent { label: smp.name.clone(), files: vec![(scene_rel, scene_text)], job });
            continue;
        }
        // The band where the recipe gives an uncertain input (else a note).
        let uncertainty = r.uncertainty == Some(true) && {
            let any = recipe_has_uncertain_input(&smp.recipe);
            if !any {
                notes.push(format!(
                    "{}: [render] uncertainty: its recipe gives no input with an uncertainty (e.g. \
                     weight_percent = {{ value = 0.65, sd = 0.03 }}): rendered without a band",
                    smp.name
                ));
            }
            any
        };
        let job = RenderJob {
            scene,
            // No spp: the scene's stop rule, else the render's default (5 % on the object).
            spp: r.spp,
            quiet: true,
            time_s: r.time_s,
            size: r.size,
            seed: Some(project.seed),
            uncertainty,
            out: sample_out.clone(),
            ..RenderJob::default()
        };
        // The fitted twin: the same render with stage fit's recipe.
        let twin = match fitted_recipe(project, out, smp) {
            Some(recipe) => {
                let text = sample_scene_with(project, out, smp, true, Some(&recipe))?;
                inputs.push(recipe.clone());
                let in_out = SampleRenderFiles::in_dir(&sample_out);
                let rel = rel.fitted_scene.display().to_string();
                let twin = RenderJob {
                    scene: in_out.fitted_scene,
                    out: in_out.fitted,
                    uncertainty: r.uncertainty == Some(true) && recipe_has_uncertain_input(&recipe),
                    ..job.clone()
                };
                let label = format!("{} fitted twin", smp.name);
                Some(Task::Lucent { label, files: vec![(rel, text)], job: Job::Render(twin) })
            }
            None => None,
        };
        let job = Job::Render(job);
        tasks.push(Task::Lucent { label: smp.name.clone(), files: vec![(scene_rel, scene_text)], job });
        tasks.extend(twin);
    }
    if tasks.is_empty() {
        return Ok(Err(if f.sample.is_empty() { Skip::Missing("[[sample]]") } else { Skip::NoEmptyBoard }));
    }
    Ok(Ok(()))
}

/// The compare stage: each sample's photo against its render (and fitted twin),
/// over the image and over the object's pixels.
fn plan_compare(project: &Project, out: &Path, p: &mut Plan) -> Planned {
    let f = &project.file;
    let Plan { inputs, notes, tasks } = p;
    for smp in &f.sample {
        let render_dir = out.join(Stage::Render.name()).join(&smp.name);
        let fitted_dir = SampleRenderFiles::in_dir(&render_dir).fitted;
        let render = RenderFiles::in_dir(&render_dir).exr;
        let Some(photo) = &smp.photo else {
            notes.push(format!("{}: no photo", smp.name));
            continue;
        };
        let photo = &developed(out, smp, "photo", Some(photo))?;
        if !render.is_file() {
            notes.push(format!("{}: no render", smp.name));
            continue;
        }
        inputs.push(photo.clone());
        let fitted = RenderFiles::in_dir(&fitted_dir).exr;
        let fitted = fitted.is_file().then_some(fitted);
        let dirs = CompareDirs::in_dir(&under_out(format!("/{}", smp.name)));
        let job = CompareJob {
            mask: valid_mask(out, smp, "photo"),
            photo_variance: photo_variance(out, smp),
            data_range: f.compare.as_ref().and_then(|c| c.data_range).unwrap_or(crate::job::DEFAULT_DATA_RANGE),
            twin_names: fitted.is_some().then(|| ["recipe".to_string(), "fitted".to_string()]),
            ..CompareJob::new(
                photo.clone(),
                std::iter::once(render.clone()).chain(fitted.clone()).collect(),
                dirs.image.clone(),
            )
        };
        // Each twin's band (render --uncertainty), when the first has one.
        let band: Vec<PathBuf> = std::iter::once(render_dir.clone())
            .chain(fitted.is_some().then_some(fitted_dir))
            .map(|d| RenderBandFiles::in_dir(&d).json)
            .take_while(|b| b.is_file())
            .collect();
        inputs.extend(band.iter().cloned());
        // The same over the object's pixels, as the render's `object` layer marks
        // them (any mesh): where the twins differ, so where their paired test looks,
        // and where the bands are.
        let object = has_exr_channel(&render, "object").then(|| CompareJob {
            mask_object: Some(render.clone()),
            band,
            out: dirs.object,
            ..job.clone()
        });
        // The fitted twin alone too: its own triplet for the report.
        let fitted_alone =
            fitted.map(|f| CompareJob { render: vec![f], twin_names: None, out: dirs.fitted, ..job.clone() });
        if let Some(j) = object {
            tasks.push(lucent_task(format!("{} object", smp.name), Job::Compare(j)));
        }
        tasks.push(lucent_task(smp.name.clone(), Job::Compare(job)));
        if let Some(j) = fitted_alone {
            tasks.push(lucent_task(format!("{} fitted twin", smp.name), Job::Compare(j)));
        }
    }
    if tasks.is_empty() {
        return Ok(Err(Skip::NoPhotoAndRender));
    }
    Ok(Ok(()))
}

/// The report stage: its inputs are the project file and the known camera.
fn plan_report(project: &Project, p: &mut Plan) -> Planned {
    let f = &project.file;
    let Plan { inputs, tasks, .. } = p;
    inputs.push(project.path.clone());
    inputs.extend(f.calibration.as_ref().and_then(|c| c.truth.clone()));
    tasks.push(Task::Report);
    Ok(Ok(()))
}

/// The key of a planned stage (see the module doc).
fn stage_key(
    stage: Stage,
    project: &Project,
    plan: &Plan,
    inputs: &[InputHash],
    upstream: &[(Stage, String)],
) -> Result<String, PipelineError> {
    let body = serde_json::json!({
        "stage": stage,
        "lucent_version": env!("CARGO_PKG_VERSION"),
        "seed": project.seed,
        "tasks": plan.tasks,
        "inputs": inputs,
        "upstream": upstream,
    });
    Ok(sha256_hex(body.to_string().as_bytes()))
}

/// A hidden file in a stage folder while the stage runs: the folder is the
/// pipeline's own even before its manifest is written.
const STAGE_MARK: &str = ".lucent-stage";

/// Whether `dir` is a stage folder this pipeline wrote (a manifest, or the
/// mark of a stage under way).
fn is_stage_folder(dir: &Path) -> bool {
    StageFiles::in_dir(dir).manifest.is_file() || dir.join(STAGE_MARK).is_file()
}

/// Before a stage runs: its folder must be the pipeline's own (a file or a
/// folder of the user's there is refused, never moved aside), and what an
/// interrupted earlier run left is put in order — a stage folder without
/// a manifest (cut short) becomes `STAGE.failed/`, and the previous result
/// that run had moved aside is put back (or, when the stage folder is
/// complete, removed).
fn recover_stage_folder(stage: Stage, dir: &Path, aside: &Path, failed: &Path) -> Result<(), PipelineError> {
    let io = |path: &Path, source| PipelineError::Io { path: path.to_path_buf(), source };
    let foreign = |path: &Path| {
        let what = if path.is_dir() { "a folder lucent run did not write (no manifest.json)" } else { "not a folder" };
        PipelineError::Foreign { path: path.to_path_buf(), what: what.into(), stage }
    };
    if std::fs::symlink_metadata(dir).is_ok() && (dir.is_symlink() || !dir.is_dir()) {
        return Err(foreign(dir));
    }
    if dir.is_dir() && !is_stage_folder(dir) && std::fs::read_dir(dir).map_or(true, |mut d| d.next().is_some()) {
        return Err(foreign(dir));
    }
    if dir.is_dir() && !StageFiles::in_dir(dir).manifest.is_file() {
        if failed.exists() {
            std::fs::remove_dir_all(failed).map_err(|e| io(failed, e))?;
        }
        std::fs::rename(dir, failed).map_err(|e| io(dir, e))?;
    }
    if aside.is_dir() {
        if dir.exists() {
            // A run stopped between its manifest and putting the user's files
            // back: they go back now, before the previous result is removed.
            let kept = users_files(aside, read_manifest(aside).as_ref());
            let _ = carry_users_files(aside, dir, &kept, stage);
            if !users_files(aside, read_manifest(aside).as_ref()).is_empty() {
                return Err(foreign(aside));
            }
            std::fs::remove_dir_all(aside).map_err(|e| io(aside, e))?;
        } else {
            std::fs::rename(aside, dir).map_err(|e| io(aside, e))?;
        }
    } else if std::fs::symlink_metadata(aside).is_ok() {
        return Err(foreign(aside));
    }
    Ok(())
}

/// Runs one job (its `{out}` already replaced by the stage folder), its
/// output appended to `log`; on failure, an error saying what failed (the
/// binary uses `anyhow`, tests their own types).
pub type Executor<'a> = dyn FnMut(&Job, &Path) -> Result<(), Box<dyn std::error::Error + Send + Sync>> + 'a;

/// Runs the project's stages in order. `exec` runs a job (its `{out}`
/// replaced by the stage folder) with its output appended to the log file;
/// `on_status` hears about every stage (for the status lines).
pub fn run(
    project: &Project,
    out: &Path,
    options: &Options,
    exec: &mut Executor,
    on_status: &mut dyn FnMut(Stage, &Status, &[String]),
) -> Result<Vec<(Stage, Status)>, PipelineError> {
    let io = |path: &Path, source| PipelineError::Io { path: path.to_path_buf(), source };
    // Held until the run ends.
    let (_lock, mut first_notes) = claim_for_project(project, out)?;
    let mut done: Vec<(Stage, Status)> = Vec::new();
    for stage in Stage::ALL {
        if options
            .until
            .is_some_and(|u| Stage::ALL.iter().position(|s| *s == stage) > Stage::ALL.iter().position(|s| *s == u))
        {
            break;
        }
        let dir = out.join(stage.name());
        let plan = match plan(stage, project, out)? {
            Ok(p) => p,
            Err(reason) => {
                let st = Status::Skipped { reason };
                on_status(stage, &st, &[]);
                done.push((stage, st));
                continue;
            }
        };
        let (inputs, key) = hashed_inputs_and_key(stage, project, out, &plan)?;
        let previous = read_manifest(&dir);
        let fresh = previous.as_ref().is_some_and(|m| {
            m.key == key && hash_listed(&dir, &m.outputs).map(|h| h == m.outputs_sha256).unwrap_or(false)
        });
        if fresh && !options.force.contains(&stage) {
            on_status(stage, &Status::UpToDate, &plan.notes);
            done.push((stage, Status::UpToDate));
            continue;
        }
        // Move the previous result aside; run into the final folder.
        let aside = out.join(format!(".{}.previous", stage.name()));
        let failed = out.join(format!("{}.failed", stage.name()));
        recover_stage_folder(stage, &dir, &aside, &failed)?;
        // The user's files in the stage folder (not in its manifest) are
        // carried into the new result, never removed with the old one.
        let last = read_manifest(&dir);
        let kept = users_files(&dir, last.as_ref());
        if dir.exists() {
            std::fs::rename(&dir, &aside).map_err(|e| io(&dir, e))?;
        }
        std::fs::create_dir_all(&dir).map_err(|e| io(&dir, e))?;
        crate::io::write_atomic(&dir.join(STAGE_MARK), stage.name().as_bytes())?;
        on_status(stage, &Status::Started { last_wall_s: last.as_ref().map(|m| m.wall_s) }, &[]);
        let start = Instant::now();
        let started_unix_s =
            std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map(|d| d.as_secs()).unwrap_or(0);
        let TasksRun { commands, deferred, result } = run_tasks(project, out, &dir, &plan.tasks, &done, exec);
        let wall_s = start.elapsed().as_secs_f64();
        if let Err(message) = result {
            if failed.exists() {
                let _ = std::fs::remove_dir_all(&failed);
            }
            let _ = std::fs::rename(&dir, &failed);
            if aside.exists() {
                let _ = std::fs::rename(&aside, &dir);
            }
            let fault = fault_of(&message);
            return Err(PipelineError::Failed { stage, fault, message, kept: failed });
        }
        if deferred > 0 {
            // Nothing of this stage is final. The stage folder stays, marked as
            // the pipeline's (the emitted merge jobs write their outputs into it):
            // the next run treats it as cut short (STAGE.failed/, the previous
            // result put back) and merges the finished shards.
            let st = Status::Deferred { tasks: deferred };
            on_status(stage, &st, &plan.notes);
            done.push((stage, st));
            return Ok(done);
        }
        let manifest = Manifest {
            stage,
            key,
            lucent_version: env!("CARGO_PKG_VERSION").into(),
            seed: project.seed,
            inputs,
            commands,
            notes: plan.notes.clone(),
            started_unix_s,
            wall_s,
            outputs_sha256: outputs_hash(&dir)?,
            outputs: output_files(&dir),
            files: output_files(&dir)
                .into_iter()
                .map(|f| hash_file(&dir.join(&f)).map(|h| InputHash { path: f, ..h }))
                .collect::<Result<_, _>>()?,
        };
        crate::io::write_json(&StageFiles::in_dir(&dir).manifest, &manifest)?;
        let _ = std::fs::remove_file(dir.join(STAGE_MARK));
        let mut notes = plan.notes.clone();
        if aside.exists() {
            notes.extend(carry_users_files(&aside, &dir, &kept, stage));
            if users_files(&aside, read_manifest(&aside).as_ref()).is_empty() {
                let _ = std::fs::remove_dir_all(&aside);
            }
        }
        if failed.exists() {
            let _ = std::fs::remove_dir_all(&failed);
        }
        notes.append(&mut first_notes);
        let st = Status::Ran { wall_s, tasks: plan.tasks.len() };
        on_status(stage, &st, &notes);
        done.push((stage, st));
    }
    Ok(done)
}

/// Claims and locks `out` for `project`'s run (one run at a time; refused
/// when it holds another project's results) and marks it as the project's:
/// the lock, held until the run ends, and a note when it replaced a stale
/// lock.
fn claim_for_project(project: &Project, out: &Path) -> Result<(crate::io::OutputLock, Vec<String>), PipelineError> {
    crate::io::claim_output_folder(out)?;
    // One run at a time writes into a folder: a second is refused clearly.
    let lock = crate::io::lock_output_folder(out)?;
    // The results of another project are not mixed into this one's.
    let file = project.path.display().to_string();
    if let Some(earlier) = earlier_project(out)
        && earlier.project != project.name
    {
        return Err(PipelineError::OtherProject {
            out: out.to_path_buf(),
            earlier: earlier.project,
            earlier_file: earlier.project_file,
            name: project.name.clone(),
            file,
        });
    }
    let mark = ProjectMark { project: project.name.clone(), project_file: file };
    crate::io::write_json(&out.join(PROJECT_MARK), &mark)?;
    let mut first_notes: Vec<String> = Vec::new();
    if let Some((pid, host)) = &lock.replaced_stale {
        first_notes.push(format!(
            "warning: {}: a stale lock of an ended run (pid {pid} on {host}) was replaced",
            out.join(crate::io::OUTPUT_LOCK).display()
        ));
    }
    Ok((lock, first_notes))
}

/// The hashes of a planned stage's inputs and its key (over them and the
/// outputs of the stages it depends on that have a folder under `out`).
fn hashed_inputs_and_key(
    stage: Stage,
    project: &Project,
    out: &Path,
    plan: &Plan,
) -> Result<(Vec<InputHash>, String), PipelineError> {
    let mut inputs = Vec::new();
    for p in &plan.inputs {
        inputs.push(hash_file(p)?);
    }
    let mut upstream = Vec::new();
    for d in stage.depends_on() {
        let ddir = out.join(d.name());
        if ddir.is_dir() {
            upstream.push((*d, listed_outputs_hash(&ddir)?));
        }
    }
    let key = stage_key(stage, project, plan, &inputs, &upstream)?;
    Ok((inputs, key))
}

/// What [`run_tasks`] did: the commands it placed, how many jobs the
/// executor deferred and the first failure.
struct TasksRun {
    commands: Vec<Vec<String>>,
    deferred: usize,
    result: Result<(), TaskError>,
}

/// Runs a stage's `tasks` into its folder `dir` (a task's files written
/// first, its job's `{out}` placed there; the report written in process
/// from the stages `done`), until the first that fails.
fn run_tasks(
    project: &Project,
    out: &Path,
    dir: &Path,
    tasks: &[Task],
    done: &[(Stage, Status)],
    exec: &mut Executor,
) -> TasksRun {
    let log = StageFiles::in_dir(dir).log;
    let mut commands = Vec::new();
    let mut deferred = 0usize;
    let mut result: Result<(), TaskError> = Ok(());
    for task in tasks {
        let r = match task {
            Task::Lucent { label, files, job } => {
                let mut r = Ok(());
                for (name, text) in files {
                    if let Err(source) = crate::io::write_atomic(&dir.join(name), text.as_bytes()) {
                        r = Err(TaskError::Write { label: label.clone(), source });
                    }
                }
                let placed = job.with_out(dir);
                if let Ok(job) = &placed {
                    commands.push(job.to_args());
                }
                r.and_then(|_| {
                    placed.map_err(|e| TaskError::Place {
                        label: label.clone(),
                        source: crate::fault::Internal(e.to_string()),
                    })
                })
                .and_then(|job| match exec(&job, &log) {
                    Err(e) if e.is::<executor::Deferred>() => {
                        deferred += 1;
                        Ok(())
                    }
                    other => other.map_err(|source| TaskError::Command { label: label.clone(), source }),
                })
            }
            Task::Report => {
                let job = report::ReportJob {
                    project: project.path.clone(),
                    run: out.to_path_buf(),
                    out: dir.to_path_buf(),
                    stages: report::outcomes(done),
                };
                commands.push(job.to_args());
                job.run_on(project).map(|_| ()).map_err(TaskError::from)
            }
        };
        if r.is_err() {
            result = r;
            break;
        }
    }
    TasksRun { commands, deferred, result }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pipeline_classes_its_own_and_slurms_errors() {
        // A Slurm failure is the environment's wherever it sits in the chain;
        // `Fault::of` below the pipeline does not know the type (user input).
        let slurm = anyhow::Error::from(executor::SlurmError::NoJobId("".into())).context("render shards");
        assert_eq!(fault_of(slurm.as_ref()), Fault::Environment);
        assert_eq!(Fault::of(slurm.as_ref()), Fault::Input);
        // A failed stage carries the class its task had.
        let failed = PipelineError::Failed {
            stage: Stage::Render,
            fault: Fault::Internal,
            message: TaskError::Command { label: "render".into(), source: "tile index out of range".into() },
            kept: PathBuf::from("render.failed"),
        };
        let e = anyhow::Error::from(failed).context("lucent run");
        assert_eq!(fault_of(e.as_ref()), Fault::Internal);
        // Anything else is classed as before.
        let disk = anyhow::Error::from(std::io::Error::from(std::io::ErrorKind::StorageFull));
        assert_eq!(fault_of(disk.as_ref()), Fault::Environment);
        assert_eq!(fault_of(anyhow::anyhow!("--spp 0").as_ref()), Fault::Input);
    }

    #[test]
    fn a_photo_is_binned_to_the_render_by_an_integer_factor_or_refused() {
        let dir = tempfile::tempdir().unwrap();
        let photo = dir.path().join("photo.exr");
        let img = crate::imageio::RgbImage::new(320, 240, vec![0.5; 320 * 240 * 3]).unwrap();
        crate::imageio::write_exr(&photo, &img).unwrap();
        assert_eq!(photo_bin("s", &photo, None).unwrap(), 1);
        let size = |width, height| Some(ImageSize { width, height });
        assert_eq!(photo_bin("s", &photo, size(320, 240)).unwrap(), 1);
        assert_eq!(photo_bin("s", &photo, size(160, 120)).unwrap(), 2);
        assert_eq!(photo_bin("s", &photo, size(80, 60)).unwrap(), 4);
        for (w, h) in [(100, 75), (160, 100), (640, 480)] {
            let e = photo_bin("s", &photo, size(w, h)).unwrap_err().to_string();
            assert!(
                e.contains("photo.exr") && e.contains("320 × 240") && e.contains("integer multiple"),
                "{w}x{h}: {e}"
            );
        }
        let e = photo_bin("s", &dir.path().join("missing.exr"), size(160, 120)).unwrap_err().to_string();
        assert!(e.contains("missing.exr"), "{e}");
    }

    #[test]
    fn recipe_inputs_include_the_files_a_recipe_names() {
        let dir = std::env::temp_dir().join(format!("lucent-recipe-inputs-{}", std::process::id()));
        std::fs::create_dir_all(dir.join("idx")).unwrap();
        std::fs::write(dir.join("idx/host.yml"), "x").unwrap();
        std::fs::write(dir.join("fit.json"), "{}").unwrap();
        let recipe = dir.join("r.toml");
        std::fs::write(
            &recipe,
            "[host]\nindex = \"idx/host.yml\"\n[[particles]]\nindex = \"builtin:TiO2\"\nname = \"fit.json\"\n             [surface]\nfit = \"fit.json\"\nnote = \"missing.yml\"\n",
        )
        .unwrap();
        let got = recipe_inputs(&recipe);
        assert_eq!(got[0], recipe);
        assert!(got.contains(&dir.join("idx/host.yml")) && got.contains(&dir.join("fit.json")), "{got:?}");
        assert_eq!(got.len(), 3, "each file once, builtins and missing files left out: {got:?}");
        std::fs::remove_dir_all(&dir).ok();
    }

    #[test]
    fn the_surface_stage_comes_before_the_bssrdf_stage_that_reads_it() {
        let k = |s: Stage| Stage::ALL.iter().position(|x| *x == s).unwrap();
        assert!(k(Stage::Optics) < k(Stage::Surface) && k(Stage::Surface) < k(Stage::Bssrdf));
        assert_eq!(Stage::Bssrdf.depends_on(), &[Stage::Surface]);
        assert!(Stage::Report.depends_on().contains(&Stage::Surface));
        // The report reads every stage before it, in their order (its key's upstream).
        assert_eq!(Stage::Report.depends_on(), &Stage::ALL[..Stage::ALL.len() - 1]);
        assert_eq!(Stage::from_name("surface").unwrap(), Stage::Surface);
    }

    #[test]
    fn stage_names_round_trip_and_dependencies_come_first() {
        for (k, s) in Stage::ALL.iter().enumerate() {
            assert_eq!(Stage::from_name(s.name()).unwrap(), *s);
            for d in s.depends_on() {
                assert!(Stage::ALL.iter().position(|x| x == d).unwrap() < k, "{s} depends on the later {d}");
            }
        }
    }
}
