//! Videos of rendered frames: GIF (the `gif` crate) or MP4 (the `ffmpeg` program, when the
//! machine has it), chosen by the file's extension, written to a temporary file beside the
//! target and renamed over it when complete; and the text overlay of `apo render`.

use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, ChildStdin, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};

use anyhow::{bail, Context};
use apo_core::inference::HostPolicy;
use apo_envs::{Camera, Env, Frame, RunningMeanStd};
use plotters::backend::BitMapBackend;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use crate::atomic;
use crate::checkpoint::Which;
use crate::config::RunConfig;
use crate::eval::{Episodes, EvalResult, LoadedRun, Moment};
use crate::run_dir::VIDEOS;

/// A video's container, from its file name's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// `.gif`: 256 colours per frame, needs nothing installed.
    Gif,
    /// `.mp4`: H.264 through `ffmpeg`.
    Mp4,
}

impl Format {
    /// The format of `path`'s extension (`gif` or `mp4`, any case).
    ///
    /// # Errors
    /// For any other extension, naming the path.
    pub fn of(path: &Path) -> anyhow::Result<Format> {
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match extension.as_deref() {
            Some("gif") => Ok(Format::Gif),
            Some("mp4") => Ok(Format::Mp4),
            _ => bail!(
                "{}: a video must end in .gif or .mp4 (the extension picks the format)",
                path.display()
            ),
        }
    }
}

/// Whether `ffmpeg` runs on this machine.
pub fn ffmpeg_available() -> bool {
    Command::new("ffmpeg")
        .arg("-version")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}

enum Sink {
    Gif(gif::Encoder<BufWriter<std::fs::File>>),
    Mp4 {
        ffmpeg: Child,
        stdin: BufWriter<ChildStdin>,
    },
}

/// A video being written: frames of one size, at a fixed rate.
///
/// Dropped before [`VideoWriter::finish`] (an error, a signal), it removes its temporary file:
/// the target is left as it was.
pub struct VideoWriter {
    /// `None` once finished.
    sink: Option<Sink>,
    path: PathBuf,
    tmp: PathBuf,
    size: (u32, u32),
    fps: u32,
    frames: usize,
}

impl VideoWriter {
    /// Starts a video of `width × height` frames at `fps` frames per second at `path`, in the
    /// format of its extension. An MP4 on a machine without `ffmpeg` becomes a GIF beside it
    /// (`video.mp4` → `video.gif`), with a warning on stderr; [`VideoWriter::path`] says which.
    ///
    /// # Errors
    /// An unknown extension, a size a GIF cannot hold, an unwritable folder.
    pub fn create(path: &Path, width: u32, height: u32, fps: u32) -> anyhow::Result<VideoWriter> {
        let mut format = Format::of(path)?;
        let mut path = path.to_path_buf();
        if format == Format::Mp4 && !ffmpeg_available() {
            path.set_extension("gif");
            eprintln!(
                "warning: ffmpeg is not installed (Debian: apt-get install ffmpeg), so the video is a GIF: {}",
                path.display()
            );
            format = Format::Gif;
        }
        crate::input::check_output_file(&path, "--out")?;
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let tmp = atomic::parent(&path).join(atomic::temp_name(&name));
        let fps = fps.clamp(1, 100);
        let sink = match format {
            Format::Gif => {
                let (w, h) = (u16::try_from(width), u16::try_from(height));
                let (Ok(w), Ok(h)) = (w, h) else {
                    bail!("a GIF's sides are at most 65535 pixels, not {width}x{height}");
                };
                let file = std::fs::File::create(&tmp)
                    .with_context(|| format!("cannot create {}", tmp.display()))?;
                let mut encoder = gif::Encoder::new(BufWriter::new(file), w, h, &[])
                    .with_context(|| format!("cannot write {}", tmp.display()))?;
                encoder.set_repeat(gif::Repeat::Infinite)?;
                Sink::Gif(encoder)
            }
            Format::Mp4 => {
                let mut ffmpeg = Command::new("ffmpeg")
                    .args(["-hide_banner", "-loglevel", "error", "-y", "-f", "rawvideo"])
                    .args(["-pix_fmt", "rgb24", "-s", &format!("{width}x{height}")])
                    .args(["-r", &fps.to_string(), "-i", "-"])
                    // H.264 in 4:2:0 needs even sides: pad by one pixel where odd
                    .args(["-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v", "libx264"])
                    .args([
                        "-pix_fmt",
                        "yuv420p",
                        "-movflags",
                        "+faststart",
                        "-f",
                        "mp4",
                    ])
                    .arg(&tmp)
                    .stdin(Stdio::piped())
                    .stdout(Stdio::null())
                    .stderr(Stdio::piped())
                    .spawn()
                    .context("cannot start ffmpeg")?;
                let stdin = ffmpeg.stdin.take().context("ffmpeg has no input pipe")?;
                Sink::Mp4 {
                    ffmpeg,
                    stdin: BufWriter::new(stdin),
                }
            }
        };
        Ok(VideoWriter {
            sink: Some(sink),
            path,
            tmp,
            size: (width, height),
            fps,
            frames: 0,
        })
    }

    /// The file the video goes to (the GIF when an MP4 fell back to it).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Frames written so far.
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// Appends `frame`, shown `repeat` times (at least once).
    ///
    /// # Errors
    /// A frame of another size than the video's, a failed write.
    pub fn push(&mut self, frame: &Frame, repeat: usize) -> anyhow::Result<()> {
        if (frame.width(), frame.height()) != self.size {
            bail!(
                "frame of {}x{} in a video of {}x{}",
                frame.width(),
                frame.height(),
                self.size.0,
                self.size.1
            );
        }
        let repeat = repeat.max(1);
        match &mut self.sink {
            None => bail!("the video is finished"),
            Some(Sink::Gif(encoder)) => {
                // quantization speed 10 of 1..=30: good colours at a few ms per frame
                let mut gif_frame = gif::Frame::from_rgb_speed(
                    self.size.0 as u16,
                    self.size.1 as u16,
                    frame.rgb(),
                    10,
                );
                // GIF delays are in hundredths of a second
                gif_frame.delay = ((100 * repeat) as f64 / f64::from(self.fps)).round() as u16;
                encoder.write_frame(&gif_frame)?;
            }
            Some(Sink::Mp4 { stdin, .. }) => {
                for _ in 0..repeat {
                    stdin
                        .write_all(frame.rgb())
                        .context("ffmpeg stopped reading frames")?;
                }
            }
        }
        self.frames += repeat;
        Ok(())
    }

    /// Completes the video: flushes it, syncs it and renames it over the target. Returns the
    /// path and the number of frames.
    ///
    /// # Errors
    /// When no frame was written, the encoder failed, or the file cannot be synced or moved.
    pub fn finish(mut self) -> anyhow::Result<(PathBuf, usize)> {
        if self.frames == 0 {
            bail!("no frame to write to {}", self.path.display());
        }
        match self.sink.take() {
            None => bail!("the video is finished"),
            Some(Sink::Gif(encoder)) => {
                let writer = encoder.into_inner()?;
                let file = writer.into_inner().map_err(|e| e.into_error())?;
                file.sync_all()?;
            }
            Some(Sink::Mp4 { mut ffmpeg, stdin }) => {
                match stdin.into_inner() {
                    // closing the pipe ends ffmpeg's input
                    Ok(pipe) => drop(pipe),
                    Err(e) => {
                        let _ = ffmpeg.kill();
                        let _ = ffmpeg.wait();
                        return Err(e.into_error()).context("ffmpeg stopped reading frames");
                    }
                }
                let output = ffmpeg.wait_with_output().context("ffmpeg did not finish")?;
                if !output.status.success() {
                    bail!(
                        "ffmpeg failed ({}): {}",
                        output.status,
                        String::from_utf8_lossy(&output.stderr).trim()
                    );
                }
                atomic::sync_file(&self.tmp)?;
            }
        }
        std::fs::rename(&self.tmp, &self.path)
            .with_context(|| format!("cannot move the video to {}", self.path.display()))?;
        atomic::sync_dir(atomic::parent(&self.path))?;
        Ok((self.path.clone(), self.frames))
    }
}

impl Drop for VideoWriter {
    /// Removes the temporary file of an unfinished (or failed) video; stops its ffmpeg.
    fn drop(&mut self) {
        if let Some(Sink::Mp4 { mut ffmpeg, stdin }) = self.sink.take() {
            drop(stdin);
            let _ = ffmpeg.kill();
            let _ = ffmpeg.wait();
        }
        let _ = std::fs::remove_file(&self.tmp);
    }
}

/// Writes `lines` on `frame`, top left, white on a dark band, in a size that suits the
/// frame's height.
///
/// # Errors
/// When no font is installed (Debian's `fonts-dejavu-core`).
pub fn overlay(frame: &mut Frame, lines: &[String]) -> anyhow::Result<()> {
    crate::plot::load_font()?;
    let (width, height) = (frame.width(), frame.height());
    let size = (height / 22).clamp(9, 40);
    let root = BitMapBackend::with_buffer(frame.rgb_mut(), (width, height)).into_drawing_area();
    let band = (lines.len() as u32 * (size + 4) + 6).min(height) as i32;
    root.draw(&Rectangle::new(
        [(0, 0), (width as i32, band)],
        RGBColor(0, 0, 0).mix(0.55).filled(),
    ))
    .map_err(|e| anyhow::anyhow!("overlay: {e}"))?;
    let style = TextStyle::from(("sans-serif", size).into_font())
        .color(&WHITE)
        .pos(Pos::new(HPos::Left, VPos::Top));
    for (i, line) in lines.iter().enumerate() {
        let y = 4 + i as i32 * (size as i32 + 4);
        root.draw_text(line, &style, (6, y))
            .map_err(|e| anyhow::anyhow!("overlay: {e}"))?;
    }
    root.present()
        .map_err(|e| anyhow::anyhow!("overlay: {e}"))?;
    Ok(())
}

/// What `apo render` records, besides the run and the output file.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOptions {
    /// Episodes, each rendered after its reset and after each of its steps.
    pub episodes: usize,
    /// Act with the mean (Gaussian) or most likely (categorical) action.
    pub deterministic: bool,
    /// The seed of the episodes, as `apo eval --seed` takes it.
    pub seed: u64,
    /// The camera.
    pub camera: Camera,
    /// Frame width in pixels.
    pub width: u32,
    /// Frame height in pixels.
    pub height: u32,
    /// Frames per second of the video.
    pub fps: u32,
    /// Keep one step in `every` (1: every step).
    pub every: usize,
}

/// A recorded video.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendered {
    /// The video file (a GIF where an MP4 fell back to one).
    pub path: PathBuf,
    /// Frames in the video.
    pub frames: usize,
    /// The episodes' returns and lengths: those `apo eval` reports with the same seed.
    pub result: EvalResult,
    /// The checkpoint's epoch.
    pub epoch: usize,
}

/// Records `options.episodes` episodes of the policy in checkpoint `which` of `run_dir` to
/// the video `out`: the episodes [`crate::eval::evaluate`] runs with the same seed, a frame
/// after each reset and each `every`-th step, with the overlay of [`record`].
///
/// # Errors
/// Those of `evaluate`; an environment without a renderer or another render error (naming
/// the environment); an unusable output path.
pub fn render_run(
    run_dir: &Path,
    which: &Which,
    options: &RenderOptions,
    out: &Path,
    stop: &AtomicBool,
) -> anyhow::Result<Rendered> {
    let mut run = LoadedRun::load(run_dir, which)?;
    let (path, frames, result) = render_policy(
        run.env.as_mut(),
        &run.config.train.env,
        &mut run.policy,
        run.normalizer.as_ref(),
        options,
        out,
        stop,
    )?;
    Ok(Rendered {
        path,
        frames,
        result,
        epoch: run.epoch,
    })
}

/// Records `options.episodes` episodes of `policy` (held in memory) on `env` to the video
/// `out`: the episodes of [`crate::eval::play_episodes`] with `options.seed`, framed as by
/// [`render_run`]. `env_name` names the environment in errors. Returns the video's path,
/// its frames and the episodes' results.
///
/// # Errors
/// A render error (naming the environment), an unusable output path, `stop` raised (by
/// SIGINT or SIGTERM): the unfinished video's temporary file is removed.
pub fn render_policy(
    env: &mut dyn Env,
    env_name: &str,
    policy: &mut HostPolicy,
    normalizer: Option<&RunningMeanStd>,
    options: &RenderOptions,
    out: &Path,
    stop: &AtomicBool,
) -> anyhow::Result<(PathBuf, usize, EvalResult)> {
    let mut frame = Frame::new(options.width, options.height)?;
    let mut writer = VideoWriter::create(out, options.width, options.height, options.fps)?;
    let result = crate::eval::play_episodes(
        env,
        policy,
        normalizer,
        &Episodes {
            count: options.episodes,
            deterministic: options.deterministic,
            seed: options.seed,
        },
        &mut |env, moment| {
            if stop.load(Ordering::Relaxed) {
                bail!("interrupted: the unfinished video was not written");
            }
            record(env, moment, options, &mut frame, &mut writer)
                .with_context(|| format!("rendering {env_name}"))
        },
    )?;
    let (path, frames) = writer.finish()?;
    Ok((path, frames, result))
}

/// Renders `env` at `moment` into `frame` when the moment is kept (a reset, every
/// `options.every`-th step, an episode's end), writes the overlay (episode, step, reward,
/// return so far; the episode's return at its end, held for a second) and appends it to
/// `writer`.
///
/// # Errors
/// The environment's render errors, the overlay's and the writer's.
pub fn record(
    env: &mut dyn Env,
    moment: &Moment,
    options: &RenderOptions,
    frame: &mut Frame,
    writer: &mut VideoWriter,
) -> anyhow::Result<()> {
    if !(moment.done || moment.step.is_multiple_of(options.every.max(1))) {
        return Ok(());
    }
    env.render(&options.camera, frame)?;
    let mut lines = vec![
        format!("episode {}  step {}", moment.episode + 1, moment.step),
        format!("reward {:+.3}  return {:.2}", moment.reward, moment.ret),
    ];
    if moment.done {
        lines.push(format!("episode return {:.2}", moment.ret));
    }
    overlay(frame, &lines)?;
    let hold = if moment.done { options.fps as usize } else { 1 };
    writer.push(frame, hold)
}

/// The seed stream of a training run's videos (`apo_train::derive_seed`; the training and
/// evaluation streams are 0–5).
const VIDEO_STREAM: u64 = 6;

/// Frames of a training run's videos: small enough for TensorBoard, large enough to see.
const EPOCH_VIDEO_SIZE: (u32, u32) = (320, 240);

/// TensorBoard gets a video only up to this size (larger ones stay in `videos/` alone).
pub const TENSORBOARD_VIDEO_BYTES: u64 = 32 << 20;

/// The videos of a training run (`render_every = N`): every N epochs, one evaluation episode
/// of the current policy as `videos/epoch-<N>.gif` (320 × 240, every 4th step at 30 frames
/// per second, with the overlay of [`record`]).
///
/// The episode is played on its own environment (made as the run's, reset only by the video's
/// seeds) from the seed stream `derive_seed(run seed, 0, 6)`, the same start at every epoch,
/// with `eval_deterministic`'s actions; nothing of the training streams is touched, so a run
/// trains exactly as without videos.
pub struct EpochVideos {
    env: Box<dyn Env>,
    env_name: String,
    every: usize,
    dir: PathBuf,
    options: RenderOptions,
}

impl EpochVideos {
    /// The videos of `config`'s run in `run_dir`, or `None` with `render_every = 0`. Renders
    /// one frame of the environment first, so that a run whose environment cannot be rendered
    /// (no renderer, no headless OpenGL) stops before its first epoch.
    ///
    /// # Errors
    /// The environment cannot be made or rendered (naming it and why).
    pub fn new(config: &RunConfig, run_dir: &Path) -> anyhow::Result<Option<EpochVideos>> {
        if config.render_every == 0 {
            return Ok(None);
        }
        let env_name = config.train.env.clone();
        let options = apo_envs::MakeOptions {
            fixed_reset_seed: None,
            ..config.train.make_options()
        };
        let mut env = apo_envs::make_with(&env_name, &options)?;
        let (width, height) = EPOCH_VIDEO_SIZE;
        let options = RenderOptions {
            episodes: 1,
            deterministic: config.train.eval_deterministic,
            seed: apo_train::derive_seed(config.train.seed, 0, VIDEO_STREAM),
            camera: Camera::Track,
            width,
            height,
            fps: 30,
            every: 4,
        };
        let mut frame = Frame::new(width, height)?;
        let mut obs = vec![0.0; env.observation_space().flat_dim()];
        env.reset(Some(options.seed), &mut obs);
        env.render(&options.camera, &mut frame).with_context(|| {
            format!(
                "render_every = {}: cannot render {env_name}",
                config.render_every
            )
        })?;
        Ok(Some(EpochVideos {
            env,
            env_name,
            every: config.render_every,
            dir: run_dir.join(VIDEOS),
            options,
        }))
    }

    /// Whether epoch `epoch` (from 1) gets a video.
    pub fn due(&self, epoch: usize) -> bool {
        epoch.is_multiple_of(self.every)
    }

    /// Records epoch `epoch`'s video of `policy` (observations normalized by `normalizer`)
    /// into `videos/epoch-<epoch>.gif`. Returns its path, its frame size and the episode.
    ///
    /// # Errors
    /// Rendering or writing failed, or `stop` was raised.
    pub fn record(
        &mut self,
        epoch: usize,
        policy: &mut HostPolicy,
        normalizer: Option<&RunningMeanStd>,
        stop: &AtomicBool,
    ) -> anyhow::Result<(PathBuf, (u32, u32), EvalResult)> {
        std::fs::create_dir_all(&self.dir)
            .with_context(|| format!("cannot create {}", self.dir.display()))?;
        let out = self.dir.join(format!("epoch-{epoch}.gif"));
        let (path, _, result) = render_policy(
            self.env.as_mut(),
            &self.env_name,
            policy,
            normalizer,
            &self.options,
            &out,
            stop,
        )?;
        Ok((path, (self.options.width, self.options.height), result))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use apo_core::{ActionKind, MlpPolicyConfig, PolicyFamily};
    use apo_envs::{Action, Space, Transition};
    use burn::backend::NdArray;

    /// An environment of its own, without a renderer.
    struct Blind {
        observation: Space,
        action: Space,
    }

    impl Env for Blind {
        fn observation_space(&self) -> &Space {
            &self.observation
        }
        fn action_space(&self) -> &Space {
            &self.action
        }
        fn reset(&mut self, _seed: Option<u64>, obs: &mut [f32]) {
            obs.fill(0.0);
        }
        fn step(&mut self, _action: Action<'_>, obs: &mut [f32]) -> Transition {
            obs.fill(0.0);
            Transition {
                reward: 1.0,
                terminated: true,
                truncated: false,
                info: Default::default(),
            }
        }
    }

    fn options() -> RenderOptions {
        RenderOptions {
            episodes: 1,
            deterministic: true,
            seed: 0,
            camera: Camera::Track,
            width: 32,
            height: 24,
            fps: 10,
            every: 1,
        }
    }

    #[test]
    fn an_environment_without_a_renderer_is_named_and_leaves_no_file() {
        let dir = tempfile::tempdir().expect("tempdir");
        let mut env = Blind {
            observation: Space::uniform_box(3, -1.0, 1.0),
            action: Space::Discrete { n: 2 },
        };
        let policy = MlpPolicyConfig::new(3, ActionKind::Discrete { n: 2 })
            .init::<NdArray>(&Default::default());
        let mut policy = HostPolicy::new(&policy, ActionKind::Discrete { n: 2 });
        let out = dir.path().join("blind.gif");
        let error = render_policy(
            &mut env,
            "Blind-v0",
            &mut policy,
            None,
            &options(),
            &out,
            &AtomicBool::new(false),
        )
        .expect_err("no renderer");
        let message = format!("{error:#}");
        assert!(
            message.contains("rendering Blind-v0") && message.contains("no renderer"),
            "{message}"
        );
        let left: Vec<_> = std::fs::read_dir(dir.path()).expect("dir").collect();
        assert!(left.is_empty(), "{left:?}");
    }

    #[test]
    fn frames_of_another_size_and_empty_videos_are_refused() {
        let dir = tempfile::tempdir().expect("tempdir");
        let out = dir.path().join("v.gif");
        let mut writer = VideoWriter::create(&out, 8, 6, 10).expect("writer");
        let wrong = Frame::new(6, 8).expect("frame");
        assert!(writer.push(&wrong, 1).is_err());
        assert!(writer.finish().is_err(), "a video without frames");
        assert!(!out.exists());
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 0);
        // a finished one: its frames, its size
        let mut writer = VideoWriter::create(&out, 8, 6, 10).expect("writer");
        let frame = Frame::new(8, 6).expect("frame");
        writer.push(&frame, 1).expect("push");
        writer.push(&frame, 3).expect("push");
        let (path, frames) = writer.finish().expect("finish");
        assert_eq!((path, frames), (out.clone(), 4));
        assert!(std::fs::read(&out).expect("gif").starts_with(b"GIF89a"));
        assert!(Format::of(Path::new("x.webm")).is_err());
        assert_eq!(Format::of(Path::new("x.MP4")).ok(), Some(Format::Mp4));
    }
}
