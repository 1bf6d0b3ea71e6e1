//! Triangle meshes of the sample for the renderer's scene (docs/method.md#render).
//!
//! [`load`] reads the object's surface from
//!
//! | extension (any case) | format | crate |
//! | --- | --- | --- |
//! | `.ply` | PLY, ASCII or binary (little or big endian) | `ply-rs-bw` |
//! | `.obj` | Wavefront OBJ (positions and faces; materials are not read) | `tobj` |
//! | `.stl` | STL, ASCII or binary | `stl_io` |
//!
//! and returns a [`Mesh`] of positions in **metres** (`positions_m`: the file's
//! coordinates times `unit_scale_m`, e.g. 0.001 for a scan in millimetres)
//! and triangles as vertex indices, plus a [`MeshReport`]. Polygons with more
//! than three vertices (PLY face lists, OBJ faces) are split into triangle
//! fans `(v0, vk, vk+1)`, which keeps their winding. PLY faces and OBJ lines
//! or points with fewer than three vertices are skipped. STL stores three
//! corners per triangle; the reader welds corners with bit-identical
//! coordinates into shared vertices. A binary STL is recognised by its size
//! (84 + 50 n bytes for the n triangles its header announces), so a binary
//! file whose 80-byte header begins with `solid` still reads as binary.
//!
//! ## Validation ([`Mesh::check`], run by [`load`])
//!
//! * A NaN or infinite coordinate is an error naming the vertex (0-based).
//! * A face index outside the vertex list is an error naming the face and the
//!   index (PLY: the face number in the file; [`Mesh::check`]: the triangle).
//! * Degenerate triangles are removed by [`load`] and counted in
//!   `degenerate_removed`, with a warning: two corners with the same index or
//!   the same position, or zero area (|e₁ × e₂| ≤ 4 ε |e₁| |e₂|, i.e. the
//!   corners are collinear up to rounding; ε is the f64 machine epsilon).
//! * No triangle left is an error.
//! * Topology is computed on welded vertices: positions that are *exactly*
//!   equal (bit for bit, with −0 = +0; no distance tolerance) count as one
//!   vertex, so a closed STL or a PLY with split vertices reports closed.
//!   Each undirected edge is counted over the triangles. An edge used once is
//!   a boundary edge (the mesh is open), an edge used more than twice is
//!   non-manifold, and an edge that both of its triangles traverse in the same
//!   direction marks an inconsistent orientation. The renderer needs a closed,
//!   consistently oriented surface around the medium, but these are warnings
//!   in [`MeshReport::warnings`], not errors; nothing is re-oriented. A closed
//!   mesh with negative signed volume (triangles wound clockwise seen from
//!   outside) is warned about too, as are vertices no triangle uses.
//! * A mesh whose bounding box is 1 m or more across, or less than 1 mm, is
//!   warned about with its size ([`size_warning`]): the file's unit is then
//!   most likely not the one `unit_scale_m` says (a scan in millimetres read
//!   as metres renders a 30 mm part as 30 m, larger than the environment's
//!   sphere and the board).
//!
//! Each parser runs under `catch_unwind`, so a panic inside a crate on a
//! malformed file (`tobj` can overflow on wild texture indices) becomes a
//! [`MeshError::Parse`] instead of aborting; a chained panic hook keeps such
//! caught panics off stderr (other panics print as before). `tobj` keeps only
//! the OBJ vertices that faces use, so a NaN in an unused `v` line is not
//! seen; in PLY every vertex is checked.
//!
//! The plaque of the samples is [`plaque_box`]: 60 mm × 40 mm × 6.35 mm has
//! a volume of 15.24 cm³, and `fixtures/mesh/plaque_ascii.ply` is that box:
//!
//! ```
//! use lucent::scene::mesh::{load, plaque_box};
//! let plaque = plaque_box(0.060, 0.040, 0.00635);
//! assert_eq!(plaque.triangles.len(), 12);
//! assert!((plaque.signed_volume_m3() - 15.24e-6).abs() < 1e-18);
//!
//! let path = std::path::Path::new("fixtures/mesh/plaque_ascii.ply");
//! let (mesh, report) = load(path, 1.0).unwrap();
//! assert_eq!(mesh, plaque);
//! assert!(report.closed && report.warnings.is_empty());
//! assert_eq!(report.bbox_max_m, [0.030, 0.020, 0.00635]);
//! ```

use std::collections::hash_map::Entry;
use std::fs::File;
use std::io::{BufRead, BufReader, Cursor};
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::path::Path;

use ply_rs_bw::parser::{Parser as PlyParser, Reader as PlyReader};
use ply_rs_bw::ply::{ElementDef, Header, PropertyAccess, PropertyAccessResult, PropertyType};
use rustc_hash::FxHashMap;
use serde::{Deserialize, Serialize};

/// File extensions [`load`] understands (compared without regard to case).
pub const SUPPORTED_EXTENSIONS: [&str; 3] = ["ply", "obj", "stl"];

/// A triangle mesh in metres.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions (m).
    pub positions_m: Vec<[f64; 3]>,
    /// Triangles as indices into `positions_m`; counter-clockwise seen from
    /// outside (right-hand rule: (p1 − p0) × (p2 − p0) points outward).
    pub triangles: Vec<[u32; 3]>,
}

/// What [`load`] or [`Mesh::check`] found in a mesh.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MeshReport {
    /// The file (or name) the mesh came from.
    pub path: String,
    /// Number of vertices in the mesh (after welding, for STL).
    pub vertices: usize,
    /// Number of non-degenerate triangles.
    pub triangles: usize,
    /// Degenerate triangles removed by [`load`] (ignored by [`Mesh::check`]).
    pub degenerate_removed: usize,
    /// Edges used by exactly one triangle.
    pub boundary_edges: usize,
    /// Edges used by more than two triangles.
    pub non_manifold_edges: usize,
    /// Every edge is used by exactly two triangles.
    pub closed: bool,
    /// Lower corner of the bounding box of the vertices in use (m).
    pub bbox_min_m: [f64; 3],
    /// Upper corner of the bounding box of the vertices in use (m).
    pub bbox_max_m: [f64; 3],
    /// Problems that do not stop loading (open or non-manifold surface,
    /// inconsistent orientation, removed triangles, skipped file content).
    pub warnings: Vec<String>,
}

/// Why a mesh could not be loaded. Every message names the file.
#[derive(Debug, thiserror::Error)]
pub enum MeshError {
    /// The file could not be opened or read.
    #[error("cannot read mesh file {path}: {source}")]
    Io {
        path: String,
        #[source]
        source: std::io::Error,
    },
    /// The extension is none of [`SUPPORTED_EXTENSIONS`].
    #[error(
        "mesh file {path}: unknown mesh format {extension:?}; supported extensions: \
         .ply, .obj, .stl (any case)"
    )]
    UnknownFormat { path: String, extension: String },
    /// The file has no bytes.
    #[error("mesh file {path} is empty (0 bytes)")]
    Empty { path: String },
    /// The file does not follow its format.
    #[error("mesh file {path}: not a valid {format} file: {message}")]
    Parse { path: String, format: &'static str, message: String },
    /// A vertex has a NaN or infinite coordinate.
    #[error(
        "mesh file {path}: vertex {vertex} (0-based) has a non-finite coordinate \
         (NaN or infinite): {position:?}"
    )]
    NonFinite { path: String, vertex: usize, position: [f64; 3] },
    /// A face refers to a vertex that does not exist.
    #[error(
        "mesh file {path}: face {face} (0-based) refers to vertex index {index}, out of range \
         for the {vertices} vertices"
    )]
    IndexOutOfRange { path: String, face: usize, index: i64, vertices: usize },
    /// No triangle is left after removing degenerate ones.
    #[error(
        "mesh file {path}: no triangles (faces read: {faces}; degenerate triangles removed: \
         {degenerate})"
    )]
    NoTriangles { path: String, faces: usize, degenerate: usize },
    /// More vertices than 32-bit indices can address.
    #[error("mesh file {path}: {count} {what} exceed the limit of {limit} (32-bit indices)")]
    TooLarge { path: String, what: &'static str, count: u64, limit: u64 },
    /// `unit_scale_m` is not a finite positive number.
    #[error("mesh file {path}: unit scale {unit_scale_m} m per file unit must be finite and > 0")]
    InvalidScale { path: String, unit_scale_m: f64 },
}

/// The formats [`load`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Format {
    Ply,
    Obj,
    Stl,
}

impl Format {
    fn name(self) -> &'static str {
        match self {
            Format::Ply => "PLY",
            Format::Obj => "OBJ",
            Format::Stl => "STL",
        }
    }

    fn of(path: &Path, name: &str) -> Result<Format, MeshError> {
        let ext = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
        match ext.as_str() {
            "ply" => Ok(Format::Ply),
            "obj" => Ok(Format::Obj),
            "stl" => Ok(Format::Stl),
            _ => Err(MeshError::UnknownFormat {
                path: name.to_string(),
                extension: if ext.is_empty() { "(none)".to_string() } else { format!(".{ext}") },
            }),
        }
    }
}

/// What a format reader hands over: the raw mesh (file units), the number of
/// faces it read, and notes on skipped content.
struct Parsed {
    mesh: Mesh,
    faces: usize,
    warnings: Vec<String>,
}

/// Reads a PLY, OBJ or STL mesh (format by extension, any case), scales the
/// coordinates by `unit_scale_m` (metres per file unit: 1 for a file in
/// metres, 0.001 for millimetres), removes degenerate triangles and reports
/// the rest of the checks of [`Mesh::check`].
pub fn load(path: &Path, unit_scale_m: f64) -> Result<(Mesh, MeshReport), MeshError> {
    let name = path.display().to_string();
    if !(unit_scale_m.is_finite() && unit_scale_m > 0.0) {
        return Err(MeshError::InvalidScale { path: name, unit_scale_m });
    }
    let format = Format::of(path, &name)?;
    let io = |source| MeshError::Io { path: name.clone(), source };
    let file = File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    if len == 0 {
        return Err(MeshError::Empty { path: name });
    }
    let parsed = guarded(&name, format, || match format {
        Format::Ply => read_ply(file, &name),
        Format::Obj => read_obj(file, &name),
        Format::Stl => read_stl(file, len, &name),
    })?;
    let Parsed { mut mesh, faces, warnings: read_warnings } = parsed;
    if unit_scale_m != 1.0 {
        for p in &mut mesh.positions_m {
            *p = p.map(|c| c * unit_scale_m);
        }
    }
    let (mut report, degenerate) = mesh.analyse(&name)?;
    if report.triangles == 0 {
        return Err(MeshError::NoTriangles { path: name, faces, degenerate: report.degenerate_removed });
    }
    if !degenerate.is_empty() {
        let mut next = degenerate.iter().copied().peekable();
        let mut i = 0usize;
        mesh.triangles.retain(|_| {
            let drop = next.peek() == Some(&i);
            if drop {
                next.next();
            }
            i += 1;
            !drop
        });
    }
    report.warnings.splice(0..0, read_warnings);
    Ok((mesh, report))
}

/// The plaque as a closed box of 12 triangles: x ∈ [−w/2, w/2],
/// y ∈ [−h/2, h/2], z ∈ [0, t] (m; origin at the centre of the bottom face),
/// wound counter-clockwise seen from outside so normals point outward.
pub fn plaque_box(width_m: f64, height_m: f64, thickness_m: f64) -> Mesh {
    let (x, y, t) = (width_m / 2.0, height_m / 2.0, thickness_m);
    Mesh {
        positions_m: vec![
            [-x, -y, 0.0],
            [x, -y, 0.0],
            [x, y, 0.0],
            [-x, y, 0.0],
            [-x, -y, t],
            [x, -y, t],
            [x, y, t],
            [-x, y, t],
        ],
        triangles: vec![
            [0, 2, 1], // bottom, −z
            [0, 3, 2],
            [4, 5, 6], // top, +z
            [4, 6, 7],
            [0, 1, 5], // front, −y
            [0, 5, 4],
            [2, 3, 7], // back, +y
            [2, 7, 6],
            [3, 0, 4], // left, −x
            [3, 4, 7],
            [1, 2, 6], // right, +x
            [1, 6, 5],
        ],
    }
}

impl Mesh {
    /// The mesh moved by a 4 × 4 object-to-world matrix `m` (row-major,
    /// column vectors: p′ = m · (p, 1), translation in `m[i][3]`; a last row
    /// other than (0, 0, 0, 1) divides by w). A reflection (negative
    /// determinant of the 3 × 3 part) reverses each triangle's winding so the
    /// normals stay outward.
    pub fn transformed(&self, object_to_world: &[[f64; 4]; 4]) -> Mesh {
        let m = object_to_world;
        let det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
        let affine = m[3] == [0.0, 0.0, 0.0, 1.0];
        let positions_m = self
            .positions_m
            .iter()
            .map(|p| {
                let row = |r: &[f64; 4]| r[0] * p[0] + r[1] * p[1] + r[2] * p[2] + r[3];
                let q = [row(&m[0]), row(&m[1]), row(&m[2])];
                if affine {
                    q
                } else {
                    let w = row(&m[3]);
                    q.map(|c| c / w)
                }
            })
            .collect();
        let triangles = if det < 0.0 {
            self.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect()
        } else {
            self.triangles.clone()
        };
        Mesh { positions_m, triangles }
    }

    /// Signed volume enclosed by the triangles (m³), by the divergence
    /// theorem: Σ p₀ · (p₁ × p₂) / 6. Positive for a closed mesh with outward
    /// normals. Indices must be in range (as after [`Mesh::check`]).
    pub fn signed_volume_m3(&self) -> f64 {
        let p = &self.positions_m;
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| p[i as usize]);
                dot(a, cross(b, c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// Validates the mesh without changing it: errors for a non-finite
    /// coordinate, an index out of range or no non-degenerate triangle;
    /// counts degenerate triangles in `degenerate_removed` (what [`load`]
    /// removes; here they are only left out of the other counts); warns about
    /// open, non-manifold or inconsistently oriented surfaces. `path` names
    /// the mesh in messages.
    pub fn check(&self, path: &str) -> Result<MeshReport, MeshError> {
        let (report, _) = self.analyse(path)?;
        if report.triangles == 0 {
            return Err(MeshError::NoTriangles {
                path: path.to_string(),
                faces: self.triangles.len(),
                degenerate: report.degenerate_removed,
            });
        }
        Ok(report)
    }

    /// The checks of [`Mesh::check`] (except "no triangles"), plus the sorted
    /// indices of the degenerate triangles.
    fn analyse(&self, path: &str) -> Result<(MeshReport, Vec<usize>), MeshError> {
        let n = self.positions_m.len();
        if n > u32::MAX as usize {
            return Err(MeshError::TooLarge {
                path: path.to_string(),
                what: "vertices",
                count: n as u64,
                limit: u32::MAX as u64,
            });
        }
        if let Some(i) = self.positions_m.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
            return Err(MeshError::NonFinite { path: path.to_string(), vertex: i, position: self.positions_m[i] });
        }
        for (face, t) in self.triangles.iter().enumerate() {
            if let Some(&index) = t.iter().find(|&&i| i as usize >= n) {
                return Err(MeshError::IndexOutOfRange {
                    path: path.to_string(),
                    face,
                    index: index.into(),
                    vertices: n,
                });
            }
        }

        // Weld bit-identical positions (−0 and +0 as one).
        let mut first: FxHashMap<[u64; 3], u32> = FxHashMap::default();
        first.reserve(n);
        let weld: Vec<u32> = self
            .positions_m
            .iter()
            .enumerate()
            .map(|(i, p)| {
                let key = p.map(|c| (c + 0.0).to_bits());
                *first.entry(key).or_insert(i as u32)
            })
            .collect();
        drop(first);

        // Degenerate triangles, edges, bounding box.
        let p = &self.positions_m;
        let mut degenerate = Vec::new();
        let mut used = vec![false; n];
        // Edge key (low, high welded id) -> (uses, uses from low to high).
        let mut edges: FxHashMap<u64, (u32, u32)> = FxHashMap::default();
        edges.reserve(self.triangles.len() * 3 / 2 + 16);
        let mut volume6 = 0.0;
        for (k, t) in self.triangles.iter().enumerate() {
            let w = t.map(|i| weld[i as usize]);
            let [a, b, c] = t.map(|i| p[i as usize]);
            let (e1, e2) = (sub(b, a), sub(c, a));
            let area2 = norm2(cross(e1, e2));
            let eps = 4.0 * f64::EPSILON;
            if w[0] == w[1] || w[1] == w[2] || w[0] == w[2] || area2 <= eps * eps * norm2(e1) * norm2(e2) {
                degenerate.push(k);
                continue;
            }
            volume6 += dot(a, cross(b, c));
            for &i in t {
                used[i as usize] = true;
            }
            for (u, v) in [(w[0], w[1]), (w[1], w[2]), (w[2], w[0])] {
                let (lo, hi, forward) = if u < v { (u, v, 1) } else { (v, u, 0) };
                let e = edges.entry((lo as u64) << 32 | hi as u64).or_insert((0, 0));
                e.0 += 1;
                e.1 += forward;
            }
        }
        let (mut boundary, mut non_manifold, mut flipped) = (0usize, 0usize, 0usize);
        for &(uses, forward) in edges.values() {
            match uses {
                1 => boundary += 1,
                2 if forward != 1 => flipped += 1,
                2 => {}
                _ => non_manifold += 1,
            }
        }
        drop(edges);
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        let mut unused = 0usize;
        for (q, &u) in p.iter().zip(&used) {
            if u {
                for d in 0..3 {
                    lo[d] = lo[d].min(q[d]);
                    hi[d] = hi[d].max(q[d]);
                }
            } else {
                unused += 1;
            }
        }
        let triangles = self.triangles.len() - degenerate.len();
        if triangles == 0 {
            (lo, hi) = ([0.0; 3], [0.0; 3]);
        }
        let closed = triangles > 0 && boundary == 0 && non_manifold == 0;

        let mut warnings = Vec::new();
        if !degenerate.is_empty() {
            warnings
                .push(format!("{} degenerate triangles (zero area or a repeated vertex) removed", degenerate.len()));
        }
        if boundary > 0 {
            warnings.push(format!(
                "the mesh is open: {boundary} boundary edges (used by only one triangle); \
                 the renderer needs a closed surface around the medium"
            ));
        }
        if non_manifold > 0 {
            warnings.push(format!("{non_manifold} non-manifold edges (used by more than two triangles)"));
        }
        if flipped > 0 {
            warnings.push(format!(
                "inconsistent orientation: {flipped} edges are traversed in the same direction \
                 by both of their triangles (some normals point inward)"
            ));
        }
        if closed && flipped == 0 && volume6 < 0.0 {
            warnings.push(
                "the closed mesh has negative signed volume: triangles are wound clockwise \
                 seen from outside (normals point inward)"
                    .to_string(),
            );
        }
        if unused > 0 {
            warnings.push(format!("{unused} vertices are not used by any triangle"));
        }
        if triangles > 0 {
            warnings.extend(size_warning(lo, hi));
        }
        let report = MeshReport {
            path: path.to_string(),
            vertices: n,
            triangles,
            degenerate_removed: degenerate.len(),
            boundary_edges: boundary,
            non_manifold_edges: non_manifold,
            closed,
            bbox_min_m: lo,
            bbox_max_m: hi,
            warnings,
        };
        Ok((report, degenerate))
    }
}

/// Largest side of a bounding box below which a mesh is taken for a file
/// in a larger unit than `unit_scale_m` says (m).
pub const SMALLEST_PLAUSIBLE_SIZE_M: f64 = 1e-3;
/// Largest side of a bounding box from which a mesh is taken for a file in
/// a smaller unit than `unit_scale_m` says (m).
pub const LARGEST_PLAUSIBLE_SIZE_M: f64 = 1.0;

/// The warning for a bounding box (corners in metres, after `unit_scale_m`)
/// too large or too small for a sample on the board, stating its size and
/// the `unit_scale_m` that would make it millimetres to centimetres; `None`
/// when its largest side is in [1 mm, 1 m).
pub fn size_warning(bbox_min_m: [f64; 3], bbox_max_m: [f64; 3]) -> Option<String> {
    let side = sub(bbox_max_m, bbox_min_m);
    let largest = side.iter().copied().fold(0.0, f64::max);
    let size = format!("{:.4} × {:.4} × {:.4} m", side[0], side[1], side[2]);
    if largest >= LARGEST_PLAUSIBLE_SIZE_M {
        Some(format!(
            "the mesh is {size} across (largest side {largest:.3} m), more than a sample on the board; \
             if the file is in millimetres, set unit_scale_m = 0.001 under [object] in the scene \
             (metres per file unit; 0.01 for centimetres)"
        ))
    } else if largest < SMALLEST_PLAUSIBLE_SIZE_M {
        Some(format!(
            "the mesh is {size} across (largest side {:.3} mm), less than a millimetre; \
             check unit_scale_m under [object] in the scene (metres per file unit: 1 for metres, \
             0.001 for millimetres)",
            largest * 1e3
        ))
    } else {
        None
    }
}

fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

fn norm2(a: [f64; 3]) -> f64 {
    dot(a, a)
}

thread_local! {
    /// Set while a format reader runs under [`guarded`]: its panics are
    /// reported as errors, so the panic hook stays quiet for them.
    static IN_READER: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
}

/// Runs a format reader, turning a panic inside a parsing crate into an error.
///
/// The first call chains a panic hook that prints nothing for panics on a
/// thread inside a reader (the message goes into the error instead) and
/// hands every other panic to the previous hook.
fn guarded(name: &str, format: Format, read: impl FnOnce() -> Result<Parsed, MeshError>) -> Result<Parsed, MeshError> {
    static QUIET_HOOK: std::sync::Once = std::sync::Once::new();
    QUIET_HOOK.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            if !IN_READER.with(|r| r.get()) {
                previous(info)
            }
        }));
    });
    IN_READER.with(|r| r.set(true));
    let result = catch_unwind(AssertUnwindSafe(read));
    IN_READER.with(|r| r.set(false));
    result.unwrap_or_else(|payload| {
        let what = payload
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown panic".to_string());
        Err(MeshError::Parse {
            path: name.to_string(),
            format: format.name(),
            message: format!("the parser failed on malformed input ({what})"),
        })
    })
}

fn parse_error(name: &str, format: Format, message: impl Into<String>) -> MeshError {
    MeshError::Parse { path: name.to_string(), format: format.name(), message: message.into() }
}

fn too_many_vertices(name: &str, count: u64) -> MeshError {
    MeshError::TooLarge { path: name.to_string(), what: "vertices", count, limit: u32::MAX as u64 }
}

// ---------------------------------------------------------------- PLY

/// A PLY vertex: x, y, z of any scalar type; other properties ignored.
#[derive(Default)]
struct PlyVertex([f64; 3]);

impl PlyVertex {
    fn set(&mut self, name: &str, v: f64) -> PropertyAccessResult {
        let d = match name {
            "x" => 0,
            "y" => 1,
            "z" => 2,
            _ => return PropertyAccessResult::Ignored,
        };
        self.0[d] = v;
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for PlyVertex {
    fn new() -> Self {
        Self::default()
    }
    fn set_char(&mut self, n: &str, v: i8) -> PropertyAccessResult {
        self.set(n, v.into())
    }
    fn set_uchar(&mut self, n: &str, v: u8) -> PropertyAccessResult {
        self.set(n, v.into())
    }
    fn set_short(&mut self, n: &str, v: i16) -> PropertyAccessResult {
        self.set(n, v.into())
    }
    fn set_ushort(&mut self, n: &str, v: u16) -> PropertyAccessResult {
        self.set(n, v.into())
    }
    fn set_int(&mut self, n: &str, v: i32) -> PropertyAccessResult {
        self.set(n, v.into())
    }
    fn set_uint(&mut self, n: &str, v: u32) -> PropertyAccessResult {
        self.set(n, v.into())
    }
    fn set_float(&mut self, n: &str, v: f32) -> PropertyAccessResult {
        self.set(n, v.into())
    }
    fn set_double(&mut self, n: &str, v: f64) -> PropertyAccessResult {
        self.set(n, v)
    }
}

/// A PLY face: the `vertex_indices` (or `vertex_index`) list of any integer
/// type; other properties ignored.
#[derive(Default)]
struct PlyFace(Vec<i64>);

fn is_face_list(name: &str) -> bool {
    name == "vertex_indices" || name == "vertex_index"
}

impl PlyFace {
    fn set<T: Into<i64>>(&mut self, name: &str, v: Vec<T>) -> PropertyAccessResult {
        if !is_face_list(name) {
            return PropertyAccessResult::Ignored;
        }
        self.0 = v.into_iter().map(Into::into).collect();
        PropertyAccessResult::Set
    }
}

impl PropertyAccess for PlyFace {
    fn new() -> Self {
        Self::default()
    }
    fn set_list_char(&mut self, n: &str, v: Vec<i8>) -> PropertyAccessResult {
        self.set(n, v)
    }
    fn set_list_uchar(&mut self, n: &str, v: Vec<u8>) -> PropertyAccessResult {
        self.set(n, v)
    }
    fn set_list_short(&mut self, n: &str, v: Vec<i16>) -> PropertyAccessResult {
        self.set(n, v)
    }
    fn set_list_ushort(&mut self, n: &str, v: Vec<u16>) -> PropertyAccessResult {
        self.set(n, v)
    }
    fn set_list_int(&mut self, n: &str, v: Vec<i32>) -> PropertyAccessResult {
        self.set(n, v)
    }
    fn set_list_uint(&mut self, n: &str, v: Vec<u32>) -> PropertyAccessResult {
        self.set(n, v)
    }
}

/// Any other PLY element: read and dropped.
struct PlySkip;

impl PropertyAccess for PlySkip {
    fn new() -> Self {
        PlySkip
    }
}

fn is_integer(t: &ply_rs_bw::ply::ScalarType) -> bool {
    use ply_rs_bw::ply::ScalarType as S;
    !matches!(t, S::Float | S::Double)
}

/// Checks the header declares what the reader needs.
fn ply_layout(header: &Header, name: &str) -> Result<(), MeshError> {
    let bad = |m: String| parse_error(name, Format::Ply, m);
    let vertex =
        header.elements.get("vertex").ok_or_else(|| bad("the header declares no 'vertex' element".to_string()))?;
    for axis in ["x", "y", "z"] {
        match vertex.properties.get(axis).map(|p| &p.data_type) {
            Some(PropertyType::Scalar(_)) => {}
            Some(PropertyType::List(..)) => {
                return Err(bad(format!("vertex property '{axis}' is a list, expected a number")))
            }
            None => return Err(bad(format!("the vertex element has no property '{axis}'"))),
        }
    }
    if vertex.count > u32::MAX as usize {
        return Err(too_many_vertices(name, vertex.count as u64));
    }
    if let Some(face) = header.elements.get("face") {
        let list = face
            .properties
            .values()
            .find(|p| is_face_list(&p.name))
            .ok_or_else(|| bad("the face element has no 'vertex_indices' (or 'vertex_index') list".into()))?;
        match &list.data_type {
            PropertyType::List(_, item) if is_integer(item) => {}
            t => return Err(bad(format!("face property '{}' has type {t:?}, expected a list of integers", list.name))),
        }
    }
    Ok(())
}

fn ply_payload_error(name: &str, element: &ElementDef, e: ply_rs_bw::parser::ParseError) -> MeshError {
    let truncated = e.kind() == std::io::ErrorKind::UnexpectedEof;
    parse_error(
        name,
        Format::Ply,
        format!(
            "{}reading element '{}' ({} declared): {}",
            if truncated { "the file ends early (truncated?) while " } else { "" },
            element.name,
            element.count,
            ply_message(&e)
        ),
    )
}

/// A `ply-rs-bw` error on one line: its message and the offending text, without
/// the grammar's debug dump.
fn ply_message(e: &ply_rs_bw::parser::ParseError) -> String {
    e.to_string()
        .split("\n\t")
        .filter(|part| !part.starts_with("Error: ParseError {"))
        .map(|part| {
            let part = part.replace('\n', " ");
            match part.char_indices().nth(160) {
                Some((cut, _)) => format!("{}…", &part[..cut]),
                None => part,
            }
        })
        .collect::<Vec<_>>()
        .join("; ")
}

fn read_ply(file: File, name: &str) -> Result<Parsed, MeshError> {
    let mut reader = PlyReader::new(BufReader::with_capacity(1 << 16, file));
    let header = PlyParser::<PlySkip>::new()
        .read_header(&mut reader)
        .map_err(|e| parse_error(name, Format::Ply, format!("bad header: {}", ply_message(&e))))?;
    ply_layout(&header, name)?;

    let mut vertices = Vec::new();
    let mut faces = Vec::new();
    let mut skipped = Vec::new();
    for (key, element) in &header.elements {
        let err = |e| ply_payload_error(name, element, e);
        match key.as_str() {
            "vertex" => {
                vertices = PlyParser::<PlyVertex>::new()
                    .read_payload_for_element(&mut reader, element, &header)
                    .map_err(err)?
            }
            "face" => {
                faces =
                    PlyParser::<PlyFace>::new().read_payload_for_element(&mut reader, element, &header).map_err(err)?
            }
            _ => {
                PlyParser::<PlySkip>::new().read_payload_for_element(&mut reader, element, &header).map_err(err)?;
                skipped.push(format!("'{key}'"));
            }
        }
    }

    let n = vertices.len();
    let mut triangles = Vec::with_capacity(faces.len());
    let mut short = 0usize;
    for (f, face) in faces.iter().enumerate() {
        let idx = &face.0;
        if let Some(&bad) = idx.iter().find(|&&i| i < 0 || i >= n as i64) {
            return Err(MeshError::IndexOutOfRange { path: name.to_string(), face: f, index: bad, vertices: n });
        }
        if idx.len() < 3 {
            short += 1;
            continue;
        }
        // In range, so each index fits in u32 (n ≤ u32::MAX was checked).
        for k in 1..idx.len() - 1 {
            triangles.push([idx[0] as u32, idx[k] as u32, idx[k + 1] as u32]);
        }
    }
    let mut warnings = Vec::new();
    if short > 0 {
        warnings.push(format!("{short} faces with fewer than 3 vertices skipped"));
    }
    if !skipped.is_empty() {
        warnings.push(format!("PLY elements not used for the mesh: {}", skipped.join(", ")));
    }
    Ok(Parsed {
        mesh: Mesh { positions_m: vertices.into_iter().map(|v| v.0).collect(), triangles },
        faces: faces.len(),
        warnings,
    })
}

// ---------------------------------------------------------------- OBJ

fn read_obj(file: File, name: &str) -> Result<Parsed, MeshError> {
    // Positions keep their own index (single_index: false); points and
    // lines are dropped; polygons become triangle fans.
    let options = tobj::LoadOptions { triangulate: true, ..tobj::OFFLINE_RENDERING_LOAD_OPTIONS };
    let mut reader = BufReader::with_capacity(1 << 16, file);
    // Materials are not needed: never open the .mtl files the OBJ names.
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, |_| Err(tobj::LoadError::OpenFileFailed))
        .map_err(|e| parse_error(name, Format::Obj, e.to_string()))?;

    let mut mesh = Mesh::default();
    for model in &models {
        let m = &model.mesh;
        let offset = mesh.positions_m.len() as u64;
        let count = offset + (m.positions.len() / 3) as u64;
        if count > u32::MAX as u64 {
            return Err(too_many_vertices(name, count));
        }
        mesh.positions_m.extend(m.positions.chunks_exact(3).map(|c| [c[0], c[1], c[2]]));
        mesh.triangles
            .extend(m.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]].map(|i| (offset + u64::from(i)) as u32)));
    }
    // tobj keeps only the vertices faces use, renumbered; name a bad one by
    // its place among the file's `v` lines instead.
    if mesh.positions_m.iter().any(|p| !p.iter().all(|c| c.is_finite()))
        && let Some((vertex, position)) = first_non_finite_obj_vertex(reader)
    {
        return Err(MeshError::NonFinite { path: name.to_string(), vertex, position });
    }
    let faces = mesh.triangles.len();
    Ok(Parsed { mesh, faces, warnings: Vec::new() })
}

/// The first `v` line of an OBJ with a non-finite coordinate: (0-based
/// index among the `v` lines, position).
fn first_non_finite_obj_vertex(reader: BufReader<File>) -> Option<(usize, [f64; 3])> {
    let mut file = reader.into_inner();
    std::io::Seek::rewind(&mut file).ok()?;
    let mut index = 0usize;
    for line in BufReader::new(file).lines() {
        let line = line.ok()?;
        let mut words = line.split_whitespace();
        if words.next() != Some("v") {
            continue;
        }
        let mut p = [0.0f64; 3];
        for c in &mut p {
            *c = words.next().and_then(|w| w.parse().ok()).unwrap_or(0.0);
        }
        if !p.iter().all(|c| c.is_finite()) {
            return Some((index, p));
        }
        index += 1;
    }
    None
}

// ---------------------------------------------------------------- STL

fn read_stl(file: File, len: u64, name: &str) -> Result<Parsed, MeshError> {
    let bad = |m: String| parse_error(name, Format::Stl, m);
    let mut data = Vec::with_capacity(len as usize);
    std::io::Read::read_to_end(&mut BufReader::new(file), &mut data)
        .map_err(|source| MeshError::Io { path: name.to_string(), source })?;
    let len = data.len() as u64;
    let announced = (data.len() >= 84).then(|| u32::from_le_bytes([data[80], data[81], data[82], data[83]]) as u64);
    let binary_size = announced.map(|n| 84 + 50 * n);
    let ascii = {
        let start = data.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(0);
        data[start..].starts_with(b"solid")
    };
    let mut warnings = Vec::new();
    let binary = match binary_size {
        Some(size) if size == len => true,
        _ if ascii => false,
        Some(size) if size < len => {
            warnings.push(format!(
                "binary STL: {} bytes after the {} announced triangles ignored",
                len - size,
                announced.unwrap_or(0)
            ));
            true
        }
        Some(size) => {
            return Err(bad(format!(
                "the file ends early (truncated?): the binary STL header announces {} \
                 triangles ({size} bytes) but the file has {len} bytes",
                announced.unwrap_or(0)
            )))
        }
        None => {
            return Err(bad(format!(
                "neither ASCII STL (does not start with 'solid') nor binary STL ({len} bytes, \
                 less than the 84-byte header)"
            )))
        }
    };
    if binary {
        // stl_io takes any file whose first line starts with "solid " for
        // ASCII; blank the text header, which carries no geometry.
        data[..80].fill(0);
    } else {
        // stl_io wants "solid " (with a space) at the very start: rewrite a
        // first line such as "solid" or "  solid".
        let eol = data.iter().position(|&b| b == b'\n').unwrap_or(data.len());
        if !data.starts_with(b"solid ") {
            let mut fixed = b"solid mesh\n".to_vec();
            fixed.extend_from_slice(data.get(eol + 1..).unwrap_or(&[]));
            data = fixed;
        }
    }
    let kind = if binary { "binary" } else { "ASCII" };
    let mut cursor = Cursor::new(data);
    let triangles = stl_io::create_stl_reader(&mut cursor).map_err(|e| bad(format!("{kind} STL: {e}")))?;

    let mut mesh = Mesh::default();
    let mut index: FxHashMap<[u32; 3], u32> = FxHashMap::default();
    let mut faces = 0usize;
    for (k, t) in triangles.enumerate() {
        let t = t.map_err(|e| {
            let early =
                if e.kind() == std::io::ErrorKind::UnexpectedEof { "the file ends early (truncated?) " } else { "" };
            bad(format!("{early}{kind} STL, at triangle {k}: {e}"))
        })?;
        faces += 1;
        let mut tri = [0u32; 3];
        for (slot, v) in tri.iter_mut().zip(&t.vertices) {
            let key = v.0.map(|c| (c + 0.0).to_bits());
            *slot = match index.entry(key) {
                Entry::Occupied(e) => *e.get(),
                Entry::Vacant(e) => {
                    let i = mesh.positions_m.len();
                    if i >= u32::MAX as usize {
                        return Err(too_many_vertices(name, i as u64 + 1));
                    }
                    mesh.positions_m.push(v.0.map(f64::from));
                    *e.insert(i as u32)
                }
            };
        }
        mesh.triangles.push(tri);
    }
    Ok(Parsed { mesh, faces, warnings })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_extension_lists_supported() {
        let e = load(Path::new("scan.xyz"), 1.0).unwrap_err();
        let s = e.to_string();
        assert!(s.contains("scan.xyz") && s.contains(".xyz") && s.contains(".ply, .obj, .stl"));
        let e = load(Path::new("scan"), 1.0).unwrap_err();
        assert!(e.to_string().contains("(none)"), "{e}");
    }

    #[test]
    fn extension_is_case_insensitive() {
        assert_eq!(Format::of(Path::new("a.PLY"), "").unwrap(), Format::Ply);
        assert_eq!(Format::of(Path::new("a.Obj"), "").unwrap(), Format::Obj);
        assert_eq!(Format::of(Path::new("a.sTl"), "").unwrap(), Format::Stl);
    }

    #[test]
    fn bad_scale_is_refused() {
        for s in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            let e = load(Path::new("a.ply"), s).unwrap_err();
            assert!(matches!(e, MeshError::InvalidScale { .. }), "{e}");
        }
    }

    #[test]
    fn check_counts_degenerate_without_changing() {
        let mut m = plaque_box(1.0, 1.0, 1.0);
        m.triangles.push([0, 0, 1]); // repeated index
        m.positions_m.push([-0.5, -0.5, -0.0]); // same place as vertex 0
        m.triangles.push([8, 0, 1]); // repeated position
        m.positions_m.push([0.0, -0.5, 0.0]); // on the edge 0–1
        m.triangles.push([0, 1, 9]); // collinear
        let r = m.check("box").unwrap();
        assert_eq!(r.degenerate_removed, 3);
        assert_eq!(r.triangles, 12);
        assert!(r.closed, "{r:?}");
        assert_eq!(m.triangles.len(), 15);
    }

    #[test]
    fn flipped_triangle_is_an_orientation_warning() {
        let mut m = plaque_box(1.0, 1.0, 1.0);
        m.triangles[0] = [0, 1, 2];
        let r = m.check("box").unwrap();
        assert!(r.closed);
        assert!(r.warnings.iter().any(|w| w.contains("inconsistent orientation: 3 edges")), "{:?}", r.warnings);
    }

    #[test]
    fn inward_box_is_warned() {
        let m = plaque_box(1.0, 1.0, 1.0);
        let inv = Mesh {
            positions_m: m.positions_m.clone(),
            triangles: m.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect(),
        };
        let r = inv.check("box").unwrap();
        assert!(r.warnings.iter().any(|w| w.contains("negative signed volume")));
    }

    #[test]
    fn non_manifold_edges_are_counted() {
        let mut m = plaque_box(1.0, 1.0, 1.0);
        // A fin on the bottom edge 0–1 (a third triangle on it).
        m.positions_m.push([0.0, -1.0, -1.0]);
        m.triangles.push([0, 1, 8]);
        let r = m.check("fin").unwrap();
        assert_eq!(r.non_manifold_edges, 1);
        assert_eq!(r.boundary_edges, 2);
        assert!(!r.closed);
    }

    #[test]
    fn check_errors_name_the_mesh() {
        let mut m = plaque_box(1.0, 1.0, 1.0);
        m.positions_m[3][1] = f64::INFINITY;
        let e = m.check("plaque").unwrap_err().to_string();
        assert!(e.contains("plaque") && e.contains("vertex 3"), "{e}");
        let mut m = plaque_box(1.0, 1.0, 1.0);
        m.triangles[5][2] = 8;
        let e = m.check("plaque").unwrap_err().to_string();
        assert!(e.contains("face 5") && e.contains("index 8"), "{e}");
        let m = Mesh { positions_m: vec![[0.0; 3]; 3], triangles: vec![[0, 1, 2]] };
        let e = m.check("flat").unwrap_err().to_string();
        assert!(e.contains("no triangles") && e.contains("degenerate triangles removed: 1"));
    }

    #[test]
    fn reflection_keeps_normals_outward() {
        let m = plaque_box(0.06, 0.04, 0.01);
        let mirror = [[-1.0, 0.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]];
        let r = m.transformed(&mirror);
        assert!((r.signed_volume_m3() - m.signed_volume_m3()).abs() < 1e-18);
        // Projective last row: dividing by w = 2 halves every coordinate.
        let mut half = mirror;
        half[0][0] = 1.0;
        half[3][3] = 2.0;
        let h = m.transformed(&half);
        assert_eq!(h.positions_m[6], [0.015, 0.01, 0.005]);
    }
}
