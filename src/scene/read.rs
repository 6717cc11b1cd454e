//! Bounded reads: the scene description (`load.rs`) and the OBJ meshes it names (`shapes.rs`).

use std::path::Path;

/// Reads `path` as UTF-8 text if it is a regular file of at most `cap` bytes. FIFOs, devices
/// (`/dev/zero`) and folders are refused before they are opened, so reading never hangs or
/// runs out of memory.
pub(crate) fn read_regular_file(path: &Path, cap: u64) -> std::io::Result<String> {
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
    let mut text = String::new();
    let n = std::fs::File::open(path)?.take(cap + 1).read_to_string(&mut text)?;
    if n as u64 > cap {
        return Err(std::io::Error::other(format!("more than the {cap} bytes read at most")));
    }
    Ok(text)
}
