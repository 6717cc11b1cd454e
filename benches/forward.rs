//! Forward transient speed on the Cornell box (issue: foundation, "Speed").
//!
//! Workload: scenes/cornell_box.toml at 64×64, 200 bins of 0.06 m OPL from 3.6 m, up to 8 bounces.
//! Reports paths per CPU-second and rays/s of our renderer, the rate of bare Embree
//! (`rtcIntersect8`/`rtcOccluded8`, no shading) on the same number and kind of rays, and the
//! error the timed render reached against a high-spp reference (cached in target/bench-cache).
//!
//! Run: `cargo bench --bench forward` (set DTR_BENCH_SPP / DTR_BENCH_THREADS to change).

mod common;
use common::{bare_seconds, bounce_rays, camera_rays, rel_l2, shadow_rays};
use difftransient::accel::{Accel, BuildQuality, Device, Ray8};
use difftransient::{RenderOptions, Scene, Transient, render};
use std::path::PathBuf;

fn env_or<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

fn main() {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::load(&root.join("scenes/cornell_box.toml"), &[]).expect("scene");
    let spp: u32 = env_or("DTR_BENCH_SPP", 64);
    let threads: usize = env_or(
        "DTR_BENCH_THREADS",
        std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1),
    );
    let reference = reference(&scene, &root);

    // warm-up, then the timed render
    let opts = RenderOptions {
        spp: Some(4),
        seed: Some(1),
        threads: Some(threads),
        ..Default::default()
    };
    render(&scene, &opts).unwrap();
    let opts = RenderOptions {
        spp: Some(spp),
        seed: Some(1),
        threads: Some(threads),
        ..Default::default()
    };
    let (t, stats) = render(&scene, &opts).unwrap();
    let err = rel_l2(&t.data, &reference.data);
    let err_img = rel_l2(&t.steady, &reference.steady);

    // bare Embree on rays of the same number and kind
    let dev = Device::new("").unwrap();
    let pos: Vec<[f32; 3]> = scene.geometry.positions.iter().map(|p| p.to_array()).collect();
    // the renderer's forward mode: Embree's default (non-robust) traversal
    let accel = Accel::build_with(&dev, &pos, &scene.geometry.indices, BuildQuality::High, false).unwrap();
    let primary = camera_rays(&scene);
    let n_primary = (scene.film.width * scene.film.height) as u64 * spp as u64;
    let n_bounce = stats.intersect_rays.saturating_sub(n_primary);
    let bounce = bounce_rays(&scene, 1 << 16, 7);
    let shadow = shadow_rays(&scene, 1 << 16, 11);
    let pool = difftransient::render::thread_pool(Some(threads)).unwrap();
    let bare = |rays: &[Ray8], count: u64, f: &(dyn Fn(&[Ray8]) -> usize + Sync)| bare_seconds(&pool, rays, count, f);
    let t_primary = bare(&primary, n_primary, &|r| accel.raw_intersect8_batch(r, true));
    let t_bounce = bare(&bounce, n_bounce, &|r| accel.raw_intersect8_batch(r, false));
    let t_shadow = bare(&shadow, stats.occluded_rays, &|r| accel.raw_occluded8_batch(r, false));
    let bare_total = t_primary + t_bounce + t_shadow;
    // the same rays as 16-wide packets (two of ours per call) and as single rays
    let p16 = bare(&primary, n_primary, &|r| accel.raw_intersect16_batch(r, true));
    let b16 = bare(&bounce, n_bounce, &|r| accel.raw_intersect16_batch(r, false));
    let s16 = bare(&shadow, stats.occluded_rays, &|r| accel.raw_occluded16_batch(r, false));
    let b1 = bare(&bounce, n_bounce, &|r| accel.raw_intersect1_batch(r));
    let s1 = bare(&shadow, stats.occluded_rays, &|r| accel.raw_occluded1_batch(r));
    println!(
        "  bare seconds, 8-wide: primary {t_primary:.4} bounce {t_bounce:.4} shadow {t_shadow:.4}; \
         16-wide: {p16:.4} {b16:.4} {s16:.4}; 1-wide: bounce {b1:.4} shadow {s1:.4}"
    );
    let rays = (stats.intersect_rays + stats.occluded_rays) as f64;

    println!("Cornell box 64x64, 200 bins x 0.06 m from 3.6 m, max 8 bounces, {spp} spp, {threads} threads");
    println!(
        "  renderer : {:.3} s wall, {:.3} CPU-s, {:.3e} paths/CPU-s, {:.3e} rays/s ({:.3e} rays/CPU-s)",
        stats.wall_seconds,
        stats.cpu_seconds,
        stats.paths_per_cpu_second,
        stats.rays_per_second,
        stats.rays_per_cpu_second
    );
    println!(
        "  rays     : {} primary, {} bounce, {} shadow",
        n_primary, n_bounce, stats.occluded_rays
    );
    println!(
        "  bare Embree on the same rays: {:.3} s wall, {:.3e} rays/s  -> renderer/bare = {:.1}%",
        bare_total,
        rays / bare_total,
        100.0 * (rays / stats.wall_seconds) / (rays / bare_total)
    );
    println!(
        "  error vs {}-spp reference: transient rel. L2 {:.4}, time-summed image rel. L2 {:.4}",
        reference_spp(),
        err,
        err_img
    );
}

fn reference_spp() -> u32 {
    env_or("DTR_BENCH_REF_SPP", 2048)
}

/// The converged reference, rendered once and cached with its settings in the file name.
fn reference(scene: &Scene, root: &std::path::Path) -> Transient {
    let spp = reference_spp();
    let dir = root.join("target/bench-cache");
    let a = &scene.film.axis;
    let path = dir.join(format!(
        "cornell_64x64_{}x{}_from{}_b8_spp{spp}_seed12345.bin",
        a.bins, a.bin_width_opl, a.start_opl
    ));
    let (w, h, t, c) = (
        scene.film.width as usize,
        scene.film.height as usize,
        scene.film.axis.bins,
        scene.film.channels,
    );
    if let Ok(bytes) = std::fs::read(&path) {
        let v: Vec<f32> = bytes
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        if v.len() == w * h * t * c + w * h * c {
            let mut out = Transient::zeros(w, h, scene.film.axis, c);
            out.data.copy_from_slice(&v[..w * h * t * c]);
            out.steady.copy_from_slice(&v[w * h * t * c..]);
            return out;
        }
    }
    eprintln!("rendering the {spp}-spp reference once (cached in {})", path.display());
    let opts = RenderOptions {
        spp: Some(spp),
        seed: Some(12345),
        ..Default::default()
    };
    let (r, _) = render(scene, &opts).unwrap();
    std::fs::create_dir_all(&dir).unwrap();
    let bytes: Vec<u8> = r.data.iter().chain(&r.steady).flat_map(|v| v.to_le_bytes()).collect();
    std::fs::write(&path, bytes).unwrap();
    r
}
