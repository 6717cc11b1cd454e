use super::*;

fn one_triangle() -> Accel {
    let dev = Device::new("").unwrap();
    Accel::build(
        &dev,
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[[0, 1, 2]],
    )
    .unwrap()
}

#[test]
fn single_ray_hit_distance_and_barycentrics() {
    let a = one_triangle();
    let h = a
        .intersect1([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
        .unwrap();
    assert_eq!(h.prim, 0);
    assert!((h.t - 2.0).abs() < 1e-6);
    assert!(
        (h.u - 0.25).abs() < 1e-6 && (h.v - 0.5).abs() < 1e-6,
        "u {} v {}",
        h.u,
        h.v
    );
    assert!(
        a.intersect1([0.8, 0.8, 2.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
            .is_none()
    );
    assert!(
        a.intersect1([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, 1.5)
            .is_none(),
        "tfar bounds the ray"
    );
    assert!(a.occluded1([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, 3.0));
    assert!(!a.occluded1([0.25, 0.5, 2.0], [0.0, 0.0, -1.0], 0.0, 1.9));
}

#[test]
fn packets_equal_single_rays_lane_by_lane() {
    let a = one_triangle();
    let mut r = Ray8::default();
    for i in 0..8 {
        r.org_x[i] = 0.1 * i as f32;
        r.org_y[i] = 0.3;
        r.org_z[i] = 1.0 + i as f32;
        r.dir_z[i] = -1.0;
        r.tfar[i] = if i == 5 { 0.5 } else { f32::INFINITY };
    }
    let active = [true, true, false, true, true, true, true, false];
    let h8 = a.intersect8(&r, active, false);
    let o8 = a.occluded8(&r, active, true);
    for i in 0..8 {
        let h1 = a.intersect1(
            [r.org_x[i], r.org_y[i], r.org_z[i]],
            [0.0, 0.0, -1.0],
            0.0,
            r.tfar[i],
        );
        if !active[i] {
            assert_eq!(h8.prim[i], u32::MAX);
            assert!(!o8[i]);
            continue;
        }
        match h1 {
            Some(h) => {
                assert_eq!(h8.prim[i], h.prim, "lane {i}");
                assert_eq!(h8.t[i], h.t);
                assert!(o8[i]);
            }
            None => {
                assert_eq!(h8.prim[i], u32::MAX, "lane {i}");
                assert!(!o8[i]);
            }
        }
    }
}

#[test]
fn bad_meshes_are_errors() {
    let dev = Device::new("").unwrap();
    assert!(Accel::build(&dev, &[[0.0; 3]], &[]).is_err());
    let e = Accel::build(
        &dev,
        &[[0.0, f32::NAN, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[[0, 1, 2]],
    );
    assert!(e.err().unwrap().to_string().contains("vertex 0"));
    assert!(Accel::build(&dev, &[[0.0; 3]; 3], &[[0, 1, 3]]).is_err());
}

#[test]
fn far_from_origin_hits_are_accurate() {
    let dev = Device::new("").unwrap();
    let o = 1.0e4f32;
    let a = Accel::build(
        &dev,
        &[[o, o, 0.0], [o + 1.0, o, 0.0], [o, o + 1.0, 0.0]],
        &[[0, 1, 2]],
    )
    .unwrap();
    let h = a
        .intersect1(
            [o + 0.2, o + 0.2, 3.0],
            [0.0, 0.0, -1.0],
            0.0,
            f32::INFINITY,
        )
        .unwrap();
    assert!((h.t - 3.0).abs() < 1e-4);
}
