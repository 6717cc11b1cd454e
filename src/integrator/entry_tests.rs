use super::*;
use crate::accel::Device;
use crate::integrator::context::RenderContext;
use crate::integrator::deposit::{LaneContribution, PathCounts};
use crate::integrator::path::{PacketLanes, PathStart, PrimaryRays, trace_packet_from};
use crate::integrator::sink::Sink;
use crate::integrator::testutil::load;
use crate::kernel::Dual8;
use crate::params::lanes::Motion;
use crate::scene::shapes;
use crate::scene::testutil::{geometry_of, header};
use wide::f32x8;

fn flipped(m: &shapes::Mesh) -> shapes::Mesh {
    let mut m = m.clone();
    m.tris.iter_mut().for_each(|t| t.swap(1, 2));
    m
}

/// `m` with its own three vertices for each triangle, as a mesh with a seam along every edge.
fn unwelded(m: &shapes::Mesh) -> shapes::Mesh {
    shapes::Mesh {
        positions: m.tris.iter().flat_map(|t| t.map(|i| m.positions[i as usize])).collect(),
        tris: (0..m.tris.len() as u32)
            .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
            .collect(),
    }
}

#[test]
fn only_meshes_closed_with_one_orientation_count_as_closed() {
    let cube = shapes::cube();
    let mut holed = cube.clone();
    holed.tris.pop();
    let mut one_flipped = cube.clone();
    one_flipped.tris[3].swap(1, 2);
    let geo = geometry_of(&[
        cube.clone(),
        shapes::rectangle(),
        holed.clone(),
        one_flipped,
        flipped(&cube),
        shapes::icosphere(2),
        unwelded(&cube),
        unwelded(&holed),
    ]);
    let bodies = Bodies::new(&geo, 9);
    let closed: Vec<bool> = (0..9).map(|s| bodies.closed[bodies.of_shape[s] as usize]).collect();
    assert_eq!(closed, [true, false, false, false, true, true, true, false, false]);
}

/// `m`'s faces (pairs of triangles) as meshes of their own, `flip` of them wound the other way.
fn faces_of(m: &shapes::Mesh, flip: &[usize]) -> Vec<shapes::Mesh> {
    m.tris
        .chunks(2)
        .enumerate()
        .map(|(f, pair)| {
            let face = shapes::Mesh {
                positions: m.positions.clone(),
                tris: pair.to_vec(),
            };
            if flip.contains(&f) { flipped(&face) } else { face }
        })
        .collect()
}

/// Open shapes that close a surface together along shared edges are one closed body (a box
/// of six rectangles); five of them (a room without its front), or six with one wound the
/// other way, are open. Closed shapes and shapes that share no edge stay bodies of their own.
#[test]
fn open_shapes_that_close_a_surface_together_are_one_closed_body() {
    let cube = shapes::cube();
    let six = faces_of(&cube, &[]);
    assert_eq!(six.len(), 6);
    let apart = |m: &shapes::Mesh, by: f32| shapes::Mesh {
        positions: m.positions.iter().map(|p| *p + Vec3::splat(by)).collect(),
        tris: m.tris.clone(),
    };
    // a box of six faces, a room of five (moved off the box), six with one flipped (moved
    // further), a cube and a lone rectangle
    let mut meshes: Vec<shapes::Mesh> = six.iter().map(unwelded).collect();
    meshes.extend(six[..5].iter().map(|f| apart(f, 10.0)));
    meshes.extend(faces_of(&cube, &[2]).iter().map(|f| apart(f, 20.0)));
    meshes.push(apart(&cube, 30.0));
    meshes.push(apart(&shapes::rectangle(), 40.0));
    let n = meshes.len();
    let geo = geometry_of(&meshes);
    let bodies = Bodies::new(&geo, n);
    let body = |s: usize| bodies.of_shape[s] as usize;
    assert!((0..6).all(|s| body(s) == body(0)), "the six faces are one body");
    assert!(
        (6..11).all(|s| body(s) == body(6)) && body(6) != body(0),
        "the room is another"
    );
    assert!((11..17).all(|s| body(s) == body(11)));
    assert_eq!(
        [0, 6, 11, 17, 18].map(|s| bodies.closed[body(s)]),
        [true, false, false, true, false]
    );
    assert_eq!(bodies.closed.len(), 5);
    // the body's volume is the cube's (six times 8, outward)
    assert!(
        (bodies.volume[body(0)] - 48.0).abs() < 1e-9,
        "{}",
        bodies.volume[body(0)]
    );
    // and the camera's side of it, from outside and inside
    let side = |eye: [f32; 3]| EntrySides::new(&geo, n, Vec3::from_array(eye)).sides[0];
    assert_eq!(side([0.3, 2.5, -4.0]), Side::Front);
    assert_eq!(side([0.2, -0.3, 0.9]), Side::Back);
}

#[test]
fn the_camera_side_follows_the_winding_and_where_the_camera_is() {
    let cube = shapes::cube();
    let geo = geometry_of(&[cube.clone(), flipped(&cube), shapes::icosphere(3)]);
    let first = |s: u32| geo.tri_shape.iter().position(|&t| t == s).unwrap();
    let side = |s: u32, eye: [f32; 3]| {
        let e = EntrySides::new(&geo, 3, Vec3::from_array(eye));
        e.sides.get(first(s)).copied().unwrap_or(Side::Any)
    };
    // outward normals: seen from outside, the front; from inside (a room), the back
    assert_eq!(side(0, [0.3, 2.5, -4.0]), Side::Front);
    assert_eq!(side(0, [0.2, -0.3, 0.9]), Side::Back);
    // inward normals: the other way round
    assert_eq!(side(1, [0.3, 2.5, -4.0]), Side::Back);
    assert_eq!(side(1, [0.2, -0.3, 0.9]), Side::Front);
    // on the surface: not checked
    assert_eq!(side(0, [0.2, -0.3, 1.0]), Side::Any);
    // inside the ball's bounding box but outside the ball, and inside it
    assert_eq!(side(2, [0.9, 0.9, 0.0]), Side::Front);
    assert_eq!(side(2, [0.1, 0.2, -0.3]), Side::Back);
    let ball = geometry_of(&[shapes::icosphere(3)]);
    let w = |p: [f64; 3]| winding_numbers(&ball, &[0], &[true], DVec3::from_array(p))[0].unwrap();
    assert!((w([0.1, 0.2, -0.3]) - 1.0).abs() < 1e-9);
    assert!(w([0.9, 0.9, 0.0]).abs() < 1e-9);
    assert!(winding_numbers(&ball, &[0], &[false], DVec3::ZERO)[0] == Some(0.0));
}

/// A box seen by a camera, lit by a point light beside the camera (on the side of the box's
/// back-facing faces' planes the camera is on), with a wall behind it.
pub(crate) const BOX: &str = concat!(
    header!(),
    r#"
[[shape]]
name = "box"
type = "cube"
material = "white"
translate = [-0.33, 0.1, -0.29]
rotate = [0.0, 17.0, 0.0]
scale = [0.3, 0.6, 0.3]

[[shape]]
name = "wall"
type = "rectangle"
material = "white"
translate = [0.0, 0.0, -1.5]
scale = 3.0

[[emitter]]
name = "lamp"
type = "point"
position = [0.4, 0.5, 3.0]
intensity = 10.0

[[param]]
name = "box_x"
kind = "translate"
shape = "box"
axis = "x"
value = -0.33
"#
);

/// [`BOX`] with each `(from, to)` replaced (each `from` must be in it), as
/// `scene::testutil::mini_with` edits its scene.
fn box_with(edits: &[(&str, &str)]) -> String {
    edits.iter().fold(BOX.to_string(), |text, (from, to)| {
        assert!(text.contains(from), "{from:?} not in BOX");
        text.replacen(from, to, 1)
    })
}

/// The triangles of the shape named `name`, or with `name` "box", of the box: every shape
/// whose name starts with "box" (one, or the faces of [`box_of_faces`]).
fn triangles_of(scene: &crate::scene::Scene, name: &str) -> Vec<usize> {
    let named = |s: u32| match name {
        "box" => in_the_box(scene, s),
        _ => scene.shapes[s as usize].name == name,
    };
    let tris: Vec<usize> = (0..scene.geometry.indices.len())
        .filter(|&t| named(scene.geometry.tri_shape[t]))
        .collect();
    assert!(!tris.is_empty(), "no shape {name:?}");
    tris
}

/// Whether shape `s` is (a part of) the box.
fn in_the_box(scene: &crate::scene::Scene, s: u32) -> bool {
    scene.shapes[s as usize].name.starts_with("box")
}

/// What each ray's path gave the film: Σ|f| and Σ|ḟ| (film x = ray index).
struct PerRay(Vec<(f64, f64)>);

impl<const C: usize> Sink<C> for PerRay {
    fn add(&mut self, _: &RenderContext, _: (usize, usize), x: usize, _: usize, lc: &LaneContribution<C>, _: f32) {
        self.0[x].0 += lc.f.iter().map(|v| v.abs() as f64).sum::<f64>();
        self.0[x].1 += lc.fdot[..C].iter().map(|v| v.abs() as f64).sum::<f64>();
    }
}

/// The box's silhouette edges seen from the camera of [`BOX`] (shared by a triangle facing the
/// camera and one facing away), and `per_edge` directions from the camera aimed at points
/// evenly along each.
pub(crate) fn silhouette_rays(ctx: &RenderContext, per_edge: usize) -> Vec<Vec3> {
    let eye = ctx.scene.camera.position;
    silhouette_points(ctx, eye, per_edge)
        .into_iter()
        .map(|p| (p - eye).normalize())
        .collect()
}

/// `per_edge` points evenly along each of the box's silhouette edges seen from `eye`.
fn silhouette_points(ctx: &RenderContext, eye: Vec3, per_edge: usize) -> Vec<Vec3> {
    let geo = &ctx.scene.geometry;
    let tris = triangles_of(ctx.scene, "box");
    let mut silhouette = Vec::new();
    for &a in &tris {
        for &b in &tris {
            // the corners the two triangles share, by position (a mesh may repeat them)
            let corners = |t: usize| geo.indices[t].map(|i| geo.positions[i as usize]);
            let shared: Vec<Vec3> = corners(a).into_iter().filter(|p| corners(b).contains(p)).collect();
            if a < b && shared.len() == 2 {
                let [p, q] = [shared[0], shared[1]];
                if facing(ctx, a, eye, (p + q) * 0.5) != facing(ctx, b, eye, (p + q) * 0.5) {
                    silhouette.push((p, q));
                }
            }
        }
    }
    assert!(silhouette.len() >= 4, "{} silhouette edges", silhouette.len());
    silhouette
        .iter()
        .flat_map(|&(p, q)| (0..per_edge).map(move |j| p + (q - p) * ((j as f32 + 0.5) / per_edge as f32)))
        .collect()
}

/// Whether triangle `t` faces `eye` at its point `p`.
fn facing(ctx: &RenderContext, t: usize, eye: Vec3, p: Vec3) -> bool {
    crate::scene::triangle_normal(ctx.tri_verts[t]).dot(p - eye) < 0.0
}

/// For each of `dirs`, traced from the camera in packets of 8 as the kernels do: `Some(true)`
/// where the first hit is on the box's face turned away from the camera, `Some(false)` on the
/// face turned towards it, `None` off the box (rounding may take a ray past the silhouette).
pub(crate) fn meets_the_inside(ctx: &RenderContext, dirs: &[Vec3]) -> Vec<Option<bool>> {
    let eye = ctx.scene.camera.position;
    let mut counts = crate::integrator::trace::RayCounts::default();
    let mut out = Vec::new();
    for chunk in dirs.chunks(8) {
        let mut d = [Vec3::Z; 8];
        d[..chunk.len()].copy_from_slice(chunk);
        let on: [bool; 8] = std::array::from_fn(|i| i < chunk.len());
        let hit = crate::integrator::trace::intersect::<f32x8>(
            &ctx.accel,
            &V3::splat(eye),
            &V3::from_lane_vecs(&d),
            f32x8::ZERO,
            f32x8::splat(f32::INFINITY),
            <f32x8 as Real>::Mask::from_bools(&on),
            true,
            &mut counts,
        );
        for (i, dir) in chunk.iter().enumerate() {
            let prim = hit.prim[i];
            out.push(
                (prim != u32::MAX && in_the_box(ctx.scene, ctx.scene.geometry.tri_shape[prim as usize]))
                    .then(|| !facing(ctx, prim as usize, eye, eye + *dir)),
            );
        }
    }
    out
}

/// [`BOX`]'s context with `box_x` as the derivative's parameter.
pub(crate) fn box_context<'a>(scene: &'a crate::scene::Scene, device: &Device) -> RenderContext<'a> {
    let mut ctx = RenderContext::new(scene, device).unwrap();
    ctx.motion = Motion::build(scene, &["box_x".to_string()]).unwrap();
    ctx
}

/// Checks what the rays' paths gave the film (`sink`) against where their ray-form vertex
/// met the box (`met`, as [`meets_the_inside`]): at least 1/`share` of them met the face
/// turned away and none of those lit the film, at least half of those that met the face
/// turned towards them did. Returns the largest |ḟ| of any ray.
fn no_path_from_the_inside(sink: &PerRay, met: &[Option<bool>], share: usize, how: &str) -> f64 {
    let n = met.len();
    let inside: Vec<usize> = (0..n).filter(|&i| met[i] == Some(true)).collect();
    let outside: Vec<usize> = (0..n).filter(|&i| met[i] == Some(false)).collect();
    let lit = |set: &[usize]| set.iter().filter(|&&i| sink.0[i].0 > 0.0).count();
    let largest = sink.0.iter().map(|s| s.1).fold(0.0, f64::max);
    println!(
        "{n} rays: {} {how} the back-facing face ({} of them lit), {} the front ({} lit); largest |ḟ| {largest:.3e}",
        inside.len(),
        lit(&inside),
        outside.len(),
        lit(&outside),
    );
    assert!(
        inside.len() >= n / share,
        "too few rays {how} the back-facing face to test: {}",
        inside.len()
    );
    for &i in &inside {
        assert_eq!(
            sink.0[i],
            (0.0, 0.0),
            "ray {i} {how} the box's inside and its path reached the film"
        );
    }
    assert!(
        lit(&outside) >= outside.len() / 2,
        "the rays that {how} the front are lit as before"
    );
    largest
}

/// Camera rays aimed exactly at points of the box's silhouette edges (as rounding allows)
/// meet either face there. The ones reported on the back-facing face start no path, so they
/// give the film nothing; the others do as before. Before the check, such rays lit their
/// hit through the crack along the edge and sent paths into the box (BDPT's camera subpaths:
/// `bdpt::walk::tests::camera_subpaths_do_not_enter_a_closed_shape_at_its_edge`).
#[test]
fn camera_rays_that_meet_a_closed_shape_from_inside_start_no_path() {
    no_camera_path_through_the_edges(&load(BOX, &[]));
}

/// A cube in an OBJ file with a normal per face: the loader gives each face its own four
/// vertices (`shapes::load_obj`), so no edge joins two triangles by vertex index, only by
/// position. Before the closed test went by position, the box counted as open and its
/// back-facing faces were not checked.
const CUBE_OBJ: &str = "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\nv -1 1 1
vn 0 0 1\nvn 0 0 -1\nvn 1 0 0\nvn -1 0 0\nvn 0 1 0\nvn 0 -1 0
f 5//1 6//1 7//1 8//1\nf 1//2 4//2 3//2 2//2\nf 2//3 3//3 7//3 6//3
f 1//4 5//4 8//4 4//4\nf 4//5 8//5 7//5 3//5\nf 1//6 2//6 6//6 5//6
";

#[test]
fn camera_rays_that_meet_a_closed_mesh_with_seams_from_inside_start_no_path() {
    let text = box_with(&[("type = \"cube\"", "type = \"obj\"\nfile = \"cube.obj\"")]);
    let scene = crate::scene::testutil::load_text("box.toml", &text, &[("cube.obj", CUBE_OBJ)], &[]).unwrap();
    let corners = triangles_of(&scene, "box")
        .into_iter()
        .flat_map(|t| scene.geometry.indices[t])
        .collect::<std::collections::BTreeSet<u32>>();
    assert_eq!(corners.len(), 24, "each face its own vertices");
    no_camera_path_through_the_edges(&scene);
}

/// [`BOX`] with its box made of six shapes, one per face (each an OBJ file of one face of
/// [`CUBE_OBJ`], under the box's transform): "box" (the face z = +1, turned to the camera,
/// which `box_x` moves) and "box_1" … "box_5".
fn box_of_faces() -> crate::scene::Scene {
    let head = &CUBE_OBJ[..CUBE_OBJ.find("\nf ").unwrap() + 1];
    let faces: Vec<String> = CUBE_OBJ
        .lines()
        .filter(|l| l.starts_with("f "))
        .map(|f| format!("{head}{f}\n"))
        .collect();
    assert_eq!(faces.len(), 6);
    // the box's shape entry, from its name to its transform
    let cube = &BOX[BOX.find("name = \"box\"").unwrap()..BOX.find("\n\n[[shape]]\nname = \"wall\"").unwrap()];
    let shape = |name: &str, file: &str| {
        cube.replace("name = \"box\"", &format!("name = \"{name}\""))
            .replace("type = \"cube\"", &format!("type = \"obj\"\nfile = \"{file}\""))
            + "\n\n[[shape]]\n"
    };
    let shapes = (0..6)
        .map(|f| match f {
            0 => shape("box", "face0.obj"),
            _ => shape(&format!("box_{f}"), &format!("face{f}.obj")),
        })
        .collect::<String>()
        .trim_end_matches("\n\n[[shape]]\n")
        .to_string();
    let text = box_with(&[(cube, &shapes)]);
    let files: Vec<(String, String)> = (0..6).map(|f| (format!("face{f}.obj"), faces[f].clone())).collect();
    let files: Vec<(&str, &str)> = files.iter().map(|(n, t)| (n.as_str(), t.as_str())).collect();
    crate::scene::testutil::load_text("box.toml", &text, &files, &[]).unwrap()
}

/// A closed box made of several shapes is checked as one: camera rays through its
/// silhouette edges (where two of its shapes meet) that meet a face from inside start no
/// path, as with a box of one shape.
#[test]
fn camera_rays_that_meet_a_box_of_several_shapes_from_inside_start_no_path() {
    let scene = box_of_faces();
    assert_eq!(scene.shapes.iter().filter(|s| s.name.starts_with("box")).count(), 6);
    no_camera_path_through_the_edges(&scene);
}

/// Camera rays aimed at the silhouette edges of `scene`'s box: [`no_path_from_the_inside`].
fn no_camera_path_through_the_edges(scene: &crate::scene::Scene) {
    let device = Device::new("threads=1").unwrap();
    let ctx = box_context(scene, &device);
    let dirs = silhouette_rays(&ctx, 1024);
    let sink = trace_camera_rays(&ctx, &dirs);
    let largest = no_path_from_the_inside(&sink, &meets_the_inside(&ctx, &dirs), 20, "met");
    assert!(largest < 1e3, "largest |ḟ| {largest:.3e}");
}

/// [`BOX`] with its wall a mirror, the camera moved aside (to x = 2.5, z = 2) so that the
/// box does not hide its own image in the mirror, and the lamp between the box and the mirror
/// where it lights the faces the camera sees in the mirror.
fn mirror_box() -> String {
    box_with(&[
        (
            "material = \"white\"\ntranslate = [0.0, 0.0, -1.5]",
            "material = \"mirror\"\ntranslate = [0.0, 0.0, -1.5]",
        ),
        ("position = [0.0, 0.0, 3.0]", "position = [2.5, 0.0, 2.0]"),
        ("position = [0.4, 0.5, 3.0]", "position = [1.5, 0.5, -1.2]"),
    ]) + "\n[[material]]\nname = \"mirror\"\ntype = \"conductor\"\n"
}

/// The plane z = const of the mirror of [`mirror_box`] (it faces +z), in the render's frame.
fn mirror_z(ctx: &RenderContext) -> f32 {
    ctx.tri_verts[triangles_of(ctx.scene, "wall")[0]][0].z
}

/// Camera rays whose reflections in the mirror of [`mirror_box`] pass through (as rounding
/// allows) points of the box's silhouette edges seen from the camera's mirror image, in a
/// 5 × 5 grid of offsets of 10⁻⁷ of the distance around each. Aimed so that the reflected
/// ray, which starts off the mirror (`spawn_point`), runs through the point.
fn rays_reflected_at_the_silhouette(ctx: &RenderContext, per_edge: usize) -> Vec<Vec3> {
    let eye = ctx.scene.camera.position;
    let z = mirror_z(ctx);
    let image = Vec3::new(eye.x, eye.y, 2.0 * z - eye.z);
    let scale = ctx.scene.offset_scale;
    let on_mirror = |from: Vec3, to: Vec3| from + (to - from) * ((z - from.z) / (to.z - from.z));
    let mut dirs = Vec::new();
    for q in silhouette_points(ctx, image, per_edge) {
        let view = (q - image).normalize();
        let u = view.cross(Vec3::Y).normalize();
        let v = view.cross(u);
        let step = 1e-7 * (q - image).length();
        for (i, j) in (-2..=2).flat_map(|i| (-2..=2).map(move |j| (i as f32, j as f32))) {
            let target = q + (u * i + v * j) * step;
            let mut m = on_mirror(image, target);
            for _ in 0..3 {
                // the reflected ray's origin: off the mirror along its normal, then back along
                // the arrival (`spawn_point`)
                let eps = m.abs().max_element().max(scale) / 262_144.0;
                let c = Vec3::Z * eps - (m - eye).normalize() * eps;
                m = on_mirror(image, target - c);
            }
            dirs.push((m - eye).normalize());
        }
    }
    // only the rays that reach the mirror, so that each packet's second rays are all mirrored
    // as [`reflections_meet_the_inside`] traces them: a ray passing through an edge meets two
    // triangles at the same distance, and which is reported can depend on the other rays of
    // its packet
    let met = reflections_meet_the_inside(ctx, &dirs);
    (0..dirs.len()).filter(|&i| met[i].is_some()).map(|i| dirs[i]).collect()
}

/// For each of `dirs` from the camera of [`mirror_box`], as the path tracer continues it
/// (first vertex in ray form, mirrored, `spawn_point`): `Some(true)` where the reflected ray
/// first meets the box on a face turned away from it, `Some(false)` on one turned towards it,
/// `None` where the camera ray misses the mirror or the reflection misses the box. Traced in
/// packets of 8 as the path tracer does.
fn reflections_meet_the_inside(ctx: &RenderContext, dirs: &[Vec3]) -> Vec<Option<bool>> {
    use crate::integrator::path::ray_plane_point;
    use crate::integrator::surface::surface_at;
    use crate::integrator::trace::{RayCounts, intersect, spawn_point};
    let eye = ctx.scene.camera.position;
    let shape = |name: &str| ctx.scene.shapes.iter().position(|s| s.name == name).unwrap() as u32;
    let (boxed, mirror) = (shape("box"), shape("wall"));
    let on = |prim: u32, s: u32| prim != u32::MAX && ctx.scene.geometry.tri_shape[prim as usize] == s;
    let mut counts = RayCounts::default();
    let mut out = Vec::new();
    for chunk in dirs.chunks(8) {
        let mut d = [Vec3::Z; 8];
        d[..chunk.len()].copy_from_slice(chunk);
        let live: [bool; 8] = std::array::from_fn(|i| i < chunk.len());
        let all = <f32x8 as Real>::Mask::from_bools(&live);
        let (o, d) = (V3::splat(eye), V3::from_lane_vecs(&d));
        let far = f32x8::splat(f32::INFINITY);
        let hit = intersect::<f32x8>(&ctx.accel, &o, &d, f32x8::ZERO, far, all, true, &mut counts);
        // the vertex as the path tracer places it, in its number type
        let x = surface_at::<Dual8<1>>(ctx, &hit.prim, hit.u, hit.v);
        let p = ray_plane_point(&V3::from_value(o), &V3::from_value(d), &x.p, &x.n).value();
        let n = x.n.value();
        // the mirror direction as the path tracer draws it (`transport::scatter_lobes`)
        let lobes = crate::integrator::bsdf::Lobes::<f32x8, 3>::gather(ctx, &hit.prim);
        let u = f32x8::splat(0.5);
        let wi = lobes.value().sample(&n, &-d, u, u, u, true).wi;
        let from = spawn_point(&p, &n, &d, &wi, ctx.scene.offset_scale);
        let second = intersect::<f32x8>(&ctx.accel, &from, &wi, f32x8::ZERO, far, all, false, &mut counts);
        for i in 0..chunk.len() {
            let prim = second.prim[i];
            let start = Vec3::new(from.x.lane(i), from.y.lane(i), from.z.lane(i));
            let w = Vec3::new(wi.x.lane(i), wi.y.lane(i), wi.z.lane(i));
            out.push(
                (on(hit.prim[i], mirror) && on(prim, boxed)).then(|| !facing(ctx, prim as usize, start, start + w)),
            );
        }
    }
    out
}

/// Traces one path per direction from the camera with `box_x`'s derivative; what each gave.
fn trace_camera_rays(ctx: &RenderContext, dirs: &[Vec3]) -> PerRay {
    let n = dirs.len();
    let mut sink = PerRay(vec![(0.0, 0.0); n]);
    let mut counts = PathCounts::default();
    for (k, chunk) in dirs.chunks(8).enumerate() {
        let mut lanes = PacketLanes::row(k * 8, 0, chunk.len(), n, 1, 0);
        lanes
            .ids
            .iter_mut()
            .enumerate()
            .for_each(|(i, id)| *id = (k * 8 + i) as u64);
        let mut rays = PrimaryRays {
            dirs: [Vec3::Z; 8],
            limit: None,
            own: [[u32::MAX; 4]; 8],
        };
        rays.dirs[..chunk.len()].copy_from_slice(chunk);
        trace_packet_from::<Dual8<1>, 3, _>(ctx, 5, &lanes, PathStart::Rays(&rays), &mut sink, &mut counts);
    }
    sink
}

/// A mirror turns a camera ray into a ray-form vertex's ray (`bsdf::delta`): reflected through
/// the box's silhouette edge, it meets either face there, and the ones on the face turned
/// away from it have entered the box through the crack along the edge, as a camera ray can
/// (`camera_rays_that_meet_a_closed_shape_from_inside_start_no_path`). Their paths end there.
/// Before, all 125 such rays lit the film, with |ḟ| up to 1.5 × 10⁵.
#[test]
fn mirrored_rays_that_meet_a_closed_shape_from_inside_end_their_path() {
    let scene = load(&mirror_box(), &[]);
    let device = Device::new("threads=1").unwrap();
    let ctx = box_context(&scene, &device);
    let dirs = rays_reflected_at_the_silhouette(&ctx, 48);
    let sink = trace_camera_rays(&ctx, &dirs);
    let largest = no_path_from_the_inside(&sink, &reflections_meet_the_inside(&ctx, &dirs), 50, "reflected onto");
    assert!(largest < 1e3, "largest |ḟ| {largest:.3e}");
}

#[test]
fn crossings_toggle_per_shape_and_give_up_past_their_capacity() {
    let mut c = Crossings::default();
    assert_eq!(c.holds(7), Some(false));
    c.toggle(7);
    c.toggle(2);
    assert_eq!(
        (c.holds(7), c.holds(2), c.holds(3)),
        (Some(true), Some(true), Some(false))
    );
    c.toggle(7);
    assert_eq!((c.holds(7), c.holds(2)), (Some(false), Some(true)));
    for s in 10..10 + Crossings::MAX as u32 {
        c.toggle(s);
    }
    assert_eq!(c.holds(2), None, "one more shape than it holds");
    c.toggle(2);
    assert_eq!(c.holds(2), None, "and it stays unknown");
}

/// The turned rays of a path that crossed into smooth glass meet the glass's faces from
/// inside, and are let through: the path records its crossings. Were it not, these rays
/// would end their paths and the glass box would be dark. (The lamp is moved aside, where
/// it lights the wall the camera sees through the glass.)
#[test]
fn rays_refracted_into_a_closed_glass_shape_go_on_inside_it() {
    let glass = box_with(&[
        (
            "material = \"white\"\ntranslate = [-0.33",
            "material = \"glass\"\ntranslate = [-0.33",
        ),
        ("position = [0.4, 0.5, 3.0]", "position = [2.0, 1.5, -1.0]"),
    ]) + "\n[[material]]\nname = \"glass\"\ntype = \"dielectric\"\nint_ior = 1.5\n";
    let scene = load(&glass, &[]);
    let device = Device::new("threads=1").unwrap();
    let ctx = box_context(&scene, &device);
    // rays at the inner parts of the box's faces turned to the camera
    let eye = ctx.scene.camera.position;
    let corners: Vec<Vec3> = triangles_of(ctx.scene, "box")
        .into_iter()
        .flat_map(|t| ctx.tri_verts[t])
        .collect();
    let centre = corners.iter().sum::<Vec3>() / corners.len() as f32;
    let dirs: Vec<Vec3> = silhouette_points(&ctx, eye, 64)
        .into_iter()
        .map(|p| (p * 0.6 + centre * 0.4 - eye).normalize())
        .collect();
    let met = meets_the_inside(&ctx, &dirs);
    let on_front: Vec<usize> = (0..dirs.len()).filter(|&i| met[i] == Some(false)).collect();
    let sink = trace_camera_rays(&ctx, &dirs);
    let lit = on_front.iter().filter(|&&i| sink.0[i].0 > 0.0).count();
    println!("{} of {} rays into the glass lit", lit, on_front.len());
    assert!(on_front.len() >= dirs.len() / 2);
    assert!(lit * 10 >= on_front.len() * 9, "{lit} of {} lit", on_front.len());
}
