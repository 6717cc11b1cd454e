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
//! File: `DTRCKPT2`, the header's length (u64 LE), the header (JSON: identity, stage, which
//! units are done, tallies, the blob list), the blobs (f32 or f64 LE arrays), then the CRC-32
//! of everything before it (u32 LE). The lengths alone let a damaged file through: bytes of
//! the bins flipped on disk resumed into a film of 1e28 where the true values were 5e-7, and
//! an edited tally into a negative energy, so a file whose checksum, tallies or values are not
//! what a render writes is refused by name (`DTRCKPT1`, the layout before the checksum,
//! included: it cannot be told from a damaged file). A blob of
//! bins is stored by runs (`"runs": true`): the written bits of its runs of 16 values (u64
//! LE words, as `film::bins` keeps them), then the values of the marked runs, in order; the
//! rest is +0. A transient is sparse in time, so this is what a checkpoint of a large film
//! holds: the Cornell box's 256×256×2000 film at 64 spp, 1.5 GB as an array, is some 400 MB
//! of runs, and no file system holes (a file of 50 000 extents, slow to replace and delete
//! where the file system discards freed blocks) are needed. Blobs without `runs` (dtr's
//! earlier checkpoints, and the steady images) are whole arrays.

use crate::boundary::BoundaryStats;
use crate::error::Error;
use crate::film::{TileSums, Transient};
use crate::integrator::deposit::PathCounts;
use serde::{Deserialize, Serialize};
use std::borrow::Cow;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::{Duration, Instant};

const MAGIC: &[u8; 8] = b"DTRCKPT2";
/// The layout before the checksum, refused by name.
const MAGIC_UNCHECKED: &[u8; 8] = b"DTRCKPT1";
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
    /// Values of the array (with `runs`, of the array the runs are put back into).
    len: usize,
    /// Stored by runs: written bits, then the marked runs' values.
    #[serde(default)]
    runs: bool,
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
    /// Bins stored by the runs the bits mark.
    Runs32(&'a [f32], Cow<'a, [u64]>),
    Runs64(&'a [f64], Cow<'a, [u64]>),
}

impl Data<'_> {
    /// Bins by runs, with their written bits when known (and fitting), else found from the values.
    fn runs32<'a>(values: &'a [f32], written: &'a [u64]) -> Data<'a> {
        Data::Runs32(values, bits(values, written))
    }

    fn runs64<'a>(values: &'a [f64], written: &'a [u64]) -> Data<'a> {
        Data::Runs64(values, bits(values, written))
    }

    fn is_f64(&self) -> bool {
        matches!(self, Data::F64(_) | Data::Runs64(..))
    }

    fn len(&self) -> usize {
        match self {
            Data::F32(v) | Data::Runs32(v, _) => v.len(),
            Data::F64(v) | Data::Runs64(v, _) => v.len(),
        }
    }

    fn write(&self, w: &mut impl Write) -> std::io::Result<()> {
        use crate::output::write_le;
        match self {
            Data::F32(v) => write_le(w, v),
            Data::F64(v) => write_le(w, v),
            Data::Runs32(v, bits) => {
                write_le(w, bits)?;
                crate::film::try_each_written(v, bits, |run| write_le(w, run))
            }
            Data::Runs64(v, bits) => {
                write_le(w, bits)?;
                crate::film::try_each_written(v, bits, |run| write_le(w, run))
            }
        }
    }
}

/// `written` when it fits `values`, else the runs of `values` that hold any bits.
fn bits<'a, T: bytemuck::Pod>(values: &[T], written: &'a [u64]) -> Cow<'a, [u64]> {
    if crate::film::written_len(values.len(), written).is_some() {
        Cow::Borrowed(written)
    } else {
        Cow::Owned(crate::film::nonzero_runs(values))
    }
}

fn write(path: &Path, identity: &serde_json::Value, s: &Saved) -> Result<(), Error> {
    let mut blobs: Vec<(String, Data)> = Vec::new();
    for (k, t) in s.frame.iter().enumerate() {
        blobs.push((format!("frame{k}.data"), Data::runs32(&t.data, &[])));
        blobs.push((format!("frame{k}.steady"), Data::F32(&t.steady)));
    }
    for (c, sums) in s.chunks.iter().enumerate() {
        if let Some(sums) = sums {
            blobs.push((format!("chunk{c}.data32"), Data::runs32(&sums.data32, &sums.written)));
            blobs.push((format!("chunk{c}.data64"), Data::runs64(&sums.data64, &sums.written)));
            blobs.push((format!("chunk{c}.steady"), Data::F64(&sums.steady)));
        }
    }
    let mut boundary = None;
    if let Some((p, q, stats)) = &s.boundary {
        for (name, films) in [("primary", p), ("secondary", q)] {
            for (k, t) in films.iter().enumerate() {
                blobs.push((format!("{name}{k}.data"), Data::runs32(&t.data, &[])));
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
                f64: d.is_f64(),
                len: d.len(),
                runs: matches!(d, Data::Runs32(..) | Data::Runs64(..)),
            })
            .collect(),
    };
    let text = serde_json::to_vec(&header).map_err(|e| Error::Invalid(format!("checkpoint header: {e}")))?;
    crate::output::write_atomic(path, |w| {
        let io = |e: std::io::Error| crate::output::OutputError::io(path, e);
        let mut w = Summed {
            w,
            crc: crc32fast::Hasher::new(),
        };
        w.write_all(MAGIC).map_err(io)?;
        w.write_all(&(text.len() as u64).to_le_bytes()).map_err(io)?;
        w.write_all(&text).map_err(io)?;
        for (_, d) in &blobs {
            d.write(&mut w).map_err(io)?;
        }
        let crc = w.crc.finalize();
        w.w.write_all(&crc.to_le_bytes()).map_err(io)
    })
    .map_err(|e| Error::Invalid(e.to_string()))
}

/// A writer that keeps the CRC-32 of what passes through it (the checkpoint's trailer).
struct Summed<W> {
    w: W,
    crc: crc32fast::Hasher,
}

impl<W: Write> Write for Summed<W> {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        let n = self.w.write(buf)?;
        self.crc.update(&buf[..n]);
        Ok(n)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.w.flush()
    }
}

/// Refuses tallies no render writes (the checksum catches damage; these catch a file written
/// with its checksum after an edit, or by a faulty dtr): a primal energy outside the window
/// that is negative or not finite, a block sum that is not finite or, for the primal (the
/// first block: radiance is never negative), negative. Named by field.
fn check_tallies(h: &Header) -> Result<(), String> {
    let energy = |field: String, v: f64| {
        if v.is_finite() && v >= 0.0 {
            Ok(())
        } else {
            Err(format!("{field}: expected a finite energy >= 0, got {v}"))
        }
    };
    for (i, t) in h.tallies.iter().enumerate() {
        let Some((_, tails, sums)) = t else { continue };
        for (k, &v) in tails.iter().enumerate() {
            energy(format!("tallies[{i}] primal energy {}", ["before", "after"][k]), v)?;
        }
        for (k, &v) in sums.iter().enumerate() {
            if k == 0 {
                energy(format!("tallies[{i}] block sum 0 (the primal)"), v)?;
            } else if !v.is_finite() {
                return Err(format!("tallies[{i}] block sum {k}: expected a finite number, got {v}"));
            }
        }
    }
    for (c, tails) in h.chunks.iter().enumerate() {
        for (k, &v) in tails.iter().flatten().enumerate() {
            energy(format!("chunks[{c}] primal energy {}", ["before", "after"][k]), v)?;
        }
    }
    Ok(())
}

/// The error of a checkpoint at `path` that cannot be resumed, saying `what` is wrong.
fn unusable(path: &Path, what: &str) -> Error {
    Error::Invalid(format!("{}: not a usable dtr checkpoint: {what}", path.display()))
}

/// The checkpoint's bytes with its header, read whole only once its start and header say it
/// is a checkpoint no longer than its blobs allow: a 20 GB file of another kind at the
/// checkpoint's path was read into memory whole before the checksum refused it.
fn read_bounded(path: &Path) -> Result<(Vec<u8>, Header, u64), Error> {
    use std::io::Read;
    let bad = |what: &str| unusable(path, what);
    let cannot = |e: std::io::Error| Error::Invalid(format!("{}: cannot read the checkpoint: {e}", path.display()));
    // not blocking: a FIFO there waited for a writer before it could be refused
    let mut open = std::fs::OpenOptions::new();
    open.read(true);
    #[cfg(unix)]
    std::os::unix::fs::OpenOptionsExt::custom_flags(&mut open, libc::O_NONBLOCK);
    let mut file = open.open(path).map_err(cannot)?;
    let size = file.metadata().map_err(cannot)?;
    if !size.is_file() {
        return Err(bad("not a regular file"));
    }
    let size = size.len();
    let mut bytes = vec![0u8; 16.min(size) as usize];
    file.read_exact(&mut bytes).map_err(cannot)?;
    if bytes.starts_with(MAGIC_UNCHECKED) {
        return Err(bad(
            "it was written by an earlier dtr, without a checksum (render again without --resume)",
        ));
    }
    if size < 20 || &bytes[..8] != MAGIC {
        return Err(bad("it does not start with DTRCKPT2"));
    }
    let hlen = u64::from_le_bytes(bytes[8..16].try_into().expect("8 bytes"));
    if hlen > HEADER_CAP || 20 + hlen > size {
        return Err(bad("its header is cut short"));
    }
    (&mut file).take(hlen).read_to_end(&mut bytes).map_err(cannot)?;
    let header: Header = serde_json::from_slice(&bytes[16..]).map_err(|e| bad(&format!("header: {e}")))?;
    // the most its blobs can take: runs at most every value, with all their written bits
    let most = header
        .blobs
        .iter()
        .try_fold(20 + hlen, |sum, b| {
            let size: u64 = if b.f64 { 8 } else { 4 };
            let bits = if b.runs {
                crate::film::written_words(b.len) as u64 * 8
            } else {
                0
            };
            (b.len as u64).checked_mul(size)?.checked_add(bits)?.checked_add(sum)
        })
        .unwrap_or(u64::MAX);
    if size > most {
        return Err(bad(&format!(
            "it has trailing bytes ({size} bytes where its header allows at most {most})"
        )));
    }
    bytes.reserve_exact((size - 16 - hlen) as usize);
    file.take(most - 16 - hlen + 1)
        .read_to_end(&mut bytes)
        .map_err(cannot)?;
    if bytes.len() as u64 > most || bytes.len() < 20 {
        return Err(bad("it changed while it was read"));
    }
    Ok((bytes, header, hlen))
}

/// Reads a checkpoint: its identity and what it saved. Every length is checked against the
/// file, its checksum against its bytes, and its tallies and values for what a render
/// writes, so a truncated, damaged or foreign file is refused with its name.
pub fn read(path: &Path) -> Result<(serde_json::Value, Saved), Error> {
    let bad = |what: &str| unusable(path, what);
    let (bytes, header, hlen) = read_bounded(path)?;
    let (bytes, crc) = bytes.split_at(bytes.len() - 4);
    if crc32fast::hash(bytes).to_le_bytes() != crc {
        return Err(bad(
            "its checksum does not match its bytes (the file was damaged or changed)",
        ));
    }
    check_tallies(&header).map_err(|e| bad(&e))?;
    let mut at = 16 + hlen as usize;
    // each blob: its entry, its written bits (stored by runs; else none) and its values' bytes
    let mut blobs = std::collections::HashMap::new();
    for b in &header.blobs {
        let size = if b.f64 { 8 } else { 4 };
        let cut = || bad("it is cut short");
        let (bits, len) = if b.runs {
            // the written bits, then the values of the runs they mark
            let words = crate::film::written_words(b.len);
            let end = at
                .checked_add(words.checked_mul(8).ok_or_else(cut)?)
                .filter(|&e| e <= bytes.len())
                .ok_or_else(cut)?;
            let bits = le_words(&bytes[at..end]);
            let packed = crate::film::written_len(b.len, &bits).ok_or_else(|| {
                bad(&format!(
                    "blob {}: its written bits do not fit {} values",
                    b.name, b.len
                ))
            })?;
            at = end;
            (bits, packed.checked_mul(size))
        } else {
            (Vec::new(), b.len.checked_mul(size))
        };
        let len = len.ok_or_else(|| bad("a blob is too large"))?;
        let end = at.checked_add(len).filter(|&e| e <= bytes.len()).ok_or_else(cut)?;
        blobs.insert(b.name.clone(), (b, bits, &bytes[at..end]));
        at = end;
    }
    if at != bytes.len() {
        return Err(bad("it has trailing bytes"));
    }
    // a blob's values and, when stored by runs, its written bits; `None` when the array the
    // runs go back into cannot be had (a corrupt length: the file bounds only the runs)
    fn values<T: bytemuck::Pod, const N: usize>(
        (b, bits, raw): &(&Blob, Vec<u64>, &[u8]),
        from_le: fn([u8; N]) -> T,
    ) -> Option<(Vec<T>, Vec<u64>)> {
        let parsed: Vec<T> = raw
            .chunks_exact(N)
            .map(|c| from_le(c.try_into().expect("N bytes")))
            .collect();
        if !b.runs {
            return Some((parsed, Vec::new()));
        }
        Some((crate::film::unpack_written(b.len, bits, &parsed)?, bits.clone()))
    }
    let no_room = |name: &str, len: usize| bad(&format!("blob {name}: {len} values do not fit in memory"));
    // a render never saves a NaN or an infinity (it would fail at its end, without the file)
    fn finite<T: Copy + Into<f64>>(name: &str, v: &[T]) -> Result<(), String> {
        match v.iter().position(|&x| !x.into().is_finite()) {
            Some(i) => Err(format!(
                "blob {name}: value {i} is {}, expected a finite number",
                v[i].into()
            )),
            None => Ok(()),
        }
    }
    let f32s = |name: &str, len: Option<usize>| -> Result<(Vec<f32>, Vec<u64>), Error> {
        let got = match blobs.get(name) {
            Some(blob) if !blob.0.f64 && len.is_none_or(|n| n == blob.0.len) => {
                values(blob, f32::from_le_bytes).ok_or_else(|| no_room(name, blob.0.len))?
            }
            _ => return Err(bad(&format!("blob {name} is missing or of the wrong size"))),
        };
        finite(name, &got.0).map_err(|e| bad(&e))?;
        Ok(got)
    };
    let f64s = |name: &str| -> Result<(Vec<f64>, Vec<u64>), Error> {
        let got = match blobs.get(name) {
            Some(blob) if blob.0.f64 => values(blob, f64::from_le_bytes).ok_or_else(|| no_room(name, blob.0.len))?,
            _ => return Err(bad(&format!("blob {name} is missing"))),
        };
        finite(name, &got.0).map_err(|e| bad(&e))?;
        Ok(got)
    };
    // a film of the header's shape, allocated only as its blobs come back
    let film = |name: &str, (width, height, axis, channels): (usize, usize, crate::temporal::TimeAxis, usize)| {
        let pixels = width.checked_mul(height).and_then(|p| p.checked_mul(channels));
        let (Some(steady), Some(data)) = (pixels, pixels.and_then(|p| p.checked_mul(axis.bins))) else {
            return Err(bad(&format!(
                "{name}: a film of {width}×{height}×{}×{channels} values",
                axis.bins
            )));
        };
        Ok(Transient {
            width,
            height,
            axis,
            channels,
            data: f32s(&format!("{name}.data"), Some(data))?.0,
            steady: f32s(&format!("{name}.steady"), Some(steady))?.0,
        })
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
                // the rows keep one precision: its blob has the written bits, the other is empty
                let (data32, bits32) = f32s(&format!("chunk{c}.data32"), None)?;
                let (data64, bits64) = f64s(&format!("chunk{c}.data64"))?;
                Some(TileSums {
                    written: if data32.is_empty() { bits64 } else { bits32 },
                    data32,
                    data64,
                    steady: f64s(&format!("chunk{c}.steady"))?.0,
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

/// u64 LE words.
fn le_words(bytes: &[u8]) -> Vec<u64> {
    bytes
        .chunks_exact(8)
        .map(|c| u64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect()
}

/// What the signal thread (`cli::output_set`) runs before the process exits on SIGINT or
/// SIGTERM: writes the render's last consistent state, when a render is checkpointing.
static ON_SIGNAL: Mutex<Option<Box<dyn Fn() + Send>>> = Mutex::new(None);

/// Sets (or with `None` clears) what a signal writes.
pub fn set_signal_writer(f: Option<Box<dyn Fn() + Send>>) {
    *ON_SIGNAL.lock().unwrap_or_else(|e| e.into_inner()) = f;
}

/// Writes the checkpoint of the running render, if any (called on SIGINT/SIGTERM/SIGHUP).
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

    /// Sparse bins with −0, values at the edges of runs and a short last run.
    fn sparse<T: Copy + Default>(n: usize, at: impl Fn(usize) -> Option<T>) -> Vec<T> {
        (0..n).map(|i| at(i).unwrap_or_default()).collect()
    }

    fn pattern(i: usize) -> Option<f64> {
        match i % 1013 {
            0 => Some(-0.0),
            15 | 16 => Some(i as f64 * 0.25),
            500..=540 => Some(-(i as f64)),
            _ if i % 4099 == 7 => Some(f64::MIN_POSITIVE),
            _ => None,
        }
    }

    fn bits32(v: &[f32]) -> Vec<u32> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    fn bits64(v: &[f64]) -> Vec<u64> {
        v.iter().map(|x| x.to_bits()).collect()
    }

    /// Bins stored by runs read back to the bit (−0 included): films of the path tracer and
    /// the boundary, and BDPT's rows in f32 and f64, with their written bits (given, or found
    /// from the values); and the file holds the runs, not the arrays.
    #[test]
    fn bins_stored_by_runs_read_back_to_the_bit() {
        use crate::temporal::TimeAxis;
        let axis = TimeAxis {
            start_opl: 0.0,
            bin_width_opl: 0.1,
            bins: 1000,
        };
        let film = |key: usize| {
            let mut t = Transient::zeros(20, 10, axis, 3);
            t.data = sparse(t.data.len(), |i| pattern(i + key).map(|v| v as f32));
            t.steady = sparse(t.steady.len(), |i| Some(i as f32 - 7.0));
            t
        };
        let n = 40 * 1000 * 3 + 5;
        let rows = |f64s: bool, written: bool| {
            let data64: Vec<f64> = sparse(n, pattern);
            let written = if written {
                crate::film::nonzero_runs(&data64)
            } else {
                Vec::new()
            };
            let (data32, data64) = if f64s {
                (Vec::new(), data64)
            } else {
                (data64.iter().map(|&v| v as f32).collect(), Vec::new())
            };
            Some(TileSums {
                data32,
                data64,
                written,
                steady: vec![1.5; 120],
                tails: [0.25, 0.5],
            })
        };
        let saved = Saved {
            units: 1,
            done: vec![true],
            tallies: vec![None],
            frame: vec![film(0), film(3)],
            chunks: vec![
                rows(false, true),
                None,
                rows(true, true),
                rows(false, false),
                rows(true, false),
            ],
            boundary: Some((vec![film(11)], vec![film(17)], BoundaryStats::default())),
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.checkpoint");
        write(&path, &serde_json::json!({}), &saved).unwrap();
        let (_, back) = read(&path).unwrap();
        let films = |a: &[Transient], b: &[Transient]| {
            assert_eq!(a.len(), b.len());
            for (a, b) in a.iter().zip(b) {
                assert!(bits32(&a.data) == bits32(&b.data), "a film's bins differ");
                assert!(bits32(&a.steady) == bits32(&b.steady), "a film's steady image differs");
            }
        };
        films(&saved.frame, &back.frame);
        let (p, q, _) = saved.boundary.as_ref().unwrap();
        let (bp, bq, _) = back.boundary.as_ref().unwrap();
        films(p, bp);
        films(q, bq);
        assert_eq!(back.chunks.len(), saved.chunks.len());
        for (a, b) in saved.chunks.iter().zip(&back.chunks) {
            let (Some(a), Some(b)) = (a, b) else {
                assert!(a.is_none() && b.is_none());
                continue;
            };
            assert!(bits32(&a.data32) == bits32(&b.data32) && bits64(&a.data64) == bits64(&b.data64));
            assert!(bits64(&a.steady) == bits64(&b.steady) && a.tails == b.tails);
            // the given bits (a run written with +0 stays marked), else those of the values
            let want = if !a.written.is_empty() {
                a.written.clone()
            } else if a.data32.is_empty() {
                crate::film::nonzero_runs(&a.data64)
            } else {
                crate::film::nonzero_runs(&a.data32)
            };
            assert!(b.written == want, "the written bits come back with the rows");
        }
        // some 10 % of the bins' runs hold values: the file is about that share of the arrays
        let arrays: usize = [&saved.frame[..], p, q]
            .iter()
            .flat_map(|f| f.iter())
            .map(|t| 4 * t.data.len())
            .sum::<usize>()
            + saved
                .chunks
                .iter()
                .flatten()
                .map(|c| 4 * c.data32.len() + 8 * c.data64.len())
                .sum::<usize>();
        let size = std::fs::metadata(&path).unwrap().len() as usize;
        assert!(size < arrays * 15 / 100, "{size} bytes for {arrays} bytes of bins");
    }

    /// The file of `header` and `body`, with its checksum.
    fn file(header: &serde_json::Value, body: &[u8]) -> Vec<u8> {
        let text = serde_json::to_vec(header).unwrap();
        let mut b = MAGIC.to_vec();
        b.extend((text.len() as u64).to_le_bytes());
        b.extend(text);
        b.extend(body);
        b.extend(crc32fast::hash(&b).to_le_bytes());
        b
    }

    /// Blobs in the layout of earlier checkpoints (every blob a whole array) still read; blobs
    /// whose written bits do not fit their length, or which are cut short, are refused by name.
    #[test]
    fn whole_arrays_read_and_bad_runs_are_refused() {
        let bytes = |header: serde_json::Value, body: &[u8]| file(&header, body);
        let header = |blobs: serde_json::Value| {
            serde_json::json!({
                "identity": {}, "units": 1, "done": [true], "tallies": [null], "frame": [],
                "chunks": [[0.0, 0.0]], "boundary": null, "blobs": blobs
            })
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.checkpoint");
        // the layout of earlier checkpoints: no "runs"
        let old = header(serde_json::json!([
            {"name": "chunk0.data32", "f64": false, "len": 3},
            {"name": "chunk0.data64", "f64": true, "len": 0},
            {"name": "chunk0.steady", "f64": true, "len": 1},
        ]));
        let mut body: Vec<u8> = [0.0f32, -0.0, 2.5].iter().flat_map(|v| v.to_le_bytes()).collect();
        body.extend(4.0f64.to_le_bytes());
        std::fs::write(&path, bytes(old, &body)).unwrap();
        let (_, back) = read(&path).unwrap();
        let rows = back.chunks[0].as_ref().unwrap();
        assert_eq!(bits32(&rows.data32), bits32(&[0.0, -0.0, 2.5]));
        assert!(
            rows.written.is_empty(),
            "found from the values when the rows are restored"
        );
        // runs: bit 1 marks values 16..32 of 20 (4 of them); a bit past the last run is refused
        let runs = |word: u64, values: usize| {
            let h = header(serde_json::json!([
                {"name": "chunk0.data32", "f64": false, "len": 20, "runs": true},
                {"name": "chunk0.data64", "f64": true, "len": 0},
                {"name": "chunk0.steady", "f64": true, "len": 0},
            ]));
            let mut body = word.to_le_bytes().to_vec();
            body.extend((0..values).flat_map(|i| (i as f32 + 1.0).to_le_bytes()));
            bytes(h, &body)
        };
        std::fs::write(&path, runs(0b10, 4)).unwrap();
        let (_, back) = read(&path).unwrap();
        let rows = back.chunks[0].as_ref().unwrap();
        let mut want = vec![0.0f32; 20];
        want[16..].copy_from_slice(&[1.0, 2.0, 3.0, 4.0]);
        assert_eq!(bits32(&rows.data32), bits32(&want));
        assert_eq!(rows.written, vec![0b10]);
        // a film whose shape overflows is refused before anything is allocated
        let mut huge = header(serde_json::json!([]));
        huge["frame"] =
            serde_json::json!([[1u64 << 40, 1u64 << 40, {"start_opl": 0.0, "bin_width_opl": 0.1, "bins": 1000}, 3]]);
        std::fs::write(&path, bytes(huge, &[])).unwrap();
        let e = read(&path).unwrap_err().to_string();
        assert!(
            e.contains("frame0: a film of 1099511627776×1099511627776×1000×3 values"),
            "{e}"
        );
        for (word, values, says) in [
            (0b110, 20, "its written bits do not fit 20 values"),
            (0b10, 3, "it is cut short"),
            (0b10, 5, "trailing bytes"),
        ] {
            std::fs::write(&path, runs(word, values)).unwrap();
            let e = read(&path).unwrap_err().to_string();
            assert!(e.contains(says) && e.contains("r.checkpoint"), "{e}");
        }
    }

    /// A file far longer than its header allows, or of another kind, is refused from its
    /// first bytes, never read into memory whole (a 20 GB file at the checkpoint's path took
    /// 20.9 GB before the checksum refused it; these 4 TB, sparse, abort a whole read).
    #[test]
    fn a_checkpoint_is_not_read_past_what_its_header_allows() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.checkpoint");
        let saved = Saved {
            units: 1,
            done: vec![true],
            tallies: vec![None],
            chunks: vec![None],
            ..Default::default()
        };
        write(&path, &serde_json::json!({}), &saved).unwrap();
        let good = std::fs::metadata(&path).unwrap().len();
        read(&path).expect("as written");
        let huge = 1u64 << 42;
        std::fs::OpenOptions::new()
            .write(true)
            .open(&path)
            .unwrap()
            .set_len(huge)
            .unwrap();
        let e = read(&path).unwrap_err().to_string();
        assert!(
            e.contains(&format!("{huge} bytes where its header allows at most {good}")),
            "{e}"
        );
        let other = dir.path().join("o.checkpoint");
        std::fs::File::create(&other).unwrap().set_len(huge).unwrap();
        let e = read(&other).unwrap_err().to_string();
        assert!(
            e.contains("o.checkpoint: not a usable dtr checkpoint: it does not start with DTRCKPT2"),
            "{e}"
        );
    }

    /// A damaged or edited checkpoint is refused by name, never resumed: bytes of its bins
    /// flipped (resumed into a film of 1e28 before the checksum), a NaN in a blob or a
    /// negative tally behind a valid checksum (a faulty writer), and a file of the layout
    /// before the checksum.
    #[test]
    fn damaged_or_edited_checkpoints_are_refused() {
        use crate::temporal::TimeAxis;
        let axis = TimeAxis {
            start_opl: 0.0,
            bin_width_opl: 0.1,
            bins: 50,
        };
        let mut t = Transient::zeros(8, 8, axis, 1);
        t.data
            .iter_mut()
            .enumerate()
            .for_each(|(i, v)| *v = (i % 7) as f32 * 1e-7);
        let saved = Saved {
            units: 1,
            done: vec![true],
            tallies: vec![Some((PathCounts::default(), [0.5, 0.25], vec![3.0]))],
            frame: vec![t],
            ..Default::default()
        };
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.checkpoint");
        write(&path, &serde_json::json!({}), &saved).unwrap();
        let good = std::fs::read(&path).unwrap();
        read(&path).expect("as written");
        let refused = |bytes: &[u8], says: &str| {
            std::fs::write(&path, bytes).unwrap();
            let e = read(&path).expect_err(says).to_string();
            assert!(
                e.contains("r.checkpoint: not a usable dtr checkpoint") && e.contains(says),
                "{e}"
            );
        };
        let hlen = u64::from_le_bytes(good[8..16].try_into().unwrap()) as usize;
        let mut flipped = good.clone();
        flipped[16 + hlen + 100..16 + hlen + 200]
            .iter_mut()
            .for_each(|b| *b ^= 0x5a);
        refused(&flipped, "checksum does not match");
        let mut unchecked = good[..good.len() - 4].to_vec();
        unchecked[..8].copy_from_slice(b"DTRCKPT1");
        refused(&unchecked, "earlier dtr, without a checksum");
        // the same with a valid checksum: the values and tallies are checked by field
        let header: serde_json::Value = serde_json::from_slice(&good[16..16 + hlen]).unwrap();
        let mut body = good[16 + hlen..good.len() - 4].to_vec();
        let steady = 4 * 64;
        let at = body.len() - steady - 8; // a value of the bins' runs
        body[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        refused(&file(&header, &body), "blob frame0.data: value");
        let body = &good[16 + hlen..good.len() - 4];
        for (pointer, value, says) in [
            (
                "/tallies/0/1/0",
                -5.0,
                "tallies[0] primal energy before: expected a finite energy >= 0, got -5",
            ),
            ("/tallies/0/2/0", -5.0, "tallies[0] block sum 0 (the primal)"),
        ] {
            let mut h = header.clone();
            *h.pointer_mut(pointer).unwrap() = serde_json::json!(value);
            refused(&file(&h, body), says);
        }
    }
}
