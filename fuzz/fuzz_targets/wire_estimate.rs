//! `Estimate::from_wire` on a `CircumferenceEstimate` whose fields are read,
//! one by one, from the fuzz bytes (little-endian; missing bytes are zero).
//! No transmute: every bit pattern of every field is a valid value.
#![no_main]

use interfaces::wire::{CircumferenceEstimate, Header, ModelExtension};
use libfuzzer_sys::fuzz_target;
use vehicle_model::estimate::Estimate;

/// Reads fixed-size little-endian fields from the input, zero past its end.
struct Fields<'a>(&'a [u8]);

impl Fields<'_> {
    fn bytes<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        let n = N.min(self.0.len());
        out[..n].copy_from_slice(&self.0[..n]);
        self.0 = &self.0[n..];
        out
    }
    fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.bytes())
    }
    fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.bytes())
    }
    fn i64(&mut self) -> i64 {
        i64::from_le_bytes(self.bytes())
    }
    fn f64(&mut self) -> f64 {
        f64::from_le_bytes(self.bytes())
    }
}

fuzz_target!(|data: &[u8]| {
    let mut f = Fields(data);
    let mut wire = CircumferenceEstimate {
        header: Header {
            t_ns: f.i64(),
            seq: f.u64(),
        },
        version: f.u64(),
        c_rl_m: f.f64(),
        c_rr_m: f.f64(),
        sigma_rl_m: f.f64(),
        sigma_rr_m: f.f64(),
        track_width_m: f.f64(),
        gyro_bias_rad_s: f.f64(),
        gyro_scale: f.f64(),
        quality_m: f.f64(),
        extension_count: f.u32(),
        _pad: f.u32(),
        ..CircumferenceEstimate::default()
    };
    for x in wire.extensions.iter_mut() {
        *x = ModelExtension {
            effect_code: f.u32(),
            param_count: f.u32(),
            params: [f.f64(), f.f64(), f.f64(), f.f64()],
        };
    }
    if let Ok(estimate) = Estimate::from_wire(&wire) {
        // Sent on again (the odometry republishes what it uses).
        let again = estimate.to_wire(wire.header, wire.version);
        let _ = Estimate::from_wire(&again);
        let _ = estimate.fusable_antenna();
    }
});
