//! What a render gives back: the [`Image`] (per pixel the mean radiance
//! in the environment's units, W m⁻² sr⁻¹ per band, the variance of that
//! mean, the sample counts per first hit, two independent half renders and
//! the derivative images), the per-region summaries of its relative
//! standard errors ([`RegionErrors`], [`Quantiles`]), the render's counters
//! ([`Stats`]) and what is reported after each pass ([`Progress`]).

/// The rendered image: per pixel the mean, the variance of the mean and
/// the number of samples, row-major from the top-left pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct Image {
    pub width: usize,
    pub height: usize,
    pub mean: Vec<[f64; 3]>,
    pub variance_of_mean: Vec<[f64; 3]>,
    pub samples: Vec<u32>,
    /// Per pixel, how many of its camera rays hit the object first.
    pub object_samples: Vec<u32>,
    /// Per pixel, how many of its camera rays hit the board first.
    pub board_samples: Vec<u32>,
    /// Two independent half renders of the same run: per pixel the mean of
    /// its samples with even index k (`halves[0]`, ⌈n/2⌉ samples) and with
    /// odd k (`halves[1]`, ⌊n/2⌋; 0 where a pixel has a single sample). Their
    /// noise is independent and twice the variance of `mean`, which is what
    /// an extrapolation of a noisy figure to zero noise needs.
    pub halves: [Vec<[f64; 3]>; 2],
    /// Per [`Settings::derivatives`] entry, ∂L/∂θ per pixel (empty without).
    ///
    /// [`Settings::derivatives`]: super::Settings::derivatives
    pub derivatives: Vec<DerivativeImage>,
}

/// One [`CoefficientDerivative`]'s ∂L/∂θ per pixel: the mean over the
/// pixel's samples and its variance, row-major like [`Image::mean`].
///
/// [`CoefficientDerivative`]: super::CoefficientDerivative
#[derive(Debug, Clone, PartialEq)]
pub struct DerivativeImage {
    pub mean: Vec<[f64; 3]>,
    pub variance_of_mean: Vec<[f64; 3]>,
}

/// Median and 90th percentile of a per-pixel figure over a set of pixels.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Quantiles {
    /// Pixels in the region that are not black (those the figure is taken over).
    pub pixels: usize,
    pub median: f64,
    pub p90: f64,
    /// The 99th percentile: the sparse bright outliers' share.
    pub p99: f64,
}

impl Quantiles {
    /// Median, 90th and 99th percentile of `values` (NaN for an empty set).
    pub fn of(mut values: Vec<f64>) -> Self {
        if values.is_empty() {
            return Self { pixels: 0, median: f64::NAN, p90: f64::NAN, p99: f64::NAN };
        }
        values.sort_by(f64::total_cmp);
        let q = |q| sorted_quantile(&values, q);
        Self { pixels: values.len(), median: q(0.5), p90: q(0.9), p99: q(0.99) }
    }
}

/// The q-quantile of non-empty ascending `sorted`: its element at ⌊q n⌋ (the last for q = 1).
pub(super) fn sorted_quantile(sorted: &[f64], q: f64) -> f64 {
    sorted[((q * sorted.len() as f64) as usize).min(sorted.len() - 1)]
}

/// The relative standard error of each pixel's mean, summarised per region:
/// the pixels where at least half the camera rays hit the object first, those
/// where at least half hit the board first, and all pixels. A pixel's
/// relative standard error is [`Image::relative_std_error`] (the RMS over
/// R, G, B), taken over the pixels that are not black; one with a channel
/// still without light, or with one sample, counts as +∞.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RegionErrors {
    pub object: Quantiles,
    pub board: Quantiles,
    pub all: Quantiles,
}

/// Which region a pixel belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Region {
    Object,
    Board,
    Other,
}

impl Image {
    /// The fraction of pixel `p`'s camera rays that hit the object first.
    pub fn object_fraction(&self, p: usize) -> f64 {
        f64::from(self.object_samples[p]) / f64::from(self.samples[p].max(1))
    }

    /// The region of pixel `p` (at least half its camera rays hit the object
    /// first, else the board first, else neither).
    pub fn region(&self, p: usize) -> Region {
        let n = self.samples[p].max(1);
        if 2 * self.object_samples[p] >= n && self.object_samples[p] > 0 {
            Region::Object
        } else if 2 * self.board_samples[p] >= n && self.board_samples[p] > 0 {
            Region::Board
        } else {
            Region::Other
        }
    }

    /// The root mean square over R, G, B of the channels' relative standard
    /// errors √(var of the mean)/mean of pixel `p` (so coloured noise counts
    /// in full). `None` for a black pixel (no channel has a positive mean:
    /// no relative error is defined). A pixel that has light in one channel
    /// but none yet in another (a band no path of it has carried), or a
    /// variance that is not finite (one sample), gets +∞: its error is not
    /// known to be small, and leaving it out would make a median over few
    /// samples read low.
    pub fn relative_std_error(&self, p: usize) -> Option<f64> {
        let (m, v) = (self.mean[p], self.variance_of_mean[p]);
        if !m.iter().any(|&x| x > 0.0) {
            return None;
        }
        let mut sum = 0.0;
        for c in 0..3 {
            if !(m[c] > 0.0 && v[c].is_finite()) {
                return Some(f64::INFINITY);
            }
            sum += v[c] / (m[c] * m[c]);
        }
        Some((sum / 3.0).sqrt())
    }

    /// Median and 90th percentile of the relative standard error over the
    /// object's pixels, the board's and all.
    pub fn region_errors(&self) -> RegionErrors {
        let [o, b, a] = self.errors_by_region();
        RegionErrors { object: Quantiles::of(o), board: Quantiles::of(b), all: Quantiles::of(a) }
    }

    /// The pixels' relative standard errors (black pixels left out) over
    /// the object's pixels, the board's and all.
    pub(super) fn errors_by_region(&self) -> [Vec<f64>; 3] {
        let mut by: [Vec<f64>; 3] = Default::default();
        for p in 0..self.mean.len() {
            let Some(r) = self.relative_std_error(p) else { continue };
            match self.region(p) {
                Region::Object => by[0].push(r),
                Region::Board => by[1].push(r),
                Region::Other => {}
            }
            by[2].push(r);
        }
        by
    }
}

/// Counters of a render.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Stats {
    pub samples: u64,
    /// Scattering events inside the medium.
    pub events: u64,
    /// Ray–surface interactions (object boundary and board).
    pub surface_hits: u64,
    /// Paths that found no boundary while inside the object (a hole in the mesh).
    pub leaked_paths: u64,
    /// Paths ended by `max_events_per_path`.
    pub truncated_paths: u64,
    pub passes: u32,
    pub wall_s: f64,
}

impl Stats {
    pub(super) fn add(&mut self, o: &Stats) {
        self.samples += o.samples;
        self.events += o.events;
        self.surface_hits += o.surface_hits;
        self.leaked_paths += o.leaked_paths;
        self.truncated_paths += o.truncated_paths;
    }
}

/// Progress after each pass.
#[derive(Debug, Clone, Copy)]
pub struct Progress {
    pub spp_done: u32,
    pub spp_target: u32,
    pub elapsed_s: f64,
    pub stats: Stats,
    /// The relative standard errors per region after this pass.
    pub errors: RegionErrors,
}
