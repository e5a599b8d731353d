"""Cloth simulation from Python: the Rust simulator's scenes, builder,
stepping and control, with NumPy arrays; coupled scenes with rapier bodies
and URDF rigs (`World`); grasps. See docs/python.md.

`cloth.envs` registers Gymnasium tasks (`cloth/Flatten-v0`, `cloth/Fold-v0`,
`cloth/Drop-v0`); `cloth.sweep` runs scenes over parameter grids on a Ray
cluster."""

from ._cloth import (  # noqa: F401
    Builder,
    ControlError,
    ModelError,
    Scene,
    SceneError,
    Simulation,
    Snapshot,
    SnapshotError,
    StepError,
    World,
    WorldSnapshot,
)

__all__ = [
    "Builder",
    "ControlError",
    "ModelError",
    "Scene",
    "SceneError",
    "Simulation",
    "Snapshot",
    "SnapshotError",
    "StepError",
    "World",
    "WorldSnapshot",
]
