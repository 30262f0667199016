//! How every command of this binary that reads a drive reads it: the
//! options shared by every wheelcal binary ([`drive_io::cli::DriveInput`]).

pub use drive_io::cli::DriveInput;
