//! Equirectangular HDR environment maps (the 360° camera's output): the
//! 2:1 check, a 3 × 3 colour matrix (camera RGB → the shared CIE RGB space,
//! from the colour stage), and a summary of the radiance values.
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
