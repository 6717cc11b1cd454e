//! Numbers written as little-endian bytes in bulk (the `.npy` body, checkpoint blobs).

use std::io::{Seek, SeekFrom, Write};

/// Bytes converted per write on a big-endian machine.
const BYTES_PER_WRITE: usize = 1 << 20;

/// Writes `values` as little-endian bytes: on a little-endian machine as they lie in memory,
/// in one write with no copy (writing a 1.5 GB film value by value through a buffered writer
/// took longer than rendering it); elsewhere converted a megabyte at a time.
pub(crate) fn write_le<T: bytemuck::Pod>(w: &mut impl Write, values: &[T]) -> std::io::Result<()> {
    if cfg!(target_endian = "little") {
        return w.write_all(bytemuck::cast_slice(values));
    }
    let size = std::mem::size_of::<T>().max(1);
    let mut bytes = Vec::with_capacity(BYTES_PER_WRITE);
    for chunk in values.chunks((BYTES_PER_WRITE / size).max(1)) {
        bytes.clear();
        for v in chunk {
            let at = bytes.len();
            bytes.extend_from_slice(bytemuck::bytes_of(v));
            bytes[at..].reverse();
        }
        w.write_all(&bytes)?;
    }
    Ok(())
}

/// The granularity of the holes [`write_le_sparse`] leaves: aligned blocks of this many bytes
/// of the file (a page).
const HOLE_BYTES: u64 = 4096;

/// [`write_le`] into a file that may keep holes: every block of [`HOLE_BYTES`] (aligned in the
/// file) whose bytes are all zero (+0 values; −0 is written) is passed over with a seek, so
/// the file system stores, copies and syncs only the blocks that hold data, and a reader
/// sees the same bytes. The last block is always written, so the file has its full length.
/// A transient is mostly zeros at low spp or on long windows: the Cornell box's 256×256×2000
/// RGB film at 1 spp is 1.5 GB, and 236 MB of it are written. Blocks are a page (4 KB): a
/// pixel's 2000 bins span 6 pages, and a few bins of each hold values. The price is a file of
/// some 50 000 extents, which a file system mounted with `discard` (this machine kind's ext4)
/// frees one by one: deleting or overwriting that file took 3.9–4.6 s, against 0.4 s for the
/// dense one. Checkpoints, which are replaced and deleted, store their bins by runs instead
/// (`crate::checkpoint`).
pub(crate) fn write_le_sparse<T: bytemuck::Pod>(w: &mut (impl Write + Seek), values: &[T]) -> std::io::Result<()> {
    if !cfg!(target_endian = "little") {
        return write_le(w, values);
    }
    let bytes: &[u8] = bytemuck::cast_slice(values);
    let start = w.stream_position()?;
    // bytes[written..] are still to go out; a run of zero blocks starts at `zeros`
    let (mut from, mut written, mut zeros) = (0usize, 0usize, None::<usize>);
    while from < bytes.len() {
        // the block ends at the next file offset that is a multiple of HOLE_BYTES
        let to_boundary = (HOLE_BYTES - (start + from as u64) % HOLE_BYTES) as usize;
        let end = (from + to_boundary).min(bytes.len());
        if end < bytes.len() && !crate::film::holds_bits(&bytes[from..end]) {
            zeros.get_or_insert(from);
        } else if let Some(z) = zeros.take() {
            w.write_all(&bytes[written..z])?;
            w.seek(SeekFrom::Current((from - z) as i64))?;
            written = from;
        }
        from = end;
    }
    w.write_all(&bytes[written..])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_what_to_le_bytes_gives() {
        let f: Vec<f32> = (0..1000).map(|i| i as f32 * -0.7 + 3.0).collect();
        let d: Vec<f64> = (0..1000).map(|i| i as f64 * 1e-3 - 0.2).collect();
        let mut got = Vec::new();
        write_le(&mut got, &f).unwrap();
        write_le(&mut got, &d).unwrap();
        let mut want: Vec<u8> = f.iter().flat_map(|v| v.to_le_bytes()).collect();
        want.extend(d.iter().flat_map(|v| v.to_le_bytes()));
        assert_eq!(got, want);
    }

    /// The sparse writer gives the dense writer's bytes, with holes where whole aligned
    /// blocks are zero: leading, inner and trailing zero runs, −0 among them, after a header
    /// of odd length.
    #[test]
    fn sparse_writes_give_the_dense_bytes() {
        use std::io::Read;
        let n = 600_000; // 2.4 MB of f32
        let value = |i: usize| match i {
            0..=40_000 => 0.0,
            40_001 => -0.0,
            100_000..=100_010 => i as f32 * 0.5,
            300_000..=330_000 => -1.25,
            _ => 0.0,
        };
        let cases = [
            ("sparse", (0..n).map(value).collect::<Vec<f32>>()),
            ("all zero", vec![0.0f32; n]),
            ("dense", (0..n).map(|i| i as f32).collect()),
            ("short", vec![0.0f32, -0.0, 3.0]),
            ("empty", Vec::new()),
        ];
        for (label, values) in &cases {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("f.bin");
            let mut file = std::fs::File::create(&path).unwrap();
            {
                let mut w = std::io::BufWriter::new(&mut file);
                w.write_all(b"header!").unwrap();
                write_le_sparse(&mut w, values).unwrap();
                w.flush().unwrap();
            }
            file.sync_all().unwrap();
            let mut got = Vec::new();
            std::fs::File::open(&path).unwrap().read_to_end(&mut got).unwrap();
            let mut want = b"header!".to_vec();
            write_le(&mut want, values).unwrap();
            assert!(
                got == want,
                "{label}: {} bytes read back, {} expected",
                got.len(),
                want.len()
            );
        }
    }

    /// Zero blocks become holes where the file system keeps them: a 64 MB film with 1 % of
    /// its blocks written takes a few MB of disk.
    #[cfg(unix)]
    #[test]
    fn zero_blocks_take_no_disk() {
        use std::os::unix::fs::MetadataExt;
        let dir = tempfile::tempdir().unwrap();
        // does this file system keep holes at all?
        let probe = dir.path().join("probe");
        let f = std::fs::File::create(&probe).unwrap();
        f.set_len(64 << 20).unwrap();
        f.sync_all().unwrap();
        if std::fs::metadata(&probe).unwrap().blocks() * 512 >= 1 << 20 {
            eprintln!("this file system keeps no holes; nothing to check");
            return;
        }
        let mut values = vec![0.0f32; 16 << 20];
        for i in (0..values.len()).step_by(1 << 20) {
            values[i] = 1.0;
        }
        let path = dir.path().join("film.bin");
        let mut file = std::fs::File::create(&path).unwrap();
        {
            let mut w = std::io::BufWriter::new(&mut file);
            write_le_sparse(&mut w, &values).unwrap();
            w.flush().unwrap();
        }
        file.sync_all().unwrap();
        let meta = std::fs::metadata(&path).unwrap();
        assert_eq!(meta.len(), 64 << 20);
        assert!(
            meta.blocks() * 512 <= 4 << 20,
            "{} bytes on disk for 17 written blocks",
            meta.blocks() * 512
        );
    }
}
