//! Outputs never replace an input, are checked before the render, appear whole or not at
//! all, never mix two renders, and leave nothing behind on SIGTERM (issue 14, data safety;
//! src/cli/output_set.rs). Each case failed before that module: `dtr render room.json -o
//! room` replaced the scene with the run's metadata (exit 0), `-o out.npy` wrote
//! `out.npy.npy`, `-o dir/` wrote a hidden `dir/.npy`, a failed JSON write left `y.npy`
//! without `y.json`, and a signal during the write left hidden `.tmp` files.

#[cfg(unix)]
use std::os::unix::fs::FileTypeExt;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn dtr(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_dtr"))
        .current_dir(cwd)
        .args(args)
        .output()
        .unwrap()
}

/// Starts dtr with `args` in `cwd`, its stderr piped (for the tests that signal or stop it).
fn spawn(args: &[&str], cwd: &Path) -> std::process::Child {
    Command::new(env!("CARGO_BIN_EXE_dtr"))
        .current_dir(cwd)
        .args(args)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap()
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// A folder holding `room.toml` (diff_room.toml) and the same scene as `room.json`.
fn workdir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let src = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/diff_room.toml");
    let text = std::fs::read_to_string(src).unwrap();
    std::fs::write(dir.path().join("room.toml"), &text).unwrap();
    let value: toml::Value = toml::from_str(&text).unwrap();
    std::fs::write(dir.path().join("room.json"), serde_json::to_string(&value).unwrap()).unwrap();
    dir
}

fn listing(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn an_output_never_replaces_the_scene() {
    let dir = workdir();
    let before = std::fs::read(dir.path().join("room.json")).unwrap();
    let o = dtr(&["render", "room.json", "-o", "room", "--spp", "1", "-q"], dir.path());
    assert!(!o.status.success(), "rendered over its own scene");
    let e = stderr(&o);
    assert!(e.contains("would replace the input") && e.contains("room.json"), "{e}");
    assert_eq!(std::fs::read(dir.path().join("room.json")).unwrap(), before);
    assert_eq!(listing(dir.path()), ["room.json", "room.toml"]);
    // the same file under another name (a hard link) is refused too
    std::fs::hard_link(dir.path().join("room.toml"), dir.path().join("alias.json")).unwrap();
    let o = dtr(&["render", "room.toml", "-o", "alias", "--spp", "1", "-q"], dir.path());
    assert!(!o.status.success(), "{}", stderr(&o));
    assert!(stderr(&o).contains("would replace the input"), "{}", stderr(&o));
}

#[test]
fn an_obj_input_is_never_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let scenes = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes");
    std::fs::copy(scenes.join("obj_mesh.toml"), dir.path().join("obj_mesh.toml")).unwrap();
    std::fs::create_dir(dir.path().join("meshes")).unwrap();
    std::fs::copy(scenes.join("meshes/pyramid.obj"), dir.path().join("meshes/pyramid.obj")).unwrap();
    // an output set named after the mesh: PREFIX.exr would be harmless, but take a link
    std::fs::hard_link(dir.path().join("meshes/pyramid.obj"), dir.path().join("mesh.json")).unwrap();
    let o = dtr(
        &["render", "obj_mesh.toml", "-o", "mesh", "--spp", "1", "-q"],
        dir.path(),
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("pyramid.obj"), "{}", stderr(&o));
}

/// `-o notes` where the user keeps `notes.json` (or `notes.npy`, a measurement) that no dtr
/// render wrote: refused before rendering, naming the file, which stays as it was. A set a
/// render wrote there is replaced as before, and so is one whose JSON predates the `"files"`
/// list (its files known by their names). Before, the user's file was silently replaced.
#[test]
fn a_file_that_no_render_wrote_is_never_replaced() {
    let dir = workdir();
    for (name, text) in [("notes.json", "{\"mine\": true}"), ("meas.npy", "not dtr's")] {
        std::fs::write(dir.path().join(name), text).unwrap();
        let prefix = name.split('.').next().unwrap();
        let o = dtr(&["render", "room.toml", "-o", prefix, "--spp", "1", "-q"], dir.path());
        assert_eq!(o.status.code(), Some(2), "{name}: {}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains(name) && e.contains("not a file of an earlier dtr render"),
            "{e}"
        );
        assert_eq!(std::fs::read_to_string(dir.path().join(name)).unwrap(), text);
    }
    assert_eq!(
        listing(dir.path()),
        ["meas.npy", "notes.json", "room.json", "room.toml"]
    );
    // a dtr set is replaced, and so is one from before the list of files
    let ok = |args: &[&str]| {
        let o = dtr(args, dir.path());
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    };
    ok(&["render", "room.toml", "-o", "x", "--spp", "1", "-q"]);
    ok(&["render", "room.toml", "-o", "x", "--spp", "2", "-q"]);
    let json = dir.path().join("x.json");
    let mut j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    j.as_object_mut().unwrap().remove("files");
    std::fs::write(&json, j.to_string()).unwrap();
    ok(&["render", "room.toml", "-o", "x", "--spp", "1", "-q"]);
    // a file the set does not list is the user's, even beside a dtr set
    std::fs::write(dir.path().join("x.exr"), "mine").unwrap();
    let o = dtr(
        &["render", "room.toml", "-o", "x", "--spp", "1", "-q", "--exr"],
        dir.path(),
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("does not list it"), "{}", stderr(&o));
    assert_eq!(std::fs::read_to_string(dir.path().join("x.exr")).unwrap(), "mine");
}

/// Whatever stands at PREFIX.json that cannot be read as a JSON (a FIFO, a file of
/// gigabytes) is refused at once, naming it and why, and left as it was. Before, a FIFO there
/// hung the render before it began (killed after 10 s here), and an 8 GB file took 8 GB of
/// memory and 30 s to be called foreign.
#[cfg(unix)]
#[test]
fn what_cannot_be_read_as_an_earlier_json_is_refused_at_once() {
    let dir = workdir();
    let fifo = dir.path().join("pipe.json");
    let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(made.success());
    std::fs::File::create(dir.path().join("big.json"))
        .unwrap()
        .set_len(8 << 30)
        .unwrap();
    std::fs::write(dir.path().join("big.npy"), "not dtr's").unwrap();
    for (prefix, why) in [("pipe", "not a regular file"), ("big", "more than the")] {
        let o = run_within_10_s(&["render", "room.toml", "-o", prefix, "--spp", "1", "-q"], dir.path());
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "-o {prefix}: {e}");
        assert!(
            e.contains(&format!("{prefix}.json cannot be read as a dtr render's JSON")) && e.contains(why),
            "-o {prefix}: {e}"
        );
    }
    assert!(std::fs::symlink_metadata(&fifo).unwrap().file_type().is_fifo());
    assert_eq!(std::fs::metadata(dir.path().join("big.json")).unwrap().len(), 8 << 30);
    assert_eq!(
        listing(dir.path()),
        ["big.json", "big.npy", "pipe.json", "room.json", "room.toml"]
    );
}

/// Runs dtr with `args` in `cwd`, killing it (and failing) if it is still running after 10 s.
#[cfg(unix)]
fn run_within_10_s(args: &[&str], cwd: &Path) -> Output {
    let mut child = spawn(args, cwd);
    let start = std::time::Instant::now();
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(10) {
            child.kill().unwrap();
            panic!("{args:?}: still running after 10 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.wait_with_output().unwrap()
}

/// A FIFO where dtr keeps a prefix's lock (`.NAME.dtr-lock`), where `--resume` reads the
/// checkpoint, or where `dtr import` would write is refused at once and left as it was.
/// Before, the first blocked the render in `open` for good (SIGTERM and SIGINT did not end
/// it), the second until a writer came, and the third until a reader did (found by an
/// independent audit).
#[cfg(unix)]
#[test]
fn fifos_where_the_lock_the_checkpoint_or_an_import_goes_are_refused_at_once() {
    let dir = workdir();
    let fifo = |name: &str| {
        let made = Command::new("mkfifo").arg(dir.path().join(name)).status().unwrap();
        assert!(made.success());
    };
    fifo(".locked.dtr-lock");
    let o = run_within_10_s(&["render", "room.toml", "-o", "locked", "--spp", "1", "-q"], dir.path());
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.contains(".locked.dtr-lock is not a regular file"), "{e}");
    fifo("resumed.checkpoint");
    let o = run_within_10_s(
        &["render", "room.toml", "-o", "resumed", "--spp", "1", "-q", "--resume"],
        dir.path(),
    );
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("resumed.checkpoint") && e.contains("not a regular file"),
        "{e}"
    );
    let xml = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_box.xml");
    fifo("imported.toml");
    let o = run_within_10_s(&["import", xml.to_str().unwrap(), "-o", "imported.toml"], dir.path());
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("imported.toml: the output exists and is not a description dtr import wrote"),
        "{e}"
    );
    for name in [".locked.dtr-lock", "resumed.checkpoint", "imported.toml"] {
        let kind = std::fs::symlink_metadata(dir.path().join(name)).unwrap().file_type();
        assert!(kind.is_fifo(), "{name}");
    }
    assert_eq!(
        listing(dir.path()),
        [
            ".locked.dtr-lock",
            "imported.toml",
            "resumed.checkpoint",
            "room.json",
            "room.toml"
        ]
    );
}

#[test]
fn output_prefix_rules() {
    let dir = workdir();
    let o = dtr(
        &["render", "room.toml", "-o", "out.npy", "--spp", "1", "-q"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("out.npy").is_file() && dir.path().join("out.json").is_file());
    assert!(!dir.path().join("out.npy.npy").exists());
    // the JSON's name names the set too (before: run.json.npy and run.json.json)
    let o = dtr(
        &["render", "room.toml", "-o", "run.json", "--spp", "1", "-q"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(dir.path().join("run.npy").is_file() && dir.path().join("run.json").is_file());
    assert!(!dir.path().join("run.json.json").exists());
    let o = dtr(
        &["render", "room.toml", "-o", "folder/", "--spp", "1", "-q"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(listing(&dir.path().join("folder")), ["room.json", "room.npy"]);
}

#[test]
fn a_bad_output_location_fails_before_rendering() {
    let dir = workdir();
    std::fs::write(dir.path().join("plain_file"), b"x").unwrap();
    // a huge render: only a check before rendering can answer at once
    let o = dtr(
        &["render", "room.toml", "-o", "plain_file/x", "--spp", "100000000", "-q"],
        dir.path(),
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("cannot create the output folder"), "{}", stderr(&o));
    std::fs::create_dir(dir.path().join("y.json")).unwrap();
    let o = dtr(
        &["render", "room.toml", "-o", "y", "--spp", "100000000", "-q"],
        dir.path(),
    );
    assert!(!o.status.success());
    assert!(stderr(&o).contains("is an existing folder"), "{}", stderr(&o));
    assert!(!dir.path().join("y.npy").exists(), "half a set was written");
}

#[test]
fn a_second_render_to_a_locked_prefix_is_refused() {
    let dir = workdir();
    let lock = std::fs::OpenOptions::new()
        .create(true)
        .truncate(false)
        .write(true)
        .open(dir.path().join(".busy.dtr-lock"))
        .unwrap();
    lock.lock().unwrap();
    let o = dtr(&["render", "room.toml", "-o", "busy", "--spp", "1", "-q"], dir.path());
    assert!(!o.status.success());
    assert!(stderr(&o).contains("another dtr render is writing"), "{}", stderr(&o));
    assert!(!dir.path().join("busy.npy").exists());
    drop(lock);
    let o = dtr(&["render", "room.toml", "-o", "busy", "--spp", "1", "-q"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(listing(dir.path()), ["busy.json", "busy.npy", "room.json", "room.toml"]);
}

/// Starts a render in `dir` of the Cornell box at 32 × 32 with `args` added, for the signal
/// tests.
#[cfg(unix)]
fn spawn_cornell(dir: &Path, args: &[&str]) -> std::process::Child {
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_box.toml");
    let mut all = vec!["render", scene.to_str().unwrap(), "-q"];
    all.extend(["--set", "camera.resolution.0=32", "--set", "camera.resolution.1=32"]);
    all.extend(args);
    spawn(&all, dir)
}

/// Starts a render in `dir` to `out/big` whose set takes a while to write (a 32 × 32 × 3000
/// Cornell film, with its EXR), for the signal tests.
#[cfg(unix)]
fn spawn_big_render(dir: &Path) -> std::process::Child {
    spawn_cornell(
        dir,
        &[
            "--spp",
            "1",
            "--threads",
            "1",
            "--set",
            "film.bins=3000",
            "--set",
            "film.bin_width_opl=0.001",
            "--exr",
            "-o",
            "out/big",
        ],
    )
}

/// A symbolic link where a render keeps its lock file is refused, and what it leads to is left
/// alone: the lock was opened through it (creating the file a dangling link named, anywhere
/// the link pointed).
#[cfg(unix)]
#[test]
fn a_link_in_place_of_the_lock_file_is_refused() {
    let dir = workdir();
    let target = dir.path().join("elsewhere.txt");
    std::os::unix::fs::symlink(&target, dir.path().join(".busy.dtr-lock")).unwrap();
    let o = dtr(&["render", "room.toml", "-o", "busy", "--spp", "1", "-q"], dir.path());
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains(".busy.dtr-lock is a symbolic link where dtr keeps the lock"),
        "{}",
        stderr(&o)
    );
    assert!(!target.exists(), "the lock was created through the link");
    assert!(!dir.path().join("busy.npy").exists());
}

/// SIGTERM, and SIGHUP (the terminal closed; before, it killed the render and left its lock
/// file and staging folder), end a render with 128 + the signal and nothing left behind.
#[cfg(unix)]
#[test]
fn sigterm_and_sighup_leave_no_files_behind() {
    for signal in [libc::SIGTERM, libc::SIGHUP] {
        let dir = workdir();
        let mut child = spawn(
            &[
                "render",
                "room.toml",
                "-o",
                "out/run",
                "--spp",
                "1000000",
                "-q",
                "--threads",
                "1",
            ],
            dir.path(),
        );
        // the lock file shows that the render has started
        let lock = dir.path().join("out/.run.dtr-lock");
        let t0 = std::time::Instant::now();
        while !lock.exists() && t0.elapsed().as_secs() < 30 {
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        assert!(lock.exists(), "the render never started");
        std::thread::sleep(std::time::Duration::from_millis(200));
        unsafe { libc::kill(child.id() as i32, signal) };
        let status = child.wait().unwrap();
        assert_eq!(status.code(), Some(128 + signal), "signal {signal}: {status:?}");
        assert!(
            listing(&dir.path().join("out")).is_empty(),
            "signal {signal}: {:?}",
            listing(&dir.path().join("out"))
        );
    }
}

#[test]
fn a_second_render_to_a_prefix_removes_what_the_first_left_and_it_does_not_write() {
    let dir = workdir();
    let ok = |args: &[&str]| {
        let o = dtr(args, dir.path());
        assert!(o.status.success(), "{args:?}: {}", stderr(&o));
    };
    ok(&[
        "render",
        "room.toml",
        "-o",
        "x",
        "--spp",
        "1",
        "-q",
        "--diff",
        "room_z,room_rot_y",
        "--exr",
    ]);
    assert_eq!(
        listing(dir.path()),
        [
            "room.json",
            "room.toml",
            "x.d_room_rot_y.npy",
            "x.d_room_z.npy",
            "x.exr",
            "x.json",
            "x.npy"
        ]
    );
    let files = |name: &str| -> Vec<String> {
        let j: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.path().join(name)).unwrap()).unwrap();
        let mut v: Vec<String> = j["files"]
            .as_array()
            .unwrap()
            .iter()
            .map(|f| f.as_str().unwrap().to_string())
            .collect();
        v.sort();
        v
    };
    assert_eq!(
        files("x.json"),
        ["x.d_room_rot_y.npy", "x.d_room_z.npy", "x.exr", "x.json", "x.npy"]
    );
    // a file that is not the set's, and one the old JSON names though it lies elsewhere or is
    // an input, are never removed
    std::fs::write(dir.path().join("x.notes.txt"), "mine").unwrap();
    let mut j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("x.json")).unwrap()).unwrap();
    j["files"]
        .as_array_mut()
        .unwrap()
        .extend(["../x.npy".into(), "room.toml".into()].map(serde_json::Value::String));
    std::fs::write(dir.path().join("x.json"), j.to_string()).unwrap();
    ok(&["render", "room.toml", "-o", "x", "--spp", "1", "-q", "--diff", "room_z"]);
    assert_eq!(
        listing(dir.path()),
        [
            "room.json",
            "room.toml",
            "x.d_room_z.npy",
            "x.json",
            "x.notes.txt",
            "x.npy"
        ]
    );
    assert_eq!(files("x.json"), ["x.d_room_z.npy", "x.json", "x.npy"]);
    ok(&["render", "room.toml", "-o", "x", "--spp", "1", "-q"]);
    assert_eq!(
        listing(dir.path()),
        ["room.json", "room.toml", "x.json", "x.notes.txt", "x.npy"]
    );
}

/// The old JSON's `"files"` is a file anyone can edit: names it lists that dtr never writes
/// for the prefix (`p.toml`, `p.victim.npy`) are not removed as stale. Before the cleanup
/// checked the names' form, both were deleted.
#[test]
fn stale_cleanup_removes_only_names_dtr_writes() {
    let dir = workdir();
    let render = || {
        let o = dtr(&["render", "room.toml", "-o", "od/p", "--spp", "1", "-q"], dir.path());
        assert!(o.status.success(), "{}", stderr(&o));
    };
    render();
    let json = dir.path().join("od/p.json");
    let mut j: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    j["files"]
        .as_array_mut()
        .unwrap()
        .extend(["p.toml".into(), "p.victim.npy".into()].map(serde_json::Value::String));
    std::fs::write(&json, j.to_string()).unwrap();
    std::fs::write(dir.path().join("od/p.toml"), "not an output").unwrap();
    std::fs::write(dir.path().join("od/p.victim.npy"), "not an output either").unwrap();
    render();
    assert_eq!(
        listing(&dir.path().join("od")),
        ["p.json", "p.npy", "p.toml", "p.victim.npy"]
    );
}

/// SIGINT while the set is written (after the render: the writes into the staging folder and
/// the moves into place) ends with 130 and leaves nothing, or, when it comes after the set is
/// in place, with 0 and the whole set; never anything between. Each try waits for the staging
/// folder to appear, then interrupts at a later moment of the writes. Before, the signal
/// thread removed the staging folder while the main thread went on writing: some runs exited
/// 3 ("cannot move big.npy into place"), others left `.big.dtr-staging-*/` behind.
#[cfg(unix)]
#[test]
fn a_signal_while_the_set_is_written_leaves_nothing_or_the_whole_set() {
    let mut outcomes = Vec::new();
    for k in 0..8u64 {
        let dir = tempfile::tempdir().unwrap();
        let mut child = spawn_big_render(dir.path());
        let out = dir.path().join("out");
        let staging = || {
            std::fs::read_dir(&out)
                .map(|d| {
                    d.flatten()
                        .any(|e| e.file_name().to_string_lossy().starts_with(".big.dtr-staging-"))
                })
                .unwrap_or(false)
        };
        let t0 = std::time::Instant::now();
        while !staging() && child.try_wait().unwrap().is_none() && t0.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_micros(500));
        }
        std::thread::sleep(std::time::Duration::from_millis(70 * k));
        unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
        let o = child.wait_with_output().unwrap();
        let left = listing(&out);
        match o.status.code() {
            Some(130) => assert!(left.is_empty(), "try {k}: exit 130 left {left:?}"),
            Some(0) => assert_eq!(left, ["big.exr", "big.json", "big.npy"], "try {k}"),
            other => panic!("try {k}: exit {other:?}, left {left:?}: {}", stderr(&o)),
        }
        outcomes.push(o.status.code().unwrap());
    }
    assert!(outcomes.contains(&130), "no try was interrupted: {outcomes:?}");
}

/// A render interrupted while it traces ends with 130 and leaves nothing, never with an
/// abort: 200 runs, each sent SIGINT a few milliseconds after its lock file appears, while its
/// threads trace (and hold Embree's mutexes). The signal thread ends the process with `_exit`
/// (`cli::exit_from_signal`); `std::process::exit` ran the C library's exit handlers and
/// Embree's static destructors under the rendering threads, which aborted an optimisation
/// that way (exit 134) in CI rehearsal 74 (`cli_optimize::an_interrupted_optimisation_never_aborts`).
#[cfg(unix)]
#[test]
fn a_render_interrupted_while_it_traces_never_aborts() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out");
    for run in 0..200u64 {
        let child = spawn_cornell(dir.path(), &["--spp", "4096", "--threads", "2", "-o", "out/r"]);
        let t0 = std::time::Instant::now();
        while !out.join(".r.dtr-lock").exists() && t0.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
        std::thread::sleep(std::time::Duration::from_millis(run % 7));
        unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
        let o = child.wait_with_output().unwrap();
        assert_eq!(o.status.code(), Some(130), "run {run}: {}", stderr(&o));
        assert!(listing(&out).is_empty(), "run {run}: {:?}", listing(&out));
    }
}

/// A render removes the staging folders and checkpoint temporaries that an earlier, killed
/// render to the same prefix left (under the prefix's lock), and nothing else. Before, they
/// stayed for good.
#[test]
fn a_render_removes_the_staging_folders_a_killed_render_left() {
    let dir = workdir();
    let out = dir.path().join("out");
    std::fs::create_dir_all(out.join(".x.dtr-staging-Ab3dE9")).unwrap();
    std::fs::write(out.join(".x.dtr-staging-Ab3dE9/npy"), "half").unwrap();
    // another prefix's, and names that are not a staging folder's
    std::fs::create_dir_all(out.join(".y.dtr-staging-Ab3dE9")).unwrap();
    std::fs::create_dir_all(out.join(".x.dtr-staging-mine")).unwrap();
    std::fs::write(out.join(".x.dtr-staging-Zz9zz9"), "a file").unwrap();
    // the temporary file of a checkpoint being written (kept for good before 2026-11-30),
    // another prefix's, and a folder of that form
    std::fs::write(out.join(".x.checkpoint.Qw3rT1.tmp"), "half a checkpoint").unwrap();
    std::fs::write(out.join(".y.checkpoint.Qw3rT1.tmp"), "half a checkpoint").unwrap();
    std::fs::create_dir_all(out.join(".x.checkpoint.Dir000.tmp")).unwrap();
    let o = dtr(&["render", "room.toml", "-o", "out/x", "--spp", "1", "-q"], dir.path());
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        listing(&out),
        [
            ".x.checkpoint.Dir000.tmp",
            ".x.dtr-staging-Zz9zz9",
            ".x.dtr-staging-mine",
            ".y.checkpoint.Qw3rT1.tmp",
            ".y.dtr-staging-Ab3dE9",
            "x.json",
            "x.npy"
        ]
    );
}

/// SIGINT while the npy is written, before the EXR and the JSON: always 130 and nothing
/// left. Before 2026-11-30 the main thread, releasing the write lock after the npy and
/// taking it again for the EXR, often won it against the waiting signal thread, went on to
/// write the whole set and exited 0 (3 of 9 tries of an NLOS capture, 2 of 5 merges).
#[cfg(unix)]
#[test]
fn a_signal_during_the_first_file_stops_the_rest() {
    for k in 0..5 {
        let dir = tempfile::tempdir().unwrap();
        let mut child = spawn_big_render(dir.path());
        let out = dir.path().join("out");
        // the npy being written into the staging folder
        let npy = || {
            std::fs::read_dir(&out).ok().is_some_and(|d| {
                d.flatten().any(|e| {
                    e.file_name().to_string_lossy().starts_with(".big.dtr-staging-")
                        && std::fs::read_dir(e.path())
                            .map(|s| s.flatten().any(|f| f.file_name().to_string_lossy().contains("npy")))
                            .unwrap_or(false)
                })
            })
        };
        let t0 = std::time::Instant::now();
        while !npy() && child.try_wait().unwrap().is_none() && t0.elapsed().as_secs() < 60 {
            std::thread::sleep(std::time::Duration::from_micros(200));
        }
        unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
        let o = child.wait_with_output().unwrap();
        let left = listing(&out);
        assert_eq!(o.status.code(), Some(130), "try {k}: left {left:?}: {}", stderr(&o));
        assert!(left.is_empty(), "try {k}: {left:?}");
    }
}

/// An input named like the prefix's lock file, or inside a folder named like its staging
/// folder, is refused and kept. Before 2026-11-30 the first was deleted when the render
/// ended (or was refused), the second with its folder as a killed render's leftovers.
#[test]
fn an_input_in_a_name_dtr_reserves_is_refused_and_kept() {
    let dir = workdir();
    let room = std::fs::read_to_string(dir.path().join("room.toml")).unwrap();
    for (file, folder) in [(".p.dtr-lock", ""), ("mesh.obj", ".p.dtr-staging-ABC123/")] {
        let d = dir.path().join("m").join(folder);
        std::fs::create_dir_all(&d).unwrap();
        std::fs::write(d.join(file), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
        let mesh = format!("m/{folder}{file}");
        let scene = format!(
            "{room}\n[[shape]]\nname = \"extra\"\ntype = \"obj\"\nfile = \"{mesh}\"\nmaterial = \"{}\"\n",
            first_material(&room)
        );
        std::fs::write(dir.path().join("s.toml"), scene).unwrap();
        let o = dtr(&["render", "s.toml", "-o", "m/p", "--spp", "1", "-q"], dir.path());
        assert_eq!(o.status.code(), Some(2), "{mesh}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("lies where dtr keeps the lock"),
            "{mesh}: {}",
            stderr(&o)
        );
        assert!(dir.path().join(&mesh).is_file(), "{mesh} was removed");
    }
}

fn first_material(scene: &str) -> String {
    let at = scene.find("[[material]]").expect("a material");
    let name = scene[at..]
        .lines()
        .find(|l| l.trim_start().starts_with("name"))
        .unwrap();
    name.split('"').nth(1).unwrap().to_string()
}

/// An output folder that the file system refuses (read-only, root included) is exit 3,
/// whichever output is refused first: the lock file of `-o ro/out`, the folder of
/// `-o ro/new/x`. Before, the lock file's refusal was exit 2, as if the input were bad.
#[cfg(unix)]
#[test]
fn a_read_only_output_folder_is_an_output_error() {
    let Some(ro) = crate::common::ReadOnlyFolder::new() else {
        return;
    };
    let dir = workdir();
    for out in ["out", "new/x"] {
        let out = ro.path.join(out);
        let o = dtr(
            &["render", "room.toml", "-o", out.to_str().unwrap(), "--spp", "1", "-q"],
            dir.path(),
        );
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(3), "-o {}: {e}", out.display());
        assert!(e.contains(ro.path.to_str().unwrap()), "{e}");
    }
    assert!(listing(&ro.path).is_empty());
}

/// A file name the file system cannot take (more than 255 bytes) is refused before anything
/// is made, naming -o, the name and its length (exit 2): a parameter's name of 246 characters
/// in `PREFIX.d_NAME.npy`, or a long -o prefix in the lock file the render keeps beside it.
/// Before, the render failed taking its locks, with exit 3 and three nested causes ("an output
/// of out/x is also named as one of x.d_aaa…'s: cannot lock the output prefix …: cannot write
/// out/.x.d_aaa….dtr-lock: File name too long"). The longest prefix whose files all fit still
/// renders.
#[test]
fn a_file_name_longer_than_the_file_system_takes_is_refused_before_anything_is_made() {
    let dir = workdir();
    let long = "a".repeat(246);
    let text = std::fs::read_to_string(dir.path().join("room.toml"))
        .unwrap()
        .replace("name = \"albedo\"", &format!("name = \"{long}\""));
    std::fs::write(dir.path().join("long.toml"), text).unwrap();
    let before = listing(dir.path());
    let o = dtr(
        &["render", "long.toml", "--diff", &long, "-o", "out", "--spp", "1", "-q"],
        dir.path(),
    );
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.starts_with("error: -o out: the render would make a file named \"out.d_aaa")
            && e.contains(".npy\" (256 bytes)")
            && e.contains("at most 255 bytes")
            && e.contains("shorter parameter names"),
        "{e}"
    );
    assert!(!e.contains("cannot lock") && !e.contains("os error"), "{e}");
    assert_eq!(listing(dir.path()), before);
    let o = dtr(
        &["render", "room.toml", "-o", &"p".repeat(233), "--spp", "1", "-q"],
        dir.path(),
    );
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains(".checkpoint.XXXXXX.tmp\" (256 bytes)") && e.contains("use a shorter -o prefix"),
        "{e}"
    );
    assert_eq!(listing(dir.path()), before);
    let o = dtr(
        &["render", "room.toml", "-o", &"p".repeat(232), "--spp", "1", "-q"],
        dir.path(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
}

/// A boundary render of any sample count reserves nothing per sample up front, and stops on
/// SIGINT. At `--spp-boundary 4294967295` the primary stage's list of every chunk (16 bytes
/// per 2048 samples) and the pilot's tallies (two 512-cell tallies per 4096 samples, kept to
/// the end) aborted the process ("memory allocation of 8589934592 bytes failed", exit 134),
/// and at 2^28 grew past 6 GB while Ctrl-C did nothing (found by an independent sweep of the
/// Python API, which defaults spp_boundary to spp).
#[cfg(unix)]
#[test]
fn a_boundary_render_of_any_length_runs_in_bounded_memory_and_stops_on_sigint() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/pose_plate.toml");
    let mut child = spawn(
        &[
            "render",
            scene.to_str().unwrap(),
            "--diff",
            "plate_x",
            "--spp",
            "1",
            "--spp-boundary",
            "4294967295",
            "--threads",
            "1",
            "-q",
            "-o",
            "out",
        ],
        tmp.path(),
    );
    let rss_kib = |pid: u32| -> u64 {
        let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
        status
            .lines()
            .find_map(|l| l.strip_prefix("VmRSS:"))
            .and_then(|v| v.split_whitespace().next().and_then(|n| n.parse().ok()))
            .unwrap_or(0)
    };
    let mut most = 0;
    for _ in 0..30 {
        std::thread::sleep(std::time::Duration::from_millis(100));
        assert!(
            child.try_wait().unwrap().is_none(),
            "the render ended: {:?}",
            child.wait_with_output()
        );
        most = most.max(rss_kib(child.id()));
    }
    assert!(most < 512 * 1024, "{most} KiB resident after 3 s");
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let t0 = std::time::Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(t0.elapsed().as_secs() < 20, "still running 20 s after SIGINT");
        std::thread::sleep(std::time::Duration::from_millis(50));
    };
    assert_eq!(status.code(), Some(130), "{status:?}");
}

/// Under a file-size limit (`ulimit -f`) with SIGXFSZ at its default, a write past the limit
/// is an output error like a full disk's: exit 3 naming the file ("File too large"), the
/// earlier set kept byte for byte, nothing left beside it (`cli::ignore_file_size_signal`).
/// Before (an independent sweep, 2026-12-02), the kernel killed the render (exit 153) and its
/// staging folder and lock files stayed, one of them (`.a.steady.dtr-lock`) for good.
#[cfg(unix)]
#[test]
fn a_file_size_limit_is_an_output_error_not_a_kill() {
    use std::os::unix::process::CommandExt;
    let dir = workdir();
    let d = dir.path();
    let args = ["render", "room.toml", "--spp", "1", "--threads", "1", "-q", "-o", "a"];
    let o = dtr(&args, d);
    assert!(o.status.success(), "{}", stderr(&o));
    let before = listing(d);
    let npy = std::fs::read(d.join("a.npy")).unwrap();
    let mut limited = Command::new(env!("CARGO_BIN_EXE_dtr"));
    limited.current_dir(d).args(args).args(["--preview", "--seed", "2"]);
    // SAFETY: only async-signal-safe calls between fork and exec
    unsafe {
        limited.pre_exec(|| {
            libc::signal(libc::SIGXFSZ, libc::SIG_DFL);
            let limit = libc::rlimit {
                rlim_cur: 1024,
                rlim_max: libc::RLIM_INFINITY,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let o = limited.output().unwrap();
    assert_eq!(o.status.code(), Some(3), "{:?}: {}", o.status, stderr(&o));
    assert!(stderr(&o).contains("File too large"), "{}", stderr(&o));
    assert_eq!(listing(d), before, "{}", stderr(&o));
    assert_eq!(std::fs::read(d.join("a.npy")).unwrap(), npy);
}

/// The lock a killed render with `--preview` left on the prefix its steady image shares
/// (`.a.steady.dtr-lock`) goes with the next render to the prefix, with or without
/// `--preview`; one that a running render holds stays. Before (an independent sweep,
/// 2026-12-02), a render without `--preview` never removed it.
#[test]
fn a_killed_renders_shared_lock_goes_with_the_next_render() {
    let dir = workdir();
    let d = dir.path();
    std::fs::write(d.join(".a.steady.dtr-lock"), b"").unwrap();
    let held = std::fs::File::create(d.join(".a.other.dtr-lock")).unwrap();
    held.try_lock().unwrap();
    let o = dtr(
        &["render", "room.toml", "--spp", "1", "--threads", "1", "-q", "-o", "a"],
        d,
    );
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        listing(d),
        [".a.other.dtr-lock", "a.json", "a.npy", "room.json", "room.toml"],
        "{}",
        stderr(&o)
    );
}
