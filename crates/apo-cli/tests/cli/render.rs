//! `apo render` and `render_every`: the episodes of `apo eval`, the video's frames and size,
//! training unchanged by videos, and clear errors for bad input.

use std::path::Path;

use super::{fails, ok, path, small, timeless, train};

/// The frames and the size of a GIF.
pub fn gif_frames(file: &Path) -> (usize, (u16, u16)) {
    let mut options = gif::DecodeOptions::new();
    options.set_color_output(gif::ColorOutput::RGBA);
    let mut decoder = options
        .read_info(std::fs::File::open(file).expect("the video"))
        .expect("a GIF");
    let size = (decoder.width(), decoder.height());
    let mut frames = 0;
    while decoder.read_next_frame().expect("a frame").is_some() {
        frames += 1;
    }
    (frames, size)
}

/// `key=value` of `apo render`'s or `apo eval`'s output line.
fn field<'a>(out: &'a str, key: &str) -> &'a str {
    out.split_whitespace()
        .find_map(|f| f.strip_prefix(&format!("{key}=")))
        .unwrap_or_else(|| panic!("no {key} in {out}"))
}

#[test]
fn render_plays_the_episodes_of_eval_frame_by_frame() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    let video = tmp.path().join("cartpole.gif");
    let out = ok(&[
        "render",
        "--run",
        path(&run),
        "--episodes",
        "2",
        "--seed",
        "5",
        "--width",
        "64",
        "--height",
        "48",
        "--fps",
        "20",
        "--out",
        path(&video),
    ]);
    let returns: Vec<f64> = field(&out, "returns")
        .split(',')
        .map(|r| r.parse().expect("a return"))
        .collect();
    // the same episodes as `apo eval` with the same seed
    let eval = ok(&[
        "eval",
        "--run",
        path(&run),
        "--episodes",
        "2",
        "--seed",
        "5",
    ]);
    assert_eq!(returns.len(), 2);
    let (lo, hi) = (returns[0].min(returns[1]), returns[0].max(returns[1]));
    let number = |key: &str| field(&eval, key).parse::<f64>().expect("a number");
    assert!((number("min_return") - lo).abs() < 1e-3, "{out} vs {eval}");
    assert!((number("max_return") - hi).abs() < 1e-3, "{out} vs {eval}");
    // CartPole pays 1 per step: a frame after each reset and each step
    let steps: usize = returns.iter().map(|&r| r.round() as usize).sum();
    let (frames, size) = gif_frames(&video);
    assert_eq!(size, (64, 48));
    assert_eq!(frames, steps + 2, "{out}");
    // the last frame of each episode is held a second (20 frames at 20 fps)
    assert_eq!(
        field(&out, "frames").parse::<usize>().expect("frames"),
        steps + 2 + 2 * 19
    );

    // one step in 10: the resets, every 10th step and the episodes' ends
    let sparse = tmp.path().join("sparse.gif");
    ok(&[
        "render",
        "--run",
        path(&run),
        "--episodes",
        "2",
        "--seed",
        "5",
        "--width",
        "64",
        "--height",
        "48",
        "--every",
        "10",
        "--out",
        path(&sparse),
    ]);
    let kept: usize = returns
        .iter()
        .map(|&r| {
            let len = r.round() as usize;
            1 + len / 10 + usize::from(!len.is_multiple_of(10))
        })
        .sum();
    assert_eq!(gif_frames(&sparse).0, kept);
}

#[test]
fn render_refuses_bad_input_by_name() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    let err = fails(&["render", "--run", path(&run), "--camera", "side"]);
    assert!(
        err.contains("unknown camera `side`") && err.contains("track"),
        "{err}"
    );
    let err = fails(&[
        "render",
        "--run",
        path(&run),
        "--out",
        path(&tmp.path().join("v.avi")),
    ]);
    assert!(err.contains(".gif or .mp4"), "{err}");
    let err = fails(&[
        "render",
        "--run",
        path(&run),
        "--out",
        path(&tmp.path().join("no/such/dir/v.gif")),
    ]);
    assert!(err.contains("no/such/dir"), "{err}");
    let err = fails(&["render", "--run", path(&tmp.path().join("nothing"))]);
    assert!(err.contains("not a run directory"), "{err}");
    let err = fails(&["render", "--run", path(&run), "--width", "0"]);
    assert!(err.contains("--width"), "{err}");
    // nothing was left behind by the failures
    let left: Vec<_> = std::fs::read_dir(tmp.path())
        .expect("tempdir")
        .map(|e| e.expect("entry").file_name())
        .collect();
    assert_eq!(left, ["run"], "{left:?}");
    // the default video goes into the run's videos/, which apo claims as its own
    let out = ok(&[
        "render",
        "--run",
        path(&run),
        "--episodes",
        "1",
        "--every",
        "50",
    ]);
    assert!(run.join("videos/render.gif").is_file(), "{out}");
    let marker = std::fs::read_to_string(run.join(".apo-run")).expect("marker");
    assert!(marker.lines().any(|l| l == "videos"), "{marker}");
}

#[test]
fn videos_during_training_change_nothing_and_reach_tensorboard() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let (plain, filmed) = (tmp.path().join("plain"), tmp.path().join("filmed"));
    train(&plain, "ppo", &[]);
    train(&filmed, "ppo", &["--set", "render_every=2"]);
    assert_eq!(
        timeless(&plain),
        timeless(&filmed),
        "videos changed the training"
    );
    let videos: Vec<_> = std::fs::read_dir(filmed.join("videos"))
        .expect("videos/")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(videos, ["epoch-2.gif"]);
    let (frames, size) = gif_frames(&filmed.join("videos/epoch-2.gif"));
    assert_eq!(size, (320, 240));
    assert!(frames >= 2, "{frames}");
    // the event file holds the GIF as an image summary
    let events = std::fs::read_dir(&filmed)
        .expect("run")
        .map(|e| e.expect("entry").path())
        .find(|p| p.to_string_lossy().contains("tfevents"))
        .expect("an event file");
    let bytes = std::fs::read(events).expect("events");
    let has = |needle: &[u8]| bytes.windows(needle.len()).any(|w| w == needle);
    assert!(has(b"video/episode") && has(b"GIF89a"));
    // `--force` removes the videos it made with the rest of the run
    train(&filmed, "ppo", &["--force"]);
    assert!(!filmed.join("videos").exists());
}

/// `apo` with `args` and the environment variable `key=value`.
pub fn apo_with(key: &str, value: &str, args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_apo"))
        .args(args)
        .env(key, value)
        .output()
        .expect("apo runs")
}

#[test]
fn mujoco_runs_render_headless_and_say_why_when_opengl_is_missing() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("hopper");
    ok(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "Hopper-v4",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "200",
        "--quiet",
        "--out",
        path(&run),
    ]);
    let video = tmp.path().join("hopper.gif");
    let out = ok(&[
        "render",
        "--run",
        path(&run),
        "--episodes",
        "1",
        "--width",
        "96",
        "--height",
        "72",
        "--out",
        path(&video),
    ]);
    let (frames, size) = gif_frames(&video);
    assert_eq!(size, (96, 72));
    let eval = ok(&["eval", "--run", path(&run), "--episodes", "1"]);
    let length: f64 = field(&eval, "mean_length").parse().expect("a length");
    assert_eq!(frames, length as usize + 1, "{out}");

    // an APO_GL that names no OpenGL platform: the error names the variable and the values it
    // takes (not a missing library); no file is left
    let bad = tmp.path().join("bad.gif");
    let out = apo_with(
        "APO_GL",
        "none",
        &["render", "--run", path(&run), "--out", path(&bad)],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("Hopper-v4")
            && stderr.contains("APO_GL=none")
            && stderr.contains("`egl` or `osmesa`")
            && !stderr.contains("install"),
        "{stderr}"
    );
    assert!(!bad.exists());
    // a run with videos whose environment cannot be rendered stops before its first epoch,
    // leaving no directory behind
    let unfilmable = tmp.path().join("unfilmable");
    let out = apo_with(
        "APO_GL",
        "none",
        &[
            "train",
            "--algo",
            "ppo",
            "--env",
            "Hopper-v4",
            "--epochs",
            "1",
            "--steps-per-epoch",
            "200",
            "--quiet",
            "--out",
            path(&unfilmable),
            "--set",
            "render_every=1",
        ],
    );
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("render_every = 1: cannot render Hopper-v4"),
        "{stderr}"
    );
    assert!(!unfilmable.exists(), "{stderr}");
}

/// Rule: the final placement of an output the user named cannot replace what appeared after
/// the check. A file or a link put at `--out` while the video is recorded stays (with
/// `--force` too, for a link), the render fails naming it and leaves no temporary file; and a
/// user's file named like apo's temporary files, of a process that is gone, is not apo's.
#[test]
fn a_file_that_appears_at_the_output_during_a_render_is_not_replaced() {
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("run");
    small(&run, &[]);
    let videos = tmp.path().join("videos");
    std::fs::create_dir(&videos).expect("mkdir");
    // a user's file of a temporary-looking name, of a process id that is not running
    let lookalike = videos.join(".race.gif.apo-4000000-0.tmp");
    std::fs::write(&lookalike, "mine").expect("write");
    let theirs = tmp.path().join("theirs.txt");
    std::fs::write(&theirs, "theirs").expect("write");
    for (case, force) in [("file", false), ("link", false), ("link", true)] {
        let out = videos.join(format!("race-{case}-{force}.gif"));
        let mut planted = false;
        // the render must still be running when the file appears: longer renders until it is
        for episodes in ["20", "80", "320"] {
            let mut args = vec![
                "render",
                "--run",
                path(&run),
                "--episodes",
                episodes,
                "--width",
                "320",
                "--height",
                "240",
                "--out",
                path(&out),
            ];
            if force {
                args.push("--force");
            }
            let mut child = super::spawn(&args);
            let prefix = format!(".race-{case}-{force}.gif.apo-");
            let deadline = std::time::Instant::now() + std::time::Duration::from_secs(120);
            let started = loop {
                let temp = std::fs::read_dir(&videos).expect("ls").any(|e| {
                    e.expect("entry")
                        .file_name()
                        .to_string_lossy()
                        .starts_with(&prefix)
                });
                if temp || child.try_wait().expect("try_wait").is_some() {
                    break temp;
                }
                assert!(
                    std::time::Instant::now() < deadline,
                    "the render did not start"
                );
                std::thread::sleep(std::time::Duration::from_millis(2));
            };
            if started {
                match case {
                    "file" => std::fs::write(&out, "mine").expect("write"),
                    _ => std::os::unix::fs::symlink(&theirs, &out).expect("link"),
                }
            }
            if started && child.try_wait().expect("try_wait").is_none() {
                let (code, stdout, stderr) = super::finish(child, 300);
                assert_eq!(code, Some(1), "{case}, force {force}: {stdout}{stderr}");
                assert!(
                    stderr.contains(&path(&out).to_string())
                        && stderr.contains("nothing was replaced"),
                    "{case}, force {force}: {stderr}"
                );
                planted = true;
                break;
            }
            let _ = child.wait();
            let _ = std::fs::remove_file(&out);
        }
        assert!(
            planted,
            "{case}: no render lasted long enough to plant a file during it"
        );
        match case {
            "file" => assert_eq!(std::fs::read_to_string(&out).expect("read"), "mine"),
            _ => assert_eq!(std::fs::read_link(&out).expect("the link stays"), theirs),
        }
        std::fs::remove_file(&out).expect("rm");
    }
    assert_eq!(std::fs::read_to_string(&theirs).expect("read"), "theirs");
    // nothing but the user's look-alike is left: no temporary file of apo's
    let left: Vec<String> = std::fs::read_dir(&videos)
        .expect("ls")
        .map(|e| e.expect("entry").file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(left, [".race.gif.apo-4000000-0.tmp"], "{left:?}");
    ok(&[
        "render",
        "--run",
        path(&run),
        "--episodes",
        "1",
        "--out",
        path(&videos.join("race.gif")),
    ]);
    assert_eq!(
        std::fs::read_to_string(&lookalike).expect("the look-alike stays"),
        "mine"
    );
}
