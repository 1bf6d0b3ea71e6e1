//! The compare stage's sections in the run's report. At the top of the
//! page, a sample's answer ([`CompareSection::answer`]): which twin is
//! closer to the photo, by how much and how sure, in one sentence
//! ([`verdict_sentence`]), the photo | render | difference picture with how
//! to read it, the approximations the renders made, and whether the photo is
//! within each twin's predictive band. In the sample's details (its
//! [`ReportSection`]): the RMSE and SSIM table, the model RMSE with the
//! noise removed and the noise floor, the photo's noise model, the object's
//! pixels alone, the twins' table and paired test per region, and the loop
//! against its known truth (the fit's parameters beside their truth,
//! [`SectionContext::fitted_vs_truth`]).

use crate::compare::{CompareFiles, Report};
use crate::job::report::{
    e3, e4, esc, f4, num, read_json, slug, table, to_value, trim, FittedVsTruth, Metrics, Page, ReportError,
    ReportSection, SectionContext,
};
use crate::scene::RenderFiles;
use serde_json::json;
use std::fmt::Write as _;
use std::path::Path;

/// A sample's comparison with its photo: the compare stage's files of the
/// whole image (`image`) and of the object's pixels alone (`object`); the
/// section is `None`-empty when the stage has not compared the sample, and
/// then shows the render's picture (`render`) instead.
pub struct CompareSection<'a> {
    /// The sample's name (in headings, captions and anchors).
    pub sample: &'a str,
    pub image: CompareFiles,
    pub object: CompareFiles,
    /// The recipe the sample is known to be made of (`truth_recipe`, read by the report only).
    pub truth_recipe: Option<&'a Path>,
    /// The sample's render, whose picture shows when there is no comparison.
    pub render: &'a RenderFiles,
}

impl ReportSection for CompareSection<'_> {
    /// The metrics, the noise, the object's pixels, which twin is closer
    /// and the loop against its known truth (`ctx.fitted_vs_truth`, from
    /// the fit's section); without a comparison, the render's picture.
    fn section(&self, ctx: &mut SectionContext<'_>, sj: &mut Metrics) -> Result<String, ReportError> {
        let Some(m) = read_json::<Report>(&self.image.metrics, "a compare metrics.json")? else {
            return ctx.page.img(&self.render.png, &format!("{} render", self.sample));
        };
        let mut h = String::from("<h3>Photo | render | difference</h3>");
        h.push_str(&compare_metrics_table(&m));
        if let Some(n) = &m.noise {
            h.push_str(&noise_paragraphs(n));
        }
        // The object's pixels alone (compare/NAME/object/, the render's object layer).
        let object = read_json::<Report>(&self.object.metrics, "a compare metrics.json")?;
        if let Some(o) = &object
            && let Some(n) = &o.noise
        {
            h.push_str(&object_paragraph(o, n));
        }
        // Which twin is closer, over the whole image and over the object; the
        // loop's verdict is the object's (where the twins differ), else the image's.
        let regions: Vec<(&str, &Report)> = std::iter::once(("the whole image", &m))
            .chain(object.as_ref().map(|o| ("the object's pixels", o)))
            .collect();
        let mut verdict: Option<(&str, &crate::compare::noise::PairedReport)> = None;
        for (region, r) in &regions {
            let Some(t) = &r.twins else { continue };
            h.push_str(&twins_table(region, r, t));
            h.push_str(&paired_test_paragraph(&t.paired));
            verdict = Some((region, &t.paired));
        }
        // The loop against its known truth (truth_recipe, read by the report only).
        if let (Some(t_path), false, Some((region, paired))) =
            (self.truth_recipe, ctx.fitted_vs_truth.is_empty(), verdict)
        {
            h.push_str(&loop_against_truth(t_path, &ctx.fitted_vs_truth, region, paired, sj));
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
        Ok(h)
    }
}

impl CompareSection<'_> {
    /// The first thing on the page for the sample: the verdict in one
    /// sentence, then the photo | render | difference picture (with two
    /// twins: side by side under one difference scale, each headed by its
    /// twin). Empty when the compare stage has not run for the sample.
    pub fn answer(&self, page: &mut Page) -> Result<String, ReportError> {
        let (image_files, object_files, name) = (&self.image, &self.object, self.sample);
        let Some(image) = read_json::<Report>(&image_files.metrics, "a compare metrics.json")? else {
            return Ok(String::new());
        };
        let object = read_json::<Report>(&object_files.metrics, "a compare metrics.json")?;
        // The object's pixels, where the twins differ, when the render marks them.
        let (region, r) = match &object {
            Some(o) if o.twins.is_some() || image.twins.is_none() => ("the object's pixels", o),
            _ => ("the whole image", &image),
        };
        let sentence = verdict_sentence(region, r).unwrap_or_else(|| single_twin_sentence(region, r));
        let mut h = format!(
            "<section class=\"answer\" id=\"answer-{}\"><h2>{}: the answer</h2><p class=\"verdict\">{}</p>",
            slug(name),
            esc(name),
            esc(&sentence)
        );
        let twins = image.twins.is_some();
        h.push_str(&difference_note(&image.display, twins, region));
        let alt = if twins {
            format!(
                "{name}: photo | A (recipe) render, difference | B (fitted) render, difference, one difference scale"
            )
        } else {
            format!("{name}: photo | render | difference")
        };
        h.push_str(&page.img(&image_files.triplet, &alt)?);
        // The approximations the renders made, with their measured bias, beside the comparison that uses them.
        h.push_str(&approximation_note(r, twins));
        // Is the photo within each twin's predictive band (`[render] uncertainty`)?
        if let Some(o) = object.as_ref().filter(|o| !o.bands.is_empty()) {
            h.push_str(&band_section(page, o, object_files, name)?);
        }
        let _ =
            write!(h, "<p class=\"note\"><a href=\"#sample-{}\">The details per stage ↓</a></p></section>", slug(name));
        Ok(h)
    }
}

/// The comparison's metrics table (as calibrated and, when refined, after
/// ECC refinement) and the pixels it is over.
fn compare_metrics_table(m: &Report) -> String {
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
fn object_paragraph(o: &Report, n: &crate::compare::noise::NoiseReport) -> String {
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
fn twins_table(region: &str, r: &Report, t: &crate::compare::TwinsReport) -> String {
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
pub fn verdict_sentence(region: &str, a: &Report) -> Option<String> {
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
fn single_twin_sentence(region: &str, r: &Report) -> String {
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
fn approximation_note(r: &Report, twins: bool) -> String {
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
fn band_section(page: &mut Page, o: &Report, object_files: &CompareFiles, sample: &str) -> Result<String, ReportError> {
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
    h.push_str(&page.img(&object_files.band_png, &format!("{sample}: photo against the twins' bands"))?);
    Ok(h)
}
