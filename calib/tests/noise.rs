//! The RAW noise model (lucent_calib::noise): a and b of var = a·x + b
//! estimated from synthetic mosaics with known a, b per channel (smooth
//! gradients, large flat patches and their edges), and read from a DNG's
//! NoiseProfile tag when the file has one.

use lucent_calib::demosaic::{Bayer, Mosaic};
use lucent_calib::noise::{estimate, model_of, NoiseSource};
use lucent_calib::raw::{read_raw, RawData};
use std::path::Path;
use tiff::encoder::{colortype, TiffEncoder};
use tiff::tags::Tag;

/// Truth per channel R, G, B: a shot term of 1/(5000 … 3300 e⁻ at white)
/// and a read-noise floor of σ ≈ 0.002 … 0.0024 of the white level.
const A: [f64; 3] = [1.5e-4, 2.0e-4, 3.0e-4];
const B: [f64; 3] = [4.0e-6, 4.0e-6, 6.0e-6];

use lucent_testkit::normal::SplitMix64 as Rng;

/// The clean scene at photosite (x, y), colour c: a diagonal gradient from
/// ≈ 0.03 to ≈ 0.8, with 48-px patches brighter by 0.2 on every other one of
/// a coarse checker (edges), the three colours in different proportions.
fn scene(x: usize, y: usize, c: usize, w: usize, h: usize) -> f64 {
    let t = 0.5 * (x as f64 / w as f64 + y as f64 / h as f64);
    let patch = if (x / 48 + y / 48).is_multiple_of(2) { 0.2 } else { 0.0 };
    (0.03 + 0.55 * t + patch) * [0.8, 1.0, 0.65][c]
}

/// A RGGB mosaic of `w × h` with the truth's noise.
fn mosaic(seed: u64, w: usize, h: usize, a: [f64; 3], b: [f64; 3]) -> Mosaic {
    let pattern = Bayer::from_name("RGGB").unwrap();
    let mut rng = Rng(seed);
    let data = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let c = pattern.colour_at(y, x);
            let s = scene(x, y, c, w, h);
            (s + (a[c] * s + b[c]).sqrt() * rng.normal()) as f32
        })
        .collect();
    Mosaic::new(w, h, pattern, data).unwrap()
}

#[test]
fn shot_and_read_noise_are_recovered_from_the_image() {
    // 8 independent 512 × 384 mosaics with edges (the patches): a within 5 %
    // of the truth in every one (its stated standard error is ≈ 1.5 %); b,
    // the read floor, is a small part of the variance above a signal of
    // ≈ 0.05 and comes from the darkest bins: each within 55 % (standard
    // error ≈ 15 %), their mean over the seeds within 20 % (the edges that
    // survive the screen pull it ≈ 10 % low in G).
    let mut b_ratio = [0.0f64; 3];
    let seeds = 8;
    for seed in 0..seeds {
        let m = estimate(&RawData::Bayer(mosaic(100 + seed, 512, 384, A, B))).unwrap();
        assert_eq!(m.source, NoiseSource::EstimatedFromImage);
        assert!(m.note.is_empty(), "{}", m.note);
        for c in 0..3 {
            let (ea, eb) = ((m.a[c] / A[c] - 1.0).abs(), (m.b[c] / B[c] - 1.0).abs());
            assert!(ea < 0.05, "seed {seed} channel {c}: a = {:.4e}, truth {:.4e}", m.a[c], A[c]);
            assert!(eb < 0.55, "seed {seed} channel {c}: b = {:.4e}, truth {:.4e}", m.b[c], B[c]);
            // The stated standard error is of the size of the actual error.
            let se = m.a_std_error.unwrap()[c];
            assert!((m.a[c] - A[c]).abs() < 5.0 * se, "channel {c}: a {:.4e} ± {se:.1e} vs {:.4e}", m.a[c], A[c]);
            b_ratio[c] += m.b[c] / B[c] / seeds as f64;
        }
    }
    for (c, r) in b_ratio.iter().enumerate() {
        assert!((r - 1.0).abs() < 0.2, "channel {c}: mean b / truth {r}");
    }
}

#[test]
fn the_estimate_tells_a_noisier_sensor_apart() {
    // 20 % more shot noise must read as such, not as the truth.
    let a2 = A.map(|v| 1.2 * v);
    let m = estimate(&RawData::Bayer(mosaic(7, 512, 384, a2, B))).unwrap();
    for c in 0..3 {
        assert!((m.a[c] / a2[c] - 1.0).abs() < 0.05, "channel {c}: a = {:.4e}, truth {:.4e}", m.a[c], a2[c]);
        assert!(m.a[c] / A[c] > 1.1, "channel {c}: a = {:.4e} is not told apart from {:.4e}", m.a[c], A[c]);
    }
}

#[test]
fn a_flat_image_falls_back_to_shot_noise_only_and_says_so() {
    let pattern = Bayer::from_name("RGGB").unwrap();
    let mut rng = Rng(3);
    let (w, h) = (128, 96);
    let data = (0..w * h).map(|_| (0.4 + (A[1] * 0.4 + B[1]).sqrt() * rng.normal()) as f32).collect();
    let m = estimate(&RawData::Bayer(Mosaic::new(w, h, pattern, data).unwrap())).unwrap();
    assert!(m.note.contains("too little"), "{}", m.note);
    // a·0.4 carries the whole variance.
    let v = A[1] * 0.4 + B[1];
    assert!((m.a[1] * 0.4 / v - 1.0).abs() < 0.1, "{:?}", m.a);
    assert_eq!(m.b, [0.0; 3]);
    // Too small to estimate: an error naming the channel.
    let tiny = Mosaic::new(8, 8, pattern, vec![0.2; 64]).unwrap();
    let e = estimate(&RawData::Bayer(tiny)).unwrap_err().to_string();
    assert!(e.contains("channel R") && e.contains("too few"), "{e}");
}

/// A 64 × 48 CFA DNG of a smooth ramp with noise (σ = 8 DN), with `profile` as its NoiseProfile.
fn write_dng(path: &Path, profile: Option<&[f64]>) {
    let (w, h) = (64u32, 48u32);
    let mut rng = Rng(5);
    let data: Vec<u16> = (0..w * h)
        .map(|i| (f64::from(1024 + 40 * (i % w) + 100 * (i / w)) + 8.0 * rng.normal()).round() as u16)
        .collect();
    let file = std::fs::File::create(path).unwrap();
    let mut enc = TiffEncoder::new(file).unwrap();
    let mut img = enc.new_image::<colortype::Gray16>(w, h).unwrap();
    img.rows_per_strip(h).unwrap();
    {
        let e = img.encoder();
        e.write_tag(Tag::NewSubfileType, 0u32).unwrap();
        e.write_tag(Tag::PhotometricInterpretation, 32803u16).unwrap();
        e.write_tag(Tag::Make, "Lucent").unwrap();
        e.write_tag(Tag::Model, "Noise profile DNG").unwrap();
        e.write_tag(Tag::Unknown(33421), &[2u16, 2][..]).unwrap();
        e.write_tag(Tag::Unknown(33422), &[0u8, 1, 1, 2][..]).unwrap();
        e.write_tag(Tag::Unknown(50706), &[1u8, 4, 0, 0][..]).unwrap();
        e.write_tag(Tag::Unknown(50714), 1024u32).unwrap();
        e.write_tag(Tag::Unknown(50717), 16383u32).unwrap();
        if let Some(p) = profile {
            e.write_tag(Tag::Unknown(51041), p).unwrap(); // NoiseProfile, DOUBLE
        }
    }
    img.write_data(&data).unwrap();
}

#[test]
fn a_dng_noise_profile_is_read_and_used() {
    let dir = std::env::temp_dir().join("lucent-calib-noise-profile");
    std::fs::create_dir_all(&dir).unwrap();
    // One pair per plane R, G, B.
    let per_plane = [1.5e-4, 4e-6, 2e-4, 5e-6, 3e-4, 6e-6];
    let p = dir.join("per_plane.dng");
    write_dng(&p, Some(&per_plane));
    let frame = read_raw(&p, None).unwrap();
    assert_eq!(frame.meta.noise_profile.as_deref(), Some(&per_plane[..]));
    let m = model_of(&frame).unwrap();
    assert_eq!(m.source, NoiseSource::DngNoiseProfile);
    assert_eq!((m.a, m.b), ([1.5e-4, 2e-4, 3e-4], [4e-6, 5e-6, 6e-6]));
    // One pair for all planes.
    write_dng(&p, Some(&[2e-4, 4e-6]));
    let m = model_of(&read_raw(&p, None).unwrap()).unwrap();
    assert_eq!((m.a, m.b), ([2e-4; 3], [4e-6; 3]));
    // A malformed profile is not used, and the model says so.
    write_dng(&p, Some(&[2e-4, 4e-6, 1.0]));
    let m = model_of(&read_raw(&p, None).unwrap()).unwrap();
    assert_eq!(m.source, NoiseSource::EstimatedFromImage);
    assert!(m.note.contains("NoiseProfile") && m.note.contains("3 values"), "{}", m.note);
    // No profile: estimated.
    write_dng(&p, None);
    let frame = read_raw(&p, None).unwrap();
    assert_eq!(frame.meta.noise_profile, None);
    assert_eq!(model_of(&frame).unwrap().source, NoiseSource::EstimatedFromImage);
}
