//! Parameters: what a `[[param]]` is, how its value reaches the scene, and how it moves things
//! in a derivative render. One home for the concept:
//!
//! - the kinds of parameter (this file: [`ParamKind`], [`Param`]) and [`MAX_PARAMS`], the most
//!   one render differentiates at once (the adjoint, `crate::adjoint`, runs groups of that
//!   many for any number);
//! - `resolve`: `[[param]]` entries and `--set` overrides applied to a scene description
//!   while it loads (each value replaces the quantity it controls);
//! - [`lanes`]: the derivative lanes of a render ([`lanes::Motion`]): the velocity field of
//!   every shape a parameter moves (material-form vertices, Algorithm 1), the albedo,
//!   radiance, η and pulse-offset lanes, and the refusal of time derivatives that S_e cannot
//!   give (supplemental Lemma 2.5).
//!
//! How a moving edge sweeps over the boundary's path vertices (the normal velocity of
//! supplemental Eqs. 18–19) is boundary theory and lives in `boundary::velocity`, built from
//! [`lanes::Motion::velocity`].

pub mod lanes;
pub(crate) mod resolve;

/// The most parameters one render differentiates at once: the derivative lanes of the widest
/// dual number the renderer dispatches (`Dual8<16>`, tied to this by a const assert in
/// `render.rs`) and the size of every per-parameter buffer (lane deposits, boundary weights).
pub const MAX_PARAMS: usize = 16;

/// Which axis a pose parameter acts along.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Axis {
    X = 0,
    Y = 1,
    Z = 2,
}

/// What a `[[param]]` entry controls.
#[derive(Clone, Debug, PartialEq)]
pub enum ParamKind {
    /// `translate[axis]` of a shape, metres.
    Translate { shape: u32, axis: Axis },
    /// `rotate_deg[axis]` of a shape, degrees.
    Rotate { shape: u32, axis: Axis },
    /// `scale[axis]` of a shape (unitless factor).
    Scale { shape: u32, axis: Axis },
    /// Albedo of a material; `channel` None sets all channels.
    Albedo { material: u32, channel: Option<usize> },
    /// Radiance (area), intensity (point) or power (laser) of an emitter; `channel` None = all.
    Radiance { emitter: u32, channel: Option<usize> },
    /// Refractive index η of the medium.
    Eta,
    /// Emission time offset of an emitter, OPL metres.
    PulseOffset { emitter: u32 },
    /// GGX roughness α of a rough conductor or dielectric.
    Roughness { material: u32 },
    /// Interior refractive index of a rough dielectric.
    Ior { material: u32 },
}

#[derive(Clone, Debug)]
pub struct Param {
    pub name: String,
    pub kind: ParamKind,
    /// The value as written (or set), in the file's coordinates: a translate param holds a
    /// world coordinate, not one relative to [`crate::scene::Scene::render_origin`].
    pub value: f64,
}
