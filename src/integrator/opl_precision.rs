//! Whether a render carries f64 OPLs ([`OplPrecision::choose`]: the film's finest time scale
//! against one f32 step). Why they are needed and how they are summed: `opl.rs`.

use crate::scene::Scene;
use crate::temporal::{Gate, Pulse};

/// Whether a render carries f64 OPLs, and why (written to the run JSON).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct OplPrecision {
    /// True: each lane's OPL is also summed in f64 from f64 hit points.
    pub f64_paths: bool,
    /// The finest time scale of the film, OPL metres: the smallest of the bin width, the
    /// pulse widths (σ of a Gaussian, width of a box) and a Gaussian gate's σ.
    pub time_scale_opl: f64,
    /// One f32 step (ulp) at the largest magnitude an OPL or a coordinate reaches: the ends
    /// of the time axis, the scene's coordinates and the camera's.
    pub f32_step_opl: f64,
}

impl OplPrecision {
    /// f64 paths when the film's finest time scale is under [`Self::MIN_STEPS`] f32 steps: a
    /// path of up to ~10 segments, each rounded by a few steps, then stays well under 1% of
    /// the time scale in f32. The Cornell box (0.06 m bins, OPL to 15.6 m: 6·10⁴ steps) stays
    /// f32; 1 mm bins at 4 m (2·10³ steps) or a 3 nm pulse go f64.
    pub fn choose(scene: &Scene) -> Self {
        let axis = &scene.film.axis;
        let mut scale = axis.bin_width_opl;
        if let Gate::Gaussian { sigma_opl } = scene.film.gate {
            scale = scale.min(sigma_opl as f64);
        }
        let mut magnitude = axis.start_opl.abs().max(axis.end_opl().abs());
        for e in &scene.emitters {
            match e.pulse {
                Pulse::Delta => {}
                Pulse::Gaussian { sigma_opl } => scale = scale.min(sigma_opl as f64),
                Pulse::Box { width_opl } => scale = scale.min(width_opl as f64),
            }
            magnitude = magnitude.max(e.offset_opl.abs());
        }
        for p in scene.geometry.positions.iter().chain([&scene.camera.position]) {
            magnitude = magnitude.max(p.abs().max_element() as f64);
        }
        let step = f32_step(magnitude);
        Self {
            f64_paths: scale < Self::MIN_STEPS * step,
            time_scale_opl: scale,
            f32_step_opl: step,
        }
    }

    /// f32 steps per finest time scale below which paths carry f64 OPLs.
    pub const MIN_STEPS: f64 = 4096.0;
}

/// The distance between consecutive f32 values at magnitude `m` (at least that of 1).
fn f32_step(m: f64) -> f64 {
    let m = (m as f32).max(1.0);
    (f32::from_bits(m.to_bits() + 1) - m) as f64
}

#[cfg(test)]
mod tests {
    use super::f32_step;

    #[test]
    fn f32_steps() {
        assert_eq!(f32_step(4.0), 2f64.powi(-21));
        assert_eq!(f32_step(3.9), 2f64.powi(-22));
        assert_eq!(f32_step(0.01), 2f64.powi(-23));
        assert_eq!(f32_step(1.0e5), 2f64.powi(-7));
    }
}
