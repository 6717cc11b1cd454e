//! How fast a visibility discontinuity sweeps over the points that parameterise a path.
//!
//! A segment x_L → x_S that grazes edge (v0, v1) lies in the plane Π through x_L and the edge.
//! With N = (v1 − v0) × (v0 − x_L), the function h̃(y) = N · (y − x_L) vanishes on the
//! discontinuity curve (the edge's shadow from x_L on the surface of x_S) and changes sign
//! across it. When the parameter θ moves the edge, x_L and the surface point y = x_S (each
//! with the velocity of its own parameterisation: material form, or ray form for the vertex
//! seen from the camera), the curve passes over y at the rate
//!
//!   dh̃/dθ = Ṅ·(y − x_L) + N·(ẏ − ẋ_L),  Ṅ = (v̇1 − v̇0) × (v0 − x_L) + (v1 − v0) × (v̇0 − ẋ_L).
//!
//! The scalar normal velocity of the curve within the surface (supplemental Eq. 18's
//! V_∂M, along the in-surface normal of the curve pointing to h̃ > 0) is
//! −(dh̃/dθ) / (|N| · √(1 − (n_Π·n_S)²)); `secondary.rs` folds the denominator into the
//! Jacobian J_B, where it cancels.

use glam::Vec3;

/// Positions and velocities (for one parameter) of the four points that fix a discontinuity.
#[derive(Clone, Copy, Debug)]
pub struct Crossing {
    pub v0: Vec3,
    pub v1: Vec3,
    pub x_l: Vec3,
    pub y: Vec3,
    pub dv0: Vec3,
    pub dv1: Vec3,
    pub dx_l: Vec3,
    pub dy: Vec3,
}

impl Crossing {
    /// N = (v1 − v0) × (v0 − x_L), the (unnormalised) normal of the plane Π.
    #[inline]
    pub fn plane_normal(&self) -> Vec3 {
        (self.v1 - self.v0).cross(self.v0 - self.x_l)
    }

    /// dh̃/dθ at y (see the module documentation).
    #[inline]
    pub fn rate(&self) -> f32 {
        let e = self.v1 - self.v0;
        let r = self.v0 - self.x_l;
        let n = e.cross(r);
        let n_dot = (self.dv1 - self.dv0).cross(r) + e.cross(self.dv0 - self.dx_l);
        n_dot.dot(self.y - self.x_l) + n.dot(self.dy - self.dx_l)
    }
}

/// Velocity of a point y that moves along the fixed camera ray ω_c (ray form, as the first
/// camera vertex of Algorithm 1) while its surface, of unit normal n, moves with material
/// velocity `v_mat` at y: ẏ = ω_c (n·v_mat) / (n·ω_c).
#[inline]
pub fn ray_form_velocity(omega_c: Vec3, n: Vec3, v_mat: Vec3) -> Vec3 {
    let c = n.dot(omega_c);
    if c.abs() < 1e-12 {
        return Vec3::ZERO;
    }
    omega_c * (n.dot(v_mat) / c)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Mat3;

    /// A rigid motion x(θ) = c + R(θ)(x₀ − c) + θ t of one body.
    fn moved(x: Vec3, theta: f32, axis: Vec3, c: Vec3, t: Vec3) -> Vec3 {
        c + Mat3::from_axis_angle(axis, theta) * (x - c) + t * theta
    }
    fn velocity(x: Vec3, axis: Vec3, c: Vec3, t: Vec3) -> Vec3 {
        axis.cross(x - c) + t
    }

    /// The shadow of the edge on a moving receiver plane, found by geometry (intersect Π(θ)
    /// with a material line of the receiver), moves past the receiver's material points at
    /// ds/dθ = −(dh̃/dθ)/(∂h̃/∂s): the rate from `Crossing::rate` matches central differences.
    #[test]
    fn rate_matches_finite_difference_of_the_shadow_position() {
        let (v0, v1) = (Vec3::new(0.1, 1.0, -0.3), Vec3::new(0.2, 1.1, 0.4));
        let x_l = Vec3::new(-0.2, 2.0, 0.1);
        // receiver: plane through p with material direction m (tilted floor)
        let p = Vec3::new(0.0, 0.05, 0.0);
        let m = Vec3::new(1.0, 0.1, 0.2).normalize();
        let edge_motion = (
            Vec3::new(0.3, 0.2, 0.9).normalize(),
            Vec3::new(0.1, 1.0, 0.0),
            Vec3::new(0.5, -0.2, 0.1),
        );
        let light_motion = (Vec3::Y, Vec3::ZERO, Vec3::new(0.0, 0.0, 0.3));
        let recv_motion = (
            Vec3::new(1.0, 0.0, 1.0).normalize(),
            Vec3::new(0.2, 0.0, 0.0),
            Vec3::new(-0.1, 0.4, 0.0),
        );
        let at = |x: Vec3, (a, c, t): (Vec3, Vec3, Vec3), th: f32| moved(x, th, a, c, t);
        // material parameter s where the shadow line crosses the receiver's material line
        let crossing_s = |th: f32| {
            let (a, b, l) = (
                at(v0, edge_motion, th),
                at(v1, edge_motion, th),
                at(x_l, light_motion, th),
            );
            let n_pi = (b - a).cross(a - l);
            let (pp, mm) = (
                at(p, recv_motion, th),
                at(p + m, recv_motion, th) - at(p, recv_motion, th),
            );
            n_pi.dot(l - pp) / n_pi.dot(mm)
        };
        let s0 = crossing_s(0.0);
        let y = p + m * s0;
        let c = Crossing {
            v0,
            v1,
            x_l,
            y,
            dv0: velocity(v0, edge_motion.0, edge_motion.1, edge_motion.2),
            dv1: velocity(v1, edge_motion.0, edge_motion.1, edge_motion.2),
            dx_l: velocity(x_l, light_motion.0, light_motion.1, light_motion.2),
            dy: velocity(y, recv_motion.0, recv_motion.1, recv_motion.2),
        };
        assert!(c.plane_normal().dot(y - x_l).abs() < 1e-5, "y is on the discontinuity");
        let dh_ds = c.plane_normal().dot(m);
        let analytic = -c.rate() / dh_ds;
        let h = 1e-3;
        let fd = (crossing_s(h) - crossing_s(-h)) / (2.0 * h);
        assert!(
            (analytic - fd).abs() < 2e-3 * (1.0 + fd.abs()),
            "ds/dθ analytic {analytic} vs FD {fd}"
        );
    }

    /// Ray form: the point where a fixed ray meets a moving plane moves along the ray at the
    /// rate of the plane's normal motion (central differences).
    #[test]
    fn ray_form_velocity_matches_finite_difference() {
        let o = Vec3::new(0.0, 1.0, 2.0);
        let w = Vec3::new(0.1, -0.5, -1.0).normalize();
        let (p, n) = (Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.1, 1.0, 0.2).normalize());
        let (t, axis) = (Vec3::new(0.2, 0.3, -0.1), Vec3::X);
        let hit = |th: f32| {
            let pp = p + t * th;
            let nn = Mat3::from_axis_angle(axis, th) * n;
            o + w * (nn.dot(pp - o) / nn.dot(w))
        };
        let y = hit(0.0);
        let v_mat = axis.cross(y - p) + t; // rotation about p, then translation
        let a = ray_form_velocity(w, n, v_mat);
        let h = 1e-3;
        let fd = (hit(h) - hit(-h)) / (2.0 * h);
        assert!((a - fd).length() < 2e-3 * (1.0 + fd.length()), "{a} vs {fd}");
    }
}
