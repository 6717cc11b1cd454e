use super::*;

const INF: f32 = f32::INFINITY;

/// SplitMix64: deterministic test randomness without a dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    fn f(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * ((self.next() >> 40) as f32 / (1u64 << 24) as f32)
    }
    fn v(&mut self, lo: f32, hi: f32) -> [f32; 3] {
        [self.f(lo, hi), self.f(lo, hi), self.f(lo, hi)]
    }
}

fn one_triangle() -> Accel {
    let dev = Device::new("").unwrap();
    Accel::build(&dev, &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], &[[0, 1, 2]]).unwrap()
}

/// 200 random triangles in [-1, 1]^3 plus a floor, for packet/single comparisons.
fn random_mesh(seed: u64) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut rng = Rng(seed);
    let mut p = vec![
        [-2.0, -2.0, -1.0],
        [2.0, -2.0, -1.0],
        [2.0, 2.0, -1.0],
        [-2.0, 2.0, -1.0],
    ];
    let mut t = vec![[0, 1, 2], [0, 2, 3]];
    for _ in 0..200 {
        let c = rng.v(-1.0, 1.0);
        let base = p.len() as u32;
        for _ in 0..3 {
            let d = rng.v(-0.3, 0.3);
            p.push([c[0] + d[0], c[1] + d[1], c[2] + d[2]]);
        }
        t.push([base, base + 1, base + 2]);
    }
    (p, t)
}

fn sub(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

#[test]
fn single_ray_hit_distance_and_barycentrics() {
    let a = one_triangle();
    let h = a.intersect1([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, INF).unwrap();
    assert_eq!(h.prim, 0);
    assert!((h.t - 2.0).abs() < 1e-6);
    assert!((h.u - 0.25).abs() < 1e-6 && (h.v - 0.5).abs() < 1e-6, "{h:?}");
    assert!(a.intersect1([0.8, 0.8, 2.0], [0.0, 0.0, -1.0], 0.0, INF).is_none());
    assert!(
        a.intersect1([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, 1.5).is_none(),
        "tfar bounds the ray"
    );
    assert!(
        a.intersect1([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 2.5, INF).is_none(),
        "tnear bounds the ray"
    );
    assert!(a.occluded1([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, 3.0));
    assert!(!a.occluded1([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, 1.9));
    // No backface culling: the same point from below.
    let h = a.intersect1([0.25, 0.5, -1.0], [0.0, 0.0, 1.0], 0.0, INF).unwrap();
    assert!((h.t - 1.0).abs() < 1e-6);
}

#[test]
fn barycentrics_and_distance_match_analytic_values_on_a_tilted_triangle() {
    let dev = Device::new("threads=1").unwrap();
    let (p0, p1, p2) = ([0.3, -0.2, 0.5], [2.1, 0.4, -0.3], [-0.5, 1.7, 0.9]);
    let a = Accel::build(&dev, &[p0, p1, p2], &[[0, 1, 2]]).unwrap();
    let mut rng = Rng(7);
    for _ in 0..200 {
        let (u, v) = (rng.f(0.02, 0.6), rng.f(0.02, 0.38));
        let target: [f32; 3] = std::array::from_fn(|k| (1.0 - u - v) * p0[k] + u * p1[k] + v * p2[k]);
        let org = rng.v(-4.0, 4.0);
        let t_true = rng.f(0.5, 3.0); // dir is not normalised: t is in units of |dir|
        let dir = sub(target, org).map(|c| c / t_true);
        let Some(h) = a.intersect1(org, dir, 0.0, INF) else {
            panic!("missed u={u} v={v} from {org:?}");
        };
        assert!((h.t - t_true).abs() <= 1e-4 * t_true, "t {} vs {t_true}", h.t);
        assert!((h.u - u).abs() < 2e-4 && (h.v - v).abs() < 2e-4, "{h:?} vs u={u} v={v}");
    }
}

#[test]
fn packets_equal_single_rays_lane_by_lane() {
    let (p, t) = random_mesh(11);
    let a = Accel::build(&Device::new("").unwrap(), &p, &t).unwrap();
    let mut rng = Rng(12);
    let mut lanes_hit = 0;
    for k in 0..400 {
        let mut r = Ray8::default();
        for i in 0..8 {
            let org = rng.v(-3.0, 3.0);
            let dir = sub(rng.v(-1.0, 1.0), org);
            let tfar = if i == 5 { rng.f(0.0, 1.0) } else { INF };
            r.set(i, org, dir, 0.0, tfar);
        }
        if k % 7 == 0 {
            r.org_x[3] = f32::NAN; // invalid lane: a miss, never sent to Embree
        }
        let active: [bool; 8] = std::array::from_fn(|_| !rng.next().is_multiple_of(4));
        let coherent = k % 2 == 0;
        let h8 = a.intersect8(&r, active, coherent);
        let o8 = a.occluded8(&r, active, coherent);
        for i in 0..8 {
            let (org, dir, tn, tf) = r.lane(i);
            let h1 = if active[i] {
                a.intersect1(org, dir, tn, tf)
            } else {
                None
            };
            let o1 = active[i] && a.occluded1(org, dir, tn, tf);
            assert_eq!(h8.get(i), h1, "packet {k} lane {i} active {}", active[i]);
            assert_eq!(o8[i], o1, "packet {k} lane {i}");
            assert_eq!(o1, h1.is_some(), "occluded agrees with intersect, lane {i}");
            if h1.is_none() {
                assert_eq!((h8.prim[i], h8.t[i]), (u32::MAX, INF));
            }
            lanes_hit += h1.is_some() as usize;
        }
    }
    assert!(lanes_hit > 1000, "the test should hit often: {lanes_hit}");
}

#[test]
fn occlusion_is_bounded_by_tnear_and_tfar() {
    let (p, t) = random_mesh(3);
    let a = Accel::build(&Device::new("").unwrap(), &p, &t).unwrap();
    let mut rng = Rng(4);
    let mut checked = 0;
    for _ in 0..2000 {
        let org = rng.v(-3.0, 3.0);
        let dir = sub(rng.v(-1.0, 1.0), org);
        let Some(h) = a.intersect1(org, dir, 0.0, INF) else {
            assert!(!a.occluded1(org, dir, 0.0, INF));
            continue;
        };
        assert!(a.occluded1(org, dir, 0.0, INF));
        assert!(a.occluded1(org, dir, 0.0, h.t * 1.001));
        // Nothing is closer than the closest hit.
        assert!(!a.occluded1(org, dir, 0.0, h.t * 0.999));
        assert!(a.intersect1(org, dir, 0.0, h.t * 0.999).is_none());
        checked += 1;
    }
    assert!(checked > 500);
}

#[test]
fn invalid_rays_are_misses() {
    let a = one_triangle();
    let (o, d) = ([0.25, 0.5, 2.0], [0.0, 0.0, -1.0]);
    let bad = [
        ([f32::NAN, 0.5, 2.0], d, 0.0, INF),
        ([0.25, INF, 2.0], d, 0.0, INF),
        (o, [0.0, f32::NAN, -1.0], 0.0, INF),
        (o, [0.0, 0.0, -INF], 0.0, INF),
        (o, d, -1.0, INF),
        (o, d, f32::NAN, INF),
        (o, d, 0.0, f32::NAN),
        (o, d, 3.0, 1.0),
        (o, [0.0; 3], 0.0, INF), // valid, but hits nothing
    ];
    let mut r = Ray8::default();
    for (i, &(o, d, tn, tf)) in bad.iter().enumerate() {
        assert!(a.intersect1(o, d, tn, tf).is_none(), "case {i}");
        assert!(!a.occluded1(o, d, tn, tf), "case {i}");
        if i < 8 {
            r.set(i, o, d, tn, tf);
        }
    }
    assert_eq!(a.intersect8(&r, [true; 8], false), Hit8::default());
    assert_eq!(a.occluded8(&r, [true; 8], true), [false; 8]);
    // A default packet has tfar = 0 and misses; so do all-inactive packets.
    assert_eq!(a.intersect8(&Ray8::default(), [true; 8], false), Hit8::default());
    r.set(0, o, d, 0.0, INF);
    assert_eq!(a.intersect8(&r, [false; 8], false), Hit8::default());
    assert!(a.intersect8(&r, [true; 8], false).get(0).is_some());
}

#[test]
fn bad_meshes_and_configs_are_errors() {
    let dev = Device::new("").unwrap();
    let e = Accel::build(&dev, &[[0.0; 3]], &[]).unwrap_err();
    assert!(matches!(e, AccelError::InvalidMesh(_)), "{e}");
    let e = Accel::build(
        &dev,
        &[[0.0, f32::NAN, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[[0, 1, 2]],
    )
    .unwrap_err();
    assert!(e.to_string().contains("vertex 0"), "{e}");
    let e = Accel::build(&dev, &[[0.0, 0.0, INF]; 3], &[[0, 1, 2]]).unwrap_err();
    assert!(matches!(e, AccelError::InvalidMesh(_)), "{e}");
    let e = Accel::build(&dev, &[[0.0; 3]; 3], &[[0, 1, 3]]).unwrap_err();
    assert!(e.to_string().contains("triangle 0"), "{e}");
    let e = Accel::build(&dev, &[], &[[0, 0, 0]]).unwrap_err();
    assert!(matches!(e, AccelError::InvalidMesh(_)), "{e}");
    // Degenerate triangles are fine and never hit.
    let a = Accel::build(&dev, &[[0.0; 3], [1.0, 0.0, 0.0]], &[[0, 1, 1]]).unwrap();
    assert!(a.intersect1([0.5, 0.0, 1.0], [0.0, 0.0, -1.0], 0.0, INF).is_none());

    let e = Device::new("threads=1\0").err().unwrap();
    assert!(matches!(e, AccelError::InvalidConfig { .. }), "{e}");
    let e = Device::new("threads=abc").err().unwrap();
    assert!(e.to_string().contains("RTC_ERROR"), "{e}");
}

#[test]
fn embree_errors_carry_code_name_and_message() {
    let dev = Device::new("").unwrap();
    // An unknown device property is an Embree error we can provoke safely.
    let _ = unsafe { ffi::rtcGetDeviceProperty(dev.raw, 12345) };
    let e = dev.check("probing").unwrap_err();
    let AccelError::Embree { code, name, .. } = &e else {
        panic!("{e:?}")
    };
    assert_eq!((*code, *name), (2, "RTC_ERROR_INVALID_ARGUMENT"));
    assert!(e.to_string().starts_with("probing: Embree error 2"), "{e}");
    assert!(
        e.to_string().contains("unknown readable property"),
        "Embree's message: {e}"
    );
    assert!(dev.check("again").is_ok(), "checking clears the error");
}

#[test]
fn device_is_the_expected_embree_build() {
    let dev = Device::new("").unwrap();
    let version = dev.property(ffi::RTC_DEVICE_PROPERTY_VERSION);
    assert!((31300..40000).contains(&version), "Embree version {version}");
    assert_eq!(dev.property(ffi::RTC_DEVICE_PROPERTY_NATIVE_RAY8_SUPPORTED), 1);
    // Our hits rely on double-sided triangles; masks are compiled in (we set them all-ones).
    assert_eq!(dev.property(ffi::RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED), 0);
    assert_eq!(dev.property(ffi::RTC_DEVICE_PROPERTY_RAY_MASK_SUPPORTED), 1);
}

#[test]
fn accel_outlives_its_device_and_is_shared_across_threads() {
    let (p, t) = random_mesh(5);
    let a = {
        let dev = Device::new("threads=1").unwrap();
        Accel::build_with_quality(&dev, &p, &t, BuildQuality::Medium).unwrap()
    };
    assert_eq!((a.triangle_count(), a.vertex_count()), (t.len(), p.len()));
    let trace = |seed: u64| -> Vec<Option<Hit>> {
        let mut rng = Rng(seed);
        (0..2000)
            .map(|_| {
                let org = rng.v(-3.0, 3.0);
                a.intersect1(org, sub(rng.v(-1.0, 1.0), org), 0.0, INF)
            })
            .collect()
    };
    let serial = trace(9);
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..4).map(|_| s.spawn(|| trace(9))).collect();
        for h in handles {
            assert_eq!(h.join().unwrap(), serial);
        }
    });
}

#[test]
fn flush_denormals_sets_the_bits_on_the_calling_thread_only() {
    std::thread::spawn(|| {
        set_flush_denormals();
        assert!(flush_denormals_enabled());
        let tiny = std::hint::black_box(f32::MIN_POSITIVE);
        assert_eq!(std::hint::black_box(tiny / 4.0), 0.0, "FTZ flushes denormal results");
    })
    .join()
    .unwrap();
    #[cfg(target_arch = "x86_64")]
    std::thread::spawn(|| assert!(!flush_denormals_enabled()))
        .join()
        .unwrap();
}

#[test]
fn far_from_origin_hits_are_accurate() {
    let dev = Device::new("").unwrap();
    let o = 1.0e4f32;
    let a = Accel::build(&dev, &[[o, o, 0.0], [o + 1.0, o, 0.0], [o, o + 1.0, 0.0]], &[[0, 1, 2]]).unwrap();
    let h = a
        .intersect1([o + 0.2, o + 0.2, 3.0], [0.0, 0.0, -1.0], 0.0, INF)
        .unwrap();
    assert!((h.t - 3.0).abs() < 1e-4);
}

#[test]
fn raw_batches_count_what_the_wrapper_finds() {
    let (p, t) = random_mesh(21);
    let a = Accel::build(&Device::new("").unwrap(), &p, &t).unwrap();
    let mut rng = Rng(22);
    let packets: Vec<Ray8> = (0..64)
        .map(|_| {
            let mut r = Ray8::default();
            for i in 0..8 {
                let org = rng.v(-3.0, 3.0);
                r.set(i, org, sub(rng.v(-1.5, 1.5), org), 0.0, INF);
            }
            r
        })
        .collect();
    let hits: usize = packets
        .iter()
        .map(|r| {
            (0..8)
                .filter(|&i| a.intersect8(r, [true; 8], false).get(i).is_some())
                .count()
        })
        .sum();
    assert!(hits > 0 && hits < 512);
    assert_eq!(a.raw_intersect1_batch(&packets), hits);
    assert_eq!(a.raw_intersect8_batch(&packets, false), hits);
    assert_eq!(a.raw_intersect8_batch(&packets, true), hits);
    assert_eq!(a.raw_occluded1_batch(&packets), hits);
    assert_eq!(a.raw_occluded8_batch(&packets, true), hits);
}
