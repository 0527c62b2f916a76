//! apo-core's correctness tests against independent float64 references, on NdArray<f64> and
//! wgpu, as one test program (each program links Burn and wgpu once; one is much faster to
//! build than seven). The NdArray<f32> runs are a separate program, `tests/ndarray_f32.rs`,
//! because Burn keeps NdArray's float type per device for the whole process.

#[path = "../common/mod.rs"]
mod common;

mod baselines;
mod buffer;
mod distributions;
mod docs_links;
mod fisher;
mod hvp;
mod learner;
mod objectives;
mod proximal;
mod shaping;
mod trust_region;
mod variants;
