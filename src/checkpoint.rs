//! Checkpoints of a long render (`dtr render --checkpoint SECONDS`, `--resume`): the partial
//! sums of the finished units of work, written atomically, so that a render killed at any
//! point (SIGKILL included) resumes from its last checkpoint and ends with the same bytes as
//! if it had never stopped.
//!
//! The unit is what the render driver already merges whole: a tile of the path tracer (its
//! sums land in pixels no other tile touches, so a film holding the finished tiles is the
//! uninterrupted film with zeros elsewhere), a wave of BDPT units (added to the frame's rows
//! in unit order when the wave ends, so the rows after a wave are those of the uninterrupted
//! render at that point; `crate::integrator::bdpt::units`), and the boundary stage as a
//! whole. Each path's random numbers depend only on its pixel and sample index, so the
//! units still to run trace exactly the paths they would have traced. The checkpoint holds
//! the sums, per-unit tallies (rays, energy), the render's identity (input hashes,
//! overrides, sample counts, seed: `cli::shard_set::identity`) and nothing that depends on
//! the thread count.
//!
//! File: `DTRCKPT1`, the header's length (u64 LE), the header (JSON: identity, stage, which
//! units are done, tallies, the blob list), then the blobs (f32 or f64 LE arrays).

use crate::boundary::BoundaryStats;
use crate::error::Error;
use crate::film::{TileSums, Transient};
use crate::integrator::deposit::PathCounts;
use serde::{Deserialize, Serialize};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

const MAGIC: &[u8; 8] = b"DTRCKPT1";
/// Largest header a checkpoint may have (the tallies of every tile of a 16k² film fit).
const HEADER_CAP: u64 = 1 << 30;

/// One unit's tallies: its path counts, primal energy before and after the window, and Σ of
/// each film block (as the render driver keeps them).
pub type Tally = (PathCounts, [f64; 2], Vec<f64>);

/// What a render has finished, as saved in (or read from) a checkpoint.
#[derive(Clone, Debug, Default)]
pub struct Saved {
    /// Units of the interior pass: tiles (path tracer) or waves (BDPT).
    pub units: usize,
    pub done: Vec<bool>,
    pub tallies: Vec<Option<Tally>>,
    /// Path tracer: the films (primal, then derivatives), not yet divided by spp, holding
    /// the finished tiles' sums.
    pub frame: Vec<Transient>,
    /// BDPT: the frame's rows (one film per row) after the finished waves.
    pub chunks: Vec<Option<TileSums>>,
    /// The boundary stage's films and record, once it has run.
    pub boundary: Option<(Vec<Transient>, Vec<Transient>, BoundaryStats)>,
}

impl Saved {
    pub fn done_units(&self) -> usize {
        self.done.iter().filter(|&&d| d).count()
    }
}

/// How a render checkpoints: where, how often, the identity it records, and what it
/// resumes from.
#[derive(Debug)]
pub struct Checkpointing {
    pub path: PathBuf,
    pub every: Duration,
    /// The render's identity (compared on resume); stored in the header as is.
    pub identity: serde_json::Value,
    /// The checkpoint to resume from (taken by the render).
    pub resume: Mutex<Option<Saved>>,
    last: Mutex<Instant>,
    /// Held while a checkpoint is written, so a signal's final write waits for it.
    writing: Mutex<()>,
}

impl Checkpointing {
    pub fn new(path: PathBuf, every: Duration, identity: serde_json::Value, resume: Option<Saved>) -> Self {
        Self {
            path,
            every,
            identity,
            resume: Mutex::new(resume),
            last: Mutex::new(Instant::now()),
            writing: Mutex::new(()),
        }
    }

    /// Whether a periodic checkpoint is due (and, if so, counts it as written now; the
    /// write then counts again from its end, [`Self::write`]).
    pub fn due(&self) -> bool {
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        if last.elapsed() >= self.every {
            *last = Instant::now();
            true
        } else {
            false
        }
    }

    /// Writes `saved` atomically (temporary file, sync, rename). The next periodic
    /// checkpoint is due `every` after the write ends: counted from its start, a checkpoint
    /// that takes longer to take and write than `every` (a 1.5 GB film takes seconds) made
    /// the next one due at once, and the workers did little but checkpoint.
    pub fn write(&self, saved: &Saved) -> Result<(), Error> {
        let _guard = self.writing.lock().unwrap_or_else(|e| e.into_inner());
        let t0 = Instant::now();
        let written = write(&self.path, &self.identity, saved);
        log::debug!(
            "checkpoint {} ({} of {} units) written in {:.3} s",
            self.path.display(),
            saved.done_units(),
            saved.units,
            t0.elapsed().as_secs_f64()
        );
        *self.last.lock().unwrap_or_else(|e| e.into_inner()) = Instant::now();
        written
    }
}

#[derive(Serialize, Deserialize)]
struct Blob {
    name: String,
    f64: bool,
    len: usize,
}

#[derive(Serialize, Deserialize)]
struct Header {
    identity: serde_json::Value,
    units: usize,
    done: Vec<bool>,
    tallies: Vec<Option<Tally>>,
    /// Shapes of the path tracer's films: (width, height, time axis, channels) each.
    frame: Vec<(usize, usize, crate::temporal::TimeAxis, usize)>,
    /// BDPT: the frame's rows, with the tails of each.
    chunks: Vec<Option<[f64; 2]>>,
    boundary: Option<(usize, (usize, usize, crate::temporal::TimeAxis, usize), BoundaryStats)>,
    blobs: Vec<Blob>,
}

enum Data<'a> {
    F32(&'a [f32]),
    F64(&'a [f64]),
}

fn write(path: &Path, identity: &serde_json::Value, s: &Saved) -> Result<(), Error> {
    let mut blobs: Vec<(String, Data)> = Vec::new();
    for (k, t) in s.frame.iter().enumerate() {
        blobs.push((format!("frame{k}.data"), Data::F32(&t.data)));
        blobs.push((format!("frame{k}.steady"), Data::F32(&t.steady)));
    }
    for (c, sums) in s.chunks.iter().enumerate() {
        if let Some(sums) = sums {
            blobs.push((format!("chunk{c}.data32"), Data::F32(&sums.data32)));
            blobs.push((format!("chunk{c}.data64"), Data::F64(&sums.data64)));
            blobs.push((format!("chunk{c}.steady"), Data::F64(&sums.steady)));
        }
    }
    let mut boundary = None;
    if let Some((p, q, stats)) = &s.boundary {
        for (name, films) in [("primary", p), ("secondary", q)] {
            for (k, t) in films.iter().enumerate() {
                blobs.push((format!("{name}{k}.data"), Data::F32(&t.data)));
                blobs.push((format!("{name}{k}.steady"), Data::F32(&t.steady)));
            }
        }
        let t = p.first().or(q.first());
        let shape = t.map_or(
            (
                0,
                0,
                s.frame.first().map_or(
                    crate::temporal::TimeAxis {
                        start_opl: 0.0,
                        bin_width_opl: 1.0,
                        bins: 0,
                    },
                    |f| f.axis,
                ),
                0,
            ),
            |t| (t.width, t.height, t.axis, t.channels),
        );
        boundary = Some((p.len(), shape, stats.clone()));
    }
    let header = Header {
        identity: identity.clone(),
        units: s.units,
        done: s.done.clone(),
        tallies: s.tallies.clone(),
        frame: s
            .frame
            .iter()
            .map(|t| (t.width, t.height, t.axis, t.channels))
            .collect(),
        chunks: s.chunks.iter().map(|c| c.as_ref().map(|c| c.tails)).collect(),
        boundary,
        blobs: blobs
            .iter()
            .map(|(name, d)| Blob {
                name: name.clone(),
                f64: matches!(d, Data::F64(_)),
                len: match d {
                    Data::F32(v) => v.len(),
                    Data::F64(v) => v.len(),
                },
            })
            .collect(),
    };
    let text = serde_json::to_vec(&header).map_err(|e| Error::Invalid(format!("checkpoint header: {e}")))?;
    crate::output::write_atomic(path, |w| {
        let io = |e: std::io::Error| crate::output::OutputError::io(path, e);
        w.write_all(MAGIC).map_err(io)?;
        w.write_all(&(text.len() as u64).to_le_bytes()).map_err(io)?;
        w.write_all(&text).map_err(io)?;
        for (_, d) in &blobs {
            match d {
                Data::F32(v) => crate::output::write_le_sparse(w, v, crate::output::MEGABYTE_HOLES).map_err(io)?,
                Data::F64(v) => crate::output::write_le_sparse(w, v, crate::output::MEGABYTE_HOLES).map_err(io)?,
            }
        }
        Ok(())
    })
    .map_err(|e| Error::Invalid(e.to_string()))
}

/// Reads a checkpoint: its identity and what it saved. Every length is checked against the
/// file, so a truncated or foreign file is refused with its name.
pub fn read(path: &Path) -> Result<(serde_json::Value, Saved), Error> {
    let bad = |what: &str| Error::Invalid(format!("{}: not a usable dtr checkpoint: {what}", path.display()));
    let meta = std::fs::metadata(path)
        .map_err(|e| Error::Invalid(format!("{}: cannot read the checkpoint: {e}", path.display())))?;
    if !meta.is_file() {
        return Err(bad("not a regular file"));
    }
    let bytes = std::fs::read(path)
        .map_err(|e| Error::Invalid(format!("{}: cannot read the checkpoint: {e}", path.display())))?;
    if bytes.len() < 16 || &bytes[..8] != MAGIC {
        return Err(bad("it does not start with DTRCKPT1"));
    }
    let hlen = u64::from_le_bytes(bytes[8..16].try_into().expect("8 bytes"));
    if hlen > HEADER_CAP || 16 + hlen > bytes.len() as u64 {
        return Err(bad("its header is cut short"));
    }
    let header: Header =
        serde_json::from_slice(&bytes[16..16 + hlen as usize]).map_err(|e| bad(&format!("header: {e}")))?;
    let mut at = 16 + hlen as usize;
    let mut blobs = std::collections::HashMap::new();
    for b in &header.blobs {
        let size = b
            .len
            .checked_mul(if b.f64 { 8 } else { 4 })
            .ok_or_else(|| bad("a blob is too large"))?;
        let end = at
            .checked_add(size)
            .filter(|&e| e <= bytes.len())
            .ok_or_else(|| bad("it is cut short"))?;
        blobs.insert(b.name.clone(), (b.f64, &bytes[at..end]));
        at = end;
    }
    if at != bytes.len() {
        return Err(bad("it has trailing bytes"));
    }
    let f32s = |name: &str, len: usize| -> Result<Vec<f32>, Error> {
        match blobs.get(name) {
            Some((false, raw)) if raw.len() == 4 * len => Ok(raw
                .chunks_exact(4)
                .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
                .collect()),
            _ => Err(bad(&format!("blob {name} is missing or of the wrong size"))),
        }
    };
    let f64s = |name: &str| -> Result<Vec<f64>, Error> {
        match blobs.get(name) {
            Some((true, raw)) => Ok(raw
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect()),
            _ => Err(bad(&format!("blob {name} is missing"))),
        }
    };
    let film =
        |name: &str, (w, h, axis, c): (usize, usize, crate::temporal::TimeAxis, usize)| -> Result<Transient, Error> {
            let mut t = Transient::zeros(w, h, axis, c);
            t.data = f32s(&format!("{name}.data"), t.data.len())?;
            t.steady = f32s(&format!("{name}.steady"), t.steady.len())?;
            Ok(t)
        };
    if header.done.len() != header.units || header.tallies.len() != header.units {
        return Err(bad("its unit lists disagree"));
    }
    let frame = header
        .frame
        .iter()
        .enumerate()
        .map(|(k, &shape)| film(&format!("frame{k}"), shape))
        .collect::<Result<Vec<_>, _>>()?;
    let mut chunks = Vec::new();
    for (c, tails) in header.chunks.iter().enumerate() {
        chunks.push(match tails {
            Some(tails) => {
                let data32 = f32s(
                    &format!("chunk{c}.data32"),
                    blobs.get(&format!("chunk{c}.data32")).map_or(0, |b| b.1.len() / 4),
                )?;
                Some(TileSums {
                    data32,
                    written: Vec::new(),
                    data64: f64s(&format!("chunk{c}.data64"))?,
                    steady: f64s(&format!("chunk{c}.steady"))?,
                    tails: *tails,
                })
            }
            None => None,
        });
    }
    let boundary = match header.boundary {
        Some((n, shape, stats)) => {
            let films = |name: &str| {
                (0..n)
                    .map(|k| film(&format!("{name}{k}"), shape))
                    .collect::<Result<Vec<_>, _>>()
            };
            Some((films("primary")?, films("secondary")?, stats))
        }
        None => None,
    };
    Ok((
        header.identity,
        Saved {
            units: header.units,
            done: header.done,
            tallies: header.tallies,
            frame,
            chunks,
            boundary,
        },
    ))
}

/// What the signal thread (`cli::output_set`) runs before the process exits on SIGINT or
/// SIGTERM: writes the render's last consistent state, when a render is checkpointing.
static ON_SIGNAL: Mutex<Option<Box<dyn Fn() + Send>>> = Mutex::new(None);

/// Sets (or with `None` clears) what a signal writes.
pub fn set_signal_writer(f: Option<Box<dyn Fn() + Send>>) {
    *ON_SIGNAL.lock().unwrap_or_else(|e| e.into_inner()) = f;
}

/// Writes the checkpoint of the running render, if any (called on SIGINT/SIGTERM).
pub fn write_on_signal() {
    if let Some(f) = ON_SIGNAL.lock().unwrap_or_else(|e| e.into_inner()).as_ref() {
        f();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The next checkpoint is due `every` after the last write ends, not after it began: a
    /// checkpoint that takes longer than `every` (here, 80 ms between the check and the
    /// write) does not make the next one due at once.
    #[test]
    fn the_next_checkpoint_counts_from_the_end_of_the_last() {
        let dir = tempfile::tempdir().unwrap();
        let every = Duration::from_millis(50);
        let ck = Checkpointing::new(dir.path().join("c.checkpoint"), every, serde_json::json!({}), None);
        assert!(!ck.due(), "not due before `every` has passed");
        std::thread::sleep(Duration::from_millis(60));
        assert!(ck.due());
        assert!(!ck.due(), "one checkpoint per interval");
        std::thread::sleep(Duration::from_millis(80));
        ck.write(&Saved::default()).unwrap();
        assert!(!ck.due(), "due again right after a write that took longer than `every`");
        std::thread::sleep(Duration::from_millis(60));
        assert!(ck.due());
    }

    /// Every f64 of the header (the tallies' energies and block sums here) reads back to the
    /// bit: a resumed render's energy report is summed from them and must equal the
    /// uninterrupted render's. serde_json's default float parser may land one ulp off
    /// (tests/cli_checkpoint.rs once failed so, on "inside" = 61.1761974901348), so the
    /// crate is built with its `float_roundtrip` feature.
    #[test]
    fn header_floats_read_back_to_the_bit() {
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            z ^ (z >> 31)
        };
        // sums of the sizes a film block has, and arbitrary finite bit patterns
        let mut values: Vec<f64> = (0..20_000)
            .map(|_| (next() >> 11) as f64 / (1u64 << 53) as f64 * 100.0)
            .collect();
        values.extend((0..20_000).map(|_| f64::from_bits(next())).filter(|v| v.is_finite()));
        values.push(61.1761974901348);
        let tally = |v: &[f64]| Some((PathCounts::default(), [v[0], v[1]], v.to_vec()));
        let saved = Saved {
            units: 2,
            done: vec![true, true],
            tallies: vec![tally(&values), tally(&values[7..])],
            ..Default::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.checkpoint");
        write(&path, &serde_json::json!({"scene": "test"}), &saved).unwrap();
        let (_, back) = read(&path).unwrap();
        for (a, b) in saved.tallies.iter().zip(&back.tallies) {
            let (a, b) = (a.as_ref().unwrap(), b.as_ref().unwrap());
            assert_eq!(a.1.map(f64::to_bits), b.1.map(f64::to_bits));
            let off: Vec<(f64, f64)> =
                a.2.iter()
                    .zip(&b.2)
                    .filter(|(x, y)| x.to_bits() != y.to_bits())
                    .map(|(x, y)| (*x, *y))
                    .collect();
            assert!(
                off.is_empty(),
                "{} of {} values read back otherwise, e.g. {:?}",
                off.len(),
                a.2.len(),
                &off[..off.len().min(3)]
            );
        }
    }
}
