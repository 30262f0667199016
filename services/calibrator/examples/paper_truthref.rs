//! The paper loop with the truth as the reference (isolates layers 2-3 from layer 1).
use calibrator::{prep, CalibrationConfig};
use sensor_bridge::sim::{simulate, Scenario, SimConfig};
fn main() -> anyhow::Result<()> {
    let seed: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let use_truth = std::env::args().nth(2).as_deref() != Some("ref");
    let drive = simulate(&SimConfig::new(Scenario::Paper, seed))?;
    let tp = drive.truth_params.clone().unwrap();
    let config = CalibrationConfig {
        time_offset: calibrator::TimeOffsetMode::Off,
        ..CalibrationConfig::default()
    };
    let mut w = Vec::new();
    let p = prep::prepare(&drive, &config, &mut w)?;
    let mut r = calibrator::reference::build(&p, &drive, &config, &mut w)?;
    let truth = drive.truth.as_ref().unwrap();
    let mut dev = (0.0, 0.0, 0.0);
    for k in 0..p.len() {
        let t = &truth[k];
        dev.0 += (r.x[k] - t.x_m).hypot(r.y[k] - t.y_m);
        let dy = odometry::two_wheel::wrap_angle(r.yaw[k] - t.yaw_rad.unwrap());
        dev.1 += dy.abs();
        dev.2 = f64::max(dev.2, dy.abs());
    }
    println!(
        "reference vs truth: mean pos {:.3} m, mean yaw {:.3} deg, max yaw {:.3} deg",
        dev.0 / p.len() as f64,
        (dev.1 / p.len() as f64).to_degrees(),
        dev.2.to_degrees()
    );
    if use_truth {
        let mut yaw = truth[0].yaw_rad.unwrap();
        for k in 0..p.len() {
            r.x[k] = truth[k].x_m;
            r.y[k] = truth[k].y_m;
            if k > 0 {
                yaw += odometry::two_wheel::wrap_angle(
                    truth[k].yaw_rad.unwrap() - truth[k - 1].yaw_rad.unwrap(),
                );
            }
            r.yaw[k] = yaw;
            r.valid[k] = true;
        }
    }
    let res = calibrator::paper::run(&p, &r, &config, &mut w, &mut |_| {})?;
    for it in &res.iterations {
        println!(
            "{} {:.5} {:.5} {:.2}",
            it.n, it.circumference_m.rl, it.circumference_m.rr, it.dr_error_mean_m
        );
    }
    println!(
        "truth {:.5} {:.5}",
        tp.circumference_m.rl, tp.circumference_m.rr
    );
    Ok(())
}
