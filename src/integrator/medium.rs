//! Which medium a point or the side of a surface lies in, for paths that do not start at the
//! camera (the boundary stage's segments x_L → x_S and its subpaths, Algorithm 2).
//!
//! Media are assigned by the dielectrics' surfaces (`scene/materials.rs`): a dielectric's
//! normals point to its exterior, which is the scene's medium or the interior of the
//! dielectric named by its `exterior`; every other material has the same medium on both
//! sides. The path kernel tracks the medium from the camera on (it starts in the scene's and
//! changes at each refraction); a path started elsewhere asks here instead.

use super::context::RenderContext;
use super::surface::self_intersection_eps;
use super::trace::RayCounts;
use crate::kernel::V3;
use crate::scene::Material;
use glam::Vec3;

/// At most this many surfaces are passed on the way to the first dielectric one
/// ([`medium_around`]); past them the scene's medium is assumed.
const MAX_CROSSINGS: usize = 64;

/// The index on the side of triangle `prim` (unit geometric normal `n`) that `dir` points
/// into, when the triangle is a dielectric's surface: its interior index against the normal,
/// its exterior's along it. None for other materials (the same medium on both sides).
pub fn side_eta(ctx: &RenderContext, prim: u32, n: Vec3, dir: Vec3) -> Option<f32> {
    let m = ctx.tri_material[prim as usize];
    match ctx.scene.materials[m as usize].material {
        Material::Dielectric { int_ior, .. } => Some(if n.dot(dir) < 0.0 {
            int_ior
        } else {
            ctx.scene.exterior_eta(m)
        }),
        _ => None,
    }
}

/// Whether any material of the scene is a dielectric (else every point is in the scene's
/// medium).
pub fn has_dielectric(ctx: &RenderContext) -> bool {
    ctx.scene
        .materials
        .iter()
        .any(|m| matches!(m.material, Material::Dielectric { .. }))
}

/// The index of the medium around the point `p` (in free space, off every surface): the
/// first dielectric surface that the ray from `p` along unit `dir` crosses says it, passing
/// other surfaces (which separate no media). Crossing it outwards (along its normal), `p` is
/// inside that dielectric; inwards, in its exterior. Right for closed dielectric surfaces
/// nested as their `exterior`s say; a ray that meets no dielectric leaves `p` in the scene's
/// medium.
pub fn medium_around(ctx: &RenderContext, p: Vec3, dir: Vec3, counts: &mut RayCounts) -> f32 {
    first_dielectric(ctx, p, dir, counts).map_or(ctx.scene.eta, |(_, eta)| eta)
}

/// The first dielectric surface the ray from `p` along unit `dir` crosses (its triangle) and
/// the index on `p`'s side of it ([`medium_around`]); None when it meets none.
pub fn first_dielectric(ctx: &RenderContext, p: Vec3, dir: Vec3, counts: &mut RayCounts) -> Option<(u32, f32)> {
    if !has_dielectric(ctx) {
        return None;
    }
    let eps = self_intersection_eps(&V3::<f32>::splat(p), ctx.scene.offset_scale);
    let mut tnear = 0.0f32;
    for _ in 0..MAX_CROSSINGS {
        counts.intersect += 1;
        let h = ctx
            .accel
            .intersect1(p.to_array(), dir.to_array(), tnear, f32::INFINITY)?;
        let n = ctx.face_normal(h.prim);
        // the side `p` is on: the one the ray arrives from
        if let Some(eta) = side_eta(ctx, h.prim, n, -dir) {
            return Some((h.prim, eta));
        }
        tnear = h.t + eps;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::Device;
    use crate::scene::Scene;

    /// scenes/liquid_pose.toml: a liquid (1.33) inside a glass block (1.5) in air (1), seen
    /// from points in each medium along several directions (some pass the liquid, the wall or
    /// the light first).
    #[test]
    fn the_medium_around_a_point_follows_the_nesting() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/liquid_pose.toml");
        let scene = Scene::load(&path, &[]).unwrap();
        let device = Device::new("").unwrap();
        let ctx = RenderContext::new(&scene, &device).unwrap();
        let o = glam::DVec3::from_array(scene.render_origin);
        let at = |x: f64, y: f64, z: f64| (glam::DVec3::new(x, y, z) - o).as_vec3();
        let dirs = [
            Vec3::X,
            -Vec3::X,
            Vec3::Y,
            -Vec3::Z,
            Vec3::Z,
            Vec3::new(1.0, 0.3, -0.5).normalize(),
        ];
        let mut counts = RayCounts::default();
        for (p, eta) in [
            (at(0.05, 0.0, 0.0), 1.33), // the liquid's centre (it is moved 0.05 along x)
            (at(0.0, 0.3, 0.0), 1.5),   // glass above the liquid
            (at(0.35, -0.1, 0.1), 1.5), // glass beside it
            (at(0.0, 0.0, 1.0), 1.0),   // air between the block and the camera
            (at(0.0, 0.0, -0.8), 1.0),  // air between the block and the wall
            (at(-1.0, 0.5, -0.5), 1.0), // air beside the block
        ] {
            for d in dirs {
                assert_eq!(medium_around(&ctx, p, d, &mut counts), eta, "from {p} along {d}");
            }
        }
    }
}
