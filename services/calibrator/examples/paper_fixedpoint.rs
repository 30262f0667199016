//! Why the paper's loop runs at 10 Hz: the least-squares solution of eq. (9)
//! at the *true* circumferences, with the simulator's truth as the reference
//! (layers 2-3 alone), for several step rates of the filter.
//!
//! `cargo run --release -p calibrator --example paper_fixedpoint`
//!
//! At the wheel rate (100 Hz) with 96-tick encoders the per-step increments
//! are so noisy that the heading row of eq. (8) becomes an errors-in-variables
//! regression: the solution sits tens of millimetres below the truth. At
//! 10 Hz the bias is a millimetre or two.

use anyhow::{anyhow, Result};
use calibrator::fit::ekf;
use calibrator::{check, clocks, reference, CalibrationConfig, TimeOffsetMode};
use simulator::{simulate, Scenario, SimConfig};
use vehicle_model::two_wheel::wrap_angle;

fn main() -> Result<()> {
    let drive = simulate(&SimConfig::new(Scenario::Paper, 1))?;
    let truth_params = drive
        .truth_params
        .clone()
        .ok_or_else(|| anyhow!("no truth.toml"))?;
    let config = CalibrationConfig {
        time_offset: TimeOffsetMode::Off,
        ..CalibrationConfig::default()
    };
    let a = clocks::align_offsets(check::drive(&drive, &config)?, &config)?;
    let mut warnings = a.warnings.clone();
    let mut r = reference::build(&a, &config, &mut warnings)?;
    let p = &a.series;
    let truth = drive
        .truth
        .as_ref()
        .ok_or_else(|| anyhow!("no truth.csv"))?;
    // The simulator writes truth at the wheel times: sample k is truth row k.
    let mut yaw = f64::NAN;
    let mut prev = f64::NAN;
    for (k, row) in truth.iter().enumerate().take(p.len()) {
        let y = row.yaw_rad.ok_or_else(|| anyhow!("truth without yaw"))?;
        yaw = if k == 0 {
            y
        } else {
            yaw + wrap_angle(y - prev)
        };
        prev = y;
        r.x[k] = row.x_m;
        r.y[k] = row.y_m;
        r.yaw[k] = yaw;
        r.valid[k] = true;
    }
    let c = [
        truth_params.circumference_m.rl,
        truth_params.circumference_m.rr,
    ];
    println!(
        "eq. (9) solved at the true circumferences, truth as reference (iteration 5 covariances)"
    );
    println!("| step rate | c_RL opt - true | c_RR opt - true |");
    println!("|---|---|---|");
    for rate in [100.0, 50.0, 20.0, 10.0, 5.0, 2.0] {
        let grid = ekf::grid(p, rate);
        let cov = ekf::schedule(5, config.q_m, config.q_p);
        let pass = ekf::run_pass(
            p,
            &r,
            &grid,
            c,
            truth_params.track_width_m,
            &cov,
            false,
            false,
            20,
        )?;
        let opt = pass.solve()?;
        println!(
            "| {rate:.0} Hz | {:+.2} mm | {:+.2} mm |",
            1000.0 * (opt[0] - c[0]),
            1000.0 * (opt[1] - c[1])
        );
    }
    Ok(())
}
