//! Helpers of the latency benchmarks: the PM QoS CPU latency request and
//! percentiles.

/// Holds the machine's PM QoS CPU latency request at 0 while alive (what
/// `tuned`'s latency-performance profile and cyclictest do): idle cores poll
/// instead of halting, so a wakeup does not wait for a core to come out of
/// its idle state. The request ends when the file is closed.
pub struct CpuLatencyZero(#[allow(dead_code)] std::fs::File);

impl CpuLatencyZero {
    /// Make the request; needs write access to `/dev/cpu_dma_latency` (root).
    pub fn hold() -> std::io::Result<CpuLatencyZero> {
        use std::io::Write as _;
        let mut f = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/cpu_dma_latency")?;
        f.write_all(&0i32.to_ne_bytes())?;
        Ok(CpuLatencyZero(f))
    }
}

/// The `p` quantile (0..=1, nearest rank) of sorted values; NaN when empty
/// (one home: [`stats::nearest_rank`]).
pub use stats::nearest_rank as quantile;
