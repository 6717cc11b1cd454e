//! Counter-based random numbers, one stream per path.
//!
//! Sample `k` of path `p` is a function of `(seed, p, k)` alone: it does not depend on which
//! lane or packet carries the path, how many threads run, or in what order tiles finish. So the
//! scalar and 8-wide kernels see the same numbers, renders are reproducible, and shards add up
//! to the whole render. Two sequences: independent numbers (a hash per dimension), or padded
//! Owen-scrambled Sobol points per pixel ([`super::sobol`]), stratified over a pixel's samples.

use super::real::Real;
use super::sobol::{sobol_pair, sobol_triple};

/// Which numbers the paths of a render draw (`[integrator] sampler`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum SampleSequence {
    /// Independent uniform numbers for every path and dimension.
    Independent,
    /// Owen-scrambled Sobol points (the default): the samples of one pixel are stratified in
    /// every pair of dimensions (a (0, 2)-sequence per pair, each pair scrambled and shuffled
    /// on its own).
    #[default]
    Sobol,
}

impl SampleSequence {
    /// The name used in scene files and the JSON.
    pub fn name(self) -> &'static str {
        match self {
            SampleSequence::Independent => "independent",
            SampleSequence::Sobol => "sobol",
        }
    }

    /// The sequence called `name` (`dtr render --sampler`, Python's `Scene.with_sampler`), or
    /// a message naming the ones there are.
    pub fn from_name(name: &str) -> Result<Self, String> {
        [SampleSequence::Independent, SampleSequence::Sobol]
            .into_iter()
            .find(|s| s.name() == name)
            .ok_or_else(|| format!("unknown sampler {name:?}: expected \"independent\" or \"sobol\""))
    }
}

/// Mixes a 64-bit key into a uniform `f32` in `[0, 1)` (24 bits of mantissa).
#[inline(always)]
pub fn hash_to_unit(key: u64) -> f32 {
    (hash_u64(key) >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// Mixes a 64-bit key into a uniform 64-bit number: the SplitMix64 finaliser (Steele et al.
/// 2014), full avalanche on 64 bits.
#[inline(always)]
pub fn hash_u64(key: u64) -> u64 {
    let mut z = key.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// Random numbers for `R::LANES` paths that advance in lock step.
#[derive(Clone, Debug)]
pub struct PathSampler {
    keys: [u64; 8],
    lanes: usize,
    dim: u64,
    /// Sobol mode: each lane's sample index within its pixel (`keys` then identify the pixel),
    /// and the second number of the last pair drawn, for a 1D draw at an odd dimension.
    sobol: Option<SobolState>,
}

#[derive(Clone, Debug)]
struct SobolState {
    index: [u32; 8],
    /// (pair, second coordinates) of the last pair drawn.
    cached: Option<(u64, [f32; 8])>,
}

/// The per-lane key of a stream: the id's low 32 bits (a path, pixel or pair) in the high
/// bits, mixed with the seed, and its high 32 bits through an odd multiplier. Until
/// 2026-11-28 the high bits were dropped: paths 2³² ids apart (a 2048 × 2048 image at 4096
/// spp has 2³⁴ paths) drew the same independent numbers. Ids below 2³² keep their keys.
#[inline(always)]
fn stream_key(seed: u64, id: u64) -> u64 {
    seed.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ (id << 32) ^ (id >> 32).wrapping_mul(0x9FB2_1C65_1E98_DF25)
}

impl PathSampler {
    /// `path_ids[i]` identifies lane `i`'s path globally (pixel and sample index).
    pub fn new(seed: u64, path_ids: &[u64]) -> Self {
        let mut keys = [0u64; 8];
        for (k, &p) in keys.iter_mut().zip(path_ids) {
            // Distinct streams: the path id occupies the high bits, the dimension the low ones.
            *k = stream_key(seed, p);
        }
        Self {
            keys,
            lanes: path_ids.len().min(8),
            dim: 0,
            sobol: None,
        }
    }

    /// Numbers of `sequence` for paths whose ids are `pixel · spp + sample` (as
    /// `integrator::path::PacketLanes::row` numbers them). Sobol points need the pixel and
    /// the sample index apart; with `spp == 0` (ids of another form) the numbers are
    /// independent.
    pub fn with_sequence(sequence: SampleSequence, seed: u64, path_ids: &[u64], spp: u32) -> Self {
        if sequence == SampleSequence::Independent || spp == 0 {
            return Self::new(seed, path_ids);
        }
        let spp = spp as u64;
        let lanes = path_ids.len().min(8);
        let mut pixels = [0u64; 8];
        for (o, &p) in pixels.iter_mut().zip(path_ids) {
            *o = p / spp;
        }
        let mut s = Self::new(seed, &pixels[..lanes]);
        let mut index = [0u32; 8];
        for (o, &p) in index.iter_mut().zip(path_ids) {
            *o = (p % spp) as u32;
        }
        s.sobol = Some(SobolState { index, cached: None });
        s
    }

    /// The next dimension, one uniform number per lane.
    #[inline(always)]
    pub fn next<R: Real>(&mut self) -> R {
        debug_assert!(R::LANES <= self.lanes.max(1) || R::LANES == 8);
        let d = self.dim;
        self.dim += 1;
        if let Some(sb) = &mut self.sobol {
            let pair = d >> 1;
            if d & 1 == 1
                && let Some((p, second)) = sb.cached
                && p == pair
            {
                return R::from_lanes(&second);
            }
            let seeds = std::array::from_fn(|i| {
                let k = stream_key(self.keys[i], pair);
                (k ^ (k >> 32)) as u32
            });
            let (first, second) = sobol_pair(sb.index, seeds);
            sb.cached = Some((pair, second));
            return R::from_lanes(if d & 1 == 0 { &first } else { &second });
        }
        let mut a = [0.0f32; 8];
        for (o, k) in a.iter_mut().zip(self.keys.iter()).take(R::LANES) {
            *o = hash_to_unit(k.wrapping_add(d.wrapping_mul(0x9E37_79B9)));
        }
        R::from_lanes(&a)
    }

    /// Passes over the next dimension without computing it: for a number the caller would
    /// not read. The numbers after it are the ones they would have been.
    #[inline(always)]
    pub fn skip(&mut self) {
        self.dim += 1;
    }

    /// Two numbers; with Sobol points, a pair of dimensions stratified together (a 2D draw
    /// starting at an odd dimension skips one).
    pub fn next2<R: Real>(&mut self) -> (R, R) {
        if self.sobol.is_some() && self.dim & 1 == 1 {
            self.dim += 1;
        }
        let a = self.next();
        (a, self.next())
    }

    /// Whether the numbers are Sobol points (else independent).
    pub fn is_sobol(&self) -> bool {
        self.sobol.is_some()
    }

    /// Three numbers. Independent numbers: the next three dimensions. Sobol points: the first
    /// three Sobol dimensions under a scramble of their own (`sobol::sobol_triple`: the
    /// samples' triples form a (1, m, 3)-net, stratified in 3D, not only pair by pair); they
    /// take four dimensions (from an even one), so the next 2D draw stays aligned.
    pub fn next3<R: Real>(&mut self) -> [R; 3] {
        let Some(sb) = &mut self.sobol else {
            return [self.next(), self.next(), self.next()];
        };
        let d = self.dim + (self.dim & 1);
        self.dim = d + 4;
        let seeds = std::array::from_fn(|i| {
            // the key of pair d/2, whose dimensions the triple takes, so no pair draw of the
            // stream shares it. (Until 2026-11-28 the id carried a bit 1 << 62 meant to set it
            // apart; `stream_key` keeps only the id's low 32 bits, so that bit changed nothing.)
            let k = stream_key(self.keys[i], d >> 1);
            (k ^ (k >> 32)) as u32
        });
        sobol_triple(sb.index, seeds).map(|v| R::from_lanes(&v))
    }

    /// Skips to a fixed dimension, so that a strategy's numbers do not depend on earlier ones.
    pub fn set_dim(&mut self, dim: u64) {
        self.dim = dim;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use wide::f32x8;

    /// Paths 2³² ids apart draw different numbers (the key once kept only the id's low 32
    /// bits), and ids below 2³² keep the keys they had.
    #[test]
    fn ids_far_apart_draw_their_own_numbers() {
        for id in [0u64, 5, (1 << 32) - 1] {
            let old = 7u64.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ id.wrapping_mul(0x1_0000_0000);
            assert_eq!(stream_key(7, id), old, "id {id}");
        }
        let ids: Vec<u64> = (0..8).map(|i| 1000 + i).collect();
        let far: Vec<u64> = ids.iter().map(|i| i + (1 << 32)).collect();
        let (mut a, mut b) = (PathSampler::new(7, &ids), PathSampler::new(7, &far));
        for d in 0..4 {
            let (x, y) = (a.next::<f32x8>().to_array(), b.next::<f32x8>().to_array());
            assert!(x.iter().zip(&y).all(|(p, q)| p != q), "dimension {d}: {x:?} and {y:?}");
        }
    }

    /// A skipped dimension leaves every later number as it was, for both sequences and
    /// whatever draw (1D, 2D, 3D) follows.
    #[test]
    fn a_skipped_dimension_leaves_the_later_numbers_alone() {
        let ids: Vec<u64> = (40..48).collect();
        for sequence in [SampleSequence::Independent, SampleSequence::Sobol] {
            for skip_at in 0..6 {
                let mut read = PathSampler::with_sequence(sequence, 3, &ids, 16);
                let mut skipped = read.clone();
                for d in 0..skip_at {
                    let (a, b) = (read.next::<f32x8>(), skipped.next::<f32x8>());
                    assert_eq!(a.to_array(), b.to_array(), "{sequence:?} dimension {d}");
                }
                let _ = read.next::<f32x8>();
                skipped.skip();
                let a = (
                    read.next::<f32x8>(),
                    read.next2::<f32x8>(),
                    read.next3::<f32x8>(),
                    read.next::<f32x8>(),
                );
                let b = (
                    skipped.next::<f32x8>(),
                    skipped.next2::<f32x8>(),
                    skipped.next3::<f32x8>(),
                    skipped.next::<f32x8>(),
                );
                assert_eq!(a.0.to_array(), b.0.to_array(), "{sequence:?}, skip at {skip_at}");
                assert_eq!(
                    [a.1.0.to_array(), a.1.1.to_array()],
                    [b.1.0.to_array(), b.1.1.to_array()]
                );
                assert_eq!(a.2.map(|v| v.to_array()), b.2.map(|v: f32x8| v.to_array()));
                assert_eq!(a.3.to_array(), b.3.to_array());
            }
        }
    }

    #[test]
    fn lanes_equal_scalar_streams() {
        let ids: Vec<u64> = (100..108).collect();
        let mut s8 = PathSampler::new(7, &ids);
        let v: Vec<f32x8> = (0..5).map(|_| s8.next::<f32x8>()).collect();
        for (i, &id) in ids.iter().enumerate() {
            let mut s1 = PathSampler::new(7, &[id]);
            for (k, vk) in v.iter().enumerate() {
                assert_eq!(s1.next::<f32>(), vk.lane(i), "lane {i} dim {k}");
            }
        }
    }

    #[test]
    fn sobol_lanes_equal_scalar_streams_and_pixels_are_stratified() {
        let spp = 16u32;
        // two pixels (5 and 6), eight samples each, in one packet
        let ids: Vec<u64> = (0..8).map(|i| if i < 4 { 5 * 16 + i } else { 6 * 16 + i }).collect();
        let mut s8 = PathSampler::with_sequence(SampleSequence::Sobol, 7, &ids, spp);
        let first: f32x8 = s8.next();
        let v: Vec<(f32x8, f32x8)> = (0..4).map(|_| s8.next2::<f32x8>()).collect();
        for (i, &id) in ids.iter().enumerate() {
            let mut s1 = PathSampler::with_sequence(SampleSequence::Sobol, 7, &[id], spp);
            assert_eq!(s1.next::<f32>(), first.lane(i));
            for (k, (a, b)) in v.iter().enumerate() {
                assert_eq!(s1.next2::<f32>(), (a.lane(i), b.lane(i)), "lane {i} pair {k}");
            }
        }
        // all 16 samples of one pixel: every 2D draw is a (0, 4, 2)-net (one point per 1/4 × 1/4
        // cell), the 1D draw is one point per 1/16
        let draws: Vec<Vec<f32>> = (0..spp as u64)
            .map(|s| {
                let mut q = PathSampler::with_sequence(SampleSequence::Sobol, 3, &[9 * 16 + s], spp);
                let mut d = vec![q.next::<f32>()];
                for _ in 0..3 {
                    let (a, b) = q.next2::<f32>();
                    d.extend([a, b]);
                }
                d
            })
            .collect();
        let mut cells = vec![0; 16];
        draws.iter().for_each(|d| cells[(d[0] * 16.0) as usize] += 1);
        assert!(cells.iter().all(|&c| c == 1), "1D: {cells:?}");
        for pair in 0..3 {
            let mut cells = vec![0; 16];
            for d in &draws {
                let (a, b) = (d[1 + 2 * pair], d[2 + 2 * pair]);
                cells[(a * 4.0) as usize * 4 + (b * 4.0) as usize] += 1;
            }
            assert!(cells.iter().all(|&c| c == 1), "pair {pair}: {cells:?}");
        }
        // without the sample count the numbers are the independent ones
        let mut a = PathSampler::with_sequence(SampleSequence::Sobol, 7, &[3], 0);
        let mut b = PathSampler::new(7, &[3]);
        assert_eq!(a.next::<f32>(), b.next::<f32>());
    }

    #[test]
    fn uniform_in_unit_interval_with_correct_mean() {
        let mut s = PathSampler::new(1, &[3]);
        let n = 100_000;
        let mut sum = 0.0f64;
        for _ in 0..n {
            let u: f32 = s.next();
            assert!((0.0..1.0).contains(&u));
            sum += u as f64;
        }
        let mean = sum / n as f64;
        // standard error of the mean of U(0,1) is sqrt(1/12/n) ≈ 9.1e-4; allow 5 sigma
        assert!(
            (mean - 0.5).abs() < 5.0 * (1.0f64 / 12.0 / n as f64).sqrt(),
            "mean {mean}"
        );
    }
}
