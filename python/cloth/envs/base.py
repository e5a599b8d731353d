"""The common part of the cloth tasks: a square cloth on a floor, one or
two pickers moved by the action, observations, images and seeding."""

from __future__ import annotations

import copy
import dataclasses
import json
import numbers
import os

import gymnasium as gym
import numpy as np
from gymnasium import spaces

import cloth

from .raster import Camera, render

SCENE = """\
[simulation]
integrator = "bdf2"
dt_s = {dt_s!r}
duration_s = 1e6
effects = ["gravity", "bending", "damping"]
initial_jitter_m = 0.0005

[solver]
rel_tol = 1e-3
max_iter = 300

[material]
areal_density_kg_m2 = 0.2
tensile_stiffness_n_m = 200.0
flexural_rigidity_n_m = 1e-5
buckling_stiffness_n_m = 200.0
damping_n_s_m = 0.02

[[panels]]
particles = [{n}, {n}]
size_m = [{side_m!r}, {side_m!r}]
origin_m = [{origin[0]!r}, {origin[1]!r}, {origin[2]!r}]
u_axis = [1.0, 0.0, 0.0]
v_axis = [{v_axis[0]!r}, {v_axis[1]!r}, {v_axis[2]!r}]

[collision]
thickness_m = {thickness_m!r}

[[colliders]]
shape = {{ kind = "half-space", normal = [0.0, 0.0, 1.0] }}
friction = 0.5

[self_collision]
thickness_m = {self_thickness_m!r}
"""


def observation_box(points: int, pickers: int, bounds) -> spaces.Box:
    """The observation's space: ``points`` positions (m), unbounded (a
    cloth's particles go wherever the simulation takes them), then per
    picker its position within ``bounds`` (m) and a holding flag in
    [0, 1]."""
    lo, hi = (np.asarray(b, dtype=np.float32) for b in bounds)
    low = np.concatenate([np.full(3 * points, -np.inf, np.float32), np.tile(np.append(lo, 0.0), pickers)])
    high = np.concatenate([np.full(3 * points, np.inf, np.float32), np.tile(np.append(hi, 1.0), pickers)])
    return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)


@dataclasses.dataclass(frozen=True, eq=False)
class EnvState:
    """A task env's state as ``ClothTaskEnv.get_state`` took it: enough for
    ``set_state`` to go on from it, to the bit, in this env or another one
    made with the same arguments. It pickles (a vector env's workers can
    send it) and its arrays are read-only."""

    #: The env's arguments that shape a state (``_start_config``).
    config: dict
    #: The scene the cloth was built from, as TOML text.
    scene_text: str
    #: The cloth and the integrator's memory.
    snapshot: cloth.Snapshot
    #: Each picker's position, m, ``(pickers, 3)``.
    picker_pos: np.ndarray
    #: Per picker, ``None`` or what it holds: the particles and their
    #: offsets from the picker (m, ``(k, 3)``).
    grasps: tuple
    #: The task's ``START_ATTRIBUTES`` (a Fold episode's shift, a Drop
    #: episode's target...).
    attributes: dict

    @property
    def time_s(self) -> float:
        """The simulated time the state was taken at, s."""
        return self.snapshot.time_s


def _read_only(array, dtype=None) -> np.ndarray:
    """A read-only copy of ``array``."""
    array = np.array(array, dtype=dtype)
    array.flags.writeable = False
    return array


def _restore(sim, state: EnvState) -> list:
    """Restores ``state``'s cloth on ``sim`` (holding no grasp) and takes
    its pickers' grasps again; returns the grasps' ids, ``None`` for a
    picker holding nothing."""
    sim.restore(state.snapshot)
    # The grasps taken as they were, not from the particles in reach now:
    # offsets recomputed from the positions would differ by a rounding.
    return [
        None if held is None else sim.grasp_at_offsets(held[0].tolist(), held[1], list(state.picker_pos[k]))
        for k, held in enumerate(state.grasps)
    ]


class StartsFileError(ValueError):
    """A ``start_states`` file that is not one, or was made for another env."""


class ClothTaskEnv(gym.Env):
    """A square cloth of ``particles`` x ``particles`` nodes and side
    ``side_m`` (m) on a floor at z = 0 (Choi & Ko's model, BDF2, contacts
    with friction 0.5, self-collision), handled by ``pickers`` pickers.

    Action: per picker ``[dx, dy, dz, pick]`` in [-1, 1]; the picker moves
    by ``max_move_m`` times the first three, within a box of half-width
    0.5 m and height 0.5 m above the floor. ``pick > 0`` grasps every free
    particle within ``picker_radius_m`` of the picker (if it holds none)
    and keeps them; ``pick <= 0`` lets them go. Held particles keep their
    offsets from the picker.

    One env step is ``substeps`` simulation steps of ``dt_s`` (s), the
    pickers moving on straight lines over them: by default three steps of
    1/90 s (Choi & Ko's step), 1/30 s in all. One step of 1/30 s is about
    twice as fast and stable, but moves the cloth differently: the
    scripted fold that succeeds with steps of 1/90 s misses with it
    (docs/results/python-envs.md).

    ``overrides`` changes the task's scene as ``cloth run --set`` does: a
    dict of dotted keys to values (``{"solver.contacts.max_passes": 3}``)
    or a list of ``"key=value"`` strings; a key the scene does not have
    raises ``ValueError`` naming it. The step is ``dt_s``'s, not an
    override's.

    ``start_states=N`` draws each episode's start from ``N`` start states
    (SoftGym's cached states): the seed picks one, the first draw of each
    makes it (the task's crumpling, settling or grasping, from a seed of
    its own) and every draw, the first included, restores it, so a reset
    costs a restore instead of the task's settling and the same seed
    gives the same start however often it was drawn. ``None`` (the
    default): every episode makes its own start from its seed.
    ``save_starts(path)`` makes the starts not made yet and writes all
    ``N`` to a ``.npz`` file; ``start_states=path`` reads them back (the
    workers of a vector env share one file instead of each making its
    own), refusing a file made by another task or with other arguments
    that shape the start (``particles``, ``side_m``, ``pickers``,
    ``dt_s``, ``substeps``, ``picker_radius_m``, ``overrides``).

    Observation (float32): with ``observation="positions"``, every
    particle's position (m, row by row, unbounded) then each picker's
    position (within ``BOUNDS``) and a holding flag (0 or 1); with
    ``"keypoints"``, the four corners and the centre instead of every
    particle.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 30}
    #: Height of the cloth's particles above the floor at the start, m.
    REST_HEIGHT_M = 0.005
    #: Lower and upper corners of the pickers' box, m.
    BOUNDS = (np.array([-0.5, -0.5, 0.0]), np.array([0.5, 0.5, 0.5]))

    def __init__(
        self,
        particles: int = 25,
        side_m: float = 0.4,
        pickers: int = 2,
        observation: str = "positions",
        render_mode: str | None = None,
        dt_s: float = 1.0 / 90.0,
        substeps: int = 3,
        max_move_m: float = 0.03,
        picker_radius_m: float = 0.02,
        threads: int | None = 1,
        image_size: int = 128,
        overrides: dict | list | None = None,
        start_states: int | str | os.PathLike | None = None,
    ):
        if pickers not in (1, 2):
            raise ValueError(f"pickers = {pickers}: one or two")
        if observation not in ("positions", "keypoints"):
            raise ValueError(f"observation = {observation!r}: 'positions' or 'keypoints'")
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode = {render_mode!r}: None or 'rgb_array'")
        if particles < 3:
            raise ValueError(f"particles = {particles}: at least 3 a side")
        if substeps < 1:
            raise ValueError(f"substeps = {substeps}: at least 1")
        starts_file = start_states if isinstance(start_states, (str, os.PathLike)) else None
        whole = isinstance(start_states, numbers.Integral) and not isinstance(start_states, bool)
        if start_states is not None and starts_file is None and not (whole and start_states >= 1):
            raise ValueError(f"start_states = {start_states!r}: None, an integer of at least 1 or a file's path")
        for name, value in (
            ("side_m", side_m),
            ("dt_s", dt_s),
            ("max_move_m", max_move_m),
            ("picker_radius_m", picker_radius_m),
        ):
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"{name} = {value}: must be finite and > 0")
        self.n, self.side_m, self.pickers = particles, side_m, pickers
        self.observation, self.render_mode = observation, render_mode
        self.dt_s, self.substeps, self.max_move_m = dt_s, substeps, max_move_m
        self.picker_radius_m, self.threads = picker_radius_m, threads
        self.spacing_m = side_m / (particles - 1)
        if any(str(key).split("=")[0].strip() == "simulation.dt_s" for key in overrides or []):
            raise ValueError("overrides: simulation.dt_s is the dt_s argument")
        # A copy: the caller's later changes do not reach new episodes.
        self.overrides = dict(overrides) if isinstance(overrides, dict) else overrides and list(overrides)
        self._scene = self.build_scene()
        self.action_space = spaces.Box(-1.0, 1.0, shape=(4 * pickers,), dtype=np.float32)
        points = particles * particles if observation == "positions" else 5
        self.observation_space = observation_box(points, pickers, self.BOUNDS)
        self._camera = Camera(eye=(0.0, -0.8, 0.8), target=(0.0, 0.0, 0.0), width=image_size, height=image_size)
        self.sim = None
        # The text of the scene ``sim`` was built from.
        self._sim_scene_text = None
        self.picker_pos = np.zeros((pickers, 3))
        self.grasps: list[int | None] = [None] * pickers
        self.start_states = None if start_states is None or starts_file else int(start_states)
        # Start state k: its scene and its EnvState.
        self._starts: dict[int, tuple] = {}
        if starts_file is not None:
            self._load_starts(starts_file)

    # -- scene -------------------------------------------------------------
    def cloth_layout(self):
        """Origin (m) and second axis of the cloth's panel at the start."""
        half = self.side_m / 2
        return (-half, -half, self.REST_HEIGHT_M), (0.0, 1.0, 0.0)

    def scene_text(self) -> str:
        origin, v_axis = self.cloth_layout()
        # Plain floats: NumPy's repr is not TOML.
        origin, v_axis = [float(c) for c in origin], [float(c) for c in v_axis]
        return SCENE.format(
            dt_s=float(self.dt_s),
            n=int(self.n),
            side_m=float(self.side_m),
            origin=origin,
            v_axis=v_axis,
            thickness_m=0.004,
            self_thickness_m=0.006,
        )

    def build_scene(self):
        """The scene of ``scene_text`` with the ``overrides``."""
        name = f"{type(self).__name__} scene"
        return cloth.Scene.from_text(self.scene_text(), overrides=self.overrides, name=name)

    def index(self, i: int, j: int) -> int:
        """The particle at column ``i`` (along x) and row ``j``."""
        return j * self.n + i

    def corners(self):
        n = self.n - 1
        return [self.index(0, 0), self.index(n, 0), self.index(0, n), self.index(n, n)]

    # -- the gymnasium interface ------------------------------------------
    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if self.start_states is None:
            self._make_start()
        else:
            self._restore_start(int(self.np_random.integers(self.start_states)))
        return self._obs(), self._info(self.measure()[1])

    @property
    def made_starts(self) -> int:
        """How many of the ``start_states`` have been made (or read from
        a file) so far."""
        return len(self._starts)

    def _make_start(self):
        """A new simulation of the episode's scene, set up by the task;
        returns the scene."""
        scene = self.episode_scene()
        self.sim = scene.simulation(threads=self.threads)
        self._sim_scene_text = self.scene_text()
        self.grasps = [None] * self.pickers
        self.picker_pos = np.zeros((self.pickers, 3))
        self.setup()
        return scene

    def _add_start(self, k: int):
        """Makes start state ``k`` from a generator seeded by ``k`` alone
        and keeps it."""
        # The task draws from ``self.np_random``; swapped, not set, so
        # the episode keeps its generator and its seed.
        episode_rng = self.np_random
        self._np_random = np.random.default_rng([0x5747, k])
        try:
            scene = self._make_start()
        finally:
            self._np_random = episode_rng
        self._starts[k] = (scene, self.get_state())

    def _restore_start(self, k: int):
        """Starts the episode from start state ``k``, made on its first draw
        with a generator seeded by ``k`` alone."""
        if k not in self._starts:
            self._add_start(k)
        scene, state = self._starts[k]
        self._apply_state(state, scene)

    # -- states --------------------------------------------------------------
    def get_state(self) -> EnvState:
        """The env's state now (SoftGym's ``get_state``): the cloth, the
        pickers and what they hold, and the task's episode attributes. The
        episode's generator and a ``TimeLimit`` wrapper's step count are
        not in it. Raises ``gymnasium.error.ResetNeeded`` before the first
        ``reset``."""
        if self.sim is None:
            raise gym.error.ResetNeeded("get_state: reset the env first")
        grasps = tuple(
            None
            if g is None
            else (_read_only(self.sim.grasp_particles(g), np.int64), _read_only(self.sim.grasp_offsets(g)))
            for g in self.grasps
        )
        return EnvState(
            config=self._start_config(),
            scene_text=self._sim_scene_text,
            snapshot=self.sim.snapshot(),
            picker_pos=_read_only(self.picker_pos),
            grasps=grasps,
            attributes={name: copy.deepcopy(getattr(self, name)) for name in self.START_ATTRIBUTES},
        )

    def set_state(self, state: EnvState):
        """Goes back to ``state`` from ``get_state`` (SoftGym's
        ``set_state``): stepping on repeats, to the bit, the steps taken
        from it. The state may come from another env made with the same
        arguments; one made with others (``particles``, ``dt_s``,
        ``overrides``...) raises ``ValueError`` naming the argument."""
        if not isinstance(state, EnvState):
            raise TypeError(f"set_state: an EnvState from get_state, not {type(state).__name__}")
        for field, here in self._start_config().items():
            if state.config.get(field) != here:
                raise ValueError(f"set_state: a state of an env with {field} = {state.config.get(field)!r}, "
                                 f"this env has {here!r}")
        self._apply_state(state)

    def _apply_state(self, state: EnvState, scene=None):
        """Puts ``state`` in place, on the simulation there is when it is of
        the state's scene, else on a new one of ``scene`` (built from the
        state's attributes when not given)."""
        for name, value in state.attributes.items():
            setattr(self, name, copy.deepcopy(value))
        if self.sim is not None and self._sim_scene_text == state.scene_text:
            for g in self.grasps:
                if g is not None:
                    self.sim.release(g)
        else:
            if scene is None:
                scene = self.build_scene()
                if self.scene_text() != state.scene_text:
                    raise ValueError("set_state: the state's scene is not the one this env builds for it")
            self.sim = scene.simulation(threads=self.threads)
            self._sim_scene_text = state.scene_text
        # The old grasps are gone (released, or on the old simulation):
        # none is held if the restore is refused.
        self.grasps = [None] * self.pickers
        self.grasps = _restore(self.sim, state)
        self.picker_pos = np.array(state.picker_pos, dtype=np.float64)

    # -- start states on disk -----------------------------------------------
    #: The layout ``save_starts`` writes and ``start_states=path`` reads.
    STARTS_FORMAT = 2

    def _start_config(self) -> dict:
        """The arguments that shape a start state, as a file records them."""
        overrides = json.dumps(self.overrides, sort_keys=True, default=str)
        return {
            "task": type(self).__name__,
            "particles": int(self.n),
            "side_m": float(self.side_m),
            "pickers": int(self.pickers),
            "dt_s": float(self.dt_s),
            "substeps": int(self.substeps),
            "picker_radius_m": float(self.picker_radius_m),
            "overrides": overrides,
        }

    def save_starts(self, path):
        """Makes the start states not made yet and writes all
        ``start_states`` of them to ``path`` (a NumPy ``.npz`` file,
        without pickled objects), for ``start_states=path``. The file is
        written whole under another name and then renamed, so a reader
        never sees half of it."""
        if self.start_states is None:
            raise ValueError("save_starts: this env has no start states (start_states=None)")
        for k in range(self.start_states):
            if k not in self._starts:
                self._add_start(k)
        arrays = {
            "format": np.array(self.STARTS_FORMAT),
            "config": np.array(json.dumps(self._start_config(), sort_keys=True)),
            "count": np.array(self.start_states),
        }
        for k in range(self.start_states):
            state = self._starts[k][1]
            arrays[f"scene_{k}"] = np.array(state.scene_text)
            arrays[f"snapshot_{k}"] = np.frombuffer(state.snapshot.to_bytes(), dtype=np.uint8)
            arrays[f"pickers_{k}"] = np.asarray(state.picker_pos, dtype=np.float64)
            arrays[f"held_{k}"] = np.array([g is not None for g in state.grasps])
            for picker, held in enumerate(state.grasps):
                if held is not None:
                    arrays[f"grasp_{k}_{picker}_particles"], arrays[f"grasp_{k}_{picker}_offsets"] = held
            for name, value in state.attributes.items():
                arrays[f"attribute_{k}_{name}"] = np.asarray(value)
        path = os.fspath(path)
        partial = f"{path}.{os.getpid()}.partial"
        with open(partial, "wb") as f:
            np.savez(f, **arrays)
        os.replace(partial, path)

    def _load_starts(self, path):
        """Reads the start states ``save_starts`` wrote to ``path``; a file
        that is not one, or was made for another env, raises
        ``ValueError`` naming the path and what differs."""
        path = os.fspath(path)
        try:
            data = np.load(path, allow_pickle=False)
        except (OSError, ValueError) as e:
            raise StartsFileError(f"start_states = {path!r}: cannot be read as start states ({e})") from None
        if not isinstance(data, np.lib.npyio.NpzFile):
            raise StartsFileError(f"start_states = {path!r}: not a .npz file of start states")
        with data:
            try:
                count, starts = self._read_starts(data)
            except StartsFileError as e:
                raise StartsFileError(f"start_states = {path!r}: {e}") from None
            except KeyError as e:
                raise StartsFileError(f"start_states = {path!r}: no array {e} in it: not a save_starts file") from None
            except (TypeError, ValueError) as e:
                why = f"not start states as save_starts writes them ({e})"
                raise StartsFileError(f"start_states = {path!r}: {why}") from None
        self.start_states, self._starts = count, starts

    def _read_starts(self, data) -> tuple[int, dict]:
        """The count and the start states of an open ``save_starts`` file,
        each checked against this env (its scene, a restore)."""
        if int(data["format"]) != self.STARTS_FORMAT:
            raise StartsFileError(f"format {int(data['format'])}; this version reads {self.STARTS_FORMAT}")
        saved = json.loads(str(data["config"]))
        for field, here in self._start_config().items():
            if saved.get(field) != here:
                raise StartsFileError(f"made with {field} = {saved.get(field)!r}, this env has {here!r}")
        count = int(data["count"])
        if count < 1:
            raise StartsFileError(f"count = {count}: no start states")
        starts = {}
        for k in range(count):
            attributes = {}
            for name in self.START_ATTRIBUTES:
                value = data[f"attribute_{k}_{name}"]
                attributes[name] = value[()] if value.ndim == 0 else value
                setattr(self, name, copy.deepcopy(attributes[name]))
            # The scene the task builds from the start's attributes (Fold's
            # shift) must be the one the start was made from.
            scene = self.build_scene()
            if self.scene_text() != str(data[f"scene_{k}"]):
                raise StartsFileError(f"start {k} was made from another scene than this env builds")
            snapshot = cloth.Snapshot(data[f"snapshot_{k}"].tobytes())
            picker_pos = _read_only(data[f"pickers_{k}"], np.float64)
            held = [bool(h) for h in data[f"held_{k}"]]
            if picker_pos.shape != (self.pickers, 3) or len(held) != self.pickers:
                raise StartsFileError(f"start {k}'s pickers are not {self.pickers}")
            grasps = tuple(
                (
                    _read_only(data[f"grasp_{k}_{picker}_particles"], np.int64),
                    _read_only(data[f"grasp_{k}_{picker}_offsets"], np.float64),
                )
                if holding
                else None
                for picker, holding in enumerate(held)
            )
            state = EnvState(self._start_config(), self.scene_text(), snapshot, picker_pos, grasps, attributes)
            # Put in place once on a simulation of its own: a snapshot or
            # a grasp that does not fit this env's cloth is refused here.
            try:
                _restore(scene.simulation(threads=self.threads), state)
            except (cloth.SnapshotError, cloth.ControlError) as e:
                raise StartsFileError(f"start {k} does not fit this env's cloth: {e}") from None
            starts[k] = (scene, state)
        return count, starts

    def step(self, action):
        action = np.clip(np.asarray(action, dtype=np.float64).reshape(self.pickers, 4), -1.0, 1.0)
        start = self.picker_pos.copy()
        goal = np.clip(start + action[:, :3] * self.max_move_m, *self.BOUNDS)
        truncated = False
        info = {}
        try:
            for sub in range(1, self.substeps + 1):
                # The pickers move on straight lines over the substeps;
                # they grasp or let go at the first.
                for k in range(self.pickers):
                    to = start[k] + (goal[k] - start[k]) * sub / self.substeps
                    self.move_picker(k, to, action[k, 3] > 0)
                self.sim.step(1)
        except cloth.StepError as e:
            # A step that fails ends the episode; the cloth stays as it was.
            truncated, info["error"] = True, str(e)
        reward, success = self.measure()
        return self._obs(), reward, False, truncated, {**self._info(success), **info}

    def render(self):
        if self.render_mode != "rgb_array" or self.sim is None:
            return None
        return render(
            self._camera,
            self.sim.positions,
            self.sim.triangles,
            markers=self.picker_pos,
            target=self.target_points(),
        )

    # -- pickers -----------------------------------------------------------
    def move_picker(self, k: int, to, pick: bool):
        """Moves picker ``k`` to ``to`` (m), grasping or letting go by ``pick``."""
        if pick and self.grasps[k] is None:
            try:
                self.grasps[k] = self.sim.grasp(list(self.picker_pos[k]), self.picker_radius_m)
            except cloth.ControlError:
                self.grasps[k] = None  # nothing within reach
        elif not pick and self.grasps[k] is not None:
            self.sim.release(self.grasps[k])
            self.grasps[k] = None
        if self.grasps[k] is not None:
            self.sim.move_grasp(self.grasps[k], list(to))
        self.picker_pos[k] = to

    def steps_for(self, seconds: float) -> int:
        """Simulation steps of ``dt_s`` in ``seconds`` (at least one)."""
        return max(1, round(seconds / self.dt_s))

    def settle(self, seconds: float):
        """Lets the cloth go on for ``seconds`` with nothing changed."""
        self.sim.step(self.steps_for(seconds))

    # -- what a task fills in ----------------------------------------------
    #: The attributes ``setup`` and ``episode_scene`` set that a start
    #: state keeps (besides the cloth and the pickers).
    START_ATTRIBUTES: tuple[str, ...] = ()

    def episode_scene(self):
        """The scene an episode starts from (drawn with ``self.np_random``)."""
        return self._scene

    def setup(self):
        """Puts the cloth and pickers where the episode starts."""

    def measure(self) -> tuple[float, bool]:
        """The reward now and whether the task is done, measured once."""
        raise NotImplementedError

    def reward(self) -> float:
        return self.measure()[0]

    def success(self) -> bool:
        return self.measure()[1]

    def target_points(self):
        """Points drawn on the floor in images (where the cloth should go)."""
        return None

    # -- observations ------------------------------------------------------
    def _obs(self):
        x = self.sim.positions
        if self.observation == "keypoints":
            x = x[self.corners() + [self.index(self.n // 2, self.n // 2)]]
        held = np.array([[0.0 if g is None else 1.0] for g in self.grasps])
        pickers = np.hstack([self.picker_pos, held])
        return np.concatenate([x.ravel(), pickers.ravel()]).astype(np.float32)

    def _info(self, success: bool):
        return {"success": bool(success), "time_s": self.sim.time_s}
