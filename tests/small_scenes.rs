//! A scene a few millimetres across renders like the room it scales, and a light keeps the
//! place its file gives it. Both rested on lengths fixed in metres: the offset off surfaces had
//! a floor of 2⁻¹⁸ m (`integrator::surface::self_intersection_eps`), and a light within
//! 2⁻¹³ m of a parallel surface counted as flush on it and was moved (`scene::flush`). In a
//! 2 mm room the first made the boundary derivative 1.6 % too large (and arrive later); the
//! second moved the Cornell light by 5 % of the room's height, darkening the image by 5 %.
//! Both floors are now the scene's own size where it is under a metre
//! (`scene::origin::offset_scale`). And a surface just in front of a light covers it: the
//! flush rule used to move the light through such a cover, lighting what it hides.
//!
//! Scenes are scaled by 2⁻¹⁰ (every length, the film's window and the pulse), a power of two,
//! so their f32 coordinates are the room's own scaled exactly.

use crate::common;
use difftransient::scene::Format;
use difftransient::{BoundaryMode, RenderOptions, Scene, Transient, render, render_diff};
use std::path::Path;
use toml::Value;

const S: f64 = 1.0 / 1024.0;

fn times(v: &mut Value, s: f64) {
    match v {
        Value::Float(x) => *x *= s,
        Value::Integer(i) => *v = Value::Float(*i as f64 * s),
        Value::Array(a) => a.iter_mut().for_each(|x| times(x, s)),
        _ => panic!("not a length: {v}"),
    }
}

/// Scene `name` from scenes/ after `edit` (in the room's metres), with every length times
/// `s`: positions, shape translations and scales, the film's window, pulses and the params
/// that hold lengths. Area lights' radiance is kept: the image of a scaled scene is the same.
fn scaled(name: &str, s: f64, edit: impl FnOnce(&mut Value)) -> Scene {
    let text = std::fs::read_to_string(common::scene_path(name)).unwrap();
    let mut v: Value = toml::from_str(&text).unwrap();
    edit(&mut v);
    for key in ["position", "look_at"] {
        times(&mut v["camera"][key], s);
    }
    for shape in v["shape"].as_array_mut().unwrap() {
        let t = shape.as_table_mut().unwrap();
        times(t.entry("translate").or_insert(Value::try_from([0.0; 3]).unwrap()), s);
        times(t.entry("scale").or_insert(Value::Float(1.0)), s);
    }
    for e in v["emitter"].as_array_mut().unwrap() {
        let t = e.as_table_mut().unwrap();
        assert_eq!(
            t["type"].as_str(),
            Some("area"),
            "{name}: only area lights are scaled here"
        );
        if let Some(Value::Table(p)) = t.get_mut("pulse") {
            for k in ["sigma_opl", "width_opl"] {
                p.get_mut(k).into_iter().for_each(|x| times(x, s));
            }
        }
        t.get_mut("offset_opl").into_iter().for_each(|x| times(x, s));
    }
    let film = v["film"].as_table_mut().unwrap();
    for k in ["start_opl", "bin_width_opl"] {
        times(film.get_mut(k).unwrap(), s);
    }
    if let Some(Value::Table(g)) = film.get_mut("gate") {
        g.get_mut("sigma_opl").into_iter().for_each(|x| times(x, s));
    }
    for p in v.get_mut("param").and_then(Value::as_array_mut).into_iter().flatten() {
        let kind = p["kind"].as_str().unwrap().to_string();
        assert!(
            matches!(kind.as_str(), "translate" | "scale"),
            "{name}: param kind {kind}"
        );
        times(&mut p["value"], s);
    }
    Scene::from_str(
        &toml::to_string(&v).unwrap(),
        Format::Toml,
        Path::new("small.toml"),
        &[],
    )
    .unwrap_or_else(|e| panic!("{e}"))
}

/// The lowest and highest y of shape `name`'s vertices.
fn y_range(scene: &Scene, name: &str) -> (f32, f32) {
    let s = scene.shapes.iter().find(|s| s.name == name).unwrap();
    let verts = s.first_vertex as usize..(s.first_vertex + s.vertex_count) as usize;
    scene.geometry.positions[verts]
        .iter()
        .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        })
}

/// The `[[shape]]` table named `name` of scene text `v`.
fn shape_mut<'a>(v: &'a mut Value, name: &str) -> &'a mut Value {
    v["shape"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .find(|s| s["name"].as_str() == Some(name))
        .unwrap()
}

fn light_at(y: f64) -> impl FnOnce(&mut Value) {
    move |v: &mut Value| shape_mut(v, "light_quad")["translate"] = Value::try_from([0.0, y, 0.0]).unwrap()
}

/// The Cornell light 2 cm below the ceiling stays there in a room of 2 mm (it was moved up to
/// 0.12 mm from the ceiling, 5 % of the room's height), and the same light put in the
/// ceiling's plane is lifted off it by a small part of the room, as a full-size room's is.
#[test]
fn a_light_in_a_millimetre_room_stays_where_its_file_puts_it() {
    let height = 2.0 * S as f32;
    for (y, gap, lifted) in [(1.98, 0.02, false), (2.0, 0.0, true)] {
        let room = scaled("cornell_box.toml", S, light_at(y));
        let ceiling = y_range(&room, "ceiling").0;
        let light = y_range(&room, "light_quad");
        assert_eq!(light.0, light.1, "the light stays level");
        let below = ceiling - light.0;
        assert_eq!(room.lifted_emitters.is_empty(), !lifted, "light at {y} m × 2⁻¹⁰");
        if lifted {
            assert!(
                below > 0.0 && below < 1e-3 * height,
                "lifted {below:e} m in a {height:e} m room"
            );
        } else {
            let want = (gap * S) as f32;
            assert!(
                (below - want).abs() < 1e-4 * want,
                "moved: {below:e} m below the ceiling, not {want:e}"
            );
        }
    }
}

/// A 0.5 m cover 0.1 mm below the 0.4 m ceiling light of the hidden-occluder scene, in a room
/// of full size and in one of 2⁻¹⁰ of it (where the cover lies 10⁻⁷ m from the light): the
/// light stays behind it and the floor the camera sees stays dark. The flush rule used to move
/// the light through the cover (a total of 22.6 where it is 0).
#[test]
fn a_surface_just_in_front_of_a_light_covers_it() {
    for s in [1.0, S] {
        let cover = |v: &mut Value| {
            v["param"][0]["value"] = Value::Float(0.0); // occluder_x
            let occ = shape_mut(v, "occluder");
            occ["translate"] = Value::try_from([0.0, 2.0 - 1e-4, 0.0]).unwrap();
            occ["scale"] = Value::try_from([0.25, 0.25, 1.0]).unwrap();
        };
        let scene = scaled("shadow_hidden_occluder.toml", s, cover);
        assert!(scene.lifted_emitters.is_empty(), "×{s}: {:?}", scene.lifted_emitters);
        let (light, occluder) = (y_range(&scene, "light_quad").0, y_range(&scene, "occluder").0);
        assert!(
            light > occluder,
            "×{s}: the light at {light} went through the cover at {occluder}"
        );
        let opts = RenderOptions {
            spp: Some(16),
            seed: Some(1),
            threads: Some(2),
            ..Default::default()
        };
        let (t, _) = render(&scene, &opts).unwrap();
        let total: f64 = t.data.iter().map(|&v| v as f64).sum();
        assert_eq!(total, 0.0, "×{s}: the covered light lit the floor");
    }
}

/// Seeds per scale; the two scales' means are compared with |z| < 4.
const SEEDS: u64 = 6;

/// Total and first moment in bins (Σ k·v) of a derivative transient.
fn total_and_moment(t: &Transient) -> (f64, f64) {
    let per_bin = t.bin_totals();
    let total = per_bin.iter().map(|&v| v as f64).sum();
    let moment = per_bin.iter().enumerate().map(|(k, &v)| k as f64 * v as f64).sum();
    (total, moment)
}

/// The boundary stage's d/d`occluder_x` of the hidden-occluder scene (all of its derivative:
/// the interior's is zero there), scaled by 2⁻¹⁰ and multiplied back by the scale, against
/// the full-size room's: the total and its first moment in time agree within 4 standard
/// errors over 6 seeds each. Its per-seed spread is 0.15 % of the total, so a bias of 1 %
/// is about 9 standard errors. With the offset's floor of 2⁻¹⁸ m it was 1.6 % too large.
#[test]
fn a_millimetre_scene_has_the_boundary_derivative_of_the_room() {
    let p = ["occluder_x".to_string()];
    let measure = |s: f64| -> Vec<(f64, f64)> {
        let scene = scaled("shadow_hidden_occluder.toml", s, |_| {});
        (0..SEEDS)
            .map(|seed| {
                let opts = RenderOptions {
                    spp: Some(1),
                    seed: Some(100 + seed),
                    threads: Some(2),
                    spp_boundary: Some(32),
                    boundary: BoundaryMode::BoundaryOnly,
                    ..Default::default()
                };
                let (_, d, _) = render_diff(&scene, &p, &opts).unwrap();
                let (total, moment) = total_and_moment(&d[0]);
                (total * s, moment * s)
            })
            .collect()
    };
    let (room, small) = (measure(1.0), measure(S));
    for (what, pick) in [("total", 0usize), ("first moment", 1)] {
        let get = |v: &[(f64, f64)]| v.iter().map(|m| if pick == 0 { m.0 } else { m.1 }).collect::<Vec<_>>();
        let ((a, sa), (b, sb)) = (common::mean_se(&get(&room)), common::mean_se(&get(&small)));
        let z = (b - a) / (sa * sa + sb * sb).sqrt();
        eprintln!("{what}: room {a:.5} ± {sa:.5}, ×2⁻¹⁰ {b:.5} ± {sb:.5}, z = {z:.2}");
        assert!(
            a.abs() > 10.0 * sa,
            "{what}: the room's derivative is lost in its noise"
        );
        assert!(z.abs() < 4.0, "{what}: room {a} ± {sa}, ×2⁻¹⁰ {b} ± {sb} (z = {z:.1})");
    }
}
