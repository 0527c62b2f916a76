#!/usr/bin/env python3
"""Fetches MuJoCo 3.17.0 for apo's opt-in `mujoco3` physics from PyPI, checking its SHA-256:

the `mujoco` 3.17.0 wheel (CPython 3.11, manylinux x86-64) ships the C library as
`mujoco/libmujoco.so.3.17.0`; it is unpacked into <repo>/.cache/mujoco-3.17.0/lib/ with the link
`libmujoco.so -> libmujoco.so.3.17.0` that the linker looks for. `mujoco-rs` links it when
MUJOCO_DYNAMIC_LINK_DIR names that folder, and programs find it at run time through
LD_LIBRARY_PATH (scripts/test.sh sets both) or the run path that apo-cli's build script records.

A library already present is not fetched again. Nothing else is written.
Usage: python3 scripts/mujoco3_assets.py   (prints the folder on its last line)
"""
import io
import os
import pathlib
import sys
import zipfile

from pypi_fetch import fetch, write_atomic

VERSION = "3.17.0"
WHEEL = (
    "https://files.pythonhosted.org/packages/90/b8/"
    "1d1ccbee32bf9ffc26fe2f62207c4bae173c8791ee0da437c821c12a5c26/"
    f"mujoco-{VERSION}-cp311-cp311-manylinux_2_27_x86_64.manylinux_2_28_x86_64.whl",
    "d66928d86a2d1b601bbaa4dc11db50214d17d5301bb8afd84721313b67ff0874",
)
LIBRARY = f"libmujoco.so.{VERSION}"


def main() -> None:
    repo = pathlib.Path(__file__).resolve().parent.parent
    lib_dir = repo / ".cache" / f"mujoco-{VERSION}" / "lib"
    library = lib_dir / LIBRARY
    if not library.exists():
        if sys.platform != "linux" or os.uname().machine != "x86_64":
            sys.exit("error: the pinned MuJoCo 3 wheel is for Linux x86-64 only")
        print(f"== fetching MuJoCo {VERSION} (the mujoco wheel from PyPI) into {lib_dir}")
        wheel = zipfile.ZipFile(io.BytesIO(fetch(*WHEEL)))
        write_atomic(library, wheel.read(f"mujoco/{LIBRARY}"), 0o755)
    link = lib_dir / "libmujoco.so"
    if not link.is_symlink():
        if link.exists():
            sys.exit(f"error: {link} exists and is not the link this script makes; move it away")
        link.symlink_to(LIBRARY)
    print(lib_dir)


if __name__ == "__main__":
    main()
