//! Ray–triangle queries over the object's mesh: a compressed 8-wide BVH
//! (`obvhs`' CWBVH, Ylitie, Karras, Laine, "Efficient incoherent ray
//! traversal on GPUs through compressed wide BVHs", HPG 2017) over f32
//! bounding boxes, and a **watertight** ray–triangle test in f64 (Woop,
//! Benthin, Wald, "Watertight ray/triangle intersection", JCGT 2(1), 2013).
//!
//! # Units and precision
//!
//! Positions are metres (any unit works; nothing here assumes a scale).
//! Vertices are kept in f64 and the hit distance `t` is computed in f64 from
//! them; the BVH only prunes, with boxes built in f32 and **inflated** by
//! 10⁻⁶ of the scene's extent (plus one f32 ulp of the coordinates), so the
//! rounding of vertices and ray origins to f32 can never make a node miss a
//! triangle that the f64 test would hit. The watertight test shears the ray
//! to +z and decides inside/outside by the signs of three edge functions, so
//! a ray through an edge or vertex shared by two triangles hits at least one
//! of them (no cracks for the medium to leak through).
//!
//! # Known quirks of obvhs 0.4.0
//!
//! * Its compressed-BVH traversal misses hits when a ray direction
//!   component is exactly −0.0 (the octant code treats it as negative while
//!   the slab test treats it as positive). [`Accel`] maps −0.0 to +0.0 in the
//!   f32 ray it hands to the traversal; `tests::negative_zero_direction` is
//!   the regression test.
//! * Its node test clamps the entry distance to at least 10⁻⁴ *scene units*
//!   (`EPSILON` in `cwbvh/node.rs`), so in metres every boundary closer than
//!   0.1 mm would be missed — most of them inside a dense medium, whose mean
//!   free path is ~70 µm. The BVH therefore works in units of extent/10
//!   (positions scaled by 10/extent, which also keeps its debug validator's
//!   absolute tolerances meaningful), and the f32 ray it traverses starts
//!   δ = 3·10⁻⁴ units *behind* the true origin: every node in front of the
//!   true origin is then entered at a distance ≥ δ > 10⁻⁴ and never
//!   clamped away, while the f64 triangle test measures from the true
//!   origin. `tests::hits_closer_than_obvhs_epsilon` is the regression test.
//!
//! ```
//! use glam::DVec3;
//! use lucent_render::accel::Accel;
//! // One triangle in the plane z = 0; a ray from z = 1 straight down hits it at t = 1.
//! let tri = [[DVec3::new(-1.0, -1.0, 0.0), DVec3::new(1.0, -1.0, 0.0), DVec3::new(0.0, 1.0, 0.0)]];
//! let accel = Accel::new(&tri);
//! let hit = accel.intersect(DVec3::new(0.0, 0.0, 1.0), DVec3::new(0.0, 0.0, -1.0), f64::INFINITY).unwrap();
//! assert_eq!(hit.t, 1.0);
//! assert_eq!(hit.normal, DVec3::Z); // counter-clockwise seen from +z
//! ```

use glam::{DVec3, Vec3A};
use obvhs::{
    aabb::Aabb,
    cwbvh::{builder::build_cwbvh, CwBvh},
    ray::{Ray, RayHit},
    Boundable, BvhBuildParams,
};
use std::sync::{Arc, OnceLock};
use std::time::Duration;

/// A hit on the mesh.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Hit {
    /// Distance along the (unit or not) direction, in units of the direction's length.
    pub t: f64,
    /// Index of the triangle in the order given to [`Accel::new`].
    pub triangle: u32,
    /// Unit geometric normal, by the right-hand rule over (v0, v1, v2).
    pub normal: DVec3,
}

/// The triangles and their BVH.
#[derive(Debug, Clone)]
pub struct Accel {
    bvh: CwBvh,
    /// Triangles in BVH leaf order (index = position in `primitive_indices`).
    tris: Vec<[DVec3; 3]>,
    /// Original index of each triangle in `tris`.
    original: Vec<u32>,
    bounds_min: DVec3,
    bounds_max: DVec3,
    /// BVH units per metre (10/extent), see the module doc.
    scale: f64,
    /// For a convex mesh with at most [`MAX_CONVEX_PLANES`] distinct face
    /// planes: the outward unit normals n and offsets c (n·x = c on the face).
    planes: Option<Vec<(DVec3, f64)>>,
    /// The mesh is convex (every vertex on the inner side of every face's
    /// plane); checked up to [`MAX_CONVEX_CHECK`] triangles, larger meshes
    /// count as not convex.
    convex: bool,
    /// The grid of [`Accel::distance_lower_bound`], built on its first call
    /// (shared by clones: the same mesh).
    surface: Arc<OnceLock<DistanceGrid>>,
    /// A convex mesh's face adjacency for [`Accel::exit_from`]'s walks.
    walk: Option<Arc<Walk>>,
}

/// Face adjacency of a closed convex mesh (every edge shared by exactly two
/// faces). Seen from a point inside, the faces project onto the unit sphere
/// of directions as a spherical triangulation; the face a ray leaves
/// through is the one whose projection holds the ray's direction, found by
/// walking across the edges the direction lies beyond (a visibility walk,
/// Devillers, Pion & Teillaud, "Walking in a triangulation", IJFCS 13, 2002).
#[derive(Debug)]
struct Walk {
    /// Per triangle (the order given to [`Accel::new`]): its vertices,
    /// counter-clockwise seen from outside.
    outward: Vec<[DVec3; 3]>,
    /// Per triangle: the triangle across the edge (v_k, v_k+1) of `outward`.
    next: Vec<[u32; 3]>,
    /// Per triangle: its index in the BVH's order.
    slot: Vec<u32>,
    /// A ball inside the mesh: its centre (the vertices' mean) and radius
    /// (a hair under the least distance from the centre to a face plane),
    /// so a segment that stays in the ball cannot cross the surface.
    centre: DVec3,
    radius: f64,
    /// The ball is nearly the mesh (its radius at least [`BALL_LIKE`] of the
    /// farthest vertex's distance from the centre): its depth then bounds
    /// the distance to the surface better than the grid does.
    ball_like: bool,
    /// Cells along each side of [`Walk::starts`]' cube of directions.
    cube: usize,
    /// Per cell of a cube of directions about `centre` (6 sides of `cube`²
    /// cells): the triangle the ray from the centre through the cell's
    /// middle leaves through, where [`Accel::exit`] starts its walk.
    starts: Vec<u32>,
}

/// How close to a ball a convex mesh is for its inscribed ball's depth to
/// serve as [`Accel::distance_lower_bound`] (the ratio of the inscribed
/// radius to the farthest vertex's distance from the centre).
const BALL_LIKE: f64 = 0.9;

/// Steps a walk takes before [`Accel::exit_from`] asks the BVH instead
/// (a walk from a face near the exit takes a few).
const WALK_STEPS: usize = 12;

impl Walk {
    /// The adjacency of `triangles` (convex, closed, no face of zero area),
    /// or None when an edge is not shared by exactly two faces in opposite
    /// directions.
    fn new(triangles: &[[DVec3; 3]], original: &[u32]) -> Option<Self> {
        let n = triangles.len();
        let count = (3 * n) as f64;
        let centre = triangles.iter().flatten().fold(DVec3::ZERO, |s, v| s + *v) / count;
        let mut outward = Vec::with_capacity(n);
        for &[a, b, c] in triangles {
            let normal = (b - a).cross(c - a);
            let side = normal.dot(a - centre);
            if side == 0.0 || side.is_nan() {
                return None;
            }
            outward.push(if side > 0.0 { [a, b, c] } else { [a, c, b] });
        }
        let key = |v: DVec3| v.to_array().map(f64::to_bits);
        let mut edges = std::collections::HashMap::with_capacity(3 * n);
        for (i, t) in outward.iter().enumerate() {
            for k in 0..3 {
                if edges.insert((key(t[k]), key(t[(k + 1) % 3])), i as u32).is_some() {
                    return None;
                }
            }
        }
        let mut next = Vec::with_capacity(n);
        for t in &outward {
            let mut across = [0u32; 3];
            for (k, a) in across.iter_mut().enumerate() {
                *a = *edges.get(&(key(t[(k + 1) % 3]), key(t[k])))?;
            }
            next.push(across);
        }
        let mut slot = vec![0u32; n];
        for (at, &i) in original.iter().enumerate() {
            slot[i as usize] = at as u32;
        }
        let radius = outward
            .iter()
            .map(|&[a, b, c]| (b - a).cross(c - a).normalize().dot(a - centre))
            .fold(f64::INFINITY, f64::min);
        if radius.is_nan() || radius <= 0.0 {
            return None;
        }
        // About 4 cells per face over the cube's 6 sides.
        let cube = (((2 * n) as f64 / 3.0).sqrt().ceil() as usize).clamp(2, 64);
        let far = triangles.iter().flatten().map(|v| v.distance(centre)).fold(0.0, f64::max);
        let radius = radius * (1.0 - 1e-9);
        let ball_like = radius >= BALL_LIKE * far;
        let mut walk = Self { outward, next, slot, centre, radius, ball_like, cube, starts: Vec::new() };
        // Each cell's face walked to from the cell before (a step or two);
        // the first from face 0 with as many steps as there are faces.
        let mut starts = Vec::with_capacity(6 * cube * cube);
        let mut at = 0u32;
        for side in 0..6 {
            for i in 0..cube {
                for j in 0..cube {
                    let dir = walk.cell_direction(side, i, j);
                    at = walk.find_in(centre, dir, at, n.max(WALK_STEPS))?;
                    starts.push(at);
                }
            }
        }
        walk.starts = starts;
        Some(walk)
    }

    /// The direction from the centre through the middle of cell (i, j) of
    /// the cube's side `side` (axis side / 2, towards + for even sides).
    fn cell_direction(&self, side: usize, i: usize, j: usize) -> DVec3 {
        let m = self.cube as f64;
        let (u, v) = (2.0 * (i as f64 + 0.5) / m - 1.0, 2.0 * (j as f64 + 0.5) / m - 1.0);
        let w = if side.is_multiple_of(2) { 1.0 } else { -1.0 };
        match side / 2 {
            0 => DVec3::new(w, u, v),
            1 => DVec3::new(u, w, v),
            _ => DVec3::new(u, v, w),
        }
    }

    /// The cube cell holding the direction of `p` from the centre.
    fn cell_of(&self, p: DVec3) -> usize {
        let a = p.abs();
        let (side, u, v, w) = if a.x >= a.y && a.x >= a.z {
            (usize::from(p.x < 0.0), p.y, p.z, a.x)
        } else if a.y >= a.z {
            (2 + usize::from(p.y < 0.0), p.x, p.z, a.y)
        } else {
            (4 + usize::from(p.z < 0.0), p.x, p.y, a.z)
        };
        let m = self.cube as f64;
        // NaN and w = 0 (p at the centre) land in cell 0 by the saturating cast.
        let cell = |x: f64| (((x / w + 1.0) * 0.5 * m) as usize).min(self.cube - 1);
        (side * self.cube + cell(u)) * self.cube + cell(v)
    }

    /// A face near where the ray from `origin` (inside) along `dir` leaves:
    /// the one the centre's ray through the point where the ray leaves the
    /// ball (or, where it misses the ball, the point of its closest
    /// approach to the centre) leaves through.
    #[inline]
    fn start(&self, origin: DVec3, dir: DVec3) -> u32 {
        let q = origin - self.centre;
        let (a, b, c) = Self::ball_quadratic(q, dir, self.radius);
        let disc = b * b - a * c;
        let t = if disc >= 0.0 { (disc.sqrt() - b) / a } else { -b / a };
        self.starts[self.cell_of(q + t.max(0.0) * dir)]
    }

    /// The distance along `dir` (in its lengths) that the ray from `origin`
    /// stays in the inscribed ball; 0 from a point outside it.
    #[inline]
    fn in_ball(&self, origin: DVec3, dir: DVec3) -> f64 {
        let (a, b, c) = Self::ball_quadratic(origin - self.centre, dir, self.radius);
        if c >= 0.0 {
            return 0.0;
        }
        // c < 0: the roots straddle 0, the far one is positive.
        ((b * b - a * c).sqrt() - b) / a
    }

    /// |q + t·dir|² = r² as a t² + 2b t + c = 0: (a, b, c) = (|dir|²,
    /// q·dir, |q|² − r²), q the ray's origin from the ball's centre.
    #[inline]
    fn ball_quadratic(q: DVec3, dir: DVec3, r: f64) -> (f64, f64, f64) {
        (dir.length_squared(), q.dot(dir), q.length_squared() - r * r)
    }

    /// The triangle the ray from `origin` (inside) along `dir` leaves
    /// through, walking from `start`; None after [`WALK_STEPS`] steps or
    /// where `origin` is not inside the face reached.
    #[inline]
    fn find(&self, origin: DVec3, dir: DVec3, start: u32) -> Option<u32> {
        self.find_in(origin, dir, start, WALK_STEPS)
    }

    /// [`Walk::find`] with at most `steps` steps.
    #[inline]
    fn find_in(&self, origin: DVec3, dir: DVec3, start: u32, steps: usize) -> Option<u32> {
        let mut f = start as usize;
        for _ in 0..steps {
            let [a, b, c] = self.outward[f];
            let (a, b, c) = (a - origin, b - origin, c - origin);
            // With dir = αa + βb + γc: these are γV, αV, βV, V = a·(b × c).
            let beyond = [a.cross(b).dot(dir), b.cross(c).dot(dir), c.cross(a).dot(dir)];
            let k = if beyond[0] <= beyond[1].min(beyond[2]) {
                0
            } else if beyond[1] <= beyond[2] {
                1
            } else {
                2
            };
            if beyond[k] >= 0.0 {
                return (a.dot(b.cross(c)) > 0.0).then_some(f as u32);
            }
            f = self.next[f][k] as usize;
        }
        None
    }
}

/// A grid over the mesh's bounding box that holds, per cell, a lower bound
/// of the distance from any point of the cell to the surface: surface
/// points are placed no farther apart than half a cell (a barycentric grid
/// on each triangle), the cells holding one are marked, and a cell k steps
/// (in the max norm, 26-neighbour breadth-first) from the nearest marked
/// cell is at least (k − 1) cells minus half a cell from the surface.
#[derive(Debug)]
struct DistanceGrid {
    lo: DVec3,
    cell: f64,
    dims: [usize; 3],
    /// Steps to the nearest marked cell (u16::MAX: none, an empty mesh).
    steps: Vec<u16>,
}

/// Cells along the bounding box's longest side.
const DISTANCE_GRID_CELLS: f64 = 64.0;

impl DistanceGrid {
    fn new(tris: &[[DVec3; 3]], lo: DVec3, hi: DVec3) -> Self {
        let cell = ((hi - lo).max_element() / DISTANCE_GRID_CELLS).max(f64::MIN_POSITIVE);
        let lo = lo - DVec3::splat(cell);
        let dims = ((hi - lo) / cell).to_array().map(|x| (x.ceil() as usize + 2).max(1));
        let index = |c: [usize; 3]| (c[2] * dims[1] + c[1]) * dims[0] + c[0];
        let cell_of = |x: DVec3| -> [usize; 3] {
            let f = ((x - lo) / cell).to_array();
            std::array::from_fn(|k| (f[k].max(0.0) as usize).min(dims[k] - 1))
        };
        let mut steps = vec![u16::MAX; dims[0] * dims[1] * dims[2]];
        let mut queue = std::collections::VecDeque::new();
        for &[a, b, c] in tris {
            let longest = (b - a).length().max((c - b).length()).max((a - c).length());
            let m = ((2.0 * longest / cell).ceil() as usize).max(1);
            for i in 0..=m {
                for j in 0..=m - i {
                    let (u, v) = (i as f64 / m as f64, j as f64 / m as f64);
                    let at = index(cell_of(a + u * (b - a) + v * (c - a)));
                    if steps[at] != 0 {
                        steps[at] = 0;
                        queue.push_back(at);
                    }
                }
            }
        }
        while let Some(at) = queue.pop_front() {
            let (x, y, z) = (at % dims[0], (at / dims[0]) % dims[1], at / (dims[0] * dims[1]));
            let next = steps[at].saturating_add(1);
            for dz in z.saturating_sub(1)..=(z + 1).min(dims[2] - 1) {
                for dy in y.saturating_sub(1)..=(y + 1).min(dims[1] - 1) {
                    for dx in x.saturating_sub(1)..=(x + 1).min(dims[0] - 1) {
                        let n = index([dx, dy, dz]);
                        if steps[n] > next {
                            steps[n] = next;
                            queue.push_back(n);
                        }
                    }
                }
            }
        }
        Self { lo, cell, dims, steps }
    }

    /// Steps from x's cell to the nearest marked cell (None outside the
    /// grid or for an empty mesh).
    fn steps(&self, x: DVec3) -> Option<u16> {
        let f = ((x - self.lo) / self.cell).to_array();
        if f.iter().zip(self.dims).any(|(&v, d)| !(v >= 0.0 && v < d as f64)) {
            return None;
        }
        let c = f.map(|v| v as usize);
        let k = self.steps[(c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]];
        (k != u16::MAX).then_some(k)
    }

    fn lower_bound(&self, x: DVec3) -> f64 {
        self.steps(x).map_or(0.0, |k| ((f64::from(k) - 1.5) * self.cell).max(0.0))
    }
}

/// Convex meshes with more distinct face planes than this are traced with
/// the BVH only.
pub const MAX_CONVEX_PLANES: usize = 64;

/// The distinct face planes of a closed convex mesh with outward winding,
/// or None if the mesh is not convex (some vertex outside a face plane by
/// more than 10⁻⁹ of the extent) or has too many planes.
fn convex_planes(triangles: &[[DVec3; 3]], extent: f64) -> Option<Vec<(DVec3, f64)>> {
    let tol = 1e-9 * extent;
    let mut planes: Vec<(DVec3, f64)> = Vec::new();
    for t in triangles {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        if n.length() == 0.0 {
            continue;
        }
        let n = n.normalize();
        let c = n.dot(t[0]);
        if !planes.iter().any(|(m, d)| (*m - n).length() < 1e-9 && (d - c).abs() < tol) {
            planes.push((n, c));
            if planes.len() > MAX_CONVEX_PLANES {
                return None;
            }
        }
    }
    let convex = triangles.iter().flatten().all(|v| planes.iter().all(|(n, c)| n.dot(*v) - c <= tol));
    (convex && planes.len() >= 4).then_some(planes)
}

/// Meshes with more triangles than this are not checked for convexity
/// (the check costs triangles × vertices).
pub const MAX_CONVEX_CHECK: usize = 4000;

/// True when every vertex lies on the inner side of every triangle's plane
/// (within 10⁻⁹ of the extent): a closed mesh with outward winding that is
/// convex. False beyond [`MAX_CONVEX_CHECK`] triangles.
fn convex_mesh(triangles: &[[DVec3; 3]], extent: f64) -> bool {
    if triangles.len() > MAX_CONVEX_CHECK || triangles.len() < 4 {
        return false;
    }
    let tol = 1e-9 * extent;
    triangles.iter().all(|t| {
        let n = (t[1] - t[0]).cross(t[2] - t[0]);
        if n.length() == 0.0 {
            return true;
        }
        let n = n.normalize();
        let c = n.dot(t[0]);
        triangles.iter().flatten().all(|v| n.dot(*v) - c <= tol)
    })
}

/// The f32 box of one triangle, inflated by `pad` on every side.
struct PaddedTriangle {
    min: Vec3A,
    max: Vec3A,
}

impl Boundable for PaddedTriangle {
    fn aabb(&self) -> Aabb {
        Aabb { min: self.min, max: self.max }
    }
}

fn to_f32_down(v: DVec3) -> Vec3A {
    Vec3A::new(down(v.x), down(v.y), down(v.z))
}
fn to_f32_up(v: DVec3) -> Vec3A {
    Vec3A::new(up(v.x), up(v.y), up(v.z))
}
fn down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x {
        f.next_down()
    } else {
        f
    }
}
fn up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x {
        f.next_up()
    } else {
        f
    }
}

impl Accel {
    /// Builds the BVH over `triangles` (vertices in f64). An empty list gives
    /// an accelerator that never hits.
    pub fn new(triangles: &[[DVec3; 3]]) -> Self {
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for t in triangles {
            for v in t {
                lo = lo.min(*v);
                hi = hi.max(*v);
            }
        }
        if triangles.is_empty() {
            return Self {
                bvh: CwBvh::default(),
                tris: Vec::new(),
                original: Vec::new(),
                bounds_min: DVec3::ZERO,
                bounds_max: DVec3::ZERO,
                scale: 1.0,
                planes: None,
                convex: false,
                surface: Arc::default(),
                walk: None,
            };
        }
        let extent = (hi - lo).max_element().max(lo.abs().max(hi.abs()).max_element());
        let extent = extent.max(f64::MIN_POSITIVE);
        let scale = 10.0 / extent;
        let pad = 1e-6 * extent;
        let boxes: Vec<PaddedTriangle> = triangles
            .iter()
            .map(|t| {
                let (mn, mx) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
                PaddedTriangle { min: to_f32_down((mn - pad) * scale), max: to_f32_up((mx + pad) * scale) }
            })
            .collect();
        let bvh = build_cwbvh(&boxes, BvhBuildParams::medium_build(), &mut Duration::default());
        let original = bvh.primitive_indices.clone();
        let tris = original.iter().map(|&i| triangles[i as usize]).collect();
        let planes = convex_planes(triangles, extent);
        let convex = planes.is_some() || convex_mesh(triangles, extent);
        let walk = (convex && planes.is_none()).then(|| Walk::new(triangles, &original).map(Arc::new)).flatten();
        Self {
            bvh,
            tris,
            original,
            bounds_min: lo,
            bounds_max: hi,
            scale,
            planes,
            convex,
            surface: Arc::default(),
            walk,
        }
    }

    /// A lower bound of the distance from `x` to the mesh's surface, in the
    /// vertices' units, from a grid of 64 cells along the bounding box's
    /// longest side built on the first call: within 1.5 cells of the surface
    /// it is 0, beyond it falls short of the true distance by at most
    /// ≈ 3.2 cells; 0 outside the box. One array read per call.
    ///
    /// For a convex mesh close to a ball (a sphere's facets) the depth in
    /// its inscribed ball, r − |x − centre|, where that is positive: no grid
    /// read, and short of the true distance by at most the facets' sag.
    pub fn distance_lower_bound(&self, x: DVec3) -> f64 {
        if let Some(w) = self.walk.as_deref().filter(|w| w.ball_like) {
            let depth = w.radius - x.distance(w.centre);
            if depth > 0.0 {
                return depth;
            }
        }
        self.distance_grid().lower_bound(x)
    }

    /// An estimate of the distance from `x` to the surface from the same
    /// grid: (k − ½) cells for a cell k steps from the surface's cells (in
    /// the max norm, so up to √3 short along a diagonal), 0 outside the
    /// box. Not a bound: for weights that need only be positive, such as a
    /// connection's attempt probability.
    pub fn distance_estimate(&self, x: DVec3) -> f64 {
        let grid = self.distance_grid();
        grid.steps(x).map_or(0.0, |k| ((f64::from(k) - 0.5) * grid.cell).max(0.0))
    }

    fn distance_grid(&self) -> &DistanceGrid {
        self.surface.get_or_init(|| DistanceGrid::new(&self.tris, self.bounds_min, self.bounds_max))
    }

    /// Number of triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }

    /// True when there are no triangles.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Bounding box of all vertices (min, max).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        (self.bounds_min, self.bounds_max)
    }

    /// The closest hit with 0 < t < `t_max` along `origin + t·dir`, if any.
    /// A convex mesh is intersected as the intersection of its face planes'
    /// half-spaces (entry = the last plane entered, exit = the first left),
    /// exact in f64 and without the BVH.
    pub fn intersect(&self, origin: DVec3, dir: DVec3, t_max: f64) -> Option<Hit> {
        if let Some(planes) = &self.planes {
            return convex_hit(planes, origin, dir, t_max);
        }
        if self.tris.is_empty() {
            return None;
        }
        let ray = self.bvh_ray(origin, dir, t_max);
        let scale = self.scale;
        let pre = Shear::new(dir);
        let mut best_t = t_max;
        let mut best = u32::MAX;
        let mut hit = RayHit::none();
        self.bvh.ray_traverse(ray, &mut hit, |_, id| {
            match pre.intersect(origin, &self.tris[id]) {
                Some(t) if t < best_t => {
                    best_t = t;
                    best = id as u32;
                    // Slightly beyond t, so f32 rounding never prunes a node
                    // holding an equally close hit.
                    ((t * scale + BEHIND) as f32) * (1.0 + 1e-6)
                }
                _ => f32::INFINITY,
            }
        });
        if best == u32::MAX {
            return None;
        }
        Some(self.hit(best as usize, best_t))
    }

    /// True when the mesh is convex (a ray leaving it never meets it again);
    /// [`exit`](Self::exit) uses its face planes when it also has few.
    pub fn is_convex(&self) -> bool {
        self.convex
    }

    /// The outward unit normals n and offsets c (n·x = c) of the face planes
    /// of a convex mesh; `None` when the mesh is not convex (or has more than
    /// [`MAX_CONVEX_PLANES`] planes).
    pub fn convex_planes(&self) -> Option<&[(DVec3, f64)]> {
        self.planes.as_deref()
    }

    /// The boundary hit of a ray that starts **inside** the closed mesh. For
    /// a convex mesh this is the nearest face plane the ray leaves through,
    /// t = min over planes with n·d > 0 of (c − n·o)/(n·d), exact in f64 and
    /// an order of magnitude cheaper than the BVH for a plaque box (the
    /// renderer calls it at every scattering event); otherwise the BVH hit.
    /// `triangle` is `u32::MAX` for a plane hit.
    ///
    /// On a convex mesh of many faces the hit is walked to across the edges
    /// from a face near it (found from the ray's exit from the inscribed
    /// ball; the BVH where the walk does not arrive): the BVH's hit, bit for
    /// bit, where the ray does not pass through an edge.
    #[inline]
    pub fn exit(&self, origin: DVec3, dir: DVec3) -> Option<Hit> {
        match self.walk.as_deref() {
            Some(w) => self.exit_from(origin, dir, w.start(origin, dir)),
            None => self.plane_or_bvh_exit(origin, dir),
        }
    }

    /// True when the segment from `origin` over `t` lengths of `dir`
    /// provably stays inside the mesh (it lies in the ball inscribed in a
    /// convex mesh of many faces): no exit closer than `t`. False says
    /// nothing.
    #[inline]
    pub fn stays_inside(&self, origin: DVec3, dir: DVec3, t: f64) -> bool {
        self.walk.as_deref().is_some_and(|w| t < w.in_ball(origin, dir))
    }

    /// [`exit`](Self::exit) by the face planes or the BVH.
    #[inline]
    fn plane_or_bvh_exit(&self, origin: DVec3, dir: DVec3) -> Option<Hit> {
        let Some(planes) = &self.planes else { return self.intersect(origin, dir, f64::INFINITY) };
        let mut best = (f64::INFINITY, DVec3::ZERO);
        for (n, c) in planes {
            let nd = n.dot(dir);
            if nd > 0.0 {
                let t = ((c - n.dot(origin)) / nd).max(0.0);
                if t < best.0 {
                    best = (t, *n);
                }
            }
        }
        (best.0 < f64::INFINITY).then_some(Hit { t: best.0, triangle: u32::MAX, normal: best.1 })
    }

    /// The same hit as [`exit`](Self::exit) for a ray from inside the closed
    /// mesh, found on a convex mesh of many faces by walking across the
    /// edges from triangle `near` (any triangle; one near the answer makes
    /// it a few steps) and measured by the same watertight test as the BVH's;
    /// the BVH answers where the walk does not arrive, on other meshes and
    /// for `near` = `u32::MAX`.
    #[inline]
    pub fn exit_from(&self, origin: DVec3, dir: DVec3, near: u32) -> Option<Hit> {
        let walked = self.walk.as_deref().filter(|_| (near as usize) < self.tris.len()).and_then(|w| {
            let slot = w.slot[w.find(origin, dir, near)? as usize] as usize;
            let t = Shear::new(dir).intersect(origin, &self.tris[slot])?;
            Some(self.hit(slot, t))
        });
        walked.or_else(|| self.plane_or_bvh_exit(origin, dir))
    }

    /// The hit at distance `t` on the triangle at `slot` (the BVH's order).
    #[inline]
    fn hit(&self, slot: usize, t: f64) -> Hit {
        let [a, b, c] = self.tris[slot];
        Hit { t, triangle: self.original[slot], normal: (b - a).cross(c - a).normalize() }
    }

    /// True when [`exit_from`](Self::exit_from) walks across faces (a
    /// closed convex mesh of more than [`MAX_CONVEX_PLANES`] planes).
    pub fn walks(&self) -> bool {
        self.walk.is_some()
    }

    /// True when some triangle lies at 0 < t < `t_max` along the ray.
    pub fn occluded(&self, origin: DVec3, dir: DVec3, t_max: f64) -> bool {
        if let Some(planes) = &self.planes {
            return convex_hit(planes, origin, dir, t_max).is_some();
        }
        if self.tris.is_empty() {
            return false;
        }
        let ray = self.bvh_ray(origin, dir, t_max);
        let pre = Shear::new(dir);
        !self.bvh.ray_traverse_miss(ray, |_, id| match pre.intersect(origin, &self.tris[id]) {
            Some(t) if t < t_max => 0.0,
            _ => f32::INFINITY,
        })
    }
}

/// The first boundary crossing of a ray with a convex polytope given by its
/// outward face planes n·x ≤ c, at 0 < t < t_max.
#[inline]
fn convex_hit(planes: &[(DVec3, f64)], o: DVec3, d: DVec3, t_max: f64) -> Option<Hit> {
    let (mut t_in, mut n_in) = (f64::NEG_INFINITY, DVec3::ZERO);
    let (mut t_out, mut n_out) = (f64::INFINITY, DVec3::ZERO);
    for (n, c) in planes {
        let nd = n.dot(d);
        let gap = c - n.dot(o);
        if nd < 0.0 {
            let t = gap / nd;
            if t > t_in {
                (t_in, n_in) = (t, *n);
            }
        } else if nd > 0.0 {
            let t = gap / nd;
            if t < t_out {
                (t_out, n_out) = (t, *n);
            }
        } else if gap < 0.0 {
            return None; // parallel to a face and outside it
        }
    }
    if t_in > t_out {
        return None;
    }
    let (t, normal) = if t_in > 0.0 { (t_in, n_in) } else { (t_out, n_out) };
    (t > 0.0 && t < t_max).then_some(Hit { t, triangle: u32::MAX, normal })
}

/// How far behind the true origin the BVH's ray starts, in BVH units (see
/// the module doc: 3 × obvhs' 10⁻⁴ entry clamp).
const BEHIND: f64 = 3e-4;

impl Accel {
    /// The f32 ray for the BVH: in BVH units, starting [`BEHIND`] behind the
    /// origin, −0.0 direction components made +0.0 (see the module doc),
    /// the range widened for rounding.
    #[inline]
    fn bvh_ray(&self, origin: DVec3, dir: DVec3, t_max: f64) -> Ray {
        let d = Vec3A::new(dir.x as f32 + 0.0, dir.y as f32 + 0.0, dir.z as f32 + 0.0);
        let o = origin * self.scale - BEHIND * dir;
        let tmax =
            if t_max.is_finite() { ((t_max * self.scale + BEHIND) as f32) * (1.0 + 1e-5) } else { f32::INFINITY };
        Ray::new(o.as_vec3a(), d, 0.0, tmax)
    }
}

/// Per-ray constants of the watertight test: the axis permutation that makes
/// the direction's largest component z, and the shear to +z.
struct Shear {
    kx: usize,
    ky: usize,
    kz: usize,
    sx: f64,
    sy: f64,
    sz: f64,
}

impl Shear {
    #[inline]
    fn new(d: DVec3) -> Self {
        let a = d.abs();
        let kz = if a.x > a.y {
            if a.x > a.z {
                0
            } else {
                2
            }
        } else if a.y > a.z {
            1
        } else {
            2
        };
        let mut kx = (kz + 1) % 3;
        let mut ky = (kx + 1) % 3;
        if d[kz] < 0.0 {
            std::mem::swap(&mut kx, &mut ky);
        }
        Self { kx, ky, kz, sx: d[kx] / d[kz], sy: d[ky] / d[kz], sz: 1.0 / d[kz] }
    }

    /// t > 0 of the hit with triangle `v`, or None.
    #[inline]
    fn intersect(&self, o: DVec3, v: &[DVec3; 3]) -> Option<f64> {
        let (a, b, c) = (v[0] - o, v[1] - o, v[2] - o);
        let (kx, ky, kz) = (self.kx, self.ky, self.kz);
        let ax = a[kx] - self.sx * a[kz];
        let ay = a[ky] - self.sy * a[kz];
        let bx = b[kx] - self.sx * b[kz];
        let by = b[ky] - self.sy * b[kz];
        let cx = c[kx] - self.sx * c[kz];
        let cy = c[ky] - self.sy * c[kz];
        let u = cx * by - cy * bx;
        let w_v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        if (u < 0.0 || w_v < 0.0 || w < 0.0) && (u > 0.0 || w_v > 0.0 || w > 0.0) {
            return None;
        }
        let det = u + w_v + w;
        if det == 0.0 {
            return None;
        }
        let t_scaled = u * self.sz * a[kz] + w_v * self.sz * b[kz] + w * self.sz * c[kz];
        let t = t_scaled / det;
        (t > 0.0 && t.is_finite()).then_some(t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Rng;

    /// Closed unit-ish box as 12 outward triangles.
    fn cube(lo: DVec3, hi: DVec3) -> Vec<[DVec3; 3]> {
        let c = |i: usize| {
            DVec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        };
        // Faces as quads (counter-clockwise seen from outside).
        let quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]];
        quads.iter().flat_map(|q| [[c(q[0]), c(q[1]), c(q[2])], [c(q[0]), c(q[2]), c(q[3])]]).collect()
    }

    #[test]
    fn negative_zero_direction() {
        // A large floor made of two triangles and a ray straight down whose
        // y component is −0.0: obvhs 0.4.0's CWBVH misses it without the fix.
        let mut tris = cube(DVec3::new(-1.0, -1.0, -1.0), DVec3::new(1.0, 1.0, 0.0));
        tris.extend(cube(DVec3::new(3.0, 3.0, 3.0), DVec3::new(4.0, 4.0, 4.0)));
        let accel = Accel::new(&tris);
        for d in [DVec3::new(0.0, -0.0, -1.0), DVec3::new(-0.0, -0.0, -1.0), DVec3::new(-0.0, 0.0, -1.0)] {
            let hit = accel.intersect(DVec3::new(0.25, 0.3, 1.0), d, f64::INFINITY);
            assert_eq!(hit.map(|h| h.t), Some(1.0), "direction {d:?}");
        }
    }

    #[test]
    fn inside_box_every_ray_exits_once_and_matches_slab_test() {
        // From random interior points, every direction meets the closed box
        // exactly at the analytic exit distance, and the normal points along
        // the ray (leaving). Watertight: no ray escapes through an edge.
        let (lo, hi) = (DVec3::new(-0.03, -0.02, 0.001), DVec3::new(0.03, 0.02, 0.00735));
        let accel = Accel::new(&cube(lo, hi));
        let mut rng = Rng::new(3, 0);
        for i in 0..200_000 {
            let u = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
            let mut o = lo + (hi - lo) * u;
            if i % 4 == 0 {
                // Exactly on an edge-parallel line through the centre, to aim at edges.
                o = (lo + hi) * 0.5;
            }
            let z = 2.0 * rng.next_f64() - 1.0;
            let phi = std::f64::consts::TAU * rng.next_f64();
            let s = (1.0 - z * z).sqrt();
            let mut d = DVec3::new(s * phi.cos(), s * phi.sin(), z);
            if i % 4 == 0 {
                // Directions straight at a box corner or edge midpoint.
                let corner = DVec3::new(
                    if i & 8 == 0 { lo.x } else { hi.x },
                    if i & 16 == 0 { lo.y } else { hi.y },
                    if i & 32 == 0 { lo.z } else { hi.z },
                );
                d = (corner - o).normalize();
            }
            let t_exit = {
                let inv = d.recip();
                let t1 = (lo - o) * inv;
                let t2 = (hi - o) * inv;
                t1.max(t2).min_element()
            };
            let hit =
                accel.intersect(o, d, f64::INFINITY).unwrap_or_else(|| panic!("ray {i} escaped: o {o:?} d {d:?}"));
            assert!((hit.t - t_exit).abs() <= 1e-12 * (1.0 + t_exit), "ray {i}: {} vs {t_exit}", hit.t);
            assert!(hit.normal.dot(d) >= 0.0);
            assert!(accel.occluded(o, d, f64::INFINITY));
            assert!(!accel.occluded(o, d, hit.t * (1.0 - 1e-9)));
        }
    }

    #[test]
    fn hits_closer_than_obvhs_epsilon() {
        // A ray 50 µm from a face of a plaque-sized box (in metres): obvhs'
        // node test alone would skip this hit (t < 10⁻⁴ scene units).
        let (lo, hi) = (DVec3::new(-0.03, -0.02, 0.001), DVec3::new(0.03, 0.02, 0.00735));
        let accel = Accel::new(&cube(lo, hi));
        let o = DVec3::new(-0.02994981919359711, -0.017209603535356176, 0.0019624176120455234);
        let d = DVec3::new(-0.6184902651986802, 0.77137204025358, 0.14984981604758674);
        let hit = accel.intersect(o, d, f64::INFINITY).expect("hit 81 µm away");
        assert!((hit.t - 8.113435122017591e-5).abs() < 1e-15);
        for gap in [1e-9, 1e-7, 1e-5] {
            let o = DVec3::new(lo.x + gap, 0.0, 0.004);
            assert!((accel.intersect(o, -DVec3::X, 1.0).unwrap().t - gap).abs() < 1e-15, "gap {gap}");
        }
    }

    #[test]
    fn convex_exit_equals_bvh_exit() {
        let (lo, hi) = (DVec3::new(-0.03, -0.02, 0.001), DVec3::new(0.03, 0.02, 0.00735));
        let accel = Accel::new(&cube(lo, hi));
        assert!(accel.is_convex());
        let mut rng = Rng::new(4, 0);
        for _ in 0..100_000 {
            let o = lo + (hi - lo) * DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64());
            let d = (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 2.0 - 1.0).normalize();
            let (a, b) = (accel.exit(o, d).unwrap(), accel.intersect(o, d, f64::INFINITY).unwrap());
            assert!((a.t - b.t).abs() <= 1e-12 * (1.0 + b.t), "{} vs {}", a.t, b.t);
            assert!((a.normal - b.normal).length() < 1e-12);
        }
        // From outside: the plane intersection equals a brute-force triangle scan.
        let tris = cube(lo, hi);
        for _ in 0..100_000 {
            let o = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 0.2 - 0.1;
            let d = (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 2.0 - 1.0).normalize();
            let pre = Shear::new(d);
            let brute = tris.iter().filter_map(|t| pre.intersect(o, t)).min_by(f64::total_cmp);
            let got = accel.intersect(o, d, f64::INFINITY).map(|h| h.t);
            match (got, brute) {
                (Some(a), Some(b)) => assert!((a - b).abs() <= 1e-12 * (1.0 + b), "{a} vs {b}"),
                (a, b) => assert_eq!(a, b, "o {o:?} d {d:?}"),
            }
            assert_eq!(accel.occluded(o, d, 0.05), brute.is_some_and(|t| t < 0.05));
        }
        // Not convex: an L-shaped pair of boxes sharing a face.
        let mut l = cube(DVec3::ZERO, DVec3::new(2.0, 1.0, 1.0));
        l.extend(cube(DVec3::new(0.0, 1.0, 0.0), DVec3::new(1.0, 2.0, 1.0)));
        assert!(!Accel::new(&l).is_convex());
    }

    #[test]
    fn misses_and_t_max() {
        let accel = Accel::new(&cube(DVec3::ZERO, DVec3::ONE));
        assert!(accel.intersect(DVec3::new(2.0, 2.0, 2.0), DVec3::new(1.0, 0.0, 0.0), f64::INFINITY).is_none());
        let o = DVec3::new(0.5, 0.5, -1.0);
        assert_eq!(accel.intersect(o, DVec3::Z, f64::INFINITY).map(|h| h.t), Some(1.0));
        assert!(accel.intersect(o, DVec3::Z, 0.999).is_none());
        assert_eq!(accel.intersect(o, DVec3::Z, f64::INFINITY).unwrap().normal, -DVec3::Z);
        assert!(Accel::new(&[]).intersect(o, DVec3::Z, 1e9).is_none());
    }

    #[test]
    fn many_triangles_agree_with_brute_force() {
        // A random triangle soup: BVH closest hits equal a linear scan.
        let mut rng = Rng::new(9, 1);
        let mut r = || rng.next_f64();
        let tris: Vec<[DVec3; 3]> = (0..3000)
            .map(|_| {
                let c = DVec3::new(r(), r(), r()) * 2.0 - 1.0;
                let e = |r: &mut dyn FnMut() -> f64| DVec3::new(r(), r(), r()) * 0.1 - 0.05;
                [c + e(&mut r), c + e(&mut r), c + e(&mut r)]
            })
            .collect();
        let accel = Accel::new(&tris);
        let mut rng = Rng::new(9, 2);
        let mut hits = 0;
        for _ in 0..3000 {
            let o = DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 3.0 - 1.5;
            let d = (DVec3::new(rng.next_f64(), rng.next_f64(), rng.next_f64()) * 2.0 - 1.0).normalize();
            let pre = Shear::new(d);
            let brute = tris
                .iter()
                .enumerate()
                .filter_map(|(i, t)| pre.intersect(o, t).map(|t| (t, i)))
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let got = accel.intersect(o, d, f64::INFINITY);
            assert_eq!(got.map(|h| (h.t, h.triangle as usize)), brute);
            hits += usize::from(brute.is_some());
        }
        assert!(hits > 300, "too few hits to test anything: {hits}");
    }
}
