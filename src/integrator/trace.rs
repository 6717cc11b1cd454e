//! Lanes to Embree and back. Embree sees plain `f32` rays only.

use super::surface::{offset_origin, self_intersection_eps};
use crate::accel::{Accel, Ray8};
use crate::kernel::{Mask, Real, V3};
use crate::timing::SampledClock;

/// Plain hit lanes: `prim[i] == u32::MAX` where lane `i` missed or was inactive.
#[derive(Clone, Copy, Debug)]
pub struct HitLanes<V> {
    pub t: V,
    pub u: V,
    pub v: V,
    pub prim: [u32; 8],
}

/// Counts of rays sent to Embree, for rays/s reports.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct RayCounts {
    pub intersect: u64,
    pub occluded: u64,
    /// Ticks spent in Embree queries (see `crate::timing`; sampled by `clock`).
    pub trace_ticks: u64,
    /// Which queries read the counter (not part of a tally).
    #[serde(skip)]
    pub clock: SampledClock,
}

fn pack<V: Real>(o: &V3<V>, d: &V3<V>, tnear: V, tfar: V) -> Ray8 {
    Ray8 {
        org_x: o.x.to_array8(),
        org_y: o.y.to_array8(),
        org_z: o.z.to_array8(),
        dir_x: d.x.to_array8(),
        dir_y: d.y.to_array8(),
        dir_z: d.z.to_array8(),
        tnear: tnear.to_array8(),
        tfar: tfar.to_array8(),
    }
}

fn bools<M: Mask>(m: M, lanes: usize) -> [bool; 8] {
    let bits = m.bits();
    std::array::from_fn(|i| i < lanes && (bits >> i) & 1 == 1)
}

/// Closest hits for the active lanes. One lane goes through `rtcIntersect1`, eight through
/// `rtcIntersect8`.
pub fn intersect<V: Real>(
    accel: &Accel,
    o: &V3<V>,
    d: &V3<V>,
    tnear: V,
    tfar: V,
    active: V::Mask,
    coherent: bool,
    counts: &mut RayCounts,
) -> HitLanes<V> {
    let t0 = counts.clock.start();
    let mut prim = [u32::MAX; 8];
    let mut t = [0.0f32; 8];
    let mut u = [0.0f32; 8];
    let mut v = [0.0f32; 8];
    if V::LANES == 1 {
        if active.bit(0) {
            counts.intersect += 1;
            let org = [o.x.lane(0), o.y.lane(0), o.z.lane(0)];
            let dir = [d.x.lane(0), d.y.lane(0), d.z.lane(0)];
            if let Some(h) = accel.intersect1(org, dir, tnear.lane(0), tfar.lane(0)) {
                prim[0] = h.prim;
                t[0] = h.t;
                u[0] = h.u;
                v[0] = h.v;
            }
        }
    } else {
        let act = bools(active, V::LANES);
        counts.intersect += act.iter().filter(|&&a| a).count() as u64;
        // Misses and inactive lanes come back with prim = u32::MAX and u = v = 0.
        let h = accel.intersect8(&pack(o, d, tnear, tfar), act, coherent);
        prim = h.prim;
        t = std::array::from_fn(|i| if h.prim[i] != u32::MAX { h.t[i] } else { 0.0 });
        u = h.u;
        v = h.v;
    }
    counts.trace_ticks += counts.clock.stop(t0);
    HitLanes {
        t: V::from_lanes(&t),
        u: V::from_lanes(&u),
        v: V::from_lanes(&v),
        prim,
    }
}

/// Visibility of segments `o + s·d, s ∈ (tnear, tfar)`: true where nothing blocks.
pub fn unoccluded<V: Real>(
    accel: &Accel,
    o: &V3<V>,
    d: &V3<V>,
    tnear: V,
    tfar: V,
    active: V::Mask,
    counts: &mut RayCounts,
) -> V::Mask {
    let t0 = counts.clock.start();
    let act = bools(active, V::LANES);
    counts.occluded += act.iter().filter(|&&a| a).count() as u64;
    let mut free = [false; 8];
    if V::LANES == 1 {
        if act[0] {
            let org = [o.x.lane(0), o.y.lane(0), o.z.lane(0)];
            let dir = [d.x.lane(0), d.y.lane(0), d.z.lane(0)];
            free[0] = !accel.occluded1(org, dir, tnear.lane(0), tfar.lane(0));
        }
    } else {
        let blocked = accel.occluded8(&pack(o, d, tnear, tfar), act, false);
        for i in 0..8 {
            free[i] = act[i] && !blocked[i];
        }
    }
    counts.trace_ticks += counts.clock.stop(t0);
    V::Mask::from_bools(&free[..V::LANES])
}

/// A ray origin for leaving surface point `p` (unit geometric normal `n`, reached along the
/// unit direction `w_in`) in direction `dir`: offset off the surface to `dir`'s side
/// ([`offset_origin`]) and stepped back along the arrival direction by the same distance.
/// The arriving segment is free space, so the step back keeps the origin on the side the
/// path came from even where `p` lies on an edge shared with another surface (a floor under a
/// box resting on it, two faces of a closed container): rays that leave a closed object's
/// inside from such a point then still meet its walls instead of starting outside them.
/// Point-like ends (n = 0, w_in = 0: the pinhole, a point light) are their own origin.
/// `scale` is the scene's offset scale ([`self_intersection_eps`]).
#[inline(always)]
pub fn spawn_point<V: Real>(p: &V3<V>, n: &V3<V>, w_in: &V3<V>, dir: &V3<V>, scale: f32) -> V3<V> {
    let o = offset_origin(p, n, dir, scale);
    let back = w_in.dot(*w_in).gt(V::zero());
    V3::select(back, o.add_scaled(*w_in, -self_intersection_eps(p, scale)), o)
}

/// One end of a shadow segment: the vertex, its unit geometric normal (zero at point-like
/// vertices) and the unit direction along which its path reached it (zero at path starts).
#[derive(Clone, Copy, Debug)]
pub struct SegmentEnd<V: Real> {
    pub p: V3<V>,
    pub n: V3<V>,
    pub w_in: V3<V>,
}

/// The shadow ray joining two path vertices: origin, unit direction and length. Both ends
/// are moved off their surfaces by [`spawn_point`], towards each other, and the ray runs the
/// whole way between them. Cutting a fixed length off the far end instead (as before
/// 2026-11-23) missed any wall crossed within that length of the target: a vertex on a
/// closed box's inner wall next to an edge was then joined to points outside the box, and
/// BDPT leaked light out of closed containers (issue 9, part 2; tests/closed_containers.rs).
/// `scale` is the scene's offset scale ([`self_intersection_eps`]).
#[inline(always)]
pub fn shadow_segment<V: Real>(from: &SegmentEnd<V>, to: &SegmentEnd<V>, scale: f32) -> (V3<V>, V3<V>, V) {
    let ab = to.p - from.p;
    let o = spawn_point(&from.p, &from.n, &from.w_in, &ab, scale);
    let target = spawn_point(&to.p, &to.n, &to.w_in, &-ab, scale);
    let to_t = target - o;
    let len = to_t.length();
    (o, to_t * V::safe_div(V::one(), len), len)
}

/// Of the lanes of `active`, those whose shadow ray from `from` to `to` ([`shadow_segment`])
/// is unblocked: the visibility test of every connection (next-event estimation, BDPT's
/// joins, the splats onto the camera and the sensor).
#[inline(always)]
pub fn visible_between<V: Real>(
    accel: &Accel,
    from: &SegmentEnd<V>,
    to: &SegmentEnd<V>,
    scale: f32,
    active: V::Mask,
    counts: &mut RayCounts,
) -> V::Mask {
    let (o, dir, len) = shadow_segment(from, to, scale);
    unoccluded(accel, &o, &dir, V::zero(), len, active, counts)
}

/// The next vertices of the lanes of `active`: the closest hits along (o, d) no farther than
/// the OPL left after `opl` allows (the window cut, `super::window`; through a medium of index
/// `eta`; no bound when `cut` is false, e.g. for the uncounted camera leg of an unwarped
/// film). Returns the hits and the lanes that found one within the bound.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub fn next_hits<V: Real>(
    accel: &Accel,
    budget: Option<f32>,
    o: &V3<V>,
    d: &V3<V>,
    opl: V,
    eta: V,
    cut: bool,
    active: V::Mask,
    coherent: bool,
    counts: &mut RayCounts,
) -> (HitLanes<V>, V::Mask) {
    let t_far = match cut {
        true => super::window::t_far(budget, opl, eta),
        false => V::splat(f32::INFINITY),
    };
    let active = active & t_far.gt(V::zero());
    let hit = intersect(accel, o, d, V::zero(), t_far, active, coherent, counts);
    let found: [bool; 8] = std::array::from_fn(|i| hit.prim[i] != u32::MAX);
    (hit, active & V::Mask::from_bools(&found[..V::LANES]))
}
