//! Rule: errors name the real cause — the child's exit status and stderr, a folder that holds
//! a config but no run, the file's actual header — and clashing flags are refused the same
//! way by every subcommand (clap's conflict error, exit status 2).

use std::os::unix::fs::FileTypeExt;
use std::path::Path;
use std::time::{Duration, Instant};

use super::*;

/// A folder holding an executable `ffmpeg` shell script with `body`.
fn fake_ffmpeg(dir: &Path, body: &str) -> String {
    use std::os::unix::fs::PermissionsExt;
    std::fs::create_dir_all(dir).expect("mkdir");
    let script = dir.join("ffmpeg");
    std::fs::write(&script, format!("#!/bin/sh\n{body}\n")).expect("write");
    std::fs::set_permissions(&script, std::fs::Permissions::from_mode(0o755)).expect("chmod");
    // the script's own tools stay reachable
    format!("{}:/usr/bin:/bin", dir.display())
}

#[test]
fn ffmpeg_failures_are_reported_with_exit_status_and_stderr_and_a_stalled_one_is_stopped() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    let mp4 = tmp.path().join("v.mp4");
    let args = [
        "render",
        "--run",
        path(&run),
        "--episodes",
        "1",
        "--width",
        "64",
        "--height",
        "48",
        "--out",
        path(&mp4),
    ];
    let render = |path_var: &str| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_apo"))
            .args(args)
            .env("PATH", path_var)
            .output()
            .expect("apo runs");
        assert!(!out.status.success());
        String::from_utf8_lossy(&out.stderr).into_owned()
    };
    // an ffmpeg that is there but broken is not "not installed"
    let broken = fake_ffmpeg(
        &tmp.path().join("broken"),
        "echo 'libavcodec.so.59: cannot open' >&2; exit 127",
    );
    let err = render(&broken);
    assert!(
        err.contains("ffmpeg -version") && err.contains("127") && err.contains("libavcodec"),
        "{err}"
    );
    assert!(!err.contains("not on the PATH"), "{err}");
    // one that fails while encoding: its exit status and its words
    let failing = fake_ffmpeg(
        &tmp.path().join("failing"),
        "[ \"$1\" = -version ] && exit 0\necho \"Unknown encoder 'libx264'\" >&2\nexit 3",
    );
    let err = render(&failing);
    assert!(
        err.contains("exit status: 3") && err.contains("Unknown encoder"),
        "{err}"
    );
    // one that stops reading (its shell waits on a child that holds the pipes) is stopped
    let stalled = fake_ffmpeg(
        &tmp.path().join("stalled"),
        "[ \"$1\" = -version ] && exit 0\nsleep 60\nexit 0",
    );
    let start = Instant::now();
    let err = render(&stalled);
    assert!(err.contains("ffmpeg read no frame for 20 s"), "{err}");
    assert!(
        start.elapsed() < Duration::from_secs(50),
        "{:?}",
        start.elapsed()
    );
    // one whose `-version` never answers is stopped too, before any file is made
    let mute = fake_ffmpeg(&tmp.path().join("mute"), "sleep 60");
    let start = Instant::now();
    let err = render(&mute);
    assert!(err.contains("did not answer within 20 s"), "{err}");
    assert!(
        start.elapsed() < Duration::from_secs(50),
        "{:?}",
        start.elapsed()
    );
    // one that reads every frame, exits 0 and writes nothing: no empty video
    let empty = fake_ffmpeg(
        &tmp.path().join("empty"),
        "[ \"$1\" = -version ] && exit 0\ncat > /dev/null\nexit 0",
    );
    let err = render(&empty);
    assert!(err.contains("wrote nothing"), "{err}");
    let left: Vec<_> = std::fs::read_dir(tmp.path())
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .filter(|n| n.contains("v.mp4"))
        .collect();
    assert!(left.is_empty(), "no video and no temporary file: {left:?}");
}

#[test]
fn a_run_missing_its_checkpoints_or_edited_to_another_task_is_named_so() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    super::train(&run, "ppo", &[]);
    // another task with other sizes: the key is named, not only the networks
    let config = std::fs::read_to_string(run.join("config.toml")).expect("read");
    std::fs::write(
        run.join("config.toml"),
        config.replace("env = \"CartPole-v1\"", "env = \"Acrobot-v1\""),
    )
    .expect("write");
    for args in [
        vec!["eval", "--run", path(&run)],
        vec!["train", "--resume", path(&run), "--epochs", "4", "--quiet"],
    ] {
        let err = fails(&args);
        assert!(
            err.contains("env") && err.contains("Acrobot-v1"),
            "{args:?}: {err}"
        );
    }
    std::fs::write(run.join("config.toml"), config).expect("restore");
    // the checkpoints removed under a recorded run
    std::fs::remove_dir_all(run.join("checkpoints")).expect("rm");
    let err = fails(&["eval", "--run", path(&run)]);
    assert!(
        err.contains("records 3 epochs: the checkpoints were removed"),
        "{err}"
    );
}

#[test]
fn a_folder_with_a_config_but_no_run_is_named_so_by_eval_render_and_resume() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let folder = tmp.path().join("only-config");
    std::fs::create_dir(&folder).expect("mkdir");
    let config = super::ok(&["config", "--algo", "ppo", "--env", "CartPole-v1"]);
    std::fs::write(folder.join("config.toml"), config).expect("write");
    let image = folder.join("x.png");
    for args in [
        vec!["eval", "--run", path(&folder)],
        vec!["render", "--run", path(&folder)],
        vec!["train", "--resume", path(&folder)],
        vec!["summary", path(&folder)],
        vec!["report", path(&folder)],
        vec!["plot", path(&folder), "--out", path(&image)],
    ] {
        let err = fails(&args);
        assert!(
            err.contains("config.toml but no run") || err.contains("is not a run directory of apo"),
            "{args:?}: {err}"
        );
        assert!(err.contains("apo train --config"), "{args:?}: {err}");
    }
    let left: Vec<_> = std::fs::read_dir(&folder)
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(
        left,
        ["config.toml"],
        "nothing written into the user's folder"
    );
}

/// Rule: a run whose `config.toml` apo cannot use (not TOML, a key no setting has, a value out
/// of range) is a run with a bad config, not "not a run directory": every command that reads a
/// run names the run, the file and the line or key at fault, and changes nothing.
#[test]
fn a_run_whose_config_apo_cannot_use_is_named_with_the_file_and_the_fault_by_every_reader() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let out = tmp.path().join("sweep");
    let done = super::sweep(&out, "1", &[]);
    assert!(done.status.success(), "{}", super::text(&done.stderr));
    let run = out.join("CartPole-v1-ppo-s0");
    let config = run.join("config.toml");
    let original = std::fs::read_to_string(&config).expect("config.toml");
    let image = tmp.path().join("x.png");
    let video = tmp.path().join("x.gif");
    let report = tmp.path().join("report");
    for (damage, fault) in [
        ("epochs = [\n".to_string(), "not valid TOML"),
        (
            format!("{original}[train]\nepochs = 3\n"),
            "unknown config key `train`",
        ),
        (original.replace("seed = 0", "seed = -1"), "`seed`"),
    ] {
        std::fs::write(&config, &damage).expect("damage");
        for args in [
            vec!["eval", "--run", path(&run)],
            vec!["render", "--run", path(&run), "--out", path(&video)],
            vec!["train", "--resume", path(&run), "--quiet"],
            vec!["report", path(&run), "--out", path(&report)],
            vec!["plot", path(&run), "--out", path(&image)],
            vec!["config", "--run", path(&run)],
            super::sweep_args(&out, "2"),
        ] {
            let err = fails(&args);
            assert!(
                err.contains(&format!(
                    "the run in {} has a config.toml apo cannot use",
                    run.display()
                )) && err.contains(&format!("config {}", config.display()))
                    && err.contains(fault)
                    && !err.contains("not a run directory"),
                "{args:?} with {fault}: {err}"
            );
        }
        assert_eq!(std::fs::read_to_string(&config).expect("config"), damage);
        assert!(!image.exists() && !video.exists() && !report.exists());
    }
    // a folder without a config.toml is still "not a run directory", naming what it lacks
    std::fs::remove_file(&config).expect("rm");
    let err = fails(&["config", "--run", path(&run)]);
    assert!(
        err.contains("is not a run directory: it has no config.toml"),
        "{err}"
    );
}

/// A reader given something that is not a run says what it is — missing, a file, a folder
/// with neither records nor a config — and never claims a `config.toml` that is not there.
#[test]
fn a_path_that_is_no_run_is_named_for_what_it_is() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let file = tmp.path().join("file");
    std::fs::write(&file, "x").expect("write");
    let empty = tmp.path().join("empty");
    std::fs::create_dir(&empty).expect("mkdir");
    let missing = tmp.path().join("missing");
    for (dir, says) in [
        (&missing, "No such file"),
        (&file, "not a folder"),
        (&empty, "neither progress.csv nor config.toml"),
    ] {
        let err = fails(&["summary", path(dir)]);
        assert!(
            err.contains(says) && !err.contains("holds a config.toml"),
            "{err}"
        );
    }
}

#[test]
fn a_score_file_with_another_header_is_shown_its_own_header() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let scores = tmp.path().join("scores.csv");
    std::fs::write(&scores, "algo,env,value\napo,Hopper,1.0\n").expect("write");
    let err = fails(&["stats", path(&scores)]);
    assert!(
        err.contains("its header is `algo,env,value`") && err.contains("algorithm,task,score"),
        "{err}"
    );
}

#[test]
fn clashing_flags_are_refused_alike_by_every_subcommand() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    for args in [
        vec!["config", "--run", path(&run), "--algo", "ppo"],
        vec!["config", "--run", path(&run), "--env", "Hopper"],
        vec!["train", "--resume", path(&run), "--algo", "ppo"],
        vec!["train", "--resume", path(&run), "--env", "Hopper"],
    ] {
        let out = apo(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("cannot be used with"), "{args:?}: {err}");
    }
}

#[test]
fn a_folder_that_merely_holds_a_config_is_not_a_run_directory() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let proj = tmp.path().join("proj");
    std::fs::create_dir(&proj).expect("mkdir");
    let config = ok(&["config", "--algo", "ppo", "--env", "CartPole-v1"]);
    std::fs::write(proj.join("config.toml"), &config).expect("write");
    plant(&proj, "train.log", "the user's own log");
    plant(
        &proj,
        "checkpoints/resnet/model.pt",
        "weights of another project",
    );
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--out",
        path(&proj),
        "--force",
        "--quiet",
    ]);
    assert!(
        err.contains("nothing in it was touched") && err.contains(".apo-run"),
        "{err}"
    );
    let err = fails(&["train", "--resume", path(&proj), "--quiet"]);
    assert!(err.contains("not a run directory of apo"), "{err}");
    assert_eq!(
        std::fs::read_to_string(proj.join("train.log")).expect("kept"),
        "the user's own log"
    );
    assert!(proj.join("checkpoints/resnet/model.pt").exists());
    assert_eq!(
        std::fs::read_to_string(proj.join("config.toml")).expect("kept"),
        config
    );
    assert!(!proj.join(".apo-run").exists() && !proj.join("progress.csv").exists());
    // a run directory where a file of apo's names was put by someone else: --force refuses
    let run = tmp.path().join("run");
    small(&run, &[]);
    let marker = run.join(".apo-run");
    let listed = std::fs::read_to_string(&marker).expect("marker");
    std::fs::write(&marker, listed.replace("train.log\n", "")).expect("edit");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--out",
        path(&run),
        "--force",
        "--quiet",
    ]);
    assert!(
        err.contains("train.log") && err.contains("did not create"),
        "{err}"
    );
    assert!(run.join("progress.csv").exists(), "nothing may be touched");
    // the same for a user's link or folder in place of a file apo lists: --force would keep it
    // and the new run would write over it
    for (name, make) in [
        ("progress.csv", "link"),
        ("episodes.csv", "link"),
        ("config.toml", "link"),
        ("progress.csv", "folder"),
    ] {
        let run = tmp.path().join(format!("{name}-{make}"));
        small(&run, &[]);
        let user = tmp.path().join(format!("{name}-{make}.user"));
        std::fs::write(&user, b"the user's").expect("user file");
        std::fs::remove_file(run.join(name)).expect("remove");
        match make {
            "link" => std::os::unix::fs::symlink(&user, run.join(name)).expect("link"),
            _ => {
                std::fs::create_dir(run.join(name)).expect("folder");
                std::fs::write(run.join(name).join("mine"), b"x").expect("file in it");
            }
        }
        let err = fails(&[
            "train",
            "--algo",
            "ppo",
            "--env",
            "CartPole-v1",
            "--out",
            path(&run),
            "--force",
            "--quiet",
        ]);
        assert!(
            err.contains(name) && err.contains("did not create"),
            "{err}"
        );
        let meta = std::fs::symlink_metadata(run.join(name)).expect("still there");
        match make {
            "link" => assert!(meta.file_type().is_symlink(), "{name}: the link stays"),
            _ => assert!(
                run.join(name).join("mine").exists(),
                "{name}: the folder stays"
            ),
        }
        assert_eq!(std::fs::read(&user).expect("user file"), b"the user's");
        assert!(run.join("train.log").exists(), "nothing may be touched");
    }
    // a resume and a --force are refused before anything is touched where something apo did
    // not make sits where apo writes or removes: apo makes no links and no special files, and
    // keeps its checkpoints as folders of plain files
    for (entry, plant, force) in [
        ("progress.csv", "link", false),
        ("videos", "link", true),
        ("videos", "link", false),
        ("videos/epoch-1.gif", "link", true),
        ("checkpoints/previous", "file", false),
        ("checkpoints/previous", "file", true),
        ("checkpoints/best", "file", false),
        ("checkpoints/best", "file", true),
        ("checkpoints/epoch-000001", "file", true),
        ("checkpoints/latest/state.json", "fifo", true),
        ("checkpoints/latest/state.json", "fifo", false),
        ("events.out.tfevents.", "fifo", true),
        ("events.out.tfevents.", "fifo", false),
    ] {
        let label = format!("{}-{plant}-{force}", entry.replace('/', "-"));
        let run = tmp.path().join(&label);
        let extra = [
            "--set",
            "render_every=1",
            "--set",
            "keep_checkpoint_every=1",
        ];
        small(&run, &extra);
        let user = tmp.path().join(format!("{label}.user"));
        std::fs::create_dir_all(&user).expect("user folder");
        // the TensorBoard file's name has the time in it
        let entry = match entry {
            "events.out.tfevents." => std::fs::read_dir(&run)
                .expect("ls")
                .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
                .find(|n| n.starts_with(entry))
                .expect("an event file"),
            _ => entry.to_string(),
        };
        let place = run.join(&entry);
        if place.is_dir() {
            std::fs::remove_dir_all(&place).expect("remove");
        } else if place.exists() {
            std::fs::remove_file(&place).expect("remove");
        }
        match plant {
            "file" => std::fs::write(&place, b"mine").expect("user file"),
            "fifo" => mkfifo(&place),
            _ => std::os::unix::fs::symlink(&user, &place).expect("link"),
        }
        let before = std::fs::read(run.join("progress.csv")).ok();
        let out = if force {
            let mut args = small_args(&run);
            args.extend_from_slice(&extra);
            args.push("--force");
            apo_within(60, &args)
        } else {
            apo_within(
                60,
                &["train", "--resume", path(&run), "--epochs", "2", "--quiet"],
            )
        };
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(&entry) && err.contains("nothing was touched"),
            "{entry} ({plant}), force {force}: {err}"
        );
        assert!(
            std::fs::symlink_metadata(&place).is_ok(),
            "{entry}: the user's entry stays"
        );
        assert!(run.join(".apo-run").exists(), "{entry}: the run stays");
        assert_eq!(
            std::fs::read(run.join("progress.csv")).ok(),
            before,
            "{entry}, force {force}: the record is untouched"
        );
    }
}

/// Rule: a folder is a new run's only when it is empty or holds nothing but what a running apo
/// is making there (its marker, the lock file the marker lists, the marker's temporary files
/// of a live process); anything else of apo's names is the user's, and the folder is refused
/// untouched.
#[test]
fn a_folder_with_files_of_apo_names_only_is_not_taken_for_an_empty_one() {
    let tmp = tempfile::tempdir().expect("tempdir");
    for (name, folder) in [
        ("apo.lock", false),
        ("apo.lock", true),
        (".apo-run.apo-999999-0.tmp", false),
    ] {
        let out = tmp
            .path()
            .join(format!("{}-{folder}", name.trim_start_matches('.')));
        std::fs::create_dir(&out).expect("folder");
        let planted = out.join(name);
        if folder {
            std::fs::create_dir(&planted).expect("user folder");
        } else {
            std::fs::write(&planted, b"mine").expect("user file");
        }
        let err = fails(&small_args(&out));
        assert!(err.contains("apo did not make it"), "{name}: {err}");
        let left: Vec<String> = std::fs::read_dir(&out)
            .expect("ls")
            .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(left, vec![name.to_string()], "{name}: nothing added");
        if !folder {
            assert_eq!(std::fs::read(&planted).expect("read"), b"mine");
        }
    }
}

/// Rule: the epochs after a run's last checkpoint are run again on resume (same seed, same
/// rows); a run stopped before its first checkpoint has epoch 0 as its last one. Records past
/// a checkpoint that was due and is gone are refused, naming how to start over.
#[test]
fn a_run_stopped_before_its_first_checkpoint_resumes_from_epoch_zero() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let whole = tmp.path().join("whole");
    let cut = tmp.path().join("cut");
    let every = ["--set", "checkpoint_every=5"];
    train(&whole, "ppo", &every);
    train(&cut, "ppo", &every);
    // a run killed before its first checkpoint (due at epoch 3, the last) has records but no
    // checkpoint folder
    std::fs::remove_dir_all(cut.join("checkpoints")).expect("rm");
    let err = fails(&["eval", "--run", path(&cut)]);
    assert!(
        err.contains("before its first checkpoint") && err.contains("--resume"),
        "{err}"
    );
    ok(&["train", "--resume", path(&cut), "--quiet"]);
    assert_eq!(timeless(&cut), timeless(&whole));
    assert_eq!(
        std::fs::read(cut.join("episodes.csv")).expect("episodes"),
        std::fs::read(whole.join("episodes.csv")).expect("episodes")
    );
    // with a checkpoint due at every epoch, three records and no checkpoint are a loss
    let lost = tmp.path().join("lost");
    train(&lost, "ppo", &[]);
    std::fs::remove_dir_all(lost.join("checkpoints")).expect("rm");
    let before = std::fs::read(lost.join("progress.csv")).expect("progress");
    let err = fails(&["train", "--resume", path(&lost), "--quiet"]);
    assert!(
        err.contains("--force") && err.contains("due at epoch 1"),
        "{err}"
    );
    assert_eq!(
        std::fs::read(lost.join("progress.csv")).expect("kept"),
        before
    );
}

/// Rule: an output apo replaces (a report's files, the default video) is replaced only when it
/// is a plain file apo wrote: a link or special file there is refused before any work.
#[test]
fn outputs_of_apo_names_that_are_links_or_pipes_are_refused_before_any_work() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    // a report folder: a pipe at a name the report writes, before and after apo wrote it
    let fresh = tmp.path().join("fresh");
    std::fs::create_dir(&fresh).expect("folder");
    mkfifo(&fresh.join("statistics.json"));
    let out = apo_within(60, &["report", path(&run), "--out", path(&fresh)]);
    assert!(
        !out.status.success() && out.stdout.is_empty(),
        "refused, nothing printed"
    );
    assert!(
        text(&out.stderr).contains("statistics.json"),
        "{}",
        text(&out.stderr)
    );
    let again = tmp.path().join("again");
    ok(&["report", path(&run), "--out", path(&again)]);
    std::fs::remove_file(again.join("report.csv")).expect("rm");
    mkfifo(&again.join("report.csv"));
    let out = apo_within(60, &["report", path(&run), "--out", path(&again)]);
    assert!(!out.status.success(), "refused");
    assert!(
        text(&out.stderr).contains("report.csv"),
        "{}",
        text(&out.stderr)
    );
    assert!(std::fs::symlink_metadata(again.join("report.csv"))
        .expect("kept")
        .file_type()
        .is_fifo());
    // the run's default video: a link there is the user's
    let precious = tmp.path().join("precious.gif");
    std::fs::write(&precious, b"mine").expect("write");
    ok(&["render", "--run", path(&run), "--episodes", "1"]);
    std::fs::remove_file(run.join("videos/render.gif")).expect("rm");
    std::os::unix::fs::symlink(&precious, run.join("videos/render.gif")).expect("link");
    let err = fails(&["render", "--run", path(&run), "--episodes", "1"]);
    assert!(
        err.contains("render.gif") && err.contains("symbolic link"),
        "{err}"
    );
    assert_eq!(std::fs::read(&precious).expect("read"), b"mine");
    assert!(std::fs::symlink_metadata(run.join("videos/render.gif"))
        .expect("kept")
        .file_type()
        .is_symlink());
}

#[test]
fn errors_name_the_culprit_and_are_said_once() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let err = fails(&[
        "train",
        "--algo",
        "apo",
        "--env",
        "CartPole-v1",
        "--set",
        "algo.k=inf",
        "--out",
        path(&tmp.path().join("r")),
    ]);
    assert!(err.contains("must be finite"), "{err}");
    // a config file with two algorithms' sections
    let two = tmp.path().join("two.toml");
    let both = "[algo.apo]\nk = 5.0\n\n[algo.trpo.trust_region]\nmax_kl = 0.01\n";
    std::fs::write(&two, both).expect("write");
    let r = tmp.path().join("r");
    for extra in [&[][..], &["--algo", "apo"][..]] {
        let mut args = vec![
            "train",
            "--env",
            "CartPole-v1",
            "--config",
            path(&two),
            "--out",
            path(&r),
        ];
        args.extend_from_slice(extra);
        let err = fails(&args);
        assert!(
            err.contains("several algorithms (apo, trpo)"),
            "{extra:?}: {err}"
        );
    }
    // a pipe or device as a config file: refused at once, never read
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--config",
        "/dev/zero",
        "--out",
        path(&tmp.path().join("r")),
    ]);
    assert!(
        err.contains("/dev/zero") && err.contains("not a regular file"),
        "{err}"
    );
    // plot: an output folder that does not exist, said with the path, before reading runs
    let err = fails(&[
        "plot",
        path(&tmp.path().join("missing-run")),
        "--out",
        path(&tmp.path().join("nodir/x.png")),
    ]);
    assert!(
        err.contains("nodir") && err.contains("does not exist"),
        "{err}"
    );
    // report: options are checked before any work
    let file = tmp.path().join("file");
    std::fs::write(&file, "").expect("write");
    let err = fails(&[
        "report",
        path(&tmp.path().join("missing")),
        "--out",
        path(&file),
    ]);
    assert!(
        err.contains("--out") && err.contains("not a directory"),
        "{err}"
    );
    let err = fails(&["report", path(&tmp.path().join("missing")), "--smooth", "0"]);
    assert!(err.contains("--smooth"), "{err}");
    // a flag and --set that disagree: the flag wins, with a warning
    let run = tmp.path().join("w");
    let out = apo(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--seed",
        "3",
        "--set",
        "seed=4",
        "--quiet",
        "--out",
        path(&run),
    ]);
    assert!(out.status.success());
    assert!(
        text(&out.stderr).contains("--seed 3 overrides --set seed=4"),
        "{}",
        text(&out.stderr)
    );
    // … and a flag that overrides the --config file's value
    let file = tmp.path().join("seeded.toml");
    std::fs::write(&file, "seed = 9\n").expect("write");
    let w2 = tmp.path().join("w2");
    let out = apo(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--seed",
        "3",
        "--config",
        path(&file),
        "--quiet",
        "--out",
        path(&w2),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("--seed 3 overrides seed = 9 of --config"),
        "{}",
        text(&out.stderr)
    );
    // an epoch count past any budget: refused with the rule, before a directory exists
    let never = tmp.path().join("never");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--epochs",
        "18446744073709551615",
        "--out",
        path(&never),
    ]);
    assert!(
        err.contains("--epochs") && err.contains("1..=1000000000"),
        "{err}"
    );
    // … and one past the budget in a config file: the config's rule
    std::fs::write(&file, "epochs = 2000000000\n").expect("write");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "CartPole-v1",
        "--config",
        path(&file),
        "--out",
        path(&never),
    ]);
    assert!(
        err.contains("`epochs`") && err.contains("must be ≤ 1000000000"),
        "{err}"
    );
    assert!(!never.exists());
}

/// Two trainings started at once into one new folder: one trains, the other is refused for
/// the true reason — the folder is in use, or already holds a run — never "apo did not make it".
#[test]
fn the_loser_of_a_creation_race_is_told_the_true_reason() {
    let tmp = tempfile::tempdir().expect("tempdir");
    for round in 0..3 {
        let dir = tmp.path().join(format!("race{round}"));
        let args = small_args(&dir);
        let (a, b) = (spawn(&args), spawn(&args));
        let (a, b) = (finish(a, 120), finish(b, 120));
        let codes = [a.0, b.0];
        assert!(codes.contains(&Some(0)), "one of them trains: {a:?} {b:?}");
        for (code, _, stderr) in [a, b] {
            if code != Some(0) {
                assert!(
                    stderr.contains("in use by another apo process")
                        || stderr.contains("already exists; pass --force"),
                    "{stderr}"
                );
            }
        }
    }
}
