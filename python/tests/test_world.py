"""Coupled scenes from Python (`cloth.World`), asserted through physics:
a body resting in the cloth weighs on it, the posts carry the whole
weight, forces and torques accelerate a body as Newton says, kinematic
targets and joint positions are reached, and bad input raises errors that
name what is wrong."""

import os

import numpy as np
import pytest

import cloth

ROOT = os.path.join(os.path.dirname(__file__), "..", "..")
HAMMOCK = os.path.join(ROOT, "fixtures", "scenes", "hammock.toml")
HUMANOID = os.path.join(ROOT, "fixtures", "scenes", "humanoid-skirt.toml")
UNDAMPED = {"bodies.2.linear_damping_1_s": 0.0, "bodies.2.angular_damping_1_s": 0.0}
G = 9.81


def test_a_ball_resting_in_the_hammock_weighs_on_it_and_the_posts_carry_all():
    world = cloth.World.from_toml(HAMMOCK)
    assert world.body_names == ["post-left", "post-right", "ball"]
    ball = world.body_mass("ball")
    weight = (world.masses.sum() + ball) * G
    world.step(360)  # 4 s
    speed = np.linalg.norm(world.body_velocity("ball")[0])
    on_ball = world.cloth_force("ball")
    # The cloth holds the ball up with its weight (measured 5.1e-4 off at 4 s).
    assert on_ball["contacts"] > 0 and speed < 1e-3
    assert abs(on_ball["force"][2] - ball * G) < 1e-3 * ball * G
    # The cloth pulls the posts down with the weight of cloth and ball
    # (measured 4.5e-4 off); the horizontal pulls cancel.
    posts = world.cloth_force("post-left")["force"] + world.cloth_force("post-right")["force"]
    assert abs(posts[2] + weight) < 1e-3 * weight
    assert abs(posts[0]) < 1e-3 * weight and abs(posts[1]) < 1e-3 * weight


def test_forces_and_torques_accelerate_a_body_for_one_step_each():
    # Before the ball meets the cloth: three times its weight up for ten
    # steps gives 2 g t up; a torque tau about z gives tau / I t (a solid
    # ball, I = 2/5 m r^2). Then, without the force, it falls at g again.
    world = cloth.World.from_toml(HAMMOCK, UNDAMPED)
    h, m = world.dt_s, world.body_mass("ball")
    inertia = 0.4 * m * 0.1**2
    for _ in range(10):
        world.apply_force("ball", [0.0, 0.0, 3 * m * G], torque=[0.0, 0.0, 1e-3])
        world.step()
    v, w = world.body_velocity("ball")
    assert abs(v[2] - 2 * G * 10 * h) < 1e-12 and abs(w[2] - 1e-3 / inertia * 10 * h) < 1e-12
    world.step()
    v2, _ = world.body_velocity("ball")
    assert abs((v2[2] - v[2]) + G * h) < 1e-12


def test_a_kinematic_body_goes_to_its_target_and_stays():
    world = cloth.World.from_toml(HAMMOCK, {"bodies.2.kind": '"kinematic"', **UNDAMPED})
    world.set_kinematic_target("ball", [0.1, 0.2, 1.4], rotation=[0.0, 0.0, 0.3])
    for _ in range(2):
        world.step()
        position, q = world.body_pose("ball")
        assert np.allclose(position, [0.1, 0.2, 1.4], atol=1e-14)
        # A turn of 0.3 rad about z: q = (0, 0, sin 0.15, cos 0.15).
        assert np.allclose(q, [0.0, 0.0, np.sin(0.15), np.cos(0.15)], atol=1e-14)


def quaternion_angle(a, b):
    """The angle of the rotation taking unit quaternion a ([x, y, z, w]) to b."""
    return 2 * np.arccos(min(1.0, abs(float(np.dot(a, b)))))


def test_a_joint_set_from_outside_turns_its_child_link_by_that_angle():
    world = cloth.World.from_toml(HUMANOID)
    assert "L_Knee" in world.joint_positions() and "L_Calf" in world.link_names
    world.step()
    thigh0, calf0 = world.link_pose("L_Thigh")[1], world.link_pose("L_Calf")[1]
    world.set_joint_positions({"L_Knee": 0.5})
    world.step(3)
    assert world.joint_positions()["L_Knee"] == 0.5
    thigh1, calf1 = world.link_pose("L_Thigh")[1], world.link_pose("L_Calf")[1]
    # The thigh stays (the character stands); the calf turns 0.5 rad.
    assert quaternion_angle(thigh0, thigh1) < 1e-12
    assert abs(quaternion_angle(calf0, calf1) - 0.5) < 1e-9


def test_bad_input_to_a_world_names_what_is_wrong():
    with pytest.raises(cloth.SceneError) as e:
        cloth.World.from_toml(HAMMOCK, {"bodies.2.mass_kg": -1.0})
    assert e.value.file.endswith("hammock.toml") and "bodies" in e.value.field
    world = cloth.World.from_toml(HAMMOCK)
    with pytest.raises(cloth.ControlError, match='no body named "box".*ball'):
        world.apply_force("box", [0.0, 0.0, 1.0])
    with pytest.raises(cloth.ControlError, match="fixed"):
        world.apply_force("post-left", [0.0, 0.0, 1.0])
    with pytest.raises(cloth.ControlError, match="not finite"):
        world.apply_force("ball", [0.0, float("nan"), 1.0])
    with pytest.raises(cloth.ControlError, match="kinematic"):
        world.set_kinematic_target("ball", [0.0, 0.0, 1.0])
    with pytest.raises(cloth.ControlError, match="no \\[rig\\]"):
        world.set_joint_positions({"L_Knee": 0.1})
    rig = cloth.World.from_toml(HUMANOID)
    with pytest.raises(cloth.ControlError, match="no joint"):
        rig.set_joint_positions({"Tail": 0.1})
    with pytest.raises(cloth.ControlError, match="rotation"):
        rig.set_joint_positions({"L_Knee": 0.1, "L_Hip": 0.2})
    # Nothing was set: the knee keeps its value.
    assert rig.joint_positions()["L_Knee"] == 0.0


def rotate(q, v):
    """Unit quaternion q ([x, y, z, w]) applied to vector v."""
    u, w = np.asarray(q[:3]), q[3]
    return v + 2 * np.cross(u, np.cross(u, v) + w * v)


def test_a_body_grasp_carries_its_particles_and_the_body_feels_their_pull():
    # A kinematic ball moved and turned every step: the particles it
    # grasped keep their place in its frame at the end of each step
    # (measured 3.5e-18 m off).
    world = cloth.World.from_toml(HAMMOCK, {"bodies.2.kind": '"kinematic"', **UNDAMPED})
    middle = world.positions[world.particle_count // 2]
    position, q = world.body_pose("ball")
    grasp = world.grasp(list(middle), 0.05, body="ball")
    held = world.grasp_particles(grasp)
    inverse = q * np.array([-1.0, -1.0, -1.0, 1.0])
    local = [rotate(inverse, world.positions[i] - position) for i in held]
    assert len(held) == 3
    for k in range(1, 5):
        world.set_kinematic_target("ball", [0.05, 0.02 + 0.01 * k, 1.25 + 0.02 * k], rotation=[0.0, 0.0, 0.05 * k])
        world.step()
        position, q = world.body_pose("ball")
        off = max(np.linalg.norm(world.positions[i] - (position + rotate(q, l))) for i, l in zip(held, local))
        assert off < 1e-15
    # Let go and taken again at the offsets it had, the ball carries them
    # as before.
    offsets = world.grasp_offsets(grasp)
    assert np.abs(offsets - local).max() < 1e-15
    world.release(grasp)
    with pytest.raises(cloth.ControlError, match="a point or a body"):
        world.grasp_at_offsets(held, offsets, point=[0.0, 0.0, 1.0], body="ball")
    grasp = world.grasp_at_offsets(held, offsets, body="ball")
    world.set_kinematic_target("ball", [0.05, 0.1, 1.4], rotation=[0.0, 0.0, 0.3])
    world.step()
    position, q = world.body_pose("ball")
    assert max(np.linalg.norm(world.positions[i] - (position + rotate(q, l))) for i, l in zip(held, offsets)) < 1e-15
    # A dynamic ball holding the cloth: each step its velocity changes by
    # gravity's and the grasp's pull of the step before (one step late),
    # until it meets the cloth; the particles follow it to 0.1 mm (the
    # step's motion is predicted before the step: measured 4.0e-5 m).
    world = cloth.World.from_toml(HAMMOCK, UNDAMPED)
    h, m = world.dt_s, world.body_mass("ball")
    position, q = world.body_pose("ball")
    grasp = world.grasp(list(world.positions[world.particle_count // 2]), 0.05, body="ball")
    held = world.grasp_particles(grasp)
    local = [rotate(q * np.array([-1.0, -1.0, -1.0, 1.0]), world.positions[i] - position) for i in held]
    pull, v_before = np.zeros(3), np.zeros(3)
    for _ in range(5):
        world.step()
        v, _ = world.body_velocity("ball")
        assert world.cloth_force("ball")["contacts"] == 0
        assert np.abs(v - v_before - (np.array([0.0, 0.0, -G]) + pull / m) * h).max() < 1e-12
        pull, v_before = world.grasp_force(grasp), v
        position, q = world.body_pose("ball")
        off = max(np.linalg.norm(world.positions[i] - (position + rotate(q, l))) for i, l in zip(held, local))
        assert off < 1e-4


def test_a_rig_link_carries_what_it_grasps_as_its_joint_turns():
    # The skirt's hem particle nearest the left calf, grasped by the calf
    # link; the knee bent to 0.6 rad: the particle stays at its place in
    # the calf's frame (measured 1.4e-17 m).
    world = cloth.World.from_toml(HUMANOID)
    world.step(2)
    origin, q = world.link_pose("L_Calf")
    nearest = int(np.argmin(np.linalg.norm(world.positions - origin, axis=1)))
    grasp = world.grasp(list(world.positions[nearest]), 0.03, body="L_Calf")
    held = world.grasp_particles(grasp)
    local = [rotate(q * np.array([-1.0, -1.0, -1.0, 1.0]), world.positions[i] - origin) for i in held]
    world.set_joint_positions({"L_Knee": 0.6})
    for _ in range(3):
        world.step()
        origin, q = world.link_pose("L_Calf")
        assert max(np.linalg.norm(world.positions[i] - (origin + rotate(q, l))) for i, l in zip(held, local)) < 1e-15
    with pytest.raises(cloth.ControlError, match='no body or rig link named "Tail"'):
        world.grasp(list(world.positions[0]), 0.03, body="Tail")


def state(world, names):
    """The cloth's positions and velocities and the bodies' poses and
    velocities, as bytes."""
    parts = [world.positions, world.velocities]
    for name in names:
        parts += [*world.body_pose(name), *world.body_velocity(name)]
    return b"".join(np.asarray(p).tobytes() for p in parts)


@pytest.mark.parametrize("scene", ["hammock", "humanoid"])
def test_a_world_snapshot_replays_cloth_bodies_and_rig_bit_for_bit(scene):
    # The ball in the hammock (on the cloth from about 0.2 s), and the
    # humanoid's skirt on its rig (walking from about 0.35 s): 20 steps
    # taken again from the snapshot end at the same bits, the rapier
    # bodies and the rig's links included.
    world = cloth.World.from_toml(HAMMOCK if scene == "hammock" else HUMANOID)
    names = world.body_names
    world.step(40)
    saved = world.snapshot()
    assert saved.time_s == pytest.approx(40 * world.dt_s)
    at_snapshot = {name: world.link_pose(name)[0] for name in world.link_names}
    world.step(20)
    first = state(world, names)
    links = {name: world.link_pose(name)[0].tobytes() for name in world.link_names}
    world.restore(saved)
    assert world.time_s == saved.time_s
    world.step(20)
    assert state(world, names) == first
    assert {name: world.link_pose(name)[0].tobytes() for name in world.link_names} == links
    if scene == "hammock":
        assert world.cloth_force("ball")["contacts"] > 0
    else:
        moved = max(np.linalg.norm(world.link_pose(n)[0] - x) for n, x in at_snapshot.items())
        assert moved > 0.01, moved
    with pytest.raises(cloth.SnapshotError, match="another World"):
        cloth.World.from_toml(HAMMOCK).restore(saved)
