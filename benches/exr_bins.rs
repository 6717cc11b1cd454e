//! Time to write the EXR (one layer per time bin in a single part) against the number of bins, at
//! a fixed 32×32 RGB frame: the time per bin stays flat when writing is linear in the bins
//! (issue 14: it grew quadratically, 2000 bins in 5.5 s, while the exr crate's parallel
//! compressor cloned every layer's header for each block). `cargo bench --bench exr_bins`.

use difftransient::output::{FilmView, write_exr_layers_with_axis};
use std::time::Instant;

fn main() {
    let (h, w, c) = (32, 32, 3);
    let dir = tempfile::tempdir().expect("temporary folder");
    println!("bins  seconds (median of 3)  ms per bin");
    for bins in [250, 500, 1000, 2000, 4000] {
        let data: Vec<f32> = (0..h * w * bins * c).map(|i| (i % 97) as f32 * 0.01).collect();
        let film = FilmView {
            data: &data,
            height: h,
            width: w,
            bins,
            channels: c,
        };
        let steady = vec![1.0f32; h * w * c];
        let mut times: Vec<f64> = (0..3)
            .map(|k| {
                let t0 = Instant::now();
                let path = dir.path().join(format!("b{bins}_{k}.exr"));
                write_exr_layers_with_axis(&path, film, &steady, (0.0, 0.01)).expect("write");
                t0.elapsed().as_secs_f64()
            })
            .collect();
        times.sort_by(f64::total_cmp);
        println!(
            "{bins:5}  {:.3} ({:.3}–{:.3})  {:.3}",
            times[1],
            times[0],
            times[2],
            1e3 * times[1] / bins as f64
        );
    }
}
