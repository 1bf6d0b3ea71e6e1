//! Synthetic random surfaces with known slope statistics, for tests, the
//! shipped fixture and `lucent surface synth`.
//!
//! **Beckmann-like**: a Gaussian random surface h = s · c · g · Δ, with
//! g = G_ℓ ∗ white noise (G_ℓ a Gaussian kernel of standard deviation ℓ
//! pixels), c chosen so that the realisation's analytic gradient c ∇g (the
//! exact derivative of the continuous field Σ n_k G_ℓ(x − x_k)) has a mean
//! square of exactly 1 per axis, and s = α/√2. The slopes are Gaussian with
//! variance α²/2 per axis, whose normal distribution is exactly Beckmann's
//! with roughness α.
//!
//! **Trowbridge–Reitz-like**: the same field with a slowly varying local
//! amplitude a(x): h = s · a · c · g · Δ, with a = 1/√E and E
//! exponentially distributed over the map's pixels. A Gaussian slope whose
//! variance is scaled by 1/E (E ~ Exp(1)) is a bivariate Student-t with
//! ν = 2 and scale s, whose density 1/(π α² (1 + |∇h|²/α²)²) (α² = 2 s²) is
//! exactly the GGX slope distribution (Walter et al. 2007; Heitz 2014). E is
//! made exact over the pixels by ranking a second Gaussian field v = G_L ∗
//! noise (L ≫ ℓ, default 8ℓ) and assigning E = −ln((rank + ½)/N). The term
//! g ∇a that a varying amplitude adds to the slope is small when L ≫ ℓ
//! (relative slope variance ≈ 2ℓ²|∇ln a|², a few 10⁻³ for L = 8ℓ).
//!
//! The returned `slope_x`, `slope_y` are the designed slopes s a c ∇g (the
//! tilt and g ∇a not included). An optional plane of tilt τ whose normal
//! has azimuth φ is added: h −= tan τ (x cos φ + y sin φ). Random points can
//! be marked invalid (NaN). All random numbers come from
//! `lucent_render::rng::Rng` streams of (seed, 1…3): the same spec gives the
//! same surface.
//!
//! ```
//! use lucent::surface::synth::{synthesize, SynthSpec};
//! let s = synthesize(&SynthSpec { nx: 64, ny: 48, alpha: 0.01, ..SynthSpec::default() }).unwrap();
//! // Beckmann-like: the designed slopes have mean square α²/2 per axis exactly.
//! let ms: f64 = s.slope_x.iter().zip(&s.slope_y).map(|(x, y)| 0.5 * (x * x + y * y)).sum::<f64>() / (64.0 * 48.0);
//! assert!((ms / (0.01 * 0.01 / 2.0) - 1.0).abs() < 1e-12);
//! assert_eq!((s.map.nx, s.map.ny), (64, 48));
//! ```

use super::error::SurfaceError;
use super::map::HeightMap;
use crate::surface::model::RoughnessModel;
use lucent_render::rng::Rng;
use rayon::prelude::*;

/// What to generate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthSpec {
    pub nx: usize,
    pub ny: usize,
    /// Pitch in metres (the same along x and y).
    pub pitch_m: f64,
    /// Roughness α of the slope distribution.
    pub alpha: f64,
    pub model: RoughnessModel,
    /// Correlation length ℓ of the height field, pixels (σ of the Gaussian kernel).
    pub correlation_px: f64,
    /// Correlation length L of the amplitude field (TR only), pixels.
    pub amplitude_correlation_px: f64,
    pub seed: u64,
    /// Tilt τ of an added plane, radians.
    pub tilt_rad: f64,
    /// Azimuth φ of the added plane's normal, radians from +x towards +y.
    pub tilt_azimuth_rad: f64,
    /// Fraction of points marked invalid at random.
    pub invalid_fraction: f64,
}

impl Default for SynthSpec {
    fn default() -> Self {
        SynthSpec {
            nx: 256,
            ny: 256,
            pitch_m: 0.871e-6,
            alpha: 0.0084,
            model: RoughnessModel::Beckmann,
            correlation_px: 8.0,
            amplitude_correlation_px: 64.0,
            seed: 1,
            tilt_rad: 0.0,
            tilt_azimuth_rad: 0.0,
            invalid_fraction: 0.0,
        }
    }
}

/// A synthetic surface and its designed slopes.
#[derive(Debug, Clone)]
pub struct Synthetic {
    pub map: HeightMap,
    /// Designed ∂h/∂x per pixel (tilt not included), row-major.
    pub slope_x: Vec<f64>,
    /// Designed ∂h/∂y per pixel.
    pub slope_y: Vec<f64>,
}

fn gaussian_noise(n: usize, seed: u64, stream: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed, stream);
    let mut out = Vec::with_capacity(n + 1);
    while out.len() < n {
        // Box–Muller: two independent standard normals per pair of uniforms.
        let u1 = 1.0 - rng.next_f64();
        let u2 = rng.next_f64();
        let r = (-2.0 * u1.ln()).sqrt();
        let (s, c) = (2.0 * std::f64::consts::PI * u2).sin_cos();
        out.push(r * c);
        out.push(r * s);
    }
    out.truncate(n);
    out
}

/// Gaussian kernel of σ = `l` and its derivative, over ±ceil(4l).
fn kernels(l: f64) -> (isize, Vec<f64>, Vec<f64>) {
    let r = (4.0 * l).ceil() as isize;
    let g: Vec<f64> = (-r..=r).map(|d| (-((d * d) as f64) / (2.0 * l * l)).exp()).collect();
    let dg: Vec<f64> = (-r..=r).zip(&g).map(|(d, g)| -(d as f64) / (l * l) * g).collect();
    (r, g, dg)
}

#[allow(clippy::too_many_arguments)] // the grid, its padding and the two kernels
/// Convolves padded noise (w × h) with separable kernels kx (along x) and ky
/// (along y) and returns the central nx × ny block.
fn convolve(noise: &[f64], w: usize, pad: usize, nx: usize, ny: usize, r: isize, kx: &[f64], ky: &[f64]) -> Vec<f64> {
    let h = noise.len() / w;
    // Along x: rows of the padded grid, columns of the output block only.
    let mut rows = vec![0.0; h * nx];
    rows.par_chunks_mut(nx).enumerate().for_each(|(j, out)| {
        for (i, o) in out.iter_mut().enumerate() {
            let c = (i + pad) as isize;
            let mut s = 0.0;
            for (t, k) in kx.iter().enumerate() {
                s += noise[j * w + (c - (t as isize - r)) as usize] * k;
            }
            *o = s;
        }
    });
    let mut out = vec![0.0; nx * ny];
    out.par_chunks_mut(nx).enumerate().for_each(|(j, o)| {
        let c = (j + pad) as isize;
        for (i, v) in o.iter_mut().enumerate() {
            let mut s = 0.0;
            for (t, k) in ky.iter().enumerate() {
                s += rows[(c - (t as isize - r)) as usize * nx + i] * k;
            }
            *v = s;
        }
    });
    out
}

/// Generates the surface described by `spec` (see the module doc).
pub fn synthesize(spec: &SynthSpec) -> Result<Synthetic, SurfaceError> {
    let bad = |name: &str, v: f64, why: &str| Err(SurfaceError::parameter(name, v, why));
    if spec.nx < 2 || spec.ny < 2 || spec.nx * spec.ny > 64_000_000 {
        return Err(SurfaceError::parameter(
            "size",
            format!("{}x{}", spec.nx, spec.ny),
            "must be from 2 × 2 to 64 Mpixels",
        ));
    }
    if !(spec.pitch_m.is_finite() && spec.pitch_m > 0.0) {
        return bad("pitch-um", spec.pitch_m * 1e6, "must be a positive finite length in µm");
    }
    // The range every command takes (model::check_alpha), and a slope to draw.
    if crate::surface::model::check_alpha(spec.alpha).is_err() || spec.alpha == 0.0 {
        let why = format!("must lie in (0, {}] (0 is a flat surface)", lucent_render::microfacet::MAX_ALPHA);
        return bad("alpha", spec.alpha, &why);
    }
    if !(spec.correlation_px.is_finite() && spec.correlation_px >= 1.0 && spec.correlation_px <= 200.0) {
        return bad("correlation-px", spec.correlation_px, "must lie in [1, 200] pixels");
    }
    if !(spec.amplitude_correlation_px.is_finite() && (1.0..=2000.0).contains(&spec.amplitude_correlation_px)) {
        return bad("amplitude-correlation-px", spec.amplitude_correlation_px, "must lie in [1, 2000] pixels");
    }
    // Said in the degrees the user gives (--tilt-deg), not the spec's radians.
    if !spec.tilt_rad.is_finite() || spec.tilt_rad.abs() >= 1.5 {
        return bad("tilt-deg", spec.tilt_rad.to_degrees(), "must be a finite angle below 85.9° (1.5 rad)");
    }
    if !spec.tilt_azimuth_rad.is_finite() {
        return bad("tilt-azimuth-deg", spec.tilt_azimuth_rad.to_degrees(), "must be a finite angle");
    }
    if !(0.0..1.0).contains(&spec.invalid_fraction) {
        return bad("invalid-fraction", spec.invalid_fraction, "must lie in [0, 1)");
    }
    let (nx, ny) = (spec.nx, spec.ny);
    let (r, g, dg) = kernels(spec.correlation_px);
    let pad = r as usize;
    let (w, h) = (nx + 2 * pad, ny + 2 * pad);
    let noise = gaussian_noise(w * h, spec.seed, 1);
    let field = convolve(&noise, w, pad, nx, ny, r, &g, &g);
    let gx = convolve(&noise, w, pad, nx, ny, r, &dg, &g);
    let gy = convolve(&noise, w, pad, nx, ny, r, &g, &dg);
    let n = (nx * ny) as f64;
    let ms = gx.iter().zip(&gy).map(|(a, b)| 0.5 * (a * a + b * b)).sum::<f64>() / n;
    let c = 1.0 / ms.sqrt();
    let amplitude: Vec<f64> = match spec.model {
        RoughnessModel::Beckmann => vec![1.0; nx * ny],
        RoughnessModel::TrowbridgeReitz => {
            let (ra, ga, _) = kernels(spec.amplitude_correlation_px);
            let pa = ra as usize;
            let wa = nx + 2 * pa;
            let noise2 = gaussian_noise(wa * (ny + 2 * pa), spec.seed, 2);
            let v = convolve(&noise2, wa, pa, nx, ny, ra, &ga, &ga);
            let mut order: Vec<usize> = (0..nx * ny).collect();
            order.sort_by(|&a, &b| v[a].total_cmp(&v[b]));
            let mut a = vec![0.0; nx * ny];
            for (rank, &k) in order.iter().enumerate() {
                let e = -((rank as f64 + 0.5) / n).ln();
                a[k] = 1.0 / e.sqrt();
            }
            a
        }
    };
    let s = spec.alpha / std::f64::consts::SQRT_2;
    let t = spec.tilt_rad.tan();
    let (sa, ca) = spec.tilt_azimuth_rad.sin_cos();
    let mut inval = Rng::new(spec.seed, 3);
    let mut heights = vec![0.0; nx * ny];
    let mut slope_x = vec![0.0; nx * ny];
    let mut slope_y = vec![0.0; nx * ny];
    for j in 0..ny {
        for i in 0..nx {
            let k = j * nx + i;
            let (x, y) = (i as f64 * spec.pitch_m, j as f64 * spec.pitch_m);
            heights[k] = s * amplitude[k] * c * field[k] * spec.pitch_m - t * (x * ca + y * sa);
            slope_x[k] = s * amplitude[k] * c * gx[k];
            slope_y[k] = s * amplitude[k] * c * gy[k];
            if spec.invalid_fraction > 0.0 && inval.next_f64() < spec.invalid_fraction {
                heights[k] = f64::NAN;
            }
        }
    }
    let name = match spec.model {
        RoughnessModel::Beckmann => "Beckmann",
        RoughnessModel::TrowbridgeReitz => "Trowbridge-Reitz",
    };
    let map = HeightMap::new(
        nx,
        ny,
        spec.pitch_m,
        spec.pitch_m,
        heights,
        format!("synthetic {name}-like surface, alpha {}, seed {}", spec.alpha, spec.seed),
    )?;
    Ok(Synthetic { map, slope_x, slope_y })
}
