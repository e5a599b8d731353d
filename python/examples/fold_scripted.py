"""A scripted policy for cloth/Fold-v0: two pickers go to the two corners
of the cloth's left edge, grasp them, turn them over the middle onto the
right corners, let go and wait. Prints the fold distance
and whether the task counts it a success.

    python python/examples/fold_scripted.py [--seed 0] [--save fold.png] [--dt-s 0.0333 --substeps 1] [--set KEY=VALUE]
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import cloth.envs  # noqa: F401  (registers the tasks)
import task_options


def towards(env, goals, pick):
    """The action moving each picker as far towards ``goals`` (m) as one
    step allows, with ``pick`` as the pick flag."""
    move = np.clip((goals - env.unwrapped.picker_pos) / env.unwrapped.max_move_m, -1.0, 1.0)
    flag = np.full((len(goals), 1), 1.0 if pick else -1.0)
    return np.hstack([move, flag]).ravel().astype(np.float32)


def go(env, goals, pick, tolerance_m=1e-3, max_steps=40):
    """Steps until every picker is within ``tolerance_m`` of its goal."""
    for _ in range(max_steps):
        obs, reward, terminated, truncated, info = env.step(towards(env, goals, pick))
        if np.abs(env.unwrapped.picker_pos - goals).max() < tolerance_m or terminated or truncated:
            break
    return reward, info


def fold(env, seed=0, waypoints=30, slack=0.2):
    """Runs the scripted fold from a reset with ``seed``; returns the last
    reward and info. The corners turn about the middle column on a circle
    shrunk by up to ``slack`` at the top (the flap hangs slack, not taut),
    in ``waypoints`` steps, and are let go 1 cm above the far corners, two
    particle spacings short of them: the fold's bend takes up that much
    cloth (ending right above the far corners left the halves 3-5 cm
    apart; two spacings short, 0.6 cm)."""
    env.reset(seed=seed)
    task = env.unwrapped
    left, right = task.corner_positions()
    go(env, left, pick=False)
    middle = (left + right) / 2
    short = 2 * task.spacing_m
    for turn in np.linspace(0.0, np.pi, waypoints)[1:]:
        radius = (left - middle)[:, 0] * (1.0 - slack * np.sin(turn))
        goal = left.copy()
        goal[:, 0] = middle[:, 0] + radius * np.cos(turn) - short * turn / np.pi
        goal[:, 2] = left[:, 2] + np.abs(radius) * np.sin(turn) + 0.01 * turn / np.pi
        go(env, goal, pick=True, max_steps=3)
    for _ in range(15):
        _, reward, _, _, info = env.step(towards(env, task.picker_pos, pick=False))
    return reward, info


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--save", help="write the last frame as a PNG (needs matplotlib)")
    task_options.add_arguments(parser)
    args = parser.parse_args()
    options = task_options.kwargs(args)
    env = gym.make("cloth/Fold-v0", render_mode="rgb_array", **options)
    reward, info = fold(env, args.seed)
    print(f"fold distance {-reward:.4f} m, success {info['success']}")
    if args.save:
        import matplotlib.pyplot as plt

        plt.imsave(args.save, env.render())


if __name__ == "__main__":
    main()
