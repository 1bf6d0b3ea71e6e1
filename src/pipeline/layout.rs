//! What a stage folder holds and where: its [`Manifest`] and log
//! ([`StageFiles`]), and the files and folders of each sample that the
//! planning, the jobs and the report name ([`DevelopFiles`],
//! [`SampleRenderFiles`], [`CompareDirs`], [`bssrdf_run_dir`],
//! [`bssrdf_comparison_dir`]), each name spelled once.

use super::stage::Stage;
use crate::bssrdf::SliceFiles;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// One input file as hashed.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct InputHash {
    pub path: String,
    pub bytes: u64,
    pub sha256: String,
}

/// `STAGE/manifest.json`: what a stage ran on and what it produced.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Manifest {
    pub stage: Stage,
    pub key: String,
    pub lucent_version: String,
    pub seed: u64,
    pub inputs: Vec<InputHash>,
    pub commands: Vec<Vec<String>>,
    pub notes: Vec<String>,
    pub started_unix_s: u64,
    pub wall_s: f64,
    /// SHA-256 over the stage folder's files (names and contents, manifest and log excluded).
    pub outputs_sha256: String,
    pub outputs: Vec<String>,
    /// Every file lucent wrote into the stage folder (paths relative to it)
    /// with its size and SHA-256: only these are ever replaced or removed by
    /// a later run. A file that is not listed, or no longer has its hash (the
    /// user edited it), is the user's and is kept ([`users_files`](super::users_files)).
    #[serde(default)]
    pub files: Vec<InputHash>,
}

/// The bookkeeping files of every stage folder, each name spelled here
/// once: the stage's [`Manifest`] (`manifest`) and the log of its jobs
/// (`log`). Written by [`run`](super::run()), read by planning, the report and
/// [`users_files`](super::users_files).
///
/// ```
/// use lucent::pipeline::StageFiles;
/// let f = StageFiles::in_dir(std::path::Path::new("out/optics"));
/// assert_eq!(f.manifest, std::path::Path::new("out/optics/manifest.json"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StageFiles {
    pub manifest: PathBuf,
    pub log: PathBuf,
}

impl StageFiles {
    /// The file names.
    pub const NAMES: [&'static str; 2] = [crate::io::STAGE_MANIFEST, "log.txt"];

    /// The bookkeeping files of the stage folder `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [manifest, log] = Self::NAMES.map(|n| dir.join(n));
        Self { manifest, log }
    }
}

/// The develop stage's files of a sample's photo `which` ("photo" or
/// "empty_board") in the sample's folder, each name spelled here once (the
/// planning below names them as the jobs' outputs): the photo in CIE RGB
/// (`exr`), of a RAW photo its per-pixel variance (`variance`, the photo
/// only) and its mask of validly recorded pixels (`valid`).
///
/// ```
/// use lucent::pipeline::DevelopFiles;
/// let f = DevelopFiles::in_dir(std::path::Path::new("out/develop/s1"), "photo");
/// assert_eq!(f.variance, std::path::Path::new("out/develop/s1/photo_variance.exr"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DevelopFiles {
    pub exr: PathBuf,
    pub variance: PathBuf,
    pub valid: PathBuf,
}

impl DevelopFiles {
    /// The files of photo `which` in the sample folder `dir`.
    pub fn in_dir(dir: &Path, which: &str) -> Self {
        Self {
            exr: dir.join(format!("{which}.exr")),
            variance: dir.join(format!("{which}_variance.exr")),
            valid: dir.join(format!("{which}_valid.png")),
        }
    }
}

/// The render and env-scale stages' files of one sample in its folder,
/// each name spelled here once (the planning writes the scenes and
/// names the folders): the scene the sample is rendered with (`scene`), its
/// render ([`RenderFiles`](crate::scene::RenderFiles) in the folder itself) and, with a fitted recipe,
/// the fitted twin's scene (`fitted_scene`) and render folder (`fitted`).
///
/// ```
/// use lucent::pipeline::SampleRenderFiles;
/// let f = SampleRenderFiles::in_dir(std::path::Path::new("out/render/s1"));
/// assert_eq!(f.fitted, std::path::Path::new("out/render/s1/fitted"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SampleRenderFiles {
    pub scene: PathBuf,
    pub fitted_scene: PathBuf,
    pub fitted: PathBuf,
}

impl SampleRenderFiles {
    /// The files of the sample folder `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        Self {
            scene: dir.join("input_scene.toml"),
            fitted_scene: dir.join("input_scene_fitted.toml"),
            fitted: dir.join("fitted"),
        }
    }
}

/// The compare stage's folders of one sample, each spelled here once (the
/// planning below names them as the jobs' outputs), each holding
/// [`crate::compare::CompareFiles`]: the whole image (`image`, the sample's folder itself),
/// the object's pixels alone (`object`) and the fitted twin alone (`fitted`).
///
/// ```
/// use lucent::pipeline::CompareDirs;
/// let d = CompareDirs::in_dir(std::path::Path::new("out/compare/s1"));
/// assert_eq!(d.object, std::path::Path::new("out/compare/s1/object"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct CompareDirs {
    pub image: PathBuf,
    pub object: PathBuf,
    pub fitted: PathBuf,
}

impl CompareDirs {
    /// The folders of the sample folder `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        Self { image: dir.to_path_buf(), object: dir.join("object"), fitted: dir.join("fitted") }
    }
}

/// The bssrdf stage's folder of a sample's comparison with its measured
/// slice of configuration `c` (θi, θo): `compare_tiθi_toθo` in the sample's
/// folder `dir`, holding [`crate::bssrdf::ComparisonFiles`].
pub fn bssrdf_comparison_dir(dir: &Path, c: (f64, f64)) -> PathBuf {
    dir.join(format!("compare_ti{}_to{}", c.0, c.1))
}

/// The slice folder `lucent bssrdf` writes for a configuration.
pub fn bssrdf_run_dir(sample_dir: &str, configs: &[(f64, f64)], c: (f64, f64)) -> String {
    let sub = SliceFiles::run_subdir(configs.len(), c.0, c.1);
    if sub.is_empty() {
        sample_dir.to_string()
    } else {
        format!("{sample_dir}/{sub}")
    }
}
