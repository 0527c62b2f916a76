//! `apo render`: a video of a run's policy.

use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::atomic::Ordering;

use apo_envs::Camera;
use apo_train::checkpoint::Which;
use apo_train::run_dir::VIDEOS;
use apo_train::video::{render_run, RenderOptions};

use crate::signals::{interrupted_status, Signals};

#[derive(clap::Args)]
pub struct RenderArgs {
    /// The run directory.
    #[arg(long)]
    run: PathBuf,
    /// Which checkpoint: `latest`, `best` (the best evaluation of a run with eval_every), or an
    /// epoch kept by keep_checkpoint_every.
    #[arg(long, default_value = "latest")]
    checkpoint: Which,
    /// Number of episodes; 1..=1000.
    #[arg(long, default_value_t = 2, value_parser = apo_cli::flags::count::<u64>(1, 1000))]
    episodes: u64,
    /// Act with the mean (Gaussian) or most likely (categorical) action.
    #[arg(long)]
    deterministic: bool,
    /// Seed of the episodes: the same seed plays the same episodes as `apo eval --seed`; 0..=18446744073709551615.
    #[arg(long, default_value_t = 12345, value_parser = apo_cli::flags::count::<u64>(0, u64::MAX))]
    seed: u64,
    /// The video: `.gif`, or `.mp4` (needs ffmpeg). Default: <run>/videos/render.gif (apo's
    /// own file in the run, replaced by each render).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Replace the file named by --out if it exists.
    #[arg(long)]
    force: bool,
    /// Frame width in pixels; 16..=4096.
    #[arg(long, default_value_t = 480, value_parser = apo_cli::flags::count::<u32>(16, 4096))]
    width: u32,
    /// Frame height in pixels; 16..=4096.
    #[arg(long, default_value_t = 360, value_parser = apo_cli::flags::count::<u32>(16, 4096))]
    height: u32,
    /// The camera: `track` (follows the robot), `free` (MuJoCo's default view) or the name of
    /// a camera of the model.
    #[arg(long, default_value = "track")]
    camera: Camera,
    /// Frames per second of the video; 1..=100.
    #[arg(long, default_value_t = 30, value_parser = apo_cli::flags::count::<u32>(1, 100))]
    fps: u32,
    /// Keep one step in N (shorter videos of long episodes); 1..=10000.
    #[arg(long, default_value_t = 1, value_parser = apo_cli::flags::count::<u64>(1, 10_000))]
    every: u64,
}

/// Records the video; SIGINT or SIGTERM stops it, removing the unfinished file, with the
/// signal's exit status.
pub fn run(args: &RenderArgs) -> anyhow::Result<ExitCode> {
    let signals = Signals::install()?;
    let (out, replace) = match &args.out {
        Some(out) => (out.clone(), args.force),
        None => {
            // only in a run apo made (a folder with just a config.toml gets nothing written),
            // and only in a `videos/` apo made (listed in the run's marker)
            let dir = if apo_train::run_dir::check_resumable(&args.run).is_ok() {
                apo_train::run_dir::own_videos(&args.run)?
            } else {
                args.run.join(VIDEOS)
            };
            // apo's own video, replaced by each render; a link or special file there is the user's
            let gif = dir.join("render.gif");
            if let Some(kind) = apo_train::atomic::not_plain(&gif) {
                anyhow::bail!(
                    "{} is {kind}, not a video apo wrote; apo does not replace it: move it away, or give \
                     `apo render` an --out",
                    gif.display()
                );
            }
            (gif, true)
        }
    };
    let options = RenderOptions {
        episodes: args.episodes as usize,
        deterministic: args.deterministic,
        seed: args.seed,
        camera: args.camera.clone(),
        width: args.width,
        height: args.height,
        fps: args.fps,
        every: args.every as usize,
        replace,
    };
    let rendered = match render_run(&args.run, &args.checkpoint, &options, &out, &signals.stop) {
        Ok(rendered) => rendered,
        Err(e) if signals.stop.load(Ordering::Relaxed) => {
            apo_train::warnln!("{e:#}");
            return Ok(ExitCode::from(interrupted_status(
                signals.which.load(Ordering::Relaxed),
            )));
        }
        Err(e) => return Err(e),
    };
    let returns: Vec<String> = rendered
        .result
        .returns
        .iter()
        .map(|r| format!("{r:.3}"))
        .collect();
    apo_cli::outln!(
        "checkpoint_epoch={} episodes={} returns={} frames={} video={}",
        rendered.epoch,
        rendered.result.returns.len(),
        returns.join(","),
        rendered.frames,
        rendered.path.display()
    )?;
    Ok(ExitCode::SUCCESS)
}
