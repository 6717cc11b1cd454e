//! Shards: one render split into disjoint sample ranges that run apart (other processes,
//! other machines, the tasks of a Slurm job array) and add up to the whole render.
//!
//! Every path's random numbers depend only on its pixel and sample index (path id =
//! pixel · spp + s, [`crate::integrator::path::PacketLanes::row`]), and every boundary
//! sample's only on its own index, so shard I of N traces exactly the paths the whole render
//! traces for samples `[I·n/N, (I+1)·n/N)` of each estimator (n = spp for the interior, the
//! boundary sample count for the primary and secondary edges). Each shard normalises by the
//! whole render's sample counts, so the shards' films *sum* to the render's: `dtr merge`
//! adds them. Only the order of the floating-point additions differs from one process
//! rendering everything (see `cli::merge` for the bound).

use crate::error::Error;
use std::ops::Range;

/// Shard `index` of `count` (0-based). [`Shard::WHOLE`] is the whole render.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct Shard {
    /// This shard's number, 0-based, `< count`.
    pub index: u32,
    /// How many shards the render is split into (≥ 1).
    pub count: u32,
}

impl Default for Shard {
    fn default() -> Self {
        Self::WHOLE
    }
}

impl Shard {
    /// The whole render: one shard of one.
    pub const WHOLE: Shard = Shard { index: 0, count: 1 };

    /// Shard `index` of `count`; refuses `count = 0` and `index ≥ count`.
    pub fn new(index: u32, count: u32) -> Result<Self, Error> {
        if count == 0 || index >= count {
            return Err(Error::Invalid(format!(
                "shard {index}/{count}: expected I/N with N ≥ 1 and 0 ≤ I < N (shards are numbered from 0)"
            )));
        }
        Ok(Self { index, count })
    }

    /// Parses `I/N` (as `--shard` and Slurm's `$SLURM_ARRAY_TASK_ID/$N` give it).
    pub fn parse(s: &str) -> Result<Self, Error> {
        let bad = || {
            Error::Invalid(format!(
                "--shard {s:?}: expected I/N, two integers with 0 ≤ I < N (e.g. 0/4)"
            ))
        };
        let (i, n) = s.split_once('/').ok_or_else(bad)?;
        let i: u32 = i.trim().parse().map_err(|_| bad())?;
        let n: u32 = n.trim().parse().map_err(|_| bad())?;
        Self::new(i, n)
    }

    /// Whether this is the whole render (one shard of one).
    pub fn is_whole(&self) -> bool {
        self.count == 1
    }

    /// This shard's part of the sample indices `0..total`: `[I·total/N, (I+1)·total/N)`.
    /// The parts of shards 0..N are disjoint and cover `0..total` (some are empty when
    /// `total < N`).
    pub fn range(&self, total: u64) -> Range<u64> {
        let at = |i: u32| (total as u128 * i as u128 / self.count as u128) as u64;
        at(self.index)..at(self.index + 1)
    }
}

impl std::fmt::Display for Shard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

/// Adds the films of the shards of one render, in the order given, in f64 (one rounding to
/// f32 per value): `dtr merge`. Refuses films of different shapes or time axes.
pub fn add_films(films: &[&crate::film::Transient]) -> Result<crate::film::Transient, Error> {
    let first = films.first().ok_or_else(|| Error::Invalid("no films to add".into()))?;
    let mut sum = FilmSum::like(first);
    for (i, f) in films.iter().enumerate() {
        sum.add(i, f)?;
    }
    Ok(sum.finish())
}

/// A running sum of shard films, film by film in the order they come, in f64: the bytes of
/// [`add_films`] with one film in memory at a time (`dtr merge` reads each shard, adds it and
/// lets it go, so merging N shards of a 1.5 GB film needs one film's memory, not N).
pub struct FilmSum {
    data: Vec<f64>,
    steady: Vec<f64>,
    shape: [usize; 4],
    axis: crate::temporal::TimeAxis,
}

impl FilmSum {
    /// Zero, for films of `first`'s shape and time axis.
    pub fn like(first: &crate::film::Transient) -> Self {
        Self {
            data: vec![0.0; first.data.len()],
            steady: vec![0.0; first.steady.len()],
            shape: first.shape(),
            axis: first.axis,
        }
    }

    /// Adds film number `i` (for the message), refusing one of another shape or time axis.
    pub fn add(&mut self, i: usize, f: &crate::film::Transient) -> Result<(), Error> {
        if f.shape() != self.shape || f.axis != self.axis || f.steady.len() != self.steady.len() {
            return Err(Error::Invalid(format!(
                "film {i} has shape {:?} (time axis {:?}), film 0 has {:?} ({:?}): not shards of one render",
                f.shape(),
                f.axis,
                self.shape,
                self.axis
            )));
        }
        self.data.iter_mut().zip(&f.data).for_each(|(a, &b)| *a += b as f64);
        self.steady.iter_mut().zip(&f.steady).for_each(|(a, &b)| *a += b as f64);
        Ok(())
    }

    /// The sum, rounded to f32.
    pub fn finish(self) -> crate::film::Transient {
        let [h, w, _, c] = self.shape;
        let mut out = crate::film::Transient::zeros(w, h, self.axis, c);
        out.data.iter_mut().zip(&self.data).for_each(|(o, &v)| *o = v as f32);
        out.steady
            .iter_mut()
            .zip(&self.steady)
            .for_each(|(o, &v)| *o = v as f32);
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ranges_are_disjoint_and_cover_everything() {
        for total in [0u64, 1, 3, 7, 64, 1000, u64::MAX / 3] {
            for count in [1u32, 2, 3, 4, 7, 16] {
                let mut next = 0;
                for index in 0..count {
                    let r = Shard::new(index, count).unwrap().range(total);
                    assert_eq!(r.start, next, "total {total}, shard {index}/{count}");
                    assert!(r.end >= r.start);
                    next = r.end;
                }
                assert_eq!(next, total);
            }
        }
    }

    #[test]
    fn parse_accepts_i_of_n_and_refuses_the_rest() {
        assert_eq!(Shard::parse("2/4").unwrap(), Shard { index: 2, count: 4 });
        assert_eq!(Shard::parse(" 0 / 1 ").unwrap(), Shard::WHOLE);
        for bad in ["4/4", "1/0", "-1/3", "1", "a/b", "1/2/3", ""] {
            let e = Shard::parse(bad).unwrap_err().to_string();
            assert!(e.contains("I/N"), "{bad}: {e}");
        }
    }
}
