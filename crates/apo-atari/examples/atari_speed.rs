//! Emulator speed on one core: frames per second of the bare emulator loop (`Emulator::act`,
//! one frame per call, sticky actions on) and of `ALE/<Game>-v5` steps (4 frames, the RAM
//! copied into the observation every step), for the games given (default Pong and Breakout).
//!
//!     cargo run --release -p apo-atari --example atari_speed -- [FRAMES] [LOOP] [GAME ...]
//!
//! LOOP: `emulator`, `v5` or `both` (default), or `threads:N`: the emulator loop on N threads
//! at once, each with its own emulator and FRAMES frames (the total rate is printed). Actions cycle through the minimal set
//! (`t mod n`); a game over resets the game. The figure to compare with is
//! `python3 scripts/ale_py_speed.py` (the ALE's C++ `act` from ale-py, the same loop).
use std::time::Instant;

use apo_atari::{Emulator, RAM_SIZE};
use apo_envs::{Action, Env};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let frames: usize = match args.next() {
        Some(n) => n.parse().map_err(|e| format!("FRAMES `{n}`: {e}"))?,
        None => 200_000,
    };
    let which = args.next().unwrap_or_else(|| "both".into());
    if let Some(n) = which.strip_prefix("threads:") {
        let threads: usize = n.parse().map_err(|e| format!("LOOP `{which}`: {e}"))?;
        let game = args.next().unwrap_or_else(|| "Pong".into());
        return threaded(frames, threads, &game);
    }
    let (emulator_loop, v5_loop) = match which.as_str() {
        "emulator" => (true, false),
        "v5" => (false, true),
        "both" => (true, true),
        other => return Err(format!("LOOP `{other}`: emulator, v5 or both").into()),
    };
    let mut games: Vec<String> = args.collect();
    if games.is_empty() {
        games = vec!["Pong".into(), "Breakout".into()];
    }
    apo_atari::register_games()?;
    println!("game,loop,frames,seconds,frames_per_s");
    for game in &games {
        let info =
            apo_atari::find(game).ok_or_else(|| format!("`{game}` is not one of the 62 games"))?;
        // the bare emulator: one frame per call
        let rom = apo_atari::rom_dir().join(apo_atari::rom_file(info.name));
        let mut emulator = Emulator::new(
            &rom,
            apo_atari::ale_seed(0),
            apo_atari::REPEAT_ACTION_PROBABILITY,
            apo_atari::MAX_FRAMES,
        )?;
        emulator.reset(Some(apo_atari::ale_seed(0)))?;
        let n = emulator.num_actions();
        if emulator_loop {
            let start = Instant::now();
            for t in 0..frames {
                emulator.act(t % n)?;
                if emulator.game_over() || emulator.truncated() {
                    emulator.reset(None)?;
                }
            }
            report(game, "emulator", frames, start.elapsed().as_secs_f64());
        }
        if !v5_loop {
            continue;
        }

        // v5 steps through the registry (TimeLimit and all), RAM observations
        let mut env = apo_envs::make(&format!("ALE/{}-v5", info.name))?;
        let mut obs = [0.0f32; RAM_SIZE];
        env.reset(Some(0), &mut obs);
        let steps = frames / apo_atari::FRAMESKIP;
        let start = Instant::now();
        for t in 0..steps {
            let out = env.step(Action::Discrete(t % n), &mut obs);
            if out.terminated || out.truncated {
                env.reset(None, &mut obs);
            }
        }
        report(
            game,
            "v5 step",
            steps * apo_atari::FRAMESKIP,
            start.elapsed().as_secs_f64(),
        );
    }
    Ok(())
}

/// The emulator loop of `game` on `threads` threads at once.
fn threaded(frames: usize, threads: usize, game: &str) -> Result<(), Box<dyn std::error::Error>> {
    let info =
        apo_atari::find(game).ok_or_else(|| format!("`{game}` is not one of the 62 games"))?;
    let rom = apo_atari::rom_dir().join(apo_atari::rom_file(info.name));
    let mut emulators = (0..threads)
        .map(|i| {
            Emulator::new(
                &rom,
                apo_atari::ale_seed(i as u64),
                apo_atari::REPEAT_ACTION_PROBABILITY,
                apo_atari::MAX_FRAMES,
            )
        })
        .collect::<Result<Vec<_>, _>>()?;
    println!("game,loop,frames,seconds,frames_per_s");
    let start = Instant::now();
    std::thread::scope(|scope| {
        for emulator in &mut emulators {
            scope.spawn(move || {
                let n = emulator.num_actions();
                for t in 0..frames {
                    let _ = emulator.act(t % n);
                    if emulator.game_over() || emulator.truncated() {
                        let _ = emulator.reset(None);
                    }
                }
            });
        }
    });
    report(
        game,
        &format!("emulator, {threads} threads"),
        frames * threads,
        start.elapsed().as_secs_f64(),
    );
    Ok(())
}

fn report(game: &str, what: &str, frames: usize, seconds: f64) {
    println!(
        "{game},{what},{frames},{seconds:.3},{:.0}",
        frames as f64 / seconds
    );
}
