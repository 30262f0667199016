//! The synthetic drives the evaluation's tests run on.

use interfaces::drive::{
    Drive, GnssAntenna, ImuSample, TruthSample, VehicleParams, WheelSample, WheelSeries, WheelUnit,
    WheelUnits,
};
use vehicle_model::estimate::OdometryParams;
use vehicle_model::two_wheel::{Pose2, TwoWheelParams};

pub(super) const C_RL: f64 = 1.83;
pub(super) const C_RR: f64 = 1.84;
pub(super) const TRACK: f64 = 1.42;

/// A synthetic drive on a winding path at 8 m/s: true wheels with
/// circumferences C_RL, C_RR and track TRACK, a perfect gyro, truth at
/// 5 Hz without yaw.
pub(super) fn winding_drive(seconds: f64) -> Drive {
    let mut drive = drive_with_yaw_rate(seconds, |t| 0.25 * (0.2 * t).sin());
    for r in drive.truth.as_mut().unwrap() {
        r.yaw_rad = None;
    }
    drive
}

/// A drive at 8 m/s with the given yaw rate; its truth (every 0.2 s)
/// has the true yaw.
pub(super) fn drive_with_yaw_rate(seconds: f64, yaw_rate: impl Fn(f64) -> f64) -> Drive {
    let dt = 0.01;
    let n = (seconds / dt).round() as usize;
    let v = 8.0;
    let (mut x, mut y, mut yaw, mut rl, mut rr) = (0.0, 0.0, 0.3, 0.0, 0.0);
    let mut wheels = Vec::new();
    let mut imu = Vec::new();
    let mut truth = Vec::new();
    for i in 0..=n {
        let t = i as f64 * dt;
        if i > 0 {
            let w = yaw_rate(t - dt / 2.0);
            let ds = v * dt;
            let dyaw = w * dt;
            x += ds * (yaw + dyaw / 2.0).cos();
            y += ds * (yaw + dyaw / 2.0).sin();
            yaw += dyaw;
            rl += (ds - dyaw * TRACK / 2.0) / C_RL;
            rr += (ds + dyaw * TRACK / 2.0) / C_RR;
        }
        wheels.push(WheelSample {
            t_s: t,
            rl,
            rr,
            fl: None,
            fr: None,
        });
        imu.push(ImuSample {
            t_s: t,
            gz_rad_s: yaw_rate(t),
            ax_m_s2: None,
            ay_m_s2: None,
            az_m_s2: None,
            gx_rad_s: None,
            gy_rad_s: None,
        });
        if i % 20 == 0 {
            truth.push(TruthSample {
                t_s: t,
                x_m: x,
                y_m: y,
                yaw_rad: Some(yaw),
            });
        }
    }
    Drive {
        vehicle: VehicleParams {
            name: None,
            track_width_m: 1.45,
            nominal_circumference_m: 1.85,
            wheelbase_m: None,
            ticks_per_rev: None,
            gnss: GnssAntenna::default(),
        },
        wheels: WheelSeries {
            units: WheelUnits::rear(WheelUnit::Rev),
            samples: wheels,
        },
        gnss: None,
        imu: Some(imu),
        heading: None,
        truth: Some(truth),
        truth_params: None,
    }
}

pub(super) fn true_params() -> OdometryParams {
    OdometryParams {
        two_wheel: TwoWheelParams {
            c_rl: C_RL,
            c_rr: C_RR,
            track_width: TRACK,
        },
        gyro_bias_rad_s: 0.0,
        gyro_scale: 0.0,
    }
}

pub(super) const ANTENNA: [f64; 2] = [0.6, -0.3];

/// The winding drive with an RTK-like truth: truth.csv is the track of an
/// antenna at ANTENNA, and gnss.csv is the same track (as on the WID
/// drives); with `gnss_offset_m`, every fix is that far east of it.
pub(super) fn antenna_truth_drive(gnss_offset_m: f64) -> Drive {
    let mut drive = drive_with_yaw_rate(120.0, |t| 0.25 * (0.2 * t).sin());
    let truth = drive.truth.as_mut().unwrap();
    for r in truth.iter_mut() {
        let yaw = r.yaw_rad.take().unwrap();
        [r.x_m, r.y_m] = Pose2 {
            x: r.x_m,
            y: r.y_m,
            yaw,
        }
        .point_at(ANTENNA);
    }
    drive.gnss = Some(
        truth
            .iter()
            .map(|r| interfaces::drive::GnssSample {
                t_s: r.t_s,
                x_m: r.x_m + gnss_offset_m,
                y_m: r.y_m,
                sigma_m: Some(0.02),
            })
            .collect(),
    );
    drive
}
