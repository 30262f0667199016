//! Read/write speed of a one-hour drive at 100 Hz (360 000 wheel rows, as many
//! IMU rows, 36 000 GNSS fixes), as a folder and as MCAP.
//!
//! Run: `cargo bench -p sensor-bridge --bench drive_io`

use drive_io::{read_drive, write_drive};
use interfaces::drive::{
    Drive, GnssAntenna, GnssSample, ImuSample, VehicleParams, WheelSample, WheelSeries, WheelUnit,
    WheelUnits,
};
use std::error::Error;
use std::time::Instant;

fn one_hour_drive() -> Drive {
    let n = 360_000;
    let t = |i: usize| i as f64 * 0.01;
    Drive {
        vehicle: VehicleParams {
            name: Some("bench".to_string()),
            track_width_m: 1.53,
            nominal_circumference_m: 2.16,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna::default(),
        },
        wheels: WheelSeries {
            units: WheelUnits::all(WheelUnit::RadS),
            samples: (0..n)
                .map(|i| {
                    let w = 40.0 + (i as f64 * 0.001).sin();
                    WheelSample {
                        t_s: t(i),
                        rl: w,
                        rr: w * 1.001,
                        fl: Some(w * 0.999),
                        fr: Some(w * 1.002),
                    }
                })
                .collect(),
        },
        gnss: Some(
            (0..n / 10)
                .map(|i| GnssSample {
                    t_s: t(i * 10) + 0.003,
                    x_m: i as f64 * 2.7 + 0.123,
                    y_m: (i as f64 * 0.01).sin() * 100.0,
                    sigma_m: Some(2.5),
                })
                .collect(),
        ),
        imu: Some(
            (0..n)
                .map(|i| ImuSample {
                    t_s: t(i) + 0.005,
                    gz_rad_s: (i as f64 * 0.0007).sin() * 0.2,
                    ax_m_s2: Some(0.1),
                    ay_m_s2: Some((i as f64 * 0.0007).cos()),
                    az_m_s2: Some(9.81),
                    gx_rad_s: None,
                    gy_rad_s: None,
                })
                .collect(),
        ),
        heading: None,
        truth: None,
        truth_params: None,
    }
}

fn time<T>(
    label: &str,
    f: impl FnOnce() -> Result<T, Box<dyn Error>>,
) -> Result<T, Box<dyn Error>> {
    let start = Instant::now();
    let out = f()?;
    println!("{label:<28} {:>8.3} s", start.elapsed().as_secs_f64());
    Ok(out)
}

fn main() -> Result<(), Box<dyn Error>> {
    let drive = one_hour_drive();
    let dir = std::env::temp_dir().join(format!("sensor-bridge-bench-{}", std::process::id()));
    let folder = dir.join("drive");
    let mcap = dir.join("drive.mcap");
    println!(
        "1 h at 100 Hz: {} wheel rows, {} IMU rows, {} GNSS fixes",
        drive.wheels.samples.len(),
        drive.imu.as_ref().map_or(0, Vec::len),
        drive.gnss.as_ref().map_or(0, Vec::len)
    );
    time("write folder", || Ok(write_drive(&drive, &folder)?))?;
    let a = time("read folder", || Ok(read_drive(&folder)?))?;
    time("write MCAP", || Ok(write_drive(&drive, &mcap)?))?;
    let b = time("read MCAP", || Ok(read_drive(&mcap)?))?;
    let size = std::fs::metadata(&mcap)?.len();
    println!("MCAP size {:.1} MB", size as f64 / 1e6);
    if a.drive != drive || b.drive != drive {
        return Err("round trip changed the drive".into());
    }
    std::fs::remove_dir_all(&dir)?;
    Ok(())
}
