#!/usr/bin/env bash
# Sets up apo on a fresh Debian (bookworm) machine and runs a small default job.
#
#   bash scripts/setup.sh              # install, build, train APO on Pendulum-v1, evaluate, plot
#   bash scripts/setup.sh --deps-only  # install the packages and assets only (what CI does)
#
# Either way it also fetches what `bash scripts/test.sh` needs beyond the packages: MuJoCo
# 3.17 (`.cache/mujoco-3.17.0`, for the `mujoco3` feature the tests build with), the ALE source
# archive and the Atari ROMs. (`--mujoco3`, which used to ask for MuJoCo 3.17, is still
# accepted.)
#
# Installs (as root, or through sudo) the Debian packages the project needs:
#   build-essential pkg-config   C toolchain for crates that build C
#   libmujoco-dev                MuJoCo 2.2.2, loaded at run time by the MuJoCo environments
#   libmujoco-samples            mujoco-testspeed, the raw-simulator benchmark
#   mesa-vulkan-drivers          a Vulkan driver (Mesa's software one on CPU-only machines) for --backend wgpu
#   fonts-dejavu-core            the font `apo plot` writes its labels with
#   strace                       the test that checkpoints are synced to disk watches the system calls
#   libopenmpi-dev openmpi-bin   Open MPI, for data-parallel training (`cargo build --features mpi`)
#   libclang-dev                 libclang, with which the `mpi` crate reads MPI's C header
#   libegl1 libgl1-mesa-dri      headless OpenGL (EGL; Mesa's software rasterizer without a GPU) for `apo render`
#   libosmesa6                   OSMesa, the other headless OpenGL `apo render` can use
#   ffmpeg                       MP4 videos (`apo render --out video.mp4`; GIFs need nothing)
#   xz-utils                     the finished campaigns' runs (results/*.tar.xz; scripts/results.sh)
# and fetches from PyPI, checksums checked (scripts/atari_assets.py): the Arcade Learning
# Environment's source archive (ale-py 0.12.1, into .cache/) and the Atari ROMs of the ale-py
# wheel (into $APO_ROM_DIR or ~/.local/share/apo/roms).
# Rust itself comes from rustup (https://rustup.rs); this script checks it is there.
set -euo pipefail
cd "$(dirname "$0")/.."

packages=(build-essential pkg-config libmujoco-dev libmujoco-samples mesa-vulkan-drivers fonts-dejavu-core strace
  libopenmpi-dev openmpi-bin libclang-dev libegl1 libgl1-mesa-dri libosmesa6 ffmpeg xz-utils)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo=""
  [ "$(id -u)" -eq 0 ] || sudo="sudo"
  echo "== installing: ${missing[*]}"
  $sudo apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $sudo apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi

deps_only=false
for arg in "$@"; do
  case "$arg" in
    --deps-only) deps_only=true ;;
    --mujoco3) ;;  # always fetched now
    *) echo "error: unknown option $arg (options: --deps-only)" >&2; exit 2 ;;
  esac
done

# the ALE's source archive and the Atari ROMs, from PyPI (apo-atari; checksums checked)
python3 scripts/atari_assets.py
# MuJoCo 3.17's library from the mujoco wheel on PyPI (the tests build the `mujoco3` feature)
python3 scripts/mujoco3_assets.py
if $deps_only; then
  exit 0
fi

if ! command -v cargo >/dev/null; then
  echo "error: cargo not found; install Rust with rustup (https://rustup.rs), then run this again" >&2
  exit 1
fi

echo "== building apo (release)"
cargo build --release -p apo-cli
echo "apo is at target/release/apo"

echo "== small default job: APO on Pendulum-v1, 20 epochs x 4000 steps"
./target/release/apo train --algo apo --env Pendulum-v1 --config configs/pendulum.toml \
  --epochs 20 --steps-per-epoch 4000 --out runs/quickstart-apo --force
./target/release/apo eval --run runs/quickstart-apo --episodes 10
./target/release/apo plot runs/quickstart-apo --out runs/quickstart-apo/curves.png
