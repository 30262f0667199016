//! Probe a simulated drive: distances per wheel against the truth.
use sensor_bridge::sim::{simulate, Scenario, SimConfig};
fn main() -> anyhow::Result<()> {
    let seed: u64 = std::env::args()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .unwrap_or(1);
    let drive = simulate(&SimConfig::new(Scenario::Paper, seed))?;
    let tp = drive.truth_params.clone().unwrap();
    println!("{:?}", tp);
    let revs = drive.wheel_revolutions()?;
    let truth = drive.truth.as_ref().unwrap();
    println!(
        "wheels {} truth {} gnss {} imu {}",
        revs.len(),
        truth.len(),
        drive.gnss.as_ref().map_or(0, |g| g.len()),
        drive.imu.as_ref().map_or(0, |g| g.len())
    );
    println!(
        "first wheel t {} truth t {} ; last {} {}",
        revs[0].t_s,
        truth[0].t_s,
        revs.last().unwrap().t_s,
        truth.last().unwrap().t_s
    );
    let mut s = 0.0;
    let mut dyaw = 0.0;
    for w in truth.windows(2) {
        s += (w[1].x_m - w[0].x_m).hypot(w[1].y_m - w[0].y_m);
        if let (Some(a), Some(b)) = (w[0].yaw_rad, w[1].yaw_rad) {
            dyaw += odometry::two_wheel::wrap_angle(b - a);
        }
    }
    let n_rl = revs.last().unwrap().rl - revs[0].rl;
    let n_rr = revs.last().unwrap().rr - revs[0].rr;
    let c = tp.circumference_m;
    println!("truth length {s:.3} m, turn {:.2} deg", dyaw.to_degrees());
    println!(
        "wheel dist with true c: rl {:.3} rr {:.3} mean {:.3}",
        n_rl * c.rl,
        n_rr * c.rr,
        0.5 * (n_rl * c.rl + n_rr * c.rr)
    );
    println!(
        "c that fits length (equal scale): {:.5} / {:.5}",
        c.rl * s / (0.5 * (n_rl * c.rl + n_rr * c.rr)),
        c.rr * s / (0.5 * (n_rl * c.rl + n_rr * c.rr))
    );
    println!(
        "heading from wheels with true c: {:.2} deg",
        ((n_rr * c.rr - n_rl * c.rl) / tp.track_width_m).to_degrees()
    );
    // gnss vs truth
    let g = drive.gnss.as_ref().unwrap();
    let mut e = 0.0;
    let mut n = 0;
    for f in g.iter() {
        if let Some(i) = truth.iter().position(|t| t.t_s >= f.t_s) {
            e += (f.x_m - truth[i].x_m).hypot(f.y_m - truth[i].y_m);
            n += 1;
        }
    }
    println!("gnss mean dev from truth {:.3} over {n}", e / n as f64);
    for (i, r) in drive.wheels.samples.iter().take(3).enumerate() {
        println!("{i} {:?}", r);
    }
    println!("units {:?} vehicle {:?}", drive.wheels.units, drive.vehicle);
    Ok(())
}
