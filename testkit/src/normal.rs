//! Standard normal variates from uniform ones by the Box–Muller transform
//! (Box & Muller 1958): √(−2 ln(1 − u₁)) cos(2π u₂) for u₁, u₂ in [0, 1)
//! (1 − u₁ keeps the logarithm finite at u₁ = 0).

use std::f64::consts::TAU;

/// One standard normal variate from two uniform variates in [0, 1).
pub fn box_muller(u1: f64, u2: f64) -> f64 {
    (-2.0 * (1.0 - u1).ln()).sqrt() * (TAU * u2).cos()
}

/// A deterministic source of uniform and standard normal variates
/// (SplitMix64, Steele, Lea & Flood 2014), for tests that need noise
/// without depending on a crate's own generator.
#[derive(Debug, Clone)]
pub struct SplitMix64(pub u64);

impl SplitMix64 {
    /// The next 64 random bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// A uniform variate in [0, 1) with 53 random bits.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// A standard normal variate.
    pub fn normal(&mut self) -> f64 {
        let (u1, u2) = (self.uniform(), self.uniform());
        box_muller(u1, u2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moments_are_standard() {
        let mut r = SplitMix64(1);
        let n = 200_000;
        let xs: Vec<f64> = (0..n).map(|_| r.normal()).collect();
        let m = xs.iter().sum::<f64>() / n as f64;
        let v = xs.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64;
        // 5σ of the sampling error of the mean (1/√n) and the variance (√(2/n)).
        assert!(m.abs() < 5.0 / (n as f64).sqrt(), "{m}");
        assert!((v - 1.0).abs() < 5.0 * (2.0 / n as f64).sqrt(), "{v}");
    }
}
