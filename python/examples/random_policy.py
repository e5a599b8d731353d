"""A short reinforcement-learning loop on a cloth task with a random
policy: episodes of cloth/Flatten-v0 (or ``--task``), the return of each
and whether it succeeded. Replace ``policy`` with a learner's.

    python python/examples/random_policy.py [--task cloth/Fold-v0] [--episodes 2]
"""

from __future__ import annotations

import argparse

import gymnasium as gym
import numpy as np

import cloth.envs  # noqa: F401  (registers the tasks)


def policy(observation: np.ndarray, action_space: gym.Space) -> np.ndarray:
    """Any function of the observation; here, a random action."""
    return action_space.sample()


def run(task: str = "cloth/Flatten-v0", episodes: int = 2, seed: int = 0, max_steps: int | None = None):
    """Runs ``episodes`` episodes; returns ``(return, steps, success)`` of each."""
    env = gym.make(task, max_episode_steps=max_steps) if max_steps else gym.make(task)
    env.action_space.seed(seed)
    results = []
    for episode in range(episodes):
        observation, info = env.reset(seed=seed + episode)
        total, steps, done = 0.0, 0, False
        while not done:
            observation, reward, terminated, truncated, info = env.step(policy(observation, env.action_space))
            total, steps, done = total + reward, steps + 1, terminated or truncated
        results.append((total, steps, info["success"]))
    env.close()
    return results


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--task", default="cloth/Flatten-v0")
    parser.add_argument("--episodes", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    for k, (total, steps, success) in enumerate(run(args.task, args.episodes, args.seed)):
        print(f"episode {k}: return {total:.3f} over {steps} steps, success {success}")


if __name__ == "__main__":
    main()
