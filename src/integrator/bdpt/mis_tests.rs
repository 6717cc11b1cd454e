//! The MIS weights of all strategies of a path sum to 1: random paths are split at every
//! (s, t), each split's subpaths are linked exactly as the random walks link them
//! ([`link`]), the connection densities come from [`path_pdfs`], and the weights of the
//! strategies that run must add up to 1 — with area and delta (point, laser-spot) lights,
//! and with a filter's h ≠ 1 in the camera density.

use super::super::vertex::{Vertex, camera_dir_pdf, dir_pdf, link, to_area};
use super::*;
use crate::kernel::{PathSampler, Spectrum, V3};
use glam::Vec3;

type Vx = Vertex<f32, 1>;

fn surface(p: Vec3, n: Vec3) -> Vx {
    let mut v = Vx::point(V3::splat(p), Spectrum::splat(1.0), true);
    v.n = V3::splat(n.normalize());
    v.on_surface = true;
    v.front = true;
    v
}

/// Light origin kinds: 0 area, 1 point (uniform sphere), 2 laser spot (on a surface, delta).
fn origin(kind: u32, p: Vec3, n: Vec3, area_pdf: f32) -> Vx {
    let mut v = if kind == 1 {
        let mut v = Vx::point(V3::splat(p), Spectrum::splat(1.0), true);
        v.uniform_sphere = true;
        v
    } else {
        surface(p, n)
    };
    v.pdf_fwd = if kind == 0 { area_pdf } else { 0.0 };
    v
}

/// Pinhole density towards a film point: a smooth stand-in for h_j(u)/(a cos³θ)/N.
fn cam_dir_pdf(cam: Vec3, x: Vec3, h: f32) -> f32 {
    let d = (x - cam).normalize();
    let cos = d.dot(-Vec3::Z).max(0.05);
    camera_dir_pdf(h, 1.0 / (0.01 * cos * cos * cos), 64.0)
}

/// The weight of every strategy of `xs` (x_0 light origin … x_{n−1} camera).
fn weights(xs: &[Vx], delta: bool, h: f32) -> Vec<(usize, f32)> {
    let n = xs.len();
    let cam = xs[n - 1].p.lane(0);
    let mut out = Vec::new();
    let (mut pl, mut pe) = (Vec::new(), Vec::new());
    for s in 0..n {
        let t = n - s;
        if !allowed::<bool>(n, s, delta) {
            continue;
        }
        // light subpath x_0..x_{s-1}, linked in order
        let mut light: Vec<Vx> = xs[..s].to_vec();
        for k in 1..s {
            let pdf = dir_pdf(&light[k - 1], &light[k].p.value());
            let (a, b) = light.split_at_mut(k);
            link(&mut a[k - 1], &mut b[0], pdf);
        }
        // camera subpath x_{n-1}, x_{n-2}, ..., x_s
        let mut camera: Vec<Vx> = xs[s..].iter().rev().copied().collect();
        for j in 1..t {
            let pdf = if j == 1 {
                cam_dir_pdf(cam, camera[1].p.lane(0), h)
            } else {
                dir_pdf(&camera[j - 1], &camera[j].p.value())
            };
            let (a, b) = camera.split_at_mut(j);
            link(&mut a[j - 1], &mut b[0], pdf);
        }
        let origin_pdf = xs[0].pdf_fwd;
        let camera_pdf = if t == 1 {
            to_area(
                &V3::splat(cam),
                &light[s - 1],
                cam_dir_pdf(cam, light[s - 1].p.lane(0), 1.0),
            )
        } else {
            0.0
        };
        let mut no_connect = Vec::new();
        path_pdfs(
            None,
            &light,
            &camera,
            origin_pdf,
            camera_pdf,
            &mut pl,
            &mut pe,
            &mut no_connect,
        );
        let (mut lower, higher) = ratio_sums(&pl, &pe, s, |sp| allowed::<bool>(n, sp, delta));
        if t == 1 {
            // the kernel computes the t = 1 sums with h = 1 and scales them per pixel by h²
            lower *= h * h;
        }
        out.push((s, weight(lower, higher)));
    }
    out
}

#[test]
fn weights_of_all_strategies_sum_to_one() {
    let mut rng = PathSampler::new(11, &[0]);
    let mut u = || rng.next::<f32>();
    let mut checked = 0;
    for trial in 0..600 {
        let n = 2 + trial % 7;
        let kind = (trial / 7) as u32 % 3;
        let mut xs: Vec<Vx> = Vec::new();
        let rv = |u: &mut dyn FnMut() -> f32| Vec3::new(u() * 2.0 - 1.0, u() * 2.0 - 1.0, u() * 2.0 - 1.0);
        let p0 = rv(&mut u) * 2.0;
        let n0 = rv(&mut u) + Vec3::Y * 0.1;
        xs.push(origin(kind, p0, n0, 0.1 + u()));
        for _ in 1..n - 1 {
            let p = rv(&mut u) * 2.0;
            let nn = rv(&mut u) + Vec3::X * 0.1;
            xs.push(surface(p, nn));
        }
        xs.push(Vx::point(
            V3::splat(Vec3::new(0.0, 0.0, 5.0)),
            Spectrum::splat(1.0),
            true,
        ));
        let delta = kind != 0;
        for _ in 0..2 {
            let h = if trial % 2 == 0 { 1.0 } else { 0.2 + u() };
            let ws = weights(&xs, delta, h);
            if ws.is_empty() {
                continue;
            }
            let sum: f32 = ws.iter().map(|w| w.1).sum();
            assert!(
                (sum - 1.0).abs() < 1e-4,
                "n {n}, light kind {kind}, h {h}: weights {ws:?} sum to {sum}"
            );
            assert!(ws.iter().all(|w| (0.0..=1.0 + 1e-6).contains(&w.1)));
            checked += 1;
        }
    }
    assert!(checked > 1000, "{checked}");
}

/// A two-vertex path (light seen directly) is made only by s = 0, and a delta light's direct
/// view has no strategy at all.
#[test]
fn excluded_strategies_get_no_weight() {
    let light = origin(0, Vec3::new(0.0, 1.0, 0.0), Vec3::Z, 0.5);
    let cam = Vx::point(V3::splat(Vec3::new(0.0, 0.0, 5.0)), Spectrum::splat(1.0), true);
    let ws = weights(&[light, cam], false, 1.0);
    assert_eq!(ws.len(), 1);
    assert_eq!(ws[0].0, 0);
    assert!((ws[0].1 - 1.0).abs() < 1e-6);
    assert!(weights(&[origin(1, Vec3::Y, Vec3::Z, 0.0), cam], true, 1.0).is_empty());
}
