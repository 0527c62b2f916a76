#!/usr/bin/env bash
# The project's tests: formatting, lints (warnings are errors), the libraries' docs, every
# crate's tests and doctests, the docs' command blocks, an outside crate on the public API, and
# the examples of the training library run for a few hundred steps.
# Needs rustfmt and clippy (rustup's default profile has both) and the packages and assets
# that `scripts/setup.sh` (or `--deps-only`) installs; MuJoCo 3.17 is fetched here when missing.
set -euo pipefail
cd "$(dirname "$0")/.."
# MuJoCo 3.17: every crate is tested with the `mujoco3` physics built in, so the MuJoCo 2.2.2
# tests also run beside MuJoCo 3 in one process.
mujoco3="$PWD/.cache/mujoco-3.17.0/lib"
if [ ! -e "$mujoco3/libmujoco.so" ]; then
  echo "== MuJoCo 3.17 is not in .cache/ yet: fetching it (scripts/mujoco3_assets.py)"
  python3 scripts/mujoco3_assets.py
fi
export MUJOCO_DYNAMIC_LINK_DIR="$mujoco3"
export LD_LIBRARY_PATH="$mujoco3${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
# apo-cli's opt-in features `mpi` (data-parallel training under Open MPI's mpirun: the tests
# launch the binary and its `mpi_update` example) and `atari` (the games listed, trained,
# resumed, evaluated from the command line) are on in every step, with the whole workspace
# selected each time: cargo resolves dependency features per selection, so one selection
# everywhere compiles Burn's tree once for the lints, docs and tests instead of once per step.
features=apo-envs/mujoco3,apo-cli/mujoco3,apo-cli/mpi,apo-cli/atari
# each step prints its wall time, so a slow CI run shows where the time went
step() { local t0=$SECONDS; "$@"; echo "== $((SECONDS - t0)) s: $*" >&2; }
step cargo fmt --all -- --check
step cargo fmt --manifest-path tests/external-user/Cargo.toml -- --check
step cargo clippy --workspace --all-targets --features "$features" -- -D warnings
step cargo clippy --manifest-path tests/external-user/Cargo.toml --target-dir target -- -D warnings
# the libraries' documentation, every link resolved (the binaries' docs are their --help);
# `--examples` resolves features as the lints did (with the dev-dependencies), so the checked
# dependencies are reused
step env RUSTDOCFLAGS="-D warnings" cargo doc --no-deps --workspace --lib --examples --features "$features"
step cargo test --workspace --features "$features"
# every command block of the README and the handbook that is not marked `long` runs, with the
# binary the tests built, in a scratch copy of the repository (scripts/doc_commands.py)
step env APO="${CARGO_TARGET_DIR:-target}/debug/apo" python3 scripts/doc_commands.py
# sweeps on a real single-node Slurm (crates/apo-cli/tests/cli/slurm.rs, ignored by a plain
# `cargo test`): Debian's slurm-wlm and munge installed when missing, the daemons started here and
# stopped when this script ends (scripts/slurm-local.sh; docs/cluster.md)
step bash scripts/slurm-local.sh install
step bash scripts/slurm-local.sh start
trap 'bash scripts/slurm-local.sh stop >&2' EXIT
eval "$(bash scripts/slurm-local.sh env)"
step cargo test --workspace --features "$features" --test cli -- --ignored slurm:: --test-threads=1
# a crate outside the workspace that uses only the public API of apo-core, apo-envs and
# apo-train (tests/external-user): the three user stories for a few epochs each, wgpu included
step cargo run --profile test -q --manifest-path tests/external-user/Cargo.toml --target-dir target -- --wgpu
# the training-library examples, a few hundred environment steps each, as `cargo test` built
# them (a `cargo run -p apo-train` would resolve features anew and rebuild the tree)
examples="${CARGO_TARGET_DIR:-target}/debug/examples"
step "$examples/train_hopper" 2 200
step "$examples/custom_policy" 5
