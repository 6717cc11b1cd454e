//! The automatic time window (`dtr render --auto-window`): a short pilot render finds where
//! the light's energy arrives, and the film's window is set over its arrival and decay.
//!
//! The pilot renders the scene at a small resolution (at most [`PILOT_SIDE`] pixels across,
//! same field of view) with [`PILOT_BINS`] bins spanning every OPL a path can have:
//! from the earliest emission (0, or an emitter's offset less its pulse's reach) to
//!
//!   (max_bounces + 2) · diagonal · η_max + the latest offset + the pulse's and gate's reach,
//!
//! where `diagonal` spans the geometry, the camera and every point or laser emitter, so no
//! segment is longer, and η_max is the largest index of the scene's media. No light arrives
//! after that bound. The window then runs from the OPL where [`LOW_QUANTILE`] of the pilot's
//! energy has arrived to where [`HIGH_QUANTILE`] has, widened by [`MARGIN`] of its length at
//! each end (the start not before the pilot's), and keeps the scene's number of bins: only
//! `start_opl` and `bin_width_opl` change. The pilot costs about
//! `PILOT_SPP · PILOT_SIDE²` paths, a fraction of any real render.

use crate::film::SteadyMode;
use crate::render::{RenderOptions, render};
use crate::scene::{EmitterKind, Material, Scene};
use crate::temporal::Correlation;
use crate::{Error, Transient};
use glam::Vec3;
use std::path::Path;

/// The pilot's film is at most this many pixels across (its aspect ratio kept).
pub const PILOT_SIDE: u32 = 32;
/// Bins of the pilot's time axis.
pub const PILOT_BINS: usize = 2048;
/// Samples per pixel of the pilot.
pub const PILOT_SPP: u32 = 16;
/// Fraction of the pilot's energy that arrives before the window.
pub const LOW_QUANTILE: f64 = 0.001;
/// Fraction of the pilot's energy that has arrived at the window's end.
pub const HIGH_QUANTILE: f64 = 0.99;
/// Widening of the window at each end, as a fraction of its length.
pub const MARGIN: f64 = 0.05;

/// The window chosen, and what the pilot saw.
#[derive(Clone, Debug, serde::Serialize)]
pub struct AutoWindow {
    /// Start of the chosen window, metres of OPL.
    pub start_opl: f64,
    /// Bin width of the chosen window, metres of OPL (the scene's bins span the window).
    pub bin_width_opl: f64,
    /// The scene's number of bins, kept.
    pub bins: usize,
    /// Start of the pilot's window (metres of OPL): the earliest emission, 0 or before.
    pub pilot_start_opl: f64,
    /// End of the pilot's window (metres of OPL): the bound on every path's OPL.
    pub pilot_end_opl: f64,
    /// The pilot's resolution (width, height).
    pub pilot_resolution: [u32; 2],
    /// The pilot's samples per pixel ([`PILOT_SPP`]).
    pub pilot_spp: u32,
    /// The pilot's bins ([`PILOT_BINS`]).
    pub pilot_bins: usize,
    /// The OPL (a pilot bin's start) by which [`LOW_QUANTILE`] of the pilot's energy arrived.
    pub low_quantile_opl: f64,
    /// The OPL (a pilot bin's end) by which [`HIGH_QUANTILE`] of the pilot's energy arrived.
    pub high_quantile_opl: f64,
    /// Wall seconds of the pilot.
    pub pilot_seconds: f64,
}

impl AutoWindow {
    /// The overrides that set this window on the scene (`film.start_opl`, `film.bin_width_opl`).
    pub fn overrides(&self) -> Vec<(String, f64)> {
        vec![
            ("film.start_opl".to_string(), self.start_opl),
            ("film.bin_width_opl".to_string(), self.bin_width_opl),
        ]
    }
}

/// Chooses the window of the scene at `path` (with `overrides` applied) by a pilot render
/// with `opts`' seed and threads. Refuses relay-wall captures (their window is the hidden
/// scene's, which the wall's own light would swamp) and scenes whose pilot sees no light.
pub fn choose_window(path: &Path, overrides: &[(String, f64)], opts: &RenderOptions) -> Result<AutoWindow, Error> {
    choose_window_with(path, overrides, opts, |o| Ok(Scene::load(path, o)?))
}

/// [`choose_window`] for a scene that `load` builds with the overrides it is given (a
/// description held in memory, say); `path` names the scene in messages.
pub fn choose_window_with(
    path: &Path,
    overrides: &[(String, f64)],
    opts: &RenderOptions,
    load: impl Fn(&[(String, f64)]) -> Result<Scene, Error>,
) -> Result<AutoWindow, Error> {
    let scene = load(overrides)?;
    let refuse = |why: String| Err(Error::Invalid(format!("{}: --auto-window: {why}", path.display())));
    if scene.nlos.is_some() {
        return refuse(
            "a relay-wall capture ([nlos]) needs its window set by hand (film.start_opl, film.bin_width_opl)".into(),
        );
    }
    let Some((first, last)) = opl_bounds(&scene) else {
        return refuse("the scene has no emitter, so no light arrives".into());
    };
    let (w, h) = (scene.film.width, scene.film.height);
    let pw = w.min(PILOT_SIDE);
    let ph = ((h as f64 * pw as f64 / w as f64).round() as u32).clamp(1, PILOT_SIDE.max(1));
    let width = (last - first) / PILOT_BINS as f64;
    let mut pilot_overrides = overrides.to_vec();
    pilot_overrides.retain(|(n, _)| !matches!(n.as_str(), "film.start_opl" | "film.bin_width_opl" | "film.bins"));
    pilot_overrides.extend([
        ("camera.resolution.0".to_string(), pw as f64),
        ("camera.resolution.1".to_string(), ph as f64),
        ("film.start_opl".to_string(), first),
        ("film.bin_width_opl".to_string(), width),
        ("film.bins".to_string(), PILOT_BINS as f64),
    ]);
    let pilot_scene = load(&pilot_overrides)?;
    let pilot_opts = RenderOptions {
        spp: Some(PILOT_SPP),
        progress: false,
        steady: SteadyMode::Full,
        ..opts.clone()
    };
    let t0 = std::time::Instant::now();
    let (film, _) = render(&pilot_scene, &pilot_opts)?;
    let (lo, hi) = match quantile_opls(&film, LOW_QUANTILE, HIGH_QUANTILE) {
        Some(q) => q,
        None => {
            return refuse(format!(
                "the pilot ({pw}x{ph}, {PILOT_SPP} spp) saw no light reach the camera"
            ));
        }
    };
    let span = (hi - lo).max(width);
    let start = (lo - MARGIN * span).max(first);
    let end = hi + MARGIN * span;
    let bins = scene.film.axis.bins;
    Ok(AutoWindow {
        start_opl: start,
        bin_width_opl: (end - start) / bins as f64,
        bins,
        pilot_start_opl: first,
        pilot_end_opl: last,
        pilot_resolution: [pw, ph],
        pilot_spp: PILOT_SPP,
        pilot_bins: PILOT_BINS,
        low_quantile_opl: lo,
        high_quantile_opl: hi,
        pilot_seconds: t0.elapsed().as_secs_f64(),
    })
}

/// The earliest and latest OPL at which any path's light can reach the film (see the module
/// documentation), or `None` without an emitter.
pub fn opl_bounds(scene: &Scene) -> Option<(f64, f64)> {
    let mut points: Vec<Vec3> = scene.geometry.positions.clone();
    points.push(scene.camera.position);
    for e in &scene.emitters {
        match e.kind {
            EmitterKind::Point { position, .. } | EmitterKind::Laser { position, .. } => points.push(position),
            EmitterKind::Area { .. } => {}
        }
    }
    let (lo, hi) = points.iter().filter(|p| p.is_finite()).fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let diagonal = (hi - lo).as_dvec3().length();
    let eta_max = scene
        .materials
        .iter()
        .filter_map(|m| match m.material {
            Material::Dielectric { int_ior, .. } => Some(int_ior as f64),
            _ => None,
        })
        .fold(scene.eta as f64, f64::max);
    let segments = scene.integrator.max_bounces as f64 + 2.0;
    let reach = |e: &crate::scene::Emitter| {
        Correlation::new(scene.film.axis, e.pulse, e.offset_opl, scene.film.gate)
            .map(|c| c.reach())
            .unwrap_or(0.0)
    };
    let first = scene
        .emitters
        .iter()
        .map(|e| e.offset_opl - reach(e))
        .fold(0.0f64, f64::min);
    let last = scene
        .emitters
        .iter()
        .map(|e| e.offset_opl + reach(e))
        .fold(f64::NEG_INFINITY, f64::max);
    (last.is_finite() && diagonal.is_finite()).then(|| (first, segments * diagonal * eta_max + last.max(0.0)))
}

/// The OPLs (bin centres) at which the fractions `low` and `high` of the film's energy (summed
/// over pixels and channels) have arrived, or `None` if the film holds no positive energy.
pub fn quantile_opls(film: &Transient, low: f64, high: f64) -> Option<(f64, f64)> {
    let totals: Vec<f64> = film.bin_totals().iter().map(|&v| (v as f64).max(0.0)).collect();
    let sum: f64 = totals.iter().sum();
    if !(sum > 0.0) {
        return None;
    }
    let mut cum = 0.0;
    let (mut lo, mut hi) = (None, None);
    for (t, v) in totals.iter().enumerate() {
        cum += v;
        if lo.is_none() && cum >= low * sum {
            lo = Some(film.axis.bin_start(t));
        }
        if hi.is_none() && cum >= high * sum {
            hi = Some(film.axis.bin_start(t + 1));
        }
    }
    Some((lo?, hi?))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::temporal::TimeAxis;

    #[test]
    fn quantiles_of_a_known_histogram() {
        let axis = TimeAxis {
            start_opl: 1.0,
            bin_width_opl: 0.5,
            bins: 10,
        };
        let mut film = Transient::zeros(1, 1, axis, 1);
        // energy 1 in bin 2, 98 in bin 4, 1 in bin 8
        film.data[2] = 1.0;
        film.data[4] = 98.0;
        film.data[8] = 1.0;
        let (lo, hi) = quantile_opls(&film, 0.001, 0.99).unwrap();
        assert_eq!(lo, axis.bin_start(2));
        assert_eq!(hi, axis.bin_start(5));
        let (_, hi) = quantile_opls(&film, 0.001, 0.995).unwrap();
        assert_eq!(hi, axis.bin_start(9));
        assert!(quantile_opls(&Transient::zeros(1, 1, axis, 1), 0.001, 0.99).is_none());
    }
}
