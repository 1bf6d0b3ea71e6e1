//! What a job's `run` is given besides the job: where its messages go.

/// The surroundings of a running job: `quiet` silences what it says about
/// its progress (warnings are always said). Messages go to standard error,
/// which `lucent run` sends into the stage's log.
#[derive(Debug, Clone, Copy, Default)]
pub struct Context {
    pub quiet: bool,
}

impl Context {
    /// A line about the work (what it is, how long it takes), unless quiet.
    pub fn say(&self, line: &str) {
        if !self.quiet {
            eprintln!("{line}");
        }
    }

    /// Something the user should know about the result ("note: …").
    pub fn note(&self, line: &str) {
        eprintln!("note: {line}");
    }

    /// Something that may be wrong with the input ("warning: …").
    pub fn warn(&self, line: &str) {
        eprintln!("warning: {line}");
    }
}

/// A duration as a "how long it takes" line says it: "45 s", "12 min", "3.5 h".
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
