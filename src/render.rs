//! The render driver: tiles over a rayon pool, packets of eight paths, deterministic merge.
//!
//! A render is a pure function of (scene, spp, seed): each path's random numbers depend only
//! on its pixel and sample index (see [`crate::kernel::PathSampler`]), each tile accumulates
//! into its own film, and tiles are merged in a fixed order. So the same seed gives the same
//! bytes for any thread count.

use crate::accel::{Device, set_flush_denormals};
use crate::checkpoint::{Checkpointing, Saved};
use crate::error::Error;
use crate::film::{DerivWindowEnergy, SharedFrame, SteadyMode, TileFilm, Transient, WindowEnergy};
use crate::integrator::RenderContext;
use crate::integrator::bdpt::{self, film::BdptFilm};
use crate::integrator::deposit::PathCounts;
use crate::integrator::path::{PacketLanes, trace_packet};
use crate::integrator::sink::Sink;
use crate::integrator::time_edges::{Needs, TimeEdges, Uncovered};
use crate::integrator::time_terms;
use crate::kernel::{Dual8, Real};
use crate::params::MAX_PARAMS;
use crate::params::lanes::Motion;
use crate::scene::{IntegratorKind, NlosSpec, Scene};
use rayon::prelude::*;
use std::time::Instant;

/// Tile edge in pixels. A tile row of 8 pixels is one packet.
pub const TILE: usize = 8;

/// The corners (x0, y0) of the tiles of a w × h film, row by row: the order tiles are
/// merged and summed in.
pub(crate) fn tiles(w: usize, h: usize) -> Vec<(usize, usize)> {
    (0..h.div_ceil(TILE))
        .flat_map(|ty| (0..w.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .collect()
}

/// The tiles of a path-traced render as (x0, y0, w, h): 8 × 8 pixels, except for an
/// exhaustive NLOS scan, whose tiles are 8 sensor columns × every laser row (one path per
/// sensor point serves every laser point: `integrator::nlos`).
pub(crate) fn tile_rects(scene: &Scene) -> Vec<(usize, usize, usize, usize)> {
    let (w, h) = (scene.film.width as usize, scene.film.height as usize);
    let exhaustive = scene.nlos.as_ref().is_some_and(|n| n.exhaustive());
    let rows = if exhaustive { 1 } else { h };
    tiles(w, rows)
        .into_iter()
        .map(|(x0, y0)| {
            let th = if exhaustive { h } else { TILE.min(h - y0) };
            (x0, y0, TILE.min(w - x0), th)
        })
        .collect()
}

/// Paths one sample traces: one per pixel, or for the path tracer one per sensor point of
/// an exhaustive scan (BDPT traces one per (sensor, laser) pair there).
pub(crate) fn paths_per_sample(scene: &Scene, kind: IntegratorKind) -> u64 {
    match &scene.nlos {
        Some(n) if n.exhaustive() && kind == IntegratorKind::Path => n.sensors.len() as u64,
        _ => scene.film.width as u64 * scene.film.height as u64,
    }
}

/// How many paths the kernel carries at once.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Lanes {
    /// Eight paths per packet (`wide::f32x8`, `rtcIntersect8`). The default.
    #[default]
    Simd8,
    /// One path at a time (`f32`, `rtcIntersect1`): the scalar reference for tests.
    Scalar,
}

/// How to render: overrides of the scene's sampling settings, threads, estimators and output
/// conventions. `RenderOptions::default()` renders the scene as its file describes it.
#[derive(Clone, Debug, Default)]
pub struct RenderOptions {
    /// Overrides the scene's samples per pixel.
    pub spp: Option<u32>,
    /// Overrides the scene's seed.
    pub seed: Option<u64>,
    /// Worker threads (default: all available).
    pub threads: Option<usize>,
    /// Show a progress bar (only on a terminal).
    pub progress: bool,
    /// Packet width of the kernel: eight paths per SIMD packet (default) or one.
    pub lanes: Lanes,
    /// Overrides the scene's `[integrator] kind` (`dtr render --integrator`).
    pub integrator: Option<IntegratorKind>,
    /// Boundary samples per pixel for `render_diff` (default: the interior's spp). The
    /// secondary-edge pass draws this many boundary rays per pixel of the film.
    pub spp_boundary: Option<u32>,
    /// Which estimators `render_diff` runs (default: all).
    pub boundary: BoundaryMode,
    /// Guide the boundary rays with grids fitted by a pilot pass (default off; see
    /// [`crate::boundary::BoundarySettings::guiding`] for the trade-off).
    pub guiding: bool,
    /// Trace forward renders in Embree's default (non-watertight) mode: about 13% faster on
    /// the Cornell box, but a ray through exactly a shared edge may miss both triangles, so
    /// light can slip out of a closed object (a few bins per 1024-spp render of the icosphere
    /// scene of tests/closed_containers.rs). Off by default; derivative renders always trace robustly.
    pub fast_traversal: bool,
    /// What the steady image integrates: the time window (default; paths end where they
    /// leave it, `integrator::window`) or all time (`--steady full`: no path is cut).
    pub steady: SteadyMode,
    /// Render only this shard's sample ranges (`dtr render --shard I/N`), normalised by the
    /// whole render's sample counts, so that the shards' films add up to the whole render
    /// ([`crate::shard`]). Default: the whole render.
    pub shard: crate::shard::Shard,
    /// Write checkpoints (and resume from one): `dtr render --checkpoint SECONDS --resume`
    /// ([`crate::checkpoint`]). Not with per-strategy films.
    pub checkpoint: Option<std::sync::Arc<crate::checkpoint::Checkpointing>>,
    /// Whether the path tracer estimates its time term f·Ṡ_e·ḋ from light points drawn on
    /// the time edges (`integrator::time_edges`; default: wherever they apply) or from its
    /// ordinary contributions (`dtr render --time-edges off`).
    pub time_edges: TimeEdgeMode,
    /// Stops the render from outside when set ([`crate::cancel`]): it then returns
    /// [`Error::Cancelled`].
    pub cancel: crate::cancel::Cancel,
}

/// Whether the render's draws on the time edges take the whole time term of the emitters
/// `needs` picks (`integrator::time_edges::TimeEdges::cover`), or why not.
fn draws_cover(scene: &Scene, motion: &Motion, opts: &RenderOptions, needs: Needs) -> Result<(), Uncovered> {
    let path = opts.integrator.unwrap_or(scene.integrator.kind) == IntegratorKind::Path;
    TimeEdges::cover(scene, motion, path && opts.time_edges == TimeEdgeMode::Auto, needs).map_err(|u| match path {
        true => u,
        false => "BDPT draws no light points on the time edges (the path tracer does: --integrator path)".into(),
    })
}

/// What a derivative render asks of its terms, before it runs: of the time term f·Ṡ_e·ḋ,
/// refused where a delta pulse's is left to paths the draws on the time edges do not make
/// (`time_terms::refuse_uncovered_delta`), said (once per process) where a narrow pulse's is
/// ([`narrow_time_term_warning`]); of the interior's throughput term, said where a parameter
/// slides a shape along one it rests on ([`sliding_contact_warning`]).
pub(crate) fn check_derivative_terms(
    scene: &Scene,
    motion: &Motion,
    params: &[String],
    opts: &RenderOptions,
) -> Result<(), Error> {
    time_terms::refuse_uncovered_delta(scene, motion, params, draws_cover(scene, motion, opts, Needs::Delta))?;
    if let Some(w) = time_terms::narrow_warning(scene, motion, params, draws_cover(scene, motion, opts, Needs::Narrow))
    {
        crate::scene::warnings::warn_once(w);
    }
    if opts.boundary.interior()
        && let Some(w) = crate::params::sliding::sliding_warning(scene, motion)
    {
        crate::scene::warnings::warn_once(w);
    }
    Ok(())
}

/// The warning a derivative render of `params` gives when a parameter shifts in time the light
/// of an emitter whose smooth pulse is narrower than a tenth of a bin
/// ([`NARROW_SIGMA_PER_BIN`](crate::integrator::time_edges::NARROW_SIGMA_PER_BIN)) along paths
/// the draws on the time edges do not make (the emitter seen from the camera while it moves,
/// a point light, `--time-edges off`, BDPT, ...): those estimate its time term without bias but
/// with a variance that grows as the bin width over σ. `None` when there is nothing to say.
pub fn narrow_time_term_warning(
    scene: &Scene,
    params: &[String],
    opts: &RenderOptions,
) -> Result<Option<String>, Error> {
    let motion = Motion::build(scene, params)?;
    Ok(time_terms::narrow_warning(
        scene,
        &motion,
        params,
        draws_cover(scene, &motion, opts, Needs::Narrow),
    ))
}

/// The warning a derivative render of `params` gives when one of them slides a shape along a
/// shape it rests on (faces in contact: `Scene::resting`): the interior estimator's variance
/// is unbounded there (`params::sliding`). `None` when there is nothing to say.
pub fn sliding_contact_warning(scene: &Scene, params: &[String]) -> Result<Option<String>, Error> {
    Ok(crate::params::sliding::sliding_warning(
        scene,
        &Motion::build(scene, params)?,
    ))
}

/// How the path tracer estimates the time term f·Ṡ_e·ḋ of a derivative (Algorithm 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TimeEdgeMode {
    /// Light points drawn where a connection's OPL crosses a bin edge, wherever they apply
    /// (box gate, area emitters with delta pulses or pulses at most half a bin wide, no NLOS
    /// capture); the ordinary contributions elsewhere.
    #[default]
    Auto,
    /// The ordinary contributions only (next-event estimation and emission hits).
    Off,
}

impl crate::named::Named for TimeEdgeMode {
    const ALL: &'static [Self] = &[Self::Auto, Self::Off];

    fn name(self) -> &'static str {
        match self {
            Self::Auto => "auto",
            Self::Off => "off",
        }
    }
}

/// Which parts of the gradient `render_diff` estimates. Tests use the parts to show that the
/// interior alone misses what moving visibility contributes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum BoundaryMode {
    /// Interior (Algorithm 1) + primary + secondary boundary (Algorithm 2).
    #[default]
    Full,
    /// The interior only: wrong wherever a parameter moves a visibility boundary.
    InteriorOnly,
    /// Primary + secondary boundary only; the interior pass is skipped and the primal is zero.
    BoundaryOnly,
    /// The primary boundary term alone (silhouettes seen from the camera): interior and
    /// secondary skipped, the primal zero. For finding which term carries a derivative's noise.
    PrimaryOnly,
    /// The secondary boundary term alone (Algorithm 2 at edges seen from path vertices):
    /// interior and primary skipped, the primal zero.
    SecondaryOnly,
}

impl crate::named::Named for BoundaryMode {
    const ALL: &'static [Self] = &[
        Self::Full,
        Self::InteriorOnly,
        Self::BoundaryOnly,
        Self::PrimaryOnly,
        Self::SecondaryOnly,
    ];

    fn name(self) -> &'static str {
        match self {
            Self::Full => "full",
            Self::InteriorOnly => "interior",
            Self::BoundaryOnly => "boundary",
            Self::PrimaryOnly => "primary",
            Self::SecondaryOnly => "secondary",
        }
    }
}

impl BoundaryMode {
    /// Whether the interior estimator (Algorithm 1) runs.
    pub fn interior(self) -> bool {
        matches!(self, Self::Full | Self::InteriorOnly)
    }

    /// Which boundary terms run where a parameter moves geometry.
    pub fn stages(self) -> crate::boundary::Stages {
        use crate::boundary::Stages;
        match self {
            Self::Full | Self::BoundaryOnly => Stages::BOTH,
            Self::InteriorOnly => Stages::NONE,
            Self::PrimaryOnly => Stages {
                primary: true,
                secondary: false,
            },
            Self::SecondaryOnly => Stages {
                primary: false,
                secondary: true,
            },
        }
    }
}

/// What a render did and how fast.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct RenderStats {
    /// Samples per pixel used (the option's or the scene's).
    pub spp: u32,
    /// Random seed used (the option's or the scene's).
    pub seed: u64,
    /// Worker threads of the pool.
    pub threads: usize,
    /// Wall and CPU seconds of the interior pass (the path or BDPT tiles); the boundary stage
    /// is in `boundary_seconds`, and the whole render in `total_*`.
    pub wall_seconds: f64,
    /// CPU seconds (all threads) of the interior pass.
    pub cpu_seconds: f64,
    /// The whole render: interior pass + boundary stage (+ the window-energy pilot of a
    /// render cut at the window).
    pub total_wall_seconds: f64,
    /// CPU seconds (all threads) of the whole render.
    pub total_cpu_seconds: f64,
    /// Interior paths traced (0 when the interior pass did not run).
    pub paths: u64,
    /// Closest-hit queries of the interior pass (Embree `rtcIntersect`).
    pub intersect_rays: u64,
    /// Shadow (any-hit) queries of the interior pass (Embree `rtcOccluded`).
    pub occluded_rays: u64,
    /// `paths / cpu_seconds` of the interior pass.
    pub paths_per_cpu_second: f64,
    /// Ray queries (closest-hit + shadow) per wall-clock second of the interior pass.
    pub rays_per_second: f64,
    /// Ray queries (closest-hit + shadow) per CPU second of the interior pass.
    pub rays_per_cpu_second: f64,
    /// Samples dropped because they were not finite (should be 0; reported, never hidden).
    pub non_finite_samples: u64,
    /// Wall time of building Embree's BVH of the scene.
    pub bvh_build_seconds: f64,
    /// Where the CPU time went: Embree queries, shading/sampling (the rest of the kernel and
    /// driver), and film binning; seconds, summing to `cpu_seconds` of the tiles.
    pub phase_seconds: PhaseSeconds,
    /// Boundary rays drawn by the secondary-edge pass (0 when the boundary stage did not run:
    /// no requested parameter moves geometry, or `BoundaryMode::InteriorOnly`).
    pub boundary_samples: u64,
    /// Wall time of the boundary stage (primary + secondary, pilot included).
    pub boundary_seconds: f64,
    /// Details of the boundary stage (primary and secondary edges), when it ran.
    pub boundary: Option<crate::boundary::BoundaryStats>,
    /// Embree traversal mode: "robust" (watertight) or "fast" (`--fast-traversal`).
    pub traversal: &'static str,
    /// What the steady images integrate ("window" or "full").
    pub steady: SteadyMode,
    /// The window cut: the largest OPL a path was traced to (metres; `None` with
    /// `--steady full` or without emitters).
    pub opl_cut: Option<f32>,
    /// Where the primal energy fell against the time window (before, inside, after).
    pub energy: WindowEnergy,
    /// The same for each derivative film (inside and outside the window), in parameter order.
    pub deriv_energy: Vec<DerivWindowEnergy>,
    /// Whether paths carried f64 OPLs, and the film time scale and f32 step that decided it.
    pub opl: crate::integrator::opl::OplPrecision,
    /// Whether the path tracer drew its derivatives' time term on the time edges
    /// ([`TimeEdgeMode`]).
    pub time_edges: bool,
}

/// CPU seconds of the interior pass split by phase, apportioned by the tiles' tick counts.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct PhaseSeconds {
    /// Embree queries (closest-hit and shadow rays).
    pub tracing: f64,
    /// Everything else in the kernel and the driver: sampling, BSDFs, MIS, connections.
    pub shading: f64,
    /// Binning contributions into the film through S_e.
    pub film: f64,
}

/// CPU time (user + system, all threads) of this process, seconds (the `cpu-time` crate:
/// `clock_gettime(CLOCK_PROCESS_CPUTIME_ID)` on Unix, `GetProcessTimes` on Windows).
pub fn cpu_seconds() -> f64 {
    cpu_time::ProcessTime::try_now()
        .map(|t| t.as_duration().as_secs_f64())
        .unwrap_or(0.0)
}

/// The most worker threads a render starts (far above any machine's core count; a typo like
/// `--threads 100000` is refused before any thread is spawned).
pub const MAX_THREADS: usize = 4096;

/// Builds a rayon pool whose workers set flush-to-zero / denormals-are-zero, as Embree's
/// documentation asks of every thread that calls it (rtcIntersect / rtcOccluded, "MXCSR").
pub fn thread_pool(threads: Option<usize>) -> Result<rayon::ThreadPool, Error> {
    let n = threads.unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    if n == 0 {
        return Err(Error::Invalid("--threads must be at least 1".into()));
    }
    if n > MAX_THREADS {
        return Err(Error::Invalid(format!(
            "--threads {n} is more than {MAX_THREADS}; use at most one thread per core"
        )));
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(n)
        .start_handler(|_| set_flush_denormals())
        .build()
        .map_err(|e| Error::Invalid(format!("cannot start {n} worker threads: {e}")))
}

/// Renders the forward transient of `scene` (no derivative lanes: the plain f32x8 kernel).
pub fn render(scene: &Scene, opts: &RenderOptions) -> Result<(Transient, RenderStats), Error> {
    let mut run = Run::new(scene, Motion::none(), opts, false)?;
    let mut interior = run.interior(opts, false);
    let stats = run.finish(opts, &mut interior, None);
    run.not_cancelled()?;
    Ok((interior.films.swap_remove(0), stats))
}

/// The parts of a derivative render: each estimator with its own samples and seed stream,
/// one film per parameter in each part. The derivative of the rendered transient is their
/// sum ([`DiffParts::sum`]).
pub struct DiffParts {
    /// The forward transient, from the interior pass (zero with
    /// [`BoundaryMode::BoundaryOnly`]).
    pub primal: Transient,
    /// The interior integral (Algorithm 1), from the path tracer or BDPT.
    pub interior: Vec<Transient>,
    /// The boundary integral at primary edges (silhouettes seen from the camera,
    /// supplemental Eqs. 18–19 on the film); empty when the boundary stage did not run.
    pub primary: Vec<Transient>,
    /// The boundary integral at secondary edges (Algorithm 2); empty like `primary`.
    pub secondary: Vec<Transient>,
    /// What the whole render did.
    pub stats: RenderStats,
}

impl DiffParts {
    /// interior + primary + secondary, per parameter: ∂I/∂θ_k of every bin.
    pub fn sum(&self) -> Vec<Transient> {
        let mut out = self.interior.clone();
        for (k, film) in out.iter_mut().enumerate() {
            if let (Some(p), Some(q)) = (self.primary.get(k), self.secondary.get(k)) {
                film.data
                    .iter_mut()
                    .zip(p.data.iter().zip(&q.data))
                    .for_each(|(d, (a, b))| *d += a + b);
                film.steady
                    .iter_mut()
                    .zip(p.steady.iter().zip(&q.steady))
                    .for_each(|(d, (a, b))| *d += a + b);
            }
        }
        out
    }
}

/// Renders the transient and the derivative of every bin with respect to each parameter in
/// `params`: interior + primary + secondary ([`render_diff_parts`]). Returns the transient
/// and one derivative transient per parameter, in order.
///
/// Parameters are the names of the scene's `[[param]]` entries (`dtr info SCENE` lists
/// them). Below, the wall albedo a of the closed room of `scenes/diff_room.toml`: every path
/// that reaches the camera scatters k ≥ 1 times off the walls, so its contribution is
/// a^k · g and its derivative k · a^(k−1) · g. Summed over the film, with the same samples,
/// ∂I/∂a ≥ I / a.
///
/// ```
/// use difftransient::{RenderOptions, Scene, render_diff};
/// use std::path::Path;
///
/// let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/diff_room.toml"));
/// let scene = Scene::load(path, &[])?;
/// let opts = RenderOptions { spp: Some(2), ..Default::default() };
/// let (primal, grads, _stats) = render_diff(&scene, &["albedo".to_string()], &opts)?;
///
/// assert_eq!(grads.len(), 1);
/// assert_eq!(grads[0].shape(), primal.shape());
/// let total: f64 = primal.data.iter().map(|&v| v as f64).sum();
/// let d_total: f64 = grads[0].data.iter().map(|&v| v as f64).sum();
/// assert!(total > 0.0);
/// assert!(d_total >= total / 0.6 * (1.0 - 1e-4), "{d_total} vs {total}");
/// # Ok::<(), difftransient::Error>(())
/// ```
pub fn render_diff(
    scene: &Scene,
    params: &[String],
    opts: &RenderOptions,
) -> Result<(Transient, Vec<Transient>, RenderStats), Error> {
    let parts = render_diff_parts(scene, params, opts)?;
    let grad = parts.sum();
    Ok((parts.primal, grad, parts.stats))
}

/// The parts of the derivative with respect to each parameter in `params`, in one run:
/// the interior pass (Algorithm 1: İ += ḟ·s + f·Ṡ_e·ḋ, with the transient itself) and, when
/// a parameter moves geometry, the boundary stage (primary and secondary edges). The kernel
/// carries `Dual8<P>` with the smallest P in {1, 2, 4, 8, 16} that fits.
pub fn render_diff_parts(scene: &Scene, params: &[String], opts: &RenderOptions) -> Result<DiffParts, Error> {
    let motion = Motion::build(scene, params)?;
    if motion.len() > MAX_PARAMS {
        return Err(Error::Invalid(format!(
            "at most {MAX_PARAMS} parameters per render (asked for {})",
            motion.len()
        )));
    }
    check_derivative_terms(scene, &motion, params, opts)?;
    let mut run = Run::new(scene, motion, opts, false)?;
    let mut interior = run.interior(opts, false);
    let boundary = run.boundary(opts);
    let stats = run.finish(opts, &mut interior, boundary.as_ref());
    run.not_cancelled()?;
    let mut films = interior.films.into_iter();
    let primal = films.next().expect("the primal film");
    let (primary, secondary) = boundary.map_or((Vec::new(), Vec::new()), |b| (b.primary, b.secondary));
    Ok(DiffParts {
        primal,
        interior: films.collect(),
        primary,
        secondary,
        stats,
    })
}

/// Renders with BDPT and also returns one transient per (s, t) strategy, in the order of
/// [`bdpt::film::strategy_list`] (MIS-weighted; they sum to the transient). Like pbrt-v4's
/// `visualizeStrategies`, for debugging. Errors unless the integrator is BDPT.
#[allow(clippy::type_complexity)]
pub fn render_strategies(
    scene: &Scene,
    opts: &RenderOptions,
) -> Result<(Transient, Vec<((usize, usize), Transient)>, RenderStats), Error> {
    if opts.integrator.unwrap_or(scene.integrator.kind) != IntegratorKind::Bdpt {
        return Err(Error::Invalid(format!(
            "{}: per-strategy transients (--strategies) need the bidirectional integrator: set [integrator] kind = \"bdpt\" or pass --integrator bdpt",
            scene.source.display()
        )));
    }
    let list = bdpt::film::strategy_list(scene.integrator.max_bounces);
    let f = &scene.film;
    let frame_bytes = f.width as usize * f.height as usize * (f.axis.bins + 1) * f.channels * 4;
    if frame_bytes.saturating_mul(list.len() + 1) > BDPT_FILM_BUDGET_BYTES {
        return Err(Error::Invalid(format!(
            "{}: --strategies would keep {} full transients ({} bounces) in memory, more than {} GiB; \
             lower [integrator] max_bounces, the resolution or the number of bins",
            scene.source.display(),
            list.len(),
            scene.integrator.max_bounces,
            BDPT_FILM_BUDGET_BYTES >> 30
        )));
    }
    let mut run = Run::new(scene, Motion::none(), opts, true)?;
    let mut interior = run.interior(opts, true);
    let stats = run.finish(opts, &mut interior, None);
    run.not_cancelled()?;
    let strategies = std::mem::take(&mut interior.strategies);
    Ok((
        interior.films.swap_remove(0),
        list.into_iter().zip(strategies).collect(),
        stats,
    ))
}

/// Memory the full-frame films of a BDPT render may take together (`--strategies` keeps one
/// per strategy).
const BDPT_FILM_BUDGET_BYTES: usize = 2 << 30;

/// Bytes the films of a render hold at once: the output transients and steady images (one
/// per derivative too), plus per worker one tile film (path tracer; its bins span the whole
/// time axis), or the full-frame rows and a wave of unit films (BDPT), plus the boundary stage's derivative
/// film. Films that carry derivatives accumulate in f64. In u128: 16384² pixels × 2²⁴ bins
/// must not overflow.
/// With `checkpointing`, a snapshot of the films is taken while they are written (path
/// tracer: the frame; BDPT: the rows), so those count twice.
fn film_bytes(
    scene: &Scene,
    derivs: usize,
    kind: IntegratorKind,
    threads: usize,
    per_strategy: bool,
    checkpointing: bool,
) -> u128 {
    let f = &scene.film;
    let (px, bins, c) = (
        f.width as u128 * f.height as u128,
        f.axis.bins as u128,
        f.channels as u128,
    );
    let frame = px * (bins * c + c);
    let acc = if derivs > 0 { 8 } else { 4 };
    let d = derivs as u128;
    let outputs = frame * (1 + d) * 4;
    let workers = match kind {
        IntegratorKind::Path => {
            // a tile film per worker, and the block films of tiles cut into sample blocks,
            // kept until their tile's last block has run (`sample_blocks`), at their most
            let tile = tile_film_bytes(scene, derivs);
            let tiles = tile_rects(scene).len();
            let per_tile = blocks_per_tile(tiles, u64::MAX, tile) as u128;
            let parked = if per_tile > 1 {
                tiles as u128 * per_tile * tile
            } else {
                0
            };
            threads as u128 * tile + parked
        }
        IntegratorKind::Bdpt => {
            let strategies = if per_strategy {
                bdpt::film::strategy_list(scene.integrator.max_bounces).len() as u128
            } else {
                0
            };
            // the full-frame rows, and two waves of unit films with their splats onto other
            // pixels at their worst (`bdpt::units`): one tracing while the other is added
            let rows = frame * ((1 + d) * acc + strategies * 4);
            let unit = bdpt::units::unit_bytes(scene, TILE, derivs, per_strategy);
            rows + 2 * (bdpt::units::wave_len(unit) * unit) as u128
        }
    };
    let copies = if checkpointing { 2 } else { 1 };
    outputs * copies + workers * if kind == IntegratorKind::Bdpt { copies } else { 1 } + frame * d * 8
}

/// Bytes of one path tracer tile film of `scene` with `derivs` derivative blocks: 8 × 8
/// pixels, or 8 sensor columns × every laser row (`tile_rects`), every bin and the steady
/// image, in f64 with derivatives and f32 without.
fn tile_film_bytes(scene: &Scene, derivs: usize) -> u128 {
    let f = &scene.film;
    let tile_px = match &scene.nlos {
        Some(n) if n.exhaustive() => TILE as u128 * n.lasers.len() as u128,
        _ => (TILE * TILE) as u128,
    };
    let (bins, c) = (f.axis.bins as u128, f.channels as u128);
    let acc = if derivs > 0 { 8 } else { 4 };
    tile_px * (bins * c + c) * (1 + derivs as u128) * acc
}

/// Memory the system can still give (Linux `MemAvailable`), if it can be read.
fn available_memory() -> Option<u128> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kib: u128 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Refuses what the materials beyond Lambertian do not support yet, naming the material.
/// Derivatives through a Dirac lobe (smooth conductor or dielectric) run in the path tracer,
/// whose vertex after a Dirac lobe is in ray form (`integrator::bsdf::delta`), and in BDPT for
/// parameters that move no vertex; refused are: BDPT's derivatives through one for a
/// parameter that moves a vertex (geometry, or an index that turns a Dirac refraction: its
/// strategies would move a specular chain in different ways, so constant MIS weights would
/// not give the derivative); with one in the scene, a parameter
/// that moves geometry (the boundary theory assumes no Dirac BSDFs, supplemental assumption
/// A.4) or changes the index at a smooth dielectric (edges seen through it then move on the
/// film: a boundary term no estimator computes) unless `--estimators interior` asks for the
/// interior alone. The boundary stage runs with rough conductors and rough dielectrics: a
/// path through glass has vertices on its surfaces, so a segment grazing an edge still jumps
/// from V = 1 to 0, and the subpaths start in the segment's medium (`boundary/secondary.rs`).
pub(crate) fn check_materials(
    scene: &Scene,
    motion: &Motion,
    kind: IntegratorKind,
    boundary: BoundaryMode,
) -> Result<(), Error> {
    if scene.materials.iter().all(|m| m.material.is_diffuse()) {
        return Ok(());
    }
    let refuse = |why: String| Err(Error::Invalid(format!("{}: {why}", scene.source.display())));
    if !motion.is_empty()
        && let Some(d) = scene.first_delta_material()
    {
        let smooth = |why: &str| {
            refuse(format!(
                "{} is smooth (a Dirac lobe): {why}",
                describe_material(scene, d)
            ))
        };
        if kind == IntegratorKind::Bdpt && (motion.moves_geometry() || bends_smooth_dielectric(scene, motion).is_some())
        {
            return smooth(
                "BDPT differentiates through it only parameters that move no path vertex (albedo, reflectance, radiance, pulse offset, an index no smooth dielectric bends with), since its strategies would move a specular chain in different ways; render this derivative with [integrator] kind = \"path\"",
            );
        }
        if boundary.stages().any() {
            if motion.moves_geometry() {
                return smooth(
                    "a parameter that moves geometry needs the boundary stage, which assumes no Dirac lobes (supplemental assumption A.4); differentiate another parameter or pass --estimators interior for the interior term alone (not the derivative: it leaves out the silhouettes and shadows that move, also those seen in or through the smooth surface)",
                );
            }
            if let Some(g) = bends_smooth_dielectric(scene, motion) {
                return refuse(format!(
                    "{} is a smooth dielectric whose index a requested parameter changes: edges seen through it move on the film, a boundary term that is not computed; pass --estimators interior for the interior term alone",
                    describe_material(scene, g),
                ));
            }
        }
    }
    Ok(())
}

/// Refuses a camera inside a dielectric whose index differs from the scene's medium: every
/// path starts in `[medium] eta` (the kernel tracks the medium from the camera on), so the
/// first segment's OPL and the refraction on its way out were those of the medium outside,
/// silently (a camera in a glass cube of index 1.5 put the arrival 1 m early per metre of
/// glass).
fn check_camera_medium(ctx: &RenderContext) -> Result<(), Error> {
    let scene = ctx.scene;
    let (_, _, forward) = scene.camera.frame();
    let mut counts = crate::integrator::trace::RayCounts::default();
    let Some((prim, eta)) =
        crate::integrator::medium::first_dielectric(ctx, scene.camera.position, forward, &mut counts)
    else {
        return Ok(());
    };
    if eta == scene.eta {
        return Ok(());
    }
    let shape = &scene.shapes[scene.geometry.tri_shape[prim as usize] as usize];
    Err(Error::Invalid(format!(
        "{}: the camera lies inside {} of shape {:?} (index {eta}), but every path starts in the scene's medium (medium.eta = {}): its first segment would be timed and refracted as if in that medium. Move the camera out of the shape, or set medium.eta = {eta} and leave out the shape around the camera",
        scene.source.display(),
        describe_material(scene, ctx.tri_material[prim as usize]),
        shape.name,
        scene.eta,
    )))
}

/// Refuses a boundary stage whose moving shapes cross another surface or themselves: the
/// crossing curve is a discontinuity on no mesh edge, which the boundary stage does not sample
/// (`boundary::interpenetration`).
fn check_crossings(ctx: &RenderContext, device: &Device, pool: &rayon::ThreadPool) -> Result<(), Error> {
    let Some(c) = crate::boundary::interpenetration::find_crossing(ctx, device, pool)? else {
        return Ok(());
    };
    let scene = ctx.scene;
    let name = |s: u32| &scene.shapes[s as usize].name;
    let at = scene.to_world(c.at);
    let other = if c.edge_shape == c.face_shape {
        "itself".to_string()
    } else {
        format!("shape {:?}", name(c.face_shape))
    };
    // an emitter flush with a face was lifted off it at load (scene::flush): say so, since
    // the file shows the two merely touching
    let lifted = [c.edge_shape, c.face_shape]
        .into_iter()
        .find(|&s| scene.lifted_emitters.contains(name(s)))
        .map(|s| format!(" (shape {:?} is an area emitter, lifted at load off a face of another shape in its plane, so that its light wins: an object resting on an emitter is not supported)", name(s)))
        .unwrap_or_default();
    Err(Error::Invalid(format!(
        "{}: shape {:?} crosses {other}{lifted} (an edge passes through a face at ({:.6}, {:.6}, {:.6})), and a requested parameter moves {:?}: the curve where two surfaces cross is a discontinuity on no mesh edge, which the boundary stage does not sample, so the derivative would miss its boundary term. Move the shapes apart, or let them only touch (a face, edge or vertex resting on a surface is supported), or pass --estimators interior for the interior term alone",
        scene.source.display(),
        name(c.edge_shape),
        at.x,
        at.y,
        at.z,
        name(c.moved),
    )))
}

/// `material "NAME" (type T)` for messages; a rough dielectric that renders as a smooth one
/// because its index equals the one outside it ([`Scene::is_dirac`]) says so, and how to
/// keep it rough.
fn describe_material(scene: &Scene, i: u32) -> String {
    let m = &scene.materials[i as usize];
    let rough_matched = match m.material {
        crate::scene::Material::Dielectric { roughness, int_ior, .. } if roughness > 0.0 => {
            scene.is_dirac(i).then_some(int_ior)
        }
        _ => None,
    };
    match rough_matched {
        Some(ior) => format!(
            "material {:?} (type roughdielectric, int_ior {ior} equal to the index outside it, so every microfacet refracts straight through; set int_ior a little off it to keep the surface rough)",
            m.name
        ),
        None => format!("material {:?} (type {})", m.name, m.material.type_name()),
    }
}

/// The index of the first smooth dielectric whose relative index a parameter of `motion`
/// changes: its own `ior`, the `ior` of the material it names as exterior, or the medium's η
/// when it has none.
fn bends_smooth_dielectric(scene: &Scene, motion: &Motion) -> Option<u32> {
    scene.materials.iter().enumerate().find_map(|(i, m)| match m.material {
        crate::scene::Material::Dielectric { exterior, .. } if scene.is_dirac(i as u32) => {
            let bends = (0..motion.len()).any(|k| {
                motion.ior[k] == Some(i as u32)
                    || (exterior.is_some() && motion.ior[k] == exterior)
                    || (exterior.is_none() && motion.eta[k])
            });
            bends.then_some(i as u32)
        }
        _ => None,
    })
}

/// Refuses a render whose films cannot fit in the memory available, before anything is
/// allocated (such films used to abort the process with SIGABRT), naming the size and the
/// fields that cause it.
fn check_memory(
    scene: &Scene,
    derivs: usize,
    kind: IntegratorKind,
    threads: Option<usize>,
    per_strategy: bool,
    checkpointing: bool,
) -> Result<(), Error> {
    let threads = threads.unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    let need = film_bytes(
        scene,
        derivs,
        kind,
        threads.clamp(1, MAX_THREADS),
        per_strategy,
        checkpointing,
    );
    // without /proc/meminfo, refuse only what no machine has (1 PiB)
    let have = available_memory().unwrap_or(1 << 50);
    if need <= have {
        return Ok(());
    }
    let gib = |b: u128| b as f64 / (1u64 << 30) as f64;
    let f = &scene.film;
    if let Some(n) = &scene.nlos {
        return Err(Error::Invalid(format!(
            "{}: the NLOS capture needs about {:.1} GiB for its films, but {:.1} GiB of memory are available: \
             a {} scan of {} laser point(s) × {} sensor point(s) (nlos.grid {}×{}{}) × film.bins {} × {} channel(s) × {} film(s); \
             scan fewer points (nlos.grid, nlos.laser_grid), lower film.bins or narrow the window",
            scene.source.display(),
            gib(need),
            gib(have),
            if n.exhaustive() { "exhaustive" } else { "confocal" },
            n.lasers.len(),
            n.sensors.len(),
            n.sensors.nx,
            n.sensors.ny,
            if n.exhaustive() {
                format!(", nlos.laser_grid {}×{}", n.lasers.nx, n.lasers.ny)
            } else {
                String::new()
            },
            f.axis.bins,
            f.channels,
            1 + derivs
        )));
    }
    Err(Error::Invalid(format!(
        "{}: the render needs about {:.1} GiB for its films, but {:.1} GiB of memory are available: \
         camera.resolution {}×{} × film.bins {} × {} channel(s) × {} film(s) (the transient{}); \
         lower the resolution or the number of bins, narrow the window, or differentiate fewer \
         parameters at once",
        scene.source.display(),
        gib(need),
        gib(have),
        f.width,
        f.height,
        f.axis.bins,
        f.channels,
        1 + derivs,
        if derivs > 0 {
            " and one per --diff parameter"
        } else {
            ""
        }
    )))
}

/// What an NLOS capture cannot render yet, refused before anything runs: BDPT (its camera
/// subpaths start at the pinhole), and derivatives with respect to a parameter that moves the
/// relay wall (its sensor and laser points are fixed points of the scan). Other geometry is
/// differentiated with the boundary term at the wall's sensor and laser points
/// (`boundary::secondary`).
fn check_nlos(scene: &Scene, spec: &NlosSpec, motion: &Motion) -> Result<(), Error> {
    let file = scene.source.display();
    if let Some(k) = (0..motion.len()).find(|&k| motion.fields[k].iter().any(|(s, _)| *s == spec.wall as usize)) {
        return Err(Error::Invalid(format!(
            "{file}: --diff {}: the parameter moves the relay wall {:?}: an NLOS capture's sensor and laser points \
             are fixed points of the wall, so the wall cannot be differentiated; differentiate the hidden scene instead",
            motion.names.get(k).map_or("?", |n| n.as_str()),
            scene.shapes[spec.wall as usize].name
        )));
    }
    Ok(())
}

/// Picks the kernel instance for (derivative lanes, lane width, channels) and calls
/// `$f::<R, C>($args)`.
macro_rules! dispatch {
    ($derivs:expr, $lanes:expr, $channels:expr, $f:ident ( $($arg:expr),* )) => {
        match ($derivs, $lanes, $channels) {
            (0, $crate::render::Lanes::Simd8, 1) => $f::<$crate::kernel::f32x8, 1, _>($($arg),*),
            (0, $crate::render::Lanes::Simd8, _) => $f::<$crate::kernel::f32x8, 3, _>($($arg),*),
            (0, $crate::render::Lanes::Scalar, 1) => $f::<f32, 1, _>($($arg),*),
            (0, $crate::render::Lanes::Scalar, _) => $f::<f32, 3, _>($($arg),*),
            (1, _, 1) => $f::<$crate::kernel::Dual8<1>, 1, _>($($arg),*),
            (1, _, _) => $f::<$crate::kernel::Dual8<1>, 3, _>($($arg),*),
            (2, _, 1) => $f::<$crate::kernel::Dual8<2>, 1, _>($($arg),*),
            (2, _, _) => $f::<$crate::kernel::Dual8<2>, 3, _>($($arg),*),
            (3..=4, _, 1) => $f::<$crate::kernel::Dual8<4>, 1, _>($($arg),*),
            (3..=4, _, _) => $f::<$crate::kernel::Dual8<4>, 3, _>($($arg),*),
            (5..=8, _, 1) => $f::<$crate::kernel::Dual8<8>, 1, _>($($arg),*),
            (5..=8, _, _) => $f::<$crate::kernel::Dual8<8>, 3, _>($($arg),*),
            (_, _, 1) => $f::<$crate::kernel::Dual8<16>, 1, _>($($arg),*),
            (_, _, _) => $f::<$crate::kernel::Dual8<16>, 3, _>($($arg),*),
        }
    };
}

pub(crate) use dispatch;

// The widest instance dispatch! picks has a derivative lane for every parameter allowed.
const _: () = assert!(<Dual8<16> as Real>::DERIVS == MAX_PARAMS);

/// One render's shared state: the scene prepared for the kernel (BVH, emitters, motion,
/// window cut), the thread pool, and the samples and seed every estimator draws from.
pub(crate) struct Run<'s> {
    pub(crate) ctx: RenderContext<'s>,
    pub(crate) pool: rayon::ThreadPool,
    pub(crate) spp: u32,
    /// The sample indices this run traces: `0..spp`, or a shard's part of them.
    pub(crate) samples: std::ops::Range<u64>,
    pub(crate) seed: u64,
    pub(crate) derivs: usize,
    pub(crate) kind: IntegratorKind,
    pub(crate) robust: bool,
    pub(crate) bvh_build_seconds: f64,
    /// With checkpoints: what the finished interior pass saved (then the boundary stage).
    pub(crate) saved: std::sync::Mutex<Option<Saved>>,
    pub(crate) checkpoint: Option<std::sync::Arc<Checkpointing>>,
    /// Whether the boundary stage runs after the interior pass: some parameter moves
    /// geometry and the options ask for it.
    pub(crate) boundary_wanted: bool,
}

fn lock<T>(m: &std::sync::Mutex<T>) -> std::sync::MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// A checkpoint that cannot be written does not stop the render: it is reported once.
fn report(ck: &Checkpointing, r: Result<(), Error>) {
    if let Err(e) = r {
        log::warn!("checkpoint {} not written: {e}", ck.path.display());
    }
}

/// The interior pass's films (the primal, then one per parameter), per-strategy films (BDPT
/// `--strategies`), and per tile or chunk, in order: (counts, primal energy before and after
/// the window, Σ of each film block).
struct Interior {
    films: Vec<Transient>,
    strategies: Vec<Transient>,
    tallies: Vec<(PathCounts, [f64; 2], Vec<f64>)>,
    /// Whether the pass ran (a boundary-only derivative render skips it).
    ran: bool,
    wall: f64,
    cpu: f64,
}

impl<'s> Run<'s> {
    /// Checks the options and the memory the films need, builds the BVH and the pool.
    pub(crate) fn new(
        scene: &'s Scene,
        motion: Motion,
        opts: &RenderOptions,
        per_strategy: bool,
    ) -> Result<Self, Error> {
        Self::with_films(scene, motion, opts, per_strategy, true)
    }

    /// [`Run::new`]; `derivative_films`: whether the render stores a film per parameter (an
    /// adjoint render contracts them away, so only the primal counts for its memory check).
    pub(crate) fn with_films(
        scene: &'s Scene,
        motion: Motion,
        opts: &RenderOptions,
        per_strategy: bool,
        derivative_films: bool,
    ) -> Result<Self, Error> {
        crate::simd::warn_if_slower_than_the_cpu();
        let spp = opts.spp.unwrap_or(scene.integrator.spp);
        if spp == 0 {
            return Err(Error::Invalid(format!(
                "{}: spp must be at least 1 (got 0)",
                scene.source.display()
            )));
        }
        if opts.spp_boundary == Some(0) {
            return Err(Error::Invalid(format!(
                "{}: spp_boundary must be at least 1 (got 0)",
                scene.source.display()
            )));
        }
        if per_strategy && opts.checkpoint.is_some() {
            return Err(Error::Invalid(format!(
                "{}: per-strategy films (--strategies) cannot be checkpointed; render them without --checkpoint",
                scene.source.display()
            )));
        }
        let derivs = motion.len();
        let kind = opts.integrator.unwrap_or(scene.integrator.kind);
        if let Some(spec) = &scene.nlos {
            check_nlos(scene, spec, &motion)?;
        }
        check_materials(scene, &motion, kind, opts.boundary)?;
        check_memory(
            scene,
            if derivative_films { derivs } else { 0 },
            kind,
            opts.threads,
            per_strategy,
            opts.checkpoint.is_some(),
        )?;
        set_flush_denormals();
        let device = Device::new("")?;
        let t_build = Instant::now();
        // Watertight traversal unless a forward render opts out (`fast_traversal`); renders
        // with derivative lanes always keep it, since the boundary stage aims rays at edges.
        let robust = derivs > 0 || !opts.fast_traversal;
        let mut ctx = RenderContext::with_traversal(scene, &device, robust)?;
        ctx.motion = motion;
        ctx.cancel = opts.cancel.clone();
        if opts.time_edges == TimeEdgeMode::Auto {
            ctx.use_time_edges();
        }
        ctx.cut_to_window(opts.steady);
        check_camera_medium(&ctx)?;
        let boundary_wanted = derivs > 0 && ctx.motion.moves_geometry() && opts.boundary.stages().any();
        let pool = thread_pool(opts.threads)?;
        if boundary_wanted {
            check_crossings(&ctx, &device, &pool)?;
        }
        Ok(Self {
            ctx,
            pool,
            spp,
            samples: opts.shard.range(spp as u64),
            seed: opts.seed.unwrap_or(scene.integrator.seed),
            derivs,
            kind,
            robust,
            bvh_build_seconds: t_build.elapsed().as_secs_f64(),
            saved: std::sync::Mutex::new(None),
            checkpoint: opts.checkpoint.clone(),
            boundary_wanted,
        })
    }

    fn checkpointing(&self) -> Option<&std::sync::Arc<Checkpointing>> {
        self.checkpoint.as_ref()
    }

    /// The checkpoint this render resumes from, once (for `units` units of the interior).
    fn resumed(&self, units: usize) -> Option<Saved> {
        let ck = self.checkpointing()?;
        let saved = ck.resume.lock().unwrap_or_else(|e| e.into_inner()).take()?;
        assert_eq!(
            saved.units, units,
            "a checkpoint of the same render (identity checked) has the same units"
        );
        *self.saved.lock().unwrap_or_else(|e| e.into_inner()) = Some(Saved {
            boundary: saved.boundary.clone(),
            ..Default::default()
        });
        Some(saved)
    }

    /// On SIGINT/SIGTERM/SIGHUP, write the state of the running pass, as `snapshot` takes it.
    fn watch(&self, snapshot: impl Fn() -> Saved + Send + 'static) {
        if let Some(ck) = self.checkpointing() {
            let ck = ck.clone();
            crate::checkpoint::set_signal_writer(Some(Box::new(move || report(&ck, ck.write(&snapshot())))));
        }
    }

    /// Writes a checkpoint of the state `snapshot` takes, when one is due.
    fn checkpoint_if_due(&self, snapshot: impl FnOnce() -> Saved) {
        if let Some(ck) = self.checkpointing().filter(|ck| ck.due()) {
            report(ck, ck.write(&snapshot()));
        }
    }

    /// Ends the signal writer of the pass whose state is `state`, and takes the state
    /// (cloned if a signal writer still held it).
    fn end_watch(state: std::sync::Arc<std::sync::Mutex<Saved>>) -> Saved {
        crate::checkpoint::set_signal_writer(None);
        std::sync::Arc::try_unwrap(state)
            .map(|m| m.into_inner().unwrap_or_else(|e| e.into_inner()))
            .unwrap_or_else(|arc| lock(&arc).clone())
    }

    /// The state at the end of the interior pass. With checkpoints, when the boundary stage
    /// is still to run, it is written (so a render stopped in that stage resumes after the
    /// interior) and kept for the boundary stage's checkpoint. When only the outputs follow,
    /// it is written only if a periodic checkpoint is due, and never kept: a render stopped
    /// while its outputs are written then resumes from its last periodic checkpoint, as it
    /// would anywhere else, and writing the outputs no longer waits on a whole extra
    /// checkpoint (on a 256×256×2000 forward render: 7–11 s on top of 4.4 s, and 1.5 GB of
    /// memory for the copy).
    fn finish_pass(&self, st: Saved) -> Saved {
        if let Some(ck) = self.checkpointing() {
            let mut kept = self.saved.lock().unwrap_or_else(|e| e.into_inner());
            let boundary = kept.take().and_then(|k| k.boundary);
            if boundary.is_some() {
                // resumed after the boundary stage: it is kept for `boundary`, nothing to write
                *kept = Some(Saved {
                    boundary,
                    ..Default::default()
                });
            } else if self.boundary_wanted {
                report(ck, ck.write(&st));
                *kept = Some(st.clone());
            } else if ck.due() {
                report(ck, ck.write(&st));
            }
        }
        st
    }

    /// The interior estimator (Algorithm 1) over every pixel: the path tracer over tiles or
    /// BDPT over waves of units (a tile, a block of samples); films averaged over spp.
    fn interior(&self, opts: &RenderOptions, per_strategy: bool) -> Interior {
        let (ctx, spp, seed, derivs) = (&self.ctx, self.spp, self.seed, self.derivs);
        let samples = &self.samples;
        let scene = ctx.scene;
        let (w, h) = (scene.film.width as usize, scene.film.height as usize);
        let axis = scene.film.axis;
        let channels = scene.film.channels;
        let ran = opts.boundary.interior() || derivs == 0;
        let rects = if ran { tile_rects(scene) } else { Vec::new() };
        let bar = progress_bar(
            opts.progress,
            rects.len() as u64,
            "{elapsed_precise} [{bar:40}] {pos}/{len} tiles ({eta})",
        );
        let cpu0 = cpu_seconds();
        let t0 = Instant::now();
        let mut out = Transient::zeros_many(1 + derivs, w, h, axis, channels);
        let mut strategy_out = Vec::new();
        let tallies: Vec<(PathCounts, [f64; 2], Vec<f64>)> = match self.kind {
            IntegratorKind::Path => {
                // Tiles cover disjoint pixels and `out` starts at zero, so each pixel receives
                // exactly one tile's sums (0 + x = x): storing tiles as they finish gives the
                // same bytes for any order and thread count, and a checkpoint's films (the
                // finished tiles, zero elsewhere) resume to the same bytes. The stores take
                // no lock (`SharedFrame`); each worker reuses one film across its tiles.
                // A film of few tiles is cut into more units, each a tile and a block of its
                // samples ([`sample_blocks`]), so that many threads have work; a tile's block
                // films are added in block order once all have run, then stored.
                let blocks = if ran {
                    sample_blocks(rects.len(), samples, tile_film_bytes(scene, derivs))
                } else {
                    Vec::new()
                };
                let per_tile = blocks.len().max(1);
                let units = rects.len() * per_tile;
                let mut state = self.resumed(units).unwrap_or_else(|| Saved {
                    units,
                    done: vec![false; units],
                    tallies: vec![None; units],
                    frame: std::mem::take(&mut out),
                    ..Default::default()
                });
                bar.set_length(units as u64);
                bar.inc(state.done_units() as u64);
                let tiles_done: Vec<bool> = (0..rects.len()).map(|i| tile_done(&state.done, i, per_tile)).collect();
                let todo: Vec<usize> = (0..units).filter(|&u| !state.done[u]).collect();
                let frame = std::sync::Arc::new(SharedFrame::new(
                    std::mem::take(&mut state.frame),
                    rects.clone(),
                    &tiles_done,
                ));
                let state = std::sync::Arc::new(std::sync::Mutex::new(state));
                // a snapshot: the finished tiles' films with their tallies, while the stores go on
                let n_tiles = rects.len();
                let snapshot = {
                    let (frame, state) = (frame.clone(), state.clone());
                    move || {
                        let (st, films) = frame.snapshot(|| {
                            let st = lock(&state).clone();
                            let done = (0..n_tiles).map(|i| tile_done(&st.done, i, per_tile)).collect();
                            (st, done)
                        });
                        Saved { frame: films, ..st }
                    }
                };
                self.watch(snapshot.clone());
                // each tile's block films with their tallies, kept until the tile's last
                // block has run (a tile of one block is stored at once)
                type Parked = Vec<Option<(TileFilm, crate::checkpoint::Tally)>>;
                let parked: Vec<std::sync::Mutex<Parked>> = (0..rects.len())
                    .map(|_| std::sync::Mutex::new((0..per_tile).map(|_| None).collect()))
                    .collect();
                let spares = std::sync::Mutex::new(Vec::<TileFilm>::new());
                self.pool.install(|| {
                    todo.par_iter().for_each_init(
                        || None::<TileFilm>,
                        |spare, &u| {
                            let (i, b) = (u / per_tile, u % per_tile);
                            let (x0, y0, tw, th) = rects[i];
                            let reused = spare.take().or_else(|| lock(&spares).pop());
                            let mut film = match reused {
                                Some(mut f) => {
                                    f.reset(x0, y0, tw, th);
                                    f
                                }
                                None => ctx.tile_film(x0, y0, tw, th, derivs),
                            };
                            let mut counts = PathCounts::default();
                            let tick0 = crate::timing::ticks();
                            let (f, c) = (&mut film, &mut counts);
                            let block = blocks.get(b).unwrap_or(samples);
                            dispatch!(
                                derivs,
                                opts.lanes,
                                channels,
                                render_tile(ctx, seed, spp, block, w, (x0, y0, tw, th), f, c)
                            );
                            counts.total_ticks = crate::timing::ticks() - tick0;
                            let tally = (counts, film.tails(), film.block_sums());
                            let all = {
                                let mut p = lock(&parked[i]);
                                p[b] = Some((film, tally));
                                p.iter().all(Option::is_some).then(|| std::mem::take(&mut *p))
                            };
                            if let Some(all) = all {
                                let mut all = all.into_iter().map(|p| p.expect("every block ran"));
                                let (mut sum, first) = all.next().expect("a tile has blocks");
                                let mut kept = vec![first];
                                for (f, t) in all {
                                    sum.add_film(&f);
                                    kept.push(t);
                                    lock(&spares).push(f);
                                }
                                frame.store(i, &sum, || {
                                    let mut st = lock(&state);
                                    for (k, t) in kept.into_iter().enumerate() {
                                        st.done[i * per_tile + k] = true;
                                        st.tallies[i * per_tile + k] = Some(t);
                                    }
                                });
                                *spare = Some(sum);
                            }
                            self.checkpoint_if_due(&snapshot);
                            bar.inc(1);
                        },
                    )
                });
                drop(snapshot);
                let mut st = Self::end_watch(state);
                // every tile is stored now: a copy of all of them is the whole frame
                st.frame = std::sync::Arc::try_unwrap(frame)
                    .map(SharedFrame::into_films)
                    .unwrap_or_else(|frame| frame.snapshot(|| ((), vec![true; rects.len()])).1);
                let st = self.finish_pass(st);
                out = st.frame;
                st.tallies.into_iter().map(|t| t.expect("every unit ran")).collect()
            }
            IntegratorKind::Bdpt => {
                // Units (a tile, a block of samples) run in waves; after each wave, while the
                // next one traces, every unit's tile and splats onto other pixels are added to
                // the full-frame rows, row by row in parallel, unit by unit in order
                // (`bdpt::units`). The rows live in the state as the checkpoint's films
                // between waves (moved, not copied), so a checkpoint or a signal always sees
                // whole waves.
                let unit_bytes = bdpt::units::unit_bytes(scene, TILE, derivs, per_strategy);
                let units = bdpt::units::Units::new(scene, TILE, if ran { samples } else { &(0..0) }, unit_bytes);
                let waves = units.waves();
                bar.set_length(units.len() as u64);
                let mut rows: Vec<BdptFilm> = (0..h)
                    .map(|y| BdptFilm::new(ctx, (0, y, w, 1), derivs, per_strategy, false))
                    .collect();
                let mut state = Saved {
                    units: waves.len(),
                    done: vec![false; waves.len()],
                    tallies: vec![None; waves.len()],
                    chunks: rows.iter_mut().map(|r| Some(r.film.take_sums())).collect(),
                    ..Default::default()
                };
                if let Some(saved) = self.resumed(waves.len()) {
                    state = saved;
                }
                for (done, wave) in state.done.iter().zip(&waves) {
                    if *done {
                        bar.inc(wave.len() as u64);
                    }
                }
                let state = std::sync::Arc::new(std::sync::Mutex::new(state));
                let snapshot = {
                    let state = state.clone();
                    move || lock(&state).clone()
                };
                self.watch(snapshot.clone());
                // Wave k traces while wave k - 1's units are added to the rows (`rayon::join`),
                // so no thread waits for the adds, and the adds fill the threads that would
                // wait for the wave's slowest unit. Two sets of unit films take turns. The
                // rows get every unit in unit order as before, so the bytes are the same.
                let trace = |films: &mut [BdptFilm], wave: &std::ops::Range<usize>| -> Vec<PathCounts> {
                    films
                        .par_iter_mut()
                        .zip(wave.clone())
                        .map(|(film, u)| {
                            let (rect, block) = units.unit(u);
                            film.reset(rect);
                            let mut counts = PathCounts::default();
                            let tick0 = crate::timing::ticks();
                            let (f, cn, tile) = (&mut *film, &mut counts, [(rect.0, rect.1)]);
                            dispatch!(
                                derivs,
                                opts.lanes,
                                channels,
                                bdpt_tiles(ctx, seed, spp, &block, &tile, TILE, f, cn)
                            );
                            counts.total_ticks = crate::timing::ticks() - tick0;
                            bar.inc(1);
                            counts
                        })
                        .collect()
                };
                // adds a traced wave's units to the rows and marks the wave done, with its tally
                let commit = |rows: &mut [BdptFilm], (k, films, counts): (usize, &[BdptFilm], Vec<PathCounts>)| {
                    let mut tally: crate::checkpoint::Tally = (PathCounts::default(), [0.0; 2], Vec::new());
                    for (c, f) in counts.iter().zip(films) {
                        tally.0.add(c);
                        let t = f.film.tails();
                        tally.1[0] += t[0];
                        tally.1[1] += t[1];
                    }
                    let mut st = lock(&state);
                    rows.par_iter_mut()
                        .zip(st.chunks.par_iter_mut())
                        .for_each(|(row, sums)| {
                            row.film
                                .restore(sums.take().expect("every row's sums sit in the state"))
                                .expect("a row's own sums");
                            for unit in films {
                                match channels {
                                    1 => row.add_unit::<1>(ctx, unit),
                                    _ => row.add_unit::<3>(ctx, unit),
                                }
                            }
                            *sums = Some(row.film.take_sums());
                        });
                    st.done[k] = true;
                    st.tallies[k] = Some(tally);
                };
                let mut sets: [Vec<BdptFilm>; 2] = [Vec::new(), Vec::new()];
                // the wave traced but not yet added: its index, its set of films, its counts
                let mut pending: Option<(usize, usize, Vec<PathCounts>)> = None;
                // a checkpoint found due after a wave is written from the state itself (no
                // copy) while the next wave traces, which leaves the rows alone; the wave
                // traced before is added first, so the checkpoint holds every traced wave
                let mut due = false;
                for (k, wave) in waves.iter().enumerate() {
                    // a cancelled render stops between waves (`crate::cancel`)
                    if ctx.cancel.is_cancelled() {
                        break;
                    }
                    if lock(&state).done[k] {
                        continue;
                    }
                    let s = pending.as_ref().map_or(0, |p| 1 - p.1);
                    while sets[s].len() < wave.len() {
                        sets[s].push(BdptFilm::new(ctx, (0, 0, TILE, TILE), derivs, per_strategy, true));
                    }
                    let [a, b] = &mut sets;
                    let (films, other) = if s == 0 { (a, &*b) } else { (b, &*a) };
                    let films = &mut films[..wave.len()];
                    let before = pending.take().map(|(j, _, c)| (j, &other[..waves[j].len()], c));
                    let writer = std::mem::take(&mut due).then_some(self.checkpointing()).flatten();
                    let counts = match writer {
                        Some(ck) => {
                            if let Some(before) = before {
                                self.pool.install(|| commit(&mut rows, before));
                            }
                            std::thread::scope(|scope| {
                                let state = &state;
                                scope.spawn(move || report(ck, ck.write(&lock(state))));
                                self.pool.install(|| trace(films, wave))
                            })
                        }
                        None => {
                            let rows = &mut rows;
                            self.pool.install(|| {
                                rayon::join(
                                    || trace(films, wave),
                                    || {
                                        if let Some(before) = before {
                                            commit(rows, before)
                                        }
                                    },
                                )
                                .0
                            })
                        }
                    };
                    pending = Some((k, s, counts));
                    due = self.checkpointing().is_some_and(|ck| ck.due());
                }
                if let Some((j, s, counts)) = pending.take() {
                    self.pool
                        .install(|| commit(&mut rows, (j, &sets[s][..waves[j].len()], counts)));
                    due |= self.checkpointing().is_some_and(|ck| ck.due());
                }
                drop(snapshot);
                if let Some(ck) = self.checkpointing().filter(|_| due && !self.boundary_wanted) {
                    // due after the last wave (`finish_pass` writes before a boundary stage)
                    report(ck, ck.write(&lock(&state)));
                }
                let mut st = self.finish_pass(Self::end_watch(state));
                let mut tallies: Vec<crate::checkpoint::Tally> = st
                    .tallies
                    .drain(..)
                    .map(|t| {
                        t.unwrap_or_else(|| {
                            assert!(ctx.cancel.is_cancelled(), "every wave ran");
                            Default::default()
                        })
                    })
                    .collect();
                let list_len = rows.first().map_or(0, |r| r.strategies.len());
                strategy_out = Transient::zeros_many(list_len, w, h, axis, channels);
                for (row, sums) in rows.iter_mut().zip(st.chunks.drain(..)) {
                    row.film
                        .restore(sums.expect("every row's sums sit in the state"))
                        .expect("a row's own sums");
                    row.film.store_into(&mut out);
                    for (k, f) in row.strategies.iter().enumerate() {
                        f.store_into(&mut strategy_out[k..k + 1]);
                    }
                    // the rows' tails are those of the splats onto other pixels (the units'
                    // own are in the waves' tallies); their block sums cover everything
                    tallies.push((PathCounts::default(), row.film.tails(), row.film.block_sums()));
                }
                tallies
            }
        };
        let wall = t0.elapsed().as_secs_f64();
        let cpu = (cpu_seconds() - cpu0).max(1e-9);
        bar.finish_and_clear();
        if ran {
            log::debug!(
                "interior pass ({:?}, {} spp, {} derivative lane(s), {} threads): {wall:.3} s wall, {cpu:.3} CPU-s",
                self.kind,
                spp,
                derivs,
                self.pool.current_num_threads()
            );
        }
        out.iter_mut()
            .chain(strategy_out.iter_mut())
            .for_each(|t| t.scale(1.0 / spp as f32));
        Interior {
            films: out,
            strategies: strategy_out,
            tallies,
            ran,
            wall,
            cpu,
        }
    }

    /// The boundary integral (primary + secondary edges, Algorithm 2), when some parameter
    /// moves geometry and the options ask for it.
    fn boundary(&mut self, opts: &RenderOptions) -> Option<crate::boundary::BoundaryParts> {
        self.boundary_wanted.then(|| {
            let resumed = lock(&self.saved).as_ref().and_then(|s| s.boundary.clone());
            if let Some((primary, secondary, stats)) = resumed {
                return crate::boundary::BoundaryParts {
                    primary,
                    secondary,
                    stats,
                };
            }
            let settings = crate::boundary::BoundarySettings {
                spp_boundary: opts.spp_boundary.unwrap_or(self.spp),
                seed: self.seed,
                shard: opts.shard,
                guiding: opts.guiding,
                stages: opts.boundary.stages(),
                progress: progress_bar(
                    opts.progress,
                    0,
                    "{elapsed_precise} [{bar:40}] {pos}/{len} boundary chunks ({eta})",
                ),
            };
            let (t_b, cpu_b) = (Instant::now(), cpu_seconds());
            let mut parts = crate::boundary::render_boundary(&mut self.ctx, &settings, &self.pool);
            settings.progress.finish_and_clear();
            parts.stats.wall_seconds = t_b.elapsed().as_secs_f64();
            parts.stats.cpu_seconds = cpu_seconds() - cpu_b;
            let st = &parts.stats;
            log::debug!(
                "boundary stage ({} edges, spp_boundary {}): primary {:.3} s; secondary {} samples after a pilot of {} \
                 ({} edge-directed, {} light-directed, {} rays) {:.3} s; total {:.3} s wall, {:.3} CPU-s",
                st.edges,
                st.spp_boundary,
                st.primary_seconds,
                st.secondary.samples,
                st.secondary.pilot_samples,
                st.secondary.edge_directed,
                st.secondary.light_directed,
                st.secondary.rays,
                st.secondary.seconds,
                st.wall_seconds,
                st.cpu_seconds
            );
            // a periodic checkpoint, if one is due (only the outputs follow)
            if let Some(ck) = self.checkpointing().filter(|ck| ck.due()) {
                let mut kept = lock(&self.saved);
                let saved = kept.get_or_insert_with(Saved::default);
                saved.boundary = Some((parts.primary.clone(), parts.secondary.clone(), parts.stats.clone()));
                report(ck, ck.write(saved));
            }
            parts
        })
    }

    /// [`Error::Cancelled`] when the render was stopped from outside (its films are then
    /// partial and are not returned).
    pub(crate) fn not_cancelled(&self) -> Result<(), Error> {
        if self.ctx.cancel.is_cancelled() {
            Err(Error::Cancelled)
        } else {
            Ok(())
        }
    }

    /// The run's statistics and energy report (the window-energy pilot runs here, after
    /// every estimator, when paths were cut at the window).
    fn finish(
        &mut self,
        opts: &RenderOptions,
        interior: &mut Interior,
        boundary: Option<&crate::boundary::BoundaryParts>,
    ) -> RenderStats {
        let (w, h) = (self.ctx.scene.film.width as usize, self.ctx.scene.film.height as usize);
        let (spp, wall, cpu) = (self.spp, interior.wall, interior.cpu);
        let mut stats = RenderStats {
            spp,
            seed: self.seed,
            threads: self.pool.current_num_threads(),
            wall_seconds: wall,
            cpu_seconds: cpu,
            paths: if interior.ran {
                paths_per_sample(self.ctx.scene, self.kind) * (self.samples.end - self.samples.start)
            } else {
                0
            },
            bvh_build_seconds: self.bvh_build_seconds,
            traversal: if self.robust { "robust" } else { "fast" },
            steady: self.ctx.steady,
            opl_cut: self.ctx.opl_budget,
            opl: self.ctx.opl,
            time_edges: self.ctx.time_edges.is_some() && self.kind == IntegratorKind::Path,
            ..Default::default()
        };
        let mut ticks = (0u64, 0u64, 0u64);
        let mut tails = [0.0f64; 2];
        let mut inside = vec![0.0f64; 1 + self.derivs];
        for (c, t, sums) in &interior.tallies {
            tails[0] += t[0];
            tails[1] += t[1];
            inside.iter_mut().zip(sums).for_each(|(a, b)| *a += b);
            stats.intersect_rays += c.rays.intersect;
            stats.occluded_rays += c.rays.occluded;
            stats.non_finite_samples += c.non_finite;
            ticks.0 += c.rays.trace_ticks;
            ticks.1 += c.film_ticks;
            ticks.2 += c.total_ticks;
        }
        let total = ticks.2.max(1) as f64;
        stats.phase_seconds = PhaseSeconds {
            tracing: cpu * ticks.0 as f64 / total,
            film: cpu * ticks.1 as f64 / total,
            shading: cpu * (ticks.2.saturating_sub(ticks.0 + ticks.1)) as f64 / total,
        };
        let rays = (stats.intersect_rays + stats.occluded_rays) as f64;
        stats.paths_per_cpu_second = stats.paths as f64 / cpu;
        stats.rays_per_second = rays / wall.max(1e-9);
        stats.rays_per_cpu_second = rays / cpu;
        stats.total_wall_seconds = wall;
        stats.total_cpu_seconds = cpu;
        // the derivative films' energy counts all three parts
        let mut steady_sums: Vec<f64> = Vec::new();
        if let Some(b) = boundary {
            for (k, (p, q)) in b.primary.iter().zip(&b.secondary).enumerate() {
                let part: f64 = p.data.iter().zip(&q.data).map(|(a, b)| (a + b) as f64).sum();
                inside[1 + k] += part * spp as f64;
                let steady: f64 = p.steady.iter().zip(&q.steady).map(|(a, b)| (a + b) as f64).sum();
                steady_sums.push(steady);
            }
            stats.non_finite_samples += b.stats.non_finite();
            stats.boundary_samples = b.stats.secondary.samples;
            stats.boundary_seconds = b.stats.wall_seconds;
            stats.total_wall_seconds += b.stats.wall_seconds;
            stats.total_cpu_seconds += b.stats.cpu_seconds;
            stats.boundary = Some(b.stats.clone());
        }
        let n = spp as f64;
        let films = &interior.films;
        // the render's mode (the window-energy pilot below leaves the context uncut)
        let steady = self.ctx.steady;
        stats.energy = match steady {
            SteadyMode::Full => WindowEnergy::of(&films[0], inside[0] / n, tails[0] / n, tails[1] / n),
            // paths were cut at the window: what arrives after it comes from an uncut pilot
            SteadyMode::Window if interior.ran => {
                let (t_p, cpu_p) = (Instant::now(), cpu_seconds());
                // as many as the whole render's (every shard runs the same pilot)
                let paths = w * h * spp as usize;
                let (after, after_se, pilot) =
                    pilot_energy_after(&mut self.ctx, self.seed, paths, &self.pool, opts.lanes);
                stats.total_wall_seconds += t_p.elapsed().as_secs_f64();
                stats.total_cpu_seconds += cpu_seconds() - cpu_p;
                WindowEnergy::with_pilot(inside[0] / n, tails[0] / n, (after, after_se), pilot)
            }
            SteadyMode::Window => WindowEnergy::default(),
        };
        stats.deriv_energy = films[1..]
            .iter()
            .zip(&inside[1..])
            .enumerate()
            .map(|(k, (t, &i))| {
                let boundary_steady = steady_sums.get(k).copied().unwrap_or(0.0);
                DerivWindowEnergy::of(t, boundary_steady, i / n, steady)
            })
            .collect();
        stats
    }
}

use bdpt::render_tiles as bdpt_tiles;

use crate::kernel::hash_u64;

/// Seed stream of the window-energy pilot (xor-ed into the render seed).
const PILOT_STREAM: u64 = 0x9e37_79b9_7f4a_7c15;
/// Seed stream of the pilot's second pass.
const PILOT_STREAM_2: u64 = 0xd1b5_4a32_d192_ed03;

/// The window-energy pilot traces about 1/`PILOT_SHARE` of the render's paths, at least
/// `PILOT_PATHS.0` and at most `PILOT_PATHS.1` (two per pixel at most, unless the film is too
/// small for `PILOT_PATHS.0` at that: then up to `PILOT_MAX_PASSES` passes): a rough estimate
/// suffices for the report and its warning, and the pilot must cost far less than the cut
/// saves.
const PILOT_SHARE: usize = 256;
const PILOT_PATHS: (usize, usize) = (1024, 1 << 15);
const PILOT_MAX_PASSES: usize = 64;

/// The primal energy that arrives after the window, estimated by an uncut pilot of the path
/// tracer (one sample per pixel of a share of the film; see [`PILOT_SHARE`]), for the energy
/// report of a render whose paths were cut at the window. Returns (energy after the window,
/// its standard error, paths).
///
/// The film is cut into segments (a tile's rows; a tile of an exhaustive scan, whose paths
/// start at its sensor points), and the segments, in order, into strata of equal count. Each
/// stratum sends a segment drawn uniformly from it in each of two passes (or more, on a film
/// too small for the pilot's paths in two; with replacement; seed streams of their own), each
/// weighted by the stratum's count: unbiased, and the spread of the passes gives the standard
/// error, both their Monte Carlo noise and what the segments left out would have added. Where
/// a pass covers the film, each stratum is one segment traced in every pass.
/// Until 2026-11-30 the pilot took every n-th tile, which on a film of 8 × 8 tiles was one
/// column of them: the Cornell box's energy after an early window read 0.2–1.9× its value.
/// Leaves `ctx` uncut.
fn pilot_energy_after(
    ctx: &mut RenderContext,
    seed: u64,
    render_paths: usize,
    pool: &rayon::ThreadPool,
    lanes: Lanes,
) -> (f64, f64, u64) {
    ctx.cut_to_window(SteadyMode::Full);
    let ctx = &*ctx;
    let w = ctx.scene.film.width as usize;
    let exhaustive = ctx.scene.nlos.as_ref().is_some_and(|n| n.exhaustive());
    let segments: Vec<_> = tile_rects(ctx.scene)
        .into_iter()
        .flat_map(|(x0, y0, tw, th)| {
            let rows = if exhaustive { 1 } else { th };
            (0..rows).map(move |r| {
                if exhaustive {
                    (x0, y0, tw, th)
                } else {
                    (x0, y0 + r, tw, 1)
                }
            })
        })
        .collect();
    // paths per pass, and how many segments of (about) TILE paths that takes; a film too
    // small for that at one path per pixel takes more passes, each stratum a draw in each (an
    // exhaustive scan of 16 sensor points sent 2 × 16 paths, and reported a third of the
    // energy after its window with an error bar 3× too small)
    let target = (render_paths / PILOT_SHARE).clamp(PILOT_PATHS.0, PILOT_PATHS.1) / 2;
    let stride = segments.len().div_ceil(target.div_ceil(TILE).max(1)).max(1);
    let film_paths: usize = segments.iter().map(|s| s.2).sum();
    let passes = (2 * target).div_ceil(film_paths.max(1)).clamp(2, PILOT_MAX_PASSES);
    let strata: Vec<(usize, usize)> = (0..segments.len())
        .step_by(stride)
        .map(|a| (a, stride.min(segments.len() - a)))
        .collect();
    // per stratum: its count times each pass's energy after the window, and the paths
    let draws: Vec<(Vec<f64>, u64)> = pool.install(|| {
        strata
            .par_iter()
            .enumerate()
            .map(|(k, &(first, count))| {
                let draw = |pass: usize| {
                    let stream = match pass {
                        0 => PILOT_STREAM,
                        1 => PILOT_STREAM_2,
                        _ => hash_u64(PILOT_STREAM ^ pass as u64),
                    };
                    let pick = hash_u64(seed ^ stream ^ hash_u64(k as u64)) % count as u64;
                    let (x0, y0, tw, th) = segments[first + pick as usize];
                    let mut film = ctx.tile_film(x0, y0, tw, th, 0);
                    let mut counts = PathCounts::default();
                    let (f, c) = (&mut film, &mut counts);
                    dispatch!(
                        0,
                        lanes,
                        ctx.scene.film.channels,
                        render_tile(ctx, seed ^ stream, 1, &(0..1), w, (x0, y0, tw, th), f, c)
                    );
                    (count as f64 * film.tails()[1], tw as u64)
                };
                let (energies, paths): (Vec<f64>, Vec<u64>) = (0..passes).map(draw).unzip();
                (energies, paths.iter().sum())
            })
            .collect()
    });
    let mean = |e: &[f64]| e.iter().sum::<f64>() / e.len() as f64;
    let after: f64 = draws.iter().map(|(e, _)| mean(e)).sum();
    // the variance of each stratum's mean over its passes, from their spread, summed
    let var: f64 = draws
        .iter()
        .map(|(e, _)| {
            let m = mean(e);
            e.iter().map(|a| (a - m).powi(2)).sum::<f64>() / (e.len() * (e.len() - 1)) as f64
        })
        .sum();
    (after, var.sqrt(), draws.iter().map(|d| d.1).sum())
}

/// The samples `samples` (of `spp` per pixel) of one tile: for each sample index, one packet
/// per tile row (up to 8 pixels).
/// `rect` = (x0, y0, w, h) of the tile; its paths go to `film`, any [`Sink`].
#[allow(clippy::too_many_arguments)]
pub(crate) fn render_tile<R: Real, const C: usize, S: Sink<C>>(
    ctx: &RenderContext,
    seed: u64,
    spp: u32,
    samples: &std::ops::Range<u64>,
    width: usize,
    rect: (usize, usize, usize, usize),
    film: &mut S,
    counts: &mut PathCounts,
) {
    let lanes_per_packet = R::LANES;
    let (x0, y0, tw, th) = rect;
    // an exhaustive scan's paths start at the sensor points (tile row 0) and reach every laser row
    let rows = if ctx.nlos.as_ref().is_some_and(|n| n.exhaustive) {
        1
    } else {
        th
    };
    for s in samples.clone() {
        if ctx.cancel.is_cancelled() {
            return;
        }
        for ty in 0..rows {
            let mut x = 0;
            while x < tw {
                let n = lanes_per_packet.min(tw - x);
                let lanes = PacketLanes::row(x0 + x, y0 + ty, n, width, spp, s);
                trace_packet::<R, C, S>(ctx, seed, &lanes, film, counts);
                x += n;
            }
        }
    }
}

/// Units of work a path-traced render is cut into at least, when its samples allow: a
/// film of fewer tiles cuts each tile's samples into blocks, so that a small film (an NLOS
/// capture of 8 × 8 or 16 × 16 sensor points is 1 or 4 tiles) runs on many threads.
pub const MIN_UNITS: usize = 256;

/// Most bytes the block films of tiles cut into sample blocks may take while they wait for
/// their tile's last block: the cut is coarser where tile films are large (many bins,
/// derivative blocks).
pub const BLOCK_BYTES: u128 = 256 << 20;

/// Whether tile `i` of a render cut into `per_tile` sample blocks a tile is finished: all
/// of its units are done (they are marked together, when the tile is stored).
fn tile_done(done: &[bool], i: usize, per_tile: usize) -> bool {
    done[i * per_tile..(i + 1) * per_tile].iter().all(|&d| d)
}

/// Blocks per tile for `tiles` tiles of `n` samples whose films take `tile_bytes` each: as
/// few as give [`MIN_UNITS`] units, at most one per sample, and no more than keep every
/// tile's block films under [`BLOCK_BYTES`].
fn blocks_per_tile(tiles: usize, n: u64, tile_bytes: u128) -> u64 {
    let by_memory = (BLOCK_BYTES / (tiles.max(1) as u128 * tile_bytes.max(1))).min(u64::MAX as u128) as u64;
    (MIN_UNITS.div_ceil(tiles.max(1)) as u64)
        .min(by_memory)
        .clamp(1, n.max(1))
}

/// The blocks of consecutive samples each tile of a `tiles`-tile render is cut into
/// ([`blocks_per_tile`]; tile films of `tile_bytes`), from the film's shape and the sample
/// range alone (never the thread count), so neither are the bytes.
pub(crate) fn sample_blocks(
    tiles: usize,
    samples: &std::ops::Range<u64>,
    tile_bytes: u128,
) -> Vec<std::ops::Range<u64>> {
    let n = samples.end.saturating_sub(samples.start);
    let count = blocks_per_tile(tiles, n, tile_bytes);
    (0..count)
        .map(|k| samples.start + n * k / count..samples.start + n * (k + 1) / count)
        .collect()
}

/// A progress bar on stderr in indicatif's `template`, hidden unless `show` and stderr is a
/// terminal.
pub(crate) fn progress_bar(show: bool, len: u64, template: &str) -> indicatif::ProgressBar {
    use std::io::IsTerminal;
    if !show || !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new(len);
    if let Ok(style) = indicatif::ProgressStyle::with_template(template) {
        bar.set_style(style.progress_chars("=> "));
    }
    bar
}

#[cfg(test)]
mod tests {
    use super::{BLOCK_BYTES, MIN_UNITS, sample_blocks};

    /// Blocks cover the sample range in order, without gaps or overlaps, as few as give
    /// `MIN_UNITS` units and never an empty one.
    #[test]
    fn sample_blocks_cover_the_samples_in_order() {
        for (tiles, samples, count) in [
            (1usize, 0..16384u64, MIN_UNITS),
            (4, 0..256, MIN_UNITS / 4),
            (64, 10..74, MIN_UNITS / 64),
            (300, 0..64, 1),
            (1, 5..8, 3),
            (4, 0..0, 1),
        ] {
            let b = sample_blocks(tiles, &samples, 1 << 10);
            assert_eq!(b.len(), count, "{tiles} tiles, samples {samples:?}");
            assert_eq!(b.first().map(|r| r.start), Some(samples.start));
            assert_eq!(b.last().map(|r| r.end), Some(samples.end));
            assert!(b.windows(2).all(|p| p[0].end == p[1].start));
            assert!(samples.is_empty() || b.iter().all(|r| !r.is_empty()), "{b:?}");
        }
        // large tile films are cut no finer than keeps their block films under BLOCK_BYTES
        assert_eq!(sample_blocks(4, &(0..4096), BLOCK_BYTES / 40).len(), 10);
        assert_eq!(sample_blocks(4, &(0..4096), BLOCK_BYTES).len(), 1);
    }
}
