//! [`OutputError`]: every way writing a result can fail, each naming the file it was for.

use std::path::PathBuf;

/// A failed write. Every variant names the destination file; when one is returned, nothing
/// was written there (a file that already existed is left as it was).
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The data length does not match the shape it claims.
    #[error("{}: shape {shape:?} holds {expected} values, but {actual} were given", .path.display())]
    ShapeMismatch {
        /// The destination file.
        path: PathBuf,
        /// The claimed shape.
        shape: Vec<usize>,
        /// The product of `shape`.
        expected: usize,
        /// The length of the data given.
        actual: usize,
    },

    /// The shape's element count does not fit in memory (`usize` overflow).
    #[error("{}: shape {shape:?} is too large", .path.display())]
    ShapeOverflow {
        /// The destination file.
        path: PathBuf,
        /// The claimed shape.
        shape: Vec<usize>,
    },

    /// Nothing to write: some dimension is zero, or a list is empty.
    #[error("{}: nothing to write: {what}", .path.display())]
    Empty {
        /// The destination file.
        path: PathBuf,
        /// Which dimension or list is empty.
        what: String,
    },

    /// The data holds NaN or ±Inf. The renderer must never produce those, so this is refused
    /// rather than written.
    #[error("{}: {count} of {total} values are not finite (NaN or ±Inf); refusing to write", .path.display())]
    NonFinite {
        /// The destination file.
        path: PathBuf,
        /// How many values are NaN or ±Inf.
        count: usize,
        /// How many values there are.
        total: usize,
    },

    /// Only mono (1) and RGB (3) films are supported.
    #[error("{}: unsupported channel count {channels} (expected 1 for mono or 3 for RGB)", .path.display())]
    Channels {
        /// The destination file.
        path: PathBuf,
        /// The channel count given.
        channels: usize,
    },

    /// An argument other than the data is out of range (exposure, time axis, series length, ...).
    #[error("{}: {detail}", .path.display())]
    Invalid {
        /// The destination file.
        path: PathBuf,
        /// Which argument, what it was and what was expected.
        detail: String,
    },

    /// The file system refused (missing folder, no permission, disk full, ...). The
    /// operating system's error is in the message and is not also a `#[source]` (so not a
    /// field called `source`): a chain (`{:#}`, as `dtr` prints errors) would say it twice.
    #[error("cannot write {}: {err}", .path.display())]
    Io {
        /// The destination file.
        path: PathBuf,
        /// The operating system's error.
        err: std::io::Error,
    },

    /// The encoder of a file format failed.
    #[error("cannot encode {} as {format}: {detail}", .path.display())]
    Encode {
        /// The destination file.
        path: PathBuf,
        /// The format being written, e.g. "PNG" or "OpenEXR".
        format: &'static str,
        /// The encoder's message.
        detail: String,
    },

    /// No usable font was found for the text of a plot.
    #[error("{}: {detail}", .path.display())]
    Font {
        /// The plot file.
        path: PathBuf,
        /// What was looked for and not found.
        detail: String,
    },
}

impl OutputError {
    /// The file this error is about.
    pub fn path(&self) -> &std::path::Path {
        match self {
            OutputError::ShapeMismatch { path, .. }
            | OutputError::ShapeOverflow { path, .. }
            | OutputError::Empty { path, .. }
            | OutputError::NonFinite { path, .. }
            | OutputError::Channels { path, .. }
            | OutputError::Invalid { path, .. }
            | OutputError::Io { path, .. }
            | OutputError::Encode { path, .. }
            | OutputError::Font { path, .. } => path,
        }
    }

    /// The same error naming `to` where it named `from`: a file written under a temporary
    /// name (a staging folder's) is reported by the name it was written for.
    pub(crate) fn renamed(mut self, from: &std::path::Path, to: &std::path::Path) -> Self {
        let path = match &mut self {
            OutputError::ShapeMismatch { path, .. }
            | OutputError::ShapeOverflow { path, .. }
            | OutputError::Empty { path, .. }
            | OutputError::NonFinite { path, .. }
            | OutputError::Channels { path, .. }
            | OutputError::Invalid { path, .. }
            | OutputError::Io { path, .. }
            | OutputError::Encode { path, .. }
            | OutputError::Font { path, .. } => path,
        };
        if path == from {
            *path = to.to_path_buf();
        }
        self
    }

    pub(crate) fn invalid(path: &std::path::Path, detail: impl Into<String>) -> Self {
        OutputError::Invalid {
            path: path.to_path_buf(),
            detail: detail.into(),
        }
    }

    pub(crate) fn empty(path: &std::path::Path, what: impl Into<String>) -> Self {
        OutputError::Empty {
            path: path.to_path_buf(),
            what: what.into(),
        }
    }

    pub(crate) fn io(path: &std::path::Path, err: std::io::Error) -> Self {
        OutputError::Io {
            path: path.to_path_buf(),
            err,
        }
    }

    pub(crate) fn encode(path: &std::path::Path, format: &'static str, detail: impl ToString) -> Self {
        OutputError::Encode {
            path: path.to_path_buf(),
            format,
            detail: detail.to_string(),
        }
    }
}
