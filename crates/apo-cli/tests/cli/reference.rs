//! The command-line reference cannot go stale: `docs/cli.md` is `apo markdown-help`'s output,
//! every subcommand's `--help` shows an example, and the completion scripts are generated from
//! the same definitions.

use super::ok;

/// The subcommands listed under `Commands:` in `apo [path…] --help` (without `help`).
fn subcommands(path: &[&str]) -> Vec<String> {
    let mut args = path.to_vec();
    args.push("--help");
    let help = ok(&args);
    help.lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| !l.trim().is_empty())
        .filter_map(|l| l.split_whitespace().next())
        .filter(|name| *name != "help")
        .map(String::from)
        .collect()
}

#[test]
fn docs_cli_md_is_the_generated_reference() {
    let generated = ok(&["markdown-help"]);
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/../../docs/cli.md");
    let committed = std::fs::read_to_string(file).expect("docs/cli.md");
    assert!(
        generated == committed,
        "docs/cli.md is not the reference of this build's command line: regenerate it with \
         `cargo run -p apo-cli -- markdown-help > docs/cli.md`"
    );
    // every subcommand is in it
    for command in subcommands(&[]) {
        assert!(
            committed.contains(&format!("## `apo {command}`")),
            "docs/cli.md has no section for `apo {command}`"
        );
    }
}

#[test]
fn every_subcommand_help_shows_an_example() {
    let top = subcommands(&[]);
    assert!(top.len() >= 12, "{top:?}");
    let bench = subcommands(&["bench"]);
    assert!(bench.len() >= 4, "{bench:?}");
    let paths = top
        .iter()
        .map(|c| vec![c.as_str()])
        .chain(bench.iter().map(|c| vec!["bench", c.as_str()]));
    for path in paths {
        let mut args = path.clone();
        args.push("--help");
        let help = ok(&args);
        let example = help
            .split("Example:")
            .nth(1)
            .unwrap_or_else(|| panic!("`apo {} --help` has no example:\n{help}", path.join(" ")));
        assert!(
            example
                .trim_start()
                .starts_with(&format!("apo {}", path[0])),
            "`apo {} --help`'s example does not run it:\n{help}",
            path.join(" ")
        );
    }
}

#[test]
fn help_and_version_on_a_full_disk_say_so() {
    for args in [vec!["--help"], vec!["train", "--help"], vec!["--version"]] {
        let file = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .expect("/dev/full");
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_apo"))
            .args(&args)
            .stdout(file)
            .output()
            .expect("apo runs");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("cannot write to standard output"),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn completion_scripts_know_every_subcommand() {
    let top = subcommands(&[]);
    for shell in ["bash", "zsh", "fish", "elvish", "powershell"] {
        let script = ok(&["completions", shell]);
        for command in &top {
            assert!(script.contains(command.as_str()), "{shell}: no `{command}`");
        }
    }
    // the bash script is valid bash
    let dir = tempfile::tempdir().expect("tempdir");
    let file = dir.path().join("apo.bash");
    std::fs::write(&file, ok(&["completions", "bash"])).expect("write");
    let check = std::process::Command::new("bash")
        .arg("-n")
        .arg(&file)
        .output()
        .expect("bash runs");
    assert!(
        check.status.success(),
        "{}",
        String::from_utf8_lossy(&check.stderr)
    );
    // an unknown shell is refused with the choices
    let err = super::fails(&["completions", "tcsh"]);
    assert!(err.contains("bash") && err.contains("zsh"), "{err}");
}

/// Every `apo …` command shown in a shell block of the README and the handbook names a
/// subcommand that exists and only flags that subcommand has, so a renamed or removed flag
/// cannot linger in the docs.
#[test]
fn every_command_in_the_docs_uses_flags_that_exist() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
    let mut pages = vec![root.join("README.md")];
    for dir in ["docs", "docs/results"] {
        let mut found: Vec<_> = std::fs::read_dir(root.join(dir))
            .expect("docs/")
            .map(|e| e.expect("entry").path())
            .filter(|p| p.extension().is_some_and(|x| x == "md") && !p.ends_with("cli.md"))
            .collect();
        found.sort();
        pages.extend(found);
    }
    let top = subcommands(&[]);
    let bench = subcommands(&["bench"]);
    let mut helps: std::collections::BTreeMap<String, String> = Default::default();
    let (mut checked, mut wrong) = (0, Vec::new());
    for page in &pages {
        let text = std::fs::read_to_string(page).expect("page");
        let mut in_shell = false;
        // a command continued over several lines (`\` at the end) is read as one
        let mut lines: Vec<String> = Vec::new();
        for line in text.lines() {
            if let Some(fence) = line.strip_prefix("```") {
                // ```sh, ```bash, ```zsh, with or without words after (```sh long), or bare
                let info = fence.split_whitespace().next();
                in_shell = !in_shell && matches!(info, None | Some("sh" | "bash" | "zsh"));
                continue;
            }
            if !in_shell {
                continue;
            }
            match lines.last_mut() {
                Some(last) if last.ends_with('\\') => {
                    last.pop();
                    last.push(' ');
                    last.push_str(line.trim());
                }
                _ => lines.push(line.trim().to_string()),
            }
        }
        for line in lines {
            let code = line.split(" #").next().unwrap_or("");
            let words: Vec<&str> = code.split_whitespace().collect();
            // `for algo in apo papo …`: a list of names, not a command
            if words.first() == Some(&"for") {
                continue;
            }
            let Some(at) = words.iter().position(|w| {
                *w == "apo" || w.ends_with("/apo") || *w == "$APO" || *w == "\"$apo\""
            }) else {
                continue;
            };
            let Some(&command) = words.get(at + 1) else {
                continue;
            };
            if command.starts_with('-') || !top.iter().any(|c| c == command) {
                if !command.starts_with('-') && command.chars().all(|c| c.is_ascii_lowercase()) {
                    wrong.push(format!(
                        "{}: `{line}`: no subcommand `{command}`",
                        page.display()
                    ));
                }
                continue;
            }
            let mut path = vec![command.to_string()];
            if command == "bench" {
                match words.get(at + 2) {
                    Some(sub) if bench.iter().any(|b| b == sub) => path.push(sub.to_string()),
                    _ => continue,
                }
            }
            let key = path.join(" ");
            let help = helps.entry(key.clone()).or_insert_with(|| {
                let mut args: Vec<&str> = path.iter().map(String::as_str).collect();
                args.push("--help");
                ok(&args)
            });
            for flag in words[at + 1..].iter().filter(|w| w.starts_with("--")) {
                let flag = flag.split('=').next().unwrap_or(flag);
                if flag.len() <= 2
                    || !flag[2..]
                        .chars()
                        .all(|c| c.is_ascii_lowercase() || c == '-')
                {
                    continue;
                }
                checked += 1;
                let listed = help
                    .lines()
                    .any(|l| l.trim_start().split([' ', ',']).any(|w| w == flag));
                if !listed {
                    wrong.push(format!(
                        "{}: `{line}`: `apo {key}` has no {flag}",
                        page.display()
                    ));
                }
            }
        }
    }
    assert!(checked > 100, "only {checked} flags found in the docs");
    assert!(
        wrong.is_empty(),
        "commands in the docs that do not parse:\n{}",
        wrong.join("\n")
    );
}
