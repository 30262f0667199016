//! The services' state files: the odometry's kept pose
//! (`odometry::kept_pose::SavedPose::from_json`, then judged at a restart by
//! `odometry::restart::judge_restart`) when byte 0 is even, the calibrator's
//! accepted estimate (`calibrator::live::LiveEstimate`, the fields beside
//! `version`; the odometry also reads the file as an estimate JSON) when odd.
#![no_main]

use libfuzzer_sys::fuzz_target;
use odometry::kept_pose::SavedPose;
use odometry::restart::{judge_restart, RestartConfig, WheelMark};
use vehicle_model::estimate::Estimate;
use vehicle_model::two_wheel::TwoWheelParams;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, rest)) = data.split_first() else {
        return;
    };
    let Ok(text) = std::str::from_utf8(rest) else {
        return;
    };
    if pick % 2 == 0 {
        if let Ok(saved) = SavedPose::from_json(text) {
            let params = TwoWheelParams {
                c_rl: 2.0,
                c_rr: 2.0,
                track_width: 1.5,
            };
            for first in [
                WheelMark { t_s: 0.0, rl_rev: 0.0, rr_rev: 0.0 },
                WheelMark { t_s: saved.t_s + 1.0, rl_rev: 10.0, rr_rev: 11.0 },
            ] {
                let _ = judge_restart(&saved.record(1.0), &first, &params, &RestartConfig::default());
            }
        }
    } else {
        let _ = serde_json::from_str::<calibrator::live::LiveEstimate>(text);
        let _ = Estimate::from_json_str(text, "state.json");
    }
});
