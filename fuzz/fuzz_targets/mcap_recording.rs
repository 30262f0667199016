//! The MCAP recording reader, on the bytes as they are and in recovery
//! mode (`skip_corrupt_chunks`), as `read_drive` does after reading a file;
//! with vehicle parameters, so that a ROS 2 bag is read as a drive too.
#![no_main]

use drive_io::ReadOptions;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.mcap");
    let vehicle = drive_io::vehicle_from_toml_str(
        Path::new("vehicle.toml"),
        "track_width_m = 1.5\nnominal_circumference_m = 2.0\n",
    )
    .ok()
    .map(|l| l.vehicle);
    for skip_corrupt_chunks in [false, true] {
        let options = ReadOptions {
            skip_corrupt_chunks,
            vehicle: vehicle.clone(),
            ..ReadOptions::default()
        };
        match drive_io::read_mcap_from_bytes(path, data, options) {
            Ok(loaded) => {
                let _ = drive_io::DriveSummary::of_loaded(&loaded);
            }
            Err(drive_io::DriveError::TruncatedMcap {
                partial: Some(partial),
                ..
            }) => {
                let _ = drive_io::DriveSummary::of_loaded(&partial);
            }
            Err(e) => {
                let _ = e.to_string();
            }
        }
    }
});
