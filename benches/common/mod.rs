//! Shared by the bench binaries: rays of the kinds the renderer traces (coherent camera rays,
//! random bounce rays, shadow segments), for measuring bare Embree on the same workload, and
//! error metrics against a reference.
#![allow(dead_code)]

use difftransient::Scene;
use difftransient::accel::Ray8;
use difftransient::integrator::camera::CameraSampler;
use glam::Vec3;

/// Relative L2 error ‖a − b‖ / ‖b‖.
pub fn rel_l2(a: &[f32], b: &[f32]) -> f64 {
    let num: f64 = a.iter().zip(b).map(|(x, y)| ((x - y) as f64).powi(2)).sum();
    let den: f64 = b.iter().map(|y| (*y as f64).powi(2)).sum();
    (num / den.max(1e-300)).sqrt()
}

pub struct Rng(u64);
impl Rng {
    pub fn next(&mut self) -> f32 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// A point uniformly distributed over the scene's surface area, and its triangle's normal.
pub fn point_on_scene(scene: &Scene, rng: &mut Rng) -> (Vec3, Vec3) {
    let g = &scene.geometry;
    let cdf = area_cdf(scene);
    let u = rng.next() as f64 * cdf.last().copied().unwrap_or(0.0);
    let t = cdf.partition_point(|&c| c <= u).min(g.indices.len() - 1);
    let [a, b, c] = g.indices[t].map(|i| g.positions[i as usize]);
    let (s, r) = (rng.next().sqrt(), rng.next());
    (
        a + (b - a) * s * (1.0 - r) + (c - a) * s * r,
        (b - a).cross(c - a).normalize_or_zero(),
    )
}

/// Cumulative triangle areas (cached per scene pointer and triangle count).
fn area_cdf(scene: &Scene) -> std::sync::Arc<Vec<f64>> {
    use std::sync::{Arc, Mutex, OnceLock};
    static CACHE: OnceLock<Mutex<(usize, usize, Arc<Vec<f64>>)>> = OnceLock::new();
    let key = (scene as *const Scene as usize, scene.geometry.indices.len());
    let m = CACHE.get_or_init(|| Mutex::new((0, 0, Arc::new(Vec::new()))));
    let mut g = m.lock().unwrap();
    if (g.0, g.1) != key {
        let geo = &scene.geometry;
        let mut acc = 0.0f64;
        let cdf = geo
            .indices
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| geo.positions[i as usize]);
                acc += 0.5 * (b - a).cross(c - a).length() as f64;
                acc
            })
            .collect();
        *g = (key.0, key.1, Arc::new(cdf));
    }
    g.2.clone()
}

pub fn bounce_rays(scene: &Scene, n: usize, seed: u64) -> Vec<Ray8> {
    let mut rng = Rng(seed);
    (0..n / 8)
        .map(|_| {
            let mut r = Ray8::default();
            for i in 0..8 {
                let (p, nrm) = point_on_scene(scene, &mut rng);
                let d = loop {
                    let v = Vec3::new(rng.next() * 2.0 - 1.0, rng.next() * 2.0 - 1.0, rng.next() * 2.0 - 1.0);
                    if v.length_squared() <= 1.0 && v.length_squared() > 1e-6 {
                        break v.normalize();
                    }
                };
                let d = if d.dot(nrm) < 0.0 { -d } else { d };
                let o = p + nrm * 1e-4;
                (r.org_x[i], r.org_y[i], r.org_z[i]) = (o.x, o.y, o.z);
                (r.dir_x[i], r.dir_y[i], r.dir_z[i]) = (d.x, d.y, d.z);
                r.tfar[i] = f32::INFINITY;
            }
            r
        })
        .collect()
}

pub fn shadow_rays(scene: &Scene, n: usize, seed: u64) -> Vec<Ray8> {
    let mut rng = Rng(seed);
    (0..n / 8)
        .map(|_| {
            let mut r = Ray8::default();
            for i in 0..8 {
                let (p, _) = point_on_scene(scene, &mut rng);
                let (q, _) = point_on_scene(scene, &mut rng);
                let d = q - p;
                let len = d.length().max(1e-3);
                (r.org_x[i], r.org_y[i], r.org_z[i]) = (p.x, p.y, p.z);
                (r.dir_x[i], r.dir_y[i], r.dir_z[i]) = (d.x / len, d.y / len, d.z / len);
                r.tnear[i] = 1e-4;
                r.tfar[i] = len - 1e-4;
            }
            r
        })
        .collect()
}

pub fn camera_rays(scene: &Scene) -> Vec<Ray8> {
    let (w, h) = (scene.film.width, scene.film.height);
    let cam = CameraSampler::new(&scene.camera, w, h, scene.film.filter);
    let mut out = Vec::new();
    for y in 0..h {
        for x0 in (0..w).step_by(8) {
            let mut r = Ray8::default();
            for i in 0..8 {
                let d = cam.direction((x0 + i as u32).min(w - 1) as f32 + 0.5, y as f32 + 0.5);
                let o = scene.camera.position;
                (r.org_x[i], r.org_y[i], r.org_z[i]) = (o.x, o.y, o.z);
                (r.dir_x[i], r.dir_y[i], r.dir_z[i]) = (d.x, d.y, d.z);
                r.tfar[i] = f32::INFINITY;
            }
            out.push(r);
        }
    }
    out
}

/// Wall seconds for bare Embree to trace `count` rays (packets of 8 cycled from `rays`) on
/// `pool`, with `f` tracing one slice of packets.
pub fn bare_seconds(pool: &rayon::ThreadPool, rays: &[Ray8], count: u64, f: &(dyn Fn(&[Ray8]) -> usize + Sync)) -> f64 {
    use rayon::prelude::*;
    let packets = count.div_ceil(8) as usize;
    let t0 = std::time::Instant::now();
    pool.install(|| {
        (0..packets.div_ceil(rays.len())).into_par_iter().for_each(|chunk| {
            difftransient::accel::set_flush_denormals();
            let n = rays.len().min(packets - chunk * rays.len());
            std::hint::black_box(f(&rays[..n]));
        });
    });
    t0.elapsed().as_secs_f64()
}

/// The Cornell box made differentiable in pose: a Gaussian pulse (σ = 0.01 m, so time shifts
/// have a derivative) and the parameter `tall_box_x` (translate x of the tall box, at its
/// current value). The derivative workload of the harness and the derivative benches.
#[allow(dead_code)]
pub fn with_pose_param(mut s: Scene) -> Scene {
    use difftransient::scene::{Axis, Param, ParamKind};
    for e in &mut s.emitters {
        e.pulse = difftransient::temporal::Pulse::Gaussian { sigma_opl: 0.01 };
    }
    let tall = s.shapes.iter().position(|x| x.name == "tall_box").expect("tall_box") as u32;
    // params hold file coordinates: the render-space translate plus the render origin
    let value = s.shapes[tall as usize].transform.translate.x as f64 + s.render_origin[0];
    s.params.push(Param {
        name: "tall_box_x".into(),
        kind: ParamKind::Translate {
            shape: tall,
            axis: Axis::X,
        },
        value,
    });
    s
}
