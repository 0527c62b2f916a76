#!/usr/bin/env python3
"""Runs one algorithm of the paper's published code on a Gymnasium MuJoCo task, for
`scripts/paper-code-speed.sh`: the timing half that apo does not ship.

    python3 scripts/paper_code_run.py CHECKOUT ALGO --env Hopper --epochs 5 --steps 4000 --seed 0

CHECKOUT is the user's clone of the paper's repository. ALGO is apo, papo, trpo or ppo; its
`<algo>-mujoco/<algo>.py` is looked up under `rl_lib/<algo>/` and then `<algo>/`. The module's
training function (named like the algorithm) is called directly with `mujoco=ENV`, so any
Gymnasium `ENV-v4` task runs, not only the ones its command line offers. Arguments the
function does not take are left out (the published versions differ), and PyTorch runs on one
thread. Prints `wall_s=…` (the training call alone) on the last line. Exit status 2 on a bad
checkout or a missing Python package, naming it.
"""
import argparse
import importlib.util
import inspect
import os
import sys
import tempfile
import time


def fail(message):
    print(f"paper_code_run.py: {message}", file=sys.stderr)
    sys.exit(2)


def find_module(checkout, algo):
    tried = []
    for root in ("rl_lib", "."):
        path = os.path.join(checkout, root, algo, f"{algo}-mujoco", f"{algo}.py")
        tried.append(path)
        if os.path.isfile(path):
            return os.path.normpath(path), os.path.normpath(os.path.join(checkout, root))
    fail(f"no {algo}-mujoco/{algo}.py in the checkout {checkout!r}; looked for: " + ", ".join(tried))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("checkout", help="the paper's repository, cloned")
    parser.add_argument("algo", choices=["apo", "papo", "trpo", "ppo"])
    parser.add_argument("--env", default="Hopper", help="Gymnasium MuJoCo task without -v4")
    parser.add_argument("--epochs", type=int, default=5)
    parser.add_argument("--steps", type=int, default=4000, help="steps per epoch")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--omega1", type=float, default=0.005)
    parser.add_argument("--omega2", type=float, default=0.005)
    args = parser.parse_args()
    if args.epochs < 1 or args.steps < 1:
        fail(f"--epochs and --steps must be at least 1, got {args.epochs} and {args.steps}")
    if not os.path.isdir(args.checkout):
        fail(f"the checkout {args.checkout!r} is not a folder")
    path, lib_root = find_module(args.checkout, args.algo)

    for package in ("numpy", "torch", "gymnasium", "mujoco", "scipy", "mpi4py"):
        if importlib.util.find_spec(package) is None:
            fail(f"the Python package {package!r} is missing (pip install {package}); "
                 "the paper's code needs it")
    import gymnasium
    import torch

    torch.set_num_threads(1)
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    # the module imports its own `<algo>_core`, the repository's `utils` and `rl_envs`
    for folder in (os.path.dirname(path), lib_root,
                   os.path.join(args.checkout, "rl_envs"), args.checkout):
        sys.path.insert(0, os.path.abspath(folder))
    spec = importlib.util.spec_from_file_location(f"paper_{args.algo}", path)
    module = importlib.util.module_from_spec(spec)
    # its `-mujoco` scripts import gymnasium only under `__main__`
    module.gymnasium = gymnasium
    spec.loader.exec_module(module)
    train = getattr(module, args.algo, None)
    if train is None:
        fail(f"{path} has no function {args.algo}()")
    accepted = inspect.signature(train).parameters
    if "mujoco" not in accepted:
        fail(f"{path}: {args.algo}() takes no `mujoco` argument, so it cannot run {args.env}-v4")
    out = tempfile.mkdtemp(prefix="paper-code-")
    wanted = dict(env_fn=None, mujoco=args.env, seed=args.seed, epochs=args.epochs,
                  steps_per_epoch=args.steps, omega_1=args.omega1, omega_2=args.omega2,
                  logger_kwargs=dict(output_dir=out, exp_name=args.algo))
    kwargs = {k: v for k, v in wanted.items() if k in accepted}
    os.chdir(out)
    start = time.perf_counter()
    train(**kwargs)
    print(f"wall_s={time.perf_counter() - start:.3f}")


if __name__ == "__main__":
    main()
