//! The journal of an output set's move into place (`output_set::OutputSet::commit`).
//!
//! The files of a set cannot be renamed into place in one step, so a render killed part-way
//! through the moves (SIGKILL, a power cut: nothing runs to undo them) would leave some new
//! files beside the earlier set's JSON, which would then describe files that are no longer
//! its. So the set moves in this order:
//! 1. the journal is written into the staging folder ([`JOURNAL`], written beside and renamed,
//!    so it is whole or absent): the files of the earlier set and of the new one;
//! 2. the earlier set's JSON is removed: from here on no JSON at the prefix claims a set;
//! 3. the new files are moved into place and the earlier set's stale ones removed;
//! 4. the new JSON is moved into place: the set is complete.
//!
//! A render to the same prefix that finds no JSON there reads the journals in the staging
//! folders a killed render left (before it removes them): their files are what it may replace
//! and, where it does not write them, remove.

use crate::output::OutputError;
use anyhow::Context;
use std::path::Path;

/// The journal's name in a staging folder (staged outputs are named by their suffix, which
/// never starts with a dot).
pub(super) const JOURNAL: &str = ".commit.json";

#[derive(serde::Serialize, serde::Deserialize)]
struct Journal {
    /// The earlier set's file names (None: a set written before JSONs listed their files,
    /// whose files are known by their form).
    earlier: Option<Vec<String>>,
    /// The new set's file names.
    files: Vec<String>,
}

/// Writes the journal of a move into `staging`: the earlier set's files (`earlier`, as
/// [`read_left`] returns them) and the new set's (`files`).
pub(super) fn write(staging: &Path, earlier: Option<&[String]>, files: &[String]) -> anyhow::Result<()> {
    let journal = Journal {
        earlier: earlier.map(<[String]>::to_vec),
        files: files.to_vec(),
    };
    let text = serde_json::to_string(&journal).context("cannot encode the output set's journal")?;
    let path = staging.join(JOURNAL);
    let part = staging.join(format!("{JOURNAL}.part"));
    std::fs::write(&part, text)
        .and_then(|()| std::fs::rename(&part, &path))
        .map_err(|e| OutputError::io(&path, e))
        .with_context(|| format!("cannot write {}", path.display()))
}

/// The files of the sets that the journals in `dir`'s folders whose names start with
/// `staging` describe (folders a killed render left; journals read up to `cap` bytes): None
/// when there is no readable journal,
/// Some(None) when one describes a set known only by the form of its files, otherwise the
/// union of their names.
pub(super) fn read_left(dir: &Path, staging: &str, cap: u64) -> Option<Option<Vec<String>>> {
    let mut found: Option<Option<Vec<String>>> = None;
    for entry in std::fs::read_dir(dir).ok()?.flatten() {
        let name = entry.file_name();
        if !name.to_str().is_some_and(|n| n.starts_with(staging)) || !entry.file_type().is_ok_and(|t| t.is_dir()) {
            continue;
        }
        let path = entry.path().join(JOURNAL);
        let Ok(text) = crate::scene::read_regular_file(&path, cap) else {
            continue;
        };
        let Ok(journal) = serde_json::from_str::<Journal>(&text) else {
            continue;
        };
        let names = journal.earlier.map(|mut e| {
            e.extend(journal.files);
            e
        });
        found = Some(match (found, names) {
            (None, names) => names,
            (Some(Some(mut a)), Some(b)) => {
                a.extend(b);
                Some(a)
            }
            _ => None,
        });
    }
    found.map(|f| {
        f.map(|mut v| {
            v.sort();
            v.dedup();
            v
        })
    })
}
