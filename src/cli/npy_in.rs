//! Reading float32 `.npy` films back (shards for `dtr merge`, targets for `dtr optimize`):
//! the size is capped by the shape expected before anything is read, and the shape, type,
//! order and finiteness are checked, each refusal naming the file and what it should hold.

use anyhow::{Context, bail};
use std::path::Path;

/// The values of the float32, C-order `.npy` at `path`, which must have shape `shape`;
/// `what` says what the file is for in messages (e.g. "the shard's film").
pub fn read_f32(path: &Path, shape: &[usize], what: &str) -> anyhow::Result<Vec<f32>> {
    let expected = 4 * shape.iter().product::<usize>() as u64;
    let meta = std::fs::metadata(path).with_context(|| format!("{}: cannot read {what}", path.display()))?;
    if !meta.is_file() || meta.len() > expected + 4096 {
        bail!("{}: {what} should be a float32 .npy of shape {shape:?}", path.display());
    }
    let bytes = std::fs::read(path).with_context(|| format!("{}: cannot read {what}", path.display()))?;
    let npy =
        npyz::NpyFile::new(&bytes[..]).with_context(|| format!("{}: {what} is not a .npy file", path.display()))?;
    let got: Vec<usize> = npy.shape().iter().map(|&d| d as usize).collect();
    let f4 = npyz::DType::new_scalar("<f4".parse().expect("<f4 is a type string"));
    if got != shape || npy.dtype() != f4 || npy.order() != npyz::Order::C {
        bail!(
            "{}: {what} holds {:?} of shape {got:?}, expected float32 {shape:?} in C order",
            path.display(),
            npy.dtype()
        );
    }
    let data: Vec<f32> = npy
        .into_vec()
        .with_context(|| format!("{}: cannot decode {what}", path.display()))?;
    if let Some(i) = data.iter().position(|v| !v.is_finite()) {
        bail!("{}: value {i} of {what} is not finite", path.display());
    }
    Ok(data)
}
