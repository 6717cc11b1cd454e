//! Unit tests of silhouette detection, projected-length sampling and film normal velocity.

use super::edges::{Edge, build_edges};
use super::silhouette::*;
use crate::integrator::camera::CameraSampler;
use crate::kernel::hash_to_unit;
use crate::scene::{Camera, Geometry, PixelFilter, shapes};
use glam::{DVec2, DVec3, Mat3, Vec3};

fn cube() -> Geometry {
    let m = shapes::cube();
    Geometry {
        positions: m.positions.clone(),
        indices: m.tris.clone(),
        tri_shape: vec![0; m.tris.len()],
        ..Default::default()
    }
}

fn counts(geo: &Geometry, edges: &[Edge], eye: DVec3) -> [usize; 5] {
    let mut n = [0; 5];
    for e in edges {
        n[match classify(geo, e, eye) {
            EdgeView::Boundary => 0,
            EdgeView::Silhouette => 1,
            EdgeView::FrontCrease => 2,
            EdgeView::BackCrease => 3,
            EdgeView::EdgeOn => 4,
        }] += 1;
    }
    n
}

/// From a face axis the eye sees one face: its 4 edges are the silhouette. From a corner
/// direction it sees three faces: a hexagonal silhouette and three creases. From between two
/// faces: two faces, six silhouette edges and one crease. With the eye in the plane of the
/// −z face, its 4 edges are edge-on, and the one face seen (−x) keeps 3 silhouette edges.
#[test]
fn cube_silhouettes_from_several_viewpoints() {
    let geo = cube();
    let edges = build_edges(&geo, 0.0);
    assert_eq!(counts(&geo, &edges, DVec3::new(0.0, 0.0, 5.0)), [0, 4, 0, 8, 0]);
    assert_eq!(counts(&geo, &edges, DVec3::new(5.0, 5.0, 5.0)), [0, 6, 3, 3, 0]);
    assert_eq!(counts(&geo, &edges, DVec3::new(-5.0, 0.3, 5.0)), [0, 6, 1, 5, 0]);
    assert_eq!(counts(&geo, &edges, DVec3::new(-4.0, 0.2, -1.0)), [0, 3, 0, 5, 4]);
    // From the +z axis the silhouette is the z = +1 square.
    for e in &edges {
        let z = [e.v0, e.v1].map(|v| geo.positions[v as usize].z);
        let sil = classify(&geo, e, DVec3::new(0.0, 0.0, 5.0)) == EdgeView::Silhouette;
        assert_eq!(sil, z == [1.0, 1.0], "{e:?}");
    }
    // Inside the cube every face faces away: nothing is a silhouette.
    assert_eq!(counts(&geo, &edges, DVec3::new(0.1, 0.2, 0.3)), [0, 0, 0, 12, 0]);
}

fn camera() -> Camera {
    Camera {
        position: Vec3::new(2.5, 1.5, 4.0),
        look_at: Vec3::new(0.0, 0.0, 0.0),
        up: Vec3::Y,
        fov_y_deg: 35.0,
    }
}

/// The f64 pinhole is the camera sampler's projection.
#[test]
fn pinhole_matches_the_camera_sampler() {
    let cam = camera();
    let sampler = CameraSampler::new(&cam, 40, 30, PixelFilter::Box);
    let pin = Pinhole::new(&cam, 40, 30);
    for p in [Vec3::ZERO, Vec3::new(0.5, -0.7, 0.2), Vec3::new(-1.0, 1.0, 1.0)] {
        let a = sampler.project(p).unwrap();
        let b = pin.film(p.as_dvec3());
        assert!(
            (a.fx as f64 - b.x).abs() < 1e-3 && (a.fy as f64 - b.y).abs() < 1e-3,
            "{a:?} vs {b}"
        );
    }
}

/// Edges are drawn in proportion to their projected length (χ² over edges), points uniformly
/// along the projected edge (χ² over ten segments of each edge), and the world point of a
/// sample lies on its edge and projects to its film point.
#[test]
fn sampling_follows_projected_length() {
    let geo = cube();
    let edges = build_edges(&geo, 0.0);
    let pin = Pinhole::new(&camera(), 40, 30);
    let set = SilhouetteSet::build(&geo, &edges, &pin, 1.0, |_| true);
    assert_eq!(
        set.edges.len(),
        12,
        "six silhouette edges, three front and three back creases"
    );
    let n = 200_000usize;
    let mut per_edge = vec![0usize; set.edges.len()];
    let mut along = vec![[0usize; 10]; set.edges.len()];
    for i in 0..n {
        let u0 = hash_to_unit(i as u64 * 2) as f64;
        let u1 = hash_to_unit(i as u64 * 2 + 1) as f64;
        let s = set.sample(u0, u1).unwrap();
        assert!((s.pdf * set.total_length - 1.0).abs() < 1e-12);
        let e = &set.edges[s.index];
        per_edge[s.index] += 1;
        // position along the projected edge, as a fraction of its visible part
        let frac = ((s.film - e.p0).length() / (e.p1 - e.p0).length() - e.s_lo) / (e.s_hi - e.s_lo);
        along[s.index][((frac * 10.0) as usize).min(9)] += 1;
        assert!(
            (pin.film(s.world) - s.film).length() < 1e-6,
            "world point off its film point"
        );
        let (a, b) = (e.x0, e.x1);
        let off_line = (s.world - a).cross(b - a).length() / (b - a).length();
        assert!(off_line < 1e-9, "world point off the edge by {off_line}");
    }
    let chi2: f64 = per_edge
        .iter()
        .zip(&set.edges)
        .map(|(&c, e)| {
            let expect = n as f64 * e.length / set.total_length;
            (c as f64 - expect).powi(2) / expect
        })
        .sum();
    // 8 dof: P(χ² > 30) ≈ 2e-4
    assert!(chi2 < 30.0, "edge choice χ² = {chi2}");
    for (bins, &c) in along.iter().zip(&per_edge) {
        let expect = c as f64 / 10.0;
        let chi2: f64 = bins.iter().map(|&b| (b as f64 - expect).powi(2) / expect).sum();
        // 9 dof: P(χ² > 33) ≈ 1e-4
        assert!(chi2 < 33.0, "position along the edge: χ² = {chi2} ({bins:?})");
    }
}

/// An edge crossing the plane of the eye is clipped to the near plane, and one leaving the
/// film is clipped to the film widened by the margin: every sample is in front of the eye
/// and on the widened film.
#[test]
fn edges_are_clipped_to_the_near_plane_and_the_film() {
    let cam = Camera {
        position: Vec3::ZERO,
        look_at: Vec3::new(0.0, 0.0, -1.0),
        up: Vec3::Y,
        fov_y_deg: 40.0,
    };
    let pin = Pinhole::new(&cam, 32, 32);
    let (a, b) = (DVec3::new(0.3, 0.1, -2.0), DVec3::new(0.2, 0.1, 1.0));
    let (x0, x1, s_lo, s_hi, length) = project_edge(&pin, a, b, 1.5).unwrap();
    assert!(pin.depth(x0) >= Z_NEAR * 0.999 && pin.depth(x1) >= Z_NEAR * 0.999);
    assert!(s_lo >= 0.0 && s_hi <= 1.0 && s_lo < s_hi && length > 0.0);
    let (p0, p1) = (pin.film(x0), pin.film(x1));
    for s in [s_lo, 0.5 * (s_lo + s_hi), s_hi] {
        let p = p0 + (p1 - p0) * s;
        assert!(p.x >= -1.5 - 1e-9 && p.x <= 33.5 + 1e-9 && p.y >= -1.5 - 1e-9 && p.y <= 33.5 + 1e-9);
    }
    assert!(project_edge(&pin, DVec3::new(0.0, 0.0, 1.0), DVec3::new(1.0, 0.0, 2.0), 1.0).is_none());
    assert!(project_edge(&pin, DVec3::new(50.0, 0.0, -1.0), DVec3::new(60.0, 0.0, -1.0), 1.0).is_none());
}

/// The film normal velocity of an edge point equals the finite difference of the distance
/// from that film point to the moved, re-projected edge line, for a rotation about a tilted
/// axis plus a translation (an affine velocity field, as `Motion` builds).
#[test]
fn normal_velocity_matches_finite_differences_of_the_projected_edge() {
    let pin = Pinhole::new(&camera(), 40, 30);
    let axis = Vec3::new(0.3, 1.0, -0.2).normalize();
    let rot = Mat3::from_cols(axis.cross(Vec3::X), axis.cross(Vec3::Y), axis.cross(Vec3::Z));
    let velocity = |x: DVec3| (rot * x.as_vec3() + Vec3::new(0.2, -0.1, 0.4)).as_dvec3();
    let (a, b) = (DVec3::new(-0.8, 0.3, 0.5), DVec3::new(0.6, -0.4, 0.9));
    let line = |t: f64| {
        let (pa, pb) = (pin.film(a + velocity(a) * t), pin.film(b + velocity(b) * t));
        let d = (pb - pa).normalize();
        (pa, DVec2::new(-d.y, d.x))
    };
    for s in [0.1, 0.5, 0.83] {
        let x = a + (b - a) * s;
        let u = pin.film(x);
        let (_, n) = line(0.0);
        let analytic = pin.film_velocity(x, velocity(x)).dot(n);
        let h = 1e-5;
        let dist = |t: f64| {
            let (p, m) = line(t);
            (u - p).dot(m) * -m.dot(n).signum()
        };
        let fd = (dist(h) - dist(-h)) / (2.0 * h);
        assert!(
            (fd - analytic).abs() < 1e-4 * (1.0 + analytic.abs()),
            "s = {s}: FD {fd} vs analytic {analytic}"
        );
        assert!(analytic.abs() > 0.1, "a test that cannot fail: velocity {analytic}");
    }
}

/// One number per sample: N jittered numbers put ⌊N·ℓ_e/ℓ_total⌋ or one more samples on each
/// edge, and each point projects to its film point.
#[test]
fn jittered_samples_stratify_the_edges() {
    let geo = cube();
    let edges = build_edges(&geo, 0.0);
    let pin = Pinhole::new(&camera(), 40, 30);
    let set = SilhouetteSet::build(&geo, &edges, &pin, 1.0, |_| true);
    let n = 10_000usize;
    let mut per_edge = vec![0usize; set.edges.len()];
    for i in 0..n {
        let u = (i as f64 + hash_to_unit(i as u64) as f64) / n as f64;
        let s = set.sample_at(u).unwrap();
        per_edge[s.index] += 1;
        assert!((pin.film(s.world) - s.film).length() < 1e-6);
        let e = &set.edges[s.index];
        let frac = (s.film - e.p0).length() / (e.p1 - e.p0).length();
        assert!(frac >= e.s_lo - 1e-9 && frac <= e.s_hi + 1e-9);
    }
    for (c, e) in per_edge.iter().zip(&set.edges) {
        let expect = n as f64 * e.length / set.total_length;
        assert!((*c as f64 - expect).abs() <= 2.0, "{c} samples, expected {expect}");
    }
}
