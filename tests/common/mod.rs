//! Helpers shared by the integration tests.
#![allow(dead_code)]

use difftransient::{RenderOptions, Scene, Transient, render};
use std::path::PathBuf;

pub fn scene_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name)
}

pub fn load(name: &str) -> Scene {
    Scene::load(&scene_path(name), &[]).unwrap_or_else(|e| panic!("loading {name}: {e}"))
}

pub fn render_with(scene: &Scene, spp: u32, seed: u64, threads: usize) -> Transient {
    let opts = RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        threads: Some(threads),
        ..Default::default()
    };
    render(scene, &opts).expect("render").0
}

/// Mean and standard error over independent estimates.
pub fn mean_se(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}
