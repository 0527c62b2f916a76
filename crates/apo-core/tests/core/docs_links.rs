//! `docs/algorithms.md` links each formula to the line of its function: every such link
//! (`[`name`](../crates/<path>.rs#L<n>)`) must land on the line that defines `fn name`, so an
//! edit that moves a function is caught here, not by a reader.

use std::path::Path;

#[test]
fn every_formula_link_of_the_algorithms_doc_lands_on_its_function() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let doc = std::fs::read_to_string(root.join("docs/algorithms.md")).expect("docs/algorithms.md");
    let mut checked = 0;
    for (i, _) in doc.match_indices("](../crates/") {
        // `[`name`](../crates/<path>#L<n>)`
        let Some(name) = doc[..i]
            .strip_suffix('`')
            .and_then(|s| s.rsplit_once("[`"))
            .map(|(_, n)| n)
        else {
            continue;
        };
        let target = &doc[i + "](../".len()..];
        let target = &target[..target.find(')').expect("a closing parenthesis")];
        let Some((path, line)) = target.split_once("#L") else {
            continue;
        };
        let line: usize = line.parse().expect("a line number");
        let source =
            std::fs::read_to_string(root.join(path)).unwrap_or_else(|e| panic!("{path}: {e}"));
        let text = source
            .lines()
            .nth(line - 1)
            .unwrap_or_else(|| panic!("{path} has no line {line}"));
        assert!(
            text.contains(&format!("fn {name}")),
            "docs/algorithms.md links `{name}` to {path}:{line}, which reads `{}`",
            text.trim()
        );
        checked += 1;
    }
    assert!(checked >= 10, "only {checked} formula links found");
}
