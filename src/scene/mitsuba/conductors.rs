//! Mitsuba's named conductors (`<string name="material" value="Au"/>` on `conductor` and
//! `roughconductor`) as RGB complex indices of refraction, the values Mitsuba 3's RGB variants
//! use: each is Mitsuba's measured spectrum (its data files `data/ior/<name>.eta.spd` and
//! `<name>.k.spd`, from the luxpop.com database) integrated against the CIE 1931 2° colour
//! matching functions over 360–830 nm, normalised to luminance and converted to linear sRGB.
//! Computed by `tools/conductor_presets.py` (which states the steps); its silver agrees to
//! four decimals with Mitsuba 3's own RGB conversion.

/// `(name, eta RGB, k RGB)`, by name as Mitsuba spells it.
pub(crate) const CONDUCTOR_PRESETS: [(&str, [f64; 3], [f64; 3]); 5] = [
    ("Ag", [0.1553, 0.1167, 0.1384], [4.8283, 3.1222, 2.1470]),
    ("Al", [1.6575, 0.8804, 0.5212], [9.2239, 6.2695, 4.8370]),
    ("Au", [0.1431, 0.3750, 1.4425], [3.9832, 2.3857, 1.6032]),
    ("Cr", [4.3697, 2.9167, 1.6547], [5.2064, 4.2314, 3.7550]),
    ("Cu", [0.2004, 0.9240, 1.1022], [3.9130, 2.4528, 2.1422]),
];

/// The `(eta, k)` of a named conductor.
pub(crate) fn preset(name: &str) -> Option<([f64; 3], [f64; 3])> {
    CONDUCTOR_PRESETS
        .iter()
        .find(|(n, _, _)| *n == name)
        .map(|&(_, eta, k)| (eta, k))
}

#[cfg(test)]
mod tests {
    use super::CONDUCTOR_PRESETS;

    /// Reflectance at normal incidence, |(n − 1 + ik)/(n + 1 + ik)|² = ((n−1)² + k²)/((n+1)² + k²).
    fn f0(n: f64, k: f64) -> f64 {
        ((n - 1.0).powi(2) + k * k) / ((n + 1.0).powi(2) + k * k)
    }

    /// What the metals look like: gold and copper reflect red most and blue least, silver and
    /// aluminium are bright and nearly neutral, chromium a neutral grey; so a channel or
    /// metal mixed up in the table shows.
    #[test]
    fn normal_incidence_reflectance_has_each_metals_colour() {
        let r = |name: &str| {
            let (_, eta, k) = CONDUCTOR_PRESETS.iter().find(|p| p.0 == name).unwrap();
            [0, 1, 2].map(|c| f0(eta[c], k[c]))
        };
        for warm in ["Au", "Cu"] {
            let [red, green, blue] = r(warm);
            assert!(
                red > 0.9 && red > green + 0.1 && green > blue && red - blue > 0.4,
                "{warm}: {:?}",
                r(warm)
            );
        }
        for (bright, min) in [("Ag", 0.9), ("Al", 0.9), ("Cr", 0.6)] {
            let v = r(bright);
            let (lo, hi) = (
                v.iter().cloned().fold(1.0, f64::min),
                v.iter().cloned().fold(0.0, f64::max),
            );
            assert!(lo > min && hi - lo < 0.07, "{bright}: {v:?}");
        }
    }
}
