//! Names as the user may type them: the canonical form that lookups of
//! illuminants, observers, colour spaces and adaptation transforms compare.
//! A leaf module (no dependency on the rest of the crate).
//!
//! ```
//! assert_eq!(lucent_colour::names::canonical_name("CIE 1931 2°"), "cie19312");
//! ```

/// The form user-typed names are compared in: lower case, ASCII letters and digits only.
pub fn canonical_name(name: &str) -> String {
    name.chars().filter(|c| c.is_ascii_alphanumeric()).map(|c| c.to_ascii_lowercase()).collect()
}
