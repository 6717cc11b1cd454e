//! Materials in world space at a vertex with unit normal `n`: the interface every estimator
//! calls. A per-lane gather ([`Lobes::gather`]) reads each lane's material; [`Lobes::eval`],
//! [`Lobes::pdf`] and [`Lobes::sample`] branch between lobes by lane masks, computing only the
//! lobes some lane has; `Lobes::delta` says which lanes have a Dirac lobe (smooth conductor or
//! dielectric). Directions follow one convention: `wo` points to the previous vertex of the
//! path, `wi` to the next; `radiance` is true on camera paths (radiance transport) and false on
//! light paths (importance transport), which differ at refraction.
//!
//! Lobes: Lambertian (this file), rough and smooth conductor (`conductor.rs`, Fresnel in
//! `fresnel.rs`), rough and smooth dielectric (`dielectric.rs`), all on the GGX distribution
//! (`ggx.rs`). A diffuse-only scene never builds a [`Lobes`]: its kernels keep the albedo
//! gather [`albedo`] and cosine sampling.

mod conductor;
mod delta;
mod dielectric;
mod fresnel;
mod ggx;
#[cfg(test)]
mod tests;

use super::context::RenderContext;
use crate::kernel::{Mask, Real, Spectrum, V3};
use crate::scene::{Material, Scene};

/// Albedo of the material of each lane's triangle, as a spectrum (diffuse-only scenes; the
/// specular reflectance of a conductor, 1 for a dielectric).
pub fn albedo<R: Real, const C: usize>(ctx: &RenderContext, prim: &[u32; 8]) -> Spectrum<R, C> {
    let mut rgb = [[0.0f32; 3]; 8];
    for i in 0..R::LANES {
        let t = prim[i].min(ctx.tri_material.len() as u32 - 1) as usize;
        rgb[i] = ctx.scene.materials[ctx.tri_material[t] as usize].material.tint();
    }
    let mut s = Spectrum::<R, C>::from_lane_rgb(&rgb[..R::LANES]);
    if R::DERIVS > 0 {
        ctx.motion.albedo_derivs(prim, &ctx.tri_material, &mut s);
    }
    s
}

/// Lambertian BSDF value f = albedo / π (two-sided).
#[inline(always)]
pub fn diffuse_eval<R: Real, const C: usize>(albedo: Spectrum<R, C>) -> Spectrum<R, C> {
    albedo.scale(R::splat(std::f32::consts::FRAC_1_PI))
}

/// Cosine-weighted direction about `n` oriented towards `side` (the incoming side), with its
/// solid-angle pdf cos θ / π. (Malley's method on a concentric disk.)
#[inline(always)]
pub fn sample_cosine<V: Real>(n: &V3<V>, side: &V3<V>, u1: V, u2: V) -> (V3<V>, V) {
    let flip = n.dot(*side).lt(V::zero());
    let nn = V3::select(flip, -*n, *n);
    let (s, t) = nn.orthonormal_basis();
    // concentric mapping (Shirley & Chiu 1997), branch-free by selects
    let a = u1 * V::splat(2.0) - V::one();
    let b = u2 * V::splat(2.0) - V::one();
    let use_a = (a * a).gt(b * b);
    let r = V::select(use_a, a, b);
    let q = std::f32::consts::FRAC_PI_4;
    let phi_a = V::safe_div(b, a).mul_f(q);
    let phi_b = V::splat(std::f32::consts::FRAC_PI_2) - V::safe_div(a, b).mul_f(q);
    let phi = V::select(use_a, phi_a, phi_b);
    let (sn, cs) = phi.sin_cos();
    let x = r * cs;
    let y = r * sn;
    let z = (V::one() - x * x - y * y).sqrt();
    let dir = s * x + t * y + nn * z;
    (dir, z.mul_f(std::f32::consts::FRAC_1_PI))
}

/// Solid-angle pdf of [`sample_cosine`] for direction `dir` (unit) given the same frame.
#[inline(always)]
pub fn cosine_pdf<V: Real>(n: &V3<V>, side: &V3<V>, dir: &V3<V>) -> V {
    let c = n.dot(*dir);
    let same = (c * n.dot(*side)).gt(V::zero());
    c.abs().mul_f(std::f32::consts::FRAC_1_PI).masked(same)
}

/// The materials of a packet's vertices, one lane each.
#[derive(Clone, Copy, Debug)]
pub struct Lobes<R: Real, const C: usize> {
    pub diffuse: R::Mask,
    pub conductor: R::Mask,
    pub dielectric: R::Mask,
    /// Lanes whose lobe is a Dirac delta (roughness 0).
    pub delta: R::Mask,
    /// Diffuse albedo, or a conductor's specular reflectance (1 on dielectric lanes).
    pub tint: Spectrum<R, C>,
    /// GGX α (rough conductor and dielectric lanes).
    pub alpha: R,
    /// Absolute refractive indices inside and outside (dielectric lanes; 1 elsewhere).
    pub eta_int: R,
    pub eta_ext: R,
    /// Conductor lanes with a complex index (η + iκ); the others reflect with F = 1.
    pub complex: R::Mask,
    pub cond_eta: Spectrum<R, C>,
    pub cond_k: Spectrum<R, C>,
}

/// One sampled direction per lane.
#[derive(Clone, Copy, Debug)]
pub struct Sampled<V: Real, const C: usize> {
    pub wi: V3<V>,
    /// Solid-angle pdf; on delta lanes the probability of the chosen lobe. Zero where the
    /// sample failed.
    pub pdf: V,
    /// f·|cos θ_i| / pdf.
    pub weight: Spectrum<V, C>,
    pub delta: V::Mask,
    /// Lanes that crossed the surface (refraction).
    pub transmitted: V::Mask,
}

/// One material as per-lane values (`rgb` by channel) for [`Lobes::from_lanes`].
#[derive(Clone, Copy, Debug, Default)]
struct LaneMaterial {
    kind: u8,
    delta: bool,
    tint: [f32; 3],
    alpha: f32,
    eta_int: f32,
    eta_ext: f32,
    complex: bool,
    cond_eta: [f32; 3],
    cond_k: [f32; 3],
}

impl LaneMaterial {
    fn new(m: &Material, eta_ext: f32) -> Self {
        let mut l = LaneMaterial {
            tint: m.tint(),
            eta_int: 1.0,
            eta_ext: 1.0,
            ..Default::default()
        };
        match *m {
            Material::Diffuse { .. } => {}
            Material::Conductor { roughness, ior, .. } => {
                l.kind = 1;
                l.alpha = roughness;
                l.delta = roughness == 0.0;
                if let Some((eta, k)) = ior {
                    (l.complex, l.cond_eta, l.cond_k) = (true, eta, k);
                }
            }
            Material::Dielectric { roughness, int_ior, .. } => {
                l.kind = 2;
                l.alpha = roughness;
                // index-matched, a rough surface bends nothing: every microfacet refracts
                // straight through (`Scene::is_dirac`; the weight is `Lobes::sample`'s)
                l.delta = roughness == 0.0 || int_ior == eta_ext;
                (l.eta_int, l.eta_ext) = (int_ior, eta_ext);
            }
        }
        l
    }
}

impl<R: Real, const C: usize> Lobes<R, C> {
    fn from_lanes(l: &[LaneMaterial]) -> Self {
        let mask = |f: &dyn Fn(&LaneMaterial) -> bool| {
            let b: [bool; 8] = std::array::from_fn(|i| l.get(i).is_some_and(f));
            R::Mask::from_bools(&b[..R::LANES])
        };
        let scalar = |f: &dyn Fn(&LaneMaterial) -> f32| {
            let v: [f32; 8] = std::array::from_fn(|i| l.get(i).map_or(1.0, f));
            R::from_lanes(&v[..R::LANES])
        };
        let rgb = |f: &dyn Fn(&LaneMaterial) -> [f32; 3]| {
            let v: [[f32; 3]; 8] = std::array::from_fn(|i| l.get(i).map_or([0.0; 3], f));
            Spectrum::<R, C>::from_lane_rgb(&v[..R::LANES])
        };
        Lobes {
            diffuse: mask(&|m| m.kind == 0),
            conductor: mask(&|m| m.kind == 1),
            dielectric: mask(&|m| m.kind == 2),
            delta: mask(&|m| m.delta),
            tint: rgb(&|m| m.tint),
            alpha: scalar(&|m| m.alpha),
            eta_int: scalar(&|m| m.eta_int),
            eta_ext: scalar(&|m| m.eta_ext),
            complex: mask(&|m| m.complex),
            cond_eta: rgb(&|m| if m.complex { m.cond_eta } else { [1.0; 3] }),
            cond_k: rgb(&|m| m.cond_k),
        }
    }

    /// The same material on every lane (tests), with `eta_ext` outside a dielectric.
    pub fn uniform(m: &Material, eta_ext: f32) -> Self {
        let l = LaneMaterial::new(m, eta_ext);
        Self::from_lanes(&[l; 8][..R::LANES])
    }

    /// The materials of each lane's triangle, with the derivative lanes of the requested
    /// albedo, roughness, ior and medium-η parameters.
    pub fn gather(ctx: &RenderContext, prim: &[u32; 8]) -> Self {
        let scene: &Scene = ctx.scene;
        let mut mats = [0u32; 8];
        let mut lanes = [LaneMaterial::default(); 8];
        for i in 0..R::LANES {
            let t = prim[i].min(ctx.tri_material.len() as u32 - 1) as usize;
            let m = ctx.tri_material[t];
            mats[i] = m;
            lanes[i] = LaneMaterial::new(&scene.materials[m as usize].material, scene.exterior_eta(m));
        }
        let mut l = Self::from_lanes(&lanes[..R::LANES]);
        if R::DERIVS > 0 {
            ctx.motion.albedo_derivs(prim, &ctx.tri_material, &mut l.tint);
            ctx.motion
                .material_derivs(scene, &mats, &mut l.alpha, &mut l.eta_int, &mut l.eta_ext);
        }
        l
    }

    /// The values (no derivative lanes).
    pub fn value(&self) -> Lobes<R::Value, C> {
        let sv = |s: &Spectrum<R, C>| Spectrum(s.0.map(|v| v.value()));
        Lobes {
            diffuse: self.diffuse,
            conductor: self.conductor,
            dielectric: self.dielectric,
            delta: self.delta,
            tint: sv(&self.tint),
            alpha: self.alpha.value(),
            eta_int: self.eta_int.value(),
            eta_ext: self.eta_ext.value(),
            complex: self.complex,
            cond_eta: sv(&self.cond_eta),
            cond_k: sv(&self.cond_k),
        }
    }

    /// Lanes with a lobe that is not a delta and not Lambertian (glossy or rough refractive):
    /// their f depends on the directions.
    pub fn glossy(&self) -> R::Mask {
        (self.conductor | self.dielectric).and_not(self.delta)
    }

    /// The conductor's reflectance at cosine `cos` (o·h): tint times the Fresnel term.
    fn conductor_reflectance(&self, cos: R) -> Spectrum<R, C> {
        let f = fresnel::conductor(cos, &self.cond_eta, &self.cond_k);
        Spectrum::select(self.complex, f, Spectrum::splat(R::one())) * self.tint
    }

    /// f(wo, wi) at normal `n` (zero on delta lanes).
    #[inline]
    pub fn eval(&self, n: &V3<R>, wo: &V3<R>, wi: &V3<R>, radiance: bool) -> Spectrum<R, C> {
        let mut f = Spectrum::<R, C>::zero();
        if self.diffuse.any() {
            let same = (n.dot(*wo) * n.dot(*wi)).gt(R::zero());
            f = Spectrum::select(self.diffuse & same, diffuse_eval(self.tint), f);
        }
        let cond = self.conductor.and_not(self.delta);
        if cond.any() {
            let (c, valid) = conductor::cosines(n, wo, wi);
            let dg = conductor::eval(self.alpha, c, valid);
            f = Spectrum::select(cond, self.conductor_reflectance(c[3]).scale(dg), f);
        }
        let diel = self.dielectric.and_not(self.delta);
        if diel.any() {
            let eta = self.eta_int / self.eta_ext;
            let h = dielectric::half(n, wo, wi, eta);
            f = Spectrum::select(
                diel,
                Spectrum::splat(dielectric::eval(self.alpha, eta, &h, radiance)),
                f,
            );
        }
        f
    }

    /// Solid-angle pdf of [`Self::sample`] choosing `wi` (zero on delta lanes).
    #[inline]
    pub fn pdf(&self, n: &V3<R>, wo: &V3<R>, wi: &V3<R>) -> R {
        let mut p = R::zero();
        if self.diffuse.any() {
            p = R::select(self.diffuse, cosine_pdf(n, wo, wi), p);
        }
        let cond = self.conductor.and_not(self.delta);
        if cond.any() {
            let (c, valid) = conductor::cosines(n, wo, wi);
            p = R::select(cond, conductor::pdf(self.alpha, c, valid), p);
        }
        let diel = self.dielectric.and_not(self.delta);
        if diel.any() {
            let eta = self.eta_int / self.eta_ext;
            let h = dielectric::half(n, wo, wi, eta);
            p = R::select(diel, dielectric::pdf(self.alpha, eta, &h), p);
        }
        p
    }
}

impl<V: Real<Value = V>, const C: usize> Lobes<V, C> {
    /// A direction per lane from three uniform numbers: `u1, u2` pick the direction (cosine
    /// or GGX visible normal), `uc` the lobe of a dielectric (reflection with probability F).
    #[inline]
    pub fn sample(&self, n: &V3<V>, wo: &V3<V>, u1: V, u2: V, uc: V, radiance: bool) -> Sampled<V, C> {
        let (cos_dir, cos_pdf) = sample_cosine(n, wo, u1, u2);
        let mut s = Sampled {
            wi: cos_dir,
            pdf: cos_pdf.masked(self.diffuse),
            weight: self.tint,
            delta: self.delta,
            transmitted: V::Mask::splat(false),
        };
        let spec = self.conductor | self.dielectric;
        if spec.none() {
            return s;
        }
        // the normal on wo's side and a visible normal (n itself on delta lanes)
        let co = n.dot(*wo);
        let nn = V3::select(co.lt(V::zero()), -*n, *n);
        let (t1, t2) = nn.orthonormal_basis();
        let local = V3::new(wo.dot(t1), wo.dot(t2), wo.dot(nn));
        let ml = ggx::sample_visible(self.alpha, &local, u1, u2);
        let m = V3::select(self.delta, nn, t1 * ml.x + t2 * ml.y + nn * ml.z);
        let om = wo.dot(m);
        let reflected = conductor::reflect(wo, &m);
        let mut wrong_side = V::Mask::splat(false);
        if self.conductor.any() {
            s.wi = V3::select(self.conductor, reflected, s.wi);
            let f = self.conductor_reflectance(co.abs());
            s.weight = Spectrum::select(self.conductor & self.delta, f, s.weight);
            s.pdf = V::select(self.conductor & self.delta, V::one(), s.pdf);
        }
        if self.dielectric.any() {
            let eta = self.eta_int / self.eta_ext;
            let eta_l = V::select(co.gt(V::zero()), eta, eta.recip());
            let f = fresnel::dielectric(om, eta_l);
            let refl = uc.lt(f);
            let refracted = dielectric::refract(wo, &m, om, eta_l);
            s.wi = V3::select(self.dielectric, V3::select(refl, reflected, refracted), s.wi);
            // a lobe that sends wi to the other side than it should fails (Walter et al.
            // 2007, §5.3: such microfacet samples carry no weight)
            let crossed = (co * n.dot(s.wi)).lt(V::zero());
            wrong_side = self.dielectric & ((refl & crossed) | (!refl & !crossed));
            s.transmitted = self.dielectric & crossed;
            s.pdf = s.pdf.masked(!wrong_side);
            let smooth = self.dielectric & self.delta;
            // an index-matched rough lane (delta, α > 0) passes what its rough lobe passes as
            // η' → 1: every visible microfacet sends o on to −o, masked by Smith's G1 of that
            // direction and faded as the lobe is at grazing microfacets, for the one drawn
            // (`dielectric::grazing_taper`); smooth lanes (α = 0) pass 1, whatever was drawn
            let masking = V::select(
                self.alpha.gt(V::zero()),
                ggx::g1(self.alpha, co.abs(), co.abs()) * dielectric::grazing_taper(ml.z),
                V::one(),
            );
            let t_weight = if radiance {
                V::safe_div(V::one(), eta_l * eta_l)
            } else {
                V::one()
            } * masking;
            s.weight = Spectrum::select(smooth, Spectrum::splat(V::select(refl, V::one(), t_weight)), s.weight);
            s.pdf = V::select(smooth, V::select(refl, f, V::one() - f), s.pdf);
        }
        let rough = spec.and_not(self.delta);
        if rough.any() {
            let f = self.eval(n, wo, &s.wi, radiance);
            let p = self.pdf(n, wo, &s.wi);
            let cos_i = n.dot(s.wi).abs();
            let w = f.scale(V::safe_div(cos_i, p));
            let ok = p.gt(V::zero()) & w.max_value().gt(V::zero()) & !wrong_side;
            s.weight = Spectrum::select(rough, w, s.weight);
            s.pdf = V::select(rough, p.masked(ok), s.pdf);
        }
        s
    }
}
