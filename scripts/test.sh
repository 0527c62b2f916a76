#!/usr/bin/env bash
# The project's tests: formatting, lints (warnings are errors), every crate's tests, and the
# examples of the training library run for a few hundred steps.
# Needs rustfmt and clippy (rustup's default profile has both) and the packages of
# `scripts/setup.sh --deps-only` (Open MPI and libclang included).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo fmt --all -- --check
cargo clippy --workspace --all-targets -- -D warnings
cargo test --workspace
# apo-cli's opt-in features, built once together: data-parallel training under Open MPI's
# mpirun (`mpi`: the binary and its `mpi_update` example, then the tests that launch them) and
# the Atari games (`atari`: listed, trained, resumed, evaluated from the command line)
cargo clippy -p apo-cli --features mpi,atari --all-targets -- -D warnings
cargo build -p apo-cli --features mpi,atari --profile test --bin apo --example mpi_update
cargo test -p apo-cli --features mpi,atari --test mpi --test atari
# the training-library examples, a few hundred environment steps each (built by `cargo test`)
cargo run --profile test -q -p apo-train --example train_hopper -- 2 200
cargo run --profile test -q -p apo-train --example custom_policy -- 5
