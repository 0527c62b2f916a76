//! Videos of rendered frames: GIF (the `gif` crate) or MP4 (the `ffmpeg` program, which an
//! `.mp4` needs), chosen by the file's extension, written to a temporary file beside the
//! target and renamed over it when complete; and the text overlay of `apo render`.

use std::io::{BufWriter, Read, Write};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc, Mutex, OnceLock};
use std::time::{Duration, Instant};

use anyhow::{bail, Context};
use apo_core::inference::HostPolicy;
use apo_envs::{Camera, Env, Frame, RunningMeanStd};
use plotters::backend::BitMapBackend;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};

use crate::atomic;
use crate::checkpoint::Which;
use crate::playback::{Episodes, EvalResult, LoadedRun, Moment};
use crate::run_config::RunConfig;
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

/// How long `ffmpeg` may take to accept a frame, or to finish once its input is closed, before
/// apo stops it and reports it (a child that stops reading would otherwise hold `apo render`
/// forever).
pub const FFMPEG_TIMEOUT: Duration = Duration::from_secs(20);

/// Frames handed to `ffmpeg`'s writer thread and not yet written: bounds the memory held.
const FRAMES_IN_FLIGHT: usize = 8;

/// The last bytes of `ffmpeg`'s stderr kept for an error message.
const STDERR_KEPT: usize = 4096;

/// Checks that `ffmpeg` runs on this machine (`ffmpeg -version` exits with 0).
///
/// # Errors
/// `ffmpeg` is not on the PATH (with how to install it, and that a `.gif` needs nothing), it
/// cannot be started (the OS's error), or it exits with a failure (its status and stderr).
pub fn check_ffmpeg() -> anyhow::Result<()> {
    let mut child = match Command::new("ffmpeg")
        .arg("-version")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
    {
        Ok(child) => child,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => bail!(
            "an .mp4 needs ffmpeg, which is not on the PATH (Debian: apt-get install ffmpeg); \
             or name a .gif, which needs nothing"
        ),
        Err(e) => return Err(e).context("cannot start ffmpeg"),
    };
    let stderr = read_in_background(child.stderr.take());
    let deadline = Instant::now() + FFMPEG_TIMEOUT;
    let status = loop {
        match child.try_wait().context("cannot wait for ffmpeg")? {
            Some(status) => break status,
            None if Instant::now() < deadline => std::thread::sleep(Duration::from_millis(20)),
            None => {
                let _ = child.kill();
                let _ = child.wait();
                bail!(
                    "`ffmpeg -version` did not answer within {} s; it was stopped",
                    FFMPEG_TIMEOUT.as_secs()
                );
            }
        }
    };
    if !status.success() {
        bail!(
            "`ffmpeg -version` failed ({status}): {}",
            kept_tail(&stderr)
        );
    }
    Ok(())
}

/// The end of a child's output, kept by a thread that reads it to its end, and whether it has
/// ended.
type Kept = Arc<(Mutex<Vec<u8>>, AtomicBool)>;

/// Reads `pipe` to its end on a thread of its own (never joined: a pipe held open by a
/// grandchild cannot hold apo), keeping the last [`STDERR_KEPT`] bytes.
fn read_in_background(pipe: Option<std::process::ChildStderr>) -> Kept {
    let kept: Kept = Arc::new((Mutex::new(Vec::new()), AtomicBool::new(false)));
    let shared = Arc::clone(&kept);
    std::thread::spawn(move || {
        if let Some(mut pipe) = pipe {
            let mut chunk = [0u8; 4096];
            while let Ok(n) = pipe.read(&mut chunk) {
                if n == 0 {
                    break;
                }
                if let Ok(mut kept) = shared.0.lock() {
                    kept.extend_from_slice(&chunk[..n]);
                    let excess = kept.len().saturating_sub(STDERR_KEPT);
                    kept.drain(..excess);
                }
            }
        }
        shared.1.store(true, Ordering::Release);
    });
    kept
}

/// The kept end of a child's output, once it has ended (waiting at most a second after the
/// child's exit for the last of it).
fn kept_tail(kept: &Kept) -> String {
    let deadline = Instant::now() + Duration::from_secs(1);
    while !kept.1.load(Ordering::Acquire) && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(10));
    }
    kept.0.lock().map(|k| tail(&k)).unwrap_or_default()
}

/// The last [`STDERR_KEPT`] bytes of a child's stderr, as text.
fn tail(stderr: &[u8]) -> String {
    let start = stderr.len().saturating_sub(STDERR_KEPT);
    let text = String::from_utf8_lossy(&stderr[start..]).trim().to_string();
    if text.is_empty() {
        "(nothing on stderr)".to_string()
    } else {
        text
    }
}

/// An `ffmpeg` encoding frames written to its stdin by a thread of ours, so that a child that
/// stops reading is noticed ([`FFMPEG_TIMEOUT`]) instead of blocking apo; its stderr is read by
/// another thread (the last [`STDERR_KEPT`] bytes are kept for the error). Neither thread is
/// ever joined: a pipe held open by a grandchild of a stopped `ffmpeg` cannot hold apo.
struct Ffmpeg {
    child: Child,
    /// `None` once the input is closed.
    frames: Option<mpsc::Sender<Arc<Vec<u8>>>>,
    /// One result per frame written by the writer thread.
    written: mpsc::Receiver<std::io::Result<()>>,
    in_flight: usize,
    /// The end of ffmpeg's stderr so far, and whether it has ended.
    stderr: Kept,
    /// Whether the child has been waited for.
    reaped: bool,
}

impl Ffmpeg {
    /// Starts ffmpeg encoding into `tmp` (after [`check_ffmpeg`]).
    fn spawn(tmp: &Path, width: u32, height: u32, fps: u32) -> anyhow::Result<Ffmpeg> {
        let mut command = Command::new("ffmpeg");
        command
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
            .arg(tmp)
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        #[cfg(target_os = "linux")]
        {
            use std::os::unix::process::CommandExt;
            // SAFETY: prctl is async-signal-safe; it only sets the child's parent-death signal:
            // an apo that exits at once (a second signal) takes its ffmpeg with it
            unsafe {
                command.pre_exec(|| {
                    if libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL) == -1 {
                        return Err(std::io::Error::last_os_error());
                    }
                    Ok(())
                });
            }
        }
        let mut child = command.spawn().context("cannot start ffmpeg")?;
        let (Some(mut stdin), Some(err)) = (child.stdin.take(), child.stderr.take()) else {
            let _ = child.kill();
            let _ = child.wait();
            bail!("ffmpeg started without its pipes");
        };
        let (frames, inbox) = mpsc::channel::<Arc<Vec<u8>>>();
        let (done, written) = mpsc::channel();
        std::thread::spawn(move || {
            for frame in inbox {
                let result = stdin.write_all(&frame);
                let failed = result.is_err();
                if done.send(result).is_err() || failed {
                    break;
                }
            }
            // dropping stdin closes ffmpeg's input
        });
        let stderr = read_in_background(Some(err));
        Ok(Ffmpeg {
            child,
            frames: Some(frames),
            written,
            in_flight: 0,
            stderr,
            reaped: false,
        })
    }

    /// Hands `frame` to the writer `repeat` times; waits while more than [`FRAMES_IN_FLIGHT`]
    /// are unwritten.
    fn push(&mut self, frame: &[u8], repeat: usize) -> anyhow::Result<()> {
        let frame = Arc::new(frame.to_vec());
        for _ in 0..repeat {
            let sent = self
                .frames
                .as_ref()
                .is_some_and(|f| f.send(Arc::clone(&frame)).is_ok());
            if !sent {
                return Err(self.stopped("ffmpeg stopped reading frames"));
            }
            self.in_flight += 1;
            self.wait_written(FRAMES_IN_FLIGHT)?;
        }
        Ok(())
    }

    /// Waits until at most `limit` frames are unwritten.
    fn wait_written(&mut self, limit: usize) -> anyhow::Result<()> {
        while self.in_flight > limit {
            match self.written.recv_timeout(FFMPEG_TIMEOUT) {
                Ok(Ok(())) => self.in_flight -= 1,
                Ok(Err(e)) => {
                    return Err(self.stopped(&format!("ffmpeg stopped reading frames ({e})")))
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    return Err(self.stopped(&format!(
                        "ffmpeg read no frame for {} s",
                        FFMPEG_TIMEOUT.as_secs()
                    )))
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => {
                    return Err(self.stopped("ffmpeg stopped reading frames"))
                }
            }
        }
        Ok(())
    }

    /// The end of ffmpeg's stderr, once it has ended.
    fn stderr_tail(&self) -> String {
        kept_tail(&self.stderr)
    }

    /// Stops ffmpeg; the error says `what` happened, how ffmpeg exited and what it wrote on
    /// stderr.
    fn stopped(&mut self, what: &str) -> anyhow::Error {
        self.frames = None;
        let _ = self.child.kill();
        let status = self.child.wait();
        self.reaped = true;
        match status {
            Ok(status) => {
                anyhow::anyhow!("{what}; it was stopped ({status}): {}", self.stderr_tail())
            }
            Err(e) => anyhow::anyhow!("{what}; it was stopped: {e}"),
        }
    }

    /// Waits for every frame to be written, closes the input and waits (at most
    /// [`FFMPEG_TIMEOUT`]) for ffmpeg to finish the file.
    fn finish(mut self) -> anyhow::Result<()> {
        self.wait_written(0)?;
        // the writer thread ends and drops ffmpeg's stdin: its input ends
        self.frames = None;
        let deadline = Instant::now() + FFMPEG_TIMEOUT;
        let status = loop {
            match self.child.try_wait() {
                Ok(Some(status)) => break status,
                Ok(None) if Instant::now() < deadline => {
                    std::thread::sleep(Duration::from_millis(20));
                }
                Ok(None) => {
                    return Err(self.stopped(&format!(
                        "ffmpeg did not finish the video within {} s of its last frame",
                        FFMPEG_TIMEOUT.as_secs()
                    )))
                }
                Err(e) => return Err(self.stopped(&format!("cannot wait for ffmpeg: {e}"))),
            }
        };
        self.reaped = true;
        if !status.success() {
            bail!("ffmpeg failed ({status}): {}", self.stderr_tail());
        }
        Ok(())
    }
}

impl Drop for Ffmpeg {
    /// Stops an unfinished ffmpeg (an error, a signal).
    fn drop(&mut self) {
        self.frames = None;
        if !self.reaped {
            let _ = self.child.kill();
            let _ = self.child.wait();
        }
    }
}

enum Sink {
    Gif(gif::Encoder<BufWriter<std::fs::File>>),
    Mp4(Ffmpeg),
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
    /// How the finished video takes its place (`--force` replaces a plain file).
    place: atomic::Place,
    size: (u32, u32),
    fps: u32,
    frames: usize,
}

impl VideoWriter {
    /// Starts a video of `width × height` frames at `fps` frames per second at `path`, in the
    /// format of its extension, written to a temporary file of a unique name beside it. An
    /// existing file at `path` is replaced (when the video is finished) only with `replace`
    /// (`--force`), by the output rule of [`crate::input::check_output_file`], checked again
    /// as the video takes its place ([`atomic::place`]): a file or link that appears there
    /// meanwhile stays.
    ///
    /// # Errors
    /// An unknown extension, an existing file without `replace`, an MP4 without a working
    /// `ffmpeg` ([`check_ffmpeg`]), a size a GIF cannot hold, an unwritable folder.
    pub fn create(
        path: &Path,
        width: u32,
        height: u32,
        fps: u32,
        replace: bool,
    ) -> anyhow::Result<VideoWriter> {
        let format = Format::of(path)?;
        crate::input::check_output_file(path, "--out", replace)?;
        let name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        let fps = fps.clamp(1, 100);
        let (w, h) = (u16::try_from(width), u16::try_from(height));
        let (Ok(w), Ok(h)) = (w, h) else {
            bail!("a video's sides are at most 65535 pixels, not {width}x{height}");
        };
        if format == Format::Mp4 {
            // before any file is made
            check_ffmpeg()?;
        }
        let (tmp, file) = atomic::create_temp(atomic::parent(path), &name).with_context(|| {
            format!("cannot create a file in {}", atomic::parent(path).display())
        })?;
        // from here on, an error removes the temporary file (the writer's Drop)
        let mut writer = VideoWriter {
            sink: None,
            path: path.to_path_buf(),
            tmp,
            place: if replace {
                atomic::Place::ReplacePlainFile
            } else {
                atomic::Place::New
            },
            size: (width, height),
            fps,
            frames: 0,
        };
        writer.sink = Some(match format {
            Format::Gif => {
                let mut encoder = gif::Encoder::new(BufWriter::new(file), w, h, &[])
                    .with_context(|| format!("cannot write {}", writer.tmp.display()))?;
                encoder.set_repeat(gif::Repeat::Infinite)?;
                Sink::Gif(encoder)
            }
            Format::Mp4 => {
                drop(file);
                Sink::Mp4(Ffmpeg::spawn(&writer.tmp, width, height, fps)?)
            }
        });
        Ok(writer)
    }

    /// The file the video goes to.
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
    /// A frame of another size than the video's, a failed write, an `ffmpeg` that stopped
    /// reading (within [`FFMPEG_TIMEOUT`]).
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
                gif_frame.delay = ((100 * repeat) as f64 / f64::from(self.fps))
                    .round()
                    .min(f64::from(u16::MAX)) as u16;
                encoder
                    .write_frame(&gif_frame)
                    .with_context(|| format!("cannot write {}", self.tmp.display()))?;
            }
            Some(Sink::Mp4(ffmpeg)) => ffmpeg.push(frame.rgb(), repeat)?,
        }
        self.frames += repeat;
        Ok(())
    }

    /// Completes the video: flushes it, syncs it and renames it over the target. Returns the
    /// path and the number of frames.
    ///
    /// # Errors
    /// When no frame was written, the encoder failed (for `ffmpeg`: its exit status and
    /// stderr), or the file cannot be synced or moved.
    pub fn finish(mut self) -> anyhow::Result<(PathBuf, usize)> {
        if self.frames == 0 {
            bail!("no frame to write to {}", self.path.display());
        }
        match self.sink.take() {
            None => bail!("the video is finished"),
            Some(Sink::Gif(encoder)) => {
                let writer = encoder
                    .into_inner()
                    .with_context(|| format!("cannot write {}", self.tmp.display()))?;
                let file = writer
                    .into_inner()
                    .map_err(|e| e.into_error())
                    .with_context(|| format!("cannot write {}", self.tmp.display()))?;
                file.sync_all()
                    .with_context(|| format!("cannot write {}", self.tmp.display()))?;
            }
            Some(Sink::Mp4(ffmpeg)) => {
                ffmpeg.finish()?;
                let written = std::fs::metadata(&self.tmp).map_or(0, |m| m.len());
                if written == 0 {
                    bail!(
                        "ffmpeg exited with success but wrote nothing to {} ({} frames given); the video was not written",
                        self.tmp.display(),
                        self.frames
                    );
                }
                atomic::sync_file(&self.tmp)
                    .with_context(|| format!("cannot sync {}", self.tmp.display()))?;
            }
        }
        atomic::place(&self.tmp, &self.path, self.place)
            .with_context(|| format!("cannot move the video to {}", self.path.display()))?;
        atomic::sync_dir(atomic::parent(&self.path))?;
        Ok((self.path.clone(), self.frames))
    }
}

impl Drop for VideoWriter {
    /// Removes the temporary file of an unfinished (or failed) video; stops its ffmpeg.
    fn drop(&mut self) {
        drop(self.sink.take());
        let _ = std::fs::remove_file(&self.tmp);
    }
}

/// Writes `lines` on `frame`, top left, white on a dark band, in a size that suits the
/// frame's height.
///
/// # Errors
/// When no font is installed (Debian's `fonts-dejavu-core`).
pub fn overlay(frame: &mut Frame, lines: &[String]) -> anyhow::Result<()> {
    crate::video::load_font()?;
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
    /// Whether an existing file at the output is replaced (`--force`; apo's own videos in a
    /// run's `videos/`).
    pub replace: bool,
}

/// A recorded video.
#[derive(Debug, Clone, PartialEq)]
pub struct Rendered {
    /// The video file.
    pub path: PathBuf,
    /// Frames in the video.
    pub frames: usize,
    /// The episodes' returns and lengths: those `apo eval` reports with the same seed.
    pub result: EvalResult,
    /// The checkpoint's epoch.
    pub epoch: usize,
}

/// Records `options.episodes` episodes of the policy in checkpoint `which` of `run_dir` to
/// the video `out`: the episodes [`crate::playback::evaluate`] runs with the same seed, a frame
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
/// `out`: the episodes of [`crate::playback::play_episodes`] with `options.seed`, framed as by
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
    let mut writer = VideoWriter::create(
        out,
        options.width,
        options.height,
        options.fps,
        options.replace,
    )?;
    let result = crate::playback::play_episodes(
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

/// The seed stream of a training run's videos (`crate::derive_seed`; the training and
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
            seed: crate::derive_seed(config.train.seed, 0, VIDEO_STREAM),
            camera: Camera::Track,
            width,
            height,
            fps: 30,
            every: 4,
            // an existing epoch-<N>.gif is moved aside first (`record`)
            replace: false,
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
        if std::fs::symlink_metadata(&out).is_ok() {
            // a file of that name (the user's, or apo's from before an interrupt) is moved
            // aside, never replaced
            // the first free name, taken without replacing one that appears meanwhile
            let mut aside = None;
            for n in 1..=10_000 {
                let name = self.dir.join(format!("epoch-{epoch}.gif.kept-{n}"));
                match atomic::rename_no_replace(&out, &name) {
                    Ok(()) => {
                        aside = Some(name);
                        break;
                    }
                    Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
                    Err(e) => {
                        return Err(e)
                            .with_context(|| format!("cannot move {} aside", out.display()))
                    }
                }
            }
            let aside = aside.context("no free name to move a video aside")?;
            crate::warnln!(
                "warning: {} existed; it was moved to {} before the epoch's video was written",
                out.display(),
                aside.display()
            );
        }
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

/// Where the font for the text of plots and videos is looked for (Debian's `fonts-dejavu-core`).
const FONT_PATHS: &[&str] = &[
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
];

/// Registers the system's sans-serif font (Debian's `fonts-dejavu-core`) with plotters,
/// once per process: the text drawn on video frames and on apo-cli's plots.
///
/// # Errors
/// When no font is installed or it cannot be read.
pub fn load_font() -> anyhow::Result<()> {
    static LOADED: OnceLock<Result<(), String>> = OnceLock::new();
    let register = || -> anyhow::Result<()> {
        let path = FONT_PATHS.iter().map(PathBuf::from).find(|p| p.exists()).context(
            "no font for the text of plots and videos: install Debian's fonts-dejavu-core (apt-get install fonts-dejavu-core)",
        )?;
        let bytes =
            std::fs::read(&path).with_context(|| format!("cannot read {}", path.display()))?;
        let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
        register_font("sans-serif", FontStyle::Normal, bytes)
            .map_err(|_| anyhow::anyhow!("{} is not a usable font", path.display()))
    };
    LOADED
        .get_or_init(|| register().map_err(|e| format!("{e:#}")))
        .clone()
        .map_err(anyhow::Error::msg)
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
            replace: false,
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
        let mut writer = VideoWriter::create(&out, 8, 6, 10, false).expect("writer");
        let wrong = Frame::new(6, 8).expect("frame");
        assert!(writer.push(&wrong, 1).is_err());
        assert!(writer.finish().is_err(), "a video without frames");
        assert!(!out.exists());
        assert_eq!(std::fs::read_dir(dir.path()).expect("dir").count(), 0);
        // a finished one: its frames, its size
        let mut writer = VideoWriter::create(&out, 8, 6, 10, false).expect("writer");
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
