//! Numbers written as little-endian bytes in bulk (the `.npy` body, checkpoint blobs).

use std::io::Write;

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
}
