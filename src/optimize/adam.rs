//! Adam (Kingma & Ba 2015, Algorithm 1) with a domain per parameter: after each step a
//! parameter is brought back into its domain (`crate::params::Domain::project`: clamped to
//! a closed end, projected gradient descent; halfway to an open one).

use crate::params::Domain;

/// Adam's state for n parameters.
#[derive(Clone, Debug)]
pub struct Adam {
    /// Learning rate per parameter.
    pub lr: Vec<f64>,
    /// Decay rate β₁ of the first-moment (mean) estimate, in [0, 1).
    pub beta1: f64,
    /// Decay rate β₂ of the second-moment (uncentred variance) estimate, in [0, 1).
    pub beta2: f64,
    /// ε, relative: the step's denominator is √v̂ + ε·s, with s the largest √v̂ the parameter
    /// has had so far. Kingma & Ba add an absolute ε (10⁻⁸), which is not small next to the
    /// gradients of a transient loss (10⁻⁹ … 10⁻¹⁴ in an NLOS capture): it then sets the
    /// step instead of the learning rate, and a target ten times dimmer was fitted ten times
    /// slower. Relative, the steps do not depend on the loss's scale.
    pub eps: f64,
    m: Vec<f64>,
    v: Vec<f64>,
    /// Per parameter, the largest √v̂ so far (s above).
    scale: Vec<f64>,
    t: i32,
}

impl Adam {
    /// Adam with a learning rate per parameter (the step it takes per iteration, roughly, in
    /// its own units: metres, degrees, ...) and the usual β₁ = 0.9, β₂ = 0.999, ε = 10⁻⁸
    /// (relative, see [`Adam::eps`]).
    pub fn new(lr: Vec<f64>) -> Self {
        let n = lr.len();
        Self {
            lr,
            beta1: 0.9,
            beta2: 0.999,
            eps: 1e-8,
            m: vec![0.0; n],
            v: vec![0.0; n],
            scale: vec![0.0; n],
            t: 0,
        }
    }

    /// One step of `x` down the gradient `g`, each parameter kept in its domain.
    pub fn step(&mut self, x: &mut [f64], g: &[f64], domains: &[Domain]) {
        self.t += 1;
        let (b1, b2) = (self.beta1, self.beta2);
        let (c1, c2) = (1.0 - b1.powi(self.t), 1.0 - b2.powi(self.t));
        for i in 0..x.len() {
            self.m[i] = b1 * self.m[i] + (1.0 - b1) * g[i];
            self.v[i] = b2 * self.v[i] + (1.0 - b2) * g[i] * g[i];
            let (m, rms) = (self.m[i] / c1, (self.v[i] / c2).sqrt());
            self.scale[i] = self.scale[i].max(rms);
            // zero only while every gradient of the parameter has been zero: no step
            let den = rms + self.eps * self.scale[i];
            if den > 0.0 {
                x[i] = domains[i].project(x[i], x[i] - self.lr[i] * m / den);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adam_finds_the_minimum_of_a_quadratic_and_respects_bounds() {
        // f = (x − 3)² + 10 (y + 1)²: minimum (3, −1); y bounded to [−0.5, 5]
        let mut adam = Adam::new(vec![0.05, 0.05]);
        let mut x = [0.0, 2.0];
        for _ in 0..2000 {
            let g = [2.0 * (x[0] - 3.0), 20.0 * (x[1] + 1.0)];
            adam.step(&mut x, &g, &[Domain::closed(-10.0, 10.0), Domain::closed(-0.5, 5.0)]);
        }
        assert!((x[0] - 3.0).abs() < 1e-3, "{x:?}");
        assert_eq!(x[1], -0.5, "y stops at its bound");
    }

    /// Scaling the loss scales every gradient: the steps must not change. A factor of 2⁻⁴⁰
    /// (gradients near 10⁻¹², as an NLOS loss has) keeps every product exact, so the paths
    /// are bit-equal. With Kingma & Ba's absolute ε = 10⁻⁸ the scaled run's first step was
    /// 5·10⁻⁴ of the unscaled one's.
    #[test]
    fn adam_takes_the_same_steps_whatever_the_loss_scale() {
        let grad = |x: &[f64; 2], c: f64| [c * 2.0 * (x[0] - 3.0), c * 20.0 * (x[1] + 1.0)];
        let bounds = [Domain::closed(-10.0, 10.0); 2];
        let (mut a, mut b) = (Adam::new(vec![0.05, 0.02]), Adam::new(vec![0.05, 0.02]));
        let (mut x, mut y) = ([0.0, 2.0], [0.0, 2.0]);
        let c = (-40.0f64).exp2();
        for k in 0..1000 {
            let (gx, gy) = (grad(&x, 1.0), grad(&y, c));
            a.step(&mut x, &gx, &bounds);
            b.step(&mut y, &gy, &bounds);
            assert_eq!(x, y, "step {k}");
        }
        assert!((x[0] - 3.0).abs() < 0.05 && (x[1] + 1.0).abs() < 0.05, "{x:?}");
        // a parameter whose gradient is always zero does not move (no 0/0)
        let mut z = [1.0];
        let mut adam = Adam::new(vec![0.1]);
        adam.step(&mut z, &[0.0], &[Domain::closed(-10.0, 10.0)]);
        assert_eq!(z, [1.0]);
    }
}
