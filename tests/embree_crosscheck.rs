//! Cross-check of our Embree 3 wrapper against an independent Embree build: PyPI `embreex`
//! (Embree 4.4), run by `tests/embreex_crosscheck.py` in the venv at `<crate>/.venv` (or the
//! interpreter in `DTR_PYTHON`). The test fails, with instructions, when that Python is
//! missing: CI must run it.
//!
//! Scene: a tessellated floor, a box resting on it (its bottom face is coplanar with the
//! floor), a UV sphere, random triangles and tiny random triangles. Rays (seeded): random,
//! aimed at random triangles (some with a short `tfar`), aimed at tiny triangles, aimed at
//! shared and boundary edges, grazing the floor, lying in the floor plane, and tangent to the
//! sphere at its vertices. Every ray must agree on hit/miss and on distance (1e-5 relative);
//! primitive ids are not compared (coplanar faces may legally report either triangle).

use difftransient::accel::{Accel, Device, Ray8};
use npyz::WriterBuilder;
use std::path::{Path, PathBuf};
use std::process::Command;

/// "No tfar": the value embreex uses for an unbounded ray; we pass the same to both sides.
const FAR: f32 = 1e37;
const REL_TOL: f32 = 1e-5;

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn f(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next() >> 40) as f32 / (1u64 << 24) as f32)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn unit(&mut self) -> [f32; 3] {
        loop {
            let v = [self.f(-1.0, 1.0), self.f(-1.0, 1.0), self.f(-1.0, 1.0)];
            let l = dot(v, v).sqrt();
            if l > 0.1 && l <= 1.0 {
                return v.map(|c| c / l);
            }
        }
    }
    fn origin(&mut self) -> [f32; 3] {
        [self.f(-6.0, 6.0), self.f(-6.0, 6.0), self.f(-1.0, 6.0)]
    }
}

fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn lerp3(p: [[f32; 3]; 3], b: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|k| b[0] * p[0][k] + b[1] * p[1][k] + b[2] * p[2][k])
}

#[derive(Default)]
struct Mesh {
    p: Vec<[f32; 3]>,
    t: Vec<[u32; 3]>,
}

impl Mesh {
    fn vert(&mut self, v: [f32; 3]) -> u32 {
        self.p.push(v);
        self.p.len() as u32 - 1
    }
    fn tri(&self, k: usize) -> [[f32; 3]; 3] {
        self.t[k].map(|i| self.p[i as usize])
    }
}

struct Parts {
    mesh: Mesh,
    /// Triangle ranges of the floor grid, the sphere and the tiny triangles.
    floor: std::ops::Range<usize>,
    tiny: std::ops::Range<usize>,
    sphere_verts: std::ops::Range<usize>,
    sphere_center: [f32; 3],
}

fn build_mesh(rng: &mut Rng) -> Parts {
    let mut m = Mesh::default();
    // Floor z = 0 over [-3, 3]^2, a 6×6 grid with shared vertices (interior shared edges).
    let n = 6;
    let base = m.p.len() as u32;
    for j in 0..=n {
        for i in 0..=n {
            m.vert([-3.0 + i as f32, -3.0 + j as f32, 0.0]);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = base + j * (n + 1) + i;
            let (b, c, d) = (a + 1, a + n + 2, a + n + 1);
            m.t.push([a, b, c]);
            m.t.push([a, c, d]);
        }
    }
    let floor = 0..m.t.len();
    // A box [0.5, 1.5]^2 × [0, 1] resting on the floor: its bottom face is coplanar with it.
    let b0 = m.p.len() as u32;
    for k in 0..8u32 {
        m.vert([0.5 + (k & 1) as f32, 0.5 + ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32]);
    }
    for q in [
        [0, 2, 3, 1], // bottom z=0
        [4, 5, 7, 6], // top
        [0, 1, 5, 4], // y=0.5
        [2, 6, 7, 3], // y=1.5
        [0, 4, 6, 2], // x=0.5
        [1, 3, 7, 5], // x=1.5
    ] {
        m.t.push([b0 + q[0], b0 + q[1], b0 + q[2]]);
        m.t.push([b0 + q[0], b0 + q[2], b0 + q[3]]);
    }
    // A UV sphere, 24 slices × 16 stacks, shared vertices and pole fans.
    let (c, r, slices, stacks) = ([-1.0f32, -0.5, 1.2], 0.8f32, 24u32, 16u32);
    let sv = m.p.len();
    let top = m.vert([c[0], c[1], c[2] + r]);
    for s in 1..stacks {
        let th = std::f32::consts::PI * s as f32 / stacks as f32;
        for k in 0..slices {
            let ph = 2.0 * std::f32::consts::PI * k as f32 / slices as f32;
            m.vert([
                c[0] + r * th.sin() * ph.cos(),
                c[1] + r * th.sin() * ph.sin(),
                c[2] + r * th.cos(),
            ]);
        }
    }
    let bottom = m.vert([c[0], c[1], c[2] - r]);
    let ring = |s: u32, k: u32| top + 1 + (s - 1) * slices + k % slices;
    for k in 0..slices {
        m.t.push([top, ring(1, k), ring(1, k + 1)]);
        m.t.push([bottom, ring(stacks - 1, k + 1), ring(stacks - 1, k)]);
        for s in 1..stacks - 1 {
            m.t.push([ring(s, k), ring(s + 1, k), ring(s + 1, k + 1)]);
            m.t.push([ring(s, k), ring(s + 1, k + 1), ring(s, k + 1)]);
        }
    }
    let sphere_verts = sv..m.p.len();
    // Random triangles, then tiny ones (edges 1e-4 .. 1e-2).
    for _ in 0..80 {
        let ctr = [rng.f(-3.0, 3.0), rng.f(-3.0, 3.0), rng.f(0.2, 3.0)];
        let v = [0, 1, 2].map(|_| {
            let d = rng.unit().map(|x| x * rng.f(0.1, 0.7));
            m.vert([ctr[0] + d[0], ctr[1] + d[1], ctr[2] + d[2]])
        });
        m.t.push(v);
    }
    let tiny0 = m.t.len();
    for _ in 0..80 {
        let ctr = [rng.f(-3.0, 3.0), rng.f(-3.0, 3.0), rng.f(0.05, 3.0)];
        let size = 10f32.powf(rng.f(-4.0, -2.0));
        let v = [0, 1, 2].map(|_| {
            let d = rng.unit().map(|x| x * size);
            m.vert([ctr[0] + d[0], ctr[1] + d[1], ctr[2] + d[2]])
        });
        m.t.push(v);
    }
    let tiny = tiny0..m.t.len();
    Parts {
        mesh: m,
        floor,
        tiny,
        sphere_verts,
        sphere_center: c,
    }
}

#[derive(Clone, Copy)]
struct Ray {
    o: [f32; 3],
    d: [f32; 3],
    tfar: f32,
    kind: &'static str,
}

fn make_rays(parts: &Parts, rng: &mut Rng) -> Vec<Ray> {
    let m = &parts.mesh;
    let mut rays = Vec::new();
    let mut push = |o: [f32; 3], d: [f32; 3], tfar: f32, kind: &'static str| rays.push(Ray { o, d, tfar, kind });
    // Random rays, direction lengths 0.1 .. 10; half start among the objects.
    for i in 0..1200 {
        let o = if i % 2 == 0 {
            rng.origin()
        } else {
            [rng.f(-3.5, 3.5), rng.f(-3.5, 3.5), rng.f(-0.5, 3.5)]
        };
        let d = rng.unit().map(|c| c * rng.f(0.1, 10.0));
        push(o, d, FAR, "random");
    }
    // Aimed at an interior point of a random triangle; a fifth have tfar near the target.
    for i in 0..1600 {
        let tri = m.tri(rng.below(m.t.len()));
        let (a, b) = (rng.f(0.02, 0.96), rng.f(0.02, 0.96));
        let (a, b) = if a + b > 0.98 { (0.98 - a, 0.98 - b) } else { (a, b) };
        let target = lerp3(tri, [1.0 - a - b, a, b]);
        let o = rng.origin();
        let s = rng.f(0.2, 5.0);
        let d = sub(target, o).map(|c| c * s);
        let tfar = if i % 5 == 0 { rng.f(0.3, 1.2) / s } else { FAR };
        push(o, d, tfar, "aimed");
    }
    // Aimed at tiny triangles.
    for _ in 0..400 {
        let tri = m.tri(parts.tiny.start + rng.below(parts.tiny.len()));
        let (a, b) = (rng.f(0.05, 0.45), rng.f(0.05, 0.45));
        let target = lerp3(tri, [1.0 - a - b, a, b]);
        let o = rng.origin();
        push(o, sub(target, o), FAR, "tiny");
    }
    // Aimed at edges: shared floor edges (interior and boundary) and box edges, from above.
    for _ in 0..400 {
        let tri = if rng.below(3) == 0 {
            m.tri(parts.floor.end + rng.below(12)) // box
        } else {
            m.tri(parts.floor.start + rng.below(parts.floor.len()))
        };
        let e = rng.below(3);
        let a = rng.f(0.0, 1.0);
        let mut bary = [0.0; 3];
        bary[e] = a;
        bary[(e + 1) % 3] = 1.0 - a;
        let target = lerp3(tri, bary);
        let o = [rng.f(-6.0, 6.0), rng.f(-6.0, 6.0), rng.f(0.5, 6.0)];
        push(o, sub(target, o), FAR, "edge");
    }
    // Grazing the floor: heights 1e-3 .. 1e-1, hitting at distance 0.5 .. 5.
    for _ in 0..400 {
        let h = 10f32.powf(rng.f(-3.0, -1.0));
        let l = rng.f(0.5, 5.0);
        let a = rng.f(0.0, std::f32::consts::TAU);
        let o = [rng.f(-2.5, 2.5), rng.f(-2.5, 2.5), h];
        push(o, [a.cos(), a.sin(), -h / l], FAR, "grazing");
    }
    // In the floor plane (parallel to it; may clip the box's bottom edges).
    for _ in 0..100 {
        let a = rng.f(0.0, std::f32::consts::TAU);
        let o = [rng.f(-2.5, 2.5), rng.f(-2.5, 2.5), 0.0];
        push(o, [a.cos(), a.sin(), 0.0], FAR, "in-plane");
    }
    // Tangent to the (ideal) sphere at its tessellation vertices: they graze a vertex.
    for _ in 0..100 {
        let v = m.p[parts.sphere_verts.start + rng.below(parts.sphere_verts.len())];
        let n = sub(v, parts.sphere_center);
        let mut t = rng.unit();
        let k = dot(t, n) / dot(n, n);
        t = [t[0] - k * n[0], t[1] - k * n[1], t[2] - k * n[2]];
        let back = rng.f(1.0, 4.0);
        let o = [v[0] - back * t[0], v[1] - back * t[1], v[2] - back * t[2]];
        push(o, t, FAR, "tangent");
    }
    // A multiple of 8, for the packet comparison.
    while rays.len() % 8 != 0 {
        rays.pop();
    }
    rays
}

fn write_npy<T: npyz::AutoSerialize + Copy>(path: &Path, shape: &[u64], data: &[T]) {
    let f = std::fs::File::create(path).unwrap();
    let mut w = npyz::WriteOptions::new()
        .default_dtype()
        .shape(shape)
        .writer(std::io::BufWriter::new(f))
        .begin_nd()
        .unwrap();
    w.extend(data.iter().copied()).unwrap();
    w.finish().unwrap();
}

fn read_npy<T: npyz::Deserialize>(path: &Path) -> Vec<T> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("reading {}: {e}", path.display()));
    npyz::NpyFile::new(&bytes[..]).unwrap().into_vec().unwrap()
}

fn python() -> PathBuf {
    match std::env::var_os("DTR_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python"),
    }
}

const VENV_HELP: &str = "create the venv with\n  \
    cd <crate> && python3 -m venv .venv && .venv/bin/pip install embreex==4.4.0.post1 numpy\n\
    (Debian: apt-get install -y python3-venv), or point DTR_PYTHON at a Python that has \
    embreex and numpy. `tools/test` does this for you. This test is required, not optional.";

struct Reference {
    t: Vec<f32>,
    prim: Vec<i32>,
    occluded: Vec<i32>,
}

fn run_reference(mesh: &Mesh, rays: &[Ray]) -> Reference {
    let py = python();
    assert!(
        py.exists(),
        "the embreex cross-check needs Python at {}, which does not exist: {VENV_HELP}",
        py.display()
    );
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let flat = |f: &dyn Fn(&Ray) -> [f32; 3]| -> Vec<f32> { rays.iter().flat_map(f).collect() };
    let (nv, nt, nr) = (mesh.p.len() as u64, mesh.t.len() as u64, rays.len() as u64);
    write_npy(&d.join("verts.npy"), &[nv, 3], mesh.p.as_flattened());
    let tris: Vec<i32> = mesh.t.as_flattened().iter().map(|&i| i as i32).collect();
    write_npy(&d.join("tris.npy"), &[nt, 3], &tris);
    write_npy(&d.join("org.npy"), &[nr, 3], &flat(&|r| r.o));
    write_npy(&d.join("dir.npy"), &[nr, 3], &flat(&|r| r.d));
    let tfar: Vec<f32> = rays.iter().map(|r| r.tfar).collect();
    write_npy(&d.join("tfar.npy"), &[nr], &tfar);

    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/embreex_crosscheck.py");
    let out = Command::new(&py)
        .arg(&script)
        .arg(d)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}\n{VENV_HELP}", py.display()));
    let stderr = String::from_utf8_lossy(&out.stderr);
    match out.status.code() {
        Some(0) => {}
        Some(3) => panic!("{} cannot import embreex/numpy ({stderr}): {VENV_HELP}", py.display()),
        _ => panic!(
            "{} {} failed ({}):\n{stderr}",
            py.display(),
            script.display(),
            out.status
        ),
    }
    Reference {
        t: read_npy(&d.join("ref_t.npy")),
        prim: read_npy(&d.join("ref_prim.npy")),
        occluded: read_npy(&d.join("ref_occ.npy")),
    }
}

fn same_distance(a: f32, b: f32) -> bool {
    (a - b).abs() <= REL_TOL * a.abs().max(b.abs()) + 1e-7
}

#[test]
fn embree3_wrapper_agrees_with_embreex() {
    let mut rng = Rng(0x5EED_2021);
    let parts = build_mesh(&mut rng);
    let rays = make_rays(&parts, &mut rng);
    let mesh = &parts.mesh;
    let r = run_reference(mesh, &rays);
    assert_eq!(r.t.len(), rays.len());
    assert_eq!(r.prim.len(), rays.len());
    assert_eq!(r.occluded.len(), rays.len());

    let device = Device::new("").unwrap();
    let accel = Accel::build(&device, &mesh.p, &mesh.t).unwrap();

    // Single rays.
    let mut failures = Vec::new();
    let mut hits = 0;
    let mut other_prim = 0;
    for (i, ray) in rays.iter().enumerate() {
        let ours = accel.intersect1(ray.o, ray.d, 0.0, ray.tfar);
        let ref_hit = r.prim[i] >= 0;
        assert_eq!(ref_hit, r.occluded[i] == 1, "embreex: occluded vs intersect, ray {i}");
        hits += ref_hit as usize;
        match ours {
            Some(h) if ref_hit && same_distance(h.t, r.t[i]) => {
                other_prim += (h.prim as i32 != r.prim[i]) as usize;
            }
            None if !ref_hit => {}
            _ => failures.push(format!(
                "ray {i} ({}): ours {ours:?}, embreex t={} prim={}",
                ray.kind, r.t[i], r.prim[i]
            )),
        }
        if accel.occluded1(ray.o, ray.d, 0.0, ray.tfar) != ref_hit {
            failures.push(format!("ray {i} ({}): occluded1 disagrees", ray.kind));
        }
    }
    let n = rays.len();
    eprintln!(
        "{n} rays, {hits} hits in embreex, {} disagreements, {other_prim} hits on another \
         triangle at the same distance",
        failures.len()
    );
    assert!(
        failures.is_empty(),
        "{} of {n} rays disagree with embreex:\n{}",
        failures.len(),
        failures.join("\n")
    );
    assert!(
        hits > n / 3 && hits < n - n / 10,
        "a meaningful mix: {hits} hits of {n}"
    );
    for kind in ["random", "aimed", "tiny", "edge", "grazing", "in-plane", "tangent"] {
        let k: Vec<usize> = (0..n).filter(|&i| rays[i].kind == kind).collect();
        let h = k.iter().filter(|&&i| r.prim[i] >= 0).count();
        eprintln!("  {kind:9} {:5} rays {h:5} hits", k.len());
    }

    // Packets, with a seeded pattern of inactive lanes, both coherence hints.
    let mut lane_failures = Vec::new();
    for (p, chunk) in rays.chunks(8).enumerate() {
        let mut r8 = Ray8::default();
        for (l, ray) in chunk.iter().enumerate() {
            r8.set(l, ray.o, ray.d, 0.0, ray.tfar);
        }
        let active: [bool; 8] = std::array::from_fn(|_| rng.below(5) != 0);
        let coherent = p % 2 == 1;
        let h8 = accel.intersect8(&r8, active, coherent);
        let o8 = accel.occluded8(&r8, active, coherent);
        for l in 0..8 {
            let i = p * 8 + l;
            let ref_hit = active[l] && r.prim[i] >= 0;
            let ok = match h8.get(l) {
                Some(h) => ref_hit && same_distance(h.t, r.t[i]),
                None => !ref_hit,
            } && o8[l] == ref_hit;
            if !ok {
                lane_failures.push(format!(
                    "ray {i} lane {l} active {}: intersect8 {:?}, occluded8 {}, embreex t={}",
                    active[l],
                    h8.get(l),
                    o8[l],
                    r.t[i]
                ));
            }
        }
    }
    assert!(
        lane_failures.is_empty(),
        "{} packet lanes disagree with embreex:\n{}",
        lane_failures.len(),
        lane_failures.join("\n")
    );
}
