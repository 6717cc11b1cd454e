//! Adjoint (reverse-mode) gradients of a loss: dL/dθ_k = Σ_bins ⟨∂L/∂I, İ_k⟩, contracted
//! path by path as the estimators produce İ, so no derivative film is ever stored.
//!
//! A user optimises a scalar loss L(I) of the transient. Its gradient with respect to the
//! scene parameters is the inner product of the adjoint volume ∂L/∂I (one value per pixel,
//! bin and channel: the film's shape) with each derivative film İ_k. Every estimator writes
//! İ as a sum of per-path terms binned through S_e (Algorithm 1: ḟ·S_e + f·Ṡ_e·ḋ; the boundary
//! terms of Algorithm 2 and the primary edges: Δf·V·S_e), so the inner product is the sum over
//! paths of each term contracted with ∂L/∂I in the bins it touches ([`AdjointFilm`]). Memory
//! is the adjoint volume plus O(P) per worker, for any number of parameters P
//! (≤ `MAX_PARAMS` per render today, as the dual-number lanes are).
//!
//! [`render_adjoint`] runs the same estimators with the same samples as
//! `render::render_diff`, so its gradient equals Σ ∂L/∂I·İ of `render_diff` up to float
//! rounding (tests/adjoint.rs).

use crate::film::{Accumulate, Transient};
use crate::params::MAX_PARAMS;
use crate::temporal::Correlation;

/// Contracts path contributions with an adjoint volume: `grad[k] += Σ_bins,c ∂L/∂I · İ_k`.
/// Primal contributions are ignored (the adjoint pass needs only derivatives).
pub struct AdjointFilm<'a> {
    adjoint: &'a Transient,
    /// Σ ⟨∂L/∂I, İ_k⟩ so far (not yet divided by the estimator's sample count).
    pub grad: [f64; MAX_PARAMS],
}

impl<'a> AdjointFilm<'a> {
    /// A contraction with `adjoint` (∂L/∂I, the film's shape), its sums at zero.
    pub fn new(adjoint: &'a Transient) -> Self {
        Self {
            adjoint,
            grad: [0.0; MAX_PARAMS],
        }
    }
}

impl Accumulate for AdjointFilm<'_> {
    #[inline]
    fn add(&mut self, _: usize, _: usize, _: &Correlation, _: f64, _: &[f32]) {}

    #[inline]
    fn add_with_derivs(
        &mut self,
        x: usize,
        y: usize,
        corr: &Correlation,
        d: f64,
        f: &[f32],
        fdot: &[f32],
        ddot: &[f32],
    ) {
        let a = self.adjoint;
        let c_n = a.channels;
        let base = a.index(x, y, 0, 0);
        let n_k = ddot.len().min(MAX_PARAMS);
        let grad = &mut self.grad;
        corr.for_each(d, |bin, s, ds| {
            let adj = &a.data[base + bin * c_n..base + (bin + 1) * c_n];
            if adj.iter().all(|&v| v == 0.0) {
                return;
            }
            for k in 0..n_k {
                let dd = ds * ddot[k] as f64;
                let mut g = 0.0;
                for c in 0..c_n {
                    g += adj[c] as f64 * (fdot[k * c_n + c] as f64 * s + f[c] as f64 * dd);
                }
                grad[k] += g;
            }
        });
    }

    #[inline]
    fn add_time_bin(&mut self, x: usize, y: usize, bin: usize, s: f64, f: &[f32], ddot: &[f32]) {
        let a = self.adjoint;
        let c_n = a.channels;
        let base = a.index(x, y, bin, 0);
        let g: f64 = s * (0..c_n).map(|c| a.data[base + c] as f64 * f[c] as f64).sum::<f64>();
        for k in 0..ddot.len().min(MAX_PARAMS) {
            self.grad[k] += g * ddot[k] as f64;
        }
    }
}

impl<const C: usize> crate::integrator::sink::Sink<C> for AdjointFilm<'_> {
    #[inline]
    fn add(
        &mut self,
        ctx: &crate::integrator::RenderContext,
        _: (usize, usize),
        x: usize,
        y: usize,
        lc: &crate::integrator::deposit::LaneContribution<C>,
        h: f32,
    ) {
        lc.add_to(ctx, self, x, y, h);
    }
}

/// What an adjoint render did.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct AdjointStats {
    /// Samples per pixel used.
    pub spp: u32,
    /// Random seed used.
    pub seed: u64,
    /// Interior paths traced.
    pub paths: u64,
    /// Samples whose contribution was NaN or infinite and was dropped.
    pub non_finite_samples: u64,
    /// The boundary stage, when a parameter moves geometry.
    pub boundary: Option<crate::boundary::BoundaryStats>,
    /// Wall-clock time of the render(s), seconds.
    pub wall_seconds: f64,
    /// Whether the path tracer drew the time term on the time edges
    /// (`crate::render::TimeEdgeMode`).
    pub time_edges: bool,
}

/// dL/dθ_k = Σ ⟨∂L/∂I, İ_k⟩ for each parameter in `params`, where `adjoint` is ∂L/∂I: a
/// film of the scene's shape ([H, W, T, C] and time axis). Runs the estimators of
/// `render::render_diff` (interior; primary and secondary edges when a parameter moves
/// geometry) with the same samples for the same options, contracting each path's
/// derivative on the fly.
///
/// Any number of parameters: the dual-number kernel carries at most `MAX_PARAMS`
/// derivative lanes, so longer lists run in groups of that many, each group a render with
/// the same samples (memory stays O(P); time grows with the number of groups).
///
/// With ∂L/∂I = 1 in every bin (L = Σ I), the gradient is the sum of
/// [`crate::render_diff`]'s derivative film, rendered with the same samples:
///
/// ```
/// use difftransient::{RenderOptions, Scene, Transient, render_adjoint, render_diff};
/// use std::path::Path;
///
/// let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/diff_room.toml"));
/// let scene = Scene::load(path, &[])?;
/// let opts = RenderOptions { spp: Some(2), ..Default::default() };
/// let params = ["intensity".to_string()];
///
/// let f = &scene.film;
/// let mut ones = Transient::zeros(f.width as usize, f.height as usize, f.axis, f.channels);
/// ones.data.fill(1.0);
/// let (grad, stats) = render_adjoint(&scene, &params, &ones, &opts)?;
/// assert_eq!((grad.len(), stats.spp), (1, 2));
///
/// let (_, films, _) = render_diff(&scene, &params, &opts)?;
/// let summed: f64 = films[0].data.iter().map(|&v| v as f64).sum();
/// assert!(summed > 0.0);
/// assert!((grad[0] - summed).abs() <= 1e-4 * summed, "{} vs {summed}", grad[0]);
/// # Ok::<(), difftransient::Error>(())
/// ```
pub fn render_adjoint(
    scene: &crate::Scene,
    params: &[String],
    adjoint: &Transient,
    opts: &crate::RenderOptions,
) -> Result<(Vec<f64>, AdjointStats), crate::Error> {
    if params.is_empty() {
        return Err(crate::Error::Invalid(
            "an adjoint render needs at least one parameter".into(),
        ));
    }
    let mut grad = Vec::with_capacity(params.len());
    let mut stats = AdjointStats::default();
    for group in params.chunks(MAX_PARAMS) {
        let (g, s) = render_adjoint_group(scene, group, adjoint, opts)?;
        grad.extend(g);
        stats.paths += s.paths;
        stats.non_finite_samples += s.non_finite_samples;
        stats.wall_seconds += s.wall_seconds;
        stats.boundary = s.boundary.or(stats.boundary);
        (stats.spp, stats.seed) = (s.spp, s.seed);
    }
    Ok((grad, stats))
}

/// Checks, without rendering, that [`render_adjoint`] takes `params` on `scene` with `opts`:
/// the names, their number per render, and time derivatives the estimators cannot take
/// (`integrator::time_terms::refuse_uncovered_delta`). A caller refuses them with it before it creates
/// anything (`dtr optimize`, before its output folder).
pub fn check_params(scene: &crate::Scene, params: &[String], opts: &crate::RenderOptions) -> Result<(), crate::Error> {
    if params.is_empty() {
        return Err(crate::Error::Invalid(
            "an adjoint render needs at least one parameter".into(),
        ));
    }
    for group in params.chunks(MAX_PARAMS) {
        group_motion(scene, group, opts)?;
    }
    Ok(())
}

/// The derivative lanes of one render's group of parameters, refused as [`check_params`]
/// says.
fn group_motion(
    scene: &crate::Scene,
    params: &[String],
    opts: &crate::RenderOptions,
) -> Result<crate::params::lanes::Motion, crate::Error> {
    let motion = crate::params::lanes::Motion::build(scene, params)?;
    if motion.len() > MAX_PARAMS || motion.is_empty() {
        return Err(crate::Error::Invalid(format!(
            "an adjoint render takes 1 to {MAX_PARAMS} parameters (asked for {})",
            motion.len()
        )));
    }
    crate::render::check_derivative_terms(scene, &motion, params, opts)?;
    // what the render would refuse of the materials, before any render (`dtr optimize` checks
    // its parameters' ranges with it)
    let kind = opts.integrator.unwrap_or(scene.integrator.kind);
    crate::render::check_materials(scene, &motion, kind, opts.boundary)?;
    Ok(motion)
}

/// [`render_adjoint`] for at most `MAX_PARAMS` parameters: one render.
fn render_adjoint_group(
    scene: &crate::Scene,
    params: &[String],
    adjoint: &Transient,
    opts: &crate::RenderOptions,
) -> Result<(Vec<f64>, AdjointStats), crate::Error> {
    use crate::Error;
    use crate::integrator::deposit::PathCounts;
    use crate::render::{Run, TILE, dispatch, render_tile};
    use crate::scene::IntegratorKind;
    use rayon::prelude::*;
    let f = &scene.film;
    let shape = [f.height as usize, f.width as usize, f.axis.bins, f.channels];
    if adjoint.shape() != shape || adjoint.axis != f.axis {
        return Err(Error::Invalid(format!(
            "{}: the adjoint (dL/dI) has shape {:?} and time axis {:?}; the scene's film is {shape:?} with {:?}",
            scene.source.display(),
            adjoint.shape(),
            adjoint.axis,
            f.axis
        )));
    }
    if let Some(i) = adjoint.data.iter().position(|v| !v.is_finite()) {
        return Err(Error::Invalid(format!(
            "{}: the adjoint (dL/dI) holds a non-finite value at index {i}",
            scene.source.display()
        )));
    }
    if opts.checkpoint.is_some() {
        return Err(Error::Invalid("adjoint renders are not checkpointed".into()));
    }
    let motion = group_motion(scene, params, opts)?;
    let t0 = std::time::Instant::now();
    // no derivative film is stored: the memory check counts the primal's alone
    let mut run = Run::with_films(scene, motion, opts, false, false)?;
    let (ctx, spp, seed, derivs) = (&run.ctx, run.spp, run.seed, run.derivs);
    let samples = &run.samples;
    let (w, h) = (f.width as usize, f.height as usize);
    let channels = f.channels;
    let interior = opts.boundary.interior();
    // Per tile (path tracer: `render::tile_rects`; BDPT: `render::tiles`, whose splats onto
    // other pixels need no film here), summed in order: the same gradient for any thread
    // count.
    enum Unit {
        Tile((usize, usize, usize, usize)),
        /// A BDPT tile's origin.
        BdptTile((usize, usize)),
    }
    let units: Vec<Unit> = match (interior, run.kind) {
        (false, _) => Vec::new(),
        (true, IntegratorKind::Path) => crate::render::tile_rects(scene).into_iter().map(Unit::Tile).collect(),
        (true, IntegratorKind::Bdpt) => crate::render::tiles(w, h).into_iter().map(Unit::BdptTile).collect(),
    };
    let parts: Vec<([f64; MAX_PARAMS], PathCounts)> = run.pool.install(|| {
        units
            .par_iter()
            .map(|unit| {
                let mut acc = AdjointFilm::new(adjoint);
                let mut counts = PathCounts::default();
                let (a, c) = (&mut acc, &mut counts);
                match unit {
                    Unit::Tile(rect) => {
                        let rect = *rect;
                        dispatch!(
                            derivs,
                            opts.lanes,
                            channels,
                            render_tile(ctx, seed, spp, samples, w, rect, a, c)
                        );
                    }
                    Unit::BdptTile(origin) => {
                        use crate::integrator::bdpt::render_tiles;
                        let tile = [*origin];
                        dispatch!(
                            derivs,
                            opts.lanes,
                            channels,
                            render_tiles(ctx, seed, spp, samples, &tile, TILE, a, c)
                        );
                    }
                }
                (acc.grad, counts)
            })
            .collect()
    });
    let mut grad = [0.0f64; MAX_PARAMS];
    let mut stats = AdjointStats {
        spp,
        seed,
        paths: if interior {
            crate::render::paths_per_sample(scene, run.kind) * (samples.end - samples.start)
        } else {
            0
        },
        time_edges: interior && ctx.time_edges.is_some() && run.kind == crate::scene::IntegratorKind::Path,
        ..Default::default()
    };
    for (g, c) in &parts {
        grad.iter_mut().zip(g).for_each(|(a, b)| *a += b / spp as f64);
        stats.non_finite_samples += c.non_finite;
    }
    let boundary = derivs > 0 && ctx.motion.moves_geometry() && opts.boundary.stages().any();
    if boundary {
        let settings = crate::boundary::BoundarySettings {
            spp_boundary: opts.spp_boundary.unwrap_or(spp),
            seed,
            guiding: opts.guiding,
            shard: opts.shard,
            stages: opts.boundary.stages(),
            // the optimizer shows its own progress per iteration
            progress: indicatif::ProgressBar::hidden(),
        };
        let (g, b) = crate::boundary::boundary_adjoint(&mut run.ctx, &settings, &run.pool, adjoint);
        grad.iter_mut().zip(g).for_each(|(a, b)| *a += b);
        stats.non_finite_samples += b.non_finite();
        stats.boundary = Some(b);
    }
    run.not_cancelled()?;
    stats.wall_seconds = t0.elapsed().as_secs_f64();
    Ok((grad[..derivs].to_vec(), stats))
}
