//! opt(c) of one EKF + LS pass around the truth (truth as reference).
use calibrator::{ekf, prep, CalibrationConfig};
use sensor_bridge::sim::{simulate, Scenario, SimConfig};
fn main() -> anyhow::Result<()> {
    let drive = simulate(&SimConfig::new(Scenario::Paper, 1))?;
    let tp = drive.truth_params.clone().unwrap();
    let config = CalibrationConfig {
        time_offset: calibrator::TimeOffsetMode::Off,
        ..CalibrationConfig::default()
    };
    let mut w = Vec::new();
    let p = prep::prepare(&drive, &config, &mut w)?;
    let mut r = calibrator::reference::build(&p, &drive, &config, &mut w)?;
    let truth = drive.truth.as_ref().unwrap();
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
    let c0 = [tp.circumference_m.rl, tp.circumference_m.rr];
    for i in [1usize, 5, 9] {
        let cov = ekf::schedule(i, config.q_m, config.q_p);
        for eps in [-0.01, 0.0, 0.01] {
            for (track, est) in [(1.58, false), (1.609, false), (1.58, true)] {
                let c = [c0[0] * (1.0 + eps), c0[1] * (1.0 + eps)];
                let g = ekf::grid(
                    &p,
                    std::env::var("RATE")
                        .ok()
                        .and_then(|v| v.parse().ok())
                        .unwrap_or(10.0),
                );
                let pass = ekf::run_pass(&p, &r, &g, c, track, &cov, false, est, 20)?;
                let o = pass.solve()?;
                println!("i {i} eps {eps:+.2} track {track} est {est}: opt rl {:+.2} mm rr {:+.2} mm t {:.4}", 1000.0*(o[0]-c0[0]), 1000.0*(o[1]-c0[1]), o[2]);
            }
        }
    }
    Ok(())
}
