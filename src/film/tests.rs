//! Unit tests of the derivative deposits of tile films (`TileFilm::add_with_derivs`,
//! Algorithm 1: İ_k += ḟ_k·S_e + f·Ṡ_e·ḋ_k) against the primal binning (`TileFilm::add`),
//! and the sparse copy of a `Transient`.

use super::*;
use crate::temporal::{Gate, Pulse};

const C: usize = 3;

/// One path of a derivative render: pixel, OPL, throughput and, per parameter k, ḟ_k and ḋ_k.
struct Path {
    x: usize,
    y: usize,
    d: f64,
    f: [f32; C],
    fdot: [[f32; C]; 2],
    ddot: [f32; 2],
}

/// A 2 × 1 tile at (3, 5) of a 6 × 7 film.
fn tile(axis: &TimeAxis, derivs: usize, steady: SteadyMode) -> TileFilm {
    TileFilm::new(3, 5, 2, 1, axis, C, derivs).with_steady(steady)
}

fn deposit(film: &mut TileFilm, corr: &Correlation, p: &Path) {
    let fdot: Vec<f32> = p.fdot.iter().flatten().copied().collect();
    film.add_with_derivs(p.x, p.y, corr, p.d, &p.f, &fdot, &p.ddot);
}

/// Central differences of the primal binning against the derivative blocks, for three
/// smooth S_e (Gaussian pulse with box and Gaussian gates, box pulse with a Gaussian gate),
/// both steady modes, two parameters and three channels. Each side of the difference bins
/// the paths with f ± h·ḟ_k and d ± h·ḋ_k through `add` into a film with f64 bins. h = 2⁻¹⁴
/// and ḟ, f are multiples of 2⁻⁸, so f ± h·ḟ is exact in f32 and the throughput part of the
/// difference is exact; the OPL moves by at most 1.5·h ≈ 9·10⁻⁵ m against an S_e width of at
/// least 0.015 m, a truncation error of (9·10⁻⁵/0.015)²/6 ≈ 6·10⁻⁶ of the lobes (f64 rounding
/// adds 10⁻¹⁶/h ≈ 10⁻¹²): the tolerance is 10⁻⁴ of the largest derivative bin.
///
/// Bugs caught: a missing ḟ·S_e or f·Ṡ_e·ḋ term, Ṡ_e with the wrong sign, ḟ indexed as
/// `c * K + k` instead of `k * C + c`, a derivative block written at the wrong offset, the
/// steady derivative (all-time: Σḟ; window: Σ_l of the bins) not matching its bins, and
/// derivative blocks merged into the wrong film or pixel.
#[test]
fn derivative_bins_match_central_differences_of_the_primal_binning() {
    let axis = TimeAxis {
        start_opl: 2.0,
        bin_width_opl: 0.02,
        bins: 64,
    };
    let paths = [
        Path {
            x: 4,
            y: 5,
            d: 2.41,
            f: [0.75, 0.5, 0.25],
            fdot: [[0.5, -0.25, 1.5], [0.0, 0.125, -0.75]],
            ddot: [1.25, -0.5],
        },
        Path {
            x: 3,
            y: 5,
            d: 2.63,
            f: [0.375, 1.25, 0.5],
            fdot: [[-1.0, 0.75, 0.0], [0.25, 0.5, 0.625]],
            ddot: [-1.5, 0.75],
        },
        Path {
            x: 4,
            y: 5,
            d: 2.478,
            f: [1.0, 0.625, 0.875],
            fdot: [[0.0, 0.0, 0.25], [-0.5, 1.0, 0.375]],
            ddot: [0.5, 1.0],
        },
    ];
    let h = 1.0 / 16384.0;
    let block = 2 * axis.bins * C;
    let sblock = 2 * C;
    let shapes = [
        (Pulse::Gaussian { sigma_opl: 0.03 }, Gate::Box),
        (Pulse::Gaussian { sigma_opl: 0.02 }, Gate::Gaussian { sigma_opl: 0.015 }),
        (Pulse::Box { width_opl: 0.1 }, Gate::Gaussian { sigma_opl: 0.02 }),
    ];
    for (pulse, gate) in shapes {
        let corr = Correlation::new(axis, pulse, 0.0, gate).unwrap();
        for mode in [SteadyMode::Full, SteadyMode::Window] {
            let mut film = tile(&axis, 2, mode);
            paths.iter().for_each(|p| deposit(&mut film, &corr, p));
            let got = film.sums();
            // the primal block is the primal binning's, to the bit
            let mut primal = tile(&axis, 1, mode);
            paths.iter().for_each(|p| primal.add(p.x, p.y, &corr, p.d, &p.f));
            let want = primal.sums();
            assert_eq!(
                got.data64[..block],
                want.data64[..block],
                "{pulse:?} {gate:?} {mode:?}: primal"
            );
            assert_eq!(
                got.steady[..sblock],
                want.steady[..sblock],
                "{pulse:?} {gate:?} {mode:?}: steady"
            );
            for k in 0..2 {
                let side = |s: f64| {
                    let mut film = tile(&axis, 1, mode);
                    for p in &paths {
                        let f: [f32; C] = std::array::from_fn(|c| p.f[c] + (s * h) as f32 * p.fdot[k][c]);
                        film.add(p.x, p.y, &corr, p.d + s * h * p.ddot[k] as f64, &f);
                    }
                    film.sums()
                };
                let (plus, minus) = (side(1.0), side(-1.0));
                let fd =
                    |a: &[f64], b: &[f64]| -> Vec<f64> { a.iter().zip(b).map(|(p, m)| (p - m) / (2.0 * h)).collect() };
                let bins = &got.data64[block * (1 + k)..block * (2 + k)];
                let steady = &got.steady[sblock * (1 + k)..sblock * (2 + k)];
                let pairs = [
                    ("bins", bins, fd(&plus.data64[..block], &minus.data64[..block])),
                    ("steady", steady, fd(&plus.steady[..sblock], &minus.steady[..sblock])),
                ];
                for (what, got, want) in pairs {
                    let scale = want.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    assert!(scale > 0.1, "{what}: the paths should reach the film");
                    for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                        assert!(
                            (g - w).abs() <= 1e-4 * scale,
                            "{pulse:?} {gate:?} {mode:?}, param {k}, {what}[{i}]: {g} vs central difference {w}"
                        );
                    }
                }
            }
            // merged: block k lands in film k, at the tile's pixels
            let mut films = vec![Transient::zeros(6, 7, axis, C); 3];
            film.store_into(&mut films);
            for (k, t) in films.iter().enumerate() {
                for (px, x) in [3, 4].into_iter().enumerate() {
                    for l in 0..axis.bins {
                        for c in 0..C {
                            let v = got.data64[block * k + (px * axis.bins + l) * C + c];
                            assert_eq!(t.at(x, 5, l, c), v as f32, "film {k}, pixel {x}, bin {l}, channel {c}");
                        }
                    }
                }
                let total: f32 = t.data.iter().map(|v| v.abs()).sum();
                let tile_total: f32 = (0..2 * axis.bins * C)
                    .map(|i| (got.data64[block * k + i] as f32).abs())
                    .sum();
                assert!(
                    (total - tile_total).abs() <= 1e-5 * tile_total,
                    "film {k}: bins outside the tile"
                );
            }
        }
    }
}

/// A 3 nm Gaussian pulse with 4 nm bins: one path's f·Ṡ_e·ḋ lobes are about ±10⁸ per bin and
/// cancel over time (Σ_l Ṡ_e = 0 when the pulse lies inside the window), so the time sum of a
/// derivative block is ḟ·Σ_l S_e = ḟ per path. 1000 paths moving in time (ḋ = 1, ḟ = 2⁻³)
/// are deposited; their time sum, taken from the f64 bins (`block_sums`), must be 1000·ḟ to
/// 10⁻¹² of Σ|İ| (f64 rounding of sums of 10¹¹: ~10⁻¹⁶ each). Bins kept in f32 round every
/// running sum to ~10⁻⁷ of it, and the sum misses by ~10⁴ (~10⁻⁷ of Σ|İ|).
///
/// Bugs caught: derivative bins accumulated in f32, and a Ṡ_e whose lobes do not cancel.
#[test]
fn narrow_pulse_derivative_lobes_cancel_over_time() {
    let axis = TimeAxis {
        start_opl: 3.0,
        bin_width_opl: 4e-9,
        bins: 64,
    };
    let corr = Correlation::new(axis, Pulse::Gaussian { sigma_opl: 3e-9 }, 0.0, Gate::Box).unwrap();
    let mut film = TileFilm::new(0, 0, 1, 1, &axis, 1, 1);
    let (n, f, fdot) = (1000, 0.6f32, 0.125f32);
    // Σ_l |İ_l| of the paths and the largest |İ_l|, from S_e itself (not from the film)
    let (mut mass, mut peak) = (0.0f64, 0.0f64);
    for i in 0..n {
        // arrivals spread over the middle 100 nm of the 256 nm window (8σ = 24 nm inside)
        let d = 3.0 + 78e-9 + 1e-10 * i as f64;
        film.add_with_derivs(0, 0, &corr, d, &[f], &[fdot], &[1.0]);
        corr.for_each(d, |_, s, ds| {
            let v = (fdot as f64 * s + f as f64 * ds).abs();
            mass += v;
            peak = peak.max(v);
        });
    }
    assert!(peak > 1e7, "the lobes should be large: peak {peak}");
    let time_sum = film.block_sums()[1];
    let want = n as f64 * fdot as f64;
    assert!(
        (time_sum - want).abs() <= 1e-12 * mass,
        "time sum of the derivative {time_sum} vs {want} (Σ|İ| = {mass:.3e})"
    );
    // the all-time steady derivative is Σḟ, exactly
    assert_eq!(film.sums().steady[1], want);
}

/// `store_into` writes the bytes that adding the tile to the film's zeros would (−0 becomes
/// +0, runs of zeros stay zero), at the tile's pixels only, for both precisions.
#[test]
fn storing_a_tile_writes_what_adding_it_to_zeros_would() {
    let axis = axis_of(37);
    let (x0, y0, w, h, c) = (1, 2, 3, 2, 2);
    for derivs in [0, 1] {
        let n = w * h * axis.bins * c * (1 + derivs);
        // sparse values, a few of them −0, with runs of zeros longer than 16
        let value = |i: usize| match i % 41 {
            0 | 7 => -0.0,
            1..=4 => i as f64 * 0.25 - 30.0,
            _ => 0.0,
        };
        let mut film = TileFilm::new(x0, y0, w, h, &axis, c, derivs);
        let (data32, data64) = if derivs == 0 {
            ((0..n).map(|i| value(i) as f32).collect(), Vec::new())
        } else {
            (Vec::new(), (0..n).map(value).collect())
        };
        let steady: Vec<f64> = (0..w * h * c * (1 + derivs)).map(|i| value(i + 3)).collect();
        film.restore(TileSums {
            data32,
            data64,
            written: Vec::new(),
            steady: steady.clone(),
            tails: [0.0; 2],
        })
        .unwrap();
        let mut got = vec![Transient::zeros(5, 4, axis, c); 1 + derivs];
        film.store_into(&mut got);
        for (k, t) in got.iter().enumerate() {
            let mut want = Transient::zeros(5, 4, axis, c);
            for ty in 0..h {
                for tx in 0..w {
                    for l in 0..axis.bins {
                        for ch in 0..c {
                            let i = k * (n / (1 + derivs)) + ((ty * w + tx) * axis.bins + l) * c + ch;
                            let j = want.index(x0 + tx, y0 + ty, l, ch);
                            want.data[j] += value(i) as f32;
                        }
                    }
                    for ch in 0..c {
                        let s = steady[k * w * h * c + (ty * w + tx) * c + ch] as f32;
                        want.steady[((y0 + ty) * 5 + x0 + tx) * c + ch] += s;
                    }
                }
            }
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&t.data), bits(&want.data), "derivs {derivs}, film {k}");
            assert_eq!(bits(&t.steady), bits(&want.steady), "derivs {derivs}, film {k} steady");
            assert!(t.data.iter().any(|&v| v != 0.0));
        }
    }
}

/// `bins` bins of 0.1 m from 0.
fn axis_of(bins: usize) -> TimeAxis {
    TimeAxis {
        start_opl: 0.0,
        bin_width_opl: 0.1,
        bins,
    }
}

/// `Transient::scale` gives the bits of multiplying every value, though it leaves runs of
/// zeros unwritten for a positive factor (and a negative one still turns +0 into −0).
#[test]
fn scaling_skips_zero_runs_without_changing_a_bit() {
    let axis = axis_of(50);
    let mut t = Transient::zeros(3, 2, axis, 3);
    for (i, v) in t.data.iter_mut().enumerate() {
        *v = match i % 97 {
            0 => -0.0,
            1..=6 => i as f32 * 0.37 - 20.0,
            _ => 0.0,
        };
    }
    t.steady
        .iter_mut()
        .enumerate()
        .for_each(|(i, v)| *v = (i % 3) as f32 - 1.0);
    for s in [0.25f32, 1.0 / 3.0, -2.0] {
        let mut got = t.clone();
        got.scale(s);
        let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let want: Vec<f32> = t.data.iter().map(|v| v * s).collect();
        let want_steady: Vec<f32> = t.steady.iter().map(|v| v * s).collect();
        assert_eq!(bits(&got.data), bits(&want), "factor {s}");
        assert_eq!(bits(&got.steady), bits(&want_steady), "factor {s}");
    }
}

/// A clone writes only the runs that hold bits, and is the film to the bit: −0, values at the
/// edges of runs, a dense stretch and the steady image.
#[test]
fn a_clone_is_the_film_to_the_bit() {
    let axis = axis_of(333);
    let mut t = Transient::zeros(5, 3, axis, 3);
    let n = t.data.len();
    for (i, v) in t.data.iter_mut().enumerate() {
        *v = match i % 97 {
            0 => -0.0,
            15 | 16 => i as f32,
            _ if i > n - 40 => -(i as f32),
            _ => 0.0,
        };
    }
    t.steady.iter_mut().enumerate().for_each(|(i, v)| *v = i as f32 - 2.0);
    let c = t.clone();
    let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&c.data), bits(&t.data));
    assert_eq!(bits(&c.steady), bits(&t.steady));
    assert_eq!(
        (c.width, c.height, c.axis, c.channels),
        (t.width, t.height, t.axis, t.channels)
    );
}

/// The preview's sums over pixels and channels are taken in f64: finite values near the top of
/// f32 add up to a finite total (in f32 it was +∞, and the time plot refused to write).
#[test]
fn totals_for_the_preview_stay_finite_where_f32_sums_overflow() {
    let axis = TimeAxis {
        start_opl: 0.0,
        bin_width_opl: 0.1,
        bins: 2,
    };
    let mut t = Transient::zeros(2, 2, axis, 3);
    t.data.iter_mut().for_each(|v| *v = 3e38);
    assert!(t.bin_totals().iter().all(|v| v.is_infinite()), "the f32 sums overflow");
    let want = 3e38f32 as f64 * 12.0;
    assert_eq!(t.bin_totals_f64(), vec![want; 2]);
    assert_eq!(t.pixel_series_f64(1, 1), vec![3e38f32 as f64 * 3.0; 2]);
}
