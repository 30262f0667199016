//! The body point scored against `truth.csv`: the rear-axle centre, a
//! given point, or the GNSS antenna when the truth is the GNSS track.

use super::error::EvaluateError;
use interfaces::drive::Drive;
use serde::Serialize;

/// A GNSS fix and a truth row this close in time are at the same instant, s.
const SAME_INSTANT_S: f64 = 1e-6;
/// A truth row this close to the fix of its instant is at the fix, m.
const SAME_POINT_M: f64 = 1e-3;
/// Fixes with a truth row at their instant needed to call the truth the GNSS track.
const MIN_COINCIDENT_FIXES: usize = 10;

/// How many GNSS fixes have a truth row at their instant, and at how many of
/// those the truth row is at the fix (within 1 mm).
pub fn truth_gnss_coincidence(drive: &Drive) -> (usize, usize) {
    let (Some(truth), Some(gnss)) = (&drive.truth, &drive.gnss) else {
        return (0, 0);
    };
    let (mut same_instant, mut same_point) = (0, 0);
    let mut k = 0;
    for fix in gnss {
        // Both files are in time order (the drive reader checks it).
        while k < truth.len() && truth[k].t_s < fix.t_s - SAME_INSTANT_S {
            k += 1;
        }
        let Some(row) = truth.get(k).filter(|r| r.t_s <= fix.t_s + SAME_INSTANT_S) else {
            continue;
        };
        same_instant += 1;
        if (row.x_m - fix.x_m).hypot(row.y_m - fix.y_m) <= SAME_POINT_M {
            same_point += 1;
        }
    }
    (same_instant, same_point)
}

/// Whether `truth.csv` is the GNSS track itself: at least
/// `MIN_COINCIDENT_FIXES` (10) fixes have a truth row at their instant, and
/// every one of those rows is at its fix. An RTK receiver's track given as
/// the truth (the WID drives) is such a truth: it follows the GNSS antenna,
/// not the rear-axle centre. A truth of the rear axle (the simulator's) or of
/// an INS (comma2k19's) is not.
pub fn truth_is_the_gnss_track(drive: &Drive) -> bool {
    let (same_instant, same_point) = truth_gnss_coincidence(drive);
    same_instant >= MIN_COINCIDENT_FIXES && same_point == same_instant
}

/// Where the scored body point's position comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum TruthPointSource {
    /// The rear-axle centre.
    Axle,
    /// Given by the user (`--truth-point X,Y`).
    Given,
    /// The GNSS antenna as `vehicle.toml`'s `[gnss]` measures it.
    MeasuredAntenna,
    /// The GNSS antenna as the estimate's calibration found it.
    EstimatedAntenna,
}

/// The body point scored against `truth.csv`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TruthPoint {
    /// Body-frame position (x forward, y left) from the rear-axle centre, m.
    pub point_m: [f64; 2],
    /// Where it comes from.
    pub source: TruthPointSource,
}

impl TruthPoint {
    /// The rear-axle centre.
    pub const AXLE: TruthPoint = TruthPoint {
        point_m: [0.0, 0.0],
        source: TruthPointSource::Axle,
    };
}

/// How the scored body point is asked for (`odometry evaluate --truth-point`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TruthPointChoice {
    /// The GNSS antenna when `truth.csv` is the GNSS track
    /// ([`truth_is_the_gnss_track`]) and the antenna's position is known,
    /// else the rear-axle centre.
    Auto,
    /// The rear-axle centre.
    Axle,
    /// The GNSS antenna (measured in `vehicle.toml`, else the estimate's).
    Antenna,
    /// A given body point, m.
    At([f64; 2]),
}

impl std::str::FromStr for TruthPointChoice {
    type Err = EvaluateError;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let bad = || {
            EvaluateError::Config(format!(
                "truth point `{text}`: expected auto, axle, antenna or X,Y in metres"
            ))
        };
        match text {
            "auto" => Ok(TruthPointChoice::Auto),
            "axle" => Ok(TruthPointChoice::Axle),
            "antenna" => Ok(TruthPointChoice::Antenna),
            xy => {
                let v: Vec<f64> = xy
                    .split(',')
                    .map(|s| s.trim().parse::<f64>())
                    .collect::<Result<_, _>>()
                    .map_err(|_| bad())?;
                match v[..] {
                    [x, y] if x.is_finite() && y.is_finite() => Ok(TruthPointChoice::At([x, y])),
                    _ => Err(bad()),
                }
            }
        }
    }
}

/// The body point to score `drive` at, as `choice` asks: the antenna is the
/// one `vehicle.toml` measures (`[gnss] antenna_x_m, antenna_y_m`), else
/// `estimated_antenna` (the estimate's calibration). `Antenna` with neither is
/// an error; `Auto` with neither falls back to the rear axle (the report's
/// `truth_is_gnss_track` then tells that the score includes the lever arm).
pub fn choose_truth_point(
    drive: &Drive,
    choice: TruthPointChoice,
    estimated_antenna: Option<[f64; 2]>,
) -> Result<TruthPoint, EvaluateError> {
    let gnss = &drive.vehicle.gnss;
    let antenna = match (gnss.antenna_x_m, gnss.antenna_y_m) {
        (Some(x), Some(y)) => Some(TruthPoint {
            point_m: [x, y],
            source: TruthPointSource::MeasuredAntenna,
        }),
        _ => estimated_antenna.map(|point_m| TruthPoint {
            point_m,
            source: TruthPointSource::EstimatedAntenna,
        }),
    };
    match choice {
        TruthPointChoice::Axle => Ok(TruthPoint::AXLE),
        TruthPointChoice::At(point_m) => Ok(TruthPoint {
            point_m,
            source: TruthPointSource::Given,
        }),
        TruthPointChoice::Antenna => antenna.ok_or_else(|| {
            EvaluateError::Config(
                "the antenna's position is not known: vehicle.toml has no [gnss] antenna_x_m, \
                 antenna_y_m and the estimate has none (gyro.antenna_m or gnss_antenna_m)"
                    .to_string(),
            )
        }),
        TruthPointChoice::Auto => Ok(match antenna {
            Some(a) if truth_is_the_gnss_track(drive) => a,
            _ => TruthPoint::AXLE,
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::evaluate::test_drives::{antenna_truth_drive, winding_drive, ANTENNA};

    #[test]
    fn a_measured_antenna_wins_and_a_truth_apart_from_the_fixes_stays_at_the_axle() {
        let mut drive = antenna_truth_drive(0.0);
        drive.vehicle.gnss.antenna_x_m = Some(0.5);
        drive.vehicle.gnss.antenna_y_m = Some(-0.25);
        let measured = TruthPoint {
            point_m: [0.5, -0.25],
            source: TruthPointSource::MeasuredAntenna,
        };
        for choice in [TruthPointChoice::Auto, TruthPointChoice::Antenna] {
            assert_eq!(
                choose_truth_point(&drive, choice, Some(ANTENNA)).unwrap(),
                measured
            );
        }
        // Fixes 2 cm off the truth: the truth is not the GNSS track.
        let apart = antenna_truth_drive(0.02);
        assert_eq!(truth_gnss_coincidence(&apart), (601, 0));
        assert!(!truth_is_the_gnss_track(&apart));
        assert_eq!(
            choose_truth_point(&apart, TruthPointChoice::Auto, Some(ANTENNA)).unwrap(),
            TruthPoint::AXLE
        );
        // No fixes at all (a drive with a truth but no gnss.csv).
        assert!(!truth_is_the_gnss_track(&winding_drive(60.0)));
        assert_eq!(
            choose_truth_point(&drive, TruthPointChoice::At([1.0, 0.5]), None).unwrap(),
            TruthPoint {
                point_m: [1.0, 0.5],
                source: TruthPointSource::Given
            }
        );
    }

    #[test]
    fn truth_point_choices_are_read_and_bad_ones_named() {
        let read = |s: &str| s.parse::<TruthPointChoice>();
        assert_eq!(read("auto").unwrap(), TruthPointChoice::Auto);
        assert_eq!(read("axle").unwrap(), TruthPointChoice::Axle);
        assert_eq!(read("antenna").unwrap(), TruthPointChoice::Antenna);
        assert_eq!(
            read(" 0.5, -0.2").unwrap(),
            TruthPointChoice::At([0.5, -0.2])
        );
        for bad in ["0.5", "x,y", "nan,0", "1,2,3", "Antenna"] {
            let err = read(bad).unwrap_err().to_string();
            assert!(err.contains(&format!("`{bad}`")), "{err}");
        }
    }
}
