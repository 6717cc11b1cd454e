//! The boundary integral (Algorithm 2): discontinuities of the path integrand where visibility
//! changes, as the part of the gradient that the interior (Algorithm 1) cannot see.
//!
//! - [`contact`]: the ends x_L, x_S of a boundary segment; contact edges (an object resting on
//!   a surface) counted once, by the product rule.
//! - [`edges`]: edge topology, built once (boundary and sharp edges, coplanar ones dropped);
//!   [`seams`]: unwelded vertices and T-junctions joined, so that no edge is listed twice.
//! - [`edge_sampler`]: boundary rays (x_B, ω_B) on silhouette directions, by edge importance.
//! - [`guiding`]: a grid over the sampler's inputs fitted by a pilot pass.
//! - [`velocity`]: how fast a discontinuity sweeps over a path vertex (V_∂Ω).
//! - [`hit`]: plain rays for the boundary segment's ends.
//! - [`interpenetration`]: moving shapes that cross a surface (refused: their crossing curve is
//!   on no mesh edge).
//! - [`subpaths`]: source and sensor subpaths without derivatives, eight boundary samples at
//!   a time on the interior's kernel (the path tracer from x_L, the importance walk from x_S).
//! - [`secondary`]: secondary edges, Algorithm 2 with Eqs. 18–19 and 30–32: two strategies.
//! - [`pass`]: the secondary pass: pilot (budget split, guiding), chunks, ordered binning.
//! - [`primary`]: silhouettes seen from the camera (and flat-shading creases, sampled by projected length in
//!   image space ([`silhouette`] classifies and projects the edges)).
//!
//! [`render_boundary`] runs both estimators, each with its own seed stream, and returns their
//! derivative transients separately; `render::render_diff` adds them to the interior.

pub mod contact;
pub mod edge_sampler;
pub mod edges;
pub mod guiding;
pub mod hit;
pub mod interpenetration;
pub mod pass;
pub mod primary;
pub mod seams;
pub mod secondary;
pub mod silhouette;
#[cfg(test)]
mod silhouette_tests;
pub mod subpaths;
pub mod velocity;
mod waves;

use crate::film::{SteadyMode, Transient};
use crate::integrator::context::RenderContext;
use std::time::Instant;

/// For unit tests: scenes/shadow_hidden_occluder.toml (light at height 2, a square occluder
/// at 1, the floor at 0) and the index of its shape named `shape`.
#[cfg(test)]
pub(crate) fn shadow_scene(shape: &str) -> (crate::scene::Scene, u32) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/shadow_hidden_occluder.toml");
    let scene = crate::scene::Scene::load(&path, &[]).unwrap();
    let index = scene.shapes.iter().position(|s| s.name == shape).unwrap() as u32;
    (scene, index)
}

/// Seed streams of the boundary estimators, derived from the render seed: independent of
/// the interior's stream and of each other.
pub const PRIMARY_SEED: u64 = 0x9E1A_0001_B0DA_0001;
pub const SECONDARY_SEED: u64 = 0x5EC0_0002_B0DA_0002;

/// Bands of film rows that bin boundary paths in parallel: one per thread of `pool`, at
/// least 8, at most one per row. Each band bins every path in sample order and a pixel lies
/// in one band, so the number changes no byte.
pub(crate) fn row_bands(rows: usize, pool: &rayon::ThreadPool) -> usize {
    rows.clamp(1, pool.current_num_threads().max(8))
}

/// How the boundary stage samples.
#[derive(Clone, Debug)]
pub struct BoundarySettings {
    /// Boundary samples per pixel: the secondary pass draws `spp_boundary · W · H` boundary
    /// rays; the primary pass gets the same per-pixel count.
    pub spp_boundary: u32,
    /// The render seed (each estimator derives its own stream).
    pub seed: u64,
    /// Fit guiding grids with a pilot of 1/8 of the samples (else the pilot, 1/16 of the
    /// samples, only splits the budget between the strategies). Off by default: in
    /// `cargo bench --bench boundary` it lowers the mean error by 25–40 % from 16 384 samples
    /// on, but paths that the pilot never saw (a shadow's tip, say) are then drawn less often,
    /// so the estimate has heavier tails: with 16 seeds, tests/secondary_fd.rs's moving
    /// receiver fails its Σz² bound when guided.
    pub guiding: bool,
    /// The shard whose part of each estimator's samples to trace ([`crate::shard`]); the
    /// films stay normalised by the whole sample counts.
    pub shard: crate::shard::Shard,
    /// Which of the two terms to estimate (both, but for diagnosis: `--estimators primary`
    /// or `secondary`); a term left out is a zero film and takes no samples.
    pub stages: Stages,
    /// Progress of the secondary pass, in chunks of boundary samples: its length is set when
    /// the pass starts and it advances per batch (`indicatif::ProgressBar::hidden()` for none).
    pub progress: indicatif::ProgressBar,
}

/// Which boundary terms a render estimates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stages {
    /// Primary edges: silhouettes seen from the camera ([`primary`]).
    pub primary: bool,
    /// Secondary edges: Algorithm 2 at edges seen from path vertices ([`secondary`]).
    pub secondary: bool,
}

impl Stages {
    pub const BOTH: Self = Self {
        primary: true,
        secondary: true,
    };
    pub const NONE: Self = Self {
        primary: false,
        secondary: false,
    };

    /// Whether any boundary term runs.
    pub fn any(self) -> bool {
        self.primary || self.secondary
    }
}

impl Default for Stages {
    fn default() -> Self {
        Self::BOTH
    }
}

/// The boundary parts of the gradient, one transient per parameter each.
#[derive(Clone, Debug)]
pub struct BoundaryParts {
    pub primary: Vec<Transient>,
    pub secondary: Vec<Transient>,
    pub stats: BoundaryStats,
}

/// What the boundary stage did.
#[derive(Clone, Debug, Default, serde::Serialize, serde::Deserialize)]
pub struct BoundaryStats {
    pub spp_boundary: u32,
    /// Wall and CPU seconds of the whole stage (set by the render driver).
    pub wall_seconds: f64,
    pub cpu_seconds: f64,
    pub primary_seconds: f64,
    /// Side-path contributions and edge weights of the primary-edge stage dropped because they
    /// were not finite (`primary::PrimaryStats::non_finite`; 0 when read from an older record).
    #[serde(default)]
    pub primary_non_finite: u64,
    pub secondary: pass::SecondaryStats,
    pub edges: usize,
}

impl BoundaryStats {
    /// Contributions of either stage dropped because they were not finite.
    pub fn non_finite(&self) -> u64 {
        self.primary_non_finite + self.secondary.non_finite
    }
}

/// Runs the primary and secondary estimators for the parameters in `ctx.motion` (those
/// `settings.stages` asks for; a term left out is a zero film).
pub fn render_boundary(
    ctx: &mut RenderContext,
    settings: &BoundarySettings,
    pool: &rayon::ThreadPool,
) -> BoundaryParts {
    let t0 = Instant::now();
    // one edge list for both passes
    let edges = edges::build_edges(&ctx.scene.geometry, ctx.scene.offset_scale);
    let (primary, pstats) = if settings.stages.primary {
        primary::render_primary_with_stats(
            ctx,
            &edges,
            settings.spp_boundary,
            settings.seed ^ PRIMARY_SEED,
            settings.shard,
            pool,
        )
    } else {
        (zero_films(ctx), Default::default())
    };
    let primary_seconds = t0.elapsed().as_secs_f64();
    let (secondary, sstats, edge_count) = if settings.stages.secondary {
        let (sec, pilot) = secondary_with_pilot(ctx, &edges, settings, pool);
        let (films, stats) = sec.render(settings, pilot.as_ref(), pool);
        (films, stats, sec.edge_count())
    } else {
        (zero_films(ctx), Default::default(), edges.len())
    };
    BoundaryParts {
        primary,
        secondary,
        stats: BoundaryStats {
            spp_boundary: settings.spp_boundary,
            primary_seconds,
            primary_non_finite: pstats.non_finite,
            secondary: sstats,
            edges: edge_count,
            ..Default::default()
        },
    }
}

/// One zero film per parameter: the part of a boundary term left out.
fn zero_films(ctx: &RenderContext) -> Vec<crate::film::Transient> {
    let film = &ctx.scene.film;
    crate::film::Transient::zeros_many(
        ctx.motion.len().min(crate::params::MAX_PARAMS),
        film.width as usize,
        film.height as usize,
        film.axis,
        film.channels,
    )
}

/// The boundary stage contracted with an adjoint volume (`crate::adjoint`): the same
/// samples as [`render_boundary`], each path's derivative contracted with ∂L/∂I on the fly.
/// Returns Σ ⟨∂L/∂I, primary_k + secondary_k⟩ per parameter and the stage's record.
pub fn boundary_adjoint(
    ctx: &mut RenderContext,
    settings: &BoundarySettings,
    pool: &rayon::ThreadPool,
    adjoint: &Transient,
) -> ([f64; crate::params::MAX_PARAMS], BoundaryStats) {
    let t0 = Instant::now();
    let edges = edges::build_edges(&ctx.scene.geometry, ctx.scene.offset_scale);
    let (mut grad, pstats) = if settings.stages.primary {
        primary::primary_adjoint(
            ctx,
            &edges,
            settings.spp_boundary,
            settings.seed ^ PRIMARY_SEED,
            settings.shard,
            pool,
            adjoint,
        )
    } else {
        ([0.0; crate::params::MAX_PARAMS], Default::default())
    };
    let primary_seconds = t0.elapsed().as_secs_f64();
    let (sstats, edge_count) = if settings.stages.secondary {
        let (sec, pilot) = secondary_with_pilot(ctx, &edges, settings, pool);
        let (g2, sstats) = sec.adjoint(settings, pilot.as_ref(), pool, adjoint);
        grad.iter_mut().zip(g2).for_each(|(a, b)| *a += b);
        (sstats, sec.edge_count())
    } else {
        (Default::default(), edges.len())
    };
    let stats = BoundaryStats {
        spp_boundary: settings.spp_boundary,
        primary_seconds,
        primary_non_finite: pstats.non_finite,
        secondary: sstats,
        edges: edge_count,
        wall_seconds: t0.elapsed().as_secs_f64(),
        ..Default::default()
    };
    (grad, stats)
}

/// The secondary pass over `ctx` and its pilot ([`secondary::Secondary::plan`]). The pilot
/// always runs with the window cut (`crate::integrator::window`), whatever `ctx`'s steady
/// mode: it measures each strategy's rays per sample, which the cut lowers, and splits the
/// budget by them. Run uncut under `--steady full`, it split the budget otherwise and the
/// pass drew other samples, so the derivative films were not the bytes of the default mode.
/// `ctx` is left as it came.
fn secondary_with_pilot<'c>(
    ctx: &'c mut RenderContext,
    edges: &[edges::Edge],
    settings: &BoundarySettings,
    pool: &rayon::ThreadPool,
) -> (secondary::Secondary<'c>, Option<pass::Pilot>) {
    let (steady, budget) = (ctx.steady, ctx.opl_budget);
    ctx.cut_to_window(SteadyMode::Window);
    let sec = secondary::Secondary::with_edge_list(ctx, edges);
    let pilot = sec.plan(settings, pool);
    let edges = sec.into_edges();
    (ctx.steady, ctx.opl_budget) = (steady, budget);
    (secondary::Secondary::with_edges(ctx, edges), pilot)
}
