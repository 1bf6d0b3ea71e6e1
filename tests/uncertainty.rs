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

/// The shipped example of an uncertain recipe reads with its three
/// uncertain inputs (normal, normal, uniform) and is otherwise IOL1068-09.
#[test]
fn the_shipped_uncertain_recipe_reads_with_its_inputs() {
    use lucent::optics::recipe::InputDistribution;
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
    let r = Recipe::load(&root.join("fixtures/samples/uncertain/IOL1068-09.toml"), Overrides::default()).unwrap();
    let keys: Vec<&str> = r.uncertain.iter().map(|u| u.key.as_str()).collect();
    assert_eq!(keys.len(), 3, "{keys:?}");
    let weight = r.uncertain.iter().find(|u| u.key.ends_with("weight_percent")).expect("weight_percent");
    assert_eq!((weight.nominal, &weight.distribution), (0.65, &InputDistribution::Normal { sd: 0.0325 }));
    assert!(r.uncertain.iter().any(|u| u.key.ends_with("diameter_um") && (u.nominal - 2.2).abs() < 1e-12));
    assert!(r.uncertain.iter().any(|u| u.key.contains("real_part")));
    let plain = Recipe::load(&root.join("fixtures/samples/IOL1068-09.toml"), Overrides::default()).unwrap();
    let a = bulk::at_wavelength(&r, 550.0, &bulk::Options::default()).unwrap();
    let b = bulk::at_wavelength(&plain, 550.0, &bulk::Options::default()).unwrap();
    assert_eq!((a.mu_s_per_m, a.mu_a_per_m, a.g), (b.mu_s_per_m, b.mu_a_per_m, b.g), "the nominal is IOL1068-09");
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
    RunOptions { stop: Stop::samples(paths), seed, batch_paths: 250, estimator: Estimator::best_for(setup), fold: true }
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
    // The figures of docs/benchmarks.md (`--nocapture`).
    eprintln!(
        "slice sum {:.5e}: first-order band {:.4e} ± {:.1e}; slope {slope:.4e} ± {slope_se:.1e} vs brute force \
         {b:.4e} ± {se_b:.1e} (z {z:.2}); spread over the {} draws {observed:.4e}, first order {predicted:.4e} \
         ({:+.1} %)",
        slice.sum,
        fo.sd[0],
        fo.sd_std_error[0],
        draws.len(),
        100.0 * (predicted / observed - 1.0)
    );
    assert!(
        (predicted - observed).abs() < 0.1 * observed,
        "spread of the slice sum over the draws {observed} vs first order {predicted} (band {} ± {}; slopes {slope} ± {slope_se}, brute force {b} ± {se_b})",
        fo.sd[0],
        fo.sd_std_error[0]
    );
}

mod cli {
    use crate::common::{lucent, stderr};
    use std::path::Path;

    /// A 24 × 18 view of an IOL1068-09 plaque (weight percentage ±5 %) on a
    /// board under a constant sky, the similar medium (a fast walk).
    fn scene(dir: &Path, render: &str) -> std::path::PathBuf {
        scene_of(dir, render, "weight_percent = { value = 0.65, sd = 0.0325 }", "diameter_um = 2.2")
    }

    /// [`scene`] with the recipe's weight percentage and diameter lines.
    fn scene_of(dir: &Path, render: &str, weight: &str, diameter: &str) -> std::path::PathBuf {
        let recipe = include_str!("../fixtures/samples/IOL1068-09.toml")
            .replace("weight_percent = 0.65", weight)
            .replace("diameter_um = 2.2", diameter)
            .replace("size_mm = [149.1, 104.5]", "size_mm = [40.0, 40.0]");
        std::fs::write(dir.join("u.toml"), recipe).unwrap();
        let scene = format!(
            "[camera]\nwidth = 24\nheight = 18\nposition_m = [0.0, -0.12, 0.10]\nlook_at_m = [0.0, 0.0, 0.0]\n\
             up = [0.0, 0.0, 1.0]\nvertical_fov_deg = 25.0\n\n[object]\n\n[material]\nrecipe = \"u.toml\"\n\
             wavelengths = \"400:700:50\"\ndispersion = false\n\n[board]\norigin_m = [-0.1, -0.1, 0.0]\n\
             square_mm = 20.0\ncolumns = 10\nrows = 10\neven = [0.8, 0.8, 0.8]\nodd = [0.1, 0.1, 0.1]\n\n\
             [environment]\nconstant = [1.0, 1.0, 1.0]\n\n[render]\nsimilarity_g = 0.0\n{render}\n"
        );
        let path = dir.join("s.toml");
        std::fs::write(&path, scene).unwrap();
        path
    }

    fn json(path: &Path) -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
    }

    /// `lucent render --uncertainty`: uncertainty.json and band.exr; the
    /// weight percentage's effect comes from the render's own paths (path
    /// derivative, no extra render), and the object's difference between
    /// +1 σ and −1 σ has a stated Monte Carlo error that matches its spread
    /// over six seeds.
    #[test]
    fn render_bands_carry_errors_that_match_the_spread_over_seeds() {
        let tmp = tempfile::tempdir().unwrap();
        let mut diffs: Vec<[f64; 3]> = Vec::new();
        let mut stated = 0.0;
        for seed in 1..=6 {
            let s = scene(tmp.path(), &format!("spp = 32\nseed = {seed}"));
            let out = tmp.path().join(format!("r{seed}"));
            let o =
                lucent(&["render", s.to_str().unwrap(), "--uncertainty", "--quiet", "--out", out.to_str().unwrap()]);
            assert!(o.status.success(), "{}", stderr(&o));
            assert!(out.join("band.exr").is_file() && out.join("render.exr").is_file());
            let j = json(&out.join("uncertainty.json"));
            assert!(j["spp_per_input_render"].is_null(), "{j}");
            assert_eq!(j["input_methods"][0]["method"].as_str(), Some("path derivative"), "{j}");
            let left_out = j["input_methods"][0]["left_out_relative_change"].as_f64().unwrap();
            assert!((0.0..1e-3).contains(&left_out), "{j}");
            let object = &j["regions"][0];
            assert_eq!(object["region"].as_str(), Some("object"), "{j}");
            let effect = &object["inputs"][0];
            assert_eq!(effect["key"].as_str(), Some("particles[0].weight_percent"), "{j}");
            let d: [f64; 3] = std::array::from_fn(|c| effect["difference"][c].as_f64().unwrap());
            for c in 0..3 {
                let se = effect["difference_std_error"][c].as_f64().unwrap();
                assert!(se > 0.0 && se.is_finite(), "{j}");
                stated += se * se / 18.0;
                let sd = object["inputs_sd"][c].as_f64().unwrap();
                assert!((sd - 0.5 * d[c].abs()).abs() <= 1e-12 * sd.max(1e-300), "one input: sd = |Δ|/2 ({j})");
            }
            diffs.push(d);
        }
        let mut spread = 0.0;
        for c in 0..3 {
            let m = diffs.iter().map(|d| d[c]).sum::<f64>() / 6.0;
            spread += diffs.iter().map(|d| (d[c] - m).powi(2)).sum::<f64>() / 5.0 / 3.0;
        }
        // 6 seeds (channels strongly correlated): the variance ratio lies in 0.2 … 2.6 with probability ≈ 0.98.
        let ratio = spread / stated;
        assert!(ratio > 0.2 && ratio < 2.6, "variance over seeds / stated variance = {ratio}");
    }

    /// The two estimators of an input's effect, independent (other seeds):
    /// the path derivative of the nominal render and the renders at ±1 σ
    /// (`--uncertainty-renders`), on the object's mean per band, within 3.5
    /// standard errors; and the renders are what a diameter, which changes
    /// the phase functions, gets.
    ///
    /// Twice: with the similar medium's depth floor held throughout, and for
    /// the first 16 events only (demo.toml's `similarity_floor_events`),
    /// where the later medium's coefficients move with the input as the
    /// first one's do only up to its flat top's cut.
    #[test]
    fn path_derivative_agrees_with_renders_at_plus_minus_one_sigma() {
        for render in ["spp = 2048", "spp = 2048\nsimilarity_floor_events = 16"] {
            path_derivative_agrees_with_renders(render);
        }
    }

    fn path_derivative_agrees_with_renders(render: &str) {
        let tmp = tempfile::tempdir().unwrap();
        let s = scene(tmp.path(), render);
        let run = |name: &str, extra: &[&str]| -> serde_json::Value {
            let out = tmp.path().join(name);
            let args = [
                &["render", s.to_str().unwrap(), "--uncertainty", "--quiet"][..],
                extra,
                &["--out", out.to_str().unwrap()],
            ]
            .concat();
            let o = lucent(&args);
            assert!(o.status.success(), "{}", stderr(&o));
            json(&out.join("uncertainty.json"))
        };
        let path = run("path", &["--seed", "11"]);
        let renders = run("renders", &["--seed", "12", "--uncertainty-renders", "--uncertainty-spp", "2048"]);
        assert_eq!(path["input_methods"][0]["method"].as_str(), Some("path derivative"), "{path}");
        assert_eq!(renders["input_methods"][0]["method"].as_str(), Some("renders at ±1 σ"), "{renders}");
        let effect = |j: &serde_json::Value, f: &str, c: usize| j["regions"][0]["inputs"][0][f][c].as_f64().unwrap();
        for c in 0..3 {
            let (a, b) = (effect(&path, "difference", c), effect(&renders, "difference", c));
            let (ea, eb) = (effect(&path, "difference_std_error", c), effect(&renders, "difference_std_error", c));
            let z = (a - b) / (ea * ea + eb * eb).sqrt();
            assert!(a > 6.0 * ea, "band {c}: the effect {a} ± {ea} is not resolved");
            assert!(z.abs() < 3.5, "{render}: band {c}: path derivative {a} ± {ea}, renders {b} ± {eb}, z = {z:.2}");
        }
        // A diameter changes the phase functions: rendered at ±1 σ.
        let d = scene_of(tmp.path(), "spp = 8", "weight_percent = 0.65", "diameter_um = { value = 2.2, sd = 0.1 }");
        let out = tmp.path().join("diameter");
        let o = lucent(&["render", d.to_str().unwrap(), "--uncertainty", "--quiet", "--out", out.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        let j = json(&out.join("uncertainty.json"));
        assert_eq!(j["input_methods"][0]["method"].as_str(), Some("renders at ±1 σ"), "{j}");
        assert_eq!(j["spp_per_input_render"].as_u64(), Some(4), "{j}");
        // So does the plaque's thickness, which moves its faces.
        let t = scene_of(tmp.path(), "spp = 8", "weight_percent = 0.65", "diameter_um = 2.2");
        let text = std::fs::read_to_string(tmp.path().join("u.toml")).unwrap();
        std::fs::write(
            tmp.path().join("u.toml"),
            text.replace("thickness_mm = 6.35", "thickness_mm = { value = 6.35, sd = 0.1 }"),
        )
        .unwrap();
        let out = tmp.path().join("thickness");
        let o = lucent(&["render", t.to_str().unwrap(), "--uncertainty", "--quiet", "--out", out.to_str().unwrap()]);
        assert!(o.status.success(), "{}", stderr(&o));
        let j = json(&out.join("uncertainty.json"));
        assert_eq!(j["inputs"][0]["key"].as_str(), Some("thickness_mm"), "{j}");
        assert_eq!(j["input_methods"][0]["method"].as_str(), Some("renders at ±1 σ"), "{j}");
    }

    /// `lucent compare --band`: a "photo" rendered (another seed) from the
    /// recipe at +0.5 σ lies within the nominal twin's predictive band on the
    /// object, one at +5 σ outside it, the z per band close to the input's
    /// offset in units of the predictive sd; band.png is written; a band
    /// without an object mask, or more bands than renders, is refused.
    #[test]
    fn compare_states_whether_the_photo_lies_within_the_band() {
        let tmp = tempfile::tempdir().unwrap();
        let render = |name: &str, weight: &str, seed: u64, extra: &[&str]| -> std::path::PathBuf {
            let dir = tmp.path().join(name);
            std::fs::create_dir_all(&dir).unwrap();
            let s = scene_of(&dir, &format!("spp = 1024\nseed = {seed}"), weight, "diameter_um = 2.2");
            let out = dir.join("out");
            let args = [&["render", s.to_str().unwrap(), "--quiet"][..], extra, &["--out", out.to_str().unwrap()]];
            let o = lucent(&args.concat());
            assert!(o.status.success(), "{}", stderr(&o));
            out
        };
        let twin = render("twin", "weight_percent = { value = 0.65, sd = 0.0325 }", 1, &["--uncertainty"]);
        let compare = |photo: &Path, name: &str, extra: &[&str]| -> std::process::Output {
            let exr = photo.join("render.exr");
            let (p, t) = (exr.to_str().unwrap(), twin.join("render.exr"));
            let out = tmp.path().join(name);
            let args = [
                &["compare", "--photo", p, "--photo-variance", p, "--render", t.to_str().unwrap()][..],
                extra,
                &["--out", out.to_str().unwrap()],
            ];
            lucent(&args.concat())
        };
        let mask = twin.join("render.exr");
        let (mask, band) = (mask.to_str().unwrap(), twin.to_str().unwrap());
        let mut z_near = Vec::new();
        for (name, weight) in [("near", 0.65 + 0.5 * 0.0325), ("far", 0.65 + 5.0 * 0.0325)] {
            let photo = render(name, &format!("weight_percent = {weight}"), 7, &[]);
            let o = compare(&photo, &format!("c_{name}"), &["--mask-object", mask, "--band", band]);
            assert!(o.status.success(), "{}", stderr(&o));
            let out = tmp.path().join(format!("c_{name}"));
            assert!(out.join("band.png").is_file());
            let j = json(&out.join("metrics.json"));
            let b = &j["bands"][0];
            assert_eq!(b["region"].as_str(), Some("object"), "{b}");
            assert!(b["photo_noise_known"].as_bool().unwrap(), "{b}");
            let z: Vec<f64> = (0..3).map(|c| b["z"][c].as_f64().unwrap()).collect();
            let within = b["within"].as_bool().unwrap();
            let stdout = String::from_utf8_lossy(&o.stdout);
            if name == "near" {
                assert!(within && stdout.contains("within its predictive band"), "{b}");
                z_near = z;
            } else {
                assert!(!within && stdout.contains("outside its predictive band"), "{b}");
                // The effect is near linear: ten times the near photo's offset (to 40 %, for curvature and noise).
                for c in 0..3 {
                    assert!(
                        z[c] > 2.0 && (z[c] / (10.0 * z_near[c]) - 1.0).abs() < 0.4,
                        "band {c}: far z {z:?}, near {z_near:?}"
                    );
                }
            }
        }
        // A band needs the object's (or board's) pixels, and one per render.
        let photo = tmp.path().join("near/out");
        let o = compare(&photo, "c_bad", &["--band", band]);
        assert!(!o.status.success() && stderr(&o).contains("--mask-object or --mask-board"), "{}", stderr(&o));
        let o = compare(&photo, "c_bad", &["--mask-object", mask, "--band", band, "--band", band]);
        assert!(!o.status.success() && stderr(&o).contains("2 bands for 1 render"), "{}", stderr(&o));
        let o = compare(&photo, "c_bad", &["--mask-object", mask, "--band", mask]);
        assert!(!o.status.success() && stderr(&o).contains("not a render's uncertainty.json"), "{}", stderr(&o));
        assert!(!tmp.path().join("c_bad").exists(), "nothing written");
    }

    #[test]
    fn render_uncertainty_refuses_what_it_cannot_do() {
        let tmp = tempfile::tempdir().unwrap();
        // (A diameter's effect needs renders at ±1 σ, which the time budget must bound.)
        let s = scene_of(tmp.path(), "spp = 4", "weight_percent = 0.65", "diameter_um = { value = 2.2, sd = 0.1 }");
        let out = tmp.path().join("r");
        let (s_arg, out_arg) = (s.to_str().unwrap(), out.to_str().unwrap());
        let o = lucent(&["render", s_arg, "--uncertainty", "--uncertainty-spp", "3", "--out", out_arg]);
        assert!(!o.status.success() && stderr(&o).contains("--uncertainty-spp 3: must be a positive even number"));
        let o = lucent(&["render", s_arg, "--uncertainty", "--shard", "0/2", "--out", out_arg]);
        assert!(!o.status.success() && stderr(&o).contains("not sharded"), "{}", stderr(&o));
        // The time budget bounds the renders at ±1 σ too.
        let start = std::time::Instant::now();
        let big = ["render", s_arg, "--uncertainty", "--uncertainty-spp", "2000000000", "--time-s", "2"];
        let o = lucent(&[&big[..], &["--quiet", "--out", out_arg]].concat());
        assert!(!o.status.success() && stderr(&o).contains("within the time budget (2 s)"), "{}", stderr(&o));
        assert!(start.elapsed().as_secs() < 60, "took {:?}", start.elapsed());
        assert!(out.join("render.exr").is_file() && !out.join("uncertainty.json").exists());
        std::fs::remove_dir_all(&out).unwrap();
        // A recipe without an uncertain input.
        let plain = include_str!("../fixtures/samples/IOL1068-09.toml");
        std::fs::write(tmp.path().join("u.toml"), plain).unwrap();
        let o = lucent(&["render", s_arg, "--uncertainty", "--out", out_arg]);
        assert!(!o.status.success() && stderr(&o).contains("gives no input with an uncertainty"), "{}", stderr(&o));
        assert!(!out.exists(), "nothing written before the check");
    }

    /// `lucent bssrdf --uncertainty`: the four files, and the refusals.
    #[test]
    fn slice_bands_are_written_beside_the_slice() {
        let tmp = tempfile::tempdir().unwrap();
        scene(tmp.path(), "");
        let recipe = tmp.path().join("u.toml");
        let out = tmp.path().join("b");
        let (r, o_arg) = (recipe.to_str().unwrap(), out.to_str().unwrap());
        let common = ["bssrdf", "--recipe", r, "--uncertainty", "--crop", "31", "--quiet", "--out", o_arg];
        let o = lucent(&[
            "bssrdf",
            "--mu-s",
            "1e4",
            "--mu-a",
            "1",
            "--g",
            "0.9",
            "--n",
            "1.5",
            "--uncertainty",
            "--paths",
            "100",
            "--out",
            o_arg,
        ]);
        assert!(!o.status.success() && stderr(&o).contains("--uncertainty needs --recipe"), "{}", stderr(&o));
        assert!(!out.exists());
        let o = lucent(&[&common[..], &["--rel-error", "0.05"]].concat());
        assert!(!o.status.success() && stderr(&o).contains("give --paths or --time-s"), "{}", stderr(&o));
        let o = lucent(&[&common[..], &["--paths", "2000"]].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        for f in ["uncertainty.json", "band.exr", "profile-band.csv", "profile-band.png", "bssrdf.exr"] {
            assert!(out.join(f).is_file(), "{f}");
        }
        let j = json(&out.join("uncertainty.json"));
        assert_eq!(j["inputs"][0]["key"].as_str(), Some("particles[0].weight_percent"), "{j}");
        let rel = j["sum_inputs_relative_sd"].as_f64().unwrap();
        assert!(rel > 0.0 && rel < 0.5, "{j}");
        let csv = std::fs::read_to_string(out.join("profile-band.csv")).unwrap();
        assert!(csv.starts_with("x_mm,f_per_m2_sr,std_error_per_m2_sr,inputs_sd_per_m2_sr,"), "{csv}");
        assert_eq!(csv.lines().count(), 32);
    }
}
