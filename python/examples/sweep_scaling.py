"""Ray's overhead per task and the sweep's scaling on this machine's cores.

    python python/examples/sweep_scaling.py [TASKS] [DURATION_S]

Runs TASKS small cloths (the hang scene at 11 x 11 for DURATION_S
simulated seconds, 0.2 by default: about 10 ms each) as a sweep on a local Ray with 1 CPU and then 2, and prints
wall times, the tasks' own time, and the overhead per task: the sweep's
wall time times its CPUs, less the tasks' own time, over the tasks. Ray's
start-up is timed apart."""

import os
import sys
import tempfile
import time

import ray

from cloth import sweep

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
HANG = os.path.join(ROOT, "fixtures", "scenes", "hang.toml")


def main():
    tasks = int(sys.argv[1]) if len(sys.argv) > 1 else 16
    duration = float(sys.argv[2]) if len(sys.argv) > 2 else 0.2
    params = {
        "panels.0.particles": [[11, 11]],
        "pins.0.nodes": ["[[0, 10], [10, 10]]"],
        "material.tensile_stiffness_n_m": [100.0 + k for k in range(tasks)],
    }
    print(f"| CPUs | Ray start (s) | sweep wall (s) | tasks' own time (s) | overhead per task (ms) | speed-up |")
    print("|---|---|---|---|---|---|")
    base = None
    for cpus in (1, 2):
        t0 = time.perf_counter()
        ray.init(num_cpus=cpus, include_dashboard=False, log_to_driver=False)
        started = time.perf_counter() - t0
        # One warm-up sweep, so worker processes exist, then the timed one.
        with tempfile.TemporaryDirectory() as out:
            sweep.sweep([HANG], params, out, duration_s=duration)
        with tempfile.TemporaryDirectory() as out:
            t1 = time.perf_counter()
            rows = sweep.sweep([HANG], params, out, duration_s=duration)
            wall = time.perf_counter() - t1
        ray.shutdown()
        own = sum(r["wall_s"] for r in rows)
        base = base or wall
        print(f"| {cpus} | {started:.2f} | {wall:.3f} | {own:.3f} | {1000 * (wall * cpus - own) / tasks:.1f} | {base / wall:.2f} |")


if __name__ == "__main__":
    main()
