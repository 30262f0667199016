//! What every channel written into a recording provides (our own streams
//! and Foxglove's), and the log time of a drive time: shared by the writer
//! and the Foxglove channels.

use std::collections::BTreeMap;

/// One stream of the drive on its way into the recording.
pub(super) trait Outgoing {
    /// Name in errors.
    fn name(&self) -> &'static str;
    /// Channel topic.
    fn topic(&self) -> &'static str;
    /// Schema name.
    fn schema_name(&self) -> &'static str;
    /// Schema (JSON schema text).
    fn schema(&self) -> Vec<u8>;
    /// Channel metadata (none unless a channel says otherwise).
    fn metadata(&self) -> BTreeMap<String, String> {
        BTreeMap::new()
    }
    /// The sample times, in order.
    fn times(&self) -> Box<dyn Iterator<Item = f64> + '_>;
    /// JSON of sample `i` into `buf`; `None` when there is no sample `i`.
    fn encode(&self, i: usize, buf: &mut Vec<u8>) -> Option<serde_json::Result<()>>;
}

/// The log time of drive time `t` (s): round(t · 1e9) + `offset_ns`, kept
/// within the unsigned nanoseconds MCAP has.
pub(super) fn log_time_ns(t: f64, offset_ns: u64) -> u64 {
    let ns = (t * 1e9).round() as i64 as i128 + offset_ns as i128;
    ns.clamp(0, u64::MAX as i128) as u64
}
