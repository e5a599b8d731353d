"""Sweeps on Ray (local, 2 CPUs): every parameter set runs as a task and
lands in the table, a failing one with its error; the physics across the
grid is right (a stiffer cloth stretches less)."""

import csv
import subprocess
import json
import os

import pytest

if "CI" in os.environ:
    import ray  # noqa: F401  (.ci/run installs it: a skipped check would pass anything)
else:
    ray = pytest.importorskip("ray")

from cloth import sweep

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
HANG = os.path.join(ROOT, "fixtures", "scenes", "hang.toml")


def test_a_sweep_gathers_every_run_and_reports_failures(tmp_path):
    params = {
        "panels.0.particles": [[11, 11]],
        "pins.0.nodes": ["[[0, 10], [10, 10]]"],
        "material.tensile_stiffness_n_m": [50.0, 400.0, -1.0],
    }
    rows = sweep.sweep([HANG], params, str(tmp_path), duration_s=0.5, retries=1, num_cpus=2)
    assert [r["material.tensile_stiffness_n_m"] for r in rows] == [50.0, 400.0, -1.0]
    soft, stiff, bad = rows
    assert soft["error"] == "" and stiff["error"] == ""
    assert soft["peak_stretch_ratio"] > stiff["peak_stretch_ratio"] > 1.0
    assert "SceneError" in bad["error"] and "tensile_stiffness_n_m" in bad["error"], bad["error"]
    with open(tmp_path / "results.csv") as f:
        table = list(csv.DictReader(f))
    assert len(table) == 3 and table[2]["error"] == bad["error"]
    with open(tmp_path / "hang-0000" / "summary.json") as f:
        assert json.load(f)["steps"] == 45


def test_the_grid_is_the_cartesian_product_in_order():
    assert sweep.grid({"a": [1, 2], "b": ["x", "y"]}) == [
        {"a": 1, "b": "x"},
        {"a": 1, "b": "y"},
        {"a": 2, "b": "x"},
        {"a": 2, "b": "y"},
    ]


def test_command_line_values_split_at_top_level_commas():
    assert sweep._values("100,2.5,[11,11],'a,b',{ kind = \"fixed\" }") == [100, 2.5, "[11,11]", "'a,b'", '{ kind = "fixed" }']


def test_64_drapes_on_ray_are_the_cloth_runs(tmp_path):
    """A sweep of 64 drapes (4 stiffnesses x 4 dampings x 4 frictions) on
    Ray gives every parameter set the same final stretch and lowest point
    as `cloth run` with the same --set overrides, to the bit."""
    exe = os.path.join(ROOT, "target", "release", "cloth")
    if not os.path.exists(exe):
        assert "CI" not in os.environ, "cargo build --release -p cloth-tools first"
        pytest.skip("no target/release/cloth")
    drape = os.path.join(ROOT, "fixtures", "scenes", "drape-sphere.toml")
    params = {
        "panels.0.particles": [[11, 11]],
        "simulation.duration_s": [0.3],
        "material.tensile_stiffness_n_m": [100.0, 200.0, 400.0, 800.0],
        "material.damping_n_s_m": [0.01, 0.02, 0.04, 0.08],
        "colliders.0.friction": [0.0, 0.1, 0.2, 0.4],
    }
    rows = sweep.sweep([drape], params, str(tmp_path / "sweep"), num_cpus=2)
    assert len(rows) == 64 and not [r for r in rows if r["error"]]
    for k, (row, overrides) in enumerate(zip(rows, sweep.grid(params))):
        out = tmp_path / f"run-{k}"
        sets = [a for key, v in overrides.items() for a in ("--set", f"{key}={json.dumps(v)}")]
        subprocess.run([exe, "run", drape, "--out", str(out), "--quiet", *sets], check=True)
        with open(out / "summary.json") as f:
            summary = json.load(f)
        got = (row["max_stretch_ratio"], row["min_z_m"])
        assert got == (summary["max_stretch_ratio"], summary["min_z_m"]), (overrides, got, summary)
