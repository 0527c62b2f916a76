//! # apo-atari (GPL-2.0, opt-in)
//!
//! Atari 2600 games through the Arcade Learning Environment (ALE 0.12.1, compiled from the
//! `ale-py` source archive by `build.rs`): the emulator ([`Emulator`]), Gymnasium's
//! `ALE/<Game>-v5` with RAM observations ([`AtariEnv`]) and the paper's 62 games
//! ([`GAMES`], registered with apo-envs by [`register_games`]).
//!
//! ```no_run
//! apo_atari::register_games()?;
//! let mut env = apo_envs::make("ALE/Pong-v5")?;
//! let mut ram = [0.0f32; apo_atari::RAM_SIZE];
//! env.reset(Some(7), &mut ram);
//! let step = env.step(apo_envs::Action::Discrete(1), &mut ram);
//! # let _ = step;
//! # Ok::<(), apo_envs::EnvError>(())
//! ```

mod env;
mod games;
mod seed;

pub use env::{AtariEnv, FRAMESKIP, MAX_FRAMES, RAM_SIZE, REPEAT_ACTION_PROBABILITY};
pub use games::{find, register_games, rom_dir, rom_file, Game, GAMES};
pub use seed::ale_seed;

use std::ffi::{c_char, c_int, c_void, CStr, CString};
use std::path::{Path, PathBuf};

mod ffi {
    use super::*;
    extern "C" {
        pub fn ale_last_error() -> *const c_char;
        pub fn ale_new(
            rom: *const c_char,
            seed: c_int,
            repeat: f32,
            max_frames: c_int,
        ) -> *mut c_void;
        pub fn ale_delete(a: *mut c_void);
        pub fn ale_rom_name(rom: *const c_char, out: *mut c_char, cap: c_int) -> c_int;
        pub fn ale_minimal_actions(a: *mut c_void, out: *mut c_int, capacity: c_int) -> c_int;
        pub fn ale_act(a: *mut c_void, action: c_int, reward: *mut c_int) -> c_int;
        pub fn ale_game_over(a: *mut c_void) -> c_int;
        pub fn ale_game_truncated(a: *mut c_void) -> c_int;
        pub fn ale_reset(a: *mut c_void) -> c_int;
        pub fn ale_reseed(a: *mut c_void, rom: *const c_char, seed: c_int) -> c_int;
        pub fn ale_ram(a: *mut c_void, out: *mut u8);
        pub fn ale_lives(a: *mut c_void) -> c_int;
        pub fn ale_screen_size(a: *mut c_void, width: *mut c_int, height: *mut c_int);
        pub fn ale_screen_rgb(a: *mut c_void, out: *mut u8) -> c_int;
        pub fn ale_episode_frame(a: *mut c_void) -> c_int;
    }
}

/// What went wrong in the emulator.
#[derive(Debug, thiserror::Error)]
pub enum AtariError {
    /// The ALE refused (a ROM it cannot load, …), with its message.
    #[error("ALE: {0}")]
    Ale(String),
    /// The ROM file is missing or not one the ALE knows.
    #[error("{0}: not a ROM the ALE supports (missing, or an unknown dump)")]
    Rom(PathBuf),
    /// The ROM file holds another game than its name says.
    #[error("{path}: by its MD5 this is the ROM of `{game}`, not of `{expected}` (the file name's game); put the right dump there")]
    WrongGame {
        /// The ROM file.
        path: PathBuf,
        /// The game the ALE identifies.
        game: String,
        /// The game of the file's name (`pong.bin`: `pong`).
        expected: String,
    },
    /// A path with a NUL byte.
    #[error("{0}: the path has a NUL byte")]
    Path(PathBuf),
}

fn last_error() -> String {
    // SAFETY: the shim returns a pointer to a thread-local NUL-terminated string.
    unsafe { CStr::from_ptr(ffi::ale_last_error()) }
        .to_string_lossy()
        .into_owned()
}

/// One emulator with a ROM loaded.
#[derive(Debug)]
pub struct Emulator {
    raw: *mut c_void,
    rom: CString,
    actions: Vec<c_int>,
}

// SAFETY: an ALEInterface has no thread affinity; `Emulator` owns it and needs `&mut self` to
// use it, so it is never used from two threads at once.
unsafe impl Send for Emulator {}

impl Emulator {
    /// Loads `rom` with the ALE seeded by `seed`, sticky actions repeating with probability
    /// `repeat_action_probability`, episodes cut after `max_frames` frames (0: never).
    pub fn new(
        rom: &Path,
        seed: i32,
        repeat_action_probability: f32,
        max_frames: i32,
    ) -> Result<Self, AtariError> {
        let c_rom = CString::new(rom.as_os_str().as_encoded_bytes())
            .map_err(|_| AtariError::Path(rom.to_path_buf()))?;
        // the ALE ends the process on a missing or unknown ROM: check first, and that the dump
        // is the game its file name says (apo finds a game's ROM by ale-py's file name)
        if !rom.is_file() {
            return Err(AtariError::Rom(rom.to_path_buf()));
        }
        let mut name = [0 as c_char; 256];
        // SAFETY: valid NUL-terminated path; `name` holds `name.len()` bytes.
        let len =
            unsafe { ffi::ale_rom_name(c_rom.as_ptr(), name.as_mut_ptr(), name.len() as c_int) };
        if len <= 0 {
            return Err(AtariError::Rom(rom.to_path_buf()));
        }
        // SAFETY: the shim wrote a NUL-terminated name into `name`.
        let game = unsafe { std::ffi::CStr::from_ptr(name.as_ptr()) }
            .to_string_lossy()
            .into_owned();
        let expected = rom
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        if game != expected {
            return Err(AtariError::WrongGame {
                path: rom.to_path_buf(),
                game,
                expected,
            });
        }
        // SAFETY: valid NUL-terminated path; the shim catches every exception.
        let raw =
            unsafe { ffi::ale_new(c_rom.as_ptr(), seed, repeat_action_probability, max_frames) };
        if raw.is_null() {
            return Err(AtariError::Ale(last_error()));
        }
        let mut actions = vec![0; 18];
        // SAFETY: `raw` is live and `actions` holds 18 slots (the full action set).
        let n = unsafe { ffi::ale_minimal_actions(raw, actions.as_mut_ptr(), 18) };
        actions.truncate(n.clamp(0, 18) as usize);
        Ok(Self {
            raw,
            rom: c_rom,
            actions,
        })
    }

    /// The number of actions of the game's minimal action set.
    pub fn num_actions(&self) -> usize {
        self.actions.len()
    }

    /// One emulator frame with the minimal set's action `action`; its reward.
    ///
    /// # Errors
    /// When the ALE reports an error.
    pub fn act(&mut self, action: usize) -> Result<i32, AtariError> {
        let code = self.actions.get(action).copied().unwrap_or(0);
        let mut reward = 0;
        // SAFETY: `raw` is live; `reward` is a valid out-pointer.
        let status = unsafe { ffi::ale_act(self.raw, code, &mut reward) };
        if status < 0 {
            return Err(AtariError::Ale(last_error()));
        }
        Ok(reward)
    }

    /// Whether the game is over (not counting the frame limit: see [`Emulator::truncated`]).
    pub fn game_over(&mut self) -> bool {
        // SAFETY: `raw` is live.
        unsafe { ffi::ale_game_over(self.raw) != 0 }
    }

    /// Whether the episode was cut by the frame limit.
    pub fn truncated(&mut self) -> bool {
        // SAFETY: `raw` is live.
        unsafe { ffi::ale_game_truncated(self.raw) != 0 }
    }

    /// Starts a new game (reseeding the ALE first with `Some(seed)`).
    ///
    /// # Errors
    /// When the ALE reports an error.
    pub fn reset(&mut self, seed: Option<i32>) -> Result<(), AtariError> {
        // SAFETY: `raw` is live; `rom` is the NUL-terminated path it was loaded from.
        let status = unsafe {
            match seed {
                Some(seed) => ffi::ale_reseed(self.raw, self.rom.as_ptr(), seed),
                None => 0,
            }
            .min(ffi::ale_reset(self.raw))
        };
        if status < 0 {
            return Err(AtariError::Ale(last_error()));
        }
        Ok(())
    }

    /// The 128 RAM bytes, copied into `out` (no allocation).
    pub fn ram(&mut self, out: &mut [u8; 128]) {
        // SAFETY: `raw` is live; `out` holds the 128 bytes the shim copies.
        unsafe { ffi::ale_ram(self.raw, out.as_mut_ptr()) }
    }

    /// The screen's width and height in pixels (160 × 210).
    pub fn screen_size(&mut self) -> (usize, usize) {
        let (mut width, mut height) = (0, 0);
        // SAFETY: `raw` is live; both are valid out-pointers.
        unsafe { ffi::ale_screen_size(self.raw, &mut width, &mut height) };
        (width.max(0) as usize, height.max(0) as usize)
    }

    /// The screen as RGB bytes, rows from the top, into `out` (resized to
    /// 3 × width × height); returns the screen's width and height.
    ///
    /// # Errors
    /// When the ALE reports an error.
    pub fn screen_rgb(&mut self, out: &mut Vec<u8>) -> Result<(usize, usize), AtariError> {
        let (width, height) = self.screen_size();
        out.resize(3 * width * height, 0);
        // SAFETY: `raw` is live; `out` holds the 3 × width × height bytes the shim copies.
        let status = unsafe { ffi::ale_screen_rgb(self.raw, out.as_mut_ptr()) };
        if status < 0 {
            return Err(AtariError::Ale(last_error()));
        }
        Ok((width, height))
    }

    /// Lives left.
    pub fn lives(&mut self) -> i32 {
        // SAFETY: `raw` is live.
        unsafe { ffi::ale_lives(self.raw) }
    }

    /// Frames since the episode started.
    pub fn episode_frame(&mut self) -> i32 {
        // SAFETY: `raw` is live.
        unsafe { ffi::ale_episode_frame(self.raw) }
    }
}

impl Drop for Emulator {
    fn drop(&mut self) {
        // SAFETY: `raw` came from `ale_new` and is freed once.
        unsafe { ffi::ale_delete(self.raw) }
    }
}
