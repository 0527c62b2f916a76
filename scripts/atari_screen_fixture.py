#!/usr/bin/env python3
"""Records the fixture of apo-atari's screen test (crates/apo-atari/tests/screen.rs): the RGB
screen Gymnasium + ale-py 0.12.1 render for Pong and Breakout v5 after `reset(seed=7)` and after
50 and 100 steps of action `(7·t) mod n`, as two checksums of the 210 × 160 × 3 bytes:
their sum, and the sum of byte i times (i mod 65521) + 1.

    python3 -m venv /tmp/ale && /tmp/ale/bin/pip install ale-py==0.12.1 gymnasium numpy
    /tmp/ale/bin/python scripts/atari_screen_fixture.py crates/apo-atari/tests/fixtures/v5_screen_seed7.json
"""

import json
import sys

import ale_py
import gymnasium as gym
import numpy as np


def checksums(img):
    b = np.ascontiguousarray(img, dtype=np.uint8).reshape(-1).astype(np.int64)
    weights = np.arange(b.size, dtype=np.int64) % 65521 + 1
    return {"sum": int(b.sum()), "weighted": int((b * weights).sum())}


def main():
    gym.register_envs(ale_py)
    out = {}
    for game in ["Pong", "Breakout"]:
        env = gym.make(f"ALE/{game}-v5", obs_type="ram", render_mode="rgb_array")
        env.reset(seed=7)
        n = env.action_space.n
        first = env.render()
        rec = {"seed": 7, "height": first.shape[0], "width": first.shape[1], "0": checksums(first)}
        for t in range(100):
            env.step((7 * t) % n)
            if t + 1 in (50, 100):
                rec[str(t + 1)] = checksums(env.render())
        out[game] = rec
    # the ALE prints its banner on stdout: the fixture goes to its own file
    with open(sys.argv[1], "w") as f:
        f.write(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
