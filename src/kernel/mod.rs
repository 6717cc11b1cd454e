//! SIMD numbers for the path kernel.
//!
//! The path code is written once, generic over [`Real`]: it runs on `f32` (one path, used by
//! tests as the scalar reference), on `wide::f32x8` (eight paths per packet, the primal
//! renderer) and on dual numbers (eight paths plus derivative lanes, the differentiable
//! renderer). Embree never sees these types: it traces plain `f32` rays built from
//! [`Real::lane`] values.

mod dual;
mod mask;
mod real;
mod sampler;
mod sobol;
mod spectrum;
mod vec3;

pub use dual::Dual8;
pub use mask::Mask;
pub use real::Real;
pub use sampler::{PathSampler, SampleSequence, hash_to_unit, hash_u64};
pub use spectrum::Spectrum;
pub use vec3::V3;
pub use wide::f32x8;
