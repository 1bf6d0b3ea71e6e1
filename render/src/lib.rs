//! Light transport for lucent: phase functions, Fresnel interfaces, the
//! slab BSSRDF simulator and (to come) the 3D path tracer (SPEC §3, §4).
//! No OpenCV; inputs are plain numbers converted by the root crate.

pub mod accel;
pub mod camera;
pub mod env;
pub mod fresnel;
pub mod microfacet;
pub mod phase;
pub mod rng;
#[cfg(target_arch = "x86_64")]
mod simd;
pub mod slab;
pub mod tracer;
