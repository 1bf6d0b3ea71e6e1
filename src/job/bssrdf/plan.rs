//! What a slab job simulates ([`Plan`]): the medium (a recipe's bulk
//! properties by Lorenz–Mie at the wavelength, or the explicit μs, μa, g,
//! n; the similar medium when asked), the beam, the sensor (the crop
//! only), the stop rule, the top boundary, the slabs at ±1 σ of the
//! recipe's uncertain inputs, and per configuration the directions, the
//! estimator and the run options — all checked before any work.

use super::error::BssrdfJobError as E;
use crate::bssrdf::{self, OpticalUsed};
use crate::job::context::Context;
use crate::job::spec::BssrdfJob;
use crate::job::spec::EstimatorChoice;
use crate::optics::recipe::{Overrides, Recipe};
use crate::optics::{bulk, PhaseModel};
use lucent_render::phase::{Phase, PhaseTable};
use lucent_render::slab::{self, Beam, BeamMap, Directions, Estimator, Medium, RunOptions, Sensor, Setup, Slab, Stop};

/// The medium, thickness and description of what was used.
pub struct MediumChoice {
    /// The recipe's measured surface, if any.
    pub surface: Option<crate::optics::recipe::Surface>,
    pub medium: Medium,
    pub thickness_m: f64,
    pub used: OpticalUsed,
    pub phase_name: String,
}

/// One uncertain recipe input of `--uncertainty`: its key, nominal value
/// and standard deviation, and the slabs at ±1 σ.
pub struct Perturbation {
    pub key: String,
    pub nominal: f64,
    pub sd: f64,
    plus: Slab,
    minus: Slab,
}

/// One configuration of a slab job, set up as the job runs it.
pub struct PlannedRun {
    /// θi, φi, θo, φo in degrees.
    pub angles: (f64, f64, f64, f64),
    pub dirs: Directions,
    pub setup: Setup,
    pub options: RunOptions,
    /// Per [`Plan::perturbations`] entry, the setups at +1 σ and −1 σ.
    pub pairs: Vec<(Setup, Setup)>,
}

/// Everything a slab job simulates, checked before any work: the medium
/// (the recipe's bulk properties at the wavelength, or the explicit
/// coefficients), the beam, the sensor (only the crop is simulated), the
/// stop rule (without one: 1 % on the slice sum, at most 600 s per
/// configuration), the top boundary, and per configuration the directions,
/// the estimator and the run options.
pub struct Plan {
    pub(super) medium: MediumChoice,
    pub beam: Beam,
    pub beam_name: String,
    /// Pixels per side of the simulated (cropped) slice.
    pub out_pixels: usize,
    pub stop: Stop,
    /// The top boundary as described in summary.json.
    pub roughness: String,
    pub runs: Vec<PlannedRun>,
    /// The uncertain inputs `uncertainty` carries to the slices (empty without it).
    pub perturbations: Vec<Perturbation>,
}

impl Plan {
    /// The beam's relative irradiance along the slice's middle row
    /// (`beam_relative` of profile.csv) for `run`, pixel size `pixel_mm`.
    pub fn beam_profile(&self, run: &PlannedRun, pixel_mm: f64) -> Vec<f64> {
        let n = self.out_pixels;
        let grid_x: Vec<f64> = (0..n).map(|c| (c as f64 + 0.5 - 0.5 * n as f64) * pixel_mm).collect();
        bssrdf::beam_profile(&self.beam, &run.dirs, &grid_x)
    }

    /// The medium's μs, μa [1/m], g and n as used.
    pub fn optical_properties(&self) -> &OpticalUsed {
        &self.medium.used
    }

    /// The phase function as described in summary.json.
    pub fn phase_name(&self) -> &str {
        &self.medium.phase_name
    }
}

/// The beam of `beam_fwhm_um` (a Gaussian) or of the map `beam_map`
/// (pixel size `beam_map_pixel_mm`, else its sidecar's), and how a report
/// describes it (`--beam-fwhm-um`, `--beam-map` of `bssrdf` and `fit`).
pub fn beam(
    beam_fwhm_um: f64,
    beam_map: Option<&std::path::Path>,
    beam_map_pixel_mm: Option<f64>,
) -> Result<(Beam, String), E> {
    match beam_map {
        Some(path) => {
            let grid = bssrdf::read_grid(path, beam_map_pixel_mm).map_err(E::BeamMap)?;
            let map = BeamMap::new(grid.size, grid.size, grid.pixel_m, grid.values)
                .map_err(|e| E::Refused(format!("{}: {e}", path.display())))?;
            Ok((Beam::Map(map), format!("map {}", path.display())))
        }
        None => {
            let fwhm = beam_fwhm_um;
            // Said in the flag's micrometres (the simulator's beam_fwhm_m is not the user's).
            if !(fwhm.is_finite() && fwhm > 0.0) {
                return Err(E::Refused(format!("--beam-fwhm-um {fwhm}: must be a positive number of micrometres")));
            }
            let beam = Beam::gaussian(fwhm * 1e-6).map_err(|e| E::Refused(format!("--beam-fwhm-um {fwhm}: {e}")))?;
            Ok((beam, format!("gaussian, FWHM {fwhm} µm")))
        }
    }
}

impl BssrdfJob {
    /// The job's beam and how summary.json describes it.
    pub fn beam(&self) -> Result<(Beam, String), E> {
        beam(self.beam_fwhm_um, self.beam_map.as_deref(), self.beam_map_pixel_mm)
    }

    /// The stop rule the job gives (paths, time, the error targets),
    /// without the default a run adds when none is given.
    pub fn stop(&self) -> Stop {
        Stop {
            samples: self.paths,
            time_s: self.time_s,
            rel_error: self.rel_error,
            pixel_rel_error: self.pixel_rel_error,
        }
    }

    /// The job's recipe (with its weight percentage), if it names one.
    pub fn load_recipe(&self) -> Result<Option<Recipe>, E> {
        let overrides = Overrides { weight_percent: self.weight_percent };
        Ok(self.recipe.as_ref().map(|path| Recipe::load(path, overrides)).transpose()?)
    }

    /// The medium of the job, its recipe read from `recipe` (warnings of
    /// Lorenz–Mie to `ctx`).
    pub fn medium(&self, ctx: &Context) -> Result<MediumChoice, E> {
        self.medium_of(self.load_recipe()?.as_ref(), Some(ctx))
    }

    /// The medium of the job with `recipe` as the recipe (`None`: the
    /// explicit coefficients).
    fn medium_of(&self, recipe: Option<&Recipe>, ctx: Option<&Context>) -> Result<MediumChoice, E> {
        let choice = self.exact_medium(recipe, ctx)?;
        self.similar_if_asked(choice)
    }

    /// `choice` with its medium replaced by the similar one when `similarity_g` asks for it.
    fn similar_if_asked(&self, mut choice: MediumChoice) -> Result<MediumChoice, E> {
        if let Some(g_max) = self.similarity_g {
            let similar = choice.medium.similar(g_max).map_err(|e| E::Refused(format!("--similarity-g: {e}")))?;
            choice.phase_name = format!(
                "{}, similar medium (g′ = {:.4}, μs′ = {:.6} /m)",
                choice.phase_name,
                similar.phase.mean_cosine(),
                similar.mu_s_per_m
            );
            choice.medium = similar;
        }
        Ok(choice)
    }

    /// `thickness_mm` in metres, checked.
    fn explicit_thickness_m(&self) -> Result<Option<f64>, E> {
        match self.thickness_mm {
            Some(t) if !(t.is_finite() && t > 0.0) => Err(E::Refused(format!(
                "--thickness-mm {t}: the slab thickness must be a positive number of millimetres"
            ))),
            t => Ok(t.map(|t| t * 1e-3)),
        }
    }

    /// The medium of `recipe` at the wavelength (Lorenz–Mie), with the
    /// phase function `phase` asks for; its warnings to `ctx` if given.
    fn recipe_medium(&self, recipe: &Recipe, ctx: Option<&Context>) -> Result<MediumChoice, E> {
        let options = bulk::Options::default();
        let s = bulk::at_wavelength(recipe, self.wavelength_nm, &options)?;
        if let Some(ctx) = ctx {
            for w in &s.warnings {
                ctx.warn(&format!("{}: {w} (at {} nm)", recipe.name, self.wavelength_nm));
            }
        }
        let choice = self.phase.unwrap_or(PhaseModel::Mie);
        let (phase, name) = match choice {
            PhaseModel::Mie => {
                (Phase::Tabulated(PhaseTable::from_theta_samples(&s.phase)?), "mie (4096-entry table)".to_string())
            }
            PhaseModel::Hg => (Phase::henyey_greenstein(s.g)?, format!("hg (g = {:.5})", s.g)),
        };
        let medium = Medium::new(s.mu_s_per_m, s.mu_a_per_m, phase, s.n_bulk.max(1.0))?;
        Ok(MediumChoice {
            surface: recipe.surface,
            medium,
            thickness_m: self.explicit_thickness_m()?.unwrap_or(recipe.thickness_m),
            used: OpticalUsed { mu_s_per_m: s.mu_s_per_m, mu_a_per_m: s.mu_a_per_m, g: s.g, n: s.n_bulk },
            phase_name: name,
        })
    }

    fn exact_medium(&self, recipe: Option<&Recipe>, ctx: Option<&Context>) -> Result<MediumChoice, E> {
        let explicit_thickness = self.explicit_thickness_m()?;
        if let Some(recipe) = recipe {
            return self.recipe_medium(recipe, ctx);
        }
        let (Some(mu_s), Some(mu_a), Some(g), Some(n)) = (self.mu_s, self.mu_a, self.g, self.n) else {
            return Err(E::Refused(
                "give --recipe R.toml, or all of --mu-s --mu-a --g --n (and optionally --thickness-mm)".into(),
            ));
        };
        if self.phase == Some(PhaseModel::Mie) {
            return Err(E::Refused("--phase mie needs --recipe (a tabulated Lorenz–Mie phase function)".into()));
        }
        let medium = Medium::new(mu_s, mu_a, Phase::henyey_greenstein(g)?, n)?;
        Ok(MediumChoice {
            surface: None,
            medium,
            thickness_m: explicit_thickness.unwrap_or(6.35e-3),
            used: OpticalUsed { mu_s_per_m: mu_s, mu_a_per_m: mu_a, g, n },
            phase_name: format!("hg (g = {g})"),
        })
    }

    /// The perturbed slabs of `uncertainty` (empty without it) of `recipe`, their tops `top`.
    fn perturbations(
        &self,
        recipe: Option<&Recipe>,
        top: &lucent_render::interface::Interface,
    ) -> Result<Vec<Perturbation>, E> {
        if !self.uncertainty {
            return Ok(Vec::new());
        }
        let Some(recipe) = recipe else {
            return Err(E::Refused("--uncertainty needs --recipe: the uncertain inputs are a recipe's (e.g. weight_percent = { value = 0.65, sd = 0.03 })".into()));
        };
        if recipe.uncertain.is_empty() {
            return Err(E::Refused(format!(
                "--uncertainty: {} gives no input with an uncertainty (write e.g. weight_percent = {{ value = 0.65, sd = 0.03 }})",
                recipe.path.display()
            )));
        }
        recipe
            .uncertain
            .iter()
            .map(|input| {
                let sd = crate::optics::uncertainty::standard_deviation(&input.distribution);
                let slab_at = |v: f64| -> Result<Slab, E> {
                    let r = recipe.with_input(input.target, v).map_err(|source| E::Perturbed {
                        what: format!("--uncertainty: {} = {v} (nominal ∓ 1 σ)", input.key),
                        source,
                    })?;
                    let m = self.similar_if_asked(self.recipe_medium(&r, None)?)?;
                    Ok(Slab::new(m.thickness_m, m.medium)?.with_top(top.clone()))
                };
                Ok(Perturbation {
                    key: input.key.clone(),
                    nominal: input.nominal,
                    sd,
                    plus: slab_at(input.nominal + sd)?,
                    minus: slab_at(input.nominal - sd)?,
                })
            })
            .collect()
    }

    /// The [`Plan`] of the job (its recipe read from `recipe`; Lorenz–Mie's
    /// warnings to `ctx`).
    pub fn plan(&self, ctx: &Context) -> Result<Plan, E> {
        self.plan_with(self.load_recipe()?.as_ref(), Some(ctx))
    }

    /// The [`Plan`] of the job with `recipe` as the medium's recipe in place
    /// of the file `recipe` names (a recipe not read from a file, e.g. the
    /// Python API's dict); `None`: the explicit coefficients. Lorenz–Mie's
    /// warnings are said to `ctx`, if given.
    pub fn plan_with(&self, recipe: Option<&Recipe>, ctx: Option<&Context>) -> Result<Plan, E> {
        let m = self.medium_of(recipe, ctx)?;
        let (beam, beam_name) = self.beam()?;
        let out_pixels = self.out_pixels()?;
        let sensor = self.sensor(out_pixels, &beam)?;
        // Without a stop rule: 1 % on the slice sum, but at most 10 minutes per
        // configuration (strongly forward-peaked media converge slowly).
        let stop = self.stop();
        let stop = if stop.is_empty() { Stop { rel_error: Some(0.01), time_s: Some(600.0), ..stop } } else { stop };
        let (top, roughness) = bssrdf::roughness(self.roughness.as_ref(), m.surface.as_ref())?;
        let perturbations = self.perturbations(recipe, &top)?;
        let slab = Slab::new(m.thickness_m, m.medium.clone())?.with_top(top);
        let configs = match &self.configs {
            Some(list) => list.pairs().into_iter().map(|(ti, to)| (ti, self.phi_i, to, self.phi_o)).collect(),
            None => vec![(self.theta_i, self.phi_i, self.theta_o, self.phi_o)],
        };
        let runs = configs
            .into_iter()
            .map(|(ti, pi, to, po)| {
                let dirs =
                    Directions::from_degrees(ti, pi, to, po).map_err(|source| E::Configuration { ti, to, source })?;
                let setup = Setup::new(slab.clone(), beam.clone(), sensor, dirs);
                let options = self.run_options(&setup, stop);
                let pairs = perturbations
                    .iter()
                    .map(|p| {
                        (
                            Setup::new(p.plus.clone(), beam.clone(), sensor, dirs),
                            Setup::new(p.minus.clone(), beam.clone(), sensor, dirs),
                        )
                    })
                    .collect();
                Ok(PlannedRun { angles: (ti, pi, to, po), dirs, setup, options, pairs })
            })
            .collect::<Result<Vec<_>, E>>()?;
        Ok(Plan { medium: m, beam, beam_name, out_pixels, stop, roughness, runs, perturbations })
    }

    /// Pixels per side of the simulated slice: the crop, else all.
    fn out_pixels(&self) -> Result<usize, E> {
        match self.crop {
            Some(c) if c == 0 || c > self.pixels => {
                Err(E::Refused(format!("--crop {c}: must lie in 1 … --pixels ({})", self.pixels)))
            }
            Some(c) => Ok(c),
            None => Ok(self.pixels),
        }
    }

    /// The sensor of the crop, its pixel size, path count and beam checked
    /// against it (a slice the flags cannot give is refused before any work).
    fn sensor(&self, out_pixels: usize, beam: &Beam) -> Result<Sensor, E> {
        // Said with the flags (the simulator's own message names its pixel_m).
        // Large and small values as written (1e300, not 300 digits).
        let num = |x: f64| if x != 0.0 && !(1e-4..1e6).contains(&x.abs()) { format!("{x:e}") } else { format!("{x}") };
        let pixel_mm = self.pixel_mm;
        if !(pixel_mm.is_finite() && pixel_mm > 0.0) {
            return Err(E::Refused(format!("--pixel-mm {pixel_mm}: must be a positive number of millimetres")));
        }
        if pixel_mm * out_pixels as f64 > 1000.0 {
            return Err(E::Refused(format!(
                "--pixel-mm {}: the slice ({out_pixels} pixels × {} mm = {} mm) must be at most 1000 mm (1 m) wide",
                num(pixel_mm),
                num(pixel_mm),
                num(pixel_mm * out_pixels as f64)
            )));
        }
        // Only the crop is simulated: the pixels outside it would be discarded.
        let sensor = Sensor::new(out_pixels, pixel_mm * 1e-3)?;
        if let Some(n) = self.paths
            && let Some(reason) = bssrdf::paths_problem(n)
        {
            return Err(E::Refused(format!("--paths {n}: {reason}")));
        }
        let field_mm = out_pixels as f64 * pixel_mm;
        if self.beam_map.is_none() && self.beam_fwhm_um * 1e-3 > field_mm {
            return Err(E::Refused(format!("--beam-fwhm-um {}: the beam is wider than the slice ({out_pixels} pixels × {} mm = {} mm); widen the slice (--pixels, --pixel-mm) or narrow the beam", self.beam_fwhm_um, num(pixel_mm), num(field_mm))));
        }
        if let (Beam::Map(map), Some(path)) = (beam, &self.beam_map) {
            // The same rule for a map, by its second moments (a map may have a wide dark border).
            let fwhm_mm = beam_map_fwhm_m(map) * 1e3;
            if fwhm_mm > field_mm {
                return Err(E::Refused(format!("--beam-map {}: the beam is wider than the slice (Gaussian-equivalent FWHM {fwhm_mm:.3} mm from its second moments; the slice is {out_pixels} pixels × {} mm = {} mm); widen the slice (--pixels, --pixel-mm) or check --beam-map-pixel-mm", path.display(), num(pixel_mm), num(field_mm))));
            }
        }
        Ok(sensor)
    }

    /// The run options of one configuration.
    fn run_options(&self, setup: &Setup, stop: Stop) -> RunOptions {
        let lobe = Estimator::Lobe { vertices: self.lobe_vertices.into() };
        let estimator = match self.estimator {
            EstimatorChoice::Auto => match Estimator::best_for(setup) {
                Estimator::Lobe { .. } => lobe,
                e => e,
            },
            EstimatorChoice::Ring => Estimator::Ring,
            EstimatorChoice::Lobe => lobe,
            EstimatorChoice::Connection => Estimator::Connection,
        };
        RunOptions { stop, seed: self.seed, estimator, fold: !self.no_fold, ..RunOptions::default() }
    }
}

/// The larger of the map's Gaussian-equivalent FWHMs along x and y [m]:
/// the FWHM of a Gaussian of σ² the irradiance-weighted variance of the
/// pixel centres (the conversion is `slab::fwhm_to_sigma`'s, inverted).
fn beam_map_fwhm_m(map: &BeamMap) -> f64 {
    let (mut w, mut sx, mut sy, mut sxx, mut syy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (i, v) in map.values.iter().enumerate() {
        let (x, y) = ((i % map.width) as f64 * map.pixel_m, (i / map.width) as f64 * map.pixel_m);
        w += v;
        sx += v * x;
        sy += v * y;
        sxx += v * x * x;
        syy += v * y * y;
    }
    let var = |s: f64, ss: f64| (ss / w - (s / w).powi(2)).max(0.0);
    var(sx, sxx).max(var(sy, syy)).sqrt() / slab::fwhm_to_sigma(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn beam_map_fwhm_is_the_gaussian_fwhm_of_a_gaussian_map() {
        // A Gaussian of σx = 0.2 mm, σy = 0.1 mm on 0.01 mm pixels, off centre:
        // FWHM = 2.3548 σ of the wider axis, 0.471 mm.
        let (n, p) = (201, 1e-5);
        let values: Vec<f64> = (0..n * n)
            .map(|i| {
                let (x, y) = (((i % n) as f64 - 120.0) * p, ((i / n) as f64 - 90.0) * p);
                (-0.5 * (x * x / 4e-8 + y * y / 1e-8)).exp()
            })
            .collect();
        let map = BeamMap::new(n, n, p, values).unwrap();
        let fwhm = beam_map_fwhm_m(&map);
        assert!((fwhm / (2.354_820 * 2e-4) - 1.0).abs() < 0.01, "{fwhm}");
    }
}
