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
        holed,
        one_flipped,
        flipped(&cube),
        shapes::icosphere(2),
    ]);
    assert_eq!(
        ShapeSums::new(&geo, 7).closed,
        [true, false, false, false, true, true, false]
    );
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
    let w = |p: [f64; 3]| winding_numbers(&ball, &[true], DVec3::from_array(p))[0].unwrap();
    assert!((w([0.1, 0.2, -0.3]) - 1.0).abs() < 1e-9);
    assert!(w([0.9, 0.9, 0.0]).abs() < 1e-9);
    assert!(winding_numbers(&ball, &[false], DVec3::ZERO)[0] == Some(0.0));
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
    let scene = ctx.scene;
    let eye = scene.camera.position;
    let geo = &scene.geometry;
    let boxed = scene.shapes.iter().position(|s| s.name == "box").unwrap() as u32;
    let tris: Vec<usize> = (0..geo.indices.len()).filter(|&t| geo.tri_shape[t] == boxed).collect();
    let mut silhouette = Vec::new();
    for &a in &tris {
        for &b in &tris {
            let shared: Vec<u32> = geo.indices[a]
                .into_iter()
                .filter(|i| geo.indices[b].contains(i))
                .collect();
            if a < b && shared.len() == 2 {
                let [p, q] = [0, 1].map(|k| geo.positions[shared[k] as usize]);
                if facing(ctx, a, (p + q) * 0.5) != facing(ctx, b, (p + q) * 0.5) {
                    silhouette.push((p, q));
                }
            }
        }
    }
    assert!(silhouette.len() >= 4, "{} silhouette edges", silhouette.len());
    silhouette
        .iter()
        .flat_map(|&(p, q)| {
            (0..per_edge).map(move |j| (p + (q - p) * ((j as f32 + 0.5) / per_edge as f32) - eye).normalize())
        })
        .collect()
}

/// Whether triangle `t` faces the camera at its point `p`.
fn facing(ctx: &RenderContext, t: usize, p: Vec3) -> bool {
    crate::scene::triangle_normal(ctx.tri_verts[t]).dot(p - ctx.scene.camera.position) < 0.0
}

/// For each of `dirs`, traced from the camera in packets of 8 as the kernels do: `Some(true)`
/// where the first hit is on the box's face turned away from the camera, `Some(false)` on the
/// face turned towards it, `None` off the box (rounding may take a ray past the silhouette).
pub(crate) fn meets_the_inside(ctx: &RenderContext, dirs: &[Vec3]) -> Vec<Option<bool>> {
    let eye = ctx.scene.camera.position;
    let boxed = ctx.scene.shapes.iter().position(|s| s.name == "box").unwrap() as u32;
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
                (prim != u32::MAX && ctx.scene.geometry.tri_shape[prim as usize] == boxed)
                    .then(|| !facing(ctx, prim as usize, eye + *dir)),
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

/// Camera rays aimed exactly at points of the box's silhouette edges (as rounding allows)
/// meet either face there. The ones reported on the back-facing face start no path, so they
/// give the film nothing; the others do as before. Before the check, such rays lit their
/// hit through the crack along the edge and sent paths into the box (BDPT's camera subpaths:
/// `bdpt::walk::tests::camera_subpaths_do_not_enter_a_closed_shape_at_its_edge`).
#[test]
fn camera_rays_that_meet_a_closed_shape_from_inside_start_no_path() {
    let scene = load(BOX, &[]);
    let device = Device::new("threads=1").unwrap();
    let ctx = box_context(&scene, &device);
    let dirs = silhouette_rays(&ctx, 1024);
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
            own: [[u32::MAX; 2]; 8],
        };
        rays.dirs[..chunk.len()].copy_from_slice(chunk);
        trace_packet_from::<Dual8<1>, 3, _>(&ctx, 5, &lanes, PathStart::Rays(&rays), &mut sink, &mut counts);
    }
    let met = meets_the_inside(&ctx, &dirs);
    let inside: Vec<usize> = (0..n).filter(|&i| met[i] == Some(true)).collect();
    let outside: Vec<usize> = (0..n).filter(|&i| met[i] == Some(false)).collect();
    let lit = |set: &[usize]| set.iter().filter(|&&i| sink.0[i].0 > 0.0).count();
    println!(
        "{} rays: {} met the back-facing face ({} of them lit), {} the front ({} lit); largest |ḟ| {:.3e}",
        n,
        inside.len(),
        lit(&inside),
        outside.len(),
        lit(&outside),
        sink.0.iter().map(|s| s.1).fold(0.0, f64::max)
    );
    assert!(
        inside.len() >= n / 20,
        "too few rays met the back-facing face to test: {}",
        inside.len()
    );
    for &i in &inside {
        assert_eq!(
            sink.0[i],
            (0.0, 0.0),
            "ray {i} met the box's inside and its path reached the film"
        );
    }
    assert!(
        lit(&outside) >= outside.len() / 2,
        "the rays that met the front are lit as before"
    );
}
