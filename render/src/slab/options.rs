//! How a run is made: its stop rule ([`Stop`]; its samples are light
//! paths, checked after each round of 32 batches), the estimator that
//! fills the slice ([`Estimator`]), the seed, batch size and fold
//! ([`RunOptions`]), and what is reported after every round of batches
//! ([`Progress`]).

use super::lobe::{lobe_applies, LOBE_VERTICES};
use super::ring::Ring;
use super::setup::Setup;
use super::tally::PixelErrors;
use crate::stop::Stop;

/// Which estimator fills the slice.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Estimator {
    /// Explicit connection at every scattering event along the one fixed
    /// direction ω₂₁ (the estimator before the ring; any configuration).
    Connection,
    /// Explicit connection over the ring of directions at the exit polar
    /// angle, using the slab's symmetry about the normal (see the module
    /// doc, "Ring connection"). Needs θ_i = 0 or θ_o = 0 and a thick slab
    /// (μ_t d / cos θ_t ≥ 40, no image terms); [`Estimator::best_for`]
    /// picks it where it applies.
    Ring,
    /// The fixed-direction connection combined by multiple importance
    /// sampling with chains of `vertices` events drawn backwards from ω₂₁
    /// through the phase function's lobe (see the module doc, "Lobe
    /// connection"; `vertices` = 1 is the two-vertex connection). Any exit
    /// direction, smooth or rough top; needs a thick slab (μ_t d / cos θ_t
    /// ≥ 40; through a rough top μ_t d ≥ 40). [`Estimator::best_for`] uses
    /// [`LOBE_VERTICES`].
    Lobe { vertices: usize },
    /// Escaping photons binned by exit pixel within a cone of half-angle
    /// `cone_deg` around ω_o (a slow, independent check).
    BruteForce { cone_deg: f64 },
}

impl Estimator {
    /// [`Estimator::Ring`] where it applies (one of θ_i, θ_o is 0 and the
    /// other is not, thick slab, smooth top), else [`Estimator::Lobe`] where
    /// it applies (thick slab, smooth or rough top), else
    /// [`Estimator::Connection`].
    pub fn best_for(setup: &Setup) -> Self {
        if Ring::applies(setup) {
            Estimator::Ring
        } else if lobe_applies(setup) {
            Estimator::Lobe { vertices: LOBE_VERTICES }
        } else {
            Estimator::Connection
        }
    }

    /// Whether the estimator is exact for `setup`: the ring needs θ_i or
    /// θ_o = 0, a thick slab and a smooth top; the lobe connection a thick
    /// slab ([`SlabError::RingNotApplicable`](super::SlabError::RingNotApplicable),
    /// [`SlabError::LobeNotApplicable`](super::SlabError::LobeNotApplicable)
    /// otherwise); the others apply to every setup.
    pub fn applies(&self, setup: &Setup) -> bool {
        match self {
            Estimator::Ring => Ring::applies(setup),
            Estimator::Lobe { .. } => lobe_applies(setup),
            Estimator::Connection | Estimator::BruteForce { .. } => true,
        }
    }

    /// A short name for summaries.
    pub fn name(&self) -> &'static str {
        match self {
            Estimator::Connection => "connection (fixed direction)",
            Estimator::Ring => "ring connection (azimuthal symmetry)",
            Estimator::Lobe { .. } => {
                "lobe connection (MIS with chains drawn through the phase lobe around the exit direction)"
            }
            Estimator::BruteForce { .. } => "brute force (exit binning)",
        }
    }
}

/// Run options.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunOptions {
    pub stop: Stop,
    pub seed: u64,
    pub batch_paths: u64,
    pub estimator: Estimator,
    /// Fold the slice about the plane of incidence (average of pixel (r, c)
    /// and its mirror (N−1−r, c), in every batch) where that is exact: both
    /// azimuths 0° or 180°, a mirror-symmetric beam and top surface ([`Setup::mirror_symmetric`]).
    pub fold: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self { stop: Stop::samples(100_000), seed: 1, batch_paths: 256, estimator: Estimator::Connection, fold: false }
    }
}

/// Progress after a round.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    pub paths: u64,
    pub events: u64,
    pub elapsed_s: f64,
    /// Relative standard error of the slice sum.
    pub rel_error: f64,
    /// Per-pixel relative standard errors over the bright pixels.
    pub pixels: PixelErrors,
}
