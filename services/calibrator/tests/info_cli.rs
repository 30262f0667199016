//! `calibrator info`: every clock offset, the GNSS jumps and the fit
//! quality of a recording, as text and JSON.

use simulator::faults::{apply, Fault};
use simulator::{simulate, Scenario, SimConfig};
use std::process::Command;

#[test]
fn info_reports_a_shifted_wheel_clock_and_the_fit_quality() {
    let drive = simulate(&SimConfig::new(Scenario::Mixed, 3)).expect("simulate");
    // The wheels' logger stamps 1 s late: the GNSS is 1 s early against them.
    let shifted = apply(&drive, &Fault::WheelClockShift { s: 1.0 }, 1).expect("shift");
    let dir = tempfile::tempdir().expect("tempdir");
    let path = dir.path().join("drive");
    drive_io::write_drive(&shifted, &path).expect("write");
    let run = |json: bool| {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_calibrator"));
        cmd.arg("info").arg(&path);
        if json {
            cmd.arg("--json");
        }
        let out = cmd.output().expect("run");
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let v: serde_json::Value = serde_json::from_str(&run(true)).expect("json");
    let gnss = &v["clock_offsets"]["gnss_s"];
    assert_eq!(gnss["status"], "determined", "{gnss}");
    let off = gnss["offset_s"].as_f64().expect("offset");
    let sigma = gnss["sigma_s"].as_f64().expect("sigma");
    assert!((off + 1.0).abs() < 0.1 && sigma < 0.1, "{gnss}");
    assert_eq!(gnss["applied"], true);
    assert_eq!(v["clock_offsets"]["imu_s"]["status"], "determined");
    let q = &v["fit_quality"];
    assert!(q["ratio"].as_f64().expect("ratio") < q["limit"].as_f64().expect("limit"));
    assert!(v["refused"].is_null());
    assert!(v["drive"].is_object());
    let text = run(false);
    for needle in [
        "clock offsets:",
        "gnss ",
        "applied",
        "fit quality:",
        "would be published",
    ] {
        assert!(text.contains(needle), "missing {needle} in\n{text}");
    }
}
