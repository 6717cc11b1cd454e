//! Counter-based random numbers, one independent stream per path.
//!
//! Sample `k` of path `p` is a hash of `(seed, p, k)`: it does not depend on which lane or
//! packet carries the path, how many threads run, or in what order tiles finish. So the
//! scalar and 8-wide kernels see the same numbers, and renders are reproducible.

use super::real::Real;

/// Mixes a 64-bit key into a uniform `f32` in `[0, 1)` (24 bits of mantissa).
#[inline(always)]
pub fn hash_to_unit(key: u64) -> f32 {
    // SplitMix64 finaliser (Steele et al. 2014): full avalanche on 64 bits.
    let mut z = key.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 40) as f32 * (1.0 / (1u64 << 24) as f32)
}

/// Random numbers for `R::LANES` paths that advance in lock step.
#[derive(Clone, Debug)]
pub struct PathSampler {
    keys: [u64; 8],
    lanes: usize,
    dim: u64,
}

impl PathSampler {
    /// `path_ids[i]` identifies lane `i`'s path globally (pixel and sample index).
    pub fn new(seed: u64, path_ids: &[u64]) -> Self {
        let mut keys = [0u64; 8];
        for (k, &p) in keys.iter_mut().zip(path_ids) {
            // Distinct streams: the path id occupies the high bits, the dimension the low ones.
            *k = seed.wrapping_mul(0xD1B5_4A32_D192_ED03) ^ p.wrapping_mul(0x1_0000_0000);
        }
        Self {
            keys,
            lanes: path_ids.len().min(8),
            dim: 0,
        }
    }

    /// The next dimension, one uniform number per lane.
    #[inline(always)]
    pub fn next<R: Real>(&mut self) -> R {
        debug_assert!(R::LANES <= self.lanes.max(1) || R::LANES == 8);
        let d = self.dim;
        self.dim += 1;
        let mut a = [0.0f32; 8];
        for (o, k) in a.iter_mut().zip(self.keys.iter()).take(R::LANES) {
            *o = hash_to_unit(k.wrapping_add(d.wrapping_mul(0x9E37_79B9)));
        }
        R::from_lanes(&a)
    }

    pub fn next2<R: Real>(&mut self) -> (R, R) {
        let a = self.next();
        (a, self.next())
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
