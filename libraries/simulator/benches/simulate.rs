//! Simulator speed: a 10 min and a 1 h drive at 100 Hz wheel rate.
//!
//! ```text
//! cargo bench -p sensor-bridge --bench simulate
//! ```
//!
//! The `long` scenario (the mixed city/highway loop driven round and round)
//! with the default effects and sensors; the 1 h drive is also timed with
//! every effect of the catalogue on. Each case runs three times; the table
//! shows the fastest and the slowest. Goal: 1 h in at most 5 s.

use interfaces::effects::Effect;
use simulator::{simulate, EffectSettings, Scenario, SimConfig};
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    println!(
        "{:<34} {:>10} {:>12} {:>10} {:>10} {:>12}",
        "case", "drive_s", "wheel_rows", "min_s", "max_s", "x_realtime"
    );
    let mut all = EffectSettings::none();
    for e in Effect::ALL {
        all.switch_on(e);
    }
    let cases = [
        (
            "long 10 min, default effects",
            600.0,
            EffectSettings::default(),
        ),
        (
            "long 1 h, default effects",
            3600.0,
            EffectSettings::default(),
        ),
        ("long 1 h, every effect on", 3600.0, all),
    ];
    for (name, duration, effects) in cases {
        let mut config = SimConfig::new(Scenario::Long, 1);
        config.duration_s = Some(duration);
        config.effects = effects;
        let mut times = Vec::new();
        let mut rows = 0;
        for _ in 0..3 {
            let t0 = Instant::now();
            let drive = simulate(&config)?;
            times.push(t0.elapsed().as_secs_f64());
            rows = drive.wheels.samples.len();
            std::hint::black_box(&drive);
        }
        let min = times.iter().copied().fold(f64::INFINITY, f64::min);
        let max = times.iter().copied().fold(0.0, f64::max);
        println!(
            "{name:<34} {duration:>10.0} {rows:>12} {min:>10.3} {max:>10.3} {:>12.0}",
            duration / min
        );
    }
    Ok(())
}
