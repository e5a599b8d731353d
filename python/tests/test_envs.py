"""The Gymnasium tasks: they pass Gymnasium's checker, replay bit for bit
from a seed (made or restored from a start state) and from a state taken
mid-episode, run under
AsyncVectorEnv, measure what they say (covered area, fold distance,
distance to the target), and the scripted fold reaches the Fold task's
success."""

import os
import pickle
import sys

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import cloth.envs
from cloth.envs.raster import covered_area

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
sys.path.insert(0, os.path.join(ROOT, "python", "examples"))

import fold_scripted  # noqa: E402

TASKS = ["cloth/Flatten-v0", "cloth/Fold-v0", "cloth/Drop-v0"]


@pytest.mark.parametrize("task", TASKS)
def test_each_task_passes_gymnasiums_checker_and_renders(task):
    env = gym.make(task, render_mode="rgb_array")
    check_env(env.unwrapped)
    env.reset(seed=0)
    image = env.render()
    assert image.shape == (128, 128, 3) and image.dtype == np.uint8
    # The cloth is drawn: blue (front) or orange (back) pixels, not only floor.
    cloth_pixels = (image[:, :, 2].astype(int) - image[:, :, 0] > 40) | (image[:, :, 0].astype(int) - image[:, :, 2] > 60)
    assert cloth_pixels.sum() > 100


@pytest.mark.parametrize("observation", ["positions", "keypoints"])
def test_the_pickers_part_of_the_observation_is_bounded_by_their_box(observation):
    env = gym.make("cloth/Fold-v0", observation=observation).unwrapped
    space, pickers = env.observation_space, env.pickers
    low, high = space.low[-4 * pickers :].reshape(pickers, 4), space.high[-4 * pickers :].reshape(pickers, 4)
    lo, hi = env.BOUNDS
    assert (low[:, :3] == lo).all() and (high[:, :3] == hi).all()
    assert (low[:, 3] == 0).all() and (high[:, 3] == 1).all()
    assert np.isinf(space.low[: -4 * pickers]).all() and np.isinf(space.high[: -4 * pickers]).all()
    # Pushed against every wall of the box, the pickers stay inside it.
    obs, _ = env.reset(seed=1)
    # 0.03 m a step: 40 steps cross the box.
    for action in ([1, 1, 1, 1], [-1, -1, -1, -1]):
        for _ in range(40):
            obs, *_ = env.step(np.array(action * pickers, dtype=np.float32))
            assert obs in space
        pos = obs[-4 * pickers :].reshape(pickers, 4)[:, :3]
        assert np.allclose(pos, hi if action[0] > 0 else lo)


@pytest.mark.parametrize("task", TASKS)
def test_the_same_seed_gives_the_same_bits(task):
    def run(seed):
        env = gym.make(task)
        obs, _ = env.reset(seed=seed)
        env.action_space.seed(seed)
        rewards = []
        for _ in range(5):
            obs, reward, *_ = env.step(env.action_space.sample())
            rewards.append(reward)
        return obs, rewards

    (a, ra), (b, rb) = run(7), run(7)
    assert a.tobytes() == b.tobytes() and ra == rb
    c, _ = run(8)
    assert c.tobytes() != a.tobytes()


def test_the_tasks_run_under_async_vector_env():
    vec = gym.vector.AsyncVectorEnv([lambda: gym.make("cloth/Fold-v0") for _ in range(2)])
    try:
        obs, _ = vec.reset(seed=[3, 3])
        single, _ = gym.make("cloth/Fold-v0").reset(seed=3)
        assert obs.shape == (2, single.size)
        assert obs[0].tobytes() == single.tobytes() == obs[1].tobytes()
        for _ in range(3):
            obs, reward, terminated, truncated, _ = vec.step(vec.action_space.sample())
        assert np.isfinite(obs).all() and reward.shape == (2,)
    finally:
        vec.close()


def test_a_flat_square_covers_its_area_and_a_crumpled_one_less():
    # Cells of 5 mm hit by a 0.4 m square: its area and at most half a
    # cell along its edges (measured 1.025 x the area).
    n, side = 25, 0.4
    i, j = np.meshgrid(np.arange(n), np.arange(n))
    flat = np.stack([i.ravel() * side / (n - 1), j.ravel() * side / (n - 1), np.zeros(n * n)], axis=1)
    env = gym.make("cloth/Flatten-v0")
    triangles = env.unwrapped._triangles
    area = covered_area(flat, triangles)
    assert side * side <= area <= side * side + 4 * side * 0.005
    # Folded in half, the square covers half as much.
    folded = flat.copy()
    left = folded[:, 0] < side / 2
    folded[left, 0] = side - folded[left, 0]
    assert abs(covered_area(folded, triangles) / area - 0.5) < 0.05
    obs, info = env.reset(seed=0)
    coverage = env.unwrapped.coverage()
    assert 0.2 < coverage < 0.9 and not info["success"]


def test_the_scripted_fold_reaches_the_fold_tasks_success():
    env = gym.make("cloth/Fold-v0")
    obs, info = env.reset(seed=0)
    assert not info["success"]
    reward, info = fold_scripted.fold(env, seed=0)
    # Measured: 0.8 cm (the halves 0.6 cm apart, the still half moved 0.2 cm).
    assert info["success"] and -reward < cloth.envs.FoldEnv.SUCCESS_DISTANCE_M


def test_the_dropped_cloth_starts_held_and_falls_when_let_go():
    env = gym.make("cloth/Drop-v0", observation="keypoints")
    obs, info = env.reset(seed=0)
    task = env.unwrapped
    assert obs.shape == (5 * 3 + 2 * 4,) and all(g is not None for g in task.grasps)
    # Hanging 10 cm above the floor: nothing below z = 0.1 m - sag.
    z = task.sim.positions[:, 2]
    assert z.min() > 0.05 and -task.reward() > 0.1
    hold = np.tile([0.0, 0.0, 0.0, 1.0], 2).astype(np.float32)
    env.step(hold)
    assert task.sim.positions[:, 2].min() > 0.05
    let_go = np.tile([0.0, 0.0, 0.0, -1.0], 2).astype(np.float32)
    for _ in range(60):
        env.step(let_go)
    assert all(g is None for g in task.grasps)
    # In a heap on the floor after 2 s (measured 6.5 cm at the highest).
    assert task.sim.positions[:, 2].max() < 0.1


@pytest.mark.parametrize(
    "argument, value",
    [
        ("pickers", 3),
        ("observation", "pixels"),
        ("particles", 2),
        ("substeps", 0),
        ("dt_s", 0.0),
        ("max_move_m", float("nan")),
        ("start_states", 0),
        ("start_states", 2.5),
    ],
)
def test_a_task_refuses_arguments_it_cannot_run_and_names_them(argument, value):
    with pytest.raises(ValueError, match=argument):
        gym.make("cloth/Fold-v0", **{argument: value})


def test_overrides_reach_every_episodes_scene():
    # Without gravity the let-go cloth stays where it hung (10 cm above the
    # floor) instead of falling into a heap.
    env = gym.make("cloth/Drop-v0", overrides={"simulation.effects": '["bending", "damping"]'})
    env.reset(seed=0)
    let_go = np.tile([0.0, 0.0, 0.0, -1.0], 2).astype(np.float32)
    for _ in range(30):
        env.step(let_go)
    assert env.unwrapped.sim.positions[:, 2].min() > 0.09
    # Fold rebuilds its scene each episode: on a floor of friction 0.1 the
    # still half slides with the folded one, and the scripted fold misses
    # (measured 5.1 cm, against 0.8 cm at the task's 0.5).
    env = gym.make("cloth/Fold-v0", overrides=["colliders.0.friction=0.1"])
    reward, info = fold_scripted.fold(env, seed=0)
    assert -reward > 0.04 and not info["success"]


def test_an_override_the_scene_does_not_have_is_refused_by_name():
    with pytest.raises(cloth.SceneError, match="max_pases"):
        gym.make("cloth/Fold-v0", overrides={"solver.contacts.max_pases": 3})
    # The step is the dt_s argument's.
    with pytest.raises(ValueError, match="simulation.dt_s"):
        gym.make("cloth/Fold-v0", overrides=["simulation.dt_s=0.01"])


@pytest.mark.parametrize("task", TASKS)
def test_start_states_give_a_seed_the_same_start_made_or_restored(task):
    # Env a makes its starts in one order, env b in another: each seed
    # starts, and goes on, to the bit alike, and a draw of a start made
    # before makes nothing new.
    a = gym.make(task, start_states=2)
    b = gym.make(task, start_states=2)
    check_env(gym.make(task, start_states=2).unwrapped)
    seeds = [0, 1, 2, 3]
    first = {seed: a.reset(seed=seed)[0] for seed in seeds}
    made = a.unwrapped.made_starts
    assert 1 <= made <= 2
    for seed in reversed(seeds):
        obs, _ = b.reset(seed=seed)
        assert obs.tobytes() == first[seed].tobytes()
        assert a.reset(seed=seed)[0].tobytes() == obs.tobytes()
        for env in (a, b):
            env.action_space.seed(seed)
        for _ in range(2):
            action = a.action_space.sample()
            assert action.tobytes() == b.action_space.sample().tobytes()
            oa, ra, *_ = a.step(action)
            ob, rb, *_ = b.step(action)
            assert oa.tobytes() == ob.tobytes() and ra == rb
    assert a.unwrapped.made_starts == made


@pytest.mark.parametrize("task", TASKS)
def test_start_states_saved_to_a_file_start_each_seed_as_made(task, tmp_path):
    # Env a makes two starts and saves them; env b reads them and makes
    # none: every seed starts and goes on to the bit alike.
    path = tmp_path / "starts.npz"
    a = gym.make(task, start_states=2)
    a.unwrapped.save_starts(path)
    assert a.unwrapped.made_starts == 2
    b = gym.make(task, start_states=str(path))
    assert (b.unwrapped.start_states, b.unwrapped.made_starts) == (2, 2)
    for seed in range(4):
        assert a.reset(seed=seed)[0].tobytes() == b.reset(seed=seed)[0].tobytes()
        a.action_space.seed(seed)
        for _ in range(2):
            action = a.action_space.sample()
            oa, ra, *_ = a.step(action)
            ob, rb, *_ = b.step(action)
            assert oa.tobytes() == ob.tobytes() and ra == rb
    assert b.unwrapped.made_starts == 2


def test_a_start_states_file_is_refused_by_another_env_and_shared_by_workers(tmp_path):
    path = tmp_path / "fold.npz"
    gym.make("cloth/Fold-v0", start_states=2).unwrapped.save_starts(path)
    for task, kwargs, field in [
        ("cloth/Fold-v0", {"particles": 20}, "particles"),
        ("cloth/Drop-v0", {}, "task"),
        ("cloth/Fold-v0", {"overrides": {"solver.contacts.max_passes": 3}}, "overrides"),
        ("cloth/Fold-v0", {"dt_s": 1 / 60, "substeps": 2}, "dt_s"),
    ]:
        with pytest.raises(ValueError, match=f"made with {field} = "):
            gym.make(task, start_states=path, **kwargs)
    with np.load(path) as data:
        arrays = dict(data)
    arrays["snapshot_1"] = arrays["snapshot_1"][:-3]
    cut = tmp_path / "cut.npz"
    np.savez(cut, **arrays)
    with pytest.raises(ValueError, match="Snapshot"):
        gym.make("cloth/Fold-v0", start_states=cut)
    arrays["format"] = np.array("one")
    np.savez(cut, **arrays)
    with pytest.raises(ValueError, match="cut.npz'?: not start states"):
        gym.make("cloth/Fold-v0", start_states=cut)
    not_starts = tmp_path / "other.npy"
    np.save(not_starts, np.zeros(3))
    for bad in (not_starts, tmp_path / "missing.npz"):
        with pytest.raises(ValueError, match="start_states = "):
            gym.make("cloth/Fold-v0", start_states=bad)
    with pytest.raises(ValueError, match="no start states"):
        gym.make("cloth/Fold-v0").unwrapped.save_starts(tmp_path / "none.npz")
    # Two workers read the one file: a seed starts as in a single env.
    vec = gym.vector.AsyncVectorEnv([lambda: gym.make("cloth/Fold-v0", start_states=str(path)) for _ in range(2)])
    try:
        obs, _ = vec.reset(seed=[5, 6])
        single = gym.make("cloth/Fold-v0", start_states=2)
        assert obs[0].tobytes() == single.reset(seed=5)[0].tobytes()
        assert obs[1].tobytes() == single.reset(seed=6)[0].tobytes()
    finally:
        vec.close()


def test_restored_starts_are_the_tasks_starts():
    # Flatten's start is crumpled (0.25-0.41 of the flat area for seeds
    # 0-7 made fresh). Drop's hanging cloth does not depend on the seed
    # (only its target does): restored, with its grasps taken again, it
    # holds the same particles and steps as a start made fresh, to the
    # bit, and falls when let go.
    flatten = gym.make("cloth/Flatten-v0", start_states=3).unwrapped
    for seed in range(4):
        flatten.reset(seed=seed)
        assert 0.2 < flatten.coverage() < 0.45
    restored, fresh = gym.make("cloth/Drop-v0", start_states=1), gym.make("cloth/Drop-v0")
    hold = np.tile([0.0, 0.0, 0.0, 1.0], 2).astype(np.float32)
    for seed in range(2):
        restored.reset(seed=seed)
        fresh.reset(seed=seed)
        a, b = restored.unwrapped, fresh.unwrapped
        assert [a.sim.grasp_particles(g) for g in a.grasps] == [b.sim.grasp_particles(g) for g in b.grasps]
        for _ in range(3):
            assert a.sim.positions.tobytes() == b.sim.positions.tobytes()
            restored.step(hold)
            fresh.step(hold)
    let_go = np.tile([0.0, 0.0, 0.0, -1.0], 2).astype(np.float32)
    for _ in range(30):
        restored.step(let_go)
    assert restored.unwrapped.sim.positions[:, 2].min() < 0.01
    assert restored.unwrapped.made_starts == 1


def grasping_moves(env, seed: int, count: int):
    """Actions that lower the pickers onto the cloth and grasp (three
    steps of 3 cm from 10 cm up), then move them at random, holding."""
    env.action_space.seed(seed)
    moves = [np.tile([0.0, 0.0, -1.0, 1.0], env.pickers).astype(np.float32)] * 3
    for _ in range(count - 3):
        action = env.action_space.sample()
        action[3::4] = 1.0
        moves.append(action)
    return moves


def replay(env, moves):
    """The observations' bytes, rewards and successes of ``moves``."""
    out = []
    for action in moves:
        obs, reward, _, truncated, info = env.step(action)
        assert not truncated
        out.append((obs.tobytes(), reward, info["success"]))
    return out


@pytest.mark.parametrize("task", TASKS)
def test_set_state_goes_on_to_the_bit_as_the_run_it_was_taken_from(task):
    # A state taken mid-episode, Fold's and Drop's pickers holding the
    # cloth: the same moves from it give the same bits in the env it came
    # from, in another env after another episode (for Fold, another
    # scene: another shift), pickled, and in an env never reset.
    env = gym.make(task).unwrapped
    env.reset(seed=3)
    moves = grasping_moves(env, seed=3, count=10)
    replay(env, moves[:5])
    state = env.get_state()
    assert state.time_s == env.sim.time_s
    if task != "cloth/Flatten-v0":
        assert any(g is not None for g in state.grasps)
    first = replay(env, moves[5:])
    env.set_state(state)
    assert replay(env, moves[5:]) == first
    other = gym.make(task).unwrapped
    other.reset(seed=4)
    other.set_state(pickle.loads(pickle.dumps(state)))
    assert replay(other, moves[5:]) == first
    never_reset = gym.make(task).unwrapped
    never_reset.set_state(state)
    assert replay(never_reset, moves[5:]) == first


def test_set_state_refuses_a_state_of_another_env_by_argument():
    fold = gym.make("cloth/Fold-v0").unwrapped
    with pytest.raises(gym.error.ResetNeeded, match="reset the env first"):
        fold.get_state()
    fold.reset(seed=0)
    state = fold.get_state()
    assert not state.picker_pos.flags.writeable
    for task, kwargs, field in [
        ("cloth/Drop-v0", {}, "task"),
        ("cloth/Fold-v0", {"particles": 20}, "particles"),
        ("cloth/Fold-v0", {"overrides": {"solver.contacts.max_passes": 3}}, "overrides"),
    ]:
        with pytest.raises(ValueError, match=f"a state of an env with {field} = "):
            gym.make(task, **kwargs).unwrapped.set_state(state)
    with pytest.raises(TypeError, match="EnvState"):
        fold.set_state(fold.sim.snapshot())


def test_the_workers_of_a_vector_env_send_their_states():
    # CEM-style planning: the workers' states, sent back through pipes,
    # go on in a single env as in the workers.
    vec = gym.vector.AsyncVectorEnv([lambda: gym.make("cloth/Fold-v0") for _ in range(2)])
    try:
        vec.reset(seed=[1, 2])
        states = vec.call("get_state")
        action = np.tile([0.3, -0.2, -1.0, 1.0], 2).astype(np.float32)
        obs, *_ = vec.step(np.stack([action, action]))
    finally:
        vec.close()
    single = gym.make("cloth/Fold-v0").unwrapped
    for k in range(2):
        single.set_state(states[k])
        assert single.step(action)[0].tobytes() == obs[k].tobytes()
