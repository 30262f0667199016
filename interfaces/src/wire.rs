//! Zero-copy wire types and the iceoryx2 service names they travel on.
//!
//! Every type is `#[repr(C)]`, holds only primitives and arrays, carries an
//! explicit versioned type name (so another language or a renamed module still
//! matches) and starts with a [`Header`]. Padding is spelled out so that the
//! layout is the same for every compiler; sizes are checked at compile time.
//!
//! Every type is also `bytemuck::Pod`: its bytes are the sample as it lies
//! in shared memory (the derive refuses a type with hidden padding), which is
//! what the gateway carries between hosts.
//!
//! Optional fields are flagged in a `valid` bit mask rather than encoded as NaN,
//! so that a NaN on the wire is always a fault, never a convention.
//!
//! Wakeups: each publish-subscribe service `NAME` below has an iceoryx2 event
//! service with the same `NAME`, which its publishers notify after every
//! sample, so that subscribers block in a WaitSet instead of polling
//! (event ids and details in `crate::bus`, with the `bus` feature).

use bytemuck::{Pod, Zeroable};
#[cfg(feature = "bus")]
use iceoryx2::prelude::ZeroCopySend;

/// Service carrying [`WheelRotations`].
pub const WHEELS_SERVICE: &str = "wheelcal/sensors/wheels";
/// Service carrying [`GnssFix`].
pub const GNSS_SERVICE: &str = "wheelcal/sensors/gnss";
/// Service carrying [`Imu`].
pub const IMU_SERVICE: &str = "wheelcal/sensors/imu";
/// Service carrying [`Heading`].
pub const HEADING_SERVICE: &str = "wheelcal/sensors/heading";
/// Service carrying [`CircumferenceEstimate`].
pub const ESTIMATE_SERVICE: &str = "wheelcal/calibration/estimate";
/// Service carrying [`Pose`].
pub const POSE_SERVICE: &str = "wheelcal/odometry/pose";

/// Every sensor service, in the order the bridge opens them.
pub const SENSOR_SERVICES: [&str; 4] = [WHEELS_SERVICE, GNSS_SERVICE, IMU_SERVICE, HEADING_SERVICE];

/// Common header of every sample.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Pod, Zeroable)]
#[cfg_attr(feature = "bus", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "bus", type_name("wheelcal/Header/v1"))]
pub struct Header {
    /// Timestamp on the vehicle clock, nanoseconds (may be negative).
    pub t_ns: i64,
    /// Sequence number per publisher, starting at 0, +1 per sample.
    pub seq: u64,
}

impl Header {
    /// Header for a time in seconds on the vehicle clock.
    pub fn from_seconds(t_s: f64, seq: u64) -> Header {
        Header {
            t_ns: seconds_to_ns(t_s),
            seq,
        }
    }

    /// The timestamp in seconds.
    pub fn t_s(&self) -> f64 {
        self.t_ns as f64 * 1e-9
    }
}

/// Seconds to integer nanoseconds, rounded to the nearest nanosecond.
pub fn seconds_to_ns(t_s: f64) -> i64 {
    (t_s * 1e9).round() as i64
}

/// Wheel rotations as cumulative revolutions since an arbitrary start.
///
/// Revolutions (not ticks) keep the type independent of the encoder: a
/// `f64` holds a million revolutions to better than 1e-9 rev.
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
#[cfg_attr(feature = "bus", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "bus", type_name("wheelcal/WheelRotations/v1"))]
pub struct WheelRotations {
    /// Time and sequence.
    pub header: Header,
    /// Rear-left cumulative revolutions (required).
    pub rl_rev: f64,
    /// Rear-right cumulative revolutions (required).
    pub rr_rev: f64,
    /// Front-left cumulative revolutions, valid when `valid & FRONT_VALID`.
    pub fl_rev: f64,
    /// Front-right cumulative revolutions, valid when `valid & FRONT_VALID`.
    pub fr_rev: f64,
    /// Bit mask of the optional fields present ([`WheelRotations::FRONT_VALID`]).
    pub valid: u32,
    /// Explicit padding, always zero.
    pub _pad: u32,
}

impl WheelRotations {
    /// `valid` bit: the front wheels are present.
    pub const FRONT_VALID: u32 = 1;
}

/// GNSS fix in local ENU metres.
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
#[cfg_attr(feature = "bus", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "bus", type_name("wheelcal/GnssFix/v1"))]
pub struct GnssFix {
    /// Time and sequence.
    pub header: Header,
    /// East, metres from the drive's local origin.
    pub x_m: f64,
    /// North, metres from the drive's local origin.
    pub y_m: f64,
    /// Horizontal 1-sigma, metres; 0 when the receiver gave none.
    pub sigma_m: f64,
    /// 0 = no fix (position not usable), 1 = fix.
    pub fix: u8,
    /// Explicit padding, always zero.
    pub _pad: [u8; 7],
}

/// IMU sample in the body frame (x forward, y left, z up).
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
#[cfg_attr(feature = "bus", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "bus", type_name("wheelcal/Imu/v1"))]
pub struct Imu {
    /// Time and sequence.
    pub header: Header,
    /// Yaw rate about z, rad/s, positive turning left (required).
    pub gz_rad_s: f64,
    /// Longitudinal acceleration, m/s^2 (valid with [`Imu::ACCEL_VALID`]).
    pub ax_m_s2: f64,
    /// Lateral acceleration, m/s^2 (valid with [`Imu::ACCEL_VALID`]).
    pub ay_m_s2: f64,
    /// Vertical acceleration, m/s^2 (valid with [`Imu::ACCEL_VALID`]).
    pub az_m_s2: f64,
    /// Roll rate, rad/s (valid with [`Imu::ROLL_PITCH_RATE_VALID`]).
    pub gx_rad_s: f64,
    /// Pitch rate, rad/s (valid with [`Imu::ROLL_PITCH_RATE_VALID`]).
    pub gy_rad_s: f64,
    /// Bit mask of the optional fields present.
    pub valid: u32,
    /// Explicit padding, always zero.
    pub _pad: u32,
}

impl Imu {
    /// `valid` bit: the three accelerations are present.
    pub const ACCEL_VALID: u32 = 1;
    /// `valid` bit: roll and pitch rates are present.
    pub const ROLL_PITCH_RATE_VALID: u32 = 2;
}

/// Absolute heading (magnetometer or other source).
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
#[cfg_attr(feature = "bus", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "bus", type_name("wheelcal/Heading/v1"))]
pub struct Heading {
    /// Time and sequence.
    pub header: Header,
    /// Yaw, rad, 0 = east, counter-clockwise positive.
    pub yaw_rad: f64,
    /// 1-sigma, rad; 0 when the source gave none.
    pub sigma_rad: f64,
}

/// Maximum number of model extensions an estimate carries.
pub const MAX_EXTENSIONS: usize = 8;
/// Maximum number of parameters of one model extension.
pub const MAX_EXTENSION_PARAMS: usize = 4;

/// One extension of the 2W model found by the diagnosis.
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
#[cfg_attr(feature = "bus", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "bus", type_name("wheelcal/ModelExtension/v1"))]
pub struct ModelExtension {
    /// Catalogue effect code ([`crate::effects::Effect::code`]); 0 = unused slot.
    pub effect_code: u32,
    /// Number of meaningful entries in `params`.
    pub param_count: u32,
    /// Effect parameters, in the order the catalogue's extended model names them.
    pub params: [f64; MAX_EXTENSION_PARAMS],
}

/// A calibration of the rear wheels, published when it passes the quality gate.
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
#[cfg_attr(feature = "bus", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "bus", type_name("wheelcal/CircumferenceEstimate/v1"))]
pub struct CircumferenceEstimate {
    /// Time (of the last sample the estimate used) and sequence.
    pub header: Header,
    /// Increases by one with every accepted estimate.
    pub version: u64,
    /// Rear-left effective circumference, metres.
    pub c_rl_m: f64,
    /// Rear-right effective circumference, metres.
    pub c_rr_m: f64,
    /// 1-sigma of `c_rl_m`, metres.
    pub sigma_rl_m: f64,
    /// 1-sigma of `c_rr_m`, metres.
    pub sigma_rr_m: f64,
    /// Effective rear track width, metres.
    pub track_width_m: f64,
    /// Yaw-rate gyro bias, rad/s (subtract from the measurement).
    pub gyro_bias_rad_s: f64,
    /// Yaw-rate gyro scale error s in w_gyro = (1 + s) w.
    pub gyro_scale: f64,
    /// Quality figure: mean dead-reckoning error on held-out data, metres.
    pub quality_m: f64,
    /// Number of used slots in `extensions`.
    pub extension_count: u32,
    /// Explicit padding, always zero.
    pub _pad: u32,
    /// Model extensions found by the diagnosis or fitted by the calibration
    /// (the first `extension_count`): `side_slip` (k_beta), and
    /// `gnss_lever_arm` (the antenna's x, y from the rear-axle centre, m, and
    /// with `param_count` 4 their 1-sigma), and the sensor clocks
    /// ([`crate::effects::GNSS_CLOCK_EXTENSION`],
    /// [`crate::effects::IMU_CLOCK_EXTENSION`]: offset s, drift ppm,
    /// reference wheel time s).
    pub extensions: [ModelExtension; MAX_EXTENSIONS],
}

/// What the pose of a [`Pose`] stands on.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum PoseMode {
    /// No pose can be given (no fix yet, or inputs stale).
    NoFix = 0,
    /// GNSS fused with the odometry.
    Fused = 1,
    /// Dead-reckoning with the 2W model through a GNSS outage.
    DeadReckoning = 2,
}

impl PoseMode {
    /// The mode with this wire code.
    pub fn from_code(code: u8) -> Option<PoseMode> {
        match code {
            0 => Some(PoseMode::NoFix),
            1 => Some(PoseMode::Fused),
            2 => Some(PoseMode::DeadReckoning),
            _ => None,
        }
    }
}

/// The odometry's pose of the rear-axle centre.
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable)]
#[cfg_attr(feature = "bus", derive(ZeroCopySend))]
#[repr(C)]
#[cfg_attr(feature = "bus", type_name("wheelcal/Pose/v1"))]
pub struct Pose {
    /// Time of the wheel sample the pose belongs to, and sequence.
    pub header: Header,
    /// East, metres.
    pub x_m: f64,
    /// North, metres.
    pub y_m: f64,
    /// Yaw, rad, 0 = east, counter-clockwise positive.
    pub yaw_rad: f64,
    /// Covariance of (x, y, yaw), row-major 3x3.
    pub covariance: [f64; 9],
    /// Version of the circumference estimate in use (0 = nominal).
    pub estimate_version: u64,
    /// [`PoseMode`] as its `u8` code.
    pub mode: u8,
    /// Explicit padding, always zero.
    pub _pad: [u8; 7],
}

// Compile-time layout checks: a change here is a wire-format change and needs
// a new `/vN` type name.
const _: () = assert!(core::mem::size_of::<Header>() == 16);
const _: () = assert!(core::mem::size_of::<WheelRotations>() == 56);
const _: () = assert!(core::mem::size_of::<GnssFix>() == 48);
const _: () = assert!(core::mem::size_of::<Imu>() == 72);
const _: () = assert!(core::mem::size_of::<Heading>() == 32);
const _: () = assert!(core::mem::size_of::<ModelExtension>() == 40);
const _: () = assert!(core::mem::size_of::<CircumferenceEstimate>() == 416);
const _: () = assert!(core::mem::size_of::<Pose>() == 128);
const _: () = assert!(core::mem::align_of::<CircumferenceEstimate>() == 8);
