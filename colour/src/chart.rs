//! ColorChecker Classic patch sampling: the robust mean camera RGB of each of
//! the 4 × 6 patches in a linear image, given the chart's four corners.
//!
//! Geometry. The corners are the outer corners of the patch grid (the outer
//! edges of patches 1, 6, 24 and 19), in the order top-left (dark skin),
//! top-right (bluish green), bottom-right (black), bottom-left (white) as the
//! chart reads, i.e. clockwise as seen in the image. Pixel coordinates are
//! continuous: x to the right, y down, the image spans [0, width] × [0,
//! height], pixel (i, j) covers [i, i+1) × [j, j+1) and its centre is
//! (i + ½, j + ½). A homography maps the chart's unit square onto the four
//! corners, so perspective is handled exactly. Patches are squares of side s
//! separated by gaps of `gap_ratio`·s (default 0.14, measured on
//! `fixtures/colour/colorchecker.jpg`; OpenCV's `mcc` chart model has 0.10);
//! of each patch only the central `inner_fraction` (default 0.5) of its side
//! is sampled, which keeps the sample inside the patch even if the corners
//! are off by a tenth of a patch.
//!
//! Robust mean: per channel, the mean of the pixels left after dropping the
//! `trim_fraction` (default 10 %) lowest and highest values (a trimmed mean:
//! dust, specks and the odd hot pixel do not move it).
//!
//! Saturation check: a pixel is clipped when a channel is ≥ `clip_level`
//! (default 0.99, for images normalised to the sensor's white level as
//! lucent's RAW decoding and integer image reading produce; `None` disables
//! the check). A patch with more than `max_clipped_fraction` (default 1 %)
//! clipped pixels is refused; the error lists every such patch by number and
//! name. Non-finite pixels are an error too.
//!
//! ```
//! use lucent_colour::chart::{sample_patches, ImageRef, SampleOptions};
//! // A 60 × 40 synthetic image whose every pixel is (0.2, 0.3, 0.4).
//! let data = vec![0.2f32, 0.3, 0.4].repeat(60 * 40);
//! let img = ImageRef::new(60, 40, &data).unwrap();
//! let corners = [[0.0, 0.0], [60.0, 0.0], [60.0, 40.0], [0.0, 40.0]];
//! let patches = sample_patches(&img, corners, &SampleOptions::default()).unwrap();
//! assert_eq!(patches.len(), 24);
//! assert!((patches[23].mean[2] - 0.4).abs() < 1e-6);
//! ```

use crate::data::colorchecker_2014;
use crate::matrix::{mat3_inverse, mat3_vec};
use crate::{ClippedPatch, ColourError, Mat3};
use nalgebra::{SMatrix, SVector};
use serde::{Deserialize, Serialize};

/// Patch rows of the ColorChecker Classic.
pub const ROWS: usize = 4;
/// Patch columns of the ColorChecker Classic.
pub const COLS: usize = 6;
/// A sample area must cover at least this many pixel centres.
pub const MIN_PIXELS: usize = 4;

/// A borrowed linear RGB image: interleaved `f32` R, G, B, row-major, top row first.
#[derive(Debug, Clone, Copy)]
pub struct ImageRef<'a> {
    pub width: usize,
    pub height: usize,
    pub data: &'a [f32],
}

impl<'a> ImageRef<'a> {
    /// An error unless `data.len() == width * height * 3` and the image is not empty.
    pub fn new(width: usize, height: usize, data: &'a [f32]) -> Result<Self, ColourError> {
        if width == 0 || height == 0 {
            return Err(ColourError::Invalid { what: "image".into(), reason: format!("{width} × {height} is empty") });
        }
        let expected = width.checked_mul(height).and_then(|n| n.checked_mul(3)).unwrap_or(usize::MAX);
        if data.len() != expected {
            return Err(ColourError::Length {
                what: format!("{width} × {height} RGB image data"),
                expected,
                got: data.len(),
            });
        }
        Ok(Self { width, height, data })
    }

    fn pixel(&self, x: usize, y: usize) -> [f32; 3] {
        let i = 3 * (y * self.width + x);
        [self.data[i], self.data[i + 1], self.data[i + 2]]
    }
}

/// How patches are sampled (see the module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SampleOptions {
    /// Gap between patches as a fraction of the patch side.
    pub gap_ratio: f64,
    /// Side of the sampled square as a fraction of the patch side.
    pub inner_fraction: f64,
    /// Fraction of pixels dropped at each end, per channel, before averaging.
    pub trim_fraction: f64,
    /// A channel at or above this value is clipped; `None`: no check.
    pub clip_level: Option<f64>,
    /// Largest tolerated fraction of clipped pixels in a patch.
    pub max_clipped_fraction: f64,
}

impl Default for SampleOptions {
    fn default() -> Self {
        Self {
            gap_ratio: 0.14,
            inner_fraction: 0.5,
            trim_fraction: 0.1,
            clip_level: Some(0.99),
            max_clipped_fraction: 0.01,
        }
    }
}

impl SampleOptions {
    fn validate(&self) -> Result<(), ColourError> {
        let bad = |what: &str, reason: &str| Err(ColourError::Invalid { what: what.into(), reason: reason.into() });
        if !(self.gap_ratio >= 0.0 && self.gap_ratio < 1.0) {
            return bad("gap_ratio", "must be in [0, 1)");
        }
        if !(self.inner_fraction > 0.0 && self.inner_fraction <= 1.0) {
            return bad("inner_fraction", "must be in (0, 1]");
        }
        if !(self.trim_fraction >= 0.0 && self.trim_fraction < 0.5) {
            return bad("trim_fraction", "must be in [0, 0.5)");
        }
        if self.clip_level.is_some_and(|c| !c.is_finite()) {
            return bad("clip_level", "must be finite");
        }
        if !(0.0..=1.0).contains(&self.max_clipped_fraction) {
            return bad("max_clipped_fraction", "must be in [0, 1]");
        }
        Ok(())
    }

    /// The sampled square of patch `index` (0-based, chart order) in chart
    /// coordinates: (u0, v0, u1, v1) in the unit square.
    pub fn sample_square(&self, index: usize) -> [f64; 4] {
        let (row, col) = (index / COLS, index % COLS);
        let g = self.gap_ratio;
        let (wu, wv) = (COLS as f64 + (COLS - 1) as f64 * g, ROWS as f64 + (ROWS - 1) as f64 * g);
        let cu = (col as f64 * (1.0 + g) + 0.5) / wu;
        let cv = (row as f64 * (1.0 + g) + 0.5) / wv;
        let (hu, hv) = (0.5 * self.inner_fraction / wu, 0.5 * self.inner_fraction / wv);
        [cu - hu, cv - hv, cu + hu, cv + hv]
    }
}

/// The projective map from chart coordinates (u, v) ∈ [0, 1]² to image pixel
/// coordinates (x, y).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Homography {
    pub h: Mat3,
    pub inverse: Mat3,
}

impl Homography {
    /// The homography taking (0,0), (1,0), (1,1), (0,1) to the four corners;
    /// an error unless the corners are finite and form a convex quadrilateral
    /// in clockwise image order.
    pub fn from_corners(corners: [[f64; 2]; 4]) -> Result<Self, ColourError> {
        if let Some(v) = corners.iter().flatten().find(|v| !v.is_finite()) {
            return Err(ColourError::NonFinite {
                what: "chart corners".into(),
                index_desc: "a coordinate".into(),
                value: *v,
            });
        }
        let cross: Vec<f64> = (0..4)
            .map(|i| {
                let (a, b, c) = (corners[i], corners[(i + 1) % 4], corners[(i + 2) % 4]);
                (b[0] - a[0]) * (c[1] - b[1]) - (b[1] - a[1]) * (c[0] - b[0])
            })
            .collect();
        if cross.iter().all(|c| *c < 0.0) {
            return Err(ColourError::Invalid {
                what: "chart corners".into(),
                reason: "they run anticlockwise in the image; give them as the chart reads: top-left (dark skin), top-right (bluish green), bottom-right (black), bottom-left (white)".into(),
            });
        }
        if !cross.iter().all(|c| *c > 0.0) {
            return Err(ColourError::Invalid {
                what: "chart corners".into(),
                reason: "they do not form a convex quadrilateral in the order top-left, top-right, bottom-right, bottom-left".into(),
            });
        }
        let src = [[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]];
        let mut a = SMatrix::<f64, 8, 8>::zeros();
        let mut b = SVector::<f64, 8>::zeros();
        for k in 0..4 {
            let ([u, v], [x, y]) = (src[k], corners[k]);
            a.set_row(
                2 * k,
                &nalgebra::RowSVector::<f64, 8>::from_row_slice(&[u, v, 1.0, 0.0, 0.0, 0.0, -u * x, -v * x]),
            );
            a.set_row(
                2 * k + 1,
                &nalgebra::RowSVector::<f64, 8>::from_row_slice(&[0.0, 0.0, 0.0, u, v, 1.0, -u * y, -v * y]),
            );
            b[2 * k] = x;
            b[2 * k + 1] = y;
        }
        let p = a.lu().solve(&b).ok_or_else(|| ColourError::Singular {
            what: "chart homography".into(),
            reason: "the corners are degenerate".into(),
        })?;
        let h = [[p[0], p[1], p[2]], [p[3], p[4], p[5]], [p[6], p[7], 1.0]];
        let inverse = mat3_inverse(&h)?;
        Ok(Self { h, inverse })
    }

    /// Image coordinates of chart point (u, v).
    pub fn map(&self, u: f64, v: f64) -> [f64; 2] {
        let p = mat3_vec(&self.h, [u, v, 1.0]);
        [p[0] / p[2], p[1] / p[2]]
    }

    /// Chart coordinates of image point (x, y).
    pub fn unmap(&self, x: f64, y: f64) -> [f64; 2] {
        let p = mat3_vec(&self.inverse, [x, y, 1.0]);
        [p[0] / p[2], p[1] / p[2]]
    }
}

/// The sampled values of one patch.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PatchSample {
    /// 1-based patch number in chart order.
    pub patch: usize,
    pub name: &'static str,
    /// Trimmed mean R, G, B.
    pub mean: [f64; 3],
    /// Standard deviation of the pixels kept by the trim, per channel.
    pub std_dev: [f64; 3],
    /// Pixels in the sampled square.
    pub pixels: usize,
    /// Fraction of them with a clipped channel.
    pub clipped_fraction: f64,
    /// The sampled square's corners in image coordinates (TL, TR, BR, BL).
    pub outline: [[f64; 2]; 4],
}

fn trimmed_mean(values: &mut [f64], trim: f64) -> (f64, f64) {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    let k = ((n as f64) * trim).floor() as usize;
    let kept = &values[k.min(n / 2)..n - k.min((n - 1) / 2)];
    let m = kept.iter().sum::<f64>() / kept.len() as f64;
    let var = kept.iter().map(|v| (v - m).powi(2)).sum::<f64>() / kept.len() as f64;
    (m, var.sqrt())
}

/// Samples the 24 patches of a ColorChecker Classic in `image` whose patch
/// grid has the four `corners` (see the module docs for order and
/// coordinates). Errors: a corner outside the image (naming it), corners in
/// the wrong order, a patch covering fewer than [`MIN_PIXELS`] pixels,
/// non-finite pixels, clipped patches (all named at once).
pub fn sample_patches(
    image: &ImageRef,
    corners: [[f64; 2]; 4],
    options: &SampleOptions,
) -> Result<Vec<PatchSample>, ColourError> {
    options.validate()?;
    ImageRef::new(image.width, image.height, image.data)?;
    let (w, h) = (image.width as f64, image.height as f64);
    for (i, c) in corners.iter().enumerate() {
        if !(c[0] >= 0.0 && c[0] <= w && c[1] >= 0.0 && c[1] <= h) {
            return Err(ColourError::CornerOutside {
                corner: i + 1,
                x: c[0],
                y: c[1],
                width: image.width,
                height: image.height,
            });
        }
    }
    let hom = Homography::from_corners(corners)?;
    let names = colorchecker_2014();
    let mut samples = Vec::with_capacity(ROWS * COLS);
    let mut clipped = Vec::new();
    for (index, patch) in names.iter().enumerate().take(ROWS * COLS) {
        let [u0, v0, u1, v1] = options.sample_square(index);
        let outline = [hom.map(u0, v0), hom.map(u1, v0), hom.map(u1, v1), hom.map(u0, v1)];
        let xmin = outline.iter().map(|p| p[0]).fold(f64::INFINITY, f64::min).floor().max(0.0) as usize;
        let xmax = (outline.iter().map(|p| p[0]).fold(f64::NEG_INFINITY, f64::max).ceil() as usize).min(image.width);
        let ymin = outline.iter().map(|p| p[1]).fold(f64::INFINITY, f64::min).floor().max(0.0) as usize;
        let ymax = (outline.iter().map(|p| p[1]).fold(f64::NEG_INFINITY, f64::max).ceil() as usize).min(image.height);
        let mut channels: [Vec<f64>; 3] = Default::default();
        let mut n_clipped = 0usize;
        let mut non_finite = 0usize;
        for y in ymin..ymax {
            for x in xmin..xmax {
                let [u, v] = hom.unmap(x as f64 + 0.5, y as f64 + 0.5);
                if !(u >= u0 && u <= u1 && v >= v0 && v <= v1) {
                    continue;
                }
                let p = image.pixel(x, y);
                if p.iter().any(|c| !c.is_finite()) {
                    non_finite += 1;
                    continue;
                }
                if options.clip_level.is_some_and(|level| p.iter().any(|c| f64::from(*c) >= level)) {
                    n_clipped += 1;
                }
                for k in 0..3 {
                    channels[k].push(f64::from(p[k]));
                }
            }
        }
        let name = patch.name;
        if non_finite > 0 {
            return Err(ColourError::Invalid {
                what: format!("patch {} ({name})", index + 1),
                reason: format!("{non_finite} of its pixels are NaN or infinite"),
            });
        }
        let pixels = channels[0].len();
        if pixels < MIN_PIXELS {
            return Err(ColourError::Invalid {
                what: format!("patch {} ({name})", index + 1),
                reason: format!(
                    "its sample area covers {pixels} pixel(s), fewer than {MIN_PIXELS}: the chart is too small in the image or the corners are wrong"
                ),
            });
        }
        let clipped_fraction = n_clipped as f64 / pixels as f64;
        if clipped_fraction > options.max_clipped_fraction {
            clipped.push(ClippedPatch { patch: index + 1, name, fraction: clipped_fraction });
        }
        let mut mean = [0.0; 3];
        let mut std_dev = [0.0; 3];
        for k in 0..3 {
            (mean[k], std_dev[k]) = trimmed_mean(&mut channels[k], options.trim_fraction);
        }
        samples.push(PatchSample { patch: index + 1, name, mean, std_dev, pixels, clipped_fraction, outline });
    }
    if !clipped.is_empty() {
        return Err(ColourError::ClippedPatches { patches: clipped, level: options.clip_level.unwrap_or(f64::NAN) });
    }
    Ok(samples)
}

/// A warning when the neutral row (patches 19 → 24, white → black) does not
/// get darker from left to right — the usual sign of corners given in the
/// wrong order or a chart upside down. `None` when it looks right.
pub fn neutral_ramp_warning(samples: &[PatchSample]) -> Option<String> {
    if samples.len() != ROWS * COLS {
        return None;
    }
    let lum: Vec<f64> = samples[18..24].iter().map(|s| s.mean.iter().sum::<f64>()).collect();
    if lum.windows(2).all(|w| w[0] > w[1]) {
        return None;
    }
    // An inverted image (a negative, or values multiplied by −1) runs
    // against the chart's lightness on all 24 patches, not only on the
    // neutral row as corners in the wrong order do.
    let all: Vec<f64> = samples.iter().map(|s| s.mean.iter().sum::<f64>()).collect();
    let reference: Vec<f64> = crate::data::colorchecker_2014().iter().map(|p| p.xyy[2]).collect();
    let r = correlation(&all, &reference);
    if all.iter().all(|v| *v < 0.0) {
        Some(format!(
            "every patch is negative (R+G+B from {:.3} to {:.3}): the image is inverted (its values multiplied by −1), \
             not a chart with its corners in the wrong order",
            all.iter().copied().fold(f64::INFINITY, f64::min),
            all.iter().copied().fold(f64::NEG_INFINITY, f64::max)
        ))
    } else if r < -INVERTED_CORRELATION {
        Some(format!(
            "the patches' lightness runs against the chart's on all 24 patches (correlation {r:.2} with the reference \
             Y): the image is inverted (a negative), not a chart with its corners in the wrong order"
        ))
    } else {
        Some(format!(
            "the neutral row (patches 19–24) does not get darker from white to black (R+G+B = {}); check the order of the corners: top-left is the dark-skin corner, bottom-left the white one",
            lum.iter().map(|v| format!("{v:.3}")).collect::<Vec<_>>().join(", ")
        ))
    }
}

/// The correlation below −this between the patches' R+G+B and the chart's
/// reference Y that says an image is inverted ([`neutral_ramp_warning`]).
/// Corners in a wrong order give no lower than −0.52 on the reference values
/// themselves (mirrored left–right −0.51, upside down −0.39, turned 180°
/// +0.14): the rows' lightness is not symmetric.
pub const INVERTED_CORRELATION: f64 = 0.8;

/// Pearson's correlation of `a` and `b` (same length); 0 when either is constant.
fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len()) as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        ab += (x - ma) * (y - mb);
        aa += (x - ma) * (x - ma);
        bb += (y - mb) * (y - mb);
    }
    if aa > 0.0 && bb > 0.0 {
        ab / (aa * bb).sqrt()
    } else {
        0.0
    }
}

/// Draws a synthetic chart: patch k (0-based, chart order) filled with
/// `patches[k]` over its whole square (gaps as in `options.gap_ratio`),
/// `background` elsewhere, in perspective through `corners`; interleaved RGB
/// `f32`, `width × height`. For tests and demonstrations of the sampling.
pub fn draw_chart(
    width: usize,
    height: usize,
    corners: [[f64; 2]; 4],
    patches: &[[f64; 3]],
    options: &SampleOptions,
    background: [f32; 3],
) -> Result<Vec<f32>, ColourError> {
    if patches.len() != ROWS * COLS {
        return Err(ColourError::Length {
            what: "chart patch colours".into(),
            expected: ROWS * COLS,
            got: patches.len(),
        });
    }
    options.validate()?;
    let hom = Homography::from_corners(corners)?;
    let g = options.gap_ratio;
    let (wu, wv) = (COLS as f64 + (COLS - 1) as f64 * g, ROWS as f64 + (ROWS - 1) as f64 * g);
    let mut data = background.repeat(width * height);
    for y in 0..height {
        for x in 0..width {
            let [u, v] = hom.unmap(x as f64 + 0.5, y as f64 + 0.5);
            let (su, sv) = (u * wu, v * wv);
            let (col, row) = ((su / (1.0 + g)).floor(), (sv / (1.0 + g)).floor());
            let inside = (0.0..COLS as f64).contains(&col)
                && (0.0..ROWS as f64).contains(&row)
                && su - col * (1.0 + g) < 1.0
                && sv - row * (1.0 + g) < 1.0;
            if inside {
                let c = patches[row as usize * COLS + col as usize];
                let i = 3 * (y * width + x);
                for k in 0..3 {
                    data[i + k] = c[k] as f32;
                }
            }
        }
    }
    Ok(data)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A synthetic chart: patch k (0-based) has value (k+1)/100 in every channel.
    fn synthetic(width: usize, height: usize, corners: [[f64; 2]; 4], opts: &SampleOptions) -> Vec<f32> {
        let patches: Vec<[f64; 3]> = (0..24).map(|k| [(k + 1) as f64 / 100.0; 3]).collect();
        draw_chart(width, height, corners, &patches, opts, [0.005; 3]).unwrap()
    }

    #[test]
    fn an_inverted_chart_is_said_to_be_inverted_not_in_the_wrong_order() {
        let y: Vec<f64> = crate::data::colorchecker_2014().iter().map(|p| p.xyy[2]).collect();
        let samples = |v: &[f64]| -> Vec<PatchSample> {
            v.iter()
                .enumerate()
                .map(|(i, y)| PatchSample {
                    patch: i + 1,
                    name: "",
                    mean: [*y / 3.0; 3],
                    std_dev: [0.0; 3],
                    pixels: 100,
                    clipped_fraction: 0.0,
                    outline: [[0.0; 2]; 4],
                })
                .collect()
        };
        assert!(neutral_ramp_warning(&samples(&y)).is_none());
        let negative: Vec<f64> = y.iter().map(|v| -v).collect();
        let w = neutral_ramp_warning(&samples(&negative)).unwrap();
        assert!(w.contains("inverted") && w.contains("negative") && !w.contains("check the order"), "{w}");
        let negated: Vec<f64> = y.iter().map(|v| 1.0 - v).collect();
        let w = neutral_ramp_warning(&samples(&negated)).unwrap();
        assert!(w.contains("inverted") && !w.contains("check the order"), "{w}");
        // Mirrored left–right (corners in the wrong order): blamed on the corners.
        let mirrored: Vec<f64> = y.chunks(COLS).flat_map(|r| r.iter().rev().copied()).collect();
        let w = neutral_ramp_warning(&samples(&mirrored)).unwrap();
        assert!(w.contains("check the order") && !w.contains("inverted"), "{w}");
    }

    #[test]
    fn samples_every_patch_of_a_perspective_chart() {
        let opts = SampleOptions::default();
        let corners = [[30.0, 20.0], [270.0, 35.0], [250.0, 190.0], [40.0, 170.0]];
        let data = synthetic(300, 210, corners, &opts);
        let img = ImageRef::new(300, 210, &data).unwrap();
        let s = sample_patches(&img, corners, &opts).unwrap();
        for (k, p) in s.iter().enumerate() {
            assert!((p.mean[0] - (k + 1) as f64 / 100.0).abs() < 1e-6, "patch {}: {:?}", k + 1, p.mean);
            assert_eq!(p.std_dev[1], 0.0);
            assert!(p.pixels > 50, "{}", p.pixels);
        }
        assert!(neutral_ramp_warning(&s).is_some(), "synthetic ramp gets brighter");
    }

    #[test]
    fn trimmed_mean_ignores_outliers() {
        let mut v: Vec<f64> = (0..20).map(|_| 0.5).collect();
        v[3] = 100.0;
        v[9] = -100.0;
        assert_eq!(trimmed_mean(&mut v, 0.1).0, 0.5);
        assert_eq!(trimmed_mean(&mut [0.25], 0.4).0, 0.25);
    }

    #[test]
    fn corner_errors() {
        let data = vec![0.5f32; 100 * 80 * 3];
        let img = ImageRef::new(100, 80, &data).unwrap();
        let opts = SampleOptions::default();
        let e = sample_patches(&img, [[0.0, 0.0], [120.0, 0.0], [100.0, 80.0], [0.0, 80.0]], &opts).unwrap_err();
        assert!(matches!(e, ColourError::CornerOutside { corner: 2, .. }), "{e}");
        assert!(e.to_string().contains("100 × 80"), "{e}");
        let anticlockwise = [[0.0, 0.0], [0.0, 80.0], [100.0, 80.0], [100.0, 0.0]];
        assert!(sample_patches(&img, anticlockwise, &opts).unwrap_err().to_string().contains("anticlockwise"));
        let crossed = [[0.0, 0.0], [100.0, 80.0], [100.0, 0.0], [0.0, 80.0]];
        assert!(sample_patches(&img, crossed, &opts).unwrap_err().to_string().contains("convex"));
        let nan = [[f64::NAN, 0.0], [100.0, 0.0], [100.0, 80.0], [0.0, 80.0]];
        assert!(sample_patches(&img, nan, &opts).is_err());
        let tiny = [[0.0, 0.0], [3.0, 0.0], [3.0, 2.0], [0.0, 2.0]];
        assert!(sample_patches(&img, tiny, &opts).unwrap_err().to_string().contains("too small"));
        assert!(ImageRef::new(10, 10, &data).is_err());
    }

    #[test]
    fn clipped_and_non_finite_patches_are_named() {
        let opts = SampleOptions::default();
        let corners = [[0.0, 0.0], [120.0, 0.0], [120.0, 80.0], [0.0, 80.0]];
        let mut data = synthetic(120, 80, corners, &opts);
        // Saturate the white patch (19) and the orange (7) by overwriting their centres.
        let hom = Homography::from_corners(corners).unwrap();
        for idx in [6usize, 18] {
            let [u0, v0, u1, v1] = opts.sample_square(idx);
            let [x0, y0] = hom.map(u0, v0);
            let [x1, y1] = hom.map(u1, v1);
            for y in y0 as usize..=y1 as usize {
                for x in x0 as usize..=x1 as usize {
                    let i = 3 * (y * 120 + x);
                    data[i] = 1.0;
                }
            }
        }
        let img = ImageRef::new(120, 80, &data).unwrap();
        let e = sample_patches(&img, corners, &opts).unwrap_err().to_string();
        assert!(e.contains("7 (orange)") && e.contains("19 (white 9.5 (.05 D))"), "{e}");
        // Without the check they are sampled.
        let no_check = SampleOptions { clip_level: None, ..opts.clone() };
        assert!(sample_patches(&img, corners, &no_check).is_ok());
        data[3 * (9 * 120 + 9)] = f32::NAN; // inside patch 1's sample area
        let img = ImageRef::new(120, 80, &data).unwrap();
        let e = sample_patches(&img, corners, &no_check).unwrap_err().to_string();
        assert!(e.contains("NaN") && e.contains("patch 1 (dark skin)"), "{e}");
    }
}
