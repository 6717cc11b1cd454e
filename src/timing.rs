//! A cheap cycle counter for per-phase timers (tracing, shading, film). Phases are reported
//! as fractions of the measured CPU time, so the counter's unit never matters.

/// A monotonic tick count: the time-stamp counter on x86_64 (a few ns per read), elsewhere
/// nanoseconds since the first call.
#[inline(always)]
pub fn ticks() -> u64 {
    #[cfg(target_arch = "x86_64")]
    {
        // SAFETY: rdtsc has no preconditions; it reads the time-stamp counter.
        unsafe { core::arch::x86_64::_rdtsc() }
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        use std::sync::OnceLock;
        use std::time::Instant;
        static START: OnceLock<Instant> = OnceLock::new();
        START.get_or_init(Instant::now).elapsed().as_nanos() as u64
    }
}

/// Reads of the counter per timed call: one call in `SAMPLED_EVERY` of a phase, on average, is
/// timed, and its ticks count for all of them. A read costs tens of cycles, and the tracing
/// and film phases are entered several times per packet and bounce: reading the counter on
/// every call took 5 % of a Cornell-box render (`benches/ab/render_ab.sh`, 2026-11-28). The
/// timed calls are drawn at random (a xorshift per clock, the same every run), not every
/// 16th: calls of different cost come in fixed patterns (a closest-hit query, then a shadow
/// ray, at every bounce), which a fixed period would sample unevenly.
pub const SAMPLED_EVERY: u64 = 16;

/// A timed call longer than this many ticks (about a millisecond at the counter's GHz
/// rates) was descheduled or interrupted part of the way: a preemption, not work (an Embree
/// packet query or a film deposit takes microseconds). Counted [`SAMPLED_EVERY`] times over,
/// one 4 ms preemption put 89 ms of tracing into a 58 ms render on a loaded 2-core machine
/// (tests/cli_json.rs in a CI rehearsal, 2026-11-28). Such a reading is dropped, and the
/// next call is timed in its place.
pub const PREEMPTED_TICKS: u64 = 1 << 22;

/// A phase's timer that reads the counter on one call in [`SAMPLED_EVERY`], on average.
#[derive(Clone, Copy, Debug)]
pub struct SampledClock {
    state: u32,
    /// The last timed call was preempted ([`PREEMPTED_TICKS`]): time the next one.
    retry: bool,
}

impl Default for SampledClock {
    fn default() -> Self {
        Self {
            state: 0x9E37_79B9,
            retry: false,
        }
    }
}

impl SampledClock {
    /// Starts a call: the counter when this call is one of the timed ones.
    #[inline(always)]
    pub fn start(&mut self) -> Option<u64> {
        // xorshift32 (Marsaglia 2003): a full period over the nonzero states
        let mut x = self.state;
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        self.state = x;
        let timed = (x as u64).is_multiple_of(SAMPLED_EVERY) || self.retry;
        self.retry = false;
        timed.then(ticks)
    }

    /// Ends a call begun with [`Self::start`]: its ticks, scaled to the calls it stands for;
    /// 0 for a call that was not timed, or that was preempted (then the next call is timed).
    #[inline(always)]
    pub fn stop(&mut self, start: Option<u64>) -> u64 {
        let Some(t0) = start else {
            return 0;
        };
        let spent = ticks().wrapping_sub(t0);
        if spent > PREEMPTED_TICKS {
            self.retry = true;
            return 0;
        }
        spent * SAMPLED_EVERY
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// About one call in `SAMPLED_EVERY` is timed, and calls that alternate (two kinds of
    /// query, in turn) are timed alike: a fixed period of 16 timed only one of the two.
    #[test]
    fn one_call_in_sampled_every_reads_the_counter_and_stands_for_them_all() {
        let mut clock = SampledClock::default();
        let n = 160_000;
        let timed: Vec<bool> = (0..n).map(|_| clock.start().is_some()).collect();
        let (even, odd) = timed.iter().enumerate().fold((0, 0), |(e, o), (i, &t)| {
            if !t {
                (e, o)
            } else if i % 2 == 0 {
                (e + 1, o)
            } else {
                (e, o + 1)
            }
        });
        let expected = n as f64 / SAMPLED_EVERY as f64;
        // binomial: sd ≈ √(n/16) = 100
        assert!(((even + odd) as f64 - expected).abs() < 500.0, "{even} + {odd} of {n}");
        assert!(((even as f64) - expected / 2.0).abs() < 400.0, "{even} even, {odd} odd");
        assert_eq!(clock.stop(None), 0);
        let spent = clock.stop(Some(ticks()));
        assert_eq!(spent % SAMPLED_EVERY, 0);
    }

    /// A timed call that took longer than a preemption's worth of ticks counts nothing, and
    /// the next call is timed in its place (one 4 ms preemption counted 16 times over made
    /// tracing outweigh a whole render's CPU time).
    #[test]
    fn a_preempted_call_is_dropped_and_the_next_one_timed() {
        let mut clock = SampledClock::default();
        let t0 = loop {
            if let Some(t0) = clock.start() {
                break t0;
            }
        };
        assert!(clock.stop(Some(t0)) < PREEMPTED_TICKS * SAMPLED_EVERY);
        let long_ago = ticks().wrapping_sub(2 * PREEMPTED_TICKS);
        assert_eq!(clock.stop(Some(long_ago)), 0, "a preempted call counted");
        assert!(clock.start().is_some(), "the next call is not timed");
        // and then the clock draws as before: about one call in SAMPLED_EVERY
        let timed = (0..16_000).filter(|_| clock.start().is_some()).count();
        assert!((800..1200).contains(&timed), "{timed} of 16000 timed");
    }
}
