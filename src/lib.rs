//! # difftransient
//!
//! Differentiable transient rendering (Yi et al., "Differentiable Transient Rendering",
//! ACM TOG 40(6) 286, 2021) on the CPU: Embree for rays, eight paths per SIMD packet.
//!
//! The pipeline:
//! [`scene`] (load a description, apply parameters) → [`integrator`] (estimate the transient
//! path integral, packet by packet, through [`accel`] queries) → [`film`] (bin each path's
//! optical path length through the correlation S_e of [`temporal`]) → [`output`] (`.npy`,
//! EXR, previews).
//!
//! [`render::render`] runs it all on a rayon pool. [`render::render_diff`] adds the derivative:
//! the interior (Algorithm 1, dual numbers in the same kernel) plus, when a parameter moves
//! geometry, the [`boundary`] integral (Algorithm 2: primary and secondary edges).

#[doc(hidden)]
pub mod accel;
pub mod adjoint;
pub mod auto_window;
#[doc(hidden)]
pub mod boundary;
#[doc(hidden)]
pub mod checkpoint;
#[doc(hidden)]
pub mod cli;
pub mod error;
pub mod film;
#[doc(hidden)]
pub mod integrator;
#[doc(hidden)]
pub mod kernel;
pub mod optimize;
pub mod output;
#[doc(hidden)]
pub mod params;
pub mod render;
pub mod scene;
pub mod sensor_noise;
pub mod shard;
pub mod simd;
pub mod temporal;
#[doc(hidden)]
pub mod timing;

pub use adjoint::render_adjoint;
pub use error::Error;
pub use film::Transient;
pub use render::{
    BoundaryMode, DiffParts, Lanes, RenderOptions, RenderStats, render, render_diff, render_diff_parts,
    render_strategies,
};
pub use scene::Scene;
pub use shard::Shard;
