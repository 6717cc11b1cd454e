//! `dtr render --checkpoint SECONDS` and `--resume` (the checkpoints themselves:
//! `crate::checkpoint`): where a render's checkpoint lives (PREFIX.checkpoint, under the
//! output set's lock, so one render owns it) and whether it may resume from it.

use super::output_set::{OutputSet, with_suffix};
use crate::checkpoint::Checkpointing;
use crate::scene::Scene;
use anyhow::bail;
use std::sync::Arc;
use std::time::Duration;

/// How often a resumed render checkpoints when `--checkpoint` is not given.
const DEFAULT_SECONDS: f64 = 300.0;

/// The longest `--checkpoint` interval, in seconds (about 31 years): far beyond any render,
/// and well inside what a `Duration` holds (1e20 s is not).
const MAX_SECONDS: f64 = 1e9;

/// Refuses a `--checkpoint` interval that is not a number of seconds in (0, [`MAX_SECONDS`]].
pub fn check_interval(seconds: f64) -> anyhow::Result<()> {
    if !(seconds > 0.0 && seconds <= MAX_SECONDS) {
        // 1e300 as 1e300, not as its 301 digits
        let shown = if seconds.abs() < MAX_SECONDS {
            seconds.to_string()
        } else {
            format!("{seconds:e}")
        };
        bail!("--checkpoint {shown}: expected a number of seconds > 0 and at most {MAX_SECONDS:e}");
    }
    Ok(())
}

/// How a checkpoint's units are cut, kept in its identity so that a checkpoint of another
/// cut (an earlier dtr's) is refused by name rather than resumed into the wrong units. 3:
/// the path tracer's units are (tile, sample block) pairs, several per tile on a film of few
/// tiles (`render::sample_blocks`); 2: BDPT's units are waves of (tile, sample block) units
/// and its films the frame's rows (`integrator::bdpt::units`), the path tracer's one per
/// tile; 1 (no field) had up to 8 chunks of tiles.
const UNITS_LAYOUT: u32 = 3;

/// The checkpointing of a render to `set`'s prefix: every `seconds`, resuming from the
/// checkpoint there when `resume` (refused when there is none, or it is another render's).
pub fn prepare(
    set: &OutputSet,
    scene: &Scene,
    mut identity: serde_json::Value,
    seconds: Option<f64>,
    resume: bool,
) -> anyhow::Result<Arc<Checkpointing>> {
    identity["checkpoint_units"] = serde_json::json!(UNITS_LAYOUT);
    let path = with_suffix(set.prefix(), "checkpoint");
    for input in &scene.inputs {
        if std::fs::canonicalize(input).ok() == std::fs::canonicalize(&path).ok().filter(|_| path.exists()) {
            bail!(
                "the checkpoint {} would replace the input {}",
                path.display(),
                input.display()
            );
        }
    }
    let saved = if resume {
        if !path.exists() {
            bail!(
                "--resume: there is no checkpoint {} (render with --checkpoint SECONDS first, or without --resume)",
                path.display()
            );
        }
        let (theirs, saved) = crate::checkpoint::read(&path)?;
        if theirs != identity {
            let key = identity
                .as_object()
                .and_then(|o| {
                    o.keys()
                        .find(|k| theirs.get(k.as_str()) != identity.get(k.as_str()))
                        .cloned()
                })
                .unwrap_or_else(|| "identity".into());
            let shown = |v: Option<&serde_json::Value>| v.map_or("absent".to_string(), |v| v.to_string());
            bail!(
                "--resume: {} is the checkpoint of another render: {key} was {} there, is {} now",
                path.display(),
                shown(theirs.get(&key)),
                shown(identity.get(&key))
            );
        }
        log::info!(
            "{}: resuming with {} of {} units of the interior pass done{}",
            path.display(),
            saved.done_units(),
            saved.units,
            if saved.boundary.is_some() {
                " and the boundary stage"
            } else {
                ""
            }
        );
        Some(saved)
    } else {
        // the work it holds may be hours: never replaced unasked (a render started without
        // --resume overwrote it, with a warning that came too late for Ctrl-C)
        if path.exists() {
            bail!(
                "{} holds an earlier render's checkpoint: --resume continues it; remove it to start over",
                path.display()
            );
        }
        None
    };
    let every = Duration::from_secs_f64(seconds.unwrap_or(DEFAULT_SECONDS));
    Ok(Arc::new(Checkpointing::new(path, every, identity, saved)))
}
