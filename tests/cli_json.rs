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
