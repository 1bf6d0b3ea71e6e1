//! Height maps from text/CSV grids, 32-bit float TIFF and single-channel
//! EXR, and [`read_height_map`], which picks the reader by file extension
//! (`.x3p` → [`super::x3p`]).
//!
//! **Text grids** (`.csv`, `.txt`, `.asc`, `.dat`): one row of heights per
//! line (row j is y = j·Δy), values separated by commas, semicolons, tabs or
//! spaces. An empty field, `NaN` or `nan` is an invalid point. Lines that
//! start with `#` are header or comment lines; these header keys are read
//! (`key = value` or `key: value`, case-insensitive):
//!
//! | key | meaning |
//! |---|---|
//! | `pitch_um`, `pitch_x_um`, `pitch_y_um` (or `_m`, `_nm`, `_mm`) | point spacing |
//! | `height_unit` | unit of the values: `m`, `mm`, `um` (`µm`), `nm` |
//! | `Width`, `Height` with a unit (`871.0 µm`), `Value units` | Gwyddion's ASCII export: the map's physical size (pitch = size / points) and the value unit |
//!
//! A pitch or unit given on the command line ([`ReadOptions`]) overrides the
//! header; the override is noted in the map's notes.
//!
//! **TIFF** (one 32- or 64-bit float grey channel) and **EXR** (one channel,
//! or a channel named `Z`, `Y`, `H` or `height`): pitch and height unit must
//! come from [`ReadOptions`] (the files carry no physical scale). Integer
//! TIFFs are refused (their values have no physical scale). NaN or ±inf
//! samples are invalid points.
//!
//! ```
//! use lucent::surface::{read_height_map, ReadOptions};
//! let dir = std::env::temp_dir().join("lucent-doc-grid");
//! std::fs::create_dir_all(&dir).unwrap();
//! std::fs::write(dir.join("m.csv"), "# pitch_um = 0.871\n# height_unit = nm\n1, 2, 3\n4, , 6\n").unwrap();
//! let map = read_height_map(&dir.join("m.csv"), &ReadOptions::default()).unwrap();
//! assert_eq!((map.nx, map.ny, map.valid_count()), (3, 2, 5));
//! assert!((map.pitch_x_m - 0.871e-6).abs() < 1e-18 && (map.at(2, 1) - 6e-9).abs() < 1e-21);
//! ```

use super::error::SurfaceError;
use super::map::HeightMap;
use std::path::Path;
use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

/// A length unit of heights or pitches.
#[derive(Debug, Clone, Copy, PartialEq, Eq, EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage)]
#[strum(serialize_all = "lowercase", ascii_case_insensitive)]
pub enum LengthUnit {
    M,
    Mm,
    #[strum(to_string = "um", serialize = "µm", serialize = "μm", serialize = "micron", serialize = "microns")]
    Um,
    Nm,
}

impl LengthUnit {
    /// Metres per unit.
    pub fn metres(self) -> f64 {
        match self {
            LengthUnit::M => 1.0,
            LengthUnit::Mm => 1e-3,
            LengthUnit::Um => 1e-6,
            LengthUnit::Nm => 1e-9,
        }
    }
}

/// A length unit [`LengthUnit::from_name`] does not know.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{name:?}: expected a length unit {}", <LengthUnit as strum::VariantNames>::VARIANTS.join(", "))]
pub struct UnknownLengthUnit {
    pub name: String,
}

impl LengthUnit {
    /// Any spelling of a unit ("um", "µm", "micron" …; case ignored).
    pub fn from_name(name: &str) -> Result<Self, UnknownLengthUnit> {
        let name = name.trim();
        name.parse().map_err(|_| UnknownLengthUnit { name: name.to_string() })
    }
}

/// What the command line says about a map (all optional).
#[derive(Debug, Clone, Copy, Default)]
pub struct ReadOptions {
    /// Column spacing in metres.
    pub pitch_x_m: Option<f64>,
    /// Row spacing in metres (defaults to the column spacing).
    pub pitch_y_m: Option<f64>,
    /// Unit of the stored heights (text, TIFF, EXR).
    pub height_unit: Option<LengthUnit>,
}

/// Reads a height map; the format follows the extension: `.x3p`, `.csv`,
/// `.txt`, `.asc`, `.dat`, `.tif`, `.tiff`, `.exr`.
pub fn read_height_map(path: &Path, options: &ReadOptions) -> Result<HeightMap, SurfaceError> {
    if !path.exists() {
        return Err(SurfaceError::Io {
            path: path.into(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        });
    }
    if path.is_dir() {
        return Err(SurfaceError::Format {
            path: path.into(),
            reason: "is a folder, expected a height map file".into(),
        });
    }
    let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    for (what, v) in [("x pitch (--pitch-um)", options.pitch_x_m), ("y pitch (--pitch-y-um)", options.pitch_y_m)] {
        if let Some(value) = v
            && !(value.is_finite() && value > 0.0)
        {
            return Err(SurfaceError::Pitch { origin: "command line".into(), what: what.into(), value });
        }
    }
    let mut map = match ext.as_str() {
        "x3p" => {
            let mut map = super::x3p::read_x3p(path)?;
            if options.height_unit.is_some() {
                map.notes.push("--height-unit ignored: X3P heights are in metres by the standard".into());
            }
            override_pitch(&mut map, options, "the X3P file");
            map
        }
        "csv" | "txt" | "asc" | "dat" => read_text(path, options)?,
        "tif" | "tiff" => {
            let (nx, ny, values) = read_tiff(path)?;
            from_raster(path, nx, ny, values, options, "TIFF")?
        }
        "exr" => {
            let (nx, ny, values) = read_exr(path)?;
            from_raster(path, nx, ny, values, options, "EXR")?
        }
        _ => {
            return Err(SurfaceError::Format {
                path: path.into(),
                reason: "unknown height-map format (expected .x3p, .csv, .txt, .asc, .dat, .tif, .tiff or .exr)".into(),
            })
        }
    };
    map.origin = path.display().to_string();
    Ok(map)
}

/// Replaces the map's pitch by the command line's, with a note when they differ.
fn override_pitch(map: &mut HeightMap, options: &ReadOptions, from: &str) {
    if let Some(px) = options.pitch_x_m {
        let py = options.pitch_y_m.unwrap_or(px);
        if (px - map.pitch_x_m).abs() > 1e-9 * px || (py - map.pitch_y_m).abs() > 1e-9 * py {
            map.notes.push(format!(
                "pitch {:.6} × {:.6} µm given (pitch_um) replaces {:.6} × {:.6} µm of {from}",
                px * 1e6,
                py * 1e6,
                map.pitch_x_m * 1e6,
                map.pitch_y_m * 1e6
            ));
        }
        map.pitch_x_m = px;
        map.pitch_y_m = py;
    }
}

fn from_raster(
    path: &Path,
    nx: usize,
    ny: usize,
    values: Vec<f64>,
    options: &ReadOptions,
    kind: &str,
) -> Result<HeightMap, SurfaceError> {
    let Some(px) = options.pitch_x_m else {
        return Err(SurfaceError::Format {
            path: path.into(),
            reason: format!("a {kind} height map carries no pitch: give it with --pitch-um"),
        });
    };
    let Some(unit) = options.height_unit else {
        return Err(SurfaceError::Format {
            path: path.into(),
            reason: format!("a {kind} height map carries no height unit: give it with --height-unit (m, mm, um, nm)"),
        });
    };
    let py = options.pitch_y_m.unwrap_or(px);
    let scale = unit.metres();
    let heights = values.into_iter().map(|v| v * scale).collect();
    HeightMap::new(nx, ny, px, py, heights, path.display().to_string())
}

fn read_tiff(path: &Path) -> Result<(usize, usize, Vec<f64>), SurfaceError> {
    use tiff::decoder::{Decoder, DecodingResult};
    let err =
        |reason: String| SurfaceError::Format { path: path.into(), reason: format!("cannot read TIFF: {reason}") };
    let file = std::fs::File::open(path).map_err(|source| SurfaceError::Io { path: path.into(), source })?;
    let mut dec = Decoder::new(std::io::BufReader::new(file)).map_err(|e| err(e.to_string()))?;
    let (w, h) = dec.dimensions().map_err(|e| err(e.to_string()))?;
    let colour = dec.colortype().map_err(|e| err(e.to_string()))?;
    if !matches!(colour, tiff::ColorType::Gray(32) | tiff::ColorType::Gray(64)) {
        return Err(err(format!(
            "colour type {colour:?}: expected one grey channel of 32- or 64-bit floats (heights with a unit given by --height-unit)"
        )));
    }
    let values: Vec<f64> = match dec.read_image().map_err(|e| err(e.to_string()))? {
        DecodingResult::F32(v) => v.into_iter().map(f64::from).collect(),
        DecodingResult::F64(v) => v,
        _ => {
            return Err(err(
                "integer samples: heights in an integer TIFF have no physical scale; export 32-bit float heights"
                    .into(),
            ))
        }
    };
    let (w, h) = (w as usize, h as usize);
    if values.len() != w * h {
        return Err(err(format!("{} samples for {w} × {h} pixels", values.len())));
    }
    Ok((w, h, values))
}

fn read_exr(path: &Path) -> Result<(usize, usize, Vec<f64>), SurfaceError> {
    let err = |reason: String| SurfaceError::Format { path: path.into(), reason: format!("cannot read EXR: {reason}") };
    let layer = crate::exr::read_layer(path)?;
    let names = layer.names();
    let index = if names.len() == 1 {
        0
    } else {
        ["Z", "Y", "H", "height", "Height"].iter().find_map(|want| names.iter().position(|n| n == want)).ok_or_else(
            || {
                err(format!(
                    "{} channels ({}); expected one, or one named Z, Y, H or height",
                    names.len(),
                    names.join(", ")
                ))
            },
        )?
    };
    let values: Vec<f64> = layer.plane_at(index)?.iter().copied().map(f64::from).collect();
    Ok((layer.width, layer.height, values))
}

/// Parses "871.000 µm" or "0.871" (with a default unit) into metres.
fn length_with_unit(text: &str) -> Option<f64> {
    let t = text.trim();
    let split = t.find(|c: char| !(c.is_ascii_digit() || matches!(c, '.' | '-' | '+' | 'e' | 'E'))).unwrap_or(t.len());
    let (num, unit) = t.split_at(split);
    let v: f64 = num.trim().parse().ok()?;
    let unit: LengthUnit = unit.trim().parse().ok()?;
    Some(v * unit.metres())
}

fn read_text(path: &Path, options: &ReadOptions) -> Result<HeightMap, SurfaceError> {
    let bytes = std::fs::read(path).map_err(|source| SurfaceError::Io { path: path.into(), source })?;
    let text = String::from_utf8(bytes)
        .map_err(|e| SurfaceError::Format { path: path.into(), reason: format!("not a UTF-8 text grid: {e}") })?;
    let text_err = |line: usize, reason: String| SurfaceError::Text { path: path.into(), line, reason };
    let mut header = TextHeader::default();
    let mut rows: Vec<Vec<f64>> = Vec::new();
    let mut first_row_line = 0;
    for (k, raw) in text.lines().enumerate() {
        let line_no = k + 1;
        let line = raw.trim().trim_start_matches('\u{feff}');
        if line.is_empty() {
            continue;
        }
        if let Some(h) = line.strip_prefix('#') {
            header.read_line(h, line_no, path)?;
            continue;
        }
        let row = text_row(line, line_no, path)?;
        if let Some(first) = rows.first() {
            if row.len() != first.len() {
                return Err(text_err(
                    line_no,
                    format!(
                        "{} values in {}, but line {first_row_line} (the first row) has {}",
                        row.len(),
                        crate::io::quoted_line(line),
                        first.len()
                    ),
                ));
            }
        } else {
            first_row_line = line_no;
        }
        rows.push(row);
    }
    let ny = rows.len();
    let nx = rows.first().map_or(0, Vec::len);
    if ny == 0 || nx == 0 {
        return Err(SurfaceError::Format { path: path.into(), reason: "no rows of heights".into() });
    }
    let mut notes = Vec::new();
    let (px, py) = header.pitch(nx, ny, options, &mut notes, path)?;
    let unit = match (options.height_unit, header.unit) {
        (Some(u), Some(h)) if u != h => {
            notes.push(format!("height unit {u:?} given (height_unit) replaces {h:?} of the header"));
            u
        }
        (Some(u), _) => u,
        (None, Some(h)) => h,
        (None, None) => {
            return Err(SurfaceError::Format {
                path: path.into(),
                reason: "no height unit: give it in the header (# height_unit = um) or with --height-unit".into(),
            })
        }
    };
    let scale = unit.metres();
    let heights: Vec<f64> = rows.into_iter().flatten().map(|v| v * scale).collect();
    let mut map = HeightMap::new(nx, ny, px, py, heights, path.display().to_string()).map_err(|e| match e {
        SurfaceError::Pitch { what, value, .. } => {
            SurfaceError::Pitch { origin: path.display().to_string(), what, value }
        }
        other => other,
    })?;
    map.notes = notes;
    Ok(map)
}

/// What the `#` header lines of a text grid state.
#[derive(Default)]
struct TextHeader {
    pitch_x: Option<f64>,
    pitch_y: Option<f64>,
    width_m: Option<f64>,
    height_m: Option<f64>,
    unit: Option<LengthUnit>,
}

impl TextHeader {
    /// Reads the header line `header` (after its `#`; line `line_no` of the
    /// file at `path`): `key = value` or `key: value`; other lines and keys
    /// are comments.
    fn read_line(&mut self, header: &str, line_no: usize, path: &Path) -> Result<(), SurfaceError> {
        let text_err = |line: usize, reason: String| SurfaceError::Text { path: path.into(), line, reason };
        let Some(pos) = header.find(['=', ':']) else { return Ok(()) };
        let key = header[..pos].trim().to_ascii_lowercase().replace([' ', '-'], "_");
        let value = header[pos + 1..].trim();
        let num = || -> Result<f64, SurfaceError> {
            value.parse::<f64>().map_err(|_| text_err(line_no, format!("header {key}: {value:?} is not a number")))
        };
        let suffix_unit = |k: &str| -> Option<(String, f64)> {
            for (suffix, m) in [("_m", 1.0), ("_mm", 1e-3), ("_um", 1e-6), ("_nm", 1e-9)] {
                if let Some(stem) = k.strip_suffix(suffix) {
                    return Some((stem.to_string(), m));
                }
            }
            None
        };
        match suffix_unit(&key) {
            Some((stem, m)) if stem == "pitch" => self.pitch_x = Some(num()? * m),
            Some((stem, m)) if stem == "pitch_x" => self.pitch_x = Some(num()? * m),
            Some((stem, m)) if stem == "pitch_y" => self.pitch_y = Some(num()? * m),
            _ => match key.as_str() {
                "height_unit" | "value_units" | "z_unit" => {
                    self.unit = Some(
                        LengthUnit::from_name(value).map_err(|e| text_err(line_no, format!("header {key}: {e}")))?,
                    )
                }
                "width" => {
                    self.width_m = Some(length_with_unit(value).ok_or_else(|| {
                        text_err(
                            line_no,
                            format!("header Width {value:?}: expected a length with a unit, e.g. 871.0 µm"),
                        )
                    })?)
                }
                "height" => {
                    self.height_m = Some(length_with_unit(value).ok_or_else(|| {
                        text_err(
                            line_no,
                            format!("header Height {value:?}: expected a length with a unit, e.g. 871.0 µm"),
                        )
                    })?)
                }
                _ => {}
            },
        }
        Ok(())
    }

    /// The pitch (x, y) of an `nx` × `ny` grid: the command line's (a note
    /// when it replaces the header's), else the header's pitch or its width
    /// and height over the grid.
    fn pitch(
        &self,
        nx: usize,
        ny: usize,
        options: &ReadOptions,
        notes: &mut Vec<String>,
        path: &Path,
    ) -> Result<(f64, f64), SurfaceError> {
        let (mut pitch_x, mut pitch_y) = (self.pitch_x, self.pitch_y);
        if pitch_x.is_none() {
            pitch_x = self.width_m.map(|w| w / nx as f64);
            if pitch_y.is_none() {
                pitch_y = self.height_m.map(|h| h / ny as f64);
            }
        }
        let header_pitch = pitch_x.map(|px| (px, pitch_y.unwrap_or(px)));
        Ok(match (options.pitch_x_m, header_pitch) {
            (Some(px), Some((hx, hy))) => {
                let py = options.pitch_y_m.unwrap_or(px);
                if (px - hx).abs() > 1e-9 * px || (py - hy).abs() > 1e-9 * py {
                    notes.push(format!(
                        "pitch {:.6} × {:.6} µm given (pitch_um) replaces {:.6} × {:.6} µm of the header",
                        px * 1e6,
                        py * 1e6,
                        hx * 1e6,
                        hy * 1e6
                    ));
                }
                (px, py)
            }
            (Some(px), None) => (px, options.pitch_y_m.unwrap_or(px)),
            (None, Some(h)) => h,
            (None, None) => {
                return Err(SurfaceError::Format {
                    path: path.into(),
                    reason: "no pitch: give it in the header (# pitch_um = 0.871) or with --pitch-um".into(),
                })
            }
        })
    }
}

/// One row of heights of a text grid (`line`, line `line_no`): fields
/// separated by commas, semicolons, tabs or spaces; an empty field or NaN
/// is an invalid point.
fn text_row(line: &str, line_no: usize, path: &Path) -> Result<Vec<f64>, SurfaceError> {
    let fields: Vec<&str> = if line.contains(',') {
        line.split(',').collect()
    } else if line.contains(';') {
        line.split(';').collect()
    } else if line.contains('\t') {
        line.split('\t').collect()
    } else {
        line.split_whitespace().collect()
    };
    let mut row = Vec::with_capacity(fields.len());
    for (c, f) in fields.iter().enumerate() {
        let f = f.trim();
        let v = if f.is_empty() || f.eq_ignore_ascii_case("nan") {
            f64::NAN
        } else {
            f.parse::<f64>().map_err(|_| SurfaceError::Text {
                path: path.into(),
                line: line_no,
                reason: format!(
                    "column {}: {f:?} is not a number (an invalid point is an empty field or NaN) in {}",
                    c + 1,
                    crate::io::quoted_line(line)
                ),
            })?
        };
        row.push(v);
    }
    Ok(row)
}
