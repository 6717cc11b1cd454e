//! Intel Embree 3 behind a narrow, safe interface. This is the only module that talks to
//! Embree; a later move to Embree 4 stays here (the differences are listed in [`ffi`]).
//!
//! - [`Device`] and [`Accel`] release their Embree objects on drop. An [`Accel`] keeps its own
//!   device reference, so it has no lifetime parameter.
//! - Queries return plain hits `(t, primitive, u, v)`; the integrator rebuilds surface points
//!   from the mesh. Embree never sees dual numbers.
//! - 8-wide packets ([`Ray8`], [`Hit8`]) and valid masks ([`Valid8`]) are 32-byte aligned;
//!   masks are `i32` -1 (active) / 0 (inactive). Embree leaves inactive lanes untouched, so
//!   we report them as misses. Ray masks are always all-ones (a zero mask misses everything).
//! - Invalid rays (non-finite origin or direction, `tnear < 0`, `tnear > tfar`) are reported
//!   as misses and never reach Embree.
//! - A committed [`Accel`] may be queried from many threads at once (`Send + Sync`).
//! - Call [`set_flush_denormals`] on every thread that traces (rayon's `start_handler`).
//!
//! Nothing here panics on bad input; mesh and device problems are [`AccelError`]s.

mod device;
pub mod ffi;
mod packet;
mod scene;

pub use device::{AccelError, Device, error_name};
pub use packet::{Hit, Hit8, Ray8, Valid8};
pub use scene::{Accel, BuildQuality};

const MXCSR_FTZ: u32 = 1 << 15;
const MXCSR_DAZ: u32 = 1 << 6;

/// Sets flush-to-zero and denormals-are-zero in MXCSR for the **calling thread only**.
///
/// Embree's traversal is slower with denormals, and its verbose mode warns when these bits are
/// off. MXCSR is per thread, so rendering code must call this on every worker that traces
/// rays, e.g. `rayon::ThreadPoolBuilder::new().start_handler(|_| set_flush_denormals())`,
/// and on the main thread if it traces too. A no-op on targets other than x86_64.
///
/// Note that it changes float semantics of all code on that thread (denormal inputs and
/// results become zero).
pub fn set_flush_denormals() {
    #[cfg(target_arch = "x86_64")]
    {
        let mut csr: u32 = 0;
        // SAFETY: stmxcsr/ldmxcsr only read and write this thread's SSE control register; we
        // set two mode bits and keep the rest.
        unsafe {
            std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack));
            csr |= MXCSR_FTZ | MXCSR_DAZ;
            std::arch::asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack, readonly));
        }
    }
}

/// Whether FTZ and DAZ are both set on the calling thread (always true off x86_64).
pub fn flush_denormals_enabled() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        let mut csr: u32 = 0;
        // SAFETY: stmxcsr only stores this thread's control register into `csr`.
        unsafe { std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack)) };
        csr & (MXCSR_FTZ | MXCSR_DAZ) == MXCSR_FTZ | MXCSR_DAZ
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        true
    }
}

#[cfg(test)]
mod tests;
