//! χ² test of next-event emitter sampling (`EmitterTable::sample`) against the densities it
//! reports and the one the path tracer's MIS uses when a BSDF ray hits an emitter
//! (`EmitterTable::area_pdf`).

use super::RenderContext;
use super::testutil::{assert_chi2, load};
use crate::accel::Device;
use crate::kernel::{Mask, PathSampler, Real, f32x8};
use crate::scene::testutil::header;
use crate::scene::{EmitterKind, Scene};
use glam::DVec3;

/// Two area emitters of unequal triangles (a squashed, rotated icosphere: 80 triangles of
/// different areas; a stretched quad), a point light between them in the emitter list, and a
/// shape that emits nothing.
const LIGHTS: &str = concat!(
    header!(),
    r#"
[[shape]]
name = "bulb"
type = "sphere"
subdivisions = 1
material = "white"
translate = [0.0, 1.0, 0.0]
rotate = [10.0, 20.0, 30.0]
scale = [0.5, 0.3, 0.8]

[[shape]]
name = "panel"
type = "rectangle"
material = "white"
translate = [0.0, -1.0, 0.0]
rotate = [90.0, 0.0, 0.0]
scale = [1.5, 0.4, 1.0]

[[shape]]
name = "floor"
type = "rectangle"
material = "white"
translate = [0.0, -2.0, 0.0]
rotate = [-90.0, 0.0, 0.0]
scale = 3.0

[[emitter]]
name = "bulb_light"
type = "area"
shape = "bulb"
radiance = [2.0, 3.0, 4.0]

[[emitter]]
name = "lamp"
type = "point"
position = [0.0, 0.0, 2.0]
intensity = [1.0, 0.5, 0.25]

[[emitter]]
name = "panel_light"
type = "area"
shape = "panel"
radiance = [1.5, 1.5, 1.5]
"#
);

/// Each triangle is cut into N² congruent cells of area A/N² (rows of the (u, v) grid split
/// along their diagonals).
const N: usize = 3;

/// Barycentrics (u, v) of `p` in triangle `tri` (p = a + u·(b − a) + v·(c − a)) and its
/// distance from the triangle's plane, in f64.
fn barycentrics(tri: [DVec3; 3], p: DVec3) -> (f64, f64, f64) {
    let (e1, e2, q) = (tri[1] - tri[0], tri[2] - tri[0], p - tri[0]);
    let (a, b, c) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (r1, r2) = (q.dot(e1), q.dot(e2));
    let det = a * c - b * b;
    let (u, v) = ((c * r1 - b * r2) / det, (a * r2 - b * r1) / det);
    (u, v, (q - e1 * u - e2 * v).length())
}

/// Index and barycentrics (u, v) of the triangle of `tris` that holds `p`: in its plane and
/// inside it (within 10⁻⁵), the most interior one where triangles share an edge. Panics,
/// naming `what`, when none does.
fn triangle_holding(tris: impl Iterator<Item = [DVec3; 3]>, p: DVec3, what: &str) -> (usize, f64, f64) {
    let (k, (u, v, dist)) = tris
        .enumerate()
        .map(|(k, t)| (k, barycentrics(t, p)))
        .filter(|(_, b)| b.2 < 1e-5)
        .max_by(|a, b| {
            let m = |b: &(f64, f64, f64)| b.0.min(b.1).min(1.0 - b.0 - b.1);
            m(&a.1).total_cmp(&m(&b.1))
        })
        .unwrap_or_else(|| panic!("{what}: sample {p} on no triangle of its shape"));
    assert!(
        u.min(v).min(1.0 - u - v) > -1e-5 && dist < 1e-5,
        "{what}: {p}: ({u}, {v}), {dist}"
    );
    (k, u, v)
}

/// The cell (of 2N² slots, N² of them real) holding barycentrics (u, v).
fn cell(u: f64, v: f64) -> usize {
    let n = N as f64;
    let (i, j) = ((u * n).floor().clamp(0.0, n - 1.0), (v * n).floor().clamp(0.0, n - 1.0));
    let (i, mut j) = (i as usize, j as usize);
    // the upper cell of a square exists below the diagonal only; points on the triangle's
    // outer edge round into the lower one
    let upper = (u * n - i as f64) + (v * n - j as f64) >= 1.0 && i + j + 2 <= N;
    j = j.min(N - 1 - i);
    (upper as usize * N + i) * N + j
}

/// Whether slot `s` of [`cell`] is a real cell.
fn is_cell(s: usize) -> bool {
    let (upper, i, j) = (s / (N * N), s / N % N, s % N);
    i + j + upper < N
}

fn triangle(scene: &Scene, t: usize) -> [DVec3; 3] {
    scene.geometry.indices[t].map(|i| scene.geometry.positions[i as usize].as_dvec3())
}

/// The index of the area emitter called `name` and the triangles of the shape it covers.
fn area_emitter(scene: &Scene, name: &str) -> (usize, Vec<[DVec3; 3]>) {
    let e = scene.emitters.iter().position(|e| e.name == name).unwrap();
    let EmitterKind::Area { shape, .. } = scene.emitters[e].kind else {
        panic!("{name} is not an area emitter")
    };
    let s = &scene.shapes[shape as usize];
    let tris = (0..s.tri_count as usize)
        .map(|k| triangle(scene, s.first_tri as usize + k))
        .collect();
    (e, tris)
}

/// 800 000 samples of `EmitterTable::sample` (8-wide, as the renderer calls it), counted per
/// emitter, per triangle of an area emitter and per cell of the triangle, against the
/// probability the sampler reports: pdf_area (with emitter selection) × the cell's area for
/// area emitters, I / weight for the point light. Pearson's χ² over the 739 cells must have
/// p > 10⁻⁴ (fixed seed). Also: the reported densities integrate to 1 over all emitters,
/// pdf_area is the one the MIS of an emitter hit uses, and weight = L_e/pdf_area.
///
/// Bugs caught: triangles picked by index instead of area (or a CDF off by one), points not
/// uniform on a triangle (u₁ without the square root), a selection probability that is not
/// the one reported, pdfs of next-event and BSDF-hit MIS that differ, and a weight that does
/// not divide by the reported pdf.
#[test]
fn emitter_samples_follow_the_reported_densities() {
    let scene = load(LIGHTS, &[]);
    let device = Device::new("").unwrap();
    let ctx = RenderContext::new(&scene, &device).unwrap();
    let n_e = scene.emitters.len();
    // cells: one per point light, 2N² slots per area-emitter triangle
    let mut offset = vec![0usize; n_e + 1];
    for (e, em) in scene.emitters.iter().enumerate() {
        offset[e + 1] = offset[e]
            + match em.kind {
                EmitterKind::Area { shape, .. } => scene.shapes[shape as usize].tri_count as usize * 2 * N * N,
                _ => 1,
            };
    }
    let mut observed = vec![0u64; offset[n_e]];
    let mut reported = vec![None::<f32>; n_e];
    let packets = 100_000u64;
    let mut sampler = PathSampler::new(0x5eed, &[0, 1, 2, 3, 4, 5, 6, 7]);
    for _ in 0..packets {
        let (u0, u1) = sampler.next2::<f32x8>();
        let u2 = sampler.next::<f32x8>();
        let ls = ctx.emitters.sample::<f32x8, 3>(&ctx, u0, u1, u2, Mask::splat(true));
        for i in 0..8 {
            assert!(ls.valid.bit(i));
            let e = ls.emitter[i] as usize;
            let p = ls.p.lane(i);
            let pdf = ls.pdf_area.lane(i);
            let weight: [f32; 3] = std::array::from_fn(|c| ls.weight.0[c].lane(i));
            match scene.emitters[e].kind {
                EmitterKind::Point { position, intensity } => {
                    assert_eq!((p, pdf), (position, 0.0), "point light sample");
                    // the selection probability the weight divides by
                    let p_sel = intensity[0] / weight[0];
                    for c in 0..3 {
                        assert!((intensity[c] / weight[c] - p_sel).abs() <= 1e-6 * p_sel);
                    }
                    assert_eq!(*reported[e].get_or_insert(p_sel), p_sel);
                    observed[offset[e]] += 1;
                }
                EmitterKind::Area { shape, radiance } => {
                    assert_eq!(*reported[e].get_or_insert(pdf), pdf, "emitter {e}: pdf varies");
                    assert_eq!(
                        pdf,
                        ctx.emitters.area_pdf(e as u32),
                        "emitter {e}: next-event vs hit pdf"
                    );
                    for c in 0..3 {
                        let w = radiance[c] / pdf;
                        assert!((weight[c] - w).abs() <= 1e-6 * w, "emitter {e}: weight {weight:?}");
                    }
                    let s = &scene.shapes[shape as usize];
                    let (k, u, v) = triangle_holding(
                        (0..s.tri_count as usize).map(|k| triangle(&scene, s.first_tri as usize + k)),
                        p.as_dvec3(),
                        &format!("emitter {e}"),
                    );
                    observed[offset[e] + k * 2 * N * N + cell(u, v)] += 1;
                }
                _ => unreachable!(),
            }
        }
    }
    // the probability of every cell as reported, and their sum
    let mut probability = vec![0.0f64; observed.len()];
    for (e, em) in scene.emitters.iter().enumerate() {
        let r = reported[e].expect("every emitter sampled") as f64;
        match em.kind {
            EmitterKind::Area { shape, .. } => {
                let s = &scene.shapes[shape as usize];
                for k in 0..s.tri_count as usize {
                    let [a, b, c] = triangle(&scene, s.first_tri as usize + k);
                    let area = 0.5 * (b - a).cross(c - a).length();
                    for slot in 0..2 * N * N {
                        if is_cell(slot) {
                            probability[offset[e] + k * 2 * N * N + slot] = r * area / (N * N) as f64;
                        }
                    }
                }
            }
            _ => probability[offset[e]] = r,
        }
    }
    // f32 densities and areas: a few ulps each
    assert_chi2("emitters", &observed, &probability, 1e-5);
}

/// A pixel's Sobol pairs stay stratified over a whole area emitter of several triangles: the
/// pair's first number picks the triangle by area and is rescaled within it
/// (`EmitterTable::sample`). 256 samples of one pixel on the panel (two triangles of equal
/// area; the panel the scene's only emitter) put exactly 128 points on each triangle, and on
/// each triangle exactly 8 in each of 16 equal-probability bands of the rescaled number
/// (u = (b₁ + b₂)², b the barycentrics), at several seeds. Caught: the triangle picked by a
/// number outside the pair (the emitter choice's remainder), which splits the points between
/// the triangles at random.
#[test]
fn a_pixels_points_are_stratified_over_the_whole_emitter() {
    let scene = load(&only_emitter(LIGHTS, "panel_light"), &[]);
    let device = Device::new("").unwrap();
    let ctx = RenderContext::new(&scene, &device).unwrap();
    let (panel, tris) = area_emitter(&scene, "panel_light");
    assert_eq!(tris.len(), 2);
    let areas: Vec<f64> = tris
        .iter()
        .map(|[a, b, c]| 0.5 * (*b - *a).cross(*c - *a).length())
        .collect();
    assert!((areas[0] / areas[1] - 1.0).abs() < 1e-5);
    for seed in [1u64, 7, 42] {
        let mut bands = [[0u32; 16]; 2];
        for (_, _, ls, i) in pixel_samples(&ctx, seed, 256) {
            assert_eq!(ls.emitter[i] as usize, panel);
            let p = ls.p.lane(i).as_dvec3();
            let (k, b1, b2) = triangle_holding(tris.iter().copied(), p, "the panel");
            let u = (b1 + b2).powi(2);
            bands[k][((u * 16.0) as usize).min(15)] += 1;
        }
        for (k, b) in bands.iter().enumerate() {
            assert_eq!(b.iter().sum::<u32>(), 128, "seed {seed}, triangle {k}: {b:?}");
            // f32 rounding may move a point sitting on a band's edge into its neighbour
            assert!(
                b.iter().all(|&n| (7..=9).contains(&n)),
                "seed {seed}, triangle {k}: {b:?}"
            );
        }
    }
}

/// The `spp` samples of pixel 5 of `seed` (Sobol points), each with its pair (u₀, u₁), the
/// emitter sample it gave (with an emitter-choice number drawn after the pair) and its lane.
fn pixel_samples(
    ctx: &RenderContext,
    seed: u64,
    spp: u64,
) -> Vec<(f32, f32, super::emitters::LightSample<f32x8, 3>, usize)> {
    use crate::kernel::SampleSequence;
    let mut out = Vec::new();
    for packet in 0..spp / 8 {
        let ids: Vec<u64> = (0..8).map(|i| 5 * spp + packet * 8 + i).collect();
        let mut sampler = PathSampler::with_sequence(SampleSequence::Sobol, seed, &ids, spp as u32);
        let (u0, u1) = sampler.next2::<f32x8>();
        let select = sampler.next::<f32x8>();
        let ls = ctx.emitters.sample::<f32x8, 3>(ctx, select, u0, u1, Mask::splat(true));
        out.extend((0..8).map(|i| (u0.lane(i), u1.lane(i), ls, i)));
    }
    out
}

/// With several emitters, a pixel's Sobol pairs choose the emitter with the pair's first
/// number, rescaled within the emitter's share (`EmitterTable::sample`), so each emitter gets
/// a stratified part of the pixel's points, not a random one: of 256 samples each of
/// [`LIGHTS`]' three emitters gets 84 to 86 (a third of the first number's 256 one-point
/// intervals, give or take the two its share cuts), and in each of 16 bands of the pair's
/// second number 4 to 6 (likewise of the band's 16 one-point cells).
/// Caught: the emitter chosen by a number apart from the pair, which split the points at
/// random (an independent sweep measured the boundary stage's variance of a two-light scene
/// at ~100× its lights' alone, where Sobol points then gained nothing).
#[test]
fn a_pixels_points_are_stratified_over_the_emitters() {
    let scene = load(LIGHTS, &[]);
    let device = Device::new("").unwrap();
    let ctx = RenderContext::new(&scene, &device).unwrap();
    let n_e = scene.emitters.len();
    assert_eq!(n_e, 3);
    for seed in [1u64, 7, 42] {
        let mut counts = vec![[0u32; 16]; n_e];
        for (_, u1, ls, i) in pixel_samples(&ctx, seed, 256) {
            counts[ls.emitter[i] as usize][((u1 * 16.0) as usize).min(15)] += 1;
        }
        for (e, c) in counts.iter().enumerate() {
            let total: u32 = c.iter().sum();
            assert!((84..=86).contains(&total), "seed {seed}, emitter {e}: {total} of 256");
            assert!(
                c.iter().all(|&n| (4..=6).contains(&n)),
                "seed {seed}, emitter {e}: {c:?}"
            );
        }
    }
}

/// An area emitter of more than [`super::emitters::REUSE_MAX_TRIANGLES`] triangles picks its
/// triangle with the remainder of the emitter's selection number, not with the point's first
/// number (`EmitterTable::sample`). [`LIGHTS`] with the bulb subdivided to 1280 triangles of
/// unequal areas: 400 000 samples counted per bulb triangle, per cell of the triangle summed
/// over each of 8 groups of the bulb's triangles (in index order, the CDF's order), and per
/// other emitter, against the reported densities (Pearson's χ², p > 10⁻⁴, fixed seed).
///
/// Bugs caught: triangles of a large mesh picked by index rather than area, a remainder
/// taken from the wrong emitter's share (which skews the choice towards one end of the CDF),
/// and a point within the triangle that depends on which triangle was picked.
#[test]
fn a_large_emitter_mesh_picks_its_triangles_by_area() {
    let text = LIGHTS.replace("subdivisions = 1", "subdivisions = 3");
    let scene = load(&text, &[]);
    let device = Device::new("").unwrap();
    let ctx = RenderContext::new(&scene, &device).unwrap();
    let (bulb, tris) = area_emitter(&scene, "bulb_light");
    let n_t = tris.len();
    assert!(n_t > super::emitters::REUSE_MAX_TRIANGLES, "{n_t} triangles");
    let areas: Vec<f64> = tris
        .iter()
        .map(|[a, b, c]| 0.5 * (*b - *a).cross(*c - *a).length())
        .collect();
    let (lo, hi) = areas.iter().fold((f64::MAX, 0.0f64), |(l, h), &a| (l.min(a), h.max(a)));
    assert!(hi > 1.5 * lo, "the bulb's triangles differ in area ({lo} to {hi})");
    let n_e = scene.emitters.len();
    // cells: the bulb's triangles, then 2N² cell slots per group of triangles, then one per
    // other emitter
    const GROUPS: usize = 8;
    let group = |k: usize| k * GROUPS / n_t;
    let others = n_t + GROUPS * 2 * N * N;
    let cells = others + n_e;
    let mut observed = vec![0u64; cells];
    let mut reported = None::<f32>;
    let mut sampler = PathSampler::new(0xB16_5EED, &[0, 1, 2, 3, 4, 5, 6, 7]);
    for _ in 0..50_000 {
        let (u0, u1) = sampler.next2::<f32x8>();
        let u2 = sampler.next::<f32x8>();
        let ls = ctx.emitters.sample::<f32x8, 3>(&ctx, u0, u1, u2, Mask::splat(true));
        for i in 0..8 {
            assert!(ls.valid.bit(i));
            let e = ls.emitter[i] as usize;
            if e != bulb {
                observed[others + e] += 1;
                continue;
            }
            let pdf = ls.pdf_area.lane(i);
            assert_eq!(*reported.get_or_insert(pdf), pdf, "the bulb's pdf varies");
            let p = ls.p.lane(i).as_dvec3();
            let (k, u, v) = triangle_holding(tris.iter().copied(), p, "the bulb");
            observed[k] += 1;
            observed[n_t + group(k) * 2 * N * N + cell(u, v)] += 1;
        }
    }
    // each bulb sample is counted twice (its triangle, its group's cell), so each half holds
    // the bulb's share; the other emitters' cells hold how often they came up
    let bulb_share = reported.expect("the bulb was sampled") as f64 * areas.iter().sum::<f64>();
    assert!(
        (bulb_share - 1.0 / n_e as f64).abs() < 1e-5,
        "bulb chosen with {bulb_share}"
    );
    let samples = observed.iter().sum::<u64>() as f64;
    let bulb_samples = observed[..n_t].iter().sum::<u64>() as f64;
    let mut probability = vec![0.0f64; cells];
    for k in 0..n_t {
        probability[k] = bulb_samples / samples * areas[k] / areas.iter().sum::<f64>();
    }
    for k in 0..n_t {
        for slot in (0..2 * N * N).filter(|&slot| is_cell(slot)) {
            probability[n_t + group(k) * 2 * N * N + slot] += probability[k] / (N * N) as f64;
        }
    }
    for e in (0..n_e).filter(|&e| e != bulb) {
        probability[others + e] = observed[others + e] as f64 / samples;
    }
    assert_chi2("a large emitter mesh", &observed, &probability, 1e-9);
}

/// `LIGHTS` with only the emitter called `name` (its shapes all kept).
fn only_emitter(text: &str, name: &str) -> String {
    let mut parts = text.split("[[emitter]]");
    let head = parts.next().unwrap().to_string();
    let kept: Vec<&str> = parts.filter(|p| p.contains(&format!("name = \"{name}\""))).collect();
    assert_eq!(kept.len(), 1, "{name}");
    head + "[[emitter]]" + kept[0]
}

/// `reads_select` says whether the emitter-choice number matters, which is what lets the
/// path tracer and BDPT skip computing it: with one emitter of few triangles the samples are
/// the same whatever that number, and where it picks an emitter or a large mesh's triangle
/// the table says it is read (and it does change the samples).
#[test]
fn the_select_number_is_read_only_where_it_picks() {
    let device = Device::new("").unwrap();
    // several emitters of few triangles are chosen by the point's number (`by_point`); one
    // emitter of 1280 triangles among three is not, nor is such a mesh alone
    let large = LIGHTS.replace("subdivisions = 1", "subdivisions = 3");
    let cases = [
        (LIGHTS.to_string(), false),
        (only_emitter(LIGHTS, "panel_light"), false),
        (large.clone(), true),
        (only_emitter(&large, "bulb_light"), true),
    ];
    for (text, reads) in cases {
        let scene = load(&text, &[]);
        let ctx = RenderContext::new(&scene, &device).unwrap();
        assert_eq!(
            ctx.emitters.reads_select(),
            reads,
            "{} emitter(s)",
            scene.emitters.len()
        );
        let mut sampler = PathSampler::new(0x5E1EC7, &[0, 1, 2, 3, 4, 5, 6, 7]);
        let mut changed = false;
        for _ in 0..64 {
            let (u0, u1) = sampler.next2::<f32x8>();
            let select = sampler.next::<f32x8>();
            let a = ctx.emitters.sample::<f32x8, 3>(&ctx, select, u0, u1, Mask::splat(true));
            let b = ctx
                .emitters
                .sample::<f32x8, 3>(&ctx, f32x8::ZERO, u0, u1, Mask::splat(true));
            for i in 0..8 {
                let same = a.emitter[i] == b.emitter[i] && a.p.lane(i) == b.p.lane(i);
                assert!(reads || same, "lane {i}: a number that is not read changed the sample");
                changed |= !same;
            }
        }
        assert_eq!(changed, reads, "whether the number changed any sample");
    }
}

/// A laser that meets a one-sided material from behind lights nothing (its spot is black, as
/// the material is there); from the front, or on a two-sided material, it lights its spot.
#[test]
fn a_laser_on_the_back_of_a_one_sided_material_lights_nothing() {
    let device = Device::new("").unwrap();
    let spot = |one_sided: bool, z: f32| {
        let text = format!(
            "{}\n[[material]]\nname = \"front\"\ntype = \"diffuse\"\nalbedo = 0.5\none_sided = {one_sided}\n\
             [[shape]]\nname = \"wall\"\ntype = \"rectangle\"\nmaterial = \"front\"\n\
             [[emitter]]\nname = \"beam\"\ntype = \"laser\"\nposition = [0.0, 0.0, {z}]\ndirection = [0.0, 0.0, {}]\npower = 1.0\n",
            header!(),
            -z
        );
        let scene = load(&text, &[]);
        let ctx = RenderContext::new(&scene, &device).unwrap();
        ctx.emitters.laser_spot(0).is_some()
    };
    // the rectangle faces +z
    assert!(spot(true, 1.0), "from the front");
    assert!(!spot(true, -1.0), "from behind");
    assert!(spot(false, -1.0), "two-sided, from behind");
}
