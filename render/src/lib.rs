//! Light transport for lucent: phase functions, media, the dielectric
//! interface (smooth or rough), the slab BSSRDF simulator, the 3D spectral
//! path tracer and the stop rule both share ([`stop`]). No OpenCV; inputs
//! are plain numbers converted by the root crate.

pub mod accel;
pub mod camera;
pub mod env;
pub mod fresnel;
pub mod interface;
pub mod medium;
pub mod microfacet;
pub mod phase;
pub mod rng;
#[cfg(target_arch = "x86_64")]
mod simd;
pub mod slab;
pub mod sphere;
pub mod stop;
pub mod tracer;
