//! Calibrator: the paper's iterative estimation of the rear wheel
//! circumferences, and better estimators beside it.
