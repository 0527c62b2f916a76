//! A ROM is the game its file name says: the ALE identifies a dump by its MD5, and a dump of
//! another game under a game's file name is refused naming both, never played under the wrong
//! name. Every installed ROM of the 62 games passes the check.

use apo_atari::{rom_dir, rom_file, Emulator, GAMES};

#[test]
fn every_installed_rom_is_its_game_and_another_games_dump_is_refused() {
    let dir = rom_dir();
    let mut checked = 0;
    for game in GAMES.iter() {
        let rom = dir.join(rom_file(game.name));
        if rom.is_file() {
            if let Err(e) = Emulator::new(&rom, 0, 0.0, 0) {
                panic!("{}: {e}", game.name);
            }
            checked += 1;
        }
    }
    assert!(checked > 0, "no ROM installed in {}", dir.display());

    let tmp = std::env::temp_dir().join(format!("apo-rom-identity-{}", std::process::id()));
    std::fs::create_dir_all(&tmp).expect("temp dir");
    let (air_raid, pong) = (dir.join("air_raid.bin"), tmp.join("pong.bin"));
    std::fs::copy(&air_raid, &pong).expect("copy a dump");
    let Err(err) = Emulator::new(&pong, 0, 0.0, 0) else {
        panic!("another game's dump was accepted");
    };
    let err = err.to_string();
    std::fs::remove_dir_all(&tmp).expect("the folder this test made");
    assert!(err.contains("air_raid") && err.contains("`pong`"), "{err}");
}
