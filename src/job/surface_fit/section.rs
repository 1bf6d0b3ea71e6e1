//! The surface stage's section of a sample in the run's report, from its
//! `fit.json` ([`FitReport`]): the height map read (points, pitch in µm),
//! its roughness (S_q in µm, S_dq), each model's fitted α (dimensionless),
//! scale and tilt (degrees) with the fit's quality as fit.json gives it —
//! the mean squared error over the histogram's bins in 1/sr² and its
//! normalised root (NRMSE); fit.json gives no standard error of α — the
//! better model, and the fit's plots (the distribution with both fits, the
//! levelled height map).

use crate::job::report::{
    e4, f4, num, read_json, table, to_value, trim, Metrics, ReportError, ReportSection, SectionContext,
};
use crate::surface::model::RoughnessModel;
use crate::surface::{FitReport, SurfaceFitFiles};
use std::fmt::Write as _;

/// A sample's fitted surface (stage surface's files); empty when the stage
/// has not fitted one for the sample.
impl ReportSection for SurfaceFitFiles {
    fn section(&self, ctx: &mut SectionContext<'_>, sj: &mut Metrics) -> Result<String, ReportError> {
        let Some(r) = read_json::<FitReport>(&self.json, "a surface fit.json")? else { return Ok(String::new()) };
        let mut h = String::from("<h3>Surface</h3>");
        let _ = write!(
            h,
            "<p>{} × {} points at {} × {} µm ({} valid); S<sub>q</sub> {} µm, S<sub>dq</sub> {} (plane-fit normals \
             {}); the global plane ({}°) {}.</p>",
            r.input.nx,
            r.input.ny,
            num(r.input.pitch_x_m * 1e6, f4),
            num(r.input.pitch_y_m * 1e6, f4),
            r.input.valid_points,
            num(r.roughness.sq_m * 1e6, f4),
            num(r.roughness.sdq, f4),
            num(r.roughness.sdq_plane_fit, f4),
            num(r.global_plane.tilt_deg, f4),
            if r.global_plane.removed { "removed" } else { "kept" },
        );
        let rows: Vec<Vec<String>> = RoughnessModel::ALL
            .iter()
            .map(|&m| {
                let f = r.fits.get(m);
                vec![
                    format!("{}{}", m.label(), if m == r.better_model { " (better)" } else { "" }),
                    num(f.alpha, |x| format!("{x:.5}")),
                    num(f.scale, f4),
                    if f.tilt_fitted { num(f.tilt_deg, f4) } else { "— (not fitted)".into() },
                    num(f.mse_per_sr2, e4),
                    num(f.nrmse, f4),
                    f.bins.to_string(),
                ]
            })
            .collect();
        h.push_str(&table(&["model", "α", "scale", "tilt (°)", "MSE (1/sr²)", "NRMSE", "bins"], &rows));
        let better = r.fits.get(r.better_model);
        let _ = write!(
            h,
            "<p class=\"note\">The fit's quality is its mean squared error over the {} bins of the normals' slope \
             histogram and that error's root over the largest measured density (NRMSE); fit.json gives no \
             standard error of α. The BSSRDF slices take the measured normals themselves (normals.exr) as the \
             top boundary unless [bssrdf] roughness is set; {} α = {} is the analytic description.</p>",
            better.bins,
            r.better_model.label(),
            num(better.alpha, |x| format!("{x:.5}")),
        );
        h.push_str("<div class=\"row\">");
        h.push_str(&ctx.page.img(&self.distribution_png, "normal distribution with both fits")?);
        h.push_str(&ctx.page.img(&self.heightmap_png, "levelled height map")?);
        h.push_str("</div>");
        sj.insert("surface".into(), trim(&to_value(&r), 16));
        Ok(h)
    }
}
