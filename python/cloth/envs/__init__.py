"""Gymnasium tasks on the cloth simulator, registered on import:

- ``cloth/Flatten-v0``: spread a crumpled cloth (reward: covered area);
- ``cloth/Fold-v0``: fold a square in half (reward: minus the distance of
  the folded half to its mirror partners);
- ``cloth/Drop-v0``: lay a held cloth flat on a target.

``gymnasium.make("cloth/Fold-v0", render_mode="rgb_array")``; the keyword
arguments of ``ClothTaskEnv`` (``particles``, ``pickers``, ``observation``,
``threads``, ...) pass through ``make``. See docs/python.md."""

from gymnasium.envs.registration import register, registry

from .base import ClothTaskEnv, EnvState, StartsFileError
from .tasks import DropEnv, FlattenEnv, FoldEnv

__all__ = ["ClothTaskEnv", "DropEnv", "EnvState", "FlattenEnv", "FoldEnv", "StartsFileError"]

for _name, _cls, _steps in (("Flatten", "FlattenEnv", 100), ("Fold", "FoldEnv", 80), ("Drop", "DropEnv", 60)):
    if f"cloth/{_name}-v0" not in registry:
        register(id=f"cloth/{_name}-v0", entry_point=f"cloth.envs.tasks:{_cls}", max_episode_steps=_steps)
