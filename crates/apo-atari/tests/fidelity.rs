//! Our v5 environments against Gymnasium + ale-py 0.12.1: the same seed and actions give the
//! same RAM, rewards and episode ends. `tests/fixtures/v5_seed7.json` was recorded once with
//! `gym.make("ALE/<Game>-v5", obs_type="ram")`, `reset(seed=7)`, action `(7·t) mod n` at step t.
use apo_atari::AtariEnv;
use apo_envs::{Action, Env};

#[test]
fn trajectories_match_gymnasium() {
    // installed by `scripts/setup.sh` (scripts/atari_assets.py)
    let dir = apo_atari::rom_dir();
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/fixtures/v5_seed7.json"),
    )
    .expect("fixture");
    let fixture: serde_json::Value = serde_json::from_str(&text).expect("json");
    for (game, rom) in [("Pong", "pong.bin"), ("Breakout", "breakout.bin")] {
        let rec = &fixture[game];
        let mut env = AtariEnv::new(&dir.join(rom)).expect("rom");
        let n = rec["n"].as_u64().unwrap() as usize;
        assert_eq!(env.action_space(), &apo_envs::Space::Discrete { n });
        let mut obs = vec![0.0f32; 128];
        env.reset(Some(rec["seed"].as_u64().unwrap()), &mut obs);
        let ram = |v: &serde_json::Value| -> Vec<f32> {
            v.as_array()
                .unwrap()
                .iter()
                .map(|x| x.as_f64().unwrap() as f32)
                .collect()
        };
        assert_eq!(obs, ram(&rec["ram0"]), "{game}: first observation");
        let rewards = rec["rewards"].as_array().unwrap();
        let mut checkpoints = rec["ram_every_50"].as_array().unwrap().iter();
        for (t, want) in rewards.iter().enumerate() {
            let step = env.step(Action::Discrete((t * 7) % n), &mut obs);
            assert_eq!(
                step.reward,
                want.as_f64().unwrap(),
                "{game}: reward at step {t}"
            );
            let done = &rec["done"][t];
            assert_eq!(
                step.terminated,
                done[0].as_bool().unwrap(),
                "{game}: terminated at {t}"
            );
            assert_eq!(
                step.truncated,
                done[1].as_bool().unwrap(),
                "{game}: truncated at {t}"
            );
            if t % 50 == 49 {
                assert_eq!(
                    obs,
                    ram(checkpoints.next().unwrap()),
                    "{game}: RAM at step {t}"
                );
            }
        }
    }
}
