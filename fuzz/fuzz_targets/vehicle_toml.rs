//! The drive folder's TOML parsers: `vehicle.toml` (as `read_vehicle` and a
//! folder read it) and `truth.toml`, both on the same text.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    // The readers refuse non-UTF-8 files before parsing.
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match drive_io::vehicle_from_toml_str(Path::new("vehicle.toml"), text) {
        Ok(loaded) => {
            // Every service checks the parameters next.
            let _ = loaded.vehicle.check_plausible();
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
    if let Err(e) = drive_io::truth_from_toml_str(Path::new("truth.toml"), text) {
        let _ = e.to_string();
    }
});
