//! Where BDPT contributions go. A unit of work (a tile and a block of samples,
//! `super::units`) has a film of its own tile, and optionally one per (s, t) strategy
//! (pbrt-v4's `visualizeStrategies`, for transients). Light-tracing splats (t = 1) land on
//! any pixel: those outside the tile are kept as splats, by film row, until the driver
//! adds every unit's tile and splats to the full-frame rows in unit order. So no film is
//! shared between workers, any number of threads runs the units, and the bytes do not depend
//! on how many did.

use crate::film::TileFilm;
use crate::integrator::context::RenderContext;
use crate::integrator::deposit::LaneContribution;
use crate::params::MAX_PARAMS;
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

/// A contribution that fell outside its unit's tile: pixel column, strategy, filter weight
/// and the contribution without its derivatives, which its row's `derivs` hold from
/// `derivs_at` on (ḟ then ḋ, `n_k`·C + `n_k` values), so a primal splat takes 48 bytes.
#[derive(Clone, Copy, Debug)]
struct Splat {
    x: u32,
    strategy: (u16, u16),
    h: f32,
    emitter: u32,
    d: f64,
    f: [f32; 3],
    n_k: u8,
    time_only: bool,
    edge: Option<u32>,
    derivs_at: u32,
}

/// The splats of one unit that land on one film row.
#[derive(Clone, Debug, Default)]
struct Row {
    splats: Vec<Splat>,
    derivs: Vec<f32>,
}

impl Row {
    fn push<const C: usize>(&mut self, strategy: (usize, usize), x: usize, lc: &LaneContribution<C>, h: f32) {
        let n_k = lc.n_k;
        self.splats.push(Splat {
            x: x as u32,
            strategy: (strategy.0 as u16, strategy.1 as u16),
            h,
            emitter: lc.emitter,
            d: lc.d,
            f: std::array::from_fn(|c| if c < C { lc.f[c] } else { 0.0 }),
            n_k: n_k as u8,
            time_only: lc.time_only,
            edge: lc.edge,
            derivs_at: self.derivs.len() as u32,
        });
        self.derivs.extend_from_slice(&lc.fdot[..n_k * C]);
        self.derivs.extend_from_slice(&lc.ddot[..n_k]);
    }

    /// Splat `sp` as the contribution it was made from.
    fn contribution<const C: usize>(&self, sp: &Splat) -> LaneContribution<C> {
        let (n_k, at) = (sp.n_k as usize, sp.derivs_at as usize);
        let mut fdot = [0.0f32; MAX_PARAMS * 3];
        let mut ddot = [0.0f32; MAX_PARAMS];
        fdot[..n_k * C].copy_from_slice(&self.derivs[at..at + n_k * C]);
        ddot[..n_k].copy_from_slice(&self.derivs[at + n_k * C..at + n_k * C + n_k]);
        LaneContribution {
            emitter: sp.emitter,
            d: sp.d,
            f: std::array::from_fn(|c| sp.f[c]),
            fdot,
            ddot,
            n_k,
            time_only: sp.time_only,
            edge: sp.edge,
        }
    }

    fn clear(&mut self) {
        self.splats.clear();
        self.derivs.clear();
    }
}

/// The films of one unit of work (a tile), or of one full-frame row the units are added to.
pub struct BdptFilm {
    pub film: TileFilm,
    /// One primal film per strategy of [`strategy_list`] (empty unless requested).
    pub strategies: Vec<TileFilm>,
    /// Index into `strategies` of (s, t) at `s * stride + t`.
    index: Vec<usize>,
    stride: usize,
    /// Contributions outside `film`'s rectangle, by film row (a unit's; a row film has none).
    outside: Vec<Row>,
}

impl BdptFilm {
    /// Films of the rectangle (x0, y0, w, h) of `ctx`'s render with `derivs` derivative
    /// blocks, and one film per (s, t) strategy when `per_strategy`. `keeps_outside`: a unit's
    /// film, which keeps what lands outside its rectangle (a row film receives only its own).
    pub fn new(
        ctx: &RenderContext,
        (x0, y0, w, h): (usize, usize, usize, usize),
        derivs: usize,
        per_strategy: bool,
        keeps_outside: bool,
    ) -> Self {
        let max_bounces = ctx.scene.integrator.max_bounces;
        let stride = max_bounces as usize + 3;
        let mut index = vec![usize::MAX; stride * stride];
        let mut strategies = Vec::new();
        if per_strategy {
            for (k, (s, t)) in strategy_list(max_bounces).into_iter().enumerate() {
                index[s * stride + t] = k;
                strategies.push(ctx.tile_film(x0, y0, w, h, 0));
            }
        }
        let rows = if keeps_outside {
            ctx.scene.film.height as usize
        } else {
            0
        };
        Self {
            film: ctx.tile_film(x0, y0, w, h, derivs),
            strategies,
            index,
            stride,
            outside: vec![Row::default(); rows],
        }
    }

    /// Empties the films and moves them to another rectangle of the same size or smaller,
    /// reusing their memory.
    pub fn reset(&mut self, (x0, y0, w, h): (usize, usize, usize, usize)) {
        self.film.reset(x0, y0, w, h);
        self.strategies.iter_mut().for_each(|f| f.reset(x0, y0, w, h));
        self.outside.iter_mut().for_each(Row::clear);
    }

    /// Adds `lc` with pixel weight `h` to pixel (x, y), for strategy (s, t): to the films when
    /// the pixel is theirs, else kept for the driver.
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
        let f = &self.film;
        if !(f.x0..f.x0 + f.w).contains(&x) || !(f.y0..f.y0 + f.h).contains(&y) {
            self.outside[y].push((s, t), x, lc, h);
            return;
        }
        lc.add_to(ctx, &mut self.film, x, y, h);
        if !self.strategies.is_empty() {
            let k = self.index[s * self.stride + t];
            lc.add_to(ctx, &mut self.strategies[k], x, y, h);
        }
    }

    /// Adds a unit's films where they overlap this row film's rows, then the unit's splats on
    /// them, in the order the unit made them (supplemental Eq. 21's sum over paths, one unit
    /// after another: the same order whoever ran the unit).
    pub fn add_unit<const C: usize>(&mut self, ctx: &RenderContext, unit: &BdptFilm) {
        self.film.add_film(&unit.film);
        for (mine, theirs) in self.strategies.iter_mut().zip(&unit.strategies) {
            mine.add_film(theirs);
        }
        for y in self.film.y0..self.film.y0 + self.film.h {
            let row = &unit.outside[y];
            for sp in &row.splats {
                let lc = row.contribution::<C>(sp);
                let strategy = (sp.strategy.0 as usize, sp.strategy.1 as usize);
                self.add(ctx, strategy, sp.x as usize, y, &lc, sp.h);
            }
        }
    }

    /// Splats this unit keeps for other pixels.
    pub fn outside_splats(&self) -> usize {
        self.outside.iter().map(|r| r.splats.len()).sum()
    }
}
