//! `dtr render` says when the answer is empty: a window that misses every path, or a scene
//! with no emitter, still exits 0 and writes its files, but warns on stderr and in the JSON.

use std::path::{Path, PathBuf};
use std::process::Command;

fn cornell_text() -> String {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/cornell_box.toml");
    std::fs::read_to_string(p).unwrap()
}

/// Renders `text` (a scene) at 1 spp; returns (stderr, the run JSON).
fn render(dir: &Path, text: &str) -> (String, serde_json::Value) {
    let scene = dir.join("scene.toml");
    std::fs::write(&scene, text).unwrap();
    let prefix = dir.join("out");
    let out = Command::new(env!("CARGO_BIN_EXE_dtr"))
        .arg("render")
        .arg(&scene)
        .arg("-o")
        .arg(&prefix)
        .args(["--spp", "1", "--quiet"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).to_string();
    assert!(out.status.success(), "render failed: {stderr}");
    let json = std::fs::read_to_string(dir.join("out.json")).unwrap();
    assert!(dir.join("out.npy").exists());
    (stderr, serde_json::from_str(&json).unwrap())
}

fn with_window(start: &str) -> String {
    let text = cornell_text();
    let i = text.find("start_opl =").expect("cornell sets film.start_opl");
    let j = i + text[i..].find('\n').unwrap();
    format!("{}start_opl = {start}{}", &text[..i], &text[j..])
}

#[test]
fn a_window_that_misses_every_path_warns() {
    // the first light arrives at 3.78 m and the last well before 100 m: windows [−8.4, 3.6] m
    // (every path after it) and [100, 112] m (every path before it) hold nothing
    for (start, side) in [("-8.4", "after"), ("100.0", "before")] {
        let d = tempfile::tempdir().unwrap();
        let (stderr, j) = render(d.path(), &with_window(start));
        assert!(
            stderr.contains("warning:") && stderr.contains("holds no energy"),
            "window from {start}: {stderr}"
        );
        let e = &j["energy"]["primal"];
        assert_eq!(e["inside"], 0.0, "{e}");
        let total = e["total"].as_f64().unwrap();
        assert!(total > 0.0);
        let other = if side == "before" { "after" } else { "before" };
        let outside = e[side].as_f64().unwrap();
        assert!((outside - total).abs() <= 1e-5 * total, "{e}");
        assert_eq!(e[other], 0.0, "{e}");
        assert!(j["energy"]["warning"].as_str().unwrap().contains("holds no energy"));
    }
}

#[test]
fn a_window_holding_a_small_part_warns_and_a_good_one_does_not() {
    let d = tempfile::tempdir().unwrap();
    // from 12.6 m: only the late tail (well under half of the energy) is inside
    let (stderr, j) = render(d.path(), &with_window("12.6"));
    assert!(stderr.contains("warning:") && stderr.contains("holds only"), "{stderr}");
    let f = j["energy"]["primal"]["inside_fraction"].as_f64().unwrap();
    assert!(f > 0.0 && f < 0.5, "{f}");
    let d = tempfile::tempdir().unwrap();
    let (stderr, j) = render(d.path(), &cornell_text());
    assert!(
        !stderr.contains("warning"),
        "the default Cornell window warns: {stderr}"
    );
    assert!(j["energy"]["warning"].is_null());
}

#[test]
fn a_scene_without_emitters_warns() {
    let text = cornell_text();
    let i = text.find("[[emitter]]").expect("cornell has an emitter");
    let d = tempfile::tempdir().unwrap();
    let (stderr, j) = render(d.path(), &text[..i]);
    assert!(
        stderr.contains("warning:") && stderr.contains("no light reached the camera"),
        "{stderr}"
    );
    assert_eq!(j["energy"]["primal"]["total"], 0.0);
}

#[test]
fn the_json_says_what_the_steady_image_integrates() {
    let d = tempfile::tempdir().unwrap();
    let (_, j) = render(d.path(), &cornell_text());
    assert_eq!(j["steady"]["mode"], "window", "{}", j["steady"]);
    let cut = j["steady"]["opl_cut"].as_f64().unwrap();
    // the Cornell window ends at 3.6 + 200 × 0.06 = 15.6 m (delta pulse: no reach)
    assert!((15.6..15.7).contains(&cut), "{cut}");
    assert!(j["energy"]["primal"]["after_pilot_paths"].as_u64().unwrap() > 0);

    let scene = d.path().join("full.toml");
    std::fs::write(&scene, cornell_text()).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_dtr"))
        .arg("render")
        .arg(&scene)
        .arg("-o")
        .arg(d.path().join("full"))
        .args(["--spp", "1", "--quiet", "--steady", "full"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let j: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.path().join("full.json")).unwrap()).unwrap();
    assert_eq!(j["steady"]["mode"], "full");
    assert!(j["steady"]["opl_cut"].is_null());
    assert_eq!(j["energy"]["primal"]["after_pilot_paths"], 0);
}
