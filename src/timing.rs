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
