//! The env-scale stage's section of a sample in the run's report: the
//! fitted scale k (and per channel), the board pixels it is over, the
//! residual's RMS (absolute, relative to the photo, the render's noise) and
//! what that residual means for k.

use crate::envfit::{EnvScaleFiles, FitReport, ScaleFit};
use crate::job::report::{e4, esc, f4, num, read_json, to_value, Metrics, ReportError, ReportSection, SectionContext};
use std::fmt::Write as _;

/// A sample's environment scale (stage env-scale's files); empty when the
/// stage has not fitted one for the sample.
impl ReportSection for EnvScaleFiles {
    fn section(&self, _: &mut SectionContext<'_>, sj: &mut Metrics) -> Result<String, ReportError> {
        let mut h = String::new();
        if let Some(e) = read_json::<FitReport>(&self.json, "an env_scale.json")? {
            let f = &e.fit;
            let _ = write!(
                h,
                "<h3>Environment scale</h3><p>k = {} (per channel {}, {}, {}) over {} board pixels; residual RMS {} \
                 ({} % of the photo; render noise {}).</p>",
                num(f.scale, f4),
                num(f.scale_per_channel[0], f4),
                num(f.scale_per_channel[1], f4),
                num(f.scale_per_channel[2], f4),
                f.pixels,
                num(f.residual_rms, e4),
                num(f.relative_residual, |x| format!("{:.2}", 100.0 * x)),
                num(f.render_noise_rms, e4),
            );
            let _ = write!(h, "<p class=\"why\">{}</p>", esc(&residual_note(f)));
            sj.insert("env_scale".into(), to_value(&e));
        }
        Ok(h)
    }
}

/// What the environment scale's residual is, and whether it matters: it is
/// the pixel-by-pixel scatter of the photo about k × the render over the
/// board, not an error of k (a ratio of sums over many pixels).
fn residual_note(f: &ScaleFit) -> String {
    // Were the scatter independent from pixel to pixel, it would move the
    // ratio of sums by about relative_residual / √(3 N).
    let moves = f.relative_residual / (3.0 * f.pixels.max(1) as f64).sqrt();
    format!(
        "What the {} % means: the residual is the pixel-by-pixel scatter of the photo about k × the render over the \
         board (the photo's noise, the render's noise, demosaicing and the squares' edges), not an error of k. k is \
         a ratio of sums over {} pixels, which scatter of this size moves by only about ±{:.2} % (were it \
         independent from pixel to pixel); it matters only if the per-channel k disagree or the residual is far \
         above the noise.",
        num(f.relative_residual, |x| format!("{:.2}", 100.0 * x)),
        f.pixels,
        100.0 * moves
    )
}
