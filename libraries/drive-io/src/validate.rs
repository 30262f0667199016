//! Checks that a drive obeys the format's rules before it is written, so that
//! what is written always reads back (a NaN would be refused on reading).

use super::folder::vehicle_values;
use super::streams::{Stream, WHEELS_NAME};
use super::DriveError;
use interfaces::drive::{Drive, GnssSample, HeadingSample, ImuSample, TruthSample, WheelUnit};

fn invalid(stream: &str, index: usize, message: String) -> DriveError {
    DriveError::InvalidDrive {
        stream: stream.to_string(),
        index,
        message,
    }
}

/// Check one stream: `t_s` finite and strictly increasing, every value finite.
/// `values` lists (field name, value) of one sample.
fn series<T>(
    stream: &str,
    samples: &[T],
    time: impl Fn(&T) -> f64,
    values: impl Fn(&T) -> Vec<(&'static str, Option<f64>)>,
) -> Result<(), DriveError> {
    let mut previous: Option<f64> = None;
    for (i, s) in samples.iter().enumerate() {
        let t = time(s);
        if !t.is_finite() {
            return Err(invalid(stream, i, format!("t_s = {t} is not finite")));
        }
        if let Some(p) = previous {
            if t <= p {
                return Err(invalid(
                    stream,
                    i,
                    format!("t_s = {t} does not increase (previous {p})"),
                ));
            }
        }
        previous = Some(t);
        for (name, v) in values(s) {
            if let Some(v) = v {
                if !v.is_finite() {
                    return Err(invalid(stream, i, format!("{name} = {v} is not finite")));
                }
            }
        }
    }
    Ok(())
}

pub(super) fn drive(d: &Drive) -> Result<(), DriveError> {
    let v = &d.vehicle;
    for (name, value) in vehicle_values(v) {
        if let Some(x) = value {
            if !x.is_finite() {
                return Err(invalid("vehicle", 0, format!("{name} = {x} is not finite")));
            }
        }
    }
    let units = d.wheels.units;
    let has_ticks =
        [Some(units.rl), Some(units.rr), units.fl, units.fr].contains(&Some(WheelUnit::Ticks));
    if has_ticks && v.ticks_per_rev.is_none() {
        return Err(invalid(
            "vehicle",
            0,
            "wheels are in ticks but ticks_per_rev is not set".to_string(),
        ));
    }
    series(
        WHEELS_NAME,
        &d.wheels.samples,
        |s| s.t_s,
        |s| {
            let mut out = vec![
                ("rl", Some(s.rl)),
                ("rr", Some(s.rr)),
                ("fl", s.fl),
                ("fr", s.fr),
            ];
            // A front value without a front column would be lost on writing.
            if units.fl.is_none() && s.fl.is_some() {
                out.push(("fl (no fl unit set)", Some(f64::NAN)));
            }
            if units.fr.is_none() && s.fr.is_some() {
                out.push(("fr (no fr unit set)", Some(f64::NAN)));
            }
            out
        },
    )?;
    stream::<GnssSample>(d)?;
    stream::<ImuSample>(d)?;
    stream::<HeadingSample>(d)?;
    stream::<TruthSample>(d)?;
    Ok(())
}

/// Check stream `S` of the drive, when it has it.
fn stream<S: Stream>(d: &Drive) -> Result<(), DriveError> {
    let Some(samples) = S::of(d) else {
        return Ok(());
    };
    series(S::NAME, samples, S::t_s, |s| {
        (1..S::FIELDS.len())
            .map(|k| (S::FIELDS[k].name, s.value(k)))
            .collect()
    })
}
