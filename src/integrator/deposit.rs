//! One lane's contribution on its way to a film: its value, derivatives and OPL pulled out
//! of the SIMD registers once, checked for finiteness, then added to one or more pixels.
//!
//! A pulse-offset parameter τ of the lane's emitter shifts S_e(d + τ), so it adds
//! ∂d/∂τ = 1 to the OPL derivative (see `temporal.rs`).
//!
//! [`PathCounts`]: the per-packet tallies every estimator keeps (rays, dropped non-finite
//! samples, film time).

use super::context::RenderContext;
use super::trace::RayCounts;
use crate::film::Accumulate;
use crate::kernel::{Real, Spectrum};
use crate::params::MAX_PARAMS;

/// A finite contribution of one lane: f (per channel), ḟ, d and ḋ.
#[derive(Clone, Copy, Debug)]
pub struct LaneContribution<const C: usize> {
    pub emitter: u32,
    /// The OPL: the lane's f64 value when the path carried one (`super::opl`), else its f32
    /// value widened.
    pub d: f64,
    pub f: [f32; C],
    /// ḟ_k per channel: `fdot[k * C + c]` (at most 3 channels).
    pub fdot: [f32; MAX_PARAMS * 3],
    pub ddot: [f32; MAX_PARAMS],
    pub n_k: usize,
    /// Only the time term f·Ṡ_e·ḋ_k goes to the film (a draw on the time edges,
    /// `super::time_edge_nee`): no value, no ḟ.
    pub time_only: bool,
    /// For a time-only draw of a delta pulse: the film edge it lies on (Ṡ_e is a Dirac
    /// there: +f·ḋ_k to the bin after the edge, −f·ḋ_k to the bin before).
    pub edge: Option<u32>,
}

impl<const C: usize> LaneContribution<C> {
    /// Lane `i` of (`d`, `contrib`) from `emitter`, with the OPL value taken from `exact`
    /// (f64 per lane) when given, its derivatives from `d`. `None` when the lane is not finite
    /// (the caller counts it and drops it, never writing it to the film).
    pub fn extract<R: Real>(
        ctx: &RenderContext,
        emitter: u32,
        d: R,
        exact: Option<&[f64; 8]>,
        contrib: &Spectrum<R, C>,
        i: usize,
    ) -> Option<Self> {
        let f: [f32; C] = std::array::from_fn(|c| contrib.0[c].lane(i));
        let di = exact.map_or(d.lane(i) as f64, |e| e[i]);
        let mut finite = di.is_finite() && f.iter().all(|v| v.is_finite());
        let n_k = R::DERIVS.min(ctx.motion.len()).min(MAX_PARAMS);
        let mut fdot = [0.0f32; MAX_PARAMS * 3];
        let mut ddot = [0.0f32; MAX_PARAMS];
        for k in 0..n_k {
            for c in 0..C {
                fdot[k * C + c] = contrib.0[c].deriv_lane(k, i);
                finite &= fdot[k * C + c].is_finite();
            }
            let shift = if ctx.motion.pulse_offset[k] == Some(emitter as usize) {
                1.0
            } else {
                0.0
            };
            ddot[k] = d.deriv_lane(k, i) + shift;
            finite &= ddot[k].is_finite();
        }
        finite.then_some(Self {
            emitter,
            d: di,
            f,
            fdot,
            ddot,
            n_k,
            time_only: false,
            edge: None,
        })
    }

    /// Whether nothing would reach the film (zero value and no derivative lanes).
    pub fn is_empty(&self) -> bool {
        self.n_k == 0 && self.f.iter().all(|&v| v == 0.0)
    }

    /// Adds h·f to pixel (x, y) of `film`, and h·ḟ_k to derivative k (the pixel weight h is a
    /// constant: film points never move); a time-only contribution adds h·f·Ṡ_e·ḋ_k alone.
    pub fn add_to<A: Accumulate>(&self, ctx: &RenderContext, film: &mut A, x: usize, y: usize, h: f32) {
        let corr = &ctx.correlations[self.emitter as usize];
        let f: [f32; C] = self.f.map(|v| v * h);
        if self.time_only {
            match self.edge {
                Some(j) => film.add_edge_term(x, y, j as usize, corr.axis().bins, &f, &self.ddot[..self.n_k]),
                None => film.add_time_term(x, y, corr, self.d, &f, &self.ddot[..self.n_k]),
            }
            return;
        }
        if self.n_k == 0 {
            film.add(x, y, corr, self.d, &f);
            return;
        }
        let mut fdot = [0.0f32; MAX_PARAMS * 3];
        for (o, &v) in fdot.iter_mut().zip(&self.fdot[..self.n_k * C]) {
            *o = v * h;
        }
        film.add_with_derivs(x, y, corr, self.d, &f, &fdot[..self.n_k * C], &self.ddot[..self.n_k]);
    }
}

/// Per-packet tallies.
#[derive(Clone, Copy, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct PathCounts {
    pub rays: RayCounts,
    /// Samples dropped because they were not finite (reported, never written to the film).
    pub non_finite: u64,
    /// Ticks spent adding contributions to the film (binning through S_e; sampled by
    /// `film_clock`).
    pub film_ticks: u64,
    /// Which film deposits read the counter (not part of a tally).
    #[serde(skip)]
    pub film_clock: crate::timing::SampledClock,
    /// Ticks spent in the whole tile (set by the render driver).
    pub total_ticks: u64,
}

impl PathCounts {
    /// Adds another unit's tallies.
    pub fn add(&mut self, o: &PathCounts) {
        self.rays.intersect += o.rays.intersect;
        self.rays.occluded += o.rays.occluded;
        self.rays.trace_ticks += o.rays.trace_ticks;
        self.non_finite += o.non_finite;
        self.film_ticks += o.film_ticks;
        self.total_ticks += o.total_ticks;
    }
}

/// Pulls every lane of `mask` with an emitter out of (`d` or `exact`, `contrib`) and hands the finite,
/// non-empty ones to `add(lane, contribution)`; non-finite lanes are counted in `counts` and
/// dropped. The time spent is counted as film time.
#[allow(clippy::too_many_arguments)]
pub fn for_each_lane<R: Real, const C: usize>(
    ctx: &RenderContext,
    emitter: &[u32; 8],
    d: R,
    exact: Option<&[f64; 8]>,
    contrib: &Spectrum<R, C>,
    mask: R::Mask,
    counts: &mut PathCounts,
    mut add: impl FnMut(usize, &LaneContribution<C>),
) {
    let t0 = counts.film_clock.start();
    for i in 0..R::LANES {
        if !crate::kernel::Mask::bit(mask, i) || emitter[i] == u32::MAX {
            continue;
        }
        match LaneContribution::<C>::extract(ctx, emitter[i], d, exact, contrib, i) {
            Some(lc) if !lc.is_empty() => add(i, &lc),
            Some(_) => {}
            None => counts.non_finite += 1,
        }
    }
    counts.film_ticks += counts.film_clock.stop(t0);
}
