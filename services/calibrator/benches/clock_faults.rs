//! Clock faults: for 3 seeds of the paper scenario, the wheel clock shifted
//! against the GNSS (and IMU) and the IMU clock shifted against the rest;
//! prints the recovered offset, the circumference error against the clean
//! drive's calibration and whether the offset is within its own 2 sigma.
//!
//! `cargo bench -p calibrator --bench clock_faults`

#![allow(clippy::expect_used, clippy::unwrap_used, clippy::print_stdout)]

use calibrator::{calibrate, CalibrationConfig, StreamOffset};
use simulator::{simulate, Scenario, SimConfig};
use std::time::Instant;

fn row(seed: u64, what: &str, shift: f64, expected: f64, o: &StreamOffset, err_pct: f64) {
    let (off, sig) = (o.offset_s, o.sigma_s);
    let within = match (off, sig) {
        (Some(v), Some(s)) => {
            if (v - expected).abs() <= 2.0 * s {
                "yes"
            } else {
                "no"
            }
        }
        _ => "n/a",
    };
    println!(
        "{seed:>4}  {what:<12} {shift:+6.2}  {:>9}  {:>8}  {:<12} {:<13} {err_pct:+9.4}  {within}",
        off.map_or("-".to_string(), |v| format!("{v:+.3}")),
        sig.map_or("-".to_string(), |v| format!("{v:.3}")),
        o.from.as_deref().unwrap_or("-"),
        format!("{:?}", o.status),
    );
}

fn main() {
    let start = Instant::now();
    let config = CalibrationConfig::default();
    println!("seed  shifted      by [s]  found [s]  sigma[s]  from         status        c err [%]  within 2 sigma");
    for seed in 1..=3u64 {
        let drive = simulate(&SimConfig::new(Scenario::Paper, seed)).expect("simulate");
        let clean = calibrate(&drive, &config).expect("clean");
        let err = |c: &calibrator::Calibration| {
            let e = |a: f64, b: f64| 100.0 * (a - b) / b;
            let (rl, rr) = (
                e(c.circumference_m.rl, clean.circumference_m.rl),
                e(c.circumference_m.rr, clean.circumference_m.rr),
            );
            if rl.abs() > rr.abs() {
                rl
            } else {
                rr
            }
        };
        for shift in [-1.5, -0.5, 0.5, 1.0, 2.5] {
            let mut d = drive.clone();
            for s in &mut d.wheels.samples {
                s.t_s += shift;
            }
            let cal = calibrate(&d, &config).expect("shifted");
            row(
                seed,
                "wheels/gnss",
                shift,
                -shift,
                &cal.clock_offsets.gnss_s,
                err(&cal),
            );
        }
        for shift in [-0.3, 0.3] {
            let mut d = drive.clone();
            for s in d.imu.as_mut().expect("imu") {
                s.t_s += shift;
            }
            let cal = calibrate(&d, &config).expect("shifted");
            row(
                seed,
                "imu",
                shift,
                shift,
                &cal.clock_offsets.imu_s,
                err(&cal),
            );
        }
    }
    println!("wall time {:.1} s", start.elapsed().as_secs_f64());
}
