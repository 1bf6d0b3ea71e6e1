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

/// The range of the largest asymmetry g a similar medium may have
/// ([`Medium::similar`]): 0 ≤ g_max < 1.
pub const SIMILARITY_G_RANGE: std::ops::Range<f64> = 0.0..1.0;

/// True when `g_max` lies in [`SIMILARITY_G_RANGE`] (NaN: false).
pub fn valid_similarity_g(g_max: f64) -> bool {
    SIMILARITY_G_RANGE.contains(&g_max)
}

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

    /// The similar medium whose phase function has asymmetry g′ ≤ `g_max`
    /// and the same reduced scattering coefficient μ_s(1 − g), μ_a and n,
    /// so μ_s′ = μ_s (1 − g)/(1 − g′) (the similarity relation of radiative
    /// transfer: Wyman, Patterson & Bilger, JOSA A 6(9), 1989; Zhao, Wu,
    /// Ramamoorthi & Bala, "High-order similarity relations in radiative
    /// transfer", ACM TOG 33(4), 2014). A table loses its forward peak to a
    /// flat top ([`PhaseTable::flat_topped`](crate::phase::PhaseTable::flat_topped)),
    /// which also keeps μ_s p(θ) outside the peak: single scattering into
    /// large angles is unchanged. A Henyey–Greenstein function becomes
    /// HG(g_max) (the first-order relation, which does change it).
    ///
    /// It is an approximation: exact in the diffusion limit, where only
    /// μ_s(1 − g) and μ_a matter, but not for light that scatters only a few
    /// times (its angular spread is then that of g′). A g ≈ 0.97 medium's
    /// walk makes (1 − g)/(1 − g′) times fewer events, and its connections
    /// to small lamps no longer hang on a narrow forward peak. A medium with
    /// g ≤ `g_max` is returned unchanged. Errors: `g_max` outside
    /// [`SIMILARITY_G_RANGE`].
    ///
    /// ```
    /// use lucent_render::medium::Medium;
    /// use lucent_render::phase::Phase;
    /// let m = Medium::new(1.47e4, 9.6, Phase::henyey_greenstein(0.974).unwrap(), 1.589).unwrap();
    /// let s = m.similar(0.0).unwrap();
    /// assert!((s.mu_s_per_m - 1.47e4 * 0.026).abs() < 1e-9 && s.phase.mean_cosine() == 0.0);
    /// ```
    pub fn similar(&self, g_max: f64) -> Result<Medium, MediumError> {
        check("similarity_g", g_max, valid_similarity_g(g_max), "must lie in [0, 1)")?;
        let g = self.phase.mean_cosine();
        if g <= g_max {
            return Ok(self.clone());
        }
        let phase = match &self.phase {
            Phase::HenyeyGreenstein { .. } => Phase::HenyeyGreenstein { g: g_max },
            // A table cut flat all over is the isotropic function; as HG(0)
            // it is sampled and evaluated without a table search (a third
            // of the walk's time in a diffusive medium such as TiO₂).
            Phase::Tabulated(t) => match t.flat_topped(g_max) {
                flat if flat.is_constant() => Phase::HenyeyGreenstein { g: 0.0 },
                cut => Phase::Tabulated(cut),
            },
        };
        let g_new = phase.mean_cosine();
        let medium = Medium { mu_s_per_m: self.mu_s_per_m * (1.0 - g) / (1.0 - g_new), phase, ..self.clone() };
        medium.validate()?;
        Ok(medium)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::phase::PhaseTable;
    use crate::slab::{simulate, Beam, Directions, RunOptions, Sensor, Setup, Slab, Stop};

    fn pdms_like(phase: Phase) -> Medium {
        Medium::new(1.47e4, 9.6, phase, 1.589).expect("valid medium")
    }

    #[test]
    fn similar_keeps_the_reduced_scattering_coefficient() {
        let m = pdms_like(Phase::henyey_greenstein(0.974).expect("valid g"));
        for g_max in [0.0, 0.5, 0.9] {
            let s = m.similar(g_max).expect("valid g_max");
            assert_eq!(s.phase, Phase::HenyeyGreenstein { g: g_max });
            let reduced = s.mu_s_per_m * (1.0 - g_max);
            assert!((reduced / (1.47e4 * 0.026) - 1.0).abs() < 1e-12, "{reduced}");
            assert_eq!((s.mu_a_per_m, s.n), (9.6, 1.589));
        }
        assert_eq!(m.similar(0.98).expect("valid g_max"), m);
        // A forward table cut down to g′ = 0 is flat all over: it becomes the
        // isotropic function itself (no table search), with μs(1 − g) kept;
        // a partial cut stays a table.
        let hg = |mu: f64| (1.0 - 0.49) / (1.0 + 0.49 - 1.4 * mu).powf(1.5);
        let values: Vec<f64> = (0..512).map(|i| hg((std::f64::consts::PI * i as f64 / 511.0).cos())).collect();
        let table = PhaseTable::from_theta_samples(&values).expect("valid table");
        let g = table.mean_cosine();
        let t = pdms_like(Phase::Tabulated(table));
        let iso = t.similar(0.0).expect("valid g_max");
        assert_eq!(iso.phase, Phase::HenyeyGreenstein { g: 0.0 });
        assert!((iso.mu_s_per_m / (1.47e4 * (1.0 - g)) - 1.0).abs() < 1e-12, "{}", iso.mu_s_per_m);
        assert!(matches!(t.similar(0.3).expect("valid g_max").phase, Phase::Tabulated(_)));
        for bad in [-0.1, 1.0, f64::NAN, f64::INFINITY] {
            let e = m.similar(bad).expect_err("outside [0, 1)");
            assert_eq!(e.name, "similarity_g");
        }
    }

    /// Total diffuse reflectance and transmittance of a 6.35 mm slab
    /// (PDMS-like, g ≈ 0.97, light at 45°) with the exact medium and with
    /// its similar media. The similarity relation is exact only in the
    /// diffusion limit; here (reduced optical thickness 2.5) the measured
    /// differences are within 1 % (R) and 3.5 % (T) with a Mie-like table
    /// (docs/method.md#render-similarity). The bounds would fail for a
    /// similar medium that did not keep μs(1 − g) (R off by tens of %).
    #[test]
    fn similar_slab_reflects_and_transmits_like_the_exact_one() {
        let n = 4096;
        let table = PhaseTable::from_theta_samples(
            &(0..n)
                .map(|i| {
                    let mu = (i as f64 * std::f64::consts::PI / (n - 1) as f64).cos();
                    let hg = |g: f64| (1.0 - g * g) / (1.0 + g * g - 2.0 * g * mu).powf(1.5);
                    0.9 * hg(0.985) + 0.1 * hg(0.8)
                })
                .collect::<Vec<_>>(),
        )
        .expect("valid table");
        let exact = pdms_like(Phase::Tabulated(table));
        let run = |medium: Medium, paths: u64| {
            let setup = Setup::new(
                Slab::new(6.35e-3, medium).expect("valid slab"),
                Beam::gaussian(200e-6).expect("valid beam"),
                Sensor::new(9, 1e-3).expect("valid sensor"),
                Directions::from_degrees(45.0, 0.0, 0.0, 180.0).expect("valid directions"),
            );
            let s =
                simulate(&setup, &RunOptions { stop: Stop::samples(paths), seed: 7, ..RunOptions::default() }, |_| {})
                    .expect("simulation runs");
            (s.diffuse_reflectance, s.transmittance)
        };
        let (r, t) = run(exact.clone(), 40_000);
        for g_max in [0.5, 0.0] {
            let similar = exact.similar(g_max).expect("valid g_max");
            assert!(similar.mu_s_per_m < 0.2 * exact.mu_s_per_m, "g_max {g_max}: μs′ = {}", similar.mu_s_per_m);
            let (rs, ts) = run(similar, 40_000);
            assert!((rs / r - 1.0).abs() < 0.02, "g_max {g_max}: R {rs} against {r}");
            assert!((ts / t - 1.0).abs() < 0.05, "g_max {g_max}: T {ts} against {t}");
        }
    }
}
