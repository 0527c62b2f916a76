//! A game whose ROM is not installed is still listed, and building it says which command
//! installs the ROMs. (Its own test binary: it points `APO_ROM_DIR` at an empty folder.)

#[test]
fn a_missing_rom_names_the_install_command() {
    let empty = std::env::temp_dir().join(format!("apo-no-roms-{}", std::process::id()));
    std::fs::create_dir_all(&empty).expect("temp dir");
    // the only test of this binary: no other thread reads the environment
    std::env::set_var("APO_ROM_DIR", &empty);
    apo_atari::register_games().expect("registers once");
    let spec = apo_envs::registry::spec("ALE/Pong-v5").expect("listed without its ROM");
    assert_eq!(spec.action_space, apo_envs::Space::Discrete { n: 6 });
    let err = apo_envs::make("ALE/Pong-v5")
        .err()
        .expect("no ROM, no game")
        .to_string();
    for part in [
        "ALE/Pong-v5",
        "pong.bin",
        "scripts/atari_assets.py",
        "APO_ROM_DIR",
    ] {
        assert!(err.contains(part), "`{part}` missing from: {err}");
    }
    std::fs::remove_dir(&empty).expect("the folder this test made");
}
