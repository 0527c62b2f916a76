//! `apo plot` on hand-made run directories: non-finite and huge returns, title, ticks,
//! legend placement, smoothing and errors. The figures are SVG so that their text can be read.

use std::path::Path;

use apo_core::Algorithm;
use apo_train::progress_csv::{self, ProgressRow};
use apo_train::RunConfig;

use super::{apo_within, fails, ok, path};

/// An epoch's row with these returns (mean, min, max) after `env_steps` steps.
pub fn row(epoch: usize, env_steps: u64, mean: f64, min: f64, max: f64) -> ProgressRow {
    ProgressRow {
        epoch,
        env_steps,
        episodes: 4,
        ep_ret_mean: Some(mean),
        ep_ret_min: Some(min),
        ep_ret_max: Some(max),
        ep_ret_std: Some(1.0),
        ep_ret_cvar10: Some(min),
        ep_ret_q10: Some(min),
        ep_len_mean: Some(100.0),
        success_rate: None,
        bound: Some(mean),
        confidence: Some(0.5),
        kl: 0.01,
        entropy: 1.0,
        loss_pi: 0.0,
        loss_v: 1.0,
        mean_surr: 0.0,
        mean_variance: None,
        variance_mean: None,
        line_search: None,
        ls_rejected_kl: None,
        ls_rejected_objective: None,
        bias: None,
        min_j_sq_on: None,
        pi_steps: None,
        ratio_deviation: None,
        eta: None,
        alpha: None,
        unstable_episodes: 0,
        eval_ret_mean: None,
        eval_ret_min: None,
        eval_ret_cvar10: None,
        eval_ret_std: None,
        eval_len_mean: None,
        eval_unstable_episodes: None,
        steps_per_s: 1000.0,
        time_s: epoch as f64,
        rollout_s: 0.5,
        update_pi_s: 0.25,
        update_v_s: 0.25,
        eval_s: 0.0,
        sim_s: 0.4,
    }
}

/// A run directory of `algo` on `env` with these rows, as `apo train` leaves one.
fn run(dir: &Path, algo: Algorithm, env: &str, rows: &[ProgressRow]) {
    std::fs::create_dir_all(dir).expect("create run dir");
    std::fs::write(
        dir.join("config.toml"),
        RunConfig::defaults(algo, env).to_toml(),
    )
    .expect("write config.toml");
    progress_csv::write(&dir.join("progress.csv"), rows).expect("write progress.csv");
}

/// The texts of an SVG figure with the x coordinate of their anchor.
fn texts(svg: &Path) -> Vec<(f64, String)> {
    let svg = std::fs::read_to_string(svg).expect("read the svg");
    svg.split("<text")
        .skip(1)
        .map(|element| {
            let x = element
                .split("x=\"")
                .nth(1)
                .and_then(|s| s.split('"').next())
                .expect("a text's x");
            let content = element
                .split_once('>')
                .and_then(|(_, s)| s.split_once("</text>"))
                .expect("a text's content")
                .0;
            (x.parse().expect("numeric x"), content.trim().to_string())
        })
        .collect()
}

#[test]
fn plot_terminates_on_non_finite_and_huge_returns() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let figure = tmp.path().join("curves.svg");
    let figure = path(&figure);

    // inf, -inf and NaN returns are left out and counted
    let odd = tmp.path().join("odd");
    run(
        &odd,
        Algorithm::Ppo,
        "CartPole-v1",
        &[
            row(1, 1000, 10.0, 5.0, 20.0),
            row(2, 2000, f64::INFINITY, 8.0, 30.0),
            row(3, 3000, 30.0, f64::NEG_INFINITY, 40.0),
            row(4, 4000, 35.0, 20.0, f64::NAN),
            row(5, 5000, 40.0, 30.0, 50.0),
        ],
    );
    let out = apo_within(60, &["plot", path(&odd), "--out", figure, "--force"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("left out 3 non-finite return values") && stderr.contains(path(&odd)),
        "{stderr}"
    );
    assert!(texts(Path::new(figure))
        .iter()
        .any(|(_, t)| t.contains("3 non-finite values left out")));

    // a range wider than the largest f64 is a clear error naming the runs
    let (low, high) = (tmp.path().join("low"), tmp.path().join("high"));
    run(
        &low,
        Algorithm::Apo,
        "Hopper",
        &[row(1, 1000, -1e308, -1e308, -1e308)],
    );
    run(
        &high,
        Algorithm::Apo,
        "Hopper",
        &[row(1, 1000, 1e308, 1e308, 1e308)],
    );
    let out = apo_within(
        60,
        &["plot", path(&low), path(&high), "--out", figure, "--force"],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("too wide") && stderr.contains(path(&low)) && stderr.contains(path(&high)),
        "{stderr}"
    );

    // wide but representable ranges, a flat curve and tiny returns are drawn
    for (name, returns) in [
        ("wide", [-8e307, 8e307]),
        ("flat", [500.0, 500.0]),
        ("tiny", [1e-300, 3e-300]),
    ] {
        let dir = tmp.path().join(name);
        run(
            &dir,
            Algorithm::Trpo,
            "Hopper",
            &[
                row(1, 1000, returns[0], returns[0], returns[0]),
                row(2, 2000, returns[1], returns[1], returns[1]),
            ],
        );
        let out = apo_within(60, &["plot", path(&dir), "--out", figure, "--force"]);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }

    // no finite return at all
    let none = tmp.path().join("none");
    run(
        &none,
        Algorithm::Ppo,
        "CartPole-v1",
        &[row(1, 1000, f64::NAN, f64::NAN, f64::INFINITY)],
    );
    let out = apo_within(60, &["plot", path(&none), "--out", figure, "--force"]);
    assert!(!out.status.success());
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("no completed episode with a finite return")
    );
    // a column that is empty in every epoch (PPO has no line search) is named as such
    for column in ["line_search", "success_rate"] {
        let out = apo_within(
            60,
            &[
                "plot",
                path(&none),
                "--out",
                figure,
                "--force",
                "--column",
                column,
            ],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(&format!("`{column}`")) && err.contains("empty"),
            "{column}: {err}"
        );
    }
}

#[test]
fn plot_title_names_environments_and_algorithms() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let rows: Vec<ProgressRow> = (1..=5)
        .map(|e| row(e, 1000 * e as u64, e as f64, 0.0, 2.0 * e as f64))
        .collect();
    let (apo, trpo, cartpole) = (
        tmp.path().join("h-apo"),
        tmp.path().join("h-trpo"),
        tmp.path().join("c-ppo"),
    );
    run(&apo, Algorithm::Apo, "Hopper", &rows);
    run(&trpo, Algorithm::Trpo, "Hopper", &rows);
    run(&cartpole, Algorithm::Ppo, "CartPole-v1", &rows);
    let figure = tmp.path().join("curves.svg");
    for (runs, title) in [
        (vec![&apo, &trpo], "Hopper — apo, trpo"),
        (vec![&cartpole], "CartPole-v1 — ppo"),
        (
            vec![&apo, &cartpole, &trpo],
            "Hopper, CartPole-v1 — apo, ppo, trpo",
        ),
    ] {
        let mut args = vec!["plot"];
        args.extend(runs.iter().map(|r| path(r)));
        args.extend(["--out", path(&figure), "--force"]);
        ok(&args);
        let texts = texts(&figure);
        assert!(
            texts.iter().any(|(_, t)| t == title),
            "no title {title:?} in {texts:?}"
        );
        assert!(
            texts
                .iter()
                .any(|(_, t)| t.contains("mean (solid), min–max band, worst (dashed)")),
            "{texts:?}"
        );
    }
}

#[test]
fn plot_ticks_are_round_and_steps_have_suffixes() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("run");
    let rows: Vec<ProgressRow> = (1..=12)
        .map(|e| {
            row(
                e,
                100_000 * e as u64,
                0.1 * e as f64,
                0.1 * e as f64 - 0.3,
                0.1 * e as f64 + 0.3,
            )
        })
        .collect();
    run(&dir, Algorithm::Papo, "Pendulum-v1", &rows);
    let figure = tmp.path().join("curves.svg");
    ok(&["plot", path(&dir), "--out", path(&figure)]);
    let texts: Vec<String> = texts(&figure).into_iter().map(|(_, t)| t).collect();
    for label in ["0", "200k", "600k", "1M", "1.2M"] {
        assert!(
            texts.iter().any(|t| t == label),
            "no step tick {label:?} in {texts:?}"
        );
    }
    let numbers: Vec<&String> = texts.iter().filter(|t| t.parse::<f64>().is_ok()).collect();
    assert!(numbers.len() >= 4, "{texts:?}");
    for number in numbers {
        assert!(
            number
                .split_once('.')
                .is_none_or(|(_, decimals)| decimals.len() <= 2),
            "unround tick {number:?} in {texts:?}"
        );
    }
}

#[test]
fn plot_legend_is_beside_the_chart() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let rows: Vec<ProgressRow> = (1..=10)
        .map(|e| row(e, 10_000 * e as u64, 10.0 * e as f64, 0.0, 20.0 * e as f64))
        .collect();
    let (a, b) = (tmp.path().join("run-a"), tmp.path().join("run-b"));
    run(&a, Algorithm::Ppo, "CartPole-v1", &rows);
    run(&b, Algorithm::Ppo, "CartPole-v1", &rows);
    let figure = tmp.path().join("curves.svg");
    ok(&["plot", path(&a), path(&b), "--out", path(&figure)]);
    let texts = texts(&figure);
    // the rightmost tick label, the last step's (100k, or 100000), is centred on the chart's right edge
    let right_edge = texts
        .iter()
        .filter(|(_, t)| t.trim_end_matches('k').parse::<f64>().is_ok())
        .map(|&(x, _)| x)
        .fold(f64::MIN, f64::max);
    assert!(right_edge > 500.0, "{texts:?}");
    for label in ["run-a", "run-b", "mean return", "worst return"] {
        let (x, _) = texts
            .iter()
            .find(|(_, t)| t == label)
            .unwrap_or_else(|| panic!("no legend entry {label:?} in {texts:?}"));
        assert!(
            *x > right_edge,
            "legend entry {label:?} at x={x} lies inside the chart (right edge {right_edge})"
        );
    }
}

#[test]
fn plot_smooths_over_epochs() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("run");
    let rows: Vec<ProgressRow> = (1..=9)
        .map(|e| {
            let v = if e % 2 == 0 { 100.0 } else { 0.0 };
            row(e, 1000 * e as u64, v, v - 10.0, v + 10.0)
        })
        .collect();
    run(&dir, Algorithm::Ppo, "CartPole-v1", &rows);
    let (raw, smooth) = (tmp.path().join("raw.svg"), tmp.path().join("smooth.svg"));
    ok(&["plot", path(&dir), "--out", path(&raw), "--smooth", "1"]);
    ok(&["plot", path(&dir), "--out", path(&smooth), "--smooth", "3"]);
    let (raw_texts, smooth_texts) = (texts(&raw), texts(&smooth));
    assert!(
        smooth_texts
            .iter()
            .any(|(_, t)| t.contains("moving average over 3 epochs")),
        "{smooth_texts:?}"
    );
    assert!(
        !raw_texts.iter().any(|(_, t)| t.contains("moving average")),
        "{raw_texts:?}"
    );
    assert_ne!(
        std::fs::read(&raw).expect("raw"),
        std::fs::read(&smooth).expect("smooth")
    );
    let err = fails(&["plot", path(&dir), "--out", path(&raw), "--smooth", "0"]);
    assert!(err.contains("--smooth"), "{err}");
}

#[test]
fn plot_errors_name_the_culprit() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let good = tmp.path().join("good");
    run(
        &good,
        Algorithm::Ppo,
        "CartPole-v1",
        &[row(1, 1000, 1.0, 0.0, 2.0)],
    );
    let figure = tmp.path().join("curves.png");

    let garbled = tmp.path().join("garbled");
    run(
        &garbled,
        Algorithm::Ppo,
        "CartPole-v1",
        &[row(1, 1000, 1.0, 0.0, 2.0)],
    );
    std::fs::write(
        garbled.join("progress.csv"),
        "epoch,env_steps\nnot,numbers\n",
    )
    .expect("garble");
    let err = fails(&["plot", path(&good), path(&garbled), "--out", path(&figure)]);
    assert!(err.contains(path(&garbled.join("progress.csv"))), "{err}");

    let missing = tmp.path().join("missing");
    let err = fails(&["plot", path(&missing), "--out", path(&figure)]);
    assert!(
        err.contains(path(&missing)) && err.contains("config.toml"),
        "{err}"
    );

    let err = fails(&[
        "plot",
        path(&good),
        "--out",
        path(&tmp.path().join("no-such-dir/curves.png")),
    ]);
    assert!(
        err.contains("--out") && err.contains("no-such-dir") && err.contains("does not exist"),
        "{err}"
    );
    assert!(!figure.exists());
}
