//! The slice's first-order band from a recipe's uncertain inputs
//! (`lucent bssrdf --uncertainty`) against brute-force sampling of the
//! inputs, and the command's outputs.

use lucent::optics::bulk;
use lucent::optics::recipe::{Overrides, Recipe};
use lucent::optics::uncertainty::{design, first_order, standard_deviation};
use lucent_render::phase::{Phase, PhaseTable};
use lucent_render::slab::{
    simulate, simulate_coupled, Beam, Directions, Estimator, Medium, RunOptions, Sensor, Setup, Slab, Stop,
};
use std::sync::atomic::AtomicBool;

/// IOL1068-09 with its weight percentage ±5 % (1 σ).
fn uncertain_recipe() -> Recipe {
    let text = include_str!("../fixtures/samples/IOL1068-09.toml")
        .replace("weight_percent = 0.65", "weight_percent = { value = 0.65, sd = 0.0325 }");
    Recipe::parse(&text, std::path::Path::new("fixtures/samples/u.toml"), Overrides::default()).unwrap()
}

/// The plaque of `recipe` at 550 nm (6.35 mm, Mie phase table), a 31-pixel
/// crop of 0.2 mm pixels, 45° → 0°.
fn setup(recipe: &Recipe) -> Setup {
    let s = bulk::at_wavelength(recipe, 550.0, &bulk::Options::default()).unwrap();
    let phase = Phase::Tabulated(PhaseTable::from_theta_samples(&s.phase).unwrap());
    let medium = Medium::new(s.mu_s_per_m, s.mu_a_per_m, phase, s.n_bulk).unwrap();
    Setup::new(
        Slab::new(recipe.thickness_m, medium).unwrap(),
        Beam::gaussian(200e-6).unwrap(),
        Sensor::new(31, 0.2e-3).unwrap(),
        Directions::from_degrees(45.0, 0.0, 0.0, 180.0).unwrap(),
    )
}

fn options(setup: &Setup, seed: u64, paths: u64) -> RunOptions {
    RunOptions { stop: Stop::paths(paths), seed, batch_paths: 250, estimator: Estimator::best_for(setup), fold: true }
}

/// First order against brute force on the slice sum of the plaque (the
/// lobe connection, as `lucent bssrdf` uses it there). Brute force: 10
/// Latin-hypercube draws of the weight percentage, each slice traced with
/// one seed for all draws (so that their Monte Carlo noise is mostly
/// shared). First order: the central difference at ±1 σ, another seed.
///
/// 1. The band's stated Monte Carlo error is below 10 % of the band.
/// 2. The sensitivity agrees with the least-squares slope of the
///    brute-force sums on the input within their stated errors (|z| < 3.5):
///    a sensitivity wrong by more than its error fails here.
/// 3. On the draws themselves, the spread the first-order model predicts is
///    within 10 % of the spread the draws show (the draws' own sampling
///    noise cancels in this comparison).
#[test]
fn first_order_band_of_the_slice_sum_matches_brute_force_sampling() {
    let recipe = uncertain_recipe();
    assert_eq!(recipe.uncertain.len(), 1);
    let input = &recipe.uncertain[0];
    let (x0, sd) = (input.nominal, standard_deviation(&input.distribution));
    let at = |v: f64| setup(&recipe.with_input(input.target, v).unwrap());
    let never = AtomicBool::new(false);
    let nominal = setup(&recipe);
    let pairs = [(at(x0 + sd), at(x0 - sd))];
    let (slice, diffs) = simulate_coupled(&nominal, &pairs, &options(&nominal, 7, 32_000), |_| {}, &never).unwrap();
    let d = &diffs[0];
    let fo = first_order(&[vec![d.sum]], &[vec![d.sum_std_error]]);
    assert!(
        fo.sd_std_error[0] < 0.1 * fo.sd[0],
        "band {} with Monte Carlo error {} (sum {} ± {})",
        fo.sd[0],
        fo.sd_std_error[0],
        slice.sum,
        slice.sum_std_error
    );
    let (slope, slope_se) = (d.sum / (2.0 * sd), d.sum_std_error / (2.0 * sd));

    // Brute force.
    let draws: Vec<f64> = design(&recipe, 10, 3).unwrap().into_iter().map(|x| x[0]).collect();
    let sums: Vec<f64> = draws
        .iter()
        .map(|&x| {
            let s = at(x);
            simulate(&s, &options(&s, 11, 12_000), |_| {}).unwrap().sum
        })
        .collect();
    // Least squares f = a + b (x − x₀).
    let n = draws.len() as f64;
    let mx = draws.iter().sum::<f64>() / n;
    let my = sums.iter().sum::<f64>() / n;
    let sxx: f64 = draws.iter().map(|x| (x - mx).powi(2)).sum();
    let b = draws.iter().zip(&sums).map(|(x, y)| (x - mx) * (y - my)).sum::<f64>() / sxx;
    let residual = draws.iter().zip(&sums).map(|(x, y)| (y - my - b * (x - mx)).powi(2)).sum::<f64>() / (n - 2.0);
    let se_b = (residual / sxx).sqrt();
    let z = (b - slope) / (se_b * se_b + slope_se * slope_se).sqrt();
    assert!(z.abs() < 3.5, "first-order slope {slope} ± {slope_se} vs brute-force slope {b} ± {se_b} (z {z})");
    // The spread on the draws: observed vs the first-order model's.
    let sd_of = |v: &[f64]| {
        let m = v.iter().sum::<f64>() / v.len() as f64;
        (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
    };
    let linear: Vec<f64> = draws.iter().map(|x| slope * (x - x0)).collect();
    let (observed, predicted) = (sd_of(&sums), sd_of(&linear));
    assert!(
        (predicted - observed).abs() < 0.1 * observed,
        "spread of the slice sum over the draws {observed} vs first order {predicted} (band {} ± {}; slopes {slope} ± {slope_se}, brute force {b} ± {se_b})",
        fo.sd[0],
        fo.sd_std_error[0]
    );
}
