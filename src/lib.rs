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
//! [`render_adjoint`] contracts the derivative with a loss's gradient ∂L/∂I without storing a
//! derivative film, and [`optimize`] uses it to recover parameters from a target transient.
//!
//! Units: lengths and optical path lengths (OPL) are in metres, time is OPL / c
//! ([`temporal::TimeAxis::time_ns_of_opl`]), angles in the scene file are in degrees. A
//! [`Transient`] is `[height, width, bins, channels]`, row-major.
//!
//! # Example
//!
//! Load the Cornell box at 16 × 16 pixels (dotted `--set` overrides of the description),
//! render two samples per pixel and look at the result:
//!
//! ```
//! use difftransient::{RenderOptions, Scene, render};
//! use std::path::Path;
//!
//! let path = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/cornell_box.toml"));
//! let overrides = [("camera.resolution.0".to_string(), 16.0), ("camera.resolution.1".to_string(), 16.0)];
//! let scene = Scene::load(path, &overrides)?;
//! let opts = RenderOptions { spp: Some(2), ..Default::default() };
//! let (transient, stats) = render(&scene, &opts)?;
//!
//! // [height, width, bins, channels]: the file's 200 bins of 6 cm, RGB.
//! assert_eq!(transient.shape(), [16, 16, 200, 3]);
//! assert_eq!(stats.spp, 2);
//! assert_eq!(transient.non_finite_count(), 0);
//! // Light reached the camera, and no path is shorter than the camera's distance to the
//! // lamp (3.78 m): bins 0 and 1, [3.6, 3.72) m of OPL, stay dark.
//! let per_bin = transient.bin_totals();
//! assert!(per_bin.iter().sum::<f32>() > 0.0);
//! assert!(per_bin[..2].iter().all(|&e| e == 0.0));
//! assert!(stats.energy.inside > 0.0);
//! # Ok::<(), difftransient::Error>(())
//! ```

#![warn(missing_docs)]

#[doc(hidden)]
pub mod accel;
pub mod adjoint;
pub mod auto_window;
#[doc(hidden)]
pub mod boundary;
pub mod cancel;
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
pub mod named;
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
pub use scene::{Entry, Scene, SceneBuilder};
pub use shard::Shard;
