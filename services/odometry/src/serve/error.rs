//! Why the service could not run.

use interfaces::bus::BusError;
use interfaces::latency_trace::TraceError;
use std::path::PathBuf;
use vehicle_model::estimate::ParamsError;

#[derive(Debug, thiserror::Error)]
pub(crate) enum ServeError {
    /// An iceoryx2 operation failed.
    #[error(transparent)]
    Bus(#[from] BusError),
    /// The vehicle parameters could not be read.
    #[error("vehicle parameters from {path}: {detail}")]
    Vehicle {
        /// The file or drive.
        path: PathBuf,
        /// What went wrong.
        detail: String,
    },
    /// The initial estimate could not be read.
    #[error(transparent)]
    Estimate(#[from] ParamsError),
    /// The initial estimate is not one this vehicle can have.
    #[error("{0}")]
    ImplausibleEstimate(String),
    /// A setting is out of range.
    #[error("invalid setting: {0}")]
    Config(String),
    /// The latency trace could not be written.
    #[error(transparent)]
    Trace(#[from] TraceError),
}
