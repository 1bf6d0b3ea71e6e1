//! The simulator's tests that need its private parts (the kernels, the
//! boundary choice, the ring's sampler); the public API's are in
//! `render/tests/slab.rs` and `render/tests/slab_rough.rs`.

use super::boundary::Crossing;
use super::kernel::{Kernel, Strategy};
use super::ring::Ring;
use super::*;
use crate::interface::Interface;
use crate::microfacet::{Distribution, Microsurface};
use crate::phase::Phase;
use crate::rng::Rng;
use std::f64::consts::PI;
use std::sync::atomic::AtomicBool;

/// Mean and standard error of the per-path totals of `paths` paths.
fn slice_sum(kernel: &Kernel, seed: u64, paths: u64) -> (f64, f64) {
    let b = kernel.batch(seed, 0, paths, Vec::new());
    let n = paths as f64;
    let mean = b.path_sum / n;
    (mean, ((b.path_sq / n - mean * mean) / (n - 1.0)).sqrt())
}

/// Common random numbers: the coupled difference of two slabs whose μ_s
/// differ by 4 % agrees with the difference of two independent long
/// runs; its stated standard error matches the spread over seeds; and
/// it is several times smaller than the independent runs' at the same
/// paths (what the coupling is for).
#[test]
fn coupled_differences_are_unbiased_with_honest_errors() {
    let setup = |mu_s: f64| {
        let medium =
            Medium::new(mu_s, 30.0, Phase::henyey_greenstein(0.8).expect("valid g"), 1.5).expect("valid medium");
        Setup::new(
            Slab::new(2.0e-3, medium).expect("valid slab"),
            Beam::gaussian(300e-6).expect("valid beam"),
            Sensor::new(21, 0.2e-3).expect("valid sensor"),
            Directions::from_degrees(45.0, 0.0, 0.0, 180.0).expect("valid directions"),
        )
    };
    let (nominal, a, b) = (setup(5.0e3), setup(5.1e3), setup(4.9e3));
    let paths = 20_000;
    let options = |seed: u64, paths: u64| RunOptions {
        stop: Stop::samples(paths),
        seed,
        batch_paths: 250,
        estimator: Estimator::Connection,
        fold: true,
    };
    let never = AtomicBool::new(false);
    let pairs = [(a.clone(), b.clone())];
    let runs: Vec<SliceDifference> = (0..8)
        .map(|seed| {
            let (slice, mut d) =
                simulate_coupled(&nominal, &pairs, &options(10 + seed, paths), |_| {}, &never).unwrap();
            assert_eq!(slice.paths, paths);
            d.remove(0)
        })
        .collect();
    let sums: Vec<f64> = runs.iter().map(|d| d.sum).collect();
    let mean = sums.iter().sum::<f64>() / 8.0;
    let spread = (sums.iter().map(|s| (s - mean).powi(2)).sum::<f64>() / 7.0).sqrt();
    let stated = (runs.iter().map(|d| d.sum_std_error.powi(2)).sum::<f64>() / 8.0).sqrt();
    // 8 seeds: the sample sd lies within 0.45 … 1.6 of the true one with probability > 0.99.
    assert!(spread > 0.45 * stated && spread < 1.6 * stated, "spread over seeds {spread} vs stated {stated}");
    // The same per pixel, pooled over the bright pixels.
    let bright: Vec<usize> = (0..runs[0].values.len()).filter(|&i| runs[0].std_error[i] > 0.0).collect();
    let mut ratio = 0.0;
    for &i in &bright {
        let m = runs.iter().map(|d| d.values[i]).sum::<f64>() / 8.0;
        let var = runs.iter().map(|d| (d.values[i] - m).powi(2)).sum::<f64>() / 7.0;
        let stated = runs.iter().map(|d| d.std_error[i].powi(2)).sum::<f64>() / 8.0;
        ratio += var / stated;
    }
    ratio /= bright.len() as f64;
    assert!(ratio > 0.7 && ratio < 1.4, "per-pixel variance over seeds / stated variance: {ratio}");
    // Independent long runs of a and b (their own seeds).
    let long = 8 * paths;
    let sa = simulate(&a, &options(101, long), |_| {}).unwrap();
    let sb = simulate(&b, &options(202, long), |_| {}).unwrap();
    let independent = sa.sum - sb.sum;
    let se_independent = (sa.sum_std_error.powi(2) + sb.sum_std_error.powi(2)).sqrt();
    let se_coupled = stated / 8f64.sqrt();
    let z = (mean - independent) / (se_coupled.powi(2) + se_independent.powi(2)).sqrt();
    assert!(z.abs() < 3.5, "coupled {mean} ± {se_coupled} vs independent {independent} ± {se_independent} (z {z})");
    // At equal paths the independent difference's error is ×√8 larger than the long runs'.
    let se_independent_equal = se_independent * 8f64.sqrt();
    assert!(
        stated < 0.5 * se_independent_equal,
        "coupled s.e. {stated} vs independent {se_independent_equal} at {paths} paths"
    );
}

#[test]
fn connection_roulette_is_unbiased() {
    // Thick, forward-scattering slab (μ_t d ≈ 60): most events lie
    // deeper than the roulette depth. Each run has its own seed, so the
    // three estimates are independent.
    let medium = Medium::new(1.0e4, 20.0, Phase::henyey_greenstein(0.9).expect("valid g"), 1.5).expect("valid medium");
    let setup = Setup::new(
        Slab::new(6.0e-3, medium).expect("valid slab"),
        Beam::gaussian(200e-6).expect("valid beam"),
        Sensor::new(65, 0.2e-3).expect("valid sensor"),
        Directions::from_degrees(45.0, 0.0, 0.0, 180.0).expect("valid directions"),
    );
    let mut kernel = Kernel::new(&setup, Estimator::Connection).expect("valid kernel");
    assert!(!kernel.image_terms);
    let (default, se_default) = slice_sum(&kernel, 3, 20_000);
    kernel.roulette_depth = f64::INFINITY;
    let (without, se_without) = slice_sum(&kernel, 4, 20_000);
    // Roulette from one optical depth on: most of the slice goes through
    // it, so a wrong weight would show.
    kernel.roulette_depth = 1.0;
    kernel.roulette_transmittance = (-1.0f64).exp();
    let (shallow, se_shallow) = slice_sum(&kernel, 5, 20_000);
    for (name, with, se_with) in [("default", default, se_default), ("τ_r = 1", shallow, se_shallow)] {
        let z = (with - without) / (se_with * se_with + se_without * se_without).sqrt();
        assert!(z.abs() < 4.0, "{name}: with roulette {with} ± {se_with}, without {without} ± {se_without} (z = {z})");
    }
    let se_with = se_default;
    assert!(se_with < 1.2 * se_without, "standard error {se_with} vs {se_without}");
}

/// The lane kernel against the scalar one on the same paths: the same
/// random numbers and decisions, so every pixel, the path tallies and
/// the event count agree to rounding. Covers the thick slab (vector
/// connection, roulette) and the thin one (image terms), HG with g ≥ 10⁻³
/// (vector sampling) and g = 0 and a table (per-lane sampling), and a
/// measured beam map.
#[cfg(target_arch = "x86_64")]
#[test]
fn lanes_trace_the_scalar_paths() {
    if crate::simd::lanes_unavailable() {
        return;
    }
    let table = table_phase();
    let hg = |g| Phase::henyey_greenstein(g).expect("valid g");
    let map = Beam::Map(BeamMap::new(3, 2, 0.1e-3, vec![0.0, 1.0, 2.0, 4.0, 0.5, 0.0]).expect("valid map"));
    let cases = [
        ("thick PDMS-like, HG", Medium::new(1.47e4, 9.6, hg(0.974), 1.589), 6.35e-3, 45.0, Beam::gaussian(200e-6)),
        ("thin, HG, image terms", Medium::new(2000.0, 10.0, hg(0.5), 1.4), 1e-3, 30.0, Beam::gaussian(300e-6)),
        ("thin, g = 0, beam map", Medium::new(3000.0, 50.0, hg(0.0), 1.3), 0.5e-3, 0.0, Ok(map)),
        ("thick, table", Medium::new(1.0e4, 30.0, table, 1.5), 5e-3, 60.0, Beam::gaussian(100e-6)),
        ("thick, g < 0", Medium::new(8000.0, 5.0, hg(-0.3), 1.45), 4e-3, 20.0, Beam::gaussian(100e-6)),
    ];
    for (name, medium, d, theta_i, beam) in cases {
        let setup = Setup::new(
            Slab::new(d, medium.expect("valid medium")).expect("valid slab"),
            beam.expect("valid beam"),
            Sensor::new(63, 0.1e-3).expect("valid sensor"),
            Directions::from_degrees(theta_i, 0.0, 15.0, 180.0).expect("valid directions"),
        );
        let kernel = Kernel::new(&setup, Estimator::Connection).expect("valid kernel");
        assert!(kernel.lanes, "{name}");
        compare_kernels(name, &kernel);
    }
    // A rough top: sampled entry, crossings and connections, thick
    // (straight-up term) and thin (the chain of image terms), analytic
    // distributions and a measured normal set.
    let measured: Vec<[f64; 3]> = (0..400)
        .map(|k| {
            let (a, b) = ((k % 20) as f64 / 20.0 - 0.5, (k / 20) as f64 / 20.0 - 0.5);
            let v = [0.3 * a, 0.2 * b + 0.05 * a, 1.0];
            let l = (v[0] * v[0] + v[1] * v[1] + 1.0f64).sqrt();
            [v[0] / l, v[1] / l, v[2] / l]
        })
        .collect();
    let rough_cases = [
        ("rough thick, TR 0.3", Microsurface::Analytic(Distribution::TrowbridgeReitz { alpha: 0.3 }), 6e-3),
        ("rough thin, Beckmann 0.1", Microsurface::Analytic(Distribution::Beckmann { alpha: 0.1 }), 1e-3),
        (
            "rough thin, measured",
            Microsurface::Measured(std::sync::Arc::new(
                crate::microfacet::MeasuredNormals::new(&measured, None).expect("valid normals"),
            )),
            1e-3,
        ),
    ];
    for (name, surface, d) in rough_cases {
        let medium = Medium::new(4000.0, 10.0, hg(0.7), 1.5).expect("valid medium");
        let setup = Setup::new(
            Slab::new(d, medium).expect("valid slab").with_top(Interface::new(surface).expect("valid α")),
            Beam::gaussian(200e-6).expect("valid beam"),
            Sensor::new(63, 0.1e-3).expect("valid sensor"),
            Directions::from_degrees(45.0, 0.0, 0.0, 180.0).expect("valid directions"),
        );
        let kernel = Kernel::new(&setup, Estimator::Connection).expect("valid kernel");
        assert!(kernel.lanes && kernel.rough, "{name}");
        compare_kernels(name, &kernel);
    }
    // The ring connection: launched from the light (θ_i = 0) and from
    // the camera (θ_o = 0), HG and a table.
    let ring_cases = [
        ("ring, reciprocal, HG", Phase::henyey_greenstein(0.9).expect("valid g"), 45.0, 0.0),
        ("ring, direct, table", table_phase(), 0.0, 30.0),
    ];
    for (name, phase, theta_i, theta_o) in ring_cases {
        let setup = Setup::new(
            Slab::new(6e-3, Medium::new(1.2e4, 10.0, phase, 1.5).expect("valid medium")).expect("valid slab"),
            Beam::gaussian(200e-6).expect("valid beam"),
            Sensor::new(63, 0.1e-3).expect("valid sensor"),
            Directions::from_degrees(theta_i, 0.0, theta_o, 180.0).expect("valid directions"),
        );
        let kernel = Kernel::new(&setup, Estimator::Ring).expect("valid kernel");
        assert!(kernel.lanes && matches!(kernel.strategy, Strategy::Ring(_)), "{name}");
        compare_kernels(name, &kernel);
    }
    // The lobe connection (45°/15° and out of plane): HG and a table,
    // chains of 4 and 16, drawn at every event, reused for 3 events and
    // for the whole path; a thick slab whose walk reflects at the
    // bottom (the MIS history restarts there).
    let lobe_cases = [
        ("lobe, HG, m 4", Phase::henyey_greenstein(0.9).expect("valid g"), 15.0, 180.0, 4, 1, 6e-3),
        ("lobe, table, m 16, reuse 3", table_phase(), 15.0, 180.0, 16, 3, 6e-3),
        (
            "lobe, HG, m 16, one chain a path",
            Phase::henyey_greenstein(0.8).expect("valid g"),
            40.0,
            100.0,
            16,
            usize::MAX,
            6e-3,
        ),
        ("lobe, table, m 2, reflecting bottom", table_phase(), 15.0, 180.0, 2, 2, 3.5e-3),
    ];
    for (name, phase, theta_o, phi_o, m, reuse, d) in lobe_cases {
        let setup = Setup::new(
            Slab::new(d, Medium::new(1.2e4, 10.0, phase, 1.5).expect("valid medium")).expect("valid slab"),
            Beam::gaussian(200e-6).expect("valid beam"),
            Sensor::new(63, 0.1e-3).expect("valid sensor"),
            Directions::from_degrees(45.0, 0.0, theta_o, phi_o).expect("valid directions"),
        );
        let mut kernel = Kernel::new(&setup, Estimator::Lobe { vertices: m }).expect("valid kernel");
        kernel.strategy = Strategy::Lobe { vertices: m, reuse };
        assert!(kernel.lanes, "{name}");
        compare_kernels(name, &kernel);
    }
    // The lobe connection through a rough top (thick): per-lane ω₂₁ and
    // C from each path's sampled exit, lost exits; an analytic
    // distribution at large α (many lost and grazing exits) and a
    // measured normal set, HG and a table.
    let rough_lobe_cases = [
        (
            "rough lobe, TR 0.8, HG, m 4",
            Microsurface::Analytic(Distribution::TrowbridgeReitz { alpha: 0.8 }),
            hg(0.9),
            4,
        ),
        (
            "rough lobe, measured, table, m 16",
            Microsurface::Measured(std::sync::Arc::new(
                crate::microfacet::MeasuredNormals::new(&measured, None).expect("valid normals"),
            )),
            table_phase(),
            16,
        ),
    ];
    for (name, surface, phase, m) in rough_lobe_cases {
        let setup = Setup::new(
            Slab::new(6e-3, Medium::new(1.2e4, 10.0, phase, 1.5).expect("valid medium"))
                .expect("valid slab")
                .with_top(Interface::new(surface).expect("valid α")),
            Beam::gaussian(200e-6).expect("valid beam"),
            Sensor::new(63, 0.1e-3).expect("valid sensor"),
            Directions::from_degrees(45.0, 0.0, 15.0, 180.0).expect("valid directions"),
        );
        let kernel = Kernel::new(&setup, Estimator::Lobe { vertices: m }).expect("valid kernel");
        assert!(
            kernel.lanes && kernel.rough && kernel.strategy.estimator() == Estimator::Lobe { vertices: m },
            "{name}"
        );
        compare_kernels(name, &kernel);
    }
}

/// A forward-peaked tabulated phase function.
#[cfg(target_arch = "x86_64")]
fn table_phase() -> Phase {
    Phase::Tabulated(
        crate::phase::PhaseTable::from_theta_samples(
            &(0..400).map(|k| (-(k as f64) / 40.0).exp() + 0.05).collect::<Vec<_>>(),
        )
        .expect("valid table"),
    )
}

/// Asserts that the lane and scalar kernels trace the same paths.
#[cfg(target_arch = "x86_64")]
fn compare_kernels(name: &str, kernel: &Kernel) {
    {
        let paths = 3001; // not a multiple of four: lanes retire at the end
        let scalar = kernel.batch_scalar(9, 100, paths, Vec::new());
        // SAFETY: `kernel.lanes` is set, so the CPU has AVX2 and FMA.
        assert!(kernel.lanes);
        let lanes = unsafe { kernel.batch_lanes(9, 100, paths, Vec::new()) };
        assert_eq!(lanes.events, scalar.events, "{name}: events");
        let close = |a: f64, b: f64, scale: f64| (a - b).abs() <= 1e-9 * scale;
        assert!(scalar.path_sum > 0.0, "{name}: empty slice");
        assert!(
            close(lanes.path_sum, scalar.path_sum, scalar.path_sum),
            "{name}: {} vs {}",
            lanes.path_sum,
            scalar.path_sum
        );
        assert!(close(lanes.path_sq, scalar.path_sq, scalar.path_sq), "{name}: squares");
        assert!(
            close(lanes.reflected, scalar.reflected, paths as f64),
            "{name}: {} vs {}",
            lanes.reflected,
            scalar.reflected
        );
        assert!(close(lanes.transmitted, scalar.transmitted, paths as f64), "{name}: transmitted");
        let peak = scalar.image.iter().fold(0.0f64, |m, v| m.max(*v));
        for (k, (a, b)) in lanes.image.iter().zip(&scalar.image).enumerate() {
            assert!(close(*a, *b, peak), "{name}: pixel {k}: {a} vs {b}");
        }
    }
}

/// χ² p-value of `observed` counts against `expected` (the shared
/// harness: bins expecting fewer than 5 pooled).
fn chi2_p(observed: &[f64], expected: &[f64]) -> f64 {
    lucent_testkit::chi2::goodness_of_fit(observed, expected).p_value
}

/// The ring's azimuth sampler draws ψ with the density it reports (χ²
/// over 64 bins, for photons along, across and against the ring).
#[test]
fn ring_azimuth_sampler_matches_its_density() {
    let ring = Ring::new(&Phase::henyey_greenstein(0.95).expect("valid g"), 0.9, 1.0, (1.0, 0.0));
    let n = 200_000;
    for c_s in [0.9, 0.3, -0.7] {
        let mut rng = Rng::new(5, (c_s * 100.0) as u64);
        let bins = 64;
        let mut observed = vec![0.0; bins];
        for _ in 0..n {
            let (psi, density) = ring.sample_psi(c_s, rng.next_f64());
            assert!((density - ring.density_at(c_s, psi)).abs() <= 1e-12 * density, "c_s {c_s}: ψ {psi}");
            observed[((psi / PI * bins as f64) as usize).min(bins - 1)] += 1.0;
        }
        // Expected: ∫ density over each bin (midpoint rule on 32 points).
        let expected: Vec<f64> = (0..bins)
            .map(|b| {
                let w = PI / bins as f64;
                (0..32).map(|k| ring.density_at(c_s, (b as f64 + (k as f64 + 0.5) / 32.0) * w)).sum::<f64>() * w / 32.0
                    * n as f64
            })
            .collect();
        let p = chi2_p(&observed, &expected);
        assert!(p > 1e-3, "c_s {c_s}: χ² p = {p}");
    }
}

/// The Fresnel choice at a boundary reflects with probability F: χ²
/// (one degree of freedom) at five angles, inside the medium (n = 1.5,
/// so the last two angles are beyond the critical angle and always
/// reflect).
#[test]
fn fresnel_choice_reflects_with_probability_f() {
    let setup = Setup::new(
        Slab::new(1e-3, Medium::new(1000.0, 0.0, Phase::henyey_greenstein(0.0).expect("g = 0"), 1.5).expect("ok"))
            .expect("valid slab"),
        Beam::gaussian(100e-6).expect("valid beam"),
        Sensor::new(8, 1e-4).expect("valid sensor"),
        Directions::from_degrees(0.0, 0.0, 0.0, 0.0).expect("valid directions"),
    );
    let kernel = Kernel::new(&setup, Estimator::Connection).expect("valid kernel");
    let n = 100_000;
    for (k, theta_deg) in [0.0f64, 20.0, 40.0, 45.0, 70.0].into_iter().enumerate() {
        let (st, ct) = theta_deg.to_radians().sin_cos();
        let f = crate::fresnel::reflectance(ct, 1.0 / 1.5);
        let mut rng = Rng::new(17, k as u64);
        let mut reflected = 0.0;
        for _ in 0..n {
            let (mut p, mut dir) = ([0.0, 0.0, -0.5e-3], [st, 0.0, ct]);
            let mut w = 1.0;
            if let Crossing::Reflected = kernel.cross(&mut p, &mut dir, &mut w, 0.5e-3, &mut rng) {
                assert!(dir[2] < 0.0 && p[2] == 0.0);
                reflected += 1.0;
            }
        }
        if f >= 1.0 {
            assert_eq!(reflected, n as f64, "θ {theta_deg}°: total internal reflection");
            continue;
        }
        let p = chi2_p(&[reflected, n as f64 - reflected], &[f * n as f64, (1.0 - f) * n as f64]);
        assert!(p > 1e-3, "θ {theta_deg}°: reflected {reflected} of {n}, F = {f} (χ² p = {p})");
    }
}
