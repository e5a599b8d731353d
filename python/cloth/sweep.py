"""Parameter sweeps on a Ray cluster: scenes times parameter grids, one Ray
task a run.

Each task reads its scene with its overrides, steps it for the scene's
duration (or ``duration_s``) and writes ``summary.json`` (and, with
``frames_every``, ``frames.npz`` of positions) into a directory of its
own. The rows gather into one CSV table, a row a parameter set; a run
that raises is retried, then reported in the table by its parameters
with the error, never stopping the sweep.

From the command line::

    python -m cloth.sweep fixtures/scenes/hang.toml \\
        --param material.tensile_stiffness_n_m=100,200,400 \\
        --param material.damping_n_s_m=0.01,0.05 --out sweep-out

Ray starts locally unless ``--address`` names a cluster (``auto`` for the
one this machine is part of, or ``ray://head:10001``); the tasks then run
on its workers, which need this package installed and the scene files at
the same paths.
"""

import argparse
import csv
import itertools
import json
import os
import time

import numpy as np

import cloth


def grid(params):
    """The cartesian product of ``{key: [values]}`` as a list of dicts, in
    the order the keys and values are given."""
    keys = list(params)
    return [dict(zip(keys, combo)) for combo in itertools.product(*(params[k] for k in keys))]


def run_case(scene, overrides, out_dir, duration_s=None, frames_every=0):
    """Runs one scene with ``overrides`` ({dotted key: value}) and writes
    ``summary.json`` (and ``frames.npz``) into ``out_dir``; returns the
    summary. Raises ``cloth.SceneError`` or ``cloth.StepError`` when the
    run cannot be built or a step fails."""
    os.makedirs(out_dir, exist_ok=True)
    loaded = cloth.Scene.from_toml(scene, overrides)
    sim = loaded.simulation()
    steps = int(round((duration_s if duration_s is not None else loaded.duration_s) / loaded.dt_s))
    frames = []
    start = time.perf_counter()
    peak = sim.max_stretch()
    for n in range(steps):
        sim.step()
        peak = max(peak, sim.max_stretch())
        if frames_every and (n + 1) % frames_every == 0:
            frames.append(sim.positions)
    wall = time.perf_counter() - start
    x = sim.positions
    summary = {
        "scene": os.path.abspath(scene),
        "overrides": {k: v for k, v in overrides.items()},
        "steps": steps,
        "time_s": sim.time_s,
        "wall_s": wall,
        "particles": sim.particle_count,
        "max_stretch_ratio": sim.max_stretch(),
        "peak_stretch_ratio": peak,
        "min_z_m": float(x[:, 2].min()),
        "max_speed_m_s": float(np.linalg.norm(sim.velocities, axis=1).max()),
    }
    with open(os.path.join(out_dir, "summary.json"), "w") as f:
        json.dump(summary, f, indent=2)
    if frames:
        np.savez_compressed(os.path.join(out_dir, "frames.npz"), positions=np.stack(frames))
    return summary


def _case_dir(out, scene, index):
    return os.path.join(out, f"{os.path.splitext(os.path.basename(scene))[0]}-{index:04d}")


def sweep(scenes, params, out, *, duration_s=None, frames_every=0, retries=2, address=None, num_cpus=None):
    """Runs every scene in ``scenes`` with every parameter set of
    ``grid(params)`` as Ray tasks, retried ``retries`` times when they
    raise. Writes ``out/results.csv`` (a row a run: scene, its
    parameters, the summary's numbers, ``error``) and returns the rows.
    Starts Ray (locally, with ``num_cpus``, unless ``address`` is given)
    when it is not running yet."""
    import ray

    if not ray.is_initialized():
        ray.init(address=address, num_cpus=num_cpus, include_dashboard=False, log_to_driver=False)
    task = ray.remote(num_cpus=1, max_retries=retries, retry_exceptions=True)(run_case)
    cases = [(scene, overrides) for scene in scenes for overrides in grid(params)]
    refs = [
        task.remote(scene, overrides, _case_dir(out, scene, k), duration_s, frames_every)
        for k, (scene, overrides) in enumerate(cases)
    ]
    rows = []
    for (scene, overrides), ref in zip(cases, refs):
        row = {"scene": scene, **{k: json.dumps(v) if not isinstance(v, (int, float, str)) else v for k, v in overrides.items()}}
        try:
            summary = ray.get(ref)
            row.update({k: v for k, v in summary.items() if k not in ("scene", "overrides")})
            row["error"] = ""
        except Exception as e:  # a run that failed every try: reported, not fatal
            cause = getattr(e, "cause", None) or e
            row["error"] = " ".join(f"{type(cause).__name__}: {cause}".split())
        rows.append(row)
    os.makedirs(out, exist_ok=True)
    columns = []
    for row in rows:
        columns += [c for c in row if c not in columns]
    with open(os.path.join(out, "results.csv"), "w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=columns)
        writer.writeheader()
        writer.writerows(rows)
    return rows


def _split_top_level(text):
    """``text`` split at commas outside brackets, braces and quotes, so a
    value may be a TOML array or table (``[11,11],[21,21]``)."""
    items, depth, quote, start = [], 0, None, 0
    for k, ch in enumerate(text):
        if quote:
            quote = None if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "[{":
            depth += 1
        elif ch in "]}":
            depth -= 1
        elif ch == "," and depth == 0:
            items.append(text[start:k])
            start = k + 1
    items.append(text[start:])
    return items


def _values(text):
    """``a,b,c`` (split at top-level commas) as numbers where they parse,
    else strings (TOML text)."""
    out = []
    for item in _split_top_level(text):
        try:
            out.append(int(item))
        except ValueError:
            try:
                out.append(float(item))
            except ValueError:
                out.append(item)
    return out


def main(argv=None):
    p = argparse.ArgumentParser(prog="python -m cloth.sweep", description=__doc__.split("\n\n")[0])
    p.add_argument("scenes", nargs="+", help="scene TOML files")
    p.add_argument("--param", action="append", default=[], metavar="KEY=V1,V2", help="a dotted key and its values")
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--duration", type=float, help="simulated time per run, s (default: each scene's)")
    p.add_argument("--frames-every", type=int, default=0, help="save positions every N steps")
    p.add_argument("--retries", type=int, default=2)
    p.add_argument("--address", help="a Ray cluster to run on (default: start Ray here)")
    p.add_argument("--num-cpus", type=int, help="CPUs of a local Ray")
    args = p.parse_args(argv)
    params = {}
    for spec in args.param:
        key, sep, values = spec.partition("=")
        if not sep:
            p.error(f"--param {spec}: expected KEY=V1,V2,...")
        params[key] = _values(values)
    rows = sweep(
        args.scenes,
        params,
        args.out,
        duration_s=args.duration,
        frames_every=args.frames_every,
        retries=args.retries,
        address=args.address,
        num_cpus=args.num_cpus,
    )
    failed = [r for r in rows if r["error"]]
    print(f"{len(rows)} runs, {len(failed)} failed: {os.path.join(args.out, 'results.csv')}")
    for r in failed:
        print(f"failed: {r}")
    return 1 if failed else 0


if __name__ == "__main__":
    raise SystemExit(main())
