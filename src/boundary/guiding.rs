//! Guiding for boundary rays: a piecewise-constant density over the unit cube of the edge
//! sampler's inputs (u0: edge CDF coordinate and position, u1: azimuth, u2: cos θ), fitted to
//! the magnitude of the boundary contribution measured by a short pilot pass (the grid that
//! psdr-cuda's edge sampling re-weights; our own implementation).
//!
//! A cell c of the grid is drawn with probability P_c and a point uniformly inside it, so the
//! density on the cube is P_c · cells. To stay unbiased wherever the pilot saw nothing, P_c
//! mixes the pilot estimate with a uniform floor: P_c = (1 − α) m_c / Σm + α / cells.

/// Cells along (u0, u1, u2).
pub const RESOLUTION: [usize; 3] = [32, 4, 4];
/// Weight of the uniform floor in the mixture: a cell is drawn at least half as often as
/// without guiding, which bounds the weight of paths the pilot missed by 2.
pub const UNIFORM_MIX: f32 = 0.5;

#[derive(Clone, Debug)]
pub struct GuideGrid {
    res: [usize; 3],
    /// Every cell equally likely: `sample` returns `inner` itself (no table search).
    uniform: bool,
    pmf: Vec<f32>,
    cdf: Vec<f32>,
}

impl GuideGrid {
    /// A grid from per-cell sums of |contribution| over a pilot pass (`sums[cell]`).
    pub fn from_pilot(res: [usize; 3], sums: &[f64], mix: f32) -> Self {
        let cells = res.iter().product::<usize>();
        assert_eq!(sums.len(), cells, "one pilot sum per cell");
        let total: f64 = sums.iter().filter(|s| s.is_finite()).sum();
        let mix = if total > 0.0 { mix.clamp(0.0, 1.0) as f64 } else { 1.0 };
        let pmf: Vec<f32> = sums
            .iter()
            .map(|&s| {
                let s = if s.is_finite() { s } else { 0.0 };
                ((1.0 - mix) * s / total.max(1e-300) + mix / cells as f64) as f32
            })
            .collect();
        let mut acc = 0.0f64;
        let mut cdf: Vec<f32> = pmf
            .iter()
            .map(|&p| {
                acc += p as f64;
                acc as f32
            })
            .collect();
        let last = acc as f32;
        cdf.iter_mut().for_each(|c| *c /= last);
        Self {
            res,
            uniform: mix == 1.0,
            pmf: pmf.iter().map(|p| p / last).collect(),
            cdf,
        }
    }

    /// The uniform grid (guiding off).
    pub fn uniform(res: [usize; 3]) -> Self {
        Self::from_pilot(res, &vec![0.0; res.iter().product()], 1.0)
    }

    pub fn cells(&self) -> usize {
        self.pmf.len()
    }

    /// The cell that contains point `u` of the unit cube.
    pub fn cell_of(&self, u: [f32; 3]) -> usize {
        let i = |k: usize| ((u[k] * self.res[k] as f32) as usize).min(self.res[k] - 1);
        (i(0) * self.res[1] + i(1)) * self.res[2] + i(2)
    }

    /// Whether every cell is equally likely (guiding off): [`GuideGrid::sample`] then returns
    /// `inner` itself, with density 1.
    pub fn is_uniform(&self) -> bool {
        self.uniform
    }

    /// Draws a cell with `pick` and a point inside it with `inner`; returns the point and its
    /// density on the unit cube (P_c · cells).
    pub fn sample(&self, pick: f32, inner: [f32; 3]) -> ([f32; 3], f32) {
        if self.uniform {
            return (inner, 1.0);
        }
        let c = self.cdf.partition_point(|&x| x <= pick).min(self.cdf.len() - 1);
        let (i2, rest) = (c % self.res[2], c / self.res[2]);
        let (i1, i0) = (rest % self.res[1], rest / self.res[1]);
        let idx = [i0, i1, i2];
        let u = std::array::from_fn(|k| ((idx[k] as f32 + inner[k]) / self.res[k] as f32).min(1.0 - f32::EPSILON));
        (u, self.pmf[c] * self.cells() as f32)
    }

    /// Density at point `u` (for tests).
    pub fn pdf(&self, u: [f32; 3]) -> f32 {
        self.pmf[self.cell_of(u)] * self.cells() as f32
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kernel::PathSampler;

    /// Samples land in cells with the pmf's frequencies, and the returned density is the one
    /// `pdf` reports; E[g(u)/p(u)] = ∫ g for a test function (unbiasedness of the change of
    /// measure).
    #[test]
    fn guided_samples_follow_the_grid_and_stay_unbiased() {
        let res = [4, 2, 2];
        let sums: Vec<f64> = (0..16).map(|i| if i % 3 == 0 { 5.0 + i as f64 } else { 0.0 }).collect();
        let g = GuideGrid::from_pilot(res, &sums, 0.2);
        let mut rng = PathSampler::new(3, &[9]);
        let n = 100_000;
        let mut hist = [0.0f64; 16];
        let mut est = Vec::with_capacity(n);
        for _ in 0..n {
            let pick = rng.next::<f32>();
            let inner = [rng.next::<f32>(), rng.next::<f32>(), rng.next::<f32>()];
            let (u, p) = g.sample(pick, inner);
            assert!((p - g.pdf(u)).abs() < 1e-5 * p);
            hist[g.cell_of(u)] += 1.0;
            // ∫ over the cube of (1 + u0·u1 + u2²) = 1 + 1/4 + 1/3
            est.push((1.0 + u[0] * u[1] + u[2] * u[2]) as f64 / p as f64);
        }
        for (c, h) in hist.iter().enumerate() {
            let e = g.pmf[c] as f64 * n as f64;
            assert!((h - e).abs() < 5.0 * e.sqrt() + 1.0, "cell {c}: {h} vs {e}");
        }
        let m = est.iter().sum::<f64>() / n as f64;
        let se = (est.iter().map(|v| (v - m).powi(2)).sum::<f64>() / ((n - 1) * n) as f64).sqrt();
        assert!((m - (1.0 + 0.25 + 1.0 / 3.0)).abs() < 4.0 * se, "{m} ± {se}");
    }
}
