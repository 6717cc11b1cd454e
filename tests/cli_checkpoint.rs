//! `dtr render --checkpoint SECONDS` and `--resume` (src/checkpoint.rs): a render killed
//! part-way (SIGKILL: from its last periodic checkpoint; SIGTERM: from the checkpoint the
//! signal writes) and resumed, with another thread count, writes the same bytes as the
//! render that was never interrupted: path tracer, BDPT, and a derivative render whose
//! boundary stage runs after the resume.

use crate::common;
use common::dtr;
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

const CORNELL: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell_box.toml");
const SLIDE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/silhouette_slide.toml");
const NLOS: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/nlos_occluder.toml");

fn spawn(args: &[&str], cwd: &Path) -> Child {
    Command::new(env!("CARGO_BIN_EXE_dtr"))
        .current_dir(cwd)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap()
}

/// (units done, units) of the checkpoint at `path`, if one is there.
fn progress(path: &Path) -> Option<(usize, usize)> {
    let bytes = std::fs::read(path).ok()?;
    let n = u64::from_le_bytes(bytes.get(8..16)?.try_into().ok()?) as usize;
    let header: serde_json::Value = serde_json::from_slice(bytes.get(16..16 + n)?).ok()?;
    let done = header["done"]
        .as_array()?
        .iter()
        .filter(|d| d.as_bool() == Some(true))
        .count();
    Some((done, header["units"].as_u64()? as usize))
}

/// Starts the render and sends `signal` once a checkpoint holds some but not all units.
fn interrupt(args: &[&str], cwd: &Path, checkpoint: &Path, signal: i32) -> std::process::Output {
    let child = spawn(args, cwd);
    let t0 = Instant::now();
    loop {
        if let Some((done, units)) = progress(checkpoint) {
            assert!(
                done < units,
                "the render finished before it could be interrupted; make it longer"
            );
            if done > 0 {
                break;
            }
        }
        assert!(t0.elapsed() < Duration::from_secs(120), "no checkpoint appeared");
        std::thread::sleep(Duration::from_millis(20));
    }
    // SAFETY: kill(2) on our own child's pid.
    unsafe { libc::kill(child.id() as i32, signal) };
    child.wait_with_output().unwrap()
}

fn resume_equals_uninterrupted(scene: &str, extra: &[&str], files: &[&str], signal: i32) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let mut base = vec!["render", scene, "-q"];
    base.extend(extra);
    fn joined<'a>(base: &[&'a str], more: &[&'a str]) -> Vec<&'a str> {
        base.iter().chain(more).copied().collect()
    }
    let with = |more: &[&'static str]| joined(&base, more);
    let o = dtr(&with(&["-o", "whole", "--threads", "2"]), dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let ck = dir.join("r.checkpoint");
    let o = interrupt(
        &with(&["-o", "r", "--threads", "2", "--checkpoint", "0.05"]),
        dir,
        &ck,
        signal,
    );
    assert!(!o.status.success());
    if signal == libc::SIGTERM {
        assert_eq!(
            o.status.code(),
            Some(128 + libc::SIGTERM),
            "{}",
            String::from_utf8_lossy(&o.stderr)
        );
    }
    let (done, units) = progress(&ck).expect("a checkpoint survives the interruption");
    assert!(done < units);
    assert!(!dir.join("r.npy").exists(), "no output of an interrupted render");
    // without -q: the resume notice is an info line (-q keeps warnings only)
    let resume: Vec<&str> = with(&["-o", "r", "--threads", "1", "--resume"])
        .into_iter()
        .filter(|&a| a != "-q")
        .collect();
    let o = dtr(&resume, dir);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stderr).contains(&format!("resuming with {done} of {units}")));
    for f in files {
        let (a, b) = (dir.join(format!("whole.{f}")), dir.join(format!("r.{f}")));
        assert!(
            std::fs::read(&a).unwrap() == std::fs::read(&b).unwrap(),
            "{f} differs after the resume"
        );
    }
    let json = |p: &str| -> serde_json::Value { serde_json::from_slice(&std::fs::read(dir.join(p)).unwrap()).unwrap() };
    assert_eq!(json("whole.json")["energy"], json("r.json")["energy"]);
    assert!(!ck.exists(), "the checkpoint is removed once the render is whole");
}

#[test]
fn a_killed_path_tracer_render_resumes_to_the_same_bytes() {
    resume_equals_uninterrupted(CORNELL, &["--spp", "1024"], &["npy"], libc::SIGKILL);
}

#[test]
fn a_terminated_render_saves_a_checkpoint_and_resumes() {
    resume_equals_uninterrupted(CORNELL, &["--spp", "1024"], &["npy"], libc::SIGTERM);
}

#[test]
fn a_killed_bdpt_render_resumes_to_the_same_bytes() {
    resume_equals_uninterrupted(
        CORNELL,
        &["--spp", "160", "--integrator", "bdpt"],
        &["npy"],
        libc::SIGKILL,
    );
}

/// BDPT on a confocal capture: its units are (tile, sample block) over the film of sensor
/// points, as any film's.
#[test]
fn a_killed_bdpt_capture_resumes_to_the_same_bytes() {
    resume_equals_uninterrupted(
        NLOS,
        &["--spp", "65536", "--integrator", "bdpt"],
        &["npy"],
        libc::SIGKILL,
    );
}

#[test]
fn a_killed_derivative_render_resumes_to_the_same_bytes() {
    // interrupted in the interior pass; the boundary stage runs after the resume
    resume_equals_uninterrupted(
        SLIDE,
        &["--spp", "1024", "--spp-boundary", "4", "--diff", "cube_x"],
        &["npy", "d_cube_x.npy"],
        libc::SIGKILL,
    );
}

#[test]
fn resume_refuses_what_is_not_this_render() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    let o = dtr(&["render", CORNELL, "--spp", "2", "-o", "r", "--resume"], dir);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("there is no checkpoint"));
    let ck = dir.join("r.checkpoint");
    let o = interrupt(
        &[
            "render",
            CORNELL,
            "--spp",
            "1024",
            "-q",
            "-o",
            "r",
            "--checkpoint",
            "0.05",
        ],
        dir,
        &ck,
        libc::SIGKILL,
    );
    assert!(!o.status.success());
    for (args, field) in [
        (vec!["--spp", "512"], "spp"),
        (vec!["--spp", "1024", "--seed", "5"], "seed"),
        (vec!["--spp", "1024", "--integrator", "bdpt"], "integrator"),
        (vec!["--spp", "1024", "--shard", "1/2"], "shard"),
        // the window --auto-window chooses: before 2026-11-30 this resumed with exit 0 into
        // a film of both windows' tiles (17 of 64 of the checkpoint's)
        (vec!["--spp", "1024", "--auto-window"], "time_axis"),
    ] {
        let mut v = vec!["render", CORNELL, "-o", "r", "--resume"];
        v.extend(args);
        let o = dtr(&v, dir);
        assert!(!o.status.success());
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains("checkpoint of another render") && e.contains(field), "{e}");
    }
    // a checkpoint whose units are cut another way (an earlier dtr's: one unit per path
    // tracer tile, or BDPT chunks) is refused by that field, never resumed into the wrong units
    // a checkpointed render started without --resume leaves the checkpoint as it is (it
    // replaced it, warning too late for Ctrl-C, before 2026-11-30)
    let bytes = std::fs::read(&ck).unwrap();
    let o = dtr(
        &["render", CORNELL, "--spp", "1024", "-o", "r", "--checkpoint", "100"],
        dir,
    );
    let e = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("holds an earlier render's checkpoint: --resume continues it"),
        "{e}"
    );
    assert_eq!(std::fs::read(&ck).unwrap(), bytes, "the checkpoint is untouched");
    let (from, to) = (&b"\"checkpoint_units\":3"[..], &b"\"checkpoint_units\":2"[..]);
    let at = bytes
        .windows(from.len())
        .position(|w| w == from)
        .expect("the identity names its units' cut");
    let mut older = bytes[..bytes.len() - 4].to_vec();
    older[at..at + from.len()].copy_from_slice(to);
    let crc = crc32fast::hash(&older);
    older.extend(crc.to_le_bytes());
    std::fs::write(&ck, &older).unwrap();
    let o = dtr(&["render", CORNELL, "--spp", "1024", "-o", "r", "--resume"], dir);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && e.contains("checkpoint_units was 2 there, is 3 now"),
        "{e}"
    );
    // a checkpoint damaged on disk (bytes of its bins flipped) is refused as bad input, by
    // name, never resumed (it resumed into a film of 1e28 before the checksum)
    let mut damaged = bytes.clone();
    let hlen = u64::from_le_bytes(bytes[8..16].try_into().unwrap()) as usize;
    damaged[16 + hlen + 100..16 + hlen + 200]
        .iter_mut()
        .for_each(|b| *b ^= 0x5a);
    std::fs::write(&ck, &damaged).unwrap();
    let o = dtr(&["render", CORNELL, "--spp", "1024", "-o", "r", "--resume"], dir);
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(
        o.status.code() == Some(2) && e.contains("r.checkpoint: not a usable dtr checkpoint: its checksum"),
        "{:?} {e}",
        o.status
    );
    std::fs::write(&ck, b"not a checkpoint").unwrap();
    let o = dtr(&["render", CORNELL, "--spp", "1024", "-o", "r", "--resume"], dir);
    assert!(String::from_utf8_lossy(&o.stderr).contains("not a usable dtr checkpoint"));
}

/// Options of a library render at 2 spp (and 2 boundary samples) on 2 threads that
/// checkpoints to `path` every `every` and resumes from `resume`.
fn checkpointed(
    path: &Path,
    every: Duration,
    resume: Option<difftransient::checkpoint::Saved>,
) -> difftransient::RenderOptions {
    difftransient::RenderOptions {
        spp: Some(2),
        spp_boundary: Some(2),
        seed: Some(1),
        threads: Some(2),
        checkpoint: Some(std::sync::Arc::new(difftransient::checkpoint::Checkpointing::new(
            path.to_path_buf(),
            every,
            serde_json::json!({}),
            resume,
        ))),
        ..Default::default()
    }
}

/// `scene` at 16×16 pixels.
fn small(scene: &str) -> difftransient::Scene {
    let mut s = common::load(scene);
    s.film.width = 16;
    s.film.height = 16;
    s
}

/// Where a render with checkpoints every hour writes one when it ends before the first is
/// due: only between the interior pass and a boundary stage still to run. A forward render
/// writes none (its outputs follow; it wrote the whole frame once more, and copied it, before
/// the fix), nor BDPT; a derivative render whose boundary stage follows writes the interior.
#[test]
fn a_render_writes_an_end_of_pass_checkpoint_only_before_a_boundary_stage() {
    use difftransient::scene::IntegratorKind;
    let tmp = tempfile::tempdir().unwrap();
    let hour = Duration::from_secs(3600);
    let cornell = small("cornell_box.toml");
    for (name, kind) in [("path", IntegratorKind::Path), ("bdpt", IntegratorKind::Bdpt)] {
        let path = tmp.path().join(format!("{name}.checkpoint"));
        let opts = difftransient::RenderOptions {
            integrator: Some(kind),
            ..checkpointed(&path, hour, None)
        };
        difftransient::render(&cornell, &opts).expect("render");
        assert!(
            !path.exists(),
            "{name}: a forward render wrote an end-of-pass checkpoint"
        );
    }
    let path = tmp.path().join("slide.checkpoint");
    let slide = small("silhouette_slide.toml");
    difftransient::render_diff(&slide, &["cube_x".to_string()], &checkpointed(&path, hour, None)).expect("render");
    let (_, saved) =
        difftransient::checkpoint::read(&path).expect("the interior's checkpoint, before the boundary stage");
    assert_eq!(saved.done_units(), saved.units, "every tile of the interior");
    assert!(
        saved.boundary.is_none(),
        "the boundary stage's end writes only a due checkpoint"
    );
}

/// A render stopped while its outputs were written resumes from the checkpoint written at
/// the end of its boundary stage (due at once here): the same bytes, without running the
/// boundary stage again (its record, timings included, is the saved one).
#[test]
fn a_render_resumed_after_its_boundary_stage_does_not_run_it_again() {
    let tmp = tempfile::tempdir().unwrap();
    let slide = small("silhouette_slide.toml");
    let params = ["cube_x".to_string()];
    let path = tmp.path().join("slide.checkpoint");
    let whole =
        difftransient::render_diff_parts(&slide, &params, &checkpointed(&path, Duration::ZERO, None)).expect("render");
    let (_, saved) = difftransient::checkpoint::read(&path).expect("the checkpoint of the boundary stage's end");
    let (_, _, stats) = saved.boundary.clone().expect("the boundary stage is saved");
    let again = tmp.path().join("again.checkpoint");
    let resumed = difftransient::render_diff_parts(
        &slide,
        &params,
        &checkpointed(&again, Duration::from_secs(3600), Some(saved)),
    )
    .expect("resumed render");
    let bits = |t: &[difftransient::Transient]| -> Vec<u32> {
        t.iter()
            .flat_map(|f| f.data.iter().chain(&f.steady).map(|v| v.to_bits()))
            .collect()
    };
    assert_eq!(
        bits(std::slice::from_ref(&whole.primal)),
        bits(std::slice::from_ref(&resumed.primal))
    );
    assert_eq!(bits(&whole.sum()), bits(&resumed.sum()));
    let b = resumed.stats.boundary.expect("the boundary record");
    assert_eq!(
        b.wall_seconds.to_bits(),
        stats.wall_seconds.to_bits(),
        "the boundary stage ran again"
    );
    assert!(!again.exists(), "nothing was due and nothing followed: no checkpoint");
}
