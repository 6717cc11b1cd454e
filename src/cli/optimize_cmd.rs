//! `dtr optimize`: recover scene parameters from a target transient (`crate::optimize`).
//!
//! Writes into a new (or empty) folder: `log.csv` (one row per iteration: loss, values,
//! gradient, seconds; flushed as it goes), `best.json` (the lowest loss so far and its
//! values), `recovered.toml` or `.json` (the scene with the run's `--set` overrides and the
//! recovered values: the best so
//! far while running, the last iterate at the end, or the mean of the last iterates with
//! `--average`), and the plots `loss.png` and `param_NAME.png`. An interrupted run (Ctrl-C)
//! keeps the log and the best values so far. Everything that can be checked before the first
//! render (options, the target, the parameters at their start) is checked before the folder
//! is made; a run that fails before it logs an iteration removes what it made, and one that
//! fails later keeps its log as Ctrl-C does and says so ([`abandon`]).

use crate::film::Transient;
use crate::optimize::{Problem, Step, loss::Loss};
use crate::render::{BoundaryMode, RenderOptions};
use crate::scene::Scene;
use anyhow::{Context, bail};
use std::io::Write;
use std::path::{Path, PathBuf};

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
    pub estimators: super::render_cmd::Estimators,
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
    check_target_axis(path, scene)?;
    Ok(t)
}

/// Refuses a target whose render's JSON (TARGET.json beside TARGET.npy, as `dtr render`
/// writes it) records another time window or unwarping than the scene's: a film of the
/// scene's shape rendered from another `film.start_opl` fits the parameters that shift the
/// light by the difference (0.2 m of OPL moved the recovered depth by 0.1 m, exit 0). A
/// target without such a JSON (a measurement, an array saved from numpy) cannot be checked,
/// and the run says so.
fn check_target_axis(path: &Path, scene: &Scene) -> anyhow::Result<()> {
    let axis = scene.film.axis;
    let json = super::output_set::with_suffix(&path.with_extension(""), "json");
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
    let text = crate::scene::read_regular_file(&json, 64 << 20)
        .with_context(|| format!("{}: cannot read the target's JSON", json.display()))?;
    let meta: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: the target's JSON is not JSON", json.display()))?;
    let t = &meta["time_axis"];
    let (Some(start), Some(width), Some(bins)) =
        (t["start_opl"].as_f64(), t["bin_width_opl"].as_f64(), t["bins"].as_u64())
    else {
        bail!(
            "{}: the target's JSON has no time_axis (start_opl, bin_width_opl, bins) to check against the scene's ({window}); move it away if it is not the JSON of the target's render",
            json.display()
        );
    };
    let same = |a: f64, b: f64| (a - b).abs() <= 1e-9 * a.abs().max(b.abs()).max(1.0);
    if bins as usize != axis.bins || !same(start, axis.start_opl) || !same(width, axis.bin_width_opl) {
        bail!(
            "{}: the target was rendered in another time window ({bins} bins of {width} m from {start} m, field time_axis) than the scene renders ({window}, {}); set the scene's film.start_opl, film.bin_width_opl and film.bins to the target's",
            json.display(),
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
    Ok(())
}

/// The scene the run fitted, as a file in the folder `out_dir`: the scene file's text with
/// the run's `--set` overrides (fields and `[[param]]` values, so that the scene renders as
/// the run rendered it), then each `[[param]]` named in `values` set to its recovered value.
/// Relative file names (meshes) are made absolute when `out_dir` is another folder than the
/// scene's, as `dtr import` makes them, so that it renders.
fn scene_with(a: &OptimizeArgs, values: &[(String, f64)], out_dir: &Path) -> anyhow::Result<String> {
    let path = &a.scene;
    let text = std::fs::read_to_string(path).with_context(|| format!("cannot read {} again", path.display()))?;
    let json = path.extension().and_then(|e| e.to_str()) == Some("json");
    let mut doc: serde_json::Value = if json {
        serde_json::from_str(&text)?
    } else {
        serde_json::to_value(toml::from_str::<toml::Value>(&text)?)?
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

fn write_text(path: &Path, text: &str) -> anyhow::Result<()> {
    crate::output::write_atomic(path, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| crate::output::OutputError::io(path, e))
    })?;
    Ok(())
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
    let scene = Scene::load_with_text(&a.scene, &fixed, &sets.texts)?;
    let target = read_target(&a.target, &scene)?;
    let mut lr = vec![a.lr; a.params.len()];
    for (k, v) in named(
        "--lr-of",
        &a.lr_of,
        &a.params,
        |s| s.parse().ok().filter(|v: &f64| *v > 0.0),
        "X (X > 0)",
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
            boundary: match a.estimators {
                super::render_cmd::Estimators::Full => BoundaryMode::Full,
                super::render_cmd::Estimators::Interior => BoundaryMode::InteriorOnly,
                super::render_cmd::Estimators::Boundary => BoundaryMode::BoundaryOnly,
            },
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
    let (dir, created) = prepare_dir(&a.output, &[&a.scene, &a.target])?;
    let recovered = dir.join(if a.scene.extension().and_then(|e| e.to_str()) == Some("json") {
        "recovered.json"
    } else {
        "recovered.toml"
    });
    // a log the file system refuses (a full disk) is an output error naming it, and leaves
    // nothing behind, as any failure before the first logged iteration
    let log_path = dir.join("log.csv");
    let log_error = |e: std::io::Error| anyhow::Error::new(crate::output::OutputError::io(&log_path, e));
    let names = a.params.join(",");
    let grads: Vec<String> = a.params.iter().map(|p| format!("d_{p}")).collect();
    let header = format!("iteration,loss,{names},{},seconds\n", grads.join(","));
    let mut log = match std::fs::File::create(&log_path)
        .map(std::io::BufWriter::new)
        .and_then(|mut log| {
            log.write_all(header.as_bytes())?;
            log.flush()?;
            Ok(log)
        }) {
        Ok(log) => log,
        Err(e) => return Err(abandon(&dir, created, 0, log_error(e))),
    };
    let bar = crate::render::progress_bar(
        super::logging::chatty(),
        a.iters as u64,
        "{elapsed_precise} [{bar:30}] {pos}/{len} {msg}",
    );
    let mut best = f64::INFINITY;
    let mut logged = 0;
    let mut failure: Option<anyhow::Error> = None;
    let steps = problem.optimize(&start, a.iters, &lr, a.lr_end, |s: &Step| {
        let row = |v: &[f64]| v.iter().map(|x| format!("{x:e}")).collect::<Vec<_>>().join(",");
        let mut ok = writeln!(
            log,
            "{},{:e},{},{},{}",
            s.iteration,
            s.loss,
            row(&s.values),
            row(&s.grad),
            s.seconds
        )
        .and_then(|_| log.flush())
        .map_err(log_error);
        if ok.is_ok() {
            logged += 1;
        }
        if ok.is_ok() && s.loss < best {
            best = s.loss;
            ok = write_best(&dir, &recovered, &a, s);
        }
        bar.set_message(format!("loss {:.3e}  {}", s.loss, pairs(&a.params, &s.values)));
        bar.inc(1);
        if let Err(e) = ok {
            failure = Some(e);
            return false;
        }
        true
    });
    bar.finish_and_clear();
    let steps = match (steps, failure) {
        (Ok(steps), None) => steps,
        (Err(e), _) => return Err(abandon(&dir, created, logged, e.into())),
        (Ok(_), Some(e)) => return Err(abandon(&dir, created, logged, e)),
    };
    let last = steps.last().context("no iteration ran")?;
    for w in crate::optimize::unsettled(&a.params, &steps, &domains) {
        log::warn!("{}: {w}", dir.display());
    }
    let result = crate::optimize::tail_average(&steps, a.average).context("no iteration ran")?;
    let values: Vec<(String, f64)> = a.params.iter().cloned().zip(result.iter().copied()).collect();
    write_text(&recovered, &scene_with(&a, &values, &dir)?)?;
    write_plots(&dir, &a.params, &steps)?;
    log::info!(
        "{}: {} iterations, loss {:.3e} → {:.3e}; {}{}",
        dir.display(),
        steps.len(),
        steps[0].loss,
        last.loss,
        pairs(&a.params, &result),
        if a.average > 0.0 {
            " (mean of the last iterates, --average)"
        } else {
            ""
        }
    );
    Ok(())
}

fn pairs(names: &[String], values: &[f64]) -> String {
    names
        .iter()
        .zip(values)
        .map(|(n, v)| format!("{n} = {v:.6}"))
        .collect::<Vec<_>>()
        .join(", ")
}

fn write_best(dir: &Path, recovered: &Path, a: &OptimizeArgs, s: &Step) -> anyhow::Result<()> {
    let values: Vec<(String, f64)> = a.params.iter().cloned().zip(s.values.iter().copied()).collect();
    let json = serde_json::json!({
        "about": "the iterate with the lowest loss so far (losses are Monte Carlo estimates)",
        "iteration": s.iteration,
        "loss": s.loss,
        "params": values.iter().map(|(n, v)| (n.clone(), serde_json::json!(v))).collect::<serde_json::Map<_, _>>(),
    });
    crate::output::write_json(&dir.join("best.json"), &json)?;
    write_text(recovered, &scene_with(a, &values, dir)?)
}

fn write_plots(dir: &Path, params: &[String], steps: &[Step]) -> anyhow::Result<()> {
    let loss: Vec<(f64, f64)> = steps.iter().map(|s| ((s.iteration + 1) as f64, s.loss)).collect();
    crate::output::write_loglog_plot(
        &dir.join("loss.png"),
        "loss over the iterations",
        "iteration + 1",
        "loss",
        &[("loss".to_string(), loss)],
    )?;
    for (k, name) in params.iter().enumerate() {
        let v: Vec<(f64, f64)> = steps.iter().map(|s| (s.iteration as f64, s.values[k])).collect();
        crate::output::write_line_plot(
            &dir.join(format!("param_{name}.png")),
            &format!("{name} over the iterations"),
            "iteration",
            name,
            &[(name.clone(), v)],
        )?;
    }
    Ok(())
}

/// The error of a run that failed after its folder was made. With no iteration logged, its
/// `log.csv` is removed, and the folder too when this run created it, so that the folder does
/// not refuse a rerun. With some, the log and the best values so far are kept, as Ctrl-C
/// keeps them, and the error says so.
fn abandon(dir: &Path, created: bool, logged: usize, e: anyhow::Error) -> anyhow::Error {
    if logged == 0 {
        let _ = std::fs::remove_file(dir.join("log.csv"));
        if created {
            let _ = std::fs::remove_dir(dir);
        }
        return e;
    }
    let iterations = if logged == 1 { "iteration" } else { "iterations" };
    e.context(format!(
        "{}: the run stopped after {logged} {iterations}; the log.csv and the best values so far \
         (best.json and the recovered scene) are kept, as an interrupted run keeps them. Give \
         another -o (or remove the folder) to run again",
        dir.display()
    ))
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
