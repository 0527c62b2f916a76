#!/usr/bin/env bash
# The project's tests: formatting, lints (warnings are errors), then every crate's tests.
# Needs rustfmt and clippy (rustup's default profile has both) and the packages of
# `scripts/setup.sh --deps-only`.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo fmt --all -- --check
cargo clippy --workspace --all-targets -- -D warnings
cargo test --workspace
