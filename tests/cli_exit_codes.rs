//! `dtr`'s exit status tells bad input (2) from an output that could not be written (3) and
//! from success (0); an interrupted render exits with 128 + the signal (tests/cli_output_safety.rs,
//! tests/cli_checkpoint.rs).

use crate::common;
use std::path::Path;

fn code(args: &[&str], cwd: &Path) -> (Option<i32>, String) {
    let o = common::dtr(args, cwd);
    (o.status.code(), String::from_utf8_lossy(&o.stderr).into_owned())
}

#[test]
fn exit_status_names_what_failed() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = common::scene_path("diff_room.toml");
    let s = scene.to_str().unwrap();

    assert_eq!(code(&["render", s, "--spp", "1", "-o", "ok"], d).0, Some(0));

    // bad input: usage, a missing or invalid scene, an unknown parameter, an option out of range
    for args in [
        vec!["render", s, "--no-such-flag"],
        vec!["render", "missing.toml", "-o", "x"],
        vec!["render", s, "--set", "nope=1", "-o", "x"],
        vec!["render", s, "--threads", "0", "-o", "x"],
        vec!["render", s, "--diff", "nope", "-o", "x"],
    ] {
        let (c, err) = code(&args, d);
        assert_eq!(c, Some(2), "{args:?}: {err}");
    }
    // the unknown parameter of a derivative render is named as the option that asked for it
    let (_, err) = code(&["render", s, "--diff", "nope", "-o", "x"], d);
    assert!(
        err.contains("--diff: no parameter named \"nope\" (parameters: "),
        "{err}"
    );
    let bad = d.join("bad.toml");
    std::fs::write(
        &bad,
        std::fs::read_to_string(&scene)
            .unwrap()
            .replace("value = 0.6", "value = -3.0"),
    )
    .unwrap();
    let (c, err) = code(&["render", bad.to_str().unwrap(), "-o", "x"], d);
    assert_eq!(c, Some(2), "{err}");

    // an output the file system refuses: its folder would have to be made inside a file
    std::fs::write(d.join("file"), b"not a folder").unwrap();
    let (c, err) = code(&["render", s, "--spp", "1", "-o", "file/sub/x"], d);
    assert_eq!(c, Some(3), "{err}");
    assert!(err.contains("cannot create the output folder"), "{err}");
}

/// `dtr completions SHELL` prints a script that completes the subcommands and their options.
#[test]
fn completions_cover_the_subcommands_and_options() {
    let dir = tempfile::tempdir().unwrap();
    for shell in ["bash", "zsh", "fish"] {
        let o = common::dtr(&["completions", shell], dir.path());
        assert!(o.status.success());
        let script = String::from_utf8_lossy(&o.stdout);
        for word in ["render", "merge", "optimize", "spp", "preview", "normalise"] {
            assert!(script.contains(word), "{shell} completions lack {word}");
        }
    }
    assert_eq!(common::dtr(&["completions", "nosh"], dir.path()).status.code(), Some(2));
}

/// `dtr info … | head`: a reader that closes the pipe early is not an error. `info` printed
/// with `print!`, which panics on a closed pipe ("failed printing to stdout: Broken pipe",
/// with a backtrace); it now writes as `import` and `completions` do and exits 0.
#[test]
fn a_reader_that_stops_early_is_not_an_error() {
    let dir = tempfile::tempdir().unwrap();
    // 2000 shapes: far more text than a pipe's buffer holds, so the writes meet the closed end
    let mut text = String::from(
        "[camera]\nposition = [0.0, 5.0, 30.0]\nlook_at = [0.0, 0.0, 0.0]\nresolution = [8, 8]\n\
         [film]\nstart_opl = 0\nbin_width_opl = 1\nbins = 80\n\
         [[material]]\nname = \"a\"\ntype = \"diffuse\"\nalbedo = 0.5\n",
    );
    for k in 0..2000 {
        text += &format!(
            "[[shape]]\nname = \"cube{k}\"\ntype = \"cube\"\nmaterial = \"a\"\ntranslate = [{}, 0.3, {}]\nscale = 0.1\n",
            (k % 50) as f64 * 0.5,
            (k / 50) as f64 * 0.5
        );
    }
    text += "[[emitter]]\nname = \"l\"\ntype = \"point\"\nposition = [0.0, 5.0, 30.0]\nintensity = 100.0\n";
    let scene = dir.path().join("many.toml");
    std::fs::write(&scene, text).unwrap();
    for json in [false, true] {
        let mut cmd = std::process::Command::new(env!("CARGO_BIN_EXE_dtr"));
        cmd.arg("info").arg(&scene);
        if json {
            cmd.arg("--json");
        }
        let mut child = cmd
            .stdout(std::process::Stdio::piped())
            .stderr(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take()); // the reader goes away before reading anything
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!err.contains("panicked"), "json {json}: {err}");
        assert_eq!(out.status.code(), Some(0), "json {json}: {err}");
    }
}

/// Standard output the file system refuses (a full disk) is an output that could not be
/// written, exit 3, for every command that prints: before, `dtr info > /dev/full` exited 2, as
/// if its input were bad.
#[cfg(target_os = "linux")]
#[test]
fn a_full_standard_output_is_an_output_error() {
    let scene = common::scene_path("diff_room.toml");
    let s = scene.to_str().unwrap();
    for args in [
        vec!["info", s],
        vec!["import", common::scene_path("cornell_box.xml").to_str().unwrap()],
        vec!["completions", "bash"],
    ] {
        let o = std::process::Command::new(env!("CARGO_BIN_EXE_dtr"))
            .args(&args)
            .stdout(std::fs::OpenOptions::new().write(true).open("/dev/full").unwrap())
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{args:?}: {err}");
        assert!(
            err.contains("standard output") && err.contains("No space left"),
            "{args:?}: {err}"
        );
    }
}
