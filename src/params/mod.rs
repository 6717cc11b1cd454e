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
//!   give (supplemental Lemma 2.5);
//! - `sliding`: the warning for a parameter that slides a shape along one it rests on (the
//!   interior's variance is unbounded there).
//!
//! How a moving edge sweeps over the boundary's path vertices (the normal velocity of
//! supplemental Eqs. 18–19) is boundary theory and lives in `boundary::velocity`, built from
//! [`lanes::Motion::velocity`].

pub mod lanes;
pub(crate) mod resolve;
pub(crate) mod sliding;

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

/// The values a parameter of some kind may take: an interval whose ends may be open. The
/// loader refuses a value outside it (`resolve`); `dtr optimize` keeps its iterates inside
/// it ([`Domain::project`]), with any bounds the user gave ([`Domain::within`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Domain {
    pub lo: f64,
    pub hi: f64,
    /// Whether `lo` itself is outside (a refractive index > 0), or inside (an albedo ≥ 0).
    pub open_lo: bool,
    pub open_hi: bool,
}

impl Domain {
    /// Every number: a position, an angle.
    pub const ANY: Domain = Domain::closed(f64::NEG_INFINITY, f64::INFINITY);

    pub const fn closed(lo: f64, hi: f64) -> Domain {
        Domain {
            lo,
            hi,
            open_lo: false,
            open_hi: false,
        }
    }

    pub fn contains(&self, v: f64) -> bool {
        let above = if self.open_lo { v > self.lo } else { v >= self.lo };
        let below = if self.open_hi { v < self.hi } else { v <= self.hi };
        above && below
    }

    /// This domain cut to the closed bounds [lo, hi] (a bound inside it closes that end).
    pub fn within(&self, lo: f64, hi: f64) -> Domain {
        let mut d = *self;
        if lo >= d.lo {
            (d.lo, d.open_lo) = (lo, lo == d.lo && d.open_lo);
        }
        if hi <= d.hi {
            (d.hi, d.open_hi) = (hi, hi == d.hi && d.open_hi);
        }
        d
    }

    /// `next`, a step from `prev` (inside), brought back inside: to a closed end it crosses
    /// (projected gradient descent), or half the way from `prev` to an open one, which no
    /// step may reach (an index of 0, a roughness of 0).
    pub fn project(&self, prev: f64, next: f64) -> f64 {
        let back = |end: f64, open: bool| if open { 0.5 * (prev + end) } else { end };
        if next.is_nan() {
            prev
        } else if !(next >= self.lo) || (self.open_lo && next <= self.lo) {
            back(self.lo, self.open_lo)
        } else if !(next <= self.hi) || (self.open_hi && next >= self.hi) {
            back(self.hi, self.open_hi)
        } else {
            next
        }
    }
}

impl std::fmt::Display for Domain {
    /// As the loader's messages say it: "in [0, 1]", "> 0", ">= 0", "any number".
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (lo_inf, hi_inf) = (self.lo == f64::NEG_INFINITY, self.hi == f64::INFINITY);
        let n = crate::scene::limits::number;
        match (lo_inf, hi_inf) {
            (true, true) => write!(f, "any number"),
            (false, true) => write!(f, "{} {}", if self.open_lo { ">" } else { ">=" }, n(self.lo)),
            (true, false) => write!(f, "{} {}", if self.open_hi { "<" } else { "<=" }, n(self.hi)),
            (false, false) => write!(
                f,
                "in {}{}, {}{}",
                if self.open_lo { "(" } else { "[" },
                n(self.lo),
                n(self.hi),
                if self.open_hi { ")" } else { "]" }
            ),
        }
    }
}

impl ParamKind {
    /// The values a parameter of this kind may take, and what the loader calls the quantity
    /// ("an albedo"): albedo in [0, 1], an emitted amount in [0, 10¹⁸]
    /// ([`crate::scene::limits::MAX_EMISSION`]), refractive indices of at least 10⁻⁶
    /// ([`crate::scene::limits::MIN_INDEX`]), a roughness in [10⁻⁶, 1]
    /// ([`crate::scene::limits::MIN_ROUGHNESS`]), a pulse offset within ±2²⁴ m ([`crate::scene::limits::MAX_TIME_OPL`]); a scale
    /// factor is nonzero, so its domain is the side of 0 that `value` is on (> 0 for 0
    /// itself); poses take any number.
    pub fn domain(&self, value: f64) -> (Domain, &'static str) {
        let positive = Domain {
            open_lo: true,
            ..Domain::closed(0.0, f64::INFINITY)
        };
        let index = Domain::closed(crate::scene::limits::MIN_INDEX, f64::INFINITY);
        match self {
            ParamKind::Translate { .. } | ParamKind::Rotate { .. } => (Domain::ANY, "a value"),
            ParamKind::PulseOffset { .. } => (
                Domain::closed(-crate::scene::limits::MAX_TIME_OPL, crate::scene::limits::MAX_TIME_OPL),
                "a pulse offset",
            ),
            ParamKind::Scale { .. } if value < 0.0 => (
                Domain {
                    open_hi: true,
                    ..Domain::closed(f64::NEG_INFINITY, 0.0)
                },
                "a scale factor",
            ),
            ParamKind::Scale { .. } => (positive, "a scale factor"),
            ParamKind::Albedo { .. } => (Domain::closed(0.0, 1.0), "an albedo"),
            ParamKind::Radiance { .. } => (
                Domain::closed(0.0, crate::scene::limits::MAX_EMISSION),
                "an emitted amount",
            ),
            ParamKind::Eta => (index, "a refractive index"),
            ParamKind::Ior { .. } => (index, "an index of refraction"),
            ParamKind::Roughness { .. } => (
                Domain::closed(crate::scene::limits::MIN_ROUGHNESS, 1.0),
                "a roughness (GGX α)",
            ),
        }
    }
}

#[cfg(test)]
mod domain_tests {
    use super::Domain;

    #[test]
    fn a_domain_keeps_steps_inside_closed_and_open_ends() {
        let albedo = Domain::closed(0.0, 1.0);
        assert_eq!(albedo.project(0.05, -0.2), 0.0, "a closed end clamps");
        assert_eq!(albedo.project(0.9, 1.3), 1.0);
        assert_eq!(albedo.project(0.5, 0.6), 0.6);
        let index = Domain {
            open_lo: true,
            ..Domain::closed(0.0, f64::INFINITY)
        };
        assert_eq!(index.project(0.2, -0.1), 0.1, "half the way to an open end");
        assert_eq!(index.project(0.2, 0.0), 0.1, "an open end itself is outside");
        assert!(index.contains(1e-9) && !index.contains(0.0) && albedo.contains(0.0));
        assert_eq!(index.project(0.2, f64::NAN), 0.2, "no step to NaN");
        let bounded = index.within(1.0, 2.0);
        assert_eq!(bounded, Domain::closed(1.0, 2.0));
        assert_eq!(bounded.project(1.2, 2.5), 2.0);
        let looser = albedo.within(-1.0, 5.0);
        assert_eq!(looser, albedo, "bounds wider than the domain keep it");
        assert!(index.within(0.0, 3.0).open_lo, "a bound at an open end keeps it open");
        assert_eq!(format!("{albedo}"), "in [0, 1]");
        assert_eq!(format!("{index}"), "> 0");
        assert_eq!(format!("{}", Domain::closed(0.0, f64::INFINITY)), ">= 0");
        assert_eq!(
            format!(
                "{}",
                Domain {
                    open_lo: true,
                    ..albedo
                }
            ),
            "in (0, 1]"
        );
    }
}
