//! The photon noise of a synthetic NLOS capture (`[nlos.noise]`): each bin of each histogram
//! becomes a photon count ~ Poisson(photons_per_unit · I + dark_counts), drawn from the seed
//! and the bin's index alone (the same counts for any thread count or order). The temporal
//! jitter of the sensor is the film's gate (a Gaussian gate is the usual SPAD jitter kernel,
//! `temporal.rs`); noise is applied to a copy, so the noiseless transient is kept.
//!
//! Poisson variates: Knuth's product of uniforms below a mean of 10, Hörmann's transformed
//! rejection with squeeze (PTRS, Hörmann 1993) from 10 on.

use crate::scene::NoiseSpec;
use rayon::prelude::*;

/// SplitMix64 (Steele, Lea and Flood 2014): a small counter-based generator, one stream per bin.
struct SplitMix(u64);

impl SplitMix {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    /// Uniform in [0, 1) with 53 bits.
    fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }
}

/// One Poisson variate of mean `mu` (≥ 0, finite).
fn poisson(mu: f64, rng: &mut SplitMix) -> f64 {
    if mu <= 0.0 {
        return 0.0;
    }
    if mu < 10.0 {
        let limit = (-mu).exp();
        let mut k = 0.0;
        let mut prod = rng.uniform();
        while prod > limit {
            k += 1.0;
            prod *= rng.uniform();
        }
        return k;
    }
    let slam = mu.sqrt();
    let loglam = mu.ln();
    let b = 0.931 + 2.53 * slam;
    let a = -0.059 + 0.02483 * b;
    let inv_alpha = 1.1239 + 1.1328 / (b - 3.4);
    let vr = 0.9277 - 3.6224 / (b - 2.0);
    loop {
        let u = rng.uniform() - 0.5;
        let v = rng.uniform();
        let us = 0.5 - u.abs();
        let k = ((2.0 * a / us + b) * u + mu + 0.43).floor();
        if us >= 0.07 && v <= vr {
            return k;
        }
        if k < 0.0 || (us < 0.013 && v > us) {
            continue;
        }
        if v.ln() + inv_alpha.ln() - (a / (us * us) + b).ln() <= -mu + k * loglam - libm::lgamma(k + 1.0) {
            return k;
        }
    }
}

/// Photon counts for every value of `data` (a transient's bins): Poisson(photons_per_unit ·
/// max(I, 0) + dark_counts). Bin i draws from its own stream of (seed, i).
pub fn photon_counts(data: &[f32], noise: &NoiseSpec) -> Vec<f32> {
    data.par_iter()
        .enumerate()
        .map(|(i, &v)| photon_count(noise, i, v))
        .collect()
}

/// The photon count of bin `i` (its index in the transient's data) of value `v`: element i
/// of [`photon_counts`], made alone, so that a writer can make the counts as it writes them
/// (`output::write_npy_mapped`).
pub fn photon_count(noise: &NoiseSpec, i: usize, v: f32) -> f32 {
    let mut rng = SplitMix(noise.seed ^ (i as u64).wrapping_mul(0xd134_2543_de82_ef95));
    rng.next_u64();
    let mu = noise.photons_per_unit * (v.max(0.0) as f64) + noise.dark_counts;
    poisson(mu, &mut rng) as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Mean and variance of the counts equal the Poisson mean on both sides of the switch
    /// between the two samplers (0.3, 4, 9.9, 10, 37, 900), within 5 standard errors of each
    /// (Var of the sample variance of a Poisson: μ/n + 2μ²/(n − 1)); and P(0) = e^{−μ} for μ = 0.3.
    #[test]
    fn counts_have_poisson_moments() {
        let n = 200_000;
        for &mu in &[0.3, 4.0, 9.9, 10.0, 37.0, 900.0] {
            let spec = NoiseSpec {
                photons_per_unit: mu,
                dark_counts: 0.0,
                seed: 11,
            };
            let c = photon_counts(&vec![1.0f32; n], &spec);
            let nf = n as f64;
            let mean = c.iter().map(|&x| x as f64).sum::<f64>() / nf;
            let var = c.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / (nf - 1.0);
            let se_mean = (mu / nf).sqrt();
            let se_var = (mu / nf + 2.0 * mu * mu / (nf - 1.0)).sqrt();
            assert!((mean - mu).abs() < 5.0 * se_mean, "μ {mu}: mean {mean}");
            assert!((var - mu).abs() < 5.0 * se_var, "μ {mu}: variance {var}");
            assert!(c.iter().all(|&x| x >= 0.0 && x.fract() == 0.0));
            if mu < 1.0 {
                let p0 = c.iter().filter(|&&x| x == 0.0).count() as f64 / nf;
                let e = (-mu).exp();
                assert!((p0 - e).abs() < 5.0 * (e * (1.0 - e) / nf).sqrt(), "P(0) {p0} vs {e}");
            }
        }
    }

    /// Dark counts add their own mean where the transient is zero; the seed fixes the draw.
    #[test]
    fn dark_counts_and_seed() {
        let spec = NoiseSpec {
            photons_per_unit: 100.0,
            dark_counts: 2.5,
            seed: 3,
        };
        let data = vec![0.0f32; 100_000];
        let c = photon_counts(&data, &spec);
        let mean = c.iter().map(|&x| x as f64).sum::<f64>() / c.len() as f64;
        assert!((mean - 2.5).abs() < 5.0 * (2.5f64 / 1e5).sqrt(), "{mean}");
        assert_eq!(c, photon_counts(&data, &spec));
        assert_ne!(c, photon_counts(&data, &NoiseSpec { seed: 4, ..spec }));
    }
}
