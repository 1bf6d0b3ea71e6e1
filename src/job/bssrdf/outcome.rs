//! What a slab job did ([`BssrdfRun`]): the lines to print and where a run
//! stopped by Ctrl-C kept its slice.

use crate::fault::Interrupted;
use std::path::PathBuf;

/// What a slab job did: the lines `lucent bssrdf` prints (one per
/// configuration, the band's sentences, the sweep table's path or the
/// shard's line), and where a run stopped by Ctrl-C kept its slice.
pub struct BssrdfRun {
    pub lines: Vec<String>,
    /// The configuration's folder when Ctrl-C stopped the run: it holds the
    /// slice so far, and the configurations after it were not run.
    pub interrupted_at: Option<PathBuf>,
}

impl BssrdfRun {
    /// The lines to print.
    pub fn summary(&self) -> Vec<String> {
        self.lines.clone()
    }

    /// `Err` when Ctrl-C stopped the run (its outputs are written, labelled
    /// "interrupted").
    pub fn finished(&self) -> Result<(), Interrupted> {
        match &self.interrupted_at {
            Some(at) => Err(Interrupted(format!(
                "{} holds the slice from the paths finished before Ctrl-C (summary.json says \"interrupted\": true); the configurations after it were not run",
                at.display()
            ))),
            None => Ok(()),
        }
    }
}
