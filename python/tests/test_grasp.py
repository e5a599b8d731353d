"""Grasps asserted through physics: the momentum the hand gives the cloth,
the weight it carries, free fall once let go, a patch lifted off the
ground, and refusals."""

import numpy as np
import pytest

import cloth

G = 9.81


def free_cloth(integrator="backward-euler"):
    builder = cloth.Builder().panel((11, 11), (0.4, 0.4), (-0.2, -0.2, 1.0)).gravity((0.0, 0.0, -G)).bending().damping()
    return builder.simulation(integrator=integrator, rel_tol=1e-12)


def momentum(sim):
    return (sim.masses[:, None] * sim.velocities).sum(axis=0)


def test_the_hand_gives_the_cloth_the_momentum_its_pull_says_and_carries_its_weight():
    sim = free_cloth()
    h, weight = sim.dt_s, sim.masses.sum() * G
    grasp = sim.grasp([0.0, 0.0, 1.0], 0.03)
    assert sim.grasp_particles(grasp) == [60]  # the middle particle
    start, impulse = momentum(sim), np.zeros(3)
    # Lift 20 cm in 1/3 s, then hold: backward Euler balances momentum per
    # step, so the change is the hand's impulse plus gravity's
    # (measured 6.0e-10 N s of 0.157 N s).
    for k in range(90):
        sim.move_grasp(grasp, [0.0, 0.0, 1.0 + 0.2 * min(1.0, (k + 1) / 30)])
        sim.step()
        impulse -= sim.grasp_force(grasp) * h
    expected = impulse + np.array([0.0, 0.0, -weight * 90 * h])
    assert np.abs(momentum(sim) - start - expected).max() < 1e-8 * weight * 90 * h
    # Hanging still after 4 s it pulls the hand down with its weight
    # (measured 1.7e-4 off: the last swing).
    sim.step(270)
    pull = sim.grasp_force(grasp)
    assert abs(pull[2] + weight) < 5e-4 * weight and np.abs(pull[:2]).max() < 1e-9
    # Let go, it falls freely: g t exactly.
    sim.release(grasp)
    v0 = momentum(sim) / sim.masses.sum()
    sim.step(10)
    v1 = momentum(sim) / sim.masses.sum()
    assert abs((v1 - v0)[2] + G * 10 * h) < 1e-12


def test_a_patch_grasped_on_the_ground_is_lifted_off_it():
    # A grasp takes precedence over the ground contact of its particles.
    import gymnasium as gym

    import cloth.envs  # noqa: F401

    env = gym.make("cloth/Fold-v0")
    env.reset(seed=0)
    sim = env.unwrapped.sim
    corner = sim.positions[0].copy()
    grasp = sim.grasp(list(corner), 0.02)
    sim.move_grasp(grasp, list(corner + [0.0, 0.0, 0.05]))
    sim.step(3)
    assert abs(sim.positions[0][2] - corner[2] - 0.05) < 1e-12


def test_grasps_that_cannot_be_made_are_refused():
    sim = free_cloth("bdf2")
    with pytest.raises(cloth.ControlError, match="no free particle within 0.01 m"):
        sim.grasp([5.0, 5.0, 5.0], 0.01)
    with pytest.raises(cloth.ControlError, match="radius"):
        sim.grasp([0.0, 0.0, 1.0], -1.0)
    grasp = sim.grasp([0.0, 0.0, 1.0], 0.03)
    # A particle held by one grasp is not taken by another.
    with pytest.raises(cloth.ControlError, match="already grasped"):
        sim.grasp([0.0, 0.0, 1.0], 0.01)
    with pytest.raises(cloth.ControlError, match="not finite"):
        sim.move_grasp(grasp, [0.0, float("inf"), 1.0])
    sim.release(grasp)
    with pytest.raises(cloth.ControlError, match="no such grasp"):
        sim.grasp_force(grasp)


def test_a_grasp_at_given_offsets_holds_its_particles_there_or_nothing():
    # The particles end the next step at the gripper plus their offsets;
    # a refused grasp holds none of its particles.
    sim = free_cloth("bdf2")
    grasp = sim.grasp([0.0, 0.0, 1.0], 0.05)
    particles, offsets = sim.grasp_particles(grasp), sim.grasp_offsets(grasp)
    assert len(particles) == 5
    assert np.array_equal(offsets, sim.positions[particles] - [0.0, 0.0, 1.0])
    sim.release(grasp)
    point = np.array([0.1, 0.0, 1.2])
    again = sim.grasp_at_offsets(particles, 2 * offsets, list(point))
    assert sim.grasp_particles(again) == particles
    assert np.array_equal(sim.grasp_offsets(again), 2 * offsets)
    sim.step()
    assert np.abs(sim.positions[particles] - (point + 2 * offsets)).max() < 1e-12
    free, one = [0, 1], np.zeros((2, 3))
    for args, match in [
        (([0, 0], one, [0.0, 0.0, 1.0]), "particle 0 is not free"),
        (([0, particles[0]], one, [0.0, 0.0, 1.0]), f"particle {particles[0]} is not free"),
        (([0, 121], one, [0.0, 0.0, 1.0]), "particle 121: the cloth has 121"),
        ((free, np.zeros((1, 3)), [0.0, 0.0, 1.0]), "2 particles with 1 offsets"),
        ((free, np.zeros((2, 4)), [0.0, 0.0, 1.0]), "offsets: 4 columns"),
        ((free, np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, 0.0]]), [0.0, 0.0, 1.0]), "offset of particle 1"),
        ((free, one, [0.0, np.inf, 1.0]), "gripper's position is not finite"),
    ]:
        with pytest.raises(cloth.ControlError, match=match):
            sim.grasp_at_offsets(*args)
    # Particle 0 came first in a refused grasp: it is still free.
    sim.grasp_at_offsets([0], np.zeros((1, 3)), list(sim.positions[0]))
