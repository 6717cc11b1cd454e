//! The crate's error type: every failure a user can cause, with a message that says where.

use crate::accel::AccelError;
use crate::output::OutputError;
use crate::scene::SceneError;
use crate::temporal::TemporalError;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error(transparent)]
    Scene(#[from] SceneError),
    #[error("Embree: {0}")]
    Accel(#[from] AccelError),
    #[error("temporal model: {0}")]
    Temporal(#[from] TemporalError),
    #[error(transparent)]
    Output(#[from] OutputError),
    #[error("{0}")]
    Invalid(String),
}
