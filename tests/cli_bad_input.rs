//! Bad input gives a clear error, a non-zero exit, no panic and no output file.

use std::path::{Path, PathBuf};
use std::process::Command;

fn dtr() -> Command {
    Command::new(env!("CARGO_BIN_EXE_dtr"))
}

fn scenes() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// Runs `dtr render` on `scene` with extra args into a fresh folder; returns (stderr, folder).
fn render_fails(scene: &Path, extra: &[&str]) -> (String, tempfile::TempDir) {
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("out");
    let out = dtr()
        .arg("render")
        .arg(scene)
        .arg("-o")
        .arg(&prefix)
        .args(["--spp", "1", "--quiet"])
        .args(extra)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(!out.status.success(), "expected failure, got success; stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "panic: {stderr}");
    // warnings (e.g. BDPT's cost at many bounces) may come first; then the error
    let first = stderr.lines().find(|l| !l.starts_with("warning:")).unwrap_or("");
    assert!(first.starts_with("error:"), "unexpected stderr: {stderr}");
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert!(left.is_empty(), "files left behind: {left:?}");
    (stderr, dir)
}

/// Renders `scene` at 1 spp on one thread with `extra`, to the prefix `a` in a new folder,
/// which it returns; the render must succeed.
fn render_succeeds(scene: &Path, extra: &[&str]) -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let out = dtr()
        .arg("render")
        .arg(scene)
        .arg("-o")
        .arg(dir.path().join("a"))
        .args(["--spp", "1", "--threads", "1", "--quiet"])
        .args(extra)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{extra:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    dir
}

fn write(dir: &Path, name: &str, text: &str) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn cornell_text() -> String {
    std::fs::read_to_string(scenes().join("cornell_box.toml")).unwrap()
}

#[test]
fn missing_scene_file() {
    let (e, _d) = render_fails(Path::new("/nonexistent/scene.toml"), &[]);
    assert!(e.contains("/nonexistent/scene.toml"), "{e}");
}

#[test]
fn toml_syntax_error_names_file_and_line() {
    let d = tempfile::tempdir().unwrap();
    let p = write(
        d.path(),
        "broken.toml",
        &cornell_text().replacen("[camera]", "[camera", 1),
    );
    let (e, _o) = render_fails(&p, &[]);
    assert!(e.contains("broken.toml") && e.contains("line"), "{e}");
}

#[test]
fn wrong_type_names_the_field() {
    let d = tempfile::tempdir().unwrap();
    let text = cornell_text();
    let start = text.find("[film]").expect("cornell has [film]");
    let bins_at = start + text[start..].find("bins").expect("film.bins");
    let line_end = bins_at + text[bins_at..].find('\n').unwrap();
    let bad = format!("{}bins = \"many\"{}", &text[..bins_at], &text[line_end..]);
    let p = write(d.path(), "wrongtype.toml", &bad);
    let (e, _o) = render_fails(&p, &[]);
    assert!(e.contains("wrongtype.toml") && e.contains("bins"), "{e}");
}

#[test]
fn nan_vertex_in_obj_names_the_obj() {
    let d = tempfile::tempdir().unwrap();
    write(d.path(), "bad.obj", "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n");
    let scene = format!(
        "{}\n[[shape]]\nname = \"bad\"\ntype = \"obj\"\nfile = \"bad.obj\"\nmaterial = \"{}\"\n",
        cornell_text(),
        first_material_name()
    );
    let p = write(d.path(), "nanobj.toml", &scene);
    let (e, _o) = render_fails(&p, &[]);
    assert!(e.contains("bad.obj"), "{e}");
}

#[test]
fn nonpositive_spp_is_refused() {
    for spp in ["0", "-3"] {
        let d = tempfile::tempdir().unwrap();
        let out = dtr()
            .args(["render"])
            .arg(scenes().join("cornell_box.toml"))
            .arg("-o")
            .arg(d.path().join("x"))
            .args(["--spp", spp, "--quiet"])
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && e.contains("spp") && !e.contains("panicked"),
            "{e}"
        );
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0);
    }
    // and in the scene file
    let d = tempfile::tempdir().unwrap();
    let text = cornell_text();
    let bad = if text.contains("spp =") {
        let i = text.find("spp =").unwrap();
        let j = i + text[i..].find('\n').unwrap();
        format!("{}spp = 0{}", &text[..i], &text[j..])
    } else {
        text.replacen("[integrator]", "[integrator]\nspp = 0", 1)
    };
    let p = write(d.path(), "zerospp.toml", &bad);
    let dir = tempfile::tempdir().unwrap();
    let out = dtr()
        .arg("render")
        .arg(&p)
        .arg("-o")
        .arg(dir.path().join("x"))
        .arg("--quiet")
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && e.contains("zerospp.toml") && e.contains("spp"),
        "{e}"
    );
}

/// `--checkpoint` takes seconds in (0, 1e9]: 0, NaN and Inf were refused, but 1e20 and
/// 1e300 panicked converting to a `Duration` ("cannot convert float seconds to Duration").
#[test]
fn checkpoint_interval_out_of_range_is_refused() {
    for bad in ["0", "-1", "nan", "inf", "1e20", "1e300"] {
        let dir = tempfile::tempdir().unwrap();
        let out = dtr()
            .arg("render")
            .arg(scenes().join("confocal_plane.toml"))
            .arg("-o")
            .arg(dir.path().join("ck"))
            .args(["--threads", "1", "--spp", "1", "--quiet"])
            .arg(format!("--checkpoint={bad}"))
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "--checkpoint {bad}: {e}");
        assert!(e.contains("--checkpoint") && e.contains("at most 1e9"), "{bad}: {e}");
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0, "{bad}: files left");
    }
}

/// A pulse or gate width that is a subnormal 32-bit float is refused by the loader, naming
/// the file, the emitter or film and the field, once. Before, it passed the loader and the
/// renderer's threads (which flush subnormals to zero) failed with "temporal model:
/// emitter.pulse.sigma_opl: expected a finite number > 0, got 0" twice, without the file.
#[test]
fn subnormal_pulse_and_gate_widths_name_the_field_once() {
    let d = tempfile::tempdir().unwrap();
    let room = std::fs::read_to_string(scenes().join("diff_room.toml")).unwrap();
    let pulse = r#"pulse = { type = "gaussian", sigma_opl = 0.1 }"#;
    assert!(room.contains(pulse) && room.contains("gate = \"box\""));
    let cases = [
        (
            room.replace(pulse, r#"pulse = { type = "gaussian", sigma_opl = 1e-45 }"#),
            r#"emitter[0] "lamp": field 'pulse.sigma_opl'"#,
        ),
        (
            room.replace(pulse, r#"pulse = { type = "box", width_opl = 1e-45 }"#),
            r#"emitter[0] "lamp": field 'pulse.width_opl'"#,
        ),
        (
            room.replace("gate = \"box\"", r#"gate = { type = "gaussian", sigma_opl = 1e-45 }"#),
            "film: field 'gate.sigma_opl'",
        ),
    ];
    for (text, field) in cases {
        let p = write(d.path(), "tiny.toml", &text);
        let (e, _o) = render_fails(&p, &["--threads", "1"]);
        assert!(e.contains(&format!("tiny.toml: {field}")), "{e}");
        assert!(
            e.contains("smallest normal 32-bit float") && e.contains("got 1e-45"),
            "{e}"
        );
        assert_eq!(e.matches("1e-45").count(), 1, "said more than once: {e}");
    }
}

#[test]
fn unknown_set_name_lists_the_parameters() {
    let (e, _o) = render_fails(&scenes().join("occluder_shadow.toml"), &["--set", "no_such_param=1"]);
    assert!(e.contains("no_such_param"), "{e}");
}

#[test]
fn malformed_set_is_refused() {
    let (e, _o) = render_fails(&scenes().join("cornell_box.toml"), &["--set", "eta"]);
    assert!(e.contains("NAME=VALUE"), "{e}");
}

fn first_material_name() -> String {
    let t = cornell_text();
    let i = t.find("[[material]]").unwrap();
    let n = i + t[i..].find("name").unwrap();
    let q1 = n + t[n..].find('"').unwrap() + 1;
    let q2 = q1 + t[q1..].find('"').unwrap();
    t[q1..q2].to_string()
}

#[test]
fn strategies_need_bdpt_and_unknown_integrators_are_refused() {
    let cornell = scenes().join("cornell_box.toml");
    let (e, _d) = render_fails(&cornell, &["--strategies"]);
    assert!(e.contains("bdpt"), "{e}");
    let (e, _d) = render_fails(&cornell, &["--integrator", "bdtp"]);
    assert!(e.contains("path") && e.contains("bdpt"), "{e}");
}

#[test]
fn strategies_that_would_not_fit_in_memory_are_refused() {
    let d = tempfile::tempdir().unwrap();
    let text = cornell_text().replace("max_bounces = 8", "max_bounces = 200");
    let p = write(d.path(), "deep.toml", &text);
    let (e, _d) = render_fails(&p, &["--integrator", "bdpt", "--strategies"]);
    assert!(e.contains("max_bounces"), "{e}");
}

#[test]
fn nonpositive_spp_boundary_is_refused() {
    for n in ["0", "-2"] {
        let (e, _d) = render_fails(
            &scenes().join("shadow_hidden_occluder.toml"),
            &["--diff", "occluder_x", "--spp-boundary", n],
        );
        assert!(e.contains("--spp-boundary"), "{e}");
    }
}

/// A FIFO named like a scene used to hang `render` and `info`; /dev/zero as an OBJ was read
/// until memory ran out. Only regular files are read, with a size cap.
#[cfg(unix)]
#[test]
fn only_regular_files_are_read() {
    let d = tempfile::tempdir().unwrap();
    let fifo = d.path().join("x.toml");
    let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
    assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o644) }, 0);
    for cmd in [vec!["info"], vec!["render"]] {
        let mut c = dtr();
        c.args(&cmd).arg(&fifo);
        if cmd[0] == "render" {
            c.arg("-o").arg(d.path().join("out"));
        }
        let out = c.output().unwrap();
        let e = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && e.contains("not a regular file"), "{e}");
    }
    let scene = format!(
        "{}\n[[shape]]\nname = \"z\"\ntype = \"obj\"\nfile = \"/dev/zero\"\nmaterial = \"{}\"\n",
        cornell_text(),
        first_material_name()
    );
    let p = write(d.path(), "zero.toml", &scene);
    let (e, _o) = render_fails(&p, &[]);
    assert!(e.contains("/dev/zero") && e.contains("not a regular file"), "{e}");
}

/// TOML vectors with extra elements were accepted silently (JSON refused them).
#[test]
fn vectors_of_the_wrong_length_name_the_field() {
    let d = tempfile::tempdir().unwrap();
    let text = cornell_text();
    for (field, bad) in [
        ("position", "[0, 1, 3, 1]"),
        ("look_at", "[0, 0, 0, \"junk\"]"),
        ("position", "[0, 1]"),
    ] {
        let i = text.find(&format!("\n{field} =")).unwrap() + 1;
        let j = i + text[i..].find('\n').unwrap();
        let p = write(
            d.path(),
            "vec.toml",
            &format!("{}{field} = {bad}{}", &text[..i], &text[j..]),
        );
        let (e, _o) = render_fails(&p, &[]);
        assert!(e.contains(&format!("'{field}")), "{e}");
    }
}

/// Repeated or meaningless arguments were accepted silently; absurd thread counts spawned
/// over 1000 threads before failing. Boundary samples with the interior alone, and a preview
/// pixel without previews, are refused as boundary samples without --diff are.
#[test]
fn repeated_and_meaningless_arguments_are_refused() {
    let diff_room = scenes().join("diff_room.toml");
    for (args, needle) in [
        (vec!["--set", "eta=1", "--set", "eta=2"], "more than once"),
        (vec!["--diff", "eta,eta"], "more than once"),
        (vec!["--spp-boundary", "4"], "needs --diff"),
        // taken without a word until an independent sweep (helper 35, D14)
        (
            vec!["--diff", "albedo", "--spp-boundary", "4", "--estimators", "interior"],
            "which --estimators interior leaves out",
        ),
        (
            vec!["--diff", "albedo", "--guiding", "--estimators", "primary"],
            "which --estimators primary leaves out",
        ),
        (vec!["--pixel", "1,1"], "it needs --preview"),
        // taken without a word until the forty-third session (clap defaults hid them)
        (
            vec!["--normalise", "frame"],
            "--normalise sets how the previews are drawn",
        ),
        (
            vec!["--estimators", "interior"],
            "--estimators sets how derivatives are estimated; it needs --diff",
        ),
        (
            vec!["--time-edges", "off"],
            "--time-edges sets how derivatives are estimated; it needs --diff",
        ),
        (
            vec!["--guiding"],
            "--guiding sets how derivatives are estimated; it needs --diff",
        ),
        (vec!["--threads", "100000"], "--threads"),
        (vec!["--threads", "0"], "--threads"),
    ] {
        let (e, _o) = render_fails(&diff_room, &args);
        assert!(e.contains(needle), "{args:?}: {e}");
    }
}

/// Films that cannot fit (18 PB, 13 TB) aborted with SIGABRT ("memory allocation of … bytes
/// failed"); they are refused before anything is allocated, naming the size and the fields.
#[test]
fn films_that_cannot_fit_are_refused() {
    let d = tempfile::tempdir().unwrap();
    for (res, bins) in [("[16384, 16384]", "16777216"), ("[8192, 8192]", "16384")] {
        let text = cornell_text();
        let mut out = String::new();
        for line in text.lines() {
            if line.starts_with("resolution =") {
                out += &format!("resolution = {res}\n");
            } else if line.starts_with("bins =") {
                out += &format!("bins = {bins}\n");
            } else {
                out += line;
                out.push('\n');
            }
        }
        let p = write(d.path(), "huge.toml", &out);
        for integrator in ["path", "bdpt"] {
            let (e, _o) = render_fails(&p, &["--integrator", integrator]);
            assert!(
                e.contains("GiB") && e.contains("memory") && e.contains("film.bins"),
                "{e}"
            );
        }
    }
}

/// BDPT's cost grows as max_bounces³ (1 s per path at 1024 bounces): `dtr render` says so.
#[test]
fn bdpt_with_many_bounces_warns() {
    let d = tempfile::tempdir().unwrap();
    let text = std::fs::read_to_string(scenes().join("diff_room.toml")).unwrap();
    let p = write(
        d.path(),
        "deep.toml",
        &text.replacen("max_bounces = 3", "max_bounces = 100", 1),
    );
    let out = dtr()
        .arg("render")
        .arg(&p)
        .arg("-o")
        .arg(d.path().join("out"))
        .args(["--spp", "1", "--integrator", "bdpt", "--quiet"])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{e}");
    assert!(
        e.contains("warning") && e.contains("max_bounces = 100") && e.contains("max_bounces³"),
        "{e}"
    );
    let out = dtr()
        .arg("render")
        .arg(&p)
        .arg("-o")
        .arg(d.path().join("out2"))
        .args(["--spp", "1", "--quiet"])
        .output()
        .unwrap();
    assert!(!String::from_utf8_lossy(&out.stderr).contains("max_bounces³"));
}

/// Runs `dtr info` on `scene` with `extra` args: it must fail with exit status 2 (bad input);
/// returns stderr.
fn info_refuses(scene: &Path, extra: &[&str]) -> String {
    let o = dtr().arg("info").arg(scene).args(extra).output().unwrap();
    let e = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(e.starts_with("error: ") && !e.contains("panicked"), "{e}");
    e
}

/// A bin width the time axis cannot hold is refused naming the file and the field: one that
/// is zero or subnormal as a 32-bit float (the time plot of --preview and the kernel's window
/// bound use f32), or one so small next to film.start_opl that a bin ends where it starts.
/// Before, bin_width_opl = 1e-300 rendered with exit 0 into the window [3, 3] m (only a
/// "holds no energy" warning), and --preview then failed with an internal error (exit 1).
#[test]
fn a_bin_width_the_time_axis_cannot_hold_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let room = std::fs::read_to_string(scenes().join("diff_room.toml")).unwrap();
    let (start, width) = ("start_opl = 3.0", "bin_width_opl = 0.1");
    assert!(room.contains(start) && room.contains(width));
    let cases = [
        (room.replace(width, "bin_width_opl = 1e-300"), "1e-300"),
        (
            room.replace(width, "bin_width_opl = 1e-40"),
            "smallest normal 32-bit float",
        ),
        // a width that rounds to 0 in f32 is refused by the loader's scan of every number
        // (`f32_value::not_finite_f32`) before the time axis sees it
        (
            room.replace(start, "start_opl = 0.0")
                .replace(width, "bin_width_opl = 1e-300"),
            "1e-300, which rounds to 0 as a 32-bit float",
        ),
        (
            room.replace(start, "start_opl = 1e6")
                .replace(width, "bin_width_opl = 1e-12"),
            "ends where it starts",
        ),
    ];
    for (text, what) in cases {
        let p = write(d.path(), "tiny.toml", &text);
        let (e, _o) = render_fails(&p, &["--threads", "1", "--preview"]);
        assert!(e.contains("tiny.toml: film: field 'bin_width_opl'"), "{e}");
        assert!(e.contains(what), "{e}");
        info_refuses(&p, &[]);
    }
}

/// A pose that sends a vertex outside the range of 32-bit floats names the field that did it
/// (scale, rotate or translate) and the param that set it; a camera too far from its target
/// for 32-bit arithmetic names camera.position (or look_at). Before, an overflowing scale or
/// rotate was reported as field 'translate', with the note of the shape's translate param
/// (another param), and a camera 1e20 m away as "up is parallel to the view direction".
#[test]
fn an_overflowing_pose_or_a_far_camera_names_its_own_field() {
    let d = tempfile::tempdir().unwrap();
    // the pyramid (vertex 4 at y = 1.5) with a translate param too
    let turn = std::fs::read_to_string(scenes().join("pyramid_turn.toml")).unwrap()
        + "\n[[param]]\nname = \"pyramid_x\"\nkind = \"translate\"\nshape = \"pyramid\"\naxis = \"x\"\nvalue = 0.0\n";
    std::fs::create_dir(d.path().join("meshes")).unwrap();
    std::fs::copy(scenes().join("meshes/pyramid.obj"), d.path().join("meshes/pyramid.obj")).unwrap();
    let turn = write(d.path(), "turn.toml", &turn);
    let e = info_refuses(&turn, &["--set", "pyramid_height=3e38"]);
    assert!(
        e.contains(r#"turn.toml: shape[1] "pyramid": field 'scale'"#)
            && e.contains(r#"value from param "pyramid_height""#),
        "{e}"
    );
    assert!(!e.contains("translate") && !e.contains("pyramid_x"), "{e}");
    // a finite scale of each axis that the rotation adds into one beyond the range
    let room = scenes().join("diff_room.toml");
    let e = info_refuses(
        &room,
        &[
            "--set",
            "room_scale_z=3e38",
            "--set",
            "shape.room.scale.0=3e38",
            "--set",
            "room_rot_y=45",
        ],
    );
    assert!(
        e.contains(r#"shape[0] "room": field 'rotate'"#) && e.contains(r#"value from param "room_rot_y""#),
        "{e}"
    );
    assert!(!e.contains("'translate'") && !e.contains("room_z"), "{e}");
    // the translate itself still names translate and its param
    let e = info_refuses(&room, &["--set", "room_scale_z=3.4e38", "--set", "room_z=1e38"]);
    assert!(
        e.contains(r#"shape[0] "room": field 'translate'"#) && e.contains(r#"value from param "room_z""#),
        "{e}"
    );
    // a camera 1e20 m from its target, and a target 1e20 m from the camera
    let text = std::fs::read_to_string(&room).unwrap();
    let (pos, look) = ("position = [0.0, 0.0, 1.0]", "look_at = [0.0, 0.0, -3.0]");
    assert!(text.contains(pos) && text.contains(look));
    for (text, field) in [
        (text.replace(pos, "position = [0.0, 0.0, 1e20]"), "position"),
        (text.replace(look, "look_at = [0.0, 0.0, -1e20]"), "look_at"),
    ] {
        let p = write(d.path(), "far.toml", &text);
        let e = info_refuses(&p, &[]);
        assert!(
            e.contains(&format!("far.toml: camera: field '{field}'")) && e.contains("32-bit"),
            "{e}"
        );
        assert!(!e.contains("parallel"), "{e}");
    }
}

/// Emission so strong that the film overflows 32-bit floats is bad input, named by emitter and
/// field (exit 2, nothing written). Before, it was "internal error: 2 non-finite values in the
/// transient; nothing written" (exit 1), naming no input. It is now refused when the scene
/// loads (an_emission_too_strong_for_32_bit_films_is_refused_at_load).
#[test]
fn an_emission_that_overflows_the_film_is_named() {
    let d = tempfile::tempdir().unwrap();
    let prefix = d.path().join("x");
    let o = dtr()
        .args(["render"])
        .arg(scenes().join("cornell_box.toml"))
        .args(["--spp", "16", "--threads", "1"])
        .args(["--set", "camera.resolution.0=8", "--set", "camera.resolution.1=8"])
        .args(["--set", "emitter.light.radiance.0=3.4e38", "-o"])
        .arg(&prefix)
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&o.stderr).to_string();
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("cornell_box.toml: emitter[0] \"light\": field 'radiance'"),
        "{e}"
    );
    assert!(!e.contains("internal error") && !e.contains("panicked"), "{e}");
    assert_eq!(
        std::fs::read_dir(d.path()).unwrap().count(),
        0,
        "nothing may be written"
    );
}

/// Counts beyond what their field holds say the maximum, and the whole number 2⁵³ is one.
/// Before (an independent sweep, 2026-12-02): `--spp 4294967296` said "--spp is too large:
/// out of range integral type conversion attempted", and `--set integrator.seed=
/// 9007199254740992` (2⁵³, exact in a 64-bit float) was refused as "not a whole number".
#[test]
fn counts_beyond_their_field_say_the_maximum_and_2_to_the_53_is_whole() {
    let cornell = scenes().join("cornell_box.toml");
    for flag in ["--spp", "--spp-boundary"] {
        let d = tempfile::tempdir().unwrap();
        let o = dtr()
            .arg("render")
            .arg(&cornell)
            .arg("-o")
            .arg(d.path().join("a"))
            .args([flag, "4294967296", "--quiet"])
            .output()
            .unwrap();
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(
            e.contains(&format!("{flag} must be at most 4294967295 (got 4294967296)")),
            "{e}"
        );
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0);
    }
    let d = render_succeeds(&cornell, &["--set", "integrator.seed=9007199254740992"]);
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(d.path().join("a.json")).unwrap()).unwrap();
    assert_eq!(json["seed"], 9007199254740992u64, "{json}");
}

/// A camera on a surface, within the rays' offset, is refused naming the field and the shape
/// (src/scene/surface_distance.rs). Before (an independent sweep, 2026-12-02), the camera of
/// diff_room.toml set on the room's wall (z = 3, or 3.0000001, outside, which rounds onto it)
/// rendered black with the path tracer and, with BDPT, light through the wall on 164 of 256
/// pixels, without a word. 0.1 mm inside the wall it renders.
#[test]
fn a_camera_on_a_wall_is_named() {
    let room = scenes().join("diff_room.toml");
    for z in ["3", "3.0000001", "2.999999"] {
        for integrator in ["path", "bdpt"] {
            let set = format!("camera.position.2={z}");
            let (e, _o) = render_fails(&room, &["--set", &set, "--integrator", integrator]);
            assert!(
                e.contains("diff_room.toml: camera: field 'position': lies")
                    && e.contains("from shape \"room\", within the rays' offset"),
                "{z} {integrator}: {e}"
            );
        }
    }
    render_succeeds(&room, &["--set", "camera.position.2=2.9999", "--integrator", "bdpt"]);
}

/// Roughnesses and refractive indices too small for 32-bit floats are refused naming the field
/// (`scene::limits::MIN_ROUGHNESS`, `MIN_INDEX`, 10⁻⁶), in the scene and as a parameter's
/// value. Before (an independent sweep, 2026-12-02), a rough conductor of α = 10⁻¹⁰ rendered
/// 20 % too dark and one of 10⁻²⁰ 68 %, silently (GGX's α⁴ flushed to zero); `int_ior` 10⁻¹⁹
/// gave a derivative of −130 where the image does not change; a medium `eta` of 10⁻³⁸ made
/// every path vanish. The smallest allowed values still render.
#[test]
fn roughnesses_and_indices_below_what_floats_resolve_are_named() {
    let conductor = scenes().join("rough_conductor.toml");
    let (e, _o) = render_fails(&conductor, &["--set", "gold_roughness=1e-10"]);
    assert!(
        e.contains(r#"param[0] "gold_roughness": field 'value': a roughness (GGX α) must be in [1e-6, 1] (got 1e-10)"#),
        "{e}"
    );
    let (e, _o) = render_fails(
        &scenes().join("cornell_gold.toml"),
        &["--set", "material.gold.roughness=1e-20"],
    );
    assert!(
        e.contains(r#"material[2] "gold": field 'roughness': must be in [1e-6, 1] (got 1e-20)"#)
            && e.contains("32-bit"),
        "{e}"
    );
    let dielectric = scenes().join("rough_dielectric.toml");
    let (e, _o) = render_fails(&dielectric, &["--set", "glass_ior=1e-19"]);
    assert!(
        e.contains(r#""glass_ior": field 'value': an index of refraction must be >= 1e-6 (got 1e-19)"#),
        "{e}"
    );
    let (e, _o) = render_fails(&scenes().join("cornell_box.toml"), &["--set", "medium.eta=1e-38"]);
    assert!(
        e.contains("medium: field 'eta': must be at least 1e-6 (got 1e-38)"),
        "{e}"
    );
    for (scene, set) in [
        (&conductor, "gold_roughness=1e-6"),
        (&dielectric, "glass_ior=1e-6"),
        (&dielectric, "glass_roughness=1e-6"),
    ] {
        render_succeeds(scene, &["--set", set]);
    }
}

/// Pixel filters narrower than a thousandth of a pixel or wider than 64 pixels are refused,
/// naming the field and the range (`scene::limits::MIN_FILTER_WIDTH`, `MAX_FILTER_WIDTH`).
/// Before, a tent of radius 10³⁰ rendered a black image whose warning blamed the emitter, a
/// Gaussian of σ = 10³⁰ ended in "internal error: non-finite values", and one of σ = 10⁻²⁰
/// rendered another image than the box, all silently but the last. Filters at the limits
/// render.
#[test]
fn pixel_filters_beyond_what_a_pixel_filter_is_are_named() {
    let cornell = scenes().join("cornell_box.toml");
    for (set, field, got) in [
        (r#"camera.filter={type="tent",radius=1e30}"#, "filter.radius", "1e30"),
        (r#"camera.filter={type="tent",radius=1e-20}"#, "filter.radius", "1e-20"),
        (
            r#"camera.filter={type="gaussian",sigma=1e-20}"#,
            "filter.sigma",
            "1e-20",
        ),
        (
            r#"camera.filter={type="gaussian",sigma=1e30,radius=3e38}"#,
            "filter.sigma",
            "1e30",
        ),
        (
            r#"camera.filter={type="gaussian",sigma=0.5,radius=65}"#,
            "filter.radius",
            "65",
        ),
    ] {
        let (e, _o) = render_fails(&cornell, &["--set", set]);
        assert!(
            e.contains(&format!(
                "cornell_box.toml: camera: field '{field}': must be in [0.001, 64] pixels (got {got})"
            )),
            "{set}: {e}"
        );
    }
    for set in [
        r#"camera.filter={type="tent",radius=64}"#,
        r#"camera.filter={type="gaussian",sigma=0.001,radius=0.001}"#,
        r#"camera.filter={type="gaussian",sigma=64,radius=1.5}"#,
    ] {
        for kind in ["path", "bdpt"] {
            render_succeeds(
                &cornell,
                &["--set", set, "--set", &format!("integrator.kind=\"{kind}\"")],
            );
        }
    }
}

/// A refractive index so large that a path's optical path length would pass what 32-bit
/// floats add up is refused naming its field: the medium's eta and a dielectric's int_ior.
/// Before, `medium.eta = 3e38 --steady full` rendered all zeros with exit 0, every sample
/// dropped as not finite (only the JSON's non_finite_samples said so). A large index that
/// stays finite across the scene still renders.
#[test]
fn an_index_whose_path_lengths_overflow_is_named() {
    let (e, _o) = render_fails(
        &scenes().join("cornell_box.toml"),
        &["--set", "medium.eta=3e38", "--steady", "full"],
    );
    assert!(
        e.contains("cornell_box.toml: medium: field 'eta': 3e38 is too large") && e.contains("32-bit"),
        "{e}"
    );
    let e = info_refuses(
        &scenes().join("cornell_glass.toml"),
        &["--set", "material.glass.int_ior=1e37"],
    );
    assert!(
        e.contains(r#"cornell_glass.toml: material[2] "glass": field 'int_ior': 1e37 is too large"#),
        "{e}"
    );
    let d = render_succeeds(
        &scenes().join("cornell_box.toml"),
        &["--steady", "full", "--set", "medium.eta=1e30"],
    );
    let j: serde_json::Value = serde_json::from_slice(&std::fs::read(d.path().join("a.json")).unwrap()).unwrap();
    assert_eq!(j["non_finite_samples"], 0);
    assert!(j["energy"]["primal"]["total"].as_f64().unwrap() > 0.0);
}

/// A camera inside a dielectric of another index than the scene's medium is refused, naming
/// the shape, its material and both indices: every path starts in the scene's medium, so a
/// camera in a glass cube (η 1.5, [−1, 1]³) looking at a lamp 2 m away put the first arrival
/// at OPL 2.0 m instead of 2.5 m, with exit 0 (found by an independent sweep). The same
/// camera outside the cube renders, and so does one inside a cube whose index is the medium's.
#[test]
fn a_camera_inside_a_dielectric_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let scene = |medium: &str| {
        format!(
            "{medium}[camera]\nposition = [0.0, 0.0, 0.0]\nlook_at = [0.0, 0.0, -1.0]\nfov = 30.0\nresolution = [8, 8]\n\
             [film]\nstart_opl = 0.0\nbin_width_opl = 0.05\nbins = 200\n\
             [[material]]\nname = \"glass\"\ntype = \"dielectric\"\nint_ior = 1.5\n\
             [[material]]\nname = \"black\"\ntype = \"diffuse\"\nalbedo = 0.0\n\
             [[shape]]\nname = \"cube\"\ntype = \"cube\"\nmaterial = \"glass\"\n\
             [[shape]]\nname = \"lamp\"\ntype = \"rectangle\"\nmaterial = \"black\"\ntranslate = [0.0, 0.0, -2.0]\nscale = [3.0, 3.0, 1.0]\n\
             [[emitter]]\nname = \"light\"\ntype = \"area\"\nshape = \"lamp\"\nradiance = 1.0\n"
        )
    };
    let inside = write(d.path(), "inside.toml", &scene(""));
    let (e, _o) = render_fails(&inside, &["--threads", "1"]);
    assert!(
        e.contains(
            r#"inside.toml: the camera lies inside material "glass" (type dielectric) of shape "cube" (index 1.5)"#
        ) && e.contains("medium.eta = 1)"),
        "{e}"
    );
    let renders = |scene: &Path, extra: &[&str]| {
        let o = dtr()
            .args(["render", "--quiet", "--spp", "1", "--threads", "1", "-o"])
            .arg(d.path().join("x"))
            .arg(scene)
            .args(extra)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::remove_file(d.path().join("x.npy")).unwrap();
        std::fs::remove_file(d.path().join("x.json")).unwrap();
    };
    renders(&inside, &["--set", "camera.position.2=3"]);
    let matched = write(d.path(), "matched.toml", &scene("[medium]\neta = 1.5\n"));
    renders(&matched, &[]);
}

/// A scene without a surface (a point light alone) is bad input naming the file and `shape`
/// (exit 2). Before, it loaded and Embree refused the empty mesh at render time: "error:
/// Embree: invalid mesh: the mesh has no triangles", exit 1 (an internal failure), naming
/// neither (found by an independent audit).
#[test]
fn a_scene_without_a_surface_is_refused_naming_the_file() {
    let d = tempfile::tempdir().unwrap();
    let text = cornell_text();
    let head = text.split("[[material]]").next().unwrap();
    let scene =
        format!("{head}[[emitter]]\nname = \"p\"\ntype = \"point\"\nposition = [0.0, 1.0, 0.0]\nintensity = 1.0\n");
    let p = write(d.path(), "empty.toml", &scene);
    let out = dtr()
        .args([
            "render",
            p.to_str().unwrap(),
            "-o",
            d.path().join("out").to_str().unwrap(),
            "-q",
        ])
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{e}");
    assert!(e.contains("empty.toml: shape:") && e.contains("no surface"), "{e}");
    render_fails(&p, &[]);
}

/// `--exr` of a film that needs more EXR channels than OpenEXR opens (one per bin and colour
/// channel, and the steady image's: at most 32 767) is refused before the render, naming the
/// option and the largest bin count that fits. Before, 10 922 RGB bins rendered and wrote an
/// EXR file OpenEXR would not open, with exit 0 (independent audit).
#[test]
fn an_exr_of_more_channels_than_openexr_opens_is_refused_before_the_render() {
    let scene = scenes().join("cornell_box.toml");
    let (e, _d) = render_fails(
        &scene,
        &["--exr", "--set", "film.bins=10922", "--set", "camera.resolution=[4, 4]"],
    );
    assert!(
        e.contains("cornell_box.toml: --exr: 10922 time bins of 3 channel(s) make 32769 EXR channels"),
        "{e}"
    );
    assert!(e.contains("at most 10921 bins"), "{e}");
}

/// An emitted amount too strong for the film's 32-bit floats is refused when the scene loads,
/// naming the file, the emitter and the field (exit 2, before any render): an area light's
/// radiance, a point light's intensity, a laser's power, and a [[param]] that sets one.
/// Before, `radiance = [3e38, 3e38, 3e38]` with --preview rendered the whole scene and only
/// then failed with exit 1 (`plot.png: 6 of 200 values are not finite`); without --preview
/// it wrote a film whose values overflow when added up.
#[test]
fn an_emission_too_strong_for_32_bit_films_is_refused_at_load() {
    let huge = "[3e38, 3e38, 3e38]";
    let e = info_refuses(
        &scenes().join("cornell_box.toml"),
        &["--set", &format!("emitter.light.radiance={huge}")],
    );
    assert!(
        e.contains("cornell_box.toml: emitter[0] \"light\": field 'radiance'") && e.contains("at most 1e18"),
        "{e}"
    );
    let (e, _o) = render_fails(
        &scenes().join("cornell_box.toml"),
        &[
            "--threads",
            "1",
            "--set",
            &format!("emitter.light.radiance={huge}"),
            "--set",
            "film.start_opl=3.7",
            "--set",
            "film.bin_width_opl=0.01",
            "--set",
            "film.bins=100",
            "--set",
            "camera.resolution.0=32",
            "--set",
            "camera.resolution.1=32",
            "--preview",
        ],
    );
    assert!(e.contains("field 'radiance'") && !e.contains("plot.png"), "{e}");
    let e = info_refuses(&scenes().join("diff_room.toml"), &["--set", "intensity=2e18"]);
    assert!(
        e.contains("diff_room.toml: param[") && e.contains("\"intensity\": field 'value'") && e.contains("1e18"),
        "{e}"
    );
    let d = tempfile::tempdir().unwrap();
    // each scene without the parameter that sets the emitter's amount (its value would be the
    // amount), and the file's amount made too strong
    for (scene, file, param, field, value, said) in [
        (
            "diff_room.toml",
            "strong.toml",
            "[[param]]\nname = \"intensity\"\nkind = \"radiance\"\nemitter = \"lamp\"\nvalue = 5.0\n",
            "intensity = 5.0",
            "intensity = 1e30",
            "strong.toml: emitter[0] \"lamp\": field 'intensity': every channel must be at most 1e18 (got 1e30)",
        ),
        (
            "gated_laser_room.toml",
            "laser.toml",
            "[[param]]\nname = \"laser_power\"\nkind = \"radiance\"\nemitter = \"laser\"\nvalue = 10.0\n",
            "power = 10.0",
            "power = [1, 2e18, 1]",
            "laser.toml: emitter[0] \"laser\": field 'power': every channel must be at most 1e18 (got [1, 2e18, 1])",
        ),
    ] {
        let text = std::fs::read_to_string(scenes().join(scene)).unwrap();
        assert!(text.contains(param) && text.contains(field), "{scene}");
        let p = write(d.path(), file, &text.replace(param, "").replace(field, value));
        let e = info_refuses(&p, &[]);
        assert!(e.contains(said), "{e}");
    }
    // the bound itself renders, and its preview is finite
    let o = dtr()
        .arg("render")
        .arg(scenes().join("cornell_box.toml"))
        .args(["--spp", "1", "--threads", "1", "--quiet", "--preview"])
        .args(["--set", "emitter.light.radiance.0=1e18"])
        .args(["--set", "camera.resolution.0=8", "--set", "camera.resolution.1=8", "-o"])
        .arg(d.path().join("bound"))
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}

/// A pulse's width or an emitter's offset beyond what 32-bit OPLs resolve is refused at load,
/// naming the field. Before, `sigma_opl = 1e30` rendered with exit 0, and with --auto-window
/// it chose a window of [-3.4e30, 2.6e30] m of OPL.
#[test]
fn a_pulse_or_offset_beyond_32_bit_opls_is_refused() {
    let d = tempfile::tempdir().unwrap();
    let room = std::fs::read_to_string(scenes().join("diff_room.toml")).unwrap();
    let pulse = r#"pulse = { type = "gaussian", sigma_opl = 0.1 }"#;
    assert!(room.contains(pulse));
    // (diff_room's offset is its parameter lamp_offset's: the file's offset_opl is the laser's)
    let laser = std::fs::read_to_string(scenes().join("gated_laser_room.toml")).unwrap();
    assert!(laser.contains(pulse) && !laser.contains("pulse_offset"));
    let cases = [
        (
            room.replace(pulse, r#"pulse = { type = "gaussian", sigma_opl = 1e30 }"#),
            r#"emitter[0] "lamp": field 'pulse.sigma_opl'"#,
            "must be at most 16777216 m (got 1e30)",
        ),
        (
            room.replace(pulse, r#"pulse = { type = "box", width_opl = 1e9 }"#),
            r#"emitter[0] "lamp": field 'pulse.width_opl'"#,
            "must be at most 16777216 m (got 1e9)",
        ),
        (
            laser.replace(pulse, &format!("{pulse}\noffset_opl = -1e30")),
            r#"emitter[0] "laser": field 'offset_opl'"#,
            "must be within ±16777216 m (got -1e30)",
        ),
    ];
    for (text, field, says) in cases {
        let p = write(d.path(), "far.toml", &text);
        let e = info_refuses(&p, &[]);
        assert!(
            e.contains(&format!("far.toml: {field}: {says}")) && e.contains("32-bit"),
            "{e}"
        );
        let (e, _o) = render_fails(&p, &["--threads", "1", "--auto-window"]);
        assert!(e.contains(&format!("far.toml: {field}")), "{e}");
    }
    let e = info_refuses(&scenes().join("diff_room.toml"), &["--set", "lamp_offset=1e30"]);
    assert!(e.contains("\"lamp_offset\": field 'value'"), "{e}");
}

/// A shape sent so far that f32 cannot tell its corners apart is refused naming its
/// translation, not its scale: `--set plate_x=1e30` read "field 'scale': empty mesh" (found
/// by an independent sweep). A scale that flattens it is still the scale's fault.
#[test]
fn a_shape_sent_beyond_f32_resolution_names_its_translation() {
    let plate = scenes().join("pose_plate.toml");
    let (e, _o) = render_fails(&plate, &["--set", "plate_x=1e30"]);
    assert!(
        e.contains("\"plate\": field 'translate'") && e.contains("[1e30, 0.05, 0]") && e.contains("cannot resolve"),
        "{e}"
    );
    let (e, _o) = render_fails(&plate, &["--set", "shape.plate.scale=[1e-30, 1e-30, 1]"]);
    assert!(e.contains("field 'scale'") && e.contains("empty mesh"), "{e}");
}
