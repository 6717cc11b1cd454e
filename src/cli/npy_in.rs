//! Reading float32 `.npy` films back (shards for `dtr merge`, targets for `dtr optimize`):
//! the size is capped by the shape expected before anything is read, and the shape, type,
//! order and finiteness are checked, each refusal naming the file and what it should hold.

use anyhow::{Context, bail};
use sha2::{Digest, Sha256};
use std::io::Read;
use std::path::Path;

/// The values of the float32, C-order `.npy` at `path`, which must have shape `shape`;
/// `what` says what the file is for in messages (e.g. "the shard's film").
pub fn read_f32(path: &Path, shape: &[usize], what: &str) -> anyhow::Result<Vec<f32>> {
    let file = open_capped(path, shape, what)?;
    parse_f32(std::io::BufReader::new(file), path, shape, what)
}

/// [`read_f32`] of a file whose bytes must be the ones a render wrote, in one pass: every
/// byte is hashed (SHA-256) as it is read, and `check` gets the file's digest as hex before
/// anything the file holds is used. A file that `check` refuses is refused for that, before
/// any complaint about what it holds (a damaged film is damaged, whatever it now parses as).
pub fn read_f32_hashed(
    path: &Path,
    shape: &[usize],
    what: &str,
    check: impl FnOnce(&str) -> anyhow::Result<()>,
) -> anyhow::Result<Vec<f32>> {
    let file = open_capped(path, shape, what)?;
    let mut hashing = Hashing {
        inner: std::io::BufReader::new(file),
        hash: Sha256::new(),
    };
    let parsed = parse_f32(&mut hashing, path, shape, what);
    // the bytes a refusal left unread count too (at most the cap of `open_capped`)
    std::io::copy(&mut hashing, &mut std::io::sink())
        .with_context(|| format!("{}: cannot read {what}", path.display()))?;
    check(&super::digest::hex(&hashing.hash.finalize()))?;
    parsed
}

/// A reader that hashes every byte it passes on.
struct Hashing<R> {
    inner: R,
    hash: Sha256,
}

impl<R: Read> Read for Hashing<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let n = self.inner.read(buf)?;
        self.hash.update(&buf[..n]);
        Ok(n)
    }
}

/// Opens `path`, refusing anything but a regular file no longer than a `.npy` of `shape`
/// (with a header of up to 4 KiB) before a byte is read.
fn open_capped(path: &Path, shape: &[usize], what: &str) -> anyhow::Result<std::fs::File> {
    let Some(expected) = shape.iter().try_fold(4u64, |n, &d| n.checked_mul(d as u64)) else {
        bail!("{}: {what} cannot have shape {shape:?}: too large", path.display());
    };
    let meta = std::fs::metadata(path).with_context(|| format!("{}: cannot read {what}", path.display()))?;
    if !meta.is_file() {
        bail!("{}: {what} should be a float32 .npy of shape {shape:?}", path.display());
    }
    let file = std::fs::File::open(path).with_context(|| format!("{}: cannot read {what}", path.display()))?;
    if meta.len() > expected + 4096 {
        // too long to be the film: say what it holds where its header says (a float64 or an
        // rgb film for a mono scene), reading no more than the header
        if let Ok(npy) = npyz::NpyFile::new(std::io::BufReader::new(file)) {
            check_header(&npy, path, shape, what)?;
        }
        bail!("{}: {what} should be a float32 .npy of shape {shape:?}", path.display());
    }
    Ok(file)
}

/// Refuses a `.npy` whose header says it is not a float32, C-order array of `shape`, saying
/// what it holds.
fn check_header<R: Read>(npy: &npyz::NpyFile<R>, path: &Path, shape: &[usize], what: &str) -> anyhow::Result<()> {
    let got: Vec<usize> = npy.shape().iter().map(|&d| d as usize).collect();
    let f4 = npyz::DType::new_scalar("<f4".parse().expect("<f4 is a type string"));
    if got != shape || npy.dtype() != f4 || npy.order() != npyz::Order::C {
        let order = match npy.order() {
            npyz::Order::C => "C order",
            npyz::Order::Fortran => "Fortran order",
        };
        bail!(
            "{}: {what} holds {} of shape {got:?} in {order}, expected float32 {shape:?} in C \
             order (little-endian '<f4'; numpy: np.ascontiguousarray(a, dtype='<f4'))",
            path.display(),
            dtype_name(&npy.dtype())
        );
    }
    Ok(())
}

/// The values of the `.npy` read from `reader` (the file `path`), checked as [`read_f32`] says.
fn parse_f32(reader: impl Read, path: &Path, shape: &[usize], what: &str) -> anyhow::Result<Vec<f32>> {
    let npy = npyz::NpyFile::new(reader).with_context(|| format!("{}: {what} is not a .npy file", path.display()))?;
    check_header(&npy, path, shape, what)?;
    // the values straight from the file into the film's memory (npyz parsed the header; its
    // element-wise reader and a copy of the whole file cost more than a 1.5 GB shard's read)
    let mut reader = npy.into_inner();
    let mut data = vec![0.0f32; shape.iter().product()];
    reader
        .read_exact(bytemuck::cast_slice_mut(&mut data))
        .with_context(|| format!("{}: {what} ends before its {} values", path.display(), data.len()))?;
    if cfg!(target_endian = "big") {
        data.iter_mut().for_each(|v| *v = f32::from_le_bytes(v.to_ne_bytes()));
    }
    if reader.read(&mut [0u8])? != 0 {
        bail!("{}: {what} holds more than its {} values", path.display(), data.len());
    }
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        let n = data.iter().filter(|v| !v.is_finite()).count();
        bail!(
            "{}: value {i} of {what} is not finite ({}; {n} of {} values are NaN or ±Inf)",
            path.display(),
            data[i],
            data.len()
        );
    }
    Ok(data)
}

/// A .npy element type as numpy writes it (`'<f8'`, `'|u1'`, ...), or "a structured type".
fn dtype_name(dtype: &npyz::DType) -> String {
    match dtype {
        npyz::DType::Plain(t) => format!("'{t}'"),
        _ => "a structured type".to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A film written by `write_npy` reads back bit for bit; a file cut short, one with bytes
    /// after its values, one of another shape and one holding NaN are refused, naming the
    /// file and what it lacks.
    #[test]
    fn reads_its_films_back_and_refuses_damaged_ones() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("film.npy");
        let shape = [2, 3, 5, 2];
        let data: Vec<f32> = (0..60).map(|i| i as f32 * 0.37 - 7.0).collect();
        crate::output::write_npy(&p, &shape, &data).unwrap();
        let back = read_f32(&p, &shape, "the film").unwrap();
        assert_eq!(
            back.iter().map(|v| v.to_bits()).collect::<Vec<_>>(),
            data.iter().map(|v| v.to_bits()).collect::<Vec<_>>()
        );

        let bytes = std::fs::read(&p).unwrap();
        let refusal = |bytes: &[u8], shape: &[usize]| {
            let q = dir.path().join("damaged.npy");
            std::fs::write(&q, bytes).unwrap();
            format!("{:#}", read_f32(&q, shape, "the film").unwrap_err())
        };
        let short = refusal(&bytes[..bytes.len() - 3], &shape);
        assert!(
            short.contains("damaged.npy") && short.contains("ends before its 60 values"),
            "{short}"
        );
        let mut long = bytes.clone();
        long.extend_from_slice(&[0, 0, 0, 0]);
        let long = refusal(&long, &shape);
        assert!(long.contains("holds more than its 60 values"), "{long}");
        let other = refusal(&bytes, &[2, 3, 10, 1]);
        assert!(other.contains("expected float32 [2, 3, 10, 1]"), "{other}");
        // a file too long for the film still says what its header holds (a float64 film, an
        // rgb one where one channel is expected); before, only what it should be
        use npyz::WriterBuilder;
        let mut wide = Vec::new();
        let mut npy = npyz::WriteOptions::<f64>::new()
            .dtype(npyz::DType::new_scalar("<f8".parse().unwrap()))
            .shape(&[2, 3, 5, 2])
            .writer(&mut wide)
            .begin_nd()
            .unwrap();
        npy.extend((0..60).map(|i| i as f64)).unwrap();
        npy.finish().unwrap();
        let wide = refusal(&wide, &shape);
        assert!(wide.contains("holds '<f8' of shape [2, 3, 5, 2]"), "{wide}");
        let rgb = refusal(&bytes, &[2, 3, 5, 1]);
        assert!(rgb.contains("holds '<f4' of shape [2, 3, 5, 2]"), "{rgb}");
        let mut nan = bytes.clone();
        let at = nan.len() - 4 * 60 + 4 * 7;
        nan[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes());
        let nan = refusal(&nan, &shape);
        assert!(nan.contains("value 7 of the film is not finite"), "{nan}");
    }

    /// The one-pass read hashes every byte of the file (the digest `file_sha256` gives, also
    /// for a file with bytes after its values), returns the values when the check passes, and
    /// puts the check's refusal before any complaint about what the file holds.
    #[test]
    fn the_hashed_read_sees_every_byte_and_refuses_on_the_digest_first() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("film.npy");
        let shape = [2, 3, 5, 2];
        let data: Vec<f32> = (0..60).map(|i| i as f32 * 0.5 - 3.0).collect();
        crate::output::write_npy(&p, &shape, &data).unwrap();
        let want = super::super::digest::file_sha256(&p).unwrap();
        let mut seen = String::new();
        let back = read_f32_hashed(&p, &shape, "the film", |got| {
            seen = got.to_string();
            Ok(())
        })
        .unwrap();
        assert_eq!(seen, want);
        assert_eq!(back, data);
        // bytes after the values are hashed too, and the check's refusal comes first
        let mut long = std::fs::read(&p).unwrap();
        long.extend_from_slice(&[7, 7, 7]);
        std::fs::write(&p, &long).unwrap();
        let want_long = super::super::digest::file_sha256(&p).unwrap();
        assert_ne!(want_long, want);
        let err = read_f32_hashed(&p, &shape, "the film", |got| {
            anyhow::ensure!(got == want, "digest {got}");
            Ok(())
        })
        .unwrap_err();
        assert_eq!(format!("{err:#}"), format!("digest {want_long}"));
        let err = read_f32_hashed(&p, &shape, "the film", |_| Ok(())).unwrap_err();
        assert!(format!("{err:#}").contains("holds more than its 60 values"), "{err:#}");
    }
}
