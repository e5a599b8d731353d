"""Lets cloth/Drop-v0's cloth go from its pickers, at once or after a few
held env steps, and counts the episodes whose simulation step failed
(``info["error"]``): a check of a step size on the case that once blew
up, a cloth falling into a heap.

    python python/examples/drop_let_go.py [--seeds 10] [--dt-s 0.0333 --substeps 1] [--set KEY=VALUE]
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import cloth.envs  # noqa: F401  (registers the tasks)
import task_options

#: Env steps the pickers hold the cloth before letting go.
HELD = (0, 1, 3)


def episode(seed: int, held: int, **options) -> str | None:
    """One episode to its time limit; the error of a failed step, if any."""
    env = gym.make("cloth/Drop-v0", threads=1, **options)
    env.reset(seed=seed)
    hold = np.zeros(env.action_space.shape, dtype=np.float32)
    hold[3::4] = 1.0
    let_go = -hold
    k = 0
    while True:
        _, _, terminated, truncated, info = env.step(hold if k < held else let_go)
        if "error" in info:
            return info["error"]
        if terminated or truncated:
            return None
        k += 1


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, default=10)
    task_options.add_arguments(parser)
    args = parser.parse_args()
    options = task_options.kwargs(args)
    failed = 0
    for seed in range(args.seeds):
        for held in HELD:
            error = episode(seed, held, **options)
            if error is not None:
                failed += 1
                print(f"seed {seed}, held {held} steps: {error}")
    print(f"{failed} of {args.seeds * len(HELD)} episodes failed")


if __name__ == "__main__":
    main()
