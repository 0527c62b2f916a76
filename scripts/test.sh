#!/usr/bin/env bash
# The project's tests: formatting, lints (warnings are errors), every crate's tests, and the
# examples of the training library run for a few hundred steps.
# Needs rustfmt and clippy (rustup's default profile has both) and the packages of
# `scripts/setup.sh --deps-only`.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo fmt --all -- --check
cargo clippy --workspace --all-targets -- -D warnings
cargo test --workspace
# the training-library examples, a few hundred environment steps each (built by `cargo test`)
cargo run --profile test -q -p apo-train --example train_hopper -- 2 200
cargo run --profile test -q -p apo-train --example custom_policy -- 5
