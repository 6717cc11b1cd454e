//! `dtr optimize`: recover scene parameters from a target transient (`crate::optimize`).
//!
//! Writes into a new (or empty) folder: `log.csv` (one row per iteration: loss, values,
//! gradient, seconds; flushed as it goes), `best.json` (the lowest loss so far and its
//! values), `recovered.toml` or `.json` (the scene with the run's `--set` overrides and the
//! recovered values: the best so
//! far while running, the last iterate at the end, or the mean of the last iterates with
//! `--average`), `result.json` (those values and how far the last iterates wandered), and
//! the plots `loss.png` and `param_NAME.png`. An interrupted run (Ctrl-C)
//! keeps the log and the best values so far. Everything that can be checked before the first
//! render (options, the target, the parameters at their start) is checked before the folder
//! is made; a run that fails before it logs an iteration removes what it made, and one that
//! fails later keeps its log as Ctrl-C does and says so (`optimize_files`, which writes the
//! run's files and keeps them on a signal).

use super::optimize_files::{RunFiles, RunState, Shared, stage_text};
use crate::film::Transient;
use crate::named::Named;
use crate::optimize::{Problem, Step, loss::Loss};
use crate::render::{BoundaryMode, RenderOptions};
use crate::scene::Scene;
use anyhow::{Context, bail};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

#[derive(clap::Args, Debug)]
pub struct OptimizeArgs {
    /// Scene description (.toml or .json) whose [[param]] entries are recovered.
    pub scene: PathBuf,
    /// The measured or rendered transient to match: float32 .npy of the scene's film shape
    /// [H, W, T, C] (as `dtr render` writes it). Where the render's JSON lies beside it
    /// (TARGET.json), its time window must be the scene's.
    #[arg(long, value_name = "TARGET.npy")]
    pub target: PathBuf,
    /// The parameters to recover (comma-separated names from `dtr info`).
    #[arg(long, value_delimiter = ',', value_name = "NAME[,NAME...]", required = true)]
    pub params: Vec<String>,
    /// Iterations of Adam.
    #[arg(long, default_value_t = 100)]
    pub iters: usize,
    /// Learning rate: roughly the step per iteration, in each parameter's units.
    #[arg(long, default_value_t = 0.01)]
    pub lr: f64,
    /// Learning rate of one parameter (repeatable): --lr-of NAME=X.
    #[arg(long = "lr-of", value_name = "NAME=X")]
    pub lr_of: Vec<String>,
    /// The learning rates decay geometrically to this fraction at the last iteration.
    #[arg(long = "lr-end", default_value_t = 0.1)]
    pub lr_end: f64,
    /// Recover the mean of the iterates of the last fraction F of the run (Polyak averaging)
    /// instead of the last iterate: with noisy gradients a steadier estimate. 0 = the last
    /// iterate.
    #[arg(long, default_value_t = 0.0, value_name = "F")]
    pub average: f64,
    /// Bounds of one parameter (repeatable): --bound NAME=LO:HI.
    #[arg(long = "bound", value_name = "NAME=LO:HI")]
    pub bound: Vec<String>,
    /// Loss: l2, smooth (Gaussian blur in time, σ = 4 bins), multiscale (time scales of
    /// 1..16 bins) or steady (time-integrated images only).
    #[arg(long, default_value = "l2", value_parser = parse_loss)]
    pub loss: Loss,
    /// Samples per pixel of each render (primal and adjoint).
    #[arg(long, default_value_t = 4)]
    pub spp: u32,
    /// Boundary samples per pixel (default: --spp).
    #[arg(long = "spp-boundary")]
    pub spp_boundary: Option<u32>,
    /// First seed of the run's seed stream (iteration i renders with seeds S + 2i, S + 2i + 1).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Override a parameter (repeatable): a recovered parameter starts there, any other
    /// stays fixed there.
    #[arg(long = "set", value_name = "NAME=VALUE")]
    pub set: Vec<String>,
    /// Which parts of the gradient to use: full (interior + boundary), interior (to see
    /// what the boundary term is for, or for a smooth dielectric's index, whose boundary
    /// term is refused) or boundary (the boundary term alone).
    #[arg(long, value_enum, default_value = "full")]
    pub estimators: BoundaryMode,
    /// Output folder (created; must be empty if it exists).
    #[arg(short = 'o', long = "output", value_name = "DIR")]
    pub output: PathBuf,
}

fn parse_loss(s: &str) -> Result<Loss, String> {
    Loss::parse(s)
}

/// `NAME=VALUE` pairs of a repeatable option, each name once and among `params`.
fn named<T>(
    option: &str,
    items: &[String],
    params: &[String],
    parse: impl Fn(&str) -> Option<T>,
    expected: &str,
) -> anyhow::Result<Vec<(usize, T)>> {
    let mut out: Vec<(usize, T)> = Vec::new();
    for item in items {
        let (name, value) = item
            .split_once('=')
            .with_context(|| format!("{option} {item:?}: expected NAME={expected}"))?;
        let k = params.iter().position(|p| p == name.trim()).with_context(|| {
            format!(
                "{option} {item:?}: {name:?} is not one of --params {}",
                params.join(",")
            )
        })?;
        if out.iter().any(|(j, _)| *j == k) {
            bail!("{option} names {name} more than once");
        }
        let v = parse(value.trim()).with_context(|| format!("{option} {item:?}: expected NAME={expected}"))?;
        out.push((k, v));
    }
    Ok(out)
}

fn read_target(path: &Path, scene: &Scene) -> anyhow::Result<Transient> {
    let f = &scene.film;
    let shape = [f.height as usize, f.width as usize, f.axis.bins, f.channels];
    let what = format!(
        "the --target (the scene {} renders [H, W, T, C])",
        scene.source.display()
    );
    let mut t = Transient::zeros(shape[1], shape[0], f.axis, f.channels);
    t.data = super::npy_in::read_f32(path, &shape, &what)?;
    check_target_render(path, scene)?;
    Ok(t)
}

/// The render JSON that describes a target: TARGET.json beside TARGET.npy, as `dtr render`
/// writes it, or for an NLOS capture's photon counts (PREFIX.noisy.npy) the capture's
/// PREFIX.json; and whether the target is such photon counts.
fn target_json(path: &Path) -> (PathBuf, bool) {
    let stem = path.with_extension("");
    match stem.to_str().and_then(|s| s.strip_suffix(".noisy")) {
        Some(capture) => (super::output_set::with_suffix(Path::new(capture), "json"), true),
        None => (super::output_set::with_suffix(&stem, "json"), false),
    }
}

/// Refuses a target whose render's JSON ([`target_json`]) says it is not a render of what
/// the scene renders: another time window or unwarping (a film of the scene's shape rendered
/// from another `film.start_opl` fits the parameters that shift the light by the difference:
/// 0.2 m of OPL moved the recovered depth by 0.1 m, exit 0), one shard of a render (about
/// 1/N of its light: an albedo came out 0.19 for 0.8), or another relay-wall capture (other
/// relay legs shift every return by the legs' length: a depth of 0.6 came out 0.889; a
/// confocal 8 × 8 scan has the film of an exhaustive 2 × 4 one). Warns of a target rendered
/// from other input files (an edited copy of the scene is one; another scene with the same
/// film is another), and of photon counts (PREFIX.noisy.npy), which are not radiance. A
/// target without such a JSON (a measurement, an array saved from numpy) cannot be
/// checked, and the run says so.
fn check_target_render(path: &Path, scene: &Scene) -> anyhow::Result<()> {
    let axis = scene.film.axis;
    let (json, counts) = target_json(path);
    let window = format!(
        "{} bins of {} m from {} m",
        axis.bins, axis.bin_width_opl, axis.start_opl
    );
    if std::fs::symlink_metadata(&json).is_err() {
        log::warn!(
            "{}: no {} beside it, so its time window cannot be checked: it must be the scene's ({window}{})",
            path.display(),
            json.display(),
            if scene.film.unwarp { ", unwarped" } else { "" }
        );
        return Ok(());
    }
    let text = crate::scene::read_regular_file(&json, super::output_set::JSON_CAP)
        .with_context(|| format!("{}: cannot read the target's JSON", json.display()))?;
    let meta: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: the target's JSON is not JSON", json.display()))?;
    let got = super::shard_set::axis_of(&meta, &json).with_context(|| {
        format!("the target's JSON, to check against the scene's window ({window}); move it away if it is not the JSON of the target's render")
    })?;
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0);
    if got.bins != axis.bins || !same(got.start_opl, axis.start_opl) || !same(got.bin_width_opl, axis.bin_width_opl) {
        bail!(
            "{}: the target was rendered in another time window ({} bins of {} m from {} m, field time_axis) than the scene renders ({window}, {}); set the scene's film.start_opl, film.bin_width_opl and film.bins to the target's",
            json.display(),
            got.bins,
            got.bin_width_opl,
            got.start_opl,
            scene.source.display()
        );
    }
    if let Some(unwarp) = meta["unwarp"].as_bool().filter(|&u| u != scene.film.unwarp) {
        bail!(
            "{}: the target was rendered with film.unwarp = {unwarp}, the scene {} has {}",
            json.display(),
            scene.source.display(),
            scene.film.unwarp
        );
    }
    if let Some(count) = meta["shard"]["count"].as_u64().filter(|&n| n > 1) {
        bail!(
            "{}: the target is shard {}/{count} of a render (field shard), about 1/{count} of its light; merge the shards (dtr merge) and give the merged render as --target",
            json.display(),
            meta["shard"]["index"]
        );
    }
    check_target_capture(&json, &meta, scene)?;
    let digest = super::shard_set::inputs_sha256(scene)?;
    if let Some(other) = meta["identity"]["inputs_sha256"].as_str().filter(|&h| h != digest) {
        log::warn!(
            "{}: the target was rendered from other input files ({}, inputs_sha256 {}) than the scene {} and its meshes: right for an edited copy of the scene, wrong for another scene whose film has the same shape",
            json.display(),
            meta["scene"].as_str().unwrap_or("a scene it does not name"),
            &other[..other.len().min(12)],
            scene.source.display()
        );
    }
    if counts && let Some(noise) = meta["nlos"]["noise"].as_object() {
        log::warn!(
            "{}: photon counts of the capture {} (nlos.noise: photons_per_unit {}, dark_counts {} per bin), not radiance, so every bin is about photons_per_unit times what the scene renders; to fit them, subtract dark_counts and divide by photons_per_unit first",
            path.display(),
            json.display(),
            noise.get("photons_per_unit").unwrap_or(&serde_json::Value::Null),
            noise.get("dark_counts").unwrap_or(&serde_json::Value::Null)
        );
    }
    Ok(())
}

/// Refuses a target captured on a relay wall otherwise than the scene captures (its JSON's
/// `nlos` block against [`crate::scene::nlos::describe`] of the scene's): another scan,
/// grid of points or relay legs, or a capture for a camera render or the other way round.
fn check_target_capture(json: &Path, meta: &serde_json::Value, scene: &Scene) -> anyhow::Result<()> {
    let ours = scene.nlos.as_ref().map(crate::scene::nlos::describe);
    let theirs = meta.get("nlos").filter(|v| !v.is_null());
    match (ours, theirs) {
        (None, None) => Ok(()),
        (Some(_), None) => bail!(
            "{}: the target is a camera render (no field nlos), the scene {} a relay-wall capture",
            json.display(),
            scene.source.display()
        ),
        (None, Some(_)) => bail!(
            "{}: the target is a relay-wall capture (field nlos), the scene {} a camera render",
            json.display(),
            scene.source.display()
        ),
        (Some(ours), Some(theirs)) => {
            for field in ["scan", "relay_legs", "sensor_grid", "laser_grid"] {
                if theirs[field] != ours[field] {
                    bail!(
                        "{}: the target was captured with nlos.{field} = {}, the scene {} captures with {}; set the scene's to the target's",
                        json.display(),
                        theirs[field],
                        scene.source.display(),
                        ours[field]
                    );
                }
            }
            Ok(())
        }
    }
}

/// The scene the run fitted, as a file in the folder `out_dir`: the scene file's text with
/// the run's `--set` overrides (fields and `[[param]]` values, so that the scene renders as
/// the run rendered it), then each `[[param]]` named in `values` set to its recovered value.
/// Relative file names (meshes) are made absolute when `out_dir` is another folder than the
/// scene's, as `dtr import` makes them, so that it renders.
/// `text` is the scene file as the run read it at its start: a file edited or moved while
/// the run goes on does not change what it writes (it did: the lamp of an edit made 3 s into
/// a run moved in the recovered scene, and a moved file stopped the run).
fn scene_with(a: &OptimizeArgs, text: &str, values: &[(String, f64)], out_dir: &Path) -> anyhow::Result<String> {
    let path = &a.scene;
    let json = path.extension().and_then(|e| e.to_str()) == Some("json");
    let mut doc: serde_json::Value = if json {
        serde_json::from_str(text)?
    } else {
        serde_json::to_value(toml::from_str::<toml::Value>(text)?)?
    };
    crate::scene::shapes::rebase_file_names(&mut doc, path, out_dir);
    let sets = super::parse_sets(&a.set)?;
    let (fields, param_sets): (Vec<_>, Vec<_>) = sets
        .numbers
        .into_iter()
        .partition(|(n, _)| crate::scene::field_set::is_field_path(n));
    crate::scene::field_set::apply_text(&mut doc, &sets.texts, path)?;
    crate::scene::field_set::apply(&mut doc, &fields, path)?;
    let values: Vec<(String, f64)> = param_sets
        .into_iter()
        .filter(|(n, _)| !values.iter().any(|(m, _)| m == n))
        .chain(values.iter().cloned())
        .collect();
    if let Some(list) = doc.get_mut("param").and_then(|p| p.as_array_mut()) {
        for p in list {
            let name = p.get("name").and_then(|n| n.as_str()).map(str::to_string);
            if let Some((_, v)) = values.iter().find(|(n, _)| Some(n) == name.as_ref()) {
                p["value"] = serde_json::json!(v);
            }
        }
    }
    Ok(if json {
        serde_json::to_string_pretty(&doc)?
    } else {
        format!(
            "# {} with the values recovered by dtr optimize\n{}",
            path.display(),
            toml::to_string_pretty(&serde_json::from_value::<toml::Value>(doc)?)?
        )
    })
}

pub fn run(a: OptimizeArgs) -> anyhow::Result<()> {
    let sets = super::parse_sets(&a.set)?;
    if let Some(name) = a
        .params
        .iter()
        .enumerate()
        .find(|(i, p)| a.params[..*i].contains(p))
        .map(|(_, p)| p)
    {
        bail!("--params names {name} more than once");
    }
    super::optimize_files::check_log_columns(&a.params)?;
    super::optimize_files::check_plot_names(&a.params)?;
    super::render_cmd::refuse_unused_boundary_samples(a.spp_boundary, a.estimators)?;
    if matches!(a.estimators, BoundaryMode::PrimaryOnly | BoundaryMode::SecondaryOnly) {
        bail!(
            "--estimators {}: one boundary term alone is for finding a derivative's noise with `dtr render`; \
             dtr optimize takes full, interior or boundary",
            a.estimators.name()
        );
    }
    if a.iters == 0 || a.spp == 0 || a.spp_boundary == Some(0) {
        bail!("--iters, --spp and --spp-boundary must be at least 1");
    }
    if !(a.lr.is_finite() && a.lr > 0.0) {
        bail!("--lr {}: expected a positive number", a.lr);
    }
    if !(a.lr_end > 0.0 && a.lr_end <= 1.0) {
        bail!(
            "--lr-end {}: expected a fraction of the learning rate in (0, 1]",
            a.lr_end
        );
    }
    if !(0.0..=1.0).contains(&a.average) {
        bail!(
            "--average {}: expected a fraction of the iterations in [0, 1]",
            a.average
        );
    }
    let (start_sets, fixed): (Vec<_>, Vec<_>) = sets.numbers.into_iter().partition(|(n, _)| a.params.contains(n));
    // the scene file as the run found it: the recovered scenes are made from this text
    let scene_text = crate::scene::read_regular_file(&a.scene, crate::scene::MAX_SCENE_BYTES)
        .with_context(|| format!("cannot read {}", a.scene.display()))?;
    let scene = Scene::load_with_text(&a.scene, &fixed, &sets.texts)?;
    let target = read_target(&a.target, &scene)?;
    if matches!(a.estimators, BoundaryMode::InteriorOnly) {
        super::render_cmd::warn_interior_alone(&scene, &a.params, &a.scene);
    }
    for w in target_warnings(&target.data) {
        log::warn!("{}: {w}", a.target.display());
    }
    let mut lr = vec![a.lr; a.params.len()];
    for (k, v) in named(
        "--lr-of",
        &a.lr_of,
        &a.params,
        |s| s.parse().ok().filter(|v: &f64| v.is_finite() && *v > 0.0),
        "X (a finite X > 0)",
    )? {
        lr[k] = v;
    }
    let mut bounds = vec![(f64::NEG_INFINITY, f64::INFINITY); a.params.len()];
    let parse_bound = |s: &str| {
        let (lo, hi) = s.split_once(':')?;
        let (lo, hi): (f64, f64) = (lo.trim().parse().ok()?, hi.trim().parse().ok()?);
        (lo < hi).then_some((lo, hi))
    };
    for (k, b) in named("--bound", &a.bound, &a.params, parse_bound, "LO:HI (LO < HI)")? {
        bounds[k] = b;
    }
    let problem = Problem {
        scene: a.scene.clone(),
        fixed,
        fixed_text: sets.texts,
        params: a.params.clone(),
        target,
        loss: a.loss,
        opts: RenderOptions {
            spp: Some(a.spp),
            spp_boundary: a.spp_boundary,
            seed: Some(a.seed),
            threads: a.threads,
            boundary: a.estimators,
            ..Default::default()
        },
        bounds,
    };
    let mut start = problem.initial_values()?;
    for (n, v) in &start_sets {
        let k = a.params.iter().position(|p| p == n).expect("partitioned by name");
        start[k] = *v;
    }
    // everything that can stop the run before its first iteration is refused before the
    // folder is made (a parameter whose time derivative cannot be taken, ...)
    let domains = problem.check(&start, &lr, a.lr_end)?;
    // a signal from here on waits for the write in progress, then keeps what the run has
    let state: Shared = Arc::new(Mutex::new(RunState::Before));
    super::optimize_files::end_on_signal(state.clone())?;
    let lock = || state.lock().unwrap_or_else(|e| e.into_inner());
    let dir = {
        let mut guard = lock();
        let (dir, created) = prepare_dir(&a.output, &[&a.scene, &a.target])?;
        let recovered = dir.join(if a.scene.extension().and_then(|e| e.to_str()) == Some("json") {
            "recovered.json"
        } else {
            "recovered.toml"
        });
        *guard = RunState::Running(RunFiles::start(&dir, created, recovered, &a.params)?);
        dir
    };
    let bar = crate::render::progress_bar(
        super::logging::chatty(),
        a.iters as u64,
        "{elapsed_precise} [{bar:30}] {pos}/{len} {msg}",
    );
    let mut failure: Option<anyhow::Error> = None;
    let steps = problem.optimize(&start, a.iters, &lr, a.lr_end, |s: &Step| {
        let logged = match &mut *lock() {
            RunState::Running(run) => run.log_step(s, |values| scene_with(&a, &scene_text, values, &dir)),
            _ => Ok(()),
        };
        bar.set_message(format!("loss {:.3e}  {}", s.loss, pairs(&a.params, &s.values)));
        bar.inc(1);
        if let Err(e) = logged {
            failure = Some(e);
            return false;
        }
        true
    });
    bar.finish_and_clear();
    // the result is written under the lock: a signal now lets the run end
    let mut guard = lock();
    let RunState::Running(run) = std::mem::replace(&mut *guard, RunState::Done) else {
        unreachable!("only this thread ends a running run");
    };
    let steps = match (steps, failure) {
        (Ok(steps), None) => steps,
        (Err(e), _) => return Err(run.abandon(e.into())),
        (Ok(_), Some(e)) => return Err(run.abandon(e)),
    };
    let last = steps.last().context("no iteration ran")?;
    for w in crate::optimize::unsettled(&a.params, &steps, &domains) {
        log::warn!("{}: {w}", dir.display());
    }
    let t = &problem.target;
    let (dark_loss, _) = problem
        .loss
        .value_and_adjoint(&Transient::zeros(t.width, t.height, t.axis, t.channels), t);
    for w in crate::optimize::no_progress(&steps, dark_loss) {
        log::warn!("{}: {w}", dir.display());
    }
    let result = crate::optimize::tail_average(&steps, a.average).context("no iteration ran")?;
    let spread = crate::optimize::tail_spread(&steps);
    // the plots first, then the recovered scene of the result and result.json staged both
    // before either moves into place: a file system that refuses any of them leaves the best
    // values so far as the failure says (before, the recovered scene was replaced by the
    // result's and then result.json or a plot refused, and the message called it the best)
    let finished = run.write_plots().and_then(|()| {
        let text = scene_with(&a, &scene_text, &run.values(&result), &dir)?;
        let scene = stage_text(run.recovered(), &text)?;
        let result = stage_result(&dir, &a, &result, spread.as_ref(), steps.len())?;
        scene.persist()?;
        Ok(result.persist()?)
    });
    if let Err(e) = finished {
        return Err(run.abandon(e));
    }
    drop(guard);
    log::info!(
        "{}: {} iterations, loss {:.3e} → {:.3e}; {}{}{}",
        dir.display(),
        steps.len(),
        steps[0].loss,
        last.loss,
        pairs(&a.params, &result),
        if a.average > 0.0 {
            " (mean of the last iterates, --average)"
        } else {
            ""
        },
        match &spread {
            Some((s, n)) => format!(
                "; the last {n} iterates spread by {} (result.json)",
                pairs(&a.params, s)
            ),
            None => String::new(),
        }
    );
    Ok(())
}

/// `result.json`, written beside its place ([`crate::output::Staged`]): the recovered values (what the recovered scene holds) and, per parameter,
/// how far its iterates wandered over the end of the run (`optimize::tail_spread`): the noise
/// left in the answer, which a single number hides.
fn stage_result(
    dir: &Path,
    a: &OptimizeArgs,
    result: &[f64],
    spread: Option<&(Vec<f64>, usize)>,
    iterations: usize,
) -> anyhow::Result<crate::output::Staged> {
    let params: serde_json::Map<String, serde_json::Value> = a
        .params
        .iter()
        .enumerate()
        .map(|(k, name)| {
            (
                name.clone(),
                serde_json::json!({
                    "value": result[k],
                    "tail_spread": spread.map(|(s, _)| s[k]),
                }),
            )
        })
        .collect();
    let json = serde_json::json!({
        "about": "the recovered values (the recovered scene's) and, per parameter, tail_spread: the standard deviation of its iterates over the last tail_iterations iterations, the scale of the gradient noise left in the last iterate (null for a run of fewer than 10); --average's mean wanders less. A measure of noise, not of the distance to the truth",
        "iterations": iterations,
        "average": a.average,
        "tail_iterations": spread.map(|(_, n)| *n),
        "params": params,
    });
    Ok(crate::output::stage_json(&dir.join("result.json"), &json)?)
}

/// What a target's values say before a run fits them: a film holding no light (every loss
/// is 0 whatever the parameters, so nothing moves), and negative values (a measurement with
/// its background subtracted?), which no render reaches.
fn target_warnings(data: &[f32]) -> Vec<String> {
    let mut out = Vec::new();
    let negative = data.iter().filter(|&&v| v < 0.0).count();
    if negative > 0 {
        let lowest = data.iter().fold(0.0f32, |m, &v| m.min(v));
        out.push(format!(
            "{negative} of its {} values are negative (the lowest {lowest:e}); a render is never negative, so the loss cannot reach 0 there",
            data.len()
        ));
    }
    if !data.iter().any(|&v| v > 0.0) {
        out.push("it holds no light in the window (no value above 0): every parameter that only moves light is fitted to darkness".to_string());
    }
    out
}

fn pairs(names: &[String], values: &[f64]) -> String {
    names
        .iter()
        .zip(values)
        .map(|(n, v)| format!("{n} = {v:.6}"))
        .collect::<Vec<_>>()
        .join(", ")
}

/// Creates `dir` (or accepts it empty): an optimisation never mixes its files with another
/// run's, and never writes where its inputs are. Returns the folder and whether it was
/// created.
fn prepare_dir(dir: &Path, inputs: &[&Path]) -> anyhow::Result<(PathBuf, bool)> {
    let created = !dir.exists();
    if !created {
        let mut entries =
            std::fs::read_dir(dir).with_context(|| format!("-o {}: not a readable folder", dir.display()))?;
        if entries.next().is_some() {
            bail!(
                "-o {}: the folder is not empty; give a new or empty folder (runs never mix their logs)",
                dir.display()
            );
        }
    } else {
        super::output_set::create_folder(dir, dir)?;
    }
    let canon = std::fs::canonicalize(dir)?;
    for input in inputs {
        if std::fs::canonicalize(input)
            .ok()
            .and_then(|p| p.parent().map(Path::to_path_buf))
            == Some(canon.clone())
        {
            bail!("-o {}: holds the input {}", dir.display(), input.display());
        }
    }
    Ok((canon, created))
}
