//! The MCAP recording reader, on the bytes as they are and in recovery
//! mode (`skip_corrupt_chunks`), as `read_drive` does after reading a file.
#![no_main]

use drive_io::ReadOptions;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let path = Path::new("fuzz.mcap");
    for skip_corrupt_chunks in [false, true] {
        let options = ReadOptions {
            skip_corrupt_chunks,
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
