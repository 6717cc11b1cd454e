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
