#!/usr/bin/env python3
"""The reference for apo-atari's speed benchmark: frames per second of the Arcade Learning
Environment as ale-py 0.12.1 runs it, on one core.

* "ale-py act": ALEInterface.act in a loop, one frame per call (sticky actions 0.25): the
  ALE's C++ emulation plus one Python call per frame;
* "ale-py act, frame_skip 4": four frames per call inside the C++ (`frame_skip` = 4), the
  closest to a pure C++ loop that ale-py offers;
* "gymnasium v5 step": gymnasium.make("ALE/<Game>-v5", obs_type="ram") stepped from Python
  (frames counted as 4 per step).

Actions cycle through the minimal action set (t mod n); a game over resets the game.
Needs `pip install ale-py==0.12.1 gymnasium` (a development-time tool; apo does not use it).
Usage: python3 scripts/ale_py_speed.py [FRAMES] [LOOP] [GAME ...]
  LOOP: act, act4, gym (the three above, in that order) or all (default); default 200000
  frames, Pong and Breakout.
"""
import sys
import time

import ale_py
import gymnasium as gym


def snake(game):
    return "".join("_" + c.lower() if c.isupper() and i else c.lower() for i, c in enumerate(game))


def main():
    frames = int(sys.argv[1]) if len(sys.argv) > 1 else 200_000
    loop = sys.argv[2] if len(sys.argv) > 2 else "all"
    if loop not in ("act", "act4", "gym", "all"):
        sys.exit(f"LOOP {loop!r}: act, act4, gym or all")
    skips = {"act": (1,), "act4": (4,), "gym": (), "all": (1, 4)}[loop]
    games = sys.argv[3:] or ["Pong", "Breakout"]
    gym.register_envs(ale_py)
    print("game,loop,frames,seconds,frames_per_s")
    for game in games:
        for skip in skips:
            ale = ale_py.ALEInterface()
            ale.setLoggerMode(ale_py.LoggerMode.Error)
            ale.setInt("random_seed", 0)
            ale.setFloat("repeat_action_probability", 0.25)
            ale.setInt("max_num_frames_per_episode", 108_000)
            ale.setInt("frame_skip", skip)
            ale.loadROM(ale_py.roms.get_rom_path(snake(game)))
            actions = ale.getMinimalActionSet()
            n = len(actions)
            calls = frames // skip
            start = time.perf_counter()
            for t in range(calls):
                ale.act(actions[t % n])
                if ale.game_over():
                    ale.reset_game()
            seconds = time.perf_counter() - start
            label = "ale-py act" if skip == 1 else "ale-py act, frame_skip 4"
            print(f"{game},{label},{calls * skip},{seconds:.3f},{calls * skip / seconds:.0f}")
        if loop not in ("gym", "all"):
            continue
        env = gym.make(f"ALE/{game}-v5", obs_type="ram")
        env.reset(seed=0)
        n = env.action_space.n
        steps = frames // 4
        start = time.perf_counter()
        for t in range(steps):
            _, _, terminated, truncated, _ = env.step(t % n)
            if terminated or truncated:
                env.reset()
        seconds = time.perf_counter() - start
        print(f"{game},gymnasium v5 step,{steps * 4},{seconds:.3f},{steps * 4 / seconds:.0f}")


if __name__ == "__main__":
    main()
