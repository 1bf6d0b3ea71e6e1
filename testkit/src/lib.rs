//! Test helpers shared by lucent's crates: the statistical checks their
//! Monte Carlo tests make and a plain EXR reader independent of the code
//! under test.
//!
//! - [`chi2`]: Pearson's χ² goodness of fit of binned samples against
//!   expected counts, and the χ² of per-pixel differences of two estimates.
//! - [`sidak`]: the per-test threshold of a family of two-sided z-tests.
//! - [`spread`]: reported standard errors against the spread over seeds.
//! - [`normal`]: standard normal variates from uniform ones (Box–Muller).
//! - [`exr`]: reading EXR channels as `f32` planes.
//! - [`mesh`]: test meshes (an icosphere).

pub mod chi2;
pub mod exr;
pub mod mesh;
pub mod normal;
pub mod sidak;
pub mod spread;
