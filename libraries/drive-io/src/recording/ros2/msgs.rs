//! The ROS 2 messages a drive is read from, decoded from CDR: only the
//! fields the drive needs are kept, but every field before them is read
//! (CDR has no field markers).

use super::cdr::{Cdr, CdrResult};

/// `std_msgs/msg/Header`: the stamp as nanoseconds since the UNIX epoch
/// (ROS time), the frame id dropped.
fn header(c: &mut Cdr<'_>) -> CdrResult<i64> {
    let sec = c.i32("header.stamp.sec")?;
    let nanosec = c.u32("header.stamp.nanosec")?;
    if nanosec >= 1_000_000_000 {
        return Err(format!("header.stamp.nanosec = {nanosec} is not below 1e9"));
    }
    c.string("header.frame_id")?;
    Ok(i64::from(sec) * 1_000_000_000 + i64::from(nanosec))
}

/// `sensor_msgs/msg/NavSatFix`.
pub(super) struct NavSatFix {
    /// Header stamp, ns.
    pub stamp_ns: i64,
    /// `status.status`: -1 no fix, 0 fix, 1 SBAS, 2 GBAS.
    pub status: i8,
    /// Latitude, degrees.
    pub latitude: f64,
    /// Longitude, degrees.
    pub longitude: f64,
    /// `position_covariance` (ENU, m², row major).
    pub covariance: [f64; 9],
    /// `position_covariance_type`: 0 unknown, 1 approximated, 2 diagonal known, 3 known.
    pub covariance_type: u8,
}

/// Decode a `sensor_msgs/msg/NavSatFix`.
pub(super) fn nav_sat_fix(data: &[u8]) -> CdrResult<NavSatFix> {
    let mut c = Cdr::new(data)?;
    let stamp_ns = header(&mut c)?;
    let status = c.u8("status.status")? as i8;
    c.u16("status.service")?;
    let [latitude, longitude, _altitude] = c.f64s::<3>("latitude/longitude/altitude")?;
    let covariance = c.f64s::<9>("position_covariance")?;
    let covariance_type = c.u8("position_covariance_type")?;
    Ok(NavSatFix {
        stamp_ns,
        status,
        latitude,
        longitude,
        covariance,
        covariance_type,
    })
}

/// `sensor_msgs/msg/Imu`.
pub(super) struct Imu {
    /// Header stamp, ns.
    pub stamp_ns: i64,
    /// `angular_velocity` x, y, z, rad/s.
    pub angular_velocity: [f64; 3],
    /// `angular_velocity_covariance[0]` (-1: no angular velocity).
    pub angular_velocity_cov0: f64,
    /// `linear_acceleration` x, y, z, m/s².
    pub linear_acceleration: [f64; 3],
    /// `linear_acceleration_covariance[0]` (-1: no acceleration).
    pub linear_acceleration_cov0: f64,
}

/// Decode a `sensor_msgs/msg/Imu`.
pub(super) fn imu(data: &[u8]) -> CdrResult<Imu> {
    let mut c = Cdr::new(data)?;
    let stamp_ns = header(&mut c)?;
    c.skip_f64s(4, "orientation")?;
    c.skip_f64s(9, "orientation_covariance")?;
    let angular_velocity = c.f64s::<3>("angular_velocity")?;
    let av_cov = c.f64s::<9>("angular_velocity_covariance")?;
    let linear_acceleration = c.f64s::<3>("linear_acceleration")?;
    let la_cov = c.f64s::<9>("linear_acceleration_covariance")?;
    Ok(Imu {
        stamp_ns,
        angular_velocity,
        angular_velocity_cov0: av_cov[0],
        linear_acceleration,
        linear_acceleration_cov0: la_cov[0],
    })
}

/// `sensor_msgs/msg/JointState` (efforts not read).
pub(super) struct JointState {
    /// Header stamp, ns.
    pub stamp_ns: i64,
    /// Joint names.
    pub names: Vec<String>,
    /// Positions, rad (may be empty).
    pub position: Vec<f64>,
    /// Velocities, rad/s (may be empty).
    pub velocity: Vec<f64>,
}

/// Decode a `sensor_msgs/msg/JointState`.
pub(super) fn joint_state(data: &[u8]) -> CdrResult<JointState> {
    let mut c = Cdr::new(data)?;
    let stamp_ns = header(&mut c)?;
    let names = c.strings("name")?;
    let position = c.f64_seq("position")?;
    let velocity = c.f64_seq("velocity")?;
    Ok(JointState {
        stamp_ns,
        names,
        position,
        velocity,
    })
}

/// A body twist: forward speed and yaw rate.
pub(super) struct BodyTwist {
    /// Header stamp, ns.
    pub stamp_ns: i64,
    /// `twist.linear.x`, m/s.
    pub speed: f64,
    /// `twist.angular.z`, rad/s.
    pub yaw_rate: f64,
}

/// Decode a `geometry_msgs/msg/TwistStamped`.
pub(super) fn twist_stamped(data: &[u8]) -> CdrResult<BodyTwist> {
    let mut c = Cdr::new(data)?;
    let stamp_ns = header(&mut c)?;
    let [speed, _, _] = c.f64s::<3>("twist.linear")?;
    let [_, _, yaw_rate] = c.f64s::<3>("twist.angular")?;
    Ok(BodyTwist {
        stamp_ns,
        speed,
        yaw_rate,
    })
}

/// Decode a `nav_msgs/msg/Odometry` (its twist, in the child frame).
pub(super) fn odometry(data: &[u8]) -> CdrResult<BodyTwist> {
    let mut c = Cdr::new(data)?;
    let stamp_ns = header(&mut c)?;
    c.string("child_frame_id")?;
    c.skip_f64s(7, "pose.pose")?;
    c.skip_f64s(36, "pose.covariance")?;
    let [speed, _, _] = c.f64s::<3>("twist.twist.linear")?;
    let [_, _, yaw_rate] = c.f64s::<3>("twist.twist.angular")?;
    Ok(BodyTwist {
        stamp_ns,
        speed,
        yaw_rate,
    })
}
