//! Inverse rendering: recover scene parameters from a measured (or rendered) transient by
//! gradient descent on a loss ([`loss::Loss`]), with gradients from the adjoint renderer
//! (`crate::adjoint::render_adjoint`) and Adam with bounds ([`adam::Adam`]).
//!
//! Each iteration renders the transient at the current parameters (forward kernel, no
//! derivative lanes), computes the loss and its adjoint ∂L/∂I against the target, and runs
//! the adjoint render with an independent seed: with one shared set of samples, ∂L/∂I
//! (a function of the noisy I) and İ would be correlated and their product biased for any
//! loss that is not linear in I.

pub mod adam;
pub mod loss;

use crate::error::Error;
use crate::film::Transient;
use crate::params::Domain;
use crate::render::RenderOptions;
use crate::scene::Scene;
use std::path::PathBuf;

/// What to recover and from what.
#[derive(Clone, Debug)]
pub struct Problem {
    /// The scene file (read once; each iteration sets the current values on the loaded scene,
    /// [`Scene::set_params`]).
    pub scene: PathBuf,
    /// Overrides held fixed (`--set`), besides the parameters being optimised.
    pub fixed: Vec<(String, f64)>,
    /// Fields held fixed at values other than numbers (`--set nlos.scan=exhaustive`;
    /// [`Scene::load_with_text`]).
    pub fixed_text: Vec<(String, String)>,
    /// The parameters to recover (names of `[[param]]` entries).
    pub params: Vec<String>,
    /// The transient to match: the film's shape and time axis.
    pub target: Transient,
    /// The loss between the rendered transient and `target`.
    pub loss: loss::Loss,
    /// Samples, threads, estimators; the seed is the first of the run's seed stream.
    pub opts: RenderOptions,
    /// Bounds per parameter (lo, hi), within the values its kind may take (an albedo in
    /// [0, 1], an index > 0: `crate::params::ParamKind::domain`), which bound it too.
    pub bounds: Vec<(f64, f64)>,
}

/// One iteration: the loss at `values` and its gradient there.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Step {
    /// Iteration number, from 0.
    pub iteration: usize,
    /// The loss at `values`.
    pub loss: f64,
    /// Parameter values of this iteration, in the order of [`Problem::params`] (their
    /// units: metres, degrees, ...).
    pub values: Vec<f64>,
    /// dL/dθ at `values`, one per parameter, from the adjoint render.
    pub grad: Vec<f64>,
    /// Wall-clock seconds of the iteration (forward and adjoint render).
    pub seconds: f64,
}

/// Polyak–Ruppert averaging (Polyak & Juditsky 1992): the mean of the iterates (`values`) of
/// the last `fraction` of `steps` (at least the last step; `fraction` in [0, 1], 0 = the last
/// iterate alone). With noisy gradients the iterates wander around the answer with a spread
/// that only the learning rate's decay narrows; their mean over the final stretch is a far
/// steadier estimate of where they wander around. `None` for no steps or a fraction outside
/// [0, 1].
pub fn tail_average(steps: &[Step], fraction: f64) -> Option<Vec<f64>> {
    if steps.is_empty() || !(0.0..=1.0).contains(&fraction) {
        return None;
    }
    let n = ((steps.len() as f64 * fraction).round() as usize).clamp(1, steps.len());
    let tail = &steps[steps.len() - n..];
    let mut mean = vec![0.0; tail[0].values.len()];
    for s in tail {
        for (m, v) in mean.iter_mut().zip(&s.values) {
            *m += v / n as f64;
        }
    }
    Some(mean)
}

/// The steps that the end-of-run checks read as a run's end ([`tail_spread`], [`unsettled`],
/// [`no_progress`]): its last quarter, at least 10.
fn end_len(steps: usize) -> usize {
    (steps / 4).max(10)
}

/// How far each parameter's iterates wander over the end of a run: the standard deviation of
/// the values of the last quarter of `steps` (at least 10 steps; `None` for a run shorter
/// than that), with the number of steps it spans. With noisy gradients the iterates wander
/// around the answer, so this is the scale of the noise left in the last iterate (the mean
/// of `--average` wanders less, by up to the square root of the steps it takes, fewer where
/// successive iterates are alike). A measure of the run's noise, not of the distance to the
/// truth: a run that settled on the wrong side of a bound or in a local minimum spreads as
/// little.
pub fn tail_spread(steps: &[Step]) -> Option<(Vec<f64>, usize)> {
    let n = end_len(steps.len());
    if steps.len() < n {
        return None;
    }
    let tail = &steps[steps.len() - n..];
    let spread = (0..tail[0].values.len())
        .map(|k| {
            let mean = tail.iter().map(|s| s.values[k]).sum::<f64>() / n as f64;
            (tail.iter().map(|s| (s.values[k] - mean).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt()
        })
        .collect();
    Some((spread, n))
}

/// What a run's iterates say about whether it got where it was going, as warnings naming
/// the parameter: one whose gradient was 0 at every iteration never moved, and its value is
/// only its start; one whose last steps all went one way (the last quarter of the run, at
/// least 10 steps: a run settled near its answer steps back and forth in its noise) was
/// still on its way when the iterations ran out; one that ended on a closed end of its
/// domain (`domains`, from [`Problem::domains`]: its kind's range within `--bound`) was
/// stopped there, and its answer may lie beyond.
pub fn unsettled(names: &[String], steps: &[Step], domains: &[Domain]) -> Vec<String> {
    let mut out = Vec::new();
    let n = end_len(steps.len());
    for (k, name) in names.iter().enumerate() {
        let values: Vec<f64> = steps.iter().map(|s| s.values[k]).collect();
        let Some(&last) = values.last() else { continue };
        if steps.iter().all(|s| s.grad[k] == 0.0) {
            out.push(format!(
                "{name} never moved from its start ({}): its gradient was 0 at every iteration, so nothing in the rendered window depends on it there (out of view, or the boundary term it needs left out: --estimators interior)",
                values[0]
            ));
            continue;
        }
        if let Some(d) = domains.get(k) {
            let at_lo = !d.open_lo && last == d.lo;
            if at_lo || (!d.open_hi && last == d.hi) {
                out.push(format!(
                    "{name} ended at {last}, the {} end of where it may go ({d}); its best value may lie beyond",
                    if at_lo { "lower" } else { "upper" }
                ));
                continue;
            }
        }
        if values.len() > n {
            let tail = &values[values.len() - n - 1..];
            let up = tail.windows(2).all(|w| w[1] > w[0]);
            let down = tail.windows(2).all(|w| w[1] < w[0]);
            if up || down {
                out.push(format!(
                    "{name} was still moving when the iterations ran out: its last {n} steps all went {} ({} → {last}); more --iters or a larger --lr would take it further",
                    if up { "up" } else { "down" },
                    tail[0]
                ));
            }
        }
    }
    out
}

/// What a run's losses say about where it went, as warnings: over its last quarter (at
/// least 10 iterations after the first) the loss stayed at or above its first value, so the start may
/// lie outside the answer's basin; or it stayed at or above `dark`, the loss of a render that
/// holds no light at all, so the iterates render little light where the target has it (the
/// object left the view or the time window). Either run still ends as any other: these are
/// local minima of the loss, not failures, but a run from 0.3 m off in an NLOS capture, or a
/// plate sent out of the window, ended with exit 0 and no word.
pub fn no_progress(steps: &[Step], dark: f64) -> Vec<String> {
    let mut out = Vec::new();
    // (until the forty-third session the last quarter here could be 2 iterations, where the
    // other checks read at least 10)
    let n = end_len(steps.len());
    if steps.len() <= n {
        return out;
    }
    let tail = steps[steps.len() - n..].iter().map(|s| s.loss).sum::<f64>() / n as f64;
    let first = steps[0].loss;
    if tail >= first {
        out.push(format!(
            "the loss did not fall over the run (first {first:.4e}, mean of the last {n} iterations {tail:.4e}): the start may lie outside the answer's basin; start nearer, or try --loss smooth or multiscale, whose basins are wider"
        ));
    }
    if dark > 0.0 && tail >= 0.99 * dark {
        out.push(format!(
            "the last {n} iterations fit the target no better than a render with no light would (mean loss {tail:.4e}, a dark render's {dark:.4e}): what they render misses the target's light; the parameters may have taken the object out of view or out of the time window"
        ));
    }
    out
}

impl Problem {
    /// The scene with the parameters at `values`.
    pub fn scene_at(&self, values: &[f64]) -> Result<Scene, Error> {
        let mut overrides = self.fixed.clone();
        overrides.extend(self.params.iter().cloned().zip(values.iter().copied()));
        Ok(Scene::load_with_text(&self.scene, &overrides, &self.fixed_text)?)
    }

    /// The parameters' values in the scene file (with the fixed overrides): the start.
    pub fn initial_values(&self) -> Result<Vec<f64>, Error> {
        let scene = Scene::load_with_text(&self.scene, &self.fixed, &self.fixed_text)?;
        self.params
            .iter()
            .map(|name| Ok(self.param(&scene, name)?.value))
            .collect()
    }

    /// L and dL/dθ at `values`, with render seeds `seed` (primal) and `seed + 1` (adjoint).
    pub fn loss_and_gradient(&self, values: &[f64], seed: u64) -> Result<(f64, Vec<f64>), Error> {
        self.loss_and_gradient_of(&self.scene_at(values)?, seed)
    }

    /// `scene` with the parameters set to `values` (the fixed overrides stay as loaded).
    fn set_values(&self, scene: &mut Scene, values: &[f64]) -> Result<(), Error> {
        let set: Vec<(&str, f64)> = self
            .params
            .iter()
            .map(String::as_str)
            .zip(values.iter().copied())
            .collect();
        Ok(scene.set_params(&set)?)
    }

    /// L and dL/dθ of `scene` (a scene of this problem with its parameters set), with render
    /// seeds `seed` (primal) and `seed + 1` (adjoint).
    pub fn loss_and_gradient_of(&self, scene: &Scene, seed: u64) -> Result<(f64, Vec<f64>), Error> {
        let primal = RenderOptions {
            seed: Some(seed),
            ..self.opts.clone()
        };
        let (image, _) = crate::render::render(scene, &primal)?;
        if image.shape() != self.target.shape() {
            return Err(Error::Invalid(format!(
                "the target has shape {:?}, the scene renders {:?} ([H, W, T, C])",
                self.target.shape(),
                image.shape()
            )));
        }
        let (l, adjoint) = self.loss.value_and_adjoint(&image, &self.target);
        let adj_opts = RenderOptions {
            seed: Some(seed.wrapping_add(1)),
            ..self.opts.clone()
        };
        let (grad, _) = crate::adjoint::render_adjoint(scene, &self.params, &adjoint, &adj_opts)?;
        Ok((l, grad))
    }

    /// Refuses, without rendering, what would stop a run from `start` with learning rates
    /// `lr` decaying to `lr · lr_end` before its first iteration: the schedule, one start
    /// value, bound and rate per parameter, and the parameters on the scene at `start`
    /// (names, and time derivatives the estimators cannot take: `adjoint::check_params`).
    /// `dtr optimize` calls it before it creates its output folder. Returns where each
    /// parameter may go ([`Problem::domains`]).
    pub fn check(&self, start: &[f64], lr: &[f64], lr_end: f64) -> Result<Vec<Domain>, Error> {
        self.check_schedule(start, lr, lr_end)?;
        let scene = self.scene_at(start)?;
        let domains = self.domains(&scene, start)?;
        crate::adjoint::check_params(&scene, &self.params, &self.opts)?;
        self.check_closed_ends(start, &domains)?;
        Ok(domains)
    }

    /// Refuses a closed end of a parameter's range (its kind's domain within `--bound`) where
    /// the scene, the other parameters at their start, would not render as the run asks: a
    /// step past that end stops exactly there (`Domain::project`). A liquid bounded at the
    /// index of the glass around it became a smooth dielectric at that end, and the run
    /// stopped part-way (iteration 7) with advice that did not apply.
    fn check_closed_ends(&self, start: &[f64], domains: &[Domain]) -> Result<(), Error> {
        for (k, d) in domains.iter().enumerate() {
            for (end, open) in [(d.lo, d.open_lo), (d.hi, d.open_hi)] {
                if open || !end.is_finite() || end == start[k] {
                    continue;
                }
                let mut at = start.to_vec();
                at[k] = end;
                let refused = self
                    .scene_at(&at)
                    .and_then(|s| crate::adjoint::check_params(&s, &self.params, &self.opts));
                if let Err(e) = refused {
                    return Err(Error::Invalid(format!(
                        "{}: a step past the end {end} of where it may go ({d}) stops there, and the scene does not render there as this run asks: {e}; set its --bound a little inside that end",
                        self.params[k]
                    )));
                }
            }
        }
        Ok(())
    }

    /// The parameter `name` of `scene` (a scene of this problem).
    fn param<'a>(&self, scene: &'a Scene, name: &str) -> Result<&'a crate::params::Param, Error> {
        scene.params.iter().find(|p| p.name == name).ok_or_else(|| {
            Error::Invalid(format!(
                "{}: no parameter {name:?} (dtr info lists them)",
                self.scene.display()
            ))
        })
    }

    /// Where each parameter may go: the values its kind may take (`ParamKind::domain`) within
    /// its bounds, on `scene` (this problem's, at `start`). Refuses a start outside its bounds.
    pub fn domains(&self, scene: &Scene, start: &[f64]) -> Result<Vec<Domain>, Error> {
        self.params
            .iter()
            .zip(start)
            .zip(&self.bounds)
            .map(|((name, &v), &(lo, hi))| {
                if !(lo..=hi).contains(&v) {
                    return Err(Error::Invalid(format!(
                        "{name}: the start {v} is outside its bounds [{lo}, {hi}] (--bound)"
                    )));
                }
                Ok(self.param(scene, name)?.kind.domain(v).0.within(lo, hi))
            })
            .collect()
    }

    /// The part of [`Problem::check`] that needs no scene.
    fn check_schedule(&self, start: &[f64], lr: &[f64], lr_end: f64) -> Result<(), Error> {
        let n = self.params.len();
        if !(lr_end > 0.0 && lr_end <= 1.0) {
            return Err(Error::Invalid(format!(
                "the final learning-rate fraction {lr_end} must be in (0, 1]"
            )));
        }
        if self.bounds.len() != n || start.len() != n || lr.len() != n {
            return Err(Error::Invalid(
                "one start value, one bound and one learning rate per parameter".into(),
            ));
        }
        if let Some((name, rate)) = self.params.iter().zip(lr).find(|(_, r)| !(r.is_finite() && **r > 0.0)) {
            return Err(Error::Invalid(format!(
                "{name}: the learning rate {rate} must be a finite number above 0"
            )));
        }
        Ok(())
    }

    /// Runs `iters` iterations of Adam from `start` with learning rates `lr` (one per
    /// parameter) that decay geometrically from `lr` for the first step to `lr · lr_end` for
    /// the last, the one to the last iteration (with noisy gradients a constant rate leaves
    /// the iterates wandering around the answer; `lr_end = 1` keeps it constant). Every
    /// iterate stays in its parameter's domain within its bounds (`Problem::bounds`).
    /// `on_step` sees every iteration and returns false to stop early. Returns every step.
    pub fn optimize(
        &self,
        start: &[f64],
        iters: usize,
        lr: &[f64],
        lr_end: f64,
        mut on_step: impl FnMut(&Step) -> bool,
    ) -> Result<Vec<Step>, Error> {
        self.check_schedule(start, lr, lr_end)?;
        let mut x = start.to_vec();
        let mut adam = adam::Adam::new(lr.to_vec());
        let base = self.opts.seed.unwrap_or(0);
        // grown as the run goes: `iters` may be any number a run is stopped short of (it
        // reserved 72 bytes per iteration up front: `--iters 18446744073709551615` panicked)
        let mut steps = Vec::new();
        let mut scene = Scene::load_with_text(&self.scene, &self.fixed, &self.fixed_text)?;
        self.set_values(&mut scene, &x)?;
        let domains = self.domains(&scene, &x)?;
        for it in 0..iters {
            let t0 = std::time::Instant::now();
            let seed = base.wrapping_add(2 * it as u64);
            if let Some((name, v)) = self.params.iter().zip(&x).find(|(_, v)| !v.is_finite()) {
                return Err(Error::Invalid(format!(
                    "iteration {it}: Adam's step took {name} to {v}: its learning rate is too large for it"
                )));
            }
            self.set_values(&mut scene, &x).map_err(|e| {
                Error::Invalid(format!(
                    "iteration {it}: the scene does not take the values the steps reached ({}): {e}",
                    self.params
                        .iter()
                        .zip(&x)
                        .map(|(n, v)| format!("{n} = {v}"))
                        .collect::<Vec<_>>()
                        .join(", ")
                ))
            })?;
            let (l, g) = self.loss_and_gradient_of(&scene, seed)?;
            if !l.is_finite() || g.iter().any(|v| !v.is_finite()) {
                return Err(Error::Invalid(format!(
                    "iteration {it}: the loss ({l}) or its gradient ({g:?}) is not finite"
                )));
            }
            let step = Step {
                iteration: it,
                loss: l,
                values: x.clone(),
                grad: g.clone(),
                seconds: t0.elapsed().as_secs_f64(),
            };
            let go_on = on_step(&step);
            steps.push(step);
            if !go_on || it + 1 == iters {
                break;
            }
            // steps 0 … iters − 2: from lr to lr · lr_end
            let decay = lr_end.powf(it as f64 / iters.saturating_sub(2).max(1) as f64);
            adam.lr = lr.iter().map(|l| l * decay).collect();
            adam.step(&mut x, &g, &domains);
        }
        Ok(steps)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn steps(values: &[f64]) -> Vec<Step> {
        values
            .iter()
            .enumerate()
            .map(|(i, &v)| Step {
                iteration: i,
                loss: 0.0,
                values: vec![v, -v],
                grad: vec![1.0, -1.0],
                seconds: 0.0,
            })
            .collect()
    }

    #[test]
    fn a_run_still_moving_or_stopped_at_its_bound_is_named() {
        let names = ["a".to_string(), "b".to_string()];
        let any = [Domain::ANY; 2];
        // 40 steps: the last 10 of a (and -a) all go down; settled values go back and forth
        let falling: Vec<f64> = (0..40).map(|i| 2.0 - 0.01 * i as f64).collect();
        let w = unsettled(&names, &steps(&falling), &any);
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(
            w[0].starts_with("a was still moving") && w[0].contains("went down"),
            "{w:?}"
        );
        assert!(w[1].contains("went up"), "{w:?}");
        let settled: Vec<f64> = (0..40).map(|i| 1.0 + 0.001 * (i % 2) as f64).collect();
        assert!(unsettled(&names, &steps(&settled), &any).is_empty());
        let short: Vec<f64> = (0..10).map(|i| i as f64).collect();
        assert!(
            unsettled(&names, &steps(&short), &any).is_empty(),
            "too few steps to tell"
        );
        // ending on a closed end of the domain
        let bounded = [Domain::closed(0.0, 1.0), Domain::ANY];
        let w = unsettled(&names, &steps(&[0.5, 0.2, 0.0]), &bounded);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("a ended at 0, the lower end") && w[0].contains("in [0, 1]"),
            "{w:?}"
        );
        // a gradient of 0 at every iteration: the value is its start, whatever else holds
        // (before, a constant value counted as settled and the run ended with no warning)
        let mut still = steps(&[1.5; 40]);
        still.iter_mut().for_each(|s| s.grad[1] = 0.0);
        let w = unsettled(&names, &still, &any);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].starts_with("b never moved from its start (-1.5)") && w[0].contains("--estimators interior"),
            "{w:?}"
        );
    }

    /// A run is asked for any number of iterations and stopped by its caller: nothing is
    /// reserved for them up front. Before, `Vec::with_capacity(iters)` panicked ("capacity
    /// overflow") for `--iters 18446744073709551615` and aborted the process for 4294967296
    /// (found by an independent sweep).
    #[test]
    fn a_run_of_any_length_reserves_nothing_up_front() {
        let scene = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/pose_plate.toml"));
        let fixed = vec![
            ("camera.resolution.0".to_string(), 4.0),
            ("camera.resolution.1".to_string(), 4.0),
        ];
        let loaded = Scene::load_with_text(&scene, &fixed, &[]).unwrap();
        let f = &loaded.film;
        let problem = Problem {
            scene,
            fixed,
            fixed_text: Vec::new(),
            params: vec!["plate_x".into()],
            target: Transient::zeros(f.width as usize, f.height as usize, f.axis, f.channels),
            loss: loss::Loss::L2,
            opts: RenderOptions {
                spp: Some(1),
                seed: Some(1),
                threads: Some(1),
                ..Default::default()
            },
            bounds: vec![(f64::NEG_INFINITY, f64::INFINITY)],
        };
        for iters in [usize::MAX, 1 << 32] {
            let steps = problem.optimize(&[0.1], iters, &[0.01], 1.0, |_| false).unwrap();
            assert_eq!(steps.len(), 1, "stopped by its caller after the first");
        }
    }

    #[test]
    fn a_run_that_never_gained_or_went_dark_is_named() {
        let run = |losses: &[f64]| -> Vec<Step> {
            let mut s = steps(&vec![1.0; losses.len()]);
            s.iter_mut().zip(losses).for_each(|(s, &l)| s.loss = l);
            s
        };
        let falling: Vec<f64> = (0..40).map(|i| 1.0 / (1.0 + i as f64)).collect();
        assert!(no_progress(&run(&falling), 2.0).is_empty());
        let flat: Vec<f64> = (0..40).map(|i| 1.0 + 0.01 * (i % 3) as f64).collect();
        let w = no_progress(&run(&flat), 5.0);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].starts_with("the loss did not fall over the run"), "{w:?}");
        // fell, but to where a dark render stands
        let dark: Vec<f64> = (0..40).map(|i| if i < 5 { 3.0 } else { 1.0 }).collect();
        let w = no_progress(&run(&dark), 1.0);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("no better than a render with no light"), "{w:?}");
        assert!(no_progress(&run(&flat[..10]), 5.0).is_empty(), "too few steps to tell");
        // the end is the last quarter, at least 10 steps, as for the other checks (20 steps
        // read their last 5 here until the forty-third session)
        let w = no_progress(&run(&flat[..20]), 5.0);
        assert!(w[0].contains("mean of the last 10 iterations"), "{w:?}");
        let w = no_progress(&run(&flat[..11]), 5.0);
        assert!(w[0].contains("mean of the last 10 iterations"), "{w:?}");
    }

    #[test]
    fn tail_spread_is_the_deviation_of_the_last_quarter() {
        // 40 steps: the last 10 alternate 1 and 3 (sample standard deviation √(10/9))
        let values: Vec<f64> = (0..40)
            .map(|i| if i < 30 { 100.0 } else { 1.0 + 2.0 * (i % 2) as f64 })
            .collect();
        let (spread, n) = tail_spread(&steps(&values)).unwrap();
        assert_eq!(n, 10);
        assert!((spread[0] - (10.0f64 / 9.0).sqrt()).abs() < 1e-12, "{spread:?}");
        assert_eq!(spread[0], spread[1]);
        assert!(tail_spread(&steps(&[1.0; 9])).is_none(), "too few steps");
    }

    #[test]
    fn tail_average_takes_the_mean_of_the_last_iterates() {
        let s = steps(&[10.0, 8.0, 1.0, 2.0, 3.0, 6.0]);
        assert_eq!(tail_average(&s, 0.5), Some(vec![11.0 / 3.0, -11.0 / 3.0]));
        assert_eq!(tail_average(&s, 0.0), Some(vec![6.0, -6.0]), "the last iterate");
        assert_eq!(tail_average(&s, 1.0), Some(vec![5.0, -5.0]));
        assert_eq!(tail_average(&s, 1.5), None);
        assert_eq!(tail_average(&[], 0.5), None);
    }
}
