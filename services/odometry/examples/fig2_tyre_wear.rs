//! Reproduce the paper's Fig. 2 table: how tyre wear spoils 2W dead-reckoning.
//!
//! ```text
//! cargo run --release -p odometry --example fig2_tyre_wear [-- --seed N] [--swap]
//! ```
//!
//! The simulator's `garage` scenario (about 540 m at 8-20 km/h, GNSS denied
//! after the first 50 m, a two-turn helix ramp) is driven with seven rear
//! tyre-wear settings. Wear is tread depth lost, read as a reduction of the
//! effective rolling radius by that many millimetres (the circumference
//! shrinks by 2 pi times it); the front tyres are unworn. The 2W model then
//! dead-reckons the whole drive from the true start pose with the NOMINAL
//! (unworn) circumference for both rear wheels and the nominal track, as a
//! car would that does not know its tyres wore. Errors are against the
//! simulator's truth over every wheel sample: position error (m) and
//! |heading error| (deg), mean and max.
//!
//! The simulator's default physics effects are on (side slip, load-transfer
//! radius, longitudinal slip) and the encoders are quantised to 96 ticks per
//! revolution, so the unworn row is not exactly zero.

use interfaces::drive::Drive;
use simulator::{simulate, Scenario, SimConfig, WheelWear};
use vehicle_model::two_wheel::{dead_reckon, wrap_angle, Pose2, TwoWheelParams};

/// (RL wear mm, RR wear mm, paper: position mean m, max m, orientation mean deg, max deg).
const PAPER: [(f64, f64, f64, f64, f64, f64); 7] = [
    (0.0, 0.0, 0.34, 0.77, 0.53, 4.08),
    (1.5, 1.5, 1.26, 3.66, 1.54, 4.95),
    (3.0, 3.0, 2.61, 7.50, 2.89, 7.44),
    (6.0, 6.0, 5.37, 15.24, 5.79, 12.55),
    (3.1, 2.9, 6.33, 19.01, 8.33, 16.39),
    (3.25, 2.75, 12.90, 36.39, 16.47, 33.44),
    (3.5, 2.5, 24.19, 70.04, 30.16, 62.34),
];

struct Errors {
    pos_mean: f64,
    pos_max: f64,
    yaw_mean_deg: f64,
    yaw_max_deg: f64,
}

fn errors(drive: &Drive) -> anyhow::Result<Errors> {
    let revs = drive.wheel_revolutions()?;
    let truth = drive
        .truth
        .as_ref()
        .ok_or_else(|| anyhow::anyhow!("the simulated drive has no truth"))?;
    anyhow::ensure!(
        truth.len() == revs.len(),
        "truth and wheels differ in length"
    );
    let first = truth[0];
    let start = Pose2 {
        x: first.x_m,
        y: first.y_m,
        yaw: first.yaw_rad.unwrap_or(0.0),
    };
    let nominal = drive.vehicle.nominal_circumference_m;
    let params = TwoWheelParams {
        c_rl: nominal,
        c_rr: nominal,
        track_width: drive.vehicle.track_width_m,
    };
    let track = dead_reckon(start, &revs, &params);
    let (mut pos_sum, mut pos_max, mut yaw_sum, mut yaw_max) = (0.0, 0.0f64, 0.0, 0.0f64);
    for (p, t) in track.iter().zip(truth) {
        let e = (p.x - t.x_m).hypot(p.y - t.y_m);
        let y = wrap_angle(p.yaw - t.yaw_rad.unwrap_or(0.0))
            .abs()
            .to_degrees();
        pos_sum += e;
        yaw_sum += y;
        pos_max = pos_max.max(e);
        yaw_max = yaw_max.max(y);
    }
    let n = track.len() as f64;
    Ok(Errors {
        pos_mean: pos_sum / n,
        pos_max,
        yaw_mean_deg: yaw_sum / n,
        yaw_max_deg: yaw_max,
    })
}

fn main() -> anyhow::Result<()> {
    let mut seed = 1u64;
    let mut swap = false;
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--swap" => swap = true,
            "--seed" => {
                seed = args
                    .next()
                    .ok_or_else(|| anyhow::anyhow!("--seed needs a value"))?
                    .parse()?
            }
            other => {
                anyhow::bail!("unknown argument {other}; usage: fig2_tyre_wear [--seed N] [--swap]")
            }
        }
    }
    let base = SimConfig::new(Scenario::Garage, seed);
    let spec = base.vehicle.spec();
    println!(
        "Fig. 2 reproduction: garage scenario, {} (track {:.2} m, unworn circumference {:.3} m), seed {seed}",
        base.vehicle.name(),
        spec.track_rear_m,
        base.unworn_circumference()
    );
    println!("2W dead-reckoning with the nominal (unworn) circumference; wear = radius lost (mm)");
    if swap {
        println!("--swap: the RL and RR wear of each row are exchanged (the mirrored course)");
    }
    println!();
    println!(
        "{:>7} {:>7} | {:>21} | {:>21} | {:>21} | {:>21}",
        "",
        "",
        "position mean [m]",
        "position max [m]",
        "orientation mean [deg]",
        "orientation max [deg]"
    );
    println!(
        "{:>7} {:>7} | {:>10} {:>10} | {:>10} {:>10} | {:>10} {:>10} | {:>10} {:>10}",
        "RL [mm]", "RR [mm]", "paper", "sim", "paper", "sim", "paper", "sim", "paper", "sim"
    );
    let mut length = 0.0;
    let mut rows = Vec::new();
    for (rl, rr, p_mean, p_max, o_mean, o_max) in PAPER {
        let mut config = base.clone();
        // --swap wears the right tyre more instead: the same as driving the
        // mirror image of the course.
        let (w_rl, w_rr) = if swap { (rr, rl) } else { (rl, rr) };
        config.wear_mm = WheelWear {
            rl: w_rl,
            rr: w_rr,
            fl: 0.0,
            fr: 0.0,
        };
        let drive = simulate(&config)?;
        length = drive.wheel_duration_s();
        let e = errors(&drive)?;
        println!(
            "{rl:>7.2} {rr:>7.2} | {p_mean:>10.2} {:>10.2} | {p_max:>10.2} {:>10.2} | {o_mean:>10.2} {:>10.2} | {o_max:>10.2} {:>10.2}",
            e.pos_mean, e.pos_max, e.yaw_mean_deg, e.yaw_max_deg
        );
        rows.push(e);
    }
    // The shape, as measured: symmetric wear rows 0-3, left/right rows 4-6.
    let rising = |idx: &[usize], f: &dyn Fn(&Errors) -> f64| {
        idx.windows(2).all(|w| f(&rows[w[1]]) > f(&rows[w[0]]))
    };
    let pos = |e: &Errors| e.pos_mean;
    let yaw = |e: &Errors| e.yaw_mean_deg;
    println!();
    println!(
        "symmetric wear 0 -> 6 mm: position mean rises {}, orientation mean rises {}",
        rising(&[0, 1, 2, 3], &pos),
        rising(&[0, 1, 2, 3], &yaw)
    );
    println!(
        "left/right difference 0.2 -> 1.0 mm: position mean rises {}, orientation mean rises {}",
        rising(&[4, 5, 6], &pos),
        rising(&[4, 5, 6], &yaw)
    );
    println!(
        "a 1 mm difference (3.5/2.5) against 6 mm on both (6/6): position mean x{:.1}, orientation mean x{:.1}",
        rows[6].pos_mean / rows[3].pos_mean,
        rows[6].yaw_mean_deg / rows[3].yaw_mean_deg
    );
    println!();
    println!("drive length {length:.1} s; the paper's course (CarSim) differs, so absolute values do too.");
    Ok(())
}
