"""Fetching pinned files from PyPI for scripts/atari_assets.py and scripts/mujoco3_assets.py:
a download checked against its SHA-256, and an atomic, synced write."""
import hashlib
import os
import pathlib
import sys
import tempfile
import urllib.request


def fetch(url: str, sha256: str) -> bytes:
    """The bytes at `url`; exits with an error naming both digests if they are not `sha256`."""
    with urllib.request.urlopen(url, timeout=300) as response:
        data = response.read()
    digest = hashlib.sha256(data).hexdigest()
    if digest != sha256:
        sys.exit(f"error: {url} has SHA-256 {digest}, expected {sha256}")
    return data


def write_atomic(path: pathlib.Path, data: bytes, mode: int = 0o644) -> None:
    """Writes `data` to `path` through a synced temporary file in the same folder."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.NamedTemporaryFile(dir=path.parent, delete=False) as tmp:
        tmp.write(data)
        tmp.flush()
        os.fsync(tmp.fileno())
    os.chmod(tmp.name, mode)
    os.replace(tmp.name, path)
