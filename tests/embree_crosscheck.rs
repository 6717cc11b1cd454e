//! Cross-check of our Embree 3 wrapper (`difftransient::accel`) against an independent Embree
//! build: PyPI `embreex` 4.4.0.post1 (Embree 4.4), run by `tests/embreex_crosscheck.py` with
//! the interpreter in `DTR_PYTHON`, else `<crate>/.venv/bin/python`. When that Python or
//! embreex is missing the test FAILS with instructions: CI must run it (`tools/test` creates
//! the venv).
//!
//! Scene (built here, seeded, 774 triangles): a 6×6-cell floor grid at z = 0 with shared
//! vertices, a closed box resting on it (its bottom face is coplanar with the floor), a closed
//! UV sphere (528 triangles), 80 random well-shaped triangles, 80 tiny equilateral ones (edges
//! 1e-4 .. 1e-2, a quarter exactly 1e-4) and two triangles about 1e3 from the origin.
//!
//! Rays (5496, seeded, shuffled so packets mix kinds; unbounded ones alternate tfar = +inf and
//! 1e37): random (a quarter with a finite tfar); aimed at interior points of random
//! triangles (a fifth with a finite tfar before or after the target); aimed at tiny and at far
//! triangles; aimed at shared edges of the floor grid and of the closed box and sphere, from
//! in front of both faces; 1e-3 inside or outside the floor's open boundary; grazing the floor
//! at shallow angles from above and below; parallel to the floor 1e-4 .. 1e-2 above it, some
//! aimed at the box's sides; tangent to the sphere at its vertices, shifted 1e-3·r inward
//! (must hit) or outward (must miss the sphere). tnear is 0 (embreex fixes it).
//!
//! Every ray is constructed so that its answer is well defined, with margins well above float
//! rounding: no ray lies in the floor plane, passes within rounding error of an open
//! boundary, a vertex, or a tiny triangle's edge, or touches a solid's silhouette. Those rays
//! are undecided: either answer is legal, and Embree's robust test is not watertight at
//! vertices (see "shared-edge" in `make_rays`). In practice Embree 3.13 and 4.4 answer them
//! identically too (2000 in-plane and 1000 exact vertex-tangent rays all agreed when tried),
//! but a geometric expectation only holds for well-defined rays.
//!
//! `wrapper_agrees_with_embreex` checks every ray: hit/miss of our `intersect1`, `occluded1`
//! and of the active lanes of `intersect8`/`occluded8` agree with embreex's INTERSECT and
//! OCCLUDED, and embreex's two queries agree with each other; hit distances agree to 1e-5
//! relative (they are in fact identical); a ray built to reach a surface point at
//! `t_target ≤ tfar` hits at `t ≤ t_target` in both libraries (an oracle independent of
//! Embree). Primitive ids are not compared (coplanar faces may legally report either
//! triangle). `packets_match_single_rays`, which needs no Python, checks `intersect8` and
//! `occluded8` against `intersect1` and `occluded1` lane by lane, with inactive lanes, both
//! coherence hints and `tnear > 0`: bit for bit, except the documented ties of coherent
//! packets.

use difftransient::accel::{Accel, Device, Hit, Ray8};
use npyz::WriterBuilder;
use std::path::{Path, PathBuf};
use std::process::Command;

const REL_TOL: f32 = 1e-5;

// ---- Seeded randomness and small vector helpers -------------------------------------------

/// SplitMix64.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [lo, hi).
    fn f(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next() >> 40) as f32 / (1u64 << 24) as f32)
    }
    /// Log-uniform in [lo, hi).
    fn log(&mut self, lo: f32, hi: f32) -> f32 {
        (self.f(lo.ln(), hi.ln())).exp()
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
    fn chance(&mut self, p: f32) -> bool {
        self.f(0.0, 1.0) < p
    }
    fn unit(&mut self) -> [f32; 3] {
        loop {
            let v = [self.f(-1.0, 1.0), self.f(-1.0, 1.0), self.f(-1.0, 1.0)];
            let l = len(v);
            if l > 0.1 && l <= 1.0 {
                return scale(v, 1.0 / l);
            }
        }
    }
    /// A ray origin in and around the scene (not the far triangles).
    fn origin(&mut self) -> [f32; 3] {
        [self.f(-6.0, 6.0), self.f(-6.0, 6.0), self.f(-2.0, 6.0)]
    }
}

fn add(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn scale(a: [f32; 3], s: f32) -> [f32; 3] {
    a.map(|c| c * s)
}
fn dot(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn len(a: [f32; 3]) -> f32 {
    dot(a, a).sqrt()
}
fn normalize(a: [f32; 3]) -> [f32; 3] {
    scale(a, 1.0 / len(a))
}
/// (1 − b1 − b2)·p0 + b1·p1 + b2·p2.
fn bary(p: [[f32; 3]; 3], b1: f32, b2: f32) -> [f32; 3] {
    let b0 = 1.0 - b1 - b2;
    std::array::from_fn(|k| b0 * p[0][k] + b1 * p[1][k] + b2 * p[2][k])
}
/// Two unit vectors completing `n` (unit) to an orthonormal frame.
fn frame(n: [f32; 3]) -> ([f32; 3], [f32; 3]) {
    let a = if n[0].abs() < 0.6 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    let e1 = normalize(cross(n, a));
    (e1, cross(n, e1))
}

// ---- The scene ------------------------------------------------------------------------------

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
    /// An equilateral triangle with circumradius `r` around `c`, normal `n` (unit).
    fn equilateral(&mut self, c: [f32; 3], n: [f32; 3], r: f32) {
        let (e1, e2) = frame(n);
        let v = [0.0f32, 1.0, 2.0].map(|k| {
            let a = k * std::f32::consts::TAU / 3.0;
            self.vert(add(c, add(scale(e1, r * a.cos()), scale(e2, r * a.sin()))))
        });
        self.t.push(v);
    }
}

type Range = std::ops::Range<usize>;

struct Scene {
    mesh: Mesh,
    /// Triangle ranges of the parts.
    floor: Range,
    boxx: Range,
    sphere: Range,
    tiny: Range,
    far: Range,
    /// Vertex range of the sphere.
    sphere_verts: Range,
    sphere_center: [f32; 3],
    sphere_radius: f32,
}

/// Floor z = 0 over [-HALF, HALF]², cells of size 1.
const HALF: f32 = 3.0;

fn build_scene(rng: &mut Rng) -> Scene {
    let mut m = Mesh::default();
    // Floor: a grid with shared vertices, so interior edges and vertices are shared.
    let n = 6u32;
    for j in 0..=n {
        for i in 0..=n {
            m.vert([-HALF + i as f32, -HALF + j as f32, 0.0]);
        }
    }
    for j in 0..n {
        for i in 0..n {
            let a = j * (n + 1) + i;
            let (b, c, d) = (a + 1, a + n + 2, a + n + 1);
            m.t.push([a, b, c]);
            m.t.push([a, c, d]);
        }
    }
    let floor = 0..m.t.len();

    // A closed box [0.5, 1.5]² × [0, 1] resting on the floor: its bottom is coplanar with it.
    let b0 = m.p.len() as u32;
    for k in 0..8u32 {
        m.vert([0.5 + (k & 1) as f32, 0.5 + ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32]);
    }
    let box_start = m.t.len();
    for q in [
        [0, 2, 3, 1], // bottom, z = 0
        [4, 5, 7, 6], // top, z = 1
        [0, 1, 5, 4], // y = 0.5
        [2, 6, 7, 3], // y = 1.5
        [0, 4, 6, 2], // x = 0.5
        [1, 3, 7, 5], // x = 1.5
    ] {
        m.t.push([b0 + q[0], b0 + q[1], b0 + q[2]]);
        m.t.push([b0 + q[0], b0 + q[2], b0 + q[3]]);
    }
    let boxx = box_start..m.t.len();

    // A closed UV sphere, 24 slices × 12 stacks with pole fans: 528 triangles.
    let (c, r, slices, stacks) = ([-1.0f32, -0.5, 1.2], 0.8f32, 24u32, 12u32);
    let sv = m.p.len();
    let sphere_start = m.t.len();
    let top = m.vert([c[0], c[1], c[2] + r]);
    for s in 1..stacks {
        let th = std::f32::consts::PI * s as f32 / stacks as f32;
        for k in 0..slices {
            let ph = std::f32::consts::TAU * k as f32 / slices as f32;
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
    let sphere = sphere_start..m.t.len();
    let sphere_verts = sv..m.p.len();

    // Random, reasonably shaped triangles (smallest altitude ≥ 0.1 × longest edge). Some
    // pierce the floor or the sphere.
    let mut made = 0;
    while made < 80 {
        let ctr = [rng.f(-3.0, 3.0), rng.f(-3.0, 3.0), rng.f(0.2, 3.0)];
        let p: [[f32; 3]; 3] = std::array::from_fn(|_| add(ctr, scale(rng.unit(), rng.f(0.1, 0.7))));
        let area2 = len(cross(sub(p[1], p[0]), sub(p[2], p[0])));
        let longest = (0..3).map(|k| len(sub(p[(k + 1) % 3], p[k]))).fold(0.0, f32::max);
        if area2 / longest < 0.1 * longest {
            continue;
        }
        let v = p.map(|q| m.vert(q));
        m.t.push(v);
        made += 1;
    }

    // Tiny equilateral triangles, edges 1e-4 .. 1e-2 (circumradius = edge / √3).
    let tiny_start = m.t.len();
    for k in 0..80 {
        let edge = if k % 4 == 0 { 1e-4 } else { rng.log(1e-4, 1e-2) };
        let ctr = [rng.f(-3.0, 3.0), rng.f(-3.0, 3.0), rng.f(0.05, 3.0)];
        let n = rng.unit();
        m.equilateral(ctr, n, edge / 3f32.sqrt());
    }
    let tiny = tiny_start..m.t.len();

    // Two triangles about 1e3 from the origin, facing it: a large one and a small one.
    let far_start = m.t.len();
    for (c, r) in [([700.0f32, -600.0, 400.0], 20.0f32), ([-950.0, 150.0, 300.0], 0.5)] {
        m.equilateral(c, normalize(scale(c, -1.0)), r);
    }
    let far = far_start..m.t.len();

    Scene {
        mesh: m,
        floor,
        boxx,
        sphere,
        tiny,
        far,
        sphere_verts,
        sphere_center: c,
        sphere_radius: r,
    }
}

// ---- The rays -------------------------------------------------------------------------------

#[derive(Clone, Copy, Debug)]
struct Ray {
    o: [f32; 3],
    d: [f32; 3],
    tfar: f32,
    kind: &'static str,
    /// The ray reaches a surface point (away from any open boundary) at this parameter:
    /// if it is ≤ tfar, the closest hit must exist and lie at or before it.
    target_t: Option<f32>,
}

const KINDS: [&str; 11] = [
    "random",
    "aimed",
    "tiny",
    "far",
    "shared-edge",
    "open-edge",
    "graze-floor",
    "parallel",
    "box-side",
    "tangent-in",
    "tangent-out",
];

/// A ray of no kind yet (`push` sets it).
fn ray(o: [f32; 3], d: [f32; 3], tfar: f32, target_t: Option<f32>) -> Ray {
    Ray {
        o,
        d,
        tfar,
        kind: "",
        target_t,
    }
}

/// "No end" for a ray: alternately +inf and embreex's default 1e37 (both must work).
fn unbounded(rng: &mut Rng) -> f32 {
    if rng.chance(0.5) { f32::INFINITY } else { 1e37 }
}

/// A ray to `target` from a random origin `o` for which `accept((o − target)/|o − target|)`
/// holds (`None` if none is found quickly). `d = s·(target − o)` with a random length factor
/// `s`, so the target is at t = 1/s.
fn aim(
    rng: &mut Rng,
    target: [f32; 3],
    accept: impl Fn([f32; 3]) -> bool,
    origin: impl Fn(&mut Rng) -> [f32; 3],
) -> Option<Ray> {
    for _ in 0..1000 {
        let o = origin(rng);
        let to = sub(target, o);
        let l = len(to);
        if l < 1e-2 || !accept(scale(to, -1.0 / l)) {
            continue;
        }
        let s = rng.log(0.1, 10.0);
        let tf = unbounded(rng);
        return Some(ray(o, scale(to, s), tf, Some(1.0 / s)));
    }
    None
}

/// Accepts directions at least `min_cos` away from edge-on to the unit normal `n`.
fn not_edge_on(n: [f32; 3], min_cos: f32) -> impl Fn([f32; 3]) -> bool {
    move |u| dot(u, n).abs() >= min_cos
}

fn tri_normal(p: [[f32; 3]; 3]) -> [f32; 3] {
    normalize(cross(sub(p[1], p[0]), sub(p[2], p[0])))
}

fn make_rays(sc: &Scene, rng: &mut Rng) -> Vec<Ray> {
    let m = &sc.mesh;
    let mut rays: Vec<Ray> = Vec::new();
    let mut push = |kind: &'static str, r: Ray| rays.push(Ray { kind, ..r });

    // Random origins and directions (lengths 0.1 .. 10); a quarter with a finite tfar.
    for _ in 0..1000 {
        let o = rng.origin();
        let d = scale(rng.unit(), rng.log(0.1, 10.0));
        let tfar = if rng.chance(0.25) {
            rng.f(0.5, 6.0) / len(d)
        } else {
            unbounded(rng)
        };
        push("random", ray(o, d, tfar, None));
    }

    // Aimed at interior points (barycentrics ≥ 0.02) of random floor, box, sphere and random
    // triangles, at least 0.05 from edge-on. (Tiny and far triangles have their own kinds: at
    // these margins a ray could pass a tiny triangle's edge within rounding error.) A fifth get
    // a finite tfar at 0.3 .. 0.9 or 1.1 .. 1.6 times the target distance.
    assert!(sc.tiny.start < sc.far.start);
    for i in 0..2000 {
        let tri = m.tri(rng.below(sc.tiny.start));
        let (b1, b2) = loop {
            let (b1, b2) = (rng.f(0.02, 0.96), rng.f(0.02, 0.96));
            if b1 + b2 <= 0.98 {
                break (b1, b2);
            }
        };
        let Some(mut r) = aim(rng, bary(tri, b1, b2), not_edge_on(tri_normal(tri), 0.05), Rng::origin) else {
            continue;
        };
        if i % 5 == 0 {
            let tt = r.target_t.unwrap();
            r.tfar = tt
                * if rng.chance(0.5) {
                    rng.f(0.3, 0.9)
                } else {
                    rng.f(1.1, 1.6)
                };
        }
        push("aimed", r);
    }

    // Aimed near the centroids of tiny triangles (barycentrics ≥ 0.24), at most 60° from
    // their normal: at edge 1e-4 the ray then passes ≥ 1e-5 inside every edge, ten times the
    // rounding error of positions around 5.
    for _ in 0..400 {
        let tri = m.tri(sc.tiny.start + rng.below(sc.tiny.len()));
        let (b1, b2) = (rng.f(0.28, 0.38), rng.f(0.28, 0.38));
        let Some(r) = aim(rng, bary(tri, b1, b2), not_edge_on(tri_normal(tri), 0.5), Rng::origin) else {
            continue;
        };
        push("tiny", r);
    }

    // Aimed at the far triangles (t up to ~1e3) from around the scene.
    for _ in 0..200 {
        let tri = m.tri(sc.far.start + rng.below(sc.far.len()));
        let (b1, b2) = (rng.f(0.1, 0.8), rng.f(0.1, 0.8));
        let (b1, b2) = if b1 + b2 > 0.9 { (0.9 - b2, 0.9 - b1) } else { (b1, b2) };
        let Some(r) = aim(rng, bary(tri, b1, b2), not_edge_on(tri_normal(tri), 0.2), Rng::origin) else {
            continue;
        };
        push("far", r);
    }

    // Aimed exactly at shared edges: interior ones of the floor grid (from above or below, not
    // in its plane), and any of the closed box and sphere from a point in front of both faces
    // at the edge (so it is not on the silhouette and the ray enters the solid there).
    // Watertight traversal must report one of the two faces, at the same distance. (On a
    // silhouette the ray would only touch the solid: undecided.) Not at vertices: Embree's
    // robust test is consistent along each shared edge but not around a vertex, so a ray
    // through a vertex can slip between all the faces around it. Embree 3.13 and 4.4 then
    // agree, but no hit is guaranteed (RenderKit/embree#174, #181; it happened with other seeds).
    let on_floor_boundary = |p: [f32; 3]| p[0].abs() == HALF || p[1].abs() == HALF;
    let mut made = 0;
    while made < 500 {
        let (part, center) = match rng.below(3) {
            0 => (&sc.floor, None),
            1 => (&sc.boxx, Some([1.0f32, 1.0, 0.5])),
            _ => (&sc.sphere, Some(sc.sphere_center)),
        };
        let k = part.start + rng.below(part.len());
        let e = rng.below(3);
        let (i0, i1) = (m.t[k][e], m.t[k][(e + 1) % 3]);
        let (p0, p1) = (m.p[i0 as usize], m.p[i1 as usize]);
        let target = add(p0, scale(sub(p1, p0), rng.f(0.01, 0.99)));
        let r = match center {
            None => {
                if on_floor_boundary(p0) && on_floor_boundary(p1) {
                    continue; // on the open boundary: see "open-edge"
                }
                let origin = |rng: &mut Rng| {
                    let mut o = rng.origin();
                    if rng.chance(0.3) {
                        o[2] = -o[2].abs() - 0.2; // the floor from below
                    }
                    o
                };
                aim(rng, target, not_edge_on([0.0, 0.0, 1.0], 0.02), origin)
            }
            Some(cen) => {
                // Outward normals of the two faces at the edge (the part is convex).
                let normals: Vec<[f32; 3]> = part
                    .clone()
                    .filter(|&j| m.t[j].contains(&i0) && m.t[j].contains(&i1))
                    .map(|j| {
                        let p = m.tri(j);
                        let n = tri_normal(p);
                        if dot(n, sub(bary(p, 1.0 / 3.0, 1.0 / 3.0), cen)) < 0.0 {
                            scale(n, -1.0)
                        } else {
                            n
                        }
                    })
                    .collect();
                assert_eq!(normals.len(), 2, "a closed part has two faces at each edge");
                // In front of all (from outside) or behind all (from inside the solid).
                let accept = move |u: [f32; 3]| {
                    normals.iter().all(|&n| dot(u, n) > 0.05) || normals.iter().all(|&n| dot(u, n) < -0.05)
                };
                aim(rng, target, accept, Rng::origin)
            }
        };
        let Some(r) = r else { continue };
        push("shared-edge", r);
        made += 1;
    }

    // 1e-3 inside or outside the floor's open boundary, from above or below: inside must hit.
    for _ in 0..200 {
        let side = rng.below(4);
        let along = rng.f(-HALF + 0.01, HALF - 0.01);
        let inside = rng.chance(0.5);
        let off = if inside { -1e-3 } else { 1e-3 };
        let edge = HALF + off;
        let target = match side {
            0 => [edge, along, 0.0],
            1 => [-edge, along, 0.0],
            2 => [along, edge, 0.0],
            _ => [along, -edge, 0.0],
        };
        let Some(mut r) = aim(rng, target, not_edge_on([0.0, 0.0, 1.0], 0.05), |rng: &mut Rng| {
            let mut o = rng.origin();
            if rng.chance(0.3) {
                o[2] = -o[2].abs() - 0.2;
            }
            o
        }) else {
            continue;
        };
        if !inside {
            r.target_t = None;
        }
        push("open-edge", r);
    }

    // Grazing the floor at shallow angles: from height ±h (1e-4 .. 1e-1) down (or up) to it
    // over a horizontal distance l, landing at least 1e-3 inside or outside its boundary.
    let mut made = 0;
    while made < 300 {
        let h = rng.log(1e-4, 1e-1) * if rng.chance(0.7) { 1.0 } else { -1.0 };
        let l = rng.f(0.5, 5.0);
        let a = rng.f(0.0, std::f32::consts::TAU);
        let o = [rng.f(-2.9, 2.9), rng.f(-2.9, 2.9), h];
        let dir = [a.cos(), a.sin(), -h / l];
        let land = [o[0] + l * dir[0], o[1] + l * dir[1]];
        let margin = |x: f32| (x.abs() - HALF).abs();
        if margin(land[0]) < 1e-3 || margin(land[1]) < 1e-3 {
            continue;
        }
        let inside = land[0].abs() < HALF && land[1].abs() < HALF;
        let tf = unbounded(rng);
        push("graze-floor", ray(o, dir, tf, inside.then_some(l)));
        made += 1;
    }

    // Parallel to the floor, 1e-4 .. 1e-2 above it, random horizontal directions: the floor
    // is never hit (den = 0), the box's sides, random and tiny triangles may be.
    for _ in 0..200 {
        let h = rng.log(1e-4, 1e-2);
        let a = rng.f(0.0, std::f32::consts::TAU);
        let o = [rng.f(-3.5, 3.5), rng.f(-3.5, 3.5), h];
        let tf = unbounded(rng);
        push("parallel", ray(o, [a.cos(), a.sin(), 0.0], tf, None));
    }

    // Parallel to the floor, 1e-4 .. 1e-2 above it, aimed at a box side from outside at up to
    // 70° from its normal: must hit the side (just above its bottom edge).
    for _ in 0..300 {
        let h = rng.log(1e-4, 1e-2);
        let w = rng.f(0.55, 1.45);
        let (p, n) = match rng.below(4) {
            0 => ([0.5, w, h], [-1.0f32, 0.0]),
            1 => ([1.5, w, h], [1.0, 0.0]),
            2 => ([w, 0.5, h], [0.0, -1.0]),
            _ => ([w, 1.5, h], [0.0, 1.0]),
        };
        let a = n[1].atan2(n[0]) + rng.f(-1.2, 1.2); // outward, within ~70° of the normal
        let l = rng.f(0.3, 3.0);
        let o = [p[0] + l * a.cos(), p[1] + l * a.sin(), h];
        let s = rng.log(0.1, 10.0);
        let d = scale(sub(p, o), s);
        let tf = unbounded(rng);
        push("box-side", ray(o, d, tf, Some(1.0 / s)));
    }

    // Tangent to the ideal sphere at its tessellation vertices, shifted by 1e-3·r along the
    // radius. Inward: the line passes through an interior point of the (convex) tessellated
    // sphere and must hit it. Outward: the line is at least 1e-3·r from the ball, so it misses
    // the sphere (it may hit other things).
    for i in 0..400 {
        let v = m.p[sc.sphere_verts.start + rng.below(sc.sphere_verts.len())];
        let n = normalize(sub(v, sc.sphere_center));
        let (e1, e2) = frame(n);
        let a = rng.f(0.0, std::f32::consts::TAU);
        let t = add(scale(e1, a.cos()), scale(e2, a.sin()));
        let inward = i % 2 == 0;
        let shift = 1e-3 * sc.sphere_radius * if inward { -1.0 } else { 1.0 };
        let back = rng.f(1.0, 4.0);
        let o = add(add(v, scale(n, shift)), scale(t, -back));
        let tf = unbounded(rng);
        // Inward, the point v + shift·n (inside the sphere mesh) is at t = back.
        let r = ray(o, t, tf, inward.then_some(back));
        push(if inward { "tangent-in" } else { "tangent-out" }, r);
    }

    // Shuffle (so packets mix kinds) and trim to a multiple of 8.
    for i in (1..rays.len()).rev() {
        let j = rng.below(i + 1);
        rays.swap(i, j);
    }
    rays.truncate(rays.len() / 8 * 8);
    rays
}

// ---- embreex ------------------------------------------------------------------------------

fn write_npy<T: npyz::AutoSerialize + Copy>(path: &Path, shape: &[u64], data: &[T]) {
    let f = std::fs::File::create(path).unwrap_or_else(|e| panic!("creating {}: {e}", path.display()));
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
    npyz::NpyFile::new(&bytes[..])
        .and_then(|f| f.into_vec())
        .unwrap_or_else(|e| panic!("parsing {}: {e}", path.display()))
}

fn python() -> PathBuf {
    match std::env::var_os("DTR_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join(".venv/bin/python"),
    }
}

fn venv_help() -> String {
    format!(
        "this cross-check is required, not optional. Create the venv with\n  \
         cd {} && python3 -m venv .venv && .venv/bin/pip install embreex==4.4.0.post1 numpy\n\
         (Debian: apt-get install -y python3-venv first), or set DTR_PYTHON to a Python that has \
         embreex 4.4.0.post1 and numpy. `tools/test` creates the venv for you.",
        env!("CARGO_MANIFEST_DIR")
    )
}

struct Reference {
    t: Vec<f32>,
    prim: Vec<i32>,
    occluded: Vec<i32>,
}

fn run_embreex(mesh: &Mesh, rays: &[Ray]) -> Reference {
    let py = python();
    assert!(
        py.exists(),
        "the embreex cross-check needs Python at {}, which does not exist: {}",
        py.display(),
        venv_help()
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
        .unwrap_or_else(|e| panic!("cannot run {}: {e}; {}", py.display(), venv_help()));
    let stderr = String::from_utf8_lossy(&out.stderr);
    match out.status.code() {
        Some(0) => {}
        Some(3) => panic!(
            "{} cannot import embreex/numpy ({}): {}",
            py.display(),
            stderr.trim(),
            venv_help()
        ),
        _ => panic!(
            "{} {} failed ({}):\n{stderr}",
            py.display(),
            script.display(),
            out.status
        ),
    }
    eprintln!("reference: {}", String::from_utf8_lossy(&out.stdout).trim());
    let r = Reference {
        t: read_npy(&d.join("ref_t.npy")),
        prim: read_npy(&d.join("ref_prim.npy")),
        occluded: read_npy(&d.join("ref_occ.npy")),
    };
    assert_eq!(r.t.len(), rays.len());
    assert_eq!(r.prim.len(), rays.len());
    assert_eq!(r.occluded.len(), rays.len());
    r
}

fn same_distance(a: f32, b: f32) -> bool {
    (a - b).abs() <= REL_TOL * a.abs().max(b.abs())
}

fn setup() -> (Scene, Vec<Ray>, Accel) {
    let mut rng = Rng(0x5EED_2021);
    let scene = build_scene(&mut rng);
    let rays = make_rays(&scene, &mut rng);
    let device = Device::new("").unwrap();
    let accel = Accel::build(&device, &scene.mesh.p, &scene.mesh.t).unwrap();
    (scene, rays, accel)
}

fn packet(rays: &[Ray], tnear: impl Fn(usize) -> f32) -> Ray8 {
    let mut r8 = Ray8::default();
    for (l, ray) in rays.iter().enumerate() {
        r8.set(l, ray.o, ray.d, tnear(l), ray.tfar);
    }
    r8
}

fn show(h: Option<Hit>) -> String {
    match h {
        Some(h) => format!("hit t={:e} prim={}", h.t, h.prim),
        None => "miss".into(),
    }
}

// ---- The tests ----------------------------------------------------------------------------

#[test]
fn wrapper_agrees_with_embreex() {
    let (scene, rays, accel) = setup();
    let mesh = &scene.mesh;
    assert!((4800..=5600).contains(&rays.len()), "{} rays", rays.len());
    let r = run_embreex(mesh, &rays);
    let n = rays.len();

    let mut failures = Vec::new();
    let mut fail = |i: usize, what: String| failures.push(format!("ray {i} ({}): {what}", rays[i].kind));
    let mut other_prim = 0;
    let mut worst_rel = 0.0f32;
    for (i, ray) in rays.iter().enumerate() {
        let ref_hit = r.prim[i] >= 0;
        let ref_t = r.t[i];
        if ref_hit != (r.occluded[i] == 1) {
            fail(
                i,
                format!(
                    "embreex disagrees with itself: INTERSECT {ref_hit}, OCCLUDED {}",
                    r.occluded[i]
                ),
            );
        }
        // The geometric oracle, for both libraries.
        if let Some(tt) = ray.target_t.filter(|&tt| tt <= ray.tfar)
            && !(ref_hit && ref_t <= tt * (1.0 + REL_TOL))
        {
            fail(
                i,
                format!("embreex t={ref_t:e}, but the ray reaches its target at t={tt:e}"),
            );
        }
        let ours = accel.intersect1(ray.o, ray.d, 0.0, ray.tfar);
        match ours {
            Some(h) if ref_hit && same_distance(h.t, ref_t) => {
                worst_rel = worst_rel.max((h.t - ref_t).abs() / ref_t.abs().max(f32::MIN_POSITIVE));
                other_prim += (h.prim as i32 != r.prim[i]) as usize;
                if !(h.t >= 0.0 && h.t <= ray.tfar) {
                    fail(i, format!("intersect1 t={:e} outside [0, {:e}]", h.t, ray.tfar));
                }
            }
            None if !ref_hit => {}
            _ => fail(
                i,
                format!(
                    "intersect1 {}, embreex {}",
                    show(ours),
                    show(ref_hit.then_some(Hit {
                        t: ref_t,
                        prim: r.prim[i] as u32,
                        u: 0.0,
                        v: 0.0
                    }))
                ),
            ),
        }
        let occ = accel.occluded1(ray.o, ray.d, 0.0, ray.tfar);
        if occ != (r.occluded[i] == 1) {
            fail(i, format!("occluded1 {occ}, embreex OCCLUDED {}", r.occluded[i] == 1));
        }
    }

    // Packets of 8 consecutive (shuffled) rays, about a fifth of the lanes inactive, some
    // packets entirely inactive, alternating coherence hints.
    let mut rng = Rng(0x00BA_C4E7);
    let mut lanes_checked = 0;
    for (p, chunk) in rays.chunks(8).enumerate() {
        let r8 = packet(chunk, |_| 0.0);
        let active: [bool; 8] = match p % 50 {
            0 => [false; 8],
            1 => [true; 8],
            _ => std::array::from_fn(|_| !rng.chance(0.2)),
        };
        let coherent = p % 2 == 1;
        let h8 = accel.intersect8(&r8, active, coherent);
        let o8 = accel.occluded8(&r8, active, coherent);
        for l in 0..8 {
            let i = p * 8 + l;
            if !active[l] {
                if h8.get(l).is_some() || h8.t[l] != f32::INFINITY || o8[l] {
                    fail(
                        i,
                        format!("inactive lane {l}: intersect8 {}, occluded8 {}", show(h8.get(l)), o8[l]),
                    );
                }
                continue;
            }
            lanes_checked += 1;
            let ref_hit = r.prim[i] >= 0;
            let ok = match h8.get(l) {
                Some(h) => ref_hit && same_distance(h.t, r.t[i]),
                None => !ref_hit,
            };
            if !ok {
                fail(
                    i,
                    format!(
                        "intersect8 lane {l} (coherent {coherent}) {}, embreex t={:e}",
                        show(h8.get(l)),
                        r.t[i]
                    ),
                );
            }
            if o8[l] != (r.occluded[i] == 1) {
                fail(
                    i,
                    format!(
                        "occluded8 lane {l} (coherent {coherent}) {}, embreex {}",
                        o8[l], r.occluded[i]
                    ),
                );
            }
        }
    }

    let hits = r.prim.iter().filter(|&&p| p >= 0).count();
    eprintln!(
        "{n} rays ({} triangles), {hits} hits in embreex; {lanes_checked} active packet lanes; {} disagreements; \
         {other_prim} hits on another triangle at the same distance; worst relative distance difference {worst_rel:e}",
        mesh.t.len(),
        failures.len()
    );
    for kind in KINDS {
        let k: Vec<usize> = (0..n).filter(|&i| rays[i].kind == kind).collect();
        let h = k.iter().filter(|&&i| r.prim[i] >= 0).count();
        eprintln!("  {kind:12} {:5} rays {h:5} hits", k.len());
        assert!(!k.is_empty(), "no {kind} rays");
    }
    assert!(
        failures.is_empty(),
        "{} disagreements with embreex (first 40):\n{}",
        failures.len(),
        failures[..failures.len().min(40)].join("\n")
    );
    assert!(
        hits > n / 3 && hits < n - n / 10,
        "a meaningful mix of hits and misses: {hits} of {n}"
    );
}

/// `intersect8`/`occluded8` against `intersect1`/`occluded1`, lane by lane, for `tnear = 0`
/// and for `tnear` before or just past the first hit, with inactive lanes.
///
/// - Incoherent packets must match bit for bit (t, prim, u, v): in incoherent mode Embree
///   3.13's hybrid packet intersector traces each active lane with a single-ray traversal
///   (`BVHNIntersectorKHybrid::intersect`, `single = true`).
/// - Coherent packets use a frustum traversal with one node order for the whole packet. Where
///   two triangles are hit at the same point (a shared edge, the box bottom on the floor),
///   whichever is found first wins, so prim, u and v may differ from `intersect1`, and t by
///   the last bit (the two planes give slightly different t at their common edge). Such a tie
///   must be the same surface point, t within 1e-6 relative; hit/miss and occlusion must match
///   exactly. About 1% of the hits are such ties; they are counted and reported.
#[test]
fn packets_match_single_rays() {
    let (scene, rays, accel) = setup();
    let mesh = &scene.mesh;
    let point = |h: Hit| {
        let p = mesh.tri(h.prim as usize);
        bary(p, h.u, h.v)
    };
    let mut rng = Rng(0x0008_8888);
    let mut failures = Vec::new();
    let (mut lanes, mut hits, mut ties) = (0, 0, 0);
    for (p, chunk) in rays.chunks(8).enumerate() {
        // tnear: 0; or half the first hit's distance (so the same hit); or just past the first
        // hit (so the next surface along the ray, if any; past tfar makes the ray invalid).
        let first: Vec<Option<f32>> = chunk
            .iter()
            .map(|r| accel.intersect1(r.o, r.d, 0.0, r.tfar).map(|h| h.t))
            .collect();
        let choice: Vec<usize> = (0..8).map(|_| rng.below(3)).collect();
        let tnear = |l: usize| match (p % 2, choice[l], first[l]) {
            (0, _, _) | (_, _, None) | (_, 0, _) => 0.0,
            (_, 1, Some(t)) => t * 0.5,
            (_, _, Some(t)) => t * 1.001,
        };
        let r8 = packet(chunk, tnear);
        let active: [bool; 8] = match p % 40 {
            0 => [false; 8],
            1 => [true; 8],
            _ => std::array::from_fn(|_| !rng.chance(0.25)),
        };
        for coherent in [false, true] {
            let h8 = accel.intersect8(&r8, active, coherent);
            let o8 = accel.occluded8(&r8, active, coherent);
            for (l, ray) in chunk.iter().enumerate() {
                let i = p * 8 + l;
                let tn = tnear(l);
                let (want, want_occ) = if active[l] {
                    lanes += 1;
                    (
                        accel.intersect1(ray.o, ray.d, tn, ray.tfar),
                        accel.occluded1(ray.o, ray.d, tn, ray.tfar),
                    )
                } else {
                    (None, false)
                };
                hits += want.is_some() as usize;
                let got = h8.get(l);
                let tie = coherent
                    && match (got, want) {
                        (Some(a), Some(b)) => {
                            let (pa, pb) = (point(a), point(b));
                            (a.t - b.t).abs() <= 1e-6 * a.t.max(b.t)
                                && a.prim != b.prim
                                && len(sub(pa, pb)) <= 1e-5 * (1.0 + len(pa))
                        }
                        _ => false,
                    };
                ties += tie as usize;
                let consistent = want.is_some() || (h8.t[l] == f32::INFINITY && h8.prim[l] == u32::MAX);
                if (got != want && !tie) || o8[l] != want_occ || !consistent {
                    failures.push(format!(
                        "ray {i} ({}) lane {l} active {} coherent {coherent} tnear {tn:e}: intersect8 {got:?} vs \
                         intersect1 {want:?}; occluded8 {} vs occluded1 {want_occ}",
                        ray.kind, active[l], o8[l]
                    ));
                }
                if let Some(h) = want
                    && !(h.t >= tn && h.t <= ray.tfar)
                {
                    failures.push(format!(
                        "ray {i}: intersect1 t={:e} outside [{tn:e}, {:e}]",
                        h.t, ray.tfar
                    ));
                }
            }
        }
    }
    eprintln!(
        "{lanes} active lanes (both coherence hints), {hits} hits, {ties} coherent-packet ties reported on another \
         triangle at the same t and point, {} mismatches",
        failures.len()
    );
    assert!(
        failures.is_empty(),
        "{} packet lanes differ from single rays (first 40):\n{}",
        failures.len(),
        failures[..failures.len().min(40)].join("\n")
    );
}
