//! Bidirectional transient path tracing with multiple importance sampling: the interior
//! estimator of Algorithm 1 (supplemental §2.4), eight paths per packet, written once for
//! `f32`, `f32x8` and `Dual8<P>`.
//!
//! Per lane, a camera subpath (from the lane's pixel) and a light subpath (from a sampled
//! emitter) are traced ([`walk`]); then every strategy (s, t) with s + t − 2 ≤ max_bounces
//! joins their vertices:
//! - s = 0: the camera subpath found an emitter ([`connect::emission`]);
//! - s ≥ 1, t ≥ 2: a shadow ray between the two ends ([`connect::connect`]; s = 1 is NEE);
//! - t = 1: the light vertex seen by the pinhole, splatted wherever it lands
//!   ([`splat::splat_to_camera`]).
//!
//! In an NLOS capture each film cell is a (sensor point, laser point) pair: the camera
//! subpath starts at the sensor point and the light subpath at the laser point ([`walk`]),
//! and t = 1 joins the light vertex to that sensor point ([`sensor::connect_to_sensor`]);
//! every vertex is then in material form.
//!
//! Each contribution is weighted by the power heuristic over all strategies of its path
//! ([`mis`], Veach 1997 Eq. 9.13 and §10.2), binned at its OPL d with S_e, and differentiated
//! as I += w·f·s, İ += w·(ḟ·s + f·Ṡ_e·ḋ) (Algorithm 1), the weight w a constant.
//!
//! **One parameterisation.** Every strategy moves the vertex next to the pinhole along its
//! fixed camera ray and every other vertex with its surface (t = 1 included, see [`splat`]),
//! so constant MIS weights give the derivative of the image, for any pixel filter. A Dirac
//! lobe breaks that (the camera side would move the vertex after it in ray form, the light
//! side the one before it), so through one only parameters that move no vertex are
//! differentiated (`render::check_materials`), with the lobe's weight in dual numbers.
//!
//! (1, 1), an emitter seen straight through the pinhole by light tracing, is left out: s = 0
//! covers area emitters (as in the path tracer), and points (point lights, laser spots) are
//! not seen directly by either integrator.

pub mod connect;
pub mod film;
pub mod mis;
pub mod sensor;
pub mod splat;
pub mod units;
pub mod vertex;
pub mod walk;

use super::context::RenderContext;
use super::deposit::{PathCounts, for_each_lane};
use super::path::PacketLanes;
use super::sink::Sink;
use crate::kernel::{PathSampler, Real, Spectrum};
use vertex::Vertex;
use walk::LightOrigin;

/// Seed stream of the light subpaths (the camera subpaths use the render seed), so the two
/// subpaths of a lane are independent.
const LIGHT_STREAM: u64 = 0x6C69_6768_745F_7375;

/// Vertex and density buffers reused from packet to packet.
pub struct Scratch<R: Real, const C: usize> {
    camera: Vec<Vertex<R, C>>,
    light: Vec<Vertex<R, C>>,
    pl: Vec<R::Value>,
    pe: Vec<R::Value>,
    no_connect: Vec<R::Mask>,
}

impl<R: Real, const C: usize> Default for Scratch<R, C> {
    fn default() -> Self {
        Self {
            camera: Vec::new(),
            light: Vec::new(),
            pl: Vec::new(),
            pe: Vec::new(),
            no_connect: Vec::new(),
        }
    }
}

/// One packet's state while its strategies run; contributions go to `sink`.
pub struct Packet<'p, 'c, R: Real, const C: usize, S: Sink<C>> {
    pub ctx: &'p RenderContext<'c>,
    pub lanes: &'p PacketLanes,
    pub camera: &'p [Vertex<R, C>],
    pub light: &'p [Vertex<R, C>],
    pub origin: LightOrigin<R>,
    pub pl: &'p mut Vec<R::Value>,
    pub pe: &'p mut Vec<R::Value>,
    /// Per path vertex, the lanes where no connection can end (`mis::allowed_through`).
    pub no_connect: &'p mut Vec<R::Mask>,
    pub sink: &'p mut S,
    pub counts: &'p mut PathCounts,
}

impl<R: Real, const C: usize, S: Sink<C>> Packet<'_, '_, R, C, S> {
    /// For a t = 1 strategy (light vertex s − 1 joined to the camera subpath's vertex 0),
    /// Σ (p_{s'} / p_s)² over the strategies with fewer light vertices, given the camera's
    /// area density `camera_pdf` at that light vertex (no strategy has more: t ≥ 1).
    pub fn light_tracing_ratios(&mut self, s: usize, camera_pdf: R::Value) -> R::Value {
        mis::path_pdfs(
            Some(self.ctx),
            &self.light[..s],
            &self.camera[..1],
            R::Value::zero(),
            camera_pdf,
            self.pl,
            self.pe,
            self.no_connect,
        );
        let (delta, n) = (self.origin.delta, s + 1);
        let no_connect = &*self.no_connect;
        let (lower, _) = mis::ratio_sums(self.pl, self.pe, s, |sp| mis::allowed_through(n, sp, delta, no_connect));
        lower
    }

    /// Adds each lane's contribution to its own pixel (strategies with t ≥ 2).
    pub fn deposit_own_pixels(
        &mut self,
        strategy: (usize, usize),
        emitter: &[u32; 8],
        d: R,
        exact: Option<&[f64; 8]>,
        contrib: &Spectrum<R, C>,
        mask: R::Mask,
    ) {
        let (ctx, lanes, sink) = (self.ctx, self.lanes, &mut *self.sink);
        for_each_lane(ctx, emitter, d, exact, contrib, mask, self.counts, |i, lc| {
            let (x, y) = (lanes.px[i] as usize, lanes.py[i] as usize);
            sink.add(ctx, strategy, x, y, lc, 1.0);
        });
    }
}

/// Traces one camera and one light subpath per lane and hands every strategy's weighted
/// contribution (and derivatives) to `sink`.
pub fn trace_packet<R: Real, const C: usize, S: Sink<C>>(
    ctx: &RenderContext,
    seed: u64,
    lanes: &PacketLanes,
    sink: &mut S,
    counts: &mut PathCounts,
    scratch: &mut Scratch<R, C>,
) {
    let max_bounces = ctx.scene.integrator.max_bounces as usize;
    let ids = &lanes.ids[..lanes.count.max(1)];
    let sequence = ctx.scene.integrator.sampler;
    let mut cam_sampler = PathSampler::with_sequence(sequence, seed, ids, lanes.spp);
    let mut light_sampler = PathSampler::with_sequence(sequence, seed ^ LIGHT_STREAM, ids, lanes.spp);
    let Scratch {
        camera,
        light,
        pl,
        pe,
        no_connect,
    } = scratch;
    walk::camera_subpath(ctx, &mut cam_sampler, lanes, camera, max_bounces + 1, &mut counts.rays);
    let origin = walk::light_subpath(ctx, &mut light_sampler, lanes, light, max_bounces, &mut counts.rays);
    let mut pk = Packet {
        ctx,
        lanes,
        camera,
        light,
        origin,
        pl,
        pe,
        no_connect,
        sink,
        counts,
    };
    for t in 1..=pk.camera.len() {
        for s in 0..=pk.light.len() {
            if s + t < 2 || s + t - 2 > max_bounces || (s, t) == (1, 1) {
                continue;
            }
            match (s, t) {
                (0, _) => connect::emission(&mut pk, t),
                (_, 1) if ctx.nlos.is_some() => sensor::connect_to_sensor(&mut pk, s),
                (_, 1) => splat::splat_to_camera(&mut pk, s),
                _ => connect::connect(&mut pk, s, t),
            }
        }
    }
}

/// The samples `samples` (of `spp` per pixel) of the tiles `tiles` (x0, y0 of each
/// `tile`-sized tile), in order, into one sink (a unit's films, `film::BdptFilm`, or the
/// adjoint's): the BDPT counterpart of the path tracer's per-tile loop.
#[allow(clippy::too_many_arguments)]
pub fn render_tiles<R: Real, const C: usize, S: Sink<C>>(
    ctx: &RenderContext,
    seed: u64,
    spp: u32,
    samples: &std::ops::Range<u64>,
    tiles: &[(usize, usize)],
    tile: usize,
    film: &mut S,
    counts: &mut PathCounts,
) {
    let (w, h) = (ctx.scene.film.width as usize, ctx.scene.film.height as usize);
    let mut scratch = Scratch::<R, C>::default();
    for &(x0, y0) in tiles {
        let (tw, th) = (tile.min(w - x0), tile.min(h - y0));
        for s in samples.clone() {
            if ctx.cancel.is_cancelled() {
                return;
            }
            for ty in 0..th {
                let mut x = 0;
                while x < tw {
                    let n = R::LANES.min(tw - x);
                    let lanes = PacketLanes::row(x0 + x, y0 + ty, n, w, spp, s);
                    trace_packet::<R, C, _>(ctx, seed, &lanes, film, counts, &mut scratch);
                    x += n;
                }
            }
        }
    }
}
