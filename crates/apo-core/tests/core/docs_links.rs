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

/// Every relative link of the README and the handbook (`[text](path)` and `[text](path#anchor)`)
/// names a file or folder of the repository, and every `#anchor` into a Markdown file names one
/// of its headings (GitHub's rule: lower case, punctuation but `-` and `_` dropped, spaces to
/// `-`), so a moved or renamed page is caught here, not by a reader.
#[test]
fn every_relative_link_of_the_docs_resolves() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut pages = vec![root.join("README.md"), root.join("CHANGELOG.md")];
    for dir in ["docs", "docs/results"] {
        let mut found: Vec<_> = std::fs::read_dir(root.join(dir))
            .expect("docs/")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.extension().is_some_and(|x| x == "md"))
            .collect();
        found.sort();
        pages.extend(found);
    }
    let anchor_of = |heading: &str| -> String {
        heading
            .trim()
            .to_lowercase()
            .chars()
            .filter(|c| c.is_alphanumeric() || *c == ' ' || *c == '-' || *c == '_')
            .map(|c| if c == ' ' { '-' } else { c })
            .collect()
    };
    let mut broken = Vec::new();
    let mut checked = 0;
    for page in &pages {
        let text = std::fs::read_to_string(page).expect("page");
        let dir = page.parent().expect("a folder");
        let mut rest = text.as_str();
        while let Some(i) = rest.find("](") {
            rest = &rest[i + 2..];
            let Some(end) = rest.find(')') else { break };
            let target = &rest[..end];
            if target.contains("://") || target.starts_with("mailto:") || target.contains(' ') {
                continue;
            }
            let (path, anchor) = target.split_once('#').unwrap_or((target, ""));
            let file = if path.is_empty() {
                page.clone()
            } else {
                dir.join(path)
            };
            checked += 1;
            if !file.exists() {
                broken.push(format!("{}: {target}", page.display()));
                continue;
            }
            if !anchor.is_empty() && file.extension().is_some_and(|x| x == "md") {
                let target_text = std::fs::read_to_string(&file).expect("linked page");
                let found = target_text
                    .lines()
                    .filter_map(|l| l.strip_prefix('#'))
                    .map(|l| anchor_of(l.trim_start_matches('#')))
                    .any(|a| a == anchor);
                if !found {
                    broken.push(format!("{}: {target} (no such heading)", page.display()));
                }
            }
        }
    }
    assert!(checked > 50, "only {checked} links found");
    assert!(broken.is_empty(), "broken links:\n{}", broken.join("\n"));
}
