//! A stop request from the same process.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

/// A stop request from the same process (a test, or another thread); signals
/// are handled by the WaitSet.
#[derive(Debug, Clone, Default)]
pub(crate) struct Shutdown(Arc<AtomicBool>);

impl Shutdown {
    /// Not requested yet.
    pub(crate) fn new() -> Shutdown {
        Shutdown::default()
    }

    /// Ask the service loop to end (it notices within its tick, 100 ms at most).
    /// The binary's own loop ends on signals; the in-process tests call this.
    #[cfg(test)]
    pub(crate) fn request(&self) {
        self.0.store(true, Ordering::SeqCst);
    }

    /// True once requested.
    pub(crate) fn is_requested(&self) -> bool {
        self.0.load(Ordering::SeqCst)
    }
}
