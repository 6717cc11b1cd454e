//! NumPy `.npy`: float32, little-endian, C order.

use super::atomic::write_atomic;
use super::{OutputError, check_data};
use npyz::WriterBuilder;
use std::path::Path;

/// Writes `data` with the given `shape` as a float32 (`<f4`), C-order `.npy` file, atomically.
///
/// `shape`'s product must equal `data.len()`; zero dimensions and NaN/±Inf values are refused.
/// An empty `shape` writes a 0-d array holding the one value of `data`.
///
/// ```
/// use difftransient::{Transient, output::{OutputError, write_npy}, temporal::TimeAxis};
///
/// let dir = std::env::temp_dir().join(format!("dtr-doc-npy-{}", std::process::id()));
/// std::fs::create_dir_all(&dir).unwrap();
/// let axis = TimeAxis { start_opl: 0.0, bin_width_opl: 0.1, bins: 3 };
/// let mut t = Transient::zeros(2, 2, axis, 1);
/// t.data[0] = 0.5;
///
/// let path = dir.join("transient.npy");
/// write_npy(&path, &t.shape(), &t.data)?;
/// let bytes = std::fs::read(&path).unwrap();
/// assert_eq!(&bytes[..6], b"\x93NUMPY");
/// // The header is followed by the 12 values, little-endian f32, C order.
/// let body = &bytes[bytes.len() - 4 * t.data.len()..];
/// assert_eq!(&body[..4], &0.5f32.to_le_bytes());
///
/// // NaN is refused and nothing is written.
/// t.data[1] = f32::NAN;
/// let bad = dir.join("bad.npy");
/// let err = write_npy(&bad, &t.shape(), &t.data).unwrap_err();
/// assert!(matches!(err, OutputError::NonFinite { count: 1, .. }));
/// assert!(!bad.exists());
/// std::fs::remove_dir_all(&dir).unwrap();
/// # Ok::<(), OutputError>(())
/// ```
pub fn write_npy(path: &Path, shape: &[usize], data: &[f32]) -> Result<(), OutputError> {
    check_data(path, shape, data)?;
    write_atomic(path, |w| {
        write_header(w, path, shape)?;
        super::write_le_sparse(w, data).map_err(|e| OutputError::io(path, e))
    })
}

/// Values made and written at a time by [`write_npy_mapped`] (16 MiB of f32).
const MAPPED_BLOCK: usize = 1 << 22;

/// [`write_npy`] of `map(i, data[i])` for every index i: the values are made a block at a time
/// (in parallel within the block) and written as they are made, so no second array of
/// `data`'s size is held (a noisy copy of a large NLOS capture, `crate::sensor_noise`).
/// `data` is checked as [`write_npy`] checks it, and so is every value `map` gives.
pub fn write_npy_mapped(
    path: &Path,
    shape: &[usize],
    data: &[f32],
    map: impl Fn(usize, f32) -> f32 + Sync,
) -> Result<(), OutputError> {
    write_mapped_in_blocks(path, shape, data, map, MAPPED_BLOCK)
}

/// [`write_npy_mapped`], making `block_len` values at a time.
fn write_mapped_in_blocks(
    path: &Path,
    shape: &[usize],
    data: &[f32],
    map: impl Fn(usize, f32) -> f32 + Sync,
    block_len: usize,
) -> Result<(), OutputError> {
    use rayon::prelude::*;
    check_data(path, shape, data)?;
    write_atomic(path, |w| {
        write_header(w, path, shape)?;
        let mut block = vec![0.0f32; block_len.min(data.len())];
        for (b, values) in data.chunks(block_len).enumerate() {
            let made = &mut block[..values.len()];
            (made.par_iter_mut().zip(values).enumerate()).for_each(|(j, (out, &v))| *out = map(b * block_len + j, v));
            super::check_finite(path, made.iter().copied())?;
            super::write_le_sparse(w, made).map_err(|e| OutputError::io(path, e))?;
        }
        Ok(())
    })
}

/// The `.npy` header of a float32 (`<f4`), C-order array of `shape`.
fn write_header(w: &mut super::atomic::AtomicWriter<'_>, path: &Path, shape: &[usize]) -> Result<(), OutputError> {
    let shape64: Vec<u64> = shape.iter().map(|&d| d as u64).collect();
    npyz::WriteOptions::new_header_only()
        .dtype(npyz::DType::new_scalar(
            "<f4".parse().expect("<f4 is a valid type string"),
        ))
        .shape(&shape64)
        .writer(&mut *w)
        .write_header_only()
        .map(drop)
        .map_err(|e| OutputError::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::super::test_util::{coded_film, entries};
    use super::*;

    fn read_back(path: &Path) -> (Vec<u64>, Vec<f32>, String) {
        let bytes = std::fs::read(path).unwrap();
        let npy = npyz::NpyFile::new(&bytes[..]).unwrap();
        let shape = npy.shape().to_vec();
        let descr = npy.dtype().descr();
        assert_eq!(npy.order(), npyz::Order::C);
        let data: Vec<f32> = npy.into_vec().unwrap();
        (shape, data, descr)
    }

    #[test]
    fn round_trip() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("film.npy");
        let data = coded_film(3, 4, 5, 3);
        write_npy(&p, &[3, 4, 5, 3], &data).unwrap();
        let (shape, back, descr) = read_back(&p);
        assert_eq!(shape, vec![3, 4, 5, 3]);
        assert_eq!(descr, "'<f4'");
        assert_eq!(back, data);
        // Raw layout: header then little-endian f32, C order.
        let bytes = std::fs::read(&p).unwrap();
        assert_eq!(&bytes[..6], b"\x93NUMPY");
        let tail = &bytes[bytes.len() - 4..];
        assert_eq!(f32::from_le_bytes(tail.try_into().unwrap()), *data.last().unwrap());
        assert_eq!(entries(dir.path()), vec!["film.npy"]);
    }

    /// The file is byte for byte what npyz's own element-wise writer makes of the same values
    /// (header, padding and data), for a 0-d, a 1-d and a 4-d array.
    #[test]
    fn bytes_are_npyz_own() {
        let dir = tempfile::tempdir().unwrap();
        for shape in [vec![], vec![7], vec![3, 4, 5, 3]] {
            let data = coded_film(1, 1, shape.iter().product::<usize>(), 1);
            let p = dir.path().join("ours.npy");
            write_npy(&p, &shape, &data).unwrap();
            let mut want = Vec::new();
            let shape64: Vec<u64> = shape.iter().map(|&d| d as u64).collect();
            let mut npy = npyz::WriteOptions::<f32>::new()
                .dtype(npyz::DType::new_scalar("<f4".parse().unwrap()))
                .shape(&shape64)
                .writer(&mut want)
                .begin_nd()
                .unwrap();
            npy.extend(data.iter().copied()).unwrap();
            npy.finish().unwrap();
            assert_eq!(std::fs::read(&p).unwrap(), want, "shape {shape:?}");
        }
    }

    #[test]
    fn scalar_and_1d() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.npy");
        write_npy(&p, &[], &[2.5]).unwrap();
        let (shape, back, _) = read_back(&p);
        assert!(shape.is_empty());
        assert_eq!(back, vec![2.5]);
        write_npy(&p, &[3], &[1.0, -2.0, 3.0]).unwrap();
        assert_eq!(read_back(&p).1, vec![1.0, -2.0, 3.0]);
    }

    #[test]
    fn refuses_bad_input_without_leaving_files() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.npy");
        let e = write_npy(&p, &[2, 2], &[1.0; 3]).unwrap_err();
        assert!(
            matches!(
                e,
                OutputError::ShapeMismatch {
                    expected: 4,
                    actual: 3,
                    ..
                }
            ),
            "{e}"
        );
        let e = write_npy(&p, &[0, 2], &[]).unwrap_err();
        assert!(matches!(e, OutputError::Empty { .. }), "{e}");
        let e = write_npy(&p, &[2, 2], &[1.0, f32::NAN, 0.0, f32::NAN]).unwrap_err();
        assert!(e.to_string().contains("2 of 4 values are not finite"), "{e}");
        assert!(e.to_string().contains("bad.npy"), "{e}");
        let e = write_npy(&p, &[usize::MAX, 3], &[1.0]).unwrap_err();
        assert!(matches!(e, OutputError::ShapeOverflow { .. }), "{e}");
        assert!(entries(dir.path()).is_empty(), "{:?}", entries(dir.path()));

        let missing = dir.path().join("nope").join("x.npy");
        let e = write_npy(&missing, &[1], &[1.0]).unwrap_err();
        assert!(e.to_string().contains("nope/x.npy"), "{e}");
        assert!(entries(dir.path()).is_empty());
    }

    /// Mapped values written a block at a time (blocks of 7 over 40 values: five whole and a
    /// partial one, and one block for all) are the bytes of `write_npy` of the mapped array;
    /// a map that gives a NaN is refused and leaves no file.
    #[test]
    fn mapped_blocks_give_the_bytes_of_the_mapped_array() {
        let dir = tempfile::tempdir().unwrap();
        let data: Vec<f32> = (0..40)
            .map(|i| if i % 3 == 0 { 0.0 } else { i as f32 * 0.25 - 4.0 })
            .collect();
        let map = |i: usize, v: f32| v * 3.0 + (i % 5) as f32;
        let mapped: Vec<f32> = data.iter().enumerate().map(|(i, &v)| map(i, v)).collect();
        let want = dir.path().join("want.npy");
        write_npy(&want, &[5, 8], &mapped).unwrap();
        for block in [7, 40, 1000] {
            let got = dir.path().join(format!("got{block}.npy"));
            write_mapped_in_blocks(&got, &[5, 8], &data, map, block).unwrap();
            assert_eq!(
                std::fs::read(&got).unwrap(),
                std::fs::read(&want).unwrap(),
                "blocks of {block}"
            );
        }
        let bad = dir.path().join("bad.npy");
        let err = write_mapped_in_blocks(&bad, &[5, 8], &data, |i, v| if i == 33 { f32::NAN } else { v }, 7);
        assert!(matches!(err, Err(OutputError::NonFinite { .. })), "{err:?}");
        assert!(!bad.exists());
        assert_eq!(entries(dir.path()).len(), 4, "{:?}", entries(dir.path()));
    }

    /// numpy itself reads the file (skipped when python3 or numpy is absent).
    #[test]
    fn numpy_reads_it() {
        let have_numpy = std::process::Command::new("python3")
            .args(["-c", "import numpy"])
            .output()
            .map(|o| o.status.success())
            .unwrap_or(false);
        if !have_numpy {
            eprintln!("numpy_reads_it: python3 with numpy not available; sub-check skipped");
            return;
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("np.npy");
        let data = coded_film(2, 3, 4, 3);
        write_npy(&p, &[2, 3, 4, 3], &data).unwrap();
        let script = "import sys, numpy as np\n\
                      a = np.load(sys.argv[1])\n\
                      assert a.dtype == np.float32 and a.dtype.byteorder in '<=', a.dtype\n\
                      assert a.shape == (2, 3, 4, 3), a.shape\n\
                      assert a.flags['C_CONTIGUOUS']\n\
                      assert a[1, 2, 3, 1] == 1000 + 200 + 30 + 1 + 0.25, a[1, 2, 3, 1]\n\
                      assert a[0, 1, 2, 0] == 100 + 20 + 0.25\n";
        let out = std::process::Command::new("python3")
            .arg("-c")
            .arg(script)
            .arg(&p)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "numpy check failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}
