//! Measurements waiting for a wheel sample: a fix or a heading is applied
//! at its own time, once the wheel sample after it has come.

/// Measurements waiting for a wheel sample, at most.
pub const MAX_PENDING: usize = 256;

/// A fix or a heading, with its 1-sigma.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum Measurement {
    Gnss {
        t_s: f64,
        x_m: f64,
        y_m: f64,
        sigma_m: f64,
    },
    Heading {
        t_s: f64,
        yaw_rad: f64,
        sigma_rad: f64,
    },
}

impl Measurement {
    /// Time of the measurement, s.
    pub(super) fn t_s(&self) -> f64 {
        match *self {
            Measurement::Gnss { t_s, .. } | Measurement::Heading { t_s, .. } => t_s,
        }
    }

    /// Order at equal times, the same as
    /// [`Input::rank`](crate::inputs::Input::rank).
    pub(super) fn rank(&self) -> u8 {
        match self {
            Measurement::Gnss { .. } => 1,
            Measurement::Heading { .. } => 2,
        }
    }
}

/// The measurements waiting, in the order they came.
#[derive(Debug, Clone, Default)]
pub(super) struct Pending(Vec<Measurement>);

impl Pending {
    /// Queue a measurement; without wheel samples the queue keeps only the
    /// newest [`MAX_PENDING`]. Returns whether the oldest was dropped for it.
    pub(super) fn push(&mut self, m: Measurement) -> bool {
        let dropped = self.0.len() >= MAX_PENDING;
        if dropped {
            self.0.remove(0);
        }
        self.0.push(m);
        dropped
    }

    /// Take the measurements up to `t1_s`, in time order (a fix before a
    /// heading of the same time, as in `crate::inputs`, whatever order they
    /// were queued in).
    pub(super) fn take_due(&mut self, t1_s: f64) -> Vec<Measurement> {
        self.0
            .sort_by(|a, b| a.t_s().total_cmp(&b.t_s()).then(a.rank().cmp(&b.rank())));
        let due = self.0.partition_point(|m| m.t_s() <= t1_s);
        self.0.drain(..due).collect()
    }

    /// Forget every measurement waiting.
    pub(super) fn clear(&mut self) {
        self.0.clear();
    }
}
