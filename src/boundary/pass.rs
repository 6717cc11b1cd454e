//! The secondary-edge pass: a pilot, then the boundary samples in parallel chunks, binned into
//! one derivative film in a fixed order.
//!
//! The pilot runs both strategies of `secondary.rs` on a stream of its own and learns
//! - how to split the budget between them: for independent unbiased estimators summed, the
//!   variance per unit cost is lowest with n_s ∝ σ_s / √c_s (σ_s: root second moment of a
//!   sample's total |contribution|, c_s: rays per sample); each strategy keeps at least 1/8 of
//!   the budget, so neither is ever starved (any n_s ≥ 1 keeps the sum unbiased);
//! - with guiding on, a grid of `guiding.rs` for each strategy: over (edge coordinate,
//!   azimuth, cos θ) for the edge-directed rays, over (edge coordinate, the two numbers of the
//!   point on the emitter) for the light-directed ones;
//! - with guiding off, how often to draw each shape's edges, per strategy: a shape's share
//!   of the edge table's probability P_s becomes q_s = (1 − α)·r_s / Σ_t r_t + α·P_s with
//!   r_s = √(M_s / c_s). M_s is the second moment the shape's edges contribute per sample
//!   (estimated as P_s/N · Σ over the pilot samples on its edges of Σ over their paths of
//!   |contribution|²) and c_s the rays a sample on them costs (its own rays, counted, plus
//!   the pilot's mean subpath rays per sample that reached the subpaths); r_s ∝ √(M_s/c_s)
//!   minimises the variance of a sum over shapes times its cost, Σ_s M_s/q_s · Σ_s q_s c_s.
//!   α = `EDGE_PRIOR_SHARE` (0.25) keeps the table's own weights (length, silhouette fraction,
//!   motion: `secondary.rs`) as a defensive part, so no shape's edges are starved. Within a
//!   shape the edges keep their relative weights: a pilot of thousands of samples says
//!   little about each of a mesh's thousands of edges, but much about which shapes' edges
//!   matter.
//!
//! `samples` boundary samples stand for 2·samples strategy evaluations, split as above.

use super::edge_sampler::EdgeSampler;
use super::guiding::{GuideGrid, RESOLUTION, UNIFORM_MIX};
use super::secondary::{BoundaryPath, EmissionSplit, LIGHT_STREAM, Prepared, Scratch, Secondary};
use super::{BoundarySettings, SECONDARY_SEED};
use crate::film::{TileFilm, Transient};
use crate::params::MAX_PARAMS;
use rayon::prelude::*;
use std::time::Instant;

/// Strategy evaluations per work unit (fixed, so results do not depend on the thread count).
const CHUNK: u64 = 4096;
/// Stream of the pilot pass, relative to the pass's seed.
const PILOT_STREAM: u64 = 0x7049_1A7B_0000_0001;
/// Smallest share of the budget either strategy gets.
const MIN_SHARE: f64 = 0.125;
/// Share of the edge table's own weights in the pilot-fitted shape mixture (module docs).
const EDGE_PRIOR_SHARE: f64 = 0.25;

/// What the secondary-edge pass did.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SecondaryStats {
    pub samples: u64,
    pub pilot_samples: u64,
    /// Evaluations of the edge-directed (A) and light-directed (B) strategies (in an NLOS
    /// capture half of B's draws end at a sensor point instead, `secondary.rs`).
    pub edge_directed: u64,
    pub light_directed: u64,
    /// Boundary rays whose segment found a surface at both ends.
    pub valid_segments: u64,
    pub rays: u64,
    pub non_finite: u64,
    pub seconds: f64,
}

/// What a pilot pass learned ([`Secondary::plan`]).
pub struct Pilot {
    /// Guiding grids of the edge-directed and the light-directed strategy.
    grid: GuideGrid,
    grid_light: GuideGrid,
    /// Share of the budget for the edge-directed strategy.
    share_a: f64,
    /// Edge tables of the edge-directed and the light-directed strategy.
    edges: [EdgeSampler; 2],
    /// Per edge, the mean share t_S/(t_L + t_S) of the light-directed samples that found a
    /// segment on it (0: none), for `secondary::shadow_aligned`; empty with guiding on (its
    /// grids are fitted to the pilot's unrotated samples).
    shadow_shares: Vec<f32>,
    rays: u64,
    /// Wall seconds the pilot took.
    seconds: f64,
}

/// Boundary samples of one strategy waiting for their subpaths, run 8 at a time
/// ([`Secondary::complete`]), in the order they were drawn; in an NLOS capture the
/// light-directed strategy's draws that end at a sensor point wait in a packet of their own
/// (their sensor side is that point, not an importance walk).
struct Queue {
    seed: u64,
    items: [Vec<Prepared>; 2],
}

impl Queue {
    fn new(seed: u64) -> Self {
        Self {
            seed,
            items: [Vec::with_capacity(8), Vec::with_capacity(8)],
        }
    }

    fn push(
        &mut self,
        sec: &Secondary,
        p: Option<Prepared>,
        scratch: &mut Scratch,
        emit: &mut impl FnMut(&Prepared, &BoundaryPath),
    ) {
        if let Some(p) = p {
            let kind = usize::from(p.segment.sensed.is_some());
            self.items[kind].push(p);
            if self.items[kind].len() == 8 {
                sec.complete(self.seed, &self.items[kind], scratch, &mut *emit);
                self.items[kind].clear();
            }
        }
    }

    fn flush(&mut self, sec: &Secondary, scratch: &mut Scratch, emit: &mut impl FnMut(&Prepared, &BoundaryPath)) {
        for items in &mut self.items {
            if !items.is_empty() {
                sec.complete(self.seed, items, scratch, &mut *emit);
                items.clear();
            }
        }
    }
}

/// One strategy's pilot tallies over a chunk: per guiding cell Σ of each sample's total
/// |contribution|, Σ of its square, and per shape of the sample's edge ([`ShapeTally`]).
/// Paths arrive sample by sample.
struct PilotTally {
    cells: Vec<f64>,
    m2: f64,
    shapes: Vec<ShapeTally>,
    /// The sample whose paths are arriving: its id, cell, shape, and Σ and Σ of squares of
    /// its paths' |contribution| so far.
    open: Option<(u64, usize, usize, f64, f64)>,
}

impl PilotTally {
    fn new(cells: usize, shapes: usize) -> Self {
        Self {
            cells: vec![0.0; cells],
            m2: 0.0,
            shapes: vec![ShapeTally::default(); shapes],
            open: None,
        }
    }

    /// A sample drawn on `edge` (None: no edge) whose preparation cast `rays` rays.
    fn drawn(&mut self, edges: &EdgeSampler, edge: Option<usize>, rays: u64, prepared: bool) {
        if let Some(e) = edge {
            let t = &mut self.shapes[edges.edges[e].shape as usize];
            t.drawn += 1;
            t.own_rays += rays;
            t.prepared += u64::from(prepared);
        }
    }

    fn add(&mut self, grid: &GuideGrid, edges: &EdgeSampler, p: &Prepared, mag: f64) {
        match &mut self.open {
            Some((id, _, _, sum, sq)) if *id == p.segment.id => {
                *sum += mag;
                *sq += mag * mag;
            }
            _ => {
                self.close();
                let shape = edges.edges[p.edge].shape as usize;
                self.open = Some((p.segment.id, grid.cell_of(p.u), shape, mag, mag * mag));
            }
        }
    }

    fn close(&mut self) {
        if let Some((_, cell, shape, mag, sq)) = self.open.take()
            && mag.is_finite()
        {
            self.cells[cell] += mag;
            self.m2 += mag * mag;
            self.shapes[shape].m2 += sq;
        }
    }
}

/// Per edge, Σ of the share t_S/(t_L + t_S) over the light-directed pilot samples that found
/// a segment on it, and their count (for `Pilot::shadow_shares`).
struct ShareTally(Vec<(f64, u64)>);

impl ShareTally {
    fn new(edges: usize) -> Self {
        Self(vec![(0.0, 0); edges])
    }

    fn add(&mut self, p: &Prepared) {
        let (t_l, t_s) = (p.segment.x_l.t as f64, p.segment.x_s.t as f64);
        let q = t_s / (t_l + t_s);
        if q.is_finite() {
            self.0[p.edge].0 += q;
            self.0[p.edge].1 += 1;
        }
    }

    fn merge(&mut self, o: &ShareTally) {
        for (a, b) in self.0.iter_mut().zip(&o.0) {
            a.0 += b.0;
            a.1 += b.1;
        }
    }

    /// The mean share per edge, 0 where no sample found a segment.
    fn means(&self) -> Vec<f32> {
        self.0
            .iter()
            .map(|&(sum, n)| if n > 0 { (sum / n as f64) as f32 } else { 0.0 })
            .collect()
    }
}

/// A pilot's record of the samples drawn on one shape's edges.
#[derive(Clone, Copy, Debug, Default)]
struct ShapeTally {
    /// Σ over samples of Σ over their paths of |contribution|²: the paths of a sample land in
    /// different pixels and bins, so this, not the square of their sum, is what a sample adds
    /// to the squared L2 error of the film.
    m2: f64,
    drawn: u64,
    /// Of them, those that reached the subpaths.
    prepared: u64,
    /// Rays their preparation cast (the boundary segment's ends).
    own_rays: u64,
}

impl ShapeTally {
    fn merge(&mut self, o: &ShapeTally) {
        self.m2 += o.m2;
        self.drawn += o.drawn;
        self.prepared += o.prepared;
        self.own_rays += o.own_rays;
    }
}

/// The edge table with each shape's share of its probability refitted to the pilot's
/// `shapes` tallies over `samples` pilot samples drawn from `table`, which cast `rays` rays
/// in all (their own and their subpaths'): the mixture of the module docs. `table` itself
/// when the pilot saw nothing.
fn refit_shapes(table: &EdgeSampler, shapes: &[ShapeTally], samples: u64, rays: u64) -> EdgeSampler {
    let mut prior = vec![0.0f64; shapes.len()];
    for (i, r) in table.edges.iter().enumerate() {
        prior[r.shape as usize] += table.edge_pmf(i) as f64;
    }
    let total = shapes.iter().fold(ShapeTally::default(), |mut a, t| {
        a.merge(t);
        a
    });
    // rays per sample: its own, plus the mean subpath rays of a prepared sample
    let per_prepared = rays.saturating_sub(total.own_rays) as f64 / total.prepared.max(1) as f64;
    let cost = |t: &ShapeTally| {
        let t = if t.drawn > 0 { t } else { &total };
        ((t.own_rays as f64 + t.prepared as f64 * per_prepared) / t.drawn.max(1) as f64).max(1.0)
    };
    // √(M_s / c_s), M_s = P_s/N · Σ |X|² (X carries 1/P(edge), so this is the second moment
    // per sample that the shape's edges would add if drawn with probability 1)
    let root: Vec<f64> = prior
        .iter()
        .zip(shapes)
        .map(|(&p, t)| (p * t.m2 / samples.max(1) as f64 / cost(t)).sqrt())
        .collect();
    let sum: f64 = root.iter().sum();
    if !(sum > 0.0 && sum.is_finite()) {
        return table.clone();
    }
    let factor: Vec<f64> = root
        .iter()
        .zip(&prior)
        .map(|(&r, &p)| {
            if p > 0.0 {
                (1.0 - EDGE_PRIOR_SHARE) * r / (sum * p) + EDGE_PRIOR_SHARE
            } else {
                1.0
            }
        })
        .collect();
    let weights: Vec<f64> = (0..table.edges.len())
        .map(|i| table.edge_pmf(i) as f64 * factor[table.edges[i].shape as usize])
        .collect();
    table.with_weights(&weights)
}

/// Σ_c |f_c| · Σ_k |weight_k| of one path.
fn magnitude(p: &BoundaryPath, params: usize) -> f64 {
    let f: f32 = p.rgb.iter().map(|v| v.abs()).sum();
    let w: f32 = p.weight[..params].iter().map(|v| v.abs()).sum();
    (f * w) as f64
}

impl Secondary<'_> {
    fn pilot(&self, samples: u64, seed: u64, guiding: bool, pool: &rayon::ThreadPool) -> Pilot {
        let t0 = Instant::now();
        let uniform = GuideGrid::uniform(RESOLUTION);
        let cells = uniform.cells();
        let shapes = self.edges.edges.iter().map(|r| r.shape as usize + 1).max().unwrap_or(0);
        let table = &self.edges;
        // both strategies draw every id from the one table
        let split = EmissionSplit {
            edges: [table, table],
            evaluations: [samples, samples],
        };
        // each wave of chunks is merged into the sums in chunk order as it ends (`waves`): a
        // list of every chunk's tallies grew by two 512-cell tallies per 4096 samples until
        // the end (2.2 GB before any work at spp_boundary 2^24 on 32 × 32 pixels)
        let mut shares = ShareTally::new(table.edges.len());
        let mut sums = [vec![0.0f64; cells], vec![0.0f64; cells]];
        let mut by_shape = [vec![ShapeTally::default(); shapes], vec![ShapeTally::default(); shapes]];
        let (mut m2, mut rays) = ([0.0f64; 2], [0u64; 2]);
        let trace_chunk = |ids: std::ops::Range<u64>| {
            let mut tally = [PilotTally::new(cells, shapes), PilotTally::new(cells, shapes)];
            let mut scratch = [Scratch::default(), Scratch::default()];
            let mut queue = [Queue::new(seed), Queue::new(seed ^ LIGHT_STREAM)];
            let mut shares = ShareTally::new(table.edges.len());
            let params = self.params;
            // a cancelled render's pilot draws no more samples, not even in this wave's
            // chunks (`crate::cancel`); the pass then traces nothing
            let ids = match self.ctx.cancel.is_cancelled() {
                true => ids.start..ids.start,
                false => ids,
            };
            for id in ids {
                for s in 0..2 {
                    let before = scratch[s].rays();
                    let p = match s {
                        0 => self.prepare(seed, id, &uniform, table, &split, 1.0, &mut scratch[0]),
                        _ => self.prepare_light(
                            seed ^ LIGHT_STREAM,
                            id,
                            &uniform,
                            table,
                            &split,
                            &[],
                            1.0,
                            &mut scratch[1],
                        ),
                    };
                    if s == 1
                        && let Some(p) = p.as_ref().filter(|p| p.segment.sensed.is_none())
                    {
                        shares.add(p);
                    }
                    let t = &mut tally[s];
                    t.drawn(table, scratch[s].edge, scratch[s].rays() - before, p.is_some());
                    let mut emit = |p: &Prepared, bp: &BoundaryPath| t.add(&uniform, table, p, magnitude(bp, params));
                    queue[s].push(self, p, &mut scratch[s], &mut emit);
                }
            }
            for s in 0..2 {
                let t = &mut tally[s];
                queue[s].flush(self, &mut scratch[s], &mut |p, bp| {
                    t.add(&uniform, table, p, magnitude(bp, params))
                });
                t.close();
            }
            (tally, [scratch[0].rays(), scratch[1].rays()], shares)
        };
        super::waves::in_waves(pool, 0..samples, CHUNK, &self.ctx.cancel, trace_chunk, |parts| {
            for (t, r, q) in &parts {
                shares.merge(q);
                for s in 0..2 {
                    sums[s].iter_mut().zip(&t[s].cells).for_each(|(a, b)| *a += b);
                    by_shape[s].iter_mut().zip(&t[s].shapes).for_each(|(a, b)| a.merge(b));
                    m2[s] += t[s].m2;
                    rays[s] += r[s];
                }
            }
        });
        let n = samples.max(1) as f64;
        let rate = |s: usize| (m2[s] / n).sqrt() / (rays[s] as f64 / n).max(0.5).sqrt();
        let (ra, rb) = (rate(0), rate(1));
        let share_a = if ra + rb > 0.0 && (ra + rb).is_finite() {
            (ra / (ra + rb)).clamp(MIN_SHARE, 1.0 - MIN_SHARE)
        } else {
            0.5
        };
        Pilot {
            grid: if guiding {
                GuideGrid::from_pilot(RESOLUTION, &sums[0], UNIFORM_MIX)
            } else {
                uniform.clone()
            },
            grid_light: if guiding {
                GuideGrid::from_pilot(RESOLUTION, &sums[1], UNIFORM_MIX)
            } else {
                uniform
            },
            share_a,
            // guiding grids read the edge coordinate of this table: they keep it
            edges: if guiding {
                [table.clone(), table.clone()]
            } else {
                [0, 1].map(|s| refit_shapes(table, &by_shape[s], samples, rays[s]))
            },
            shadow_shares: if guiding { Vec::new() } else { shares.means() },
            rays: rays[0] + rays[1],
            seconds: t0.elapsed().as_secs_f64(),
        }
    }

    /// The secondary pass of `settings` (`spp_boundary · W · H` boundary samples after a
    /// pilot, guided or not, on the secondary seed stream) returning one derivative transient
    /// per parameter. With a shard, only its part of the sample indices is traced (every
    /// shard runs the same pilot), still normalised by all the samples.
    pub fn render(
        &self,
        settings: &BoundarySettings,
        pilot: Option<&Pilot>,
        pool: &rayon::ThreadPool,
    ) -> (Vec<Transient>, SecondaryStats) {
        let film = &self.ctx.scene.film;
        let (w, h) = (film.width as usize, film.height as usize);
        let mut out = Transient::zeros_many(1 + self.params, w, h, film.axis, film.channels);
        // Bands of film rows bin each batch's paths in parallel, each band every path in
        // chunk order, so the bytes do not depend on the thread count, and memory stays one
        // film plus a batch of path lists.
        let bands = super::row_bands(h, pool);
        let mut tiles: Vec<TileFilm> = (0..bands)
            .map(|b| {
                let (y0, y1) = (b * h / bands, (b + 1) * h / bands);
                self.ctx.tile_film(0, y0, w, y1 - y0, self.params)
            })
            .collect();
        let (stats, samples) = self.trace(
            settings,
            pilot,
            pool,
            |paths| paths,
            |paths| {
                let dropped: Vec<u64> = pool.install(|| {
                    tiles
                        .par_iter_mut()
                        .map(|tile| {
                            let rows = tile.y0..tile.y0 + tile.h;
                            paths
                                .iter()
                                .map(|bp| u64::from(!self.splat(tile, rows.clone(), bp)))
                                .sum()
                        })
                        .collect()
                });
                dropped[0]
            },
        );
        for tile in &tiles {
            tile.store_into(&mut out);
        }
        out.remove(0);
        out.iter_mut().for_each(|t| t.scale(1.0 / samples.max(1) as f32));
        (out, stats)
    }

    /// The secondary term contracted with an adjoint volume (`crate::adjoint`): the same
    /// samples as [`Secondary::render`], each path's İ_k contracted with ∂L/∂I in the bins
    /// it touches, without a derivative film.
    pub fn adjoint(
        &self,
        settings: &BoundarySettings,
        pilot: Option<&Pilot>,
        pool: &rayon::ThreadPool,
        adjoint: &Transient,
    ) -> ([f64; MAX_PARAMS], SecondaryStats) {
        // each chunk's paths contracted where they were traced, the chunks' sums added in
        // chunk order (chunks have a fixed size: the same gradient for any thread count)
        let h = self.ctx.scene.film.height as usize;
        let contract = |paths: Vec<BoundaryPath>| {
            let mut acc = crate::adjoint::AdjointFilm::new(adjoint);
            let dropped: u64 = paths.iter().map(|bp| u64::from(!self.splat(&mut acc, 0..h, bp))).sum();
            (acc.grad, dropped)
        };
        let mut grad = [0.0f64; MAX_PARAMS];
        let (stats, samples) = self.trace(settings, pilot, pool, contract, |(part, dropped)| {
            grad.iter_mut().zip(part).for_each(|(g, p)| *g += p);
            *dropped
        });
        grad.iter_mut().for_each(|g| *g /= samples.max(1) as f64);
        (grad, stats)
    }

    /// The boundary samples of `settings`' pass (all shards), and its pilot's (1/8 of them
    /// when the pilot fits guiding grids, else 1/16 for the budget split alone, at least 1024).
    fn sample_counts(&self, settings: &BoundarySettings) -> (u64, u64) {
        let film = &self.ctx.scene.film;
        let samples = settings.spp_boundary as u64 * film.width as u64 * film.height as u64;
        (samples, (samples / if settings.guiding { 8 } else { 16 }).max(1024))
    }

    /// The pilot of `settings`' pass, `None` when the pass has nothing to trace. The render
    /// driver runs it with the window cut whatever the steady mode (`super::secondary_pilot`),
    /// so that `--steady full` draws the same boundary samples.
    pub fn plan(&self, settings: &BoundarySettings, pool: &rayon::ThreadPool) -> Option<Pilot> {
        let (samples, pilot) = self.sample_counts(settings);
        if self.edges.is_empty() || samples == 0 || self.params == 0 {
            return None;
        }
        let seed = settings.seed ^ SECONDARY_SEED ^ PILOT_STREAM;
        Some(self.pilot(pilot, seed, settings.guiding, pool))
    }

    /// Every boundary sample of the settings' shard, drawn as `pilot` (of [`Self::plan`])
    /// says, in chunks of a fixed size traced in parallel; each chunk's paths are mapped by
    /// `per_chunk` on the thread that traced them, and the results go to `consume` in chunk
    /// order, which returns how many paths it dropped as not finite. Returns the pass's
    /// record (the pilot's rays included) and its sample count (the normalisation of every
    /// shard).
    fn trace<T: Send>(
        &self,
        settings: &BoundarySettings,
        pilot: Option<&Pilot>,
        pool: &rayon::ThreadPool,
        per_chunk: impl Fn(Vec<BoundaryPath>) -> T + Sync,
        mut consume: impl FnMut(&T) -> u64,
    ) -> (SecondaryStats, u64) {
        let (samples, pilot_samples) = self.sample_counts(settings);
        let shard = settings.shard;
        let seed = settings.seed ^ SECONDARY_SEED;
        let t0 = Instant::now();
        let own = shard.range(samples);
        let mut stats = SecondaryStats {
            // this shard's share (the shards' counts add up to `samples`)
            samples: own.end - own.start,
            pilot_samples,
            ..Default::default()
        };
        let Some(pl) = pilot else {
            return (stats, samples);
        };
        stats.rays += pl.rays;
        let budget = 2 * samples;
        let n_a = ((budget as f64 * pl.share_a).round() as u64).clamp(1, budget - 1);
        let n_b = budget - n_a;
        let ids = n_a.max(n_b);
        let mine = shard.range(ids);
        // this shard's evaluations of each (ids below n_s of its range; the whole render's
        // counts in every shard until the forty-third session, so shards added to N times
        // the work)
        stats.edge_directed = mine.end.min(n_a).saturating_sub(mine.start);
        stats.light_directed = mine.end.min(n_b).saturating_sub(mine.start);
        // each strategy's paths carry samples/n_s, so that the final 1/samples averages each
        // over its own count
        let scale = [samples as f32 / n_a as f32, samples as f32 / n_b as f32];
        let split = EmissionSplit {
            edges: [&pl.edges[0], &pl.edges[1]],
            evaluations: [n_a, n_b],
        };
        let my_chunks = super::waves::chunks_of(&mine, CHUNK);
        settings.progress.set_length(my_chunks.end - my_chunks.start);
        let trace_chunk = |ids: std::ops::Range<u64>| {
            let mut scratch = Scratch::default();
            let mut paths = Vec::new();
            let mut queue = [Queue::new(seed), Queue::new(seed ^ LIGHT_STREAM)];
            let mut keep = |_: &Prepared, bp: &BoundaryPath| paths.push(*bp);
            for id in ids {
                if id < n_a {
                    let p = self.prepare(seed, id, &pl.grid, &pl.edges[0], &split, scale[0], &mut scratch);
                    queue[0].push(self, p, &mut scratch, &mut keep);
                }
                if id < n_b {
                    let p = self.prepare_light(
                        seed ^ LIGHT_STREAM,
                        id,
                        &pl.grid_light,
                        &pl.edges[1],
                        &split,
                        &pl.shadow_shares,
                        scale[1],
                        &mut scratch,
                    );
                    queue[1].push(self, p, &mut scratch, &mut keep);
                }
            }
            for q in &mut queue {
                q.flush(self, &mut scratch, &mut keep);
            }
            (per_chunk(paths), scratch)
        };
        // a cancelled render stops between waves (`crate::cancel`)
        super::waves::in_waves(pool, mine.clone(), CHUNK, &self.ctx.cancel, trace_chunk, |parts| {
            for (paths, s) in &parts {
                stats.non_finite += consume(paths) + s.counts.non_finite;
                stats.rays += s.rays();
                stats.valid_segments += s.valid;
            }
            settings.progress.inc(parts.len() as u64);
        });
        stats.seconds = t0.elapsed().as_secs_f64() + pl.seconds;
        (stats, samples)
    }

    /// Bins one boundary path into the derivative channels of `tile` (its primal stays 0):
    /// İ_k += f_L·f_S·weight_k·h_j · S_e(d) at each pixel j of the tile's rows that the filter
    /// reaches. False (and nothing added) when a value is not finite.
    fn splat<A: crate::film::Accumulate>(&self, tile: &mut A, rows: std::ops::Range<usize>, bp: &BoundaryPath) -> bool {
        let ctx = self.ctx;
        let (c_n, p) = (ctx.scene.film.channels, self.params);
        let finite =
            bp.opl.is_finite() && bp.rgb.iter().all(|v| v.is_finite()) && bp.weight[..p].iter().all(|v| v.is_finite());
        if !finite {
            return false;
        }
        let corr = &ctx.correlations[bp.emitter as usize];
        let zeros = [0.0f32; 3];
        let ddot = [0.0f32; MAX_PARAMS];
        let mut fdot = [0.0f32; MAX_PARAMS * 3];
        let band = rows.start as u32..rows.end as u32;
        let mut add = |px: u32, py: u32, hw: f32| {
            if hw == 0.0 {
                return;
            }
            for k in 0..p {
                for c in 0..c_n {
                    fdot[k * c_n + c] = bp.rgb[c] * bp.weight[k] * hw;
                }
            }
            tile.add_with_derivs(
                px as usize,
                py as usize,
                corr,
                bp.opl,
                &zeros[..c_n],
                &fdot[..p * c_n],
                &ddot[..p],
            );
        };
        if ctx.nlos.is_some() {
            // a capture's film points are sensor (and laser) points: no pixel filter
            let (px, py) = (bp.fx as u32, bp.fy as u32);
            if band.contains(&py) {
                add(px, py, 1.0);
            }
        } else {
            ctx.camera.for_each_pixel_in_rows(bp.fx, bp.fy, band, add);
        }
        true
    }
}

#[cfg(test)]
mod refit_tests {
    use super::*;

    fn shape_pmf(t: &EdgeSampler, shape: usize) -> f64 {
        (0..t.edges.len())
            .filter(|&i| t.edges[i].shape as usize == shape)
            .map(|i| t.edge_pmf(i) as f64)
            .sum()
    }

    /// The pilot-fitted mixture of the module docs: shape shares (1 − α)·r_s/Σr + α·P_s with
    /// r_s = √(M_s/c_s), the edges of a shape keeping their relative weights; the table itself
    /// when the pilot saw no contribution.
    #[test]
    fn shapes_are_drawn_by_root_second_moment_per_ray() {
        let (scene, occluder) = crate::boundary::shadow_scene("occluder");
        let occluder = occluder as usize;
        let table = EdgeSampler::new(&scene.geometry, scene.offset_scale);
        let shapes = scene.shapes.len();
        let floor = scene.shapes.iter().position(|s| s.name == "floor").unwrap();
        let prior: Vec<f64> = (0..shapes).map(|s| shape_pmf(&table, s)).collect();
        assert!(prior[occluder] > 0.0 && prior[floor] > 0.0);
        let n = 4096u64;
        // every shape drawn in proportion to its prior, each sample casting 2 rays, half of
        // them reaching subpaths of 6 rays each: 5 rays a sample everywhere
        let mut tally: Vec<ShapeTally> = prior
            .iter()
            .map(|&p| {
                let drawn = (p * n as f64).round() as u64;
                ShapeTally {
                    m2: 0.0,
                    drawn,
                    prepared: drawn / 2,
                    own_rays: 2 * drawn,
                }
            })
            .collect();
        let rays = |tally: &[ShapeTally]| tally.iter().map(|t| t.own_rays + 6 * t.prepared).sum::<u64>();
        let same = refit_shapes(&table, &tally, n, rays(&tally));
        for i in 0..table.edges.len() {
            assert_eq!(same.edge_pmf(i), table.edge_pmf(i));
        }
        // only the occluder's edges contribute: it gets 1 − α of the draws besides its prior
        // share of α; every other shape keeps α of its prior
        tally[occluder].m2 = 3.0;
        let fit = refit_shapes(&table, &tally, n, rays(&tally));
        let a = EDGE_PRIOR_SHARE;
        for s in 0..shapes {
            let want = if s == occluder {
                1.0 - a + a * prior[s]
            } else {
                a * prior[s]
            };
            assert!(
                (shape_pmf(&fit, s) - want).abs() < 1e-5,
                "shape {s}: {} vs {want}",
                shape_pmf(&fit, s)
            );
        }
        for i in 0..table.edges.len() {
            let s = table.edges[i].shape as usize;
            let ratio = fit.edge_pmf(i) as f64 / table.edge_pmf(i) as f64;
            let want = shape_pmf(&fit, s) / prior[s];
            assert!((ratio / want - 1.0).abs() < 1e-4, "edge {i}: {ratio} vs {want}");
        }
        // the floor too, with 4× the occluder's second moment per draw but samples 4× as
        // costly: r ∝ √(M/c), so they split 1 − α as √(M_o P_o) : √(4 M_o P_f / 4)
        tally[floor].m2 = 4.0 * tally[occluder].m2 * (tally[floor].drawn as f64 / tally[occluder].drawn as f64);
        tally[floor].own_rays *= 4;
        tally[floor].prepared *= 4;
        let fit = refit_shapes(&table, &tally, n, rays(&tally));
        // cost per sample: occluder 2 + ½·6 = 5 rays; floor 8 + 2·6 = 20 rays
        let m = |s: usize| prior[s] * tally[s].m2 / n as f64;
        let (r_o, r_f) = ((m(occluder) / 5.0).sqrt(), (m(floor) / 20.0).sqrt());
        for (s, r) in [(occluder, r_o), (floor, r_f)] {
            let want = (1.0 - a) * r / (r_o + r_f) + a * prior[s];
            assert!(
                (shape_pmf(&fit, s) - want).abs() < 1e-5,
                "shape {s}: {} vs {want}",
                shape_pmf(&fit, s)
            );
        }
    }
}

#[cfg(test)]
mod shadow_share_tests {
    use super::*;
    use crate::accel::Device;
    use crate::integrator::context::RenderContext;
    use crate::params::lanes::Motion;

    /// The pilot's share q = t_S/(t_L + t_S) per edge (for `secondary::shadow_aligned`): ½ on
    /// the edges of the occluder in scenes/shadow_hidden_occluder.toml that `occluder_x`
    /// moves across themselves (light at height 2, occluder at 1, floor at 0: t_S = t_L on
    /// every light-directed segment), 0 on the floor's edges (their segments find nothing
    /// beyond the floor); none with guiding on.
    #[test]
    fn the_pilot_measures_each_edges_shadow_share() {
        let (scene, occluder) = crate::boundary::shadow_scene("occluder");
        let device = Device::new("").unwrap();
        let mut ctx = RenderContext::new(&scene, &device).unwrap();
        ctx.motion = Motion::build(&scene, &["occluder_x".to_string()]).unwrap();
        let sec = Secondary::new(&ctx);
        let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
        let floor = scene.shapes.iter().position(|s| s.name == "floor").unwrap() as u32;
        let pilot = sec.pilot(4096, 11, false, &pool);
        assert_eq!(pilot.shadow_shares.len(), sec.edges.edges.len());
        let mut across = 0;
        for (rec, &q) in sec.edges.edges.iter().zip(&pilot.shadow_shares) {
            let along_z = (rec.v1 - rec.v0).normalize().x.abs() < 1e-3;
            if rec.shape == occluder && along_z {
                assert!((q - 0.5).abs() < 1e-3, "occluder edge: q = {q}");
                across += 1;
            } else if rec.shape == floor {
                assert_eq!(q, 0.0);
            }
        }
        assert_eq!(across, 2);
        assert!(sec.pilot(4096, 11, true, &pool).shadow_shares.is_empty());
    }
}
