//! Rule: every number has a range. Every numeric config key of every algorithm documents a
//! finite range in `apo config`, and a value just outside it — above or below, or a number
//! TOML cannot hold — is refused with an error that names the key.

use std::collections::BTreeMap;

use super::{apo, ok};

const ALGORITHMS: [&str; 8] = [
    "apo", "papo", "trpo", "ppo", "a2c", "espo", "vmpo", "alphappo",
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

/// Runs `apo args`; kills it and fails after 30 s (a count without a bound would run on).
fn apo_bounded(args: &[&str]) -> std::process::Output {
    use std::process::{Command, Stdio};
    use std::time::{Duration, Instant};
    let mut child = Command::new(env!("CARGO_BIN_EXE_apo"))
        .args(args)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn apo");
    let deadline = Instant::now() + Duration::from_secs(30);
    while child.try_wait().expect("poll").is_none() {
        if Instant::now() > deadline {
            let _ = child.kill();
            panic!("apo {args:?} still running after 30 s: the value has no bound");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    child.wait_with_output().expect("output")
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
            let out = apo_bounded(&args);
            let err = String::from_utf8_lossy(&out.stderr);
            assert!(!out.status.success(), "{args:?} was accepted");
            assert!(!err.contains("panicked"), "{args:?}: {err}");
            assert!(
                err.contains(flag),
                "{args:?}: the error does not name {flag}: {err}"
            );
        }
    }
}
