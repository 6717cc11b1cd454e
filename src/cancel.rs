//! Stopping a render from outside it: a flag its loops read between samples (the path
//! tracer's and BDPT's sample loops, the boundary stage's chunks). A cancelled render
//! returns [`crate::Error::Cancelled`] and no film. The Python package sets it when Ctrl-C
//! reaches the interpreter, so that a long render in a notebook stops without losing the
//! kernel.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// A flag shared by the render and whoever may stop it (clones share it).
#[derive(Clone, Debug, Default)]
pub struct Cancel(Arc<AtomicBool>);

impl Cancel {
    /// A flag not set.
    pub fn new() -> Self {
        Self::default()
    }

    /// Asks every render holding this flag to stop.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether [`Cancel::cancel`] was called.
    #[inline]
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::Cancel;
    use crate::scene::IntegratorKind;
    use crate::{Error, RenderOptions};
    use std::time::{Duration, Instant};

    /// Renders asked for weeks of samples (2³⁰ per pixel) stop within 5 s of the flag
    /// being set from another thread, and say so: the path tracer and BDPT, a derivative
    /// render whose parameter moves geometry (interior, then the boundary stage) and the
    /// adjoint. Before the flag, nothing could stop them but the end of the process.
    #[test]
    fn a_render_stops_when_cancelled_and_says_so() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/diff_room.toml");
        let scene = crate::Scene::load(&path, &[]).unwrap();
        let params = ["room_z".to_string()];
        let adjoint = crate::film::Transient::zeros(
            scene.film.width as usize,
            scene.film.height as usize,
            scene.film.axis,
            scene.film.channels,
        );
        type Job<'a> = Box<dyn Fn(&RenderOptions) -> Result<(), Error> + 'a>;
        let jobs: [(&str, Option<IntegratorKind>, Job); 4] = [
            ("path", None, Box::new(|o| crate::render(&scene, o).map(|_| ()))),
            (
                "bdpt",
                Some(IntegratorKind::Bdpt),
                Box::new(|o| crate::render(&scene, o).map(|_| ())),
            ),
            (
                "derivative",
                None,
                Box::new(|o| crate::render_diff(&scene, &params, o).map(|_| ())),
            ),
            (
                "adjoint",
                None,
                Box::new(|o| crate::adjoint::render_adjoint(&scene, &params, &adjoint, o).map(|_| ())),
            ),
        ];
        for (what, integrator, job) in jobs {
            let cancel = Cancel::new();
            let opts = RenderOptions {
                spp: Some(1 << 30),
                spp_boundary: Some(1 << 12),
                threads: Some(2),
                integrator,
                cancel: cancel.clone(),
                ..Default::default()
            };
            stops_when_cancelled(what, cancel, || job(&opts));
        }
    }

    /// Runs `job`, sets `cancel` 300 ms after it started, and checks that the job returned
    /// [`Error::Cancelled`] within 5 s.
    fn stops_when_cancelled(what: &str, cancel: Cancel, job: impl FnOnce() -> Result<(), Error>) {
        let start = Instant::now();
        let stopper = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(300));
            cancel.cancel();
        });
        let result = job();
        stopper.join().unwrap();
        assert!(matches!(result, Err(Error::Cancelled)), "{what}: {result:?}");
        eprintln!("{what}: stopped after {:?}", start.elapsed());
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "{what}: {:?}",
            start.elapsed()
        );
    }

    /// The secondary pass's pilot (an eighth of its samples) stops too: a scene whose moving
    /// occluder the camera never sees (no primary edges), one interior sample and 2²⁰
    /// boundary samples per pixel, so the pilot alone is 2²⁷ samples. Before, the flag was
    /// read only between the pass's batches, after the pilot.
    #[test]
    fn a_boundary_pilot_stops_when_cancelled() {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/shadow_hidden_occluder.toml");
        let scene = crate::Scene::load(&path, &[]).unwrap();
        let cancel = Cancel::new();
        let opts = RenderOptions {
            spp: Some(1),
            spp_boundary: Some(1 << 20),
            threads: Some(2),
            cancel: cancel.clone(),
            ..Default::default()
        };
        stops_when_cancelled("boundary pilot", cancel, || {
            crate::render_diff(&scene, &["occluder_x".to_string()], &opts).map(|_| ())
        });
    }
}
