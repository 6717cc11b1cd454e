//! What a derivative render asks of the time term f·Ṡ_e·ḋ (Algorithm 1) where the draws on the
//! time edges (`super::time_edges`) leave it to the ordinary contributions
//! ([`TimeEdges::cover`](super::time_edges::TimeEdges::cover) says where): a delta pulse's
//! is refused, a narrow one's is said.

use super::time_edges::{Needs, Uncovered};
use crate::error::Error;
use crate::params::lanes::Motion;
use crate::scene::Scene;

/// Refuses parameters that shift paths in time when S_e is discontinuous in time (delta
/// pulse, box gate): Ṡ_e is then a Dirac distribution (supplemental Lemma 2.5), which only
/// the path tracer's draws on the time edges estimate, and only where they make every path
/// that needs it (`delta_draws`: `Ok`, or why not).
pub fn refuse_uncovered_delta(
    scene: &Scene,
    motion: &Motion,
    params: &[String],
    delta_draws: Result<(), Uncovered>,
) -> Result<(), Error> {
    let Some((k, e, why)) = uncovered_pair(scene, motion, delta_draws, Needs::Delta) else {
        return Ok(());
    };
    Err(Error::Invalid(format!(
        "{}: parameter {:?} shifts paths in time, but emitter {:?} has a delta pulse and the film a box gate: \
         S_e is then discontinuous in time and its derivative is a Dirac distribution on the bin edges, which the \
         path tracer's draws on the time edges estimate, but not here: {why}. Use a Gaussian pulse \
         (pulse = {{ type = \"gaussian\", sigma_opl = ... }}) or a Gaussian gate (film.gate = {{ type = \"gaussian\", sigma_opl = ... }}).",
        scene.source.display(),
        params[k],
        scene.emitters[e].name
    )))
}

/// What to say of a parameter that shifts in time the light of an emitter with a narrow
/// smooth pulse ([`Needs::Narrow`]) along paths the draws on the time edges do not make
/// (`narrow_draws`: `Ok`, or why not): that time term is then estimated by the ordinary
/// contributions, without bias but with a variance that grows as the bin width over σ.
/// `None` when there is no such pair.
pub fn narrow_warning(
    scene: &Scene,
    motion: &Motion,
    params: &[String],
    narrow_draws: Result<(), Uncovered>,
) -> Option<String> {
    let (k, e, why) = uncovered_pair(scene, motion, narrow_draws, Needs::Narrow)?;
    let emitter = &scene.emitters[e];
    let (sigma, w) = (emitter.pulse.std_dev(), scene.film.axis.bin_width_opl);
    Some(format!(
        "{}: parameter {:?} shifts in time the light of emitter {:?}, whose pulse is narrow (standard deviation \
         {sigma:.2e} m, {:.2e} of a bin of {w:.2e} m), along paths the draws on the time edges do not make: {why}. \
         Those paths estimate its time term by ordinary samples, without bias but with a variance that grows as \
         the bin width over sigma (up to about {:.0}x that of a pulse half a bin wide, at equal samples): expect a noisy \
         derivative, or take more samples",
        scene.source.display(),
        params[k],
        emitter.name,
        sigma / w,
        0.5 * w / sigma
    ))
}

/// The parameter and the emitter the draws' shortfall `draws` is about, with its reason:
/// a parameter that shifts paths in time and an emitter `needs` picks (a pulse offset
/// shifts only its own emitter), the ones the reason names where it names one. `None`
/// when the draws cover everything or no pair is left.
fn uncovered_pair(
    scene: &Scene,
    motion: &Motion,
    draws: Result<(), Uncovered>,
    needs: Needs,
) -> Option<(usize, usize, String)> {
    let uncovered = draws.err()?;
    let mut pairs = (0..motion.len())
        .filter(|&k| motion.shifts_time(k) && uncovered.param.is_none_or(|p| p == k))
        .flat_map(|k| (0..scene.emitters.len()).map(move |e| (k, e)));
    let (k, e) = pairs.find(|&(k, e)| {
        uncovered.emitter.is_none_or(|u| u == e)
            && needs.of(&scene.emitters[e], &scene.film)
            && motion.pulse_offset[k].is_none_or(|o| o == e)
    })?;
    Some((k, e, uncovered.why))
}
