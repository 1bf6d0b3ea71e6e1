//! The optics stage's section of a sample in the run's report: its optical
//! properties (μs, μa, μt in 1/m, g, n_bulk at every 50 nm of a fine grid,
//! every wavelength of a coarse one), the absorption model, the clamped
//! index warnings, and the spectra and phase-function plots.

use crate::job::report::{
    e4, esc, f4, num, table, to_value, trim, Metrics, ReportError, ReportSection, SectionContext,
};
use crate::optics::output::{OpticalProperties, OpticsFiles, SampleFiles};
use crate::optics::recipe::{Overrides, Recipe};
use std::fmt::Write as _;
use std::path::Path;

/// The optics stage's spectra (one sample writes an object, several an
/// array), none when the stage has not run.
pub fn read_spectra(files: &OpticsFiles) -> Result<Vec<OpticalProperties>, ReportError> {
    if !files.json.exists() {
        return Ok(vec![]);
    }
    Ok(crate::optics::output::read_optical_properties(&files.json)?)
}

/// A sample's optical properties: its entry of the optics stage's
/// `spectra` (read once by [`read_spectra`]), matched by its recipe's name, with
/// their plots in the stage folder `dir`; empty when the stage has not
/// computed the sample.
pub struct OpticsSection<'a> {
    /// The sample's name (in captions; its recipe's when the recipe does not load).
    pub sample: &'a str,
    /// The sample's recipe file and its weight-percent override.
    pub recipe: &'a Path,
    pub weight_percent: Option<f64>,
    /// Every sample's spectra of the stage.
    pub spectra: &'a [OpticalProperties],
    /// The optics stage's folder.
    pub dir: &'a Path,
}

impl ReportSection for OpticsSection<'_> {
    fn section(&self, ctx: &mut SectionContext<'_>, sj: &mut Metrics) -> Result<String, ReportError> {
        let mut h = String::new();
        // Optics: match by recipe name (the "sample" field is the recipe's sample name).
        let recipe_name = Recipe::load(self.recipe, Overrides { weight_percent: self.weight_percent })
            .map(|r| r.name)
            .unwrap_or_else(|_| self.sample.to_string());
        if let Some(sp) = self.spectra.iter().find(|s| s.sample.as_deref() == Some(recipe_name.as_str())) {
            h.push_str("<h3>Optical properties (Lorenz–Mie)</h3>");
            let wl = &sp.wavelength_nm;
            let mut rows = Vec::new();
            for (i, w) in wl.iter().enumerate() {
                if wl.len() > 12 && (w.round() as i64) % 50 != 0 {
                    continue;
                }
                // μt and n_bulk may be left out of a hand-made file (read_optical_properties
                // checks every array given has one value per wavelength); μt = μs + μa then.
                let (mu_s, mu_a) = (sp.mu_s_per_m[i], sp.mu_a_per_m[i]);
                let mu_t = sp.mu_t_per_m.get(i).copied().unwrap_or(mu_s + mu_a);
                rows.push(vec![
                    format!("{w}"),
                    num(mu_s, e4),
                    num(mu_a, e4),
                    num(mu_t, e4),
                    num(sp.g[i], f4),
                    sp.n_bulk.get(i).map_or_else(|| "not in the file".into(), |n| num(*n, f4)),
                ]);
            }
            h.push_str(&table(&["λ [nm]", "μs [1/m]", "μa [1/m]", "μt [1/m]", "g", "n_bulk"], &rows));
            if let Some(a) = &sp.absorption {
                let _ = write!(h, "<p class=\"note\">absorption model: {}</p>", esc(a));
            }
            let clamps: Vec<&String> = sp.warnings.iter().filter(|w| w.contains(" clamped outside")).collect();
            if !clamps.is_empty() {
                let _ = write!(
                    h,
                    "<p class=\"why\">Clamped index: {}. The recipe's extrapolate = \"clamp\" holds n and κ at the \
                     data's end value there; at 380–399 nm the CIE colour-matching functions are below 1.2 % of their \
                     peaks, so a render's colour barely depends on it.</p>",
                    esc(&clamps.iter().map(|s| s.as_str()).collect::<Vec<_>>().join("; "))
                );
            }
            let files = SampleFiles::in_dir(&OpticsFiles::sample_dir(self.dir, self.spectra.len(), &recipe_name));
            h.push_str("<div class=\"row\">");
            h.push_str(&ctx.page.img(&files.png, &format!("{} μs, μa, g against wavelength", self.sample))?);
            for p in files.phase_pngs() {
                h.push_str(&ctx.page.img(&p, &format!("{} phase function (Lorenz–Mie vs HG)", self.sample))?);
            }
            h.push_str("</div>");
            sj.insert("optics".into(), trim(&to_value(sp), 64));
        }
        Ok(h)
    }
}
