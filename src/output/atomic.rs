//! Atomic file replacement: write into a temporary file in the destination's folder, flush
//! and sync it, then rename it over the destination. A failure at any step removes the
//! temporary file, so a reader sees either the old file (or none) or the complete new one.

use super::OutputError;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// The writer handed to [`write_atomic`]'s closure: buffered, seekable (EXR needs `Seek`).
pub(crate) type AtomicWriter<'a> = BufWriter<&'a mut File>;

/// Writes `path` atomically with `write`, which fills the temporary file.
///
/// The temporary file is `.<file name>.<random>.tmp` beside `path`. New files get the usual
/// permissions (0666 less the umask), not the 0600 of a temporary file.
pub(crate) fn write_atomic<F>(path: &Path, write: F) -> Result<(), OutputError>
where
    F: FnOnce(&mut AtomicWriter<'_>) -> Result<(), OutputError>,
{
    stage_atomic(path, write)?.persist()
}

/// A file written whole and synced beside its destination, not yet in place: [`persist`]
/// renames it there; dropped before that, it is removed. Files that must appear together
/// are all staged before the first is persisted, so that a full disk leaves none of them.
///
/// [`persist`]: Self::persist
pub(crate) struct Staged {
    tmp: tempfile::NamedTempFile,
    path: PathBuf,
}

impl Staged {
    /// Renames the staged file to its destination.
    pub(crate) fn persist(self) -> Result<(), OutputError> {
        // On failure the PersistError owns the temporary file and deletes it when dropped.
        self.tmp
            .persist(&self.path)
            .map_err(|e| OutputError::io(&self.path, e.error))?;
        Ok(())
    }
}

/// [`write_atomic`]'s temporary file, written with `write`, flushed and synced, but not
/// renamed into place ([`Staged`]).
pub(crate) fn stage_atomic<F>(path: &Path, write: F) -> Result<Staged, OutputError>
where
    F: FnOnce(&mut AtomicWriter<'_>) -> Result<(), OutputError>,
{
    let name = path
        .file_name()
        .ok_or_else(|| OutputError::invalid(path, "not a file path (no file name)"))?;
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut builder = tempfile::Builder::new();
    let prefix = format!(".{}.", name.to_string_lossy());
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut tmp = builder.tempfile_in(dir).map_err(|e| OutputError::io(path, e))?;

    {
        let mut w = BufWriter::with_capacity(1 << 20, tmp.as_file_mut());
        write(&mut w)?;
        w.flush().map_err(|e| OutputError::io(path, e))?;
    }
    tmp.as_file().sync_all().map_err(|e| OutputError::io(path, e))?;
    Ok(Staged {
        tmp,
        path: path.to_path_buf(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn entries(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn writes_and_replaces() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        write_atomic(&p, |w| w.write_all(b"one").map_err(|e| OutputError::io(&p, e))).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"one");
        write_atomic(&p, |w| w.write_all(b"two!").map_err(|e| OutputError::io(&p, e))).unwrap();
        assert_eq!(std::fs::read(&p).unwrap(), b"two!");
        assert_eq!(entries(dir.path()), vec!["a.txt"]);
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let mode = std::fs::metadata(&p).unwrap().permissions().mode() & 0o777;
            assert_ne!(
                mode & 0o044,
                0,
                "final file should be readable by others per umask, got {mode:o}"
            );
        }
    }

    #[test]
    fn failure_mid_write_leaves_nothing_and_keeps_old_file() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("b.bin");
        let r = write_atomic(&p, |w| {
            w.write_all(&[7u8; 4096]).unwrap();
            Err(OutputError::invalid(&p, "simulated encoder failure"))
        });
        assert!(r.is_err());
        assert!(entries(dir.path()).is_empty(), "left behind: {:?}", entries(dir.path()));

        std::fs::write(&p, b"old").unwrap();
        let r = write_atomic(&p, |w| {
            w.write_all(b"partial").unwrap();
            Err(OutputError::invalid(&p, "simulated"))
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read(&p).unwrap(), b"old");
        assert_eq!(entries(dir.path()), vec!["b.bin"]);
    }

    #[test]
    fn missing_folder_is_an_error_naming_the_path() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("no/such/folder/c.npy");
        let e = write_atomic(&p, |_| Ok(())).unwrap_err();
        assert!(matches!(e, OutputError::Io { .. }));
        assert!(e.to_string().contains("no/such/folder/c.npy"), "{e}");
        assert!(entries(dir.path()).is_empty());
    }

    #[test]
    fn destination_is_a_folder() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub");
        std::fs::create_dir(&p).unwrap();
        let e = write_atomic(&p, |w| w.write_all(b"x").map_err(|e| OutputError::io(&p, e))).unwrap_err();
        assert!(e.to_string().contains("sub"), "{e}");
        assert_eq!(entries(dir.path()), vec!["sub"]);
    }
}
