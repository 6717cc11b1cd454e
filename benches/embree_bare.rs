//! Bare Embree against our wrapper, on the same rays, one thread.
//!
//! Scene: a Cornell-box-like room (5 walls as 3×3 grids, a ceiling light, a short and a tall
//! box: 116 triangles). Rays: a coherent 64×64 pinhole camera grid, packed in 4×2 pixel tiles,
//! and random rays (origin inside the room, uniform direction). For each set:
//! `raw_*` calls Embree directly (`Accel::raw_*_batch`); `ours_*` goes through
//! `Accel::intersect1/intersect8/occluded8` with their validation and result conversion.
//! Compare with the bare rates in BENCHMARKS.md (Cornell box, 1 thread).
//!
//! `cargo bench --bench embree_bare` (about 20 s).

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use difftransient::accel::{Accel, Device, Ray8, set_flush_denormals};
use std::hint::black_box;
use std::time::Duration;

fn quad_grid(p: &mut Vec<[f32; 3]>, t: &mut Vec<[u32; 3]>, o: [f32; 3], a: [f32; 3], b: [f32; 3], n: u32) {
    let base = p.len() as u32;
    for j in 0..=n {
        for i in 0..=n {
            let (s, r) = (i as f32 / n as f32, j as f32 / n as f32);
            p.push(std::array::from_fn(|k| o[k] + s * a[k] + r * b[k]));
        }
    }
    for j in 0..n {
        for i in 0..n {
            let v = base + j * (n + 1) + i;
            t.push([v, v + 1, v + n + 2]);
            t.push([v, v + n + 2, v + n + 1]);
        }
    }
}

fn cuboid(p: &mut Vec<[f32; 3]>, t: &mut Vec<[u32; 3]>, lo: [f32; 3], hi: [f32; 3]) {
    let [x0, y0, z0] = lo;
    let [x1, y1, z1] = hi;
    let (dx, dy, dz) = ([x1 - x0, 0.0, 0.0], [0.0, y1 - y0, 0.0], [0.0, 0.0, z1 - z0]);
    let neg = |v: [f32; 3]| v.map(|c| -c);
    quad_grid(p, t, [x0, y0, z0], dx, dz, 1); // front
    quad_grid(p, t, [x1, y0, z1], neg(dx), neg(dz), 1); // back
    quad_grid(p, t, [x0, y0, z1], dz.map(|c| -c), dy, 1); // left, wound outward-ish
    quad_grid(p, t, [x1, y0, z0], dz, dy, 1); // right
    quad_grid(p, t, [x0, y1, z0], dx, dz, 1); // top
    quad_grid(p, t, [x0, y0, z0], dz, dx, 1); // bottom
}

/// The room spans [0, 1]^3, open towards -z where the camera is.
fn cornell() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (mut p, mut t) = (Vec::new(), Vec::new());
    let (x, y, z) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    quad_grid(&mut p, &mut t, [0.0, 0.0, 0.0], x, z, 3); // floor
    quad_grid(&mut p, &mut t, [0.0, 1.0, 0.0], x, z, 3); // ceiling
    quad_grid(&mut p, &mut t, [0.0, 0.0, 1.0], x, y, 3); // back
    quad_grid(&mut p, &mut t, [0.0, 0.0, 0.0], z, y, 3); // left
    quad_grid(&mut p, &mut t, [1.0, 0.0, 0.0], z, y, 3); // right
    quad_grid(&mut p, &mut t, [0.4, 0.999, 0.4], [0.2, 0.0, 0.0], [0.0, 0.0, 0.2], 1); // light
    cuboid(&mut p, &mut t, [0.15, 0.0, 0.45], [0.45, 0.6, 0.75]); // tall box
    cuboid(&mut p, &mut t, [0.55, 0.0, 0.2], [0.85, 0.3, 0.5]); // short box
    (p, t)
}

fn camera_rays(res: usize) -> Vec<Ray8> {
    let eye = [0.5, 0.5, -1.4];
    let mut packets = Vec::new();
    for ty in (0..res).step_by(2) {
        for tx in (0..res).step_by(4) {
            let mut r = Ray8::default();
            for l in 0..8 {
                let (px, py) = (tx + l % 4, ty + l / 4);
                let sx = (px as f32 + 0.5) / res as f32 - 0.5;
                let sy = 0.5 - (py as f32 + 0.5) / res as f32;
                r.set(l, eye, [sx * 0.75, sy * 0.75, 1.0], 0.0, f32::INFINITY);
            }
            packets.push(r);
        }
    }
    packets
}

fn random_rays(n_packets: usize, seed: u64) -> Vec<Ray8> {
    let mut s = seed;
    let mut f = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 40) as f32 / (1u64 << 24) as f32
    };
    (0..n_packets)
        .map(|_| {
            let mut r = Ray8::default();
            for l in 0..8 {
                let o = [0.02 + 0.96 * f(), 0.02 + 0.96 * f(), 0.02 + 0.96 * f()];
                let d = loop {
                    let d = [2.0 * f() - 1.0, 2.0 * f() - 1.0, 2.0 * f() - 1.0];
                    let l2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                    if l2 > 1e-4 && l2 <= 1.0 {
                        break d.map(|c| c / l2.sqrt());
                    }
                };
                r.set(l, o, d, 0.0, f32::INFINITY);
            }
            r
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    set_flush_denormals();
    let (p, t) = cornell();
    let device = Device::new("threads=1").expect("Embree device");
    let accel = Accel::build(&device, &p, &t).expect("Cornell box BVH");
    eprintln!("Cornell box: {} triangles", accel.triangle_count());

    for (name, rays, coherent) in [
        ("coherent", camera_rays(64), true),
        ("random", random_rays(512, 0x9E37_79B9_7F4A_7C15), false),
    ] {
        let n = rays.len() as u64 * 8;
        let mut g = c.benchmark_group(format!("cornell_{name}"));
        g.throughput(Throughput::Elements(n));
        g.bench_function("raw_intersect1", |b| {
            b.iter(|| accel.raw_intersect1_batch(black_box(&rays)))
        });
        g.bench_function("raw_intersect8", |b| {
            b.iter(|| accel.raw_intersect8_batch(black_box(&rays), coherent))
        });
        g.bench_function("ours_intersect1", |b| {
            b.iter(|| {
                let mut hits = 0;
                for r in black_box(&rays) {
                    for l in 0..8 {
                        let (o, d, tn, tf) = r.lane(l);
                        hits += accel.intersect1(o, d, tn, tf).is_some() as usize;
                    }
                }
                hits
            })
        });
        g.bench_function("ours_intersect8", |b| {
            b.iter(|| {
                let mut sum = 0.0f32;
                for r in black_box(&rays) {
                    let h = accel.intersect8(r, [true; 8], coherent);
                    sum += h.t.iter().filter(|t| t.is_finite()).sum::<f32>();
                }
                sum
            })
        });
        // a packet of which only half the lanes are alive, as the path tracer's bounce
        // packets are on average (4.1 of 8 on the Cornell box): what a half-empty packet costs
        // against a full one, per call (throughput counts all 8 lanes)
        g.bench_function("ours_intersect8_half_lanes", |b| {
            b.iter(|| {
                let mut sum = 0.0f32;
                for r in black_box(&rays) {
                    let h = accel.intersect8(r, std::array::from_fn(|l| l % 2 == 0), coherent);
                    sum += h.t.iter().filter(|t| t.is_finite()).sum::<f32>();
                }
                sum
            })
        });
        g.bench_function("ours_occluded8_half_lanes", |b| {
            b.iter(|| {
                let mut blocked = 0;
                for r in black_box(&rays) {
                    let active = std::array::from_fn(|l| l % 2 == 0);
                    blocked += accel.occluded8(r, active, coherent).iter().filter(|&&o| o).count();
                }
                blocked
            })
        });
        g.bench_function("raw_occluded1", |b| {
            b.iter(|| accel.raw_occluded1_batch(black_box(&rays)))
        });
        g.bench_function("raw_occluded8", |b| {
            b.iter(|| accel.raw_occluded8_batch(black_box(&rays), coherent))
        });
        g.bench_function("ours_occluded8", |b| {
            b.iter(|| {
                let mut blocked = 0;
                for r in black_box(&rays) {
                    blocked += accel.occluded8(r, [true; 8], coherent).iter().filter(|&&o| o).count();
                }
                blocked
            })
        });
        g.finish();
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default()
        .sample_size(20)
        .warm_up_time(Duration::from_millis(300))
        .measurement_time(Duration::from_secs(1));
    targets = bench
}
criterion_main!(benches);
