//! The luminance Y = w·(R, G, B) of `ssim.Y`, the difference picture and
//! ECC: the choice of weights ([`Luminance`]).

use strum::{EnumMessage, EnumString, IntoStaticStr, VariantArray, VariantNames};

/// Luminance weights for `ssim.Y`, the difference picture and ECC.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Default, EnumString, IntoStaticStr, VariantNames, VariantArray, EnumMessage,
)]
#[strum(ascii_case_insensitive)]
pub enum Luminance {
    /// Y row of CIE 1931 RGB → XYZ: 0.1769, 0.8124, 0.0107 (the default).
    #[default]
    #[strum(to_string = "cie-rgb", serialize = "cie")]
    CieRgb,
    /// Y row of linear sRGB / Rec. 709 → XYZ: 0.2126, 0.7152, 0.0722.
    #[strum(to_string = "rec709", serialize = "srgb")]
    Rec709,
}

impl Luminance {
    /// (w_R, w_G, w_B), summing to 1.
    pub fn weights(self) -> [f64; 3] {
        use lucent_colour::spaces::RgbSpace;
        match self {
            Self::CieRgb => RgbSpace::CieRgb.to_xyz_matrix()[1],
            Self::Rec709 => RgbSpace::Srgb.to_xyz_matrix()[1],
        }
    }

    pub fn describe(self) -> &'static str {
        match self {
            Self::CieRgb => "Y row of the CIE 1931 RGB -> XYZ matrix",
            Self::Rec709 => "Y row of the linear sRGB / Rec. 709 -> XYZ matrix",
        }
    }
}
