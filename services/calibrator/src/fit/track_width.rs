//! The track width decision, shared by both methods: whether the effective
//! rear track width is estimated on a drive ([`decide_track`]), and whether
//! an estimate of it is believable ([`implausible_track`]).

use crate::config::{CalibrationConfig, TrackWidthMode};
use crate::error::CalibrationError;
use crate::reference::Reference;
use crate::series::Series;
use crate::warnings::{Warning, WarningCode};

/// Turning below which the drive counts as having no turn, degrees.
pub const NO_TURN_DEG: f64 = 30.0;

/// Whether the track width is estimated on this drive (per the
/// configuration and the turning); an `Auto` decision to keep it is a warning.
pub fn decide_track(
    p: &Series,
    r: &Reference,
    config: &CalibrationConfig,
    warnings: &mut Vec<Warning>,
) -> Result<bool, CalibrationError> {
    let turn_deg = r.total_turn_rad.to_degrees();
    match config.track_width {
        TrackWidthMode::Fixed => Ok(false),
        TrackWidthMode::Estimate => {
            if turn_deg < NO_TURN_DEG {
                return Err(CalibrationError::Unobservable {
                    parameter: "track_width_m",
                    reason: format!("the drive turns only {turn_deg:.0} deg in total; the track width needs turns"),
                });
            }
            Ok(true)
        }
        TrackWidthMode::Auto => {
            let ok = turn_deg >= 3.0 * NO_TURN_DEG;
            if !ok
                && !warnings
                    .iter()
                    .any(|w| w.code == WarningCode::TrackWidthFixed)
            {
                warnings.push(Warning::new(
                    WarningCode::TrackWidthFixed,
                    format!(
                        "track width kept at the nominal {:.3} m: the drive turns only {turn_deg:.0} deg (at least {:.0} needed to estimate it)",
                        p.track,
                        3.0 * NO_TURN_DEG
                    ),
                ));
            }
            Ok(ok)
        }
    }
}

/// Relative deviation of an estimated track width from the nominal beyond
/// which it is not believed: the effective track differs from the physical
/// one by a few percent (physics catalogue: 1-3 %).
pub const TRACK_PLAUSIBLE_REL: f64 = 0.1;

/// A warning when the estimated track width `t` is implausible (in `Auto`
/// mode the caller then keeps the nominal value).
pub fn implausible_track(t: f64, nominal: f64, mode: TrackWidthMode) -> Option<Warning> {
    ((t / nominal - 1.0).abs() > TRACK_PLAUSIBLE_REL).then(|| {
        Warning::new(
            WarningCode::TrackWidthImplausible,
            format!(
                "the estimated effective track width {t:.3} m is {:+.0} % from the nominal {nominal:.3} m, more than the \
                 {:.0} % a real track differs: physics the 2W model leaves out (GNSS antenna position, time offset, \
                 wheel rate errors) is being absorbed by it; {}",
                100.0 * (t / nominal - 1.0),
                100.0 * TRACK_PLAUSIBLE_REL,
                if mode == TrackWidthMode::Auto {
                    "the nominal value is kept and the fit repeated"
                } else {
                    "kept because --track-width estimate was asked for"
                }
            ),
        )
    })
}
