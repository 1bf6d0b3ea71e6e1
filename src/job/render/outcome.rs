//! What a render job did ([`RenderRun`]): the image with its report, error
//! figures and band ([`Rendered::Image`], [`BandRun`]), or a shard.

use crate::fault::Interrupted;
use crate::scene::{self, RenderReport};
use lucent_render::tracer;
use std::path::PathBuf;

/// What a render job did: the image (its report and error figures, the
/// band) or a shard, in `out`.
pub struct RenderRun {
    pub out: PathBuf,
    /// `None`: a shard stopped before it wrote anything.
    pub rendered: Option<Rendered>,
    /// Ctrl-C or SIGTERM stopped the render: the files hold what was
    /// finished (render.json says so), or a shard was not written. The
    /// command fails with it after the summary.
    pub interrupted: Option<Interrupted>,
}

/// The result of a render job.
pub enum Rendered {
    /// render.exr, png and json written (and with `uncertainty`, the band).
    Image { report: Box<RenderReport>, errors: tracer::RegionErrors, band: Option<Box<BandRun>> },
    /// Shard `k` of `n`: samples `range` of every pixel, in `wall_s`.
    Shard { k: u32, n: u32, range: std::ops::Range<u64>, wall_s: f64 },
}

/// The band a render with `uncertainty` wrote, the renders at ±1 σ it took and their time.
pub struct BandRun {
    pub band: scene::band::RenderBand,
    pub renders: usize,
    pub wall_s: f64,
}
