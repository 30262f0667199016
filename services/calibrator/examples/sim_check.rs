//! Quick look at one simulated drive: `cargo run --release -p calibrator --example sim_check -- SEED [paper|batch] [slip]`.

#[path = "../benches/common/mod.rs"]
mod common;

use calibrator::{calibrate, CalibrationConfig, Method};
use simulator::{simulate, Scenario, SimConfig};
use vehicle_model::two_wheel::TwoWheelParams;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let seed: u64 = args.get(1).and_then(|s| s.parse().ok()).unwrap_or(1);
    let scenario = args
        .get(4)
        .map_or(Ok(Scenario::Paper), |s| Scenario::from_name(s))?;
    let mut sim = SimConfig::new(scenario, seed);
    for kv in args.iter().skip(5) {
        if kv == "noiseless" {
            sim.sensors = simulator::SensorSettings::noiseless();
        }
        if let Some(e) = kv.strip_prefix("effect=") {
            sim.effects.apply_spec(e)?;
        }
        if let Some(e) = kv.strip_prefix("sensor=") {
            sim.sensors.apply_spec(e)?;
        }
        if let Some(e) = kv.strip_prefix("duration=") {
            sim.duration_s = Some(e.parse()?);
        }
    }
    let drive = simulate(&sim)?;
    let truth = drive
        .truth_params
        .clone()
        .ok_or_else(|| anyhow::anyhow!("no truth"))?;
    let mut config = CalibrationConfig {
        compare: true,
        ..CalibrationConfig::default()
    };
    if args.get(2).map(String::as_str) == Some("paper") {
        config.method = Method::Paper;
    }
    config.side_slip = args.get(3).map(String::as_str) == Some("slip");
    for kv in args.iter().skip(5) {
        let (k, v) = kv.split_once('=').unwrap_or((kv, ""));
        match k {
            "offset" => {
                config.time_offset = match v {
                    "off" => calibrator::TimeOffsetMode::Off,
                    "check" => calibrator::TimeOffsetMode::Check,
                    _ => calibrator::TimeOffsetMode::Compensate,
                }
            }
            "seg" => config.segment_length_s = v.parse()?,
            "alpha" => config.alpha = v.parse()?,
            "qm" => config.q_m = v.parse()?,
            "qp" => config.q_p = v.parse()?,
            "iter" => config.iterations = v.parse()?,
            "noaccel" => config.use_imu_acceleration = false,
            "track" => config.track_width = calibrator::TrackWidthMode::Estimate,
            "fixedtrack" => config.track_width = calibrator::TrackWidthMode::Fixed,
            "noiseless" | "effect" | "sensor" | "duration" => {}
            _ => anyhow::bail!("unknown option {k}"),
        }
    }
    let cal = calibrate(&drive, &config)?;
    print!("{}", calibrator::result::report::render_text(&cal));
    let tc = truth.circumference_m;
    println!(
        "truth: c_RL {:.5} c_RR {:.5} track {:.4} effects {:?}",
        tc.rl,
        tc.rr,
        truth.track_width_m,
        truth.effects.keys().collect::<Vec<_>>()
    );
    let true_params = TwoWheelParams {
        c_rl: tc.rl,
        c_rr: tc.rr,
        track_width: truth.track_width_m,
    };
    println!(
        "DR vs truth with true c: {:?}",
        common::dr_error_vs_truth(&drive, &true_params)
    );
    for m in &cal.comparison {
        let p = TwoWheelParams {
            c_rl: m.circumference_m.rl,
            c_rr: m.circumference_m.rr,
            track_width: m.track_width_m,
        };
        println!(
            "{}: err RL {:+.2} mm RR {:+.2} mm; DR vs truth {:?}",
            m.method,
            1000.0 * (m.circumference_m.rl - tc.rl),
            1000.0 * (m.circumference_m.rr - tc.rr),
            common::dr_error_vs_truth(&drive, &p)
        );
    }
    Ok(())
}
