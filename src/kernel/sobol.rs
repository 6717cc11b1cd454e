//! Owen-scrambled Sobol points, eight lanes at once: the `sobol` sample sequence.
//!
//! Each 2D sample a path asks for is the first two dimensions of the Sobol sequence (a
//! (0, 2)-sequence in base 2), Owen-scrambled with a seed of its own and taken at a shuffled
//! index ("padding", as pbrt-v4's PaddedSobolSampler does): every pair of dimensions of one
//! pixel's samples is stratified in every elementary interval, and different pairs are
//! decorrelated. The scrambling is Burley's hash-based nested uniform scramble (B. Burley,
//! "Practical Hash-based Owen Scrambling", JCGT 9(4), 2020) with the constants of its
//! improved form in the `sobol_burley` crate; the index shuffle is the same scramble applied to
//! the index. Owen scrambling keeps each point uniform on [0, 1)², so estimates stay unbiased,
//! and keeps the net property, so `2^m` samples of a pixel put one point in each elementary
//! interval of area `2^-m`.

use wide::u32x8;

#[inline(always)]
fn reverse_bits(x: u32x8) -> u32x8 {
    let swap = |x: u32x8, s: u32, m: u32| ((x >> s) & u32x8::splat(m)) | ((x & u32x8::splat(m)) << s);
    let x = swap(x, 1, 0x5555_5555);
    let x = swap(x, 2, 0x3333_3333);
    let x = swap(x, 4, 0x0F0F_0F0F);
    let x = swap(x, 8, 0x00FF_00FF);
    (x >> 16u32) | (x << 16u32)
}

/// A hash-based permutation of bit strings in which each bit depends only on the bits below it
/// (Laine–Karras style), so applied to reversed bits it is a nested uniform (Owen) scramble.
#[inline(always)]
fn lk_permute(mut x: u32x8, seed: u32x8) -> u32x8 {
    x ^= x * u32x8::splat(0x3d20_adea);
    x += seed;
    x *= (seed >> 16u32) | u32x8::splat(1);
    x ^= x * u32x8::splat(0x0552_6c56);
    x ^= x * u32x8::splat(0x53a2_2864);
    x
}

#[inline(always)]
fn owen_scramble(x: u32x8, seed: u32x8) -> u32x8 {
    reverse_bits(lk_permute(reverse_bits(x), seed))
}

/// A fast 32-bit integer hash (mixes a seed before scrambling).
#[inline(always)]
fn hash(x: u32x8) -> u32x8 {
    let x = (x ^ (x >> 16u32)) * u32x8::splat(0x21f0_aaad);
    let x = (x ^ (x >> 15u32)) * u32x8::splat(0x735a_2d97);
    x ^ (x >> 15u32)
}

#[inline(always)]
fn to_unit(x: u32x8) -> [f32; 8] {
    // 24 high bits: exactly representable, so every value is < 1
    (x >> 8u32).to_array().map(|v| v as f32 * (1.0 / (1u32 << 24) as f32))
}

/// Sobol dimension 1 with its bits reversed (least significant bit = the first binary digit).
/// Its generator matrix is Pascal's triangle mod 2, so by Lucas' theorem digit r is the XOR of
/// the index bits c with r ⊆ c (bitwise): a superset-XOR transform, five shift-XOR steps.
#[inline(always)]
fn sobol1_reversed(i: u32x8) -> u32x8 {
    let mut y = i;
    for (k, m) in [0x5555_5555u32, 0x3333_3333, 0x0F0F_0F0F, 0x00FF_00FF, 0x0000_FFFF]
        .into_iter()
        .enumerate()
    {
        y ^= (y >> (1u32 << k)) & u32x8::splat(m);
    }
    y
}

/// Point `index` of a pair of dimensions scrambled with `seed`, per lane: two numbers in
/// [0, 1). Different seeds give independent scrambles (and index orders) of the same net.
#[inline]
pub fn sobol_pair(index: [u32; 8], seed: [u32; 8]) -> ([f32; 8], [f32; 8]) {
    let seed = hash(u32x8::from(seed));
    let i = owen_scramble(u32x8::from(index), seed);
    let s0 = hash(seed ^ u32x8::splat(0x9e37_79b9));
    let s1 = hash(seed ^ u32x8::splat(0x7f4a_7c15));
    // Owen scrambling a point is reverse ∘ permute ∘ reverse, and both dimensions are cheapest
    // in reversed form: dimension 0 (van der Corput) is the index itself reversed.
    let d0 = reverse_bits(lk_permute(i, s0));
    let d1 = reverse_bits(lk_permute(sobol1_reversed(i), s1));
    (to_unit(d0), to_unit(d1))
}

/// Generator matrix columns of Sobol dimension 2 (primitive polynomial x² + x + 1, initial
/// direction numbers m₁ = 1, m₂ = 3, as in Joe and Kuo's table), most significant bit first:
/// column `b` is the image of index bit `b`. The recurrence for degree 2 with a₁ = 1:
/// m_k = 2·m_{k−1} ⊕ 4·m_{k−2} ⊕ m_{k−2}.
const DIM2: [u32; 32] = {
    let mut m = [0u64; 33];
    m[1] = 1;
    m[2] = 3;
    let mut k = 3;
    while k <= 32 {
        m[k] = (2 * m[k - 1]) ^ (4 * m[k - 2]) ^ m[k - 2];
        k += 1;
    }
    let mut v = [0u32; 32];
    let mut b = 0;
    while b < 32 {
        // v_k = m_k / 2^k as a 32-bit fraction
        v[b] = (m[b + 1] << (31 - b)) as u32;
        b += 1;
    }
    v
};

/// [`DIM2`] as four tables of 256 entries, one per byte of the index: entry `v` of table `k`
/// is the XOR of the columns of the bits set in `v << 8k`. The generator matrix is linear over
/// GF(2), so the image of an index is the XOR of its four bytes' entries.
const DIM2_BYTES: [[u32; 256]; 4] = {
    let mut t = [[0u32; 256]; 4];
    let mut k = 0;
    while k < 4 {
        let mut v = 1;
        while v < 256 {
            // v's lowest bit's column, XOR the entry of v without that bit
            let low = v & (v - 1);
            t[k][v] = t[k][low] ^ DIM2[8 * k + (v ^ low).trailing_zeros() as usize];
            v += 1;
        }
        k += 1;
    }
    t
};

#[inline(always)]
fn sobol2(i: u32x8) -> u32x8 {
    let idx = i.to_array();
    u32x8::from(idx.map(|i| {
        let b = i.to_le_bytes();
        DIM2_BYTES[0][b[0] as usize]
            ^ DIM2_BYTES[1][b[1] as usize]
            ^ DIM2_BYTES[2][b[2] as usize]
            ^ DIM2_BYTES[3][b[3] as usize]
    }))
}

/// Point `index` of the first three Sobol dimensions scrambled with `seed`, per lane: three
/// numbers in [0, 1) whose first 2^m points (for any m) form a (1, m, 3)-net, so a region of
/// the cube that no pair of coordinates describes (a slab across all three) is still
/// stratified. Each dimension gets its own Owen scramble and the index one shared shuffle,
/// as in [`sobol_pair`].
#[inline]
pub fn sobol_triple(index: [u32; 8], seed: [u32; 8]) -> [[f32; 8]; 3] {
    let seed = hash(u32x8::from(seed) ^ u32x8::splat(0x5bd1_e995));
    let i = owen_scramble(u32x8::from(index), seed);
    let s = [0x9e37_79b9u32, 0x7f4a_7c15, 0x94d0_49bb].map(|k| hash(seed ^ u32x8::splat(k)));
    let d0 = reverse_bits(lk_permute(i, s[0]));
    let d1 = reverse_bits(lk_permute(sobol1_reversed(i), s[1]));
    let d2 = owen_scramble(sobol2(i), s[2]);
    [to_unit(d0), to_unit(d1), to_unit(d2)]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Generator matrix columns of Sobol dimension 1 (primitive polynomial x + 1, all direction
    /// numbers 1), most significant bit first: column `b` is the image of index bit `b`.
    const DIM1: [u32; 32] = {
        let mut v = [0u32; 32];
        v[0] = 1 << 31;
        let mut b = 1;
        while b < 32 {
            v[b] = v[b - 1] ^ (v[b - 1] >> 1);
            b += 1;
        }
        v
    };

    fn pairs(n: u32, seed: u32) -> Vec<(f32, f32)> {
        let mut out = Vec::new();
        for base in (0..n).step_by(8) {
            let idx = std::array::from_fn(|k| base + k as u32);
            let (a, b) = sobol_pair(idx, [seed; 8]);
            out.extend((0..8).map(|k| (a[k], b[k])));
        }
        out.truncate(n as usize);
        out
    }

    #[test]
    fn superset_xor_equals_the_generator_matrix() {
        let mut x = 0x1234_5678u32;
        for _ in 0..2000 {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let mut by_matrix = 0u32;
            for (b, c) in DIM1.iter().enumerate() {
                if x >> b & 1 == 1 {
                    by_matrix ^= c;
                }
            }
            let fast = reverse_bits(sobol1_reversed(u32x8::splat(x))).to_array()[0];
            assert_eq!(fast, by_matrix, "index {x:#x}");
        }
    }

    /// Dimension 2's byte tables give the generator matrix's product column by column, for
    /// indices with any bits set (the top byte included).
    #[test]
    fn byte_tables_equal_the_generator_matrix() {
        let mut x = 0x9abc_def0u32;
        for n in 0..4000 {
            x = x.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            let i = if n < 32 { 1u32 << n } else { x };
            let mut by_matrix = 0u32;
            for (b, c) in DIM2.iter().enumerate() {
                if i >> b & 1 == 1 {
                    by_matrix ^= c;
                }
            }
            assert_eq!(sobol2(u32x8::splat(i)).to_array()[0], by_matrix, "index {i:#x}");
        }
        assert_eq!(sobol2(u32x8::splat(0)).to_array()[0], 0);
    }

    #[test]
    fn unscrambled_dimensions_are_sobol() {
        // the generator matrix of dimension 1 (direction numbers 1/2, 3/4, 5/8, ...), in index
        // (not Gray-code) order: indices 1, 2, 3, 4 give 1/2, 3/4, 1/4, 5/8
        let col = |i: u32| {
            let mut d = 0u32;
            for (b, c) in DIM1.iter().enumerate() {
                if i >> b & 1 == 1 {
                    d ^= c;
                }
            }
            d as f64 / 2f64.powi(32)
        };
        assert_eq!([col(1), col(2), col(3), col(4)], [0.5, 0.75, 0.25, 0.625]);
        let r = reverse_bits(u32x8::from([1, 2, 3, 0x8000_0000, 0, 0, 0, 0])).to_array();
        assert_eq!(&r[..4], &[0x8000_0000, 0x4000_0000, 0xC000_0000, 1]);
    }

    /// (0, m, 2)-net: every elementary interval of area 2^-m holds exactly one of the first
    /// 2^m points, for every shape 2^-j × 2^-(m-j) and several seeds.
    #[test]
    fn first_power_of_two_points_form_a_net() {
        for seed in [0u32, 1, 77, 0xdead_beef] {
            for m in [4u32, 6, 8] {
                let pts = pairs(1 << m, seed);
                for j in 0..=m {
                    let mut seen = vec![0u32; 1 << m];
                    for &(x, y) in &pts {
                        assert!((0.0..1.0).contains(&x) && (0.0..1.0).contains(&y));
                        let cx = (x * (1u32 << j) as f32) as usize;
                        let cy = (y * (1u32 << (m - j)) as f32) as usize;
                        seen[(cx << (m - j)) | cy] += 1;
                    }
                    assert!(seen.iter().all(|&c| c == 1), "seed {seed} m {m} j {j}: {seen:?}");
                }
            }
        }
    }

    /// Over many seeds each point is uniform: the mean of point k over seeds is 1/2 in both
    /// dimensions (within 5 standard errors) and the two dimensions are uncorrelated.
    #[test]
    fn scrambled_points_are_uniform_over_seeds() {
        let seeds = 4096;
        for k in [0u32, 1, 5, 13] {
            let (mut sx, mut sy, mut sxy) = (0.0f64, 0.0f64, 0.0f64);
            for s in 0..seeds {
                let (a, b) = sobol_pair([k; 8], [s; 8]);
                sx += a[0] as f64;
                sy += b[0] as f64;
                sxy += (a[0] as f64 - 0.5) * (b[0] as f64 - 0.5);
            }
            let n = seeds as f64;
            let se = (1.0 / 12.0 / n).sqrt();
            assert!((sx / n - 0.5).abs() < 5.0 * se, "k {k} mean x {}", sx / n);
            assert!((sy / n - 0.5).abs() < 5.0 * se, "k {k} mean y {}", sy / n);
            assert!((sxy / n).abs() < 5.0 / 12.0 / n.sqrt(), "k {k} cov {}", sxy / n);
        }
    }

    fn triples(n: u32, seed: u32) -> Vec<[f32; 3]> {
        let mut out = Vec::new();
        for base in (0..n).step_by(8) {
            let idx = std::array::from_fn(|k| base + k as u32);
            let t = sobol_triple(idx, [seed; 8]);
            out.extend((0..8).map(|k| [t[0][k], t[1][k], t[2][k]]));
        }
        out.truncate(n as usize);
        out
    }

    /// The unscrambled third dimension, in index (not Gray-code) order: direction numbers
    /// v_k = m_k/2^k with m = 1, 3, 3, 9 (the recurrence), so indices 1..8 give v₁, v₂, v₁⊕v₂,
    /// v₃, v₁⊕v₃, v₂⊕v₃, v₁⊕v₂⊕v₃, v₄.
    #[test]
    fn third_dimension_is_sobol() {
        let got: Vec<f64> = (1..=8u32)
            .map(|i| sobol2(u32x8::splat(i)).to_array()[0] as f64 / 2f64.powi(32))
            .collect();
        assert_eq!(got, [0.5, 0.75, 0.25, 0.375, 0.875, 0.625, 0.125, 0.5625]);
    }

    /// (1, m, 3)-net: every elementary box of volume 2^(1−m) holds exactly two of the first
    /// 2^m points, for every shape and several seeds.
    #[test]
    fn first_power_of_two_triples_form_a_net() {
        for seed in [0u32, 1, 77, 0xdead_beef] {
            for m in [4u32, 6, 8] {
                let pts = triples(1 << m, seed);
                let k = m - 1;
                for a in 0..=k {
                    for b in 0..=k - a {
                        let c = k - a - b;
                        let mut seen = vec![0u32; 1 << k];
                        for p in &pts {
                            assert!(p.iter().all(|v| (0.0..1.0).contains(v)));
                            let ia = (p[0] * (1u32 << a) as f32) as usize;
                            let ib = (p[1] * (1u32 << b) as f32) as usize;
                            let ic = (p[2] * (1u32 << c) as f32) as usize;
                            seen[(ia << (b + c)) | (ib << c) | ic] += 1;
                        }
                        assert!(
                            seen.iter().all(|&n| n == 2),
                            "seed {seed} m {m} ({a}, {b}, {c}): {seen:?}"
                        );
                    }
                }
            }
        }
    }

    /// Over many seeds each triple is uniform: means 1/2 and no correlation between any two
    /// coordinates (within 5 standard errors).
    #[test]
    fn scrambled_triples_are_uniform_over_seeds() {
        let seeds = 4096;
        for k in [0u32, 1, 5, 13] {
            let (mut sum, mut cross) = ([0.0f64; 3], [0.0f64; 3]);
            for s in 0..seeds {
                let t = sobol_triple([k; 8], [s; 8]);
                let p = [t[0][0] as f64, t[1][0] as f64, t[2][0] as f64];
                for d in 0..3 {
                    sum[d] += p[d];
                    cross[d] += (p[d] - 0.5) * (p[(d + 1) % 3] - 0.5);
                }
            }
            let n = seeds as f64;
            let se = (1.0 / 12.0 / n).sqrt();
            for d in 0..3 {
                assert!((sum[d] / n - 0.5).abs() < 5.0 * se, "k {k} dim {d} mean {}", sum[d] / n);
                assert!(
                    (cross[d] / n).abs() < 5.0 / 12.0 / n.sqrt(),
                    "k {k} dims {d} cov {}",
                    cross[d] / n
                );
            }
        }
    }

    /// Two seeds give unrelated point sets (padding decorrelates the pairs of one path).
    #[test]
    fn different_seeds_are_decorrelated() {
        let n = 1 << 12;
        let (a, b) = (pairs(n, 3), pairs(n, 4));
        let c: f64 = a
            .iter()
            .zip(&b)
            .map(|(p, q)| (p.0 as f64 - 0.5) * (q.0 as f64 - 0.5))
            .sum::<f64>()
            / n as f64;
        assert!(c.abs() < 5.0 / 12.0 / (n as f64).sqrt(), "cov {c}");
    }
}
