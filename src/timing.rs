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

/// Reads of the counter per timed call: one call in `SAMPLED_EVERY` of a phase is timed, and
/// its ticks count for all of them. A read costs tens of cycles, and the tracing and film
/// phases are entered several times per packet and bounce: reading the counter on every
/// call took 5 % of a Cornell-box render (`benches/ab/render_ab.sh`, 2026-11-28). The calls
/// a phase makes are alike and the timed ones are spread evenly over them, so the phase's
/// share of the ticks comes out the same up to sampling noise.
pub const SAMPLED_EVERY: u64 = 16;

/// A phase's timer that reads the counter on one call in [`SAMPLED_EVERY`].
#[derive(Clone, Copy, Debug, Default)]
pub struct SampledClock {
    calls: u64,
}

impl SampledClock {
    /// Starts a call: the counter when this call is one of the timed ones.
    #[inline(always)]
    pub fn start(&mut self) -> Option<u64> {
        self.calls = self.calls.wrapping_add(1);
        self.calls.is_multiple_of(SAMPLED_EVERY).then(ticks)
    }
}

/// Ends a call begun with [`SampledClock::start`]: its ticks, scaled to the calls it stands
/// for, or 0 for a call that was not timed.
#[inline(always)]
pub fn sampled_ticks(start: Option<u64>) -> u64 {
    start.map_or(0, |t0| ticks().wrapping_sub(t0) * SAMPLED_EVERY)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_call_in_sampled_every_reads_the_counter_and_stands_for_them_all() {
        let mut clock = SampledClock::default();
        let timed: Vec<bool> = (0..3 * SAMPLED_EVERY).map(|_| clock.start().is_some()).collect();
        assert_eq!(timed.iter().filter(|&&t| t).count(), 3);
        assert!(
            timed
                .chunks(SAMPLED_EVERY as usize)
                .all(|c| c.iter().filter(|&&t| t).count() == 1)
        );
        assert_eq!(sampled_ticks(None), 0);
        let t0 = ticks();
        let spent = sampled_ticks(Some(t0));
        assert_eq!(spent % SAMPLED_EVERY, 0);
    }
}
