//! The secondary-edge pass: a pilot, then the boundary samples in parallel chunks, binned into
//! one derivative film in a fixed order.
//!
//! The pilot runs both strategies of `secondary.rs` on a stream of its own and learns
//! - how to split the budget between them: for independent unbiased estimators summed, the
//!   variance per unit cost is lowest with n_s ∝ σ_s / √c_s (σ_s: root second moment of a
//!   sample's total |contribution|, c_s: rays per sample); each strategy keeps at least 1/8 of
//!   the budget, so neither is ever starved (any n_s ≥ 1 keeps the sum unbiased);
//! - with guiding on, a grid of `guiding.rs` for each strategy: over (edge coordinate,
//!   azimuth, cos θ) for the edge-directed rays, over (edge coordinate, emitter choice, point
//!   on the emitter) for the light-directed ones.
//!
//! `samples` boundary samples stand for 2·samples strategy evaluations, split as above.

use super::guiding::{GuideGrid, RESOLUTION, UNIFORM_MIX};
use super::secondary::{BoundaryPath, LIGHT_STREAM, Scratch, Secondary};
use super::{BoundarySettings, SECONDARY_SEED};
use crate::film::{TileFilm, Transient};
use crate::integrator::motion::MAX_PARAMS;
use rayon::prelude::*;
use std::time::Instant;

/// Strategy evaluations per work unit (fixed, so results do not depend on the thread count).
const CHUNK: u64 = 4096;
/// Work units traced at once; their paths are binned in order before the next batch.
const BATCH: u64 = 8;
/// Bands of film rows that bin paths in parallel.
const BANDS: usize = 8;
/// Stream of the pilot pass, relative to the pass's seed.
const PILOT_STREAM: u64 = 0x7049_1A7B_0000_0001;
/// Smallest share of the budget either strategy gets.
const MIN_SHARE: f64 = 0.125;

/// What the secondary-edge pass did.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct SecondaryStats {
    pub samples: u64,
    pub pilot_samples: u64,
    /// Evaluations of the edge-directed (A) and light-directed (B) strategies.
    pub edge_directed: u64,
    pub light_directed: u64,
    /// Boundary rays whose segment found a surface at both ends.
    pub valid_segments: u64,
    pub rays: u64,
    pub non_finite: u64,
    pub seconds: f64,
}

/// What a pilot pass learned.
struct Pilot {
    /// Guiding grids of the edge-directed and the light-directed strategy.
    grid: GuideGrid,
    grid_light: GuideGrid,
    /// Share of the budget for the edge-directed strategy.
    share_a: f64,
    rays: u64,
}

/// Per-chunk pilot tallies: guiding cell sums, then per strategy Σ mag², rays.
struct PilotPart {
    cells: [Vec<f64>; 2],
    m2: [f64; 2],
    rays: [u64; 2],
}

/// Σ_c |f_c| · Σ_k |weight_k| of one path.
fn magnitude(p: &BoundaryPath, params: usize) -> f64 {
    let f: f32 = p.rgb.iter().map(|v| v.abs()).sum();
    let w: f32 = p.weight[..params].iter().map(|v| v.abs()).sum();
    (f * w) as f64
}

impl Secondary<'_> {
    fn pilot(&self, samples: u64, seed: u64, guiding: bool, pool: &rayon::ThreadPool) -> Pilot {
        let uniform = GuideGrid::uniform(RESOLUTION);
        let cells = uniform.cells();
        let chunks: Vec<u64> = (0..samples.div_ceil(CHUNK)).collect();
        let parts: Vec<PilotPart> = pool.install(|| {
            chunks
                .par_iter()
                .map(|&c| {
                    let mut part = PilotPart {
                        cells: [vec![0.0; cells], vec![0.0; cells]],
                        m2: [0.0; 2],
                        rays: [0; 2],
                    };
                    let mut scratch = Scratch::default();
                    for id in c * CHUNK..((c + 1) * CHUNK).min(samples) {
                        let before = scratch.rays.intersect + scratch.rays.occluded;
                        let mut mag = 0.0f64;
                        let u = self.evaluate(seed, id, &uniform, 1.0, &mut scratch, |p| {
                            mag += magnitude(p, self.params)
                        });
                        let mid = scratch.rays.intersect + scratch.rays.occluded;
                        if mag.is_finite() {
                            if let Some(u) = u {
                                part.cells[0][uniform.cell_of(u)] += mag;
                            }
                            part.m2[0] += mag * mag;
                        }
                        let mut mag_b = 0.0f64;
                        let u_b = self.evaluate_light(seed ^ LIGHT_STREAM, id, &uniform, 1.0, &mut scratch, |p| {
                            mag_b += magnitude(p, self.params)
                        });
                        if mag_b.is_finite() {
                            part.cells[1][uniform.cell_of(u_b)] += mag_b;
                            part.m2[1] += mag_b * mag_b;
                        }
                        let after = scratch.rays.intersect + scratch.rays.occluded;
                        part.rays[0] += mid - before;
                        part.rays[1] += after - mid;
                    }
                    part
                })
                .collect()
        });
        let mut sums = [vec![0.0f64; cells], vec![0.0f64; cells]];
        let (mut m2, mut rays) = ([0.0f64; 2], [0u64; 2]);
        for p in &parts {
            for s in 0..2 {
                sums[s].iter_mut().zip(&p.cells[s]).for_each(|(a, b)| *a += b);
            }
            for s in 0..2 {
                m2[s] += p.m2[s];
                rays[s] += p.rays[s];
            }
        }
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
            rays: rays[0] + rays[1],
        }
    }

    /// The secondary pass of `settings` (`spp_boundary · W · H` boundary samples after a
    /// pilot, guided or not, on the secondary seed stream) returning one derivative transient
    /// per parameter. With a shard, only its part of the sample indices is traced (every
    /// shard runs the same pilot), still normalised by all the samples.
    pub fn render(&self, settings: &BoundarySettings, pool: &rayon::ThreadPool) -> (Vec<Transient>, SecondaryStats) {
        let film = &self.ctx.scene.film;
        let (w, h) = (film.width as usize, film.height as usize);
        let mut out = vec![Transient::zeros(w, h, film.axis, film.channels); 1 + self.params];
        // Bands of film rows bin each batch's paths in parallel, each band every path in
        // chunk order, so the bytes do not depend on the thread count, and memory stays one
        // film plus a batch of path lists.
        let bands = h.clamp(1, BANDS);
        let mut tiles: Vec<TileFilm> = (0..bands)
            .map(|b| {
                let (y0, y1) = (b * h / bands, (b + 1) * h / bands);
                self.ctx.tile_film(0, y0, w, y1 - y0, self.params)
            })
            .collect();
        let (stats, samples) = self.trace(settings, pool, |paths| {
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
        });
        for tile in &tiles {
            tile.merge_into(&mut out);
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
        pool: &rayon::ThreadPool,
        adjoint: &Transient,
    ) -> ([f64; MAX_PARAMS], SecondaryStats) {
        let mut acc = crate::adjoint::AdjointFilm::new(adjoint);
        let h = self.ctx.scene.film.height as usize;
        let (stats, samples) = self.trace(settings, pool, |paths| {
            paths.iter().map(|bp| u64::from(!self.splat(&mut acc, 0..h, bp))).sum()
        });
        let mut grad = acc.grad;
        grad.iter_mut().for_each(|g| *g /= samples.max(1) as f64);
        (grad, stats)
    }

    /// The pilot, then every boundary sample of the settings' shard in chunks traced in
    /// parallel; each batch's paths go to `consume` in chunk order, which returns how many it
    /// dropped as not finite. Returns the pass's record and its sample count (the
    /// normalisation of every shard).
    fn trace(
        &self,
        settings: &BoundarySettings,
        pool: &rayon::ThreadPool,
        mut consume: impl FnMut(&[BoundaryPath]) -> u64,
    ) -> (SecondaryStats, u64) {
        let film = &self.ctx.scene.film;
        let samples = settings.spp_boundary as u64 * film.width as u64 * film.height as u64;
        // the pilot: 1/8 of the samples when it fits guiding grids, else 1/16 (only the budget
        // split), at least 1024
        let (guiding, shard) = (settings.guiding, settings.shard);
        let pilot = (samples / if guiding { 8 } else { 16 }).max(1024);
        let seed = settings.seed ^ SECONDARY_SEED;
        let t0 = Instant::now();
        let own = shard.range(samples);
        let mut stats = SecondaryStats {
            // this shard's share (the shards' counts add up to `samples`)
            samples: own.end - own.start,
            pilot_samples: pilot,
            ..Default::default()
        };
        if self.edges.is_empty() || samples == 0 || self.params == 0 {
            return (stats, samples);
        }
        let pl = self.pilot(pilot.max(1), seed ^ PILOT_STREAM, guiding, pool);
        stats.rays += pl.rays;
        let budget = 2 * samples;
        let n_a = ((budget as f64 * pl.share_a).round() as u64).clamp(1, budget - 1);
        let n_b = budget - n_a;
        stats.edge_directed = n_a;
        stats.light_directed = n_b;
        // each strategy's paths carry samples/n_s, so that the final 1/samples averages each
        // over its own count
        let scale = [samples as f32 / n_a as f32, samples as f32 / n_b as f32];
        let ids = n_a.max(n_b);
        let mine = shard.range(ids);
        let chunks = ids.div_ceil(CHUNK);
        let mut batch0 = mine.start / CHUNK;
        while batch0 < chunks && batch0 * CHUNK < mine.end {
            let batch: Vec<u64> = (batch0..(batch0 + BATCH).min(chunks)).collect();
            let parts: Vec<(Vec<BoundaryPath>, Scratch)> = pool.install(|| {
                batch
                    .par_iter()
                    .map(|&c| {
                        let mut scratch = Scratch::default();
                        let mut paths = Vec::new();
                        for id in (c * CHUNK).max(mine.start)..((c + 1) * CHUNK).min(mine.end) {
                            let mut keep = |bp: &BoundaryPath| paths.push(*bp);
                            if id < n_a {
                                self.evaluate(seed, id, &pl.grid, scale[0], &mut scratch, &mut keep);
                            }
                            if id < n_b {
                                self.evaluate_light(
                                    seed ^ LIGHT_STREAM,
                                    id,
                                    &pl.grid_light,
                                    scale[1],
                                    &mut scratch,
                                    &mut keep,
                                );
                            }
                        }
                        (paths, scratch)
                    })
                    .collect()
            });
            for (paths, s) in &parts {
                stats.non_finite += consume(paths);
                stats.rays += s.rays.intersect + s.rays.occluded;
                stats.valid_segments += s.valid;
            }
            batch0 += BATCH;
        }
        stats.seconds = t0.elapsed().as_secs_f64();
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
        ctx.camera.for_each_pixel(bp.fx, bp.fy, |px, py, hw| {
            if hw == 0.0 || !rows.contains(&(py as usize)) {
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
        });
        true
    }
}
