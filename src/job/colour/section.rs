//! The colour stage's section in the run's report (under "Calibration"):
//! per camera its colour correction's method, the ΔE2000 mean and maximum
//! and the ΔE2000 / ΔE76 table of the 24 patches with the chart and ΔE
//! pictures; beside the known camera response where `[[colour]] truth`
//! gives one (the recovered matrix's gain and largest entry error, ΔE2000
//! of truth vs recovered).

use crate::ccm_file::{CcmFile, ColourFiles};
use crate::job::report::{esc, f3, num, table, to_value, trim, Metrics, ReportError, ReportSection, SectionContext};
use serde_json::{json, Value};
use std::fmt::Write as _;
use std::path::Path;

/// One camera of the project's colour calibrations.
pub struct ColourCamera<'a> {
    /// Its name (`[[colour]] camera`, its folder of the stage).
    pub camera: &'a str,
    /// The known camera response (`[[colour]] truth`).
    pub truth: Option<&'a Path>,
}

/// Every colour calibration of the project (stage colour's folder `dir`,
/// one [`ColourFiles`] per camera) with its ΔE2000 table; empty when there
/// is none.
pub struct ColourSection<'a> {
    pub dir: &'a Path,
    pub cameras: Vec<ColourCamera<'a>>,
}

impl ReportSection for ColourSection<'_> {
    fn section(&self, ctx: &mut SectionContext<'_>, metrics: &mut Metrics) -> Result<String, ReportError> {
        let mut h = String::new();
        let mut colour_json = serde_json::Map::new();
        for c in &self.cameras {
            let files = ColourFiles::in_dir(&self.dir.join(c.camera));
            if !files.ccm.exists() {
                continue;
            }
            let (ccm, _) = CcmFile::read(&files.ccm)?;
            let _ = write!(
                h,
                "<h3>Colour: {}</h3><p>{} · ΔE2000 mean {} max {}</p>",
                esc(c.camera),
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
            if let Some(t) = c.truth {
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
            h.push_str(&ctx.page.img(&files.chart, &format!("{} chart: measured | corrected | reference", c.camera))?);
            h.push_str(&ctx.page.img(&files.delta_e, &format!("{} ΔE per patch", c.camera))?);
            h.push_str("</div>");
            colour_json.insert(c.camera.to_string(), cj);
        }
        metrics.insert("colour".into(), Value::Object(colour_json));
        Ok(h)
    }
}
