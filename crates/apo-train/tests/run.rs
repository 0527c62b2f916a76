//! A run in a directory through the public API: created, trained, stopped, dropped, resumed
//! from its files — bit-identical to a run that never stopped — and the progress it reports.

use std::path::Path;
use std::sync::atomic::AtomicBool;

use apo_core::Algorithm;
use apo_train::checkpoint::Which;
use apo_train::playback::LoadedRun;
use apo_train::progress_csv::{self, ProgressRow};
use apo_train::run::{Launch, Run};
use apo_train::RunConfig;
use burn::backend::NdArray;

fn small(algo: Algorithm, env: &str, epochs: usize) -> RunConfig {
    let mut config = RunConfig::defaults(algo, env);
    config.train.epochs = epochs;
    config.train.steps_per_epoch = 200;
    config.train.num_envs = 2;
    config.train.hidden = vec![16];
    config
}

/// Trains the run in `dir` to its end, or for `epochs` epochs when given; returns the rows.
fn train(run: &mut Run<NdArray>, epochs: Option<usize>) -> Vec<ProgressRow> {
    let stop = AtomicBool::new(false);
    let mut rows = Vec::new();
    while epochs.is_none_or(|n| rows.len() < n) {
        match run.epoch(&stop, &mut |_| {}).expect("an epoch") {
            Some(row) => rows.push(row),
            None => break,
        }
    }
    rows
}

fn timeless(rows: Vec<ProgressRow>) -> Vec<ProgressRow> {
    rows.into_iter().map(ProgressRow::timeless).collect()
}

fn rows_on_disk(dir: &Path) -> Vec<ProgressRow> {
    timeless(progress_csv::read(&dir.join("progress.csv")).expect("progress.csv"))
}

/// What a checkpoint of the run in `dir` plays: its epoch, its policy's weights and its
/// observation normalizer (by their exact `Debug` text: shortest round-trip floats).
fn played(dir: &Path, which: &Which) -> (usize, String, String) {
    let loaded = LoadedRun::load(dir, which)
        .unwrap_or_else(|e| panic!("{} {which:?}: {e:#}", dir.display()));
    (
        loaded.epoch,
        format!("{:?}", loaded.policy),
        format!("{:?}", loaded.normalizer),
    )
}

/// Every algorithm, resumed at two points — once from a checkpoint it wrote when asked, once
/// after it was dropped past its checkpoint (as a killed process is, between the two writes of
/// a kept epoch), so that an epoch it had recorded is run again — ends bit-identical to a run
/// that never stopped: its networks, every column of `progress.csv` but the times (V-MPO's
/// learned temperature included), `episodes.csv`, and the policy and normalizer of the
/// checkpoints it keeps (`epoch-<N>`, `best`, `latest`).
#[test]
fn every_algorithm_resumed_at_two_points_equals_a_run_that_never_stopped() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let device = Default::default();
    for &algo in Algorithm::ALL {
        let (straight, split) = (
            tmp.path().join(format!("{algo}-straight")),
            tmp.path().join(format!("{algo}-split")),
        );
        let mut config = small(algo, "CartPole-v1", 6);
        // the normalizer's statistics travel in state.json, as the cap of return capping does
        config.train.normalize_obs = true;
        config.train.checkpoint_every = 3;
        config.train.keep_checkpoint_every = 2;
        config.train.eval_every = 2;
        config.train.eval_episodes = 1;
        config.train.max_episode_steps = 50;
        let mut run =
            Run::<NdArray>::create(&straight, config.clone(), &Launch::new(1), &device, false)
                .expect("a new run");
        assert_eq!(train(&mut run, None).len(), 6);
        assert!(run.finished() && !run.interrupted());
        let params = (
            run.trainer().learner().policy_params(),
            run.trainer().learner().value_params(),
        );
        drop(run);

        // the first stop: a checkpoint at epoch 2, asked for
        let mut run = Run::<NdArray>::create(&split, config, &Launch::new(1), &device, false)
            .expect("a new run");
        assert_eq!(train(&mut run, Some(2)).len(), 2);
        run.checkpoint().expect("a checkpoint");
        drop(run);
        let state = std::fs::read_to_string(split.join("checkpoints/latest/state.json"))
            .expect("state.json");
        assert_eq!(
            state.contains("\"cap\""),
            algo == Algorithm::Retcap,
            "{algo}: the cap is in the checkpoint exactly for return capping: {state}"
        );
        // the second: dropped after epoch 5 (no checkpoint is due at 5), and stopped between
        // epoch 4's two writes (`latest`, then the kept `epoch-000004`): epoch 5 is run again,
        // and the kept checkpoint made again on resume
        let mut run =
            Run::<NdArray>::resume(&split, &Launch::new(1), &device, None).expect("resumes");
        assert_eq!(run.epochs_done(), 2);
        assert_eq!(train(&mut run, Some(3)).len(), 3);
        drop(run);
        std::fs::remove_dir_all(split.join("checkpoints/epoch-000004")).expect("rm");
        let mut run =
            Run::<NdArray>::resume(&split, &Launch::new(1), &device, None).expect("resumes");
        assert_eq!(
            run.epochs_done(),
            4,
            "{algo}: resumed from the kept epoch 4"
        );
        assert!(
            split.join("checkpoints/epoch-000004").is_dir(),
            "{algo}: made again"
        );
        assert_eq!(train(&mut run, None).len(), 2);
        assert!(run.finished());
        assert_eq!(
            (
                run.trainer().learner().policy_params(),
                run.trainer().learner().value_params()
            ),
            params,
            "{algo}: the networks after 2 + 2 (+ 1 lost) + 2 epochs equal those after 6"
        );
        drop(run);
        assert_eq!(
            rows_on_disk(&split),
            rows_on_disk(&straight),
            "{algo}: progress.csv"
        );
        let episodes = |dir: &Path| std::fs::read(dir.join("episodes.csv")).expect("episodes.csv");
        assert_eq!(
            episodes(&split),
            episodes(&straight),
            "{algo}: episodes.csv"
        );
        for which in [
            Which::Epoch(2),
            Which::Epoch(4),
            Which::Epoch(6),
            Which::Best,
            Which::Latest,
        ] {
            assert_eq!(
                played(&split, &which),
                played(&straight, &which),
                "{algo}: the checkpoint {which:?} differs from the run that never stopped"
            );
        }
    }
}

#[test]
fn a_raised_stop_checkpoints_the_epoch_and_resume_raises_the_target() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("run");
    let device = Default::default();
    let mut run = Run::<NdArray>::create(
        &dir,
        small(Algorithm::Trpo, "CartPole-v1", 3),
        &Launch::new(1),
        &device,
        false,
    )
    .expect("a new run");
    let stop = AtomicBool::new(false);
    assert!(run.epoch(&stop, &mut |_| {}).expect("epoch 1").is_some());
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    // the epoch under way ends (its rollout may be in already: the pipelined schedule), then
    // the run stops with a checkpoint of it
    while run.epoch(&stop, &mut |_| {}).expect("stopping").is_some() {}
    assert!(run.interrupted() && !run.finished());
    let done = run.epochs_done();
    assert!((1..=2).contains(&done), "{done}");
    drop(run);
    assert_eq!(
        apo_train::checkpoint::latest_epoch(&dir).expect("readable"),
        Some(done)
    );
    // a locked run is not resumed twice; a dropped one is
    let mut run = Run::<NdArray>::resume(&dir, &Launch::new(1), &device, Some(4)).expect("resumes");
    let err = Run::<NdArray>::resume(&dir, &Launch::new(1), &device, None)
        .err()
        .expect("the run is locked");
    assert!(
        format!("{err:#}").contains("in use by another apo process"),
        "{err:#}"
    );
    assert_eq!(
        train(&mut run, None).len(),
        4 - done,
        "epochs {}..=4",
        done + 1
    );
    drop(run);
    let config = RunConfig::load(&dir.join("config.toml")).expect("config.toml");
    assert_eq!(config.train.epochs, 4, "the new target is the run's");
}

#[test]
fn a_new_run_is_refused_in_a_folder_of_the_users_without_touching_it() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let device = Default::default();
    let mine = tmp.path().join("mine");
    std::fs::create_dir(&mine).expect("mkdir");
    std::fs::write(mine.join("notes.txt"), "mine").expect("write");
    let err = Run::<NdArray>::create(
        &mine,
        small(Algorithm::Apo, "Pendulum-v1", 1),
        &Launch::new(1),
        &device,
        true,
    )
    .err()
    .expect("refused");
    assert!(format!("{err:#}").contains("marker"), "{err:#}");
    assert_eq!(
        std::fs::read_to_string(mine.join("notes.txt")).expect("kept"),
        "mine"
    );
    assert_eq!(
        std::fs::read_dir(&mine).expect("ls").count(),
        1,
        "nothing written"
    );
}

#[test]
fn progress_advances_within_the_epoch() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let mut config = RunConfig::defaults(Algorithm::Ppo, "CartPole-v1");
    config.train.epochs = 2;
    config.train.steps_per_epoch = 1000;
    let mut run = Run::<NdArray>::create(
        tmp.path(),
        config,
        &Launch::new(1),
        &Default::default(),
        false,
    )
    .expect("a new run");
    let (mut steps, mut epochs) = (Vec::new(), Vec::new());
    let stop = AtomicBool::new(false);
    while let Some(row) = run.epoch(&stop, &mut |s| steps.push(s)).expect("an epoch") {
        epochs.push(row.epoch);
    }
    assert!(run.finished());
    assert_eq!(epochs, vec![1, 2]);
    let every = apo_train::rollout::PROGRESS_EVERY as u64;
    let expected: Vec<u64> = (0..1000)
        .step_by(every as usize)
        .chain((1000..2000).step_by(every as usize))
        .collect();
    assert_eq!(
        steps, expected,
        "steps reported every {every} steps within each epoch"
    );
}

/// Copies the directory tree `from` into `to`.
fn copy_tree(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("mkdir");
    for entry in std::fs::read_dir(from).expect("read_dir") {
        let entry = entry.expect("entry");
        let target = to.join(entry.file_name());
        if entry.file_type().expect("type").is_dir() {
            copy_tree(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).expect("copy");
        }
    }
}

/// A run written by an earlier version (`apo train --algo ppo --env CartPole-v1 --epochs 2
/// --steps-per-epoch 200 --set 'hidden=[8]'`, committed under `tests/fixtures/`): its
/// checkpoint passes the manifest's checks, loads for playback and resumes to a third epoch,
/// with its two recorded rows kept.
#[test]
fn a_checkpoint_written_by_an_earlier_version_loads_and_resumes() {
    let fixture =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/ppo-cartpole-2-epochs");
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("run");
    copy_tree(&fixture, &dir);
    let recorded = rows_on_disk(&dir);
    assert_eq!(recorded.len(), 2);

    let loaded = apo_train::playback::LoadedRun::load(&dir, &apo_train::checkpoint::Which::Latest)
        .expect("the checkpoint loads for playback");
    assert_eq!(loaded.epoch, 2);

    let device = Default::default();
    let mut run = Run::<NdArray>::resume(&dir, &Launch::new(1), &device, Some(3)).expect("resumes");
    assert_eq!(run.epochs_done(), 2);
    assert_eq!(train(&mut run, None).len(), 1);
    assert!(run.finished());
    drop(run);
    let rows = rows_on_disk(&dir);
    assert_eq!(rows.len(), 3);
    assert_eq!(
        rows[..2],
        recorded[..],
        "the recorded epochs are kept as they were"
    );
}
