//! SHA-256 digests as the JSONs record them: a shard's files (`files_sha256`), which
//! `dtr merge` checks as it reads them (`npy_in::read_f32_hashed`).

use anyhow::Context;
use sha2::{Digest, Sha256};
use std::path::Path;

/// The SHA-256 of a file's bytes, as hex: what a shard's JSON records of each of its files
/// (`files_sha256`) as its render writes them (`output_set`).
pub fn file_sha256(path: &Path) -> anyhow::Result<String> {
    let mut file = std::fs::File::open(path).with_context(|| format!("cannot read {} to hash it", path.display()))?;
    let mut hash = Sha256::new();
    std::io::copy(&mut file, &mut hash).with_context(|| format!("cannot read {} to hash it", path.display()))?;
    Ok(hex(&hash.finalize()))
}

/// Bytes as lowercase hex (a digest as the JSON records it).
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}
