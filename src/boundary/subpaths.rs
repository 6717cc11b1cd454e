//! The two ends of a boundary path (Algorithm 2: EstimateSourceSubpath, EstimateSensorSubpath)
//! for up to eight boundary samples at once, on the interior's kernel: unbiased estimates of
//! the radiance leaving x_L towards x_S and of the importance arriving at x_S from x_L, each
//! split into terms with their own optical path length (so that S_e bins every full path at
//! its own d). Plain numbers, mono or RGB as the film is: the boundary stage differentiates
//! the visibility jump, not the subpaths.
//!
//! - The source side is the path tracer itself (`integrator::path`, `PathStart::Surface`):
//!   started at x_L as if a camera ray had arrived there against ω, with its next-event
//!   estimation, power-heuristic MIS (Veach 1997, Eq. 9.13) and BSDF sampling, and
//!   without x_L's own emission (strategy B of `secondary.rs` estimates that). A term of
//!   strategy (s, t) has t − 2 + s scattering vertices, x_L included.
//! - The sensor side is the importance walk (`integrator::importance`): x_S and each later
//!   vertex joined to the pinhole (in an NLOS capture, to the sample's sensor point, whose
//!   laser points the source side's next-event estimation ends at). When x_S is itself a
//!   sensor point (`SegmentSample::sensed`), that point's importance is the only sensor term.
//!
//! So a new BSDF or emitter reaches the boundary stage through the same code as the interior.
//! Optical path lengths are f64 when the render carries f64 OPLs (`integrator::opl`): each
//! segment is measured between points rebuilt in f64 from Embree's barycentrics, from x_L's
//! and x_S's f64 points on the boundary line.

use super::hit::SurfaceHit;
use crate::integrator::context::RenderContext;
use crate::integrator::deposit::{LaneContribution, PathCounts};
use crate::integrator::importance::trace_importance_packet;
use crate::integrator::path::{PacketLanes, PathStart, SurfaceStarts, trace_packet_from};
use crate::integrator::sink::Sink;
use glam::Vec3;
use wide::f32x8;

/// The first random dimension of the source subpath (past what the sampling of the boundary
/// ray draws).
const SOURCE_DIM: u64 = 1 << 8;
/// The first random dimension of the sensor subpath (far past what the source subpath draws,
/// so that ending the source side early changes no other number).
const SENSOR_DIM: u64 = 1 << 16;

/// One term of the source estimate: radiance `rgb` from `emitter` (channels past the film's
/// are 0), optical length `opl` from the emitter (pulse offsets excluded: S_e holds them) to
/// x_S (d_B included), `scatters` scattering vertices (x_L included when it reflects).
#[derive(Clone, Copy, Debug)]
pub struct SourceTerm {
    pub rgb: [f32; 3],
    pub opl: f64,
    pub emitter: u32,
    pub scatters: u32,
    /// The laser point it ends at in an exhaustive NLOS scan (the film's y), else 0.
    pub laser: u32,
}

/// One term of the sensor estimate: importance `rgb` (f_s·|cos|/r²·W_e without the pixel
/// filter) reaching film point (fx, fy), optical length `opl` from x_S to the camera,
/// `scatters` scattering vertices (x_S included; 1: x_S itself is joined to the camera, the
/// ray-form first vertex of Algorithm 1).
#[derive(Clone, Copy, Debug)]
pub struct SensorTerm {
    pub rgb: [f32; 3],
    pub opl: f64,
    pub fx: f32,
    pub fy: f32,
    pub scatters: u32,
}

/// A boundary sample whose segment x_L → x_S has been found: what its subpaths start from.
#[derive(Clone, Copy, Debug)]
pub struct SegmentSample {
    /// Path id of the sample in its strategy's stream.
    pub id: u64,
    pub x_l: SurfaceHit,
    pub x_s: SurfaceHit,
    /// Direction of the segment, x_L → x_S.
    pub omega: Vec3,
    /// Index of the medium the segment crosses (`integrator::medium`), where both subpaths
    /// start.
    pub eta: f32,
    /// OPL of the segment, η·|x_S − x_L|.
    pub d_b: f64,
    /// x_L's emission when it is a light sample (strategy B): its only source term. None: x_L
    /// reflects, and the source subpath estimates its radiance.
    pub emitted: Option<SourceTerm>,
    /// x_L's own emission where strategy A found x_L on an emitter and takes that term
    /// (`secondary::EmissionSplit`): a source term beside the source subpath's.
    pub also_emitted: Option<SourceTerm>,
    /// x_S's importance when it is a sensor point of an NLOS capture (the sensor-directed
    /// draws of strategy B): its only sensor term. None: the importance walk from x_S.
    pub sensed: Option<SensorTerm>,
    /// In an NLOS capture, the sensor point the sample's sensor side ends at (both subpaths
    /// pair with it: the source side's next-event estimation goes to its laser points).
    pub sensor: usize,
    /// x_L is a laser point at the sensor point x_S's walk ends at (a confocal scan): the
    /// connection of x_S to it runs back along the segment, over the edge, and is taken
    /// unblocked (`secondary::Secondary::complete` explains why).
    pub retro: bool,
}

/// Per-lane term lists, kept between packets to reuse their memory.
#[derive(Default)]
pub struct Terms {
    pub source: [Vec<SourceTerm>; 8],
    pub sensor: [Vec<SensorTerm>; 8],
}

/// Collects the source kernel's contributions per lane (film x = lane).
struct SourceSink<'a>(&'a mut [Vec<SourceTerm>; 8]);

impl<const C: usize> Sink<C> for SourceSink<'_> {
    fn add(&mut self, _: &RenderContext, (s, t): (usize, usize), x: usize, y: usize, lc: &LaneContribution<C>, _: f32) {
        let mut rgb = [0.0f32; 3];
        rgb[..C].copy_from_slice(&lc.f);
        self.0[x].push(SourceTerm {
            rgb,
            opl: lc.d,
            emitter: lc.emitter,
            scatters: (t + s - 2) as u32,
            laser: y as u32,
        });
    }
}

/// The source and sensor terms of `group` (at most 8 samples, all of one strategy and
/// stream `seed`) into `terms`, lane i for `group[i]`. The sensor side of each lane walks at
/// most max_bounces − (fewest scatters of its source terms) vertices, from the OPL of its
/// shortest source term (the window cut). Film channels C.
pub fn subpaths<const C: usize>(
    ctx: &RenderContext,
    seed: u64,
    group: &[SegmentSample],
    counts: &mut PathCounts,
    terms: &mut Terms,
) {
    let n = group.len();
    debug_assert!(n <= 8);
    let max_bounces = ctx.scene.integrator.max_bounces;
    for i in 0..8 {
        terms.source[i].clear();
        terms.sensor[i].clear();
    }
    let mut ids = [0u64; 8];
    for (o, s) in ids.iter_mut().zip(group) {
        *o = s.id;
    }
    if group.iter().all(|s| s.emitted.is_some()) {
        for (i, s) in group.iter().enumerate() {
            terms.source[i].extend(s.emitted);
        }
    } else {
        debug_assert!(group.iter().all(|s| s.emitted.is_none()));
        // x_S scatters unless it is a sensor point
        let sensor_scatters = u32::from(group.iter().all(|s| s.sensed.is_none()));
        let starts = starts(
            group,
            |s| (s.x_l, s.omega, s.d_b),
            max_bounces.saturating_sub(sensor_scatters),
            SOURCE_DIM,
        );
        let lanes = PacketLanes {
            px: std::array::from_fn(|i| i as u32),
            py: [0; 8],
            ids,
            count: n,
            spp: 0,
        };
        let mut sink = SourceSink(&mut terms.source);
        trace_packet_from::<f32x8, C, _>(ctx, seed, &lanes, PathStart::Surface(&starts), &mut sink, counts);
        for (i, s) in group.iter().enumerate() {
            terms.source[i].extend(s.also_emitted);
        }
    }
    let mut limit = [0u32; 8];
    let mut from = [0.0f64; 8];
    for i in 0..n {
        let src = &terms.source[i];
        if let Some(fewest) = src.iter().map(|t| t.scatters).min() {
            limit[i] = max_bounces.saturating_sub(fewest);
            from[i] = src.iter().map(|t| t.opl).fold(f64::INFINITY, f64::min);
        }
    }
    if group.iter().all(|s| s.sensed.is_some()) {
        for (i, s) in group.iter().enumerate() {
            terms.sensor[i].extend(s.sensed);
        }
        return;
    }
    debug_assert!(group.iter().all(|s| s.sensed.is_none()));
    let mut starts = starts(group, |s| (s.x_s, -s.omega, 0.0), 0, SENSOR_DIM);
    starts.opl = from;
    let sensor = &mut terms.sensor;
    trace_importance_packet::<f32x8, C>(ctx, seed, &ids[..n], &starts, &limit, counts, |i, t| {
        let mut rgb = [0.0f32; 3];
        rgb[..C].copy_from_slice(&t.value);
        sensor[i].push(SensorTerm {
            rgb,
            opl: t.opl,
            fx: t.fx,
            fy: t.fy,
            scatters: t.scatters,
        });
    });
}

/// Start points of `group` from `pick(sample) = (point, direction light leaves it in, OPL so
/// far)`.
fn starts(
    group: &[SegmentSample],
    pick: impl Fn(&SegmentSample) -> (SurfaceHit, Vec3, f64),
    max_scatters: u32,
    dim: u64,
) -> SurfaceStarts {
    let mut st = SurfaceStarts {
        prim: [0; 8],
        p: [Vec3::ZERO; 8],
        p64: [glam::DVec3::ZERO; 8],
        n: [Vec3::Z; 8],
        out: [Vec3::Z; 8],
        eta: [1.0; 8],
        opl: [0.0; 8],
        max_scatters,
        dim,
        sensor: [0; 8],
        unblocked_first: [false; 8],
    };
    for (i, s) in group.iter().enumerate() {
        let (h, out, opl) = pick(s);
        st.prim[i] = h.prim;
        st.p[i] = h.p;
        st.p64[i] = h.p64;
        st.n[i] = h.n;
        st.out[i] = out;
        st.eta[i] = s.eta;
        st.opl[i] = opl;
        st.sensor[i] = s.sensor;
        st.unblocked_first[i] = s.retro;
    }
    st
}
