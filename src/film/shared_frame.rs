//! The path tracer's full-frame films while its tiles render: finished tiles are stored from
//! many threads at once, without a lock.
//!
//! Tiles cover disjoint pixels and each is stored once, so the stores never write the same
//! value. A lock around every store serialised the workers: at 1 spp on a 256×256 film of
//! 2000 bins, a tile's store (and the page faults of the frame's first touch) costs about as
//! much as its paths, and 2 threads ran 1.3× faster than one.

use std::cell::UnsafeCell;
use std::sync::atomic::{AtomicU8, Ordering};

use super::{TileFilm, Transient};

/// A tile whose store has not begun.
const EMPTY: u8 = 0;
/// A tile whose store is under way.
const STORING: u8 = 1;
/// A tile whose store has ended (or that the films held when the frame was made).
const STORED: u8 = 2;

/// A tile's rectangle: `(x0, y0, w, h)` in pixels.
pub type Rect = (usize, usize, usize, usize);

/// Full-frame films (the primal, then one per derivative) that tiles are stored into
/// concurrently ([`Self::store`]) and whose finished tiles a checkpoint copies while the
/// stores go on ([`Self::snapshot`]).
pub struct SharedFrame {
    films: UnsafeCell<Vec<Transient>>,
    /// Each film's `data` and `steady` buffers, taken once from the owned films: stores
    /// write through these, never through a reference to the films.
    data: Vec<*mut f32>,
    steady: Vec<*mut f32>,
    /// Each film's (height, time axis, channels); all are `width` pixels wide.
    shapes: Vec<(usize, super::TimeAxis, usize)>,
    width: usize,
    rects: Vec<Rect>,
    /// Tile `i`'s store: [`EMPTY`], [`STORING`] or [`STORED`] (its store has ended, or it
    /// came with the films).
    stored: Vec<AtomicU8>,
}

// SAFETY: the raw pointers point into `films`, which the frame owns and never moves or
// resizes until `into_films` consumes it. Stores write only inside their own tile's
// rectangle; `new` checks that the rectangles are disjoint and inside every film, and
// `store` lets each rectangle be written once. So concurrent stores write disjoint memory,
// and `snapshot` reads only rectangles whose store has ended.
unsafe impl Send for SharedFrame {}
unsafe impl Sync for SharedFrame {}

impl SharedFrame {
    /// Takes `films` (all of one size) and the tiles that will be stored into them; the
    /// tiles `held` marks (a resumed checkpoint's) are in the films already and are not
    /// stored again. Panics if a rectangle leaves the films or overlaps another: either
    /// would let two stores write the same memory.
    pub fn new(mut films: Vec<Transient>, rects: Vec<Rect>, held: &[bool]) -> Self {
        let (width, height) = films.first().map_or((0, 0), |f| (f.width, f.height));
        for f in &films {
            assert_eq!((f.width, f.height), (width, height), "the frame's films share a size");
            assert_eq!(f.data.len(), width * height * f.axis.bins * f.channels, "a whole film");
            assert_eq!(f.steady.len(), width * height * f.channels, "a whole steady image");
        }
        let mut covered = vec![false; width * height];
        for &(x0, y0, w, h) in &rects {
            assert!(
                x0 + w <= width && y0 + h <= height,
                "tile {x0},{y0} {w}×{h} leaves the frame"
            );
            for y in y0..y0 + h {
                for c in &mut covered[y * width + x0..y * width + x0 + w] {
                    assert!(!*c, "tile {x0},{y0} {w}×{h} overlaps another");
                    *c = true;
                }
            }
        }
        Self {
            data: films.iter_mut().map(|f| f.data.as_mut_ptr()).collect(),
            steady: films.iter_mut().map(|f| f.steady.as_mut_ptr()).collect(),
            shapes: films.iter().map(|f| (f.height, f.axis, f.channels)).collect(),
            films: UnsafeCell::new(films),
            width,
            stored: (0..rects.len())
                .map(|i| AtomicU8::new(if held.get(i) == Some(&true) { STORED } else { EMPTY }))
                .collect(),
            rects,
        }
    }

    /// Stores `tile`, which must cover rectangle `i`, into the films (which hold zeros
    /// there: [`TileFilm::store_into`]), then runs `then`: whatever `then` records of the
    /// tile, a [`Self::snapshot`] that sees it finds the tile's store ended. Panics if
    /// rectangle `i` was stored before or the tile covers another one.
    pub fn store(&self, i: usize, tile: &TileFilm, then: impl FnOnce()) {
        assert_eq!(
            self.rects[i],
            (tile.x0, tile.y0, tile.w, tile.h),
            "tile {i}'s rectangle"
        );
        let claimed = self.stored[i].compare_exchange(EMPTY, STORING, Ordering::AcqRel, Ordering::Acquire);
        assert!(claimed.is_ok(), "tile {i} is stored once");
        for k in 0..tile.films().min(self.data.len()) {
            for (ty, data, steady) in tile.rows_in(self.width) {
                // SAFETY: the ranges are row `ty` of rectangle `i` in film `k` (`rows_in`),
                // inside the film and written by no other store (see the `Sync` impl).
                let (data, steady) = unsafe {
                    (
                        std::slice::from_raw_parts_mut(self.data[k].add(data.start), data.len()),
                        std::slice::from_raw_parts_mut(self.steady[k].add(steady.start), steady.len()),
                    )
                };
                tile.store_row(k, ty, data, steady);
            }
        }
        self.stored[i].store(STORED, Ordering::Release);
        then();
    }

    /// Calls `finished` for a record and which tiles it holds (by index), and copies those
    /// tiles into fresh films of zeros: the films of a checkpoint. The stores go on while it
    /// copies: a finished tile is never written again, and its store has ended (a tile
    /// called finished whose store has not is refused with a panic; the store's `then`
    /// runs after it ends). Only the finished tiles are read. A copy of whole films would
    /// read every page no tile has reached yet, mapping it to the kernel's shared zero page,
    /// and each later store there would fault again and flush the TLB of every core; it
    /// would also write every page of the copy.
    pub fn snapshot<T>(&self, finished: impl FnOnce() -> (T, Vec<bool>)) -> (T, Vec<Transient>) {
        let (record, done) = finished();
        let mut copy: Vec<Transient> = self
            .shapes
            .iter()
            .map(|&(h, axis, c)| Transient::zeros(self.width, h, axis, c))
            .collect();
        for (i, rect) in self.rects.iter().enumerate().filter(|(i, _)| done[*i]) {
            let state = self.stored[i].load(Ordering::Acquire);
            assert_eq!(state, STORED, "tile {i} is called finished before its store ended");
            for (k, to) in copy.iter_mut().enumerate() {
                for (_, data, steady) in super::rect_rows(*rect, self.width, to.axis.bins, to.channels) {
                    // SAFETY: rows of a tile whose store has ended (STORED, acquired above)
                    // and which no store writes again, inside film `k` (the `Sync` impl).
                    let (from_data, from_steady) = unsafe {
                        (
                            std::slice::from_raw_parts(self.data[k].add(data.start), data.len()),
                            std::slice::from_raw_parts(self.steady[k].add(steady.start), steady.len()),
                        )
                    };
                    // runs of +0 stay untouched pages of the copy
                    super::bins::copy_nonzero(&mut to.data[data], from_data);
                    to.steady[steady].copy_from_slice(from_steady);
                }
            }
        }
        (record, copy)
    }

    /// The films, once no store can run any more.
    pub fn into_films(self) -> Vec<Transient> {
        self.films.into_inner()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::temporal::TimeAxis;

    fn axis(bins: usize) -> TimeAxis {
        TimeAxis {
            start_opl: 0.0,
            bin_width_opl: 0.1,
            bins,
        }
    }

    fn tile(rect: Rect, axis: &TimeAxis, derivs: usize, seed: usize) -> TileFilm {
        let (x0, y0, w, h) = rect;
        let n = w * h * axis.bins * 3 * (1 + derivs);
        // sparse values with a few −0 among them, different in every tile
        let value = |i: usize| match (i + seed * 7) % 23 {
            0 => -0.0,
            1..=3 => (i + seed) as f64 * 0.25 - 40.0,
            _ => 0.0,
        };
        let (data32, data64) = if derivs == 0 {
            ((0..n).map(|i| value(i) as f32).collect(), Vec::new())
        } else {
            (Vec::new(), (0..n).map(value).collect())
        };
        let mut t = TileFilm::new(x0, y0, w, h, axis, 3, derivs);
        t.restore(super::super::TileSums {
            data32,
            data64,
            written: Vec::new(),
            steady: (0..w * h * 3 * (1 + derivs)).map(|i| value(i + 5)).collect(),
            tails: [0.0; 2],
        })
        .expect("sums of the tile's own size");
        t
    }

    fn assert_same_bits(a: &[Transient], b: &[Transient]) {
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>();
        assert_eq!(a.len(), b.len());
        for (a, b) in a.iter().zip(b) {
            assert!(bits(&a.data) == bits(&b.data) && bits(&a.steady) == bits(&b.steady));
        }
    }

    /// Stores from several threads at once give the bytes of storing the same tiles one by
    /// one into the films, whatever the order.
    #[test]
    fn concurrent_stores_give_the_serial_bytes() {
        let axis = axis(40);
        let (w, h, derivs) = (29, 23, 2);
        let mut rects = Vec::new();
        for y0 in (0..h).step_by(8) {
            for x0 in (0..w).step_by(8) {
                rects.push((x0, y0, 8.min(w - x0), 8.min(h - y0)));
            }
        }
        let tiles: Vec<TileFilm> = rects
            .iter()
            .enumerate()
            .map(|(i, &r)| tile(r, &axis, derivs, i))
            .collect();
        let mut serial = Transient::zeros_many(1 + derivs, w, h, axis, 3);
        for t in &tiles {
            t.store_into(&mut serial);
        }
        let frame = SharedFrame::new(Transient::zeros_many(1 + derivs, w, h, axis, 3), rects.clone(), &[]);
        let count = std::sync::atomic::AtomicUsize::new(0);
        let finished = std::sync::Mutex::new(vec![false; tiles.len()]);
        let snapshots = std::sync::Mutex::new(Vec::new());
        std::thread::scope(|s| {
            for part in 0..4 {
                let (frame, tiles, count, finished, snapshots) = (&frame, &tiles, &count, &finished, &snapshots);
                s.spawn(move || {
                    for i in (0..tiles.len()).rev().filter(|i| i % 4 == part) {
                        frame.store(i, &tiles[i], || {
                            count.fetch_add(1, Ordering::Relaxed);
                            finished.lock().unwrap()[i] = true;
                        });
                        // a checkpoint's copy while the other threads store
                        let taken = frame.snapshot(|| {
                            let done = finished.lock().unwrap().clone();
                            (done.clone(), done)
                        });
                        snapshots.lock().unwrap().push(taken);
                    }
                });
            }
        });
        assert_eq!(count.into_inner(), tiles.len());
        // each copy holds what storing its finished tiles into zeros gives
        for (done, copy) in snapshots.into_inner().unwrap() {
            let mut want = Transient::zeros_many(1 + derivs, w, h, axis, 3);
            tiles
                .iter()
                .zip(&done)
                .filter(|(_, d)| **d)
                .for_each(|(t, _)| t.store_into(&mut want));
            assert_same_bits(&copy, &want);
        }
        let got = frame.into_films();
        assert_same_bits(&got, &serial);
        assert!(serial[0].data.iter().any(|&v| v != 0.0) && serial[2].data.iter().any(|&v| v != 0.0));
    }

    /// A snapshot holds the tiles it is told are finished, bit for bit, and zeros elsewhere.
    #[test]
    fn a_snapshot_copies_the_finished_tiles() {
        let axis = axis(24);
        let (w, h, derivs) = (20, 12, 1);
        let rects: Vec<Rect> = vec![(0, 0, 8, 8), (8, 0, 8, 8), (16, 0, 4, 8), (0, 8, 20, 4)];
        let tiles: Vec<TileFilm> = rects
            .iter()
            .enumerate()
            .map(|(i, &r)| tile(r, &axis, derivs, i))
            .collect();
        let frame = SharedFrame::new(Transient::zeros_many(1 + derivs, w, h, axis, 3), rects.clone(), &[]);
        for i in [0, 2, 3] {
            frame.store(i, &tiles[i], || {});
        }
        let (record, copy) = frame.snapshot(|| ("record", vec![true, false, true, false]));
        assert_eq!(record, "record");
        let mut want = Transient::zeros_many(1 + derivs, w, h, axis, 3);
        tiles[0].store_into(&mut want);
        tiles[2].store_into(&mut want);
        assert_same_bits(&copy, &want);
        assert!(want[0].data.iter().any(|&v| v != 0.0) && want[1].steady.iter().any(|&v| v != 0.0));
        // the whole frame still holds tile 3, which the snapshot was told is not finished
        assert_ne!(frame.into_films()[0].data, copy[0].data);
    }

    /// Tiles the films hold already (a resumed checkpoint's) are copied by a snapshot and
    /// never stored again.
    #[test]
    #[should_panic(expected = "is stored once")]
    fn held_tiles_are_not_stored_again() {
        let axis = axis(4);
        let mut films = vec![Transient::zeros(16, 8, axis, 3)];
        films[0].data[5] = 2.5;
        let frame = SharedFrame::new(films, vec![(0, 0, 8, 8), (8, 0, 8, 8)], &[true, false]);
        let (_, copy) = frame.snapshot(|| ((), vec![true, false]));
        assert_eq!(copy[0].data[5], 2.5);
        frame.store(0, &tile((0, 0, 8, 8), &axis, 0, 1), || {});
    }

    /// A tile called finished whose store has not ended is refused, not read.
    #[test]
    #[should_panic(expected = "before its store ended")]
    fn a_snapshot_refuses_a_tile_not_yet_stored() {
        let axis = axis(4);
        let frame = SharedFrame::new(vec![Transient::zeros(16, 8, axis, 3)], vec![(0, 0, 8, 8)], &[]);
        frame.snapshot(|| ((), vec![true]));
    }

    #[test]
    #[should_panic(expected = "overlaps another")]
    fn overlapping_tiles_are_refused() {
        let axis = axis(4);
        SharedFrame::new(
            vec![Transient::zeros(16, 16, axis, 1)],
            vec![(0, 0, 8, 8), (4, 4, 8, 8)],
            &[],
        );
    }

    #[test]
    #[should_panic(expected = "leaves the frame")]
    fn tiles_outside_the_films_are_refused() {
        let axis = axis(4);
        SharedFrame::new(vec![Transient::zeros(16, 16, axis, 1)], vec![(12, 0, 8, 8)], &[]);
    }

    #[test]
    #[should_panic(expected = "is stored once")]
    fn a_tile_is_stored_once() {
        let axis = axis(4);
        let frame = SharedFrame::new(vec![Transient::zeros(16, 16, axis, 3)], vec![(0, 0, 8, 8)], &[]);
        let t = tile((0, 0, 8, 8), &axis, 0, 1);
        frame.store(0, &t, || {});
        frame.store(0, &t, || {});
    }
}
