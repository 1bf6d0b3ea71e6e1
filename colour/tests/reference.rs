//! lucent-colour against colour-science and published values (fixtures/reference/colour_*), plus exact-data and noise properties of the colour-correction fits.

use lucent_colour::adaptation::{adaptation_matrix, Cat};
use lucent_colour::ccm::{fit, CcmMethod};
use lucent_colour::data::{colorchecker_2014, colorchecker_reflectance, CHECKER_WHITE, ICC_D50_XYZ};
use lucent_colour::difference::{delta_e_2000, delta_e_76};
use lucent_colour::spaces::{self, mat3_vec, RgbSpace};
use lucent_colour::spectrum::SpectralIntegrator;
use lucent_colour::{band_weights, Illuminant, Observer, WavelengthGrid};
use serde_json::Value;
use std::sync::OnceLock;

fn reference() -> &'static Value {
    static R: OnceLock<Value> = OnceLock::new();
    R.get_or_init(|| {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/reference/colour_reference.json");
        serde_json::from_str(&std::fs::read_to_string(path).expect("read colour_reference.json")).expect("JSON")
    })
}

fn f(v: &Value) -> f64 {
    v.as_f64().unwrap_or_else(|| panic!("not a number: {v}"))
}

fn vec3(v: &Value) -> [f64; 3] {
    [f(&v[0]), f(&v[1]), f(&v[2])]
}

fn rows3(v: &Value) -> Vec<[f64; 3]> {
    v.as_array().expect("array").iter().map(vec3).collect()
}

fn mat3(v: &Value) -> [[f64; 3]; 3] {
    [vec3(&v[0]), vec3(&v[1]), vec3(&v[2])]
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array().expect("array").iter().map(f).collect()
}

/// Largest |a − b| / max(|b|, floor).
fn rel_err(a: &[f64], b: &[f64], floor: f64) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).map(|(x, y)| (x - y).abs() / y.abs().max(floor)).fold(0.0, f64::max)
}

fn flat(rows: &[[f64; 3]]) -> Vec<f64> {
    rows.iter().flatten().copied().collect()
}

fn observer(name: &str) -> Observer {
    match name {
        "cie1931_2" => Observer::Cie1931_2,
        "cie2012_2" => Observer::Cie2012_2,
        other => panic!("observer {other}"),
    }
}

#[test]
fn xyz_xyy_lab_of_the_colorchecker_spectra_match_colour_science() {
    let mut worst = 0.0f64;
    for case in reference()["spectral_xyz"]["cases"].as_array().unwrap() {
        let g = floats(&case["grid_nm"]);
        let grid = WavelengthGrid::new(g[0], g[1], g[2]).unwrap();
        let obs = observer(case["observer"].as_str().unwrap());
        let ill: Illuminant = case["illuminant"].as_str().unwrap().parse().unwrap();
        let integ = SpectralIntegrator::new(&grid, obs, ill).unwrap();
        let xyz: Vec<[f64; 3]> = (0..24)
            .map(|p| {
                let r: Vec<f64> =
                    grid.wavelengths_nm().iter().map(|&nm| colorchecker_reflectance(p, nm).unwrap()).collect();
                integ.xyz(&r).unwrap()
            })
            .collect();
        let label = format!("{} {} {:?}", obs.name(), ill.name(), g);
        let e = rel_err(&flat(&xyz), &flat(&rows3(&case["xyz"])), 1e-3);
        assert!(e < 1e-12, "{label}: XYZ relative error {e:e}");
        worst = worst.max(e);
        let e = rel_err(&integ.white_xyz(), &vec3(&case["white_xyz"]), 1e-3);
        assert!(e < 1e-12, "{label}: white {e:e}");
        let xyy: Vec<[f64; 3]> = xyz.iter().map(|x| spaces::xyz_to_xyy(*x)).collect();
        assert!(rel_err(&flat(&xyy), &flat(&rows3(&case["xyy"])), 1e-3) < 1e-12, "{label}: xyY");
        let white = spaces::xy_to_xyz([f(&case["tabulated_white_xy"][0]), f(&case["tabulated_white_xy"][1])]);
        let lab: Vec<[f64; 3]> = xyz.iter().map(|x| spaces::xyz_to_lab(*x, white)).collect();
        let e = rel_err(&flat(&lab), &flat(&rows3(&case["lab_tabulated_white"])), 1.0);
        assert!(e < 1e-11, "{label}: Lab {e:e}");
    }
    eprintln!("spectral XYZ: worst relative difference to colour-science {worst:e}");
}

#[test]
fn lab_and_xyy_conversions_match_colour_science_and_x_rite() {
    let r = &reference()["lab"];
    let white = spaces::xy_to_xyz([f(&r["checker_white_xy"][0]), f(&r["checker_white_xy"][1])]);
    // The ICC D50 white from its xy is the ICC PCS white.
    assert!(rel_err(&white, &ICC_D50_XYZ, 1.0) < 1e-8, "{white:?}");
    let xyz = rows3(&r["checker_xyz"]);
    let lab: Vec<[f64; 3]> = xyz.iter().map(|x| spaces::xyz_to_lab(*x, white)).collect();
    assert!(rel_err(&flat(&lab), &flat(&rows3(&r["checker_lab"])), 1.0) < 1e-12);
    // The embedded chart data: xyY → XYZ → Lab gives X-Rite's published two-decimal L*a*b*.
    for p in colorchecker_2014() {
        let l = spaces::xyz_to_lab(p.xyz(), ICC_D50_XYZ);
        assert!(rel_err(&l, &p.lab, 1.0) < 2e-7, "patch {}: {l:?} vs {:?}", p.number, p.lab);
        let back = spaces::lab_to_xyz(p.lab, ICC_D50_XYZ);
        assert!(rel_err(&back, &p.xyz(), 1e-2) < 2e-7, "patch {}", p.number);
    }
    let extra = rows3(&r["extra_xyz"]);
    let d65 = Illuminant::D65.white_xyz();
    let lab: Vec<[f64; 3]> = extra.iter().map(|x| spaces::xyz_to_lab(*x, d65)).collect();
    assert!(rel_err(&flat(&lab), &flat(&rows3(&r["extra_lab_d65"])), 1.0) < 1e-12);
    let xyy: Vec<[f64; 3]> = extra[..3].iter().map(|x| spaces::xyz_to_xyy(*x)).collect();
    assert!(rel_err(&flat(&xyy), &flat(&rows3(&r["extra_xyy"])), 1e-3) < 1e-12);
    assert_eq!(spaces::xyz_to_xyy([0.0; 3]), [0.0; 3]);
}

#[test]
fn chromatic_adaptation_matrices_match_colour_science() {
    let r = &reference()["chromatic_adaptation"];
    for (name, ill) in [("D50", Illuminant::D50), ("D65", Illuminant::D65), ("A", Illuminant::A), ("E", Illuminant::E)]
    {
        let xy = [f(&r["white_xy"][name][0]), f(&r["white_xy"][name][1])];
        assert!((xy[0] - ill.white_xy()[0]).abs() < 1e-15 && (xy[1] - ill.white_xy()[1]).abs() < 1e-15, "{name}");
    }
    let mut worst = 0.0f64;
    for case in r["cases"].as_array().unwrap() {
        let cat: Cat = case["transform"].as_str().unwrap().parse().unwrap();
        let src: Illuminant = case["source"].as_str().unwrap().parse().unwrap();
        let dst: Illuminant = case["target"].as_str().unwrap().parse().unwrap();
        let m = adaptation_matrix(src.white_xyz(), dst.white_xyz(), cat).unwrap();
        let e = rel_err(&flat(&m), &flat(&mat3(&case["matrix"])), 1.0);
        assert!(e < 1e-13, "{} {}→{}: {e:e}", cat.name(), src.name(), dst.name());
        let a = mat3_vec(&m, vec3(&case["sample_xyz"]));
        assert!(rel_err(&a, &vec3(&case["sample_adapted"]), 1e-3) < 1e-13);
        worst = worst.max(e);
    }
    eprintln!("adaptation matrices: worst difference {worst:e}");
}

#[test]
fn cie_rgb_and_srgb_conversions_match_colour_science() {
    let r = &reference()["rgb"];
    let close = |a: &[[f64; 3]; 3], b: &Value, tol: f64, what: &str| {
        let e = rel_err(&flat(a), &flat(&mat3(b)), 1.0);
        assert!(e < tol, "{what}: {e:e}");
    };
    close(&RgbSpace::CieRgb.to_xyz_matrix(), &r["cie_rgb_to_xyz"], 1e-15, "CIE RGB → XYZ");
    close(&RgbSpace::CieRgb.from_xyz_matrix(), &r["xyz_to_cie_rgb"], 1e-13, "XYZ → CIE RGB");
    close(&RgbSpace::Srgb.to_xyz_matrix(), &r["srgb_to_xyz"], 1e-15, "sRGB → XYZ");
    close(&RgbSpace::Srgb.from_xyz_matrix(), &r["xyz_to_srgb"], 1e-15, "XYZ → sRGB");

    let d50 = spaces::xy_to_xyz([f(&r["checker_white_xy"][0]), f(&r["checker_white_xy"][1])]);
    let xyz = rows3(&r["checker_xyz_d50"]);
    for (space, cat, key) in [
        (RgbSpace::CieRgb, Some(Cat::Bradford), "checker_cie_rgb_bradford"),
        (RgbSpace::CieRgb, None, "checker_cie_rgb_unadapted"),
        (RgbSpace::Srgb, Some(Cat::Bradford), "checker_srgb_linear_bradford"),
    ] {
        let m = space.from_xyz_adapted_matrix(d50, cat).unwrap();
        let rgb: Vec<[f64; 3]> = xyz.iter().map(|x| mat3_vec(&m, *x)).collect();
        let e = rel_err(&flat(&rgb), &flat(&rows3(&r[key])), 1e-2);
        assert!(e < 1e-12, "{key}: {e:e}");
    }
    // With Bradford adaptation the chart's white patch is neutral in CIE RGB.
    let m = RgbSpace::CieRgb.from_xyz_adapted_matrix(d50, Some(Cat::Bradford)).unwrap();
    let w = mat3_vec(&m, d50);
    assert!((w[0] - 1.0).abs() < 1e-12 && (w[2] - 1.0).abs() < 1e-12, "{w:?}");

    let samples = rows3(&r["cie_rgb_samples"]);
    let expect = rows3(&r["cie_rgb_samples_to_xyz"]);
    for (s, e) in samples.iter().zip(&expect) {
        assert!(rel_err(&RgbSpace::CieRgb.to_xyz(*s), e, 1e-2) < 1e-15);
        assert!(rel_err(&RgbSpace::CieRgb.from_xyz(*e), s, 1e-2) < 1e-13);
    }
    for (x, y) in floats(&r["srgb_encode_in"]).iter().zip(floats(&r["srgb_encode_out"])) {
        assert!((spaces::srgb_encode(*x) - y).abs() < 1e-15, "sRGB encode {x}");
    }
}

#[test]
fn ciede2000_reproduces_the_34_sharma_pairs() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/reference/colour_sharma2005.csv");
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines().filter(|l| !l.starts_with('#'));
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap();
    let (mut worst_pub, mut worst_cs, mut n) = (0.0f64, 0.0f64, 0);
    for line in lines {
        let v: Vec<f64> = line.split(',').map(|s| s.parse().unwrap()).collect();
        let lab1 = [v[col("L1")], v[col("a1")], v[col("b1")]];
        let lab2 = [v[col("L2")], v[col("a2")], v[col("b2")]];
        let de = delta_e_2000(lab1, lab2);
        assert!((de - delta_e_2000(lab2, lab1)).abs() < 1e-12, "pair {} not symmetric", v[0]);
        worst_pub = worst_pub.max((de - v[col("de00_published")]).abs());
        worst_cs = worst_cs.max((de - v[col("de00_colour")]).abs());
        assert!((delta_e_76(lab1, lab2) - v[col("de76_colour")]).abs() < 1e-12);
        n += 1;
    }
    assert_eq!(n, 34);
    // The table is rounded to 4 decimals: agreement to half a unit of the last digit.
    assert!(worst_pub <= 5e-5, "vs published: {worst_pub:e}");
    assert!(worst_cs < 1e-12, "vs colour-science: {worst_cs:e}");
    eprintln!("CIEDE2000: max |Δ| to the published table {worst_pub:e}, to colour-science {worst_cs:e}");
}

#[test]
fn colour_correction_fits_match_colour_science() {
    let r = &reference()["ccm"];
    let rgb = rows3(&r["camera_rgb"]);
    let xyz = rows3(&r["reference_xyz"]);
    let white = spaces::xy_to_xyz([f(&r["white_xy"][0]), f(&r["white_xy"][1])]);
    // The embedded chart references are the same numbers.
    let embedded: Vec<[f64; 3]> = colorchecker_2014().iter().map(|p| p.xyz()).collect();
    assert!(rel_err(&flat(&embedded), &flat(&xyz), 1e-3) < 1e-10);
    for case in r["fits"].as_array().unwrap() {
        let name = case["method"].as_str().unwrap();
        if name == "Finlayson 2015 degree 1" {
            // colour-science's degree-1 root polynomial is the 3 × 3 linear fit.
            let ccm = fit(CcmMethod::Cheung2004, &rgb, &xyz, CHECKER_WHITE).unwrap();
            let m: Vec<f64> = ccm.matrix().iter().flatten().copied().collect();
            assert!(rel_err(&m, &floats_2d(&case["matrix"]), 1e-3) < 1e-9, "{name}");
            continue;
        }
        let method: CcmMethod = name.parse().unwrap();
        let ccm = fit(method, &rgb, &xyz, CHECKER_WHITE).unwrap();
        let m: Vec<f64> = ccm.matrix().iter().flatten().copied().collect();
        let e = rel_err(&m, &floats_2d(&case["matrix"]), 1e-3);
        assert!(e < 1e-9, "{name}: matrix relative difference {e:e}");
        let names: Vec<&str> = colorchecker_2014().iter().map(|p| p.name).collect();
        let report = ccm.report(&rgb, &xyz, white, &names).unwrap();
        let de: Vec<f64> = report.patches.iter().map(|p| p.de2000).collect();
        let de76: Vec<f64> = report.patches.iter().map(|p| p.de76).collect();
        assert!(rel_err(&de, &floats(&case["de2000"]), 1e-2) < 1e-7, "{name}: ΔE00");
        assert!(rel_err(&de76, &floats(&case["de76"]), 1e-2) < 1e-7, "{name}: ΔE76");
        assert!((report.de2000_mean - f(&case["de2000_mean"])).abs() < 1e-9);
        assert!((report.de2000_max - f(&case["de2000_max"])).abs() < 1e-9);
        eprintln!(
            "{name}: matrix relative difference {e:e}; ΔE00 mean {:.3} max {:.3}",
            report.de2000_mean, report.de2000_max
        );
        if method == CcmMethod::Finlayson1997 {
            let w = ccm.apply(rgb[CHECKER_WHITE]);
            assert!(rel_err(&w, &xyz[CHECKER_WHITE], 1e-3) < 1e-12, "white not preserved: {w:?}");
        }
    }
}

fn floats_2d(v: &Value) -> Vec<f64> {
    v.as_array().unwrap().iter().flat_map(floats).collect()
}

#[test]
fn band_weights_match_the_numpy_reference() {
    for case in reference()["bands"]["cases"].as_array().unwrap() {
        let g = floats(&case["grid_nm"]);
        let grid = WavelengthGrid::new(g[0], g[1], g[2]).unwrap();
        let w = band_weights(&grid).unwrap();
        let expect = rows3(&case["weights"]);
        assert_eq!(expect.len(), grid.len());
        for (i, e) in expect.iter().enumerate() {
            for (b, want) in e.iter().enumerate() {
                assert!((w.weights[b][i] - want).abs() < 1e-14, "{g:?} λ {} band {b}", grid.wavelengths_nm()[i]);
            }
        }
        for (name, values) in case["values"].as_object().unwrap() {
            let got = w.average(&floats(values)).unwrap();
            let e = rel_err(&got, &vec3(&case["bands"][name]), 1e-6);
            assert!(e < 1e-13, "{g:?} {name}: {e:e}");
        }
    }
}

/// splitmix64 → uniform → Box–Muller normal; deterministic.
use lucent_testkit::normal::SplitMix64 as Rng;

/// A random camera: a well-conditioned 3 × 3 RGB ← XYZ matrix.
fn random_camera(rng: &mut Rng) -> [[f64; 3]; 3] {
    let mut m = [[0.0; 3]; 3];
    for (i, row) in m.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            *v = if i == j { 0.8 + 0.4 * rng.uniform() } else { 0.3 * (rng.uniform() - 0.5) };
        }
    }
    m
}

#[test]
fn fits_to_exact_synthetic_data_return_the_matrix() {
    let xyz: Vec<[f64; 3]> = colorchecker_2014().iter().map(|p| p.xyz()).collect();
    let mut rng = Rng(2004);
    for _ in 0..20 {
        let cam = random_camera(&mut rng);
        let truth = spaces::mat3_inverse(&cam).unwrap();
        let rgb: Vec<[f64; 3]> = xyz.iter().map(|x| mat3_vec(&cam, *x)).collect();
        for method in [CcmMethod::Cheung2004, CcmMethod::Finlayson1997] {
            let ccm = fit(method, &rgb, &xyz, CHECKER_WHITE).unwrap();
            let m: Vec<f64> = ccm.matrix().iter().flatten().copied().collect();
            assert!(rel_err(&m, &flat(&truth), 1e-2) < 1e-10, "{method}");
        }
        // Root polynomial: data made by a known 3 × 6 matrix.
        let m6: Vec<Vec<f64>> = (0..3).map(|_| (0..6).map(|_| rng.uniform() - 0.3).collect()).collect();
        let target: Vec<[f64; 3]> = rgb
            .iter()
            .map(|c| {
                let t = CcmMethod::Finlayson2015.expand(*c);
                let row = |r: usize| (0..6).map(|k| m6[r][k] * t[k]).sum::<f64>();
                [row(0), row(1), row(2)]
            })
            .collect();
        let ccm = fit(CcmMethod::Finlayson2015, &rgb, &target, CHECKER_WHITE).unwrap();
        let got: Vec<f64> = ccm.matrix().iter().flatten().copied().collect();
        let want: Vec<f64> = m6.iter().flatten().copied().collect();
        assert!(rel_err(&got, &want, 1e-1) < 1e-8, "Finlayson 2015: {got:?} vs {want:?}");
    }
}

#[test]
fn finlayson_2015_is_exposure_invariant_and_cheung_is_not_fooled_by_scale() {
    let r = &reference()["ccm"];
    let rgb = rows3(&r["camera_rgb"]);
    let xyz = rows3(&r["reference_xyz"]);
    for method in <CcmMethod as strum::IntoEnumIterator>::iter() {
        let base = fit(method, &rgb, &xyz, CHECKER_WHITE).unwrap();
        for k in [0.25, 3.0] {
            let scaled: Vec<[f64; 3]> = rgb.iter().map(|c| [k * c[0], k * c[1], k * c[2]]).collect();
            let ccm = fit(method, &scaled, &xyz, CHECKER_WHITE).unwrap();
            for (a, b) in rgb.iter().zip(&scaled) {
                assert!(rel_err(&ccm.apply(*b), &base.apply(*a), 1e-3) < 1e-10, "{method} k = {k}");
            }
        }
        // A fixed correction applied to a brighter exposure gives proportionally brighter XYZ.
        let p = base.apply([0.2, 0.3, 0.1]);
        let q = base.apply([0.4, 0.6, 0.2]);
        assert!(rel_err(&q, &[2.0 * p[0], 2.0 * p[1], 2.0 * p[2]], 1e-3) < 1e-12, "{method}");
    }
}

#[test]
fn with_noise_the_fitted_error_stays_within_the_noise_level() {
    let chart = colorchecker_2014();
    let xyz: Vec<[f64; 3]> = chart.iter().map(|p| p.xyz()).collect();
    let lab_ref: Vec<[f64; 3]> = chart.iter().map(|p| p.lab).collect();
    let mut rng = Rng(1996);
    for sigma in [0.002, 0.01] {
        let cam = random_camera(&mut rng);
        let truth = spaces::mat3_inverse(&cam).unwrap();
        let noisy: Vec<[f64; 3]> = xyz
            .iter()
            .map(|x| {
                let c = mat3_vec(&cam, *x);
                [
                    c[0] * (1.0 + sigma * rng.normal()),
                    c[1] * (1.0 + sigma * rng.normal()),
                    c[2] * (1.0 + sigma * rng.normal()),
                ]
            })
            .collect();
        // ΔE of the noisy patches through the true matrix: the noise level.
        let noise_de: f64 = noisy
            .iter()
            .zip(&lab_ref)
            .map(|(c, l)| delta_e_2000(spaces::xyz_to_lab(mat3_vec(&truth, *c), ICC_D50_XYZ), *l))
            .sum::<f64>()
            / 24.0;
        for method in <CcmMethod as strum::IntoEnumIterator>::iter() {
            let ccm = fit(method, &noisy, &xyz, CHECKER_WHITE).unwrap();
            let report = ccm.report(&noisy, &xyz, ICC_D50_XYZ, &[]).unwrap();
            assert!(
                report.de2000_mean <= 1.2 * noise_de,
                "{method} σ = {sigma}: mean ΔE00 {} vs noise level {noise_de}",
                report.de2000_mean
            );
        }
    }
}
