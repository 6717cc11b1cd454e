//! How far a derivative is from finite differences, as a relative bias: a diagnostic for
//! derivative tests that sit a little off (tests/dielectric_pose_fd.rs was found this way to
//! need a per-pixel fit and a smaller step, not a fix of the derivative).
//!
//! For K seeds it renders the derivative's parts (interior, primary, secondary edges) and
//! Richardson's finite-difference reference (4·FD(h) − FD(2h)) / 3 with common random
//! numbers, aggregates them (4×4 blocks and bin groups, or single pixels), and fits the
//! residual full − FD per seed by weighted least squares: on the full derivative (its relative
//! bias, mean ± standard error over seeds) and on the parts at once (a relative bias per part).
//!
//! ```sh
//! PROBE_SCENE=scenes/glass_pose.toml PROBE_PARAM=glass_x PROBE_VALUE=0.1 PROBE_H=0.01 \
//!   PROBE_SEEDS=64 PROBE_SPP=512 PROBE_SPPB=2048 PROBE_SPPFD=2048 PROBE_INT=bdpt PROBE_PIXELS=1 \
//!   cargo test --release --test integration derivative_bias:: -- --ignored --nocapture
//! ```
//!
//! It asserts nothing and is ignored: a measurement to run by hand, kept beside the tests it
//! serves.
//!
//! Other settings: PROBE_SEED0 (first seed), PROBE_GROUP (bins per group), PROBE_THREADS,
//! PROBE_GUIDE (guided boundary rays), PROBE_VERBOSE (every aggregate; with PROBE_PIXELS the
//! pixels beyond 3.5 standard errors are always listed).

use crate::common;
use difftransient::scene::IntegratorKind;
use difftransient::{BoundaryMode, RenderOptions, Scene, render, render_diff_parts};

fn env<T: std::str::FromStr>(k: &str, d: T) -> T {
    std::env::var(k).ok().and_then(|v| v.parse().ok()).unwrap_or(d)
}

fn col(m: &[Vec<f64>], i: usize) -> Vec<f64> {
    m.iter().map(|r| r[i]).collect()
}

/// Solves the small dense system a x = b (Gaussian elimination with pivoting).
fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Vec<f64> {
    let n = b.len();
    for c in 0..n {
        let p = (c..n).max_by(|&i, &j| a[i][c].abs().total_cmp(&a[j][c].abs())).unwrap();
        a.swap(c, p);
        b.swap(c, p);
        for r in c + 1..n {
            let f = a[r][c] / a[c][c];
            for k in c..n {
                a[r][k] -= f * a[c][k];
            }
            b[r] -= f * b[c];
        }
    }
    let mut x = vec![0.0; n];
    for c in (0..n).rev() {
        x[c] = (b[c] - (c + 1..n).map(|k| a[c][k] * x[k]).sum::<f64>()) / a[c][c];
    }
    x
}

#[test]
#[ignore]
fn derivative_bias() {
    let scene_path = std::path::PathBuf::from(std::env::var("PROBE_SCENE").unwrap());
    let param: String = std::env::var("PROBE_PARAM").unwrap();
    let value: f64 = env("PROBE_VALUE", 0.0);
    let h: f64 = env("PROBE_H", 0.03);
    let seeds: u64 = env("PROBE_SEEDS", 16);
    let spp: u32 = env("PROBE_SPP", 64);
    let sppb: u32 = env("PROBE_SPPB", 64);
    let sppfd: u32 = env("PROBE_SPPFD", 256);
    let group: usize = env("PROBE_GROUP", 4);
    let integrator = match std::env::var("PROBE_INT").as_deref() {
        Ok("bdpt") => Some(IntegratorKind::Bdpt),
        _ => None,
    };
    let load = |v: f64| Scene::load(&scene_path, &[(param.clone(), v)]).unwrap();
    let opts = |seed: u64, spp: u32| RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        threads: Some(env("PROBE_THREADS", 2)),
        spp_boundary: Some(sppb),
        boundary: BoundaryMode::Full,
        integrator,
        guiding: std::env::var("PROBE_GUIDE").is_ok(),
        ..Default::default()
    };
    let base = load(value);
    let steps = [
        load(value + h),
        load(value - h),
        load(value + 2.0 * h),
        load(value - 2.0 * h),
    ];
    let mut parts: [Vec<Vec<f64>>; 3] = [vec![], vec![], vec![]];
    let mut rich = vec![];
    let seed0: u64 = env("PROBE_SEED0", 0);
    for seed in seed0..seed0 + seeds {
        let p = render_diff_parts(&base, std::slice::from_ref(&param), &opts(seed, spp)).unwrap();
        let agg = |t: &difftransient::Transient| {
            if std::env::var("PROBE_PIXELS").is_ok() {
                (0..t.height)
                    .flat_map(|y| (0..t.width).map(move |x| (x, y)))
                    .map(|(x, y)| t.time_sum(x, y, 0) as f64)
                    .collect()
            } else {
                common::blocks_and_bin_groups(t, group)
            }
        };
        parts[0].push(agg(&p.interior[0]));
        parts[1].push(
            p.primary
                .first()
                .map(agg)
                .unwrap_or_else(|| vec![0.0; parts[0][0].len()]),
        );
        parts[2].push(
            p.secondary
                .first()
                .map(agg)
                .unwrap_or_else(|| vec![0.0; parts[0][0].len()]),
        );
        let f: Vec<Vec<f64>> = steps
            .iter()
            .map(|s| agg(&render(s, &opts(seed, sppfd)).unwrap().0))
            .collect();
        let n = f[0].len();
        rich.push(
            (0..n)
                .map(|i| {
                    let d1 = (f[0][i] - f[1][i]) / (2.0 * h);
                    let d2 = (f[2][i] - f[3][i]) / (4.0 * h);
                    (4.0 * d1 - d2) / 3.0
                })
                .collect::<Vec<f64>>(),
        );
    }
    let n = rich[0].len();
    let k = seeds as usize;
    let full: Vec<Vec<f64>> = (0..k)
        .map(|s| (0..n).map(|i| parts.iter().map(|p| p[s][i]).sum()).collect())
        .collect();
    let resid: Vec<Vec<f64>> = (0..k)
        .map(|s| (0..n).map(|i| full[s][i] - rich[s][i]).collect())
        .collect();
    let v: Vec<f64> = (0..n)
        .map(|i| {
            let (_, se) = common::mean_se(&col(&resid, i));
            se * se * k as f64
        })
        .collect();
    let means: Vec<Vec<f64>> = parts
        .iter()
        .map(|p| (0..n).map(|i| common::mean_se(&col(p, i)).0).collect())
        .collect();
    let fullm: Vec<f64> = (0..n).map(|i| common::mean_se(&col(&full, i)).0).collect();
    let richm: Vec<f64> = (0..n).map(|i| common::mean_se(&col(&rich, i)).0).collect();
    for i in 0..n {
        let z = (fullm[i] - richm[i]) / (v[i] / k as f64).sqrt();
        if std::env::var("PROBE_VERBOSE").is_ok() || (std::env::var("PROBE_PIXELS").is_ok() && z.abs() > 3.5) {
            eprintln!(
                "{i:3}: int {:+.4e} prim {:+.4e} sec {:+.4e} | full {:+.4e} FD {:+.4e} ± {:.2e}",
                means[0][i],
                means[1][i],
                means[2][i],
                fullm[i],
                richm[i],
                (v[i] / k as f64).sqrt()
            );
        }
    }
    // per-seed GLS fits: one regressor (the full derivative) and one per part that is not zero
    let fit = |regs: &[Vec<f64>], label: &str| {
        let m = regs.len();
        let mut a = vec![vec![0.0; m]; m];
        for p in 0..m {
            for q in 0..m {
                a[p][q] = (0..n)
                    .filter(|&i| v[i] > 0.0)
                    .map(|i| regs[p][i] * regs[q][i] / v[i])
                    .sum();
            }
        }
        let betas: Vec<Vec<f64>> = (0..k)
            .map(|s| {
                let b: Vec<f64> = (0..m)
                    .map(|p| {
                        (0..n)
                            .filter(|&i| v[i] > 0.0)
                            .map(|i| regs[p][i] * resid[s][i] / v[i])
                            .sum()
                    })
                    .collect();
                solve(a.clone(), b)
            })
            .collect();
        for p in 0..m {
            let (mb, se) = common::mean_se(&betas.iter().map(|b| b[p]).collect::<Vec<_>>());
            eprintln!(
                "{label} β{p}: {:+.2} % ± {:.2} % (z {:.2})",
                100.0 * mb,
                100.0 * se,
                mb / se
            );
        }
    };
    fit(std::slice::from_ref(&fullm), "full");
    let nz: Vec<Vec<f64>> = means.iter().filter(|m| m.iter().any(|v| *v != 0.0)).cloned().collect();
    fit(&nz, "parts(int,prim?,sec)");
    let chi2: f64 = (0..n)
        .filter(|&i| v[i] > 0.0)
        .map(|i| (fullm[i] - richm[i]).powi(2) / (v[i] / k as f64))
        .sum();
    eprintln!("Σz² full {chi2:.1} over {n}");
}
