//! Where BDPT contributions go: a full-frame film per chunk of tiles (light-tracing splats
//! land on any pixel), and optionally one film per (s, t) strategy (pbrt-v4's
//! `visualizeStrategies`, for transients).

use crate::film::TileFilm;
use crate::integrator::context::RenderContext;
use crate::integrator::deposit::LaneContribution;

/// Every (s, t) strategy of paths with at most `max_bounces` bounces (s + t − 2 ≤ max), in
/// the order they are written: by path length, then by t. Left out: (1, 1), the light seen
/// directly through the pinhole, which the s = 0 strategy covers as the path tracer does.
pub fn strategy_list(max_bounces: u32) -> Vec<(usize, usize)> {
    let mut out = Vec::new();
    for n in 2..=max_bounces as usize + 2 {
        for t in 1..=n {
            let s = n - t;
            if (s, t) != (1, 1) {
                out.push((s, t));
            }
        }
    }
    out
}

/// The films of one chunk of tiles.
pub struct BdptFilm {
    pub film: TileFilm,
    /// One primal film per strategy of [`strategy_list`] (empty unless requested).
    pub strategies: Vec<TileFilm>,
    /// Index into `strategies` of (s, t) at `s * stride + t`.
    index: Vec<usize>,
    stride: usize,
}

impl BdptFilm {
    /// A full-frame film of `ctx`'s render with `derivs` derivative blocks, and one film per
    /// (s, t) strategy when `per_strategy`.
    pub fn new(ctx: &RenderContext, derivs: usize, per_strategy: bool) -> Self {
        let f = &ctx.scene.film;
        let max_bounces = ctx.scene.integrator.max_bounces;
        let stride = max_bounces as usize + 3;
        let mut index = vec![usize::MAX; stride * stride];
        let mut strategies = Vec::new();
        if per_strategy {
            for (k, (s, t)) in strategy_list(max_bounces).into_iter().enumerate() {
                index[s * stride + t] = k;
                strategies.push(ctx.tile_film(0, 0, f.width as usize, f.height as usize, 0));
            }
        }
        Self {
            film: ctx.tile_film(0, 0, f.width as usize, f.height as usize, derivs),
            strategies,
            index,
            stride,
        }
    }

    /// Adds `lc` with pixel weight `h` to pixel (x, y), for strategy (s, t).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    pub fn add<const C: usize>(
        &mut self,
        ctx: &RenderContext,
        (s, t): (usize, usize),
        x: usize,
        y: usize,
        lc: &LaneContribution<C>,
        h: f32,
    ) {
        lc.add_to(ctx, &mut self.film, x, y, h);
        if !self.strategies.is_empty() {
            let k = self.index[s * self.stride + t];
            lc.add_to(ctx, &mut self.strategies[k], x, y, h);
        }
    }
}
