//! lucent: digital twins of translucent objects.
//!
//! The library behind the `lucent` command. Data flow is one way (docs/method.md):
//! recipe → optical properties ([`optics`]) → slab simulator or renderer
//! (`lucent-render`) → images → comparison.

pub mod bssrdf;
pub mod ccm_file;
pub mod chart_detect;
pub mod cli;
pub mod compare;
pub mod envfit;
pub mod exr;
pub mod fault;
pub mod fit;
pub mod imageio;
pub mod interrupt;
pub mod io;
pub mod job;
pub mod optics;
pub mod pipeline;
pub mod plot;
pub mod scene;
pub mod shard;
pub mod surface;
pub mod synth;
mod text;
