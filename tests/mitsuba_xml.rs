//! Mitsuba 3 XML import (issue 15, src/scene/mitsuba/): the Cornell box written as a Mitsuba
//! scene renders the same bytes as the TOML; each supported element converts to the values
//! Mitsuba means (transforms composed in Mitsuba's order, the look-at camera, fov axes,
//! max_depth, spheres, flip_normals, materials, emitters, `$` defaults); a table of inputs
//! outside the subset, each refused naming the file, the element and its line; and the CLI
//! (`dtr render x.xml`, `dtr import`).

use crate::common;
use difftransient::scene::{EmitterKind, Material};
use difftransient::{RenderOptions, Scene, render};
use glam::{DMat4, DVec3, Vec3};
use std::path::Path;

const HEAD: &str = r#"<scene version="3.0.0">
    <integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>
    <sensor type="perspective">
        <float name="fov" value="40"/>
        <transform name="to_world"><lookat origin="0, 0, 4" target="0, 0, 0" up="0, 1, 0"/></transform>
        <sampler type="independent"><integer name="sample_count" value="2"/></sampler>
        <film type="transient_hdr_film"><integer name="width" value="8"/><integer name="height" value="8"/><integer name="temporal_bins" value="20"/><float name="bin_width_opl" value="0.5"/><rfilter type="box"/></film>
    </sensor>
"#;
const LIGHT: &str = r#"    <emitter type="point"><point name="position" value="0, 0, 2"/><rgb name="intensity" value="1"/></emitter>
"#;

/// A scene: HEAD, `body`, a point light, closed.
fn scene_text(body: &str) -> String {
    format!("{HEAD}{body}\n{LIGHT}</scene>\n")
}

/// Writes `text` as `dir/name` and loads it.
fn load_in(dir: &Path, name: &str, text: &str) -> Result<Scene, String> {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    Scene::load(&p, &[]).map_err(|e| e.to_string())
}

fn load(body: &str) -> Scene {
    let dir = tempfile::tempdir().unwrap();
    load_in(dir.path(), "s.xml", &scene_text(body)).unwrap_or_else(|e| panic!("{e}"))
}

/// World vertices of shape `i` against `m` applied to its local vertices.
fn assert_placed(s: &Scene, i: usize, m: &DMat4) {
    let sh = &s.shapes[i];
    let world = &s.geometry.positions[sh.first_vertex as usize..(sh.first_vertex + sh.vertex_count) as usize];
    for (w, l) in world.iter().zip(&sh.local_positions) {
        let want = m.transform_point3(l.as_dvec3());
        assert!((w.as_dvec3() - want).length() < 1e-5, "{w} vs {want}");
    }
}

fn normal(s: &Scene, tri: usize) -> Vec3 {
    let [a, b, c] = s.geometry.indices[tri].map(|i| s.geometry.positions[i as usize]);
    (b - a).cross(c - a).normalize()
}

#[test]
fn the_cornell_box_xml_renders_the_same_bytes_as_the_toml() {
    let toml = common::load("cornell_box.toml");
    let xml = common::load("cornell_box.xml");
    assert_eq!(toml.geometry.positions, xml.geometry.positions);
    assert_eq!(toml.geometry.indices, xml.geometry.indices);
    assert_eq!(
        (
            toml.integrator.max_bounces,
            toml.integrator.spp,
            toml.integrator.rr_depth
        ),
        (xml.integrator.max_bounces, xml.integrator.spp, xml.integrator.rr_depth)
    );
    let opts = RenderOptions {
        spp: Some(2),
        seed: Some(7),
        threads: Some(2),
        ..Default::default()
    };
    let a = render(&toml, &opts).unwrap().0;
    let b = render(&xml, &opts).unwrap().0;
    assert!(a.data.iter().sum::<f32>() > 0.0);
    assert_eq!(a.shape(), b.shape());
    assert_eq!(a.data, b.data);
}

#[test]
fn transforms_compose_in_mitsubas_order() {
    // rotations about z then x (not our order), a uniform scale, a translation: decomposed
    let s = load(
        r#"<shape type="rectangle"><transform name="to_world"><rotate z="1" angle="30"/><rotate x="1" angle="-50"/><scale value="2"/><translate value="1, 2, 3"/></transform></shape>
           <shape type="cube"><transform name="to_world"><translate x="0.5"/><rotate value="0.6, 0.8, 0" angle="40"/><scale value="0.5, 0.5, 0.5"/></transform></shape>
           <shape type="cube"><transform name="to_world"><matrix value="0 -2 0 1  1 0 0 2  0 0 3 3  0 0 0 1"/></transform></shape>
           <shape type="rectangle"><transform name="to_world"><lookat origin="1, 1, 1" target="0, 0, 0" up="0, 1, 0"/></transform></shape>"#,
    );
    let r = |axis: DVec3, deg: f64| DMat4::from_axis_angle(axis.normalize(), deg.to_radians());
    let m0 = DMat4::from_translation(DVec3::new(1.0, 2.0, 3.0))
        * DMat4::from_scale(DVec3::splat(2.0))
        * r(DVec3::X, -50.0)
        * r(DVec3::Z, 30.0);
    assert_placed(&s, 0, &m0);
    let m1 = DMat4::from_scale(DVec3::splat(0.5))
        * r(DVec3::new(0.6, 0.8, 0.0), 40.0)
        * DMat4::from_translation(DVec3::X * 0.5);
    assert_placed(&s, 1, &m1);
    // row-major in the file
    let m2 = DMat4::from_cols_array(&[0., 1., 0., 0., -2., 0., 0., 0., 0., 0., 3., 0., 1., 2., 3., 1.]);
    assert_placed(&s, 2, &m2);
    // a rectangle placed by lookat faces its target (normal +z → towards the origin)
    let n = normal(&s, s.shapes[3].first_tri as usize).as_dvec3();
    assert!((n + DVec3::ONE.normalize()).length() < 1e-5, "{n}");
    // Mitsuba's rectangle and cube are ours: [-1, 1]² at z = 0 (normal +z) and [-1, 1]³
    let s = load(r#"<shape type="rectangle"/><shape type="cube"/>"#);
    assert!(
        s.shapes[0]
            .local_positions
            .iter()
            .all(|p| p.z == 0.0 && p.x.abs() == 1.0 && p.y.abs() == 1.0)
    );
    assert_eq!(normal(&s, 0), Vec3::Z);
    assert!(s.shapes[1].local_positions.iter().all(|p| p.abs() == Vec3::ONE));
}

#[test]
fn camera_fov_axes_and_depths() {
    let s = load(r#"<shape type="rectangle"/>"#);
    assert_eq!(
        (s.camera.position, s.camera.look_at, s.camera.up),
        (Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, Vec3::Y)
    );
    // fov_axis x (Mitsuba's default) on a square film is the vertical fov
    assert_eq!(s.camera.fov_y_deg, 40.0);
    // max_depth 3 = 2 bounces; rr_depth 5 (the default) is past them: no roulette
    assert_eq!(
        (s.integrator.max_bounces, s.integrator.rr_depth, s.integrator.spp),
        (2, None, 2)
    );
    let dir = tempfile::tempdir().unwrap();
    let wide = scene_text(r#"<shape type="rectangle"/>"#)
        .replace(r#"name="width" value="8""#, r#"name="width" value="16""#)
        .replace(
            r#"name="max_depth" value="3""#,
            r#"name="max_depth" value="8"/><integer name="rr_depth" value="3""#,
        );
    let s = load_in(dir.path(), "w.xml", &wide).unwrap();
    let want = 2.0 * ((20.0f64).to_radians().tan() / 2.0).atan().to_degrees();
    assert!(
        (s.camera.fov_y_deg as f64 - want).abs() < 1e-4,
        "{}",
        s.camera.fov_y_deg
    );
    assert_eq!((s.integrator.max_bounces, s.integrator.rr_depth), (7, Some(3)));
    let s = load_in(
        dir.path(),
        "d.xml",
        &wide.replace(r#"value="40"/>"#, r#"value="40"/><string name="fov_axis" value="y"/>"#),
    )
    .unwrap();
    assert_eq!(s.camera.fov_y_deg, 40.0);
}

#[test]
fn spheres_flipped_rectangles_materials_emitters_and_defaults() {
    let s = load(
        r#"<default name="r" value="0.5"/>
           <bsdf type="twosided" id="wall"><bsdf type="diffuse"><rgb name="reflectance" value="0.2, 0.4, 0.6"/></bsdf></bsdf>
           <shape type="sphere"><point name="center" value="1, 0, 0"/><float name="radius" value="$r"/>
               <bsdf type="roughdielectric"><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/><string name="int_ior" value="water"/></bsdf></shape>
           <shape type="rectangle" id="lamp"><boolean name="flip_normals" value="true"/><ref id="wall"/>
               <emitter type="area"><rgb name="radiance" value="3, 2, 1"/></emitter></shape>
           <shape type="rectangle"><bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha" value="0.3"/>
               <rgb name="eta" value="0.2, 0.4, 1.4"/><rgb name="k" value="3.6, 2.4, 1.8"/></bsdf></shape>"#,
    );
    // the sphere: our icosphere at level 6, vertices on the true sphere
    let sh = &s.shapes[0];
    assert_eq!(sh.tri_count, 81920);
    let world = &s.geometry.positions[sh.first_vertex as usize..(sh.first_vertex + sh.vertex_count) as usize];
    assert!(world.iter().all(|p| ((*p - Vec3::X).length() - 0.5).abs() < 1e-5));
    assert_eq!(
        s.materials[0].material,
        Material::Diffuse {
            albedo: [0.2, 0.4, 0.6]
        }
    );
    match &s.materials[1].material {
        Material::Dielectric {
            roughness,
            int_ior,
            exterior,
        } => {
            assert_eq!((*roughness, *int_ior, *exterior), (0.2, 1.333, None))
        }
        m => panic!("{m:?}"),
    }
    match &s.materials[2].material {
        Material::Conductor { roughness, ior, .. } => {
            assert_eq!(*roughness, 0.3);
            assert_eq!(*ior, Some(([0.2, 0.4, 1.4], [3.6, 2.4, 1.8])));
        }
        m => panic!("{m:?}"),
    }
    // flip_normals: the lamp emits towards -z
    assert_eq!(normal(&s, s.shapes[1].first_tri as usize), -Vec3::Z);
    assert!(matches!(
        s.emitters[0].kind,
        EmitterKind::Area {
            shape: 1,
            radiance: [3.0, 2.0, 1.0]
        }
    ));
    assert!(
        matches!(s.emitters[1].kind, EmitterKind::Point { position, intensity: [1.0, 1.0, 1.0] } if position == Vec3::new(0.0, 0.0, 2.0))
    );
}

/// Whether every triangle of shape `i` faces away from the point `c` (its front outward).
fn faces_out(s: &Scene, i: usize, c: Vec3) -> bool {
    let sh = &s.shapes[i];
    (sh.first_tri..sh.first_tri + sh.tri_count).all(|t| {
        let [a, ..] = s.geometry.indices[t as usize].map(|k| s.geometry.positions[k as usize]);
        normal(s, t as usize).dot(a - c) > 0.0
    })
}

/// Which side is the front, as Mitsuba 3.9.1 has it (an independent sweep against it, helper
/// 41, forty-fourth session): a bare diffuse or conductor is black from behind (it was lit
/// on both sides here: a rectangle's back 0.14 against 0), a mirrored cube keeps its outward
/// front (it was turned inward, or refused where it emitted), a sphere scaled by −1 is
/// inside out (it stayed outward: an emitting one shone 1.0 against 0), and `flip_normals`
/// turns cubes and spheres.
#[test]
fn front_sides_and_one_sided_bsdfs_are_mitsubas() {
    let s = load(
        r#"<bsdf type="twosided" id="both"><bsdf type="diffuse"/></bsdf>
           <bsdf type="diffuse" id="front"/>
           <shape type="cube"><transform name="to_world"><scale x="-1"/><translate x="5"/></transform><ref id="front"/></shape>
           <shape type="cube"><boolean name="flip_normals" value="true"/><transform name="to_world"><translate x="10"/></transform><ref id="both"/></shape>
           <shape type="sphere"><transform name="to_world"><scale value="-1"/><translate x="15"/></transform>
               <emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
           <shape type="sphere"><boolean name="flip_normals" value="true"/><point name="center" value="20, 0, 0"/></shape>
           <shape type="sphere"><boolean name="flip_normals" value="true"/><transform name="to_world"><scale value="-1"/><translate x="25"/></transform><ref id="front"/></shape>
           <shape type="rectangle"><bsdf type="conductor"/></shape>"#,
    );
    let centre = |x: f32| Vec3::new(x, 0.0, 0.0);
    assert!(faces_out(&s, 0, centre(5.0)));
    assert!(!faces_out(&s, 1, centre(10.0)));
    assert!(!faces_out(&s, 2, centre(15.0)));
    assert!(!faces_out(&s, 3, centre(20.0)));
    assert!(faces_out(&s, 4, centre(25.0)));
    let sided: Vec<(&str, bool)> = s.materials.iter().map(|m| (m.name.as_str(), m.one_sided)).collect();
    assert_eq!(
        sided,
        [
            ("both", false),
            ("front", true),
            ("default_emitter_black", true),
            ("default_diffuse", true),
            ("rectangle_bsdf", true)
        ]
    );
}

/// Where the importer's reading differed from Mitsuba 3.9.1's render of the same file
/// without a word (an independent sweep against Mitsuba, helper 39; forty-third session):
/// an emitting shape with no BSDF is black in Mitsuba (it was diffuse 0.5: a lit lamp 5.6×
/// too bright); a constant `<spectrum>` in an emitter is an equal-energy light, not white
/// (it was (v, v, v)); clip planes that hide nothing are accepted.
#[test]
fn emitters_take_mitsubas_defaults_and_spectra() {
    let s = load(
        r#"<shape type="rectangle"><emitter type="area"><spectrum name="radiance" value="5"/></emitter></shape>
           <shape type="cube"><transform name="to_world"><translate x="3"/></transform></shape>
           <shape type="rectangle"><transform name="to_world"><translate y="3"/></transform><bsdf type="diffuse"/>
               <emitter type="area"><spectrum name="radiance" value="2"/></emitter></shape>
           <emitter type="point"><point name="position" value="1, 1, 1"/><spectrum name="intensity" value="4"/></emitter>"#,
    );
    let albedo = |i: usize| match s.materials[s.shapes[i].material as usize].material {
        Material::Diffuse { albedo } => albedo,
        ref m => panic!("{m:?}"),
    };
    assert_eq!(albedo(0), [0.0; 3], "an emitter without a BSDF is black");
    assert_eq!(
        albedo(1),
        [0.5; 3],
        "another shape without one is Mitsuba's diffuse 0.5"
    );
    assert_eq!(albedo(2), [0.5; 3], "a BSDF given is kept");
    let equal_energy = [1.2048, 0.9483, 0.9089];
    let close = |got: [f32; 3], v: f32| got.iter().zip(equal_energy).all(|(g, e)| (g / v - e).abs() < 2e-4);
    let mut seen = 0;
    for e in &s.emitters {
        match e.kind {
            EmitterKind::Area { shape: 0, radiance } => assert!(close(radiance, 5.0), "{radiance:?}"),
            EmitterKind::Area { shape: 2, radiance } => assert!(close(radiance, 2.0), "{radiance:?}"),
            EmitterKind::Point { intensity, .. } if intensity != [1.0; 3] => {
                assert!(close(intensity, 4.0), "{intensity:?}")
            }
            _ => continue,
        }
        seen += 1;
    }
    assert_eq!(seen, 3);
    // a constant spectrum as a reflectance stays grey, as in Mitsuba
    let s = load(
        r#"<shape type="rectangle"><bsdf type="diffuse"><spectrum name="reflectance" value="0.3"/></bsdf></shape>"#,
    );
    assert!(matches!(s.materials[0].material, Material::Diffuse { albedo } if albedo == [0.3; 3]));
    // clip planes that hide no shape: accepted
    let dir = tempfile::tempdir().unwrap();
    load_in(dir.path(), "near.xml", &clipped("near_clip", "1")).unwrap();
    load_in(dir.path(), "far.xml", &clipped("far_clip", "100")).unwrap();
}

#[test]
fn an_obj_mesh_by_relative_file_name() {
    // written beside scenes/obj_mesh.toml, so meshes/pyramid.obj resolves the same way
    let text = scene_text(
        r#"<shape type="obj"><string name="filename" value="meshes/pyramid.obj"/><boolean name="face_normals" value="true"/></shape>"#,
    );
    let imported = difftransient::scene::mitsuba::import_str(&text, &common::scene_path("x.xml")).unwrap();
    let s = Scene::from_str(
        &imported.toml,
        difftransient::scene::Format::Toml,
        &common::scene_path("x.xml"),
        &[],
    )
    .unwrap();
    let obj = common::load("obj_mesh.toml");
    let k = obj.shapes.iter().position(|s| s.name == "pyramid").unwrap();
    assert_eq!(s.shapes[0].local_positions, obj.shapes[k].local_positions);
}

#[test]
fn a_twosided_bsdf_may_refer_to_another_by_id() {
    let s = load(
        r#"<bsdf type="diffuse" id="paint"><rgb name="reflectance" value="0.1, 0.7, 0.3"/></bsdf>
           <bsdf type="twosided" id="two"><ref id="paint"/></bsdf>
           <bsdf type="twosided" id="twice"><ref id="two"/></bsdf>
           <shape type="rectangle"><ref id="twice"/></shape>
           <shape type="rectangle"><bsdf type="twosided"><ref id="paint"/></bsdf></shape>"#,
    );
    let paint = Material::Diffuse {
        albedo: [0.1, 0.7, 0.3],
    };
    assert_eq!(
        s.materials.len(),
        4,
        "{:?}",
        s.materials.iter().map(|m| &m.name).collect::<Vec<_>>()
    );
    assert!(s.materials.iter().all(|m| m.material == paint));
    let of = |i: usize| &s.materials[s.shapes[i].material as usize].name;
    assert_eq!(of(0), "twice");
}

/// A named conductor becomes its RGB complex index (src/scene/mitsuba/conductors.rs, computed
/// from Mitsuba's spectra by tools/conductor_presets.py), on smooth and rough conductors.
#[test]
fn conductor_material_presets_become_their_rgb_index() {
    let s = load(
        r#"<shape type="rectangle"><bsdf type="conductor"><string name="material" value="Au"/></bsdf></shape>
           <shape type="rectangle"><bsdf type="roughconductor"><string name="material" value="Cu"/><string name="distribution" value="ggx"/></bsdf></shape>
           <shape type="rectangle"><bsdf type="conductor"><string name="material" value="none"/></bsdf></shape>"#,
    );
    let ior = |i: usize| match &s.materials[i].material {
        Material::Conductor { ior, roughness, .. } => (*ior, *roughness),
        m => panic!("{m:?}"),
    };
    assert_eq!(
        ior(0),
        (Some(([0.1431, 0.3750, 1.4425], [3.9832, 2.3857, 1.6032])), 0.0)
    );
    assert_eq!(
        ior(1),
        (Some(([0.2004, 0.9240, 1.1022], [3.9130, 2.4528, 2.1422])), 0.1)
    );
    assert_eq!(ior(2), (None, 0.0));
}

#[test]
fn included_files_are_read_relative_to_the_including_file() {
    let dir = tempfile::tempdir().unwrap();
    let sub = dir.path().join("parts");
    std::fs::create_dir_all(sub.join("meshes")).unwrap();
    std::fs::copy(common::scene_path("meshes/pyramid.obj"), sub.join("meshes/p.obj")).unwrap();
    // the included file names its mesh and its own include relative to its folder, uses the
    // including file's default, and defines a BSDF the scene file refers to
    std::fs::write(
        sub.join("materials.xml"),
        r#"<scene version="3.0.0"><include filename="more/paint.xml"/>
             <shape type="obj"><string name="filename" value="meshes/p.obj"/><ref id="paint"/></shape></scene>"#,
    )
    .unwrap();
    std::fs::create_dir_all(sub.join("more")).unwrap();
    std::fs::write(
        sub.join("more/paint.xml"),
        r#"<scene version="3.0.0"><default name="r" value="0.9"/>
             <bsdf type="diffuse" id="paint"><float name="reflectance" value="$r"/></bsdf></scene>"#,
    )
    .unwrap();
    let text = scene_text(
        r#"<default name="r" value="0.25"/><include filename="parts/materials.xml"/>
           <shape type="rectangle"><ref id="paint"/></shape>"#,
    );
    let s = load_in(dir.path(), "s.xml", &text).unwrap_or_else(|e| panic!("{e}"));
    let inputs: Vec<String> = s.inputs.iter().map(|p| p.display().to_string()).collect();
    for file in [
        "s.xml",
        "parts/meshes/p.obj",
        "parts/materials.xml",
        "parts/more/paint.xml",
    ] {
        assert!(inputs.iter().any(|i| i.ends_with(file)), "{file} not in {inputs:?}");
    }
    assert_eq!(s.shapes.len(), 2);
    assert_eq!(s.materials.len(), 1);
    assert_eq!(s.materials[0].material, Material::Diffuse { albedo: [0.25; 3] });
    let obj = common::load("obj_mesh.toml");
    let k = obj.shapes.iter().position(|s| s.name == "pyramid").unwrap();
    assert_eq!(s.shapes[0].local_positions, obj.shapes[k].local_positions);
}

#[test]
fn include_cycles_and_errors_in_included_files_name_that_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    let write = |name: &str, body: &str| {
        std::fs::write(p.join(name), format!("<scene version=\"3.0.0\">{body}</scene>")).unwrap();
    };
    let include =
        |name: &str| load_in(p, "s.xml", &scene_text(&format!(r#"<include filename="{name}"/>"#))).unwrap_err();
    let shown = |name: &str| p.join(name).display().to_string();
    write("a.xml", "\n<include filename=\"b.xml\"/>");
    write("b.xml", "\n\n<include filename=\"a.xml\"/>");
    let e = include("a.xml");
    assert!(e.starts_with(&shown("b.xml")), "{e}");
    assert!(e.contains(&format!("<include> (line 3 of {})", shown("b.xml"))), "{e}");
    assert!(
        e.contains("include cycle") && e.contains("a.xml includes") && e.contains("b.xml includes"),
        "{e}"
    );
    // a file including itself
    write("c.xml", "<include filename=\"./c.xml\"/>");
    assert!(include("c.xml").contains("include cycle"));
    // an unsupported element inside an included file: that file, its element and line
    write("d.xml", "\n  <shape type=\"disk\"/>\n");
    let e = include("d.xml");
    assert!(e.starts_with(&shown("d.xml")), "{e}");
    assert!(
        e.contains(&format!("<shape type=\"disk\"> (line 2 of {})", shown("d.xml"))),
        "{e}"
    );
    // a missing file and a syntax error in an included file
    let e = include("none.xml");
    assert!(
        e.contains("cannot read the included file") && e.contains("none.xml"),
        "{e}"
    );
    write("e.xml", "\n<shape>\n");
    let e = include("e.xml");
    assert!(e.starts_with(&shown("e.xml")) && e.contains("XML syntax error"), "{e}");
}

/// Bad inputs: (the scene text, a string on the offending element's line, what `at` names,
/// what the message says).
/// A rectangle 4 m in front of HEAD's camera, seen with the sensor's `name` set to `value`
/// (and far_clip 2.5 for a near_clip of 3, which then exceeds it).
fn clipped(name: &str, value: &str) -> String {
    let far = if value == "3" {
        r#"<float name="far_clip" value="2.5"/>"#
    } else {
        ""
    };
    scene_text(r#"<shape type="rectangle"/>"#).replacen(
        r#"<float name="fov" value="40"/>"#,
        &format!(r#"<float name="fov" value="40"/><float name="{name}" value="{value}"/>{far}"#),
        1,
    )
}

fn bad_cases() -> Vec<(String, &'static str, &'static str, &'static str)> {
    let body = |b: &str| scene_text(b);
    let rect = r#"<shape type="rectangle"/>"#;
    let texture = |ty: &str| {
        body(&format!(
            r#"<shape type="rectangle"><bsdf type="diffuse"><texture type="{ty}" name="reflectance"/></bsdf></shape>"#
        ))
    };
    let mut rows = vec![
        (
            body(r#"<shape type="disk"/>"#),
            r#"<shape type="disk""#,
            r#"<shape type="disk">"#,
            "rectangle, cube, sphere, obj, ply",
        ),
        (
            body(r#"<bsdf type="plastic" id="p"/>"#),
            r#"type="plastic""#,
            r#"<bsdf type="plastic" id="p">"#,
            "not supported",
        ),
        (
            body(r#"<shape type="rectangle"><bsdf type="roughconductor"/></shape>"#),
            "roughconductor",
            r#"<bsdf type="roughconductor">"#,
            "Beckmann",
        ),
        (
            body(
                r#"<shape type="rectangle"><bsdf type="conductor"><string name="material" value="W"/></bsdf></shape>"#,
            ),
            r#"value="W""#,
            r#"<string name="material">"#,
            "\"W\" is not built in (built in: Ag, Al, Au, Cr, Cu, none)",
        ),
        (
            body(r#"<bsdf type="thindielectric" id="t"/>"#),
            "thindielectric",
            r#"<bsdf type="thindielectric""#,
            "thindielectric",
        ),
        (
            body(r#"<include filename="more.xml"/>"#),
            "<include",
            r#"<include>"#,
            "cannot read the included file",
        ),
        (
            body(
                r#"<shape type="rectangle"><bsdf type="roughconductor"><string name="distribution" value="beckmann"/></bsdf></shape>"#,
            ),
            "beckmann",
            r#"<string name="distribution">"#,
            "\"beckmann\" is not supported (only \"ggx\")",
        ),
        (
            body(
                r#"<bsdf type="twosided" id="a"><ref id="b"/></bsdf><bsdf type="twosided" id="b"><ref id="a"/></bsdf>"#,
            ),
            r#"<ref id="b""#,
            r#"<ref id="b">"#,
            "cycle",
        ),
        (
            body(r#"<bsdf type="twosided" id="a"><ref id="zz"/></bsdf>"#),
            "zz",
            r#"<ref id="zz">"#,
            "no <bsdf id=\"zz\">",
        ),
        (
            body(r#"<bsdf type="dielectric" id="g"/><bsdf type="twosided" id="a"><ref id="g"/></bsdf>"#),
            r#"<ref id="g""#,
            r#"<ref id="g">"#,
            "cannot be two-sided",
        ),
        (
            body(r#"<emitter type="spot"/>"#),
            r#"type="spot""#,
            r#"<emitter type="spot">"#,
            "laser",
        ),
        (
            body(r#"<shape type="rectangle"><float name="foo" value="1"/></shape>"#),
            "foo",
            r#"<float name="foo">"#,
            "supported:",
        ),
        (
            body(r#"<shape type="rectangle"><transform name="to_world"><translate value="$dx"/></transform></shape>"#),
            "$dx",
            "<translate>",
            "$dx has no value",
        ),
        (
            body(rect).replace(r#"name="max_depth" value="3""#, r#"name="max_depth" value="1""#),
            r#"value="1"/></integrator>"#,
            r#"<integer name="max_depth">"#,
            "max_depth 1",
        ),
        (
            body(rect).replace("transient_hdr_film", "hdrfilm"),
            "hdrfilm",
            r#"<film type="hdrfilm">"#,
            "transient_hdr_film",
        ),
        (
            body(
                r#"<shape type="cube"><transform name="to_world"><rotate z="1" angle="45"/><scale x="2"/></transform></shape>"#,
            ),
            r#"angle="45""#,
            r#"<transform name="to_world">"#,
            "shear",
        ),
        (
            body(
                r#"<shape type="sphere"><transform name="to_world"><scale value="-1"/></transform><bsdf type="dielectric"/></shape>"#,
            ),
            r#"<shape type="sphere">"#,
            r#"<shape type="sphere">"#,
            "inside out",
        ),
        (
            body(
                r#"<shape type="sphere"><bsdf type="dielectric"><string name="ext_ior" value="water"/></bsdf></shape>"#,
            ),
            "ext_ior",
            r#"<string name="ext_ior">"#,
            "vacuum or air",
        ),
        (
            body(r#"<shape type="rectangle"><ref id="nope"/></shape>"#),
            "nope",
            "<ref id=\"nope\">",
            "no <bsdf id=\"nope\">",
        ),
        (
            body(
                r#"<shape type="rectangle"><bsdf type="roughconductor"><string name="distribution" value="ggx"/><float name="alpha_u" value="0.1"/><float name="alpha_v" value="0.2"/></bsdf></shape>"#,
            ),
            "alpha_u",
            r#"<bsdf type="roughconductor">"#,
            "anisotropic",
        ),
        (
            body(rect).replace(r#"value="40"/>"#, r#"value="40"/><string name="fov_axis" value="z"/>"#),
            r#"name="fov_axis""#,
            r#"<string name="fov_axis">"#,
            "unknown fov_axis",
        ),
        (
            body(rect).replace(r#"value="40""#, r#"value="wide""#),
            r#"value="wide""#,
            r#"<float name="fov">"#,
            "expected a finite number",
        ),
        (
            body(rect).replace(r#"version="3.0.0""#, r#"version="0.6.0""#),
            "<scene",
            "<scene>",
            "Mitsuba 0.x",
        ),
        (
            format!("{HEAD}{LIGHT}</scene>").replace(
                r#"<integrator type="transient_path"><integer name="max_depth" value="3"/></integrator>"#,
                "",
            ),
            "<scene",
            "<scene>",
            "no <integrator>",
        ),
        (
            body(r#"<shape type="rectangle"><transform name="to_world"><shear/></transform></shape>"#),
            "<shear",
            "<shear>",
            "lookat",
        ),
        (
            body(
                r#"<shape type="cube"><transform name="to_world"><rotate value="1, 1, 0" angle="35"/></transform></shape>"#,
            ),
            "<rotate",
            "<rotate>",
            "not a unit vector",
        ),
        // found after conversion, when the description is checked: the XML element is named too
        (
            body(
                r#"<shape type="rectangle"><bsdf type="diffuse"><float name="reflectance" value="1.5"/></bsdf></shape>"#,
            ),
            r#"value="1.5""#,
            r#"<bsdf type="diffuse">"#,
            "albedo",
        ),
        (
            body(
                r#"<shape type="rectangle"><bsdf type="diffuse"/></shape><shape type="rectangle"><emitter type="area"><rgb name="radiance" value="-1"/></emitter></shape>"#,
            ),
            r#"value="-1""#,
            r#"<emitter type="area">"#,
            "radiance",
        ),
        (body(r#"<shape type="rectangle">"#), "", "XML syntax error", ""),
        // an uneven scale makes Mitsuba's sphere no ellipsoid (it stays round); converted to
        // an ellipsoid without a word until the forty-third session (helper 39)
        (
            body(
                r#"<shape type="sphere"><transform name="to_world"><scale x="1" y="0.3" z="0.3"/></transform></shape>"#,
            ),
            r#"<transform name="to_world"><scale x="1""#,
            r#"<transform name="to_world">"#,
            "Mitsuba 3 keeps a sphere round",
        ),
        // clip planes that hide a shape from Mitsuba's camera (ignored until then)
        (
            clipped("near_clip", "5"),
            "<sensor",
            r#"<sensor type="perspective">"#,
            "near_clip 5: Mitsuba 3 hides",
        ),
        (
            clipped("far_clip", "2"),
            "<sensor",
            r#"<sensor type="perspective">"#,
            "far_clip 2: Mitsuba 3 hides",
        ),
        (
            clipped("near_clip", "3"),
            r#"name="near_clip""#,
            "near_clip",
            "expected 0 < near_clip < far_clip",
        ),
    ];
    // what Mitsuba 3 itself refuses, accepted here until the forty-fourth session (an
    // independent sweep against Mitsuba 3.9.1, helper 41): a misspelt attribute (dropped, so
    // the shape stayed put), a point missing a coordinate (taken as 0) or mixing `value` with
    // x/y/z, a sampler or film format Mitsuba has no plugin or value for, an index of
    // refraction given as a string of digits
    rows.extend([
        (
            body(r#"<shape type="rectangle"><transform name="to_world"><translate X="0.8"/></transform></shape>"#),
            r#"<translate X"#,
            "<translate>",
            "unexpected attribute 'X' on <translate>",
        ),
        (
            body(r#"<shape type="sphere"><point name="center" x="0.5"/></shape>"#),
            r#"<point name="center""#,
            r#"<point name="center">"#,
            "missing attribute 'y'",
        ),
        (
            body(r#"<shape type="sphere"><point name="center" value="0, 0, 0" x="1"/></shape>"#),
            r#"<point name="center""#,
            r#"<point name="center">"#,
            "not both",
        ),
        (
            body(rect).replace(r#"<sampler type="independent">"#, r#"<sampler type="bogus">"#),
            r#"<sampler type="bogus""#,
            r#"<sampler type="bogus">"#,
            "not one of Mitsuba 3's",
        ),
        (
            body(rect).replace(
                r#"<rfilter type="box"/>"#,
                r#"<rfilter type="box"/><string name="pixel_format" value="luminance"/>"#,
            ),
            r#"name="pixel_format""#,
            r#"<string name="pixel_format">"#,
            "pixel_format \"luminance\" is not supported",
        ),
        (
            body(r#"<shape type="sphere"><bsdf type="dielectric"><string name="int_ior" value="1.6"/></bsdf></shape>"#),
            r#"name="int_ior""#,
            r#"<string name="int_ior">"#,
            "unknown index of refraction \"1.6\"",
        ),
        // errors named where they are (until the forty-fourth session an rr_depth of 0 was
        // reported at max_depth, a sample_count of 0 at the integrator's spp, a mesh file's
        // error at the converted shape only, a repeated property as "not supported")
        (
            body(rect).replace(
                r#"<integer name="max_depth" value="3"/>"#,
                r#"<integer name="max_depth" value="3"/>
        <integer name="rr_depth" value="0"/>"#,
            ),
            r#"name="rr_depth""#,
            r#"<integer name="rr_depth">"#,
            "rr_depth must be at least 1",
        ),
        (
            body(rect).replace(r#"name="sample_count" value="2""#, r#"name="sample_count" value="0""#),
            r#"name="sample_count""#,
            r#"<integer name="sample_count">"#,
            "sample_count must be >= 1",
        ),
        (
            body(
                r#"<shape type="ply"><string name="filename" value="missing.ply"/><boolean name="face_normals" value="true"/></shape>"#,
            ),
            r#"<shape type="ply""#,
            r#"<shape type="ply">"#,
            "PLY file",
        ),
        (
            body(
                r#"<shape type="rectangle"><bsdf type="diffuse"><float name="reflectance" value="0.2"/><float name="reflectance" value="0.3"/></bsdf></shape>"#,
            ),
            r#"<float name="reflectance" value="0.3""#,
            r#"<float name="reflectance">"#,
            "given twice",
        ),
        (
            body(r#"<shape type="rectangle"><emitter type="point"/></shape>"#),
            r#"<emitter type="point""#,
            r#"<emitter type="point">"#,
            "only an area emitter goes inside a <shape>",
        ),
    ]);
    // textures are refused whatever their type, naming the element and its line
    for ty in ["bitmap", "checkerboard"] {
        rows.push((texture(ty), "<texture", "<texture type=", "textures are not supported"));
    }
    rows
}

/// A mesh that Mitsuba shades with its vertex normals (`face_normals` not true) has its
/// front where those normals point, mirrored or not (helper 41: an emitting box whose
/// normals point in shone 1.0 here and 0 in Mitsuba). Normals that disagree from face to face
/// are refused where the side matters.
#[test]
fn a_smooth_mesh_faces_where_its_normals_point() {
    let dir = tempfile::tempdir().unwrap();
    // a square in z = 0 wound counter-clockwise seen from +z, normals ±z
    let obj = |vn: &str| format!("v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn 0 0 {vn}\nf 1//1 2//1 3//1 4//1\n");
    std::fs::write(dir.path().join("out.obj"), obj("1")).unwrap();
    std::fs::write(dir.path().join("in.obj"), obj("-1")).unwrap();
    std::fs::write(
        dir.path().join("mixed.obj"),
        "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn 0 0 1\nvn 0 0 -1\nf 1//1 2//1 3//1\nf 1//2 3//2 4//2\n",
    )
    .unwrap();
    let shape = |file: &str, transform: &str| {
        format!(
            r#"<shape type="obj"><string name="filename" value="{file}"/>{transform}<emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>"#
        )
    };
    let mirror = r#"<transform name="to_world"><scale z="-1"/></transform>"#;
    let z_of = |file: &str, transform: &str| {
        let s = load_in(dir.path(), "s.xml", &scene_text(&shape(file, transform))).unwrap_or_else(|e| panic!("{e}"));
        normal(&s, s.shapes[0].first_tri as usize).z
    };
    assert!(z_of("out.obj", "") > 0.99);
    assert!(z_of("in.obj", "") < -0.99, "the normals point to -z");
    // mirrored in z: the vertices stay, the normals keep their side as normals do
    assert!(z_of("out.obj", mirror) < -0.99);
    assert!(z_of("in.obj", mirror) > 0.99);
    let err = load_in(dir.path(), "s.xml", &scene_text(&shape("mixed.obj", ""))).expect_err("mixed normals");
    for part in [
        "<shape type=\"obj\">",
        "mixed.obj",
        "against the winding on 1 of its 2 faces",
        "face_normals",
    ] {
        assert!(err.contains(part), "no {part:?} in {err}");
    }
}

/// A PLY mesh whose vertex coordinates are integers: Mitsuba 3 does not read them as metres
/// (its mesh all but vanished against ours in an independent sweep, helper 41), so the import
/// refuses it, naming the shape and the file; the same mesh with float coordinates loads.
#[test]
fn a_ply_with_integer_coordinates_is_refused() {
    let dir = tempfile::tempdir().unwrap();
    let ply = |ty: &str| {
        format!(
            "ply\nformat ascii 1.0\nelement vertex 3\nproperty {ty} x\nproperty {ty} y\nproperty {ty} z\n\
             element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
        )
    };
    let xml = scene_text(
        r#"<shape type="ply"><string name="filename" value="m.ply"/><boolean name="face_normals" value="true"/></shape>"#,
    );
    std::fs::write(dir.path().join("m.ply"), ply("int")).unwrap();
    let err = load_in(dir.path(), "s.xml", &xml).expect_err("integer coordinates");
    for part in ["<shape type=\"ply\">", "m.ply", "x is int", "store them as float"] {
        assert!(err.contains(part), "no {part:?} in {err}");
    }
    std::fs::write(dir.path().join("m.ply"), ply("float")).unwrap();
    load_in(dir.path(), "s.xml", &xml).unwrap();
}

#[test]
fn inputs_outside_the_subset_name_the_file_the_element_and_its_line() {
    let dir = tempfile::tempdir().unwrap();
    for (k, (text, marker, element, what)) in bad_cases().into_iter().enumerate() {
        let name = format!("bad{k}.xml");
        let err = load_in(dir.path(), &name, &text).expect_err(&text);
        let line = if marker.is_empty() {
            None
        } else {
            let at = text
                .find(marker)
                .unwrap_or_else(|| panic!("case {k}: marker {marker} not in the text"));
            Some(1 + text[..at].matches('\n').count())
        };
        assert!(
            err.starts_with(&dir.path().join(&name).display().to_string()),
            "case {k}: {err}"
        );
        assert!(err.contains(element), "case {k}: no {element:?} in {err}");
        if let Some(l) = line {
            assert!(err.contains(&format!("(line {l})")), "case {k}: no line {l} in {err}");
        }
        assert!(err.contains(what), "case {k}: no {what:?} in {err}");
    }
}

#[test]
fn cli_renders_xml_and_imports_it_to_toml() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let xml = common::scene_path("cornell_box.xml");
    let xml = xml.to_str().unwrap();
    let o = common::dtr(&["render", xml, "--spp", "1", "-o", "x", "-q"], d);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // the converter's TOML, written elsewhere (a folder it makes, as dtr render does),
    // renders the same bytes
    assert!(!d.join("sub").exists());
    let o = common::dtr(&["import", xml, "-o", "sub/cornell.toml"], d);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = common::dtr(&["render", "sub/cornell.toml", "--spp", "1", "-o", "y", "-q"], d);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(
        std::fs::read(d.join("x.npy")).unwrap(),
        std::fs::read(d.join("y.npy")).unwrap()
    );
    // printed without -o
    let o = common::dtr(&["import", xml], d);
    assert!(String::from_utf8_lossy(&o.stdout).contains("[[shape]]\nname = \"tall_box\""));
    // a relative mesh path still resolves from another folder
    std::fs::create_dir(d.join("meshes")).unwrap();
    std::fs::copy(common::scene_path("meshes/pyramid.obj"), d.join("meshes/pyramid.obj")).unwrap();
    std::fs::write(
        d.join("m.xml"),
        scene_text(r#"<shape type="obj"><string name="filename" value="meshes/pyramid.obj"/></shape>"#),
    )
    .unwrap();
    let o = common::dtr(&["import", "m.xml", "-o", "sub/m.toml"], d);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let o = common::dtr(&["info", "sub/m.toml"], d);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // a mesh Mitsuba shades smooth (no face_normals) is rendered with face normals here: said
    // once, naming the file and the element (silent until the forty-third session); not with
    // face_normals true
    let o = common::dtr(&["render", "m.xml", "--spp", "1", "-o", "m"], d);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert_eq!(err.matches("face_normals is not true").count(), 1, "{err}");
    assert!(err.contains("m.xml: <shape type=\"obj\"> (line 9)"), "{err}");
    std::fs::write(
        d.join("flat.xml"),
        scene_text(
            r#"<shape type="obj"><string name="filename" value="meshes/pyramid.obj"/><boolean name="face_normals" value="true"/></shape>"#,
        ),
    )
    .unwrap();
    let o = common::dtr(&["render", "flat.xml", "--spp", "1", "-o", "flat"], d);
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success() && !err.contains("face_normals"), "{err}");
    // bad input: exit status 2, the file and the line on stderr, nothing written
    std::fs::write(d.join("bad.xml"), scene_text(r#"<shape type="disk"/>"#)).unwrap();
    for args in [
        &["import", "bad.xml", "-o", "bad.toml"][..],
        &["render", "bad.xml", "-o", "bad"],
    ] {
        let o = common::dtr(args, d);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains("bad.xml") && err.contains("<shape type=\"disk\"> (line 9)"),
            "{err}"
        );
    }
    assert!(!d.join("bad.toml").exists() && !d.join("bad.npy").exists());
    // the output must be TOML and must not replace the input
    let o = common::dtr(&["import", "m.xml", "-o", "m.xml"], d);
    assert_eq!(o.status.code(), Some(2));
    // an earlier import is replaced; a TOML file of the user's is not (before: replaced, exit 0)
    let o = common::dtr(&["import", "m.xml", "-o", "sub/m.toml"], d);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::write(d.join("mine.toml"), "# my scene\n").unwrap();
    import_is_refused(
        d,
        &["m.xml", "-o", "mine.toml"],
        "mine.toml",
        "not a description dtr import wrote",
    );
}

/// `dtr import ARGS` run in `d` exits 2 with a message naming `file` and saying `says`, and
/// leaves `file` (in `d`) as it was.
fn import_is_refused(d: &Path, args: &[&str], file: &str, says: &str) {
    let before = std::fs::read(d.join(file)).unwrap();
    let args: Vec<&str> = std::iter::once("import").chain(args.iter().copied()).collect();
    let o = common::dtr(&args, d);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(err.contains(file) && err.contains(says), "{err}");
    assert_eq!(std::fs::read(d.join(file)).unwrap(), before);
}

/// `dtr import -o` refuses an output that is a mesh the XML names, as `dtr render` refuses an
/// output that would replace an input: before, the mesh was replaced by the TOML (exit 0).
#[test]
fn import_never_replaces_a_mesh_it_reads() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // a mesh file whose name ends in .toml, as the output must
    std::fs::copy(common::scene_path("meshes/pyramid.obj"), d.join("mesh.toml")).unwrap();
    std::fs::write(
        d.join("mm.xml"),
        scene_text(r#"<shape type="obj" id="pyr"><string name="filename" value="mesh.toml"/></shape>"#),
    )
    .unwrap();
    let before = std::fs::read(d.join("mesh.toml")).unwrap();
    import_is_refused(
        d,
        &["mm.xml", "-o", "mesh.toml"],
        "mesh.toml",
        "would replace the input",
    );
    // another spelling of the same file, from another folder, is refused too
    std::fs::create_dir(d.join("sub")).unwrap();
    let o = common::dtr(&["import", "../mm.xml", "-o", "../mesh.toml"], &d.join("sub"));
    assert_eq!(o.status.code(), Some(2), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(std::fs::read(d.join("mesh.toml")).unwrap(), before);
}

/// An error found when the converted description is resolved names the XML file, not the
/// output that was never written (before: "out.toml: <sensor ...> (line 5) ..."). (A width
/// of −64 was that error until the import itself refused widths below 1, naming the film:
/// `a_film_of_no_rows_or_columns_is_refused_naming_the_film`; a width above the resolution
/// cap is still found only when the description is resolved.)
#[test]
fn import_errors_name_the_xml_file() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = scene_text("").replace(
        r#"<integer name="width" value="8"/>"#,
        r#"<integer name="width" value="100000000"/>"#,
    );
    std::fs::write(d.join("in.xml"), text).unwrap();
    let o = common::dtr(&["import", "in.xml", "-o", "out.toml"], d);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("in.xml: <sensor") && err.contains("resolution[0]"),
        "{err}"
    );
    assert!(!err.contains("out.toml"), "{err}");
    assert!(!d.join("out.toml").exists());
}

#[test]
fn truncated_and_mutated_xml_never_panics() {
    use difftransient::scene::{Format, mitsuba};
    let path = common::scene_path("mitsuba_features.xml");
    let text = std::fs::read_to_string(&path).unwrap();
    let load = |t: &str| {
        if let Ok(imported) = mitsuba::import_str(t, &path) {
            let _ = Scene::from_str(&imported.toml, Format::Toml, &path, &[]);
        }
    };
    // every prefix (at character boundaries, every 5th byte)
    for i in (0..text.len()).step_by(5).filter(|&i| text.is_char_boundary(i)) {
        load(&text[..i]);
    }
    // every number replaced by values outside what it may hold
    let mut starts = Vec::new();
    for (i, c) in text.char_indices() {
        if c.is_ascii_digit() && !text[..i].ends_with(|p: char| p.is_ascii_digit() || p == '.') {
            starts.push(i);
        }
    }
    let mut refused = 0;
    for &i in &starts {
        let end = text[i..]
            .find(|c: char| !(c.is_ascii_digit() || c == '.' || c == 'e' || c == '-'))
            .map_or(text.len(), |e| i + e);
        for bad in ["nan", "inf", "1e400", "1e39", "-7", "0", "99999999999", ""] {
            let t = format!("{}{}{}", &text[..i], bad, &text[end..]);
            let ok = mitsuba::import_str(&t, &path)
                .map_err(|e| e.to_string())
                .and_then(|im| Scene::from_str(&im.toml, Format::Toml, &path, &[]).map_err(|e| e.to_string()));
            if let Err(e) = ok {
                assert!(e.contains("mitsuba_features.xml") && !e.contains('\n'), "{e}");
                refused += 1;
            }
        }
    }
    assert!(
        starts.len() > 50 && refused > starts.len(),
        "{} numbers, {refused} refused",
        starts.len()
    );
}

/// A `max_depth` past our largest depth (max_bounces 1024, the TOML loader's limit) is
/// refused naming the XML file, the element and its line, by `dtr import` and `dtr render`
/// alike; -1 (Mitsuba's unbounded) still imports as max_bounces = 1024. Before, 100000 was
/// quietly clamped to 1024 and imported with exit 0.
#[test]
fn import_refuses_a_max_depth_beyond_the_largest() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let depth = |v: &str| {
        scene_text(r#"<shape type="rectangle"/>"#).replace(
            r#"name="max_depth" value="3""#,
            &format!(r#"name="max_depth" value="{v}""#),
        )
    };
    std::fs::write(d.join("deep.xml"), depth("100000")).unwrap();
    for args in [
        &["import", "deep.xml", "-o", "deep.toml"][..],
        &["render", "deep.xml", "-o", "deep", "-q"],
    ] {
        let o = common::dtr(args, d);
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(
            err.contains("deep.xml: <integer name=\"max_depth\"> (line 2)")
                && err.contains("max_depth 100000")
                && err.contains("1025"),
            "{err}"
        );
    }
    assert!(!d.join("deep.toml").exists() && !d.join("deep.npy").exists());
    // the largest depth and -1 import as our largest max_bounces
    for v in ["1025", "-1"] {
        std::fs::write(d.join("ok.xml"), depth(v)).unwrap();
        let o = common::dtr(&["import", "ok.xml"], d);
        let out = String::from_utf8_lossy(&o.stdout);
        assert!(out.contains("max_bounces = 1024"), "{v}: {out}");
    }
}

/// `dtr import -o` makes a missing output folder, as `dtr render -o` does; an output it cannot
/// write is exit 3 with the operating system's reason said once. Before, a missing folder was
/// exit 3 and its reason was printed twice.
#[test]
fn import_makes_the_output_folder_and_says_a_failure_once() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let xml = common::scene_path("cornell_box.xml");
    let xml = xml.to_str().unwrap();
    let o = common::dtr(&["import", xml, "-o", "new/deeper/cornell.toml"], d);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = std::fs::read_to_string(d.join("new/deeper/cornell.toml")).unwrap();
    assert!(text.contains("[[shape]]"));
    // a folder that cannot be made: its parent is a file
    std::fs::write(d.join("plain"), "not a folder").unwrap();
    let o = common::dtr(&["import", xml, "-o", "plain/cornell.toml"], d);
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(3), "{err}");
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(err.contains("plain"), "{err}");
    let reason = err.rsplit(": ").next().unwrap();
    assert_eq!(err.matches(reason).count(), 1, "said twice: {err}");
    assert_eq!(std::fs::read_to_string(d.join("plain")).unwrap(), "not a folder");
}

/// A film of width or height 0 is refused naming the film element and the size. With
/// fov_axis x (Mitsuba's default) a height of 0 made the vertical field of view 0, and the
/// error named `fov` (independent audit).
#[test]
fn a_film_of_no_rows_or_columns_is_refused_naming_the_film() {
    let dir = tempfile::tempdir().unwrap();
    for (w, h) in [(8, 0), (0, 8), (-64, 8)] {
        let text = scene_text("").replace(
            r#"<integer name="width" value="8"/><integer name="height" value="8"/>"#,
            &format!(r#"<integer name="width" value="{w}"/><integer name="height" value="{h}"/>"#),
        );
        let e = load_in(dir.path(), "flat.xml", &text).unwrap_err();
        assert!(
            e.contains("flat.xml") && e.contains("<film") && e.contains(&format!("got width {w}, height {h}")),
            "{w}x{h}: {e}"
        );
        assert!(!e.contains("'fov'"), "{w}x{h}: {e}");
    }
}

/// Two elements of one id are refused, as Mitsuba 3 refuses them, whatever their kinds: the
/// error names the second element, its line and the id, and the first element and its line.
/// Before, only two `<bsdf>` of one id were refused: a second `<shape>` or `<emitter>` (or an
/// area emitter named like a shape) was renamed "floor_2" without a word (independent audit).
#[test]
fn two_elements_of_one_id_are_refused_naming_both() {
    let dir = tempfile::tempdir().unwrap();
    let white = r#"<bsdf type="diffuse" id="white"/>"#;
    let cases = [
        (
            r#"<shape type="rectangle" id="floor"/>
<shape type="cube" id="floor"/>"#,
            r#"<shape type="rectangle" id="floor"> (line "#,
            r#"<shape type="cube" id="floor"> (line "#,
        ),
        (
            r#"<shape type="rectangle" id="floor"/>
<shape type="cube"><emitter type="area" id="floor"><rgb name="radiance" value="1"/></emitter></shape>"#,
            r#"<shape type="rectangle" id="floor"> (line "#,
            r#"<emitter type="area" id="floor"> (line "#,
        ),
        (
            r#"<emitter type="point" id="lamp"><point name="position" value="0, 1, 2"/><rgb name="intensity" value="1"/></emitter>
<emitter type="point" id="lamp"><point name="position" value="0, 1, 3"/><rgb name="intensity" value="1"/></emitter>
<shape type="rectangle"/>"#,
            r#"<emitter type="point" id="lamp"> (line "#,
            r#"<emitter type="point" id="lamp"> (line "#,
        ),
        (
            r#"<bsdf type="diffuse" id="white"/>
<shape type="rectangle"><ref id="white"/></shape>"#,
            r#"<bsdf type="diffuse" id="white"> (line "#,
            r#"<bsdf type="diffuse" id="white"> (line "#,
        ),
    ];
    for (k, (body, first, second)) in cases.into_iter().enumerate() {
        let text = scene_text(&format!("{white}\n{body}"));
        let id = if k == 2 {
            "lamp"
        } else if k == 3 {
            "white"
        } else {
            "floor"
        };
        let lines: Vec<usize> = text
            .lines()
            .enumerate()
            .filter(|(_, l)| l.contains(&format!("id=\"{id}\"")) && !l.contains("<ref"))
            .map(|(i, _)| i + 1)
            .collect();
        assert_eq!(lines.len(), 2, "case {k}: {text}");
        let e = load_in(dir.path(), "dup.xml", &text).expect_err(&text);
        assert!(
            e.contains("dup.xml")
                && e.contains(&format!("{second}{})", lines[1]))
                && e.contains(&format!("a second element with id \"{id}\""))
                && e.contains(&format!("{first}{})", lines[0])),
            "case {k}: {e}"
        );
    }
}
