//! `dtr render --shard I/N` and `dtr merge` (src/cli/shard_set.rs): the merged output set is
//! the whole render's up to float reordering (tests/shards.rs has the bounds; here the CLI's
//! plumbing: files, derivatives, JSON), and shards that do not belong together are refused
//! before anything is written.

use crate::common;
use common::dtr;
use std::path::Path;
use std::process::Output;

fn ok(o: Output) -> Output {
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    o
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn npy(path: &Path) -> Vec<f32> {
    common::npy(path).1
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap()
}

const SCENE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/silhouette_slide.toml");

fn render(dir: &Path, out: &str, extra: &[&str]) {
    let mut args = vec![
        "render",
        SCENE,
        "--spp",
        "3",
        "--spp-boundary",
        "2",
        "--diff",
        "cube_x",
        "-q",
        "-o",
        out,
    ];
    args.extend(extra);
    ok(dtr(&args, dir));
}

#[test]
fn merged_shards_are_the_whole_render() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    render(dir, "whole", &[]);
    for i in 0..3 {
        render(dir, &format!("s{i}"), &["--shard", &format!("{i}/3")]);
    }
    ok(dtr(&["merge", "s2", "s0.json", "s1.npy", "-o", "merged", "-q"], dir));
    for file in ["npy", "d_cube_x.npy"] {
        let (w, m) = (
            npy(&dir.join(format!("whole.{file}"))),
            npy(&dir.join(format!("merged.{file}"))),
        );
        assert_eq!(w.len(), m.len());
        let scale = w.iter().fold(0.0f32, |a, v| a.max(v.abs()));
        assert!(scale > 0.0, "{file} is empty");
        for (a, b) in w.iter().zip(&m) {
            assert!((a - b).abs() <= 1e-5 * scale, "{file}: {a} vs {b}");
        }
    }
    let (w, m) = (json(&dir.join("whole.json")), json(&dir.join("merged.json")));
    assert_eq!(w["paths"], m["paths"]);
    assert_eq!(w["identity"], m["identity"]);
    assert_eq!(m["merged"]["shards"].as_array().unwrap().len(), 3);
    assert!(m.get("shard").is_none());
    let e = |v: &serde_json::Value, k: &str| v["energy"]["primal"][k].as_f64().unwrap();
    for k in ["inside", "after", "total"] {
        assert!((e(&w, k) - e(&m, k)).abs() <= 1e-9 * e(&w, "total"), "energy.{k}");
    }
    let files: Vec<String> = serde_json::from_value(m["files"].clone()).unwrap();
    assert_eq!(files, ["merged.npy", "merged.d_cube_x.npy", "merged.json"]);
    // the merged JSON holds a render's fields, not a shard's: it carried shard 0's
    // files_sha256 (its file names and digests) until the forty-third session
    let keys = |v: &serde_json::Value| {
        v.as_object()
            .unwrap()
            .keys()
            .cloned()
            .collect::<std::collections::BTreeSet<_>>()
    };
    let mut want = keys(&w);
    want.remove("shard");
    want.insert("merged".into());
    assert_eq!(keys(&m), want);
    // each shard counts its own boundary evaluations: they add up to the whole render's
    // (every shard reported the whole render's edge_directed and light_directed before)
    let shards: Vec<serde_json::Value> = (0..3).map(|i| json(&dir.join(format!("s{i}.json")))).collect();
    for k in ["samples", "edge_directed", "light_directed", "valid_segments"] {
        let of = |v: &serde_json::Value| v["boundary"]["secondary"][k].as_u64().unwrap();
        assert!(of(&w) > 0, "{k}");
        assert_eq!(shards.iter().map(of).sum::<u64>(), of(&w), "boundary.secondary.{k}");
    }
}

#[test]
fn shards_that_do_not_belong_together_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for i in 0..2 {
        render(dir, &format!("s{i}"), &["--shard", &format!("{i}/2")]);
    }
    render(dir, "other_seed", &["--shard", "1/2", "--seed", "99"]);
    render(dir, "of3", &["--shard", "1/3"]);
    render(dir, "plain", &[]);
    let cases: [(&[&str], &str); 6] = [
        (&["s0"], "missing shard(s) 1/2"),
        (&["s0", "s1", "s1"], "given twice"),
        (&["s0", "other_seed"], "identity.seed differs"),
        (&["s0", "of3"], "not shards of one split"),
        (&["s0", "plain"], "is shard 0/1"),
        (&["s0", "nothing"], "nothing.json"),
    ];
    for (shards, message) in cases {
        let mut args = vec!["merge"];
        args.extend(shards);
        args.extend(["-o", "out"]);
        let o = dtr(&args, dir);
        assert!(!o.status.success(), "{shards:?} merged");
        assert!(stderr(&o).contains(message), "{shards:?}: {}", stderr(&o));
        assert!(!dir.join("out.npy").exists() && !dir.join("out.json").exists());
    }
    // the merge never writes over a shard
    let before = std::fs::read(dir.join("s0.npy")).unwrap();
    let o = dtr(&["merge", "s0", "s1", "-o", "s0"], dir);
    assert!(!o.status.success());
    assert!(stderr(&o).contains("would replace the input"), "{}", stderr(&o));
    assert_eq!(std::fs::read(dir.join("s0.npy")).unwrap(), before);
    // bad --shard values
    for bad in ["2/2", "1/0", "x"] {
        let o = dtr(&["render", SCENE, "--shard", bad, "-o", "bad"], dir);
        assert!(!o.status.success());
        assert!(stderr(&o).contains("I/N"), "{}", stderr(&o));
    }
}

/// Renders shards 0/2 and 1/2, then merges them with s1.json replaced by each edit `edits`
/// makes of it (a label, the edited JSON, what stderr must say): each is refused with exit
/// status 2 naming s1.json and the message, and nothing is written; the shards as rendered
/// then merge.
fn edited_shards_are_refused(edits: impl Fn(&serde_json::Value) -> Vec<(String, serde_json::Value, String)>) {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for i in 0..2 {
        render(dir, &format!("s{i}"), &["--shard", &format!("{i}/2")]);
    }
    let original = std::fs::read_to_string(dir.join("s1.json")).unwrap();
    for (label, j, message) in edits(&serde_json::from_str(&original).unwrap()) {
        std::fs::write(dir.join("s1.json"), j.to_string()).unwrap();
        let o = dtr(&["merge", "s0", "s1", "-o", "out"], dir);
        assert_eq!(o.status.code(), Some(2), "{label}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("s1.json") && stderr(&o).contains(&message),
            "{label}: {}",
            stderr(&o)
        );
        assert!(!dir.join("out.npy").exists() && !dir.join("out.json").exists());
    }
    std::fs::write(dir.join("s1.json"), original).unwrap();
    ok(dtr(&["merge", "s0", "s1", "-o", "out", "-q"], dir));
}

/// A shard's JSON claiming a film far larger than its files is refused with exit 2, naming
/// the file that does not hold it, and leaves nothing behind. Before, the merge allocated
/// the claimed film (4 TB here) before reading a file and aborted (exit 134), leaving its
/// lock file.
#[test]
fn a_shard_claiming_a_huge_film_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for i in 0..2 {
        render(dir, &format!("s{i}"), &["--shard", &format!("{i}/2")]);
    }
    let mut j = json(&dir.join("s0.json"));
    j["shape"] = serde_json::json!([4096, 4096, 20000, 3]);
    j["time_axis"]["bins"] = serde_json::json!(20000);
    std::fs::write(dir.join("s0.json"), j.to_string()).unwrap();
    let o = dtr(&["merge", "s0", "s1", "-o", "out"], dir);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("s0.npy") && stderr(&o).contains("[4096, 4096, 20000, 3]"),
        "{}",
        stderr(&o)
    );
    let left: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter(|n| !n.starts_with("s0") && !n.starts_with("s1"))
        .collect();
    assert!(left.is_empty(), "{left:?}");
}

/// A shard's film whose bytes are not those its render wrote is refused with exit 2, naming
/// the file: one float flipped to 3.4·10³⁸ on disk, or the .npy of a render at another seed
/// copied over it. Before, both merged with exit 0 (the JSON was checked, the films not).
/// The suffixes of the files in `dir` named `STEM.…`, sorted.
fn suffixes(dir: &Path, stem: &str) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| {
            let name = e.unwrap().file_name().to_string_lossy().into_owned();
            name.strip_prefix(&format!("{stem}.")).map(str::to_string)
        })
        .collect();
    v.sort();
    v
}

/// Shards renamed after their render (collected from nodes under new names, the same bytes)
/// merge to the same films as under their own names; before, they were refused as "not
/// written by `dtr render --shard I/N` of this version". And `dtr merge --preview` writes
/// the files `dtr render --preview` writes: before, it left out PREFIX.steady.npy and
/// PREFIX.d_NAME.png. Both found by an independent sweep.
#[test]
fn renamed_shards_merge_and_a_merges_previews_are_a_renders() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for i in 0..2 {
        render(dir, &format!("s{i}"), &["--shard", &format!("{i}/2")]);
    }
    ok(dtr(&["merge", "s0", "s1", "-o", "kept", "-q"], dir));
    for suffix in suffixes(dir, "s1") {
        std::fs::rename(dir.join(format!("s1.{suffix}")), dir.join(format!("node1.{suffix}"))).unwrap();
    }
    ok(dtr(&["merge", "s0", "node1", "-o", "merged", "-q", "--preview"], dir));
    for file in ["npy", "d_cube_x.npy"] {
        assert_eq!(
            npy(&dir.join(format!("kept.{file}"))),
            npy(&dir.join(format!("merged.{file}"))),
            "{file}"
        );
    }
    render(dir, "whole", &["--preview"]);
    let merged = suffixes(dir, "merged");
    assert_eq!(merged, suffixes(dir, "whole"));
    assert!(
        merged.contains(&"steady.npy".to_string()) && merged.contains(&"d_cube_x.png".to_string()),
        "{merged:?}"
    );
}

#[test]
fn a_shard_whose_film_was_damaged_or_replaced_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for i in 0..2 {
        render(dir, &format!("s{i}"), &["--shard", &format!("{i}/2")]);
    }
    render(dir, "other", &["--shard", "1/2", "--seed", "5"]);
    let original = std::fs::read(dir.join("s1.npy")).unwrap();
    let mut flipped = original.clone();
    let at = flipped.len() - 4 * 7;
    flipped[at..at + 4].copy_from_slice(&f32::MAX.to_le_bytes());
    let other = std::fs::read(dir.join("other.npy")).unwrap();
    assert_ne!(other, original);
    for (label, bytes) in [("flipped", flipped), ("another seed's", other)] {
        std::fs::write(dir.join("s1.npy"), &bytes).unwrap();
        let o = dtr(&["merge", "s0", "s1", "-o", "out"], dir);
        assert_eq!(o.status.code(), Some(2), "{label}: {}", stderr(&o));
        assert!(
            stderr(&o).contains("s1.npy: not the file this shard's render wrote"),
            "{label}: {}",
            stderr(&o)
        );
        assert!(!dir.join("out.npy").exists(), "{label}");
    }
    std::fs::write(dir.join("s1.npy"), &original).unwrap();
    ok(dtr(&["merge", "s0", "s1", "-o", "out", "-q"], dir));
}

/// A shard's JSON whose tallies were changed or damaged is refused, naming the file and the
/// field, before anything is written. Before, a shard with `"paths": -5` and a negative
/// energy total merged with exit 0 (the negative count read as 0, the energy summed).
#[test]
fn a_shard_with_tampered_tallies_is_refused() {
    let cases: [(&str, serde_json::Value, &str); 5] = [
        ("/paths", serde_json::json!(-5), "field \"paths\": expected a count"),
        ("/rays", serde_json::json!(1.5), "field \"rays\": expected a count"),
        ("/wall_seconds", serde_json::json!(-1.0), "field \"wall_seconds\""),
        (
            "/energy/primal/total",
            serde_json::json!(-3.0),
            "field \"energy.primal.total\": expected a finite number >= 0",
        ),
        (
            "/energy/derivatives/0/inside",
            serde_json::json!("many"),
            "field \"energy.derivatives.0.inside\"",
        ),
    ];
    edited_shards_are_refused(|original| {
        cases
            .iter()
            .map(|(pointer, value, message)| {
                let mut j = original.clone();
                *j.pointer_mut(pointer).unwrap_or_else(|| panic!("no {pointer}")) = value.clone();
                (pointer.to_string(), j, message.to_string())
            })
            .collect()
    });
}

/// A shard's JSON that lacks a tally the merge adds up is refused, naming the file and the
/// field, before anything is written. Before, a missing tally counted 0: without "paths" or
/// "energy.primal.total" two shards merged with exit 0 into a record of half the render.
#[test]
fn a_shard_with_a_missing_tally_is_refused() {
    let cases = [
        ("", "paths"),
        ("", "wall_seconds"),
        ("/phase_seconds", "tracing"),
        ("/energy/primal", "total"),
        ("/energy/primal", "after_pilot_paths"),
        ("/energy/derivatives/0", "inside"),
        ("/energy", "derivatives"),
    ];
    edited_shards_are_refused(|original| {
        cases
            .iter()
            .map(|(parent, key)| {
                let mut j = original.clone();
                let removed = j
                    .pointer_mut(parent)
                    .and_then(|p| p.as_object_mut())
                    .and_then(|o| o.remove(*key));
                assert!(removed.is_some(), "no {parent}/{key}");
                let field = format!("{}.{key}", parent.trim_start_matches('/').replace('/', "."));
                let field = field.trim_start_matches('.').to_string();
                let message = format!("field \"{field}\": missing");
                (field, j, message)
            })
            .collect()
    });
}

/// Rewrites values of the shard film `dir/file` (`(index, value)`) and records the file's new
/// SHA-256 in the shard's JSON `dir/json`, as someone who edits a shard on purpose would.
fn tamper(dir: &Path, json_name: &str, file: &str, values: &[(usize, f32)]) {
    use sha2::Digest;
    let mut bytes = std::fs::read(dir.join(file)).unwrap();
    assert_eq!(&bytes[..6], b"\x93NUMPY");
    let data = 10 + u16::from_le_bytes([bytes[8], bytes[9]]) as usize;
    for &(i, v) in values {
        bytes[data + 4 * i..data + 4 * i + 4].copy_from_slice(&v.to_le_bytes());
    }
    std::fs::write(dir.join(file), &bytes).unwrap();
    let mut meta = json(&dir.join(json_name));
    meta["files_sha256"][file] = format!("{:x}", sha2::Sha256::digest(&bytes)).into();
    std::fs::write(dir.join(json_name), serde_json::to_vec(&meta).unwrap()).unwrap();
}

/// A shard whose transient or steady image holds negative values is refused even when its
/// JSON records the edited file's SHA-256, naming the file, how many values are negative and
/// the lowest, before anything is written (exit 2); a derivative film may be negative, but
/// not NaN. Before, a shard's .npy rewritten with -1 everywhere (its hash recomputed) merged
/// with exit 0 (independent audit, `mt_neg_npy`).
#[test]
fn a_shard_with_a_negative_transient_is_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for i in 0..2 {
        render(dir, &format!("s{i}"), &["--shard", &format!("{i}/2")]);
    }
    let keep: Vec<Vec<u8>> = ["s1.json", "s1.npy", "s1.steady.npy", "s1.d_cube_x.npy"]
        .iter()
        .map(|f| std::fs::read(dir.join(f)).unwrap())
        .collect();
    let restore = || {
        for (f, b) in ["s1.json", "s1.npy", "s1.steady.npy", "s1.d_cube_x.npy"]
            .iter()
            .zip(&keep)
        {
            std::fs::write(dir.join(f), b).unwrap();
        }
    };
    for (file, said) in [("s1.npy", "s1.npy: 3 of "), ("s1.steady.npy", "s1.steady.npy: 3 of ")] {
        tamper(dir, "s1.json", file, &[(0, -1.0), (5, -2.5), (9, -0.25)]);
        let o = dtr(&["merge", "s0", "s1", "-o", "out"], dir);
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{file}: {e}");
        assert!(
            e.contains(said)
                && e.contains("are negative (the lowest is -2.5e0); expected values >= 0, as a render writes them"),
            "{file}: {e}"
        );
        assert!(!e.contains("dtr-staging"), "{e}");
        let left: Vec<_> = std::fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with("out"))
            .collect();
        assert!(left.is_empty(), "{file}: {left:?}");
        restore();
    }
    // a derivative: negative is fine, NaN is not
    tamper(dir, "s1.json", "s1.d_cube_x.npy", &[(0, -1.0)]);
    ok(dtr(&["merge", "s0", "s1", "-o", "out", "-q"], dir));
    tamper(dir, "s1.json", "s1.d_cube_x.npy", &[(3, f32::NAN)]);
    let o = dtr(&["merge", "s0", "s1", "-o", "out2"], dir);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("s1.d_cube_x.npy: value 3 of") && stderr(&o).contains("(NaN; 1 of "),
        "{}",
        stderr(&o)
    );
    restore();
}

/// Shards whose films, each finite, add up past the largest 32-bit float are refused naming
/// them, before anything is written (exit 2). Before, two shards of 3·10³⁸ everywhere (their
/// hashes recomputed) failed writing the merged .npy with exit 1, an internal failure
/// (independent audit, `mt_huge_npy`).
#[test]
fn shards_whose_films_add_up_past_32_bit_floats_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path();
    for i in 0..2 {
        render(dir, &format!("s{i}"), &["--shard", &format!("{i}/2")]);
    }
    for s in ["s0", "s1"] {
        tamper(dir, &format!("{s}.json"), &format!("{s}.npy"), &[(4, 3e38)]);
    }
    let o = dtr(&["merge", "s0", "s1", "-o", "out"], dir);
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(2), "{e}");
    assert!(
        e.contains("s0.npy, ") && e.contains("s1.npy: the shards' films add up past the largest 32-bit float"),
        "{e}"
    );
    assert!(!e.contains("dtr-staging") && !dir.join("out.npy").exists(), "{e}");
}
