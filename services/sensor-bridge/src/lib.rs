//! Sensor bridge: drives in and out (drive folder, MCAP), the vehicle
//! simulator, and publishing drives over iceoryx2.

pub mod dev_data;
pub mod drive_io;
pub mod record;
pub mod replay;
pub mod sim;
pub use drive_io::{
    read_drive, read_vehicle, summarize, write_drive, DriveError, DriveSummary, LoadedDrive,
    LoadedVehicle,
};
