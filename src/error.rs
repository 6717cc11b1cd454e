//! The crate's error type: every failure a user can cause, with a message that says where.

use crate::accel::AccelError;
use crate::output::OutputError;
use crate::scene::SceneError;
use crate::temporal::TemporalError;

/// Any failure of loading, rendering or writing. Its `Display` is one line for the user.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// The scene description could not be read or is invalid.
    #[error(transparent)]
    Scene(#[from] SceneError),
    /// Embree failed to create a device or build the scene's BVH.
    #[error("Embree: {0}")]
    Accel(#[from] AccelError),
    /// The film's time axis, the pulse or the gate is invalid. Not a `#[source]`: its
    /// message is already in this one, and a chain (`{:#}`) would print it twice.
    #[error("temporal model: {0}")]
    Temporal(TemporalError),
    /// An output file could not be written or its data is not writable as asked.
    #[error(transparent)]
    Output(#[from] OutputError),
    /// A request that does not fit the scene or the options (e.g. an unknown parameter, an
    /// adjoint of the wrong shape, a malformed shard); the message says what was expected.
    #[error("{0}")]
    Invalid(String),
}

impl From<TemporalError> for Error {
    fn from(e: TemporalError) -> Self {
        Error::Temporal(e)
    }
}
