//! ISO 25178-72 X3P surface files: reading and writing.
//!
//! An X3P file is a zip archive holding `main.xml` (namespace
//! `http://www.opengps.eu/2008/ISO5436_2`), `md5checksum.hex` (the MD5 of
//! `main.xml`, `md5sum` layout) and, unless the points are written into
//! `main.xml` as a `DataList` of `Datum` texts, a binary point file
//! (`bindata/data.bin`, named by `Record3/DataLink/PointDataLink`) with an
//! optional validity file (`ValidPointsLink`, one bit per point, least
//! significant bit first, 1 = valid).
//!
//! What is read (ISO 25178-72:2017 and its Amd 1:2020, both revisions):
//! - `FeatureType` SUR with a `MatrixDimension` (SizeX × SizeY × SizeZ; of
//!   several layers the first is used and a note says so); x fastest, then y.
//!   Profiles (PRF), point clouds (PCL), point lists and absolute (irregular)
//!   lateral axes are refused with a clear error.
//! - Lateral axes CX, CY: incremental, pitch = `Increment` in metres (must be
//!   positive and finite).
//! - Heights CZ: absolute, point type I (int16), L (int32), F (float32) or
//!   D (float64), little-endian; height = stored value × `Increment`
//!   (default 1) in metres, as in Amd 1:2020 (`Offset` places the view
//!   coordinate system and is not added).
//! - Invalid points: NaN in F/D, a 0 bit in the validity file for any type,
//!   an empty `Datum`. They become NaN in the [`HeightMap`].
//! - Checks: zip integrity (a truncated archive or a damaged member is an
//!   error), the MD5 of `main.xml`, of the point file and of the validity file
//!   when stated, and that the point file holds exactly SizeX·SizeY·SizeZ
//!   points.
//!
//! Writing ([`write_x3p`]) produces Amd 1:2020 files valid against the
//! standard's schema: Record1–4, binary points in the chosen type, a validity
//! file for the integer types when points are invalid, all three MD5
//! checksums, fixed zip timestamps (the same map gives the same bytes).
//!
//! ```
//! use lucent::surface::HeightMap;
//! use lucent::surface::x3p::{read_x3p, write_x3p, PointType, WriteOptions};
//! let dir = std::env::temp_dir().join("lucent-doc-x3p");
//! let map = HeightMap::new(3, 2, 0.871e-6, 0.871e-6, vec![0.0, 1e-8, f64::NAN, -2e-8, 5e-9, 0.0], "doc").unwrap();
//! write_x3p(&dir.join("a.x3p"), &map, &WriteOptions { point_type: PointType::F, ..Default::default() }).unwrap();
//! let back = read_x3p(&dir.join("a.x3p")).unwrap();
//! assert_eq!((back.nx, back.ny, back.valid_count()), (3, 2, 5));
//! assert_eq!(back.pitch_x_m, 0.871e-6);
//! ```

use super::error::SurfaceError;
use super::map::HeightMap;
use crate::io::write_atomic;
use md5::{Digest, Md5};
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

/// XML namespace of `main.xml`.
pub const NAMESPACE: &str = "http://www.opengps.eu/2008/ISO5436_2";

/// The storage type of the heights (the `DataType` of the z axis).
#[derive(Debug, Clone, Copy, PartialEq, Eq, EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage)]
#[strum(ascii_case_insensitive)]
#[derive(serde::Serialize, serde::Deserialize)]
pub enum PointType {
    /// 16-bit signed integer, scaled by the increment.
    I,
    /// 32-bit signed integer, scaled by the increment.
    L,
    /// 32-bit IEEE float, metres (increment 1).
    F,
    /// 64-bit IEEE float, metres (increment 1).
    D,
}

impl PointType {
    /// Bytes per stored value.
    pub fn size(self) -> usize {
        match self {
            PointType::I => 2,
            PointType::L | PointType::F => 4,
            PointType::D => 8,
        }
    }

    fn letter(self) -> &'static str {
        self.into()
    }

    /// The letter as X3P writes it (upper case, exactly).
    fn parse(text: &str) -> Option<Self> {
        let t = text.trim();
        <Self as strum::VariantArray>::VARIANTS.iter().copied().find(|p| p.letter() == t)
    }

    fn is_integer(self) -> bool {
        matches!(self, PointType::I | PointType::L)
    }
}

/// Options of [`write_x3p`].
#[derive(Debug, Clone)]
pub struct WriteOptions {
    pub point_type: PointType,
    /// `Record2/Date` (xsd:dateTime). Fixed by default so that output is reproducible.
    pub date: String,
    /// `Record2/Creator`.
    pub creator: Option<String>,
    /// `Record2/Comment`.
    pub comment: Option<String>,
}

impl Default for WriteOptions {
    fn default() -> Self {
        WriteOptions {
            point_type: PointType::D,
            date: "2026-01-01T00:00:00+00:00".into(),
            creator: None,
            comment: None,
        }
    }
}

fn md5_hex(bytes: &[u8]) -> String {
    Md5::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

fn xml_escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

/// Formats a double so that it parses back to the same value (Rust's
/// shortest round-trip form, valid as xsd:double).
fn xsd_double(v: f64) -> String {
    format!("{v:e}")
}

/// The X3P archive of `map` as bytes.
pub fn x3p_bytes(map: &HeightMap, options: &WriteOptions) -> Result<Vec<u8>, SurfaceError> {
    let n = map.nx * map.ny;
    let t = options.point_type;
    let max_abs = map.heights_m.iter().filter(|h| h.is_finite()).fold(0.0f64, |a, h| a.max(h.abs()));
    let increment = match t {
        PointType::F | PointType::D => 1.0,
        PointType::I if max_abs > 0.0 => max_abs / i16::MAX as f64,
        PointType::L if max_abs > 0.0 => max_abs / i32::MAX as f64,
        _ => 1e-9,
    };
    let mut data = Vec::with_capacity(n * t.size());
    let mut valid_bits = vec![0u8; n.div_ceil(8)];
    let mut any_invalid = false;
    for (k, h) in map.heights_m.iter().enumerate() {
        let valid = h.is_finite();
        if valid {
            valid_bits[k / 8] |= 1 << (k % 8);
        } else {
            any_invalid = true;
        }
        match t {
            PointType::I => {
                let v = if valid { (h / increment).round().clamp(i16::MIN as f64, i16::MAX as f64) as i16 } else { 0 };
                data.extend_from_slice(&v.to_le_bytes());
            }
            PointType::L => {
                let v = if valid { (h / increment).round().clamp(i32::MIN as f64, i32::MAX as f64) as i32 } else { 0 };
                data.extend_from_slice(&v.to_le_bytes());
            }
            PointType::F => {
                let v = if valid { *h as f32 } else { f32::NAN };
                data.extend_from_slice(&v.to_le_bytes());
            }
            PointType::D => {
                let v = if valid { *h } else { f64::NAN };
                data.extend_from_slice(&v.to_le_bytes());
            }
        }
    }
    // Integer types have no value for a missing point: they need the validity file.
    let write_valid = any_invalid && t.is_integer();
    let mut link = format!(
        "      <PointDataLink>bindata/data.bin</PointDataLink>\n      <MD5ChecksumPointData>{}</MD5ChecksumPointData>\n",
        md5_hex(&data)
    );
    if write_valid {
        link.push_str(&format!(
            "      <ValidPointsLink>bindata/valid.bin</ValidPointsLink>\n      <MD5ChecksumValidPoints>{}</MD5ChecksumValidPoints>\n",
            md5_hex(&valid_bits)
        ));
    }
    let creator =
        options.creator.as_ref().map(|c| format!("    <Creator>{}</Creator>\n", xml_escape(c))).unwrap_or_default();
    let comment =
        options.comment.as_ref().map(|c| format!("    <Comment>{}</Comment>\n", xml_escape(c))).unwrap_or_default();
    let main = format!(
        r#"<?xml version="1.0" encoding="UTF-8"?>
<p:ISO5436_2 xmlns:p="{NAMESPACE}" xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance" xsi:schemaLocation="{NAMESPACE} {NAMESPACE}/ISO5436_2.xsd">
  <Record1>
    <Revision>ISO25178-72:2017/DAM1</Revision>
    <FeatureType>SUR</FeatureType>
    <Axes>
      <CX>
        <AxisType>I</AxisType>
        <DataType>D</DataType>
        <Increment>{px}</Increment>
        <Offset>0</Offset>
      </CX>
      <CY>
        <AxisType>I</AxisType>
        <DataType>D</DataType>
        <Increment>{py}</Increment>
        <Offset>0</Offset>
      </CY>
      <CZ>
        <AxisType>A</AxisType>
        <DataType>{dt}</DataType>
        <Increment>{pz}</Increment>
        <Offset>0</Offset>
      </CZ>
    </Axes>
  </Record1>
  <Record2>
    <Date>{date}</Date>
{creator}    <Instrument>
      <Manufacturer>lucent</Manufacturer>
      <Model>lucent surface</Model>
      <Serial>none</Serial>
      <Version>{version}</Version>
    </Instrument>
    <ProbingSystem>
      <Type>Software</Type>
      <Identification>lucent {version}</Identification>
    </ProbingSystem>
{comment}  </Record2>
  <Record3>
    <MatrixDimension>
      <SizeX>{nx}</SizeX>
      <SizeY>{ny}</SizeY>
      <SizeZ>1</SizeZ>
    </MatrixDimension>
    <DataLink>
{link}    </DataLink>
  </Record3>
  <Record4>
    <ChecksumFile>md5checksum.hex</ChecksumFile>
  </Record4>
</p:ISO5436_2>
"#,
        px = xsd_double(map.pitch_x_m),
        py = xsd_double(map.pitch_y_m),
        pz = xsd_double(increment),
        dt = t.letter(),
        date = xml_escape(&options.date),
        version = env!("CARGO_PKG_VERSION"),
        nx = map.nx,
        ny = map.ny,
    );
    let checksum = format!("{} *main.xml\n", md5_hex(main.as_bytes()));
    let mut members: Vec<(&str, &[u8])> =
        vec![("main.xml", main.as_bytes()), ("md5checksum.hex", checksum.as_bytes()), ("bindata/data.bin", &data)];
    if write_valid {
        members.push(("bindata/valid.bin", &valid_bits));
    }
    let zip_err = |e: zip::result::ZipError| SurfaceError::Data {
        origin: map.origin.clone(),
        reason: format!("cannot build the zip archive: {e}"),
    };
    let mut writer = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    let opts = zip::write::SimpleFileOptions::default()
        .compression_method(zip::CompressionMethod::Deflated)
        .last_modified_time(zip::DateTime::DEFAULT)
        .unix_permissions(0o644);
    for (name, bytes) in members {
        writer.start_file(name, opts).map_err(zip_err)?;
        writer.write_all(bytes).map_err(|e| zip_err(e.into()))?;
    }
    Ok(writer.finish().map_err(zip_err)?.into_inner())
}

/// Writes `map` as an X3P file, atomically.
pub fn write_x3p(path: &Path, map: &HeightMap, options: &WriteOptions) -> Result<(), SurfaceError> {
    let bytes = x3p_bytes(map, options)?;
    Ok(write_atomic(path, &bytes)?)
}

/// Reads an X3P file into a [`HeightMap`] (metres).
pub fn read_x3p(path: &Path) -> Result<HeightMap, SurfaceError> {
    let bytes = std::fs::read(path).map_err(|source| SurfaceError::Io { path: path.into(), source })?;
    read_x3p_bytes(&bytes, path)
}

struct Archive<'a> {
    path: PathBuf,
    zip: zip::ZipArchive<std::io::Cursor<&'a [u8]>>,
    /// Folder of main.xml inside the archive ("" or "name/").
    prefix: String,
}

impl Archive<'_> {
    fn has(&mut self, name: &str) -> bool {
        self.zip.index_for_name(&format!("{}{name}", self.prefix)).is_some()
    }

    fn read(&mut self, name: &str) -> Result<Vec<u8>, SurfaceError> {
        let full = format!("{}{name}", self.prefix);
        let member_err =
            |reason: String| SurfaceError::Member { path: self.path.clone(), member: name.to_string(), reason };
        let mut file = match self.zip.by_name(&full) {
            Ok(f) => f,
            Err(zip::result::ZipError::FileNotFound) => {
                return Err(member_err("not in the archive (main.xml refers to it)".into()))
            }
            Err(e) => return Err(member_err(format!("cannot read: {e}"))),
        };
        let declared = file.size();
        let mut out = Vec::with_capacity(declared.min(1 << 30) as usize);
        // The zip reader checks the CRC-32 when the member ends: a damaged or
        // cut member is an error here.
        file.read_to_end(&mut out).map_err(|e| member_err(format!("damaged: {e}")))?;
        if out.len() as u64 != declared {
            return Err(member_err(format!("holds {} bytes, the archive declares {declared}", out.len())));
        }
        Ok(out)
    }
}

/// Child element of `node` with local name `name`.
fn child<'a, 'i>(node: roxmltree::Node<'a, 'i>, name: &str) -> Option<roxmltree::Node<'a, 'i>> {
    node.children().find(|c| c.is_element() && c.tag_name().name() == name)
}

fn text_of(node: roxmltree::Node) -> String {
    node.text().unwrap_or("").trim().to_string()
}

/// One axis of Record1.
struct Axis {
    incremental: bool,
    point_type: Option<PointType>,
    increment: f64,
}

/// Reads an X3P archive held in memory; `path` names it in messages.
pub fn read_x3p_bytes(bytes: &[u8], path: &Path) -> Result<HeightMap, SurfaceError> {
    let zip = zip::ZipArchive::new(std::io::Cursor::new(bytes))
        .map_err(|e| SurfaceError::Archive { path: path.into(), reason: e.to_string() })?;
    let mut notes = Vec::new();
    let prefix = main_xml_folder(&zip, path)?;
    let mut ar = Archive { path: path.into(), zip, prefix };
    let main = ar.read("main.xml")?;
    let text = std::str::from_utf8(&main).map_err(|e| xml_err(path, format!("not UTF-8: {e}")))?;
    let doc = roxmltree::Document::parse(text).map_err(|e| xml_err(path, e.to_string()))?;
    let root = doc.root_element();
    if root.tag_name().name() != "ISO5436_2" {
        return Err(xml_err(path, format!("root element <{}>, expected <ISO5436_2>", root.tag_name().name())));
    }

    // Checksum of main.xml (Record4 names the file).
    let record4 = need(root, "Record4", "ISO5436_2", path)?;
    let checksum_name = child(record4, "ChecksumFile").map(text_of).unwrap_or_else(|| "md5checksum.hex".into());
    if ar.has(&checksum_name) {
        let content = ar.read(&checksum_name)?;
        let stated = String::from_utf8_lossy(&content).split_whitespace().next().unwrap_or("").to_ascii_lowercase();
        let actual = md5_hex(&main);
        if stated != actual {
            return Err(SurfaceError::Checksum {
                path: path.into(),
                member: "main.xml".into(),
                expected: stated,
                actual,
                stated_in: checksum_name,
            });
        }
    } else {
        notes.push(format!("{}: no checksum file {checksum_name} (main.xml not verified)", path.display()));
    }

    let record1 = need(root, "Record1", "ISO5436_2", path)?;
    check_feature_type(record1, path)?;
    let axes = need(record1, "Axes", "Record1", path)?;
    let (cx, cy, cz) = (axis(axes, "CX", path)?, axis(axes, "CY", path)?, axis(axes, "CZ", path)?);
    if !cx.incremental || !cy.incremental {
        return Err(SurfaceError::Format {
            path: path.into(),
            reason: "absolute lateral axes (an irregular grid with stored x, y) are not supported: lucent needs a regular grid (CX, CY incremental)".into(),
        });
    }
    for (what, value) in [("CX/Increment (x pitch)", cx.increment), ("CY/Increment (y pitch)", cy.increment)] {
        if !(value.is_finite() && value > 0.0) {
            return Err(SurfaceError::Pitch { origin: path.display().to_string(), what: what.into(), value });
        }
    }
    if cz.incremental {
        return Err(xml_err(path, "CZ/AxisType I: the height axis must be absolute (A)".into()));
    }
    if !(cz.increment.is_finite() && cz.increment != 0.0) {
        return Err(xml_err(path, format!("CZ/Increment {}: must be a finite, non-zero scale", cz.increment)));
    }
    let record3 = need(root, "Record3", "ISO5436_2", path)?;
    let dims = matrix_dimension(record3, path)?;
    if dims.nz > 1 {
        notes.push(format!("{}: {} layers (SizeZ); the first is used", path.display(), dims.nz));
    }
    let heights = if let Some(link) = child(record3, "DataLink") {
        linked_heights(&mut ar, link, &cz, &dims, path)?
    } else if let Some(list) = child(record3, "DataList") {
        listed_heights(list, &cz, &dims, path)?
    } else {
        return Err(xml_err(path, "Record3 has neither a DataLink nor a DataList".into()));
    };
    let mut map = HeightMap::new(dims.nx, dims.ny, cx.increment, cy.increment, heights, path.display().to_string())?;
    map.notes = notes;
    Ok(map)
}

/// An error in main.xml of the archive at `path`.
fn xml_err(path: &Path, reason: String) -> SurfaceError {
    SurfaceError::Xml { path: path.into(), reason }
}

/// The child element `name` of `node` (the element `within`); an error
/// naming both when it has none.
fn need<'a, 'i>(
    node: roxmltree::Node<'a, 'i>,
    name: &str,
    within: &str,
    path: &Path,
) -> Result<roxmltree::Node<'a, 'i>, SurfaceError> {
    child(node, name)
        .ok_or_else(|| SurfaceError::Xml { path: path.into(), reason: format!("<{within}> has no <{name}>") })
}

/// The folder of main.xml in the archive: "" at the root, or "name/" for
/// the archive's one folder holding one.
fn main_xml_folder(zip: &zip::ZipArchive<std::io::Cursor<&[u8]>>, path: &Path) -> Result<String, SurfaceError> {
    let names: Vec<String> = zip.file_names().filter_map(|s| s.ok().map(|s| s.into_owned())).collect();
    if names.iter().any(|n| n == "main.xml") {
        return Ok(String::new());
    }
    let nested: Vec<&String> =
        names.iter().filter(|n| n.ends_with("/main.xml") && n.matches('/').count() == 1).collect();
    match nested.as_slice() {
        [one] => Ok(one.trim_end_matches("main.xml").to_string()),
        [] => Err(SurfaceError::Member {
            path: path.into(),
            member: "main.xml".into(),
            reason: "not in the archive (not an X3P file?)".into(),
        }),
        _ => Err(SurfaceError::Format {
            path: path.into(),
            reason: "the archive holds several folders with a main.xml".into(),
        }),
    }
}

/// Record1's FeatureType: an areal surface (SUR), not a profile or a point cloud.
fn check_feature_type(record1: roxmltree::Node, path: &Path) -> Result<(), SurfaceError> {
    let feature = text_of(need(record1, "FeatureType", "Record1", path)?).to_ascii_uppercase();
    match feature.as_str() {
        "SUR" => Ok(()),
        "PRF" => Err(SurfaceError::Format {
            path: path.into(),
            reason: "a profile (FeatureType PRF), not an areal surface: a normal distribution needs a surface (SUR)"
                .into(),
        }),
        "PCL" => Err(SurfaceError::Format {
            path: path.into(),
            reason: "a point cloud (FeatureType PCL) is not supported: resample it to a grid (SUR) first".into(),
        }),
        other => Err(xml_err(path, format!("unknown FeatureType {other:?} (expected SUR, PRF or PCL)"))),
    }
}

/// The axis `name` (CX, CY or CZ) of Record1's `axes`.
fn axis(axes: roxmltree::Node, name: &str, path: &Path) -> Result<Axis, SurfaceError> {
    let a = need(axes, name, "Axes", path)?;
    let kind = text_of(need(a, "AxisType", name, path)?);
    let incremental = match kind.as_str() {
        "I" => true,
        "A" => false,
        other => return Err(xml_err(path, format!("{name}/AxisType {other:?}: expected I or A"))),
    };
    let point_type = match child(a, "DataType").map(text_of) {
        None => None,
        Some(t) => Some(
            PointType::parse(&t)
                .ok_or_else(|| xml_err(path, format!("{name}/DataType {t:?}: expected I, L, F or D")))?,
        ),
    };
    let increment = match child(a, "Increment").map(text_of) {
        None => 1.0,
        Some(t) if t.is_empty() => 1.0,
        Some(t) => t.parse::<f64>().map_err(|_| xml_err(path, format!("{name}/Increment {t:?} is not a number")))?,
    };
    Ok(Axis { incremental, point_type, increment })
}

/// Record3's MatrixDimension: the grid's size and its point counts.
struct Dimensions {
    nx: usize,
    ny: usize,
    nz: usize,
    /// Points of one layer (the heights read).
    layer: usize,
    /// Points of every layer (the points stored).
    total: usize,
    /// Where the count is stated, for messages.
    stated: String,
}

/// Record3's MatrixDimension (a grid, every size at least 1).
fn matrix_dimension(record3: roxmltree::Node, path: &Path) -> Result<Dimensions, SurfaceError> {
    let Some(matrix) = child(record3, "MatrixDimension") else {
        return Err(SurfaceError::Format {
            path: path.into(),
            reason: "Record3 has no MatrixDimension (a point list is not supported: lucent needs a grid)".into(),
        });
    };
    let size = |name: &str| -> Result<usize, SurfaceError> {
        let t = text_of(need(matrix, name, "MatrixDimension", path)?);
        t.parse::<usize>().map_err(|_| xml_err(path, format!("MatrixDimension/{name} {t:?} is not a count")))
    };
    let (nx, ny, nz) = (size("SizeX")?, size("SizeY")?, size("SizeZ")?);
    if nx == 0 || ny == 0 || nz == 0 {
        return Err(xml_err(path, format!("MatrixDimension {nx} × {ny} × {nz}: every size must be at least 1")));
    }
    let layer = nx.checked_mul(ny).ok_or_else(|| xml_err(path, format!("MatrixDimension {nx} × {ny} is too large")))?;
    let total = layer
        .checked_mul(nz)
        .ok_or_else(|| xml_err(path, format!("MatrixDimension {nx} × {ny} × {nz} is too large")))?;
    let stated = format!("main.xml (MatrixDimension {nx} × {ny} × {nz})");
    Ok(Dimensions { nx, ny, nz, layer, total, stated })
}

/// The first layer's heights from the binary point data of Record3's
/// DataLink (`link`), checked against its MD5, with its validity bits.
fn linked_heights(
    ar: &mut Archive,
    link: roxmltree::Node,
    cz: &Axis,
    dims: &Dimensions,
    path: &Path,
) -> Result<Vec<f64>, SurfaceError> {
    let (total, stated) = (dims.total, &dims.stated);
    let mut heights = vec![f64::NAN; dims.layer];
    let t = cz.point_type.ok_or_else(|| xml_err(path, "CZ has no DataType: cannot decode binary points".into()))?;
    let data_name = text_of(need(link, "PointDataLink", "DataLink", path)?).replace('\\', "/");
    let data = ar.read(&data_name)?;
    if data.len() != total * t.size() {
        return Err(SurfaceError::PointCount {
            path: path.into(),
            member: format!("{data_name} ({} bytes of {}-byte {} points)", data.len(), t.size(), t.letter()),
            got: data.len() / t.size(),
            expected: total,
            stated_in: stated.clone(),
        });
    }
    if let Some(sum) = child(link, "MD5ChecksumPointData").map(text_of).filter(|s| !s.is_empty()) {
        let actual = md5_hex(&data);
        if sum.to_ascii_lowercase() != actual {
            return Err(SurfaceError::Checksum {
                path: path.into(),
                member: data_name,
                expected: sum.to_ascii_lowercase(),
                actual,
                stated_in: "main.xml (MD5ChecksumPointData)".into(),
            });
        }
    }
    let inc = cz.increment;
    for (k, h) in heights.iter_mut().enumerate() {
        let b = &data[k * t.size()..(k + 1) * t.size()];
        let v = match t {
            PointType::I => i16::from_le_bytes([b[0], b[1]]) as f64 * inc,
            PointType::L => i32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64 * inc,
            PointType::F => f32::from_le_bytes([b[0], b[1], b[2], b[3]]) as f64 * inc,
            PointType::D => f64::from_le_bytes([b[0], b[1], b[2], b[3], b[4], b[5], b[6], b[7]]) * inc,
        };
        *h = if v.is_finite() { v } else { f64::NAN };
    }
    if let Some(valid_name) = child(link, "ValidPointsLink").map(text_of).filter(|s| !s.is_empty()) {
        let valid_name = valid_name.replace('\\', "/");
        let bits = ar.read(&valid_name)?;
        if bits.len() < total.div_ceil(8) {
            return Err(SurfaceError::PointCount {
                path: path.into(),
                member: format!("{valid_name} ({} bytes of validity bits)", bits.len()),
                got: bits.len() * 8,
                expected: total,
                stated_in: stated.clone(),
            });
        }
        if let Some(sum) = child(link, "MD5ChecksumValidPoints").map(text_of).filter(|s| !s.is_empty()) {
            let actual = md5_hex(&bits);
            if sum.to_ascii_lowercase() != actual {
                return Err(SurfaceError::Checksum {
                    path: path.into(),
                    member: valid_name,
                    expected: sum.to_ascii_lowercase(),
                    actual,
                    stated_in: "main.xml (MD5ChecksumValidPoints)".into(),
                });
            }
        }
        for (k, h) in heights.iter_mut().enumerate() {
            if bits[k / 8] & (1 << (k % 8)) == 0 {
                *h = f64::NAN;
            }
        }
    }
    Ok(heights)
}

/// The first layer's heights from the Datum elements of Record3's
/// DataList (`list`; an empty Datum is an invalid point).
fn listed_heights(list: roxmltree::Node, cz: &Axis, dims: &Dimensions, path: &Path) -> Result<Vec<f64>, SurfaceError> {
    let mut heights = vec![f64::NAN; dims.layer];
    let datums: Vec<roxmltree::Node> =
        list.children().filter(|c| c.is_element() && c.tag_name().name() == "Datum").collect();
    if datums.len() != dims.total {
        return Err(SurfaceError::PointCount {
            path: path.into(),
            member: "main.xml DataList".into(),
            got: datums.len(),
            expected: dims.total,
            stated_in: dims.stated.clone(),
        });
    }
    for (k, h) in heights.iter_mut().enumerate() {
        let t = text_of(datums[k]);
        if t.is_empty() {
            continue; // an empty Datum is an invalid point
        }
        let v: f64 = t.parse().map_err(|_| xml_err(path, format!("Datum {} {t:?} is not a number", k + 1)))?;
        let v = v * cz.increment;
        *h = if v.is_finite() { v } else { f64::NAN };
    }
    Ok(heights)
}
