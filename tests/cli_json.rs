//! What the run JSON says about how the render ran.

use crate::common;
use common::dtr;

/// `--scalar --diff` runs the 8-wide Dual8 kernel (there is no scalar derivative kernel),
/// and the JSON said `"lanes": 1` (issue 10).
#[test]
fn the_json_reports_the_lanes_the_kernel_ran() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/diff_room.toml");
    for (extra, lanes) in [
        (vec!["--scalar"], 1),
        (vec![], 8),
        (vec!["--scalar", "--diff", "room_z"], 8),
    ] {
        let mut args = vec!["render", scene, "--spp", "1", "-q", "-o", "out"];
        args.extend(&extra);
        let o = dtr(&args, tmp.path());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(tmp.path().join("out.json")).unwrap()).unwrap();
        assert_eq!(json["lanes"], lanes, "{extra:?}");
    }
}

/// The JSON's CPU split by phase: tracing and film time are timed on one call in 16
/// (`timing::SampledClock`), so a clock that never reached its timed call (one reset per
/// packet, say) would report no tracing at all. Every phase is present, positive and a
/// plausible share of the CPU time, for the 8-wide and the scalar path tracer and for BDPT.
#[test]
fn the_json_splits_the_cpu_time_by_phase() {
    let tmp = tempfile::tempdir().unwrap();
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell_box.toml");
    for extra in [vec![], vec!["--scalar"], vec!["--integrator", "bdpt"]] {
        let mut args = vec!["render", scene, "--spp", "4", "--threads", "1", "-q", "-o", "out"];
        args.extend(&extra);
        let o = dtr(&args, tmp.path());
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let json: serde_json::Value =
            serde_json::from_slice(&std::fs::read(tmp.path().join("out.json")).unwrap()).unwrap();
        let phase = |k: &str| json["phase_seconds"][k].as_f64().unwrap_or(f64::NAN);
        let (tracing, shading, film) = (phase("tracing"), phase("shading"), phase("film"));
        let cpu = json["cpu_seconds"].as_f64().unwrap();
        let sum = tracing + shading + film;
        assert!(
            tracing > 0.05 * cpu && film > 0.0 && shading > 0.0,
            "{extra:?}: phases {tracing} (tracing), {shading} (shading), {film} (film) of {cpu} CPU-s"
        );
        assert!(
            (sum - cpu).abs() <= 0.25 * cpu,
            "{extra:?}: the phases add up to {sum} of {cpu} CPU-s"
        );
    }
}
