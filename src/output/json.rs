//! Pretty-printed JSON (metadata next to the film).

use super::OutputError;
use super::atomic::{Staged, stage_atomic};
use std::io::Write;
use std::path::Path;

/// Writes `value` as pretty-printed JSON with a trailing newline, atomically.
pub fn write_json(path: &Path, value: &serde_json::Value) -> Result<(), OutputError> {
    stage_json(path, value)?.persist()
}

/// [`write_json`]'s file, written and synced beside `path` but not yet in place ([`Staged`]).
pub(crate) fn stage_json(path: &Path, value: &serde_json::Value) -> Result<Staged, OutputError> {
    let mut bytes = serde_json::to_vec_pretty(value).map_err(|e| OutputError::encode(path, "JSON", e))?;
    bytes.push(b'\n');
    stage_atomic(path, |w| w.write_all(&bytes).map_err(|e| OutputError::io(path, e)))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("meta.json");
        let v = json!({"shape": [2, 3, 4, 1], "time_axis": {"start_opl": 0.5, "bins": 4}, "name": "ü"});
        write_json(&p, &v).unwrap();
        let text = std::fs::read_to_string(&p).unwrap();
        assert!(text.contains('\n') && text.ends_with('\n'));
        let back: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(back, v);
    }

    #[test]
    fn missing_folder() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("missing").join("m.json");
        let e = write_json(&p, &json!({})).unwrap_err();
        assert!(e.to_string().contains("m.json"));
        assert!(!p.exists());
    }
}
