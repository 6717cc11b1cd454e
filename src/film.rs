//! Transient films: per-pixel, per-bin accumulation of path contributions.
//!
//! The integrator reports each path's throughput and optical path length; the film bins it
//! through the correlation S_e of the emitter pulse with the sensor gate (supplemental
//! Eq. 24): `I[y, x, l, c] += f_c · S_e(l, d)` for `l ∈ S_e.range(d)`. The derivative films
//! add `ḟ_c · S_e(l, d) + f_c · Ṡ_e(l, d) · ḋ` (Algorithm 1, last loop).

use crate::temporal::{Correlation, TimeAxis};

/// A finished transient: `data` is `[height, width, bins, channels]`, row-major, averaged
/// over samples. `steady` is the time-integrated image `[height, width, channels]` of the
/// same paths, counting every path whether or not it falls inside the time axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Transient {
    pub width: usize,
    pub height: usize,
    pub axis: TimeAxis,
    pub channels: usize,
    pub data: Vec<f32>,
    pub steady: Vec<f32>,
}

impl Transient {
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
    #[inline]
    pub fn index(&self, x: usize, y: usize, bin: usize, c: usize) -> usize {
        ((y * self.width + x) * self.axis.bins + bin) * self.channels + c
    }
    pub fn at(&self, x: usize, y: usize, bin: usize, c: usize) -> f32 {
        self.data[self.index(x, y, bin, c)]
    }
    /// Σ over time bins for one pixel and channel.
    pub fn time_sum(&self, x: usize, y: usize, c: usize) -> f32 {
        (0..self.axis.bins).map(|t| self.at(x, y, t, c)).sum()
    }
    /// Σ over pixels and channels, one value per bin (radiance over time of the whole image).
    pub fn bin_totals(&self) -> Vec<f32> {
        let mut out = vec![0.0f32; self.axis.bins];
        for px in self.data.chunks_exact(self.axis.bins * self.channels) {
            for (t, o) in out.iter_mut().enumerate() {
                for c in 0..self.channels {
                    *o += px[t * self.channels + c];
                }
            }
        }
        out
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
    pub fn scale(&mut self, s: f32) {
        self.data.iter_mut().chain(self.steady.iter_mut()).for_each(|v| *v *= s);
    }
}

/// A rectangle of pixels accumulated by one worker; merged into a [`Transient`] in a fixed
/// order, so results do not depend on the thread count or scheduling.
#[derive(Clone, Debug)]
pub struct TileFilm {
    pub x0: usize,
    pub y0: usize,
    pub w: usize,
    pub h: usize,
    bins: usize,
    channels: usize,
    /// Primal, then one block per derivative, each `[h, w, bins, channels]`.
    data: Vec<f32>,
    steady: Vec<f32>,
    derivs: usize,
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
            data: vec![0.0; n * (1 + derivs)],
            steady: vec![0.0; w * h * channels * (1 + derivs)],
            derivs,
        }
    }

    /// Empties the film and moves it to the rectangle at (x0, y0) of w × h pixels, reusing
    /// its memory (a worker renders many tiles into one film; fresh zeroed pages cost page
    /// faults on every tile).
    pub fn reset(&mut self, x0: usize, y0: usize, w: usize, h: usize) {
        let n = w * h * self.bins * self.channels * (1 + self.derivs);
        let sn = w * h * self.channels * (1 + self.derivs);
        (self.x0, self.y0, self.w, self.h) = (x0, y0, w, h);
        self.data.clear();
        self.data.resize(n, 0.0);
        self.steady.clear();
        self.steady.resize(sn, 0.0);
    }

    #[inline]
    fn block(&self) -> usize {
        self.w * self.h * self.bins * self.channels
    }

    /// Adds one path of OPL `d` with throughput `f` (per channel) to pixel (x, y) (global
    /// coordinates, inside this tile).
    #[inline]
    pub fn add(&mut self, x: usize, y: usize, corr: &Correlation, d: f32, f: &[f32]) {
        let p = (y - self.y0) * self.w + (x - self.x0);
        let c_n = self.channels;
        for c in 0..c_n {
            self.steady[p * c_n + c] += f[c];
        }
        let base = p * self.bins * c_n;
        let data = &mut self.data;
        corr.for_each(d, |bin, s, _ds| {
            let i = base + bin * c_n;
            for c in 0..c_n {
                data[i + c] += f[c] * s;
            }
        });
    }

    /// Adds one path and its derivatives in a single pass over S_e.range(d) (S_e and Ṡ_e are
    /// evaluated once for all films): `I += f·S_e(d)` and, for each parameter k,
    /// `İ_k += ḟ_k·S_e(d) + f·Ṡ_e(d)·ḋ_k` (Algorithm 1). `fdot[k*C + c]` and `ddot[k]` are the
    /// derivatives of throughput and OPL; `fdot.len() == ddot.len() * C`.
    #[inline]
    pub fn add_with_derivs(
        &mut self,
        x: usize,
        y: usize,
        corr: &Correlation,
        d: f32,
        f: &[f32],
        fdot: &[f32],
        ddot: &[f32],
    ) {
        let p = (y - self.y0) * self.w + (x - self.x0);
        let c_n = self.channels;
        let n_k = ddot.len().min(self.derivs);
        let sblock = self.w * self.h * c_n;
        for c in 0..c_n {
            self.steady[p * c_n + c] += f[c];
        }
        for k in 0..n_k {
            for c in 0..c_n {
                self.steady[sblock * (1 + k) + p * c_n + c] += fdot[k * c_n + c];
            }
        }
        let block = self.block();
        let base = p * self.bins * c_n;
        let data = &mut self.data;
        corr.for_each(d, |bin, s, ds| {
            let i = base + bin * c_n;
            for c in 0..c_n {
                data[i + c] += f[c] * s;
            }
            for k in 0..n_k {
                let ik = block * (1 + k) + i;
                for c in 0..c_n {
                    data[ik + c] += fdot[k * c_n + c] * s + f[c] * ds * ddot[k];
                }
            }
        });
    }

    /// Copies this tile into the full films (primal first, then derivatives).
    pub fn merge_into(&self, films: &mut [Transient]) {
        let row = self.w * self.bins * self.channels;
        let srow = self.w * self.channels;
        for (k, film) in films.iter_mut().enumerate().take(1 + self.derivs) {
            let off = self.block() * k;
            let soff = self.w * self.h * self.channels * k;
            for ty in 0..self.h {
                let dst = film.index(self.x0, self.y0 + ty, 0, 0);
                let src = off + ty * row;
                for (d, s) in film.data[dst..dst + row].iter_mut().zip(&self.data[src..src + row]) {
                    *d += *s;
                }
                let sdst = ((self.y0 + ty) * film.width + self.x0) * self.channels;
                let ssrc = soff + ty * srow;
                for (d, s) in film.steady[sdst..sdst + srow]
                    .iter_mut()
                    .zip(&self.steady[ssrc..ssrc + srow])
                {
                    *d += *s;
                }
            }
        }
    }
}
