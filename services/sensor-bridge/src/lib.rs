//! Sensor bridge: drives onto the bus and back.
//!
//! - [`replay`]: publish a [`Drive`](interfaces::drive::Drive) on the sensor
//!   topics, paced or as fast as the subscribers take it.
//! - [`record`]: subscribe to the sensor topics and collect a drive.
//!
//! Reading and writing drive files is the `drive-io` library's; the vehicle
//! simulator is the `simulator` library's. The binary (`sensor-bridge`) puts
//! the three together as commands.

pub mod record;
pub mod replay;
