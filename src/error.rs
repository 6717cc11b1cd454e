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
    /// Embree failed to create a device or build the scene's BVH. Not a `#[source]`, as
    /// [`Error::Temporal`]: its message is already in this one.
    #[error("Embree: {0}")]
    Accel(AccelError),
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
    /// A derivative was asked for with respect to a parameter the scene does not declare
    /// (`dtr render --diff NAME`; front ends that take the names otherwise name their own
    /// argument, [`Error::unknown_parameter`]).
    #[error("{}", Error::unknown_parameter(.path, "--diff", .name, .available))]
    UnknownParameter {
        /// The scene's file.
        path: std::path::PathBuf,
        /// The name asked for.
        name: String,
        /// The parameters the scene declares.
        available: Vec<String>,
    },
    /// The render was stopped from outside ([`crate::cancel::Cancel`]) before it finished.
    #[error("the render was cancelled before it finished")]
    Cancelled,
}

impl Error {
    /// [`Error::UnknownParameter`]'s message, naming `asked_by`, the option or argument that
    /// gave the names (`--diff` for the CLI), and listing the parameters the scene declares.
    pub fn unknown_parameter(path: &std::path::Path, asked_by: &str, name: &str, available: &[String]) -> String {
        let available = if available.is_empty() {
            "none; add [[param]] entries".to_string()
        } else {
            available.join(", ")
        };
        format!(
            "{}: {asked_by}: no parameter named {name:?} (parameters: {available})",
            path.display()
        )
    }
}

impl From<AccelError> for Error {
    fn from(e: AccelError) -> Self {
        Error::Accel(e)
    }
}

impl From<TemporalError> for Error {
    fn from(e: TemporalError) -> Self {
        Error::Temporal(e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `dtr` prints an error with its chain (`{:#}`: each source after a colon). A variant
    /// that writes its cause into its own message must not also give it as its source, or
    /// the cause is printed twice ("Embree: invalid mesh: m: invalid mesh: m"; an output's
    /// "No such file or directory" twice). Every variant says its cause once.
    #[test]
    fn no_error_says_its_cause_twice() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such folder");
        let cases: Vec<(Error, &str)> = vec![
            (
                AccelError::InvalidMesh("a triangle of 4 vertices".into()).into(),
                "a triangle of 4 vertices",
            ),
            (
                TemporalError::Invalid {
                    field: "film.bins",
                    expected: "at least 1",
                    got: "0".into(),
                }
                .into(),
                "film.bins",
            ),
            (
                crate::output::OutputError::io(std::path::Path::new("out/x.npy"), io).into(),
                "no such folder",
            ),
            (
                SceneError::Invalid {
                    path: "s.toml".into(),
                    at: "camera: field 'fov'".into(),
                    message: "must be in (0, 180)".into(),
                }
                .into(),
                "must be in (0, 180)",
            ),
            (Error::Invalid("no parameter named x".into()), "no parameter named x"),
            (
                Error::UnknownParameter {
                    path: "s.toml".into(),
                    name: "x".into(),
                    available: vec!["a".into(), "b".into()],
                },
                "s.toml: --diff: no parameter named \"x\" (parameters: a, b)",
            ),
        ];
        for (e, cause) in cases {
            let chain = format!("{:#}", anyhow::Error::from(e));
            assert_eq!(chain.matches(cause).count(), 1, "said more than once: {chain}");
        }
    }
}
