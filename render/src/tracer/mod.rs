//! The 3D digital twin: unidirectional volumetric path tracing of a
//! translucent object on a checkerboard under an HDR environment (docs/method.md §5).
//!
//! # What is computed
//!
//! Each pixel's value is the mean radiance L [W m⁻² sr⁻¹, in the units of
//! the environment map] arriving at the camera through that pixel's square
//! (box filter, [`crate::camera`]), in three bands R, G, B of CIE RGB. Every
//! pixel also gets the variance of that mean, estimated from its samples, so
//! a render can be compared with another by a per-pixel z-test.
//!
//! # Scene
//!
//! * One **object**: a closed triangle mesh ([`Accel`]) whose boundary is an
//!   [`Interface`] (smooth dielectric: unpolarised Fresnel and Snell,
//!   [`crate::fresnel`]; or rough: the microfacet BSDF of Walter et al. 2007
//!   with an analytic or measured-normal microsurface, docs/method.md §2,
//!   [`crate::interface`], sampled with its weight f|cos|/pdf, radiance
//!   transport) around a homogeneous [`Medium`] per band: scattering and
//!   absorption coefficients μ_s, μ_a [1/m], a phase function and the index n.
//! * A **checkerboard** ([`Board`]): a finite plane, Lambertian (two-sided),
//!   reflectance per square from two RGB values or an image texture.
//! * The **environment** ([`Environment`]): equirectangular radiance at
//!   infinity or on the finite sphere of docs/method.md §5.
//!
//! # Estimator
//!
//! Paths start at the camera. At the object's boundary the path chooses
//! reflection with probability F (the Fresnel reflectance of the path's
//! band) and refraction otherwise, so the Fresnel factors cancel.
//!
//! **Bands.** At its first contact with the object a path picks one band h
//! uniformly (probability 1/3); h drives the sampling from then on (free
//! flights with density μ_t,h e^{−μ_t,h s}, directions from h's phase
//! function, h's index at the boundary). The plain estimator of docs/method.md §5 carries 3·β_h
//! in band h and 0 in the others ([`Settings::spectral_mis`] = false, and
//! always when the index differs between bands: a refraction direction then
//! belongs to one band only). When the index is the same in all bands the
//! path carries all three (**spectral MIS**, the one-sample balance
//! heuristic over the band that drives the sampling; Wilkie et al. 2014,
//! Miller et al. 2019): band c's estimate is f_c / ((1/3) Σ_k p_k), f_c the
//! path's contribution in band c and p_k its density had band k driven it.
//! The weight is at most 3·Π(μ_s/μ_t) per path, so it is never much worse
//! than the single band and, for bands with similar coefficients, close to
//! three independent paths for the price of one. A flight ends at a
//! scattering event (contribution μ_s,c e^{−μ_t,c s}) or at the boundary
//! (e^{−μ_t,c t}, exactly the probability of getting there). There is no
//! depth limit.
//!
//! **Connections from inside.** A smooth boundary makes the light that
//! leaves the medium a delta in direction, so no shadow ray can reach the
//! environment from a scattering point x. For a convex object (its flat
//! faces known, [`Accel::convex_planes`]) the connection is made backwards:
//! a direction ω_o is drawn from the environment's sampler at x; for each
//! face with n·ω_o > 0 Snell's law gives the inside direction ω_i that
//! refracts into ω_o, and if the ray x + tω_i leaves through that face (and
//! the board does not block ω_o) the path gets p(ω_in·ω_i) e^{−μ_t t}
//! (1 − F) L(q, ω_o) cos θ_o / (n² cos θ_i) / p_env(x, ω_o), the last
//! factor dω_i/dω_o of the refraction. Phase sampling finds the same light
//! when its path leaves straight through a face; the two are combined by the
//! balance heuristic (over bands too). A third strategy, the **phase
//! connection** ([`Settings::phase_connection`]), draws ω_i from the phase
//! function instead, follows x + tω_i to the face it leaves through,
//! refracts into ω_o and takes e^{−μ_t t} and (1 − F) as factors rather than
//! sampling them: the phase function's forward peak (g ≈ 0.97: most of its
//! mass within a few degrees), where an environment-sampled ω_o rarely
//! lands and then carries a huge p(ω_in·ω_i), is sampled by this strategy,
//! and the path's own escape, which must first fly unscattered to the
//! face, gives up most of its weight to it. All three share one balance
//! heuristic (densities in outside solid angle). A connection is attempted with
//! probability exp(−μ_t d), d the distance to the nearest face plane that
//! looks into the hemisphere the environment's sampling favours (not the
//! bottom face on a board, which hides that face's connections), a
//! bound on its transmittance (the probability is part of its density in
//! the weights). Connections are skipped under a uniform environment, where
//! they cannot help, and through a rough boundary, which this connection
//! does not model ([`Settings::medium_nee`]).
//!
//! **Specular chains** ([`Settings::specular_chains`], off by default): the
//! environment and phase connections also follow one reflection at a face
//! before the refraction out (the environment connection by the image
//! method: the ray from x's mirror image across the reflecting face), the
//! reflection made with probability max_c R_c and weighted by its inverse;
//! and the board's next-event estimation, where the object blocks its
//! shadow ray, connects through the object (in at one face, one
//! unscattered flight, out at another). The
//! path's own escape along such a chain is weighted against them (balance
//! heuristic), where it used to count in full and, meeting a lamp, made
//! the object's bright outliers.
//!
//! **Russian roulette** acts on the path throughput only, never on the
//! depth: when max β < 1/4 the path survives with probability 4·max β and
//! its β is divided by that probability (unbiased; the test renders the
//! same scene with and without roulette). A slab of optical depth ≈ 90 with
//! albedo 0.9993 keeps β ≈ 3 · 0.9993ⁿ for thousands of events, so its long
//! subsurface paths are not cut early (a depth-based roulette such as
//! Mitsuba's default starts at depth 5 and loses most of them).
//!
//! **On the board** (diffuse, reflectance ρ) the environment is sampled by
//! next-event estimation ([`Environment::sample`], pdf in solid angle *at
//! the board point*, which on the finite sphere differs from the pdf at the
//! sphere's centre), shadow rays blocked by the object (a smooth dielectric
//! cannot be connected through), and the next direction is drawn
//! cosine-weighted (pdf cos θ/π, weight ρ). The two strategies for light
//! that arrives straight from the environment are combined by multiple
//! importance sampling with the power heuristic (Veach & Guibas 1995):
//! NEE weight p_env²/(p_env² + p_bsdf²), and the same with the roles swapped
//! when a BSDF-sampled ray escapes directly. A ray that escapes after passing
//! through the object could not have been found by NEE and has weight 1.
//!
//! **Options** (none on by default; each is z-tested against the default
//! in `tests/tracer.rs`, per pixel and on the object's mean):
//! [`Settings::split_entry`] follows both the reflection (weight F_c) and
//! the refraction (1 − F_c) where a path meets the object from outside;
//! [`Dispersion::SharedDirections`] refracts with the bands' mean index
//! while keeping each band's Fresnel factors, so a path carries all bands
//! (approximate: the refracted directions of the bands no longer spread);
//! [`Sampling::ObjectWeighted`] gives pixels whose camera rays hit the
//! object more samples per pass, from the two regions' median per-sample
//! relative variances (a region-level statistic over thousands of pixels).
//!
//! **Figures.** Every [`Image`] counts per pixel the camera rays whose first
//! hit is the object or the board; [`Image::region_errors`] gives the median
//! and 90th percentile of the per-pixel relative standard error over the
//! object's pixels, the board's and all, and the stop rule's per-pixel
//! target ([`Stop::pixel_rel_error`]) stops on the object's median.
//!
//! **Self-intersection:** a ray leaving a surface starts ε = 10⁻⁷ × (the
//! scene's extent) off the surface along the geometric normal (20 nm for a
//! 0.2 m scene), on the side it travels into.
//!
//! **Determinism:** sample k of pixel p draws from
//! [`Rng::new`]`(seed, k·2³² + p)`, so an image depends on the seed and the
//! sample count only, never on the thread count or the tile order.
//!
//! # Where things are
//!
//! - here: the entry points [`render`], [`render_cancellable`] and
//!   [`render_samples`] (progressive passes, the samples each pixel gets
//!   per pass, the stop rules);
//! - `settings.rs`: how a render is made ([`Settings`] with its [`Stop`], [`Dispersion`],
//!   [`Sampling`], [`CoefficientDerivative`]);
//! - `scene.rs`: what is rendered ([`Scene`], [`Object`], [`Board`],
//!   [`BoardReflectance`], [`SceneError`]) and the similar media;
//! - `image.rs`: what comes out ([`Image`], [`DerivativeImage`],
//!   [`RegionErrors`], [`Quantiles`], [`Stats`], [`Progress`]);
//! - `accumulate.rs`: the per-pixel sums of the passes ([`Accumulator`])
//!   and one path's estimate with its derivatives (`Estimate`);
//! - `throughput.rs`: a path's spectral-MIS throughput (`Throughput`) and
//!   its Russian roulette;
//! - `walk.rs`: the path walk (free flights, scattering, sphere jumps, the
//!   board's bounce, the escape to the environment and its MIS weights);
//! - `boundary.rs`: crossing the object's surface from inside and from
//!   outside (Fresnel choice and refraction, a rough interface's sample,
//!   the entry's band branches and split) and the face search of a mesh
//!   (`mesh_exit`);
//! - `connections.rs`: the medium vertex's connections (environment,
//!   phase, chains through one reflection) and their balance heuristic;
//!   `board_nee.rs`: the board's next-event estimation, straight and by the
//!   object's faces;
//! - `tests.rs`: the tests of the private parts.
//!
//! ```
//! use glam::DVec3;
//! use lucent_render::{camera::Camera, env::{Environment, Projection}, tracer::*};
//! // An empty scene under a constant sky: every pixel sees the sky exactly.
//! let camera = Camera::look_at(8, 6, DVec3::new(0.0, -1.0, 1.0), DVec3::ZERO, DVec3::Z, 40.0).unwrap();
//! let env = Environment::constant([0.5, 1.0, 2.0], Projection::Infinite);
//! let scene = Scene::new(None, None, env, camera).unwrap();
//! let settings = Settings { stop: Stop::samples(4), ..Settings::default() };
//! let (img, _) = render(&scene, &settings, &mut |_| {}).unwrap();
//! assert_eq!(img.mean[0], [0.5, 1.0, 2.0]);
//! ```
//!
//! [`Accel`]: crate::accel::Accel
//! [`Interface`]: crate::interface::Interface
//! [`Medium`]: crate::medium::Medium
//! [`Environment`]: crate::env::Environment
//! [`Accel::convex_planes`]: crate::accel::Accel::convex_planes
//! [`Environment::sample`]: crate::env::Environment::sample
//! [`Rng::new`]: crate::rng::Rng::new

mod accumulate;
mod board_nee;
mod boundary;
mod connections;
mod image;
mod scene;
mod settings;
#[cfg(test)]
mod tests;
mod throughput;
mod walk;

pub use crate::stop::{Condition, NotSplittable, Stop, StopError};
pub use accumulate::Accumulator;
pub use image::{DerivativeImage, Image, Progress, Quantiles, Region, RegionErrors, Stats};
pub use scene::{Board, BoardReflectance, Object, Scene, SceneError, SIMILAR_LATER_MIN_DEPTH, SIMILAR_MIN_DEPTH};
pub use settings::{
    CoefficientDerivative, Dispersion, Sampling, Settings, MAX_DERIVATIVES, MAX_OBJECT_RATIO, SPHERE_MARGIN_MFP,
};

use crate::stop::Standing;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Renders `scene` progressively; `on_pass` is called after every pass.
/// Stops by `settings.stop` ([`Settings::stop`]: at its samples per pixel,
/// after the pass that exceeds its time budget or in which the object's
/// median error reaches its target) or when `cancel` (if given) is set.
/// A stop rule a render cannot honour is refused before any work
/// ([`Settings::check_stop`]).
pub fn render(
    scene: &Scene,
    settings: &Settings,
    on_pass: &mut dyn FnMut(&Progress),
) -> Result<(Image, Stats), StopError> {
    render_cancellable(scene, settings, on_pass, None)
}

/// [`render`] with a cancellation flag checked between passes.
pub fn render_cancellable(
    scene: &Scene,
    settings: &Settings,
    on_pass: &mut dyn FnMut(&Progress),
    cancel: Option<&AtomicBool>,
) -> Result<(Image, Stats), StopError> {
    settings.check_stop()?;
    let spp = settings.spp();
    let (w, h) = (scene.camera.width, scene.camera.height);
    let n = w * h;
    let mut acc = Accumulator::new(w, h);
    let mut stats = Stats::default();
    let start = Instant::now();
    let per_pass = settings.spp_per_pass.max(1);
    let weighted = settings.sampling == Sampling::ObjectWeighted && scene.object.is_some();
    // Samples per pass of an object pixel relative to a pixel that misses it.
    let mut ratio = 1u32;
    // This pass's samples per object pixel, in units of `per_pass`: it
    // doubles from pass to pass up to `ratio`, as long as a pass is expected
    // to end within the time budget and within MAX_PASS_S.
    let mut step = 1u32;
    let mut last_elapsed = 0.0;
    // Samples per pixel so far of a pixel whose rays all hit the object.
    let mut object_done = 0u32;
    let mut quota = vec![0u32; n];
    loop {
        // This pass's samples per pixel: the object's pixels get `step`
        // times more, pro rata of the fraction of rays that hit the object;
        // in all, the object's pixels get `spp`, the others spp / ratio.
        let object_next = object_done.saturating_add(per_pass.saturating_mul(step)).min(spp);
        let mut any = false;
        for (p, q) in quota.iter_mut().enumerate() {
            let done = acc.samples[p];
            let target = if !weighted {
                object_next
            } else if done == 0 {
                per_pass.min(spp)
            } else {
                // Keep pace with the object's pixels, at 1/ratio for a pixel that misses the object.
                let share = f64::from(acc.object_samples[p]) / f64::from(done);
                let t = (f64::from(object_next) * (share + (1.0 - share) / f64::from(ratio))).ceil() as u32;
                // A pixel that gets samples gets at least a pass's worth.
                if t > done {
                    t.max(done + per_pass)
                } else {
                    t
                }
            };
            *q = target.min(spp).saturating_sub(done);
            any |= *q > 0;
        }
        if !any {
            break;
        }
        let pass_stats = acc.add_pass(scene, settings, &quota, cancel);
        object_done = object_next;
        stats.add(&pass_stats);
        stats.passes += 1;
        let elapsed = start.elapsed().as_secs_f64();
        stats.wall_s = elapsed;
        let image = acc.image();
        let errors = image.region_errors();
        if weighted {
            ratio = object_ratio(&image);
            let unit_s = (elapsed - last_elapsed) / f64::from(step);
            let mut next = step.saturating_mul(2).min(ratio);
            if unit_s > 0.0 {
                let remaining = settings.stop.time_s.map_or(MAX_PASS_S, |b| (b - elapsed).min(MAX_PASS_S));
                next = next.min((remaining / unit_s).floor().max(1.0) as u32);
            }
            step = next.max(1);
        }
        last_elapsed = elapsed;
        let spp_done = acc.max_samples();
        on_pass(&Progress { spp_done, spp_target: spp, elapsed_s: elapsed, stats, errors });
        // The sample count ends the render through the quotas above (with
        // object-weighted sampling the other pixels may still be short).
        let standing = Standing {
            samples: None,
            elapsed_s: elapsed,
            rel_error: None,
            pixel_rel_error: (errors.object.pixels > 0).then_some(errors.object.median),
        };
        if settings.stop.met(&standing).is_some() || cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            break;
        }
    }
    stats.wall_s = start.elapsed().as_secs_f64();
    Ok((acc.image(), stats))
}

/// The longest a pass of [`Sampling::ObjectWeighted`] is planned to take,
/// seconds (progress and cancellation are seen between passes).
pub(super) const MAX_PASS_S: f64 = 10.0;

/// The samples-per-pass ratio between the object's pixels and the others
/// that makes their relative standard errors meet: the ratio of the medians
/// (over each region) of the per-sample relative variance n·(SE/mean)² of
/// the object's pixels and the board's (of all other pixels without a
/// board: the environment's pixels, nearly noiseless, would otherwise set
/// the ratio and starve the board), between 1 and [`MAX_OBJECT_RATIO`].
pub(super) fn object_ratio(image: &Image) -> u32 {
    let mut by: [Vec<f64>; 3] = Default::default();
    for p in 0..image.mean.len() {
        let Some(r) = image.relative_std_error(p) else { continue };
        let v = f64::from(image.samples[p]) * r * r;
        by[match image.region(p) {
            Region::Object => 0,
            Region::Board => 1,
            Region::Other => 2,
        }]
        .push(v);
    }
    let [objects, mut board, other] = by;
    if board.is_empty() {
        board = other;
    }
    let [o, rest] = [objects, board].map(|v| Quantiles::of(v).median);
    let ratio = if o.is_nan() {
        1.0
    } else if rest.is_nan() || rest <= 0.0 {
        f64::from(MAX_OBJECT_RATIO)
    } else {
        o / rest
    };
    (ratio.round() as u32).clamp(1, MAX_OBJECT_RATIO)
}

/// Samples `samples.start .. samples.end` of every pixel (uniform
/// sampling, in passes of `settings.spp_per_pass`), as per-pixel sums: one
/// shard of the render [`render`] makes with `spp = samples.end` (sample k
/// of pixel p draws from the same stream, so the shards of a partition of
/// 0..spp together hold exactly that render's samples). The stop rule
/// (`settings.stop`) and the sampling are not used. Stops
/// early only when `cancel` is set (then the counts say so).
pub fn render_samples(
    scene: &Scene,
    settings: &Settings,
    samples: std::ops::Range<u32>,
    cancel: Option<&AtomicBool>,
) -> (Accumulator, Stats) {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mut acc = Accumulator::new(w, h);
    acc.first_sample = samples.start;
    let count = samples.end.saturating_sub(samples.start);
    let per_pass = settings.spp_per_pass.max(1);
    let mut stats = Stats::default();
    let start = Instant::now();
    let mut done = 0u32;
    while done < count && !cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
        let q = per_pass.min(count - done);
        let pass_stats = acc.add_pass(scene, settings, &vec![q; w * h], cancel);
        stats.add(&pass_stats);
        stats.passes += 1;
        done += q;
    }
    stats.wall_s = start.elapsed().as_secs_f64();
    (acc, stats)
}
