"""A robot picks a cloth up by a corner: the three-joint arm of
fixtures/scenes/arm-lift.toml (fixtures/rigs/arm.urdf) moves its gripper
link over a corner of the cloth lying on the floor, grasps the particles
there with the link, lifts the corner 0.75 m and holds it. Prints the
gripper's load against the cloth's weight.

    python python/examples/robot_lift.py [--scene fixtures/scenes/arm-lift.toml]
"""

from __future__ import annotations

import argparse
import os

import numpy as np

import cloth

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
SCENE = os.path.join(ROOT, "fixtures", "scenes", "arm-lift.toml")
#: The arm's shoulder above its base and its two link lengths, m (arm.urdf).
SHOULDER_Z, UPPER, FORE = 0.4, 0.4, 0.4


def inverse_kinematics(base, target):
    """Joint angles (rad) putting the gripper's origin at ``target`` (m)
    for the arm standing at ``base``: the turret faces the target, the
    two links reach it elbow up."""
    d = np.asarray(target, dtype=float) - np.asarray(base, dtype=float)
    yaw = np.arctan2(d[1], d[0])
    r, z = np.hypot(d[0], d[1]), d[2] - SHOULDER_Z
    cos_bend = np.clip((r * r + z * z - UPPER**2 - FORE**2) / (2 * UPPER * FORE), -1.0, 1.0)
    bend = np.arccos(cos_bend)
    rise = np.arctan2(z, r) + np.arctan2(FORE * np.sin(bend), UPPER + FORE * np.cos(bend))
    # At rest the arm stands up and positive pitch leans a link forward:
    # the shoulder leans by a right angle less the upper arm's rise, the
    # elbow by the bend.
    return {"yaw": float(yaw), "shoulder": float(np.pi / 2 - rise), "elbow": float(bend)}


def move(world, base, start, end, seconds):
    """Moves the gripper on a straight line from ``start`` to ``end`` (m)."""
    steps = max(1, round(seconds / world.dt_s))
    for k in range(1, steps + 1):
        world.set_joint_positions(inverse_kinematics(base, start + (end - start) * k / steps))
        world.step()


def lift(scene=SCENE, hold_s=3.0):
    """Runs the pick-up; returns the world, the grasp id and the gripper's
    pull (N) averaged over the last 1.5 s of the hold (about one swing of
    the hanging cloth, whose pull still swings by some 10%)."""
    world = cloth.World.from_toml(scene)
    world.step()
    base = world.link_pose("base")[0]
    x = world.positions
    corner = x[np.argmin(x[:, 0] + x[:, 1])]  # the corner at the smallest x + y
    rest = world.link_pose("gripper")[0]
    above = corner + [0.0, 0.0, 0.05]
    move(world, base, rest, above, 0.5)
    move(world, base, above, corner, 0.2)
    grasp = world.grasp(list(world.link_pose("gripper")[0]), 0.02, body="gripper")
    high = np.array([0.0, 0.0, 0.75])
    move(world, base, corner, high, 1.5)
    pulls = []
    for _ in range(round(hold_s / world.dt_s)):
        world.step()
        pulls.append(world.grasp_force(grasp))
    return world, grasp, np.mean(pulls[-round(1.5 / world.dt_s) :], axis=0)


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--scene", default=SCENE)
    args = parser.parse_args()
    world, grasp, pull = lift(args.scene)
    weight = world.masses.sum() * 9.81
    print(f"gripper holds {len(world.grasp_particles(grasp))} particles, pulled by {pull} N; cloth weight {weight:.4f} N")
    print(f"lowest particle {world.positions[:, 2].min():.3f} m above the floor")


if __name__ == "__main__":
    main()
