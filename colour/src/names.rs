//! Names as the user may type them, and the closed sets of names of this
//! crate (illuminants, observers, colour spaces, adaptation transforms,
//! colour-correction methods). Each such enum lists its spellings once, in
//! strum attributes: `to_string` is its name (written in files and
//! messages), `serialize` the other spellings read. The `named!` macro derives from
//! that list its `FromStr` (any spelling, compared in [`canonical_name`]
//! form; an unknown name's error lists the valid ones) and its serde form
//! (written as the name, read as `FromStr` reads). A leaf module (no
//! dependency on the rest of the crate).
//!
//! ```
//! assert_eq!(lucent_colour::names::canonical_name("CIE 1931 2°"), "cie19312");
//! ```

use strum::{EnumMessage, VariantArray, VariantNames};

/// The form user-typed names are compared in: lower case, ASCII letters and digits only.
pub fn canonical_name(name: &str) -> String {
    name.chars().filter(|c| c.is_ascii_alphanumeric()).map(|c| c.to_ascii_lowercase()).collect()
}

/// The variant one of whose spellings has the canonical form of `text`.
pub fn lookup<T: VariantArray + EnumMessage + Copy>(text: &str) -> Option<T> {
    let c = canonical_name(text);
    <T as VariantArray>::VARIANTS
        .iter()
        .copied()
        .find(|v| v.get_serializations().iter().any(|s| canonical_name(s) == c))
}

/// The names of the variants, in order, for an error message.
pub fn valid_names<T: VariantNames>() -> String {
    T::VARIANTS.join(", ")
}

/// `FromStr` (by [`lookup`], of the text `$prepare` makes of it if given;
/// an unknown name is a `ColourError::UnknownName` of `$kind` listing
/// [`valid_names`]), `Display` and serde as the name, for an enum deriving
/// strum's `IntoStaticStr`, `VariantArray`, `VariantNames` and `EnumMessage`.
macro_rules! named {
    ($t:ty, $kind:literal $(, $prepare:expr)?) => {
        impl std::str::FromStr for $t {
            type Err = $crate::ColourError;
            fn from_str(s: &str) -> Result<Self, Self::Err> {
                let text = s.to_string();
                $(let text: String = $prepare(&text);)?
                $crate::names::lookup(&text).ok_or_else(|| $crate::ColourError::UnknownName {
                    kind: $kind,
                    name: s.to_string(),
                    valid: $crate::names::valid_names::<Self>(),
                })
            }
        }

        impl std::fmt::Display for $t {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.into())
            }
        }

        impl serde::Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.serialize_str(self.into())
            }
        }

        impl<'de> serde::Deserialize<'de> for $t {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let s = String::deserialize(d)?;
                s.parse().map_err(serde::de::Error::custom)
            }
        }
    };
}
pub(crate) use named;
