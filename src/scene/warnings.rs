//! Warnings about a scene that loads but will render poorly: said once per process and
//! message, however often the scene is resolved again (`Scene::set_params` in an
//! optimisation loop resolves it at every iteration).

use super::{Emitter, FilmSpec};
use crate::temporal::Gate;
use std::collections::HashSet;
use std::path::Path;
use std::sync::Mutex;

/// Logs `message` as a warning unless this process has logged it already.
pub(crate) fn warn_once(message: String) {
    static SAID: Mutex<Option<HashSet<String>>> = Mutex::new(None);
    let mut said = SAID.lock().unwrap_or_else(|e| e.into_inner());
    if said.get_or_insert_with(HashSet::new).insert(message.clone()) {
        log::warn!("{message}");
    }
}

/// Below this share of a bin's width, a Gaussian gate's bins sample time at their centres.
const NARROW_GATE: f64 = 0.1;

/// A Gaussian gate g_l = w·N(t; centre_l, σ) much narrower than the bin width w, with the
/// widest pulse's spread added (σ_eff² = σ² + the pulse's variance), does not tile time: bin l
/// counts only paths whose OPL lands within a few σ_eff of its centre, with weight up to
/// w/(σ_eff·√(2π)). The transient is unbiased but its variance is about w/(2√π·σ_eff) times
/// that of box bins at equal samples (the second moment of g_l over a bin), which at
/// σ_eff = w/100 is 28× and at a femtometre is hopeless. A Gaussian gate models a sensor's
/// jitter over bins of about its width; the message says so.
pub(crate) fn narrow_gate(path: &Path, film: &FilmSpec, emitters: &[Emitter]) -> Option<String> {
    let Gate::Gaussian { sigma_opl } = film.gate else {
        return None;
    };
    let w = film.axis.bin_width_opl;
    let sigma = sigma_opl as f64;
    let widest = emitters.iter().map(|e| e.pulse.variance()).fold(0.0, f64::max);
    let eff = (sigma * sigma + widest).sqrt();
    if !(eff < NARROW_GATE * w) {
        return None;
    }
    let factor = w / (2.0 * std::f64::consts::PI.sqrt() * eff);
    Some(format!(
        "{}: film.gate: a Gaussian gate of sigma {sigma:.3e} m (with the pulse, {eff:.3e} m) is {:.1e} of a bin \
         ({w:.3e} m): each bin counts only the paths that arrive within a few sigma of its centre, so the \
         transient has about {factor:.0}x the variance of box bins at equal samples; a Gaussian gate models \
         a sensor's jitter over bins of about its width: use gate = \"box\" (with any pulse), or a sigma \
         nearer the bin width",
        path.display(),
        eff / w
    ))
}
