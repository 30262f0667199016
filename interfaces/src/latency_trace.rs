//! The latency trace file: one line per pose, `t_ns,woke_wall_ns,published_wall_ns`
//! (the pose's sample time, the wall clock at the wakeup that brought its
//! wheel sample, the wall clock when it was handed to the publisher).
//!
//! `odometry serve --latency-trace` writes it, and so does the latency
//! bench's bare relay; the bench reads both. Measurement only: no service
//! reads it back.

use std::path::{Path, PathBuf};

/// Why a latency trace could not be written or read.
#[derive(Debug, thiserror::Error)]
pub enum TraceError {
    /// The file could not be written or read.
    #[error("latency trace {path}: {source}")]
    Io {
        /// The trace file.
        path: PathBuf,
        /// The I/O error.
        source: std::io::Error,
    },
    /// A line that is not the header or three integers.
    #[error(
        "latency trace {path}, line {line}: expected the header `t_ns,woke_wall_ns,published_wall_ns` \
         or three integers, found `{text}`"
    )]
    Line {
        /// The trace file.
        path: PathBuf,
        /// Line number, from 1.
        line: usize,
        /// The line.
        text: String,
    },
}

/// Wall-clock time in ns since the Unix epoch (the one clock every process of
/// the machine shares; 0 if the clock is before 1970).
pub fn wall_clock_ns() -> i128 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as i128)
}

/// The header line of a latency trace.
pub const LATENCY_TRACE_HEADER: &str = "t_ns,woke_wall_ns,published_wall_ns";

/// Read a latency trace written by [`write_latency_trace`]: `(pose time,
/// wakeup wall clock, publish wall clock)` per line, in file order. A wrong
/// header or line is an error naming the file and line.
pub fn read_latency_trace(path: &Path) -> Result<Vec<(i64, i128, i128)>, TraceError> {
    let text = std::fs::read_to_string(path).map_err(|source| TraceError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let bad = |line: usize, text: &str| TraceError::Line {
        path: path.to_path_buf(),
        line,
        text: text.to_string(),
    };
    let mut lines = text.lines().enumerate();
    match lines.next() {
        Some((_, LATENCY_TRACE_HEADER)) => {}
        other => return Err(bad(1, other.map_or("", |(_, l)| l))),
    }
    lines
        .map(|(i, l)| {
            let f: Vec<&str> = l.split(',').collect();
            match f[..] {
                [t, woke, published] => Ok((
                    t.parse().map_err(|_| bad(i + 1, l))?,
                    woke.parse().map_err(|_| bad(i + 1, l))?,
                    published.parse().map_err(|_| bad(i + 1, l))?,
                )),
                _ => Err(bad(i + 1, l)),
            }
        })
        .collect()
}

/// Write a latency trace: a header and one `t_ns,woke_wall_ns,published_wall_ns`
/// line per pose, from `(pose time, wall clock at the wakeup that brought its
/// wheel sample, wall clock when handed to the publisher)`, all ns.
pub fn write_latency_trace(path: &Path, trace: &[(i64, i128, i128)]) -> Result<(), TraceError> {
    use std::fmt::Write as _;
    let mut text = format!("{LATENCY_TRACE_HEADER}\n");
    for (t, woke, published) in trace {
        let _ = writeln!(text, "{t},{woke},{published}");
    }
    std::fs::write(path, text).map_err(|source| TraceError::Io {
        path: path.to_path_buf(),
        source,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_latency_trace_reads_back_and_a_bad_line_is_named() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("trace.csv");
        let rows = vec![(10, 1_000, 1_500), (20, 2_000, 2_400)];
        write_latency_trace(&path, &rows).unwrap();
        assert_eq!(read_latency_trace(&path).unwrap(), rows);

        std::fs::write(
            &path,
            format!("{LATENCY_TRACE_HEADER}\n10,1000,1500\n20,x,2400\n"),
        )
        .unwrap();
        let err = read_latency_trace(&path).unwrap_err();
        assert!(matches!(err, TraceError::Line { line: 3, .. }), "{err}");
        assert!(err.to_string().contains("20,x,2400"), "{err}");

        std::fs::write(&path, "t,a,b\n").unwrap();
        assert!(matches!(
            read_latency_trace(&path),
            Err(TraceError::Line { line: 1, .. })
        ));
    }
}
