"""FMPy (0.3.32) checks of the cloth FMU, run by tools/tests/fmu.rs.

Usage: python fmpy_check.py CLOTH_EXE WORKDIR

Builds FMUs from three fixtures with `cloth fmu build` (the hanging cloth
with its pins as inputs, the flag with its wind as an input, the drape on
an OBJ pillow) and checks,
with FMPy as the independent importer:
- validate_fmu reports no problem;
- simulate_fmu with an unshifted input signal matches `cloth run` of the
  same scene with the same motion as keyframes (lowest point and worst
  stretch, to 1e-9 relative: the same computation, the host's rounded
  steps aside); with the pins' rates in the signal from the first step,
  with values only from the second (the first is held);
- stepped at output intervals of 1/30, 0.1 and 1 s the drape is where
  the 1/90 s run is at their common times (substeps inside the FMU);
- a state got, stepped, restored and stepped again gives identical
  outputs, and so does the state through serialised bytes;
- invalid call sequences (a get before initialisation, a negative step)
  raise fmi3Error and log a message.
Prints 'fmu: N passed, M failed' and exits non-zero on any failure.
"""

import json
import os
import subprocess
import sys

import numpy as np
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi3 import FMU3Slave
from fmpy.validation import validate_fmu

CLOTH, WORK = sys.argv[1], sys.argv[2]
ROOT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..")
SCENES = os.path.join(ROOT, "fixtures", "scenes")
H = 1.0 / 90.0
T = 30 * H  # 30 steps

results = []


def check(name, ok, detail=""):
    results.append((name, bool(ok)))
    print(f"{'ok  ' if ok else 'FAIL'} {name}: {detail}", flush=True)


def cloth(*args):
    out = subprocess.run([CLOTH, *args], capture_output=True, text=True)
    if out.returncode != 0:
        raise RuntimeError(f"cloth {' '.join(args)}: {out.stderr}")
    return out.stdout


def sets(overrides):
    return [a for o in overrides for a in ("--set", o)]


def run_summary(scene, overrides, name):
    out = os.path.join(WORK, f"run-{name}")
    cloth("run", os.path.join(SCENES, scene), "--out", out, "--quiet", *sets(overrides))
    with open(os.path.join(out, "summary.json")) as f:
        return json.load(f)


COMMON = [f"simulation.duration_s={T!r}", "solver.rel_tol=1e-8"]
# The hanging cloth, 21 x 21, its two pinned corners moving 0.3 m/s along x.
HANG = ["panels.0.particles=[21, 21]", "pins.0.nodes=[[0, 20], [20, 20]]", *COMMON]
HANG_FMU = [*HANG, 'pins.0.motion={ kind = "external" }']
SPEED = 0.3
HANG_RUN = [*HANG, 'pins.0.motion={ kind = "fixed" }']
# The flag (21 x 14), its wind rising from 2 to 8 m/s along x.
FLAG = ["panels.0.particles=[21, 14]", *COMMON]
FLAG_FMU = [*FLAG, 'wind.profile={ kind = "external" }']
FLAG_RUN = [
    *FLAG,
    f'wind.profile={{ kind = "keyframes", times_s = [0.0, {T!r}], velocities_m_s = [[2.0, 0.5, 0.0], [8.0, 0.5, 0.0]] }}',
]


def build(scene, overrides, name):
    path = os.path.join(WORK, f"{name}.fmu")
    cloth("fmu", "build", os.path.join(SCENES, scene), "--out", path, *sets(overrides))
    return path


def compare(name, result, summary):
    got = (result["lowest_z"][-1], result["max_stretch"][-1])
    want = (summary["min_z_m"], summary["max_stretch_ratio"])
    apart = max(abs(g - w) / abs(w) for g, w in zip(got, want))
    check(f"{name}: simulate_fmu matches cloth run", apart < 1e-9, f"lowest {got[0]!r} vs {want[0]!r}, stretch {got[1]!r} vs {want[1]!r}, {apart:.1e} apart")


hang = build("hang.toml", HANG_FMU, "hang")
flag = build("flag.toml", FLAG_FMU, "flag")
# A scene with an OBJ solid (the pillow travels under resources/meshes/).
MESH = ["panels.0.particles=[21, 21]", *COMMON]
mesh = build("drape-mesh.toml", MESH, "mesh")
for name, path in [("hang", hang), ("flag", flag), ("mesh", mesh)]:
    problems = validate_fmu(path)
    check(f"{name}: validate_fmu", problems == [], repr(problems))

# The hang: a pin input is the pin's place at the communication point
# (FMPy applies the signal's value at t before fmi3DoStep from t), so the
# signal is the keyframed motion itself, unshifted. With the target's rate
# in the signal too (the input declared `derivative` of the target), every
# step is exact.
md = read_model_description(hang)
start = {v.name: float(v.start) for v in md.modelVariables if v.causality == "input"}
names = [f"pin{k}.target.{a}" for k in (0, 1) for a in "xyz"]
rates = [f"pin{k}.target_rate.{a}" for k in (0, 1) for a in "xyz"]
columns = [("time", np.float64)] + [(n, np.float64) for n in names + rates]
signal = np.array(
    [
        (t, *(start[n] + (SPEED * t if n.endswith(".x") else 0.0) for n in names), *(SPEED if r.endswith(".x") else 0.0 for r in rates))
        for t in (0.0, T)
    ],
    dtype=columns,
)
result = simulate_fmu(hang, stop_time=T, output_interval=H, input=signal)
keyframed = f'pins.0.motion={{ kind = "keyframes", times_s = [0.0, {T!r}], offsets_m = [[0.0, 0.0, 0.0], [{SPEED * T!r}, 0.0, 0.0]] }}'
compare("hang", result, run_summary("hang.toml", [*HANG, keyframed], "hang"))

# With values only, the FMU continues each pin from the previous
# communication point: it holds the first step (there is none before) and
# follows a constant velocity exactly from the second on: the pin is at its
# start at H and on the signal from 2 H, as these keyframes say.
signal = np.array(
    [(t, *(start[n] + (SPEED * t if n.endswith(".x") else 0.0) for n in names)) for t in (0.0, T)],
    dtype=[("time", np.float64)] + [(n, np.float64) for n in names],
)
result = simulate_fmu(hang, stop_time=T, output_interval=H, input=signal)
held = f'pins.0.motion={{ kind = "keyframes", times_s = [0.0, {H!r}, {2 * H!r}, {T!r}], offsets_m = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [{SPEED * 2 * H!r}, 0.0, 0.0], [{SPEED * T!r}, 0.0, 0.0]] }}'
compare("hang, values only", result, run_summary("hang.toml", [*HANG, held], "hang-values"))

# The flag: the wind input holds over the step, as the keyframed wind
# evaluated at the step's start.
names = ["wind.velocity.x", "wind.velocity.y", "wind.velocity.z"]
signal = np.array([(0.0, 2.0, 0.5, 0.0), (T, 8.0, 0.5, 0.0)], dtype=[("time", np.float64)] + [(n, np.float64) for n in names])
result = simulate_fmu(flag, stop_time=T, output_interval=H, input=signal)
compare("flag", result, run_summary("flag.toml", FLAG_RUN, "flag"))

# The drape on the pillow: no inputs.
compare("mesh", simulate_fmu(mesh, stop_time=T, output_interval=H), run_summary("drape-mesh.toml", MESH, "mesh"))

# Gravity is a tunable parameter: given as a start value it is the scene's
# gravity changed.
result = simulate_fmu(mesh, stop_time=T, output_interval=H, start_values={"gravity.z": -5.0})
compare("mesh, gravity 5 m/s^2", result, run_summary("drape-mesh.toml", [*MESH, "simulation.gravity_m_s2=[0.0, 0.0, -5.0]"], "mesh-g5"))

# So is damping: as a start value it is the scene's material damping changed.
result = simulate_fmu(mesh, stop_time=T, output_interval=H, start_values={"damping": 2.0})
compare("mesh, damping 2 N s/m", result, run_summary("drape-mesh.toml", [*MESH, "material.damping_n_s_m=2.0"], "mesh-d2"))

# Array outputs: every particle's position, recorded by FMPy as an
# (particles, 3) array per communication point; its lowest z is the
# lowest_z output, exactly.
result = simulate_fmu(mesh, stop_time=10 * H, output_interval=H, output=["positions", "velocities", "lowest_z"])
positions = result["positions"]
shape_ok = positions.shape == (11, 21 * 21, 3) and result["velocities"].shape == (11, 21 * 21, 3)
lowest = positions[:, :, 2].min(axis=1)
check("mesh: positions as an array output", shape_ok and np.array_equal(lowest, result["lowest_z"]), f"shape {positions.shape}, lowest z {lowest[-1]!r} vs {result['lowest_z'][-1]!r}")

# Any macro step: inside the FMU a communication step is taken as substeps
# of at most the scene's 1/90 s, so the drape stepped at 1/30, 0.1 and 1 s
# is where the 1/90 s run is at their common times.
fine = simulate_fmu(mesh, stop_time=1.0, output_interval=H)
for dt in (3 * H, 0.1, 1.0):
    coarse = simulate_fmu(mesh, stop_time=1.0, output_interval=dt)
    apart, common = 0.0, 0
    for row in coarse[1:]:
        match = [r for r in fine if abs(r["time"] - row["time"]) < 1e-9]
        if match:
            common += 1
            for key in ("lowest_z", "max_stretch"):
                apart = max(apart, abs(row[key] - match[0][key]) / abs(match[0][key]))
    check(f"mesh at output interval {dt:.4f} s: the same cloth at common times", common > 0 and apart < 1e-9, f"{common} common times, {apart:.1e} apart")

# States and their serialisation, through FMPy's own calls.
md = read_model_description(flag)
outputs = [v.valueReference for v in md.modelVariables if v.causality == "output" and not v.dimensions]
unzipped = extract(flag)
messages = []


def logger(env, status, category, message):
    messages.append((status, message.decode("utf-8")))


fmu = FMU3Slave(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=md.coSimulation.modelIdentifier, instanceName="flag")
fmu.instantiate(logMessage=logger)
wind = [v.valueReference for v in md.modelVariables if v.name.startswith("wind.velocity")]
try:
    fmu.getFloat64(outputs)
    check("get before initialisation is fmi3Error", False, "no error")
except Exception as e:
    check("get before initialisation is fmi3Error", "error" in str(e), str(e))
check("get before initialisation is logged", any("not allowed in Instantiated" in m for _, m in messages), repr(messages[-1:]))
fmu.enterInitializationMode(startTime=0.0)
fmu.exitInitializationMode()
fmu.setFloat64(wind, [6.0, 0.5, 0.0])
t = 0.0
for _ in range(5):
    fmu.doStep(currentCommunicationPoint=t, communicationStepSize=H)
    t += H
state = fmu.getFMUState()
data = fmu.serializeFMUState(state)


def five_steps(t0):
    t = t0
    for _ in range(5):
        fmu.doStep(currentCommunicationPoint=t, communicationStepSize=H)
        t += H
    return fmu.getFloat64(outputs)


first = five_steps(t)
fmu.setFMUState(state)
again = five_steps(t)
check("state restored: identical outputs", again == first, f"{len(first)} outputs")
restored = fmu.deserializeFMUState(data)
fmu.setFMUState(restored)
third = five_steps(t)
check("serialised state round trip: identical outputs", third == first, f"{len(data)} bytes")
fmu.freeFMUState(state)
fmu.freeFMUState(restored)
try:
    fmu.doStep(currentCommunicationPoint=t + 5 * H, communicationStepSize=-H)
    check("negative step is fmi3Error", False, "no error")
except Exception as e:
    check("negative step is fmi3Error", "error" in str(e), str(e))
check("negative step is logged", any("must be finite and > 0" in m for _, m in messages), repr(messages[-1:]))
fmu.terminate()
fmu.freeInstance()

passed = sum(ok for _, ok in results)
failed = len(results) - passed
print(f"fmu: {passed} passed, {failed} failed")
sys.exit(1 if failed else 0)
