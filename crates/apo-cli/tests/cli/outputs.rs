//! Rule: one output rule. apo writes only the paths the user names; a named file that exists
//! is replaced only with `--force`, in every subcommand that writes one (`render`, `plot`);
//! no fallback name, and temporary files of unique names that never land on a file that
//! exists.

use std::path::Path;

use super::render::{apo_with, gif_frames};
use super::*;

/// Every entry of `dir`, sorted.
fn entries(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("read_dir")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn a_named_file_that_exists_is_replaced_only_with_force_in_every_subcommand() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    let out = tmp.path().join("out");
    std::fs::create_dir(&out).expect("mkdir");
    // a user's file of the old fixed temporary name stays untouched by every write
    for name in [".v.gif.tmp", ".c.png.tmp", ".c.svg.tmp"] {
        std::fs::write(out.join(name), "user's").expect("write");
    }
    let commands: [(&str, Vec<&str>); 3] = [
        (
            "v.gif",
            vec![
                "render",
                "--run",
                path(&run),
                "--episodes",
                "1",
                "--width",
                "32",
                "--height",
                "24",
            ],
        ),
        ("c.png", vec!["plot", path(&run)]),
        ("c.svg", vec!["plot", path(&run)]),
    ];
    for (name, args) in &commands {
        let target = out.join(name);
        std::fs::write(&target, "the user's own file").expect("write");
        let mut named: Vec<&str> = args.clone();
        named.extend(["--out", path(&target)]);
        let err = fails(&named);
        assert!(
            err.contains("exists") && err.contains("--force") && err.contains(path(&target)),
            "{name}: {err}"
        );
        assert_eq!(
            std::fs::read(&target).expect("kept"),
            b"the user's own file"
        );
        named.push("--force");
        ok(&named);
        let bytes = std::fs::read(&target).expect("replaced");
        assert_ne!(bytes, b"the user's own file", "{name}");
        // and a second time, the file apo made is not replaced without --force either
        named.pop();
        fails(&named);
    }
    assert_eq!(gif_frames(&out.join("v.gif")).1, (32, 24));
    for name in [".v.gif.tmp", ".c.png.tmp", ".c.svg.tmp"] {
        assert_eq!(
            std::fs::read(out.join(name)).expect("kept"),
            b"user's",
            "{name}"
        );
    }
    assert_eq!(
        entries(&out),
        [
            ".c.png.tmp",
            ".c.svg.tmp",
            ".v.gif.tmp",
            "c.png",
            "c.svg",
            "v.gif"
        ],
        "no temporary file left"
    );
    // a FIFO or a device is never an output, --force or not
    let err = fails(&["plot", path(&run), "--out", "/dev/null", "--force"]);
    assert!(err.contains("not a regular file"), "{err}");
    // the default video is apo's own, in the run: each render replaces it
    ok(&[
        "render",
        "--run",
        path(&run),
        "--episodes",
        "1",
        "--width",
        "32",
        "--height",
        "24",
    ]);
    ok(&[
        "render",
        "--run",
        path(&run),
        "--episodes",
        "1",
        "--width",
        "40",
        "--height",
        "24",
    ]);
    assert_eq!(gif_frames(&run.join("videos/render.gif")).1, (40, 24));
}

#[test]
fn an_mp4_without_ffmpeg_is_an_error_and_writes_no_other_file() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    let out = tmp.path().join("out");
    std::fs::create_dir(&out).expect("mkdir");
    // the file a fallback would have written over
    std::fs::write(out.join("v.gif"), "precious").expect("write");
    let mp4 = out.join("v.mp4");
    let args = [
        "render",
        "--run",
        path(&run),
        "--episodes",
        "1",
        "--width",
        "65",
        "--height",
        "49",
        "--out",
        path(&mp4),
    ];
    let empty = tmp.path().join("empty-path");
    std::fs::create_dir(&empty).expect("dir");
    let output = apo_with("PATH", path(&empty), &args);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success(), "{stderr}");
    assert!(
        stderr.contains("ffmpeg") && stderr.contains("not on the PATH") && stderr.contains(".gif"),
        "{stderr}"
    );
    assert_eq!(entries(&out), ["v.gif"], "nothing written");
    assert_eq!(std::fs::read(out.join("v.gif")).expect("kept"), b"precious");
    if apo_train::video::check_ffmpeg().is_ok() {
        // with ffmpeg: an MP4 (odd sides padded), and the rule for an existing file
        ok(&args);
        let bytes = std::fs::read(&mp4).expect("the MP4");
        assert_eq!(&bytes[4..8], b"ftyp", "an MP4 starts with its ftyp box");
        let err = fails(&args);
        assert!(err.contains("--force"), "{err}");
        let mut forced = args.to_vec();
        forced.push("--force");
        ok(&forced);
        assert_eq!(entries(&out), ["v.gif", "v.mp4"]);
    }
}

#[test]
fn force_replaces_only_run_directories_and_keeps_foreign_files() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let notes = tmp.path().join("notes");
    std::fs::create_dir(&notes).expect("mkdir");
    std::fs::write(notes.join("thesis.txt"), "years of work").expect("write");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--out",
        path(&notes),
        "--force",
        "--quiet",
    ]);
    assert!(
        err.contains("not one") && err.contains("nothing in it was touched"),
        "{err}"
    );
    assert_eq!(
        std::fs::read_to_string(notes.join("thesis.txt")).expect("kept"),
        "years of work"
    );

    let run = tmp.path().join("run");
    small(&run, &[]);
    std::fs::write(run.join("curves.png"), "a plot the user made").expect("write");
    let out = apo(&[
        "train",
        "--algo",
        "a2c",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--quiet",
        "--out",
        path(&run),
        "--force",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("kept what apo did not create"));
    assert_eq!(
        std::fs::read_to_string(run.join("curves.png")).expect("kept"),
        "a plot the user made"
    );
    assert!(std::fs::read_to_string(run.join("config.toml"))
        .expect("config")
        .contains("[algo.a2c]"));
}

#[test]
fn force_removes_only_the_files_apo_created_and_never_a_folder_with_user_files() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &["--set", "keep_checkpoint_every=1"]);
    let planted = [
        ("notes.txt", "notes of the user"),
        ("checkpoints/mybest/model.pt", "the user's best model"),
        (
            "checkpoints/latest/mine.txt",
            "a file the user put into latest",
        ),
        (
            "checkpoints/epoch-000001/why.txt",
            "a note inside a kept checkpoint",
        ),
    ];
    for (rel, content) in planted {
        plant(&run, rel, content);
    }
    small(&run, &["--force", "--set", "keep_checkpoint_every=1"]);
    for (rel, content) in planted {
        assert_eq!(
            find_content(&run, content).len(),
            1,
            "{rel} was lost by --force"
        );
    }
    assert_eq!(
        std::fs::read_to_string(run.join("checkpoints/mybest/model.pt")).expect("kept"),
        "the user's best model"
    );
    // the run itself was replaced and is whole
    ok(&["eval", "--run", path(&run), "--episodes", "1"]);
    let marker = std::fs::read_to_string(run.join(".apo-run")).expect("marker");
    for entry in [
        "config.toml",
        "progress.csv",
        "episodes.csv",
        "train.log",
        "checkpoints",
        "apo.lock",
    ] {
        assert!(
            marker.lines().any(|l| l == entry),
            "{entry} not in {marker}"
        );
    }
    assert!(!marker.contains("notes.txt"), "{marker}");
}

#[test]
fn a_run_that_fails_before_its_first_epoch_leaves_only_what_was_there() {
    let tmp = tempfile::tempdir().expect("tempdir");
    // an empty folder the user made, then a run that fails at its first update
    let dir = tmp.path().join("empty");
    std::fs::create_dir(&dir).expect("mkdir");
    let err = fails(&[
        "train",
        "--algo",
        "a2c",
        "--env",
        "Pendulum-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "400",
        "--set",
        "algo.policy_update.lr=1e30",
        "--quiet",
        "--out",
        path(&dir),
    ]);
    assert!(err.contains("non-finite"), "{err}");
    assert!(dir.is_dir(), "a folder apo did not create stays");
    assert_eq!(
        std::fs::read_dir(&dir).expect("ls").count(),
        0,
        "nothing of apo's is left"
    );
}

#[test]
fn apo_writes_its_own_run_files_only_where_it_made_them_never_through_a_link() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    // a `videos/` apo did not make: its files are the user's, and no render writes there
    std::fs::create_dir(run.join("videos")).expect("mkdir");
    std::fs::write(run.join("videos/render.gif"), "mine").expect("write");
    let err = fails(&[
        "render",
        "--run",
        path(&run),
        "--episodes",
        "1",
        "--width",
        "32",
        "--height",
        "24",
    ]);
    assert!(
        err.contains("videos") && err.contains("not made by apo"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(run.join("videos/render.gif")).expect("kept"),
        b"mine"
    );
    // apo's lock and log are never opened through a link
    let victim = tmp.path().join("victim.txt");
    std::fs::write(&victim, "precious").expect("write");
    for own in ["apo.lock", "train.log"] {
        let file = run.join(own);
        let _ = std::fs::remove_file(&file);
        std::os::unix::fs::symlink(&victim, &file).expect("symlink");
        let err = fails(&["train", "--resume", path(&run), "--epochs", "2", "--quiet"]);
        assert!(
            err.contains("symbolic link") && err.contains(own),
            "{own}: {err}"
        );
        assert_eq!(std::fs::read(&victim).expect("kept"), b"precious", "{own}");
        std::fs::remove_file(&file).expect("rm");
    }
    // a link to nothing is an existing output too
    let dangling = tmp.path().join("d.png");
    std::os::unix::fs::symlink(tmp.path().join("nothere.png"), &dangling).expect("symlink");
    let err = fails(&["plot", path(&run), "--out", path(&dangling)]);
    assert!(err.contains("symbolic link"), "{err}");
    // one rule for a file the user names: a link there is never replaced, --force or not, by
    // any subcommand; what it points to is untouched
    for name in ["l.png", "l.gif"] {
        let target = tmp.path().join(format!("target-{name}"));
        std::fs::write(&target, "mine").expect("write");
        let link = tmp.path().join(name);
        std::os::unix::fs::symlink(&target, &link).expect("symlink");
        let args: Vec<&str> = if name.ends_with(".png") {
            vec!["plot", path(&run), "--out", path(&link), "--force"]
        } else {
            vec![
                "render",
                "--run",
                path(&run),
                "--episodes",
                "1",
                "--out",
                path(&link),
                "--force",
            ]
        };
        let err = fails(&args);
        assert!(err.contains("symbolic link"), "{name}: {err}");
        assert!(std::fs::symlink_metadata(&link)
            .expect("kept")
            .file_type()
            .is_symlink());
        assert_eq!(std::fs::read(&target).expect("kept"), b"mine");
    }
    // a long name (the temporary file's name is cut to fit)
    let long = tmp.path().join(format!("{}.png", "c".repeat(245)));
    ok(&["plot", path(&run), "--out", path(&long)]);
    assert!(long.is_file());
}

#[test]
fn force_never_follows_a_link_in_a_run_directory() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    // the user's folders, linked in apo's places, hold files of apo's names
    let mine = tmp.path().join("mine");
    let clips = tmp.path().join("clips");
    for (dir, files) in [
        (&mine, ["state.json", "policy.mpk"]),
        (&clips, ["render.gif", "epoch-1.gif"]),
    ] {
        std::fs::create_dir(dir).expect("mkdir");
        for f in files {
            std::fs::write(dir.join(f), "precious").expect("write");
        }
    }
    std::fs::remove_dir_all(run.join("checkpoints/latest")).expect("rm");
    std::os::unix::fs::symlink(&mine, run.join("checkpoints/latest")).expect("symlink");
    std::os::unix::fs::symlink(&clips, run.join("videos")).expect("symlink");
    let _ = apo(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--quiet",
        "--force",
        "--out",
        path(&run),
    ]);
    for (dir, files) in [
        (&mine, ["state.json", "policy.mpk"]),
        (&clips, ["render.gif", "epoch-1.gif"]),
    ] {
        for f in files {
            assert_eq!(
                std::fs::read(dir.join(f)).expect("kept"),
                b"precious",
                "{f}"
            );
        }
    }
    // and a linked checkpoints/ is refused, never written through
    let other = tmp.path().join("other");
    small(&other, &[]);
    let outside = tmp.path().join("outside");
    std::fs::create_dir(&outside).expect("mkdir");
    std::fs::remove_dir_all(other.join("checkpoints")).expect("rm");
    std::os::unix::fs::symlink(&outside, other.join("checkpoints")).expect("symlink");
    let out = apo(&[
        "train",
        "--resume",
        path(&other),
        "--epochs",
        "2",
        "--quiet",
    ]);
    assert!(!out.status.success());
    assert_eq!(
        std::fs::read_dir(&outside).expect("ls").count(),
        0,
        "nothing written through the link"
    );
}

#[test]
fn force_removes_only_the_epochs_apo_wrote_and_no_file_shared_by_a_hard_link_is_written() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    ok(&[
        "render",
        "--run",
        path(&run),
        "--episodes",
        "1",
        "--width",
        "16",
        "--height",
        "16",
    ]);
    // names of apo's form that this 1-epoch run never wrote are the user's
    for name in ["epoch-0.gif", "epoch-01.gif", "epoch-7.gif"] {
        std::fs::write(run.join("videos").join(name), "mine").expect("write");
    }
    std::fs::create_dir(run.join("checkpoints/epoch-000007")).expect("mkdir");
    std::fs::write(run.join("checkpoints/epoch-000007/state.json"), "mine").expect("write");
    small(&run, &["--force"]);
    for name in ["epoch-0.gif", "epoch-01.gif", "epoch-7.gif"] {
        assert_eq!(
            std::fs::read(run.join("videos").join(name)).expect("kept"),
            b"mine",
            "{name}"
        );
    }
    assert_eq!(
        std::fs::read(run.join("checkpoints/epoch-000007/state.json")).expect("kept"),
        b"mine"
    );
    // nor when they are not plain files (a FIFO would block the open forever)
    for own in ["apo.lock", "train.log"] {
        let file = run.join(own);
        let _ = std::fs::remove_file(&file);
        mkfifo(&file);
        let out = apo_within(
            60,
            &["train", "--resume", path(&run), "--epochs", "2", "--quiet"],
        );
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success()
                && (err.contains("not a regular file") || err.contains("is a special file"))
                && err.contains(own),
            "{own}: {err}"
        );
        std::fs::remove_file(&file).expect("rm");
    }
    // apo's lock and log are never written in place when another name shares them
    let notes = tmp.path().join("notes.txt");
    std::fs::write(&notes, "my notes").expect("write");
    for own in ["apo.lock", "train.log"] {
        let file = run.join(own);
        let _ = std::fs::remove_file(&file);
        std::fs::hard_link(&notes, &file).expect("hard link");
        let err = fails(&["train", "--resume", path(&run), "--epochs", "2", "--quiet"]);
        assert!(
            err.contains("hard links") && err.contains(own),
            "{own}: {err}"
        );
        assert_eq!(std::fs::read(&notes).expect("kept"), b"my notes", "{own}");
        std::fs::remove_file(&file).expect("rm");
    }
    // an epoch video of a name that exists is moved aside, never replaced
    let filmed = tmp.path().join("filmed");
    small(&filmed, &["--set", "render_every=1"]);
    std::fs::write(filmed.join("videos/epoch-2.gif"), "mine").expect("write");
    ok(&[
        "train",
        "--resume",
        path(&filmed),
        "--epochs",
        "2",
        "--quiet",
    ]);
    assert_eq!(
        std::fs::read(filmed.join("videos/epoch-2.gif.kept-1")).expect("aside"),
        b"mine"
    );
}

/// `apo args` with standard output (`stdout`) or standard error going to `target`.
fn apo_into(args: &[&str], stdout: Stdio, stderr: Stdio) -> std::process::ExitStatus {
    Command::new(env!("CARGO_BIN_EXE_apo"))
        .args(args)
        .stdout(stdout)
        .stderr(stderr)
        .status()
        .expect("the apo binary runs")
}

/// Rule: printing never panics. A full standard output (`/dev/full`) is an error naming it
/// (exit 1), a closed pipe ends apo quietly (exit 141, as a process SIGPIPE killed), and a
/// standard error that cannot be written loses the message, not the exit status — in every
/// subcommand that prints.
#[test]
fn a_full_or_closed_standard_output_is_an_error_never_a_panic() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    let full = || Stdio::from(std::fs::File::create("/dev/full").expect("/dev/full"));
    let cases: Vec<Vec<&str>> = vec![
        vec!["list"],
        vec!["config", "--algo", "apo", "--env", "CartPole-v1"],
        vec!["theory", "--states", "3", "--actions", "2", "--seeds", "1"],
        vec!["eval", "--run", path(&run), "--episodes", "1"],
        vec!["summary", path(&run)],
    ];
    for args in &cases {
        let out = Command::new(env!("CARGO_BIN_EXE_apo"))
            .args(args)
            .stdout(full())
            .output()
            .expect("runs");
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{args:?}: {err}");
        assert!(
            err.contains("cannot write to standard output"),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");

        // a reader that went away at once: quiet, 141 (or 0 when all fit in the pipe first)
        let mut child = Command::new(env!("CARGO_BIN_EXE_apo"))
            .args(args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn");
        drop(child.stdout.take());
        let out = child.wait_with_output().expect("waits");
        let err = text(&out.stderr);
        assert!(
            matches!(out.status.code(), Some(0 | 141)),
            "{args:?}: {:?} {err}",
            out.status
        );
        assert!(
            !err.contains("panicked") && !err.contains("error"),
            "{args:?}: {err}"
        );
    }
    // an error with a standard error that cannot be written still exits 1
    let status = apo_into(&["eval", "--run", "no-such-run"], Stdio::null(), full());
    assert_eq!(status.code(), Some(1));
}

/// Rule: apo never removes through a symbolic link, so it never replaces through one either:
/// `train --force` on a link to a run is refused with every file of the run kept, and the
/// write check of a folder reached through a link leaves nothing behind.
#[test]
fn force_refuses_a_linked_run_and_a_linked_output_folder_keeps_no_probe() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let ext = tmp.path().join("ext");
    std::fs::create_dir(&ext).expect("mkdir");
    let run = ext.join("run");
    small(&run, &[]);
    let config = std::fs::read(run.join("config.toml")).expect("config");
    let link = tmp.path().join("link");
    std::os::unix::fs::symlink(&run, &link).expect("symlink");
    let err = fails(&[
        "train",
        "--algo",
        "trpo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--quiet",
        "--force",
        "--out",
        path(&link),
    ]);
    assert!(
        err.contains("symbolic link") && err.contains(path(&run)),
        "{err}"
    );
    assert_eq!(
        std::fs::read(run.join("config.toml")).expect("kept"),
        config
    );

    let linked = tmp.path().join("linked");
    std::os::unix::fs::symlink(&ext, &linked).expect("symlink");
    ok(&["report", path(&run), "--reps", "10", "--out", path(&linked)]);
    let probes: Vec<String> = entries(&ext)
        .into_iter()
        .filter(|n| n.contains("probe"))
        .collect();
    assert!(probes.is_empty(), "{probes:?}");
}

/// A refused command writes nothing — not even the removal of a file that looks like apo's
/// own temporary file — and `.<name>.tmp`, the old fixed temporary name, is a user's name.
#[test]
fn a_refused_folder_and_files_of_temporary_looking_names_are_left_alone() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let mine = tmp.path().join("mine");
    std::fs::create_dir(&mine).expect("mkdir");
    let planted = [".report.md.apo-999998-7.tmp", "data.csv"];
    for name in planted {
        std::fs::write(mine.join(name), "mine").expect("write");
    }
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "50",
        "--quiet",
        "--out",
        path(&mine),
    ]);
    assert!(err.contains("apo did not make it"), "{err}");
    assert_eq!(entries(&mine), [".report.md.apo-999998-7.tmp", "data.csv"]);

    let run = tmp.path().join("run");
    small(&run, &[]);
    for name in [".progress.csv.tmp", ".config.toml.tmp"] {
        std::fs::write(run.join(name), "user data").expect("write");
    }
    ok(&["train", "--resume", path(&run), "--epochs", "3", "--quiet"]);
    for name in [".progress.csv.tmp", ".config.toml.tmp"] {
        assert_eq!(
            std::fs::read_to_string(run.join(name)).expect("kept"),
            "user data",
            "{name}"
        );
    }
}

/// Rule: a name apo would create that is longer than its file system takes is refused before
/// any work, naming the flag, the name's length and the limit — in every subcommand that
/// writes (a file, a run, a report, a sweep and the runs its grid names) — and nothing is left.
#[test]
fn a_name_too_long_for_its_file_system_is_refused_before_any_work_everywhere() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    let out = tmp.path().join("out");
    std::fs::create_dir(&out).expect("mkdir");
    let long = "a".repeat(300);
    let at = |name: String| out.join(name);
    let (video, image, folder) = (
        at(format!("{long}.gif")),
        at(format!("{long}.png")),
        at(long.clone()),
    );
    let said = |err: &str| err.contains("bytes long") && err.contains("takes at most");
    for args in [
        vec!["render", "--run", path(&run), "--out", path(&video)],
        vec!["plot", path(&run), "--out", path(&image)],
        small_args(&folder),
        vec!["report", path(&run), "--out", path(&folder)],
        sweep_args(&folder, "1"),
    ] {
        let err = fails(&args);
        assert!(said(&err) && err.contains("--out"), "{args:?}: {err}");
        assert!(
            entries(&out).is_empty(),
            "{args:?} left {:?}",
            entries(&out)
        );
    }
    // a grid value long enough to make a run's name too long: refused before the first run
    let sweep_dir = out.join("sweep");
    let value = format!("0.{}", "1".repeat(250));
    let grid = format!("algo.gamma=0.9,{value}");
    let mut args = sweep_args(&sweep_dir, "1");
    args.extend(["--grid", grid.as_str()]);
    let err = fails(&args);
    assert!(said(&err) && err.contains("grid values"), "{err}");
    assert!(
        !sweep_dir.exists(),
        "the sweep made {:?}",
        entries(&sweep_dir)
    );
}
