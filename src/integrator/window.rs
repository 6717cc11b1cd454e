//! The time-window cut: no path is traced past the last optical path length that can still
//! reach a bin of the film.
//!
//! A path of OPL d adds f·S_e(l, d) to bin l (supplemental Eq. 24), and S_e(l, ·) is zero
//! beyond the window's end plus the pulse's and gate's reach
//! ([`crate::temporal::Correlation::last_opl`]). OPL only grows along a path, so once a
//! subpath's OPL passes that bound nothing it leads to can land in the transient, nor can its
//! derivative (∂S_e/∂d is zero there too). The estimators therefore
//! - bound each ray's t_far by the OPL left, η·t ≤ budget − d, so Embree culls farther hits
//!   and the path ends where it would have left the window;
//! - skip next-event and BDPT connections whose OPL lands past the budget, before their
//!   shadow ray;
//! - end a path at a vertex from which no end is near enough ([`EndBox`]): whatever
//!   follows a path tracer's or BDPT camera subpath's vertex ends on an emitter, a BDPT
//!   light subpath's or boundary sensor walk's (`super::importance`) at the pinhole, so it
//!   adds at least η_min times the distance to the nearest such point (the triangle
//!   inequality), plus what every end adds after its point (a laser's leg to its spot) and
//!   what every connection of the path adds (an NLOS capture's leg from the sensor point to
//!   the SPAD, where they count); when even that passes the budget, no connection from the
//!   vertex or later bounce can land.
//!
//! Paths are sampled with counter-based random numbers (`kernel::PathSampler`), so ending one
//! lane early changes no other lane: the transient and its derivatives are the same bytes as
//! without the cut (tests/window_cut.rs), with fewer rays. What the cut does change is the
//! time-summed (steady) image, which then integrates the window ([`crate::film::SteadyMode`]);
//! `--steady full` turns the cut off.

use crate::kernel::{Mask, Real, V3};
use crate::scene::{EmitterKind, Material, Scene};
use crate::temporal::Correlation;
use glam::Vec3;

/// Relative slack added to the bound: the kernel's f32 OPL and the f64 OPL the film bins
/// may differ by a few f32 ulps per segment (about 10⁻⁶ relative over a long path); 2⁻¹⁰ is
/// far more than that, so the cut never drops a path that could reach a bin.
const SLACK: f64 = 1.0 / 1024.0;

/// The largest OPL any emitter's paths can have and still touch a bin, with slack, in the
/// kernel's f32; `None` when there is no emitter (nothing to bound).
pub fn opl_budget(correlations: &[Correlation]) -> Option<f32> {
    let last = correlations
        .iter()
        .map(Correlation::last_opl)
        .fold(f64::NEG_INFINITY, f64::max);
    last.is_finite().then(|| (last + SLACK * last.abs().max(1.0)) as f32)
}

/// The ray parameter beyond which a segment leaving a subpath of OPL `opl` through a medium
/// of index `eta` cannot end in the window: (budget − opl) / η, or +∞ without a budget. It is
/// ≤ 0 for lanes already past the budget.
#[inline(always)]
pub fn t_far<V: Real>(budget: Option<f32>, opl: V, eta: V) -> V {
    match budget {
        Some(b) => V::safe_div(V::splat(b) - opl, eta),
        None => V::splat(f32::INFINITY),
    }
}

/// Lanes whose OPL `d` is still within the budget (all lanes without one).
#[inline(always)]
pub fn within<V: Real>(budget: Option<f32>, d: V) -> V::Mask {
    match budget {
        Some(b) => d.le(V::splat(b)),
        None => V::Mask::from_bools(&[true; 8][..V::LANES]),
    }
}

/// A box around every point a subpath can end on, the smallest refractive index of the scene,
/// and the least length an end adds after its point. For camera subpaths the ends are the
/// emitters (the area emitters' triangles, the point lights, the laser spots, an NLOS scan's
/// included) and the length is a laser's leg to its spot where the time of flight counts it;
/// for light subpaths and sensor walks the end is the pinhole ([`EndBox::point`]). From a
/// vertex at distance r from the box, any continuation has an OPL of at least η_min·(r + tail)
/// (a path is at least as long as the straight line, and each of its segments, the laser's
/// leg included, is weighted by an index ≥ η_min).
#[derive(Clone, Copy, Debug)]
pub struct EndBox {
    lo: Vec3,
    hi: Vec3,
    eta_min: f32,
    tail: f32,
}

impl EndBox {
    /// The box of `scene`'s emitter points; `spots` are the points laser beams land on (the
    /// scene's lasers and an NLOS scan's laser points), each with the OPL its beam adds to a
    /// path that ends there (the laser-to-spot length, or 0 where it is left out). A spot is
    /// a point, not its triangle: where geometry moves, the spot moves along the fixed beam
    /// (ray form), and the primal path, which alone is cut, ends at the spot found here.
    /// `None` when there is no such point: then no path reaches an emitter, and nothing is
    /// bounded.
    pub fn new(scene: &Scene, spots: impl IntoIterator<Item = (Vec3, f32)>) -> Option<Self> {
        let geo = &scene.geometry;
        let tri = |t: u32| geo.indices[t as usize].map(|i| geo.positions[i as usize]);
        let mut points: Vec<(Vec3, f32)> = spots.into_iter().collect();
        for e in &scene.emitters {
            match &e.kind {
                EmitterKind::Area { shape, .. } => {
                    let s = &scene.shapes[*shape as usize];
                    points.extend((s.first_tri..s.first_tri + s.tri_count).flat_map(tri).map(|p| (p, 0.0)));
                }
                EmitterKind::Point { position, .. } => points.push((*position, 0.0)),
                // the spot it lights is among `spots`
                EmitterKind::Laser { .. } => {}
            }
        }
        Self::around(scene, points)
    }

    /// The box of `points`, each with the OPL a path that ends there still adds (its tail);
    /// `None` without points. An NLOS capture's light subpaths end at its sensor points, with
    /// the wall's leg to the SPAD where the capture counts it.
    pub fn around(scene: &Scene, points: impl IntoIterator<Item = (Vec3, f32)>) -> Option<Self> {
        let mut points = points.into_iter();
        let (first, t0) = points.next()?;
        let (lo, hi, tail) = points.fold((first, first, t0), |(lo, hi, tail), (p, t)| {
            (lo.min(p), hi.max(p), tail.min(t))
        });
        let eta_min = least_index(scene);
        let finite = lo.is_finite() && hi.is_finite() && tail.is_finite() && tail >= 0.0;
        (finite && eta_min > 0.0).then_some(Self { lo, hi, eta_min, tail })
    }

    /// One point as the box: the pinhole, where every path of a light subpath ends.
    pub fn point(scene: &Scene, p: Vec3) -> Self {
        Self {
            lo: p,
            hi: p,
            eta_min: least_index(scene),
            tail: 0.0,
        }
    }

    /// Lanes at `p` with OPL `opl` from which an emitter may still be reached within the
    /// budget (all lanes without one): opl + η_min·(dist(p, box) + tail) ≤ budget. The least
    /// OPL is taken a hair short (its f32 rounding is far below the budget's slack), so that
    /// no path that could land is ended.
    #[inline(always)]
    pub fn reachable<V: Real>(&self, budget: Option<f32>, opl: V, p: &V3<V>) -> V::Mask {
        if budget.is_none() {
            // every lane, as `within` gives without a budget, and no distance taken per vertex
            return within(budget, opl);
        }
        let out = |x: V, lo: f32, hi: f32| (V::splat(lo) - x).max(x - V::splat(hi)).max(V::zero());
        let gap = V3::new(
            out(p.x, self.lo.x, self.hi.x),
            out(p.y, self.lo.y, self.hi.y),
            out(p.z, self.lo.z, self.hi.z),
        );
        let least = (gap.length() + V::splat(self.tail)).mul_f(self.eta_min * (1.0 - 1e-5));
        within(budget, opl + least)
    }
}

/// The least refractive index of `scene`: its medium's and every dielectric's interior.
fn least_index(scene: &Scene) -> f32 {
    scene
        .materials
        .iter()
        .filter_map(|m| match m.material {
            Material::Dielectric { int_ior, .. } => Some(int_ior),
            _ => None,
        })
        .fold(scene.eta, f32::min)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::temporal::{Gate, Pulse, TimeAxis};

    fn corr(pulse: Pulse, gate: Gate, offset: f64) -> Correlation {
        let axis = TimeAxis {
            start_opl: 2.0,
            bin_width_opl: 0.1,
            bins: 30,
        };
        Correlation::new(axis, pulse, offset, gate).unwrap()
    }

    #[test]
    fn no_path_past_the_budget_touches_a_bin_and_paths_just_inside_do() {
        let cases = [
            corr(Pulse::Delta, Gate::Box, 0.0),
            corr(Pulse::Gaussian { sigma_opl: 0.03 }, Gate::Box, 0.2),
            corr(Pulse::Box { width_opl: 0.25 }, Gate::Box, -0.4),
            corr(Pulse::Delta, Gate::Gaussian { sigma_opl: 0.05 }, 0.0),
            corr(
                Pulse::Gaussian { sigma_opl: 0.02 },
                Gate::Gaussian { sigma_opl: 0.05 },
                0.1,
            ),
        ];
        for c in &cases {
            let last = c.last_opl();
            // beyond the bound no bin is touched, for values and derivatives alike
            for k in 0..200 {
                let d = last + 1e-9 + k as f64 * 1e-3;
                assert!(c.range(d).is_empty(), "{c:?}: d = {d} reaches {:?}", c.range(d));
            }
            // and the bound is tight: a little before it, the last bin is still reached
            let before = last - 0.05;
            assert!(
                c.range(before).contains(&29),
                "{c:?}: d = {before}: {:?}",
                c.range(before)
            );
            let b = opl_budget(std::slice::from_ref(c)).unwrap() as f64;
            assert!(b >= last && b <= last + 0.02, "{b} vs {last}");
        }
        assert_eq!(opl_budget(&[]), None);
    }

    /// The bound never ends a lane that an emitter point lies within reach of: for points p
    /// and emitter points q (inside the box, on it, for a box that is one point, and for a
    /// laser spot whose beam adds a leg), a lane whose opl + η_min·(|p − q| + tail) ≤ budget
    /// is kept, and lanes far past it are ended.
    #[test]
    fn the_emitter_box_keeps_every_lane_an_emitter_point_is_within_reach_of() {
        let b = EndBox {
            lo: Vec3::new(-1.0, 2.0, 0.5),
            hi: Vec3::new(1.0, 2.0, 1.5),
            eta_min: 1.25,
            tail: 0.0,
        };
        let point = EndBox {
            lo: Vec3::splat(3.0),
            hi: Vec3::splat(3.0),
            eta_min: 1.0,
            tail: 0.0,
        };
        // a spot whose beam adds 2.5 m to every path that ends on it
        let spot = EndBox {
            lo: Vec3::new(0.5, -1.0, 0.0),
            hi: Vec3::new(0.5, -1.0, 0.0),
            eta_min: 1.1,
            tail: 2.5,
        };
        let mut state = 0x2545_F491_4F6C_DD1Du64;
        let mut next = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let budget = 20.0f32;
        let (mut kept, mut ended) = (0, 0);
        for bx in [b, point, spot] {
            for _ in 0..20_000 {
                let p = Vec3::new(next() * 16.0 - 8.0, next() * 16.0 - 8.0, next() * 16.0 - 8.0);
                let q = bx.lo + (bx.hi - bx.lo) * Vec3::new(next(), next(), next());
                let opl = next() * budget;
                let reach = opl + bx.eta_min * ((p - q).length() + bx.tail);
                let pv = V3::new(p.x, p.y, p.z);
                let r = bx.reachable(Some(budget), opl, &pv);
                if reach <= budget {
                    assert!(r, "{bx:?}: p {p}, q {q}, opl {opl}: {reach} ≤ {budget} but ended");
                    kept += 1;
                }
                // the nearest point of the box: ended once it is out of reach
                let nearest = p.clamp(bx.lo, bx.hi);
                if opl + bx.eta_min * ((p - nearest).length() + bx.tail) > budget * 1.001 {
                    assert!(!r, "{bx:?}: p {p}, opl {opl} kept though no point is within reach");
                    ended += 1;
                }
            }
            assert!(
                bx.reachable(None, 1e30f32, &V3::new(1e9, 0.0, 0.0)),
                "no budget, no bound"
            );
        }
        assert!(
            kept > 1000 && ended > 1000,
            "both cases seen: {kept} kept, {ended} ended"
        );
    }

    /// The box covers the area emitters' triangles, and η_min is the least index of the scene:
    /// a dielectric's interior below the scene's medium lowers it.
    #[test]
    fn the_emitter_box_covers_the_lights_with_the_least_index() {
        let mut scene = crate::scene::testutil::load_scene("cornell_box.toml");
        let b = EndBox::new(&scene, []).unwrap();
        assert_eq!(b.eta_min, scene.eta);
        let geo = &scene.geometry;
        let mut lights = 0;
        for (t, tri) in geo.indices.iter().enumerate() {
            let shape = &scene.shapes[geo.tri_shape[t] as usize];
            if shape.emitter.is_some() {
                for v in tri.map(|i| geo.positions[i as usize]) {
                    assert!(v.cmpge(b.lo).all() && v.cmple(b.hi).all(), "{v} outside {b:?}");
                    lights += 1;
                }
            }
        }
        assert!(
            lights >= 3 && (b.hi - b.lo).max_element() < 1.0,
            "{lights} vertices, {b:?}"
        );
        scene.materials.push(crate::scene::NamedMaterial {
            name: "thin".into(),
            material: Material::Dielectric {
                int_ior: 0.8,
                roughness: 0.0,
                exterior: None,
            },
            one_sided: false,
        });
        assert_eq!(EndBox::new(&scene, []).unwrap().eta_min, 0.8);
        scene.emitters.clear();
        assert!(EndBox::new(&scene, []).is_none(), "no emitter, nothing bounded");
    }

    /// A laser's box is its spot, not the triangle the spot lies on, and the beam's leg is its
    /// tail: always for a scene's laser, for a scan's laser points only where the relay legs
    /// count. Where a point light shares the scene, it adds nothing after its point, so
    /// neither does the box.
    #[test]
    fn a_laser_spot_bounds_by_its_point_and_its_leg() {
        use crate::integrator::RenderContext;
        let device = crate::accel::Device::new("").unwrap();
        let scene = crate::scene::testutil::load_scene("gated_laser_room.toml");
        let ctx = RenderContext::new(&scene, &device).unwrap();
        let s = ctx.emitters.laser_spot(0).expect("the room's laser lights a spot");
        let b = ctx.emitter_box.unwrap();
        let at = s.origin + s.direction * s.distance;
        assert!((b.hi - b.lo).max_element() < 1e-6, "a point, not a triangle: {b:?}");
        assert!((b.lo - at).length() < 1e-5, "{b:?} vs the spot {at}");
        assert!(s.distance > 1.0 && b.tail == s.distance, "{b:?}, leg {}", s.distance);
        let text = crate::scene::testutil::scene_text("nlos_occluder.toml");
        let capture = |legs: &str| {
            let text = text.replace(
                "scan = \"confocal\"",
                &format!("scan = \"confocal\"\nrelay_legs = \"{legs}\""),
            );
            let scene = crate::scene::testutil::load_text("occ.toml", &text, &[], &[]).unwrap();
            let ctx = RenderContext::new(&scene, &device).unwrap();
            let n = ctx.nlos.as_ref().unwrap();
            let least = n
                .spots
                .iter()
                .flatten()
                .map(|s| s.distance)
                .fold(f32::INFINITY, f32::min);
            (ctx.emitter_box.unwrap(), least)
        };
        let (excluded, _) = capture("excluded");
        assert_eq!(excluded.tail, 0.0, "{excluded:?}");
        let (included, least) = capture("included");
        assert!(
            least > 1.0 && included.tail <= least && included.tail >= 0.99 * least,
            "{included:?}, {least}"
        );
        let mut lit = scene.clone();
        lit.emitters.push(crate::scene::Emitter {
            kind: EmitterKind::Point {
                position: Vec3::new(0.0, 1.0, 0.0),
                intensity: [1.0; 3],
            },
            ..scene.emitters[0].clone()
        });
        assert_eq!(EndBox::new(&lit, [(at, s.distance)]).unwrap().tail, 0.0);
    }

    /// The path tracer and BDPT with the bound against without it (both boxes taken away),
    /// on a window that ends early: the same bytes in every bin and the same shadow rays, and
    /// far fewer bounce rays. The third case keeps the pinhole's box alone, so that BDPT's
    /// light subpaths are seen to end early on their own.
    #[test]
    fn paths_that_no_end_is_within_reach_of_end_with_the_same_bytes() {
        use crate::film::{SteadyMode, Transient};
        use crate::integrator::RenderContext;
        use crate::integrator::bdpt::{self, film::BdptFilm};
        use crate::integrator::deposit::PathCounts;
        use crate::integrator::trace::RayCounts;
        use crate::kernel::f32x8;
        let mut scene = crate::scene::testutil::load_scene("cornell_box.toml");
        (scene.film.width, scene.film.height, scene.film.axis.bins) = (16, 16, 40);
        let device = crate::accel::Device::new("").unwrap();
        // (bidirectional, keep the emitter box, keep the pinhole's)
        let render = |(bidirectional, emitters, pinhole): (bool, bool, bool)| -> (Transient, RayCounts) {
            let mut ctx = RenderContext::new(&scene, &device).unwrap();
            ctx.cut_to_window(SteadyMode::Window);
            if !emitters {
                ctx.emitter_box = None;
            }
            if !pinhole {
                ctx.camera_box = None;
            }
            let mut counts = PathCounts::default();
            let film = if bidirectional {
                let mut f = BdptFilm::new(&ctx, (0, 0, 16, 16), 0, false, true);
                bdpt::render_tiles::<f32x8, 3, _>(&ctx, 7, 4, &(0..4), &[(0, 0)], 16, &mut f, &mut counts);
                f.film
            } else {
                let mut f = ctx.tile_film(0, 0, 16, 16, 0);
                crate::render::render_tile::<f32x8, 3, _>(
                    &ctx,
                    7,
                    16,
                    &(0..16),
                    16,
                    (0, 0, 16, 16),
                    &mut f,
                    &mut counts,
                );
                f
            };
            let mut t = Transient::zeros_many(1, 16, 16, scene.film.axis, 3);
            film.store_into(&mut t);
            (t.remove(0), counts.rays)
        };
        let bits = |t: &Transient| t.data.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        for (what, with, without) in [
            ("path tracer", (false, true, true), (false, false, false)),
            ("BDPT", (true, true, true), (true, false, false)),
            ("BDPT's light subpaths", (true, false, true), (true, false, false)),
        ] {
            let (a, ra) = render(with);
            let (b, rb) = render(without);
            assert!(bits(&a) == bits(&b), "{what}: the transients differ");
            assert!(a.data.iter().any(|&v| v > 0.0), "{what}: nothing rendered");
            fewer_bounce_rays(what, &ra, &rb);
        }
    }

    /// The boundary stage's sensor walks (`integrator::importance`) with the pinhole box
    /// against without it, from points on the Cornell box's floor, on a window that ends early:
    /// the same terms to the bit, the same shadow rays, and fewer bounce rays.
    #[test]
    fn importance_walks_end_where_the_pinhole_is_out_of_reach_with_the_same_terms() {
        use crate::film::SteadyMode;
        use crate::integrator::RenderContext;
        use crate::integrator::deposit::PathCounts;
        use crate::integrator::importance::{ImportanceTerm, trace_importance_packet};
        use crate::integrator::path::SurfaceStarts;
        use crate::kernel::f32x8;
        let mut scene = crate::scene::testutil::load_scene("cornell_box.toml");
        scene.film.axis.bins = 40;
        let device = crate::accel::Device::new("").unwrap();
        let walk = |pinhole: bool| {
            let mut ctx = RenderContext::new(&scene, &device).unwrap();
            ctx.cut_to_window(SteadyMode::Window);
            if !pinhole {
                ctx.camera_box = None;
            }
            let mut terms: Vec<(usize, u64, ImportanceTerm<3>)> = Vec::new();
            let mut counts = PathCounts::default();
            for packet in 0..64u64 {
                // eight points on the floor, found by rays cast down onto it
                let mut starts = SurfaceStarts {
                    prim: [0; 8],
                    p: [Vec3::ZERO; 8],
                    p64: [glam::DVec3::ZERO; 8],
                    n: [Vec3::Y; 8],
                    out: [Vec3::Y; 8],
                    eta: [scene.eta; 8],
                    opl: [0.5; 8],
                    max_scatters: 8,
                    dim: 0,
                    sensor: [0; 8],
                    unblocked_first: [false; 8],
                };
                for i in 0..8 {
                    let k = (packet * 8 + i as u64) as f32;
                    let o = [(k * 0.618).fract() * 1.6 - 0.8, 0.5, (k * 0.382).fract() * 1.6 - 0.8];
                    let h = ctx.accel.intersect1(o, [0.0, -1.0, 0.0], 0.0, f32::INFINITY).unwrap();
                    starts.prim[i] = h.prim;
                    starts.p[i] = Vec3::new(o[0], o[1] - h.t, o[2]);
                    starts.p64[i] = starts.p[i].as_dvec3();
                }
                let ids: Vec<u64> = (0..8).map(|i| packet * 8 + i).collect();
                trace_importance_packet::<f32x8, 3>(&ctx, 5, &ids, &starts, &[8; 8], &mut counts, |i, t| {
                    terms.push((i, packet, *t))
                });
            }
            (terms, counts.rays)
        };
        let (a, ra) = walk(true);
        let (b, rb) = walk(false);
        let key = |(i, packet, t): &(usize, u64, ImportanceTerm<3>)| {
            let value = t.value.map(f32::to_bits);
            (
                *i,
                *packet,
                value,
                t.opl.to_bits(),
                t.fx.to_bits(),
                t.fy.to_bits(),
                t.scatters,
            )
        };
        assert!(a.iter().map(key).eq(b.iter().map(key)), "the terms differ");
        assert!(a.len() > 100, "{} terms", a.len());
        fewer_bounce_rays("importance walks", &ra, &rb);
    }

    /// The same shadow rays with the bound as without it, and at most 0.9× the bounce rays.
    fn fewer_bounce_rays(
        what: &str,
        with: &crate::integrator::trace::RayCounts,
        without: &crate::integrator::trace::RayCounts,
    ) {
        assert_eq!(with.occluded, without.occluded, "{what}: shadow rays");
        assert!(
            (with.intersect as f64) < 0.9 * without.intersect as f64,
            "{what}: {} bounce rays with the bound, {} without",
            with.intersect,
            without.intersect
        );
    }

    #[test]
    fn t_far_and_within_follow_the_budget() {
        let t: f32 = t_far(Some(10.0), 4.0f32, 1.5f32);
        assert_eq!(t, 4.0);
        assert!(t_far::<f32>(Some(1.0), 4.0, 1.0) < 0.0);
        assert_eq!(t_far::<f32>(None, 4.0, 1.0), f32::INFINITY);
        assert!(within(Some(10.0), 10.0f32).bit(0));
        assert!(!within(Some(10.0), 10.5f32).bit(0));
        assert!(within(None, 1e30f32).bit(0));
    }
}
