//! Helpers shared by the integration tests.
#![allow(dead_code)]

pub mod fd;
pub mod power;

use difftransient::{RenderOptions, Scene, Transient, render};
use std::path::PathBuf;

pub fn scene_path(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name)
}

pub fn load(name: &str) -> Scene {
    Scene::load(&scene_path(name), &[]).unwrap_or_else(|e| panic!("loading {name}: {e}"))
}

/// scenes/cornell_box.toml at `width` × `height` pixels and `max_bounces` bounces.
pub fn cornell(width: u32, height: u32, max_bounces: u32) -> Scene {
    let mut s = load("cornell_box.toml");
    s.film.width = width;
    s.film.height = height;
    s.integrator.max_bounces = max_bounces;
    s
}

/// Every conductor and dielectric of `scene` made smooth (roughness 0: Dirac lobes).
pub fn make_smooth(scene: &mut Scene) {
    use difftransient::scene::Material;
    for m in &mut scene.materials {
        if let Material::Conductor { roughness, .. } | Material::Dielectric { roughness, .. } = &mut m.material {
            *roughness = 0.0;
        }
    }
}

/// A forward render whose steady image integrates all time (`SteadyMode::Full`, no window
/// cut): the tests that use it compare steady images with all-time references (energy
/// conservation, umbrae, closed forms); tests/window_cut.rs checks the cut itself.
pub fn render_with(scene: &Scene, spp: u32, seed: u64, threads: usize) -> Transient {
    let opts = RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        threads: Some(threads),
        steady: difftransient::film::SteadyMode::Full,
        ..Default::default()
    };
    render(scene, &opts).expect("render").0
}

/// 4×4 blocks of the time-summed image (channel 0), then groups of `group` bins of the image
/// total: the aggregates of the boundary-term tests (tests/secondary_fd.rs,
/// tests/dielectric_pose_fd.rs).
pub fn blocks_and_bin_groups(t: &Transient, group: usize) -> Vec<f64> {
    let (bw, bh) = (t.width / 4, t.height / 4);
    let mut out = vec![0.0f64; 16];
    for y in 0..t.height {
        for x in 0..t.width {
            out[(y / bh).min(3) * 4 + (x / bw).min(3)] += t.time_sum(x, y, 0) as f64;
        }
    }
    out.extend(bin_groups(t, group));
    out
}

/// Every pixel's time-summed value (channel 0, row by row), then groups of `group` bins of the
/// image total: aggregates fine enough that a relative-bias fit is not dominated by the
/// blocks where two parts of the derivative cancel (tests/dielectric_pose_fd.rs).
pub fn pixels_and_bin_groups(t: &Transient, group: usize) -> Vec<f64> {
    let mut out: Vec<f64> = (0..t.height)
        .flat_map(|y| (0..t.width).map(move |x| t.time_sum(x, y, 0) as f64))
        .collect();
    out.extend(bin_groups(t, group));
    out
}

/// Sums of `group` consecutive bins of the image total (over pixels and channels).
fn bin_groups(t: &Transient, group: usize) -> Vec<f64> {
    let bins = t.bin_totals();
    bins.chunks(group)
        .map(|c| c.iter().map(|&v| v as f64).sum::<f64>())
        .collect()
}

/// Options of a render at `spp` samples per pixel from `seed` on two threads, everything else
/// as the scene or the defaults say (a derivative render: both terms of the gradient).
pub fn options(spp: u32, seed: u64) -> RenderOptions {
    RenderOptions {
        spp: Some(spp),
        seed: Some(seed),
        threads: Some(2),
        ..Default::default()
    }
}

/// Mean and standard error over independent estimates.
pub fn mean_se(xs: &[f64]) -> (f64, f64) {
    let n = xs.len() as f64;
    let m = xs.iter().sum::<f64>() / n;
    let var = xs.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0);
    (m, (var / n).sqrt())
}

/// E[Σ t²] and its standard deviation over `n` independent Student-t entries with `dof`
/// degrees of freedom: E[t²] = ν/(ν−2), Var[t²] = 2ν²(ν−1)/((ν−2)²(ν−4)).
pub fn t2_sum_moments(n: f64, dof: f64) -> (f64, f64) {
    let mean = n * dof / (dof - 2.0);
    let sd = (n * 2.0 * dof * dof * (dof - 1.0) / ((dof - 2.0).powi(2) * (dof - 4.0))).sqrt();
    (mean, sd)
}

/// Two independent sets of K estimates per entry (`a[k][i]`, `b[k][i]`): Σz², max |z| and
/// the number of entries where either varies, with z = (mean_a − mean_b) / √(se_a² + se_b²).
pub fn two_sample_z(a: &[Vec<f64>], b: &[Vec<f64>]) -> (f64, f64, usize) {
    let (mut chi2, mut zmax, mut n) = (0.0, 0.0f64, 0);
    for i in 0..a[0].len() {
        let (ma, sa) = mean_se(&a.iter().map(|r| r[i]).collect::<Vec<_>>());
        let (mb, sb) = mean_se(&b.iter().map(|r| r[i]).collect::<Vec<_>>());
        let se = (sa * sa + sb * sb).sqrt();
        if se == 0.0 {
            continue;
        }
        let z = (ma - mb) / se;
        chi2 += z * z;
        zmax = zmax.max(z.abs());
        n += 1;
    }
    (chi2, zmax, n)
}

/// Asserts that two independent sets of K estimates of the same aggregates (`a[k][i]`,
/// `reference[k][i]`, entry 0 their total) agree within noise: Σz² within 5 standard deviations
/// of its χ² expectation, every |z| below 4.5, and the reference's total resolved to 1 %.
pub fn assert_agree(a: &[Vec<f64>], reference: &[Vec<f64>], what: &str) {
    let (m, se) = mean_se(&reference.iter().map(|r| r[0]).collect::<Vec<_>>());
    eprintln!("{what}: total {m:.4} ± {se:.4}");
    assert!(
        se / m < 0.01,
        "{what}: the total is resolved only to {:.2} %",
        100.0 * se / m
    );
    assert_within_noise(a, reference, what);
}

/// Asserts that two independent sets of K estimates of the same aggregates agree within
/// noise: Σz² within 5 standard deviations of its χ² expectation, and every |z| below 4.5
/// ([`two_sample_z`]). The caller shows that the comparison resolves what it must.
pub fn assert_within_noise(a: &[Vec<f64>], reference: &[Vec<f64>], what: &str) {
    let (chi2, zmax, n) = two_sample_z(a, reference);
    eprintln!("{what}: Σz² = {chi2:.1} over {n}, max|z| = {zmax:.2}");
    let nf = n as f64;
    assert!(
        chi2 <= nf + 5.0 * (2.0 * nf).sqrt(),
        "{what}: Σz² = {chi2:.1} over {n} aggregates"
    );
    assert!(zmax < 4.5, "{what}: an aggregate is {zmax:.2} standard errors off");
}

fn add_to_position(v: &mut toml::Value, by: [f64; 3]) {
    let a = v.as_array_mut().expect("a position is an array");
    for (x, b) in a.iter_mut().zip(by) {
        *x = toml::Value::Float(x.as_float().or_else(|| x.as_integer().map(|i| i as f64)).unwrap() + b);
    }
}

/// The scene text with every world position moved by `by`: shape translations, camera
/// position and target, point and laser positions.
pub fn translated(text: &str, by: [f64; 3]) -> String {
    let mut v: toml::Value = toml::from_str(text).unwrap();
    add_to_position(&mut v["camera"]["position"], by);
    add_to_position(&mut v["camera"]["look_at"], by);
    for s in v["shape"].as_array_mut().unwrap() {
        let t = s.as_table_mut().unwrap();
        let tr = t
            .entry("translate")
            .or_insert(toml::Value::Array(vec![toml::Value::Float(0.0); 3]));
        add_to_position(tr, by);
    }
    if let Some(es) = v.get_mut("emitter").and_then(|e| e.as_array_mut()) {
        for e in es {
            if let Some(p) = e.get_mut("position") {
                add_to_position(p, by);
            }
        }
    }
    toml::to_string(&v).unwrap()
}

/// The shape and the f32 values of an .npy file `dtr` wrote.
pub fn npy(path: &std::path::Path) -> (Vec<u64>, Vec<f32>) {
    let bytes = std::fs::read(path).unwrap();
    let f = npyz::NpyFile::new(&bytes[..]).unwrap();
    let shape = f.shape().to_vec();
    (shape, f.into_vec().unwrap())
}

/// Runs the `dtr` binary with `args` in `cwd`.
pub fn dtr(args: &[&str], cwd: &std::path::Path) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_dtr"))
        .current_dir(cwd)
        .args(args)
        .output()
        .unwrap()
}

/// [`dtr`] with every file it writes limited to `bytes` (RLIMIT_FSIZE, SIGXFSZ ignored): a
/// write past the limit fails with EFBIG ("File too large"), partly written where it crosses
/// it, as a write to a full disk fails with ENOSPC; no mount, no root.
#[cfg(unix)]
pub fn dtr_with_file_size_limit(args: &[&str], cwd: &std::path::Path, bytes: u64) -> std::process::Output {
    use std::os::unix::process::CommandExt;
    let mut limited = std::process::Command::new(env!("CARGO_BIN_EXE_dtr"));
    limited.current_dir(cwd).args(args);
    // SAFETY: only async-signal-safe calls between fork and exec
    unsafe {
        limited.pre_exec(move || {
            // a write past the limit fails with EFBIG instead of raising SIGXFSZ
            libc::signal(libc::SIGXFSZ, libc::SIG_IGN);
            let limit = libc::rlimit {
                rlim_cur: bytes as libc::rlim_t,
                rlim_max: libc::RLIM_INFINITY,
            };
            if libc::setrlimit(libc::RLIMIT_FSIZE, &limit) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    limited.output().unwrap()
}

/// The scene file's transient at its own parameter values, rendered at 1024 spp: a target
/// for inverse rendering whose noise barely moves the loss's minimum.
pub fn converged_target(scene: &std::path::Path) -> Transient {
    let truth = Scene::load(scene, &[]).unwrap();
    let opts = RenderOptions {
        spp: Some(1024),
        seed: Some(1000),
        threads: Some(2),
        ..Default::default()
    };
    render(&truth, &opts).unwrap().0
}

/// A fixed pseudo-random adjoint ∂L/∂I of both signs over the film of `t` (xorshift values in
/// [−1, 1)), for tests of adjoint gradients.
pub fn adjoint_like(t: &Transient) -> Transient {
    let mut a = t.clone();
    let mut x = 0x2545_f491_4f6c_dd1du64;
    for v in a.data.iter_mut() {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        *v = (x >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0;
    }
    a
}

/// An inverse-rendering problem on a shipped scene: its 1024-spp transient as the target
/// ([`converged_target`]), `params` free within `bounds`, 4 spp per iteration, seed 1,
/// two threads.
pub fn small_problem(
    scene: &str,
    params: &[&str],
    loss: difftransient::optimize::loss::Loss,
    bounds: Vec<(f64, f64)>,
) -> difftransient::optimize::Problem {
    let scene = scene_path(scene);
    let target = converged_target(&scene);
    difftransient::optimize::Problem {
        scene,
        fixed: vec![],
        fixed_text: Vec::new(),
        params: params.iter().map(|p| p.to_string()).collect(),
        target,
        loss,
        opts: RenderOptions {
            spp: Some(4),
            seed: Some(1),
            threads: Some(2),
            ..Default::default()
        },
        bounds,
    }
}

/// An empty folder that nobody may write in, root included (the tests run as root in CI,
/// where permissions block nothing): a read-only tmpfs mounted on a temporary folder when
/// running as root, a folder without write permission otherwise. `None` (the caller skips,
/// saying so) when root may not mount.
#[cfg(unix)]
pub struct ReadOnlyFolder {
    pub path: std::path::PathBuf,
    mounted: bool,
    _tmp: tempfile::TempDir,
}

#[cfg(unix)]
impl ReadOnlyFolder {
    pub fn new() -> Option<Self> {
        use std::os::unix::fs::PermissionsExt;
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("ro");
        std::fs::create_dir(&path).unwrap();
        let root = unsafe { libc::geteuid() } == 0;
        if root {
            let mounted = std::process::Command::new("mount")
                .args(["-t", "tmpfs", "-o", "ro,size=64k", "tmpfs"])
                .arg(&path)
                .status()
                .is_ok_and(|s| s.success());
            if !mounted {
                eprintln!("skipped: root here may not mount a read-only tmpfs");
                return None;
            }
        } else {
            std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o555)).unwrap();
        }
        Some(Self {
            path,
            mounted: root,
            _tmp: tmp,
        })
    }
}

#[cfg(unix)]
impl Drop for ReadOnlyFolder {
    fn drop(&mut self) {
        use std::os::unix::fs::PermissionsExt;
        if self.mounted {
            let _ = std::process::Command::new("umount").arg(&self.path).status();
        } else {
            let _ = std::fs::set_permissions(&self.path, std::fs::Permissions::from_mode(0o755));
        }
    }
}
