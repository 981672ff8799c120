//! The compute pool (`set_compute_threads`): streams and batched rounds computed with tract's
//! matrix products split over 2 threads equal the same computed on the calling thread alone,
//! bit for bit (each output tile is computed by one thread, in the same order), and the setting
//! is reported, bounded and reverts. One test in its own binary: the setting is process-wide.

mod common;

use common::*;
use troupe::{set_compute_threads, Error};

fn stream_and_round() -> (Vec<f32>, Vec<Vec<f32>>) {
    let model = model();
    let actor = actor();
    let mut alone = model.session(default_options()).unwrap();
    let frames = alone.step(actor.view()).unwrap();
    let mut a = model.session(default_options()).unwrap();
    let mut b = model.session(default_options()).unwrap();
    let chunk = actor.slice(ndarray::s![..40, ..]).to_owned();
    let slice = chunk.as_slice().unwrap();
    let outs = troupe::step_sessions(&mut [&mut a, &mut b], &[slice, slice]).unwrap();
    let round = outs
        .into_iter()
        .map(|o| o.frames.into_raw_vec_and_offset().0)
        .collect();
    (frames.into_raw_vec_and_offset().0, round)
}

/// Threads of this process named `troupe-compute-N` (Linux: `/proc/self/task/*/comm`).
fn pool_threads() -> usize {
    std::fs::read_dir("/proc/self/task")
        .expect("Linux /proc")
        .filter_map(|t| std::fs::read_to_string(t.ok()?.path().join("comm")).ok())
        .filter(|name| name.starts_with("troupe-compute"))
        .count()
}

#[test]
fn a_compute_pool_changes_no_output_and_the_setting_is_bounded() {
    assert_eq!(troupe::compute_threads(), 1, "one thread by default");
    let single = stream_and_round();
    // The tiny bundle's products are below tract's size gates: thread every one of them.
    tract_linalg::multithread::set_threading_panel_threshold(0);
    tract_linalg::multithread::set_threading_mac_threshold(0);
    tract_linalg::multithread::set_threading_element_threshold(0);
    set_compute_threads(2).unwrap();
    assert_eq!(troupe::compute_threads(), 2);
    let pooled = stream_and_round();
    assert!(single == pooled, "2 compute threads changed the output");
    assert_eq!(pool_threads(), 2, "the pool's threads run");
    assert!(matches!(
        set_compute_threads(5000),
        Err(Error::InvalidOption(_))
    ));
    assert_eq!(
        troupe::compute_threads(),
        2,
        "a refused setting leaves the pool"
    );
    set_compute_threads(1).unwrap();
    assert_eq!(troupe::compute_threads(), 1);
    assert!(stream_and_round() == single);
}
