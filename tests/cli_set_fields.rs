//! `--set PATH=VALUE` sets any number of the description (issue 15): the render equals the
//! render of a file that says the same, and a bad path or value is refused like a bad file.

use crate::common;

#[test]
fn a_field_set_on_the_command_line_equals_the_same_field_in_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = common::scene_path("diff_room.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    assert!(text.contains("bins = 150") && text.contains("resolution = [16, 16]"));
    let edited = d.join("edited.toml");
    std::fs::write(
        &edited,
        text.replace("bins = 150", "bins = 40")
            .replace("resolution = [16, 16]", "resolution = [12, 16]"),
    )
    .unwrap();
    let run = |args: &[&str]| {
        let o = common::dtr(args, d);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    };
    let s = scene.to_str().unwrap();
    run(&[
        "render",
        s,
        "--spp",
        "2",
        "--set",
        "film.bins=40",
        "--set",
        "camera.resolution.0=12",
        "-o",
        "a",
    ]);
    run(&["render", edited.to_str().unwrap(), "--spp", "2", "-o", "b"]);
    let a = std::fs::read(d.join("a.npy")).unwrap();
    let b = std::fs::read(d.join("b.npy")).unwrap();
    assert_eq!(a, b, "the overridden render differs from the edited file's");
    assert!(String::from_utf8_lossy(&a[..128]).contains("(16, 12, 40, 1,"));

    for (set, says) in [
        ("film.bins=0", "must be at least 1"),
        ("film.bins=2.5", "whole number"),
        ("flim.bins=3", "no \"flim\""),
        ("material.glass.albedo=0.5", "no entry named \"glass\""),
        ("camera.resolution=8", "list of 2"),
    ] {
        let o = common::dtr(&["render", s, "--set", set, "-o", "x"], d);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{set}: {err}");
        assert!(err.contains(says) && err.contains("diff_room.toml"), "{set}: {err}");
    }
}

/// A `--set` value outside the range of 32-bit floats is refused, naming the file, the name
/// and the range, as the same value in the file is. Before, the overrides checked only that
/// the value was finite in 64 bits: these renders exited 0 with an all-zero transient, or
/// failed late.
#[test]
fn a_value_outside_the_f32_range_is_refused_as_in_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for (scene, set) in [
        ("confocal_plane.toml", "emitter.lamp.intensity=1e39"),
        ("confocal_plane.toml", "emitter.lamp.offset_opl=1e39"),
        ("diff_room.toml", "intensity=1e39"),
        ("diff_room.toml", "eta=1e39"),
        ("diff_room.toml", "lamp_offset=-1e39"),
        ("nlos_occluder.toml", "nlos.noise.photons_per_unit=1e300"),
        ("nlos_occluder.toml", "nlos.noise.dark_counts=1e300"),
    ] {
        let s = common::scene_path(scene);
        let args = ["render", s.to_str().unwrap(), "--threads", "1", "--spp", "1", "-q"];
        let o = common::dtr(&[&args[..], &["--set", set, "-o", "x"]].concat(), d);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{set}: {err}");
        let name = set.split('=').next().unwrap();
        assert!(
            err.contains(scene)
                && err.contains(&format!("--set {name}"))
                && err.contains("outside the range of 32-bit floats"),
            "{set}: {err}"
        );
        assert_eq!(std::fs::read_dir(d).unwrap().count(), 0, "{set}: files left");
    }
}

/// `--set` gives fields values other than numbers, written as in a TOML file: a word, a list,
/// an inline table. Before, `--set nlos.scan=exhaustive` was refused ("is not a number") and
/// such fields needed an edited copy of the scene file.
#[test]
fn words_lists_and_tables_set_on_the_command_line_equal_the_same_in_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = common::scene_path("nlos_occluder.toml");
    let text = std::fs::read_to_string(&scene).unwrap();
    let lines = [
        ("scan = \"confocal\"", "scan = \"exhaustive\""),
        ("grid = [16, 16]", "grid = [4, 3]"),
        ("channels = \"mono\"", "channels = \"rgb\""),
        ("gate = { type = \"gaussian\", sigma_opl = 0.01 }", "gate = \"box\""),
        (
            "pulse = { type = \"gaussian\", sigma_opl = 0.01 }",
            "pulse = { type = \"box\", width_opl = 0.04 }",
        ),
    ];
    let mut edited_text = text.clone();
    for (from, to) in lines {
        assert_eq!(text.matches(from).count(), 1, "{from}");
        edited_text = edited_text.replace(from, to);
    }
    let edited = d.join("edited.toml");
    std::fs::write(&edited, edited_text).unwrap();
    let run = |args: &[&str]| {
        let o = common::dtr(args, d);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stdout).to_string()
    };
    let s = scene.to_str().unwrap();
    let sets = [
        "--set",
        "nlos.scan=exhaustive",
        "--set",
        "nlos.grid=[4, 3]",
        "--set",
        "film.channels=\"rgb\"",
        "--set",
        "film.gate=box",
        "--set",
        "emitter.laser.pulse={ type = \"box\", width_opl = 0.04 }",
    ];
    let common_args = ["--spp", "8", "--seed", "3", "--threads", "1", "-q"];
    run(&[&["render", s][..], &common_args, &sets, &["-o", "a"]].concat());
    run(&[&["render", edited.to_str().unwrap()][..], &common_args, &["-o", "b"]].concat());
    let a = std::fs::read(d.join("a.npy")).unwrap();
    assert_eq!(
        a,
        std::fs::read(d.join("b.npy")).unwrap(),
        "the overridden render differs from the edited file's"
    );
    // 12 laser points × 12 sensor points, RGB
    assert!(
        String::from_utf8_lossy(&a[..128]).contains("(12, 12, 128, 3,"),
        "{}",
        String::from_utf8_lossy(&a[..128])
    );
    let info = run(&[&["info", s][..], &sets].concat());
    assert!(
        info.contains("exhaustive scan") && info.contains("grid 4x3") && info.contains("pulse box"),
        "{info}"
    );

    // numbers and words together, and a [[param]] beside them
    run(&[
        "render",
        s,
        "--spp",
        "2",
        "-q",
        "--set",
        "nlos.scan=exhaustive",
        "--set",
        "nlos.grid.0=2",
        "--set",
        "nlos.grid.1=2",
        "--set",
        "hidden_x=0.4",
        "-o",
        "c",
    ]);

    for (set, says) in [
        ("nlos.scan=sideways", "'confocal' or 'exhaustive'"),
        ("nlos.grid=[4, inf]", "--set nlos.grid"),
        ("film.bins=[3]", "field 'bins'"),
        ("hidden_x=left", "[[param]] takes numbers"),
        ("flim.channels=rgb", "no \"flim\""),
    ] {
        let o = common::dtr(&["render", s, "--spp", "1", "--set", set, "-o", "x"], d);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{set}: {err}");
        assert!(err.contains(says), "{set}: {err}");
        assert!(
            !d.join("x.npy").exists() && !d.join("x.json").exists(),
            "{set}: files left"
        );
    }
}

/// A number given for a field that takes a word is checked like that value in the file, and
/// the error names the field: before, `--set film.channels=5` said "only numbers can be set",
/// where words can be set too.
#[test]
fn a_number_for_a_word_field_is_checked_as_the_file_would_be() {
    let dir = tempfile::tempdir().unwrap();
    let s = common::scene_path("cornell_box.toml");
    let o = common::dtr(&["info", s.to_str().unwrap(), "--set", "film.channels=5"], dir.path());
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cornell_box.toml: film: field 'channels'") && err.contains("integer '5'"),
        "{err}"
    );
    assert!(!err.contains("only numbers"), "{err}");
}

/// A seed beyond 2⁵³ set with `--set integrator.seed=N` renders as the same seed given with
/// `--seed N` (the same bytes) and is recorded exactly. Before, the value went through a
/// float, lost its last digit, and was refused: "expected a whole number, got
/// 9007199254740992" (helper 20).
#[test]
fn a_64_bit_seed_set_as_a_field_is_exact() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = common::scene_path("diff_room.toml");
    let s = s.to_str().unwrap();
    let seed = "9007199254740993";
    for (out, args) in [
        ("field", ["--set", &format!("integrator.seed={seed}")]),
        ("flag", ["--seed", seed]),
    ] {
        let o = common::dtr(
            &[&["render", s, "--spp", "1", "-q", "-o", out][..], &args[..]].concat(),
            d,
        );
        assert!(o.status.success(), "{out}: {}", String::from_utf8_lossy(&o.stderr));
    }
    assert_eq!(
        std::fs::read(d.join("field.npy")).unwrap(),
        std::fs::read(d.join("flag.npy")).unwrap()
    );
    let other = common::dtr(
        &[
            "render",
            s,
            "--spp",
            "1",
            "-q",
            "-o",
            "other",
            "--seed",
            "9007199254740992",
        ],
        d,
    );
    assert!(other.status.success());
    assert_ne!(
        std::fs::read(d.join("field.npy")).unwrap(),
        std::fs::read(d.join("other.npy")).unwrap(),
        "the seed's last digit is kept"
    );
}

/// A `--set` of a field that a `[[param]]` sets (the whole field, or a component the param
/// sets) is refused, naming both: the param's value replaced it without a word (`dtr info
/// diff_room.toml --set material.wall.albedo=0.4` showed albedo 0.6, `--set medium.eta=1.3`
/// showed 1; found by an independent audit). A component no param sets is still taken.
#[test]
fn a_field_a_param_sets_is_refused_on_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::scene_path("diff_room.toml");
    let s = scene.to_str().unwrap();
    for (set, param) in [
        ("material.wall.albedo=0.4", "param[3] \"albedo\""),
        ("medium.eta=1.3", "param[5] \"eta\""),
        ("emitter.lamp.intensity=2", "param[4] \"intensity\""),
        ("shape.room.scale.2=2", "param[2] \"room_scale_z\""),
        ("emitter.lamp.offset_opl=0.1", "param[6] \"lamp_offset\""),
    ] {
        let o = common::dtr(&["info", s, "--set", set], dir.path());
        let e = String::from_utf8_lossy(&o.stderr);
        let field = set.split('=').next().unwrap();
        assert_eq!(o.status.code(), Some(2), "--set {set}: {e}");
        assert!(
            e.contains(&format!("diff_room.toml: --set {field}: {param} sets this field")),
            "--set {set}: {e}"
        );
    }
    // the scale's x is no param's: taken
    let o = common::dtr(&["info", s, "--set", "shape.room.scale.0=2.75"], dir.path());
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(out.contains("2.75"), "{out}");
}
