//! The Atari games from the command line, in a build with the `atari` feature (ROMs from
//! `scripts/setup.sh`): listed, suggested when misspelled, trained with the paper's Atari
//! configs (categorical policy over the minimal action set, 1 000-step trajectories), resumed
//! and evaluated.
#![cfg(feature = "atari")]

use std::path::Path;
use std::process::{Command, Output};

use apo_train::progress_csv;

fn apo(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_apo"))
        .args(args)
        .output()
        .expect("the apo binary runs")
}

fn ok(args: &[&str]) -> String {
    let out = apo(args);
    assert!(
        out.status.success(),
        "apo {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn config(algo: &str) -> String {
    format!(
        "{}/../../configs/atari/{algo}.toml",
        env!("CARGO_MANIFEST_DIR")
    )
}

fn text(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

#[test]
fn the_62_games_are_listed_and_misspellings_get_suggestions() {
    let list = ok(&["list"]);
    let games: Vec<&str> = list.lines().filter(|l| l.starts_with("ALE/")).collect();
    assert_eq!(games.len(), 62, "{list}");
    let pong = games
        .iter()
        .find(|l| l.starts_with("ALE/Pong-v5 "))
        .expect("Pong");
    let columns: Vec<&str> = pong.split_whitespace().collect();
    assert_eq!(columns, ["ALE/Pong-v5", "128", "discrete(6)", "27000"]);

    let out = apo(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "ALE/Pongg-v5",
        "--epochs",
        "1",
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        err.contains("unknown environment `ALE/Pongg-v5`") && err.contains("`ALE/Pong-v5`"),
        "{err}"
    );
    assert!(
        !err.contains("--features atari"),
        "the feature is on: {err}"
    );
}

#[test]
fn trains_resumes_and_evaluates_with_the_paper_configs() {
    let tmp = tempfile::tempdir().expect("tempdir");
    for (algo, game) in [("ppo", "ALE/Pong-v5"), ("apo", "ALE/Breakout-v5")] {
        let run = tmp.path().join(format!("{algo}-run"));
        let file = config(algo);
        let common = [
            "--config",
            &file,
            "--env",
            game,
            "--steps-per-epoch",
            "2500",
            "--seed",
            "3",
            "--quiet",
        ];
        let mut args = vec!["train", "--epochs", "1", "--out", text(&run)];
        args.extend_from_slice(&common);
        ok(&args);
        ok(&["train", "--resume", text(&run), "--epochs", "2", "--quiet"]);
        let rows = progress_csv::read(&run.join("progress.csv")).expect("progress");
        assert_eq!(rows.len(), 2, "{algo}");
        for row in &rows {
            assert_eq!(row.env_steps, 2500 * row.epoch as u64);
            assert!(
                row.episodes >= 2,
                "{algo}: trajectories are cut at 1 000 steps"
            );
            let len = row.ep_len_mean.expect("complete episodes");
            assert!(len <= 1000.0, "{algo}: mean episode length {len}");
            assert!(row.kl.is_finite() && row.loss_v.is_finite(), "{algo}");
            assert!(row.ep_ret_mean.is_some_and(f64::is_finite), "{algo}");
        }
        // the run's config is the paper's Atari config
        let written = std::fs::read_to_string(run.join("config.toml")).expect("config");
        assert!(written.contains("max_episode_steps = 1000"), "{written}");
        // resumed equals uninterrupted (the learning columns)
        let whole = tmp.path().join(format!("{algo}-whole"));
        let mut args = vec!["train", "--epochs", "2", "--out", text(&whole)];
        args.extend_from_slice(&common);
        ok(&args);
        let again = progress_csv::read(&whole.join("progress.csv")).expect("progress");
        let learning = |r: &progress_csv::ProgressRow| {
            (
                r.env_steps,
                r.episodes,
                r.ep_ret_mean,
                r.ep_ret_min,
                r.kl,
                r.loss_v,
            )
        };
        assert_eq!(
            rows.iter().map(learning).collect::<Vec<_>>(),
            again.iter().map(learning).collect::<Vec<_>>(),
            "{algo}"
        );
        // evaluation builds the game as the run did: episodes cut at 1 000 steps
        let eval = ok(&["eval", "--run", text(&run), "--episodes", "2"]);
        assert!(eval.contains("checkpoint_epoch=2 episodes=2 "), "{eval}");
        let length: f64 = eval
            .split("mean_length=")
            .nth(1)
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or_else(|| panic!("{eval}"));
        assert!(length <= 1000.0, "{eval}");
    }
}
