//! Stage 5, the sigmas: the error model of the fits' residuals
//! ([`error_model`]) and the sigmas and observability warnings
//! ([`uncertainty`]).

pub mod error_model;
pub mod uncertainty;
