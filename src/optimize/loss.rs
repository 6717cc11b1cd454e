//! Losses between a rendered transient I and a target T, each with its adjoint ∂L/∂I (the
//! input of `crate::adjoint::render_adjoint`). All are means of squares, so their scale does
//! not grow with the film's size.
//!
//! - `L2`: mean over bins of (I − T)².
//! - `Smooth`: the same after a Gaussian blur along time (σ in bins) of both: a time-aware
//!   loss whose basin is wider than L2's, since a return that arrives a few bins early or
//!   late still overlaps its target.
//! - `Multiscale`: the sum over time scales 1, 2, 4, … bins (sums of 2^l adjacent bins) of
//!   the mean square difference: coarse scales pull from afar, fine ones settle the answer.
//! - `Steady`: mean over pixels and channels of the squared difference of the time sums (what
//!   a conventional camera sees), for comparison: it cannot see when light arrived.

use crate::film::Transient;

/// A loss L(I, T) between a rendered transient and a target of the same shape (see the
/// module documentation for each).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum Loss {
    /// Mean over all values of (I − T)².
    L2,
    /// Mean square difference after a Gaussian blur along time of both.
    Smooth {
        /// Standard deviation of the blur, in bins.
        sigma_bins: f64,
    },
    /// Sum over time scales of the mean square difference of sums of 2^l adjacent bins.
    Multiscale {
        /// Number of time scales (1, 2, 4, … bins).
        levels: u32,
    },
    /// Mean square difference of the time-summed images (blind to arrival time).
    Steady,
}

impl Loss {
    /// Parses `l2`, `smooth`, `multiscale`, `steady` (default widths: σ = 4 bins, 5 levels).
    pub fn parse(s: &str) -> Result<Self, String> {
        match s {
            "l2" => Ok(Loss::L2),
            "smooth" => Ok(Loss::Smooth { sigma_bins: 4.0 }),
            "multiscale" => Ok(Loss::Multiscale { levels: 5 }),
            "steady" => Ok(Loss::Steady),
            other => Err(format!(
                "unknown loss {other:?}: expected l2, smooth, multiscale or steady"
            )),
        }
    }

    /// L(I, T) and ∂L/∂I (same shape as I). `image` and `target` must have the same shape.
    pub fn value_and_adjoint(&self, image: &Transient, target: &Transient) -> (f64, Transient) {
        assert_eq!(image.shape(), target.shape(), "the loss compares films of one shape");
        let [h, w, t, c] = image.shape();
        let mut adj = image.clone();
        adj.data.iter_mut().for_each(|v| *v = 0.0);
        adj.steady.iter_mut().for_each(|v| *v = 0.0);
        // every loss is Σ over pixels and channels of a function of one time series
        let series = |f: &Transient, p: usize, ch: usize| -> Vec<f64> {
            (0..t).map(|b| f.data[(p * t + b) * c + ch] as f64).collect()
        };
        let mut loss = 0.0;
        for p in 0..h * w {
            for ch in 0..c {
                let (i, tg) = (series(image, p, ch), series(target, p, ch));
                let (l, g) = self.series(&i, &tg);
                loss += l;
                for (b, gb) in g.iter().enumerate() {
                    adj.data[(p * t + b) * c + ch] = *gb as f32;
                }
            }
        }
        let n = (h * w * c) as f64;
        let per_bin = if matches!(self, Loss::Steady) { 1.0 } else { t as f64 };
        let scale = 1.0 / (n * per_bin);
        adj.data.iter_mut().for_each(|v| *v = (*v as f64 * scale) as f32);
        (loss * scale, adj)
    }

    /// Σ of squares for one time series and its gradient (before the mean's scale).
    fn series(&self, i: &[f64], t: &[f64]) -> (f64, Vec<f64>) {
        let diff: Vec<f64> = i.iter().zip(t).map(|(a, b)| a - b).collect();
        match *self {
            Loss::L2 => (diff.iter().map(|d| d * d).sum(), diff.iter().map(|d| 2.0 * d).collect()),
            Loss::Smooth { sigma_bins } => {
                // G symmetric (zero padding), so Gᵀ = G: ∂/∂I Σ (G·diff)² = G·(2 G·diff)
                let gd = blur(&diff, sigma_bins);
                let l = gd.iter().map(|d| d * d).sum();
                let g = blur(&gd.iter().map(|d| 2.0 * d).collect::<Vec<_>>(), sigma_bins);
                (l, g)
            }
            Loss::Multiscale { levels } => {
                let mut l = 0.0;
                let mut g = vec![0.0; diff.len()];
                for level in 0..levels {
                    let width = 1usize << level;
                    if width > diff.len() {
                        break;
                    }
                    for (k, block) in diff.chunks(width).enumerate() {
                        let s: f64 = block.iter().sum();
                        l += s * s;
                        g[k * width..k * width + block.len()]
                            .iter_mut()
                            .for_each(|v| *v += 2.0 * s);
                    }
                }
                (l, g)
            }
            Loss::Steady => {
                let s: f64 = diff.iter().sum();
                (s * s, vec![2.0 * s; diff.len()])
            }
        }
    }
}

/// Gaussian blur of `x` with σ = `sigma` samples, truncated at 4σ, zero outside.
fn blur(x: &[f64], sigma: f64) -> Vec<f64> {
    let r = (4.0 * sigma).ceil() as isize;
    let k: Vec<f64> = (-r..=r)
        .map(|j| (-(j * j) as f64 / (2.0 * sigma * sigma)).exp())
        .collect();
    let norm: f64 = k.iter().sum();
    (0..x.len() as isize)
        .map(|i| {
            (-r..=r)
                .filter_map(|j| {
                    let at = i + j;
                    (0..x.len() as isize)
                        .contains(&at)
                        .then(|| x[at as usize] * k[(j + r) as usize])
                })
                .sum::<f64>()
                / norm
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::temporal::TimeAxis;

    fn film(seed: u64) -> Transient {
        let axis = TimeAxis {
            start_opl: 0.0,
            bin_width_opl: 0.1,
            bins: 24,
        };
        let mut f = Transient::zeros(3, 2, axis, 3);
        let mut x = seed.wrapping_mul(0x9e37_79b9_7f4a_7c15) | 1;
        for v in f.data.iter_mut() {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            *v = (x >> 40) as f32 / (1u64 << 24) as f32;
        }
        f
    }

    /// Each loss's adjoint is its gradient: central differences in f64 of L along random
    /// directions agree with ⟨∂L/∂I, direction⟩ (a wrong Gᵀ, block, or scale would not).
    #[test]
    fn adjoints_are_the_gradients_of_the_losses() {
        let (image, target, dir) = (film(1), film(2), film(3));
        for loss in [
            Loss::L2,
            Loss::Smooth { sigma_bins: 2.5 },
            Loss::Multiscale { levels: 4 },
            Loss::Steady,
        ] {
            let (_, adj) = loss.value_and_adjoint(&image, &target);
            // every loss is quadratic in I, so central differences are exact but for rounding:
            // a large step keeps the f32 rounding of I ± h·dir small against h
            let h = 0.05f32;
            let at = |s: f32| {
                let mut i = image.clone();
                i.data.iter_mut().zip(&dir.data).for_each(|(v, d)| *v += s * d);
                loss.value_and_adjoint(&i, &target).0
            };
            let fd = (at(h) - at(-h)) / (2.0 * h as f64);
            let dot: f64 = adj.data.iter().zip(&dir.data).map(|(a, d)| *a as f64 * *d as f64).sum();
            assert!(
                (fd - dot).abs() <= 1e-3 * dot.abs().max(1e-6),
                "{loss:?}: FD {fd} vs adjoint {dot}"
            );
            assert_eq!(
                loss.value_and_adjoint(&target, &target).0,
                0.0,
                "{loss:?} of T against T"
            );
        }
    }
}
