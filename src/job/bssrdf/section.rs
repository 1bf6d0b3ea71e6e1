//! The bssrdf stage's section of a sample in the run's report: per
//! configuration the simulated slice's sum (± standard error, 1/(m² sr))
//! and, where measured, the measured sum, their ratio and the mean squared
//! relative error, with the slice, profile and comparison pictures; and
//! what the rings of the ring estimator are.

use crate::bssrdf::{Comparison, ComparisonFiles, SliceFiles, Summary};
use crate::job::report::{e4, f4, num, read_json, table, trim, Metrics, ReportError, ReportSection, SectionContext};
use serde_json::json;
use std::fmt::Write as _;
use std::path::Path;

/// The files of one configuration (θi, θo in degrees) of a sample's
/// slices: the simulated slice and its comparison with the measured one.
pub struct BssrdfConfigFiles {
    pub config: (f64, f64),
    pub slice: SliceFiles,
    pub comparison: ComparisonFiles,
}

/// A sample's BSSRDF slices (its folder `dir` of the bssrdf stage, one run
/// per configuration) and, where measured, their comparisons; empty when
/// the stage has not run for the sample.
pub struct BssrdfSection<'a> {
    /// The sample's name (in captions).
    pub sample: &'a str,
    /// The sample's folder of the stage.
    pub dir: &'a Path,
    /// The files of every configuration, in the project's order.
    pub configs: Vec<BssrdfConfigFiles>,
}

impl ReportSection for BssrdfSection<'_> {
    fn section(&self, ctx: &mut SectionContext<'_>, sj: &mut Metrics) -> Result<String, ReportError> {
        let mut h = String::new();
        if !self.dir.is_dir() {
            return Ok(h);
        }
        let name = self.sample;
        h.push_str("<h3>BSSRDF slices (slab simulator)</h3>");
        let mut rows = Vec::new();
        let mut bj = Vec::new();
        let mut imgs = String::new();
        // The largest median per-pixel error of a slice drawn with the ring estimator.
        let mut ring_noise: Option<f64> = None;
        for BssrdfConfigFiles { config: c, slice: run, comparison: compared } in &self.configs {
            let summary: Option<Summary> = read_json(&run.summary, "a BSSRDF summary.json")?;
            let cmp: Option<Comparison> = read_json(&compared.json, "a BSSRDF comparison.json")?;
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
            let page = &mut *ctx.page;
            imgs.push_str(&page.img(&run.png, &format!("{name} slice θi {}° θo {}°", c.0, c.1))?);
            imgs.push_str(&page.img(&run.profile_png, &format!("{name} profile θi {}° θo {}°", c.0, c.1))?);
            imgs.push_str(
                &page.img(&compared.panel, &format!("{name} measured vs simulated θi {}° θo {}°", c.0, c.1))?,
            );
            imgs.push_str(
                &page.img(
                    &compared.profiles,
                    &format!("{name} measured vs simulated profiles θi {}° θo {}°", c.0, c.1),
                )?,
            );
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
        Ok(h)
    }
}
