//! Chunks of boundary samples traced a wave at a time, for the primary pass, the secondary
//! pass and its pilot: each wave's chunks are mapped in parallel and handed on in chunk
//! order, so the sums are the same additions in the same order for any thread count, and
//! memory holds one wave's results, never a list as long as the sample count (an abort at
//! 2³² boundary samples per pixel until the forty-second session).

use crate::cancel::Cancel;
use rayon::prelude::*;
use std::ops::Range;

/// Chunks per thread in one wave (at least 8 chunks a wave): enough to keep every thread busy
/// while the slowest chunk of the wave finishes.
const CHUNKS_PER_THREAD: u64 = 4;

/// Maps each chunk of `chunks` by `map` on `pool`, a wave of a few chunks per thread at a time,
/// and hands every wave's results to `consume` in chunk order. A cancelled render
/// (`crate::cancel`) starts no more waves.
pub(super) fn in_waves<T: Send>(
    pool: &rayon::ThreadPool,
    chunks: Range<u64>,
    cancel: &Cancel,
    map: impl Fn(u64) -> T + Sync,
    mut consume: impl FnMut(Vec<T>),
) {
    let per_wave = (CHUNKS_PER_THREAD * pool.current_num_threads() as u64).max(8);
    let mut next = chunks.start;
    while next < chunks.end && !cancel.is_cancelled() {
        let wave = next..(next + per_wave).min(chunks.end);
        next = wave.end;
        consume(pool.install(|| wave.into_par_iter().map(&map).collect()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_chunk_is_consumed_once_in_order_on_any_pool() {
        for threads in [1, 2, 5] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut seen = Vec::new();
            let mut waves = 0;
            in_waves(
                &pool,
                3..100,
                &Cancel::default(),
                |c| c * c,
                |w| {
                    waves += 1;
                    seen.extend(w)
                },
            );
            assert_eq!(seen, (3..100u64).map(|c| c * c).collect::<Vec<_>>());
            let per_wave = (CHUNKS_PER_THREAD * threads as u64).max(8);
            assert_eq!(waves, 97u64.div_ceil(per_wave));
        }
    }

    #[test]
    fn a_cancelled_render_starts_no_wave() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let cancel = Cancel::default();
        cancel.cancel();
        in_waves(&pool, 0..10, &cancel, |c| c, |_: Vec<u64>| panic!("a wave ran"));
    }
}
