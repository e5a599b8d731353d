"""The three cloth tasks: Flatten, Fold and Drop (after SoftGym's
ClothFlatten, ClothFold and ClothDrop)."""

from __future__ import annotations

import numpy as np

from .base import ClothTaskEnv
from .raster import covered_area


class FlattenEnv(ClothTaskEnv):
    """Spread a crumpled cloth. Each episode crumples the flat cloth by
    lifting a random particle 30-45 cm, moving it up to 10 cm sideways and
    dropping it. Reward: the area the cloth covers on the floor over the
    flat cloth's (1 when flat; folded layers count once). Success at 0.9."""

    SUCCESS_COVERAGE = 0.9

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        i, j = np.meshgrid(np.arange(self.n), np.arange(self.n))
        flat = np.stack([i.ravel() * self.spacing_m, j.ravel() * self.spacing_m, np.zeros(self.n * self.n)], axis=1)
        sim = self._scene.simulation(threads=self.threads)
        self._triangles = sim.triangles
        self._flat_area = covered_area(flat, self._triangles)

    def setup(self):
        rng = self.np_random
        particle = int(rng.integers(self.n * self.n))
        start = self.sim.positions[particle]
        grasp = self.sim.grasp(list(start), 0.5 * self.spacing_m)
        top = start + np.array([*rng.uniform(-0.1, 0.1, size=2), rng.uniform(0.3, 0.45)])
        lift = self.steps_for(0.27)
        for k in range(1, lift + 1):
            self.sim.move_grasp(grasp, list(start + (top - start) * k / lift))
            self.sim.step(1)
        self.settle(0.27)
        self.sim.release(grasp)
        self.settle(0.5)
        self.picker_pos = np.array([[-0.1, 0.0, 0.1], [0.1, 0.0, 0.1]])[: self.pickers]

    def coverage(self) -> float:
        """Covered floor area over the flat cloth's."""
        return covered_area(self.sim.positions, self._triangles) / self._flat_area

    def measure(self):
        coverage = self.coverage()
        return coverage, coverage >= self.SUCCESS_COVERAGE


class FoldEnv(ClothTaskEnv):
    """Fold a flat square in half along its middle column, the half at
    small x onto the other. Reward: minus the mean distance (m) of the
    folded half's particles to their mirror partners, plus the mean
    distance the other half moved from where it lay. Success when that sum
    is under 2 cm, a twentieth of the side. Each episode shifts the cloth
    by up to 3 cm."""

    SUCCESS_DISTANCE_M = 0.02
    START_ATTRIBUTES = ("_shift", "_fixed_start")

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        n = self.n
        i, j = np.meshgrid(np.arange(n), np.arange(n))
        folded = i < n // 2
        self._moving = (j * n + i)[folded]
        self._partner = (j * n + (n - 1 - i))[folded]
        self._fixed = (j * n + i)[i >= n // 2]

    def cloth_layout(self):
        (x, y, z), v_axis = super().cloth_layout()
        shift = getattr(self, "_shift", (0.0, 0.0))
        return (x + shift[0], y + shift[1], z), v_axis

    def episode_scene(self):
        # The whole cloth shifted: the pickers must find it.
        self._shift = self.np_random.uniform(-0.03, 0.03, size=2)
        return self.build_scene()

    def setup(self):
        self.settle(self.dt_s)
        self._fixed_start = self.sim.positions[self._fixed]
        self.picker_pos = np.array([[0.0, -0.1, 0.1], [0.0, 0.1, 0.1]])[: self.pickers]

    def fold_distance(self) -> float:
        x = self.sim.positions
        pair = np.linalg.norm(x[self._moving] - x[self._partner], axis=1).mean()
        drift = np.linalg.norm(x[self._fixed] - self._fixed_start, axis=1).mean()
        return float(pair + drift)

    def measure(self):
        distance = self.fold_distance()
        return -distance, distance < self.SUCCESS_DISTANCE_M

    def corner_positions(self):
        """The folded half's two outer corners and their partners, m."""
        x, n = self.sim.positions, self.n - 1
        return x[[self.index(0, 0), self.index(0, n)]], x[[self.index(n, 0), self.index(n, n)]]


class DropEnv(ClothTaskEnv):
    """Lay a cloth held by two pickers at its top corners, hanging with its
    lower edge 10 cm above the floor, flat on a target: the cloth's own
    square, its held edge at the far side (+y), placed up to 5 cm off the
    point under the hanging cloth. Reward: minus the mean distance (m) of
    the particles to their places on the target. Success under 3 cm."""

    SUCCESS_DISTANCE_M = 0.03
    LOWER_EDGE_M = 0.1
    START_ATTRIBUTES = ("_target",)

    def cloth_layout(self):
        half = self.side_m / 2
        return (-half, 0.0, self.LOWER_EDGE_M + self.side_m), (0.0, 0.0, -1.0)

    def setup(self):
        n, s, half = self.n, self.spacing_m, self.side_m / 2
        offset = self.np_random.uniform(-0.05, 0.05, size=2)
        i, j = np.meshgrid(np.arange(n), np.arange(n))
        self._target = np.stack(
            [
                (-half + i * s + offset[0]).ravel(),
                (offset[1] + self.side_m - j * s).ravel(),
                np.full(n * n, self.REST_HEIGHT_M),
            ],
            axis=1,
        )
        x = self.sim.positions
        top = [self.index(0, 0), self.index(n - 1, 0)]
        # The top edge starts at the box's ceiling, the initial jitter
        # lifting some corners above it: the pickers start inside the box
        # (the grasp keeps each particle's offset, so nothing moves).
        self.picker_pos = np.clip(x[top][: self.pickers], *self.BOUNDS)
        for k in range(self.pickers):
            self.move_picker(k, self.picker_pos[k], True)
        self.settle(0.5)

    def distance(self) -> float:
        return float(np.linalg.norm(self.sim.positions - self._target, axis=1).mean())

    def measure(self):
        distance = self.distance()
        return -distance, distance < self.SUCCESS_DISTANCE_M

    def target_points(self):
        return self._target
