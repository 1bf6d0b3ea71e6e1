//! DNG path: a DNG written here (tiff crate) from a known mosaic must decode
//! exactly — CFA pattern and black levels relative to the active area, white
//! level, colour matrix, as-shot neutral, orientation — and broken DNGs must
//! give errors naming the file.

use lucent_calib::demosaic::Demosaic;
use lucent_calib::raw::{
    decode_raw, developed_size, raw_output_size, read_raw, RawData, RawError, RawOptions, WhiteBalance,
};
use std::path::{Path, PathBuf};
use tiff::encoder::{colortype, Rational, SRational, TiffEncoder};
use tiff::tags::Tag;

const SENSOR: (usize, usize) = (70, 52);
/// ActiveArea top, left, bottom, right: odd offsets, so a decoder that takes
/// the CFA or black pattern from the sensor origin gets them wrong.
const ACTIVE: [u32; 4] = [1, 3, 49, 67];
/// Black level per CFA position of the active area (BlackLevelRepeatDim 2 × 2).
const BLACK: [u16; 4] = [512, 514, 516, 518];
const WHITE: u16 = 15000;
const XYZ_TO_CAM: [f64; 9] = [0.6722, -0.0635, -0.0963, -0.4287, 1.246, 0.2028, -0.0908, 0.2162, 0.5668];
const NEUTRAL: [f64; 3] = [0.5, 1.0, 0.625];

/// Sensor value at (x, y): smooth plus a per-position offset, never below black.
fn value(x: usize, y: usize) -> u16 {
    (600 + 37 * x + 101 * y + 13 * ((x * y) % 7)) as u16
}

struct Dng {
    orientation: u16,
    cfa: [u8; 4],
}

fn write_dng(path: &Path, d: &Dng) {
    let (w, h) = SENSOR;
    let data: Vec<u16> = (0..w * h).map(|i| value(i % w, i / w)).collect();
    let file = std::fs::File::create(path).unwrap();
    let mut enc = TiffEncoder::new(file).unwrap();
    let mut img = enc.new_image::<colortype::Gray16>(w as u32, h as u32).unwrap();
    img.rows_per_strip(h as u32).unwrap();
    {
        let e = img.encoder();
        e.write_tag(Tag::NewSubfileType, 0u32).unwrap();
        e.write_tag(Tag::PhotometricInterpretation, 32803u16).unwrap(); // CFA
        e.write_tag(Tag::Make, "Lucent").unwrap();
        e.write_tag(Tag::Model, "Round-trip DNG").unwrap();
        e.write_tag(Tag::Orientation, d.orientation).unwrap();
        e.write_tag(Tag::Unknown(33421), &[2u16, 2][..]).unwrap(); // CFARepeatPatternDim
        e.write_tag(Tag::Unknown(33422), &d.cfa[..]).unwrap(); // CFAPattern
        e.write_tag(Tag::Unknown(50706), &[1u8, 4, 0, 0][..]).unwrap(); // DNGVersion
        e.write_tag(Tag::Unknown(50708), "Lucent Round-trip DNG").unwrap(); // UniqueCameraModel
        e.write_tag(Tag::Unknown(50713), &[2u16, 2][..]).unwrap(); // BlackLevelRepeatDim
        e.write_tag(Tag::Unknown(50714), &BLACK[..]).unwrap(); // BlackLevel
        e.write_tag(Tag::Unknown(50717), WHITE).unwrap(); // WhiteLevel
        let cm: Vec<SRational> =
            XYZ_TO_CAM.iter().map(|v| SRational { n: (v * 10000.0).round() as i32, d: 10000 }).collect();
        e.write_tag(Tag::Unknown(50721), &cm[..]).unwrap(); // ColorMatrix1
        e.write_tag(Tag::Unknown(50778), 21u16).unwrap(); // CalibrationIlluminant1 = D65
        let an: Vec<Rational> = NEUTRAL.iter().map(|v| Rational { n: (v * 1000.0) as u32, d: 1000 }).collect();
        e.write_tag(Tag::Unknown(50728), &an[..]).unwrap(); // AsShotNeutral
        e.write_tag(Tag::Unknown(50829), &ACTIVE[..]).unwrap(); // ActiveArea
    }
    img.write_data(&data).unwrap();
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lucent-dng-{}-{name}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

#[test]
fn known_mosaic_round_trips_exactly() {
    for (cfa, name) in [([0u8, 1, 1, 2], "RGGB"), ([1, 2, 0, 1], "GBRG")] {
        let path = temp(&format!("{name}.dng"));
        write_dng(&path, &Dng { orientation: 1, cfa });
        let frame = read_raw(&path, None).expect("decode DNG");
        let m = &frame.meta;
        assert!(m.dng);
        assert_eq!((m.make.as_str(), m.model.as_str()), ("Lucent", "Round-trip DNG"));
        assert_eq!(m.cfa_pattern, name, "CFAPattern applies from the active area's origin");
        assert_eq!(m.black_levels, BLACK.map(f32::from), "BlackLevel per active-area CFA position");
        assert_eq!(m.white_levels, [f32::from(WHITE); 4]);
        let [top, left, bottom, right] = ACTIVE.map(|v| v as usize);
        assert_eq!(
            (m.active_area.top, m.active_area.left, m.active_area.width, m.active_area.height),
            (top, left, right - left, bottom - top)
        );
        for r in 0..3 {
            for c in 0..3 {
                assert!((m.xyz_to_camera[r][c] - XYZ_TO_CAM[3 * r + c]).abs() < 1e-6, "matrix [{r}][{c}]");
            }
        }
        let wb = m.camera_wb_multipliers.unwrap();
        assert!((wb[0] - 2.0).abs() < 1e-6 && wb[1] == 1.0 && (wb[2] - 1.6).abs() < 1e-6, "{wb:?}");

        let RawData::Bayer(mos) = &frame.data else { panic!("Bayer") };
        assert_eq!((mos.width, mos.height), (right - left, bottom - top));
        assert_eq!(raw_output_size(&path).unwrap(), (m.output_width, m.output_height), "{name}: header-only size");
        assert_eq!(developed_size(&path).unwrap(), (m.output_width, m.output_height), "{name}: unturned");
        for y in 0..mos.height {
            for x in 0..mos.width {
                let k = 2 * (y & 1) + (x & 1);
                let raw = f64::from(value(x + left, y + top));
                let want = ((raw - f64::from(BLACK[k])) / (f64::from(WHITE) - f64::from(BLACK[k]))) as f32;
                assert_eq!(mos.data[y * mos.width + x], want, "{name} ({x},{y})");
            }
        }
        std::fs::remove_file(&path).ok();
    }
}

#[test]
fn orientation_white_balance_and_demosaic_through_the_pipeline() {
    let path = temp("rot.dng");
    write_dng(&path, &Dng { orientation: 6, cfa: [0, 1, 1, 2] });
    let opts = RawOptions { demosaic: Demosaic::Bilinear, white_balance: WhiteBalance::Camera, white_level: None };
    let (img, meta) = decode_raw(&path, &opts).unwrap();
    let [top, left, bottom, right] = ACTIVE.map(|v| v as usize);
    let (aw, ah) = (right - left, bottom - top);
    assert_eq!((img.width, img.height), (ah, aw), "rotated 90°");
    assert_eq!(meta.orientation_applied, "rotate 90° clockwise");
    assert_eq!((meta.output_width, meta.output_height), (ah, aw));
    // read_raw's size (and raw_output_size's) is the active area as stored, before orientation.
    let frame = read_raw(&path, None).unwrap();
    assert_eq!((frame.meta.output_width, frame.meta.output_height), (aw, ah));
    assert_eq!(raw_output_size(&path).unwrap(), (aw, ah));
    // The developed photo's size, what planning checks against the render, is turned.
    assert_eq!(developed_size(&path).unwrap(), (img.width, img.height), "developed size, from the header");
    // Output (xo, yo) shows stored pixel (yo, ah − 1 − xo); its own CFA sample survives demosaicing.
    let (xo, yo) = (10, 20);
    let (xs, ys) = (yo, ah - 1 - xo);
    let k = 2 * (ys & 1) + (xs & 1);
    let colour = [0usize, 1, 1, 2][k];
    let raw = f64::from(value(xs + left, ys + top));
    let gain = [2.0, 1.0, 1.6][colour];
    let want = (raw - f64::from(BLACK[k])) / (f64::from(WHITE) - f64::from(BLACK[k])) * gain;
    let got = f64::from(img.pixel(xo, yo)[colour]);
    assert!((got - want).abs() < 1e-6 * want, "{got} vs {want}");
    std::fs::remove_file(&path).ok();
}

#[test]
fn a_dng_cut_inside_its_directory_names_the_file_and_the_problem() {
    let path = temp("dir_whole.dng");
    write_dng(&path, &Dng { orientation: 1, cfa: [0, 1, 1, 2] });
    let bytes = std::fs::read(&path).unwrap();
    assert_eq!(&bytes[..4], b"II*\0", "TiffEncoder writes little-endian");
    let ifd0 = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) as usize;
    // IFD0 = the raw image (CFA): its entry count and half an entry, the rest missing.
    for (name, len) in [("dir_cut_ifd0.dng", ifd0 + 8), ("dir_cut_header.dng", 6)] {
        let cut = temp(name);
        std::fs::write(&cut, &bytes[..len]).unwrap();
        let e = read_raw(&cut, None).unwrap_err();
        assert!(matches!(e, RawError::Decode { .. }), "{e:?}");
        let e = e.to_string();
        assert_eq!(raw_output_size(&cut).unwrap_err().to_string(), e, "header-only: the same error");
        let problem =
            format!("truncated or corrupt: its TIFF directory structure runs past the end of the file ({len} bytes)");
        assert!(e.contains(name) && e.contains(&problem), "{e}");
        std::fs::remove_file(&cut).ok();
    }
    std::fs::remove_file(&path).ok();
}

#[test]
fn truncated_and_corrupt_dngs_are_errors_naming_the_file() {
    let path = temp("whole.dng");
    write_dng(&path, &Dng { orientation: 1, cfa: [0, 1, 1, 2] });
    let bytes = std::fs::read(&path).unwrap();

    // Cut in the middle of the pixel data: refused, not padded.
    let cut = temp("cut.dng");
    std::fs::write(&cut, &bytes[..bytes.len() - 2000]).unwrap();
    let e = read_raw(&cut, None).unwrap_err();
    assert!(matches!(e, RawError::Decode { .. }), "{e:?}");
    assert!(e.to_string().contains("cut.dng") && e.to_string().contains("truncated"), "{e}");
    // The header-only size refuses it too (the directories declare data past the end), with the same error.
    let h = raw_output_size(&cut).unwrap_err();
    assert!(matches!(h, RawError::Decode { .. }), "{h:?}");
    assert_eq!(h.to_string(), e.to_string());

    // Header destroyed.
    let mut bad = bytes.clone();
    bad[4..64].iter_mut().for_each(|b| *b = 0xEE);
    let corrupt = temp("corrupt.dng");
    std::fs::write(&corrupt, &bad).unwrap();
    let e = read_raw(&corrupt, None).unwrap_err();
    assert!(e.to_string().contains("corrupt.dng"), "{e}");
    assert_eq!(raw_output_size(&corrupt).unwrap_err().to_string(), e.to_string());

    // A plain greyscale TIFF is not a RAW file.
    let plain = temp("plain.tif");
    {
        let f = std::fs::File::create(&plain).unwrap();
        let mut enc = TiffEncoder::new(f).unwrap();
        enc.write_image::<colortype::Gray16>(8, 8, &[100u16; 64]).unwrap();
    }
    let e = read_raw(&plain, None).unwrap_err();
    assert!(matches!(e, RawError::Decode { .. }) && e.to_string().contains("plain.tif"), "{e}");
    assert_eq!(raw_output_size(&plain).unwrap_err().to_string(), e.to_string());

    // The intact file still decodes.
    let (img, _) = decode_raw(&path, &RawOptions::default()).unwrap();
    assert_eq!((img.width, img.height), (64, 48));
    for p in [&path, &cut, &corrupt, &plain] {
        std::fs::remove_file(p).ok();
    }
}

#[test]
fn the_header_only_size_ignores_the_pixel_values_and_refuses_missing_data() {
    // Every pixel byte replaced by garbage, the file's length and directories
    // intact: the size comes from the tags alone, so it is still reported
    // (and read_raw, which has no check on DNG sample values, decodes the
    // same size: all its values are then garbage, not an error).
    let path = temp("garbage_pixels.dng");
    write_dng(&path, &Dng { orientation: 1, cfa: [0, 1, 1, 2] });
    let mut bytes = std::fs::read(&path).unwrap();
    let (w, h) = SENSOR;
    // IFD0's StripOffsets entry: one LONG, the only strip's offset inline.
    let ifd0 = u32::from_le_bytes([bytes[4], bytes[5], bytes[6], bytes[7]]) as usize;
    let n = usize::from(u16::from_le_bytes([bytes[ifd0], bytes[ifd0 + 1]]));
    let entry = (0..n).map(|k| ifd0 + 2 + 12 * k).find(|&e| bytes[e..e + 2] == 273u16.to_le_bytes()).unwrap();
    assert_eq!(bytes[entry + 2..entry + 8], [4, 0, 1, 0, 0, 0], "StripOffsets: one LONG");
    let strip = u32::from_le_bytes(bytes[entry + 8..entry + 12].try_into().unwrap()) as usize;
    for (k, b) in bytes[strip..strip + 2 * w * h].iter_mut().enumerate() {
        *b = (k * 7919 % 251) as u8;
    }
    std::fs::write(&path, &bytes).unwrap();
    let [top, left, bottom, right] = ACTIVE.map(|v| v as usize);
    assert_eq!(raw_output_size(&path).unwrap(), (right - left, bottom - top));
    let frame = read_raw(&path, None).unwrap();
    assert_eq!((frame.meta.output_width, frame.meta.output_height), (right - left, bottom - top));

    // The directories intact but the pixel data missing, as a file cut after
    // its directories looks to a reader: the strip's offset moved past the
    // end of the file. The header-only size refuses it as truncated (the
    // declared data runs past the end), with read_raw's error, naming the
    // file; never a panic.
    let past = bytes.len() as u32 + 1000;
    bytes[entry + 8..entry + 12].copy_from_slice(&past.to_le_bytes());
    let cut = temp("no_pixels.dng");
    std::fs::write(&cut, &bytes).unwrap();
    let e = raw_output_size(&cut).unwrap_err();
    assert!(matches!(e, RawError::Decode { .. }), "{e:?}");
    assert!(e.to_string().contains("no_pixels.dng") && e.to_string().contains("truncated"), "{e}");
    assert_eq!(e.to_string(), read_raw(&cut, None).unwrap_err().to_string());
    for p in [&path, &cut] {
        std::fs::remove_file(p).ok();
    }
}
