//! Structural similarity (SSIM) of two single-channel images, as defined by
//! Wang, Bovik, Sheikh & Simoncelli (2004), "Image quality assessment: from
//! error visibility to structural similarity", IEEE Trans. Image Process.
//! 13(4), 600–612, and computed exactly as scikit-image's
//! `structural_similarity(x, y, gaussian_weights=True, sigma=1.5,
//! use_sample_covariance=False, data_range=L)` (scikit-image 0.26):
//!
//! * local means μ, variances σ² and covariance σ_xy from a normalised
//!   Gaussian window, σ = 1.5 px, truncated at 3.5 σ → radius 5, 11 taps
//!   (scipy's `gaussian_filter`); the image is extended by mirror reflection
//!   at its borders (scipy's `mode='reflect'`: `d c b a | a b c d`);
//! * population (co)variances: σ_x² = ⟨x²⟩ − μ_x², σ_xy = ⟨xy⟩ − μ_x μ_y;
//! * SSIM(p) = (2 μ_x μ_y + C1)(2 σ_xy + C2) / ((μ_x² + μ_y² + C1)(σ_x² + σ_y² + C2)),
//!   C1 = (K1 L)², C2 = (K2 L)², K1 = 0.01, K2 = 0.03, L the data range;
//! * the mean SSIM averages the map over the pixels at least
//!   `(11 − 1) / 2 = 5` px from every border (skimage crops the map by this
//!   before its mean). With a mask, the mean is over the mask pixels in that
//!   same interior, so an all-true mask gives skimage's number.
//!
//! All arithmetic is in f64 (inputs may be f32). The filter is separable
//! (rows, then columns; scipy does columns first — the results agree to
//! rounding, ~1e-16) and runs over strips of 64 rows on all cores (rayon),
//! in 4-wide AVX2 vectors where the CPU has them (same bits either way).
//! Partial sums are per strip and added in strip order, so the thread count
//! never changes a result. Checked against scikit-image on committed image
//! pairs (`tests/compare.rs`, `tools/reference/skimage_ssim.py`).
//!
//! ```
//! use lucent::compare::ssim::{ssim, Gray, SsimParams};
//! let (w, h) = (32, 24);
//! let x: Vec<f64> = (0..w * h).map(|i| 0.5 + 0.3 * ((i % w) as f64 * 0.4).sin() * ((i / w) as f64 * 0.3).cos()).collect();
//! let y: Vec<f64> = x.iter().map(|v| 0.8 * v + 0.05).collect();
//! let p = SsimParams::new(1.0).unwrap();
//! let same = ssim(&Gray::new(w, h, &x), &Gray::new(w, h, &x), &p, None).unwrap();
//! assert!((same.mean - 1.0).abs() < 1e-12 && same.pixels == (w - 10) * (h - 10));
//! let other = ssim(&Gray::new(w, h, &x), &Gray::new(w, h, &y), &p, None).unwrap();
//! assert!(other.mean < 1.0 && other.mean > 0.9, "{}", other.mean);
//! ```

use super::error::CompareError;
use super::mask::Mask;
use crate::imageio::RgbImage;
use rayon::prelude::*;

/// Rows per parallel strip (fixed, so results do not depend on threads).
const STRIP: usize = 64;

/// The parameters of SSIM (Wang et al. 2004 defaults but the data range).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SsimParams {
    /// Gaussian window σ in pixels (1.5).
    pub sigma: f64,
    /// Window truncated at this many σ (3.5, skimage's choice → 11 taps).
    pub truncate: f64,
    pub k1: f64,
    pub k2: f64,
    /// L: the dynamic range of the values (1 for images scaled to [0, 1]).
    pub data_range: f64,
}

impl SsimParams {
    /// σ = 1.5, truncate 3.5 (11 taps), K1 = 0.01, K2 = 0.03, and `data_range`
    /// (positive, finite).
    pub fn new(data_range: f64) -> Result<Self, CompareError> {
        if !(data_range.is_finite() && data_range > 0.0) {
            return Err(CompareError::NotPositive { what: "data range", value: data_range });
        }
        Ok(Self { sigma: 1.5, truncate: 3.5, k1: 0.01, k2: 0.03, data_range })
    }

    /// Window radius, `int(truncate σ + 0.5)` (5).
    pub fn radius(&self) -> usize {
        (self.truncate * self.sigma + 0.5) as usize
    }

    /// Window side, 2 × radius + 1 (11).
    pub fn window(&self) -> usize {
        2 * self.radius() + 1
    }

    /// Pixels dropped at each border before the mean, `(window − 1) / 2`.
    pub fn border(&self) -> usize {
        (self.window() - 1) / 2
    }

    pub fn c1(&self) -> f64 {
        (self.k1 * self.data_range).powi(2)
    }

    pub fn c2(&self) -> f64 {
        (self.k2 * self.data_range).powi(2)
    }
}

/// scipy's `_gaussian_kernel1d(sigma, 0, radius)`: exp(−x²/2σ²) for
/// x = −r … r, divided by its sum.
pub fn gaussian_kernel(sigma: f64, radius: usize) -> Vec<f64> {
    let r = radius as f64;
    let raw: Vec<f64> = (0..=2 * radius).map(|k| (-0.5 / (sigma * sigma) * (k as f64 - r).powi(2)).exp()).collect();
    let sum: f64 = raw.iter().sum();
    raw.into_iter().map(|v| v / sum).collect()
}

/// A single-channel image read row by row as f64.
pub trait Plane: Sync {
    /// (width, height).
    fn size(&self) -> (usize, usize);
    /// Row `y` into `out` (length = width).
    fn row(&self, y: usize, out: &mut [f64]);
}

/// A borrowed single-channel f64 image, row-major.
#[derive(Debug, Clone, Copy)]
pub struct Gray<'a> {
    width: usize,
    height: usize,
    data: &'a [f64],
}

impl<'a> Gray<'a> {
    /// Panics if `data.len() != width × height` (a programming error).
    pub fn new(width: usize, height: usize, data: &'a [f64]) -> Self {
        assert_eq!(data.len(), width * height, "Gray::new: {} values for {width} × {height}", data.len());
        Self { width, height, data }
    }
}

impl Plane for Gray<'_> {
    fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }
    fn row(&self, y: usize, out: &mut [f64]) {
        out.copy_from_slice(&self.data[y * self.width..(y + 1) * self.width]);
    }
}

/// One channel (0 = R, 1 = G, 2 = B) of an RGB image.
#[derive(Debug, Clone, Copy)]
pub struct Channel<'a>(pub &'a RgbImage, pub usize);

impl Plane for Channel<'_> {
    fn size(&self) -> (usize, usize) {
        (self.0.width, self.0.height)
    }
    fn row(&self, y: usize, out: &mut [f64]) {
        let w = self.0.width;
        for (o, p) in out.iter_mut().zip(self.0.data[3 * y * w..3 * (y + 1) * w].chunks_exact(3)) {
            *o = f64::from(p[self.1]);
        }
    }
}

/// A weighted sum of the channels, `w₀ R + w₁ G + w₂ B` in f64 (luminance).
#[derive(Debug, Clone, Copy)]
pub struct Weighted<'a>(pub &'a RgbImage, pub [f64; 3]);

impl Plane for Weighted<'_> {
    fn size(&self) -> (usize, usize) {
        (self.0.width, self.0.height)
    }
    fn row(&self, y: usize, out: &mut [f64]) {
        let (w, k) = (self.0.width, self.1);
        for (o, p) in out.iter_mut().zip(self.0.data[3 * y * w..3 * (y + 1) * w].chunks_exact(3)) {
            *o = k[0] * f64::from(p[0]) + k[1] * f64::from(p[1]) + k[2] * f64::from(p[2]);
        }
    }
}

/// A mean SSIM and the number of map pixels it averages.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Ssim {
    pub mean: f64,
    pub pixels: usize,
}

/// scipy's 'reflect' extension: index `i` of a signal of length `n`.
fn reflect(i: isize, n: usize) -> usize {
    let n = n as isize;
    let m = i.rem_euclid(2 * n);
    (if m >= n { 2 * n - 1 - m } else { m }) as usize
}

/// `out[i] = Σ_k kernel[k] · src[i + k]`.
#[inline(always)]
fn correlate(src: &[f64], kernel: &[f64], out: &mut [f64]) {
    let n = out.len();
    out.fill(0.0);
    for (k, &c) in kernel.iter().enumerate() {
        for (o, s) in out.iter_mut().zip(&src[k..k + n]) {
            *o += c * s;
        }
    }
}

struct Setup<'a> {
    width: usize,
    height: usize,
    kernel: Vec<f64>,
    c1: f64,
    c2: f64,
    border: usize,
    /// Source column of each padded column (reflection).
    columns: Vec<usize>,
    mask: Option<&'a [bool]>,
}

/// SSIM map rows `a..b`: returns (sum, count) over the counted pixels of
/// these rows, and writes the map into `map` (rows a..b) if given. On CPUs
/// with AVX2 the same code is compiled for 4-wide vectors; there is no
/// fused multiply-add in it, so both forms give identical bits.
fn strip<P: Plane, Q: Plane>(x: &P, y: &Q, s: &Setup, a: usize, b: usize, map: Option<&mut [f32]>) -> (f64, usize) {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: the CPU has AVX2 (checked just above).
        return unsafe { strip_avx2(x, y, s, a, b, map) };
    }
    strip_body(x, y, s, a, b, map)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn strip_avx2<P: Plane, Q: Plane>(
    x: &P,
    y: &Q,
    s: &Setup,
    a: usize,
    b: usize,
    map: Option<&mut [f32]>,
) -> (f64, usize) {
    strip_body(x, y, s, a, b, map)
}

#[inline(always)]
fn strip_body<P: Plane, Q: Plane>(
    x: &P,
    y: &Q,
    s: &Setup,
    a: usize,
    b: usize,
    map: Option<&mut [f32]>,
) -> (f64, usize) {
    let (w, h) = (s.width, s.height);
    let r = s.kernel.len() / 2;
    let rows = b - a + 2 * r;
    let wp = w + 2 * r;
    // Horizontally filtered x, y, x², y², xy for the strip's rows and halo.
    let mut hf = vec![0.0f64; 5 * rows * w];
    let (mut xr, mut yr) = (vec![0.0f64; w], vec![0.0f64; w]);
    let mut padded = vec![0.0f64; 5 * wp];
    for j in 0..rows {
        let src = reflect(a as isize - r as isize + j as isize, h);
        x.row(src, &mut xr);
        y.row(src, &mut yr);
        let (p0, rest) = padded.split_at_mut(wp);
        let (p1, rest) = rest.split_at_mut(wp);
        let (p2, rest) = rest.split_at_mut(wp);
        let (p3, p4) = rest.split_at_mut(wp);
        for (p, &c) in s.columns.iter().enumerate() {
            let (u, v) = (xr[c], yr[c]);
            p0[p] = u;
            p1[p] = v;
            p2[p] = u * u;
            p3[p] = v * v;
            p4[p] = u * v;
        }
        for q in 0..5 {
            let dst = (q * rows + j) * w;
            correlate(&padded[q * wp..(q + 1) * wp], &s.kernel, &mut hf[dst..dst + w]);
        }
    }
    // Vertical filter and the SSIM formula, row by row.
    let mut acc = vec![0.0f64; 5 * w];
    let mut srow = vec![0.0f64; w];
    let (mut sum, mut count) = (0.0, 0usize);
    let mut map = map;
    for yo in a..b {
        let jo = yo - a;
        for q in 0..5 {
            let out = &mut acc[q * w..(q + 1) * w];
            out.fill(0.0);
            for (k, &c) in s.kernel.iter().enumerate() {
                let src = &hf[(q * rows + jo + k) * w..(q * rows + jo + k + 1) * w];
                for (o, v) in out.iter_mut().zip(src) {
                    *o += c * v;
                }
            }
        }
        let (ux, rest) = acc.split_at(w);
        let (uy, rest) = rest.split_at(w);
        let (uxx, rest) = rest.split_at(w);
        let (uyy, uxy) = rest.split_at(w);
        for i in 0..w {
            let (mx, my) = (ux[i], uy[i]);
            let vx = uxx[i] - mx * mx;
            let vy = uyy[i] - my * my;
            let vxy = uxy[i] - mx * my;
            let a1 = 2.0 * mx * my + s.c1;
            let a2 = 2.0 * vxy + s.c2;
            let b1 = mx * mx + my * my + s.c1;
            let b2 = vx + vy + s.c2;
            srow[i] = (a1 * a2) / (b1 * b2);
        }
        if let Some(m) = map.as_deref_mut() {
            for (o, v) in m[jo * w..(jo + 1) * w].iter_mut().zip(&srow) {
                *o = *v as f32;
            }
        }
        if yo >= s.border && yo + s.border < h {
            let cols = s.border..w - s.border;
            match s.mask {
                None => {
                    sum += srow[cols.clone()].iter().sum::<f64>();
                    count += cols.len();
                }
                Some(m) => {
                    for i in cols {
                        if m[yo * w + i] {
                            sum += srow[i];
                            count += 1;
                        }
                    }
                }
            }
        }
    }
    (sum, count)
}

fn setup<'a, P: Plane, Q: Plane>(
    x: &P,
    y: &Q,
    params: &SsimParams,
    mask: Option<&'a Mask>,
) -> Result<Setup<'a>, CompareError> {
    let (w, h) = x.size();
    if y.size() != (w, h) {
        let (w2, h2) = y.size();
        return Err(CompareError::Size {
            first: "the first SSIM image".into(),
            first_size: (w, h),
            second: "the second".into(),
            second_size: (w2, h2),
        });
    }
    let win = params.window();
    if w < win || h < win {
        return Err(CompareError::TooSmallForSsim { window: win, width: w, height: h });
    }
    if let Some(m) = mask
        && (m.width, m.height) != (w, h)
    {
        return Err(CompareError::Size {
            first: "the mask".into(),
            first_size: (m.width, m.height),
            second: "the images".into(),
            second_size: (w, h),
        });
    }
    let radius = params.radius();
    let columns = (0..w + 2 * radius).map(|p| reflect(p as isize - radius as isize, w)).collect();
    Ok(Setup {
        width: w,
        height: h,
        kernel: gaussian_kernel(params.sigma, radius),
        c1: params.c1(),
        c2: params.c2(),
        border: params.border(),
        columns,
        mask: mask.map(|m| m.include.as_slice()),
    })
}

fn finish(parts: Vec<(f64, usize)>) -> Result<Ssim, CompareError> {
    let (mut sum, mut pixels) = (0.0, 0usize);
    for (s, n) in parts {
        sum += s;
        pixels += n;
    }
    if pixels == 0 {
        return Err(CompareError::NoSsimPixels);
    }
    Ok(Ssim { mean: sum / pixels as f64, pixels })
}

/// Mean SSIM of `x` and `y` (same size, at least 11 × 11), over `mask`
/// pixels if given (see the module docs).
pub fn ssim<P: Plane, Q: Plane>(x: &P, y: &Q, params: &SsimParams, mask: Option<&Mask>) -> Result<Ssim, CompareError> {
    let s = setup(x, y, params, mask)?;
    let strips = s.height.div_ceil(STRIP);
    let parts: Vec<(f64, usize)> = (0..strips)
        .into_par_iter()
        .map(|k| strip(x, y, &s, k * STRIP, ((k + 1) * STRIP).min(s.height), None))
        .collect();
    finish(parts)
}

/// The SSIM map of `x` against the noise-free image behind two independent
/// noisy estimates `a` and `b` of it (two half renders of one run: same
/// expectation, independent noise), all `width × height` f64 planes. The
/// window moments that noise biases are replaced by unbiased ones from the
/// pair: μ_y² by μ_a μ_b and σ_y² by ⟨ab⟩ − μ_a μ_b (for independent noise
/// E\[a b\] = E\[a\] E\[b\] pixel by pixel), while μ_y and σ_xy come from
/// y = (a + b)/2 (noise independent of x leaves them unbiased). The
/// remaining bias is that of a ratio of unbiased estimates, which shrinks
/// with the window's effective number of pixels (≈ 4πσ² = 28). Same window,
/// border reflection and constants as [`ssim`]; the map is clamped to
/// [−1, 1] (a noise-dominated window can drive the debiased variance
/// below −σ_x² − C2).
pub fn ssim_map_noise_free(
    x: &[f64],
    a: &[f64],
    b: &[f64],
    width: usize,
    height: usize,
    params: &SsimParams,
) -> Result<Vec<f64>, CompareError> {
    let n = width * height;
    if x.len() != n || a.len() != n || b.len() != n {
        return Err(CompareError::Size {
            first: "the photo".into(),
            first_size: (width, height),
            second: "the half renders".into(),
            second_size: (width, a.len().min(b.len()).min(x.len()) / width.max(1)),
        });
    }
    let k = gaussian_kernel(params.sigma, params.radius());
    let r = params.radius() as isize;
    // Separable Gaussian filter with scipy's reflection.
    let filter = |f: &dyn Fn(usize) -> f64| -> Vec<f64> {
        let src: Vec<f64> = (0..n).map(f).collect();
        let mut rows = vec![0.0; n];
        rows.par_chunks_mut(width).enumerate().for_each(|(y, out)| {
            for (xx, o) in out.iter_mut().enumerate() {
                *o = k
                    .iter()
                    .enumerate()
                    .map(|(t, c)| c * src[y * width + reflect(xx as isize + t as isize - r, width)])
                    .sum();
            }
        });
        let mut out = vec![0.0; n];
        out.par_chunks_mut(width).enumerate().for_each(|(y, o)| {
            for (t, c) in k.iter().enumerate() {
                let yy = reflect(y as isize + t as isize - r, height);
                for (v, s) in o.iter_mut().zip(&rows[yy * width..(yy + 1) * width]) {
                    *v += c * s;
                }
            }
        });
        out
    };
    let y = |i: usize| 0.5 * (a[i] + b[i]);
    let (mx, ma, mb) = (filter(&|i| x[i]), filter(&|i| a[i]), filter(&|i| b[i]));
    let (xx, xy, ab) = (filter(&|i| x[i] * x[i]), filter(&|i| x[i] * y(i)), filter(&|i| a[i] * b[i]));
    let (c1, c2) = (params.c1(), params.c2());
    Ok((0..n)
        .map(|i| {
            let my = 0.5 * (ma[i] + mb[i]);
            let my2 = ma[i] * mb[i];
            let (vx, vy, vxy) = (xx[i] - mx[i] * mx[i], ab[i] - my2, xy[i] - mx[i] * my);
            let s = (2.0 * mx[i] * my + c1) * (2.0 * vxy + c2) / ((mx[i] * mx[i] + my2 + c1) * (vx + vy + c2));
            if s.is_finite() {
                s.clamp(-1.0, 1.0)
            } else {
                0.0
            }
        })
        .collect())
}

/// The pixels [`ssim`]'s mean is taken over: those of `mask` (all if none)
/// at least [`SsimParams::border`] pixels from every image border.
pub fn mean_pixels(width: usize, height: usize, params: &SsimParams, mask: Option<&Mask>) -> Vec<bool> {
    let b = params.border();
    (0..width * height)
        .map(|p| {
            let (x, y) = (p % width, p / width);
            x >= b && x + b < width && y >= b && y + b < height && mask.is_none_or(|m| m.include[p])
        })
        .collect()
}

/// [`ssim`] and the full SSIM map (`width × height`, row-major, f32; the
/// border pixels hold values too, but are not in the mean).
pub fn ssim_with_map<P: Plane, Q: Plane>(
    x: &P,
    y: &Q,
    params: &SsimParams,
    mask: Option<&Mask>,
) -> Result<(Ssim, Vec<f32>), CompareError> {
    let s = setup(x, y, params, mask)?;
    let mut map = vec![0.0f32; s.width * s.height];
    let parts: Vec<(f64, usize)> = map
        .par_chunks_mut(STRIP * s.width)
        .enumerate()
        .map(|(k, m)| strip(x, y, &s, k * STRIP, ((k + 1) * STRIP).min(s.height), Some(m)))
        .collect();
    Ok((finish(parts)?, map))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kernel_is_scipys() {
        let k = gaussian_kernel(1.5, 5);
        assert_eq!(k.len(), 11);
        assert!((k.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        // scipy.ndimage._filters._gaussian_kernel1d(1.5, 0, 5)[5] (centre tap).
        assert!((k[5] - 0.26601172486179436).abs() < 1e-15, "{}", k[5]);
        assert_eq!(k[0], k[10]);
        let p = SsimParams::new(1.0).unwrap();
        assert_eq!((p.radius(), p.window(), p.border()), (5, 11, 5));
        assert!(SsimParams::new(0.0).is_err() && SsimParams::new(f64::NAN).is_err());
    }

    #[test]
    fn reflection_is_half_sample_symmetric() {
        let n = 4;
        let got: Vec<usize> = (-5..9).map(|i| reflect(i, n)).collect();
        assert_eq!(got, [3, 3, 2, 1, 0, 0, 1, 2, 3, 3, 2, 1, 0, 0]);
    }

    /// Direct (non-separable, no strips) evaluation of the same definition.
    fn brute(x: &[f64], y: &[f64], w: usize, h: usize, p: &SsimParams) -> Vec<f64> {
        let k = gaussian_kernel(p.sigma, p.radius());
        let r = p.radius() as isize;
        let mut out = vec![0.0; w * h];
        for yy in 0..h {
            for xx in 0..w {
                let mut m = [0.0; 5];
                for dy in -r..=r {
                    for dx in -r..=r {
                        let wgt = k[(dy + r) as usize] * k[(dx + r) as usize];
                        let i = reflect(yy as isize + dy, h) * w + reflect(xx as isize + dx, w);
                        let (a, b) = (x[i], y[i]);
                        for (mq, v) in m.iter_mut().zip([a, b, a * a, b * b, a * b]) {
                            *mq += wgt * v;
                        }
                    }
                }
                let (vx, vy, vxy) = (m[2] - m[0] * m[0], m[3] - m[1] * m[1], m[4] - m[0] * m[1]);
                out[yy * w + xx] = (2.0 * m[0] * m[1] + p.c1()) * (2.0 * vxy + p.c2())
                    / ((m[0] * m[0] + m[1] * m[1] + p.c1()) * (vx + vy + p.c2()));
            }
        }
        out
    }

    #[test]
    fn separable_strips_match_the_direct_sum_across_strip_boundaries() {
        let (w, h) = (23, 150); // three strips, the last one short
        let x: Vec<f64> = (0..w * h).map(|i| ((i * 7919) % 101) as f64 / 100.0).collect();
        let y: Vec<f64> = (0..w * h).map(|i| ((i * 104729) % 97) as f64 / 96.0 * 0.7 + 0.1).collect();
        let p = SsimParams::new(1.0).unwrap();
        let (s, map) = ssim_with_map(&Gray::new(w, h, &x), &Gray::new(w, h, &y), &p, None).unwrap();
        let want = brute(&x, &y, w, h, &p);
        for (a, b) in map.iter().zip(&want) {
            assert!((f64::from(*a) - b).abs() < 1e-6, "{a} vs {b}");
        }
        let inner: Vec<f64> =
            (5..h - 5).flat_map(|yy| (5..w - 5).map(move |xx| yy * w + xx)).map(|i| want[i]).collect();
        let mean = inner.iter().sum::<f64>() / inner.len() as f64;
        assert!((s.mean - mean).abs() < 1e-12, "{} vs {mean}", s.mean);
        assert_eq!(s.pixels, inner.len());
        assert!((ssim(&Gray::new(w, h, &x), &Gray::new(w, h, &y), &p, None).unwrap().mean - s.mean).abs() == 0.0);
    }

    #[test]
    fn vector_and_plain_forms_give_identical_bits() {
        let (w, h) = (37, 70);
        let x: Vec<f64> = (0..w * h).map(|i| ((i * 7919) % 101) as f64 / 100.0).collect();
        let y: Vec<f64> = (0..w * h).map(|i| ((i * 104729) % 97) as f64 / 96.0).collect();
        let (gx, gy) = (Gray::new(w, h, &x), Gray::new(w, h, &y));
        let p = SsimParams::new(1.0).unwrap();
        let s = setup(&gx, &gy, &p, None).unwrap();
        let (mut m1, mut m2) = (vec![0f32; 64 * w], vec![0f32; 64 * w]);
        let a = strip(&gx, &gy, &s, 0, 64, Some(&mut m1));
        let b = strip_body(&gx, &gy, &s, 0, 64, Some(&mut m2));
        assert_eq!(a.0.to_bits(), b.0.to_bits());
        assert_eq!(m1, m2);
    }

    #[test]
    fn small_or_mismatched_images_are_errors() {
        let p = SsimParams::new(1.0).unwrap();
        let a = vec![0.5; 10 * 20];
        let e = ssim(&Gray::new(10, 20, &a), &Gray::new(10, 20, &a), &p, None).unwrap_err();
        assert!(e.to_string().contains("11 × 11"), "{e}");
        let b = vec![0.5; 12 * 12];
        let c = vec![0.5; 13 * 12];
        assert!(ssim(&Gray::new(12, 12, &b), &Gray::new(13, 12, &c), &p, None).is_err());
        let none = Mask { width: 12, height: 12, include: vec![false; 144] };
        let e = ssim(&Gray::new(12, 12, &b), &Gray::new(12, 12, &b), &p, Some(&none)).unwrap_err();
        assert!(e.to_string().contains("no pixel"), "{e}");
    }
}
