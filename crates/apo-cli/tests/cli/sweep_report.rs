//! `apo report` on hand-made progress files, `apo sweep` end to end (resume, extension,
//! refusal of another sweep), and `--preset paper`.

use std::path::Path;

use apo_cli::report::{self, Baseline};
use apo_core::Algorithm;
use apo_train::progress_csv::{self, ProgressRow};
use apo_train::run_config::RunConfig;

use super::{apo, fails, files_under, ok, path, sweep, text, timeless, train_args};

/// An epoch's row with mean return `mean`, worst `min`, bound `bound` and confidence 0.5.
fn row(epoch: usize, mean: f64, min: f64, bound: f64) -> ProgressRow {
    ProgressRow {
        bound: Some(bound),
        ..super::plot::row(epoch, 1000 * epoch as u64, mean, min, mean + 1.0)
    }
}

/// A run directory of `algo` on CartPole with rows `(mean, min)` (bound = mean − 10).
pub fn run(dir: &Path, algo: Algorithm, rows: &[(f64, f64)]) {
    std::fs::create_dir_all(dir).expect("create run dir");
    let mut config = RunConfig::defaults(algo, "CartPole-v1");
    // complete runs: as many epochs as rows; the seed of the name's `-s<seed>`
    config.train.epochs = rows.len().max(1);
    let name = dir.file_name().map(|n| n.to_string_lossy().into_owned());
    if let Some(seed) = name
        .as_deref()
        .and_then(|n| n.rsplit_once("-s"))
        .and_then(|(_, s)| s.parse().ok())
    {
        config.train.seed = seed;
    }
    std::fs::write(dir.join("config.toml"), config.to_toml()).expect("write config.toml");
    let rows: Vec<ProgressRow> = rows
        .iter()
        .enumerate()
        .map(|(i, &(mean, min))| row(i + 1, mean, min, mean - 10.0))
        .collect();
    progress_csv::write(&dir.join("progress.csv"), &rows).expect("write progress.csv");
}

fn refs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

fn close(got: f64, want: f64) -> bool {
    (got - want).abs() < 1e-9
}

#[test]
fn report_numbers_by_hand() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let t = tmp.path();
    run(
        &t.join("CartPole-v1-apo-s0"),
        Algorithm::Apo,
        &[(10.0, 5.0), (20.0, 6.0), (30.0, 7.0)],
    );
    run(
        &t.join("CartPole-v1-apo-s1"),
        Algorithm::Apo,
        &[(20.0, 7.0), (30.0, 8.0), (40.0, 9.0)],
    );
    run(
        &t.join("CartPole-v1-trpo-s0"),
        Algorithm::Trpo,
        &[(10.0, 1.0); 3],
    );
    run(
        &t.join("CartPole-v1-trpo-s1"),
        Algorithm::Trpo,
        &[(20.0, 3.0); 3],
    );
    // a second setting of APO: its own group
    run(
        &t.join("CartPole-v1-apo-omega1=0.01-s0"),
        Algorithm::Apo,
        &[(1.0, 0.0); 3],
    );
    let runs = report::find_runs(&[t.to_path_buf()]).expect("runs");
    assert_eq!(runs.len(), 5);
    let report = report::report(&runs, 2, &mut |env, options| {
        assert_eq!(env, "CartPole-v1");
        // built as the runs were: their config's options, MuJoCo 2.2.2 spelled out
        let expected = apo_envs::MakeOptions {
            physics: Some(apo_envs::mujoco::Physics::Mujoco2),
            ..Default::default()
        };
        assert_eq!(options, &expected);
        Ok(Baseline {
            mean: 10.0,
            worst: 5.0,
            cvar10: 5.0,
            q10: 6.0,
        })
    })
    .expect("report");
    let labels: Vec<String> = report.groups.iter().map(|g| g.label()).collect();
    assert_eq!(labels, ["apo", "apo (omega1=0.01)", "trpo"]);
    let apo = &report.groups[0];
    assert_eq!(apo.runs.len(), 2);
    let stat = |s: Option<report::Stat>| s.map(|s| (s.mean, s.std)).expect("a value");
    // seeds: mean over all epochs 20 and 30; over the last 2: 25 and 35
    assert_eq!(stat(apo.mean_all), (25.0, 5.0));
    assert_eq!(stat(apo.mean_last), (30.0, 5.0));
    // worst: all 6 and 8; last 2: 6.5 and 8.5
    assert_eq!(stat(apo.worst_all), (7.0, 1.0));
    assert_eq!(stat(apo.worst_last), (7.5, 1.0));
    // bound = mean − 10 in every epoch
    assert_eq!(stat(apo.bound_last), (20.0, 5.0));
    assert_eq!(stat(apo.confidence_last), (0.5, 0.0));
    // TRPO: mean(last 2) 15, worst(last 2) 2; random 10 / 5
    // mean: Δ1 = 30 − 10 = 20, Δ2 = 15 − 10 = 5 → 4
    assert!(close(apo.score_mean.expect("score"), 4.0));
    // worst: Δ1 = 7.5 − 5 = 2.5, Δ2 = 2 − 5 = −3 (not both negative) → 2.5 / −3
    assert!(close(apo.score_worst.expect("score"), -2.5 / 3.0));
    // the weak APO setting: Δ1 = 1 − 10 = −9 and Δ2 = 5, then worst Δ1 = −5, Δ2 = −3 → 3/5
    let weak = &report.groups[1];
    assert!(close(weak.score_mean.expect("score"), -9.0 / 5.0));
    assert!(close(weak.score_worst.expect("score"), 0.6));
    let trpo = &report.groups[2];
    assert!(close(trpo.score_mean.expect("score"), 1.0));

    // APO is best in every metric on the one environment
    let counts = report::best_counts(&report);
    assert_eq!(
        counts,
        vec![
            ("apo".to_string(), [1, 1, 1, 1]),
            ("apo (omega1=0.01)".to_string(), [0, 0, 0, 0]),
            ("trpo".to_string(), [0, 0, 0, 0]),
        ]
    );
    let md = report::markdown(&report);
    assert!(md.contains("| apo | 2 | **25.00 ± 5.00** | **30.00 ± 5.00** | **7.00 ± 1.00** | **7.50 ± 1.00** | 20.00 ± 5.00 | 0.500 | 4.000 | -0.833 |"), "{md}");
    assert!(
        md.contains("Random policy: mean return 10.00, worst 5.00."),
        "{md}"
    );
    let csv = report::csv(&report).expect("csv");
    let mut reader = ::csv::Reader::from_reader(csv.as_bytes());
    let header = reader.headers().expect("header").clone();
    let records: Vec<::csv::StringRecord> = reader.records().map(|r| r.expect("record")).collect();
    assert_eq!(records.len(), 3);
    let field = |r: &::csv::StringRecord, name: &str| {
        let i = header.iter().position(|h| h == name).expect(name);
        r[i].to_string()
    };
    assert_eq!(field(&records[0], "mean_last2"), "30");
    assert_eq!(field(&records[0], "worst_all_std"), "1");
    assert_eq!(field(&records[1], "variant"), "omega1=0.01");
    assert_eq!(field(&records[2], "random_worst"), "5");

    // statistics over environments and runs; with TRPO normalization on the mean return
    // (last 2): random 10, TRPO's runs 10 and 20 (mean 15) score 0 and 2, APO's 25 and 35
    // score 3 and 5, the weak setting's 1 scores Δ1/Δ2 = −9/5
    let options = |normalization| report::StatsOptions {
        normalization,
        bootstrap: apo_cli::stats::StratifiedBootstrap {
            reps: 300,
            level: 0.95,
            seed: 1,
        },
    };
    let statistics = report::statistics(&report, &options(report::Normalization::Trpo));
    assert_eq!(statistics.len(), report::RunMetric::ALL.len());
    let of = |statistics: &[report::MetricStatistics], metric| {
        statistics
            .iter()
            .find(|m| m.metric == metric)
            .and_then(|m| m.analysis.clone())
            .expect("an analysis")
    };
    let a = of(&statistics, report::RunMetric::MeanLast);
    assert_eq!(a.tasks, ["CartPole-v1"]);
    let point = |a: &apo_cli::stats::Analysis, label: &str, aggregate: &str| {
        a.aggregates[label][aggregate].point
    };
    assert!(close(point(&a, "trpo", "mean"), 1.0));
    assert!(close(point(&a, "apo", "mean"), 4.0));
    assert!(close(point(&a, "apo", "iqm"), 4.0));
    assert!(close(point(&a, "apo (omega1=0.01)", "mean"), -1.8));
    // optimality gap: TRPO's scores clipped at 1 are 0 and 1
    assert!(close(point(&a, "trpo", "optimality_gap"), 0.5));
    let improvement = |a: &apo_cli::stats::Analysis, x: &str, y: &str| {
        a.probability_of_improvement
            .iter()
            .find(|p| p.x == x && p.y == y)
            .expect("a pair")
            .estimate
    };
    let p = improvement(&a, "apo", "trpo");
    assert_eq!((p.point, p.lower, p.upper), (1.0, 1.0, 1.0));
    // min–max over all runs (1 … 35): APO's 25 and 35 → 24/34 and 1
    let minmax = report::statistics(&report, &options(report::Normalization::MinMax));
    let a = of(&minmax, report::RunMetric::MeanLast);
    assert!(close(point(&a, "apo", "mean"), (24.0 / 34.0 + 1.0) / 2.0));
    assert!(close(point(&a, "apo (omega1=0.01)", "mean"), 0.0));
    // the risk metrics are there (rows with CVaR = worst return)
    let a = of(&minmax, report::RunMetric::Cvar10Last);
    assert!(close(
        point(&a, "apo", "mean"),
        of(&minmax, report::RunMetric::WorstLast).aggregates["apo"]["mean"].point
    ));
    let mut with = report.clone();
    with.statistics = statistics;
    let md = report::markdown(&with);
    assert!(
        md.contains("## Statistics over environments and runs"),
        "{md}"
    );
    assert!(md.contains("| apo | 2 | 4.000 ["), "{md}");
    assert!(md.contains("| apo | trpo | 1.000 [1.000, 1.000] |"), "{md}");
}

#[test]
fn variants_strip_environment_algorithm_and_seed() {
    let v = |name: &str, algo| report::variant(name, "Hopper-v4", algo);
    assert_eq!(v("Hopper-v4-apo-s0", Algorithm::Apo), "");
    assert_eq!(v("Hopper-apo-s12", Algorithm::Apo), "");
    assert_eq!(
        v(
            "Hopper-v4-papo-omega1=0.003-omega2=0.01-s2",
            Algorithm::Papo
        ),
        "omega1=0.003-omega2=0.01"
    );
    assert_eq!(v("Hopper-trpo-paper-s1", Algorithm::Trpo), "paper");
    assert_eq!(v("my-run", Algorithm::Trpo), "my-run");
    // a namespaced environment's runs are named with `_` for the `/`
    assert_eq!(
        report::variant("ALE_Pong-v5-ppo-s1", "ALE/Pong-v5", Algorithm::Ppo),
        ""
    );
    assert_eq!(apo_train::run_dir::env_label("ALE/Pong-v5"), "ALE_Pong-v5");
}

#[test]
fn report_command_writes_markdown_csv_and_curves() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let t = tmp.path();
    run(
        &t.join("runs/CartPole-v1-apo-s0"),
        Algorithm::Apo,
        &[(10.0, 5.0), (20.0, 6.0)],
    );
    run(
        &t.join("runs/CartPole-v1-trpo-s0"),
        Algorithm::Trpo,
        &[(15.0, 5.0), (15.0, 6.0)],
    );
    let out = t.join("report");
    let text = ok(&[
        "report",
        path(&t.join("runs")),
        "--last",
        "1",
        "--out",
        path(&out),
        "--random-episodes",
        "3",
    ]);
    assert!(text.contains("### CartPole-v1"), "{text}");
    // the random baseline is measured on the real environment: CartPole's random returns
    // are short episodes of a few tens of steps
    let line = text
        .lines()
        .find(|l| l.starts_with("Random policy"))
        .expect("baseline");
    let mean: f64 = line
        .split("mean return ")
        .nth(1)
        .and_then(|s| s.split(',').next())
        .and_then(|s| s.parse().ok())
        .expect("a number");
    assert!((5.0..100.0).contains(&mean), "{line}");
    assert!(
        text.contains("## Statistics over environments and runs"),
        "{text}"
    );
    assert!(text.contains("### worst return (last 1 epochs)"), "{text}");
    for file in [
        "report.md",
        "report.csv",
        "curves-CartPole-v1.png",
        "statistics.json",
        "profile-worst_last.png",
        "profile-cvar10_last.svg",
        "intervals-mean_last.png",
        "intervals-q10_last.svg",
    ] {
        let len = std::fs::metadata(out.join(file))
            .map(|m| m.len())
            .unwrap_or(0);
        assert!(len > 100, "{file}: {len} bytes");
    }
    let json: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(out.join("statistics.json")).expect("statistics.json"),
    )
    .expect("JSON");
    assert_eq!(json[3]["metric"], "worst_last");
    assert_eq!(json[3]["analysis"]["tasks"][0], "CartPole-v1");
    let err = fails(&["report", path(&t.join("nothing"))]);
    assert!(
        err.contains("neither a run directory nor a folder of runs"),
        "{err}"
    );
}

#[test]
fn sweep_runs_the_grid_resumes_extends_and_refuses_another_sweep() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let sweep = |epochs: &str, grid: &str| {
        vec![
            "sweep".to_string(),
            "--algo".into(),
            "apo,trpo".into(),
            "--env".into(),
            "CartPole".into(),
            "--seeds".into(),
            "0..2".into(),
            "--grid".into(),
            grid.into(),
            "--epochs".into(),
            epochs.into(),
            "--steps-per-epoch".into(),
            "300".into(),
            "--jobs".into(),
            "2".into(),
            "--last".into(),
            "1".into(),
            "--out".into(),
            path(&out).into(),
        ]
    };
    let run_sweep = |v: Vec<String>| ok(&refs(&v));
    let text = run_sweep(sweep("2", "algo.omega1=0.001,0.01"));
    assert!(text.contains("6 runs"), "{text}");
    let names = [
        "CartPole-v1-apo-omega1=0.001-s0",
        "CartPole-v1-apo-omega1=0.001-s1",
        "CartPole-v1-apo-omega1=0.01-s0",
        "CartPole-v1-apo-omega1=0.01-s1",
        "CartPole-v1-trpo-s0",
        "CartPole-v1-trpo-s1",
    ];
    for name in names {
        assert_eq!(apo_cli::sweep::epochs_done(&out.join(name)), 2, "{name}");
    }
    let config = RunConfig::load(&out.join(names[2]).join("config.toml")).expect("config");
    let apo_core::AlgoConfig::Apo(apo) = &config.train.algo else {
        panic!("an APO run")
    };
    assert_eq!(apo.omega1, 0.01);
    assert_eq!(config.train.seed, 0);
    assert_eq!(config.train.steps_per_epoch, 300);
    let cells = std::fs::read_to_string(out.join("cells.csv")).expect("cells.csv");
    assert_eq!(cells.lines().count(), 4, "{cells}");
    assert!(cells.contains("CartPole-v1,trpo,\"-\",2,"), "{cells}");

    // the same sweep again: everything is skipped
    let first = progress_csv::read(&out.join(names[0]).join("progress.csv")).expect("progress");
    let text = run_sweep(sweep("2", "algo.omega1=0.001,0.01"));
    assert!(text.contains("finished 0 (skipped 6"), "{text}");
    // a finished run kept as its results only (config.toml, progress.csv and the marker, as
    // a campaign commits them) is skipped too; a run kept without checkpoints whose progress
    // falls short stops the sweep (its recorded epochs are never trained over), and once the
    // user moves it away it is run anew
    let copy = tmp.path().join("copy");
    std::fs::create_dir(&copy).expect("mkdir");
    for file in ["sweep.toml", "cells.csv"] {
        std::fs::copy(out.join(file), copy.join(file)).expect("copy");
    }
    for name in names {
        std::fs::create_dir(copy.join(name)).expect("mkdir");
        for file in ["config.toml", "progress.csv", ".apo-run"] {
            std::fs::copy(out.join(name).join(file), copy.join(name).join(file)).expect("copy");
        }
    }
    let short = copy.join(names[5]).join("progress.csv");
    progress_csv::write(&short, &first[..1]).expect("write");
    let mut again = sweep("2", "algo.omega1=0.001,0.01");
    *again.last_mut().expect("--out") = path(&copy).into();
    let err = fails(&refs(&again));
    assert!(err.contains("never replaces recorded epochs"), "{err}");
    assert_eq!(progress_csv::read(&short).expect("kept").len(), 1);
    std::fs::remove_dir_all(copy.join(names[5])).expect("the user moves it away");
    let text = run_sweep(again);
    assert!(text.contains("finished 1 (skipped 5"), "{text}");
    assert_eq!(apo_cli::sweep::epochs_done(&copy.join(names[5])), 2);
    // more epochs: every run resumes from its checkpoint, its first epochs unchanged
    let text = run_sweep(sweep("3", "algo.omega1=0.001,0.01"));
    assert!(text.contains("finished 6 (skipped 0"), "{text}");
    let now = progress_csv::read(&out.join(names[0]).join("progress.csv")).expect("progress");
    assert_eq!(now.len(), 3);
    assert_eq!(
        now[..2].iter().map(|r| r.ep_ret_mean).collect::<Vec<_>>(),
        first.iter().map(|r| r.ep_ret_mean).collect::<Vec<_>>()
    );

    // a sweep with fewer epochs than its runs have mixes nothing: those runs are named apart
    let text = run_sweep(sweep("2", "algo.omega1=0.001,0.01"));
    assert!(text.contains("finished 0 (skipped 6"), "{text}");
    assert!(text.contains("2 of another epoch target"), "{text}");
    let cells = std::fs::read_to_string(out.join("cells.csv")).expect("cells.csv");
    assert!(
        cells.contains("CartPole-v1,trpo,\"-\",0,0,2,0,,,false"),
        "{cells}"
    );
    // a finished run whose records are gone is named, not counted, and its cell stays listed
    std::fs::remove_file(out.join(names[4]).join("progress.csv")).expect("rm");
    let text = run_sweep(sweep("3", "algo.omega1=0.001,0.01"));
    assert!(text.contains("finished 0 (skipped 6"), "{text}");
    assert!(
        text.contains("(1 seeds, left out: 1 without readable records)"),
        "{text}"
    );
    let cells = std::fs::read_to_string(out.join("cells.csv")).expect("cells.csv");
    assert!(cells.contains("CartPole-v1,trpo,\"-\",1,0,0,1,"), "{cells}");

    // another grid into the same folder is refused, naming what differs
    let err = fails(&refs(&sweep("2", "algo.omega1=0.003")));
    assert!(
        err.contains("holds another sweep") && err.contains("--grid"),
        "{err}"
    );
    // a key no algorithm has
    let err = fails(&[
        "sweep",
        "--algo",
        "trpo",
        "--env",
        "CartPole",
        "--grid",
        "algo.omega1=0.1",
        "--out",
        path(&tmp.path().join("x")),
    ]);
    assert!(err.contains("no algorithm of the sweep"), "{err}");
}

#[test]
fn the_paper_preset_sets_the_reference_choices() {
    let trpo = ok(&[
        "config", "--algo", "trpo", "--env", "Hopper", "--preset", "paper",
    ]);
    for line in [
        "cg_iters = 100",
        "cg_damping = 0.0",
        "actions = \"raw\"",
        "bootstrap_time_limit = false",
        "episode_reset = \"run_seed\"",
    ] {
        assert!(trpo.lines().any(|l| l == line), "{line} in\n{trpo}");
    }
    // the hands ran through the same Gymnasium loop: the same time-limit and reset choices
    let hand = ok(&[
        "config",
        "--algo",
        "papo",
        "--env",
        "HandReachDense",
        "--preset",
        "paper",
    ]);
    for line in [
        "bootstrap_time_limit = false",
        "episode_reset = \"run_seed\"",
    ] {
        assert!(hand.lines().any(|l| l == line), "{line} in\n{hand}");
    }
    // not a Gym MuJoCo task: no time-limit or reset change; a proximal method: no CG
    let ppo = ok(&[
        "config", "--algo", "ppo", "--env", "Pendulum", "--preset", "paper",
    ]);
    assert!(
        ppo.lines().any(|l| l == "bootstrap_time_limit = true"),
        "{ppo}"
    );
    assert!(
        ppo.lines().any(|l| l == "episode_reset = \"epoch\""),
        "{ppo}"
    );
    assert!(ppo.lines().any(|l| l == "actions = \"raw\""), "{ppo}");
    assert!(!ppo.contains("cg_iters"), "{ppo}");
    // A2C's single policy step; --set still wins over the preset
    let a2c = ok(&[
        "config",
        "--algo",
        "a2c",
        "--preset",
        "paper",
        "--set",
        "actions=\"rescale\"",
    ]);
    assert!(a2c.lines().any(|l| l == "iters = 1"), "{a2c}");
    assert!(a2c.lines().any(|l| l == "actions = \"rescale\""), "{a2c}");
    // the preset wins over a config file that spells out the defaults
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../../configs/trpo.toml");
    let with_file = ok(&[
        "config", "--algo", "trpo", "--config", file, "--env", "Hopper", "--preset", "paper",
    ]);
    assert!(
        with_file.lines().any(|l| l == "cg_iters = 100"),
        "{with_file}"
    );
    let defaults = ok(&["config", "--algo", "trpo", "--env", "Hopper"]);
    assert!(defaults.lines().any(|l| l == "cg_iters = 10"), "{defaults}");
}

/// A sweep is bound to its `--config` file's contents: run again after the file was edited
/// (or with another file of the same path), it is refused naming the file, since its runs hold
/// the old values.
#[test]
fn a_sweep_run_again_with_an_edited_config_file_is_refused() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let (config, out) = (tmp.path().join("c.toml"), tmp.path().join("sweep"));
    std::fs::write(&config, "env = \"CartPole-v1\"\n[algo.ppo]\nclip = 0.25\n").expect("write");
    let first = sweep(&out, "1", &["--config", path(&config)]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    std::fs::write(&config, "env = \"CartPole-v1\"\n[algo.ppo]\nclip = 0.35\n").expect("edit");
    let again = sweep(&out, "2", &["--config", path(&config)]);
    let err = text(&again.stderr);
    assert_eq!(again.status.code(), Some(1), "{err}");
    assert!(err.contains("the file's contents"), "{err}");
    let run_config = files_under(&out)
        .into_iter()
        .find(|p| p.ends_with("config.toml"))
        .expect("a run");
    let kept = std::fs::read_to_string(run_config).expect("read");
    assert!(kept.contains("clip = 0.25"), "{kept}");
}

/// A sweep trains only in the folders it made: a symbolic link, or a run of other settings, at
/// one of its runs' places stops the sweep before anything starts, naming it; the link's target
/// and the other run are untouched.
#[test]
fn a_sweep_refuses_a_link_or_a_foreign_run_in_its_place() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let first = sweep(&out, "1", &[]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let place = out.join("CartPole-v1-ppo-s0");
    assert!(place.is_dir(), "the sweep's run");
    let outside = tmp.path().join("outside");
    ok(&train_args(&outside, "ppo", "CartPole-v1", "1", "300"));
    let outside_progress = std::fs::read(outside.join("progress.csv")).expect("progress");
    std::fs::remove_dir_all(&place).expect("rm");
    std::os::unix::fs::symlink(&outside, &place).expect("symlink");
    let again = sweep(&out, "2", &[]);
    let err = text(&again.stderr);
    assert_eq!(again.status.code(), Some(1), "{err}");
    assert!(err.contains("symbolic link"), "{err}");
    std::fs::remove_file(&place).expect("rm link");
    let copy = std::process::Command::new("cp")
        .args(["-a", path(&outside), path(&place)])
        .status()
        .expect("cp");
    assert!(copy.success());
    let again = sweep(&out, "2", &[]);
    let err = text(&again.stderr);
    assert_eq!(again.status.code(), Some(1), "{err}");
    assert!(
        err.contains("other settings") && err.contains("steps_per_epoch"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(outside.join("progress.csv")).expect("kept"),
        outside_progress
    );
    assert_eq!(
        timeless(&place).len(),
        1,
        "the foreign run is not continued"
    );
    // a folder or a file of the user's at a run's place: named, with what to do, untouched
    std::fs::remove_dir_all(&place).expect("rm");
    for folder in [true, false] {
        if folder {
            std::fs::create_dir(&place).expect("user folder");
            std::fs::write(place.join("notes.txt"), b"mine").expect("user file");
        } else {
            std::fs::write(&place, b"mine").expect("user file");
        }
        let again = sweep(&out, "2", &[]);
        let err = text(&again.stderr);
        assert_eq!(again.status.code(), Some(1), "{err}");
        assert!(err.contains("move") && !err.contains("--force"), "{err}");
        if folder {
            assert_eq!(
                std::fs::read(place.join("notes.txt")).expect("kept"),
                b"mine"
            );
            std::fs::remove_dir_all(&place).expect("rm");
        } else {
            assert_eq!(std::fs::read(&place).expect("kept"), b"mine");
        }
    }
}

/// A sweep never trains over recorded epochs: a run kept without its checkpoints, short of a
/// raised target, stops the sweep before anything starts, its files kept.
#[test]
fn a_sweep_refuses_to_replace_a_run_with_recorded_epochs_and_no_checkpoint() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let first = sweep(&out, "1", &[]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let run = out.join("CartPole-v1-ppo-s0");
    std::fs::remove_dir_all(run.join("checkpoints")).expect("rm");
    let progress = std::fs::read(run.join("progress.csv")).expect("progress");
    let again = sweep(&out, "2", &[]);
    let err = text(&again.stderr);
    assert_eq!(again.status.code(), Some(1), "{err}");
    assert!(
        err.contains("no checkpoint") && err.contains("never replaces"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(run.join("progress.csv")).expect("kept"),
        progress
    );
}

/// The runs of a sweep are made from the `--config` text it recorded: a file edited while the
/// sweep runs changes none of them.
#[test]
fn a_config_file_edited_during_a_sweep_changes_none_of_its_runs() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let (config, out) = (tmp.path().join("c.toml"), tmp.path().join("sweep"));
    std::fs::write(&config, "env = \"CartPole-v1\"\n[algo.ppo]\ngamma = 0.99\n").expect("write");
    let child = super::spawn(&[
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--seeds",
        "0,1",
        "--epochs",
        "2",
        "--steps-per-epoch",
        "200",
        "--jobs",
        "1",
        "--quiet",
        "--config",
        path(&config),
        "--out",
        path(&out),
    ]);
    super::wait_for(&out.join("CartPole-v1-ppo-s0").join("progress.csv"));
    std::fs::write(&config, "env = \"CartPole-v1\"\n[algo.ppo]\ngamma = 0.5\n").expect("edit");
    let (code, _, stderr) = super::finish(child, 300);
    assert_eq!(code, Some(0), "{stderr}");
    for seed in ["0", "1"] {
        let run_config =
            std::fs::read_to_string(out.join(format!("CartPole-v1-ppo-s{seed}/config.toml")))
                .expect("config.toml");
        assert!(
            run_config.contains("gamma = 0.99"),
            "seed {seed}: {run_config}"
        );
    }
}

/// Rule: one sweep at a time in a sweep's directory: a second, started while the first runs,
/// is refused naming the first's process, and the first finishes untouched.
#[test]
fn a_second_sweep_of_a_running_sweeps_directory_is_refused() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let args = super::sweep_args(&out, "200");
    let child = super::spawn(&args);
    super::wait_for(&out.join("CartPole-v1-ppo-s0").join("progress.csv"));
    let second = apo(&args);
    let err = text(&second.stderr);
    assert!(!second.status.success(), "refused");
    assert!(
        err.contains("sweep directory") && err.contains("in use by another apo process"),
        "{err}"
    );
    super::signal(&child, "TERM");
    let (code, _, stderr) = super::finish(child, 120);
    assert_eq!(code, Some(143), "the first sweep stops as asked: {stderr}");
}

/// `summary` and `plot` read a sweep's folder as the runs directly inside it, as `report`
/// does; a folder that holds no run is named.
#[test]
fn summary_and_plot_read_a_sweep_folder_as_its_runs() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let done = sweep(&out, "2", &[]);
    assert!(done.status.success(), "{}", text(&done.stderr));
    let run = out.join("CartPole-v1-ppo-s0");
    let of_folder = ok(&["summary", path(&out), "--csv", "--last", "1"]);
    let of_run = ok(&["summary", path(&run), "--csv", "--last", "1"]);
    assert_eq!(of_folder.lines().count(), 2, "{of_folder}");
    // the same row, the run named by its path under the folder either way
    assert_eq!(of_folder, of_run);
    let png = tmp.path().join("curves.png");
    ok(&["plot", path(&out), "--out", path(&png)]);
    assert!(std::fs::metadata(&png).expect("plot written").len() > 0);
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).expect("folder");
    for command in ["summary", "plot"] {
        let mut args = vec![command, path(&empty)];
        if command == "plot" {
            args.extend(["--out", path(&png), "--force"]);
        }
        let failed = apo(&args);
        let err = text(&failed.stderr);
        assert_eq!(failed.status.code(), Some(1), "{command}: {err}");
        assert!(err.contains("holds no run directory"), "{command}: {err}");
    }
}

/// A key the sweep record does not know (an edit of `sweep.toml`) is refused by name, by the
/// next sweep and by `--status`, rather than dropped.
#[test]
fn a_sweep_record_with_an_unknown_key_is_refused_by_name() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let first = sweep(&out, "1", &[]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let record = out.join("sweep.toml");
    let mut edited = std::fs::read_to_string(&record).expect("record");
    edited.push_str("seedz = [1, 2]\n");
    std::fs::write(&record, &edited).expect("edit");
    let again = sweep(&out, "2", &[]);
    let status = apo(&["sweep", "--status", "--out", path(&out)]);
    for (what, done) in [("sweep", &again), ("--status", &status)] {
        let err = text(&done.stderr);
        assert_eq!(done.status.code(), Some(1), "{what}: {err}");
        assert!(
            err.contains("sweep.toml") && err.contains("seedz"),
            "{what}: {err}"
        );
    }
    // nothing was trained again: the run still ends at epoch 1
    let rows = timeless(&out.join("CartPole-v1-ppo-s0"));
    assert_eq!(rows.len(), 1);
}
