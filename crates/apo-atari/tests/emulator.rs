//! The emulator binding, and every game through the registry (ROMs from `scripts/setup.sh`).
use apo_atari::Emulator;
use apo_envs::Env;

#[test]
fn pong_loads_steps_and_reads_ram() {
    // installed by `scripts/setup.sh` (scripts/atari_assets.py)
    let dir = apo_atari::rom_dir();
    let mut e = Emulator::new(&dir.join("pong.bin"), 0, 0.25, 108_000).expect("pong loads");
    assert_eq!(e.num_actions(), 6);
    e.reset(Some(0)).expect("reset");
    let mut ram = [0u8; 128];
    let mut total = 0;
    for t in 0..4000 {
        total += e.act(t % 6).expect("act");
    }
    e.ram(&mut ram);
    assert!(ram.iter().any(|&b| b != 0));
    assert!(total < 0, "random play loses points at Pong: {total}");
    assert!(Emulator::new(std::path::Path::new("/nonexistent.bin"), 0, 0.25, 0).is_err());
}

#[test]
fn every_game_loads_from_the_registry_with_its_minimal_action_set() {
    apo_atari::register_games().expect("registers once");
    for game in apo_atari::GAMES {
        let name = format!("ALE/{}-v5", game.name);
        let spec = apo_envs::registry::spec(&name).expect(game.name);
        assert_eq!(spec.family, "atari");
        assert_eq!(spec.observation_dim, 128, "{name}");
        assert_eq!(spec.max_episode_steps, 27_000, "{name}: 108 000 frames / 4");
        assert_eq!(
            spec.action_space,
            apo_envs::Space::Discrete { n: game.actions },
            "{name}"
        );
        // the built game has the stated sizes (a mismatch would be an error here)
        let env = apo_envs::make(&name).expect(game.name);
        assert_eq!(
            env.action_space(),
            &apo_envs::Space::Discrete { n: game.actions }
        );
    }
    // a game without its namespace and version, and misspellings, get suggestions
    for (asked, meant) in [
        ("Pong", "ALE/Pong-v5"),
        ("ALE/Pongg-v5", "ALE/Pong-v5"),
        ("Breakuot", "ALE/Breakout-v5"),
        ("ALE/Riverrade-v5", "ALE/Riverraid-v5"),
    ] {
        let Err(apo_envs::EnvError::Unknown { suggestions, .. }) = apo_envs::make(asked) else {
            panic!("{asked} is not a registered name");
        };
        assert_eq!(
            suggestions.first().map(String::as_str),
            Some(meant),
            "{asked}"
        );
    }
    // the namespace without the version is the game
    assert_eq!(
        apo_envs::registry::spec("ALE/Pong")
            .expect("unversioned")
            .name,
        "ALE/Pong-v5"
    );
}
