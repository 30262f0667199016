//! The calibrator's estimate JSON (`Estimate::from_json_str`, what
//! `read_estimate` and the odometry's `--estimate` parse).
#![no_main]

use interfaces::wire::Header;
use libfuzzer_sys::fuzz_target;
use vehicle_model::estimate::Estimate;

fuzz_target!(|data: &[u8]| {
    // `read_estimate` refuses non-UTF-8 files before parsing.
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match Estimate::from_json_str(text, "fuzz.json") {
        Ok(estimate) => {
            // An accepted estimate goes on the wire; that must not panic either.
            let wire = estimate.to_wire(Header::default(), 1);
            let _ = Estimate::from_wire(&wire);
            let _ = estimate.fusable_antenna();
        }
        Err(e) => {
            let _ = e.to_string();
        }
    }
});
