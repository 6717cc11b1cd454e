//! The boundary integral (Algorithm 2): discontinuities of the path integrand where visibility
//! changes. So far: the edge topology that edge sampling builds on.

pub mod edges;
