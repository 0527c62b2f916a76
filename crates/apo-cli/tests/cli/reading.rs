//! Rule: reading results never guesses. Sweeps and reports refuse or report apart what they
//! would otherwise mix (another sweep, another epoch target, an unparsable cell, a bad row),
//! count each run once (by content, not path) and name gaps and rows left out.

use apo_core::Algorithm;

use super::*;

#[test]
fn a_finished_sweep_run_with_an_unparsable_cell_is_reported_and_left_alone() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let first = sweep(&out, "2", &[]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let run = out.join("CartPole-v1-ppo-s0");
    let progress = run.join("progress.csv");
    let csv = std::fs::read_to_string(&progress).expect("progress");
    let mut lines: Vec<String> = csv.lines().map(str::to_string).collect();
    lines[1] = lines[1].replacen(",", ",not-a-number", 2);
    std::fs::write(&progress, lines.join("\n") + "\n").expect("corrupt");
    let damaged = std::fs::read_to_string(&progress).expect("read");
    plant(&run, "checkpoints/mybest/best.pt", "keep me");
    let again = sweep(&out, "2", &[]);
    let (stdout, stderr) = (text(&again.stdout), text(&again.stderr));
    assert!(again.status.success(), "{stderr}");
    assert!(stdout.contains("skipped 1 finished before"), "{stdout}");
    assert!(
        stderr.contains("progress.csv") && stderr.contains("left out") && stderr.contains("line 2"),
        "{stderr}"
    );
    assert_eq!(
        std::fs::read_to_string(&progress).expect("read"),
        damaged,
        "untouched"
    );
    assert_eq!(
        std::fs::read_to_string(run.join("checkpoints/mybest/best.pt")).expect("kept"),
        "keep me"
    );
}

#[test]
fn sweeps_refuse_what_they_would_get_wrong() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("s");
    let base = [
        "sweep",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--out",
        path(&out),
    ];
    let cases: [(&[&str], &str); 9] = [
        (&["--algo", "ppo", "--grid", "seed=1,2"], "use --seeds"),
        (&["--algo", "ppo", "--grid", "epochs=1,2"], "use --epochs"),
        (
            &["--algo", "ppo", "--grid", "steps_per_epoch=200,400"],
            "use --steps-per-epoch",
        ),
        (&["--algo", "ppo", "--set", "env=Pendulum-v1"], "use --env"),
        (
            &["--algo", "ppo", "--seeds", "0,1,0"],
            "seed 0 is listed twice",
        ),
        (&["--algo", "ppo,ppo"], "are the same"),
        (&["--algo", "apo", "--grid", "algo.k=1,1.0"], "given twice"),
        (
            &["--algo", "apo", "--grid", "algo.k=1", "--grid", "algo.k=2"],
            "given twice",
        ),
        (
            &["--algo", "ppo", "--epochs", "18446744073709551615"],
            "epochs",
        ),
    ];
    for (extra, expected) in cases {
        let mut args = base.to_vec();
        args.extend_from_slice(extra);
        let err = fails(&args);
        assert!(err.contains(expected), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?} created the sweep folder");
    }
    let err = fails(&[
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "Hopper,Hopper-v4",
        "--out",
        path(&out),
    ]);
    assert!(err.contains("are the same"), "{err}");
    // a config file with one algorithm's section and a sweep of two: said before anything runs
    let config = tmp.path().join("apo.toml");
    std::fs::write(&config, ok(&["config", "--algo", "apo"])).expect("write");
    let err = fails(&[
        "sweep",
        "--algo",
        "apo,trpo",
        "--env",
        "CartPole-v1",
        "--config",
        path(&config),
        "--out",
        path(&out),
    ]);
    assert!(err.contains("[algo.apo]") && err.contains("trpo"), "{err}");
    // the sweep's --out is a file: named
    let file = tmp.path().join("file");
    std::fs::write(&file, "").expect("write");
    let err = fails(&[
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--seeds",
        "0",
        "--epochs",
        "1",
        "--out",
        path(&file),
    ]);
    assert!(
        err.contains(path(&file)) && err.contains("not a directory"),
        "{err}"
    );
    assert_eq!(
        err.matches("not a directory").count(),
        1,
        "said once: {err}"
    );
}

#[test]
fn grid_values_can_be_lists() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("s");
    let result = sweep(&out, "1", &["--grid", "hidden=[32,32],[16]"]);
    assert!(result.status.success(), "{}", text(&result.stderr));
    assert!(text(&result.stdout).contains("sweep: 2 runs"));
    for (name, hidden) in [
        ("CartPole-v1-ppo-hidden=[32,32]-s0", "[32, 32]"),
        ("CartPole-v1-ppo-hidden=[16]-s0", "[16]"),
    ] {
        let config = ok(&["config", "--run", path(&out.join(name))]);
        let compact: String = config.split_whitespace().collect();
        assert!(
            compact.contains(&format!("hidden={}", hidden.replace(' ', ""))),
            "{name}: {config}"
        );
    }
}

#[test]
fn report_and_summary_count_each_run_once_and_leave_out_bad_rows() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let runs = tmp.path().join("runs");
    for seed in ["0", "1"] {
        let dir = runs.join(format!("CartPole-v1-ppo-s{seed}"));
        let mut args = train_args(&dir, "ppo", "CartPole-v1", "2", "200");
        args.extend(["--seed", seed]);
        ok(&args);
    }
    let one = runs.join("CartPole-v1-ppo-s0");
    let report = ok(&["report", path(&runs), path(&one), "--random-episodes", "1"]);
    assert!(report.contains("| ppo | 2 |"), "{report}");
    // a report folder: apo rewrites its own report, never a user's file of the same name
    let folder = tmp.path().join("folder");
    ok(&[
        "report",
        path(&runs),
        "--random-episodes",
        "1",
        "--out",
        path(&folder),
    ]);
    ok(&[
        "report",
        path(&runs),
        "--random-episodes",
        "1",
        "--out",
        path(&folder),
    ]);
    let mine = tmp.path().join("mine");
    plant(&mine, "report.md", "my own report");
    let err = fails(&[
        "report",
        path(&runs),
        "--random-episodes",
        "1",
        "--out",
        path(&mine),
    ]);
    assert!(
        err.contains("report.md") && err.contains("not written by apo"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(mine.join("report.md")).expect("kept"),
        "my own report"
    );
    // a non-finite and a duplicated epoch row: left out with a warning, never a NaN in a table
    let progress = one.join("progress.csv");
    let csv = std::fs::read_to_string(&progress).expect("read");
    let lines: Vec<&str> = csv.lines().collect();
    let nan_row = {
        let header: Vec<&str> = lines[0].split(',').collect();
        let col = header
            .iter()
            .position(|h| *h == "ep_ret_mean")
            .expect("column");
        let mut cells: Vec<String> = lines[2].split(',').map(str::to_string).collect();
        cells[col] = "inf".to_string();
        cells.join(",")
    };
    let edited = format!("{}\n{}\n{}\n{}\n", lines[0], lines[1], lines[1], nan_row);
    std::fs::write(&progress, edited).expect("write");
    let out = apo(&["summary", path(&one), "--csv"]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("2 row(s) left out")
            && stderr.contains("repeated")
            && stderr.contains("inf"),
        "{stderr}"
    );
    assert!(
        !stdout.contains("NaN") && !stdout.contains(",inf"),
        "{stdout}"
    );
    let report = ok(&["report", path(&runs), "--random-episodes", "1"]);
    assert!(
        !report.contains("NaN") && !report.contains("inf ±"),
        "{report}"
    );
    assert!(report.contains("(1 incomplete)"), "{report}");
}

#[test]
fn the_same_run_under_two_paths_counts_once_and_gaps_in_epochs_are_named() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let (a, b, c) = (
        tmp.path().join("CartPole-v1-apo-s0"),
        tmp.path().join("copy/CartPole-v1-apo-s0"),
        tmp.path().join("CartPole-v1-apo-s1"),
    );
    super::sweep_report::run(&a, Algorithm::Apo, &[(10.0, 1.0), (20.0, 2.0)]);
    super::sweep_report::run(&b, Algorithm::Apo, &[(10.0, 1.0), (20.0, 2.0)]);
    // another seed is another run
    super::sweep_report::run(&c, Algorithm::Apo, &[(30.0, 3.0), (40.0, 4.0)]);
    let report = apo_cli::report::report(&[a.clone(), b.clone(), c.clone()], 1, &mut |_, _| {
        anyhow::bail!("no baseline in this test")
    })
    .expect("report");
    assert_eq!(report.groups.len(), 1);
    assert_eq!(
        report.groups[0].runs,
        vec![a.clone(), c.clone()],
        "the copy counts once"
    );

    // epochs 1, 2, 7: the gap is named, and the run's epochs are 7, not 3 rows
    let gap = tmp.path().join("gap");
    super::sweep_report::run(&gap, Algorithm::Apo, &[(1.0, 0.0), (2.0, 0.0), (3.0, 0.0)]);
    let mut rows = progress_csv::read(&gap.join("progress.csv")).expect("rows");
    rows[2].epoch = 7;
    progress_csv::write(&gap.join("progress.csv"), &rows).expect("write");
    let read = progress_csv::read_lenient(&gap.join("progress.csv"), false).expect("read");
    assert_eq!(read.missing, vec![(3, 6)]);
    assert_eq!(
        apo_cli::summary::summarize(&gap, 1)
            .expect("summary")
            .epochs,
        7
    );
    let out = super::apo(&["summary", path(&gap)]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.contains("3–6") && stderr.contains("missing"),
        "{stderr}"
    );
}

#[test]
fn reports_keep_epoch_targets_apart_join_aliases_and_name_missing_records() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let mixed = tmp.path().join("mixed");
    let train = |dir: &std::path::Path, env: &str, epochs: &str, seed: &str| {
        let mut args = train_args(dir, "ppo", env, epochs, "200");
        args.extend(["--seed", seed]);
        ok(&args);
    };
    train(&mixed.join("CartPole-v1-ppo-s0"), "CartPole", "2", "0");
    train(&mixed.join("CartPole-v1-ppo-s1"), "cartpole-v1", "3", "1");
    train(&mixed.join("CartPole-v1-ppo-s2"), "CartPole-v1", "3", "2");
    let out = apo(&["report", path(&mixed), "--reps", "10"]);
    let (stdout, stderr) = (text(&out.stdout), text(&out.stderr));
    assert!(out.status.success(), "{stderr}");
    assert!(
        stderr.contains("different epoch targets (2, 3)"),
        "{stderr}"
    );
    // one environment (the aliases joined), the 2- and 3-epoch runs apart
    assert!(
        !stdout.contains("### cartpole-v1") && !stdout.contains("### CartPole\n"),
        "{stdout}"
    );
    assert!(
        stdout.contains("epochs=2") && stdout.contains("epochs=3"),
        "{stdout}"
    );

    // rows missing at the end are named against the checkpoint
    let run = mixed.join("CartPole-v1-ppo-s2");
    let progress = run.join("progress.csv");
    let text_rows = std::fs::read_to_string(&progress).expect("read");
    let kept: Vec<&str> = text_rows.lines().take(3).collect();
    std::fs::write(&progress, kept.join("\n") + "\n").expect("write");
    let out = apo(&["summary", path(&run)]);
    let stderr = text(&out.stderr);
    assert!(
        stderr.contains("missing at the end (the checkpoint is at epoch 3)"),
        "{stderr}"
    );
    // a header that is not apo's is named by its column, in every reader and in resume alike
    std::fs::write(
        &progress,
        text_rows.replacen("ep_ret_mean", "ep_ret_avg", 1),
    )
    .expect("write");
    let says = "column 4 of the header, `ep_ret_avg`, is not a column of apo's progress file";
    let err = fails(&["summary", path(&run)]);
    assert!(err.contains(says), "{err}");
    let err = fails(&["train", "--resume", path(&run), "--quiet"]);
    assert!(err.contains(says), "resume: {err}");
    assert!(
        std::fs::read_to_string(&progress)
            .expect("read")
            .contains("ep_ret_avg"),
        "a refused resume rewrites nothing"
    );
    // a run without its records: named, in every reader
    std::fs::remove_file(&progress).expect("rm");
    for args in [
        vec!["summary", path(&run)],
        vec!["plot", path(&run), "--out", path(&tmp.path().join("x.png"))],
    ] {
        let err = fails(&args);
        assert!(
            err.contains("no progress.csv, although its checkpoint is at epoch 3"),
            "{args:?}: {err}"
        );
    }
}
