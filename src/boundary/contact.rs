//! The two ends x_S and x_L of a boundary segment through x_B, contact edges included.
//!
//! A **contact edge** lies on another surface: the base edge of a pyramid resting on the floor.
//! Every silhouette direction ω through such an edge meets that surface at x_B itself, so one
//! side of the boundary segment has zero length. Supplemental Eqs. 31–32 ask for an edge point
//! z in the *open* segment (x, y), which excludes this case: here z = x_B is an end point. Its
//! discontinuity is the one of V(x_{i−1}, x_i)·V(x_i, x_{i+1}) as the path vertex x_i on the
//! supporting surface crosses the edge into the region the object covers, where both segments
//! are blocked at once. The product rule (supplemental Eq. 20, as Eq. 30 applies it to the
//! segments of a path, light to sensor) splits the jump as V_i⁺ · ΔV_{i+1} + ΔV_i · V_{i+1}⁻,
//! with ⁺ the free side and ⁻ the covered one. V_{i+1}⁻ = 0, so the contact vertex counts
//! **once**, with its departing segment (towards the sensor) and the light arriving at it
//! evaluated on the free side. The primary estimator does the same for the camera segment (its
//! outer side ray sees the lit floor next to the edge), which is why the arriving segment must
//! not count too: doing so adds the direct light at the contact a second time.
//!
//! - ω enters the supporting surface from the object's side (x_S = x_B): no contribution.
//! - ω leaves it (x_L = x_B): x_L is taken a hair off the edge on the free side, x_S is the
//!   first hit along ω. The collapsed weight of `secondary.rs` degenerates here (Π contains
//!   x_L, N = 0), so the limit is taken directly: with x_S in area measure,
//!   G(x_L, x_S) dA(x_S) = |cos_L| dω, and the free region of the surface, whose boundary is
//!   the edge, changes at the rate −(v_edge − v_surface)·u_out per unit length (u_out: in the
//!   surface, ⊥ edge, away from the object). Per boundary ray of density p_e p_ω / ℓ_e the
//!   derivative weight is −((v_edge − v_surface)·u_out) |cos_L| ℓ_e / (p_e p_ω), times the
//!   source and sensor subpaths. Only the in-surface motion counts: lifting or sinking an
//!   object off its support is not differentiable there (a gap opens one way, the surfaces
//!   interpenetrate the other).
//!
//! A supporting surface that emits towards x_S (an object resting on an area light's front)
//! adds its emission at x_L to the source subpath: the light's free area changes at the edge
//! at the same rate (`secondary.rs`, `contact_emits`).
//!
//! Tracing: ray origins are moved off x_B by ε to the free side of the plane Π(edge, ω) (so no
//! ray meets the edge's own faces) and backed off by `BACK_OFF`·ε along the ray, so a surface
//! through x_B is hit at t ≈ `BACK_OFF`·ε whichever side of it the offset origin fell on. A hit
//! whose plane passes within 2ε of x_B (within ε where the edge's faces lie flat along it:
//! `passes_through`) is a supporting surface; any other hit closer than the back-off lies
//! behind x_B, and the ray goes on past it. A supporting surface's side holding
//! the edge's faces orients it; the x_S ray then starts on that side, λ = 2ε/|ω·n| along the
//! line. Where that exceeds `REACH`·ε (|cos_L| < 2/`REACH`) the sample is dropped: its weight
//! carries |cos_L|, so the loss is of order (2/`REACH`)².
use super::edge_sampler::EdgeRecord;
use super::hit::{SurfaceHit, trace, trace_past};
use crate::integrator::context::RenderContext;
use crate::integrator::opl::on_plane64;
use crate::integrator::surface::self_intersection_eps;
use crate::integrator::trace::RayCounts;
use crate::kernel::V3;
use crate::scene::Geometry;
use glam::Vec3;

/// Back-off of the ray origins behind x_B, in units of the self-intersection ε.
pub(super) const BACK_OFF: f32 = 8.0;
/// Farthest a supporting surface may be hit from x_B (and x_L's ray start), in units of ε.
const REACH: f32 = 256.0;

/// The ends of a boundary segment, distances t measured from x_B.
#[derive(Clone, Copy, Debug)]
pub(super) enum SegmentEnds {
    /// An ordinary segment: x_S along ω, x_L along −ω (None: the ray leaves the scene).
    Open { x_s: SurfaceHit, x_l: Option<SurfaceHit> },
    /// A contact edge: x_L = x_B on the supporting surface (on the free side of the edge),
    /// x_S along ω; `outward` lies in the surface, ⊥ edge, away from the object.
    Contact {
        x_l: SurfaceHit,
        x_s: SurfaceHit,
        outward: Vec3,
    },
}

fn shifted(h: SurfaceHit, dt: f32) -> SurfaceHit {
    SurfaceHit { t: h.t + dt, ..h }
}

/// `hit`, found by a ray that ran ε beside the line x_B + t·`dir` (so as not to meet the
/// edge's own faces), moved within its surface's plane onto the line itself, `t` then
/// measured from x_B: the boundary segment grazes the edge, and its ends are where its
/// integrand is evaluated. Left as found were they lie ε/(the line's angle to the plane)
/// away, i.e. where the line grazes its surface (farther than `REACH`·ε).
///
/// ε is 2⁻¹⁸ of the largest coordinate, 16 mm at 3 km from the render origin (which stays at
/// the world origin when the geometry's box holds it, e.g. a kilometre-wide ground): ends
/// found off the line moved every shadow sample's pixel and weights by some 2ε, and a shadow
/// cut by the image border lost or gained that strip, +4.6 % on its derivative at 3 km.
fn onto_line(ctx: &RenderContext, hit: SurfaceHit, x_b: Vec3, dir: Vec3, eps: f32) -> SurfaceHit {
    let (x_b64, dir64) = (x_b.as_dvec3(), dir.as_dvec3());
    let p64 = on_plane64(ctx, hit.prim, x_b64, dir64);
    let t = (p64 - x_b64).dot(dir64);
    if !((p64 - hit.p.as_dvec3()).length() <= (REACH * eps) as f64 && t > 0.0) {
        return hit;
    }
    SurfaceHit {
        p: p64.as_vec3(),
        p64,
        t: t as f32,
        ..hit
    }
}

/// Most surfaces a ray backed off behind x_B may meet before it reaches x_B.
const BEHIND: usize = 4;

/// The first hit of the ray `o + t·d`, started `back` behind x_B, that is not a surface lying
/// behind x_B: one met before x_B (t < `back`) whose plane does not pass through x_B
/// (`through`: [`passes_through`]) is on the other end's side of the line, so the ray goes on
/// past it.
/// Such a surface is as near x_B as the back-off (a light 20 µm over an occluder's edge in a
/// room, 8ε = 61 µm). Taken for a supporting surface, as it once was, the edge's faces lay
/// on neither side of it and every line through the edge was dropped: the occluder's shadow
/// derivative read 0. None after `BEHIND` such surfaces (coplanar pieces of one surface met
/// again at grazing incidence).
fn first_not_behind(
    ctx: &RenderContext,
    o: Vec3,
    d: Vec3,
    back: f32,
    eps: f32,
    through: &dyn Fn(&SurfaceHit) -> bool,
    rays: &mut RayCounts,
) -> Option<SurfaceHit> {
    let mut t_near = 0.0;
    for _ in 0..BEHIND {
        let h = trace_past(ctx, o, d, t_near, rays)?;
        if h.t >= back || through(&h) {
            return Some(h);
        }
        t_near = h.t + 0.25 * eps;
    }
    None
}

/// x_S along ω and x_L along −ω through x_B on edge `rec` (s_o: the side of Π holding the
/// edge's faces), contact edges handled as the module documentation says. None: no x_S,
/// or no contribution (x_S at x_B on a supporting surface, a grazing or penetrating
/// contact).
pub(super) fn segment_ends(
    ctx: &RenderContext,
    rec: &EdgeRecord,
    x_b: Vec3,
    omega: Vec3,
    s_o: f32,
    rays: &mut RayCounts,
) -> Option<SegmentEnds> {
    let eps = self_intersection_eps(&V3::<f32>::splat(x_b), ctx.scene.offset_scale);
    let back = BACK_OFF * eps;
    let free = (rec.v1 - rec.v0).cross(omega).normalize_or_zero() * -s_o;
    let o = x_b + free * eps;
    let through = |h: &SurfaceHit| passes_through(&ctx.scene.geometry, rec, x_b, h, eps);
    let s_hit = first_not_behind(ctx, o - omega * back, omega, back, eps, &through, rays);
    let l_hit = first_not_behind(ctx, o + omega * back, -omega, back, eps, &through, rays);
    let supports = |h: &SurfaceHit| through(h) && h.t <= back + REACH * eps;
    match s_hit.filter(supports).or(l_hit.filter(supports)) {
        None => Some(SegmentEnds::Open {
            x_s: onto_line(ctx, shifted(s_hit?, -back), x_b, omega, eps),
            x_l: l_hit.map(|h| onto_line(ctx, shifted(h, -back), x_b, -omega, eps)),
        }),
        Some(support) => contact_ends(ctx, rec, x_b, omega, free, eps, &support, rays),
    }
}

/// Whether the plane of `h`'s surface passes through x_B on edge `rec`: within 2ε of it, or
/// within ε where the edge's faces lie flat along that plane (a panel under a light). Such
/// faces stand on neither side of it, so a contact there adds nothing (`contact_ends`); a gap
/// wider than ε, the rays' own offset, is one the forward render resolves (the panel shades
/// the light: `scene::flush` lifts a light off a face only within ε), and it is an ordinary
/// gap here too. A panel 10 µm under a light in a room (ε 7.6 µm) was taken to lie on it, and
/// its shadow's derivative read 0.
pub(super) fn passes_through(geo: &Geometry, rec: &EdgeRecord, x_b: Vec3, h: &SurfaceHit, eps: f32) -> bool {
    let d = h.n.dot(x_b - h.p).abs();
    d <= eps || (d <= 2.0 * eps && faces_beside(geo, rec, x_b, h.n, eps) != (false, false))
}

/// Whether the opposite vertices of edge `rec`'s faces lie beyond the plane through x_B with
/// normal `n` on its front (first) or its back (second), by more than the back-off.
fn faces_beside(geo: &Geometry, rec: &EdgeRecord, x_b: Vec3, n: Vec3, eps: f32) -> (bool, bool) {
    let tol = BACK_OFF * eps;
    let (mut above, mut below) = (false, false);
    for o in std::iter::once(rec.edge.opposite0).chain(rec.edge.opposite1) {
        let h = n.dot(geo.positions[o as usize] - x_b);
        above |= h > tol;
        below |= h < -tol;
    }
    (above, below)
}

/// The ends when `support` passes through x_B (a contact edge).
#[allow(clippy::too_many_arguments)]
fn contact_ends(
    ctx: &RenderContext,
    rec: &EdgeRecord,
    x_b: Vec3,
    omega: Vec3,
    free: Vec3,
    eps: f32,
    support: &SurfaceHit,
    rays: &mut RayCounts,
) -> Option<SegmentEnds> {
    let n = support.n;
    // the edge's faces must lie on one side of the supporting plane (their opposite
    // vertices on it or beyond it on one side; none beyond: a flat face lying on it)
    let n_obj = match faces_beside(&ctx.scene.geometry, rec, x_b, n, eps) {
        (true, false) => n,
        (false, true) => -n,
        _ => return None,
    };
    let cos = omega.dot(n_obj);
    // cos < 0: x_S = x_B, the ΔV_i · V_{i+1}⁻ term of the product rule, zero
    let lambda = 2.0 * eps / cos;
    if !(cos > 0.0 && lambda <= REACH * eps) {
        return None;
    }
    let outward = (free - n_obj * free.dot(n_obj)).normalize_or_zero();
    let p = x_b + outward * (2.0 * eps);
    let x_l = SurfaceHit {
        p,
        // a point of its own (not a hit): exact as it stands
        p64: p.as_dvec3(),
        t: 0.0,
        ..*support
    };
    let x_s = onto_line(
        ctx,
        shifted(trace(ctx, x_b + free * eps + omega * lambda, omega, rays)?, lambda),
        x_b,
        omega,
        eps,
    );
    Some(SegmentEnds::Contact { x_l, x_s, outward })
}
