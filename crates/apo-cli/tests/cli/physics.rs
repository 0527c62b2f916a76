//! `--physics`: the MuJoCo tasks on MuJoCo 3.17 (builds with the `mujoco3` feature), recorded in
//! the run's config so that evaluation rebuilds the same physics; a clear error in other builds.

use super::fails;

#[cfg(feature = "mujoco3")]
#[test]
fn a_run_on_mujoco3_records_its_physics_and_evaluates_on_it() {
    use super::{ok, path};
    let bench = ok(&[
        "bench",
        "env",
        "--env",
        "Hopper",
        "--steps",
        "300",
        "--physics",
        "mujoco3",
    ]);
    assert!(bench.contains("physics=mujoco3"), "{bench}");
    let tmp = tempfile::tempdir().expect("tempdir");
    let run = tmp.path().join("hopper3");
    ok(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "Hopper",
        "--physics",
        "mujoco3",
        "--epochs",
        "1",
        "--steps-per-epoch",
        "300",
        "--quiet",
        "--out",
        path(&run),
    ]);
    let config = std::fs::read_to_string(run.join("config.toml")).expect("config.toml");
    assert!(
        config.lines().any(|l| l == "physics = \"mujoco3\""),
        "{config}"
    );
    let eval = ok(&["eval", "--run", path(&run), "--episodes", "2"]);
    assert!(eval.contains("episodes=2"), "{eval}");
}

#[cfg(not(feature = "mujoco3"))]
#[test]
fn mujoco3_without_the_feature_names_the_feature() {
    let err = fails(&[
        "bench",
        "env",
        "--env",
        "Hopper",
        "--steps",
        "10",
        "--physics",
        "mujoco3",
    ]);
    assert!(err.contains("--features mujoco3"), "{err}");
}

#[test]
fn an_unknown_physics_lists_the_choices() {
    let err = fails(&[
        "bench",
        "env",
        "--env",
        "Hopper",
        "--steps",
        "10",
        "--physics",
        "bullet",
    ]);
    assert!(err.contains("mujoco2") && err.contains("mujoco3"), "{err}");
    let err = fails(&[
        "train",
        "--algo",
        "ppo",
        "--env",
        "Hopper",
        "--set",
        "physics=\"bullet\"",
    ]);
    assert!(err.contains("physics"), "{err}");
}
