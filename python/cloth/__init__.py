"""Cloth simulation from Python: the Rust simulator's scenes, builder,
stepping and control, with NumPy arrays. See the README's "From Python".

`cloth.sweep` runs scenes over parameter grids on a Ray cluster."""

from ._cloth import (  # noqa: F401
    Builder,
    ControlError,
    ModelError,
    Scene,
    SceneError,
    Simulation,
    Snapshot,
    StepError,
)

__all__ = ["Builder", "ControlError", "ModelError", "Scene", "SceneError", "Simulation", "Snapshot", "StepError"]
