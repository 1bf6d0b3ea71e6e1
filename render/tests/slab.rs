//! Statistical tests of the slab BSSRDF simulator (docs/method.md#slab): explicit
//! connection against brute-force binning, total reflectance and
//! transmittance against adding–doubling (iadpython, committed reference),
//! reciprocity, the white furnace, determinism across thread counts, and bad
//! input; the ring connection against the fixed-direction one pixel by
//! pixel, its furnace, the reported standard errors against the spread over
//! seeds, the fold, and χ² tests of the direction and beam samplers; the
//! lobe connection against the fixed-direction one pixel by pixel, brute
//! force, its furnace and its standard errors. Fixed
//! seeds; tolerances are multiples of the reported standard errors, which
//! are themselves tested.

use lucent_render::interface::Interface;
use lucent_render::phase::Phase;
use lucent_render::slab::*;

fn hg(g: f64) -> Phase {
    Phase::henyey_greenstein(g).unwrap()
}

#[allow(clippy::too_many_arguments)] // one argument per physical input of the slab
fn setup(mu_s: f64, mu_a: f64, g: f64, n: f64, d_m: f64, pixels: usize, pixel_m: f64, dirs: Directions) -> Setup {
    let slab = Slab::new(d_m, Medium::new(mu_s, mu_a, hg(g), n).unwrap()).unwrap();
    Setup::new(slab, Beam::gaussian(200e-6).unwrap(), Sensor::new(pixels, pixel_m).unwrap(), dirs)
}

fn run(s: &Setup, paths: u64, seed: u64, estimator: Estimator) -> Slice {
    let opts = RunOptions { stop: Stop::samples(paths), seed, batch_paths: 256, estimator, fold: false };
    simulate(s, &opts, |_| {}).unwrap()
}

fn lab_45_0() -> Directions {
    Directions::from_degrees(45.0, 0.0, 0.0, 180.0).unwrap()
}

fn lab_45_15() -> Directions {
    Directions::from_degrees(45.0, 0.0, 15.0, 180.0).unwrap()
}

/// Asserts |a − b| ≤ k·σ_combined + bias·|b|.
fn agree(name: &str, a: f64, sa: f64, b: f64, sb: f64, k: f64, bias: f64) {
    let s = (sa * sa + sb * sb).sqrt();
    let diff = (a - b).abs();
    assert!(
        diff <= k * s + bias * b.abs(),
        "{name}: {a:.6e} ± {sa:.2e} vs {b:.6e} ± {sb:.2e} (diff {diff:.2e} = {:.1}σ)",
        diff / s
    );
}

#[test]
fn connection_agrees_with_brute_force_thin_medium() {
    // Thin, moderately scattering: τ = 2.2, g = 0.5, n = 1.4; 45°/0°.
    let s = setup(2000.0, 200.0, 0.5, 1.4, 1e-3, 24, 0.25e-3, lab_45_0());
    let conn = run(&s, 200_000, 7, Estimator::Connection);
    let brute = run(&s, 3_000_000, 8, Estimator::BruteForce { cone_deg: 6.0 });
    agree("thin slab sum", conn.sum, conn.sum_std_error, brute.sum, brute.sum_std_error, 3.0, 0.005);
    // Also the centre rows, where the slice is brightest.
    let rows = |sl: &Slice| -> (f64, f64) {
        let n = sl.pixels;
        let (mut v, mut e2) = (0.0, 0.0);
        for r in n / 2 - 2..n / 2 + 2 {
            for c in 0..n {
                v += sl.values[r * n + c];
                e2 += sl.std_error[r * n + c].powi(2);
            }
        }
        (v, e2.sqrt())
    };
    let (a, sa) = rows(&conn);
    let (b, sb) = rows(&brute);
    agree("thin slab centre rows", a, sa, b, sb, 3.5, 0.005);
}

#[test]
fn connection_agrees_with_brute_force_sample_like_medium() {
    // Like the samples: μs ≈ 1.5e4 /m, μa ≈ 10 /m, g ≈ 0.97, 6.35 mm.
    let s = setup(1.5e4, 10.0, 0.97, 1.589, 6.35e-3, 24, 1.0e-3, lab_45_0());
    let conn = run(&s, 20_000, 11, Estimator::Connection);
    let brute = run(&s, 250_000, 12, Estimator::BruteForce { cone_deg: 10.0 });
    agree("sample-like sum", conn.sum, conn.sum_std_error, brute.sum, brute.sum_std_error, 3.0, 0.01);
}

struct IadSlab {
    name: String,
    albedo: f64,
    tau: f64,
    g: f64,
    n: f64,
    ur1: f64,
    ut1: f64,
    specular: f64,
}

fn iad_slabs() -> Vec<IadSlab> {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/reference/iad_slabs.csv");
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let mut lines = text.lines().filter(|l| !l.starts_with('#') && !l.trim().is_empty());
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |k: &str| header.iter().position(|h| h.trim() == k).unwrap_or_else(|| panic!("column {k}"));
    let (ci, ca, ct, cg, cn, cr, cu, cs) = (
        col("name"),
        col("albedo"),
        col("optical_thickness"),
        col("g"),
        col("n_slab"),
        col("ur1"),
        col("ut1"),
        col("specular_r"),
    );
    lines
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let x = |i: usize| f[i].trim().parse::<f64>().unwrap();
            IadSlab {
                name: f[ci].to_string(),
                albedo: x(ca),
                tau: x(ct),
                g: x(cg),
                n: x(cn),
                ur1: x(cr),
                ut1: x(cu),
                specular: x(cs),
            }
        })
        .collect()
}

fn iad_setup(s: &IadSlab, theta_o: f64, pixels: usize, pixel_m: f64) -> Setup {
    let d = 1e-3;
    let mu_t = s.tau / d;
    let dirs = Directions::from_degrees(0.0, 0.0, theta_o, 0.0).unwrap();
    setup(s.albedo * mu_t, (1.0 - s.albedo) * mu_t, s.g, s.n, d, pixels, pixel_m, dirs)
}

#[test]
fn total_reflectance_and_transmittance_match_adding_doubling() {
    // The random walk's own escape tallies against iadpython's UR1/UT1
    // (UR1 includes the specular reflection of the top surface).
    let slabs = iad_slabs();
    assert!(slabs.len() >= 4);
    for s in &slabs {
        let setup = iad_setup(s, 0.0, 1, 1e-3);
        let sl = run(&setup, 200_000, 3, Estimator::Connection);
        let r = sl.diffuse_reflectance + sl.specular_reflectance;
        assert!((sl.specular_reflectance - s.specular).abs() < 1e-9, "{}", s.name);
        assert!((r - s.ur1).abs() < 0.01 * s.ur1.max(0.02), "{}: R = {r:.5} vs UR1 {:.5}", s.name, s.ur1);
        assert!(
            (sl.transmittance - s.ut1).abs() < 0.01 * s.ut1.max(0.02),
            "{}: T = {:.5} vs UT1 {:.5}",
            s.name,
            sl.transmittance,
            s.ut1
        );
    }
}

#[test]
fn slice_integrated_over_area_and_directions_matches_adding_doubling() {
    // R_d = 2π ∫₀¹ S(μ_o) μ_o dμ_o with S the slice summed over pixels times
    // the pixel area; 8-point Gauss–Legendre in μ_o = cos θ_o.
    // Published 16-digit nodes and weights, kept as printed.
    #[allow(clippy::excessive_precision)]
    const GL: [(f64, f64); 8] = [
        (-0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
        (-0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
        (-0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
        (-0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
        (0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
        (0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
        (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
        (0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
    ];
    // The PDMS-like slab (g = 0.974) is checked by the escape tallies above:
    // its connection estimate needs ~10⁶ paths per direction for 0.5 %.
    for s in iad_slabs().iter().filter(|s| s.name != "pdms09_like") {
        // Sensor wide enough to catch all the light (lateral spread ≲ a few transport lengths).
        let (pixels, pixel_m) = (64, 2.5e-3);
        let (mut rd, mut var) = (0.0, 0.0);
        for (k, (t, w)) in GL.iter().enumerate() {
            let mu = 0.5 * (t + 1.0);
            let setup = iad_setup(s, mu.acos().to_degrees(), pixels, pixel_m);
            let sl = run(&setup, 80_000, 100 + k as u64, Estimator::Connection);
            let area = pixel_m * pixel_m;
            let c = 2.0 * std::f64::consts::PI * 0.5 * w * mu * area;
            rd += c * sl.sum;
            var += (c * sl.sum_std_error).powi(2);
        }
        // UR1 holds two specular parts that are deltas in direction and not
        // in the slice: the top surface's reflection and the unscattered beam
        // reflected back by the bottom surface (normal incidence, F the same
        // inside and out): (1 − F)² F e^{−2τ} / (1 − F² e^{−2τ}).
        let f = s.specular;
        let e2 = (-2.0 * s.tau).exp();
        let unscattered = (1.0 - f).powi(2) * f * e2 / (1.0 - f * f * e2);
        let expected = s.ur1 - s.specular - unscattered;
        let se = var.sqrt();
        assert!(
            (rd - expected).abs() < 0.01 * expected + 3.0 * se,
            "{}: ∫ slice = {rd:.5} ± {se:.5} vs UR1 − specular parts = {expected:.5}",
            s.name
        );
        assert!(se < 0.0075 * expected, "{}: too noisy to test ({se:.5})", s.name);
    }
}

#[test]
fn reciprocity_of_the_integrated_slice() {
    let base = lab_45_0();
    for (mu_s, mu_a, g, d) in [(2000.0, 200.0, 0.5, 1e-3), (1.5e4, 10.0, 0.97, 6.35e-3)] {
        let (pixels, pixel_m) = (48, 1e-3);
        let a = run(&setup(mu_s, mu_a, g, 1.5, d, pixels, pixel_m, base), 60_000, 21, Estimator::Connection);
        let b = run(&setup(mu_s, mu_a, g, 1.5, d, pixels, pixel_m, base.swapped()), 60_000, 22, Estimator::Connection);
        agree("reciprocity", a.sum, a.sum_std_error, b.sum, b.sum_std_error, 3.0, 0.002);
    }
}

#[test]
fn white_furnace_everything_that_enters_leaves() {
    for (g, n) in [(0.0, 1.0), (0.9, 1.5), (-0.3, 1.33)] {
        let s = setup(5000.0, 0.0, g, n, 2e-3, 8, 1e-3, lab_45_0());
        let sl = run(&s, 20_000, 5, Estimator::Connection);
        let total = sl.specular_reflectance + sl.diffuse_reflectance + sl.transmittance;
        assert!((total - 1.0).abs() < 1e-9, "g={g} n={n}: R + T = {total}");
    }
}

#[test]
fn deterministic_for_a_seed_whatever_the_thread_count() {
    let s = setup(3000.0, 50.0, 0.8, 1.5, 2e-3, 16, 0.2e-3, lab_45_0());
    // 20 050 paths: the last batch is partial.
    let opts = RunOptions {
        stop: Stop::samples(20_050),
        seed: 42,
        batch_paths: 100,
        estimator: Estimator::Connection,
        fold: false,
    };
    let one = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| simulate(&s, &opts, |_| {}).unwrap());
    let two = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap()
        .install(|| simulate(&s, &opts, |_| {}).unwrap());
    assert_eq!(one.values, two.values);
    assert_eq!(one.sum, two.sum);
    assert_eq!(one.paths, 20_050);
    // The pixels add up to the slice sum.
    let total: f64 = one.values.iter().sum();
    assert!((total / one.sum - 1.0).abs() < 1e-9, "{total} vs {}", one.sum);
    let other = simulate(&s, &RunOptions { seed: 43, ..opts }, |_| {}).unwrap();
    assert_ne!(one.sum, other.sum);
}

#[test]
fn stops_at_the_target_error() {
    let s = setup(3000.0, 50.0, 0.8, 1.5, 2e-3, 16, 0.2e-3, lab_45_0());
    let opts = RunOptions { stop: Stop { rel_error: Some(0.02), ..Stop::default() }, ..RunOptions::default() };
    let mut rounds = 0;
    let sl = simulate(&s, &opts, |_| rounds += 1).unwrap();
    assert!(sl.sum_std_error / sl.sum <= 0.02);
    assert!(rounds >= 2);
}

#[test]
fn bad_input_is_rejected() {
    assert!(Slab::new(-1e-3, Medium::new(1.0, 1.0, hg(0.0), 1.5).unwrap()).is_err());
    assert!(Slab::new(f64::NAN, Medium::new(1.0, 1.0, hg(0.0), 1.5).unwrap()).is_err());
    assert!(Medium::new(-1.0, 1.0, hg(0.0), 1.5).is_err());
    assert!(Medium::new(0.0, 0.0, hg(0.0), 1.5).is_err());
    assert!(Medium::new(1.0, 1.0, hg(0.0), 0.5).is_err());
    assert!(Directions::from_degrees(90.0, 0.0, 0.0, 0.0).is_err());
    assert!(Directions::from_degrees(0.0, 0.0, 95.0, 0.0).is_err());
    assert!(Directions::from_degrees(f64::NAN, 0.0, 0.0, 0.0).is_err());
    assert!(Sensor::new(0, 1e-4).is_err());
    assert!(Beam::gaussian(0.0).is_err());
    // Bad beam maps: typed errors whose messages name the problem and pixel.
    let bad_maps = [
        (
            vec![1.0, f64::NAN, 0.0, 0.0],
            SlabError::BeamMapNotFinite { column: 1, row: 0 },
            "pixel (1, 0) is not a finite",
        ),
        (vec![0.0, 1.0, -1.0, 0.0], SlabError::BeamMapNegative { column: 0, row: 1 }, "pixel (0, 1) is negative"),
        (vec![0.0; 4], SlabError::BeamMapAllZero, "all pixels are zero"),
        (vec![1.0; 3], SlabError::BeamMapSize { values: 3, width: 2, height: 2 }, "3 values do not fill 2 × 2"),
    ];
    for (values, error, message) in bad_maps {
        let e = BeamMap::new(2, 2, 1e-4, values).unwrap_err();
        assert!(e.to_string().starts_with("beam map: ") && e.to_string().contains(message), "{e}");
        assert_eq!(e, error);
    }
    let s = setup(3000.0, 50.0, 0.8, 1.5, 2e-3, 16, 0.2e-3, lab_45_0());
    let no_stop = RunOptions { stop: Stop::default(), ..RunOptions::default() };
    assert_eq!(simulate(&s, &no_stop, |_| {}).unwrap_err(), SlabError::Stop(StopError::Empty));
    // The coupled simulation stops on paths or time only: an error target is refused, not ignored.
    let target = RunOptions { stop: Stop { pixel_rel_error: Some(0.1), ..Stop::samples(64) }, ..RunOptions::default() };
    let e = simulate_coupled(&s, &[], &target, |_| {}, &std::sync::atomic::AtomicBool::new(false)).unwrap_err();
    assert_eq!(
        e,
        SlabError::Stop(StopError::Unsupported {
            integrator: "the coupled simulation",
            condition: Condition::PixelRelError
        })
    );
    assert!(e.to_string().contains("pixel_rel_error"), "{e}");
    let bad = RunOptions { stop: Stop { rel_error: Some(1.5), ..Stop::default() }, ..RunOptions::default() };
    assert!(matches!(
        simulate(&s, &bad, |_| {}).unwrap_err(),
        SlabError::Stop(StopError::Parameter { name: "rel_error", .. })
    ));
}

#[test]
fn beam_map_and_gaussian_give_the_same_integrated_slice() {
    // A map of a Gaussian footprint integrates to the same slice sum.
    let dirs = Directions::from_degrees(0.0, 0.0, 30.0, 0.0).unwrap();
    let g = setup(3000.0, 30.0, 0.8, 1.5, 2e-3, 40, 0.5e-3, dirs);
    let (w, px) = (41usize, 20e-6);
    let sigma = 200e-6 / (2.0 * (2.0 * 2f64.ln()).sqrt());
    let values: Vec<f64> = (0..w * w)
        .map(|i| {
            let (x, y) = (((i % w) as f64 - 20.0) * px, ((i / w) as f64 - 20.0) * px);
            (-(x * x + y * y) / (2.0 * sigma * sigma)).exp()
        })
        .collect();
    let mut m = g.clone();
    m.beam = Beam::Map(BeamMap::new(w, w, px, values).unwrap());
    let a = run(&g, 40_000, 1, Estimator::Connection);
    let b = run(&m, 40_000, 2, Estimator::Connection);
    agree("beam map vs gaussian", a.sum, a.sum_std_error, b.sum, b.sum_std_error, 3.0, 0.002);
}

/// χ² p-value of binned counts against expected counts.
fn chi2_counts(observed: &[f64], expected: &[f64]) -> f64 {
    lucent_testkit::chi2::goodness_of_fit(observed, expected).p_value
}

/// A thick, moderately forward-scattering slab where the ring applies
/// (μ_t d = 45).
fn thick_setup(dirs: Directions, pixels: usize, pixel_m: f64) -> Setup {
    setup(3000.0, 30.0, 0.8, 1.5, 15e-3, pixels, pixel_m, dirs)
}

/// Σ z² over the pixels where both slices are resolved (relative error
/// below 25 %), and their count.
fn pixel_chi2(a: &Slice, b: &Slice) -> (f64, usize) {
    let c = lucent_testkit::chi2::pixel_differences((&a.values, &a.std_error), (&b.values, &b.std_error), 0.25);
    (c.chi2, c.dof)
}

#[test]
fn ring_agrees_with_the_fixed_direction_connection_pixel_by_pixel() {
    // From the camera's side (45°/0°, reciprocal) and from the light's
    // (0°/45°): every resolved pixel, χ² of the differences over their
    // combined errors, and the sums.
    for (theta_i, theta_o) in [(45.0, 0.0), (0.0, 45.0)] {
        let dirs = Directions::from_degrees(theta_i, 0.0, theta_o, 180.0).unwrap();
        let s = thick_setup(dirs, 12, 0.5e-3);
        assert_eq!(Estimator::best_for(&s), Estimator::Ring);
        let conn = run(&s, 60_000, 31, Estimator::Connection);
        let ring = run(&s, 12_000, 32, Estimator::Ring);
        assert_eq!(ring.reciprocal, theta_o == 0.0);
        let (chi2, k) = pixel_chi2(&ring, &conn);
        assert!(k >= 60, "{theta_i}/{theta_o}: only {k} resolved pixels");
        let p = lucent_testkit::chi2::upper_tail(chi2, k);
        assert!(p > 1e-3, "{theta_i}/{theta_o}: χ² = {chi2:.1} over {k} pixels (p = {p:.2e})");
        agree("ring vs connection sum", ring.sum, ring.sum_std_error, conn.sum, conn.sum_std_error, 3.5, 0.0);
    }
}

#[test]
fn ring_agrees_with_brute_force_binning() {
    // Exits binned within 8° of ω_o = the normal (45°/0°); the cone
    // average differs from the exact direction by well under 1 % here.
    let dirs = lab_45_0();
    let s = thick_setup(dirs, 8, 1.0e-3);
    let ring = run(&s, 10_000, 41, Estimator::Ring);
    let brute = run(&s, 600_000, 42, Estimator::BruteForce { cone_deg: 8.0 });
    agree("ring vs brute force sum", ring.sum, ring.sum_std_error, brute.sum, brute.sum_std_error, 3.0, 0.01);
}

#[test]
fn reported_standard_errors_match_the_spread_over_seeds() {
    // 30 independent runs; (n − 1) s² / mean(SE²) ~ χ²(n − 1) for the sum
    // and for single pixels, for the fixed-direction connection (thin slab,
    // image terms), the ring and the lobe connection (m = 3) (thick slab),
    // folded.
    let seeds = 30u64;
    let cases = [
        (setup(2000.0, 200.0, 0.5, 1.4, 1e-3, 12, 0.25e-3, lab_45_0()), Estimator::Connection, 8_000u64),
        (thick_setup(lab_45_0(), 12, 0.5e-3), Estimator::Ring, 1_500),
        (thick_setup(lab_45_15(), 12, 0.5e-3), Estimator::Lobe { vertices: 3 }, 1_500),
    ];
    for (s, estimator, paths) in cases {
        let runs: Vec<Slice> = (0..seeds)
            .map(|k| {
                let opts =
                    RunOptions { stop: Stop::samples(paths), seed: 500 + k, batch_paths: 64, estimator, fold: true };
                simulate(&s, &opts, |_| {}).unwrap()
            })
            .collect();
        assert!(runs[0].folded);
        let n = s.sensor.pixels;
        errors_match_spread(
            &format!("{estimator:?}"),
            &runs,
            &[n / 2 * n + n / 2, n / 2 * n + n / 2 - 2, (n / 2 - 3) * n + n / 2],
        );
    }
}

/// (k − 1) s² / mean(SE²) ~ χ²(k − 1) over k independent runs, for the sum
/// and for each of `pixels`: fails when the reported standard errors are
/// inflated or deflated (both tails at 5 × 10⁻⁴).
pub(crate) fn errors_match_spread(label: &str, runs: &[Slice], pixels: &[usize]) {
    let figures = std::iter::once(None).chain(pixels.iter().copied().map(Some));
    for pixel in figures {
        let xs: Vec<(f64, f64)> = runs
            .iter()
            .map(|r| match pixel {
                None => (r.sum, r.sum_std_error),
                Some(i) => (r.values[i], r.std_error[i]),
            })
            .collect();
        assert!(xs.iter().map(|x| x.0).sum::<f64>() > 0.0, "{label} {pixel:?}: empty");
        let what = pixel.map_or("sum".to_string(), |i| format!("pixel {i}"));
        lucent_testkit::spread::assert_errors_match_spread(&format!("{label} {what}"), &xs, 5e-4);
    }
}

#[test]
fn ring_white_furnace_slice_integrates_to_one_minus_transmittance() {
    white_furnace(Estimator::Ring, 6_000, 200);
}

#[test]
fn lobe_white_furnace_slice_integrates_to_one_minus_transmittance() {
    white_furnace(Estimator::Lobe { vertices: 3 }, 6_000, 300);
}

fn white_furnace(estimator: Estimator, paths: u64, seed: u64) {
    // μ_a = 0, normal incidence (the ring launched from the light): the
    // slice integrated over exit area and directions (8-point Gauss–Legendre
    // in μ_o = cos θ_o, the azimuth by symmetry) must be everything that
    // entered, 1 − F(0°), less what the random walk let through the bottom
    // (its own tally, an estimator that shares nothing with the
    // connection). The unscattered beam's bounce is e^{−2τ} = e^{−120}.
    #[allow(clippy::excessive_precision)]
    const GL: [(f64, f64); 8] = [
        (-0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
        (-0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
        (-0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
        (-0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
        (0.183_434_642_495_649_8, 0.362_683_783_378_362_0),
        (0.525_532_409_916_329_0, 0.313_706_645_877_887_3),
        (0.796_666_477_413_626_7, 0.222_381_034_453_374_5),
        (0.960_289_856_497_536_3, 0.101_228_536_290_376_3),
    ];
    let (pixels, pixel_m) = (48, 0.25e-3);
    let (mut rd, mut var, mut t, mut count) = (0.0, 0.0, 0.0, 0.0);
    let mut f0 = 0.0;
    for (k, (x, w)) in GL.iter().enumerate() {
        let mu = 0.5 * (x + 1.0);
        let dirs = Directions::from_degrees(0.0, 0.0, mu.acos().to_degrees(), 0.0).unwrap();
        let s = setup(60_000.0, 0.0, 0.9, 1.4, 1e-3, pixels, pixel_m, dirs);
        let sl = run(&s, paths, seed + k as u64, estimator);
        let c = 2.0 * std::f64::consts::PI * 0.5 * w * mu * pixel_m * pixel_m;
        rd += c * sl.sum;
        var += (c * sl.sum_std_error).powi(2);
        t += sl.transmittance * sl.paths as f64;
        count += sl.paths as f64;
        f0 = sl.specular_reflectance;
    }
    let t = t / count;
    // With μ_a = 0 a path leaves with weight 1 (after the entry factor) or
    // 0.1 after roulette: the Bernoulli bound on the error is close.
    let t_se = (t * (1.0 - t) / count).sqrt();
    let expected = 1.0 - f0 - t;
    let se = (var + t_se * t_se).sqrt();
    assert!(
        (rd - expected).abs() < 0.01 * expected + 3.0 * se,
        "{estimator:?}: ∫ slice = {rd:.5} ± {:.5} vs 1 − F − T = {expected:.5} ± {t_se:.5}",
        var.sqrt()
    );
    assert!(se < 0.01 * expected, "too noisy to test ({se:.5})");
}

#[test]
fn lobe_agrees_with_the_fixed_direction_connection_pixel_by_pixel() {
    // The lab's 45°/15° and an out-of-plane pair (30°/40°, φ_o = 100°), HG
    // g = 0.8 and g = 0.9: every resolved pixel, χ² of the
    // differences over their combined errors, and the sums.
    // Two vertices (m = 1) and chains of four (strategies 0 … 4 and the
    // walk's history truncated at m − j).
    for (theta_i, theta_o, phi_o, g, m) in [(45.0, 15.0, 180.0, 0.8, 1), (30.0, 40.0, 100.0, 0.9, 4)] {
        let dirs = Directions::from_degrees(theta_i, 0.0, theta_o, phi_o).unwrap();
        let s = setup(3000.0, 30.0, g, 1.5, 15e-3, 12, 0.5e-3, dirs);
        assert_eq!(Estimator::best_for(&s), Estimator::Lobe { vertices: LOBE_VERTICES });
        let conn = run(&s, 60_000, 51, Estimator::Connection);
        let two = run(&s, 20_000 / m as u64, 52, Estimator::Lobe { vertices: m });
        let (chi2, k) = pixel_chi2(&two, &conn);
        assert!(k >= 20, "{theta_i}/{theta_o}: only {k} resolved pixels");
        let p = lucent_testkit::chi2::upper_tail(chi2, k);
        assert!(p > 1e-3, "{theta_i}/{theta_o}: χ² = {chi2:.1} over {k} pixels (p = {p:.2e})");
        agree("lobe vs connection sum", two.sum, two.sum_std_error, conn.sum, conn.sum_std_error, 3.5, 0.0);
    }
}

#[test]
fn lobe_agrees_with_brute_force_binning() {
    // Exits binned within 8° of ω_o (45°/15°); the cone average differs
    // from the exact direction by well under 1 % here.
    let s = thick_setup(lab_45_15(), 8, 1.0e-3);
    let two = run(&s, 5_000, 61, Estimator::Lobe { vertices: 3 });
    let brute = run(&s, 600_000, 62, Estimator::BruteForce { cone_deg: 8.0 });
    agree("lobe vs brute force sum", two.sum, two.sum_std_error, brute.sum, brute.sum_std_error, 3.0, 0.01);
}

#[test]
fn lobe_is_refused_where_it_does_not_apply() {
    // A thin slab (image terms) falls back to the fixed direction.
    let thin = setup(2000.0, 200.0, 0.5, 1.4, 1e-3, 8, 0.25e-3, lab_45_15());
    assert_eq!(Estimator::best_for(&thin), Estimator::Connection);
    let opts = RunOptions {
        stop: Stop::samples(100),
        estimator: Estimator::Lobe { vertices: LOBE_VERTICES },
        ..RunOptions::default()
    };
    assert_eq!(simulate(&thin, &opts, |_| {}).unwrap_err(), SlabError::LobeNotApplicable);
    // Chains longer than MAX_LOBE_VERTICES are refused.
    let thick = thick_setup(lab_45_15(), 8, 1e-3);
    let long = RunOptions { estimator: Estimator::Lobe { vertices: MAX_LOBE_VERTICES + 1 }, ..opts };
    assert!(matches!(simulate(&thick, &long, |_| {}), Err(SlabError::Parameter { name: "lobe_vertices", .. })));
}

#[test]
fn fold_gives_a_symmetric_slice_that_agrees_with_the_unfolded_one() {
    let s = thick_setup(lab_45_0(), 12, 0.5e-3);
    assert!(s.mirror_symmetric());
    let opts =
        RunOptions { stop: Stop::samples(6_000), seed: 3, batch_paths: 64, estimator: Estimator::Ring, fold: true };
    let folded = simulate(&s, &opts, |_| {}).unwrap();
    let plain = simulate(&s, &RunOptions { fold: false, seed: 4, ..opts }, |_| {}).unwrap();
    assert!(folded.folded && !plain.folded);
    let n = s.sensor.pixels;
    for r in 0..n {
        for c in 0..n {
            assert_eq!(folded.values[r * n + c], folded.values[(n - 1 - r) * n + c]);
        }
    }
    let (chi2, k) = pixel_chi2(&folded, &plain);
    let p = lucent_testkit::chi2::upper_tail(chi2, k);
    assert!(k > 30 && p > 1e-3, "χ² = {chi2:.1} over {k} pixels (p = {p:.2e})");
    // Not symmetric: light arriving from φ_i = 30°, or an asymmetric map.
    let mut tilted = s.clone();
    tilted.directions = Directions::from_degrees(45.0, 30.0, 0.0, 180.0).unwrap();
    assert!(!tilted.mirror_symmetric());
    let mut mapped = s.clone();
    mapped.beam = Beam::Map(BeamMap::new(2, 2, 1e-4, vec![1.0, 1.0, 0.0, 1.0]).unwrap());
    assert!(!mapped.mirror_symmetric());
    mapped.beam = Beam::Map(BeamMap::new(2, 2, 1e-4, vec![1.0, 0.5, 1.0, 0.5]).unwrap());
    assert!(mapped.mirror_symmetric());
    // The top: an isotropic distribution is symmetric; a measured normal set
    // only if it equals its mirror image (m_y → −m_y).
    use lucent_render::microfacet::{Distribution, MeasuredNormals, Microsurface};
    let with_top = |m: Microsurface| {
        let mut t = s.clone();
        t.slab.top = Interface::new(m).unwrap();
        t
    };
    assert!(with_top(Microsurface::Analytic(Distribution::Beckmann { alpha: 0.3 })).mirror_symmetric());
    let unit = |x: f64, y: f64| {
        let z = (1.0 - x * x - y * y).sqrt();
        [x, y, z]
    };
    let tilted_normals = [unit(0.1, 0.2), unit(-0.05, 0.1), unit(0.0, 0.0), unit(0.2, 0.15)];
    let measured = |n: &[[f64; 3]]| Microsurface::Measured(std::sync::Arc::new(MeasuredNormals::new(n, None).unwrap()));
    assert!(!with_top(measured(&tilted_normals)).mirror_symmetric());
    let mut both = tilted_normals.to_vec();
    both.extend(tilted_normals.iter().map(|m| [m[0], -m[1], m[2]]));
    assert!(with_top(measured(&both)).mirror_symmetric());
}

#[test]
fn direction_sampling_matches_the_phase_function_in_two_dimensions() {
    // Directions from a fixed, oblique incident direction binned on the
    // sphere in global (cos θ, φ), 16 × 16 bins, against p(ω·ω_in)
    // integrated over each bin (8 × 8 midpoint rule): tests the polar
    // sampling, the azimuth and the frame together.
    let inc = {
        let v = [0.3f64, -0.5, 0.81];
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    };
    let table = Phase::Tabulated(
        lucent_render::phase::PhaseTable::from_theta_samples(
            &(0..300).map(|k| (-(k as f64) / 30.0).exp() + 0.02).collect::<Vec<_>>(),
        )
        .unwrap(),
    );
    for (name, phase) in [("HG 0.6", hg(0.6)), ("HG -0.3", hg(-0.3)), ("table", table)] {
        let (nc, np, n) = (16usize, 16usize, 200_000usize);
        let mut observed = vec![0.0; nc * np];
        let mut rng = lucent_render::rng::Rng::new(77, 1);
        for _ in 0..n {
            let d = phase.sample_direction(inc, rng.next_f64(), rng.next_f64());
            let ic = (((d[2] + 1.0) * 0.5 * nc as f64) as usize).min(nc - 1);
            let phi = d[1].atan2(d[0]).rem_euclid(std::f64::consts::TAU);
            let ip = ((phi / std::f64::consts::TAU * np as f64) as usize).min(np - 1);
            observed[ic * np + ip] += 1.0;
        }
        let sub = 8;
        let expected: Vec<f64> = (0..nc * np)
            .map(|b| {
                let (ic, ip) = (b / np, b % np);
                let (dc, dp) = (2.0 / nc as f64, std::f64::consts::TAU / np as f64);
                let mut acc = 0.0;
                for a in 0..sub {
                    for q in 0..sub {
                        let c = -1.0 + (ic as f64 + (a as f64 + 0.5) / sub as f64) * dc;
                        let phi = (ip as f64 + (q as f64 + 0.5) / sub as f64) * dp;
                        let s = (1.0 - c * c).sqrt();
                        let cos = s * phi.cos() * inc[0] + s * phi.sin() * inc[1] + c * inc[2];
                        acc += phase.eval(cos);
                    }
                }
                acc * dc * dp / (sub * sub) as f64 * n as f64
            })
            .collect();
        let p = chi2_counts(&observed, &expected);
        assert!(p > 1e-3, "{name}: χ² p = {p:.2e}");
    }
}

#[test]
fn beam_footprints_are_sampled_with_their_irradiance() {
    // 2-D χ² of the sampled entry points against the footprint's own
    // irradiance, for a Gaussian arriving obliquely off the axes (θ = φ =
    // 45°: the footprint is an ellipse turned by 45°) and for a map.
    let map = Beam::Map(BeamMap::new(3, 2, 0.1e-3, vec![0.0, 1.0, 2.0, 4.0, 0.5, 0.0]).unwrap());
    let cases = [(Beam::gaussian(200e-6).unwrap(), 45.0, 45.0, 0.4e-3), (map, 30.0, 0.0, 0.15e-3)];
    for (beam, theta, phi, half) in cases {
        let fp = beam.footprint(theta, phi);
        let (nb, n) = (24usize, 200_000usize);
        let w = 2.0 * half / nb as f64;
        let mut observed = vec![0.0; nb * nb + 1];
        let mut rng = lucent_render::rng::Rng::new(9, 2);
        for _ in 0..n {
            let (x, y) = fp.sample(&mut rng);
            let (c, r) = ((x + half) / w, (y + half) / w);
            if c >= 0.0 && r >= 0.0 && c < nb as f64 && r < nb as f64 {
                observed[r as usize * nb + c as usize] += 1.0;
            } else {
                observed[nb * nb] += 1.0;
            }
        }
        let sub = 6;
        let mut expected: Vec<f64> = (0..nb * nb)
            .map(|b| {
                let (r, c) = (b / nb, b % nb);
                let mut acc = 0.0;
                for a in 0..sub {
                    for q in 0..sub {
                        let x = -half + (c as f64 + (q as f64 + 0.5) / sub as f64) * w;
                        let y = -half + (r as f64 + (a as f64 + 0.5) / sub as f64) * w;
                        acc += fp.irradiance(x, y);
                    }
                }
                acc * w * w / (sub * sub) as f64 * n as f64
            })
            .collect();
        let inside: f64 = expected.iter().sum();
        expected.push((n as f64 - inside).max(0.0));
        let p = chi2_counts(&observed, &expected);
        assert!(p > 1e-3, "θ {theta}° φ {phi}°: χ² p = {p:.2e}");
    }
}

/// `Estimator::applies` says exactly which setups the kernel accepts: the
/// ring and the lobe connection are refused for a thin slab (and the ring
/// for 45°/15° and a rough top), the others run everywhere.
#[test]
fn estimator_applies_where_the_kernel_accepts_it() {
    let rough = Interface::new(lucent_render::microfacet::Microsurface::Analytic(
        lucent_render::microfacet::Distribution::TrowbridgeReitz { alpha: 0.1 },
    ))
    .unwrap();
    let thick = setup(2.0e4, 5.0, 0.9, 1.5, 4e-3, 9, 0.2e-3, lab_45_0());
    let cases = [
        ("thick 45/0", thick.clone()),
        ("thin 45/0", setup(2.0e3, 5.0, 0.9, 1.5, 1e-3, 9, 0.2e-3, lab_45_0())),
        ("thick 45/15", setup(2.0e4, 5.0, 0.9, 1.5, 4e-3, 9, 0.2e-3, lab_45_15())),
        ("thick 45/0, rough top", Setup { slab: thick.slab.clone().with_top(rough), ..thick.clone() }),
    ];
    let estimators = [
        Estimator::Connection,
        Estimator::Ring,
        Estimator::Lobe { vertices: 2 },
        Estimator::BruteForce { cone_deg: 5.0 },
    ];
    let mut refused = 0;
    for (name, s) in &cases {
        for e in estimators {
            let options = RunOptions { stop: Stop::samples(8), estimator: e, ..RunOptions::default() };
            let result = simulate(s, &options, |_| {});
            let accepted = !matches!(result, Err(SlabError::RingNotApplicable | SlabError::LobeNotApplicable));
            assert_eq!(e.applies(s), accepted, "{name}, {e:?}: {:?}", result.err());
            refused += usize::from(!accepted);
        }
        assert!(Estimator::best_for(s).applies(s), "{name}");
    }
    // thin: ring and lobe; 45/15: ring; rough: ring.
    assert_eq!(refused, 4);
}
