//! Spectral optical properties of a turbid material from its recipe (docs/method.md#optics):
//! refractive-index data ([`index`]), recipes ([`recipe`]), Lorenz–Mie theory
//! ([`mie`]), bulk coefficients and phase tables ([`bulk`]) and their files
//! ([`output`]).

pub mod bulk;
pub mod index;
pub mod mie;
pub mod output;
pub mod recipe;
pub mod uncertainty;
