//! Primary edges: silhouettes seen from the camera, sampled in image space.
//!
//! PLACEHOLDER OWNED BY ANOTHER BRANCH: the primary-edge estimator is written on a separate
//! branch and replaces this file at merge. Until then it returns zero transients, so the
//! gradient is interior + secondary only; tests of this branch use scenes where the camera
//! sees no moving silhouette (the primary term vanishes there).

use crate::film::Transient;
use crate::integrator::context::RenderContext;

/// One derivative transient per parameter (index = parameter order), estimated with
/// `spp_boundary` samples per pixel from random stream `seed`.
pub fn render_primary(ctx: &RenderContext, spp_boundary: u32, seed: u64, pool: &rayon::ThreadPool) -> Vec<Transient> {
    let _ = (spp_boundary, seed, pool);
    let film = &ctx.scene.film;
    vec![Transient::zeros(film.width as usize, film.height as usize, film.axis, film.channels); ctx.motion.len()]
}
