//! Gymnasium's `ALE/<Game>-v5` with RAM observations, on an [`Emulator`]: frame skip 4
//! (the 4 frames' rewards summed), sticky actions with repeat probability 0.25, the minimal
//! action set, episodes ending at game over (terminated) or after 108 000 frames (truncated),
//! observations the 128 RAM bytes as `f32` in 0–255, and a seeded reset that reseeds the ALE
//! as ale-py does ([`crate::ale_seed`]) and reloads the ROM.

use std::path::Path;

use apo_envs::{Action, Camera, Env, Frame, RenderError, Space, Transition};

use crate::{ale_seed, AtariError, Emulator};

/// v5's frames per step.
pub const FRAMESKIP: usize = 4;
/// v5's sticky-action probability.
pub const REPEAT_ACTION_PROBABILITY: f32 = 0.25;
/// v5's frame limit per episode.
pub const MAX_FRAMES: i32 = 108_000;
/// The observation's length: the console's 128 bytes of RAM.
pub const RAM_SIZE: usize = 128;

/// One game as a v5 environment with RAM observations.
#[derive(Debug)]
pub struct AtariEnv {
    emulator: Emulator,
    observation_space: Space,
    action_space: Space,
    ram: [u8; RAM_SIZE],
    /// The last rendered screen, RGB.
    screen: Vec<u8>,
}

impl AtariEnv {
    /// The game of `rom` (a ROM file the ALE supports).
    ///
    /// # Errors
    /// When the ROM is missing or unknown, or the ALE refuses it.
    pub fn new(rom: &Path) -> Result<Self, AtariError> {
        let emulator = Emulator::new(rom, ale_seed(0), REPEAT_ACTION_PROBABILITY, MAX_FRAMES)?;
        let n = emulator.num_actions();
        Ok(Self {
            emulator,
            observation_space: Space::uniform_box(RAM_SIZE, 0.0, 255.0),
            action_space: Space::Discrete { n },
            ram: [0; RAM_SIZE],
            screen: Vec::new(),
        })
    }

    fn observe(&mut self, obs: &mut [f32]) {
        self.emulator.ram(&mut self.ram);
        for (o, &b) in obs.iter_mut().zip(&self.ram) {
            *o = f32::from(b);
        }
    }
}

impl Env for AtariEnv {
    fn observation_space(&self) -> &Space {
        &self.observation_space
    }

    fn action_space(&self) -> &Space {
        &self.action_space
    }

    fn reset(&mut self, seed: Option<u64>, obs: &mut [f32]) {
        // an error here (the ROM file vanished mid-run) leaves the last game loaded; a step that
        // then fails ends its episode as an instability
        let _ = self.emulator.reset(seed.map(ale_seed));
        self.observe(obs);
    }

    fn step(&mut self, action: Action<'_>, obs: &mut [f32]) -> Transition {
        let a = match action {
            Action::Discrete(a) => a,
            Action::Continuous(_) => 0,
        };
        let mut reward = 0.0;
        for _ in 0..FRAMESKIP {
            match self.emulator.act(a) {
                Ok(r) => reward += f64::from(r),
                Err(_) => {
                    // the emulator refused: end the episode as an instability (counted, not
                    // trusted), never a panic
                    self.observe(obs);
                    return Transition {
                        reward,
                        terminated: true,
                        truncated: false,
                        info: apo_envs::StepInfo {
                            unstable: true,
                            success: None,
                        },
                    };
                }
            }
        }
        self.observe(obs);
        Transition {
            reward,
            terminated: self.emulator.game_over(),
            truncated: self.emulator.truncated(),
            info: Default::default(),
        }
    }

    /// The emulator's screen (160 × 210, the ALE's palette), scaled to the frame with the
    /// nearest pixel: the picture Gymnasium's `render_mode="rgb_array"` gives, stretched.
    /// Cameras: `track` and `free` (both the screen).
    fn render(&mut self, camera: &Camera, frame: &mut Frame) -> Result<(), RenderError> {
        if let Camera::Named(name) = camera {
            return Err(RenderError::UnknownCamera {
                name: name.clone(),
                available: vec!["track".into(), "free".into()],
            });
        }
        let (sw, sh) = self
            .emulator
            .screen_rgb(&mut self.screen)
            .map_err(|e| RenderError::Failed(e.to_string()))?;
        if sw == 0 || sh == 0 {
            return Err(RenderError::Failed("the emulator has no screen".into()));
        }
        let (fw, fh) = (frame.width() as usize, frame.height() as usize);
        let rgb = frame.rgb_mut();
        for y in 0..fh {
            let row = (y * sh / fh) * sw;
            for x in 0..fw {
                let from = 3 * (row + x * sw / fw);
                rgb[3 * (y * fw + x)..][..3].copy_from_slice(&self.screen[from..from + 3]);
            }
        }
        Ok(())
    }
}
