//! BSSRDF slices of a plane-parallel slab by light tracing with explicit
//! connection to a fixed observation direction (docs/method.md §3).
//!
//! # Geometry and units
//!
//! The surface is the plane z = 0 with air (n = 1) above; the medium fills
//! −d ≤ z ≤ 0 with index n, scattering and absorption coefficients μ_s, μ_a
//! [1/m] and a phase function ([`Phase`](crate::phase::Phase)); below is air again. Lengths are in
//! metres, angles in degrees at the interface and radians inside. A direction
//! given by (θ, φ) is (sin θ cos φ, sin θ sin φ, cos θ): ω_i points from the
//! surface towards the light, ω_o towards the camera. The camera is
//! orthographic along −ω_o; its N × N pixels of side p form a grid *on the
//! surface*, centred at the origin, columns along +x, rows from +y (top) to
//! −y, so the plane of incidence for φ = 0° or 180° is the middle row.
//!
//! # Estimator
//!
//! Photons leave the beam with total flux Φ_i (weight 1 per path; Φ_i
//! cancels), are refracted into the slab with weight (1 − F(θ_i)) (the
//! specular part F is a delta in direction and is not part of the slice; it
//! is reported as `specular_reflectance`), fly distances with pdf μ_t e^{−μ_t s},
//! are reflected or transmitted at the boundaries with probability F and
//! 1 − F, and at every scattering event keep the weight factor μ_s/μ_t
//! (absorption as weight) before sampling the phase function. Russian
//! roulette below weight 0.1 survives with probability w/0.1 and resets the
//! weight to 0.1, which keeps the estimator unbiased. Connections (below)
//! from deeper than 8 optical depths along ω₂₁ are Russian-rouletted too:
//! made with probability e^{−(τ−8)} and weighted by its inverse.
//!
//! **Explicit connection.** For a smooth top surface the in-medium direction
//! that refracts into ω_o is fixed: ω₂₁ with sin θ_t = sin θ_o / n and the
//! azimuth of ω_o. From a scattering event at x_s (depth |z_s|) it meets the
//! surface after ℓ = |z_s| / cos θ_t at x_o = x_s + ℓ ω₂₁. The radiance that
//! leaves towards ω_o at x_o is L_o = T(θ_t)/n² · L_in, with L_in the
//! radiance arriving along ω₂₁ below the surface (radiance/n² is invariant
//! across a refraction) and T = 1 − F. Writing L_in as the integral of the
//! in-scattered source μ_s ∫p L along the line through x_o, and averaging
//! over the pixel area A_o = p², the volume element of the slanted column is
//! dV = cos θ_t dA dℓ, so
//!
//! ⟨L_o⟩_pixel = T / (n² A_o cos θ_t) · E[ Σ_events w (μ_s/μ_t) p(ω_s·ω₂₁) e^{−μ_t ℓ} 1{x_o ∈ pixel} ],
//!
//! because the power-weighted density of collisions is μ_t L. Each event
//! therefore splats w · p · e^{−μ_t ℓ} · T / (n² A_o cos θ_t) (w already
//! multiplied by μ_s/μ_t), and the slice is f_ssr = ⟨L_o⟩/Φ_i = I_p/(A_⊥ Φ_i)
//! with A_⊥ = A_o cos θ_o, in 1/(m² sr). The connection direction is never
//! sampled, so the split of the transport integral is exact.
//!
//! **Internal reflections.** Light scattered at x_s can also reach ω_o after
//! specular reflections at the smooth boundaries: down along the mirror of
//! ω₂₁, reflected at the bottom (factor F(θ_t)), up through the slab; or up,
//! reflected at the top, down, reflected at the bottom, up; and so on. These
//! are the same straight column folded at the boundaries, so each adds an
//! image term with path length (2d − |z_s| + 2kd)/cos θ_t (factor F^{2k+1},
//! phase function at the mirrored direction) or (|z_s| + 2(k+1)d)/cos θ_t
//! (F^{2k+2}), splatted at its own exit point. Without them a thin slab's
//! slice is several percent low; in a thick slab (μ_t d / cos θ_t ≥ 40) they
//! are skipped.
//!
//! **Rough top** ([`Interface::Rough`](crate::interface::Interface::Rough), docs/method.md §2–§3). The top is then the
//! microfacet dielectric of [`crate::microfacet`] (Walter et al. 2007) and
//! every crossing samples it ([`Interface::sample`](crate::interface::Interface::sample)): the entry direction
//! is −ω_i refracted through a microfacet normal drawn from the visible
//! normals of ω_i (weight (1 − F(ω_i·m)) G1(ω_t, m), the exact f|cos|/pdf
//! with the transmission lobe forced); a photon reaching the top from
//! below reflects or leaves through a normal drawn for it, by the Fresnel
//! choice (weight G1 of the new direction); samples sent to the wrong side
//! of the macro-surface are lost (single scattering). The connection can no
//! longer use one ω₂₁: the radiance leaving towards ω_o is
//! L_o(x_o) = ∫ f_t(ω_o, ω′) L_in(x_o, ω′) |cos θ′| dω′, estimated by
//! drawing ω′ (refracting ω_o into the slab through a normal drawn from
//! ω_o's visible normals, forced transmission) independently of the path:
//! L_o ≈ W · L_in(x_o, ω′), W = (1 − F) G1(ω′, m)/n² (radiance transport).
//! For a fixed ω′ the smooth derivation above holds with T/n² replaced by
//! W and θ_t by the angle of ω₂₁ = −ω′, so every event of a path splats
//! w p(ω_s·ω₂₁) e^{−μ_t ℓ} W / (A_o cos θ₂₁) with ℓ = |z_s|/cos θ₂₁ for the
//! ω′ the path drew at its launch. (One ω′ per path, not per event: the
//! sum over events stays unbiased, paths stay independent so the errors
//! from path and batch statistics stay right, and the sampling — a visible
//! normal, a refraction — is done once instead of at every event: 6× the
//! events/s for TR α 0.0084, 12× for Beckmann, measured with `lucent bench
//! surface`; a rough top then runs at about 0.65× the smooth one's speed.)
//! The direction is drawn from the surface alone, never from the photon, so
//! the split stays exact; as α → 0 it becomes the smooth connection. In a
//! thin slab (μ_t d < 40; every image term crosses the slab at least once)
//! the image terms follow a chain of segments traced backwards from the
//! exit — up along ω₂₁, before it the bottom's mirror (F), before that a
//! reflection at the rough top drawn for radiance leaving downwards
//! (weight F G1), and so on — and an event connecting into a segment of
//! direction v splats w p(ω_s·v) e^{−μ_t L} c / (A_o |v_z|), L its length
//! to the exit along the chain and c the chain's weight so far (|v_z| is
//! the Jacobian of the slanted segment, as cos θ_t above; the chain is
//! independent of the event, so the change of variables holds per chain).
//! Light that reaches the rough top from below *without having scattered*
//! (entered, crossed the slab, reflected at the bottom; the paths that have
//! no event to connect from, and through a smooth top leave in one
//! specular direction only) is connected at the top itself: a photon of
//! weight w arriving along d adds w f_t(ω_o, −d)/A_o (radiance transport)
//! to the pixel of its hit point; in an optically thin slab near the
//! mirror direction that is most of the slice. The surface's own
//! reflection lobe at the entry is not part of the slice (reported as
//! `specular_reflectance`, its directional albedo, as the smooth F).
//! The ring needs a fixed exit polar angle and is not used with a rough
//! top; in a thick slab (μ_t d ≥ 40) the lobe connection (below, "Through
//! a rough top") takes the path's ω′ as its ω₂₁ and is the default.
//! Tested (`render/tests/slab_rough.rs`): α = 10⁻⁴ against the smooth
//! slice pixel by pixel, against brute-force exit binning at α = 0.05 and
//! 0.3 (thick and thin), reciprocity, and the lane kernel against the
//! scalar one.
//!
//! **Ring connection** ([`Estimator::Ring`], the default where it
//! applies: θ_i or θ_o is 0 and the slab is thick). Under normal incidence
//! on the launch side the slab is symmetric about the normal, so every
//! direction on the ring of the exit polar angle is a valid connection; the
//! derivation is with its code, `slab/ring.rs`.
//!
//! **Lobe connection** ([`Estimator::Lobe`], the default where the ring
//! does not apply and the slab is thick): the fixed-direction connection
//! combined by multiple importance sampling with chains drawn backwards
//! from ω₂₁ through the phase function's lobe; derivation in `slab/lobe.rs`.
//!
//! **Fold** ([`RunOptions::fold`]). With both azimuths 0° or 180°, a
//! mirror-symmetric beam and a top surface symmetric about the plane of
//! incidence (smooth, an isotropic distribution, or a measured normal set
//! equal to its mirror image — a measured surface generally is not) the
//! slice is symmetric about the plane of incidence; each batch's image is averaged with its mirror image before
//! the batch statistics, so the reported errors include the correlation of
//! the two halves.
//!
//! **Per-pixel errors** ([`PixelErrors`]): the median and 90th percentile of
//! σ_i/f_i over the pixels above 1 % of the maximum, after every round and
//! as a stop rule ([`Stop::pixel_rel_error`]).
//!
//! **Stop rule** ([`Stop`], checked after every round): its samples are
//! light paths; [`simulate`] honours all four conditions (the error
//! targets once two rounds are in), [`simulate_coupled`] a path count and
//! a time budget and refuses the error targets
//! ([`StopError::Unsupported`]); [`simulate_batches`] runs a given range
//! of batches (one shard) and takes no stop rule.
//!
//! **Brute force** ([`Estimator::BruteForce`], for testing): photons that
//! leave through the top within a cone of half-angle δ around ω_o add
//! w / (A_o cos θ_e Ω_δ) to the pixel of their exit point, Ω_δ = 2π(1 − cos δ).
//! It converges to the same slice as δ → 0 and shares no code with the
//! connection except the random walk itself.
//!
//! # Errors and determinism
//!
//! Paths are traced in batches of [`RunOptions::batch_paths`]; a round of
//! 32 batches runs in parallel (rayon) and is reduced in batch order, and
//! path k draws from the random stream (seed, k), so a result depends on the
//! seed and the stop rule, not on the thread count. The standard error of
//! the slice sum comes from the per-path totals; per-pixel errors from batch
//! means.
//!
//! # Speed
//!
//! On a CPU with AVX2 and FMA the connection estimators trace four paths at
//! a time, one per vector lane (module `lanes`, reported as
//! [`Slice::kernel`]): the flight, the scattering angles, the turn and the
//! fixed-direction connection's geometry, phase function and transmittance
//! of four events are one set of vector instructions; the ring's and the
//! lobe's connections run per lane on that vector walk (each lane with its
//! own path's ω₂₁ and C through a rough top), the lobe's chain links four
//! at a time. Each lane draws the same random
//! numbers for its path as the scalar kernel, so both give the same slice to
//! rounding (tested), whichever the CPU.
//!
//! ```
//! use lucent_render::slab::*;
//! use lucent_render::phase::Phase;
//! let slab = Slab::new(1e-3, Medium::new(2000.0, 10.0, Phase::henyey_greenstein(0.5).unwrap(), 1.4).unwrap()).unwrap();
//! let setup = Setup::new(slab, Beam::gaussian(200e-6).unwrap(), Sensor::new(31, 0.1e-3).unwrap(),
//!     Directions::from_degrees(45.0, 0.0, 0.0, 180.0).unwrap());
//! let slice = simulate(&setup, &RunOptions { stop: Stop::samples(20_000), ..RunOptions::default() }, |_| {}).unwrap();
//! assert!(slice.sum > 0.0 && slice.sum_std_error < 0.1 * slice.sum);
//! ```
//!
//! # Where things are
//!
//! - here: the entry points [`simulate`], [`simulate_cancellable`] and
//!   [`simulate_batches`] (rounds of batches, the stop rule);
//! - `setup.rs`, `beam.rs`, `error.rs`: what is simulated ([`Slab`],
//!   [`Sensor`], [`Directions`], [`Setup`]; [`Beam`], [`BeamMap`],
//!   [`Footprint`]) and the input errors ([`SlabError`]);
//! - `options.rs`: how ([`Stop`], [`Estimator`], [`RunOptions`],
//!   [`Progress`]);
//! - `kernel.rs`: the path walk and its batches; `boundary.rs`: the
//!   boundary crossings and a path's exit; `lanes.rs`: the walk four paths
//!   at a time;
//! - `connection.rs`, `ring.rs`, `lobe.rs`: the connections of the
//!   fixed direction, the ring and the lobe (with their derivations);
//! - `tally.rs`: the tallies and the slice with its errors ([`SliceSums`],
//!   [`Slice`], [`PixelErrors`]); `coupled.rs`: differences by common random
//!   numbers ([`simulate_coupled`], [`SliceDifference`]);
//! - `tests.rs`: the tests of the private parts.

mod beam;
mod boundary;
mod connection;
mod coupled;
mod error;
mod kernel;
#[cfg(target_arch = "x86_64")]
mod lanes;
mod lobe;
mod options;
mod ring;
mod setup;
mod tally;
#[cfg(test)]
mod tests;

pub use crate::medium::{valid_coefficients, Medium, MediumError, MU_T_MAX_PER_M};
pub use crate::stop::{Condition, NotSplittable, Stop, StopError};
pub use beam::{fwhm_to_sigma, Beam, BeamMap, Footprint};
pub use coupled::{simulate_coupled, SliceDifference};
pub use error::SlabError;
pub use lobe::{LOBE_REUSE, LOBE_VERTICES, MAX_LOBE_VERTICES};
pub use options::{Estimator, Progress, RunOptions};
pub use ring::RING_SPLATS;
pub use setup::{direction, Directions, Sensor, Setup, Slab};
pub use tally::{PixelErrors, Slice, SliceSums, PIXEL_MASK_FRACTION};

use crate::stop::Standing;
use kernel::Kernel;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;
use tally::pixel_estimates;

/// Batches per round (fixed, so results do not depend on the thread count).
const ROUND_BATCHES: u64 = 32;

/// Simulates the slice of `setup`, calling `progress` after every round.
pub fn simulate(setup: &Setup, options: &RunOptions, progress: impl FnMut(&Progress)) -> Result<Slice, SlabError> {
    simulate_cancellable(setup, options, progress, &AtomicBool::new(false))
}

/// [`simulate`] that also stops at the end of the round under way when
/// `cancel` becomes true (a Ctrl-C handler sets it): the slice returned is
/// then a valid estimate from the paths finished so far, with its errors.
pub fn simulate_cancellable(
    setup: &Setup,
    options: &RunOptions,
    mut progress: impl FnMut(&Progress),
    cancel: &AtomicBool,
) -> Result<Slice, SlabError> {
    let stop = options.stop;
    stop.check()?;
    let batch_paths = options.batch_paths.max(1);
    let kernel = Kernel::new(setup, options.estimator)?;
    let fold = options.fold && setup.mirror_symmetric();
    let mut sums = SliceSums::empty(&kernel, setup, fold);
    let mut batches = 0u64;
    let mut pool: Vec<Vec<f64>> = Vec::new();
    let start = Instant::now();
    let rel_err = |paths: u64, s: f64, sq: f64| {
        let n = paths as f64;
        let mean = s / n;
        let var = (sq / n - mean * mean).max(0.0) / (n - 1.0).max(1.0);
        if mean > 0.0 {
            var.sqrt() / mean
        } else {
            f64::INFINITY
        }
    };
    loop {
        let mut round = ROUND_BATCHES;
        if let Some(max) = stop.samples {
            let left = max.saturating_sub(batches * batch_paths).div_ceil(batch_paths);
            round = round.min(left);
        }
        if round == 0 {
            break;
        }
        let firsts: Vec<(u64, u64)> = (0..round)
            .map(|k| {
                let first = (batches + k) * batch_paths;
                let count = match stop.samples {
                    Some(max) => batch_paths.min(max - first),
                    None => batch_paths,
                };
                (first, count)
            })
            .collect();
        sums.add_round(&kernel, options.seed, &firsts, &mut pool);
        let (path_sum, path_sq, events) = (sums.path_sum, sums.path_sq, sums.events);
        batches += round;
        let paths = stop.samples.map_or(batches * batch_paths, |m| m.min(batches * batch_paths));
        let elapsed = start.elapsed().as_secs_f64();
        let e = rel_err(paths, path_sum, path_sq);
        let (v, se) = pixel_estimates(&sums.raw, &sums.sum_b, &sums.sq_b, paths, batches);
        let pixels = PixelErrors::of(&v, &se);
        progress(&Progress { paths, events, elapsed_s: elapsed, rel_error: e, pixels });
        // The error estimates are trusted after two rounds.
        let enough = batches >= 2 * ROUND_BATCHES;
        let standing = Standing {
            samples: Some(paths),
            elapsed_s: elapsed,
            rel_error: enough.then_some(e),
            pixel_rel_error: enough.then_some(pixels.median),
        };
        if stop.met(&standing).is_some() || cancel.load(Ordering::Relaxed) {
            break;
        }
    }
    sums.batches = batches;
    sums.paths = stop.samples.map_or(batches * batch_paths, |m| m.min(batches * batch_paths));
    sums.wall_s = start.elapsed().as_secs_f64();
    Ok(sums.slice())
}

/// Batches `batches` of the run [`simulate`] makes with
/// `options.stop = Stop::samples(total_paths)` (batch b holds paths
/// b·batch_paths … up to `total_paths`, each path drawing from its own
/// stream), as tallies: one shard of that run. The shards of a partition of
/// its batches add up to its tallies ([`SliceSums::add`], in batch order).
/// Stops at the end of the round under way when `cancel` becomes true.
pub fn simulate_batches(
    setup: &Setup,
    options: &RunOptions,
    batches: std::ops::Range<u64>,
    total_paths: u64,
    cancel: &AtomicBool,
) -> Result<SliceSums, SlabError> {
    let batch_paths = options.batch_paths.max(1);
    let kernel = Kernel::new(setup, options.estimator)?;
    let fold = options.fold && setup.mirror_symmetric();
    let mut sums = SliceSums::empty(&kernel, setup, fold);
    let mut pool: Vec<Vec<f64>> = Vec::new();
    let start = Instant::now();
    let mut b = batches.start;
    let end = batches.end.min(total_paths.div_ceil(batch_paths));
    while b < end && !cancel.load(Ordering::Relaxed) {
        let round: Vec<(u64, u64)> = (b..end.min(b + ROUND_BATCHES))
            .map(|k| (k * batch_paths, batch_paths.min(total_paths - k * batch_paths)))
            .collect();
        sums.add_round(&kernel, options.seed, &round, &mut pool);
        sums.batches += round.len() as u64;
        sums.paths += round.iter().map(|r| r.1).sum::<u64>();
        b += round.len() as u64;
    }
    sums.wall_s = start.elapsed().as_secs_f64();
    Ok(sums)
}
