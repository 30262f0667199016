//! The drive folder's CSV stream parser (`drive_io::read_drive` on a folder).
//!
//! Input: byte 0 picks the stream file (`% 5`: wheels, gnss, imu, heading,
//! truth), the rest is that file's content. The other files are fixed and
//! valid: a `vehicle.toml` (with `ticks_per_rev`, so `_ticks` columns parse)
//! and, unless the fuzzed file is `wheels.csv`, a two-row `wheels.csv`.
//! The reader only takes paths, so the folder is written to a per-process
//! directory (on tmpfs when there is one) for every input.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

const FILES: [&str; 5] = ["wheels.csv", "gnss.csv", "imu.csv", "heading.csv", "truth.csv"];
const VEHICLE: &str = "track_width_m = 1.6\nnominal_circumference_m = 2.0\nticks_per_rev = 100.0\n";
const WHEELS: &str = "t_s,rl_rev,rr_rev\n0.0,0.0,0.0\n0.1,0.1,0.1\n";

fn dir() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let shm = PathBuf::from("/dev/shm");
        let base = if shm.is_dir() { shm } else { std::env::temp_dir() };
        let d = base.join(format!("wheelcal-fuzz-csv-{}", std::process::id()));
        std::fs::create_dir_all(&d).expect("create the fuzz folder");
        std::fs::write(d.join("vehicle.toml"), VEHICLE).expect("write vehicle.toml");
        d
    })
}

fuzz_target!(|data: &[u8]| {
    let Some((&pick, content)) = data.split_first() else {
        return;
    };
    let dir = dir();
    let name = FILES[usize::from(pick) % FILES.len()];
    for other in &FILES[1..] {
        // Leave no stream file of the previous input behind.
        let _ = std::fs::remove_file(dir.join(other));
    }
    if name != "wheels.csv" {
        std::fs::write(dir.join("wheels.csv"), WHEELS).expect("write wheels.csv");
    }
    std::fs::write(dir.join(name), content).expect("write the fuzzed file");
    if let Ok(loaded) = drive_io::read_drive(dir) {
        // What `info` does with a drive it has read.
        let _ = drive_io::DriveSummary::of_loaded(&loaded);
    }
});
