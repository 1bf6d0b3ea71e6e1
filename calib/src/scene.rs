//! Board and sample poses for the renderer, and the one place where OpenCV's
//! camera convention becomes the renderer's.
//!
//! OpenCV (what calibration and PnP give): `x_cam = R · x_board + t`, metres;
//! camera axes x right, y down, z forward (into the scene); board frame with
//! the origin at inner corner (0, 0), x along corner index i (columns), y
//! along j (rows), z = x × y (into the board, away from the camera, for the
//! usual corner order).
//!
//! Renderer (what [`opencv_to_renderer`] returns and the scene JSON holds):
//! - world: right-handed, metres, origin at board corner (0, 0), the board in
//!   the plane z = 0, **z up** (towards the camera's side of the board),
//!   x along the board's i axis, y = z × x (so y = −j when z_board points
//!   away from the camera);
//! - camera: x right, **y up, looking along −z** (OpenGL / Blender);
//! - `camera_to_world` is a 4 × 4 row-major matrix acting on column vectors.
//!
//! Intrinsics stay in OpenCV's pixel convention (the centre of the top-left
//! pixel is (0, 0); v grows downwards); a renderer whose pixel centres are at
//! i + ½ adds ½ to cx and cy. The renderer images the *undistorted* photo,
//! so only fx, fy, cx, cy are needed.
//!
//! Board numbering, one convention for `lucent pose` and `lucent env orient`
//! ([`find_board_corners`]): inner corner (0, 0) is the one diagonally
//! beyond the **light** outer corner square — how OpenCV's sector-based
//! detector numbers a board, made sure of for either detector by
//! [`crate::env::canonical_corner_order`]. Only a board with one odd and one
//! even inner-corner count (9 × 6, 13 × 10) fixes it under a 180° turn; for
//! others the detector's order is kept and the commands warn. A scene draws
//! that board with its `even` squares (the outer square at corner (0, 0))
//! light.
//!
//! The sample: "its top-left corner lies on board corner (i, j), edges along
//! the board axes" — it spans i·s … i·s + width along the board's x and
//! j·s … j·s + height along the board's y, and 0 … thickness up.
//!
//! ```
//! use lucent_calib::scene::{opencv_to_renderer, project_renderer, Pose};
//! use lucent_calib::camera::Intrinsics;
//! // Camera 0.5 m above the board corner, looking straight down at it:
//! // the board's x and y (into the board: z) are the camera's x, y, z.
//! let pose = Pose::from_rvec_tvec([0.0; 3], [0.0, 0.0, 0.5]);
//! let frame = opencv_to_renderer(&pose);
//! assert_eq!(frame.camera_position(), [0.0, 0.0, 0.5]); // z up
//! let k = Intrinsics { fx: 1000.0, fy: 1000.0, cx: 320.0, cy: 240.0 };
//! // A board point 0.1 m along x and 0.05 m along the board's y (= world −y):
//! let px = project_renderer(&k, &frame.camera_to_world, [0.1, -0.05, 0.0]).unwrap();
//! assert!((px[0] - 520.0).abs() < 1e-9 && (px[1] - 340.0).abs() < 1e-9);
//! ```

use crate::model::Intrinsics;
use crate::pose::{mat_mul, mat_vec, transpose};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

// Kept at these paths for the root crate and the tests (`lucent_calib::scene::Pose`, …):
// boards and poses are leaf modules of their own, the detection is the driver's.
pub use crate::board::{BoardError, BoardSpec};
pub use crate::calibrate::find_board_corners;
pub use crate::pose::{rodrigues, rotation_vector, Mat3, Mat4, Pose};

/// The renderer's view of a board pose ([`opencv_to_renderer`]).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RendererFrame {
    /// Renderer camera (x right, y up, looking along −z) → world (z up), row-major.
    pub camera_to_world: Mat4,
    /// Board coordinates → world: diag(1, s, s) with s = −1 for the usual
    /// corner order (board z pointing away from the camera).
    pub world_from_board: Mat3,
}

impl RendererFrame {
    /// Board point → world.
    pub fn board_to_world(&self, p: [f64; 3]) -> [f64; 3] {
        mat_vec(&self.world_from_board, p)
    }

    /// The camera's centre in the world.
    pub fn camera_position(&self) -> [f64; 3] {
        std::array::from_fn(|r| self.camera_to_world[r][3])
    }
}

/// **The** OpenCV → renderer conversion (see the module docs); nothing else
/// in lucent converts camera conventions.
pub fn opencv_to_renderer(camera_from_board: &Pose) -> RendererFrame {
    let centre_b = camera_from_board.camera_centre_in_board();
    // World z points to the camera's side of the board.
    let s = if centre_b[2] > 0.0 { 1.0 } else { -1.0 };
    let w = [[1.0, 0.0, 0.0], [0.0, s, 0.0], [0.0, 0.0, s]];
    // OpenCV camera axes from renderer camera axes: flip y and z.
    let f = [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, -1.0]];
    let rot = mat_mul(&mat_mul(&w, &transpose(&camera_from_board.rotation)), &f);
    let pos = mat_vec(&w, centre_b);
    let mut m = [[0.0; 4]; 4];
    for r in 0..3 {
        m[r][..3].copy_from_slice(&rot[r]);
        m[r][3] = pos[r];
    }
    m[3][3] = 1.0;
    RendererFrame { camera_to_world: m, world_from_board: w }
}

/// Pixel of a world point seen by a renderer-convention pinhole camera
/// (x right, y up, looking along −z) with OpenCV-convention intrinsics;
/// `None` behind the camera. For checks of [`opencv_to_renderer`].
pub fn project_renderer(k: &Intrinsics, camera_to_world: &Mat4, p: [f64; 3]) -> Option<[f64; 2]> {
    let rot: Mat3 = std::array::from_fn(|r| std::array::from_fn(|c| camera_to_world[r][c]));
    let d: [f64; 3] = std::array::from_fn(|r| p[r] - camera_to_world[r][3]);
    let q = mat_vec(&transpose(&rot), d);
    let depth = -q[2];
    if depth.partial_cmp(&0.0) != Some(std::cmp::Ordering::Greater) {
        return None;
    }
    Some([k.cx + k.fx * q[0] / depth, k.cy - k.fy * q[1] / depth])
}

/// Where the sample sits on the board.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct SampleSpec {
    /// Board inner corner (i, j) under the sample's top-left corner.
    pub corner: [usize; 2],
    /// Width (along the board's i axis), height (along j), thickness, metres.
    pub size_m: [f64; 3],
}

/// The sample placed in the world.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SamplePlacement {
    pub corner_ij: [usize; 2],
    pub size_m: [f64; 3],
    /// Object frame (origin at the centre of the bottom face, axes along the
    /// world's x, y, z) → world, row-major 4 × 4.
    pub object_to_world: Mat4,
    /// The eight box corners in world coordinates (bottom face first).
    pub box_corners_world_m: Vec<[f64; 3]>,
}

/// Places the sample ([`SampleSpec`]) in the world of `frame`.
pub fn place_sample(board: &BoardSpec, sample: &SampleSpec, frame: &RendererFrame) -> SamplePlacement {
    let [i, j] = sample.corner;
    let [w, h, t] = sample.size_m;
    let p0 = board.corner(i, j);
    let at = |dx: f64, dy: f64, dz: f64| {
        let mut q = frame.board_to_world([p0[0] + dx, p0[1] + dy, 0.0]);
        q[2] += dz;
        q
    };
    let centre = at(w / 2.0, h / 2.0, 0.0);
    let mut m = [[0.0; 4]; 4];
    for r in 0..3 {
        m[r][r] = 1.0;
        m[r][3] = centre[r];
    }
    m[3][3] = 1.0;
    let mut corners = Vec::with_capacity(8);
    for dz in [0.0, t] {
        for (dx, dy) in [(0.0, 0.0), (w, 0.0), (w, h), (0.0, h)] {
            corners.push(at(dx, dy, dz));
        }
    }
    SamplePlacement {
        corner_ij: sample.corner,
        size_m: sample.size_m,
        object_to_world: m,
        box_corners_world_m: corners,
    }
}

/// `path` with `suffix` in place of its extension: `out/camera.json`,
/// `"_views"` → `out/camera_views` (stem `out` when `path` has none).
pub fn sibling(path: &Path, suffix: &str) -> PathBuf {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "out".into());
    path.with_file_name(format!("{stem}{suffix}"))
}

/// The files of `lucent pose`, each name spelled here once: the
/// [`SceneDescription`] (`json`, in a stage folder `scene.json`) and beside
/// it the view of the board's pose and the sample's outline (`view_png`,
/// `NAME_view.png`). Written by `lucent pose`, read by `lucent run`'s
/// planning and report.
///
/// ```
/// use lucent_calib::scene::PoseFiles;
/// let f = PoseFiles::in_dir(std::path::Path::new("out/pose"));
/// assert_eq!(f.view_png, std::path::Path::new("out/pose/scene_view.png"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PoseFiles {
    pub json: PathBuf,
    pub view_png: PathBuf,
}

impl PoseFiles {
    /// The scene file's name in a folder ([`PoseFiles::in_dir`]).
    pub const JSON: &'static str = "scene.json";

    /// The files beside the scene file `json`.
    pub fn of(json: &Path) -> Self {
        Self { json: json.to_path_buf(), view_png: sibling(json, "_view.png") }
    }

    /// The files of the pose written into the folder `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        Self::of(&dir.join(Self::JSON))
    }
}

/// The scene JSON: camera, board and sample in the renderer's convention.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneDescription {
    pub units: String,
    pub convention: String,
    pub image_width: usize,
    pub image_height: usize,
    /// Intrinsics of the undistorted photo (pixel-centre convention: see `convention`).
    pub intrinsics: Intrinsics,
    pub vertical_fov_deg: f64,
    pub camera_to_world: Mat4,
    pub camera_position_m: [f64; 3],
    pub board: BoardSpec,
    pub world_from_board: Mat3,
    pub sample: Option<SamplePlacement>,
    /// The OpenCV pose it came from (rvec radians, tvec metres) and its RMS.
    pub opencv_rvec: [f64; 3],
    pub opencv_tvec_m: [f64; 3],
    pub pose_rms_px: f64,
}

/// Human-readable statement of the conventions, stored in every scene JSON.
pub const CONVENTION: &str = "world: right-handed, metres, origin at board inner corner (0,0), board in z=0, z up towards the camera, x along board corner index i; camera: x right, y up, looks along -z (OpenGL/Blender); camera_to_world row-major acting on column vectors; intrinsics in OpenCV pixels (centre of the top-left pixel at (0,0), v down) for the undistorted image";

/// Builds the scene description from a PnP pose.
pub fn describe_scene(
    intrinsics: &Intrinsics,
    image_size: (usize, usize),
    pose: &Pose,
    board: &BoardSpec,
    sample: Option<&SampleSpec>,
    pose_rms_px: f64,
) -> SceneDescription {
    let frame = opencv_to_renderer(pose);
    SceneDescription {
        units: "metres, degrees, pixels".into(),
        convention: CONVENTION.into(),
        image_width: image_size.0,
        image_height: image_size.1,
        intrinsics: *intrinsics,
        vertical_fov_deg: 2.0 * (image_size.1 as f64 / 2.0 / intrinsics.fy).atan().to_degrees(),
        camera_to_world: frame.camera_to_world,
        camera_position_m: frame.camera_position(),
        board: *board,
        world_from_board: frame.world_from_board,
        sample: sample.map(|s| place_sample(board, s, &frame)),
        opencv_rvec: pose.rvec(),
        opencv_tvec_m: pose.translation_m,
        pose_rms_px,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn opencv_pinhole(k: &Intrinsics, p: [f64; 3]) -> [f64; 2] {
        [k.fx * p[0] / p[2] + k.cx, k.fy * p[1] / p[2] + k.cy]
    }

    #[test]
    fn renderer_camera_sees_what_opencv_sees() {
        let k = Intrinsics { fx: 1510.0, fy: 1490.0, cx: 2010.5, cy: 1480.25 };
        let board = BoardSpec { cols: 9, rows: 6, square_m: 0.02 };
        // Oblique views from both sides of the board's own z (the detector's
        // corner order decides which side the camera is on).
        for (rvec, tvec) in [([0.4, -0.3, 0.2], [-0.05, -0.03, 0.45]), ([2.9, 0.3, -0.1], [-0.08, 0.04, 0.6])] {
            let pose = Pose::from_rvec_tvec(rvec, tvec);
            let frame = opencv_to_renderer(&pose);
            assert!(frame.camera_position()[2] > 0.0, "camera above the board in world z");
            for p in board.corners().into_iter().chain([[0.05, 0.03, -0.004], [0.1, 0.0, 0.01]]) {
                let cv = opencv_pinhole(&k, pose.to_camera(p));
                let gl = project_renderer(&k, &frame.camera_to_world, frame.board_to_world(p)).unwrap();
                assert!((cv[0] - gl[0]).abs() < 1e-8 && (cv[1] - gl[1]).abs() < 1e-8, "{p:?}: {cv:?} vs {gl:?}");
            }
            // camera_to_world is a rotation (orthonormal, det +1) and a translation.
            let r: Mat3 = std::array::from_fn(|a| std::array::from_fn(|b| frame.camera_to_world[a][b]));
            let det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
                - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
                + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
            assert!((det - 1.0).abs() < 1e-12);
        }
    }

    #[test]
    fn sample_sits_on_its_corner_with_the_board_axes() {
        let board = BoardSpec { cols: 9, rows: 6, square_m: 0.02 };
        let pose = Pose::from_rvec_tvec([0.1, 0.2, 0.0], [0.0, 0.0, 0.5]);
        let frame = opencv_to_renderer(&pose);
        let s = place_sample(&board, &SampleSpec { corner: [2, 1], size_m: [0.1491, 0.1045, 0.00635] }, &frame);
        // Bottom top-left = corner (2, 1) = (0.04, 0.02) on the board → world (0.04, −0.02, 0).
        let c0 = s.box_corners_world_m[0];
        assert!((c0[0] - 0.04).abs() < 1e-12 && (c0[1] + 0.02).abs() < 1e-12 && c0[2] == 0.0, "{c0:?}");
        let c2 = s.box_corners_world_m[2];
        assert!((c2[0] - 0.1891).abs() < 1e-12 && (c2[1] + 0.1245).abs() < 1e-12);
        assert!((s.box_corners_world_m[4][2] - 0.00635).abs() < 1e-15);
        assert!((s.object_to_world[0][3] - (0.04 + 0.1491 / 2.0)).abs() < 1e-12);
        let scene = describe_scene(
            &Intrinsics { fx: 800.0, fy: 800.0, cx: 320.0, cy: 240.0 },
            (640, 480),
            &pose,
            &board,
            None,
            0.1,
        );
        assert!((scene.vertical_fov_deg - 2.0 * (0.3f64).atan().to_degrees()).abs() < 1e-12);
    }
}
