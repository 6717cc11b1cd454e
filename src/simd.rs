//! Which SIMD instructions this build of the library uses, against what the CPU offers.
//!
//! The 8-wide kernel (`wide::f32x8`) maps to one 256-bit register only when AVX is enabled at
//! compile time; otherwise it runs as two 128-bit halves, 8–10 % slower (measured when issue 15 was filed).
//! The repository's `.cargo/config.toml` builds with `-C target-cpu=x86-64-v3` (AVX2 + FMA),
//! but Cargo reads that file only for builds started inside this repository: a crate that
//! depends on difftransient must set the flag itself (its own `.cargo/config.toml`, or
//! `RUSTFLAGS="-C target-cpu=x86-64-v3"`). Every render calls [`warn_if_slower_than_the_cpu`],
//! which says so once per process when the CPU could do better than the build.

/// The instruction set the library was compiled for: `"avx2+fma"`, `"avx"` or `"sse2"` (or
/// `"other"` off x86-64). Recorded in `dtr render`'s JSON as `simd`.
pub fn compiled_for() -> &'static str {
    if cfg!(all(target_feature = "avx2", target_feature = "fma")) {
        "avx2+fma"
    } else if cfg!(target_feature = "avx") {
        "avx"
    } else if cfg!(target_arch = "x86_64") {
        "sse2"
    } else {
        "other"
    }
}

/// Whether this CPU has AVX2 and FMA (checked at run time).
pub fn cpu_has_avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// The advice for a build compiled for `compiled` on a CPU that does (`cpu_avx2_fma`) or does
/// not have AVX2 + FMA: `None` when the build already uses what the CPU has.
pub fn advice(compiled: &str, cpu_avx2_fma: bool) -> Option<String> {
    (cpu_avx2_fma && compiled != "avx2+fma").then(|| {
        format!(
            "difftransient was compiled for {compiled} but this CPU has AVX2 and FMA: the 8-wide kernel \
             runs as two 128-bit halves (8-10% slower). Build with RUSTFLAGS=\"-C target-cpu=x86-64-v3\" \
             or put `rustflags = [\"-C\", \"target-cpu=x86-64-v3\"]` under [target.x86_64-unknown-linux-gnu] \
             in your project's .cargo/config.toml"
        )
    })
}

/// Logs [`advice`] once per process, as a warning, when it applies.
pub fn warn_if_slower_than_the_cpu() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        if let Some(a) = advice(compiled_for(), cpu_has_avx2_fma()) {
            log::warn!("{a}");
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn advice_only_when_the_cpu_could_do_better() {
        assert_eq!(advice("avx2+fma", true), None);
        assert_eq!(advice("sse2", false), None);
        let a = advice("sse2", true).unwrap();
        assert!(
            a.contains("compiled for sse2") && a.contains("target-cpu=x86-64-v3"),
            "{a}"
        );
        assert!(advice("avx", true).is_some());
    }

    #[test]
    fn this_repository_builds_for_avx2() {
        // .cargo/config.toml sets target-cpu=x86-64-v3 for every build inside the repository
        #[cfg(target_arch = "x86_64")]
        assert_eq!(compiled_for(), "avx2+fma");
    }
}
