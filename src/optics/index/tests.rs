//! Tests of the index model, the dispersion formulas and the YAML parser.

use super::*;

const TOL: f64 = 1e-12;

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * b.abs().max(1.0)
}

fn formula_file(kind: u8, range: &str, coefficients: &str) -> String {
    format!(
        "REFERENCES: test\nDATA:\n  - type: formula {kind}\n    wavelength_range: {range}\n    coefficients: {coefficients}\n"
    )
}

fn n_of_formula(kind: u8, range: &str, coefficients: &str, wavelength_nm: f64) -> f64 {
    let s = IndexSpectrum::parse(&formula_file(kind, range, coefficients), "test").unwrap();
    let sample = s.at(wavelength_nm, Extrapolation::None).unwrap();
    assert_eq!(sample.index.im, 0.0, "formula files without k data have κ = 0");
    assert!(!sample.extrapolated);
    sample.index.re
}

// Expected values below were computed independently in Python 3 (float64)
// directly from the formulas of the database document, e.g. for formula 1:
//   python3 -c "from math import sqrt; c=[0,0.6961663,0.0684043,0.4079426,0.1162414,0.8974794,9.896161]; l=0.5876;
//               print(sqrt(1+c[0]+sum(c[i]*l**2/(l**2-c[i+1]**2) for i in (1,3,5))))"

#[test]
fn formula_1_sellmeier() {
    // Malitson fused silica at 587.6 nm (the d line; the known 1.4585).
    let n = n_of_formula(1, "0.21 6.7", "0 0.6961663 0.0684043 0.4079426 0.1162414 0.8974794 9.896161", 587.6);
    assert!(close(n, 1.4584623420532408, TOL), "{n}");
}

#[test]
fn formula_2_sellmeier2() {
    // python3 -c "from math import sqrt; l=0.55; print(sqrt(1+0+1.4182*l**2/(l**2-0.021304)))"
    let n = n_of_formula(2, "0.4368 1.052", "0 1.4182 0.021304", 550.0);
    assert!(close(n, 1.5892280556562557, TOL), "{n}");
    // The shipped Sultanova polycarbonate file is this formula.
    let pc = IndexSpectrum::builtin("PC_Sultanova2009").unwrap();
    assert!(close(pc.at(550.0, Extrapolation::None).unwrap().index.re, 1.5892280556562557, TOL));
}

#[test]
fn formula_3_polynomial() {
    // python3 -c "from math import sqrt; c=[2.2,0.01,2,-0.012,-2,0.0003,-4]; l=0.6;
    //             print(sqrt(c[0]+c[1]*l**c[2]+c[3]*l**c[4]+c[5]*l**c[6]))"
    let n = n_of_formula(3, "0.4 1.0", "2.2 0.01 2 -0.012 -2 0.0003 -4", 600.0);
    assert!(close(n, 1.473967937738634, TOL), "{n}");
}

#[test]
fn formula_4_refractiveindex_info() {
    // python3 -c "from math import sqrt; c=[2.0,0.5,2,0.25,2,0.1,2,4.0,1.5,-0.01,2,0.002,-2]; l=0.7;
    //   print(sqrt(c[0]+c[1]*l**c[2]/(l**2-c[3]**c[4])+c[5]*l**c[6]/(l**2-c[7]**c[8])+c[9]*l**c[10]+c[11]*l**c[12]))"
    let n = n_of_formula(4, "0.5 1.0", "2.0 0.5 2 0.25 2 0.1 2 4.0 1.5 -0.01 2 0.002 -2", 700.0);
    assert!(close(n, 1.6017978692819415, TOL), "{n}");
}

#[test]
fn formula_5_cauchy() {
    // PVP (König 2014): python3 -c "l=0.55; print(1.5151+0.00279*l**-2+5.0756e-4*l**-4)"
    let n = n_of_formula(5, "0.375 1", "1.5151 0.00279 -2 5.0756E-4 -4", 550.0);
    assert!(close(n, 1.5298698654463492, TOL), "{n}");
}

#[test]
fn formula_6_gases() {
    // Argon, Bideau-Mehu: python3 -c "c=[0,2.50141e-3,91.012,5.00283e-4,87.892,5.22343e-2,214.02]; l=0.5;
    //                                 print(1+c[0]+sum(c[i]/(c[i+1]-l**-2) for i in (1,3,5)))"
    let n = n_of_formula(6, "0.1404 0.5677", "0 2.50141e-3 91.012 5.00283e-4 87.892 5.22343e-2 214.02", 500.0);
    assert!(close(n, 1.000283422366243, TOL), "{n}");
}

#[test]
fn formula_7_herzberger() {
    // Si, Edwards (5 coefficients, C5 = 0): python3 -c "c=[3.41983,0.159906,-0.123109,1.26878E-6,-1.95104E-9,0]; l=5.0;
    //   print(c[0]+c[1]/(l**2-0.028)+c[2]/(l**2-0.028)**2+c[3]*l**2+c[4]*l**4+c[5]*l**6)"
    let n = n_of_formula(7, "2.4373 25", "3.41983 0.159906 -0.123109 1.26878E-6 -1.95104E-9", 5000.0);
    assert!(close(n, 3.4260664955562214, TOL), "{n}");
    // All six terms: same one-liner with c=[1.5,0.004,0.0001,-0.002,0.00001,-1e-7]; l=0.6
    let n = n_of_formula(7, "0.4 1.0", "1.5 0.004 0.0001 -0.002 0.00001 -1e-7", 600.0);
    assert!(close(n, 1.5122367275370419, TOL), "{n}");
}

#[test]
fn formula_8_retro() {
    // AgBr, Schröter: python3 -c "from math import sqrt; c=[0.452505,0.09939,0.070537,-0.000150]; l=0.6;
    //   r=c[0]+c[1]*l**2/(l**2-c[2])+c[3]*l**2; print(sqrt((1+2*r)/(1-r)))"
    let n = n_of_formula(8, "0.495 0.67", "0.452505 0.09939 0.070537 -0.000150", 600.0);
    assert!(close(n, 2.2531051408242906, TOL), "{n}");
}

#[test]
fn formula_9_exotic() {
    // Urea (e), Rosker: python3 -c "from math import sqrt; c=[2.51527,0.0240,0.0300,0.020,1.52,0.8771]; l=0.8;
    //   print(sqrt(c[0]+c[1]/(l**2-c[2])+c[3]*(l-c[4])/((l-c[4])**2+c[5])))"
    let n = n_of_formula(9, "0.3 1.06", "2.51527 0.0240 0.0300 0.020 1.52 0.8771", 800.0);
    assert!(close(n, 1.5950847564233002, TOL), "{n}");
}

#[test]
fn formula_negative_n_squared_is_an_error_not_nan() {
    // Polynomial n² = -1 + 0·…: no real index.
    let s = IndexSpectrum::parse(&formula_file(3, "0.4 1.0", "-1 0.1 2"), "neg.yml").unwrap();
    let e = s.at(500.0, Extrapolation::None).unwrap_err();
    assert!(matches!(e, IndexError::NonPhysical { .. }), "{e}");
    assert!(e.to_string().contains("neg.yml"));
}

#[test]
fn formula_with_too_many_coefficients_is_an_error() {
    let e = IndexSpectrum::parse(&formula_file(8, "0.4 1.0", "1 2 3 4 5"), "f8.yml").unwrap_err();
    assert!(matches!(e, IndexError::Format { .. }), "{e}");
    assert!(e.to_string().contains("at most 4"), "{e}");
}

// Rows quoted from the shipped files (data/refractiveindex/*.yml).
#[test]
fn shipped_tables_exact_at_nodes() {
    let cases: &[(&str, f64, f64, f64)] = &[
        // name, λ nm, n, κ — row "λ(µm) n κ" of the file
        ("PC_Zhang2020", 400.0, 1.63389, 1.12e-5),
        ("PC_Zhang2020", 550.0, 1.59509, 4.08e-7),
        ("PC_Zhang2020", 790.0, 1.57772, 1.97e-9),
        ("PDMS_Zhang2020_20-1", 550.0, 1.40929, 9.16e-7),
        ("PDMS_Zhang2020_20-1", 780.0, 1.40201, 8.32e-7),
        ("PMMA_Zhang2020_Mitsubishi", 550.0, 1.49463, 1.74e-7),
        ("PMMA_Zhang2020_Mitsubishi", 410.0, 1.50670, 2.12e-7),
        ("TiO2_Siefke2016", 552.505141, 2.434019934, 4.81e-8),
        ("TiO2_Siefke2016", 380.046138, 2.773411776, 0.003973052),
        ("PDMS_Gupta", 550.0, 1.412946, 0.0),
    ];
    for &(name, wl, n, k) in cases {
        let s = IndexSpectrum::builtin(name).unwrap();
        let v = s.at(wl, Extrapolation::None).unwrap();
        assert!(close(v.index.re, n, 1e-15), "{name} {wl}: n {} vs {n}", v.index.re);
        assert!(close(v.index.im, k, 1e-15), "{name} {wl}: k {} vs {k}", v.index.im);
        assert!(!v.extrapolated);
    }
}

#[test]
fn shipped_tables_interpolate_linearly_between_nodes() {
    // Midpoints: the mean of the two rows.
    let cases: &[(&str, f64, [f64; 2], [f64; 2])] = &[
        ("PC_Zhang2020", 405.0, [1.63389, 1.62840], [1.12e-5, 2.28e-6]),
        ("PC_Zhang2020", 785.0, [1.57701, 1.57772], [5.95e-9, 1.97e-9]),
        ("PDMS_Zhang2020_20-1", 405.0, [1.42109, 1.41984], [9.29e-7, 9.08e-7]),
        ("PMMA_Zhang2020_Mitsubishi", 795.0, [1.48609, 1.48555], [1.13e-7, 9.92e-8]),
        ("PVP_Konig2014", 562.5, [f64::NAN, f64::NAN], [0.00227814062415041, 0.00213575411562198]),
    ];
    for &(name, wl, n, k) in cases {
        let v = IndexSpectrum::builtin(name).unwrap().at(wl, Extrapolation::None).unwrap();
        if !n[0].is_nan() {
            assert!(close(v.index.re, 0.5 * (n[0] + n[1]), 1e-12), "{name} {wl}: n {}", v.index.re);
        }
        assert!(close(v.index.im, 0.5 * (k[0] + k[1]), 1e-12), "{name} {wl}: k {}", v.index.im);
    }
    // A quarter of the way: 0.5525 µm between TiO2 rows 0.549333803 and 0.552505141
    // is not a node; check the linear formula with the rows themselves.
    let (w0, n0, w1, n1) = (0.549333803, 2.436329289, 0.552505141, 2.434019934);
    let x = w0 + 0.25 * (w1 - w0);
    let v = IndexSpectrum::builtin("TiO2_Siefke2016").unwrap().at(x * 1000.0, Extrapolation::None).unwrap();
    assert!(close(v.index.re, n0 + 0.25 * (n1 - n0), 1e-12), "{}", v.index.re);
}

#[test]
fn builtin_ranges() {
    let expected: &[(&str, f64, f64)] = &[
        ("PC_Zhang2020", 400.0, 19942.0),
        ("PC_Sultanova2009", 436.8, 1052.0),
        ("TiO2_Siefke2016", 120.181141, 125122.7623),
        ("PDMS_Zhang2020_5-1", 400.0, 19942.0),
        ("PDMS_Zhang2020_10-1", 400.0, 19942.0),
        ("PDMS_Zhang2020_15-1", 400.0, 19942.0),
        ("PDMS_Zhang2020_20-1", 400.0, 19942.0),
        ("PDMS_Gupta", 300.0, 1690.0),
        ("PDMS_Schneider-Sylgard184", 350.0, 700.0),
        ("PVP_Konig2014", 375.0, 1000.0),
        ("PMMA_Zhang2020_Mitsubishi", 400.0, 19942.0),
        ("PMMA_Zhang2020_Tomson", 400.0, 19942.0),
    ];
    assert_eq!(expected.len(), BUILTIN_NAMES.len());
    for &(name, lo, hi) in expected {
        let s = IndexSpectrum::builtin(name).unwrap();
        assert_eq!(s.source(), format!("builtin:{name}"));
        assert_eq!(s.range_nm(), (lo, hi), "{name}");
        // Both ends are inside (tolerance for nm ↔ µm rounding).
        assert!(!s.at(lo, Extrapolation::None).unwrap().extrapolated, "{name}");
        assert!(!s.at(hi, Extrapolation::None).unwrap().extrapolated, "{name}");
    }
}

#[test]
fn every_data_file_is_built_in() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/refractiveindex");
    let mut stems: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "yml").then(|| p.file_stem().unwrap().to_string_lossy().into_owned())
        })
        .collect();
    stems.sort();
    let mut names: Vec<String> = BUILTIN_NAMES.iter().map(|s| s.to_string()).collect();
    names.sort();
    assert_eq!(stems, names);
    let files: Vec<&str> = BUILTIN_FILES.iter().map(|(n, _)| *n).collect();
    assert_eq!(files, BUILTIN_NAMES);
    for (name, text) in BUILTIN_FILES {
        // The embedded text is the file on disk, and it parses.
        assert_eq!(std::fs::read_to_string(dir.join(format!("{name}.yml"))).unwrap(), *text);
        IndexSpectrum::builtin(name).unwrap();
    }
}

#[test]
fn unknown_builtin_lists_valid_names() {
    let e = IndexSpectrum::builtin("PC_Zhang").unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains("PC_Zhang"), "{msg}");
    for name in BUILTIN_NAMES {
        assert!(msg.contains(name), "{msg}");
    }
}

#[test]
fn pvp_combines_formula_n_and_table_k() {
    let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
    // Wavelengths on and between table nodes.
    for wl in [375.0, 400.0, 550.0, 562.5, 733.0, 1000.0] {
        let v = pvp.at(wl, Extrapolation::None).unwrap();
        let l: f64 = wl / 1000.0;
        let n = 1.5151 + 0.00279 * l.powi(-2) + 5.0756e-4 * l.powi(-4);
        assert!(close(v.index.re, n, 1e-13), "{wl}: {} vs {n}", v.index.re);
    }
    // κ from the table (row "0.55 1.52986391503313 0.00227814062415041");
    // the table's n (1.52986…) is not used.
    let v = pvp.at(550.0, Extrapolation::None).unwrap();
    assert_eq!(v.index.im, 0.00227814062415041);
    assert!((v.index.re - 1.52986391503313).abs() > 1e-6);
}

#[test]
fn out_of_range_error_names_file_wavelength_and_range() {
    let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
    let e = pc.at(380.0, Extrapolation::None).unwrap_err();
    let msg = e.to_string();
    assert!(matches!(e, IndexError::OutOfRange { .. }));
    assert!(msg.contains("builtin:PC_Zhang2020"), "{msg}");
    assert!(msg.contains("380 nm"), "{msg}");
    assert!(msg.contains("400–19942 nm"), "{msg}");
    let e = pc.at(25_000.0, Extrapolation::None).unwrap_err();
    assert!(e.to_string().contains("400–19942 nm"), "{e}");

    let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
    let msg = pvp.at(1100.0, Extrapolation::None).unwrap_err().to_string();
    assert!(msg.contains("375–1000 nm") && msg.contains("1100 nm"), "{msg}");
}

#[test]
fn invalid_wavelengths_are_errors() {
    let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
    for wl in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -550.0] {
        for mode in [Extrapolation::None, Extrapolation::Clamp, Extrapolation::Linear] {
            let e = pc.at(wl, mode).unwrap_err();
            assert!(matches!(e, IndexError::InvalidWavelength { .. }), "{e}");
        }
    }
    let e = pc.clone().with_real_part_at(f64::NAN, 1.5, RealPartCorrection::Shift).unwrap_err();
    assert!(matches!(e, IndexError::InvalidWavelength { .. }), "{e}");
}

#[test]
fn clamp_holds_end_values_and_reports_extrapolation() {
    let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
    for wl in [380.0, 390.0, 399.0] {
        let v = pc.at(wl, Extrapolation::Clamp).unwrap();
        assert_eq!(v.index, Complex64::new(1.63389, 1.12e-5));
        assert!(v.extrapolated);
    }
    let v = pc.at(24_000.0, Extrapolation::Clamp).unwrap();
    assert_eq!(v.index, Complex64::new(1.62390, 2.13e-2)); // last row "19.942 1.62390 2.13E-02"
    assert!(v.extrapolated);
    // Inside the range nothing changes and nothing is reported.
    let v = pc.at(550.0, Extrapolation::Clamp).unwrap();
    assert_eq!(v.index, Complex64::new(1.59509, 4.08e-7));
    assert!(!v.extrapolated);
    // Formula n clamps to the formula at the range end.
    let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
    let v = pvp.at(1100.0, Extrapolation::Clamp).unwrap();
    assert!(close(v.index.re, 1.5151 + 0.00279 + 5.0756e-4, 1e-13));
    assert_eq!(v.index.im, 0.00116809325380068);
    assert!(v.extrapolated);
}

#[test]
fn linear_extends_end_segments_and_reports_extrapolation() {
    let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
    let v = pc.at(380.0, Extrapolation::Linear).unwrap();
    // python3 -c "x=0.38; print(1.63389+(x-0.40)*(1.62840-1.63389)/0.01, 1.12e-5+(x-0.40)*(2.28e-6-1.12e-5)/0.01)"
    //   -> 1.64487 2.904e-05
    assert!(close(v.index.re, 1.64487, 1e-12), "{}", v.index.re);
    assert!(close(v.index.im, 2.904e-5, 1e-12), "{}", v.index.im);
    assert!(v.extrapolated);

    // PVP at 1100 nm: formula evaluated outside its range, κ from the last
    // table segment (0.975, 1.0):
    // python3 -c "l=1.1; print(1.5151+0.00279*l**-2+5.0756e-4*l**-4,
    //   0.00116809325380068+(l-1)*(0.00116809325380068-0.00119280393490076)/0.025)"
    let v = IndexSpectrum::builtin("PVP_Konig2014").unwrap().at(1100.0, Extrapolation::Linear).unwrap();
    assert!(close(v.index.re, 1.517752455433372, 1e-13), "{}", v.index.re);
    assert!(close(v.index.im, 0.0010692505294003598, 1e-10), "{}", v.index.im);
    assert!(v.extrapolated);
}

#[test]
fn linear_kappa_is_clamped_at_zero() {
    let text = "DATA:\n  - type: tabulated nk\n    data: |\n        0.5 1.5 0.001\n        0.6 1.4 0.0005\n";
    let s = IndexSpectrum::parse(text, "k.yml").unwrap();
    // κ line reaches 0 at 0.7 µm; n = 1.5 - (x - 0.5) (per µm).
    let v = s.at(740.0, Extrapolation::Linear).unwrap();
    assert_eq!(v.index.im, 0.0);
    assert!(close(v.index.re, 1.26, 1e-12), "{}", v.index.re);
    assert!(v.extrapolated);
    // A non-physical n from linear extrapolation is an error: n = 1.5 − 10 (x − 0.5) < 0 at 0.7 µm.
    let steep = "DATA:\n  - type: tabulated nk\n    data: |\n        0.5 1.5 0.001\n        0.6 0.5 0.0005\n";
    let s = IndexSpectrum::parse(steep, "steep.yml").unwrap();
    let e = s.at(700.0, Extrapolation::Linear).unwrap_err();
    assert!(matches!(e, IndexError::NonPhysical { .. }), "{e}");
}

#[test]
fn extrapolation_reaches_a_quarter_of_the_range_end() {
    // PC_Zhang2020 covers 400–19942 nm: clamping reaches 300–24927.5 nm.
    let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
    for mode in [Extrapolation::Clamp, Extrapolation::Linear] {
        assert!(pc.at(301.0, mode).is_ok());
        for wl in [299.0, 25_000.0, 1e9] {
            let e = pc.at(wl, mode).unwrap_err();
            assert!(matches!(e, IndexError::TooFarOutside { .. }), "{e}");
            let text = e.to_string();
            assert!(text.contains("PC_Zhang2020") && text.contains("300–24927.5 nm"), "{text}");
        }
    }
    // Without extrapolation the plain out-of-range error stays.
    assert!(matches!(pc.at(1e9, Extrapolation::None).unwrap_err(), IndexError::OutOfRange { .. }));
}

#[test]
fn shift_sets_n_at_550_and_keeps_kappa() {
    let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
    let host = pc.clone().with_real_part_at(550.0, 1.5889, RealPartCorrection::Shift).unwrap();
    assert_eq!(host.at(550.0, Extrapolation::None).unwrap().index, Complex64::new(1.5889, 4.08e-7));
    // Elsewhere: table n + (1.5889 − 1.59509), κ unchanged (row "0.60 1.58873 4.80E-07").
    let v = host.at(600.0, Extrapolation::None).unwrap();
    assert!(close(v.index.re, 1.58873 + (1.5889 - 1.59509), 1e-12), "{}", v.index.re);
    assert_eq!(v.index.im, 4.8e-7);
    for wl in [400.0, 455.0, 700.0, 780.0] {
        let a = pc.at(wl, Extrapolation::None).unwrap().index;
        let b = host.at(wl, Extrapolation::None).unwrap().index;
        assert_eq!(a.im, b.im);
        assert!(close(b.re - a.re, 1.5889 - 1.59509, 1e-12));
    }
    // Range and extrapolation behaviour unchanged.
    assert_eq!(host.range_nm(), pc.range_nm());
    assert!(host.at(380.0, Extrapolation::None).is_err());
    let v = host.at(380.0, Extrapolation::Clamp).unwrap();
    assert!(close(v.index.re, 1.63389 + (1.5889 - 1.59509), 1e-12) && v.extrapolated);
    // A second shift replaces the first.
    let again = host.with_real_part_at(400.0, 1.6, RealPartCorrection::Shift).unwrap();
    assert_eq!(again.at(400.0, Extrapolation::None).unwrap().index.re, 1.6);
    assert!(close(again.at(550.0, Extrapolation::None).unwrap().index.re, 1.6 + (1.59509 - 1.63389), 1e-12));
}

#[test]
fn shift_of_a_formula_and_replace() {
    let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
    let shifted = pvp.clone().with_real_part_at(500.0, 1.55, RealPartCorrection::Shift).unwrap();
    assert_eq!(shifted.at(500.0, Extrapolation::None).unwrap().index.re, 1.55);

    let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
    let flat = pc.clone().with_real_part_at(550.0, 1.5889, RealPartCorrection::Replace).unwrap();
    for wl in [400.0, 550.0, 777.0] {
        let v = flat.at(wl, Extrapolation::None).unwrap();
        assert_eq!(v.index.re, 1.5889);
        assert_eq!(v.index.im, pc.at(wl, Extrapolation::None).unwrap().index.im);
    }
    // The valid range stays that of the data.
    assert!(flat.at(380.0, Extrapolation::None).is_err());
    assert_eq!(flat.at(380.0, Extrapolation::Clamp).unwrap().index, Complex64::new(1.5889, 1.12e-5));
}

#[test]
fn bad_corrections_are_errors() {
    let pc = IndexSpectrum::builtin("PC_Zhang2020").unwrap();
    for n in [f64::NAN, 0.0, -1.5, f64::INFINITY] {
        let e = pc.clone().with_real_part_at(550.0, n, RealPartCorrection::Shift).unwrap_err();
        assert!(matches!(e, IndexError::InvalidCorrection { .. }), "{e}");
    }
    // Shift needs n at a wavelength where n is valid.
    let e = pc.with_real_part_at(380.0, 1.6, RealPartCorrection::Shift).unwrap_err();
    assert!(matches!(e, IndexError::OutOfRange { .. }) && e.to_string().contains("400–19942 nm"), "{e}");
}

#[test]
fn imaginary_part_overrides() {
    let pvp = IndexSpectrum::builtin("PVP_Konig2014").unwrap();
    let raw = pvp.at(550.0, Extrapolation::None).unwrap().index;
    assert!((raw.im - 0.00227814062415041).abs() < 1e-15, "{raw}"); // the table row at 0.55 µm
    let clear = pvp.clone().with_imaginary_part(ImaginaryPartCorrection::Replace { kappa: 0.0 }).unwrap();
    let scaled = pvp.clone().with_imaginary_part(ImaginaryPartCorrection::Scale { factor: 0.5 }).unwrap();
    for w in [400.0, 550.0, 700.0] {
        let (r, c, h) = (
            pvp.at(w, Extrapolation::None).unwrap().index,
            clear.at(w, Extrapolation::None).unwrap().index,
            scaled.at(w, Extrapolation::None).unwrap().index,
        );
        assert_eq!((c.re, c.im), (r.re, 0.0), "{w}: n kept, κ replaced");
        assert_eq!((h.re, h.im), (r.re, 0.5 * r.im), "{w}: n kept, κ halved");
    }
    // Replaced κ no longer needs the κ table: PC's κ starts at 400 nm like
    // its n, so use a file whose κ range is narrower than its n range.
    let narrow = "DATA:\n  - type: tabulated n\n    data: |\n        0.3 1.5\n        1.0 1.5\n  - type: tabulated k\n    data: |\n        0.5 1e-3\n        0.6 1e-3\n";
    let s = IndexSpectrum::parse(narrow, "narrow").unwrap();
    assert_eq!(s.range_nm(), (500.0, 600.0));
    assert!(s.at(400.0, Extrapolation::None).is_err());
    let s = s.with_imaginary_part(ImaginaryPartCorrection::Replace { kappa: 2e-4 }).unwrap();
    assert_eq!(s.range_nm(), (300.0, 1000.0));
    let sample = s.at(400.0, Extrapolation::None).unwrap();
    assert_eq!(sample.index, Complex64::new(1.5, 2e-4));
    assert!(!sample.extrapolated);
    for bad in [-1e-3, f64::NAN, f64::INFINITY] {
        for c in [ImaginaryPartCorrection::Replace { kappa: bad }, ImaginaryPartCorrection::Scale { factor: bad }] {
            let e = pvp.clone().with_imaginary_part(c).unwrap_err();
            assert!(matches!(e, IndexError::InvalidImaginaryCorrection { .. }) && e.to_string().contains("PVP"), "{e}");
        }
    }
}

#[test]
fn serde_names() {
    #[derive(Deserialize)]
    struct T {
        e: Vec<Extrapolation>,
        c: Vec<RealPartCorrection>,
    }
    let t: T = serde_yaml_ng::from_str("e: [none, clamp, linear]\nc: [shift, replace]\n").unwrap();
    assert_eq!(t.e, [Extrapolation::None, Extrapolation::Clamp, Extrapolation::Linear]);
    assert_eq!(t.c, [RealPartCorrection::Shift, RealPartCorrection::Replace]);
    assert!(serde_yaml_ng::from_str::<Extrapolation>("nearest").is_err());
    assert_eq!(Extrapolation::default(), Extrapolation::None);
}

#[test]
fn load_names_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.yml");
    let e = IndexSpectrum::load(&missing).unwrap_err();
    assert!(matches!(e, IndexError::Read { .. }));
    assert!(e.to_string().contains("missing.yml"), "{e}");

    let path = dir.path().join("pvp.yml");
    std::fs::write(&path, BUILTIN_FILES[9].1).unwrap();
    let s = IndexSpectrum::load(&path).unwrap();
    assert_eq!(s.source(), path.display().to_string());

    let bad = dir.path().join("bad.yml");
    std::fs::write(&bad, "DATA:\n  - type: tabulated n\n    data: |\n        0.5 1.5\n        0.6 x1.4\n").unwrap();
    let msg = IndexSpectrum::load(&bad).unwrap_err().to_string();
    assert!(msg.contains("bad.yml") && msg.contains("x1.4"), "{msg}");
}

fn parse_err(text: &str) -> IndexError {
    match IndexSpectrum::parse(text, "user.yml") {
        Ok(s) => panic!("expected an error, parsed {s:?}"),
        Err(e) => {
            assert!(e.to_string().contains("user.yml"), "error does not name the file: {e}");
            e
        }
    }
}

#[test]
fn malformed_yaml_is_an_error() {
    for text in [
        "DATA: [\n",
        "DATA:\n  - type: tabulated nk\n   data: |\n  bad indent",
        "",
        "just a string",
        "DATA: 3",
        "DATA:\n  - [1, 2]\n",
        "\u{0}\u{1}binary",
    ] {
        let e = parse_err(text);
        assert!(matches!(e, IndexError::Yaml { .. } | IndexError::Format { .. }), "{text:?}: {e}");
    }
    assert!(matches!(parse_err("REFERENCES: x\n"), IndexError::Format { .. }));
    assert!(matches!(parse_err("DATA: []\n"), IndexError::Format { .. }));
}

#[test]
fn unknown_type_is_an_error() {
    for kind in ["tabulated n2", "formula 10", "formula 0", "formula", "formula x", "sellmeier", "tabulated"] {
        let text = format!("DATA:\n  - type: {kind}\n    data: |\n        0.5 1.5\n        0.6 1.4\n");
        let e = parse_err(&text);
        assert!(matches!(e, IndexError::UnknownType { .. }), "{kind}: {e}");
        assert!(e.to_string().contains(kind), "{e}");
    }
    // Even in a later, unused entry.
    let text = "DATA:\n  - type: tabulated n\n    data: |\n        0.5 1.5\n        0.6 1.4\n  - type: tabulated q\n    data: '0.5 1'\n";
    assert!(matches!(parse_err(text), IndexError::UnknownType { .. }));
}

#[test]
fn bad_number_reports_the_file_line() {
    let text = "# comment\nDATA:\n  - type: tabulated nk\n    data: |\n        0.40 1.63 1e-5\n        0.41 1,62 1e-5\n        0.42 1.61 1e-5\n";
    let e = parse_err(text);
    assert!(matches!(e, IndexError::BadNumber { .. }), "{e}");
    let msg = e.to_string();
    assert!(msg.contains("line 6") && msg.contains("'1,62'"), "{msg}");

    let e = parse_err(&formula_file(5, "0.4 1.0", "1.5 0.003 -2 oops -4"));
    assert!(matches!(e, IndexError::BadNumber { .. }), "{e}");
    assert!(e.to_string().contains("line 5") && e.to_string().contains("oops"), "{e}");

    let e = parse_err(&formula_file(5, "0.4 one", "1.5"));
    assert!(matches!(e, IndexError::BadNumber { .. }), "{e}");
    assert!(matches!(parse_err(&formula_file(5, "0.4", "1.5")), IndexError::Format { .. }));
    assert!(matches!(parse_err(&formula_file(5, "1.0 0.4", "1.5")), IndexError::Format { .. }));
    assert!(matches!(parse_err(&formula_file(5, "0.4 1.0", "")), IndexError::Format { .. }));
    // Wrong number of columns.
    let e = parse_err("DATA:\n  - type: tabulated nk\n    data: |\n        0.5 1.5\n        0.6 1.4\n");
    assert!(matches!(e, IndexError::Format { .. }) && e.to_string().contains("line 4"), "{e}");
}

#[test]
fn nan_and_negative_values_are_errors() {
    for (row, quantity) in [
        ("0.55 nan 1e-6", "n"),
        ("0.55 1.5 NaN", "k"),
        ("0.55 inf 1e-6", "n"),
        ("0.55 -1.5 1e-6", "n"),
        ("0.55 1.5 -1e-6", "k"),
        ("nan 1.5 1e-6", "wavelength"),
        ("-0.55 1.5 1e-6", "wavelength"),
        ("0 1.5 1e-6", "wavelength"),
    ] {
        let text = format!(
            "DATA:\n  - type: tabulated nk\n    data: |\n        0.50 1.5 1e-6\n        {row}\n        0.60 1.5 1e-6\n"
        );
        let e = parse_err(&text);
        match &e {
            IndexError::InvalidValue { quantity: q, .. } => assert!(q.starts_with(quantity), "{row}: {e}"),
            _ => panic!("{row}: {e}"),
        }
        assert!(e.to_string().contains("line 5"), "{e}");
    }
    assert!(matches!(parse_err(&formula_file(1, "0.4 1.0", "0 nan 0.1")), IndexError::InvalidValue { .. }));
    assert!(matches!(parse_err(&formula_file(1, "nan 1.0", "0 1 0.1")), IndexError::InvalidValue { .. }));
}

#[test]
fn table_shape_errors() {
    let e = parse_err("DATA:\n  - type: tabulated nk\n    data: |\n        0.5 1.5 0.1\n");
    assert!(matches!(e, IndexError::TooFewRows { rows: 1, .. }), "{e}");
    let e = parse_err("DATA:\n  - type: tabulated k\n    data: ''\n");
    assert!(matches!(e, IndexError::TooFewRows { rows: 0, .. }), "{e}");
    let e = parse_err("DATA:\n  - type: tabulated n\n    data: |\n        0.5 1.5\n        0.6 1.5\n        0.6 1.4\n");
    assert!(matches!(e, IndexError::NonIncreasing { .. }) && e.to_string().contains("line 6"), "{e}");
    let e = parse_err("DATA:\n  - type: tabulated n\n    data: |\n        0.6 1.5\n        0.5 1.4\n");
    assert!(matches!(e, IndexError::NonIncreasing { .. }), "{e}");
    let e = parse_err("DATA:\n  - type: tabulated n\n");
    assert!(matches!(e, IndexError::Format { .. }), "{e}");
}

#[test]
fn k_only_file_has_no_real_part() {
    let e = parse_err("DATA:\n  - type: tabulated k\n    data: |\n        0.5 0.1\n        0.6 0.2\n");
    assert!(matches!(e, IndexError::NoRealPart { .. }), "{e}");
}

#[test]
fn separate_n_and_k_entries_and_first_wins() {
    // n from a formula (0.4–1.0 µm), k from a table (0.5–2.0 µm), then a
    // second n table that must be ignored.
    let text = "DATA:\n  - type: formula 5\n    wavelength_range: 0.4 1.0\n    coefficients: 1.5\n  - type: tabulated k\n    data: |\n        0.5 0.1\n        2.0 0.4\n  - type: tabulated n\n    data: |\n        0.3 9\n        3.0 9\n";
    let s = IndexSpectrum::parse(text, "mix.yml").unwrap();
    assert_eq!(s.range_nm(), (500.0, 1000.0));
    let v = s.at(800.0, Extrapolation::None).unwrap();
    assert_eq!(v.index.re, 1.5);
    assert!(close(v.index.im, 0.16, 1e-12), "{}", v.index.im); // 0.1 + (0.8 − 0.5)·(0.4 − 0.1)/1.5
                                                               // 450 nm: n valid, k not.
    let e = s.at(450.0, Extrapolation::None).unwrap_err();
    assert!(e.to_string().contains("500–2000 nm of the κ data"), "{e}");
    let v = s.at(450.0, Extrapolation::Clamp).unwrap();
    assert_eq!(v.index, Complex64::new(1.5, 0.1));
    assert!(v.extrapolated);
    // Only n data: κ = 0 and the range is n's.
    let s = IndexSpectrum::parse(&formula_file(5, "0.4 1.0", "1.5"), "n.yml").unwrap();
    assert_eq!(s.range_nm(), (400.0, 1000.0));
    assert_eq!(s.at(400.0, Extrapolation::None).unwrap().index, Complex64::new(1.5, 0.0));
}

#[test]
fn numbers_as_yaml_scalars_and_other_keys_are_accepted() {
    // A single coefficient written as a YAML number, the old `range` key,
    // unrelated keys, CRLF line ends.
    let text = "REFERENCES: x\r\nCONDITIONS:\r\n    temperature: 293\r\nDATA:\r\n  - type: formula 5\r\n    range: 0.4 1.0\r\n    coefficients: 1.25\r\nPROPERTIES: {}\r\n";
    let s = IndexSpectrum::parse(text, "crlf.yml").unwrap();
    assert_eq!(s.at(700.0, Extrapolation::None).unwrap().index.re, 1.25);
}
