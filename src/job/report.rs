//! What every stage's section of the run's report is written with: the
//! [`ReportSection`] each stage's outputs implement beside their job (e.g.
//! [`RenderFiles`](crate::scene::RenderFiles) in `job/render/section.rs`),
//! the [`SectionContext`] a section gets (the [`Page`] its pictures are
//! copied into, what the fit leaves for the comparison), the numbers a
//! section adds to metrics.json ([`Metrics`]), the [`ReportError`] of a
//! stage file that is not in its format, and the formatting the sections
//! share: HTML escaping ([`esc`]), tables, number formats, a stage file
//! read into its writer's type ([`read_json`]). The page's assembly is
//! `lucent::pipeline::report`.

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

/// One stage's section of the report, written from the files its job
/// wrote (its typed outputs, e.g. [`RenderFiles`](crate::scene::RenderFiles)):
/// the section's HTML, empty when the stage has not run, and its numbers
/// into `metrics` (a sample's for a sample's section, the page's for a
/// project-wide one).
pub trait ReportSection {
    fn section(&self, ctx: &mut SectionContext<'_>, metrics: &mut Metrics) -> Result<String, ReportError>;
}

/// What a section is written with besides its own files.
pub struct SectionContext<'a> {
    /// The page: where a section's pictures are copied.
    pub page: &'a mut Page,
    /// A sample's fitted parameters beside their known truth, left by the
    /// fit's section for the comparison's (the loop against its truth);
    /// empty until then, and without a fit or a truth.
    pub fitted_vs_truth: Vec<FittedVsTruth>,
}

impl<'a> SectionContext<'a> {
    /// The context of one sample's sections (or the project's) on `page`.
    pub fn new(page: &'a mut Page) -> Self {
        Self { page, fitted_vs_truth: Vec::new() }
    }
}

/// A section's numbers for metrics.json.
pub type Metrics = serde_json::Map<String, Value>;

/// A fitted parameter beside its known truth: (name, fitted, 95 % interval, truth).
pub type FittedVsTruth = (String, Option<f64>, Option<[f64; 2]>, f64);

/// The report's pictures: each one a section shows is copied into
/// `img_dir`, numbered in the order they appear.
pub struct Page {
    img_dir: PathBuf,
    copied: usize,
}

impl Page {
    /// A page whose pictures go into `img_dir` (created with the first).
    pub fn new(img_dir: PathBuf) -> Self {
        Self { img_dir, copied: 0 }
    }

    /// Copies `src` into img/ and returns an <img> tag, or nothing when absent.
    pub fn img(&mut self, src: &Path, alt: &str) -> Result<String, ReportError> {
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

/// HTML-escapes text.
pub fn esc(t: &str) -> String {
    t.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
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
pub(crate) fn to_value<T: Serialize>(v: &T) -> Value {
    serde_json::to_value(v).unwrap_or(Value::Null)
}

/// Drops arrays of more than `max` numbers (phase tables, corner lists)
/// so metrics.json stays readable; everything else is kept.
pub(crate) fn trim(v: &Value, max: usize) -> Value {
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
pub(crate) fn num(v: f64, fmt: fn(f64) -> String) -> String {
    if v.is_finite() {
        fmt(v)
    } else {
        "—".into()
    }
}

pub(crate) fn e4(x: f64) -> String {
    format!("{x:.4e}")
}
pub(crate) fn e3(x: f64) -> String {
    format!("{x:.3e}")
}
pub(crate) fn f3(x: f64) -> String {
    format!("{x:.3}")
}
pub(crate) fn f4(x: f64) -> String {
    format!("{x:.4}")
}

/// `t` as an HTML id or file name: lower-case ASCII letters and digits
/// joined by single dashes, at most 48 characters.
pub(crate) fn slug(t: &str) -> String {
    let s: String = t.chars().map(|c| if c.is_ascii_alphanumeric() { c.to_ascii_lowercase() } else { '-' }).collect();
    s.split('-').filter(|p| !p.is_empty()).collect::<Vec<_>>().join("-").chars().take(48).collect()
}

/// An HTML table of `head` and `rows`, every cell escaped.
pub(crate) fn table(head: &[&str], rows: &[Vec<String>]) -> String {
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
