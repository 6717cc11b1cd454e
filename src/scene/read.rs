//! Bounded reads: the scene description (`load.rs`) and the OBJ and PLY meshes it names
//! (`shapes.rs`, `ply.rs`).

use std::path::Path;

/// The largest scene description read (a scene is text; meshes go in OBJ files).
pub(crate) const MAX_SCENE_BYTES: u64 = 64 << 20;

/// Reads `path` as UTF-8 text if it is a regular file of at most `cap` bytes. FIFOs, devices
/// (`/dev/zero`) and folders are refused before they are opened, so reading never hangs or
/// runs out of memory.
pub(crate) fn read_regular_file(path: &Path, cap: u64) -> std::io::Result<String> {
    String::from_utf8(read_regular_bytes(path, cap)?)
        .map_err(|e| std::io::Error::new(std::io::ErrorKind::InvalidData, format!("not UTF-8 text: {e}")))
}

/// Opens `path` if it is a regular file (FIFOs, devices and folders refused before they are
/// opened, as by [`read_regular_file`]), to read a part of it (a PLY header).
pub(crate) fn open_regular(path: &Path) -> std::io::Result<std::fs::File> {
    if !std::fs::metadata(path)?.is_file() {
        return Err(std::io::Error::other("not a regular file (a folder, FIFO or device)"));
    }
    std::fs::File::open(path)
}

/// [`read_regular_file`] for bytes (binary meshes).
pub(crate) fn read_regular_bytes(path: &Path, cap: u64) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let meta = std::fs::metadata(path)?;
    if !meta.is_file() {
        return Err(std::io::Error::other("not a regular file (a folder, FIFO or device)"));
    }
    if meta.len() > cap {
        return Err(std::io::Error::other(format!(
            "{} bytes, more than the {} bytes read at most",
            meta.len(),
            cap
        )));
    }
    let mut bytes = Vec::new();
    let n = std::fs::File::open(path)?.take(cap + 1).read_to_end(&mut bytes)?;
    if n as u64 > cap {
        return Err(std::io::Error::other(format!("more than the {cap} bytes read at most")));
    }
    Ok(bytes)
}
