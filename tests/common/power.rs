//! The statistical power of a derivative test: the smallest uniform relative bias b of the
//! derivative (AD → (1 + b)·AD on every seed, so every aggregate's AD − FD moves by b·AD) that
//! the test's own assertions reject.
//!
//! A judge describes its assertions to a [`Test`] on the per-seed columns it already has: for
//! each judged entry, AD − FD and AD over the seeds, and how the entry's z is formed (the
//! standard error of the mean, widened by the finite difference's own error). [`Test::power`]
//! scales AD by 1 + b and asks, per sign of b, for the smallest |b| at which some assertion
//! fails, in two ways:
//! - `plus` / `minus`: with the scaled derivative's own spread, b·AD_k on every seed k (the
//!   standard error of AD − FD + b·AD): what the test really sees. An entry whose derivative
//!   is not resolved from zero (mean / se of AD below its |z| limit) can never reject a
//!   relative bias, however large: with common random numbers AD − FD is nearly 0 and the
//!   biased difference is b·AD, whose z is AD's own.
//! - `plus_fixed` / `minus_fixed`: the standard errors held at b = 0 (only the means move), the
//!   first-order figure.
//!
//! The detectable bias ([`Power::detectable`]) is the larger of the two signs of the first
//! way: a bias of either sign this large fails the test with these renders.

/// The project's standard: "a test of a derivative must be strong enough that a bias of a few
/// percent fails it (a single pixel at 4 spp hides a z = 55 bias)". Every FD judge asserts that
/// its detectable bias ([`Power::detectable`]) is at most this; a derivative that is truly 0
/// (nothing to scale) and the cases documented as exempt (with their measured power) are the
/// only exceptions.
pub const MAX_DETECTABLE_BIAS: f64 = 0.05;

/// One judged entry: per seed, AD − FD (`d`) and AD (`a`); the entry's z is
/// mean(d) / max(`scale`·√(se² + `extra`²) + `add`, `floor`), se the standard error of the mean
/// of d over the seeds.
#[derive(Clone, Debug)]
pub struct Entry {
    pub d: Vec<f64>,
    pub a: Vec<f64>,
    pub scale: f64,
    pub extra: f64,
    pub add: f64,
    pub floor: f64,
}

impl Entry {
    /// z = mean(d) / √(se² + `extra`²), the usual form.
    pub fn new(d: Vec<f64>, a: Vec<f64>, extra: f64) -> Self {
        Entry {
            d,
            a,
            scale: 1.0,
            extra,
            add: 0.0,
            floor: 0.0,
        }
    }

    /// The entry's z with AD scaled by 1 + b; `fixed`: the standard error of b = 0.
    fn z(&self, b: f64, fixed: bool) -> f64 {
        let n = self.d.len() as f64;
        let col = |b: f64| self.d.iter().zip(&self.a).map(move |(d, a)| d + b * a);
        let m = col(b).sum::<f64>() / n;
        let var = |b: f64| {
            let m = col(b).sum::<f64>() / n;
            col(b).map(|x| (x - m) * (x - m)).sum::<f64>() / (n - 1.0) / n
        };
        let se2 = if fixed { var(0.0) } else { var(b) };
        let sd = (self.scale * (se2 + self.extra * self.extra).sqrt() + self.add).max(self.floor);
        if sd > 0.0 {
            m / sd
        } else if m == 0.0 {
            0.0
        } else {
            f64::INFINITY
        }
    }
}

/// An assertion of a judge.
#[derive(Clone, Debug)]
enum Assertion {
    /// Every |z| ≤ limit.
    Every(Vec<Entry>, f64),
    /// Σ z² ≤ bound.
    SumOfSquares(Vec<Entry>, f64),
    /// |fitted relative bias| ≤ limit standard errors + the reference's own error
    /// ([`RelativeBias::fit`] of AD against the reference, seed × entry, with the reference's
    /// error bound per entry).
    Fit(Vec<Vec<f64>>, Vec<Vec<f64>>, Vec<f64>, f64),
}

impl Assertion {
    fn fails(&self, b: f64, fixed: bool) -> bool {
        match self {
            Assertion::Every(es, limit) => es.iter().any(|e| e.z(b, fixed).abs() > *limit),
            Assertion::SumOfSquares(es, bound) => es.iter().map(|e| e.z(b, fixed).powi(2)).sum::<f64>() > *bound,
            Assertion::Fit(ad, reference, err, limit) => {
                let scaled: Vec<Vec<f64>> = ad.iter().map(|r| r.iter().map(|v| v * (1.0 + b)).collect()).collect();
                !RelativeBias::fit(&scaled, reference, err).within(*limit)
            }
        }
    }
}

/// The assertions of one test (it fails when any one does).
#[derive(Clone, Debug, Default)]
pub struct Test {
    assertions: Vec<Assertion>,
}

impl Test {
    /// Every entry's |z| ≤ `limit` (a family-wise bound such as max |z| ≤ 8, or |z| ≤ 4 per
    /// aggregate).
    pub fn every(&mut self, entries: Vec<Entry>, limit: f64) -> &mut Self {
        self.assertions.push(Assertion::Every(entries, limit));
        self
    }

    /// Σ z² over the entries ≤ `bound`.
    pub fn sum_of_squares(&mut self, entries: Vec<Entry>, bound: f64) -> &mut Self {
        self.assertions.push(Assertion::SumOfSquares(entries, bound));
        self
    }

    /// One statistic (e.g. the grand total): |z| ≤ 1 with z as [`Entry`] forms it.
    pub fn one(&mut self, entry: Entry) -> &mut Self {
        self.every(vec![entry], 1.0)
    }

    /// The fitted relative bias of `ad` against `reference` ([`RelativeBias::fit`]) within
    /// `limit` standard errors and the reference's own error `err` (per entry).
    pub fn fit(&mut self, ad: Vec<Vec<f64>>, reference: Vec<Vec<f64>>, err: Vec<f64>, limit: f64) -> &mut Self {
        self.assertions.push(Assertion::Fit(ad, reference, err, limit));
        self
    }

    /// The assertions of `other` too.
    pub fn and(&mut self, other: Test) -> &mut Self {
        self.assertions.extend(other.assertions);
        self
    }

    fn fails(&self, b: f64, fixed: bool) -> bool {
        self.assertions.iter().any(|a| a.fails(b, fixed))
    }

    /// Per sign, the smallest |b| ≤ 10 that fails the test (∞ if none): the first failing
    /// point of a logarithmic scan from 10⁻⁶, then bisection below it.
    fn smallest(&self, sign: f64, fixed: bool) -> f64 {
        if self.fails(0.0, fixed) {
            return 0.0;
        }
        let grid: Vec<f64> = (0..=140).map(|i| 1e-6 * 10f64.powf(i as f64 / 20.0)).collect();
        let Some(k) = grid.iter().position(|&b| self.fails(sign * b, fixed)) else {
            return f64::INFINITY;
        };
        let (mut lo, mut hi) = (if k == 0 { 0.0 } else { grid[k - 1] }, grid[k]);
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            if self.fails(sign * mid, fixed) {
                hi = mid
            } else {
                lo = mid
            }
        }
        hi
    }

    pub fn power(&self) -> Power {
        Power {
            plus: self.smallest(1.0, false),
            minus: self.smallest(-1.0, false),
            plus_fixed: self.smallest(1.0, true),
            minus_fixed: self.smallest(-1.0, true),
        }
    }
}

/// The relative bias of `ad` against `reference` (seed × entry), fitted over all entries at
/// once: per seed k, T_k = Σ_i w_i (AD_ki − R_ki) / Σ_i w_i m_i with weights w_i = m_i / v_i,
/// m_i the mean over seeds of (AD_i + R_i) / 2 and v_i the per-seed variance of AD_i − R_i
/// plus K·err_i² (K seeds; err_i the reference's own error bound plus 10⁻⁹ of the largest
/// |AD|, so that entries where AD − R is only rounding get no weight): the generalised-least-squares slope of
/// AD − R against the derivative, one number per seed, whose mean over seeds is the fitted
/// relative bias. Where the derivative is concentrated in a few entries, this resolves a
/// scaled derivative far better than Σz² over all entries, whose other entries only add
/// noise; it is the statistic aimed at the bias [`MAX_DETECTABLE_BIAS`] speaks of. The weights
/// come from the same runs, so they correlate with AD − R (by var(AD) − var(R) per entry);
/// that biases the fit by about Σ_i (var(AD_i) − var(R_i)) / (2 K v_i) over Σ_i w_i m_i, at
/// most n / (2K) over that. The reference is best Richardson's extrapolation
/// R = (4 FD(h) − FD(2h)) / 3 (truncation O(h⁴), its noise in the spread over seeds).
pub struct RelativeBias {
    pub mean: f64,
    pub se: f64,
    /// Σ |w_i| err_i / Σ w_i m_i: what the reference's own error can move the fit by.
    pub allowance: f64,
}

impl RelativeBias {
    pub fn fit(ad: &[Vec<f64>], reference: &[Vec<f64>], err: &[f64]) -> Self {
        let seeds = ad.len();
        let n = ad[0].len();
        let col = |m: &[Vec<f64>], i: usize| -> Vec<f64> { m.iter().map(|r| r[i]).collect() };
        let m: Vec<f64> = (0..n)
            .map(|i| 0.5 * (super::mean_se(&col(ad, i)).0 + super::mean_se(&col(reference, i)).0))
            .collect();
        // f32 films resolve ~1e-7 of their largest entry: an entry far below it (a pulse's
        // tail, 1e-14 of the peak) carries no information, however small its spread
        let peak = ad.iter().flatten().fold(0.0f64, |p, v| p.max(v.abs()));
        let err: Vec<f64> = err.iter().map(|e| e + 1e-9 * peak).collect();
        let w: Vec<f64> = (0..n)
            .map(|i| {
                let d: Vec<f64> = (0..seeds).map(|k| ad[k][i] - reference[k][i]).collect();
                let (_, se) = super::mean_se(&d);
                let v = (se * se + err[i] * err[i]) * seeds as f64;
                if v > 0.0 { m[i] / v } else { 0.0 }
            })
            .collect();
        let u: f64 = (0..n).map(|i| w[i] * m[i]).sum();
        let t: Vec<f64> = (0..seeds)
            .map(|k| (0..n).map(|i| w[i] * (ad[k][i] - reference[k][i])).sum::<f64>() / u)
            .collect();
        if std::env::var("FD_DEBUG").is_ok() {
            eprintln!(
                "per-seed fitted relative bias: {:?}",
                t.iter().map(|v| (v * 1000.0).round() / 10.0).collect::<Vec<_>>()
            );
        }
        let (mean, se) = super::mean_se(&t);
        let allowance = (0..n).map(|i| w[i].abs() * err[i]).sum::<f64>() / u;
        RelativeBias { mean, se, allowance }
    }

    /// |mean| ≤ `limit`·se + allowance.
    pub fn within(&self, limit: f64) -> bool {
        self.mean.abs() <= limit * self.se + self.allowance
    }

    /// Prints the fit and asserts it within 4 standard errors and the allowance.
    pub fn assert_unbiased(&self, label: &str) {
        eprintln!(
            "{label}: fitted relative bias {:.3} % ± {:.3} % (z {:.2}, reference's error {:.3} %)",
            100.0 * self.mean,
            100.0 * self.se,
            self.mean / self.se,
            100.0 * self.allowance
        );
        assert!(
            self.within(4.0),
            "{label}: AD and FD disagree: the relative bias fitted over every aggregate is {:.3} % ± {:.3} % \
             (reference's error {:.3} %)",
            100.0 * self.mean,
            100.0 * self.se,
            100.0 * self.allowance
        );
    }
}

/// Richardson's extrapolation (4 FD(h) − FD(2h)) / 3 of two central differences (seed ×
/// entry), the reference of [`RelativeBias::fit`].
pub fn richardson_reference(fd: &[Vec<f64>], fd2: &[Vec<f64>]) -> Vec<Vec<f64>> {
    fd.iter()
        .zip(fd2)
        .map(|(a, b)| a.iter().zip(b).map(|(a, b)| (4.0 * a - b) / 3.0).collect())
        .collect()
}

/// Per sign of the bias, the smallest |b| that some assertion of a test rejects.
#[derive(Clone, Copy, Debug)]
pub struct Power {
    /// AD too large (b > 0), with the scaled derivative's own spread.
    pub plus: f64,
    /// AD too small (b < 0), as |b|.
    pub minus: f64,
    /// The same with the standard errors of b = 0.
    pub plus_fixed: f64,
    pub minus_fixed: f64,
}

impl Power {
    /// The detectable bias: a relative bias of either sign this large fails the test.
    pub fn detectable(&self) -> f64 {
        self.plus.max(self.minus)
    }

    /// Both tests run (either failing fails): per sign the smaller bias.
    pub fn or(self, o: Power) -> Power {
        Power {
            plus: self.plus.min(o.plus),
            minus: self.minus.min(o.minus),
            plus_fixed: self.plus_fixed.min(o.plus_fixed),
            minus_fixed: self.minus_fixed.min(o.minus_fixed),
        }
    }

    /// Prints the power as a `POWER` line.
    pub fn report(&self, label: &str) {
        eprintln!(
            "POWER {label}: detectable bias {:.2} % (+{:.2} % / −{:.2} %; standard errors held: {:.2} %)",
            100.0 * self.detectable(),
            100.0 * self.plus,
            100.0 * self.minus,
            100.0 * self.plus_fixed.max(self.minus_fixed),
        );
    }

    /// Prints the power and asserts that the test rejects a bias of [`MAX_DETECTABLE_BIAS`].
    pub fn assert_enough(&self, label: &str) {
        self.report(label);
        assert!(
            self.detectable() <= MAX_DETECTABLE_BIAS,
            "{label}: the test rejects only a relative bias of the derivative of {:.1} % (+{:.1} % / −{:.1} %), \
             above the {:.0} % the standard asks: strengthen it (seeds, samples, aggregates)",
            100.0 * self.detectable(),
            100.0 * self.plus,
            100.0 * self.minus,
            100.0 * MAX_DETECTABLE_BIAS
        );
    }

    /// A test exempt from the power check, with the reason (a derivative that is truly 0, a
    /// one-sided or infinite-variance case, or one documented as out of the CI budget): its
    /// power is printed, not asserted.
    pub fn exempt(&self, label: &str, reason: &str) {
        self.report(&format!("{label} [exempt: {reason}]"));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With the standard errors held, one entry fails at (limit·sd ∓ m) / |a|; with the scaled
    /// derivative's spread, an entry whose AD is not resolved never fails.
    #[test]
    fn a_single_entry_fails_at_its_limit() {
        let e = Entry::new(vec![0.0, 2.0, 1.0, 1.0], vec![100.0, 100.0, 100.0, 100.0], 0.0);
        // mean 1, se √(2/3 / 4) = 0.408
        let se = (2.0f64 / 3.0 / 4.0).sqrt();
        let p = Test::default().every(vec![e], 4.0).power();
        assert!((p.plus_fixed - (4.0 * se - 1.0) / 100.0).abs() < 1e-9, "{p:?}");
        assert!((p.minus_fixed - (4.0 * se + 1.0) / 100.0).abs() < 1e-9, "{p:?}");
        // AD is the same on every seed: its spread adds nothing
        assert!((p.plus - p.plus_fixed).abs() < 1e-9);
        let noisy = Entry::new(vec![0.0; 4], vec![1.0, -1.0, 1.0, 1.5], 0.0);
        assert!(
            Test::default()
                .every(vec![noisy], 4.0)
                .power()
                .detectable()
                .is_infinite()
        );
    }
}
