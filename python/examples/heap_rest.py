"""How still the heap of ``fixtures/scenes/heap.toml`` lies at the end, over
the scene and ten neighbours (the step 1/88-1/92 s, 0.3-0.7 mm of
initial jitter, the solver's ``rel_tol`` halved and doubled): the
fastest particle and the largest kinetic energy over the last 0.3 s,
and the lowest particle at the end. A heap's path depends on every
rounding, so one run says little; the test
``a_cloth_dropped_in_a_heap_settles_without_ringing`` takes its limits
from this spread.

    python python/examples/heap_rest.py [--scene fixtures/scenes/heap.toml]
"""

from __future__ import annotations

import argparse

import numpy as np

import cloth

#: The overrides of each variant (dotted keys, as `cloth run --set`).
VARIANTS = [
    {},
    {"simulation.dt_s": 1 / 88},
    {"simulation.dt_s": 1 / 89},
    {"simulation.dt_s": 1 / 91},
    {"simulation.dt_s": 1 / 92},
    {"simulation.initial_jitter_m": 0.0003},
    {"simulation.initial_jitter_m": 0.0004},
    {"simulation.initial_jitter_m": 0.0006},
    {"simulation.initial_jitter_m": 0.0007},
    {"solver.rel_tol": 5e-4},
    {"solver.rel_tol": 2e-3},
]

#: The window at the end over which motion is measured, s.
WINDOW_S = 0.3


def measure(scene: cloth.Scene) -> tuple[float, float, float]:
    """Fastest particle (m/s) and largest kinetic energy (J) over the last
    ``WINDOW_S``, and the lowest particle at the end (m)."""
    sim = scene.simulation(threads=1)
    steps = round(scene.duration_s / scene.dt_s)
    window = round(WINDOW_S / scene.dt_s)
    masses = np.asarray(sim.masses)
    fastest, kinetic = 0.0, 0.0
    for step in range(steps):
        sim.step(1)
        if step + window >= steps:
            v = np.asarray(sim.velocities)
            fastest = max(fastest, float(np.linalg.norm(v, axis=1).max()))
            kinetic = max(kinetic, float(0.5 * (masses * (v * v).sum(axis=1)).sum()))
    return fastest, kinetic, float(np.asarray(sim.positions)[:, 2].min())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="fixtures/scenes/heap.toml")
    args = parser.parse_args()
    print("| variant | fastest, m/s | kinetic energy, J | lowest, mm |")
    print("|---|---|---|---|")
    for overrides in VARIANTS:
        name = ", ".join(f"{key} = {value:.6g}" for key, value in overrides.items()) or "the scene"
        fastest, kinetic, lowest = measure(cloth.Scene.from_toml(args.scene, overrides=overrides))
        print(f"| {name} | {fastest:.4f} | {kinetic:.2e} | {lowest * 1000:.2f} |", flush=True)


if __name__ == "__main__":
    main()
