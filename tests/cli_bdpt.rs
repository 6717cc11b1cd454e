//! `dtr render --integrator bdpt --strategies` writes the transient and one transient per
//! (s, t) strategy, and records the integrator in PREFIX.json.

use std::process::Command;

#[test]
fn strategies_files_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let prefix = dir.path().join("out");
    let scene = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/confocal_plane.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_dtr"))
        .arg("render")
        .arg(&scene)
        .arg("-o")
        .arg(&prefix)
        .args(["--spp", "1", "--quiet", "--integrator", "bdpt", "--strategies"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    // max_bounces = 1: (0, 2), then (0, 3), (1, 2), (2, 1); (1, 1) is left out
    for name in [
        "out.npy",
        "out.s0_t2.npy",
        "out.s0_t3.npy",
        "out.s1_t2.npy",
        "out.s2_t1.npy",
    ] {
        assert!(dir.path().join(name).exists(), "{name} missing");
    }
    assert!(!dir.path().join("out.s1_t1.npy").exists());
    let json = std::fs::read_to_string(dir.path().join("out.json")).unwrap();
    assert!(json.contains("\"integrator\": \"bdpt\""), "{json}");
}
