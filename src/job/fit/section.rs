//! The fit stage's section of a sample in the run's report: each fitted
//! parameter (start, fit, 95 % interval, and whether the known truth lies in
//! it), the measured slices against the simulation at the recipe and at the
//! fit (sum ratios, mean squared relative errors), the objective and the
//! profiles; and the parameters beside their truth for the comparison's
//! section ([`SectionContext::fitted_vs_truth`]).

use crate::fit::report::FitFiles;
use crate::job::report::{
    e4, esc, f4, num, read_json, table, FittedVsTruth, Metrics, ReportError, ReportSection, SectionContext,
};
use crate::optics::recipe::{Overrides, Recipe};
use serde_json::{json, Value};
use std::fmt::Write as _;
use std::path::Path;

/// A sample's fitted recipe (stage fit's `files`) beside the truth when
/// known; empty when the stage has not fitted the sample.
pub struct FitSection<'a> {
    /// The sample's name (in captions).
    pub sample: &'a str,
    pub files: FitFiles,
    /// The recipe the sample is known to be made of (`truth_recipe`, read by the report only).
    pub truth_recipe: Option<&'a Path>,
}

impl ReportSection for FitSection<'_> {
    fn section(&self, ctx: &mut SectionContext<'_>, sj: &mut Metrics) -> Result<String, ReportError> {
        let (files, sample) = (&self.files, self.sample);
        let mut h = String::new();
        // (parameter, fitted, 95 % interval, truth) of the fit, for the loop's summary of the comparison.
        let mut fitted_vs_truth: Vec<FittedVsTruth> = Vec::new();
        if let Some(fj) = read_json::<Value>(&files.json, "a fit.json")? {
            h.push_str("<h3>Recipe fitted to the measured slices (lucent fit)</h3>");
            let truth = match self.truth_recipe {
                Some(t) => Recipe::load(t, Overrides::default()).ok(),
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
            let mut imgs = ctx.page.img(&files.objective_png, &format!("{sample} fit objective"))?;
            for c in fj["configurations"].as_array().into_iter().flatten() {
                let (Some(ti), Some(to)) = (c["theta_i_deg"].as_f64(), c["theta_o_deg"].as_f64()) else { continue };
                imgs.push_str(&ctx.page.img(
                    &files.profiles_png(ti, to),
                    &format!("{sample} measured profile vs simulated at the recipe and at the fit, θi {ti}° θo {to}°"),
                )?);
            }
            let _ = write!(h, "<div class=\"row\">{imgs}</div>");
            sj.insert(
                "fit".into(),
                json!({"parameters": pj, "identifiable": fj["identifiable"], "evaluations": fj["evaluations"]}),
            );
        }
        ctx.fitted_vs_truth = fitted_vs_truth;
        Ok(h)
    }
}
