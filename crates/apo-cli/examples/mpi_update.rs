//! One update of a data-parallel job, for checking it against a one-process update.
//!
//! Every rank collects the same batch (2 000 steps of Pendulum-v1 under the initial policy,
//! seeded alike), keeps its contiguous share of the rows (`Batch::rows`), and runs one update of
//! `ALGO` over the union of the shares; each rank then writes its parameters and the update's
//! numbers to `OUT/rank<r>-of-<N>.json`. With `-n 1` that is the whole-batch update.
//!
//! ```text
//! cargo build --features mpi --example mpi_update
//! mpirun -n 2 target/debug/examples/mpi_update apo /tmp/out
//! ```

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;

use anyhow::Context;
use apo_core::{Algorithm, Learner};
use apo_envs::VecEnv;
use apo_train::mpi::Mpi;
use apo_train::run_config::RunConfig;
use apo_train::{action_kind, Actor, Collector, HostActor};
use burn::backend::NdArray;
use rand::rngs::StdRng;
use rand::SeedableRng;

fn main() -> anyhow::Result<()> {
    let mut args = std::env::args().skip(1);
    let usage = "usage: mpi_update ALGO OUT_DIR [KEY=VALUE …]";
    let algo: Algorithm = args
        .next()
        .context(usage)?
        .parse()
        .map_err(anyhow::Error::msg)?;
    let out = PathBuf::from(args.next().context(usage)?);
    let mpi = Mpi::init()?;
    let comm = mpi.comm();

    let sets: Vec<String> = args.collect();
    let mut config = RunConfig::build_with_preset(algo, "Pendulum-v1", None, None, &sets)?;
    config.train.num_envs = 1;
    let steps = 2000;
    let train = &config.train;
    let envs = VecEnv::make_with(&train.env, 1, &train.make_options())?;
    let (observation_dim, action) = (envs.obs_dim(), action_kind(envs.action_space()));
    let common = train.algo.common();
    let mut collector = Collector::from_envs(envs, steps, common.gamma, common.lambda, None);
    let value = train.value(observation_dim);
    let device = Default::default();
    let mut learner = Learner::<NdArray, _>::new(
        train.mlp_policy(observation_dim, action),
        action,
        &value,
        train.algo.clone(),
        &device,
        train.seed,
    )?;
    learner.set_kernels(config.kernels.resolve(config.backend));
    let mut actor = HostActor::from_learner(&learner, &value);
    let rollout = collector
        .collect(&mut actor, 11, &AtomicBool::new(false), &mut |_| {})
        .context("the rollout was stopped")?;

    let (rank, size, n) = (comm.rank(), comm.size(), rollout.batch.len);
    let share = rollout.batch.rows(rank * n / size..(rank + 1) * n / size);
    let before = learner.policy_params();
    learner.set_comm(comm);
    let report = learner.update(&share, &mut StdRng::seed_from_u64(5))?;

    let json = serde_json::json!({
        "rank": rank,
        "size": size,
        "rows": share.len,
        "loss_pi": report.loss_pi,
        "kl": report.kl,
        "loss_v": report.loss_v,
        "moved": before
            .iter()
            .zip(learner.policy_params())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max),
        "line_search": format!("{:?} {:?}", report.line_search, report.rejections),
        "multipliers": learner.multipliers().map(|m| vec![m.eta, m.alpha]).unwrap_or_default(),
        "policy": learner.policy_params(),
        "value": learner.value_params(),
    });
    std::fs::create_dir_all(&out)?;
    let path = out.join(format!("rank{rank}-of-{size}.json"));
    std::fs::write(&path, serde_json::to_vec(&json)?)
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}
