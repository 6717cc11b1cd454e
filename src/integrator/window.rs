//! The time-window cut: no path is traced past the last optical path length that can still
//! reach a bin of the film.
//!
//! A path of OPL d adds f·S_e(l, d) to bin l (supplemental Eq. 24), and S_e(l, ·) is zero
//! beyond the window's end plus the pulse's and gate's reach
//! ([`crate::temporal::Correlation::last_opl`]). OPL only grows along a path, so once a
//! subpath's OPL passes that bound nothing it leads to can land in the transient, nor can its
//! derivative (∂S_e/∂d is zero there too). The estimators therefore
//! - bound each ray's t_far by the OPL left, η·t ≤ budget − d, so Embree culls farther hits
//!   and the path ends where it would have left the window;
//! - skip next-event and BDPT connections whose OPL lands past the budget, before their
//!   shadow ray.
//!
//! Paths are sampled with counter-based random numbers (`kernel::PathSampler`), so ending one
//! lane early changes no other lane: the transient and its derivatives are the same bytes as
//! without the cut (tests/window_cut.rs), with fewer rays. What the cut does change is the
//! time-summed (steady) image, which then integrates the window ([`crate::film::SteadyMode`]);
//! `--steady full` turns the cut off.

use crate::kernel::{Mask, Real};
use crate::temporal::Correlation;

/// Relative slack added to the bound: the kernel's f32 OPL and the f64 OPL the film bins
/// may differ by a few f32 ulps per segment (about 10⁻⁶ relative over a long path); 2⁻¹⁰ is
/// far more than that, so the cut never drops a path that could reach a bin.
const SLACK: f64 = 1.0 / 1024.0;

/// The largest OPL any emitter's paths can have and still touch a bin, with slack, in the
/// kernel's f32; `None` when there is no emitter (nothing to bound).
pub fn opl_budget(correlations: &[Correlation]) -> Option<f32> {
    let last = correlations
        .iter()
        .map(Correlation::last_opl)
        .fold(f64::NEG_INFINITY, f64::max);
    last.is_finite().then(|| (last + SLACK * last.abs().max(1.0)) as f32)
}

/// The ray parameter beyond which a segment leaving a subpath of OPL `opl` through a medium
/// of index `eta` cannot end in the window: (budget − opl) / η, or +∞ without a budget. It is
/// ≤ 0 for lanes already past the budget.
#[inline(always)]
pub fn t_far<V: Real>(budget: Option<f32>, opl: V, eta: V) -> V {
    match budget {
        Some(b) => V::safe_div(V::splat(b) - opl, eta),
        None => V::splat(f32::INFINITY),
    }
}

/// Lanes whose OPL `d` is still within the budget (all lanes without one).
#[inline(always)]
pub fn within<V: Real>(budget: Option<f32>, d: V) -> V::Mask {
    match budget {
        Some(b) => d.le(V::splat(b)),
        None => V::Mask::from_bools(&[true; 8][..V::LANES]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::temporal::{Gate, Pulse, TimeAxis};

    fn corr(pulse: Pulse, gate: Gate, offset: f64) -> Correlation {
        let axis = TimeAxis {
            start_opl: 2.0,
            bin_width_opl: 0.1,
            bins: 30,
        };
        Correlation::new(axis, pulse, offset, gate).unwrap()
    }

    #[test]
    fn no_path_past_the_budget_touches_a_bin_and_paths_just_inside_do() {
        let cases = [
            corr(Pulse::Delta, Gate::Box, 0.0),
            corr(Pulse::Gaussian { sigma_opl: 0.03 }, Gate::Box, 0.2),
            corr(Pulse::Box { width_opl: 0.25 }, Gate::Box, -0.4),
            corr(Pulse::Delta, Gate::Gaussian { sigma_opl: 0.05 }, 0.0),
            corr(
                Pulse::Gaussian { sigma_opl: 0.02 },
                Gate::Gaussian { sigma_opl: 0.05 },
                0.1,
            ),
        ];
        for c in &cases {
            let last = c.last_opl();
            // beyond the bound no bin is touched, for values and derivatives alike
            for k in 0..200 {
                let d = last + 1e-9 + k as f64 * 1e-3;
                assert!(c.range(d).is_empty(), "{c:?}: d = {d} reaches {:?}", c.range(d));
            }
            // and the bound is tight: a little before it, the last bin is still reached
            let before = last - 0.05;
            assert!(
                c.range(before).contains(&29),
                "{c:?}: d = {before}: {:?}",
                c.range(before)
            );
            let b = opl_budget(std::slice::from_ref(c)).unwrap() as f64;
            assert!(b >= last && b <= last + 0.02, "{b} vs {last}");
        }
        assert_eq!(opl_budget(&[]), None);
    }

    #[test]
    fn t_far_and_within_follow_the_budget() {
        let t: f32 = t_far(Some(10.0), 4.0f32, 1.5f32);
        assert_eq!(t, 4.0);
        assert!(t_far::<f32>(Some(1.0), 4.0, 1.0) < 0.0);
        assert_eq!(t_far::<f32>(None, 4.0, 1.0), f32::INFINITY);
        assert!(within(Some(10.0), 10.0f32).bit(0));
        assert!(!within(Some(10.0), 10.5f32).bit(0));
        assert!(within(None, 1e30f32).bit(0));
    }
}
