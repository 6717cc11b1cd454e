//! A tile's bins while it accumulates, and which runs of them were written.
//!
//! A transient is sparse in time: a path adds to the few bins its pulse reaches, so a tile of
//! 2000 bins at a few samples per pixel writes a few percent of them. The bins keep one bit
//! per run of [`RUN`] values that was written since they were last emptied, and emptying,
//! summing, storing and adding a film touch those runs only: at 2000 bins, a tile's film is
//! megabytes, and passing over all of it once per tile cost more than tracing its paths.

/// Values per run, the unit the written bits stand for.
const RUN: usize = 16;

/// Values a word of written bits covers.
const WORD: usize = 64 * RUN;

/// A tile's bins: f64 when the film has derivative blocks (a narrow pulse's derivative adds
/// ±lobes of f·∂S_e/∂d·ḋ, with ∂S_e/∂d about 0.24/σ per metre: 8·10⁷ for σ = 3 nm, which
/// cancel over time only if no f32 rounding of the running sums breaks them), f32 for a film
/// without derivatives (a primal has no lobes; half the memory keeps the forward renderer's
/// tile in cache). The finished film is f32 either way.
#[derive(Clone, Debug)]
pub(super) struct Bins {
    values: Values,
    /// Bit r % 64 of word r / 64 is set once run r (values 16r..16r + 16) is written; every
    /// value of a run whose bit is clear is +0.
    written: Vec<u64>,
}

#[derive(Clone, Debug)]
enum Values {
    F32(Vec<f32>),
    F64(Vec<f64>),
}

/// Calls `f(a, b)` for the part [a, b) inside [lo, hi) of every run whose bit is set in
/// `written`, in order.
fn written_runs(written: &[u64], lo: usize, hi: usize, mut f: impl FnMut(usize, usize)) {
    if lo >= hi {
        return;
    }
    let end = (hi - 1) / RUN + 1;
    let mut r = lo / RUN;
    while r < end {
        let word = written[r / 64] >> (r % 64);
        if word == 0 {
            r = (r / 64 + 1) * 64;
            continue;
        }
        r += word.trailing_zeros() as usize;
        if r >= end {
            break;
        }
        f((r * RUN).max(lo), ((r + 1) * RUN).min(hi));
        r += 1;
    }
}

/// Words of written bits for `n` values.
fn words(n: usize) -> usize {
    n.div_ceil(WORD)
}

/// Words of written bits for `n` values (a checkpoint's blob stored by runs starts with them).
pub(crate) fn written_words(n: usize) -> usize {
    words(n)
}

/// A copy of `values` that reads only the runs `written` marks; the rest of it is fresh
/// zeros. With no written bits (not known, as for sums read from an earlier checkpoint) it
/// copies the runs that hold any bits ([`copy_nonzero`]).
pub(super) fn copy_written<T: bytemuck::Pod>(values: &[T], written: &[u64]) -> Vec<T> {
    let mut out = vec![T::zeroed(); values.len()];
    if written.is_empty() {
        copy_nonzero(&mut out, values);
    } else {
        written_runs(written, 0, values.len(), |a, b| {
            out[a..b].copy_from_slice(&values[a..b])
        });
    }
    out
}

/// Whether any value of `values` is not +0 (has any bit set; −0 counts): an OR over words,
/// without an early exit, which vectorises.
pub(crate) fn holds_bits<T: bytemuck::Pod>(values: &[T]) -> bool {
    let (head, words, tail) = bytemuck::pod_align_to::<u8, u64>(bytemuck::cast_slice(values));
    words.iter().fold(0u64, |a, &x| a | x) != 0 || head.iter().chain(tail).any(|&b| b != 0)
}

/// Written bits found from the values: a run is marked when it [holds bits](holds_bits).
pub(crate) fn nonzero_runs<T: bytemuck::Pod>(values: &[T]) -> Vec<u64> {
    let mut w = vec![0; words(values.len())];
    for (r, run) in values.chunks(RUN).enumerate() {
        if holds_bits(run) {
            w[r / 64] |= 1 << (r % 64);
        }
    }
    w
}

/// Calls `f` with each stretch of consecutive runs of `values` that `written` marks, in
/// order, and stops at the first error.
pub(crate) fn try_each_written<T, E>(
    values: &[T],
    written: &[u64],
    mut f: impl FnMut(&[T]) -> Result<(), E>,
) -> Result<(), E> {
    let mut stretch: Option<(usize, usize)> = None;
    let mut result = Ok(());
    written_runs(written, 0, values.len(), |a, b| {
        if result.is_err() {
            return;
        }
        match &mut stretch {
            Some((_, end)) if *end == a => *end = b,
            _ => {
                if let Some((s, e)) = stretch.replace((a, b)) {
                    result = f(&values[s..e]);
                }
            }
        }
    });
    result?;
    stretch.map_or(Ok(()), |(s, e)| f(&values[s..e]))
}

/// How many of `n` values the runs `written` marks hold, or `None` when the bits do not
/// fit `n` values (a word too many or too few, or a bit past the last run).
pub(crate) fn written_len(n: usize, written: &[u64]) -> Option<usize> {
    let runs = n.div_ceil(RUN);
    if written.len() != words(n)
        || written
            .iter()
            .enumerate()
            .any(|(k, &w)| k * 64 + 64 > runs && w >> (runs - k * 64) != 0)
    {
        return None;
    }
    let mut len = 0;
    written_runs(written, 0, n, |a, b| len += b - a);
    Some(len)
}

/// `n` values: those of the runs `written` marks taken in order from `packed`, +0 elsewhere.
/// `None` when `packed` does not hold exactly those runs' values, or when `n` values cannot
/// be allocated (they are allocated zeroed, so pages no run reaches stay untouched).
pub(crate) fn unpack_written<T: bytemuck::Pod>(n: usize, written: &[u64], packed: &[T]) -> Option<Vec<T>> {
    if written_len(n, written)? != packed.len() {
        return None;
    }
    let mut out: Vec<T> = bytemuck::allocation::try_zeroed_vec(n).ok()?;
    let mut at = 0;
    written_runs(written, 0, n, |a, b| {
        out[a..b].copy_from_slice(&packed[at..at + b - a]);
        at += b - a;
    });
    Some(out)
}

/// Copies the runs of `from` that hold any bits into `to` (of the same length), leaving the
/// other runs of `to` untouched: the pages of a fresh film that only zeros would have gone
/// to are never written.
pub(crate) fn copy_nonzero<T: bytemuck::Pod>(to: &mut [T], from: &[T]) {
    for (t, f) in to.chunks_mut(RUN).zip(from.chunks(RUN)) {
        if holds_bits(f) {
            t.copy_from_slice(f);
        }
    }
}

impl Bins {
    /// `n` zeros, f32 for a primal film (`derivs == 0`), else f64.
    pub(super) fn new(n: usize, derivs: usize) -> Self {
        let values = if derivs == 0 {
            Values::F32(vec![0.0; n])
        } else {
            Values::F64(vec![0.0; n])
        };
        Self {
            values,
            written: vec![0; words(n)],
        }
    }

    pub(super) fn len(&self) -> usize {
        match &self.values {
            Values::F32(v) => v.len(),
            Values::F64(v) => v.len(),
        }
    }

    /// Empties the bins and sizes them to `n` values, zeroing only the runs written since
    /// they were last emptied.
    pub(super) fn reset(&mut self, n: usize) {
        fn zero<T: Copy + Default>(v: &mut Vec<T>, written: &[u64], n: usize) {
            written_runs(written, 0, v.len(), |a, b| v[a..b].fill(T::default()));
            v.resize(n, T::default());
        }
        match &mut self.values {
            Values::F32(v) => zero(v, &self.written, n),
            Values::F64(v) => zero(v, &self.written, n),
        }
        self.written.clear();
        self.written.resize(words(n), 0);
    }

    /// Adds `x` to value `i`. Into a run not yet written (all +0) the value is stored,
    /// 0 + x, not added: a fresh film's page is then first touched by a write. Read first, it
    /// would be mapped to the kernel's shared zero page, and the write after it would fault
    /// again and flush the TLB of every core running the process (BDPT's splat films on a
    /// 2000-bin film spent 18 % of a 2-thread render there).
    #[inline(always)]
    pub(super) fn add(&mut self, i: usize, x: f64) {
        let (word, bit) = (i / WORD, 1u64 << ((i / RUN) % 64));
        let fresh = self.written[word] & bit == 0;
        self.written[word] |= bit;
        match &mut self.values {
            Values::F32(v) if fresh => v[i] = 0.0 + x as f32,
            Values::F64(v) if fresh => v[i] = 0.0 + x,
            Values::F32(v) => v[i] += x as f32,
            Values::F64(v) => v[i] += x,
        }
    }

    /// Calls `f(a, b)` for the part [a, b) inside [lo, hi) of every written run, in order.
    fn for_each_written(&self, lo: usize, hi: usize, f: impl FnMut(usize, usize)) {
        written_runs(&self.written, lo, hi, f)
    }

    /// Adds `len` values of `other` from `src` on into these from `dst` on (the same
    /// precision), `other`'s written runs only (x + 0 = x: the sums are those of adding all).
    pub(super) fn add_from(&mut self, dst: usize, other: &Bins, src: usize, len: usize) {
        // into a run not yet written (all +0) the values are stored, 0 + y, not added: a
        // fresh film's pages are then first touched by a write (see `store_into`)
        fn add<T: Copy + std::ops::Add<Output = T> + Default>(x: &mut [T], y: &[T], fresh: bool) {
            if fresh {
                x.iter_mut().zip(y).for_each(|(x, &y)| *x = T::default() + y);
            } else {
                x.iter_mut().zip(y).for_each(|(x, &y)| *x = *x + y);
            }
        }
        let written = &mut self.written;
        other.for_each_written(src, src + len, |a, b| {
            let to = dst + (a - src);
            // the part of [to, to + b − a) in each destination run
            let mut at = to;
            while at < to + b - a {
                let r = at / RUN;
                let end = ((r + 1) * RUN).min(to + b - a);
                let fresh = written[r / 64] & (1 << (r % 64)) == 0;
                let from = a + (at - to);
                match (&mut self.values, &other.values) {
                    (Values::F32(x), Values::F32(y)) => add(&mut x[at..end], &y[from..from + end - at], fresh),
                    (Values::F64(x), Values::F64(y)) => add(&mut x[at..end], &y[from..from + end - at], fresh),
                    _ => unreachable!("films of one render accumulate in one precision"),
                }
                written[r / 64] |= 1 << (r % 64);
                at = end;
            }
        });
    }

    /// Writes `dst.len()` values from `src` on into `dst`, which holds zeros: `dst = 0 + src`
    /// (−0 lands as +0, as an addition would leave it), written runs only. Only stores reach
    /// `dst`: a fresh film's pages are first touched by a write (one page fault, no copy of
    /// the shared zero page and no TLB flush on the other cores), and pages that only zeros
    /// would reach are never touched.
    pub(super) fn store_into(&self, dst: &mut [f32], src: usize) {
        self.for_each_written(src, src + dst.len(), |a, b| {
            let d = &mut dst[a - src..b - src];
            match &self.values {
                Values::F32(v) => d.iter_mut().zip(&v[a..b]).for_each(|(d, &s)| *d = 0.0 + s),
                Values::F64(v) => d.iter_mut().zip(&v[a..b]).for_each(|(d, &s)| *d = 0.0 + s as f32),
            }
        });
    }

    /// Σ of each consecutive block of `block` values, in f64, in index order (the sums of
    /// adding every value: the runs left out hold +0).
    pub(super) fn block_sums(&self, block: usize) -> Vec<f64> {
        (0..self.len() / block)
            .map(|k| {
                let mut sum = 0.0f64;
                self.for_each_written(k * block, (k + 1) * block, |a, b| match &self.values {
                    Values::F32(v) => v[a..b].iter().for_each(|&x| sum += x as f64),
                    Values::F64(v) => v[a..b].iter().for_each(|&x| sum += x),
                });
                sum
            })
            .collect()
    }

    /// The values as (f32, f64) vectors, one of them empty, and the written bits.
    pub(super) fn to_parts(&self) -> (Vec<f32>, Vec<f64>, Vec<u64>) {
        match &self.values {
            Values::F32(v) => (v.clone(), Vec::new(), self.written.clone()),
            Values::F64(v) => (Vec::new(), v.clone(), self.written.clone()),
        }
    }

    /// Moves the values and written bits out, leaving no values.
    pub(super) fn take_parts(&mut self) -> (Vec<f32>, Vec<f64>, Vec<u64>) {
        let written = std::mem::take(&mut self.written);
        match &mut self.values {
            Values::F32(v) => (std::mem::take(v), Vec::new(), written),
            Values::F64(v) => (Vec::new(), std::mem::take(v), written),
        }
    }

    /// Puts back `n` values of this precision (the other vector empty) with their written
    /// bits, or finds the bits from the values when `written` does not fit them (sums read
    /// from a checkpoint). `false`, and nothing changed, for values of another size or
    /// precision.
    pub(super) fn restore(&mut self, n: usize, data32: Vec<f32>, data64: Vec<f64>, written: Vec<u64>) -> bool {
        let fits = written.len() == words(n);
        match &mut self.values {
            Values::F32(v) if data32.len() == n && data64.is_empty() => {
                self.written = if fits { written } else { nonzero_runs(&data32) };
                *v = data32;
            }
            Values::F64(v) if data64.len() == n && data32.is_empty() => {
                self.written = if fits { written } else { nonzero_runs(&data64) };
                *v = data64;
            }
            _ => return false,
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Sparse adds at pseudo-random places (some runs of 16 untouched, some straddled).
    fn filled(n: usize, derivs: usize, key: u64) -> (Bins, Vec<f64>) {
        let mut bins = Bins::new(n, derivs);
        let mut want = vec![0.0f64; n];
        for j in 0..n as u64 / 7 {
            let u = crate::kernel::hash_to_unit(key ^ (j * 2 + 1)) as f64;
            let i = (crate::kernel::hash_to_unit(key ^ (j * 2)) as f64 * n as f64) as usize % n;
            let x = u - 0.3;
            bins.add(i, x);
            want[i] = if derivs == 0 {
                (want[i] as f32 + x as f32) as f64
            } else {
                want[i] + x
            };
        }
        (bins, want)
    }

    fn values(b: &Bins) -> Vec<f64> {
        match &b.values {
            Values::F32(v) => v.iter().map(|&x| x as f64).collect(),
            Values::F64(v) => v.clone(),
        }
    }

    /// A copy by written runs has every value's bits, with the bits known or not.
    #[test]
    fn copies_by_written_runs_have_every_value() {
        for derivs in [0, 2] {
            for n in [997, 4096, 1] {
                let (bins, _) = filled(n, derivs, 5 + n as u64);
                let (d32, d64, written) = bins.to_parts();
                assert!(written.iter().any(|&w| w != 0) || n < 7);
                for known in [&written[..], &[]] {
                    let (c32, c64) = (copy_written(&d32, known), copy_written(&d64, known));
                    assert!(c32.iter().map(|v| v.to_bits()).eq(d32.iter().map(|v| v.to_bits())));
                    assert!(c64.iter().map(|v| v.to_bits()).eq(d64.iter().map(|v| v.to_bits())));
                }
            }
        }
    }

    /// Emptying, summing, storing and adding by written runs give what the same operations
    /// over every value give, for film sizes that are and are not multiples of a run.
    #[test]
    fn written_runs_stand_for_every_value() {
        for derivs in [0, 2] {
            for (n, block) in [(997, 331), (4096, 1024), (40, 40), (1, 1)] {
                let (bins, want) = filled(n, derivs, n as u64 * 31 + derivs as u64);
                assert_eq!(values(&bins), want);
                // block sums, in index order
                let sums: Vec<f64> = want
                    .chunks_exact(block)
                    .map(|b| b.iter().fold(0.0, |s, &x| s + x))
                    .collect();
                assert_eq!(bins.block_sums(block), sums, "n {n}, derivs {derivs}");
                // storing a range into zeros
                let (lo, len) = (n / 5, n - n / 5 - n / 7);
                let mut dst = vec![0.0f32; len];
                bins.store_into(&mut dst, lo);
                let stored: Vec<f32> = want[lo..lo + len].iter().map(|&x| 0.0 + x as f32).collect();
                assert_eq!(dst, stored);
                // adding a range of another film at an offset
                let (other, other_want) = filled(n, derivs, 77 + n as u64);
                let mut sum = bins.clone();
                let dst_at = n / 3;
                let len2 = (n - dst_at).min(n - lo);
                sum.add_from(dst_at, &other, lo, len2);
                let mut added = want.clone();
                for t in 0..len2 {
                    added[dst_at + t] = if derivs == 0 {
                        (added[dst_at + t] as f32 + other_want[lo + t] as f32) as f64
                    } else {
                        added[dst_at + t] + other_want[lo + t]
                    };
                }
                assert_eq!(values(&sum), added);
                // and what add_from wrote is written: storing it all shows it
                let mut all = vec![0.0f32; n];
                sum.store_into(&mut all, 0);
                assert_eq!(all, added.iter().map(|&x| x as f32).collect::<Vec<_>>());
                // emptying leaves zeros, at a smaller and at a larger size
                for m in [n / 2 + 1, 2 * n] {
                    let mut b = sum.clone();
                    b.reset(m);
                    assert_eq!(b.len(), m);
                    assert!(values(&b).iter().all(|&x| x.to_bits() == 0), "n {n} → {m}");
                    assert!(b.written.iter().all(|&w| w == 0));
                }
                // restored from values alone, the written runs are found again
                let (d32, d64, _) = sum.to_parts();
                let mut back = Bins::new(n, derivs);
                assert!(back.restore(n, d32, d64, Vec::new()));
                let mut again = vec![0.0f32; n];
                back.store_into(&mut again, 0);
                assert_eq!(again, all);
                back.reset(n);
                assert!(values(&back).iter().all(|&x| x.to_bits() == 0));
            }
        }
    }
}
