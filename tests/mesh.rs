//! Triangle-mesh loading (`lucent::scene::mesh`): the plaque box, round trips
//! through every format, transforms and unit scale, bad files under
//! `tests/bad/mesh/`, open meshes, and a million-triangle load.

use lucent::scene::mesh::{load, plaque_box, Mesh, MeshError};
use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

// ------------------------------------------------------------ writers

/// Faces as polygons (lists of vertex indices).
fn polygons(m: &Mesh) -> Vec<Vec<u32>> {
    m.triangles.iter().map(|t| t.to_vec()).collect()
}

fn ply_header(format: &str, scalar: &str, v: usize, f: usize, extra: bool) -> String {
    let mut h = format!("ply\nformat {format} 1.0\ncomment written by tests/mesh.rs\n");
    write!(h, "element vertex {v}\nproperty {scalar} x\nproperty {scalar} y\n").unwrap();
    writeln!(h, "property {scalar} z").unwrap();
    if extra {
        h += "property uchar red\n";
    }
    write!(h, "element face {f}\nproperty list uchar int vertex_indices\n").unwrap();
    if extra {
        h += "property float quality\nelement edge 1\nproperty int vertex1\nproperty int vertex2\n";
    }
    h + "end_header\n"
}

fn write_ply_ascii(path: &Path, positions: &[[f64; 3]], faces: &[Vec<u32>]) {
    let mut s = ply_header("ascii", "double", positions.len(), faces.len(), false);
    for p in positions {
        writeln!(s, "{} {} {}", p[0], p[1], p[2]).unwrap();
    }
    for f in faces {
        write!(s, "{}", f.len()).unwrap();
        for i in f {
            write!(s, " {i}").unwrap();
        }
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

/// Binary PLY with doubles, an extra vertex property, an extra face property
/// and an extra element, so the reader has to skip what it does not use.
fn write_ply_binary(path: &Path, positions: &[[f64; 3]], faces: &[Vec<u32>], big: bool) {
    let format = if big { "binary_big_endian" } else { "binary_little_endian" };
    let mut b = ply_header(format, "double", positions.len(), faces.len(), true).into_bytes();
    let f64b = |x: f64| {
        if big {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        }
    };
    let i32b = |x: i32| {
        if big {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        }
    };
    let f32b = |x: f32| {
        if big {
            x.to_be_bytes()
        } else {
            x.to_le_bytes()
        }
    };
    for p in positions {
        for c in p {
            b.extend(f64b(*c));
        }
        b.push(200); // red
    }
    for f in faces {
        b.push(f.len() as u8);
        for &i in f {
            b.extend(i32b(i as i32));
        }
        b.extend(f32b(0.5)); // quality
    }
    b.extend(i32b(0));
    b.extend(i32b(1));
    std::fs::write(path, b).unwrap();
}

fn write_obj(path: &Path, positions: &[[f64; 3]], faces: &[Vec<u32>]) {
    let mut s = String::from("# written by tests/mesh.rs\nmtllib missing.mtl\no box\n");
    for p in positions {
        writeln!(s, "v {} {} {}", p[0], p[1], p[2]).unwrap();
    }
    s += "vn 0 0 1\nusemtl nothing\n";
    for f in faces {
        s.push('f');
        for i in f {
            write!(s, " {}//1", i + 1).unwrap();
        }
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

fn write_stl_ascii(path: &Path, m: &Mesh, first_line: &str) {
    let mut s = format!("{first_line}\n");
    for t in &m.triangles {
        s += "  facet normal 0 0 0\n    outer loop\n";
        for &i in t {
            let p = m.positions_m[i as usize];
            writeln!(s, "      vertex {} {} {}", p[0] as f32, p[1] as f32, p[2] as f32).unwrap();
        }
        s += "    endloop\n  endfacet\n";
    }
    s += "endsolid box\n";
    std::fs::write(path, s).unwrap();
}

fn write_stl_binary(path: &Path, positions: &[[f32; 3]], triangles: &[[u32; 3]], header: &[u8]) {
    let mut b = Vec::with_capacity(84 + 50 * triangles.len());
    let mut h = [0u8; 80];
    h[..header.len()].copy_from_slice(header);
    b.extend(h);
    b.extend((triangles.len() as u32).to_le_bytes());
    for t in triangles {
        b.extend([0u8; 12]); // normal: readers recompute it
        for &i in t {
            for c in positions[i as usize] {
                b.extend(c.to_le_bytes());
            }
        }
        b.extend([0u8; 2]);
    }
    std::fs::write(path, b).unwrap();
}

fn f32_positions(m: &Mesh) -> Vec<[f32; 3]> {
    m.positions_m.iter().map(|p| p.map(|c| c as f32)).collect()
}

// ------------------------------------------------------------ helpers

/// Signed volume by the divergence theorem, computed here independently.
fn volume(m: &Mesh) -> f64 {
    let p = |i: u32| m.positions_m[i as usize];
    m.triangles
        .iter()
        .map(|&[a, b, c]| {
            let (a, b, c) = (p(a), p(b), p(c));
            a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])
        })
        .sum::<f64>()
        / 6.0
}

/// Triangles as position triples, rotated to start at their smallest corner
/// and sorted: equal for meshes that differ only in vertex numbering.
fn geometry(m: &Mesh) -> Vec<[[u64; 3]; 3]> {
    let mut g: Vec<_> = m
        .triangles
        .iter()
        .map(|t| {
            let mut q = t.map(|i| m.positions_m[i as usize].map(f64::to_bits));
            let k = (0..3).min_by_key(|&k| q[k]).unwrap();
            q.rotate_left(k);
            q
        })
        .collect();
    g.sort();
    g
}

fn sorted_positions(m: &Mesh) -> Vec<[u64; 3]> {
    let mut p: Vec<_> = m.positions_m.iter().map(|p| p.map(f64::to_bits)).collect();
    p.sort();
    p
}

/// A box whose coordinates are exact in f32, so STL keeps them bit for bit.
fn exact_box() -> Mesh {
    plaque_box(1.0, 0.5, 0.25)
}

/// The box's six faces as quads, counter-clockwise seen from outside; their
/// fans (a, b, c), (a, c, d) are the triangles of `plaque_box`.
fn box_quads() -> Vec<Vec<u32>> {
    vec![vec![0, 3, 2, 1], vec![4, 5, 6, 7], vec![0, 1, 5, 4], vec![2, 3, 7, 6], vec![3, 0, 4, 7], vec![1, 2, 6, 5]]
}

fn bad(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad/mesh").join(name)
}

fn load_err(name: &str) -> (MeshError, String) {
    let e = load(&bad(name), 1.0).expect_err(name);
    let s = e.to_string();
    assert!(s.contains(name), "message does not name the file: {s}");
    (e, s)
}

// ------------------------------------------------------------ the plaque

#[test]
fn plaque_box_is_closed_with_outward_normals() {
    let (w, h, t) = (0.060, 0.040, 0.00635);
    let m = plaque_box(w, h, t);
    assert_eq!(m.triangles.len(), 12);
    assert_eq!(m.positions_m.len(), 8);
    let v = volume(&m);
    assert!(v > 0.0);
    assert!((v - w * h * t).abs() < 1e-12, "{v}");
    assert!((m.signed_volume_m3() - w * h * t).abs() < 1e-18);
    let r = m.check("plaque").unwrap();
    assert!(r.closed);
    assert_eq!((r.boundary_edges, r.non_manifold_edges), (0, 0));
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    assert_eq!(r.bbox_min_m, [-0.030, -0.020, 0.0]);
    assert_eq!(r.bbox_max_m, [0.030, 0.020, 0.00635]);
    // Every triangle's normal points away from the centre of the box.
    for tri in &m.triangles {
        let [a, b, c] = tri.map(|i| m.positions_m[i as usize]);
        let (e1, e2) = ([b[0] - a[0], b[1] - a[1], b[2] - a[2]], [c[0] - a[0], c[1] - a[1], c[2] - a[2]]);
        let n = [e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]];
        let centroid = [(a[0] + b[0] + c[0]) / 3.0, (a[1] + b[1] + c[1]) / 3.0, (a[2] + b[2] + c[2]) / 3.0 - t / 2.0];
        assert!(n.iter().zip(&centroid).map(|(n, c)| n * c).sum::<f64>() > 0.0);
    }
}

#[test]
fn fixture_is_the_plaque() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mesh/plaque_ascii.ply");
    let (m, r) = load(&path, 1.0).unwrap();
    assert_eq!(m, plaque_box(0.060, 0.040, 0.00635));
    assert!(r.closed && r.warnings.is_empty(), "{r:?}");
    // The report is what a run report stores.
    let j = serde_json::to_value(&r).unwrap();
    assert_eq!(j["triangles"], 12);
    assert_eq!(j["closed"], true);
    assert!(j["path"].as_str().unwrap().ends_with("plaque_ascii.ply"));
}

/// Regenerates `fixtures/mesh/plaque_ascii.ply` (see fixtures/mesh/README.md).
#[test]
#[ignore = "writes the committed fixture; run by hand to regenerate it"]
fn write_plaque_fixture() {
    let m = plaque_box(0.060, 0.040, 0.00635);
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("fixtures/mesh/plaque_ascii.ply");
    let mut s = String::from("ply\nformat ascii 1.0\n");
    s += "comment lucent::scene::mesh::plaque_box(0.060, 0.040, 0.00635): plaque 60 x 40 x 6.35 mm\n";
    s += "comment units: metres; origin at the centre of the bottom face; outward normals (CCW)\n";
    writeln!(s, "element vertex {}", m.positions_m.len()).unwrap();
    s += "property double x\nproperty double y\nproperty double z\n";
    writeln!(s, "element face {}", m.triangles.len()).unwrap();
    s += "property list uchar int vertex_indices\nend_header\n";
    for p in &m.positions_m {
        writeln!(s, "{} {} {}", p[0], p[1], p[2]).unwrap();
    }
    for t in &m.triangles {
        writeln!(s, "3 {} {} {}", t[0], t[1], t[2]).unwrap();
    }
    std::fs::write(path, s).unwrap();
}

// ------------------------------------------------------------ round trips

fn assert_same_box(m: &Mesh, path: &Path) {
    let want = exact_box();
    assert_eq!(m.triangles.len(), 12, "{}", path.display());
    assert_eq!(m.positions_m.len(), 8, "{}", path.display());
    assert_eq!(sorted_positions(m), sorted_positions(&want));
    assert_eq!(geometry(m), geometry(&want), "{}", path.display());
}

/// The report's warnings other than the size hint (these test meshes are
/// 1 m across, which the size check flags as a likely unit mistake).
fn mesh_warnings(r: &lucent::scene::mesh::MeshReport) -> Vec<&String> {
    r.warnings.iter().filter(|w| !w.contains("unit_scale_m")).collect()
}

fn assert_closed_report(r: &lucent::scene::mesh::MeshReport) {
    assert!(r.closed, "{r:?}");
    assert!(mesh_warnings(r).is_empty(), "{:?}", r.warnings);
    assert_eq!(r.triangles, 12);
    assert_eq!(r.bbox_min_m, [-0.5, -0.25, 0.0]);
    assert_eq!(r.bbox_max_m, [0.5, 0.25, 0.25]);
}

#[test]
fn ply_ascii_round_trip() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.ply");
    let m = exact_box();
    write_ply_ascii(&path, &m.positions_m, &polygons(&m));
    let (back, r) = load(&path, 1.0).unwrap();
    assert_eq!(back, m);
    assert_closed_report(&r);
}

#[test]
fn ply_binary_round_trips_both_byte_orders_with_quads() {
    let dir = tempfile::tempdir().unwrap();
    let m = exact_box();
    for big in [false, true] {
        let path = dir.path().join(if big { "box_be.PLY" } else { "box_le.ply" });
        write_ply_binary(&path, &m.positions_m, &box_quads(), big);
        let (back, r) = load(&path, 1.0).unwrap();
        assert_eq!(back.positions_m, m.positions_m);
        assert_same_box(&back, &path);
        assert!(r.closed && r.triangles == 12, "{r:?}");
        // The unused 'edge' element is reported, nothing else.
        let w = mesh_warnings(&r);
        assert_eq!(w.len(), 1, "{:?}", r.warnings);
        assert!(w[0].contains("'edge'"));
    }
}

#[test]
fn obj_round_trip_with_quad_faces() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("box.obj");
    let m = exact_box();
    // Five quads and the last face as two triangles: quads are fan-split.
    let mut faces = box_quads();
    faces.pop();
    faces.extend(m.triangles[10..].iter().map(|t| t.to_vec()));
    write_obj(&path, &m.positions_m, &faces);
    let (back, r) = load(&path, 1.0).unwrap();
    assert_same_box(&back, &path);
    assert_closed_report(&r);
}

#[test]
fn stl_ascii_round_trip_welds_corners() {
    let dir = tempfile::tempdir().unwrap();
    let m = exact_box();
    // The first line may carry a name, none, or leading blanks.
    for (k, first) in ["solid box", "solid", "  solid box"].iter().enumerate() {
        let path = dir.path().join(format!("box{k}.stl"));
        write_stl_ascii(&path, &m, first);
        let (back, r) = load(&path, 1.0).unwrap();
        assert_same_box(&back, &path);
        assert_closed_report(&r);
        assert_eq!(r.vertices, 8);
    }
}

#[test]
fn stl_binary_round_trip_welds_corners() {
    let dir = tempfile::tempdir().unwrap();
    let m = exact_box();
    // Some exporters start the binary header with "solid": still binary.
    for (k, header) in [&b"binary box"[..], &b"solid box (binary)"[..]].iter().enumerate() {
        let path = dir.path().join(format!("box{k}.stl"));
        write_stl_binary(&path, &f32_positions(&m), &m.triangles, header);
        let (back, r) = load(&path, 1.0).unwrap();
        assert_same_box(&back, &path);
        assert_closed_report(&r);
    }
    // The crate's own writer gives the same.
    let path = dir.path().join("stl_io.STL");
    let tris: Vec<stl_io::Triangle> = m
        .triangles
        .iter()
        .map(|t| stl_io::Triangle {
            normal: stl_io::Normal::new([0.0; 3]),
            vertices: t.map(|i| stl_io::Vertex::new(m.positions_m[i as usize].map(|c| c as f32))),
        })
        .collect();
    stl_io::write_stl(&mut std::fs::File::create(&path).unwrap(), tris.iter()).unwrap();
    let (back, _) = load(&path, 1.0).unwrap();
    assert_same_box(&back, &path);
}

#[test]
fn unit_scale_converts_millimetres() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("plaque_mm.ply");
    let mm = plaque_box(60.0, 40.0, 6.35);
    write_ply_ascii(&path, &mm.positions_m, &polygons(&mm));
    let (m, r) = load(&path, 0.001).unwrap();
    let want = plaque_box(0.060, 0.040, 0.00635);
    for (p, q) in m.positions_m.iter().zip(&want.positions_m) {
        for d in 0..3 {
            assert!((p[d] - q[d]).abs() <= 1e-17, "{p:?} vs {q:?}");
        }
    }
    assert!((r.bbox_max_m[2] - 0.00635).abs() < 1e-17);
    assert!((volume(&m) - 0.060 * 0.040 * 0.00635).abs() < 1e-18);
}

#[test]
fn transformed_translates_and_rotates() {
    let m = plaque_box(0.060, 0.040, 0.00635);
    // A quarter turn about z, then a shift: (x, y, z) -> (-y + 1, x + 2, z + 3).
    let quarter = [[0.0, -1.0, 0.0, 1.0], [1.0, 0.0, 0.0, 2.0], [0.0, 0.0, 1.0, 3.0], [0.0, 0.0, 0.0, 1.0]];
    let t = m.transformed(&quarter);
    assert_eq!(t.triangles, m.triangles);
    for (p, q) in m.positions_m.iter().zip(&t.positions_m) {
        assert_eq!(*q, [-p[1] + 1.0, p[0] + 2.0, p[2] + 3.0]);
    }
    let r = t.check("turned").unwrap();
    assert!(r.closed && r.warnings.is_empty());
    assert!((r.bbox_min_m[0] - 0.98).abs() < 1e-15 && (r.bbox_max_m[1] - 2.03).abs() < 1e-15);
    // A general rotation (30° about (1, 1, 1)/√3) keeps lengths and volume.
    let (s, c) = 30f64.to_radians().sin_cos();
    let k = 1.0 / 3f64.sqrt();
    let (a, b) = ((1.0 - c) / 3.0, s * k);
    let rot =
        [[c + a, a - b, a + b, -0.5], [a + b, c + a, a - b, 0.25], [a - b, a + b, c + a, 0.0], [0.0, 0.0, 0.0, 1.0]];
    let t = m.transformed(&rot);
    let v = m.signed_volume_m3();
    assert!((t.signed_volume_m3() - v).abs() < 1e-12 * v);
    let dist = |m: &Mesh, i: usize, j: usize| {
        let (p, q) = (m.positions_m[i], m.positions_m[j]);
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt()
    };
    for (i, j) in [(0, 6), (1, 7), (2, 4), (0, 1)] {
        assert!((dist(&t, i, j) - dist(&m, i, j)).abs() < 1e-15);
    }
}

// ------------------------------------------------------------ warnings

#[test]
fn open_box_loads_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("open.ply");
    let mut m = plaque_box(0.060, 0.040, 0.00635);
    m.triangles.drain(2..4); // no top
    write_ply_ascii(&path, &m.positions_m, &polygons(&m));
    let (back, r) = load(&path, 1.0).unwrap();
    assert_eq!(back.triangles.len(), 10);
    assert!(!r.closed);
    assert_eq!(r.boundary_edges, 4);
    assert_eq!(r.non_manifold_edges, 0);
    let w = r.warnings.join("; ");
    assert!(w.contains("open") && w.contains("4 boundary edges"), "{w}");
}

#[test]
fn degenerate_triangles_are_removed_on_load() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("degenerate.obj");
    let m = exact_box();
    let mut faces = polygons(&m);
    faces.insert(3, vec![0, 1, 0]); // repeated index
    faces.push(vec![4, 5, 5]);
    write_obj(&path, &m.positions_m, &faces);
    let (back, r) = load(&path, 1.0).unwrap();
    assert_eq!(r.degenerate_removed, 2);
    assert_eq!(back.triangles.len(), 12);
    assert_same_box(&back, &path);
    assert!(r.closed);
    assert!(r.warnings.iter().any(|w| w.contains("2 degenerate triangles")));
}

// ------------------------------------------------------------ bad input

#[test]
fn bad_files_give_specific_errors() {
    let (e, s) = load_err("truncated_binary.ply");
    assert!(matches!(e, MeshError::Parse { .. }), "{s}");
    assert!(s.contains("ends early") && s.contains("'vertex'"), "{s}");

    let (e, s) = load_err("face_index_out_of_range.ply");
    assert!(matches!(e, MeshError::IndexOutOfRange { face: 2, index: 7, vertices: 4, .. }), "{s}");
    assert!(s.contains("face 2") && s.contains("vertex index 7"), "{s}");

    let (e, s) = load_err("negative_index.ply");
    assert!(matches!(e, MeshError::IndexOutOfRange { index: -1, .. }), "{s}");

    let (e, s) = load_err("nan_vertex.obj");
    assert!(matches!(e, MeshError::NonFinite { vertex: 1, .. }), "{s}");
    assert!(s.contains("vertex 1") && s.contains("non-finite"), "{s}");

    let (e, s) = load_err("empty.stl");
    assert!(matches!(e, MeshError::Empty { .. }) && s.contains("empty"), "{s}");

    let (e, s) = load_err("unknown_format.xyz");
    assert!(matches!(e, MeshError::UnknownFormat { .. }), "{s}");
    assert!(s.contains("unknown mesh format \".xyz\"") && s.contains(".ply, .obj, .stl"));

    let (e, s) = load_err("garbage.ply");
    assert!(matches!(e, MeshError::Parse { format: "PLY", .. }), "{s}");
    assert!(s.contains("magic number"), "{s}");

    let (_, s) = load_err("truncated_binary.stl");
    assert!(s.contains("ends early") && s.contains("12 triangles"), "{s}");

    let (_, s) = load_err("bad_number.stl");
    assert!(s.contains("ASCII STL"), "{s}");

    let (_, s) = load_err("face_out_of_range.obj");
    assert!(s.contains("out of bounds"), "{s}");

    let (e, s) = load_err("no_faces.ply");
    assert!(matches!(e, MeshError::NoTriangles { faces: 0, .. }), "{s}");

    let (e, s) = load_err("too_many_vertices.ply");
    assert!(matches!(e, MeshError::TooLarge { .. }), "{s}");

    let (e, s) = load_err("bad_texcoord_index.obj");
    assert!(matches!(e, MeshError::Parse { format: "OBJ", .. }), "{s}");

    let e = load(&bad("does_not_exist.ply"), 1.0).unwrap_err();
    assert!(matches!(e, MeshError::Io { .. }));
    assert!(e.to_string().contains("does_not_exist.ply"));
}

/// Every file under tests/bad/mesh/ is refused with a message naming it, and
/// none makes a parser panic through `load`.
#[test]
fn every_bad_file_is_an_error() {
    let mut n = 0;
    for entry in std::fs::read_dir(bad("")).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap().to_string_lossy().to_string();
        if name == "README.md" {
            continue;
        }
        let r = std::panic::catch_unwind(|| load(&path, 1.0));
        let e = r.unwrap_or_else(|_| panic!("{name}: load panicked"));
        let e = e.expect_err(&name).to_string();
        assert!(e.contains(&name), "{e}");
        n += 1;
    }
    assert!(n >= 13, "{n} bad files");
}

/// Truncated and byte-flipped copies of valid files in every format load to
/// `Ok` or `Err`, never a panic (the parsers run under `catch_unwind`, and the
/// checks after them must not panic either).
#[test]
fn mutated_files_never_panic() {
    let dir = tempfile::tempdir().unwrap();
    let m = exact_box();
    let sources = [
        ("a.ply", {
            let p = dir.path().join("a.ply");
            write_ply_ascii(&p, &m.positions_m, &box_quads());
            p
        }),
        ("b.ply", {
            let p = dir.path().join("b.ply");
            write_ply_binary(&p, &m.positions_m, &box_quads(), false);
            p
        }),
        ("c.obj", {
            let p = dir.path().join("c.obj");
            write_obj(&p, &m.positions_m, &box_quads());
            p
        }),
        ("d.stl", {
            let p = dir.path().join("d.stl");
            write_stl_ascii(&p, &m, "solid box");
            p
        }),
        ("e.stl", {
            let p = dir.path().join("e.stl");
            write_stl_binary(&p, &f32_positions(&m), &m.triangles, b"solid box");
            p
        }),
    ];
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = move || {
        // xorshift64*: a fixed, seeded sequence of edits.
        state ^= state >> 12;
        state ^= state << 25;
        state ^= state >> 27;
        state.wrapping_mul(0x2545_f491_4f6c_dd1d)
    };
    let (mut ok, mut err) = (0, 0);
    for (name, source) in &sources {
        let bytes = std::fs::read(source).unwrap();
        for k in 0..200 {
            // A new file each time: rewriting one in place can force a disk flush.
            let target = dir.path().join(format!("mutated_{k}_{name}"));
            let mut b = bytes.clone();
            if k % 4 == 0 {
                b.truncate(next() as usize % b.len());
            } else {
                for _ in 0..1 + k % 3 {
                    let i = next() as usize % b.len();
                    b[i] = match next() % 3 {
                        0 => next() as u8,
                        1 => b"0123456789-.e \n/"[next() as usize % 16],
                        _ => b[i] ^ 0x80,
                    };
                }
            }
            std::fs::write(&target, &b).unwrap();
            match load(&target, 1.0) {
                Ok(_) => ok += 1,
                Err(e) => {
                    assert!(e.to_string().contains("mutated_"), "{e}");
                    err += 1
                }
            }
        }
    }
    assert_eq!(ok + err, 1000);
    assert!(err > 100 && ok > 100, "{ok} loaded, {err} refused");
}

// ------------------------------------------------------------ size

/// The surface of the unit cube, each face an n × n grid of quads split in
/// two: 12 n² triangles on 6 n² + 2 shared vertices, closed, outward.
fn tessellated_cube(n: u32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    // (corner, u, v) with u × v the outward normal.
    let faces: [([u32; 3], [u32; 3], [u32; 3]); 6] = [
        ([0, 0, 0], [0, 1, 0], [1, 0, 0]),
        ([0, 0, n], [1, 0, 0], [0, 1, 0]),
        ([0, 0, 0], [1, 0, 0], [0, 0, 1]),
        ([0, n, 0], [0, 0, 1], [1, 0, 0]),
        ([0, 0, 0], [0, 0, 1], [0, 1, 0]),
        ([n, 0, 0], [0, 1, 0], [0, 0, 1]),
    ];
    let mut ids: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut triangles = Vec::with_capacity(12 * (n * n) as usize);
    let mut id = |p: [u32; 3]| {
        *ids.entry(p).or_insert_with(|| {
            positions.push(p.map(|c| c as f32 / n as f32 - 0.5));
            (positions.len() - 1) as u32
        })
    };
    for (o, u, v) in faces {
        let at = |i: u32, j: u32| [0, 1, 2].map(|d| o[d] + i * u[d] + j * v[d]);
        for i in 0..n {
            for j in 0..n {
                let a = id(at(i, j));
                let b = id(at(i + 1, j));
                let c = id(at(i + 1, j + 1));
                let d = id(at(i, j + 1));
                triangles.push([a, b, c]);
                triangles.push([a, c, d]);
            }
        }
    }
    (positions, triangles)
}

fn write_ply_binary_f32(path: &Path, positions: &[[f32; 3]], triangles: &[[u32; 3]]) {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nelement face {}\n\
         property list uchar uint vertex_indices\nend_header\n",
        positions.len(),
        triangles.len()
    )
    .into_bytes();
    b.reserve(12 * positions.len() + 13 * triangles.len());
    for p in positions {
        for c in p {
            b.extend(c.to_le_bytes());
        }
    }
    for t in triangles {
        b.push(3);
        for i in t {
            b.extend(i.to_le_bytes());
        }
    }
    std::fs::write(path, b).unwrap();
}

/// Writes the tessellated cube as binary PLY and binary STL, loads both and
/// prints the load time (parse + check).
fn load_big(n: u32) {
    let (positions, triangles) = tessellated_cube(n);
    let (v, f) = (6 * (n * n) as usize + 2, 12 * (n * n) as usize);
    assert_eq!((positions.len(), triangles.len()), (v, f));
    let dir = tempfile::tempdir().unwrap();
    let ply = dir.path().join("cube.ply");
    let stl = dir.path().join("cube.stl");
    write_ply_binary_f32(&ply, &positions, &triangles);
    write_stl_binary(&stl, &positions, &triangles, b"tessellated cube");
    for path in [ply, stl] {
        let start = Instant::now();
        let (m, r) = load(&path, 1.0).unwrap();
        let seconds = start.elapsed().as_secs_f64();
        println!("{f} triangles, {}: load (parse + check) {seconds:.3} s", path.extension().unwrap().to_string_lossy());
        assert_eq!((r.vertices, r.triangles, m.triangles.len()), (v, f, f));
        assert!(r.closed, "{r:?}");
        assert_eq!((r.boundary_edges, r.non_manifold_edges), (0, 0));
        assert!(mesh_warnings(&r).is_empty(), "{:?}", r.warnings);
        assert_eq!(r.bbox_min_m, [-0.5; 3]);
        assert_eq!(r.bbox_max_m, [0.5; 3]);
        assert!((m.signed_volume_m3() - 1.0).abs() < 1e-6);
    }
}

#[test]
fn hundred_thousand_triangles_load_closed() {
    load_big(91); // 99 372 triangles
}

#[test]
fn million_triangles_load_closed() {
    load_big(289); // 1 002 252 triangles
}
