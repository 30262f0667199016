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
    quiet_on_closed_stdout();
}

/// The exit status of a process whose standard output was closed by its
/// reader (128 + SIGPIPE, what a shell reports for a tool killed by it).
pub const CLOSED_STDOUT_STATUS: i32 = 141;

/// A reader that closes our standard output early (`calibrator diagnose
/// DRIVE | head`) ends the process quietly with [`CLOSED_STDOUT_STATUS`]
/// instead of a panic's backtrace: Rust ignores SIGPIPE, so `println!`
/// panics on the closed pipe; this hook recognises that one panic and
/// leaves every other to the default hook. Installed once by [`init`].
fn quiet_on_closed_stdout() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            let payload = info.payload();
            let text = payload
                .downcast_ref::<String>()
                .map(String::as_str)
                .or_else(|| payload.downcast_ref::<&str>().copied())
                .unwrap_or("");
            if is_closed_stdout(text) {
                std::process::exit(CLOSED_STDOUT_STATUS);
            }
            default(info);
        }));
    });
}

/// Whether a panic's message is `print!`'s on a closed standard output.
fn is_closed_stdout(message: &str) -> bool {
    message.starts_with("failed printing to stdout") && message.contains("Broken pipe")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_the_closed_stdout_panic_is_quietened() {
        assert!(is_closed_stdout(
            "failed printing to stdout: Broken pipe (os error 32)"
        ));
        assert!(!is_closed_stdout(
            "failed printing to stdout: No space left on device"
        ));
        assert!(!is_closed_stdout("index out of bounds: Broken pipe"));
    }
}
