//! `lucent render --uncertainty`: the recipe's uncertain inputs carried to
//! the twin. An input that changes only μs and μa is estimated from the
//! nominal render's own paths (a path derivative, [`RenderJob::uncertain_inputs`]),
//! any other from renders of the scene at ±1 σ with the nominal's seed
//! ([`RenderJob::band_of`]); the band ([`scene::band::render_band`]) is
//! each region's mean with its standard deviation from the inputs.

use super::error::{BandError, RenderError};
use crate::fault::Interrupted;
use crate::job::context::Context;
use crate::job::spec::RenderJob;
use crate::scene;
use lucent_render::tracer::{self, Image, Settings};
use std::sync::atomic::{AtomicBool, Ordering};

/// The recipe's uncertain inputs of a render ([`RenderJob::uncertain_inputs`]).
pub struct Uncertain {
    pub recipe: crate::optics::recipe::Recipe,
    /// Per input, its index in the settings' derivatives and what that
    /// leaves out (relative), or `None`: rendered at ±1 σ.
    pub path_derivatives: Vec<Option<(usize, f64)>>,
}

/// The largest relative change of the phase functions and indices between
/// an input's ±1 σ that its path derivative may leave out (a weight
/// percentage of IOL1068-09 changes them by ≤ 4·10⁻⁴ through the bands'
/// spectral weights and 2·10⁻⁶ through the mixture's index; the test
/// against renders at ±1 σ bounds the effect).
const PATH_DERIVATIVE_LEFT_OUT: f64 = 1e-3;

/// The similar medium's g′ (and the later one's) that the nominal render
/// walks, for the renders at ±1 σ: the depth floor would otherwise move g′
/// with the input, and the phase functions with it, and the renders would
/// no longer share their paths.
fn walked_similarity(loaded: &scene::LoadedScene) -> Option<(f64, Option<(u64, f64)>)> {
    loaded.summary.material.as_ref().and_then(|m| m.similar.as_ref()).map(|s| {
        // (+1e-9: the walked g′ is the table's mean cosine, which the cut's own test may round just above.)
        (s.g[0] + 1e-9, s.later.as_ref().map(|l| (l.from_event, l.g[0] + 1e-9)))
    })
}

impl RenderJob {
    /// With `uncertainty`: the scene's recipe (refused without one or
    /// without an uncertain input) and, per uncertain input, its index in
    /// `settings.derivatives` (pushed here) where the nominal render's own
    /// paths carry its effect (with what that leaves out), `None` where it is
    /// rendered at ±1 σ. `None` without `uncertainty`.
    pub fn uncertain_inputs(
        &self,
        ctx: &Context,
        loaded: &scene::LoadedScene,
        settings: &mut Settings,
    ) -> Result<Option<Uncertain>, RenderError> {
        if !self.uncertainty {
            return Ok(None);
        }
        if let Some(n) = self.uncertainty_spp
            && (n == 0 || n % 2 == 1)
        {
            return Err(RenderError::UncertaintySpp(n));
        }
        let recipe =
            scene::material_recipe(&self.scene)?.ok_or_else(|| RenderError::NoRecipe { scene: self.scene.clone() })?;
        if recipe.uncertain.is_empty() {
            return Err(RenderError::NoUncertainInput { recipe: recipe.path.clone() });
        }
        let found = if self.uncertainty_renders {
            vec![None; recipe.uncertain.len()]
        } else {
            self.coefficient_derivatives(loaded, &recipe)?
        };
        let mut index = Vec::new();
        for d in found {
            index.push(match d {
                Some((d, left_out)) if settings.derivatives.len() < tracer::MAX_DERIVATIVES => {
                    settings.derivatives.push(d);
                    Some((settings.derivatives.len() - 1, left_out))
                }
                _ => None,
            });
        }
        if settings.sphere_jumps && !settings.derivatives.is_empty() && !ctx.quiet {
            ctx.note("sphere jumps are off in this render: the path derivatives of --uncertainty need every scattering event");
        }
        Ok(Some(Uncertain { recipe, path_derivatives: index }))
    }

    /// The scene with one uncertain input at `value` (`sign` 1 σ from its
    /// nominal), the similar medium walked as the nominal render's.
    fn at_one_sigma(
        &self,
        input: &crate::optics::recipe::UncertainInput,
        sign: &'static str,
        value: f64,
        walked: Option<(f64, Option<(u64, f64)>)>,
    ) -> Result<scene::LoadedScene, RenderError> {
        let (loaded, _) = self.prepare_as(false, Some((input.target, value)), walked).map_err(|source| {
            RenderError::AtOneSigma { key: input.key.clone(), value, sign, source: Box::new(source) }
        })?;
        Ok(loaded)
    }

    /// Per uncertain input of `recipe`, the derivative of the object's
    /// coefficients per 1 σ where the input changes only μs and μa
    /// ([`tracer::Object::coefficient_derivative`] of the scenes at ±1 σ): the
    /// nominal render then estimates its effect from its own paths. `None`
    /// for an input that changes more (it is rendered at ±1 σ).
    fn coefficient_derivatives(
        &self,
        loaded: &scene::LoadedScene,
        recipe: &crate::optics::recipe::Recipe,
    ) -> Result<Vec<Option<(tracer::CoefficientDerivative, f64)>>, RenderError> {
        let walked = walked_similarity(loaded);
        let inputs = crate::optics::uncertainty::InputSd::of(recipe);
        let mut out = Vec::new();
        for (input, sd) in recipe.uncertain.iter().zip(&inputs) {
            let mut at = Vec::new();
            for (sign, value) in [("+", input.nominal + sd.sd), ("−", input.nominal - sd.sd)] {
                at.push(self.at_one_sigma(input, sign, value, walked)?.scene.object);
            }
            out.push(match (&loaded.scene.object, &at[0], &at[1]) {
                (Some(o), Some(plus), Some(minus)) => o.coefficient_derivative(plus, minus, PATH_DERIVATIVE_LEFT_OUT),
                _ => None,
            });
        }
        Ok(out)
    }

    /// The band of the nominal render `image` ([`scene::band::render_band`]):
    /// each of `recipe`'s uncertain inputs' effect from the nominal render's own
    /// paths where `path_derivatives` ([`RenderJob::uncertain_inputs`]) gives its index in
    /// [`Image::derivatives`], else from renders at ±1 σ with the nominal's
    /// seed (`uncertainty_spp` samples, default half the nominal's median on
    /// the object), which `cancel` stops (an error) as does the time budget.
    /// Also the number of those renders.
    #[allow(clippy::too_many_arguments)]
    pub fn band_of(
        &self,
        ctx: &Context,
        loaded: &scene::LoadedScene,
        settings: &Settings,
        pool: &rayon::ThreadPool,
        image: &Image,
        recipe: &crate::optics::recipe::Recipe,
        path_derivatives: &[Option<(usize, f64)>],
        cancel: &AtomicBool,
    ) -> Result<(scene::band::RenderBand, usize), BandError> {
        use crate::optics::uncertainty::InputSd;
        use scene::band::EffectEstimate;
        // The renders at ±1 σ carry no derivatives.
        let settings = &Settings { derivatives: Vec::new(), ..settings.clone() };
        let spp = self.uncertainty_spp.unwrap_or_else(|| half_the_median_on_the_object(image));
        let inputs = InputSd::of(recipe);
        let renders = 2 * path_derivatives.iter().filter(|d| d.is_none()).count();
        for (input, d) in inputs.iter().zip(path_derivatives) {
            if let Some((_, left_out)) = d {
                ctx.say(&format!(
                    "uncertainty: {} changes μs and μa (its phase functions and index by ≤ {left_out:.1e}, left out): its effect from the render's own paths (path derivative)",
                    input.key
                ));
            }
        }
        if renders > 0 {
            ctx.say(&format!(
                "uncertainty: {renders} renders of {spp} spp (each other input of {} at ±1 σ, with the same seed)",
                recipe.path.display()
            ));
        }
        let pairs = self.renders_at_one_sigma(ctx, loaded, settings, pool, recipe, path_derivatives, spp, cancel)?;
        let mut rendered = pairs.iter();
        let mut effects = Vec::new();
        for d in path_derivatives {
            effects.push(match d {
                Some((index, left_out)) => EffectEstimate::PathDerivative { index: *index, left_out: *left_out },
                None => {
                    let (plus, minus) =
                        rendered.next().ok_or(RenderError::Internal("one pair of renders per rendered input"))?;
                    EffectEstimate::Renders { plus, minus, spp }
                }
            });
        }
        Ok((scene::band::render_band(image, &inputs, &effects), renders))
    }

    /// The renders at +1 σ and −1 σ of each input without a path
    /// derivative, of `spp` samples each. `time_s` (or `[render] time_s`)
    /// bounds them together: past it, or when `cancel` is set, a watcher
    /// stops them.
    #[allow(clippy::too_many_arguments)]
    fn renders_at_one_sigma(
        &self,
        ctx: &Context,
        loaded: &scene::LoadedScene,
        settings: &Settings,
        pool: &rayon::ThreadPool,
        recipe: &crate::optics::recipe::Recipe,
        path_derivatives: &[Option<(usize, f64)>],
        spp: u32,
        cancel: &AtomicBool,
    ) -> Result<Vec<(Image, Image)>, BandError> {
        let walked = walked_similarity(loaded);
        let inputs = crate::optics::uncertainty::InputSd::of(recipe);
        let deadline = settings.stop.time_s.map(|t| std::time::Instant::now() + std::time::Duration::from_secs_f64(t));
        let (stop, finished, timed_out) = (AtomicBool::new(false), AtomicBool::new(false), AtomicBool::new(false));
        std::thread::scope(|scope| {
            scope.spawn(|| {
                while !finished.load(Ordering::Relaxed) {
                    if deadline.is_some_and(|d| std::time::Instant::now() >= d) {
                        timed_out.store(true, Ordering::Relaxed);
                        stop.store(true, Ordering::Relaxed);
                    }
                    if cancel.load(Ordering::Relaxed) {
                        stop.store(true, Ordering::Relaxed);
                    }
                    std::thread::sleep(std::time::Duration::from_millis(20));
                }
            });
            let rendered = (|| -> Result<Vec<(Image, Image)>, BandError> {
                let mut pairs = Vec::new();
                let each = recipe.uncertain.iter().zip(&inputs).zip(path_derivatives).filter(|(_, d)| d.is_none());
                for ((input, sd), _) in each {
                    let mut pair = Vec::new();
                    for (sign, value) in [("+", input.nominal + sd.sd), ("−", input.nominal - sd.sd)] {
                        let loaded = self.at_one_sigma(input, sign, value, walked)?;
                        let (acc, stats) =
                            pool.install(|| tracer::render_samples(&loaded.scene, settings, 0..spp, Some(&stop)));
                        if timed_out.load(Ordering::Relaxed) {
                            return Err(RenderError::BandTimeBudget(settings.stop.time_s.unwrap_or(0.0)).into());
                        }
                        if stop.load(Ordering::Relaxed) {
                            return Err(Interrupted("the renders at ±1 σ were stopped".into()).into());
                        }
                        ctx.say(&format!(
                            "  {} {sign} 1 σ = {value:.6}: {spp} spp in {:.1} s",
                            input.key, stats.wall_s
                        ));
                        pair.push(acc.image());
                    }
                    let minus = pair.pop().ok_or(RenderError::Internal("two renders per input"))?;
                    let plus = pair.pop().ok_or(RenderError::Internal("two renders per input"))?;
                    pairs.push((plus, minus));
                }
                Ok(pairs)
            })();
            finished.store(true, Ordering::Relaxed);
            rendered
        })
    }
}

/// Half the nominal render's median samples over the object's pixels (all
/// pixels without an object), even, ≥ 2: the default samples of a render at ±1 σ.
fn half_the_median_on_the_object(image: &Image) -> u32 {
    let mut counts: Vec<u32> = (0..image.samples.len())
        .filter(|&p| image.region(p) == tracer::Region::Object)
        .map(|p| image.samples[p])
        .collect();
    if counts.is_empty() {
        counts = image.samples.clone();
    }
    counts.sort_unstable();
    let median = counts.get(counts.len() / 2).copied().unwrap_or(2);
    ((median / 2).max(2) + 1) & !1
}
