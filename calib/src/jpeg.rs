//! The size of a JPEG photo as [`crate::cv::read_rgb8`] decodes it, read
//! from the file's markers alone (ITU-T T.81, Annex B): the frame header
//! (SOFn: height and width in pixels) and the EXIF orientation of an APP1
//! segment before it (JEITA CP-3451, tag 0x0112). OpenCV's decoder turns
//! the image upright by that tag, so orientations 5–8 swap the width and
//! height. Planning a project needs the size of every photo; this reads a
//! few kilobytes instead of decoding megapixels.
//!
//! ```no_run
//! let (w, h) = lucent_calib::jpeg::jpeg_size(std::path::Path::new("photo.jpg")).unwrap();
//! println!("{w} × {h} px");
//! ```

use crate::raw::Orientation;
use std::io::{BufReader, Read};
use std::path::Path;
use thiserror::Error;

/// Why a JPEG's size cannot be read from its markers.
#[derive(Debug, Error)]
#[error("{path}: {reason}")]
pub struct JpegHeaderError {
    pub path: std::path::PathBuf,
    pub reason: String,
}

/// Start-of-frame markers: baseline, extended, progressive and lossless,
/// Huffman or arithmetic coded (not DHT 0xC4, JPG 0xC8 or DAC 0xCC).
fn is_frame_header(marker: u8) -> bool {
    matches!(marker, 0xC0..=0xCF) && !matches!(marker, 0xC4 | 0xC8 | 0xCC)
}

/// Width and height in pixels of the upright image (EXIF orientation applied).
pub fn jpeg_size(path: &Path) -> Result<(usize, usize), JpegHeaderError> {
    let err = |reason: &str| JpegHeaderError { path: path.to_path_buf(), reason: reason.to_string() };
    let file = std::fs::File::open(path).map_err(|e| err(&e.to_string()))?;
    let ((w, h), orientation) = read_header(&mut BufReader::new(file)).map_err(|r| err(&r))?;
    Ok(if orientation.transposes() { (h, w) } else { (w, h) })
}

/// The frame's (width, height) as stored and the orientation of the EXIF
/// segment before it (1, as stored, without one).
fn read_header(r: &mut impl Read) -> Result<((usize, usize), Orientation), String> {
    let truncated = |e: std::io::Error| {
        if e.kind() == std::io::ErrorKind::UnexpectedEof {
            "ends before its frame header (a cut-off or empty file)".to_string()
        } else {
            e.to_string()
        }
    };
    let mut two = [0u8; 2];
    r.read_exact(&mut two).map_err(truncated)?;
    if two != [0xFF, 0xD8] {
        return Err("not a JPEG file (no start-of-image marker)".into());
    }
    let mut orientation = Orientation::from_exif(1);
    loop {
        let (code, body) = next_segment(r).map_err(|e| match e {
            SegmentError::Io(e) => truncated(e),
            SegmentError::Corrupt(why) => why,
        })?;
        if code == 0xD9 || code == 0xDA {
            return Err("no frame header before the image data".into());
        }
        if code == 0xE1 && body.starts_with(b"Exif\0\0") {
            orientation = exif_orientation(&body[6..]).unwrap_or(orientation);
        } else if is_frame_header(code) {
            // P (1 byte), Y (2), X (2), components …
            if body.len() < 6 {
                return Err("frame header too short".into());
            }
            let h = usize::from(u16::from_be_bytes([body[1], body[2]]));
            let w = usize::from(u16::from_be_bytes([body[3], body[4]]));
            if w == 0 || h == 0 {
                return Err(format!(
                    "frame header gives {w} × {h} pixels (a height set later by a DNL marker is not supported)"
                ));
            }
            return Ok(((w, h), orientation));
        }
    }
}

/// Why [`next_segment`] found no segment.
pub(crate) enum SegmentError {
    /// The reader failed or ended (`UnexpectedEof`: the data is cut off).
    Io(std::io::Error),
    /// Bytes that are not a marker where one should start, or a length under 2.
    Corrupt(String),
}

/// The next marker segment after SOI (T.81 B.1.1.4): its marker code and
/// the bytes its length covers (empty for EOI and for markers without a
/// length: TEM, RSTn, which are skipped). Fill bytes 0xFF before a code are
/// skipped. Also the DNG reader's walk to a lossless-JPEG tile's scan header.
pub(crate) fn next_segment(r: &mut impl Read) -> Result<(u8, Vec<u8>), SegmentError> {
    let mut b = [0u8; 1];
    loop {
        r.read_exact(&mut b).map_err(SegmentError::Io)?;
        if b[0] != 0xFF {
            return Err(SegmentError::Corrupt(format!(
                "corrupt marker structure (byte 0x{:02X} where a marker should start)",
                b[0]
            )));
        }
        let mut code = 0xFF;
        while code == 0xFF {
            r.read_exact(&mut b).map_err(SegmentError::Io)?;
            code = b[0];
        }
        // Markers without a length: TEM, RSTn, SOI; EOI ends the data.
        if code == 0x01 || (0xD0..=0xD8).contains(&code) {
            continue;
        }
        if code == 0xD9 {
            return Ok((code, Vec::new()));
        }
        let mut two = [0u8; 2];
        r.read_exact(&mut two).map_err(SegmentError::Io)?;
        let len = usize::from(u16::from_be_bytes(two));
        if len < 2 {
            return Err(SegmentError::Corrupt(format!("corrupt segment length {len} of marker 0x{code:02X}")));
        }
        let mut body = vec![0u8; len - 2];
        r.read_exact(&mut body).map_err(SegmentError::Io)?;
        return Ok((code, body));
    }
}

/// The orientation tag of an EXIF block (TIFF structure), when it has one.
fn exif_orientation(tiff: &[u8]) -> Option<Orientation> {
    let exif = exif::Reader::new().read_raw(tiff.to_vec()).ok()?;
    let field = exif.get_field(exif::Tag::Orientation, exif::In::PRIMARY)?;
    let v = field.value.get_uint(0)?;
    Some(Orientation::from_exif(u16::try_from(v).ok()?))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A minimal EXIF APP1 body ("Exif\0\0" + little-endian TIFF, one IFD
    /// entry: Orientation = `o`).
    pub(super) fn exif_app1(o: u16) -> Vec<u8> {
        let mut t = b"Exif\0\0II*\0".to_vec();
        t.extend(8u32.to_le_bytes()); // IFD0 offset
        t.extend(1u16.to_le_bytes()); // one entry
        t.extend(0x0112u16.to_le_bytes()); // Orientation
        t.extend(3u16.to_le_bytes()); // SHORT
        t.extend(1u32.to_le_bytes()); // count
        t.extend(o.to_le_bytes());
        t.extend([0, 0]);
        t.extend(0u32.to_le_bytes()); // no next IFD
        let mut seg = vec![0xFF, 0xE1];
        seg.extend(u16::try_from(t.len() + 2).unwrap().to_be_bytes());
        seg.extend(t);
        seg
    }

    fn header(w: u16, h: u16, before: &[u8]) -> Vec<u8> {
        let mut f = vec![0xFF, 0xD8];
        f.extend(before);
        f.extend([0xFF, 0xDB, 0, 3, 0]); // a (short) quantisation table segment
        f.extend([0xFF, 0xC2, 0, 11, 8]); // progressive frame, 8 bits
        f.extend(h.to_be_bytes());
        f.extend(w.to_be_bytes());
        f.extend([1, 1, 0x11, 0]);
        f.extend([0xFF, 0xDA]);
        f
    }

    #[test]
    fn reads_the_frame_size_and_turns_it_by_the_orientation() {
        let plain = header(640, 480, &[]);
        assert_eq!(read_header(&mut plain.as_slice()).unwrap(), ((640, 480), Orientation(1)));
        let turned = header(640, 480, &exif_app1(6));
        assert_eq!(read_header(&mut turned.as_slice()).unwrap(), ((640, 480), Orientation(6)));
        let dir = std::env::temp_dir().join(format!("lucent-jpeg-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("turned.jpg");
        std::fs::write(&p, &turned).unwrap();
        assert_eq!(jpeg_size(&p).unwrap(), (480, 640));
        std::fs::write(&p, header(640, 480, &exif_app1(3))).unwrap();
        assert_eq!(jpeg_size(&p).unwrap(), (640, 480));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn refuses_what_is_not_a_jpeg_header() {
        assert!(read_header(&mut &b"\x89PNG\r\n"[..]).unwrap_err().contains("not a JPEG"));
        let cut = &header(640, 480, &[])[..12];
        assert!(read_header(&mut &cut[..]).unwrap_err().contains("cut-off"));
        let mut no_frame = vec![0xFF, 0xD8, 0xFF, 0xDA];
        no_frame.extend([0, 2]);
        assert!(read_header(&mut no_frame.as_slice()).unwrap_err().contains("no frame header"));
        assert!(read_header(&mut &[0xFF, 0xD8, 0x12][..]).unwrap_err().contains("corrupt marker"));
    }
}

/// Against OpenCV's decoder (the reader whose size this must give): real
/// photos as they are and with an EXIF orientation that turns them.
#[cfg(test)]
mod against_opencv {
    use super::*;

    fn root(rel: &str) -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(rel)
    }

    #[test]
    fn gives_the_size_opencv_decodes() {
        let dir = std::env::temp_dir().join(format!("lucent-jpeg-cv-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for photo in ["fixtures/colour/colorchecker.jpg", "fixtures/camera/chessboard/left01.jpg"] {
            let p = root(photo);
            let img = crate::cv::read_rgb8(&p).unwrap();
            assert_eq!(jpeg_size(&p).unwrap(), (img.width, img.height), "{photo}");
            for o in [3u16, 6, 8] {
                let bytes = std::fs::read(&p).unwrap();
                let mut turned = bytes[..2].to_vec();
                turned.extend(super::tests::exif_app1(o));
                turned.extend(&bytes[2..]);
                let q = dir.join(format!("o{o}.jpg"));
                std::fs::write(&q, &turned).unwrap();
                let img = crate::cv::read_rgb8(&q).unwrap();
                let (w, h) = jpeg_size(&q).unwrap();
                assert_eq!((w, h), (img.width, img.height), "{photo} with orientation {o}");
                if o != 3 {
                    assert!(w < h || img.width == img.height, "{photo}: orientation {o} stands the photo up");
                }
            }
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
