//! The rendered screen against Gymnasium + ale-py 0.12.1: `tests/fixtures/v5_screen_seed7.json`
//! holds checksums of `env.render()` (`render_mode="rgb_array"`, 210 × 160 RGB) after
//! `reset(seed=7)` and after 50 and 100 steps of action `(7·t) mod n`, recorded by
//! `scripts/atari_screen_fixture.py`. A frame of the screen's own size is the screen, byte for
//! byte; other sizes are the same picture scaled.
use apo_atari::AtariEnv;
use apo_envs::{Action, Camera, Env, Frame, RenderError};

/// The fixture's checksums of an RGB buffer: the byte sum, and the sum of byte i times
/// (i mod 65521) + 1.
fn checksums(rgb: &[u8]) -> (u64, u64) {
    rgb.iter().enumerate().fold((0, 0), |(s, w), (i, &b)| {
        (s + u64::from(b), w + u64::from(b) * (i as u64 % 65_521 + 1))
    })
}

#[test]
fn screens_match_gymnasium() {
    let dir = apo_atari::rom_dir();
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/fixtures/v5_screen_seed7.json"),
    )
    .expect("fixture");
    let fixture: serde_json::Value = serde_json::from_str(&text).expect("json");
    for (game, rom) in [("Pong", "pong.bin"), ("Breakout", "breakout.bin")] {
        let rec = &fixture[game];
        let mut env = AtariEnv::new(&dir.join(rom)).expect("rom");
        let n = match env.action_space() {
            apo_envs::Space::Discrete { n } => *n,
            other => panic!("{other:?}"),
        };
        let (w, h) = (
            rec["width"].as_u64().unwrap(),
            rec["height"].as_u64().unwrap(),
        );
        let mut frame = Frame::new(w as u32, h as u32).expect("frame");
        let want = |at: &str| {
            (
                rec[at]["sum"].as_u64().unwrap(),
                rec[at]["weighted"].as_u64().unwrap(),
            )
        };
        let mut obs = vec![0.0f32; 128];
        env.reset(Some(rec["seed"].as_u64().unwrap()), &mut obs);
        env.render(&Camera::Track, &mut frame).expect("render");
        assert_eq!(
            checksums(frame.rgb()),
            want("0"),
            "{game}: screen after reset"
        );
        for t in 0..100 {
            env.step(Action::Discrete((7 * t) % n), &mut obs);
            if t + 1 == 50 || t + 1 == 100 {
                env.render(&Camera::Free, &mut frame).expect("render");
                assert_eq!(
                    checksums(frame.rgb()),
                    want(&(t + 1).to_string()),
                    "{game}: screen after {} steps",
                    t + 1
                );
            }
        }
    }
}

#[test]
fn frames_scale_the_screen_and_rendering_changes_nothing() {
    let dir = apo_atari::rom_dir();
    let mut a = AtariEnv::new(&dir.join("pong.bin")).expect("rom");
    let mut b = AtariEnv::new(&dir.join("pong.bin")).expect("rom");
    let (mut oa, mut ob) = (vec![0.0f32; 128], vec![0.0f32; 128]);
    a.reset(Some(3), &mut oa);
    b.reset(Some(3), &mut ob);
    let mut small = Frame::new(80, 105).expect("frame");
    let mut twice = Frame::new(320, 420).expect("frame");
    let mut exact = Frame::new(160, 210).expect("frame");
    for t in 0..200 {
        // `a` is rendered at every step, `b` never: they must play the same game
        a.render(&Camera::Track, &mut small).expect("render");
        let sa = a.step(Action::Discrete(t % 6), &mut oa);
        let sb = b.step(Action::Discrete(t % 6), &mut ob);
        assert_eq!((sa, &oa), (sb, &ob), "step {t}");
    }
    a.render(&Camera::Track, &mut exact).expect("render");
    a.render(&Camera::Track, &mut twice).expect("render");
    // twice the size: every screen pixel becomes a 2 × 2 block
    for (x, y) in [(0, 0), (17, 33), (80, 105), (159, 209)] {
        let p = exact.pixel(x, y).unwrap();
        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
            assert_eq!(twice.pixel(2 * x + dx, 2 * y + dy), Some(p), "({x}, {y})");
        }
    }
    let colours: std::collections::BTreeSet<_> = exact.rgb().chunks_exact(3).collect();
    assert!(
        colours.len() >= 3,
        "a Pong screen has a field, paddles and a score"
    );
    assert!(matches!(
        a.render(&Camera::Named("side".into()), &mut exact),
        Err(RenderError::UnknownCamera { .. })
    ));
}
