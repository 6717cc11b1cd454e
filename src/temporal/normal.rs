//! The standard normal density φ and CDF Φ in f64, for S_e's Gaussian factors (issue 11).
//!
//! Φ is taken through the upper tail Q(z) = 1 − Φ(z) = φ(z)·m(z) for z = |x|, where m is the
//! Mills ratio, so one `exp` gives both φ and Φ (a bin's mass and its ∂S_e/∂d share it), and
//! the small tail is computed directly: no cancellation in either tail. m is a rational
//! function of z on [0, 4) and z⁻¹ times a rational function of 1/z² beyond, the construction
//! of W. J. Cody, "Rational Chebyshev approximations for the error function", Math. Comp. 23
//! (1969) 631–637 (erfc as exp(−x²)·P(x)/Q(x), then exp(−x²)/x·R(1/x²)), with our own
//! coefficients: `tools/fit_normal_tail.py` fits them (interpolation at Chebyshev points in
//! 120-digit arithmetic) and checks this evaluation order in f64 on a grid of step 5·10⁻⁴.
//!
//! Error (that grid against 120-digit values; `temporal::tests` against such values and
//! against `libm::erfc`): m within 6·10⁻¹⁶ relative; Q within 4·10⁻¹⁵ relative for z ≤ 8.5
//! (past the 8σ cut, [`super::GAUSSIAN_CUTOFF_SIGMAS`]) and within 4·10⁻¹⁶·(1 + z²) wherever
//! Q is a normal f64 (the z² is the rounding of z² inside exp(−z²/2), which any f64 evaluation
//! at z has: the rounding of z itself moves Q as much); Φ near 1 within an ulp of 1. A bin's
//! mass, a difference of two tails, is then within 4·10⁻¹⁵ of the unit pulse mass. This
//! replaced `libm::erfc` (up to two `exp` of its own per CDF, besides φ's), which was most of
//! a Gaussian pulse's binning cost.

/// 1/√(2π).
const FRAC_1_SQRT_2PI: f64 = 0.398_942_280_401_432_7;

/// From here on φ(z) and Q(z) are 0 in f64 (exp(−z²/2) < 2⁻¹⁰⁷⁵ past z ≈ 38.61): `Normal::at`
/// returns them without calling `exp`, whose underflow path is slow (a box gate's tail at the
/// far end of the window lies thousands of σ away).
const UNDERFLOW: f64 = 39.0;

/// Where the Mills ratio switches from P1/Q1 in z to P2/Q2 in 1/z².
const TAIL_START: f64 = 4.0;

// m(z) = P1(z) / Q1(z) on [0, 4) (coefficients of z⁰, z¹, …)
const P1: [f64; 9] = [
    1.2533141373155001,
    1.4100227345543423,
    0.8011110566312625,
    0.28030670882322717,
    0.06425365837675374,
    0.009574291267920287,
    0.0008584072574544482,
    3.5891735193669885e-05,
    5.571822374367902e-12,
];
const Q1: [f64; 9] = [
    1.0,
    1.9229199310848033,
    1.6734622682474498,
    0.8633836569031544,
    0.28983906600100295,
    0.06510934819950702,
    0.009610375476760032,
    0.0008583972851028869,
    3.5892072329420334e-05,
];
// m(z) = P2(s) / (z · Q2(s)), s = 1/z², on [4, ∞)
const P2: [f64; 7] = [
    0.9999999999999999,
    51.535750686476874,
    910.6471539092731,
    6732.792563190107,
    20236.925107517225,
    19750.593807345384,
    2720.796440538873,
];
const Q2: [f64; 7] = [
    1.0,
    52.535750686476206,
    960.182904596391,
    7550.368215473063,
    25589.780924887607,
    32520.752123268623,
    10160.560431787508,
];

/// Σ c_k x^k by Horner's rule with fused multiply-adds (as the fit was checked; one instruction
/// each with the crate's x86-64-v3 target, a correctly rounded library call without FMA).
#[inline(always)]
fn poly<const N: usize>(c: &[f64; N], x: f64) -> f64 {
    let mut r = c[N - 1];
    for k in (0..N - 1).rev() {
        r = r.mul_add(x, c[k]);
    }
    r
}

/// The Mills ratio Q(z)/φ(z) for z ≥ 0 (0 at z = ∞).
#[inline]
fn mills(z: f64) -> f64 {
    if z < TAIL_START {
        poly(&P1, z) / poly(&Q1, z)
    } else {
        let s = 1.0 / (z * z);
        poly(&P2, s) / (z * poly(&Q2, s))
    }
}

/// Standard normal density φ(x).
#[inline]
pub(super) fn pdf(x: f64) -> f64 {
    (-0.5 * x * x).exp() * FRAC_1_SQRT_2PI
}

/// φ and Φ at one point, from one `exp`.
#[derive(Clone, Copy, Debug)]
pub(super) struct Normal {
    pub x: f64,
    /// φ(x)
    pub pdf: f64,
    /// Φ(x)
    pub lower: f64,
    /// Φ(−x) = 1 − Φ(x)
    pub upper: f64,
}

impl Normal {
    #[inline]
    pub fn at(x: f64) -> Self {
        if x.abs() >= UNDERFLOW {
            let lower = if x < 0.0 { 0.0 } else { 1.0 };
            return Self {
                x,
                pdf: 0.0,
                lower,
                upper: 1.0 - lower,
            };
        }
        let pdf = pdf(x);
        // Q(|x|), the smaller of Φ(x) and Φ(−x)
        let tail = pdf * mills(x.abs());
        let (lower, upper) = if x < 0.0 {
            (tail, 1.0 - tail)
        } else {
            (1.0 - tail, tail)
        };
        Self { x, pdf, lower, upper }
    }

    /// Φ(b) − Φ(a) for a = `self.x` ≤ b, from the side of the smaller tail (no cancellation).
    #[inline]
    pub fn mass_to(&self, b: &Normal) -> f64 {
        if self.x > 0.0 {
            self.upper - b.upper
        } else {
            b.lower - self.lower
        }
    }
}

/// The standard normal truncated to [−c, c]: at x, Φ and its tails at x clamped to [−c, c]
/// (`x` is the clamped value), so that Φ(b) − Φ(a) is the truncated density's mass on [a, b],
/// continuous in a and b; and its density, φ(x) inside [−c, c] and 0 outside, the derivative
/// of that mass in either end (the cut is a kink in the mass, not a jump). The two values
/// beyond the cut are taken once: a box gate's outermost edges around a Gaussian pulse lie
/// there for every path, and each cost an `exp` and a rational (issue 11).
#[derive(Clone, Copy, Debug)]
pub(super) struct Truncated {
    c: f64,
    below: Normal,
    above: Normal,
}

impl Truncated {
    pub fn new(c: f64) -> Self {
        let end = |x: f64| Normal {
            pdf: 0.0,
            ..Normal::at(x)
        };
        Self {
            c,
            below: end(-c),
            above: end(c),
        }
    }

    #[inline]
    pub fn at(&self, x: f64) -> Normal {
        if x < -self.c {
            self.below
        } else if x > self.c {
            self.above
        } else {
            Normal::at(x)
        }
    }
}

/// Φ(x).
#[inline]
pub(super) fn cdf(x: f64) -> f64 {
    Normal::at(x).lower
}
