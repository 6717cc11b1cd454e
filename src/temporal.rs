//! Time: emitter pulses, sensor gates, and their correlation S_e (supplemental Eq. 24).
//!
//! Time is measured as optical path length (OPL, metres; time = OPL / c). An emitter emits a
//! unit-area pulse p(t − τ) with offset τ; bin l of the film has a gate g_l(t). A path of OPL d
//! leaves at t and arrives at t + d, so its correlated importance for bin l is
//!
//!   S_e(l, d) = ∫ p(t − τ) g_l(t + d) dt = ∫ p(s − u) g_l(s) ds,   u = d + τ.
//!
//! Every pulse/gate pair has a closed form below, and so does ∂S_e/∂d (= ∂S_e/∂u). Since
//! u = d + τ, the derivative with respect to the pulse offset is ∂S_e/∂τ = ∂S_e/∂d.
//! With a delta pulse and box gate S_e jumps where d crosses a bin edge (supplemental
//! Lemma 2.5): its derivative is then a Dirac distribution, which
//! [`Correlation::derivative_is_distribution`] reports.

use normal::{Normal, Truncated, cdf, pdf as phi};
use serde::{Deserialize, Serialize};

mod normal;

/// Speed of light in vacuum, m/s (exact, SI): converts OPL in metres to time.
pub const SPEED_OF_LIGHT_M_PER_S: f64 = 299_792_458.0;

/// Gaussian factors are truncated at this many standard deviations; `eval` is zero outside
/// `range`, so the truncation is consistent everywhere. The truncation leaves S_e continuous in
/// the path's OPL d, so that ∂S_e/∂d is all of its derivative: a Gaussian pulse's density is
/// cut (a bin's S_e is the truncated density's mass on the bin, a kink where an edge crosses
/// the cut), and a Gaussian gate is lowered by its value at the cut (φ(8) ≈ 5·10⁻¹⁵ of its
/// peak). The mass lost is 1.2·10⁻¹⁵. A jump at the cut, however small against the peak,
/// would be all of the derivative in a bin that only the pulse's far tail reaches (a bin's
/// f32 value has its own relative precision): a moving path's d crossing the cut is a Dirac
/// in ∂S_e/∂d that no sampled estimator sees (tests/boundary_primary.rs, the panel's bins
/// 8σ before its first arrivals, had the interior derivative at a third of the finite
/// difference when the cut was a jump).
pub const GAUSSIAN_CUTOFF_SIGMAS: f64 = 8.0;

/// The film's time axis: `bins` bins of `bin_width_opl` starting at `start_opl`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TimeAxis {
    /// OPL of the start of bin 0, metres. f64 end to end (scene file, axis, binning, JSON):
    /// at 4 m an f32 step is 4.8·10⁻⁷ m, coarser than the sub-micrometre bins of
    /// femtosecond pulses.
    pub start_opl: f64,
    /// Width of every bin, metres of OPL (> 0); in time, `bin_width_opl / c`.
    pub bin_width_opl: f64,
    /// Number of bins (≥ 1).
    pub bins: usize,
}

impl TimeAxis {
    /// OPL (metres) of the left edge of bin `l`: `start_opl + l · bin_width_opl`.
    /// `l == bins` gives [`Self::end_opl`].
    pub fn bin_start(&self, l: usize) -> f64 {
        self.start_opl + l as f64 * self.bin_width_opl
    }
    /// OPL (metres) of the centre of bin `l`, half a bin width after [`Self::bin_start`].
    ///
    /// ```
    /// use difftransient::temporal::TimeAxis;
    ///
    /// let axis = TimeAxis { start_opl: 1.0, bin_width_opl: 0.03, bins: 100 };
    /// assert!((axis.bin_centre(0) - 1.015).abs() < 1e-12);
    /// assert!((axis.end_opl() - 4.0).abs() < 1e-12);
    /// // 0.299792458 m of OPL is one nanosecond of flight.
    /// let ns = TimeAxis::time_ns_of_opl(axis.bin_centre(10) - axis.bin_centre(0));
    /// assert!((ns - 0.3 / 0.299_792_458).abs() < 1e-9);
    /// ```
    pub fn bin_centre(&self, l: usize) -> f64 {
        self.bin_start(l) + 0.5 * self.bin_width_opl
    }
    /// OPL (metres) of the right edge of the last bin, `start_opl + bins · bin_width_opl`.
    pub fn end_opl(&self) -> f64 {
        self.bin_start(self.bins)
    }
    /// Converts an OPL in metres to the time light takes to travel it in vacuum, in
    /// nanoseconds (`opl / c · 10⁹`).
    pub fn time_ns_of_opl(opl: f64) -> f64 {
        opl / SPEED_OF_LIGHT_M_PER_S * 1e9
    }
}

/// Emitted pulse shape (unit area), centred on the emitter's offset τ.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Pulse {
    /// A Dirac impulse at τ: S_e is then the gate itself, shifted by the path's OPL.
    Delta,
    /// Normal density centred on τ, truncated at [`GAUSSIAN_CUTOFF_SIGMAS`].
    Gaussian {
        /// Standard deviation, metres of OPL (> 0).
        sigma_opl: f32,
    },
    /// Uniform on [τ − width/2, τ + width/2].
    Box {
        /// Full width, metres of OPL (> 0).
        width_opl: f32,
    },
}

impl Pulse {
    /// The pulse's variance in time of flight (m² of OPL): 0, σ², or a box's width²/12.
    pub fn variance(&self) -> f64 {
        match *self {
            Pulse::Delta => 0.0,
            Pulse::Gaussian { sigma_opl } => (sigma_opl as f64).powi(2),
            Pulse::Box { width_opl } => (width_opl as f64).powi(2) / 12.0,
        }
    }

    /// The pulse's standard deviation (m of OPL).
    pub fn std_dev(&self) -> f64 {
        self.variance().sqrt()
    }
}

/// Sensor gate of each bin.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Gate {
    /// g_l(t) = 1 on [start + l·w, start + (l+1)·w).
    Box,
    /// g_l(t) = w · N(t; bin centre, σ). Σ_l g_l = 1 up to a ripple of 2·exp(−2π²σ²/w²):
    /// 1.4% at σ = w/2, 5·10⁻⁹ at σ = w.
    Gaussian {
        /// Standard deviation σ of the gate, metres of OPL (> 0).
        sigma_opl: f32,
    },
}

/// A time axis, pulse or gate that [`Correlation::new`] rejects.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum TemporalError {
    /// A value is not finite, not positive where it must be, or a count is zero.
    #[error("{field}: expected {expected}, got {got}")]
    Invalid {
        /// The scene field, e.g. `film.bin_width_opl`.
        field: &'static str,
        /// What was expected, e.g. "a finite number > 0".
        expected: &'static str,
        /// The value that was given.
        got: String,
    },
}

/// S_e for one emitter pulse and the film's gate.
#[derive(Clone, Debug)]
pub struct Correlation {
    axis: TimeAxis,
    pulse: Pulse,
    offset: f64,
    gate: Gate,
    /// Half-width of the support of S_e(l, ·) around the bin (beyond the box gate's own edges
    /// for a box gate; around the centre for a Gaussian gate).
    reach: f64,
    /// A Gaussian gate with a delta or Gaussian pulse: S_e is one Gaussian in the bin centres.
    gaussian: Option<GaussianRun>,
    /// The standard normal truncated at [`GAUSSIAN_CUTOFF_SIGMAS`], for the box pulse's and
    /// gate's edges against a Gaussian.
    truncated: Truncated,
}

/// A Gaussian S_e of σ = `s` sampled at bin centres w apart, whose standardised positions z
/// fall by Δ = w/σ per bin: φ(z − Δ) = φ(z)·g with g = exp(Δz − Δ²/2), and g itself falls by
/// the factor q = exp(−Δ²) per bin. So a run of bins needs two `exp` at its start and two
/// products per bin after it ([`Correlation::gaussian_bins`]).
#[derive(Clone, Copy, Debug)]
struct GaussianRun {
    /// q = exp(−Δ²), with Δ = w/σ = `bin.w_inv_s`.
    q: f64,
    /// The bins' values given φ, without a division per bin.
    bin: GaussBin,
}

/// w · N(x; 0, s), lowered by its value at the cut (so that it falls to 0 there, continuously)
/// and 0 beyond, and its derivative in x, for one bin width w and σ = s: the reciprocals and
/// the level at the cut taken once, so a bin costs products only (a division per bin was a
/// quarter of a Gaussian film add's time in `perf`).
#[derive(Clone, Copy, Debug)]
struct GaussBin {
    inv_s: f64,
    /// w / s: the recurrence's step Δ ([`GaussianRun`]) too.
    w_inv_s: f64,
    /// w · φ(cut) / s.
    floor: f64,
    /// The cut in x (cut · s): bins whose centre is farther from u get 0.
    reach: f64,
}

impl GaussBin {
    fn new(w: f64, s: f64) -> Self {
        let inv_s = 1.0 / s;
        GaussBin {
            inv_s,
            w_inv_s: w / s,
            floor: w * inv_s * phi(GAUSSIAN_CUTOFF_SIGMAS),
            reach: GAUSSIAN_CUTOFF_SIGMAS * s,
        }
    }

    /// (value, derivative in x) at x, given φ(x/s) (`phi_z`, which a run of bins carries by
    /// recurrence).
    #[inline]
    fn at(&self, x: f64, phi_z: f64) -> (f64, f64) {
        if x.abs() > self.reach {
            return (0.0, 0.0);
        }
        let v = self.w_inv_s * phi_z;
        (v - self.floor, -v * x * self.inv_s * self.inv_s)
    }
}

/// The most bins of a Gaussian gate's tail that [`Correlation::tails`] evaluates one by one.
/// A longer tail (a gate wide against the bins: more than 16 bins per σ) is summed in at most
/// this many blocks of consecutive bins, each counted as the value at its middle times its
/// size. The blocks are then at most σ/16 wide, where S_e is smooth, so the sum is within
/// about 10⁻⁴ of the tail (it only feeds the energy split of the run JSON). Summed bin by
/// bin, a gate of σ = 100 m over 6 cm bins cost 7 ms per path and σ = 10⁶ m never finished.
const TAIL_BINS: u64 = 256;

/// Every bin whose index is a multiple of this starts the Gaussian recurrence afresh from
/// `exp` (and so does the first bin of every call), so rounding compounds over at most this many
/// steps: about RUN²/2 ulp of each value's relative error (10⁻¹³), far below the f32 films.
/// Fixed bins, not an offset from a path's range, so that one bin's value can be computed
/// alone exactly as a run computes it (`eval` equals `for_each` to the bit).
const GAUSSIAN_RUN: usize = 32;

fn check(field: &'static str, v: impl Into<f64>, positive: bool) -> Result<(), TemporalError> {
    let v: f64 = v.into();
    let ok = v.is_finite() && (!positive || v > 0.0);
    if ok {
        Ok(())
    } else {
        let expected = if positive {
            "a finite number > 0"
        } else {
            "a finite number"
        };
        Err(TemporalError::Invalid {
            field,
            expected,
            got: v.to_string(),
        })
    }
}

impl Correlation {
    /// The correlation of `pulse`, emitted with offset τ = `offset_opl` (metres of OPL), with
    /// the gate of every bin of `axis` (supplemental Eq. 24). Fails if the axis start, the
    /// offset or a width is not finite, a width or σ is not positive, or the axis has no bins.
    pub fn new(axis: TimeAxis, pulse: Pulse, offset_opl: f64, gate: Gate) -> Result<Self, TemporalError> {
        check("film.start_opl", axis.start_opl, false)?;
        check("film.bin_width_opl", axis.bin_width_opl, true)?;
        if axis.bins == 0 {
            return Err(TemporalError::Invalid {
                field: "film.bins",
                expected: "at least 1",
                got: "0".into(),
            });
        }
        check("emitter.offset_opl", offset_opl, false)?;
        let p_reach = match pulse {
            Pulse::Delta => 0.0,
            Pulse::Gaussian { sigma_opl } => {
                check("emitter.pulse.sigma_opl", sigma_opl, true)?;
                sigma_opl as f64
            }
            Pulse::Box { width_opl } => {
                check("emitter.pulse.width_opl", width_opl, true)?;
                0.0
            }
        };
        let box_half = if let Pulse::Box { width_opl } = pulse {
            0.5 * width_opl as f64
        } else {
            0.0
        };
        let reach = match gate {
            Gate::Box => GAUSSIAN_CUTOFF_SIGMAS * p_reach + box_half,
            Gate::Gaussian { sigma_opl } => {
                check("film.gate.sigma_opl", sigma_opl, true)?;
                let s = (p_reach * p_reach + (sigma_opl as f64).powi(2)).sqrt();
                GAUSSIAN_CUTOFF_SIGMAS * s + box_half
            }
        };
        let gaussian = match (pulse, gate) {
            (Pulse::Delta | Pulse::Gaussian { .. }, Gate::Gaussian { sigma_opl }) => {
                let s = (p_reach * p_reach + (sigma_opl as f64).powi(2)).sqrt();
                let bin = GaussBin::new(axis.bin_width_opl, s);
                Some(GaussianRun {
                    q: (-bin.w_inv_s * bin.w_inv_s).exp(),
                    bin,
                })
            }
            _ => None,
        };
        Ok(Self {
            axis,
            pulse,
            offset: offset_opl,
            gate,
            reach,
            gaussian,
            truncated: Truncated::new(GAUSSIAN_CUTOFF_SIGMAS),
        })
    }

    /// The film time axis the correlation was built for.
    pub fn axis(&self) -> &TimeAxis {
        &self.axis
    }

    /// True when S_e is discontinuous in d (delta pulse, box gate): Ṡ_e is then a Dirac
    /// distribution that a sampled estimator cannot evaluate (supplemental Lemma 2.5).
    pub fn derivative_is_distribution(&self) -> bool {
        matches!((self.pulse, self.gate), (Pulse::Delta, Gate::Box))
    }

    /// An OPL past which no path touches a bin: `range(d)` is empty for every d >
    /// `last_opl()` (the window's end plus the reach of pulse and gate, less the emitter's
    /// offset; a box gate's last bin is reached up to this bound, a Gaussian gate's up to half
    /// a bin before it). The window cut (`integrator::window`) traces no path beyond it.
    /// Half-width of the support of S_e(l, ·) beyond a bin (pulse ⋆ gate), metres of OPL.
    pub fn reach(&self) -> f64 {
        self.reach
    }

    /// The largest OPL a path can have and still touch a bin: the axis's end plus the reach,
    /// less the emitter's offset.
    pub fn last_opl(&self) -> f64 {
        self.axis.end_opl() + self.reach - self.offset
    }

    /// The bins a path of OPL `d` touches (S_e ≠ 0); empty outside the axis.
    #[inline]
    pub fn range(&self, d: f64) -> std::ops::Range<usize> {
        let u = d + self.offset;
        if !u.is_finite() {
            return 0..0;
        }
        let w = self.axis.bin_width_opl;
        let x = (u - self.axis.start_opl) / w;
        let n = self.axis.bins as f64;
        let (lo, hi) = match self.gate {
            // bins [a, b) meeting [u − reach, u + reach]; a delta needs the one bin holding u
            Gate::Box if self.reach == 0.0 => (x.floor(), x.floor() + 1.0),
            Gate::Box => ((x - self.reach / w).floor(), (x + self.reach / w).floor() + 1.0),
            // bins whose centre lies within reach of u
            Gate::Gaussian { .. } => (
                (x - self.reach / w - 0.5).ceil(),
                (x + self.reach / w - 0.5).floor() + 1.0,
            ),
        };
        let lo = lo.clamp(0.0, n) as usize;
        let hi = hi.clamp(0.0, n) as usize;
        lo..hi.max(lo)
    }

    /// S_e(l, d) (dimensionless; a box gate with any unit-area pulse sums to 1 over bins).
    #[inline]
    pub fn eval(&self, bin: usize, d: f64) -> f64 {
        self.bin_pair(bin, d).0
    }

    /// ∂S_e(l, d)/∂d, per OPL metre (0 where S_e is piecewise constant).
    #[inline]
    pub fn eval_deriv(&self, bin: usize, d: f64) -> f64 {
        self.bin_pair(bin, d).1
    }

    /// (S_e, ∂S_e/∂d) of one bin, exactly as [`Correlation::for_each`] gives it: for a
    /// Gaussian S_e, the recurrence from the run's start ([`GAUSSIAN_RUN`]) or the range's.
    fn bin_pair(&self, bin: usize, d: f64) -> (f64, f64) {
        let r = self.range(d);
        if !r.contains(&bin) {
            return (0.0, 0.0);
        }
        let u = d + self.offset;
        match &self.gaussian {
            Some(g) => {
                let from = r.start.max(bin - bin % GAUSSIAN_RUN);
                let mut out = (0.0, 0.0);
                self.gaussian_bins(g, u, from..bin + 1, |_, s, ds| out = (s, ds));
                out
            }
            None => self.eval_pair(bin, u),
        }
    }

    /// (S_e, ∂S_e/∂u) of every bin in `bins` for a Gaussian S_e ([`GaussianRun`]), each as
    /// [`gauss_with`] gives it from the closed form's φ, with φ carried from bin to bin and
    /// taken afresh at the first bin and at every multiple of [`GAUSSIAN_RUN`].
    #[inline]
    fn gaussian_bins(&self, g: &GaussianRun, u: f64, bins: std::ops::Range<usize>, mut f: impl FnMut(usize, f64, f64)) {
        let (w, r0) = (self.axis.bin_width_opl, self.axis.start_opl - u);
        let (mut p, mut ratio) = (0.0, 0.0);
        let (first, end) = (bins.start, bins.end);
        for l in bins {
            // the bin's centre, less u, by `eval_at`'s expression
            let x = -(r0 + (l as f64 + 0.5) * w);
            if l == first || l % GAUSSIAN_RUN == 0 {
                let z = x * g.bin.inv_s;
                p = phi(z);
                let step = g.bin.w_inv_s;
                ratio = (step * (z - 0.5 * step)).exp();
            }
            let (se, ds) = g.bin.at(x, p);
            f(l, se, ds);
            if l + 1 < end {
                p *= ratio;
                ratio *= g.q;
            }
        }
    }

    /// Calls `f(bin, S_e, ∂S_e/∂d)` for every bin in `range(d)` where either is nonzero, in
    /// f64: a narrow pulse's ±lobes of ∂S_e/∂d (about 0.24/σ per metre) cancel over the bins
    /// only if they reach the film unrounded.
    #[inline]
    pub fn for_each(&self, d: f64, mut f: impl FnMut(usize, f64, f64)) {
        let r = self.range(d);
        if let (Pulse::Delta, Gate::Box) = (self.pulse, self.gate) {
            if r.len() == 1 {
                f(r.start, 1.0, 0.0);
            }
            return;
        }
        let u = d + self.offset;
        if let (Pulse::Gaussian { sigma_opl }, Gate::Box) = (self.pulse, self.gate) {
            // adjacent bins share an edge: one CDF per edge instead of two per bin, the edges
            // by `eval_at`'s expression (bin l + 1 starts at (l + 1.0)·w), so the same values
            let (s, w, r0) = (sigma_opl as f64, self.axis.bin_width_opl, self.axis.start_opl - u);
            let edge = |l: f64| self.truncated.at((r0 + l * w) / s);
            let mut lo = edge(r.start as f64);
            for l in r {
                let hi = edge(l as f64 + 1.0);
                let (se, ds) = gaussian_box(&lo, &hi, s);
                if se != 0.0 || ds != 0.0 {
                    f(l, se, ds);
                }
                lo = hi;
            }
            return;
        }
        if let Some(g) = &self.gaussian {
            self.gaussian_bins(
                g,
                u,
                r,
                #[inline(always)]
                |l, s, ds| {
                    if s != 0.0 || ds != 0.0 {
                        f(l, s, ds);
                    }
                },
            );
            return;
        }
        for l in r {
            let (s, ds) = self.eval_pair(l, u);
            if s != 0.0 || ds != 0.0 {
                f(l, s, ds);
            }
        }
    }

    /// The parts of a path's unit S_e mass that fall before bin 0 and after the last bin:
    /// (Σ_{l<0} S_e(l, d), Σ_{l≥bins} S_e(l, d)) with the bins continued past both ends of the
    /// axis, so that with the film's share Σ_l S_e(l, d) they add up to 1 (for a box gate,
    /// whose bins tile time; up to the ripple of Σ_l g_l for a Gaussian gate, see
    /// [`Gate::Gaussian`]). `None` when the whole support lies inside the axis (the common
    /// case, two comparisons). A box gate's tails are the pulse's CDF at the axis' ends; a
    /// Gaussian gate's are summed bin by bin (the bins within reach of d), since a
    /// half-line of its bins is not its integral.
    #[inline]
    pub fn tails(&self, d: f64) -> Option<(f64, f64)> {
        let u = d + self.offset;
        let start = self.axis.start_opl;
        let end = self.axis.end_opl();
        if !u.is_finite() || (u - self.reach >= start && u + self.reach < end) {
            return None;
        }
        let w = self.axis.bin_width_opl;
        let x = (u - start) / w;
        let n = self.axis.bins as f64;
        Some(match (self.pulse, self.gate) {
            // the same test as `range`: a delta lands in bin floor(x)
            (Pulse::Delta, Gate::Box) => ((x < 0.0) as u8 as f64, (x >= n) as u8 as f64),
            (Pulse::Gaussian { sigma_opl }, Gate::Box) => {
                let s = sigma_opl as f64;
                (cdf((start - u) / s), cdf((u - end) / s))
            }
            (Pulse::Box { width_opl }, Gate::Box) => {
                let wp = width_opl as f64;
                let part = |y: f64| ((y + 0.5 * wp) / wp).clamp(0.0, 1.0);
                (part(start - u), part(u - end))
            }
            (_, Gate::Gaussian { .. }) => {
                // bins whose centre start + (l + ½)·w lies within reach of u, as in `range`
                let lo = (x - self.reach / w - 0.5).ceil();
                let hi = (x + self.reach / w - 0.5).floor();
                let sum = |a: f64, b: f64| {
                    let (a, b) = (a.max(lo), b.min(hi));
                    let count = (b - a + 1.0).max(0.0);
                    if count <= TAIL_BINS as f64 {
                        // a count, not a float loop counter
                        (0..count as u64).map(|k| self.eval_at(a + k as f64, u).0).sum::<f64>()
                    } else {
                        // TAIL_BINS blocks of `len` bins (bin l spanning l ± ½), each its
                        // middle's value times its size
                        let len = count / TAIL_BINS as f64;
                        (0..TAIL_BINS)
                            .map(|j| len * self.eval_at(a - 0.5 + (j as f64 + 0.5) * len, u).0)
                            .sum::<f64>()
                    }
                };
                (sum(lo, -1.0), sum(n, hi))
            }
        })
    }

    /// (S_e, ∂S_e/∂u) for bin l at arrival u = d + τ, in closed form.
    fn eval_pair(&self, l: usize, u: f64) -> (f64, f64) {
        self.eval_at(l as f64, u)
    }

    /// (S_e, ∂S_e/∂u) for bin `l` (which may lie outside the axis: negative, or ≥ bins).
    ///
    /// Bin edges are taken relative to u as (start − u) + l·w, the same expression for the
    /// end of bin l and the start of bin l + 1: then the ±lobes of a narrow pulse's ∂S_e/∂u
    /// telescope exactly over the bins (Σ_l = 0). Edges computed as absolute OPLs and then
    /// differenced with u would differ by an f64 step (4·10⁻¹⁶ m at 4 m), which for a 3 nm
    /// pulse leaves ~10 per metre of ∂S_e/∂u at every edge.
    fn eval_at(&self, l: f64, u: f64) -> (f64, f64) {
        let w = self.axis.bin_width_opl;
        let r0 = self.axis.start_opl - u;
        // edges of the bin and its centre, minus u
        let (a, b, c) = (r0 + l * w, r0 + (l + 1.0) * w, r0 + (l + 0.5) * w);
        match (self.pulse, self.gate) {
            (Pulse::Delta, Gate::Box) => (if a <= 0.0 && 0.0 < b { 1.0 } else { 0.0 }, 0.0),
            (Pulse::Gaussian { sigma_opl }, Gate::Box) => {
                let s = sigma_opl as f64;
                gaussian_box(&self.truncated.at(a / s), &self.truncated.at(b / s), s)
            }
            (Pulse::Box { width_opl }, Gate::Box) => {
                let wp = width_opl as f64;
                let (lo, hi) = (-0.5 * wp, 0.5 * wp);
                let overlap = (hi.min(b) - lo.max(a)).max(0.0);
                let inside = |t: f64| if a < t && t < b { 1.0 } else { 0.0 };
                (overlap / wp, (inside(hi) - inside(lo)) / wp)
            }
            (Pulse::Delta, Gate::Gaussian { sigma_opl }) => gauss(w, -c, sigma_opl as f64),
            (Pulse::Gaussian { sigma_opl: sp }, Gate::Gaussian { sigma_opl: sg }) => {
                gauss(w, -c, ((sp as f64).powi(2) + (sg as f64).powi(2)).sqrt())
            }
            (Pulse::Box { width_opl }, Gate::Gaussian { sigma_opl }) => {
                let (wp, s) = (width_opl as f64, sigma_opl as f64);
                let na = self.truncated.at((-0.5 * wp - c) / s);
                let nb = self.truncated.at((0.5 * wp - c) / s);
                (w / wp * na.mass_to(&nb), w / wp * (nb.pdf - na.pdf) / s)
            }
        }
    }
}

/// (S_e, ∂S_e/∂u) of a Gaussian pulse of σ = `s` and a box gate whose bin edges, less u, are
/// σ·`a.x` and σ·`b.x`.
#[inline]
fn gaussian_box(a: &Normal, b: &Normal, s: f64) -> (f64, f64) {
    (a.mass_to(b), (a.pdf - b.pdf) / s)
}

/// w · N(x; 0, s) as [`GaussBin`] gives it, with φ(x/s) in closed form.
#[inline]
fn gauss(w: f64, x: f64, s: f64) -> (f64, f64) {
    let bin = GaussBin::new(w, s);
    bin.at(x, phi(x * bin.inv_s))
}

#[cfg(test)]
mod tests;
