//! APO on MuJoCo Hopper from your own program, through the same loop as `apo train`.
//!
//! Run with `cargo run --release -p apo-train --example train_hopper -- [EPOCHS] [STEPS_PER_EPOCH]`
//! (default 10 epochs of 4 000 steps).

use std::sync::atomic::AtomicBool;

use apo_core::{Algorithm, Kernels};
use apo_train::{TrainConfig, Trainer};
use burn::backend::NdArray;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let arg = |i: usize, default: usize| std::env::args().nth(i).map_or(Ok(default), |a| a.parse());
    let mut config = TrainConfig::defaults(Algorithm::Apo, "Hopper-v4");
    config.epochs = arg(1, 10)?;
    config.steps_per_epoch = arg(2, 4_000)?;
    config.num_envs = 4;

    // the updates on Burn's NdArray backend, its Fisher products and value fit on host kernels;
    // the environments on every core (0)
    let mut trainer = Trainer::<NdArray, _, _>::mlp(config, &Default::default(), 0)?;
    trainer.learner_mut().set_kernels(Kernels::Host);

    let stop = AtomicBool::new(false); // raise it (e.g. from a signal handler) to stop early
    while let Some(epoch) = trainer.epoch(&stop, &mut |_steps| {})? {
        let row = &epoch.row;
        println!(
            "epoch {:3}  steps {:7}  return mean {:8.2}  worst {:8.2}  bound J-kV {:10.2}  kl {:.4}",
            row.epoch,
            row.env_steps,
            row.ep_ret_mean.unwrap_or(f64::NAN),
            row.ep_ret_min.unwrap_or(f64::NAN),
            row.bound.unwrap_or(f64::NAN),
            row.kl,
        );
    }
    Ok(())
}
