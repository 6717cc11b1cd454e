//! The files a `dtr optimize` run writes as it goes, in its folder: `log.csv` (a row per
//! iteration, flushed as it goes), `best.json` and the recovered scene (the lowest loss so
//! far), and at the end the recovered scene of the result and the plots.
//!
//! A run interrupted by SIGINT, SIGTERM or SIGHUP waits for the write in progress (the row,
//! best.json and the recovered scene are written together, under one lock), then keeps what
//! it has: with iterations logged, the log, the best values so far and the plots of those
//! iterations; with none, nothing (the log's header and the folder it made are removed, so a
//! rerun into the same folder is not refused). Before, Ctrl-C killed the process wherever it
//! was: best.json and the recovered scene could disagree, a staging file stayed behind, and a
//! run stopped before its first iteration left a folder that refused the rerun.

use crate::optimize::Step;
use anyhow::Context;
use std::io::{Seek, Write};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

/// What a run has written so far, shared with the signal thread.
pub(super) struct RunFiles {
    dir: PathBuf,
    /// whether this run made the folder (an empty one given with -o is kept)
    created: bool,
    recovered: PathBuf,
    names: Vec<String>,
    log: std::fs::File,
    /// the length of the log's complete rows: a row the file system cuts short is cut back
    /// to it
    log_len: u64,
    best: f64,
    steps: Vec<Step>,
}

/// Where a run is, as the signal thread sees it.
pub(super) enum RunState {
    /// Its folder is not made yet: a signal ends it at once.
    Before,
    /// It logs iterations: a signal keeps what it has ([`RunFiles`]'s module doc).
    Running(RunFiles),
    /// It writes its result: a signal waits for it to end.
    Done,
}

/// The run's state behind the lock the signal thread takes before it acts.
pub(super) type Shared = Arc<Mutex<RunState>>;

/// The columns of `log.csv`: the iteration, the loss, each parameter's value and each one's
/// gradient (`d_NAME`), and the seconds the iteration took.
fn log_columns(names: &[String]) -> Vec<String> {
    let values = names.iter().cloned();
    let grads = names.iter().map(|p| format!("d_{p}"));
    ["iteration".to_string(), "loss".to_string()]
        .into_iter()
        .chain(values)
        .chain(grads)
        .chain(["seconds".to_string()])
        .collect()
}

/// Refuses parameters whose names would make a column of `log.csv` twice (a parameter named
/// `loss`, or `a` beside `d_a`): a reader that takes columns by name read the parameter's
/// value as the loss.
pub(super) fn check_log_columns(names: &[String]) -> anyhow::Result<()> {
    let columns = log_columns(names);
    for (i, c) in columns.iter().enumerate() {
        if let Some(first) = columns[..i].iter().position(|d| d == c) {
            anyhow::bail!(
                "--params {}: log.csv would have the column {c} twice (columns {} and {}: iteration, loss, the values, their gradients d_NAME, seconds); rename the parameter in the scene",
                names.join(","),
                first + 1,
                i + 1
            );
        }
    }
    Ok(())
}

/// Refuses parameters whose plot `param_NAME.png` would have a file name longer than a file
/// system takes, before the first iteration. Before, a parameter named with 300 characters
/// ran every iteration and then failed writing its plot, without `result.json` (exit 3).
pub(super) fn check_plot_names(names: &[String]) -> anyhow::Result<()> {
    let max = super::output_set::NAME_MAX;
    let plots = names.iter().map(|n| (n, format!("param_{n}.png")));
    if let Some((name, plot)) = plots.into_iter().find(|(_, plot)| plot.len() > max) {
        anyhow::bail!(
            "--params {name}: the run would plot it to {plot} ({} bytes), and a file name may have at most {max} \
             bytes; rename the parameter in the scene",
            plot.len()
        );
    }
    Ok(())
}

impl RunFiles {
    /// Starts the log in `dir` (made by this run when `created`) with its header. A log the
    /// file system refuses is an output error naming it, and the folder is left as it was
    /// found.
    pub(super) fn start(dir: &Path, created: bool, recovered: PathBuf, names: &[String]) -> anyhow::Result<Self> {
        let log_path = dir.join("log.csv");
        let header = format!("{}\n", log_columns(names).join(","));
        let log = std::fs::File::create(&log_path).and_then(|mut log| {
            log.write_all(header.as_bytes())?;
            Ok(log)
        });
        match log {
            Ok(log) => Ok(Self {
                dir: dir.to_path_buf(),
                created,
                recovered,
                names: names.to_vec(),
                log,
                log_len: header.len() as u64,
                best: f64::INFINITY,
                steps: Vec::new(),
            }),
            Err(e) => {
                remove_run(dir, created);
                Err(crate::output::OutputError::io(&log_path, e).into())
            }
        }
    }

    /// Logs `s` (its row whole: a row the file system cuts short is cut back off, so the log
    /// holds complete rows only), and where its loss is the lowest so far writes `best.json`
    /// and the recovered scene together ([`write_best`]; `scene_text` makes the scene's text
    /// from the values).
    pub(super) fn log_step(
        &mut self,
        s: &Step,
        scene_text: impl Fn(&[(String, f64)]) -> anyhow::Result<String>,
    ) -> anyhow::Result<()> {
        let row = |v: &[f64]| v.iter().map(|x| format!("{x:e}")).collect::<Vec<_>>().join(",");
        let line = format!(
            "{},{:e},{},{},{}\n",
            s.iteration,
            s.loss,
            row(&s.values),
            row(&s.grad),
            s.seconds
        );
        if let Err(e) = self.log.write_all(line.as_bytes()) {
            // a full disk takes part of the row: cut the log back to its last complete row
            // (shortening a file needs no space), where the next write would go too
            let _ = self.log.set_len(self.log_len);
            let _ = self.log.seek(std::io::SeekFrom::Start(self.log_len));
            return Err(crate::output::OutputError::io(&self.dir.join("log.csv"), e).into());
        }
        self.log_len += line.len() as u64;
        self.steps.push(s.clone());
        if s.loss < self.best {
            self.best = s.loss;
            let values = self.values(&s.values);
            let json = serde_json::json!({
                "about": "the iterate with the lowest loss so far (losses are Monte Carlo estimates)",
                "iteration": s.iteration,
                "loss": s.loss,
                "params": values.iter().map(|(n, v)| (n.clone(), serde_json::json!(v))).collect::<serde_json::Map<_, _>>(),
            });
            write_best(
                &self.dir.join("best.json"),
                &json,
                &self.recovered,
                &scene_text(&values)?,
            )?;
        }
        Ok(())
    }

    /// The parameters' names paired with `values`.
    pub(super) fn values(&self, values: &[f64]) -> Vec<(String, f64)> {
        self.names.iter().cloned().zip(values.iter().copied()).collect()
    }

    /// The recovered scene's file.
    pub(super) fn recovered(&self) -> &Path {
        &self.recovered
    }

    /// Writes the plots of the iterations logged: `loss.png` (log-log where every loss is
    /// above 0, else on linear axes: a run whose window holds no light has losses of 0) and
    /// `param_NAME.png`.
    pub(super) fn write_plots(&self) -> anyhow::Result<()> {
        let loss: Vec<(f64, f64)> = self.steps.iter().map(|s| ((s.iteration + 1) as f64, s.loss)).collect();
        let series = [("loss".to_string(), loss)];
        let path = self.dir.join("loss.png");
        let title = "loss over the iterations";
        if series[0].1.iter().all(|&(_, l)| l > 0.0) {
            crate::output::write_loglog_plot(&path, title, "iteration + 1", "loss", &series)?;
        } else {
            crate::output::write_line_plot(&path, title, "iteration + 1", "loss", &series)?;
        }
        for (k, name) in self.names.iter().enumerate() {
            let v: Vec<(f64, f64)> = self.steps.iter().map(|s| (s.iteration as f64, s.values[k])).collect();
            crate::output::write_line_plot(
                &self.dir.join(format!("param_{name}.png")),
                &format!("{name} over the iterations"),
                "iteration",
                name,
                &[(name.clone(), v)],
            )?;
        }
        Ok(())
    }

    /// What the run's folder holds of the files a stopped run keeps, as a list to print:
    /// `log.csv` and its rows, `best.json` and the recovered scene (the best values so far),
    /// the plots; only the files that are there (a full disk may have refused the pair or
    /// the plots).
    fn kept(&self) -> Vec<String> {
        let there = |name: &str| self.dir.join(name).is_file();
        let rows = self.steps.len();
        let mut kept = vec![format!(
            "the log.csv of {rows} {}",
            if rows == 1 { "iteration" } else { "iterations" }
        )];
        let recovered = self.recovered.file_name().unwrap_or_default().to_string_lossy();
        if there("best.json") && self.recovered.is_file() {
            kept.push(format!("the best values so far (best.json and {recovered})"));
        }
        let plots: Vec<String> = std::iter::once("loss.png".to_string())
            .chain(self.names.iter().map(|n| format!("param_{n}.png")))
            .filter(|p| there(p))
            .collect();
        if !plots.is_empty() {
            kept.push(format!("the plots {}", plots.join(", ")));
        }
        kept
    }

    /// The error of a run that failed after its folder was made. With no iteration logged,
    /// its `log.csv` is removed, and the folder too when this run made it, so that the folder
    /// does not refuse a rerun. With some, the log, the best values so far and their plots
    /// are kept, as Ctrl-C keeps them, and the error lists those of them that are there.
    pub(super) fn abandon(self, e: anyhow::Error) -> anyhow::Error {
        let logged = self.steps.len();
        if logged == 0 {
            remove_run(&self.dir, self.created);
            return e;
        }
        let _ = self.write_plots();
        let iterations = if logged == 1 { "iteration" } else { "iterations" };
        let kept = self.kept();
        e.context(format!(
            "{}: the run stopped after {logged} {iterations}; {} {} kept, as an interrupted run \
             keeps {}. Give another -o (or remove the folder) to run again",
            self.dir.display(),
            listed(&kept),
            if kept.len() == 1 { "is" } else { "are" },
            if kept.len() == 1 { "it" } else { "them" }
        ))
    }
}

/// Writes `best.json` (`json`) and the recovered scene (`recovered`, `text`) as a pair: both
/// are written whole beside their places first, so that a file system that refuses either
/// leaves the earlier pair (or none) as it was. Then the earlier `best.json` is removed, the
/// scene moved into place and the new `best.json` last, so that a `best.json` is always
/// beside the scene of its values; a move that fails removes both. Before, each was written
/// in turn, and a full disk left `best.json` without the recovered scene.
fn write_best(json_path: &Path, json: &serde_json::Value, recovered: &Path, text: &str) -> anyhow::Result<()> {
    let json_staged = crate::output::stage_json(json_path, json)?;
    let scene_staged = stage_text(recovered, text)?;
    match std::fs::remove_file(json_path) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            return Err(crate::output::OutputError::io(json_path, e).into());
        }
        _ => {}
    }
    let moved = scene_staged.persist().and_then(|()| json_staged.persist());
    if moved.is_err() {
        let _ = std::fs::remove_file(json_path);
        let _ = std::fs::remove_file(recovered);
    }
    Ok(moved?)
}

/// `items` as a list in a sentence: "a", "a and b", "a, b and c".
fn listed(items: &[String]) -> String {
    match items.split_last() {
        Some((last, [])) => last.clone(),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
        None => String::new(),
    }
}

/// Removes the log of a run that logged no iteration, and its folder when the run made it.
fn remove_run(dir: &Path, created: bool) {
    let _ = std::fs::remove_file(dir.join("log.csv"));
    if created {
        let _ = std::fs::remove_dir(dir);
    }
}

/// `text` written whole beside `path`, not yet in place ([`crate::output::Staged`]).
pub(super) fn stage_text(path: &Path, text: &str) -> Result<crate::output::Staged, crate::output::OutputError> {
    crate::output::stage_atomic(path, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| crate::output::OutputError::io(path, e))
    })
}

/// Starts the thread that ends the run on SIGINT, SIGTERM or SIGHUP: it takes the lock on
/// `state` (so no write is cut in two) and, while the run logs iterations, keeps what it has
/// ([`RunFiles`]'s module doc), says so, and exits with 128 + the signal, holding the lock.
/// Before the folder is made it exits at once; once the run writes its result it lets it end.
pub(super) fn end_on_signal(state: Shared) -> anyhow::Result<()> {
    use signal_hook::consts::{SIGHUP, SIGINT, SIGTERM};
    let mut signals = signal_hook::iterator::Signals::new([SIGINT, SIGTERM, SIGHUP])
        .context("cannot install the SIGINT/SIGTERM/SIGHUP handler")?;
    std::thread::spawn(move || {
        for sig in signals.forever() {
            let guard = state.lock().unwrap_or_else(|e| e.into_inner());
            let said = match &*guard {
                RunState::Done => continue,
                RunState::Before => "nothing was written".to_string(),
                RunState::Running(run) if run.steps.is_empty() => {
                    remove_run(&run.dir, run.created);
                    "no iteration was logged, so nothing was kept".to_string()
                }
                RunState::Running(run) => {
                    let plots = match run.write_plots() {
                        Ok(()) => String::new(),
                        Err(e) => format!(" (no plots: {e:#})"),
                    };
                    format!("{} keeps {}{plots}", run.dir.display(), listed(&run.kept()))
                }
            };
            eprintln!("dtr: interrupted (signal {sig}); {said}");
            super::exit_from_signal(128 + sig);
        }
    });
    Ok(())
}
