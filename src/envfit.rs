//! Environment radiance scale from the empty checkerboard (docs/method.md#env-scale): the HDR
//! environment's radiance is multiplied by a factor k so that the rendered
//! empty board matches the photographed one.
//!
//! The board is lit by the environment only, so a render R of the empty
//! board (no object) is linear in the environment's scale: the photo P ≈ k·R.
//! Over the board pixels 𝓑 (every pixel whose four corners see the board's
//! squares, margin excluded) and the channels c, k is the ratio of sums
//!
//! k = Σ_{p∈𝓑,c} P_pc / Σ_{p∈𝓑,c} R_pc,
//!
//! and per channel the same sums over one channel (k_R, k_G, k_B). The ratio
//! of sums is unchanged by anything that moves light between neighbouring
//! pixels without creating or losing it — lens blur, demosaicing, a pixel of
//! misregistration — where the least-squares slope Σ R·P / Σ R² is not: on
//! the `make demo` board (320 × 240 px, squares of 3–8 px, a Bayer capture
//! developed back) least squares gave 1.661 with Malvar–He–Cutler
//! demosaicing (which sharpens) and 1.513 with bilinear (which blurs) for a
//! true 1.600, the ratio 1.597 and 1.609. Monte Carlo noise in R does not bias it beyond
//! second order (the relative variance of Σ R over thousands of pixels,
//! ≪ 10⁻⁴). The residual is the root mean square of P − k·R over 𝓑 and the
//! channels (in the photo's units), reported also relative to the RMS of P;
//! `render_noise_rms` = k·√(mean V), with V the variance of the render's
//! pixel means, is the part of that residual the render's own noise explains.
//!
//! ```
//! use lucent::envfit::fit_scale;
//! // A "photo" that is exactly 2.5 × the render on four board pixels.
//! let render = vec![[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.2, 0.2, 0.2], [0.8, 0.1, 0.05]];
//! let photo: Vec<[f64; 3]> = render.iter().map(|p| p.map(|v| 2.5 * v)).collect();
//! let fit = fit_scale(&render, &vec![[0.0; 3]; 4], &photo, &[true; 4]).unwrap();
//! assert!((fit.scale - 2.5).abs() < 1e-12 && fit.residual_rms < 1e-12);
//! ```

use crate::scene::SceneFile;
use lucent_render::camera::Camera;
use lucent_render::tracer::Board;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use thiserror::Error;

/// Why no scale could be fitted.
#[derive(Debug, Error)]
pub enum FitError {
    #[error("photo is {photo_w}×{photo_h} but the render is {render_w}×{render_h}: render at the photo's size")]
    Size { photo_w: usize, photo_h: usize, render_w: usize, render_h: usize },
    #[error("no board pixels: the board is not in view of the camera (or the mask is empty)")]
    EmptyMask,
    #[error("photo pixel ({x}, {y}) channel {channel} is {value}: NaN and infinities cannot be fitted")]
    NonFinite { x: usize, y: usize, channel: usize, value: f64 },
    #[error("the render of the board is black ({what}): no light reaches the board, no scale can match it")]
    Black { what: String },
    #[error(
        "the photo of the board is black or negative ({what}): a scale must be > 0; give a linear photo of the lit \
         board"
    )]
    DarkPhoto { what: String },
    #[error("the scene has no [board]: the environment scale is fitted over the board's pixels")]
    NoBoard,
}

/// The files of `lucent env fit-scale` in its output folder, each name
/// spelled here once: the render of the empty board (`exr`), the scene with
/// the fitted scale (`toml`) and the [`FitReport`] (`json`). Written by the
/// command, read by `lucent run`'s planning and report.
///
/// ```
/// use lucent::envfit::EnvScaleFiles;
/// let f = EnvScaleFiles::in_dir(std::path::Path::new("out/env-scale/s1"));
/// assert_eq!(f.json, std::path::Path::new("out/env-scale/s1/env_scale.json"));
/// ```
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EnvScaleFiles {
    pub exr: PathBuf,
    pub toml: PathBuf,
    pub json: PathBuf,
}

impl EnvScaleFiles {
    /// The file names.
    pub const NAMES: [&'static str; 3] = ["board_render.exr", "scene.toml", "env_scale.json"];

    /// The files of the fit whose output folder is `dir`.
    pub fn in_dir(dir: &Path) -> Self {
        let [exr, toml, json] = Self::NAMES.map(|n| dir.join(n));
        Self { exr, toml, json }
    }
}

/// `env_scale.json` of `lucent env fit-scale`: the fit and what it was
/// made from; written by the command and read back by the report of
/// `lucent run`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FitReport {
    pub lucent_version: String,
    pub scene: String,
    pub photo: String,
    pub mask: Option<String>,
    pub per_channel: bool,
    pub spp: u32,
    pub seed: u64,
    pub render_wall_s: f64,
    pub previous_scale: f64,
    pub new_scale: f64,
    /// Set when --per-channel wrote a constant environment per channel.
    pub new_constant: Option<[f64; 3]>,
    pub fit: ScaleFit,
    pub method: String,
}

/// The fitted scale and how well it fits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ScaleFit {
    /// k over all channels (multiply the environment's radiance by it).
    pub scale: f64,
    /// k_R, k_G, k_B fitted per channel.
    pub scale_per_channel: [f64; 3],
    /// RMS of P − k·R over the board pixels and channels, photo units.
    pub residual_rms: f64,
    /// The same per channel with the channel's own k_c.
    pub residual_rms_per_channel: [f64; 3],
    /// residual_rms / RMS(P) over the same pixels.
    pub relative_residual: f64,
    /// k·√(mean V): the residual the render's noise alone would leave.
    pub render_noise_rms: f64,
    /// Number of board pixels used.
    pub pixels: usize,
}

/// Scale of `render` (means, with the variance of each mean)
/// against `photo` over the pixels where `mask` is true (see the module doc).
pub fn fit_scale(
    render: &[[f64; 3]],
    variance: &[[f64; 3]],
    photo: &[[f64; 3]],
    mask: &[bool],
) -> Result<ScaleFit, FitError> {
    let n = render.len().min(variance.len()).min(photo.len()).min(mask.len());
    let (mut sp, mut sr) = ([0.0f64; 3], [0.0f64; 3]);
    let (mut pp, mut vv) = ([0.0f64; 3], 0.0f64);
    let mut pixels = 0usize;
    for i in (0..n).filter(|&i| mask[i]) {
        pixels += 1;
        for c in 0..3 {
            let (r, p, v) = (render[i][c], photo[i][c], variance[i][c].max(0.0));
            sp[c] += p;
            sr[c] += r;
            pp[c] += p * p;
            vv += if v.is_finite() { v } else { 0.0 };
        }
    }
    if pixels == 0 {
        return Err(FitError::EmptyMask);
    }
    let positive = |x: f64| x.partial_cmp(&0.0) == Some(std::cmp::Ordering::Greater);
    let total_r: f64 = sr.iter().sum();
    if !positive(total_r) {
        return Err(FitError::Black { what: format!("Σ R = {total_r:e} over {pixels} pixels") });
    }
    // A scale is a positive factor: a photo whose board is black, or
    // negative on the whole, has none to give (it is not a linear photo of a
    // lit board).
    let total_p: f64 = sp.iter().sum();
    if !positive(total_p) {
        return Err(FitError::DarkPhoto { what: format!("Σ P = {total_p:e} over {pixels} pixels") });
    }
    let scale = total_p / total_r;
    let mut per = [0.0; 3];
    for c in 0..3 {
        if !positive(sr[c]) {
            return Err(FitError::Black { what: format!("channel {c}: Σ R = {:e}", sr[c]) });
        }
        if !positive(sp[c]) {
            return Err(FitError::DarkPhoto { what: format!("channel {c}: Σ P = {:e}", sp[c]) });
        }
        per[c] = sp[c] / sr[c];
    }
    let (mut se, mut se_c) = (0.0, [0.0; 3]);
    for i in (0..n).filter(|&i| mask[i]) {
        for c in 0..3 {
            se += (photo[i][c] - scale * render[i][c]).powi(2);
            se_c[c] += (photo[i][c] - per[c] * render[i][c]).powi(2);
        }
    }
    let m = pixels as f64;
    let residual_rms = (se / (3.0 * m)).sqrt();
    let p_rms = (pp.iter().sum::<f64>() / (3.0 * m)).sqrt();
    Ok(ScaleFit {
        scale,
        scale_per_channel: per,
        residual_rms,
        residual_rms_per_channel: se_c.map(|s| (s / m).sqrt()),
        relative_residual: if p_rms > 0.0 { residual_rms / p_rms } else { f64::NAN },
        render_noise_rms: scale * (vv / (3.0 * m)).sqrt(),
        pixels,
    })
}

/// Checks a photo (interleaved RGB, `width` × `height`) against the render size and converts it.
pub fn photo_pixels(
    data: &[f32],
    width: usize,
    height: usize,
    render_w: usize,
    render_h: usize,
) -> Result<Vec<[f64; 3]>, FitError> {
    if (width, height) != (render_w, render_h) {
        return Err(FitError::Size { photo_w: width, photo_h: height, render_w, render_h });
    }
    let mut out = Vec::with_capacity(width * height);
    for (i, px) in data.chunks_exact(3).enumerate() {
        let v = [f64::from(px[0]), f64::from(px[1]), f64::from(px[2])];
        if let Some(c) = v.iter().position(|x| !x.is_finite()) {
            return Err(FitError::NonFinite { x: i % width, y: i / width, channel: c, value: v[c] });
        }
        out.push(v);
    }
    Ok(out)
}

/// The board pixels: those whose four corner rays all meet the board's
/// squares (the margin excluded), row-major. Pixels the board is seen
/// through at a grazing angle from behind are excluded too.
pub fn board_mask(camera: &Camera, board: &Board) -> Vec<bool> {
    let normal = board.u.cross(board.v);
    let (wu, wv) = (board.columns as f64 * board.square_m, board.rows as f64 * board.square_m);
    let hits = |i: usize, j: usize, u: [f64; 2]| {
        let (o, d) = camera.ray(i, j, u);
        let denom = d.dot(normal);
        if denom.abs() < 1e-12 {
            return false;
        }
        let t = (board.origin - o).dot(normal) / denom;
        if t <= 0.0 {
            return false;
        }
        let q = o + t * d - board.origin;
        let (a, b) = (q.dot(board.u), q.dot(board.v));
        (0.0..=wu).contains(&a) && (0.0..=wv).contains(&b)
    };
    let (w, h) = (camera.width, camera.height);
    let mut mask = vec![false; w * h];
    for j in 0..h {
        for i in 0..w {
            mask[j * w + i] = [[0.0, 0.0], [1.0, 0.0], [0.0, 1.0], [1.0, 1.0]].iter().all(|&u| hits(i, j, u));
        }
    }
    mask
}

/// The scene without its object and material: the empty board.
pub fn empty_board(file: &SceneFile) -> Result<SceneFile, FitError> {
    if file.board.is_none() {
        return Err(FitError::NoBoard);
    }
    let mut f = file.clone();
    f.object = None;
    f.material = None;
    Ok(f)
}

fn absolute(dir: &Path, p: &mut Option<PathBuf>) {
    if let Some(q) = p
        && q.is_relative()
    {
        *q = dir.join(&*q);
    }
}

/// The scene file with every relative path made relative to `dir` (the
/// original file's folder) joined, so a copy written elsewhere still finds
/// its inputs. Paths are made absolute when `dir` is.
pub fn with_paths_from(file: &SceneFile, dir: &Path) -> SceneFile {
    let mut f = file.clone();
    absolute(dir, &mut f.camera.scene_json);
    absolute(dir, &mut f.camera.camera_json);
    if let Some(o) = &mut f.object {
        absolute(dir, &mut o.mesh);
    }
    if let Some(m) = &mut f.material {
        absolute(dir, &mut m.recipe);
    }
    if let Some(b) = &mut f.board {
        absolute(dir, &mut b.even_spectrum);
        absolute(dir, &mut b.odd_spectrum);
        absolute(dir, &mut b.texture);
    }
    absolute(dir, &mut f.environment.map);
    f
}

/// The scene file's folder as an absolute path (for [`with_paths_from`]).
pub fn scene_dir(path: &Path) -> PathBuf {
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let dir = if dir.as_os_str().is_empty() { PathBuf::from(".") } else { dir };
    std::path::absolute(&dir).unwrap_or(dir)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_in_the_render_does_not_bias_the_scale() {
        // R̂ = R + noise with V/R² = 0.25: a least-squares slope would be
        // biased low by 1/(1 + V/R²) = 1/1.25; the ratio of sums is not.
        let mut state = 12345u64;
        let mut normal = || {
            // Box–Muller from a 64-bit LCG.
            let mut u = || {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
            };
            (-2.0 * u().ln()).sqrt() * (std::f64::consts::TAU * u()).cos()
        };
        let n = 40_000;
        let truth = 1.7;
        let r_true = 0.2;
        let v: f64 = 0.01; // σ = 0.1: V/R² = 0.25
        let render: Vec<[f64; 3]> = (0..n).map(|_| [0; 3].map(|_| r_true + v.sqrt() * normal())).collect();
        let photo: Vec<[f64; 3]> = vec![[truth * r_true; 3]; n];
        let fit = fit_scale(&render, &vec![[v; 3]; n], &photo, &vec![true; n]).unwrap();
        assert!((fit.scale - truth).abs() < 0.005, "{fit:?}");
        let slope = render.iter().zip(&photo).map(|(r, p)| r[0] * p[0]).sum::<f64>()
            / render.iter().map(|r| r[0] * r[0]).sum::<f64>();
        assert!((slope - truth / 1.25).abs() < 0.02, "the least-squares slope {slope} is biased");
        // The residual is the render noise scaled by k.
        assert!((fit.residual_rms / fit.render_noise_rms - 1.0).abs() < 0.03, "{fit:?}");
    }

    #[test]
    fn blur_in_the_photo_does_not_bias_the_scale() {
        // A 1-D checker of 3-pixel squares (periodic), photographed through a
        // [1 2 1]/4 blur at scale 2: the ratio of sums is exact, the
        // least-squares slope is not.
        let n = 600;
        let render: Vec<[f64; 3]> = (0..n).map(|i| [if (i / 3) % 2 == 0 { 0.9 } else { 0.05 }; 3]).collect();
        let photo: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let (a, b, c) = (render[(i + n - 1) % n][0], render[i][0], render[(i + 1) % n][0]);
                [2.0 * (a + 2.0 * b + c) / 4.0; 3]
            })
            .collect();
        let fit = fit_scale(&render, &vec![[0.0; 3]; n], &photo, &vec![true; n]).unwrap();
        assert!((fit.scale - 2.0).abs() < 1e-12, "{fit:?}");
        let slope = render.iter().zip(&photo).map(|(r, p)| r[0] * p[0]).sum::<f64>()
            / render.iter().map(|r| r[0] * r[0]).sum::<f64>();
        assert!(slope < 1.9, "least squares would give {slope}");
    }

    #[test]
    fn per_channel_scales_are_recovered() {
        let render: Vec<[f64; 3]> = (0..50).map(|i| [0.1 + 0.01 * i as f64, 0.3, 0.05 * (1 + i % 7) as f64]).collect();
        let k = [1.2, 0.8, 3.0];
        let photo: Vec<[f64; 3]> = render.iter().map(|p| [k[0] * p[0], k[1] * p[1], k[2] * p[2]]).collect();
        let fit = fit_scale(&render, &[[0.0; 3]; 50], &photo, &[true; 50]).unwrap();
        for (c, kc) in k.iter().enumerate() {
            assert!((fit.scale_per_channel[c] - kc).abs() < 1e-12);
            assert!(fit.residual_rms_per_channel[c] < 1e-12);
        }
        assert!(fit.residual_rms > 0.01, "a scalar cannot fit three different scales");
    }

    #[test]
    fn bad_inputs_are_errors() {
        let r = vec![[0.0; 3]; 4];
        assert!(matches!(fit_scale(&r, &r, &r, &[false; 4]), Err(FitError::EmptyMask)));
        assert!(matches!(fit_scale(&r, &r, &r, &[true; 4]), Err(FitError::Black { .. })));
        assert!(matches!(photo_pixels(&[0.0; 12], 2, 2, 3, 2), Err(FitError::Size { .. })));
        let mut d = vec![0.5f32; 12];
        d[7] = f32::NAN;
        let e = photo_pixels(&d, 2, 2, 2, 2).unwrap_err();
        assert!(e.to_string().contains("(0, 1) channel 1"), "{e}");
    }
}
