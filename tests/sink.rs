//! The estimators hand every contribution to a sink (`integrator::sink`): a sink written
//! outside the crate receives each path with its film point and (s, t) strategy, and
//! replaying what it received into a film gives the film sink's bytes.

use crate::common;
use difftransient::accel::Device;
use difftransient::film::TileFilm;
use difftransient::integrator::RenderContext;
use difftransient::integrator::bdpt::{self, film::BdptFilm};
use difftransient::integrator::deposit::LaneContribution;
use difftransient::integrator::deposit::PathCounts;
use difftransient::integrator::path::{PacketLanes, trace_packet};
use difftransient::integrator::sink::Sink;
use difftransient::kernel::f32x8;

#[derive(Default)]
struct Recorder {
    got: Vec<((usize, usize), usize, usize, LaneContribution<3>, f32)>,
}

impl Sink<3> for Recorder {
    fn add(&mut self, _: &RenderContext, st: (usize, usize), x: usize, y: usize, lc: &LaneContribution<3>, h: f32) {
        self.got.push((st, x, y, *lc, h));
    }
}

fn replay(ctx: &RenderContext, rec: &Recorder, film: &mut TileFilm) {
    for (_, x, y, lc, h) in &rec.got {
        lc.add_to(ctx, film, *x, *y, *h);
    }
}

fn bits(film: &TileFilm, ctx: &RenderContext) -> Vec<u32> {
    let f = &ctx.scene.film;
    let mut t = vec![difftransient::Transient::zeros(
        f.width as usize,
        f.height as usize,
        f.axis,
        f.channels,
    )];
    film.store_into(&mut t);
    t[0].data.iter().chain(&t[0].steady).map(|v| v.to_bits()).collect()
}

#[test]
fn path_tracer_and_bdpt_contributions_reach_any_sink_with_their_strategy() {
    let mut scene = common::load("cornell_box.toml");
    scene.film.width = 8;
    scene.film.height = 8;
    let bounces = 4;
    scene.integrator.max_bounces = bounces;
    let device = Device::new("").unwrap();
    let ctx = RenderContext::new(&scene, &device).unwrap();
    let (mut rec, mut rec_b) = (Recorder::default(), Recorder::default());
    let mut film = ctx.tile_film(0, 0, 8, 8, 0);
    let mut bfilm = BdptFilm::new(&ctx, (0, 0, 8, 8), 0, false, true);
    let mut counts = PathCounts::default();
    let mut scratch = bdpt::Scratch::<f32x8, 3>::default();
    for s in 0..4 {
        for y in 0..8 {
            let lanes = PacketLanes::row(0, y, 8, 8, 4, s);
            trace_packet::<f32x8, 3, _>(&ctx, 7, &lanes, &mut rec, &mut counts);
            trace_packet::<f32x8, 3, _>(&ctx, 7, &lanes, &mut film, &mut counts);
            bdpt::trace_packet::<f32x8, 3, _>(&ctx, 7, &lanes, &mut rec_b, &mut counts, &mut scratch);
            bdpt::trace_packet::<f32x8, 3, _>(&ctx, 7, &lanes, &mut bfilm, &mut counts, &mut scratch);
        }
    }
    let b = bounces as usize;
    // the path tracer: emission found at vertex k is (0, k + 1), next-event (1, k + 1)
    assert!(rec.got.iter().any(|g| g.0 == (0, 2)), "the lamp seen directly");
    assert!(rec.got.iter().any(|g| g.0.0 == 1), "next-event estimation");
    for (st, ..) in &rec.got {
        assert!(
            st.0 <= 1 && st.1 >= 2 && st.0 + st.1 <= b + 2,
            "path tracer strategy {st:?}"
        );
    }
    // BDPT: every strategy of a path with at most `bounces` scattering vertices, (1, 1) left out
    let mut seen = std::collections::BTreeSet::new();
    for (st, ..) in &rec_b.got {
        assert!(
            st.0 + st.1 >= 2 && st.0 + st.1 <= b + 2 && *st != (1, 1),
            "BDPT strategy {st:?}"
        );
        seen.insert(*st);
    }
    assert!(
        seen.contains(&(0, 2)) && seen.contains(&(2, 1)) && seen.contains(&(1, 3)),
        "{seen:?}"
    );
    // what a sink receives is the whole contribution: replayed, it gives the film's bytes
    let mut again = ctx.tile_film(0, 0, 8, 8, 0);
    replay(&ctx, &rec, &mut again);
    assert_eq!(bits(&again, &ctx), bits(&film, &ctx));
    let mut again_b = ctx.tile_film(0, 0, 8, 8, 0);
    replay(&ctx, &rec_b, &mut again_b);
    assert_eq!(bits(&again_b, &ctx), bits(&bfilm.film, &ctx));
}

/// A BDPT unit (one tile) keeps its light-tracing splats onto other pixels and adds them, with
/// its tile's film, to the frame's rows (`bdpt::film`): the frame then holds the bytes of a
/// full-frame film that took the same contributions directly (each pixel receives either the
/// tile's own sums or splats, in the order they were made).
#[test]
fn a_bdpt_unit_and_its_splats_add_up_to_a_full_frame_film() {
    let scene = common::cornell(16, 16, 4);
    let device = Device::new("").unwrap();
    let ctx = RenderContext::new(&scene, &device).unwrap();
    let mut full = BdptFilm::new(&ctx, (0, 0, 16, 16), 0, false, false);
    let mut unit = BdptFilm::new(&ctx, (8, 0, 8, 8), 0, false, true);
    let mut counts = PathCounts::default();
    let mut scratch = bdpt::Scratch::<f32x8, 3>::default();
    for s in 0..4 {
        for y in 0..8 {
            let lanes = PacketLanes::row(8, y, 8, 16, 4, s);
            bdpt::trace_packet::<f32x8, 3, _>(&ctx, 7, &lanes, &mut full, &mut counts, &mut scratch);
            bdpt::trace_packet::<f32x8, 3, _>(&ctx, 7, &lanes, &mut unit, &mut counts, &mut scratch);
        }
    }
    assert!(
        unit.outside_splats() > 100,
        "{} splats onto other tiles",
        unit.outside_splats()
    );
    let f = &scene.film;
    let frame = || vec![difftransient::Transient::zeros(16, 16, f.axis, f.channels)];
    let mut from_rows = frame();
    for y in 0..16 {
        let mut row = BdptFilm::new(&ctx, (0, y, 16, 1), 0, false, false);
        row.add_unit::<3>(&ctx, &unit);
        row.film.store_into(&mut from_rows);
    }
    let mut direct = frame();
    full.film.store_into(&mut direct);
    let bits = |t: &[difftransient::Transient]| -> Vec<u32> {
        t[0].data.iter().chain(&t[0].steady).map(|v| v.to_bits()).collect()
    };
    assert!(direct[0].data.iter().any(|&v| v > 0.0));
    assert_eq!(bits(&from_rows), bits(&direct));
}
