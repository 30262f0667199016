//! GNSS fixes read at the receiver's epochs: a logger that stamps a fix
//! when it arrives puts the arrival's jitter on a position the receiver
//! took on its regular epoch ([`stats::stamps::stamp_jitter`]). At 17 m/s,
//! comma2k19's 8.6 ms RMS is 0.15 m of along-track scatter, ten times the
//! fixes' own (0.014 m); wid-trial02's 3.4 ms doubles its 6 mm.
//!
//! The repair is decided by the drive's own fixes: each fix's distance
//! from the line between its neighbours, at the stamps and at the epochs.
//! Only where the epochs bring the fixes clearly closer to a smooth motion
//! ([`MIN_SCATTER_GAIN`]) are the stamps moved; a receiver whose positions
//! truly belong to their stamps keeps them.

use super::Finding;
use interfaces::drive::Drive;

pub use stats::stamps::{MIN_JITTER_S, MIN_SCATTER_GAIN};

/// `drive` with its GNSS fixes at the receiver's epochs, and a
/// [`Finding::GnssStampsOnEpochs`] saying so; `None` when the stamps are
/// regular, too few, not a receiver's, or when the epochs do not bring the
/// fixes closer to a smooth motion than the stamps by
/// [`MIN_SCATTER_GAIN`].
pub fn gnss_on_epochs(drive: &Drive) -> Option<(Drive, Finding)> {
    let fixes = drive.gnss.as_deref()?;
    let stamps: Vec<f64> = fixes.iter().map(|f| f.t_s).collect();
    let x: Vec<f64> = fixes.iter().map(|f| f.x_m).collect();
    let y: Vec<f64> = fixes.iter().map(|f| f.y_m).collect();
    let stats::stamps::OnEpochs {
        epochs,
        jitter_rms_s: rms,
        scatter_stamps_m: at_stamps,
        scatter_epochs_m: at_epochs,
    } = stats::stamps::on_epochs(&stamps, &x, &y)?;
    let moved = stamps.iter().zip(&epochs).filter(|(s, e)| s != e).count();
    let mut out = drive.clone();
    if let Some(g) = out.gnss.as_mut() {
        for (f, e) in g.iter_mut().zip(&epochs) {
            f.t_s = *e;
        }
    }
    Some((
        out,
        Finding::GnssStampsOnEpochs {
            jitter_rms_s: rms,
            fixes: moved,
            scatter_stamps_m: at_stamps,
            scatter_epochs_m: at_epochs,
        },
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::drive::{GnssSample, VehicleParams, WheelSeries, WheelUnit, WheelUnits};

    fn drive_with(fixes: Vec<GnssSample>) -> Drive {
        Drive {
            vehicle: VehicleParams {
                name: None,
                track_width_m: 1.5,
                nominal_circumference_m: 2.0,
                wheelbase_m: None,
                ticks_per_rev: None,
                gnss: Default::default(),
            },
            wheels: WheelSeries {
                units: WheelUnits {
                    rl: WheelUnit::RadS,
                    rr: WheelUnit::RadS,
                    fl: None,
                    fr: None,
                },
                samples: Vec::new(),
            },
            gnss: Some(fixes),
            imu: None,
            heading: None,
            truth: None,
            truth_params: None,
        }
    }

    /// A car at 20 m/s north, fixes taken every 0.1 s with 1 cm of noise,
    /// stamped on arrival with up to 10 ms of jitter: read at its epochs,
    /// the fixes' scatter drops to their own noise, every fix is moved
    /// back to its epoch, and the repair says so.
    #[test]
    fn jittered_stamps_are_read_at_the_receivers_epochs() {
        let jit = |k: usize| 0.01 * (((k * 7919) % 11) as f64 / 5.0 - 1.0);
        let noise = |k: usize| 0.01 * (((k * 104_729) % 13) as f64 / 6.0 - 1.0);
        let fixes: Vec<GnssSample> = (0..600)
            .map(|k| GnssSample {
                t_s: 5.0 + 0.1 * k as f64 + jit(k),
                x_m: noise(k + 7),
                y_m: 20.0 * 0.1 * k as f64 + noise(k),
                sigma_m: None,
            })
            .collect();
        let d = drive_with(fixes);
        let (r, f) = gnss_on_epochs(&d).expect("the jitter is repaired");
        let Finding::GnssStampsOnEpochs {
            jitter_rms_s,
            fixes,
            scatter_stamps_m,
            scatter_epochs_m,
        } = f
        else {
            panic!("{f:?}");
        };
        assert!((jitter_rms_s - 0.0063).abs() < 1.5e-3, "{jitter_rms_s}");
        assert!(fixes > 500, "{fixes}");
        assert!(scatter_stamps_m > 0.05, "{scatter_stamps_m}");
        assert!(scatter_epochs_m < 0.02, "{scatter_epochs_m}");
        let g = r.gnss.as_deref().unwrap_or_default();
        let worst = g
            .iter()
            .enumerate()
            .skip(30)
            .take(540)
            .map(|(k, s)| (s.t_s - (5.0 + 0.1 * k as f64)).abs())
            .fold(0.0_f64, f64::max);
        assert!(worst < 2e-3, "{worst}");
        assert!(!f.is_error());
    }

    /// Positions that truly belong to their irregular stamps (a receiver
    /// that reports when it measures) keep them: the epochs would bend the
    /// motion, so nothing is moved. Regular stamps are left alone too.
    #[test]
    fn stamps_that_the_positions_follow_are_kept() {
        let jit = |k: usize| 0.01 * (((k * 7919) % 11) as f64 / 5.0 - 1.0);
        let at_stamp: Vec<GnssSample> = (0..600)
            .map(|k| {
                let t = 5.0 + 0.1 * k as f64 + jit(k);
                GnssSample {
                    t_s: t,
                    x_m: 0.0,
                    y_m: 20.0 * t,
                    sigma_m: None,
                }
            })
            .collect();
        assert!(gnss_on_epochs(&drive_with(at_stamp)).is_none());
        let regular: Vec<GnssSample> = (0..600)
            .map(|k| GnssSample {
                t_s: 0.1 * k as f64,
                x_m: 0.0,
                y_m: 2.0 * k as f64,
                sigma_m: None,
            })
            .collect();
        assert!(gnss_on_epochs(&drive_with(regular)).is_none());
    }
}
