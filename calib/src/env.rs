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

use crate::RgbBuffer;
use serde::{Deserialize, Serialize};

/// What is wrong with an environment map.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EnvError {
    #[error("{width} × {height} pixels is not an equirectangular map: the width must be exactly twice the height (2:1, e.g. 2048 × 1024)")]
    NotEquirectangular { width: usize, height: usize },
    #[error("{count} pixel values are NaN or infinite (first at x = {x}, y = {y})")]
    NonFinite { count: usize, x: usize, y: usize },
    #[error("colour matrix: {0}")]
    Matrix(String),
    #[error("view: {0}")]
    View(String),
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
    let bad = |why: &str| {
        EnvError::Matrix(format!(
            "{why}; give 9 numbers row-major, a JSON [[..],[..],[..]] or {{\"matrix\": [[..],..]}}"
        ))
    };
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
        .map(|s| s.parse::<f64>().map_err(|_| bad(&format!("{s:?} is not a number"))))
        .collect::<Result<_, _>>()?;
    if nums.len() != 9 {
        return Err(bad(&format!("found {} numbers", nums.len())));
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
        let bad = |m: String| Err(EnvError::View(m));
        if !self.yaw_deg.is_finite() {
            return bad(format!("yaw {}° must be finite", self.yaw_deg));
        }
        if !(self.pitch_deg.is_finite() && self.pitch_deg.abs() <= 90.0) {
            return bad(format!("pitch {}° must be within [−90°, 90°]", self.pitch_deg));
        }
        if !(self.fov_deg > 0.0 && self.fov_deg < 180.0) {
            return bad(format!("field of view {}° must be within (0°, 180°)", self.fov_deg));
        }
        if self.width == 0 || self.height == 0 || self.width > 16384 || self.height > 16384 {
            return bad(format!("size {} × {} must be 1 to 16384 pixels each way", self.width, self.height));
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
            assert!(matches!(perspective_view(&map, &spec), Err(EnvError::View(_))), "{spec:?}");
        }
    }
}
