//! The boundary integral (Algorithm 2): discontinuities of the path integrand where visibility
//! changes. So far: the edge topology that edge sampling builds on, and the primary edges
//! (silhouettes seen from the camera, [`primary`]).

pub mod edges;
pub mod primary;
pub mod silhouette;
#[cfg(test)]
mod silhouette_tests;
