//! Least-squares fits of Trowbridge–Reitz and Beckmann distributions to a
//! measured D(θ) (docs/method.md#surface).
//!
//! Models (normalised so that ∫ D(m)(m·n) dω_m = 1):
//! - Trowbridge–Reitz (GGX; Trowbridge & Reitz 1975, Walter et al. 2007):
//!   D(θ) = α² / (π cos⁴θ (α² + tan²θ)²) = α² / (π (α² cos²θ + sin²θ)²);
//! - Beckmann (Beckmann & Spizzichino 1963): D(θ) = exp(−tan²θ/α²) / (π α² cos⁴θ).
//!
//! The fitted function is s · D_α, with a free scale s, optionally about an
//! axis tilted by τ from the macroscopic normal: then θ' = angle(m, axis)
//! with cos θ' = cos θ cos τ + sin θ sin τ cos φ, and the 1-D histogram is
//! compared with D averaged over φ (trapezoid rule with enough nodes to
//! resolve the tilted peak, ≥ 13 τ/α + 9). Each bin's model value is the
//! bin average weighted like the histogram, ∫ D̄ cos θ sin θ dθ / ∫ cos θ
//! sin θ dθ (4-point Gauss–Legendre per bin), so coarse bins do not bias α.
//!
//! Least squares: for fixed α (and τ) the best s is Σ y M / Σ M² in closed
//! form; α is found by a scan of 81 values of ln α over a factor 100 around
//! the median of tan θ_m, refined by golden-section search. With a tilt, τ
//! is the angle of the mean normal (the first moment: a consistent estimator
//! of the axis of a distribution symmetric about it; fitting τ to the 1-D
//! histogram alone is nearly degenerate with α when τ < α, since both
//! broaden it), and α, s are fitted about that axis. MSE = mean over bins of
//! (y − s M)² in 1/sr²; NRMSE = √MSE / max y. The better model is the one
//! with the lower MSE.
//!
//! ```
//! use lucent::surface::fit::d_model;
//! use lucent::surface::model::RoughnessModel;
//! // Both models peak at 1/(π α²) at θ = 0.
//! let a: f64 = 0.1;
//! for m in [RoughnessModel::TrowbridgeReitz, RoughnessModel::Beckmann] {
//!     assert!((d_model(m, a, 1.0) * std::f64::consts::PI * a * a - 1.0).abs() < 1e-12);
//! }
//! ```

use super::distribution::Distribution;
use super::error::SurfaceError;
use crate::surface::model::RoughnessModel;
use serde::{Deserialize, Serialize};
use std::f64::consts::PI;

/// D(θ) of `model` with roughness α at cos θ (0 for cos θ ≤ 0), 1/sr.
pub fn d_model(model: RoughnessModel, alpha: f64, cos_theta: f64) -> f64 {
    if cos_theta <= 0.0 {
        return 0.0;
    }
    let c2 = cos_theta * cos_theta;
    let s2 = (1.0 - c2).max(0.0);
    let a2 = alpha * alpha;
    match model {
        RoughnessModel::TrowbridgeReitz => {
            let q = a2 * c2 + s2;
            a2 / (PI * q * q)
        }
        RoughnessModel::Beckmann => (-(s2 / c2) / a2).exp() / (PI * a2 * c2 * c2),
    }
}

/// D of `model` about an axis tilted by τ, averaged over φ at polar angle θ.
pub fn d_tilted_phi_average(model: RoughnessModel, alpha: f64, tau: f64, theta: f64) -> f64 {
    if tau == 0.0 {
        return d_model(model, alpha, theta.cos());
    }
    let n = phi_nodes(alpha, tau);
    let (st, ct) = theta.sin_cos();
    let (sa, ca) = tau.sin_cos();
    let mut sum = 0.0;
    for k in 0..=n {
        let phi = PI * k as f64 / n as f64;
        let w = if k == 0 || k == n { 0.5 } else { 1.0 };
        sum += w * d_model(model, alpha, ct * ca + st * sa * phi.cos());
    }
    sum / n as f64
}

fn phi_nodes(alpha: f64, tau: f64) -> usize {
    ((13.0 * tau / alpha).ceil() as usize + 9).min(4001)
}

/// One model's fit.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ModelFit {
    pub model: RoughnessModel,
    /// Roughness α (dimensionless).
    pub alpha: f64,
    /// Scale factor s of s · D_α.
    pub scale: f64,
    /// Whether the tilt τ was a fit parameter.
    pub tilt_fitted: bool,
    /// Fitted tilt τ of the distribution's axis from the macroscopic normal, degrees (0 if not fitted).
    pub tilt_deg: f64,
    /// Mean squared error over the bins, 1/sr².
    pub mse_per_sr2: f64,
    /// √MSE / max measured D.
    pub nrmse: f64,
    /// Bins fitted.
    pub bins: usize,
    /// Model evaluations the search used.
    pub evaluations: usize,
}

/// The binned model and measured values of one fit problem.
struct Problem<'a> {
    model: RoughnessModel,
    edges: &'a [f64],
    y: &'a [f64],
    evaluations: usize,
}

const GL4: [(f64, f64); 4] = [
    (-0.861_136_311_594_052_6, 0.347_854_845_137_453_85),
    (-0.339_981_043_584_856_3, 0.652_145_154_862_546_2),
    (0.339_981_043_584_856_3, 0.652_145_154_862_546_2),
    (0.861_136_311_594_052_6, 0.347_854_845_137_453_85),
];

impl Problem<'_> {
    /// Bin averages of D̄ weighted by cos θ sin θ.
    fn binned(&self, alpha: f64, tau: f64) -> Vec<f64> {
        self.edges
            .windows(2)
            .map(|e| {
                let (t0, t1) = (e[0], e[1]);
                let (mid, half) = (0.5 * (t0 + t1), 0.5 * (t1 - t0));
                let mut num = 0.0;
                for (x, w) in GL4 {
                    let t = mid + half * x;
                    num += w * half * d_tilted_phi_average(self.model, alpha, tau, t) * t.cos() * t.sin();
                }
                num / (0.5 * (t1.sin().powi(2) - t0.sin().powi(2)))
            })
            .collect()
    }

    /// (MSE, best scale) at (α, τ).
    fn mse(&mut self, alpha: f64, tau: f64) -> (f64, f64) {
        self.evaluations += 1;
        let m = self.binned(alpha, tau);
        let (ym, mm) = self.y.iter().zip(&m).fold((0.0, 0.0), |(a, b), (y, m)| (a + y * m, b + m * m));
        let s = if mm > 0.0 { (ym / mm).max(0.0) } else { 0.0 };
        let sse: f64 = self.y.iter().zip(&m).map(|(y, m)| (y - s * m).powi(2)).sum();
        let mse = sse / self.y.len() as f64;
        (if mse.is_finite() { mse } else { f64::INFINITY }, s)
    }
}

/// Golden-section minimum of f on [a, b].
fn golden(mut a: f64, mut b: f64, tol: f64, f: &mut dyn FnMut(f64) -> f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let mut c = b - g * (b - a);
    let mut d = a + g * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    while (b - a).abs() > tol {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - g * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    0.5 * (a + b)
}

/// Fits `model` to the measured distribution (see the module doc).
pub fn fit_model(dist: &Distribution, model: RoughnessModel, fit_tilt: bool) -> Result<ModelFit, SurfaceError> {
    let y = &dist.d_per_sr;
    if y.len() < 3 || y.iter().all(|v| *v == 0.0) {
        return Err(SurfaceError::Data {
            origin: "distribution".into(),
            reason: "too few non-empty bins to fit".into(),
        });
    }
    let mut p = Problem { model, edges: &dist.edges_rad, y, evaluations: 0 };
    let a0 = dist.median_tan_theta.max(1e-7);
    // Scan ln α over a factor 100 around a0, shifting the window if the minimum is at its edge.
    let mut centre = a0.ln();
    let n = 81;
    let span = 100f64.ln();
    let mut best = (f64::INFINITY, centre);
    let mut step = span / (n - 1) as f64;
    for _ in 0..6 {
        let grid: Vec<f64> = (0..n).map(|k| centre - span / 2.0 + k as f64 * step).collect();
        let vals: Vec<f64> = grid.iter().map(|&la| p.mse(la.exp(), 0.0).0).collect();
        let k = (0..n).min_by(|&a, &b| vals[a].total_cmp(&vals[b])).unwrap_or(0);
        best = (vals[k], grid[k]);
        if k == 0 || k == n - 1 {
            centre = grid[k];
            continue;
        }
        step = grid[1] - grid[0];
        break;
    }
    let la = golden(best.1 - step, best.1 + step, 1e-8, &mut |la| p.mse(la.exp(), 0.0).0);
    let (mut alpha, mut tau) = (la.exp(), 0.0);
    if fit_tilt {
        // τ from the mean normal (the 1-D histogram alone leaves α and τ
        // nearly degenerate for τ < α), then α by least squares about that axis.
        tau = dist.mean_normal[2].clamp(-1.0, 1.0).acos();
        if tau > 0.0 {
            let la = golden(alpha.ln() - 4f64.ln(), alpha.ln() + 4f64.ln(), 1e-8, &mut |la| p.mse(la.exp(), tau).0);
            alpha = la.exp();
        }
    }
    let (mse, scale) = p.mse(alpha, tau);
    let ymax = y.iter().copied().fold(0.0, f64::max);
    Ok(ModelFit {
        model,
        alpha,
        scale,
        tilt_fitted: fit_tilt,
        tilt_deg: tau.to_degrees(),
        mse_per_sr2: mse,
        nrmse: mse.sqrt() / ymax,
        bins: y.len(),
        evaluations: p.evaluations,
    })
}
