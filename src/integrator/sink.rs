//! Where the estimators put finished path contributions. Every estimator hands each finite
//! lane contribution (f, ḟ, d, ḋ: [`LaneContribution`]) to a sink with the film point it
//! belongs to, the weight of that point and the strategy that made it; the sink decides what
//! the contribution becomes (as mitransient's films receive `add_transient` calls). Today:
//! - [`TileFilm`]: I += h·f·S_e(d) and İ_k += h·(ḟ_k·S_e + f·Ṡ_e·ḋ_k) (Algorithm 1);
//! - [`BdptFilm`]: the same, plus one film per (s, t) strategy when asked;
//! - `crate::adjoint::AdjointFilm`: the adjoint contraction, dL/dθ_k += ⟨∂L/∂I, h·İ_k⟩ over
//!   the bins a path touches, with no film.
//!
//! An NLOS capture's film points are its cells (sensor grid cell, or (sensor, laser) point;
//! `super::nlos`), so every sink above takes a capture as it is.

use super::bdpt::film::BdptFilm;
use super::context::RenderContext;
use super::deposit::LaneContribution;
use crate::film::TileFilm;

/// Receives finished contributions.
pub trait Sink<const C: usize> {
    /// Adds `lc` with weight `h` at film point (x, y) (pixel indices of the render's film).
    /// `strategy` = (s, t): the path has s light-subpath and t camera-subpath vertices (the
    /// pinhole counts as a camera vertex), as in BDPT (Veach 1997, §10.2); the path tracer's
    /// emission hit at vertex k is (0, k + 1) and its next-event connection (1, k + 1).
    fn add(
        &mut self,
        ctx: &RenderContext,
        strategy: (usize, usize),
        x: usize,
        y: usize,
        lc: &LaneContribution<C>,
        h: f32,
    );
}

impl<const C: usize> Sink<C> for TileFilm {
    #[inline]
    fn add(&mut self, ctx: &RenderContext, _: (usize, usize), x: usize, y: usize, lc: &LaneContribution<C>, h: f32) {
        lc.add_to(ctx, self, x, y, h);
    }
}

impl<const C: usize> Sink<C> for BdptFilm {
    #[inline]
    fn add(
        &mut self,
        ctx: &RenderContext,
        strategy: (usize, usize),
        x: usize,
        y: usize,
        lc: &LaneContribution<C>,
        h: f32,
    ) {
        BdptFilm::add(self, ctx, strategy, x, y, lc, h);
    }
}
