//! The render stage's section of a sample in the run's report: samples
//! per pixel, image size, seed, wall time, the relative standard error per
//! pixel by region (the object's, the board's, all) and the approximations
//! the render made.

use crate::job::report::{esc, num, read_json, to_value, trim, Metrics, ReportError, ReportSection, SectionContext};
use crate::scene::{RenderFiles, RenderReport};
use std::fmt::Write as _;

/// A sample's render (stage render's files); empty when the stage has not
/// rendered it.
impl ReportSection for RenderFiles {
    fn section(&self, _: &mut SectionContext<'_>, sj: &mut Metrics) -> Result<String, ReportError> {
        let mut h = String::new();
        if let Some(r) = read_json::<RenderReport>(&self.json, "a render.json")? {
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
                            "relative standard error per pixel, median (90th percentile): the object's {} px {} % \
                             ({} %), the board's {} px {} % ({} %), all {} %",
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
}
