//! Wheel values beyond any car set aside, so that a logger glitch costs the
//! samples it hit and not the drive.
//!
//! A value is impossible when it means a wheel rate beyond
//! [`wheel_rate_limit`](super::wheel_rate_limit): for a rate unit the
//! sample itself, for a cumulative count the step from the last good value
//! over the time since it (the counter's resolution allowed on top).
//!
//! - **Rates** (`_rad_s`, `_m_s`): the sample is set aside. A rear value
//!   takes its row with it (the two rear wheels are read together; the
//!   rates are integrated across the lost row, a sample interval); a front
//!   value is emptied, since the rear-wheel model never reads it.
//! - **Counts** (`_rev`, `_ticks`): a value whose step is impossible and
//!   after which the counter comes back (within [`SPIKE_LOOKAHEAD`]
//!   samples) to where the last good value says it could be is a spike:
//!   set aside like a rate. A step that stays is a jump of the counter:
//!   the values after it are re-referenced so that the counter continues
//!   from the last good value at the rate it had before (the distance of
//!   that one interval is the only thing estimated). A jump so large that
//!   the later values lose their increments in floating point (a 1e308
//!   glitch) leaves the wheel standing still after it, which the checks
//!   after this one report as a stuck wheel.
//!
//! A wheel of which more than [`MAX_SET_ASIDE_SHARE`] of the samples are
//! impossible is not glitching: its unit or `ticks_per_rev` is wrong. A rear
//! wheel like that is reported as [`Finding::ImpossibleWheelRate`] (an
//! error: what is left cannot support a calibration); a front wheel is
//! emptied with a warning.

use super::{count_quantum, rev_scale, set_value, value_of, wheel_rate_limit, Finding};
use interfaces::drive::{Drive, Wheel, WheelUnit};

/// How many samples after an impossible count value a spike may last
/// before the step counts as a jump that stays.
pub const SPIKE_LOOKAHEAD: usize = 20;

/// A wheel with more than this share of impossible samples has a wrong unit
/// or `ticks_per_rev`, not a glitch.
pub const MAX_SET_ASIDE_SHARE: f64 = 0.5;

/// What happened to one wheel's impossible values.
#[derive(Debug, Clone, Copy, PartialEq)]
struct WheelGlitches {
    /// Sample indices set aside (spikes and impossible rates).
    spikes: usize,
    /// Jumps of the counter re-referenced.
    jumps: usize,
    /// Time, value and rate of the first impossible one.
    first: (f64, f64, f64),
    /// Samples of the wheel with a finite value.
    samples: usize,
}

/// Set aside the wheel values beyond any car (see the module's text).
/// Returns `None` when there are none; else the drive without them and a
/// finding per wheel: [`Finding::WheelSamplesSetAside`] (a warning), or
/// [`Finding::ImpossibleWheelRate`] (an error) for a rear wheel that is
/// impossible throughout.
pub fn set_aside_impossible(drive: &Drive) -> Option<(Drive, Vec<Finding>)> {
    let limit = wheel_rate_limit(drive);
    let mut out: Option<Drive> = None;
    let mut findings = Vec::new();
    // Rows to drop (rear spikes), collected over both rear wheels.
    let mut drop_rows = vec![false; drive.wheels.samples.len()];
    for wheel in Wheel::ALL {
        let Some(unit) = drive.wheels.units.of(wheel) else {
            continue;
        };
        let Some(k) = rev_scale(drive, unit) else {
            continue;
        };
        let d = out.as_ref().unwrap_or(drive);
        let Some((glitches, bad, offsets)) = scan(d, wheel, unit, k, limit) else {
            continue;
        };
        let rear = matches!(wheel, Wheel::Rl | Wheel::Rr);
        let total = glitches.spikes + glitches.jumps;
        let (t_s, value, rev_per_s) = glitches.first;
        if rear && total as f64 > MAX_SET_ASIDE_SHARE * glitches.samples as f64 {
            findings.push(Finding::ImpossibleWheelRate {
                wheel,
                t_s,
                value,
                unit,
                rev_per_s,
                limit_rev_per_s: limit,
                samples: total,
            });
            continue;
        }
        let d = out.get_or_insert_with(|| drive.clone());
        for (i, s) in d.wheels.samples.iter_mut().enumerate() {
            if bad[i] {
                if rear {
                    drop_rows[i] = true;
                } else {
                    match wheel {
                        Wheel::Fl => s.fl = None,
                        _ => s.fr = None,
                    }
                }
            } else if offsets[i] != 0.0 {
                if let Some(v) = value_of(s, wheel) {
                    set_value(s, wheel, v + offsets[i]);
                }
            }
        }
        findings.push(Finding::WheelSamplesSetAside {
            wheel,
            t_s,
            value,
            unit,
            rev_per_s,
            limit_rev_per_s: limit,
            set_aside: glitches.spikes,
            jumps: glitches.jumps,
            samples: glitches.samples,
        });
    }
    if findings.is_empty() {
        return None;
    }
    if let Some(d) = out.as_mut() {
        if drop_rows.iter().any(|b| *b) {
            let mut keep = drop_rows.iter().map(|b| !b);
            d.wheels.samples.retain(|_| keep.next().unwrap_or(true));
        }
    }
    Some((out.unwrap_or_else(|| drive.clone()), findings))
}

/// Per-sample verdicts of one wheel: what it holds, which samples are set
/// aside, and the offset to add to each (re-referenced jumps); `None`
/// when every value is possible.
fn scan(
    drive: &Drive,
    wheel: Wheel,
    unit: WheelUnit,
    k: f64,
    limit: f64,
) -> Option<(WheelGlitches, Vec<bool>, Vec<f64>)> {
    let samples = &drive.wheels.samples;
    let n = samples.len();
    let mut bad = vec![false; n];
    let mut offsets = vec![0.0; n];
    let mut first: Option<(f64, f64, f64)> = None;
    let (mut spikes, mut jumps) = (0usize, 0usize);
    let values: Vec<Option<f64>> = samples
        .iter()
        .map(|s| value_of(s, wheel).filter(|v| v.is_finite() && s.t_s.is_finite()))
        .collect();
    let finite = values.iter().filter(|v| v.is_some()).count();
    if unit.is_rate() {
        for (i, v) in values.iter().enumerate() {
            if let Some(v) = v {
                let r = (v * k).abs();
                if r > limit {
                    bad[i] = true;
                    spikes += 1;
                    first.get_or_insert((samples[i].t_s, *v, r));
                }
            }
        }
    } else {
        let quantum = count_quantum(values.iter().flatten().copied(), k);
        let possible = |from: (f64, f64), to: (f64, f64)| {
            let dt = to.0 - from.0;
            dt > 0.0 && ((to.1 - from.1) * k).abs() - quantum <= limit * dt
        };
        // The last good (time, value as re-referenced) and its rate, rev/unit per s.
        let mut good: Option<(f64, f64)> = None;
        let mut rate = 0.0;
        let mut offset = 0.0;
        let mut i = 0;
        while i < n {
            let Some(raw) = values[i] else {
                i += 1;
                continue;
            };
            let here = (samples[i].t_s, raw + offset);
            let Some(g) = good else {
                good = Some(here);
                offsets[i] = offset;
                i += 1;
                continue;
            };
            if possible(g, here) {
                if here.0 > g.0 {
                    rate = (here.1 - g.1) / (here.0 - g.0);
                }
                good = Some(here);
                offsets[i] = offset;
                i += 1;
                continue;
            }
            let dt = here.0 - g.0;
            first.get_or_insert((
                here.0,
                raw,
                if dt > 0.0 {
                    ((here.1 - g.1) * k).abs() / dt
                } else {
                    f64::INFINITY
                },
            ));
            // A spike: the counter comes back within the look-ahead.
            let back = (i + 1..n.min(i + 1 + SPIKE_LOOKAHEAD))
                .find(|&j| values[j].is_some_and(|v| possible(g, (samples[j].t_s, v + offset))));
            match back {
                Some(j) => {
                    for (b, v) in bad[i..j].iter_mut().zip(&values[i..j]) {
                        if v.is_some() {
                            *b = true;
                            spikes += 1;
                        }
                    }
                    i = j;
                }
                None => {
                    // A jump that stays: continue from the last good value
                    // at the rate it had.
                    offset += g.1 + rate * dt - here.1;
                    jumps += 1;
                    let v = raw + offset;
                    good = Some((here.0, v));
                    offsets[i] = offset;
                    i += 1;
                }
            }
        }
    }
    let first = first?;
    Some((
        WheelGlitches {
            spikes,
            jumps,
            first,
            samples: finite,
        },
        bad,
        offsets,
    ))
}
