//! Which estimator produces the result.

use serde::{Deserialize, Serialize};

/// Which estimator produces the result.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Method {
    /// The paper's iterative EKF + weighted least squares (eq. 3-11).
    Paper,
    /// Levenberg-Marquardt fit of the 2W model to the GNSS fixes over the
    /// whole drive, in segments with their own initial pose.
    Batch,
}

impl Method {
    /// The name used on the command line and in the JSON.
    pub fn name(self) -> &'static str {
        match self {
            Method::Paper => "paper",
            Method::Batch => "batch",
        }
    }
}

impl std::fmt::Display for Method {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}
