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

/// The chunks of `chunk` ids, counted from id 0, that hold ids of `ids` (none for no ids):
/// the grid is the whole render's, so a shard's chunks are the whole render's chunks.
pub(super) fn chunks_of(ids: &Range<u64>, chunk: u64) -> Range<u64> {
    match ids.is_empty() {
        true => 0..0,
        false => ids.start / chunk..ids.end.div_ceil(chunk),
    }
}

/// Maps the ids of `ids` by `map`, one chunk of `chunk` ids (`chunks_of`, each cut to `ids`)
/// at a time on `pool`, a wave of a few chunks per thread at a time, and hands every wave's
/// results to `consume` in chunk order. A cancelled render (`crate::cancel`) starts no more
/// waves.
pub(super) fn in_waves<T: Send>(
    pool: &rayon::ThreadPool,
    ids: Range<u64>,
    chunk: u64,
    cancel: &Cancel,
    map: impl Fn(Range<u64>) -> T + Sync,
    mut consume: impl FnMut(Vec<T>),
) {
    let chunks = chunks_of(&ids, chunk);
    let ids_of = |c: u64| (c * chunk).max(ids.start)..((c + 1) * chunk).min(ids.end);
    let per_wave = (CHUNKS_PER_THREAD * pool.current_num_threads() as u64).max(8);
    let mut next = chunks.start;
    while next < chunks.end && !cancel.is_cancelled() {
        let wave = next..(next + per_wave).min(chunks.end);
        next = wave.end;
        consume(pool.install(|| wave.into_par_iter().map(|c| map(ids_of(c))).collect()));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_id_is_consumed_once_in_chunk_order_on_any_pool() {
        for threads in [1, 2, 5] {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let mut seen = Vec::new();
            let mut waves = 0;
            in_waves(
                &pool,
                3..1000,
                10,
                &Cancel::default(),
                |ids| ids,
                |w| {
                    waves += 1;
                    seen.extend(w)
                },
            );
            // chunks on the grid from 0: [3, 10), [10, 20), …, [990, 1000)
            assert_eq!(seen.len(), 100);
            assert_eq!(seen[0], 3..10);
            assert!(seen.windows(2).all(|w| w[0].end == w[1].start && w[1].start % 10 == 0));
            assert_eq!(seen.last(), Some(&(990..1000)));
            let per_wave = (CHUNKS_PER_THREAD * threads as u64).max(8);
            assert_eq!(waves, 100u64.div_ceil(per_wave));
        }
        assert_eq!(chunks_of(&(4000..4000), 2048), 0..0, "no ids, no chunk");
        assert_eq!(chunks_of(&(4000..4097), 2048), 1..3);
    }

    #[test]
    fn a_cancelled_render_starts_no_wave() {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
        let cancel = Cancel::default();
        cancel.cancel();
        in_waves(&pool, 0..100, 10, &cancel, |ids| ids, |_| panic!("a wave ran"));
    }
}
