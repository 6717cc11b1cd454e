//! `dtr render` of NLOS captures end to end: the files it writes (the transient, the noisy copy,
//! HDF5 in y-tal's layout read back here), the JSON's `nlos` block, and bad `[nlos]` input
//! refused with the file and the field named, no panic and no output.

use crate::common;
use std::path::{Path, PathBuf};

fn scene_text(name: &str) -> String {
    std::fs::read_to_string(common::scene_path(name)).unwrap()
}

/// Writes `text` as a scene next to the scenes folder's meshes (so OBJ paths resolve).
fn scene_file(dir: &Path, name: &str, text: &str) -> PathBuf {
    std::fs::create_dir_all(dir.join("meshes")).unwrap();
    std::fs::copy(
        common::scene_path("meshes/curved_wall.obj"),
        dir.join("meshes/curved_wall.obj"),
    )
    .unwrap();
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// A confocal capture with noise writes PREFIX.{npy, json, h5, noisy.npy, noisy.h5}; the noisy
/// copy is whole photon counts with the mean the model gives; the JSON says the scan, the
/// relay-leg convention and the layout.
#[test]
fn confocal_capture_writes_its_files() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_file(
        dir.path(),
        "occ.toml",
        &scene_text("nlos_occluder.toml").replace("grid = [16, 16]", "grid = [6, 5]"),
    );
    let out = common::dtr(
        &["render", scene.to_str().unwrap(), "-o", "cap", "--spp", "64", "--quiet"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("cap"))
        .collect();
    names.sort();
    let mut expected = vec!["cap.json", "cap.noisy.npy", "cap.npy"];
    if cfg!(feature = "hdf5") {
        expected.extend(["cap.h5", "cap.noisy.h5"]);
    }
    expected.sort();
    assert_eq!(names, expected);
    let (shape, clean) = common::npy(&dir.path().join("cap.npy"));
    assert_eq!(shape, vec![5, 6, 128, 1]);
    let (nshape, noisy) = common::npy(&dir.path().join("cap.noisy.npy"));
    assert_eq!(nshape, shape);
    assert!(noisy.iter().all(|&c| c >= 0.0 && c.fract() == 0.0));
    // E[counts] = 1e6 · I + 0.01 per bin: the sums agree within 5 Poisson standard deviations
    let expect: f64 = clean.iter().map(|&v| 1e6 * v as f64 + 0.01).sum();
    let got: f64 = noisy.iter().map(|&v| v as f64).sum();
    assert!(expect > 1000.0);
    assert!((got - expect).abs() < 5.0 * expect.sqrt(), "{got} counts vs {expect}");
    let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("cap.json")).unwrap()).unwrap();
    let n = &meta["nlos"];
    assert_eq!(n["scan"], "confocal");
    assert_eq!(n["relay_legs"], "excluded");
    assert_eq!(n["sensor_grid"], serde_json::json!([6, 5]));
    assert!(n["time_of_flight"].as_str().unwrap().contains("left out"));
    assert_eq!(n["noise"]["photons_per_unit"], 1e6);
    #[cfg(feature = "hdf5")]
    {
        let f = hdf5::File::open(dir.path().join("cap.h5")).unwrap();
        let h = f.dataset("H").unwrap();
        assert_eq!(h.shape(), vec![128, 6, 5]);
        let hv: Vec<f32> = h.read_raw().unwrap();
        // H[t, ix, iy] = npy[iy, ix, t, 0]
        for (t, ix, iy) in [(40, 2, 3), (70, 5, 0), (10, 0, 4)] {
            assert_eq!(hv[(t * 6 + ix) * 5 + iy], clean[(iy * 6 + ix) * 128 + t]);
        }
        assert_eq!(f.dataset("H_format").unwrap().read_scalar::<i32>().unwrap(), 1);
        assert_eq!(
            f.dataset("sensor_grid_format").unwrap().read_scalar::<i32>().unwrap(),
            2
        );
        assert_eq!(f.dataset("sensor_grid_xyz").unwrap().shape(), vec![6, 5, 3]);
        assert_eq!(f.dataset("delta_t").unwrap().read_scalar::<f64>().unwrap(), 0.02);
        assert_eq!(f.dataset("t_start").unwrap().read_scalar::<f64>().unwrap(), 1.0);
        assert!(
            !f.dataset("t_accounts_first_and_last_bounces")
                .unwrap()
                .read_scalar::<bool>()
                .unwrap()
        );
        let spad: Vec<f32> = f.dataset("sensor_xyz").unwrap().read_raw().unwrap();
        assert_eq!(spad, vec![-1.5, -0.5, 2.0]);
        // grid points lie on the wall (z = 0) in file coordinates, normals +z
        let xyz: Vec<f32> = f.dataset("sensor_grid_xyz").unwrap().read_raw().unwrap();
        let nrm: Vec<f32> = f.dataset("sensor_grid_normals").unwrap().read_raw().unwrap();
        assert!(
            xyz.chunks(3)
                .all(|p| p[2].abs() < 1e-6 && p[0].abs() < 1.0 && p[1].abs() < 1.0)
        );
        assert!(nrm.chunks(3).all(|n| (n[2] - 1.0).abs() < 1e-6));
        // ix runs along +x: the first two points differ in x by the cell width 2/6
        assert!((xyz[3 * 5] - xyz[0] - 2.0 / 6.0).abs() < 1e-5, "{:?}", &xyz[..18]);
        let noisy_h5: Vec<f32> = hdf5::File::open(dir.path().join("cap.noisy.h5"))
            .unwrap()
            .dataset("H")
            .unwrap()
            .read_raw()
            .unwrap();
        assert_eq!(noisy_h5.iter().sum::<f32>(), noisy.iter().sum::<f32>());
    }
}

/// An exhaustive capture on the curved wall with relay legs included: [L, S, T, C] in the npy,
/// (T, Lx, Ly, Sx, Sy) in the HDF5 (every entry), and the convention in both. The window
/// holds only light from the small hidden box: at 16 spp (128 paths per laser point) a
/// capture finds it at some seeds and not at others (nothing at seeds 0, 1 and 5 of 0–9), at
/// 1024 spp at every seed tried (0–9, either sampler: the JSON's energy inside 2.4–4.2·10⁻⁴),
/// so the layout is checked on a capture that holds light whatever the seed.
#[test]
fn exhaustive_capture_layout() {
    let dir = tempfile::tempdir().unwrap();
    let text = scene_text("nlos_curved_wall.toml")
        .replace(
            "scan = \"confocal\"",
            "scan = \"exhaustive\"\nlaser_grid = [2, 3]\nrelay_legs = \"included\"",
        )
        .replace("grid = [16, 16]", "grid = [4, 2]")
        .replace("start_opl = 1.0", "start_opl = 4.0");
    let scene = scene_file(dir.path(), "ex.toml", &text);
    let out = common::dtr(
        &[
            "render",
            scene.to_str().unwrap(),
            "-o",
            "ex",
            "--spp",
            "1024",
            "--quiet",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (shape, data) = common::npy(&dir.path().join("ex.npy"));
    assert_eq!(shape, vec![6, 8, 128, 1]);
    assert!(data.iter().sum::<f32>() > 0.0);
    let meta: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("ex.json")).unwrap()).unwrap();
    assert_eq!(meta["nlos"]["scan"], "exhaustive");
    assert_eq!(meta["nlos"]["relay_legs"], "included");
    assert_eq!(meta["nlos"]["laser_grid"], serde_json::json!([2, 3]));
    #[cfg(feature = "hdf5")]
    {
        let f = hdf5::File::open(dir.path().join("ex.h5")).unwrap();
        let h = f.dataset("H").unwrap();
        assert_eq!(h.shape(), vec![128, 2, 3, 4, 2]);
        let hv: Vec<f32> = h.read_raw().unwrap();
        // H[t, jx, jy, ix, iy] = npy[jy * 2 + jx, iy * 4 + ix, t, 0], for every entry
        let mut h_of_npy = vec![f32::NAN; hv.len()];
        for t in 0..128 {
            for (jx, jy, ix, iy) in (0..2).flat_map(|jx| {
                (0..3).flat_map(move |jy| (0..4).flat_map(move |ix| (0..2).map(move |iy| (jx, jy, ix, iy))))
            }) {
                let (j, i) = (jy * 2 + jx, iy * 4 + ix);
                h_of_npy[(((t * 2 + jx) * 3 + jy) * 4 + ix) * 2 + iy] = data[(j * 8 + i) * 128 + t];
            }
        }
        assert_eq!(hv, h_of_npy);
        assert_eq!(f.dataset("H_format").unwrap().read_scalar::<i32>().unwrap(), 2);
        assert!(
            f.dataset("t_accounts_first_and_last_bounces")
                .unwrap()
                .read_scalar::<bool>()
                .unwrap()
        );
        assert_eq!(f.dataset("laser_grid_xyz").unwrap().shape(), vec![2, 3, 3]);
    }
}

/// Runs `dtr render` on `text` and returns its error; checks there is no panic and no output.
fn refused(text: &str, extra: &[&str]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_file(dir.path(), "bad.toml", text);
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "-o",
        "out/x",
        "--spp",
        "1",
        "--quiet",
    ];
    args.extend(extra);
    std::fs::create_dir(dir.path().join("out")).unwrap();
    let out = common::dtr(&args, dir.path());
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(!out.status.success(), "accepted: {text}");
    assert!(!err.contains("panicked"), "{err}");
    assert_eq!(std::fs::read_dir(dir.path().join("out")).unwrap().count(), 0, "{err}");
    assert!(err.contains("bad.toml"), "{err}");
    err
}

#[test]
fn bad_nlos_input_names_the_field() {
    let base = scene_text("nlos_occluder.toml");
    let cases: Vec<(String, Vec<&str>)> = vec![
        (
            base.replace("wall = \"wall\"", "wall = \"wal\""),
            vec!["nlos: field 'wall'", "no shape named \"wal\""],
        ),
        (
            base.replace("laser = \"laser\"\nscan", "laser = \"lazer\"\nscan"),
            vec!["nlos: field 'laser'", "no emitter"],
        ),
        (
            base.replace("grid = [16, 16]", "grid = [0, 16]"),
            vec!["nlos: field 'grid[0]'", "at least 1"],
        ),
        (
            base.replace("grid = [16, 16]", "grid = [16, 16, 2]"),
            vec!["nlos: field 'grid'", "length 2"],
        ),
        (
            base.replace("grid = [16, 16]", ""),
            vec!["nlos: field 'grid'", "missing"],
        ),
        (
            base.replace("grid = [16, 16]", "grid = [4, 4]\npoints = [[0, 0, 0]]"),
            vec!["nlos: field 'points'", "not both"],
        ),
        (
            base.replace("grid = [16, 16]", "points = [[0, 0]]"),
            vec!["nlos: field 'points[0]'", "[x, y, z]"],
        ),
        (
            base.replace("grid = [16, 16]", "points = [[5.0, 0, 0]]"),
            vec!["nlos: field 'points[0]'", "misses the wall"],
        ),
        (
            base.replace("grid = [16, 16]", "grid = [4, 4]\nlaser_grid = [2, 2]"),
            vec!["nlos: field 'laser_grid'", "confocal"],
        ),
        (
            base.replace("scan = \"confocal\"", "scan = \"diagonal\""),
            vec!["nlos: field 'scan'", "confocal"],
        ),
        (
            base.replace("relay_legs", "relay_leg")
                .replace("scan = \"confocal\"", "scan = \"confocal\"\nrelay_legs = \"both\""),
            vec!["nlos: field 'relay_legs'"],
        ),
        (
            base.replace("photons_per_unit = 1e6", "photons_per_unit = -1"),
            vec!["nlos.noise: field 'photons_per_unit'", "> 0"],
        ),
        (
            base.replace("dark_counts = 0.01", "dark_counts = nan"),
            vec!["dark_counts"],
        ),
        (
            base.replace("channels = \"mono\"", "channels = \"mono\"\nunwarp = true"),
            vec!["film: field 'unwarp'", "relay_legs"],
        ),
        (
            base.replace(
                "[nlos]",
                "[[emitter]]\nname = \"lamp\"\ntype = \"point\"\nposition = [0, 0, 1]\nintensity = 1.0\n\n[nlos]",
            ),
            vec!["emitter[1] \"lamp\"", "laser alone"],
        ),
        (
            base.replace(
                "[nlos]",
                "[[emitter]]\nname = \"lamp\"\ntype = \"point\"\nposition = [0, 0, 1]\nintensity = 1.0\n\n[nlos]",
            )
            .replace("laser = \"laser\"\nscan", "laser = \"lamp\"\nscan"),
            vec!["nlos: field 'laser'", "not a laser"],
        ),
        (
            // a glossy hidden box in the laser's beams, half way from the laser to the wall
            base.replace(
                "name = \"hidden\"\ntype = \"diffuse\"\nalbedo = 0.7",
                "name = \"hidden\"\ntype = \"roughconductor\"\nroughness = 0.3",
            )
            .replace("value = 0.5", "value = -0.75")
            .replace("value = 0.2", "value = 0.0")
            .replace("value = 0.9", "value = 1.0"),
            vec![
                "[nlos] laser: aimed at laser point 86 of 256",
                "the beam is stopped before the wall",
                "lands on material \"hidden\" of type roughconductor",
            ],
        ),
    ];
    for (text, want) in &cases {
        let err = refused(text, &[]);
        for w in want {
            assert!(err.contains(w), "expected {w:?} in: {err}");
        }
    }
    // photon counts beyond float32: exit 1 naming a staging file before 2026-11-30 (the
    // laser's power at its largest, 1e18: a power of 1e38 is refused when the scene loads)
    let err = refused(
        &base,
        &["--set", "laser_power=1e18", "--set", "nlos.noise.photons_per_unit=1e30"],
    );
    assert!(
        err.contains("nlos.noise.photons_per_unit") && err.contains("beyond what a float32 count holds"),
        "{err}"
    );
}

/// What a capture cannot do is refused before rendering: derivatives with respect to the
/// relay wall's position (its sensor and laser points are fixed). The hidden scene's geometry
/// is differentiated (with its boundary term: tests/nlos_boundary_fd.rs), with either
/// integrator.
#[test]
fn unsupported_renders_are_refused() {
    let base = scene_text("nlos_occluder.toml");
    let wall = format!(
        "{base}\n[[param]]\nname = \"wall_z\"\nkind = \"translate\"\nshape = \"wall\"\naxis = \"z\"\nvalue = 0.0\n"
    );
    let err = refused(&wall, &["--diff", "hidden_albedo,wall_z"]);
    // named, not numbered (it said "parameter 2")
    assert!(
        err.contains("--diff wall_z: the parameter moves the relay wall \"wall\""),
        "{err}"
    );
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_file(dir.path(), "occ.toml", &base);
    let out = common::dtr(
        &[
            "render",
            scene.to_str().unwrap(),
            "-o",
            "occ",
            "--spp",
            "16",
            "--quiet",
            "--diff",
            "hidden_x",
        ],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (shape, data) = common::npy(&dir.path().join("occ.d_hidden_x.npy"));
    assert_eq!(shape, vec![16, 16, 128, 1]);
    assert!(data.iter().all(|v| v.is_finite()) && data.iter().any(|&v| v != 0.0));
    // BDPT
    let args = [
        "render",
        scene.to_str().unwrap(),
        "-o",
        "occ_bdpt",
        "--spp",
        "16",
        "--quiet",
    ];
    let out = common::dtr(
        &[&args[..], &["--integrator", "bdpt", "--diff", "hidden_x"]].concat(),
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (shape, data) = common::npy(&dir.path().join("occ_bdpt.d_hidden_x.npy"));
    assert_eq!(shape, vec![16, 16, 128, 1]);
    assert!(data.iter().all(|v| v.is_finite()) && data.iter().any(|&v| v != 0.0));
    let meta: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("occ_bdpt.json")).unwrap()).unwrap();
    assert_eq!(meta["integrator"], "bdpt");
}

/// Explicit sensor points: y-tal's point-list formats ((T, Si) and (N, 3) grids), and
/// `dtr info` describes the capture.
#[test]
fn explicit_points_and_info() {
    let dir = tempfile::tempdir().unwrap();
    let scene = scene_file(dir.path(), "pts.toml", &scene_text("nlos_hidden_patch.toml"));
    let out = common::dtr(
        &["render", scene.to_str().unwrap(), "-o", "pts", "--spp", "64", "--quiet"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let (shape, data) = common::npy(&dir.path().join("pts.npy"));
    assert_eq!(shape, vec![1, 3, 80, 1]);
    assert!(data.iter().sum::<f32>() > 0.0);
    #[cfg(feature = "hdf5")]
    {
        let f = hdf5::File::open(dir.path().join("pts.h5")).unwrap();
        assert_eq!(f.dataset("H").unwrap().shape(), vec![80, 3]);
        let hv: Vec<f32> = f.dataset("H").unwrap().read_raw().unwrap();
        assert_eq!(hv[12 * 3 + 2], data[2 * 80 + 12]);
        assert_eq!(f.dataset("H_format").unwrap().read_scalar::<i32>().unwrap(), 3);
        assert_eq!(
            f.dataset("sensor_grid_format").unwrap().read_scalar::<i32>().unwrap(),
            1
        );
        let xyz: Vec<f32> = f.dataset("sensor_grid_xyz").unwrap().read_raw().unwrap();
        assert_eq!(xyz.len(), 9);
        // the second point as written, [0.3, 0, 0]
        assert!(
            (xyz[3] - 0.3).abs() < 1e-6 && xyz[4].abs() < 1e-6 && xyz[5].abs() < 1e-6,
            "{xyz:?}"
        );
    }
    let info = common::dtr(&["info", scene.to_str().unwrap()], dir.path());
    let text = String::from_utf8_lossy(&info.stdout);
    assert!(
        text.contains("nlos: confocal scan on shape \"wall\": 3 sensor point(s) (explicit)"),
        "{text}"
    );
    assert!(text.contains("relay legs out of the time of flight"), "{text}");
    // max_bounces = 1: the third bounce (laser → spot → patch → sensor point → SPAD)
    assert!(text.contains("paths of up to 3 bounces from laser to SPAD"), "{text}");
    let json = common::dtr(&["info", scene.to_str().unwrap(), "--json"], dir.path());
    let v: serde_json::Value = serde_json::from_slice(&json.stdout).unwrap();
    assert_eq!(v["nlos"]["scan"], "confocal");
    assert_eq!(v["nlos"]["wall"], "wall");
}

/// An exhaustive capture's shards (`--shard I/N`, merged by `dtr merge`) add up to the whole
/// render (up to the order of float additions), a checkpointed render gives its bytes, and a
/// shard writes no HDF5 or noisy copy.
#[test]
fn shards_and_checkpoints_of_a_capture() {
    let dir = tempfile::tempdir().unwrap();
    let text = scene_text("nlos_occluder.toml")
        .replace("scan = \"confocal\"", "scan = \"exhaustive\"")
        .replace("grid = [16, 16]", "grid = [4, 4]");
    let scene = scene_file(dir.path(), "ex.toml", &text);
    let s = scene.to_str().unwrap();
    let run = |args: &[&str]| {
        let out = common::dtr(args, dir.path());
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    };
    run(&["render", s, "-o", "whole", "--spp", "8", "--quiet"]);
    run(&["render", s, "-o", "s0", "--spp", "8", "--shard", "0/2", "--quiet"]);
    run(&["render", s, "-o", "s1", "--spp", "8", "--shard", "1/2", "--quiet"]);
    run(&["merge", "s0", "s1", "-o", "merged"]);
    run(&["render", s, "-o", "ck", "--spp", "8", "--checkpoint", "100", "--quiet"]);
    let (shape, whole) = common::npy(&dir.path().join("whole.npy"));
    assert_eq!(shape, vec![16, 16, 128, 1]);
    assert!(whole.iter().sum::<f32>() > 0.0);
    // shards split the samples: the merge equals the whole render up to the order of the
    // float additions (README, "--shard"; tests/shards.rs): a film entry sums at most
    // spp · 2 · (bounces + 1) terms, each way, in f32
    let merged = common::npy(&dir.path().join("merged.npy")).1;
    let n = 8.0 * 2.0 * (3.0 + 1.0);
    for (i, (m, w)) in merged.iter().zip(&whole).enumerate() {
        let bound = (2.0 * n + 8.0) * f64::from(f32::EPSILON) / 2.0 * w.abs() as f64;
        assert!(
            ((m - w) as f64).abs() <= bound,
            "entry {i}: merged {m} against whole {w}"
        );
    }
    assert_eq!(common::npy(&dir.path().join("ck.npy")).1, whole);
    assert!(!dir.path().join("s0.h5").exists() && !dir.path().join("s0.noisy.npy").exists());
    // the merge writes the capture's files from the sum, as the whole render did: the noisy
    // copy draws each bin's count from the same stream, so only a bin whose mean moved by the
    // sum's rounding across a step of its draw can differ, and then by one count
    let (noisy_whole, noisy_merged) = (
        common::npy(&dir.path().join("whole.noisy.npy")).1,
        common::npy(&dir.path().join("merged.noisy.npy")).1,
    );
    assert_eq!(noisy_whole.len(), noisy_merged.len());
    let moved: Vec<(f32, f32)> = noisy_whole
        .iter()
        .zip(&noisy_merged)
        .filter(|(w, m)| w != m)
        .map(|(w, m)| (*w, *m))
        .collect();
    assert!(
        moved.len() * 1000 <= noisy_whole.len() && moved.iter().all(|(w, m)| (w - m).abs() == 1.0),
        "{} of {} counts differ: {:?}",
        moved.len(),
        noisy_whole.len(),
        &moved[..moved.len().min(8)]
    );
    assert!(noisy_merged.iter().sum::<f32>() > 0.0);
    let meta: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.path().join("merged.json")).unwrap()).unwrap();
    let files = &meta["nlos"]["files"];
    assert!(
        files["noisy_npy"].as_str().unwrap().ends_with("merged.noisy.npy"),
        "{files}"
    );
    #[cfg(feature = "hdf5")]
    {
        assert!(files["hdf5"].as_str().unwrap().ends_with("merged.h5"), "{files}");
        let h = |name: &str| -> Vec<f32> {
            hdf5::File::open(dir.path().join(name))
                .unwrap()
                .dataset("H")
                .unwrap()
                .read_raw()
                .unwrap()
        };
        let (hw, hm) = (h("whole.h5"), h("merged.h5"));
        assert_eq!(hw.len(), hm.len());
        let (sum_h, sum_npy) = (
            hw.iter().map(|&v| v as f64).sum::<f64>(),
            whole.iter().map(|&v| v as f64).sum::<f64>(),
        );
        assert!((sum_h - sum_npy).abs() <= 1e-9 * sum_npy, "{sum_h} against {sum_npy}");
        for (m, w) in hm.iter().zip(&hw) {
            let bound = (2.0 * n + 8.0) * f64::from(f32::EPSILON) / 2.0 * w.abs() as f64;
            assert!(((m - w) as f64).abs() <= bound, "merged H {m} against whole {w}");
        }
        assert_eq!(
            h("merged.noisy.h5").iter().sum::<f32>(),
            noisy_merged.iter().sum::<f32>()
        );
    }
}

/// The merge of a capture's shards makes its HDF5 file and noisy copy from the scene the
/// shards rendered, so it refuses, before writing anything, a scene edited since (naming it)
/// or one it cannot find from where it runs, and `--scene` names the file as rendered.
#[test]
fn a_capture_merge_reads_the_scene_the_shards_rendered() {
    let dir = tempfile::tempdir().unwrap();
    let text = scene_text("nlos_occluder.toml").replace("grid = [16, 16]", "grid = [4, 4]");
    let scene = scene_file(dir.path(), "cap.toml", &text);
    let dtr = |args: &[&str], cwd: &Path| common::dtr(args, cwd);
    for i in 0..2 {
        let shard = format!("{i}/2");
        let out = dtr(
            &[
                "render",
                "cap.toml",
                "-o",
                &format!("s{i}"),
                "--spp",
                "4",
                "--shard",
                &shard,
                "--quiet",
            ],
            dir.path(),
        );
        assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    }
    let left = |prefix: &str| {
        std::fs::read_dir(dir.path())
            .unwrap()
            .any(|e| e.unwrap().file_name().to_string_lossy().starts_with(prefix))
    };
    // from another folder the recorded path "cap.toml" does not reach the scene
    let elsewhere = dir.path().join("elsewhere");
    std::fs::create_dir(&elsewhere).unwrap();
    let out = dtr(&["merge", "../s0", "../s1", "-o", "../far"], &elsewhere);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("s0.json") && err.contains("cap.toml") && err.contains("--scene"),
        "{err}"
    );
    assert!(!left("far"));
    let out = dtr(
        &["merge", "../s0", "../s1", "-o", "../far", "--scene", "../cap.toml"],
        &elsewhere,
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(dir.path().join("far.noisy.npy").exists());
    // an edited scene is not the one rendered
    std::fs::copy(&scene, dir.path().join("as_rendered.toml")).unwrap();
    std::fs::write(&scene, text.replace("photons_per_unit = 1e6", "photons_per_unit = 1e3")).unwrap();
    let out = dtr(&["merge", "s0", "s1", "-o", "edited"], dir.path());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(
        err.contains("cap.toml: not the scene the shards rendered") && err.contains("--scene"),
        "{err}"
    );
    assert!(!left("edited"));
    let out = dtr(
        &["merge", "s0", "s1", "-o", "kept", "--scene", "as_rendered.toml"],
        dir.path(),
    );
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert_eq!(
        std::fs::read(dir.path().join("kept.noisy.npy")).unwrap(),
        std::fs::read(dir.path().join("far.noisy.npy")).unwrap()
    );
}

/// A capture aims its laser at each laser point, so the laser's own `direction` plays no part:
/// it is not refused where that direction would land on a surface that is not diffuse (it was:
/// "its spot lands on material ..."), and the capture does not depend on it (the same bytes,
/// path tracer and BDPT, with a derivative).
#[test]
fn a_captures_laser_direction_plays_no_part() {
    let base = scene_text("nlos_occluder.toml").replace("grid = [16, 16]", "grid = [6, 6]");
    // the occluder made glossy, and the laser's own beam aimed at it
    let glossy = base.replace(
        "name = \"grey\"\ntype = \"diffuse\"\nalbedo = 0.5",
        "name = \"grey\"\ntype = \"roughconductor\"\nroughness = 0.3",
    );
    assert_ne!(glossy, base);
    let aimed = glossy.replace("direction = [1.5, 0.0, -2.0]", "direction = [1.0, 0.0, 0.0]");
    assert_ne!(aimed, glossy);
    let dir = tempfile::tempdir().unwrap();
    for integrator in ["path", "bdpt"] {
        let mut outputs = Vec::new();
        for (name, text) in [("wall_dir.toml", &glossy), ("occluder_dir.toml", &aimed)] {
            let scene = scene_file(dir.path(), name, text);
            let prefix = format!("{integrator}_{name}");
            let out = common::dtr(
                &[
                    "render",
                    scene.to_str().unwrap(),
                    "-o",
                    &prefix,
                    "--spp",
                    "32",
                    "--quiet",
                    "--integrator",
                    integrator,
                    "--diff",
                    "hidden_x",
                ],
                dir.path(),
            );
            assert!(
                out.status.success(),
                "{integrator}, {name}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
            let read = |suffix: &str| std::fs::read(dir.path().join(format!("{prefix}{suffix}"))).unwrap();
            outputs.push((read(".npy"), read(".d_hidden_x.npy")));
        }
        assert!(
            outputs[0].0 == outputs[1].0,
            "{integrator}: the capture depends on the laser's direction"
        );
        assert!(
            outputs[0].1 == outputs[1].1,
            "{integrator}: its derivative depends on the laser's direction"
        );
    }
}

/// An HDF5 capture the file system refuses (each file limited to a size that the transient and
/// the JSON fit in and the capture does not: a full disk without a mount) is exit 3 naming
/// the output asked for, PREFIX.h5, and leaves nothing, for a render and for the merge of its
/// shards. Before, it was exit 1 ("internal failure") with HDF5's message naming the staging
/// folder's `h5.h5.partial` (found with 36 KB free on a tmpfs).
#[cfg(all(unix, feature = "hdf5"))]
#[test]
fn a_refused_hdf5_capture_is_an_output_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let scene = common::scene_path("nlos_occluder.toml");
    let s = scene.to_str().unwrap();
    let render = |prefix: &'static str, shard: Option<&'static str>| {
        let mut v = vec![
            "render",
            s,
            "-q",
            "--threads",
            "1",
            "--spp",
            "1",
            "--set",
            "film.bins=20",
            "--set",
            "nlos.grid=[16, 16]",
            "-o",
            prefix,
        ];
        if let Some(shard) = shard {
            v.extend(["--shard", shard]);
        }
        v
    };
    for (prefix, shard) in [("free", None), ("s0", Some("0/2")), ("s1", Some("1/2"))] {
        let o = common::dtr(&render(prefix, shard), d);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let (mut h5, mut others) = (0, 0);
    for entry in std::fs::read_dir(d).unwrap() {
        let entry = entry.unwrap();
        let name = entry.file_name().to_string_lossy().into_owned();
        let len = entry.metadata().unwrap().len();
        if name == "free.h5" {
            h5 = len;
        } else if name.starts_with("free.") && !name.ends_with(".h5") {
            others = others.max(len);
        }
    }
    let limit = others + 1024;
    assert!(h5 > limit, "the capture ({h5} bytes) must not fit in {limit}");
    for (args, prefix) in [
        (render("n", None), "n"),
        (vec!["merge", "s0", "s1", "-q", "-o", "m"], "m"),
    ] {
        let o = common::dtr_with_file_size_limit(&args, d, limit);
        let e = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(3), "{args:?}: {e}");
        assert!(
            e.contains(&format!("{prefix}.h5")) && e.contains("File too large"),
            "{args:?}: {e}"
        );
        assert!(!e.contains("partial") && !e.contains("dtr-staging"), "{args:?}: {e}");
        let left: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(&format!("{prefix}.")) || n.starts_with(&format!(".{prefix}.")))
            .collect();
        assert!(left.is_empty(), "{args:?} left {left:?}");
    }
}
