//! Intel Embree 3 behind a narrow, safe interface. This is the only module that talks to
//! Embree; a later move to Embree 4 stays here (see ../shared/EMBREE.md).
//!
//! - [`Device`] and [`Accel`] release their Embree objects on drop.
//! - Queries return plain hits `(t, primitive, u, v)`; the integrator rebuilds surface points
//!   from the mesh (STYLE example 1). Embree never sees dual numbers.
//! - 8-wide packets ([`Ray8`]) and their valid masks are 32-byte aligned; masks are `i32`
//!   -1 (active) / 0 (inactive); ray masks are always all-ones (a zero mask misses everything).
//! - A committed [`Accel`] is safe to query from many threads at once.
//! - Call [`set_flush_denormals`] on every thread that traces (rayon's `start_handler`).

mod device;
pub mod ffi;
mod packet;
mod scene;

pub use device::{AccelError, Device};
pub use packet::{Hit8, Ray8};
pub use scene::{Accel, Hit};

/// Sets flush-to-zero and denormals-are-zero in MXCSR for the calling thread (Embree's
/// traversal is slower and its verbose mode warns without them).
pub fn set_flush_denormals() {
    #[cfg(target_arch = "x86_64")]
    {
        const FTZ: u32 = 1 << 15;
        const DAZ: u32 = 1 << 6;
        let mut csr: u32 = 0;
        // SAFETY: stmxcsr/ldmxcsr only read and write this thread's SSE control register; we
        // set two mode bits and keep the rest.
        unsafe {
            std::arch::asm!("stmxcsr [{}]", in(reg) &mut csr, options(nostack));
            csr |= FTZ | DAZ;
            std::arch::asm!("ldmxcsr [{}]", in(reg) &csr, options(nostack, readonly));
        }
    }
}

#[cfg(test)]
mod tests;
