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

/// The phase function a recipe's medium is simulated with (`lucent bssrdf
/// --phase`, the scene's and the project's `phase` key).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "kebab-case")]
#[derive(strum::EnumString, strum::IntoStaticStr, strum::VariantNames, strum::VariantArray, strum::EnumMessage)]
#[strum(serialize_all = "kebab-case", ascii_case_insensitive)]
pub enum PhaseModel {
    /// The recipe's tabulated Lorenz–Mie phase function.
    Mie,
    /// Henyey–Greenstein with the same g.
    Hg,
}

impl PhaseModel {
    /// The name files and flags use.
    pub fn name(self) -> &'static str {
        self.into()
    }
}
