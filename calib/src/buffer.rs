//! The plain pixel buffers this crate takes and returns (linear RGB `f32`,
//! 8-bit grey) and bilinear sampling of an RGB buffer. A leaf module: every
//! other module builds on it; the crate root re-exports its types.
//!
//! ```
//! // A linear RGB buffer, row-major, interleaved.
//! let img = lucent_calib::RgbBuffer::new(2, 1, vec![0.0, 0.5, 1.0, 1.0, 0.5, 0.0]).unwrap();
//! assert_eq!(img.pixel(1, 0), [1.0, 0.5, 0.0]);
//! assert_eq!(lucent_calib::buffer::sample_bilinear(&img, 0.5, 0.0), [0.5, 0.5, 0.5]);
//! ```

/// A linear RGB image: `data` holds `width × height` interleaved `[r, g, b]`
/// triples, row-major, top row first. The same layout as the root crate's
/// `imageio::RgbImage`, so conversion is a move of the fields.
#[derive(Debug, Clone, PartialEq)]
pub struct RgbBuffer {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f32>,
}

/// A buffer whose length does not match its stated size.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("image buffer of {len} values does not hold {width} × {height} × {channels}")]
pub struct BufferSizeError {
    pub width: usize,
    pub height: usize,
    pub channels: usize,
    pub len: usize,
}

impl RgbBuffer {
    /// Checks that `data` holds exactly `width × height` RGB triples.
    pub fn new(width: usize, height: usize, data: Vec<f32>) -> Result<Self, BufferSizeError> {
        if width.checked_mul(height).and_then(|n| n.checked_mul(3)) != Some(data.len()) {
            return Err(BufferSizeError { width, height, channels: 3, len: data.len() });
        }
        Ok(Self { width, height, data })
    }

    /// A black image.
    pub fn zeros(width: usize, height: usize) -> Self {
        Self { width, height, data: vec![0.0; width * height * 3] }
    }

    /// The RGB triple at column `x`, row `y` (panics outside the image).
    pub fn pixel(&self, x: usize, y: usize) -> [f32; 3] {
        let i = 3 * (y * self.width + x);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
}

/// An 8-bit grey image (row-major, top row first), e.g. a photo for corner
/// detection.
#[derive(Debug, Clone, PartialEq)]
pub struct GrayImage {
    pub width: usize,
    pub height: usize,
    pub data: Vec<u8>,
}

impl GrayImage {
    /// Checks that `data` holds exactly `width × height` values.
    pub fn new(width: usize, height: usize, data: Vec<u8>) -> Result<Self, BufferSizeError> {
        if width.checked_mul(height) != Some(data.len()) {
            return Err(BufferSizeError { width, height, channels: 1, len: data.len() });
        }
        Ok(Self { width, height, data })
    }

    /// Grey from linear RGB for display and detection: luma of the
    /// sRGB-encoded values (Rec. 709 weights), each image scaled so its
    /// 99.5th percentile maps to 255 (so dark linear photos still show the
    /// board).
    pub fn from_linear_rgb(img: &RgbBuffer) -> Self {
        let mut luma: Vec<f32> =
            img.data.chunks_exact(3).map(|p| (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]).max(0.0)).collect();
        let mut sorted: Vec<f32> = luma.iter().copied().filter(|v| v.is_finite()).collect();
        sorted.sort_by(f32::total_cmp);
        let index = (sorted.len().saturating_sub(1) as f64 * 0.995).round() as usize;
        let white = sorted.get(index).copied().unwrap_or(1.0);
        let white = if white > 0.0 { white } else { 1.0 };
        for v in &mut luma {
            *v = (*v / white).clamp(0.0, 1.0);
        }
        let data = luma
            .iter()
            .map(|&v| {
                let s = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
                (s * 255.0).round().clamp(0.0, 255.0) as u8
            })
            .collect();
        Self { width: img.width, height: img.height, data }
    }
}

/// Bilinear sample at (u, v), pixel centres at integers; pixels outside the
/// image count as 0 (OpenCV's `BORDER_CONSTANT`).
#[inline]
pub fn sample_bilinear(img: &RgbBuffer, u: f64, v: f64) -> [f32; 3] {
    if !(u > -1.0 && v > -1.0 && u < img.width as f64 && v < img.height as f64) {
        return [0.0; 3];
    }
    let (x0, y0) = (u.floor(), v.floor());
    let (fx, fy) = ((u - x0) as f32, (v - y0) as f32);
    let (x0, y0) = (x0 as isize, y0 as isize);
    let mut out = [0.0f32; 3];
    for (dy, wy) in [(0isize, 1.0 - fy), (1, fy)] {
        for (dx, wx) in [(0isize, 1.0 - fx), (1, fx)] {
            let (x, y) = (x0 + dx, y0 + dy);
            if x < 0 || y < 0 || x >= img.width as isize || y >= img.height as isize || wx * wy == 0.0 {
                continue;
            }
            let p = img.pixel(x as usize, y as usize);
            for c in 0..3 {
                out[c] += wx * wy * p[c];
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_from_linear_rgb_scales_to_the_bright_end_and_encodes_srgb() {
        // 199 dark pixels at 0.01 and one at 0.04: white = 0.01 (99.5th percentile),
        // so the dark ones become 255 and the bright one clips at 255.
        let mut data = vec![0.01f32; 200 * 3];
        data[..3].copy_from_slice(&[0.04; 3]);
        let g = GrayImage::from_linear_rgb(&RgbBuffer::new(200, 1, data).unwrap());
        assert!(g.data.iter().all(|&v| v == 255));
        // Linear 0.5 of white → sRGB 0.7354 → 188.
        let img = RgbBuffer::new(2, 1, vec![0.5, 0.5, 0.5, 1.0, 1.0, 1.0]).unwrap();
        assert_eq!(GrayImage::from_linear_rgb(&img).data, [188, 255]);
        assert!(GrayImage::new(2, 2, vec![0; 3]).is_err());
        assert!(RgbBuffer::new(2, 2, vec![0.0; 11]).is_err());
    }

    #[test]
    fn bilinear_sampling_at_and_between_pixels() {
        let img = RgbBuffer::new(2, 2, vec![0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 2.0, 2.0, 2.0, 3.0, 3.0, 3.0]).unwrap();
        assert_eq!(sample_bilinear(&img, 1.0, 1.0), [3.0; 3]);
        assert_eq!(sample_bilinear(&img, 0.5, 0.5), [1.5; 3]);
        assert_eq!(sample_bilinear(&img, -0.5, 1.0), [1.0; 3], "half way to the zero border");
        assert_eq!(sample_bilinear(&img, 1.5, 0.0), [0.5; 3]);
        assert_eq!(sample_bilinear(&img, 5.0, 0.0), [0.0; 3]);
        assert_eq!(sample_bilinear(&img, f64::NAN, 0.0), [0.0; 3]);
    }
}
