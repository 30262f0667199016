//! Shared contracts of the wheel-odometry calibration graph.
//!
//! - [`wire`]: the `#[repr(C)]` zero-copy types published over iceoryx2 and the
//!   service names they travel on. Only primitives and arrays cross the wire.
//! - [`drive`]: the in-memory drive (one time series per sensor plus the vehicle
//!   parameters) that every tool reads, writes, simulates and calibrates.
//! - [`collect`]: wire samples collected into a drive.
//! - [`effects`]: the stable ids of the physics catalogue.
//! - [`latency_trace`]: the latency trace file the latency bench reads.
//! - [`speed_map`]: the wheels' speed reading beyond the catalogue, as a
//!   comparison measures it and a twin carries it.
//! - [`yaw_wander`]: the wheels' slow yaw-rate error against the gyro, as
//!   a comparison measures it and a twin carries it.
//!
//! With the `bus` feature (on by default, off for the workspace's pure
//! libraries), the process side:
//!
//! - `bus`: the iceoryx2 helpers every service uses to open topics the same way.
//! - `sensors`: the four sensor subscribers, opened and drained together.
//! - `logging`: the one tracing setup every binary uses.

#[cfg(feature = "bus")]
pub mod bus;
pub mod collect;
pub mod drive;
pub mod effects;
pub mod latency_trace;
#[cfg(feature = "bus")]
pub mod logging;
#[cfg(feature = "bus")]
pub mod sensors;
pub mod speed_map;
pub mod wire;
pub mod yaw_wander;
