//! χ² tests of a light subpath's first direction (`light_subpath`): uniform on the sphere at
//! a point light (`sample_sphere`), cosine-weighted at an area light (`sample_cosine`),
//! against the density BDPT's MIS reports for that vertex (`vertex::dir_pdf`).

use super::super::vertex::{Vertex, dir_pdf};
use super::sample_sphere;
use crate::integrator::bsdf::sample_cosine;
use crate::integrator::testutil::assert_chi2;
use crate::kernel::{Mask, PathSampler, Real, Spectrum, V3, f32x8};
use glam::Vec3;
use std::f32::consts::PI;

/// Bands of equal height along the axis (equal solid angle, Archimedes) × sectors of azimuth.
const BANDS: usize = 16;
const SECTORS: usize = 32;

type Vx = Vertex<f32x8, 1>;

/// A light vertex at a fixed point: a point light, or an area light's point with normal `n`.
fn light_vertex(n: Option<Vec3>) -> Vx {
    let p = V3::<f32x8>::splat(Vec3::new(0.3, -1.0, 2.0));
    let mut v = Vx::point(p, Spectrum::splat(f32x8::ONE), Mask::splat(true));
    match n {
        Some(n) => {
            v.n = V3::splat(n);
            v.on_surface = Mask::splat(true);
        }
        None => v.uniform_sphere = Mask::splat(true),
    }
    v
}

/// 400 000 directions from `sample` (8-wide, fixed seed), binned by height z ∈ [z_lo, 1]
/// along `axis` and azimuth about it, against N × the integral of `dir_pdf(v, ·)` over each
/// cell (Simpson's rule in z at the sector's middle azimuth: exact for a density linear in
/// z, as both are). Checks the returned pdf is `dir_pdf`'s, that the latter integrates to 1
/// (to 10⁻⁴: f32 densities, Simpson on f32 cell bounds) and the χ² ([`assert_chi2`]).
fn check_directions(
    what: &str,
    v: &Vx,
    axis: Vec3,
    z_lo: f32,
    mut sample: impl FnMut(f32x8, f32x8) -> (V3<f32x8>, f32x8),
) {
    let (t, b) = axis.any_orthonormal_pair();
    let band_h = (1.0 - z_lo) / BANDS as f32;
    let dphi = 2.0 * PI / SECTORS as f32;
    let mut observed = vec![0u64; BANDS * SECTORS];
    let mut sampler = PathSampler::new(0xd1ec, &[0, 1, 2, 3, 4, 5, 6, 7]);
    let packets = 50_000;
    for _ in 0..packets {
        let (u1, u2) = sampler.next2::<f32x8>();
        let (dir, pdf) = sample(u1, u2);
        let want = dir_pdf(v, &(v.p.value() + dir));
        for i in 0..8 {
            let d = dir.lane(i);
            assert!((d.length() - 1.0).abs() < 1e-5, "{d}");
            let (got, want) = (pdf.lane(i), want.lane(i));
            // near the horizon, f32 √(1 − x² − y²) is off by up to √(2ε) ≈ 5·10⁻⁴ in cos θ,
            // 1.6·10⁻⁴ in cos θ/π; a wrong density is off by more than 10⁻²
            assert!(
                (got - want).abs() <= 1e-5 * want + 2e-4,
                "{d}: sampled pdf {got}, dir_pdf {want}"
            );
            let z = axis.dot(d);
            assert!(z >= z_lo - 1e-6, "{d} below the sampled domain");
            let band = (((z - z_lo) / band_h) as usize).min(BANDS - 1);
            let phi = b.dot(d).atan2(t.dot(d)) + PI;
            let sector = ((phi / dphi) as usize).min(SECTORS - 1);
            observed[band * SECTORS + sector] += 1;
        }
    }
    let pdf_at = |z: f32, phi: f32| {
        let r = (1.0 - z * z).max(0.0).sqrt();
        let d = t * (r * phi.cos()) + b * (r * phi.sin()) + axis * z;
        dir_pdf(v, &(v.p.value() + V3::splat(d))).lane(0) as f64
    };
    let mut probability = vec![0.0; BANDS * SECTORS];
    for band in 0..BANDS {
        let (z0, z1) = (z_lo + band as f32 * band_h, z_lo + (band + 1) as f32 * band_h);
        for sector in 0..SECTORS {
            let phi = (sector as f32 + 0.5) * dphi - PI;
            let simpson = (pdf_at(z0, phi) + 4.0 * pdf_at(0.5 * (z0 + z1), phi) + pdf_at(z1, phi)) / 6.0;
            probability[band * SECTORS + sector] = simpson * band_h as f64 * dphi as f64;
        }
    }
    assert_chi2(what, &observed, &probability, 1e-4);
}

/// A point light's directions are uniform on the sphere with density 1/(4π), as MIS assumes.
///
/// Bugs caught: z = 1 − u₁ (a hemisphere) or r = √(1 − z) instead of √(1 − z²) (not uniform
/// in z), an azimuth over π only, and a dir_pdf that is not 1/(4π) at a point light.
#[test]
fn point_light_directions_are_uniform_on_the_sphere() {
    let v = light_vertex(None);
    check_directions("point light", &v, Vec3::Z, -1.0, sample_sphere);
}

/// An area light's directions follow cos θ/π about its normal, the density dir_pdf reports
/// at an emitting surface vertex.
///
/// Bugs caught: a warp that is not cosine-weighted (uniform hemisphere, cos² θ), directions
/// about the wrong axis, and a dir_pdf at a surface that is not cos θ/π.
#[test]
fn area_light_directions_are_cosine_weighted() {
    let n = Vec3::new(0.2, 0.9, -0.3).normalize();
    let v = light_vertex(Some(n));
    let nv = V3::<f32x8>::splat(n);
    check_directions("area light", &v, n, 0.0, |u1, u2| sample_cosine(&nv, &nv, u1, u2));
}

/// BDPT's camera subpaths take the path tracer's rule (`crate::integrator::entry`): camera
/// rays aimed exactly at the silhouette edges of a box (as rounding allows) that are reported
/// on the face turned away from the camera add no vertex; the others add theirs. Before the
/// check, every such ray's subpath went on inside the box.
#[test]
fn camera_subpaths_do_not_enter_a_closed_shape_at_its_edge() {
    use crate::integrator::entry::tests::{BOX, box_context, meets_the_inside, silhouette_rays};
    use crate::kernel::Dual8;
    type R = Dual8<1>;
    let scene = crate::integrator::testutil::load(BOX, &[]);
    let device = crate::accel::Device::new("threads=1").unwrap();
    let ctx = box_context(&scene, &device);
    let dirs = silhouette_rays(&ctx, 256);
    let met = meets_the_inside(&ctx, &dirs);
    let eye = scene.camera.position;
    let mut counts = crate::integrator::trace::RayCounts::default();
    let (mut inside, mut outside) = (0, 0);
    for (k, chunk) in dirs.chunks(8).enumerate() {
        let ids: Vec<u64> = (0..chunk.len()).map(|i| (k * 8 + i) as u64).collect();
        let mut sampler = PathSampler::new(3, &ids);
        let mut d = [Vec3::Z; 8];
        d[..chunk.len()].copy_from_slice(chunk);
        let on: [bool; 8] = std::array::from_fn(|i| i < chunk.len());
        let alive = <R as Real>::Mask::from_bools(&on);
        let mut path = vec![Vertex::<R, 3>::point(V3::splat(eye), Spectrum::splat(R::one()), alive)];
        super::random_walk(
            &ctx,
            &mut sampler,
            &mut path,
            V3::splat(eye),
            V3::from_lane_vecs(&d),
            f32x8::ONE,
            Spectrum::splat(R::one()),
            alive,
            2,
            true,
            &mut counts,
        );
        for (i, m) in met[k * 8..k * 8 + chunk.len()].iter().enumerate() {
            let added = path.len() > 1 && path[1].alive.bit(i);
            match m {
                Some(true) => {
                    inside += 1;
                    assert!(!added, "ray {} met the box's inside and its subpath went on", k * 8 + i);
                }
                Some(false) => {
                    outside += 1;
                    assert!(added, "ray {} met the box's front and added no vertex", k * 8 + i);
                }
                None => {}
            }
        }
    }
    assert!(
        inside >= dirs.len() / 20 && outside >= dirs.len() / 20,
        "{inside} inside, {outside} outside"
    );
}
