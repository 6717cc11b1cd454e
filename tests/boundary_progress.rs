//! The boundary stage reports its progress (issue 15): the secondary pass sets the bar's
//! length to its chunks and advances it to the end, for a whole render and for a shard.

use difftransient::boundary::{BoundarySettings, render_boundary};
use difftransient::integrator::RenderContext;
use difftransient::params::lanes::Motion;
use difftransient::{Scene, Shard};

#[test]
fn the_secondary_pass_advances_its_bar_to_the_end() {
    let path = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes/shadow_hidden_occluder.toml");
    let scene = Scene::load(&path, &[]).unwrap();
    let device = difftransient::accel::Device::new("").unwrap();
    let mut ctx = RenderContext::new(&scene, &device).unwrap();
    ctx.motion = Motion::build(&scene, &["occluder_x".to_string()]).unwrap();
    let pool = difftransient::render::thread_pool(Some(2)).unwrap();
    for shard in [Shard::WHOLE, Shard::new(1, 3).unwrap()] {
        let bar = indicatif::ProgressBar::hidden();
        let settings = BoundarySettings {
            spp_boundary: 8,
            seed: 1,
            guiding: false,
            shard,
            stages: Default::default(),
            progress: bar.clone(),
        };
        render_boundary(&mut ctx, &settings, &pool);
        let len = bar.length().unwrap();
        assert!(len > 0, "{shard:?}: no chunks");
        assert_eq!(bar.position(), len, "{shard:?}");
    }
}
