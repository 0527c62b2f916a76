//! `apo theory`: the report's checks on a small run, and bad options.

use crate::{fails, ok};

#[test]
fn theory_reports_the_four_checks() {
    let out = ok(&[
        "theory",
        "--states",
        "2",
        "--actions",
        "2",
        "--gamma",
        "0.5",
        "--seeds",
        "600",
        "--iteration-seeds",
        "2",
        "--iterations",
        "2",
        "--ascent-steps",
        "5",
        "--selberg-seeds",
        "2",
        "--episodes",
        "2000",
    ]);
    // seed 584 is among the 600: the paper's cross term fails there (docs/theory.md)
    let line = |prefix: &str| {
        out.lines()
            .find(|l| l.starts_with(prefix))
            .unwrap_or_else(|| panic!("no `{prefix}` line in:\n{out}"))
            .to_string()
    };
    assert!(
        line("(a)").contains("21600 candidates on 600 MDPs"),
        "{out}"
    );
    assert!(!line("(a)").contains(" 0 violations"), "{out}");
    assert!(line("(b)").contains("largest |M − B| at π_j"), "{out}");
    assert_eq!(
        out.lines().filter(|l| l.starts_with("(c)")).count(),
        3,
        "{out}"
    );
    assert!(line("(d)").contains("on 6 cases"), "{out}");
    // the corrected cross term: no violation on the same candidates
    let fixed = ok(&[
        "theory",
        "--states",
        "2",
        "--actions",
        "2",
        "--gamma",
        "0.5",
        "--seeds",
        "600",
        "--cross-term",
        "absolute",
        "--iteration-seeds",
        "0",
        "--selberg-seeds",
        "0",
    ]);
    assert!(fixed.contains(", 0 violations"), "{fixed}");
}

#[test]
fn theory_refuses_bad_options() {
    for (args, culprit) in [
        (vec!["theory", "--gamma", "1"], "--gamma"),
        (vec!["theory", "--k=-1"], "--k"),
        (vec!["theory", "--max-kl", "0"], "--max-kl"),
        (vec!["theory", "--states", "0"], "--states"),
        (vec!["theory", "--mu-norm", "l2"], "--mu-norm"),
    ] {
        let err = fails(&args);
        assert!(err.contains(culprit), "{args:?}: {err}");
    }
    // every number has a finite range, named with the flag, chosen so that the checks stay
    // finite and bounded in time (a δ of 1e308 overflowed the logits; a γ of 0.9999999999 made
    // check (d) run for hours)
    for (flag, value, range) in [
        ("--max-kl", "1e308", "1e308 is out of its range (0, 1]"),
        ("--gamma", "0.9999999999", "[0, 0.999]"),
        ("--k", "1e308", "[0, 1000]"),
        ("--temperature", "inf", "[0, 4]"),
        ("--temperature", "100", "[0, 4]"),
        ("--reward-scale", "1e300", "(0, 1e6]"),
        ("--reward-offset", "-1e300", "[-1e6, 1e6]"),
    ] {
        let err = fails(&["theory", &format!("{flag}={value}")]);
        assert!(
            err.contains(flag) && err.contains(range),
            "{flag} {value}: {err}"
        );
    }
    // a run that would check nothing is an error, never a pass
    let err = fails(&["theory", "--practical-only", "--practical-seeds", "0"]);
    assert!(
        err.contains("--practical-seeds") && err.contains("nothing"),
        "{err}"
    );
    // the steps check (d) would sample are counted before it starts
    let err = fails(&["theory", "--gamma", "0.999", "--selberg-seeds", "1000"]);
    assert!(
        err.contains("check (d) would sample") && err.contains("--episodes"),
        "{err}"
    );
    // the ends of the ranges run, and quickly
    ok(&[
        "theory",
        "--seeds",
        "2",
        "--iteration-seeds",
        "1",
        "--iterations",
        "2",
        "--selberg-seeds",
        "1",
        "--episodes",
        "50",
        "--practical-seeds",
        "1",
        "--practical-iterations",
        "2",
        "--max-kl",
        "1",
        "--gamma",
        "0.999",
        "--k",
        "0,1000",
        "--temperature",
        "4",
        "--reward-scale",
        "1e6",
        "--reward-offset=-1e6",
    ]);
}
