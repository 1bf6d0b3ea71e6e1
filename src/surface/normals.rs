//! Levelling, per-pixel Gaussian-weighted plane fits → microfacet normals,
//! and the ISO 25178-2 roughness parameters S_q and S_dq.
//!
//! **Global plane** ([`fit_plane`]): least squares z ≈ z̄ + s_x (x − x̄) +
//! s_y (y − ȳ) over all valid points (x, y in metres); tilt = atan(√(s_x² +
//! s_y²)), the normal (−s_x, −s_y, 1)/‖·‖ has azimuth atan2(−s_y, −s_x).
//!
//! **Local planes** ([`plane_fit_normals`]): at pixel (i, j) the plane
//! a + b·u + c·v (u, v the pixel offsets in the window) minimises
//! Σ w(u) w(v) m (h − a − b u − c v)² over the k × k window, with
//! w(u) = exp(−u²/2σ²) and m = 1 for valid points, 0 otherwise (and outside
//! the map). The nine weighted moments Σ w m uᵖ vᵠ and Σ w m h uᵖ vᵠ are
//! separable correlations, computed in two 1-D passes, so the cost is
//! O(k) per pixel and moment, not O(k²). The slopes are ∂h/∂x = b/Δx,
//! ∂h/∂y = c/Δy and the microfacet normal m = (−∂h/∂x, −∂h/∂y, 1)/‖·‖.
//! A pixel gets no normal if it is invalid, if its window's valid points
//! carry less than `min_weight_fraction` of the full window's weight (next to
//! the map's edge or to invalid points), or if its 3 × 3 system is singular.
//! For a surface smooth on the scale of σ the fit's slope is the surface's
//! slope smoothed by a Gaussian of σ: the RMS slope of a Gaussian random
//! surface with correlation length ℓ (Gaussian kernel) is reduced by the
//! factor ≈ ℓ²/(ℓ² + σ²).
//!
//! **S_q** = √(mean (z − z̄)²) over the valid points of the levelled map.
//! **S_dq** = √(mean (Δz/Δx)² + mean (Δz/Δy)²), forward differences between
//! neighbouring valid points, each direction averaged over its own
//! differences (the discretisation of surfalize and of ISO 25178-2's
//! definition on a grid). The RMS slope of the plane-fit normals is
//! reported beside it as `sdq_plane_fit`.
//!
//! ```
//! use lucent::surface::{HeightMap, FitOptions};
//! use lucent::surface::normals::{fit_plane, plane_fit_normals};
//! // A plane rising 0.01 m per m along x: tilt atan(0.01), every normal (−0.01, 0, 1)/‖·‖.
//! let (nx, ny, p) = (40, 30, 1e-6);
//! let h: Vec<f64> = (0..nx * ny).map(|k| 0.01 * (k % nx) as f64 * p).collect();
//! let map = HeightMap::new(nx, ny, p, p, h, "doc").unwrap();
//! assert!((fit_plane(&map).unwrap().tilt_rad() - 0.01f64.atan()).abs() < 1e-12);
//! let field = plane_fit_normals(&map, &FitOptions::default()).unwrap();
//! let n = field.normal(20, 15).unwrap();
//! assert!((n[0] + 0.01 / (1.0001f64).sqrt()).abs() < 1e-9 && n[1].abs() < 1e-9);
//! ```

use super::error::SurfaceError;
use super::map::HeightMap;
use super::options::FitOptions;
use rayon::prelude::*;

/// The least-squares plane z = mean + slope_x (x − x_c) + slope_y (y − y_c),
/// x, y in metres from the first point, (x_c, y_c) the centroid of the valid points.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Plane {
    pub mean_m: f64,
    pub slope_x: f64,
    pub slope_y: f64,
    pub x_c_m: f64,
    pub y_c_m: f64,
}

impl Plane {
    /// Angle between the plane's normal and z, radians.
    pub fn tilt_rad(&self) -> f64 {
        self.slope_x.hypot(self.slope_y).atan()
    }

    /// Azimuth of the normal's horizontal part, radians from +x towards +y.
    pub fn normal_azimuth_rad(&self) -> f64 {
        (-self.slope_y).atan2(-self.slope_x)
    }

    /// The plane's height at (x, y) in metres.
    pub fn at(&self, x_m: f64, y_m: f64) -> f64 {
        self.mean_m + self.slope_x * (x_m - self.x_c_m) + self.slope_y * (y_m - self.y_c_m)
    }
}

/// Fits the least-squares plane to the valid points.
pub fn fit_plane(map: &HeightMap) -> Result<Plane, SurfaceError> {
    // Sums over valid points in pixel units, accumulated per row in parallel.
    let sums = (0..map.ny)
        .into_par_iter()
        .map(|j| {
            let mut s = [0.0f64; 6]; // n, Σi, Σj, Σh (for centroids)
            for i in 0..map.nx {
                let h = map.at(i, j);
                if h.is_finite() {
                    s[0] += 1.0;
                    s[1] += i as f64;
                    s[2] += j as f64;
                    s[3] += h;
                }
            }
            s
        })
        .reduce(|| [0.0; 6], |a, b| std::array::from_fn(|k| a[k] + b[k]));
    let n = sums[0];
    if n < 1.0 {
        return Err(SurfaceError::AllInvalid { origin: map.origin.clone(), points: map.nx * map.ny });
    }
    let (ic, jc, hc) = (sums[1] / n, sums[2] / n, sums[3] / n);
    // Centred second moments.
    let m = (0..map.ny)
        .into_par_iter()
        .map(|j| {
            let mut s = [0.0f64; 5]; // Σuu, Σuv, Σvv, Σuh, Σvh
            let v = j as f64 - jc;
            for i in 0..map.nx {
                let h = map.at(i, j);
                if h.is_finite() {
                    let u = i as f64 - ic;
                    let dh = h - hc;
                    s[0] += u * u;
                    s[1] += u * v;
                    s[2] += v * v;
                    s[3] += u * dh;
                    s[4] += v * dh;
                }
            }
            s
        })
        .reduce(|| [0.0; 5], |a, b| std::array::from_fn(|k| a[k] + b[k]));
    let det = m[0] * m[2] - m[1] * m[1];
    let (b, c) = if det > 1e-12 * (m[0] * m[2]).max(f64::MIN_POSITIVE) {
        ((m[3] * m[2] - m[4] * m[1]) / det, (m[4] * m[0] - m[3] * m[1]) / det)
    } else if m[0] > 0.0 {
        // All valid points on one row: only the x slope is defined.
        (m[3] / m[0], 0.0)
    } else if m[2] > 0.0 {
        (0.0, m[4] / m[2])
    } else {
        (0.0, 0.0)
    };
    Ok(Plane {
        mean_m: hc,
        slope_x: b / map.pitch_x_m,
        slope_y: c / map.pitch_y_m,
        x_c_m: ic * map.pitch_x_m,
        y_c_m: jc * map.pitch_y_m,
    })
}

/// The map minus the plane (invalid points stay NaN).
pub fn remove_plane(map: &HeightMap, plane: &Plane) -> HeightMap {
    let mut out = map.clone();
    out.heights_m.par_chunks_mut(map.nx).enumerate().for_each(|(j, row)| {
        let y = j as f64 * map.pitch_y_m;
        for (i, h) in row.iter_mut().enumerate() {
            if h.is_finite() {
                *h -= plane.at(i as f64 * map.pitch_x_m, y);
            }
        }
    });
    out
}

/// S_q, S_dq (ISO 25178-2) and the RMS slope of the plane-fit normals.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Roughness {
    /// Root-mean-square height about the mean, metres.
    pub sq_m: f64,
    /// Arithmetic mean height |z − z̄|, metres.
    pub sa_m: f64,
    /// Root-mean-square gradient from forward differences (dimensionless).
    pub sdq: f64,
    /// Root-mean-square slope √(mean |∇h|²) of the plane-fit normals.
    pub sdq_plane_fit: f64,
}

/// S_q, S_a and S_dq of a map (levelled or not, as given);
/// `sdq_plane_fit` is left 0 (filled in by the pipeline).
pub fn roughness(map: &HeightMap) -> Roughness {
    let valid: Vec<f64> = map.heights_m.iter().copied().filter(|h| h.is_finite()).collect();
    let n = valid.len().max(1) as f64;
    let mean = valid.iter().sum::<f64>() / n;
    let sq = (valid.iter().map(|h| (h - mean).powi(2)).sum::<f64>() / n).sqrt();
    let sa = valid.iter().map(|h| (h - mean).abs()).sum::<f64>() / n;
    let (mut sx, mut nxd, mut sy, mut nyd) = (0.0, 0usize, 0.0, 0usize);
    for j in 0..map.ny {
        for i in 0..map.nx {
            let h = map.at(i, j);
            if !h.is_finite() {
                continue;
            }
            if i + 1 < map.nx {
                let r = map.at(i + 1, j);
                if r.is_finite() {
                    sx += ((r - h) / map.pitch_x_m).powi(2);
                    nxd += 1;
                }
            }
            if j + 1 < map.ny {
                let d = map.at(i, j + 1);
                if d.is_finite() {
                    sy += ((d - h) / map.pitch_y_m).powi(2);
                    nyd += 1;
                }
            }
        }
    }
    let mx = if nxd > 0 { sx / nxd as f64 } else { 0.0 };
    let my = if nyd > 0 { sy / nyd as f64 } else { 0.0 };
    Roughness { sq_m: sq, sa_m: sa, sdq: (mx + my).sqrt(), sdq_plane_fit: 0.0 }
}

/// Per-pixel slopes from the plane fits; NaN where a pixel has no normal.
#[derive(Debug, Clone, PartialEq)]
pub struct NormalField {
    pub nx: usize,
    pub ny: usize,
    /// ∂h/∂x per pixel, row-major.
    pub slope_x: Vec<f64>,
    /// ∂h/∂y per pixel, row-major.
    pub slope_y: Vec<f64>,
    /// Pixels with a normal.
    pub count: usize,
}

impl NormalField {
    /// The unit normal at column i, row j, if that pixel has one.
    pub fn normal(&self, i: usize, j: usize) -> Option<[f64; 3]> {
        let k = j * self.nx + i;
        slope_normal(self.slope_x[k], self.slope_y[k])
    }

    /// All unit normals (pixels without one left out), row-major order.
    pub fn normals(&self) -> Vec<[f64; 3]> {
        self.slope_x.iter().zip(&self.slope_y).filter_map(|(&sx, &sy)| slope_normal(sx, sy)).collect()
    }

    /// √(mean |∇h|²) over the pixels with a normal.
    pub fn rms_slope(&self) -> f64 {
        let (s, n) = self
            .slope_x
            .iter()
            .zip(&self.slope_y)
            .filter(|(x, _)| x.is_finite())
            .fold((0.0, 0usize), |(s, n), (x, y)| (s + x * x + y * y, n + 1));
        if n == 0 {
            0.0
        } else {
            (s / n as f64).sqrt()
        }
    }
}

/// The unit normal (−s_x, −s_y, 1)/‖·‖, or None for NaN slopes.
pub fn slope_normal(sx: f64, sy: f64) -> Option<[f64; 3]> {
    if !(sx.is_finite() && sy.is_finite()) {
        return None;
    }
    let inv = 1.0 / (1.0 + sx * sx + sy * sy).sqrt();
    Some([-sx * inv, -sy * inv, inv])
}

/// Gaussian-weighted least-squares plane at every pixel (see the module doc).
pub fn plane_fit_normals(map: &HeightMap, options: &FitOptions) -> Result<NormalField, SurfaceError> {
    options.validate()?;
    let (nx, ny) = (map.nx, map.ny);
    let r = (options.window_px / 2) as isize;
    let taps: Vec<(isize, f64)> =
        (-r..=r).map(|d| (d, (-(d * d) as f64 / (2.0 * options.sigma_px * options.sigma_px)).exp())).collect();
    let w_full: f64 = taps.iter().map(|t| t.1).sum::<f64>().powi(2);
    // Heights relative to their mean, for conditioning; invalid → weight 0.
    let valid: Vec<f64> = map.heights_m.iter().copied().filter(|h| h.is_finite()).collect();
    let mean = valid.iter().sum::<f64>() / valid.len().max(1) as f64;
    let mask: Vec<f64> = map.heights_m.iter().map(|h| if h.is_finite() { 1.0 } else { 0.0 }).collect();
    let mh: Vec<f64> = map.heights_m.iter().map(|h| if h.is_finite() { h - mean } else { 0.0 }).collect();

    // Pass 1 along x: A0 = Σ w m, A1 = Σ u w m, A2 = Σ u² w m, H0 = Σ w m h, H1 = Σ u w m h.
    let mut pass = vec![[0.0f64; 5]; nx * ny];
    pass.par_chunks_mut(nx).enumerate().for_each(|(j, row)| {
        let base = j * nx;
        for (i, out) in row.iter_mut().enumerate() {
            let mut s = [0.0f64; 5];
            for &(d, w) in &taps {
                let ii = i as isize + d;
                if ii < 0 || ii >= nx as isize {
                    continue;
                }
                let k = base + ii as usize;
                let (m, h) = (mask[k], mh[k]);
                if m == 0.0 {
                    continue;
                }
                let u = d as f64;
                s[0] += w;
                s[1] += u * w;
                s[2] += u * u * w;
                s[3] += w * h;
                s[4] += u * w * h;
            }
            *out = s;
        }
    });

    // Pass 2 along y, then the 3 × 3 solve per pixel.
    let min_w = options.min_weight_fraction * w_full;
    let (px, py) = (map.pitch_x_m, map.pitch_y_m);
    let mut slope_x = vec![f64::NAN; nx * ny];
    let mut slope_y = vec![f64::NAN; nx * ny];
    slope_x.par_chunks_mut(nx).zip(slope_y.par_chunks_mut(nx)).enumerate().for_each(|(j, (sxr, syr))| {
        for i in 0..nx {
            if mask[j * nx + i] == 0.0 {
                continue;
            }
            // S00 S10 S20 S01 S11 S02 T0 Tx Ty
            let mut s = [0.0f64; 9];
            for &(d, w) in &taps {
                let jj = j as isize + d;
                if jj < 0 || jj >= ny as isize {
                    continue;
                }
                let a = &pass[jj as usize * nx + i];
                let v = d as f64;
                s[0] += w * a[0];
                s[1] += w * a[1];
                s[2] += w * a[2];
                s[3] += v * w * a[0];
                s[4] += v * w * a[1];
                s[5] += v * v * w * a[0];
                s[6] += w * a[3];
                s[7] += w * a[4];
                s[8] += v * w * a[3];
            }
            if s[0] < min_w {
                continue;
            }
            let [s00, s10, s20, s01, s11, s02, t0, tx, ty] = s;
            // Symmetric system [[s00 s10 s01] [s10 s20 s11] [s01 s11 s02]] (a b c)ᵀ = (t0 tx ty)ᵀ, by Cramer.
            let det = s00 * (s20 * s02 - s11 * s11) - s10 * (s10 * s02 - s11 * s01) + s01 * (s10 * s11 - s20 * s01);
            if det.is_nan() || det <= 1e-9 * s00 * s20 * s02 {
                continue;
            }
            let db = s00 * (tx * s02 - s11 * ty) - t0 * (s10 * s02 - s11 * s01) + s01 * (s10 * ty - tx * s01);
            let dc = s00 * (s20 * ty - tx * s11) - s10 * (s10 * ty - tx * s01) + t0 * (s10 * s11 - s20 * s01);
            sxr[i] = db / det / px;
            syr[i] = dc / det / py;
        }
    });
    let count = slope_x.iter().filter(|v| v.is_finite()).count();
    if count == 0 {
        return Err(SurfaceError::Data {
            origin: map.origin.clone(),
            reason: format!(
                "no pixel has a complete enough {0} × {0} window of valid points for a plane fit (map {nx} × {ny}, {1} valid points)",
                options.window_px,
                valid.len()
            ),
        });
    }
    Ok(NormalField { nx, ny, slope_x, slope_y, count })
}
