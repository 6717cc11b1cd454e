//! The files of one render (`PREFIX.npy`, `PREFIX.json`, derivatives, EXR, previews) appear
//! whole or not at all, never replace an input, and never mix with another render's.
//!
//! - **`-o` rules.** `-o out` writes `out.npy`, `out.json`, …; a trailing `.npy` or `.json` is
//!   dropped (`-o out.npy` and `-o out.json` are `-o out`); `-o dir/` or an existing folder writes `dir/SCENE.npy`, …
//!   with the scene file's stem. A missing output folder is created.
//! - **Checked before rendering.** The folder is created and written to (the lock file), and
//!   every output the render will write is checked: none may be an input (the scene file or
//!   an OBJ it names, compared by device and inode, so links and other spellings count), and
//!   none may be an existing folder. A bad `-o` fails in milliseconds, not after the render.
//! - **One writer per prefix.** `.NAME.dtr-lock` in the output folder is locked (an advisory
//!   `flock`) from before the render until the set is in place; a second render to the same
//!   prefix is refused with a message naming the lock. An output whose name is also one of
//!   another prefix's outputs (`x.steady.npy`: the steady image of `x`, the film of
//!   `x.steady`) takes that prefix's lock too, so two renders never write one file.
//! - **Whole or nothing.** Every file is written into a staging folder beside the outputs and
//!   moved into place only when all of them are written, the JSON last (its presence marks a
//!   complete set). A failure before that removes the staging folder.
//! - **A kill while the set moves.** The moves are journalled (`commit_journal.rs`): the
//!   earlier set's JSON is removed before the first file moves, so a render killed part-way
//!   (SIGKILL, a power cut) leaves no JSON beside a mix of two sets, and the next render to
//!   the prefix learns from the journal which files there were either set's.
//! - **Signals.** SIGINT, SIGTERM and SIGHUP remove the staging folder and the lock file and exit
//!   with 128 + the signal number; no temporary file is left behind. The writes into the
//!   staging folder and the moves into place each hold one lock (`WRITING`) that the signal
//!   thread takes before it removes anything and keeps until the process exits: a signal
//!   during a write waits for that file to be whole, then the set is removed and nothing more
//!   is written. A signal after the set is in place is let pass: the run ends with 0. Staging
//!   folders that a killed render left (`.NAME.dtr-staging-*`) are removed by the next render
//!   to the prefix, under its lock.
//! - **No stale files.** The JSON lists the set's files (`"files"`, names in the output
//!   folder). A render to a prefix that already holds a set removes the files of the old set
//!   (as its JSON lists them) that the new one does not write, before the new JSON lands: a
//!   `-o x --diff a` render followed by `-o x` leaves no `x.d_a.npy` behind. Only plain names
//!   in the same folder that have the form of one of dtr's own outputs for that prefix are
//!   removed (an edited JSON cannot name a scene), never an input.
//! - **Only its own files.** An existing file at an output's name is replaced only when the
//!   set at the prefix holds it (its JSON, or a file that JSON lists); anything else (a user's
//!   `notes.json` under `-o notes`, a measurement `meas.npy` under `-o meas`) is refused
//!   before rendering, naming it.

use super::commit_journal;
use crate::output::OutputError;
use anyhow::{Context, bail};
use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

/// Paths that the signal thread removes before exiting (staging folders, lock files).
static ON_SIGNAL: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// Held by the main thread while it makes or removes a watched path, writes a file into the
/// staging folder or moves the set into place, and by the signal thread from the signal until
/// the process exits: the two never work on the set at once (module docs).
static WRITING: Mutex<()> = Mutex::new(());

/// Set, under [`WRITING`], once an output set is in place: a signal after that has nothing to
/// undo.
static IN_PLACE: AtomicBool = AtomicBool::new(false);

/// Set by the signal thread before it waits for [`WRITING`]: the main thread then takes the
/// lock for no further write, so the signal thread gets it as soon as the current write ends.
/// (A mutex is not fair: the main thread, releasing it after one file and taking it again
/// for the next, won against the waiting signal thread, and a render interrupted while it
/// wrote its npy went on to write the rest and exit 0.)
static SIGNALLED: AtomicBool = AtomicBool::new(false);

/// [`WRITING`] for the main thread's next write: never while a signal waits for it.
fn writing() -> std::sync::MutexGuard<'static, ()> {
    loop {
        let guard = WRITING.lock().unwrap_or_else(|e| e.into_inner());
        if !SIGNALLED.load(Ordering::SeqCst) {
            return guard;
        }
        drop(guard);
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
}

/// Starts the thread that cleans up on SIGINT/SIGTERM/SIGHUP (once per process).
fn install_signal_cleanup() -> anyhow::Result<()> {
    static STARTED: std::sync::Once = std::sync::Once::new();
    let mut result = Ok(());
    STARTED.call_once(|| {
        use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
        // SIGHUP: the terminal a render runs in was closed
        match signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP]) {
            Ok(mut signals) => {
                std::thread::spawn(move || {
                    for sig in signals.forever() {
                        // kept until the exit: the main thread writes nothing more
                        SIGNALLED.store(true, Ordering::SeqCst);
                        let _writing = WRITING.lock().unwrap_or_else(|e| e.into_inner());
                        if IN_PLACE.load(Ordering::SeqCst) {
                            // the set is whole and in place; the run ends with 0
                            SIGNALLED.store(false, Ordering::SeqCst);
                            continue;
                        }
                        let paths = ON_SIGNAL.lock().map(|p| p.clone()).unwrap_or_default();
                        for p in paths {
                            let _ = if p.is_dir() {
                                std::fs::remove_dir_all(&p)
                            } else {
                                std::fs::remove_file(&p)
                            };
                        }
                        // a checkpointing render saves what it has finished (crate::checkpoint)
                        crate::checkpoint::write_on_signal();
                        eprintln!("dtr: interrupted (signal {sig}); no output was written");
                        super::exit_from_signal(128 + sig);
                    }
                });
            }
            Err(e) => result = Err(e),
        }
    });
    result.context("cannot install the SIGINT/SIGTERM/SIGHUP handler")
}

fn watch(p: &Path) {
    if let Ok(mut v) = ON_SIGNAL.lock() {
        v.push(p.to_path_buf());
    }
}

fn unwatch(p: &Path) {
    if let Ok(mut v) = ON_SIGNAL.lock() {
        v.retain(|q| q != p);
    }
}

/// The prefix that `-o` names (see the module docs).
pub fn resolve_prefix(output: &Path, scene: &Path) -> anyhow::Result<PathBuf> {
    let text = output.as_os_str().to_string_lossy();
    let names_folder = text.ends_with('/') || output.is_dir();
    if names_folder {
        let stem = scene.file_stem().filter(|s| !s.is_empty()).with_context(|| {
            format!(
                "-o {}: a folder, and the scene file has no name to use",
                output.display()
            )
        })?;
        return Ok(output.join(stem));
    }
    // the name of the set's film or of its JSON (a merge's `-o x.json` wrote x.json.json)
    let prefix = match text.strip_suffix(".npy").or_else(|| text.strip_suffix(".json")) {
        Some(p) => PathBuf::from(p),
        None => output.to_path_buf(),
    };
    match prefix.file_name() {
        Some(n) if !n.is_empty() && n != "." && n != ".." => Ok(prefix),
        _ => bail!(
            "-o {}: expected an output prefix such as out/run1 (files out/run1.npy, out/run1.json, ...)",
            output.display()
        ),
    }
}

/// `PREFIX.ext`, keeping any dots already in the prefix.
pub fn with_suffix(prefix: &Path, ext: &str) -> PathBuf {
    let mut s = prefix.as_os_str().to_owned();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

#[cfg(unix)]
fn same_file(a: &std::fs::Metadata, b: &std::fs::Metadata) -> bool {
    use std::os::unix::fs::MetadataExt;
    a.dev() == b.dev() && a.ino() == b.ino()
}

#[cfg(not(unix))]
fn same_file(_: &std::fs::Metadata, _: &std::fs::Metadata) -> bool {
    false
}

/// Each of `paths` that exists, with its metadata: the inputs an output is compared with
/// ([`replaced_input`]), taken before anything is written.
pub fn input_metadata(paths: &[PathBuf]) -> Vec<(PathBuf, std::fs::Metadata)> {
    paths
        .iter()
        .filter_map(|p| std::fs::metadata(p).ok().map(|m| (p.clone(), m)))
        .collect()
}

/// The input that a file at the output `dest` (of metadata `dest_meta`) would replace:
/// compared by device and inode, so links and other spellings of a path count.
pub fn replaced_input<'a>(
    dest_meta: &std::fs::Metadata,
    inputs: &'a [(PathBuf, std::fs::Metadata)],
) -> Option<&'a Path> {
    inputs
        .iter()
        .find(|(_, m)| same_file(m, dest_meta))
        .map(|(p, _)| p.as_path())
}

/// A render's output set while it is prepared and written.
pub struct OutputSet {
    prefix: PathBuf,
    inputs: Vec<(PathBuf, std::fs::Metadata)>,
    lock_path: PathBuf,
    _lock: File,
    /// The locks of the other prefixes that an output's name belongs to as well
    /// ([`prefixes_sharing_names`]), and their paths.
    shared: Vec<(File, PathBuf)>,
    staging: Option<tempfile::TempDir>,
    /// (staged file, destination), in the order they were added.
    files: Vec<(PathBuf, PathBuf)>,
    /// What the JSON at the prefix said before this render: which existing files it may
    /// replace.
    earlier: EarlierSet,
}

/// The most bytes of a render's JSON dtr reads back: an earlier set's (to learn its files), a
/// shard's (`dtr merge`), an optimisation target's (its time window). A render's JSON is
/// kilobytes; a merge of many shards' stays far below this.
pub(super) const JSON_CAP: u64 = 64 << 20;

/// The set an earlier render left at a prefix, as its JSON (`PREFIX.json`) describes it.
#[derive(Debug, PartialEq)]
enum EarlierSet {
    /// No JSON there: no earlier set, so no file there is dtr's.
    None,
    /// A JSON that is not a dtr set's (not an object with dtr's `"version"`): someone
    /// else's file.
    Foreign,
    /// Something at the JSON's path that cannot be read as one (why): a FIFO, a folder, a file
    /// larger than any JSON of dtr's, one it may not read. Its set is unknown, so nothing
    /// there is taken for dtr's.
    Unreadable(String),
    /// A dtr set; `files` its list of file names (None: written before the list existed,
    /// its files known by their form, [`is_own_output`]).
    Dtr { files: Option<Vec<String>> },
}

impl EarlierSet {
    fn read(json: &Path) -> Self {
        if std::fs::symlink_metadata(json).is_err() {
            return Self::None;
        }
        // regular files only, and no more than a JSON of dtr's holds: a FIFO there hung the
        // render before it began, an 8 GB file took 8 GB of memory to be found foreign
        let text = match crate::scene::read_regular_file(json, JSON_CAP) {
            Ok(text) => text,
            Err(e) => return Self::Unreadable(e.to_string()),
        };
        let Ok(serde_json::Value::Object(map)) = serde_json::from_str::<serde_json::Value>(&text) else {
            return Self::Foreign;
        };
        if !map.get("version").is_some_and(|v| v.is_string()) {
            return Self::Foreign;
        }
        let files = map
            .get("files")
            .and_then(|f| f.as_array())
            .map(|list| list.iter().filter_map(|v| v.as_str().map(str::to_string)).collect());
        Self::Dtr { files }
    }

    /// Whether the file `name` (a plain name in the prefix's folder; `stem` the prefix's) is
    /// part of this set: the JSON itself, or a file its list names (or, for a set without a
    /// list, a name of the form of dtr's own outputs).
    fn holds(&self, name: &str, stem: &str) -> bool {
        match self {
            Self::Dtr { files } => {
                name == format!("{stem}.json")
                    || files
                        .as_ref()
                        .map_or_else(|| is_own_output(name, stem), |f| f.iter().any(|n| n == name))
            }
            _ => false,
        }
    }
}

/// Makes the folder that will hold `file` (the output an `-o` path names) when it is missing,
/// as every dtr command does, and returns it (`.` for a bare file name). A failure is an
/// output error (exit 3) naming `-o` and the folder.
pub fn make_output_folder(output: &Path, file: &Path) -> anyhow::Result<PathBuf> {
    let dir = match file.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    create_folder(output, &dir)?;
    Ok(dir)
}

/// Makes `dir` and the folders above it, naming `-o output` when it cannot.
pub fn create_folder(output: &Path, dir: &Path) -> anyhow::Result<()> {
    std::fs::create_dir_all(dir)
        .map_err(|e| OutputError::io(dir, e))
        .with_context(|| {
            if dir == output {
                format!("-o {}: cannot create the output folder", output.display())
            } else {
                format!(
                    "-o {}: cannot create the output folder {}",
                    output.display(),
                    dir.display()
                )
            }
        })
}

impl OutputSet {
    /// Resolves `-o`, creates the folder, takes the prefix's lock and checks that none of
    /// `suffixes` (`"npy"`, `"json"`, …) would replace an input or a folder. Call it before
    /// rendering.
    pub fn prepare(output: &Path, scene_inputs: &[PathBuf], scene: &Path, suffixes: &[String]) -> anyhow::Result<Self> {
        install_signal_cleanup()?;
        let prefix = resolve_prefix(output, scene)?;
        refuse_long_file_names(&prefix, suffixes)?;
        let dir = make_output_folder(output, &prefix)?;
        let inputs = input_metadata(scene_inputs);
        let name = file_name(&prefix);
        let lock_path = dir.join(Reserved::of(&name).lock);
        refuse_inputs_in_reserved_names(scene_inputs, &dir, &name)?;
        let lock = Self::lock(&lock_path, &prefix)?;
        // a set of its own: a signal from now on undoes it, whatever sets this process put
        // in place before (library use may write several)
        IN_PLACE.store(false, Ordering::SeqCst);
        let earlier = match EarlierSet::read(&with_suffix(&prefix, "json")) {
            // a render killed while it moved its set into place left no JSON, and its journal
            EarlierSet::None => commit_journal::read_left(&dir, &Reserved::of(&name).staging, JSON_CAP)
                .map_or(EarlierSet::None, |files| EarlierSet::Dtr { files }),
            earlier => earlier,
        };
        remove_stale_staging(&dir, &name);
        let mut set = Self {
            prefix,
            inputs,
            lock_path,
            _lock: lock,
            shared: Vec::new(),
            staging: None,
            files: Vec::new(),
            earlier,
        };
        let names: Vec<String> = suffixes.iter().map(|s| format!("{name}.{s}")).collect();
        for other in prefixes_sharing_names(&name, &names) {
            refuse_inputs_in_reserved_names(scene_inputs, &dir, &other)?;
            let path = dir.join(Reserved::of(&other).lock);
            let lock = Self::lock(&path, &dir.join(&other)).with_context(|| {
                format!(
                    "an output of {} is also named as one of {other}'s",
                    set.prefix.display()
                )
            })?;
            set.shared.push((lock, path));
        }
        for s in suffixes {
            set.check_destination(&with_suffix(&set.prefix, s))?;
        }
        Ok(set)
    }

    /// Creates and locks `path`; refuses when another process holds the lock. Retries when
    /// the file was removed and recreated between opening and locking it (its holder just
    /// finished), so that two renders never both hold a lock on the same prefix.
    fn lock(path: &Path, prefix: &Path) -> anyhow::Result<File> {
        loop {
            let _writing = writing();
            // Only a regular file (or none) may stand there: a link would have dtr create, lock
            // and write through it wherever it leads, and a FIFO blocked the open until a
            // reader came, and caught signals with it.
            let what = match std::fs::symlink_metadata(path) {
                Ok(m) if m.file_type().is_symlink() => Some("a symbolic link"),
                Ok(m) if !m.is_file() => Some("not a regular file (a FIFO, device or folder)"),
                _ => None,
            };
            if let Some(what) = what {
                bail!(
                    "{} is {what} where dtr keeps the lock of the output prefix {}; remove it",
                    path.display(),
                    prefix.display()
                );
            }
            let mut open = std::fs::OpenOptions::new();
            open.create(true).truncate(false).write(true);
            // (O_NONBLOCK: one made there since is refused, not waited on)
            #[cfg(unix)]
            std::os::unix::fs::OpenOptionsExt::custom_flags(&mut open, libc::O_NOFOLLOW | libc::O_NONBLOCK);
            let f = open
                .open(path)
                .map_err(|e| OutputError::io(path, e))
                .with_context(|| format!("cannot lock the output prefix {}", prefix.display()))?;
            match f.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => bail!(
                    "another dtr render is writing {} (it holds {}); wait for it or choose another -o",
                    prefix.display(),
                    path.display()
                ),
                Err(std::fs::TryLockError::Error(e)) => {
                    return Err(OutputError::io(path, e))
                        .with_context(|| format!("cannot lock the output prefix {}", prefix.display()));
                }
            }
            let still_there = match (f.metadata(), std::fs::metadata(path)) {
                (Ok(a), Ok(b)) => same_file(&a, &b) || cfg!(not(unix)),
                _ => false,
            };
            if still_there {
                watch(path);
                return Ok(f);
            }
        }
    }

    /// Refuses a destination that is an input, an existing folder, or an existing file that
    /// no earlier dtr set at this prefix holds (a user's `notes.json` under `-o notes`).
    fn check_destination(&self, dest: &Path) -> anyhow::Result<()> {
        if std::fs::symlink_metadata(dest).is_err() {
            return Ok(());
        }
        // what the name leads to (None: a dangling link)
        let target = std::fs::metadata(dest).ok();
        if target.as_ref().is_some_and(|m| m.is_dir()) {
            bail!("output {} is an existing folder; choose another -o", dest.display());
        }
        if let Some(input) = target.and_then(|m| replaced_input(&m, &self.inputs)) {
            bail!(
                "output {} would replace the input {}; nothing was written. Choose another -o",
                dest.display(),
                input.display()
            );
        }
        let name = dest.file_name().unwrap_or_default().to_string_lossy();
        if !self.earlier.holds(&name, &self.stem()) {
            let json = with_suffix(&self.prefix, "json");
            let why = match &self.earlier {
                EarlierSet::None => format!("no dtr render's set is at this prefix ({} is missing)", json.display()),
                EarlierSet::Foreign => format!("{} is not a dtr render's JSON", json.display()),
                EarlierSet::Unreadable(why) => {
                    format!("{} cannot be read as a dtr render's JSON: {why}", json.display())
                }
                EarlierSet::Dtr { .. } => format!("the set at this prefix ({}) does not list it", json.display()),
            };
            bail!(
                "output {} already exists and is not a file of an earlier dtr render ({why}); \
                 dtr replaces only the files it wrote, so nothing was written. Move it away or choose another -o",
                dest.display()
            );
        }
        Ok(())
    }

    /// The file name of the prefix.
    fn stem(&self) -> String {
        file_name(&self.prefix)
    }

    /// The prefix the outputs are named after.
    pub fn prefix(&self) -> &Path {
        &self.prefix
    }

    /// Writes the output `PREFIX.suffix` with `write`, given the path to write it to (in the
    /// staging folder): it reaches its place in [`commit`], which checks every destination.
    /// A signal during the write waits for it to end (module docs). An [`OutputError`] about
    /// the staged file is returned naming `PREFIX.suffix`.
    ///
    /// [`commit`]: Self::commit
    pub fn write<T, E: Into<anyhow::Error>>(
        &mut self,
        suffix: &str,
        write: impl FnOnce(&Path) -> Result<T, E>,
    ) -> anyhow::Result<T> {
        let _writing = writing();
        let staged = self.stage(suffix)?;
        let dest = with_suffix(&self.prefix, suffix);
        // a failure names the output asked for, not its name in the staging folder
        write(&staged).map_err(|e| match e.into().downcast::<OutputError>() {
            Ok(e) => e.renamed(&staged, &dest).into(),
            Err(e) => e,
        })
    }

    /// Where to write `PREFIX.suffix` in the staging folder (made on first use); called with
    /// [`WRITING`] held.
    fn stage(&mut self, suffix: &str) -> anyhow::Result<PathBuf> {
        if self.staging.is_none() {
            let dir = self.lock_path.parent().unwrap_or(Path::new("."));
            let name = self.stem();
            let tmp = tempfile::Builder::new()
                .prefix(&Reserved::of(&name).staging)
                .tempdir_in(dir)
                .map_err(|e| OutputError::io(dir, e))
                .with_context(|| format!("cannot write to the output folder {}", dir.display()))?;
            watch(tmp.path());
            self.staging = Some(tmp);
        }
        let dest = with_suffix(&self.prefix, suffix);
        let staged = self.staging.as_ref().expect("created above").path().join(suffix);
        self.files.push((staged.clone(), dest));
        Ok(staged)
    }

    /// The SHA-256 of each output staged so far, by its file name in the output folder.
    pub fn digests(&self) -> anyhow::Result<serde_json::Map<String, serde_json::Value>> {
        self.files
            .iter()
            .map(|(staged, dest)| {
                let name = file_name(dest);
                Ok((name, serde_json::Value::from(super::digest::file_sha256(staged)?)))
            })
            .collect()
    }

    /// The file names (in the output folder) of the outputs staged so far and of
    /// `PREFIX.suffix`: the set the JSON lists.
    pub fn names_with(&self, suffix: &str) -> Vec<String> {
        let mut v = self.staged_names();
        v.push(file_name(&with_suffix(&self.prefix, suffix)));
        v
    }

    /// The file names (in the output folder) of the outputs staged so far.
    fn staged_names(&self) -> Vec<String> {
        self.files.iter().map(|(_, d)| file_name(d)).collect()
    }

    /// Leaves the staging folder in place (with its journal, [`commit_journal`]) for the next
    /// render to the prefix, as a killed render would.
    fn keep_staging(&mut self) {
        if let Some(s) = self.staging.take() {
            unwatch(s.path());
            let _ = s.keep();
        }
    }

    /// Moves every staged file into place, the JSON last, after checking every destination
    /// once more; files of the set the old JSON at this prefix listed and this one does not
    /// write are removed before the new JSON lands (module docs). The moves are journalled so
    /// that a render killed part-way leaves no JSON beside a mix of two sets
    /// ([`commit_journal`]).
    pub fn commit(mut self) -> anyhow::Result<PathBuf> {
        let _writing = writing();
        self.move_into_place(usize::MAX)?;
        IN_PLACE.store(true, Ordering::SeqCst);
        Ok(self.prefix.clone())
    }

    /// [`commit`]'s work in its order ([`commit_journal`]), stopping after `steps` steps (the
    /// journal, the earlier JSON's removal, each move and removal), as a kill would: tests
    /// stop it part-way. A failure once the journal is written keeps the staging folder, so
    /// that the next render to the prefix finds the journal.
    ///
    /// [`commit`]: Self::commit
    fn move_into_place(&mut self, steps: usize) -> anyhow::Result<()> {
        for (_, dest) in &self.files {
            self.check_destination(dest)?;
        }
        let stale = self.stale_files();
        self.files
            .sort_by_key(|(_, d)| d.extension().is_some_and(|e| e == "json"));
        let Some(staging) = self.staging.as_ref().map(|s| s.path().to_path_buf()) else {
            return Ok(());
        };
        let earlier: Option<Vec<String>> = match &self.earlier {
            EarlierSet::Dtr { files } => files.clone(),
            _ => Some(Vec::new()),
        };
        let names = self.staged_names();
        let mut taken = 0usize;
        let mut go = || {
            taken += 1;
            taken <= steps
        };
        if !go() {
            return Ok(());
        }
        commit_journal::write(&staging, earlier.as_deref(), &names)?;
        let result = (|| -> anyhow::Result<()> {
            let old_json = with_suffix(&self.prefix, "json");
            if std::fs::symlink_metadata(&old_json).is_ok() {
                if !go() {
                    return Ok(());
                }
                std::fs::remove_file(&old_json)
                    .map_err(|e| OutputError::io(&old_json, e))
                    .with_context(|| format!("cannot remove {}, the earlier set's JSON", old_json.display()))?;
            }
            for (staged, dest) in &self.files {
                if dest.extension().is_some_and(|e| e == "json") {
                    for old in &stale {
                        if !go() {
                            return Ok(());
                        }
                        std::fs::remove_file(old)
                            .map_err(|e| OutputError::io(old, e))
                            .with_context(|| format!("cannot remove {}, left by an earlier render", old.display()))?;
                    }
                }
                if !go() {
                    return Ok(());
                }
                std::fs::rename(staged, dest)
                    .map_err(|e| OutputError::io(dest, e))
                    .with_context(|| format!("cannot move {} into place", dest.display()))?;
            }
            Ok(())
        })();
        if result.is_err() {
            self.keep_staging();
        }
        result
    }

    /// The files the JSON already at `PREFIX.json` lists (an earlier render's set) that this
    /// set does not write: plain names of the prefix's own outputs ([`is_own_output`]), in
    /// the output folder, regular files, not inputs. Nothing when there is no such JSON or it
    /// lists no files (sets written before the list existed are left alone).
    fn stale_files(&self) -> Vec<PathBuf> {
        let EarlierSet::Dtr { files: Some(list) } = &self.earlier else {
            return Vec::new();
        };
        let dir = self.lock_path.parent().unwrap_or(Path::new("."));
        let stem = self.stem();
        // compared by name: the destinations all lie in `dir`
        let new: Vec<&std::ffi::OsStr> = self.files.iter().filter_map(|(_, d)| d.file_name()).collect();
        list.iter()
            .map(String::as_str)
            .filter(|n| {
                let plain = Path::new(n).file_name().is_some_and(|f| f == std::ffi::OsStr::new(n));
                plain && is_own_output(n, &stem)
            })
            .filter(|n| !new.contains(&std::ffi::OsStr::new(n)))
            .map(|n| dir.join(n))
            .filter(|p| {
                std::fs::symlink_metadata(p).is_ok_and(|m| m.is_file())
                    && std::fs::metadata(p).is_ok_and(|m| replaced_input(&m, &self.inputs).is_none())
            })
            .collect()
    }
}

/// The preview files `dtr render --preview` writes (`render_cmd::write_previews`; suffixes of
/// the prefix).
pub(super) const PREVIEWS: [&str; 5] = ["frames.png", "steady.png", "plot.png", "flight.gif", "streak.png"];

/// Whether `name` is a file dtr writes for the prefix whose file name is `stem` (`STEM.npy`,
/// `STEM.d_NAME.npy`, the previews, …; not the JSON itself). The old JSON's `"files"` is a
/// file anyone can edit, so a name it lists is removed as stale only when it has the form of
/// one of dtr's own outputs: `"STEM.toml"` there never deletes a scene.
fn is_own_output(name: &str, stem: &str) -> bool {
    let Some(suffix) = name.strip_prefix(stem).and_then(|s| s.strip_prefix('.')) else {
        return false;
    };
    // the render's fixed outputs (render_cmd, nlos_out, shard_set)
    const FIXED: [&str; 6] = ["npy", "exr", "steady.npy", "h5", "noisy.npy", "noisy.h5"];
    let derivative = suffix
        .strip_prefix("d_")
        .and_then(|s| s.strip_suffix(".npy").or_else(|| s.strip_suffix(".png")))
        .is_some_and(|param| !param.is_empty());
    let digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    // `--strategies`: PREFIX.s{s}_t{t}.npy
    let strategy = suffix
        .strip_prefix('s')
        .and_then(|s| s.strip_suffix(".npy"))
        .and_then(|s| s.split_once("_t"))
        .is_some_and(|(s, t)| digits(s) && digits(t));
    FIXED.contains(&suffix) || PREVIEWS.contains(&suffix) || derivative || strategy
}

/// The file name of `p`, as text.
fn file_name(p: &Path) -> String {
    p.file_name().unwrap_or_default().to_string_lossy().into_owned()
}

/// The other prefixes (file names in the same folder) that one of `names`, the outputs of the
/// prefix `stem`, is also an output of: `x.steady.npy` is the steady image of `x` and the film
/// of `x.steady`, `x.d_a.npy` a derivative of `x` and the film of `x.d_a`. A render locks
/// them too, so two renders at once never write one file (`-o x --preview` and `-o x.steady`
/// would each have written `x.steady.npy` and listed it in their JSON). In a fixed order.
fn prefixes_sharing_names(stem: &str, names: &[String]) -> Vec<String> {
    let mut out: Vec<String> = names
        .iter()
        .flat_map(|name| name.match_indices('.').map(move |(k, _)| (name, &name[..k])))
        .filter(|(name, other)| !other.is_empty() && *other != stem && is_own_output(name, other))
        .map(|(_, other)| other.to_string())
        .collect();
    out.sort();
    out.dedup();
    out
}

/// The longest file name (in bytes) that Linux's file systems and macOS's take (NAME_MAX).
pub(super) const NAME_MAX: usize = 255;

/// Refuses a prefix whose outputs (`suffixes`), or the files a render keeps beside them (its
/// lock, staging folder and checkpoint's temporary file, and the locks of the prefixes that
/// share an output's name), would have a file name longer than [`NAME_MAX`] bytes, before
/// anything is made. Before, a parameter's name of 246 characters failed when the render
/// took its locks, with exit 3 and a message of three nested causes ("an output of out/x is
/// also named as one of x.d_aaa…'s: cannot lock the output prefix …: cannot write
/// out/.x.d_aaa….dtr-lock: File name too long").
fn refuse_long_file_names(prefix: &Path, suffixes: &[String]) -> anyhow::Result<()> {
    let name = file_name(prefix);
    let outputs: Vec<String> = suffixes.iter().map(|s| format!("{name}.{s}")).collect();
    let kept = |n: &str| {
        let r = Reserved::of(n);
        // tempfile's six random characters; a checkpoint's temporary file ends in ".tmp"
        [
            r.lock,
            format!("{}XXXXXX", r.staging),
            format!("{}XXXXXX.tmp", r.checkpoint),
        ]
    };
    let longest = |names: Vec<String>| names.into_iter().filter(|n| n.len() > NAME_MAX).max_by_key(|n| n.len());
    // an output first: the name the user asked for says more than a hidden file's
    let too_long = longest(outputs.clone()).or_else(|| {
        let others = prefixes_sharing_names(&name, &outputs);
        longest(
            kept(&name)
                .into_iter()
                .chain(others.iter().map(|o| Reserved::of(o).lock))
                .collect(),
        )
    });
    if let Some(longest) = too_long {
        let what = if suffixes.iter().any(|s| s.starts_with("d_")) {
            "a shorter -o prefix or shorter parameter names"
        } else {
            "a shorter -o prefix"
        };
        bail!(
            "-o {}: the render would make a file named {longest:?} ({} bytes), and a file name may have at \
             most {NAME_MAX} bytes; use {what}",
            prefix.display(),
            longest.len()
        );
    }
    Ok(())
}

/// The names a render to the prefix named NAME keeps beside its outputs: its lock file, its
/// staging folders (a prefix, then tempfile's six characters) and its checkpoint's temporary
/// files (a prefix, six characters, `.tmp`: `output::write_atomic`).
struct Reserved {
    lock: String,
    staging: String,
    checkpoint: String,
}

impl Reserved {
    fn of(name: &str) -> Self {
        Self {
            lock: format!(".{name}.dtr-lock"),
            staging: format!(".{name}.dtr-staging-"),
            checkpoint: format!(".{name}.checkpoint."),
        }
    }
}

/// Refuses an input that lies where a render to the prefix named `name` in `dir` keeps its
/// lock (`.NAME.dtr-lock`, removed at exit), a staging folder or a checkpoint's temporary
/// file (removed as a killed render's, [`remove_stale_staging`]): an OBJ named like the lock
/// file was deleted at the exit, one inside a folder named like a staging folder with it.
fn refuse_inputs_in_reserved_names(inputs: &[PathBuf], dir: &Path, name: &str) -> anyhow::Result<()> {
    let Ok(dir) = std::fs::canonicalize(dir) else {
        return Ok(());
    };
    for input in inputs {
        let Ok(path) = std::fs::canonicalize(input) else {
            continue;
        };
        let Ok(rest) = path.strip_prefix(&dir) else { continue };
        let Some(first) = rest.components().next().and_then(|c| c.as_os_str().to_str()) else {
            continue;
        };
        let r = Reserved::of(name);
        let reserved = first == r.lock
            || first.starts_with(&r.staging)
            || (first.starts_with(&r.checkpoint) && first.ends_with(".tmp"));
        if reserved {
            bail!(
                "the input {} lies where dtr keeps the lock or temporary files of the output prefix {name} in {} (it would be removed): rename it, or write elsewhere",
                input.display(),
                dir.display()
            );
        }
    }
    Ok(())
}

/// Removes what earlier renders to the prefix named `name` in `dir` left when killed: their
/// staging folders (`.NAME.dtr-staging-` and tempfile's six characters), the temporary
/// files of checkpoints they were writing (`.NAME.checkpoint.` six characters `.tmp`,
/// `output::write_atomic`; 50 MB each on a large film, kept by every later render before
/// 2026-11-30), and the locks they took on prefixes that share names with theirs
/// (`.NAME.steady.dtr-lock` of a render with `--preview`, which a later render without it
/// never took, so never removed: an independent sweep, 2026-12-02) where no render holds
/// them. Called with the prefix's lock held, so no render is writing the rest.
fn remove_stale_staging(dir: &Path, name: &str) {
    let random = |s: &str| s.len() == 6 && s.bytes().all(|b| b.is_ascii_alphanumeric());
    let Reserved {
        staging, checkpoint, ..
    } = Reserved::of(name);
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for e in entries.flatten() {
        let file_name = e.file_name();
        let Some(n) = file_name.to_str() else { continue };
        let Ok(kind) = e.file_type() else { continue };
        if n.strip_prefix(staging.as_str()).is_some_and(random) && kind.is_dir() {
            let _ = std::fs::remove_dir_all(e.path());
        }
        let temporary = n.strip_prefix(checkpoint.as_str()).and_then(|r| r.strip_suffix(".tmp"));
        if temporary.is_some_and(random) && kind.is_file() {
            let _ = std::fs::remove_file(e.path());
        }
        let shared = n
            .strip_prefix(&format!(".{name}."))
            .and_then(|r| r.strip_suffix(".dtr-lock"));
        if shared.is_some_and(|r| !r.is_empty()) && kind.is_file() {
            remove_unheld_lock(&e.path());
        }
    }
}

/// Removes the lock file `path` when no render holds it. One that starts to lock it as it
/// goes finds it gone and makes another (`OutputSet::lock`).
fn remove_unheld_lock(path: &Path) {
    let mut open = std::fs::OpenOptions::new();
    open.write(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut open, libc::O_NOFOLLOW | libc::O_NONBLOCK);
    if let Ok(f) = open.open(path)
        && f.try_lock().is_ok()
    {
        let _ = std::fs::remove_file(path);
    }
}

impl Drop for OutputSet {
    fn drop(&mut self) {
        let _writing = writing();
        if let Some(s) = self.staging.take() {
            unwatch(s.path());
            drop(s);
        }
        for (_, path) in &self.shared {
            unwatch(path);
            let _ = std::fs::remove_file(path);
        }
        unwatch(&self.lock_path);
        let _ = std::fs::remove_file(&self.lock_path);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn own_outputs_are_recognised_by_their_form() {
        for own in [
            "p.npy",
            "p.exr",
            "p.steady.npy",
            "p.d_plane_z.npy",
            "p.d_plane_z.png",
            "p.s2_t1.npy",
            "p.frames.png",
            "p.flight.gif",
            "p.h5",
            "p.noisy.npy",
        ] {
            assert!(is_own_output(own, "p"), "{own}");
        }
        for other in [
            "p.toml",
            "p.victim.npy",
            "p.json",
            "p.d_.npy",
            "p.sx_t1.npy",
            "q.npy",
            "pp.npy",
            "p.checkpoint",
        ] {
            assert!(!is_own_output(other, "p"), "{other}");
        }
    }

    /// Writes a set of `suffixes` (and the JSON) at `out`, each file holding `label`; with
    /// `kill_after`, stops moving it into place after that many steps and leaves its staging
    /// folder, as a SIGKILL would.
    fn write_set(
        out: &Path,
        scene: &Path,
        label: &str,
        suffixes: &[&str],
        kill_after: Option<usize>,
    ) -> anyhow::Result<()> {
        let planned: Vec<String> = suffixes
            .iter()
            .map(|s| s.to_string())
            .chain(["json".to_string()])
            .collect();
        let mut set = OutputSet::prepare(out, &[scene.to_path_buf()], scene, &planned)?;
        for s in suffixes {
            set.write(s, |p| std::fs::write(p, label))?;
        }
        let files = set.names_with("json");
        let json = serde_json::json!({ "version": "test", "label": label, "files": files });
        set.write("json", |p| std::fs::write(p, json.to_string()))?;
        match kill_after {
            None => set.commit().map(|_| ()),
            Some(steps) => {
                set.move_into_place(steps)?;
                set.keep_staging();
                Ok(())
            }
        }
    }

    /// The files in `dir` other than the scene, sorted.
    fn listing(dir: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| n != "s.toml")
            .collect();
        v.sort();
        v
    }

    /// A render killed at any step of moving its set into place never leaves a JSON beside
    /// files that are not that JSON's set's (before the journal, the earlier set's JSON stayed
    /// while the new files replaced its own), and the next render to the prefix replaces
    /// whatever either set wrote and leaves nothing of them behind.
    #[test]
    fn a_render_killed_while_moving_its_set_leaves_no_mixed_set() {
        // the killed set's steps: journal, earlier JSON, two moves, a stale file, its JSON
        for kill_after in 0..7 {
            let dir = tempfile::tempdir().unwrap();
            let (out, scene) = (dir.path().join("x"), dir.path().join("s.toml"));
            std::fs::write(&scene, "").unwrap();
            write_set(&out, &scene, "A", &["npy", "d_a.npy"], None).unwrap();
            write_set(&out, &scene, "B", &["npy", "d_b.npy"], Some(kill_after)).unwrap();
            let json = dir.path().join("x.json");
            if let Ok(text) = std::fs::read_to_string(&json) {
                let set: serde_json::Value = serde_json::from_str(&text).unwrap();
                let label = set["label"].as_str().unwrap();
                let files: Vec<&str> = set["files"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter_map(|f| f.as_str())
                    .collect();
                for f in &files {
                    if *f != "x.json" {
                        let held = std::fs::read_to_string(dir.path().join(f)).unwrap();
                        assert_eq!(held, label, "killed after {kill_after} steps: {f} is not set {label}'s");
                    }
                }
                for f in listing(dir.path()) {
                    let outputs = f.starts_with("x.");
                    assert!(
                        !outputs || files.contains(&f.as_str()),
                        "killed after {kill_after}: {f} beside set {label}"
                    );
                }
            }
            write_set(&out, &scene, "C", &["npy"], None)
                .unwrap_or_else(|e| panic!("killed after {kill_after}: the next render was refused: {e:#}"));
            assert_eq!(listing(dir.path()), ["x.json", "x.npy"], "killed after {kill_after}");
            assert_eq!(std::fs::read_to_string(dir.path().join("x.npy")).unwrap(), "C");
        }
    }

    /// Two renders whose outputs share a file name never run at once: `-o q --preview` writes
    /// `q.steady.npy`, which is `-o q.steady`'s film. Before, each took only its own prefix's
    /// lock, and both wrote that file and listed it in their JSON. Prefixes that share no
    /// output name still run at once, and no lock file is left behind.
    #[test]
    fn renders_whose_outputs_share_a_name_do_not_run_at_once() {
        let dir = tempfile::tempdir().unwrap();
        let scene = dir.path().join("s.toml");
        std::fs::write(&scene, "").unwrap();
        let prepare = |prefix: &str, suffixes: &[&str]| {
            let suffixes: Vec<String> = suffixes.iter().map(|s| s.to_string()).collect();
            OutputSet::prepare(
                &dir.path().join(prefix),
                std::slice::from_ref(&scene),
                &scene,
                &suffixes,
            )
        };
        let preview = ["npy", "steady.npy", "json"];
        let first = prepare("q", &preview).unwrap();
        let err = prepare("q.steady", &["npy", "json"])
            .err()
            .expect("q.steady.npy is written by both");
        assert!(format!("{err:#}").contains("another dtr render"), "{err:#}");
        drop(first);
        let first = prepare("q.steady", &["npy", "json"]).unwrap();
        assert!(prepare("q", &preview).is_err(), "the other way round");
        drop(first);
        let first = prepare("q", &["npy", "d_a.npy", "json"]).unwrap();
        assert!(
            prepare("q.d_a", &["npy", "json"]).is_err(),
            "q.d_a.npy is written by both"
        );
        let apart = prepare("q.v2", &["npy", "json"]).expect("q.v2's outputs are not q's");
        drop((first, apart));
        assert_eq!(listing(dir.path()), Vec::<String>::new());
    }

    #[test]
    fn prefix_rules() {
        let scene = Path::new("scenes/room.toml");
        assert_eq!(
            resolve_prefix(Path::new("out/a"), scene).unwrap(),
            PathBuf::from("out/a")
        );
        assert_eq!(
            resolve_prefix(Path::new("out/a.npy"), scene).unwrap(),
            PathBuf::from("out/a")
        );
        assert_eq!(
            resolve_prefix(Path::new("out/a.b"), scene).unwrap(),
            PathBuf::from("out/a.b")
        );
        assert_eq!(
            resolve_prefix(Path::new("out/"), scene).unwrap(),
            PathBuf::from("out/room")
        );
        assert!(resolve_prefix(Path::new(".npy"), scene).is_err());
        assert_eq!(
            resolve_prefix(Path::new(".."), scene).unwrap(),
            PathBuf::from("../room")
        );
    }
}
