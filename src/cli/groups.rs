//! Groups of flags that several commands share, each defined once and
//! pulled into a command with `#[command(flatten)]` (clap), so the flags are
//! spelled, documented and checked the same everywhere:
//!
//! * [`BeamArgs`]: the incident beam of a slab slice (`bssrdf`, `fit`);
//! * [`BoardArgs`]: the calibration chessboard (`calibrate`, `pose`);
//! * [`TwinRenderArgs`]: the overrides of a scene's `[render]` section and
//!   the image size (`render`, `env fit-scale`).

use anyhow::{anyhow, Result};
use clap::Args;
use lucent_calib::board::BoardSize;
use lucent_calib::scene::BoardSpec;
use lucent_render::slab::Beam;
use std::path::PathBuf;

/// The beam that lights the slab.
#[derive(Debug, Clone, Args)]
pub struct BeamArgs {
    /// Gaussian beam FWHM in µm.
    #[arg(long, default_value_t = 200.0, conflicts_with = "beam_map")]
    pub beam_fwhm_um: f64,
    /// Measured map of incident irradiance on the surface (EXR, float TIFF or CSV grid).
    #[arg(long)]
    pub beam_map: Option<PathBuf>,
    /// Pixel size of the beam map in mm (else from its sidecar JSON).
    #[arg(long)]
    pub beam_map_pixel_mm: Option<f64>,
}

impl Default for BeamArgs {
    /// The flags' defaults: a Gaussian beam of 200 µm FWHM.
    fn default() -> Self {
        BeamArgs { beam_fwhm_um: 200.0, beam_map: None, beam_map_pixel_mm: None }
    }
}

impl BeamArgs {
    /// The beam, and how a report describes it.
    pub fn beam(&self) -> Result<(Beam, String)> {
        Ok(crate::job::beam(self.beam_fwhm_um, self.beam_map.as_deref(), self.beam_map_pixel_mm)?)
    }
}

/// The chessboard of a calibration or a pose.
#[derive(Debug, Clone, Args)]
pub struct BoardArgs {
    /// Inner corners COLSxROWS, e.g. 9x6 for a board of 10 × 7 squares. Corner (0, 0), the
    /// world's origin, is the one diagonally beyond the light outer corner square (OpenCV's
    /// numbering, also `lucent env orient`'s); only a board with one odd and one even count
    /// (e.g. 9x6) fixes it.
    #[arg(long)]
    pub board: BoardSize,
    /// Side of one square in millimetres.
    #[arg(long)]
    pub square_mm: f64,
}

impl BoardArgs {
    /// The board, or an error naming both flags.
    pub fn spec(&self) -> Result<BoardSpec> {
        BoardSpec::new(self.board, self.square_mm).map_err(|e| anyhow!("--square-mm: {e}"))
    }
}

/// How a scene is rendered: the overrides of its `[render]` section and
/// the image size.
#[derive(Debug, Clone, Default, Args)]
pub struct TwinRenderArgs {
    /// Samples per pixel (overrides [render] spp).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Seed of the random streams (overrides [render] seed).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Image size WIDTHxHEIGHT instead of the camera's (the intrinsics are scaled to match).
    #[arg(long)]
    pub size: Option<crate::job::ImageSize>,
    /// Worker threads (default: the batch job's allocation, LUCENT_THREADS or
    /// SLURM_CPUS_PER_TASK, when set, else all cores; 0: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
}
