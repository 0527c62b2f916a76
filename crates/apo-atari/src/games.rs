//! The paper's 62 Atari games as Gymnasium registers them (`ALE/<Game>-v5`), their ROM files,
//! and their registration with apo-envs.

use std::path::PathBuf;

use apo_envs::{register, EnvError, Family};

use crate::env::{AtariEnv, FRAMESKIP, MAX_FRAMES};

/// The games, as in their registered names `ALE/<Game>-v5`.
pub const GAMES: [&str; 62] = [
    "Adventure",
    "AirRaid",
    "Alien",
    "Amidar",
    "Assault",
    "Asterix",
    "Asteroids",
    "Atlantis",
    "BankHeist",
    "BattleZone",
    "BeamRider",
    "Berzerk",
    "Bowling",
    "Boxing",
    "Breakout",
    "Carnival",
    "Centipede",
    "ChopperCommand",
    "CrazyClimber",
    "Defender",
    "DemonAttack",
    "DoubleDunk",
    "ElevatorAction",
    "Enduro",
    "FishingDerby",
    "Freeway",
    "Frostbite",
    "Gopher",
    "Gravitar",
    "Hero",
    "IceHockey",
    "Jamesbond",
    "JourneyEscape",
    "Kangaroo",
    "Krull",
    "KungFuMaster",
    "MontezumaRevenge",
    "MsPacman",
    "NameThisGame",
    "Phoenix",
    "Pitfall",
    "Pong",
    "Pooyan",
    "PrivateEye",
    "Qbert",
    "Riverraid",
    "RoadRunner",
    "Robotank",
    "Seaquest",
    "Skiing",
    "Solaris",
    "SpaceInvaders",
    "StarGunner",
    "Tennis",
    "TimePilot",
    "Tutankham",
    "UpNDown",
    "Venture",
    "VideoPinball",
    "WizardOfWor",
    "YarsRevenge",
    "Zaxxon",
];

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
/// `scripts/setup.sh --atari` installs them).
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
        let name = format!("ALE/{game}-v5");
        let rom = rom_file(game);
        let env_name = name.clone();
        family.add(name, MAX_FRAMES as usize / FRAMESKIP, move || {
            let path = rom_dir().join(&rom);
            AtariEnv::new(&path)
                .map(|env| Box::new(env) as Box<dyn apo_envs::Env>)
                .map_err(|e| EnvError::Init {
                    name: env_name.clone(),
                    reason: format!(
                        "{e}; install the ROMs with `bash scripts/setup.sh --atari` (into {}; \
                         APO_ROM_DIR overrides)",
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
    }
}
