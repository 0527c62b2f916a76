//! The emulator binding, and every game through the registry (ROMs from `scripts/setup.sh`).
use apo_atari::Emulator;

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
        let spec = apo_envs::registry::spec(&format!("ALE/{game}-v5")).expect(game);
        assert_eq!(spec.observation_dim, 128, "{game}");
        match spec.action_space {
            apo_envs::Space::Discrete { n } => assert!((2..=18).contains(&n), "{game}: {n}"),
            other => panic!("{game}: {other:?}"),
        }
    }
}
