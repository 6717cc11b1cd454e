//! Transient films: per-pixel, per-bin accumulation of path contributions.
//!
//! The integrator reports each path's throughput and optical path length; the film bins it
//! through the correlation S_e of the emitter pulse with the sensor gate (supplemental
//! Eq. 24): `I[y, x, l, c] += f_c · S_e(l, d)` for `l ∈ S_e.range(d)`. The derivative films
//! add `ḟ_c · S_e(l, d) + f_c · Ṡ_e(l, d) · ḋ` (Algorithm 1, last loop).

use std::ops::Range;

use crate::temporal::{Correlation, TimeAxis};
use bins::Bins;
pub(crate) use bins::{holds_bits, nonzero_runs, try_each_written, unpack_written, written_len, written_words};

mod bins;
mod shared_frame;

pub use shared_frame::{Rect, SharedFrame};

/// A finished transient: `data` is `[height, width, bins, channels]`, row-major, averaged
/// over samples. `steady` is the time-integrated image `[height, width, channels]` of the
/// same paths: the integral over the window ([`SteadyMode::Window`], the default) or over
/// all time, counting every path whether or not it falls inside the time axis
/// ([`SteadyMode::Full`]).
///
/// ```
/// use difftransient::{Transient, temporal::TimeAxis};
///
/// let axis = TimeAxis { start_opl: 0.0, bin_width_opl: 0.1, bins: 4 };
/// let mut t = Transient::zeros(3, 2, axis, 1);
/// assert_eq!(t.shape(), [2, 3, 4, 1]);
/// // Pixel (x = 2, y = 1), bin 3, channel 0 is the last value of `data`.
/// let i = t.index(2, 1, 3, 0);
/// assert_eq!(i, t.data.len() - 1);
/// t.data[i] = 2.0;
/// assert_eq!(t.at(2, 1, 3, 0), 2.0);
/// assert_eq!(t.pixel_series(2, 1), vec![0.0, 0.0, 0.0, 2.0]);
/// assert_eq!(t.bin_totals()[3], 2.0);
/// ```
#[derive(Debug, PartialEq)]
pub struct Transient {
    /// Image width in pixels (for an NLOS capture: sensor columns, or sensor points).
    pub width: usize,
    /// Image height in pixels (for an NLOS capture: sensor rows, or laser points).
    pub height: usize,
    /// The time axis of the bins (OPL in metres).
    pub axis: TimeAxis,
    /// Channels per value: 1 (mono) or 3 (RGB).
    pub channels: usize,
    /// Radiance per bin, `[height, width, bins, channels]` row-major; index it with
    /// [`Self::index`]. For a derivative film, ∂I/∂θ in the same layout.
    pub data: Vec<f32>,
    /// Time-integrated image, `[height, width, channels]` row-major (see [`SteadyMode`]).
    pub steady: Vec<f32>,
}

/// A copy that writes only the runs of bins that hold any bits: the rest of the copy is
/// fresh zeros, whose pages are never touched. A transient is sparse in time, and a copy of
/// every value of a 256×256×2000 film at a few spp wrote 1.5 GB where some 200 MB hold
/// values (the copy kept for a checkpoint before a boundary stage, a derivative's sum of
/// parts).
impl Clone for Transient {
    fn clone(&self) -> Self {
        let mut data = vec![0.0; self.data.len()];
        bins::copy_nonzero(&mut data, &self.data);
        Self {
            data,
            steady: self.steady.clone(),
            ..*self
        }
    }
}

impl Transient {
    /// `count` films of zeros, each allocated on its own. `vec![Transient::zeros(..); n]`
    /// would clone one film of zeros: the copies write every value (all their pages mapped,
    /// whether a tile ever reaches them or not), and reading the original maps its pages to
    /// the shared zero page, so each page's first store faults again and flushes the TLB of
    /// every core running the process.
    pub fn zeros_many(count: usize, width: usize, height: usize, axis: TimeAxis, channels: usize) -> Vec<Self> {
        (0..count).map(|_| Self::zeros(width, height, axis, channels)).collect()
    }

    /// A film of zeros with the given size, axis and channel count.
    pub fn zeros(width: usize, height: usize, axis: TimeAxis, channels: usize) -> Self {
        Self {
            width,
            height,
            axis,
            channels,
            data: vec![0.0; width * height * axis.bins * channels],
            steady: vec![0.0; width * height * channels],
        }
    }
    /// Shape `[H, W, T, C]` as written to `.npy`.
    pub fn shape(&self) -> [usize; 4] {
        [self.height, self.width, self.axis.bins, self.channels]
    }
    /// Offset of pixel (`x`, `y`), bin `bin`, channel `c` in [`Self::data`].
    #[inline]
    pub fn index(&self, x: usize, y: usize, bin: usize, c: usize) -> usize {
        ((y * self.width + x) * self.axis.bins + bin) * self.channels + c
    }
    /// The value of pixel (`x`, `y`), bin `bin`, channel `c`. Panics when out of range.
    pub fn at(&self, x: usize, y: usize, bin: usize, c: usize) -> f32 {
        self.data[self.index(x, y, bin, c)]
    }
    /// Σ over time bins for one pixel and channel.
    pub fn time_sum(&self, x: usize, y: usize, c: usize) -> f32 {
        (0..self.axis.bins).map(|t| self.at(x, y, t, c)).sum()
    }
    /// Σ over pixels and channels, one value per bin (radiance over time of the whole image).
    pub fn bin_totals(&self) -> Vec<f32> {
        self.bin_totals_in()
    }
    /// [`Self::bin_totals`] added up in f64: finite for any film of finite values (a sum of
    /// 32-bit values near their largest, 3.4·10³⁸, overflows in f32; the preview's time plot
    /// then failed on its own sums).
    pub fn bin_totals_f64(&self) -> Vec<f64> {
        self.bin_totals_in()
    }
    /// [`Self::bin_totals`] accumulated in `T` (pixel by pixel, channels in order).
    fn bin_totals_in<T: Copy + Default + From<f32> + std::ops::AddAssign>(&self) -> Vec<T> {
        let mut out = vec![T::default(); self.axis.bins];
        for px in self.data.chunks_exact(self.axis.bins * self.channels) {
            for (t, o) in out.iter_mut().enumerate() {
                for c in 0..self.channels {
                    *o += T::from(px[t * self.channels + c]);
                }
            }
        }
        out
    }
    /// [`Self::pixel_series`] added up in f64.
    pub fn pixel_series_f64(&self, x: usize, y: usize) -> Vec<f64> {
        (0..self.axis.bins)
            .map(|t| (0..self.channels).map(|c| self.at(x, y, t, c) as f64).sum())
            .collect()
    }
    /// Per-bin series of one pixel, channels summed.
    pub fn pixel_series(&self, x: usize, y: usize) -> Vec<f32> {
        (0..self.axis.bins)
            .map(|t| (0..self.channels).map(|c| self.at(x, y, t, c)).sum())
            .collect()
    }
    /// Count of NaN or infinite values in data and steady image.
    pub fn non_finite_count(&self) -> usize {
        self.data.iter().chain(&self.steady).filter(|v| !v.is_finite()).count()
    }
    /// Multiplies every value of the transient and the steady image by `s`. For a positive,
    /// finite `s` (an average over samples) runs of 16 zeros are left unwritten, since they
    /// would stay the same zeros: the pages of a sparse transient that no path reached are
    /// then only read, never copied from the kernel's zero page.
    pub fn scale(&mut self, s: f32) {
        let keep_zeros = s > 0.0 && s.is_finite();
        for run in self.data.chunks_mut(16).chain(self.steady.chunks_mut(16)) {
            // ±0 have no bits but the sign's
            if !(keep_zeros && run.iter().fold(0, |bits, v| bits | v.to_bits() << 1) == 0) {
                run.iter_mut().for_each(|v| *v *= s);
            }
        }
    }
}

/// What a render's time-summed (steady) image integrates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SteadyMode {
    /// The time window: Σ_l S_e(l, d)·f per path, the time sum of the transient's bins. Lets
    /// the estimators end paths that have left the window (`integrator::window`).
    #[default]
    Window,
    /// All time: every path's f, in or out of the window (`dtr render --steady full`). No
    /// path is cut, so the render also measures the energy after the window exactly.
    Full,
}

/// What estimators add path contributions to: a tile's bins ([`TileFilm`]), or the adjoint
/// contraction of a loss's gradient (`crate::adjoint::AdjointFilm`), which keeps no bins.
pub trait Accumulate {
    /// `I += f·S_e(d)` at pixel (x, y).
    fn add(&mut self, x: usize, y: usize, corr: &Correlation, d: f64, f: &[f32]);
    /// `I += f·S_e(d)` and `İ_k += ḟ_k·S_e(d) + f·Ṡ_e(d)·ḋ_k` at pixel (x, y) (Algorithm 1);
    /// `fdot[k*C + c]`, `ddot[k]`.
    #[allow(clippy::too_many_arguments)]
    fn add_with_derivs(
        &mut self,
        x: usize,
        y: usize,
        corr: &Correlation,
        d: f64,
        f: &[f32],
        fdot: &[f32],
        ddot: &[f32],
    );
    /// `İ_k += s·f·ḋ_k` in bin `bin` (on the film) of pixel (x, y), and nothing else: one bin
    /// of a time term whose value and ḟ another estimator counts.
    fn add_time_bin(&mut self, x: usize, y: usize, bin: usize, s: f64, f: &[f32], ddot: &[f32]);

    /// `İ_k += f·Ṡ_e(d)·ḋ_k` at pixel (x, y), and nothing else: the time term of a path whose
    /// value and ḟ another estimator counts (`integrator::time_edge_nee`).
    fn add_time_term(&mut self, x: usize, y: usize, corr: &Correlation, d: f64, f: &[f32], ddot: &[f32]) {
        corr.for_each(d, |bin, _, ds| self.add_time_bin(x, y, bin, ds, f, ddot));
    }

    /// `İ_k += f·ḋ_k` in bin `edge` and `İ_k −= f·ḋ_k` in bin `edge − 1` (those of them on the
    /// film) at pixel (x, y): the time term of a delta pulse's path on that bin edge
    /// (Ṡ_e is a Dirac there), drawn by `integrator::time_edge_nee`.
    fn add_edge_term(&mut self, x: usize, y: usize, edge: usize, bins: usize, f: &[f32], ddot: &[f32]) {
        if edge < bins {
            self.add_time_bin(x, y, edge, 1.0, f, ddot);
        }
        if (1..=bins).contains(&edge) {
            self.add_time_bin(x, y, edge - 1, -1.0, f, ddot);
        }
    }
}

/// A tile film bins each path through S_e into its own pixels.
impl Accumulate for TileFilm {
    /// Adds one path of OPL `d` with throughput `f` (per channel) to pixel (x, y) (global
    /// coordinates, inside this tile).
    #[inline]
    fn add(&mut self, x: usize, y: usize, corr: &Correlation, d: f64, f: &[f32]) {
        let p = (y - self.y0) * self.w + (x - self.x0);
        let c_n = self.channels;
        let full = self.steady_mode == SteadyMode::Full;
        if full {
            for c in 0..c_n {
                self.steady[p * c_n + c] += f[c] as f64;
            }
        }
        self.add_tails(corr, d, f);
        let base = p * self.bins * c_n;
        let (data, steady) = (&mut self.data, &mut self.steady[p * c_n..(p + 1) * c_n]);
        // inlined into each of S_e's loops: as a call per bin it took 12–14 % of an exhaustive
        // NLOS capture's time (Gaussian gate; `perf`, BENCHMARKS.md "Gaussian S_e splats")
        corr.for_each(
            d,
            #[inline(always)]
            |bin, s, _ds| {
                let i = base + bin * c_n;
                for (c, &fc) in f.iter().enumerate().take(c_n) {
                    data.add(i + c, fc as f64 * s);
                    if !full {
                        steady[c] += fc as f64 * s;
                    }
                }
            },
        );
    }

    /// Adds one path and its derivatives in a single pass over S_e.range(d) (S_e and Ṡ_e are
    /// evaluated once for all films): `I += f·S_e(d)` and, for each parameter k,
    /// `İ_k += ḟ_k·S_e(d) + f·Ṡ_e(d)·ḋ_k` (Algorithm 1). `fdot[k*C + c]` and `ddot[k]` are the
    /// derivatives of throughput and OPL; `fdot.len() == ddot.len() * C`.
    #[inline]
    fn add_with_derivs(
        &mut self,
        x: usize,
        y: usize,
        corr: &Correlation,
        d: f64,
        f: &[f32],
        fdot: &[f32],
        ddot: &[f32],
    ) {
        let p = (y - self.y0) * self.w + (x - self.x0);
        let c_n = self.channels;
        let n_k = ddot.len().min(self.derivs);
        let sblock = self.w * self.h * c_n;
        let full = self.steady_mode == SteadyMode::Full;
        if full {
            for c in 0..c_n {
                self.steady[p * c_n + c] += f[c] as f64;
            }
            for k in 0..n_k {
                for c in 0..c_n {
                    self.steady[sblock * (1 + k) + p * c_n + c] += fdot[k * c_n + c] as f64;
                }
            }
        }
        self.add_tails(corr, d, f);
        let block = self.block();
        let base = p * self.bins * c_n;
        let (data, steady) = (&mut self.data, &mut self.steady);
        // inlined into S_e's loops, as in `add`
        corr.for_each(
            d,
            #[inline(always)]
            |bin, s, ds| {
                let i = base + bin * c_n;
                for (c, &fc) in f.iter().enumerate().take(c_n) {
                    data.add(i + c, fc as f64 * s);
                    if !full {
                        steady[p * c_n + c] += fc as f64 * s;
                    }
                }
                for k in 0..n_k {
                    let ik = block * (1 + k) + i;
                    let dd = ds * ddot[k] as f64;
                    for c in 0..c_n {
                        let v = fdot[k * c_n + c] as f64 * s + f[c] as f64 * dd;
                        data.add(ik + c, v);
                        if !full {
                            steady[sblock * (1 + k) + p * c_n + c] += v;
                        }
                    }
                }
            },
        );
    }

    /// Into the derivative bins, and their steady image when it integrates the window (over
    /// all time Ṡ_e integrates to zero, so a `Full` steady image takes nothing).
    #[inline]
    fn add_time_bin(&mut self, x: usize, y: usize, bin: usize, s: f64, f: &[f32], ddot: &[f32]) {
        let p = (y - self.y0) * self.w + (x - self.x0);
        let c_n = self.channels;
        let n_k = ddot.len().min(self.derivs);
        let sblock = self.w * self.h * c_n;
        let full = self.steady_mode == SteadyMode::Full;
        let block = self.block();
        let i = (p * self.bins + bin) * c_n;
        for k in 0..n_k {
            for c in 0..c_n {
                let v = f[c] as f64 * (s * ddot[k] as f64);
                self.data.add(block * (1 + k) + i + c, v);
                if !full {
                    self.steady[sblock * (1 + k) + p * c_n + c] += v;
                }
            }
        }
    }
}

/// A [`TileFilm`]'s running sums, exactly (f32 or f64 bins as the film keeps them).
#[derive(Debug, Default)]
#[doc(hidden)]
pub struct TileSums {
    pub data32: Vec<f32>,
    pub data64: Vec<f64>,
    /// Which runs of the bins were written (`film::bins`); empty when not known (sums read
    /// from a checkpoint), and then found from the values.
    pub written: Vec<u64>,
    pub steady: Vec<f64>,
    pub tails: [f64; 2],
}

/// A copy that reads only the written runs of the bins (all of them when that is not known):
/// the rest of the copy is fresh zeros. A checkpoint copies BDPT's row sums this way; a copy of
/// every value would map the untouched pages of the rows to the kernel's shared zero page,
/// and the next wave's first store into each would fault again and flush the TLB of every core.
impl Clone for TileSums {
    fn clone(&self) -> Self {
        Self {
            data32: bins::copy_written(&self.data32, &self.written),
            data64: bins::copy_written(&self.data64, &self.written),
            written: self.written.clone(),
            steady: self.steady.clone(),
            tails: self.tails,
        }
    }
}

/// Each row `ty` of the pixel rectangle `(x0, y0, w, h)` in a full film `width` pixels wide,
/// of `bins` bins and `channels` channels: the row's range of the film's `data` and of its
/// `steady` image.
pub fn rect_rows(
    (x0, y0, w, h): (usize, usize, usize, usize),
    width: usize,
    bins: usize,
    channels: usize,
) -> impl Iterator<Item = (usize, Range<usize>, Range<usize>)> {
    (0..h).map(move |ty| {
        let first = (y0 + ty) * width + x0;
        let (data, steady) = (first * bins * channels, first * channels);
        (ty, data..data + w * bins * channels, steady..steady + w * channels)
    })
}

/// A rectangle of pixels accumulated by one worker, then stored into a [`Transient`]
/// ([`TileFilm::store_into`]), so results do not depend on the thread count or scheduling.
#[derive(Clone, Debug)]
#[doc(hidden)]
pub struct TileFilm {
    pub x0: usize,
    pub y0: usize,
    pub w: usize,
    pub h: usize,
    bins: usize,
    channels: usize,
    /// Primal, then one block per derivative, each `[h, w, bins, channels]`.
    data: Bins,
    steady: Vec<f64>,
    derivs: usize,
    steady_mode: SteadyMode,
    /// Primal energy (Σ over channels of f · S_e mass) that fell before bin 0 and after the
    /// last bin ([`Correlation::tails`]), for the run's energy report; f64, per tile, so the
    /// driver can sum tiles in a fixed order.
    tails: [f64; 2],
}

impl TileFilm {
    pub fn new(x0: usize, y0: usize, w: usize, h: usize, axis: &TimeAxis, channels: usize, derivs: usize) -> Self {
        let n = w * h * axis.bins * channels;
        Self {
            x0,
            y0,
            w,
            h,
            bins: axis.bins,
            channels,
            data: Bins::new(n * (1 + derivs), derivs),
            steady: vec![0.0; w * h * channels * (1 + derivs)],
            derivs,
            steady_mode: SteadyMode::Full,
            tails: [0.0; 2],
        }
    }

    /// The film with its steady image integrating `mode` (all time by default).
    pub fn with_steady(mut self, mode: SteadyMode) -> Self {
        self.steady_mode = mode;
        self
    }

    /// Empties the film and moves it to the rectangle at (x0, y0) of w × h pixels, reusing
    /// its memory (a worker renders many tiles into one film; fresh zeroed pages cost page
    /// faults on every tile).
    pub fn reset(&mut self, x0: usize, y0: usize, w: usize, h: usize) {
        let n = w * h * self.bins * self.channels * (1 + self.derivs);
        let sn = w * h * self.channels * (1 + self.derivs);
        (self.x0, self.y0, self.w, self.h) = (x0, y0, w, h);
        self.data.reset(n);
        self.steady.clear();
        self.steady.resize(sn, 0.0);
        self.tails = [0.0; 2];
    }

    /// The film's running sums as they stand (for a checkpoint, `crate::checkpoint`).
    pub fn sums(&self) -> TileSums {
        let (data32, data64, written) = self.data.to_parts();
        TileSums {
            data32,
            data64,
            written,
            steady: self.steady.clone(),
            tails: self.tails,
        }
    }

    /// Puts back sums taken by [`TileFilm::sums`] from a film of the same shape; refuses
    /// sums of another shape or precision.
    pub fn restore(&mut self, s: TileSums) -> Result<(), String> {
        let n = self.w * self.h * self.bins * self.channels * (1 + self.derivs);
        let refused = || Err("the saved film has another shape or precision".into());
        if s.steady.len() != self.w * self.h * self.channels * (1 + self.derivs) {
            return refused();
        }
        if !self.data.restore(n, s.data32, s.data64, s.written) {
            return refused();
        }
        self.steady = s.steady;
        self.tails = s.tails;
        Ok(())
    }

    /// Moves the film's running sums out (no copy), leaving it empty until [`Self::restore`]
    /// moves them (or others of its shape) back.
    pub fn take_sums(&mut self) -> TileSums {
        let (data32, data64, written) = self.data.take_parts();
        TileSums {
            data32,
            data64,
            written,
            steady: std::mem::take(&mut self.steady),
            tails: std::mem::take(&mut self.tails),
        }
    }

    /// Primal energy (summed over pixels and channels, not yet divided by spp) that fell
    /// before and after the time axis.
    pub fn tails(&self) -> [f64; 2] {
        self.tails
    }

    /// Σ of the primal and of each derivative block, in f64 before the f32 store, summed in
    /// the driver in a fixed order: a narrow pulse's derivative has per-bin ±lobes ~10⁷ times
    /// its time integral, more than f32 bins can cancel, so the run report takes the time
    /// integral from here.
    pub fn block_sums(&self) -> Vec<f64> {
        self.data.block_sums(self.block().max(1))
    }

    #[inline]
    fn add_tails(&mut self, corr: &Correlation, d: f64, f: &[f32]) {
        if let Some((before, after)) = corr.tails(d) {
            let e: f64 = f.iter().map(|&v| v as f64).sum();
            self.tails[0] += before * e;
            self.tails[1] += after * e;
        }
    }

    #[inline]
    fn block(&self) -> usize {
        self.w * self.h * self.bins * self.channels
    }

    /// Adds the sums of `other` (same time axis, channels and derivative blocks) where its
    /// rectangle overlaps this one's; tails are not carried over (the caller tallies
    /// `other`'s own). BDPT adds each unit's tile into the full-frame rows this way.
    pub fn add_film(&mut self, other: &TileFilm) {
        debug_assert!(self.bins == other.bins && self.channels == other.channels && self.derivs == other.derivs);
        let (x0, x1) = (self.x0.max(other.x0), (self.x0 + self.w).min(other.x0 + other.w));
        let (y0, y1) = (self.y0.max(other.y0), (self.y0 + self.h).min(other.y0 + other.h));
        if x0 >= x1 || y0 >= y1 {
            return;
        }
        let (bc, c) = (self.bins * self.channels, self.channels);
        let len = (x1 - x0) * bc;
        for k in 0..1 + self.derivs {
            for y in y0..y1 {
                let dst = k * self.block() + ((y - self.y0) * self.w + (x0 - self.x0)) * bc;
                let src = k * other.block() + ((y - other.y0) * other.w + (x0 - other.x0)) * bc;
                self.data.add_from(dst, &other.data, src, len);
                let sdst = k * self.w * self.h * c + ((y - self.y0) * self.w + (x0 - self.x0)) * c;
                let ssrc = k * other.w * other.h * c + ((y - other.y0) * other.w + (x0 - other.x0)) * c;
                for i in 0..(x1 - x0) * c {
                    self.steady[sdst + i] += other.steady[ssrc + i];
                }
            }
        }
    }

    /// Writes this tile into the full films (primal first, then derivatives), whose pixels
    /// under the tile hold zeros: every caller stores disjoint tiles, bands or rows into
    /// fresh films (a film resumed from a checkpoint holds zeros where its tiles did not
    /// finish). The bytes are those of adding the tile to the zeros (`0 + x`), but the
    /// films are only written ([`Bins::store_into`]).
    pub fn store_into(&self, films: &mut [Transient]) {
        for (k, film) in films.iter_mut().enumerate().take(1 + self.derivs) {
            for (ty, data, steady) in self.rows_in(film.width) {
                self.store_row(k, ty, &mut film.data[data], &mut film.steady[steady]);
            }
        }
    }

    /// Each of the tile's rows `ty` with where it lies in a full film `width` pixels wide:
    /// its range of the film's `data` and of its `steady` image.
    pub fn rows_in(&self, width: usize) -> impl Iterator<Item = (usize, Range<usize>, Range<usize>)> + '_ {
        rect_rows((self.x0, self.y0, self.w, self.h), width, self.bins, self.channels)
    }

    /// Stores row `ty` of film `k` (0: the primal, then the derivatives) into `data` and
    /// `steady`, the row's place in a full film ([`Self::rows_in`]), which holds zeros.
    pub fn store_row(&self, k: usize, ty: usize, data: &mut [f32], steady: &mut [f32]) {
        debug_assert!(
            data.iter().all(|&v| v == 0.0),
            "a tile is stored only where the film holds zeros"
        );
        let src = self.block() * k + ty * self.w * self.bins * self.channels;
        self.data.store_into(data, src);
        let ssrc = self.w * self.h * self.channels * k + ty * self.w * self.channels;
        for (d, s) in steady.iter_mut().zip(&self.steady[ssrc..]) {
            *d = 0.0 + *s as f32;
        }
    }

    /// Films this tile writes: the primal, then one per derivative.
    pub fn films(&self) -> usize {
        1 + self.derivs
    }
}

/// Where a render's primal energy fell against the film's time window, summed over pixels
/// and channels (the time integral of the whole image): `inside` is Σ of the transient (in
/// f64, from the tiles),
/// `total` Σ of the steady image (every path, in or out of the window), `before` / `after`
/// the S_e mass of the paths that fell before bin 0 / after the last bin
/// ([`crate::temporal::Correlation::tails`]). `before + inside + after = total` up to
/// rounding for a box gate (up to the ripple of Σ_l g_l for a Gaussian gate).
///
/// When paths were cut at the window ([`SteadyMode::Window`]), the render traced nothing
/// past it: `after` is then estimated by an uncut pilot of `after_pilot_paths` paths, and
/// `total = before + inside + after`.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct WindowEnergy {
    /// Σ of the steady image: all primal energy that reached the camera.
    pub total: f64,
    /// S_e mass of the paths that arrived before bin 0.
    pub before: f64,
    /// Σ of the transient over pixels, bins and channels.
    pub inside: f64,
    /// S_e mass of the paths that arrived after the last bin (estimated by a pilot when
    /// `after_pilot_paths > 0`).
    pub after: f64,
    /// `inside / total` (0 when nothing reached the camera).
    pub inside_fraction: f64,
    /// Paths of the pilot that estimated `after` (0: measured on every path of the render).
    pub after_pilot_paths: u64,
    /// The standard error of the pilot's `after`, from two independent draws per stratum of
    /// the film: the Monte Carlo noise and, where a pass traces fewer paths than the film
    /// has pixels (1/512 of the render's, 512 to 16,384), the error of the rows it leaves
    /// out (`render::pilot_energy_after`). `None` when `after` was measured on every path.
    pub after_standard_error: Option<f64>,
}

/// The same for a derivative film: Σ of ∂I/∂θ inside the window (summed in f64 before the
/// bins are stored as f32, so a narrow pulse's ±lobes cancel) and in all (the steady
/// derivative); `outside = total − inside`. Not split into before and after: the boundary
/// stage's primary-edge jumps keep only their in-window bins and their time integral.
/// With paths cut at the window the steady derivative integrates the window too, so
/// `total = inside` and `outside` is not measured (`None`).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct DerivWindowEnergy {
    /// Σ of the steady derivative image.
    pub total: f64,
    /// Σ of the derivative transient over pixels, bins and channels.
    pub inside: f64,
    /// `total − inside`; `None` when paths were cut at the window.
    pub outside: Option<f64>,
}

/// A window holding less than this share of the primal energy draws a warning
/// ([`WindowEnergy::warning`]). One half: the transient then shows the minority of the light
/// that reached the camera, the mark of a misplaced window (one that ends on the rise or
/// starts after most paths arrived), while a decay tail clipped on purpose stays quiet (the
/// shipped scenes hold 52–100%: laser_room 86%, contact_wall 88%, the rest above 93% except
/// shadow_hidden_occluder, whose window starts after 47% of its light arrived). Gated set-ups
/// that cut out a bright direct return (NLOS) get a one-line warning that tells them what
/// they already know.
pub const MIN_INSIDE_FRACTION: f64 = 0.5;

impl WindowEnergy {
    /// The report of a finished (averaged) transient, with the Σ of its bins and the tails
    /// its tiles counted in f64 (already divided by spp).
    pub fn of(t: &Transient, inside: f64, before: f64, after: f64) -> Self {
        let total: f64 = t.steady.iter().map(|&v| v as f64).sum();
        Self::with_total(total, inside, before, after, 0)
    }

    /// The report of a render cut at the window: `inside` and `before` measured on every
    /// path (nothing before the window's end is cut), `after` estimated by a pilot of `paths`
    /// uncut paths, with its standard error.
    pub fn with_pilot(inside: f64, before: f64, (after, after_se): (f64, f64), paths: u64) -> Self {
        Self {
            after_standard_error: Some(after_se),
            ..Self::with_total(before + inside + after, inside, before, after, paths)
        }
    }

    fn with_total(total: f64, inside: f64, before: f64, after: f64, after_pilot_paths: u64) -> Self {
        Self {
            total,
            before,
            inside,
            after,
            inside_fraction: if total > 0.0 { inside / total } else { 0.0 },
            after_pilot_paths,
            after_standard_error: None,
        }
    }

    /// A one-line warning when the window holds nothing or less than
    /// [`MIN_INSIDE_FRACTION`] of the energy; `None` when it looks right.
    pub fn warning(&self, axis: &TimeAxis) -> Option<String> {
        let window = format!("[{}, {}] m of OPL", axis.start_opl, axis.end_opl());
        if self.total <= 0.0 {
            return Some(format!(
                "no light reached the camera at all (is there an emitter, and can the camera see what it lights?); the transient is all zeros (window {window})"
            ));
        }
        let pct = |v: f64| 100.0 * v / self.total;
        let split = format!(
            "{:.1}% of the energy arrived before the window, {:.1}% inside, {:.1}% after",
            pct(self.before),
            pct(self.inside),
            pct(self.after)
        );
        if self.inside <= 0.0 {
            Some(format!(
                "the time window {window} holds no energy: every path arrived outside it ({split}); move film.start_opl or widen the window"
            ))
        } else if self.inside_fraction < MIN_INSIDE_FRACTION {
            Some(format!(
                "the time window {window} holds only {:.1}% of the energy ({split}); move film.start_opl or widen the window",
                pct(self.inside)
            ))
        } else {
            None
        }
    }
}

impl DerivWindowEnergy {
    /// `inside`: Σ of the film's bins as the tiles summed them in f64 (divided by spp), with
    /// the boundary parts; `extra_steady`: Σ of the steady images of parts not in `t`.
    pub fn of(t: &Transient, extra_steady: f64, inside: f64, steady: SteadyMode) -> Self {
        match steady {
            SteadyMode::Full => {
                let total: f64 = t.steady.iter().map(|&v| v as f64).sum::<f64>() + extra_steady;
                Self {
                    total,
                    inside,
                    outside: Some(total - inside),
                }
            }
            SteadyMode::Window => Self {
                total: inside,
                inside,
                outside: None,
            },
        }
    }
}

#[cfg(test)]
mod tests;
