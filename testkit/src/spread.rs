//! Reported standard errors against the spread over independent runs: over
//! k runs with estimates xᵢ and reported standard errors σᵢ of one quantity,
//! (k − 1) s² / mean(σᵢ²) ~ χ²(k − 1) when the σᵢ are right (s² the sample
//! variance of the xᵢ), so the test fails both when the errors are inflated
//! (lower tail) and when they are deflated (upper tail).

use crate::chi2::upper_tail;

/// The spread check of one quantity over k runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    /// Sample variance of the estimates.
    pub s2: f64,
    /// Mean of the reported squared standard errors.
    pub se2: f64,
    /// Upper-tail p-value of (k − 1) s² / mean(σ²) under χ²(k − 1).
    pub p_upper: f64,
}

/// The check over `(estimate, reported standard error)` per run (k ≥ 2).
pub fn check(runs: &[(f64, f64)]) -> Spread {
    let k = runs.len();
    assert!(k >= 2, "the spread needs at least two runs");
    let m = runs.iter().map(|x| x.0).sum::<f64>() / k as f64;
    let s2 = runs.iter().map(|x| (x.0 - m).powi(2)).sum::<f64>() / (k - 1) as f64;
    let se2 = runs.iter().map(|x| x.1 * x.1).sum::<f64>() / k as f64;
    Spread { s2, se2, p_upper: upper_tail((k - 1) as f64 * s2 / se2, k - 1) }
}

/// Asserts both tails of [`check`] at level `tail`: the p-value lies in
/// (`tail`, 1 − `tail`).
pub fn assert_errors_match_spread(label: &str, runs: &[(f64, f64)], tail: f64) {
    let s = check(runs);
    assert!(s.se2 > 0.0, "{label}: no reported standard error");
    assert!(
        s.p_upper > tail && s.p_upper < 1.0 - tail,
        "{label}: spread² {:.3e} vs mean reported SE² {:.3e} (ratio {:.2}, χ² p = {:.2e})",
        s.s2,
        s.se2,
        s.s2 / s.se2,
        s.p_upper
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inflated_and_deflated_errors_fail() {
        // Estimates ±1 around 0: s² = 30/29 over 30 runs.
        let xs: Vec<f64> = (0..30).map(|i| if i % 2 == 0 { 1.0 } else { -1.0 }).collect();
        let with = |se: f64| xs.iter().map(|&x| (x, se)).collect::<Vec<_>>();
        assert!(std::panic::catch_unwind(|| assert_errors_match_spread("right", &with(1.0), 5e-4)).is_ok());
        assert!(std::panic::catch_unwind(|| assert_errors_match_spread("inflated", &with(3.0), 5e-4)).is_err());
        assert!(std::panic::catch_unwind(|| assert_errors_match_spread("deflated", &with(0.3), 5e-4)).is_err());
    }
}
