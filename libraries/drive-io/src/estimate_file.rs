//! The estimate file that `calibrator calibrate --json` writes, read from
//! disk; the parsing is the estimate contract's
//! ([`Estimate::from_json_str`]).

use std::path::Path;
use vehicle_model::estimate::{Estimate, ParamsError};

/// Read and parse an estimate file written by `calibrator calibrate --json`.
pub fn read_estimate(path: &Path) -> Result<Estimate, ParamsError> {
    let text = std::fs::read_to_string(path).map_err(|source| ParamsError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    Estimate::from_json_str(&text, &path.display().to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unreadable_file_names_the_path() {
        let msg = read_estimate(Path::new("/nonexistent/est.json"))
            .unwrap_err()
            .to_string();
        assert!(msg.contains("/nonexistent/est.json"), "{msg}");
    }
}
