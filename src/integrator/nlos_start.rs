//! Where the paths of an NLOS capture start: at each lane's sensor point on the relay wall,
//! with a cosine-weighted first direction or one aimed at the hidden shapes (`super::nlos`
//! explains the estimator, `super::nlos_aim` the aiming).

use super::bsdf::{albedo, cosine_pdf, sample_cosine};
use super::context::RenderContext;
use super::nlos::NlosSensor;
use super::nlos_aim::{Aim, first_directions};
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
    /// first hit then sets the weight ([`super::nlos_aim::weigh_first_hit`]).
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
        o: spawn_point(&p, &n, &V3::zero(), &d),
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
