//! 8-wide ray packets in structure-of-arrays form.

/// Eight rays, SoA, 32-byte aligned. `tnear`/`tfar` bound the parametric range.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, Default)]
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

/// Eight plain hits: `prim[i] == u32::MAX` where lane i missed or was inactive.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug)]
pub struct Hit8 {
    pub t: [f32; 8],
    pub prim: [u32; 8],
    pub u: [f32; 8],
    pub v: [f32; 8],
}

impl Default for Hit8 {
    fn default() -> Self {
        Self {
            t: [f32::INFINITY; 8],
            prim: [u32::MAX; 8],
            u: [0.0; 8],
            v: [0.0; 8],
        }
    }
}
