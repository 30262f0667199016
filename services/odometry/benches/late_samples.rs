//! What taking late samples in order costs: the service's filter
//! ([`odometry::rewind::RewindingFusion`]) over the real drives, in order and
//! with every GNSS fix delivered late, against the bare [`Fusion`].
//!
//! ```text
//! cargo bench -p odometry --bench late_samples
//! ```
//!
//! Per drive: the time per input over the whole drive (best of 5 runs) for
//! the bare filter in order, the rewinding filter in order (its log and
//! copies: what every pose pays), and the rewinding filter with the fixes
//! 0.1 s and 0.2 s late; and the time of the single `process` calls that
//! went back (p50 / p99 / max): what the pose after a late fix waits.
//! Nominal parameters (the cost does not depend on them).
//!
//! Skips with a message when `shared/data/real` is absent.

use odometry::fusion::{Fusion, FusionConfig};
use odometry::inputs::{drive_inputs, gnss_late, sort_by_delivery, Input};
use odometry::rewind::{RewindConfig, RewindingFusion};
use std::path::Path;
use std::time::{Duration, Instant};

const RUNS: usize = 5;

fn delivered(inputs: &[Input], gnss_late_s: f64) -> Vec<Input> {
    let mut out = inputs.to_vec();
    sort_by_delivery(&mut out, gnss_late(gnss_late_s));
    out
}

fn best_of(mut run: impl FnMut() -> Duration) -> Duration {
    (0..RUNS).map(|_| run()).min().unwrap_or_default()
}

fn main() -> anyhow::Result<()> {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data/real");
    if !root.is_dir() {
        println!("skipped: {} is absent", root.display());
        return Ok(());
    }
    println!(
        "| drive | inputs | bare filter, in order | rewinding, in order | fixes 0.1 s late | fixes 0.2 s late | calls that went back, 0.1 s late: p50 / p99 / max |"
    );
    println!("|---|---|---|---|---|---|---|");
    for name in ["wid-trial02", "wid-trial04", "comma2k19-seg40"] {
        let drive = drive_io::read_drive(&root.join(name))?.drive;
        let inputs = drive_inputs(&drive)?;
        let fresh = || Fusion::nominal(&drive.vehicle, FusionConfig::default());
        let per_input = |d: Duration| d.as_nanos() as f64 / inputs.len() as f64;
        let bare = best_of(|| {
            let mut f = fresh();
            let start = Instant::now();
            for i in &inputs {
                let _ = std::hint::black_box(f.process(i));
            }
            start.elapsed()
        });
        let rewinding = |order: &[Input]| {
            best_of(|| {
                let mut f = RewindingFusion::new(fresh(), RewindConfig::default());
                let start = Instant::now();
                for i in order {
                    let _ = std::hint::black_box(f.process(i));
                }
                start.elapsed()
            })
        };
        let in_order = rewinding(&inputs);
        let late_100 = delivered(&inputs, 0.1);
        let late_200 = delivered(&inputs, 0.2);
        let (t100, t200) = (rewinding(&late_100), rewinding(&late_200));
        // The calls that went back, timed one by one.
        let mut f = RewindingFusion::new(fresh(), RewindConfig::default());
        let mut went_back = Vec::new();
        for i in &late_100 {
            let before = f.stats().rewinds;
            let start = Instant::now();
            let _ = std::hint::black_box(f.process(i));
            let took = start.elapsed();
            if f.stats().rewinds > before {
                went_back.push(took.as_secs_f64() * 1e6);
            }
        }
        went_back.sort_by(f64::total_cmp);
        println!(
            "| {name} | {} | {:.0} ns | {:.0} ns | {:.0} ns | {:.0} ns | {:.1} / {:.1} / {:.1} µs ({} calls) |",
            inputs.len(),
            per_input(bare),
            per_input(in_order),
            per_input(t100),
            per_input(t200),
            stats::nearest_rank(&went_back, 0.5),
            stats::nearest_rank(&went_back, 0.99),
            went_back.last().copied().unwrap_or(f64::NAN),
            went_back.len()
        );
    }
    Ok(())
}
