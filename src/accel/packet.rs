//! 8-wide ray packets in structure-of-arrays form, their hits and valid masks, and the plain
//! single-ray [`Hit`] a packet lane reads as.

/// A plain hit: distance along the ray (in units of `|dir|`), the triangle's index in the
/// input index array, and Embree's barycentrics: p = (1 − u − v)·p0 + u·p1 + v·p2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    pub t: f32,
    pub prim: u32,
    pub u: f32,
    pub v: f32,
}

/// Eight rays, SoA, 32-byte aligned: lane `i` is `org + t·dir`, `t ∈ [tnear, tfar]`.
///
/// `Default` gives zeroed rays with `tfar = 0`, which miss everything: fill every field of
/// the lanes you activate. Directions need not be normalised; hit distances are in units of
/// `|dir|`.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Ray8 {
    pub org_x: [f32; 8],
    pub org_y: [f32; 8],
    pub org_z: [f32; 8],
    pub dir_x: [f32; 8],
    pub dir_y: [f32; 8],
    pub dir_z: [f32; 8],
    pub tnear: [f32; 8],
    pub tfar: [f32; 8],
}

impl Ray8 {
    /// Sets lane `i` (panics only if `i >= 8`, like any array index).
    #[inline]
    pub fn set(&mut self, i: usize, org: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) {
        self.org_x[i] = org[0];
        self.org_y[i] = org[1];
        self.org_z[i] = org[2];
        self.dir_x[i] = dir[0];
        self.dir_y[i] = dir[1];
        self.dir_z[i] = dir[2];
        self.tnear[i] = tnear;
        self.tfar[i] = tfar;
    }

    /// Lane `i` as `(org, dir, tnear, tfar)`.
    #[inline]
    pub fn lane(&self, i: usize) -> ([f32; 3], [f32; 3], f32, f32) {
        (
            [self.org_x[i], self.org_y[i], self.org_z[i]],
            [self.dir_x[i], self.dir_y[i], self.dir_z[i]],
            self.tnear[i],
            self.tfar[i],
        )
    }
}

/// Eight plain hits. Where lane `i` missed or was inactive: `prim[i] == u32::MAX`,
/// `t[i] == +inf`, `u[i] == v[i] == 0`.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit8 {
    pub t: [f32; 8],
    pub prim: [u32; 8],
    pub u: [f32; 8],
    pub v: [f32; 8],
}

impl Default for Hit8 {
    /// All lanes missed.
    fn default() -> Self {
        Self {
            t: [f32::INFINITY; 8],
            prim: [u32::MAX; 8],
            u: [0.0; 8],
            v: [0.0; 8],
        }
    }
}

impl Hit8 {
    /// Lane `i` as a single hit, `None` on a miss.
    #[inline]
    pub fn get(&self, i: usize) -> Option<Hit> {
        (self.prim[i] != u32::MAX).then_some(Hit {
            t: self.t[i],
            prim: self.prim[i],
            u: self.u[i],
            v: self.v[i],
        })
    }
}

/// The valid mask of an 8-wide Embree query, as Embree wants it: `i32` lanes, -1 active and
/// 0 inactive, 32-byte aligned. Embree does not touch inactive lanes at all.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Valid8(pub [i32; 8]);

impl From<[bool; 8]> for Valid8 {
    #[inline]
    fn from(active: [bool; 8]) -> Self {
        Self(active.map(|a| if a { -1 } else { 0 }))
    }
}

impl Valid8 {
    /// Whether lane `i` is active.
    #[inline]
    pub fn is_active(&self, i: usize) -> bool {
        self.0[i] != 0
    }
}

const _: () = {
    assert!(std::mem::size_of::<Ray8>() == 256 && std::mem::align_of::<Ray8>() == 32);
    assert!(std::mem::size_of::<Hit8>() == 128 && std::mem::align_of::<Hit8>() == 32);
    assert!(std::mem::size_of::<Valid8>() == 32 && std::mem::align_of::<Valid8>() == 32);
};
