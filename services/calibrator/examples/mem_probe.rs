//! Resident memory at each progress step of a 1 h calibration.
#[path = "../benches/common/mod.rs"]
mod common;
use calibrator::{calibrate_with_progress, CalibrationConfig, Method};
use simulator::{simulate, Scenario, SimConfig};
fn main() {
    let mut sim = SimConfig::new(Scenario::Long, 7);
    sim.duration_s = Some(3600.0);
    let mut drive = simulate(&sim).expect("sim");
    if std::env::args().any(|a| a == "notruth") {
        drive.truth = None;
    }
    println!(
        "drive resident {:?} peak {:?}",
        common::resident_memory_mb(),
        common::peak_memory_mb()
    );
    let method = if std::env::args().nth(1).as_deref() == Some("paper") {
        Method::Paper
    } else {
        Method::Batch
    };
    let config = CalibrationConfig {
        method,
        ..CalibrationConfig::default()
    };
    let mut last = -1.0;
    calibrate_with_progress(&drive, &config, &mut |p| {
        if p.fraction - last > 0.02 {
            last = p.fraction;
            println!(
                "{:?} {:.2} rss {:.0} hwm {:.0}",
                p.stage,
                p.fraction,
                common::resident_memory_mb().unwrap_or(0.0),
                common::peak_memory_mb().unwrap_or(0.0)
            );
        }
    })
    .expect("cal");
    println!(
        "end rss {:?} hwm {:?}",
        common::resident_memory_mb(),
        common::peak_memory_mb()
    );
}
