//! The estimate file that `calibrator calibrate --json` writes, read from
//! disk; the parsing is the estimate contract's ([`EstimateFile`], one
//! serde type for the calibrator's writer and this reader).

use crate::files::{read_text_limited, MAX_TEXT_FILE_BYTES};
use crate::DriveError;
use std::io::{Error, ErrorKind};
use std::path::Path;
use vehicle_model::estimate::{Estimate, ParamsError};
use vehicle_model::estimate_file::EstimateFile;
use vehicle_model::estimate_vehicle::EstimateVehicle;

/// Read and parse an estimate file written by `calibrator calibrate --json`.
///
/// Only a regular file of at most [`MAX_TEXT_FILE_BYTES`] is read: a FIFO,
/// a directory or a link to a device is refused without opening it, and a
/// larger file without reading it (both [`ParamsError::Io`], whose message
/// says what the path is or the size and the limit).
pub fn read_estimate(path: &Path) -> Result<Estimate, ParamsError> {
    let text = read_text(path)?;
    Estimate::from_json_str(&text, &path.display().to_string())
}

/// Read an estimate file and the vehicle it was made for (`None` when the
/// file does not say), to compare with the drive it is applied to
/// ([`EstimateVehicle::differences`]).
pub fn read_estimate_with_vehicle(
    path: &Path,
) -> Result<(Estimate, Option<EstimateVehicle>), ParamsError> {
    let text = read_text(path)?;
    let source = path.display().to_string();
    let file = EstimateFile::from_json_str(&text, &source)?;
    Ok((file.estimate(&source)?, file.made_for()))
}

fn read_text(path: &Path) -> Result<String, ParamsError> {
    let io = |source: Error| ParamsError::Io {
        path: path.to_path_buf(),
        source,
    };
    let text = read_text_limited(path, MAX_TEXT_FILE_BYTES).map_err(|e| match e {
        DriveError::Io { source, .. } => io(source),
        DriveError::NotAFile { what, .. } => io(Error::new(
            ErrorKind::InvalidInput,
            format!("expected a regular file, found {what}"),
        )),
        DriveError::FileTooLarge { size, limit, .. } => io(Error::new(
            ErrorKind::FileTooLarge,
            format!("{size} bytes, more than the {limit} bytes allowed for an estimate file"),
        )),
        other => io(Error::other(other.to_string())),
    })?;
    Ok(text)
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
