//! One-dimensional minimisation of a noisy objective (Monte Carlo with
//! common random numbers): bracketing by golden-ratio expansion, golden-
//! section search inside the bracket, and a least-squares parabola through
//! points evaluated at the full budget around the best point; and
//! Nelder–Mead for several parameters.
//!
//! The objective is evaluated in a transformed coordinate x (ln p for
//! positive parameters), with bounds [lo, hi] in x. With common random
//! numbers the objective is a smooth function of x plus a small noise, so
//! golden section (which only compares values) converges as on a smooth
//! function until the bracket is as narrow as the noise allows; the
//! parabola then gives the minimum and the local curvature.
//!
//! ```
//! use lucent::fit::search::{golden_bracket_search, quadratic_fit};
//! let mut f = |x: f64| -> Result<f64, std::convert::Infallible> { Ok((x - 0.3).powi(2)) };
//! let r = golden_bracket_search(&mut f, 1.0, 0.2, (-5.0, 5.0), 1e-4).unwrap();
//! assert!((r.best_x - 0.3).abs() < 1e-3);
//! let xs = [0.1, 0.2, 0.3, 0.4, 0.5];
//! let q = quadratic_fit(&xs, &xs.map(|x| 2.0 + (x - 0.3) * (x - 0.3))).unwrap();
//! assert!((q.vertex() - 0.3).abs() < 1e-9);
//! ```

/// The golden ratio φ = (1 + √5)/2.
const GOLDEN: f64 = 1.618_033_988_749_895;

/// What the bracketing and golden-section stage found.
#[derive(Debug, Clone)]
pub struct SearchResult {
    /// The best point evaluated.
    pub best_x: f64,
    pub best_f: f64,
    /// The final bracket [a, c] (a < c) around the minimum.
    pub bracket: (f64, f64),
    /// Every point evaluated, in order.
    pub points: Vec<(f64, f64)>,
    /// Whether the minimum lies at a bound (the objective still fell there).
    pub at_bound: Option<f64>,
}

/// Evaluates with a cache (the bracketing may touch a bound twice).
struct Cached<'a, E, F: FnMut(f64) -> Result<f64, E>> {
    f: &'a mut F,
    points: Vec<(f64, f64)>,
    _e: std::marker::PhantomData<E>,
}

impl<E, F: FnMut(f64) -> Result<f64, E>> Cached<'_, E, F> {
    fn eval(&mut self, x: f64) -> Result<f64, E> {
        if let Some(&(_, v)) = self.points.iter().find(|(p, _)| (p - x).abs() < 1e-12) {
            return Ok(v);
        }
        let v = (self.f)(x)?;
        self.points.push((x, v));
        Ok(v)
    }
}

/// Minimises `f` from `x0` with initial step `step` within `bounds`, until the
/// bracket is narrower than `tol`: expansion by the golden ratio downhill
/// until the objective rises (or a bound is reached), then golden-section
/// search (Kiefer 1953; Press et al., Numerical Recipes, §10.1–10.2).
pub fn golden_bracket_search<E>(
    f: &mut impl FnMut(f64) -> Result<f64, E>,
    x0: f64,
    step: f64,
    bounds: (f64, f64),
    tol: f64,
) -> Result<SearchResult, E> {
    let (lo, hi) = bounds;
    let clamp = |x: f64| x.clamp(lo, hi);
    let mut c = Cached { f, points: Vec::new(), _e: std::marker::PhantomData };
    let x0 = clamp(x0);
    let f0 = c.eval(x0)?;
    // Downhill direction.
    let xp = clamp(x0 + step);
    let fp = c.eval(xp)?;
    let (mut a, mut b, mut fb) = if fp < f0 {
        (x0, xp, fp)
    } else {
        let xm = clamp(x0 - step);
        let fm = c.eval(xm)?;
        if fm < f0 {
            (x0, xm, fm)
        } else {
            // x0 is already bracketed by x0 ± step.
            return finish(c, (xm, x0, xp), tol, None);
        }
    };
    // Expand: a → b is downhill; step on by φ × (b − a) until f rises.
    let cx = loop {
        let cx = clamp(b + GOLDEN * (b - a));
        if (cx - b).abs() < 1e-12 {
            // b sits at a bound and the objective still falls towards it.
            let (l, r) = if a < b { (a, b) } else { (b, a) };
            return finish(c, (l, b, r), tol, Some(b));
        }
        let fc = c.eval(cx)?;
        if fc > fb {
            break cx;
        }
        (a, b, fb) = (b, cx, fc);
    };
    let triple = if a < cx { (a, b, cx) } else { (cx, b, a) };
    finish(c, triple, tol, None)
}

/// Golden-section search on the bracket (l, m, r) with f(m) ≤ f(l), f(r).
fn finish<E, F: FnMut(f64) -> Result<f64, E>>(
    mut c: Cached<'_, E, F>,
    (mut l, mut m, mut r): (f64, f64, f64),
    tol: f64,
    at_bound: Option<f64>,
) -> Result<SearchResult, E> {
    const R: f64 = 0.381_966_011_250_105_1; // 2 − φ
    if at_bound.is_none() {
        let mut fm = c.eval(m)?;
        while r - l > tol {
            // Probe the larger of the two sub-intervals.
            let x = if r - m > m - l { m + R * (r - m) } else { m - R * (m - l) };
            let fx = c.eval(x)?;
            if fx < fm {
                if x > m {
                    l = m;
                } else {
                    r = m;
                }
                (m, fm) = (x, fx);
            } else if x > m {
                r = x;
            } else {
                l = x;
            }
        }
    }
    let (best_x, best_f) = c.points.iter().copied().min_by(|p, q| p.1.total_cmp(&q.1)).unwrap_or((m, f64::INFINITY));
    Ok(SearchResult { best_x, best_f, bracket: (l, r), points: c.points, at_bound })
}

/// A parabola f(x) = c0 + c1 (x − x_ref) + c2 (x − x_ref)².
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Quadratic {
    pub x_ref: f64,
    pub c0: f64,
    pub c1: f64,
    pub c2: f64,
}

impl Quadratic {
    /// The stationary point (the minimum when c2 > 0); ±∞ or NaN when c2 = 0.
    pub fn vertex(&self) -> f64 {
        self.x_ref - self.c1 / (2.0 * self.c2)
    }

    pub fn at(&self, x: f64) -> f64 {
        let d = x - self.x_ref;
        self.c0 + self.c1 * d + self.c2 * d * d
    }
}

/// Least-squares parabola through (xs, fs) (at least 3 distinct points),
/// centred on the mean of xs; `None` if the points are degenerate.
pub fn quadratic_fit(xs: &[f64], fs: &[f64]) -> Option<Quadratic> {
    if xs.len() < 3 || xs.len() != fs.len() {
        return None;
    }
    let x_ref = xs.iter().sum::<f64>() / xs.len() as f64;
    // Normal equations of [1, d, d²].
    let mut m = [[0.0f64; 3]; 3];
    let mut v = [0.0f64; 3];
    for (x, f) in xs.iter().zip(fs) {
        let d = x - x_ref;
        let row = [1.0, d, d * d];
        for (i, ri) in row.iter().enumerate() {
            for (j, rj) in row.iter().enumerate() {
                m[i][j] += ri * rj;
            }
            v[i] += ri * f;
        }
    }
    let c = solve3(m, v)?;
    Some(Quadratic { x_ref, c0: c[0], c1: c[1], c2: c[2] })
}

/// Solves a 3 × 3 system by Cramer's rule; `None` if (nearly) singular.
fn solve3(m: [[f64; 3]; 3], v: [f64; 3]) -> Option<[f64; 3]> {
    let det = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(m);
    let diag = m[0][0] * m[1][1] * m[2][2];
    if d.is_nan() || d.abs() <= 1e-12 * diag.abs() {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut a = m;
        for (row, vi) in a.iter_mut().zip(v) {
            row[k] = vi;
        }
        *o = det(a) / d;
    }
    Some(out)
}

/// A point evaluated by Nelder–Mead and its value.
pub type Point = (Vec<f64>, f64);

/// Nelder–Mead simplex minimisation (Nelder & Mead 1965, coefficients
/// reflection 1, expansion 2, contraction ½, shrink ½) of `f` from `x0`
/// with initial steps `steps`, until the simplex's objective spread falls
/// below `f_tol` and its size below `x_tol` (per coordinate, in units of
/// the steps), or after `max_evaluations`. Returns the best point, its
/// value and every point evaluated.
pub fn nelder_mead<E>(
    f: &mut impl FnMut(&[f64]) -> Result<f64, E>,
    x0: &[f64],
    steps: &[f64],
    f_tol: f64,
    x_tol: f64,
    max_evaluations: usize,
) -> Result<(Vec<f64>, f64, Vec<Point>), E> {
    let n = x0.len();
    let mut history: Vec<Point> = Vec::new();
    let mut eval = |x: &[f64], history: &mut Vec<Point>| -> Result<f64, E> {
        let v = f(x)?;
        history.push((x.to_vec(), v));
        Ok(v)
    };
    let mut simplex: Vec<Point> = Vec::with_capacity(n + 1);
    simplex.push((x0.to_vec(), eval(x0, &mut history)?));
    for i in 0..n {
        let mut x = x0.to_vec();
        x[i] += steps[i];
        let v = eval(&x, &mut history)?;
        simplex.push((x, v));
    }
    while history.len() < max_evaluations {
        simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
        let spread = simplex[n].1 - simplex[0].1;
        let size = (0..n)
            .map(|i| {
                let (mn, mx) =
                    simplex.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| (a.min(p.0[i]), b.max(p.0[i])));
                (mx - mn) / steps[i].abs()
            })
            .fold(0.0, f64::max);
        if spread <= f_tol && size <= x_tol {
            break;
        }
        let centroid: Vec<f64> = (0..n).map(|i| simplex[..n].iter().map(|p| p.0[i]).sum::<f64>() / n as f64).collect();
        let worst = simplex[n].0.clone();
        let along = |t: f64| -> Vec<f64> { (0..n).map(|i| centroid[i] + t * (worst[i] - centroid[i])).collect() };
        let xr = along(-1.0);
        let fr = eval(&xr, &mut history)?;
        if fr < simplex[0].1 {
            let xe = along(-2.0);
            let fe = eval(&xe, &mut history)?;
            simplex[n] = if fe < fr { (xe, fe) } else { (xr, fr) };
        } else if fr < simplex[n - 1].1 {
            simplex[n] = (xr, fr);
        } else {
            let xc = if fr < simplex[n].1 { along(-0.5) } else { along(0.5) };
            let fc = eval(&xc, &mut history)?;
            if fc < simplex[n].1.min(fr) {
                simplex[n] = (xc, fc);
            } else {
                let best = simplex[0].0.clone();
                for p in simplex.iter_mut().skip(1) {
                    let x: Vec<f64> = best.iter().zip(&p.0).map(|(b, q)| b + 0.5 * (q - b)).collect();
                    let v = eval(&x, &mut history)?;
                    *p = (x, v);
                }
            }
        }
    }
    simplex.sort_by(|a, b| a.1.total_cmp(&b.1));
    let (x, v) = simplex.swap_remove(0);
    Ok((x, v, history))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::convert::Infallible;

    #[test]
    fn brackets_and_finds_minimum_far_from_start() {
        let mut calls = 0;
        let mut f = |x: f64| -> Result<f64, Infallible> {
            calls += 1;
            Ok((x + 2.0).powi(2) + 1.0)
        };
        let r = golden_bracket_search(&mut f, 1.0, 0.1, (-10.0, 10.0), 1e-3).unwrap();
        assert!((r.best_x + 2.0).abs() < 1e-3, "{r:?}");
        assert!(r.at_bound.is_none());
        assert!(calls < 40, "{calls} evaluations");
    }

    #[test]
    fn minimum_at_bound_is_reported() {
        let mut f = |x: f64| -> Result<f64, Infallible> { Ok(x) };
        let r = golden_bracket_search(&mut f, 0.0, 0.1, (-1.0, 1.0), 1e-3).unwrap();
        assert_eq!(r.at_bound, Some(-1.0));
    }

    #[test]
    fn quadratic_fit_recovers_coefficients() {
        let xs = [-0.2, -0.1, 0.0, 0.1, 0.2];
        let fs = xs.map(|x: f64| 3.0 - 2.0 * x + 5.0 * x * x);
        let q = quadratic_fit(&xs, &fs).unwrap();
        assert!((q.c2 - 5.0).abs() < 1e-9 && (q.vertex() - 0.2).abs() < 1e-9, "{q:?}");
        assert!(quadratic_fit(&[1.0, 1.0, 1.0], &[1.0, 2.0, 3.0]).is_none());
    }

    #[test]
    fn nelder_mead_on_a_narrow_valley() {
        let mut f = |x: &[f64]| -> Result<f64, Infallible> { Ok((x[0] - 1.0).powi(2) + 10.0 * (x[1] - x[0]).powi(2)) };
        let (x, v, _) = nelder_mead(&mut f, &[-1.0, 2.0], &[0.5, 0.5], 1e-12, 1e-6, 2000).unwrap();
        assert!((x[0] - 1.0).abs() < 1e-3 && (x[1] - 1.0).abs() < 1e-3 && v < 1e-6, "{x:?} {v}");
    }
}
