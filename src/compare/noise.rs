//! The twin's error separated from noise: the **model RMSE** of a render R
//! against a photo P whose pixels carry known variances.
//!
//! For independent noise, E[(R − P)²] = (E R − E P)² + var R + var P per
//! pixel and channel, so
//!
//!   d = (R − P)² − var R − var P
//!
//! is an unbiased estimate of the squared model error (E R − E P)² there,
//! and over the included pixels (and channels)
//!
//!   model RMSE = √max(0, mean d),   noise floor = √mean(var R + var P),
//!
//! the noise floor being what the plain RMSE would read for a perfect twin.
//! `var R` is the variance of the render's pixel mean (render.exr's
//! `variance.R/G/B`); `var P` the photo's, when known (else 0: the model
//! RMSE then still contains the photo's noise).
//!
//! **Interval.** Neighbouring pixels are correlated (demosaicing, filters),
//! so the 95 % interval comes from a moving-block bootstrap over square
//! blocks of pixels (Künsch 1989): blocks of `block_px` × `block_px` pixels
//! are drawn with replacement as many times as there are blocks, mean d is
//! recomputed, and the 2.5 and 97.5 percentiles of √max(0, mean d*) over
//! the resamples bound the model RMSE. The resampling is seeded: the same
//! inputs give the same interval.
//!
//! ```
//! use lucent::compare::noise::{model_rmse, NoiseInput};
//! // A render off by 0.1 everywhere with variance 0.01 per pixel: the plain
//! // RMSE of the noise-free difference is 0.1, the floor √0.01 = 0.1.
//! let n = 64 * 64 * 3;
//! let photo = vec![0.5f32; n];
//! let render = vec![0.6f32; n];
//! let var = vec![0.0f32; n];
//! let r = model_rmse(&NoiseInput { width: 64, height: 64, photo: &photo, render: &render,
//!     render_variance: &var, photo_variance: None, include: None }, 8, 200, 1).unwrap();
//! assert!((r.total.model_rmse - 0.1).abs() < 1e-6);
//! assert!(r.total.ci95[0] <= 0.1 + 1e-6 && r.total.ci95[1] >= 0.1 - 1e-6);
//! ```

use serde::{Deserialize, Serialize};

/// Fewer blocks than this make the bootstrap interval unreliable (stated as a note).
pub const MIN_BLOCKS: usize = 30;

/// The model RMSE of one channel (or of all), with its interval and the noise floor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ModelError {
    /// √max(0, mean((R − P)² − var R − var P)), in the images' units.
    pub model_rmse: f64,
    /// 95 % interval of the model RMSE (block bootstrap); [0, 0] when even
    /// the upper end of the squared error's interval is negative (the data
    /// show no model error above the noise).
    pub ci95: [f64; 2],
    /// mean((R − P)² − var R − var P), signed, and its 95 % interval:
    /// the squared model error before the clamp at 0.
    pub squared: f64,
    pub squared_ci95: [f64; 2],
    /// √mean(var R + var P): the RMSE a noise-free-in-expectation twin would show.
    pub noise_floor: f64,
    /// The plain RMSE over the same pixels, for comparison.
    pub rmse: f64,
}

/// `noise` in metrics.json.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct NoiseReport {
    pub definition: String,
    /// Where var R and var P come from.
    pub render_variance: String,
    pub photo_variance: String,
    /// How the photo's variance was made from its RAW noise model (the
    /// sidecar JSON of `lucent colour apply --variance-out`), when known.
    #[serde(default)]
    pub photo_noise: Option<super::photo_noise::PhotoVarianceFile>,
    pub block_px: usize,
    /// Blocks holding included pixels (the bootstrap's sample size: with
    /// fewer than [`MIN_BLOCKS`] the interval is too narrow to trust).
    pub blocks: usize,
    pub resamples: usize,
    pub pixels: usize,
    pub total: ModelError,
    pub r: ModelError,
    pub g: ModelError,
    pub b: ModelError,
}

/// The images of [`model_rmse`]: interleaved RGB, row-major, all of
/// `width × height × 3` values; `include` (if any) of `width × height`.
pub struct NoiseInput<'a> {
    pub width: usize,
    pub height: usize,
    pub photo: &'a [f32],
    pub render: &'a [f32],
    pub render_variance: &'a [f32],
    pub photo_variance: Option<&'a [f32]>,
    pub include: Option<&'a [bool]>,
}

/// Why the model error cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum NoiseError {
    #[error("{what} has {got} values, expected {expected} ({width} × {height} × 3)")]
    Size { what: &'static str, got: usize, expected: usize, width: usize, height: usize },
    #[error("no pixel is included")]
    Empty,
    #[error("{what}: a variance must be finite and ≥ 0 (got {value} at pixel ({x}, {y}))")]
    BadVariance { what: &'static str, value: f32, x: usize, y: usize },
    #[error("block size must be at least 1 pixel and resamples at least 20")]
    Settings,
}

/// Per block: the number of included pixels and the sums of d per channel
/// and of (r − p)², var per channel.
#[derive(Debug, Clone, Copy, Default)]
struct BlockSums {
    n: f64,
    d: [f64; 3],
    sq: [f64; 3],
    var: [f64; 3],
}

/// The model RMSE per channel and over all channels, with 95 % block-bootstrap intervals.
pub fn model_rmse(input: &NoiseInput, block_px: usize, resamples: usize, seed: u64) -> Result<NoiseReport, NoiseError> {
    let (w, h) = (input.width, input.height);
    let expected = w * h * 3;
    let check = |what: &'static str, len: usize| {
        if len == expected {
            Ok(())
        } else {
            Err(NoiseError::Size { what, got: len, expected, width: w, height: h })
        }
    };
    check("photo", input.photo.len())?;
    check("render", input.render.len())?;
    check("render variance", input.render_variance.len())?;
    if let Some(v) = input.photo_variance {
        check("photo variance", v.len())?;
    }
    if let Some(m) = input.include
        && m.len() != w * h
    {
        return Err(NoiseError::Size { what: "mask", got: m.len() * 3, expected, width: w, height: h });
    }
    if block_px == 0 || resamples < 20 {
        return Err(NoiseError::Settings);
    }
    for (what, v) in [("render variance", Some(input.render_variance)), ("photo variance", input.photo_variance)] {
        let Some(v) = v else { continue };
        if let Some(i) = v.iter().position(|x| !(x.is_finite() && *x >= 0.0)) {
            return Err(NoiseError::BadVariance { what, value: v[i], x: (i / 3) % w, y: i / 3 / w });
        }
    }
    let (bw, bh) = (w.div_ceil(block_px), h.div_ceil(block_px));
    let mut blocks = vec![BlockSums::default(); bw * bh];
    for y in 0..h {
        for x in 0..w {
            let p = y * w + x;
            if input.include.is_some_and(|m| !m[p]) {
                continue;
            }
            let b = &mut blocks[(y / block_px) * bw + x / block_px];
            b.n += 1.0;
            for c in 0..3 {
                let i = 3 * p + c;
                let diff = f64::from(input.render[i]) - f64::from(input.photo[i]);
                let var = f64::from(input.render_variance[i]) + input.photo_variance.map_or(0.0, |v| f64::from(v[i]));
                b.sq[c] += diff * diff;
                b.var[c] += var;
                b.d[c] += diff * diff - var;
            }
        }
    }
    blocks.retain(|b| b.n > 0.0);
    if blocks.is_empty() {
        return Err(NoiseError::Empty);
    }
    let totals = sum_blocks(blocks.iter());
    // Bootstrap: mean d per channel and over channels for each resample.
    let mut rng = lucent_render::rng::Rng::new(seed, 0);
    // Signed mean d per resample (the square root is monotone, so its
    // percentiles are the roots of these).
    let mut draws: [Vec<f64>; 4] = Default::default();
    for _ in 0..resamples {
        let picked = (0..blocks.len()).map(|_| &blocks[(rng.next_u64() % blocks.len() as u64) as usize]);
        let s = sum_blocks(picked);
        for (draw, d) in draws.iter_mut().zip(s.d) {
            draw.push(d / s.n);
        }
        draws[3].push((s.d[0] + s.d[1] + s.d[2]) / (3.0 * s.n));
    }
    let interval = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        let at = |q: f64| v[((q * (v.len() - 1) as f64).round() as usize).min(v.len() - 1)];
        [at(0.025), at(0.975)]
    };
    let n = totals.n;
    let error = |d: f64, var: f64, sq: f64, v: &mut Vec<f64>| {
        let ci = interval(v);
        ModelError {
            model_rmse: root(d / n),
            ci95: ci.map(root),
            squared: d / n,
            squared_ci95: ci,
            noise_floor: (var / n).sqrt(),
            rmse: (sq / n).sqrt(),
        }
    };
    let [mut dr, mut dg, mut db, mut dt] = draws;
    let channel = |c: usize, v: &mut Vec<f64>| error(totals.d[c], totals.var[c], totals.sq[c], v);
    let total = error(
        totals.d.iter().sum::<f64>() / 3.0,
        totals.var.iter().sum::<f64>() / 3.0,
        totals.sq.iter().sum::<f64>() / 3.0,
        &mut dt,
    );
    Ok(NoiseReport {
        definition: "model RMSE = sqrt(max(0, mean((R - P)^2 - var R - var P))) over the included pixels; \
                     noise floor = sqrt(mean(var R + var P)); 95 % interval: moving-block bootstrap over square \
                     pixel blocks"
            .into(),
        render_variance: String::new(),
        photo_variance: String::new(),
        photo_noise: None,
        block_px,
        blocks: blocks.len(),
        resamples,
        pixels: n as usize,
        total,
        r: channel(0, &mut dr),
        g: channel(1, &mut dg),
        b: channel(2, &mut db),
    })
}

fn sum_blocks<'a>(blocks: impl Iterator<Item = &'a BlockSums>) -> BlockSums {
    let mut s = BlockSums::default();
    for b in blocks {
        s.n += b.n;
        for c in 0..3 {
            s.d[c] += b.d[c];
            s.sq[c] += b.sq[c];
            s.var[c] += b.var[c];
        }
    }
    s
}

/// √max(0, x).
fn root(x: f64) -> f64 {
    x.max(0.0).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Box–Muller normals from SplitMix64.
    struct Normal(lucent_render::rng::Rng);
    impl Normal {
        fn next(&mut self) -> f64 {
            let (u1, u2) = self.0.next_f64_pair();
            lucent_testkit::normal::box_muller(u1, u2)
        }
    }

    /// A photo and a render of a smooth scene, the render biased by a
    /// pattern of RMS `bias` and both noisy with standard deviation `sigma`
    /// (the render's variance known exactly, the photo's too); returns the
    /// report and the true model RMSE.
    fn synthetic(seed: u64, bias: f64, sigma: f64, w: usize, h: usize) -> (NoiseReport, f64) {
        let mut g = Normal(lucent_render::rng::Rng::new(seed, 1));
        let n = w * h * 3;
        let (mut photo, mut render) = (vec![0f32; n], vec![0f32; n]);
        let mut truth2 = 0.0;
        for i in 0..n {
            let (x, y) = ((i / 3) % w, i / 3 / w);
            let clean = 0.5 + 0.2 * ((x as f64 * 0.3).sin() * (y as f64 * 0.2).cos());
            // ±bias in a checker of 4-pixel squares: RMS exactly `bias`.
            let b = if (x / 4 + y / 4) % 2 == 0 { bias } else { -bias };
            truth2 += b * b;
            photo[i] = (clean + sigma * g.next()) as f32;
            render[i] = (clean + b + sigma * g.next()) as f32;
        }
        let var = vec![(sigma * sigma) as f32; n];
        let input = NoiseInput {
            width: w,
            height: h,
            photo: &photo,
            render: &render,
            render_variance: &var,
            photo_variance: Some(&var),
            include: None,
        };
        (model_rmse(&input, 8, 200, seed ^ 0x9e37).unwrap(), (truth2 / n as f64).sqrt())
    }

    #[test]
    fn interval_covers_the_truth_at_its_stated_rate() {
        // 400 independent pairs: the 95 % interval must cover the true model
        // RMSE 95 % ± 3 % of the time (binomial SD at 400 draws is 1.1 %).
        let runs = 400;
        let covered = (0..runs)
            .filter(|&s| {
                let (r, truth) = synthetic(1000 + s, 0.02, 0.05, 48, 48);
                r.total.ci95[0] <= truth && truth <= r.total.ci95[1]
            })
            .count();
        let rate = covered as f64 / runs as f64;
        assert!((rate - 0.95).abs() <= 0.03, "coverage {rate}");
    }

    #[test]
    fn removes_the_noise_where_the_bias_is_a_fifth_of_it() {
        // Bias 0.01, noise 0.05 per image: the plain RMSE reads ≈ 0.072,
        // the model RMSE must be within 10 % of 0.01.
        let (r, truth) = synthetic(7, 0.01, 0.05, 256, 256);
        assert!(r.total.rmse > 5.0 * truth, "plain RMSE {} vs truth {truth}", r.total.rmse);
        assert!((r.total.model_rmse - truth).abs() < 0.1 * truth, "model {} vs {truth}", r.total.model_rmse);
        assert!((r.total.noise_floor - 0.05 * 2f64.sqrt()).abs() < 1e-6);
        // Per channel a third of the data: within its own interval widened
        // to ≈ ±4 standard errors.
        for ch in [r.r, r.g, r.b] {
            let half = 0.5 * (ch.ci95[1] - ch.ci95[0]);
            assert!(ch.ci95[0] - half <= truth && truth <= ch.ci95[1] + half, "{ch:?} vs {truth}");
        }
    }

    #[test]
    fn bad_inputs_are_refused() {
        let v = vec![0f32; 12];
        let short = vec![0f32; 11];
        let i = NoiseInput {
            width: 2,
            height: 2,
            photo: &v,
            render: &v,
            render_variance: &short,
            photo_variance: None,
            include: None,
        };
        assert!(matches!(model_rmse(&i, 8, 100, 1), Err(NoiseError::Size { what: "render variance", .. })));
        let mut neg = v.clone();
        neg[4] = -1.0;
        let i = NoiseInput {
            width: 2,
            height: 2,
            photo: &v,
            render: &v,
            render_variance: &neg,
            photo_variance: None,
            include: None,
        };
        assert!(matches!(model_rmse(&i, 8, 100, 1), Err(NoiseError::BadVariance { x: 1, y: 0, .. })));
        let none = [false; 4];
        let i = NoiseInput {
            width: 2,
            height: 2,
            photo: &v,
            render: &v,
            render_variance: &v,
            photo_variance: None,
            include: Some(&none),
        };
        assert_eq!(model_rmse(&i, 8, 100, 1), Err(NoiseError::Empty));
    }
}

/// Which of two twins is closer to the photo, from their squared errors
/// with the renders' own variances removed (`paired`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PairedReport {
    pub definition: String,
    /// Side of the square cells whose means are compared, in pixels (1:
    /// pixel by pixel).
    #[serde(default = "super::photo_noise::one")]
    pub cell_px: usize,
    /// Mean over the cells' included pixels and channels of
    /// [(Ā − P̄)² − var Ā] − [(B̄ − P̄)² − var B̄] (bars: means over a cell)
    /// = (model error A)² − (model error B)² at the cells' scale, in
    /// expectation (the photo's noise cancels).
    pub squared_difference: f64,
    /// Its standard error over pixel blocks.
    pub standard_error: f64,
    /// squared_difference / standard_error, referred to Student's t with
    /// blocks − 1 degrees of freedom.
    pub z: f64,
    /// Two-sided p-value of "the twins are equally close".
    pub p_value: f64,
    /// Significance level of the verdict.
    pub alpha: f64,
    /// "A is closer", "B is closer" or "the data cannot tell them apart at this noise".
    pub verdict: String,
    pub blocks: usize,
}

/// The paired comparison of two renders `a`, `b` (with the variances of
/// their pixels' means) against one photo, over the included pixels.
///
/// The images are compared as means over square cells of `cell_px` pixels
/// (1: pixel by pixel): a cell's mean has 1/n of a pixel's noise variance
/// while a model error that is smooth over the cell stays whole, so cells
/// test where a twin's error lives (a recipe changes the object's
/// brightness and blur over many pixels) rather than the Monte Carlo noise
/// of single pixels. A cell's variance is Σ var / n² over its n included
/// pixels (render pixels are independent). Cells are grouped into blocks
/// of `block_px` pixels (at least one cell; neighbouring pixels are
/// correlated): the ratio estimate of the mean squared-error difference,
/// its standard error from the spread of the block sums (linearised,
/// B/(B − 1) corrected), and a two-sided Student-t p-value with B − 1
/// degrees of freedom at level `alpha`.
#[allow(clippy::too_many_arguments)]
pub fn paired(
    width: usize,
    height: usize,
    photo: &[f32],
    a: (&[f32], &[f32]),
    b: (&[f32], &[f32]),
    include: Option<&[bool]>,
    (cell_px, block_px): (usize, usize),
    alpha: f64,
) -> Result<PairedReport, NoiseError> {
    let expected = width * height * 3;
    for (what, v) in [("photo", photo), ("render A", a.0), ("variance A", a.1), ("render B", b.0), ("variance B", b.1)]
    {
        if v.len() != expected {
            return Err(NoiseError::Size { what, got: v.len(), expected, width, height });
        }
    }
    if block_px == 0 || cell_px == 0 {
        return Err(NoiseError::Settings);
    }
    // Per cell and channel: Σ A, Σ B, Σ P, Σ var A, Σ var B; and n.
    let cw = width.div_ceil(cell_px);
    let mut cells = vec![([[0.0f64; 5]; 3], 0usize); cw * height.div_ceil(cell_px)];
    for y in 0..height {
        for x in 0..width {
            let p = y * width + x;
            if include.is_some_and(|m| !m[p]) {
                continue;
            }
            let cell = &mut cells[(y / cell_px) * cw + x / cell_px];
            cell.1 += 1;
            for (c, acc) in cell.0.iter_mut().enumerate() {
                let i = 3 * p + c;
                for (k, v) in [a.0[i], b.0[i], photo[i], a.1[i], b.1[i]].into_iter().enumerate() {
                    acc[k] += f64::from(v);
                }
            }
        }
    }
    let cells_a_side = (block_px / cell_px).max(1);
    let bw = cw.div_ceil(cells_a_side);
    let mut sums = vec![(0.0f64, 0.0f64); bw * height.div_ceil(cell_px).div_ceil(cells_a_side)];
    for (j, (acc, n)) in cells.iter().enumerate() {
        if *n == 0 {
            continue;
        }
        let nf = *n as f64;
        let s = &mut sums[(j / cw / cells_a_side) * bw + (j % cw) / cells_a_side];
        s.1 += 3.0 * nf;
        for ch in acc {
            let (ma, mb, mp) = (ch[0] / nf, ch[1] / nf, ch[2] / nf);
            let (va, vb) = (ch[3] / (nf * nf), ch[4] / (nf * nf));
            s.0 += nf * (((ma - mp).powi(2) - va) - ((mb - mp).powi(2) - vb));
        }
    }
    sums.retain(|s| s.1 > 0.0);
    if sums.len() < 2 {
        return Err(NoiseError::Empty);
    }
    let (total, count): (f64, f64) = sums.iter().fold((0.0, 0.0), |(t, n), s| (t + s.0, n + s.1));
    let mean = total / count;
    let k = sums.len() as f64;
    let spread: f64 = sums.iter().map(|s| (s.0 - mean * s.1).powi(2)).sum::<f64>() * k / (k - 1.0);
    let se = spread.sqrt() / count;
    let z = if se > 0.0 { mean / se } else { 0.0 };
    let p = student_t_two_sided(z, k - 1.0);
    let verdict = if p >= alpha {
        "the data cannot tell them apart at this noise"
    } else if mean < 0.0 {
        "A is closer"
    } else {
        "B is closer"
    };
    Ok(PairedReport {
        definition: format!(
            "mean over included pixels and channels of [(A - P)^2 - var A] - [(B - P)^2 - var B], A, B, P and the \
             variances taken as means over square cells of {cell_px} x {cell_px} px (var of a cell's mean = sum of \
             its pixels' var / n^2); standard error from the spread of block sums; two-sided Student-t test with \
             blocks - 1 degrees of freedom"
        ),
        cell_px,
        squared_difference: mean,
        standard_error: se,
        z,
        p_value: p,
        alpha,
        verdict: verdict.into(),
        blocks: sums.len(),
    })
}

/// P(|T| ≥ |t|) for Student's t with `dof` degrees of freedom.
fn student_t_two_sided(t: f64, dof: f64) -> f64 {
    use statrs::distribution::{ContinuousCDF, StudentsT};
    match StudentsT::new(0.0, 1.0, dof) {
        Ok(d) if t.is_finite() => 2.0 * d.cdf(-t.abs()),
        _ => 1.0,
    }
}

/// SSIM of the photo against the noise-free render, estimated from two
/// independent half renders (see [`ssim_at_zero_noise`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SsimAtZeroNoise {
    pub definition: String,
    /// SSIM(P, R) of the whole render, as measured, over the same pixels.
    pub ssim: f64,
    /// The estimate of SSIM(P, E\[R\]), the render without its noise.
    pub at_zero_noise: f64,
    /// 95 % moving-block bootstrap interval of `at_zero_noise`.
    pub ci95: [f64; 2],
    /// `at_zero_noise − ssim`: how much the render's noise lowers SSIM.
    pub correction: f64,
    /// Pixels of the SSIM map the means are taken over.
    pub pixels: usize,
    pub block_px: usize,
    pub blocks: usize,
    pub resamples: usize,
}

/// SSIM at zero render noise: the mean of `noise_free`, the SSIM map with
/// the window moments debiased by two independent half renders
/// ([`crate::compare::ssim::ssim_map_noise_free`]), beside the mean of the
/// `measured` map over the same `include`d pixels. The 95 % interval is a
/// moving-block bootstrap over `block_px` square blocks of the debiased map
/// (seeded: the same inputs give the same interval).
///
/// What remains is the bias of a ratio of unbiased estimates: small where
/// the render's noise variance is small against the local variance of the
/// image, and a shortfall where it is not (synthetic test, truth 0.948:
/// measured 0.925 → 0.947 at half-render noise σ = 0.02; 0.781 → 0.934 at
/// σ = 0.06, i.e. ≈ 90 % of the way back). Trust the interval where the
/// correction is small (`lucent compare` notes it when it exceeds 0.05).
///
/// Why not extrapolate: SSIM's contrast term falls like 1/(D + v) in the
/// render's noise variance v, so a straight line through SSIM(P, R) and
/// SSIM(P, half) (Richardson, S₀ ≈ 2S(v) − S(2v)) stops short of the truth
/// once v is comparable to the local variance D (measured on the synthetic
/// test: 0.894 for a truth of 0.948 where the measured SSIM read 0.781).
/// Debiasing the moments that noise inflates removes v from D directly.
#[allow(clippy::too_many_arguments)]
pub fn ssim_at_zero_noise(
    width: usize,
    height: usize,
    measured: &[f32],
    noise_free: &[f64],
    include: &[bool],
    block_px: usize,
    resamples: usize,
    seed: u64,
) -> Result<SsimAtZeroNoise, NoiseError> {
    let n = width * height;
    for (what, len) in
        [("SSIM map", measured.len()), ("noise-free SSIM map", noise_free.len()), ("mask", include.len())]
    {
        if len != n {
            return Err(NoiseError::Size { what, got: len * 3, expected: n * 3, width, height });
        }
    }
    if block_px == 0 || resamples < 20 {
        return Err(NoiseError::Settings);
    }
    let bw = width.div_ceil(block_px);
    // Per block: pixels, Σ measured, Σ noise-free.
    let mut blocks = vec![(0.0f64, 0.0f64, 0.0f64); bw * height.div_ceil(block_px)];
    for y in 0..height {
        for x in 0..width {
            let p = y * width + x;
            if !include[p] {
                continue;
            }
            let b = &mut blocks[(y / block_px) * bw + x / block_px];
            b.0 += 1.0;
            b.1 += f64::from(measured[p]);
            b.2 += noise_free[p];
        }
    }
    blocks.retain(|b| b.0 > 0.0);
    if blocks.is_empty() {
        return Err(NoiseError::Empty);
    }
    let sum = |it: &mut dyn Iterator<Item = &(f64, f64, f64)>| {
        it.fold((0.0, 0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1, a.2 + b.2))
    };
    let (count, s_measured, s_free) = sum(&mut blocks.iter());
    let mut rng = lucent_render::rng::Rng::new(seed, 0);
    let mut draws: Vec<f64> = (0..resamples)
        .map(|_| {
            let (n, _, f) =
                sum(&mut (0..blocks.len()).map(|_| &blocks[(rng.next_u64() % blocks.len() as u64) as usize]));
            f / n
        })
        .collect();
    draws.sort_by(f64::total_cmp);
    let at = |q: f64| draws[((q * (draws.len() - 1) as f64).round() as usize).min(draws.len() - 1)];
    let at_zero_noise = s_free / count;
    Ok(SsimAtZeroNoise {
        definition: "SSIM (luminance Y) of the photo against the render without its noise: the SSIM map with the \
                     render's window moments debiased by its two independent half renders A, B (even- and \
                     odd-numbered samples): mu_y^2 -> mu_A mu_B, sigma_y^2 -> <AB> - mu_A mu_B; 95 % interval: \
                     moving-block bootstrap of that map"
            .into(),
        ssim: s_measured / count,
        at_zero_noise,
        ci95: [at(0.025), at(0.975)],
        correction: at_zero_noise - s_measured / count,
        pixels: count as usize,
        block_px,
        blocks: blocks.len(),
        resamples,
    })
}

#[cfg(test)]
mod paired_tests {
    use super::*;

    fn normal(rng: &mut lucent_render::rng::Rng) -> f64 {
        let (u1, u2) = rng.next_f64_pair();
        lucent_testkit::normal::box_muller(u1, u2)
    }

    /// A photo and two renders with model errors `bias_a`, `bias_b` (a ±
    /// checker of 16-pixel squares) and independent noise `sigma` in all
    /// three, compared over cells of `cell` pixels.
    fn run(seed: u64, (bias_a, bias_b): (f64, f64), sigma: f64, cell: usize) -> PairedReport {
        let (w, h) = (48usize, 48usize);
        let mut rng = lucent_render::rng::Rng::new(seed, 7);
        let n = w * h * 3;
        let (mut p, mut a, mut b) = (vec![0f32; n], vec![0f32; n], vec![0f32; n]);
        for i in 0..n {
            let (x, y) = ((i / 3) % w, i / 3 / w);
            let sign = if (x / 16 + y / 16) % 2 == 0 { 1.0 } else { -1.0 };
            let clean = 0.5 + 0.1 * (x as f64 * 0.2).sin();
            p[i] = (clean + sigma * normal(&mut rng)) as f32;
            a[i] = (clean + sign * bias_a + sigma * normal(&mut rng)) as f32;
            b[i] = (clean + sign * bias_b + sigma * normal(&mut rng)) as f32;
        }
        let var = vec![(sigma * sigma) as f32; n];
        paired(w, h, &p, (&a, &var), (&b, &var), None, (cell, 8), 0.05).unwrap()
    }

    #[test]
    fn rejects_at_the_stated_rate_under_the_null_and_finds_a_real_difference() {
        for cell in [1, 8] {
            // Two renders of the same twin: "cannot tell" 95 % of the time
            // (400 pairs: binomial SD 1.1 %, allowed 5 % ± 2.5 %).
            let rejected = (0..400).filter(|&s| run(5000 + s, (0.02, 0.02), 0.05, cell).p_value < 0.05).count();
            let rate = rejected as f64 / 400.0;
            assert!((rate - 0.05).abs() <= 0.025, "rejection rate under the null {rate} with cells of {cell} px");
            // A twin with half the model error is found closer.
            let r = run(1, (0.04, 0.02), 0.05, cell);
            assert_eq!(r.verdict, "B is closer", "{r:?}");
            let r = run(2, (0.02, 0.04), 0.05, cell);
            assert_eq!(r.verdict, "A is closer", "{r:?}");
        }
    }

    #[test]
    fn cells_find_a_smooth_model_error_that_pixel_noise_hides() {
        // Noise 6× the model error: pixel by pixel the squared errors are
        // noise (z ≈ 0.7 expected), cell means of 8 × 8 px keep the error
        // and lose 1/64 of the noise variance (z ≈ 4).
        let (mut pixel_found, mut cell_found) = (0, 0);
        for seed in 0..20 {
            pixel_found += usize::from(run(100 + seed, (0.05, 0.0), 0.3, 1).p_value < 0.01);
            let r = run(100 + seed, (0.05, 0.0), 0.3, 8);
            cell_found += usize::from(r.p_value < 0.01 && r.verdict == "B is closer");
        }
        assert!(pixel_found <= 3, "pixel by pixel found it {pixel_found} times in 20");
        assert!(cell_found >= 14, "cells found it only {cell_found} times in 20");
    }
}

#[cfg(test)]
mod zero_noise_tests {
    use super::*;
    use crate::compare::ssim::{mean_pixels, ssim, ssim_map_noise_free, ssim_with_map, Gray, SsimParams};

    fn normal(rng: &mut lucent_render::rng::Rng) -> f64 {
        let (u1, u2) = rng.next_f64_pair();
        lucent_testkit::normal::box_muller(u1, u2)
    }

    /// A photo, a noise-free render with a model error, and two half renders
    /// with independent noise σ each: the noise-free SSIM (the truth) and the
    /// extrapolation.
    fn run(seed: u64, sigma: f64) -> (f64, SsimAtZeroNoise) {
        let (w, h) = (96usize, 96usize);
        let mut rng = lucent_render::rng::Rng::new(seed, 11);
        let photo: Vec<f64> = (0..w * h)
            .map(|p| {
                let (x, y) = ((p % w) as f64, (p / w) as f64);
                0.5 + 0.25 * (0.3 * x).sin() * (0.2 * y).cos() + 0.02 * normal(&mut rng)
            })
            .collect();
        let clean: Vec<f64> = photo
            .iter()
            .enumerate()
            .map(|(p, v)| {
                let (x, y) = ((p % w) as f64, (p / w) as f64);
                0.92 * v + 0.03 * (0.7 * x + 0.4 * y).sin()
            })
            .collect();
        let mut half = || clean.iter().map(|v| v + sigma * normal(&mut rng)).collect::<Vec<f64>>();
        let (a, b) = (half(), half());
        let full: Vec<f64> = a.iter().zip(&b).map(|(x, y)| 0.5 * (x + y)).collect();
        let params = SsimParams::new(1.0).unwrap();
        let pg = Gray::new(w, h, &photo);
        let truth = ssim(&pg, &Gray::new(w, h, &clean), &params, None).unwrap().mean;
        let measured = ssim_with_map(&pg, &Gray::new(w, h, &full), &params, None).unwrap().1;
        let free = ssim_map_noise_free(&photo, &a, &b, w, h, &params).unwrap();
        let include = mean_pixels(w, h, &params, None);
        let r = ssim_at_zero_noise(w, h, &measured, &free, &include, 8, 400, seed).unwrap();
        (truth, r)
    }

    #[test]
    fn extrapolation_recovers_the_noise_free_ssim_within_its_interval() {
        // Noise that lowers SSIM by ten times the interval's half-width: the
        // measured SSIM is far off, the estimate covers the truth.
        let seeds = 40;
        let mut covered = 0;
        for s in 0..seeds {
            let (truth, r) = run(100 + s, 0.02);
            let half = 0.5 * (r.ci95[1] - r.ci95[0]);
            assert!(truth - r.ssim > 3.0 * half, "noise too weak to test: truth {truth}, measured {}, ±{half}", r.ssim);
            if r.ci95[0] <= truth && truth <= r.ci95[1] {
                covered += 1;
            }
        }
        assert!(covered >= 34, "the 95 % interval covered the noise-free SSIM {covered}/{seeds} times");
    }

    #[test]
    fn stronger_noise_leaves_a_stated_shortfall() {
        // Noise comparable to the local variance (σ = 0.06 per half): the
        // measured SSIM falls by ≈ 0.17; the estimate keeps ≥ 85 % of the
        // way back to the truth (the ratio bias documented on
        // `ssim_at_zero_noise`) and never overshoots.
        for s in 0..5 {
            let (truth, r) = run(300 + s, 0.06);
            assert!(truth - r.ssim > 0.15, "truth {truth}, measured {}", r.ssim);
            let recovered = (r.at_zero_noise - r.ssim) / (truth - r.ssim);
            assert!((0.85..=1.02).contains(&recovered), "recovered {recovered} of the gap: {r:?} vs {truth}");
        }
    }
}
