//! Which pixels a comparison uses: a mask image, or the sample or the board
//! projected from the scene JSON of `lucent pose` into the (undistorted)
//! image.
//!
//! * Mask image (`--mask M.png`): same size as the photo; a pixel is
//!   included where any colour channel is nonzero (alpha is ignored).
//! * Object (`--mask-object scene.json`): the silhouette of the sample's box
//!   — the convex hull of its eight corners (`sample.box_corners_world_m`)
//!   projected with the scene's pinhole camera
//!   (`lucent_calib::scene::project_renderer`). A box is convex, so the hull
//!   is its exact outline.
//! * Board (`--mask-board scene.json`): the printed squares — the
//!   quadrilateral one square beyond the outer inner corners, i.e. board
//!   coordinates `[−s, cols·s] × [−s, rows·s]` (any white margin is not
//!   included) — minus the object's silhouette.
//!
//! Pixel `(i, j)` has its centre at `(i, j)` (OpenCV's convention, that of
//! the scene's intrinsics) and is inside a polygon when its centre is
//! (even–odd rule, half-open spans, so adjacent polygons share no pixel).
//!
//! ```
//! use lucent::compare::mask::polygon_mask;
//! // A 4 × 3 rectangle of pixel centres: x 1..=4, y 1..=3 in a 6 × 5 image.
//! let m = polygon_mask(&[[0.5, 0.5], [4.5, 0.5], [4.5, 3.5], [0.5, 3.5]], 6, 5);
//! assert_eq!(m.count(), 12);
//! assert!(m.get(1, 1) && m.get(4, 3) && !m.get(0, 0) && !m.get(5, 4));
//! ```

use super::error::{CompareError, ReadProblem};
use lucent_calib::scene::{project_renderer, SceneDescription};
use std::path::Path;

/// Included pixels of a `width × height` image, row-major.
#[derive(Debug, Clone, PartialEq)]
pub struct Mask {
    pub width: usize,
    pub height: usize,
    pub include: Vec<bool>,
}

impl Mask {
    /// Every pixel included.
    pub fn all(width: usize, height: usize) -> Self {
        Self { width, height, include: vec![true; width * height] }
    }

    /// Whether pixel (x, y) is included.
    pub fn get(&self, x: usize, y: usize) -> bool {
        self.include[y * self.width + x]
    }

    /// Number of included pixels.
    pub fn count(&self) -> usize {
        self.include.iter().filter(|&&v| v).count()
    }

    /// The object's interior in a render: pixels whose object fraction
    /// (render.exr's `object` layer: the share of camera rays that hit the
    /// object first) exceeds `min_fraction` and all of whose neighbours
    /// within `erode_px` pixels (a (2·erode_px + 1)² square) do too, so
    /// that the silhouette's edge, where sub-pixel position changes the
    /// value, is left out. The region where an estimator's bias on the
    /// object is measured (docs/method.md#render-similarity).
    pub fn interior(object: &[f32], width: usize, height: usize, min_fraction: f64, erode_px: usize) -> Self {
        let inside = |x: usize, y: usize| f64::from(object[y * width + x]) > min_fraction;
        let include = (0..width * height)
            .map(|i| {
                let (x, y) = (i % width, i / width);
                x >= erode_px
                    && y >= erode_px
                    && x + erode_px < width
                    && y + erode_px < height
                    && (y - erode_px..=y + erode_px).all(|v| (x - erode_px..=x + erode_px).all(|u| inside(u, v)))
            })
            .collect();
        Self { width, height, include }
    }

    /// The mean over the included pixels of `values` and its standard
    /// error from the pixels' own variances of the mean (`variances`, same
    /// layout): √(Σ var) / n, the pixels' estimates being independent.
    /// `None` without included pixels.
    pub fn mean_with_error(&self, values: &[f32], variances: &[f32]) -> Option<(f64, f64)> {
        let (mut sum, mut var, mut n) = (0.0, 0.0, 0usize);
        for ((v, s), _) in values.iter().zip(variances).zip(&self.include).filter(|(_, inc)| **inc) {
            sum += f64::from(*v);
            var += f64::from(*s);
            n += 1;
        }
        (n > 0).then(|| (sum / n as f64, var.sqrt() / n as f64))
    }

    /// Included fraction of the image.
    pub fn fraction(&self) -> f64 {
        self.count() as f64 / self.include.len().max(1) as f64
    }

    /// Pixels included in both (same size required).
    pub fn and(&self, other: &Mask) -> Result<Mask, CompareError> {
        if (self.width, self.height) != (other.width, other.height) {
            return Err(CompareError::Size {
                first: "one mask".into(),
                first_size: (self.width, self.height),
                second: "the other".into(),
                second_size: (other.width, other.height),
            });
        }
        let include = self.include.iter().zip(&other.include).map(|(a, b)| *a && *b).collect();
        Ok(Mask { width: self.width, height: self.height, include })
    }

    /// 1 for included, 0 for excluded (for OpenCV masks and EXR channels).
    pub fn to_u8(&self) -> Vec<u8> {
        self.include.iter().map(|&v| u8::from(v)).collect()
    }

    /// Reads a mask image (PNG, TIFF; any bit depth) that must be
    /// `width × height`; nonzero colour = included.
    pub fn from_image(path: &Path, width: usize, height: usize) -> Result<Mask, CompareError> {
        let err = |reason: ReadProblem| CompareError::Read { role: "mask", path: path.to_path_buf(), reason };
        if !path.is_file() {
            return Err(err(ReadProblem::Missing));
        }
        let img = image::ImageReader::open(path)
            .map_err(|e| err(e.into()))?
            .with_guessed_format()
            .map_err(|e| err(e.into()))?
            .decode()
            .map_err(|e| err(e.into()))?;
        let (w, h) = (img.width() as usize, img.height() as usize);
        if (w, h) != (width, height) {
            return Err(CompareError::Size {
                first: format!("mask {}", path.display()),
                first_size: (w, h),
                second: "the photo and render".into(),
                second_size: (width, height),
            });
        }
        let rgb = img.into_rgb16();
        let include = rgb.pixels().map(|p| p.0.iter().any(|&v| v != 0)).collect();
        Ok(Mask { width, height, include })
    }
}

/// Pixels whose centres lie inside `polygon` (pixel coordinates).
pub fn polygon_mask(polygon: &[[f64; 2]], width: usize, height: usize) -> Mask {
    let mut include = vec![false; width * height];
    let n = polygon.len();
    let mut xs = Vec::new();
    for y in 0..height {
        let yc = y as f64;
        xs.clear();
        for k in 0..n {
            let (p, q) = (polygon[k], polygon[(k + 1) % n]);
            if (p[1] <= yc) != (q[1] <= yc) {
                xs.push(p[0] + (yc - p[1]) * (q[0] - p[0]) / (q[1] - p[1]));
            }
        }
        xs.sort_by(f64::total_cmp);
        for span in xs.chunks_exact(2) {
            // Centres x with span[0] <= x < span[1].
            let first = span[0].ceil().max(0.0);
            let end = span[1].ceil().min(width as f64);
            if first < end {
                for x in first as usize..end as usize {
                    include[y * width + x] = true;
                }
            }
        }
    }
    Mask { width, height, include }
}

/// Convex hull (Andrew's monotone chain), counter-clockwise in a y-up frame.
fn convex_hull(points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut p = points.to_vec();
    p.sort_by(|a, b| a[0].total_cmp(&b[0]).then(a[1].total_cmp(&b[1])));
    p.dedup();
    if p.len() < 3 {
        return p;
    }
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0]);
    let mut hull: Vec<[f64; 2]> = Vec::with_capacity(2 * p.len());
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &[f64; 2]>> =
            if pass == 0 { Box::new(p.iter()) } else { Box::new(p.iter().rev()) };
        for &q in iter {
            while hull.len() >= start + 2 && cross(hull[hull.len() - 2], hull[hull.len() - 1], q) <= 0.0 {
                hull.pop();
            }
            hull.push(q);
        }
        hull.pop();
    }
    hull
}

/// Reads a scene JSON written by `lucent pose`.
pub fn read_scene(path: &Path) -> Result<SceneDescription, CompareError> {
    let err = |reason: ReadProblem| CompareError::Read { role: "scene", path: path.to_path_buf(), reason };
    let text = crate::io::read_text(path).map_err(|e| err(e.into()))?;
    serde_json::from_str(&text).map_err(|e| err(e.into()))
}

fn project(scene: &SceneDescription, p: [f64; 3], what: &'static str) -> Result<[f64; 2], CompareError> {
    project_renderer(&scene.intrinsics, &scene.camera_to_world, p)
        .filter(|q| q[0].is_finite() && q[1].is_finite())
        .ok_or(CompareError::BehindCamera { what, point: p })
}

fn check_size(scene: &SceneDescription, width: usize, height: usize) -> Result<(), CompareError> {
    if (scene.image_width, scene.image_height) != (width, height) {
        return Err(CompareError::Size {
            first: "the scene's image".into(),
            first_size: (scene.image_width, scene.image_height),
            second: "the photo and render".into(),
            second_size: (width, height),
        });
    }
    Ok(())
}

/// The sample's silhouette in the image (convex polygon, pixels).
pub fn object_outline(scene: &SceneDescription) -> Result<Vec<[f64; 2]>, CompareError> {
    let sample = scene.sample.as_ref().ok_or(CompareError::NoSample)?;
    let pts = sample
        .box_corners_world_m
        .iter()
        .map(|&p| project(scene, p, "sample corner"))
        .collect::<Result<Vec<_>, _>>()?;
    Ok(convex_hull(&pts))
}

/// The board's printed squares in the image (quadrilateral, pixels).
pub fn board_outline(scene: &SceneDescription) -> Result<Vec<[f64; 2]>, CompareError> {
    let s = scene.board.square_m;
    let (c, r) = (scene.board.cols as f64, scene.board.rows as f64);
    let m = &scene.world_from_board;
    [[-s, -s], [c * s, -s], [c * s, r * s], [-s, r * s]]
        .iter()
        .map(|&[x, y]| {
            let world = [m[0][0] * x + m[0][1] * y, m[1][0] * x + m[1][1] * y, m[2][0] * x + m[2][1] * y];
            project(scene, world, "board corner")
        })
        .collect()
}

/// The sample's pixels.
pub fn object_mask(scene: &SceneDescription, width: usize, height: usize) -> Result<Mask, CompareError> {
    check_size(scene, width, height)?;
    Ok(polygon_mask(&object_outline(scene)?, width, height))
}

/// The board's pixels not covered by the sample (all the board's if the
/// scene has no sample).
pub fn board_mask(scene: &SceneDescription, width: usize, height: usize) -> Result<Mask, CompareError> {
    check_size(scene, width, height)?;
    let mut board = polygon_mask(&board_outline(scene)?, width, height);
    if scene.sample.is_some() {
        let object = polygon_mask(&object_outline(scene)?, width, height);
        for (b, o) in board.include.iter_mut().zip(&object.include) {
            *b = *b && !o;
        }
    }
    Ok(board)
}

#[cfg(test)]
mod tests {
    use super::*;
    use lucent_calib::camera::Intrinsics;
    use lucent_calib::scene::{describe_scene, BoardSpec, Pose, SampleSpec};

    #[test]
    fn the_interior_leaves_out_the_edge_and_its_mean_carries_the_pixels_errors() {
        // A 7 × 6 object (fraction 1) in a 11 × 10 image, one edge pixel at 0.5.
        let (w, h) = (11, 10);
        let mut object = vec![0.0f32; w * h];
        for y in 2..8 {
            for x in 2..9 {
                object[y * w + x] = 1.0;
            }
        }
        object[2 * w + 2] = 0.5;
        assert_eq!(Mask::interior(&object, w, h, 0.99, 0).count(), 41);
        // Eroded by 1 px: x 3..=7, y 3..=6 (20), less the corner's neighbour (3, 3).
        let m = Mask::interior(&object, w, h, 0.99, 1);
        assert_eq!(m.count(), 19);
        assert!(!m.get(3, 3) && m.get(4, 3) && m.get(7, 6) && !m.get(8, 6));
        assert_eq!(Mask::interior(&object, w, h, 0.99, 3).count(), 0);
        // Values 2 with variance 0.04 each: mean 2, error √(19 · 0.04) / 19.
        let (v, var) = (vec![2.0f32; w * h], vec![0.04f32; w * h]);
        let (mean, se) = m.mean_with_error(&v, &var).unwrap();
        assert!((mean - 2.0).abs() < 1e-12 && (se - (19.0f64 * 0.04).sqrt() / 19.0).abs() < 1e-7, "{mean} {se}");
        assert_eq!(Mask::interior(&object, w, h, 0.99, 3).mean_with_error(&v, &var), None);
    }

    #[test]
    fn adjacent_polygons_share_no_pixel_and_cover_their_union() {
        let a = polygon_mask(&[[-0.5, -0.5], [3.3, -0.5], [3.3, 4.5], [-0.5, 4.5]], 8, 5);
        let b = polygon_mask(&[[3.3, -0.5], [7.5, -0.5], [7.5, 4.5], [3.3, 4.5]], 8, 5);
        assert!(a.include.iter().zip(&b.include).all(|(x, y)| !(x & y)));
        assert_eq!(a.count() + b.count(), 40);
        assert_eq!(a.count(), 4 * 5);
    }

    #[test]
    fn hull_of_a_box_drops_inner_points() {
        let h = convex_hull(&[[0.0, 0.0], [2.0, 0.0], [2.0, 2.0], [0.0, 2.0], [1.0, 1.0], [1.0, 0.5]]);
        assert_eq!(h.len(), 4);
    }

    #[test]
    fn board_and_object_masks_from_a_scene() {
        // Camera 0.5 m above the board, looking straight down (fx = 1000 px).
        let board = BoardSpec { cols: 9, rows: 6, square_m: 0.02 };
        let pose = Pose::from_rvec_tvec([0.0; 3], [-0.08, -0.05, 0.5]);
        // Centres at x.5 put every edge half-way between pixel centres.
        let k = Intrinsics { fx: 1000.0, fy: 1000.0, cx: 320.5, cy: 240.5 };
        let sample = SampleSpec { corner: [2, 1], size_m: [0.06, 0.04, 0.0] };
        let scene = describe_scene(&k, (640, 480), &pose, &board, Some(&sample), 0.1);
        // Board: x from −0.02 to 0.18 m → pixels 320.5 + 2000·(x − 0.08) = 120.5 … 520.5.
        let outline = board_outline(&scene).unwrap();
        let xs: Vec<f64> = outline.iter().map(|p| p[0]).collect();
        assert!(
            xs.iter().any(|x| (x - 120.5).abs() < 1e-9) && xs.iter().any(|x| (x - 520.5).abs() < 1e-9),
            "{outline:?}"
        );
        let object = object_mask(&scene, 640, 480).unwrap();
        // Sample 0.06 × 0.04 m → 120 × 80 pixel centres.
        assert_eq!(object.count(), 120 * 80);
        let boardm = board_mask(&scene, 640, 480).unwrap();
        assert_eq!(boardm.count(), 400 * 280 - 120 * 80);
        assert!(object.and(&boardm).unwrap().count() == 0);
        let e = object_mask(&scene, 64, 48).unwrap_err().to_string();
        assert!(e.contains("640 × 480"), "{e}");
        let bare = describe_scene(&k, (640, 480), &pose, &board, None, 0.1);
        assert!(object_mask(&bare, 640, 480).unwrap_err().to_string().contains("no sample"));
        assert_eq!(board_mask(&bare, 640, 480).unwrap().count(), 400 * 280);
    }
}
