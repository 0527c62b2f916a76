//! Rule: every number has a range. Every numeric config key of every algorithm documents a
//! finite range in `apo config`, and a value just outside it — above or below, or a number
//! TOML cannot hold — is refused with an error that names the key.

use std::collections::BTreeMap;

use super::*;

const ALGORITHMS: [&str; 12] = [
    "apo", "papo", "trpo", "ppo", "a2c", "espo", "vmpo", "alphappo", "mvpi", "cvar", "retcap",
    "tailppo",
];

/// `(full key, its documentation, its value)` of every key `apo config` prints (optional keys
/// that are unset, printed commented out, have an empty value).
fn documented_keys(algo: &str) -> Vec<(String, String, String)> {
    let text = ok(&["config", "--algo", algo, "--env", "CartPole-v1"]);
    let mut keys = Vec::new();
    let (mut section, mut doc) = (String::new(), String::new());
    for line in text.lines() {
        if let Some(table) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            section = format!("{table}.");
            doc.clear();
        } else if let Some(key) = line.strip_prefix("# ").and_then(|l| l.strip_suffix(" =")) {
            keys.push((
                format!("{section}{key}"),
                std::mem::take(&mut doc),
                String::new(),
            ));
        } else if let Some(comment) = line.strip_prefix("# ") {
            doc = comment.to_string();
        } else if let Some((key, value)) = line.split_once(" = ") {
            keys.push((
                format!("{section}{key}"),
                std::mem::take(&mut doc),
                value.to_string(),
            ));
        }
    }
    keys
}

/// The range at the end of a key's documentation: `a..=b` (integers) or `[a, b]`, `(a, b]`,
/// `[a, b)`, `(a, b)` (reals), as `(lower or None when it is another key, upper)`.
fn range(doc: &str) -> Option<(Option<f64>, f64)> {
    let tail = doc
        .rsplit(';')
        .find(|part| part.contains("..=") || part.contains(", "))?;
    if let Some((low, high)) = tail.split_once("..=") {
        let low = low.trim().rsplit(' ').next()?.trim();
        let high: f64 = high.trim().split([' ', ',']).next()?.parse().ok()?;
        return Some((low.parse().ok(), high));
    }
    let start = tail.rfind(['[', '('])?;
    let inner = &tail[start + 1..];
    let end = inner.find([']', ')'])?;
    let (low, high) = inner[..end].split_once(", ")?;
    Some((Some(low.trim().parse().ok()?), high.trim().parse().ok()?))
}

/// Whether `value` (as printed) is a number, or the key is an unset optional number.
fn numeric(key: &str, value: &str) -> bool {
    value.parse::<f64>().is_ok()
        || (value.is_empty()
            && ["minibatch_size", "target_kl"]
                .iter()
                .any(|k| key.ends_with(k)))
}

#[test]
fn every_numeric_key_documents_a_finite_range_and_refuses_values_outside_it() {
    let mut keys: BTreeMap<String, (String, String, String)> = BTreeMap::new();
    for algo in ALGORITHMS {
        for (key, doc, value) in documented_keys(algo) {
            keys.entry(key).or_insert((algo.to_string(), doc, value));
        }
    }
    let unranged: Vec<&String> = keys
        .iter()
        .filter(|(key, (_, doc, value))| numeric(key, value) && range(doc).is_none())
        .map(|(key, _)| key)
        .collect();
    assert!(
        unranged.is_empty(),
        "numeric keys without a documented range: {unranged:?}"
    );
    let mut checked = 0;
    for (key, (algo, doc, value)) in &keys {
        if !numeric(key, value) {
            continue;
        }
        let (low, high) = range(doc).expect("checked above");
        assert!(high.is_finite(), "{key}: {doc}");
        let integer = doc.contains("..=");
        let above = if integer {
            format!("{}", high as u64 + 1)
        } else {
            format!("{:e}", high * 2.0 + 1.0)
        };
        let mut outside = vec![
            above,
            "99999999999999999999".to_string(),
            "1e400".to_string(),
        ];
        if let Some(low) = low {
            outside.push(if integer {
                format!("{}", low as i64 - 1)
            } else {
                format!("{:e}", low - low.abs() - 1.0)
            });
        }
        for bad in outside {
            let out = apo(&[
                "config",
                "--algo",
                algo,
                "--env",
                "CartPole-v1",
                "--set",
                &format!("{key}={bad}"),
            ]);
            let err = String::from_utf8_lossy(&out.stderr);
            let last = key.rsplit('.').next().unwrap_or(key);
            assert!(!out.status.success(), "{key} = {bad} was accepted ({doc})");
            assert!(
                err.contains(last),
                "{key} = {bad}: the error does not name the key: {err}"
            );
            checked += 1;
        }
    }
    assert!(checked > 100, "only {checked} values checked");
}

#[test]
fn ranges_are_read_from_the_documentation() {
    assert_eq!(
        range("passes over the batch (paper: 80); 1..=10000"),
        Some((Some(1.0), 10000.0))
    );
    assert_eq!(
        range("KL radius δ (paper: 0.02); (0, 10]"),
        Some((Some(0.0), 10.0))
    );
    assert_eq!(
        range("steps per epoch (paper: 30000); num_envs..=100000000"),
        Some((None, 1e8))
    );
    assert_eq!(range("a switch; true/false"), None);
}

#[test]
fn every_count_flag_refuses_the_largest_integer_and_one_past_it_naming_the_flag() {
    let flags: &[(&[&str], &str)] = &[
        (&["train"], "--epochs"),
        (&["train"], "--steps-per-epoch"),
        (&["train"], "--num-envs"),
        (&["train"], "--threads"),
        (&["eval"], "--episodes"),
        (&["render"], "--episodes"),
        (&["render"], "--width"),
        (&["render"], "--height"),
        (&["render"], "--fps"),
        (&["render"], "--every"),
        (&["plot"], "--smooth"),
        (&["report"], "--last"),
        (&["report"], "--random-episodes"),
        (&["report"], "--smooth"),
        (&["report"], "--reps"),
        (&["stats"], "--reps"),
        (&["sweep"], "--epochs"),
        (&["sweep"], "--steps-per-epoch"),
        (&["sweep"], "--jobs"),
        (&["sweep"], "--threads"),
        (&["sweep"], "--last"),
        (&["summary"], "--last"),
        (&["theory"], "--states"),
        (&["theory"], "--actions"),
        (&["theory"], "--seeds"),
        (&["theory"], "--draws"),
        (&["theory"], "--iterations"),
        (&["theory"], "--ascent-steps"),
        (&["theory"], "--episodes"),
        (&["theory"], "--practical-iterations"),
        (&["bench", "update"], "--batch"),
        (&["bench", "update"], "--repeats"),
        (&["bench", "epoch"], "--epochs"),
        (&["bench", "epoch"], "--steps-per-epoch"),
        (&["bench", "epoch"], "--num-envs"),
        (&["bench", "env"], "--steps"),
        (&["bench", "env"], "--num-envs"),
        (&["bench", "policy"], "--calls"),
        (&["bench", "policy"], "--batch"),
    ];
    for (command, flag) in flags {
        for value in ["18446744073709551615", "18446744073709551616", "-1"] {
            let mut args: Vec<&str> = command.to_vec();
            let given = format!("{flag}={value}");
            args.push(&given);
            let out = apo_within(30, &args);
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success(), "{args:?} was accepted");
            assert!(!err.contains("panicked"), "{args:?}: {err}");
            assert!(
                err.contains(flag),
                "{args:?}: the error does not name {flag}: {err}"
            );
            assert!(
                err.contains("is not in"),
                "{args:?}: the error does not give the range: {err}"
            );
        }
    }
}

/// The seed flags take every 64-bit seed, and refuse one past the largest or a negative one
/// with the range, as the count flags do.
#[test]
fn every_seed_flag_refuses_values_outside_64_bits_naming_the_flag_and_range() {
    let flags: &[(&[&str], &str)] = &[
        (&["eval"], "--seed"),
        (&["render"], "--seed"),
        (&["report"], "--ci-seed"),
        (&["stats"], "--ci-seed"),
        (&["train"], "--seed"),
    ];
    for (command, flag) in flags {
        for value in ["18446744073709551616", "-1"] {
            let mut args: Vec<&str> = command.to_vec();
            let given = format!("{flag}={value}");
            args.push(&given);
            let out = apo_within(30, &args);
            let err = text(&out.stderr);
            assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
            assert!(
                err.contains(flag) && err.contains("is not in 0..="),
                "{args:?}: {err}"
            );
        }
    }
}

#[test]
fn sizes_are_checked_before_anything_is_created() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let o = path(&run);
    for (flags, culprit) in [
        (
            vec!["--steps-per-epoch", "1000000000000"],
            "--steps-per-epoch",
        ),
        (
            vec!["--set", "steps_per_epoch=1000000000000"],
            "steps_per_epoch",
        ),
        (vec!["--set", "hidden=[1000000000]"], "hidden"),
        (vec!["--set", "hidden=[1000000, 1000000]"], "GiB of memory"),
        (vec!["--num-envs", "1000000000000"], "1..=65536"),
        (
            vec!["--set", "num_envs=1000000000000"],
            "`num_envs` = 1000000000000",
        ),
        (vec!["--set", "init_log_std=1e30"], "init_log_std"),
    ] {
        let mut args = vec![
            "train",
            "--algo",
            "apo",
            "--env",
            "CartPole-v1",
            "--quiet",
            "--out",
            o,
        ];
        args.extend(flags.iter().copied());
        let err = fails(&args);
        assert!(err.contains(culprit), "{flags:?}: {err}");
        assert!(
            !run.exists(),
            "{flags:?}: a run that fails before its first epoch leaves no directory behind"
        );
    }
    let err = fails(&[
        "train",
        "--algo",
        "apo",
        "--env",
        "CartPole-v1",
        "--seed",
        "9223372036854775808",
        "--out",
        o,
    ]);
    assert!(err.contains("0..=9223372036854775807"), "{err}");
    for args in [
        vec!["bench", "update", "--obs", "0"],
        vec!["bench", "update", "--act", "0"],
        vec!["bench", "update", "--batch", "0"],
        vec!["bench", "policy", "--obs", "0"],
        vec!["bench", "policy", "--batch", "0"],
        vec!["bench", "env", "--env", "CartPole-v1", "--steps", "0"],
    ] {
        let out = apo(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("is not in 1.."), "{args:?}: {err}");
    }
    // a memory refusal names the command's own flags and values, not config keys it never took
    let err = fails(&["bench", "update", "--batch", "10000000", "--obs", "100000"]);
    assert!(
        err.contains("apo bench update --batch 10000000 --obs 100000 --act 8 would need about")
            && err.contains("GiB of memory")
            && !err.contains("steps_per_epoch"),
        "{err}"
    );
    let err = fails(&[
        "bench",
        "epoch",
        "--env",
        "Pendulum-v1",
        "--steps-per-epoch",
        "100000000",
        "--num-envs",
        "65536",
    ]);
    assert!(
        err.contains("--steps-per-epoch 100000000 --num-envs 65536 would need about")
            && !err.contains("steps_per_epoch"),
        "{err}"
    );
}

#[test]
fn a_diverging_update_stops_the_run_with_an_error_and_keeps_the_last_good_checkpoint() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let train = |extra: &[&str]| {
        let mut args = vec![
            "train",
            "--algo",
            "a2c",
            "--env",
            "Pendulum-v1",
            "--epochs",
            "1",
            "--steps-per-epoch",
            "400",
        ];
        args.extend(["--quiet", "--out", path(&run)]);
        args.extend_from_slice(extra);
        apo(&args)
    };
    // diverging in the first epoch: an error, exit 1, and no run directory left behind
    // a policy learning rate of 1e30 sends the log-std to ~1e30, and the KL after the update to NaN
    let out = train(&["--set", "algo.policy_update.lr=1e30"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        out.status.code(),
        Some(1),
        "a diverged run must not exit 0: {err}"
    );
    assert!(
        err.contains("epoch 1: the update produced")
            && err.contains("non-finite")
            && err.contains("nothing was saved"),
        "{err}"
    );
    // the error describes the epoch's batch, where a non-finite update would come from
    assert!(
        err.contains("the epoch's batch: 400 transitions, max |obs| ") && err.contains("adv_scale"),
        "{err}"
    );
    assert!(!String::from_utf8_lossy(&out.stdout).contains("run finished"));
    assert!(!run.exists());

    // diverging later: the rows and the checkpoint of the good epochs stay (a policy learning
    // rate of 1e3 keeps epoch 1 finite and sends epoch 2's update to NaN; a run's learning
    // rate cannot be edited under its checkpoint, bound_config.rs)
    let out = apo(&[
        "train",
        "--algo",
        "a2c",
        "--env",
        "Pendulum-v1",
        "--epochs",
        "3",
        "--steps-per-epoch",
        "400",
        "--set",
        "algo.policy_update.lr=1e3",
        "--quiet",
        "--out",
        path(&run),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("epoch 2: the update produced") && err.contains("non-finite"),
        "{err}"
    );
    assert!(err.contains("last good checkpoint (epoch 1)"), "{err}");
    // the settings that scale the update are named with their values
    assert!(err.contains("algo.a2c.policy_update.lr = 1000"), "{err}");
    assert_eq!(timeless(&run).len(), 1);
    let state = std::fs::read_to_string(run.join("checkpoints/latest/state.json"))
        .expect("last good checkpoint");
    assert!(state.contains("\"epoch\": 1"), "{state}");
}

#[test]
fn sweeps_are_counted_before_anything_is_allocated() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("s");
    let started = Instant::now();
    let sweep_of = |seeds: &str| {
        apo(&[
            "sweep",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--seeds",
            seeds,
            "--out",
            path(&out),
        ])
    };
    for seeds in ["0..9223372036854775807", "0..1000000000", "0..10001"] {
        let result = sweep_of(seeds);
        let err = text(&result.stderr);
        assert_eq!(result.status.code(), Some(1), "{seeds}: {err}");
        assert!(err.contains("--max-runs"), "{seeds}: {err}");
    }
    // an empty range says so (the end is excluded)
    for seeds in ["5..2", "5..5"] {
        let result = sweep_of(seeds);
        let err = text(&result.stderr);
        assert!(!result.status.success(), "{seeds}");
        assert!(
            err.contains("empty range") && err.contains(seeds),
            "{seeds}: {err}"
        );
    }
    assert!(!out.exists(), "nothing is made");
    let values: Vec<String> = (0..1000)
        .map(|i| format!("{}", 0.001 * (i + 1) as f64))
        .collect();
    let (k, w) = (
        format!("algo.k={}", values.join(",")),
        format!("algo.omega1={}", values.join(",")),
    );
    let err = fails(&[
        "sweep",
        "--algo",
        "apo",
        "--env",
        "Pendulum-v1",
        "--grid",
        &k,
        "--grid",
        &w,
        "--out",
        path(&out),
    ]);
    assert!(
        err.contains("3000000 runs") || err.contains("1000000"),
        "{err}"
    );
    assert!(
        started.elapsed() < Duration::from_secs(60),
        "{:?}",
        started.elapsed()
    );
    assert!(!out.exists(), "nothing is created");
    // an explicit limit
    let err = fails(&[
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--seeds",
        "0..3",
        "--max-runs",
        "2",
        "--out",
        path(&out),
    ]);
    assert!(
        err.contains("more than the 2") && err.contains("--max-runs"),
        "{err}"
    );
    // --max-runs itself is bounded, said in --help and in the error: no limit a user gives
    // lets a count through to an allocation
    let err = fails(&[
        "sweep",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--seeds",
        "0..18446744073709551615",
        "--max-runs",
        "18446744073709551615",
        "--out",
        path(&out),
    ]);
    assert!(
        err.contains("--max-runs") && err.contains("1..=1000000"),
        "{err}"
    );
    let help = ok(&["sweep", "--help"]);
    assert!(help.contains("1..=1000000"), "{help}");
    // a range of more seeds than the most --max-runs allows, and a long list: refused by count,
    // the long text quoted as an excerpt
    let list: Vec<String> = (0..20_000).map(|i| i.to_string()).collect();
    for (seeds, says) in [
        (
            "0..18446744073709551615".to_string(),
            "more than the 1000000 runs",
        ),
        (
            list.join(","),
            "lists 20000 seeds, more than the 10000 runs",
        ),
    ] {
        let max = if seeds.contains("..") {
            "1000000"
        } else {
            "10000"
        };
        let err = fails(&[
            "sweep",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--seeds",
            &seeds,
            "--max-runs",
            max,
            "--out",
            path(&out),
        ]);
        assert!(err.contains(says) && err.len() < 1_000, "{err}");
    }
    assert!(!out.exists(), "nothing is created");
}

/// Rule: a memory check takes the process's own limits into account (`ulimit -v`), so a run
/// that passes it does not then abort on an allocation: the limit is named in the refusal.
#[test]
fn the_memory_check_takes_the_process_limit_into_account() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let dir = tmp.path().join("run");
    let limited = std::process::Command::new("bash")
        .args([
            "-c",
            // 3 GiB of address space; the run asks for about 9 GiB of batch
            "ulimit -v 3145728 && exec \"$0\" \"$@\"",
            env!("CARGO_BIN_EXE_apo"),
            "train",
            "--algo",
            "ppo",
            "--env",
            "Hopper-v4",
            "--num-envs",
            "64",
            "--steps-per-epoch",
            "4000000",
            "--quiet",
            "--out",
            path(&dir),
        ])
        .output()
        .expect("bash");
    let err = text(&limited.stderr);
    assert_eq!(limited.status.code(), Some(1), "{err}");
    assert!(
        err.contains("GiB of memory") && err.contains("ulimit -v"),
        "{err}"
    );
    assert!(!dir.exists(), "no directory is left behind");
}

#[test]
fn memory_is_checked_before_anything_is_created() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let err = fails(&[
        "bench", "policy", "--obs", "100000", "--act", "10000", "--batch", "100000",
    ]);
    assert!(
        err.contains("GiB of memory") && err.contains("--batch"),
        "{err}"
    );
    let dir = tmp.path().join("humanoids");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "Humanoid",
        "--num-envs",
        "65536",
        "--steps-per-epoch",
        "65536",
        "--quiet",
        "--out",
        path(&dir),
    ]);
    assert!(err.contains("GiB of memory"), "{err}");
    assert!(!dir.exists(), "no directory is left behind");
}

#[test]
fn a_key_set_twice_and_a_list_toml_cannot_hold_are_refused() {
    for sets in [["seed=1", "seed=2"], ["algo.k=1", "algo.apo.k=2"]] {
        let out = apo(&["config", "--set", sets[0], "--set", sets[1]]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains("set one key twice"),
            "{err}"
        );
    }
    // a section and a value do not stand for each other, also where a flag later sets the
    // key (`--env`, `--epochs`): said for --set and --config files alike
    for (set, key, said) in [
        ("env.x=5", "env", "found a table"),
        ("epochs.x=5", "epochs", "found a table"),
        ("env.x=", "env", "found a table"),
        ("algo.apo=1", "algo.apo", "is a section"),
    ] {
        let out = apo(&[
            "train",
            "--algo",
            "apo",
            "--env",
            "CartPole-v1",
            "--epochs",
            "1",
            "--set",
            set,
            "--out",
            "/nonexistent/never-made",
        ]);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(&format!("`{key}`")) && err.contains(said),
            "--set {set}: {err}"
        );
    }
    let tmp = tempfile::tempdir().expect("tempdir");
    let file = tmp.path().join("c.toml");
    std::fs::write(&file, "seed = 1\n[epochs]\nx = 5\n").expect("config");
    let err = fails(&["config", "--algo", "ppo", "--config", path(&file)]);
    assert!(
        err.contains("`epochs`") && err.contains("found a table"),
        "{err}"
    );
    let out = apo(&["config", "--set", "hidden=[99999999999999999999]"]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && err.contains("hidden") && err.contains("not a TOML list"),
        "{err}"
    );
}

/// A key given by `--grid` and by `--set` of one sweep is refused before anything is made,
/// as a key given twice by `--set` is.
#[test]
fn a_sweep_refuses_a_key_in_both_grid_and_set_before_making_anything() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    for extra in [
        ["--grid", "algo.ppo.clip=0.1,0.2", "--set", "algo.clip=0.3"],
        ["--set", "algo.clip=0.1", "--set", "algo.ppo.clip=0.3"],
    ] {
        let result = sweep(&out, "1", &extra);
        let err = text(&result.stderr);
        assert_eq!(result.status.code(), Some(1), "{extra:?}: {err}");
        assert!(err.contains("set one key twice"), "{extra:?}: {err}");
        assert!(!out.exists(), "{extra:?}: nothing is made");
    }
}

/// Rule: nothing is rounded silently: an epoch of a number of steps that the environments do
/// not divide is rounded up to whole steps of all of them, and the run says so.
#[test]
fn an_epoch_rounded_up_to_whole_environment_steps_is_said() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    let mut args = small_args(&run);
    args.extend_from_slice(&["--set", "num_envs=3"]);
    let out = apo(&args);
    let err = text(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("collects 201 steps") && err.contains("multiple of 3"),
        "{err}"
    );
    assert_eq!(timeless(&run)[0].env_steps, 201);
    // a multiple says nothing
    let exact = tmp.path().join("exact");
    let mut args = small_args(&exact);
    args.extend_from_slice(&["--set", "num_envs=4"]);
    let out = apo(&args);
    assert!(
        !text(&out.stderr).contains("collects"),
        "{}",
        text(&out.stderr)
    );
}
