//! When the next wheel sample is due, so that a serving loop can wake a
//! little before it ([`WheelCadence`]). Pure: the caller passes the clock.
//!
//! Why: between two wheel samples (10 ms at 100 Hz) the process sleeps, and
//! on the machines we measured the first pass after such a sleep runs on cold
//! caches and TLB (BENCHMARKS.md, "Sample-to-pose latency": a few ns per
//! instruction instead of one). A pass of the loop without a sample, 1 to 2 ms
//! before the sample is due, warms them, so the sample's own pass is short.
//! It costs one extra wakeup per sample and does no work a sample needs.

use std::time::{Duration, Instant};

/// Gaps between wheel wakeups outside this range are pauses or bursts, not
/// the sample rate (wheel rates of 5 to 1000 Hz).
const PERIOD_RANGE: (Duration, Duration) = (Duration::from_millis(1), Duration::from_millis(200));

/// The wheel samples' wall-clock cadence, learned from the wakeups that
/// brought them, and the wait until `lead` before the next one is due.
#[derive(Debug, Clone)]
pub struct WheelCadence {
    lead: Duration,
    /// The last wakeup that brought wheel samples.
    last: Option<Instant>,
    /// The shortest recent gap between such wakeups.
    period: Option<Duration>,
    /// The early pass before the next sample has run.
    early_pass_done: bool,
}

impl WheelCadence {
    /// Wake `lead` before each sample; a zero `lead` never wakes early.
    pub fn new(lead: Duration) -> WheelCadence {
        WheelCadence {
            lead,
            last: None,
            period: None,
            early_pass_done: false,
        }
    }

    /// A wakeup at `now` brought wheel samples (call once per wakeup).
    pub fn wheels_at(&mut self, now: Instant) {
        if let Some(last) = self.last {
            let gap = now.saturating_duration_since(last);
            if (PERIOD_RANGE.0..=PERIOD_RANGE.1).contains(&gap) {
                self.period = Some(match self.period {
                    // A shorter gap is the rate (or its jitter) at once; a
                    // longer one (a late wakeup, a slower rate) only slowly,
                    // so that one late wakeup does not make the next early
                    // wakeup late.
                    Some(p) if gap > p => p + (gap - p) / 16,
                    _ => gap,
                });
            }
        }
        self.last = Some(now);
        self.early_pass_done = false;
    }

    /// Before the loop waits at `now`: how long to wait at most, so that it
    /// wakes `lead` to `lead` + 1 ms before the next sample is due (`None`:
    /// block until an event: the early pass has run, or its point has
    /// passed, or the rate is not known yet). Whole milliseconds, rounded
    /// down, because an iceoryx2 WaitSet waits in whole milliseconds rounded
    /// up.
    pub fn wait_for_early_wakeup(&self, now: Instant) -> Option<Duration> {
        if self.lead.is_zero() || self.early_pass_done {
            return None;
        }
        let wait = self.early_point()?.checked_duration_since(now)?;
        Some(Duration::from_millis(
            u64::try_from(wait.as_millis()).unwrap_or(u64::MAX),
        ))
    }

    /// A pass of the loop at `now` that brought no wheel sample: is it the
    /// early pass (at most 1 ms before the early point, or after it, and the
    /// first since the last sample)? Then it is marked as run. Whatever
    /// woke the pass (the early wakeup's timeout, or another event such as
    /// a tick that falls near the sample), once per sample.
    pub fn take_early_pass(&mut self, now: Instant) -> bool {
        if self.lead.is_zero() || self.early_pass_done {
            return false;
        }
        let Some(at) = self.early_point() else {
            return false;
        };
        self.early_pass_done = now + Duration::from_millis(1) >= at;
        self.early_pass_done
    }

    /// `lead` before the next sample is due, once the rate is known.
    fn early_point(&self) -> Option<Instant> {
        (self.last? + self.period?).checked_sub(self.lead)
    }

    /// The learned gap between wheel samples, once two have come.
    pub fn period(&self) -> Option<Duration> {
        self.period
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    fn steady(lead: Duration, start: Instant, samples: u32) -> WheelCadence {
        let mut c = WheelCadence::new(lead);
        for k in 0..samples {
            c.wheels_at(start + 10 * MS * k);
        }
        c
    }

    #[test]
    fn it_wakes_a_lead_before_the_next_sample_once() {
        let t0 = Instant::now();
        let mut c = steady(MS, t0, 3);
        assert_eq!(c.period(), Some(10 * MS));
        // Last sample at 20 ms, next due at 30 ms: wake at 29 ms, from 20.3 ms
        // that is 8.7 ms, rounded down to 8 ms (so 1 to 2 ms early).
        let now = t0 + 20 * MS + MS * 3 / 10;
        assert_eq!(c.wait_for_early_wakeup(now), Some(8 * MS));
        // A tick before that is not the early pass, and the wait stays.
        assert!(!c.take_early_pass(now + 3 * MS));
        assert_eq!(c.wait_for_early_wakeup(now + 3 * MS), Some(5 * MS));
        // The early wakeup, once: then block until the sample.
        assert!(c.take_early_pass(now + 8 * MS));
        assert!(!c.take_early_pass(now + 8 * MS));
        assert_eq!(c.wait_for_early_wakeup(now + 8 * MS), None);
        c.wheels_at(t0 + 30 * MS);
        assert!(c.wait_for_early_wakeup(t0 + 30 * MS).is_some());
        // A tick that falls after the early point is the early pass.
        assert!(!c.take_early_pass(t0 + 33 * MS));
        assert!(c.take_early_pass(t0 + 39 * MS + MS / 2));
        assert_eq!(c.wait_for_early_wakeup(t0 + 39 * MS + MS / 2), None);
    }

    #[test]
    fn nothing_early_before_the_rate_is_known_or_when_off_or_too_late() {
        let t0 = Instant::now();
        let mut one = steady(MS, t0, 1);
        assert_eq!(one.wait_for_early_wakeup(t0), None);
        assert!(!one.take_early_pass(t0 + 5 * MS));
        let mut off = steady(Duration::ZERO, t0, 5);
        assert_eq!(off.wait_for_early_wakeup(t0 + 40 * MS), None);
        assert!(!off.take_early_pass(t0 + 49 * MS));
        // Past the early point (49 ms) already: block, do not spin.
        let late = steady(MS, t0, 5);
        assert_eq!(late.wait_for_early_wakeup(t0 + 49 * MS + MS / 2), None);
    }

    #[test]
    fn a_late_wakeup_barely_moves_the_rate_and_a_faster_rate_is_taken_at_once() {
        let t0 = Instant::now();
        let mut c = steady(MS, t0, 3);
        // Two samples in one late wakeup: a 20 ms gap.
        c.wheels_at(t0 + 40 * MS);
        assert_eq!(c.period(), Some(10 * MS + 10 * MS / 16));
        // A pause of a second is not a rate.
        c.wheels_at(t0 + 1040 * MS);
        assert_eq!(c.period(), Some(10 * MS + 10 * MS / 16));
        // 200 Hz from now on.
        c.wheels_at(t0 + 1045 * MS);
        assert_eq!(c.period(), Some(5 * MS));
    }
}
