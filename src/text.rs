//! Values that are their text: a type whose `Display` writes what its
//! `FromStr` reads (an image size "640x480", a wavelength grid
//! "400:700:10") is serialised as that text, so a job file, a project file
//! and a command line hold the same words. Also the wording of a
//! duration ([`duration`]), which the commands and jobs share.

/// Serde for a type as its text: serialised with `Display`, read with
/// `FromStr` (whose error names the text).
macro_rules! serde_as_text {
    ($t:ty) => {
        impl serde::Serialize for $t {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                s.collect_str(self)
            }
        }
        impl<'de> serde::Deserialize<'de> for $t {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                let text = <String as serde::Deserialize>::deserialize(d)?;
                text.parse().map_err(serde::de::Error::custom)
            }
        }
    };
}
pub(crate) use serde_as_text;

/// "95 s", "12 min", "3.4 h" (the "expect ≈ …" lines).
pub fn duration(s: f64) -> String {
    if !s.is_finite() {
        "an unknown time".into()
    } else if s < 120.0 {
        format!("{s:.0} s")
    } else if s < 7200.0 {
        format!("{:.0} min", s / 60.0)
    } else {
        format!("{:.1} h", s / 3600.0)
    }
}
