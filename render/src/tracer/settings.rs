//! How a render is made ([`Settings`]): the stop rule ([`Stop`]: samples
//! per pixel, seconds, the object's median relative error), passes, the
//! seed, Russian roulette, and which of the estimator's strategies are on
//! (spectral MIS, band branches, the medium connections, specular chains,
//! sphere jumps, entry splitting); how dispersion is handled
//! ([`Dispersion`]); how samples are spread over the pixels ([`Sampling`]);
//! and the coefficient derivatives a render estimates alongside
//! ([`CoefficientDerivative`]: perturbation Monte Carlo, Hayakawa et al.
//! 2001, Sassaroli 2012). Distances in metres, coefficients in 1/m.

use crate::stop::{Condition, Stop, StopError};

/// How long to render and with what.
#[derive(Debug, Clone, PartialEq)]
pub struct Settings {
    /// When to stop, checked after every pass; the first condition met
    /// ends the render. Its samples are samples per pixel (at most
    /// `u32::MAX`; with [`Sampling::ObjectWeighted`] the object's pixels'),
    /// its time budget ends the render after the pass that exceeds it, its
    /// per-pixel target is the median relative standard error over the
    /// object's pixels ([`RegionErrors::object`]). A target relative error
    /// of the whole image is refused
    /// ([`StopError::Unsupported`](crate::stop::StopError::Unsupported)).
    /// Without a sample count the render goes on until another condition
    /// ends it.
    ///
    /// [`RegionErrors::object`]: super::RegionErrors::object
    pub stop: Stop,
    /// Samples per pixel per progressive pass.
    pub spp_per_pass: u32,
    pub seed: u64,
    /// Throughput below which Russian roulette starts; `None` disables it.
    pub roulette_threshold: Option<f64>,
    /// Safety stop: a path with more scattering events is ended and counted
    /// in [`Stats::truncated_paths`] (reported, never silent).
    ///
    /// [`Stats::truncated_paths`]: super::Stats::truncated_paths
    pub max_events_per_path: u64,
    /// Carry all three bands along one path inside the medium, combined by
    /// multiple importance sampling over the band that drives the sampling
    /// (see the module documentation). `false` gives docs/method.md §5's plain
    /// estimator (one band per path, weight 3). Applies only when the
    /// boundary's index is the same in all bands.
    pub spectral_mis: bool,
    /// Where a path meets the object and must keep one band from there on
    /// (a boundary whose index differs between bands, or
    /// [`Settings::spectral_mis`] = false), follow three branches from that
    /// point, one per band, each weighing 1 in its band, instead of one band
    /// drawn at random with weight 3 (docs/method.md §5). A sample's value
    /// is the branches' sum, so its variance stays that of independent
    /// samples. Per sample the object costs three walks instead of one, and
    /// the variance of the random band's estimator, 3 E(X²) − E(X)² per band,
    /// falls to Var X, for any X: never less efficient. `false`: one band
    /// at random.
    pub band_branches: bool,
    /// Next-event estimation of the environment from scattering events
    /// inside a convex object, through its flat faces (see the module
    /// documentation). `false`: light leaves the medium only by chance.
    pub medium_nee: bool,
    /// With [`Settings::medium_nee`]: also connect along a direction drawn
    /// from the phase function, the transmittance to the face and the
    /// Fresnel transmission taken as factors instead of sampled (a third
    /// strategy in the same balance heuristic; see the module
    /// documentation). `false`: the two strategies of before.
    pub phase_connection: bool,
    /// With [`Settings::medium_nee`]: connections also through the specular
    /// chains a path takes without scattering (see the module
    /// documentation): from a scattering point through one reflection at a
    /// face and out through another (image method), and from the board
    /// through the object (in at one face, one unscattered flight, out at
    /// another) or by a reflection at one of its faces. `false` (default):
    /// such paths are found only by chance,
    /// unweighted, and carry most of the object's sparse bright pixels
    /// (fireflies); on the demo plaque the chains cut the 99th percentile of
    /// the per-pixel error from 44 % to 12 % at the same median, for 12 %
    /// more time (fixtures/render/demo.toml turns them on).
    pub specular_chains: bool,
    /// Where a path scatters deeper than [`SPHERE_MARGIN_MFP`] + the
    /// smallest sphere inside an object that scatters isotropically in
    /// every band (a similar medium of g′ = 0, for instance), replace the
    /// walk inside the largest tabulated sphere that fits by one draw from
    /// its exit distribution ([`crate::sphere`]): a diffusive medium's
    /// deep excursions cost O(log depth) jumps instead of depth² events.
    /// The tables are Monte Carlo estimates (a fixed error of a few % per
    /// bin in the exit angle). `false` (default): the plain walk.
    pub sphere_jumps: bool,
    /// With [`Settings::sphere_jumps`]: the least depth, in mean free paths
    /// of the least extinct band, between a sphere and the nearest face
    /// plane (default [`SPHERE_MARGIN_MFP`]). Smaller: more jumps and
    /// fewer events, each exit point near a face connected to the
    /// environment as a scattering point is.
    pub sphere_margin_mfp: f64,
    /// How a smooth boundary whose index differs between bands refracts a
    /// path that carries all bands (see [`Dispersion`]).
    pub dispersion: Dispersion,
    /// Split the path where it meets the object from outside: the
    /// reflection (weight F per band) and the refraction (1 − F) are both
    /// followed instead of choosing one with probability F. The reflected
    /// branch is traced without further splitting.
    pub split_entry: bool,
    /// How the samples are spread over the pixels.
    pub sampling: Sampling,
    /// Changes of the object's coefficients whose effect on every pixel the
    /// render estimates from its own paths ([`Image::derivatives`]; at most
    /// [`MAX_DERIVATIVES`], the rest are ignored). Turns
    /// [`Settings::sphere_jumps`] off (a jump's events are not seen).
    ///
    /// [`Image::derivatives`]: super::Image::derivatives
    pub derivatives: Vec<CoefficientDerivative>,
}

impl Default for Settings {
    fn default() -> Self {
        Self {
            stop: Stop::samples(64),
            spp_per_pass: 4,
            seed: 1,
            roulette_threshold: Some(0.25),
            max_events_per_path: 10_000_000,
            spectral_mis: true,
            band_branches: true,
            medium_nee: true,
            phase_connection: true,
            specular_chains: false,
            sphere_jumps: false,
            sphere_margin_mfp: SPHERE_MARGIN_MFP,
            dispersion: Dispersion::PerBand,
            split_entry: false,
            sampling: Sampling::Uniform,
            derivatives: Vec::new(),
        }
    }
}

impl Settings {
    /// What the stop rule asks a render to stop on: samples per pixel, a
    /// time budget, the object's median per-pixel error.
    pub const STOP_CONDITIONS: [Condition; 3] = [Condition::Samples, Condition::Time, Condition::PixelRelError];

    /// The samples per pixel a render plans for: the stop rule's sample
    /// count, `u32::MAX` without one.
    pub fn spp(&self) -> u32 {
        self.stop.samples.map_or(u32::MAX, |n| u32::try_from(n).unwrap_or(u32::MAX))
    }

    /// Checks the stop rule ([`Stop::check`]) and refuses what a render
    /// cannot honour: a target relative error of the whole image, more
    /// than `u32::MAX` samples per pixel.
    pub fn check_stop(&self) -> Result<(), StopError> {
        self.stop.check()?;
        self.stop.refuse_unsupported("a render", &Self::STOP_CONDITIONS)?;
        match self.stop.samples {
            Some(n) if n > u64::from(u32::MAX) => {
                Err(StopError::TooManySamples { integrator: "a render", samples: n, max: u32::MAX.into() })
            }
            _ => Ok(()),
        }
    }
}

/// Refraction at a smooth boundary whose index n differs between bands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Dispersion {
    /// Exact: a refraction direction belongs to one band, so a path keeps
    /// one band from its first contact with the object (weight 3, docs/method.md §5).
    PerBand,
    /// Approximate: refraction directions (Snell's law and its solid-angle
    /// factor cos θ_o/(n² cos θ_i)) from the bands' mean index, while each
    /// band keeps its own Fresnel factors F_c and 1 − F_c (where the mean
    /// index reflects totally, F_c = 1 in every band). A path then carries
    /// all three bands (spectral MIS). Reflection is exact; what is lost is
    /// the spread of the refracted directions between bands (≈ 0.5° for
    /// polycarbonate's 1.582–1.608).
    SharedDirections,
}

/// How a render spreads its samples over the pixels.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sampling {
    /// Every pixel gets the stop rule's samples.
    Uniform,
    /// Samples go where the error is: after each pass the per-sample
    /// relative variance of the object's pixels and of the others (medians
    /// over each region, [`RegionErrors`]) sets how many more samples a
    /// pixel whose camera rays hit the object gets per pass than one whose
    /// rays miss it (at most [`MAX_OBJECT_RATIO`]), so both regions approach
    /// the same relative error. The object's pixels get the stop rule's
    /// samples (spp), the others spp / ratio (at least one pass). A pixel's share depends on
    /// the fraction of its camera rays that hit the object (geometry) and
    /// on the two region medians, never on its own samples alone.
    ///
    /// [`RegionErrors`]: super::RegionErrors
    ObjectWeighted,
}

/// The largest ratio of samples per pass between an object pixel and a
/// pixel that does not see the object ([`Sampling::ObjectWeighted`]).
pub const MAX_OBJECT_RATIO: u32 = 256;

/// The default [`Settings::sphere_margin_mfp`]: a sphere jump leaves at
/// least this many mean free paths (of the least extinct band) between the
/// sphere and the nearest face plane. A scattered exit is a vertex with
/// connections of its own, so a small margin costs no tail. Measured on
/// IOL1068-06 (320 × 240, 64 spp): margin 3, 17.8 % median, 4.51 s; 1,
/// 17.1 %, 4.08 s; 0.5, 16.9 %, 3.87 s; 0, 16.7 %, 3.65 s (99th
/// percentiles 24–25 % throughout); 0.5 keeps the exit points off the faces.
pub const SPHERE_MARGIN_MFP: f64 = 0.5;

/// The most [`CoefficientDerivative`]s one render carries.
pub const MAX_DERIVATIVES: usize = 4;

/// The derivative of the object's scattering and absorption coefficients
/// with respect to one parameter θ (a recipe's weight percentage, for
/// instance), per band R, G, B; the phase functions, indices and geometry
/// do not depend on θ. The render then estimates ∂L/∂θ per pixel from the
/// same paths as L (perturbation Monte Carlo, the likelihood-ratio or
/// "score" estimator: Hayakawa et al., Opt. Lett. 26(17), 2001; Sassaroli,
/// J. Biomed. Opt. 17(7), 2012): every contribution f/p of a path with n
/// scattering events and medium length ℓ_c in band c is weighted by
///
///   ∂ ln f_c / ∂θ = n ∂ln μ_s,c/∂θ − (∂μ_s,c/∂θ + ∂μ_a,c/∂θ) ℓ_c,
///
/// unbiased for ∂L/∂θ, whatever the sampling densities and multiple
/// importance weights (they do not depend on θ). A similar medium of fixed
/// g and g′ scales its μ_s′ with μ_s, so the relative derivative serves it
/// too.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CoefficientDerivative {
    /// ∂ ln μ_s / ∂θ per band (per unit of θ).
    pub d_ln_mu_s: [f64; 3],
    /// ∂μ_a / ∂θ per band, 1/m per unit of θ.
    pub d_mu_a_per_m: [f64; 3],
}

impl CoefficientDerivative {
    /// ∂μ_t/∂θ in band c of a medium whose scattering coefficient is `mu_s_per_m`.
    #[inline]
    pub(super) fn d_mu_t(&self, c: usize, mu_s_per_m: f64) -> f64 {
        self.d_ln_mu_s[c] * mu_s_per_m + self.d_mu_a_per_m[c]
    }
}
