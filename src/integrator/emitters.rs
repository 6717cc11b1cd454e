//! Emitter sampling for next-event estimation: [`EmitterTable::sample`] picks an emitter, a
//! triangle and a point per lane from the tables of `emitter_table.rs`, then rebuilds the
//! point in the kernel's number type through the render context (surface motion, f64 OPL
//! points, the laser spot in ray form, derivative lanes of the emission).

use super::context::RenderContext;
use super::emitter_table::{EmitterTable, Entry};
use super::emitter_table::{pick_and_rescale, uniform_in_triangle};
use super::path::ray_plane_point;
use super::surface::{SurfacePoint, surface_at};
use crate::kernel::{Mask, Real, Spectrum, V3};
use glam::Vec3;

/// A point sampled on an emitter, per lane.
#[derive(Clone, Copy, Debug)]
pub struct LightSample<R: Real, const C: usize> {
    pub p: V3<R>,
    /// Unit normal at the sampled point (area and laser spot); unused for point lights.
    pub n: V3<R>,
    /// Lanes whose emission carries cos θ at the emitter (area, laser spot).
    pub has_cos: R::Mask,
    /// Emission divided by the sampling pdf: Le/p_A (area), I/p_sel (point, laser spot).
    pub weight: Spectrum<R, C>,
    /// Area pdf including emitter selection, 0 for delta emitters (MIS weight 1).
    pub pdf_area: R::Value,
    pub emitter: [u32; 8],
    /// Geometric length travelled before the sampled point (laser to spot), else 0.
    pub pre_length: R,
    pub valid: R::Mask,
    /// The sampled points and `pre_length` in f64, rebuilt from the f32 barycentrics (see
    /// `super::opl`); zero unless the render carries f64 OPLs.
    pub p64: [glam::DVec3; 8],
    pub pre64: [f64; 8],
}

pub use super::emitter_table::REUSE_MAX_TRIANGLES;

impl EmitterTable {
    /// Whether [`EmitterTable::sample`] reads its `select` number: to pick one of several
    /// emitters where the point's number cannot spare the bits, or a triangle of a mesh larger
    /// than `REUSE_MAX_TRIANGLES`. Elsewhere the number is never read, so a caller may skip
    /// its dimension ([`crate::kernel::sampler::PathSampler::skip`]) instead of computing it.
    pub fn reads_select(&self) -> bool {
        !self.by_point
            && (self.entries.len() > 1
                || self
                    .entries
                    .iter()
                    .any(|e| matches!(e, Entry::Area { tris, .. } if tris.len() > REUSE_MAX_TRIANGLES)))
    }

    /// Samples one emitter point per lane: `select` picks the emitter, and the 2D point
    /// (`u0`, `u1`) the point on it. An area emitter of at most [`REUSE_MAX_TRIANGLES`]
    /// triangles maps the whole 2D point onto its surface: `u0` picks the triangle by area and
    /// is then rescaled within that triangle's share (as Mitsuba's `sample_reuse`), so a
    /// stratified 2D point set (a pixel's Sobol pair) stays stratified over the whole emitter,
    /// not only within whichever triangle each point happened to pick. A larger emitter mesh
    /// picks its triangle with the rest of `select` (after the emitter choice), since rescaling
    /// would leave `u0` too few of its 24 bits. Several emitters are chosen the same way, by
    /// `u0` rescaled within the emitter's share 1/n, wherever every emitter's triangles times
    /// n stay within `REUSE_MAX_TRIANGLES` (`EmitterTable::by_point`): a number apart from
    /// the point split a stratified set between the emitters at random, so that each emitter
    /// got an unstratified half (an independent sweep measured the boundary stage's variance
    /// of a two-light scene ~100× its lights' alone, where Sobol points gained nothing).
    pub fn sample<R: Real, const C: usize>(
        &self,
        ctx: &RenderContext,
        select: R::Value,
        u0: R::Value,
        u1: R::Value,
        active: R::Mask,
    ) -> LightSample<R, C> {
        self.sample_with(ctx, select, u0, u1, active, None)
    }

    /// The laser spots `scan.spots[points[i]]` of laser `scan.laser`, one per lane (an NLOS
    /// scan's laser points, `super::nlos`), each chosen with probability 1; with
    /// `scan.laser_leg` false the laser-to-spot length is left out of `pre_length`.
    pub fn sample_laser_points<R: Real, const C: usize>(
        &self,
        ctx: &RenderContext,
        scan: &super::nlos::NlosSensor,
        points: &[u32; 8],
        active: R::Mask,
    ) -> LightSample<R, C> {
        let z = R::Value::zero();
        self.sample_with(ctx, z, z, z, active, Some((scan, points)))
    }

    fn sample_with<R: Real, const C: usize>(
        &self,
        ctx: &RenderContext,
        select: R::Value,
        u0: R::Value,
        u1: R::Value,
        active: R::Mask,
        scan: Option<(&super::nlos::NlosSensor, &[u32; 8])>,
    ) -> LightSample<R, C> {
        let n_e = self.entries.len();
        let mut emitter = [u32::MAX; 8];
        let mut prim = [0u32; 8];
        let mut bu = [0.0f32; 8];
        let mut bv = [0.0f32; 8];
        let mut point = [Vec3::ZERO; 8];
        let mut radiance_rgb = [[0.0f32; 3]; 8];
        let mut inv_pdf = [0.0f32; 8];
        let mut laser = [false; 8];
        let mut laser_o = [Vec3::ZERO; 8];
        let mut laser_d = [Vec3::ZERO; 8];
        let mut per_power = [[0.0f32; 3]; 8];
        let mut pdf = [0.0f32; 8];
        let mut pre = [0.0f32; 8];
        let mut on_surface = [false; 8];
        let mut side = [1.0f32; 8];
        let mut valid = [false; 8];
        for i in 0..R::LANES {
            if !active.bit(i) || n_e == 0 {
                continue;
            }
            let sel = select.lane(i) * n_e as f32;
            let mut e = (sel as usize).min(n_e - 1);
            // the point's first number, rescaled within the emitter's share where it chose it
            let mut u_point = u0.lane(i);
            if self.by_point {
                let s = u_point * n_e as f32;
                e = (s as usize).min(n_e - 1);
                u_point = (s - e as f32).clamp(0.0, 1.0 - f32::EPSILON);
            }
            let mut p_sel = 1.0 / n_e as f32;
            let scanned;
            let entry = match scan {
                Some((sc, points)) => {
                    e = sc.laser as usize;
                    p_sel = 1.0;
                    scanned = Entry::Laser {
                        spot: sc.spots[points[i] as usize].clone(),
                    };
                    &scanned
                }
                None => &self.entries[e],
            };
            emitter[i] = e as u32;
            match entry {
                Entry::Area {
                    tris,
                    cdf,
                    area,
                    radiance,
                } => {
                    if *area <= 0.0 {
                        continue;
                    }
                    let (k, ua) = if tris.len() <= REUSE_MAX_TRIANGLES {
                        pick_and_rescale(cdf, u_point)
                    } else {
                        // the fractional part of the selection number
                        let ut = (sel - e as f32).clamp(0.0, 1.0 - f32::EPSILON);
                        (pick_and_rescale(cdf, ut).0, u_point)
                    };
                    prim[i] = tris[k];
                    (bu[i], bv[i]) = uniform_in_triangle(ua, u1.lane(i));
                    pdf[i] = p_sel / area;
                    radiance_rgb[i] = *radiance;
                    inv_pdf[i] = 1.0 / pdf[i];
                    on_surface[i] = true;
                    valid[i] = true;
                }
                Entry::Point { position, intensity } => {
                    point[i] = *position;
                    radiance_rgb[i] = *intensity;
                    inv_pdf[i] = 1.0 / p_sel;
                    valid[i] = true;
                }
                Entry::Laser { spot: Some(s) } => {
                    prim[i] = s.prim;
                    bu[i] = s.u;
                    bv[i] = s.v;
                    pre[i] = if scan.is_none_or(|(sc, _)| sc.laser_leg) {
                        s.distance
                    } else {
                        0.0
                    };
                    side[i] = s.side;
                    radiance_rgb[i] = s.intensity;
                    inv_pdf[i] = 1.0 / p_sel;
                    laser[i] = true;
                    laser_o[i] = s.origin;
                    laser_d[i] = s.direction;
                    per_power[i] = s.intensity_per_power;
                    on_surface[i] = true;
                    valid[i] = true;
                }
                Entry::Laser { spot: None } => {}
            }
        }
        let surf: SurfacePoint<R> = surface_at(ctx, &prim, R::Value::from_lanes(&bu), R::Value::from_lanes(&bv));
        let mut p64 = [glam::DVec3::ZERO; 8];
        let mut pre64 = [0.0f64; 8];
        if ctx.opl.f64_paths {
            for i in 0..R::LANES {
                if !valid[i] {
                    continue;
                }
                p64[i] = if on_surface[i] {
                    super::opl::point64(ctx, prim[i], bu[i], bv[i])
                } else {
                    point[i].as_dvec3()
                };
                if laser[i] && pre[i] != 0.0 {
                    pre64[i] = (p64[i] - laser_o[i].as_dvec3()).length();
                }
            }
        }
        let has_cos = R::Mask::from_bools(&on_surface[..R::LANES]);
        let mut p = V3::select(has_cos, surf.p, V3::from_lane_vecs(&point[..R::LANES]));
        let mut pre_length = R::from_lanes(&pre);
        let is_laser = R::Mask::from_bools(&laser[..R::LANES]);
        if R::DERIVS > 0 && is_laser.any() {
            // The spot is where the fixed laser ray meets the moving surface (ray form).
            let o = V3::<R>::from_lane_vecs(&laser_o[..R::LANES]);
            let d = V3::<R>::from_lane_vecs(&laser_d[..R::LANES]);
            let spot = ray_plane_point(&o, &d, &surf.p, &surf.n);
            p = V3::select(is_laser, spot, p);
            let counted = R::Value::from_lanes(&pre).gt(R::Value::zero());
            pre_length = R::select(is_laser & counted, (spot - o).dot(d), pre_length);
        }
        let mut radiance = Spectrum::<R, C>::from_lane_rgb(&radiance_rgb[..R::LANES]);
        if R::DERIVS > 0 {
            ctx.motion.radiance_derivs(&emitter, &mut radiance);
            if is_laser.any() {
                laser_intensity_derivs(ctx, &prim, &radiance_rgb, &per_power, is_laser, &mut radiance);
            }
        }
        // area samples move with their surface (material form): weight · J
        let area = has_cos & !is_laser;
        let scale = R::from_lanes(&inv_pdf) * R::select(area, surf.jacobian, R::one());
        LightSample {
            p,
            n: surf.n * R::from_lanes(&side),
            has_cos,
            weight: radiance.scale(scale),
            pdf_area: R::Value::from_lanes(&pdf),
            emitter,
            pre_length,
            valid: R::Mask::from_bools(&valid[..R::LANES]),
            p64,
            pre64,
        }
    }
}

/// A laser spot's intensity I = Φ·ρ/π in derivative form: `radiance_derivs` gave the power
/// parameter ∂I/∂Φ = 1, which is ρ/π here, and the albedo ρ of the lit surface scales I too
/// (∂I/∂ρ = I/ρ). Lanes outside `is_laser` are left alone.
fn laser_intensity_derivs<R: Real, const C: usize>(
    ctx: &RenderContext,
    prim: &[u32; 8],
    intensity: &[[f32; 3]; 8],
    per_power: &[[f32; 3]; 8],
    is_laser: R::Mask,
    radiance: &mut Spectrum<R, C>,
) {
    let value = Spectrum::<R, C>::from_lane_rgb(&intensity[..R::LANES]);
    let slope = Spectrum::<R, C>::from_lane_rgb(&per_power[..R::LANES]);
    let albedo = super::bsdf::albedo::<R, C>(ctx, prim);
    for c in 0..C {
        // (radiance − value) carries only the power derivative (1); rescale it to ρ/π
        let power_part = (radiance.0[c] - value.0[c]) * slope.0[c];
        let albedo_ratio = R::safe_div(albedo.0[c], R::from_value(albedo.0[c].value()));
        let laser = (value.0[c] + power_part) * albedo_ratio;
        radiance.0[c] = R::select(is_laser, laser, radiance.0[c]);
    }
}
