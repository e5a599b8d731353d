"""Env steps per second, per core, of the cloth tasks: each task on one
thread (the simulation's pool and NumPy's), 25 x 25 particles, a random
policy and an idle one (pickers still, nothing held), the median of
``--repeat`` runs of ``--steps`` steps, the resets of the episodes that
end among them included; then what a reset takes, what taking a state
mid-episode and setting it again take and, with
``--start-states N``, what saving the ``N`` starts to a file and making
an env from it take. Prints Markdown tables.

    python python/examples/env_speed.py [--steps 200] [--repeat 3] [--dt-s 0.0333 --substeps 1] [--set KEY=VALUE]
        [--start-states N]
"""

from __future__ import annotations

import os

# One core: NumPy's BLAS threads would spin beside the simulation's.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import argparse  # noqa: E402
import statistics  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402

import gymnasium as gym  # noqa: E402
import numpy as np  # noqa: E402

import cloth.envs  # noqa: E402,F401
import task_options  # noqa: E402

TASKS = ["cloth/Flatten-v0", "cloth/Fold-v0", "cloth/Drop-v0"]


def made(task: str, **options):
    """The task's env on one thread; with start states, all of them made
    first (not timed), so that the resets timed are the restores a long
    run sees. ``options``: ``gym.make`` keywords (``dt_s``, ``substeps``,
    ``overrides``, ``start_states``)."""
    env = gym.make(task, threads=1, **options)
    while env.unwrapped.made_starts < (env.unwrapped.start_states or 0):
        env.reset()
    return env


def rate(task: str, policy: str, steps: int, seed: int, **options) -> float:
    """Env steps per second over ``steps`` steps after a reset (not timed)."""
    env = made(task, **options)
    env.reset(seed=seed)
    env.action_space.seed(seed)
    idle = np.zeros(env.action_space.shape, dtype=np.float32)
    idle[3::4] = -1.0
    start = time.perf_counter()
    for _ in range(steps):
        action = env.action_space.sample() if policy == "random" else idle
        _, _, terminated, truncated, _ = env.step(action)
        if terminated or truncated:
            env.reset()
    return steps / (time.perf_counter() - start)


def starts_file(task: str, repeat: int, **options):
    """Seconds to make and save the task's start states, the file's bytes,
    and milliseconds to make an env from the file (``repeat`` runs) and
    one without start states."""
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "starts.npz")
        start = time.perf_counter()
        gym.make(task, threads=1, **options).unwrapped.save_starts(path)
        saved = time.perf_counter() - start
        read = []
        for _ in range(repeat):
            start = time.perf_counter()
            gym.make(task, threads=1, **{**options, "start_states": path})
            read.append(1e3 * (time.perf_counter() - start))
        plain = {key: value for key, value in options.items() if key != "start_states"}
        start = time.perf_counter()
        gym.make(task, threads=1, **plain)
        return saved, os.path.getsize(path), read, 1e3 * (time.perf_counter() - start)


def state_costs(task: str, runs: int, **options):
    """Milliseconds to take a state mid-episode (five env steps of random
    moves, picking) and to set it again: in the same env (``runs`` of
    each, an env step between) and in a new one."""
    env = made(task, **options).unwrapped
    env.reset(seed=0)
    env.action_space.seed(0)
    for _ in range(5):
        action = env.action_space.sample()
        action[3::4] = 1.0
        env.step(action)
    taken, put = [], []
    for _ in range(runs):
        start = time.perf_counter()
        state = env.get_state()
        taken.append(1e3 * (time.perf_counter() - start))
        env.step(env.action_space.sample())
        start = time.perf_counter()
        env.set_state(state)
        put.append(1e3 * (time.perf_counter() - start))
    other = gym.make(task, threads=1, **options).unwrapped
    start = time.perf_counter()
    other.set_state(state)
    return taken, put, 1e3 * (time.perf_counter() - start)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--steps", type=int, default=200)
    parser.add_argument("--repeat", type=int, default=3)
    task_options.add_arguments(parser)
    args = parser.parse_args()
    options = task_options.kwargs(args)
    print("| task | policy | env steps/s (median) | runs |")
    print("|---|---|---|---|")
    for task in TASKS:
        for policy in ("random", "idle"):
            runs = [rate(task, policy, args.steps, seed, **options) for seed in range(args.repeat)]
            shown = ", ".join(f"{r:.0f}" for r in runs)
            print(f"| {task} | {policy} | {statistics.median(runs):.0f} | {shown} |")
    print("\n| task | reset, ms (median) | runs |")
    print("|---|---|---|")
    for task in TASKS:
        env = made(task, **options)
        runs = []
        for seed in range(args.repeat):
            start = time.perf_counter()
            env.reset(seed=seed)
            runs.append(1e3 * (time.perf_counter() - start))
        shown = ", ".join(f"{r:.1f}" for r in runs)
        print(f"| {task} | {statistics.median(runs):.1f} | {shown} |")
    print("\n| task | get_state, ms (median) | set_state, ms (median) | set_state in a new env, ms |")
    print("|---|---|---|---|")
    for task in TASKS:
        taken, put, new = state_costs(task, 10 * args.repeat, **options)
        print(f"| {task} | {statistics.median(taken):.2f} | {statistics.median(put):.2f} | {new:.1f} |")
    if options.get("start_states"):
        print("\n| task | make and save the starts, s | file, kB | env from the file, ms (median) | runs", end="")
        print(" | env without, ms |\n|---|---|---|---|---|---|")
        for task in TASKS:
            saved, size, read, plain = starts_file(task, args.repeat, **options)
            shown = ", ".join(f"{r:.1f}" for r in read)
            median = statistics.median(read)
            print(f"| {task} | {saved:.2f} | {size / 1e3:.0f} | {median:.1f} | {shown} | {plain:.1f} |")


if __name__ == "__main__":
    main()
