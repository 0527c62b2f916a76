//! The paper's 62 Atari games as Gymnasium registers them (`ALE/<Game>-v5`), their ROM files,
//! and their registration with apo-envs.

use std::path::PathBuf;

use apo_envs::{register, EnvError, Family};

use crate::env::{AtariEnv, FRAMESKIP, MAX_FRAMES, RAM_SIZE};

/// One of the paper's Atari games.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Game {
    /// The name in its registered name `ALE/<name>-v5`, e.g. `"Pong"`.
    pub name: &'static str,
    /// The size of its minimal action set, the `Discrete(n)` of Gymnasium's `ALE/<name>-v5`
    /// (read from Gymnasium 1.x with ale-py 0.12.1; a test checks it against the emulator).
    pub actions: usize,
}

const fn game(name: &'static str, actions: usize) -> Game {
    Game { name, actions }
}

/// The paper's 62 games, in alphabetical order.
pub const GAMES: [Game; 62] = [
    game("Adventure", 18),
    game("AirRaid", 6),
    game("Alien", 18),
    game("Amidar", 10),
    game("Assault", 7),
    game("Asterix", 9),
    game("Asteroids", 14),
    game("Atlantis", 4),
    game("BankHeist", 18),
    game("BattleZone", 18),
    game("BeamRider", 9),
    game("Berzerk", 18),
    game("Bowling", 6),
    game("Boxing", 18),
    game("Breakout", 4),
    game("Carnival", 6),
    game("Centipede", 18),
    game("ChopperCommand", 18),
    game("CrazyClimber", 9),
    game("Defender", 18),
    game("DemonAttack", 6),
    game("DoubleDunk", 18),
    game("ElevatorAction", 18),
    game("Enduro", 9),
    game("FishingDerby", 18),
    game("Freeway", 3),
    game("Frostbite", 18),
    game("Gopher", 8),
    game("Gravitar", 18),
    game("Hero", 18),
    game("IceHockey", 18),
    game("Jamesbond", 18),
    game("JourneyEscape", 16),
    game("Kangaroo", 18),
    game("Krull", 18),
    game("KungFuMaster", 14),
    game("MontezumaRevenge", 18),
    game("MsPacman", 9),
    game("NameThisGame", 6),
    game("Phoenix", 8),
    game("Pitfall", 18),
    game("Pong", 6),
    game("Pooyan", 6),
    game("PrivateEye", 18),
    game("Qbert", 6),
    game("Riverraid", 18),
    game("RoadRunner", 18),
    game("Robotank", 18),
    game("Seaquest", 18),
    game("Skiing", 3),
    game("Solaris", 18),
    game("SpaceInvaders", 6),
    game("StarGunner", 18),
    game("Tennis", 18),
    game("TimePilot", 10),
    game("Tutankham", 8),
    game("UpNDown", 6),
    game("Venture", 18),
    game("VideoPinball", 9),
    game("WizardOfWor", 10),
    game("YarsRevenge", 18),
    game("Zaxxon", 18),
];

/// The game called `name` in [`GAMES`] (exactly as written there).
pub fn find(name: &str) -> Option<&'static Game> {
    GAMES.iter().find(|g| g.name == name)
}

/// The ROM file of `game` as ale-py names it: `KungFuMaster` → `kung_fu_master.bin`.
pub fn rom_file(game: &str) -> String {
    let mut out = String::with_capacity(game.len() + 8);
    for (i, c) in game.chars().enumerate() {
        if c.is_ascii_uppercase() && i > 0 {
            out.push('_');
        }
        out.push(c.to_ascii_lowercase());
    }
    out + ".bin"
}

/// Where the ROMs are: `APO_ROM_DIR`, else `$HOME/.local/share/apo/roms` (where
/// `scripts/setup.sh` installs them, through `scripts/atari_assets.py`).
pub fn rom_dir() -> PathBuf {
    std::env::var_os("APO_ROM_DIR").map_or_else(
        || {
            PathBuf::from(std::env::var_os("HOME").unwrap_or_default())
                .join(".local/share/apo/roms")
        },
        PathBuf::from,
    )
}

/// Registers `ALE/<Game>-v5` for every game (family `atari`), truncated after 27 000 steps
/// (the 108 000-frame cap at frame skip 4).
///
/// # Errors
/// When a name is already registered.
pub fn register_games() -> Result<(), EnvError> {
    let mut family = Family::new("atari");
    for game in GAMES {
        let name = format!("ALE/{}-v5", game.name);
        let rom = rom_file(game.name);
        let env_name = name.clone();
        let max_steps = MAX_FRAMES as usize / FRAMESKIP;
        family.add_discrete(name, max_steps, RAM_SIZE, game.actions, move || {
            let path = rom_dir().join(&rom);
            AtariEnv::new(&path)
                .map(|env| Box::new(env) as Box<dyn apo_envs::Env>)
                .map_err(|e| EnvError::Init {
                    name: env_name.clone(),
                    reason: format!(
                        "{e}; install the ROMs with `python3 scripts/atari_assets.py` (or \
                         `bash scripts/setup.sh --deps-only`) into {} (APO_ROM_DIR overrides)",
                        rom_dir().display()
                    ),
                })
        });
    }
    register(family)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rom_names_follow_ale_py() {
        assert_eq!(rom_file("Pong"), "pong.bin");
        assert_eq!(rom_file("KungFuMaster"), "kung_fu_master.bin");
        assert_eq!(rom_file("UpNDown"), "up_n_down.bin");
        assert_eq!(GAMES.len(), 62);
        assert!(
            GAMES.windows(2).all(|w| w[0].name < w[1].name),
            "sorted, no repeats"
        );
        assert_eq!(find("Pong").map(|g| g.actions), Some(6));
        assert_eq!(find("pong"), None);
    }
}
