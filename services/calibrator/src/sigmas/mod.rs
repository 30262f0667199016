//! Stage 5, the sigmas: the sigmas and observability warnings
//! ([`uncertainty`]). The GNSS error model of the fits' residuals the
//! sigmas rest on is a shared module beside the stages
//! ([`crate::error_model`]): the fits compute their sigmas from it as
//! they go, and the diagnosis's information limit whitens with it.
//!
//! The fits compute their sigmas as they go (the batch fit from the error
//! model, the paper's from a block jackknife); [`of`] reads what the
//! primary method's sigmas say is not determined on the drive.

pub mod uncertainty;

use crate::fit::Fits;
use crate::reference::Reference;
use crate::warnings::{Warning, WarningCode};

/// The product of the sigmas stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Observability {
    /// What the estimate's sigmas say is not determined on the drive, as
    /// warnings (each names the parameter and the reason).
    pub warnings: Vec<Warning>,
}

/// The observability of the estimate in `fits` on the drive described by
/// `r`. Where the common scale came from the wheel + gyro model, the 2W
/// model's scale warning is left out (the fits warn on the model's own).
pub fn of(fits: &Fits, r: &Reference) -> Observability {
    let primary = &fits.primary;
    let mut warnings = uncertainty::observability(
        r,
        &primary.sigmas,
        primary.track_estimated,
        primary.residual_rms_m,
    );
    if fits.scale_from_gyro {
        warnings.retain(|w| w.code != WarningCode::ScaleUnobservable);
    }
    Observability { warnings }
}
