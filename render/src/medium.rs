//! A homogeneous scattering medium in one wavelength band: scattering and
//! absorption coefficients μ_s, μ_a in 1/m, a phase function and the real
//! bulk refractive index n — the radiative transfer equation's parameters
//! (Chandrasekhar, Radiative Transfer, 1960, ch. 1). The slab simulator
//! takes one [`Medium`]; the path tracer's object one per band.
//!
//! ```
//! use lucent_render::medium::Medium;
//! use lucent_render::phase::Phase;
//! let m = Medium::new(1.0e4, 10.0, Phase::henyey_greenstein(0.9).unwrap(), 1.49).unwrap();
//! assert!((m.albedo() - 1.0e4 / 1.001e4).abs() < 1e-15);
//! assert!(Medium::new(-1.0, 10.0, Phase::henyey_greenstein(0.9).unwrap(), 1.49).is_err());
//! ```

use crate::phase::Phase;

/// The largest extinction coefficient μt = μs + μa [1/m] a medium may have
/// (slab simulator and path tracer alike): a mean free path of 0.1 µm, well
/// below the wavelengths of light, where radiative transfer no longer
/// describes the medium (and every path would be cut at its event limit).
pub const MU_T_MAX_PER_M: f64 = 1e7;

/// True when μs, μa ≥ 0 and 0 < μs + μa ≤ [`MU_T_MAX_PER_M`] (NaN: false).
pub fn valid_coefficients(mu_s_per_m: f64, mu_a_per_m: f64) -> bool {
    let t = mu_s_per_m + mu_a_per_m;
    mu_s_per_m >= 0.0 && mu_a_per_m >= 0.0 && t > 0.0 && t <= MU_T_MAX_PER_M
}

/// A medium parameter outside its range.
#[derive(Debug, Clone, thiserror::Error, PartialEq)]
#[error("{name} = {value} is invalid: {reason}")]
pub struct MediumError {
    pub name: &'static str,
    pub value: f64,
    pub reason: &'static str,
}

fn check(name: &'static str, value: f64, ok: bool, reason: &'static str) -> Result<f64, MediumError> {
    if ok && value.is_finite() {
        Ok(value)
    } else {
        Err(MediumError { name, value, reason })
    }
}

/// A homogeneous scattering medium in one band.
#[derive(Debug, Clone, PartialEq)]
pub struct Medium {
    /// Scattering coefficient μ_s, 1/m.
    pub mu_s_per_m: f64,
    /// Absorption coefficient μ_a, 1/m.
    pub mu_a_per_m: f64,
    /// The phase function.
    pub phase: Phase,
    /// Refractive index (bulk, real), relative to the air around it.
    pub n: f64,
}

impl Medium {
    /// Checks μ_s, μ_a ≥ 0, 0 < μ_t ≤ [`MU_T_MAX_PER_M`] and n in
    /// [`crate::fresnel::INDEX_RANGE`].
    pub fn new(mu_s_per_m: f64, mu_a_per_m: f64, phase: Phase, n: f64) -> Result<Self, MediumError> {
        let m = Self { mu_s_per_m, mu_a_per_m, phase, n };
        m.validate()?;
        Ok(m)
    }

    /// The checks of [`Medium::new`], for a medium built field by field.
    pub fn validate(&self) -> Result<(), MediumError> {
        let (s, a) = (self.mu_s_per_m, self.mu_a_per_m);
        check("mu_s_per_m", s, s >= 0.0, "must be ≥ 0")?;
        check("mu_a_per_m", a, a >= 0.0, "must be ≥ 0")?;
        check("mu_t_per_m", s + a, s + a > 0.0, "μs + μa must be > 0")?;
        check(
            "mu_t_per_m",
            s + a,
            valid_coefficients(s, a),
            "μs + μa must be at most 1e7 /m (MU_T_MAX_PER_M: a mean free path of 0.1 µm)",
        )?;
        check("n", self.n, crate::fresnel::valid_index(self.n), "must lie in [1, 10] (fresnel::INDEX_RANGE)")?;
        Ok(())
    }

    /// Extinction coefficient μ_t = μ_s + μ_a, 1/m.
    pub fn mu_t_per_m(&self) -> f64 {
        self.mu_s_per_m + self.mu_a_per_m
    }

    /// Single-scattering albedo μ_s / μ_t.
    pub fn albedo(&self) -> f64 {
        self.mu_s_per_m / self.mu_t_per_m()
    }
}
