//! `lucent::surface` and `lucent surface`: synthetic random surfaces with
//! known slope statistics recovered (α within 5 %, the right model), tilt,
//! the X3P writer read back (all four point types, masks, DataList, nested
//! folder), text/TIFF/EXR readers, the plane fit, S_q and S_dq against the
//! numpy/surfalize/x3pio references in fixtures/reference/surface, the
//! normalisation of D, the recipe's `[surface] fit = …`, the CLI end to end,
//! and the malformed inputs of tests/bad/surface.

use crate::common;
use common::{lucent, stderr, stdout};

use lucent::optics::recipe::{Overrides, Recipe};
use lucent::surface::fit::d_model;
use lucent::surface::model::RoughnessModel;
use lucent::surface::normals::{fit_plane, plane_fit_normals, roughness};
use lucent::surface::synth::{synthesize, SynthSpec};
use lucent::surface::x3p::{read_x3p, read_x3p_bytes, write_x3p, x3p_bytes, PointType, WriteOptions};
use lucent::surface::{fit_surface, read_height_map, FitOptions, HeightMap, LengthUnit, ReadOptions};
use serde_json::Value;
use std::f64::consts::PI;
use std::io::Write;
use std::path::{Path, PathBuf};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn json(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))).unwrap()
}

fn name(m: RoughnessModel) -> &'static str {
    match m {
        RoughnessModel::TrowbridgeReitz => "TR",
        RoughnessModel::Beckmann => "Beckmann",
    }
}

// ------------------------------------------------------------ synthetic surfaces

/// The designed slopes of the generator follow the closed-form radial CDFs
/// of the two models: P(|∇h| < t) = 1 − exp(−t²/α²) (Beckmann) and
/// t²/(α² + t²) (GGX). Kolmogorov distance over the pixels (correlated, so
/// the bound is loose but far below the distance between the two models).
#[test]
fn generator_slopes_follow_the_closed_forms() {
    for model in [RoughnessModel::Beckmann, RoughnessModel::TrowbridgeReitz] {
        let alpha = 0.02;
        let s = synthesize(&SynthSpec { nx: 512, ny: 512, alpha, model, seed: 11, ..SynthSpec::default() }).unwrap();
        let mut t: Vec<f64> = s.slope_x.iter().zip(&s.slope_y).map(|(x, y)| x.hypot(*y)).collect();
        t.sort_by(f64::total_cmp);
        let n = t.len() as f64;
        let cdf = |m: RoughnessModel, v: f64| match m {
            RoughnessModel::Beckmann => 1.0 - (-(v * v) / (alpha * alpha)).exp(),
            RoughnessModel::TrowbridgeReitz => v * v / (alpha * alpha + v * v),
        };
        let ks = |m: RoughnessModel| {
            t.iter().enumerate().map(|(k, v)| ((k as f64 + 0.5) / n - cdf(m, *v)).abs()).fold(0.0, f64::max)
        };
        let other =
            if model == RoughnessModel::Beckmann { RoughnessModel::TrowbridgeReitz } else { RoughnessModel::Beckmann };
        let (own, cross) = (ks(model), ks(other));
        println!("{}: KS distance to own CDF {own:.4}, to the other model's {cross:.4}", name(model));
        assert!(own < 0.02, "{}: KS {own}", name(model));
        assert!(cross > 0.08, "{}: KS to the other model {cross}", name(model));
    }
}

/// α from 0.002 to 0.3, Beckmann- and TR-like, 768² and 1024² maps (ℓ = 8 px,
/// TR amplitude correlation 32 px): α within 5 % of the generator's, and the
/// right model chosen. Expected deviations: −1.5 % from the plane fit's
/// smoothing (ℓ²/(ℓ² + σ²)), and ±2–3 % (TR) or ±1.5 % (Beckmann) of
/// realisation noise, measured over seeds.
#[test]
fn synthetic_surfaces_are_recovered() {
    let mut worst: f64 = 0.0;
    for model in [RoughnessModel::Beckmann, RoughnessModel::TrowbridgeReitz] {
        // Beckmann's Gaussian slopes need fewer points than TR's heavy tail.
        let n = if model == RoughnessModel::Beckmann { 768 } else { 1024 };
        for (k, alpha) in [0.002, 0.0084, 0.05, 0.3].into_iter().enumerate() {
            let spec = SynthSpec {
                nx: n,
                ny: n,
                alpha,
                model,
                correlation_px: 8.0,
                amplitude_correlation_px: 32.0,
                seed: 20 + k as u64,
                ..SynthSpec::default()
            };
            let map = synthesize(&spec).unwrap().map;
            let fit = fit_surface(&map, &FitOptions::default()).unwrap();
            let r = &fit.report;
            let got = r.fits.get(model);
            let err = got.alpha / alpha - 1.0;
            println!(
                "{:<8} α {alpha:<7} → TR α {:.5} (scale {:.3}, MSE {:.3e}), Beckmann α {:.5} (scale {:.3}, MSE {:.3e}); own error {:+.2} %",
                name(model),
                r.fits.trowbridge_reitz.alpha,
                r.fits.trowbridge_reitz.scale,
                r.fits.trowbridge_reitz.mse_per_sr2,
                r.fits.beckmann.alpha,
                r.fits.beckmann.scale,
                r.fits.beckmann.mse_per_sr2,
                100.0 * err
            );
            assert_eq!(r.better_model, model, "α {alpha}: wrong model chosen");
            assert!(err.abs() < 0.05, "{} α {alpha}: fitted {}", name(model), got.alpha);
            worst = worst.max(err.abs());
        }
    }
    println!("worst relative α error {:.2} %", 100.0 * worst);
}

/// A Beckmann surface (α 0.05) on a plane tilted by 2° whose normal points
/// to azimuth 30°: the global plane returns the tilt; without levelling, the
/// fit's tilt parameter returns it too; with levelling it is ≈ 0.
#[test]
fn tilted_surface_returns_its_tilt() {
    let spec = SynthSpec {
        nx: 384,
        ny: 384,
        alpha: 0.05,
        model: RoughnessModel::Beckmann,
        correlation_px: 10.0,
        seed: 5,
        tilt_rad: 2f64.to_radians(),
        tilt_azimuth_rad: 30f64.to_radians(),
        ..SynthSpec::default()
    };
    let map = synthesize(&spec).unwrap().map;
    // The random part has a best-fit plane of its own (a few 0.01°); least
    // squares is linear, so the tilted map's plane is that plane plus the added one.
    let own = fit_plane(&synthesize(&SynthSpec { tilt_rad: 0.0, ..spec }).unwrap().map).unwrap();
    let t = 2f64.to_radians().tan();
    let (ex, ey) = (own.slope_x - t * 30f64.to_radians().cos(), own.slope_y - t * 30f64.to_radians().sin());
    let (want_tilt, want_az) = (ex.hypot(ey).atan().to_degrees(), (-ey).atan2(-ex).to_degrees());
    let levelled = fit_surface(&map, &FitOptions { fit_tilt: true, ..FitOptions::default() }).unwrap().report;
    let g = &levelled.global_plane;
    println!(
        "global plane: tilt {:.5}° (expected {want_tilt:.5}°), normal azimuth {:.3}° (expected {want_az:.3}°)",
        g.tilt_deg, g.normal_azimuth_deg
    );
    assert!((g.tilt_deg - want_tilt).abs() < 1e-9 && (g.normal_azimuth_deg - want_az).abs() < 1e-7);
    assert!((g.tilt_deg - 2.0).abs() < 0.1 && (g.normal_azimuth_deg - 30.0).abs() < 3.0);
    let b = &levelled.fits.beckmann;
    println!("levelled, tilt fitted: α {:.5}, tilt {:.4}°", b.alpha, b.tilt_deg);
    assert!(b.tilt_deg < 0.3, "{}", b.tilt_deg);
    let kept =
        fit_surface(&map, &FitOptions { remove_tilt: false, fit_tilt: true, ..FitOptions::default() }).unwrap().report;
    let b = &kept.fits.beckmann;
    let d = &kept.distribution;
    println!(
        "not levelled: fitted tilt {:.4}°, α {:.5}; mean normal tilt {:.4}° azimuth {:.3}°",
        b.tilt_deg, b.alpha, d.mean_normal_tilt_deg, d.mean_normal_azimuth_deg
    );
    assert_eq!(kept.better_model, RoughnessModel::Beckmann);
    assert!((b.tilt_deg / want_tilt - 1.0).abs() < 0.05, "fitted tilt {} vs {want_tilt}", b.tilt_deg);
    assert!((b.alpha / 0.05 - 1.0).abs() < 0.05, "α {}", b.alpha);
    // The mean normal and the least-squares plane are different estimators of the tilt (mean local slope vs plane).
    assert!((d.mean_normal_tilt_deg - want_tilt).abs() < 0.05 && (d.mean_normal_azimuth_deg - want_az).abs() < 3.0);
}

/// Both model D's satisfy ∫ D(m)(m·n) dω = 1 (numerical quadrature), and
/// the measured histogram's Σ D Ω_proj is the fraction of normals in range.
#[test]
fn distributions_are_normalised() {
    for model in [RoughnessModel::Beckmann, RoughnessModel::TrowbridgeReitz] {
        for alpha in [0.003f64, 0.05, 0.3] {
            // ∫₀^{π/2} D cos θ sin θ dθ · 2π, substituting u = tan θ / α to resolve the peak.
            let n = 200_000;
            let umax: f64 = if model == RoughnessModel::Beckmann { 12.0 } else { 1e5 };
            let mut s = 0.0;
            for k in 0..n {
                // u on a log grid from 1e-6 to umax, midpoint rule in ln u.
                let (l0, l1) = ((1e-6f64).ln(), umax.ln());
                let lu = l0 + (l1 - l0) * (k as f64 + 0.5) / n as f64;
                let u = lu.exp();
                let theta = (alpha * u).atan();
                let dtheta_du = alpha / (1.0 + alpha * alpha * u * u);
                s += d_model(model, alpha, theta.cos()) * theta.cos() * theta.sin() * dtheta_du * u * (l1 - l0)
                    / n as f64;
            }
            let total = 2.0 * PI * s;
            let tail = if model == RoughnessModel::TrowbridgeReitz { 1.0 / (1.0 + umax * umax) } else { 0.0 };
            assert!((total + tail - 1.0).abs() < 1e-4, "{} α {alpha}: ∫ D cos dω = {total}", name(model));
        }
    }
    let map = synthesize(&SynthSpec { nx: 200, ny: 200, alpha: 0.02, ..SynthSpec::default() }).unwrap().map;
    let d = fit_surface(&map, &FitOptions::default()).unwrap().report.distribution;
    let total: f64 = d
        .d_per_sr
        .iter()
        .zip(d.edges_rad.windows(2))
        .map(|(v, e)| v * PI * (e[1].sin().powi(2) - e[0].sin().powi(2)))
        .sum();
    assert!((total - d.fraction_in_range).abs() < 1e-12 && d.fraction_in_range > 0.998, "{total}");
}

// ------------------------------------------------------------ readers

fn small_map() -> HeightMap {
    let (nx, ny) = (23, 17);
    let mut h: Vec<f64> = (0..nx * ny)
        .map(|k| {
            let (i, j) = ((k % nx) as f64, (k / nx) as f64);
            1e-7 * (0.3 * i).sin() + 4e-8 * (0.5 * j).cos() - 2e-8 + 1e-9 * i
        })
        .collect();
    for k in [0, 5, 100, 250, nx * ny - 1] {
        h[k] = f64::NAN;
    }
    HeightMap::new(nx, ny, 0.871e-6, 1.25e-6, h, "small").unwrap()
}

/// Written with every point type and read back: D exact, F to float32
/// rounding, I/L to half an increment; invalid points stay invalid.
#[test]
fn x3p_round_trip_for_every_point_type() {
    let dir = tempfile::tempdir().unwrap();
    let map = small_map();
    let max = map.heights_m.iter().filter(|h| h.is_finite()).fold(0.0f64, |a, h| a.max(h.abs()));
    for t in [PointType::D, PointType::F, PointType::L, PointType::I] {
        let p = dir.path().join(format!("m_{t:?}.x3p"));
        write_x3p(
            &p,
            &map,
            &WriteOptions { point_type: t, comment: Some("a <test> & more".into()), ..Default::default() },
        )
        .unwrap();
        let back = read_x3p(&p).unwrap();
        assert_eq!((back.nx, back.ny), (map.nx, map.ny));
        assert_eq!((back.pitch_x_m, back.pitch_y_m), (map.pitch_x_m, map.pitch_y_m));
        let tol = match t {
            PointType::D => 0.0,
            PointType::F => 1e-7 * max,
            PointType::L => 0.51 * max / i32::MAX as f64,
            PointType::I => 0.51 * max / i16::MAX as f64,
        };
        for (a, b) in map.heights_m.iter().zip(&back.heights_m) {
            assert_eq!(a.is_finite(), b.is_finite(), "{t:?}");
            if a.is_finite() {
                assert!((a - b).abs() <= tol, "{t:?}: {a} vs {b}");
            }
        }
        // Same map, same bytes.
        assert_eq!(
            std::fs::read(&p).unwrap(),
            x3p_bytes(
                &map,
                &WriteOptions { point_type: t, comment: Some("a <test> & more".into()), ..Default::default() }
            )
            .unwrap()
        );
    }
}

/// The archive's structure: main.xml's MD5 in md5checksum.hex, the point
/// file's and validity file's MD5 in main.xml, elements in the schema's order.
#[test]
fn x3p_archive_is_spec_conformant() {
    use md5::{Digest, Md5};
    use std::io::Read;
    let map = small_map();
    let bytes = x3p_bytes(&map, &WriteOptions { point_type: PointType::I, ..Default::default() }).unwrap();
    let mut zip = zip::ZipArchive::new(std::io::Cursor::new(&bytes)).unwrap();
    let mut read = |name: &str| {
        let mut v = Vec::new();
        zip.by_name(name).unwrap_or_else(|e| panic!("{name}: {e}")).read_to_end(&mut v).unwrap();
        v
    };
    let hex = |b: &[u8]| Md5::digest(b).iter().map(|x| format!("{x:02x}")).collect::<String>();
    let main = read("main.xml");
    let sum = String::from_utf8(read("md5checksum.hex")).unwrap();
    assert_eq!(sum, format!("{} *main.xml\n", hex(&main)));
    let data = read("bindata/data.bin");
    let valid = read("bindata/valid.bin");
    assert_eq!(data.len(), 2 * map.nx * map.ny);
    assert_eq!(valid.len(), (map.nx * map.ny).div_ceil(8));
    assert_eq!(valid[0] & 1, 0, "point 0 is invalid: bit 0 of byte 0 clear");
    assert_eq!(valid[0] & 2, 2);
    let xml = String::from_utf8(main).unwrap();
    assert!(xml.contains(&format!("<MD5ChecksumPointData>{}</MD5ChecksumPointData>", hex(&data))));
    assert!(xml.contains(&format!("<MD5ChecksumValidPoints>{}</MD5ChecksumValidPoints>", hex(&valid))));
    let order = [
        "<Record1>",
        "<Revision>",
        "<FeatureType>SUR",
        "<Axes>",
        "<CX>",
        "<AxisType>I",
        "<DataType>D",
        "<Increment>",
        "<CY>",
        "<CZ>",
        "<AxisType>A",
        "<DataType>I",
        "<Record2>",
        "<Date>",
        "<Instrument>",
        "<Manufacturer>",
        "<Model>",
        "<Serial>",
        "<Version>",
        "<ProbingSystem>",
        "<Type>Software",
        "<Identification>",
        "<Record3>",
        "<MatrixDimension>",
        "<SizeX>23",
        "<SizeY>17",
        "<SizeZ>1",
        "<DataLink>",
        "<PointDataLink>bindata/data.bin",
        "<MD5ChecksumPointData>",
        "<ValidPointsLink>bindata/valid.bin",
        "<MD5ChecksumValidPoints>",
        "<Record4>",
        "<ChecksumFile>md5checksum.hex",
    ];
    let mut at = 0;
    for tag in order {
        let k = xml[at..].find(tag).unwrap_or_else(|| panic!("{tag} missing or out of order in\n{xml}"));
        at += k + tag.len();
    }
    let doc = roxmltree::Document::parse(&xml).unwrap();
    assert_eq!(doc.root_element().tag_name().namespace(), Some("http://www.opengps.eu/2008/ISO5436_2"));
}

fn zip_of(members: &[(&str, Vec<u8>)]) -> Vec<u8> {
    let mut w = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for (n, b) in members {
        w.start_file(*n, zip::write::SimpleFileOptions::default()).unwrap();
        w.write_all(b).unwrap();
    }
    w.finish().unwrap().into_inner()
}

fn md5_hex(b: &[u8]) -> String {
    use md5::{Digest, Md5};
    Md5::digest(b).iter().map(|x| format!("{x:02x}")).collect()
}

/// A DataList X3P (heights as XML text, empty Datum = invalid, int16 scaled
/// by the increment) in a folder inside the archive, as some instruments write.
#[test]
fn x3p_data_list_in_a_folder_is_read() {
    let main = r#"<?xml version="1.0" encoding="UTF-8"?>
<p:ISO5436_2 xmlns:p="http://www.opengps.eu/2008/ISO5436_2">
 <Record1><Revision>ISO5436 - 2000</Revision><FeatureType>SUR</FeatureType>
  <Axes><CX><AxisType>I</AxisType><DataType>D</DataType><Increment>2e-6</Increment><Offset>0</Offset></CX>
   <CY><AxisType>I</AxisType><DataType>D</DataType><Increment>3e-6</Increment><Offset>0</Offset></CY>
   <CZ><AxisType>A</AxisType><DataType>I</DataType><Increment>1e-9</Increment><Offset>0</Offset></CZ></Axes></Record1>
 <Record3><MatrixDimension><SizeX>3</SizeX><SizeY>2</SizeY><SizeZ>1</SizeZ></MatrixDimension>
  <DataList><Datum>10</Datum><Datum>-20</Datum><Datum></Datum><Datum>40</Datum><Datum>5</Datum><Datum>6</Datum></DataList></Record3>
 <Record4><ChecksumFile>md5checksum.hex</ChecksumFile></Record4>
</p:ISO5436_2>"#;
    let sum = format!("{} *main.xml\n", md5_hex(main.as_bytes()));
    let bytes = zip_of(&[("scan/main.xml", main.as_bytes().to_vec()), ("scan/md5checksum.hex", sum.into_bytes())]);
    let m = read_x3p_bytes(&bytes, Path::new("datalist.x3p")).unwrap();
    assert_eq!((m.nx, m.ny, m.pitch_x_m, m.pitch_y_m), (3, 2, 2e-6, 3e-6));
    assert_eq!(m.valid_count(), 5);
    assert!((m.at(1, 0) + 20e-9).abs() < 1e-20 && m.at(2, 0).is_nan() && (m.at(0, 1) - 40e-9).abs() < 1e-20);
}

/// Text grids (lucent header, Gwyddion header, command line), float TIFF and
/// EXR give the same map.
#[test]
fn text_tiff_and_exr_readers_agree() {
    let dir = tempfile::tempdir().unwrap();
    let map = small_map();
    let um: Vec<f64> = map.heights_m.iter().map(|h| h * 1e6).collect();
    let rows = |sep: &str| -> String {
        um.chunks(map.nx)
            .map(|r| {
                r.iter()
                    .map(|v| if v.is_finite() { format!("{v:e}") } else { "NaN".into() })
                    .collect::<Vec<_>>()
                    .join(sep)
            })
            .collect::<Vec<_>>()
            .join("\n")
    };
    let csv = dir.path().join("a.csv");
    std::fs::write(&csv, format!("# pitch_x_um = 0.871\n# pitch_y_um = 1.25\n# height_unit = um\n{}\n", rows(",")))
        .unwrap();
    let gwy = dir.path().join("b.txt");
    std::fs::write(
        &gwy,
        format!(
            "# Channel: Height\n# Width: {} µm\n# Height: {} µm\n# Value units: um\n{}\n",
            0.871 * map.nx as f64,
            1.25 * map.ny as f64,
            rows("\t")
        ),
    )
    .unwrap();
    let bare = dir.path().join("c.asc");
    std::fs::write(&bare, rows(" ").replace("NaN", "nan") + "\n").unwrap();
    let tif = dir.path().join("d.tif");
    {
        let f = std::fs::File::create(&tif).unwrap();
        let mut enc = tiff::encoder::TiffEncoder::new(f).unwrap();
        let data: Vec<f32> = um.iter().map(|v| *v as f32).collect();
        enc.write_image::<tiff::encoder::colortype::Gray32Float>(map.nx as u32, map.ny as u32, &data).unwrap();
    }
    let exr = dir.path().join("e.exr");
    let data: Vec<f32> = um.iter().map(|v| *v as f32).collect();
    lucent::exr::write_channels(&exr, map.nx, map.ny, &[("Z", &data)]).unwrap();
    let cli = ReadOptions { pitch_x_m: Some(0.871e-6), pitch_y_m: Some(1.25e-6), height_unit: Some(LengthUnit::Um) };
    for (p, opts, tol) in [
        (&csv, ReadOptions::default(), 1e-15),
        (&gwy, ReadOptions::default(), 1e-15),
        (&bare, cli, 1e-15),
        (&tif, cli, 1e-7),
        (&exr, cli, 1e-7),
    ] {
        let m = read_height_map(p, &opts).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
        assert_eq!((m.nx, m.ny), (map.nx, map.ny), "{}", p.display());
        assert!(
            (m.pitch_x_m / map.pitch_x_m - 1.0).abs() < 1e-12 && (m.pitch_y_m / map.pitch_y_m - 1.0).abs() < 1e-12,
            "{}",
            p.display()
        );
        for (a, b) in map.heights_m.iter().zip(&m.heights_m) {
            assert_eq!(a.is_finite(), b.is_finite(), "{}", p.display());
            if a.is_finite() {
                assert!((a - b).abs() <= tol * 1e-6, "{}: {a} vs {b}", p.display());
            }
        }
    }
    // The command line overrides a header pitch, with a note.
    let m = read_height_map(&csv, &ReadOptions { pitch_x_m: Some(1e-6), ..Default::default() }).unwrap();
    assert_eq!(m.pitch_x_m, 1e-6);
    assert!(m.notes.iter().any(|n| n.contains("replaces")), "{:?}", m.notes);
}

// ------------------------------------------------------------ references

const REF: &str = "fixtures/reference/surface";

/// Heights, plane, S_q, S_dq and per-pixel plane fits against the numpy,
/// surfalize and x3pio references (tools/reference/surface_reference.py).
#[test]
fn agrees_with_numpy_surfalize_and_x3pio() {
    let dir = root().join(REF);
    let r = json(&dir.join("reference.json"));
    let opts = FitOptions::default();
    for case in r["files"].as_array().unwrap() {
        let file = case["file"].as_str().unwrap();
        let map = read_x3p(&dir.join(file)).unwrap();
        assert_eq!(map.nx as u64, case["nx"].as_u64().unwrap(), "{file}");
        assert_eq!(map.ny as u64, case["ny"].as_u64().unwrap(), "{file}");
        assert_eq!(map.valid_count() as u64, case["valid_points"].as_u64().unwrap(), "{file}");
        let sum: f64 = map.heights_m.iter().filter(|h| h.is_finite()).sum();
        let want = case["sum_valid_m"].as_f64().unwrap();
        assert!((sum - want).abs() <= 1e-12 * want.abs().max(1e-6), "{file}: Σh {sum} vs x3pio {want}");
        for p in case["samples"].as_array().unwrap() {
            let (i, j) = (p["i"].as_u64().unwrap() as usize, p["j"].as_u64().unwrap() as usize);
            let got = map.at(i, j);
            match p["z_m"].as_f64() {
                Some(z) => assert!((got - z).abs() <= 1e-15, "{file} ({i}, {j}): {got} vs {z}"),
                None => assert!(got.is_nan(), "{file} ({i}, {j}) should be invalid"),
            }
        }
        let plane = fit_plane(&map).unwrap();
        let (sx, sy) = (case["plane"]["slope_x"].as_f64().unwrap(), case["plane"]["slope_y"].as_f64().unwrap());
        assert!(
            (plane.slope_x - sx).abs() < 1e-12 && (plane.slope_y - sy).abs() < 1e-12,
            "{file}: plane {plane:?} vs ({sx}, {sy})"
        );
        let levelled = lucent::surface::normals::remove_plane(&map, &plane);
        if let Some(s) = case.get("surfalize") {
            let rough = roughness(&levelled);
            let (sq, sdq) = (s["Sq_m"].as_f64().unwrap(), s["Sdq"].as_f64().unwrap());
            println!("{file}: Sq {} vs surfalize {sq}; Sdq {} vs {sdq}", rough.sq_m, rough.sdq);
            assert!((rough.sq_m / sq - 1.0).abs() < 1e-9, "{file}: Sq {} vs surfalize {sq}", rough.sq_m);
            assert!((rough.sdq / sdq - 1.0).abs() < 1e-9, "{file}: Sdq {} vs surfalize {sdq}", rough.sdq);
        }
        let field = plane_fit_normals(&levelled, &opts).unwrap();
        let mut worst: f64 = 0.0;
        for p in case["plane_fits"].as_array().unwrap() {
            let (i, j) = (p["i"].as_u64().unwrap() as usize, p["j"].as_u64().unwrap() as usize);
            let k = j * map.nx + i;
            match (p["slope_x"].as_f64(), p["slope_y"].as_f64()) {
                (Some(ex), Some(ey)) => {
                    let (gx, gy) = (field.slope_x[k], field.slope_y[k]);
                    let d = (gx - ex).abs().max((gy - ey).abs());
                    worst = worst.max(d);
                    assert!(d < 1e-10, "{file} ({i}, {j}): slopes ({gx}, {gy}) vs numpy ({ex}, {ey})");
                }
                _ => assert!(
                    field.slope_x[k].is_nan(),
                    "{file} ({i}, {j}): numpy gives no normal (weight fraction {})",
                    p["weight_fraction"]
                ),
            }
        }
        println!("{file}: worst plane-fit slope difference to numpy {worst:.2e}");
    }
    // The project's fixture as x3pio read it.
    let fx = &r["lucent_fixture"];
    let map = read_x3p(&root().join(fx["file"].as_str().unwrap())).unwrap();
    assert_eq!(map.valid_count() as u64, fx["valid_points"].as_u64().unwrap());
    let sum: f64 = map.heights_m.iter().filter(|h| h.is_finite()).sum();
    assert!((sum - fx["sum_valid_m"].as_f64().unwrap()).abs() < 1e-12 * sum.abs().max(1e-6));
    assert_eq!(map.pitch_x_m, fx["pitch_x_m"].as_f64().unwrap());
}

// ------------------------------------------------------------ recipe

#[test]
fn recipe_surface_accepts_fit_json() {
    let dir = tempfile::tempdir().unwrap();
    let map = synthesize(&SynthSpec {
        nx: 160,
        ny: 160,
        alpha: 0.02,
        model: RoughnessModel::TrowbridgeReitz,
        ..SynthSpec::default()
    })
    .unwrap()
    .map;
    let fit = fit_surface(&map, &FitOptions::default()).unwrap();
    lucent::surface::write_fit_outputs(&dir.path().join("fit"), &fit).unwrap();
    let base = std::fs::read_to_string(root().join("fixtures/samples/IOL1068-08.toml")).unwrap();
    let base: String = base.split("[surface]").next().unwrap().to_string();
    let write = |name: &str, surface: &str| {
        let p = dir.path().join(name);
        std::fs::write(&p, format!("{base}\n[surface]\n{surface}\n")).unwrap();
        p
    };
    let r = Recipe::load(&write("a.toml", "fit = \"fit/fit.json\""), Overrides::default()).unwrap();
    let s = r.surface.unwrap();
    let better = fit.report.better_model;
    assert_eq!(s.model, better);
    assert_eq!(s.alpha, fit.report.fits.get(better).alpha);
    assert_eq!(s.scale, fit.report.fits.get(better).scale);
    let r =
        Recipe::load(&write("b.toml", "fit = \"fit/fit.json\"\nmodel = \"beckmann\""), Overrides::default()).unwrap();
    assert_eq!(r.surface.unwrap().alpha, fit.report.fits.beckmann.alpha);
    let e = Recipe::load(&write("c.toml", "fit = \"missing.json\""), Overrides::default()).unwrap_err().to_string();
    assert!(e.contains("missing.json") && e.contains("surface.fit"), "{e}");
    let e = Recipe::load(&write("d.toml", "fit = \"fit/fit.json\"\nalpha = 0.1"), Overrides::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("surface"), "{e}");
    // α in the one range every file and command takes.
    let e = Recipe::load(&write("f.toml", "model = \"beckmann\"\nalpha = 5.0"), Overrides::default())
        .unwrap_err()
        .to_string();
    assert!(e.contains("surface.alpha") && e.contains("[0, 4]"), "{e}");
    std::fs::write(dir.path().join("bad.json"), "{\"schema\": 3}").unwrap();
    let e = Recipe::load(&write("e.toml", "fit = \"bad.json\""), Overrides::default()).unwrap_err().to_string();
    assert!(e.contains("bad.json"), "{e}");
}

// ------------------------------------------------------------ CLI

#[test]
fn cli_fits_the_shipped_height_map() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("fit");
    let o = lucent(&["surface", "fit", "fixtures/surface/tr_0p0084.x3p", "--out", out.to_str().unwrap()]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = stdout(&o);
    assert!(text.contains("Trowbridge–Reitz") && text.contains("better"), "{text}");
    for f in lucent::surface::OUTPUT_FILES {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    let r = json(&out.join("fit.json"));
    assert_eq!(r["schema"], "lucent.surface.fit/1");
    assert_eq!(r["better_model"], "trowbridge-reitz");
    // 256 × 256 points are few for a heavy-tailed surface: ±10 % realisation noise.
    let a = r["fits"]["trowbridge-reitz"]["alpha"].as_f64().unwrap();
    assert!((a / 0.0084 - 1.0).abs() < 0.15, "α {a}");
    let (w, h, planes) = lucent::exr::read_channels(&out.join("normals.exr"), &["R", "G", "B", "A"]).unwrap();
    assert_eq!((w, h), (256, 256));
    let k = 128 * 256 + 128;
    let n = (planes[0][k].powi(2) + planes[1][k].powi(2) + planes[2][k].powi(2)).sqrt();
    assert!((n - 1.0).abs() < 1e-6 && planes[3][k] == 1.0);
    // synth → fit through the CLI, with options.
    let x3p = dir.path().join("s.x3p");
    let o = lucent(&[
        "surface",
        "synth",
        "--model",
        "beckmann",
        "--alpha",
        "0.05",
        "--size",
        "200x150",
        "--point-type",
        "L",
        "--invalid-fraction",
        "0.01",
        "--out",
        x3p.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let o = lucent(&[
        "surface",
        "fit",
        x3p.to_str().unwrap(),
        "--window",
        "9",
        "--sigma-px",
        "1.5",
        "--fit-tilt",
        "--out",
        dir.path().join("s").to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let r = json(&dir.path().join("s/fit.json"));
    assert_eq!(r["options"]["window_px"], 9);
    assert_eq!(r["fits"]["beckmann"]["tilt_fitted"], true);
}

// ------------------------------------------------------------ bad input

#[test]
fn bad_inputs_are_rejected_with_which_and_what() {
    let bad = "tests/bad/surface";
    let dir = tempfile::tempdir().unwrap();
    let cases: Vec<(Vec<String>, Vec<&str>)> = vec![
        (vec![format!("{bad}/truncated.x3p")], vec!["truncated.x3p", "truncated"]),
        (vec![format!("{bad}/not_a_zip.x3p")], vec!["not_a_zip.x3p", "not a readable X3P"]),
        (vec![format!("{bad}/point_count.x3p")], vec!["point_count.x3p", "bindata/data.bin", "3999", "4000"]),
        (vec![format!("{bad}/zero_pitch.x3p")], vec!["zero_pitch.x3p", "CX/Increment", "0", "positive"]),
        (vec![format!("{bad}/negative_pitch.x3p")], vec!["negative_pitch.x3p", "CY/Increment", "-", "positive"]),
        (vec![format!("{bad}/all_invalid.x3p")], vec!["all_invalid.x3p", "no valid height point", "4000"]),
        (vec![format!("{bad}/data_checksum.x3p")], vec!["data_checksum.x3p", "bindata/data.bin", "MD5"]),
        (vec![format!("{bad}/main_checksum.x3p")], vec!["main_checksum.x3p", "main.xml", "MD5", "md5checksum.hex"]),
        (vec![format!("{bad}/missing_data.x3p")], vec!["missing_data.x3p", "bindata/data.bin", "not in the archive"]),
        (vec![format!("{bad}/valid_short.x3p")], vec!["valid_short.x3p", "bindata/valid.bin", "4000"]),
        (vec![format!("{bad}/profile.x3p")], vec!["profile.x3p", "PRF"]),
        (vec![format!("{bad}/bad_xml.x3p")], vec!["bad_xml.x3p", "main.xml"]),
        (vec![format!("{bad}/negative_pitch.csv")], vec!["negative_pitch.csv", "x pitch", "-5e-7", "positive"]),
        (vec![format!("{bad}/all_invalid.csv")], vec!["all_invalid.csv", "no valid height point"]),
        (vec![format!("{bad}/ragged.csv")], vec!["ragged.csv", "line 5", "3 values", "line 3", "4"]),
        (vec![format!("{bad}/bad_number.csv")], vec!["bad_number.csv", "line 4", "column 2", "1.2.3"]),
        (vec![format!("{bad}/no_pitch.csv")], vec!["no_pitch.csv", "no pitch", "--pitch-um"]),
        (
            vec![format!("{bad}/integer.tif"), "--pitch-um".into(), "1".into(), "--height-unit".into(), "um".into()],
            vec!["integer.tif", "float"],
        ),
        (vec![format!("{bad}/no_pitch.csv"), "--pitch-um".into(), "0".into()], vec!["--pitch-um", "0", "positive"]),
        (vec![format!("{bad}/no_pitch.csv"), "--pitch-um".into(), "-2".into()], vec!["--pitch-um", "-2"]),
        (vec!["fixtures/surface/tr_0p0084.x3p".into(), "--window".into(), "4".into()], vec!["window", "4", "odd"]),
        (vec!["fixtures/surface/tr_0p0084.x3p".into(), "--sigma-px".into(), "0".into()], vec!["sigma-px", "0"]),
        (
            vec!["fixtures/surface/tr_0p0084.x3p".into(), "--height-unit".into(), "furlong".into()],
            vec!["--height-unit", "furlong"],
        ),
        (vec![format!("{bad}/missing.x3p")], vec!["missing.x3p", "no such file"]),
        (vec![format!("{bad}/README.md")], vec!["README.md", "unknown height-map format"]),
    ];
    for (k, (args, expect)) in cases.iter().enumerate() {
        let out = dir.path().join(format!("out{k}"));
        let mut all: Vec<&str> = vec!["surface", "fit"];
        all.extend(args.iter().map(String::as_str));
        all.extend(["--out", out.to_str().unwrap()]);
        let o = lucent(&all);
        let err = stderr(&o);
        assert!(!o.status.success(), "{args:?} succeeded");
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
        for e in expect {
            assert!(err.contains(e), "{args:?}: {e:?} not in: {err}");
        }
        assert!(!out.exists(), "{args:?} wrote output");
    }
}
