//! Next-event estimation on the time edges, the kernel step: at a path tracer vertex, light
//! points drawn where the connection's OPL crosses a bin edge (`time_edges.rs`), each traced
//! with one shadow ray per packet and handed to the film as a time-only contribution
//! (İ_k += f·Ṡ_e·ḋ_k; no value, no ḟ).
//!
//! The time term of a path that ends on an emitter after a vertex where next-event
//! estimation runs is then taken from these draws alone, with weight 1 (the estimator covers
//! every light point such a path can end on). So the path tracer leaves the time term out of
//! its ordinary next-event contributions and out of the emission its BSDF-sampled rays find
//! after such a vertex, and keeps it where next-event estimation cannot make the path: the
//! emitter seen from the camera, and emission found after a Dirac lobe or a refraction. The
//! value and ḟ parts keep their MIS weights; only f·Ṡ_e·ḋ moves (Algorithm 1's derivative is
//! the sum of the two parts, each estimated on its own).

use super::bsdf::Lobes;
use super::context::RenderContext;
use super::deposit::{PathCounts, for_each_lane};
use super::sink::Sink;
use super::surface::{SurfacePoint, resolvable};
use super::time_edges::{DIMS_PER_VERTEX, Draw, MAX_SLOTS, Plan, TimeEdges};
use super::trace::{SegmentEnd, visible_between};
use crate::kernel::{Mask, PathSampler, Real, Spectrum, V3};
use glam::{DVec3, Vec3};

/// Seed of the draws' random numbers, xor the render's (a stream of their own, so that the
/// path's other numbers are those of a render without the draws).
pub const SEED: u64 = 0x7E4D_6E5A_11C0_9B3F;

/// A path tracer vertex as the draws need it.
pub struct Vertex<'a, R: Real, const C: usize> {
    pub x: &'a SurfacePoint<R>,
    /// x in f64 (valid when the render carries f64 OPLs).
    pub x64: &'a [DVec3; 8],
    /// Unit direction the path arrived along, with its derivatives, and its value.
    pub w_in: &'a V3<R>,
    pub ray_d: &'a V3<R::Value>,
    pub beta: &'a Spectrum<R, C>,
    /// The vertex's lobes, or `None` for a diffuse-only scene (then `f_diffuse` is f).
    pub lobes: Option<&'a Lobes<R, C>>,
    pub f_diffuse: &'a Spectrum<R, C>,
    /// Prefix OPL (in R, and per lane in f64 when the render carries f64 OPLs).
    pub opl: R,
    pub opl64: &'a [f64; 8],
    /// Index of the medium the path is in.
    pub eta: R,
}

/// Draws light points for the lanes of `active` (vertices where next-event estimation runs)
/// whose OPL can move, traces them and deposits their time terms at pixels (`px`, `py`).
#[allow(clippy::too_many_arguments)]
pub fn connect<R: Real, const C: usize, S: Sink<C>>(
    ctx: &RenderContext,
    te: &TimeEdges,
    sampler: &mut PathSampler,
    depth: u32,
    v: &Vertex<R, C>,
    active: R::Mask,
    (px, py): (&[u32; 8], &[u32; 8]),
    sink: &mut S,
    counts: &mut PathCounts,
) {
    type V<R> = <R as Real>::Value;
    let exact = ctx.opl.f64_paths;
    sampler.set_dim(depth as u64 * DIMS_PER_VERTEX);
    let (u_e, u_p) = sampler.next2::<V<R>>();
    let n_k = R::DERIVS.min(ctx.motion.len());
    let x_val = v.x.p.value();
    let mut plans: [Option<Plan>; 8] = [None; 8];
    let mut slots = 0;
    for (i, plan) in plans.iter_mut().enumerate().take(R::LANES) {
        if !active.bit(i) {
            continue;
        }
        let moves = te.always
            || (0..n_k).any(|k| {
                [v.opl, v.eta, v.x.p.x, v.x.p.y, v.x.p.z]
                    .iter()
                    .any(|c| c.deriv_lane(k, i) != 0.0)
            });
        if !moves {
            continue;
        }
        let (x, d_p) = if exact {
            (v.x64[i], v.opl64[i])
        } else {
            let p = Vec3::new(x_val.x.lane(i), x_val.y.lane(i), x_val.z.lane(i));
            (p.as_dvec3(), v.opl.value().lane(i) as f64)
        };
        *plan = te.plan(
            x,
            d_p,
            v.eta.value().lane(i) as f64,
            u_e.lane(i) as f64,
            u_p.lane(i) as f64,
        );
        slots = slots.max(plan.map_or(0, |p| p.slots));
    }
    // Every draw of the vertex takes the same two numbers: the strata of the components laid
    // end to end get one offset (systematic sampling), and every circle the same fraction of
    // its arcs. Each draw keeps its own density, so each stays unbiased; draws on neighbouring
    // edges land at the same place relative to their edge and near the same light point, so
    // their terms are positively correlated, and a bin's derivative, the difference of its
    // two edges' terms, varies less than with numbers of their own.
    let (xi, u_phi) = sampler.next2::<V<R>>();
    for slot in 0..slots.min(MAX_SLOTS) {
        let mut draws: [Option<Draw>; 8] = [None; 8];
        let mut emitter = [u32::MAX; 8];
        for i in 0..R::LANES {
            if let Some(plan) = plans[i].as_ref().filter(|p| slot < p.slots) {
                draws[i] = te.draw(plan, slot, xi.lane(i) as f64, u_phi.lane(i) as f64);
                if draws[i].is_some() {
                    emitter[i] = plan.emitter;
                }
            }
        }
        let valid: [bool; 8] = std::array::from_fn(|i| draws[i].is_some());
        if !valid.iter().any(|&b| b) {
            continue;
        }
        let y_lanes: [Vec3; 8] = std::array::from_fn(|i| draws[i].map_or(Vec3::ZERO, |d| d.y.as_vec3()));
        let normals: [Vec3; 8] = std::array::from_fn(|i| match (&plans[i], draws[i]) {
            (Some(p), Some(_)) => te.normal(p).as_vec3(),
            _ => Vec3::Y,
        });
        let weights: [f32; 8] = std::array::from_fn(|i| draws[i].map_or(0.0, |d| d.weight as f32));
        let radiance: [[f32; 3]; 8] =
            std::array::from_fn(|i| if valid[i] { te.radiance(emitter[i]) } else { [0.0; 3] });
        // the light point moves with its emitter (material form)
        let mut y = V3::<R>::from_lane_vecs(&y_lanes[..R::LANES]);
        for k in (0..n_k).filter(|_| te.emitters_move) {
            let vel: [Vec3; 8] = std::array::from_fn(|i| {
                if valid[i] {
                    ctx.motion.velocity(k, te.shape(emitter[i]), y_lanes[i])
                } else {
                    Vec3::ZERO
                }
            });
            y.x = y.x.with_deriv_lanes(k, &vel.map(|w| w.x));
            y.y = y.y.with_deriv_lanes(k, &vel.map(|w| w.y));
            y.z = y.z.with_deriv_lanes(k, &vel.map(|w| w.z));
        }
        let n_y = V3::<R>::from_lane_vecs(&normals[..R::LANES]);
        let to = y - v.x.p;
        let d2 = to.length_squared();
        let dist = d2.sqrt();
        let wl = to * R::safe_div(R::one(), dist);
        let cos_x = v.x.n.dot(wl);
        let incoming = v.x.n.value().dot(-*v.ray_d);
        let same_side = (cos_x.value() * incoming).gt(V::<R>::zero());
        let cos_y = -n_y.dot(wl);
        let lit = active
            & R::Mask::from_bools(&valid[..R::LANES])
            & same_side
            & cos_y.value().gt(V::<R>::zero())
            & d2.value().gt(V::<R>::zero())
            & resolvable(
                &x_val,
                ctx.scene.offset_scale,
                cos_x.value(),
                cos_y.value(),
                dist.value(),
            );
        if lit.none() {
            continue;
        }
        let here = SegmentEnd {
            p: x_val,
            n: v.x.n.value(),
            w_in: *v.ray_d,
        };
        let light = SegmentEnd {
            p: y.value(),
            n: n_y.value(),
            w_in: V3::zero(),
        };
        let lit = lit & visible_between(&ctx.accel, &here, &light, ctx.scene.offset_scale, lit, &mut counts.rays);
        if lit.none() {
            continue;
        }
        let f = match v.lobes {
            None => *v.f_diffuse,
            Some(l) => l.eval(&v.x.n, &-*v.w_in, &wl, true),
        };
        let g = cos_x.abs() * cos_y / d2;
        let le = Spectrum::<R, C>::from_lane_rgb(&radiance[..R::LANES]);
        let contrib = (*v.beta * f * le).scale(g * R::from_lanes(&weights[..R::LANES]));
        let d = v.opl + v.eta * dist;
        let mut d64 = [0.0f64; 8];
        if exact {
            for i in 0..R::LANES {
                if let Some(draw) = draws[i] {
                    d64[i] = v.opl64[i] + v.eta.value().lane(i) as f64 * (draw.y - v.x64[i]).length();
                }
            }
        }
        for_each_lane(
            ctx,
            &emitter,
            d,
            exact.then_some(&d64),
            &contrib,
            lit,
            counts,
            |i, lc| {
                let mut lc = *lc;
                lc.time_only = true;
                lc.edge = draws[i].and_then(|d| d.edge);
                sink.add(ctx, (1, depth as usize + 1), px[i] as usize, py[i] as usize, &lc, 1.0);
            },
        );
    }
}
