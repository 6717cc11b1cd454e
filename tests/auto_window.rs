//! `dtr render --auto-window` (issue 15, src/auto_window.rs): the pilot's OPL bounds hold
//! every path, and the chosen window holds the light's arrival and decay.

use crate::common;

use difftransient::auto_window::{choose_window, opl_bounds};
use difftransient::film::SteadyMode;
use difftransient::{RenderOptions, Scene, render};

/// A render over the pilot's whole span with no cut: nothing may arrive before or after it,
/// or the bound of `opl_bounds` is wrong.
#[test]
fn the_pilot_span_holds_every_path() {
    for (name, bounces) in [
        ("cornell_box.toml", 8.0),
        ("diff_room.toml", 3.0),
        ("glass_slab.toml", 6.0),
    ] {
        let path = common::scene_path(name);
        let scene = Scene::load(&path, &[]).unwrap();
        let (first, last) = opl_bounds(&scene).unwrap();
        let overrides = vec![
            ("camera.resolution.0".to_string(), 16.0),
            ("camera.resolution.1".to_string(), 16.0),
            ("integrator.max_bounces".to_string(), bounces),
            ("film.start_opl".to_string(), first),
            ("film.bin_width_opl".to_string(), (last - first) / 64.0),
            ("film.bins".to_string(), 64.0),
        ];
        let wide = Scene::load(&path, &overrides).unwrap();
        let opts = RenderOptions {
            spp: Some(64),
            seed: Some(3),
            steady: SteadyMode::Full,
            ..Default::default()
        };
        let (_, stats) = render(&wide, &opts).unwrap();
        let e = stats.energy;
        assert!(e.total > 0.0, "{name}: no light");
        assert_eq!(
            (e.before, e.after),
            (0.0, 0.0),
            "{name}: light outside [{first}, {last}]: {e:?}"
        );
    }
}

/// The chosen window holds all but a sliver of the light (LOW_QUANTILE before it, 1 −
/// HIGH_QUANTILE after it, less the margins), measured by an uncut render with the window.
#[test]
fn the_chosen_window_holds_the_light() {
    for name in ["cornell_box.toml", "diff_room.toml", "shadow_hidden_occluder.toml"] {
        let path = common::scene_path(name);
        let small = vec![
            ("camera.resolution.0".to_string(), 24.0),
            ("camera.resolution.1".to_string(), 24.0),
        ];
        let opts = RenderOptions {
            seed: Some(1),
            ..Default::default()
        };
        let w = choose_window(&path, &small, &opts).unwrap();
        let scene = Scene::load(&path, &[]).unwrap();
        assert_eq!(w.bins, scene.film.axis.bins, "{name}: the bins are kept");
        assert!(w.start_opl > 0.0 && w.bin_width_opl > 0.0, "{name}: {w:?}");
        let mut with = small.clone();
        with.extend(w.overrides());
        let chosen = Scene::load(&path, &with).unwrap();
        let run = RenderOptions {
            spp: Some(64),
            seed: Some(9),
            steady: SteadyMode::Full,
            ..Default::default()
        };
        let (film, stats) = render(&chosen, &run).unwrap();
        let e = stats.energy;
        assert!(e.before <= 0.003 * e.total, "{name}: {e:?}");
        assert!(e.after <= 0.02 * e.total, "{name}: {e:?}");
        // and it is not needlessly wide: the first and last tenth of the window hold light
        let totals = film.bin_totals();
        let tenth = totals.len() / 10;
        assert!(
            totals[..tenth].iter().any(|&v| v > 0.0),
            "{name}: the first tenth is dark"
        );
        assert!(
            totals[totals.len() - tenth..].iter().any(|&v| v > 0.0),
            "{name}: the last tenth is dark"
        );
    }
}

#[test]
fn the_cli_records_the_window_and_refuses_what_it_cannot_choose() {
    let dir = tempfile::tempdir().unwrap();
    let cornell = common::scene_path("cornell_box.toml");
    let c = cornell.to_str().unwrap();
    let o = common::dtr(&["render", c, "--spp", "2", "--auto-window", "-o", "a"], dir.path());
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("auto window ["), "{err}");
    let json: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.path().join("a.json")).unwrap()).unwrap();
    let w = &json["auto_window"];
    assert_eq!(json["time_axis"]["start_opl"], w["start_opl"]);
    assert_eq!(json["time_axis"]["bin_width_opl"], w["bin_width_opl"]);
    assert_eq!(w["pilot_spp"], 16);

    let o = common::dtr(
        &["render", c, "--auto-window", "--set", "film.start_opl=2", "-o", "b"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--auto-window chooses film.start_opl"));

    let nlos = common::scene_path("nlos_hidden_patch.toml");
    let o = common::dtr(
        &["render", nlos.to_str().unwrap(), "--auto-window", "-o", "c"],
        dir.path(),
    );
    assert_eq!(o.status.code(), Some(2));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("nlos_hidden_patch.toml: --auto-window: a relay-wall capture"),
        "{err}"
    );
    assert!(!dir.path().join("b.npy").exists() && !dir.path().join("c.npy").exists());
}
