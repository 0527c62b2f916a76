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
}
