//! Šidák's correction (Šidák 1967): `m` independent two-sided z-tests at
//! family-wise level α each use the per-test level 1 − (1 − α)^(1/m), so the
//! largest |z| of a correct estimator exceeds [`z_threshold`] with
//! probability α.

use statrs::distribution::{ContinuousCDF, Normal};

/// The |z| a single test of a family of `m` must stay below for family-wise
/// level `alpha`.
pub fn z_threshold(m: usize, alpha: f64) -> f64 {
    let per_test = 1.0 - (1.0 - alpha).powf(1.0 / m as f64);
    let normal = Normal::standard();
    // The upper quantile through the survival function's complement keeps
    // precision for per-test levels far below f64's epsilon near 1.
    -normal.inverse_cdf(per_test / 2.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn threshold_is_right() {
        // One test at α = 0.05: the familiar 1.959964.
        assert!((z_threshold(1, 0.05) - 1.959_964).abs() < 1e-5);
        // 9216 tests at 1e-3: per-test 1.085e-7, two-sided z = 5.31.
        let z = z_threshold(9216, 1e-3);
        assert!((z - 5.31).abs() < 0.01, "{z}");
    }
}
