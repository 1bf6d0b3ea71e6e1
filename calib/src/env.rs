//! Equirectangular HDR environment maps (the 360° camera's output): the
//! 2:1 check, a 3 × 3 colour matrix (camera RGB → the shared CIE RGB space,
//! from the colour stage), a summary of the radiance values, and perspective
//! views cut from the map ([`perspective_view`], `lucent env view`) so a
//! chart photographed by the 360° camera can be found and measured.
//!
//! Map convention (the renderer's, `lucent-render`'s env module): pixel
//! (x, y) covers u ∈ [x/W, (x+1)/W), v ∈ [y/H, (y+1)/H); the direction is
//! (sin θ cos φ, sin θ sin φ, cos θ) with θ = πv from +z (up) and φ = −2πu,
//! so u = 0 looks along +x. A view is a pinhole camera at the centre with
//! its axis at azimuth `yaw` (counter-clockwise from +x seen from above, the
//! renderer's sense of yaw) and elevation `pitch`; each view pixel takes the
//! map's bilinear interpolation at its centre's direction (wrapping in u,
//! clamped at the poles' first and last rows).
//!
//! Orientation ([`rotate_yaw`], [`board_in_map`], `lucent env orient`): the
//! map is turned about +z so that world = R_z(yaw) · map puts the board's i
//! axis on world +x (the board found in a view by OpenCV, its pose from PnP
//! with the view's pinhole camera, yaw = −azimuth of the i axis; corner
//! (0, 0) fixed by the light outer square, [`canonical_corner_order`], the
//! numbering `lucent pose` uses too); the
//! [`Orientation`] file gives a scene its yaw. [`lens_to_equirect`] maps a
//! calibrated lens's photo onto a latitude–longitude map around its axis
//! (Kannala–Brandt by the angle off the axis, so beyond 90°);
//! [`paste_view`] is the inverse of [`perspective_view`], for synthetic
//! panoramas.
//!
//! Values are linear relative radiance, unchanged in scale. The matrix acts
//! on column vectors: `out = M · [r, g, b]ᵀ`; negative results (colours
//! outside the target gamut) are kept, not clipped.
//!
//! ```
//! use lucent_calib::env::{apply_matrix, check_equirectangular};
//! use lucent_calib::RgbBuffer;
//! assert!(check_equirectangular(1024, 512).is_ok());
//! assert!(check_equirectangular(1000, 512).is_err());
//! let mut img = RgbBuffer::new(2, 1, vec![1.0, 2.0, 3.0, 0.0, 0.0, 1.0]).unwrap();
//! // Swap red and blue, halve green.
//! apply_matrix(&mut img, &[[0.0, 0.0, 1.0], [0.0, 0.5, 0.0], [1.0, 0.0, 0.0]]);
//! assert_eq!(img.pixel(0, 0), [3.0, 1.0, 1.0]);
//! // Looking along +x (yaw 0) sees the map's column u = 0.
//! let cam = lucent_calib::env::ViewSpec { yaw_deg: 0.0, pitch_deg: 0.0, fov_deg: 90.0, width: 3, height: 3 }
//!     .camera()
//!     .unwrap();
//! assert_eq!(lucent_calib::env::direction_to_uv(cam.direction(1.5, 1.5)), (0.0, 0.5));
//! ```

use crate::buffer::RgbBuffer;
use crate::model::{CameraModel, DistortionModel};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

/// What is wrong with an environment map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EnvError {
    #[error("{width} × {height} pixels is not an equirectangular map: the width must be exactly twice the height (2:1, e.g. 2048 × 1024)")]
    NotEquirectangular { width: usize, height: usize },
    #[error("{count} pixel values are NaN or infinite (first at x = {x}, y = {y})")]
    NonFinite { count: usize, x: usize, y: usize },
    #[error("colour matrix: {reason}; give 9 numbers row-major, a JSON [[..],[..],[..]] or {{\"matrix\": [[..],..]}}")]
    MatrixSyntax { reason: &'static str },
    #[error("colour matrix: {text:?} is not a number; give 9 numbers row-major, a JSON [[..],[..],[..]] or {{\"matrix\": [[..],..]}}")]
    MatrixNumber { text: String },
    #[error("colour matrix: found {count} numbers; give 9 numbers row-major, a JSON [[..],[..],[..]] or {{\"matrix\": [[..],..]}}")]
    MatrixCount { count: usize },
    #[error("view: yaw {yaw_deg}° must be finite")]
    Yaw { yaw_deg: f64 },
    #[error("view: pitch {pitch_deg}° must be within [−90°, 90°]")]
    Pitch { pitch_deg: f64 },
    #[error("view: field of view {fov_deg}° must be within (0°, 180°)")]
    FieldOfView { fov_deg: f64 },
    #[error("view: size {width} × {height} must be 1 to 16384 pixels each way")]
    ViewSize { width: usize, height: usize },
    /// A photo whose size is not the one its camera was calibrated at.
    #[error(
        "view: image is {width} × {height} pixels but the camera was calibrated at {camera_width} × {camera_height}"
    )]
    PhotoSize { width: usize, height: usize, camera_width: usize, camera_height: usize },
    #[error("view: map width {width} must be even, 2 to 32768 pixels")]
    MapWidth { width: usize },
    /// A picture to paste whose size is not the view's.
    #[error("view: picture of {width} × {height} pixels for a view of {view_width} × {view_height}")]
    PictureSize { width: usize, height: usize, view_width: usize, view_height: usize },
    /// An orientation file used with a map it was not made for.
    #[error("orientation: it is for {source_map} (yaw {source_yaw_deg}°) or its turned copy {output_map} (yaw {output_yaw_deg}°), not for {map}")]
    OtherMap { source_map: String, source_yaw_deg: f64, output_map: String, output_yaw_deg: f64, map: String },
}

/// Checks the 2:1 aspect ratio of an equirectangular map.
pub fn check_equirectangular(width: usize, height: usize) -> Result<(), EnvError> {
    if height == 0 || width != 2 * height {
        return Err(EnvError::NotEquirectangular { width, height });
    }
    Ok(())
}

/// Checks that every value is finite.
pub fn check_finite(img: &RgbBuffer) -> Result<(), EnvError> {
    let mut bad = img.data.iter().enumerate().filter(|(_, v)| !v.is_finite());
    if let Some((i, _)) = bad.next() {
        let count = 1 + bad.count();
        let p = i / 3;
        return Err(EnvError::NonFinite { count, x: p % img.width.max(1), y: p / img.width.max(1) });
    }
    Ok(())
}

/// Applies `m` to every pixel (column vectors, f64 arithmetic).
pub fn apply_matrix(img: &mut RgbBuffer, m: &[[f64; 3]; 3]) {
    for px in img.data.chunks_exact_mut(3) {
        let v = [f64::from(px[0]), f64::from(px[1]), f64::from(px[2])];
        for (r, out) in px.iter_mut().enumerate() {
            *out = (m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2]) as f32;
        }
    }
}

/// A 3 × 3 matrix from text: a JSON array of three rows, a JSON object with
/// a `"matrix"` key holding one, or nine numbers separated by commas,
/// semicolons or spaces (row-major).
pub fn parse_matrix(text: &str) -> Result<[[f64; 3]; 3], EnvError> {
    let bad = |reason| EnvError::MatrixSyntax { reason };
    // Numbers in order of appearance; a JSON object's other keys must not hold numbers.
    let t = text.trim();
    let body = if t.starts_with('{') {
        let key = t.find("\"matrix\"").ok_or_else(|| bad("no \"matrix\" key"))?;
        let start = t[key..].find('[').map(|s| key + s).ok_or_else(|| bad("no array after \"matrix\""))?;
        let mut depth = 0;
        let mut end = None;
        for (k, ch) in t[start..].char_indices() {
            match ch {
                '[' => depth += 1,
                ']' => {
                    depth -= 1;
                    if depth == 0 {
                        end = Some(start + k + 1);
                        break;
                    }
                }
                _ => {}
            }
        }
        &t[start..end.ok_or_else(|| bad("unbalanced brackets"))?]
    } else {
        t
    };
    let nums: Vec<f64> = body
        .split(|c: char| c == ',' || c == ';' || c == '[' || c == ']' || c.is_whitespace())
        .filter(|s| !s.is_empty())
        .map(|s| s.parse::<f64>().map_err(|_| EnvError::MatrixNumber { text: s.to_string() }))
        .collect::<Result<_, _>>()?;
    if nums.len() != 9 {
        return Err(EnvError::MatrixCount { count: nums.len() });
    }
    if nums.iter().any(|v| !v.is_finite()) {
        return Err(bad("values must be finite"));
    }
    Ok(std::array::from_fn(|r| std::array::from_fn(|c| nums[3 * r + c])))
}

/// Per-channel statistics of an environment map.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EnvSummary {
    pub width: usize,
    pub height: usize,
    pub min: [f32; 3],
    pub max: [f32; 3],
    /// Mean over the sphere (each row weighted by cos(latitude), i.e. by solid angle).
    pub mean_over_sphere: [f64; 3],
    pub negative_values: usize,
}

/// Statistics of `img` (an equirectangular map, rows from the north pole down).
pub fn summarize(img: &RgbBuffer) -> EnvSummary {
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    let mut sum = [0.0f64; 3];
    let mut weight = 0.0;
    let mut negative = 0;
    for y in 0..img.height {
        let lat = std::f64::consts::PI * (0.5 - (y as f64 + 0.5) / img.height as f64);
        let wgt = lat.cos();
        for x in 0..img.width {
            let p = img.pixel(x, y);
            for c in 0..3 {
                min[c] = min[c].min(p[c]);
                max[c] = max[c].max(p[c]);
                sum[c] += wgt * f64::from(p[c]);
                negative += usize::from(p[c] < 0.0);
            }
            weight += wgt;
        }
    }
    let mean = if weight > 0.0 { sum.map(|s| s / weight) } else { [0.0; 3] };
    EnvSummary { width: img.width, height: img.height, min, max, mean_over_sphere: mean, negative_values: negative }
}

/// A perspective view to cut from an equirectangular map
/// ([`perspective_view`]). Angles in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ViewSpec {
    /// Azimuth of the view axis in the map frame, counter-clockwise from +x
    /// seen from above (+z): 0 looks at the map's column u = 0, 90 at u = 0.75.
    pub yaw_deg: f64,
    /// Elevation of the view axis above the horizon (+90 = zenith).
    pub pitch_deg: f64,
    /// Horizontal field of view, 0 < fov < 180.
    pub fov_deg: f64,
    pub width: usize,
    pub height: usize,
}

/// The pinhole camera of a view: square pixels, principal point at the
/// image centre, axes as unit vectors in the map frame (z up). A pixel
/// centre (i + ½, j + ½) looks along
/// forward + ((i + ½ − cx)/f)·right − ((j + ½ − cy)/f)·up.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ViewCamera {
    pub spec: ViewSpec,
    /// Focal length in pixels, f = (width / 2) / tan(fov / 2).
    pub f_px: f64,
    pub cx_px: f64,
    pub cy_px: f64,
    pub forward: [f64; 3],
    pub right: [f64; 3],
    pub up: [f64; 3],
    /// "bilinear, wrapping in u, clamped in v".
    pub filter: String,
}

impl ViewSpec {
    /// Checks the parameters and builds the view's camera.
    pub fn camera(&self) -> Result<ViewCamera, EnvError> {
        if !self.yaw_deg.is_finite() {
            return Err(EnvError::Yaw { yaw_deg: self.yaw_deg });
        }
        if !(self.pitch_deg.is_finite() && self.pitch_deg.abs() <= 90.0) {
            return Err(EnvError::Pitch { pitch_deg: self.pitch_deg });
        }
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            return Err(EnvError::FieldOfView { fov_deg: self.fov_deg });
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return Err(EnvError::ViewSize { width: self.width, height: self.height });
        }
        let (sy, cy) = self.yaw_deg.to_radians().sin_cos();
        let (sp, cp) = self.pitch_deg.to_radians().sin_cos();
        let forward = [cp * cy, cp * sy, sp];
        // right = forward × z at the horizon; defined from the yaw alone so the zenith and nadir views work.
        let right = [sy, -cy, 0.0];
        let up = [-cy * sp, -sy * sp, cp];
        let f_px = 0.5 * self.width as f64 / (0.5 * self.fov_deg.to_radians()).tan();
        Ok(ViewCamera {
            spec: *self,
            f_px,
            cx_px: 0.5 * self.width as f64,
            cy_px: 0.5 * self.height as f64,
            forward,
            right,
            up,
            filter: "bilinear, wrapping in u, clamped in v".into(),
        })
    }
}

impl ViewCamera {
    /// Unit direction (map frame) through image point (x, y) in pixels
    /// (pixel centres at half-integers).
    pub fn direction(&self, x: f64, y: f64) -> [f64; 3] {
        let a = (x - self.cx_px) / self.f_px;
        let b = -(y - self.cy_px) / self.f_px;
        let d: [f64; 3] = std::array::from_fn(|k| self.forward[k] + a * self.right[k] + b * self.up[k]);
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        d.map(|v| v / n)
    }
}

/// Map coordinates (u, v) ∈ [0, 1)² of a unit direction, in the renderer's
/// convention (`lucent-render` env module): θ = πv from +z, φ = −2πu from +x.
pub fn direction_to_uv(d: [f64; 3]) -> (f64, f64) {
    let v = d[2].clamp(-1.0, 1.0).acos() / std::f64::consts::PI;
    let u = (-d[1].atan2(d[0]) / std::f64::consts::TAU).rem_euclid(1.0);
    (u, v)
}

/// Bilinear lookup at map coordinates (u, v): pixel centres at
/// ((x + ½)/W, (y + ½)/H); wraps around in u, clamps to the first and last
/// rows in v.
pub fn sample_bilinear(map: &RgbBuffer, u: f64, v: f64) -> [f32; 3] {
    let (w, h) = (map.width, map.height);
    let px = u * w as f64 - 0.5;
    let py = (v * h as f64 - 0.5).clamp(0.0, (h - 1) as f64);
    let x0f = px.floor();
    let fx = px - x0f;
    let x0 = (x0f as i64).rem_euclid(w as i64) as usize;
    let x1 = (x0 + 1) % w;
    let y0 = py.floor() as usize;
    let y1 = (y0 + 1).min(h - 1);
    let fy = py - y0 as f64;
    let (a, b, c, d) = (map.pixel(x0, y0), map.pixel(x1, y0), map.pixel(x0, y1), map.pixel(x1, y1));
    std::array::from_fn(|k| {
        let top = (1.0 - fx) * f64::from(a[k]) + fx * f64::from(b[k]);
        let bottom = (1.0 - fx) * f64::from(c[k]) + fx * f64::from(d[k]);
        ((1.0 - fy) * top + fy * bottom) as f32
    })
}

/// A perspective (pinhole) view of an equirectangular map, bilinear
/// ([`sample_bilinear`]), with the camera that made it.
pub fn perspective_view(map: &RgbBuffer, spec: &ViewSpec) -> Result<(RgbBuffer, ViewCamera), EnvError> {
    if map.width == 0 || map.height == 0 {
        return Err(EnvError::NotEquirectangular { width: map.width, height: map.height });
    }
    let cam = spec.camera()?;
    let mut out = RgbBuffer::zeros(spec.width, spec.height);
    for j in 0..spec.height {
        for i in 0..spec.width {
            let (u, v) = direction_to_uv(cam.direction(i as f64 + 0.5, j as f64 + 0.5));
            let p = sample_bilinear(map, u, v);
            out.data[3 * (j * spec.width + i)..3 * (j * spec.width + i) + 3].copy_from_slice(&p);
        }
    }
    Ok((out, cam))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn matrix_forms() {
        let want = [[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.5]];
        assert_eq!(parse_matrix("1,2,3; 4,5,6; 7,8,9.5").unwrap(), want);
        assert_eq!(parse_matrix("[[1,2,3],[4,5,6],[7,8,9.5]]").unwrap(), want);
        assert_eq!(
            parse_matrix("{\"note\": \"x\", \"matrix\": [[1,2,3],[4,5,6],[7,8,9.5]], \"n\": 24}").unwrap(),
            want
        );
        assert!(parse_matrix("1,2,3").unwrap_err().to_string().contains("found 3 numbers"));
        assert!(parse_matrix("1,2,x,4,5,6,7,8,9").is_err());
        assert!(parse_matrix("{\"m\": [1]}").is_err());
    }

    #[test]
    fn checks() {
        assert!(check_equirectangular(0, 0).is_err());
        let e = check_equirectangular(1024, 1024).unwrap_err().to_string();
        assert!(e.contains("1024 × 1024") && e.contains("2:1"), "{e}");
        let mut img = RgbBuffer::zeros(4, 2);
        assert!(check_finite(&img).is_ok());
        img.data[3 * 5 + 1] = f32::NAN;
        img.data[3 * 6] = f32::INFINITY;
        assert_eq!(check_finite(&img), Err(EnvError::NonFinite { count: 2, x: 1, y: 1 }));
    }

    #[test]
    fn uniform_sky_has_its_value_as_mean() {
        let img = RgbBuffer::new(8, 4, [0.5f32, 1.0, 2.0].repeat(32)).unwrap();
        let s = summarize(&img);
        for (m, want) in s.mean_over_sphere.iter().zip([0.5, 1.0, 2.0]) {
            assert!((m - want).abs() < 1e-12);
        }
        assert_eq!((s.min, s.max, s.negative_values), ([0.5, 1.0, 2.0], [0.5, 1.0, 2.0], 0));
    }
}

#[cfg(test)]
mod view_tests {
    use super::*;

    /// A map whose pixel colours are the unit direction of the pixel centre,
    /// computed here from the renderer's stated formula (not from
    /// [`direction_to_uv`]).
    fn direction_map(w: usize, h: usize) -> RgbBuffer {
        let mut m = RgbBuffer::zeros(w, h);
        for y in 0..h {
            for x in 0..w {
                let theta = std::f64::consts::PI * (y as f64 + 0.5) / h as f64;
                let phi = -std::f64::consts::TAU * (x as f64 + 0.5) / w as f64;
                let d = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
                for (o, v) in m.data[3 * (y * w + x)..3 * (y * w + x) + 3].iter_mut().zip(d) {
                    *o = v as f32;
                }
            }
        }
        m
    }

    fn unit(v: [f64; 3]) -> [f64; 3] {
        let n = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|x| x / n)
    }

    #[test]
    fn view_pixels_see_the_expected_directions() {
        let map = direction_map(1024, 512);
        // Each case: the view, a pixel, and the direction it must see, worked by hand.
        let t = (45f64).to_radians().tan(); // fov 90° → the image edge is at tan 45° = 1
        let s2 = std::f64::consts::FRAC_1_SQRT_2;
        let cases: [(f64, f64, usize, usize, [f64; 3]); 6] = [
            // Centre of a 90° view at yaw 0: +x.
            (0.0, 0.0, 50, 50, [1.0, 0.0, 0.0]),
            // yaw 90 (counter-clockwise from above): +y.
            (90.0, 0.0, 50, 50, [0.0, 1.0, 0.0]),
            // yaw 180, pitch 45: up and back.
            (180.0, 45.0, 50, 50, [-s2, 0.0, s2]),
            // yaw 0: the right edge's centre, (100.5 − 50.5)/f to the right (right = −y).
            (0.0, 0.0, 100, 50, unit([1.0, -t * 50.0 / 50.5, 0.0])),
            // yaw 0: the top row's centre looks up at 45°.
            (0.0, 0.0, 50, 0, unit([1.0, 0.0, t * 50.0 / 50.5])),
            // yaw −90 (looking at −y, so right = −x), top-left pixel: left (+x) and up.
            (-90.0, 0.0, 0, 0, unit([t * 50.0 / 50.5, -1.0, t * 50.0 / 50.5])),
        ];
        for (yaw, pitch, i, j, want) in cases {
            // 101 × 101 pixels, fov 90°: f = 50.5 px, the edge pixels' centres at ±50/50.5.
            let spec = ViewSpec { yaw_deg: yaw, pitch_deg: pitch, fov_deg: 90.0, width: 101, height: 101 };
            let (view, _) = perspective_view(&map, &spec).unwrap();
            let got = view.pixel(i, j);
            let got = unit([f64::from(got[0]), f64::from(got[1]), f64::from(got[2])]);
            let err = (0..3).map(|k| (got[k] - want[k]).powi(2)).sum::<f64>().sqrt();
            assert!(err < 2e-3, "yaw {yaw} pitch {pitch} pixel ({i}, {j}): got {got:?}, want {want:?}");
        }
    }

    #[test]
    fn zenith_views_and_bad_parameters() {
        let map = direction_map(256, 128);
        let spec = ViewSpec { yaw_deg: 30.0, pitch_deg: 90.0, fov_deg: 60.0, width: 9, height: 9 };
        let (view, cam) = perspective_view(&map, &spec).unwrap();
        let c = view.pixel(4, 4);
        assert!(c[2] > 0.99, "{c:?}");
        assert!((cam.f_px - 4.5 / (30f64).to_radians().tan()).abs() < 1e-12);
        for (yaw, pitch, fov, w) in
            [(f64::NAN, 0.0, 60.0, 9), (0.0, 91.0, 60.0, 9), (0.0, 0.0, 180.0, 9), (0.0, 0.0, 60.0, 0)]
        {
            let spec = ViewSpec { yaw_deg: yaw, pitch_deg: pitch, fov_deg: fov, width: w, height: 9 };
            assert!(
                matches!(
                    perspective_view(&map, &spec),
                    Err(EnvError::Yaw { .. }
                        | EnvError::Pitch { .. }
                        | EnvError::FieldOfView { .. }
                        | EnvError::ViewSize { .. })
                ),
                "{spec:?}"
            );
        }
    }
}

// ---------------------------------------------------------------- orientation

/// The convention every orientation file states: how its yaw turns a map.
pub const ORIENTATION_CONVENTION: &str =
    "world direction = R_z(yaw_deg) · map direction (the renderer's [environment] yaw_deg: counter-clockwise seen from above, z up); world x = the board's i axis, z up";

/// The map turned about +z (the zenith) by `yaw_deg`: the returned map seen
/// with yaw 0 is `map` seen with yaw `yaw_deg`, i.e. its pixel at world
/// direction d holds `map` at R_z(−yaw)·d. In u this is a shift,
/// out(u) = map(u + yaw/360) (φ = −2πu), interpolated linearly along each
/// row (exact when yaw is a multiple of 360°/W).
pub fn rotate_yaw(map: &RgbBuffer, yaw_deg: f64) -> Result<RgbBuffer, EnvError> {
    check_equirectangular(map.width, map.height)?;
    if !yaw_deg.is_finite() {
        return Err(EnvError::Yaw { yaw_deg });
    }
    let w = map.width;
    let shift = (yaw_deg / 360.0).rem_euclid(1.0) * w as f64;
    let whole = shift.floor();
    let f = shift - whole;
    let whole = whole as usize;
    let mut out = RgbBuffer::zeros(w, map.height);
    for y in 0..map.height {
        for x in 0..w {
            let (a, b) = (map.pixel((x + whole) % w, y), map.pixel((x + whole + 1) % w, y));
            let o = 3 * (y * w + x);
            for c in 0..3 {
                out.data[o + c] = ((1.0 - f) * f64::from(a[c]) + f * f64::from(b[c])) as f32;
            }
        }
    }
    Ok(out)
}

/// Which way round the detected corners were numbered.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CornerOrder {
    /// The detector's order already had the light outer square at corner (0, 0).
    AsDetected,
    /// Reversed (the board turned 180°) to put the light outer square at corner (0, 0).
    Reversed,
    /// The board's four outer squares do not single out one corner (both
    /// counts even, or the squares' contrast unclear): the detector's order is kept.
    Ambiguous,
}

/// Puts the corners in the one board numbering of `lucent pose` and
/// `lucent env orient` ([`crate::scene`]'s module docs): the outer corner
/// square diagonally beyond inner corner (0, 0) is the **light** one, as
/// OpenCV's sector-based detector numbers them (a scene draws that board
/// with its `even` squares light). Only boards with one odd and one even
/// inner-corner count single out a corner under the 180° turn; others are
/// left as detected ([`CornerOrder::Ambiguous`]), as are boards whose two
/// outer corner squares cannot be compared (outside the image, or less than
/// 20 grey levels apart). `corners` are row-major (`cols` per row), pixel
/// centres at integers.
pub fn canonical_corner_order(
    img: &crate::buffer::GrayImage,
    cols: usize,
    rows: usize,
    corners: &[[f64; 2]],
) -> (Vec<[f64; 2]>, CornerOrder) {
    let keep = (corners.to_vec(), CornerOrder::Ambiguous);
    if corners.len() != cols * rows || cols < 2 || rows < 2 || (cols + rows).is_multiple_of(2) {
        return keep;
    }
    let at = |i: usize, j: usize| corners[j * cols + i];
    // Centre of the outer square beyond inner corner (i, j), away from the grid by half a square each way.
    let outer = |i: usize, j: usize, di: usize, dj: usize| {
        let c = at(i, j);
        let (a, b) = (at(di, j), at(i, dj));
        let g = |k: usize| c[k] - 0.5 * ((a[k] - c[k]) + (b[k] - c[k]));
        grey_bilinear(img, g(0), g(1))
    };
    let first = outer(0, 0, 1, 1);
    let last = outer(cols - 1, rows - 1, cols - 2, rows - 2);
    match (first, last) {
        (Some(a), Some(b)) if (a - b).abs() > 20.0 => {
            if a > b {
                (corners.to_vec(), CornerOrder::AsDetected)
            } else {
                (corners.iter().rev().copied().collect(), CornerOrder::Reversed)
            }
        }
        _ => keep,
    }
}

fn grey_bilinear(img: &crate::buffer::GrayImage, x: f64, y: f64) -> Option<f64> {
    if !(x >= 0.0 && y >= 0.0 && x <= (img.width as f64 - 1.0) && y <= (img.height as f64 - 1.0)) {
        return None;
    }
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(img.width - 1), (y0 + 1).min(img.height - 1));
    let (fx, fy) = (x - x0 as f64, y - y0 as f64);
    let g = |x: usize, y: usize| f64::from(img.data[y * img.width + x]);
    Some((1.0 - fy) * ((1.0 - fx) * g(x0, y0) + fx * g(x1, y0)) + fy * ((1.0 - fx) * g(x0, y1) + fx * g(x1, y1)))
}

/// The board as seen in a view cut from the map, in the map frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardInMap {
    /// The yaw that turns the map so the board's i axis is world +x
    /// (−azimuth of that axis in the map, degrees, in (−180°, 180°]).
    pub yaw_deg: f64,
    /// The board's i axis (unit, map frame).
    pub i_axis_map: [f64; 3],
    /// The board's normal towards the camera's side (unit, map frame; +z for a level board seen from above).
    pub normal_map: [f64; 3],
    /// Angle between that normal and the map's zenith, degrees: how far the
    /// board (or the 360° camera) is from level. The yaw alone cannot undo it.
    pub tilt_deg: f64,
    /// Direction of board corner (0, 0) from the map's centre (unit, map frame).
    pub corner00_direction_map: [f64; 3],
    /// Distance from the map's centre (the 360° camera) to corner (0, 0) in metres (the given square size's scale).
    pub corner00_distance_m: f64,
}

/// The pinhole camera of a view in OpenCV's pixel convention (pixel centres
/// at integers), for corner detection and PnP: fx = fy = f, cx = W/2 − ½,
/// cy = H/2 − ½.
pub fn view_intrinsics(cam: &ViewCamera) -> crate::model::Intrinsics {
    crate::model::Intrinsics { fx: cam.f_px, fy: cam.f_px, cx: cam.cx_px - 0.5, cy: cam.cy_px - 0.5 }
}

/// From a board pose found in a view (OpenCV: x_cam = R·x_board + t, camera
/// x right, y down, z forward) to the board's axes in the map frame and the
/// yaw that aligns the map with the board's world (x along i, z up).
pub fn board_in_map(cam: &ViewCamera, rotation: &[[f64; 3]; 3], translation_m: [f64; 3]) -> BoardInMap {
    // OpenCV camera axes in the map frame: x = right, y = −up, z = forward.
    let to_map = |v: [f64; 3]| -> [f64; 3] {
        std::array::from_fn(|k| v[0] * cam.right[k] - v[1] * cam.up[k] + v[2] * cam.forward[k])
    };
    let col = |c: usize| [rotation[0][c], rotation[1][c], rotation[2][c]];
    let i_axis = to_map(col(0));
    // The board's z points into the board (away from the camera): the normal towards the camera is −z.
    let normal = to_map(col(2)).map(|v| -v);
    let tilt = normal[2].clamp(-1.0, 1.0).acos().to_degrees();
    let azimuth = i_axis[1].atan2(i_axis[0]).to_degrees();
    let mut yaw = -azimuth;
    if yaw <= -180.0 {
        yaw += 360.0;
    }
    let c = to_map(translation_m);
    let dist = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
    BoardInMap {
        yaw_deg: yaw,
        i_axis_map: i_axis,
        normal_map: normal,
        tilt_deg: tilt,
        corner00_direction_map: c.map(|v| v / dist.max(1e-300)),
        corner00_distance_m: dist,
    }
}

/// The orientation file `lucent env orient` writes beside its output
/// (NAME.json) and a scene's `[environment] orientation` reads.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Orientation {
    /// [`ORIENTATION_CONVENTION`].
    pub convention: String,
    /// File name of the map as it came from the camera.
    pub source: String,
    /// The yaw that aligns `source` with the board's world.
    pub source_yaw_deg: f64,
    /// File name of the turned map (`source` rotated by `source_yaw_deg`).
    pub output: String,
    /// The yaw to render `output` with: 0 (the turn is in its pixels).
    pub output_yaw_deg: f64,
    /// "given" (--yaw) or "board" (found in a view).
    pub method: String,
    /// The view the board was found in, its detection and the board's axes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub board: Option<BoardFound>,
}

/// How the board was found for an orientation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct BoardFound {
    /// The perspective view cut from the source map.
    pub view: ViewSpec,
    /// Inner corners COLSxROWS and square side.
    pub board: String,
    pub square_mm: f64,
    /// Corner detector that found it.
    pub detector: String,
    pub corner_order: CornerOrder,
    /// RMS distance between the detected corners and the PnP pose's projection, pixels of the view.
    pub pnp_rms_px: f64,
    /// The board's axes in the source map's frame.
    pub in_map: BoardInMap,
}

impl Orientation {
    /// The yaw for a scene whose map file is named `map_file_name`: the
    /// output's (0) or the source's; another file is an error (the
    /// orientation belongs to a different map).
    pub fn yaw_for_map(&self, map_file_name: &str) -> Result<f64, EnvError> {
        if map_file_name == self.output {
            Ok(self.output_yaw_deg)
        } else if map_file_name == self.source {
            Ok(self.source_yaw_deg)
        } else {
            Err(EnvError::OtherMap {
                source_map: self.source.clone(),
                source_yaw_deg: self.source_yaw_deg,
                output_map: self.output.clone(),
                output_yaw_deg: self.output_yaw_deg,
                map: map_file_name.to_string(),
            })
        }
    }
}

// ---------------------------------------------------------------- a lens to equirectangular

/// Pixel (OpenCV convention, centres at integers) of a ray in the camera
/// frame (x right, y down, z forward). Fisheye: by the angle off the axis,
/// θ = atan2(√(x² + y²), z), so rays 90° or more off the axis (lenses wider
/// than 180°) project too; the pinhole models need z > 0. `None` where the
/// ray has no image (behind a pinhole, or the Kannala–Brandt polynomial no
/// longer increasing, past the lens's field).
pub fn project_ray(cam: &CameraModel, r: [f64; 3]) -> Option<[f64; 2]> {
    let k = &cam.intrinsics;
    match cam.model {
        DistortionModel::Fisheye => {
            let rho = r[0].hypot(r[1]);
            let t = rho.atan2(r[2]);
            let d = &cam.distortion;
            let t2 = t * t;
            // dθ_d/dθ > 0: past its maximum the polynomial folds back over the image.
            let slope = 1.0 + t2 * (3.0 * d.k1 + t2 * (5.0 * d.k2 + t2 * (7.0 * d.k3 + t2 * 9.0 * d.k4)));
            if slope <= 0.0 {
                return None;
            }
            let td = t * (1.0 + t2 * (d.k1 + t2 * (d.k2 + t2 * (d.k3 + t2 * d.k4))));
            let (x, y) = if rho < 1e-15 { (0.0, 0.0) } else { (td * r[0] / rho, td * r[1] / rho) };
            Some([k.fx * x + k.cx, k.fy * y + k.cy])
        }
        DistortionModel::PinholeK3 | DistortionModel::Rational => cam.project(r),
    }
}

/// The camera ray (OpenCV frame) seen at map direction `d` of a lens's
/// equirectangular view: the lens axis at the map's centre (u = ½, v = ½,
/// map direction −x), up = −y of the camera = +z of the map, the camera's
/// right = map +y. So r = (d_y, −d_z, −d_x) (the view of [`ViewSpec`] with
/// yaw 180°, pitch 0).
pub fn lens_ray_of_map_direction(d: [f64; 3]) -> [f64; 3] {
    [d[1], -d[2], -d[0]]
}

/// A photo of `cam` resampled to a `width` × `width/2` equirectangular map
/// of the whole sphere around the camera ([`lens_ray_of_map_direction`];
/// the renderer's map convention): each map pixel's centre direction is
/// projected into the photo ([`project_ray`]) and sampled bilinearly
/// (pixels outside the photo or the lens's field are 0). Values pass
/// through unchanged. For one lens of a 360° rig at a time; the rig's
/// stitching is not done here.
pub fn lens_to_equirect(img: &RgbBuffer, cam: &CameraModel, width: usize) -> Result<RgbBuffer, EnvError> {
    if (img.width, img.height) != (cam.image_width, cam.image_height) {
        return Err(EnvError::PhotoSize {
            width: img.width,
            height: img.height,
            camera_width: cam.image_width,
            camera_height: cam.image_height,
        });
    }
    if width < 2 || !width.is_multiple_of(2) || width > 32768 {
        return Err(EnvError::MapWidth { width });
    }
    let h = width / 2;
    let mut out = RgbBuffer::zeros(width, h);
    out.data.par_chunks_mut(3 * width).enumerate().for_each(|(y, row)| {
        let theta = std::f64::consts::PI * (y as f64 + 0.5) / h as f64;
        for x in 0..width {
            let phi = -std::f64::consts::TAU * (x as f64 + 0.5) / width as f64;
            let d = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
            if let Some([u, v]) = project_ray(cam, lens_ray_of_map_direction(d)) {
                row[3 * x..3 * x + 3].copy_from_slice(&crate::buffer::sample_bilinear(img, u, v));
            }
        }
    });
    Ok(out)
}

// ---------------------------------------------------------------- pasting a flat picture into a map

/// Puts `img` into the map as the view `spec` would see it (the inverse of
/// [`perspective_view`], for making synthetic panoramas: a chart or a board
/// "photographed" by the 360° camera): every map pixel whose centre
/// direction d falls inside the view's frame takes `img`'s bilinear value
/// at d's image point, x = cx + f (d·right)/(d·forward),
/// y = cy − f (d·up)/(d·forward) (pixel centres at i + ½, clamped at the
/// edges); other pixels are left as they are. The view's width and height
/// are `img`'s. Returns the number of map pixels written.
pub fn paste_view(map: &mut RgbBuffer, img: &RgbBuffer, spec: &ViewSpec) -> Result<usize, EnvError> {
    check_equirectangular(map.width, map.height)?;
    if (img.width, img.height) != (spec.width, spec.height) {
        return Err(EnvError::PictureSize {
            width: img.width,
            height: img.height,
            view_width: spec.width,
            view_height: spec.height,
        });
    }
    let cam = spec.camera()?;
    let (w, h) = (map.width, map.height);
    let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let mut written = 0;
    for y in 0..h {
        let theta = std::f64::consts::PI * (y as f64 + 0.5) / h as f64;
        for x in 0..w {
            let phi = -std::f64::consts::TAU * (x as f64 + 0.5) / w as f64;
            let d = [theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()];
            let z = dot(&d, &cam.forward);
            if z <= 1e-9 {
                continue;
            }
            let px = cam.cx_px + cam.f_px * dot(&d, &cam.right) / z;
            let py = cam.cy_px - cam.f_px * dot(&d, &cam.up) / z;
            if !(px >= 0.0 && py >= 0.0 && px < img.width as f64 && py < img.height as f64) {
                continue;
            }
            let (sx, sy) =
                ((px - 0.5).clamp(0.0, (img.width - 1) as f64), (py - 0.5).clamp(0.0, (img.height - 1) as f64));
            let p = crate::buffer::sample_bilinear(img, sx, sy);
            map.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&p);
            written += 1;
        }
    }
    Ok(written)
}

/// A flat chessboard picture for [`paste_view`]: `cols` × `rows` inner
/// corners, so (cols + 1) × (rows + 1) squares of `square_px` pixels, the
/// outer corner square at the top left dark ((column + row) even: `dark`,
/// odd: `light`), a margin of one square in `light`. For one odd and one
/// even count, [`canonical_corner_order`] numbers it from the light outer
/// square at the bottom right: inner corner (0, 0) there, i pointing left,
/// j up (the board seen from its front).
pub fn chessboard_picture(cols: usize, rows: usize, square_px: usize, dark: f32, light: f32) -> RgbBuffer {
    let (w, h) = ((cols + 3) * square_px, (rows + 3) * square_px);
    let mut img = RgbBuffer::zeros(w, h);
    for y in 0..h {
        for x in 0..w {
            let (c, r) = (x / square_px, y / square_px);
            let inside = (1..=cols + 1).contains(&c) && (1..=rows + 1).contains(&r);
            let v = if inside && (c + r).is_multiple_of(2) { dark } else { light };
            img.data[3 * (y * w + x)..3 * (y * w + x) + 3].copy_from_slice(&[v; 3]);
        }
    }
    img
}
