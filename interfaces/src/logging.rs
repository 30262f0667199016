//! The one tracing setup shared by every binary.
//!
//! Log level comes from `RUST_LOG` (default `info`); iceoryx2's own log goes
//! through the same subscriber because the workspace builds it with its
//! `tracing` feature.

use std::io::IsTerminal as _;
use tracing_subscriber::EnvFilter;

/// Install the global tracing subscriber, writing to standard error, with
/// colours only when standard error is a terminal (a log file or a pipe
/// gets plain text).
///
/// Safe to call more than once (later calls do nothing), so tests may call it.
pub fn init() {
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new("info"));
    let _ = tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_target(false)
        .with_ansi(std::io::stderr().is_terminal())
        .try_init();
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Warn);
}
