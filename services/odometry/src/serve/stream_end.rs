//! Whether the wheel stream has ended.

/// Whether the wheel stream has ended, from the end-of-stream notifications
/// taken after each wakeup's poses.
#[derive(Debug, Default)]
pub(crate) struct StreamEnd {
    ended: bool,
    // While wheel samples wait: an end taken, and wheel samples taken, since
    // the end was last judged.
    end_pending: bool,
    got_wheels: bool,
}

impl StreamEnd {
    /// After a wakeup that took wheel samples or not (`got_wheels`), then the
    /// notifications (`end_taken`: one said the stream ended), with a wheel
    /// sample still waiting or not.
    pub(crate) fn after_wakeup(&mut self, got_wheels: bool, end_taken: bool, sample_waiting: bool) {
        self.got_wheels |= got_wheels;
        self.end_pending |= end_taken;
        if sample_waiting {
            // The samples still waiting were sent before that end: judge it
            // after them. Samples came, so an earlier end is over.
            if got_wheels {
                self.ended = false;
            }
            return;
        }
        let end = std::mem::take(&mut self.end_pending);
        if std::mem::take(&mut self.got_wheels) {
            // A stream that ended may start again (a new replay).
            self.ended = end;
        } else {
            self.ended |= end;
        }
    }

    /// The wheel stream's publisher said it ended, and no wheel sample came since.
    pub(crate) fn ended(&self) -> bool {
        self.ended
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_end_of_stream_is_judged_after_the_samples_that_wait_before_it() {
        // The usual end: the last samples' wakeup, then their end.
        let mut end = StreamEnd::default();
        end.after_wakeup(true, false, false);
        assert!(!end.ended());
        end.after_wakeup(false, true, false);
        assert!(end.ended());
        // The end taken with the last sample's notification while that
        // sample still waits: not ended until it is taken (it used to be
        // forgotten when the next wakeup took the sample).
        let mut end = StreamEnd::default();
        end.after_wakeup(true, true, true);
        assert!(!end.ended());
        end.after_wakeup(true, false, false);
        assert!(end.ended());
        // A new run of the stream after its end.
        end.after_wakeup(true, false, false);
        assert!(!end.ended());
        // Wakeups without wheel samples keep the end.
        end.after_wakeup(false, true, false);
        end.after_wakeup(false, false, false);
        assert!(end.ended());
        // A new run whose first wakeup leaves a sample waiting is not ended.
        end.after_wakeup(true, false, true);
        assert!(!end.ended());
    }
}
