//! Criterion micro-benchmarks of the kernel's pieces.
//! - `dual`: a fixed chain of kernel-typical arithmetic (V3 dot/cross/normalize, div, sqrt) on
//!   f32x8 and on Dual8<P>, P ∈ {1, 2, 4, 8, 16}: the cost of each derivative lane.
//! - `correlation`: S_e and ∂S_e/∂d for one path (`Correlation::for_each`) per pulse/gate pair:
//!   delta, Gaussian and box pulses with a box gate, a box and a Gaussian pulse with a Gaussian
//!   gate (Gaussian⋆box and box⋆Gaussian evaluate the Gaussian CDF in every bin they touch);
//!   and `Correlation::tails` of a path whose Gaussian pulse straddles the window's start.
//! - `film`: adding one path to a 200-bin tile film, primal and with one derivative.
//!
//! Run: `cargo bench --bench micro`.

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use difftransient::film::{Accumulate, TileFilm};
use difftransient::kernel::{Dual8, Real, V3, f32x8};
use difftransient::temporal::{Correlation, Gate, Pulse, TimeAxis};
use std::hint::black_box;
use std::time::Duration;

fn chain<R: Real>(a: V3<R>, b: V3<R>) -> R {
    let n = a.cross(b).normalize();
    let d = (a - b).length();
    let g = n.dot(a).abs() * n.dot(b).abs() / (d * d + R::one());
    g.sqrt() + R::safe_div(g, d)
}

fn input<R: Real>(s: f32) -> (V3<R>, V3<R>) {
    let lanes: Vec<f32> = (0..8).map(|i| 0.3 + 0.1 * i as f32 + s).collect();
    let a = V3::new(R::from_lanes(&lanes), R::splat(1.0), R::splat(0.2)).add_scaled(V3::splat(glam::Vec3::X), R::one());
    let b = V3::new(R::splat(0.5), R::from_lanes(&lanes), R::splat(-0.7));
    (a.with_derivs(), b)
}

trait WithDerivs {
    fn with_derivs(self) -> Self;
}
impl<R: Real> WithDerivs for V3<R> {
    fn with_derivs(mut self) -> Self {
        for k in 0..R::DERIVS {
            self.x = self.x.with_deriv_lanes(k, &[1.0; 8]);
        }
        self
    }
}

fn bench_dual(c: &mut Criterion) {
    let mut g = c.benchmark_group("dual");
    g.throughput(Throughput::Elements(8));
    macro_rules! run {
        ($name:expr, $t:ty) => {
            let (a, b) = input::<$t>(0.0);
            g.bench_function($name, |bch| bch.iter(|| chain::<$t>(black_box(a), black_box(b))));
        };
    }
    run!("f32x8", f32x8);
    run!("Dual8<1>", Dual8<1>);
    run!("Dual8<2>", Dual8<2>);
    run!("Dual8<4>", Dual8<4>);
    run!("Dual8<8>", Dual8<8>);
    run!("Dual8<16>", Dual8<16>);
    g.finish();
}

fn bench_correlation(c: &mut Criterion) {
    let axis = TimeAxis {
        start_opl: 0.0,
        bin_width_opl: 0.03,
        bins: 200,
    };
    let mut g = c.benchmark_group("correlation");
    g.throughput(Throughput::Elements(1));
    for (name, p, gate) in [
        ("delta*box", Pulse::Delta, Gate::Box),
        ("gauss0.01*box", Pulse::Gaussian { sigma_opl: 0.01 }, Gate::Box),
        ("box0.05*box", Pulse::Box { width_opl: 0.05 }, Gate::Box),
        (
            "box0.05*gauss0.02",
            Pulse::Box { width_opl: 0.05 },
            Gate::Gaussian { sigma_opl: 0.02 },
        ),
        (
            "gauss0.01*gauss0.02",
            Pulse::Gaussian { sigma_opl: 0.01 },
            Gate::Gaussian { sigma_opl: 0.02 },
        ),
    ] {
        let corr = Correlation::new(axis, p, 0.0, gate).unwrap();
        let mut d = 3.0f64;
        g.bench_function(name, |b| {
            b.iter(|| {
                d = if d > 5.0 { 3.0 } else { d + 0.0137 };
                let mut acc = 0.0f64;
                corr.for_each(black_box(d), |_, s, ds| acc += s + ds);
                acc
            })
        });
    }
    // a Gaussian pulse around the window's start: both tails are its CDF at the axis' ends
    let corr = Correlation::new(axis, Pulse::Gaussian { sigma_opl: 0.01 }, 0.0, Gate::Box).unwrap();
    let mut d = -0.04f64;
    g.bench_function("tails gauss0.01*box", |b| {
        b.iter(|| {
            d = if d > 0.04 { -0.04 } else { d + 0.00137 };
            corr.tails(black_box(d))
        })
    });
    g.finish();
}

fn bench_film(c: &mut Criterion) {
    let axis = TimeAxis {
        start_opl: 0.0,
        bin_width_opl: 0.03,
        bins: 200,
    };
    let corr = Correlation::new(axis, Pulse::Gaussian { sigma_opl: 0.01 }, 0.0, Gate::Box).unwrap();
    let mut g = c.benchmark_group("film");
    g.throughput(Throughput::Elements(1));
    for ch in [1usize, 3] {
        let mut film = TileFilm::new(0, 0, 8, 8, &axis, ch, 1);
        let f = [0.5f32; 3];
        let mut d = 3.0f64;
        g.bench_function(format!("add C={ch}"), |b| {
            b.iter(|| {
                d = if d > 5.0 { 3.0 } else { d + 0.0137 };
                film.add(3, 4, &corr, black_box(d), &f[..ch]);
            })
        });
        g.bench_function(format!("add+1 derivative C={ch}"), |b| {
            b.iter(|| {
                d = if d > 5.0 { 3.0 } else { d + 0.0137 };
                film.add_with_derivs(3, 4, &corr, black_box(d), &f[..ch], &f[..ch], &[0.7]);
            })
        });
    }
    g.finish();
}

fn config() -> Criterion {
    Criterion::default()
        .measurement_time(Duration::from_millis(800))
        .warm_up_time(Duration::from_millis(300))
        .sample_size(20)
}

criterion_group!(name = micro; config = config(); targets = bench_dual, bench_correlation, bench_film);
criterion_main!(micro);
