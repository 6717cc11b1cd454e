//! How a BDPT render is cut into units of work that any number of threads can run: a unit is
//! one tile and one block of consecutive samples. Units run in waves of a fixed size; while
//! the next wave traces, the driver adds every unit's tile and its splats onto other pixels
//! (`super::film`) to the full-frame rows, row by row in parallel and unit by unit in order
//! (two waves' films are alive at once).
//! The cut depends on the scene, the film and the sample range only, never on the thread
//! count, so neither do the bytes.
//!
//! A unit keeps its splats onto other pixels until its wave ends, so a block holds as many
//! samples as keep the worst case (every light vertex seen, each splat on the filter's whole
//! footprint) under [`SPLATS_PER_UNIT`] (the samples split evenly over the blocks), and a
//! wave as many units as keep their tile films and worst-case splats under [`WAVE_BYTES`].
//! A unit's film is zeroed and added to the rows once per unit, so blocks are as long as the
//! splats allow: at 8 bounces and a box filter, 56 samples of a 64-pixel tile.

use crate::scene::{PixelFilter, Scene};
use std::ops::Range;

/// Most splats onto other pixels one unit may keep, in the worst case.
pub const SPLATS_PER_UNIT: usize = 32768;

/// Bytes of one kept splat: 48, plus 4 per derivative value (ḟ per channel, ḋ).
pub fn splat_bytes(derivs: usize, channels: usize) -> usize {
    48 + 4 * derivs * (channels + 1)
}

/// Memory one wave's units may take together: their tile films and worst-case splats.
pub const WAVE_BYTES: usize = 256 << 20;

/// Bytes one unit of `scene`'s render takes at most: its `tile`² films (primal and `derivs`
/// derivative blocks, f64 with derivatives and f32 without, one f32 film per strategy when
/// `per_strategy`; each with its steady image) and [`SPLATS_PER_UNIT`] splats.
pub fn unit_bytes(scene: &Scene, tile: usize, derivs: usize, per_strategy: bool) -> usize {
    let f = &scene.film;
    let strategies = if per_strategy {
        super::film::strategy_list(scene.integrator.max_bounces).len()
    } else {
        0
    };
    let acc = if derivs > 0 { 8 } else { 4 };
    let tile_floats = tile * tile * (f.axis.bins * f.channels + f.channels);
    tile_floats * ((1 + derivs) * acc + strategies * 4) + SPLATS_PER_UNIT * splat_bytes(derivs, f.channels)
}

/// Units in a wave of units that take `unit_bytes` each.
pub fn wave_len(unit_bytes: usize) -> usize {
    (WAVE_BYTES / unit_bytes.max(1)).clamp(MIN_WAVE, MAX_WAVE)
}

/// Most and fewest units in a wave (fewer than `MAX_WAVE` only when the units' memory asks
/// it, and never fewer than `MIN_WAVE`, whatever the memory).
pub const MAX_WAVE: usize = 256;
pub const MIN_WAVE: usize = 16;

/// The units of a render's BDPT pass.
#[derive(Clone, Debug)]
pub struct Units {
    /// Tile rectangles (x0, y0, w, h).
    rects: Vec<(usize, usize, usize, usize)>,
    blocks: Vec<Range<u64>>,
    /// Units per wave.
    pub wave: usize,
}

/// Pixels one light-tracing splat may touch: the pixel filter's footprint.
fn footprint(filter: PixelFilter) -> usize {
    let radius = match filter {
        PixelFilter::Box => return 1,
        PixelFilter::Tent { radius } | PixelFilter::Gaussian { radius, .. } => radius,
    };
    let side = (2.0 * radius).ceil() as usize + 1;
    side * side
}

impl Units {
    /// Units of `scene`'s film in `tile`-sized tiles over `samples`, each unit's films and
    /// worst-case splats taking `unit_bytes`.
    pub fn new(scene: &Scene, tile: usize, samples: &Range<u64>, unit_bytes: usize) -> Self {
        let (w, h) = (scene.film.width as usize, scene.film.height as usize);
        let rects: Vec<_> = (0..h.div_ceil(tile))
            .flat_map(|ty| {
                (0..w.div_ceil(tile)).map(move |tx| {
                    let (x0, y0) = (tx * tile, ty * tile);
                    (x0, y0, tile.min(w - x0), tile.min(h - y0))
                })
            })
            .collect();
        let per_sample = tile * tile * (scene.integrator.max_bounces as usize + 1) * footprint(scene.film.filter);
        let longest = (SPLATS_PER_UNIT / per_sample.max(1)).max(1) as u64;
        let n = samples.end.saturating_sub(samples.start);
        let count = n.div_ceil(longest);
        let blocks = (0..count)
            .map(|b| samples.start + b * n / count..samples.start + (b + 1) * n / count)
            .collect();
        Self {
            rects,
            blocks,
            wave: wave_len(unit_bytes),
        }
    }

    pub fn len(&self) -> usize {
        self.rects.len() * self.blocks.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Unit `i`: its tile and its samples. Units go block by block, each block over every
    /// tile, so a wave spreads over the film's rows (which the driver fills in parallel).
    pub fn unit(&self, i: usize) -> ((usize, usize, usize, usize), Range<u64>) {
        let n = self.rects.len();
        (self.rects[i % n], self.blocks[i / n].clone())
    }

    /// The waves, as ranges of unit indices, in order.
    pub fn waves(&self) -> Vec<Range<usize>> {
        let n = self.len();
        (0..n.div_ceil(self.wave))
            .map(|k| k * self.wave..((k + 1) * self.wave).min(n))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator::testutil::{POSED, load};

    /// Every (pixel, sample) of the range lies in exactly one unit, units go block by block,
    /// no unit's worst case keeps more splats than allowed, and the waves cover the units in
    /// order with the size that does not depend on anything but the films' memory.
    #[test]
    fn units_cover_every_pixel_and_sample_once() {
        let scene = load(POSED, &[]);
        let (fw, fh) = (scene.film.width as usize, scene.film.height as usize);
        let per_sample = 8 * 8 * (scene.integrator.max_bounces as usize + 1) * footprint(scene.film.filter);
        for samples in [0..1, 0..4, 3..1000] {
            let units = Units::new(&scene, 8, &samples, 1 << 20);
            let mut seen = vec![0u32; fw * fh * (samples.end as usize)];
            let mut last_block = 0;
            for i in 0..units.len() {
                let ((x0, y0, w, h), block) = units.unit(i);
                assert!(block.start >= last_block, "units go block by block");
                last_block = block.start;
                assert!(
                    block.end - block.start == 1 || (block.end - block.start) as usize * per_sample <= SPLATS_PER_UNIT
                );
                assert!(!block.is_empty());
                for y in y0..y0 + h {
                    for x in x0..x0 + w {
                        for s in block.clone() {
                            seen[(y * fw + x) * samples.end as usize + s as usize] += 1;
                        }
                    }
                }
            }
            for y in 0..fh {
                for x in 0..fw {
                    for s in 0..samples.end as usize {
                        let want = samples.contains(&(s as u64)) as u32;
                        assert_eq!(
                            seen[(y * fw + x) * samples.end as usize + s],
                            want,
                            "({x}, {y}) sample {s}"
                        );
                    }
                }
            }
            let waves = units.waves();
            assert_eq!(waves.first().map(|w| w.start), Some(0));
            assert_eq!(waves.last().map(|w| w.end), Some(units.len()));
            assert!(waves.windows(2).all(|p| p[0].end == p[1].start));
            assert_eq!(units.wave, 256);
        }
        // a huge unit: the wave shrinks to its floor, never to one unit
        assert_eq!(Units::new(&scene, 8, &(0..4), 1 << 30).wave, MIN_WAVE);
        assert_eq!(Units::new(&scene, 8, &(0..4), 4 << 20).wave, 64);
        // the samples split evenly: blocks differ by one sample at most
        let longest = (SPLATS_PER_UNIT / per_sample) as u64;
        for spp in [1, longest, longest + 1, 3 * longest - 1, 1000] {
            let units = Units::new(&scene, 8, &(0..spp), 1 << 20);
            let lens: Vec<u64> = units.blocks.iter().map(|b| b.end - b.start).collect();
            let (lo, hi) = (lens.iter().min().unwrap(), lens.iter().max().unwrap());
            assert!(hi - lo <= 1 && *hi <= longest.max(1), "spp {spp}: blocks {lens:?}");
        }
    }
}
