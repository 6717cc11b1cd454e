//! Where the paths of an NLOS capture start: at each lane's sensor point on the relay wall,
//! with a cosine-weighted first direction or one aimed at the hidden shapes (`super::nlos`
//! explains the estimator, `super::nlos_aim` the aiming).

use super::bsdf::{albedo, cosine_pdf, sample_cosine};
use super::context::RenderContext;
use super::nlos::NlosSensor;
use super::nlos_aim::{Aim, HiddenTargets};
use super::trace::spawn_point;
use crate::kernel::{Mask, Real, Spectrum, V3};
use glam::Vec3;

/// Where a packet's paths start on the wall (per lane): the first ray, the sensor point and
/// its normal, the direction's pdf and the starting weight ρ_s (with its derivatives).
pub struct SensorStart<R: Real, const C: usize> {
    pub o: V3<R::Value>,
    pub d: V3<R::Value>,
    pub p: V3<R>,
    pub n: V3<R>,
    pub pdf: R::Value,
    pub beta: Spectrum<R, C>,
    pub p64: [glam::DVec3; 8],
    /// Which lanes were aimed at the hidden shapes, and where (`None` without aiming): the
    /// first hit then sets the weight ([`weigh_first_hit`]).
    pub aim: Option<Aim>,
    /// Lanes with a path to trace (an aimed point behind the wall gives none).
    pub alive: R::Mask,
}

/// The first ray of each lane from its sensor point `sensor[i]`: a cosine-weighted direction
/// about the wall's normal from the filter's two random numbers, weight f_r·cos/pdf = ρ_s;
/// with aiming, the first number also picks the strategy, and the weight is the cosine
/// strategy's until the first hit corrects it.
pub fn start<R: Real, const C: usize>(
    ctx: &RenderContext,
    scan: &NlosSensor,
    sensor: &[usize; 8],
    u1: R::Value,
    u2: R::Value,
) -> SensorStart<R, C> {
    let pts: [Vec3; 8] = std::array::from_fn(|i| scan.sensors[sensor[i]].p);
    let nrm: [Vec3; 8] = std::array::from_fn(|i| scan.sensors[sensor[i]].n);
    let prims: [u32; 8] = std::array::from_fn(|i| scan.sensors[sensor[i]].prim);
    let p = V3::<R::Value>::from_lane_vecs(&pts[..R::LANES]);
    let n = V3::<R::Value>::from_lane_vecs(&nrm[..R::LANES]);
    let (d, pdf, aim, alive) = match &scan.hidden {
        None => {
            let (d, pdf) = sample_cosine(&n, &n, u1, u2);
            (d, pdf, None, R::Mask::splat(true))
        }
        Some(t) => {
            let (d, aim, alive) = first_directions::<R>(ctx, t, &pts, &n, u1, u2);
            (d, cosine_pdf(&n, &n, &d), Some(aim), alive)
        }
    };
    SensorStart {
        o: spawn_point(&p, &n, &V3::zero(), &d, ctx.scene.offset_scale),
        d,
        p: V3::from_value(p),
        n: V3::from_value(n),
        pdf,
        beta: albedo::<R, C>(ctx, &prims),
        p64: pts.map(|q| q.as_dvec3()),
        aim,
        alive,
    }
}

/// The first segment's directions: cosine-sampled from (`u1`, `u2`) in the lanes that
/// `u1 ≥ α` picks (with `u1` rescaled to [0, 1)), aimed at a point drawn on the hidden shapes
/// in the others. Returns the directions, the aim and the lanes whose aimed point lies
/// behind the wall (f_r = 0 there: those paths carry nothing).
pub fn first_directions<R: Real>(
    ctx: &RenderContext,
    targets: &HiddenTargets,
    p: &[Vec3; 8],
    n: &V3<R::Value>,
    u1: R::Value,
    u2: R::Value,
) -> (V3<R::Value>, Aim, R::Mask) {
    let alpha = targets.probability;
    let mut aim = Aim::default();
    let mut u_cos = [0.0f32; 8];
    let mut to = [Vec3::Z; 8];
    let mut alive = [true; 8];
    for i in 0..R::LANES {
        let u = u1.lane(i);
        if u < alpha {
            let (prim, bu, bv) = targets.draw(u / alpha, u2.lane(i));
            let [a, b, c] = ctx.tri_verts[prim as usize];
            let y = a + (b - a) * bu + (c - a) * bv;
            let d = y - p[i];
            let dist = d.length();
            let dir = d / dist;
            aim.aimed[i] = true;
            aim.prim[i] = prim;
            aim.dist[i] = dist;
            alive[i] = dist > 0.0 && dir.dot(n.lane(i)) > 0.0;
            // a dead lane keeps a finite direction (its ray is masked out)
            to[i] = if alive[i] { dir } else { n.lane(i) };
        } else {
            u_cos[i] = ((u - alpha) / (1.0 - alpha)).min(1.0 - f32::EPSILON);
        }
    }
    let (cos_dir, _) = sample_cosine(n, n, R::Value::from_lanes(&u_cos[..R::LANES]), u2);
    let aimed = <R::Value as Real>::Mask::from_bools(&aim.aimed[..R::LANES]);
    let d = V3::select(aimed, V3::from_lane_vecs(&to[..R::LANES]), cos_dir);
    (d, aim, R::Mask::from_bools(&alive[..R::LANES]))
}

/// At the first hit (triangle `prim`, distance² `r2`, |cos θ₁| `cos_1`, reached along unit
/// `dir` from the sensor point with normal `n`): the factor that turns the cosine strategy's
/// weight ρ_s into ρ_s·(cos θ_s/π)/p(ω), the mixture's density p(ω), and the lanes that count
/// (an aimed lane whose ray met another surface before its point carries nothing).
pub fn weigh_first_hit<R: Real>(
    targets: &HiddenTargets,
    aim: &Aim,
    prim: &[u32; 8],
    n: &V3<R::Value>,
    dir: &V3<R::Value>,
    r2: R::Value,
    cos_1: R::Value,
) -> (R::Value, R::Value, R::Mask) {
    let cos_s = n.dot(*dir);
    let mut scale = [0.0f32; 8];
    let mut pdf = [0.0f32; 8];
    let mut keep = [false; 8];
    for i in 0..R::LANES {
        let (r2, c1, cs) = (r2.lane(i), cos_1.lane(i), cos_s.lane(i));
        let t = prim[i];
        if aim.aimed[i] {
            let same = t == aim.prim[i] || (r2.sqrt() - aim.dist[i]).abs() <= 1e-4 * aim.dist[i];
            if !same {
                continue;
            }
        }
        let p_cos = cs.max(0.0) * std::f32::consts::FRAC_1_PI;
        let p = targets.mixture_pdf(p_cos, t, r2, c1);
        if p > 0.0 && p.is_finite() && p_cos > 0.0 {
            scale[i] = p_cos / p;
            pdf[i] = p;
            keep[i] = true;
        }
    }
    (
        R::Value::from_lanes(&scale[..R::LANES]),
        R::Value::from_lanes(&pdf[..R::LANES]),
        R::Mask::from_bools(&keep[..R::LANES]),
    )
}
