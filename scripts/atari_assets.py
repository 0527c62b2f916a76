#!/usr/bin/env python3
"""Fetches what apo-atari needs from PyPI, checking SHA-256 checksums:

* the Arcade Learning Environment's C++ source, as published in the ale-py 0.12.1 source
  archive, into <repo>/.cache/ale_py-0.12.1.tar.gz (apo-atari's build.rs compiles it);
* the Atari ROMs shipped in the ale-py 0.12.1 wheel, into $APO_ROM_DIR or
  ~/.local/share/apo/roms (the ALE checks each ROM's MD5 when it loads it).

Files already present with the right checksum are not fetched again. Nothing else is written.
Usage: python3 scripts/atari_assets.py
"""
import hashlib
import io
import os
import pathlib
import zipfile

from pypi_fetch import fetch, write_atomic

FILES = "https://files.pythonhosted.org/packages"
SDIST = (
    f"{FILES}/3e/e8/e69da8a5fb5feafa9fffb32ed8c2b306b7571b77faf779f61e4eb53304ec/ale_py-0.12.1.tar.gz",
    "c503d574c5983e1063b451201ccb779d935919c0f6bf116fb0f4f8aa4c86d249",
)
WHEEL = (
    f"{FILES}/c6/96/6e461165f1256ac54a577e49d87dcd3a3f1c9280801376db78cd280d548f/"
    "ale_py-0.12.1-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl",
    "ba7429074ba6ffc1555f9a41bf00bee5d427b5080253101a8fe00412ca481033",
)


def main() -> None:
    repo = pathlib.Path(__file__).resolve().parent.parent
    archive = repo / ".cache" / "ale_py-0.12.1.tar.gz"
    if not (archive.exists() and hashlib.sha256(archive.read_bytes()).hexdigest() == SDIST[1]):
        print(f"== fetching the ALE source archive into {archive}")
        write_atomic(archive, fetch(*SDIST))
    rom_dir = pathlib.Path(
        os.environ.get("APO_ROM_DIR") or pathlib.Path.home() / ".local/share/apo/roms"
    )
    marker = rom_dir / ".ale-py-0.12.1"
    if not marker.exists():
        print(f"== installing the Atari ROMs of the ale-py 0.12.1 wheel into {rom_dir}")
        wheel = zipfile.ZipFile(io.BytesIO(fetch(*WHEEL)))
        count = 0
        for name in wheel.namelist():
            if name.startswith("ale_py/roms/") and name.endswith(".bin"):
                write_atomic(rom_dir / pathlib.PurePosixPath(name).name, wheel.read(name))
                count += 1
        write_atomic(marker, f"{count} ROMs from {WHEEL[0]}\n".encode())
        print(f"   {count} ROMs")


if __name__ == "__main__":
    main()
