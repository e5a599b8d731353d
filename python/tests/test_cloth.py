"""The Python binding, asserting physics through it: momentum under
gravity, pins carrying the weight, snapshots replaying, errors naming the
file and field, the GIL released while stepping."""

import copy
import os
import pickle
import threading

import numpy as np
import pytest

import cloth

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
HANG = os.path.join(ROOT, "fixtures", "scenes", "hang.toml")
SMALL = {"panels.0.particles": [11, 11], "pins.0.nodes": "[[0, 10], [10, 10]]"}


def test_a_free_cloth_gains_the_momentum_gravity_gives():
    # No pins, no solids: internal forces cancel, so the mean velocity
    # after t is g t (BDF2, solves to 1e-12; measured 1.3e-14 relative).
    builder = cloth.Builder().panel((9, 9), (0.4, 0.4), (0.0, 0.0, 1.0)).gravity((0.0, 0.0, -9.81)).bending().damping()
    sim = builder.simulation(rel_tol=1e-12)
    sim.step(30)
    v = sim.velocities
    assert v.shape == (81, 3) and v.dtype == np.float64
    mean_vz = np.average(v[:, 2], weights=sim.masses)
    assert abs(mean_vz - (-9.81 * sim.time_s)) < 1e-12 * 9.81 * sim.time_s
    assert abs(sim.time_s - 30 / 90) < 1e-12


def test_the_pins_take_what_the_cloth_does_not_gain_in_momentum():
    # Backward Euler balances momentum each step: the change of the
    # cloth's momentum is the step's weight less the pins' mean pull
    # (measured 3.5e-15 of the weight's impulse over 60 steps).
    overrides = {**SMALL, "simulation.integrator": '"backward-euler"', "solver.rel_tol": 1e-12}
    sim = cloth.Scene.from_toml(HANG, overrides).simulation()
    h, m = sim.dt_s, sim.masses
    pulled = np.zeros(3)
    for _ in range(60):
        sim.step()
        pulled += h * sim.pin_reactions().sum(axis=0)
    momentum = (m[:, None] * sim.velocities).sum(axis=0)
    expected = np.array([0.0, 0.0, -9.81]) * m.sum() * sim.time_s - pulled
    weight_impulse = 9.81 * m.sum() * sim.time_s
    assert np.abs(momentum - expected).max() < 1e-12 * weight_impulse, (momentum, expected)
    assert -pulled[2] > 0.5 * weight_impulse  # the pins hold most of it by now
    assert sim.max_stretch() < 1.2


def test_a_snapshot_replays_the_same_steps_bit_for_bit():
    sim = cloth.Scene.from_toml(HANG, ["panels.0.particles=[11, 11]", "pins.0.nodes=[[0, 10], [10, 10]]"]).simulation()
    sim.step(5)
    saved = sim.snapshot()
    sim.step(10)
    first = sim.positions
    sim.restore(saved)
    assert saved.time_s == pytest.approx(5 / 90)
    sim.step(10)
    assert np.array_equal(sim.positions, first)


def test_a_snapshot_pickled_or_saved_as_bytes_replays_in_another_simulation(tmp_path):
    scene = cloth.Scene.from_toml(HANG, ["panels.0.particles=[11, 11]", "pins.0.nodes=[[0, 10], [10, 10]]"])
    sim = scene.simulation()
    sim.step(5)
    saved = sim.snapshot()
    sim.step(10)
    path = tmp_path / "start.snap"
    path.write_bytes(saved.to_bytes())
    for read in (cloth.Snapshot(path.read_bytes()), pickle.loads(pickle.dumps(saved)), copy.deepcopy(saved)):
        assert read == saved and (read.steps, read.particle_count) == (5, 121)
        other = scene.simulation()
        other.restore(read)
        other.step(10)
        # BDF2's history and the integrator's memory came along: the same bits.
        assert np.array_equal(other.positions, sim.positions) and np.array_equal(other.velocities, sim.velocities)
    data = saved.to_bytes()
    assert len(data) > 96 * 121
    for bad in (data[:-1], data[:100], b"", data[:40] + bytes([data[40] ^ 1]) + data[41:]):
        with pytest.raises(ValueError, match="Snapshot"):
            cloth.Snapshot(bad)
    # A snapshot that does not fit is refused as bad input, and the
    # simulation is left as it was.
    larger = cloth.Scene.from_toml(HANG, ["panels.0.particles=[12, 11]", "pins.0.nodes=[[0, 10], [11, 10]]"])
    refusing = larger.simulation()
    refusing.step(3)
    before = (refusing.positions, refusing.velocities, refusing.time_s)
    with pytest.raises(cloth.SnapshotError, match="121") as e:
        refusing.restore(saved)
    assert isinstance(e.value, ValueError) and not isinstance(e.value, cloth.StepError)
    assert np.array_equal(refusing.positions, before[0]) and np.array_equal(refusing.velocities, before[1])
    assert refusing.time_s == before[2]
    refusing.step(1)
    assert refusing.time_s == pytest.approx(4 / 90)
    vbd = ["panels.0.particles=[11, 11]", "pins.0.nodes=[[0, 10], [10, 10]]", 'simulation.integrator="vbd"']
    with pytest.raises(cloth.SnapshotError, match="memory"):
        cloth.Scene.from_toml(HANG, vbd).simulation().restore(saved)


def test_control_inputs_move_the_cloth_and_bad_ones_are_refused():
    sim = cloth.Scene.from_toml(HANG, {**SMALL, "pins.0.motion": '{ kind = "external" }'}).simulation()
    start = sim.positions
    # Pin 0 is node (0, 10): particle 10 * 11.
    sim.set_pin_target(0, start[110] + np.array([0.05, 0.0, 0.0]))
    sim.step()
    assert sim.positions[110, 0] == pytest.approx(start[110, 0] + 0.05, abs=1e-12)
    with pytest.raises(cloth.ControlError, match="pin 7"):
        sim.set_pin_target(7, (0.0, 0.0, 0.0))
    with pytest.raises(cloth.ControlError, match="not external"):
        sim.set_wind((1.0, 0.0, 0.0))
    with pytest.raises(cloth.ControlError, match="columns"):
        sim.set_external_forces(np.zeros((121, 2)))
    # A force of m g upward on every particle cancels gravity exactly.
    free = cloth.Builder().panel((5, 5), (0.2, 0.2)).gravity((0.0, 0.0, -9.81)).simulation()
    free.set_external_forces(np.outer(free.masses, [0.0, 0.0, 9.81]))
    free.step(10)
    assert np.abs(free.velocities).max() < 1e-12


def test_errors_name_the_file_and_field():
    with pytest.raises(cloth.SceneError) as e:
        cloth.Scene.from_toml(HANG, {"material.tensile_stiffness_n_m": -1.0}).simulation()
    assert e.value.field == "material.tensile_stiffness_n_m" and e.value.file.endswith("hang.toml"), vars(e.value)
    with pytest.raises(cloth.SceneError) as e:
        cloth.Scene.from_toml(os.path.join(ROOT, "no-such.toml"))
    assert "no-such.toml" in e.value.file and "cannot read" in str(e.value)
    with pytest.raises(cloth.SceneError, match="unknown field `nope`"):
        cloth.Scene.from_toml(HANG, ["panels.0.nope=1"])
    with pytest.raises(cloth.ModelError, match="not_a_constant"):
        cloth.Builder().material(not_a_constant=1.0)
    with pytest.raises(ValueError, match="model kind"):
        cloth.Builder().kind("springs")
    with pytest.raises(cloth.ModelError):
        cloth.Builder().simulation()  # no panels


def test_a_failing_step_raises_and_keeps_the_last_good_state():
    sim = cloth.Scene.from_toml(HANG, {**SMALL, "solver.max_iter": 1, "solver.accept_unconverged": False}).simulation()
    before = sim.positions
    with pytest.raises(cloth.StepError) as e:
        sim.step(3)
    assert e.value.time_s == 0.0 and np.array_equal(sim.positions, before)


def test_stepping_releases_the_gil():
    sim = cloth.Scene.from_toml(HANG, {"panels.0.particles": [41, 41]}).simulation()
    worker = threading.Thread(target=sim.step, args=(60,))
    worker.start()
    ran = 0
    while worker.is_alive():
        ran += 1
    worker.join()
    # Held, the loop could not run until the steps were done.
    assert ran > 1000, ran


def test_the_readme_example_runs():
    with open(os.path.join(ROOT, "README.md")) as f:
        text = f.read()
    block = text.split("```python\n", 1)[1].split("```", 1)[0]
    here = os.getcwd()
    os.chdir(ROOT)
    try:
        names = {}
        exec(block, names)
    finally:
        os.chdir(here)
    assert names["x"].shape == (441, 3) and names["pull"].shape == (2, 3)
    assert names["pull"][:, 2].sum() < 0  # the cloth pulls the pins down


def test_the_last_step_reports_its_solve_and_contacts():
    # A hanging cloth: no report before a step, then a converged solve in
    # some CG iterations and no contacts; the Fold task's cloth lying on
    # its floor: every particle held (stuck by friction, so the solve
    # has nothing left to iterate on).
    import gymnasium as gym

    import cloth.envs  # noqa: F401

    sim = cloth.Scene.from_toml(HANG, SMALL).simulation(threads=1)
    assert sim.last_step() is None
    sim.step(10)
    report = sim.last_step()
    assert report["converged"] and report["cg_iterations"] > 0 and report["contacts"] == 0
    assert not report["retaken"] and report["rel_residual"] < 1e-3
    assert set(report["stages_s"]) == {"forces", "assembly", "solve", "update", "collision", "self_collision"}
    assert all(0.0 <= t < 10.0 for t in report["stages_s"].values())
    lying = gym.make("cloth/Fold-v0").unwrapped._scene.simulation(threads=1)
    lying.step(10)
    assert lying.last_step()["contacts"] == lying.particle_count


def test_any_thread_count_gives_the_same_bits():
    # The Fold task's cloth grasped by a corner and dragged: self-collision,
    # floor contacts with friction and a hold, on one thread and on two.
    import gymnasium as gym

    import cloth.envs  # noqa: F401

    def run(threads):
        sim = gym.make("cloth/Fold-v0").unwrapped._scene.simulation(threads=threads)
        grasp = sim.grasp(list(sim.positions[0]), 0.02)
        for k in range(30):
            sim.move_grasp(grasp, [-0.2 + 0.01 * k, -0.2, 0.005 + 0.004 * k])
            sim.step()
        return sim.positions.tobytes()

    assert run(1) == run(2)
