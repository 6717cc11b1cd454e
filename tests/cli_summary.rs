//! The line `dtr render` prints at the end reports the whole run (issue 15): the total time
//! (the JSON's total_wall_seconds), the interior pass, and the boundary stage when it ran.

use crate::common;

fn numbers_after(line: &str, key: &str) -> f64 {
    let rest = &line[line.find(key).unwrap_or_else(|| panic!("{key:?} not in {line:?}")) + key.len()..];
    rest.trim_start()
        .split([' ', ':', ')'])
        .next()
        .unwrap()
        .parse()
        .unwrap()
}

#[test]
fn the_summary_line_reports_the_whole_run() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::scene_path("shadow_hidden_occluder.toml");
    let s = scene.to_str().unwrap();
    let run = |args: &[&str]| {
        let o = common::dtr(args, dir.path());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        String::from_utf8_lossy(&o.stderr).lines().last().unwrap().to_string()
    };
    let line = run(&[
        "render",
        s,
        "--spp",
        "2",
        "--spp-boundary",
        "64",
        "--diff",
        "occluder_x",
        "-o",
        "d",
    ]);
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("d.json")).unwrap()).unwrap();
    let total = numbers_after(&line, " in ");
    let interior = numbers_after(&line, "(interior ");
    let boundary = numbers_after(&line, "boundary stage ");
    assert!(
        (total - json["total_wall_seconds"].as_f64().unwrap()).abs() <= 0.006,
        "{line}"
    );
    assert!(
        (boundary - json["boundary_seconds"].as_f64().unwrap()).abs() <= 0.006,
        "{line}"
    );
    assert!(total + 0.011 >= interior + boundary, "{line}");

    let line = run(&["render", s, "--spp", "2", "-o", "p"]);
    assert!(
        line.contains("(interior ") && !line.contains("boundary stage"),
        "{line}"
    );
}
