//! Pearson's χ² test (Pearson 1900; Cochran 1954 for the minimum expected
//! count).
//!
//! [`goodness_of_fit`] compares observed counts with expected counts: bins
//! expecting fewer than [`MIN_EXPECTED`] are pooled into one bin (a bin of
//! its own in the statistic), so the χ² approximation of the statistic's
//! distribution holds; the statistic has (bins − 1) degrees of freedom.
//! [`pixel_differences`] is Σ z² of two independent estimates per pixel,
//! χ² with one degree of freedom per pixel.

use statrs::distribution::{ChiSquared, ContinuousCDF};

/// Bins expecting fewer counts than this are pooled.
pub const MIN_EXPECTED: f64 = 5.0;

/// A χ² statistic, its degrees of freedom and its upper-tail p-value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Chi2 {
    pub chi2: f64,
    pub dof: usize,
    pub p_value: f64,
}

/// Upper-tail probability P(X ≥ `chi2`) of X ~ χ²(`dof`); 0 for an infinite
/// statistic, 1 for zero degrees of freedom.
pub fn upper_tail(chi2: f64, dof: usize) -> f64 {
    if !chi2.is_finite() {
        return 0.0;
    }
    match ChiSquared::new(dof as f64) {
        Ok(d) => d.sf(chi2),
        Err(_) => 1.0,
    }
}

/// Pearson's goodness of fit of `observed` counts against `expected`
/// counts (same bins, same total). Bins expecting fewer than
/// [`MIN_EXPECTED`] are pooled into one; counts observed where nothing is
/// expected give an infinite statistic (p = 0).
pub fn goodness_of_fit(observed: &[f64], expected: &[f64]) -> Chi2 {
    assert_eq!(observed.len(), expected.len(), "observed and expected bins differ in number");
    let (mut chi2, mut bins) = (0.0, 0usize);
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    for (&o, &e) in observed.iter().zip(expected) {
        if e < MIN_EXPECTED {
            pool_o += o;
            pool_e += e;
        } else {
            chi2 += (o - e).powi(2) / e;
            bins += 1;
        }
    }
    if pool_e > 0.0 {
        chi2 += (pool_o - pool_e).powi(2) / pool_e;
        bins += 1;
    } else if pool_o > 0.0 {
        chi2 = f64::INFINITY;
    }
    let dof = bins.saturating_sub(1);
    Chi2 { chi2, dof, p_value: upper_tail(chi2, dof) }
}

/// Σ (a − b)² / (σ_a² + σ_b²) over the pixels both estimates resolve
/// (positive, relative standard error below `max_rel_error`), with one
/// degree of freedom per such pixel. Inputs are values and standard errors
/// per pixel.
pub fn pixel_differences(a: (&[f64], &[f64]), b: (&[f64], &[f64]), max_rel_error: f64) -> Chi2 {
    let ((va, sa), (vb, sb)) = (a, b);
    assert!(va.len() == vb.len() && sa.len() == va.len() && sb.len() == vb.len(), "images differ in size");
    let (mut chi2, mut dof) = (0.0, 0usize);
    for i in 0..va.len() {
        let resolved = |v: f64, s: f64| v > 0.0 && s < max_rel_error * v;
        if resolved(va[i], sa[i]) && resolved(vb[i], sb[i]) {
            chi2 += (va[i] - vb[i]).powi(2) / (sa[i] * sa[i] + sb[i] * sb[i]);
            dof += 1;
        }
    }
    Chi2 { chi2, dof, p_value: upper_tail(chi2, dof) }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn upper_tail_matches_tabulated_critical_values() {
        // χ²(9) at 27.877 is the 0.1 % point; χ²(1) at 3.841 the 5 % point.
        assert!((upper_tail(27.877, 9) - 1e-3).abs() < 1e-5);
        assert!((upper_tail(3.841_459, 1) - 0.05).abs() < 1e-6);
        assert_eq!(upper_tail(f64::INFINITY, 3), 0.0);
    }

    #[test]
    fn goodness_of_fit_pools_small_bins_and_catches_impossible_counts() {
        // Two bins of 50 expected and two of 2 (pooled into one of 4):
        // χ² = 1/50 + 1/50 + 0 over 3 bins, 2 degrees of freedom.
        let g = goodness_of_fit(&[49.0, 51.0, 1.0, 3.0], &[50.0, 50.0, 2.0, 2.0]);
        assert_eq!(g.dof, 2);
        assert!((g.chi2 - 0.04).abs() < 1e-12, "{g:?}");
        assert!((g.p_value - (-0.02f64).exp()).abs() < 1e-12, "{g:?}");
        // Counts where nothing is expected fail outright.
        let g = goodness_of_fit(&[50.0, 1.0], &[51.0, 0.0]);
        assert_eq!(g.p_value, 0.0);
    }

    #[test]
    fn pixel_differences_skip_unresolved_pixels() {
        let a = ([1.0, 2.0, 0.0], [0.1, 0.1, 0.0]);
        let b = ([1.2, 2.0, 1.0], [0.1, 0.9, 0.1]);
        let c = pixel_differences((&a.0, &a.1), (&b.0, &b.1), 0.25);
        // Only pixel 0: pixel 1's b error is 45 %, pixel 2's a is empty.
        assert_eq!(c.dof, 1);
        assert!((c.chi2 - 0.04 / 0.02).abs() < 1e-12);
    }
}
