//! Phone DNG variants, written here byte by byte (a minimal TIFF writer:
//! either byte order, strips in any order or tiles, CFA or LinearRaw,
//! 16-bit, opcode lists): linear three-channel DNGs as phones' "pro RAW"
//! modes write them (PhotometricInterpretation 34892, per-channel black and
//! white levels, 256-pixel-style tiles with partial edge tiles, uncompressed
//! or lossless-JPEG tiles — compression 7, encoded here from ITU-T T.81)
//! and Bayer DNGs in several layouts must decode to exactly the linear
//! camera RGB that was stored; the opcode lists are reported as ignored.
//! Each variant is also given to `rawloader` 0.37 directly, to record why
//! `lucent_calib::raw` reads uncompressed DNGs itself.

use lucent_calib::raw::{decode_raw, raw_output_size, read_raw, RawData, RawOptions};
use std::path::{Path, PathBuf};

/// A TIFF value: type code and its bytes (already in the file's byte order).
struct Value {
    typ: u16,
    count: u32,
    bytes: Vec<u8>,
}

struct Writer {
    le: bool,
}

impl Writer {
    fn u16s(&self, v: &[u16]) -> Value {
        let bytes = v.iter().flat_map(|x| if self.le { x.to_le_bytes() } else { x.to_be_bytes() }).collect();
        Value { typ: 3, count: v.len() as u32, bytes }
    }
    fn u32s(&self, v: &[u32]) -> Value {
        let bytes = v.iter().flat_map(|x| if self.le { x.to_le_bytes() } else { x.to_be_bytes() }).collect();
        Value { typ: 4, count: v.len() as u32, bytes }
    }
    fn bytes(&self, v: &[u8], typ: u16) -> Value {
        Value { typ, count: v.len() as u32, bytes: v.to_vec() }
    }
    fn ascii(&self, s: &str) -> Value {
        let mut b = s.as_bytes().to_vec();
        b.push(0);
        self.bytes(&b, 2)
    }
    fn rationals(&self, v: &[f64], signed: bool) -> Value {
        let mut bytes = Vec::new();
        for x in v {
            let (n, d) = ((x * 10000.0).round() as i32, 10000i32);
            for w in [n as u32, d as u32] {
                bytes.extend(if self.le { w.to_le_bytes() } else { w.to_be_bytes() });
            }
        }
        Value { typ: if signed { 10 } else { 5 }, count: v.len() as u32, bytes }
    }
    fn sample_bytes(&self, v: &[u16]) -> Vec<u8> {
        v.iter().flat_map(|x| if self.le { x.to_le_bytes() } else { x.to_be_bytes() }).collect()
    }

    /// A one-IFD TIFF: `blocks` of pixel data placed in the given order
    /// (their offsets go to `offsets_tag` in block-index order), then the
    /// tags (sorted), with `counts_tag` holding the blocks' byte counts.
    fn file(
        &self,
        mut tags: Vec<(u16, Value)>,
        blocks: &[Vec<u8>],
        order: &[usize],
        offsets_tag: u16,
        counts_tag: u16,
    ) -> Vec<u8> {
        let mut out = Vec::new();
        out.extend(if self.le { *b"II\x2a\x00" } else { *b"MM\x00\x2a" });
        out.extend([0u8; 4]); // IFD offset, set below
        let mut offsets = vec![0u32; blocks.len()];
        for &k in order {
            offsets[k] = out.len() as u32;
            out.extend(&blocks[k]);
        }
        tags.push((offsets_tag, self.u32s(&offsets)));
        tags.push((counts_tag, self.u32s(&blocks.iter().map(|b| b.len() as u32).collect::<Vec<_>>())));
        tags.sort_by_key(|t| t.0);
        // Out-of-line values.
        let mut at = Vec::new();
        for (_, v) in &tags {
            if v.bytes.len() > 4 {
                if out.len() % 2 == 1 {
                    out.push(0);
                }
                at.push(Some(out.len() as u32));
                out.extend(&v.bytes);
            } else {
                at.push(None);
            }
        }
        if out.len() % 2 == 1 {
            out.push(0);
        }
        let ifd = out.len() as u32;
        let put32 = |o: &mut Vec<u8>, x: u32| o.extend(if self.le { x.to_le_bytes() } else { x.to_be_bytes() });
        out.extend(self.u16s(&[tags.len() as u16]).bytes);
        for ((tag, v), a) in tags.iter().zip(at) {
            out.extend(self.u16s(&[*tag, v.typ]).bytes);
            put32(&mut out, v.count);
            match a {
                Some(a) => put32(&mut out, a),
                None => {
                    let mut b = v.bytes.clone();
                    b.resize(4, 0);
                    out.extend(b);
                }
            }
        }
        put32(&mut out, 0);
        let head = if self.le { ifd.to_le_bytes() } else { ifd.to_be_bytes() };
        out[4..8].copy_from_slice(&head);
        out
    }
}

/// Stored sample (x, y, channel c).
fn value(x: usize, y: usize, c: usize) -> u16 {
    (300 + 41 * x + 97 * y + 1013 * c + 7 * ((x * y + c) % 5)) as u16
}

const W: usize = 40;
const H: usize = 30;

enum Layout {
    /// Strips of this many rows, written to the file last strip first.
    StripsReversed(usize),
    /// Tiles of this size (edge tiles padded).
    Tiles(usize, usize),
    /// Tiles of this size, each a lossless JPEG ([`ljpeg`]; compression 7), as phones' "pro RAW" files.
    LjpegTiles(usize, usize),
}

/// Appends bits MSB first, with JPEG's byte stuffing (0x00 after 0xFF).
struct Bits {
    out: Vec<u8>,
    acc: u32,
    n: u32,
}

impl Bits {
    fn put(&mut self, value: u32, count: u32) {
        for k in (0..count).rev() {
            self.acc = (self.acc << 1) | ((value >> k) & 1);
            self.n += 1;
            if self.n == 8 {
                let byte = self.acc as u8;
                self.out.push(byte);
                if byte == 0xFF {
                    self.out.push(0);
                }
                self.acc = 0;
                self.n = 0;
            }
        }
    }
}

/// One lossless JPEG (ITU-T T.81 Annex H, process 14, SOF3) of `tw` × `tl`
/// pixels of `cpp` interleaved 16-bit components, written here from the
/// standard (not from `rawloader`, which decodes it): predictor 1 (Table
/// H.1: the sample to the left; the first sample of a row predicted from
/// the one above, the very first from 2^15, H.1.2.1), differences modulo
/// 2^16 coded as category SSSS (bits of |diff|; 16 for 32768, without
/// extra bits) and SSSS extra bits (diff, or diff − 1 when negative; Table
/// H.2 and F.1.2.1), one Huffman table in which all 17 categories have
/// 5-bit codes (canonical, category k ↦ k), the last byte padded with 1s.
fn ljpeg(samples: &[u16], tw: usize, tl: usize, cpp: usize) -> Vec<u8> {
    let segment = |out: &mut Vec<u8>, marker: u8, body: &[u8]| {
        out.extend([0xFF, marker]);
        out.extend(((body.len() + 2) as u16).to_be_bytes());
        out.extend(body);
    };
    let mut out = vec![0xFF, 0xD8];
    let mut dht = vec![0x00]; // class 0 (DC/lossless), table 0
    dht.extend((1..=16).map(|len| if len == 5 { 17u8 } else { 0 }));
    dht.extend(0u8..17);
    segment(&mut out, 0xC4, &dht);
    let mut sof = vec![16u8];
    sof.extend((tl as u16).to_be_bytes());
    sof.extend((tw as u16).to_be_bytes());
    sof.push(cpp as u8);
    for c in 0..cpp {
        sof.extend([c as u8 + 1, 0x11, 0]);
    }
    segment(&mut out, 0xC3, &sof);
    let mut sos = vec![cpp as u8];
    for c in 0..cpp {
        sos.extend([c as u8 + 1, 0x00]);
    }
    sos.extend([1, 0, 0]); // Ss = predictor 1, Se = 0, Ah/Al = 0 (no point transform)
    segment(&mut out, 0xDA, &sos);
    let mut bits = Bits { out, acc: 0, n: 0 };
    let at = |x: usize, y: usize, c: usize| samples[(y * tw + x) * cpp + c];
    for y in 0..tl {
        for x in 0..tw {
            for c in 0..cpp {
                let pred = match (x, y) {
                    (0, 0) => 1 << 15,
                    (0, _) => at(0, y - 1, c),
                    _ => at(x - 1, y, c),
                };
                let diff = i32::from(at(x, y, c).wrapping_sub(pred) as i16); // −32768 ≡ 32768
                let category = if diff == -32768 { 16 } else { 32 - diff.unsigned_abs().leading_zeros() };
                bits.put(category, 5);
                if (1..16).contains(&category) {
                    let extra = if diff > 0 { diff } else { diff - 1 };
                    bits.put(extra as u32 & ((1 << category) - 1), category);
                }
            }
        }
    }
    if bits.n > 0 {
        bits.put(0xFF, 8 - bits.n);
    }
    let mut out = bits.out;
    out.extend([0xFF, 0xD9]);
    out
}

/// Common DNG tags for IFD0 = the raw image.
fn dng_tags(w: &Writer, cpp: usize, linear: bool) -> Vec<(u16, Value)> {
    let mut t = vec![
        (254, w.u32s(&[0])),
        (256, w.u32s(&[W as u32])),
        (257, w.u32s(&[H as u32])),
        (258, w.u16s(&vec![16; cpp])),
        (259, w.u16s(&[1])),
        (262, w.u16s(&[if linear { 34892 } else { 32803 }])),
        (271, w.ascii("Lucent")),
        (272, w.ascii("Phone DNG")),
        (274, w.u16s(&[1])),
        (277, w.u16s(&[cpp as u16])),
        (284, w.u16s(&[1])),
        (50706, w.bytes(&[1, 6, 0, 0], 1)),
        (50708, w.ascii("Lucent Phone DNG")),
        (50721, w.rationals(&[0.6722, -0.0635, -0.0963, -0.4287, 1.246, 0.2028, -0.0908, 0.2162, 0.5668], true)),
        (50728, w.rationals(&[0.5, 1.0, 0.625], false)),
        (50778, w.u16s(&[21])),
    ];
    if !linear {
        t.push((33421, w.u16s(&[2, 2])));
        t.push((33422, w.bytes(&[0, 1, 1, 2], 1)));
    }
    t
}

/// Pixel data of the layout: blocks and the order they go into the file.
fn blocks(
    w: &Writer,
    cpp: usize,
    layout: &Layout,
    tags: &mut Vec<(u16, Value)>,
) -> (Vec<Vec<u8>>, Vec<usize>, u16, u16) {
    match *layout {
        Layout::StripsReversed(rows) => {
            tags.push((278, w.u32s(&[rows as u32])));
            let strips: Vec<Vec<u8>> = (0..H.div_ceil(rows))
                .map(|k| {
                    let v: Vec<u16> = (k * rows..((k + 1) * rows).min(H))
                        .flat_map(|y| (0..W).flat_map(move |x| (0..cpp).map(move |c| value(x, y, c))))
                        .collect();
                    w.sample_bytes(&v)
                })
                .collect();
            let order = (0..strips.len()).rev().collect();
            (strips, order, 273, 279)
        }
        Layout::Tiles(tw, tl) | Layout::LjpegTiles(tw, tl) => {
            let compressed = matches!(layout, Layout::LjpegTiles(..));
            if compressed {
                tags.retain(|t| t.0 != 259);
                tags.push((259, w.u16s(&[7])));
            }
            tags.push((322, w.u32s(&[tw as u32])));
            tags.push((323, w.u32s(&[tl as u32])));
            let (across, down) = (W.div_ceil(tw), H.div_ceil(tl));
            let tiles: Vec<Vec<u8>> = (0..across * down)
                .map(|k| {
                    let (x0, y0) = ((k % across) * tw, (k / across) * tl);
                    // Padding outside the image: a value that would show if read.
                    let v: Vec<u16> =
                        (0..tl)
                            .flat_map(|y| {
                                (0..tw).flat_map(move |x| {
                                    (0..cpp).map(move |c| {
                                        if x0 + x < W && y0 + y < H {
                                            value(x0 + x, y0 + y, c)
                                        } else {
                                            65535
                                        }
                                    })
                                })
                            })
                            .collect();
                    if compressed {
                        ljpeg(&v, tw, tl, cpp)
                    } else {
                        w.sample_bytes(&v)
                    }
                })
                .collect();
            let order = (0..tiles.len()).collect();
            (tiles, order, 324, 325)
        }
    }
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lucent-dng-phone-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// Writes a linear (three-channel) DNG with per-channel levels and opcode lists.
fn write_linear(path: &Path, le: bool, layout: &Layout) {
    let w = Writer { le };
    let mut tags = dng_tags(&w, 3, true);
    tags.push((50713, w.u16s(&[1, 1])));
    tags.push((50714, w.u16s(&[256, 260, 264]))); // BlackLevel per sample
    tags.push((50717, w.u16s(&[16000, 16100, 16200]))); // WhiteLevel per sample
    tags.push((50719, w.u32s(&[2, 2]))); // DefaultCropOrigin
    tags.push((50720, w.u32s(&[36, 26]))); // DefaultCropSize
    tags.push((51009, w.bytes(&[0, 0, 0, 1, 0, 0, 0, 0], 7))); // OpcodeList2: one (empty) list
    tags.push((51022, w.bytes(&[0, 0, 0, 0], 7))); // OpcodeList3: no opcodes
    let (b, order, ot, ct) = blocks(&w, 3, layout, &mut tags);
    std::fs::write(path, w.file(tags, &b, &order, ot, ct)).unwrap();
}

const LINEAR_BLACK: [f64; 3] = [256.0, 260.0, 264.0];
const LINEAR_WHITE: [f64; 3] = [16000.0, 16100.0, 16200.0];

#[test]
fn linear_phone_dngs_decode_to_the_stored_camera_rgb() {
    for (le, layout, name) in [
        (true, Layout::Tiles(16, 16), "tiled_le.dng"),
        (false, Layout::Tiles(16, 8), "tiled_be.dng"),
        (true, Layout::StripsReversed(7), "strips_le.dng"),
        (true, Layout::LjpegTiles(16, 16), "ljpeg_tiled_le.dng"),
        (false, Layout::LjpegTiles(24, 8), "ljpeg_tiled_be.dng"),
    ] {
        let path = temp(name);
        write_linear(&path, le, &layout);
        let frame = read_raw(&path, None).unwrap_or_else(|e| panic!("{name}: {e}"));
        let m = &frame.meta;
        assert!(m.dng && m.samples_per_pixel == 3 && m.cfa_pattern.is_empty(), "{name}: {m:?}");
        assert_eq!(&m.black_levels[..3], &LINEAR_BLACK.map(|v| v as f32), "{name}: per-channel black");
        assert_eq!(&m.white_levels[..3], &LINEAR_WHITE.map(|v| v as f32), "{name}: per-channel white");
        assert!(m.warnings.iter().any(|w| w.contains("OpcodeList2")), "{name}: {:?}", m.warnings);
        assert!(m.warnings.iter().any(|w| w.contains("OpcodeList3")), "{name}: {:?}", m.warnings);
        assert!(m.warnings.iter().any(|w| w.contains("DefaultCrop")), "{name}: {:?}", m.warnings);
        let wb = m.camera_wb_multipliers.unwrap();
        assert!((wb[0] - 2.0).abs() < 1e-6 && (wb[2] - 1.6).abs() < 1e-6, "{wb:?}");
        assert!((m.xyz_to_camera[1][1] - 1.246).abs() < 1e-6);
        let RawData::Rgb(img) = &frame.data else { panic!("{name}: three-channel data") };
        assert_eq!((img.width, img.height), (W, H));
        assert_eq!(raw_output_size(&path).unwrap(), (m.output_width, m.output_height), "{name}: header-only size");
        for y in 0..H {
            for x in 0..W {
                for c in 0..3 {
                    let want =
                        ((f64::from(value(x, y, c)) - LINEAR_BLACK[c]) / (LINEAR_WHITE[c] - LINEAR_BLACK[c])) as f32;
                    assert_eq!(img.pixel(x, y)[c], want, "{name} ({x}, {y}) channel {c}");
                }
            }
        }
        // Through develop: no demosaicing, the same numbers.
        let (rgb, meta) = decode_raw(&path, &RawOptions::default()).unwrap();
        assert_eq!(&rgb, img);
        assert_eq!(meta.demosaic, "none (linear DNG)");
        std::fs::remove_file(&path).ok();
    }
}

#[test]
fn bayer_dngs_in_strips_and_tiles_of_either_byte_order_decode_exactly() {
    let black = [512.0, 514.0, 516.0, 518.0];
    let white = 15000.0;
    for (le, layout, name) in
        [(false, Layout::StripsReversed(7), "bayer_strips_be.dng"), (true, Layout::Tiles(16, 16), "bayer_tiles_le.dng")]
    {
        let w = Writer { le };
        let mut tags = dng_tags(&w, 1, false);
        tags.push((50713, w.u16s(&[2, 2])));
        tags.push((50714, w.u16s(&black.map(|v| v as u16))));
        tags.push((50717, w.u16s(&[white as u16])));
        tags.push((50829, w.u32s(&[2, 4, 28, 38]))); // ActiveArea top, left, bottom, right
        tags.push((51008, w.bytes(&[0, 0, 0, 0], 7))); // OpcodeList1
        let (b, order, ot, ct) = blocks(&w, 1, &layout, &mut tags);
        let path = temp(name);
        std::fs::write(&path, w.file(tags, &b, &order, ot, ct)).unwrap();
        let frame = read_raw(&path, None).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(frame.meta.cfa_pattern, "RGGB", "{name}");
        assert!(frame.meta.warnings.iter().any(|w| w.contains("OpcodeList1")), "{:?}", frame.meta.warnings);
        let RawData::Bayer(mos) = &frame.data else { panic!("{name}: Bayer") };
        assert_eq!((mos.width, mos.height), (34, 26));
        let m = &frame.meta;
        assert_eq!(raw_output_size(&path).unwrap(), (m.output_width, m.output_height), "{name}: header-only size");
        for y in 0..26 {
            for x in 0..34 {
                let k = 2 * (y & 1) + (x & 1);
                let want = ((f64::from(value(x + 4, y + 2, 0)) - black[k]) / (white - black[k])) as f32;
                assert_eq!(mos.data[y * 34 + x], want, "{name} ({x}, {y})");
            }
        }
        std::fs::remove_file(&path).ok();
    }
}

#[test]
fn rawloader_alone_misreads_these_variants() {
    // Why raw.rs reads uncompressed DNGs itself: rawloader 0.37 refuses tiles,
    // reads strips as one contiguous block and 16-bit data as little-endian,
    // and keeps one black level for the three channels of a linear DNG.
    let decode = |path: &Path| rawloader::decode(&mut std::io::Cursor::new(std::fs::read(path).unwrap()));
    let tiled = temp("rl_tiled.dng");
    write_linear(&tiled, true, &Layout::Tiles(16, 16));
    assert!(decode(&tiled).is_err(), "rawloader read uncompressed tiles");
    // Strips stored last first: rawloader reads from the first offset on, past the file's end.
    let strips = temp("rl_strips.dng");
    write_linear(&strips, true, &Layout::StripsReversed(7));
    match decode(&strips) {
        Err(_) => {}
        Ok(img) => {
            let rawloader::RawImageData::Integer(v) = &img.data else { panic!() };
            assert_ne!(v[0], value(0, 0, 0), "rawloader found the first strip");
        }
    }
    let be = temp("rl_be.dng");
    write_linear(&be, false, &Layout::StripsReversed(H));
    let img = decode(&be).unwrap();
    let rawloader::RawImageData::Integer(v) = &img.data else { panic!() };
    assert_eq!(v[0], value(0, 0, 0).swap_bytes(), "rawloader read big-endian samples");
    assert_eq!(img.blacklevels, [256; 4], "rawloader kept per-channel black levels");
    for p in [tiled, strips, be] {
        std::fs::remove_file(p).ok();
    }
}

#[test]
fn broken_phone_dngs_are_errors_naming_the_file() {
    let w = Writer { le: true };
    // Tile offsets for fewer tiles than the image needs.
    let mut tags = dng_tags(&w, 3, true);
    let (b, _, _, _) = blocks(&w, 3, &Layout::Tiles(16, 16), &mut tags);
    let bad = temp("too_few_tiles.dng");
    std::fs::write(&bad, w.file(tags, &b[..4], &[0, 1, 2, 3], 324, 325)).unwrap();
    let e = read_raw(&bad, None).unwrap_err().to_string();
    assert_eq!(raw_output_size(&bad).unwrap_err().to_string(), e, "header-only: the same error");
    assert!(e.contains("too_few_tiles.dng") && e.contains("tile offsets"), "{e}");
    // LinearRaw with one sample per pixel.
    let mut tags = dng_tags(&w, 1, true);
    let (b, order, ot, ct) = blocks(&w, 1, &Layout::StripsReversed(H), &mut tags);
    let bad = temp("linear_one_sample.dng");
    std::fs::write(&bad, w.file(tags, &b, &order, ot, ct)).unwrap();
    let e = read_raw(&bad, None).unwrap_err().to_string();
    assert_eq!(raw_output_size(&bad).unwrap_err().to_string(), e, "header-only: the same error");
    assert!(e.contains("linear_one_sample.dng") && e.contains("samples per pixel"), "{e}");
    // A compression other than none (1) and lossless JPEG (7): JPEG XL, as newer phones write.
    let mut tags = dng_tags(&w, 3, true);
    let (b, order, ot, ct) = blocks(&w, 3, &Layout::Tiles(16, 16), &mut tags);
    tags.retain(|t| t.0 != 259);
    tags.push((259, w.u16s(&[52546])));
    let bad = temp("jpeg_xl.dng");
    std::fs::write(&bad, w.file(tags, &b, &order, ot, ct)).unwrap();
    let e = read_raw(&bad, None).unwrap_err().to_string();
    assert_eq!(raw_output_size(&bad).unwrap_err().to_string(), e, "header-only: the same error");
    assert!(e.contains("jpeg_xl.dng") && e.contains("compression 52546") && e.contains("JPEG XL"), "{e}");
    // Lossless JPEG with predictor 6, which rawloader does not decode.
    let mut tags = dng_tags(&w, 3, true);
    let (mut b, order, ot, ct) = blocks(&w, 3, &Layout::LjpegTiles(16, 16), &mut tags);
    let sos = b[0].windows(2).position(|m| m == [0xFF, 0xDA]).unwrap();
    assert_eq!(b[0][sos + 5 + 2 * 3], 1, "SOS: Ns = 3, three component specs, then Ss");
    b[0][sos + 5 + 2 * 3] = 6;
    let bad = temp("ljpeg_predictor6.dng");
    std::fs::write(&bad, w.file(tags, &b, &order, ot, ct)).unwrap();
    let e = read_raw(&bad, None).unwrap_err().to_string();
    assert_eq!(raw_output_size(&bad).unwrap_err().to_string(), e, "header-only: the same error");
    assert!(e.contains("ljpeg_predictor6.dng") && e.contains("predictor 6"), "{e}");
    // Cut inside the last tile.
    let good = temp("cut_tiles.dng");
    write_linear(&good, true, &Layout::Tiles(16, 16));
    let bytes = std::fs::read(&good).unwrap();
    let first_tile_end = 8 + 16 * 16 * 3 * 2;
    std::fs::write(&good, &bytes[..first_tile_end + 100]).unwrap();
    let e = read_raw(&good, None).unwrap_err().to_string();
    assert_eq!(raw_output_size(&good).unwrap_err().to_string(), e, "header-only: the same error");
    assert!(e.contains("cut_tiles.dng") && (e.contains("truncated") || e.contains("corrupt")), "{e}");
}
